/* Landmark EKF, existence bookkeeping and the association helpers. */
#include "test_util.h"

#include <string.h>

#include "coslam/landmark.h"
#include "coslam/observe.h"
#include "coslam/rng.h"

static slam_params_t params(void)
{
    slam_params_t p = slam_params_default();
    p.noise.range_var_m2 = 0.01;
    p.noise.range_var_per_m2 = 0.0;
    p.noise.bearing_var_rad2 = 0.0025;
    p.noise.lm_init_var_m2 = 0.0;
    return p;
}

/* landmark_d2_lower_bound never exceeds the exact distance (random poses,
 * landmarks, covariances and sightings, with and without a pose
 * covariance), and is tight enough to be useful: a sighting on the other
 * side of the robot is far beyond the new-landmark band */
static void test_d2_lower_bound(void **state)
{
    (void)state;
    slam_params_t p = slam_params_default();
    rng_t rng;
    rng_seed(&rng, 31U);
    int useful = 0;
    for (int t = 0; t < 20000; ++t) {
        landmark_t lm;
        memset(&lm, 0, sizeof lm);
        lm.mean = (point2_t){rng_uniform(&rng) * 12.0 - 6.0, rng_uniform(&rng) * 12.0 - 6.0};
        const double a = 0.001 + rng_uniform(&rng) * 0.3;
        const double b = 0.001 + rng_uniform(&rng) * 0.3;
        const double c = (rng_uniform(&rng) * 2.0 - 1.0) * 0.9 * sqrt(a * b);
        lm.cov = cov2_make(a, c, b);
        const pose2_t pose = {rng_uniform(&rng) * 2.0 - 1.0, rng_uniform(&rng) * 2.0 - 1.0,
                              (rng_uniform(&rng) * 2.0 - 1.0) * COSLAM_PI};
        double g[3][3];
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                g[i][j] = rng_gauss(&rng) * 0.2;
            }
        }
        const cov3_t pc = cov3_congruence(g, cov3_diag(1.0, 1.0, 1.0));
        const cov3_t *pcp = (t % 2 == 0) ? &pc : NULL;
        const sighting_t z = {0.3 + rng_uniform(&rng) * 6.0, (rng_uniform(&rng) * 2.0 - 1.0) * COSLAM_PI, 0};
        lm_expect_t e;
        if (landmark_expect(&lm, &p, pose, pcp, &e) != COSLAM_OK) {
            continue;
        }
        const double d2 = landmark_mahalanobis2(&e, z);
        const sighting_t zhat = observe_predict(pose, lm.mean);
        const lm_d2_bound_t bound = landmark_d2_bound_prepare(&lm, &p, pcp, zhat);
        const double lb = landmark_d2_lower_bound(&bound, z);
        assert_true(lb >= 0.0);
        assert_true(lb <= d2 * (1.0 + 1e-9) + 1e-12);
        useful += lb > p.new_landmark_chi2;
    }
    /* most random pairs are far apart: the bound must say so for many */
    assert_true(useful > 5000);
    /* no bound from a NaN covariance */
    landmark_t lm;
    memset(&lm, 0, sizeof lm);
    lm.mean = (point2_t){2.0, 0.0};
    lm.cov = cov2_make(NAN, 0.0, 0.01);
    const sighting_t zhat = observe_predict((pose2_t){0.0, 0.0, 0.0}, lm.mean);
    const lm_d2_bound_t bound = landmark_d2_bound_prepare(&lm, &p, NULL, zhat);
    assert_true(landmark_d2_lower_bound(&bound, (sighting_t){2.0, 3.0, 0}) == 0.0);
}

static void test_init_hand_computed(void **state)
{
    (void)state;
    slam_params_t p = params();
    const pose2_t pose = {1.0, 1.0, COSLAM_PI / 2.0};
    const sighting_t z = {2.0, 0.0, 3};
    landmark_t lm;
    assert_int_equal(landmark_init(&lm, &p, pose, z, 7U, 0x4U), COSLAM_OK);
    ASSERT_NEAR(lm.mean.x, 1.0, 1e-12);
    ASSERT_NEAR(lm.mean.y, 3.0, 1e-12);
    /* G_z = [[0, -2], [1, 0]]: cov = diag(4 * 0.0025, 0.01) */
    ASSERT_NEAR(lm.cov.xx, 0.01, 1e-15);
    ASSERT_NEAR(lm.cov.xy, 0.0, 1e-15);
    ASSERT_NEAR(lm.cov.yy, 0.01, 1e-15);
    assert_int_equal(lm.id, 7);
    assert_int_equal(lm.src_mask, 0x4);
    assert_int_equal(lm.signature, 3);
    assert_int_equal(lm.n_obs, 1);
    /* w8 adds to both axes */
    p.noise.lm_init_var_m2 = 0.5;
    assert_int_equal(landmark_init(&lm, &p, pose, z, 7U, 0x4U), COSLAM_OK);
    ASSERT_NEAR(lm.cov.xx, 0.51, 1e-12);
    ASSERT_NEAR(lm.cov.yy, 0.51, 1e-12);
}

static void test_kalman_update_hand_computed(void **state)
{
    (void)state;
    const slam_params_t p = params();
    const pose2_t pose = {0.0, 0.0, 0.0};
    landmark_t lm;
    lm.mean.x = 2.0;
    lm.mean.y = 0.0;
    lm.cov = cov2_make(0.04, 0.0, 0.09);
    lm.n_obs = 1;
    lm.signature = 0;
    lm_expect_t e;
    assert_int_equal(landmark_expect(&lm, &p, pose, NULL, &e), COSLAM_OK);
    /* H = [[1, 0], [0, 0.5]], S = diag(0.05, 0.025) */
    ASSERT_NEAR(e.s.xx, 0.05, 1e-15);
    ASSERT_NEAR(e.s.xy, 0.0, 1e-15);
    ASSERT_NEAR(e.s.yy, 0.025, 1e-15);
    const sighting_t z = {2.1, 0.05, 0};
    const double d2 = landmark_mahalanobis2(&e, z);
    ASSERT_NEAR(d2, 0.3, 1e-12);
    ASSERT_NEAR(landmark_log_lik(&e, d2), -log(COSLAM_TWO_PI * sqrt(0.05 * 0.025)) - 0.15, 1e-12);
    landmark_update(&lm, &p, &e, z);
    /* K = diag(0.8, 1.8), nu = (0.1, 0.05) */
    ASSERT_NEAR(lm.mean.x, 2.08, 1e-12);
    ASSERT_NEAR(lm.mean.y, 0.09, 1e-12);
    ASSERT_NEAR(lm.cov.xx, 0.008, 1e-15);
    ASSERT_NEAR(lm.cov.xy, 0.0, 1e-15);
    ASSERT_NEAR(lm.cov.yy, 0.009, 1e-15);
    assert_int_equal(lm.n_obs, 2);
}

/* The track-offset floor (slam_params_t track_offset_*): off, a landmark
 * sighted 1,000 times from one pose ends with covariance Q / 1000; with
 * the floor it ends at the offset's covariance, analytic for a landmark
 * straight ahead at 2 m: diag(4 v_r, 4 v_b) (range along x, bearing times
 * the range across). From another pose (bearing 90 deg) the floor only
 * adds: the result dominates both the old covariance and the new floor.
 * Both weights 0 leave landmark_update bit for bit as it was. */
static void test_track_offset_floor(void **state)
{
    (void)state;
    slam_params_t p = params();
    const pose2_t pose = {0.0, 0.0, 0.0};
    landmark_t lm;
    memset(&lm, 0, sizeof lm);
    lm.mean = (point2_t){2.0, 0.0};
    lm.cov = cov2_make(0.04, 0.0, 0.09);
    lm_expect_t e;
    const sighting_t z = {2.0, 0.0, 0};
    landmark_t off = lm;
    for (int i = 0; i < 1000; ++i) {
        assert_int_equal(landmark_expect(&off, &p, pose, NULL, &e), COSLAM_OK);
        landmark_update(&off, &p, &e, z);
    }
    assert_true(off.cov.xx < 0.01 / 900.0 && off.cov.yy < 4.0 * 0.0025 / 900.0);
    /* floor off: the helper returns its input unchanged */
    const cov2_t c0 = cov2_make(0.3, 0.1, 0.2);
    const cov2_t c1 = landmark_offset_floor(&p, &e, c0);
    assert_true(c1.xx == c0.xx && c1.xy == c0.xy && c1.yy == c0.yy);

    p.track_offset_range_var_per_m2 = 0.0017;
    p.track_offset_bearing_var_rad2 = 7.7e-5;
    landmark_t on = lm;
    for (int i = 0; i < 1000; ++i) {
        assert_int_equal(landmark_expect(&on, &p, pose, NULL, &e), COSLAM_OK);
        landmark_update(&on, &p, &e, z);
    }
    ASSERT_NEAR(on.cov.xx, 4.0 * 0.0017, 1e-12);
    ASSERT_NEAR(on.cov.xy, 0.0, 1e-12);
    ASSERT_NEAR(on.cov.yy, 4.0 * 7.7e-5, 1e-12);

    /* seen from the side (robot at (2, -2) facing +y, the landmark 2 m
     * ahead): the floor is now diag(4 v_b, 4 v_r); the result dominates it
     * and the covariance it started from */
    const pose2_t side = {2.0, -2.0, 0.5 * COSLAM_PI};
    const cov2_t before = on.cov;
    assert_int_equal(landmark_expect(&on, &p, side, NULL, &e), COSLAM_OK);
    const cov2_t floor_side = cov2_make(4.0 * 7.7e-5, 0.0, 4.0 * 0.0017);
    const cov2_t got = landmark_offset_floor(&p, &e, before);
    double lmin;
    double lmax;
    cov2_eigenvalues(cov2_make(got.xx - floor_side.xx, got.xy - floor_side.xy, got.yy - floor_side.yy), &lmin, &lmax);
    assert_true(lmin > -1e-12);
    cov2_eigenvalues(cov2_make(got.xx - before.xx, got.xy - before.xy, got.yy - before.yy), &lmin, &lmax);
    assert_true(lmin > -1e-12);
    ASSERT_NEAR(got.xx, fmax(before.xx, floor_side.xx), 1e-12); /* diagonal case: elementwise max */
    ASSERT_NEAR(got.yy, fmax(before.yy, floor_side.yy), 1e-12);
}

/* The update against the information form: Sigma'^-1 = Sigma^-1 + H^T Q^-1 H
 * for a general (rotated, correlated) case. */
static void test_kalman_update_information_form(void **state)
{
    (void)state;
    const slam_params_t p = params();
    const pose2_t pose = {0.3, -0.2, 0.7};
    landmark_t lm;
    lm.mean.x = 1.9;
    lm.mean.y = 1.4;
    lm.cov = cov2_make(0.05, 0.02, 0.03);
    lm.n_obs = 1;
    lm.signature = 0;
    lm_expect_t e;
    assert_int_equal(landmark_expect(&lm, &p, pose, NULL, &e), COSLAM_OK);
    const cov2_t prior = lm.cov;
    landmark_update(&lm, &p, &e, e.zhat);
    cov2_t prior_inv;
    cov2_t post_inv;
    assert_int_equal(cov2_inverse(prior, &prior_inv), COSLAM_OK);
    assert_int_equal(cov2_inverse(lm.cov, &post_inv), COSLAM_OK);
    const cov2_t qinv = cov2_make(1.0 / 0.01, 0.0, 1.0 / 0.0025);
    double ht[2][2] = {{e.h_lm[0][0], e.h_lm[1][0]}, {e.h_lm[0][1], e.h_lm[1][1]}};
    const cov2_t info = cov2_add(prior_inv, cov2_congruence(ht, qinv));
    ASSERT_NEAR(post_inv.xx, info.xx, 1e-9 * info.xx);
    ASSERT_NEAR(post_inv.xy, info.xy, 1e-9 * fabs(info.xx));
    ASSERT_NEAR(post_inv.yy, info.yy, 1e-9 * info.yy);
    /* a sighting equal to the prediction leaves the mean */
    ASSERT_NEAR(lm.mean.x, 1.9, 1e-12);
    ASSERT_NEAR(lm.mean.y, 1.4, 1e-12);
}

static void test_existence(void **state)
{
    (void)state;
    slam_params_t p = params();
    p.exist_init = 1.0f;
    p.exist_hit = 1.0f;
    p.exist_miss = 1.0f;
    p.exist_confirm = 3.0f;
    p.exist_max = 5.0f;
    p.exist_miss_confirmed = 0.0f; /* the rule before it: confirmed never die */
    float e = p.exist_init;
    uint8_t once = 0U;
    assert_int_equal(exist_miss(&e, &once, 1, &p), 0); /* 1 -> 0 */
    assert_int_equal(exist_miss(&e, &once, 1, &p), 1); /* 0 -> -1: removed */
    e = p.exist_init;
    exist_hit(&e, &p);
    exist_hit(&e, &p); /* 3: confirmed */
    landmark_t lm;
    lm.exist = e;
    assert_true(landmark_is_confirmed(&lm, &p));
    for (int i = 0; i < 10; ++i) {
        exist_hit(&e, &p);
    }
    ASSERT_NEAR(e, 5.0, 0.0); /* capped */
    for (int i = 0; i < 10; ++i) {
        assert_int_equal(exist_miss(&e, &once, 1, &p), 0); /* confirmed landmarks are never removed */
    }
    ASSERT_NEAR(e, 3.0, 0.0);
    assert_int_equal(once, 1U);
}

/* exist_miss_confirmed > 0: a confirmed (or once confirmed) landmark decays
 * at one slow rate through exist_confirm down to removal; only certain misses
 * count; tentative ones keep the fast rate. */
static void test_existence_confirmed_decay(void **state)
{
    (void)state;
    slam_params_t p = params();
    p.exist_init = 1.0f;
    p.exist_hit = 1.0f;
    p.exist_miss = 1.0f;
    p.exist_confirm = 3.0f;
    p.exist_max = 5.0f;
    p.exist_miss_confirmed = 0.5f; /* exact in binary: no rounding in the counts */

    float e = p.exist_max;
    uint8_t once = 0U;
    assert_int_equal(exist_miss(&e, &once, 0, &p), 0); /* uncertain: no evidence */
    ASSERT_NEAR(e, 5.0, 0.0);
    assert_int_equal(once, 1U); /* but it is marked */
    int n = 0;
    int n_confirmed = 0;
    while (!exist_miss(&e, &once, 1, &p)) {
        ++n;
        n_confirmed += e >= p.exist_confirm;
        assert_true(n < 100);
    }
    /* (5 - 3) / 0.5 = 4 misses keep it confirmed; it reaches 0 at the 10th
     * (5 / 0.5) and is removed at the 11th (below zero) */
    assert_int_equal(n_confirmed, 4);
    assert_int_equal(n + 1, 11);

    /* tentative (never confirmed): the fast rate, certain or not */
    e = 2.0f;
    once = 0U;
    assert_int_equal(exist_miss(&e, &once, 0, &p), 0);
    ASSERT_NEAR(e, 1.0, 0.0);
    assert_int_equal(once, 0U);
    /* a hit-miss flicker (1 -> 2 -> 1) never confirmed stays on the fast
     * rate, however many sightings it collects */
    e = p.exist_init;
    for (int i = 0; i < 20; ++i) {
        exist_hit(&e, &p);
        assert_int_equal(exist_miss(&e, &once, 1, &p), 0);
    }
    assert_int_equal(once, 0U);
    assert_int_equal(exist_miss(&e, &once, 1, &p), 0); /* 1 -> 0 */
    assert_int_equal(exist_miss(&e, &once, 1, &p), 1); /* removed */
    /* received in a merge at exist_confirm (flag clear): the first miss marks
     * it and ends its export; it survives 3 / 0.5 = 6 misses, the 7th
     * removes it */
    e = p.exist_confirm;
    once = 0U;
    for (int i = 0; i < 6; ++i) {
        assert_int_equal(exist_miss(&e, &once, 1, &p), 0);
        assert_true(e < p.exist_confirm);
    }
    assert_int_equal(exist_miss(&e, &once, 1, &p), 1);
}

static void test_miss_is_certain(void **state)
{
    (void)state;
    slam_params_t p = params();
    p.sensor_fov_rad = 1.0;
    p.exist_miss_bearing_sd_frac = 0.2; /* bearing sd <= 0.1 rad */
    lm_expect_t e;
    memset(&e, 0, sizeof e);
    e.s = cov2_make(4.0, 0.0, 0.0099);
    assert_true(landmark_miss_is_certain(&p, &e));
    e.s.yy = 0.0101;
    assert_false(landmark_miss_is_certain(&p, &e));
    e.s.yy = NAN;
    assert_false(landmark_miss_is_certain(&p, &e));
}

static void test_should_be_seen(void **state)
{
    (void)state;
    slam_params_t p = params();
    p.sensor_min_range_m = 0.3;
    p.sensor_max_range_m = 5.0;
    p.sensor_fov_rad = 1.0;
    p.visibility_margin = 0.9;
    sighting_t z = {2.0, 0.0, 0};
    assert_true(landmark_should_be_seen(&p, z));
    z.bearing_rad = 0.46; /* > 0.45 = 0.5 * 0.9 */
    assert_false(landmark_should_be_seen(&p, z));
    z.bearing_rad = -0.44;
    assert_true(landmark_should_be_seen(&p, z));
    z.range_m = 4.6; /* > 4.5 */
    assert_false(landmark_should_be_seen(&p, z));
    z.range_m = 0.32; /* < 0.3 / 0.9 */
    assert_false(landmark_should_be_seen(&p, z));
}

static void test_greedy_mutual_exclusion(void **state)
{
    (void)state;
    /* sighting 0 prefers landmark 5 (score 3) over 6 (score 1); sighting 1
     * likes landmark 5 even more (score 4) and has no other option. */
    assoc_pair_t pairs[3] = {{3.0, 0, 5}, {1.0, 0, 6}, {4.0, 1, 5}};
    int32_t assign[2];
    assoc_greedy(pairs, 3, 2, assign);
    assert_int_equal(assign[1], 5);
    assert_int_equal(assign[0], 6);
    /* a sighting with no pair stays unassigned; two sightings, one landmark */
    assoc_pair_t pairs2[2] = {{2.0, 0, 1}, {2.5, 2, 1}};
    int32_t a3[3];
    assoc_greedy(pairs2, 2, 3, a3);
    assert_int_equal(a3[0], -1);
    assert_int_equal(a3[1], -1);
    assert_int_equal(a3[2], 1);
    /* larger random instances: the result is a matching (no landmark twice) */
    assoc_pair_t big[64];
    int n = 0;
    for (int i = 0; i < 8; ++i) {
        for (int j = 0; j < 8; ++j) {
            if ((i * 7 + j * 3) % 4 != 0) {
                big[n].score = (double)((i * 13 + j * 29) % 17);
                big[n].sighting = i;
                big[n].landmark = j;
                ++n;
            }
        }
    }
    int32_t ab[8];
    assoc_greedy(big, n, 8, ab);
    for (int i = 0; i < 8; ++i) {
        for (int k = i + 1; k < 8; ++k) {
            assert_true(ab[i] < 0 || ab[i] != ab[k]);
        }
    }
}

static void test_classify_and_new(void **state)
{
    (void)state;
    slam_params_t p = params();
    p.gate_chi2 = 9.21;
    p.new_landmark_chi2 = 25.0;
    p.new_landmark_log_lik = -1.0;
    assert_int_equal(assoc_classify(&p, 1.0, 0.0), ASSOC_ADMISSIBLE);
    assert_int_equal(assoc_classify(&p, 1.0, -2.0), ASSOC_NEAR);   /* less likely than a new landmark */
    assert_int_equal(assoc_classify(&p, 10.0, 5.0), ASSOC_NEAR);   /* outside the gate */
    assert_int_equal(assoc_classify(&p, 30.0, 5.0), ASSOC_FAR);
    assert_int_equal(assoc_classify(&p, NAN, 5.0), ASSOC_FAR);
    /* sighting 0 is paired with landmark 3; sighting 1 could only be landmark 3
     * (taken): a distinct object -> new. Sighting 2 has a free candidate -> ambiguous. */
    assoc_pair_t pairs[4] = {{1.0, 0, 3}, {0.5, 1, 3}, {0.2, 2, 4}, {0.1, 2, 3}};
    const int32_t assign[3] = {3, -1, -1};
    const uint8_t n_near[3] = {0, 0, 0};
    assert_true(assoc_unpaired_is_new(pairs, 4, 1, assign, 3, n_near));
    assert_false(assoc_unpaired_is_new(pairs, 4, 2, assign, 3, n_near));
    /* a near-but-inadmissible landmark makes a sighting ambiguous */
    const uint8_t n_near2[3] = {0, 1, 0};
    assert_false(assoc_unpaired_is_new(pairs, 4, 1, assign, 3, n_near2));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_init_hand_computed),
        cmocka_unit_test(test_kalman_update_hand_computed),
        cmocka_unit_test(test_kalman_update_information_form),
        cmocka_unit_test(test_existence),
        cmocka_unit_test(test_existence_confirmed_decay),
        cmocka_unit_test(test_miss_is_certain),
        cmocka_unit_test(test_should_be_seen),
        cmocka_unit_test(test_greedy_mutual_exclusion),
        cmocka_unit_test(test_classify_and_new),
        cmocka_unit_test(test_d2_lower_bound),
        cmocka_unit_test(test_track_offset_floor),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
