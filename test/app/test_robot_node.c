/*
 * test_robot_node - the robot node (app/robot_node.h) against fake HALs:
 * what happens to the robot sightings of a camera frame. A sighting with
 * an id no partner has (outside the team, or this robot's own) or one the
 * meeting refuses (range not finite and positive, bearing not finite) is
 * counted in robot_sightings_refused; it used to be skipped without a
 * trace. A good one reaches the meeting and is not counted.
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

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(refused_robot_sightings_are_counted),
                                       cmocka_unit_test(no_drives_configured_is_not_a_fault)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
