#include "coslam/slam_params.h"

#include <math.h>

void slam_noise_to_array(const slam_noise_t *n, double w[SLAM_NOISE_N_WEIGHTS])
{
    w[0] = n->range_var_m2;
    w[1] = n->bearing_var_rad2;
    w[2] = n->odo_xy_var_m2_per_m;
    w[3] = n->odo_theta_var_rad2_per_m;
    w[4] = n->lm_process_var_m2_per_m;
    w[5] = n->init_xy_var_m2;
    w[6] = n->init_theta_var_rad2;
    w[7] = n->lm_init_var_m2;
}

void slam_noise_from_array(slam_noise_t *n, const double w[SLAM_NOISE_N_WEIGHTS])
{
    n->range_var_m2 = w[0];
    n->bearing_var_rad2 = w[1];
    n->odo_xy_var_m2_per_m = w[2];
    n->odo_theta_var_rad2_per_m = w[3];
    n->lm_process_var_m2_per_m = w[4];
    n->init_xy_var_m2 = w[5];
    n->init_theta_var_rad2 = w[6];
    n->lm_init_var_m2 = w[7];
}

slam_params_t slam_params_default(void)
{
    slam_params_t p;
    p.noise.range_var_m2 = 0.02 * 0.02;
    p.noise.bearing_var_rad2 = 0.035 * 0.035; /* 2 deg */
    p.noise.odo_xy_var_m2_per_m = 0.02 * 0.02;      /* 2 cm per sqrt(m) of wheel travel */
    p.noise.odo_theta_var_rad2_per_m = 0.0175 * 0.0175; /* 1 deg per sqrt(m) */
    p.noise.lm_process_var_m2_per_m = 0.0;
    p.noise.init_xy_var_m2 = 0.0;
    p.noise.init_theta_var_rad2 = 0.0;
    p.noise.lm_init_var_m2 = 0.0;
    p.noise.range_var_per_m2 = 0.03 * 0.03; /* 3 % of range, 1 sigma */
    p.track_offset_range_var_per_m2 = 0.0;
    p.track_offset_bearing_var_rad2 = 0.0;
    p.base_radius_m = 0.132;
    p.sensor_min_range_m = 0.3;
    p.sensor_max_range_m = 5.0;
    p.sensor_fov_rad = 50.0 * 3.14159265358979323846 / 180.0;
    p.visibility_margin = 0.9;
    p.gate_chi2 = 9.21;           /* 99 % of chi-square, 2 dof */
    p.new_landmark_chi2 = 25.0;   /* 5 sigma: nearer sightings are ambiguous, not new */
    p.new_landmark_log_lik = -1.0;
    p.exist_init = 1.0f;
    p.exist_hit = 1.0f;
    p.exist_miss = 1.0f;
    p.exist_confirm = 5.0f;
    p.exist_max = 10.0f;
    /* the paper's camera detects a marker in view with probability 0.9:
     * 0.5587, a landmark at exist_max exported through 8 certain misses
     * and removed at the 18th (slam_params.h) */
    p.exist_miss_confirmed = (float)slam_exist_miss_for_detection(0.9);
    p.exist_miss_bearing_sd_frac = 0.25;
    p.max_speed_mps = 3.0;
    p.max_turn_radps = 2.0 * 3.14159265358979323846;
    p.sighting_max_range_m = 20.0;
    return p;
}

double slam_exist_miss_for_detection(double p_detect)
{
    const double pf = SLAM_EXIST_P_FALSE;
    if (!(p_detect > pf && p_detect < 1.0)) {
        return -1.0;
    }
    return log((1.0 - pf) / (1.0 - p_detect)) / log(p_detect / pf);
}

static int finite_nonneg(double v)
{
    return isfinite(v) && v >= 0.0;
}

coslam_status_t slam_params_validate(const slam_params_t *p)
{
    if (p == 0) {
        return COSLAM_E_ARG;
    }
    const slam_noise_t *n = &p->noise;
    /* the sighting noise must be positive: it is inverted in every update */
    if (!(isfinite(n->range_var_m2) && n->range_var_m2 > 0.0) ||
        !(isfinite(n->bearing_var_rad2) && n->bearing_var_rad2 > 0.0) ||
        !finite_nonneg(n->odo_xy_var_m2_per_m) || !finite_nonneg(n->odo_theta_var_rad2_per_m) ||
        !finite_nonneg(n->lm_process_var_m2_per_m) || !finite_nonneg(n->init_xy_var_m2) ||
        !finite_nonneg(n->init_theta_var_rad2) || !finite_nonneg(n->lm_init_var_m2) ||
        !finite_nonneg(n->range_var_per_m2) || !finite_nonneg(p->track_offset_range_var_per_m2) ||
        !finite_nonneg(p->track_offset_bearing_var_rad2)) {
        return COSLAM_E_ARG;
    }
    if (!finite_nonneg(p->base_radius_m) || !finite_nonneg(p->sensor_min_range_m) ||
        !(isfinite(p->sensor_max_range_m) && p->sensor_max_range_m > p->sensor_min_range_m) ||
        !(isfinite(p->sensor_fov_rad) && p->sensor_fov_rad > 0.0 && p->sensor_fov_rad <= 6.2832) ||
        !(isfinite(p->visibility_margin) && p->visibility_margin > 0.0 && p->visibility_margin <= 1.0)) {
        return COSLAM_E_ARG;
    }
    if (!(isfinite(p->gate_chi2) && p->gate_chi2 > 0.0) ||
        !(isfinite(p->new_landmark_chi2) && p->new_landmark_chi2 >= p->gate_chi2) ||
        !isfinite(p->new_landmark_log_lik)) {
        return COSLAM_E_ARG;
    }
    if (!(isfinite(p->exist_init) && isfinite(p->exist_hit) && isfinite(p->exist_miss) &&
          isfinite(p->exist_confirm) && isfinite(p->exist_max)) ||
        p->exist_init < 0.0f || p->exist_hit < 0.0f || p->exist_miss < 0.0f ||
        p->exist_confirm < p->exist_init || p->exist_max < p->exist_confirm) {
        return COSLAM_E_ARG;
    }
    if (!(isfinite(p->exist_miss_confirmed) && p->exist_miss_confirmed >= 0.0f) ||
        !(isfinite(p->exist_miss_bearing_sd_frac) && p->exist_miss_bearing_sd_frac > 0.0)) {
        return COSLAM_E_ARG;
    }
    if (!(isfinite(p->max_speed_mps) && p->max_speed_mps > 0.0) ||
        !(isfinite(p->max_turn_radps) && p->max_turn_radps > 0.0) ||
        !(isfinite(p->sighting_max_range_m) && p->sighting_max_range_m > p->sensor_min_range_m)) {
        return COSLAM_E_ARG;
    }
    return COSLAM_OK;
}
