/*
 * app/odo_check.h - do the wheels and the laser agree on how the robot
 * moved? A scan-to-scan check of the odometry, for the health monitor
 * (app/health.h).
 *
 * Why: the filter trusts odometry increments that are physically possible
 * (motion_is_plausible). Wheels that report five times the true speed, an
 * encoder gone random, or a robot carried elsewhere (kidnapped) give
 * increments that pass that bound, and among non-unique landmarks the
 * filter then localises itself into a look-alike place with normal
 * innovations: the landmark-based measures of the health monitor stay
 * quiet. The laser sees the true motion, independently of the wheels and
 * of the map.
 *
 * How: every period_s the newest scan (points in the robot frame, thinned
 * to at most COSLAM_APP_ODO_CHECK_POINTS, each with the normal of the
 * surface through its scan neighbours) is registered onto the reference
 * scan of the previous check by point-to-line ICP: nearest neighbours
 * inside a correspondence distance that shrinks from match_start_m to
 * match_end_m, Gauss-Newton steps on the normal distances (points without
 * a normal: both coordinates), damped so that directions the scene does not
 * constrain stay where they started. ICP starts from three guesses - the
 * odometry's motion, no motion, and the laser's own motion of the previous
 * check rescaled to this interval - so wrong odometry does not pull the
 * registration into its own local minimum; the result that explains most
 * points wins (inlier: nearest neighbour within neighbour_m and normal
 * distance within inlier_m), ties to the first guess. Then:
 *  - too few points in either scan (open space, laser blinded): not
 *    judged (counted);
 *  - best inlier fraction below min_inlier_frac: the two scans do not show
 *    the same place from any guess: MISMATCH (the robot was carried without
 *    its wheels knowing, or the view changed completely). When the
 *    newest scan has too few points the reference could have seen (a jump
 *    from a cramped place into an open one), the other way: the reference
 *    onto the newest scan, from the inverse guesses;
 *  - registered: e = L - U, the laser's motion against the odometry's (x,
 *    y, theta, from the reference to now, robot frame), is tested with the
 *    registration's covariance P_L = point_sd_m^2 H^-1 (H the Gauss-Newton
 *    information of the inliers: a wall seen head-on says nothing about
 *    sliding along it, and P_L says so) and the odometry's allowance
 *    P_U = diag(s_t^2, s_t^2, s_r^2), s_t = trans_sd_m + trans_sd_frac |t|,
 *    s_r = rot_sd_rad + rot_sd_frac |theta| (|t|, |theta| the larger of
 *    the two motions): DISAGREE when e^T (P_L + P_U)^-1 e > chi2_max.
 * One check's allowance hides a small systematic error (wheels reporting
 * twice the motion at 0.2 m/s: chi-square about 6). A drift test adds the
 * evidence up: z = the error along the odometry's direction of travel
 * (and of turning) over its standard deviation, from the same covariances
 * (an unconstrained direction gives z near 0), in two-sided CUSUM sums
 * S = max(0, S + z - cusum_k); S > cusum_h is a DISAGREEMENT too (and the
 * sums restart). Moves shorter than 2 cm or turns under 0.02 rad add
 * nothing.
 * A mismatch or a disagreement makes the check `bad` for hold_s after it
 * (the pose estimate carries the error from then on, the check sees only
 * the moment it happened); the monitor reports that as divergence.
 *
 * Limits (docs/robot-app.md "Odometry check"): motion along a direction the
 * scene does not constrain (a featureless corridor) is not judged; another
 * robot or a person filling most of the view is a mismatch (a false report,
 * bounded by hold_s).
 *
 * Caller-owned, no heap; O(guesses * iters * P^2) per check with P points,
 * every period_s (about 0.35 M distance evaluations for P = 96: a few ms
 * on a 500 MHz core, twice a second; twice that when the fallback way runs).
 */
#ifndef COSLAM_APP_ODO_CHECK_H
#define COSLAM_APP_ODO_CHECK_H

#include <stddef.h>
#include <stdint.h>

#include "coslam/cov3.h"
#include "coslam/pose2.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Scan points kept per scan (evenly thinned). */
#ifndef COSLAM_APP_ODO_CHECK_POINTS
#define COSLAM_APP_ODO_CHECK_POINTS 96
#endif
#if COSLAM_APP_ODO_CHECK_POINTS < 8 || COSLAM_APP_ODO_CHECK_POINTS > 1024
#error "COSLAM_APP_ODO_CHECK_POINTS must be in [8, 1024]"
#endif

typedef struct {
    double period_s;         /**< seconds between checks (> 0) */
    double max_gap_s;        /**< a reference older than period_s plus this is replaced, not compared (>= 0) */
    double min_range_m;      /**< returns used: robot-frame distance in [min_range_m, max_range_m] */
    double max_range_m;
    uint16_t min_points;     /**< both scans need this many points to be judged (>= 3) */
    uint16_t iters;          /**< ICP iterations per guess (>= 1) */
    double match_start_m;    /**< correspondence distance of the first iteration */
    double match_end_m;      /**< ... shrinking geometrically to this one */
    double neighbour_m;      /**< scan neighbours closer than this define a normal; an inlier's nearest neighbour is closer */
    double inlier_m;         /**< an inlier's normal distance after registration is within this */
    double min_inlier_frac;  /**< below: mismatch, in (0, 1] */
    double point_sd_m;       /**< sd of a point's normal distance (laser noise and thinning) */
    double trans_sd_m;       /**< the odometry's allowance, see the header comment */
    double trans_sd_frac;
    double rot_sd_rad;
    double rot_sd_frac;
    double chi2_max;         /**< disagreement bound on e^T (P_L + P_U)^-1 e (3 dof) */
    double cusum_k;          /**< drift test: allowance per check, in standard deviations (> 0) */
    double cusum_h;          /**< drift test: alarm level (> 0) */
    double hold_s;           /**< `bad` holds this long after a mismatch or disagreement */
} odo_check_config_t;

/** One thinned scan: points in the robot frame in scan order, normals. */
typedef struct {
    point2_t p[COSLAM_APP_ODO_CHECK_POINTS];
    point2_t normal[COSLAM_APP_ODO_CHECK_POINTS];   /**< unit; (0, 0) where none */
    uint16_t n;
} odo_scan_t;

typedef struct {
    odo_check_config_t cfg;
    odo_scan_t ref;              /**< reference scan */
    odo_scan_t cur;              /**< newest scan */
    int have_ref;
    pose2_t ref_odo;             /**< odometry pose at the reference scan */
    uint64_t ref_us;
    pose2_t laser_rate;          /**< last registered laser motion per second (x, y, theta) */
    int have_rate;
    double cusum[4];             /**< drift sums: translation over/under, rotation over/under (cusum_*) */
    uint64_t bad_until_us;
    int bad;                     /**< status: a mismatch or disagreement within hold_s */
    /* counters */
    uint32_t checks;             /**< pairs of scans compared */
    uint32_t unjudged;           /**< of those, too few points */
    uint32_t agreements;
    uint32_t disagreements;      /**< registered, motion differs from the odometry's */
    uint32_t mismatches;         /**< not registered from any guess */
    uint32_t stale_refs;         /**< references older than period_s plus max_gap_s, replaced */
    uint32_t drifts;             /**< the drift test fired (counted with disagreements) */
    /* the last judged check (for logs and tuning) */
    double last_inlier_frac;
    double last_chi2;            /**< e^T (P_L + P_U)^-1 e of the last registered check */
    pose2_t last_laser;          /**< L of the last registered check */
    pose2_t last_odo;            /**< U of the last registered check */
    double worst_chi2;           /**< largest e^T (P_L + P_U)^-1 e seen */
    double worst_cusum;          /**< largest drift sum seen */
    double worst_inlier_frac;    /**< smallest best inlier fraction among judged checks */
} odo_check_t;

/** period 0.5 s, max gap 1.5 s, ranges [0.1, 4] m, 12 points minimum, 10
 *  iterations from 0.5 m to 0.1 m, neighbours 0.3 m, inlier 0.05 m, min
 *  inlier fraction 0.5, point sd 0.02 m, allowances 0.03 m + 0.1 |t| and
 *  0.035 rad + 0.1 |theta|, chi2_max 16.27 (99.9 %, 3 dof), drift test
 *  k 1, h 10, hold 10 s
 *  (docs/robot-app.md "Odometry check" says why). */
odo_check_config_t odo_check_config_default(void);

/** COSLAM_OK or COSLAM_E_ARG (NULL, bounds out of range). */
coslam_status_t odo_check_init(odo_check_t *c, const odo_check_config_t *cfg);

/**
 * One laser scan: `pts` in the robot frame, in scan order (n of them;
 * non-finite ones and those outside the range bounds are skipped), taken at
 * now_us when the odometry pose was odo_pose. Compares it with the reference
 * when period_s has passed, then makes it the reference. Returns 1 if this
 * call ran a judged check, else 0.
 */
int odo_check_on_scan(odo_check_t *c, uint64_t now_us, pose2_t odo_pose, const point2_t *pts, size_t n);

/** Thin `pts` into `out` (range bounds of cfg, evenly spread) and compute
 *  the normals. Exposed for tests. O(n). */
void odo_check_thin(const odo_check_config_t *cfg, const point2_t *pts, size_t n, odo_scan_t *out);

/**
 * Register `cur` onto `ref` from `guess` (cur's frame in ref's frame), as
 * in the header comment. Writes the result to *out and its information
 * (Gauss-Newton H over the inliers, unit point noise) to *info (may be
 * NULL); returns the inlier fraction, among the points of cur that the
 * reference could have seen (a bearing where the reference scan reached at
 * least that far, less 0.3 m; their number in *n_checkable, may be NULL),
 * at the result. Exposed for tests. O(iters * n_cur * n_ref).
 */
double odo_check_register(const odo_check_config_t *cfg, const odo_scan_t *ref, const odo_scan_t *cur, pose2_t guess,
                          pose2_t *out, cov3_t *info, size_t *n_checkable);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_APP_ODO_CHECK_H */
