/*
 * The health monitor's landmark measures (firmware/app health.h) on an
 * EKF-SLAM map built by hand: which landmarks it expects to see. Proves: a
 * landmark near the border of the field of view (inside the sensor's 50 deg
 * but outside the filter's visibility margin) is not expected; one behind a
 * wall of the occupancy grid is not expected, and is when no grid is given;
 * so a frame that sees only the landmark in plain view misses nothing with
 * the grid and half of what it expects without.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "app/health.h"
#include "app/slam_filter.h"
#include "coslam/occ_grid.h"

#define DEG (COSLAM_PI / 180.0)

static slam_filter_t g_f;
static health_t g_h;
static occ_grid_t g_grid;

/* A landmark of class sig at robot-frame (x, y), well known. */
static void add(double x, double y, uint8_t sig)
{
    ekfslam_meta_t meta;
    memset(&meta, 0, sizeof meta);
    meta.signature = sig;
    meta.exist = 1.0f;
    meta.n_obs = 10;
    const cov2_t cov = {1e-4, 0.0, 1e-4};
    assert_int_equal(ekfslam_add_landmark_body(&g_f.u.ekf, (point2_t){x, y}, cov, &meta), COSLAM_OK);
}

/* A wall segment x = 2 m, y in [0.4, 1.0], seen four times from the origin. */
static void build_wall(void)
{
    assert_int_equal(occ_grid_init(&g_grid, NULL, -0.5 * COSLAM_GRID_CELLS_X * OCC_GRID_CELL_M,
                                   -0.5 * COSLAM_GRID_CELLS_Y * OCC_GRID_CELL_M),
                     COSLAM_OK);
    double r[64], a[64];
    size_t n = 0;
    for (double y = 0.4; y <= 1.0 + 1e-9; y += 0.02) {
        a[n] = atan2(y, 2.0);
        r[n] = hypot(2.0, y);
        ++n;
    }
    for (int k = 0; k < 4; ++k) {
        (void)occ_grid_integrate_scan(&g_grid, (pose2_t){0.0, 0.0, 0.0}, r, a, n, NULL);
    }
}

static int setup(void **state)
{
    (void)state;
    slam_filter_config_t cfg = slam_filter_config_default();
    cfg.kind = SLAM_FILTER_EKF;
    assert_int_equal(slam_filter_init(&g_f, &cfg, (pose2_t){0.0, 0.0, 0.0}), COSLAM_OK);
    const health_config_t hc = health_config_default();
    assert_int_equal(health_init(&g_h, &hc), COSLAM_OK);
    add(3.0, 0.0, 1);                                         /* 0: plain view */
    add(3.0 * cos(24.0 * DEG), 3.0 * sin(24.0 * DEG), 2);     /* 1: inside 25 deg, outside 0.9 x 25 */
    add(3.0, 1.0, 3);                                         /* 2: 18 deg, behind the wall */
    build_wall();
    return 0;
}

static void test_expected_landmarks(void **state)
{
    (void)state;
    const slam_params_t *sp = slam_filter_params(&g_f);
    assert_true(fabs(24.0 * DEG) <= 0.5 * sp->sensor_fov_rad); /* the premise: in the raw field */
    health_before_update(&g_h, &g_f, &g_grid);
    assert_int_equal(g_h.n_in_view, 1);
    assert_int_equal(g_h.in_view[0], 0);
    health_before_update(&g_h, &g_f, NULL); /* no grid: the landmark behind the wall is expected */
    assert_int_equal(g_h.n_in_view, 2);
    assert_int_equal(g_h.in_view[0], 0);
    assert_int_equal(g_h.in_view[1], 2);
}

/* One frame that sees the landmark in plain view: nothing missed with the
 * grid; without it, the one behind the wall counts as missed. */
static void test_missed_fraction(void **state)
{
    (void)state;
    const sighting_t z = {3.0, 0.0, 1};
    health_before_update(&g_h, &g_f, &g_grid);
    assert_int_equal(slam_filter_update(&g_f, &z, 1), COSLAM_OK);
    health_after_update(&g_h, &g_f, &z, 1);
    assert_true(g_h.missed_frac == 0.0);
    health_before_update(&g_h, &g_f, NULL);
    assert_int_equal(slam_filter_update(&g_f, &z, 1), COSLAM_OK);
    health_after_update(&g_h, &g_f, &z, 1);
    /* the window: frame 1 expected 1, missed 0; frame 2 expected 2, missed 1 */
    assert_true(fabs(g_h.missed_frac - 1.0 / 3.0) < 1e-12);
}

/* A sighting the association held back (an ambiguous revisit; the
 * filter's scratch written by hand, as ekfslam_update leaves it): neither
 * eligible nor unassociated, and the landmark it was held against counts
 * as seen. The same frame with the sighting left unpaired instead: one
 * unassociated, one missed. */
static void test_held_sighting_counts_as_neither(void **state)
{
    (void)state;
    const sighting_t z = {3.0, 0.0, 1};
    ekfslam_scratch_t *sc = &g_f.u.ekf.scratch;
    for (int held = 1; held >= 0; --held) {
        const health_config_t hc = health_config_default();
        assert_int_equal(health_init(&g_h, &hc), COSLAM_OK);
        health_before_update(&g_h, &g_f, &g_grid);
        assert_int_equal(g_h.n_in_view, 1);
        memset(sc->matched, 0, sizeof sc->matched);
        sc->assign[0] = -1;
        sc->best[0] = 0;
        sc->held[0] = (uint8_t)held;
        g_f.u.ekf.ctr.updates++; /* the update that left this scratch */
        health_after_update(&g_h, &g_f, &z, 1);
        const health_frame_t *fr = &g_h.frame[0];
        assert_int_equal(fr->n_eligible, held ? 0 : 1);
        assert_int_equal(fr->n_unassoc, held ? 0 : 1);
        assert_int_equal(fr->n_expected, 1);
        assert_int_equal(fr->n_missed, held ? 0 : 1);
    }
}

/* A frame that cannot be held behind an EKF-SLAM merge's held inputs
 * (the queue is full) makes them apply first: here a held prediction that
 * turns the robot 90 deg left, then SLAM_FILTER_HELD_FRAMES empty updates.
 * The monitor must judge the frame against the state the update applies
 * to (robot_node's order: prepare, look, apply). After the turn nothing is
 * in view, so the frame's sighting of class 1 straight ahead is neither
 * expected nor missed. Judged on the state before the turn (the order
 * before slam_filter_update_prepare), landmark 0 was expected and missed. */
static void test_judged_on_the_state_the_update_applies_to(void **state)
{
    (void)state;
    slam_filter_t *f = &g_f;
    memset(f->held, 0, sizeof f->held);
    f->held[0].is_update = 0U;
    f->held[0].u = (odo_increment_t){0.0, 0.0, 0.5 * COSLAM_PI};
    for (uint16_t k = 1; k <= SLAM_FILTER_HELD_FRAMES; ++k) {
        f->held[k].is_update = 1U; /* no sightings */
    }
    f->n_held = (uint16_t)(SLAM_FILTER_HELD_FRAMES + 1U);
    f->held_next = 0U;
    f->n_held_z = 0U;
    f->n_held_frames = (uint16_t)SLAM_FILTER_HELD_FRAMES;
    const uint32_t updates0 = f->u.ekf.ctr.updates;
    const sighting_t z = {3.0, 0.0, 1};

    assert_int_equal(slam_filter_update_prepare(f, 1), 0); /* does not fit: the held inputs apply */
    assert_int_equal(f->n_held, 0);
    assert_int_equal(f->holds_forced, 1);
    assert_int_equal(f->u.ekf.ctr.updates, updates0 + SLAM_FILTER_HELD_FRAMES);
    health_before_update(&g_h, f, &g_grid);
    assert_int_equal(g_h.n_in_view, 0);
    assert_int_equal(slam_filter_update_apply(f, &z, 1), COSLAM_OK);
    assert_int_equal(f->u.ekf.ctr.updates, updates0 + SLAM_FILTER_HELD_FRAMES + 1U); /* exactly this frame */
    health_after_update(&g_h, f, &z, 1);
    const health_frame_t *fr = &g_h.frame[0];
    assert_int_equal(fr->n_expected, 0);
    assert_int_equal(fr->n_missed, 0);
    assert_int_equal(fr->n_eligible, 0);
}

/* The monitor checks its own precondition: a frame whose update is not
 * the one it looked at is not judged but counted. The order before
 * slam_filter_update_prepare (look, then slam_filter_update, which applied
 * the held inputs' 16 updates first) and an update nobody looked at. */
static void test_a_frame_of_another_state_is_not_judged(void **state)
{
    (void)state;
    slam_filter_t *f = &g_f;
    memset(f->held, 0, sizeof f->held);
    f->held[0].u = (odo_increment_t){0.0, 0.0, 0.5 * COSLAM_PI};
    for (uint16_t k = 1; k <= SLAM_FILTER_HELD_FRAMES; ++k) {
        f->held[k].is_update = 1U;
    }
    f->n_held = (uint16_t)(SLAM_FILTER_HELD_FRAMES + 1U);
    f->held_next = 0U;
    f->n_held_z = 0U;
    f->n_held_frames = (uint16_t)SLAM_FILTER_HELD_FRAMES;
    const sighting_t z = {3.0, 0.0, 1};
    health_before_update(&g_h, f, &g_grid);
    assert_int_equal(g_h.n_in_view, 1);
    assert_int_equal(slam_filter_update(f, &z, 1), COSLAM_OK);
    health_after_update(&g_h, f, &z, 1);
    assert_int_equal(g_h.unjudged_frames, 1);
    assert_int_equal(g_h.count, 0); /* nothing entered the window */
    assert_int_equal(slam_filter_update(f, &z, 1), COSLAM_OK);
    health_after_update(&g_h, f, &z, 1); /* not looked at */
    assert_int_equal(g_h.unjudged_frames, 2);
    assert_int_equal(g_h.count, 0);
    health_before_update(&g_h, f, &g_grid); /* the right order again: judged */
    assert_int_equal(slam_filter_update(f, &z, 1), COSLAM_OK);
    health_after_update(&g_h, f, &z, 1);
    assert_int_equal(g_h.unjudged_frames, 2);
    assert_int_equal(g_h.count, 1);
}

/* A frame that fits behind the held inputs is held: prepare says so and
 * changes nothing, the apply holds it. */
static void test_prepare_of_a_held_frame_changes_nothing(void **state)
{
    (void)state;
    slam_filter_t *f = &g_f;
    memset(f->held, 0, sizeof f->held);
    f->held[0].u = (odo_increment_t){0.0, 0.0, 0.5 * COSLAM_PI};
    f->n_held = 1U;
    f->held_next = 0U;
    f->n_held_z = 0U;
    f->n_held_frames = 0U;
    static ekfslam_t before;
    before = f->u.ekf;
    const uint32_t inputs_held = f->inputs_held;
    const sighting_t z = {3.0, 0.0, 1};
    assert_int_equal(slam_filter_update_prepare(f, 1), 1);
    assert_int_equal(f->n_held, 1);
    assert_int_equal(f->holds_forced, 0);
    assert_int_equal(f->inputs_held, inputs_held);
    assert_memory_equal(f->u.ekf.x, before.x, sizeof before.x); /* the state untouched */
    assert_int_equal(f->u.ekf.ctr.updates, before.ctr.updates);
    assert_int_equal(f->u.ekf.n_lm, before.n_lm);
    assert_int_equal(slam_filter_update_apply(f, &z, 1), COSLAM_E_MERGE_PENDING);
    assert_int_equal(f->n_held, 2);
    assert_int_equal(f->n_held_frames, 1);
    assert_int_equal(f->inputs_held, inputs_held + 1U);
    assert_int_equal(f->u.ekf.ctr.updates, before.ctr.updates);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_expected_landmarks, setup),
        cmocka_unit_test_setup(test_missed_fraction, setup),
        cmocka_unit_test_setup(test_held_sighting_counts_as_neither, setup),
        cmocka_unit_test_setup(test_judged_on_the_state_the_update_applies_to, setup),
        cmocka_unit_test_setup(test_prepare_of_a_held_frame_changes_nothing, setup),
        cmocka_unit_test_setup(test_a_frame_of_another_state_is_not_judged, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
