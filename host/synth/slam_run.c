#define _POSIX_C_SOURCE 199309L
#include "slam_run.h"

#include "app/slam_filter.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

run_opts_t run_opts_default(run_filter_t filter)
{
    run_opts_t o;
    memset(&o, 0, sizeof o);
    o.filter = filter;
    o.n_particles = COSLAM_MAX_PARTICLES < 100 ? COSLAM_MAX_PARTICLES : 100;
    o.params = slam_params_default();
    o.filter_seed = 12345U;
    o.gate_m = 1.0;
    o.min_seen = 5;
    o.ekf_active_radius_m = -1.0;
    o.ekf_mh_frames = -1;
    return o;
}

static double now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

static int size_bin(int n_lm)
{
    int k = 0;
    while (k + 1 < RUN_SIZE_BINS && (double)n_lm >= 1.41421356237 * (double)(1 << k)) {
        ++k;
    }
    return k;
}

void run_trace_free(run_trace_t *trace)
{
    free(trace->t);
    free(trace->est);
    free(trace->truth);
    free(trace->map_t);
    free(trace->map_rmse_m);
    free(trace->map_matched);
    free(trace->map_spurious);
    memset(trace, 0, sizeof *trace);
}

int run_synth(const synth_config_t *scfg, const run_opts_t *opts, run_result_t *res)
{
    return run_synth_traced(scfg, opts, res, NULL);
}

int run_synth_traced(const synth_config_t *scfg, const run_opts_t *opts, run_result_t *res, run_trace_t *trace)
{
    memset(res, 0, sizeof *res);
    synth_world_t *w = malloc(sizeof *w);
    synth_step_t *st = malloc(sizeof *st);
    fastslam_t *fs = NULL;
    ekfslam_t *ekf = NULL;
    ekfslam_t *ekf_alt = NULL; /* a revisit's second hypothesis (ekfslam_set_alt) */
    map_estimate_t *map_est = NULL; /* map checkpoints of the trace (large: heap) */
    map_eval_t *map_ev = NULL;
    if (w == NULL || st == NULL) {
        free(w);
        free(st);
        return -1;
    }
    synth_init(w, scfg);
    if (trace != NULL) {
        memset(trace, 0, sizeof *trace);
        trace->t = malloc(sizeof(double) * (size_t)w->n_steps);
        trace->est = malloc(sizeof(pose2_t) * (size_t)w->n_steps);
        trace->truth = malloc(sizeof(pose2_t) * (size_t)w->n_steps);
        if (opts->trace_map_every > 0) {
            const size_t n_map = (size_t)(w->n_steps / opts->trace_map_every + 1);
            trace->map_t = malloc(sizeof(double) * n_map);
            trace->map_rmse_m = malloc(sizeof(double) * n_map);
            trace->map_matched = malloc(sizeof(int) * n_map);
            trace->map_spurious = malloc(sizeof(int) * n_map);
            map_est = malloc(sizeof *map_est);
            map_ev = malloc(sizeof *map_ev);
        }
    }
    const pose2_t start = synth_start_pose(scfg);
    if (opts->filter == RUN_EKFSLAM) {
        ekf = malloc(sizeof *ekf);
        ekf_alt = malloc(sizeof *ekf_alt);
        ekfslam_config_t c = ekfslam_config_default();
        c.slam = opts->params;
        if (opts->ekf_active_radius_m >= 0.0) {
            c.active_radius_m = opts->ekf_active_radius_m;
        }
        if (opts->ekf_mh_frames >= 0) {
            c.mh_frames = (uint32_t)opts->ekf_mh_frames;
        }
        if (ekf == NULL || ekf_alt == NULL || ekfslam_init(ekf, &c, start) != COSLAM_OK) {
            free(ekf);
            free(ekf_alt);
            free(map_est);
            free(map_ev);
            free(w);
            free(st);
            return -1;
        }
        ekfslam_set_alt(ekf, ekf_alt);
    } else {
        fs = malloc(sizeof *fs);
        fastslam_config_t c = fastslam_config_default();
        c.slam = opts->params;
        c.n_particles = (uint16_t)opts->n_particles;
        if (opts->ess_fraction > 0.0) {
            c.resample_ess_fraction = opts->ess_fraction;
        }
        c.proposal = opts->filter == RUN_FASTSLAM2 ? FASTSLAM_PROPOSAL_OPTIMAL : FASTSLAM_PROPOSAL_MOTION;
        if (fs == NULL || fastslam_init(fs, &c, start, opts->filter_seed) != COSLAM_OK) {
            free(fs);
            free(map_est);
            free(map_ev);
            free(w);
            free(st);
            return -1;
        }
    }
    /* the estimated path, kept for the pose error after the map's rigid fit */
    const int keep_path = opts->score_rigid_fit != 0;
    point2_t *path_est = keep_path ? malloc(sizeof(point2_t) * (size_t)w->n_steps) : NULL;
    point2_t *path_truth = keep_path ? malloc(sizeof(point2_t) * (size_t)w->n_steps) : NULL;
    int n_path = 0;
    pose2_t odo = start;
    double se = 0.0;
    double se_h = 0.0;
    double se_odo = 0.0;
    double nees_sum = 0.0;
    double t_sum = 0.0;
    double idle_sum = 0.0;
    pose2_t est = start;
    cov3_t cov = cov3_zero();
    pose2_t last_truth = start;
    const int ckpt_every = opts->nees_every > 0 ? opts->nees_every : 50;
    while (synth_next(w, st)) {
        if (opts->stop_after_steps > 0 && res->n_steps >= opts->stop_after_steps) {
            break;
        }
        const double t0 = now_us();
        coslam_status_t s1;
        coslam_status_t s2 = COSLAM_OK;
        if (ekf != NULL) {
            s1 = ekfslam_predict(ekf, st->u);
            if (st->is_frame) {
                s2 = ekfslam_update(ekf, st->z, st->n_z);
            }
        } else {
            s1 = fastslam_predict(fs, st->u);
            if (st->is_frame) {
                s2 = fastslam_update(fs, st->z, st->n_z);
                res->ess_mean += fs->last_ess / fs->cfg.n_particles;
            }
        }
        const double dt = now_us() - t0;
        if (ekf != NULL) {
            /* the rest of the robot's step period (slam_filter_idle, the
             * same budget), timed apart from the step */
            const double ti = now_us();
            ekfslam_idle(ekf, SLAM_FILTER_IDLE_SHARES);
            idle_sum += now_us() - ti;
        }
        t_sum += dt;
        const int bin = size_bin(ekf != NULL ? ekfslam_n_landmarks(ekf) : fs->particles[0].n_lm);
        res->size_bin_us[bin] += dt;
        res->size_bin_steps[bin]++;
        if (dt > res->step_us_max) {
            res->step_us_max = dt;
        }
        if (s1 == COSLAM_E_CAPACITY || s2 == COSLAM_E_CAPACITY) {
            res->capacity_errors++;
        }
        if (ekf != NULL) {
            ekfslam_pose(ekf, &est, &cov);
        } else {
            fastslam_pose_estimate(fs, &est, &cov);
        }
        odo = motion_apply(odo, st->u);
        const double ex = est.x - st->true_pose.x;
        const double ey = est.y - st->true_pose.y;
        const double eh = angle_wrap(est.theta - st->true_pose.theta);
        se += ex * ex + ey * ey;
        se_h += eh * eh;
        const double ox = odo.x - st->true_pose.x;
        const double oy = odo.y - st->true_pose.y;
        se_odo += ox * ox + oy * oy;
        if (path_est != NULL && path_truth != NULL && n_path < w->n_steps) {
            path_est[n_path] = (point2_t){est.x, est.y};
            path_truth[n_path] = (point2_t){st->true_pose.x, st->true_pose.y};
            n_path++;
        }
        if (trace != NULL && trace->n < w->n_steps) {
            trace->t[trace->n] = st->t_s;
            trace->est[trace->n] = est;
            trace->truth[trace->n] = st->true_pose;
            trace->n++;
        }
        last_truth = st->true_pose;
        res->n_steps++;
        if (trace != NULL && map_est != NULL && map_ev != NULL && trace->map_t != NULL && trace->map_rmse_m != NULL &&
            trace->map_matched != NULL && trace->map_spurious != NULL && res->n_steps % opts->trace_map_every == 0 &&
            trace->n_map <= w->n_steps / opts->trace_map_every) {
            if (ekf != NULL) {
                (void)ekfslam_export(ekf, map_est);
            } else {
                (void)fastslam_export(fs, map_est);
            }
            eval_map(map_est, w->lm, w->n_seen, w->n_lm, opts->min_seen, opts->gate_m, map_ev);
            trace->map_t[trace->n_map] = st->t_s;
            trace->map_rmse_m[trace->n_map] = map_ev->n_matched > 0 ? map_ev->rmse_m : NAN;
            trace->map_matched[trace->n_map] = map_ev->n_matched;
            trace->map_spurious[trace->n_map] = map_ev->n_spurious;
            trace->n_map++;
        }
        if (res->n_steps % ckpt_every == 0 && res->n_ckpt < RUN_MAX_CKPT) {
            res->pose_nees_ckpt[res->n_ckpt++] = nees_pose(est, cov, st->true_pose);
        }
        if (st->is_frame) {
            res->n_frames++;
            nees_sum += nees_pose(est, cov, st->true_pose);
        }
        res->final_pos_err_m = sqrt(ex * ex + ey * ey);
    }
    res->pose_nees_final = nees_pose(est, cov, last_truth);
    res->pose_nees_mean = res->n_frames > 0 ? nees_sum / res->n_frames : 0.0;
    res->pose_rmse_m = sqrt(se / res->n_steps);
    res->heading_rmse_rad = sqrt(se_h / res->n_steps);
    res->odo_rmse_m = sqrt(se_odo / res->n_steps);
    res->step_us_mean = t_sum / res->n_steps;
    res->idle_us_mean = idle_sum / res->n_steps;
    for (int k = 0; k < RUN_SIZE_BINS; ++k) {
        res->size_bin_us[k] = res->size_bin_steps[k] > 0 ? res->size_bin_us[k] / res->size_bin_steps[k] : 0.0;
    }
    map_whole_t *full = malloc(sizeof *full);
    if (ekf != NULL) {
        (void)ekfslam_export(ekf, &res->estimate);
        res->n_final_landmarks = ekf->n_lm;
        res->ekf_global_updates = ekf->ctr.cekf_global_updates;
        if (full != NULL) {
            (void)ekfslam_export_whole(ekf, full);
        }
    } else {
        (void)fastslam_export(fs, &res->estimate);
        res->n_final_landmarks = fs->particles[0].n_lm;
        if (full != NULL) {
            (void)fastslam_export_whole(fs, full);
        }
        res->resamples = fs->ctr.resamples;
        res->ess_mean /= res->n_frames > 0 ? res->n_frames : 1;
    }
    if (full != NULL) {
        eval_map_whole(full, w->lm, w->n_seen, w->n_lm, opts->min_seen, opts->gate_m, &res->map);
        pose2_t fit;
        res->has_map_fit = opts->score_rigid_fit &&
                           eval_map_rigid_whole(full, w->lm, w->n_seen, w->n_lm, opts->min_seen, opts->gate_m, &fit,
                                                &res->map_fit) == COSLAM_OK;
        if (res->has_map_fit && path_est != NULL && path_truth != NULL && n_path > 0) {
            /* the path moved with the map: the robot's error in its own map */
            double se_fit = 0.0;
            for (int k = 0; k < n_path; ++k) {
                const point2_t q = pose2_apply(fit, path_est[k]);
                se_fit += (q.x - path_truth[k].x) * (q.x - path_truth[k].x) + (q.y - path_truth[k].y) * (q.y - path_truth[k].y);
            }
            res->pose_rmse_fit_m = sqrt(se_fit / n_path);
        }
    } else {
        eval_map(&res->estimate, w->lm, w->n_seen, w->n_lm, opts->min_seen, opts->gate_m, &res->map);
    }
    free(full);
    free(path_est);
    free(path_truth);
    free(map_est);
    free(map_ev);
    free(fs);
    free(ekf);
    free(ekf_alt);
    free(w);
    free(st);
    return 0;
}
