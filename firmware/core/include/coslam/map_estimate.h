/*
 * coslam/map_estimate.h - the map estimate both filters export, in the
 * common format of the map message (../DESIGN "The map message"): the
 * robot's pose with its covariance and, per landmark, mean, 2x2 covariance
 * and observation count, plus the landmark's identity, class and provenance.
 *
 * Landmark correlations are dropped (paper sec. 2.1): each landmark is a
 * marginal Gaussian. The pose and landmarks are in the exporting robot's map
 * frame. sizeof(map_estimate_t) is about 72 * COSLAM_MAX_MSG_LANDMARKS bytes.
 *
 * Each landmark carries two covariances. `cov` is its uncertainty in the map
 * frame (for display and evaluation). `cov_rel` is the uncertainty of its
 * position *relative to the robot*, expressed in the robot's body frame:
 * Cov(R(theta)^T (m - p)). The map merge needs the latter: the receiver
 * learns where the sender is from the mutual sightings, not from the
 * sender's map frame, so the sender's absolute pose uncertainty must not
 * enter - and the pose-landmark correlation, which the per-landmark marginal
 * in the map frame has lost, is exactly what makes the relative position
 * better known than either absolute one.
 */
#ifndef COSLAM_MAP_ESTIMATE_H
#define COSLAM_MAP_ESTIMATE_H

#include <stdint.h>

#include "coslam/config.h"
#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/pose2.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    point2_t mean;      /**< [m], map frame */
    cov2_t cov;         /**< [m^2], map frame */
    cov2_t cov_rel;     /**< [m^2], of the position relative to the robot, robot body frame */
    uint32_t id;        /**< exporter's landmark identity (stable across exports) */
    uint16_t n_obs;     /**< sightings fused into it */
    uint16_t src_mask;  /**< provenance bit mask over robot ids */
    uint8_t signature;  /**< landmark class */
} map_landmark_t;

typedef struct {
    pose2_t pose;       /**< robot pose in its map frame */
    cov3_t pose_cov;    /**< [m^2, m rad, rad^2] */
    uint16_t n_landmarks;
    map_landmark_t lm[COSLAM_MAX_MSG_LANDMARKS];
} map_estimate_t;

/**
 * The whole map: what a map_estimate_t holds, up to the map capacity
 * COSLAM_MAX_LANDMARKS instead of a message's COSLAM_MAX_MSG_LANDMARKS
 * (*_export_whole). What the merge check compares with the incoming map
 * and what the tools score; a message carries a map_estimate_t.
 */
typedef struct {
    pose2_t pose;
    cov3_t pose_cov;
    uint16_t n_landmarks;
    map_landmark_t lm[COSLAM_MAX_LANDMARKS];
} map_whole_t;

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_MAP_ESTIMATE_H */
