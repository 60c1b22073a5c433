#include "run_output.hpp"
#include "checked_file.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "app/slam_filter.h"
#include "profile_json.hpp"
#include "coslam/occ_grid.h"

namespace coslam::sim {

namespace {

constexpr double kRad2Deg = 180.0 / COSLAM_PI;

std::ofstream open_out(const std::string &dir, const std::string &name)
{
    std::ofstream f = coslam::cli::open_checked(dir + "/" + name);
    f << std::setprecision(9);
    return f;
}

// Closes a file of open_out / write_grid: a write that failed (a full disk)
// is an error naming the file, never a silently short file.
void close_out(std::ofstream &f, const std::string &dir, const std::string &name)
{
    coslam::cli::close_checked(f, dir + "/" + name);
}

// JSON null where nothing was measured
nlohmann::json measured(bool valid, double v)
{
    return valid ? nlohmann::json(v) : nlohmann::json(nullptr);
}

// A CSV cell: the value, or nan where nothing was measured (docs/sim.md
// "Outputs": the convention of every CSV of the host tools)
template <typename T>
void csv_cell(std::ostream &f, bool valid, T v)
{
    if (valid) {
        f << v;
    } else {
        f << "nan";
    }
}

void write_tum(const std::string &dir, const std::string &name, const std::vector<std::pair<double, pose2_t>> &path,
               const pose2_t *frame)
{
    std::ofstream f = open_out(dir, name);
    f << "# TUM trajectory, world frame: t x y z qx qy qz qw\n";
    for (const auto &s : path) {
        const pose2_t p = frame ? pose2_compose(*frame, s.second) : s.second;
        f << s.first << ' ' << p.x << ' ' << p.y << " 0 0 0 " << std::sin(0.5 * p.theta) << ' '
          << std::cos(0.5 * p.theta) << '\n';
    }
    close_out(f, dir, name);
}

map_landmark_t to_world(const pose2_t &start, const map_landmark_t &l)
{
    map_landmark_t w = l;
    w.mean = pose2_apply(start, l.mean);
    const double c = std::cos(start.theta), s = std::sin(start.theta);
    double r[2][2] = {{c, -s}, {s, c}};
    w.cov = cov2_congruence(r, l.cov);
    return w;
}

void write_map(const std::string &dir, const std::string &name, const pose2_t &start, const MapSnapshot &m)
{
    std::ofstream f = open_out(dir, name);
    f << "id,x,y,cxx,cxy,cyy,signature,n_obs,src_mask,truth_id\n";
    for (size_t i = 0; i < m.landmarks.size(); ++i) {
        const map_landmark_t w = to_world(start, m.landmarks[i]);
        f << w.id << ',' << w.mean.x << ',' << w.mean.y << ',' << w.cov.xx << ',' << w.cov.xy << ',' << w.cov.yy << ','
          << static_cast<int>(w.signature) << ',' << w.n_obs << ',' << w.src_mask << ',';
        // truth_id: the true landmark it was matched to; nan: none (spurious)
        const int match = i < static_cast<size_t>(COSLAM_MAX_MSG_LANDMARKS) ? m.eval.match[i] : -1;
        csv_cell(f, match >= 0, match);
        f << '\n';
    }
    close_out(f, dir, name);
}

// Occupancy grid as an 8-bit PGM: white free, black occupied, grey unknown;
// row 0 is the top (largest y) of the robot's map frame.
void write_grid(const std::string &dir, const std::string &name, const occ_grid_t &g)
{
    std::ofstream f = coslam::cli::open_checked(dir + "/" + name, std::ios::binary);
    f << "P5\n" << COSLAM_GRID_CELLS_X << ' ' << COSLAM_GRID_CELLS_Y << "\n255\n";
    for (int iy = COSLAM_GRID_CELLS_Y - 1; iy >= 0; --iy) {
        for (int ix = 0; ix < COSLAM_GRID_CELLS_X; ++ix) {
            const double p = occ_grid_prob(&g, ix, iy);
            f.put(static_cast<char>(static_cast<unsigned char>(std::lround(255.0 * (1.0 - p)))));
        }
    }
    close_out(f, dir, name);
}

nlohmann::json eval_json(const MapSnapshot &m)
{
    if (!m.valid) return nullptr;
    return {{"t_s", m.t_s},
            {"n_estimated", m.eval.n_estimated},
            {"n_matched", m.eval.n_matched},
            {"n_missed", m.eval.n_missed},
            {"n_spurious", m.eval.n_spurious},
            {"rmse_m", measured(m.eval.n_matched > 0, m.eval.rmse_m)},
            {"max_err_m", measured(m.eval.n_matched > 0, m.eval.max_err_m)},
            {"nees_mean", std::isfinite(m.eval.nees_mean) ? nlohmann::json(m.eval.nees_mean) : nlohmann::json(nullptr)}};
}

}  // namespace

// The rate at which a filter finds its confirmed landmarks where it expects
// them, from slam_filter_view_counts; NaN with none.
double view_pair_rate(uint64_t pairs, uint64_t misses)
{
    return pairs + misses > 0 ? static_cast<double>(pairs) / static_cast<double>(pairs + misses)
                              : std::numeric_limits<double>::quiet_NaN();
}

// slam_exist_miss_for_detection where the rate allows it (not NaN)
bool miss_weight_for(double p_d, double *w)
{
    if (!(p_d > SLAM_EXIST_P_FALSE && p_d < 1.0)) return false;
    *w = slam_exist_miss_for_detection(p_d);
    return true;
}

// The camera's detection rate over the filter's view (detection_tally.hpp),
// the filter's own rate, and the miss weight each gives; null where nothing
// was in view.
nlohmann::json detection_json(const DetectionTally &t, const robot_node_t &n)
{
    uint64_t pairs = 0, misses = 0;
    slam_filter_view_counts(&n.filter, &pairs, &misses);
    const double pr = view_pair_rate(pairs, misses);
    double wpr = 0.0;
    const bool okp = miss_weight_for(pr, &wpr);
    const double pdc = detection_rate_clear(t);
    double wpdc = 0.0;
    const bool ok = miss_weight_for(pdc, &wpdc);
    return {{"frames", t.frames},
            {"in_view", t.in_view},
            {"detected", t.detected},
            {"p_d", measured(t.in_view > 0, detection_rate(t))},
            {"in_view_clear", t.in_view_clear},
            {"detected_clear", t.detected_clear},
            {"p_d_clear", measured(t.in_view_clear > 0, pdc)},
            {"exist_miss_for_p_d_clear", measured(ok, wpdc)},
            {"filter_view_pairs", pairs},
            {"filter_view_misses", misses},
            {"filter_pair_rate", measured(pairs + misses > 0, pr)},
            {"exist_miss_for_pair_rate", measured(okp, wpr)},
            {"exist_miss_confirmed", n.cfg.filter.slam.exist_miss_confirmed}};
}

// EKF-SLAM's revisits kept as two hypotheses (ekfslam_config_t.mh_frames):
// forks, those decided against the revisit, those ended by a merge; null
// for Fast-SLAM, which has none
nlohmann::json revisit_hypotheses_json(const slam_filter_t &f)
{
    if (f.kind != SLAM_FILTER_EKF) {
        return nullptr;
    }
    const ekfslam_counters_t &c = f.u.ekf.ctr;
    return {{"forks", c.mh_forks}, {"reverted", c.mh_reverted}, {"decided_early", c.mh_decided_early}};
}

nlohmann::json merge_json(const MergeRecord &m)
{
    nlohmann::json j = {{"t_s", m.t_s},
                        {"robot", m.robot},
                        {"peer", m.peer},
                        {"seq", m.seq},
                        {"status", coslam_status_str(m.status)},
                        {"n_landmarks_in", m.n_landmarks_in}};
    if (m.kind == MEETING_EV_MERGED) {
        j["dt_sightings_ms"] = m.dt_sightings_ms;
        j["transform_est"] = {m.other_in_self.x, m.other_in_self.y, m.other_in_self.theta};
        j["transform_true"] = {m.other_in_self_true.x, m.other_in_self_true.y, m.other_in_self_true.theta};
        j["transform_err_m"] = m.transform_err_m;
        j["transform_err_deg"] = m.transform_err_rad * kRad2Deg;
        j["transform_nees"] = std::isfinite(m.transform_nees) ? nlohmann::json(m.transform_nees) : nlohmann::json(nullptr);
        // summed over the receiver's particles (docs/sim.md): Fast-SLAM
        // fuses and adds in every particle; EKF-SLAM's are landmarks
        j["fused_particle_sum"] = m.stats.fused;
        j["fused_ci_particle_sum"] = m.stats.fused_ci;
        j["added_particle_sum"] = m.stats.added;
        j["capacity_drops_particle_sum"] = m.stats.capacity_drops;
        j["map_before"] = eval_json(m.before);
        j["map_after"] = eval_json(m.after);
    }
    // the check's figures: of every merge, and of the refusals the check
    // made (for those they are the reason, e.g. placed_sd_m of a lost one)
    if (m.kind == MEETING_EV_MERGED || merge_refused_by_check(m.status)) {
        j["check"] = {{"pairs", m.stats.pairs},
                      {"nis", m.stats.nis},
                      {"nis_bound", m.stats.nis_bound},
                      {"vetoed_negative_info", m.stats.vetoed},
                      {"echoes", m.stats.echoes},
                      {"ambiguous", m.stats.ambiguous},
                      {"unrefutable", m.stats.unrefutable},
                      {"placed_sd_m", m.stats.placed_sd_m},
                      {"t_shift", {m.stats.t_shift.x, m.stats.t_shift.y, m.stats.t_shift.theta}}};
    }
    return j;
}

nlohmann::json run_metrics(const Simulation &sim)
{
    const SimulationResult &r = sim.result();
    const Scenario &sc = sim.scenario();
    nlohmann::json j;
    j["profile"] = coslam::profile_json(); // the build's capacities
    j["scenario"] = {{"name", sc.name}, {"source", sc.source}, {"seed", sim.seed()}, {"duration_s", r.sim_s},
                     {"n_landmarks", sim.world().landmarks().size()}};
    j["timing"] = {{"sim_s", r.sim_s},
                   {"wall_s", r.wall_s},
                   {"realtime_factor", measured(r.wall_s > 0.0, r.wall_s > 0.0 ? r.sim_s / r.wall_s : 0.0)},
                   {"physics_dt_ms", sc.physics_dt_ms},
                   {"control_period_ms", sc.control_period_ms}};
    int seen = 0;
    for (int d : r.team_detections) seen += d >= sc.evaluation.min_seen ? 1 : 0;
    j["landmarks_seen_by_team"] = seen;
    j["camera"] = {{"source", camera_source_name(sim.camera_source())}};
    for (size_t k = 0; k < sim.n_robots(); ++k) {
        const PixelCamera *pc = sim.robot(k).pixel_camera();
        if (pc == nullptr) continue;
        const PixelCameraStats &st = pc->stats();
        const double nm = static_cast<double>(st.landmark_matched);
        j["camera"]["robots"].push_back(
            {{"frames", st.frames},
             {"landmark_sightings", st.landmark_sightings},
             {"landmark_sightings_matched", st.landmark_matched},
             {"false_markers", st.false_markers},
             {"robot_sightings", st.robot_sightings},
             {"robot_id_errors", st.robot_id_errors},
             {"range_err_rel_rms", measured(nm > 0, nm > 0 ? std::sqrt(st.range_rel_err_sum2 / nm) : 0.0)},
             {"bearing_err_rms_deg",
              measured(nm > 0, nm > 0 ? std::sqrt(st.bearing_err_sum2 / nm) * 180.0 / COSLAM_PI : 0.0)}});
    }
    j["robots"] = nlohmann::json::array();
    for (size_t k = 0; k < r.robots.size(); ++k) {
        const RobotRecord &rr = r.robots[k];
        const occ_grid_t *g = robot_node_grid(&sim.node(k));
        nlohmann::json rj = {
            {"name", rr.name},
            {"id", rr.id},
            {"filter", slam_filter_kind_name(rr.filter)},
            // null: EKF-SLAM is not a particle filter
            {"particles", rr.particles > 0 ? nlohmann::json(rr.particles) : nlohmann::json(nullptr)},
            {"start", {rr.start.x, rr.start.y, rr.start.theta}},
            {"distance_m", rr.distance_m},
            {"pose_rmse_m", {{"all", rr.pose_rmse_m}, {"before_merge", rr.pose_rmse_before_merge_m},
                             {"after_merge", measured(rr.first_merge_s >= 0.0, rr.pose_rmse_after_merge_m)}}},
            {"heading_rmse_deg", rr.heading_rmse_rad * kRad2Deg},
            // null: the robot never merged (a -1 here was plotted as a time)
            {"first_merge_s", measured(rr.first_merge_s >= 0.0, rr.first_merge_s)},
            {"map", {{"pre_merge", eval_json(rr.pre_merge)}, {"post_merge", eval_json(rr.post_merge)},
                     {"final", eval_json(rr.final_map)}}},
            {"detection", detection_json(sim.robot(k).detection_tally(), sim.node(k))},
            {"wall_collisions", rr.wall_collisions},
            {"robot_collisions", rr.robot_collisions},
            {"min_wall_clearance_m", rr.min_wall_clearance_m},
            {"avoid_turns", rr.avoid_turns},
            {"final_mode", behaviour_mode_name(rr.final_mode)},
            {"grid", {{"file", "robot" + std::to_string(k) + "_grid.pgm"}, {"frame", "map"},
                      {"origin_x_m", g->origin_x_m}, {"origin_y_m", g->origin_y_m}, {"cell_m", OCC_GRID_CELL_M},
                      {"cells_x", COSLAM_GRID_CELLS_X}, {"cells_y", COSLAM_GRID_CELLS_Y}}},
            {"node", {{"steps", rr.node.steps}, {"scans", rr.node.scans}, {"scan_errors", rr.node.scan_errors},
                      {"frames", rr.node.frames}, {"views", rr.node.views},
                      {"filter_errors", rr.node.filter_errors},
                      {"drive_faults", rr.node.drive_faults}, {"drive_errors", rr.node.drive_errors},
                      {"stalls", rr.node.stalls}, {"stall_resets", rr.node.stall_resets},
                      {"stop_steps", rr.node.stop_steps}, {"bumper_acks", rr.node.bumper_acks},
                      {"grid_out_of_grid", rr.node.grid_out_of_grid}, {"laser_lost", rr.node.laser_lost},
                      {"laser_connect_failures", rr.node.laser_connect_failures},
                      {"odometry_errors", rr.node.odometry_errors}, {"can_errors", rr.node.can_errors},
                      {"diverged", rr.node.diverged}}},
            {"health", {{"diverged_now", rr.health.diverged != 0}, {"episodes", rr.health.episodes},
                        {"diverged_frames", rr.health.diverged_frames}, {"diverged_at_s", rr.diverged_at_s},
                        {"unjudged_frames", rr.health.unjudged_frames},
                        {"worst_mean_nis", rr.health.worst_nis}, {"worst_unassociated", rr.health.worst_unassoc},
                        {"worst_ess_fraction", rr.health.worst_ess}, {"worst_missed", rr.health.worst_missed},
                        {"odometry_check",
                         {{"checks", rr.health.odo.checks}, {"unjudged", rr.health.odo.unjudged},
                          {"agreements", rr.health.odo.agreements}, {"disagreements", rr.health.odo.disagreements},
                          {"mismatches", rr.health.odo.mismatches}, {"worst_chi2", rr.health.odo.worst_chi2},
                          {"worst_inlier_fraction", rr.health.odo.worst_inlier_frac}}}}},
            {"meeting", {{"sent", rr.meeting.sent}, {"send_failures", rr.meeting.send_failures},
                         {"received", rr.meeting.received}, {"rx_errors", rr.meeting.rx_errors},
                         {"ignored_recent", rr.meeting.ignored_recent}, {"replays", rr.meeting.replays},
                         {"stale", rr.meeting.stale}, {"merged", rr.meeting.merged},
                         {"merge_failures", rr.meeting.merge_failures},
                         {"refused_range", rr.meeting.refused_range},
                         {"refused_disagree", rr.meeting.refused_disagree},
                         {"refused_lost", rr.meeting.refused_lost},
                         {"ignored_disagreed", rr.meeting.ignored_disagreed},
                         {"weak_not_sent", rr.meeting.weak_not_sent}}},
            {"laser", {{"scans_ok", rr.laser.scans_ok}, {"err_checksum", rr.laser.err_checksum},
                       {"err_line", rr.laser.err_line}, {"err_timeout", rr.laser.err_timeout},
                       {"rx_search_bytes", robot_node_laser_rx_search_bytes(&sim.node(k))}}},
            {"revisit_hypotheses", revisit_hypotheses_json(sim.node(k).filter)},
        };
        j["robots"].push_back(rj);
    }
    j["merges"] = nlohmann::json::array();
    for (const auto &m : r.merges) j["merges"].push_back(merge_json(m));
    j["refusals"] = nlohmann::json::array();
    for (const auto &m : r.refusals) j["refusals"].push_back(merge_json(m));
    if (!r.faults.empty()) {
        j["faults"] = nlohmann::json::array();
        for (const auto &f : r.faults) {
            // a run shortened by --duration may end before a fault's start
            // or end: null, and "reached" false when it never started
            j["faults"].push_back({{"robot", f.spec.robot}, {"kind", fault_kind_name(f.spec.kind)},
                                   {"at_s", f.spec.at_s}, {"duration_s", f.spec.duration_s},
                                   {"reached", f.start_s >= 0.0},
                                   {"start_s", measured(f.start_s >= 0.0, f.start_s)},
                                   {"end_s", measured(f.end_s >= 0.0, f.end_s)}, {"applied", f.applied_ok}});
        }
    }
    return j;
}

void write_run_outputs(const Simulation &sim, const std::string &dir)
{
    std::filesystem::create_directories(dir);
    const SimulationResult &r = sim.result();
    for (size_t k = 0; k < r.robots.size(); ++k) {
        const RobotRecord &rr = r.robots[k];
        const std::string p = "robot" + std::to_string(k);
        write_tum(dir, p + "_path.tum", rr.est_path, &rr.start);
        write_tum(dir, p + "_truth_path.tum", rr.truth_path, nullptr);
        write_map(dir, p + "_map.csv", rr.start, rr.final_map);
        if (rr.pre_merge.valid) write_map(dir, p + "_map_premerge.csv", rr.start, rr.pre_merge);
        if (rr.post_merge.valid) write_map(dir, p + "_map_postmerge.csv", rr.start, rr.post_merge);
        std::ofstream e = open_out(dir, p + "_errors.csv");
        e << "t,pos_err_m,heading_err_deg,map_rmse_m,map_max_err_m,n_est,n_matched,n_missed,n_spurious\n";
        for (const auto &s : rr.errors) {
            // no matched landmark: no map error (nan, was 0)
            e << s.t_s << ',' << s.pos_err_m << ',' << s.heading_err_rad * kRad2Deg << ',';
            csv_cell(e, s.n_matched > 0, s.map_rmse_m);
            e << ',';
            csv_cell(e, s.n_matched > 0, s.map_max_err_m);
            e << ',' << s.n_est << ',' << s.n_matched << ',' << s.n_missed << ',' << s.n_spurious << '\n';
        }
        close_out(e, dir, p + "_errors.csv");
        write_grid(dir, p + "_grid.pgm", *robot_node_grid(&sim.node(k)));
    }
    {
        std::ofstream f = open_out(dir, "truth_map.csv");
        f << "id,x,y,signature,detections\n";
        for (const auto &l : sim.world().landmarks()) {
            f << l.id << ',' << l.p.x() << ',' << l.p.y() << ',' << static_cast<int>(l.signature) << ','
              << r.team_detections[static_cast<size_t>(l.id)] << '\n';
        }
        close_out(f, dir, "truth_map.csv");
    }
    {
        std::ofstream f = open_out(dir, "merge_events.csv");
        // fused ... added: summed over the receiver's particles (docs/sim.md)
        f << "t,robot,peer,seq,status,n_in,fused_particle_sum,fused_ci_particle_sum,added_particle_sum,transform_err_m,"
             "transform_err_deg,dt_sightings_ms\n";
        for (const auto &m : r.merges) {
            f << m.t_s << ',' << m.robot << ',' << m.peer << ',' << m.seq << ',' << coslam_status_str(m.status) << ','
              << m.n_landmarks_in << ',' << m.stats.fused << ',' << m.stats.fused_ci << ',' << m.stats.added << ','
              << m.transform_err_m << ',' << m.transform_err_rad * kRad2Deg << ',' << m.dt_sightings_ms << '\n';
        }
        close_out(f, dir, "merge_events.csv");
    }
    {
        nlohmann::json w;
        w["walls"] = nlohmann::json::array();
        for (const auto &s : sim.world().walls()) w["walls"].push_back({s.a.x(), s.a.y(), s.b.x(), s.b.y()});
        w["pillars"] = nlohmann::json::array();
        for (const auto &p : sim.world().pillars()) w["pillars"].push_back({p.c.x(), p.c.y(), p.r});
        w["robots"] = nlohmann::json::array();
        for (size_t k = 0; k < r.robots.size(); ++k) {
            w["robots"].push_back({{"name", r.robots[k].name},
                                   {"filter", slam_filter_kind_name(r.robots[k].filter)},
                                   {"start", {r.robots[k].start.x, r.robots[k].start.y, r.robots[k].start.theta}},
                                   {"radius_m", sim.scenario().robots[k].radius_m}});
        }
        std::ofstream f = open_out(dir, "world.json");
        f << w.dump(1) << '\n';
        close_out(f, dir, "world.json");
    }
    std::ofstream f = open_out(dir, "metrics.json");
    f << run_metrics(sim).dump(2) << '\n';
    close_out(f, dir, "metrics.json");
}

std::string merge_summary_line(const MergeRecord &m, const std::string &robot, const std::string &peer,
                               int particles)
{
    // Fast-SLAM merges into every particle: its counts as the mean per particle
    char what[384];
    (void)slam_filter_merge_format(&m.stats, static_cast<uint32_t>(std::max(1, particles)), what, sizeof what);
    // dt = own sighting - the sender's: its size, and whose came first
    const long dt_ms = std::lround(m.dt_sightings_ms);
    const std::string first = dt_ms == 0 ? "" : (dt_ms > 0 ? " (" + peer + "'s first)" : " (" + robot + "'s first)");
    std::ostringstream s;
    s << std::fixed << "  merge t=" << std::setprecision(1) << m.t_s << " s: " << robot << " <- " << peer << " ("
      << m.n_landmarks_in << " landmarks: " << what << "), transform error " << std::setprecision(3)
      << m.transform_err_m << " m / " << std::setprecision(2) << m.transform_err_rad * kRad2Deg << " deg, sightings "
      << std::labs(dt_ms) << " ms apart" << first;
    return s.str();
}

std::string run_summary(const Simulation &sim, const std::string &out_dir)
{
    const SimulationResult &r = sim.result();
    const Scenario &sc = sim.scenario();
    std::ostringstream s;
    s << std::fixed;
    int seen = 0;
    for (int d : r.team_detections) seen += d >= sc.evaluation.min_seen ? 1 : 0;
    s << "coslam-sim: scenario '" << sc.name << "', seed " << sim.seed() << ", " << std::setprecision(0) << r.sim_s
      << " s simulated in " << std::setprecision(2) << r.wall_s << " s (x" << std::setprecision(0)
      << (r.wall_s > 0.0 ? r.sim_s / r.wall_s : 0.0) << " real time)\n";
    s << "  landmarks: " << sim.world().landmarks().size() << " in the world, " << seen << " seen by the team (>= "
      << sc.evaluation.min_seen << " detections)\n";
    if (sim.camera_source() == CameraSource::Oracle) {
        s << "  camera: oracle (the geometric stand-in, no pixels)\n";
    } else {
        s << "  camera: pixels (rendered 320x240 frames through the marker detector, docs/vision.md)\n";
        for (size_t k = 0; k < sim.n_robots(); ++k) {
            const PixelCamera *pc = sim.robot(k).pixel_camera();
            if (pc == nullptr) continue;
            const PixelCameraStats &st = pc->stats();
            const double nm = static_cast<double>(st.landmark_matched);
            char err[96] = "range and bearing error n/a (no sighting matched a landmark)";
            if (nm > 0) {
                std::snprintf(err, sizeof err, "range error RMS %.1f %%, bearing %.2f deg",
                              100.0 * std::sqrt(st.range_rel_err_sum2 / nm),
                              std::sqrt(st.bearing_err_sum2 / nm) * 180.0 / COSLAM_PI);
            }
            char cl[400];
            std::snprintf(cl, sizeof cl,
                          "    %s: %llu frames, %llu landmark sightings (%llu false), %s; %llu robot sightings (%llu "
                          "wrong id)\n",
                          r.robots[k].name.c_str(), static_cast<unsigned long long>(st.frames),
                          static_cast<unsigned long long>(st.landmark_sightings),
                          static_cast<unsigned long long>(st.landmark_sightings - st.landmark_matched), err,
                          static_cast<unsigned long long>(st.robot_sightings),
                          static_cast<unsigned long long>(st.robot_id_errors));
            s << cl;
        }
    }
    // the miss weight's input (docs/core-slam.md): said, so a camera that
    // detects less than its filter is configured for is seen
    s << "  landmarks found where the filter expects them (its view, a clear line of sight):\n";
    for (size_t k = 0; k < sim.n_robots(); ++k) {
        const DetectionTally &t = sim.robot(k).detection_tally();
        const double pdc = detection_rate_clear(t);
        uint64_t pairs = 0, misses = 0;
        slam_filter_view_counts(&sim.node(k).filter, &pairs, &misses);
        const double pr = view_pair_rate(pairs, misses);
        double wd = 0.0, wp = 0.0;
        const bool okd = miss_weight_for(pdc, &wd);
        const bool okp = miss_weight_for(pr, &wp);
        char wds[32] = "n/a", wps[32] = "n/a", pds[32] = "n/a", prs[32] = "n/a";
        if (t.in_view_clear > 0) std::snprintf(pds, sizeof pds, "%.3f", pdc);
        if (okd) std::snprintf(wds, sizeof wds, "%.3f", wd);
        if (std::isfinite(pr)) std::snprintf(prs, sizeof prs, "%.3f", pr);
        if (okp) std::snprintf(wps, sizeof wps, "%.3f", wp);
        char dl[400];
        std::snprintf(dl, sizeof dl,
                      "    %s: camera detected %s (%llu landmark-frames; miss weight %s), filter paired %s of its "
                      "confirmed landmarks (miss weight %s); %.3f configured\n",
                      r.robots[k].name.c_str(), pds, static_cast<unsigned long long>(t.in_view_clear), wds, prs, wps,
                      static_cast<double>(sim.node(k).cfg.filter.slam.exist_miss_confirmed));
        s << dl;
    }
    s << std::setprecision(3);
    s << "  per robot: pose RMSE before / after its first merge; maps as known/missed/spurious landmarks and\n"
         "  the RMSE of the known ones (missed = seen by the team, not in this map), from its own map frame\n";
    char line[256];
    std::snprintf(line, sizeof line, "  %-8s %-14s %-11s %15s   %-19s %-19s %-19s%s\n", "robot", "filter",
                  "first merge", "pose RMSE [m]", "map before merge", "map after merge", "map at the end", "collisions");
    s << line;
    std::snprintf(line, sizeof line, "  %-8s %-14s %-11s %7s %7s   %-19s %-19s %-19s%s\n", "", "", "", "before", "after",
                  "", "", "", "wall robot");
    s << line;
    auto mapcol = [](const MapSnapshot &m) {
        char c[64];
        if (!m.valid) {
            std::snprintf(c, sizeof c, "%-19s", "-");
        } else if (m.eval.n_matched == 0) {
            // no known landmark: no RMSE to show
            std::snprintf(c, sizeof c, "%2d/%2d/%-2d %6s    ", m.eval.n_matched, m.eval.n_missed, m.eval.n_spurious,
                          "n/a");
        } else {
            std::snprintf(c, sizeof c, "%2d/%2d/%-2d %6.3f m  ", m.eval.n_matched, m.eval.n_missed, m.eval.n_spurious,
                          m.eval.rmse_m);
        }
        return std::string(c);
    };
    for (const auto &rr : r.robots) {
        const std::string filt = std::string(slam_filter_kind_name(rr.filter)) +
                                 (rr.particles > 0 ? "/" + std::to_string(rr.particles) : std::string());
        char after[32] = "n/a"; // never merged: nothing after
        char first[32] = "no merge";
        if (rr.first_merge_s >= 0.0) {
            std::snprintf(after, sizeof after, "%.3f", rr.pose_rmse_after_merge_m);
            std::snprintf(first, sizeof first, "%.1f s", rr.first_merge_s);
        }
        std::snprintf(line, sizeof line, "  %-8s %-14s %-11s %7.3f %7s   ", rr.name.c_str(), filt.c_str(), first,
                      rr.pose_rmse_before_merge_m, after);
        s << line << mapcol(rr.pre_merge) << " " << mapcol(rr.post_merge) << " " << mapcol(rr.final_map);
        std::snprintf(line, sizeof line, " %4u %5u\n", rr.wall_collisions, rr.robot_collisions);
        s << line;
    }
    if (r.merges.empty()) {
        s << "  merges: none\n";
    }
    for (const auto &m : r.merges) {
        const RobotRecord &self = r.robots[static_cast<size_t>(m.robot)];
        s << merge_summary_line(m, self.name, r.robots[static_cast<size_t>(m.peer)].name, self.particles) << '\n';
    }
    if (!r.refusals.empty()) {
        s << "  refused messages: " << r.refusals.size() << " (see metrics.json)\n";
    }
    for (const auto &f : r.faults) {
        // a run shortened by --duration may end before the fault starts or ends
        char span[96];
        if (f.start_s < 0.0) {
            std::snprintf(span, sizeof span, "not reached (at %.1f s, the run ended at %.1f s)", f.spec.at_s, r.sim_s);
        } else if (f.end_s < 0.0) {
            std::snprintf(span, sizeof span, "%.1f s .. still on at the end (%.1f s)", f.start_s, r.sim_s);
        } else {
            std::snprintf(span, sizeof span, "%.1f s .. %.1f s", f.start_s, f.end_s);
        }
        char fl[256];
        std::snprintf(fl, sizeof fl, "  fault %s on %s: %s%s\n", fault_kind_name(f.spec.kind),
                      r.robots[static_cast<size_t>(f.spec.robot)].name.c_str(), span,
                      f.applied_ok ? "" : " (NOT applied: target not free)");
        s << fl;
    }
    // the health monitor speaks only when it has something to say (a
    // fault-free run prints what it always printed)
    for (const auto &rr : r.robots) {
        if (r.faults.empty() && rr.diverged_at_s.empty()) continue;
        char first[48] = "";
        if (!rr.diverged_at_s.empty()) std::snprintf(first, sizeof first, ", first at %.1f s", rr.diverged_at_s.front());
        char hl[400];
        std::snprintf(hl, sizeof hl,
                      "  health %s: %s, diverged %u time(s)%s; laser lost %u, scan errors %u, drive faults %u, "
                      "CAN errors %u, stop steps %u; wheels against laser: %u disagreements, %u mismatches\n",
                      rr.name.c_str(), rr.health.diverged ? "DIVERGED" : "ok", rr.health.episodes, first,
                      rr.node.laser_lost, rr.node.scan_errors, rr.node.drive_faults, rr.node.can_errors,
                      rr.node.stop_steps, rr.health.odo.disagreements, rr.health.odo.mismatches);
        s << hl;
    }
    s << "  outputs: " << out_dir << "/ (metrics.json, robot<k>_path.tum, robot<k>_map.csv, merge_events.csv, ...)";
    return s.str();
}

}  // namespace coslam::sim
