#include "app/slam_filter.h"

#include <stdio.h>

#include <math.h>
#include <stddef.h>
#include <string.h>

slam_filter_config_t slam_filter_config_default(void)
{
    slam_filter_config_t c;
    c.kind = SLAM_FILTER_FASTSLAM2;
    c.slam = slam_params_default();
    c.slam.exist_miss_confirmed = SLAM_EXIST_MISS_FLAT_MARKERS; /* the robot's markers are flat */
    c.n_particles = (uint16_t)(COSLAM_MAX_PARTICLES < 100 ? COSLAM_MAX_PARTICLES : 100);
    c.seed = 1U;
    c.robot_id = 0U;
    const fastslam_config_t fc = fastslam_config_default();
    const ekfslam_config_t ec = ekfslam_config_default();
    c.resample_ess_fraction = fc.resample_ess_fraction;
    c.export_min_weight = fc.export_min_weight;
    c.closure_drift_ratio = fc.closure_drift_ratio;
    c.closure_gap = fc.closure_gap;
    c.closure_ambiguity_ll = fc.closure_ambiguity_ll;
    c.closure_misses_per_support = fc.closure_misses_per_support;
    c.closure_chance_max = fc.closure_chance_max;
    c.closure_unsupported_every = fc.closure_unsupported_every;
    c.assoc = ec.assoc;
    c.jcbb_max_nodes = ec.jcbb_max_nodes;
    c.fej = ec.fej;
    c.iekf_max_iters = ec.iekf_max_iters;
    c.nis_inflate = ec.nis_inflate;
    c.active_spread_madds = ec.active_spread_madds;
    c.mh_frames = ec.mh_frames;
    return c;
}

coslam_status_t slam_filter_init(slam_filter_t *f, const slam_filter_config_t *cfg, pose2_t pose0)
{
    if (f == NULL || cfg == NULL) {
        return COSLAM_E_ARG;
    }
    f->kind = cfg->kind;
    f->robot_id = cfg->robot_id;
    merge_coverage_init(&f->coverage);
    f->coverage_at_fork = 0U;
    f->thinned_at_fork = 0U;
    f->coverage_dropped = 0U;
    f->view = NULL;
    f->merge_due = NULL;
    memset(&f->merge_late, 0, sizeof f->merge_late);
    f->merges_in_parts = 0U;
    f->merges_late_partial = 0U;
    f->merges_forced = 0U;
    f->checks_waited = 0U;
    f->merge_due_updates = 0U;
    f->send_out = NULL;
    f->send_state = 0U;
    f->send_status = COSLAM_OK;
    f->send_units = 0U;
    f->send_updates = 0U;
    f->sends_in_parts = 0U;
    f->sends_forced = 0U;
    f->send_yields = 0U;
    f->observes_in_parts = 0U;
    f->observes_yielded = 0U;
    f->n_held = 0U;
    f->held_next = 0U;
    f->n_held_z = 0U;
    f->n_held_frames = 0U;
    f->inputs_held = 0U;
    f->held_failures = 0U;
    f->holds_forced = 0U;
    switch (cfg->kind) {
    case SLAM_FILTER_FASTSLAM1:
    case SLAM_FILTER_FASTSLAM2: {
        fastslam_config_t c = fastslam_config_default();
        c.slam = cfg->slam;
        c.n_particles = cfg->n_particles;
        c.proposal = cfg->kind == SLAM_FILTER_FASTSLAM2 ? FASTSLAM_PROPOSAL_OPTIMAL : FASTSLAM_PROPOSAL_MOTION;
        c.robot_id = cfg->robot_id;
        c.resample_ess_fraction = cfg->resample_ess_fraction;
        c.export_min_weight = cfg->export_min_weight;
        c.closure_drift_ratio = cfg->closure_drift_ratio;
        c.closure_gap = cfg->closure_gap;
        c.closure_ambiguity_ll = cfg->closure_ambiguity_ll;
        c.closure_misses_per_support = cfg->closure_misses_per_support;
        c.closure_chance_max = cfg->closure_chance_max;
        c.closure_unsupported_every = cfg->closure_unsupported_every;
        return fastslam_init(&f->u.fs, &c, pose0, cfg->seed);
    }
    case SLAM_FILTER_EKF: {
        ekfslam_config_t c = ekfslam_config_default();
        c.slam = cfg->slam;
        c.robot_id = cfg->robot_id;
        c.assoc = cfg->assoc;
        c.jcbb_max_nodes = cfg->jcbb_max_nodes;
        c.fej = cfg->fej;
        c.iekf_max_iters = cfg->iekf_max_iters;
        c.nis_inflate = cfg->nis_inflate;
        c.active_spread_madds = cfg->active_spread_madds;
        c.mh_frames = cfg->mh_frames;
        const coslam_status_t st = ekfslam_init(&f->u.ekf, &c, pose0);
        if (st == COSLAM_OK) {
            ekfslam_set_alt(&f->u.ekf, &f->u.ekf2.alt);
        }
        return st;
    }
    }
    return COSLAM_E_ARG;
}

static int seed_landmark_ok(const map_landmark_t *l)
{
    return isfinite(l->mean.x) && isfinite(l->mean.y) && cov2_is_finite(l->cov_rel) && cov2_is_pd(l->cov_rel) &&
           l->id != 0U;
}

static coslam_status_t seed_ekf(ekfslam_t *ekf, const map_estimate_t *map)
{
    ekfslam_sync(ekf); /* p is written directly below */
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            ekf->p[r * EKFSLAM_DIM + c] = map->pose_cov.m[r][c];
        }
    }
    coslam_status_t result = COSLAM_OK;
    uint32_t max_id = 0U;
    for (uint16_t i = 0; i < map->n_landmarks; ++i) {
        const map_landmark_t *l = &map->lm[i];
        ekfslam_meta_t meta;
        memset(&meta, 0, sizeof meta);
        meta.id = l->id;
        meta.exist = ekf->cfg.slam.exist_max;
        meta.n_obs = l->n_obs;
        meta.src_mask = l->src_mask;
        meta.signature = l->signature;
        const coslam_status_t st =
            ekfslam_add_landmark_body(ekf, pose2_apply_inverse(map->pose, l->mean), l->cov_rel, &meta);
        if (st == COSLAM_E_CAPACITY) {
            result = st;
            break;
        }
        if (st != COSLAM_OK) {
            return COSLAM_E_ARG;
        }
        ekf->lm_confirmed_once[ekf->n_lm - 1U] = 1U;
        max_id = l->id > max_id ? l->id : max_id;
    }
    if (max_id >= ekf->next_id) {
        ekf->next_id = max_id + 1U;
    }
    return result;
}

static coslam_status_t seed_fastslam(fastslam_t *fs, const map_estimate_t *map)
{
    const double c = cos(map->pose.theta);
    const double s = sin(map->pose.theta);
    double r[2][2] = {{c, -s}, {s, c}}; /* body -> map */
    /* the anchors hold floats: the pose marginal is rounded the same way, so
     * that no drift since the anchor appears (marginal_relative_drift) */
    landmark_t probe;
    memset(&probe, 0, sizeof probe);
    landmark_set_anchor(&probe, &map->pose_cov, (point2_t){map->pose.x, map->pose.y});
    const cov3_t marg = landmark_anchor(&probe);
    for (uint16_t k = 0; k < fs->cfg.n_particles; ++k) {
        fastslam_particle_t *p = &fs->particles[k];
        p->pose = map->pose;
        p->pending_cov = cov3_zero();
        p->pose_marg = marg;
        p->log_w = 0.0;
        fastslam_particle_clear(fs, k);
    }
    coslam_status_t result = COSLAM_OK;
    uint32_t max_id = 0U;
    for (uint16_t i = 0; i < map->n_landmarks; ++i) {
        const map_landmark_t *l = &map->lm[i];
        landmark_t lm = probe;
        lm.mean = l->mean;
        lm.cov = cov2_congruence(r, l->cov_rel);
        lm.id = l->id;
        lm.exist = fs->cfg.slam.exist_max;
        lm.n_obs = l->n_obs;
        lm.src_mask = l->src_mask;
        lm.signature = l->signature;
        lm.confirmed_once = 1U;
        int full = 0;
        for (uint16_t k = 0; k < fs->cfg.n_particles; ++k) {
            if (fastslam_particle_add(fs, k, &lm) != COSLAM_OK) {
                full = 1;
            }
        }
        if (full) {
            result = COSLAM_E_CAPACITY;
            break;
        }
        max_id = l->id > max_id ? l->id : max_id;
    }
    if (max_id >= fs->next_id) {
        fs->next_id = max_id + 1U;
    }
    return result;
}

coslam_status_t slam_filter_seed(slam_filter_t *f, const slam_filter_config_t *cfg, const map_estimate_t *map)
{
    if (f == NULL || cfg == NULL || map == NULL || !pose2_is_finite(map->pose)) {
        return COSLAM_E_ARG;
    }
    coslam_status_t st = slam_filter_init(f, cfg, map->pose);
    if (st != COSLAM_OK) {
        return st;
    }
    if (!cov3_is_finite(map->pose_cov) || !cov3_is_psd(map->pose_cov) || map->n_landmarks > COSLAM_MAX_MSG_LANDMARKS) {
        return COSLAM_E_ARG;
    }
    for (uint16_t i = 0; i < map->n_landmarks; ++i) {
        if (!seed_landmark_ok(&map->lm[i])) {
            return COSLAM_E_ARG;
        }
    }
    st = f->kind == SLAM_FILTER_EKF ? seed_ekf(&f->u.ekf, map) : seed_fastslam(&f->u.fs, map);
    if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
        (void)slam_filter_init(f, cfg, map->pose);
    }
    return st;
}

static void merge_due_run(slam_merge_work_t *w, uint32_t budget);

/* the second hypothesis of EKF-SLAM's revisits costs no memory: it fits in
 * the union beside Fast-SLAM's state in every profile */
_Static_assert(sizeof(((slam_filter_t *)0)->u.ekf2) <= sizeof(fastslam_t),
               "two EKF-SLAM states must fit where one Fast-SLAM state does");
_Static_assert(SLAM_FILTER_HELD_FRAMES * COSLAM_MAX_SIGHTINGS <= UINT16_MAX && SLAM_FILTER_HELD_INPUTS <= UINT16_MAX,
               "held sightings and inputs are indexed by uint16_t");

/* ---- EKF-SLAM: the inputs held while a merge runs in parts ---------------
 *
 * An EKF-SLAM merge in parts (merge_ekfslam_run) runs on the state as it
 * was when the message arrived; the filter cannot predict or update in
 * between (ekfslam_predict refuses). So its inputs are held, in order,
 * and applied once the merge is done: the state is then the whole merge
 * at the arrival followed by those inputs, bit for bit. */

/* An EKF-SLAM merge runs in parts, or an export in parts completes the
 * compressed EKF's phase (send_state 1), or inputs they held are still to
 * apply (a few an idle call after them, ekf_apply_held_part): new inputs
 * wait behind them. */
static int ekf_holding(const slam_filter_t *f)
{
    return f->kind == SLAM_FILTER_EKF && (f->merge_due != NULL || f->send_state == 1U || f->held_next < f->n_held);
}

static coslam_status_t ekf_update_now(slam_filter_t *f, const sighting_t *z, int n)
{
    const uint32_t forks = f->u.ekf.ctr.mh_forks;
    const uint32_t reverted = f->u.ekf.ctr.mh_reverted;
    const coslam_status_t st = ekfslam_update(&f->u.ekf, z, n);
    if (f->u.ekf.ctr.mh_forks != forks) {
        f->coverage_at_fork = f->coverage.n; /* the keyframes below were looked from where both agree */
        f->thinned_at_fork = f->coverage.thinned;
    }
    if (f->u.ekf.ctr.mh_reverted != reverted && f->coverage.thinned == f->thinned_at_fork &&
        f->coverage_at_fork <= f->coverage.n) {
        /* the keyframes noted since the fork are poses of the hypothesis
         * given up: where the robot did not look from */
        f->coverage_dropped += (uint32_t)(f->coverage.n - f->coverage_at_fork);
        f->coverage.n = f->coverage_at_fork;
    }
    pose2_t pose;
    cov3_t cov;
    ekfslam_pose(&f->u.ekf, &pose, &cov); /* the filter's own: held predictions are not yet in it */
    merge_coverage_note(&f->coverage, pose);
    return st;
}

/* Apply held inputs in order (the merge is done): all of them, or with
 * `one_update` those up to and including the next update (an idle call's
 * share: an update at a thousand landmarks is a few ms). */
static void ekf_apply_held_part(slam_filter_t *f, int one_update)
{
    while (f->held_next < f->n_held) {
        const slam_filter_held_t *h = &f->held[f->held_next++];
        const coslam_status_t st = h->is_update ? ekf_update_now(f, &f->held_z[h->z0], (int)h->nz)
                                                : ekfslam_predict(&f->u.ekf, h->u);
        if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
            f->held_failures++;
        }
        if (one_update && h->is_update) {
            break;
        }
    }
    if (f->held_next == f->n_held) {
        f->n_held = 0U;
        f->held_next = 0U;
        f->n_held_z = 0U;
        f->n_held_frames = 0U;
    }
}

/* Drop the held inputs already applied from the front of the queue (they
 * go one update an idle call, and new ones arrive meanwhile). */
static void ekf_held_compact(slam_filter_t *f)
{
    if (f->held_next == 0U) {
        return;
    }
    const uint16_t n = (uint16_t)(f->n_held - f->held_next);
    const uint16_t z0 = n > 0U ? f->held[f->held_next].z0 : f->n_held_z;
    uint16_t frames = 0U;
    for (uint16_t k = 0; k < n; ++k) {
        f->held[k] = f->held[f->held_next + k];
        f->held[k].z0 = (uint16_t)(f->held[k].z0 - z0);
        frames = (uint16_t)(frames + f->held[k].is_update);
    }
    memmove(f->held_z, &f->held_z[z0], (size_t)(f->n_held_z - z0) * sizeof f->held_z[0]);
    f->n_held = n;
    f->held_next = 0U;
    f->n_held_z = (uint16_t)(f->n_held_z - z0);
    f->n_held_frames = frames;
}

/* The queue has room for one more input (an update with n sightings). */
static int ekf_hold_fits(const slam_filter_t *f, int is_update, int n)
{
    if (f->n_held >= SLAM_FILTER_HELD_INPUTS) {
        return 0;
    }
    return !is_update || (f->n_held_frames < SLAM_FILTER_HELD_FRAMES && n >= 0 &&
                          (size_t)f->n_held_z + (size_t)n <= sizeof f->held_z / sizeof f->held_z[0]);
}

/* The queue has room for one more input once the applied ones are dropped. */
static int ekf_hold_room(slam_filter_t *f, int is_update, int n)
{
    if (ekf_hold_fits(f, is_update, n)) {
        return 1;
    }
    ekf_held_compact(f);
    return ekf_hold_fits(f, is_update, n);
}

/* Hold one input while the merge runs; 0 if it does not fit (the caller
 * finishes the merge first). */
static int ekf_hold(slam_filter_t *f, int is_update, odo_increment_t u, const sighting_t *z, int n)
{
    if (!ekf_hold_room(f, is_update, n)) {
        return 0;
    }
    slam_filter_held_t *h = &f->held[f->n_held];
    h->is_update = (uint8_t)is_update;
    h->u = u;
    h->z0 = f->n_held_z;
    h->nz = 0U;
    if (is_update) {
        for (int i = 0; i < n; ++i) {
            f->held_z[f->n_held_z + i] = z[i];
        }
        h->nz = (uint16_t)n;
        f->n_held_z = (uint16_t)(f->n_held_z + n);
        f->n_held_frames++;
    }
    f->n_held++;
    f->inputs_held++;
    return 1;
}

static void send_finish_now(slam_filter_t *f);

/* The merge or export under way finished now, and every held input applied. */
static void ekf_finish_now(slam_filter_t *f)
{
    if (f->merge_due != NULL) {
        f->merges_forced++;
        slam_merge_work_finish(f->merge_due);
    }
    send_finish_now(f);
    if (f->held_next < f->n_held) {
        f->holds_forced++; /* the held inputs' rest in this one call */
        ekf_apply_held_part(f, 0);
    }
}

coslam_status_t slam_filter_predict(slam_filter_t *f, odo_increment_t u, double dt_s)
{
    if (motion_is_finite(u) && !motion_is_plausible(slam_filter_params(f), u, dt_s)) {
        /* finite but beyond what the base can do in dt_s: refused and
         * counted with the non-finite ones, the state is not touched */
        if (f->kind == SLAM_FILTER_EKF) {
            f->u.ekf.ctr.rejected_controls++;
        } else {
            f->u.fs.ctr.rejected_controls++;
        }
        return COSLAM_E_ARG;
    }
    if (ekf_holding(f)) {
        if (ekf_hold(f, 0, u, NULL, 0)) {
            return COSLAM_E_MERGE_PENDING; /* applied once the merge is done (held_failures) */
        }
        ekf_finish_now(f);
    }
    return f->kind == SLAM_FILTER_EKF ? ekfslam_predict(&f->u.ekf, u) : fastslam_predict(&f->u.fs, u);
}

/* The next part of the send export under way (budget 0: all of it). */
static void send_run(slam_filter_t *f, uint32_t budget)
{
    if (f->kind == SLAM_FILTER_EKF) {
        /* the local phase completed in parts, then the export at once (the
         * core's: the inputs since are held) */
        if (ekfslam_sync_run(&f->u.ekf, (double)budget * MERGE_EKF_MADDS_PER_UNIT, NULL)) {
            f->send_status = ekfslam_export(&f->u.ekf, f->send_out);
            f->send_state = 2U;
        }
        return;
    }
    int done = 0;
    uint32_t spent = 0U;
    const coslam_status_t st = fastslam_export_run_msg(&f->u.fs, f->send_out, budget, &done, &spent);
    if (done) {
        f->send_state = 2U;
        f->send_status = st;
    }
}

/* A send export under way is finished at once (counted): something else
 * needs the filter's export table, or the particles. */
static void send_finish_now(slam_filter_t *f)
{
    if (f->send_state == 1U) {
        if (!f->send_yields) {
            f->sends_forced++;
        }
        send_run(f, 0U);
    }
}

/* A send or a merge needs the export table: an observer's export under
 * way is aborted, one done but not taken is dropped (the observer begins
 * again); a send's under way is finished at once. */
static void export_table_for_robot(slam_filter_t *f)
{
    if (f->send_state != 0U && f->send_yields) {
        if (f->send_state == 1U && f->kind != SLAM_FILTER_EKF) {
            fastslam_export_abort(&f->u.fs); /* EKF-SLAM: the phase completed so far stays done */
        }
        f->send_state = 0U;
        f->send_out = NULL;
        f->send_yields = 0U;
        f->observes_yielded++;
        return;
    }
    send_finish_now(f);
}

int slam_filter_update_prepare(slam_filter_t *f, int n)
{
    if (ekf_holding(f)) {
        if (ekf_hold_room(f, 1, n)) {
            return 1;
        }
        ekf_finish_now(f);
        return 0;
    }
    if (f->kind == SLAM_FILTER_EKF) {
        return 0;
    }
    if (f->merge_due != NULL && ++f->merge_due_updates > SLAM_FILTER_MERGE_MAX_UPDATES) {
        f->merges_forced++;
        merge_due_run(f->merge_due, 0U);
    }
    if (f->send_state == 1U && ++f->send_updates > SLAM_FILTER_MERGE_MAX_UPDATES) {
        send_finish_now(f);
    }
    return 0;
}

void slam_filter_set_view(slam_filter_t *f, const view_profile_t *v)
{
    f->view = v != NULL && v->valid ? v : NULL;
}

coslam_status_t slam_filter_update_apply(slam_filter_t *f, const sighting_t *z, int n)
{
    if (ekf_holding(f)) {
        if (ekf_hold(f, 1, (odo_increment_t){0.0, 0.0, 0.0}, z, n)) {
            f->view = NULL; /* the held frame applies later without it */
            return COSLAM_E_MERGE_PENDING; /* applied once the merge is done (held_failures) */
        }
        ekf_finish_now(f); /* not prepared: it did not fit after all */
    }
    /* this frame's view, to the core just before its update (held frames
     * applied above went without it); the core's update forgets it */
    const view_profile_t *view = f->view;
    f->view = NULL;
    if (f->kind == SLAM_FILTER_EKF) {
        ekfslam_set_view(&f->u.ekf, view);
        return ekf_update_now(f, z, n);
    }
    fastslam_set_view(&f->u.fs, view);
    const coslam_status_t st = fastslam_update(&f->u.fs, z, n);
    pose2_t pose;
    cov3_t cov;
    slam_filter_pose(f, &pose, &cov);
    merge_coverage_note(&f->coverage, pose);
    return st;
}

coslam_status_t slam_filter_update(slam_filter_t *f, const sighting_t *z, int n)
{
    (void)slam_filter_update_prepare(f, n);
    return slam_filter_update_apply(f, z, n);
}

void slam_merge_work_init(slam_merge_work_t *w)
{
    w->due = NULL;
    w->checking = 0U;
    w->outcome_ready = 0U;
}

/* w holds no merge any more. */
static void merge_work_release(slam_merge_work_t *w)
{
    w->due->merge_due = NULL;
    w->due = NULL;
    w->checking = 0U;
}

/* Unchecked fusion of w->body into f (Fast-SLAM: in parts from the poses
 * `at`, NULL: the present ones, spending at most `budget` units, 0: all;
 * what is left stays due in w). */
static coslam_status_t merge_fuse(slam_filter_t *f, slam_merge_work_t *w, const merge_config_t *cfg,
                                  const pose2_t *at, uint32_t budget, merge_stats_t *stats)
{
    if (cfg->step_units == 0U || (f->kind == SLAM_FILTER_EKF && budget == 0U)) {
        return slam_filter_merge(f, &w->body, cfg, &w->scratch, stats);
    }
    int done = 0;
    coslam_status_t st;
    if (f->kind == SLAM_FILTER_EKF) {
        st = merge_ekfslam_begin(&f->u.ekf, &w->body, cfg, &w->scratch, stats);
        if (st != COSLAM_OK) {
            return st;
        }
        st = merge_ekfslam_run(&f->u.ekf, &w->body, &w->scratch, stats, budget, &done);
    } else {
        st = merge_fastslam_begin(&f->u.fs, &w->body, cfg, &w->scratch, at);
        if (st != COSLAM_OK) {
            return st;
        }
        uint16_t left = 0U;
        st = merge_fastslam_run(&f->u.fs, &w->body, cfg, &w->scratch, stats, budget, &left);
        done = left == 0U;
    }
    if (!done) {
        w->due = f;
        w->due_cfg = *cfg;
        w->checking = 0U;
        f->merge_due = w;
        f->merge_due_updates = 0U;
    }
    return st;
}

/* What a part's budget leaves the fusion after the export spent `spent`
 * units of it: the rest, at least 1 (one particle); 0 stays 0 (no budget). */
static uint32_t budget_left(uint32_t budget, uint32_t spent)
{
    if (budget == 0U) {
        return 0U;
    }
    return spent < budget ? budget - spent : 1U;
}

/* The check of w->body against w->own (the own export, done), then the
 * fusion from the export's poses (`at`) within `budget`. */
static coslam_status_t merge_check_fuse(slam_filter_t *f, slam_merge_work_t *w, const merge_config_t *cfg,
                                        const occ_grid_t *grid, const pose2_t *at, uint32_t budget,
                                        merge_stats_t *stats)
{
    /* unresolved pairs, landmarks too uncertain to refute and a lost
     * receiver are refused for EKF-SLAM receivers only: a Fast-SLAM
     * receiver's per-particle association resolves them, and its maps were
     * worse with each rule (on MRCLAM; the lost receiver's on the held-out
     * arena teams; merge_config_t, docs/map-merge.md) */
    merge_config_t check_cfg = *cfg;
    if (f->kind != SLAM_FILTER_EKF) {
        check_cfg.unresolved_chi2 = 0.0;
        check_cfg.refute_sd_factor = 0.0;
        check_cfg.lost_sd_factor = 0.0;
    }
    const coslam_status_t st =
        merge_check(&w->own, &f->coverage, grid, slam_filter_params(f), f->robot_id, &check_cfg, &w->body, &w->scratch, stats);
    if (st != COSLAM_OK) {
        return st;
    }
    const int check_lost = stats->check_lost > 0U;
    if (check_lost) {
        /* the check's pairing: the landmarks it left out are counted in
         * stats->check_lost, the merge goes on with the rest */
        if (f->kind == SLAM_FILTER_EKF) {
            f->u.ekf.ctr.merge_pair_drops++;
        } else {
            f->u.fs.ctr.merge_pair_drops++;
        }
    }
    const coslam_status_t fst = merge_fuse(f, w, cfg, at, budget, stats);
    return fst == COSLAM_OK && check_lost ? COSLAM_E_CAPACITY : fst;
}

/* A fusion continues in parts after the call that reported it (with
 * `reported`): its later parts' status is followed from here. */
static void merge_parts_began(slam_merge_work_t *w, coslam_status_t reported)
{
    w->reported = reported;
    w->late_capacity = 0U;
}

/* A later part of a fusion in parts returned st; once done, a merge
 * reported whole whose later parts left something out is counted. */
static void merge_late_part(slam_filter_t *f, slam_merge_work_t *w, coslam_status_t st, int done)
{
    if (st == COSLAM_E_CAPACITY) {
        w->late_capacity = 1U;
    }
    if (done && w->late_capacity && w->reported == COSLAM_OK) {
        f->merges_late_partial++;
    }
}

/* The next part of the merge that w holds (budget 0: all of it): the own
 * export, then the check and the fusion's first part (the outcome into w),
 * or the fusion's next part. */
static void merge_due_run(slam_merge_work_t *w, uint32_t budget)
{
    slam_filter_t *f = w->due;
    if (f->kind == SLAM_FILTER_EKF) {
        if (w->checking) {
            /* the compressed EKF completed first; then the check and the
             * fusion's first part, on the state of the message's arrival
             * (the inputs since are held: the export is the core's, not
             * slam_filter_export_whole's, which would apply them first) */
            double spent = 0.0;
            if (!ekfslam_sync_run(&f->u.ekf, (double)budget * MERGE_EKF_MADDS_PER_UNIT, &spent)) {
                return;
            }
            merge_work_release(w);
            const uint32_t left = budget_left(budget, (uint32_t)(spent / MERGE_EKF_MADDS_PER_UNIT));
            coslam_status_t st;
            if (!w->due_cfg.check) {
                st = merge_fuse(f, w, &w->due_cfg, NULL, left, &w->outcome_stats);
            } else {
                st = ekfslam_export_whole(&f->u.ekf, &w->own);
                if (st == COSLAM_OK || st == COSLAM_E_CAPACITY) {
                    st = merge_check_fuse(f, w, &w->due_cfg, w->due_grid, NULL, left, &w->outcome_stats);
                }
            }
            w->outcome = st;
            w->outcome_ready = 1U;
            merge_parts_began(w, st);
            return;
        }
        int done = 0;
        const coslam_status_t st = merge_ekfslam_run(&f->u.ekf, &w->body, &w->scratch, &f->merge_late, budget, &done);
        merge_late_part(f, w, st, done);
        if (done) {
            merge_work_release(w); /* its held inputs follow, from the next idle call */
        }
        return;
    }
    fastslam_t *fs = &f->u.fs;
    if (w->checking) {
        int done = 0;
        uint32_t spent = 0U;
        const coslam_status_t est = fastslam_export_run(fs, &w->own, budget, &done, &spent);
        if (!done) {
            return;
        }
        merge_work_release(w);
        merge_stats_t *stats = &w->outcome_stats;
        coslam_status_t st = est;
        if (est == COSLAM_OK || est == COSLAM_E_CAPACITY) {
            st = merge_check_fuse(f, w, &w->due_cfg, w->due_grid, fs->export_scratch.job_pose,
                                  budget_left(budget, spent), stats);
        }
        w->outcome = st;
        w->outcome_ready = 1U;
        merge_parts_began(w, st);
        return;
    }
    uint16_t left = 0U;
    const coslam_status_t st = merge_fastslam_run(fs, &w->body, &w->due_cfg, &w->scratch, &f->merge_late, budget, &left);
    merge_late_part(f, w, st, left == 0U);
    if (left == 0U) {
        merge_work_release(w);
    }
}

void slam_merge_work_finish(slam_merge_work_t *w)
{
    while (w != NULL && w->due != NULL) {
        merge_due_run(w, 0U);
    }
}

int slam_merge_work_outcome(slam_merge_work_t *w, coslam_status_t *st, merge_stats_t *stats, pose2_t *t,
                            cov3_t *t_cov)
{
    if (w == NULL || !w->outcome_ready) {
        return 0;
    }
    w->outcome_ready = 0U;
    if (st != NULL) {
        *st = w->outcome;
    }
    if (stats != NULL) {
        *stats = w->outcome_stats;
    }
    if (t != NULL) {
        *t = w->body.t;
    }
    if (t_cov != NULL) {
        *t_cov = w->body.t_cov;
    }
    return 1;
}

int slam_filter_idle(slam_filter_t *f)
{
    if (f->kind == SLAM_FILTER_EKF) {
        if (f->merge_due != NULL) {
            merge_due_run(f->merge_due, f->merge_due->due_cfg.step_units);
            return 1;
        }
        if (f->send_state == 1U) {
            send_run(f, f->send_units);
            return 1;
        }
        if (ekf_holding(f)) {
            ekf_apply_held_part(f, 1);
            return ekf_holding(f);
        }
        ekfslam_idle(&f->u.ekf, SLAM_FILTER_IDLE_SHARES);
        return 0;
    }
    if (f->merge_due != NULL) {
        merge_due_run(f->merge_due, f->merge_due->due_cfg.step_units);
    } else if (f->send_state == 1U) {
        send_run(f, f->send_units);
    }
    return f->merge_due != NULL || f->send_state == 1U;
}

/* An export in parts into *out for a send (yields 0) or an observer (1). */
static coslam_status_t export_in_parts(slam_filter_t *f, map_estimate_t *out, uint32_t step_units, uint8_t yields)
{
    if (f == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    if (!yields && f->send_yields) {
        export_table_for_robot(f); /* a send goes before an observer */
    }
    if (f->send_state != 0U || (f->merge_due != NULL && f->merge_due->checking) || ekf_holding(f)) {
        return COSLAM_E_MERGE_BUSY; /* the export table is taken, or the EKF-SLAM state by a merge */
    }
    if (step_units == 0U) {
        return slam_filter_export(f, out);
    }
    if (f->kind == SLAM_FILTER_EKF) {
        /* a local phase of the compressed EKF is completed in parts first
         * (the filter's inputs held meanwhile), the export then at once */
        if (ekfslam_sync_run(&f->u.ekf, (double)step_units * MERGE_EKF_MADDS_PER_UNIT, NULL)) {
            return slam_filter_export(f, out);
        }
    } else {
        fastslam_t *fs = &f->u.fs;
        coslam_status_t st = fastslam_export_begin(fs);
        if (st != COSLAM_OK) {
            return st;
        }
        int done = 0;
        uint32_t spent = 0U;
        st = fastslam_export_run_msg(fs, out, step_units, &done, &spent);
        if (done) {
            return st;
        }
    }
    f->send_out = out;
    f->send_state = 1U;
    f->send_yields = yields;
    f->send_units = step_units;
    f->send_updates = 0U;
    if (yields) {
        f->observes_in_parts++;
    } else {
        f->sends_in_parts++;
    }
    return COSLAM_E_MERGE_PENDING;
}

coslam_status_t slam_filter_export_send(slam_filter_t *f, map_estimate_t *out, uint32_t step_units)
{
    return export_in_parts(f, out, step_units, 0U);
}

coslam_status_t slam_filter_export_observe(slam_filter_t *f, map_estimate_t *out, uint32_t step_units)
{
    return export_in_parts(f, out, step_units, 1U);
}

int slam_filter_export_busy(const slam_filter_t *f)
{
    return f != NULL &&
           ((f->merge_due != NULL && f->merge_due->checking) || f->send_state == 1U || ekf_holding(f));
}

int slam_filter_export_poll(slam_filter_t *f, const map_estimate_t *out, coslam_status_t *st)
{
    if (f == NULL || out == NULL || f->send_state == 0U || f->send_out != out) {
        return -1;
    }
    if (f->send_state != 2U) {
        return 0;
    }
    f->send_state = 0U;
    f->send_out = NULL;
    f->send_yields = 0U;
    if (st != NULL) {
        *st = f->send_status;
    }
    return 1;
}

/* Before an export: a check waiting for the own export needs the filter's
 * export table, so it is finished first (its outcome stays in its w). */
static void export_needs_table(slam_filter_t *f)
{
    if (ekf_holding(f)) {
        ekf_finish_now(f); /* an export reads the whole state: what holds it done first */
    }
    if (f->merge_due != NULL && f->merge_due->checking) {
        f->merges_forced++;
        merge_due_run(f->merge_due, 0U);
    }
    send_finish_now(f);
}

void slam_filter_pose(const slam_filter_t *f, pose2_t *pose, cov3_t *cov)
{
    if (f->kind == SLAM_FILTER_EKF) {
        ekfslam_pose(&f->u.ekf, pose, cov);
        /* inputs held (an EKF-SLAM merge or export in parts): the robot
         * has moved on since, by the odometry of the held predictions; its
         * readers (the occupancy grid, the behaviour) get the pose moved
         * by it (the covariance is the filter's, without its growth) */
        for (uint16_t k = f->held_next; k < f->n_held; ++k) {
            if (!f->held[k].is_update) {
                *pose = motion_apply(*pose, f->held[k].u);
            }
        }
    } else {
        fastslam_pose_estimate(&f->u.fs, pose, cov);
    }
}

coslam_status_t slam_filter_export(slam_filter_t *f, map_estimate_t *out)
{
    export_needs_table(f);
    return f->kind == SLAM_FILTER_EKF ? ekfslam_export(&f->u.ekf, out) : fastslam_export(&f->u.fs, out);
}

coslam_status_t slam_filter_export_whole(slam_filter_t *f, map_whole_t *out)
{
    export_needs_table(f);
    return f->kind == SLAM_FILTER_EKF ? ekfslam_export_whole(&f->u.ekf, out) : fastslam_export_whole(&f->u.fs, out);
}

coslam_status_t slam_filter_merge(slam_filter_t *f, const merge_body_map_t *bm, const merge_config_t *cfg,
                                  merge_scratch_t *scratch, merge_stats_t *stats)
{
    return f->kind == SLAM_FILTER_EKF ? merge_into_ekfslam(&f->u.ekf, bm, cfg, scratch, stats)
                                      : merge_into_fastslam(&f->u.fs, bm, cfg, scratch, stats);
}

const char *slam_filter_kind_name(slam_filter_kind_t kind)
{
    switch (kind) {
    case SLAM_FILTER_FASTSLAM1: return "fastslam1";
    case SLAM_FILTER_FASTSLAM2: return "fastslam2";
    case SLAM_FILTER_EKF: return "ekf";
    }
    return "?";
}

const slam_params_t *slam_filter_params(const slam_filter_t *f)
{
    return f->kind == SLAM_FILTER_EKF ? &f->u.ekf.cfg.slam : &f->u.fs.cfg.slam;
}

void slam_filter_view_counts(const slam_filter_t *f, uint64_t *pairs, uint64_t *misses)
{
    *pairs = f->kind == SLAM_FILTER_EKF ? f->u.ekf.ctr.view_pairs : f->u.fs.ctr.view_pairs;
    *misses = f->kind == SLAM_FILTER_EKF ? f->u.ekf.ctr.view_misses : f->u.fs.ctr.view_misses;
}

/* The check cannot be made in this call (Fast-SLAM: the own export in
 * parts; EKF-SLAM: the local phase completed in parts): w holds the merge
 * until the idle calls have made it, and its outcome is taken from w. */
static coslam_status_t merge_wait_for_check(slam_filter_t *f, slam_merge_work_t *w, const merge_config_t *cfg,
                                            const occ_grid_t *grid, const merge_stats_t *stats)
{
    w->outcome_stats = *stats; /* merge_prepare's; the check and the fusion add theirs */
    w->due = f;
    w->checking = 1U;
    w->due_cfg = *cfg;
    w->due_grid = grid;
    f->merge_due = w;
    f->merge_due_updates = 0U;
    f->merges_in_parts++;
    f->checks_waited++;
    return COSLAM_E_MERGE_PENDING;
}

coslam_status_t slam_filter_merge_map(slam_filter_t *f, const map_estimate_t *in, const merge_geometry_t *g,
                                      const merge_config_t *cfg, const occ_grid_t *grid, slam_merge_work_t *w,
                                      merge_stats_t *stats, pose2_t *t_out, cov3_t *t_cov_out)
{
    if (f == NULL || in == NULL || g == NULL || cfg == NULL || w == NULL || stats == NULL) {
        return COSLAM_E_ARG;
    }
    /* merges never overlap: what is due in this filter, or in w (for any
     * filter: its body map and scratch are about to be overwritten), is
     * finished first */
    if (f->merge_due != NULL) {
        slam_merge_work_finish(f->merge_due);
    }
    slam_merge_work_finish(w);
    export_table_for_robot(f); /* its export table, and the particles, are the merge's now */
    if (ekf_holding(f)) {
        ekf_finish_now(f); /* inputs held before the message go first */
    }
    if (w->outcome_ready) {
        return COSLAM_E_MERGE_BUSY; /* an outcome nobody has taken */
    }
    const slam_params_t *sp = slam_filter_params(f);
    coslam_status_t st = merge_prepare(in, g, sp, cfg, &w->body, stats);
    if (st != COSLAM_OK) {
        return st;
    }
    if (t_out != NULL) {
        *t_out = w->body.t;
    }
    if (t_cov_out != NULL) {
        *t_cov_out = w->body.t_cov;
    }
    uint32_t budget = f->kind == SLAM_FILTER_EKF || !cfg->check ? cfg->step_units : 0U;
    if (f->kind == SLAM_FILTER_EKF && budget > 0U) {
        /* EKF-SLAM in parts: a local phase of the compressed EKF is ended
         * and completed in parts first (a global update: 60 ms at 500
         * landmarks), the filter's inputs held meanwhile; the check and
         * the fusion follow in idle time, the outcome is taken from w */
        double spent = 0.0;
        if (!ekfslam_sync_run(&f->u.ekf, (double)budget * MERGE_EKF_MADDS_PER_UNIT, &spent)) {
            return merge_wait_for_check(f, w, cfg, grid, stats);
        }
        budget = budget_left(budget, (uint32_t)(spent / MERGE_EKF_MADDS_PER_UNIT));
    }
    if (!cfg->check) {
        st = merge_fuse(f, w, cfg, NULL, budget, stats);
        if (f->merge_due != NULL) {
            f->merges_in_parts++;
            merge_parts_began(w, st);
        }
        return st;
    }
    if (f->kind == SLAM_FILTER_EKF || cfg->step_units == 0U) {
        st = slam_filter_export_whole(f, &w->own);
        if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
            return st;
        }
        /* EKF-SLAM: the fusion in parts of step_units (0: at once) */
        st = merge_check_fuse(f, w, cfg, grid, NULL, budget, stats);
        if (f->merge_due != NULL) {
            f->merges_in_parts++;
            merge_parts_began(w, st);
        }
    } else {
        /* Fast-SLAM: the own export in parts of step_units, then the check
         * and the fusion, in this call as far as the budget goes */
        fastslam_t *fs = &f->u.fs;
        st = fastslam_export_begin(fs);
        if (st != COSLAM_OK) {
            return st;
        }
        int done = 0;
        uint32_t spent = 0U;
        st = fastslam_export_run(fs, &w->own, cfg->step_units, &done, &spent);
        if (!done) {
            return merge_wait_for_check(f, w, cfg, grid, stats);
        }
        if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
            return st;
        }
        st = merge_check_fuse(f, w, cfg, grid, fs->export_scratch.job_pose, budget_left(cfg->step_units, spent),
                              stats);
        if (f->merge_due != NULL) {
            f->merges_in_parts++;
            merge_parts_began(w, st);
        }
    }
    if (t_out != NULL) {
        *t_out = w->body.t; /* refined by the shared landmarks */
    }
    return st;
}

int slam_filter_limits(const slam_filter_t *f, slam_filter_limit_t out[SLAM_FILTER_N_LIMITS])
{
    if (f == NULL || out == NULL) {
        return 0;
    }
    /* both filters' counter structs name these fields alike */
#define SLAM_FILTER_LOSS_COUNTERS(v, c)                                                                                  \
    do {                                                                                                                 \
        (v)[0] = (c)->lm_capacity_drops;                                                                                 \
        (v)[1] = (c)->sighting_capacity_drops;                                                                           \
        (v)[2] = (c)->export_capacity_drops;                                                                             \
        (v)[3] = (c)->rejected_controls;                                                                                 \
        (v)[4] = (c)->rejected_sightings;                                                                                \
        (v)[5] = (c)->numeric_faults;                                                                                    \
        (v)[6] = (c)->merge_pair_drops;                                                                                  \
    } while (0)
    uint32_t v[SLAM_FILTER_N_LIMITS];
    if (f->kind == SLAM_FILTER_EKF) {
        SLAM_FILTER_LOSS_COUNTERS(v, &f->u.ekf.ctr);
        v[7] = 0U; /* no landmark tree */
    } else {
        SLAM_FILTER_LOSS_COUNTERS(v, &f->u.fs.ctr);
        v[7] = f->u.fs.ctr.tree_capacity_drops;
    }
#undef SLAM_FILTER_LOSS_COUNTERS
    static const slam_filter_limit_t table[SLAM_FILTER_N_LIMITS] = {
        {"lm_capacity_drops", "sightings not mapped: the map is full", "COSLAM_MAX_LANDMARKS", COSLAM_MAX_LANDMARKS, 0U},
        {"sighting_capacity_drops", "sightings dropped: more in one frame than fit", "COSLAM_MAX_SIGHTINGS",
         COSLAM_MAX_SIGHTINGS, 0U},
        {"export_capacity_drops",
         "landmarks left out of the exported map (a map message carries at most what fits one link datagram; "
         "Fast-SLAM's identity table is COSLAM_MAX_EXPORT_IDS)",
         "COSLAM_MAX_MSG_LANDMARKS", COSLAM_MAX_MSG_LANDMARKS, 0U},
        {"rejected_controls",
         "odometry increments refused (non-finite, or faster than max_speed_mps / max_turn_radps allow)", NULL, 0L, 0U},
        {"rejected_sightings", "sightings refused (non-finite, range beyond sighting_max_range_m, |bearing| > pi)",
         NULL, 0L, 0U},
        {"numeric_faults", "numeric faults (degenerate geometry skipped, weight collapse)", NULL, 0L, 0U},
        {"merge_pair_drops",
         "merge pairings with more candidate duplicate pairs than fit (the nearest kept; an incoming landmark that "
         "lost one was neither fused nor added)",
         "COSLAM_MERGE_MAX_PAIRS", COSLAM_MERGE_MAX_PAIRS, 0U},
        {"tree_capacity_drops",
         "Fast-SLAM landmark changes skipped: the landmark tree's pool ran out (it holds LM_TREE_MAX_LEAVES leaves "
         "and LM_TREE_MAX_NODES nodes, the worst case unless lowered)",
         "LM_TREE_MAX_LEAVES", (long)LM_TREE_MAX_LEAVES, 0U},
    };
    int n = 0;
    for (int i = 0; i < SLAM_FILTER_N_LIMITS; ++i) {
        if (v[i] > 0U) {
            out[n] = table[i];
            out[n].value = v[i];
            if (i == 0 && f->kind == SLAM_FILTER_EKF) { /* EKF-SLAM's state has its own capacity */
                out[n].capacity_macro = "COSLAM_EKF_MAX_LANDMARKS";
                out[n].capacity = COSLAM_EKF_MAX_LANDMARKS;
            }
            ++n;
        }
    }
    return n;
}

/* sum / k in tenths, rounded half up (k >= 1; sum * 10 fits in 64 bits) */
static uint64_t merge_tenths(uint64_t sum, uint32_t k)
{
    return (sum * 10U + k / 2U) / k;
}

/* a merge count: whole for EKF-SLAM (k == 1), to 0.1 for Fast-SLAM's mean
 * per particle */
static void merge_count_str(char *b, size_t cap, uint64_t tenths, uint32_t k)
{
    if (k == 1U) {
        (void)snprintf(b, cap, "%lu", (unsigned long)(tenths / 10U));
    } else {
        (void)snprintf(b, cap, "%lu.%lu", (unsigned long)(tenths / 10U), (unsigned long)(tenths % 10U));
    }
}

int slam_filter_merge_format(const merge_stats_t *s, uint32_t per, char *buf, size_t cap)
{
    if (s == NULL || buf == NULL || cap == 0U) {
        return 0;
    }
    const uint32_t k = per == 0U ? 1U : per;
    /* fused and added are rounded together: added is the rounded mean of
     * their total less the rounded fused, so the two add up (each is still
     * within 0.1 of its mean) */
    const uint64_t both = merge_tenths((uint64_t)s->fused + s->added, k);
    const uint64_t fused = merge_tenths(s->fused, k);
    char f[24], a[24];
    merge_count_str(f, sizeof f, fused, k);
    merge_count_str(a, sizeof a, both - fused, k);
    char ci[40] = "";
    if (s->fused_ci != 0U) {
        char c[24];
        merge_count_str(c, sizeof c, merge_tenths(s->fused_ci, k), k);
        (void)snprintf(ci, sizeof ci, ", %s by CI", c);
    }
    char unit[48] = "";
    if (k > 1U) {
        (void)snprintf(unit, sizeof unit, " (per particle, mean of %lu)", (unsigned long)k);
    }
    char lost[160] = "";
    if (s->check_lost != 0U || s->pair_lost != 0U) {
        /* the check's count is of landmarks, the fusion's summed over the
         * particles like fused and added */
        char l[24];
        merge_count_str(l, sizeof l, merge_tenths(s->pair_lost, k), k);
        (void)snprintf(lost, sizeof lost,
                       "; pair table full (COSLAM_MERGE_MAX_PAIRS): %lu left out by the check, %s%s by the fusion",
                       (unsigned long)s->check_lost, l, k > 1U ? " per particle" : "");
    }
    return snprintf(buf, cap,
                    "%s fused, %s added%s%s; not added: %lu where it looked and saw nothing, %lu echoes, %lu "
                    "ambiguous, %lu too uncertain to refute%s",
                    f, a, ci, unit, (unsigned long)s->vetoed, (unsigned long)s->echoes, (unsigned long)s->ambiguous,
                    (unsigned long)s->unrefutable, lost);
}

int slam_filter_limit_format(const slam_filter_limit_t *l, unsigned robot_id, char *buf, size_t cap)
{
    if (l == NULL || buf == NULL || cap == 0U) {
        return 0;
    }
    if (l->capacity_macro != NULL) {
        return snprintf(buf, cap,
                        "LIMIT robot %u: %lu %s (%s; %s = %ld in this build, profile %s; raise it with -D%s=N at "
                        "build time)",
                        robot_id, (unsigned long)l->value, l->what, l->counter, l->capacity_macro, l->capacity,
                        COSLAM_PROFILE_NAME, l->capacity_macro);
    }
    return snprintf(buf, cap, "warning: robot %u: %lu %s (%s)", robot_id, (unsigned long)l->value, l->what,
                    l->counter);
}
