#include "eval_worlds.h"

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

int eval_world_parse(const char *name, eval_world_t *out)
{
    if (!strcmp(name, "paper")) {
        *out = EVAL_WORLD_PAPER;
    } else if (!strcmp(name, "loop")) {
        *out = EVAL_WORLD_LOOP;
    } else if (!strcmp(name, "large")) {
        *out = EVAL_WORLD_LARGE;
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
    run_opts_t o = run_opts_default(filter);
    o.ekf_active_radius_m = ekf_active_radius_m;
    o.params = sc.truth;
    o.n_particles = n_particles;
    o.filter_seed = 7919U * seed + 17U;
    return run_synth(&sc, &o, r);
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
