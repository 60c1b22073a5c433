/*
 * test_robot_devices_counters - a backend counter that each open of its
 * device starts again, reported by the status as a total since the start
 * (robot_devices.h): the SocketCAN backend's stamps_unbelieved
 * (robot_devices_can_stamps_unbelieved, status key can_stamps_unbelieved).
 * White box, no processes: the CAN slot on an inherited SOCK_SEQPACKET
 * socket (--can-fd, as the e2e tests), closed and reopened by the slot;
 * the kernel's receive stamp is moved an hour back by a link-time wrap of
 * recvmsg (as test_socketcan does), so every frame's stamp is not
 * believed. The status used to have no such key; the backend's own count
 * goes back to 0 at each reopen. And the live sighting stream's refusals
 * (robot_devices_live_counters), which must not dip while a lost stream
 * waits for its close.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <linux/can.h>

#include <cmocka.h>

#include "hal/hal_clock_linux.h"
#include "robot_config.h"
#include "robot_devices.h"

ssize_t __real_recvmsg(int fd, struct msghdr *msg, int flags);
ssize_t __wrap_recvmsg(int fd, struct msghdr *msg, int flags);

/* added to every SCM_TIMESTAMP the kernel hands over [us] */
static int64_t stamp_shift_us;

ssize_t __wrap_recvmsg(int fd, struct msghdr *msg, int flags)
{
    const ssize_t n = __real_recvmsg(fd, msg, flags);
    if (n > 0 && stamp_shift_us != 0) {
        for (struct cmsghdr *c = CMSG_FIRSTHDR(msg); c != NULL; c = CMSG_NXTHDR(msg, c)) {
            if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMP) {
                struct timeval tv;
                memcpy(&tv, CMSG_DATA(c), sizeof tv);
                const int64_t us = (int64_t)tv.tv_sec * 1000000 + tv.tv_usec + stamp_shift_us;
                tv.tv_sec = (time_t)(us / 1000000);
                tv.tv_usec = (suseconds_t)(us % 1000000);
                memcpy(CMSG_DATA(c), &tv, sizeof tv);
            }
        }
    }
    return n;
}

static robot_config_t cfg;
static robot_devices_t dev;

/* n frames from the peer, each received through the slot's proxy (the
 * robot node's handle) */
static void frames_through_proxy(int peer, int n)
{
    for (int i = 0; i < n; ++i) {
        struct can_frame cf;
        memset(&cf, 0, sizeof cf);
        cf.can_id = 0x181;
        assert_int_equal(write(peer, &cf, sizeof cf), (ssize_t)sizeof cf);
        hal_can_frame_t f;
        assert_int_equal(hal_can_receive(&dev.can, &f, 1000000U), HAL_OK);
    }
}

/* The slots with one device only, the CAN bus (--can-fd) or the live
 * sighting stream (--sightings-fd), on a SOCK_SEQPACKET pair: sv[1] is the
 * robot's end (inherited), sv[0] the peer's. Returns the log (closed by the
 * caller). */
static FILE *open_one_device(int sv[2], robot_dev_t which)
{
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    robot_config_default(&cfg);
    cfg.laser_device[0] = '\0';
    cfg.can_interface[0] = '\0';
    cfg.gpio_chip[0] = '\0';
    cfg.camera_device[0] = '\0';
    cfg.camera_replay_log[0] = '\0';
    cfg.storage_dir[0] = '\0';
    cfg.fleet_key_file[0] = '\0';
    if (which == ROBOT_DEV_CAN) {
        cfg.can_fd = sv[1];
    } else {
        cfg.camera_live_fd = sv[1];
    }
    cfg.retry_period_s = 0.1;
    char msg[512];
    FILE *log = fopen("/dev/null", "w");
    assert_non_null(log);
    assert_int_equal(robot_devices_init(&dev, &cfg, hal_clock_linux(), log, 0, msg, sizeof msg), COSLAM_OK);
    robot_devices_open_all(&dev, 0U);
    return log;
}

static void can_stamps_unbelieved_across_reopen(void **state)
{
    (void)state;
    int sv[2];
    FILE *log = open_one_device(sv, ROBOT_DEV_CAN);
    assert_int_equal(dev.dev[ROBOT_DEV_CAN].state, ROBOT_DEV_UP);
    assert_true(robot_devices_can_stamps_unbelieved(&dev) == 0U);

    stamp_shift_us = -3600LL * 1000000; /* the wall clock stepped an hour ahead since */
    frames_through_proxy(sv[0], 3);
    assert_int_equal(dev.can_state.stamps_unbelieved, 3u);
    assert_true(robot_devices_can_stamps_unbelieved(&dev) == 3U);
    /* the bus goes down: closed */
    robot_devices_fail(&dev, ROBOT_DEV_CAN, HAL_E_IO, "test: lost", 1000U);
    assert_int_equal(dev.dev[ROBOT_DEV_CAN].state, ROBOT_DEV_DOWN);
    assert_true(robot_devices_can_stamps_unbelieved(&dev) == 3U); /* down: the total so far */
    /* reopened after the retry period, on the slot's opener */
    (void)robot_devices_service(&dev, 1000000U);
    assert_int_equal(robot_devices_wait_opens(&dev, 5000U), 0u);
    (void)robot_devices_service(&dev, 1000000U);
    assert_int_equal(dev.dev[ROBOT_DEV_CAN].state, ROBOT_DEV_UP);
    assert_int_equal(dev.dev[ROBOT_DEV_CAN].opens, 2u);
    assert_int_equal(dev.can_state.stamps_unbelieved, 0u); /* the backend's own count started again */
    assert_true(robot_devices_can_stamps_unbelieved(&dev) == 3U); /* not 0 */
    frames_through_proxy(sv[0], 2);
    assert_true(robot_devices_can_stamps_unbelieved(&dev) == 5U);

    /* the peer goes away: the slot is lost at once (closed by the next
     * service); the total neither drops meanwhile nor counts twice */
    close(sv[0]);
    hal_can_frame_t f;
    assert_int_equal(hal_can_receive(&dev.can, &f, 0U), HAL_E_CLOSED);
    assert_int_equal(dev.dev[ROBOT_DEV_CAN].lost, 1);
    assert_true(robot_devices_can_stamps_unbelieved(&dev) == 5U);
    (void)robot_devices_service(&dev, 2000000U);
    assert_int_equal(dev.dev[ROBOT_DEV_CAN].state, ROBOT_DEV_DOWN);
    assert_true(robot_devices_can_stamps_unbelieved(&dev) == 5U);
    robot_devices_close_all(&dev);
    assert_true(robot_devices_can_stamps_unbelieved(&dev) == 5U);
    stamp_shift_us = 0;
    fclose(log);
    close(sv[1]);
}

/* The live sighting stream (--sightings-fd) counts the datagrams it
 * refuses; the status reads them since the start. A stream found lost is
 * closed by the next service, and its counts are added to the totals at
 * that close: in between they must still be read (the status reported
 * that loop pass's counts without the open stream's, a dip of a report). */
static void live_counters_do_not_dip_while_lost(void **state)
{
    (void)state;
    int sv[2];
    FILE *log = open_one_device(sv, ROBOT_DEV_CAMERA);
    assert_int_equal(dev.dev[ROBOT_DEV_CAMERA].state, ROBOT_DEV_UP);
    uint32_t bad = 99U;
    uint32_t refused = 99U;
    robot_devices_live_counters(&dev, &bad, &refused);
    assert_int_equal(bad, 0u);
    assert_int_equal(refused, 0u);

    /* two datagrams without a T line: refused, counted */
    static const char junk[] = "this is not a frame\n";
    for (int i = 0; i < 2; ++i) {
        assert_int_equal(write(sv[0], junk, sizeof junk - 1U), (ssize_t)(sizeof junk - 1U));
    }
    sighting_frame_t fr;
    assert_int_equal(sighting_source_next_frame(&dev.sightings, &fr, 0U), HAL_E_TIMEOUT);
    robot_devices_live_counters(&dev, &bad, NULL);
    assert_int_equal(bad, 2u);

    /* the peer goes away: lost at once, closed by the next service */
    close(sv[0]);
    (void)sighting_source_next_frame(&dev.sightings, &fr, 0U);
    assert_int_equal(dev.dev[ROBOT_DEV_CAMERA].lost, 1);
    assert_int_equal(dev.dev[ROBOT_DEV_CAMERA].state, ROBOT_DEV_UP);
    robot_devices_live_counters(&dev, &bad, NULL);
    assert_int_equal(bad, 2u); /* 0 before: the open stream's counts were left out while lost */
    (void)robot_devices_service(&dev, 1000000U);
    assert_int_equal(dev.dev[ROBOT_DEV_CAMERA].state, ROBOT_DEV_DOWN);
    robot_devices_live_counters(&dev, &bad, NULL);
    assert_int_equal(bad, 2u); /* added once, at the close */
    robot_devices_close_all(&dev);
    robot_devices_live_counters(&dev, &bad, NULL);
    assert_int_equal(bad, 2u);
    fclose(log);
    close(sv[1]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(can_stamps_unbelieved_across_reopen),
                                       cmocka_unit_test(live_counters_do_not_dip_while_lost)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
