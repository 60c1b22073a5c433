// sim/world/camera_renderer.hpp - the pixel-level simulated camera: renders
// the 2.5-D world (walls, boxes and pillars of unbounded height, a tiled
// floor, landmark markers on tubes, robots with their markers) into the
// camera's RGB24 frames, as the robot's webcam would see it. The camera and
// the markers are vision/marker_spec.h's, shared with the detector.
//
// Image formation, per frame:
//  - geometry: a ray per sub-column (subcolumns per pixel column, default
//    2) through the pinhole; the nearest wall segment or pillar ends it;
//    robot bodies and landmark tubes (vertical cylinders) in front of it
//    are layers with a vertical extent (tube z in [0.25, 0.45] m, robot
//    [0, 0.45] m), composited far to near with their exact vertical pixel
//    coverage (so band edges fall between rows as they do on a sensor);
//    below the horizon the floor shows until the wall's foot;
//  - light: surface albedo (linear) x shading (ambient + directional,
//    Lambert on the cylinder's or wall's normal; each marker also gets a
//    fixed random paper/dirt factor) x a slowly varying illumination field
//    over the arena x a per-frame global gain (auto-exposure error) x a
//    per-frame white balance error x vignetting;
//  - motion blur: the view is rendered at mid-exposure (the exposure ends
//    at the frame's time) and slid sideways over the exposure by the
//    robot's turn and sideways motion (a horizontal box blur);
//  - optics and sensor: Gaussian blur (sigma optical_blur_px), sRGB
//    encoding, read + shot noise, 8-bit quantisation; a small random pitch
//    jitter per frame (a robot on a real floor rocks);
//  - decor: posters (flat colour patches, some in the markers' colours) on
//    walls away from markers, which the detector must not take for markers.
// Ground truth per frame: the class of each pixel (vision_colour_t of the
// surface seen at the pixel's centre, before noise: the labelled pixels the
// colour classifier learns from) and, per marker in front of the camera,
// its true range, bearing, projected size and the fraction of it that is
// not hidden.
//
// All randomness from one seeded core RNG (config.seed): the same seed and
// the same sequence of render() calls give the same pixels.
#ifndef COSLAM_SIM_WORLD_CAMERA_RENDERER_HPP
#define COSLAM_SIM_WORLD_CAMERA_RENDERER_HPP

#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "sim/world/world.hpp"
#include "vision/marker_spec.h"

namespace coslam::sim {

struct CameraRendererConfig {
    uint32_t width_px = VISION_IMAGE_WIDTH_PX;
    uint32_t height_px = VISION_IMAGE_HEIGHT_PX;
    double focal_px = VISION_FOCAL_PX;
    double cx_px = VISION_CX_PX;
    double cy_px = VISION_CY_PX;
    double camera_height_m = VISION_CAMERA_HEIGHT_M;
    int subcolumns = 2;               ///< rays per pixel column (horizontal anti-aliasing)
    // light
    double gain_min = 0.6;            ///< per-frame global gain, log-uniform in [min, max]
    double gain_max = 1.4;
    double white_balance_sd = 0.05;   ///< per-frame relative gain error of R and B
    double ambient = 0.55;            ///< shade = ambient + (1 - ambient) max(0, n . light)
    double marker_albedo_min = 0.75;  ///< fixed per marker: paper, print, dirt
    double marker_albedo_max = 1.1;
    double illumination_var = 0.2;    ///< amplitude of the arena's illumination field
    double vignetting = 0.2;          ///< relative fall-off at the image corners
    // motion, optics, sensor
    double exposure_ms = 25.0;
    double optical_blur_px = 0.6;     ///< Gaussian sigma; 0: none
    double read_noise_dn = 2.0;       ///< sd in 8-bit units
    double shot_noise_dn = 0.5;       ///< variance per unit of signal (sd = sqrt(read^2 + shot * value))
    double pitch_jitter_deg = 0.3;    ///< sd per frame
    // decor
    double posters_per_m = 0.12;      ///< coloured patches per metre of wall
    uint64_t seed = 1;
};

/// Ground truth of one marker in a rendered frame (markers whose axis is in
/// front of the camera within 12 m).
struct RenderedMarker {
    vision_marker_kind_t kind = VISION_MARKER_NONE;
    int index = 0;              ///< signature (landmark) or robot id
    int landmark_id = -1;       ///< the world's landmark id; -1 for a robot
    double range_m = 0.0;       ///< camera (robot centre) to the marker's axis, mid-exposure
    double bearing_rad = 0.0;   ///< of the axis, mid-exposure
    double u_px = 0.0;          ///< projected axis column
    double h_px = 0.0;          ///< projected marker height (near surface)
    double half_width_rad = 0.0;///< half the angle its silhouette spans
    double u_min = 0.0, u_max = 0.0;  ///< the silhouette's columns (may lie outside the image)
    double visible = 0.0;       ///< fraction of its silhouette's columns that show it (occlusion and image edges)
    bool whole_rows = false;    ///< its top and bottom rows are inside the image
};

class CameraRenderer {
public:
    /// world must outlive the renderer. Posters are placed from the seed.
    CameraRenderer(const World &world, const CameraRendererConfig &cfg);

    /// Render the frame whose exposure ends with the camera at `pose`
    /// (world frame) while its body moves with (vx, vy) [m/s, robot frame]
    /// and w [rad/s]. self_body: the camera's own robot (not rendered;
    /// -1 for none). rgb: width*height*3 bytes (stride 3*width). labels
    /// (may be null): width*height class ids. truth (may be null): the
    /// markers in front of the camera.
    void render(const pose2_t &pose, double vx, double vy, double w, int self_body, uint8_t *rgb, uint8_t *labels,
                std::vector<RenderedMarker> *truth);

    const CameraRendererConfig &config() const { return cfg_; }
    /// The global gain of the last frame.
    double last_gain() const { return gain_; }

    /// Override the per-frame randomness of the next render() (tests,
    /// evaluation sweeps): gain (<= 0: draw), shading factor per marker.
    void set_next_gain(double gain) { forced_gain_ = gain; }

private:
    struct Poster {
        int segment;
        double s0, s1, z0, z1;   ///< along the segment [m], height [m]
        std::array<float, 3> albedo;
        uint8_t label;
    };
    struct Layer;
    void render_subframe(const pose2_t &cam, double cy, int self_body, float weight, bool want_labels,
                         uint8_t *labels, std::vector<int> *vis_cols);
    double illumination(double x, double y) const;
    void update_world_properties();

    const World &world_;
    CameraRendererConfig cfg_;
    rng_t rng_;
    std::vector<Poster> posters_;
    std::vector<std::array<float, 3>> wall_albedo_;    ///< per wall segment
    std::vector<float> landmark_albedo_;               ///< per landmark (paper factor)
    std::array<float, 16> robot_albedo_{};             ///< per robot id
    std::array<std::array<float, 3>, VISION_N_COLOURS> colour_lin_{};
    double light_dir_ = 0.0;                           ///< azimuth of the directional light
    double field_phase_[4] = {0, 0, 0, 0};
    std::vector<float> acc_;                           ///< linear RGB accumulation, W*H*3
    std::vector<float> blurred_;
    std::array<float, 4096> gauss_{};                  ///< N(0,1) draws for the sensor noise
    std::array<float, 1025> sin_table_{};              ///< sin over one turn
    cv::Mat motion_;                                   ///< after the motion blur
    std::vector<float> vignette_;                      ///< per pixel
    double gain_ = 1.0, forced_gain_ = 0.0;
    std::array<double, 3> wb_{1.0, 1.0, 1.0};
};

/// The class (vision_colour_t) of each 8-bit sRGB reference colour, and
/// sRGB <-> linear helpers shared by the renderer and the host tools.
float srgb_to_linear(float v01);
float linear_to_srgb(float lin);

}  // namespace coslam::sim

#endif
