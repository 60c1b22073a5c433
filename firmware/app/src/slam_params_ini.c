#include "app/slam_params_ini.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define D_ SLAM_PARAMS_INI_DOUBLE
#define F_ SLAM_PARAMS_INI_FLOAT
#define NOISE_(f) offsetof(slam_params_t, noise) + offsetof(slam_noise_t, f)

/* Domains as slam_params_validate() has them; HUGE_VAL: no bound beyond
 * "finite"; FLT_MAX for float fields (a larger double would become inf). */
static const slam_params_ini_key_t keys[] = {
    {"range_var_m2", NOISE_(range_var_m2), D_, 0.0, HUGE_VAL, 1U},
    /* at most merge_config_t's max_bearing_var_rad2: the robot sends it with
     * its sightings of partners, who refuse more as implausible */
    {"bearing_var_rad2", NOISE_(bearing_var_rad2), D_, 0.0, 0.25, 1U},
    {"odo_xy_var_m2_per_m", NOISE_(odo_xy_var_m2_per_m), D_, 0.0, HUGE_VAL, 0U},
    {"odo_theta_var_rad2_per_m", NOISE_(odo_theta_var_rad2_per_m), D_, 0.0, HUGE_VAL, 0U},
    {"lm_process_var_m2_per_m", NOISE_(lm_process_var_m2_per_m), D_, 0.0, HUGE_VAL, 0U},
    {"init_xy_var_m2", NOISE_(init_xy_var_m2), D_, 0.0, HUGE_VAL, 0U},
    {"init_theta_var_rad2", NOISE_(init_theta_var_rad2), D_, 0.0, HUGE_VAL, 0U},
    {"lm_init_var_m2", NOISE_(lm_init_var_m2), D_, 0.0, HUGE_VAL, 0U},
    {"range_var_per_m2", NOISE_(range_var_per_m2), D_, 0.0, HUGE_VAL, 0U},
    {"base_radius_m", offsetof(slam_params_t, base_radius_m), D_, 0.0, HUGE_VAL, 0U},
    {"sensor_min_range_m", offsetof(slam_params_t, sensor_min_range_m), D_, 0.0, HUGE_VAL, 0U},
    {"sensor_max_range_m", offsetof(slam_params_t, sensor_max_range_m), D_, 0.0, HUGE_VAL, 1U},
    {"sensor_fov_rad", offsetof(slam_params_t, sensor_fov_rad), D_, 0.0, 6.2832, 1U},
    {"visibility_margin", offsetof(slam_params_t, visibility_margin), D_, 0.0, 1.0, 1U},
    {"gate_chi2", offsetof(slam_params_t, gate_chi2), D_, 0.0, HUGE_VAL, 1U},
    {"new_landmark_chi2", offsetof(slam_params_t, new_landmark_chi2), D_, 0.0, HUGE_VAL, 1U},
    {"new_landmark_log_lik", offsetof(slam_params_t, new_landmark_log_lik), D_, -HUGE_VAL, HUGE_VAL, 0U},
    {"exist_init", offsetof(slam_params_t, exist_init), F_, 0.0, FLT_MAX, 0U},
    {"exist_hit", offsetof(slam_params_t, exist_hit), F_, 0.0, FLT_MAX, 0U},
    {"exist_miss", offsetof(slam_params_t, exist_miss), F_, 0.0, FLT_MAX, 0U},
    {"exist_confirm", offsetof(slam_params_t, exist_confirm), F_, 0.0, FLT_MAX, 0U},
    {"exist_max", offsetof(slam_params_t, exist_max), F_, 0.0, FLT_MAX, 0U},
    {"exist_miss_confirmed", offsetof(slam_params_t, exist_miss_confirmed), F_, 0.0, FLT_MAX, 0U},
    {"exist_miss_bearing_sd_frac", offsetof(slam_params_t, exist_miss_bearing_sd_frac), D_, 0.0, HUGE_VAL, 1U},
    {"max_speed_mps", offsetof(slam_params_t, max_speed_mps), D_, 0.0, HUGE_VAL, 1U},
    {"max_turn_radps", offsetof(slam_params_t, max_turn_radps), D_, 0.0, HUGE_VAL, 1U},
    {"sighting_max_range_m", offsetof(slam_params_t, sighting_max_range_m), D_, 0.0, HUGE_VAL, 1U},
    {"track_offset_range_var_per_m2", offsetof(slam_params_t, track_offset_range_var_per_m2), D_, 0.0, HUGE_VAL, 0U},
    {"track_offset_bearing_var_rad2", offsetof(slam_params_t, track_offset_bearing_var_rad2), D_, 0.0, HUGE_VAL, 0U},
};

#define N_KEYS (sizeof keys / sizeof keys[0])

size_t slam_params_ini_count(void)
{
    return N_KEYS;
}

const slam_params_ini_key_t *slam_params_ini_key(size_t i)
{
    return i < N_KEYS ? &keys[i] : NULL;
}

const slam_params_ini_key_t *slam_params_ini_find(const char *name)
{
    if (name == NULL) {
        return NULL;
    }
    for (size_t i = 0; i < N_KEYS; ++i) {
        if (strcmp(keys[i].name, name) == 0) {
            return &keys[i];
        }
    }
    return NULL;
}

size_t slam_params_ini_index(const slam_params_ini_key_t *k)
{
    COSLAM_ASSERT(k >= keys && k < keys + N_KEYS);
    return (size_t)(k - keys);
}

coslam_status_t slam_params_ini_parse_number(const char *text, double *out)
{
    if (text == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    errno = 0;
    char *end = NULL;
    const double v = strtod(text, &end);
    if (end == text || *end != '\0' || errno == ERANGE || !isfinite(v)) {
        return COSLAM_E_NUMERIC;
    }
    *out = v;
    return COSLAM_OK;
}

coslam_status_t slam_params_ini_set(slam_params_t *p, const char *key, const char *text, char *msg, size_t msg_cap)
{
    if (msg != NULL && msg_cap > 0U) {
        msg[0] = '\0';
    }
    if (p == NULL || key == NULL || text == NULL) {
        return COSLAM_E_ARG;
    }
    const slam_params_ini_key_t *k = slam_params_ini_find(key);
    if (k == NULL) {
        if (msg != NULL && msg_cap > 0U) {
            (void)snprintf(msg, msg_cap, "unknown key '%s' in [slam]", key);
        }
        return COSLAM_E_UNSUPPORTED;
    }
    double v = 0.0;
    if (slam_params_ini_parse_number(text, &v) != COSLAM_OK) {
        if (msg != NULL && msg_cap > 0U) {
            (void)snprintf(msg, msg_cap, "not a finite number: '%s'", text);
        }
        return COSLAM_E_NUMERIC;
    }
    const int below = k->min_open ? !(v > k->min) : !(v >= k->min);
    if (below || !(v <= k->max)) {
        if (msg != NULL && msg_cap > 0U) {
            (void)snprintf(msg, msg_cap, "%s is outside its domain %s%g, %g%s", text,
                           k->min_open || isinf(k->min) ? "(" : "[", k->min, k->max, isinf(k->max) ? ")" : "]");
        }
        return COSLAM_E_ARG;
    }
    uint8_t *base = (uint8_t *)p;
    if (k->type == SLAM_PARAMS_INI_FLOAT) {
        const float f = (float)v;
        memcpy(base + k->offset, &f, sizeof f);
    } else {
        memcpy(base + k->offset, &v, sizeof v);
    }
    return COSLAM_OK;
}

double slam_params_ini_get(const slam_params_t *p, const slam_params_ini_key_t *k)
{
    const uint8_t *base = (const uint8_t *)p;
    if (k->type == SLAM_PARAMS_INI_FLOAT) {
        float f;
        memcpy(&f, base + k->offset, sizeof f);
        return (double)f;
    }
    double d;
    memcpy(&d, base + k->offset, sizeof d);
    return d;
}

coslam_status_t slam_params_ini_cross_check(const slam_params_t *p, const slam_params_ini_key_t **key,
                                            const slam_params_ini_key_t **other, char *msg, size_t msg_cap)
{
    const char *bad = NULL;
    const char *with = NULL;
    const char *rule = NULL;
    if (!(p->sensor_max_range_m > p->sensor_min_range_m)) {
        bad = "sensor_max_range_m";
        with = "sensor_min_range_m";
        rule = "sensor_max_range_m must be greater than sensor_min_range_m";
    } else if (!(p->new_landmark_chi2 >= p->gate_chi2)) {
        bad = "new_landmark_chi2";
        with = "gate_chi2";
        rule = "new_landmark_chi2 must be at least gate_chi2";
    } else if (!(p->exist_confirm >= p->exist_init)) {
        bad = "exist_confirm";
        with = "exist_init";
        rule = "exist_confirm must be at least exist_init";
    } else if (!(p->exist_max >= p->exist_confirm)) {
        bad = "exist_max";
        with = "exist_confirm";
        rule = "exist_max must be at least exist_confirm";
    } else if (!(p->sighting_max_range_m > p->sensor_min_range_m)) {
        bad = "sighting_max_range_m";
        with = "sensor_min_range_m";
        rule = "sighting_max_range_m must be greater than sensor_min_range_m";
    }
    if (key != NULL) {
        *key = bad != NULL ? slam_params_ini_find(bad) : NULL;
    }
    if (other != NULL) {
        *other = with != NULL ? slam_params_ini_find(with) : NULL;
    }
    if (msg != NULL && msg_cap > 0U) {
        (void)snprintf(msg, msg_cap, "%s", rule != NULL ? rule : "");
    }
    return bad != NULL ? COSLAM_E_ARG : COSLAM_OK;
}
