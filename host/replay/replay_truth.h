// host/replay/replay_truth.h - ground truth of a replay, interpolated in
// time and expressed in a robot's map frame.
//
// Each robot's filter starts at the identity pose (default), so its map
// frame is its true pose at the filter's start; or at the true start pose
// (--start-at-truth), so its map frame is the world. Every comparison with
// truth goes through MapFrame, so both cases share one code path.
#ifndef COSLAM_HOST_REPLAY_TRUTH_H
#define COSLAM_HOST_REPLAY_TRUTH_H

#include <optional>
#include <vector>

#include "coslam/pose2.h"
#include "replay_data.h"

namespace coslam::replay {

/// Linear interpolation of a time-ordered path (heading along the shorter arc).
class TruthTrack {
public:
    /// `max_gap_s`: no answer between two samples farther apart than this.
    explicit TruthTrack(const std::vector<TruthPose> &path, double max_gap_s = 0.5);

    /// World pose at t, or nothing outside the path or inside a gap. O(log n).
    std::optional<pose2_t> at(double t_s) const;
    bool empty() const { return path_.empty(); }
    double begin_s() const { return path_.empty() ? 0.0 : path_.front().t_s; }
    double end_s() const { return path_.empty() ? 0.0 : path_.back().t_s; }

private:
    std::vector<TruthPose> path_;
    double max_gap_s_;
};

/// A robot's map frame in the world (origin = where its filter started).
struct MapFrame {
    pose2_t origin{}; ///< the map frame's pose in the world

    pose2_t pose_in_map(pose2_t world) const { return pose2_between(origin, world); }
    point2_t point_in_map(point2_t world) const { return pose2_apply_inverse(origin, world); }
};

} // namespace coslam::replay

#endif
