/* Obstacle behaviour: total least squares fits of known lines (exact and
 * noisy), the right-turn rule, and whole scans ray-cast against walls at
 * known distances and angles giving the expected detection, line and
 * command. */
#include <string.h>

#include "test_util.h"

#include "coslam/obstacle.h"
#include "coslam/rng.h"

#define PI COSLAM_PI
#define N_SCAN 682

static double rr[N_SCAN], aa[N_SCAN];

/* URG-04LX angles: steps 44..725, 1024 per turn, front at 384 */
static void urg_angles(void)
{
    for (int i = 0; i < N_SCAN; ++i) aa[i] = (44.0 + i - 384.0) * 2.0 * PI / 1024.0;
}

typedef struct {
    point2_t a, b;
} seg_t;

/* distance from the sensor (pose s, in the robot frame) along sensor angle
 * `ang` to the nearest segment, NaN if none within 5.6 m */
static double cast(pose2_t s, double ang, const seg_t *segs, int n)
{
    const double th = s.theta + ang;
    const double dx = cos(th), dy = sin(th);
    double best = NAN;
    for (int i = 0; i < n; ++i) {
        const double ex = segs[i].b.x - segs[i].a.x, ey = segs[i].b.y - segs[i].a.y;
        const double den = dx * ey - dy * ex;
        if (fabs(den) < 1e-12) continue;
        const double wx = segs[i].a.x - s.x, wy = segs[i].a.y - s.y;
        const double t = (wx * ey - wy * ex) / den; /* along the ray */
        const double u = (wx * dy - wy * dx) / den; /* along the segment */
        if (t > 0 && u >= 0 && u <= 1 && t <= 5.6 && (isnan(best) || t < best)) best = t;
    }
    return best;
}

static void scan_of(pose2_t sensor, const seg_t *segs, int n)
{
    urg_angles();
    for (int i = 0; i < N_SCAN; ++i) rr[i] = cast(sensor, aa[i], segs, n);
}

/* a wall through p at direction phi, 20 m long */
static seg_t wall(double px, double py, double phi)
{
    seg_t s = {{px - 10 * cos(phi), py - 10 * sin(phi)}, {px + 10 * cos(phi), py + 10 * sin(phi)}};
    return s;
}

static obstacle_params_t P;
static const pose2_t AT_ORIGIN = {0, 0, 0};

static int setup(void **state)
{
    (void)state;
    obstacle_params_default(&P);
    return 0;
}

static void test_fit_exact_lines(void **state)
{
    (void)state;
    point2_t pts[50];
    for (int i = 0; i < 50; ++i) pts[i] = (point2_t){-1.0 + 0.05 * i, 2.0 * (-1.0 + 0.05 * i) + 1.0};
    obstacle_line_t l;
    assert_int_equal(obstacle_fit_line(pts, 50, &l), COSLAM_OK);
    ASSERT_NEAR(l.dir_rad, atan(2.0), 1e-12);
    ASSERT_NEAR(l.dist_m, 1.0 / sqrt(5.0), 1e-12); /* |c| / sqrt(a^2 + b^2) for 2x - y + 1 = 0 */
    ASSERT_NEAR(l.rms_m, 0.0, 1e-7);
    assert_int_equal(l.n, 50);
    /* a vertical line x = 3 (where a y-on-x regression would fail) */
    for (int i = 0; i < 50; ++i) pts[i] = (point2_t){3.0, -2.0 + 0.1 * i};
    assert_int_equal(obstacle_fit_line(pts, 50, &l), COSLAM_OK);
    ASSERT_NEAR(fabs(l.dir_rad), PI / 2, 1e-12);
    ASSERT_NEAR(l.dist_m, 3.0, 1e-12);
    ASSERT_NEAR(l.centroid.x, 3.0, 1e-12);
    ASSERT_NEAR(l.centroid.y, -2.0 + 0.1 * 24.5, 1e-12);
    /* far from the origin: the shifted sums stay accurate */
    for (int i = 0; i < 50; ++i) pts[i] = (point2_t){1e6 + 0.01 * i, 1e6 - 0.01 * i};
    assert_int_equal(obstacle_fit_line(pts, 50, &l), COSLAM_OK);
    ASSERT_NEAR(l.dir_rad, -PI / 4, 1e-9);
}

static void test_fit_noisy_line(void **state)
{
    (void)state;
    rng_t rng;
    rng_seed(&rng, 7);
    enum { N = 400 };
    static point2_t pts[N];
    const double phi = 0.3, sigma = 0.01;
    for (int i = 0; i < N; ++i) {
        const double t = -1.0 + 2.0 * i / (N - 1);
        const double e = rng_normal(&rng, 0.0, sigma); /* perpendicular noise */
        pts[i] = (point2_t){0.5 + t * cos(phi) - e * sin(phi), 0.2 + t * sin(phi) + e * cos(phi)};
    }
    obstacle_line_t l;
    assert_int_equal(obstacle_fit_line(pts, N, &l), COSLAM_OK);
    /* angle standard error ~ sigma / (sqrt(N) * spread) = 0.01 / (20 * 0.58) */
    ASSERT_NEAR(l.dir_rad, phi, 0.005);
    ASSERT_NEAR(l.rms_m, sigma, 0.15 * sigma);
}

static void test_fit_degenerate(void **state)
{
    (void)state;
    point2_t pts[3] = {{1, 1}, {1, 1}, {1, 1}};
    obstacle_line_t l;
    assert_int_equal(obstacle_fit_line(pts, 1, &l), COSLAM_E_DEGENERATE);
    assert_int_equal(l.n, 1);
    assert_int_equal(obstacle_fit_line(pts, 3, &l), COSLAM_E_DEGENERATE);
    pts[1].x = NAN;
    assert_int_equal(obstacle_fit_line(pts, 3, &l), COSLAM_E_NUMERIC);
    assert_int_equal(obstacle_fit_line(NULL, 3, &l), COSLAM_E_ARG);
}

static void test_right_turn_rule(void **state)
{
    (void)state;
    ASSERT_NEAR(obstacle_parallel_right_rad(PI / 2, 0), -PI / 2, 1e-12);
    ASSERT_NEAR(obstacle_parallel_right_rad(-PI / 2, 0), -PI / 2, 1e-12);
    ASSERT_NEAR(obstacle_parallel_right_rad(PI / 3, 0), -2 * PI / 3, 1e-12);
    ASSERT_NEAR(obstacle_parallel_right_rad(-PI / 3, 0), -PI / 3, 1e-12);
    ASSERT_NEAR(obstacle_parallel_right_rad(0, 0), 0, 1e-12);
    ASSERT_NEAR(obstacle_parallel_right_rad(PI, 0), 0, 1e-12);
    /* relative to the motion direction: moving left (pi/2), a wall along x */
    ASSERT_NEAR(obstacle_parallel_right_rad(0, PI / 2), -PI / 2, 1e-12);
    for (int i = -50; i <= 50; ++i) {
        const double d = obstacle_parallel_right_rad(0.07 * i, 0.05 * i * i);
        assert_true(d > -PI && d <= 0.0);
        /* parallel: differs from the line direction by a multiple of pi */
        const double k = (0.05 * i * i + d - 0.07 * i) / PI;
        ASSERT_NEAR(k, round(k), 1e-9);
    }
}

static void test_wall_across_path(void **state)
{
    (void)state;
    const seg_t w = wall(0.5, 0.0, PI / 2);
    scan_of(AT_ORIGIN, &w, 1);
    obstacle_cmd_t c;
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    assert_true(c.detected && c.line_ok);
    ASSERT_NEAR(c.nearest_m, 0.5, 1e-3); /* the ray nearest the x axis */
    ASSERT_NEAR(fabs(c.line.dir_rad), PI / 2, 1e-9);
    ASSERT_NEAR(c.line.dist_m, 0.5, 1e-9);
    ASSERT_NEAR(c.line.rms_m, 0.0, 1e-6);
    /* points within the 1 m fit radius of (0.5, 0): |y| <= 1 */
    assert_true(c.line.n > 300);
    ASSERT_NEAR(c.heading_change_rad, -PI / 2, 1e-9); /* turn right */
    ASSERT_NEAR(c.speed_mps, 0.0, 1e-9);               /* on the spot */
}

static void test_slanted_walls(void **state)
{
    (void)state;
    obstacle_cmd_t c;
    /* receding to the left at 60 deg: the right turn is the long one, -120 deg */
    seg_t w = wall(0.5, 0.0, PI / 3);
    scan_of(AT_ORIGIN, &w, 1);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    assert_true(c.detected);
    ASSERT_NEAR(c.line.dir_rad, PI / 3, 1e-9);
    ASSERT_NEAR(c.line.dist_m, 0.5 * sin(PI / 3), 1e-9);
    ASSERT_NEAR(c.heading_change_rad, -2 * PI / 3, 1e-9);
    ASSERT_NEAR(c.speed_mps, 0.0, 1e-12);
    /* receding to the right at -60 deg: -60 deg, half speed */
    w = wall(0.5, 0.0, -PI / 3);
    scan_of(AT_ORIGIN, &w, 1);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    ASSERT_NEAR(c.line.dir_rad, -PI / 3, 1e-9);
    ASSERT_NEAR(c.heading_change_rad, -PI / 3, 1e-9);
    ASSERT_NEAR(c.speed_mps, 0.5 * P.cruise_speed_mps, 1e-9);
}

static void test_noisy_wall(void **state)
{
    (void)state;
    const double phi = -0.4;
    const seg_t w = wall(0.45, 0.05, phi);
    scan_of(AT_ORIGIN, &w, 1);
    rng_t rng;
    rng_seed(&rng, 99);
    for (int i = 0; i < N_SCAN; ++i)
        if (!isnan(rr[i])) rr[i] += rng_normal(&rng, 0.0, 0.01);
    obstacle_cmd_t c;
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    ASSERT_NEAR(c.line.dir_rad, phi, 0.02);
    ASSERT_NEAR(c.heading_change_rad, phi, 0.02);
    ASSERT_NEAR(c.line.rms_m, 0.01, 0.004);
}

static void test_clear_paths(void **state)
{
    (void)state;
    obstacle_cmd_t c;
    /* a wall alongside, outside the corridor (half width 0.275 m) */
    seg_t w = wall(0.0, 0.4, 0.0);
    scan_of(AT_ORIGIN, &w, 1);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    assert_false(c.detected);
    assert_true(isinf(c.nearest_m));
    ASSERT_NEAR(c.heading_change_rad, 0.0, 0.0);
    ASSERT_NEAR(c.speed_mps, P.cruise_speed_mps, 0.0);
    /* a wall ahead beyond the stop distance: seen, not acted on */
    w = wall(2.0, 0.0, PI / 2);
    scan_of(AT_ORIGIN, &w, 1);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    assert_false(c.detected);
    ASSERT_NEAR(c.nearest_m, 2.0, 1e-3);
    ASSERT_NEAR(c.speed_mps, P.cruise_speed_mps, 0.0);
    /* an empty scan */
    for (int i = 0; i < N_SCAN; ++i) rr[i] = INFINITY;
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    assert_false(c.detected);
}

static void test_omni_motion_and_sensor_offset(void **state)
{
    (void)state;
    obstacle_cmd_t c;
    /* moving left (+y); a wall along x at y = 0.5 is in the way */
    seg_t w = wall(0.0, 0.5, 0.0);
    scan_of(AT_ORIGIN, &w, 1);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, PI / 2, rr, aa, N_SCAN, &c), COSLAM_OK);
    assert_true(c.detected);
    ASSERT_NEAR(c.nearest_m, 0.5, 1e-3);
    ASSERT_NEAR(c.heading_change_rad, -PI / 2, 1e-9); /* new direction: straight ahead */
    /* sensor 0.2 m ahead of the robot centre: a wall 0.3 m from the sensor
     * is 0.5 m from the robot */
    const pose2_t sensor = {0.2, 0.0, 0.0};
    w = wall(0.5, 0.0, PI / 2);
    scan_of(sensor, &w, 1); /* cast() works in the robot frame */
    assert_int_equal(obstacle_evaluate(&P, sensor, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    ASSERT_NEAR(c.nearest_m, 0.5, 1e-3);
    ASSERT_NEAR(c.line.dist_m, 0.5, 1e-9);
    /* a sensor mounted backwards sees the same wall through the other side */
    const pose2_t back = {0.0, 0.0, PI - 1e-9};
    const seg_t behind = wall(-0.5, 0.0, PI / 2);
    scan_of(back, &behind, 1);
    assert_int_equal(obstacle_evaluate(&P, back, PI, rr, aa, N_SCAN, &c), COSLAM_OK);
    assert_true(c.detected);
    ASSERT_NEAR(c.heading_change_rad, -PI / 2, 1e-6);
}

static void test_only_the_obstacle_is_fitted(void **state)
{
    (void)state;
    /* a 0.2 m box face at x = 0.4 in front of a far wall at x = 1.5 */
    const seg_t segs[2] = {{{0.4, -0.1}, {0.4, 0.1}}, {{1.5, -5}, {1.5, 5}}};
    scan_of(AT_ORIGIN, segs, 2);
    int box_rays = 0;
    for (int i = 0; i < N_SCAN; ++i) box_rays += !isnan(rr[i]) && fabs(rr[i] * cos(aa[i]) - 0.4) < 1e-9;
    obstacle_cmd_t c;
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    assert_int_equal(c.line.n, box_rays);
    ASSERT_NEAR(c.line.centroid.x, 0.4, 1e-9);
    ASSERT_NEAR(c.heading_change_rad, -PI / 2, 1e-9);
}

static void test_degenerate_and_clearance(void **state)
{
    (void)state;
    obstacle_cmd_t c;
    /* one return in the corridor, nothing else: stop and turn right */
    for (int i = 0; i < N_SCAN; ++i) rr[i] = NAN;
    urg_angles();
    rr[340] = 0.4;
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_E_DEGENERATE);
    assert_true(c.detected);
    assert_false(c.line_ok);
    ASSERT_NEAR(c.heading_change_rad, -PI / 2, 0.0);
    ASSERT_NEAR(c.speed_mps, 0.0, 0.0);
    /* a wall receding right but closer than the clearance: turn, speed 0 */
    const seg_t w = wall(0.1, 0.0, -PI / 6);
    scan_of(AT_ORIGIN, &w, 1);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0.0, rr, aa, N_SCAN, &c), COSLAM_OK);
    ASSERT_NEAR(c.heading_change_rad, -PI / 6, 1e-9);
    ASSERT_NEAR(c.speed_mps, 0.0, 0.0);
}

static void test_arguments(void **state)
{
    (void)state;
    obstacle_cmd_t c;
    obstacle_params_t p = P;
    assert_int_equal(obstacle_evaluate(NULL, AT_ORIGIN, 0, rr, aa, 1, &c), COSLAM_E_ARG);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0, NULL, aa, 1, &c), COSLAM_E_ARG);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0, rr, aa, 1, NULL), COSLAM_E_ARG);
    p.min_fit_points = 1;
    assert_int_equal(obstacle_evaluate(&p, AT_ORIGIN, 0, rr, aa, 1, &c), COSLAM_E_ARG);
    p = P;
    p.stop_distance_m = -1;
    assert_int_equal(obstacle_evaluate(&p, AT_ORIGIN, 0, rr, aa, 1, &c), COSLAM_E_ARG);
    p = P;
    p.robot_width_m = NAN;
    assert_int_equal(obstacle_evaluate(&p, AT_ORIGIN, 0, rr, aa, 1, &c), COSLAM_E_ARG);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, NAN, rr, aa, 1, &c), COSLAM_E_NUMERIC);
    const pose2_t bad = {0, INFINITY, 0};
    assert_int_equal(obstacle_evaluate(&P, bad, 0, rr, aa, 1, &c), COSLAM_E_NUMERIC);
    assert_int_equal(obstacle_evaluate(&P, AT_ORIGIN, 0, NULL, NULL, 0, &c), COSLAM_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fit_exact_lines),
        cmocka_unit_test(test_fit_noisy_line),
        cmocka_unit_test(test_fit_degenerate),
        cmocka_unit_test(test_right_turn_rule),
        cmocka_unit_test_setup(test_wall_across_path, setup),
        cmocka_unit_test_setup(test_slanted_walls, setup),
        cmocka_unit_test_setup(test_noisy_wall, setup),
        cmocka_unit_test_setup(test_clear_paths, setup),
        cmocka_unit_test_setup(test_omni_motion_and_sensor_offset, setup),
        cmocka_unit_test_setup(test_only_the_obstacle_is_fitted, setup),
        cmocka_unit_test_setup(test_degenerate_and_clearance, setup),
        cmocka_unit_test_setup(test_arguments, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
