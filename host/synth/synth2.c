#include "synth2.h"

#include <math.h>
#include <string.h>

synth2_config_t synth2_config_default(uint64_t seed, int n_landmarks)
{
    synth2_config_t c;
    memset(&c, 0, sizeof c);
    c.seed = seed;
    c.n_landmarks = n_landmarks;
    c.n_signatures = 4;
    c.half_m = 6.0;
    c.min_separation_m = 0.5;
    c.loop_radius_m = 2.5;
    c.speed_mps = 0.3;
    c.turn_radps = 0.5;
    c.stand_s = 2.0;
    c.dt_s = 0.1;
    c.camera_every = 2;
    c.p_detect = 0.9;
    c.robot_range_sd_m = 0.05;
    c.robot_bearing_sd_rad = 0.035;
    c.truth = slam_params_default();
    c.truth.sensor_max_range_m = 3.0; /* a 320x240 camera sizing blobs: the robots map separate halves */
    return c;
}

pose2_t synth2_start_pose(int k)
{
    const pose2_t p0 = {-1.0, 0.0, COSLAM_PI};
    const pose2_t p1 = {1.0, 0.0, 0.0};
    pose2_t r = k == 0 ? p0 : p1;
    r.theta = angle_wrap(r.theta);
    return r;
}

void synth2_init(synth2_world_t *w, const synth2_config_t *cfg)
{
    memset(w, 0, sizeof *w);
    w->cfg = *cfg;
    rng_seed(&w->rng, cfg->seed);
    const int want = cfg->n_landmarks < SYNTH_MAX_LANDMARKS ? cfg->n_landmarks : SYNTH_MAX_LANDMARKS;
    double sep = cfg->min_separation_m;
    int tries = 0;
    while (w->n_lm < want) {
        const point2_t p = {(2.0 * rng_uniform(&w->rng) - 1.0) * cfg->half_m,
                            (2.0 * rng_uniform(&w->rng) - 1.0) * cfg->half_m};
        int ok = fabs(p.y) > 0.4 || fabs(p.x) > 1.5; /* keep the meeting corridor clear */
        for (int j = 0; j < w->n_lm && ok; ++j) {
            const double dx = p.x - w->lm[j].x;
            const double dy = p.y - w->lm[j].y;
            ok = dx * dx + dy * dy >= sep * sep;
        }
        if (ok) {
            w->sig[w->n_lm] = synth_signature(&w->rng, cfg->n_signatures, w->n_lm);
            w->lm[w->n_lm++] = p;
        } else if (++tries > 200000) {
            sep *= 0.9;
            tries = 0;
        }
    }
    for (int k = 0; k < 2; ++k) {
        w->pose[k] = synth2_start_pose(k);
    }
    w->loop_steps = (int)ceil(COSLAM_TWO_PI * cfg->loop_radius_m / (cfg->speed_mps * cfg->dt_s));
    w->turn_steps = (int)ceil(COSLAM_PI / (cfg->turn_radps * cfg->dt_s));
    w->stand_steps = (int)ceil(cfg->stand_s / cfg->dt_s);
}

int synth2_next(synth2_world_t *w, synth2_step_t *s)
{
    const synth2_config_t *c = &w->cfg;
    const int total = w->loop_steps + w->turn_steps + w->stand_steps;
    if (w->step >= total) {
        return 0;
    }
    odo_increment_t u_true;
    if (w->step < w->loop_steps) {
        s->phase = 0;
        /* the last loop step lands exactly on the start */
        const double ang = COSLAM_TWO_PI / w->loop_steps;
        const double v = ang * c->loop_radius_m / c->dt_s;
        u_true = motion_from_body_velocity(v, 0.0, ang / c->dt_s, c->dt_s);
    } else if (w->step < w->loop_steps + w->turn_steps) {
        s->phase = 1;
        const double ang = COSLAM_PI / w->turn_steps;
        u_true = motion_from_body_velocity(0.0, 0.0, ang / c->dt_s, c->dt_s);
    } else {
        s->phase = 2;
        u_true.dx = 0.0;
        u_true.dy = 0.0;
        u_true.dtheta = 0.0;
    }
    w->step++;
    s->t_s = w->step * c->dt_s;
    s->is_frame = (w->step % c->camera_every) == 0;
    for (int k = 0; k < 2; ++k) {
        synth2_robot_step_t *r = &s->r[k];
        r->u = motion_sample(&c->truth, u_true, &w->rng);
        w->pose[k] = motion_apply(w->pose[k], u_true);
        r->true_pose = w->pose[k];
        r->n_z = 0;
        r->sees_other = 0;
    }
    if (!s->is_frame) {
        return 1;
    }
    const slam_params_t *sp = &c->truth;
    for (int k = 0; k < 2; ++k) {
        synth2_robot_step_t *r = &s->r[k];
        r->n_z = synth_sight_landmarks(sp, &w->rng, w->pose[k], w->lm, w->sig, w->n_lm, c->p_detect, r->z, r->true_id,
                                       SYNTH_MAX_Z, w->n_seen[k]);
        const point2_t other = {w->pose[1 - k].x, w->pose[1 - k].y};
        const sighting_t zo = observe_predict(w->pose[k], other);
        if (zo.range_m <= sp->sensor_max_range_m && fabs(zo.bearing_rad) <= 0.5 * sp->sensor_fov_rad) {
            r->sees_other = 1;
            r->other.range_m = zo.range_m + c->robot_range_sd_m * rng_gauss(&w->rng);
            r->other.bearing_rad = angle_wrap(zo.bearing_rad + c->robot_bearing_sd_rad * rng_gauss(&w->rng));
            r->other.signature = 0;
        }
    }
    return 1;
}
