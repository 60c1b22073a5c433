/*
 * coslam/observe.h - the range-bearing observation model of a point landmark
 * seen from a robot pose, its Jacobians, and its inverse (landmark
 * initialisation).
 *
 *   range   = |m - p|                                  [m]
 *   bearing = atan2(m_y - p_y, m_x - p_x) - p_theta    [rad], wrapped
 *
 * Sighting noise Q = diag(w1 + k r^2, w2) (paper eq. 6; k = range_var_per_m2).
 * All functions O(1), stateless.
 */
#ifndef COSLAM_OBSERVE_H
#define COSLAM_OBSERVE_H

#include <stdint.h>

#include "coslam/cov2.h"
#include "coslam/pose2.h"
#include "coslam/slam_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/** A range-bearing sighting. Used for landmarks and for other robots. */
typedef struct {
    double range_m;
    double bearing_rad;
    /** Landmark class (marker colour pair). Association only pairs a sighting
     *  with landmarks of the same signature; 0 when all markers look alike. */
    uint8_t signature;
} sighting_t;

/** Ranges below this are degenerate for the model (bearing undefined) [m]. */
#define OBSERVE_MIN_RANGE_M 1e-6

/** Predicted sighting of landmark m from pose p (signature 0). */
sighting_t observe_predict(pose2_t p, point2_t m);

/**
 * Jacobians of observe_predict: h_pose (2x3) w.r.t. (x, y, theta) and
 * h_lm (2x2) w.r.t. (m_x, m_y). Either may be NULL.
 * Returns COSLAM_E_DEGENERATE when the landmark sits on the robot.
 */
coslam_status_t observe_jacobians(pose2_t p, point2_t m, double h_pose[2][3], double h_lm[2][2]);

/** Landmark position from a sighting: p (+) (r cos b, r sin b). */
point2_t observe_inverse(pose2_t p, sighting_t z);

/** Jacobians of observe_inverse w.r.t. the pose (2x3) and (range, bearing) (2x2). */
void observe_inverse_jacobians(pose2_t p, sighting_t z, double g_pose[2][3], double g_z[2][2]);

/** Q for a sighting at the given range, as a cov2_t (xx = range, yy = bearing). */
cov2_t observe_noise(const slam_params_t *params, double range_m);

/** Innovation z - zhat with the bearing wrapped, as (d_range, d_bearing). */
void observe_innovation(sighting_t z, sighting_t zhat, double nu[2]);

/** 1 if range and bearing are finite and the range is positive. */
int sighting_is_valid(const sighting_t *z);

/** sighting_is_valid, and what the camera can report: range at most
 *  sighting_max_range_m, |bearing| <= pi (a bearing is not wrapped from
 *  outside (-pi, pi]: 1e308 rad is a fault, not an angle). */
int sighting_is_plausible(const sighting_t *z, const slam_params_t *p);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_OBSERVE_H */
