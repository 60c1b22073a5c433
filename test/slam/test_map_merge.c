/* Map merge: the relative pose from mutual sightings (hand computation and
 * Monte Carlo), the transformed landmark covariance (Monte Carlo), eqs. 4-5
 * against the information form, covariance intersection, merging into both
 * filters, repeated meetings, replay rejection. */
#include "test_util.h"

#include <stdlib.h>
#include <string.h>

#include "coslam/map_merge.h"
#include "coslam/rng.h"

static fastslam_t g_fs;
static ekfslam_t g_ekf;
static merge_scratch_t g_sc;
static merge_body_map_t g_bm;
static map_estimate_t g_msg;

/* Sightings each robot takes of the other, from their true poses. */
static void mutual(pose2_t self, pose2_t other, robot_sighting_t *s_o, robot_sighting_t *o_s)
{
    const point2_t po = {other.x, other.y};
    const point2_t ps = {self.x, self.y};
    const sighting_t a = observe_predict(self, po);
    const sighting_t b = observe_predict(other, ps);
    s_o->range_m = a.range_m;
    s_o->bearing_rad = a.bearing_rad;
    o_s->range_m = b.range_m;
    o_s->bearing_rad = b.bearing_rad;
    s_o->range_var_m2 = 0.0025;
    o_s->range_var_m2 = 0.0016;
    s_o->bearing_var_rad2 = 0.0012;
    o_s->bearing_var_rad2 = 0.0009;
}

static void test_relative_pose_hand(void **state)
{
    (void)state;
    /* self at the origin facing +x; other at (3, 4) facing -x: both see a
     * 3-4-5 triangle, at bearing atan2(4, 3) each (other looks back at
     * (-3, -4), which in its frame turned by pi is (3, 4)). */
    const robot_sighting_t s_o = {5.0, atan2(4.0, 3.0), 0.01, 0.001};
    const robot_sighting_t o_s = {5.0, atan2(4.0, 3.0), 0.01, 0.001};
    pose2_t t;
    cov3_t c;
    assert_int_equal(merge_relative_pose(&s_o, &o_s, &t, &c), COSLAM_OK);
    ASSERT_NEAR(t.x, 3.0, 1e-12);
    ASSERT_NEAR(t.y, 4.0, 1e-12);
    ASSERT_NEAR(angle_wrap(t.theta - COSLAM_PI), 0.0, 1e-12);
    /* the range is fused: equal variances -> half the variance along the ray */
    const double along = (3.0 * 3.0 * c.m[0][0] + 2 * 3.0 * 4.0 * c.m[0][1] + 4.0 * 4.0 * c.m[1][1]) / 25.0;
    ASSERT_NEAR(along, 0.005, 1e-12);
    /* heading variance: both bearings */
    ASSERT_NEAR(c.m[2][2], 0.002, 1e-15);
    /* random configurations are recovered exactly from exact sightings */
    rng_t r;
    rng_seed(&r, 5U);
    for (int i = 0; i < 200; ++i) {
        const pose2_t self = {rng_normal(&r, 0, 3), rng_normal(&r, 0, 3), angle_wrap(rng_normal(&r, 0, 3))};
        const pose2_t other = {rng_normal(&r, 0, 3), rng_normal(&r, 0, 3), angle_wrap(rng_normal(&r, 0, 3))};
        robot_sighting_t a;
        robot_sighting_t b;
        mutual(self, other, &a, &b);
        if (a.range_m < 0.1) {
            continue;
        }
        assert_int_equal(merge_relative_pose(&a, &b, &t, &c), COSLAM_OK);
        const pose2_t want = pose2_between(self, other);
        ASSERT_NEAR(t.x, want.x, 1e-9);
        ASSERT_NEAR(t.y, want.y, 1e-9);
        ASSERT_NEAR(angle_wrap(t.theta - want.theta), 0.0, 1e-9);
    }
    /* bad input */
    robot_sighting_t bad = s_o;
    bad.range_m = NAN;
    assert_int_equal(merge_relative_pose(&bad, &o_s, &t, &c), COSLAM_E_NUMERIC);
    bad = s_o;
    bad.range_var_m2 = 0.0;
    assert_int_equal(merge_relative_pose(&bad, &o_s, &t, &c), COSLAM_E_ARG);
}

/* Monte Carlo agreement, within 10 % of sqrt(C_ii C_jj) per entry. */
static void assert_mc3(const cov3_t *analytic, const double mc[3][3])
{
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            const double scale = sqrt(analytic->m[i][i] * analytic->m[k][k]);
            ASSERT_NEAR(mc[i][k], analytic->m[i][k], 0.10 * scale);
        }
    }
}

static void test_relative_pose_monte_carlo(void **state)
{
    (void)state;
    const pose2_t self = {0.3, -0.2, 0.4};
    const pose2_t other = {2.1, 0.9, -2.6};
    robot_sighting_t a;
    robot_sighting_t b;
    mutual(self, other, &a, &b);
    pose2_t t;
    cov3_t c;
    assert_int_equal(merge_relative_pose(&a, &b, &t, &c), COSLAM_OK);
    rng_t r;
    rng_seed(&r, 9U);
    const int n = 10000;
    double mc[3][3] = {{0}};
    for (int i = 0; i < n; ++i) {
        robot_sighting_t an = a;
        robot_sighting_t bn = b;
        an.range_m += sqrt(a.range_var_m2) * rng_gauss(&r);
        an.bearing_rad += sqrt(a.bearing_var_rad2) * rng_gauss(&r);
        bn.range_m += sqrt(b.range_var_m2) * rng_gauss(&r);
        bn.bearing_rad += sqrt(b.bearing_var_rad2) * rng_gauss(&r);
        pose2_t ts;
        cov3_t cs;
        assert_int_equal(merge_relative_pose(&an, &bn, &ts, &cs), COSLAM_OK);
        const double d[3] = {ts.x - t.x, ts.y - t.y, angle_wrap(ts.theta - t.theta)};
        for (int p = 0; p < 3; ++p) {
            for (int q = 0; q < 3; ++q) {
                mc[p][q] += d[p] * d[q] / n;
            }
        }
    }
    assert_mc3(&c, mc);
    /* motion compensation: covariance of u^-1 (+) T against Monte Carlo */
    const odo_increment_t u = {0.3, 0.1, 0.2};
    const cov3_t ucov = cov3_diag(0.0004, 0.0004, 0.0009);
    pose2_t tc = t;
    cov3_t cc = c;
    merge_compensate(&tc, &cc, u, &ucov, 0.0);
    const pose2_t up = {u.dx, u.dy, u.dtheta};
    const pose2_t want = pose2_compose(pose2_inverse(up), t);
    ASSERT_NEAR(tc.x, want.x, 1e-12);
    ASSERT_NEAR(tc.theta, want.theta, 1e-12);
    double l[3][3];
    double lu[3][3];
    assert_int_equal(cov3_cholesky(c, l), COSLAM_OK);
    assert_int_equal(cov3_cholesky(ucov, lu), COSLAM_OK);
    double mc2[3][3] = {{0}};
    for (int i = 0; i < n; ++i) {
        const double g1[3] = {rng_gauss(&r), rng_gauss(&r), rng_gauss(&r)};
        const double g2[3] = {rng_gauss(&r), rng_gauss(&r), rng_gauss(&r)};
        pose2_t ts = t;
        odo_increment_t us = u;
        ts.x += l[0][0] * g1[0];
        ts.y += l[1][0] * g1[0] + l[1][1] * g1[1];
        ts.theta += l[2][0] * g1[0] + l[2][1] * g1[1] + l[2][2] * g1[2];
        us.dx += lu[0][0] * g2[0];
        us.dy += lu[1][1] * g2[1];
        us.dtheta += lu[2][2] * g2[2];
        const pose2_t ups = {us.dx, us.dy, us.dtheta};
        const pose2_t rs = pose2_compose(pose2_inverse(ups), ts);
        const double d[3] = {rs.x - tc.x, rs.y - tc.y, angle_wrap(rs.theta - tc.theta)};
        for (int p = 0; p < 3; ++p) {
            for (int q = 0; q < 3; ++q) {
                mc2[p][q] += d[p] * d[q] / n;
            }
        }
    }
    assert_mc3(&cc, mc2);
}

/* A transformed landmark: R cov_rel R^T + J_T C_T J_T^T against sampling
 * the transform and the relative position. */
static void test_transformed_landmark_monte_carlo(void **state)
{
    (void)state;
    const pose2_t t = {2.0, 1.0, 2.5};
    cov3_t tc = cov3_zero();
    tc.m[0][0] = 0.004;
    tc.m[1][1] = 0.006;
    tc.m[2][2] = 0.003;
    tc.m[0][2] = tc.m[2][0] = 0.001;
    memset(&g_msg, 0, sizeof g_msg);
    g_msg.pose.x = 5.0;
    g_msg.pose.y = -1.0;
    g_msg.pose.theta = 0.7;
    g_msg.n_landmarks = 1;
    map_landmark_t *l = &g_msg.lm[0];
    const point2_t rel = {2.5, -1.2};
    l->mean = pose2_apply(g_msg.pose, rel);
    l->cov = cov2_make(0.02, 0.0, 0.02);
    l->cov_rel = cov2_make(0.01, 0.004, 0.02);
    l->id = 1;
    l->n_obs = 9;
    l->src_mask = 2;
    merge_config_t cfg = merge_config_default();
    merge_stats_t st;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_transform_map(&g_msg, t, &tc, &cfg, &g_bm, &st), COSLAM_OK);
    assert_int_equal(g_bm.n, 1);
    const point2_t want = pose2_apply(t, rel);
    ASSERT_NEAR(g_bm.mean[0].x, want.x, 1e-12);
    ASSERT_NEAR(g_bm.mean[0].y, want.y, 1e-12);
    rng_t r;
    rng_seed(&r, 13U);
    double lt[3][3];
    assert_int_equal(cov3_cholesky(tc, lt), COSLAM_OK);
    double lr[3];
    assert_int_equal(cov2_cholesky(l->cov_rel, lr), COSLAM_OK);
    const int n = 10000;
    double sxx = 0, sxy = 0, syy = 0;
    for (int i = 0; i < n; ++i) {
        const double g[5] = {rng_gauss(&r), rng_gauss(&r), rng_gauss(&r), rng_gauss(&r), rng_gauss(&r)};
        pose2_t ts = t;
        ts.x += lt[0][0] * g[0];
        ts.y += lt[1][0] * g[0] + lt[1][1] * g[1];
        ts.theta += lt[2][0] * g[0] + lt[2][1] * g[1] + lt[2][2] * g[2];
        const point2_t rs = {rel.x + lr[0] * g[3], rel.y + lr[1] * g[3] + lr[2] * g[4]};
        const point2_t p = pose2_apply(ts, rs);
        sxx += (p.x - want.x) * (p.x - want.x) / n;
        sxy += (p.x - want.x) * (p.y - want.y) / n;
        syy += (p.y - want.y) * (p.y - want.y) / n;
    }
    const cov2_t c = g_bm.cov[0];
    const double scale = sqrt(c.xx * c.yy);
    ASSERT_NEAR(sxx, c.xx, 0.10 * c.xx);
    ASSERT_NEAR(syy, c.yy, 0.10 * c.yy);
    ASSERT_NEAR(sxy, c.xy, 0.10 * scale);
    /* paper mode: the rotated map-frame covariance only, smaller here */
    cfg.transform_uncertainty = 0;
    assert_int_equal(merge_transform_map(&g_msg, t, &tc, &cfg, &g_bm, &st), COSLAM_OK);
    ASSERT_NEAR(g_bm.cov[0].xx + g_bm.cov[0].yy, 0.04, 1e-12); /* trace is rotation invariant */
    assert_true(g_bm.cov[0].xx + g_bm.cov[0].yy < c.xx + c.yy);
    /* min_obs filters */
    cfg = merge_config_default();
    cfg.min_obs = 10;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_transform_map(&g_msg, t, &tc, &cfg, &g_bm, &st), COSLAM_OK);
    assert_int_equal(g_bm.n, 0);
    assert_int_equal(st.skipped, 1);
}

static void test_fusion_rules(void **state)
{
    (void)state;
    const point2_t a = {1.0, 2.0};
    const point2_t b = {1.3, 1.8};
    const cov2_t sa = cov2_make(0.04, 0.01, 0.03);
    const cov2_t sb = cov2_make(0.02, -0.005, 0.05);
    point2_t x;
    cov2_t s;
    assert_int_equal(merge_fuse_kalman(a, sa, b, sb, &x, &s), COSLAM_OK);
    /* information form: S^-1 = Sa^-1 + Sb^-1, x = S (Sa^-1 a + Sb^-1 b) */
    cov2_t ia;
    cov2_t ib;
    cov2_t si;
    assert_int_equal(cov2_inverse(sa, &ia), COSLAM_OK);
    assert_int_equal(cov2_inverse(sb, &ib), COSLAM_OK);
    const cov2_t info = cov2_add(ia, ib);
    assert_int_equal(cov2_inverse(info, &si), COSLAM_OK);
    ASSERT_NEAR(s.xx, si.xx, 1e-14);
    ASSERT_NEAR(s.xy, si.xy, 1e-14);
    ASSERT_NEAR(s.yy, si.yy, 1e-14);
    const double vx = ia.xx * a.x + ia.xy * a.y + ib.xx * b.x + ib.xy * b.y;
    const double vy = ia.xy * a.x + ia.yy * a.y + ib.xy * b.x + ib.yy * b.y;
    ASSERT_NEAR(x.x, si.xx * vx + si.xy * vy, 1e-12);
    ASSERT_NEAR(x.y, si.xy * vx + si.yy * vy, 1e-12);
    /* covariance intersection: of an estimate with itself, nothing changes */
    double w;
    assert_int_equal(merge_fuse_ci(a, sa, a, sa, &x, &s, &w), COSLAM_OK);
    ASSERT_NEAR(s.xx, sa.xx, 1e-9);
    ASSERT_NEAR(s.yy, sa.yy, 1e-9);
    ASSERT_NEAR(x.x, a.x, 1e-9);
    /* re-fusing a piece of information already in a Kalman result adds nothing */
    point2_t k;
    cov2_t sk;
    assert_int_equal(merge_fuse_kalman(a, sa, b, sb, &k, &sk), COSLAM_OK);
    assert_int_equal(merge_fuse_ci(k, sk, b, sb, &x, &s, &w), COSLAM_OK);
    ASSERT_NEAR(w, 1.0, 1e-6);
    ASSERT_NEAR(s.xx, sk.xx, 1e-9);
    ASSERT_NEAR(s.yy, sk.yy, 1e-9);
    /* CI of two different estimates: inside both ellipses' information, and
     * consistent for any correlation: S >= the Kalman result */
    assert_int_equal(merge_fuse_ci(a, sa, b, sb, &x, &s, &w), COSLAM_OK);
    assert_true(w > 0.0 && w < 1.0);
    double lo;
    double hi;
    cov2_eigenvalues(cov2_add(s, cov2_scale(si, -1.0)), &lo, &hi);
    assert_true(lo > -1e-12);
    /* not PD */
    assert_int_equal(merge_fuse_kalman(a, cov2_make(-1, 0, -1), b, cov2_make(0.5, 0, 0.5), &x, &s), COSLAM_E_NOT_PD);
}

static void test_session_replay(void **state)
{
    (void)state;
    merge_session_t s;
    merge_session_init(&s);
    assert_int_equal(merge_session_accept(&s, 1, 10U), COSLAM_OK);
    assert_int_equal(merge_session_accept(&s, 1, 10U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 1, 9U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 1, 11U), COSLAM_OK);
    assert_int_equal(merge_session_accept(&s, 2, 5U), COSLAM_OK); /* senders are separate */
    /* the counter may wrap */
    assert_int_equal(merge_session_accept(&s, 3, 0xFFFFFFFFU), COSLAM_OK);
    assert_int_equal(merge_session_accept(&s, 3, 2U), COSLAM_OK);
    assert_int_equal(s.rejected_replays, 2);
    assert_int_equal(merge_session_accept(&s, COSLAM_MAX_ROBOTS, 1U), COSLAM_E_ARG);
    /* one number 2^31 - 16 ahead does not move the window: the genuine
     * sender's next numbers still pass; a step of exactly the limit does */
    assert_int_equal(merge_session_accept(&s, 1, 11U + 0x7FFFFFF0U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 1, 11U + MERGE_SEQ_MAX_JUMP + 1U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(s.rejected_jumps, 2);
    assert_int_equal(s.rejected_replays, 2);
    for (uint32_t k = 12U; k < 100U; ++k) {
        assert_int_equal(merge_session_accept(&s, 1, k), COSLAM_OK);
    }
    assert_int_equal(merge_session_accept(&s, 1, 99U + MERGE_SEQ_MAX_JUMP), COSLAM_OK);
}

/* A sender restarted without its snapshot numbers from 1 again: its third
 * message in a row below the remembered number, each newer than the one
 * before, is taken (the window starts there; counted) - not the first two,
 * not an old number replayed twice, not a run broken by an accepted newer
 * message, not late messages a few numbers behind. */
static void test_session_restarted_sender(void **state)
{
    (void)state;
    merge_session_t s;
    merge_session_init(&s);
    assert_int_equal(merge_session_accept(&s, 1, 500U), COSLAM_OK);
    assert_int_equal(merge_session_accept(&s, 1, 1U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 1, 2U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 1, 3U), COSLAM_OK);
    assert_int_equal(s.rebased, 1U);
    assert_int_equal(merge_session_accept(&s, 1, 4U), COSLAM_OK); /* numbered on from there */
    assert_int_equal(merge_session_accept(&s, 1, 499U), COSLAM_OK);
    /* the same old message replayed: never a run */
    assert_int_equal(merge_session_accept(&s, 2, 100U), COSLAM_OK);
    for (int k = 0; k < 10; ++k) {
        assert_int_equal(merge_session_accept(&s, 2, 90U), COSLAM_E_MERGE_REPLAY);
    }
    /* late messages overtaken by newer ones that are accepted: the run restarts */
    assert_int_equal(merge_session_accept(&s, 2, 91U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 2, 101U), COSLAM_OK);
    assert_int_equal(merge_session_accept(&s, 2, 92U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 2, 102U), COSLAM_OK);
    assert_int_equal(merge_session_accept(&s, 2, 93U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(s.rebased, 1U);
    assert_int_equal(s.last_seq[2], 102U);
    /* three late messages overtaken by a newer one, a few numbers behind
     * it: not a restart (an old map merged after a newer one) */
    assert_int_equal(merge_session_accept(&s, 4, 12U), COSLAM_OK);
    assert_int_equal(merge_session_accept(&s, 4, 9U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 4, 10U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 4, 11U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(s.last_seq[4], 12U);
    assert_int_equal(s.rebased, 1U);
    /* a run whose steps jump too far is not a restart */
    assert_int_equal(merge_session_accept(&s, 3, 200000U), COSLAM_OK);
    assert_int_equal(merge_session_accept(&s, 3, 1U), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 3, 2U + MERGE_SEQ_MAX_JUMP), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 3, 3U + MERGE_SEQ_MAX_JUMP), COSLAM_E_MERGE_REPLAY);
    assert_int_equal(merge_session_accept(&s, 3, 4U + MERGE_SEQ_MAX_JUMP), COSLAM_OK); /* 1 step: a run of 3 */
    assert_int_equal(s.rebased, 2U);
}

/* An incoming map with one landmark that the receiver knows and one it does
 * not, built in the receiver's body frame with an exact transform. */
static void incoming_two(pose2_t robot, point2_t known_world, point2_t new_world, uint16_t src)
{
    memset(&g_bm, 0, sizeof g_bm);
    g_bm.n = 2;
    const point2_t pts[2] = {known_world, new_world};
    for (int i = 0; i < 2; ++i) {
        g_bm.mean[i] = pose2_apply_inverse(robot, pts[i]);
        g_bm.cov[i] = cov2_make(0.01, 0.0, 0.01);
        g_bm.rel[i] = g_bm.mean[i]; /* identity transform */
        g_bm.rel_cov[i] = g_bm.cov[i];
        g_bm.src_mask[i] = src;
        g_bm.n_obs[i] = 7;
        g_bm.signature[i] = 0;
        g_bm.id[i] = 100U + (uint32_t)i;
    }
    g_bm.t.x = 0.0;
    g_bm.t.y = 0.0;
    g_bm.t.theta = 0.0;
    g_bm.t_cov = cov3_zero();
}

static void test_merge_into_fastslam(void **state)
{
    (void)state;
    fastslam_config_t c = fastslam_config_default();
    c.n_particles = 20;
    c.robot_id = 0;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 3U), COSLAM_OK);
    landmark_t own;
    memset(&own, 0, sizeof own);
    own.mean = (point2_t){2.0, 0.0};
    own.cov = cov2_make(0.02, 0.0, 0.02);
    own.id = 1U;
    own.exist = 6.0f;
    own.n_obs = 8;
    own.src_mask = 1;
    for (uint16_t k = 0; k < 20; ++k) {
        g_fs.particles[k].pose.theta = 0.3;
        assert_int_equal(fastslam_particle_add(&g_fs, k, &own), COSLAM_OK);
    }
    const pose2_t robot = {0.0, 0.0, 0.3};
    const point2_t known = {2.05, 0.02};
    const point2_t fresh = {-1.0, 3.0};
    incoming_two(robot, known, fresh, 0x2U);
    merge_config_t mc = merge_config_default();
    merge_stats_t st;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_into_fastslam(&g_fs, &g_bm, &mc, &g_sc, &st), COSLAM_OK);
    assert_int_equal(st.fused, 20);
    assert_int_equal(st.added, 20);
    assert_int_equal(st.fused_ci, 0);
    point2_t want;
    cov2_t want_c;
    assert_int_equal(merge_fuse_kalman(own.mean, own.cov, known, cov2_make(0.01, 0.0, 0.01), &want, &want_c),
                     COSLAM_OK);
    for (uint16_t k = 0; k < 20; ++k) {
        const fastslam_particle_t *p = &g_fs.particles[k];
        assert_int_equal(p->n_lm, 2);
        const landmark_t *l0 = fastslam_particle_lm(&g_fs, k, 0);
        const landmark_t *l1 = fastslam_particle_lm(&g_fs, k, 1);
        ASSERT_NEAR(l0->mean.x, want.x, 1e-9);
        ASSERT_NEAR(l0->cov.xx, want_c.xx, 1e-12); /* eqs. 4-5 */
        assert_int_equal(l0->src_mask, 0x3);
        assert_int_equal(l0->n_obs, 15);
        ASSERT_NEAR(l1->mean.x, fresh.x, 1e-9);
        assert_int_equal(l1->id, fastslam_particle_lm(&g_fs, 0, 1)->id); /* one identity across particles */
    }
    /* the same map again (a second meeting, nothing new): provenance overlaps,
     * covariance intersection, and the covariances do not shrink */
    const double before = fastslam_particle_lm(&g_fs, 0, 0)->cov.xx;
    const double before_new = fastslam_particle_lm(&g_fs, 0, 1)->cov.xx;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_into_fastslam(&g_fs, &g_bm, &mc, &g_sc, &st), COSLAM_OK);
    assert_int_equal(st.fused, 40);
    assert_int_equal(st.fused_ci, 40);
    assert_int_equal(st.added, 0);
    ASSERT_NEAR(fastslam_particle_lm(&g_fs, 0, 0)->cov.xx, before, 1e-9);
    ASSERT_NEAR(fastslam_particle_lm(&g_fs, 0, 1)->cov.xx, before_new, 1e-9);
    assert_int_equal(g_fs.particles[0].n_lm, 2);
    /* capacity: a full map reports and keeps what it has */
    for (uint16_t k = 0; k < 20; ++k) {
        while (g_fs.particles[k].n_lm < COSLAM_MAX_LANDMARKS) {
            landmark_t far = own;
            far.mean.x = 100.0 + g_fs.particles[k].n_lm;
            far.signature = 9;
            assert_int_equal(fastslam_particle_add(&g_fs, k, &far), COSLAM_OK);
        }
    }
    const point2_t fresh2 = {-3.0, -3.0};
    incoming_two(robot, known, fresh2, 0x4U);
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_into_fastslam(&g_fs, &g_bm, &mc, &g_sc, &st), COSLAM_E_CAPACITY);
    assert_int_equal(st.capacity_drops, 20);
    assert_int_equal(g_fs.particles[3].n_lm, COSLAM_MAX_LANDMARKS);
}

/* Fast-SLAM's duplicate search against brute force: random particles (poses
 * spread), own maps and an incoming map of 2 classes in two clusters far
 * apart with one very uncertain landmark (a wide grid cell), some own
 * landmarks one cell beyond the incoming ones; the trees' boxes clean in
 * three trials of four (subtrees skipped by box_may_pair), stale in the
 * fourth. Every particle must end
 * with its own landmarks plus exactly the incoming ones that the
 * all-pairs, one-to-one by increasing distance pairing leaves unpaired. */
#define BF_IN 24  /* incoming landmarks, two clusters */
#define BF_OWN 36 /* own landmarks per particle, BF_IN / 2 near copies */
_Static_assert(BF_IN + BF_OWN <= COSLAM_MAX_LANDMARKS && BF_IN <= COSLAM_MAX_MSG_LANDMARKS,
               "the brute-force case must fit the smallest profile");

static void test_fastslam_pairing_brute_force(void **state)
{
    (void)state;
    rng_t r;
    rng_seed(&r, 77U);
    fastslam_config_t c = fastslam_config_default();
    c.n_particles = 30;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    merge_config_t mc = merge_config_default();
    for (int trial = 0; trial < 20; ++trial) {
        assert_int_equal(fastslam_init(&g_fs, &c, p0, 5U + (uint64_t)trial), COSLAM_OK);
        /* incoming: two clusters 30 m apart, body frame */
        memset(&g_bm, 0, sizeof g_bm);
        g_bm.n = BF_IN;
        for (int i = 0; i < g_bm.n; ++i) {
            const double cx = i < BF_IN / 2 ? 3.0 : 33.0;
            g_bm.mean[i] = (point2_t){cx + 4.0 * rng_uniform(&r), -2.0 + 4.0 * rng_uniform(&r)};
            const double v = i == 5 ? 0.5 + trial * 0.05 : 0.005 + 0.02 * rng_uniform(&r);
            g_bm.cov[i] = cov2_make(v, 0.3 * v * (rng_uniform(&r) - 0.5), v * (0.5 + rng_uniform(&r)));
            g_bm.rel[i] = g_bm.mean[i];
            g_bm.rel_cov[i] = g_bm.cov[i];
            g_bm.src_mask[i] = 0x2U;
            g_bm.n_obs[i] = 7;
            g_bm.signature[i] = (uint8_t)(i % 2);
            g_bm.id[i] = 100U + (uint32_t)i;
        }
        g_bm.t_cov = cov3_zero();
        /* own maps: near copies of half the incoming ones, landmarks between
         * and around the clusters, per particle a jittered pose */
        for (uint16_t k = 0; k < c.n_particles; ++k) {
            fastslam_particle_t *pk = &g_fs.particles[k];
            pk->pose = (pose2_t){0.2 * rng_gauss(&r), 0.2 * rng_gauss(&r), 0.05 * rng_gauss(&r)};
            for (int j = 0; j < BF_OWN; ++j) {
                landmark_t lm;
                memset(&lm, 0, sizeof lm);
                point2_t body;
                if (j < BF_IN / 2) {
                    const int i = 2 * j;
                    body = (point2_t){g_bm.mean[i].x + 0.15 * rng_gauss(&r), g_bm.mean[i].y + 0.15 * rng_gauss(&r)};
                    lm.signature = g_bm.signature[i];
                } else {
                    body = (point2_t){-10.0 + 50.0 * rng_uniform(&r), -6.0 + 12.0 * rng_uniform(&r)};
                    lm.signature = (uint8_t)(j % 2);
                }
                lm.mean = pose2_apply(pk->pose, body);
                const double v = 0.005 + 0.02 * rng_uniform(&r);
                lm.cov = cov2_make(v, 0.0, v);
                lm.id = (uint32_t)(j + 1);
                lm.exist = 6.0f;
                lm.n_obs = 8;
                lm.src_mask = 1;
                assert_int_equal(fastslam_particle_add(&g_fs, k, &lm), COSLAM_OK);
            }
            if (trial % 4 != 0) {
                /* clean boxes, as after the filter's queries: the merge
                 * then skips subtrees by them (stale in the other trials) */
                lm_tree_clean(&g_fs.lm_pool, pk->lm_root);
            }
        }
        /* brute force, per particle */
        int expect_new[COSLAM_MAX_PARTICLES];
        uint32_t expect_fused = 0;
        for (uint16_t k = 0; k < c.n_particles; ++k) {
            const fastslam_particle_t *pk = &g_fs.particles[k];
            const double ct = cos(pk->pose.theta);
            const double st = sin(pk->pose.theta);
            double rt[2][2] = {{ct, st}, {-st, ct}};
            int n_pairs = 0;
            static merge_pair_t pairs[BF_OWN * BF_IN];
            for (uint16_t j = 0; j < pk->n_lm; ++j) {
                const landmark_t *lm = fastslam_particle_lm(&g_fs, k, j);
                const point2_t b = pose2_apply_inverse(pk->pose, lm->mean);
                const cov2_t bc = cov2_congruence(rt, lm->cov);
                for (int i = 0; i < g_bm.n; ++i) {
                    double d2;
                    if (g_bm.signature[i] != lm->signature ||
                        cov2_mahalanobis2(cov2_add(bc, g_bm.cov[i]), g_bm.mean[i].x - b.x, g_bm.mean[i].y - b.y,
                                          &d2) != COSLAM_OK ||
                        !(d2 < mc.gate_chi2)) {
                        continue;
                    }
                    pairs[n_pairs].own = j;
                    pairs[n_pairs].in = i;
                    pairs[n_pairs].d2 = d2;
                    n_pairs++;
                }
            }
            /* one to one by increasing distance (selection, n is small) */
            uint8_t used_own[BF_OWN] = {0};
            uint8_t used_in[BF_IN] = {0};
            int matched = 0;
            for (;;) {
                int best = -1;
                for (int q = 0; q < n_pairs; ++q) {
                    if (!used_own[pairs[q].own] && !used_in[pairs[q].in] && (best < 0 || pairs[q].d2 < pairs[best].d2)) {
                        best = q;
                    }
                }
                if (best < 0) {
                    break;
                }
                used_own[pairs[best].own] = 1;
                used_in[pairs[best].in] = 1;
                matched++;
            }
            expect_new[k] = g_bm.n - matched;
            expect_fused += (uint32_t)matched;
        }
        merge_stats_t stt;
        memset(&stt, 0, sizeof stt);
        assert_int_equal(merge_into_fastslam(&g_fs, &g_bm, &mc, &g_sc, &stt), COSLAM_OK);
        assert_int_equal(stt.fused, expect_fused);
        assert_true(expect_fused > 0U);
        for (uint16_t k = 0; k < c.n_particles; ++k) {
            assert_int_equal(g_fs.particles[k].n_lm, BF_OWN + expect_new[k]);
        }
    }
}

/* More candidate pairs than the pair table holds (COSLAM_MERGE_MAX_PAIRS):
 * PT_N own landmarks of one class in a 0.3 m box, each with an exact twin in
 * the incoming map, so PT_N^2 candidate pairs; and one incoming landmark
 * 1.2 m off the box, inside the gate of the box's landmarks only at d2 >= 5.
 * The table keeps the nearest pairs: every twin is paired with its own
 * landmark (exactly as with the whole set), the pairs not kept are counted,
 * and the off-box landmark, which lost every candidate, is neither fused
 * nor added (a copy of a mapped landmark is worse than a landmark missed),
 * counted, and the merge says E_CAPACITY. Before: the pairs beyond the
 * table were those of the last own landmarks, whose twins then went in as
 * new landmarks, and the merge returned OK. */
#define PT_N 60
static void pair_table_case(rng_t *r, uint16_t n_particles, int with_extra)
{
    fastslam_config_t c = fastslam_config_default();
    c.n_particles = n_particles;
    c.robot_id = 0;
    assert_int_equal(fastslam_init(&g_fs, &c, (pose2_t){0.0, 0.0, 0.0}, 11U), COSLAM_OK);
    memset(&g_bm, 0, sizeof g_bm);
    for (int j = 0; j < PT_N; ++j) {
        landmark_t lm;
        memset(&lm, 0, sizeof lm);
        lm.mean = (point2_t){3.0 + 0.3 * rng_uniform(r), 0.3 * rng_uniform(r)};
        lm.cov = cov2_make(0.1, 0.0, 0.1);
        lm.id = (uint32_t)(j + 1);
        lm.exist = 6.0f;
        lm.n_obs = 8;
        lm.src_mask = 1;
        lm.signature = 1;
        for (uint16_t k = 0; k < n_particles; ++k) {
            assert_int_equal(fastslam_particle_add(&g_fs, k, &lm), COSLAM_OK);
        }
        g_bm.mean[j] = lm.mean; /* the robot at the origin: body = world */
        g_bm.cov[j] = lm.cov;
        g_bm.rel[j] = lm.mean;
        g_bm.rel_cov[j] = lm.cov;
        g_bm.src_mask[j] = 0x2U;
        g_bm.n_obs[j] = 7;
        g_bm.signature[j] = 1;
        g_bm.id[j] = 100U + (uint32_t)j;
    }
    g_bm.n = PT_N;
    if (with_extra) {
        const uint16_t i = g_bm.n++;
        g_bm.mean[i] = (point2_t){4.5, 0.15};
        g_bm.cov[i] = cov2_make(0.1, 0.0, 0.1);
        g_bm.rel[i] = g_bm.mean[i];
        g_bm.rel_cov[i] = g_bm.cov[i];
        g_bm.src_mask[i] = 0x2U;
        g_bm.n_obs[i] = 7;
        g_bm.signature[i] = 1;
        g_bm.id[i] = 999U;
    }
    g_bm.t_cov = cov3_zero();
}

static void test_pair_table_full(void **state)
{
    (void)state;
    assert_true(PT_N * PT_N > COSLAM_MERGE_MAX_PAIRS);
    assert_true(PT_N + 1 <= COSLAM_MAX_MSG_LANDMARKS && PT_N <= COSLAM_MAX_LANDMARKS);
    rng_t r;
    rng_seed(&r, 31U);
    const merge_config_t mc = merge_config_default();
    const uint16_t np = 3;
    /* the twins alone: every one fused with its own landmark, status OK */
    pair_table_case(&r, np, 0);
    merge_stats_t st;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_into_fastslam(&g_fs, &g_bm, &mc, &g_sc, &st), COSLAM_OK);
    assert_true(st.pair_drops > 0U);
    assert_int_equal(st.pair_lost, 0);
    assert_int_equal(st.fused, (uint32_t)PT_N * np);
    assert_int_equal(st.added, 0);
    assert_int_equal(g_fs.ctr.merge_pair_drops, 0);
    for (uint16_t k = 0; k < np; ++k) {
        assert_int_equal(g_fs.particles[k].n_lm, PT_N);
        for (uint16_t j = 0; j < PT_N; ++j) { /* each with its twin: the mean stays, the covariance shrinks */
            const landmark_t *lm = fastslam_particle_lm(&g_fs, k, j);
            assert_true(fabs(lm->mean.x - g_bm.mean[j].x) < 1e-12 && fabs(lm->mean.y - g_bm.mean[j].y) < 1e-12);
            assert_true(lm->cov.xx < 0.1 - 1e-6);
        }
    }
    /* with the landmark whose candidates were all beyond the table */
    pair_table_case(&r, np, 1);
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_into_fastslam(&g_fs, &g_bm, &mc, &g_sc, &st), COSLAM_E_CAPACITY);
    assert_int_equal(st.pair_lost, np);
    assert_int_equal(st.fused, (uint32_t)PT_N * np);
    assert_int_equal(st.added, 0);
    assert_int_equal(g_fs.ctr.merge_pair_drops, np);
    for (uint16_t k = 0; k < np; ++k) {
        assert_int_equal(g_fs.particles[k].n_lm, PT_N);
    }
    /* the check: the same pairing, the lost landmark left out and counted */
    static map_whole_t own;
    memset(&own, 0, sizeof own);
    own.n_landmarks = PT_N;
    for (uint16_t j = 0; j < PT_N; ++j) {
        own.lm[j].mean = g_bm.mean[j];
        own.lm[j].cov = g_bm.cov[j];
        own.lm[j].cov_rel = g_bm.cov[j];
        own.lm[j].signature = 1;
        own.lm[j].n_obs = 8;
        own.lm[j].src_mask = 1;
    }
    g_bm.t_cov = cov3_diag(1e-4, 1e-4, 1e-6);
    memset(&st, 0, sizeof st);
    const slam_params_t sp = slam_params_default();
    assert_int_equal(merge_check(&own, NULL, NULL, &sp, 0U, &mc, &g_bm, &g_sc, &st), COSLAM_OK);
    assert_true(st.pair_drops > 0U);
    assert_int_equal(st.pairs, PT_N);
    assert_int_equal(st.check_lost, 1);
    assert_int_equal(g_bm.n, PT_N);
    for (uint16_t i = 0; i < g_bm.n; ++i) {
        assert_true(g_bm.id[i] != 999U);
    }
}

/* A receiver lost in its own map (merge_check step 2, lost_sd_factor): four
 * incoming landmarks that pair with four own ones, 3 m apart; the merge is
 * refused with COSLAM_E_MERGE_LOST exactly when the best-placed own landmark
 * of the pairs is placed worse than lost_sd_factor x merge_refute_sd_m
 * (largest axis of its relative covariance); stats->placed_sd_m is that sd.
 * The test comes before the joint test; 0 disables it. */
static void lost_case(map_whole_t *own, double sd_best, double sd_rest)
{
    memset(own, 0, sizeof *own);
    memset(&g_bm, 0, sizeof g_bm);
    own->pose = (pose2_t){1.0, -2.0, 0.7};
    own->n_landmarks = 4;
    g_bm.n = 4;
    g_bm.t = (pose2_t){0.0, 0.0, 0.0};
    g_bm.t_cov = cov3_diag(1e-4, 1e-4, 1e-6);
    for (uint16_t j = 0; j < 4; ++j) {
        const point2_t rel = {1.0 + 3.0 * (j % 2), -1.5 + 3.0 * (j / 2)};
        const double sd = j == 2 ? sd_best : sd_rest;
        own->lm[j].mean = pose2_apply(own->pose, rel);
        /* the largest axis along x, a tenth across */
        own->lm[j].cov_rel = cov2_make(sd * sd, 0.0, 0.01 * sd * sd);
        own->lm[j].cov = own->lm[j].cov_rel;
        own->lm[j].signature = 1;
        own->lm[j].n_obs = 8;
        own->lm[j].src_mask = 1;
        g_bm.rel[j] = (point2_t){rel.x + 0.02, rel.y - 0.01};
        g_bm.rel_cov[j] = cov2_make(0.01, 0.0, 0.01);
        g_bm.mean[j] = g_bm.rel[j];
        g_bm.cov[j] = g_bm.rel_cov[j];
        g_bm.signature[j] = 1;
        g_bm.n_obs[j] = 8;
        g_bm.src_mask[j] = 2;
        g_bm.id[j] = 100U + j;
    }
}

static void test_check_lost_receiver(void **state)
{
    (void)state;
    static map_whole_t own;
    const slam_params_t sp = slam_params_default();
    const double bound = merge_refute_sd_m(&sp);
    assert_true(bound > 0.3 && bound < 0.6);
    merge_config_t mc = merge_config_default();
    assert_true(mc.lost_sd_factor == 1.0);
    merge_stats_t st;
    const struct {
        double best, rest, factor;
        coslam_status_t want;
    } cases[] = {
        {2.0 * bound, 3.0 * bound, 1.0, COSLAM_E_MERGE_LOST}, /* none placed */
        {1.01 * bound, 3.0 * bound, 1.0, COSLAM_E_MERGE_LOST},
        {0.99 * bound, 3.0 * bound, 1.0, COSLAM_OK},           /* one placed is enough */
        {0.2 * bound, 0.2 * bound, 1.0, COSLAM_OK},
        {2.0 * bound, 3.0 * bound, 0.0, COSLAM_OK},            /* off */
        {2.0 * bound, 3.0 * bound, 2.5, COSLAM_OK},            /* the factor scales the bound */
        {2.6 * bound, 3.0 * bound, 2.5, COSLAM_E_MERGE_LOST},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
        lost_case(&own, cases[c].best, cases[c].rest);
        mc.lost_sd_factor = cases[c].factor;
        memset(&st, 0, sizeof st);
        assert_int_equal(merge_check(&own, NULL, NULL, &sp, 0U, &mc, &g_bm, &g_sc, &st), cases[c].want);
        assert_int_equal(st.pairs, 4);
        assert_true(fabs(st.placed_sd_m - cases[c].best) < 1e-5 * cases[c].best + 1e-6);
        if (cases[c].want == COSLAM_OK) {
            assert_int_equal(g_bm.n, 4); /* all four fused */
        }
    }
    /* no pairs (the incoming map elsewhere): nothing to place, not refused */
    lost_case(&own, 3.0 * bound, 3.0 * bound);
    for (uint16_t i = 0; i < g_bm.n; ++i) {
        g_bm.rel[i].x += 40.0;
    }
    mc.lost_sd_factor = 1.0;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_check(&own, NULL, NULL, &sp, 0U, &mc, &g_bm, &g_sc, &st), COSLAM_OK);
    assert_int_equal(st.pairs, 0);
    assert_true(st.placed_sd_m == 0.0f);
    /* a non-finite or negative factor is a bad configuration */
    mc.lost_sd_factor = -1.0;
    assert_int_equal(merge_check(&own, NULL, NULL, &sp, 0U, &mc, &g_bm, &g_sc, &st), COSLAM_E_ARG);
    mc.lost_sd_factor = NAN;
    assert_int_equal(merge_check(&own, NULL, NULL, &sp, 0U, &mc, &g_bm, &g_sc, &st), COSLAM_E_ARG);
}

/* The same table in an EKF-SLAM merge in parts: the landmark that lost its
 * candidates is known from the begin, so every part says E_CAPACITY, the
 * first too (the robot reports the merge with that part's status), and the
 * merge in parts ends as the merge at once does. */
static void test_pair_table_full_ekf_in_parts(void **state)
{
    (void)state;
    rng_t r;
    rng_seed(&r, 31U);
    pair_table_case(&r, 1, 0); /* the twins, into an empty EKF-SLAM: its map */
    ekfslam_config_t c = ekfslam_config_default();
    c.robot_id = 0;
    assert_int_equal(ekfslam_init(&g_ekf, &c, (pose2_t){0.0, 0.0, 0.0}), COSLAM_OK);
    merge_config_t mc = merge_config_default();
    merge_stats_t st;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_into_ekfslam(&g_ekf, &g_bm, &mc, &g_sc, &st), COSLAM_OK);
    assert_int_equal(g_ekf.n_lm, PT_N);
    rng_seed(&r, 31U);
    pair_table_case(&r, 1, 1); /* the same twins and the off-box landmark */
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_ekfslam_begin(&g_ekf, &g_bm, &mc, &g_sc, &st), COSLAM_OK);
    assert_int_equal(st.pair_lost, 1);
    int done = 0;
    int parts = 0;
    while (!done) {
        assert_int_equal(merge_ekfslam_run(&g_ekf, &g_bm, &g_sc, &st, 50U, &done), COSLAM_E_CAPACITY);
        parts++;
    }
    assert_true(parts > 1);
    assert_int_equal(g_ekf.n_lm, PT_N); /* nothing added */
    assert_int_equal(st.fused, PT_N);
    assert_int_equal(g_ekf.ctr.merge_pair_drops, 1);
}

/* A filter whose particles hold jittered copies of an own map, half of the
 * incoming landmarks among them (as the brute-force case), and g_bm. */
static fastslam_t g_fs_parts;

static void parts_case(fastslam_t *fs, uint16_t n_particles, rng_t *r)
{
    fastslam_config_t c = fastslam_config_default();
    c.n_particles = n_particles;
    c.resample_ess_fraction = 1.0; /* every update that tells particles apart resamples */
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(fs, &c, p0, 9U), COSLAM_OK);
    memset(&g_bm, 0, sizeof g_bm);
    g_bm.n = BF_IN;
    for (int i = 0; i < g_bm.n; ++i) {
        g_bm.mean[i] = (point2_t){1.0 + 5.0 * rng_uniform(r), -2.5 + 5.0 * rng_uniform(r)};
        const double v = 0.005 + 0.02 * rng_uniform(r);
        g_bm.cov[i] = cov2_make(v, 0.0, v);
        g_bm.rel[i] = g_bm.mean[i];
        g_bm.rel_cov[i] = g_bm.cov[i];
        g_bm.src_mask[i] = 0x2U;
        g_bm.n_obs[i] = 7;
        g_bm.signature[i] = (uint8_t)(i % 2);
        g_bm.id[i] = 100U + (uint32_t)i;
    }
    g_bm.t_cov = cov3_zero();
    for (uint16_t k = 0; k < n_particles; ++k) {
        fastslam_particle_t *pk = &fs->particles[k];
        pk->pose = (pose2_t){0.1 * rng_gauss(r), 0.1 * rng_gauss(r), 0.02 * rng_gauss(r)};
        for (int j = 0; j < BF_OWN; ++j) {
            landmark_t lm;
            memset(&lm, 0, sizeof lm);
            const int i = 2 * j;
            const point2_t body = j < BF_IN / 2 ? (point2_t){g_bm.mean[i].x + 0.1 * rng_gauss(r), g_bm.mean[i].y}
                                                 : (point2_t){-8.0 + 4.0 * rng_uniform(r), 6.0 * rng_uniform(r)};
            lm.signature = j < BF_IN / 2 ? g_bm.signature[i] : (uint8_t)(j % 2);
            lm.mean = pose2_apply(pk->pose, body);
            lm.cov = cov2_make(0.01, 0.0, 0.01);
            lm.id = (uint32_t)(j + 1);
            lm.exist = 6.0f;
            lm.n_obs = 8;
            lm.src_mask = 1;
            assert_int_equal(fastslam_particle_add(fs, k, &lm), COSLAM_OK);
        }
    }
    fs->next_id = 1000U; /* identities beyond the own ones */
}

/* The merge in parts (merge_fastslam_begin / merge_fastslam_run): with no
 * step in between it is the whole merge bit for bit; with steps in between
 * every particle is merged once, through the pose it had when the merge
 * began, and resampling waits for the last part. */
static void test_fastslam_merge_in_parts(void **state)
{
    (void)state;
    rng_t r;
    rng_seed(&r, 41U);
    const uint16_t n = 24;
    parts_case(&g_fs, n, &r);
    memcpy(&g_fs_parts, &g_fs, sizeof g_fs); /* the pool is inside: an independent copy */
    merge_config_t mc = merge_config_default();
    mc.reweight_particles = 1U;
    merge_stats_t whole;
    memset(&whole, 0, sizeof whole);
    assert_int_equal(merge_into_fastslam(&g_fs, &g_bm, &mc, &g_sc, &whole), COSLAM_OK);
    /* in parts of about three particles */
    const uint32_t budget = 3U * (BF_OWN + MERGE_UNITS_PER_INCOMING * BF_IN);
    merge_stats_t parts;
    memset(&parts, 0, sizeof parts);
    assert_int_equal(merge_fastslam_begin(&g_fs_parts, &g_bm, &mc, &g_sc, NULL), COSLAM_OK);
    int calls = 0;
    uint16_t left = n;
    while (left > 0U) {
        assert_int_equal(merge_fastslam_run(&g_fs_parts, &g_bm, &mc, &g_sc, &parts, budget, &left), COSLAM_OK);
        calls++;
        if (calls == 1) {
            assert_true(left > 0U && left < n);
            /* a second merge while one is due is refused, nothing changed */
            const uint32_t merges = g_fs_parts.merges;
            assert_int_equal(merge_fastslam_begin(&g_fs_parts, &g_bm, &mc, &g_sc, NULL), COSLAM_E_MERGE_BUSY);
            assert_int_equal(g_fs_parts.merges, merges);
            assert_int_equal(g_fs_parts.merge_due_n, left);
        }
    }
    assert_int_equal(calls, (n + 2) / 3);
    assert_int_equal(parts.fused, whole.fused);
    assert_int_equal(parts.added, whole.added);
    assert_true(whole.fused > 0U && whole.added > 0U);
    for (uint16_t k = 0; k < n; ++k) {
        const fastslam_particle_t *a = &g_fs.particles[k];
        const fastslam_particle_t *b = &g_fs_parts.particles[k];
        assert_int_equal(a->n_lm, b->n_lm);
        assert_true(a->log_w == b->log_w);
        for (uint16_t j = 0; j < a->n_lm; ++j) {
            assert_memory_equal(fastslam_particle_lm(&g_fs, k, j), fastslam_particle_lm(&g_fs_parts, k, j),
                                sizeof(landmark_t));
        }
    }

    /* steps between the parts */
    rng_seed(&r, 41U);
    parts_case(&g_fs_parts, n, &r);
    mc.reweight_particles = 0U;
    assert_int_equal(merge_fastslam_begin(&g_fs_parts, &g_bm, &mc, &g_sc, NULL), COSLAM_OK);
    const uint32_t resamples = g_fs_parts.ctr.resamples;
    int steps = 0;
    left = n;
    while (left > 0U) {
        assert_int_equal(merge_fastslam_run(&g_fs_parts, &g_bm, &mc, &g_sc, NULL, budget, &left), COSLAM_OK);
        if (left == 0U) {
            break;
        }
        const odo_increment_t u = {0.05, 0.0, 0.01};
        assert_int_equal(fastslam_predict(&g_fs_parts, u), COSLAM_OK);
        const sighting_t z = {2.0, 0.1, 0};
        (void)fastslam_update(&g_fs_parts, &z, 1);
        steps++;
        assert_int_equal(g_fs_parts.ctr.resamples, resamples); /* held back */
    }
    assert_true(steps > 1);
    int moved = 0; /* the particles merged after steps moved in between */
    assert_true(g_fs_parts.ctr.resamples_deferred > 0U);
    for (uint16_t k = 0; k < n; ++k) {
        const fastslam_particle_t *pk = &g_fs_parts.particles[k];
        assert_false(pk->merge_due);
        moved += fabs(pk->merge_pose.x - pk->pose.x) > 0.01;
        /* the incoming landmarks this particle added are there once each,
         * where its pose at the merge's start put them */
        for (int i = 0; i < g_bm.n; ++i) {
            const uint32_t id = g_sc.new_id[i];
            int found = 0;
            for (uint16_t j = 0; j < pk->n_lm; ++j) {
                const landmark_t *lm = fastslam_particle_lm(&g_fs_parts, k, j);
                if (lm->id != id) {
                    continue;
                }
                found++;
                if (lm->n_obs == g_bm.n_obs[i] && lm->src_mask == g_bm.src_mask[i]) {
                    const point2_t w = pose2_apply(pk->merge_pose, g_bm.mean[i]);
                    assert_true(fabs(lm->mean.x - w.x) < 1e-12 && fabs(lm->mean.y - w.y) < 1e-12);
                }
            }
            assert_true(found <= 1);
        }
    }
    assert_true(moved > n / 2);
    /* the next update resamples again */
    const sighting_t z = {2.0, 0.1, 0};
    (void)fastslam_update(&g_fs_parts, &z, 1);
    assert_true(g_fs_parts.ctr.resamples > resamples);
}

static void test_merge_into_ekfslam(void **state)
{
    (void)state;
    ekfslam_config_t c = ekfslam_config_default();
    c.robot_id = 0;
    c.slam.noise.init_xy_var_m2 = 0.01;
    c.slam.noise.init_theta_var_rad2 = 0.001;
    c.slam.exist_confirm = c.slam.exist_init;
    const pose2_t p0 = {0.0, 0.0, 0.3};
    assert_int_equal(ekfslam_init(&g_ekf, &c, p0), COSLAM_OK);
    const sighting_t z = {2.0, -0.3, 0};
    assert_int_equal(ekfslam_update(&g_ekf, &z, 1), COSLAM_OK);
    point2_t own_rel;
    cov2_t own_rel_cov;
    ekfslam_landmark_relative(&g_ekf, 0, &own_rel, &own_rel_cov);
    const point2_t known = pose2_apply(p0, own_rel);
    const point2_t fresh = {-1.0, 3.0};
    incoming_two(p0, known, fresh, 0x2U);
    g_bm.mean[0].x += 0.05;
    g_bm.rel[0].x += 0.05;
    merge_config_t mc = merge_config_default();
    merge_stats_t st;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_into_ekfslam(&g_ekf, &g_bm, &mc, &g_sc, &st), COSLAM_OK);
    assert_int_equal(st.fused, 1);
    assert_int_equal(st.added, 1);
    assert_int_equal(g_ekf.n_lm, 2);
    /* the fused relative position is the Kalman fusion of the two relative estimates */
    point2_t want;
    cov2_t want_c;
    assert_int_equal(merge_fuse_kalman(own_rel, own_rel_cov, g_bm.mean[0], g_bm.cov[0], &want, &want_c), COSLAM_OK);
    point2_t rel;
    cov2_t rc;
    ekfslam_landmark_relative(&g_ekf, 0, &rel, &rc);
    ASSERT_NEAR(rel.x, want.x, 1e-6);
    ASSERT_NEAR(rel.y, want.y, 1e-6);
    ASSERT_NEAR(rc.xx, want_c.xx, 1e-6);
    ASSERT_NEAR(rc.yy, want_c.yy, 1e-6);
    /* the added landmark is correlated with the pose exactly like a sighting:
     * relative covariance = the incoming covariance */
    ekfslam_landmark_relative(&g_ekf, 1, &rel, &rc);
    ASSERT_NEAR(rel.x, g_bm.mean[1].x, 1e-9);
    ASSERT_NEAR(rc.xx, 0.01, 1e-9);
    ASSERT_NEAR(rc.yy, 0.01, 1e-9);
    assert_true(fabs(ekfslam_p(&g_ekf, 0, 5)) > 1e-6); /* cross-covariance with x */
    assert_int_equal(g_ekf.meta[1].src_mask, 0x2);
    /* the same map again: covariance intersection, no shrinking */
    const double before0 = ekfslam_p(&g_ekf, 3, 3);
    const double before1 = ekfslam_p(&g_ekf, 5, 5);
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_into_ekfslam(&g_ekf, &g_bm, &mc, &g_sc, &st), COSLAM_OK);
    assert_int_equal(st.fused_ci, 2);
    assert_int_equal(g_ekf.n_lm, 2);
    ASSERT_NEAR(ekfslam_p(&g_ekf, 3, 3), before0, 0.02 * before0);
    ASSERT_NEAR(ekfslam_p(&g_ekf, 5, 5), before1, 0.02 * before1);
}

/* EKF cov_rel against a Monte Carlo of the joint Gaussian of the state. */
static void test_relative_covariance(void **state)
{
    (void)state;
    ekfslam_config_t c = ekfslam_config_default();
    c.slam.noise.init_xy_var_m2 = 0.02;
    c.slam.noise.init_theta_var_rad2 = 0.01;
    const pose2_t p0 = {1.0, 0.5, 0.8};
    assert_int_equal(ekfslam_init(&g_ekf, &c, p0), COSLAM_OK);
    const sighting_t z = {3.0, 0.2, 0};
    assert_int_equal(ekfslam_update(&g_ekf, &z, 1), COSLAM_OK);
    point2_t rel;
    cov2_t rc;
    ekfslam_landmark_relative(&g_ekf, 0, &rel, &rc);
    /* sample (x, y, th, mx, my) from N(x, P) */
    double l[5][5] = {{0}};
    for (int j = 0; j < 5; ++j) {
        double d = ekfslam_p(&g_ekf, j, j);
        for (int k = 0; k < j; ++k) {
            d -= l[j][k] * l[j][k];
        }
        l[j][j] = sqrt(d);
        for (int i = j + 1; i < 5; ++i) {
            double s = ekfslam_p(&g_ekf, i, j);
            for (int k = 0; k < j; ++k) {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = s / l[j][j];
        }
    }
    rng_t r;
    rng_seed(&r, 21U);
    const int n = 20000;
    double sxx = 0, sxy = 0, syy = 0;
    for (int i = 0; i < n; ++i) {
        double g[5];
        double x[5];
        for (int k = 0; k < 5; ++k) {
            g[k] = rng_gauss(&r);
        }
        for (int a = 0; a < 5; ++a) {
            x[a] = g_ekf.x[a];
            for (int k = 0; k <= a; ++k) {
                x[a] += l[a][k] * g[k];
            }
        }
        const pose2_t ps = {x[0], x[1], x[2]};
        const point2_t ms = {x[3], x[4]};
        const point2_t q = pose2_apply_inverse(ps, ms);
        sxx += (q.x - rel.x) * (q.x - rel.x) / n;
        sxy += (q.x - rel.x) * (q.y - rel.y) / n;
        syy += (q.y - rel.y) * (q.y - rel.y) / n;
    }
    ASSERT_NEAR(sxx, rc.xx, 0.10 * rc.xx);
    ASSERT_NEAR(syy, rc.yy, 0.10 * rc.yy);
    ASSERT_NEAR(sxy, rc.xy, 0.10 * sqrt(rc.xx * rc.yy));
    /* and the exported relative covariance is that one */
    static map_estimate_t est;
    c.slam.exist_confirm = c.slam.exist_init;
    ekfslam_export(&g_ekf, &est);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_relative_pose_hand),
        cmocka_unit_test(test_relative_pose_monte_carlo),
        cmocka_unit_test(test_transformed_landmark_monte_carlo),
        cmocka_unit_test(test_fusion_rules),
        cmocka_unit_test(test_session_replay),
        cmocka_unit_test(test_session_restarted_sender),
        cmocka_unit_test(test_merge_into_fastslam),
        cmocka_unit_test(test_fastslam_pairing_brute_force),
        cmocka_unit_test(test_pair_table_full),
        cmocka_unit_test(test_check_lost_receiver),
        cmocka_unit_test(test_pair_table_full_ekf_in_parts),
        cmocka_unit_test(test_fastslam_merge_in_parts),
        cmocka_unit_test(test_merge_into_ekfslam),
        cmocka_unit_test(test_relative_covariance),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
