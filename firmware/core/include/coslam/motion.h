/*
 * coslam/motion.h - motion models for the prediction step.
 *
 * The filters consume one kind of control: an odometry increment
 * u = (dx, dy, dtheta) in the robot frame at the start of the increment
 * [m, m, rad], applied as pose' = pose (+) u. An omni-drive (Robotino)
 * produces this directly from its wheel odometry. Datasets logged as
 * velocity commands (v, w) held for dt are converted exactly (constant body
 * velocity, i.e. a circular arc) by motion_from_body_velocity().
 *
 * Noise (paper eq. 6, w3 and w4, see slam_params.h): the increment is
 * corrupted by zero-mean Gaussian noise in the robot frame with covariance
 * R(u) = diag(w3 s, w3 s, w4 s), s = |(dx, dy)| + base_radius |dtheta|
 * the wheel travel. All functions O(1), stateless except the RNG.
 */
#ifndef COSLAM_MOTION_H
#define COSLAM_MOTION_H

#include "coslam/cov3.h"
#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "coslam/slam_params.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double dx;     /**< [m], robot frame at the start of the increment */
    double dy;     /**< [m] */
    double dtheta; /**< [rad], not wrapped (a full turn stays a full turn) */
} odo_increment_t;

/**
 * Exact increment for a constant body velocity (vx, vy, w) held for dt:
 * the integral of R(w t) (vx, vy) over [0, dt]. A differential-drive
 * velocity command (v, w) is vx = v, vy = 0. dt >= 0 [s].
 */
odo_increment_t motion_from_body_velocity(double vx_mps, double vy_mps, double w_radps, double dt_s);

/** pose (+) u. */
pose2_t motion_apply(pose2_t pose, odo_increment_t u);

/** Wheel travel s of an increment [m]. */
double motion_travel_m(odo_increment_t u, double base_radius_m);

/** R(u), the increment's noise covariance in the robot frame. */
cov3_t motion_noise_cov(const slam_params_t *p, odo_increment_t u);

/** u plus one draw of its noise (for particle prediction and simulation). */
odo_increment_t motion_sample(const slam_params_t *p, odo_increment_t u, rng_t *rng);

/**
 * Jacobians of pose (+) u: g = d/d pose (3x3), v = d/d u (3x3).
 * Either may be NULL.
 */
void motion_jacobians(pose2_t pose, odo_increment_t u, double g[3][3], double v[3][3]);

/** 1 if all fields are finite. */
int motion_is_finite(odo_increment_t u);

/** Time-stamp slack of motion_is_plausible [s]: an increment may cover up
 *  to this much more time than the stamps say (jitter of the odometry and
 *  control clocks). */
#define MOTION_PLAUSIBLE_SLACK_S 0.1

/** The longest time one increment may stand for in the filters' own check
 *  [s]: ekfslam_predict / fastslam_predict, which are not told the time,
 *  refuse an increment the base could not do in this long (180 m at the
 *  default 3 m/s), so an absurd value (1e308 m) never reaches the
 *  covariance. slam_filter_predict checks against the real time span. */
#define MOTION_MAX_INCREMENT_S 60.0

/**
 * 1 if the increment u is something the base can do in dt_s seconds:
 * finite, |(dx, dy)| <= max_speed_mps * (dt_s + slack) and |dtheta| <=
 * max_turn_radps * (dt_s + slack) (slam_params_t). dt_s must be finite and
 * >= 0; a negative or non-finite dt_s makes every increment implausible.
 */
int motion_is_plausible(const slam_params_t *p, odo_increment_t u, double dt_s);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_MOTION_H */
