/*
 * slam_run.h - drive a filter of the core through a synthetic run and
 * measure it against ground truth. Shared by the core tests and the
 * benchmark so both measure the same thing.
 */
#ifndef COSLAM_TEST_SLAM_RUN_H
#define COSLAM_TEST_SLAM_RUN_H

#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"
#include "stats.h"
#include "synth.h"

#ifdef __cplusplus
extern "C" {
#endif

#define RUN_MAX_CKPT 128
#define RUN_SIZE_BINS 16

typedef enum { RUN_FASTSLAM1 = 1, RUN_FASTSLAM2 = 2, RUN_EKFSLAM = 3 } run_filter_t;

typedef struct {
    run_filter_t filter;
    int n_particles;            /**< Fast-SLAM only */
    slam_params_t params;       /**< the filter's model (usually = the truth's) */
    uint64_t filter_seed;
    double gate_m;              /**< landmark matching gate for evaluation */
    int min_seen;               /**< a true landmark counts as missed only if seen this often */
    double ess_fraction;        /**< Fast-SLAM resampling threshold (0: default) */
    int stop_after_steps;       /**< end the run early (0: run to the end) */
    int nees_every;             /**< pose NEES checkpoint period in steps (0: 50) */
    double ekf_active_radius_m; /**< EKF-SLAM: ekfslam_config_t.active_radius_m (< 0: the default) */
    long ekf_mh_frames;         /**< EKF-SLAM: ekfslam_config_t.mh_frames (< 0: the default) */
    int score_rigid_fit;        /**< also score the final map after the best rigid fit (run_result_t.map_fit) */
    int trace_map_every;        /**< run_synth_traced: score the map every this many steps
                                     into the trace (0: never; costs an export and eval_map each) */
} run_opts_t;

typedef struct {
    int n_steps;
    int n_frames;
    double pose_rmse_m;         /**< position RMSE over all steps */
    double heading_rmse_rad;
    double final_pos_err_m;
    double odo_rmse_m;          /**< dead reckoning position RMSE on the same run */
    double pose_nees_final;     /**< NEES (3 dof) at the last step */
    double pose_nees_mean;      /**< NEES averaged over the frames */
    int n_ckpt;
    double pose_nees_ckpt[RUN_MAX_CKPT]; /**< pose NEES every nees_every steps */
    map_eval_t map;
    int has_map_fit;            /**< map_fit is set (run_opts_t.score_rigid_fit) */
    map_eval_t map_fit;         /**< the final map after the best rigid fit (eval_map_rigid_whole),
                                     as coslam-replay scores maps without robot truth */
    double pose_rmse_fit_m;     /**< position RMSE of the path moved by that fit: the robot's
                                     error in its own map, a turned map frame taken out */
    double step_us_mean;        /**< wall time per control step (predict + update) */
    double step_us_max;
    double idle_us_mean;        /**< EKF-SLAM: wall time per step of the idle call after it
                                     (ekfslam_idle, as slam_filter_idle), not in step_us_* */
    uint32_t capacity_errors;
    uint32_t resamples;         /**< Fast-SLAM resampling events */
    double ess_mean;            /**< Fast-SLAM mean ESS fraction after updates */
    map_estimate_t estimate;    /**< final exported map (what a message carries; `map` scores the whole map) */
    int n_final_landmarks;      /**< landmarks in the filter at the end (EKF-SLAM state, Fast-SLAM particle 0) */
    uint32_t ekf_global_updates; /**< EKF-SLAM: compressed EKF global updates (ctr.cekf_global_updates) */
    /** Wall time per control step by the filter's map size L at that step:
     *  bin k holds the steps with round(log2 L) = k (L within a factor
     *  sqrt 2 of 2^k; bin 0 also L = 0). */
    double size_bin_us[RUN_SIZE_BINS];
    int size_bin_steps[RUN_SIZE_BINS];
} run_result_t;


/** Per-step trajectories of a run (heap arrays, free with run_trace_free).
 *  With opts->trace_map_every > 0 also the map's error over time: every
 *  trace_map_every steps the exported map is scored against the truth as
 *  run_result_t.map is at the end (eval_map, gate_m, min_seen; landmarks
 *  seen so far), n_map entries. */
typedef struct {
    int n;
    double *t;
    pose2_t *est;
    pose2_t *truth;
    int n_map;
    double *map_t;          /**< time of the map checkpoint [s] */
    double *map_rmse_m;     /**< landmark RMSE over matched pairs (NaN: none matched) */
    int *map_matched;
    int *map_spurious;
} run_trace_t;

run_opts_t run_opts_default(run_filter_t filter);

/** Run one synthetic episode. Returns 0 on success. Allocates the filter state
 *  on the heap (this is host test code). */
int run_synth(const synth_config_t *scfg, const run_opts_t *opts, run_result_t *res);

/** As run_synth, also recording the estimated and true paths into `trace`. */
int run_synth_traced(const synth_config_t *scfg, const run_opts_t *opts, run_result_t *res, run_trace_t *trace);
void run_trace_free(run_trace_t *trace);

#ifdef __cplusplus
}
#endif

#endif
