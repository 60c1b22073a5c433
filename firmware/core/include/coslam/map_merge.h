/*
 * coslam/map_merge.h - cooperative map merging from robot-to-robot
 * sightings (paper sec. 2.1, eqs. 1-5), with the uncertainty of the
 * transform carried into the merged landmarks.
 *
 * Pipeline, as the receiving robot ("self") runs it on a message from the
 * sender ("other"):
 *  1. merge_relative_pose: the other robot's pose in self's body frame from
 *     the two mutual sightings alone (geometry below), with covariance.
 *     merge_compensate then moves it to "now" with self's odometry since
 *     its own sighting.
 *  2. merge_transform_map: every incoming landmark once into self's body
 *     frame, with covariance R Sigma_rel R^T + J_T Sigma_T J_T^T (paper eq.
 *     3 corrected: eq. 3 as printed multiplies a 3x3 homogeneous T with a
 *     2x2 Sigma; the rotation of a covariance is R Sigma R^T, and the
 *     uncertainty of T itself must be added or the merged landmarks come
 *     out biased and overconfident, as in the paper's Fig. 7).
 *  3. merge_into_fastslam / merge_into_ekfslam: duplicates found by
 *     nearest neighbour inside a Mahalanobis gate through a grid hash built
 *     once over the incoming map (O(N M) over N particles, not O(N M^2));
 *     one incoming landmark matches at most one own landmark; a match is
 *     fused by the Kalman form of eqs. 4-5, an unmatched one is added.
 *     Fast-SLAM: into every particle with that particle's pose. EKF-SLAM:
 *     as Cartesian observations of the landmark relative to the robot pose
 *     in the state, so the robot-landmark cross-covariances stay right.
 *  5. Repeated meetings never count information twice: every landmark
 *     carries a provenance mask (which robots' sightings it holds). A pair
 *     whose masks are disjoint is independent and fused by the Kalman
 *     update; a pair sharing any robot is fused by covariance intersection
 *     (Julier and Uhlmann 1997), consistent for unknown correlation, so
 *     re-merging information already fused cannot shrink the covariance.
 *     Messages are accepted from a sender only with a sequence number
 *     newer than the last merged one, by at most MERGE_SEQ_MAX_JUMP
 *     (merge_session_t).
 *  0. Before any of this, merge_prepare refuses a message whose numbers no
 *     robot of this team can produce (COSLAM_E_MERGE_IMPLAUSIBLE): a pose or
 *     landmark farther than max_extent_m from the sender's origin, a
 *     landmark covariance (either one) with an axis outside
 *     [min_var_m2, max_var_m2], a sighting of the receiver with a variance
 *     outside [min_var_m2, max_var_m2] (range) or [min_bearing_var_rad2,
 *     max_bearing_var_rad2] or a range beyond max_extent_m, or a transform
 *     so uncertain that a landmark's covariance in the receiver's body
 *     frame gets an axis above max_var_m2 (merge_transform_map; 1e6 rad^2
 *     of sighting variance gave 1.25e6 m^2 there). The codec already
 *     refused non-finite and non-positive-definite values; these bounds
 *     stop finite but absurd ones (a landmark at 1e6 m, a covariance of
 *     1e-20 m^2 that would override the receiver's map).
 *
 * Geometry of the mutual sightings (both robots' markers at their centres):
 *
 *            other (O)            z_self,other  = (r1, b1): O seen from S,
 *             ^  \  b2                            bearing in S's body frame
 *      theta_O |   \  (O's x axis)  z_other,self = (r2, b2): S seen from O,
 *             |  r  \                              bearing in O's body frame
 *             |      \
 *   S's x --> S ------ (b1 measured from S's x axis towards O)
 *
 *   O's position in S's frame:  t = r (cos b1, sin b1)
 *   The ray O->S points along b1 + pi in S's frame and along b2 in O's
 *   frame, so O's heading in S's frame is theta_O = b1 + pi - b2.
 *   The range is measured twice: r = (r1/v1 + r2/v2) / (1/v1 + 1/v2),
 *   variance 1 / (1/v1 + 1/v2).
 *
 * Memory: merge_scratch_t is caller-owned (about 100 * COSLAM_MAX_MSG_
 * LANDMARKS bytes plus the grid). Nothing allocates.
 */
#ifndef COSLAM_MAP_MERGE_H
#define COSLAM_MAP_MERGE_H

#include <stdint.h>

#include "coslam/config.h"
#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"
#include "coslam/map_estimate.h"
#include "coslam/motion.h"
#include "coslam/occ_grid.h"
#include "coslam/pose2.h"
#include "coslam/slam_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Buckets of the merge grid hash (a power of two is not required). */
#ifndef COSLAM_MERGE_GRID_BUCKETS
#define COSLAM_MERGE_GRID_BUCKETS (2 * COSLAM_MAX_MSG_LANDMARKS)
#endif

/** A sighting of one robot by another, with its noise. */
typedef struct {
    double range_m;
    double bearing_rad;
    double range_var_m2;
    double bearing_var_rad2;
} robot_sighting_t;

typedef struct {
    /** Squared Mahalanobis gate for "these two landmarks are the same" (2 dof). */
    double gate_chi2;
    /** Smallest cell edge of the grid hash [m]. The cell in use grows to the
     *  largest distance the gate can accept for the incoming covariances, so
     *  the 3x3 neighbourhood never misses a gated pair. */
    double grid_cell_m;
    /** 1: add the uncertainty of the transform (this project);
     *  0: the paper's eq. 3, rotation of the covariance only (for comparison). */
    uint8_t transform_uncertainty;
    /** Fast-SLAM: multiply each particle's weight by how well its map agrees
     *  with the incoming one (product of the duplicate pairs' likelihoods),
     *  then resample if the ESS falls low. */
    uint8_t reweight_particles;
    /** Import only landmarks the sender sighted at least this often. */
    uint16_t min_obs;
    /** The duplicates of one message count as at most this many independent
     *  observations (each one's information scaled by fuse_eff_pairs / n):
     *  their errors relative to the sender share its pose error, which the
     *  message drops. 0: every duplicate counts fully. */
    double fuse_eff_pairs;

    /* ---- set-up (merge_prepare) ---- */
    /** Bound on the sender's speed and turn rate between its sighting and
     *  the receiver's [m/s, rad/s], >= 0: (v dt)^2 is added to the
     *  transform's x and y variance, (w dt)^2 to its heading variance. */
    double peer_speed_mps;
    double peer_turn_radps;
    /** Both robots measure the same distance: (r1 - r2)^2 / (v1 + v2) above
     *  this refuses the merge (COSLAM_E_MERGE_RANGE; a misread marker).
     *  0 disables the check. */
    double range_check_chi2;
    /** Plausibility (step 0 above): largest distance of the sender's pose
     *  and landmarks from its map origin [m]; the bounds on every axis of a
     *  landmark covariance [m^2] (the sender's, and each one's once in the
     *  receiver's body frame); the range variance of the sender's sighting
     *  within the same bounds, its range at most max_extent_m; its bearing
     *  variance in [min_bearing_var_rad2, max_bearing_var_rad2] [rad^2]
     *  (default 0.25: a standard deviation of 0.5 rad, wider than a
     *  camera's half field of view, is no sighting). 0 < min_var_m2 <
     *  max_var_m2, 0 < min_bearing_var_rad2 < max_bearing_var_rad2. */
    double max_extent_m;
    double min_var_m2;
    double max_var_m2;
    double min_bearing_var_rad2;
    double max_bearing_var_rad2;

    /* ---- check before trust (merge_check) ---- */
    /** 1: merge_check runs (agreement test, transform refinement, negative
     *  information, echo and ambiguity rules); 0: every incoming landmark is
     *  fused or added as in the paper (for comparison). */
    uint8_t check;
    /** Gauss-Newton refinements of the transform from the shared landmarks
     *  (each re-pairs the landmarks first); 0 keeps the sightings' transform. */
    uint8_t refine_iters;
    /** The pairs' information on the transform counts as that of at most
     *  this many independent pairs (their errors are correlated through
     *  each robot's pose; the message drops those correlations); 0: every
     *  pair counts fully. */
    double refine_eff_pairs;
    /** Normal quantile of the joint agreement test: the pairs' normalised
     *  innovation squared plus the transform shift's, against the chi-square
     *  quantile of 2 n_pairs dof at this z (Wilson-Hilferty); 2.33 = 99 %. */
    double agree_z;
    /** An unpaired incoming landmark that the receiver should have seen from
     *  at least this many of its keyframes (merge_coverage_t) and did not
     *  map is refused (negative information). 0 disables. */
    uint16_t veto_looks;
    /** The merge is refused when more than this fraction of the checked
     *  incoming landmarks (paired + refused by negative information) was
     *  refused, and at least two were. */
    double max_contradict_fraction;
    /** An unpaired incoming landmark closer than this squared Mahalanobis
     *  distance to an own landmark left unpaired is ambiguous (a failed
     *  pairing, not a new object) and is not added. */
    double ambiguous_chi2;
    /** An unpaired incoming landmark closer than this squared Mahalanobis
     *  distance to another incoming landmark of its signature, on the two
     *  relative covariances (the sender's own uncertainty of the pair), is
     *  unresolved (the sender cannot tell the two apart) and is not added.
     *  Default 9.21, the 99 % quantile of 2 dof. 0 disables. The robot's
     *  merge path (slam_filter_merge_map) applies it to EKF-SLAM receivers
     *  only: Fast-SLAM's per-particle association resolves such a pair, and
     *  on MRCLAM Fast-SLAM's maps were worse with the rule than without it
     *  (docs/map-merge.md). */
    double unresolved_chi2;
    /** An unpaired incoming landmark is added only if the receiver could
     *  refute it by its own sightings: the largest axis of its position sd
     *  in the receiver's body frame (the transform's uncertainty included)
     *  at most this factor times merge_refute_sd_m(receiver's parameters),
     *  the sd up to which a miss is certain at the far edge of the view.
     *  A landmark more uncertain than that is never removed by negative
     *  evidence (landmark_miss_is_certain), so a spurious one would stay
     *  and be passed on. Default 1 (derived, not fitted); 0 disables. A
     *  paired (fused) landmark is not affected. The robot's merge path
     *  (slam_filter_merge_map) applies it to EKF-SLAM receivers only, as
     *  unresolved_chi2: with Fast-SLAM receivers it was worse on MRCLAM
     *  (docs/map-merge.md). */
    double refute_sd_factor;
    /** A receiver lost in its own map is refused the merge
     *  (COSLAM_E_MERGE_LOST): when none of its own landmarks that the merge
     *  pairs is placed relative to it within this factor times
     *  merge_refute_sd_m(receiver's parameters) (largest axis of its
     *  relative sd), the bound of refute_sd_factor. A landmark placed worse
     *  than that is one whose absence from the view the receiver cannot
     *  tell (landmark_miss_is_certain); a receiver that places none of the
     *  paired ones cannot tell which of its identical landmarks an incoming
     *  one is, and its wide gates let a consistent wrong assignment pass
     *  the joint test. Default 1 (derived, not fitted); 0 disables. The
     *  robot's merge path (slam_filter_merge_map) applies it to EKF-SLAM
     *  receivers only: with Fast-SLAM receivers it was worse on the
     *  held-out arena teams (docs/map-merge.md). */
    double lost_sd_factor;
    /** Work units one call may spend on a Fast-SLAM merge in parts
     *  (merge_fastslam_run; a particle costs one unit per own landmark and
     *  MERGE_UNITS_PER_INCOMING per incoming one): the robot's merge path
     *  (slam_filter_merge_map) merges that much in the step the message
     *  arrives, and the rest in the idle time after the following steps
     *  (slam_filter_idle). 0: the whole merge at once. Default 524,288:
     *  4-5 ms a call on the bench's machine (coslam-bench-merge), so one
     *  message into 1,000 particles of 1,024 landmarks takes 9 calls;
     *  300 particles of 100 landmarks with 100 incoming, or anything
     *  smaller, merge at once (docs/scale.md). */
    uint32_t step_units;
} merge_config_t;

/** Defaults: gate 9.21 (99 %), cell 1 m, full uncertainty, no reweighting,
 *  min_obs 1, Kalman fusion of disjoint provenance with the duplicates
 *  counting as 2 independent ones, peer bounds 0.3 m/s and
 *  0.5 rad/s, range check 9, plausibility: extent 1 km, landmark variances
 *  in [1e-6, 1e4] m^2 (1 mm .. 100 m standard deviation), bearing variance
 *  >= 1e-8 rad^2 (0.006 deg), check on with 3 refinements moving the map
 *  and counting as 2 independent pairs, agree_z 2.33 (99 %), veto_looks 5,
 *  contradict fraction 0.3, ambiguous_chi2 25, unresolved_chi2 9.21,
 *  refute_sd_factor 1, lost_sd_factor 1, step_units 524,288.
 *  docs/map-merge.md says why and on what they were chosen. */
merge_config_t merge_config_default(void);

/** The position sd [m] up to which a landmark at the far edge of the view
 *  (sensor_max_range_m x visibility_margin) is certainly missed when not
 *  seen: exist_miss_bearing_sd_frac x half the field of view x that range
 *  (landmark_miss_is_certain, bearing sd about position sd / range). */
double merge_refute_sd_m(const slam_params_t *p);

/** The incoming map in self's body frame (output of merge_transform_map). */
typedef struct {
    uint16_t n;
    point2_t mean[COSLAM_MAX_MSG_LANDMARKS];     /**< [m], self's body frame */
    cov2_t cov[COSLAM_MAX_MSG_LANDMARKS];        /**< [m^2], same frame */
    uint16_t src_mask[COSLAM_MAX_MSG_LANDMARKS];
    uint16_t n_obs[COSLAM_MAX_MSG_LANDMARKS];
    uint8_t signature[COSLAM_MAX_MSG_LANDMARKS];
    uint32_t id[COSLAM_MAX_MSG_LANDMARKS];       /**< sender's identity (for logs) */
    /* the same landmarks before the transform (for EKF-SLAM's batch form) */
    point2_t rel[COSLAM_MAX_MSG_LANDMARKS];      /**< [m], sender's body frame */
    cov2_t rel_cov[COSLAM_MAX_MSG_LANDMARKS];    /**< [m^2], sender's body frame, no transform term */
    pose2_t t;                                   /**< the transform used (sender body in receiver body) */
    cov3_t t_cov;                                /**< its covariance (zero in paper mode) */
} merge_body_map_t;

/** Gated duplicate candidate: own landmark, incoming landmark, distance. */
typedef struct {
    int32_t own;
    int32_t in;
    double d2;
} merge_pair_t;

/** The cost of one incoming landmark in a particle's merge (moved into its
 *  frame, looked up, fused or added through the tree), in own landmarks
 *  (moved into the body frame and tested against the grid): measured with
 *  coslam-bench-merge, about 146 against 8.5 ns (docs/scale.md). */
#define MERGE_UNITS_PER_INCOMING 16U

/** The EKF-SLAM merge's work in multiply-adds per work unit
 *  (merge_ekfslam_run): a unit is about 8.5 ns (MERGE_UNITS_PER_INCOMING),
 *  and the merge's symmetric rank-k update runs at about 3 G
 *  multiply-adds per second on the bench's machine (docs/scale.md). */
#define MERGE_EKF_MADDS_PER_UNIT 24.0

/** Candidate pairs kept per map (config.h COSLAM_MERGE_MAX_PAIRS): beyond
 *  it the nearest are kept and the others counted (merge_stats_t.pair_drops).
 *  The one-to-one selection takes pairs nearest first, so every incoming
 *  landmark is paired as with the whole set, but one left unpaired that
 *  lost a candidate: it is marked MERGE_PAIR_LOST, neither fused nor added
 *  (an own landmark inside its gate was not weighed), counted in pair_lost,
 *  and then the pairing bumps the filter's merge_pair_drops (a LIMIT line)
 *  and the merge returns COSLAM_E_CAPACITY. */
#define MERGE_MAX_PAIRS COSLAM_MERGE_MAX_PAIRS
/** match_of_in of an unpaired incoming landmark that lost a candidate pair. */
#define MERGE_PAIR_LOST (-2)

/** Side of the occupancy bitmap over the incoming map's grid cells. */
#define MERGE_OCC_BINS 64

/** Grid hash over a body map plus per-call scratch. Caller-owned. */
typedef struct {
    int32_t bucket_head[COSLAM_MERGE_GRID_BUCKETS];   /**< first entry, -1 empty */
    int32_t next[COSLAM_MAX_MSG_LANDMARKS];            /**< chain */
    int32_t cell_x[COSLAM_MAX_MSG_LANDMARKS];
    int32_t cell_y[COSLAM_MAX_MSG_LANDMARKS];
    /* per-particle / per-filter pairing */
    int32_t match_of_in[COSLAM_MAX_MSG_LANDMARKS];     /**< own landmark index, -1, MERGE_PAIR_LOST */
    uint8_t pair_lost[COSLAM_MAX_MSG_LANDMARKS];       /**< a candidate pair of it was not kept */
    double match_d2[COSLAM_MAX_MSG_LANDMARKS];
    uint8_t drop[COSLAM_MAX_MSG_LANDMARKS];         /**< merge_check: unpaired and refused */
    point2_t world_mean[COSLAM_MAX_MSG_LANDMARKS];
    cov2_t world_cov[COSLAM_MAX_MSG_LANDMARKS];
    /* one own map seen from the robot (per particle for Fast-SLAM) */
    point2_t own_body[COSLAM_MAX_LANDMARKS];
    cov2_t own_cov[COSLAM_MAX_LANDMARKS];
    uint8_t own_sig[COSLAM_MAX_LANDMARKS];
    uint8_t own_used[COSLAM_MAX_LANDMARKS];
    uint16_t own_idx[COSLAM_MAX_LANDMARKS];     /**< Fast-SLAM: own slot of each candidate */
    /* cells (dilated by one) that hold an incoming landmark, in bins of
     * occ_bin cells from (occ_x0, occ_y0): an own landmark outside them
     * has no incoming one in its 3x3 neighbourhood */
    uint64_t occ[MERGE_OCC_BINS];
    int32_t occ_x0;
    int32_t occ_y0;
    int32_t occ_bin;
    merge_pair_t pairs[MERGE_MAX_PAIRS];
    uint32_t new_id[COSLAM_MAX_MSG_LANDMARKS];  /**< identities of added landmarks (shared by particles) */
    double cell_m;                              /**< grid cell edge in use */
    /* EKF-SLAM merge in parts (merge_ekfslam_run): the next incoming
     * landmark, 0..n-1 the duplicates' pass, n..2n-1 the additions' */
    uint32_t ekf_next;
    double ekf_dup_w;
    coslam_status_t ekf_result;
} merge_scratch_t;

typedef struct {
    uint32_t fused;         /**< duplicate pairs fused (summed over particles for Fast-SLAM) */
    uint32_t fused_ci;      /**< of which by covariance intersection */
    uint32_t added;         /**< incoming landmarks added (summed over particles) */
    uint32_t capacity_drops;/**< landmarks that did not fit */
    uint32_t skipped;       /**< incoming landmarks below min_obs or numerically unusable */
    uint32_t pair_drops;    /**< candidate pairs beyond MERGE_MAX_PAIRS (the farthest) */
    uint32_t pair_lost;     /**< the fusion's incoming landmarks neither fused nor added:
                                 unpaired, and a candidate pair of theirs was beyond
                                 MERGE_MAX_PAIRS (summed over particles for Fast-SLAM) */
    /* merge_check */
    uint32_t pairs;         /**< incoming landmarks paired with own ones */
    uint32_t vetoed;        /**< unpaired, where the receiver looked and saw nothing */
    uint32_t echoes;        /**< unpaired, holding the receiver's own information */
    uint32_t ambiguous;     /**< unpaired, next to an unpaired own landmark or unresolved
                                 from another incoming one */
    uint32_t unrefutable;   /**< unpaired, too uncertain for the receiver ever to refute
                                 (refute_sd_factor) */
    uint32_t check_lost;    /**< unpaired, a candidate pair beyond MERGE_MAX_PAIRS: left out
                                 by the check (per landmark, as vetoed) */
    float placed_sd_m;      /**< the smallest relative sd (largest axis) of the own landmarks
                                 paired [m]: the receiver's best-placed one (lost_sd_factor);
                                 0 with no pairs */
    double nis;             /**< joint normalised innovation squared of the pairs */
    double nis_bound;       /**< its chi-square bound (0: no pairs) */
    pose2_t t_shift;        /**< refined transform minus the sightings' one */
} merge_stats_t;

/** Per-robot record of what was merged from whom. */
typedef struct {
    uint32_t last_seq[COSLAM_MAX_ROBOTS];
    uint8_t seen[COSLAM_MAX_ROBOTS];
    /* a run of refused older numbers, each newer than the one before: a
     * sender that restarted without its last number (merge_session_accept) */
    uint32_t run_seq[COSLAM_MAX_ROBOTS]; /**< the run's last number */
    uint8_t run_n[COSLAM_MAX_ROBOTS];    /**< its length (0: none) */
    uint32_t merges;            /**< numbers accepted (the meeting takes them before it merges) */
    uint32_t rejected_replays;  /**< not newer than the last merged number */
    uint32_t rejected_jumps;    /**< newer by more than MERGE_SEQ_MAX_JUMP */
    uint32_t rebased;           /**< senders taken as restarted (MERGE_SEQ_REBASE_RUN) */
} merge_session_t;

/** Largest forward step of a sender's sequence number between two merges.
 *  A robot numbers every message it sends (to any peer, a few per meeting),
 *  so 65536 covers hours of meetings; one forged or faulty number near
 *  last + 2^31 would otherwise make every later genuine message a replay. */
#define MERGE_SEQ_MAX_JUMP 65536U

/** A sender that restarted without its snapshot numbers from 1 again, below
 *  what the receiver remembers; every message would be a replay until it
 *  passed its old number (for the rest of a mission, at a few a meeting).
 *  This many refused older numbers in a row, each newer than the one before
 *  by at most MERGE_SEQ_MAX_JUMP, with no accepted one between, the last of
 *  them more than MERGE_SEQ_REBASE_MIN_BEHIND below the remembered number,
 *  take the sender as restarted: the last of them is accepted and the
 *  window starts there (counted in rebased). A genuine message replayed
 *  again and again never makes such a run, and late messages overtaken by
 *  a newer one are a few numbers behind it, not 64 (a robot sends a few
 *  messages a second at most); three old genuine messages replayed in
 *  order would, which the link's authentication refuses
 *  (docs/security.md) and which, without it, is no more than a forged
 *  message with a new number can do. A restarted sender less than that far
 *  behind passes its old number within a few messages anyway. */
#define MERGE_SEQ_REBASE_RUN 3U
#define MERGE_SEQ_REBASE_MIN_BEHIND 64U

void merge_session_init(merge_session_t *s);

/**
 * Accept a message from `sender` with sequence `seq` only if newer than the
 * last merged one (serial-number arithmetic, so the counter may wrap) by at
 * most MERGE_SEQ_MAX_JUMP, or if it completes a restarted sender's run
 * (MERGE_SEQ_REBASE_RUN). Returns COSLAM_OK (and records it),
 * COSLAM_E_MERGE_REPLAY (counted in rejected_replays, or in rejected_jumps
 * for a jump: the window does not move) or COSLAM_E_ARG. Call after the merge succeeded - or before, and accept that
 * a failed merge consumes the number.
 */
coslam_status_t merge_session_accept(merge_session_t *s, uint8_t sender, uint32_t seq);

/**
 * Step 1. The other robot's pose in self's body frame from the two mutual
 * sightings (geometry in the header comment) and its covariance by first-
 * order propagation of the four measurement variances. E_NUMERIC for
 * non-finite input, E_ARG for non-positive variances or ranges.
 */
coslam_status_t merge_relative_pose(const robot_sighting_t *self_sees_other, const robot_sighting_t *other_sees_self,
                                    pose2_t *other_in_self, cov3_t *cov);

/**
 * Move a relative pose estimated at self's sighting time to now, given
 * self's own motion since then (odometry increment u with covariance
 * u_cov): other_in_self_now = u^-1 (+) other_in_self, covariance through
 * the Jacobians. If the other robot may also have moved, pass its bound as
 * extra_var_m2 (added to x and y) or refuse the merge upstream.
 */
void merge_compensate(pose2_t *other_in_self, cov3_t *cov, odo_increment_t u, const cov3_t *u_cov,
                      double extra_var_m2);

/**
 * Step 2. Transform the incoming map estimate into self's body frame:
 * each landmark's position relative to the sender (from the sender's pose
 * and landmark means) is moved by other_in_self; its covariance is
 * R cov_rel R^T (+ J_T t_cov J_T^T when transform_uncertainty is set).
 * Landmarks below min_obs are skipped (counted in stats).
 * O(M). E_MSG_COVARIANCE if a resulting covariance is not PD,
 * E_MERGE_IMPLAUSIBLE if one has an axis above cfg->max_var_m2 (out->n is
 * then 0).
 */
coslam_status_t merge_transform_map(const map_estimate_t *in, pose2_t other_in_self, const cov3_t *t_cov,
                                    const merge_config_t *cfg, merge_body_map_t *out, merge_stats_t *stats);

/**
 * Step 3-4 for Fast-SLAM: into every particle. O(N (M_own + M_in)).
 * Returns E_CAPACITY (counted in stats and in the filter's counters) if some
 * particle's map could not hold every new landmark; the rest is merged.
 * The same as merge_fastslam_begin, then merge_fastslam_run without a
 * budget.
 */
coslam_status_t merge_into_fastslam(fastslam_t *fs, const merge_body_map_t *bm, const merge_config_t *cfg,
                                    merge_scratch_t *sc, merge_stats_t *stats);

/**
 * A merge into Fast-SLAM in parts, so that no one call of a large one
 * (1,000 particles, a thousand landmarks: tens of ms) takes a control
 * step's time: merge_fastslam_begin gives the incoming landmarks their
 * identities, builds the grid over them in sc, and marks every particle
 * due at its present pose (fastslam_particle_t.merge_pose), or at at[k]
 * if `at` is not NULL: the poses the particles had when the incoming map
 * was put in the body frame, if the filter has run since (the merge path
 * does so when its check waited for an export in parts,
 * fastslam_export_begin: the export's job_pose; the particles must not
 * have been resampled since).
 * merge_fastslam_run then fuses into the particles still due, in index
 * order, until `budget` work units are spent (a particle costs one unit
 * per own landmark and MERGE_UNITS_PER_INCOMING per incoming one; the
 * particle that crosses the budget is finished; 0: no budget), and
 * returns how many are left in *left.
 * Each particle is merged through merge_pose, so the steps the filter runs
 * in between (its predictions and updates) do not move where the incoming
 * map lands; the filter holds resampling back while a particle is due
 * (fastslam_reweighted), so every particle is merged exactly once. With no
 * step in between, the parts give the whole merge bit for bit. bm, cfg and
 * sc must stay as they are until *left is 0 (nothing else may use sc).
 * Re-weighting (cfg->reweight_particles) is done when the last particle is.
 */
coslam_status_t merge_fastslam_begin(fastslam_t *fs, const merge_body_map_t *bm, const merge_config_t *cfg,
                                     merge_scratch_t *sc, const pose2_t *at);
coslam_status_t merge_fastslam_run(fastslam_t *fs, const merge_body_map_t *bm, const merge_config_t *cfg,
                                   merge_scratch_t *sc, merge_stats_t *stats, uint32_t budget, uint16_t *left);

/**
 * Step 3-4 for EKF-SLAM, as one batch: the transform error joins the
 * state for the duration of the merge (ekfslam_merge_begin), every
 * duplicate is an EKF update of "own landmark j relative to the robot =
 * the incoming landmark moved by T", every new landmark is appended with
 * its cross-covariances to the pose, T and the rest, and T's error is
 * marginalised out at the end. Duplicates of overlapping provenance get
 * their noise scaled by 1/(1-w), w the covariance-intersection weight of
 * the two relative marginals (w -> 1: nothing new, no update).
 * O(M_in D^2).
 */
coslam_status_t merge_into_ekfslam(ekfslam_t *ekf, const merge_body_map_t *bm, const merge_config_t *cfg,
                                   merge_scratch_t *scratch, merge_stats_t *stats);

/**
 * The same in parts, so that no one call of a large merge (a message of
 * 221 landmarks into 1,024: 130-190 ms at once) takes a control step's
 * time. merge_ekfslam_begin completes the compressed EKF (ekfslam_sync),
 * pairs the maps and appends the transform's error to the state
 * (ekfslam_merge_begin); merge_ekfslam_run fuses the duplicates, then
 * appends the new landmarks, until about `budget` work units are spent
 * (MERGE_EKF_MADDS_PER_UNIT multiply-adds each; the item or tile of rows
 * that crosses it is finished; 0: no budget), and sets *done when the
 * merge has ended (ekfslam_merge_end). Each call returns the merge's
 * status so far: COSLAM_E_CAPACITY from the call in which a landmark was
 * first left out (the state full, or MERGE_PAIR_LOST at the begin) on.
 * The pending updates' columns are applied in tiles of rows
 * (ekfslam_merge_flush_run) before an update that could fill them and
 * before the first addition, whatever the budget: the parts are the whole
 * merge (merge_into_ekfslam) bit for bit.
 * Unlike Fast-SLAM's, the filter cannot run in between: its predictions
 * and updates are refused (COSLAM_E_MERGE_BUSY) until *done; the robot's
 * merge path (slam_filter) holds them and applies them after, in order.
 * bm and sc must stay as they are until *done.
 */
coslam_status_t merge_ekfslam_begin(ekfslam_t *ekf, const merge_body_map_t *bm, const merge_config_t *cfg,
                                    merge_scratch_t *sc, merge_stats_t *stats);
coslam_status_t merge_ekfslam_run(ekfslam_t *ekf, const merge_body_map_t *bm, merge_scratch_t *sc,
                                  merge_stats_t *stats, uint32_t budget, int *done);

/* ---- one merge set-up for every caller (robot, replay, simulator) ----- */

/** What the receiver knows about a meeting besides the two maps. */
typedef struct {
    robot_sighting_t self_sees_other;  /**< own sighting of the sender (own body frame) */
    robot_sighting_t other_sees_self;  /**< the sender's sighting of self (from its message) */
    odo_increment_t own_motion;        /**< own odometry from own sighting to now */
    double own_travel_m;               /**< wheel travel over own_motion [m], >= 0 */
    double sighting_dt_s;              /**< |own sighting time - sender's sighting time| [s] */
} merge_geometry_t;

/**
 * Step 0 alone: 1 if the message's map and the sender's sighting of the
 * receiver (other_sees_self) pass the plausibility bounds of cfg (the
 * header's step 0: extents, covariance axes, sighting variances and
 * range), else 0 (also for a NULL argument). merge_prepare makes this
 * test first; a receiver may make it on arrival, before the message
 * changes anything (meeting.c). O(M).
 */
int merge_message_plausible(const map_estimate_t *in, const robot_sighting_t *other_sees_self,
                            const merge_config_t *cfg);

/**
 * Steps 0-2 in one call, the only set-up any caller uses: the plausibility
 * bounds (COSLAM_E_MERGE_IMPLAUSIBLE, nothing written), the range check
 * (range_check_chi2), merge_relative_pose, merge_compensate with the own
 * odometry (covariance diag(w3 s, w3 s, w4 s) from own_params, s the
 * travel), the sender's possible motion during sighting_dt_s (peer bounds,
 * on x, y and heading), then merge_transform_map. Returns COSLAM_OK,
 * COSLAM_E_MERGE_RANGE, or the status of the failing step. O(M).
 */
coslam_status_t merge_prepare(const map_estimate_t *in, const merge_geometry_t *g, const slam_params_t *own_params,
                              const merge_config_t *cfg, merge_body_map_t *out, merge_stats_t *stats);

/* ---- where the receiver has looked (negative information) ------------- */

/** Keyframes kept; when full, every second one is dropped and the spacing
 *  doubles (so the record spans the whole run at a coarser step). */
#ifndef COSLAM_COVERAGE_KEYFRAMES
#define COSLAM_COVERAGE_KEYFRAMES 256
#endif

/** Poses (map frame) from which the robot looked with a working camera. */
typedef struct {
    pose2_t pose[COSLAM_COVERAGE_KEYFRAMES];
    uint16_t n;
    double step_m;          /**< a new keyframe after this much translation */
    double step_rad;        /**< or this much rotation */
    uint32_t thinned;       /**< times the record was thinned (capacity) */
} merge_coverage_t;

/** Empty record; keyframes every 0.3 m or 15 deg at first. O(1). */
void merge_coverage_init(merge_coverage_t *c);

/** Note that the robot looked from `pose` (map frame) after a camera frame;
 *  kept as a keyframe if far enough from the last one. O(1) (O(K) when it
 *  thins). */
void merge_coverage_note(merge_coverage_t *c, pose2_t pose);

/** Keyframes from which a point (map frame) lies inside the sensor
 *  footprint with the visibility margin of `p` and, if `grid` is not NULL,
 *  in a clear line of sight through the occupancy grid (an obstacle
 *  between hides the point: that look is no evidence). O(K) (O(K * ray)
 *  with a grid). */
uint16_t merge_coverage_looks(const merge_coverage_t *c, const slam_params_t *p, const occ_grid_t *grid, point2_t pt);

/**
 * Check before trust (docs/map-merge.md "Check before trust"). `own` is the
 * receiver's exported map (confirmed landmarks; cov_rel relative to its
 * pose); `bm` the incoming map from merge_prepare. With cfg->check:
 *  1. pair incoming and own landmarks (same signature, gate_chi2, one to
 *     one by distance) and refine the transform by Gauss-Newton on the
 *     pairs with the sightings' transform as prior (refine_iters rounds,
 *     re-pairing each time), so one sighting pair's heading error does not
 *     misplace far landmarks;
 *  2. the receiver lost in its own map: none of the own landmarks paired
 *     placed within lost_sd_factor x merge_refute_sd_m relative to it
 *     refuses the merge (COSLAM_E_MERGE_LOST); then the agreement test:
 *     the pairs' NIS under the refined transform plus the shift's own NIS
 *     against the prior, below the chi-square bound of 2 n_pairs dof
 *     (agree_z);
 *  3. each unpaired incoming landmark: refused if it carries own_id's
 *     provenance bit (an echo of the receiver's own information that the
 *     receiver no longer holds), if an unpaired own landmark is within
 *     ambiguous_chi2 (a failed pairing), if another incoming landmark of
 *     its signature is within unresolved_chi2 on the two relative covariances
 *     (the sender cannot tell them apart), or if coverage (may be NULL) shows
 *     the receiver looked at the spot from veto_looks keyframes, in line of
 *     sight through `grid` if given (negative information);
 *  4. too many contradictions (max_contradict_fraction) refuse the merge.
 * On COSLAM_OK `bm` holds only the landmarks to fuse or add, moved by the
 * refined transform, with the sightings' transform covariance: the pairs'
 * errors are correlated through each robot's pose (the message drops those
 * correlations), so their information on the transform is overcounted and
 * the refinement's posterior is overconfident; the prior is the
 * conservative choice. On COSLAM_E_MERGE_DISAGREE and COSLAM_E_MERGE_LOST
 * nothing may be merged. Figures in stats.
 * `own` is the receiver's whole map (*_export_whole), not the message-sized
 * export: an own landmark left out of the message must still pair, or its
 * incoming duplicate would be taken as new or vetoed.
 * O((M_own + M_in) * refine_iters + M_in * K).
 */
coslam_status_t merge_check(const map_whole_t *own, const merge_coverage_t *coverage, const occ_grid_t *grid,
                            const slam_params_t *own_params, uint8_t own_id, const merge_config_t *cfg, merge_body_map_t *bm, merge_scratch_t *scratch,
                            merge_stats_t *stats);

/** 1 if st is a refusal merge_check made (COSLAM_E_MERGE_DISAGREE,
 *  COSLAM_E_MERGE_LOST): its stats hold the check's figures, the reason. */
int merge_refused_by_check(coslam_status_t st);

/**
 * Paper eqs. 4-5, the Kalman form of fusing two estimates of one point:
 *   K = S_a (S_a + S_b)^-1,  x = a + K (b - a),  S = S_a - K S_a.
 * E_NOT_PD if S_a + S_b is not positive definite. O(1).
 */
coslam_status_t merge_fuse_kalman(point2_t a, cov2_t sa, point2_t b, cov2_t sb, point2_t *x, cov2_t *s);

/**
 * Covariance intersection of two estimates of unknown correlation:
 *   S^-1 = w S_a^-1 + (1 - w) S_b^-1,  x = S (w S_a^-1 a + (1 - w) S_b^-1 b),
 * with w in [0, 1] minimising det(S) (golden-section search). *w_out may be
 * NULL. O(1).
 */
coslam_status_t merge_fuse_ci(point2_t a, cov2_t sa, point2_t b, cov2_t sb, point2_t *x, cov2_t *s, double *w_out);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_MAP_MERGE_H */
