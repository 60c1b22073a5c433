/*
 * The robot's behaviour (firmware/app behaviour.h) in closed loop with a
 * tiny kinematic world in this file: walls as segments, a laser scan ray
 * cast from the laser's pose (140 deg, 0.35 deg steps), the body velocity
 * integrated exactly. Proves: straight ahead without obstacles; a right
 * turn on the spot parallel to a wall across the path, then along it
 * without touching it; a sideways slide away from a parallel wall inside
 * the corridor; the guard refusing a slide into a post beside the robot,
 * then turning away; the way back around a box to the rendezvous point;
 * SEEK -> FACE -> SEEK on a peer in and out of view; leaving the
 * rendezvous once merged and acknowledged, or after linger_s; a quarter
 * turn right after a bumper hit; no translation without a scan; config checks.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "app/behaviour.h"
#include "coslam/motion.h"

#define DEG (COSLAM_PI / 180.0)
#define N_RAYS 401
#define MAX_SEGS 16

typedef struct {
    double x0, y0, x1, y1;
} seg_t;

typedef struct {
    seg_t seg[MAX_SEGS];
    int n;
    double range[N_RAYS];
    double angle[N_RAYS];
    obstacle_params_t op;
    pose2_t laser;
} world_t;

static world_t g_w;
static point2_t g_pts[N_RAYS + 64];
static size_t g_npts;

/* The scan's valid readings as robot-frame points, as the node provides them. */
static void scan_points(const double *r, const double *a, size_t n, pose2_t laser)
{
    g_npts = 0;
    for (size_t i = 0; i < n; ++i) {
        if (isfinite(r[i]) && r[i] > 0.0) {
            g_pts[g_npts++] = pose2_apply(laser, (point2_t){r[i] * cos(a[i]), r[i] * sin(a[i])});
        }
    }
}
static uint64_t g_scan_stamp = UINT64_MAX;
static double g_scan_heading;

static void world_reset(void)
{
    g_scan_stamp = UINT64_MAX;
    memset(&g_w, 0, sizeof g_w);
    obstacle_params_default(&g_w.op);
    g_w.laser = (pose2_t){0.12, 0.0, 0.0};
}

static void add_seg(double x0, double y0, double x1, double y1)
{
    g_w.seg[g_w.n++] = (seg_t){x0, y0, x1, y1};
}

static void add_box(double cx, double cy, double hx, double hy)
{
    add_seg(cx - hx, cy - hy, cx + hx, cy - hy);
    add_seg(cx + hx, cy - hy, cx + hx, cy + hy);
    add_seg(cx + hx, cy + hy, cx - hx, cy + hy);
    add_seg(cx - hx, cy + hy, cx - hx, cy - hy);
}

static double ray(double ox, double oy, double dx, double dy)
{
    double best = INFINITY;
    for (int i = 0; i < g_w.n; ++i) {
        const seg_t *s = &g_w.seg[i];
        const double ex = s->x1 - s->x0, ey = s->y1 - s->y0;
        const double den = dx * ey - dy * ex;
        if (fabs(den) < 1e-12) continue;
        const double wx = s->x0 - ox, wy = s->y0 - oy;
        const double t = (wx * ey - wy * ex) / den;
        const double u = (wx * dy - wy * dx) / den;
        if (t >= 0.0 && u >= 0.0 && u <= 1.0 && t < best) best = t;
    }
    return best <= 5.6 ? best : INFINITY;
}

static double dist_to_walls(double x, double y)
{
    double best = INFINITY;
    for (int i = 0; i < g_w.n; ++i) {
        const seg_t *s = &g_w.seg[i];
        const double ex = s->x1 - s->x0, ey = s->y1 - s->y0;
        double t = ((x - s->x0) * ex + (y - s->y0) * ey) / (ex * ex + ey * ey);
        t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
        best = fmin(best, hypot(s->x0 + t * ex - x, s->y0 + t * ey - y));
    }
    return best;
}

static void scan_from(pose2_t robot)
{
    const pose2_t l = pose2_compose(robot, g_w.laser);
    for (int i = 0; i < N_RAYS; ++i) {
        const double a = (-70.0 + 140.0 * i / (N_RAYS - 1)) * DEG;
        g_w.angle[i] = a;
        g_w.range[i] = ray(l.x, l.y, cos(l.theta + a), sin(l.theta + a));
    }
}

/* The inputs at now_us; the laser delivers a new scan every 100 ms (taken at
 * the pose of that moment), as the URG does. */

static behaviour_input_t input_at(uint64_t now_us, pose2_t pose)
{
    behaviour_input_t in;
    memset(&in, 0, sizeof in);
    in.now_us = now_us;
    in.odo_pose = pose;
    in.map_pose = pose;
    const uint64_t stamp = now_us / 100000U * 100000U;
    if (stamp != g_scan_stamp) {
        g_scan_stamp = stamp;
        g_scan_heading = pose.theta;
        scan_from(pose);
        scan_points(g_w.range, g_w.angle, N_RAYS, g_w.laser);
    }
    in.scan_ok = 1;
    in.scan.params = &g_w.op;
    in.scan.laser_in_robot = g_w.laser;
    in.scan.range_m = g_w.range;
    in.scan.angle_rad = g_w.angle;
    in.scan.n = N_RAYS;
    in.scan.stamp_us = g_scan_stamp;
    in.scan.heading_rad = g_scan_heading;
    in.scan.points_m = g_pts;
    in.scan.n_points = g_npts;
    return in;
}

/* Run the closed loop for `seconds` at 100 Hz; returns the closest approach
 * of the robot centre to any wall. */
static double run_loop(behaviour_t *b, pose2_t *pose, uint64_t *now_us, double seconds)
{
    double closest = INFINITY;
    const int steps = (int)(seconds * 100.0);
    for (int i = 0; i < steps; ++i) {
        behaviour_input_t in = input_at(*now_us, *pose);
        behaviour_cmd_t cmd;
        behaviour_step(b, &in, &cmd);
        *pose = motion_apply(*pose, motion_from_body_velocity(cmd.vx_mps, cmd.vy_mps, cmd.w_radps, 0.01));
        *now_us += 10000U;
        closest = fmin(closest, dist_to_walls(pose->x, pose->y));
    }
    return closest;
}

static void test_straight_without_obstacles(void **state)
{
    (void)state;
    world_reset();
    behaviour_t b;
    behaviour_config_t c = behaviour_config_default();
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    pose2_t p = {0.0, 0.0, 0.3};
    uint64_t now = 1000000;
    run_loop(&b, &p, &now, 5.0);
    assert_int_equal(b.mode, BEHAVIOUR_WANDER);
    assert_true(fabs(hypot(p.x, p.y) - 1.0) < 0.01); /* 5 s at 0.2 m/s */
    assert_true(fabs(p.theta - 0.3) < 1e-6);
    assert_int_equal(b.avoid_turns, 0);
}

static void test_turns_right_parallel_to_a_wall(void **state)
{
    (void)state;
    world_reset();
    add_seg(2.0, -10.0, 2.0, 10.0); /* wall across the path, 2 m ahead */
    behaviour_t b;
    behaviour_config_t c = behaviour_config_default();
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    pose2_t p = {0.0, 0.0, 0.0};
    uint64_t now = 0;
    const double closest = run_loop(&b, &p, &now, 20.0);
    assert_int_equal(b.avoid_turns, 1);
    /* turned right (clockwise) to run parallel to the wall: heading -90 deg */
    assert_true(fabs(angle_wrap(p.theta + 0.5 * COSLAM_PI)) < 6.0 * DEG);
    /* turned on the spot once the wall was within the stop distance (0.6 m,
     * a step or two of motion later), then drove along it at that distance */
    assert_true(closest > 0.55 && closest < 0.6);
    assert_true(p.y < -2.0);
    assert_true(fabs(p.x - (2.0 - closest)) < 0.05);
}

/* Running along a wall that is too close (inside the corridor): it slides
 * away sideways and keeps going, never turning round. */
static void test_slides_away_from_a_close_parallel_wall(void **state)
{
    (void)state;
    world_reset();
    add_seg(-5.0, 0.22, 8.0, 0.22); /* 0.22 m to the left, parallel */
    behaviour_t b;
    behaviour_config_t c = behaviour_config_default();
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    pose2_t p = {0.0, 0.0, 0.0};
    uint64_t now = 0;
    const double closest = run_loop(&b, &p, &now, 6.0);
    assert_true(b.slides > 0);
    assert_true(closest >= 0.2199);
    const double half = 0.5 * g_w.op.robot_width_m + g_w.op.margin_m;
    assert_true(0.22 - p.y >= half - 0.01); /* out of the corridor now */
    assert_true(fabs(angle_wrap(p.theta)) < 6.0 * DEG);
    assert_true(p.x > 0.6);
}

/* The guard: a close parallel wall on the left asks for a slide to the
 * right, but a post stands right beside the robot on that side (outside the
 * corridor, which only looks ahead): the slide is refused; held back for
 * guard_patience_s the robot turns a quarter right. Hand-made scan. */
static void test_guard_refuses_a_move_into_a_post(void **state)
{
    (void)state;
    world_reset();
    static double r[64], a[64];
    size_t n = 0;
    for (int i = 0; i < 40; ++i) { /* the wall: (x, 0.2) for x in 0.05 .. 1.0 */
        const double x = 0.05 + 0.025 * i;
        a[n] = atan2(0.2, x);
        r[n++] = hypot(x, 0.2);
    }
    a[n] = -95.0 * DEG; /* the post, 0.235 m away to the right, a hair behind */
    r[n++] = 0.235;
    /* angle order, as scans come */
    for (size_t i = 0; i + 1 < n; ++i) {
        for (size_t j = i + 1; j < n; ++j) {
            if (a[j] < a[i]) {
                double t = a[i]; a[i] = a[j]; a[j] = t;
                t = r[i]; r[i] = r[j]; r[j] = t;
            }
        }
    }
    behaviour_t b;
    behaviour_config_t c = behaviour_config_default();
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    behaviour_input_t in;
    memset(&in, 0, sizeof in);
    in.scan_ok = 1;
    in.scan.params = &g_w.op;
    in.scan.laser_in_robot = (pose2_t){0.0, 0.0, 0.0};
    in.scan.range_m = r;
    in.scan.angle_rad = a;
    in.scan.n = n;
    scan_points(r, a, n, in.scan.laser_in_robot);
    in.scan.points_m = g_pts;
    in.scan.n_points = g_npts;
    behaviour_cmd_t cmd;
    for (int k = 0; k < 100; ++k) { /* 1 s at 100 Hz, the same scan */
        in.now_us = (uint64_t)k * 10000U;
        behaviour_step(&b, &in, &cmd);
        assert_true(cmd.vx_mps == 0.0 && cmd.vy_mps == 0.0);
    }
    assert_true(b.slides > 0);
    assert_true(b.guard_stops >= 99);
    in.now_us += 10000U;
    behaviour_step(&b, &in, &cmd);
    assert_int_equal(b.bump_turns, 1);
    assert_true(fabs(angle_wrap(b.hold_heading_rad + 0.5 * COSLAM_PI)) < 1e-9);
    /* without the post the slide goes through */
    world_reset();
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    size_t m = 0;
    for (size_t i = 0; i < n; ++i) {
        if (r[i] != 0.235) {
            r[m] = r[i];
            a[m++] = a[i];
        }
    }
    in.scan.n = m;
    scan_points(r, a, m, in.scan.laser_in_robot);
    in.scan.n_points = g_npts;
    in.now_us = 0;
    behaviour_step(&b, &in, &cmd);
    assert_true(cmd.vy_mps < 0.0);
    assert_int_equal(b.guard_stops, 0);
}

/* Back to the rendezvous point around a box standing in the way. */
static void test_returns_around_a_box(void **state)
{
    (void)state;
    world_reset();
    add_box(2.0, 0.0, 0.4, 0.4);
    behaviour_t b;
    behaviour_config_t c = behaviour_config_default();
    c.explore_s = 0.0;           /* straight to the rendezvous */
    c.rendezvous_m = (point2_t){4.0, 0.0};
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    pose2_t p = {0.0, 0.1, 0.0};
    uint64_t now = 0;
    double closest = INFINITY;
    for (int k = 0; k < 60 && b.mode == BEHAVIOUR_RETURN; ++k) {
        closest = fmin(closest, run_loop(&b, &p, &now, 1.0));
    }
    assert_int_equal(b.mode, BEHAVIOUR_SEEK);
    assert_true(hypot(p.x - 4.0, p.y) < c.goal_tol_m + 0.01);
    assert_true(closest > 0.19 + 0.1); /* a Robotino's radius plus margin */
    assert_true(b.goal_blocked > 0);   /* the box was in the way */
}

static void test_seek_face_and_leave(void **state)
{
    (void)state;
    world_reset();
    behaviour_t b;
    behaviour_config_t c = behaviour_config_default();
    c.explore_s = 0.0;
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    const pose2_t at_goal = {0.1, 0.0, 0.0};
    behaviour_input_t in = input_at(0, at_goal);
    behaviour_cmd_t cmd;
    behaviour_step(&b, &in, &cmd); /* RETURN, already there */
    in.now_us += 10000;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_SEEK);
    assert_true(cmd.vx_mps == 0.0);
    assert_true(fabs(cmd.w_radps - c.seek_turn_radps) < 1e-12);
    in.peer_in_view = 1;
    in.peer_bearing_rad = 0.2;
    in.now_us += 10000;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_FACE);
    assert_true(cmd.vx_mps == 0.0);
    assert_true(fabs(cmd.w_radps - c.face_gain * 0.2) < 1e-12);
    in.peer_in_view = 0;
    in.now_us += 10000;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_SEEK);
    /* merged but not acknowledged: stay up to linger_s, then explore */
    in.peer_in_view = 1;
    in.merged_all = 1;
    in.now_us += 10000;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_FACE);
    in.now_us += (uint64_t)(c.linger_s * 1e6) - 20000U;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_FACE);
    in.now_us += 20000U;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_WANDER);
    /* and no second rendezvous */
    in.now_us += 100000000U;
    in.merged_all = 0;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_WANDER);

    /* merged and acknowledged: leaves at once */
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    in = input_at(0, at_goal);
    behaviour_step(&b, &in, &cmd);
    in.peer_in_view = 1;
    in.now_us += 10000;
    behaviour_step(&b, &in, &cmd);
    in.now_us += 10000;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_FACE);
    in.merged_all = 1;
    in.acked_all = 1;
    in.now_us += 10000;
    assert_int_equal(behaviour_step(&b, &in, &cmd), BEHAVIOUR_WANDER);
}

static void test_bump_quarter_turn_and_blind(void **state)
{
    (void)state;
    world_reset();
    behaviour_t b;
    behaviour_config_t c = behaviour_config_default();
    assert_int_equal(behaviour_init(&b, &c), COSLAM_OK);
    pose2_t p = {0.0, 0.0, 1.0};
    behaviour_input_t in = input_at(0, p);
    in.bumped = 1;
    behaviour_cmd_t cmd;
    behaviour_step(&b, &in, &cmd);
    assert_int_equal(b.bump_turns, 1);
    assert_true(cmd.vx_mps == 0.0);
    assert_true(cmd.w_radps < 0.0);
    uint64_t now = 10000;
    run_loop(&b, &p, &now, 3.0);
    assert_true(fabs(angle_wrap(p.theta - (1.0 - 0.5 * COSLAM_PI))) < 6.0 * DEG);
    /* without a recent scan: no translation */
    in = input_at(now, p);
    in.scan_ok = 0;
    behaviour_step(&b, &in, &cmd);
    assert_true(cmd.vx_mps == 0.0);
}

static void test_config_checks(void **state)
{
    (void)state;
    behaviour_t b;
    behaviour_config_t c = behaviour_config_default();
    assert_int_equal(behaviour_init(NULL, &c), COSLAM_E_ARG);
    c.cruise_mps = 0.0;
    assert_int_equal(behaviour_init(&b, &c), COSLAM_E_ARG);
    c = behaviour_config_default();
    c.seek_turn_radps = 0.0;
    assert_int_equal(behaviour_init(&b, &c), COSLAM_E_ARG);
    c = behaviour_config_default();
    c.rendezvous_m.x = NAN;
    assert_int_equal(behaviour_init(&b, &c), COSLAM_E_ARG);
    c = behaviour_config_default();
    c.probe_step_rad = -1.0;
    assert_int_equal(behaviour_init(&b, &c), COSLAM_E_ARG);
    assert_string_equal(behaviour_mode_name(BEHAVIOUR_FACE), "face");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_straight_without_obstacles),
        cmocka_unit_test(test_turns_right_parallel_to_a_wall),
        cmocka_unit_test(test_slides_away_from_a_close_parallel_wall),
        cmocka_unit_test(test_guard_refuses_a_move_into_a_post),
        cmocka_unit_test(test_returns_around_a_box),
        cmocka_unit_test(test_seek_face_and_leave),
        cmocka_unit_test(test_bump_quarter_turn_and_blind),
        cmocka_unit_test(test_config_checks),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
