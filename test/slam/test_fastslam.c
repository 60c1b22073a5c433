/* Fast-SLAM white-box and API tests: resampling, mixture export, identities,
 * association rules, negative evidence, capacity and bad input, the 2.0
 * proposal against the analytic EKF update, reproducibility. */
#include "test_util.h"

#include <stdlib.h>
#include <string.h>

#include "coslam/fastslam.h"
#include "slam_run.h"

static fastslam_t g_fs;
static fastslam_t g_fs2;

static fastslam_config_t config(uint16_t n)
{
    fastslam_config_t c = fastslam_config_default();
    c.n_particles = n;
    return c;
}

static landmark_t make_lm(double x, double y, cov2_t c, uint32_t id, float exist)
{
    landmark_t lm;
    memset(&lm, 0, sizeof lm);
    lm.mean.x = x;
    lm.mean.y = y;
    lm.cov = c;
    lm.id = id;
    lm.exist = exist;
    lm.n_obs = 5;
    lm.src_mask = 1;
    return lm;
}

static void test_resampling_counts(void **state)
{
    (void)state;
    const uint16_t n = 10;
    const fastslam_config_t c = config(n);
    const double w[10] = {0.31, 0.02, 0.17, 0.0, 0.05, 0.15, 0.1, 0.07, 0.08, 0.05};
    double expected_mean[10] = {0};
    const int trials = 4000;
    for (int t = 0; t < trials; ++t) {
        const pose2_t p0 = {0.0, 0.0, 0.0};
        assert_int_equal(fastslam_init(&g_fs, &c, p0, (uint64_t)t), COSLAM_OK);
        for (uint16_t k = 0; k < n; ++k) {
            fastslam_particle_t *p = &g_fs.particles[k];
            p->pose.x = k;
            p->log_w = w[k] > 0.0 ? log(w[k]) : -INFINITY;
            const landmark_t lm = make_lm(k, 0.0, cov2_make(1, 0, 1), 100U + k, 3.0f);
            fastslam_particle_clear(&g_fs, k);
            assert_int_equal(fastslam_particle_add(&g_fs, k, &lm), COSLAM_OK);
        }
        fastslam_resample(&g_fs);
        int copies[10] = {0};
        for (uint16_t k = 0; k < n; ++k) {
            const fastslam_particle_t *p = &g_fs.particles[k];
            const int src = (int)p->pose.x;
            assert_true(src >= 0 && src < 10);
            /* the map travelled with the pose */
            assert_int_equal(p->n_lm, 1);
            assert_int_equal(fastslam_particle_lm(&g_fs, k, 0)->id, 100U + (uint32_t)src);
            ASSERT_NEAR(p->log_w, 0.0, 0.0);
            copies[src]++;
        }
        int total = 0;
        for (int k = 0; k < 10; ++k) {
            /* low-variance sampling: floor(N w) <= copies <= ceil(N w) */
            assert_true(copies[k] >= (int)floor(n * w[k] - 1e-9));
            assert_true(copies[k] <= (int)ceil(n * w[k] + 1e-9));
            total += copies[k];
            expected_mean[k] += copies[k];
        }
        assert_int_equal(total, n);
    }
    /* weight mass is preserved in expectation: E[copies] = N w */
    for (int k = 0; k < 10; ++k) {
        ASSERT_NEAR(expected_mean[k] / trials, n * w[k], 0.05);
    }
}

static void test_export_moment_match(void **state)
{
    (void)state;
    const fastslam_config_t c = config(4);
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 1U), COSLAM_OK);
    const double w[4] = {0.4, 0.3, 0.2, 0.1};
    const double theta[4] = {3.1, -3.1, 3.0, 2.9}; /* around the +-pi seam */
    const cov2_t ca = cov2_make(0.02, 0.005, 0.03);
    const cov2_t cb = cov2_make(0.04, -0.01, 0.02);
    for (int k = 0; k < 4; ++k) {
        fastslam_particle_t *p = &g_fs.particles[k];
        p->log_w = log(w[k]);
        p->pose.x = 1.0 + 0.1 * k;
        p->pose.y = -0.5 * k;
        p->pose.theta = theta[k];
        fastslam_particle_clear(&g_fs, (uint16_t)k);
        landmark_t lm;
        /* id 5 in particles 0, 1, 2 (weight 0.9) */
        if (k < 3) {
            lm = make_lm(2.0 + 0.1 * k, 1.0 - 0.2 * k, (k % 2) ? ca : cb, 5U, c.slam.exist_confirm);
            assert_int_equal(fastslam_particle_add(&g_fs, (uint16_t)k, &lm), COSLAM_OK);
        }
        /* id 6 only in particle 3 (weight 0.1 < 0.5): not exported */
        if (k == 3) {
            lm = make_lm(9.0, 9.0, ca, 6U, c.slam.exist_max);
            assert_int_equal(fastslam_particle_add(&g_fs, (uint16_t)k, &lm), COSLAM_OK);
        }
        /* id 7 everywhere but tentative: not exported */
        lm = make_lm(-3.0, 0.0, ca, 7U, c.slam.exist_confirm - 1.0f);
        assert_int_equal(fastslam_particle_add(&g_fs, (uint16_t)k, &lm), COSLAM_OK);
    }
    static map_estimate_t est;
    assert_int_equal(fastslam_export(&g_fs, &est), COSLAM_OK);
    assert_int_equal(est.n_landmarks, 1);
    const map_landmark_t *l = &est.lm[0];
    assert_int_equal(l->id, 5);
    /* direct mixture computation */
    double W = 0.0, mx = 0.0, my = 0.0;
    for (int k = 0; k < 3; ++k) {
        W += w[k];
        mx += w[k] * (2.0 + 0.1 * k);
        my += w[k] * (1.0 - 0.2 * k);
    }
    mx /= W;
    my /= W;
    double cxx = 0.0, cxy = 0.0, cyy = 0.0;
    for (int k = 0; k < 3; ++k) {
        const cov2_t ck = (k % 2) ? ca : cb;
        const double dx = 2.0 + 0.1 * k - mx;
        const double dy = 1.0 - 0.2 * k - my;
        cxx += w[k] * (ck.xx + dx * dx);
        cxy += w[k] * (ck.xy + dx * dy);
        cyy += w[k] * (ck.yy + dy * dy);
    }
    ASSERT_NEAR(l->mean.x, mx, 1e-12);
    ASSERT_NEAR(l->mean.y, my, 1e-12);
    ASSERT_NEAR(l->cov.xx, cxx / W, 1e-12);
    ASSERT_NEAR(l->cov.xy, cxy / W, 1e-12);
    ASSERT_NEAR(l->cov.yy, cyy / W, 1e-12);
    /* pose: circular mean of the heading across the seam */
    double ss = 0.0, sc = 0.0;
    for (int k = 0; k < 4; ++k) {
        ss += w[k] * sin(theta[k]);
        sc += w[k] * cos(theta[k]);
    }
    ASSERT_NEAR(angle_wrap(est.pose.theta - atan2(ss, sc)), 0.0, 1e-12);
    ASSERT_NEAR(est.pose.x, 0.4 * 1.0 + 0.3 * 1.1 + 0.2 * 1.2 + 0.1 * 1.3, 1e-12);
    double vth = 0.0;
    for (int k = 0; k < 4; ++k) {
        const double d = angle_wrap(theta[k] - est.pose.theta);
        vth += w[k] * d * d;
    }
    ASSERT_NEAR(est.pose_cov.m[2][2], vth, 1e-12);
    assert_true(vth < 0.05); /* not the naive variance of values near +-pi */
}

static void test_new_landmark_identity_shared(void **state)
{
    (void)state;
    const fastslam_config_t c = config(50);
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 3U), COSLAM_OK);
    const sighting_t z[2] = {{2.0, 0.1, 0}, {3.0, -0.2, 0}};
    assert_int_equal(fastslam_update(&g_fs, z, 2), COSLAM_OK);
    for (uint16_t k = 0; k < 50; ++k) {
        assert_int_equal(g_fs.particles[k].n_lm, 2);
        assert_int_equal(fastslam_particle_lm(&g_fs, k, 0)->id, fastslam_particle_lm(&g_fs, 0, 0)->id);
        assert_int_equal(fastslam_particle_lm(&g_fs, k, 1)->id, fastslam_particle_lm(&g_fs, 0, 1)->id);
    }
    assert_true(fastslam_particle_lm(&g_fs, 0, 0)->id != fastslam_particle_lm(&g_fs, 0, 1)->id);
    assert_int_equal(g_fs.ctr.landmarks_added, 2);
}

static void test_mutual_exclusion(void **state)
{
    (void)state;
    const fastslam_config_t c = config(20);
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 4U), COSLAM_OK);
    const sighting_t one = {2.0, 0.0, 0};
    assert_int_equal(fastslam_update(&g_fs, &one, 1), COSLAM_OK);
    /* two sightings a few cm apart, both compatible with the one landmark:
     * one is matched, the other is a distinct object beside it */
    const sighting_t two[2] = {{2.0, 0.0, 0}, {2.0, 0.02, 0}};
    assert_int_equal(fastslam_update(&g_fs, two, 2), COSLAM_OK);
    for (uint16_t k = 0; k < 20; ++k) {
        assert_int_equal(g_fs.particles[k].n_lm, 2);
        assert_int_equal(fastslam_particle_lm(&g_fs, k, 0)->n_obs, 2);
        assert_int_equal(fastslam_particle_lm(&g_fs, k, 1)->n_obs, 1);
    }
    /* signatures separate: a sighting of another class never matches */
    const sighting_t other = {2.0, 0.0, 1};
    assert_int_equal(fastslam_update(&g_fs, &other, 1), COSLAM_OK);
    assert_int_equal(g_fs.particles[0].n_lm, 3);
    assert_int_equal(fastslam_particle_lm(&g_fs, 0, 2)->signature, 1);
}

static void test_negative_evidence(void **state)
{
    (void)state;
    fastslam_config_t c = config(10);
    c.slam.exist_init = 1.0f;
    c.slam.exist_miss = 1.0f;
    c.slam.exist_hit = 1.0f;
    c.slam.exist_confirm = 3.0f;
    /* the rule without decay of confirmed landmarks (test_exist_decay.c has
     * the decay) */
    c.slam.exist_miss_confirmed = 0.0f;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 5U), COSLAM_OK);
    /* a real landmark, seen three times (confirmed), and a clutter sighting once */
    const sighting_t real = {2.0, 0.1, 0};
    const sighting_t both[2] = {{2.0, 0.1, 0}, {3.0, -0.3, 0}};
    assert_int_equal(fastslam_update(&g_fs, &real, 1), COSLAM_OK);
    assert_int_equal(fastslam_update(&g_fs, &real, 1), COSLAM_OK);
    assert_int_equal(fastslam_update(&g_fs, both, 2), COSLAM_OK);
    assert_int_equal(g_fs.particles[0].n_lm, 2);
    /* the clutter is in view but not seen again: 1 -> 0 -> removed */
    assert_int_equal(fastslam_update(&g_fs, &real, 1), COSLAM_OK);
    assert_int_equal(g_fs.particles[0].n_lm, 2);
    assert_int_equal(fastslam_update(&g_fs, &real, 1), COSLAM_OK);
    for (uint16_t k = 0; k < 10; ++k) {
        assert_int_equal(g_fs.particles[k].n_lm, 1);
    }
    /* the confirmed landmark survives any number of misses (occlusion) */
    for (int i = 0; i < 30; ++i) {
        assert_int_equal(fastslam_update(&g_fs, NULL, 0), COSLAM_OK);
    }
    assert_int_equal(g_fs.particles[0].n_lm, 1);
    static map_estimate_t est;
    assert_int_equal(fastslam_export(&g_fs, &est), COSLAM_OK);
    assert_int_equal(est.n_landmarks, 1);
    assert_true(g_fs.ctr.landmarks_removed >= 10U);
    /* a landmark out of view is not punished */
    const pose2_t far = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, far, 6U), COSLAM_OK);
    const sighting_t side = {2.0, 0.3, 0};
    assert_int_equal(fastslam_update(&g_fs, &side, 1), COSLAM_OK);
    const odo_increment_t turn = {0.0, 0.0, 1.5}; /* face away */
    c.slam.noise.odo_theta_var_rad2_per_m = 0.0;
    assert_int_equal(fastslam_predict(&g_fs, turn), COSLAM_OK);
    for (int i = 0; i < 5; ++i) {
        assert_int_equal(fastslam_update(&g_fs, NULL, 0), COSLAM_OK);
    }
    assert_int_equal(g_fs.particles[0].n_lm, 1);
}

static void test_capacity_and_bad_input(void **state)
{
    (void)state;
    fastslam_config_t c = config(5);
    c.slam.exist_confirm = c.slam.exist_init; /* confirmed at once and never */
    c.slam.exist_miss_confirmed = 0.0f;       /* decaying: no removal while filling */
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 7U), COSLAM_OK);
    /* fill the map with well separated landmarks, one per update: 8 ranges
     * x 8 bearings 0.1 rad apart, the next class for the next 64 (classes
     * never pair), so the layout holds any capacity (64 in the default
     * profile, 2,048 in the host one) */
    int added = 0;
    for (int i = 0; added < COSLAM_MAX_LANDMARKS; ++i) {
        const int q = i % 64;
        const sighting_t z = {1.0 + 0.5 * (q % 8), -0.4 + 0.1 * (q / 8), (uint8_t)((i / 64) % 256)};
        const coslam_status_t st = fastslam_update(&g_fs, &z, 1);
        assert_int_equal(st, COSLAM_OK);
        added = g_fs.particles[0].n_lm;
        assert_true(i < 4 * COSLAM_MAX_LANDMARKS);
    }
    static uint32_t before_id[COSLAM_MAX_LANDMARKS];
    for (uint16_t j = 0; j < COSLAM_MAX_LANDMARKS; ++j) {
        before_id[j] = fastslam_particle_lm(&g_fs, 0, j)->id;
    }
    const uint32_t drops = g_fs.ctr.lm_capacity_drops;
    const sighting_t far = {0.35, 0.0, 5};
    assert_int_equal(fastslam_update(&g_fs, &far, 1), COSLAM_E_CAPACITY);
    assert_int_equal(g_fs.ctr.lm_capacity_drops, drops + 5U);
    assert_int_equal(g_fs.particles[0].n_lm, COSLAM_MAX_LANDMARKS);
    for (int j = 0; j < COSLAM_MAX_LANDMARKS; ++j) {
        assert_int_equal(fastslam_particle_lm(&g_fs, 0, (uint16_t)j)->id, before_id[j]);
    }
    /* too many sightings in one update: processed up to capacity, rest counted */
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 8U), COSLAM_OK);
    sighting_t many[COSLAM_MAX_SIGHTINGS + 3];
    for (int i = 0; i < COSLAM_MAX_SIGHTINGS + 3; ++i) {
        many[i].range_m = 1.0 + 0.2 * i;
        many[i].bearing_rad = 0.0;
        many[i].signature = (uint8_t)i;
    }
    assert_int_equal(fastslam_update(&g_fs, many, COSLAM_MAX_SIGHTINGS + 3), COSLAM_E_CAPACITY);
    assert_int_equal(g_fs.ctr.sighting_capacity_drops, 3);
    assert_int_equal(g_fs.particles[0].n_lm, COSLAM_MAX_SIGHTINGS);
    /* NaN sightings and odometry are rejected, counted, and change nothing */
    const fastslam_particle_t snap = g_fs.particles[0];
    const sighting_t bad[3] = {{NAN, 0.0, 0}, {1.0, INFINITY, 0}, {-1.0, 0.0, 0}};
    assert_int_equal(fastslam_update(&g_fs, bad, 3), COSLAM_E_NUMERIC);
    assert_int_equal(g_fs.ctr.rejected_sightings, 3);
    const odo_increment_t nan_u = {NAN, 0.0, 0.0};
    assert_int_equal(fastslam_predict(&g_fs, nan_u), COSLAM_E_NUMERIC);
    assert_int_equal(g_fs.ctr.rejected_controls, 1);
    assert_int_equal(g_fs.particles[0].n_lm, snap.n_lm);
    ASSERT_NEAR(g_fs.particles[0].pose.x, snap.pose.x, 0.0);
    /* invalid configurations are refused */
    c.n_particles = 0;
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 1U), COSLAM_E_ARG);
    c = config(5);
    c.slam.noise.range_var_m2 = -1.0;
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 1U), COSLAM_E_ARG);
    c = config(5);
    c.resample_ess_fraction = 1.5;
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 1U), COSLAM_E_ARG);
}

/*
 * Fast-SLAM 2.0: with one particle and a known landmark, the pose drawn
 * from the improved proposal must be distributed as the EKF posterior of
 * the pose (mean and covariance), computed here independently.
 */
static void test_fs2_proposal_matches_ekf(void **state)
{
    (void)state;
    fastslam_config_t c = config(1);
    c.proposal = FASTSLAM_PROPOSAL_OPTIMAL;
    c.slam.noise.odo_xy_var_m2_per_m = 0.01;
    c.slam.noise.odo_theta_var_rad2_per_m = 0.01;
    c.slam.noise.range_var_m2 = 0.0004;
    c.slam.noise.range_var_per_m2 = 0.0;
    c.slam.noise.bearing_var_rad2 = 0.0004;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    const odo_increment_t u = {1.0, 0.0, 0.0};
    const landmark_t lm = make_lm(3.0, 1.0, cov2_make(1e-4, 0.0, 1e-4), 9U, 5.0f);
    /* the measured sighting disagrees with the odometry by a few cm */
    const pose2_t truth = {1.05, -0.03, 0.02};
    const sighting_t z = observe_predict(truth, lm.mean);
    /* analytic EKF update of the pose prior N(pose0 (+) u, V R V^T) */
    double g[3][3];
    double v[3][3];
    motion_jacobians(p0, u, g, v);
    const cov3_t prior = cov3_congruence(v, motion_noise_cov(&c.slam, u));
    const pose2_t mu0 = motion_apply(p0, u);
    lm_expect_t e;
    assert_int_equal(landmark_expect(&lm, &c.slam, mu0, &prior, &e), COSLAM_OK);
    double nu[2];
    observe_innovation(z, e.zhat, nu);
    double k[3][2];
    double cht[3][2];
    for (int r = 0; r < 3; ++r) {
        for (int q = 0; q < 2; ++q) {
            cht[r][q] = 0.0;
            for (int m = 0; m < 3; ++m) {
                cht[r][q] += prior.m[r][m] * e.h_pose[q][m];
            }
        }
        k[r][0] = cht[r][0] * e.s_inv.xx + cht[r][1] * e.s_inv.xy;
        k[r][1] = cht[r][0] * e.s_inv.xy + cht[r][1] * e.s_inv.yy;
    }
    const double mean[3] = {mu0.x + k[0][0] * nu[0] + k[0][1] * nu[1], mu0.y + k[1][0] * nu[0] + k[1][1] * nu[1],
                            mu0.theta + k[2][0] * nu[0] + k[2][1] * nu[1]};
    double post[3][3];
    for (int r = 0; r < 3; ++r) {
        for (int q = 0; q < 3; ++q) {
            post[r][q] = prior.m[r][q] - (k[r][0] * cht[q][0] + k[r][1] * cht[q][1]);
        }
    }
    /* Monte Carlo over independent single-particle filters */
    const int trials = 20000;
    double s[3] = {0, 0, 0};
    double ss[3][3] = {{0}};
    for (int t = 0; t < trials; ++t) {
        assert_int_equal(fastslam_init(&g_fs, &c, p0, 1000U + (uint64_t)t), COSLAM_OK);
        assert_int_equal(fastslam_particle_add(&g_fs, 0, &lm), COSLAM_OK);
        assert_int_equal(fastslam_predict(&g_fs, u), COSLAM_OK);
        assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
        const pose2_t p = g_fs.particles[0].pose;
        const double d[3] = {p.x - mean[0], p.y - mean[1], angle_wrap(p.theta - mean[2])};
        for (int r = 0; r < 3; ++r) {
            s[r] += d[r];
            for (int q = 0; q < 3; ++q) {
                ss[r][q] += d[r] * d[q];
            }
        }
    }
    for (int r = 0; r < 3; ++r) {
        ASSERT_NEAR(s[r] / trials, 0.0, 5.0 * sqrt(post[r][r] / trials));
        ASSERT_NEAR(ss[r][r] / trials, post[r][r], 0.05 * post[r][r]);
    }
    ASSERT_NEAR(ss[0][2] / trials, post[0][2], 0.05 * sqrt(post[0][0] * post[2][2]));
    /* the proposal moved the pose well away from the odometry-only mean */
    assert_true(fabs(mean[0] - mu0.x) > 10.0 * sqrt(post[0][0] / trials));
}


/* Revisits (fastslam.c "Revisits"): one Fast-SLAM 2.0 particle, sure of
 * itself (no motion since its last sample) but with a pose marginal that
 * says it may have drifted 0.3 m since an exact old landmark O was started.
 * It sights O 0.5 m farther than predicted: outside the ordinary gate (a new
 * landmark without the closure), inside the gate widened by the drift. The
 * closure moves the pose by D g, g = Hp^T (S + Hp D Hp^T)^-1 nu (computed
 * here from landmark_expect), a landmark R started later (anchor A_R, from
 * the pose) by its share W_R Phi^T g = A_R g (through G_R, a rotation about
 * its anchor), and neither a landmark E started exactly (no drift shared)
 * nor a partner's landmark F. A second old landmark of O's class that explains the sighting nearly
 * as well makes it ambiguous: no closure. */
static void revisit_setup(fastslam_config_t *c, int with_twin)
{
    *c = config(1);
    c->proposal = FASTSLAM_PROPOSAL_OPTIMAL;
    c->closure_unsupported_every = 1U; /* every particle closes: the formulas alone */
    c->slam.noise.range_var_m2 = 0.0004;
    c->slam.noise.range_var_per_m2 = 0.0;
    c->slam.noise.bearing_var_rad2 = 0.0004;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, c, p0, 7U), COSLAM_OK);
    const cov3_t exact = cov3_zero();
    const cov3_t a_r = cov3_diag(0.04, 0.04, 0.0009);
    landmark_t o = make_lm(3.0, 0.0, cov2_make(1e-4, 0.0, 1e-4), 1U, 5.0f);
    landmark_set_anchor(&o, &exact, (point2_t){0.0, 0.0});
    landmark_t r = make_lm(-5.0, 4.0, cov2_make(1e-4, 0.0, 1e-4), 2U, 5.0f);
    landmark_set_anchor(&r, &a_r, (point2_t){0.0, 0.0});
    landmark_t e = make_lm(-6.0, -4.0, cov2_make(1e-4, 0.0, 1e-4), 3U, 5.0f);
    landmark_set_anchor(&e, &exact, (point2_t){0.0, 0.0});
    assert_int_equal(fastslam_particle_add(&g_fs, 0, &o), COSLAM_OK);
    assert_int_equal(fastslam_particle_add(&g_fs, 0, &r), COSLAM_OK);
    assert_int_equal(fastslam_particle_add(&g_fs, 0, &e), COSLAM_OK);
    /* F: a partner's landmark (merged in), anchored like R */
    landmark_t f = make_lm(-5.0, -6.0, cov2_make(1e-4, 0.0, 1e-4), 5U, 5.0f);
    f.src_mask = 2U;
    landmark_set_anchor(&f, &a_r, (point2_t){0.0, 0.0});
    assert_int_equal(fastslam_particle_add(&g_fs, 0, &f), COSLAM_OK);
    if (with_twin) {
        landmark_t t = make_lm(3.0, 0.25, cov2_make(1e-4, 0.0, 1e-4), 4U, 5.0f);
        landmark_set_anchor(&t, &exact, (point2_t){0.0, 0.0});
        assert_int_equal(fastslam_particle_add(&g_fs, 0, &t), COSLAM_OK);
    }
    g_fs.particles[0].pose_marg = cov3_diag(0.09, 0.09, 0.0025);
    g_fs.ctr.updates = 100U; /* the landmarks (last_seen 0) are old */
}

static void test_revisit_closes_the_loop(void **state)
{
    (void)state;
    fastslam_config_t c;
    revisit_setup(&c, 0);
    const sighting_t z = {3.5, 0.0, 0}; /* range, bearing, class */
    /* the expected closure, from the same expectation */
    const landmark_t *o = fastslam_particle_lm(&g_fs, 0, 0);
    lm_expect_t e;
    assert_int_equal(landmark_expect(o, &c.slam, g_fs.particles[0].pose, &g_fs.particles[0].pending_cov, &e),
                     COSLAM_OK);
    assert_true(landmark_mahalanobis2(&e, z) > c.slam.new_landmark_chi2); /* ordinarily a new landmark */
    const cov3_t d = g_fs.particles[0].pose_marg;                          /* O's anchor is exact */
    cov2_t sw = e.s;
    for (int a = 0; a < 2; ++a) {
        for (int b = 0; b < 2; ++b) {
            double acc = 0.0;
            for (int i = 0; i < 3; ++i) {
                for (int j = 0; j < 3; ++j) {
                    acc += e.h_pose[a][i] * d.m[i][j] * e.h_pose[b][j];
                }
            }
            if (a == 0 && b == 0) sw.xx += acc;
            if (a == 0 && b == 1) sw.xy += acc;
            if (a == 1 && b == 1) sw.yy += acc;
        }
    }
    cov2_t si;
    assert_int_equal(cov2_inverse(sw, &si), COSLAM_OK);
    double nu[2];
    observe_innovation(z, e.zhat, nu);
    const double sn[2] = {si.xx * nu[0] + si.xy * nu[1], si.xy * nu[0] + si.yy * nu[1]};
    double g[3];
    for (int i = 0; i < 3; ++i) {
        g[i] = e.h_pose[0][i] * sn[0] + e.h_pose[1][i] * sn[1];
    }
    double dpose[3];
    for (int i = 0; i < 3; ++i) {
        dpose[i] = d.m[i][0] * g[0] + d.m[i][1] * g[1] + d.m[i][2] * g[2];
    }
    /* R: anchor at the origin, A_R = diag(0.04, 0.04, 0.0009) (as floats) */
    const double ax = (double)0.04f;
    const double at = (double)0.0009f;
    const double da[3] = {ax * g[0], ax * g[1], at * g[2]};
    const point2_t r_shift = {da[0] - 4.0 * da[2], da[1] + (-5.0) * da[2]};

    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    const fastslam_particle_t *p = &g_fs.particles[0];
    assert_int_equal(p->n_lm, 4); /* no copy of O */
    assert_int_equal(g_fs.ctr.closures, 1U);
    assert_true(dpose[0] < -0.4 && dpose[0] > -0.5); /* most of the 0.5 m */
    ASSERT_NEAR(p->pose.x, dpose[0], 1e-9);
    ASSERT_NEAR(p->pose.y, dpose[1], 1e-9);
    ASSERT_NEAR(p->pose.theta, dpose[2], 1e-9);
    const landmark_t *r = fastslam_particle_lm(&g_fs, 0, 1);
    ASSERT_NEAR(r->mean.x, -5.0 + r_shift.x, 1e-6);
    ASSERT_NEAR(r->mean.y, 4.0 + r_shift.y, 1e-6);
    assert_true(fabs(r_shift.x) > 0.1); /* it moved with the pose, about 0.44 of it */
    const landmark_t *ee = fastslam_particle_lm(&g_fs, 0, 2);
    ASSERT_NEAR(ee->mean.x, -6.0, 1e-12);
    ASSERT_NEAR(ee->mean.y, -4.0, 1e-12);
    const landmark_t *ff = fastslam_particle_lm(&g_fs, 0, 3); /* a partner's errors: unmoved */
    ASSERT_NEAR(ff->mean.x, -5.0, 1e-12);
    ASSERT_NEAR(ff->mean.y, -6.0, 1e-12);
    const landmark_t *o2 = fastslam_particle_lm(&g_fs, 0, 0);
    assert_true(hypot(o2->mean.x - 3.0, o2->mean.y) < 0.02); /* the old landmark stays */
    assert_int_equal(o2->last_seen, 101U);
    /* the pose marginal learnt the drift */
    assert_true(p->pose_marg.m[0][0] < 0.5 * 0.09);

    /* off: the same sighting starts a copy, nothing moves */
    revisit_setup(&c, 0);
    c.closure_drift_ratio = 0.0;
    g_fs.cfg.closure_drift_ratio = 0.0;
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    assert_int_equal(g_fs.particles[0].n_lm, 5);
    assert_int_equal(g_fs.ctr.closures, 0U);
    ASSERT_NEAR(g_fs.particles[0].pose.x, 0.0, 1e-12);
    ASSERT_NEAR(fastslam_particle_lm(&g_fs, 0, 1)->mean.x, -5.0, 1e-12);

    /* recently seen: not a revisit */
    revisit_setup(&c, 0);
    g_fs.ctr.updates = 10U;
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures, 0U);
    assert_int_equal(g_fs.particles[0].n_lm, 5);

    /* O holds a partner's information (merged): its error is no longer its
     * anchor's, so it closes nothing */
    revisit_setup(&c, 0);
    {
        landmark_t om = *fastslam_particle_lm(&g_fs, 0, 0);
        om.src_mask = 3U;
        assert_int_equal(fastslam_particle_set(&g_fs, 0, 0, &om), COSLAM_OK);
    }
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures, 0U);
    assert_int_equal(g_fs.particles[0].n_lm, 5);

    /* after a merge: no revisits at all (the merged map is in a frame the
     * anchors do not describe) */
    revisit_setup(&c, 0);
    g_fs.merges = 1U;
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures, 0U);

    /* a twin of O that explains the sighting nearly as well: ambiguous */
    revisit_setup(&c, 1);
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures, 0U);
    ASSERT_NEAR(g_fs.particles[0].pose.x, 0.0, 1e-12);

    /* a bad configuration is refused */
    c = config(1);
    c.closure_drift_ratio = -1.0;
    assert_int_equal(fastslam_init(&g_fs2, &c, (pose2_t){0.0, 0.0, 0.0}, 1U), COSLAM_E_ARG);
    c = config(1);
    c.closure_ambiguity_ll = NAN;
    assert_int_equal(fastslam_init(&g_fs2, &c, (pose2_t){0.0, 0.0, 0.0}, 1U), COSLAM_E_ARG);
    c = config(1);
    c.closure_misses_per_support = -1.0;
    assert_int_equal(fastslam_init(&g_fs2, &c, (pose2_t){0.0, 0.0, 0.0}, 1U), COSLAM_E_ARG);
}

/* An old landmark of class `sig`, started exactly (the closure does not move it). */
static void add_old(double x, double y, uint8_t sig)
{
    const cov3_t exact = cov3_zero();
    landmark_t l = make_lm(x, y, cov2_make(1e-4, 0.0, 1e-4), 20U + g_fs.particles[0].n_lm, 5.0f);
    l.signature = sig;
    landmark_set_anchor(&l, &exact, (point2_t){0.0, 0.0});
    assert_int_equal(fastslam_particle_add(&g_fs, 0, &l), COSLAM_OK);
}

/* A lone sighting of O (revisit_setup) with closure_unsupported_every
 * `every` and closure_chance_max `chance`, optionally with a recent
 * landmark of O's class at (3.0, 0.6): the closures and refusals counted. */
static void lone_revisit(uint16_t every, double chance, int neighbour, uint32_t closures, uint32_t unsupported)
{
    fastslam_config_t c;
    const sighting_t z = {3.5, 0.0, 0};
    revisit_setup(&c, 0);
    g_fs.cfg.closure_unsupported_every = every;
    g_fs.cfg.closure_chance_max = chance;
    if (neighbour) {
        add_old(3.0, 0.6, 0U);
        const uint16_t last = (uint16_t)(g_fs.particles[0].n_lm - 1U);
        landmark_t nb = *fastslam_particle_lm(&g_fs, 0, last);
        nb.last_seen = 99U; /* recent: not a revisit itself */
        assert_int_equal(fastslam_particle_set(&g_fs, 0, last, &nb), COSLAM_OK);
    }
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures, closures);
    assert_int_equal(g_fs.ctr.closures_unsupported, unsupported);
}

/* Revisits the frame supports (closure_misses_per_support): the set-up of
 * test_revisit_closes_the_loop with the check on for its one particle. A
 * lone sighting of O is not closed: the particle starts a landmark and
 * waits. With a second old landmark S that, from the corrected pose,
 * explains a second sighting, it closes as before. With, besides, three
 * confirmed old landmarks that only the corrected pose puts in view (just
 * outside the field of view from the present one) and nothing sights, 3
 * misses > 2 x 1 support: not closed. A particle with k % N == N - 1 closes
 * without support. */
static void test_revisit_needs_support(void **state)
{
    (void)state;
    fastslam_config_t c;
    const sighting_t z = {3.5, 0.0, 0};
    /* the corrected pose, from the closure with the check off */
    revisit_setup(&c, 0);
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures, 1U);
    const pose2_t q = g_fs.particles[0].pose;
    assert_true(q.x < -0.4);

    /* alone: unsupported, a landmark is started, nothing moves */
    revisit_setup(&c, 0);
    g_fs.cfg.closure_unsupported_every = 2U; /* particle 0 of 1: checks */
    g_fs.cfg.closure_chance_max = 0.0;       /* support asked always */
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures, 0U);
    assert_int_equal(g_fs.ctr.closures_unsupported, 1U);
    assert_int_equal(g_fs.particles[0].n_lm, 5);
    ASSERT_NEAR(g_fs.particles[0].pose.x, 0.0, 1e-12);
    ASSERT_NEAR(fastslam_particle_lm(&g_fs, 0, 1)->mean.x, -5.0, 1e-12);

    /* supported by S (class 2), sighted from the corrected pose: both
     * sightings close (each supports the other), no copy */
    const point2_t s_at = {2.0, 0.8};
    sighting_t zz[2] = {z, observe_predict(q, s_at)};
    zz[1].signature = 2U;
    revisit_setup(&c, 0);
    g_fs.cfg.closure_unsupported_every = 2U;
    g_fs.cfg.closure_chance_max = 0.0;
    add_old(s_at.x, s_at.y, 2U);
    assert_int_equal(fastslam_update(&g_fs, zz, 2), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures_unsupported, 0U);
    assert_int_equal(g_fs.ctr.closures, 2U);
    assert_int_equal(g_fs.particles[0].n_lm, 5);
    assert_true(hypot(g_fs.particles[0].pose.x - q.x, g_fs.particles[0].pose.y - q.y) < 0.02);

    /* ... and three certain misses that only the corrected pose makes:
     * each closure has 1 support and 3 misses, refused */
    revisit_setup(&c, 0);
    g_fs.cfg.closure_unsupported_every = 2U;
    g_fs.cfg.closure_chance_max = 0.0;
    add_old(s_at.x, s_at.y, 2U);
    add_old(1.0, 0.55, 3U);  /* bearing 0.50 rad from the present pose, 0.36 from q */
    add_old(1.2, -0.6, 3U);  /* -0.46 and -0.35 */
    add_old(0.8, 0.45, 3U);  /* 0.51 and 0.35 (in view: |bearing| <= 0.39) */
    assert_int_equal(fastslam_update(&g_fs, zz, 2), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures, 0U);
    assert_int_equal(g_fs.ctr.closures_unsupported, 2U);
    ASSERT_NEAR(g_fs.particles[0].pose.x, 0.0, 0.05); /* the proposal's small step only */
    /* two misses would be allowed (2 x 1 support); a landmark missed from
     * the present pose as well is not the closure's miss */
    revisit_setup(&c, 0);
    g_fs.cfg.closure_unsupported_every = 2U;
    g_fs.cfg.closure_chance_max = 0.0;
    add_old(s_at.x, s_at.y, 2U);
    add_old(1.0, 0.55, 3U);
    add_old(1.2, -0.6, 3U);
    add_old(2.0, -0.3, 3U); /* in view from both poses, never sighted */
    assert_int_equal(fastslam_update(&g_fs, zz, 2), COSLAM_OK);
    assert_int_equal(g_fs.ctr.closures_unsupported, 0U);
    assert_int_equal(g_fs.ctr.closures, 2U);

    /* a lone sighting of O: N = 1 closes it (k % 1 == 0), N = 0 does not;
     * closure_chance_max (1, the default): with no other landmark of the
     * class in the widened gate a chance pairing is unlikely and it
     * closes; a recent one at (3.0, 0.6) (d2 about 5 in the widened gate,
     * far outside the ordinary one) asks for support */
    lone_revisit(1U, 0.0, 0, 1U, 0U);
    lone_revisit(0U, 0.0, 0, 0U, 1U);
    lone_revisit(0U, 1.0, 0, 1U, 0U);
    lone_revisit(0U, 1.0, 1, 0U, 1U);
    c = config(1);
    c.closure_chance_max = NAN;
    assert_int_equal(fastslam_init(&g_fs2, &c, (pose2_t){0.0, 0.0, 0.0}, 1U), COSLAM_E_ARG);
}

static void test_reproducible(void **state)
{
    (void)state;
    synth_config_t sc = synth_config_default(11U, 20);
    sc.loops = 0.5;
    static synth_world_t w;
    static synth_step_t st;
    for (int variant = 0; variant < 2; ++variant) {
        fastslam_config_t c = config(30);
        c.proposal = variant ? FASTSLAM_PROPOSAL_OPTIMAL : FASTSLAM_PROPOSAL_MOTION;
        synth_init(&w, &sc);
        assert_int_equal(fastslam_init(&g_fs, &c, synth_start_pose(&sc), 99U), COSLAM_OK);
        assert_int_equal(fastslam_init(&g_fs2, &c, synth_start_pose(&sc), 99U), COSLAM_OK);
        while (synth_next(&w, &st)) {
            fastslam_predict(&g_fs, st.u);
            fastslam_predict(&g_fs2, st.u);
            if (st.is_frame) {
                fastslam_update(&g_fs, st.z, st.n_z);
                fastslam_update(&g_fs2, st.z, st.n_z);
            }
        }
        static map_estimate_t a;
        static map_estimate_t b;
        memset(&a, 0, sizeof a);
        memset(&b, 0, sizeof b);
        fastslam_export(&g_fs, &a);
        fastslam_export(&g_fs2, &b);
        assert_true(a.n_landmarks > 0);
        assert_int_equal(a.n_landmarks, b.n_landmarks);
        assert_memory_equal(&a.pose, &b.pose, sizeof a.pose);
        for (int i = 0; i < a.n_landmarks; ++i) {
            assert_memory_equal(&a.lm[i].mean, &b.lm[i].mean, sizeof a.lm[i].mean);
            assert_memory_equal(&a.lm[i].cov, &b.lm[i].cov, sizeof a.lm[i].cov);
        }
    }
}

/* The export in parts (fastslam_export_begin / _run): with no step in
 * between, fastslam_export_whole bit for bit; with predictions in between,
 * still the export of the moment it began (weights, poses and pose
 * marginals were taken then, and predictions move no landmark); resampling
 * waits for it; a second export is refused while it runs; a landmark gone
 * from every particle between the passes is left out, not exported with a
 * zero covariance. */
static void export_parts_world(void)
{
    synth_config_t sc = synth_config_default(12U, 20);
    sc.loops = 0.5;
    static synth_world_t w;
    static synth_step_t st;
    fastslam_config_t c = config(30);
    c.proposal = FASTSLAM_PROPOSAL_OPTIMAL;
    synth_init(&w, &sc);
    assert_int_equal(fastslam_init(&g_fs, &c, synth_start_pose(&sc), 5U), COSLAM_OK);
    while (synth_next(&w, &st)) {
        fastslam_predict(&g_fs, st.u);
        if (st.is_frame) {
            fastslam_update(&g_fs, st.z, st.n_z);
        }
    }
}

static int export_in_parts(fastslam_t *fs, map_whole_t *out, int predict_between, coslam_status_t *st)
{
    int done = 0;
    int calls = 0;
    while (!done) {
        uint32_t spent = 0U;
        *st = fastslam_export_run(fs, out, 1U, &done, &spent);
        assert_true(spent >= FASTSLAM_EXPORT_UNITS_PARTICLE);
        calls++;
        if (predict_between) {
            const odo_increment_t u = {0.05, 0.01, 0.02};
            assert_int_equal(fastslam_predict(fs, u), COSLAM_OK);
        }
    }
    return calls;
}

static void assert_same_whole(const map_whole_t *a, const map_whole_t *b)
{
    assert_int_equal(a->n_landmarks, b->n_landmarks);
    assert_memory_equal(&a->pose, &b->pose, sizeof a->pose);
    assert_memory_equal(&a->pose_cov, &b->pose_cov, sizeof a->pose_cov);
    assert_memory_equal(a->lm, b->lm, sizeof a->lm[0] * a->n_landmarks);
}

static void test_export_in_parts(void **state)
{
    (void)state;
    export_parts_world();
    static map_whole_t whole;
    static map_whole_t parts;
    static map_estimate_t est;
    assert_int_equal(fastslam_export_whole(&g_fs, &whole), COSLAM_OK);
    assert_true(whole.n_landmarks > 5);
    const uint16_t n = g_fs.cfg.n_particles;
    uint32_t spent = 0U;
    int done = 0;

    /* one particle a call: both passes, the whole export bit for bit */
    memcpy(&g_fs2, &g_fs, sizeof g_fs);
    assert_int_equal(fastslam_export_begin(&g_fs2), COSLAM_OK);
    assert_int_equal(fastslam_export_begin(&g_fs2), COSLAM_E_MERGE_BUSY);
    assert_int_equal(fastslam_export_whole(&g_fs2, &parts), COSLAM_E_MERGE_BUSY);
    assert_int_equal(fastslam_export(&g_fs2, &est), COSLAM_E_MERGE_BUSY);
    coslam_status_t st = COSLAM_E_ARG;
    memset(&parts, 0, sizeof parts);
    assert_int_equal(export_in_parts(&g_fs2, &parts, 0, &st), 2 * n);
    assert_int_equal(st, COSLAM_OK);
    assert_same_whole(&parts, &whole);
    assert_false(g_fs2.export_due);
    assert_int_equal(fastslam_export_run(&g_fs2, &parts, 0U, &done, &spent), COSLAM_E_ARG); /* none under way */

    /* the message's map (fastslam_export's, capped) in parts */
    static map_estimate_t est_parts;
    assert_int_equal(fastslam_export(&g_fs, &est), COSLAM_OK);
    memcpy(&g_fs2, &g_fs, sizeof g_fs);
    assert_int_equal(fastslam_export_begin(&g_fs2), COSLAM_OK);
    memset(&est_parts, 0, sizeof est_parts);
    int msg_calls = 0;
    done = 0;
    while (!done) {
        assert_int_equal(fastslam_export_run_msg(&g_fs2, &est_parts, 1U, &done, &spent), COSLAM_OK);
        msg_calls++;
    }
    assert_int_equal(msg_calls, 2 * n);
    assert_int_equal(est_parts.n_landmarks, est.n_landmarks);
    assert_memory_equal(&est_parts.pose, &est.pose, sizeof est.pose);
    assert_memory_equal(est_parts.lm, est.lm, sizeof est.lm[0] * est.n_landmarks);

    /* predictions in between: the export of the moment it began */
    memcpy(&g_fs2, &g_fs, sizeof g_fs);
    assert_int_equal(fastslam_export_begin(&g_fs2), COSLAM_OK);
    memset(&parts, 0, sizeof parts);
    (void)export_in_parts(&g_fs2, &parts, 1, &st);
    assert_int_equal(st, COSLAM_OK);
    assert_same_whole(&parts, &whole);
    assert_true(g_fs2.particles[0].pose.x != g_fs.particles[0].pose.x); /* the predictions did move the particles */

    /* resampling waits for the export */
    memcpy(&g_fs2, &g_fs, sizeof g_fs);
    assert_int_equal(fastslam_export_begin(&g_fs2), COSLAM_OK);
    for (uint16_t k = 1; k < n; ++k) {
        g_fs2.particles[k].log_w = -50.0;
    }
    const uint32_t resamples = g_fs2.ctr.resamples;
    const uint32_t deferred = g_fs2.ctr.resamples_deferred;
    fastslam_reweighted(&g_fs2);
    assert_int_equal(g_fs2.ctr.resamples, resamples);
    assert_int_equal(g_fs2.ctr.resamples_deferred, deferred + 1U);
    assert_int_equal(fastslam_export_run(&g_fs2, &parts, 0U, &done, &spent), COSLAM_OK);
    assert_true(done);
    fastslam_reweighted(&g_fs2);
    assert_int_equal(g_fs2.ctr.resamples, resamples + 1U);

    /* every landmark gone between the passes: none exported */
    memcpy(&g_fs2, &g_fs, sizeof g_fs);
    assert_int_equal(fastslam_export_begin(&g_fs2), COSLAM_OK);
    while (g_fs2.export_scratch.job_pass == 1U) {
        assert_int_equal(fastslam_export_run(&g_fs2, &parts, 1U, &done, &spent), COSLAM_OK);
    }
    for (uint16_t k = 0; k < n; ++k) {
        fastslam_particle_clear(&g_fs2, k);
    }
    assert_int_equal(fastslam_export_run(&g_fs2, &parts, 0U, &done, &spent), COSLAM_OK);
    assert_true(done);
    assert_int_equal(parts.n_landmarks, 0);

    /* dropped: the table is free again */
    memcpy(&g_fs2, &g_fs, sizeof g_fs);
    assert_int_equal(fastslam_export_begin(&g_fs2), COSLAM_OK);
    assert_int_equal(fastslam_export_run(&g_fs2, &parts, 1U, &done, &spent), COSLAM_OK);
    fastslam_export_abort(&g_fs2);
    assert_int_equal(fastslam_export_whole(&g_fs2, &parts), COSLAM_OK);
    assert_same_whole(&parts, &whole);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_resampling_counts),
        cmocka_unit_test(test_export_moment_match),
        cmocka_unit_test(test_new_landmark_identity_shared),
        cmocka_unit_test(test_mutual_exclusion),
        cmocka_unit_test(test_negative_evidence),
        cmocka_unit_test(test_capacity_and_bad_input),
        cmocka_unit_test(test_fs2_proposal_matches_ekf),
        cmocka_unit_test(test_revisit_closes_the_loop),
        cmocka_unit_test(test_revisit_needs_support),
        cmocka_unit_test(test_reproducible),
        cmocka_unit_test(test_export_in_parts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
