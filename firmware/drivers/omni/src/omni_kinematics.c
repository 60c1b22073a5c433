#include "omni/omni_kinematics.h"

#include <math.h>
#include <stddef.h>

#define RPM_PER_RADPS (60.0 / COSLAM_TWO_PI)

omni_kinematics_config_t omni_kinematics_config_default(void)
{
    omni_kinematics_config_t c;
    c.wheel_radius_m = 0.040;
    c.base_radius_m = 0.132;
    c.gear_ratio = 16.0;
    c.wheel_angle0_rad = COSLAM_PI / 3.0;
    return c;
}

coslam_status_t omni_kinematics_config_check(const omni_kinematics_config_t *cfg)
{
    if (cfg == NULL) return COSLAM_E_ARG;
    if (!isfinite(cfg->wheel_radius_m) || !(cfg->wheel_radius_m > 0.0)) return COSLAM_E_ARG;
    if (!isfinite(cfg->base_radius_m) || !(cfg->base_radius_m > 0.0)) return COSLAM_E_ARG;
    if (!isfinite(cfg->gear_ratio) || !(cfg->gear_ratio > 0.0)) return COSLAM_E_ARG;
    if (!isfinite(cfg->wheel_angle0_rad)) return COSLAM_E_ARG;
    return COSLAM_OK;
}

static double wheel_angle(const omni_kinematics_config_t *cfg, int k)
{
    return cfg->wheel_angle0_rad + (double)k * (COSLAM_TWO_PI / 3.0);
}

coslam_status_t omni_kinematics_inverse(const omni_kinematics_config_t *cfg, double vx_mps, double vy_mps,
                                        double w_radps, double motor_rpm[OMNI_WHEELS])
{
    if (motor_rpm == NULL || omni_kinematics_config_check(cfg) != COSLAM_OK) return COSLAM_E_ARG;
    if (!isfinite(vx_mps) || !isfinite(vy_mps) || !isfinite(w_radps)) {
        for (int k = 0; k < OMNI_WHEELS; ++k) motor_rpm[k] = 0.0;
        return COSLAM_E_NUMERIC;
    }
    /* rim speed -> wheel rate -> motor rate */
    const double scale = cfg->gear_ratio / cfg->wheel_radius_m * RPM_PER_RADPS;
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        const double a = wheel_angle(cfg, k);
        const double v = -sin(a) * vx_mps + cos(a) * vy_mps + cfg->base_radius_m * w_radps;
        motor_rpm[k] = v * scale;
    }
    return COSLAM_OK;
}

coslam_status_t omni_kinematics_forward(const omni_kinematics_config_t *cfg, const double motor_rpm[OMNI_WHEELS],
                                        double *vx_mps, double *vy_mps, double *w_radps)
{
    if (motor_rpm == NULL || omni_kinematics_config_check(cfg) != COSLAM_OK) return COSLAM_E_ARG;
    double vx = 0.0;
    double vy = 0.0;
    double w = 0.0;
    coslam_status_t st = COSLAM_OK;
    if (!isfinite(motor_rpm[0]) || !isfinite(motor_rpm[1]) || !isfinite(motor_rpm[2])) {
        st = COSLAM_E_NUMERIC;
    } else {
        const double scale = cfg->wheel_radius_m / (cfg->gear_ratio * RPM_PER_RADPS);
        double sum = 0.0;
        for (int k = 0; k < OMNI_WHEELS; ++k) {
            const double a = wheel_angle(cfg, k);
            const double v = motor_rpm[k] * scale;
            vx -= sin(a) * v;
            vy += cos(a) * v;
            sum += v;
        }
        vx *= 2.0 / 3.0;
        vy *= 2.0 / 3.0;
        w = sum / (3.0 * cfg->base_radius_m);
    }
    if (vx_mps != NULL) *vx_mps = vx;
    if (vy_mps != NULL) *vy_mps = vy;
    if (w_radps != NULL) *w_radps = w;
    return st;
}

coslam_status_t omni_kinematics_odometry(const omni_kinematics_config_t *cfg, const double motor_rpm[OMNI_WHEELS],
                                         double dt_s, odo_increment_t *u)
{
    if (u == NULL) return COSLAM_E_ARG;
    u->dx = 0.0;
    u->dy = 0.0;
    u->dtheta = 0.0;
    if (!isfinite(dt_s)) return COSLAM_E_NUMERIC;
    if (dt_s < 0.0) return COSLAM_E_ARG;
    double vx;
    double vy;
    double w;
    const coslam_status_t st = omni_kinematics_forward(cfg, motor_rpm, &vx, &vy, &w);
    if (st != COSLAM_OK) return st;
    *u = motion_from_body_velocity(vx, vy, w, dt_s);
    return COSLAM_OK;
}

odo_increment_t omni_kinematics_compose(odo_increment_t a, odo_increment_t b)
{
    const double c = cos(a.dtheta);
    const double s = sin(a.dtheta);
    odo_increment_t r;
    r.dx = a.dx + c * b.dx - s * b.dy;
    r.dy = a.dy + s * b.dx + c * b.dy;
    r.dtheta = a.dtheta + b.dtheta;
    return r;
}

double omni_kinematics_saturate(double motor_rpm[OMNI_WHEELS], double max_rpm)
{
    if (motor_rpm == NULL || !isfinite(max_rpm) || !(max_rpm > 0.0)) return 1.0;
    double peak = 0.0;
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        const double m = fabs(motor_rpm[k]);
        if (m > peak) peak = m;
    }
    if (!(peak > max_rpm)) return 1.0;
    const double f = max_rpm / peak;
    for (int k = 0; k < OMNI_WHEELS; ++k) motor_rpm[k] *= f;
    return f;
}
