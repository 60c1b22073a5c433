// host/replay/bench_mrclam.cpp - coslam-bench-mrclam: coslam's EKF-SLAM and
// Fast-SLAM side by side with MRPT's EKF-SLAM (CRangeBearingKFSLAM2D) on
// the single-robot streams of MRCLAM (each robot alone, unknown landmark
// identities, no merging).
//
// Every method gets the same steps: for each camera frame with landmark
// sightings, the odometry increment since the previous frame (through the
// replay's odometry model, with coslam's motion covariance) and the frame's
// sightings. Every filter starts at the identity pose with zero covariance
// and is evaluated in that frame (the robot's true start pose); for these
// frame-equivariant filters that is the same as starting at the true pose.
// Pose RMSE over the steps, landmark RMSE after optimal one-to-one matching
// with the gate of the evaluation config, time per step = prediction +
// update (wall clock).
//
//   coslam-bench-mrclam [--data DIR] [--config F] [--robots 1,2] [--particles N]
//                       [--out DIR] [--mrpt-grid] [--repeats K]
//                       [--methods ekf,fs2,fs1,mrpt] [--report NAME]
//                       [--mrpt-sd-range M] [--mrpt-sd-bearing RAD] [--mrpt-assoc nn,jcbb]
// The data folder defaults to $COSLAM_DATA_DIR/mrclam/MRCLAM_Dataset6 (the
// build's COSLAM_DATA_DIR if the variable is unset or empty); without it the
// benchmark prints SKIPPED and exits 0. Any folder coslam-replay reads
// works (an MRCLAM dataset or a landmark log, e.g. the large world of
// `coslam-eval-worlds --world large --write-log DIR`: issue 13's stream for
// MRPT, `make bench-mrpt`). --methods picks the methods (mrpt: its NN and
// JCBB variants, plus the grid with --mrpt-grid); the report goes to
// <out>/<NAME>.{md,json} (default mrclam_bench) and ends with the time
// ratios of MRPT's EKF-SLAM to coslam's, measured in this run.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bench_slam.h"
#include "checked_file.hpp"
#include "cli_checks.hpp"
#include "data_dir.hpp"
#include "replay_config.h"
#include "replay_data.h"
#include "coslam/pose2.h"
#include "replay_filter.h"
#include "replay_odometry.h"
#include "replay_run.h"
#include "replay_truth.h"
#include "profile_json.hpp"

using namespace coslam::replay;
using nlohmann::json;

namespace {

class CoslamSlam : public SlamUnderTest {
public:
    CoslamSlam(FilterKind k, const ReplayConfig &cfg, int particles)
        : kind_(k), particles_(particles), f_(k, cfg, 0, pose2_t{0.0, 0.0, 0.0}, cfg.filter.seed)
    {
    }
    std::string name() const override
    {
        switch (kind_) {
        case FilterKind::Ekf:
            return "coslam EKF-SLAM (JCBB, FEJ)";
        case FilterKind::FastSlam1:
            return "coslam Fast-SLAM 1.0 (" + std::to_string(particles_) + " particles)";
        case FilterKind::FastSlam2:
            return "coslam Fast-SLAM 2.0 (" + std::to_string(particles_) + " particles)";
        }
        return "?";
    }
    void step(const StreamStep &s) override
    {
        for (size_t i = 0; i < s.chunks.size(); ++i) {
            f_.predict(s.chunks[i], s.chunk_dt_s[i]);
        }
        f_.update(s.z.data(), static_cast<int>(s.z.size()));
    }
    pose2_t pose() const override
    {
        pose2_t p;
        cov3_t c;
        f_.pose(&p, &c);
        return p;
    }
    void export_map(map_whole_t *out) override { f_.export_whole(out); }

private:
    FilterKind kind_;
    int particles_;
    RobotFilter f_;
};

struct Stream {
    int robot = 0;
    std::vector<StreamStep> steps;
    std::vector<std::optional<pose2_t>> truth; // per step, map frame
    std::vector<point2_t> truth_lm;            // map frame
    std::vector<int> n_seen;
};

/// The data folder's name for the report ("MRCLAM_Dataset6"), trailing
/// separators ignored.
std::string dataset_label(const std::string &dir)
{
    std::filesystem::path p(dir);
    if (!p.has_filename()) {
        p = p.parent_path();
    }
    return p.filename().string();
}

Stream build_stream(const Dataset &ds, const RobotLog &log, const ReplayConfig &cfg)
{
    Stream s;
    s.robot = log.id;
    const double start = log.odo.empty() ? 0.0 : log.odo.front().t_s;
    double end = start;
    if (!log.odo.empty()) {
        end = std::max(end, log.odo.back().t_s);
    }
    if (!log.z.empty()) {
        end = std::max(end, log.z.back().t_s);
    }
    const OdoTrack odo(log, cfg.odo_of(log.id), end);
    const TruthTrack tt(log.truth);
    const auto origin = tt.at(start);
    if (!origin) {
        throw ReplayError("robot " + std::to_string(log.id) + " has no ground truth at its start");
    }
    const MapFrame frame{*origin};
    std::map<int, int> index;
    for (size_t j = 0; j < ds.landmarks.size(); ++j) {
        index[ds.landmarks[j].id] = static_cast<int>(j);
        s.truth_lm.push_back(frame.point_in_map(ds.landmarks[j].pos));
    }
    s.n_seen.assign(ds.landmarks.size(), 0);
    double t_prev = start;
    size_t i = 0;
    while (i < log.z.size()) {
        const double t = log.z[i].t_s;
        StreamStep st;
        st.t_s = t;
        while (i < log.z.size() && std::fabs(log.z[i].t_s - t) <= 1e-9 * std::max(1.0, std::fabs(t))) {
            const LandmarkSighting &z = log.z[i++];
            if (z.t_s < start || z.range_m < cfg.input.min_range_m || z.range_m > cfg.input.max_range_m) {
                continue;
            }
            st.z.push_back({z.range_m, z.bearing_rad, 0});
            const auto it = index.find(z.landmark_id);
            if (it != index.end()) {
                s.n_seen[static_cast<size_t>(it->second)]++;
            }
        }
        if (st.z.empty()) {
            continue;
        }
        // control-rate chunks, composed with their covariance compounded:
        // C = J_a C_a J_a^T + J_b C_b J_b^T for u = a (+) b
        st.u = {0.0, 0.0, 0.0};
        st.u_cov = cov3_zero();
        for (double ta = t_prev; ta < t - 1e-9;) {
            const double tb = std::min(t, ta + cfg.filter.predict_period_s);
            const odo_increment_t c = odo.increment(ta, tb);
            st.chunks.push_back(c);
            st.chunk_dt_s.push_back(tb - ta);
            double ja[3][3];
            double jb[3][3];
            pose2_compose_jacobians({st.u.dx, st.u.dy, st.u.dtheta}, {c.dx, c.dy, c.dtheta}, ja, jb);
            st.u_cov = cov3_add(cov3_congruence(ja, st.u_cov), cov3_congruence(jb, motion_noise_cov(&cfg.slam, c)));
            st.u = odo_compose(st.u, c);
            ta = tb;
        }
        t_prev = t;
        const auto p = tt.at(t);
        s.truth.push_back(p ? std::optional<pose2_t>(frame.pose_in_map(*p)) : std::nullopt);
        s.steps.push_back(std::move(st));
    }
    return s;
}

struct Row {
    std::string method;
    int robot = 0;
    double pose_rmse_m = 0.0;
    MapScore map;
    double step_us_mean = 0.0;
    double step_us_max = 0.0;
    long steps = 0;
};

Row run_one(SlamUnderTest &slam, const Stream &s, const EvalConfig &ec)
{
    Row r;
    r.method = slam.name();
    r.robot = s.robot;
    double se = 0.0;
    long n = 0;
    double sum_us = 0.0;
    for (size_t k = 0; k < s.steps.size(); ++k) {
        const auto t0 = std::chrono::steady_clock::now();
        slam.step(s.steps[k]);
        const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
        sum_us += us;
        r.step_us_max = std::max(r.step_us_max, us);
        if (s.truth[k]) {
            const pose2_t e = slam.pose();
            se += (e.x - s.truth[k]->x) * (e.x - s.truth[k]->x) + (e.y - s.truth[k]->y) * (e.y - s.truth[k]->y);
            n++;
        }
    }
    r.steps = static_cast<long>(s.steps.size());
    r.pose_rmse_m = n > 0 ? std::sqrt(se / static_cast<double>(n)) : 0.0;
    r.step_us_mean = r.steps > 0 ? sum_us / static_cast<double>(r.steps) : 0.0;
    auto est = std::make_unique<map_whole_t>();
    slam.export_map(est.get());
    r.map = score_map(*est, s.truth_lm, s.n_seen, ec);
    return r;
}

} // namespace

static int bench_mrclam_main(int argc, char **argv)
{
    CLI::App app{"coslam-bench-mrclam: coslam EKF-SLAM / Fast-SLAM vs MRPT EKF-SLAM on MRCLAM single-robot streams"};
    // COSLAM_DATA_DIR in the environment overrides the build's data folder
    std::string data = coslam::cli::data_dir(COSLAM_DATA_DIR) + "/mrclam/MRCLAM_Dataset6";
    std::string config;
    std::vector<int> robots;
    int particles = 100;
    std::string out = "out/bench";
    bool grid = false;
    int repeats = 1;
    std::vector<std::string> method_names = {"ekf", "fs2", "fs1", "mrpt"};
    std::string report = "mrclam_bench";
    MrptSlamOptions mrpt_base;
    std::vector<std::string> mrpt_assoc = {"nn", "jcbb"};
    app.add_option("--data", data, "MRCLAM dataset folder");
    app.add_option("-c,--config", config, "replay INI (noise, odometry model, gates)");
    app.add_option("-r,--robots", robots, "robots (default: all)")
        ->delimiter(',')
        ->check(coslam::cli::int_in(1, kMaxRobotId));
    app.add_option("-p,--particles", particles, "Fast-SLAM particles")
        ->check(coslam::cli::int_in(1, COSLAM_MAX_PARTICLES));
    app.add_option("-o,--out", out, "report folder");
    app.add_flag("--mrpt-grid", grid, "also run MRPT over a grid of its noise settings");
    app.add_option("--repeats", repeats, "run each stream this often, keep the fastest time")
        ->check(coslam::cli::int_in(1, 100));
    app.add_option("--methods", method_names, "methods to run: ekf, fs2, fs1, mrpt")
        ->delimiter(',')
        ->check(CLI::IsMember({"ekf", "fs2", "fs1", "mrpt"}));
    app.add_option("--report", report, "report file name in the out folder, without extension");
    app.add_option("--mrpt-sd-range", mrpt_base.std_range_m, "MRPT's range noise sd [m] (it has no range-dependent model)")
        ->check(coslam::cli::finite_in(0.0, 10.0, true));
    app.add_option("--mrpt-sd-bearing", mrpt_base.std_bearing_rad, "MRPT's bearing noise sd [rad]")
        ->check(coslam::cli::finite_in(0.0, 3.14159, true));
    app.add_option("--mrpt-assoc", mrpt_assoc, "MRPT's data associations to run: nn, jcbb")
        ->delimiter(',')
        ->check(CLI::IsMember({"nn", "jcbb"}));
    if (const int rc = coslam::cli::parse_usage(app, argc, argv); rc >= 0) {
        return rc; // 2: a bad option or value
    }
    std::cerr << coslam::profile_line("coslam-bench-mrclam") << "\n";

    try {
        if (!std::filesystem::is_directory(data)) {
            std::cout << "coslam-bench-mrclam: SKIPPED, no dataset at " << data << "\n";
            return 0;
        }
        ReplayConfig cfg = replay_config_default();
        if (!config.empty()) {
            replay_config_load(cfg, config);
        }
        cfg.filter.particles = particles;
        const Dataset ds = load_dataset(data);
        if (robots.empty()) {
            for (const auto &r : ds.robots) {
                robots.push_back(r.id);
            }
        }
        std::vector<Stream> streams;
        for (const int id : robots) {
            const RobotLog *log = ds.robot(id);
            if (log == nullptr) {
                throw ReplayError("no robot " + std::to_string(id));
            }
            streams.push_back(build_stream(ds, *log, cfg));
        }
        const auto wanted = [&](const char *m) {
            return std::find(method_names.begin(), method_names.end(), m) != method_names.end();
        };
        struct Method {
            std::function<std::unique_ptr<SlamUnderTest>()> make;
            const MrptSlamOptions *mrpt = nullptr; ///< set for MRPT's methods
        };
        std::vector<Method> methods;
        if (wanted("ekf")) {
            methods.push_back({[&] { return std::make_unique<CoslamSlam>(FilterKind::Ekf, cfg, 0); }});
        }
        if (wanted("fs2")) {
            methods.push_back({[&] { return std::make_unique<CoslamSlam>(FilterKind::FastSlam2, cfg, particles); }});
        }
        if (wanted("fs1")) {
            methods.push_back({[&] { return std::make_unique<CoslamSlam>(FilterKind::FastSlam1, cfg, particles); }});
        }
        std::vector<MrptSlamOptions> mrpt_opts;
        if (wanted("mrpt") && mrpt_available()) {
            for (const auto &a : mrpt_assoc) {
                MrptSlamOptions o = mrpt_base;
                o.jcbb = a == "jcbb";
                mrpt_opts.push_back(o);
            }
            if (grid) {
                MrptSlamOptions own;
                own.own_motion_model = true;
                mrpt_opts.push_back(own);
                own.std_range_m = 0.5;
                own.std_bearing_rad = 0.04;
                mrpt_opts.push_back(own);
                for (const double sr : {0.1, 0.3, 0.5}) {
                    for (const double sb : {0.01, 0.04, 0.08}) {
                        MrptSlamOptions g;
                        g.std_range_m = sr;
                        g.std_bearing_rad = sb;
                        mrpt_opts.push_back(g);
                    }
                }
            }
            for (const auto &o : mrpt_opts) { // mrpt_opts is not resized below: the pointers stay valid
                methods.push_back({[o] { return make_mrpt_slam(o); }, &o});
            }
        } else if (wanted("mrpt")) {
            std::cout << "MRPT: not built (CMake did not find mrpt-slam; run `make bench-mrpt` to install "
                         "libmrpt-slam-dev and rebuild)\n";
        }

        std::vector<Row> rows;
        std::vector<std::string> ratio_mrpt; // MRPT's base methods, for the ratios
        for (size_t m = 0; m < methods.size(); ++m) {
            for (const auto &s : streams) {
                Row best;
                for (int rep = 0; rep < repeats; ++rep) {
                    auto slam = methods[m].make();
                    Row r = run_one(*slam, s, cfg.eval);
                    if (rep == 0 || r.step_us_mean < best.step_us_mean) {
                        best = r;
                    }
                }
                if (methods[m].mrpt != nullptr) {
                    const MrptSlamOptions &o = *methods[m].mrpt;
                    std::ostringstream os;
                    os << best.method << " sd " << o.std_range_m << " m, " << o.std_bearing_rad << " rad";
                    best.method = os.str();
                    // the first mrpt_assoc.size() options are the base settings, the rest the grid
                    const bool base = methods[m].mrpt - mrpt_opts.data() < static_cast<std::ptrdiff_t>(mrpt_assoc.size());
                    if (base && std::find(ratio_mrpt.begin(), ratio_mrpt.end(), best.method) == ratio_mrpt.end()) {
                        ratio_mrpt.push_back(best.method);
                    }
                }
                std::cerr << "  " << best.method << " robot " << best.robot << ": pose " << best.pose_rmse_m
                          << " m, landmarks " << best.map.rmse_m << " m (" << best.map.n_estimated << "), "
                          << best.step_us_mean << " us/step\n";
                rows.push_back(best);
            }
        }

        // table: mean over robots per method
        std::ostringstream md;
        md << dataset_label(data) << ", each robot alone (" << streams.size()
           << " robots), unknown identities, filters started at identity = true start pose frame; "
              "landmark gate "
           << cfg.eval.gate_m << " m; " << ds.landmarks.size()
           << " true landmarks. Means over the robots; landmark RMSE pooled over all matched landmarks. "
              "Time per step: the predictions since the last frame (10 Hz) and the update.\n\n";
        md << "| method | pose RMSE [m] | landmark RMSE [m] | landmarks | matched | spurious | missed | "
              "time/step mean [us] | time/step max [us] |\n|---|---|---|---|---|---|---|---|---|\n";
        json jrows = json::array();
        std::vector<std::string> order;
        for (const auto &r : rows) {
            if (std::find(order.begin(), order.end(), r.method) == order.end()) {
                order.push_back(r.method);
            }
            jrows.push_back({{"method", r.method},
                             {"robot", r.robot},
                             {"pose_rmse_m", r.pose_rmse_m},
                             {"landmark_rmse_m", r.map.rmse_m},
                             {"n_estimated", r.map.n_estimated},
                             {"n_spurious", r.map.n_spurious},
                             {"n_missed", r.map.n_missed},
                             {"step_us_mean", r.step_us_mean},
                             {"step_us_max", r.step_us_max},
                             {"steps", r.steps}});
        }
        std::map<std::string, double> mean_us;
        for (const auto &name : order) {
            double p = 0, se = 0, nm = 0, n = 0, sp = 0, mi = 0, us = 0, mx = 0;
            int k = 0;
            for (const auto &r : rows) {
                if (r.method != name) {
                    continue;
                }
                p += r.pose_rmse_m;
                se += r.map.rmse_m * r.map.rmse_m * r.map.n_matched;
                nm += r.map.n_matched;
                n += r.map.n_estimated;
                sp += r.map.n_spurious;
                mi += r.map.n_missed;
                us += r.step_us_mean;
                mx = std::max(mx, r.step_us_max);
                k++;
            }
            mean_us[name] = us / k;
            md << std::fixed << "| " << name << " | " << std::setprecision(2) << p / k << " | "
               << (nm > 0 ? std::sqrt(se / nm) : 0.0) << " | " << std::setprecision(1) << n / k << " | " << nm / k
               << " | " << sp / k << " | " << mi / k << " | " << std::setprecision(0) << us / k << " | " << mx
               << " |\n";
        }
        md << "\nper robot (pose RMSE / landmark RMSE / landmarks / spurious):\n\n| method |";
        for (const auto &s : streams) {
            md << " robot " << s.robot << " |";
        }
        md << "\n|---|";
        for (size_t i = 0; i < streams.size(); ++i) {
            md << "---|";
        }
        md << "\n";
        for (const auto &name : order) {
            md << "| " << name << " |";
            for (const auto &r : rows) {
                if (r.method == name) {
                    md << std::fixed << std::setprecision(2) << " " << r.pose_rmse_m << " / " << r.map.rmse_m << " / "
                       << r.map.n_estimated << " / " << r.map.n_spurious << " |";
                }
            }
            md << "\n";
        }
        // the ratios the comparison is about (MRPT's base settings, not the
        // grid, over each coslam filter), from this run's own timings
        bool ratio_head = false;
        for (const auto &mname : ratio_mrpt) {
            for (const auto &name : order) {
                if (name.rfind("coslam", 0) != 0 || !(mean_us[name] > 0.0)) {
                    continue;
                }
                if (!ratio_head) {
                    md << "\nTime per step, MRPT over coslam (same streams, same run):\n\n";
                    ratio_head = true;
                }
                md << "- " << mname << " / " << name << ": " << std::setprecision(1) << mean_us[mname] / mean_us[name]
                   << "x\n";
            }
        }
        std::cout << md.str();
        std::filesystem::create_directories(out);
        std::ostringstream js;
        js << std::setw(2) << json{{"rows", jrows}, {"data", data}} << "\n";
        coslam::cli::write_text_file(out + "/" + report + ".md", md.str());
        coslam::cli::write_text_file(out + "/" + report + ".json", js.str());
        std::cout << "report: " << out << "/" << report << ".md\n";
        return 0;
    } catch (const coslam::cli::WriteError &e) {
        // the report not written whole (a full disk): exit 1, as coslam-replay
        std::cerr << "coslam-bench-mrclam: " << e.what() << "\n";
        return 1;
    } catch (const std::exception &e) {
        std::cerr << "coslam-bench-mrclam: " << e.what() << "\n";
        return 2;
    }
}

// exit status with standard output checked (stdout_check.h)
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-bench-mrclam", bench_mrclam_main(argc, argv));
}
