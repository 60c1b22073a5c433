// host/replay/replay_config.h - every parameter of a replay, with defaults
// fitted to MRCLAM (docs/replay.md gives the measurements behind each), read
// from an INI file (libinih).
//
// INI layout (section.key; every key optional; an unknown section or key, a
// value that is not a number, or an out-of-domain value is an error naming
// the file and line):
//   [slam]      every field of slam_params_t by its C name (noise weights
//               w1..w8 as variances, range_var_per_m2, sensor footprint,
//               gates, existence counters): the shared key table of
//               app/slam_params_ini.h, the same one coslam-robot reads
//               (same names, parser and per-key domains)
//   [odometry]  scale_v, scale_w, delay_s (OdoModel)
//   [filter]    type (fastslam1 | fastslam2 | ekf), particles, ess_fraction,
//               export_min_weight, closure_drift_ratio, closure_gap,
//               closure_ambiguity_ll, closure_misses_per_support,
//               closure_chance_max, closure_unsupported_every, assoc (jcbb | nn), jcbb_max_nodes, fej,
//               iekf_max_iters, nis_inflate, active_spread_madds, mh_frames, seed,
//               predict_period_s
//   [input]     min_range_m, max_range_m (sightings outside are dropped, counted),
//               known_id_gate_rad, known_id_gate_chi2, known_id_log_lik
//               (known-ids mode, see below)
//   [merge]     enabled, window_s, interval_s, gate_chi2, grid_cell_m,
//               transform_uncertainty, reweight_particles, min_obs,
//               range_check_chi2, sender_speed_mps, sender_turn_radps
//   [eval]      gate_m, min_seen, map_period_s, pose_period_s, pose_fit_min_matched,
//               pose_fit_max_landmarks
//   [robotN]    per-robot overrides: filter, scale_v, scale_w, delay_s
#ifndef COSLAM_HOST_REPLAY_CONFIG_H
#define COSLAM_HOST_REPLAY_CONFIG_H

#include <cstdint>
#include <iosfwd>
#include <map>
#include <string>

#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"
#include "coslam/map_merge.h"
#include "coslam/slam_params.h"
#include "replay_odometry.h"

namespace coslam::replay {

enum class FilterKind { FastSlam1, FastSlam2, Ekf };

/// "fastslam1" | "fastslam2" | "ekf" (also "fs1", "fs2"); throws ReplayError otherwise.
FilterKind filter_kind_from_string(const std::string &s);
const char *filter_kind_name(FilterKind k);

struct FilterConfig {
    FilterKind type = FilterKind::FastSlam2;
    int particles = 100;
    double ess_fraction = 0.5;
    double export_min_weight = 0.5;
    /// Fast-SLAM 2.0 revisits (fastslam_config_t; 0 switches them off).
    double closure_drift_ratio = 4.0;
    int closure_gap = 25;
    double closure_ambiguity_ll = 2.302585093;
    double closure_misses_per_support = 2.0;
    double closure_chance_max = 1.0;
    int closure_unsupported_every = 2;
    ekfslam_assoc_t assoc = EKFSLAM_ASSOC_JCBB;
    uint32_t jcbb_max_nodes = 20000;
    int fej = 1;
    int iekf_max_iters = 0; ///< ekfslam_config_t::iekf_max_iters
    double nis_inflate = 3.0; ///< ekfslam_config_t::nis_inflate (0: off)
    uint32_t active_spread_madds = 8000000; ///< ekfslam_config_t::active_spread_madds
    uint32_t mh_frames = 50; ///< ekfslam_config_t::mh_frames (0: off)
    uint64_t seed = 1;
    /// Odometry is folded into one prediction at most this long [s] (and
    /// always right before a camera frame): the robot's control rate.
    double predict_period_s = 0.1;
};

struct InputConfig {
    double min_range_m = 0.0;
    double max_range_m = 1e9;
    /// Known-ids mode: a sighting of landmark id k whose bearing differs by
    /// more than this [rad] from the bearing of the filter's landmark with
    /// signature k (seen from the current pose estimate) is a misread
    /// barcode and dropped (MRCLAM's misreads are off by more than 100 deg).
    /// 0 disables the gate.
    double known_id_gate_rad = 1.0;
    /// Known-ids mode: the identity decides the association, so the
    /// filter's gates are opened (slam.gate_chi2, new_landmark_chi2 and the
    /// merge's duplicate gate set to this, new_landmark_log_lik to
    /// known_id_log_lik); otherwise a loop
    /// closure after a long landmark-free stretch (30-40 deg of heading
    /// drift happen on MRCLAM) fails the gate and duplicates the landmark.
    double known_id_gate_chi2 = 1e4;
    double known_id_log_lik = -1e4;
};

struct MergeParams {
    bool enabled = true;
    /// The meeting protocol (app/meeting.h) with these settings:
    double window_s = 0.5;    ///< both sightings at most this far apart in time (pair_window_us)
    double interval_s = 30.0; ///< after merging a peer, ignore it this long (remerge_period_us)
    double max_range_m = 1e3; ///< robot sightings farther away do not start or feed a meeting
    int export_min_obs = 5;   ///< landmarks sent must have this many sightings
    /// Messages per meeting and peer, and their spacing: MRCLAM's camera
    /// sees the other robot in a few frames per second at best, so the
    /// receiver's own sighting within window_s of the sender's comes only
    /// with more tries than the robot's default (3, 1 s).
    int max_sends = 10;
    double resend_s = 0.5;
    /// Set-up, check and fusion (map_merge.h): range_check_chi2,
    /// peer_speed_mps / peer_turn_radps (INI: sender_speed_mps,
    /// sender_turn_radps), check, refine_iters, agree_z, veto_looks,
    /// max_contradict_fraction, ambiguous_chi2, gate_chi2, min_obs, ...
    merge_config_t core = merge_config_default();
};

struct EvalConfig {
    double gate_m = 0.5;       ///< landmark matching gate
    int min_seen = 5;          ///< a true landmark is "missed" only if sighted this often
    double map_period_s = 5.0; ///< map error time series period
    double pose_period_s = 0.1;///< pose error samples
    /// the pose in the map's fitted frame (pose.fit_rmse_m) is scored at a
    /// map evaluation only when the fit matched this many landmarks: with
    /// few identical markers the fit can lock onto a wrong correspondence
    /// (MRCLAM Dataset 6, robot 4 early on: 55 deg with 2 or more allowed)
    int pose_fit_min_matched = 6;
    /// ... and only while the map holds at most this many landmarks: the
    /// fit searches the correspondences (0.4 ms at 15 landmarks, 0.2 s at
    /// 800 against 1,024), and every 5 s on the large world it took three
    /// quarters of the replay's time; above, a note says it was skipped
    int pose_fit_max_landmarks = 128;
};

struct RobotOverride {
    bool has_filter = false;
    FilterKind filter = FilterKind::FastSlam2;
    bool has_odo = false;
    OdoModel odo;
};

struct ReplayConfig {
    slam_params_t slam = slam_params_default();
    OdoModel odo;
    FilterConfig filter;
    InputConfig input;
    MergeParams merge;
    EvalConfig eval;
    std::map<int, RobotOverride> robot;

    FilterKind filter_of(int robot_id) const;
    OdoModel odo_of(int robot_id) const;
};

/// The defaults for MRCLAM's camera and velocity odometry (docs/replay.md).
ReplayConfig replay_config_default();

/// Apply an INI file on top of `cfg`. Throws ReplayError("file:line: ...").
void replay_config_load(ReplayConfig &cfg, const std::string &path);
/// Same, from text (`name` for messages).
void replay_config_load_string(ReplayConfig &cfg, const std::string &text, const std::string &name);

/// Write `cfg` as an INI file that replay_config_load reads back exactly.
void replay_config_write(const ReplayConfig &cfg, std::ostream &out);

/// The periods' ranges [s] (docs/replay.md, Limits): a period too small for
/// the replay's clock stopped it from advancing (1e-300 s), and the map
/// series keeps one score per map_period_s (not thinned like the path), so
/// over the kMaxSpanS span it holds at most 10^7 scores.
inline constexpr double kMinPredictPeriodS = 1e-3;
inline constexpr double kMaxPredictPeriodS = 10.0;
inline constexpr double kMinPosePeriodS = 1e-3;
inline constexpr double kMinMapPeriodS = 0.1;
inline constexpr double kMaxEvalPeriodS = 3600.0;

/// Validate the whole configuration (slam_params_validate and the rest);
/// throws ReplayError naming the offending key.
void replay_config_validate(const ReplayConfig &cfg);

} // namespace coslam::replay

#endif
