#include "coslam/view.h"

#include <math.h>
#include <string.h>

#include "coslam/pose2.h"

static int view_bin(double bearing_rad)
{
    const double a = angle_wrap(bearing_rad); /* [-pi, pi] */
    int b = (int)floor((a + COSLAM_PI) * ((double)COSLAM_VIEW_BINS / (2.0 * COSLAM_PI)));
    if (b < 0) {
        b = 0;
    }
    if (b >= COSLAM_VIEW_BINS) {
        b = COSLAM_VIEW_BINS - 1; /* bearing +pi is bin 0's -pi: either side is fine */
    }
    return b;
}

void view_profile_clear(view_profile_t *v)
{
    if (v != NULL) {
        v->valid = 0U;
    }
}

coslam_status_t view_profile_build(view_profile_t *v, const point2_t *pts, size_t n, pose2_t at)
{
    if (v == NULL) {
        return COSLAM_E_ARG;
    }
    v->valid = 0U;
    if ((pts == NULL && n > 0U) || !pose2_is_finite(at)) {
        return COSLAM_E_ARG;
    }
    const double c = cos(at.theta);
    const double s = sin(at.theta);
    for (int b = 0; b < COSLAM_VIEW_BINS; ++b) {
        v->near_m[b] = INFINITY;
    }
    for (size_t i = 0; i < n; ++i) {
        const double x = at.x + c * pts[i].x - s * pts[i].y;
        const double y = at.y + s * pts[i].x + c * pts[i].y;
        if (!isfinite(x) || !isfinite(y) || (x == 0.0 && y == 0.0)) {
            continue;
        }
        const float r = (float)sqrt(x * x + y * y);
        const int b = view_bin(atan2(y, x));
        if (r < v->near_m[b]) {
            v->near_m[b] = r;
        }
    }
    v->valid = 1U;
    return COSLAM_OK;
}

int view_blocks(const view_profile_t *v, double range_m, double bearing_rad, double margin_m)
{
    if (v == NULL || !v->valid || !isfinite(range_m) || !isfinite(bearing_rad) || !isfinite(margin_m)) {
        return 0;
    }
    return (double)v->near_m[view_bin(bearing_rad)] < range_m - margin_m;
}
