// coslam-sim: run a simulation scenario (the robots' firmware against the
// simulated world and device emulators), write the run outputs and print a
// one-screen summary. See docs/sim.md.
//
//   coslam-sim [--scenario FILE] [--out DIR] [--seed N] [--duration S] [--camera pixels|oracle] [--quiet]
//
// --camera: where the robots' sightings come from. pixels (the scenario
// default): rendered camera frames through the real detector
// (firmware/vision, docs/vision.md); oracle: the geometric stand-in.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <unistd.h>

#include "checked_file.hpp"
#include "cli_checks.hpp"
#include "profile_json.hpp"
#include "run_output.hpp"
#include "sim/world/scenario.hpp"
#include "sim/world/simulation.hpp"

#ifndef COSLAM_DEFAULT_SCENARIO
#define COSLAM_DEFAULT_SCENARIO "sim/scenarios/paper.toml"
#endif

namespace {

// Exit codes (docs/sim.md): 0 done; 1 an output file or standard output
// (main, stdout_check.h) not written whole or another failure of the run;
// 2 bad usage or configuration (an option, the scenario file); 3 a capacity
// of the core was hit (--allow-capacity-limits).
constexpr int kExitFailed = 1;
constexpr int kExitUsage = 2;
constexpr int kExitCapacity = 3;

// A progress bar on stderr: redrawn in place on a terminal, a line every
// 10 % otherwise (logs).
class ProgressBar {
public:
    explicit ProgressBar(bool quiet) : quiet_(quiet), tty_(isatty(fileno(stderr)) != 0) {}
    void update(const coslam::sim::SimulationProgress &p)
    {
        if (quiet_) return;
        const double frac = p.duration_s > 0.0 ? p.t_s / p.duration_s : 1.0;
        const int pct = static_cast<int>(frac * 100.0 + 0.5);
        const double speed = p.wall_s > 0.0 ? p.t_s / p.wall_s : 0.0;
        if (tty_) {
            const int width = 40;
            const int fill = static_cast<int>(frac * width + 0.5);
            std::fprintf(stderr, "\r[%.*s%*s] %3d%%  t = %6.1f / %.0f s  x%.0f real time", fill,
                         "########################################", width - fill, "", pct, p.t_s, p.duration_s,
                         speed);
            if (pct >= 100) std::fprintf(stderr, "\n");
        } else if (pct >= next_pct_) {
            std::fprintf(stderr, "progress %3d%%  t = %.1f / %.0f s  x%.0f real time\n", pct, p.t_s, p.duration_s, speed);
            next_pct_ = pct - pct % 10 + 10;
        }
        std::fflush(stderr);
    }

private:
    bool quiet_;
    bool tty_;
    int next_pct_ = 0;
};

}  // namespace

static int sim_main(int argc, char **argv)
{
    CLI::App app{"coslam-sim: the two-robot cooperative SLAM experiment in simulation"};
    std::string scenario_path = COSLAM_DEFAULT_SCENARIO;
    std::string out_dir = "out/sim";
    int64_t seed = -1;
    double duration = -1.0;
    bool quiet = false;
    std::string camera;
    bool allow_limits = false;
    app.add_option("--scenario", scenario_path, "scenario file (TOML, docs/sim.md)")->capture_default_str();
    app.add_option("--out", out_dir, "output directory of the run")->capture_default_str();
    app.add_option("--seed", seed, "seed (default: the scenario's)")
        ->check(coslam::cli::int_in(0, INT64_MAX));
    app.add_option("--duration", duration, "simulated seconds (default: the scenario's)")
        ->check(coslam::cli::finite_in(0.0, coslam::sim::kMaxDurationS, true));
    app.add_flag("--quiet", quiet, "no progress bar");
    app.add_option("--camera", camera, "sightings from rendered pixels through the detector, or from the geometric stand-in "
                                       "(default: the scenario's camera.source, pixels)")
        ->check(CLI::IsMember({"pixels", "oracle"}));
    app.add_flag("--allow-capacity-limits", allow_limits,
                 "exit 0 even when a capacity of the core was hit (LIMIT lines); without it such a run exits 3");
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError &e) {
        // --help exits 0; a bad option or value is a usage error (exit 2)
        return app.exit(e) == 0 ? 0 : kExitUsage;
    }

    try {
        coslam::sim::Scenario sc = coslam::sim::load_scenario_file(scenario_path);
        if (!camera.empty()) sc.camera.source = coslam::sim::parse_camera_source(camera);
        coslam::sim::SimulationOptions opt;
        if (seed >= 0) opt.seed = static_cast<uint64_t>(seed);
        if (duration > 0.0) opt.duration_s = duration;
        // the capacities this binary was built with (one visible choice)
        std::fprintf(stderr, "%s\n", coslam::profile_line("coslam-sim").c_str());
        coslam::sim::Simulation sim(sc, opt);
        ProgressBar bar(quiet);
        sim.run([&](const coslam::sim::SimulationProgress &p) { bar.update(p); }, 0.5);
        coslam::sim::write_run_outputs(sim, out_dir);
        // before the LIMIT lines on stderr; a failure's reason kept for main
        std::cout << coslam::sim::run_summary(sim, out_dir) << '\n';
        (void)stdout_check_flush();
        // limits are loud: every loss counter of every robot's filter, and
        // the sightings its source could not fit in a frame
        bool capacity = false;
        for (size_t k = 0; k < sim.n_robots(); ++k) {
            const robot_node_t &node = sim.node(k);
            slam_filter_limit_t lim[SLAM_FILTER_N_LIMITS];
            const int nl = slam_filter_limits(&node.filter, lim);
            for (int i = 0; i < nl; ++i) {
                char line[512];
                (void)slam_filter_limit_format(&lim[i], static_cast<unsigned>(k), line, sizeof line);
                std::fprintf(stderr, "%s\n", line);
                capacity = capacity || lim[i].capacity_macro != nullptr;
            }
            if (node.ctr.sightings_dropped > 0U) {
                std::fprintf(stderr,
                             "LIMIT robot %zu: %u sightings dropped by the camera source: more in one frame than "
                             "fit (sightings_dropped; COSLAM_MAX_SIGHTINGS = %d in this build, profile %s)\n",
                             k, node.ctr.sightings_dropped, (int)COSLAM_MAX_SIGHTINGS, COSLAM_PROFILE_NAME);
                capacity = true;
            }
        }
        if (capacity && !allow_limits) {
            std::fprintf(stderr, "coslam-sim: a capacity of the core was hit (LIMIT lines above); the results are "
                                 "not those of an unlimited run. Exit %d (--allow-capacity-limits to accept)\n",
                         kExitCapacity);
            return kExitCapacity;
        }
    } catch (const coslam::sim::ScenarioError &e) {
        // the scenario file: unreadable, or a key outside its domain
        std::cerr << "coslam-sim: " << e.what() << std::endl;
        return kExitUsage;
    } catch (const std::exception &e) {
        // an output file not written whole (coslam::cli::WriteError), or a
        // failure of the run itself
        std::cerr << "coslam-sim: " << e.what() << std::endl;
        return kExitFailed;
    }
    return 0;
}

// exit status with standard output checked (stdout_check.h)
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-sim", sim_main(argc, argv));
}
