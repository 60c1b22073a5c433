/* Pose and covariance maths: analytic values, identities, and every Jacobian
 * against central finite differences. */
#include "test_util.h"

#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/motion.h"
#include "coslam/observe.h"
#include "coslam/pose2.h"
#include "coslam/rng.h"

static void test_angle_wrap(void **state)
{
    (void)state;
    ASSERT_NEAR(angle_wrap(0.0), 0.0, 0.0);
    ASSERT_NEAR(angle_wrap(COSLAM_PI), -COSLAM_PI, 1e-15);
    ASSERT_NEAR(angle_wrap(-COSLAM_PI), -COSLAM_PI, 1e-15);
    ASSERT_NEAR(angle_wrap(3.0 * COSLAM_PI / 2.0), -COSLAM_PI / 2.0, 1e-12);
    ASSERT_NEAR(angle_wrap(-7.0), -7.0 + COSLAM_TWO_PI, 1e-12);
    ASSERT_NEAR(angle_wrap(1000.0), 1000.0 - 159.0 * COSLAM_TWO_PI, 1e-9);
    assert_true(isnan(angle_wrap(NAN)));
    assert_true(isnan(angle_wrap(INFINITY)));
    /* range holds for many values */
    for (int i = -2000; i <= 2000; ++i) {
        const double w = angle_wrap(0.0137 * i * i);
        assert_true(w >= -COSLAM_PI && w < COSLAM_PI);
    }
}

static void test_pose_compose_inverse(void **state)
{
    (void)state;
    const pose2_t a = {1.0, 2.0, COSLAM_PI / 2.0};
    const pose2_t b = {0.5, 0.0, 0.25};
    /* hand computation: rotate b by 90 deg -> (0, 0.5), add (1, 2) */
    const pose2_t c = pose2_compose(a, b);
    ASSERT_NEAR(c.x, 1.0, 1e-12);
    ASSERT_NEAR(c.y, 2.5, 1e-12);
    ASSERT_NEAR(c.theta, COSLAM_PI / 2.0 + 0.25, 1e-12);
    const pose2_t id = pose2_compose(a, pose2_inverse(a));
    ASSERT_NEAR(id.x, 0.0, 1e-12);
    ASSERT_NEAR(id.y, 0.0, 1e-12);
    ASSERT_NEAR(id.theta, 0.0, 1e-12);
    const pose2_t rel = pose2_between(a, c);
    ASSERT_NEAR(rel.x, b.x, 1e-12);
    ASSERT_NEAR(rel.y, b.y, 1e-12);
    ASSERT_NEAR(rel.theta, b.theta, 1e-12);
    const point2_t p = {0.3, -0.7};
    const point2_t q = pose2_apply_inverse(a, pose2_apply(a, p));
    ASSERT_NEAR(q.x, p.x, 1e-12);
    ASSERT_NEAR(q.y, p.y, 1e-12);
    /* associativity */
    const pose2_t d = {-0.2, 0.9, -2.5};
    const pose2_t l = pose2_compose(pose2_compose(a, b), d);
    const pose2_t r = pose2_compose(a, pose2_compose(b, d));
    ASSERT_NEAR(l.x, r.x, 1e-12);
    ASSERT_NEAR(l.y, r.y, 1e-12);
    ASSERT_NEAR(angle_wrap(l.theta - r.theta), 0.0, 1e-12);
}

static void test_cov2_ops(void **state)
{
    (void)state;
    const cov2_t a = cov2_make(4.0, 1.0, 3.0);
    ASSERT_NEAR(cov2_det(a), 11.0, 1e-12);
    cov2_t inv;
    assert_int_equal(cov2_inverse(a, &inv), COSLAM_OK);
    ASSERT_NEAR(inv.xx, 3.0 / 11.0, 1e-12);
    ASSERT_NEAR(inv.xy, -1.0 / 11.0, 1e-12);
    ASSERT_NEAR(inv.yy, 4.0 / 11.0, 1e-12);
    double l[3];
    assert_int_equal(cov2_cholesky(a, l), COSLAM_OK);
    ASSERT_NEAR(l[0] * l[0], 4.0, 1e-12);
    ASSERT_NEAR(l[0] * l[1], 1.0, 1e-12);
    ASSERT_NEAR(l[1] * l[1] + l[2] * l[2], 3.0, 1e-12);
    double d2;
    assert_int_equal(cov2_mahalanobis2(a, 1.0, 2.0, &d2), COSLAM_OK);
    /* (1,2) inv (1,2)^T = (3 - 4 + 16) / 11 */
    ASSERT_NEAR(d2, 15.0 / 11.0, 1e-12);
    /* not PD */
    assert_int_equal(cov2_inverse(cov2_make(1.0, 2.0, 1.0), &inv), COSLAM_E_NOT_PD);
    assert_int_equal(cov2_cholesky(cov2_make(-1.0, 0.0, 1.0), l), COSLAM_E_NOT_PD);
    assert_int_equal(cov2_mahalanobis2(cov2_make(NAN, 0.0, 1.0), 1.0, 1.0, &d2), COSLAM_E_NOT_PD);
    /* rotation by 90 deg swaps the axes */
    double rot[2][2] = {{0.0, -1.0}, {1.0, 0.0}};
    const cov2_t r = cov2_congruence(rot, cov2_make(4.0, 0.5, 1.0));
    ASSERT_NEAR(r.xx, 1.0, 1e-12);
    ASSERT_NEAR(r.xy, -0.5, 1e-12);
    ASSERT_NEAR(r.yy, 4.0, 1e-12);
    /* eigenvalues and clamping */
    double lo;
    double hi;
    cov2_eigenvalues(a, &lo, &hi);
    ASSERT_NEAR(lo + hi, 7.0, 1e-12);
    ASSERT_NEAR(lo * hi, 11.0, 1e-12);
    const cov2_t bad = cov2_make(1.0, 1.0 + 1e-9, 1.0); /* slightly indefinite */
    const cov2_t fixed = cov2_clamp_eigen(bad, 1e-6);
    assert_true(cov2_is_pd(fixed));
    cov2_eigenvalues(fixed, &lo, &hi);
    ASSERT_NEAR(lo, 1e-6, 1e-12);
    ASSERT_NEAR(hi, 2.0, 1e-8);
    const cov2_t same = cov2_clamp_eigen(a, 1e-6);
    ASSERT_NEAR(same.xy, a.xy, 0.0);
}

static void test_cov2_from_3x3(void **state)
{
    (void)state;
    double j[2][3] = {{1.0, 2.0, 0.0}, {0.0, 1.0, -1.0}};
    double p[3][3] = {{2.0, 0.5, 0.1}, {0.5, 1.0, 0.2}, {0.1, 0.2, 3.0}};
    const cov2_t r = cov2_from_3x3(j, p);
    /* J P J^T by hand: row0 = (1,2,0): 2 + 2*2*0.5 + 4*1 = 8 */
    ASSERT_NEAR(r.xx, 8.0, 1e-12);
    /* row0 P row1^T: (1,2,0) P (0,1,-1)^T = P01 - P02 + 2(P11 - P12) = 0.5 - 0.1 + 2*0.8 = 2.0 */
    ASSERT_NEAR(r.xy, 2.0, 1e-12);
    /* row1: P11 - 2 P12 + P22 = 1 - 0.4 + 3 = 3.6 */
    ASSERT_NEAR(r.yy, 3.6, 1e-12);
}

static void test_cov3_ops(void **state)
{
    (void)state;
    cov3_t a = cov3_zero();
    const double m[3][3] = {{4.0, 2.0, 0.6}, {2.0, 5.0, 1.0}, {0.6, 1.0, 2.0}};
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            a.m[i][k] = m[i][k];
        }
    }
    ASSERT_NEAR(cov3_det(a), 4.0 * (10.0 - 1.0) - 2.0 * (4.0 - 0.6) + 0.6 * (2.0 - 3.0), 1e-12);
    assert_true(cov3_is_pd(a));
    cov3_t inv;
    assert_int_equal(cov3_inverse(a, &inv), COSLAM_OK);
    double prod[3][3];
    mat3_mul(a.m, inv.m, prod);
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            ASSERT_NEAR(prod[i][k], i == k ? 1.0 : 0.0, 1e-12);
        }
    }
    double l[3][3];
    assert_int_equal(cov3_cholesky(a, l), COSLAM_OK);
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            double s = 0.0;
            for (int q = 0; q < 3; ++q) {
                s += l[i][q] * l[k][q];
            }
            ASSERT_NEAR(s, m[i][k], 1e-12);
        }
    }
    const double v[3] = {1.0, -1.0, 0.5};
    double d2;
    assert_int_equal(cov3_mahalanobis2(a, v, &d2), COSLAM_OK);
    double direct = 0.0;
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            direct += v[i] * inv.m[i][k] * v[k];
        }
    }
    ASSERT_NEAR(d2, direct, 1e-12);
    /* congruence with the identity and a permutation */
    double perm[3][3] = {{0, 1, 0}, {1, 0, 0}, {0, 0, 1}};
    const cov3_t pa = cov3_congruence(perm, a);
    ASSERT_NEAR(pa.m[0][0], 5.0, 0.0);
    ASSERT_NEAR(pa.m[0][2], 1.0, 0.0);
    /* indefinite and non-finite rejected */
    cov3_t bad = a;
    bad.m[2][2] = -1.0;
    assert_false(cov3_is_pd(bad));
    assert_int_equal(cov3_inverse(bad, &inv), COSLAM_E_NOT_PD);
    bad = a;
    bad.m[0][1] = NAN;
    assert_false(cov3_is_pd(bad));
    bad = a;
    bad.m[0][1] = 2.5; /* asymmetric */
    assert_false(cov3_is_pd(bad));
    /* symmetrize: each off-diagonal pair replaced by its mean, in its own
     * place (distinct values, so a swapped pair fails), the diagonal kept */
    cov3_t asym;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            asym.m[i][j] = (double)(10 * i + j) + (i > j ? 0.5 : 0.0);
        }
    }
    const cov3_t sy = cov3_symmetrize(asym);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            ASSERT_NEAR(sy.m[i][j], 0.5 * (asym.m[i][j] + asym.m[j][i]), 0.0);
        }
    }
    const cov3_t again = cov3_symmetrize(sy);
    assert_memory_equal(&again, &sy, sizeof sy);
}

/* --- Jacobians against central differences ------------------------------ */

static const double H = 1e-6;

static void fd_check(const double *analytic, const double *numeric, int n, double tol)
{
    for (int i = 0; i < n; ++i) {
        ASSERT_NEAR(analytic[i], numeric[i], tol);
    }
}

static void test_compose_jacobians(void **state)
{
    (void)state;
    const pose2_t a = {0.7, -1.2, 2.9};
    const pose2_t b = {1.5, 0.4, -0.8};
    double ja[3][3];
    double jb[3][3];
    pose2_compose_jacobians(a, b, ja, jb);
    double na[3][3];
    double nb[3][3];
    for (int k = 0; k < 3; ++k) {
        double ap[3] = {a.x, a.y, a.theta};
        double am[3] = {a.x, a.y, a.theta};
        ap[k] += H;
        am[k] -= H;
        const pose2_t cp = pose2_compose((pose2_t){ap[0], ap[1], ap[2]}, b);
        const pose2_t cm = pose2_compose((pose2_t){am[0], am[1], am[2]}, b);
        na[0][k] = (cp.x - cm.x) / (2 * H);
        na[1][k] = (cp.y - cm.y) / (2 * H);
        na[2][k] = angle_wrap(cp.theta - cm.theta) / (2 * H);
        double bp[3] = {b.x, b.y, b.theta};
        double bm[3] = {b.x, b.y, b.theta};
        bp[k] += H;
        bm[k] -= H;
        const pose2_t dp = pose2_compose(a, (pose2_t){bp[0], bp[1], bp[2]});
        const pose2_t dm = pose2_compose(a, (pose2_t){bm[0], bm[1], bm[2]});
        nb[0][k] = (dp.x - dm.x) / (2 * H);
        nb[1][k] = (dp.y - dm.y) / (2 * H);
        nb[2][k] = angle_wrap(dp.theta - dm.theta) / (2 * H);
    }
    fd_check(&ja[0][0], &na[0][0], 9, 1e-7);
    fd_check(&jb[0][0], &nb[0][0], 9, 1e-7);
}

static void test_apply_jacobians(void **state)
{
    (void)state;
    const pose2_t a = {0.3, 2.2, -1.1};
    const point2_t p = {2.0, -0.5};
    double jp[2][3];
    double jq[2][2];
    pose2_apply_jacobians(a, p, jp, jq);
    double np[2][3];
    double nq[2][2];
    for (int k = 0; k < 3; ++k) {
        double ap[3] = {a.x, a.y, a.theta};
        double am[3] = {a.x, a.y, a.theta};
        ap[k] += H;
        am[k] -= H;
        const point2_t qp = pose2_apply((pose2_t){ap[0], ap[1], ap[2]}, p);
        const point2_t qm = pose2_apply((pose2_t){am[0], am[1], am[2]}, p);
        np[0][k] = (qp.x - qm.x) / (2 * H);
        np[1][k] = (qp.y - qm.y) / (2 * H);
    }
    for (int k = 0; k < 2; ++k) {
        point2_t pp = p;
        point2_t pm = p;
        if (k == 0) {
            pp.x += H;
            pm.x -= H;
        } else {
            pp.y += H;
            pm.y -= H;
        }
        const point2_t qp = pose2_apply(a, pp);
        const point2_t qm = pose2_apply(a, pm);
        nq[0][k] = (qp.x - qm.x) / (2 * H);
        nq[1][k] = (qp.y - qm.y) / (2 * H);
    }
    fd_check(&jp[0][0], &np[0][0], 6, 1e-7);
    fd_check(&jq[0][0], &nq[0][0], 4, 1e-7);
}

static void test_observe_jacobians(void **state)
{
    (void)state;
    const pose2_t p = {0.5, -0.3, 2.8};
    const point2_t m = {-1.7, 1.1};
    double hp[2][3];
    double hm[2][2];
    assert_int_equal(observe_jacobians(p, m, hp, hm), COSLAM_OK);
    double np[2][3];
    double nm[2][2];
    for (int k = 0; k < 3; ++k) {
        double a[3] = {p.x, p.y, p.theta};
        double b[3] = {p.x, p.y, p.theta};
        a[k] += H;
        b[k] -= H;
        const sighting_t zp = observe_predict((pose2_t){a[0], a[1], a[2]}, m);
        const sighting_t zm = observe_predict((pose2_t){b[0], b[1], b[2]}, m);
        np[0][k] = (zp.range_m - zm.range_m) / (2 * H);
        np[1][k] = angle_wrap(zp.bearing_rad - zm.bearing_rad) / (2 * H);
    }
    for (int k = 0; k < 2; ++k) {
        point2_t a = m;
        point2_t b = m;
        if (k == 0) {
            a.x += H;
            b.x -= H;
        } else {
            a.y += H;
            b.y -= H;
        }
        const sighting_t zp = observe_predict(p, a);
        const sighting_t zm = observe_predict(p, b);
        nm[0][k] = (zp.range_m - zm.range_m) / (2 * H);
        nm[1][k] = angle_wrap(zp.bearing_rad - zm.bearing_rad) / (2 * H);
    }
    fd_check(&hp[0][0], &np[0][0], 6, 1e-7);
    fd_check(&hm[0][0], &nm[0][0], 4, 1e-7);
    /* degenerate: landmark on the robot */
    const point2_t on = {p.x, p.y};
    assert_int_equal(observe_jacobians(p, on, hp, hm), COSLAM_E_DEGENERATE);
}

static void test_observe_inverse(void **state)
{
    (void)state;
    const pose2_t p = {1.0, 2.0, -0.6};
    const point2_t m = {3.5, 0.4};
    /* inverse(predict) is the identity */
    const point2_t back = observe_inverse(p, observe_predict(p, m));
    ASSERT_NEAR(back.x, m.x, 1e-12);
    ASSERT_NEAR(back.y, m.y, 1e-12);
    const sighting_t z = {2.3, 0.4, 0};
    double gp[2][3];
    double gz[2][2];
    observe_inverse_jacobians(p, z, gp, gz);
    double np[2][3];
    double nz[2][2];
    for (int k = 0; k < 3; ++k) {
        double a[3] = {p.x, p.y, p.theta};
        double b[3] = {p.x, p.y, p.theta};
        a[k] += H;
        b[k] -= H;
        const point2_t qa = observe_inverse((pose2_t){a[0], a[1], a[2]}, z);
        const point2_t qb = observe_inverse((pose2_t){b[0], b[1], b[2]}, z);
        np[0][k] = (qa.x - qb.x) / (2 * H);
        np[1][k] = (qa.y - qb.y) / (2 * H);
    }
    for (int k = 0; k < 2; ++k) {
        sighting_t a = z;
        sighting_t b = z;
        if (k == 0) {
            a.range_m += H;
            b.range_m -= H;
        } else {
            a.bearing_rad += H;
            b.bearing_rad -= H;
        }
        const point2_t qa = observe_inverse(p, a);
        const point2_t qb = observe_inverse(p, b);
        nz[0][k] = (qa.x - qb.x) / (2 * H);
        nz[1][k] = (qa.y - qb.y) / (2 * H);
    }
    fd_check(&gp[0][0], &np[0][0], 6, 1e-7);
    fd_check(&gz[0][0], &nz[0][0], 4, 1e-7);
}

static void test_motion_model(void **state)
{
    (void)state;
    /* body velocity integration against fine Euler steps */
    const double vx = 0.4;
    const double vy = -0.15;
    const double w = 0.9;
    const double dt = 0.5;
    const odo_increment_t u = motion_from_body_velocity(vx, vy, w, dt);
    pose2_t p = {0.0, 0.0, 0.0};
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
        const double h = dt / n;
        const double th = p.theta + 0.5 * w * h; /* midpoint heading */
        p.x += h * (cos(th) * vx - sin(th) * vy);
        p.y += h * (sin(th) * vx + cos(th) * vy);
        p.theta += w * h;
    }
    ASSERT_NEAR(u.dx, p.x, 1e-9);
    ASSERT_NEAR(u.dy, p.y, 1e-9);
    ASSERT_NEAR(u.dtheta, w * dt, 1e-15);
    /* w -> 0 limit is a straight line and continuous */
    const odo_increment_t s = motion_from_body_velocity(vx, vy, 1e-12, dt);
    ASSERT_NEAR(s.dx, vx * dt, 1e-12);
    ASSERT_NEAR(s.dy, vy * dt, 1e-12);
    /* either side of the series switch (th = 1e-6) agrees with the series */
    for (int k = 0; k < 2; ++k) {
        const double wk = k == 0 ? 1.9e-6 : 2.1e-6;
        const double th = wk * dt;
        const odo_increment_t s2 = motion_from_body_velocity(vx, vy, wk, dt);
        ASSERT_NEAR(s2.dx, dt * (vx * (1.0 - th * th / 6.0) - vy * 0.5 * th), 1e-15);
        ASSERT_NEAR(s2.dy, dt * (vy * (1.0 - th * th / 6.0) + vx * 0.5 * th), 1e-15);
    }
    /* noise covariance scales with the wheel travel */
    slam_params_t sp = slam_params_default();
    sp.noise.odo_xy_var_m2_per_m = 0.01;
    sp.noise.odo_theta_var_rad2_per_m = 0.02;
    sp.base_radius_m = 0.2;
    const odo_increment_t v = {0.3, 0.4, -0.5}; /* travel 0.5 + 0.2 * 0.5 = 0.6 m */
    const cov3_t r = motion_noise_cov(&sp, v);
    ASSERT_NEAR(r.m[0][0], 0.006, 1e-15);
    ASSERT_NEAR(r.m[1][1], 0.006, 1e-15);
    ASSERT_NEAR(r.m[2][2], 0.012, 1e-15);
    ASSERT_NEAR(r.m[0][1], 0.0, 0.0);
    const odo_increment_t zero = {0.0, 0.0, 0.0};
    ASSERT_NEAR(motion_noise_cov(&sp, zero).m[0][0], 0.0, 0.0);
    /* Monte Carlo: sample covariance of motion_sample matches R(u) */
    rng_t rng;
    rng_seed(&rng, 7U);
    const int mc = 200000;
    double m1[3] = {0, 0, 0};
    double m2[3] = {0, 0, 0};
    for (int i = 0; i < mc; ++i) {
        const odo_increment_t x = motion_sample(&sp, v, &rng);
        const double d[3] = {x.dx - v.dx, x.dy - v.dy, x.dtheta - v.dtheta};
        for (int k = 0; k < 3; ++k) {
            m1[k] += d[k];
            m2[k] += d[k] * d[k];
        }
    }
    for (int k = 0; k < 3; ++k) {
        const double var = r.m[k][k];
        ASSERT_NEAR(m1[k] / mc, 0.0, 5.0 * sqrt(var / mc));
        /* variance of a sample variance: 2 var^2 / n; 5 sigma */
        ASSERT_NEAR(m2[k] / mc, var, 5.0 * var * sqrt(2.0 / mc));
    }
}

static void test_motion_jacobians(void **state)
{
    (void)state;
    const pose2_t p = {1.0, -2.0, 0.7};
    const odo_increment_t u = {0.2, 0.05, 0.1};
    double g[3][3];
    double v[3][3];
    motion_jacobians(p, u, g, v);
    for (int k = 0; k < 3; ++k) {
        double a[3] = {u.dx, u.dy, u.dtheta};
        double b[3] = {u.dx, u.dy, u.dtheta};
        a[k] += H;
        b[k] -= H;
        const pose2_t qa = motion_apply(p, (odo_increment_t){a[0], a[1], a[2]});
        const pose2_t qb = motion_apply(p, (odo_increment_t){b[0], b[1], b[2]});
        ASSERT_NEAR(v[0][k], (qa.x - qb.x) / (2 * H), 1e-7);
        ASSERT_NEAR(v[1][k], (qa.y - qb.y) / (2 * H), 1e-7);
        ASSERT_NEAR(v[2][k], angle_wrap(qa.theta - qb.theta) / (2 * H), 1e-7);
    }
    ASSERT_NEAR(g[0][2], -sin(0.7) * 0.2 - cos(0.7) * 0.05, 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_angle_wrap),
        cmocka_unit_test(test_pose_compose_inverse),
        cmocka_unit_test(test_cov2_ops),
        cmocka_unit_test(test_cov2_from_3x3),
        cmocka_unit_test(test_cov3_ops),
        cmocka_unit_test(test_compose_jacobians),
        cmocka_unit_test(test_apply_jacobians),
        cmocka_unit_test(test_observe_jacobians),
        cmocka_unit_test(test_observe_inverse),
        cmocka_unit_test(test_motion_model),
        cmocka_unit_test(test_motion_jacobians),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
