#include "coslam/observe.h"

#include <math.h>

sighting_t observe_predict(pose2_t p, point2_t m)
{
    const double dx = m.x - p.x;
    const double dy = m.y - p.y;
    sighting_t z;
    z.range_m = sqrt(dx * dx + dy * dy);
    z.bearing_rad = angle_wrap(atan2(dy, dx) - p.theta);
    z.signature = 0;
    return z;
}

coslam_status_t observe_jacobians(pose2_t p, point2_t m, double h_pose[2][3], double h_lm[2][2])
{
    const double dx = m.x - p.x;
    const double dy = m.y - p.y;
    const double q = dx * dx + dy * dy;
    if (!(q > OBSERVE_MIN_RANGE_M * OBSERVE_MIN_RANGE_M)) {
        return COSLAM_E_DEGENERATE;
    }
    const double r = sqrt(q);
    /* d range / d m = (dx, dy)/r ; d bearing / d m = (-dy, dx)/q */
    const double rx = dx / r;
    const double ry = dy / r;
    const double bx = -dy / q;
    const double by = dx / q;
    if (h_lm != 0) {
        h_lm[0][0] = rx; h_lm[0][1] = ry;
        h_lm[1][0] = bx; h_lm[1][1] = by;
    }
    if (h_pose != 0) {
        h_pose[0][0] = -rx; h_pose[0][1] = -ry; h_pose[0][2] = 0.0;
        h_pose[1][0] = -bx; h_pose[1][1] = -by; h_pose[1][2] = -1.0;
    }
    return COSLAM_OK;
}

point2_t observe_inverse(pose2_t p, sighting_t z)
{
    const double a = p.theta + z.bearing_rad;
    point2_t m;
    m.x = p.x + z.range_m * cos(a);
    m.y = p.y + z.range_m * sin(a);
    return m;
}

void observe_inverse_jacobians(pose2_t p, sighting_t z, double g_pose[2][3], double g_z[2][2])
{
    const double a = p.theta + z.bearing_rad;
    const double c = cos(a);
    const double s = sin(a);
    if (g_pose != 0) {
        g_pose[0][0] = 1.0; g_pose[0][1] = 0.0; g_pose[0][2] = -z.range_m * s;
        g_pose[1][0] = 0.0; g_pose[1][1] = 1.0; g_pose[1][2] = z.range_m * c;
    }
    if (g_z != 0) {
        g_z[0][0] = c; g_z[0][1] = -z.range_m * s;
        g_z[1][0] = s; g_z[1][1] = z.range_m * c;
    }
}

cov2_t observe_noise(const slam_params_t *params, double range_m)
{
    const double vr = params->noise.range_var_m2 + params->noise.range_var_per_m2 * range_m * range_m;
    return cov2_make(vr, 0.0, params->noise.bearing_var_rad2);
}

void observe_innovation(sighting_t z, sighting_t zhat, double nu[2])
{
    nu[0] = z.range_m - zhat.range_m;
    nu[1] = angle_wrap(z.bearing_rad - zhat.bearing_rad);
}

int sighting_is_valid(const sighting_t *z)
{
    return isfinite(z->range_m) && isfinite(z->bearing_rad) && z->range_m > OBSERVE_MIN_RANGE_M;
}

int sighting_is_plausible(const sighting_t *z, const slam_params_t *p)
{
    return sighting_is_valid(z) && z->range_m <= p->sighting_max_range_m && fabs(z->bearing_rad) <= COSLAM_PI + 1e-9;
}
