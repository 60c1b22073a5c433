// The pixel-level simulated camera (sim/world camera_renderer, pixel_camera):
// reproducible pixels, geometry that agrees with the marker spec, the
// firmware's sighting source on rendered frames, the camera source switch
// of the scenario, and a short run of the paper scenario on pixels.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "sim/world/camera_renderer.hpp"
#include "sim/world/pixel_camera.hpp"
#include "sim/world/scenario.hpp"
#include "sim/world/simulation.hpp"
#include "vision_scenes.hpp"

using namespace coslam;
using namespace coslam::sim;
using namespace coslam::vision_host;

namespace {

constexpr int W = VISION_IMAGE_WIDTH_PX, H = VISION_IMAGE_HEIGHT_PX;
constexpr double kDeg = COSLAM_PI / 180.0;

// A room with one landmark 3 m ahead of a camera at the origin and a robot.
void small_world(World &w)
{
    w.add_polygon({{-1, -4}, {6, -4}, {6, 4}, {-1, 4}});
    w.add_landmark(Eigen::Vector2d(3.0, 0.5), 2);
    w.set_body(0, pose2_t{0, 0, 0}, 0.19);
    w.set_body(3, pose2_t{2.0, -0.4, 1.0}, 0.19);
}

}  // namespace

TEST(Renderer, SameSeedSamePixelsOtherSeedOtherNoise)
{
    World w;
    small_world(w);
    CameraRendererConfig c;
    c.seed = 5;
    CameraRenderer a(w, c), b(w, c);
    c.seed = 6;
    CameraRenderer other(w, c);
    std::vector<uint8_t> fa(W * H * 3), fb(fa.size()), fo(fa.size());
    for (int k = 0; k < 3; ++k) {
        a.render(pose2_t{0, 0, 0}, 0.1, 0, 0.3, 0, fa.data(), nullptr, nullptr);
        b.render(pose2_t{0, 0, 0}, 0.1, 0, 0.3, 0, fb.data(), nullptr, nullptr);
        EXPECT_EQ(fa, fb) << "frame " << k;
    }
    other.render(pose2_t{0, 0, 0}, 0.1, 0, 0.3, 0, fo.data(), nullptr, nullptr);
    EXPECT_NE(fa, fo);
}

TEST(Renderer, MarkersLandWhereThePinholePutsThem)
{
    World w;
    small_world(w);
    CameraRendererConfig c;
    c.pitch_jitter_deg = 0.0;
    c.read_noise_dn = 0.0;
    c.shot_noise_dn = 0.0;
    c.optical_blur_px = 0.0;
    c.posters_per_m = 0.0;
    CameraRenderer r(w, c);
    std::vector<uint8_t> rgb(W * H * 3), lab(W * H);
    std::vector<RenderedMarker> truth;
    r.render(pose2_t{0, 0, 0}, 0, 0, 0, 0, rgb.data(), lab.data(), &truth);
    ASSERT_EQ(truth.size(), 2u);
    const RenderedMarker &lm = truth[0];
    EXPECT_EQ(lm.kind, VISION_MARKER_LANDMARK);
    EXPECT_EQ(lm.index, 2);
    EXPECT_NEAR(lm.range_m, std::hypot(3.0, 0.5), 1e-9);
    EXPECT_NEAR(lm.bearing_rad, std::atan2(0.5, 3.0), 1e-9);
    EXPECT_NEAR(lm.u_px, VISION_CX_PX - VISION_FOCAL_PX * 0.5 / 3.0, 1e-9);
    EXPECT_NEAR(lm.visible, 1.0, 0.05);
    EXPECT_TRUE(lm.whole_rows);
    // the labels: the landmark's colours around its column, top over bottom
    const int u = static_cast<int>(std::lround(lm.u_px));
    const vision_pair_t p = vision_landmark_pairs[2];
    const double near = 3.0 - VISION_LANDMARK_RADIUS_M;
    const int v_top = static_cast<int>(std::lround(VISION_CY_PX - VISION_FOCAL_PX * 0.05 / near));
    const int v_bot = static_cast<int>(std::lround(VISION_CY_PX + VISION_FOCAL_PX * 0.05 / near));
    EXPECT_EQ(lab[static_cast<size_t>(v_top * W + u)], p.top);
    EXPECT_EQ(lab[static_cast<size_t>(v_bot * W + u)], p.bottom);
    EXPECT_EQ(lab[static_cast<size_t>(5 * W + u)], VISION_COLOUR_NONE);  // the wall above
    // the robot (id 3) and its pair
    EXPECT_EQ(truth[1].kind, VISION_MARKER_ROBOT);
    EXPECT_EQ(truth[1].index, 3);
    const int ur = static_cast<int>(std::lround(truth[1].u_px));
    EXPECT_EQ(lab[static_cast<size_t>((v_top + 2) * W + ur)], vision_robot_pairs[3].top);
}

TEST(PixelCamera, TheFirmwareSourceSeesTheRenderedMarkers)
{
    World w;
    small_world(w);
    SimClock clock(0);
    PixelCameraConfig pc;
    pc.period_us = 200000;
    PixelCamera cam(clock, w, 0, pc);
    sighting_source_t *src = cam.source();
    sighting_frame_t f;
    EXPECT_EQ(sighting_source_next_frame(src, &f, 0), HAL_E_TIMEOUT);
    int frames = 0, lm = 0, rb = 0;
    for (uint64_t t = 0; t <= 2000000; t += 10000) {
        clock.advance_to(t);
        cam.set_time_us(t, 0.0, 0.0, 0.0);
        if (sighting_source_next_frame(src, &f, 0) != HAL_OK) continue;
        ++frames;
        for (int i = 0; i < f.n_landmarks; ++i) {
            EXPECT_EQ(f.landmarks[i].signature, 2);
            EXPECT_NEAR(f.landmarks[i].range_m, std::hypot(3.0, 0.5), 0.1);
            EXPECT_NEAR(f.landmarks[i].bearing_rad, std::atan2(0.5, 3.0), 0.5 * kDeg);
            ++lm;
        }
        for (int i = 0; i < f.n_robots; ++i) {
            EXPECT_EQ(f.robots[i].robot_id, 3);
            EXPECT_NEAR(f.robots[i].range_m, std::hypot(2.0, 0.4), 0.1);
            EXPECT_NEAR(f.robots[i].bearing_rad, std::atan2(-0.4, 2.0), 1.0 * kDeg);
            ++rb;
        }
    }
    EXPECT_EQ(frames, 11);  // 5 Hz over [0, 2] s
    EXPECT_GE(lm, 10);
    EXPECT_GE(rb, 10);
    EXPECT_EQ(cam.stats().false_markers, 0u);
    EXPECT_EQ(cam.stats().robot_id_errors, 0u);
    EXPECT_EQ(cam.detections()[0], lm);
    EXPECT_EQ(cam.camera().stats().grabbed, 11u);
}

TEST(PixelCamera, MissingDataFilesAreReported)
{
    World w;
    small_world(w);
    SimClock clock(0);
    PixelCameraConfig pc;
    pc.lut_path = "/nonexistent/lut.bin";
    EXPECT_THROW(PixelCamera(clock, w, 0, pc), std::runtime_error);
}

TEST(CameraSource, ScenarioKeyAndDefault)
{
    const Scenario paper = load_scenario_file(paper_scenario_path());
    EXPECT_EQ(paper.camera.source, CameraSource::Pixels);  // the default
    const std::string base = "[[robot]]\nstart = [0, 0, 0]\n[[robot]]\nstart = [1, 0, 0]\n";
    EXPECT_EQ(load_scenario_string("[camera]\nsource = \"oracle\"\n" + base).camera.source, CameraSource::Oracle);
    EXPECT_EQ(load_scenario_string("[camera]\nsource = \"pixels\"\n" + base).camera.source, CameraSource::Pixels);
    try {
        load_scenario_string("[camera]\nsource = \"lidar\"\n" + base);
        FAIL() << "accepted a bad camera source";
    } catch (const ScenarioError &e) {
        EXPECT_NE(std::string(e.what()).find("camera.source"), std::string::npos) << e.what();
    }
    EXPECT_EQ(parse_camera_source("oracle"), CameraSource::Oracle);
    EXPECT_STREQ(camera_source_name(CameraSource::Pixels), "pixels");
    // the pixel camera is 50 deg wide: another field of view needs the stand-in
    Scenario wide = paper;
    wide.camera.fov_deg = 70.0;
    EXPECT_THROW(Simulation(wide, SimulationOptions{1u, 1.0}), ScenarioError);
    wide.camera.source = CameraSource::Oracle;
    EXPECT_NO_THROW(Simulation(wide, SimulationOptions{1u, 1.0}));
}

TEST(CameraSource, PaperScenarioOnPixelsSeesWhatTheStandInSees)
{
    Scenario sc = load_scenario_file(paper_scenario_path());
    sc.camera.source = CameraSource::Oracle;
    Simulation oracle(sc, SimulationOptions{1u, 30.0});
    oracle.run();
    std::set<int> seen_oracle;
    for (size_t k = 0; k < 2; ++k) {
        for (size_t j = 0; j < oracle.robot(k).detections().size(); ++j) {
            if (oracle.robot(k).detections()[j] > 0) seen_oracle.insert(static_cast<int>(j));
        }
    }
    sc.camera.source = CameraSource::Pixels;
    Simulation sim(sc, SimulationOptions{1u, 30.0});
    ASSERT_EQ(sim.camera_source(), CameraSource::Pixels);
    sim.run();
    std::set<int> seen;
    for (size_t k = 0; k < 2; ++k) {
        const PixelCamera *pc = sim.robot(k).pixel_camera();
        ASSERT_NE(pc, nullptr);
        EXPECT_GE(pc->stats().frames, 149u);
        EXPECT_GT(pc->stats().landmark_sightings, 100u);
        EXPECT_EQ(pc->stats().false_markers, 0u);
        EXPECT_EQ(pc->stats().robot_id_errors, 0u);
        EXPECT_GT(robot_node_counters(&sim.node(k))->frames, 140u);
        for (size_t j = 0; j < sim.robot(k).detections().size(); ++j) {
            if (sim.robot(k).detections()[j] > 0) seen.insert(static_cast<int>(j));
        }
    }
    // the same landmarks, give or take one (the paths differ once the sightings do)
    std::printf("landmarks seen in 30 s: pixels %zu, stand-in %zu\n", seen.size(), seen_oracle.size());
    EXPECT_GE(seen.size() + 1, seen_oracle.size());
    EXPECT_GE(seen.size(), 6u);
    EXPECT_THROW(sim.robot(0).oracle(), std::logic_error);
}
