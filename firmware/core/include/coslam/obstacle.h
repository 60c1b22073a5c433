/*
 * coslam/obstacle.h - the paper's obstacle behaviour: "The robots detect
 * obstacles with the laser range finder in the direction of movement. The
 * detected obstacles are represented as a line formed by laser readings.
 * The robots always turn right as parallel to the obstacle line when they
 * encounter an obstacle." (paper, section 5, real-world experiments).
 *
 * Geometry (all in the robot frame: x forward, y left, angles
 * counter-clockwise):
 *
 *                      obstacle line (fitted)
 *              \   *  *  *  *  *  *            u = (cos m, sin m): the
 *               \ .---------------.              direction of motion m
 *    new heading  |   corridor    | <- half width w/2 + margin
 *    m + dpsi  <--|      ^ u      |    stop distance s along u
 *                 '------|--------'
 *                      robot
 *
 *  1. Each valid reading (finite range > 0) becomes a point q in the robot
 *     frame: q = T_sensor (r cos a, r sin a) (sensor_in_robot, paper eq. 1).
 *  2. Corridor: along = q . u > 0 and |q . v| <= w/2 + margin, with
 *     v = (-sin m, cos m). An obstacle is detected if some corridor point has
 *     along < s; its nearest such point q0 seeds the obstacle.
 *  3. The obstacle's points are the readings adjacent to q0 in scan order
 *     (scans are angle-ordered) while consecutive valid points are closer
 *     than max_gap_m and within fit_radius_m of q0. Invalid readings in
 *     between are skipped, not gaps.
 *  4. Total least squares line: centroid c and the scatter matrix
 *     S = sum (q - c)(q - c)^T; the line direction is the eigenvector of the
 *     larger eigenvalue, phi = 0.5 atan2(2 Sxy, Sxx - Syy); the residual rms
 *     is sqrt(lambda_min / n), lambda_min = (Sxx + Syy)/2 -
 *     sqrt(((Sxx - Syy)/2)^2 + Sxy^2). TLS minimises perpendicular, not
 *     vertical, distances, so walls at any angle fit alike.
 *  5. Turn right, parallel: the line has two directions phi and phi + pi.
 *     The heading change dpsi = wrap(phi - m) is taken in (-pi, 0] (a right,
 *     i.e. clockwise, turn): if wrap(phi - m) > 0 use wrap(phi - m) - pi;
 *     -pi maps to 0 (already parallel). A wall square across the path gives
 *     dpsi = -pi/2; a wall receding to the left at 60 deg gives -120 deg
 *     (the robot always turns right, as in the paper, so two robots starting
 *     back to back explore different halves); one receding to the right at
 *     -60 deg gives -60 deg.
 *  6. Speed: cruise * max(0, cos dpsi) - a robot turns on the spot for turns
 *     of 90 deg or more, and slows for smaller ones - and 0 whenever the
 *     nearest corridor point is closer than min_clearance_m. Without an
 *     obstacle: dpsi = 0, speed = cruise.
 *
 * Pure functions, no state, no heap. O(n) in the scan size.
 */
#ifndef COSLAM_OBSTACLE_H
#define COSLAM_OBSTACLE_H

#include <stddef.h>
#include <stdint.h>

#include "coslam/pose2.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double robot_width_m;    /**< corridor width w (the robot's width) [m] */
    double margin_m;         /**< extra clearance each side [m] */
    double stop_distance_m;  /**< s: obstacles nearer than this along the motion are handled [m] */
    double min_clearance_m;  /**< nearer than this: speed 0 [m] */
    double cruise_speed_mps; /**< speed without obstacle [m/s] */
    double fit_radius_m;     /**< points within this distance of q0 join the line fit [m] */
    double max_gap_m;        /**< a larger jump between neighbouring points ends the obstacle [m] */
    uint16_t min_fit_points; /**< fewer points: no line (>= 2) */
} obstacle_params_t;

/** A fitted line. */
typedef struct {
    point2_t centroid;   /**< c [m] */
    double dir_rad;      /**< phi, direction of the line, in [-pi/2, pi/2] */
    double dist_m;       /**< perpendicular distance from the frame origin to the line [m] */
    double rms_m;        /**< rms perpendicular residual [m] */
    uint16_t n;          /**< points fitted */
} obstacle_line_t;

/** What the behaviour decided. */
typedef struct {
    int detected;              /**< 1 if an obstacle is in the corridor nearer than s */
    int line_ok;               /**< 1 if `line` holds a fit */
    double nearest_m;          /**< smallest `along` of any corridor point (INFINITY if none) [m] */
    obstacle_line_t line;      /**< the obstacle's line (robot frame) */
    double heading_change_rad; /**< dpsi in (-pi, 0]: new motion direction = m + dpsi [rad] */
    double speed_mps;          /**< speed along the new direction [m/s] */
} obstacle_cmd_t;

/** Defaults for a Robotino-sized robot: width 0.45 m, margin 0.05 m, stop
 *  0.6 m, clearance 0.15 m, cruise 0.2 m/s, fit radius 1.0 m, gap 0.15 m,
 *  3 points. */
void obstacle_params_default(obstacle_params_t *p);

/**
 * Total least squares line through n points (step 4 above).
 * Returns COSLAM_OK; COSLAM_E_ARG (NULL, or n over 65535);
 * COSLAM_E_NUMERIC (a non-finite point); COSLAM_E_DEGENERATE if n < 2 or
 * all points coincide (line->n is still set). O(n).
 */
coslam_status_t obstacle_fit_line(const point2_t *pts, size_t n, obstacle_line_t *line);

/**
 * The behaviour (steps 1-6). range_m / angle_rad: a scan in the sensor
 * frame, in angle order (NaN or +INFINITY readings are ignored);
 * sensor_in_robot: the laser's mounting pose; motion_dir_rad: m, the current
 * direction of motion in the robot frame (0 for straight ahead; any value
 * for an omnidirectional base). Returns COSLAM_OK (out filled);
 * COSLAM_E_ARG (NULL, n > 0 with NULL arrays, non-positive or non-finite
 * parameters, min_fit_points < 2); COSLAM_E_NUMERIC (non-finite pose or
 * motion direction); COSLAM_E_DEGENERATE when an obstacle is detected but
 * has fewer than min_fit_points points or they coincide: out then commands
 * the safe fallback, stop and turn right a quarter (dpsi = -pi/2, speed 0),
 * with line_ok = 0. O(n), no memory beyond the stack.
 */
coslam_status_t obstacle_evaluate(const obstacle_params_t *p, pose2_t sensor_in_robot, double motion_dir_rad,
                                  const double *range_m, const double *angle_rad, size_t n, obstacle_cmd_t *out);

/** Right-turn heading change parallel to a line of direction line_dir_rad for
 *  motion direction motion_dir_rad (step 5), in (-pi, 0]. */
double obstacle_parallel_right_rad(double line_dir_rad, double motion_dir_rad);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_OBSTACLE_H */
