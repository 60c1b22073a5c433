#include "synth.h"

#include <math.h>
#include <string.h>

synth_config_t synth_config_default(uint64_t seed, int n_landmarks)
{
    synth_config_t c;
    memset(&c, 0, sizeof c);
    c.seed = seed;
    c.n_landmarks = n_landmarks;
    c.n_signatures = 1;
    c.loop_radius_m = 4.0;
    c.ring_half_width_m = 3.0;
    c.min_separation_m = 0.5;
    c.loops = 1.25;
    c.speed_mps = 0.3;
    c.dt_s = 0.1;
    c.camera_every = 2;
    c.p_detect = 0.9;
    c.clutter_per_frame = 0.0;
    c.truth = slam_params_default();
    return c;
}

uint8_t synth_signature(rng_t *rng, int n_signatures, int index)
{
    if (n_signatures <= 0) {
        return (uint8_t)(index % 256);
    }
    return (uint8_t)(n_signatures > 1 ? rng_below(rng, (uint32_t)n_signatures) : 0);
}

int synth_sight_landmarks(const slam_params_t *sp, rng_t *rng, pose2_t pose, const point2_t *lm, const uint8_t *sig,
                          int n_lm, double p_detect, sighting_t *z, int32_t *true_id, int cap, int *n_seen)
{
    int n = 0;
    for (int j = 0; j < n_lm && n < cap; ++j) {
        const sighting_t zt = observe_predict(pose, lm[j]);
        if (zt.range_m < sp->sensor_min_range_m || zt.range_m > sp->sensor_max_range_m ||
            fabs(zt.bearing_rad) > 0.5 * sp->sensor_fov_rad) {
            continue;
        }
        if (rng_uniform(rng) >= p_detect) {
            continue;
        }
        const cov2_t q = observe_noise(sp, zt.range_m);
        z[n].range_m = zt.range_m + sqrt(q.xx) * rng_gauss(rng);
        z[n].bearing_rad = angle_wrap(zt.bearing_rad + sqrt(q.yy) * rng_gauss(rng));
        z[n].signature = sig[j];
        true_id[n] = j;
        n++;
        n_seen[j]++;
    }
    return n;
}

static int is_arena(const synth_config_t *cfg) { return cfg->arena_half_x_m > 0.0; }

pose2_t synth_start_pose(const synth_config_t *cfg)
{
    if (is_arena(cfg)) {
        const pose2_t centre = {0.0, 0.0, 0.0};
        return centre;
    }
    const pose2_t p = {cfg->loop_radius_m, 0.0, COSLAM_PI / 2.0};
    return p;
}

/* a uniform point of the arena, `inset` inside its edges */
static point2_t arena_point(synth_world_t *w, double inset)
{
    const double hx = fmax(w->cfg.arena_half_x_m - inset, 0.0);
    const double hy = fmax(w->cfg.arena_half_y_m - inset, 0.0);
    const point2_t p = {(2.0 * rng_uniform(&w->rng) - 1.0) * hx, (2.0 * rng_uniform(&w->rng) - 1.0) * hy};
    return p;
}

void synth_init(synth_world_t *w, const synth_config_t *cfg)
{
    memset(w, 0, sizeof *w);
    w->cfg = *cfg;
    rng_seed(&w->rng, cfg->seed);
    const int want = cfg->n_landmarks < SYNTH_MAX_LANDMARKS ? cfg->n_landmarks : SYNTH_MAX_LANDMARKS;
    const double r_in = cfg->loop_radius_m - cfg->ring_half_width_m;
    const double r_out = cfg->loop_radius_m + cfg->ring_half_width_m;
    /* relax the separation if the ring is too crowded for it */
    double sep = cfg->min_separation_m;
    double centre_sep = 1.5;
    int tries = 0;
    while (w->n_lm < want) {
        point2_t p;
        if (is_arena(cfg) && cfg->arena_clusters > 0 && w->n_lm >= cfg->arena_clusters) {
            /* a landmark of cluster n_lm mod k: uniform in the disc round the centre */
            const point2_t c = w->lm[w->n_lm % cfg->arena_clusters];
            const double rad = cfg->cluster_radius_m * sqrt(rng_uniform(&w->rng));
            const double ang = COSLAM_TWO_PI * rng_uniform(&w->rng);
            p.x = c.x + rad * cos(ang);
            p.y = c.y + rad * sin(ang);
        } else if (is_arena(cfg)) {
            p = arena_point(w, 0.0);
        } else {
            /* uniform in the ring (area-weighted radius) */
            const double u = rng_uniform(&w->rng);
            const double rad = sqrt(r_in * r_in + u * (r_out * r_out - r_in * r_in));
            const double ang = COSLAM_TWO_PI * rng_uniform(&w->rng);
            p.x = rad * cos(ang);
            p.y = rad * sin(ang);
        }
        /* cluster centres (the first landmarks) stand 1.5 m apart */
        const double sep_here = is_arena(cfg) && w->n_lm < cfg->arena_clusters ? centre_sep : sep;
        int ok = 1;
        for (int j = 0; j < w->n_lm && ok; ++j) {
            const double dx = p.x - w->lm[j].x;
            const double dy = p.y - w->lm[j].y;
            ok = dx * dx + dy * dy >= sep_here * sep_here;
        }
        if (ok) {
            w->sig[w->n_lm] = synth_signature(&w->rng, cfg->n_signatures, w->n_lm);
            w->lm[w->n_lm++] = p;
        } else if (++tries > 200000) {
            sep *= 0.9;
            centre_sep *= 0.9;
            tries = 0;
        }
    }
    w->pose = synth_start_pose(cfg);
    if (is_arena(cfg)) {
        w->waypoint = arena_point(w, 0.5);
        w->n_steps = (int)ceil(cfg->wander_s / cfg->dt_s);
        return;
    }
    const double length = cfg->loops * COSLAM_TWO_PI * cfg->loop_radius_m;
    w->n_steps = (int)ceil(length / (cfg->speed_mps * cfg->dt_s));
}

void synth_arena_place(synth_world_t *w, pose2_t start, uint64_t seed)
{
    w->pose = start;
    rng_seed(&w->rng, seed);
    w->waypoint = arena_point(w, 0.5);
}

/* arena mode: turn on the spot towards the waypoint, then drive to it */
static odo_increment_t wander_motion(synth_world_t *w)
{
    const synth_config_t *c = &w->cfg;
    double dx = w->waypoint.x - w->pose.x;
    double dy = w->waypoint.y - w->pose.y;
    if (dx * dx + dy * dy < 0.3 * 0.3) {
        w->waypoint = arena_point(w, 0.5);
        dx = w->waypoint.x - w->pose.x;
        dy = w->waypoint.y - w->pose.y;
    }
    const double e = angle_wrap(atan2(dy, dx) - w->pose.theta);
    const double w_max = c->turn_radps;
    if (fabs(e) > 0.2) {
        const double wz = fabs(e) / c->dt_s < w_max ? e / c->dt_s : copysign(w_max, e);
        return motion_from_body_velocity(0.0, 0.0, wz, c->dt_s);
    }
    const double wz = fmax(-w_max, fmin(w_max, 2.0 * e));
    return motion_from_body_velocity(c->speed_mps, 0.0, wz, c->dt_s);
}

static int poisson(rng_t *rng, double mean)
{
    if (mean <= 0.0) {
        return 0;
    }
    const double l = exp(-mean);
    int k = 0;
    double p = 1.0;
    do {
        ++k;
        p *= rng_uniform(rng);
    } while (p > l && k < 1000);
    return k - 1;
}

int synth_next(synth_world_t *w, synth_step_t *s)
{
    const synth_config_t *c = &w->cfg;
    if (w->step >= w->n_steps) {
        return 0;
    }
    /* true motion: a circular arc (or the arena's wandering); the odometry
     * reports it with noise */
    const odo_increment_t u_true =
        is_arena(c) ? wander_motion(w)
                    : motion_from_body_velocity(c->speed_mps, 0.0, c->speed_mps / c->loop_radius_m, c->dt_s);
    s->u = motion_sample(&c->truth, u_true, &w->rng);
    w->pose = motion_apply(w->pose, u_true);
    w->step++;
    s->true_pose = w->pose;
    s->t_s = w->step * c->dt_s;
    s->n_z = 0;
    s->is_frame = (w->step % c->camera_every) == 0;
    if (!s->is_frame) {
        return 1;
    }
    const slam_params_t *sp = &c->truth;
    s->n_z = synth_sight_landmarks(sp, &w->rng, w->pose, w->lm, w->sig, w->n_lm, c->p_detect, s->z, s->true_id,
                                   SYNTH_MAX_Z, w->n_seen);
    const int n_clutter = poisson(&w->rng, c->clutter_per_frame);
    for (int k = 0; k < n_clutter && s->n_z < SYNTH_MAX_Z; ++k) {
        sighting_t z;
        z.range_m = sp->sensor_min_range_m + rng_uniform(&w->rng) * (sp->sensor_max_range_m - sp->sensor_min_range_m);
        z.bearing_rad = (rng_uniform(&w->rng) - 0.5) * sp->sensor_fov_rad;
        const uint32_t n_sig = c->n_signatures <= 0 ? 256U : (uint32_t)c->n_signatures;
        z.signature = (uint8_t)rng_below(&w->rng, n_sig);
        s->z[s->n_z] = z;
        s->true_id[s->n_z] = -1;
        s->n_z++;
    }
    return 1;
}
