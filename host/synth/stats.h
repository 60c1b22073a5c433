/*
 * stats.h - evaluation helpers for tests and benchmarks: chi-square
 * quantiles for NEES bands, pose NEES, optimal one-to-one landmark matching
 * (Hungarian algorithm) with a gate, map error figures, and map error
 * figures after the best rigid fit (when the map frame is unknown).
 */
#ifndef COSLAM_TEST_STATS_H
#define COSLAM_TEST_STATS_H

#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/map_estimate.h"
#include "coslam/pose2.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Quantile of the chi-square distribution (Wilson-Hilferty; < 1 % error for dof >= 3). */
double chi2_quantile(double p, double dof);

/** Two-sided 95 % band for the average of k NEES values of d dof each. */
void nees_band95(int k, int d, double *lo, double *hi);

/** (e^T P^-1 e) for a pose error (heading wrapped). NaN if P is not PD. */
double nees_pose(pose2_t est, cov3_t cov, pose2_t truth);

/** The two parts of a pose's NEES: position (2 dof, on the 2x2 position
 *  block) and heading (1 dof, on the heading variance). NaN where the block
 *  is not PD. They do not add up to nees_pose (its cross terms). */
void nees_pose_parts(pose2_t est, cov3_t cov, pose2_t truth, double *xy, double *theta);

/** NEES of a landmark estimate. NaN if the covariance is not PD. */
double nees_point(point2_t est, cov2_t cov, point2_t truth);

typedef struct {
    int n_estimated;
    int n_matched;
    int n_spurious;      /**< estimated landmarks with no true landmark within the gate */
    int n_missed;        /**< true landmarks seen >= min_seen times, not matched */
    double rmse_m;       /**< over matched pairs */
    double max_err_m;
    double nees_mean;    /**< mean landmark NEES over matched pairs */
    int match[COSLAM_MAX_LANDMARKS]; /**< true index matched to estimate i, or -1 */
} map_eval_t;

/**
 * Optimal one-to-one matching (minimum total squared distance) between the
 * exported landmarks and the true ones, pairs farther than gate_m rejected.
 * n_seen[j] (may be NULL) is the number of times true landmark j was
 * detected; only those with n_seen >= min_seen count as missed.
 */
void eval_map(const map_estimate_t *est, const point2_t *truth, const int *n_seen, int n_truth, int min_seen,
              double gate_m, map_eval_t *out);

/** eval_map on a whole map (*_export_whole: more landmarks than a message). */
void eval_map_whole(const map_whole_t *est, const point2_t *truth, const int *n_seen, int n_truth, int min_seen,
                   double gate_m, map_eval_t *out);

/** eval_map where an estimate may pair only with a true landmark of its
 *  own signature (truth_sig[j]; NULL: any), the simulator's marker classes. */
void eval_map_signed(const map_estimate_t *est, const point2_t *truth, const uint8_t *truth_sig, const int *n_seen,
                     int n_truth, int min_seen, double gate_m, map_eval_t *out);

/* Search limits of eval_map_rigid (defaults; a test may define its own). */
#ifndef EVAL_RIGID_MAX_STEPS
#define EVAL_RIGID_MAX_STEPS 720        /**< rotation steps of the sweep, at most */
#endif
#ifndef EVAL_RIGID_MAX_CELLS
#define EVAL_RIGID_MAX_CELLS (1L << 18) /**< translation vote cells (2 B each), at most */
#endif
#ifndef EVAL_RIGID_KEEP
#define EVAL_RIGID_KEEP 8               /**< distinct best hypotheses refined */
#endif
#ifndef EVAL_RIGID_ITERATIONS
#define EVAL_RIGID_ITERATIONS 10        /**< match / least-squares rounds per refinement */
#endif
#ifndef EVAL_RIGID_POLISH
#define EVAL_RIGID_POLISH 48            /**< refinements restarted around the best fit, at most */
#endif
#if EVAL_RIGID_MAX_STEPS < 16 || EVAL_RIGID_MAX_CELLS < 16 || EVAL_RIGID_KEEP < 1 || EVAL_RIGID_ITERATIONS < 1 || \
    EVAL_RIGID_POLISH < 0
#error "eval_map_rigid limits: EVAL_RIGID_MAX_STEPS, EVAL_RIGID_MAX_CELLS >= 16, KEEP, ITERATIONS >= 1, POLISH >= 0"
#endif

/**
 * Map error figures after the best rigid fit, for a map whose frame in the
 * truth frame is unknown (no robot ground truth). Finds the rotation and
 * translation (no scale) `fit` that takes the estimate's frame into the
 * truth frame (truth = pose2_apply(fit, estimate)) minimising eval_map's own
 * cost: the sum over estimated landmarks of the squared distance to the
 * true landmark matched one-to-one within gate_m, gate_m^2 for an unmatched
 * one. So the fit matches as many landmarks as it can, unless an extra
 * match would cost nearly a full gate^2 in the others' error (a plain
 * "most matches, then least error" rule let a 3-deg-off fit catch one
 * spurious landmark). Then eval_map runs on the estimate moved by `fit`
 * (means moved, covariances rotated). Correspondences are unknown: the
 * landmarks carry no identity, the estimate may hold many spurious
 * landmarks (duplicates, a merged-in wrong map) and lack real ones.
 *
 * Method (deterministic, no sampling):
 *  1. The finite estimates are centred on their centroid; r = the 90th
 *     percentile of their distances to it (at least gate_m). Only the true
 *     landmarks that can be in the map vote: n_seen > 0 (all if n_seen is
 *     NULL).
 *  2. Rotation sweep (a generalised Hough transform): for each of
 *     S = 2 pi r / gate_m rotations (16..EVAL_RIGID_MAX_STEPS), every
 *     (estimate, true landmark) pair votes for the translation that puts
 *     the rotated estimate on the true landmark, in cells of gate_m / 2.
 *     Near the right rotation the real landmarks' votes pile up in about
 *     one 2 x 2 block (the nearest step leaves a landmark at r within
 *     gate_m / 2 of its place); spurious ones scatter. The EVAL_RIGID_KEEP
 *     blocks with most votes (>= 2), distinct (moving the estimate by
 *     >= gate_m / 2 apart), become hypotheses. Every estimate takes part,
 *     so a map made mostly of spurious landmarks is still fitted by its
 *     real ones.
 *  3. Refinement of each hypothesis on all estimates: one-to-one matching
 *     within the gate (greedy, closest pairs first, then pairwise
 *     exchanges; inside each connected group of candidate pairs of up to
 *     16 estimates and 16 true landmarks, the optimal assignment by
 *     `hungarian` - greedy crosses pairs in tight clusters), then the
 *     least-squares rotation and translation of the matched pairs (2-D
 *     Procrustes without scale: theta = atan2(sum p x q, sum p . q) over
 *     the centred pairs, t = q_bar - R p_bar), repeated up to
 *     EVAL_RIGID_ITERATIONS times until it stops moving.
 *  4. Polish: the matching makes the cost piecewise, so a refinement stops
 *     at the first fixed point; it is restarted from the best fit turned
 *     (about the estimate's centroid) by +-gate_m / (2 r) and moved by
 *     +-gate_m / 2 in x and y, then by half and a quarter of that (at most
 *     EVAL_RIGID_POLISH restarts). The least cost seen wins.
 * Why not pairs: an earlier version drew hypotheses from pairs of
 * estimates vs pairs of true landmarks of equal spacing (sorted spacings),
 * seeded by the most-observed estimates; on MRCLAM Dataset 1 maps with 84
 * of 99 landmarks spurious it missed the best fit, and trying all pairs
 * took 0.7 s per map. On 50 MRCLAM maps (Datasets 1 and 6, both filters,
 * with and without merging, 11-99 landmarks) this one finds the same fit
 * as a brute-force search (1 deg grid x every landmark-to-landmark
 * translation, the best 40 refined with optimal assignment).
 *
 * Cost: O(S (N V + cells)) for the sweep (N estimates, V voting true
 * landmarks; the vote grid is cleared each step), O((K + P) I N T log(N T))
 * for the refinement and polish (T = n_truth, P = EVAL_RIGID_POLISH),
 * then eval_map (Hungarian, O(max(N, T)^3), dominant for large maps).
 * Measured (test_replay_fit, shared 2-core VM, busy): 256 estimated and 50
 * true landmarks in 20 x 15 m with a 0.5 m gate, 13-20 ms in all, about
 * half of it eval_map's Hungarian step; MRCLAM maps of 15-22 landmarks
 * 0.4 ms, of 99 landmarks 2 ms. Memory: heap, O(N T) plus up to EVAL_RIGID_MAX_CELLS vote
 * cells and one map_estimate_t.
 *
 * After the fit, "spurious" means: an estimated landmark that no true
 * landmark matches one-to-one within gate_m once the whole map is moved by
 * the single best rigid transform. The fit absorbs any overall rotation and
 * offset of the map (the unknown start pose, and also a drift common to the
 * whole map, e.g. a heading error made before the first landmark), so the
 * figures measure the map's shape only, and they are optimistic: the fit is
 * chosen to match as much as it can, so a spurious landmark that happens to
 * fall near an unmatched true one counts as matched, the more likely the
 * denser the map. With fewer than 2 finite estimates, fewer than 2 true
 * landmarks, or no fit matching at least 2 landmarks, `fit` is the identity
 * and nothing is matched (every estimate spurious, every true landmark seen
 * >= min_seen times missed).
 *
 * n_seen and min_seen as for eval_map. fit may be NULL.
 * Returns COSLAM_OK; COSLAM_E_ARG (est or out NULL, truth NULL with
 * n_truth > 0, n_truth < 0, gate_m not finite and > 0, n_landmarks above
 * COSLAM_MAX_MSG_LANDMARKS; out is then zeroed if not NULL);
 * COSLAM_E_CAPACITY if the heap is exhausted.
 */
coslam_status_t eval_map_rigid(const map_estimate_t *est, const point2_t *truth, const int *n_seen, int n_truth,
                               int min_seen, double gate_m, pose2_t *fit, map_eval_t *out);

/** eval_map_rigid on a whole map (map_whole_t: more landmarks than a
 *  message). */
coslam_status_t eval_map_rigid_whole(const map_whole_t *est, const point2_t *truth, const int *n_seen, int n_truth,
                                    int min_seen, double gate_m, pose2_t *fit, map_eval_t *out);

/**
 * Minimum-cost assignment for an n x m cost matrix (row-major), n <= m:
 * row_to_col[i] receives the column of row i. O(n^2 m).
 */
void hungarian(const double *cost, int n, int m, int *row_to_col);

/** Components of the candidate graph larger than this (estimates + true
 *  landmarks) are assigned greedily (nearest pairs first) instead of by
 *  the O(k^3) optimal assignment; counted by assign_gated's return. */
#define ASSIGN_GATED_OPT_MAX 256

/**
 * The evaluation's matching: one-to-one pairs (estimate i, true landmark j)
 * with equal signatures (est_sig/truth_sig may be NULL: all equal) and
 * squared distance d2 < gate_m^2: the most pairs, and among those the least
 * sum of d2 (what one square assignment problem with prohibitive costs for
 * non-candidates gives). Solved per connected
 * component of the candidate graph (candidates found through a grid of
 * gate_m cells), so a map of thousands of separated landmarks costs
 * O((n + n_truth) log n_truth) instead of the O((n + n_truth)^3) of one
 * square problem. match[i] = j or -1. Returns the number of components
 * that were too large for the optimal assignment (ASSIGN_GATED_OPT_MAX)
 * and were matched greedily, or -1 when out of memory (match all -1).
 */
int assign_gated(const point2_t *est, const uint8_t *est_sig, int n, const point2_t *truth,
                 const uint8_t *truth_sig, int n_truth, double gate_m, int *match);

#ifdef __cplusplus
}
#endif

#endif
