/*
 * coslam/fastslam.h - Fast-SLAM 1.0 and 2.0 with unknown data association
 * over a static particle pool (Montemerlo et al.; Thrun, Burgard, Fox,
 * "Probabilistic Robotics", ch. 13).
 *
 * Each particle holds a pose and its own map: one 2-D EKF per landmark
 * (landmark.h). Per update and per particle:
 *   1. every landmark near the sensor footprint gets its expected sighting
 *      and innovation covariance;
 *   2. sightings are associated by maximum likelihood inside a chi-square
 *      gate, greedily and with mutual exclusion (two sightings of one update
 *      never claim the same landmark) and only within the same signature;
 *   3. Fast-SLAM 1.0: the particle weight is multiplied by the likelihood of
 *      each matched sighting (p0 for a new landmark), and the matched
 *      landmarks get an EKF update.
 *      Fast-SLAM 2.0: the pose is sampled from the proposal improved by the
 *      matched sightings (the motion Gaussian updated sighting by sighting),
 *      and the weight is the product of the sequential predictive
 *      likelihoods; landmarks are then updated at the sampled pose.
 *   4. unmatched sightings start tentative landmarks (the copies started by
 *      one sighting in different particles share one identity); sightings
 *      in the ambiguity band (see slam_params_t) are dropped;
 *   5. landmarks that should have been seen but were not lose existence
 *      evidence; tentative ones that run out are removed (negative evidence).
 *   Fast-SLAM 2.0 also tries a sighting that would start a landmark against
 *   the old landmarks of its class with the pose drift since their anchors
 *   in the gate, and closes the loop on one it finds (closure_drift_ratio,
 *   fastslam.c "Revisits").
 * Weights are kept in log space; when the effective sample size falls below
 * resample_ess_fraction * N the particles are resampled with the
 * low-variance sampler, in place (no second particle array).
 *
 * Maps are shared between particles (log-time Fast-SLAM, Montemerlo et al.
 * 2002): each particle's map is the root of a balanced tree over its
 * landmark slots in fastslam_t.lm_pool, with copy-on-write and reference
 * counts (lm_tree.h). Resampling copies a root (O(1) per particle plus the
 * release of the maps no longer drawn); updating a landmark copies its path
 * (O(F log_F M)); the sighting's candidates come from the tree's spatial
 * boxes, not a scan of the whole map. A particle's slots and their order are
 * exactly those of the former flat array (removal still moves the last
 * landmark into the hole), so results are bit-identical to it.
 * Read a particle's landmarks with fastslam_particle_lm() or
 * fastslam_particle_landmarks(), change them with fastslam_particle_set().
 *
 * Memory: sizeof(fastslam_t) ~ COSLAM_MAX_PARTICLES * (190 + 90 *
 * COSLAM_MAX_LANDMARKS + 36 * LM_TREE_NODES_PER_MAP) bytes plus
 * O(COSLAM_MAX_SIGHTINGS * COSLAM_MAX_LANDMARKS) scratch; the tree pools are
 * sized for the worst case (no particle shares anything, lm_tree.h), so the
 * tree never runs out unless LM_TREE_MAX_LEAVES / LM_TREE_MAX_NODES are
 * lowered (then COSLAM_E_CAPACITY, counted in tree_capacity_drops). The
 * caller owns it (static storage on the robot); the functions never allocate.
 *
 * Time per update: O(N * (D F K + S * M_near + S^2 + S D F)) for N particles,
 * M landmarks per particle (tree depth D = ceil(log_F M), fan-out F), K
 * landmarks in tree cells within sensor reach, S sightings, M_near landmarks
 * close enough to be sighted; resampling O(N) plus the maps it frees.
 * Prediction: O(N) (O(N * M * D F) if w5 > 0: every landmark changes).
 */
#ifndef COSLAM_FASTSLAM_H
#define COSLAM_FASTSLAM_H

#include <stdint.h>

#include "coslam/config.h"
#include "coslam/cov3.h"
#include "coslam/landmark.h"
#include "coslam/view.h"
#include "coslam/lm_tree.h"
#include "coslam/map_estimate.h"
#include "coslam/motion.h"
#include "coslam/rng.h"
#include "coslam/slam_params.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    FASTSLAM_PROPOSAL_MOTION = 1,   /**< Fast-SLAM 1.0 */
    FASTSLAM_PROPOSAL_OPTIMAL = 2,  /**< Fast-SLAM 2.0 */
} fastslam_proposal_t;

typedef struct {
    slam_params_t slam;
    uint16_t n_particles;           /**< 1 .. COSLAM_MAX_PARTICLES */
    fastslam_proposal_t proposal;
    double resample_ess_fraction;   /**< resample when ESS < this * N, in (0, 1] */
    double export_min_weight;       /**< export a landmark held (confirmed) by at
                                         least this weight fraction, in (0, 1] */
    uint8_t robot_id;               /**< own provenance bit, < COSLAM_MAX_ROBOTS */
    /** Revisits (Fast-SLAM 2.0; fastslam.c "Revisits"): a sighting that
     *  would start a landmark is tried against the old landmarks of its
     *  class with the pose drift since each one's anchor in the gate
     *  (marginal.h), if that drift adds more than this many times the
     *  sighting's own innovation covariance (trace of (Hp D Hp^T) S^-1);
     *  a pairing found so closes the loop: the pose is corrected by the
     *  drift's Kalman estimate and every landmark of the particle moves by
     *  its anchor's share of it. Only landmarks of the robot's own
     *  sightings, and none after the first merge (fastslam_t.merges). 0:
     *  off. Default 4, chosen on the long-loop world's seeds 1-10 and
     *  201-230 (docs/consistency.md section 3). */
    double closure_drift_ratio;
    /** ... only for landmarks not sighted for more than this many updates
     *  (as EKF-SLAM's jcbb_closure_gap). Default 25 (5 s at 5 Hz). */
    uint16_t closure_gap;
    /** ... and only if no other such landmark explains the sighting within
     *  this log-likelihood (ln 10 = 2.3, the default: 10:1). >= 0. */
    double closure_ambiguity_ll;
    /** A revisit is supported by its frame when, from the pose its closure
     *  would give (every own landmark moved as the closure would move it),
     *  a landmark not sighted for closure_gap updates explains at least one
     *  other sighting of the frame (gate_chi2), and the confirmed landmarks
     *  that pose puts certainly in view with no sighting near them, misses
     *  the closure makes, are at most this many per supporting sighting.
     *  Default 2. >= 0 (docs/consistency.md "Revisits the frame supports"). */
    double closure_misses_per_support;
    /** ... support is asked only where a chance pairing is likely: where
     *  the gate widened by the drift (gate_chi2 against the revisit's
     *  S + Hp D Hp^T) holds at least this many of the particle's other
     *  landmarks of the class, counted among those the update's tree query
     *  returned (a count, not a density estimate). Default 1; 0: always. */
    double closure_chance_max;
    /** Particles k with k % N == N - 1 close an unsupported revisit anyway;
     *  the others start a landmark and wait for support, and the weights
     *  choose between the two. The split is by index only: resampling
     *  (in place) leaves a particle drawn more than once in its slot and
     *  puts the other copies in the lowest free slots, not at neighbouring
     *  indices, so with N = 2 (the default) about half the particles close
     *  but a family of copies is split only by chance (measured: 60 % of
     *  families of two or more, 53 % of pairs). 1: every particle closes,
     *  the check is off; 0: none does. */
    uint16_t closure_unsupported_every;
} fastslam_config_t;

typedef struct {
    pose2_t pose;          /**< [m, m, rad], map frame */
    cov3_t pending_cov;    /**< Fast-SLAM 2.0: motion covariance accumulated
                                since the pose was last sampled (else zero) */
    cov3_t pose_marg;      /**< conservative marginal covariance of the pose
                                (marginal.h): odometry noise in, sightings of
                                landmarks out by covariance intersection */
    double log_w;          /**< log importance weight, max over particles = 0 */
    uint16_t n_lm;         /**< landmarks: slots 0 .. n_lm-1 of the map */
    lm_tree_idx_t lm_root; /**< the map in fastslam_t.lm_pool (shared, copy-on-write:
                                never write through it, see fastslam_particle_set) */
    pose2_t merge_pose;    /**< the pose when a merge began (map_merge.h, merge_fastslam_begin) */
    uint8_t merge_due;     /**< that merge has not reached this particle yet */
} fastslam_particle_t;

typedef struct {
    uint32_t predictions;
    uint32_t updates;
    uint32_t resamples;
    uint32_t landmarks_added;       /**< counted once per identity */
    uint32_t landmarks_removed;     /**< removals by negative evidence, all particles */
    uint32_t misses_hidden;         /**< landmarks in view not counted as missed because the
                                         view profile (fastslam_set_view) put an obstacle in
                                         front of them, all particles */
    uint64_t view_pairs;            /**< confirmed landmarks a miss would have counted for
                                         certain (in view, not hidden) that a sighting paired,
                                         all particles; with view_misses the rate at which
                                         the map's landmarks are found where expected: the
                                         p_d slam_exist_miss_for_detection asks for */
    uint64_t view_misses;           /**< ... that none paired: certain misses counted */
    uint32_t lm_capacity_drops;     /**< a particle's map was full: sighting not mapped */
    uint32_t sighting_capacity_drops; /**< sightings beyond COSLAM_MAX_SIGHTINGS */
    uint32_t export_capacity_drops; /**< identities or landmarks beyond the export tables */
    uint32_t rejected_sightings;    /**< NaN/Inf, range <= 0 or beyond sighting_max_range_m, abs(bearing) > pi */
    uint32_t rejected_controls;     /**< NaN/Inf odometry, or beyond max_speed_mps / max_turn_radps (slam_filter_predict) */
    uint32_t numeric_faults;        /**< degenerate geometry skipped, weight collapse */
    uint32_t merge_pair_drops;      /**< merge pairings (checks and fusions) that left an incoming
                                         landmark out: candidate pairs beyond COSLAM_MERGE_MAX_PAIRS */
    uint32_t resamples_deferred;    /**< resampling held back while a merge or an export in
                                         parts was due (fastslam_reweighted) */
    uint32_t tree_capacity_drops;   /**< the landmark tree pool ran out (only if
                                         LM_TREE_MAX_* were lowered): change skipped */
    uint32_t closures;              /**< revisits closed by the drift (closure_drift_ratio),
                                         all particles */
    uint32_t closure_moves;         /**< landmark copies moved by those closures */
    uint32_t closures_unsupported;  /**< revisits a particle did not close for want of
                                         support in the frame (closure_misses_per_support);
                                         it started a landmark instead */
} fastslam_counters_t;

/* Scratch for one update; contents are meaningless between calls. */
typedef struct {
    lm_expect_t expect[COSLAM_MAX_LANDMARKS];
    uint8_t near[COSLAM_MAX_LANDMARKS];
    uint8_t matched[COSLAM_MAX_LANDMARKS];
    assoc_pair_t pairs[COSLAM_MAX_SIGHTINGS * COSLAM_MAX_LANDMARKS];
    uint8_t n_near[COSLAM_MAX_SIGHTINGS];
    int32_t assign[COSLAM_MAX_SIGHTINGS];
    uint32_t new_id[COSLAM_MAX_SIGHTINGS];
    double gain[COSLAM_MAX_SIGHTINGS][3][2]; /**< Fast-SLAM 2.0: the proposal's pose gain per sighting */
    uint16_t copies[COSLAM_MAX_PARTICLES];
    double weights[COSLAM_MAX_PARTICLES];
    const landmark_t *view[COSLAM_MAX_LANDMARKS]; /**< one particle's landmarks (tree query) */
    uint16_t view_slot[COSLAM_MAX_LANDMARKS];
    uint16_t near_list[COSLAM_MAX_LANDMARKS];     /**< slots with near[] set, ascending */
} fastslam_scratch_t;

/* Scratch of the map export: identity hash table and accumulators. */
typedef struct {
    uint32_t id[COSLAM_MAX_EXPORT_IDS];     /**< 0 = empty slot */
    double w[COSLAM_MAX_EXPORT_IDS];
    double mx[COSLAM_MAX_EXPORT_IDS];
    double my[COSLAM_MAX_EXPORT_IDS];
    double cxx[COSLAM_MAX_EXPORT_IDS];      /**< mixture of the marginals */
    double cxy[COSLAM_MAX_EXPORT_IDS];
    double cyy[COSLAM_MAX_EXPORT_IDS];
    double rx[COSLAM_MAX_EXPORT_IDS];       /**< relative (body-frame) mean */
    double ry[COSLAM_MAX_EXPORT_IDS];
    double rxx[COSLAM_MAX_EXPORT_IDS];      /**< relative covariance */
    double rxy[COSLAM_MAX_EXPORT_IDS];
    double ryy[COSLAM_MAX_EXPORT_IDS];
    double nobs[COSLAM_MAX_EXPORT_IDS];
    uint16_t src_mask[COSLAM_MAX_EXPORT_IDS];
    uint8_t signature[COSLAM_MAX_EXPORT_IDS];
    double w2[COSLAM_MAX_EXPORT_IDS];       /**< the weight the covariances summed
                                                 (pass 2; pass 1's w unless the
                                                 filter ran between the parts) */
    uint32_t sel[COSLAM_MAX_EXPORT_IDS];    /**< selected slots */
    /* The particles as the export began (fastslam_export_begin), stable
     * until it ends because resampling waits for it: */
    double job_w[COSLAM_MAX_PARTICLES];     /**< normalised weights */
    pose2_t job_pose[COSLAM_MAX_PARTICLES]; /**< poses */
    cov3_t job_marg[COSLAM_MAX_PARTICLES];  /**< pose marginals */
    pose2_t job_est;                        /**< the pose estimate */
    cov3_t job_est_cov;
    coslam_status_t job_result;             /**< COSLAM_E_CAPACITY once the table overflowed */
    uint16_t job_next;                      /**< next particle of the pass */
    uint8_t job_pass;                       /**< 0: no export under way; 1, 2: the passes */
} fastslam_export_scratch_t;

typedef struct {
    fastslam_config_t cfg;
    rng_t rng;
    uint32_t next_id;        /**< next landmark identity (never 0) */
    uint32_t merges;         /**< maps merged in (map_merge.c); revisits
                                  (closure_drift_ratio) stop at the first */
    double last_ess;         /**< effective sample size after the last update */
    uint16_t merge_due_n;    /**< particles a merge in parts has not reached yet
                                  (map_merge.h); no resampling until 0 */
    uint8_t export_due;      /**< an export in parts is under way
                                  (fastslam_export_begin); no resampling until done */
    fastslam_counters_t ctr;
    const view_profile_t *view; /**< the next update's view profile (fastslam_set_view), or NULL */
    fastslam_particle_t particles[COSLAM_MAX_PARTICLES];
    lm_tree_pool_t lm_pool;  /**< every particle's map (lm_tree.h) */
    fastslam_scratch_t scratch;
    fastslam_export_scratch_t export_scratch;
} fastslam_t;

/** Defaults: 100 particles (or COSLAM_MAX_PARTICLES if smaller), Fast-SLAM 1.0,
 *  ESS fraction 0.5, export weight 0.5, robot 0, slam_params_default(). */
fastslam_config_t fastslam_config_default(void);

/**
 * Start the filter at `pose0` (map frame = this pose unless w6/w7 > 0, in
 * which case the particles are drawn around it). Returns COSLAM_E_ARG for an
 * invalid configuration (the state is then unusable). O(N).
 */
coslam_status_t fastslam_init(fastslam_t *fs, const fastslam_config_t *cfg, pose2_t pose0, uint64_t seed);

/**
 * Prediction with one odometry increment (motion.h). Fast-SLAM 1.0 samples
 * every particle's pose; 2.0 moves the proposal mean and accumulates its
 * covariance. Non-finite input returns COSLAM_E_NUMERIC, counted, and
 * changes nothing. COSLAM_E_CAPACITY: the prediction is made, but the
 * landmark tree pool ran out while adding the landmarks' process noise
 * (w5) to some of them (tree_capacity_drops).
 */
coslam_status_t fastslam_predict(fastslam_t *fs, odo_increment_t u);

/**
 * Update with the sightings of one camera frame (n may be 0: a frame with
 * nothing in view still gives negative evidence). Invalid sightings are
 * skipped and counted; sightings beyond COSLAM_MAX_SIGHTINGS are counted
 * and dropped and the call returns COSLAM_E_CAPACITY after processing the
 * rest; a full particle map likewise returns COSLAM_E_CAPACITY. Returns
 * COSLAM_E_NUMERIC if an invalid sighting was skipped, else COSLAM_OK.
 */
coslam_status_t fastslam_update(fastslam_t *fs, const sighting_t *z, int n);

/**
 * The obstacles around the robot for the next update only (view.h; NULL
 * clears it): a landmark the profile hides is not counted as missed
 * (misses_hidden). Without one every miss counts, as before there was a
 * laser. The filter keeps the pointer, not a copy (the default profile's
 * RAM budget): `v` must stay unchanged until the update, which forgets it,
 * so a stale profile is never used.
 */
void fastslam_set_view(fastslam_t *fs, const view_profile_t *v);

/**
 * Pose estimate over the particles: weighted mean (circular mean for the
 * heading); covariance: the bound (cov3_loewner_max) of the particles'
 * mixture covariance (spread plus the Fast-SLAM 2.0 pending covariance) and
 * the mixture of their conservative marginals (pose_marg plus spread), so
 * that it stays honest after resampling has collapsed the spread
 * (marginal.h). O(N).
 */
void fastslam_pose_estimate(const fastslam_t *fs, pose2_t *mean, cov3_t *cov);

/**
 * Export the map estimate (map_estimate.h). Landmarks with the same identity
 * are combined over the particles as a Gaussian mixture, moment matched:
 *   W = sum_k w_k,  mean = sum_k w_k mu_k / W,
 *   cov = sum_k w_k (Sigma_k + (mu_k - mean)(mu_k - mean)^T) / W,
 * over the particles in which the landmark is confirmed; a landmark is
 * exported if W >= export_min_weight, with Sigma_k the landmark's marginal
 * (landmark_marginal: its EKF covariance plus its anchor's pose error,
 * marginal.h), which carries the pose uncertainty that resampling removes
 * from the spread.
 * cov_rel is the mixture of the positions relative to each particle's own
 * pose (R_k^T (mu_k - x_k), with covariance R_k^T C_k R_k, C_k the EKF
 * covariance, plus the pose drift since the anchor,
 * marginal_relative_drift). Landmarks are ordered by identity.
 * Returns COSLAM_E_CAPACITY (counted) if the identity table or the message
 * overflowed, the heaviest landmarks being kept. O(N * M) time.
 */
coslam_status_t fastslam_export(fastslam_t *fs, map_estimate_t *out);

/**
 * fastslam_export into a map_whole_t: up to COSLAM_MAX_LANDMARKS landmarks
 * (the combined map can hold more identities than one particle's map: then
 * the heaviest, the rest counted and COSLAM_E_CAPACITY), for the merge
 * check and the tools. O(N * M).
 */
coslam_status_t fastslam_export_whole(fastslam_t *fs, map_whole_t *out);

/** Work units of an export in parts (fastslam_export_run), in the merge's
 *  units (map_merge.h, merge_config_t.step_units: about 8.5 ns each on the
 *  bench's machine): per landmark visited in pass 1 and in pass 2, and per
 *  particle. From coslam-bench-merge's own-export timing, not from any
 *  accuracy figure. */
#define FASTSLAM_EXPORT_UNITS_PASS1 3U
#define FASTSLAM_EXPORT_UNITS_PASS2 24U
#define FASTSLAM_EXPORT_UNITS_PARTICLE 64U

/**
 * fastslam_export_whole in parts, so that no one call of a large one
 * (1,000 particles x 1,024 landmarks: about 230 ms) takes a control step's
 * time. fastslam_export_begin records every particle's normalised weight,
 * pose and pose marginal and the pose estimate (O(N)); fastslam_export_run
 * visits the particles' maps, pass 1 (weights and means) then pass 2
 * (covariances), particle by particle in index order, until `budget` work
 * units (FASTSLAM_EXPORT_UNITS_*; the particle that crosses the budget is
 * finished, at least one per call; 0: no budget) are spent, sets *spent
 * to the units this call spent, and *done to 1 when the map is in `out`
 * (as fastslam_export_whole's, returned then).
 * Resampling waits until the export is done (fastslam_reweighted), so the
 * particles stay where they are; every landmark is taken relative to the
 * pose and pose marginal its particle had when the export began. With no
 * step in between, the parts give fastslam_export_whole bit for bit. With
 * steps in between, each particle's landmarks are read when its part runs;
 * the covariances are normalised by the weight pass 2 found, so a landmark
 * a step removed from every particle between the passes is left out, not
 * exported with a zero covariance. While an export is under way,
 * fastslam_export, fastslam_export_whole and a second begin return
 * COSLAM_E_MERGE_BUSY; fastslam_export_abort drops it (O(1)).
 */
coslam_status_t fastslam_export_begin(fastslam_t *fs);
coslam_status_t fastslam_export_run(fastslam_t *fs, map_whole_t *out, uint32_t budget, int *done, uint32_t *spent);
/** The same, ending as fastslam_export (the map a message carries: at most
 *  COSLAM_MAX_MSG_LANDMARKS, the heaviest). */
coslam_status_t fastslam_export_run_msg(fastslam_t *fs, map_estimate_t *out, uint32_t budget, int *done,
                                        uint32_t *spent);
void fastslam_export_abort(fastslam_t *fs);

/** Index of the particle with the largest weight. O(N). */
uint16_t fastslam_best_particle(const fastslam_t *fs);

/**
 * After the log weights changed (an update, a merge that re-weights):
 * normalise them (max = 0), record the ESS in last_ess, and resample if it
 * fell below resample_ess_fraction * N, unless a merge in parts is due
 * (merge_due_n > 0) or an export in parts is under way (export_due):
 * counted in resamples_deferred, resampled at a later update. O(N)
 * (resampling: see fastslam_resample).
 */
void fastslam_reweighted(fastslam_t *fs);

/** Normalised weights w_k (sum 1) into out[0..N-1]. O(N). */
void fastslam_weights(const fastslam_t *fs, double *out);

/**
 * Low-variance resampling now, in place (exposed for tests and for the
 * merge). O(N) map references copied, plus releasing the maps that were
 * not drawn (each node freed once).
 */
void fastslam_resample(fastslam_t *fs);

/**
 * Add a landmark to particle k's map (slot n_lm; used by the map merge).
 * Returns COSLAM_E_CAPACITY (counted) if the map is full (lm_capacity_drops)
 * or the tree pool ran out (tree_capacity_drops). O(F log_F M).
 */
coslam_status_t fastslam_particle_add(fastslam_t *fs, uint16_t k, const landmark_t *lm);

/** Landmark j (< n_lm) of particle k, read-only; valid until the filter
 *  changes. O(log_F M). */
const landmark_t *fastslam_particle_lm(const fastslam_t *fs, uint16_t k, uint16_t j);

/**
 * All landmarks of particle k in slot order (n_lm of them), read-only, in
 * fs->scratch: valid until the next call into the filter. O(M).
 */
const landmark_t *const *fastslam_particle_landmarks(fastslam_t *fs, uint16_t k);

/**
 * Particle k's landmarks in slot order but for whole subtrees of its map
 * whose box may_hold rejects (lm_tree_select: stale boxes are never
 * tested), read-only, in fs->scratch.view (the caller may reorder or
 * overwrite the array); their slots into slot_out and lm_tree_select's
 * all_out flags into all_out (n_lm entries each, either may be NULL),
 * their count into *n. Valid until the next call into the filter. O(M) at
 * most.
 */
const landmark_t **fastslam_particle_select(fastslam_t *fs, uint16_t k, lm_tree_box_fn may_hold, void *ctx,
                                            uint16_t *slot_out, uint8_t *all_out, uint16_t *n);

/**
 * Replace landmark j (< n_lm) of particle k by *lm (copy-on-write: other
 * particles sharing it keep theirs). COSLAM_E_ARG if j >= n_lm;
 * COSLAM_E_CAPACITY (tree_capacity_drops) if the tree pool ran out.
 * O(F log_F M).
 */
coslam_status_t fastslam_particle_set(fastslam_t *fs, uint16_t k, uint16_t j, const landmark_t *lm);

/** Empty particle k's map (releases its share of the tree). O(freed). */
void fastslam_particle_clear(fastslam_t *fs, uint16_t k);

/** A fresh landmark identity (never 0). */
uint32_t fastslam_new_id(fastslam_t *fs);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_FASTSLAM_H */
