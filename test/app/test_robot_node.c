/*
 * test_robot_node - the robot node (app/robot_node.h) against fake HALs:
 * what happens to the robot sightings of a camera frame. A sighting with
 * an id no partner has (outside the team, or this robot's own) or one the
 * meeting refuses (range not finite and positive, bearing not finite) is
 * counted in robot_sightings_refused; it used to be skipped without a
 * trace. A good one reaches the meeting and is not counted. And the laser
 * driver's search count, which a lost laser's driver reset starts again,
 * as a total across resets (robot_node_laser_rx_search_bytes).
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "app/robot_node.h"
#include "hal/hal_can.h"
#include "hal/hal_clock.h"
#include "hal/hal_gpio.h"
#include "hal/hal_link.h"
#include "hal/hal_serial.h"

/* a clock that moves 10 ms a reading */
static uint64_t fake_now_us = 1000000u;

static hal_status_t fake_now(hal_clock_t *c, uint64_t *now_us)
{
    (void)c;
    fake_now_us += 10000u;
    *now_us = fake_now_us;
    return HAL_OK;
}

static const hal_clock_ops_t fake_clock_ops = {.now_us = fake_now};
static hal_clock_t fake_clock = {&fake_clock_ops, NULL};

/* a sighting source that hands out `frame` once */
static sighting_frame_t frame;
static int frame_ready;

static hal_status_t fake_next_frame(sighting_source_t *src, sighting_frame_t *out, uint32_t timeout_us)
{
    (void)src;
    (void)timeout_us;
    if (!frame_ready) {
        return HAL_E_TIMEOUT;
    }
    frame_ready = 0;
    *out = frame;
    return HAL_OK;
}

static const sighting_source_ops_t fake_source_ops = {fake_next_frame};
static sighting_source_t fake_source = {&fake_source_ops, NULL};

static robot_node_t node;

static void add_robot(uint8_t id, double range_m, double bearing_rad)
{
    robot_seen_t *r = &frame.robots[frame.n_robots++];
    r->robot_id = id;
    r->range_m = range_m;
    r->bearing_rad = bearing_rad;
}

static void refused_robot_sightings_are_counted(void **state)
{
    (void)state;
    static const hal_serial_ops_t no_serial = {0};
    static hal_serial_t serial = {&no_serial, NULL};
    robot_node_io_t io = {&fake_clock, &serial, hal_can_null(), hal_gpio_null(), hal_link_null(), &fake_source};
    /* robot 1 of a team of 3 (ids 0 .. 2); COSLAM_MAX_ROBOTS is larger */
    robot_node_config_t cfg = robot_node_config_default(1, 3);
    cfg.laser_optional = 1;
    cfg.gpio_optional = 1;
    cfg.filter.n_particles = 20;
    assert_true(COSLAM_MAX_ROBOTS > 3);
    assert_int_equal(robot_node_init(&node, &cfg, &io), COSLAM_OK);
    (void)robot_node_step(&node);
    assert_int_equal(robot_node_counters(&node)->robot_sightings_refused, 0);

    memset(&frame, 0, sizeof frame);
    frame.stamp_us = fake_now_us;
    add_robot(3, 1.0, 0.1);       /* id = n_robots: outside the team */
    add_robot(1, 1.0, 0.1);       /* this robot's own id */
    add_robot(2, NAN, 0.1);       /* the meeting refuses these (COSLAM_E_ARG) */
    add_robot(2, -1.0, 0.1);
    add_robot(2, 1.0, INFINITY);
    add_robot(0, 1.5, -0.2);      /* a good one */
    frame_ready = 1;
    (void)robot_node_step(&node);
    assert_int_equal(robot_node_counters(&node)->frames, 1);
    assert_int_equal(robot_node_counters(&node)->robot_sightings_refused, 5);
    /* the good one reached the meeting, the refused ones did not */
    meeting_sighting_t s;
    assert_int_equal(meeting_last_sighting(&node.meeting, 0, &s), COSLAM_OK);
    assert_true(s.range_m == 1.5);
    assert_int_equal(meeting_last_sighting(&node.meeting, 2, &s), COSLAM_E_EMPTY);

    /* a frame of good sightings only: nothing more counted */
    memset(&frame, 0, sizeof frame);
    frame.stamp_us = fake_now_us;
    add_robot(2, 2.0, 0.3);
    frame_ready = 1;
    (void)robot_node_step(&node);
    assert_int_equal(robot_node_counters(&node)->robot_sightings_refused, 5);
    assert_int_equal(meeting_last_sighting(&node.meeting, 2, &s), COSLAM_OK);
}

/* A missing bus is a drive fault only where drives are configured: with
 * drive_absent (coslam-robot without [can] interface) the node counts
 * none over several retry periods, and runs its sightings; without it the
 * same missing bus (the null CAN) is one fault, counted once. */
static void no_drives_configured_is_not_a_fault(void **state)
{
    (void)state;
    static const hal_serial_ops_t no_serial = {0};
    static hal_serial_t serial = {&no_serial, NULL};
    robot_node_io_t io = {&fake_clock, &serial, hal_can_null(), hal_gpio_null(), hal_link_null(), &fake_source};
    for (int absent = 0; absent <= 1; ++absent) {
        robot_node_config_t cfg = robot_node_config_default(1, 3);
        cfg.laser_optional = 1;
        cfg.gpio_optional = 1;
        cfg.filter.n_particles = 20;
        cfg.retry_period_us = 100000U;
        cfg.drive_absent = (uint8_t)absent;
        assert_int_equal(robot_node_init(&node, &cfg, &io), COSLAM_OK);
        for (int k = 0; k < 100; ++k) { /* 1 s: ten retry periods */
            (void)robot_node_step(&node);
        }
        memset(&frame, 0, sizeof frame);
        frame.stamp_us = fake_now_us;
        add_robot(0, 1.5, -0.2);
        frame_ready = 1;
        (void)robot_node_step(&node);
        const robot_node_counters_t *c = robot_node_counters(&node);
        assert_int_equal(c->frames, 1); /* the camera side runs either way */
        if (absent) {
            assert_int_equal(c->drive_faults, 0);
            assert_int_equal(c->drive_errors, 0);
            assert_int_equal(robot_node_state(&node), ROBOT_NODE_DRIVE_UP);
        } else {
            assert_int_equal(c->drive_faults + c->drive_errors, 1); /* the missing bus, once */
        }
    }
}

/* A URG that answers the connect (SCIP2.0, PP, MD) at once and then sends
 * no scan: the node connects, the laser goes silent, the node counts it
 * lost after laser_lost_us and resets its driver. */
static uint8_t urg_out[1024];
static size_t urg_out_len;
static int urg_mute; /* 1: no replies */

static void urg_queue(const char *text)
{
    const size_t n = strlen(text);
    assert_true(urg_out_len + n <= sizeof urg_out);
    memcpy(urg_out + urg_out_len, text, n);
    urg_out_len += n;
}

static hal_status_t urg_write(hal_serial_t *dev, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    (void)dev;
    (void)timeout_us;
    char cmd[32];
    const size_t n = len < sizeof cmd - 1U ? len : sizeof cmd - 1U;
    memcpy(cmd, data, n);
    cmd[n] = '\0';
    if (urg_mute) {
        return HAL_OK;
    }
    if (strncmp(cmd, "SCIP2.0", 7) == 0) {
        urg_queue("SCIP2.0\n0\n\n");
    } else if (strncmp(cmd, "PP", 2) == 0) { /* the URG-04LX's published reply */
        urg_queue("PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nDMIN:20;4\nDMAX:5600;_\nARES:1024;\\\n"
                  "AMIN:44;7\nAMAX:725;o\nAFRT:384;6\nSCAN:600;e\n\n");
    } else if (strncmp(cmd, "MD", 2) == 0 || strncmp(cmd, "QT", 2) == 0) {
        urg_queue(cmd); /* the echo (with its LF), status 00 */
        urg_queue("00P\n\n");
    }
    return HAL_OK;
}

static hal_status_t urg_read(hal_serial_t *dev, uint8_t *buf, size_t cap, size_t *n_read, uint32_t timeout_us)
{
    (void)dev;
    (void)timeout_us;
    const size_t n = urg_out_len < cap ? urg_out_len : cap;
    memcpy(buf, urg_out, n);
    memmove(urg_out, urg_out + n, urg_out_len - n);
    urg_out_len -= n;
    *n_read = n;
    return n > 0U ? HAL_OK : HAL_E_TIMEOUT;
}

static hal_status_t urg_flush(hal_serial_t *dev)
{
    (void)dev;
    urg_out_len = 0U;
    return HAL_OK;
}

/* The laser driver's search count (urg_scip2_rx_search_bytes) starts again
 * at every reset of the driver (a lost laser) and wraps at 2^32; the
 * status line's urg_rx_search_bytes (robot_node_laser_rx_search_bytes) is
 * the total since the start, so it never goes back. */
static void laser_search_bytes_survive_a_lost_laser(void **state)
{
    (void)state;
    static const hal_serial_ops_t urg_ops = {NULL, urg_write, urg_read, urg_flush, NULL};
    static hal_serial_t serial = {&urg_ops, NULL};
    urg_out_len = 0U;
    urg_mute = 0;
    robot_node_io_t io = {&fake_clock, &serial, hal_can_null(), hal_gpio_null(), hal_link_null(), &fake_source};
    robot_node_config_t cfg = robot_node_config_default(1, 3);
    cfg.laser_optional = 1;
    cfg.gpio_optional = 1;
    cfg.filter.n_particles = 20;
    assert_int_equal(robot_node_init(&node, &cfg, &io), COSLAM_OK);
    for (int k = 0; k < 20 && !robot_node_laser_up(&node); ++k) {
        (void)robot_node_step(&node);
    }
    assert_true(robot_node_laser_up(&node));
    const uint32_t connect = urg_scip2_rx_search_bytes(&node.urg);
    assert_true(connect > 0U); /* the three replies were searched */
    assert_true(robot_node_laser_rx_search_bytes(&node) == connect);

    /* no scan comes: lost after laser_lost_us (2 s; the clock moves 10 ms
     * a reading), the driver reset and the connect begun again, unanswered */
    urg_mute = 1;
    uint32_t before = 0U;
    for (int k = 0; k < 1000 && robot_node_counters(&node)->laser_lost == 0U; ++k) {
        before = urg_scip2_rx_search_bytes(&node.urg);
        (void)robot_node_step(&node);
    }
    assert_int_equal(robot_node_counters(&node)->laser_lost, 1);
    assert_true(before >= connect);
    assert_int_equal(urg_scip2_rx_search_bytes(&node.urg), 0); /* the driver's own count started again */
    assert_true(robot_node_laser_rx_search_bytes(&node) == before); /* the total did not */
    /* the laser answers again: connected at a retry */
    urg_mute = 0;
    for (int k = 0; k < 1000 && !robot_node_laser_up(&node); ++k) {
        (void)robot_node_step(&node);
    }
    assert_true(robot_node_laser_up(&node));
    const uint64_t total = robot_node_laser_rx_search_bytes(&node);
    assert_true(total == (uint64_t)before + urg_scip2_rx_search_bytes(&node.urg));
    assert_true(total >= 2U * (uint64_t)connect);

    /* white box: the driver's count wraps within a session (2^32 bytes,
     * days of scans); the total goes on */
    const uint32_t near = UINT32_MAX - 3U;
    node.urg.rx_searched = near;
    node.laser_rx_search_seen = near;
    const uint64_t at = robot_node_laser_rx_search_bytes(&node);
    urg_queue("MD0044072501000\n99b\n"); /* a scan's start: searched, not whole */
    (void)robot_node_step(&node);
    const uint32_t wrapped = urg_scip2_rx_search_bytes(&node.urg);
    assert_true(wrapped < near);
    assert_true(robot_node_laser_rx_search_bytes(&node) == at + (uint32_t)(wrapped - near));
    assert_true(robot_node_laser_rx_search_bytes(&node) > at);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(refused_robot_sightings_are_counted),
                                       cmocka_unit_test(no_drives_configured_is_not_a_fault),
                                       cmocka_unit_test(laser_search_bytes_survive_a_lost_laser)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
