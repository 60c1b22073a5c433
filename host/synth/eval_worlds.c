#include "eval_worlds.h"

#include "mrclam_model.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

synth_config_t eval_world_config(eval_world_t world, uint64_t seed)
{
    synth_config_t sc;
    if (world == EVAL_WORLD_PAPER) {
        sc = synth_config_default(seed, 64);
        sc.loop_radius_m = 2.5;
        sc.ring_half_width_m = 2.0;
    } else if (world == EVAL_WORLD_LARGE) {
        return eval_world_large_config(seed, 1024);
    } else if (world == EVAL_WORLD_ARENA) {
        return eval_world_arena_config(seed);
    } else {
        sc = synth_config_default(seed, 160);
        sc.loop_radius_m = 8.0;
        sc.ring_half_width_m = 1.5;
        sc.loops = 1.15;
    }
    sc.n_signatures = 4;
    return sc;
}

synth_config_t eval_world_large_config(uint64_t seed, int n_landmarks)
{
    /* a ring 5 m wide at 2 landmarks per m^2 (about 20 sightings per
     * frame), its radius from the count: 1,024 landmarks, 16.3 m */
    synth_config_t sc = synth_config_default(seed, n_landmarks);
    sc.ring_half_width_m = 2.5;
    sc.loop_radius_m = (double)n_landmarks / (2.0 * COSLAM_TWO_PI * 2.0 * sc.ring_half_width_m);
    sc.loops = 1.1;
    sc.n_signatures = 4;
    return sc;
}

synth_config_t eval_world_arena_config(uint64_t seed)
{
    /* MRCLAM as docs/replay.md measured it: 15 landmarks in 6 clusters
     * (0.17-0.28 m apart inside one, 1.5 m or more between), about a third
     * of the landmarks in view detected, sighting noise 4.25 % of range and
     * 0.65 deg, odometry heading variance 0.0022 rad^2/m + 0.0124 rad^2 per
     * rad turned and position 0.0052 m^2/m (the motion model's travel
     * s = d + b |dtheta| with b = 0.0124 / 0.0022 = 5.6 m carries the
     * turn term). The filter is given coslam-replay's MRCLAM model instead
     * (mrclam_slam_params), as on the real data. */
    synth_config_t sc = synth_config_default(seed, 15);
    sc.n_signatures = 1;
    sc.arena_half_x_m = 3.0;
    sc.arena_half_y_m = 5.5;
    sc.arena_clusters = 6;
    sc.cluster_radius_m = 0.3;
    sc.min_separation_m = 0.17;
    sc.wander_s = 600.0;
    sc.speed_mps = 0.15;
    sc.turn_radps = 0.5;
    sc.p_detect = 0.33;
    slam_params_t *t = &sc.truth;
    t->noise.range_var_m2 = 0.0001;
    t->noise.range_var_per_m2 = 0.0425 * 0.0425;
    t->noise.bearing_var_rad2 = 0.0113 * 0.0113;
    t->noise.odo_xy_var_m2_per_m = 0.0052 / 5.6;
    t->noise.odo_theta_var_rad2_per_m = 0.0022;
    t->base_radius_m = 5.6;
    t->sensor_min_range_m = 1.0;
    t->sensor_max_range_m = 6.0;
    t->sensor_fov_rad = 0.8;
    return sc;
}

int eval_world_parse(const char *name, eval_world_t *out)
{
    if (!strcmp(name, "paper")) {
        *out = EVAL_WORLD_PAPER;
    } else if (!strcmp(name, "loop")) {
        *out = EVAL_WORLD_LOOP;
    } else if (!strcmp(name, "large")) {
        *out = EVAL_WORLD_LARGE;
    } else if (!strcmp(name, "arena")) {
        *out = EVAL_WORLD_ARENA;
    } else {
        return -1;
    }
    return 0;
}

int eval_filter_parse(const char *name, run_filter_t *out)
{
    if (!strcmp(name, "ekf")) {
        *out = RUN_EKFSLAM;
    } else if (!strcmp(name, "fs1")) {
        *out = RUN_FASTSLAM1;
    } else if (!strcmp(name, "fs2")) {
        *out = RUN_FASTSLAM2;
    } else {
        return -1;
    }
    return 0;
}

int eval_world_run(eval_world_t world, run_filter_t filter, int n_particles, uint64_t seed, run_result_t *r)
{
    return eval_world_run_ekf_radius(world, filter, n_particles, seed, -1.0, r);
}

int eval_world_run_ekf_radius(eval_world_t world, run_filter_t filter, int n_particles, uint64_t seed,
                              double ekf_active_radius_m, run_result_t *r)
{
    const synth_config_t sc = eval_world_config(world, seed);
    const run_opts_t o = eval_world_opts(world, filter, n_particles, seed, ekf_active_radius_m);
    return run_synth(&sc, &o, r);
}

run_opts_t eval_world_opts(eval_world_t world, run_filter_t filter, int n_particles, uint64_t seed,
                           double ekf_active_radius_m)
{
    run_opts_t o = run_opts_default(filter);
    o.ekf_active_radius_m = ekf_active_radius_m;
    o.params = world == EVAL_WORLD_ARENA ? mrclam_slam_params() : eval_world_config(world, seed).truth;
    o.n_particles = n_particles;
    o.filter_seed = 7919U * seed + 17U;
    o.score_rigid_fit = world == EVAL_WORLD_ARENA;
    return o;
}

int eval_closed(const run_result_t *r)
{
    return r->final_pos_err_m < 0.5 && r->map.n_spurious <= 0.02 * r->map.n_estimated;
}

void eval_summary_init(eval_summary_t *s) { memset(s, 0, sizeof *s); }

void eval_summary_add(eval_summary_t *s, const run_result_t *r)
{
    if (s->n < (int)(sizeof s->nees / sizeof s->nees[0])) {
        s->nees[s->n] = r->map.nees_mean;
    }
    s->n++;
    s->closed += eval_closed(r);
    s->estimated += r->map.n_estimated;
    s->spurious += r->map.n_spurious;
    s->pose_rmse_sum += r->pose_rmse_m;
    s->nees_sum += r->map.nees_mean;
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a;
    const double y = *(const double *)b;
    return (x > y) - (x < y);
}

double eval_summary_median_nees(const eval_summary_t *s)
{
    const int n = s->n < 1000 ? s->n : 1000;
    if (n == 0) {
        return NAN;
    }
    double v[1000];
    memcpy(v, s->nees, sizeof(double) * (size_t)n);
    qsort(v, (size_t)n, sizeof v[0], cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}
