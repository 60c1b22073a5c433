/*
 * stats.h - evaluation helpers for tests and benchmarks: chi-square
 * quantiles for NEES bands, pose NEES, optimal one-to-one landmark matching
 * (Hungarian algorithm) with a gate, map error figures.
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
    int match[COSLAM_MAX_MSG_LANDMARKS]; /**< true index matched to estimate i, or -1 */
} map_eval_t;

/**
 * Optimal one-to-one matching (minimum total squared distance) between the
 * exported landmarks and the true ones, pairs farther than gate_m rejected.
 * n_seen[j] (may be NULL) is the number of times true landmark j was
 * detected; only those with n_seen >= min_seen count as missed.
 */
void eval_map(const map_estimate_t *est, const point2_t *truth, const int *n_seen, int n_truth, int min_seen,
              double gate_m, map_eval_t *out);

/**
 * Minimum-cost assignment for an n x m cost matrix (row-major), n <= m:
 * row_to_col[i] receives the column of row i. O(n^2 m).
 */
void hungarian(const double *cost, int n, int m, int *row_to_col);

#ifdef __cplusplus
}
#endif

#endif
