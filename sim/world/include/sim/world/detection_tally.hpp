// sim/world/detection_tally.hpp - the camera's detection rate over the
// region the filter calls in view, measured against the world's truth.
//
// A confirmed landmark's miss weighs by the camera's detection probability
// p_d (slam_exist_miss_for_detection, docs/core-slam.md). The rate that
// matters is not the camera model's p_detect but the fraction of frames in
// which a marker is detected when the filter's view model
// (landmark_should_be_seen: range, field of view, visibility margin) says,
// from the robot's true pose, that it is in view. Flat markers on walls and
// box faces, seen edge-on or from behind their box, bring it down.
//
// Counted per delivered frame and per true landmark in that view: in view,
// in view with a clear line of sight (what the laser's view profile can
// tell the filter: a landmark behind an obstacle is hidden, not missed), and
// of each, detected in that frame. The tally reads the world only; it
// draws nothing, so a run is the same with or without it.
#ifndef COSLAM_SIM_WORLD_DETECTION_TALLY_HPP
#define COSLAM_SIM_WORLD_DETECTION_TALLY_HPP

#include <cstdint>
#include <vector>

#include "coslam/slam_params.h"
#include "sim/world/world.hpp"

namespace coslam::sim {

/// A true landmark the filter's view model calls in view in one frame.
struct ViewedLandmark {
    int id = 0;          ///< LandmarkMarker::id
    bool clear = false;  ///< nothing blocks the line from the camera to it
};

struct DetectionTally {
    uint64_t frames = 0;          ///< frames delivered to the robot and tallied
    uint64_t in_view = 0;         ///< landmark-frames in the filter's view (true pose)
    uint64_t detected = 0;        ///< ... detected in that frame
    uint64_t in_view_clear = 0;   ///< ... of in_view, with a clear line of sight
    uint64_t detected_clear = 0;  ///< ... of those, detected
};

/// The landmarks of `world` that `view_model` (landmark_should_be_seen)
/// calls in view from `pose` (camera at the robot centre along its x axis),
/// with their line of sight (body `self` excluded).
std::vector<ViewedLandmark> landmarks_in_filter_view(const World &world, int self, const pose2_t &pose,
                                                     const slam_params_t &view_model);

/// Add one delivered frame: `viewed` from landmarks_in_filter_view at its
/// capture, `detected[id]` nonzero for the landmarks a sighting of the frame
/// was matched to (ids outside `detected` count as not detected).
void tally_frame(DetectionTally &t, const std::vector<ViewedLandmark> &viewed, const std::vector<uint8_t> &detected);

/// detected / in_view, and the same over a clear line of sight; NaN with
/// nothing in view.
double detection_rate(const DetectionTally &t);
double detection_rate_clear(const DetectionTally &t);

}  // namespace coslam::sim

#endif
