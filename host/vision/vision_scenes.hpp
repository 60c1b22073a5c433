// host/vision/vision_scenes.hpp - rendered scenes with known markers for the
// vision host tools (training, range fit, evaluation, benchmark) and the
// vision tests: random camera poses in the paper's arena
// (sim/scenarios/paper.toml), another robot in view in most of them, random
// occluding posts in front of the camera in some, random motion (blur) and
// lighting; each scene is a function of its seed. Plus the matching of
// detections to the renderer's ground truth, and image helpers (PNG,
// colour-class image, annotation).
#ifndef COSLAM_HOST_VISION_SCENES_HPP
#define COSLAM_HOST_VISION_SCENES_HPP

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "sim/world/camera_renderer.hpp"
#include "sim/world/scenario.hpp"
#include "sim/world/world.hpp"
#include "vision/vision.h"

namespace coslam::vision_host {

/// The paper scenario file of the source tree.
std::string paper_scenario_path();

/// The world of a scenario (arena, boxes, pillars, walls, landmarks), as
/// the simulator builds it; no robot bodies.
void build_world(const sim::Scenario &sc, sim::World &world);

struct SceneOptions {
    double p_other_robot = 0.6;     ///< another robot in front of the camera
    double p_posts = 0.4;           ///< 1-3 thin occluding posts in front of the camera
    double gain_min = 0.45;         ///< global light gain, log-uniform (wider than the simulator's)
    double gain_max = 1.8;
    double max_turn_rps = 0.8;      ///< |w| during the exposure
    double max_speed_mps = 0.3;
};

struct Scene {
    sim::World world;
    int self_id = 0;
    pose2_t cam{0, 0, 0};
    double vx = 0, vy = 0, w = 0;
    double gain = 1.0;
    uint64_t seed = 0;
};

/// Scene number `seed` in the world of sc.
Scene make_scene(const sim::Scenario &sc, uint64_t seed, const SceneOptions &opt = {});

struct Frame {
    std::vector<uint8_t> rgb;                    ///< 320x240 RGB24
    std::vector<uint8_t> labels;                 ///< class per pixel
    std::vector<sim::RenderedMarker> truth;
    double gain = 1.0;
};

/// Render a scene (renderer config `base`, seeded with the scene's seed).
Frame render_scene(const Scene &s, const sim::CameraRendererConfig &base = {});

/// Ground truth a detector should find: whole rows, at least `min_visible`
/// of it showing, range in [min_range, max_range]; with min_visible >= 0.95
/// also its whole silhouette inside the image with 2 pixels to spare (a
/// marker cut by the image edge has no measurable centre).
bool expected(const sim::RenderedMarker &m, double min_visible, double min_range_m = 0.3, double max_range_m = 5.0);

/// Matching of one frame's detections with its truth.
struct FrameMatch {
    struct Hit {
        int truth = -1;            ///< index into truth, -1: none
        bool same_identity = false;///< same kind and class/id
    };
    std::vector<Hit> det;          ///< per detected marker
    std::vector<int> truth_det;    ///< per truth marker: index of the matching detection (same identity) or -1
};

/// A detection matches a truth marker if its bearing is within the marker's
/// silhouette (half-width + 1 deg, at least 3 deg: a partly hidden marker's
/// centre moves) and |range error| < 30 % of the range. Same-identity matches first; a
/// detection that only matches a marker of another class/id is an identity
/// error; one that matches nothing is a false marker.
FrameMatch match_frame(const vision_result_t &res, const std::vector<sim::RenderedMarker> &truth);

/// Colour to draw a class with (BGR, for OpenCV drawing).
cv::Scalar class_bgr(uint8_t colour);
/// The class image as a colour picture (RGB24 Mat).
cv::Mat classes_picture(const uint8_t *classes, int w, int h);
/// A copy of the RGB image, scaled by `scale` (1 or 2), with boxes and
/// labels for the markers (RGB24 Mat); truth: ticks under the true markers.
cv::Mat annotate(const cv::Mat &rgb, const vision_result_t &res, const std::vector<sim::RenderedMarker> *truth = nullptr,
                 int scale = 2);
/// Write an RGB24 Mat as PNG/JPEG (by extension). False on failure.
bool write_rgb(const std::string &path, const cv::Mat &rgb);
/// The same, checked: throws cli::WriteError ("cannot write PATH: the OS's
/// reason") when the file cannot be written whole, std::runtime_error when
/// the extension has no encoder.
void write_rgb_checked(const std::string &path, const cv::Mat &rgb);

/// Load the shipped (or given) colour table and range model; throws
/// std::runtime_error with the reason.
void load_vision_data(const std::string &lut_path, const std::string &model_path, vision_lut_t *lut,
                      vision_range_model_t *model);

/// RGB24 -> YUYV 4:2:2 as a webcam delivers it (BT.601, limited range: the
/// inverse of OpenCV's COLOR_YUV2RGB_YUYV, which the detector uses).
std::vector<uint8_t> rgb_to_yuyv(const uint8_t *rgb, int w, int h);

/// Quantiles of a sample (q in [0,1], linear interpolation); NaN if empty.
double quantile(std::vector<double> v, double q);

}  // namespace coslam::vision_host

#endif
