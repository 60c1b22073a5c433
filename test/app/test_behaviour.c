/*
 * The robot's behaviour (firmware/app behaviour.h) in closed loop with a
 * tiny kinematic world in this file: walls as segments, a laser scan ray
 * cast from the laser's pose (140 deg, 0.35 deg steps), the body velocity
 * integrated exactly. Proves: straight ahead without obstacles; a right
 * turn on the spot parallel to a wall across the path, then along it
 * without touching it; the way back around a box to the rendezvous point;
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

static void world_reset(void)
{
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

static behaviour_input_t input_at(uint64_t now_us, pose2_t pose)
{
    behaviour_input_t in;
    memset(&in, 0, sizeof in);
    in.now_us = now_us;
    in.odo_pose = pose;
    in.map_pose = pose;
    scan_from(pose);
    in.scan_ok = 1;
    in.scan.params = &g_w.op;
    in.scan.laser_in_robot = g_w.laser;
    in.scan.range_m = g_w.range;
    in.scan.angle_rad = g_w.angle;
    in.scan.n = N_RAYS;
    in.scan.stamp_us = now_us / 100000U * 100000U; /* a new scan every 100 ms */
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
        cmocka_unit_test(test_returns_around_a_box),
        cmocka_unit_test(test_seek_face_and_leave),
        cmocka_unit_test(test_bump_quarter_turn_and_blind),
        cmocka_unit_test(test_config_checks),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
