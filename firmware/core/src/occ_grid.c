#include "coslam/occ_grid.h"

#include <math.h>
#include <string.h>

/* Largest |cell coordinate| the tracer accepts for the sensor (keeps every
 * int32_t computation far from overflow). */
#define SENSOR_CELL_LIMIT 1.0e6

void occ_grid_params_default(occ_grid_params_t *p)
{
    COSLAM_ASSERT(p != NULL);
    p->l_occ = 0.8472978603872037;   /* ln(0.7 / 0.3) */
    p->l_free = -0.4054651081081644; /* ln(0.4 / 0.6) */
    p->l_min = -2.0;
    p->l_max = 3.5;
    p->min_range_m = 0.02;
    p->max_range_m = 5.6;
    p->no_return_free_m = 2.0;
}

static int finite_all(const occ_grid_params_t *p)
{
    return isfinite(p->l_occ) && isfinite(p->l_free) && isfinite(p->l_min) && isfinite(p->l_max) &&
           isfinite(p->min_range_m) && isfinite(p->max_range_m) && isfinite(p->no_return_free_m);
}

static int16_t quantise(double l)
{
    return (int16_t)lround(l * OCC_GRID_LOGODDS_SCALE);
}

coslam_status_t occ_grid_init(occ_grid_t *g, const occ_grid_params_t *p, double origin_x_m, double origin_y_m)
{
    if (g == NULL || !isfinite(origin_x_m) || !isfinite(origin_y_m)) {
        return COSLAM_E_ARG;
    }
    occ_grid_params_t q;
    if (p != NULL) {
        q = *p;
    } else {
        occ_grid_params_default(&q);
    }
    const double lim = 32767.0 / OCC_GRID_LOGODDS_SCALE;
    if (!finite_all(&q) || q.l_occ <= 0.0 || q.l_free >= 0.0 || q.l_min >= 0.0 || q.l_max <= 0.0 || q.l_min < -lim ||
        q.l_max > lim || q.l_occ > lim || q.l_free < -lim || q.min_range_m < 0.0 || q.max_range_m <= q.min_range_m ||
        q.no_return_free_m < 0.0 || q.max_range_m > OCC_GRID_MAX_RAY_M || q.no_return_free_m > OCC_GRID_MAX_RAY_M) {
        return COSLAM_E_ARG;
    }
    g->params = q;
    g->origin_x_m = origin_x_m;
    g->origin_y_m = origin_y_m;
    g->q_occ = quantise(q.l_occ);
    g->q_free = quantise(q.l_free);
    g->q_min = quantise(q.l_min);
    g->q_max = quantise(q.l_max);
    occ_grid_clear(g);
    return COSLAM_OK;
}

void occ_grid_clear(occ_grid_t *g)
{
    COSLAM_ASSERT(g != NULL);
    memset(g->cell, 0, sizeof g->cell);
    memset(&g->stats, 0, sizeof g->stats);
}

/* Cell coordinate (may be outside the grid) of a map coordinate. */
static double cell_coord(double v_m, double origin_m)
{
    return floor((v_m - origin_m) / OCC_GRID_CELL_M);
}

static int inside(int32_t ix, int32_t iy)
{
    return ix >= 0 && iy >= 0 && ix < COSLAM_GRID_CELLS_X && iy < COSLAM_GRID_CELLS_Y;
}

int occ_grid_cell_of(const occ_grid_t *g, double x_m, double y_m, int32_t *ix, int32_t *iy)
{
    if (g == NULL || !isfinite(x_m) || !isfinite(y_m)) {
        return 0;
    }
    const double cx = cell_coord(x_m, g->origin_x_m);
    const double cy = cell_coord(y_m, g->origin_y_m);
    if (cx < 0.0 || cy < 0.0 || cx >= (double)COSLAM_GRID_CELLS_X || cy >= (double)COSLAM_GRID_CELLS_Y) {
        return 0;
    }
    if (ix != NULL) *ix = (int32_t)cx;
    if (iy != NULL) *iy = (int32_t)cy;
    return 1;
}

point2_t occ_grid_cell_center(const occ_grid_t *g, int32_t ix, int32_t iy)
{
    point2_t c;
    c.x = g->origin_x_m + ((double)ix + 0.5) * OCC_GRID_CELL_M;
    c.y = g->origin_y_m + ((double)iy + 0.5) * OCC_GRID_CELL_M;
    return c;
}

double occ_grid_logodds(const occ_grid_t *g, int32_t ix, int32_t iy)
{
    if (g == NULL || !inside(ix, iy)) {
        return 0.0;
    }
    return (double)g->cell[iy][ix] / OCC_GRID_LOGODDS_SCALE;
}

double occ_grid_prob(const occ_grid_t *g, int32_t ix, int32_t iy)
{
    return 1.0 - 1.0 / (1.0 + exp(occ_grid_logodds(g, ix, iy)));
}

const occ_grid_stats_t *occ_grid_stats(const occ_grid_t *g)
{
    return g != NULL ? &g->stats : NULL;
}

int occ_grid_line_free(const occ_grid_t *g, point2_t a, point2_t b, double l_occupied, double skip_end_m)
{
    if (g == NULL) {
        return 1;
    }
    const double dx = b.x - a.x;
    const double dy = b.y - a.y;
    const double len = sqrt(dx * dx + dy * dy);
    const double step = 0.5 * (double)COSLAM_GRID_CELL_MM * 1e-3;
    if (!isfinite(len) || len > 1e4) {
        return 1;
    }
    const double end = len - skip_end_m;
    for (double s = 0.0; s < end; s += step) {
        int32_t ix;
        int32_t iy;
        const double f = s / len;
        if (occ_grid_cell_of(g, a.x + f * dx, a.y + f * dy, &ix, &iy) && occ_grid_logodds(g, ix, iy) > l_occupied) {
            return 0;
        }
    }
    return 1;
}

/* Add q to a cell inside the grid, clamped to [q_min, q_max]. */
static void update(occ_grid_t *g, int32_t ix, int32_t iy, int16_t q, occ_grid_result_t *r)
{
    if (!inside(ix, iy)) {
        return;
    }
    int32_t v = (int32_t)g->cell[iy][ix] + q;
    if (v >= g->q_max) {
        v = g->q_max;
        g->stats.saturated++;
    } else if (v <= g->q_min) {
        v = g->q_min;
        g->stats.saturated++;
    }
    g->cell[iy][ix] = (int16_t)v;
    r->cells_updated++;
}

/*
 * Bresenham from (x0, y0) to (x1, y1) in cell coordinates: every cell but
 * the last gets l_free; the last gets l_occ if `hit`, else l_free.
 * Error term e = dx + dy (dy <= 0) tracks the signed distance of the next
 * cell corner to the ideal line, scaled by 2 max(|dx|, |dy|)-ish integers.
 */
static void trace(occ_grid_t *g, int32_t x0, int32_t y0, int32_t x1, int32_t y1, int hit, occ_grid_result_t *r)
{
    const int32_t dx = x1 > x0 ? x1 - x0 : x0 - x1;
    const int32_t dy = -(y1 > y0 ? y1 - y0 : y0 - y1);
    const int32_t sx = x0 < x1 ? 1 : -1;
    const int32_t sy = y0 < y1 ? 1 : -1;
    int32_t e = dx + dy;
    for (;;) {
        if (x0 == x1 && y0 == y1) {
            update(g, x0, y0, hit ? g->q_occ : g->q_free, r);
            return;
        }
        update(g, x0, y0, g->q_free, r);
        const int32_t e2 = 2 * e;
        if (e2 >= dy) {
            e += dy;
            x0 += sx;
        }
        if (e2 <= dx) {
            e += dx;
            y0 += sy;
        }
    }
}

coslam_status_t occ_grid_integrate_scan(occ_grid_t *g, pose2_t sensor_pose, const double *range_m,
                                        const double *angle_rad, size_t n, occ_grid_result_t *res)
{
    if (g == NULL || (n > 0U && (range_m == NULL || angle_rad == NULL))) {
        return COSLAM_E_ARG;
    }
    if (!pose2_is_finite(sensor_pose)) {
        return COSLAM_E_NUMERIC;
    }
    const double sx = cell_coord(sensor_pose.x, g->origin_x_m);
    const double sy = cell_coord(sensor_pose.y, g->origin_y_m);
    if (fabs(sx) > SENSOR_CELL_LIMIT || fabs(sy) > SENSOR_CELL_LIMIT) {
        return COSLAM_E_ARG;
    }
    const occ_grid_params_t *p = &g->params;
    occ_grid_result_t r;
    memset(&r, 0, sizeof r);
    const int32_t cx0 = (int32_t)sx;
    const int32_t cy0 = (int32_t)sy;
    for (size_t i = 0; i < n; ++i) {
        const double rng = range_m[i];
        const double a = angle_rad[i];
        if (isnan(rng) || rng < p->min_range_m || !isfinite(a)) {
            r.invalid++;
            continue;
        }
        const int hit = rng <= p->max_range_m; /* +INFINITY compares false */
        double len = rng;
        if (!hit) {
            r.no_returns++;
            len = p->no_return_free_m;
            if (len <= 0.0) {
                continue;
            }
        }
        const double th = sensor_pose.theta + a;
        const double ex = sensor_pose.x + len * cos(th);
        const double ey = sensor_pose.y + len * sin(th);
        const int32_t cx1 = (int32_t)cell_coord(ex, g->origin_x_m);
        const int32_t cy1 = (int32_t)cell_coord(ey, g->origin_y_m);
        if (hit) {
            if (inside(cx1, cy1)) {
                r.hits++;
            } else {
                r.out_of_grid++;
            }
        }
        trace(g, cx0, cy0, cx1, cy1, hit, &r);
    }
    g->stats.scans++;
    g->stats.hits += r.hits;
    g->stats.no_returns += r.no_returns;
    g->stats.invalid += r.invalid;
    g->stats.out_of_grid += r.out_of_grid;
    if (res != NULL) {
        *res = r;
    }
    return r.out_of_grid > 0U ? COSLAM_E_CAPACITY : COSLAM_OK;
}
