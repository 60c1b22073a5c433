/*
 * app/slam_filter.h - one robot's SLAM filter, chosen at start-up: Fast-SLAM
 * 1.0, Fast-SLAM 2.0 or EKF-SLAM from the core, behind one set of calls
 * (predict, update, pose, export, merge). The robot app and the meeting
 * protocol never look at which one runs: the map estimate they exchange is
 * the common format (coslam/map_estimate.h), as in the paper, where two
 * robots may run different filters.
 *
 * Memory: the filters share storage (a union), so sizeof(slam_filter_t) is
 * the larger of fastslam_t and ekfslam_t (about 390 KB and 140 KB in the
 * default profile). Caller-owned, no heap. One thread at a time.
 * Time: as the wrapped core function (see fastslam.h, ekfslam.h, map_merge.h).
 */
#ifndef COSLAM_APP_SLAM_FILTER_H
#define COSLAM_APP_SLAM_FILTER_H

#include <stdint.h>

#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"
#include "coslam/map_estimate.h"
#include "coslam/map_merge.h"
#include "coslam/motion.h"
#include "coslam/observe.h"
#include "coslam/occ_grid.h"
#include "coslam/slam_params.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    SLAM_FILTER_FASTSLAM1 = 1, /**< Fast-SLAM 1.0 (motion proposal) */
    SLAM_FILTER_FASTSLAM2 = 2, /**< Fast-SLAM 2.0 (improved proposal) */
    SLAM_FILTER_EKF = 3,       /**< EKF-SLAM (JCBB association, FEJ) */
} slam_filter_kind_t;

typedef struct {
    slam_filter_kind_t kind;
    slam_params_t slam;      /**< noise model (the paper's w1..w8) and gates */
    uint16_t n_particles;    /**< Fast-SLAM only: 1 .. COSLAM_MAX_PARTICLES */
    uint64_t seed;           /**< Fast-SLAM only: particle RNG seed */
    uint8_t robot_id;        /**< own provenance bit, < COSLAM_MAX_ROBOTS */
    double resample_ess_fraction; /**< Fast-SLAM: fastslam_config_t */
    double export_min_weight;     /**< Fast-SLAM: fastslam_config_t */
    double closure_drift_ratio;   /**< Fast-SLAM 2.0 revisits: fastslam_config_t (0: off) */
    uint16_t closure_gap;         /**< Fast-SLAM 2.0 revisits: fastslam_config_t */
    double closure_ambiguity_ll;  /**< Fast-SLAM 2.0 revisits: fastslam_config_t */
    double closure_misses_per_support;  /**< Fast-SLAM 2.0 revisits: fastslam_config_t */
    double closure_chance_max;          /**< Fast-SLAM 2.0 revisits: fastslam_config_t */
    uint16_t closure_unsupported_every; /**< Fast-SLAM 2.0 revisits: fastslam_config_t */
    ekfslam_assoc_t assoc;        /**< EKF-SLAM: ekfslam_config_t */
    uint32_t jcbb_max_nodes;      /**< EKF-SLAM: ekfslam_config_t */
    uint8_t fej;                  /**< EKF-SLAM: ekfslam_config_t */
    uint8_t iekf_max_iters;       /**< EKF-SLAM: ekfslam_config_t */
    double nis_inflate;           /**< EKF-SLAM: ekfslam_config_t (0: off) */
    uint32_t active_spread_madds; /**< EKF-SLAM: ekfslam_config_t (0: a global
                                       update's deferred part at once); its time
                                       per step depends on the CPU */
    uint32_t mh_frames;           /**< EKF-SLAM: revisits as two hypotheses,
                                       ekfslam_config_t (0: off); the second
                                       one's storage is u.ekf2.alt */
} slam_filter_config_t;

struct slam_merge_work_s;

/** A merge in parts (merge_config_t.step_units) holds Fast-SLAM's resampling
 *  back; if idle time has not finished it after this many updates (2 s at 5
 *  Hz: an overloaded robot), the next update finishes it first. */
#define SLAM_FILTER_MERGE_MAX_UPDATES 10U

/** An EKF-SLAM merge in parts runs on the state as it was when it began,
 *  so the filter's inputs in the meantime are held (slam_filter_predict,
 *  slam_filter_update) and applied in order once it is done: at most this
 *  many inputs (predictions and updates) ... */
#define SLAM_FILTER_HELD_INPUTS 128U
/** ... and this many camera frames' sightings. Beyond either, the merge is
 *  finished at once first (merges_forced). */
#define SLAM_FILTER_HELD_FRAMES 16U

/** One input held while an EKF-SLAM merge runs in parts. */
typedef struct {
    uint8_t is_update;       /**< 0: a prediction (u); 1: an update (sightings z0..z0+nz-1) */
    odo_increment_t u;
    uint16_t z0;
    uint16_t nz;
} slam_filter_held_t;

typedef struct slam_filter_s {
    slam_filter_kind_t kind;
    uint8_t robot_id;            /**< own provenance bit */
    /** Keyframes from which this robot looked (noted after every update);
     *  the merge's negative information (merge_check). */
    merge_coverage_t coverage;
    uint16_t coverage_at_fork;   /**< EKF-SLAM: keyframes before the running revisit fork
                                      (ekfslam_config_t.mh_frames); a revert drops those after */
    uint32_t thinned_at_fork;    /**< coverage.thinned then (thinned since: the keyframes stay) */
    uint32_t coverage_dropped;   /**< keyframes dropped with a hypothesis given up */
    /** The next update's view profile (slam_filter_set_view, the caller's),
     *  handed to the core just before that update; NULL: none. */
    const view_profile_t *view;
    /** A merge in parts not yet done (merge_config_t.step_units): for
     *  Fast-SLAM, its check waiting for the own export or its fusion; for
     *  EKF-SLAM, its fusion (the inputs meanwhile held). The working
     *  memory that holds it, NULL if none. */
    struct slam_merge_work_s *merge_due;
    /** What the parts of merges done after the call that began them
     *  fused, added and dropped (that call's stats hold its own part). */
    merge_stats_t merge_late;
    uint32_t merges_in_parts;    /**< merges that did not finish in the call that began them */
    uint32_t merges_late_partial; /**< of which a later part left landmarks out (capacity: the
                                      map full, merge_pair_drops) while the merge had been
                                      reported whole (its event's status COSLAM_OK) */
    uint32_t checks_waited;      /**< of which the check waited for the own export in parts */
    uint32_t merges_forced;      /**< of which finished by an update, the idle time having
                                      not sufficed for SLAM_FILTER_MERGE_MAX_UPDATES updates,
                                      or by an export that needed the filter's export table */
    uint16_t merge_due_updates;  /**< updates since the merge in parts began */
    /** The export of a map the meeting sends, in parts
     *  (slam_filter_export_send): where it goes, and how far it is. */
    map_estimate_t *send_out;
    uint8_t send_state;          /**< 0: none; 1: under way; 2: done, not taken yet */
    uint8_t send_yields;         /**< it is an observer's (slam_filter_export_observe):
                                      a send or a merge aborts it instead of finishing it */
    coslam_status_t send_status; /**< the export's status once done */
    uint32_t send_units;         /**< its budget per idle call */
    uint16_t send_updates;       /**< updates since it began */
    uint32_t sends_in_parts;     /**< exports of a sent map that did not fit the call that began them */
    uint32_t sends_forced;       /**< of which finished at once: by an update after
                                      SLAM_FILTER_MERGE_MAX_UPDATES, a merge or another export */
    uint32_t observes_in_parts;  /**< observers' exports (slam_filter_export_observe) that
                                      did not fit the call that began them */
    uint32_t observes_yielded;   /**< of which aborted or dropped for a send or a merge (the
                                      observer begins again) */
    /** EKF-SLAM: the inputs held while a merge runs in parts, in order. */
    slam_filter_held_t held[SLAM_FILTER_HELD_INPUTS];
    sighting_t held_z[SLAM_FILTER_HELD_FRAMES * COSLAM_MAX_SIGHTINGS];
    uint16_t n_held;
    uint16_t held_next;          /**< the first not applied yet (they go a few an idle call) */
    uint16_t n_held_z;
    uint16_t n_held_frames;
    uint32_t inputs_held;        /**< inputs held so far (EKF-SLAM merges in parts) */
    uint32_t held_failures;      /**< held inputs the filter refused once applied (predictions
                                      out of bounds, numeric faults; capacity not counted) */
    uint32_t holds_forced;       /**< times the held inputs' rest was applied in one call (a
                                      limit reached, an export or a merge needing the state) */
    union {
        fastslam_t fs;
        ekfslam_t ekf;
        /** EKF-SLAM with the storage of a revisit's second hypothesis
         *  (ekfslam_set_alt): `first` is `ekf`. Inside the union, so the
         *  filter is no larger where Fast-SLAM's state is (every profile:
         *  two ekfslam_t are smaller than one fastslam_t). */
        struct {
            ekfslam_t first;
            ekfslam_t alt;
        } ekf2;
    } u;
} slam_filter_t;

/** Fast-SLAM 2.0 with 100 particles (or the profile's maximum), default
 *  slam_params, seed 1, robot 0; the rest as fastslam_config_default() and
 *  ekfslam_config_default(). */
slam_filter_config_t slam_filter_config_default(void);

/** Start at pose0 (the robot's map frame is its start pose: pass the
 *  identity). Returns COSLAM_OK or COSLAM_E_ARG (NULL, unknown kind, or the
 *  filter refused the configuration). O(N) / O(1). */
coslam_status_t slam_filter_init(slam_filter_t *f, const slam_filter_config_t *cfg, pose2_t pose0);

/**
 * Start the filter from a saved map estimate: a snapshot written before a
 * restart, during which the robot did not move. slam_filter_init at
 * map->pose, the pose covariance set to map->pose_cov, then every landmark
 * placed relative to that pose with its relative covariance cov_rel
 * (map_estimate.h), on top of the core's own insertion paths:
 *   EKF-SLAM: P_rr = pose_cov; each landmark through
 *     ekfslam_add_landmark_body(R^T (m - p), cov_rel), i.e. with the
 *     cross-covariances to the pose that a sighting gives;
 *   Fast-SLAM: every particle at the pose with weight 1 and pose marginal
 *     pose_cov (to float precision: the anchors store floats); each landmark
 *     with EKF covariance R cov_rel R^T, anchored at that marginal
 *     (marginal.h), through fastslam_particle_add.
 * Identities, observation counts, provenance masks and classes are kept;
 * the landmarks start confirmed (existence exist_max, like a merged one);
 * new identities continue after the largest one. The merge coverage record
 * starts empty.
 * What slam_filter_export gives back right after: the pose, pose_cov, the
 * means, cov_rel and the bookkeeping as saved (to rounding); the map-frame
 * covariance `cov` as G pose_cov G^T + R cov_rel R^T (G the Jacobian of
 * pose (+) rel with respect to the pose). The map estimate has dropped the
 * pose-landmark correlation, so the saved `cov` cannot be rebuilt together
 * with cov_rel; the relative one is kept because association and merging
 * use it. Seeding from that export gives it again (a fixed point).
 * Returns COSLAM_OK; COSLAM_E_ARG (NULL, a configuration slam_filter_init
 * refuses, a non-finite pose, a pose covariance that is not finite,
 * symmetric and positive semi-definite (cov3_is_psd), a landmark with a
 * non-finite mean, a cov_rel that is not positive definite, or id 0):
 * the filter is then initialised at the pose with no landmark;
 * COSLAM_E_CAPACITY: more landmarks than the filter holds (counted by the
 * core), the first ones kept. O(N M) Fast-SLAM, O(M D) EKF-SLAM.
 */
coslam_status_t slam_filter_seed(slam_filter_t *f, const slam_filter_config_t *cfg, const map_estimate_t *map);

/**
 * fastslam_predict / ekfslam_predict of the odometry increment u covering
 * dt_s seconds. An increment the base cannot do in dt_s
 * (motion_is_plausible: slam_params_t max_speed_mps, max_turn_radps) is
 * refused with COSLAM_E_ARG and counted in the filter's rejected_controls;
 * the state is not touched. A non-finite one is refused by the core
 * (COSLAM_E_NUMERIC, same counter).
 */
coslam_status_t slam_filter_predict(slam_filter_t *f, odo_increment_t u, double dt_s);

/** fastslam_update / ekfslam_update with one frame's landmark sightings:
 *  slam_filter_update_prepare(f, n), then slam_filter_update_apply(f, z, n). */
coslam_status_t slam_filter_update(slam_filter_t *f, const sighting_t *z, int n);

/**
 * The first half of slam_filter_update, for a caller that reads the filter
 * between the halves (the robot's health monitor). What must finish before
 * an update of n sightings can apply is finished here: a Fast-SLAM merge
 * or send export held past SLAM_FILTER_MERGE_MAX_UPDATES (their counters
 * count updates here), or, for EKF-SLAM, whatever holds its inputs (a
 * merge or a send export in parts, held inputs still to apply) when the
 * frame would not fit behind them (then those held inputs are applied;
 * the queue may be compacted either way). So what the caller reads next is
 * the state the update applies to. Returns 1 if the frame will be held
 * instead (EKF-SLAM, nothing applied: the apply returns
 * COSLAM_E_MERGE_PENDING), 0 if it will update. Call it once per frame,
 * then the apply with the same n: an apply without it skips the
 * finishing.
 */
int slam_filter_update_prepare(slam_filter_t *f, int n);

/** The second half: the update (or the frame held). */
coslam_status_t slam_filter_update_apply(slam_filter_t *f, const sighting_t *z, int n);

/**
 * The obstacles around the robot for the next update (fastslam_set_view /
 * ekfslam_set_view; NULL: none): a landmark behind one is not counted as
 * missed. Set it just before slam_filter_update_apply and keep `v`
 * unchanged until then (the filter keeps the pointer); the update forgets
 * it. A frame held behind an EKF-SLAM merge in parts is applied later
 * without it (its misses count, as without a laser).
 */
void slam_filter_set_view(slam_filter_t *f, const view_profile_t *v);

/** Deferred work done in one idle call, in per-step shares
 *  (active_spread_madds): ekfslam_idle keeps at most two steps' worth
 *  ahead, the rest catches up a backlog of two generations. */
#define SLAM_FILTER_IDLE_SHARES 4U

/** Idle time between control steps (the rest of the step period): the
 *  compressed EKF switches regions and completes SLAM_FILTER_IDLE_SHARES
 *  shares of its deferred global update ahead of its pace (ekfslam_idle:
 *  no number changes beyond rounding, only when the work is done, so that
 *  the steps themselves do little of it); Fast-SLAM merges the next part
 *  of a merge in parts (merge_config_t.step_units), if one is due, else
 *  the next part of an export in parts. The robot, the simulator, the
 *  replay and the benches call it after each step; the robot calls it
 *  again while its period has time left and it returns 1.
 *  Returns 1 if a merge or an export in parts is still due after this
 *  call (another call would do the next part), else 0 (EKF-SLAM: always
 *  0, its deferred work keeps its own pace). */
int slam_filter_idle(slam_filter_t *f);

/** Pose estimate and covariance in the robot's map frame. */
void slam_filter_pose(const slam_filter_t *f, pose2_t *pose, cov3_t *cov);

/** The map estimate (confirmed landmarks, pose, covariances incl. cov_rel). */
coslam_status_t slam_filter_export(slam_filter_t *f, map_estimate_t *out);

/** The whole map (ekfslam_export_whole, fastslam_export_whole): what the
 *  merge check compares with, and what map files and evaluations hold. */
coslam_status_t slam_filter_export_whole(slam_filter_t *f, map_whole_t *out);

/** merge_into_fastslam / merge_into_ekfslam of an incoming map already in
 *  this robot's body frame (merge_transform_map), unchecked. Prefer
 *  slam_filter_merge_map. */
coslam_status_t slam_filter_merge(slam_filter_t *f, const merge_body_map_t *bm, const merge_config_t *cfg,
                                  merge_scratch_t *scratch, merge_stats_t *stats);

/** The filter's parameters (noise, gates): the one settings source the
 *  meeting's compensation and the merge check use. */
const slam_params_t *slam_filter_params(const slam_filter_t *f);

/** The filter's confirmed landmarks a miss would have counted for certain
 *  (landmark_miss_would_count), paired by a sighting (*pairs) or not
 *  (*misses), since it started (Fast-SLAM: summed over the particles).
 *  pairs / (pairs + misses) is the rate at which its map is found where
 *  expected: the p_d the miss weight stands for (docs/core-slam.md). */
void slam_filter_view_counts(const slam_filter_t *f, uint64_t *pairs, uint64_t *misses);

/** Caller-owned working memory of one merge (the meeting holds one; one may
 *  serve several filters). Initialise with slam_merge_work_init. */
typedef struct slam_merge_work_s {
    merge_body_map_t body;      /**< the incoming map in the own body frame */
    merge_scratch_t scratch;
    map_whole_t own;            /**< the own whole map, exported for the check */
    struct slam_filter_s *due;  /**< the filter whose merge this holds (its check
                                     or its fusion in parts), or NULL */
    uint8_t checking;           /**< due's check waits for its own export in parts */
    merge_config_t due_cfg;     /**< that merge's configuration */
    const occ_grid_t *due_grid; /**< and its occlusion grid (NULL: none) */
    /** The outcome of a merge whose check waited (slam_filter_merge_map
     *  returned COSLAM_E_MERGE_PENDING), once decided; taken by
     *  slam_merge_work_outcome. */
    uint8_t outcome_ready;
    coslam_status_t outcome;    /**< as slam_filter_merge_map would have returned */
    merge_stats_t outcome_stats; /**< its check and the fusion's first part; the
                                      transform it used stays in body (t, t_cov):
                                      no merge begins until the outcome is taken */
    /** A fusion in parts: the status its merge was reported with (the
     *  first part's), and whether a later part left something out
     *  (COSLAM_E_CAPACITY, counted in the filter's merges_late_partial). */
    coslam_status_t reported;
    uint8_t late_capacity;
} slam_merge_work_t;

/** Empty working memory (no merge held). */
void slam_merge_work_init(slam_merge_work_t *w);

/**
 * The whole merge of a received map, the one path the robot, the replay
 * and the simulator take (map_merge.h): merge_prepare (range check,
 * relative pose, compensation, sender motion, transform), the own export,
 * merge_check (refined transform, agreement, negative information against
 * this filter's coverage, occlusion by `grid` (the laser's occupancy grid
 * in the map frame; NULL: none known), echoes, ambiguity), then the fusion into the
 * filter. A refused merge (COSLAM_E_MERGE_RANGE, COSLAM_E_MERGE_DISAGREE,
 * COSLAM_E_MERGE_LOST, or any failure before the fusion) leaves the filter
 * unchanged.
 * COSLAM_E_CAPACITY: merged, some landmarks did not fit (counted).
 * *t_out / *t_cov_out (may be NULL): the transform used (sender at its
 * sighting in the own body frame now), refined by the shared landmarks,
 * and the covariance the merge used (the sightings'; see merge_check).
 * O(merge_check + fusion).
 * Fast-SLAM with cfg->step_units > 0 bounds the work of this call and of
 * each idle call to about step_units (docs/scale.md "The merge in
 * parts"): the own export for the check (fastslam_export_begin, taken at
 * the poses of this call), then the check, then the fusion
 * (merge_fastslam_run, each particle through the pose of this call).
 * What does not fit is done by slam_filter_idle after the next steps:
 *  - the fusion: this call returns the check's outcome, *stats counts its
 *    own part, f->merge_late the others;
 *  - the export: the check has not been made; this call returns
 *    COSLAM_E_MERGE_PENDING (nothing changed yet, *t_out as merge_prepare
 *    gave it) and the outcome is taken later from w
 *    (slam_merge_work_outcome), as this call would have returned it.
 * Until the export is done, Fast-SLAM holds resampling back, and
 * slam_filter_export / slam_filter_export_whole finish the check first.
 * EKF-SLAM with cfg->step_units > 0: the compressed EKF's local phase is
 * ended and completed in parts first (ekfslam_sync_run; if that does not
 * fit this call, COSLAM_E_MERGE_PENDING as for Fast-SLAM's export, the
 * outcome taken later from w), then the own export and the check, then
 * the fusion (merge_ekfslam_run) within step_units and the rest by
 * slam_filter_idle, as for Fast-SLAM's fusion. Meanwhile the
 * filter's predictions and updates are held (at most
 * SLAM_FILTER_HELD_INPUTS inputs and SLAM_FILTER_HELD_FRAMES frames;
 * beyond, the merge is finished first, merges_forced) and applied in
 * order after it, up to one update an idle call (new inputs wait behind
 * them): the outcome is the whole merge at the message's arrival followed
 * by those inputs, bit for bit (up to rounding where a local phase was
 * ended in parts). slam_filter_pose reads
 * the state of the merge under way; exports finish it first, and
 * slam_filter_export_busy says so to observers that may wait.
 * Any merge still due in f or in w is finished first (its outcome, if its
 * check waited, stays in w to be taken), so merges never overlap and w may
 * serve several filters; an outcome not yet taken is refused with
 * COSLAM_E_MERGE_BUSY (take it first).
 */
coslam_status_t slam_filter_merge_map(slam_filter_t *f, const map_estimate_t *in, const merge_geometry_t *g,
                                      const merge_config_t *cfg, const occ_grid_t *grid, slam_merge_work_t *w,
                                      merge_stats_t *stats, pose2_t *t_out, cov3_t *t_cov_out);

/**
 * The map a meeting sends (slam_filter_export's, at most
 * COSLAM_MAX_MSG_LANDMARKS) into *out. EKF-SLAM, or step_units 0: at once.
 * Fast-SLAM: the export in parts of step_units (fastslam_export_begin,
 * docs/scale.md "The export in parts"): if it is done within this call,
 * its status; else COSLAM_E_MERGE_PENDING, the rest is done by
 * slam_filter_idle, and slam_filter_export_poll says when *out holds it
 * (*out must stay valid until then; the map is the one of this call's
 * moment, every particle at the pose it had then). COSLAM_E_MERGE_BUSY:
 * the filter's export table is taken (a merge's check waits for its own
 * export, or a send export is under way): try again later. Until it is
 * done Fast-SLAM holds resampling back; a merge, another export, or an
 * update after SLAM_FILTER_MERGE_MAX_UPDATES finish it first
 * (sends_forced).
 */
coslam_status_t slam_filter_export_send(slam_filter_t *f, map_estimate_t *out, uint32_t step_units);

/** 1 while an export in parts holds the filter's export table (a merge's
 *  check waits for it, or a send's export runs): an export now
 *  (slam_filter_export, slam_filter_export_whole) would finish it at once
 *  (counted). Observers that may wait, such as the replay's map
 *  evaluations, ask this first. O(1). */
int slam_filter_export_busy(const slam_filter_t *f);

/**
 * An export for an observer (a status count, a periodic snapshot) into
 * *out, as slam_filter_export_send does it (in parts of step_units, the
 * rest in idle time), except that it yields: a send or a merge that needs
 * the export table aborts it (or drops its result not yet taken) instead
 * of finishing it (observes_yielded), and the observer begins again later.
 * So an observer never delays the robot's own work and never takes a whole
 * export's time in one step. Returns as slam_filter_export_send.
 */
coslam_status_t slam_filter_export_observe(slam_filter_t *f, map_estimate_t *out, uint32_t step_units);

/** The export in parts into *out (slam_filter_export_send or _observe):
 *  1 once done, taken once (its status into *st, may be NULL); 0 while it
 *  runs; -1 if no export into *out is under way or waiting (never begun,
 *  taken already, or an observer's that yielded). */
int slam_filter_export_poll(slam_filter_t *f, const map_estimate_t *out, coslam_status_t *st);

/** Finish now whatever merge w holds (check and fusion; slam_filter_idle
 *  would do it in parts). O(the rest of it). */
void slam_merge_work_finish(slam_merge_work_t *w);

/** The outcome of a merge whose check waited (COSLAM_E_MERGE_PENDING),
 *  once decided: 1 and the status, stats, transform and its covariance
 *  (each may be NULL) the merge path would have given, taken once; else
 *  0. */
int slam_merge_work_outcome(slam_merge_work_t *w, coslam_status_t *st, merge_stats_t *stats, pose2_t *t,
                            cov3_t *t_cov);

/** "fastslam1", "fastslam2", "ekf", or "?" (static strings). */
const char *slam_filter_kind_name(slam_filter_kind_t kind);

/** One counter of the filter that means input was lost: a capacity of the
 *  core was hit (capacity_macro names the config.h macro that sets it), or
 *  input was refused (capacity_macro NULL). */
typedef struct {
    const char *counter;         /**< the counter's name, as in metrics and status */
    const char *what;            /**< what was lost, for a console line */
    const char *capacity_macro;  /**< NULL: a refusal, not a capacity */
    long capacity;               /**< the macro's value in this build (0 for refusals) */
    uint32_t value;
} slam_filter_limit_t;

/** Number of entries slam_filter_limits can write. */
#define SLAM_FILTER_N_LIMITS 8

/**
 * The filter's loss counters (every tool reports limits from this one
 * table: coslam-replay, coslam-sim, coslam-robot): map full
 * (COSLAM_MAX_LANDMARKS), sightings over COSLAM_MAX_SIGHTINGS in a frame,
 * exported map cut (COSLAM_MAX_EXPORT_IDS), refused controls, refused
 * sightings, numeric faults, merge pairings over COSLAM_MERGE_MAX_PAIRS,
 * Fast-SLAM's landmark tree pool run out (LM_TREE_MAX_LEAVES and _NODES;
 * only if the pool was made smaller than the worst case). Writes those
 * with a non-zero value, in that order, to out (room for
 * SLAM_FILTER_N_LIMITS); returns how many. O(1).
 */
int slam_filter_limits(const slam_filter_t *f, slam_filter_limit_t out[SLAM_FILTER_N_LIMITS]);

/**
 * One console line for a limit, the same in every tool:
 *   "LIMIT robot 1: 3064 sightings not mapped: the map is full
 *    (lm_capacity_drops; COSLAM_MAX_LANDMARKS = 256 in this build, profile
 *    large; raise it with -DCOSLAM_MAX_LANDMARKS=N at build time)"
 * or, for a refusal, "warning: robot 1: 2 odometry increments refused (...)
 * (rejected_controls)". No newline. snprintf's return (the length it
 * needed); the line is cut at cap - 1.
 */
int slam_filter_limit_format(const slam_filter_limit_t *l, unsigned robot_id, char *buf, size_t cap);

/**
 * What a merge did and left out, the same in the robot and the simulator:
 *   "5 fused, 9 added; not added: 0 where it looked and saw nothing, 0
 *    echoes, 0 ambiguous, 0 too uncertain to refute"
 * (", 2 by CI" after "added" when covariance intersection fused any).
 * `per`: the filter's particles for Fast-SLAM, 1 for EKF-SLAM; 0 is taken
 * as 1. Fast-SLAM fuses and adds in every particle and merge_stats_t holds
 * the sums: with per > 1 the fused, added, CI and lost counts are the mean
 * per particle to 0.1, "7.0 fused, 9.0 added (per particle, mean of 100);
 * not added: ...", fused and added rounded so that they add up to their
 * total's rounded mean; the check's refusals are per landmark as counted.
 * No newline; snprintf's return, cut at cap - 1 as slam_filter_limit_format.
 */
int slam_filter_merge_format(const merge_stats_t *s, uint32_t per, char *buf, size_t cap);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_APP_SLAM_FILTER_H */
