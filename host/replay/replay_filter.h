// host/replay/replay_filter.h - one robot's SLAM filter: the robot app's own
// filter wrapper (app/slam_filter.h: Fast-SLAM 1.0/2.0 or EKF-SLAM, with
// the coverage record the merge check uses), called exactly as the robot
// calls it.
//
// The filter state is large (a 1000-particle Fast-SLAM of the large profile
// is about 15 MB), so it lives on the heap here; the robot keeps it in
// static storage. Nothing here changes the filter beyond its public API.
#ifndef COSLAM_HOST_REPLAY_FILTER_H
#define COSLAM_HOST_REPLAY_FILTER_H

#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "app/slam_filter.h"
#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"
#include "coslam/map_merge.h"
#include "replay_config.h"
#include "stats.h"

namespace coslam::replay {

class RobotFilter {
public:
    /// Start at pose0 (the map frame is pose0's frame unless it is the world
    /// pose). core_robot_id is the provenance bit (< COSLAM_MAX_ROBOTS).
    /// Throws ReplayError for an invalid configuration.
    RobotFilter(FilterKind kind, const ReplayConfig &cfg, uint8_t core_robot_id, pose2_t pose0, uint64_t seed);
    ~RobotFilter();
    RobotFilter(const RobotFilter &) = delete;
    RobotFilter &operator=(const RobotFilter &) = delete;

    FilterKind kind() const { return kind_; }
    coslam_status_t predict(odo_increment_t u, double dt_s);
    coslam_status_t update(const sighting_t *z, int n);
    /// the idle time after a step, as the robot spends it (slam_filter_idle)
    void idle();
    void pose(pose2_t *mean, cov3_t *cov) const;
    /// Exports the map estimate (non-const: the core uses scratch in the state).
    coslam_status_t export_map(map_estimate_t *out);
    /// The whole map (for scoring and map files): a message carries at most
    /// COSLAM_MAX_MSG_LANDMARKS, the map may hold more.
    coslam_status_t export_whole(map_whole_t *out);
    /// The robot app's filter (the meeting protocol drives it).
    slam_filter_t *app() { return f_.get(); }
    /// Mean of the landmark of signature `sig` (known-ids mode: at most one
    /// should exist). EKF: the state; Fast-SLAM: the best particle. The one
    /// with most sightings if several.
    std::optional<point2_t> landmark_of_signature(uint8_t sig) const;
    /// The core's counters by name (capacity drops, rejected input, ...).
    std::map<std::string, long> counters() const;

    const fastslam_t *fastslam() const { return kind_ == FilterKind::Ekf ? nullptr : &f_->u.fs; }
    const ekfslam_t *ekfslam() const { return kind_ == FilterKind::Ekf ? &f_->u.ekf : nullptr; }

private:
    FilterKind kind_;
    // calloc, not make_unique: a zeroed slam_filter_t either way, but the
    // pages of a fresh calloc are zero already and stay untouched until the
    // filter uses them (203 MB per robot in the host profile, most of it
    // Fast-SLAM's worst-case landmark pool: value-initialising it was 70 %
    // of a replay's time)
    struct Free {
        void operator()(slam_filter_t *p) const { std::free(p); }
    };
    std::unique_ptr<slam_filter_t, Free> f_;
};

} // namespace coslam::replay

#endif
