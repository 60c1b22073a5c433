// host/replay/replay_truth.cpp - interpolated ground truth.
#include "replay_truth.h"

#include <algorithm>

namespace coslam::replay {

TruthTrack::TruthTrack(const std::vector<TruthPose> &path, double max_gap_s) : path_(path), max_gap_s_(max_gap_s) {}

std::optional<pose2_t> TruthTrack::at(double t) const
{
    if (path_.empty() || t < path_.front().t_s || t > path_.back().t_s) {
        return std::nullopt;
    }
    const auto it = std::lower_bound(path_.begin(), path_.end(), t,
                                     [](const TruthPose &p, double v) { return p.t_s < v; });
    if (it == path_.begin() || it->t_s == t) {
        return it->pose;
    }
    const TruthPose &b = *it;
    const TruthPose &a = *(it - 1);
    const double span = b.t_s - a.t_s;
    if (span > max_gap_s_) {
        return std::nullopt;
    }
    const double f = span > 0.0 ? (t - a.t_s) / span : 0.0;
    pose2_t p;
    p.x = a.pose.x + f * (b.pose.x - a.pose.x);
    p.y = a.pose.y + f * (b.pose.y - a.pose.y);
    p.theta = angle_wrap(a.pose.theta + f * angle_wrap(b.pose.theta - a.pose.theta));
    return p;
}

} // namespace coslam::replay
