/*
 * The scan-to-scan odometry check (firmware/app odo_check.h) on scans ray
 * cast in this file: a room of wall segments, the laser 140 deg wide in
 * 0.35 deg steps with 1 cm Gaussian range noise (fixed seed). Proves:
 * registration recovers a known motion; correct odometry over many checks
 * raises nothing; wheels reporting five times the motion disagree;
 * a robot carried elsewhere is a mismatch or a disagreement at the next
 * check, the flag holds hold_s and clears; in a corridor without ends in
 * range, wrong odometry ALONG it is not judged (the documented limit) while
 * wrong odometry ACROSS it is; configuration bounds.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "app/odo_check.h"
#include "room_scan.h"


static room_t room_with_box(void)
{
    room_t r;
    memset(&r, 0, sizeof r);
    add_box(&r, -3.0, -2.0, 3.0, 2.0);
    add_box(&r, 1.0, 0.4, 1.6, 1.0);
    return r;
}

static void test_register_recovers_motion(void **state)
{
    (void)state;
    const room_t room = room_with_box();
    const odo_check_config_t cfg = odo_check_config_default();
    point2_t pts[N_RAYS];
    static odo_scan_t ref, cur;
    const pose2_t p0 = {-0.5, -0.3, 0.3};
    const pose2_t motion = {0.10, 0.02, 0.05};
    odo_check_thin(&cfg, pts, scan(&room, p0, pts), &ref);
    odo_check_thin(&cfg, pts, scan(&room, pose2_compose(p0, motion), pts), &cur);
    assert_true(ref.n >= 60U);
    pose2_t got;
    cov3_t info;
    size_t nc = 0;
    /* from no motion and from a guess 0.2 m, 5 deg off */
    const pose2_t guesses[2] = {{0.0, 0.0, 0.0}, {0.3, -0.1, 0.14}};
    for (int g = 0; g < 2; ++g) {
        const double f = odo_check_register(&cfg, &ref, &cur, guesses[g], &got, &info, &nc);
        assert_true(f > 0.9);
        assert_true(nc >= 50U);
        assert_true(fabs(got.x - motion.x) < 0.01);
        assert_true(fabs(got.y - motion.y) < 0.01);
        assert_true(fabs(got.theta - motion.theta) < 0.3 * DEG);
        assert_true(cov3_is_pd(info));
    }
}

/* Drive along a path; the odometry reports `scale` times each step, and at
 * step `jump_at` the robot is carried by `jump` (the wheels know nothing). */
typedef struct {
    uint32_t disagreements, mismatches, agreements, unjudged, drifts;
    int bad_at_end;
    int first_bad_step;
} drive_result_t;

static drive_result_t drive(const room_t *room, pose2_t start, pose2_t step, int n_steps, double scale, int jump_at,
                            pose2_t jump)
{
    static odo_check_t c;
    odo_check_config_t cfg = odo_check_config_default();
    cfg.hold_s = 3.0;
    assert_int_equal(odo_check_init(&c, &cfg), COSLAM_OK);
    point2_t pts[N_RAYS];
    pose2_t truth = start, odo = {0.0, 0.0, 0.0};
    drive_result_t r = {0, 0, 0, 0, 0, 0, -1};
    for (int k = 0; k < n_steps; ++k) {   /* 0.1 s steps, a scan each */
        truth = pose2_compose(truth, step);
        const pose2_t reported = {step.x * scale, step.y * scale, step.theta * scale};
        odo = pose2_compose(odo, reported);
        if (k == jump_at) {
            truth = pose2_compose(jump, truth);
        }
        (void)odo_check_on_scan(&c, (uint64_t)(k + 1) * 100000U, odo, pts, scan(room, truth, pts));
        if (c.bad && r.first_bad_step < 0) {
            r.first_bad_step = k;
        }
    }
    r.disagreements = c.disagreements;
    r.mismatches = c.mismatches;
    r.agreements = c.agreements;
    r.unjudged = c.unjudged;
    r.drifts = c.drifts;
    r.bad_at_end = c.bad;
    return r;
}

static void test_true_odometry_raises_nothing(void **state)
{
    (void)state;
    const room_t room = room_with_box();
    const pose2_t step = {0.02, 0.0, 0.03}; /* 0.2 m/s on a 0.3 rad/s arc */
    const drive_result_t r = drive(&room, (pose2_t){-1.5, -1.0, 0.2}, step, 200, 1.0, -1, (pose2_t){0, 0, 0});
    assert_int_equal(r.disagreements, 0);
    assert_int_equal(r.mismatches, 0);
    assert_int_equal(r.drifts, 0);
    assert_true(r.agreements >= 35U);
    assert_int_equal(r.first_bad_step, -1);
}

static void test_scaled_odometry_disagrees(void **state)
{
    (void)state;
    const room_t room = room_with_box();
    const pose2_t step = {0.02, 0.0, 0.0};
    const drive_result_t r = drive(&room, (pose2_t){-2.0, -1.0, 0.0}, step, 30, 5.0, -1, (pose2_t){0, 0, 0});
    assert_true(r.disagreements >= 4U);
    assert_true(r.first_bad_step >= 0 && r.first_bad_step <= 5);
    assert_true(r.bad_at_end);
}

/* Wheels reporting twice the motion: one check's allowance hides it
 * (0.1 m against an sd of 0.04 m), the drift test adds it up. */
static void test_doubled_odometry_is_a_drift(void **state)
{
    (void)state;
    const room_t room = room_with_box();
    const pose2_t step = {0.02, 0.0, 0.0};
    /* facing the east wall 3 m ahead: the motion is constrained */
    const drive_result_t r = drive(&room, (pose2_t){0.0, -1.0, 0.0}, step, 60, 2.0, -1, (pose2_t){0, 0, 0});
    assert_true(r.drifts >= 1U);
    assert_true(r.disagreements >= 1U);
    assert_true(r.first_bad_step >= 10 && r.first_bad_step <= 50);
}

static void test_carried_robot_is_seen_and_the_flag_clears(void **state)
{
    (void)state;
    const room_t room = room_with_box();
    const pose2_t step = {0.02, 0.0, 0.0};
    /* carried about 2 m and turned 100 deg at step 20 (2.1 s) */
    const drive_result_t r = drive(&room, (pose2_t){-2.0, -1.2, 0.5}, step, 80, 1.0, 20, (pose2_t){-0.5, 1.5, 100.0 * DEG});
    assert_true(r.mismatches + r.disagreements >= 1U);
    assert_true(r.first_bad_step >= 20 && r.first_bad_step <= 25);
    assert_false(r.bad_at_end); /* hold 3 s, the run goes on 5.9 s */
}

/* Carried from a closet into a hall with the wheels still: every new return
 * lies beyond the old ones, so the newest scan has no point the reference
 * could have seen and one way alone judges nothing (before the check went
 * both ways, this was not judged); the closet's walls, which the hall scan
 * reaches past, are judged the other way: a mismatch. */
static void test_carried_from_a_closet_into_a_hall(void **state)
{
    (void)state;
    room_t room;
    memset(&room, 0, sizeof room);
    add_box(&room, -0.6, -0.6, 0.6, 0.6);
    add_box(&room, 17.0, -3.0, 23.0, 3.0);
    odo_check_t c;
    const odo_check_config_t cfg = odo_check_config_default();
    assert_int_equal(odo_check_init(&c, &cfg), COSLAM_OK);
    point2_t pts[N_RAYS];
    const pose2_t odo = {0.0, 0.0, 0.0};
    (void)odo_check_on_scan(&c, 100000U, odo, pts, scan(&room, (pose2_t){0.0, 0.0, 0.0}, pts));
    assert_int_equal(odo_check_on_scan(&c, 600000U, odo, pts, scan(&room, (pose2_t){20.0, 0.0, 0.0}, pts)), 1);
    assert_int_equal(c.mismatches, 1);
    assert_int_equal(c.unjudged, 0);
    assert_true(c.bad);
    assert_true(c.last_inlier_frac < cfg.min_inlier_frac);
}

static void test_corridor_along_not_judged_across_judged(void **state)
{
    (void)state;
    room_t corr;
    memset(&corr, 0, sizeof corr);
    corr.s[0] = (seg_t){{-50.0, -1.0}, {50.0, -1.0}};
    corr.s[1] = (seg_t){{-50.0, 1.0}, {50.0, 1.0}};
    corr.n = 2;
    /* along: the wheels report 3x, the walls cannot tell */
    drive_result_t r = drive(&corr, (pose2_t){0.0, 0.0, 0.0}, (pose2_t){0.02, 0.0, 0.0}, 40, 3.0, -1, (pose2_t){0, 0, 0});
    assert_int_equal(r.disagreements, 0);
    assert_int_equal(r.mismatches, 0);
    /* across: a sideways slide reported 5x is seen */
    r = drive(&corr, (pose2_t){0.0, -0.5, 0.0}, (pose2_t){0.0, 0.01, 0.0}, 40, 5.0, -1, (pose2_t){0, 0, 0});
    assert_true(r.disagreements >= 3U);
}

static void test_config_bounds(void **state)
{
    (void)state;
    static odo_check_t c;
    odo_check_config_t cfg = odo_check_config_default();
    assert_int_equal(odo_check_init(&c, &cfg), COSLAM_OK);
    assert_int_equal(odo_check_init(NULL, &cfg), COSLAM_E_ARG);
    odo_check_config_t bad = cfg;
    bad.period_s = 0.0;
    assert_int_equal(odo_check_init(&c, &bad), COSLAM_E_ARG);
    bad = cfg;
    bad.min_inlier_frac = 1.5;
    assert_int_equal(odo_check_init(&c, &bad), COSLAM_E_ARG);
    bad = cfg;
    bad.chi2_max = NAN;
    assert_int_equal(odo_check_init(&c, &bad), COSLAM_E_ARG);
    bad = cfg;
    bad.min_points = 2;
    assert_int_equal(odo_check_init(&c, &bad), COSLAM_E_ARG);
    /* a non-finite odometry pose or an empty scan is ignored, not judged */
    const pose2_t nan_pose = {NAN, 0.0, 0.0};
    assert_int_equal(odo_check_on_scan(&c, 100000U, nan_pose, NULL, 0U), 0);
    assert_int_equal(odo_check_on_scan(&c, 200000U, (pose2_t){0, 0, 0}, NULL, 0U), 0);
    assert_int_equal(odo_check_on_scan(&c, 800000U, (pose2_t){0, 0, 0}, NULL, 0U), 0);
    assert_int_equal(c.unjudged, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_register_recovers_motion),
        cmocka_unit_test(test_true_odometry_raises_nothing),
        cmocka_unit_test(test_scaled_odometry_disagrees),
        cmocka_unit_test(test_doubled_odometry_is_a_drift),
        cmocka_unit_test(test_carried_robot_is_seen_and_the_flag_clears),
        cmocka_unit_test(test_carried_from_a_closet_into_a_hall),
        cmocka_unit_test(test_corridor_along_not_judged_across_judged),
        cmocka_unit_test(test_config_bounds),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
