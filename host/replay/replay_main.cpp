// host/replay/replay_main.cpp - coslam-replay: replay recorded multi-robot
// landmark data (MRCLAM or the generic landmark log) through the firmware
// core, with map merges at meetings; see docs/replay.md.
//
//   coslam-replay run DATASET [options]     replay, write out/<run>/, plot
//   coslam-replay fit-odometry DATASET      fit the odometry model (scale, delay)
//   coslam-replay fit-noise DATASET         measure the sighting noise model and the detection rate
//   coslam-replay convert DATASET OUT_DIR   write DATASET as a landmark log
//   coslam-replay print-config [--config F] the configuration in effect, as INI
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iomanip>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

#include "checked_file.hpp"
#include "cli_checks.hpp"
#include "replay_config.h"
#include "replay_data.h"
#include "replay_noise.h"
#include "profile_json.hpp"
#include "replay_odometry.h"
#include "replay_output.h"
#include "replay_run.h"

using namespace coslam::replay;
using coslam::cli::finite_in;
using coslam::cli::int_in;

namespace {

// Fewer windows than this cannot tell the odometry's delay and scales apart
// (fit-odometry).
constexpr int kMinOdoFitWindows = 10;

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

void print_noise_row(std::ostream &os, const std::string &who, const NoiseStats &s)
{
    if (!s.has_truth) {
        os << std::setw(7) << who << ": no ground truth\n";
        return;
    }
    os << std::fixed << std::setw(7) << who << std::setw(8) << s.used << std::setw(6) << s.rejected
       << std::setprecision(2) << std::setw(7) << 100.0 * s.rejected_fraction() << std::setprecision(4)
       << std::setw(10) << s.range_bias_m << std::setw(10) << s.bearing_bias_rad << std::setw(9) << s.range_sd_m
       << std::setprecision(6) << std::setw(13) << s.range_var_m2 << std::setw(13) << s.range_var_per_m2
       << std::setw(13) << s.bearing_var_rad2 << std::setprecision(4) << std::setw(9) << std::sqrt(s.range_var_m2)
       << std::setw(9) << std::sqrt(s.range_var_per_m2) << std::setw(9) << std::sqrt(s.bearing_var_rad2)
       << std::setprecision(2) << std::setw(8) << std::sqrt(s.bearing_var_rad2) * 180.0 / M_PI << "\n";
}

void print_noise_fit(std::ostream &os, const NoiseFit &nf, const ReplayConfig &cfg)
{
    const NoiseStats &o = nf.overall;
    os << "sighting noise against ground truth: residual = measured - true, var(range) = range_var_m2 + "
          "range_var_per_m2 * r^2\n"
       << o.sightings << " landmark sightings: " << o.unknown_id << " without known landmark, " << o.no_truth
       << " without robot truth, " << o.out_of_range << " outside [input] range limits, " << o.used << " used\n";
    os << "  robot    used  rej  rej_%  r_bias_m  b_bias_r  r_sd_m  range_var_m2 r_var_per_m2 bearing_var2"
          "  sd_r0_m  sd_frac  sd_b_r  sd_b_deg\n";
    for (const auto &s : nf.robots) {
        print_noise_row(os, std::to_string(s.robot), s);
    }
    print_noise_row(os, "all", o);
    os << "range bins (all robots, inliers): r_mean_m n sd_m model_sd_m\n";
    for (const auto &b : o.bins) {
        os << std::fixed << std::setprecision(2) << "  " << std::setw(6) << b.r_mean_m << std::setw(7) << b.n
           << std::setprecision(4) << std::setw(9) << std::sqrt(b.var_m2) << std::setw(9)
           << std::sqrt(o.range_var_m2 + o.range_var_per_m2 * b.r2_mean_m2) << "\n";
    }
    auto corr_row = [&](const char *what, const NoiseCorrelation &c) {
        os << std::setprecision(3) << "  " << std::setw(8) << what;
        for (size_t k = 0; k < 5; ++k) {
            os << std::setw(8) << (k < c.rho.size() ? c.rho[k] : 0.0);
        }
        os << std::setw(7) << c.lags_summed << std::setw(8) << c.tau << std::setw(8) << c.factor << "\n";
    };
    os << "residual correlation along tracks (one robot, one landmark, gaps <= track gap): " << nf.tracks
       << " tracks, " << nf.samples << " inliers\n"
       << "             rho_1   rho_2   rho_3   rho_4   rho_5  lags     tau  factor  (tau = 1 + 2 sum rho_k while "
          "rho_k > 0; factor = (1 - rho_1) + n rho_1, n = mean track length: the inflation used)\n";
    corr_row("range", nf.range_corr);
    corr_row("bearing", nf.bearing_corr);
    os << std::setprecision(6) << "  raw:      range_var_m2 " << o.range_var_m2 << " range_var_per_m2 "
       << o.range_var_per_m2 << " bearing_var_rad2 " << o.bearing_var_rad2 << std::setprecision(4) << "  (sd_frac "
       << std::sqrt(o.range_var_per_m2) << ", sd_b_deg " << std::sqrt(o.bearing_var_rad2) * 180.0 / M_PI << ")\n"
       << std::setprecision(6) << "  inflated: range_var_m2 " << nf.range_var_m2_eff << " range_var_per_m2 "
       << nf.range_var_per_m2_eff << " bearing_var_rad2 " << nf.bearing_var_rad2_eff << std::setprecision(4)
       << "  (sd_frac " << std::sqrt(nf.range_var_per_m2_eff) << ", sd_b_deg "
       << std::sqrt(nf.bearing_var_rad2_eff) * 180.0 / M_PI << ")\n";
    const auto &n = cfg.slam.noise;
    os << std::setprecision(6) << "configuration in effect: range_var_m2 " << n.range_var_m2 << " range_var_per_m2 "
       << n.range_var_per_m2 << " bearing_var_rad2 " << n.bearing_var_rad2 << "\n";
}

void print_detection_row(std::ostream &os, const std::string &who, const DetectionStats &s)
{
    if (!s.has_truth) {
        os << std::setw(7) << who << std::setw(8) << s.frames << "  n/a: no ground truth\n";
        return;
    }
    const double em = slam_exist_miss_for_detection(s.p_d());
    os << std::fixed << std::setw(7) << who << std::setw(8) << s.frames << std::setw(9) << s.no_truth << std::setw(8)
       << s.used << std::setw(8) << s.other << std::setw(9) << s.in_view << std::setw(9) << s.detected
       << std::setw(9) << s.out_of_view << std::setprecision(4) << std::setw(8) << s.p_d() << std::setw(10)
       << s.p_d_truncated << std::setw(12);
    if (em >= 0.0) {
        os << em;
    } else {
        os << "n/a";
    }
    os << "\n";
}

void print_detection_fit(std::ostream &os, const DetectionFit &df, const ReplayConfig &cfg)
{
    const slam_params_t &p = cfg.slam;
    const double m = p.visibility_margin;
    const DetectionStats &o = df.overall;
    os << std::fixed << std::setprecision(3)
       << "detection rate over the filter's view: true landmarks landmark_should_be_seen calls in view from the true "
          "pose (range "
       << p.sensor_min_range_m / m << ".." << p.sensor_max_range_m * m << " m, |bearing| <= "
       << 0.5 * p.sensor_fov_rad * m << " rad), detected when the frame holds a sighting with that identity\n"
       << "  robot  frames no_truth    used   other  in_view detected  out_view     p_d p_d_trunc  exist_miss\n";
    for (const auto &s : df.robots) {
        print_detection_row(os, std::to_string(s.robot), s);
    }
    print_detection_row(os, "all", o);
    os << "  (frames: logged stamps; other: frames holding a sighting other than an in-view detection; out_view: "
          "sightings of a true landmark outside the view, not in p_d)\n"
       << "  bias: a frame is logged only when it holds a sighting, so the " << o.used
       << " frames counted (those with truth) are frames with at least one detection, and no frame without one "
          "is: p_d over them is biased upward\n"
          "  p_d_trunc: the zero-truncated estimate (a frame holding nothing but in-view detections was logged "
          "because one was detected; detections independent), reported only\n";
    os << "range bins (all robots, true range): r_m in_view detected p_d\n";
    for (const auto &b : o.bins) {
        if (b.in_view == 0) {
            continue;
        }
        os << std::setprecision(1) << "  " << std::setw(4) << b.r_lo_m << "-" << std::setw(4) << b.r_lo_m + df.bin_m
           << std::setw(9) << b.in_view << std::setw(9) << b.detected << std::setprecision(4) << std::setw(8)
           << static_cast<double>(b.detected) / static_cast<double>(b.in_view) << "\n";
    }
    os << std::setprecision(4) << "exist_miss_confirmed = slam_exist_miss_for_detection(p_d) = log((1 - p_f) / (1 - "
          "p_d)) / log(p_d / p_f), p_f = "
       << SLAM_EXIST_P_FALSE << ": ";
    if (df.exist_miss_confirmed >= 0.0) {
        os << df.exist_miss_confirmed;
    } else {
        os << "n/a (needs p_f < p_d < 1)";
    }
    os << " (p_d " << o.p_d() << "); of p_d_trunc " << o.p_d_truncated << ": ";
    if (df.exist_miss_confirmed_truncated >= 0.0) {
        os << df.exist_miss_confirmed_truncated;
    } else {
        os << "n/a";
    }
    os << "; configuration in effect: " << p.exist_miss_confirmed << "\n";
}

// Why a plot command run through std::system failed, for the error line.
std::string plot_failure(int status)
{
    if (status == -1) {
        return "no shell could be started";
    }
    if (WIFEXITED(status)) {
        return "the plotter exited with status " + std::to_string(WEXITSTATUS(status));
    }
    if (WIFSIGNALED(status)) {
        return "the plotter was killed by signal " + std::to_string(WTERMSIG(status));
    }
    return "status " + std::to_string(status);
}

int replay_main(int argc, char **argv);

} // namespace

static_assert(kExitWrite == STDOUT_CHECK_EXIT_WRITE, "a lost stdout exits as a lost output file");

// Every subcommand's exit status, then standard output checked: what was
// printed to a full disk or a closed pipe (SIGPIPE ignored) is lost, and a
// run that lost it does not exit 0 (replay_output.h: exit codes).
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-replay", replay_main(argc, argv));
}

namespace {

int replay_main(int argc, char **argv)
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
    bool allow_capacity = false;
    run->add_option("dataset", dataset, "MRCLAM folder or landmark-log folder")->required();
    run->add_option("--format", format, "auto | mrclam | log");
    run->add_option("-c,--config", config_files, "INI file(s) with parameters, applied in order (print-config shows them all)");
    run->add_option("-r,--robots", robots, "robot ids to replay, e.g. 1,2 (default: all)")
        ->delimiter(',')
        ->check(int_in(1, kMaxRobotId));
    run->add_option("-f,--filter", filter, "filter of every robot: fastslam1 | fastslam2 | ekf");
    run->add_option("--robot-filter", robot_filters, "per robot, e.g. 2=ekf (repeatable)");
    run->add_option("-p,--particles", particles, "Fast-SLAM particles")->check(int_in(1, COSLAM_MAX_PARTICLES));
    run->add_flag("--known-ids", known_ids, "use the true landmark identities (comparison mode)");
    run->add_flag("--start-at-truth", start_at_truth, "start each filter at its true pose (map frame = world)");
    run->add_option("-d,--duration", duration, "replay only the first DURATION seconds")
        ->check(finite_in(0.0, kMaxSpanS, true));
    run->add_flag("--no-merge", no_merge, "no map merging at meetings");
    run->add_option("--merge-window", merge_window, "max time between the two mutual sightings [s]")
        ->check(finite_in(0.0, 4000.0, true));
    run->add_option("--merge-interval", merge_interval, "min time between two merges of a pair [s]")
        ->check(finite_in(0.0, 4000.0));
    run->add_option("--seed", seed, "filter seed")->check(int_in(0, std::numeric_limits<long long>::max()));
    run->add_option("-o,--out", out_dir, "output folder");
    run->add_flag("--no-plots", no_plots, "do not draw the figures (figures that fail to draw: exit 4)");
    run->add_flag("-q,--quiet", quiet, "no progress bar");
    run->add_flag("--allow-capacity-limits", allow_capacity,
                  "exit 0 even when a capacity of the core was hit (otherwise exit 3)");

    auto *fit = app.add_subcommand("fit-odometry", "fit the odometry scale and delay against ground truth");
    double window = 1.0;
    fit->add_option("dataset", dataset, "dataset folder")->required();
    fit->add_option("--format", format, "auto | mrclam | log");
    fit->add_option("--window", window, "fit window [s]")->check(finite_in(0.0, 1e4, true));

    auto *fitn = app.add_subcommand("fit-noise", "measure the sighting noise (range, bearing) against ground truth");
    std::string noise_out;
    bool noise_inflate = false;
    NoiseFitOptions nopt;
    fitn->add_option("dataset", dataset, "dataset folder (needs robot and landmark ground truth)")->required();
    fitn->add_option("--format", format, "auto | mrclam | log");
    fitn->add_option("-c,--config", config_files,
                     "INI file(s): [input] range limits, the [slam] view of the detection rate, and the values compared "
                     "with");
    fitn->add_option("-o,--out", noise_out, "write the fitted [slam] noise keys to this INI file");
    fitn->add_option("--bin", nopt.bin_m, "range bin width of the range fit [m]")->check(finite_in(0.0, 1e3, true));
    fitn->add_option("--reject-sd", nopt.reject_sd, "reject residuals beyond this many robust sd")
        ->check(finite_in(0.0, 1e6, true));
    fitn->add_flag("--inflate", noise_inflate,
                   "write the variances inflated for a per-track offset ((1 - rho_1) + n rho_1) to -o");
    fitn->add_option("--track-gap", nopt.track_gap_s, "sightings further apart start a new track [s]")
        ->check(finite_in(0.0, 1e6, true));
    fitn->add_option("--max-lag", nopt.max_lag, "autocorrelation lags 1..N [sightings]")->check(int_in(1, 1000));
    DetectionOptions dopt;
    fitn->add_option("--detect-bin", dopt.bin_m, "range bin width of the detection-rate table [m]")
        ->check(finite_in(0.0, 1e3, true));

    auto *conv = app.add_subcommand("convert", "write a dataset in the generic landmark-log format");
    std::string conv_out;
    conv->add_option("dataset", dataset, "dataset folder")->required();
    conv->add_option("out_dir", conv_out, "output folder")->required();
    conv->add_option("--format", format, "auto | mrclam | log");

    auto *pc = app.add_subcommand("print-config", "print the configuration in effect as INI");
    pc->add_option("-c,--config", config_files, "INI file(s) applied over the defaults, in order");

    if (const int rc = coslam::cli::parse_usage(app, argc, argv); rc >= 0) {
        return rc; // --help 0, a bad option or value 2 (CLI11's own codes were 105, 106, ...)
    }

    try {
        ReplayConfig cfg = replay_config_default();
        for (const auto &f : config_files) {
            replay_config_load(cfg, f);
        }
        if (*pc) {
            replay_config_write(cfg, std::cout);
            return 0;
        }
        if (*run) {
            // the capacities this binary was built with (one visible choice)
            std::cerr << coslam::profile_line("coslam-replay") << "\n";
        }
        const auto t_load = std::chrono::steady_clock::now();
        // a run with -r reads only those robots' files (a bad line in another
        // robot's file does not stop it; their stamps still set t0)
        const Dataset ds = load_dataset(dataset, parse_format(format), *run ? robots : std::vector<int>{});
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
        for (const auto &[id, g] : ds.report.odo_gaps) {
            std::cerr << "warning: robot " << id << ": " << g.count << " gap(s) of more than " << kOdoGapWarnS
                      << " s between odometry records, the largest " << fmt_value(g.max_s) << " s (before "
                      << g.where << "): the last command is held across them (odometry_gaps)\n";
        }

        if (*conv) {
            write_landmark_log(ds, conv_out);
            std::cout << "wrote " << ds.robots.size() << " robot log(s) to " << conv_out << "\n";
            return 0;
        }
        if (*fitn) {
            // the sightings the replay would drop are not measured either
            nopt.min_range_m = cfg.input.min_range_m;
            nopt.max_range_m = cfg.input.max_range_m;
            const NoiseFit nf = fit_noise(ds, nopt);
            print_noise_fit(std::cout, nf, cfg);
            // p_d over the view of the slam parameters `run -c` would use
            dopt.min_range_m = cfg.input.min_range_m;
            dopt.max_range_m = cfg.input.max_range_m;
            const DetectionFit df = fit_detection(ds, cfg.slam, dopt);
            print_detection_fit(std::cout, df, cfg);
            if (!noise_out.empty()) {
                std::ofstream f = coslam::cli::open_checked(noise_out);
                write_noise_ini(nf, ds, f, noise_inflate, &df);
                coslam::cli::close_checked(f, noise_out);
                std::cout << "wrote " << noise_out << "\n";
            }
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
                if (f.windows < kMinOdoFitWindows) {
                    /* nothing to fit: every delay scores alike, and the first
                     * one tried would be printed as if it were a fit */
                    std::cout << r.id << ": " << f.windows << " windows of truth and odometry together (at least "
                              << kMinOdoFitWindows << " needed): no fit, left out of the mean\n";
                    continue;
                }
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
            if (n == 0) {
                // as fit-noise: a fit of nothing is not a success
                throw ReplayError(ds.source, 0,
                                  "nothing fitted: no robot has ground truth overlapping its odometry in at least " +
                                      std::to_string(kMinOdoFitWindows) + " windows (RobotN_Groundtruth.dat or "
                                      "robot<k>_truth.txt)");
            }
            std::cout << std::setprecision(3) << "mean: scale_v " << sv / n << " scale_w " << sw / n << " delay_s "
                      << std::setprecision(2) << dl / n << "\n";
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
            std::string id_text = rf.substr(0, eq);
            if (!int_in(1, kMaxRobotId)(id_text).empty()) {
                throw ReplayError("--robot-filter: robot id '" + printable(rf.substr(0, eq)) + "' is not in 1.." +
                                  std::to_string(kMaxRobotId));
            }
            RobotOverride &o = cfg.robot[std::stoi(id_text)];
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
        replay_config_validate(cfg);
        {
            // per-robot settings ([robotN], --robot-filter) of a robot that is
            // not replayed were dropped without a word
            std::string unused;
            for (const auto &[id, o] : cfg.robot) {
                if (ds.robot(id) == nullptr) {
                    unused += (unused.empty() ? "" : ", ") + std::to_string(id);
                }
            }
            if (!unused.empty()) {
                std::cerr << "note: settings for robot(s) " << unused << " ([robotN] or --robot-filter) not used: "
                          << "not in the dataset" << (robots.empty() ? "" : " or not selected with -r") << "\n";
            }
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
        const bool capacity_hit = report_limits(std::cerr, ds, res);
        std::cout << "outputs in " << out_dir << " (dataset read in " << std::fixed << std::setprecision(2) << load_s
                  << " s)\n";
        bool plot_failed = false;
        if (!no_plots) {
            // the summary before the plotter's own lines on a shared stdout
            (void)stdout_check_flush(); // a failure's reason kept for main
            const std::string cmd = "/usr/bin/python3 '" + plot_script() + "' '" + out_dir + "'";
            const int status = std::system(cmd.c_str());
            if (status != 0) {
                // figures were asked for and are missing: not a success,
                // though every data file above was written whole
                std::cerr << "coslam-replay: error: the figures were not drawn: " << plot_failure(status) << " ("
                          << cmd << "); the data outputs in " << out_dir
                          << " are complete (--no-plots runs without figures)\n";
                plot_failed = true;
            }
        }
        if (capacity_hit && !allow_capacity) {
            std::cerr << "coslam-replay: a capacity of the core was hit (LIMIT lines above); the results are not "
                         "those of an unlimited filter. Exit "
                      << kExitCapacity << " (--allow-capacity-limits to accept)\n";
            return kExitCapacity;
        }
        if (plot_failed) {
            std::cerr << "coslam-replay: exit " << kExitPlot << ": figures missing\n";
            return kExitPlot;
        }
        return 0;
    } catch (const coslam::cli::WriteError &e) {
        // an output file not written whole (a full disk): the results are
        // incomplete, whatever was printed
        std::cerr << "coslam-replay: " << e.what() << "\n";
        return kExitWrite;
    } catch (const ReplayError &e) {
        std::cerr << "coslam-replay: " << e.what() << "\n";
        return 2;
    } catch (const std::exception &e) {
        std::cerr << "coslam-replay: " << e.what() << "\n";
        return 2;
    }
}

} // namespace
