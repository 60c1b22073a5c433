// The simulated world piece by piece: geometry queries against analytic
// values, the camera stand-in (field of view, range, occlusion, timing,
// seeded noise statistics, detection rate), scenario parsing and its error
// messages, a robot's physics through the real drive driver on the CAN
// emulators (motion, collision, bumper), a node's start-up and its e-stop
// on the simulated GPIO, and the run outputs on disk.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "cia402/cia402_omni.h"
#include "run_output.hpp"
#include "sim/world/scenario.hpp"
#include "sim/world/sighting_oracle.hpp"
#include "sim/world/sim_robot.hpp"
#include "sim/world/simulation.hpp"
#include "sim/world/world.hpp"

using namespace coslam::sim;
using Eigen::Vector2d;

namespace {

constexpr double kDeg = COSLAM_PI / 180.0;
const std::string kPaper = std::string(COSLAM_SOURCE_DIR) + "/sim/scenarios/paper.toml";

// A small valid scenario: `top` goes before the first table (root keys),
// `tail` after the robots (more tables).
std::string scenario_text(const std::string &top = "", const std::string &robots = "", const std::string &tail = "")
{
    return top + R"(
name = "t"
duration_s = 5.0
[world]
arena = [[-3.0, -3.0], [3.0, -3.0], [3.0, 3.0], [-3.0, 3.0]]
landmarks = [ { pos = [2.9, 0.0], signature = 1 } ]
)" + (robots.empty() ? R"(
[[robot]]
start = [-1.0, 0.0, 180.0]
[[robot]]
start = [1.0, 0.0, 0.0]
filter = "ekf"
)"
                     : robots) +
           tail;
}

}  // namespace

// ---------------------------------------------------------------------------
// geometry
// ---------------------------------------------------------------------------

TEST(World, RaycastHitsWallsBoxesPillarsAndBodies)
{
    World w;
    w.add_wall(Vector2d(3.0, -5.0), Vector2d(3.0, 5.0));
    w.add_box(Vector2d(1.0, 2.0), Vector2d(0.4, 0.4), 0.0);
    w.add_pillar(Vector2d(-2.0, 0.0), 0.5);
    w.set_body(5, pose2_t{0.0, -1.0, 0.0}, 0.2);
    EXPECT_NEAR(w.raycast(Vector2d(0, 0), Vector2d(1, 0), 10.0), 3.0, 1e-12);
    EXPECT_NEAR(w.raycast(Vector2d(1.0, 0.0), Vector2d(0, 1), 10.0), 1.8, 1e-12);
    EXPECT_NEAR(w.raycast(Vector2d(0, 0), Vector2d(-1, 0), 10.0), 1.5, 1e-12);
    EXPECT_NEAR(w.raycast(Vector2d(0, 0), Vector2d(0, -1), 10.0), 0.8, 1e-12);
    EXPECT_TRUE(std::isinf(w.raycast(Vector2d(0, 0), Vector2d(0, -1), 10.0, 5)));        // own body excluded
    EXPECT_TRUE(std::isinf(w.raycast(Vector2d(0, 0), Vector2d(0, -1), 10.0, -1, false))); // bodies off
    EXPECT_TRUE(std::isinf(w.raycast(Vector2d(0, 0), Vector2d(1, 0), 2.9)));              // beyond max
    // a 45 degree ray against the box corner region: enters the west face
    const Vector2d d = Vector2d(1, 1).normalized();
    EXPECT_NEAR(w.raycast(Vector2d(-0.2, 0.9), d, 10.0), std::sqrt(2.0) * 1.0, 1e-9);
    EXPECT_NEAR(w.raycast(Vector2d(-0.2, 0.4), d, 10.0), std::sqrt(2.0) * 1.4, 1e-9); // just misses it: south face
    // from inside a body (not excluded) the ray meets its rim on the way out
    EXPECT_NEAR(w.raycast(Vector2d(0.0, -1.0), Vector2d(1, 0), 10.0), 0.2, 1e-12);
}

TEST(World, LineOfSightAndClearance)
{
    World w;
    w.add_polygon({Vector2d(-3, -3), Vector2d(3, -3), Vector2d(3, 3), Vector2d(-3, 3)});
    const Vector2d marker(3.0, 0.0); // on the wall
    EXPECT_TRUE(w.line_of_sight(Vector2d(0, 0), marker, -1, -1)); // not hidden by its own wall
    EXPECT_FALSE(w.line_of_sight(Vector2d(0, 0), marker, -1, -1, 0.0));
    w.add_box(Vector2d(1.5, 0.0), Vector2d(0.2, 0.2), 0.3);
    EXPECT_FALSE(w.line_of_sight(Vector2d(0, 0), marker, -1, -1));
    EXPECT_TRUE(w.line_of_sight(Vector2d(0, 1), Vector2d(2.98, 1.0), -1, -1));
    w.set_body(1, pose2_t{1.0, 1.0, 0.0}, 0.2);
    EXPECT_FALSE(w.line_of_sight(Vector2d(0, 1), Vector2d(2.98, 1.0), -1, -1));
    EXPECT_TRUE(w.line_of_sight(Vector2d(0, 1), Vector2d(2.98, 1.0), -1, 1));
    EXPECT_NEAR(w.static_clearance(Vector2d(2.5, 2.0)), 0.5, 1e-12);
    EXPECT_NEAR(w.body_clearance(Vector2d(1.0, 2.0), -1), 0.8, 1e-12);
    EXPECT_TRUE(std::isinf(w.body_clearance(Vector2d(1.0, 2.0), 1)));
}

// ---------------------------------------------------------------------------
// the camera stand-in
// ---------------------------------------------------------------------------

namespace {

SightingOracleConfig exact_oracle()
{
    SightingOracleConfig c;
    c.p_detect = 1.0;
    c.robot_p_detect = 1.0;
    c.range_sd_m = c.range_sd_rel = c.bearing_sd_rad = 0.0;
    c.robot_range_sd_m = c.robot_bearing_sd_rad = 0.0;
    return c;
}

}  // namespace

TEST(SightingOracle, FieldOfViewRangeOcclusionAndRobots)
{
    World w;
    w.set_body(0, pose2_t{0.0, 0.0, 0.5}, 0.19);
    const pose2_t me{0.0, 0.0, 0.5};
    auto at = [&](double r, double b) { return Vector2d(r * std::cos(me.theta + b), r * std::sin(me.theta + b)); };
    w.add_landmark(at(2.0, 0.1), 1);           // 0 visible
    w.add_landmark(at(2.0, 30.0 * kDeg), 2);   // 1 outside +-25 deg
    w.add_landmark(at(5.5, 0.0), 3);           // 2 too far
    w.add_landmark(at(0.2, 0.0), 0);           // 3 too near
    w.add_landmark(at(3.0, -0.2), 1);          // 4 behind a box
    w.add_box(at(1.5, -0.2), Vector2d(0.2, 0.2), 0.0);
    w.add_landmark(at(4.0, 0.2), 2);           // 5 behind robot 2
    w.set_body(2, pose2_t{at(2.5, 0.2).x(), at(2.5, 0.2).y(), 0.0}, 0.19);
    w.set_body(3, pose2_t{at(1.0, -0.35).x(), at(1.0, -0.35).y(), 0.0}, 0.19); // a robot in view
    SightingOracle o(w, 0, exact_oracle());
    sighting_frame_t f;
    EXPECT_EQ(sighting_source_next_frame(o.source(), &f, 0), HAL_E_TIMEOUT);
    o.set_time_us(0);
    ASSERT_EQ(sighting_source_next_frame(o.source(), &f, 0), HAL_OK);
    ASSERT_EQ(f.n_landmarks, 1u);
    EXPECT_NEAR(f.landmarks[0].range_m, 2.0, 1e-12);
    EXPECT_NEAR(f.landmarks[0].bearing_rad, 0.1, 1e-12);
    EXPECT_EQ(f.landmarks[0].signature, 1);
    ASSERT_EQ(f.n_robots, 2u);
    // robot 2 (in view, nothing between) and robot 3; never itself
    std::vector<int> ids = {f.robots[0].robot_id, f.robots[1].robot_id};
    std::sort(ids.begin(), ids.end());
    EXPECT_EQ(ids, (std::vector<int>{2, 3}));
    for (unsigned i = 0; i < f.n_robots; ++i) {
        if (f.robots[i].robot_id == 3) {
            EXPECT_NEAR(f.robots[i].range_m, 1.0, 1e-12);
            EXPECT_NEAR(f.robots[i].bearing_rad, -0.35, 1e-12);
        }
    }
    EXPECT_EQ(o.detections()[0], 1);
    for (size_t j = 1; j < 6; ++j) EXPECT_EQ(o.detections()[j], 0) << j;
    EXPECT_EQ(sighting_source_next_frame(o.source(), &f, 0), HAL_E_TIMEOUT); // never the same frame twice
}

TEST(SightingOracle, FrameTimingAndNewestFrameOnly)
{
    World w;
    w.set_body(0, pose2_t{0, 0, 0}, 0.19);
    SightingOracleConfig c = exact_oracle();
    c.period_us = 200000;
    c.phase_us = 100000;
    SightingOracle o(w, 0, c);
    sighting_frame_t f;
    o.set_time_us(99999);
    EXPECT_EQ(sighting_source_next_frame(o.source(), &f, 0), HAL_E_TIMEOUT);
    o.set_time_us(100000);
    ASSERT_EQ(sighting_source_next_frame(o.source(), &f, 0), HAL_OK);
    EXPECT_EQ(f.stamp_us, 100000u);
    EXPECT_EQ(f.sequence, 1u);
    o.set_time_us(650000); // frames at 300 and 500 ms: only the newest is handed out
    ASSERT_EQ(sighting_source_next_frame(o.source(), &f, 0), HAL_OK);
    EXPECT_EQ(f.stamp_us, 500000u);
    EXPECT_EQ(f.sequence, 3u); // the gap shows the skipped frame
    EXPECT_EQ(o.frames(), 3u);
}

TEST(SightingOracle, NoiseAndDetectionRateFollowTheConfiguration)
{
    World w;
    w.set_body(0, pose2_t{0, 0, 0}, 0.19);
    const double r0 = 3.0, b0 = 10.0 * kDeg;
    w.add_landmark(Vector2d(r0 * std::cos(b0), r0 * std::sin(b0)), 0);
    w.set_body(1, pose2_t{2.0, -0.3, 0.0}, 0.19);
    SightingOracleConfig c; // defaults: 2 cm + 3 %, 2 deg, p = 0.9
    c.period_us = 1000;
    SightingOracle o(w, 0, c);
    const int n = 4000;
    double sr = 0, srr = 0, sb = 0, sbb = 0, rr = 0;
    int got = 0, robots = 0;
    for (int i = 0; i < n; ++i) {
        o.set_time_us(static_cast<uint64_t>(i) * 1000u);
        sighting_frame_t f;
        ASSERT_EQ(sighting_source_next_frame(o.source(), &f, 0), HAL_OK);
        if (f.n_landmarks == 1) {
            const double er = f.landmarks[0].range_m - r0, eb = f.landmarks[0].bearing_rad - b0;
            sr += er, srr += er * er, sb += eb, sbb += eb * eb;
            got++;
        }
        if (f.n_robots == 1) {
            rr += std::pow(f.robots[0].range_m - std::hypot(2.0, 0.3), 2);
            robots++;
        }
    }
    const double sd_r = std::sqrt(0.02 * 0.02 + std::pow(0.03 * r0, 2));
    EXPECT_NEAR(static_cast<double>(got) / n, 0.9, 0.025);
    EXPECT_NEAR(static_cast<double>(robots) / n, 0.9, 0.025);
    EXPECT_LT(std::fabs(sr / got), 4.0 * sd_r / std::sqrt(got));
    EXPECT_NEAR(std::sqrt(srr / got) / sd_r, 1.0, 0.06);
    EXPECT_LT(std::fabs(sb / got), 4.0 * 2.0 * kDeg / std::sqrt(got));
    EXPECT_NEAR(std::sqrt(sbb / got) / (2.0 * kDeg), 1.0, 0.06);
    EXPECT_NEAR(std::sqrt(rr / robots) / 0.05, 1.0, 0.06);
    // seeded: the same seed gives the same frames, another seed others
    SightingOracle a(w, 0, c), b(w, 0, c);
    c.seed = 99;
    SightingOracle d(w, 0, c);
    sighting_frame_t fa, fb, fd;
    bool differ = false;
    for (int i = 0; i < 50; ++i) {
        a.set_time_us(static_cast<uint64_t>(i) * 1000u);
        b.set_time_us(static_cast<uint64_t>(i) * 1000u);
        d.set_time_us(static_cast<uint64_t>(i) * 1000u);
        sighting_source_next_frame(a.source(), &fa, 0);
        sighting_source_next_frame(b.source(), &fb, 0);
        sighting_source_next_frame(d.source(), &fd, 0);
        ASSERT_EQ(std::memcmp(&fa, &fb, sizeof fa), 0);
        differ = differ || std::memcmp(&fa, &fd, sizeof fa) != 0;
    }
    EXPECT_TRUE(differ);
}

// The detection tally (detection_tally.hpp): per delivered frame, the true
// landmarks the FILTER's view model calls in view (its own range, field of
// view and margin, not the camera's), with a clear line of sight or not, and
// how many of each were detected. A camera detecting with p 0.5 gives 0.5
// within 4 binomial sd over the clear ones; one behind a box is in view,
// never clear and never detected; one the camera sees but the filter's
// narrower view leaves out, and one beyond its range, are not counted; a
// frame taken but not delivered is not tallied.
TEST(SightingOracle, DetectionTallyOverTheFiltersView)
{
    World w;
    w.set_body(0, pose2_t{0, 0, 0}, 0.19);
    auto at = [&](double r, double b) { return Vector2d(r * std::cos(b), r * std::sin(b)); };
    w.add_landmark(at(2.0, 0.05), 0);          // 0 in view, clear
    w.add_landmark(at(3.0, -0.1), 1);          // 1 in view, clear
    w.add_landmark(at(3.0, 0.2), 2);           // 2 behind a box
    w.add_box(at(1.5, 0.2), Vector2d(0.2, 0.2), 0.0);
    w.add_landmark(at(2.5, 20.0 * kDeg), 3);   // 3 the camera's view (+-25 deg), not the filter's (+-15 deg x 0.9)
    w.add_landmark(at(4.8, 0.0), 0);           // 4 the camera's range (5 m), not the filter's (4 x 0.9)
    SightingOracleConfig c = exact_oracle();
    c.p_detect = 0.5;
    c.period_us = 1000;
    c.view_model = slam_params_default();
    c.view_model.sensor_fov_rad = 30.0 * kDeg;
    c.view_model.sensor_max_range_m = 4.0;
    c.view_model.visibility_margin = 0.9;
    SightingOracle o(w, 0, c);
    const int n = 2000;
    for (int i = 0; i < n; ++i) {
        o.set_time_us(static_cast<uint64_t>(i) * 1000u);
        sighting_frame_t f;
        ASSERT_EQ(sighting_source_next_frame(o.source(), &f, 0), HAL_OK);
    }
    o.set_time_us(static_cast<uint64_t>(n) * 1000u); // taken, never delivered
    const DetectionTally &t = o.detection_tally();
    EXPECT_EQ(t.frames, static_cast<uint64_t>(n));
    EXPECT_EQ(t.in_view, 3u * n);
    EXPECT_EQ(t.in_view_clear, 2u * n);
    EXPECT_EQ(t.detected, t.detected_clear); // the box hides landmark 2 from the camera too
    const double sd = std::sqrt(0.25 / t.in_view_clear);
    EXPECT_NEAR(detection_rate_clear(t), 0.5, 4.0 * sd);
    EXPECT_NEAR(detection_rate(t), 0.5 * 2.0 / 3.0, 4.0 * sd);
    // the camera did detect the ones outside the filter's view
    EXPECT_GT(o.detections()[3], n / 3);
    EXPECT_GT(o.detections()[4], n / 3);
    EXPECT_EQ(o.detections()[2], 0);
    // nothing in view: NaN, not 0
    EXPECT_TRUE(std::isnan(detection_rate(DetectionTally{})));
    EXPECT_TRUE(std::isnan(detection_rate_clear(DetectionTally{})));
}

// ---------------------------------------------------------------------------
// scenarios
// ---------------------------------------------------------------------------

TEST(Scenario, DefaultScenarioLoads)
{
    const Scenario sc = load_scenario_file(kPaper);
    EXPECT_EQ(sc.name, "paper");
    ASSERT_EQ(sc.robots.size(), 2u);
    EXPECT_EQ(sc.robots[0].filter, SLAM_FILTER_FASTSLAM2);
    EXPECT_EQ(sc.robots[0].particles, 100);
    EXPECT_EQ(sc.robots[1].filter, SLAM_FILTER_EKF);
    EXPECT_NEAR(std::fabs(sc.robots[0].start.theta), COSLAM_PI, 1e-12); // back to back
    EXPECT_NEAR(sc.robots[1].start.theta, 0.0, 1e-12);
    EXPECT_EQ(sc.world.landmarks.size(), 26u);
    EXPECT_EQ(sc.world.boxes.size(), 4u);
    EXPECT_EQ(sc.world.arena.size(), 4u);
    EXPECT_NEAR(sc.laser.fov_deg, 140.0, 1e-12);
    // several identical markers per class
    int per_class[4] = {0, 0, 0, 0};
    for (const auto &l : sc.world.landmarks) per_class[l.signature]++;
    for (int c : per_class) EXPECT_GE(c, 5);
}

TEST(Scenario, ErrorsNameTheKey)
{
    auto fails_with = [](const std::string &text, const std::string &needle) {
        try {
            load_scenario_string(text, "x.toml");
        } catch (const ScenarioError &e) {
            EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
            return;
        }
        ADD_FAILURE() << "no error for " << needle;
    };
    EXPECT_NO_THROW(load_scenario_string(scenario_text()));
    fails_with(scenario_text("durration_s = 3.0\n"), "durration_s: unknown key");
    fails_with(scenario_text("seed = \"one\"\n"), "seed: expected a non-negative integer");
    fails_with(scenario_text("", "", "[camera]\np_detect = 1.5\n"), "camera.p_detect: value 1.5 outside");
    fails_with(scenario_text("", "", "[camera]\nfov = 50\n"), "camera.fov: unknown key");
    fails_with(scenario_text("", "[[robot]]\nstart = [0, 0, 0]\n"), "at least two");
    fails_with(scenario_text("", "[[robot]]\nstart = [0, 0, 0]\n[[robot]]\nfilter = \"ekf\"\n"), "robot[1].start: missing");
    fails_with(scenario_text("", "[[robot]]\nstart = [0, 0, 0]\n[[robot]]\nstart = [1, 0]\n"),
               "robot[1].start: expected an array of 3 numbers");
    fails_with(scenario_text("", "[[robot]]\nstart = [0, 0, 0]\nfilter = \"ukf\"\n[[robot]]\nstart = [1, 0, 0]\n"),
               "unknown filter 'ukf'");
    fails_with(scenario_text("", "", "[timing]\nphysics_dt_ms = 3.0\ncontrol_period_ms = 10.0\n"),
               "multiple of physics_dt_ms");
    fails_with(scenario_text("", "", "[world]\n"), "x.toml:"); // a table defined twice: a TOML error with its place
    fails_with("name = \n", "x.toml:1");
    fails_with(scenario_text("", "[[robot]]\nstart = [0, 0, 0]\n[robot.noise]\nodo_xy = 1\n[[robot]]\nstart = [1, 0, 0]\n"),
               "robot[0].noise.odo_xy: unknown key");
    EXPECT_THROW(load_scenario_file("/nonexistent/x.toml"), ScenarioError);
    // a fault that would never happen (duration_s = 5 in scenario_text)
    fails_with(scenario_text("", "", "[[fault]]\nrobot = 1\nkind = \"laser_unplug\"\nat_s = 500\nduration_s = 2\n"),
               "fault[0].at_s: at_s 500 is at or after the run's end (duration_s 5 s)");
    fails_with(scenario_text("", "", "[[fault]]\nrobot = 1\nkind = \"kidnap\"\nat_s = 5\nto = [0, 1, 0]\n"),
               "at or after the run's end");
    EXPECT_NO_THROW(load_scenario_string(
        scenario_text("", "", "[[fault]]\nrobot = 1\nkind = \"laser_unplug\"\nat_s = 4.9\nduration_s = 20\n")));
    // a directory is not an empty scenario
    try {
        load_scenario_file(::testing::TempDir());
        ADD_FAILURE() << "a directory loaded";
    } catch (const ScenarioError &e) {
        EXPECT_NE(std::string(e.what()).find("is a directory"), std::string::npos) << e.what();
    }
}

TEST(Scenario, ValuesAndOverrides)
{
    const Scenario sc = load_scenario_string(scenario_text("seed = 42\n", R"(
[[robot]]
name = "a"
start = [-1.0, 0.5, 90.0]
particles = 30
filter = "fastslam1"
explore_s = 12.0
[robot.filter_noise]
bearing_sd_deg = 3.0
[[robot]]
start = [1.0, 0.0, 0.0]
[robot.noise]
odo_theta_sd_deg = 2.0
)",
                                                           "[noise]\nodo_xy_sd_m = 0.05\n"));
    EXPECT_EQ(sc.seed, 42u);
    EXPECT_EQ(sc.robots[0].name, "a");
    EXPECT_EQ(sc.robots[1].name, "robot1");
    EXPECT_NEAR(sc.robots[0].start.theta, 0.5 * COSLAM_PI, 1e-12);
    EXPECT_EQ(sc.robots[0].particles, 30);
    EXPECT_EQ(sc.robots[0].filter, SLAM_FILTER_FASTSLAM1);
    EXPECT_EQ(*sc.robots[0].explore_s, 12.0);
    EXPECT_EQ(*sc.robots[0].filter_noise.bearing_sd_deg, 3.0);
    EXPECT_FALSE(sc.robots[0].filter_noise.range_sd_m.has_value());
    EXPECT_EQ(sc.robots[0].noise.odo_xy_sd_m, 0.05); // scenario default
    EXPECT_EQ(sc.robots[1].noise.odo_xy_sd_m, 0.05);
    EXPECT_EQ(sc.robots[1].noise.odo_theta_sd_deg, 2.0); // robot override
}

// ---------------------------------------------------------------------------
// a robot's body on its drives: the real cia402_omni driver over the CAN emulators
// ---------------------------------------------------------------------------

namespace {

struct Rig {
    SimClock clock{0};
    World world;
    SimLinkHub hub{clock, 2};
    std::unique_ptr<SimRobot> robot;
    cia402_omni_t omni{};
    uint64_t now = 0;

    explicit Rig(const SimRobotConfig &c)
    {
        robot = std::make_unique<SimRobot>(clock, world, hub, c);
        const cia402_omni_config_t oc = cia402_omni_config_default();
        EXPECT_EQ(cia402_omni_init(&omni, &oc, robot->io().can), COSLAM_OK);
        EXPECT_EQ(cia402_omni_start(&omni, 0), COSLAM_OK);
    }
    void run_ms(int ms)
    {
        for (int i = 0; i < ms; ++i) {
            now += 1000;
            clock.advance_to(now);
            robot->physics_step(now, 0.001);
            cia402_omni_poll(&omni, now);
        }
    }
    void enable()
    {
        for (int i = 0; i < 500 && !cia402_omni_is_running(&omni); ++i) run_ms(1);
        ASSERT_EQ(cia402_omni_enable(&omni, 1), COSLAM_OK);
        for (int i = 0; i < 200 && !cia402_omni_is_enabled(&omni); ++i) run_ms(1);
        ASSERT_TRUE(cia402_omni_is_enabled(&omni));
    }
};

SimRobotConfig quiet_robot()
{
    SimRobotConfig c;
    c.odo_xy_var_m2_per_m = 0.0;
    c.odo_theta_var_rad2_per_m = 0.0;
    return c;
}

}  // namespace

TEST(SimRobot, WheelSpeedsFromTheDrivesMoveTheRobot)
{
    SimRobotConfig c = quiet_robot();
    c.start = pose2_t{1.0, 2.0, 0.3};
    Rig rig(c);
    rig.enable();
    const pose2_t p0 = rig.robot->pose();
    ASSERT_EQ(cia402_omni_set_body_velocity(&rig.omni, 0.2, 0.0, 0.3), COSLAM_OK);
    rig.run_ms(3000);
    // the closed-form arc from p0, minus what the 50 ms motor lag costs
    const double v = 0.2, w = 0.3, t = 3.0;
    const pose2_t arc = pose2_compose(p0, pose2_t{std::sin(w * t) * v / w, (1.0 - std::cos(w * t)) * v / w, w * t});
    const pose2_t p = rig.robot->pose();
    EXPECT_NEAR(p.x, arc.x, 0.03);
    EXPECT_NEAR(p.y, arc.y, 0.03);
    EXPECT_NEAR(angle_wrap(p.theta - arc.theta), 0.0, 0.03);
    EXPECT_NEAR(rig.robot->distance_m(), v * t, 0.02);
    EXPECT_EQ(rig.robot->wall_collisions(), 0u);
}

TEST(SimRobot, AWallStopsTheBodyAndPressesTheBumper)
{
    SimRobotConfig c = quiet_robot();
    Rig rig(c);
    rig.world.add_wall(Vector2d(0.6, -2.0), Vector2d(0.6, 2.0));
    hal_gpio_t *gpio = rig.robot->io().gpio;
    hal_gpio_config_t in{};
    in.dir = HAL_GPIO_DIR_INPUT;
    ASSERT_EQ(hal_gpio_configure(gpio, SimRobot::kBumperLine, &in), HAL_OK);
    ASSERT_EQ(hal_gpio_configure(gpio, SimRobot::kEstopLine, &in), HAL_OK);
    bool level = false;
    ASSERT_EQ(hal_gpio_read(gpio, SimRobot::kEstopLine, &level), HAL_OK);
    EXPECT_TRUE(level); // the e-stop loop is closed: released
    rig.enable();
    ASSERT_EQ(cia402_omni_set_body_velocity(&rig.omni, 0.2, 0.0, 0.0), COSLAM_OK);
    rig.run_ms(4000);
    EXPECT_LE(rig.robot->pose().x, 0.6 - c.radius_m + 1e-9);
    EXPECT_GT(rig.robot->pose().x, 0.6 - c.radius_m - 0.01);
    EXPECT_TRUE(rig.robot->in_contact());
    EXPECT_EQ(rig.robot->wall_collisions(), 1u); // one contact episode, however long
    ASSERT_EQ(hal_gpio_read(gpio, SimRobot::kBumperLine, &level), HAL_OK);
    EXPECT_TRUE(level);
    EXPECT_LT(rig.robot->min_wall_clearance_m(), 1e-3);
    // backing off releases the bumper
    ASSERT_EQ(cia402_omni_set_body_velocity(&rig.omni, -0.2, 0.0, 0.0), COSLAM_OK);
    rig.run_ms(1000);
    ASSERT_EQ(hal_gpio_read(gpio, SimRobot::kBumperLine, &level), HAL_OK);
    EXPECT_FALSE(level);
}

// ---------------------------------------------------------------------------
// a whole node on the simulated devices
// ---------------------------------------------------------------------------

TEST(Simulation, NodesStartUpAndTheEstopStopsTheRobot)
{
    Scenario sc = load_scenario_file(kPaper);
    Simulation sim(sc, SimulationOptions{std::nullopt, 20.0});
    sim.advance_to(4.0);
    for (size_t k = 0; k < 2; ++k) {
        EXPECT_EQ(robot_node_state(&sim.node(k)), ROBOT_NODE_RUN);
        EXPECT_GT(robot_node_counters(&sim.node(k))->scans, 30u);  // 10 Hz URG over SCIP
        EXPECT_GT(robot_node_counters(&sim.node(k))->frames, 15u); // 5 Hz sightings
        EXPECT_EQ(robot_node_laser_stats(&sim.node(k))->err_checksum, 0u);
        EXPECT_GT(sim.robot(k).distance_m(), 0.3); // exploring
    }
    // cut robot 0's e-stop loop: it must stand still within half a second
    sim.robot(0).gpio().set_input_level(SimRobot::kEstopLine, false);
    sim.advance_to(4.5);
    const pose2_t p = sim.robot(0).pose();
    const double d1 = sim.robot(1).distance_m();
    sim.advance_to(6.0);
    EXPECT_LT(std::hypot(sim.robot(0).pose().x - p.x, sim.robot(0).pose().y - p.y), 0.005);
    EXPECT_GT(sim.robot(1).distance_m() - d1, 0.2); // the other robot goes on
    EXPECT_GT(robot_node_counters(&sim.node(0))->stop_steps, 100u);
    // the status LED blinks fast while stopped (the firmware drives line 2)
    int toggles = 0;
    bool last = sim.robot(0).gpio().output_level(SimRobot::kLedLine).value_or(false);
    for (int i = 0; i < 100; ++i) {
        sim.advance_to(6.0 + 0.01 * (i + 1));
        const bool now = sim.robot(0).gpio().output_level(SimRobot::kLedLine).value_or(false);
        toggles += now != last;
        last = now;
    }
    EXPECT_GE(toggles, 6); // 4 Hz for 1 s: 8 edges
    // released again (after the e-stop's release time) it drives on
    sim.robot(0).gpio().set_input_level(SimRobot::kEstopLine, true);
    const pose2_t q = sim.robot(0).pose();
    sim.advance_to(9.0);
    EXPECT_GT(std::hypot(sim.robot(0).pose().x - q.x, sim.robot(0).pose().y - q.y), 0.1);
}

// The laser tells the filters what stands around the robot (view.h): every
// frame after the laser is up has a view profile, and among the boxes of
// the paper scenario some landmarks are hidden behind them rather than
// missed (misses_hidden, both filters: robot 0 Fast-SLAM 2.0, robot 1
// EKF-SLAM). Without the profile (no laser) the count would stay 0.
TEST(Simulation, TheLaserHidesMarkersBehindBoxesFromTheMissCount)
{
    Scenario sc = load_scenario_file(kPaper);
    Simulation sim(sc, SimulationOptions{std::nullopt, 120.0});
    sim.run();
    for (size_t k = 0; k < 2; ++k) {
        const robot_node_counters_t *c = robot_node_counters(&sim.node(k));
        EXPECT_GT(c->frames, 550u);
        EXPECT_GE(c->views + 10u, c->frames) << "robot " << k; // all but the first second's
    }
    const slam_filter_t &f0 = sim.node(0).filter;
    const slam_filter_t &f1 = sim.node(1).filter;
    ASSERT_EQ(f0.kind, SLAM_FILTER_FASTSLAM2);
    ASSERT_EQ(f1.kind, SLAM_FILTER_EKF);
    std::printf("misses hidden: %u (Fast-SLAM, all particles), %u (EKF-SLAM)\n", f0.u.fs.ctr.misses_hidden,
                f1.u.ekf.ctr.misses_hidden);
    EXPECT_GT(f0.u.fs.ctr.misses_hidden, 0u);
    EXPECT_GT(f1.u.ekf.ctr.misses_hidden, 0u);
    // the rates the miss weight stands for (docs/core-slam.md): the pixel
    // camera's detection over the filter's view, every frame the robot
    // received tallied once; and the filter's own pairing of its confirmed
    // landmarks where it expects them, which no camera rate can exceed by
    // much (the filter's misses include its estimates' errors)
    for (size_t k = 0; k < 2; ++k) {
        const DetectionTally &t = sim.robot(k).detection_tally();
        EXPECT_EQ(t.frames, robot_node_counters(&sim.node(k))->frames) << "robot " << k;
        EXPECT_GT(t.in_view_clear, 500u) << "robot " << k;
        EXPECT_GT(t.in_view, t.in_view_clear) << "robot " << k; // the boxes hide some
        EXPECT_GT(detection_rate_clear(t), 0.95) << "robot " << k;
        uint64_t pairs = 0, misses = 0;
        slam_filter_view_counts(&sim.node(k).filter, &pairs, &misses);
        const double pr = static_cast<double>(pairs) / (pairs + misses);
        std::printf("robot %zu: camera %.3f over its filter's view (clear), filter pairs %.3f (%llu of %llu)\n", k,
                    detection_rate_clear(t), pr, static_cast<unsigned long long>(pairs),
                    static_cast<unsigned long long>(pairs + misses));
        EXPECT_GT(pairs + misses, 500u) << "robot " << k;
        EXPECT_GT(pr, 0.8) << "robot " << k;
        EXPECT_LT(pr, detection_rate_clear(t) + 0.01) << "robot " << k;
    }
}

TEST(RunOutput, FilesAreWrittenAndParse)
{
    Scenario sc = load_scenario_file(kPaper);
    Simulation sim(sc, SimulationOptions{std::nullopt, 3.0});
    sim.run();
    const std::string dir = ::testing::TempDir() + "coslam_run_output";
    std::filesystem::remove_all(dir);
    write_run_outputs(sim, dir);
    for (const char *f : {"robot0_path.tum", "robot1_truth_path.tum", "robot0_map.csv", "robot1_errors.csv",
                          "truth_map.csv", "merge_events.csv", "world.json", "metrics.json", "robot0_grid.pgm"}) {
        EXPECT_TRUE(std::filesystem::exists(dir + "/" + f)) << f;
    }
    std::ifstream tum(dir + "/robot0_path.tum");
    std::string line;
    int rows = 0;
    while (std::getline(tum, line)) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream ls(line);
        double v[8];
        for (double &x : v) ASSERT_TRUE(static_cast<bool>(ls >> x)) << line;
        EXPECT_NEAR(v[6] * v[6] + v[7] * v[7], 1.0, 1e-6);
        if (rows == 0) {
            EXPECT_EQ(v[0], 0.0);
            EXPECT_NEAR(v[1], -1.0, 1e-9); // world frame: robot 0 starts at (-1, 0)
        }
        rows++;
    }
    EXPECT_EQ(rows, 31); // 3 s at 10 Hz, both ends
    std::ifstream mj(dir + "/metrics.json");
    const nlohmann::json m = nlohmann::json::parse(mj);
    EXPECT_EQ(m["scenario"]["name"], "paper");
    EXPECT_EQ(m["robots"].size(), 2u);
    EXPECT_EQ(m["robots"][1]["filter"], "ekf");
    EXPECT_GT(m["timing"]["realtime_factor"].get<double>(), 1.0);
    // the laser driver's search bytes and EKF-SLAM's revisit hypotheses
    // (null for robot 0's Fast-SLAM)
    EXPECT_EQ(m["robots"][0]["laser"]["rx_search_bytes"].get<uint64_t>(),
              robot_node_laser_rx_search_bytes(&sim.node(0)));
    EXPECT_GT(m["robots"][0]["laser"]["rx_search_bytes"].get<uint64_t>(), 0u);
    EXPECT_TRUE(m["robots"][0]["revisit_hypotheses"].is_null());
    EXPECT_EQ(m["robots"][1]["revisit_hypotheses"]["forks"].get<uint32_t>(), sim.node(1).filter.u.ekf.ctr.mh_forks);
    EXPECT_TRUE(m["robots"][1]["revisit_hypotheses"].contains("reverted"));
    std::ifstream pgm(dir + "/robot0_grid.pgm", std::ios::binary);
    std::string magic;
    int w = 0, h = 0, maxv = 0;
    pgm >> magic >> w >> h >> maxv;
    EXPECT_EQ(magic, "P5");
    EXPECT_EQ(w, COSLAM_GRID_CELLS_X);
    EXPECT_EQ(h, COSLAM_GRID_CELLS_Y);
    EXPECT_EQ(std::filesystem::file_size(dir + "/robot0_grid.pgm"),
              static_cast<uintmax_t>(w * h) +
                  ("P5\n" + std::to_string(w) + " " + std::to_string(h) + "\n255\n").size());
    const std::string summary = run_summary(sim, dir);
    EXPECT_NE(summary.find("robot0"), std::string::npos);
    EXPECT_NE(summary.find("merges: none"), std::string::npos);
    // no merge: nothing measured after one (n/a, null), not 0.000
    for (size_t k = 0; k < 2; ++k) {
        EXPECT_TRUE(m["robots"][k]["pose_rmse_m"]["after_merge"].is_null()) << k;
        EXPECT_TRUE(m["robots"][k]["first_merge_s"].is_null()) << k; // not a -1 time

        EXPECT_TRUE(m["robots"][k]["map"]["pre_merge"].is_null()) << k;
        const nlohmann::json &fin = m["robots"][k]["map"]["final"];
        if (fin["n_matched"].get<int>() == 0) {
            EXPECT_TRUE(fin["rmse_m"].is_null()) << k;
        }
    }
    std::istringstream ss(summary);
    int rows_na = 0;
    while (std::getline(ss, line)) {
        if (line.rfind("  robot", 0) != 0) continue;
        std::istringstream ls(line);
        std::string name, filt, first_a, first_b, before, after;
        ls >> name >> filt >> first_a >> first_b >> before >> after;
        if (name == "robot") continue; // the header
        EXPECT_EQ(first_a + " " + first_b, "no merge") << line;
        EXPECT_EQ(after, "n/a") << line;
        EXPECT_EQ(line.find("0.000 m"), std::string::npos) << "an RMSE of nothing: " << line; // 0 matched: n/a
        rows_na++;
    }
    EXPECT_EQ(rows_na, 2);
}

// Not measured is nan in the CSVs and null in metrics.json, never a number:
// with an evaluation gate of 1 mm no landmark is matched, so every map
// error is unmeasured (it was 0) and every landmark has no true one
// (truth_id, it was -1); the EKF-SLAM robot has no particles (it was 0).
TEST(RunOutput, NotMeasuredIsNanInTheCsvsAndNullInTheJson)
{
    Scenario sc = load_scenario_file(kPaper);
    sc.evaluation.gate_m = 1e-3;
    Simulation sim(sc, SimulationOptions{std::nullopt, 3.0});
    sim.run();
    const std::string dir = ::testing::TempDir() + "coslam_run_output_unmeasured";
    std::filesystem::remove_all(dir);
    write_run_outputs(sim, dir);
    std::ifstream mj(dir + "/metrics.json");
    const nlohmann::json m = nlohmann::json::parse(mj);
    EXPECT_TRUE(m["robots"][1]["particles"].is_null()) << "EKF-SLAM is not a particle filter (it was 0)";
    EXPECT_EQ(m["robots"][0]["particles"], 100);
    for (const char *f : {"robot0_errors.csv", "robot0_map.csv", "robot1_map.csv"}) {
        std::ifstream cf(dir + "/" + f);
        std::string head, line;
        std::getline(cf, head);
        const bool errors = head.rfind("t,pos_err_m,heading_err_deg,map_rmse_m,map_max_err_m,n_est,n_matched", 0) == 0;
        ASSERT_TRUE(errors || head == "id,x,y,cxx,cxy,cyy,signature,n_obs,src_mask,truth_id") << head;
        int rows = 0;
        while (std::getline(cf, line)) {
            std::vector<std::string> c;
            std::stringstream ls(line);
            for (std::string v; std::getline(ls, v, ',');) c.push_back(v);
            ASSERT_EQ(c.size(), errors ? 9u : 10u) << line;
            if (errors) {
                EXPECT_EQ(c[6], "0") << line; // nothing matched
                EXPECT_EQ(c[3], "nan") << line;
                EXPECT_EQ(c[4], "nan") << line;
            } else {
                EXPECT_EQ(c[9], "nan") << line;
            }
            rows++;
        }
        EXPECT_GT(rows, 0) << f;
    }
    std::filesystem::remove_all(dir);
}

// The summary's merge line: Fast-SLAM's counts (sums over the particles in
// merge_stats_t) as the mean per particle that adds up, said so (it printed
// "16 landmarks: 6 fused, 9 added"); the sightings' time apart unsigned with
// the first named (it printed "-100 ms apart"); EKF-SLAM's as landmarks.
TEST(RunOutput, MergeLineCountsPerParticleAndSightingsUnsigned)
{
    MergeRecord m;
    m.t_s = 52.3;
    m.n_landmarks_in = 16;
    m.stats.fused = 696U;
    m.stats.added = 904U;
    m.dt_sightings_ms = -100.0; // own sighting first
    std::string l = merge_summary_line(m, "robot0", "robot1", 100);
    EXPECT_NE(l.find("robot0 <- robot1 (16 landmarks: 7.0 fused, 9.0 added (per particle, mean of 100);"),
              std::string::npos)
        << l;
    EXPECT_NE(l.find("sightings 100 ms apart (robot0's first)"), std::string::npos) << l;
    EXPECT_EQ(l.find("-100"), std::string::npos) << l;
    m.dt_sightings_ms = 40.2; // the sender's first
    EXPECT_NE(merge_summary_line(m, "robot0", "robot1", 100).find("sightings 40 ms apart (robot1's first)"),
              std::string::npos);
    m.dt_sightings_ms = 0.2;
    l = merge_summary_line(m, "robot0", "robot1", 100);
    EXPECT_NE(l.find("sightings 0 ms apart"), std::string::npos) << l;
    EXPECT_EQ(l.find("first)"), std::string::npos) << l;
    m.stats.fused = 6U; // EKF-SLAM: landmarks, no unit said
    m.stats.added = 10U;
    l = merge_summary_line(m, "robot1", "robot0", 0);
    EXPECT_NE(l.find("(16 landmarks: 6 fused, 10 added; not added"), std::string::npos) << l;
}

TEST(RunOutput, FaultNotReachedInAShortenedRun)
{
    Scenario sc = load_scenario_file(kPaper);
    FaultSpec f;
    f.robot = 1;
    f.kind = FaultKind::LaserUnplug;
    f.at_s = 2.0;
    f.duration_s = 5.0;
    sc.faults.push_back(f);
    f.at_s = 50.0; // after the end of the 3 s run below (as with --duration 3)
    sc.faults.push_back(f);
    Simulation sim(sc, SimulationOptions{std::nullopt, 3.0});
    sim.run();
    const std::string summary = run_summary(sim, "x");
    EXPECT_EQ(summary.find("-1.0"), std::string::npos) << summary;
    EXPECT_NE(summary.find("fault laser_unplug on robot1: 2.0 s .. still on at the end (3.0 s)"), std::string::npos)
        << summary;
    EXPECT_NE(summary.find("fault laser_unplug on robot1: not reached (at 50.0 s, the run ended at 3.0 s)"),
              std::string::npos)
        << summary;
    const nlohmann::json m = run_metrics(sim);
    ASSERT_EQ(m["faults"].size(), 2u);
    EXPECT_TRUE(m["faults"][0]["reached"].get<bool>());
    EXPECT_NEAR(m["faults"][0]["start_s"].get<double>(), 2.0, 1e-6);
    EXPECT_TRUE(m["faults"][0]["end_s"].is_null());
    EXPECT_FALSE(m["faults"][1]["reached"].get<bool>());
    EXPECT_TRUE(m["faults"][1]["start_s"].is_null());
    EXPECT_TRUE(m["faults"][1]["end_s"].is_null());
}

// A refusal by the check carries the check's figures, its reason among them
// (a lost receiver's placed_sd_m); one before the check (the range check)
// has none; a merge has them and its maps.
TEST(RunOutput, CheckFiguresOfRefusalsByTheCheck)
{
    MergeRecord m;
    m.kind = MEETING_EV_REFUSED;
    m.status = COSLAM_E_MERGE_LOST;
    m.stats.pairs = 9;
    m.stats.placed_sd_m = 1.63f;
    nlohmann::json j = merge_json(m);
    EXPECT_EQ(j["status"], "E_MERGE_LOST");
    ASSERT_TRUE(j.contains("check"));
    EXPECT_EQ(j["check"]["pairs"].get<int>(), 9);
    EXPECT_NEAR(j["check"]["placed_sd_m"].get<double>(), 1.63, 1e-6);
    EXPECT_FALSE(j.contains("map_after"));
    m.status = COSLAM_E_MERGE_DISAGREE;
    EXPECT_TRUE(merge_json(m).contains("check"));
    m.status = COSLAM_E_MERGE_RANGE;
    EXPECT_FALSE(merge_json(m).contains("check"));
    m.kind = MEETING_EV_MERGED;
    m.status = COSLAM_OK;
    j = merge_json(m);
    EXPECT_TRUE(j.contains("check"));
    EXPECT_TRUE(j.contains("map_after"));
}

TEST(RunOutput, AFullDiskIsAnErrorNamingTheFile)
{
    if (!std::filesystem::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
    Scenario sc = load_scenario_file(kPaper);
    Simulation sim(sc, SimulationOptions{std::nullopt, 1.0});
    sim.run();
    for (const char *name : {"robot0_path.tum", "robot0_grid.pgm", "robot1_errors.csv", "merge_events.csv",
                             "world.json", "metrics.json"}) {
        const std::string dir = ::testing::TempDir() + "coslam_run_output_full";
        std::filesystem::remove_all(dir);
        std::filesystem::create_directories(dir);
        std::filesystem::create_symlink("/dev/full", dir + "/" + name);
        try {
            write_run_outputs(sim, dir);
            ADD_FAILURE() << name << ": no error";
        } catch (const std::runtime_error &e) {
            EXPECT_NE(std::string(e.what()).find(dir + "/" + name), std::string::npos) << e.what();
        }
    }
}
