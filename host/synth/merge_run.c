#define _POSIX_C_SOURCE 199309L
#include "merge_run.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

merge_run_opts_t merge_run_opts_default(run_filter_t a, run_filter_t b)
{
    merge_run_opts_t o;
    memset(&o, 0, sizeof o);
    o.filter[0] = a;
    o.filter[1] = b;
    o.n_particles = COSLAM_MAX_PARTICLES < 100 ? COSLAM_MAX_PARTICLES : 100;
    o.params = slam_params_default();
    o.merge = merge_config_default();
    o.filter_seed = 77U;
    o.gate_m = 1.0;
    o.meet_frames = 3;
    return o;
}

/* The robot app's filter wrapper (app/slam_filter.h): the synthetic
 * meetings run the robot's own merge path. */
static int filter_init(slam_filter_t **f, run_filter_t kind, const merge_run_opts_t *o, int k)
{
    const pose2_t origin = {0.0, 0.0, 0.0};
    *f = malloc(sizeof **f);
    if (*f == NULL) {
        return -1;
    }
    slam_filter_config_t c = slam_filter_config_default();
    c.kind = kind == RUN_EKFSLAM ? SLAM_FILTER_EKF : kind == RUN_FASTSLAM2 ? SLAM_FILTER_FASTSLAM2 : SLAM_FILTER_FASTSLAM1;
    c.slam = o->params;
    c.robot_id = (uint8_t)k;
    c.n_particles = (uint16_t)o->n_particles;
    c.seed = o->filter_seed + (uint64_t)k;
    return slam_filter_init(*f, &c, origin) == COSLAM_OK ? 0 : -1;
}

static void filter_step(slam_filter_t *f, const synth2_robot_step_t *r, int is_frame, double dt_s)
{
    slam_filter_predict(f, r->u, dt_s);
    if (is_frame) {
        slam_filter_update(f, r->z, r->n_z);
    }
}

static double now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

/* truth landmarks expressed in robot k's map frame (its start pose) */
static void truth_in_frame(const synth2_world_t *w, int k, point2_t *out)
{
    const pose2_t s = synth2_start_pose(k);
    for (int j = 0; j < w->n_lm; ++j) {
        out[j] = pose2_apply_inverse(s, w->lm[j]);
    }
}

int merge_run(const synth2_config_t *scfg, const merge_run_opts_t *o, merge_run_result_t *res)
{
    memset(res, 0, sizeof *res);
    synth2_world_t *w = malloc(sizeof *w);
    synth2_step_t *st = malloc(sizeof *st);
    map_estimate_t *est[2] = {malloc(sizeof(map_estimate_t)), malloc(sizeof(map_estimate_t))};
    map_estimate_t *after = malloc(sizeof(map_estimate_t));
    slam_merge_work_t *work = malloc(sizeof *work);
    point2_t *truth = malloc(sizeof(point2_t) * SYNTH_MAX_LANDMARKS);
    slam_filter_t *f[2] = {NULL, NULL};
    int rc = -1;
    if (!w || !st || !est[0] || !est[1] || !after || !work || !truth) {
        goto out;
    }
    slam_merge_work_init(work);
    synth2_init(w, scfg);
    if (filter_init(&f[0], o->filter[0], o, 0) != 0 || filter_init(&f[1], o->filter[1], o, 1) != 0) {
        goto out;
    }
    double se[2] = {0.0, 0.0};
    int n_steps = 0;
    int mutual = 0;
    int done = 0;
    while (synth2_next(w, st) && !done) {
        n_steps++;
        for (int k = 0; k < 2; ++k) {
            filter_step(f[k], &st->r[k], st->is_frame, scfg->dt_s);
            pose2_t e;
            cov3_t c;
            slam_filter_pose(f[k], &e, &c);
            const pose2_t tr = pose2_between(synth2_start_pose(k), st->r[k].true_pose);
            se[k] += (e.x - tr.x) * (e.x - tr.x) + (e.y - tr.y) * (e.y - tr.y);
        }
        if (!st->is_frame || st->phase != 2 || !st->r[0].sees_other || !st->r[1].sees_other) {
            continue;
        }
        if (++mutual < o->meet_frames) {
            continue;
        }
        /* the meeting: both export, exchange, and merge the other's map */
        for (int k = 0; k < 2; ++k) {
            slam_filter_export(f[k], est[k]);
        }
        for (int k = 0; k < 2; ++k) {
            merge_robot_result_t *rr = &res->r[k];
            const int ok = 1 - k;
            truth_in_frame(w, k, truth);
            eval_map(est[k], truth, w->n_seen[k], w->n_lm, 5, o->gate_m, &rr->before);
            const robot_sighting_t s_o = {st->r[k].other.range_m, st->r[k].other.bearing_rad,
                                          scfg->robot_range_sd_m * scfg->robot_range_sd_m,
                                          scfg->robot_bearing_sd_rad * scfg->robot_bearing_sd_rad};
            const robot_sighting_t o_s = {st->r[ok].other.range_m, st->r[ok].other.bearing_rad,
                                          scfg->robot_range_sd_m * scfg->robot_range_sd_m,
                                          scfg->robot_bearing_sd_rad * scfg->robot_bearing_sd_rad};
            /* the meeting is instantaneous: no own motion, no time between the sightings */
            merge_geometry_t g;
            memset(&g, 0, sizeof g);
            g.self_sees_other = s_o;
            g.other_sees_self = o_s;
            pose2_t pose_before;
            cov3_t pose_cov_before;
            slam_filter_pose(f[k], &pose_before, &pose_cov_before);
            pose2_t t;
            cov3_t tc;
            const double t0 = now_us();
            coslam_status_t mst = slam_filter_merge_map(f[k], est[ok], &g, &o->merge, NULL, work, &rr->stats, &t, &tc);
            if (mst == COSLAM_E_MERGE_PENDING) {
                /* the check waited for the own export in parts: decided now */
                slam_merge_work_finish(work);
                (void)slam_merge_work_outcome(work, &mst, &rr->stats, &t, &tc);
            }
            const pose2_t t_true = pose2_between(st->r[k].true_pose, st->r[ok].true_pose);
            rr->t_err_refined_m = hypot(t.x - t_true.x, t.y - t_true.y);
            rr->t_err_refined_rad = fabs(angle_wrap(t.theta - t_true.theta));
            /* the sightings' transform: the refined one less the shift */
            const pose2_t t_prior = {t.x - rr->stats.t_shift.x, t.y - rr->stats.t_shift.y,
                                angle_wrap(t.theta - rr->stats.t_shift.theta)};
            rr->t_err_m = hypot(t_prior.x - t_true.x, t_prior.y - t_true.y);
            rr->t_err_rad = fabs(angle_wrap(t_prior.theta - t_true.theta));
            rr->t_nees = nees_pose(t_prior, tc, t_true);
            rr->status = mst;
            if (mst != COSLAM_OK && mst != COSLAM_E_CAPACITY) {
                continue;
            }
            const merge_body_map_t *bm = &work->body;
            rr->merge_us = now_us() - t0;
            rr->merged = 1;
            slam_filter_export(f[k], after);
            const pose2_t true_pose_k = pose2_between(synth2_start_pose(k), st->r[k].true_pose);
            eval_map(after, truth, w->n_seen[k], w->n_lm, 5, o->gate_m, &rr->after);
            /* the other robot's estimates of the same truth, moved into this
             * robot's frame with the TRUE transform between the map frames */
            const pose2_t frames = pose2_between(synth2_start_pose(k), synth2_start_pose(ok));
            truth_in_frame(w, ok, truth); /* truth in the other's frame, for its matching */
            map_eval_t other_eval;
            eval_map(est[ok], truth, w->n_seen[ok], w->n_lm, 5, o->gate_m, &other_eval);
            truth_in_frame(w, k, truth);
            double nees_added = 0.0;
            for (int i = 0; i < after->n_landmarks; ++i) {
                const int j = rr->after.match[i];
                if (j < 0) {
                    continue;
                }
                const double nees = nees_point(after->lm[i].mean, after->lm[i].cov, truth[j]);
                /* was j in this robot's map before, and in the other's? */
                int own_before = -1;
                int other_before = -1;
                for (int q = 0; q < est[k]->n_landmarks; ++q) {
                    if (rr->before.match[q] == j) {
                        own_before = q;
                    }
                }
                for (int q = 0; q < est[ok]->n_landmarks; ++q) {
                    if (other_eval.match[q] == j) {
                        other_before = q;
                    }
                }
                if (own_before >= 0 && other_before < 0) {
                    rr->n_own_only++;
                    rr->nees_own_only_after += nees;
                    rr->nees_own_only_before +=
                        nees_point(est[k]->lm[own_before].mean, est[k]->lm[own_before].cov, truth[j]);
                } else if (own_before < 0 && other_before >= 0) {
                    nees_added += nees;
                    rr->n_added_eval++;
                } else if (own_before >= 0 && other_before >= 0) {
                    const point2_t a = est[k]->lm[own_before].mean;
                    const point2_t b = pose2_apply(frames, est[ok]->lm[other_before].mean);
                    const point2_t m = after->lm[i].mean;
                    point2_t recv = b;
                    for (int q = 0; q < bm->n; ++q) {
                        if (bm->id[q] == est[ok]->lm[other_before].id) {
                            recv = pose2_apply(pose_before, bm->mean[q]);
                        }
                    }
                    rr->se_common_received +=
                        (recv.x - truth[j].x) * (recv.x - truth[j].x) + (recv.y - truth[j].y) * (recv.y - truth[j].y);
                    const point2_t tr = pose2_apply_inverse(true_pose_k, truth[j]);
                    const point2_t rs = pose2_apply_inverse(pose_before, a);
                    const point2_t rv = pose2_apply_inverse(pose_before, recv);
                    const point2_t rm = pose2_apply_inverse(after->pose, m);
                    rr->se_rel_self += (rs.x - tr.x) * (rs.x - tr.x) + (rs.y - tr.y) * (rs.y - tr.y);
                    rr->se_rel_received += (rv.x - tr.x) * (rv.x - tr.x) + (rv.y - tr.y) * (rv.y - tr.y);
                    rr->se_rel_merged += (rm.x - tr.x) * (rm.x - tr.x) + (rm.y - tr.y) * (rm.y - tr.y);
                    rr->se_common_self += (a.x - truth[j].x) * (a.x - truth[j].x) + (a.y - truth[j].y) * (a.y - truth[j].y);
                    rr->se_common_other += (b.x - truth[j].x) * (b.x - truth[j].x) + (b.y - truth[j].y) * (b.y - truth[j].y);
                    rr->se_common_merged += (m.x - truth[j].x) * (m.x - truth[j].x) + (m.y - truth[j].y) * (m.y - truth[j].y);
                    rr->nees_common_merged += nees;
                    rr->n_common++;
                }
            }
            rr->after_nees_added = rr->n_added_eval > 0 ? nees_added / rr->n_added_eval : 0.0;
        }
        done = 1;
    }
    for (int k = 0; k < 2; ++k) {
        res->pose_rmse_m[k] = n_steps > 0 ? sqrt(se[k] / n_steps) : 0.0;
    }
    rc = 0;
out:
    for (int k = 0; k < 2; ++k) {
        free(f[k]);
        free(est[k]);
    }
    free(after);
    free(work);
    free(truth);
    free(w);
    free(st);
    return rc;
}
