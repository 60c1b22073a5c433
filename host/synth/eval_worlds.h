/*
 * eval_worlds.h - the named synthetic worlds of the consistency and
 * loop-closure evaluation (docs/consistency.md), shared by
 * coslam-eval-worlds and the tests so both measure the same thing.
 *
 *  - EVAL_WORLD_PAPER: the paper's scale. 1.25 turns of a 2.5 m circle
 *    (20 m) at 0.3 m/s among 64 landmarks of 4 classes in a 4 m wide ring.
 *  - EVAL_WORLD_LOOP: one large loop. 1.15 turns of an 8 m circle (58 m)
 *    among 160 landmarks of 4 classes in a 3 m wide ring; the robot comes
 *    back to its start after 50 m of dead reckoning and must recognise it.
 *  - EVAL_WORLD_LARGE: scale (issue 13). 1.1 turns of a 16.3 m circle
 *    (113 m) among 1,024 landmarks of 4 classes in a 5 m wide ring (2 per
 *    m^2, about 20 sightings per frame); eval_world_large_config gives the
 *    same field with another landmark count.
 *  - EVAL_WORLD_ARENA: MRCLAM's regime. 15 identical landmarks in 6
 *    clusters in a 6 m x 11 m arena, the robot wandering between random
 *    waypoints for 600 s (0.15 m/s, turning on the spot), MRCLAM's sensor
 *    footprint, detection rate and noise as measured (docs/replay.md): one
 *    or two sightings per frame, and every return to a landmark out of view
 *    for 5 s is a loop closure. The filter runs coslam-replay's MRCLAM model.
 * All but the arena with the default ("paper") noise of
 * slam_params_default(); the filter is given the truth's model.
 */
#ifndef COSLAM_EVAL_WORLDS_H
#define COSLAM_EVAL_WORLDS_H

#include "slam_run.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { EVAL_WORLD_PAPER = 1, EVAL_WORLD_LOOP = 2, EVAL_WORLD_LARGE = 3, EVAL_WORLD_ARENA = 4 } eval_world_t;

/** World configuration for a seed. */
synth_config_t eval_world_config(eval_world_t world, uint64_t seed);

/** The large world's field (2 landmarks per m^2 in a ring 5 m wide, 1.1
 *  turns) with n_landmarks landmarks: the ring's radius grows with them. */
synth_config_t eval_world_large_config(uint64_t seed, int n_landmarks);

/** The arena world (MRCLAM's regime, above): the truth as measured on MRCLAM. */
synth_config_t eval_world_arena_config(uint64_t seed);

int eval_world_parse(const char *name, eval_world_t *out);
int eval_filter_parse(const char *name, run_filter_t *out);

/** One run: world seed `seed`, filter seed derived from it. Returns 0 on success. */
int eval_world_run(eval_world_t world, run_filter_t filter, int n_particles, uint64_t seed, run_result_t *r);
/** eval_world_run with EKF-SLAM's active_radius_m (< 0: the profile's default; 0: the full EKF). */
int eval_world_run_ekf_radius(eval_world_t world, run_filter_t filter, int n_particles, uint64_t seed,
                              double ekf_active_radius_m, run_result_t *r);

/** The run options of eval_world_run_ekf_radius: the filter's model (the
 *  truth's, or the arena's MRCLAM model) and the filter seed of `seed`. */
run_opts_t eval_world_opts(eval_world_t world, run_filter_t filter, int n_particles, uint64_t seed,
                           double ekf_active_radius_m);

/** The loop-closure criterion of issue 9: final position error < 0.5 m and at
 *  most 2 % of the exported landmarks spurious. */
int eval_closed(const run_result_t *r);

typedef struct {
    int n;
    int closed;
    int estimated;
    int spurious;
    double pose_rmse_sum;
    double nees_sum;
    double nees[1000];
} eval_summary_t;

void eval_summary_init(eval_summary_t *s);
void eval_summary_add(eval_summary_t *s, const run_result_t *r);
double eval_summary_median_nees(const eval_summary_t *s);

#ifdef __cplusplus
}
#endif

#endif
