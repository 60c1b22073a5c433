/*
 * The arena world's generator (synth.h arena mode, eval_worlds.h
 * EVAL_WORLD_ARENA): MRCLAM's regime must be what the world produces, or
 * the figures measured on it mean nothing.
 *  - landmarks: inside the rectangle, in their clusters (within
 *    cluster_radius_m of the centre, centres >= 1.5 m apart, every pair
 *    >= min_separation_m);
 *  - motion: the robot stays inside the rectangle, turns on the spot (no
 *    translation while turning), drives straight otherwise, for wander_s;
 *  - sightings: each one is of a landmark inside the footprint of the true
 *    pose, and the fraction detected matches p_detect (binomial, 4 sd);
 *  - odometry noise: the heading and position errors of the reported
 *    increments have the truth's variance (Monte Carlo over the run,
 *    chi-square of about 6,000 degrees of freedom: +-10 %);
 *  - the same seed gives the same run, another seed another;
 *  - the circle worlds are unchanged by the new fields (the arena fields
 *    are 0 there).
 */
#include "test_util.h"

#include <stdlib.h>
#include <string.h>

#include "eval_worlds.h"
#include "synth.h"

static synth_world_t *arena(uint64_t seed)
{
    synth_world_t *w = malloc(sizeof *w);
    assert_non_null(w);
    const synth_config_t sc = eval_world_arena_config(seed);
    synth_init(w, &sc);
    return w;
}

static void test_landmarks_in_clusters(void **state)
{
    (void)state;
    for (uint64_t seed = 1; seed <= 20; ++seed) {
        synth_world_t *w = arena(seed);
        const synth_config_t *c = &w->cfg;
        assert_int_equal(w->n_lm, 15);
        for (int j = 0; j < w->n_lm; ++j) {
            assert_true(fabs(w->lm[j].x) <= c->arena_half_x_m + c->cluster_radius_m);
            assert_true(fabs(w->lm[j].y) <= c->arena_half_y_m + c->cluster_radius_m);
            const point2_t centre = w->lm[j % c->arena_clusters];
            ASSERT_TRUE_MSG(hypot(w->lm[j].x - centre.x, w->lm[j].y - centre.y) <= c->cluster_radius_m + 1e-12,
                            "seed %d landmark %d off its cluster\n", (int)seed, j);
            assert_int_equal(w->sig[j], 0); /* one class: identities unknown */
            for (int k = 0; k < j; ++k) {
                const double d = hypot(w->lm[j].x - w->lm[k].x, w->lm[j].y - w->lm[k].y);
                ASSERT_TRUE_MSG(d >= c->min_separation_m - 1e-12, "seed %d landmarks %d, %d %.3f m apart\n",
                                (int)seed, k, j, d);
                if (j < c->arena_clusters) {
                    ASSERT_TRUE_MSG(d >= 1.5 - 1e-12, "seed %d centres %d, %d %.3f m apart\n", (int)seed, k, j, d);
                }
            }
        }
        free(w);
    }
}

static void test_motion_and_sightings(void **state)
{
    (void)state;
    synth_world_t *w = arena(7U);
    synth_step_t *st = malloc(sizeof *st);
    assert_non_null(st);
    const synth_config_t *c = &w->cfg;
    const slam_params_t *tp = &c->truth;
    pose2_t prev = synth_start_pose(c);
    int steps = 0;
    int turning = 0;
    long in_view = 0;
    long detected = 0;
    double chi_theta = 0.0;
    double chi_xy = 0.0;
    int n_xy = 0;
    while (synth_next(w, st)) {
        steps++;
        const pose2_t p = st->true_pose;
        assert_true(fabs(p.x) <= c->arena_half_x_m && fabs(p.y) <= c->arena_half_y_m);
        /* the true increment in the body frame of the previous pose */
        const double dx = p.x - prev.x;
        const double dy = p.y - prev.y;
        const double bx = cos(prev.theta) * dx + sin(prev.theta) * dy;
        const double by = -sin(prev.theta) * dx + cos(prev.theta) * dy;
        const double dth = angle_wrap(p.theta - prev.theta);
        if (fabs(dth) > 1e-9 && hypot(dx, dy) < 1e-12) {
            turning++;
        } else {
            /* forward along an arc, no side slip: the chord's angle is half the turn */
            assert_true(fabs(by) <= 1.01 * fabs(bx) * tan(0.5 * fabs(dth)) + 1e-12);
        }
        const odo_increment_t ut = {bx, by, dth};
        const double s = motion_travel_m(ut, tp->base_radius_m);
        if (s > 0.0) {
            const double eth = angle_wrap(st->u.dtheta - dth);
            chi_theta += eth * eth / (tp->noise.odo_theta_var_rad2_per_m * s);
            const double ex = st->u.dx - bx;
            const double ey = st->u.dy - by;
            chi_xy += (ex * ex + ey * ey) / (tp->noise.odo_xy_var_m2_per_m * s);
            n_xy++;
        }
        if (st->is_frame) {
            for (int j = 0; j < w->n_lm; ++j) {
                const sighting_t zt = observe_predict(p, w->lm[j]);
                in_view += zt.range_m >= tp->sensor_min_range_m && zt.range_m <= tp->sensor_max_range_m &&
                           fabs(zt.bearing_rad) <= 0.5 * tp->sensor_fov_rad;
            }
            for (int i = 0; i < st->n_z; ++i) {
                const int j = st->true_id[i];
                assert_true(j >= 0 && j < w->n_lm); /* no clutter in the arena */
                const sighting_t zt = observe_predict(p, w->lm[j]);
                assert_true(zt.range_m >= tp->sensor_min_range_m && zt.range_m <= tp->sensor_max_range_m);
                assert_true(fabs(zt.bearing_rad) <= 0.5 * tp->sensor_fov_rad);
                detected++;
            }
        }
        prev = p;
    }
    assert_int_equal(steps, (int)ceil(c->wander_s / c->dt_s));
    printf("arena seed 7: %d steps, %d turning on the spot, %ld of %ld landmarks in view detected (%.3f), "
           "odometry chi2/n heading %.3f position %.3f\n",
           steps, turning, detected, in_view, (double)detected / (double)in_view, chi_theta / n_xy,
           chi_xy / (2.0 * n_xy));
    assert_true(turning > steps / 20 && turning < steps / 2);
    const double p = c->p_detect;
    const double sd = sqrt(p * (1.0 - p) / (double)in_view);
    ASSERT_TRUE_MSG(fabs((double)detected / (double)in_view - p) <= 4.0 * sd, "detected fraction %.3f, p %.2f\n",
                    (double)detected / (double)in_view, p);
    ASSERT_TRUE_MSG(fabs(chi_theta / n_xy - 1.0) < 0.1, "heading noise chi2/n %.3f\n", chi_theta / n_xy);
    ASSERT_TRUE_MSG(fabs(chi_xy / (2.0 * n_xy) - 1.0) < 0.1, "position noise chi2/n %.3f\n", chi_xy / (2.0 * n_xy));
    free(st);
    free(w);
}

static void run_prefix(uint64_t seed, pose2_t *poses, double *ranges, int n)
{
    synth_world_t *w = arena(seed);
    synth_step_t *st = malloc(sizeof *st);
    assert_non_null(st);
    int k = 0;
    while (k < n && synth_next(w, st)) {
        poses[k] = st->true_pose;
        ranges[k] = st->n_z > 0 ? st->z[0].range_m : -1.0;
        k++;
    }
    assert_int_equal(k, n);
    free(st);
    free(w);
}

static void test_seeded(void **state)
{
    (void)state;
    enum { N = 2000 };
    static pose2_t a[N], b[N], c[N];
    static double ra[N], rb[N], rc[N];
    run_prefix(3U, a, ra, N);
    run_prefix(3U, b, rb, N);
    run_prefix(4U, c, rc, N);
    assert_memory_equal(a, b, sizeof a);
    assert_memory_equal(ra, rb, sizeof ra);
    assert_true(memcmp(a, c, sizeof a) != 0);
}

static void test_circle_worlds_unchanged(void **state)
{
    (void)state;
    /* the arena fields default to 0: a circle world runs as before (one
     * full turn at radius R ends where it started, facing the same way) */
    synth_config_t sc = synth_config_default(5U, 20);
    assert_true(sc.arena_half_x_m == 0.0 && sc.wander_s == 0.0 && sc.arena_clusters == 0);
    sc.loops = 1.0;
    synth_world_t *w = malloc(sizeof *w);
    synth_step_t *st = malloc(sizeof *st);
    assert_non_null(w);
    assert_non_null(st);
    synth_init(w, &sc);
    const pose2_t p0 = synth_start_pose(&sc);
    pose2_t last = p0;
    while (synth_next(w, st)) {
        last = st->true_pose;
        ASSERT_NEAR(hypot(last.x, last.y), sc.loop_radius_m, 1e-3);
    }
    ASSERT_NEAR(hypot(last.x - p0.x, last.y - p0.y), 0.0, sc.speed_mps * sc.dt_s);
    free(st);
    free(w);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_landmarks_in_clusters),
        cmocka_unit_test(test_motion_and_sightings),
        cmocka_unit_test(test_seeded),
        cmocka_unit_test(test_circle_worlds_unchanged),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
