/* Occupancy grid: exact log-odds along axis and diagonal rays, the
 * Bresenham cell set of arbitrary rays checked against its defining
 * property, clamping, no-return and invalid readings, rays leaving or
 * starting outside the grid, and a ray-cast room. */
#include <stdlib.h>
#include <string.h>

#include "test_util.h"

#include "coslam/occ_grid.h"
#include "coslam/rng.h"

#define C OCC_GRID_CELL_M
#define NX COSLAM_GRID_CELLS_X
#define NY COSLAM_GRID_CELLS_Y

static occ_grid_t grid; /* 80 KB: static, not on the stack */

/* sensor in the centre of cell (100, 100) of a grid with its corner at 0 */
static const pose2_t S0 = {100.5 * C, 100.5 * C, 0.0};

static void fresh(const occ_grid_params_t *p)
{
    assert_int_equal(occ_grid_init(&grid, p, 0.0, 0.0), COSLAM_OK);
}

static int count_nonzero(void)
{
    int n = 0;
    for (int y = 0; y < NY; ++y)
        for (int x = 0; x < NX; ++x) n += grid.cell[y][x] != 0;
    return n;
}

static void test_init_and_params(void **state)
{
    (void)state;
    occ_grid_params_t p;
    occ_grid_params_default(&p);
    assert_int_equal(occ_grid_init(&grid, NULL, 0.0, 0.0), COSLAM_OK);
    assert_int_equal(grid.q_occ, 847);
    assert_int_equal(grid.q_free, -405);
    assert_int_equal(grid.q_min, -2000);
    assert_int_equal(grid.q_max, 3500);
    assert_int_equal(count_nonzero(), 0);
    ASSERT_NEAR(occ_grid_prob(&grid, 5, 5), 0.5, 0.0);
    occ_grid_params_t bad = p;
    bad.l_occ = -1.0;
    assert_int_equal(occ_grid_init(&grid, &bad, 0, 0), COSLAM_E_ARG);
    bad = p;
    bad.l_free = 0.1;
    assert_int_equal(occ_grid_init(&grid, &bad, 0, 0), COSLAM_E_ARG);
    bad = p;
    bad.l_max = 40.0; /* beyond int16 storage */
    assert_int_equal(occ_grid_init(&grid, &bad, 0, 0), COSLAM_E_ARG);
    bad = p;
    bad.max_range_m = 0.01; /* below min range */
    assert_int_equal(occ_grid_init(&grid, &bad, 0, 0), COSLAM_E_ARG);
    bad = p;
    bad.no_return_free_m = NAN;
    assert_int_equal(occ_grid_init(&grid, &bad, 0, 0), COSLAM_E_ARG);
    bad = p;
    bad.max_range_m = 1e7;
    assert_int_equal(occ_grid_init(&grid, &bad, 0, 0), COSLAM_E_ARG);
    assert_int_equal(occ_grid_init(NULL, &p, 0, 0), COSLAM_E_ARG);
    assert_int_equal(occ_grid_init(&grid, &p, INFINITY, 0), COSLAM_E_ARG);
}

static void test_cells_along_x_ray(void **state)
{
    (void)state;
    fresh(NULL);
    const double r = 1.0, a = 0.0;
    occ_grid_result_t res;
    assert_int_equal(occ_grid_integrate_scan(&grid, S0, &r, &a, 1, &res), COSLAM_OK);
    /* end x = 100.5 c + 1 m = 120.5 c: cells 100..119 free, 120 occupied */
    for (int x = 100; x < 120; ++x) {
        ASSERT_NEAR(occ_grid_logodds(&grid, x, 100), -0.405, 1e-12);
    }
    ASSERT_NEAR(occ_grid_logodds(&grid, 120, 100), 0.847, 1e-12);
    ASSERT_NEAR(occ_grid_prob(&grid, 120, 100), 1.0 - 1.0 / (1.0 + exp(0.847)), 1e-12);
    assert_int_equal(count_nonzero(), 21);
    assert_int_equal(res.hits, 1);
    assert_int_equal(res.cells_updated, 21);
    int32_t ix = 0, iy = 0;
    assert_true(occ_grid_cell_of(&grid, 100.5 * C + 1.0, 100.5 * C, &ix, &iy));
    assert_int_equal(ix, 120);
    assert_int_equal(iy, 100);
    /* the same ray seen from the sensor rotated by pi/2 with angle -pi/2 */
    fresh(NULL);
    const pose2_t s90 = {S0.x, S0.y, COSLAM_PI / 2};
    const double am = -COSLAM_PI / 2;
    assert_int_equal(occ_grid_integrate_scan(&grid, s90, &r, &am, 1, NULL), COSLAM_OK);
    ASSERT_NEAR(occ_grid_logodds(&grid, 120, 100), 0.847, 1e-12);
    assert_int_equal(count_nonzero(), 21);
    /* and the -y direction: cells 100 down to 81 free, 80 occupied */
    fresh(NULL);
    const double ay = -COSLAM_PI / 2;
    assert_int_equal(occ_grid_integrate_scan(&grid, S0, &r, &ay, 1, NULL), COSLAM_OK);
    for (int y = 81; y <= 100; ++y) ASSERT_NEAR(occ_grid_logodds(&grid, 100, y), -0.405, 1e-12);
    ASSERT_NEAR(occ_grid_logodds(&grid, 100, 80), 0.847, 1e-12);
}

static void test_cells_along_diagonal(void **state)
{
    (void)state;
    fresh(NULL);
    const double r = sqrt(2.0) * 10.0 * C, a = COSLAM_PI / 4;
    assert_int_equal(occ_grid_integrate_scan(&grid, S0, &r, &a, 1, NULL), COSLAM_OK);
    for (int k = 0; k < 10; ++k) ASSERT_NEAR(occ_grid_logodds(&grid, 100 + k, 100 + k), -0.405, 1e-12);
    ASSERT_NEAR(occ_grid_logodds(&grid, 110, 110), 0.847, 1e-12);
    assert_int_equal(count_nonzero(), 11);
}

/* Every ray's cells: one per step of the major axis, 8-connected, each cell
 * centre within half a cell (perpendicular) of the line joining the centres
 * of the sensor's and the end point's cells, end cell occupied. */
static void test_bresenham_property_random_rays(void **state)
{
    (void)state;
    rng_t rng;
    rng_seed(&rng, 20240611);
    const int n_rays = COSLAM_TEST_FULL ? 2000 : 150;
    for (int k = 0; k < n_rays; ++k) {
        fresh(NULL);
        const pose2_t s = {(60.0 + 80.0 * rng_uniform(&rng)) * C, (60.0 + 80.0 * rng_uniform(&rng)) * C,
                           angle_wrap(6.3 * rng_uniform(&rng))};
        const double a = -COSLAM_PI + COSLAM_TWO_PI * rng_uniform(&rng);
        const double r = 0.05 + 2.9 * rng_uniform(&rng);
        assert_int_equal(occ_grid_integrate_scan(&grid, s, &r, &a, 1, NULL), COSLAM_OK);
        int32_t x0, y0, x1, y1;
        assert_true(occ_grid_cell_of(&grid, s.x, s.y, &x0, &y0));
        assert_true(occ_grid_cell_of(&grid, s.x + r * cos(s.theta + a), s.y + r * sin(s.theta + a), &x1, &y1));
        const int dx = abs(x1 - x0), dy = abs(y1 - y0);
        const int major = dx > dy ? dx : dy;
        assert_int_equal(count_nonzero(), major + 1);
        ASSERT_NEAR(occ_grid_logodds(&grid, x1, y1), 0.847, 1e-12);
        const double len = hypot((double)(x1 - x0), (double)(y1 - y0));
        const int lo_x = x0 < x1 ? x0 : x1, hi_x = x0 < x1 ? x1 : x0;
        const int lo_y = y0 < y1 ? y0 : y1, hi_y = y0 < y1 ? y1 : y0;
        int seen = 0;
        for (int y = 0; y < NY; ++y) {
            for (int x = 0; x < NX; ++x) {
                if (grid.cell[y][x] == 0) continue;
                ++seen;
                assert_true(x >= lo_x && x <= hi_x && y >= lo_y && y <= hi_y);
                if (len > 0.0) {
                    const double perp = fabs((double)(x - x0) * (y1 - y0) - (double)(y - y0) * (x1 - x0)) / len;
                    /* half a cell along the minor axis is at most half a cell perpendicular */
                    ASSERT_TRUE_MSG(perp <= 0.5 + 1e-9, "ray %d: cell (%d,%d) %.3f cells off the line\n", k, x, y,
                                    perp);
                }
                if (!(x == x1 && y == y1)) {
                    ASSERT_NEAR(occ_grid_logodds(&grid, x, y), -0.405, 1e-12);
                }
            }
        }
        assert_int_equal(seen, major + 1);
    }
}

static void test_clamping(void **state)
{
    (void)state;
    fresh(NULL);
    const double r = 1.0, a = 0.0;
    for (int i = 0; i < 10; ++i) occ_grid_integrate_scan(&grid, S0, &r, &a, 1, NULL);
    ASSERT_NEAR(occ_grid_logodds(&grid, 120, 100), 3.5, 0.0);   /* 10 * 0.847 clamped */
    ASSERT_NEAR(occ_grid_logodds(&grid, 110, 100), -2.0, 0.0);  /* 10 * -0.405 clamped */
    assert_true(occ_grid_stats(&grid)->saturated > 0);
    /* a clamped cell changes its mind in a bounded number of scans: moving
     * the wall away frees the old end cell after ceil(3.5 / 0.405) = 9 */
    const double r2 = 2.0;
    int n = 0;
    while (occ_grid_logodds(&grid, 120, 100) > 0.0) {
        occ_grid_integrate_scan(&grid, S0, &r2, &a, 1, NULL);
        ++n;
    }
    assert_int_equal(n, 9); /* 3.5 - 9 * 0.405 = -0.145 */
}

static void test_no_return_and_invalid(void **state)
{
    (void)state;
    occ_grid_params_t p;
    occ_grid_params_default(&p);
    p.no_return_free_m = 1.0;
    fresh(&p);
    const double r[] = {INFINITY, 6.0, NAN, -1.0, 0.01, 1.0};
    const double a[] = {0.0, COSLAM_PI / 2, 0.0, 0.0, 0.0, NAN};
    occ_grid_result_t res;
    assert_int_equal(occ_grid_integrate_scan(&grid, S0, r, a, 6, &res), COSLAM_OK);
    assert_int_equal(res.no_returns, 2);
    assert_int_equal(res.invalid, 4);
    assert_int_equal(res.hits, 0);
    /* free up to 1 m along +x and +y, the end cells free too, nothing occupied */
    for (int k = 0; k <= 20; ++k) {
        ASSERT_NEAR(occ_grid_logodds(&grid, 100 + k, 100), k == 0 ? -0.81 : -0.405, 1e-12);
        ASSERT_NEAR(occ_grid_logodds(&grid, 100, 100 + k), k == 0 ? -0.81 : -0.405, 1e-12);
    }
    assert_int_equal(count_nonzero(), 41);
    /* free length 0: no-return rays change nothing */
    p.no_return_free_m = 0.0;
    fresh(&p);
    assert_int_equal(occ_grid_integrate_scan(&grid, S0, r, a, 2, &res), COSLAM_OK);
    assert_int_equal(count_nonzero(), 0);
    assert_int_equal(res.no_returns, 2);
    /* non-finite pose: refused, nothing touched */
    const pose2_t bad = {NAN, 0, 0};
    assert_int_equal(occ_grid_integrate_scan(&grid, bad, r, a, 2, NULL), COSLAM_E_NUMERIC);
    const pose2_t far = {1e9, 0, 0};
    assert_int_equal(occ_grid_integrate_scan(&grid, far, r, a, 2, NULL), COSLAM_E_ARG);
    assert_int_equal(occ_grid_integrate_scan(&grid, S0, NULL, a, 2, NULL), COSLAM_E_ARG);
    assert_int_equal(occ_grid_integrate_scan(&grid, S0, NULL, NULL, 0, NULL), COSLAM_OK);
}

static void test_out_of_grid(void **state)
{
    (void)state;
    fresh(NULL);
    /* end at x = 100.5 c + 5.5 m = 210.5 c, beyond cell 199 */
    const double r[] = {5.5, 1.0}, a[] = {0.0, COSLAM_PI};
    occ_grid_result_t res;
    assert_int_equal(occ_grid_integrate_scan(&grid, S0, r, a, 2, &res), COSLAM_E_CAPACITY);
    assert_int_equal(res.out_of_grid, 1);
    assert_int_equal(res.hits, 1); /* the other ray still counted and integrated */
    assert_int_equal(occ_grid_stats(&grid)->out_of_grid, 1);
    for (int x = 101; x < NX; ++x) ASSERT_NEAR(occ_grid_logodds(&grid, x, 100), -0.405, 1e-12);
    ASSERT_NEAR(occ_grid_logodds(&grid, 80, 100), 0.847, 1e-12);
    /* sensor outside the grid looking in: cells from the border are updated */
    fresh(NULL);
    const pose2_t out = {-1.0, 100.5 * C, 0.0};
    const double r2 = 2.0, a2 = 0.0;
    assert_int_equal(occ_grid_integrate_scan(&grid, out, &r2, &a2, 1, &res), COSLAM_OK);
    for (int x = 0; x < 20; ++x) ASSERT_NEAR(occ_grid_logodds(&grid, x, 100), -0.405, 1e-12);
    ASSERT_NEAR(occ_grid_logodds(&grid, 20, 100), 0.847, 1e-12);
    assert_int_equal(count_nonzero(), 21);
}

/* range from (x, y) along th to the inside walls of the box [x0,x1]x[y0,y1] */
static double box_range(double x, double y, double th, double x0, double x1, double y0, double y1)
{
    const double c = cos(th), s = sin(th);
    double best = INFINITY;
    if (c > 1e-12) best = fmin(best, (x1 - x) / c);
    if (c < -1e-12) best = fmin(best, (x0 - x) / c);
    if (s > 1e-12) best = fmin(best, (y1 - y) / s);
    if (s < -1e-12) best = fmin(best, (y0 - y) / s);
    return best;
}

static void test_room(void **state)
{
    (void)state;
    fresh(NULL);
    enum { N = 720 };
    static double r[N], a[N];
    const pose2_t s = {5.01, 4.97, 0.3};
    for (int i = 0; i < N; ++i) {
        a[i] = -COSLAM_PI + COSLAM_TWO_PI * i / N;
        r[i] = box_range(s.x, s.y, s.theta + a[i], 3.0, 7.0, 3.5, 6.5);
    }
    occ_grid_result_t res;
    assert_int_equal(occ_grid_integrate_scan(&grid, s, r, a, N, &res), COSLAM_OK);
    assert_int_equal(res.hits, N);
    int occupied_ends = 0;
    for (int i = 0; i < N; ++i) {
        int32_t x, y;
        assert_true(occ_grid_cell_of(&grid, s.x + r[i] * cos(s.theta + a[i]), s.y + r[i] * sin(s.theta + a[i]), &x, &y));
        occupied_ends += occ_grid_prob(&grid, x, y) > 0.5;
    }
    /* rays grazing a neighbour's end cell near the corners may free it */
    ASSERT_TRUE_MSG(occupied_ends >= N * 95 / 100, "%d of %d end cells occupied\n", occupied_ends, N);
    int32_t x, y;
    assert_true(occ_grid_cell_of(&grid, 4.0, 4.0, &x, &y));
    assert_true(occ_grid_prob(&grid, x, y) < 0.5); /* inside: free */
    assert_true(occ_grid_cell_of(&grid, 8.0, 5.0, &x, &y));
    ASSERT_NEAR(occ_grid_prob(&grid, x, y), 0.5, 0.0); /* behind the wall: unknown */
    assert_true(occ_grid_cell_of(&grid, 5.0, 2.0, &x, &y));
    ASSERT_NEAR(occ_grid_prob(&grid, x, y), 0.5, 0.0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_init_and_params),
        cmocka_unit_test(test_cells_along_x_ray),
        cmocka_unit_test(test_cells_along_diagonal),
        cmocka_unit_test(test_bresenham_property_random_rays),
        cmocka_unit_test(test_clamping),
        cmocka_unit_test(test_no_return_and_invalid),
        cmocka_unit_test(test_out_of_grid),
        cmocka_unit_test(test_room),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
