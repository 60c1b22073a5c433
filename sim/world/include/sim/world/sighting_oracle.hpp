// sim/world/sighting_oracle.hpp - the simulator's STAND-IN for the camera
// pipeline: marker sightings computed from the world's geometry. It is NOT
// a camera: no image is rendered, nothing is segmented. It implements the
// app's sighting_source_t (firmware/app/include/app/sighting_source.h) until
// the vision issue renders camera frames and runs the real pipeline behind
// the same interface.
//
// Model, per frame (every period_us, first at phase_us), from the robot's
// true pose (camera at the robot centre, looking along its x axis):
//  - a landmark marker or another robot is a candidate if its true range is
//    in [min_range_m, max_range_m], its true bearing within +-fov/2, and the
//    line from the camera to it is not blocked by a wall, a pillar or
//    another robot (markers on a wall are not hidden by their own wall);
//  - a candidate is detected with probability p_detect (landmarks) or
//    robot_p_detect (robots);
//  - range and bearing get independent Gaussian noise: landmarks
//    sd_r = sqrt(range_sd_m^2 + (range_sd_rel r)^2) (distance from blob
//    size grows with range), sd_b = bearing_sd_rad; robots
//    robot_range_sd_m, robot_bearing_sd_rad. Ranges are kept >= 1 cm.
// All draws come from one seeded core RNG per oracle, so a run is a
// function of the seeds. Landmark sightings carry the marker's signature,
// robot sightings the robot's id (robot markers are unique, as in the paper).
#ifndef COSLAM_SIM_WORLD_SIGHTING_ORACLE_HPP
#define COSLAM_SIM_WORLD_SIGHTING_ORACLE_HPP

#include <cstdint>
#include <vector>

#include "app/sighting_source.h"
#include "coslam/rng.h"
#include "coslam/slam_params.h"
#include "sim/world/detection_tally.hpp"
#include "sim/world/world.hpp"

namespace coslam::sim {

struct SightingOracleConfig {
    uint64_t period_us = 200000;   ///< frame period (5 Hz)
    uint64_t phase_us = 0;         ///< time of the first frame
    double fov_rad = 50.0 * COSLAM_PI / 180.0;
    double min_range_m = 0.3;
    double max_range_m = 5.0;
    double p_detect = 0.9;
    double range_sd_m = 0.02;
    double range_sd_rel = 0.03;
    double bearing_sd_rad = 2.0 * COSLAM_PI / 180.0;
    double robot_p_detect = 0.9;
    double robot_range_sd_m = 0.05;
    double robot_bearing_sd_rad = 2.0 * COSLAM_PI / 180.0;
    uint64_t seed = 1;
    /// the filter's view model, for the detection tally (detection_tally.hpp)
    slam_params_t view_model = slam_params_default();
};

class SightingOracle {
public:
    /// The oracle of robot `self_id` (its body in `world`); world must outlive it.
    SightingOracle(const World &world, int self_id, const SightingOracleConfig &cfg);
    SightingOracle(const SightingOracle &) = delete;
    SightingOracle &operator=(const SightingOracle &) = delete;

    sighting_source_t *source() { return &src_; }

    /// Take every frame due up to t_us, at the world's current state (the
    /// simulator calls this each physics step, after moving the robots).
    void set_time_us(uint64_t t_us);

    /// Fault: a stalled camera takes no frames (frames falling due are
    /// skipped, not caught up later; the sequence numbers show the gap).
    void set_stalled(bool stalled) { stalled_ = stalled; }
    uint64_t stalled_frames() const { return stalled_frames_; }

    /// Times true landmark j was detected (ground truth for evaluation).
    const std::vector<int> &detections() const { return detections_; }
    uint64_t frames() const { return frames_; }
    uint64_t robot_sightings() const { return robot_sightings_; }
    uint64_t dropped() const { return dropped_; }
    const SightingOracleConfig &config() const { return cfg_; }
    /// Detections over the filter's view, per delivered frame.
    const DetectionTally &detection_tally() const { return tally_; }

private:
    void capture(uint64_t stamp_us);
    static hal_status_t op_next_frame(sighting_source_t *src, sighting_frame_t *out, uint32_t timeout_us);
    static const sighting_source_ops_t kOps;

    const World &world_;
    int self_;
    SightingOracleConfig cfg_;
    rng_t rng_;
    sighting_source_t src_;
    sighting_frame_t latest_{};
    bool have_frame_ = false;
    uint32_t frame_seq_ = 0;
    uint64_t next_us_;
    std::vector<int> detections_;
    std::vector<ViewedLandmark> latest_viewed_;  ///< the filter's view at latest_'s capture
    std::vector<uint8_t> latest_detected_;       ///< per landmark id: in latest_
    DetectionTally tally_;
    uint64_t frames_ = 0;
    uint64_t robot_sightings_ = 0;
    uint64_t dropped_ = 0;
    bool stalled_ = false;
    uint64_t stalled_frames_ = 0;
};

}  // namespace coslam::sim

#endif
