/*
 * coslam/marginal.h - honest map and pose covariances for Fast-SLAM
 * (docs/consistency.md).
 *
 * A Fast-SLAM particle's landmark EKF is conditional on the particle's path:
 * its covariance leaves out the robot's pose error at the times the landmark
 * was seen. The spread of the landmark over the particles puts it back only
 * while the particles still differ in that part of their paths; resampling
 * makes them share one ancestor (Bailey, Nieto, Nebot, ICRA 2006), after
 * which the exported map was overconfident by 10-1000x.
 *
 * So each particle also keeps a marginal covariance of its pose, P, and each
 * landmark its anchor: P and the robot position when the landmark was
 * started. The pose error at any time is the anchor's error carried forward
 * (a heading error turns everything after it about the anchor position:
 * e_t = Phi e_a + d) plus the drift d since, independent of it (odometry
 * noise). A landmark started from the anchor pose has error G e_a (G its
 * Jacobian with respect to that pose) plus the sensor noise its conditional
 * covariance holds; so its marginal is cov + G A G^T (landmark_marginal),
 * and a later sighting of it tells the robot about d alone (Hp Phi + Hm G =
 * 0: moving the whole map does not change a sighting).
 *  - prediction: P = F P F^T + V M V^T, as the EKF;
 *  - a sighting of a landmark anchored at (A, a): P = Phi A Phi^T + the
 *    posterior of d, prior P - Phi A Phi^T, sighting z = Hp d + n with
 *    n = Hm cov Hm^T + Q. The posterior is that of the correction the
 *    particle made: Fast-SLAM 2.0 moves its pose by the proposal's gain K,
 *    whose prior is the motion since the last sample, not the drift d, so
 *    the drift left is (I - K Hp) D (I - K Hp)^T + K n K^T (Joseph form,
 *    marginal_pose_observe_gain); where D is much larger than that prior
 *    (an old landmark seen again after a long drift) the pose hardly moves
 *    and neither does P, while the optimal update, which the particle did
 *    not make, would claim the drift removed. Fast-SLAM 1.0 does not move
 *    the pose at all; its marginal keeps the Kalman posterior
 *    (marginal_pose_observe), the selection by weights doing that work;
 *  - a new landmark is anchored at the particle's current P.
 * The anchor is not moved by later sightings: a depleted filter does not
 * correct an old landmark's mean when the loop closes (its EKF averages the
 * old sightings with the new ones at poses pulled onto it), so its error
 * stays that of its anchor. A landmark received in a merge is anchored at
 * the receiver's pose marginal at the merge (map_merge.c).
 */
#ifndef COSLAM_MARGINAL_H
#define COSLAM_MARGINAL_H

#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/pose2.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/**
 * Pose marginal *p after a sighting of a landmark anchored at (anchor,
 * anchor_xy), taken at `pose` with pose Jacobian hp (d z / d pose) and noise
 * n = Hm cov Hm^T + Q (see above). Negative directions of P - Phi A Phi^T
 * (the robot better placed than the anchor) are clipped to zero, and the
 * result is intersected (cov3_ci) with the prior so that it never grows.
 * Returns COSLAM_E_NOT_PD (nothing changed) for a non-finite P or anchor or
 * a non-PD n. O(1).
 */
coslam_status_t marginal_pose_observe(cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy,
                                      double hp[2][3], cov2_t n);

/**
 * The same for a particle that corrected its pose with gain k (3x2) on the
 * sighting's innovation (Fast-SLAM 2.0's proposal): the drift after that
 * correction, (I - k Hp) D (I - k Hp)^T + k n k^T with D the drift since
 * the anchor (Joseph form: any gain). A gain larger than D warrants (the
 * proposal's prior above D: a landmark anchored a step or two ago) leaves
 * more than the prior in some direction; the result says so. With D
 * clipped the result is intersected with the prior, as in
 * marginal_pose_observe. k = the optimal gain D Hp^T (Hp D Hp^T + n)^-1
 * gives marginal_pose_observe's result. O(1).
 */
coslam_status_t marginal_pose_observe_gain(cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy,
                                           double hp[2][3], cov2_t n, double k[3][2]);

/**
 * Keep *p (a pose marginal after a frame's sightings) within `before` (the
 * marginal before them): if before - *p is not positive semi-definite,
 * *p becomes their covariance intersection (cov3_ci), else it is left
 * alone. A frame's sightings then never grow P, while one sighting may
 * (marginal_pose_observe_gain). Non-finite input changes nothing. O(1).
 */
void marginal_bound(const cov3_t *before, cov3_t *p);

/**
 * Covariance that the pose drift since a landmark's anchor adds to the
 * landmark's position relative to the robot, in the robot's body frame:
 * J (P - Phi A Phi^T)+ J^T with J = d rel / d pose, rel = the landmark in the
 * body frame (the anchor's own error moves robot and landmark alike and
 * cancels). Zero for non-finite input. O(1).
 */
cov2_t marginal_relative_drift(const cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy,
                               point2_t rel);

/** The same with c = cos(pose.theta), s = sin(pose.theta) given (a caller
 *  with many landmarks at one pose computes them once), bit for bit. */
cov2_t marginal_relative_drift_cs(const cov3_t *p, pose2_t pose, double c, double s, const cov3_t *anchor,
                                  point2_t anchor_xy, point2_t rel);

/**
 * The drift since a landmark's anchor: P - Phi A Phi^T (Phi carries the
 * anchor's heading error to the current position), negative directions
 * clipped to zero. O(1).
 */
cov3_t marginal_drift(const cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy);

/**
 * A covariance that bounds both a and b in the Loewner order (C >= a and
 * C >= b): with a = L L^T and L^-1 b L^-T = U diag(l) U^T,
 * C = L U diag(max(l, 1)) U^T L^T, the union of the two ellipses' bounds
 * along their common axes. If a is not PD, returns a + b.
 */
cov2_t cov2_loewner_max(cov2_t a, cov2_t b);
cov3_t cov3_loewner_max(cov3_t a, cov3_t b);

/**
 * Covariance intersection of two bounds of the same pose error with unknown
 * correlation: (w a^-1 + (1 - w) b^-1)^-1, w in [0, 1] maximising the
 * information determinant. If either is singular, the one with the smaller
 * trace. O(1). (For 2x2 estimates: merge_fuse_ci in map_merge.h.)
 */
cov3_t cov3_ci(cov3_t a, cov3_t b);

/** Eigen decomposition of a symmetric 3x3: a = V diag(lam) V^T (cyclic Jacobi). */
void cov3_eigen(cov3_t a, double lam[3], double v[3][3]);

/** V diag(max(lam, min_eig)) V^T: the eigenvalues below min_eig raised to it. */
cov3_t cov3_clamp_eigen(cov3_t a, double min_eig);

/**
 * cov3_clamp_eigen(a, 0): the negative eigenvalues set to zero, in closed
 * form (the characteristic cubic's trigonometric roots, the one eigenvector
 * needed from a cross product of two rows of a - lam I); Jacobi when that
 * eigenvalue is within 1e-6 (relative) of another, where the cross product
 * loses its direction. The Fast-SLAM pose marginal clips on most sightings
 * (issue 13's step time).
 */
cov3_t cov3_clamp_psd(cov3_t a);

#ifdef __cplusplus
}
#endif

#endif
