/*
 * test_robot_live - the live sighting stream of coslam-robot
 * (robot_live_open, robot_sightings.h): the e2e device server's camera
 * stand-in over an inherited SOCK_SEQPACKET socket (docs/e2e.md).
 * Frames with their stamps and marker classes, robot sightings, the newest
 * of several queued frames, refused datagrams, an empty frame, the peer's
 * close, and the inherited fd staying open after close (it is dup'ed).
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

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_live)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
