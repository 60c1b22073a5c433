// sim/world/scenario.hpp - a simulation scenario: the world, the robots
// (filter, particles, noise, start pose), sensors, link, behaviour, meeting
// protocol, duration and seed; read from a TOML file (toml++). The format is
// documented in docs/sim.md; sim/scenarios/paper.toml is the default.
//
// Loading checks every key: an unknown key (a typo), a wrong type or a value
// outside its domain throws ScenarioError naming the key, so a scenario
// never runs with a silently ignored setting.
#ifndef COSLAM_SIM_WORLD_SCENARIO_HPP
#define COSLAM_SIM_WORLD_SCENARIO_HPP

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/slam_filter.h"
#include "coslam/pose2.h"

namespace coslam::sim {

/// Longest simulation a scenario or --duration may ask for [s] (11.6 days;
/// the simulator's memory is flat in simulated time, this bounds the wall time).
inline constexpr double kMaxDurationS = 1e6;

struct ScenarioError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

struct BoxSpec {
    Eigen::Vector2d center{0, 0};
    Eigen::Vector2d size{1, 1};
    double angle_deg = 0.0;
};
struct PillarSpec {
    Eigen::Vector2d center{0, 0};
    double radius_m = 0.1;
};
struct WallSpec {
    Eigen::Vector2d from{0, 0}, to{1, 0};
};
struct LandmarkSpec {
    Eigen::Vector2d pos{0, 0};
    int signature = 0;
};

struct WorldSpec {
    std::vector<Eigen::Vector2d> arena;   ///< closed polygon (may be empty)
    std::vector<BoxSpec> boxes;
    std::vector<PillarSpec> pillars;
    std::vector<WallSpec> walls;
    std::vector<LandmarkSpec> landmarks;
};

/// Where the robots' sightings come from: rendered pixels through the real
/// detector (firmware/vision), or the geometric stand-in (SightingOracle).
enum class CameraSource { Pixels, Oracle };

/// "pixels" | "oracle"; throws ScenarioError otherwise.
CameraSource parse_camera_source(const std::string &s);
const char *camera_source_name(CameraSource s);

struct CameraSpec {               ///< period, range limits, fov: both sources; the rest: the stand-in (truth side) and the filters' defaults
    CameraSource source = CameraSource::Pixels;
    double period_ms = 200.0;
    double fov_deg = 50.0;
    double min_range_m = 0.3;
    double max_range_m = 5.0;
    double p_detect = 0.9;
    double range_sd_m = 0.02;
    double range_sd_rel = 0.03;
    double bearing_sd_deg = 2.0;
    double robot_p_detect = 0.9;
    double robot_range_sd_m = 0.05;
    double robot_bearing_sd_deg = 2.0;
};

struct LaserSpec {
    double fov_deg = 140.0;               ///< requested by the robot app (MD steps)
    pose2_t mount{0.12, 0.0, 0.0};        ///< robot frame (heading in rad after loading)
    double noise_sd_m = 0.01;             ///< URG emulator: sd = max(noise_sd_m, noise_rel * r)
    double noise_rel = 0.01;
    double reply_delay_ms = 0.0;          ///< URG emulator: a command's reply this long after it (< 100)
};

struct LinkSpec {
    double range_m = 10.0;
    double latency_ms = 2.0;
    double jitter_ms = 0.0;
    double loss = 0.0;
};

struct TruthNoiseSpec {                   ///< injected into the simulated world
    double odo_xy_sd_m = 0.02;            ///< per sqrt(m) of wheel travel (Gaussian slip of the floor contact)
    double odo_theta_sd_deg = 1.0;        ///< per sqrt(m)
    double wheel_slip_sd = 0.0;           ///< drive emulators: relative slip per physics step
};

struct FilterNoiseSpec {                  ///< assumed by the filter; unset = the truth values
    std::optional<double> range_sd_m, range_sd_rel, bearing_sd_deg;
    std::optional<double> odo_xy_sd_m, odo_theta_sd_deg;
    std::optional<double> init_xy_sd_m, init_theta_sd_deg, lm_init_sd_m;
    std::optional<double> robot_range_sd_m, robot_bearing_sd_deg;
};

struct BehaviourSpec {
    double explore_s = 90.0;
    double cruise_mps = 0.2;
    double max_turn_dps = 45.0;
    double seek_turn_dps = 23.0;
    double linger_s = 3.0;
    double goal_tol_m = 0.25;
    double bypass_s = 1.0;
};

struct MeetingSpec {
    double pair_window_ms = 300.0;
    double resend_s = 1.0;
    int max_sends = 3;
    double meeting_gap_s = 5.0;
    double remerge_s = 60.0;
    double peer_speed_mps = 0.3;
    double peer_turn_dps = 30.0;
    double max_range_m = 3.0;             ///< robot sightings beyond this start no meeting
    bool transform_uncertainty = true;    ///< false: the paper's eq. 3 (rotation only)
    double gate_chi2 = 9.21;
    /// Fast-SLAM's merge and send-export work per step (merge_config_t
    /// step_units, docs/scale.md "The export in parts"); -1: the robot's
    /// default
    int step_units = -1;
};

struct RobotSpec {
    std::string name;
    pose2_t start{0, 0, 0};               ///< world frame (heading in rad after loading)
    slam_filter_kind_t filter = SLAM_FILTER_FASTSLAM2;
    int particles = 100;
    double radius_m = 0.19;
    TruthNoiseSpec noise;
    FilterNoiseSpec filter_noise;
    std::optional<double> explore_s;      ///< overrides behaviour.explore_s
};

struct EvaluationSpec {
    double gate_m = 1.0;                  ///< estimate-truth pairs farther apart are not matched
    int min_seen = 5;                     ///< a true landmark counts as missed if detected at least this often
};

/// A fault injected at the wire / device level (docs/sim.md "Faults").
enum class FaultKind {
    LaserUnplug,   ///< the URG's serial device errors, output lost; replugged: a fresh device (SCIP 1.1, laser off)
    LaserGarbage,  ///< random bytes on the URG's serial line
    LaserSilent,   ///< the URG's line goes silent (port open, nothing through: a cut cable, a hung sensor)
    CanErrors,     ///< frames destroyed on the robot's CAN bus with probability `loss`
    DriveEmcy,     ///< drive `wheel` goes to FAULT with an EMCY; faults again while the window lasts
    Estop,         ///< the e-stop loop opened (line low)
    CameraStall,   ///< no camera frames
    LinkPartition, ///< the robot's link drops every datagram, both ways
    Kidnap,        ///< the true pose jumps to `to` at at_s (duration ignored)
    OdometryWild,  ///< the drives' encoders report `scale` times the motor speed, or garbage
    ControllerHang,///< the robot's control process stalls: robot_node_step is not called (a hang,
                   ///< a SIGSTOP, a crash before a restart); the devices and the world go on
};

/// "laser_unplug", ...; nullptr-safe name of a kind.
const char *fault_kind_name(FaultKind k);

struct FaultSpec {
    int robot = 0;
    FaultKind kind = FaultKind::Estop;
    double at_s = 0.0;
    double duration_s = 0.0;
    double loss = 0.5;            ///< can_errors: probability a frame is destroyed
    int wheel = 0;                ///< drive_emcy: wheel 0..2
    int emcy_code = 0x2310;       ///< drive_emcy: CiA 301 error code (0x2310: continuous over-current)
    double scale = 5.0;           ///< odometry_wild: encoder scale
    bool garbage = false;         ///< odometry_wild: random encoder readings instead of scaled ones
    double bytes_per_ms = 10.0;   ///< laser_garbage: random bytes put on the line per ms
    pose2_t to{0, 0, 0};          ///< kidnap: new true pose (world frame, heading in rad after loading)
    int line = 0;                 ///< the [[fault]] table's line in the file (for messages)
};

struct Scenario {
    std::string name = "unnamed";
    std::string description;
    std::string source;                   ///< file it came from ("" for a string)
    double duration_s = 60.0;
    uint64_t seed = 1;
    double physics_dt_ms = 1.0;
    double control_period_ms = 10.0;
    double sample_period_s = 0.5;         ///< errors over time
    double path_period_s = 0.1;           ///< TUM paths
    WorldSpec world;
    CameraSpec camera;
    LaserSpec laser;
    LinkSpec link;
    TruthNoiseSpec noise;                 ///< default for every robot
    BehaviourSpec behaviour;
    MeetingSpec meeting;
    EvaluationSpec evaluation;
    std::vector<RobotSpec> robots;
    std::vector<FaultSpec> faults;        ///< [[fault]] tables; none: a fault-free run
};

/// Parse a scenario from TOML text; `source` names it in error messages.
Scenario load_scenario_string(const std::string &toml_text, const std::string &source = "<string>");
/// Parse a scenario file.
Scenario load_scenario_file(const std::string &path);

/// Parse "fastslam1" | "fastslam2" | "ekf"; throws ScenarioError otherwise.
slam_filter_kind_t parse_filter_kind(const std::string &s);

}  // namespace coslam::sim

#endif
