/*
 * omni/omni_kinematics.h - kinematics and wheel odometry of a three-wheel
 * omnidirectional base (Festo Robotino): body velocity <-> motor speeds,
 * and the odometry increment the SLAM filter consumes (coslam/motion.h).
 *
 * Geometry (robot frame: x forward, y left, theta counter-clockwise):
 * wheel k (k = 0, 1, 2) touches the floor at distance R (base_radius_m)
 * from the centre, at position angle a_k = wheel_angle0_rad + k 2pi/3.
 * An omni wheel transmits force only along its rolling direction, the
 * tangent t_k = (-sin a_k, cos a_k); positive motor speed pushes the
 * contact point along t_k, i.e. counter-clockwise about the centre, so
 * three equal positive speeds turn the robot counter-clockwise (w > 0).
 *
 * Inverse (body velocity -> wheel rim speed v_k [m/s] -> motor speed n_k):
 *     v_k = -sin(a_k) vx + cos(a_k) vy + R w
 *     n_k = v_k / r * G * 60 / (2 pi)     [rpm], r wheel radius, G gear ratio
 * Forward (exact inverse for 120 degree spacing, since
 * sum sin^2 a_k = sum cos^2 a_k = 3/2 and sum sin a_k = sum cos a_k =
 * sum sin a_k cos a_k = 0):
 *     vx = (2/3) sum_k -sin(a_k) v_k
 *     vy = (2/3) sum_k  cos(a_k) v_k
 *     w  = (1 / (3 R)) sum_k v_k
 * Odometry: the body velocity from measured motor speeds, held constant
 * over dt (zero-order hold), integrated exactly along the arc by
 * motion_from_body_velocity().
 *
 * Defaults (Robotino): r = 0.040 m, R = 0.132 m, G = 16 (16:1), wheel 0 at
 * +60 degrees (front left), wheel 1 at 180 degrees (rear), wheel 2 at
 * 300 degrees (front right). Check the mounting and motor polarity of a
 * real unit: a mirrored motor is a negative speed here.
 *
 * All functions are pure, O(1), use no memory beyond their arguments and
 * never block.
 */
#ifndef OMNI_KINEMATICS_H
#define OMNI_KINEMATICS_H

#include "coslam/motion.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Wheels of the base. Structural (the formulas above need exactly 3). */
#define OMNI_WHEELS 3

typedef struct {
    double wheel_radius_m;   /**< r > 0 */
    double base_radius_m;    /**< R > 0, centre to wheel contact point */
    double gear_ratio;       /**< G > 0, motor turns per wheel turn */
    double wheel_angle0_rad; /**< a_0, finite */
} omni_kinematics_config_t;

/** The Robotino defaults listed above. */
omni_kinematics_config_t omni_kinematics_config_default(void);

/** COSLAM_OK if every field is finite and r, R, G > 0, else COSLAM_E_ARG. */
coslam_status_t omni_kinematics_config_check(const omni_kinematics_config_t *cfg);

/**
 * Inverse kinematics: body velocity (vx, vy [m/s], w [rad/s], robot frame)
 * to motor speeds motor_rpm[3] [rpm]. Returns COSLAM_OK; COSLAM_E_ARG NULL
 * or bad config; COSLAM_E_NUMERIC non-finite input (motor_rpm set to 0).
 */
coslam_status_t omni_kinematics_inverse(const omni_kinematics_config_t *cfg, double vx_mps, double vy_mps,
                                        double w_radps, double motor_rpm[OMNI_WHEELS]);

/**
 * Forward kinematics: motor speeds [rpm] to body velocity. Any output
 * pointer may be NULL. Returns COSLAM_OK; COSLAM_E_ARG NULL cfg/motor_rpm or
 * bad config; COSLAM_E_NUMERIC non-finite input (outputs set to 0).
 */
coslam_status_t omni_kinematics_forward(const omni_kinematics_config_t *cfg, const double motor_rpm[OMNI_WHEELS],
                                        double *vx_mps, double *vy_mps, double *w_radps);

/**
 * Odometry increment for motor speeds motor_rpm held for dt_s >= 0 [s]:
 * forward kinematics, then motion_from_body_velocity (exact arc). Returns
 * COSLAM_OK; COSLAM_E_ARG NULL, bad config or dt_s < 0; COSLAM_E_NUMERIC
 * non-finite input. *u is the zero increment on error.
 */
coslam_status_t omni_kinematics_odometry(const omni_kinematics_config_t *cfg, const double motor_rpm[OMNI_WHEELS],
                                         double dt_s, odo_increment_t *u);

/**
 * Concatenate increments: a, then b expressed in the frame reached after a
 * (the SE(2) product, with dtheta summed unwrapped as odo_increment_t
 * requires). Used to accumulate several increments into one.
 */
odo_increment_t omni_kinematics_compose(odo_increment_t a, odo_increment_t b);

/**
 * Scale motor_rpm uniformly so that no |n_k| exceeds max_rpm (> 0); the
 * direction of the body velocity is kept, its magnitude shrinks. Returns
 * the factor applied, in (0, 1]; 1 when nothing was scaled or max_rpm is
 * not a positive finite number.
 */
double omni_kinematics_saturate(double motor_rpm[OMNI_WHEELS], double max_rpm);

#ifdef __cplusplus
}
#endif

#endif /* OMNI_KINEMATICS_H */
