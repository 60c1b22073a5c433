/*
 * mrclam_model.h - the sighting, odometry and association model coslam-replay
 * runs on MRCLAM (fitted to Dataset 6, docs/replay.md "Parameters"), in one
 * place: replay_config_default() starts from it, and the arena world
 * (eval_worlds.h) gives it to the filters it runs on MRCLAM-like data.
 */
#ifndef COSLAM_SYNTH_MRCLAM_MODEL_H
#define COSLAM_SYNTH_MRCLAM_MODEL_H

#include "coslam/slam_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/** slam_params_default() with MRCLAM's camera, odometry, gates and existence. */
slam_params_t mrclam_slam_params(void);

#ifdef __cplusplus
}
#endif

#endif
