/*
 * The honest-covariance helpers of Fast-SLAM (coslam/marginal.h): symmetric
 * eigen decomposition, Loewner-order bounds, covariance intersection, the
 * landmark marginal from its anchor and the anchored pose update, against
 * hand-computed results and the properties each must have.
 */
#include "test_util.h"

#include <math.h>
#include <string.h>

#include "coslam/landmark.h"
#include "coslam/map_merge.h"
#include "coslam/marginal.h"
#include "coslam/rng.h"

/* smallest eigenvalue of a symmetric 3x3 */
static double min_eig3(cov3_t a)
{
    double lam[3];
    double v[3][3];
    cov3_eigen(a, lam, v);
    return fmin(lam[0], fmin(lam[1], lam[2]));
}

static cov3_t random_spd3(rng_t *rng)
{
    double g[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            g[i][j] = rng_gauss(rng);
        }
    }
    cov3_t c = cov3_congruence(g, cov3_diag(1.0, 1.0, 1.0));
    for (int i = 0; i < 3; ++i) {
        c.m[i][i] += 0.05;
    }
    return c;
}

static cov3_t sub3(cov3_t a, cov3_t b)
{
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            a.m[i][j] -= b.m[i][j];
        }
    }
    return a;
}

static void test_eigen_reconstructs(void **state)
{
    (void)state;
    rng_t rng;
    rng_seed(&rng, 11U);
    for (int t = 0; t < 200; ++t) {
        const cov3_t a = random_spd3(&rng);
        double lam[3];
        double v[3][3];
        cov3_eigen(a, lam, v);
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                double r = 0.0;
                double o = 0.0;
                for (int k = 0; k < 3; ++k) {
                    r += v[i][k] * lam[k] * v[j][k];
                    o += v[k][i] * v[k][j];
                }
                ASSERT_NEAR(r, a.m[i][j], 1e-10);
                ASSERT_NEAR(o, i == j ? 1.0 : 0.0, 1e-10);
            }
        }
    }
}

/* the closed-form clamp agrees with the Jacobi one: random rotations and
 * eigenvalues of every sign pattern, spread over six decades, near-double
 * eigenvalues (its fallback) and exact ones */
static void test_clamp_psd_matches_jacobi(void **state)
{
    (void)state;
    rng_t rng;
    rng_seed(&rng, 12U);
    for (int t = 0; t < 20000; ++t) {
        double lam_v[3][3];
        double lam[3];
        cov3_eigen(random_spd3(&rng), lam, lam_v); /* a random rotation */
        const double s = pow(10.0, rng_uniform(&rng) * 6.0 - 4.0);
        for (int k = 0; k < 3; ++k) {
            lam[k] = (rng_uniform(&rng) * 2.0 - 1.0) * s;
        }
        switch (t % 5) {
        case 1:
            lam[1] = lam[0] * (1.0 + 1e-9); /* near double */
            break;
        case 2:
            lam[1] = lam[0]; /* exact double */
            break;
        case 3:
            lam[1] = lam[2] = lam[0]; /* a multiple of I */
            break;
        default:
            break;
        }
        cov3_t a;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                double r = 0.0;
                for (int k = 0; k < 3; ++k) {
                    r += lam_v[i][k] * lam[k] * lam_v[j][k];
                }
                a.m[i][j] = r;
            }
        }
        const cov3_t fast = cov3_clamp_psd(a);
        const cov3_t ref = cov3_clamp_eigen(a, 0.0);
        const double scale = fabs(lam[0]) + fabs(lam[1]) + fabs(lam[2]);
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                ASSERT_NEAR(fast.m[i][j], ref.m[i][j], 1e-9 * scale);
                ASSERT_NEAR(fast.m[i][j], fast.m[j][i], 1e-12 * scale);
            }
        }
    }
    /* an exact multiple of I (a zero drift: the anchor is the present pose
     * marginal): the eigen route's matrix, bit for bit */
    const double qs[4] = {0.0, 2.5, -1.5, 1e-300};
    for (int k = 0; k < 4; ++k) {
        const cov3_t a = cov3_diag(qs[k], qs[k], qs[k]);
        const cov3_t fast = cov3_clamp_psd(a);
        const cov3_t ref = cov3_clamp_eigen(a, 0.0);
        assert_memory_equal(&fast, &ref, sizeof fast);
        ASSERT_NEAR(fast.m[1][1], qs[k] > 0.0 ? qs[k] : 0.0, 0.0);
    }
}

static void test_loewner_max(void **state)
{
    (void)state;
    /* diagonal: the element-wise maximum */
    const cov2_t m2 = cov2_loewner_max(cov2_make(1.0, 0.0, 4.0), cov2_make(3.0, 0.0, 2.0));
    ASSERT_NEAR(m2.xx, 3.0, 1e-12);
    ASSERT_NEAR(m2.xy, 0.0, 1e-12);
    ASSERT_NEAR(m2.yy, 4.0, 1e-12);
    const cov3_t m3 = cov3_loewner_max(cov3_diag(1.0, 5.0, 2.0), cov3_diag(3.0, 1.0, 2.5));
    ASSERT_NEAR(m3.m[0][0], 3.0, 1e-12);
    ASSERT_NEAR(m3.m[1][1], 5.0, 1e-12);
    ASSERT_NEAR(m3.m[2][2], 2.5, 1e-12);
    ASSERT_NEAR(m3.m[0][1], 0.0, 1e-12);
    /* b inside a: a itself, exactly */
    const cov3_t a = cov3_diag(2.0, 2.0, 2.0);
    const cov3_t in = cov3_loewner_max(a, cov3_diag(1.0, 1.5, 0.5));
    assert_memory_equal(&in, &a, sizeof a);
    /* random pairs: the result bounds both */
    rng_t rng;
    rng_seed(&rng, 5U);
    for (int t = 0; t < 300; ++t) {
        const cov3_t x = random_spd3(&rng);
        const cov3_t y = random_spd3(&rng);
        const cov3_t m = cov3_loewner_max(x, y);
        assert_true(min_eig3(sub3(m, x)) > -1e-9);
        assert_true(min_eig3(sub3(m, y)) > -1e-9);
        /* and is no larger than their sum (a bound that is not loose) */
        assert_true(min_eig3(sub3(cov3_add(x, y), m)) > -1e-9);
        const cov2_t p = cov2_make(x.m[0][0], x.m[0][1], x.m[1][1]);
        const cov2_t q = cov2_make(y.m[0][0], y.m[0][1], y.m[1][1]);
        const cov2_t r = cov2_loewner_max(p, q);
        double lo, hi;
        cov2_eigenvalues(cov2_make(r.xx - p.xx, r.xy - p.xy, r.yy - p.yy), &lo, &hi);
        assert_true(lo > -1e-9);
        cov2_eigenvalues(cov2_make(r.xx - q.xx, r.xy - q.xy, r.yy - q.yy), &lo, &hi);
        assert_true(lo > -1e-9);
    }
}

static void test_covariance_intersection(void **state)
{
    (void)state;
    /* diag(1, 4) and diag(4, 1): w = 1/2 by symmetry, information 5/8 each */
    /* the 2x2 intersection is map_merge's */
    point2_t xm;
    cov2_t c;
    assert_int_equal(merge_fuse_ci((point2_t){0.0, 0.0}, cov2_make(1.0, 0.0, 4.0), (point2_t){0.0, 0.0},
                                   cov2_make(4.0, 0.0, 1.0), &xm, &c, NULL),
                     COSLAM_OK);
    ASSERT_NEAR(c.xx, 1.6, 1e-6);
    ASSERT_NEAR(c.yy, 1.6, 1e-6);
    ASSERT_NEAR(c.xy, 0.0, 1e-9);
    /* one inside the other: the smaller one */
    const cov3_t s = cov3_ci(cov3_diag(1.0, 1.0, 1.0), cov3_diag(0.5, 0.25, 0.5));
    ASSERT_NEAR(s.m[0][0], 0.5, 1e-9);
    ASSERT_NEAR(s.m[1][1], 0.25, 1e-9);
    /* never larger in determinant than either */
    rng_t rng;
    rng_seed(&rng, 8U);
    for (int t = 0; t < 200; ++t) {
        const cov3_t x = random_spd3(&rng);
        const cov3_t y = random_spd3(&rng);
        const cov3_t m = cov3_ci(x, y);
        assert_true(cov3_det(m) <= fmin(cov3_det(x), cov3_det(y)) * (1.0 + 1e-9));
        /* the weight is the optimum: no mix on a fine grid of w has a
         * smaller covariance determinant (det of the information larger) */
        cov3_t ix;
        cov3_t iy;
        assert_int_equal(cov3_inverse(x, &ix), COSLAM_OK);
        assert_int_equal(cov3_inverse(y, &iy), COSLAM_OK);
        const double info_det = 1.0 / cov3_det(m);
        for (int g = 0; g <= 1000; ++g) {
            const double w = g / 1000.0;
            cov3_t mix;
            for (int i = 0; i < 3; ++i) {
                for (int j = 0; j < 3; ++j) {
                    mix.m[i][j] = w * ix.m[i][j] + (1.0 - w) * iy.m[i][j];
                }
            }
            assert_true(cov3_det(mix) <= info_det * (1.0 + 1e-9));
        }
    }
}

static void test_landmark_marginal_from_anchor(void **state)
{
    (void)state;
    landmark_t lm;
    memset(&lm, 0, sizeof lm);
    lm.mean = (point2_t){3.0, 1.0};
    lm.cov = cov2_make(0.01, 0.0, 0.02);
    /* no anchor: the conditional covariance */
    cov2_t m = landmark_marginal(&lm);
    ASSERT_NEAR(m.xx, 0.01, 1e-15);
    ASSERT_NEAR(m.yy, 0.02, 1e-15);
    /* anchored at (1, 1) with diag(a, b, c): G = [1 0 0; 0 1 2] */
    const cov3_t a = cov3_diag(0.04, 0.09, 0.0025);
    landmark_set_anchor(&lm, &a, (point2_t){1.0, 1.0});
    m = landmark_marginal(&lm);
    ASSERT_NEAR(m.xx, 0.01 + 0.04, 1e-7);
    ASSERT_NEAR(m.xy, 0.0, 1e-7);
    ASSERT_NEAR(m.yy, 0.02 + 0.09 + 4.0 * 0.0025, 1e-7);
}

/* P' = (P^-1 + Hp^T N^-1 Hp)^-1 written out for a diagonal P */
static void test_pose_observe_unanchored_is_kalman(void **state)
{
    (void)state;
    cov3_t p = cov3_diag(0.04, 0.09, 0.01);
    const cov3_t anchor = cov3_zero();
    double hp[2][3] = {{-1.0, 0.0, 0.0}, {0.0, -0.5, -1.0}};
    const cov2_t n = cov2_make(0.01, 0.0, 0.0004);
    const pose2_t pose = {2.0, 0.0, 0.0};
    assert_int_equal(marginal_pose_observe(&p, pose, &anchor, (point2_t){0.0, 0.0}, hp, n), COSLAM_OK);
    /* information form */
    cov2_t ni;
    assert_int_equal(cov2_inverse(n, &ni), COSLAM_OK);
    cov3_t info = cov3_diag(1.0 / 0.04, 1.0 / 0.09, 1.0 / 0.01);
    const double nim[2][2] = {{ni.xx, ni.xy}, {ni.xy, ni.yy}};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            for (int a = 0; a < 2; ++a) {
                for (int b = 0; b < 2; ++b) {
                    info.m[i][j] += hp[a][i] * nim[a][b] * hp[b][j];
                }
            }
        }
    }
    cov3_t want;
    assert_int_equal(cov3_inverse(info, &want), COSLAM_OK);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            ASSERT_NEAR(p.m[i][j], want.m[i][j], 1e-9);
        }
    }
}

static void test_pose_observe_floor_is_the_anchor(void **state)
{
    (void)state;
    /* robot at its anchor with P = A: the landmark tells nothing new */
    const cov3_t a = cov3_diag(0.04, 0.04, 0.001);
    cov3_t p = a;
    double hp[2][3] = {{-1.0, 0.0, 0.0}, {0.0, -0.5, -1.0}};
    assert_int_equal(
        marginal_pose_observe(&p, (pose2_t){1.0, 2.0, 0.0}, &a, (point2_t){1.0, 2.0}, hp, cov2_make(1e-4, 0.0, 1e-6)),
        COSLAM_OK);
    for (int i = 0; i < 3; ++i) {
        ASSERT_NEAR(p.m[i][i], a.m[i][i], 1e-9);
    }
    /* moved 3 m along x since the anchor: the anchor's heading error is now
     * 3 m of lateral error, P = A carried forward + drift; a precise sighting
     * removes the drift but leaves the carried-forward anchor */
    double phi[3][3] = {{1, 0, 0}, {0, 1, 3.0}, {0, 0, 1}};
    cov3_t ac = a; /* heading error correlated with the lateral one */
    ac.m[1][2] = ac.m[2][1] = 0.004;
    const cov3_t carried = cov3_congruence(phi, ac);
    p = cov3_add(carried, cov3_diag(0.1, 0.1, 0.01));
    double hfull[2][3] = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}};
    assert_int_equal(marginal_pose_observe(&p, (pose2_t){4.0, 2.0, 0.0}, &ac, (point2_t){1.0, 2.0}, hfull,
                                           cov2_make(1e-8, 0.0, 1e-8)),
                     COSLAM_OK);
    ASSERT_NEAR(p.m[0][0], carried.m[0][0], 1e-6);
    ASSERT_NEAR(p.m[1][1], carried.m[1][1], 1e-6);
    /* never grows, for any input (and any gain: marginal_pose_observe_gain,
     * then marginal_bound as Fast-SLAM 2.0 applies it once a frame) */
    rng_t rng;
    rng_seed(&rng, 21U);
    for (int t = 0; t < 300; ++t) {
        cov3_t q = random_spd3(&rng);
        const cov3_t before = q;
        const cov3_t anc = random_spd3(&rng);
        double h[2][3];
        double kk[3][2]; /* any gain, also one that overshoots */
        for (int i = 0; i < 2; ++i) {
            for (int j = 0; j < 3; ++j) {
                h[i][j] = rng_gauss(&rng);
                kk[j][i] = 3.0 * rng_gauss(&rng);
            }
        }
        const pose2_t at = {rng_gauss(&rng), rng_gauss(&rng), 0.0};
        cov3_t qg = q;
        assert_int_equal(marginal_pose_observe(&q, at, &anc, (point2_t){0.0, 0.0}, h, cov2_make(0.1, 0.0, 0.1)),
                         COSLAM_OK);
        assert_true(cov3_det(q) <= cov3_det(before) * (1.0 + 1e-9));
        assert_int_equal(
            marginal_pose_observe_gain(&qg, at, &anc, (point2_t){0.0, 0.0}, h, cov2_make(0.1, 0.0, 0.1), kk),
            COSLAM_OK);
        marginal_bound(&before, &qg);
        assert_true(cov3_det(qg) <= cov3_det(before) * (1.0 + 1e-9));
    }
    /* bad input changes nothing */
    cov3_t bad = cov3_diag(NAN, 1.0, 1.0);
    assert_int_equal(marginal_pose_observe(&bad, (pose2_t){0, 0, 0}, &a, (point2_t){0, 0}, hp, cov2_make(1, 0, 1)),
                     COSLAM_E_NOT_PD);
}

/* The drift left after a correction with any gain (Fast-SLAM 2.0's
 * proposal): the optimal gain gives the Kalman posterior; zero gain (the
 * pose not moved) leaves P; a suboptimal gain leaves what a Monte Carlo of
 * d - K (Hp d + v) leaves; an overshooting one leaves more than P, which
 * marginal_bound takes back within it. */
static void test_pose_observe_with_the_gain_applied(void **state)
{
    (void)state;
    const cov3_t none = cov3_zero();
    const pose2_t pose = {2.0, 1.0, 0.3};
    double hp[2][3] = {{-0.8, -0.6, 0.0}, {0.3, -0.4, -1.0}};
    const cov2_t n = cov2_make(0.01, 0.002, 0.0009);
    cov3_t prior = cov3_diag(0.09, 0.04, 0.01);
    prior.m[0][1] = prior.m[1][0] = 0.01;
    prior.m[0][2] = prior.m[2][0] = 0.004;
    prior.m[1][2] = prior.m[2][1] = -0.002;
    /* 1. the optimal gain D Hp^T (Hp D Hp^T + n)^-1: marginal_pose_observe */
    double k[3][2];
    {
        double dht[3][2];
        for (int i = 0; i < 3; ++i) {
            for (int q = 0; q < 2; ++q) {
                dht[i][q] = prior.m[i][0] * hp[q][0] + prior.m[i][1] * hp[q][1] + prior.m[i][2] * hp[q][2];
            }
        }
        cov2_t s = n;
        for (int q = 0; q < 2; ++q) {
            const double sq0 = hp[q][0] * dht[0][0] + hp[q][1] * dht[1][0] + hp[q][2] * dht[2][0];
            const double sq1 = hp[q][0] * dht[0][1] + hp[q][1] * dht[1][1] + hp[q][2] * dht[2][1];
            if (q == 0) {
                s.xx += sq0;
                s.xy += sq1;
            } else {
                s.yy += sq1;
            }
        }
        cov2_t si;
        assert_int_equal(cov2_inverse(s, &si), COSLAM_OK);
        for (int i = 0; i < 3; ++i) {
            k[i][0] = dht[i][0] * si.xx + dht[i][1] * si.xy;
            k[i][1] = dht[i][0] * si.xy + dht[i][1] * si.yy;
        }
    }
    cov3_t a = prior;
    cov3_t b = prior;
    assert_int_equal(marginal_pose_observe(&a, pose, &none, (point2_t){0.0, 0.0}, hp, n), COSLAM_OK);
    assert_int_equal(marginal_pose_observe_gain(&b, pose, &none, (point2_t){0.0, 0.0}, hp, n, k),
                     COSLAM_OK);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            ASSERT_NEAR(b.m[i][j], a.m[i][j], 1e-12);
        }
    }
    /* 2. the pose not moved: the drift stays whole */
    double k0[3][2] = {{0.0, 0.0}, {0.0, 0.0}, {0.0, 0.0}};
    cov3_t c = prior;
    assert_int_equal(marginal_pose_observe_gain(&c, pose, &none, (point2_t){0.0, 0.0}, hp, n, k0), COSLAM_OK);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            ASSERT_NEAR(c.m[i][j], prior.m[i][j], 1e-12);
        }
    }
    /* 3. a fifth of the optimal gain (a proposal whose prior is the motion
     * since the last sample, smaller than the drift): Monte Carlo */
    double ks[3][2];
    for (int i = 0; i < 3; ++i) {
        ks[i][0] = 0.2 * k[i][0];
        ks[i][1] = 0.2 * k[i][1];
    }
    cov3_t g = prior;
    assert_int_equal(marginal_pose_observe_gain(&g, pose, &none, (point2_t){0.0, 0.0}, hp, n, ks),
                     COSLAM_OK);
    double ld[3][3];
    assert_int_equal(cov3_cholesky(prior, ld), COSLAM_OK);
    const double ln00 = sqrt(n.xx);
    const double ln10 = n.xy / ln00;
    const double ln11 = sqrt(n.yy - ln10 * ln10);
    rng_t rng;
    rng_seed(&rng, 5U);
    const int trials = 200000;
    double acc[3][3] = {{0}};
    for (int t = 0; t < trials; ++t) {
        const double u[3] = {rng_gauss(&rng), rng_gauss(&rng), rng_gauss(&rng)};
        double d[3];
        for (int i = 0; i < 3; ++i) {
            d[i] = ld[i][0] * u[0] + ld[i][1] * u[1] + ld[i][2] * u[2];
        }
        const double w0 = rng_gauss(&rng);
        const double w1 = rng_gauss(&rng);
        const double v[2] = {ln00 * w0, ln10 * w0 + ln11 * w1};
        double zz[2];
        for (int q = 0; q < 2; ++q) {
            zz[q] = hp[q][0] * d[0] + hp[q][1] * d[1] + hp[q][2] * d[2] + v[q];
        }
        double e[3];
        for (int i = 0; i < 3; ++i) {
            e[i] = d[i] - (ks[i][0] * zz[0] + ks[i][1] * zz[1]);
        }
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                acc[i][j] += e[i] * e[j];
            }
        }
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            /* sampling sd of a covariance entry: sqrt((s_ii s_jj + s_ij^2) / N) */
            const double tol = 5.0 * sqrt((g.m[i][i] * g.m[j][j] + g.m[i][j] * g.m[i][j]) / trials);
            ASSERT_NEAR(acc[i][j] / trials, g.m[i][j], tol);
        }
        /* and more than the optimal correction leaves */
        assert_true(g.m[i][i] > a.m[i][i]);
    }
    /* 4. a gain of five times the optimal one overshoots: the particle
     * moved further than the sighting warrants, and the result is the
     * Joseph form, larger than the prior in that direction; marginal_bound
     * then brings it back within the prior */
    double kb[3][2];
    for (int i = 0; i < 3; ++i) {
        kb[i][0] = 5.0 * k[i][0];
        kb[i][1] = 5.0 * k[i][1];
    }
    double a5[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            a5[i][j] = (i == j ? 1.0 : 0.0) - (kb[i][0] * hp[0][j] + kb[i][1] * hp[1][j]);
        }
    }
    cov3_t want = cov3_congruence(a5, prior);
    double tr_want = 0.0;
    double tr_prior = 0.0;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            want.m[i][j] +=
                kb[i][0] * (n.xx * kb[j][0] + n.xy * kb[j][1]) + kb[i][1] * (n.xy * kb[j][0] + n.yy * kb[j][1]);
        }
        tr_want += want.m[i][i];
        tr_prior += prior.m[i][i];
    }
    assert_true(tr_want > tr_prior);
    cov3_t o = prior;
    assert_int_equal(marginal_pose_observe_gain(&o, pose, &none, (point2_t){0.0, 0.0}, hp, n, kb), COSLAM_OK);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            ASSERT_NEAR(o.m[i][j], want.m[i][j], 1e-12);
        }
    }
    marginal_bound(&prior, &o);
    assert_true(cov3_det(o) <= cov3_det(prior) * (1.0 + 1e-9));
    for (int i = 0; i < 3; ++i) {
        assert_true(o.m[i][i] <= prior.m[i][i] * (1.0 + 1e-9));
    }
    /* within the prior already (the optimal gain's result): left alone */
    cov3_t w = a;
    marginal_bound(&prior, &w);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            ASSERT_NEAR(w.m[i][j], a.m[i][j], 0.0);
        }
    }
    cov3_t bad = cov3_diag(NAN, 1.0, 1.0);
    assert_int_equal(marginal_pose_observe_gain(&bad, pose, &none, (point2_t){0, 0}, hp, n, k0), COSLAM_E_NOT_PD);
}

static void test_relative_drift(void **state)
{
    (void)state;
    /* no anchor, heading 0, landmark 2 m ahead: J = [-1 0 0; 0 -1 -2] */
    const cov3_t p = cov3_diag(0.04, 0.09, 0.01);
    const cov3_t none = cov3_zero();
    cov2_t r = marginal_relative_drift(&p, (pose2_t){1.0, 1.0, 0.0}, &none, (point2_t){0.0, 0.0},
                                       (point2_t){2.0, 0.0});
    ASSERT_NEAR(r.xx, 0.04, 1e-12);
    ASSERT_NEAR(r.xy, 0.0, 1e-12);
    ASSERT_NEAR(r.yy, 0.09 + 4.0 * 0.01, 1e-12);
    /* anchored where the robot stands with its whole P: no drift since */
    r = marginal_relative_drift(&p, (pose2_t){1.0, 1.0, 0.3}, &p, (point2_t){1.0, 1.0}, (point2_t){2.0, 0.5});
    ASSERT_NEAR(r.xx, 0.0, 1e-12);
    ASSERT_NEAR(r.yy, 0.0, 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_eigen_reconstructs),
        cmocka_unit_test(test_clamp_psd_matches_jacobi),
        cmocka_unit_test(test_loewner_max),
        cmocka_unit_test(test_covariance_intersection),
        cmocka_unit_test(test_landmark_marginal_from_anchor),
        cmocka_unit_test(test_pose_observe_unanchored_is_kalman),
        cmocka_unit_test(test_pose_observe_floor_is_the_anchor),
        cmocka_unit_test(test_pose_observe_with_the_gain_applied),
        cmocka_unit_test(test_relative_drift),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
