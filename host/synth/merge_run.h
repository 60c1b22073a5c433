/*
 * merge_run.h - a two-robot synthetic meeting (synth2.h) run through the
 * robot app's filter wrapper and its merge path (slam_filter_merge_map:
 * set-up, check, fusion), evaluated against ground truth. Shared by the
 * merge tests, the merge benchmark and the demo.
 */
#ifndef COSLAM_TEST_MERGE_RUN_H
#define COSLAM_TEST_MERGE_RUN_H

#include "app/slam_filter.h"
#include "coslam/map_merge.h"
#include "slam_run.h"
#include "synth2.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    run_filter_t filter[2];
    int n_particles;
    slam_params_t params;
    merge_config_t merge;
    uint64_t filter_seed;
    double gate_m;
    int meet_frames;            /**< merge after this many frames of mutual sighting (>= 1) */
} merge_run_opts_t;

typedef struct {
    /* per receiving robot k */
    int merged;                 /**< 1 if the merge took place */
    coslam_status_t status;     /**< of slam_filter_merge_map (refusals included) */
    double t_err_m;             /**< error of the estimated transform (position) */
    double t_err_rad;
    double t_nees;              /**< 3 dof, of the sightings' transform */
    double t_err_refined_m;     /**< the transform refined by the shared landmarks (merge_check) */
    double t_err_refined_rad;
    map_eval_t before;          /**< own map before the merge, in own frame */
    map_eval_t after;           /**< after the merge */
    double after_nees_added;    /**< mean NEES over landmarks that came from the other robot */
    int n_added_eval;
    /* landmarks known by both before the merge */
    int n_common;
    double se_common_self;      /**< sum of squared errors, own estimate before */
    double se_common_other;     /**< other's estimate before, moved by the TRUE transform */
    double se_common_received;  /**< other's estimate as received: own pose (+) transformed */
    double se_common_merged;    /**< after the merge */
    /* the same relative to the receiving robot (its body frame at the meeting):
     * what a merge can improve; the absolute errors above also hold the
     * receiver's own drift, which no merge removes */
    double se_rel_self;
    double se_rel_received;
    double se_rel_merged;
    double nees_common_merged;  /**< sum of NEES after the merge */
    int n_own_only;             /**< landmarks only this robot knew */
    double nees_own_only_before;
    double nees_own_only_after;
    merge_stats_t stats;
    double merge_us;            /**< wall time of steps 2-4 */
} merge_robot_result_t;

typedef struct {
    merge_robot_result_t r[2];
    double pose_rmse_m[2];      /**< each robot's path, before the merge */
} merge_run_result_t;

merge_run_opts_t merge_run_opts_default(run_filter_t a, run_filter_t b);

/** Run one meeting. Returns 0 on success, -1 on allocation failure. */
int merge_run(const synth2_config_t *scfg, const merge_run_opts_t *opts, merge_run_result_t *res);

#ifdef __cplusplus
}
#endif

#endif
