// host/replay/replay_run.h - the replay: every robot's filter driven by its
// odometry and camera frames in time order, robot-to-robot meetings turned
// into map merges, and the evaluation against ground truth.
//
// Per robot (as on the robot): odometry is folded into one prediction per
// predict_period_s and right before each camera frame; a camera frame (all
// sightings sharing one stamp) is one filter update. Landmark identities are
// dropped (signature 0) unless known_ids, where the signature is the id and
// sightings far from the filter's landmark of that id are dropped as
// misread barcodes.
//
// Meetings (docs/replay.md "Merge protocol"): each robot runs the robot
// app's own filter wrapper and meeting protocol (app/slam_filter.h,
// app/meeting.h) over an in-process link that delivers every datagram at
// once: a robot sighting goes to meeting_on_sighting (which sends the map
// when the protocol says so), and after each camera frame the robot polls
// its link and merges a pending message through slam_filter_merge_map (the
// one merge path: set-up, check, fusion). Nothing here re-implements a merge
// step. Each merge or refusal is evaluated: transform error and NEES
// against the true relative pose, receiver map error before and after.
#ifndef COSLAM_HOST_REPLAY_RUN_H
#define COSLAM_HOST_REPLAY_RUN_H

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "app/slam_filter.h"
#include "coslam/map_estimate.h"
#include "coslam/map_merge.h"
#include "replay_config.h"
#include "replay_data.h"
#include "replay_truth.h"
#include "stats.h"

namespace coslam::replay {

/// Most points of a robot's recorded path (RobotResult::path, the TUM file):
/// beyond it the path is thinned to every other point (memory bounded by
/// this, not by the dataset's span; the error statistics use every sample).
inline constexpr size_t kMaxPathPoints = 131072;

struct ReplayOptions {
    std::vector<int> robots;   ///< robot ids to replay; empty: all
    bool known_ids = false;
    bool start_at_truth = false;
    double duration_s = 0.0;   ///< > 0: replay only [begin, begin + duration]
    bool record_history = true;///< paths and error series (off: summaries only)
    /// Called now and then with the replayed fraction in [0, 1].
    std::function<void(double)> progress;
};

/// A map estimate scored after the best rigid fit onto the true landmarks
/// in the world frame (stats.h eval_map_rigid): needs no robot ground
/// truth, measures the map's shape only (the fit absorbs the unknown start
/// pose and any rotation or offset common to the whole map).
struct FitScore {
    bool valid = false;     ///< false: not computed (no true landmarks)
    pose2_t transform{};    ///< the estimate's map frame in the world: world = transform (+) map
    int n_matched = 0;
    int n_spurious = 0;     ///< no true landmark within the gate once the map is moved by `transform`
    int n_missed = 0;
    double rmse_m = 0.0;    ///< over matched pairs (0 if none)
    double max_err_m = 0.0;
    double nees_mean = 0.0; ///< landmark NEES over matched pairs after the fit (covariances
                            ///< rotated with the map); the fit removes the map's common
                            ///< offset, which the covariances still hold: a lower bound
    /// the errors and the transform were measured: evaluated, and at least
    /// one landmark matched (with none they are 0, printed n/a / null)
    bool measured() const { return valid && n_matched > 0; }
};

/// A map estimate evaluated against the true landmarks (stats.h eval_map).
struct MapScore {
    int n_estimated = 0;
    int n_matched = 0;
    int n_spurious = 0;
    int n_missed = 0;
    double rmse_m = 0.0;
    double max_err_m = 0.0;
    double nees_mean = 0.0;
    bool valid = false; ///< false when the truth is unknown (no robot ground truth: no map frame)
    FitScore fit;       ///< rigid-fit score; computed for the final maps only (RobotResult::final_score)
    /// rmse_m, max_err_m, nees_mean were measured (valid, >= 1 landmark matched;
    /// with none they are 0, printed n/a / null); the counts need only valid
    bool measured() const { return valid && n_matched > 0; }
};

struct PoseSample {
    double t_s;
    pose2_t est;      ///< map frame
    cov3_t cov;
    bool has_truth;
    pose2_t truth;    ///< map frame
};

struct MapSample {
    double t_s;
    MapScore score;
};

struct MergeEvent {
    double t_s = 0.0;
    int receiver = 0;
    int sender = 0;
    double t_receiver_sighting_s = 0.0;
    double t_sender_sighting_s = 0.0;
    uint32_t seq = 0;
    coslam_status_t status = COSLAM_OK; ///< of the merge (OK, or why it failed)
    pose2_t transform{};                ///< sender (at its snapshot) in the receiver's body frame, now
    cov3_t transform_cov{};
    bool has_truth = false;
    pose2_t transform_true{};
    double t_err_m = 0.0;
    double t_err_rad = 0.0;
    double t_nees = 0.0;
    merge_stats_t stats{};              ///< of the call (a merge in parts: its first part)
    unsigned particles_due = 0;         ///< Fast-SLAM particles left to idle time (merge in parts)
    MapScore before;
    MapScore after;                     ///< after the call (a merge in parts: its first part)
    double merge_us = 0.0;
};

struct RobotResult {
    int id = 0;
    FilterKind filter = FilterKind::FastSlam2;
    MapFrame frame;                 ///< map frame in the world (truth)
    bool has_truth = false;
    double t_start_s = 0.0;
    /// when `frame` was placed: t_start_s (the true pose at the start), or,
    /// for a robot whose ground truth begins later, the first truth sample,
    /// where the frame is placed so that the estimate of that moment is
    /// the truth (pose errors before it are not scored); -1 if never placed
    double t_frame_s = -1.0;
    std::vector<PoseSample> path;   ///< at pose_period_s
    std::vector<MapSample> map_series;
    std::shared_ptr<map_whole_t> final_map; ///< the whole map, not the message-sized export
    /// The map right before and after the merge that added the most
    /// landmarks to it (the figures show this one); null if never merged.
    std::shared_ptr<map_whole_t> map_before_merge;
    std::shared_ptr<map_whole_t> map_after_merge;
    double t_shown_merge_s = -1.0;
    double t_first_merge_s = -1.0;
    int shown_merge_gain = -1;      ///< landmarks it added
    std::vector<point2_t> truth_landmarks; ///< true landmarks in the map frame
    std::vector<int> truth_ids;
    std::vector<int> n_seen;        ///< sightings of each true landmark (own and merged in)
    // summaries
    int pose_samples = 0;
    double pose_rmse_m = 0.0;
    double heading_rmse_rad = 0.0;
    /// the pose in the frame of the map's rigid fit, at the map evaluations
    /// (Replay::score_pose_in_fit): localisation in its own map, whatever
    /// that map's frame
    int pose_fit_samples = 0;
    double pose_fit_rmse_m = 0.0;
    double heading_fit_rmse_rad = 0.0;
    double pose_nees_mean = 0.0;
    double pose_nees_xy_mean = 0.0;      ///< position part (2 dof)
    double pose_nees_heading_mean = 0.0; ///< heading part (1 dof)
    double final_pos_err_m = 0.0;
    MapScore final_score;           ///< map frame (needs truth); .fit: rigid fit (every robot)
    // work
    long frames = 0;
    long updates = 0;
    long predictions = 0;
    double step_us_mean = 0.0;      ///< per camera frame: predictions since the last frame + update
    double step_us_max = 0.0;
    double filter_s = 0.0;          ///< total time in the filter (predict + update)
    // input bookkeeping
    long sightings_used = 0;
    long sightings_range_dropped = 0;
    long sightings_known_id_dropped = 0;
    long sightings_before_start = 0;       ///< landmark sightings before the robot's first odometry record
    long robot_sightings_before_start = 0; ///< and sightings of robots (meetings lost with them)
    long robot_sightings = 0;
    long capacity_errors = 0;
    std::map<std::string, long> counters;
    std::vector<slam_filter_limit_t> limits; ///< the filter's loss counters that moved (slam_filter_limits)
};

struct ReplayResult {
    std::vector<RobotResult> robots;
    std::vector<MergeEvent> merges;
    long meetings_refused_range = 0;  ///< mutual sightings whose ranges disagree
    long merges_refused_replay = 0;   ///< merge_session_accept refused
    long merges_refused_disagree = 0; ///< merge_check: the maps disagree
    long merges_refused_lost = 0;     ///< merge_check: the receiver was lost in its own map
    long merges_refused_implausible = 0; ///< values no robot of the team can produce (merge_prepare step 0)
    long merges_stale = 0;            ///< no own sighting within the window
    long merges_failed = 0;
    double t_begin_s = 0.0;
    double t_end_s = 0.0;
    double wall_s = 0.0;
    std::vector<std::string> notes;
};

/// Run the replay. Throws ReplayError for an unusable request (unknown
/// robot id, known_ids with ids outside 1..255, no truth for
/// start_at_truth, invalid configuration).
ReplayResult run_replay(const Dataset &ds, const ReplayConfig &cfg, const ReplayOptions &opt);

/// Evaluate `est` against true landmarks (map frame), stats.h eval_map.
MapScore score_map(const map_whole_t &est, const std::vector<point2_t> &truth, const std::vector<int> &n_seen,
                   const EvalConfig &ec, map_eval_t *detail = nullptr);

/// Score `est` after its best rigid fit onto the true landmarks given in the
/// world frame (stats.h eval_map_rigid, gate and min_seen of `ec`): works
/// without robot ground truth. Not valid if `truth_world` is empty.
FitScore score_map_fit(const map_whole_t &est, const std::vector<point2_t> &truth_world,
                       const std::vector<int> &n_seen, const EvalConfig &ec, map_eval_t *detail = nullptr);

} // namespace coslam::replay

#endif
