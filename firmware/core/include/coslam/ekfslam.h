/*
 * coslam/ekfslam.h - EKF-SLAM with unknown data association in statically
 * sized arrays (Thrun, Burgard, Fox, "Probabilistic Robotics", ch. 10).
 *
 * State x = (x_r, y_r, theta_r, m_1x, m_1y, ..., m_Lx, m_Ly), size 3 + 2L,
 * covariance P (3 + 2L)^2, both stored with the fixed stride EKFSLAM_DIM so
 * that adding or removing a landmark never moves the other entries.
 *
 * Update, per camera frame:
 *   1. every landmark near the sensor gets its expected sighting and
 *      innovation covariance S = H P H^T + Q (H touches the robot and that
 *      landmark only, so S costs O(1) per landmark);
 *   2. association, same signature only, inside the chi-square gate:
 *      EKFSLAM_ASSOC_NN: Mahalanobis nearest neighbour ranked by likelihood
 *      (a tight landmark beats a vague one at the same distance), greedy with
 *      mutual exclusion;
 *      EKFSLAM_ASSOC_JCBB (default): joint compatibility branch and bound
 *      (Neira and Tardos 2001): the largest set of pairings whose joint
 *      innovation passes the chi-square gate of 2k dof, ties broken by the
 *      smaller joint Mahalanobis distance. Individual NN fails at loop
 *      closure, where the robot's pose error is shared by all sightings of a
 *      frame; JCBB does not. The search is capped at jcbb_max_nodes
 *      (counted when hit; the best hypothesis found so far is used). Among
 *      non-unique landmarks a wrong hypothesis can be jointly compatible
 *      too when the pose is uncertain: if a different hypothesis with as
 *      many pairings is almost as likely (jcbb_ambiguity_d2), only the
 *      pairings both share are used and the other sightings are held back
 *      (neither matched nor new), counted in jcbb_ambiguous;
 *   3. matched sightings are applied one after the other, each relinearised
 *      at the current state, in the symmetric Joseph form computed in
 *      O(D^2) thanks to the sparsity of H;
 *   4. negative evidence as in Fast-SLAM: a tentative landmark that should
 *      have been seen but was not loses evidence and is removed when it runs
 *      out (its rows and columns are deleted);
 *   5. an unmatched sighting outside the ambiguity band starts a landmark,
 *      with its cross-covariances to the whole state: P_mm = G_r P_rr G_r^T +
 *      G_z Q G_z^T + w8 I, P_m* = G_r P_r*.
 *
 * Compressed EKF (active_radius_m > 0, Guivant and Nebot 2001): steps 1-5
 * run on the active part around the robot only, O(N_A^2) per sighting;
 * a global update, O(N_B^2 N_A), brings the rest up to date when the
 * robot leaves its region or a function needs the whole state; its
 * O(N_B^2 N_A) part is spread over the following steps
 * (active_spread_madds) except where something needs the whole state.
 * Results equal the full EKF's up to rounding (test_cekf).
 *
 * Memory: sizeof(ekfslam_t) ~ 8 * EKFSLAM_DIM^2 bytes (137 KB for 64
 * landmarks, 2.1 MB for 256, 34 MB for 1024: the capacity is its own,
 * COSLAM_EKF_MAX_LANDMARKS, config.h). Never allocates.
 * Time: predict O(L); update O(L + S * L_near + S * L^2) for S sightings
 * (compressed: O(L + S * L_near + S * N_A^2) plus the global updates).
 */
#ifndef COSLAM_EKFSLAM_H
#define COSLAM_EKFSLAM_H

#include <stdint.h>

#include "coslam/config.h"
#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/landmark.h"
#include "coslam/map_estimate.h"
#include "coslam/motion.h"
#include "coslam/slam_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest state: pose and COSLAM_EKF_MAX_LANDMARKS landmarks. */
#define EKFSLAM_STATE_MAX (3 + 2 * COSLAM_EKF_MAX_LANDMARKS)
/** Fixed stride of x and P: the state plus 3 entries reserved for the
 *  transform error a map merge carries while it runs (ekfslam_merge_*). */
#define EKFSLAM_DIM (EKFSLAM_STATE_MAX + 3)

typedef enum {
    EKFSLAM_ASSOC_NN = 1,
    EKFSLAM_ASSOC_JCBB = 2,
} ekfslam_assoc_t;

typedef struct {
    slam_params_t slam;
    uint8_t robot_id;          /**< own provenance bit, < COSLAM_MAX_ROBOTS */
    ekfslam_assoc_t assoc;
    uint32_t jcbb_max_nodes;   /**< search budget per update (>= 1) */
    double jcbb_ambiguity_d2;  /**< the best joint hypothesis is ambiguous if another
                                    one with as many pairings has a joint distance
                                    less than this much larger; then only the
                                    pairings they share are used, the other
                                    sightings are held back (no new landmark).
                                    0 disables. Default 9.21 (likelihood ratio
                                    about 100, the 99 % point of 2 dof) */
    double jcbb_single_closure_d2; /**< a loop-closing pairing in a frame where it is
                                    the only sighting with candidates must beat
                                    "no pairing" (a new landmark) by this much
                                    (twice the log-likelihood ratio), else it is
                                    held back. With two or more such sightings the
                                    margin is jcbb_ambiguity_d2. One sighting cannot
                                    beat a new landmark by 100:1 once the pose is
                                    0.5 m uncertain, and one that beats it by 1.3:1
                                    turned robots 20 deg the wrong way
                                    (docs/consistency.md, "The arena world").
                                    Default 4.61 (likelihood ratio 10, the 90 %
                                    point of 2 dof); 0 <= it <= jcbb_ambiguity_d2 */
    uint32_t jcbb_min_closure_pairs; /**< a hypothesis with loop-closing pairings
                                    (robot-landmark uncertainty well above the
                                    sensor's) needs at least this many of them;
                                    with fewer, those sightings are held back.
                                    Default 1 (>= 1; 1 = plain JCBB) */
    uint32_t jcbb_closure_gap;  /**< a pairing is loop-closing if its landmark was
                                    last sighted more than this many updates ago
                                    and det S > 4 det Q. Default 25 (5 s at 5 Hz) */
    double jcbb_closure_max_spread; /**< a pairing whose robot-landmark offset
                                    standard deviation (largest axis) exceeds
                                    this fraction of the range is held back: its
                                    linearisation fails (the bearing's Jacobian
                                    changes by about that fraction over the
                                    uncertainty). Mostly a loop closure
                                    (jcbb_closures_nonlinear); any pairing
                                    once the pose block has lost its landmarks
                                    (pairs_nonlinear). Default 0.7, chosen on
                                    MRCLAM Dataset 6 (docs/consistency.md); > 0 */
    /** First-estimates Jacobians (Huang, Mourikis, Roumeliotis 2008): the
     *  propagation Jacobian uses the previous *predicted* pose and the
     *  measurement Jacobians the predicted pose and each landmark's first
     *  estimate, so that the linearised system keeps the unobservable
     *  directions of SLAM (global position and heading) unobservable. The
     *  standard EKF gains spurious heading information and becomes
     *  overconfident over a loop; FEJ removes most of that. */
    uint8_t fej;
    /** Iterated EKF for revisits: a loop-closing pairing (jcbb_closure_gap)
     *  whose offset spread s / r (jcbb_closure_max_spread) exceeds
     *  bearing_sd^(1/2) (where the bearing's second-order term, about
     *  (s / r)^2, reaches one bearing standard deviation) is relinearised
     *  at the updated estimate up to this many times (Gauss-Newton on the
     *  update's cost, ending at its MAP), instead of one step along the
     *  prior's tangent. Default 0: off; on MRCLAM it helped the merging
     *  robots and hurt one robot alone, and changed nothing on the
     *  synthetic worlds (docs/consistency.md). */
    uint8_t iekf_max_iters;
    /** Innovation monitor (ekfslam.c "Innovation monitor"): the frame's
     *  normalised innovation per degree of freedom (sum of the paired
     *  sightings' d^2 over 2 per sighting), averaged over frames with
     *  weight 0.2; above this threshold the pose block of P is scaled by
     *  average / threshold (at most 4x per frame), as process noise. 0:
     *  off; below about 2 it trips on a consistent filter. Default 3: the
     *  99.99 % point of that average for a consistent filter with one
     *  sighting per frame (more sightings give a lower point), so a
     *  consistent filter almost never trips it. */
    double nis_inflate;
    /** Compressed EKF (Guivant and Nebot 2001; ekfslam.c "Compressed
     *  EKF"): while the robot stays within this distance of where its
     *  local region was chosen, predictions and updates touch only the
     *  active part (pose and the landmarks that can come into reach) and
     *  auxiliary matrices, O(N_A^2) per sighting whatever the map size; a
     *  global update, exact, brings the rest up to date when the robot
     *  leaves, or when something needs the whole state. 0: off, the full
     *  EKF bit for bit. > 0 needs COSLAM_EKF_MAX_ACTIVE > 0 (config.h).
     *  Default 0, except 3 m in a profile with COSLAM_EKF_MAX_ACTIVE >=
     *  128 (the host profile; docs/core-slam.md "Compressed EKF"). */
    double active_radius_m;
    /** The compression starts only with at least this many landmarks in
     *  the state (below, the full update is as cheap). Default 128. */
    uint16_t active_min_landmarks;
    /** Compressed EKF: the global update that ends a local phase (the
     *  robot left its region, or a removal) does at once only x_B and the
     *  pose's rows, O(N_B N_A), and leaves the rest (P_AB = phi P_A0B and
     *  P_BB -= P_BA0 psi P_A0B) pending; the next local phase completes
     *  the entries between its own active landmarks when it starts, and
     *  each later predict and update completes about this many
     *  multiply-adds per generation with pending entries (whole landmark
     *  rows, at least one, the active landmarks' first); whatever reads or
     *  rewrites pending entries completes them first (ekfslam.c "The
     *  deferred part of a global update"). 0: the whole global update at
     *  once, as before. Default 8,000,000 (1.5-3 ms on a desktop core; at
     *  800 landmarks the pending entries then end within the next local
     *  phase). */
    uint32_t active_spread_madds;
    /** A map merge's scalar updates kept pending and applied to P together
     *  (ekfslam.c "A merge's updates together"), at most; fewer where the
     *  compressed EKF's phi buffer, which holds them, is smaller than this
     *  many columns of the state. 1 (or a profile without the compressed
     *  EKF): each at once. Equal up to rounding. Default 128. */
    uint16_t merge_batch;
    /** Revisits kept as two hypotheses (ekfslam.c "Revisits as two
     *  hypotheses"; docs/consistency.md): a frame that applies a
     *  loop-closing pairing, with at least mh_min_sightings sightings that
     *  had candidates, forks the filter into the one that closes (kept
     *  running) and one in which no loop-closing pairing is allowed (its
     *  sightings start landmarks), in the storage given by ekfslam_set_alt.
     *  Both run on the same inputs for mh_frames updates; then the one
     *  whose best readings of those frames (JCBB's log-likelihood, a
     *  sighting without candidates scored as a new landmark) sum higher is
     *  kept. 0, or no storage given: off. Default 50 (10 s at 5 Hz). */
    uint32_t mh_frames;
    /** Sightings with candidates a closing frame needs to fork. With one to
     *  five a frame (MRCLAM's regime, the arena world) the comparison is
     *  decided by which map is locally fresher, not by the revisit, and it
     *  made more copies than it saved; the large world's closing frames
     *  have 11-22. Default 8; >= 1. */
    uint32_t mh_min_sightings;
} ekfslam_config_t;

/** Per-landmark bookkeeping beside the state (same meaning as in landmark_t). */
typedef struct {
    uint32_t id;
    float exist;
    uint16_t n_obs;
    uint16_t src_mask;
    uint8_t signature;
    uint32_t last_seen;   /**< ctr.updates when last sighted (or added) */
} ekfslam_meta_t;

typedef struct {
    uint32_t predictions;
    uint32_t updates;
    uint32_t landmarks_added;
    uint32_t landmarks_removed;
    uint32_t removals_deferred;       /**< ... of those, decided in a compressed EKF's local phase:
                                           dead at once (no association, miss or export reads
                                           them), out of the state when the phase ends
                                           (ekfslam_landmark_live) */
    uint32_t misses_hidden;           /**< landmarks in view not counted as missed because the
                                           view profile (ekfslam_set_view) put an obstacle in
                                           front of them */
    uint32_t misses_held;             /**< landmarks in view not counted as missed because a
                                           sighting held back as a possible revisit of them
                                           (a loop-closing candidate of it) was in the frame */
    uint64_t view_pairs;              /**< confirmed landmarks a miss would have counted for
                                           certain (in view, not hidden) that a sighting
                                           paired (fastslam_counters_t.view_pairs) */
    uint64_t view_misses;             /**< ... that none paired: certain misses counted */
    uint32_t lm_capacity_drops;       /**< state full: sighting not mapped */
    uint32_t sighting_capacity_drops; /**< sightings beyond COSLAM_MAX_SIGHTINGS */
    uint32_t export_capacity_drops;
    uint32_t rejected_sightings;
    uint32_t rejected_controls;
    uint32_t numeric_faults;          /**< update skipped: S not PD, degenerate geometry */
    uint32_t merge_pair_drops;        /**< merge pairings (checks and fusions) that left an incoming
                                           landmark out: candidate pairs beyond COSLAM_MERGE_MAX_PAIRS */
    uint32_t jcbb_budget_hits;        /**< JCBB searches cut at jcbb_max_nodes */
    uint32_t jcbb_ambiguous;          /**< frames whose best hypothesis was ambiguous */
    uint32_t jcbb_closures_held;      /**< frames with a loop closure of too few pairings */
    uint32_t jcbb_closures_nonlinear; /**< frames with a loop closure held back as too nonlinear */
    uint32_t pairs_nonlinear;         /**< frames with another pairing held back as too nonlinear
                                           (jcbb_closure_max_spread) */
    uint32_t iekf_updates;            /**< loop-closing pairings applied by the iterated EKF */
    uint32_t iekf_iterations;         /**< their relinearisations, in all */
    uint32_t nis_inflations;          /**< frames whose pose block was inflated (nis_inflate) */
    uint32_t cekf_global_updates;     /**< compressed EKF: local phases ended by a global update */
    uint32_t cekf_active_overflows;   /**< compressed EKF: regions with more than COSLAM_EKF_MAX_ACTIVE
                                           landmarks in reach (that frame used the full update) */
    uint32_t cekf_spread_rows;        /**< compressed EKF: landmark rows of a global update's P_BB
                                           completed later, a budget per step (active_spread_madds) */
    uint32_t cekf_spread_forced;      /**< compressed EKF: times pending entries had to be completed
                                           at once (sync, export, a full-EKF frame, the active rows left
                                           when a phase ends, a full set of generations) */
    uint32_t cekf_spread_gens_full;   /**< compressed EKF: global updates that found all
                                           EKFSLAM_PEND_GENS generations pending and completed the oldest
                                           at once */
    uint32_t mh_forks;                /**< revisits kept as two hypotheses (mh_frames) */
    uint32_t mh_reverted;             /**< ... decided for the one without the revisit: the state
                                           went back to it (the counters do not: they count what this
                                           filter did, reverted or not) */
    uint32_t mh_decided_early;        /**< ... decided before mh_frames updates: a merge or a
                                           landmark added or removed from outside came first */
} ekfslam_counters_t;

/** Largest joint innovation handled by JCBB (2 rows per sighting). */
#define EKFSLAM_JCBB_DIM (2 * COSLAM_MAX_SIGHTINGS)
/** Candidate landmarks whose cross blocks JCBB keeps once computed (an
 *  update with more computes them at every use). */
#define EKFSLAM_JCBB_CROSS COSLAM_MAX_SIGHTINGS

typedef struct {
    lm_expect_t expect[COSLAM_EKF_MAX_LANDMARKS];
    uint8_t near[COSLAM_EKF_MAX_LANDMARKS];
    uint8_t matched[COSLAM_EKF_MAX_LANDMARKS];
    uint8_t closure[COSLAM_EKF_MAX_LANDMARKS];      /**< candidate is loop-closing (valid for paired landmarks) */
    assoc_pair_t pairs[COSLAM_MAX_SIGHTINGS * COSLAM_EKF_MAX_LANDMARKS];
    uint8_t n_near[COSLAM_MAX_SIGHTINGS];
    int32_t assign[COSLAM_MAX_SIGHTINGS];
    /* JCBB search state */
    int32_t cand_begin[COSLAM_MAX_SIGHTINGS + 1]; /**< candidates of sighting i: pairs[begin[i] .. begin[i+1]) */
    int32_t hyp[COSLAM_MAX_SIGHTINGS];
    int32_t hyp_pair[COSLAM_MAX_SIGHTINGS];       /**< pair index of the k-th pairing */
    int32_t hyp_pi[COSLAM_MAX_SIGHTINGS];         /**< pair index of sighting i's pairing (valid if hyp[i] >= 0) */
    double chol[EKFSLAM_JCBB_DIM][EKFSLAM_JCBB_DIM]; /**< Cholesky factor of the joint S */
    double y[EKFSLAM_JCBB_DIM];                   /**< L^-1 nu */
    double chi2_joint[COSLAM_MAX_SIGHTINGS + 1];
    int32_t best[COSLAM_MAX_SIGHTINGS];
    int best_pairings;
    double best_score;                            /**< joint log-likelihood (see ekfslam.c) */
    int32_t second[COSLAM_MAX_SIGHTINGS];         /**< the runner-up hypothesis */
    int second_pairings;
    double second_score;
    uint8_t held[COSLAM_MAX_SIGHTINGS];           /**< sighting held back: 1 as a possible
                                                       revisit (ambiguous, or its loop-closing
                                                       pairing nonlinear), 2 its other pairing
                                                       nonlinear (the pose has lost its landmarks) */
    uint32_t closures_short;                      /**< leaves refused: too few closure pairings */
    uint32_t pass;                                /**< 0: find the best; 1: the alternatives */
    double alt_other[COSLAM_MAX_SIGHTINGS];       /**< best score found pairing sighting i elsewhere */
    double alt_none[COSLAM_MAX_SIGHTINGS];        /**< best score found leaving sighting i unpaired */
    uint8_t need_alt[COSLAM_MAX_SIGHTINGS];       /**< pass 1: sighting i's best pairing closes a loop and no
                                                       alternative within the margin is found yet */
    int n_need_alt;                               /**< pass 1: sightings with need_alt set */
    double margin_other;                          /**< pass 1: an alternative pairing within this of the best
                                                       holds the sighting back */
    double margin_none;                           /**< pass 1: "unpaired" within this of the best holds it */
    double ub_rest[COSLAM_MAX_SIGHTINGS + 1];     /**< bound of the score of sightings i.. */
    uint32_t nodes;
    /** H_b P H_a^T of candidate landmarks b, a (their cross_ix), filled
     *  as the search asks; valid where cross_ok */
    double cross[EKFSLAM_JCBB_CROSS][EKFSLAM_JCBB_CROSS][2][2];
    uint8_t cross_ok[EKFSLAM_JCBB_CROSS][EKFSLAM_JCBB_CROSS];
    int16_t cross_ix[COSLAM_EKF_MAX_LANDMARKS];   /**< landmark's row in cross, -1 none (valid for
                                                       paired landmarks) */
    int cross_n;                                  /**< landmarks in the table (0: too many) */
    double pht[EKFSLAM_DIM][2];
    double k[EKFSLAM_DIM][2];
    uint16_t order[COSLAM_EKF_MAX_LANDMARKS];
} ekfslam_scratch_t;

/** Active states of the compressed EKF at most: the pose and COSLAM_EKF_MAX_ACTIVE landmarks. */
#define EKFSLAM_ACTIVE_DIM (3 + 2 * COSLAM_EKF_MAX_ACTIVE)
#define EKFSLAM_SYNC_BLOCK 8
/** Pairings of one frame applied to the compressed EKF's active part in one
 *  pass (ekfslam.c "One pass for a frame's pairings"); more are applied in
 *  passes of this many. 4 EKFSLAM_ACTIVE_DIM doubles each: 264 KB in the host
 *  profile, 67 KB in the large one, nothing where there is no active part. */
#define EKFSLAM_BATCH (COSLAM_EKF_MAX_ACTIVE > 0 ? 8 : 1)
/** Landmarks the deferred part of a global update keeps (1 where the
 *  compressed EKF is compiled out, so that the profile does not grow). */
#define EKFSLAM_SPREAD_LM (COSLAM_EKF_MAX_ACTIVE > 0 ? COSLAM_EKF_MAX_LANDMARKS : 1)
/** Generations of pending entries (config.h COSLAM_EKF_PEND_GENS). */
#define EKFSLAM_PEND_GENS COSLAM_EKF_PEND_GENS

/** Flag of a landmark in a pending generation: it was passive (B) or
 *  active (A) in the local phase that the generation's global update ended. */
#define EKFSLAM_PEND_B 1U
#define EKFSLAM_PEND_A 2U

/**
 * The deferred part of one global update (ekfslam.c "The deferred part of
 * a global update"). With A0, phi, psi of the phase it ended, the entry
 * (r, c) of P between two flagged landmarks, not both A and (in a local
 * phase) not both active now, is pending: its value is P(r, c) plus
 *   -u_r^T psi u_c    both B (u_r = P_A0,r then)
 *   +u_r^T u_c        r A, c B (u_r = phi_r - e_r then, e_r the unit row of
 *                     r's position in A0, 0 beyond A0: (1) as a correction)
 * and every such correction only adds, so generations overlap.
 */
typedef struct {
    int32_t n;                                /**< flagged landmarks (list) */
    int32_t n_b;                              /**< ... of them B */
    int32_t n0;                               /**< |A0| of the phase it ended */
    uint32_t seq;                             /**< age: larger is younger */
    uint16_t list[EKFSLAM_SPREAD_LM];         /**< the flagged landmarks */
    uint8_t flag[EKFSLAM_SPREAD_LM];          /**< 0, EKFSLAM_PEND_B or EKFSLAM_PEND_A */
    uint8_t drift_on;                         /**< drift_* hold this local phase's sums */
    double psi[EKFSLAM_ACTIVE_DIM * EKFSLAM_ACTIVE_DIM]; /**< that phase's psi, stride EKFSLAM_ACTIVE_DIM */
    double u[2 * EKFSLAM_SPREAD_LM][EKFSLAM_ACTIVE_DIM]; /**< row 2j+q: u of state 3+2j+q */
    /* x_now's share of the pending entries between the active part A0'
     * of the local phase now and a passive landmark: sum_i theta'_i u_i
     * over the flagged A (drift_a) and B (drift_b) states i of A0', and
     * psi drift_b (drift_bpsi) */
    double drift_a[EKFSLAM_ACTIVE_DIM];
    double drift_b[EKFSLAM_ACTIVE_DIM];
    double drift_bpsi[EKFSLAM_ACTIVE_DIM];
} ekfslam_pend_t;

/**
 * Compressed EKF bookkeeping (ekfslam.c "Compressed EKF"). In a local
 * phase the state splits into the active part A (states idx[0 .. na)) and
 * the passive rest B. A0 = idx[0 .. na0) is A at the phase start (landmarks
 * added since are appended). x_A and P_AA are current in x and p; x_B,
 * P_AB and P_BB hold their values at the phase start, and the current ones
 * are P_AB = phi P_A0B, P_BB = P_BB - P_BA0 psi P_A0B + w5_sum I, x_B = x_B
 * + P_BA0 theta. Global updates spread over later steps leave entries of P
 * pending (gen, ekfslam_pend_t).
 */
typedef struct {
    uint8_t local;                            /**< 1 in a local phase */
    uint8_t gain_stale;                       /**< drift_gain not yet computed for this phase */
    int32_t na;                               /**< active states now */
    int32_t na0;                              /**< active states at the phase start */
    point2_t centre;                          /**< robot position at the phase start */
    double w5_sum;                            /**< landmark process noise added since (lm_process_var_m2_per_m) */
    int32_t idx[EKFSLAM_ACTIVE_DIM];          /**< state index of active state k */
    int32_t slot[COSLAM_EKF_MAX_LANDMARKS];   /**< active position of landmark j's x, -1 passive */
    double drift_gain[COSLAM_EKF_MAX_LANDMARKS]; /**< |P_bA0| of passive landmark b (x and y rows);
                                                      < 0: unknown (pending entries), test exactly */
    double phi[EKFSLAM_ACTIVE_DIM * EKFSLAM_ACTIVE_DIM]; /**< na x na0, stride EKFSLAM_ACTIVE_DIM */
    double psi[EKFSLAM_ACTIVE_DIM * EKFSLAM_ACTIVE_DIM]; /**< na0 x na0 */
    double theta[EKFSLAM_ACTIVE_DIM];
    /* a frame's pairings not yet applied to P_AA, phi and psi (ekfslam.c
     * "One pass for a frame's pairings"): columns 2k, 2k + 1 of pairing k */
    int32_t bn;                               /**< pairings pending */
    double bk[2 * EKFSLAM_BATCH][EKFSLAM_ACTIVE_DIM]; /**< K over the active states */
    double bp[2 * EKFSLAM_BATCH][EKFSLAM_ACTIVE_DIM]; /**< P H^T, P before the pairing */
    double bh[2 * EKFSLAM_BATCH][EKFSLAM_ACTIVE_DIM]; /**< H phi over A0, phi before the pairing */
    double bs[2 * EKFSLAM_BATCH][EKFSLAM_ACTIVE_DIM]; /**< S^-1 H phi */
    /* scratch of the global update, in blocks of EKFSLAM_SYNC_BLOCK rows or
     * columns of B (each block reads the rows of A0 once) */
    double u[EKFSLAM_ACTIVE_DIM][EKFSLAM_SYNC_BLOCK];
    double w[EKFSLAM_SYNC_BLOCK][EKFSLAM_ACTIVE_DIM];
    /* the deferred parts of the last global updates (active_spread_madds) */
    uint32_t pend_seq;                        /**< generations made so far */
    double spread_owed;                       /**< multiply-adds of completion owed: an update that
                                                   spent its share on its own pairings leaves it to
                                                   the next predict (cekf_spread) */
    ekfslam_pend_t gen[EKFSLAM_PEND_GENS];
    double pend_w[2][EKFSLAM_ACTIVE_DIM];     /**< scratch: psi u of one landmark */
    uint16_t pend_act[EKFSLAM_SPREAD_LM];     /**< scratch: flagged active landmarks */
} ekfslam_cekf_t;

typedef struct ekfslam_s {
    ekfslam_config_t cfg;
    uint16_t n_lm;
    uint32_t next_id;
    ekfslam_counters_t ctr;
    const view_profile_t *view;              /**< the next update's view profile (ekfslam_set_view), or NULL */
    double x[EKFSLAM_DIM];
    point2_t lm_first[COSLAM_EKF_MAX_LANDMARKS]; /**< first estimate of each landmark (FEJ) */
    uint8_t merging;                         /**< 1 between ekfslam_merge_begin and _end */
    double nis_avg;                          /**< running mean normalised innovation per degree
                                                  of freedom (nis_inflate; kept when off too) */
    pose2_t pose_prior;                      /**< pose after the last prediction (FEJ) */
    double p[EKFSLAM_DIM * EKFSLAM_DIM];   /**< row-major, stride EKFSLAM_DIM */
    ekfslam_meta_t meta[COSLAM_EKF_MAX_LANDMARKS];
    /** 1 once landmark j's evidence was seen at or above exist_confirm
     *  (exist_miss(); like landmark_t.confirmed_once, kept beside meta so
     *  that callers filling an ekfslam_meta_t need not know it) */
    uint8_t lm_confirmed_once[COSLAM_EKF_MAX_LANDMARKS];
    /** 1 for a landmark removed in a local phase of the compressed EKF and
     *  still in the state until a phase ends (ekfslam.c "Removal in a
     *  local phase"; passive in a phase started before they went); n_dead
     *  of them. Set only in a local phase; a full map takes them out to
     *  make room. */
    uint8_t lm_dead[COSLAM_EKF_MAX_LANDMARKS];
    uint16_t n_dead;
    ekfslam_cekf_t cekf;
    ekfslam_scratch_t scratch;
    /** A merge's updates not yet applied to p (ekfslam.c "A merge's updates
     *  together"): P = p - sum_t w_t w_t^T over merge_len active
     *  positions, the columns w_t held in cekf.phi (free while merging: no
     *  local phase then). */
    int32_t merge_bn;
    int32_t merge_len;
    /** A flush of those columns in parts (ekfslam_merge_flush_run): the
     *  active positions below it have them applied; 0: none begun. */
    int32_t merge_flush_r0;
    /** Revisits as two hypotheses (ekfslam_config_t.mh_frames): the other
     *  hypothesis's storage (ekfslam_set_alt), NULL: none. */
    struct ekfslam_s *alt;
    uint32_t mh_left;      /**< updates until the hypotheses are compared; 0: no fork */
    uint8_t mh_forbid;     /**< 1 in the other hypothesis: no loop-closing pairing */
    double mh_sum;         /**< this one's best readings since the fork */
    double mh_sum_alt;     /**< the other's */
    double frame_score;    /**< the last update's best reading (log-likelihood) */
} ekfslam_t;

/** Defaults: slam_params_default(), robot 0, JCBB with a 20000-node budget, FEJ on. */
ekfslam_config_t ekfslam_config_default(void);

/** Start at pose0 with P = diag(w6, w6, w7) and no landmarks. E_ARG on a bad config. O(1). */
coslam_status_t ekfslam_init(ekfslam_t *ekf, const ekfslam_config_t *cfg, pose2_t pose0);

/**
 * Idle time (between control steps), for the compressed EKF: a local phase
 * whose region the robot has left ends here and the next region is
 * selected (what the next update would do), and about `shares` x
 * active_spread_madds multiply-adds of the deferred global updates are
 * completed ahead of their pace, at most two steps' shares ahead (a step's
 * share is active_spread_madds per pending generation); the next predicts
 * and updates then do that much less of it themselves. Changes no number
 * beyond rounding, only when the work is done. A no-op without the
 * compressed EKF.
 */
void ekfslam_idle(ekfslam_t *ekf, uint32_t shares);

/** Storage for the second hypothesis of a revisit (ekfslam_config_t.
 *  mh_frames), owned by the caller, not used for anything else while
 *  `ekf` runs; NULL: revisits are not forked. Call after ekfslam_init
 *  (which forgets it). A fork copies the whole filter into it (sizeof
 *  (ekfslam_t)); while a fork runs, predict, update and idle do the work
 *  twice. */
void ekfslam_set_alt(ekfslam_t *ekf, ekfslam_t *alt);

/** Prediction with an odometry increment. Non-finite: E_NUMERIC, counted, no change. O(L).
 *  Between ekfslam_merge_begin and _end (a merge in parts): E_MERGE_BUSY,
 *  no change (the caller holds its inputs until the merge is done). */
coslam_status_t ekfslam_predict(ekfslam_t *ekf, odo_increment_t u);

/** Update with one camera frame's sightings; return codes as fastslam_update().
 *  E_MERGE_BUSY, no change, while a merge runs (as ekfslam_predict); the
 *  frame's view profile (ekfslam_set_view) is forgotten either way. */
coslam_status_t ekfslam_update(ekfslam_t *ekf, const sighting_t *z, int n);

/** The obstacles around the robot for the next update only; as
 *  fastslam_set_view (a landmark the profile hides is not missed; the
 *  pointer is kept until the update). */
void ekfslam_set_view(ekfslam_t *ekf, const view_profile_t *v);

/** Robot pose and its covariance. O(1). */
void ekfslam_pose(const ekfslam_t *ekf, pose2_t *pose, cov3_t *cov);

/** Landmark j (0 <= j < n_lm): mean and marginal covariance. O(1); O(N_A^2)
 *  for a passive landmark in a local phase of the compressed EKF. */
void ekfslam_landmark(const ekfslam_t *ekf, uint16_t j, point2_t *mean, cov2_t *cov);

/** Mean of landmark j (0 <= j < n_lm). O(1); O(N_A) for a passive landmark
 *  of the compressed EKF. */
point2_t ekfslam_landmark_mean(const ekfslam_t *ekf, uint16_t j);

/** P entry (r, c) of the current state. O(1); in a local phase of the
 *  compressed EKF O(N_A) for an active-passive entry, O(N_A^2) for a
 *  passive-passive one. */
double ekfslam_p(const ekfslam_t *ekf, int r, int c);

/**
 * Compressed EKF: end the local phase with the global update and complete
 * any pending part of an earlier one, so that x and p hold the whole
 * current state (needed before reading or writing them directly). No-op
 * outside a local phase with nothing pending. O(N_B^2 N_A) time (plus
 * what is pending, O(N_pend^2 N_A0) per generation), no memory.
 * ekfslam_export, _export_whole, _merge_begin, _remove_landmark call it.
 */
void ekfslam_sync(ekfslam_t *ekf);

/**
 * ekfslam_sync in parts, for a caller that may not take its time in one
 * step (a merge in parts, map_merge.h): a local phase is ended the way
 * the filter ends one with active_spread_madds > 0 (the global update's
 * P_BB share deferred as pending rows), and the pending rows of every
 * generation are completed until about `budget` multiply-adds are spent
 * (0: all; *spent, may be NULL, adds them). Returns 1 once x and p hold
 * the whole state (as after ekfslam_sync), 0 while rows pend; the caller
 * must not predict or update in between, or a new phase may begin. The
 * same state as ekfslam_sync up to rounding (the deferred form sums in
 * another order). Without active_spread_madds, ekfslam_sync at once.
 */
int ekfslam_sync_run(ekfslam_t *ekf, double budget, double *spent);

/**
 * Export the map estimate: the pose with P_rr and every confirmed landmark
 * with its marginal covariance, ordered by identity. E_CAPACITY (counted
 * in export_capacity_drops) if more confirmed landmarks than
 * COSLAM_MAX_MSG_LANDMARKS: the most observed ones (n_obs) are exported.
 * O(L^2) (insertion sorts; exports are rare), after ekfslam_sync.
 */
coslam_status_t ekfslam_export(ekfslam_t *ekf, map_estimate_t *out);

/**
 * ekfslam_export into a map_whole_t: every confirmed landmark (the state
 * holds at most COSLAM_EKF_MAX_LANDMARKS <= COSLAM_MAX_LANDMARKS), for the
 * merge check and the tools. O(L^2).
 */
coslam_status_t ekfslam_export_whole(ekfslam_t *ekf, map_whole_t *out);

/**
 * Add a landmark at `mean` whose error relative to the robot is Gaussian:
 * mean = pose (+) m_body with m_body having covariance cov_body (robot
 * frame). Cross-covariances with the state follow from the pose part, like
 * a sighting in Cartesian form (used by the map merge). O(L).
 */
coslam_status_t ekfslam_add_landmark_body(ekfslam_t *ekf, point2_t m_body, cov2_t cov_body,
                                          const ekfslam_meta_t *meta);

/**
 * Landmark j relative to the robot, in the robot's body frame:
 * R(theta)^T (m_j - p) and its covariance including the pose-landmark
 * cross-covariance. O(1); O(N_A^2) for a passive landmark in a local phase.
 */
void ekfslam_landmark_relative(const ekfslam_t *ekf, uint16_t j, point2_t *mean_body, cov2_t *cov_body);

/*
 * Map merge as a batch (used by map_merge.c). The incoming landmarks all
 * share the error of the transform T between the robots; treating them as
 * independent observations would count T's information once per
 * landmark. So the merge appends T's error tau ~ N(0, t_cov) (additive on
 * x, y, theta) to the state, processes every incoming landmark against it,
 * and drops it at the end (marginalisation): duplicates and additions keep
 * their correct correlations with T, the pose and each other.
 *   ekfslam_merge_begin: append tau (t_cov NULL: exact transform).
 *   ekfslam_merge_observe: own landmark j and an incoming one are the same
 *     point: R(theta)^T (m_j - p) = (t_hat + tau) (+) rel_other + v, where
 *     v carries the information `info_body` (inverse covariance, receiver's
 *     body frame; it may be singular: only directions with positive
 *     information update the state). For independent estimates info_body =
 *     (R_t noise_other R_t^T)^-1; the merge passes less for covariance
 *     intersection.
 *   ekfslam_merge_add: append the incoming landmark at
 *     p (+) ((t_hat + tau) (+) rel_other) with the matching cross-covariances.
 *   ekfslam_merge_end: drop tau.
 * rel_other and noise_other are in the sender's body frame. Each O(D^2) or O(D).
 */
coslam_status_t ekfslam_merge_begin(ekfslam_t *ekf, const cov3_t *t_cov);
coslam_status_t ekfslam_merge_observe(ekfslam_t *ekf, uint16_t j, pose2_t t_hat, point2_t rel_other, cov2_t info_body);
coslam_status_t ekfslam_merge_add(ekfslam_t *ekf, pose2_t t_hat, point2_t rel_other, cov2_t noise_other,
                                  const ekfslam_meta_t *meta);
void ekfslam_merge_end(ekfslam_t *ekf);

/*
 * A merge's updates in parts (map_merge.c merge_ekfslam_run). Each
 * duplicate direction's update changes x at once and keeps P's change as a
 * pending column; the columns are applied together, a symmetric rank-k
 * update of all of P, O(k D^2) (ekfslam.c "A merge's updates together").
 * ekfslam_merge_room: columns that may still pend before the pending ones
 * must be applied (0 or less: apply first; INT32_MAX where every update is
 * applied at once, profiles without the compressed EKF).
 * ekfslam_merge_flush_run: apply them in tiles of rows until about
 * `budget` multiply-adds are spent (0: all), adding what it spent to
 * *spent (may be NULL); returns 1 when none pend. A flush begun is
 * finished by the next update of the merge, ekfslam_merge_add, _end, or
 * ekfslam_sync; readers in between (ekfslam_pose, ekfslam_p) account for
 * the rows not yet done. Tile by tile it is the whole flush bit for bit.
 */
int ekfslam_merge_room(const ekfslam_t *ekf);
int ekfslam_merge_flush_run(ekfslam_t *ekf, double budget, double *spent);

/** Remove landmark j now, deleting its rows and columns. O(L), after
 *  ekfslam_sync (compressed EKF with active_spread_madds > 0: after the
 *  spread global update, pending entries stay pending). In a local phase
 *  the landmarks the filter's own misses removed go too (they were dead,
 *  ekfslam_landmark_live): indices of other landmarks may change. */
void ekfslam_remove_landmark(ekfslam_t *ekf, uint16_t j);

/** 0 for a landmark the filter removed in a compressed EKF's local phase,
 *  which stays in the state, unread, until the phase ends (a removal does
 *  not end the phase: ekfslam.c "Removal in a local phase"). Readers that
 *  walk the landmarks without ekfslam_sync skip it; exports and merges
 *  never see one (ekfslam_sync takes them out). */
static inline int ekfslam_landmark_live(const ekfslam_t *ekf, uint16_t j)
{
    return ekf->lm_dead[j] == 0U;
}

/** Landmarks in the map: in the state and not dead. */
static inline uint16_t ekfslam_n_landmarks(const ekfslam_t *ekf)
{
    return (uint16_t)(ekf->n_lm - ekf->n_dead);
}

/** A fresh landmark identity (never 0). */
uint32_t ekfslam_new_id(ekfslam_t *ekf);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_EKFSLAM_H */
