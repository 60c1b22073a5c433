/* Omni-wheel kinematics: analytic cases, round trips, saturation, and
 * odometry integrated along an arc against the closed-form trajectory. */
#include "../slam/test_util.h"

#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "omni/omni_kinematics.h"

/* motor rpm for a wheel rim speed v [m/s] with the Robotino defaults */
static double rim_to_rpm(double v) { return v / 0.040 * 16.0 * 60.0 / (2.0 * COSLAM_PI); }

static void test_defaults_and_checks(void **state)
{
    (void)state;
    const omni_kinematics_config_t c = omni_kinematics_config_default();
    ASSERT_NEAR(c.wheel_radius_m, 0.040, 0.0);
    ASSERT_NEAR(c.base_radius_m, 0.132, 0.0);
    ASSERT_NEAR(c.gear_ratio, 16.0, 0.0);
    assert_int_equal(omni_kinematics_config_check(&c), COSLAM_OK);
    omni_kinematics_config_t b = c;
    b.wheel_radius_m = 0.0;
    assert_int_equal(omni_kinematics_config_check(&b), COSLAM_E_ARG);
    b = c;
    b.base_radius_m = -0.1;
    assert_int_equal(omni_kinematics_config_check(&b), COSLAM_E_ARG);
    b = c;
    b.gear_ratio = NAN;
    assert_int_equal(omni_kinematics_config_check(&b), COSLAM_E_ARG);
    b = c;
    b.wheel_angle0_rad = INFINITY;
    assert_int_equal(omni_kinematics_config_check(&b), COSLAM_E_ARG);
    double rpm[3] = {1, 2, 3};
    assert_int_equal(omni_kinematics_inverse(&b, 0, 0, 0, rpm), COSLAM_E_ARG);
    assert_int_equal(omni_kinematics_inverse(&c, NAN, 0, 0, rpm), COSLAM_E_NUMERIC);
    assert_true(rpm[0] == 0.0 && rpm[1] == 0.0 && rpm[2] == 0.0);
    double vx = 1.0;
    rpm[1] = INFINITY;
    assert_int_equal(omni_kinematics_forward(&c, rpm, &vx, NULL, NULL), COSLAM_E_NUMERIC);
    ASSERT_NEAR(vx, 0.0, 0.0);
    odo_increment_t u;
    rpm[1] = 0.0;
    assert_int_equal(omni_kinematics_odometry(&c, rpm, -0.1, &u), COSLAM_E_ARG);
    assert_int_equal(omni_kinematics_odometry(&c, rpm, NAN, &u), COSLAM_E_NUMERIC);
    assert_int_equal(omni_kinematics_odometry(NULL, rpm, 0.1, &u), COSLAM_E_ARG);
}

static void test_analytic_cases(void **state)
{
    (void)state;
    const omni_kinematics_config_t c = omni_kinematics_config_default();
    double rpm[3];
    /* pure rotation: every wheel turns at R w / r * G, all equal */
    assert_int_equal(omni_kinematics_inverse(&c, 0.0, 0.0, 1.0, rpm), COSLAM_OK);
    const double expect_rot = rim_to_rpm(0.132 * 1.0);
    ASSERT_NEAR(expect_rot, 504.2029, 1e-3); /* 3.3 * 16 * 60 / 2pi */
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(rpm[k], expect_rot, 1e-9);
    /* forward at 1 m/s: wheels at 60, 180, 300 deg -> rim speeds -sin(a) */
    assert_int_equal(omni_kinematics_inverse(&c, 1.0, 0.0, 0.0, rpm), COSLAM_OK);
    ASSERT_NEAR(rpm[0], rim_to_rpm(-sqrt(3.0) / 2.0), 1e-9);
    ASSERT_NEAR(rpm[1], 0.0, 1e-9); /* the rear wheel only rolls sideways */
    ASSERT_NEAR(rpm[2], rim_to_rpm(sqrt(3.0) / 2.0), 1e-9);
    /* left at 1 m/s: rim speeds cos(a) = 0.5, -1, 0.5 */
    assert_int_equal(omni_kinematics_inverse(&c, 0.0, 1.0, 0.0, rpm), COSLAM_OK);
    ASSERT_NEAR(rpm[0], rim_to_rpm(0.5), 1e-9);
    ASSERT_NEAR(rpm[1], rim_to_rpm(-1.0), 1e-9);
    ASSERT_NEAR(rpm[2], rim_to_rpm(0.5), 1e-9);
    /* any pure translation has zero wheel-speed sum (no rotation) */
    assert_int_equal(omni_kinematics_inverse(&c, 0.37, -0.81, 0.0, rpm), COSLAM_OK);
    ASSERT_NEAR(rpm[0] + rpm[1] + rpm[2], 0.0, 1e-9);
    /* forward of equal speeds is a pure rotation */
    const double eq[3] = {100.0, 100.0, 100.0};
    double vx, vy, w;
    assert_int_equal(omni_kinematics_forward(&c, eq, &vx, &vy, &w), COSLAM_OK);
    ASSERT_NEAR(vx, 0.0, 1e-12);
    ASSERT_NEAR(vy, 0.0, 1e-12);
    ASSERT_NEAR(w, 100.0 / expect_rot, 1e-12);
}

static void round_trip(const omni_kinematics_config_t *c, uint64_t seed)
{
    rng_t rng;
    rng_seed(&rng, seed);
    for (int i = 0; i < 2000; ++i) {
        const double vx = rng_normal(&rng, 0.0, 1.0);
        const double vy = rng_normal(&rng, 0.0, 1.0);
        const double w = rng_normal(&rng, 0.0, 3.0);
        double rpm[3];
        double bx, by, bw;
        assert_int_equal(omni_kinematics_inverse(c, vx, vy, w, rpm), COSLAM_OK);
        assert_int_equal(omni_kinematics_forward(c, rpm, &bx, &by, &bw), COSLAM_OK);
        ASSERT_NEAR(bx, vx, 1e-12);
        ASSERT_NEAR(by, vy, 1e-12);
        ASSERT_NEAR(bw, w, 1e-12);
        /* and the other way: any three motor speeds are reachable */
        const double m[3] = {rng_normal(&rng, 0, 2000), rng_normal(&rng, 0, 2000), rng_normal(&rng, 0, 2000)};
        double m2[3];
        assert_int_equal(omni_kinematics_forward(c, m, &bx, &by, &bw), COSLAM_OK);
        assert_int_equal(omni_kinematics_inverse(c, bx, by, bw, m2), COSLAM_OK);
        for (int k = 0; k < 3; ++k) ASSERT_NEAR(m2[k], m[k], 1e-9);
    }
}

static void test_round_trip(void **state)
{
    (void)state;
    const omni_kinematics_config_t c = omni_kinematics_config_default();
    round_trip(&c, 1);
    const omni_kinematics_config_t other = {0.05, 0.2, 10.0, 0.3};
    round_trip(&other, 2);
}

static void test_saturation(void **state)
{
    (void)state;
    double rpm[3] = {6000.0, -3000.0, 1500.0};
    ASSERT_NEAR(omni_kinematics_saturate(rpm, 3000.0), 0.5, 1e-15);
    ASSERT_NEAR(rpm[0], 3000.0, 1e-12);
    ASSERT_NEAR(rpm[1], -1500.0, 1e-12);
    ASSERT_NEAR(rpm[2], 750.0, 1e-12);
    ASSERT_NEAR(omni_kinematics_saturate(rpm, 3000.0), 1.0, 0.0); /* already inside */
    ASSERT_NEAR(omni_kinematics_saturate(rpm, NAN), 1.0, 0.0);
    /* the direction of the body velocity is kept */
    const omni_kinematics_config_t c = omni_kinematics_config_default();
    double m[3];
    omni_kinematics_inverse(&c, 2.0, 1.0, 3.0, m);
    const double f = omni_kinematics_saturate(m, 1000.0);
    assert_true(f < 1.0);
    double vx, vy, w;
    omni_kinematics_forward(&c, m, &vx, &vy, &w);
    ASSERT_NEAR(vx, 2.0 * f, 1e-12);
    ASSERT_NEAR(vy, 1.0 * f, 1e-12);
    ASSERT_NEAR(w, 3.0 * f, 1e-12);
}

/* Closed form: constant body velocity (vx, vy, w) for t seconds from the
 * origin: theta = w t, p = int_0^t R(w s) v ds. */
static pose2_t arc(double vx, double vy, double w, double t)
{
    pose2_t p;
    const double th = w * t;
    p.x = (sin(th) * vx + (cos(th) - 1.0) * vy) / w;
    p.y = ((1.0 - cos(th)) * vx + sin(th) * vy) / w;
    p.theta = th;
    return p;
}

static void test_odometry_arc(void **state)
{
    (void)state;
    const omni_kinematics_config_t c = omni_kinematics_config_default();
    const double vx = 0.3, vy = 0.1, w = 0.5;
    double rpm[3];
    assert_int_equal(omni_kinematics_inverse(&c, vx, vy, w, rpm), COSLAM_OK);
    /* 10 s in 1000 steps of 10 ms, concatenated: 5 rad of turning */
    odo_increment_t acc = {0.0, 0.0, 0.0};
    for (int i = 0; i < 1000; ++i) {
        odo_increment_t inc;
        assert_int_equal(omni_kinematics_odometry(&c, rpm, 0.01, &inc), COSLAM_OK);
        acc = omni_kinematics_compose(acc, inc);
    }
    const pose2_t truth = arc(vx, vy, w, 10.0);
    ASSERT_NEAR(acc.dx, truth.x, 1e-9);
    ASSERT_NEAR(acc.dy, truth.y, 1e-9);
    ASSERT_NEAR(acc.dtheta, 5.0, 1e-9); /* unwrapped */
    /* one increment over the whole arc is the same */
    odo_increment_t one;
    omni_kinematics_odometry(&c, rpm, 10.0, &one);
    ASSERT_NEAR(one.dx, truth.x, 1e-9);
    ASSERT_NEAR(one.dy, truth.y, 1e-9);
    /* straight line (w = 0 branch) */
    omni_kinematics_inverse(&c, 0.4, -0.2, 0.0, rpm);
    omni_kinematics_odometry(&c, rpm, 2.5, &one);
    ASSERT_NEAR(one.dx, 1.0, 1e-12);
    ASSERT_NEAR(one.dy, -0.5, 1e-12);
    ASSERT_NEAR(one.dtheta, 0.0, 1e-12);
    /* compose agrees with SE(2) composition, and keeps full turns */
    const odo_increment_t a = {0.5, -0.2, 2.0};
    const odo_increment_t b = {-0.1, 0.7, 3.0};
    const odo_increment_t ab = omni_kinematics_compose(a, b);
    const pose2_t pa = {a.dx, a.dy, a.dtheta};
    const pose2_t pb = {b.dx, b.dy, b.dtheta};
    const pose2_t pab = pose2_compose(pa, pb);
    ASSERT_NEAR(ab.dx, pab.x, 1e-12);
    ASSERT_NEAR(ab.dy, pab.y, 1e-12);
    ASSERT_NEAR(ab.dtheta, 5.0, 1e-15);
    ASSERT_NEAR(angle_wrap(ab.dtheta - pab.theta), 0.0, 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_defaults_and_checks),
        cmocka_unit_test(test_analytic_cases),
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_saturation),
        cmocka_unit_test(test_odometry_arc),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
