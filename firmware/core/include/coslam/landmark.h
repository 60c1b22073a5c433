/*
 * coslam/landmark.h - one point landmark as a 2-D Gaussian (a Fast-SLAM
 * particle's landmark EKF), its bookkeeping (identity, existence evidence,
 * provenance), and the helpers both filters use to associate sightings.
 *
 * All functions O(1) unless noted; no memory beyond their arguments.
 */
#ifndef COSLAM_LANDMARK_H
#define COSLAM_LANDMARK_H

#include <stdint.h>

#include "coslam/config.h"
#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/observe.h"
#include "coslam/pose2.h"
#include "coslam/slam_params.h"
#include "coslam/view.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    point2_t mean;      /**< [m], map frame */
    cov2_t cov;         /**< [m^2] */
    uint32_t id;        /**< identity, shared by the copies of this landmark in
                             all particles (inherited through resampling) */
    float exist;        /**< existence evidence, see slam_params_t */
    uint16_t n_obs;     /**< sightings fused into it (saturates at 65535) */
    uint16_t src_mask;  /**< provenance: bit k set = holds information from robot k */
    uint8_t signature;  /**< landmark class, see sighting_t */
    uint8_t confirmed_once; /**< 1 once its evidence was seen at or above
                                 exist_confirm (set by exist_miss(); 0 from
                                 landmark_init() or a zeroed struct) */
    uint16_t last_seen; /**< Fast-SLAM: the filter's update count (mod 2^16)
                             when it was last sighted, started or received;
                             a revisit is a sighting after closure_gap
                             updates without one (fastslam.h). Fits the
                             struct's padding: landmark_t stays 88 bytes */
    float anchor_cov[6];/**< robot pose marginal when the landmark was started
                             (xx, xy, xt, yy, yt, tt; marginal.h): the part of
                             the pose error it shares; all zero = exact */
    float anchor_xy[2]; /**< [m] robot position when it was started */
} landmark_t;

/** The anchor's pose covariance (all zero if none). */
cov3_t landmark_anchor(const landmark_t *lm);
/** Set the anchor: pose marginal `p` at position `at` (rounded to float). */
void landmark_set_anchor(landmark_t *lm, const cov3_t *p, point2_t at);
/**
 * Marginal covariance of the landmark in the map frame: cov + G A G^T, with
 * A the anchor covariance and G = [1 0 -(m_y - a_y); 0 1 m_x - a_x] the
 * Jacobian of the landmark with respect to the anchoring pose (a rotation
 * of that pose turns the landmark about the anchor position). O(1).
 */
cov2_t landmark_marginal(const landmark_t *lm);

/** What a landmark is expected to look like from a pose. */
typedef struct {
    sighting_t zhat;    /**< predicted sighting */
    double h_lm[2][2];  /**< d zhat / d landmark */
    double h_pose[2][3];/**< d zhat / d pose */
    cov2_t s;           /**< innovation covariance H Sigma H^T + Q (+ pose term) */
    cov2_t s_inv;
    double log_norm;    /**< -log(2 pi sqrt(det S)) */
} lm_expect_t;

/**
 * Start a landmark from a sighting taken at `pose` (treated as exact, as in
 * a Fast-SLAM particle): mean from the inverse model, covariance
 * G_z Q G_z^T + w8 I; no anchor (set it with landmark_set_anchor).
 * Returns COSLAM_E_NOT_PD if the result is not PD.
 */
coslam_status_t landmark_init(landmark_t *lm, const slam_params_t *params, pose2_t pose,
                              sighting_t z, uint32_t id, uint16_t src_mask);

/**
 * Fill `e` for landmark `lm` seen from `pose`. S = H_m Sigma H_m^T + Q
 * (+ H_p pose_cov H_p^T if pose_cov is not NULL, the Fast-SLAM 2.0 form).
 * Returns E_DEGENERATE (landmark on the robot) or E_NOT_PD.
 */
coslam_status_t landmark_expect(const landmark_t *lm, const slam_params_t *params, pose2_t pose,
                                const cov3_t *pose_cov, lm_expect_t *e);

/**
 * A cheap lower bound on the squared Mahalanobis distance that
 * landmark_expect() + landmark_mahalanobis2() would give for a sighting of
 * landmark lm from `pose` (pose_cov as there, may be NULL), from the
 * predicted sighting `zhat` (observe_predict(pose, lm->mean)) alone: no
 * Jacobian, no inverse. For any PD S, nu^T S^-1 nu >= nu_k^2 / S_kk, and
 * S_kk is bounded by traces (the Jacobians' rows have norm 1 for the range
 * and 1/r, sqrt(1/r^2 + 1) for the bearing). Used to skip landmarks that
 * no sighting of the frame can come near (Fast-SLAM's association at
 * scale, issue 13). landmark_d2_bound_prepare once per landmark, then
 * landmark_d2_lower_bound per sighting; a non-finite or degenerate input
 * gives no bound (0).
 */
typedef struct {
    sighting_t zhat;
    double inv_s_rr; /**< 1 / (upper bound of S_rr); 0: no bound */
    double inv_s_bb; /**< 1 / (upper bound of S_bb) */
} lm_d2_bound_t;
lm_d2_bound_t landmark_d2_bound_prepare(const landmark_t *lm, const slam_params_t *params, const cov3_t *pose_cov,
                                        sighting_t zhat);
double landmark_d2_lower_bound(const lm_d2_bound_t *b, sighting_t z);

/** Squared Mahalanobis distance and log-likelihood of z under e. */
double landmark_mahalanobis2(const lm_expect_t *e, sighting_t z);
double landmark_log_lik(const lm_expect_t *e, double d2);

/**
 * EKF update of the landmark with sighting z given the pose is known
 * (Joseph form, so the covariance stays symmetric PD). `e` must come from
 * landmark_expect() at the same pose without pose covariance.
 */
void landmark_update(landmark_t *lm, const slam_params_t *params, const lm_expect_t *e, sighting_t z);

/**
 * `cov` kept at least the covariance of the offset a track of sightings
 * shares (slam_params_t track_offset_*), at the sighting `e` predicts: cov
 * plus the positive part of (offset - cov). Unchanged where both are 0.
 */
cov2_t landmark_offset_floor(const slam_params_t *params, const lm_expect_t *e, cov2_t cov);

/** 1 if the predicted sighting lies inside the sensor footprint (with margin). */
int landmark_should_be_seen(const slam_params_t *params, sighting_t zhat);

/**
 * 1 if the view profile `v` (view.h; NULL or not valid: never) holds an
 * obstacle certainly in front of the landmark expected as `e`: a laser
 * return in its bearing bin nearer than its predicted range by more than
 * 0.1 m + 3 sqrt(S_rr) (the marker may sit on the obstacle's face). Such a
 * landmark was hidden, not missed.
 */
int landmark_hidden(const view_profile_t *v, const lm_expect_t *e);


/** Positive evidence on an existence counter: the landmark was sighted. */
void exist_hit(float *exist, const slam_params_t *params);

/**
 * 1 if a miss of a landmark expected as `e` is certain enough to count
 * against a confirmed (or once confirmed) landmark: sqrt(e->s.yy), the
 * bearing sd of the predicted sighting, is at most
 * exist_miss_bearing_sd_frac * sensor_fov_rad / 2 (a NaN is not certain).
 */
int landmark_miss_is_certain(const slam_params_t *params, const lm_expect_t *e);

/**
 * 1 if a confirmed landmark expected as `e` that no sighting pairs would
 * lose evidence for certain: in view (landmark_should_be_seen), not hidden
 * by `v` (landmark_hidden) and its miss certain (landmark_miss_is_certain).
 * The filters count such landmarks, paired or not (view_pairs,
 * view_misses): the rate at which the map is found where it is expected.
 */
int landmark_miss_would_count(const slam_params_t *params, const view_profile_t *v, const lm_expect_t *e);

/** 1 if a landmark with evidence `exist` and flag `confirmed_once` counts as
 *  confirmed for the miss rule: confirmed now or once (exist_miss sets the
 *  flag when it first sees the evidence at exist_confirm). */
int exist_confirmed(float exist, uint8_t confirmed_once, const slam_params_t *params);

/** The largest bearing sd [rad] of a certain miss (landmark_miss_is_certain):
 *  exist_miss_bearing_sd_frac * sensor_fov_rad / 2. */
double landmark_miss_bearing_sd_max(const slam_params_t *params);

/**
 * Negative evidence: the landmark (evidence *exist, flag *confirmed_once,
 * see landmark_t) should have been seen (landmark_should_be_seen) but was
 * not; `certain` is landmark_miss_is_certain() for its prediction. Sets
 * *confirmed_once if *exist >= exist_confirm. Returns 1 if the landmark
 * should now be removed (evidence below zero).
 *  - exist_miss_confirmed > 0 and *confirmed_once (confirmed now, or once:
 *    by its own sightings, or received in a map merge, which places it at
 *    exist_confirm): loses exist_miss_confirmed if `certain`, else nothing.
 *    It drops out of the export below exist_confirm and is removed below
 *    zero; a landmark at evidence e survives floor(e / exist_miss_confirmed)
 *    consecutive certain misses.
 *  - otherwise tentative landmarks (never confirmed) lose exist_miss;
 *    confirmed ones (only with exist_miss_confirmed == 0) weaken by
 *    exist_miss down to exist_confirm and never below (the rule before
 *    exist_miss_confirmed).
 */
int exist_miss(float *exist, uint8_t *confirmed_once, int certain, const slam_params_t *params);

int landmark_is_confirmed(const landmark_t *lm, const slam_params_t *params);

/** A gated (sighting, landmark) candidate pair and its score (log-likelihood). */
typedef struct {
    double score;
    int32_t sighting;
    int32_t landmark;
} assoc_pair_t;

/** How a sighting relates to one landmark (assoc_classify). */
typedef enum {
    ASSOC_FAR = 0,          /**< d2 >= new_landmark_chi2: surely another object */
    ASSOC_NEAR = 1,         /**< plausible but not admissible as a match */
    ASSOC_ADMISSIBLE = 2,   /**< d2 < gate_chi2 and log-likelihood >= new_landmark_log_lik */
} assoc_class_t;

/**
 * Classify a (sighting, landmark) pair from its squared Mahalanobis distance
 * d2 and log-likelihood ll. A match must pass the chi-square gate AND be
 * more likely than a new landmark (Thrun et al. 2005, sec. 13.8: the
 * maximum-likelihood rule with the new-landmark likelihood p0), so the
 * acceptance distance shrinks when the innovation covariance is large, as at
 * a loop closure with an uncertain pose.
 */
assoc_class_t assoc_classify(const slam_params_t *params, double d2, double ll);

/**
 * Decide whether unpaired sighting i starts a new landmark: yes if every
 * landmark it could plausibly be (admissible or near) was taken by another
 * sighting of the frame (a distinct object beside it); no if some plausible
 * landmark is left (the sighting is ambiguous and dropped). n_near[i] counts
 * the ASSOC_NEAR landmarks of sighting i. O(P ns).
 */
int assoc_unpaired_is_new(const assoc_pair_t *pairs, int n_pairs, int i, const int32_t *assign, int ns,
                          const uint8_t *n_near);

/**
 * Greedy maximum-likelihood assignment with mutual exclusion: pairs are
 * taken in decreasing score; a pair is accepted if neither its sighting nor
 * its landmark is taken yet. `pairs` (only gated pairs) is sorted in place.
 * assign[i] receives the landmark of sighting i, or -1.
 * O(P log P + P ns) time for P pairs and ns sightings, no memory.
 */
void assoc_greedy(assoc_pair_t *pairs, int n_pairs, int ns, int32_t *assign);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_LANDMARK_H */
