// host/replay/replay_main.cpp - coslam-replay: replay recorded multi-robot
// landmark data (MRCLAM or the generic landmark log) through the firmware
// core, with map merges at meetings; see docs/replay.md.
//
//   coslam-replay run DATASET [options]     replay, write out/<run>/, plot
//   coslam-replay fit-odometry DATASET      fit the odometry model (scale, delay)
//   coslam-replay convert DATASET OUT_DIR   write DATASET as a landmark log
//   coslam-replay print-config [--config F] the configuration in effect, as INI
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <unistd.h>

#include "replay_config.h"
#include "replay_data.h"
#include "replay_odometry.h"
#include "replay_output.h"
#include "replay_run.h"

using namespace coslam::replay;

namespace {

// A progress bar on stderr: redrawn in place on a terminal, one line per
// 10 % otherwise (logs stay readable).
class ProgressBar {
public:
    explicit ProgressBar(bool enabled) : enabled_(enabled), tty_(isatty(2) != 0) {}
    void operator()(double f)
    {
        if (!enabled_) {
            return;
        }
        const int pct = static_cast<int>(std::floor(100.0 * std::min(1.0, std::max(0.0, f))));
        if (pct == last_ || (!tty_ && pct / 10 == last_ / 10 && pct != 100)) {
            return;
        }
        last_ = pct;
        const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
        const int width = 40;
        const int fill = pct * width / 100;
        std::ostringstream os;
        os << "[" << std::string(static_cast<size_t>(fill), '#') << std::string(static_cast<size_t>(width - fill), ' ')
           << "] " << std::setw(3) << pct << "%  " << std::fixed << std::setprecision(1) << el << " s";
        if (pct > 0 && pct < 100) {
            os << ", ~" << el * (100 - pct) / pct << " s left";
        }
        std::cerr << (tty_ ? "\r" : "") << os.str() << (tty_ ? "   " : "\n") << std::flush;
        if (pct == 100 && tty_) {
            std::cerr << "\n";
        }
    }

private:
    bool enabled_;
    bool tty_;
    int last_ = -1;
    std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

DataFormat parse_format(const std::string &s)
{
    if (s == "auto") {
        return DataFormat::Auto;
    }
    if (s == "mrclam") {
        return DataFormat::Mrclam;
    }
    if (s == "log") {
        return DataFormat::Log;
    }
    throw ReplayError("--format must be auto, mrclam or log");
}

std::string plot_script()
{
    if (const char *e = std::getenv("COSLAM_PLOT_REPLAY")) {
        return e;
    }
    return std::string(COSLAM_SOURCE_DIR) + "/tools/plot_replay.py";
}

} // namespace

int main(int argc, char **argv)
{
    CLI::App app{"coslam-replay: replay recorded multi-robot landmark data through the coslam core"};
    app.require_subcommand(1);

    std::string dataset;
    std::string format = "auto";
    std::vector<std::string> config_files;

    auto *run = app.add_subcommand("run", "replay a dataset and write the run outputs");
    std::vector<int> robots;
    std::string filter;
    std::vector<std::string> robot_filters;
    int particles = 0;
    bool known_ids = false;
    bool start_at_truth = false;
    double duration = 0.0;
    bool no_merge = false;
    double merge_window = -1.0;
    double merge_interval = -1.0;
    long long seed = -1;
    std::string out_dir = "out/replay";
    bool no_plots = false;
    bool quiet = false;
    run->add_option("dataset", dataset, "MRCLAM folder or landmark-log folder")->required();
    run->add_option("--format", format, "auto | mrclam | log");
    run->add_option("-c,--config", config_files, "INI file(s) with parameters, applied in order (print-config shows them all)");
    run->add_option("-r,--robots", robots, "robot ids to replay, e.g. 1,2 (default: all)")->delimiter(',');
    run->add_option("-f,--filter", filter, "filter of every robot: fastslam1 | fastslam2 | ekf");
    run->add_option("--robot-filter", robot_filters, "per robot, e.g. 2=ekf (repeatable)");
    run->add_option("-p,--particles", particles, "Fast-SLAM particles");
    run->add_flag("--known-ids", known_ids, "use the true landmark identities (comparison mode)");
    run->add_flag("--start-at-truth", start_at_truth, "start each filter at its true pose (map frame = world)");
    run->add_option("-d,--duration", duration, "replay only the first DURATION seconds");
    run->add_flag("--no-merge", no_merge, "no map merging at meetings");
    run->add_option("--merge-window", merge_window, "max time between the two mutual sightings [s]");
    run->add_option("--merge-interval", merge_interval, "min time between two merges of a pair [s]");
    run->add_option("--seed", seed, "filter seed");
    run->add_option("-o,--out", out_dir, "output folder");
    run->add_flag("--no-plots", no_plots, "do not draw the figures");
    run->add_flag("-q,--quiet", quiet, "no progress bar");

    auto *fit = app.add_subcommand("fit-odometry", "fit the odometry scale and delay against ground truth");
    double window = 1.0;
    fit->add_option("dataset", dataset, "dataset folder")->required();
    fit->add_option("--format", format, "auto | mrclam | log");
    fit->add_option("--window", window, "fit window [s]");

    auto *conv = app.add_subcommand("convert", "write a dataset in the generic landmark-log format");
    std::string conv_out;
    conv->add_option("dataset", dataset, "dataset folder")->required();
    conv->add_option("out_dir", conv_out, "output folder")->required();
    conv->add_option("--format", format, "auto | mrclam | log");

    auto *pc = app.add_subcommand("print-config", "print the configuration in effect as INI");
    pc->add_option("-c,--config", config_files, "INI file(s) applied over the defaults, in order");

    CLI11_PARSE(app, argc, argv);

    try {
        ReplayConfig cfg = replay_config_default();
        for (const auto &f : config_files) {
            replay_config_load(cfg, f);
        }
        if (*pc) {
            replay_config_write(cfg, std::cout);
            return 0;
        }
        const auto t_load = std::chrono::steady_clock::now();
        const Dataset ds = load_dataset(dataset, parse_format(format));
        const double load_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_load).count();
        if (ds.report.unknown_barcode_rows > 0) {
            std::cerr << "warning: " << ds.report.unknown_barcode_rows
                      << " sightings with barcodes not in Barcodes.dat skipped (false detections):";
            for (const auto &[b, n] : ds.report.unknown_barcodes) {
                std::cerr << " " << b << " (x" << n << ")";
            }
            std::cerr << "\n";
        }
        for (const auto &n : ds.report.notes) {
            std::cerr << "note: " << n << "\n";
        }

        if (*conv) {
            write_landmark_log(ds, conv_out);
            std::cout << "wrote " << ds.robots.size() << " robot log(s) to " << conv_out << "\n";
            return 0;
        }
        if (*fit) {
            std::cout << "odometry model fit (" << window
                      << " s windows): the command acts delay_s after its stamp, scaled by scale_v / scale_w\n";
            std::cout << "robot  windows  raw_scale_v  raw_scale_w  delay_s  scale_v  scale_w  resid_xy_sd_m  "
                         "resid_th_sd_rad  w3_m2_per_m  w4_rad2_per_m  drift30s_raw_m  drift30s_fit_m\n";
            double sv = 0.0, sw = 0.0, dl = 0.0;
            int n = 0;
            for (const auto &r : ds.robots) {
                if (r.truth.empty()) {
                    std::cout << r.id << ": no ground truth\n";
                    continue;
                }
                const OdoFit f = fit_odometry(r, window, cfg.slam.base_radius_m);
                std::cout << std::fixed << std::setw(5) << r.id << std::setw(9) << f.windows << std::setprecision(3)
                          << std::setw(13) << f.raw_scale_v << std::setw(13) << f.raw_scale_w << std::setprecision(2)
                          << std::setw(9) << f.model.delay_s << std::setprecision(3) << std::setw(9)
                          << f.model.scale_v << std::setw(9) << f.model.scale_w << std::setprecision(4)
                          << std::setw(15) << f.resid_xy_sd_m << std::setw(17) << f.resid_th_sd_rad
                          << std::setprecision(5) << std::setw(13) << f.w3_m2_per_m << std::setw(15)
                          << f.w4_rad2_per_m << std::setprecision(3) << std::setw(16) << f.drift_raw_m
                          << std::setw(16) << f.drift_fit_m << "\n";
                sv += f.model.scale_v;
                sw += f.model.scale_w;
                dl += f.model.delay_s;
                n++;
            }
            if (n > 0) {
                std::cout << std::setprecision(3) << "mean: scale_v " << sv / n << " scale_w " << sw / n
                          << " delay_s " << std::setprecision(2) << dl / n << "\n";
            }
            return 0;
        }

        // run
        if (!filter.empty()) {
            cfg.filter.type = filter_kind_from_string(filter);
        }
        for (const auto &rf : robot_filters) {
            const auto eq = rf.find('=');
            if (eq == std::string::npos) {
                throw ReplayError("--robot-filter expects ID=FILTER, got '" + rf + "'");
            }
            RobotOverride &o = cfg.robot[std::stoi(rf.substr(0, eq))];
            o.filter = filter_kind_from_string(rf.substr(eq + 1));
            o.has_filter = true;
        }
        if (particles > 0) {
            cfg.filter.particles = particles;
        }
        if (no_merge) {
            cfg.merge.enabled = false;
        }
        if (merge_window >= 0.0) {
            cfg.merge.window_s = merge_window;
        }
        if (merge_interval >= 0.0) {
            cfg.merge.interval_s = merge_interval;
        }
        if (seed >= 0) {
            cfg.filter.seed = static_cast<uint64_t>(seed);
        }
        if (cfg.filter.particles > COSLAM_MAX_PARTICLES) {
            throw ReplayError("at most " + std::to_string(COSLAM_MAX_PARTICLES) + " particles");
        }
        ReplayOptions opt;
        opt.robots = robots;
        opt.known_ids = known_ids;
        opt.start_at_truth = start_at_truth;
        opt.duration_s = duration;
        ProgressBar bar(!quiet);
        opt.progress = [&bar](double f) { bar(f); };
        const ReplayResult res = run_replay(ds, cfg, opt);
        RunInfo info;
        for (int i = 0; i < argc; ++i) {
            info.command += (i ? " " : "") + std::string(argv[i]);
        }
        info.load_s = load_s;
        write_run_outputs(out_dir, ds, cfg, opt, res, info);
        print_summary(std::cout, res, opt);
        std::cout << "outputs in " << out_dir << " (dataset read in " << std::fixed << std::setprecision(2) << load_s
                  << " s)\n";
        if (!no_plots) {
            const std::string cmd = "/usr/bin/python3 '" + plot_script() + "' '" + out_dir + "'";
            if (std::system(cmd.c_str()) != 0) {
                std::cerr << "warning: plotting failed (" << cmd << ")\n";
            }
        }
        return 0;
    } catch (const ReplayError &e) {
        std::cerr << "coslam-replay: " << e.what() << "\n";
        return 2;
    } catch (const std::exception &e) {
        std::cerr << "coslam-replay: " << e.what() << "\n";
        return 2;
    }
}
