#include "sim/world/simulation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace coslam::sim {

namespace {

constexpr double kDeg = COSLAM_PI / 180.0;

double sq(double v)
{
    return v * v;
}

slam_params_t filter_params(const Scenario &sc, const RobotSpec &rs)
{
    const FilterNoiseSpec &f = rs.filter_noise;
    slam_params_t p = slam_params_default();
    p.noise.range_var_m2 = sq(f.range_sd_m.value_or(sc.camera.range_sd_m));
    p.noise.range_var_per_m2 = sq(f.range_sd_rel.value_or(sc.camera.range_sd_rel));
    p.noise.bearing_var_rad2 = sq(f.bearing_sd_deg.value_or(sc.camera.bearing_sd_deg) * kDeg);
    p.noise.odo_xy_var_m2_per_m = sq(f.odo_xy_sd_m.value_or(rs.noise.odo_xy_sd_m));
    p.noise.odo_theta_var_rad2_per_m = sq(f.odo_theta_sd_deg.value_or(rs.noise.odo_theta_sd_deg) * kDeg);
    p.noise.init_xy_var_m2 = sq(f.init_xy_sd_m.value_or(0.0));
    p.noise.init_theta_var_rad2 = sq(f.init_theta_sd_deg.value_or(0.0) * kDeg);
    p.noise.lm_init_var_m2 = sq(f.lm_init_sd_m.value_or(0.0));
    // the filter's range variance must be positive even for a noiseless camera
    if (p.noise.range_var_m2 <= 0.0) p.noise.range_var_m2 = 1e-6;
    if (p.noise.bearing_var_rad2 <= 0.0) p.noise.bearing_var_rad2 = 1e-8;
    p.sensor_min_range_m = sc.camera.min_range_m;
    p.sensor_max_range_m = sc.camera.max_range_m;
    p.sensor_fov_rad = sc.camera.fov_deg * kDeg;
    // a confirmed landmark's miss weighs by the rate at which it is found
    // where expected (slam_params.h). Measured here (metrics.json
    // robots[].detection): the camera detects 0.999 (pixels) or 0.91
    // (oracle) of the markers in the filter's view, the filter pairs
    // 0.96-0.98 of its confirmed ones; at the weights those rates give
    // (0.56-1.6) the simulator loses real markers, because one marker's
    // misses are not independent (docs/core-slam.md), so 0.125 is kept
    p.exist_miss_confirmed = SLAM_EXIST_MISS_FLAT_MARKERS;
    return p;
}

}  // namespace

void evaluate_map(const map_estimate_t &est, const std::vector<point2_t> &truth, const std::vector<uint8_t> &truth_sig,
                  const std::vector<int> &n_seen, int min_seen, double gate_m, map_eval_t *out)
{
    // one evaluation for every tool (host/synth/stats.h), with the marker classes
    eval_map_signed(&est, truth.data(), truth_sig.data(), n_seen.data(), static_cast<int>(truth.size()), min_seen,
                    gate_m, out);
}

uint64_t derive_seed(uint64_t seed, int robot, int stream)
{
    // splitmix64 of (seed, robot, stream): independent streams per device
    uint64_t z = seed * 0x9E3779B97F4A7C15ull + static_cast<uint64_t>(robot + 1) * 0xBF58476D1CE4E5B9ull +
                 static_cast<uint64_t>(stream) * 0x94D049BB133111EBull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

namespace {
// every other element, the first kept: a series at half its rate
template <typename T> void thin_half(std::vector<T> &v)
{
    size_t w = 0;
    for (size_t i = 0; i < v.size(); i += 2) v[w++] = v[i];
    v.resize(w);
}
}  // namespace

SimRobotConfig robot_config_from_scenario(const Scenario &sc, size_t k, uint64_t seed)
{
    const RobotSpec &rs = sc.robots[k];
    const int id = static_cast<int>(k);
    const size_t n = sc.robots.size();
    const uint64_t period_us = static_cast<uint64_t>(sc.camera.period_ms * 1000.0);
    SimRobotConfig rc;
    rc.id = id;
    rc.start = rs.start;
    rc.radius_m = rs.radius_m;
    rc.odo_xy_var_m2_per_m = sq(rs.noise.odo_xy_sd_m);
    rc.odo_theta_var_rad2_per_m = sq(rs.noise.odo_theta_sd_deg * kDeg);
    rc.wheel_slip_sd = rs.noise.wheel_slip_sd;
    rc.laser_mount = sc.laser.mount;
    rc.laser_noise_sd_m = sc.laser.noise_sd_m;
    rc.laser_noise_rel = sc.laser.noise_rel;
    rc.laser_reply_delay_us = static_cast<uint64_t>(std::llround(sc.laser.reply_delay_ms * 1000.0));
    SightingOracleConfig oc;
    oc.period_us = period_us;
    // robots' cameras are not synchronised: spread the frames over a period
    oc.phase_us = (period_us * k / n) / 1000u * 1000u;
    oc.fov_rad = sc.camera.fov_deg * kDeg;
    oc.min_range_m = sc.camera.min_range_m;
    oc.max_range_m = sc.camera.max_range_m;
    oc.p_detect = sc.camera.p_detect;
    oc.range_sd_m = sc.camera.range_sd_m;
    oc.range_sd_rel = sc.camera.range_sd_rel;
    oc.bearing_sd_rad = sc.camera.bearing_sd_deg * kDeg;
    oc.robot_p_detect = sc.camera.robot_p_detect;
    oc.robot_range_sd_m = sc.camera.robot_range_sd_m;
    oc.robot_bearing_sd_rad = sc.camera.robot_bearing_sd_deg * kDeg;
    oc.seed = derive_seed(seed, id, 1);
    oc.view_model = filter_params(sc, rs);  // the filter's own view (detection_tally.hpp)
    rc.oracle = oc;
    rc.camera = CameraSource::Oracle;
    rc.seed_laser = derive_seed(seed, id, 2);
    rc.seed_drive = derive_seed(seed, id, 3);
    rc.seed_motion = derive_seed(seed, id, 4);
    return rc;
}

Simulation::Simulation(const Scenario &sc, const SimulationOptions &opt)
    : sc_(sc), seed_(opt.seed.value_or(sc.seed)), duration_s_(opt.duration_s.value_or(sc.duration_s)),
      max_series_(std::max<size_t>(opt.max_series, 16)), truth_hist_keep_(std::max<size_t>(opt.truth_hist_keep, 1024)),
      camera_(sc.camera.source),
      export_buf_(std::make_unique<map_estimate_t>())
{
    // world
    if (!sc.world.arena.empty()) world_.add_polygon(sc.world.arena);
    for (const auto &b : sc.world.boxes) world_.add_box(b.center, b.size, b.angle_deg * kDeg);
    for (const auto &p : sc.world.pillars) world_.add_pillar(p.center, p.radius_m);
    for (const auto &w : sc.world.walls) world_.add_wall(w.from, w.to);
    for (const auto &l : sc.world.landmarks) world_.add_landmark(l.pos, static_cast<uint8_t>(l.signature));

    const size_t n = sc.robots.size();
    if (n < 2 || n > COSLAM_MAX_ROBOTS) throw std::invalid_argument("scenario: 2..COSLAM_MAX_ROBOTS robots needed");
    clock_ = std::make_unique<SimClock>(0);
    SimLinkParams lp;
    lp.range_m = sc.link.range_m;
    lp.latency_us = static_cast<uint64_t>(sc.link.latency_ms * 1000.0);
    lp.jitter_us = static_cast<uint64_t>(sc.link.jitter_ms * 1000.0);
    lp.loss_prob = sc.link.loss;
    lp.seed = derive_seed(seed_, -1, 6);
    hub_ = std::make_unique<SimLinkHub>(*clock_, n, lp);

    for (size_t k = 0; k < n; ++k) {
        SimRobotConfig rc = robot_config_from_scenario(sc, k, seed_);
        rc.camera = camera_;
        if (camera_ == CameraSource::Pixels) {
            // the rendered camera is vision/marker_spec.h's; the filters' field of view must be its
            if (std::fabs(sc.camera.fov_deg - VISION_HFOV_DEG) > 0.5) {
                throw ScenarioError("camera.fov_deg: the pixel camera sees " + std::to_string(VISION_HFOV_DEG) +
                                    " deg (vision/marker_spec.h); use camera.source = \"oracle\" for another");
            }
            rc.pixels.period_us = rc.oracle.period_us;
            rc.pixels.phase_us = rc.oracle.phase_us;
            rc.pixels.render.seed = rc.oracle.seed;  // the camera's stream, as the stand-in's
            rc.pixels.view_model = rc.oracle.view_model;
            rc.pixels.detector.min_range_m = sc.camera.min_range_m;
            rc.pixels.detector.max_range_m = sc.camera.max_range_m;
        }
        robots_.push_back(std::make_unique<SimRobot>(*clock_, world_, *hub_, rc));
    }
    for (size_t k = 0; k < n; ++k) {
        const RobotSpec &rs = sc.robots[k];
        robot_node_config_t c = robot_node_config_default(static_cast<uint8_t>(k), static_cast<uint8_t>(n));
        c.filter.kind = rs.filter;
        c.filter.n_particles = static_cast<uint16_t>(rs.particles);
        c.filter.seed = derive_seed(seed_, static_cast<int>(k), 5);
        c.filter.slam = filter_params(sc, rs);
        c.meeting.robot_range_var_m2 = sq(rs.filter_noise.robot_range_sd_m.value_or(sc.camera.robot_range_sd_m));
        c.meeting.robot_bearing_var_rad2 =
            sq(rs.filter_noise.robot_bearing_sd_deg.value_or(sc.camera.robot_bearing_sd_deg) * kDeg);
        if (c.meeting.robot_range_var_m2 <= 0.0) c.meeting.robot_range_var_m2 = 1e-6;
        if (c.meeting.robot_bearing_var_rad2 <= 0.0) c.meeting.robot_bearing_var_rad2 = 1e-8;
        c.meeting.link_latency_us = static_cast<uint32_t>(sc.link.latency_ms * 1000.0);
        c.meeting.pair_window_us = static_cast<uint32_t>(sc.meeting.pair_window_ms * 1000.0);
        c.meeting.resend_period_us = static_cast<uint32_t>(sc.meeting.resend_s * 1e6);
        c.meeting.max_sends = static_cast<uint8_t>(sc.meeting.max_sends);
        c.meeting.meeting_gap_us = static_cast<uint32_t>(sc.meeting.meeting_gap_s * 1e6);
        c.meeting.remerge_period_us = static_cast<uint32_t>(std::fmin(sc.meeting.remerge_s * 1e6, 4.0e9));
        c.meeting.merge.peer_speed_mps = sc.meeting.peer_speed_mps;
        c.meeting.merge.peer_turn_radps = sc.meeting.peer_turn_dps * kDeg;
        c.meeting.max_range_m = sc.meeting.max_range_m;
        c.meeting.merge.transform_uncertainty = sc.meeting.transform_uncertainty ? 1u : 0u;
        c.meeting.merge.gate_chi2 = sc.meeting.gate_chi2;
        if (sc.meeting.step_units >= 0) {
            c.meeting.merge.step_units = static_cast<uint32_t>(sc.meeting.step_units);
        }
        c.behaviour.explore_s = rs.explore_s.value_or(sc.behaviour.explore_s);
        c.behaviour.cruise_mps = sc.behaviour.cruise_mps;
        c.behaviour.max_turn_radps = sc.behaviour.max_turn_dps * kDeg;
        c.behaviour.seek_turn_radps = sc.behaviour.seek_turn_dps * kDeg;
        c.behaviour.linger_s = sc.behaviour.linger_s;
        c.behaviour.goal_tol_m = sc.behaviour.goal_tol_m;
        c.behaviour.bypass_s = sc.behaviour.bypass_s;
        c.laser_in_robot = sc.laser.mount;
        c.laser_fov_rad = sc.laser.fov_deg * kDeg;
        auto node = std::make_unique<robot_node_t>();
        const robot_node_io_t io = robots_[k]->io();
        const coslam_status_t st = robot_node_init(node.get(), &c, &io);
        if (st != COSLAM_OK) {
            throw std::invalid_argument("robot " + rs.name + ": robot_node_init refused the configuration (" +
                                        coslam_status_str(st) + ")");
        }
        nodes_.push_back(std::move(node));
    }
    truth_hist_.resize(n);
    hung_.assign(n, 0);
    last_sample_.resize(n);
    result_.robots.resize(n);
    for (size_t k = 0; k < n; ++k) {
        RobotRecord &r = result_.robots[k];
        r.name = sc.robots[k].name;
        r.id = static_cast<int>(k);
        r.filter = sc.robots[k].filter;
        r.particles = sc.robots[k].filter == SLAM_FILTER_EKF ? 0 : sc.robots[k].particles;
        r.start = sc.robots[k].start;
    }
    for (const FaultSpec &f : sc.faults) {
        if (f.robot < 0 || static_cast<size_t>(f.robot) >= n) throw std::invalid_argument("fault: no robot " + std::to_string(f.robot));
        FaultRecord fr;
        fr.spec = f;
        result_.faults.push_back(fr);
    }
    result_.team_detections.assign(world_.landmarks().size(), 0);
    for (const auto &l : world_.landmarks()) truth_sig_.push_back(l.signature);
}

Simulation::~Simulation() = default;

std::vector<point2_t> Simulation::truth_in_map(size_t k) const
{
    std::vector<point2_t> out;
    const pose2_t s = sc_.robots.at(k).start;
    for (const auto &l : world_.landmarks()) out.push_back(pose2_apply_inverse(s, point2_t{l.p.x(), l.p.y()}));
    return out;
}

MapSnapshot Simulation::snapshot(size_t k, double t_s)
{
    MapSnapshot s;
    map_estimate_t *m = export_buf_.get();
    (void)robot_node_export(nodes_[k].get(), m);
    s.valid = true;
    s.t_s = t_s;
    s.pose = m->pose;
    s.landmarks.assign(m->lm, m->lm + m->n_landmarks);
    evaluate_map(*m, truth_in_map(k), truth_sig_, result_.team_detections, sc_.evaluation.min_seen,
                 sc_.evaluation.gate_m, &s.eval);
    return s;
}

void Simulation::collect_events(size_t k, double t_s)
{
    RobotRecord &rr = result_.robots[k];
    const uint64_t ctrl_us = static_cast<uint64_t>(sc_.control_period_ms * 1000.0);
    auto truth_at = [&](size_t who, uint64_t t_us) {
        const auto &h = truth_hist_[who];
        uint64_t step = (t_us + ctrl_us / 2) / ctrl_us;
        step = step < truth_hist_base_ ? truth_hist_base_ : step;  // older than kept: the oldest kept
        size_t i = static_cast<size_t>(step - truth_hist_base_);
        if (i >= h.size()) i = h.size() - 1;
        return h[i];
    };
    meeting_event_t ev;
    while (robot_node_take_event(nodes_[k].get(), &ev) == COSLAM_OK) {
        if (ev.kind == MEETING_EV_SENT) {
            rr.messages_sent++;
            continue;
        }
        MergeRecord m;
        m.t_s = t_s;
        m.robot = static_cast<int>(k);
        m.peer = ev.peer;
        m.seq = ev.seq;
        m.kind = ev.kind;
        m.status = ev.status;
        m.n_landmarks_in = ev.n_landmarks;
        m.stats = ev.stats;
        if (ev.kind != MEETING_EV_MERGED || ev.peer >= robots_.size()) {
            result_.refusals.push_back(m);
            continue;
        }
        m.dt_sightings_ms = (static_cast<double>(ev.own_sighting_us) - static_cast<double>(ev.sender_sighting_us)) * 1e-3;
        m.other_in_self = ev.other_in_self;
        m.other_in_self_true = pose2_between(truth_at(k, ev.stamp_us), truth_at(ev.peer, ev.sender_sighting_us));
        m.transform_err_m = std::hypot(m.other_in_self.x - m.other_in_self_true.x, m.other_in_self.y - m.other_in_self_true.y);
        m.transform_err_rad = std::fabs(angle_wrap(m.other_in_self.theta - m.other_in_self_true.theta));
        m.transform_nees = nees_pose(ev.other_in_self, ev.other_in_self_cov, m.other_in_self_true);
        m.before = last_sample_[k];
        m.after = snapshot(k, t_s);
        if (rr.first_merge_s < 0.0) {
            rr.first_merge_s = t_s;
            rr.pre_merge = m.before;
            rr.post_merge = m.after;
        }
        result_.merges.push_back(m);
    }
}

// Faults act on the devices only (docs/sim.md "Faults"); the firmware
// finds out through its drivers, as on the robot.
void Simulation::set_fault(FaultRecord &f, bool on)
{
    const FaultSpec &s = f.spec;
    SimRobot &r = *robots_.at(static_cast<size_t>(s.robot));
    switch (s.kind) {
    case FaultKind::LaserUnplug: r.urg().set_unplugged(on); break;
    case FaultKind::LaserGarbage: r.urg().set_line_noise(on ? s.bytes_per_ms : 0.0); break;
    case FaultKind::LaserSilent: r.urg().set_silent(on); break;
    case FaultKind::CanErrors:
        r.rig().bus().set_error_rate(on ? s.loss : 0.0, derive_seed(seed_, s.robot, 6));
        break;
    case FaultKind::DriveEmcy:
        if (on) r.rig().drive(s.wheel).raise_fault(static_cast<uint16_t>(s.emcy_code));
        break;
    case FaultKind::Estop: r.gpio().set_input_level(SimRobot::kEstopLine, !on); break;
    case FaultKind::CameraStall: r.set_camera_stalled(on); break;
    case FaultKind::LinkPartition: hub_->set_partitioned(static_cast<uint16_t>(s.robot), on); break;
    case FaultKind::Kidnap:
        if (on) f.applied_ok = r.teleport(s.to);
        break;
    case FaultKind::OdometryWild:
        for (int w = 0; w < 3; ++w) r.rig().drive(w).set_encoder_fault(on ? s.scale : 1.0, on && s.garbage);
        break;
    case FaultKind::ControllerHang: hung_.at(static_cast<size_t>(s.robot)) = on ? 1 : 0; break;
    }
}

void Simulation::apply_faults(uint64_t t_us)
{
    const double t_s = static_cast<double>(t_us) * 1e-6;
    for (FaultRecord &f : result_.faults) {
        const FaultSpec &s = f.spec;
        const uint64_t at = static_cast<uint64_t>(std::llround(s.at_s * 1e6));
        const uint64_t end = at + static_cast<uint64_t>(std::llround(s.duration_s * 1e6));
        if (f.start_s < 0.0 && t_us >= at) {
            f.start_s = t_s;
            set_fault(f, true);
            if (s.kind == FaultKind::Kidnap) f.end_s = t_s;
        }
        if (f.start_s >= 0.0 && f.end_s < 0.0) {
            if (t_us >= end) {
                f.end_s = t_s;
                set_fault(f, false);
            } else if (s.kind == FaultKind::DriveEmcy) {
                // a persistent fault: the drive faults again after every reset
                Cia402DriveEmu &d = robots_.at(static_cast<size_t>(s.robot))->rig().drive(s.wheel);
                if (d.state() != Cia402DriveEmu::State::Fault && d.state() != Cia402DriveEmu::State::FaultReactionActive) {
                    d.raise_fault(static_cast<uint16_t>(s.emcy_code));
                }
            }
        }
    }
}

void Simulation::sample(double t_s)
{
    for (size_t k = 0; k < robots_.size(); ++k) {
        const pose2_t truth = pose2_between(sc_.robots[k].start, robots_[k]->pose());
        pose2_t est;
        cov3_t cov;
        robot_node_pose(nodes_[k].get(), &est, &cov);
        // the map sample is an observer: while an export in parts holds the
        // filter's export table (a merge's check or a send), it keeps the
        // last sample's map rather than finish that export at once, which
        // the robot never does for it
        MapSnapshot s = slam_filter_export_busy(&nodes_[k]->filter) && last_sample_[k].valid ? last_sample_[k]
                                                                                              : snapshot(k, t_s);
        ErrorSample e;
        e.t_s = t_s;
        e.pos_err_m = std::hypot(est.x - truth.x, est.y - truth.y);
        e.heading_err_rad = std::fabs(angle_wrap(est.theta - truth.theta));
        e.n_est = s.eval.n_estimated;
        e.n_matched = s.eval.n_matched;
        e.n_missed = s.eval.n_missed;
        e.n_spurious = s.eval.n_spurious;
        e.map_rmse_m = s.eval.n_matched > 0 ? s.eval.rmse_m : 0.0;
        e.map_max_err_m = s.eval.n_matched > 0 ? s.eval.max_err_m : 0.0;
        result_.robots[k].errors.push_back(e);
        last_sample_[k] = std::move(s);
    }
}

void Simulation::advance_to(double t_end_s, const std::function<void(const SimulationProgress &)> &progress,
                            double progress_every_s)
{
    const uint64_t dt_us = static_cast<uint64_t>(std::llround(sc_.physics_dt_ms * 1000.0));
    const uint64_t ctrl_us = static_cast<uint64_t>(std::llround(sc_.control_period_ms * 1000.0));
    const uint64_t path_us = static_cast<uint64_t>(std::llround(sc_.path_period_s * 1e6));
    const uint64_t sample_us = static_cast<uint64_t>(std::llround(sc_.sample_period_s * 1e6));
    const uint64_t prog_us = static_cast<uint64_t>(std::llround(progress_every_s * 1e6));
    const uint64_t end_us =
        static_cast<uint64_t>(std::llround(std::fmin(t_end_s, duration_s_) * 1e6));
    const double dt_s = static_cast<double>(dt_us) * 1e-6;
    if (next_prog_us_ == 0) next_prog_us_ = prog_us;
    for (; next_t_us_ <= end_us; next_t_us_ += dt_us) {
        const uint64_t t = next_t_us_;
        clock_->advance_to(t);
        if (!result_.faults.empty()) apply_faults(t);
        for (auto &r : robots_) r->physics_step(t, dt_s);
        const double t_s = static_cast<double>(t) * 1e-6;
        if (t >= next_ctrl_us_) {
            next_ctrl_us_ += ctrl_us;
            for (size_t k = 0; k < robots_.size(); ++k) truth_hist_[k].push_back(robots_[k]->pose());
            if (truth_hist_[0].size() >= 2 * truth_hist_keep_) {
                for (auto &h : truth_hist_) h.erase(h.begin(), h.begin() + static_cast<std::ptrdiff_t>(truth_hist_keep_));
                truth_hist_base_ += truth_hist_keep_;
            }
            std::fill(result_.team_detections.begin(), result_.team_detections.end(), 0);
            for (auto &r : robots_) {
                const auto &d = r->detections();
                for (size_t j = 0; j < d.size() && j < result_.team_detections.size(); ++j) result_.team_detections[j] += d[j];
            }
            for (size_t k = 0; k < nodes_.size(); ++k) {
                if (hung_[k] != 0u) continue; /* its process stalls: no step, no idle work, no events */
                const int was = robot_node_diverged(nodes_[k].get());
                (void)robot_node_step(nodes_[k].get());
                robot_node_idle(nodes_[k].get()); /* as the robot does in the rest of its period */
                if (!was && robot_node_diverged(nodes_[k].get())) result_.robots[k].diverged_at_s.push_back(t_s);
                collect_events(k, t_s);
            }
        }
        if (t >= next_path_us_) {
            if (!result_.robots.empty() && result_.robots[0].est_path.size() >= max_series_) {
                for (auto &rr : result_.robots) {
                    thin_half(rr.est_path);
                    thin_half(rr.truth_path);
                }
                path_stride_ *= 2;
            }
            next_path_us_ += path_us * path_stride_;
            for (size_t k = 0; k < robots_.size(); ++k) {
                pose2_t est;
                cov3_t cov;
                robot_node_pose(nodes_[k].get(), &est, &cov);
                result_.robots[k].truth_path.emplace_back(t_s, robots_[k]->pose());
                result_.robots[k].est_path.emplace_back(t_s, est);
            }
        }
        if (t >= next_sample_us_) {
            if (!result_.robots.empty() && result_.robots[0].errors.size() >= max_series_) {
                for (auto &rr : result_.robots) thin_half(rr.errors);
                sample_stride_ *= 2;
            }
            next_sample_us_ += sample_us * sample_stride_;
            sample(t_s);
        }
        if (progress && t >= next_prog_us_) {
            next_prog_us_ += prog_us;
            progress(SimulationProgress{t_s, duration_s_, wall_s_ + wall_since(run_start_)});
        }
    }
}

void Simulation::run(const std::function<void(const SimulationProgress &)> &progress, double progress_every_s)
{
    run_start_ = std::chrono::steady_clock::now();
    advance_to(duration_s_, progress, progress_every_s);
    wall_s_ += wall_since(run_start_);
    finish(wall_s_);
    if (progress) progress(SimulationProgress{duration_s_, duration_s_, result_.wall_s});
}

double Simulation::wall_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void Simulation::finish(double wall_s)
{
    result_.sim_s = duration_s_;
    result_.wall_s = wall_s;
    for (size_t k = 0; k < robots_.size(); ++k) {
        RobotRecord &r = result_.robots[k];
        r.final_map = snapshot(k, duration_s_);
        double se = 0.0, se_b = 0.0, se_a = 0.0, sh = 0.0;
        int n = 0, nb = 0, na = 0;
        for (size_t i = 0; i < r.est_path.size(); ++i) {
            const pose2_t tr = pose2_between(r.start, r.truth_path[i].second);
            const pose2_t &es = r.est_path[i].second;
            const double e2 = sq(es.x - tr.x) + sq(es.y - tr.y);
            se += e2;
            sh += sq(angle_wrap(es.theta - tr.theta));
            n++;
            if (r.first_merge_s < 0.0 || r.est_path[i].first < r.first_merge_s) {
                se_b += e2;
                nb++;
            } else {
                se_a += e2;
                na++;
            }
        }
        r.pose_rmse_m = n > 0 ? std::sqrt(se / n) : 0.0;
        r.heading_rmse_rad = n > 0 ? std::sqrt(sh / n) : 0.0;
        r.pose_rmse_before_merge_m = nb > 0 ? std::sqrt(se_b / nb) : 0.0;
        r.pose_rmse_after_merge_m = na > 0 ? std::sqrt(se_a / na) : 0.0;
        r.wall_collisions = robots_[k]->wall_collisions();
        r.robot_collisions = robots_[k]->robot_collisions();
        r.min_wall_clearance_m = robots_[k]->min_wall_clearance_m();
        r.distance_m = robots_[k]->distance_m();
        r.node = *robot_node_counters(nodes_[k].get());
        r.meeting = *robot_node_meeting_counters(nodes_[k].get());
        r.laser = *robot_node_laser_stats(nodes_[k].get());
        r.health = *robot_node_health(nodes_[k].get());
        r.final_mode = robot_node_mode(nodes_[k].get());
        r.avoid_turns = nodes_[k]->behaviour.avoid_turns;
    }
}

}  // namespace coslam::sim
