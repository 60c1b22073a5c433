// sim/world/simulation.hpp - a whole simulated run: the world, the robots
// with their device emulators, one robot_node_t firmware instance per
// robot, the team's link, all in one process and one thread, in simulated
// time (SimClock, polling model: nothing in the firmware waits).
//
// Loop, per physics step (physics_dt_ms, default 1 ms):
//   clock -> t; every robot: drives, body motion, laser, camera (pixels
//   rendered for the real detector, or the geometric stand-in),
//   link position (SimRobot::physics_step); every control period: every
//   robot's robot_node_step(), then its meeting events are collected; every
//   path period: poses; every sample period: map exports and errors.
//
// Evaluation (ground truth is used here only, never by the firmware):
// each robot's estimates live in its own map frame, which is its true start
// pose; the truth is moved into that frame (pose2_between(start, truth))
// and landmarks are matched one-to-one, same marker class only (Hungarian,
// evaluate_map below, gate evaluation.gate_m). A true landmark counts as missed if the
// team detected it at least evaluation.min_seen times and the map has no
// match for it.
#ifndef COSLAM_SIM_WORLD_SIMULATION_HPP
#define COSLAM_SIM_WORLD_SIMULATION_HPP

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "app/robot_node.h"
#include "sim/world/scenario.hpp"
#include "sim/world/sim_robot.hpp"
#include "sim/world/world.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_link.hpp"
#include "stats.h"

namespace coslam::sim {

struct MapSnapshot {
    bool valid = false;
    double t_s = 0.0;
    pose2_t pose{0, 0, 0};                ///< robot pose estimate, map frame
    std::vector<map_landmark_t> landmarks;///< map frame
    map_eval_t eval{};                    ///< against the truth at t_s
};

struct ErrorSample {
    double t_s = 0.0;
    double pos_err_m = 0.0;
    double heading_err_rad = 0.0;
    int n_est = 0, n_matched = 0, n_missed = 0, n_spurious = 0;
    double map_rmse_m = 0.0;              ///< 0 when nothing is matched
    double map_max_err_m = 0.0;
};

struct MergeRecord {
    double t_s = 0.0;
    int robot = 0;                        ///< the receiver
    int peer = 0;                         ///< the sender
    uint32_t seq = 0;
    meeting_event_kind_t kind = MEETING_EV_MERGED;
    coslam_status_t status = COSLAM_OK;
    uint16_t n_landmarks_in = 0;
    double dt_sightings_ms = 0.0;         ///< own sighting - sender's (estimated)
    pose2_t other_in_self{0, 0, 0};       ///< estimated (after compensation)
    pose2_t other_in_self_true{0, 0, 0};
    double transform_err_m = 0.0, transform_err_rad = 0.0, transform_nees = 0.0;
    merge_stats_t stats{};
    MapSnapshot before;                   ///< the last sample before the merge (<= sample period old)
    MapSnapshot after;                    ///< right after the merge
};

struct RobotRecord {
    std::string name;
    int id = 0;
    slam_filter_kind_t filter = SLAM_FILTER_FASTSLAM2;
    int particles = 0;
    pose2_t start{0, 0, 0};               ///< true start = the map frame, world coordinates
    std::vector<std::pair<double, pose2_t>> truth_path;  ///< world frame
    std::vector<std::pair<double, pose2_t>> est_path;    ///< map frame
    std::vector<ErrorSample> errors;
    MapSnapshot pre_merge, post_merge, final_map;        ///< around the first merge, and at the end
    double first_merge_s = -1.0;
    double pose_rmse_m = 0.0, pose_rmse_before_merge_m = 0.0, pose_rmse_after_merge_m = 0.0;
    double heading_rmse_rad = 0.0;
    uint32_t wall_collisions = 0, robot_collisions = 0;
    double min_wall_clearance_m = 0.0;
    double distance_m = 0.0;
    uint32_t messages_sent = 0;
    robot_node_counters_t node{};
    meeting_counters_t meeting{};
    urg_scip2_stats_t laser{};
    health_t health{};                    ///< the node's health monitor at the end
    std::vector<double> diverged_at_s;    ///< when its diverged flag rose
    behaviour_mode_t final_mode = BEHAVIOUR_WANDER;
    uint32_t avoid_turns = 0;
};

/// One scenario fault as it happened.
struct FaultRecord {
    FaultSpec spec;
    double start_s = -1.0;                ///< applied (-1: not reached)
    double end_s = -1.0;                  ///< reverted (-1: not reached; kidnap: = start)
    bool applied_ok = true;               ///< kidnap: false if the target was not free at at_s
};

struct SimulationResult {
    double sim_s = 0.0;
    double wall_s = 0.0;
    std::vector<RobotRecord> robots;
    std::vector<MergeRecord> merges;      ///< MEETING_EV_MERGED events
    std::vector<MergeRecord> refusals;    ///< MEETING_EV_REFUSED events
    std::vector<int> team_detections;     ///< per true landmark
    std::vector<FaultRecord> faults;      ///< the scenario's [[fault]] tables, in order
};

struct SimulationOptions {
    std::optional<uint64_t> seed;         ///< overrides the scenario's seed
    std::optional<double> duration_s;     ///< overrides the scenario's duration
    /// Memory is flat in simulated time: the recorded series (paths, error
    /// samples) are thinned to every other point, their period doubled,
    /// when they reach max_series points; the truth history keeps the last
    /// truth_hist_keep control steps (merges look back seconds, not hours).
    size_t max_series = 131072;
    size_t truth_hist_keep = 65536;
};

struct SimulationProgress {
    double t_s, duration_s, wall_s;
};

class Simulation {
public:
    explicit Simulation(const Scenario &sc, const SimulationOptions &opt = {});
    ~Simulation();
    Simulation(const Simulation &) = delete;
    Simulation &operator=(const Simulation &) = delete;

    /// Run to the end and evaluate (finish). progress (optional) is called
    /// about every progress_every_s of simulated time and at the end.
    void run(const std::function<void(const SimulationProgress &)> &progress = {}, double progress_every_s = 1.0);
    /// Run up to simulated time t_s (at most the duration) without the final
    /// evaluation; for tests that act on the world between steps. run()
    /// continues from there.
    void advance_to(double t_s, const std::function<void(const SimulationProgress &)> &progress = {},
                    double progress_every_s = 1.0);
    /// Simulated time of the next physics step [s].
    double now_s() const { return static_cast<double>(next_t_us_) * 1e-6; }

    const SimulationResult &result() const { return result_; }
    const Scenario &scenario() const { return sc_; }
    uint64_t seed() const { return seed_; }
    CameraSource camera_source() const { return camera_; }
    const World &world() const { return world_; }
    size_t n_robots() const { return robots_.size(); }
    robot_node_t &node(size_t k) { return *nodes_.at(k); }
    const robot_node_t &node(size_t k) const { return *nodes_.at(k); }
    SimRobot &robot(size_t k) { return *robots_.at(k); }
    const SimRobot &robot(size_t k) const { return *robots_.at(k); }
    SimLinkHub &link() { return *hub_; }
    /// True landmark positions in robot k's map frame.
    std::vector<point2_t> truth_in_map(size_t k) const;

private:
    MapSnapshot snapshot(size_t k, double t_s);
    void collect_events(size_t k, double t_s);
    void sample(double t_s);
    void apply_faults(uint64_t t_us);
    void set_fault(FaultRecord &f, bool on);
    void finish(double wall_s);
    static double wall_since(std::chrono::steady_clock::time_point t0);

    Scenario sc_;
    uint64_t seed_;
    double duration_s_;
    size_t max_series_, truth_hist_keep_;             ///< SimulationOptions
    CameraSource camera_;
    World world_;
    std::unique_ptr<SimClock> clock_;
    std::unique_ptr<SimLinkHub> hub_;
    std::vector<std::unique_ptr<SimRobot>> robots_;
    std::vector<std::unique_ptr<robot_node_t>> nodes_;
    std::vector<uint8_t> hung_;                      ///< controller_hang: the node is not stepped
    std::vector<std::vector<pose2_t>> truth_hist_;   ///< per control step, from truth_hist_base_
    uint64_t truth_hist_base_ = 0;                   ///< control step of truth_hist_[k][0]
    uint64_t path_stride_ = 1, sample_stride_ = 1;   ///< multiples of the path / sample periods
    std::vector<MapSnapshot> last_sample_;
    std::unique_ptr<map_estimate_t> export_buf_;
    std::vector<uint8_t> truth_sig_;
    SimulationResult result_;
    uint64_t next_t_us_ = 0, next_ctrl_us_ = 0, next_path_us_ = 0, next_sample_us_ = 0, next_prog_us_ = 0;
    std::chrono::steady_clock::time_point run_start_{};
    double wall_s_ = 0.0;
};

/// Optimal one-to-one matching of estimated and true landmarks (Hungarian,
/// host/synth stats.h), same marker class only, pairs within gate_m; as
/// eval_map otherwise: a true landmark detected at least min_seen times and
/// unmatched is missed, an unmatched estimate is spurious.
void evaluate_map(const map_estimate_t &est, const std::vector<point2_t> &truth, const std::vector<uint8_t> &truth_sig,
                  const std::vector<int> &n_seen, int min_seen, double gate_m, map_eval_t *out);

/// Derive an independent seed for (scenario seed, robot, stream).
uint64_t derive_seed(uint64_t seed, int robot, int stream);

/// Robot k of scenario sc as the simulator builds it (body, odometry and
/// laser noise, the geometric camera stand-in, seeds from `seed` by
/// derive_seed), camera = Oracle; Simulation switches it to Pixels. Also
/// used by the end-to-end device server (host/e2e), so both run the same
/// robots.
SimRobotConfig robot_config_from_scenario(const Scenario &sc, size_t k, uint64_t seed);

}  // namespace coslam::sim

#endif
