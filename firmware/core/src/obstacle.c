#include "coslam/obstacle.h"

#include <math.h>
#include <string.h>

void obstacle_params_default(obstacle_params_t *p)
{
    COSLAM_ASSERT(p != NULL);
    p->robot_width_m = 0.45;
    p->margin_m = 0.05;
    p->stop_distance_m = 0.6;
    p->min_clearance_m = 0.15;
    p->cruise_speed_mps = 0.2;
    p->fit_radius_m = 1.0;
    p->max_gap_m = 0.15;
    p->min_fit_points = 3;
}

/* Scatter accumulator. Points are shifted by `ref` (a point of the set) so
 * the single-pass sums do not cancel catastrophically far from the origin. */
typedef struct {
    point2_t ref;
    double n, sx, sy, sxx, syy, sxy;
} scatter_t;

static void scatter_add(scatter_t *s, point2_t q)
{
    const double x = q.x - s->ref.x;
    const double y = q.y - s->ref.y;
    s->n += 1.0;
    s->sx += x;
    s->sy += y;
    s->sxx += x * x;
    s->syy += y * y;
    s->sxy += x * y;
}

/* Fit from the sums (step 4 of the header). */
static coslam_status_t scatter_fit(const scatter_t *s, obstacle_line_t *line)
{
    memset(line, 0, sizeof *line);
    line->n = (uint16_t)(s->n > 65535.0 ? 65535.0 : s->n);
    if (s->n < 2.0) {
        return COSLAM_E_DEGENERATE;
    }
    const double mx = s->sx / s->n;
    const double my = s->sy / s->n;
    /* central second moments (scatter matrix S / n) */
    const double cxx = s->sxx / s->n - mx * mx;
    const double cyy = s->syy / s->n - my * my;
    const double cxy = s->sxy / s->n - mx * my;
    const double half_diff = 0.5 * (cxx - cyy);
    const double root = sqrt(half_diff * half_diff + cxy * cxy);
    const double mean_eig = 0.5 * (cxx + cyy);
    const double lmax = mean_eig + root;
    const double lmin = mean_eig - root;
    line->centroid.x = s->ref.x + mx;
    line->centroid.y = s->ref.y + my;
    if (!(lmax > 1e-18)) {
        return COSLAM_E_DEGENERATE; /* all points (numerically) the same */
    }
    double phi = 0.5 * atan2(2.0 * cxy, cxx - cyy); /* in [-pi/2, pi/2] */
    line->dir_rad = phi;
    line->rms_m = sqrt(lmin > 0.0 ? lmin : 0.0);
    /* distance of the origin to the line: |c x d| */
    line->dist_m = fabs(line->centroid.x * sin(phi) - line->centroid.y * cos(phi));
    return COSLAM_OK;
}

coslam_status_t obstacle_fit_line(const point2_t *pts, size_t n, obstacle_line_t *line)
{
    if (pts == NULL || line == NULL || n > 65535U) {
        return COSLAM_E_ARG;
    }
    scatter_t s;
    memset(&s, 0, sizeof s);
    if (n > 0U) {
        s.ref = pts[0];
    }
    for (size_t i = 0; i < n; ++i) {
        if (!isfinite(pts[i].x) || !isfinite(pts[i].y)) {
            memset(line, 0, sizeof *line);
            return COSLAM_E_NUMERIC;
        }
        scatter_add(&s, pts[i]);
    }
    return scatter_fit(&s, line);
}

double obstacle_parallel_right_rad(double line_dir_rad, double motion_dir_rad)
{
    double d = angle_wrap(line_dir_rad - motion_dir_rad); /* [-pi, pi) */
    if (d > 0.0) {
        d -= COSLAM_PI;
    } else if (d <= -COSLAM_PI) {
        d = 0.0;
    }
    return d;
}

/* Reading i as a robot-frame point; 0 if it is not a valid return. */
static int reading_point(pose2_t sensor, const double *range_m, const double *angle_rad, size_t i, point2_t *q)
{
    const double r = range_m[i];
    const double a = angle_rad[i];
    if (!isfinite(r) || !(r > 0.0) || !isfinite(a)) {
        return 0;
    }
    const point2_t local = {r * cos(a), r * sin(a)};
    *q = pose2_apply(sensor, local);
    return 1;
}

static double dist2(point2_t a, point2_t b)
{
    const double dx = a.x - b.x;
    const double dy = a.y - b.y;
    return dx * dx + dy * dy;
}

/* Grow the obstacle from index i0 in direction step (+1/-1), adding points. */
static void grow(const obstacle_params_t *p, pose2_t sensor, const double *range_m, const double *angle_rad, size_t n,
                 size_t i0, int step, point2_t q0, scatter_t *s)
{
    point2_t prev = q0;
    const double gap2 = p->max_gap_m * p->max_gap_m;
    const double rad2 = p->fit_radius_m * p->fit_radius_m;
    size_t i = i0;
    for (;;) {
        if (step < 0) {
            if (i == 0U) return;
            --i;
        } else {
            if (i + 1U >= n) return;
            ++i;
        }
        point2_t q;
        if (!reading_point(sensor, range_m, angle_rad, i, &q)) {
            continue; /* invalid readings are skipped, not gaps */
        }
        if (dist2(q, prev) > gap2 || dist2(q, q0) > rad2) {
            return;
        }
        scatter_add(s, q);
        prev = q;
    }
}

static int params_ok(const obstacle_params_t *p)
{
    const double v[] = {p->robot_width_m, p->stop_distance_m, p->cruise_speed_mps, p->fit_radius_m, p->max_gap_m};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; ++i) {
        if (!isfinite(v[i]) || !(v[i] > 0.0)) return 0;
    }
    return isfinite(p->margin_m) && p->margin_m >= 0.0 && isfinite(p->min_clearance_m) && p->min_clearance_m >= 0.0 &&
           p->min_fit_points >= 2U;
}

coslam_status_t obstacle_evaluate(const obstacle_params_t *p, pose2_t sensor_in_robot, double motion_dir_rad,
                                  const double *range_m, const double *angle_rad, size_t n, obstacle_cmd_t *out)
{
    if (p == NULL || out == NULL || (n > 0U && (range_m == NULL || angle_rad == NULL)) || !params_ok(p)) {
        return COSLAM_E_ARG;
    }
    if (!pose2_is_finite(sensor_in_robot) || !isfinite(motion_dir_rad)) {
        return COSLAM_E_NUMERIC;
    }
    memset(out, 0, sizeof *out);
    out->nearest_m = (double)INFINITY;
    out->speed_mps = p->cruise_speed_mps;

    /* steps 1-2: corridor along u = (cos m, sin m) */
    const double ux = cos(motion_dir_rad);
    const double uy = sin(motion_dir_rad);
    const double half = 0.5 * p->robot_width_m + p->margin_m;
    size_t i0 = 0;
    point2_t q0 = {0.0, 0.0};
    for (size_t i = 0; i < n; ++i) {
        point2_t q;
        if (!reading_point(sensor_in_robot, range_m, angle_rad, i, &q)) {
            continue;
        }
        const double along = q.x * ux + q.y * uy;
        const double lateral = -q.x * uy + q.y * ux;
        if (along > 0.0 && fabs(lateral) <= half && along < out->nearest_m) {
            out->nearest_m = along;
            i0 = i;
            q0 = q;
        }
    }
    if (!(out->nearest_m < p->stop_distance_m)) {
        return COSLAM_OK; /* nothing in the way: keep going */
    }
    out->detected = 1;

    /* step 3: the obstacle's points around q0 */
    scatter_t s;
    memset(&s, 0, sizeof s);
    s.ref = q0;
    scatter_add(&s, q0);
    grow(p, sensor_in_robot, range_m, angle_rad, n, i0, -1, q0, &s);
    grow(p, sensor_in_robot, range_m, angle_rad, n, i0, +1, q0, &s);

    /* step 4 */
    const coslam_status_t st = scatter_fit(&s, &out->line);
    if (st != COSLAM_OK || out->line.n < p->min_fit_points) {
        out->line_ok = 0;
        out->heading_change_rad = -0.5 * COSLAM_PI;
        out->speed_mps = 0.0;
        return COSLAM_E_DEGENERATE;
    }
    out->line_ok = 1;

    /* steps 5-6 */
    out->heading_change_rad = obstacle_parallel_right_rad(out->line.dir_rad, motion_dir_rad);
    const double c = cos(out->heading_change_rad);
    out->speed_mps = out->nearest_m < p->min_clearance_m ? 0.0 : p->cruise_speed_mps * (c > 0.0 ? c : 0.0);
    return COSLAM_OK;
}
