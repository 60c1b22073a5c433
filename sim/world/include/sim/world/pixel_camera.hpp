// sim/world/pixel_camera.hpp - one robot's camera in pixels: the renderer
// (camera_renderer.hpp) draws the world from the robot's true pose at the
// camera's frame rate and pushes the frames into a SimCamera (the
// hal_camera_t the robot owns); the robot's sighting source is the REAL
// pipeline, vision_source_t (firmware/vision: grab -> colour table ->
// blobs -> markers -> sightings), exactly what coslam-robot would run on a
// V4L2 camera. It replaces the geometric stand-in (SightingOracle), which
// stays available (scenario camera.source = "oracle", coslam-sim --camera
// oracle).
//
// The handle given to the firmware (source()) is the vision source's, seen
// through a thin evaluation tap: after each frame it compares the sightings
// with the renderer's ground truth of that frame (same class, bearing
// within the marker's silhouette or 3 deg, range within 30 %) to count
// detections per true landmark
// (the simulator's "missed landmark" evaluation needs them), false markers
// and wrong robot ids. The tap never changes what the firmware receives.
#ifndef COSLAM_SIM_WORLD_PIXEL_CAMERA_HPP
#define COSLAM_SIM_WORLD_PIXEL_CAMERA_HPP

#include <cstdint>
#include <deque>
#include <string>
#include <utility>
#include <vector>

#include "app/sighting_source.h"
#include "coslam/slam_params.h"
#include "sim/world/camera_renderer.hpp"
#include "sim/world/detection_tally.hpp"
#include "sim/world/world.hpp"
#include "sim_hal/sim_camera.hpp"
#include "sim_hal/sim_clock.hpp"
#include "vision/vision.h"
#include "vision/vision_source.h"

namespace coslam::sim {

struct PixelCameraConfig {
    uint64_t period_us = 200000;   ///< frame period (5 Hz)
    uint64_t phase_us = 0;         ///< time of the first frame
    CameraRendererConfig render;
    vision_config_t detector = vision_config_default();
    std::string lut_path;          ///< "" = the shipped table (firmware/vision/data)
    std::string model_path;        ///< "" = the shipped range model
    /// the filter's view model, for the detection tally (detection_tally.hpp)
    slam_params_t view_model = slam_params_default();
};

/// The shipped colour table and range model.
std::string default_vision_lut_path();
std::string default_vision_model_path();

struct PixelCameraStats {
    uint64_t frames = 0;              ///< rendered and pushed
    uint64_t landmark_sightings = 0;  ///< handed to the firmware
    uint64_t landmark_matched = 0;    ///< ... that match a true marker of their class
    uint64_t false_markers = 0;       ///< landmark or robot sightings matching nothing
    uint64_t robot_sightings = 0;
    uint64_t robot_id_errors = 0;     ///< a robot sighting at a true robot with another id
    double range_rel_err_sum2 = 0.0;  ///< over matched landmark sightings
    double bearing_err_sum2 = 0.0;
};

class PixelCamera {
public:
    /// Throws std::runtime_error if the colour table or range model cannot
    /// be loaded or the detector cannot be created.
    PixelCamera(SimClock &clock, const World &world, int self_id, const PixelCameraConfig &cfg);
    ~PixelCamera();
    PixelCamera(const PixelCamera &) = delete;
    PixelCamera &operator=(const PixelCamera &) = delete;

    /// The firmware's sighting source.
    sighting_source_t *source() { return &tap_; }
    /// Render every frame due up to t_us at the world's current state; the
    /// body moves with (vx, vy) [m/s, robot frame] and w [rad/s].
    void set_time_us(uint64_t t_us, double vx, double vy, double w);
    /// Fault: a stalled camera delivers no frames (those falling due are skipped).
    void set_stalled(bool stalled) { stalled_ = stalled; }

    const std::vector<int> &detections() const { return detections_; }
    const PixelCameraStats &stats() const { return stats_; }
    /// Detections over the filter's view, per frame the firmware received.
    const DetectionTally &detection_tally() const { return tally_; }
    const vision_source_counters_t &source_counters() const { return vs_.ctr; }
    SimCamera &camera() { return cam_; }
    CameraRenderer &renderer() { return renderer_; }
    /// The last rendered frame (RGB24, 320x240).
    const std::vector<uint8_t> &last_frame() const { return frame_; }

private:
    static hal_status_t op_next_frame(sighting_source_t *src, sighting_frame_t *out, uint32_t timeout_us);
    static const sighting_source_ops_t kTapOps;
    void evaluate(const sighting_frame_t &f);

    const World &world_;
    int self_;
    PixelCameraConfig cfg_;
    SimCamera cam_;
    CameraRenderer renderer_;
    vision_detector_t *det_ = nullptr;
    vision_source_t vs_{};
    sighting_source_t tap_{};
    std::vector<uint8_t> frame_, grab_buf_;
    uint64_t next_us_;
    uint32_t pushed_seq_ = 0;
    struct FrameTruth {
        uint32_t seq = 0;
        std::vector<RenderedMarker> markers;
        std::vector<ViewedLandmark> viewed;  ///< the filter's view from the rendering pose
    };
    std::deque<FrameTruth> truth_;  ///< recent frames' truth by sequence
    std::vector<uint8_t> detected_scratch_;
    DetectionTally tally_;
    std::vector<RenderedMarker> scratch_;
    std::vector<int> detections_;
    PixelCameraStats stats_;
    bool stalled_ = false;
};

}  // namespace coslam::sim

#endif
