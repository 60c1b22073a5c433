// host/replay/replay_output.cpp - TUM paths, map CSVs, metrics.json.
#include "replay_output.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>

#include "checked_file.hpp"
#include "profile_json.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace coslam::replay {

namespace {

// Every output file is opened and closed checked (host/cli/checked_file.hpp):
// a failed open or write (a full disk) throws coslam::cli::WriteError with the
// path and the OS's reason; coslam-replay exits kExitWrite.
std::ofstream open_out(const fs::path &p)
{
    std::ofstream f = coslam::cli::open_checked(p.string());
    f << std::setprecision(10);
    return f;
}

void close_out(std::ofstream &f, const fs::path &p)
{
    coslam::cli::close_checked(f, p.string());
}

void write_tum_row(std::ostream &f, double t, pose2_t p)
{
    f << t << ' ' << p.x << ' ' << p.y << " 0 0 0 " << std::sin(0.5 * p.theta) << ' ' << std::cos(0.5 * p.theta)
      << '\n';
}

void write_map(const fs::path &p, const map_whole_t &m)
{
    auto f = open_out(p);
    f << "id,x,y,cxx,cxy,cyy,signature,n_obs,src_mask\n";
    for (int i = 0; i < m.n_landmarks; ++i) {
        const map_landmark_t &l = m.lm[i];
        f << l.id << ',' << l.mean.x << ',' << l.mean.y << ',' << l.cov.xx << ',' << l.cov.xy << ',' << l.cov.yy
          << ',' << unsigned(l.signature) << ',' << l.n_obs << ',' << l.src_mask << '\n';
    }
    close_out(f, p);
}

json pose_json(pose2_t p)
{
    return json{p.x, p.y, p.theta};
}

// null stands for "no ground truth" in metrics.json
json or_null(bool known, const json &v)
{
    return known ? v : json(nullptr);
}

// map-frame score: needs the robot's ground truth (the map frame in the world)
json score_json(const MapScore &s)
{
    const bool k = s.valid;
    return json{{"evaluated", k},
                {"n_estimated", s.n_estimated},
                {"n_matched", or_null(k, s.n_matched)},
                {"n_spurious", or_null(k, s.n_spurious)},
                {"n_missed", or_null(k, s.n_missed)},
                {"rmse_m", or_null(s.measured(), s.rmse_m)},
                {"max_err_m", or_null(s.measured(), s.max_err_m)},
                {"nees_mean", or_null(s.measured(), s.nees_mean)}};
}

// rigid-fit score (stats.h eval_map_rigid): needs the true landmarks only
json fit_json(const MapScore &s)
{
    const FitScore &f = s.fit;
    const bool k = f.valid;
    return json{{"evaluated", k},
                {"n_estimated", s.n_estimated},
                {"n_matched", or_null(k, f.n_matched)},
                {"n_spurious", or_null(k, f.n_spurious)},
                {"n_missed", or_null(k, f.n_missed)},
                {"rmse_m", or_null(f.measured(), f.rmse_m)},
                {"max_err_m", or_null(f.measured(), f.max_err_m)},
                {"nees_mean", or_null(f.measured(), f.nees_mean)},
                {"transform", or_null(f.measured(), pose_json(f.transform))}};
}

// a CSV field: the value, or nan where there is no ground truth
template <typename T>
std::string csv_or_nan(bool known, T v)
{
    std::ostringstream os;
    os << std::setprecision(10);
    if (known) {
        os << v;
    } else {
        os << "nan";
    }
    return os.str();
}

json cov3_json(const cov3_t &c)
{
    return json{{c.m[0][0], c.m[0][1], c.m[0][2]}, {c.m[1][0], c.m[1][1], c.m[1][2]}, {c.m[2][0], c.m[2][1], c.m[2][2]}};
}

} // namespace

void write_run_outputs(const std::string &dir, const Dataset &ds, const ReplayConfig &cfg, const ReplayOptions &opt,
                       const ReplayResult &res, const RunInfo &info)
{
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
        throw coslam::cli::WriteError(dir, ec.value(), "create the output folder");
    }
    const fs::path d(dir);
    const fs::path errors_path = d / "errors.csv";
    const fs::path map_errors_path = d / "map_errors.csv";
    auto errors = open_out(errors_path);
    errors << "t,robot,pos_err_m,heading_err_rad,nees\n";
    auto map_errors = open_out(map_errors_path);
    map_errors << "t,robot,n_estimated,n_matched,n_spurious,n_missed,rmse_m\n";
    for (const auto &r : res.robots) {
        const std::string base = "robot" + std::to_string(r.id);
        {
            const fs::path p = d / (base + "_path.tum");
            auto f = open_out(p);
            f << "# robot " << r.id << " " << filter_kind_name(r.filter) << " estimate, map frame\n";
            for (const auto &s : r.path) {
                write_tum_row(f, s.t_s, s.est);
            }
            close_out(f, p);
        }
        if (r.has_truth) {
            const fs::path p = d / (base + "_truth_path.tum");
            const fs::path q = d / (base + "_truth_map.csv");
            auto f = open_out(p);
            f << "# robot " << r.id << " ground truth in its map frame\n";
            for (const auto &s : r.path) {
                if (s.has_truth) {
                    write_tum_row(f, s.t_s, s.truth);
                }
            }
            close_out(f, p);
            auto g = open_out(q);
            g << "id,x,y\n";
            for (size_t j = 0; j < r.truth_landmarks.size(); ++j) {
                g << r.truth_ids[j] << ',' << r.truth_landmarks[j].x << ',' << r.truth_landmarks[j].y << '\n';
            }
            close_out(g, q);
        }
        if (r.final_map) {
            write_map(d / (base + "_map.csv"), *r.final_map);
        }
        if (r.map_before_merge) {
            write_map(d / (base + "_map_before_merge.csv"), *r.map_before_merge);
            write_map(d / (base + "_map_after_merge.csv"), *r.map_after_merge);
        }
        for (const auto &s : r.path) {
            if (!s.has_truth) {
                continue;
            }
            const double e = std::hypot(s.est.x - s.truth.x, s.est.y - s.truth.y);
            const double h = std::fabs(angle_wrap(s.est.theta - s.truth.theta));
            const double n = nees_pose(s.est, s.cov, s.truth);
            errors << s.t_s << ',' << r.id << ',' << e << ',' << h << ',' << csv_or_nan(std::isfinite(n), n) << '\n';
        }
        for (const auto &m : r.map_series) {
            const bool k = m.score.valid;
            map_errors << m.t_s << ',' << r.id << ',' << m.score.n_estimated << ',' << csv_or_nan(k, m.score.n_matched)
                       << ',' << csv_or_nan(k, m.score.n_spurious) << ',' << csv_or_nan(k, m.score.n_missed) << ','
                       << csv_or_nan(m.score.measured(), m.score.rmse_m) << '\n';
        }
    }
    close_out(errors, errors_path);
    close_out(map_errors, map_errors_path);
    {
        const fs::path p = d / "merge_events.csv";
        auto f = open_out(p);
        // fused ... capacity_drops: summed over the receiver's particles (docs/replay.md)
        f << "t,robot,sender,status,t_err_m,t_err_rad,t_nees,fused_particle_sum,fused_ci_particle_sum,"
             "added_particle_sum,capacity_drops_particle_sum,"
             "n_before,rmse_before_m,spurious_before,missed_before,n_after,rmse_after_m,spurious_after,"
             "missed_after,merge_us\n";
        for (const auto &e : res.merges) {
            f << e.t_s << ',' << e.receiver << ',' << e.sender << ',' << static_cast<int>(e.status) << ','
              << csv_or_nan(e.has_truth, e.t_err_m) << ',' << csv_or_nan(e.has_truth, e.t_err_rad) << ','
              << csv_or_nan(e.has_truth, e.t_nees) << ',' << e.stats.fused << ',' << e.stats.fused_ci << ','
              << e.stats.added << ',' << e.stats.capacity_drops << ',' << e.before.n_estimated << ','
              << csv_or_nan(e.before.measured(), e.before.rmse_m) << ',' << csv_or_nan(e.before.valid, e.before.n_spurious)
              << ',' << csv_or_nan(e.before.valid, e.before.n_missed) << ',' << e.after.n_estimated << ','
              << csv_or_nan(e.after.measured(), e.after.rmse_m) << ',' << csv_or_nan(e.after.valid, e.after.n_spurious)
              << ',' << csv_or_nan(e.after.valid, e.after.n_missed) << ',' << e.merge_us << '\n';
        }
        close_out(f, p);
    }

    json j;
    j["tool"] = "coslam-replay";
    j["profile"] = coslam::profile_json(); // the build's capacities
    j["command"] = info.command;
    json rep;
    rep["lines_read"] = ds.report.lines_read;
    rep["unknown_barcode_rows"] = ds.report.unknown_barcode_rows;
    json ub = json::object();
    for (const auto &[b, n] : ds.report.unknown_barcodes) {
        ub[std::to_string(b)] = n;
    }
    rep["unknown_barcodes"] = ub;
    rep["self_sightings"] = ds.report.self_sightings;
    rep["unknown_robot_sightings"] = ds.report.unknown_robot_sightings;
    rep["unknown_subject_rows"] = ds.report.unknown_subject_rows;
    rep["notes"] = ds.report.notes;
    json gaps = json::object();
    for (const auto &[id, g] : ds.report.odo_gaps) {
        gaps[std::to_string(id)] = {{"count", g.count}, {"max_s", g.max_s}, {"where", g.where}};
    }
    rep["odometry_gaps"] = gaps; // gaps of more than kOdoGapWarnS, by robot
    rep["odometry_gap_warn_s"] = kOdoGapWarnS;
    j["dataset"] = {{"source", ds.source},
                    {"format", ds.format},
                    {"t0_s", ds.t0_s},
                    {"robots", static_cast<int>(ds.robots.size())},
                    {"landmarks", static_cast<int>(ds.landmarks.size())},
                    {"report", rep}};
    json robots_opt = json::array();
    for (const auto &r : res.robots) {
        robots_opt.push_back(r.id);
    }
    j["options"] = {{"robots", robots_opt},
                    {"known_ids", opt.known_ids},
                    {"start_at_truth", opt.start_at_truth},
                    {"map_frame", opt.start_at_truth ? "world (filter started at the true pose)"
                                                     : "each robot's true pose at its start (filter at identity)"},
                    {"duration_s", opt.duration_s},
                    {"t_begin_s", res.t_begin_s},
                    {"t_end_s", res.t_end_s}};
    std::ostringstream ini;
    replay_config_write(cfg, ini);
    j["config_ini"] = ini.str();

    json robots = json::array();
    double sum_pose = 0.0, sum_head = 0.0, sum_lm = 0.0, sum_step = 0.0, max_step = 0.0, sum_fit = 0.0;
    int n_pose = 0, n_lm = 0, sum_spur = 0, sum_miss = 0, sum_est = 0;
    int n_fit = 0, n_fit_rmse = 0, sum_fit_spur = 0, sum_fit_miss = 0, n_lm_rmse = 0;
    for (const auto &r : res.robots) {
        json rj;
        rj["id"] = r.id;
        rj["filter"] = filter_kind_name(r.filter);
        // null: EKF-SLAM is not a particle filter
        rj["particles"] = or_null(r.filter != FilterKind::Ekf, cfg.filter.particles);
        rj["t_start_s"] = r.t_start_s;
        rj["map_frame_in_world"] = pose_json(r.frame.origin);
        // when the frame was placed: the start, or the first truth sample of
        // a robot whose truth begins later (null: no truth, never placed)
        rj["map_frame_placed_at_s"] = or_null(r.t_frame_s >= 0.0, r.t_frame_s);
        const bool pk = r.pose_samples > 0; // robot ground truth
        rj["pose"] = {{"samples", r.pose_samples},
                      {"rmse_m", or_null(pk, r.pose_rmse_m)},
                      {"heading_rmse_rad", or_null(pk, r.heading_rmse_rad)},
                      {"heading_rmse_deg", or_null(pk, r.heading_rmse_rad * 180.0 / M_PI)},
                      {"nees_mean", or_null(pk, r.pose_nees_mean)},
                      {"nees_xy_mean", or_null(pk, r.pose_nees_xy_mean)},
                      {"nees_heading_mean", or_null(pk, r.pose_nees_heading_mean)},
                      {"final_err_m", or_null(pk, r.final_pos_err_m)},
                      {"fit_samples", r.pose_fit_samples},
                      {"fit_rmse_m", or_null(r.pose_fit_samples > 0, r.pose_fit_rmse_m)},
                      {"fit_heading_rmse_deg", or_null(r.pose_fit_samples > 0, r.heading_fit_rmse_rad * 180.0 / M_PI)}};
        rj["map"] = score_json(r.final_score);
        rj["map_fit"] = fit_json(r.final_score);
        // null: the robot never merged (these were -1)
        rj["first_merge_t_s"] = or_null(r.t_first_merge_s >= 0.0, r.t_first_merge_s);
        rj["shown_merge_t_s"] = or_null(r.t_shown_merge_s >= 0.0, r.t_shown_merge_s);
        rj["shown_merge_added"] = or_null(r.t_shown_merge_s >= 0.0, r.shown_merge_gain);
        rj["steps"] = {{"frames", r.frames},           {"updates", r.updates},
                       {"predictions", r.predictions}, {"step_us_mean", r.step_us_mean},
                       {"step_us_max", r.step_us_max}, {"filter_s", r.filter_s}};
        rj["input"] = {{"sightings_used", r.sightings_used},
                       {"sightings_range_dropped", r.sightings_range_dropped},
                       {"sightings_known_id_dropped", r.sightings_known_id_dropped},
                       {"sightings_before_start", r.sightings_before_start},
                       {"robot_sightings_before_start", r.robot_sightings_before_start},
                       {"robot_sightings", r.robot_sightings},
                       {"capacity_errors", r.capacity_errors}};
        rj["counters"] = r.counters;
        robots.push_back(rj);
        if (r.pose_samples > 0) {
            sum_pose += r.pose_rmse_m;
            sum_head += r.heading_rmse_rad;
            n_pose++;
        }
        if (r.final_score.measured()) {
            sum_lm += r.final_score.rmse_m; // 0 when nothing matched: not averaged in
            n_lm_rmse++;
        }
        if (r.final_score.valid) {
            sum_spur += r.final_score.n_spurious;
            sum_miss += r.final_score.n_missed;
            sum_est += r.final_score.n_estimated;
            n_lm++;
        }
        if (r.final_score.fit.valid) {
            sum_fit_spur += r.final_score.fit.n_spurious;
            sum_fit_miss += r.final_score.fit.n_missed;
            n_fit++;
            if (r.final_score.fit.n_matched > 0) {
                sum_fit += r.final_score.fit.rmse_m;
                n_fit_rmse++;
            }
        }
        sum_step += r.step_us_mean;
        max_step = std::max(max_step, r.step_us_max);
    }
    j["robots"] = robots;
    const double nr = res.robots.empty() ? 1.0 : static_cast<double>(res.robots.size());
    j["mean"] = {{"pose_rmse_m", or_null(n_pose > 0, n_pose ? sum_pose / n_pose : 0.0)},
                 {"heading_rmse_rad", or_null(n_pose > 0, n_pose ? sum_head / n_pose : 0.0)},
                 {"landmark_rmse_m", or_null(n_lm_rmse > 0, n_lm_rmse ? sum_lm / n_lm_rmse : 0.0)},
                 {"n_estimated", or_null(n_lm > 0, n_lm ? static_cast<double>(sum_est) / n_lm : 0.0)},
                 {"spurious", or_null(n_lm > 0, n_lm ? static_cast<double>(sum_spur) / n_lm : 0.0)},
                 {"missed", or_null(n_lm > 0, n_lm ? static_cast<double>(sum_miss) / n_lm : 0.0)},
                 {"fit_landmark_rmse_m", or_null(n_fit_rmse > 0, n_fit_rmse ? sum_fit / n_fit_rmse : 0.0)},
                 {"fit_spurious", or_null(n_fit > 0, n_fit ? static_cast<double>(sum_fit_spur) / n_fit : 0.0)},
                 {"fit_missed", or_null(n_fit > 0, n_fit ? static_cast<double>(sum_fit_miss) / n_fit : 0.0)},
                 {"step_us_mean", sum_step / nr},
                 {"step_us_max", max_step}};

    json ev = json::array();
    double se_t = 0.0, max_t = 0.0, se_r = 0.0, sum_nees = 0.0;
    int n_ok = 0, n_truth = 0;
    for (const auto &e : res.merges) {
        json ej = {{"t", e.t_s},
                   {"receiver", e.receiver},
                   {"sender", e.sender},
                   {"t_receiver_sighting_s", e.t_receiver_sighting_s},
                   {"t_sender_sighting_s", e.t_sender_sighting_s},
                   {"seq", e.seq},
                   {"status", coslam_status_str(e.status)},
                   {"transform", pose_json(e.transform)},
                   {"transform_cov", cov3_json(e.transform_cov)},
                   // summed over the receiver's particles (docs/replay.md)
                   {"fused_particle_sum", e.stats.fused},
                   {"particles_due", e.particles_due},
                   {"fused_ci_particle_sum", e.stats.fused_ci},
                   {"added_particle_sum", e.stats.added},
                   {"capacity_drops_particle_sum", e.stats.capacity_drops},
                   {"skipped_particle_sum", e.stats.skipped},
                   {"check",
                    {{"pairs", e.stats.pairs},
                     {"nis", or_null(e.stats.pairs > 0, e.stats.nis)}, // no pairs: nothing measured
                     {"nis_bound", or_null(e.stats.pairs > 0, e.stats.nis_bound)},
                     {"vetoed_negative_info", e.stats.vetoed},
                     {"echoes", e.stats.echoes},
                     {"ambiguous", e.stats.ambiguous},
                     {"unrefutable", e.stats.unrefutable},
                     // the receiver's best-placed own landmark of the pairs (lost_sd_factor)
                     {"placed_sd_m", or_null(e.stats.pairs > 0, static_cast<double>(e.stats.placed_sd_m))},
                     {"t_shift", pose_json(e.stats.t_shift)}}},
                   {"map_before", score_json(e.before)},
                   {"map_after", score_json(e.after)},
                   {"merge_us", e.merge_us}};
        if (e.has_truth) {
            ej["transform_true"] = pose_json(e.transform_true);
            ej["t_err_m"] = e.t_err_m;
            ej["t_err_rad"] = e.t_err_rad;
            ej["t_nees"] = e.t_nees;
        }
        ev.push_back(ej);
        if (e.status == COSLAM_OK || e.status == COSLAM_E_CAPACITY) {
            n_ok++;
            if (e.has_truth) {
                se_t += e.t_err_m * e.t_err_m;
                se_r += e.t_err_rad * e.t_err_rad;
                max_t = std::max(max_t, e.t_err_m);
                sum_nees += e.t_nees;
                n_truth++;
            }
        }
    }
    j["merges"] = {{"merged", n_ok},
                   {"refused_range_check", res.meetings_refused_range},
                   {"refused_replay", res.merges_refused_replay},
                   {"refused_disagree", res.merges_refused_disagree},
                   {"refused_lost", res.merges_refused_lost},
                   {"refused_implausible", res.merges_refused_implausible},
                   {"stale", res.merges_stale},
                   {"failed", res.merges_failed},
                   {"t_err_rmse_m", or_null(n_truth > 0, n_truth ? std::sqrt(se_t / n_truth) : 0.0)},
                   {"t_err_max_m", or_null(n_truth > 0, max_t)},
                   {"t_err_rmse_rad", or_null(n_truth > 0, n_truth ? std::sqrt(se_r / n_truth) : 0.0)},
                   {"t_nees_mean", or_null(n_truth > 0, n_truth ? sum_nees / n_truth : 0.0)},
                   {"events", ev}};
    const double replayed = res.t_end_s - res.t_begin_s;
    j["timing"] = {{"wall_s", res.wall_s},
                   {"load_s", info.load_s},
                   {"replayed_s", replayed},
                   {"realtime_factor", or_null(res.wall_s > 0.0, res.wall_s > 0.0 ? replayed / res.wall_s : 0.0)}};
    j["notes"] = res.notes;
    const fs::path metrics_path = d / "metrics.json";
    auto f = open_out(metrics_path);
    f << std::setw(2) << j << '\n';
    close_out(f, metrics_path);
}

bool report_limits(std::ostream &err, const Dataset &ds, const ReplayResult &res)
{
    bool capacity = false;
    for (const auto &r : res.robots) {
        for (const slam_filter_limit_t &l : r.limits) {
            char line[512];
            (void)slam_filter_limit_format(&l, static_cast<unsigned>(r.id), line, sizeof line);
            err << line << "\n";
            capacity = capacity || l.capacity_macro != nullptr;
        }
    }
    for (const auto &r : res.robots) {
        if (r.sightings_range_dropped > 0) {
            err << "note: robot " << r.id << ": " << r.sightings_range_dropped
                << " sightings outside the [input] range limits dropped (sightings_range_dropped)\n";
        }
        if (r.sightings_before_start > 0 || r.robot_sightings_before_start > 0) {
            /* the filter starts at the first odometry record: a robot that
             * stood still at the start may have seen things before it */
            err << "note: robot " << r.id << ": " << r.sightings_before_start << " landmark and "
                << r.robot_sightings_before_start
                << " robot sightings before its first odometry record not used (sightings_before_start, "
                   "robot_sightings_before_start)\n";
        }
    }
    if (ds.report.unknown_robot_sightings > 0) {
        err << "warning: " << ds.report.unknown_robot_sightings
            << " sightings of robots not in the dataset skipped (unknown_robot_sightings)\n";
    }
    if (ds.report.unknown_subject_rows > 0) {
        err << "warning: " << ds.report.unknown_subject_rows
            << " sightings of subjects neither robot nor true landmark skipped (unknown_subject_rows)\n";
    }
    return capacity;
}

void print_summary(std::ostream &out, const ReplayResult &res, const ReplayOptions &opt)
{
    const auto flags = out.flags();
    out << std::fixed << std::setprecision(3);
    out << "replay " << res.t_begin_s << " .. " << res.t_end_s << " s, " << res.robots.size() << " robot(s), "
        << (opt.known_ids ? "known" : "unknown") << " identities, map frame "
        << (opt.start_at_truth ? "world" : "start pose") << "\n";
    // n/a: no ground truth for that figure (pose and map-frame figures need
    // the robot's; the fit_ figures, after the best rigid fit of the map onto
    // the true landmarks, only the landmarks')
    out << "robot  filter     pose_rmse_m  heading_deg  pose_nees  lm_rmse_m  landmarks  spurious  missed  "
           "fit_rmse_m  fit_spurious  fit_missed  step_us(mean/max)\n";
    const auto cell = [&out](int w, bool known, auto v) -> std::ostream & {
        if (known) {
            return out << std::setw(w) << v;
        }
        return out << std::setw(w) << "n/a";
    };
    for (const auto &r : res.robots) {
        const bool pk = r.pose_samples > 0;
        const MapScore &m = r.final_score;
        out << std::setw(5) << r.id << "  " << std::left << std::setw(9) << filter_kind_name(r.filter) << std::right;
        cell(13, pk, r.pose_rmse_m);
        cell(13, pk, r.heading_rmse_rad * 180.0 / M_PI);
        cell(11, pk, r.pose_nees_mean);
        cell(11, m.measured(), m.rmse_m);
        out << std::setw(11) << m.n_estimated;
        cell(10, m.valid, m.n_spurious);
        cell(8, m.valid, m.n_missed);
        cell(12, m.fit.measured(), m.fit.rmse_m);
        cell(14, m.fit.valid, m.fit.n_spurious);
        cell(12, m.fit.valid, m.fit.n_missed);
        out << "  " << std::setprecision(0) << r.step_us_mean << "/" << r.step_us_max << std::setprecision(3) << "\n";
    }
    bool any_fit = false;
    for (const auto &r : res.robots) {
        any_fit = any_fit || r.final_score.fit.valid;
    }
    if (any_fit) {
        out << "rigid fit (map frame in the world: x y [m] theta [deg]):";
        for (const auto &r : res.robots) {
            const FitScore &f = r.final_score.fit;
            if (f.measured()) {
                out << "  " << r.id << ": " << std::setprecision(2) << f.transform.x << " " << f.transform.y << " "
                    << std::setprecision(1) << f.transform.theta * 180.0 / M_PI << std::setprecision(3);
            } else if (f.valid) {
                out << "  " << r.id << ": n/a"; // no landmark matched: no transform
            }
        }
        out << "\n";
    }
    int n_ok = 0;
    for (const auto &e : res.merges) {
        if (e.status == COSLAM_OK || e.status == COSLAM_E_CAPACITY) {
            n_ok++;
        }
    }
    out << "merges: " << n_ok << " (refused: " << res.meetings_refused_range << " range check, "
        << res.merges_refused_disagree << " maps disagree, " << res.merges_refused_lost << " receiver lost, "
        << res.merges_refused_implausible << " implausible, "
        << res.merges_refused_replay << " replay; "
        << res.merges_stale << " stale; failed " << res.merges_failed << ")\n";
    for (const auto &e : res.merges) {
        out << "  t=" << std::setprecision(1) << e.t_s << std::setprecision(3) << "  " << e.sender << " -> "
            << e.receiver << "  " << coslam_status_str(e.status);
        if (e.has_truth) {
            out << "  T err " << e.t_err_m << " m " << e.t_err_rad * 180.0 / M_PI << " deg, NEES " << e.t_nees;
        }
        out << "  pairs " << e.stats.pairs << " NIS ";
        if (e.stats.pairs > 0) {
            out << std::setprecision(1) << e.stats.nis << "/" << e.stats.nis_bound << std::setprecision(3)
                << " placed sd " << e.stats.placed_sd_m << " m";
        } else {
            out << "n/a"; // no pairs: nothing measured
        }
        out << " refused " << e.stats.vetoed << "+" << e.stats.echoes << "+"
            << e.stats.ambiguous << "+" << e.stats.unrefutable << "  fused " << e.stats.fused << " added " << e.stats.added;
        const auto rcv = std::find_if(res.robots.begin(), res.robots.end(),
                                      [&](const RobotResult &r) { return r.id == e.receiver; });
        if (rcv != res.robots.end() && rcv->filter != FilterKind::Ekf) {
            out << " (sums over the particles)"; // Fast-SLAM fuses and adds in each
        }
        if (e.particles_due > 0U) {
            out << " (first part; " << e.particles_due << " particles in idle time)";
        }
        out << "  map rmse ";
        cell(0, e.before.measured(), e.before.rmse_m) << " -> ";
        cell(0, e.after.measured(), e.after.rmse_m) << " (" << e.before.n_estimated << " -> " << e.after.n_estimated
                                                << " landmarks)\n";
    }
    out << "wall time " << std::setprecision(2) << res.wall_s << " s for " << (res.t_end_s - res.t_begin_s)
        << " s of data\n";
    for (const auto &n : res.notes) {
        out << "note: " << n << "\n";
    }
    out.flags(flags);
}

} // namespace coslam::replay
