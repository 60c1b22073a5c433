/*
 * coslam/pose2.h - SE(2) poses: composition, inverse, point transforms,
 * angle wrapping, and the Jacobians the filters and the merge need.
 *
 * A pose (x, y, theta) [m, m, rad] is the frame of a body expressed in a
 * parent frame: a point p_b in the body frame is R(theta) p_b + (x, y) in
 * the parent frame. Composition a (+) b is "b expressed in a, then a in the
 * world": (+) is the homogeneous matrix product T_a T_b of paper eq. 1.
 *
 * All functions are O(1), use no memory beyond their arguments, and are pure
 * (no state). Angles returned are wrapped to [-pi, pi).
 */
#ifndef COSLAM_POSE2_H
#define COSLAM_POSE2_H

#ifdef __cplusplus
extern "C" {
#endif

#define COSLAM_PI 3.14159265358979323846
#define COSLAM_TWO_PI 6.28318530717958647692

typedef struct {
    double x;     /**< [m] */
    double y;     /**< [m] */
    double theta; /**< [rad], kept in [-pi, pi) by every function here */
} pose2_t;

typedef struct {
    double x; /**< [m] */
    double y; /**< [m] */
} point2_t;

/** Wrap an angle [rad] to [-pi, pi). Returns NaN for NaN/Inf input. */
double angle_wrap(double angle_rad);

/** a (+) b: compose b (expressed in a's frame) onto a. */
pose2_t pose2_compose(pose2_t a, pose2_t b);

/** a^-1, so that a (+) a^-1 = identity. */
pose2_t pose2_inverse(pose2_t a);

/** a^-1 (+) b: b expressed in a's frame (the relative pose from a to b). */
pose2_t pose2_between(pose2_t a, pose2_t b);

/** Transform a point from the frame of `a` into a's parent frame. */
point2_t pose2_apply(pose2_t a, point2_t p_local);

/** Transform a parent-frame point into the frame of `a`. */
point2_t pose2_apply_inverse(pose2_t a, point2_t p_parent);

/** pose2_apply / pose2_apply_inverse with cos and sin of a.theta given
 *  (c, s): for many points through one pose, the trigonometry once. */
point2_t pose2_apply_cs(pose2_t a, double c, double s, point2_t p_local);
point2_t pose2_apply_inverse_cs(pose2_t a, double c, double s, point2_t p_parent);

/**
 * Jacobians of c = a (+) b with respect to a (ja, 3x3) and b (jb, 3x3),
 * row-major, rows (x, y, theta) of c. Either output may be NULL.
 */
void pose2_compose_jacobians(pose2_t a, pose2_t b, double ja[3][3], double jb[3][3]);

/**
 * Jacobians of p' = pose2_apply(a, p): d p'/d a (2x3) and d p'/d p (2x2).
 * Either output may be NULL.
 */
void pose2_apply_jacobians(pose2_t a, point2_t p_local, double j_pose[2][3], double j_point[2][2]);

/** 1 if all three components are finite, else 0. */
int pose2_is_finite(pose2_t a);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_POSE2_H */
