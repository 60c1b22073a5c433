/*
 * test_robot_live - the live sighting stream of coslam-robot
 * (robot_live_open, robot_sightings.h): the e2e device server's camera
 * stand-in over an inherited SOCK_SEQPACKET socket (docs/e2e.md).
 * Frames with their stamps and marker classes, robot sightings, the newest
 * of several queued frames, refused datagrams, an empty frame, the peer's
 * close, and the inherited fd staying open after close (it is dup'ed).
 * In the robot's device slot: the refusal counters the status reports stay
 * totals across a reopen of the stream (robot_devices_live_counters).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmocka.h>

#include "hal/hal_clock_linux.h"
#include "robot_config.h"
#include "robot_devices.h"
#include "robot_sightings.h"

static hal_status_t fake_now(hal_clock_t *c, uint64_t *now_us)
{
    (void)c;
    *now_us = 1000u;
    return HAL_OK;
}

static const hal_clock_ops_t fake_clock_ops = {.now_us = fake_now};

static void send_text(int fd, const char *text)
{
    assert_int_equal(send(fd, text, strlen(text), 0), (ssize_t)strlen(text));
}

static void test_live(void **state)
{
    (void)state;
    hal_clock_t clock = {.ops = &fake_clock_ops, .backend = NULL};
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    static robot_replay_t r;
    char msg[256];
    /* robot 0 of a fleet of 3 */
    assert_int_equal(robot_live_open(&r, -1, 0, 3, &clock, msg, sizeof msg), HAL_E_ARG);
    assert_int_equal(robot_live_open(&r, sv[1], 0, 3, &clock, msg, sizeof msg), HAL_OK);
    sighting_frame_t f;
    assert_int_equal(sighting_source_next_frame(&r.src, &f, 0), HAL_E_TIMEOUT);

    /* one frame: two markers of classes 3 and 1, one robot */
    send_text(sv[0], "T 123456789\nS 1.2 3 2.5 0.25\nS 1.2 1 1.5 -0.5\nR 1.2 1 2.0 0.1\n");
    assert_int_equal(sighting_source_next_frame(&r.src, &f, 0), HAL_OK);
    assert_int_equal(f.stamp_us, 123456789u);
    assert_int_equal(f.n_landmarks, 2);
    assert_int_equal(f.landmarks[0].signature, 3);
    assert_true(f.landmarks[0].range_m == 2.5 && f.landmarks[0].bearing_rad == 0.25);
    assert_int_equal(f.landmarks[1].signature, 1);
    assert_int_equal(f.n_robots, 1);
    assert_int_equal(f.robots[0].robot_id, 1);
    const uint32_t seq1 = f.sequence;
    assert_int_equal(sighting_source_next_frame(&r.src, &f, 0), HAL_E_TIMEOUT);

    /* bad datagrams are refused and counted: no T line, a bad record, a bad class */
    send_text(sv[0], "S 1.4 0 2.0 0.0\n");
    send_text(sv[0], "T 5\nS 1.4 zero 2.0 0.0\n");
    send_text(sv[0], "T 5\nS 1.4 300 2.0 0.0\n");
    assert_int_equal(sighting_source_next_frame(&r.src, &f, 0), HAL_E_TIMEOUT);
    assert_int_equal(r.live_bad, 3u);

    /* two queued frames: the newest is handed out, the other counted as skipped */
    send_text(sv[0], "T 200\nS 1.6 0 1.0 0.0\n");
    send_text(sv[0], "T 400\n"); /* an empty frame: the camera saw nothing */
    assert_int_equal(sighting_source_next_frame(&r.src, &f, 0), HAL_OK);
    assert_int_equal(f.stamp_us, 400u);
    assert_int_equal(f.n_landmarks, 0);
    assert_int_equal(f.sequence, seq1 + 2u);
    assert_int_equal(r.frames_skipped, 1u);

    /* robot sightings of this robot itself or outside the fleet are refused
     * as the landmark log refuses them at open (they were handed to the
     * node): the record, not the frame; counted, the first said once */
    assert_int_equal(robot_live_say_refusals(&r, stderr), 0);
    send_text(sv[0], "T 300\nS 1.5 2 1.0 0.0\nR 1.5 0 2.0 0.1\nR 1.5 3 2.0 0.1\nR 1.5 2 2.5 -0.1\n");
    assert_int_equal(sighting_source_next_frame(&r.src, &f, 0), HAL_OK);
    assert_int_equal(f.n_landmarks, 1);
    assert_int_equal(f.n_robots, 1);
    assert_int_equal(f.robots[0].robot_id, 2);
    assert_int_equal(r.live_robots_refused, 2u);
    assert_int_equal(r.live_bad, 3u); /* not a bad datagram */
    char said[512] = "";
    FILE *out = fmemopen(said, sizeof said, "w");
    assert_non_null(out);
    assert_int_equal(robot_live_say_refusals(&r, out), 1);
    send_text(sv[0], "T 350\nR 1.6 7 2.0 0.1\n");
    assert_int_equal(sighting_source_next_frame(&r.src, &f, 0), HAL_OK);
    assert_int_equal(f.n_robots, 0);
    assert_int_equal(r.live_robots_refused, 3u);
    assert_int_equal(robot_live_say_refusals(&r, out), 0); /* once */
    fclose(out);
    assert_non_null(strstr(said, "coslam-robot: sightings fd "));
    assert_non_null(strstr(said, "robot sightings refused: other_robot_id 0 is this robot's own id ([robot] id = 0)"));
    assert_null(strchr(strchr(said, '\n') + 1, '\n')); /* one line */

    /* the server goes away */
    close(sv[0]);
    assert_int_equal(sighting_source_next_frame(&r.src, &f, 0), HAL_E_CLOSED);
    robot_replay_close(&r);
    /* the inherited fd is still ours (a reopen would dup it again) */
    assert_int_equal(close(sv[1]), 0);
}

/* Bad datagrams on the stream, handed to the node through the slot's proxy. */
static void send_bad_and_poll(robot_devices_t *d, int fd, int n)
{
    for (int i = 0; i < n; ++i) {
        send_text(fd, "S 1.4 0 2.0 0.0\n"); /* no T line */
    }
    send_text(fd, "T 10\nR 1.0 0 2.0 0.1\n"); /* robot 0 is this robot: refused */
    sighting_frame_t f;
    (void)sighting_source_next_frame(&d->sightings, &f, 0);
}

static robot_config_t cfg;
static robot_devices_t dev;

/* The status's live_bad and live_robots_refused are totals: a reopen of the
 * stream (the slot lost it and opened it again) starts the stream's own
 * counters, which the status used to report, so they went back to 0. */
static void test_live_counters_across_reopen(void **state)
{
    (void)state;
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    robot_config_default(&cfg);
    cfg.laser_device[0] = '\0';
    cfg.can_interface[0] = '\0';
    cfg.gpio_chip[0] = '\0';
    cfg.storage_dir[0] = '\0';
    cfg.fleet_key_file[0] = '\0';
    cfg.camera_live_fd = sv[1];
    cfg.retry_period_s = 0.1;
    char msg[512];
    FILE *log = fopen("/dev/null", "w");
    assert_non_null(log);
    assert_int_equal(robot_devices_init(&dev, &cfg, hal_clock_linux(), log, 0, msg, sizeof msg), COSLAM_OK);
    robot_devices_open_all(&dev, 0U);
    assert_int_equal(dev.dev[ROBOT_DEV_CAMERA].state, ROBOT_DEV_UP);
    send_bad_and_poll(&dev, sv[0], 3);
    uint32_t bad = 0U;
    uint32_t refused = 0U;
    robot_devices_live_counters(&dev, &bad, &refused);
    assert_int_equal(bad, 3u);
    assert_int_equal(refused, 1u);
    /* the stream goes down (as after HAL_E_IO in a row): closed */
    robot_devices_fail(&dev, ROBOT_DEV_CAMERA, HAL_E_IO, "test: lost", 1000U);
    robot_devices_live_counters(&dev, &bad, &refused);
    assert_int_equal(bad, 3u); /* down: the totals so far */
    assert_int_equal(refused, 1u);
    /* reopened after the retry period, on the slot's opener */
    (void)robot_devices_service(&dev, 1000000U);
    assert_int_equal(robot_devices_wait_opens(&dev, 5000U), 0u);
    (void)robot_devices_service(&dev, 1000000U);
    assert_int_equal(dev.dev[ROBOT_DEV_CAMERA].state, ROBOT_DEV_UP);
    assert_int_equal(dev.dev[ROBOT_DEV_CAMERA].opens, 2u);
    assert_int_equal(dev.replay.live_bad, 0u); /* the stream's own counters started again */
    robot_devices_live_counters(&dev, &bad, &refused);
    assert_int_equal(bad, 3u); /* not 0 */
    assert_int_equal(refused, 1u);
    send_bad_and_poll(&dev, sv[0], 2);
    robot_devices_live_counters(&dev, &bad, &refused);
    assert_int_equal(bad, 5u);
    assert_int_equal(refused, 2u);
    robot_devices_close_all(&dev);
    robot_devices_live_counters(&dev, &bad, &refused);
    assert_int_equal(bad, 5u);
    assert_int_equal(refused, 2u);
    fclose(log);
    close(sv[0]);
    close(sv[1]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_live), cmocka_unit_test(test_live_counters_across_reopen)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
