#include "coslam/motion.h"

#include <math.h>

odo_increment_t motion_from_body_velocity(double vx, double vy, double w, double dt)
{
    const double th = w * dt;
    /* a = sin(th)/w, b = (1 - cos(th))/w, with their series near w = 0 */
    double a;
    double b;
    if (fabs(th) < 1e-6) {
        a = dt * (1.0 - th * th / 6.0);
        b = dt * (0.5 * th);
    } else {
        a = sin(th) / w;
        const double sh = sin(0.5 * th);
        b = 2.0 * sh * sh / w; /* 1 - cos without cancellation */
    }
    odo_increment_t u;
    u.dx = a * vx - b * vy;
    u.dy = b * vx + a * vy;
    u.dtheta = th;
    return u;
}

pose2_t motion_apply(pose2_t pose, odo_increment_t u)
{
    const pose2_t d = {u.dx, u.dy, u.dtheta};
    return pose2_compose(pose, d);
}

double motion_travel_m(odo_increment_t u, double base_radius_m)
{
    return sqrt(u.dx * u.dx + u.dy * u.dy) + base_radius_m * fabs(u.dtheta);
}

cov3_t motion_noise_cov(const slam_params_t *p, odo_increment_t u)
{
    const double s = motion_travel_m(u, p->base_radius_m);
    const double vxy = p->noise.odo_xy_var_m2_per_m * s;
    return cov3_diag(vxy, vxy, p->noise.odo_theta_var_rad2_per_m * s);
}

odo_increment_t motion_sample(const slam_params_t *p, odo_increment_t u, rng_t *rng)
{
    const double s = motion_travel_m(u, p->base_radius_m);
    const double sd_xy = sqrt(p->noise.odo_xy_var_m2_per_m * s);
    const double sd_th = sqrt(p->noise.odo_theta_var_rad2_per_m * s);
    odo_increment_t r;
    r.dx = u.dx + sd_xy * rng_gauss(rng);
    r.dy = u.dy + sd_xy * rng_gauss(rng);
    r.dtheta = u.dtheta + sd_th * rng_gauss(rng);
    return r;
}

void motion_jacobians(pose2_t pose, odo_increment_t u, double g[3][3], double v[3][3])
{
    const pose2_t d = {u.dx, u.dy, u.dtheta};
    pose2_compose_jacobians(pose, d, g, v);
}

int motion_is_finite(odo_increment_t u)
{
    return isfinite(u.dx) && isfinite(u.dy) && isfinite(u.dtheta);
}

int motion_is_plausible(const slam_params_t *p, odo_increment_t u, double dt_s)
{
    if (!motion_is_finite(u) || !isfinite(dt_s) || dt_s < 0.0) {
        return 0;
    }
    const double t = dt_s + MOTION_PLAUSIBLE_SLACK_S;
    return hypot(u.dx, u.dy) <= p->max_speed_mps * t && fabs(u.dtheta) <= p->max_turn_radps * t;
}
