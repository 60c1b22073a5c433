// host/replay/replay_noise.h - the sensor noise model (slam_params.h
// noise.range_var_m2, range_var_per_m2, bearing_var_rad2) measured from a
// dataset's residuals against ground truth, so the filter's sighting noise
// is a stated measurement rather than the outcome of a parameter search.
//
// For each sighting with a known landmark identity at a time with robot
// ground truth: residual = measured - true (range; bearing wrapped to
// [-pi, pi]), the truth being the range and bearing from the interpolated
// true pose to the surveyed landmark. Gross outliers (misread barcodes,
// occlusions) are rejected per robot at `reject_sd` robust sd
// (1.4826 * MAD around the median); for range the robust sd is taken per
// range bin, since the model lets it grow with the range. The model
//   var(range)   = range_var_m2 + range_var_per_m2 * r^2
//   var(bearing) = bearing_var_rad2
// is then fitted to the inliers: range by weighted least squares of the bin
// variances on the bin mean r^2 (both coefficients >= 0), bearing as the
// inlier variance. Biases (mean residuals) are reported, not folded into
// the variances: the filter assumes zero-mean noise, and a bias is a
// calibration question of its own.
//
// The residuals are correlated in time: consecutive sightings of the same
// landmark by the same robot share much of their error. Per robot and
// landmark, the inliers in time order are split into tracks (a gap longer
// than `track_gap_s` starts a new one), normalised by the fitted model
// ((residual - bias) / model sd at the true range), and the autocorrelation
// rho_k at lags k = 1..`max_lag` (in sightings, pairs within a track only,
// pooled over tracks and robots) is estimated for range and bearing. The
// integrated correlation tau = 1 + 2 sum rho_k, summed while rho_k > 0
// (initial-positive-sequence truncation), is reported; it does not converge
// on MRCLAM (rho stays positive past lag 20: the error is an offset shared
// by a whole track, not a short-memory process). The inflation used is that
// of a per-track offset: residual = o + w, var(o) = rho_1 var, var(w) =
// (1 - rho_1) var. A filter that fuses the n sightings of a track as
// independent with variance v_eff gets v_eff / n for their mean, whose true
// variance is var(o) + var(w) / n; equal when v_eff = var ((1 - rho_1) +
// n rho_1). n = the mean track length. The inflated model multiplies the
// fitted variances by that factor.
#ifndef COSLAM_HOST_REPLAY_NOISE_H
#define COSLAM_HOST_REPLAY_NOISE_H

#include <cmath>
#include <iosfwd>
#include <vector>

#include "coslam/slam_params.h"
#include "replay_data.h"

namespace coslam::replay {

struct NoiseFitOptions {
    double bin_m = 0.5;         ///< range bin width [m]
    double reject_sd = 5.0;     ///< outlier threshold in robust sd
    int min_bin_count = 10;     ///< bins with fewer inliers do not enter the range fit
    double max_gap_s = 0.5;     ///< truth gaps longer than this give no truth (TruthTrack)
    double min_range_m = 0.0;   ///< sightings outside [min, max] are not used (as [input] drops them)
    double max_range_m = 1e9;
    double track_gap_s = 1.0;   ///< sightings of one landmark by one robot further apart start a new track
    int max_lag = 20;           ///< autocorrelation lags 1..max_lag [sightings]
};

/// Autocorrelation of the normalised inlier residuals within tracks.
struct NoiseCorrelation {
    std::vector<double> rho;   ///< rho[k - 1] = autocorrelation at lag k (k = 1..max_lag); 0 where no pair
    std::vector<long> pairs;   ///< pairs[k - 1] = pairs at lag k
    int lags_summed = 0;       ///< lags before the first non-positive rho (those in tau)
    double tau = 1.0;          ///< 1 + 2 * sum of the first lags_summed rho (>= 1)
    double factor = 1.0;       ///< track-offset inflation (1 - rho_1) + n_track * rho_1 (>= 1)
};

/// One range bin of the range fit.
struct NoiseBin {
    double r_mean_m = 0.0;   ///< mean true range of the bin's inliers
    double r2_mean_m2 = 0.0; ///< mean true range^2
    double var_m2 = 0.0;     ///< variance of the range residuals (about the bin mean)
    long n = 0;
};

/// Fitted noise of one robot, or of all robots pooled (robot = 0).
struct NoiseStats {
    int robot = 0;
    bool has_truth = false;
    long sightings = 0;       ///< landmark sightings in the log
    long unknown_id = 0;      ///< no true identity, or identity without landmark truth
    long no_truth = 0;        ///< no robot truth at the sighting's time (gap or outside)
    long out_of_range = 0;    ///< outside [min_range_m, max_range_m]
    long used = 0;            ///< residuals computed (before rejection)
    long rejected = 0;        ///< gross outliers among `used`
    double range_bias_m = 0.0;      ///< mean inlier range residual
    double bearing_bias_rad = 0.0;  ///< mean inlier bearing residual
    double range_sd_m = 0.0;        ///< inlier range residual sd, all ranges together
    double range_var_m2 = 0.0;      ///< fitted model
    double range_var_per_m2 = 0.0;
    double bearing_var_rad2 = 0.0;
    std::vector<NoiseBin> bins;     ///< the bins that entered the range fit

    double rejected_fraction() const { return used > 0 ? static_cast<double>(rejected) / used : 0.0; }
};

struct NoiseFit {
    std::vector<NoiseStats> robots; ///< by increasing id, robots without truth included (has_truth false)
    NoiseStats overall;             ///< every robot's inliers pooled
    long tracks = 0;                ///< tracks (robot, landmark, gap <= track_gap_s) of inliers
    long samples = 0;               ///< normalised inlier residuals in the correlation estimate
    NoiseCorrelation range_corr;    ///< of (range residual - bias) / model sd
    NoiseCorrelation bearing_corr;  ///< of (bearing residual - bias) / bearing sd
    /// overall model inflated by the correlation: range by range_corr.tau, bearing by bearing_corr.tau
    double range_var_m2_eff = 0.0;
    double range_var_per_m2_eff = 0.0;
    double bearing_var_rad2_eff = 0.0;
};

/// Fit the sighting noise of `ds`. Throws ReplayError when the dataset has
/// no landmark ground truth, no robot with ground truth, or no usable
/// sighting.
NoiseFit fit_noise(const Dataset &ds, const NoiseFitOptions &opt = {});

// The camera's detection rate over the region the filter calls in view:
// p_d of the existence filter's miss weight (slam_exist_miss_for_detection,
// docs/core-slam.md "The miss weight from the camera's detection rate").
//
// A logged frame is one stamp of a robot's sightings (landmarks and robots
// alike, grouped as the replay groups them). At each frame with robot
// ground truth (the truth pose interpolated at the stamp, as for the
// residuals above), every true landmark that landmark_should_be_seen()
// calls in view from the true pose (observe_predict of its surveyed
// position; the footprint and visibility_margin of the slam parameters the
// replay runs with) is one landmark-frame in view; it is detected when the
// frame holds a sighting whose true identity is that landmark and whose
// range lies within [min_range_m, max_range_m] (the [input] limits: the
// filter never sees what they drop). p_d = detected / in view.
//
// Bias: a frame enters the log only if it holds at least one sighting
// (MRCLAM writes no frame without one), so the frames counted are the
// frames with a detection, and p_d over them is biased upward: a frame in
// which every landmark in view was missed and nothing else was seen is
// absent. p_d_truncated corrects for that under a model, and is reported
// only: detections independent across the landmarks in view with one
// probability p; a frame that holds some other sighting (a robot, a
// landmark out of view, an unknown identity, one outside the [input]
// limits) would have been logged anyway, so its in-view detections count
// as Binomial(n, p); a frame with nothing else was logged because k >= 1,
// so its count is Binomial(n, p) conditioned on k >= 1 (zero-truncated).
// p_d_truncated maximises that likelihood over p (frames with n = 1 and
// nothing else carry no information on p: k = 1 is certain).

struct DetectionOptions {
    double bin_m = 1.0;         ///< range bin width of the table [m]
    double max_gap_s = 0.5;     ///< truth gaps longer than this give no truth (TruthTrack)
    double min_range_m = 0.0;   ///< sightings outside [min, max] are not detections (as [input] drops them)
    double max_range_m = 1e9;
};

/// Landmark-frames in view whose true range lies in [r_lo_m, r_lo_m + bin_m).
struct DetectionBin {
    double r_lo_m = 0.0;
    long in_view = 0;
    long detected = 0;
};

/// Detection counts of one robot, or of all robots pooled (robot = 0).
struct DetectionStats {
    int robot = 0;
    bool has_truth = false;
    long frames = 0;          ///< logged frames (each holds at least one sighting)
    long no_truth = 0;        ///< of them, without robot truth at the stamp (not counted below)
    long used = 0;            ///< frames with truth
    long other = 0;           ///< used frames that hold a sighting other than an in-view detection
    long in_view = 0;         ///< landmark-frames landmark_should_be_seen calls in view
    long detected = 0;        ///< of them, with a sighting of that landmark in the frame
    long out_of_view = 0;     ///< sightings of a true landmark the view model calls out of view (not in p_d)
    std::vector<DetectionBin> bins; ///< every bin up to the farthest in-view range, bin i from i * bin_m
    double p_d_truncated = std::nan(""); ///< zero-truncated estimate (above); NaN when nothing is in view

    /// detected / in view; NaN when nothing was in view.
    double p_d() const
    {
        return in_view > 0 ? static_cast<double>(detected) / static_cast<double>(in_view) : std::nan("");
    }
};

struct DetectionFit {
    std::vector<DetectionStats> robots; ///< by increasing id, robots without truth included (has_truth false)
    DetectionStats overall;             ///< every robot with truth pooled
    double bin_m = 1.0;
    /// slam_exist_miss_for_detection(overall.p_d()): -1 unless p_f < p_d < 1
    double exist_miss_confirmed = -1.0;
    /// the same of overall.p_d_truncated (reported, not written)
    double exist_miss_confirmed_truncated = -1.0;
};

/// Measure the detection rate of `ds` over the view of `params`
/// (landmark_should_be_seen). Throws ReplayError when the dataset has no
/// landmark ground truth or no robot with ground truth. O(frames x landmarks).
DetectionFit fit_detection(const Dataset &ds, const slam_params_t &params, const DetectionOptions &opt = {});

/// The fitted (overall) values as an INI fragment of the replay
/// configuration ([slam] range_var_m2, range_var_per_m2, bearing_var_rad2;
/// with `det`, also exist_miss_confirmed from its p_d, when the formula
/// gives one, with a comment line stating p_d and the formula).
/// The variances are floored at 1e-6 (the filter requires them > 0; a
/// comment line in the file says when a floor was applied). With `inflate`
/// the inflated values (the *_eff members) are written instead, with a
/// comment stating tau and the rule.
void write_noise_ini(const NoiseFit &fit, const Dataset &ds, std::ostream &out, bool inflate = false,
                     const DetectionFit *det = nullptr);

} // namespace coslam::replay

#endif
