// host/calibrate/calibrate_main.cpp - coslam-calibrate: search the paper's
// eight noise weights (eq. 6) with an Evolution Strategy on training
// episodes, report them on held-out episodes, write the result as INI.
// docs/calibration.md has the method, the choices and the measurements.
//
//   coslam-calibrate [options]                 synthetic worlds (default)
//   coslam-calibrate --source mrclam [options] MRCLAM robots, each alone
//   mpirun -np K coslam-calibrate ...          episodes split over K ranks
//   coslam-calibrate --sweep-particles 5,...   particle-count curve and choice (Fig. 10)
//   coslam-calibrate --figures calibrated.ini  hand-tuned vs calibrated traces (Figs. 4, 5)
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <thread>

#include "app/slam_params_ini.h"
#include "calib.h"
#include "checked_file.hpp"
#include "data_dir.hpp"
#include "experiments.h"
#include "replay_config.h"
#include "profile_json.hpp"
#include "replay_data.h"
#include "replay_run.h"

#ifdef COSLAM_HAVE_MPI
#include <mpi.h>
#endif

using namespace coslam::calibrate;
using coslam::replay::ReplayConfig;
using nlohmann::json;

namespace {

struct UsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// "1-4", "1,3,7", "1-3,10" -> list; refuses empty, reversed, negative, > 1e9
std::vector<uint64_t> parse_seed_list(const std::string &s, const char *what)
{
    std::vector<uint64_t> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ',')) {
        const auto dash = item.find('-', 1);
        try {
            size_t p1 = 0;
            if (item.empty() || item[0] == '-' || item[0] == '+') {
                throw std::invalid_argument("");
            }
            if (dash == std::string::npos) {
                const unsigned long long v = std::stoull(item, &p1);
                if (p1 != item.size()) {
                    throw std::invalid_argument("");
                }
                out.push_back(v);
            } else {
                size_t p2 = 0;
                const std::string a = item.substr(0, dash), b = item.substr(dash + 1);
                if (b.empty() || b[0] == '-' || b[0] == '+') {
                    throw std::invalid_argument("");
                }
                const unsigned long long lo = std::stoull(a, &p1);
                const unsigned long long hi = std::stoull(b, &p2);
                if (p1 != a.size() || p2 != b.size() || hi < lo || hi - lo > 10000) {
                    throw std::invalid_argument("");
                }
                for (unsigned long long v = lo; v <= hi; ++v) {
                    out.push_back(v);
                }
            }
        } catch (const std::exception &) {
            throw UsageError(std::string(what) + ": '" + item + "' is not a seed, a list (1,2,5) or a range (1-4)");
        }
    }
    if (out.empty() || out.size() > 10000) {
        throw UsageError(std::string(what) + ": give 1 to 10000 seeds");
    }
    for (uint64_t v : out) {
        if (v > 1000000000ULL) {
            throw UsageError(std::string(what) + ": seeds must be in 0..1e9");
        }
    }
    return out;
}

void require_finite_range(double v, double lo, double hi, bool lo_open, const char *name)
{
    if (!std::isfinite(v) || v > hi || (lo_open ? v <= lo : v < lo)) {
        std::ostringstream os;
        os << name << ": " << v << " is outside " << (lo_open ? "(" : "[") << lo << ", " << hi << "]";
        throw UsageError(os.str());
    }
}

std::string fmt(double v, int prec = 4)
{
    std::ostringstream os;
    os << std::setprecision(prec) << v;
    return os.str();
}

struct SetScore {
    double fitness = 0.0;   ///< mean cost (with the stop penalty)
    double mean_err = 0.0;  ///< mean of the episodes' mean position errors
    int stopped = 0;
    std::vector<EpisodeScore> per;
};

SetScore summarise(const std::vector<EpisodeScore> &s)
{
    SetScore r;
    r.per = s;
    r.fitness = Evaluator::fitness(s);
    for (const auto &e : s) {
        r.mean_err += e.mean_err_m;
        r.stopped += e.stopped_at >= 0;
    }
    r.mean_err /= s.empty() ? 1.0 : static_cast<double>(s.size());
    return r;
}

json set_json(const SetScore &s, const std::vector<Episode> &eps)
{
    json j;
    j["fitness_m"] = s.fitness;
    j["mean_pos_err_m"] = s.mean_err;
    j["stopped"] = s.stopped;
    for (size_t i = 0; i < s.per.size(); ++i) {
        j["episodes"].push_back({{"episode", eps[i].label()},
                                 {"cost_m", s.per[i].cost},
                                 {"mean_pos_err_m", s.per[i].mean_err_m},
                                 {"stopped_at", s.per[i].stopped_at},
                                 {"samples", s.per[i].samples}});
    }
    return j;
}

json weights_json(const Weights &w)
{
    json j;
    for (int i = 0; i < kNW; ++i) {
        j[weight_field(i)] = w[static_cast<size_t>(i)];
    }
    return j;
}

// The [slam] section with every key (app/slam_params_ini.h): coslam-robot's
// and coslam-replay's loader read it back bit for bit (%.17g).
void write_slam_ini(std::ostream &out, const slam_params_t &p)
{
    out << "[slam]\n";
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        const slam_params_ini_key_t *k = slam_params_ini_key(i);
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.17g", slam_params_ini_get(&p, k));
        out << k->name << " = " << buf << "\n";
    }
}

struct MapDataScore {
    bool valid = false;
    double fit_rmse_m = 0.0;
    double spurious = 0.0;
    double missed = 0.0;
    int robots = 0;
};

// A held-out dataset without robot truth (MRCLAM Dataset 1): every robot,
// merging as configured, maps scored after the best rigid fit.
MapDataScore score_map_data(const coslam::replay::Dataset &ds, ReplayConfig cfg, const Weights &w)
{
    slam_noise_from_array(&cfg.slam.noise, w.data());
    coslam::replay::ReplayOptions opt;
    opt.record_history = false;
    const auto rr = coslam::replay::run_replay(ds, cfg, opt);
    MapDataScore s;
    for (const auto &r : rr.robots) {
        if (r.final_score.fit.valid) {
            s.fit_rmse_m += r.final_score.fit.rmse_m;
            s.spurious += r.final_score.fit.n_spurious;
            s.missed += r.final_score.fit.n_missed;
            s.robots++;
        }
    }
    if (s.robots > 0) {
        s.valid = true;
        s.fit_rmse_m /= s.robots;
        s.spurious /= s.robots;
        s.missed /= s.robots;
    }
    return s;
}

int run(int argc, char **argv)
{
    const int rank = mpi_rank();
    CLI::App app{"coslam-calibrate: the paper's eight noise weights (eq. 6) by an Evolution Strategy "
                 "(docs/calibration.md)"};
    std::vector<std::string> config_files;
    std::string source = "synth", world = "paper", filter = "ekf", train_seeds = "1-4",
                test_seeds = "101-104", data_dir = coslam::cli::data_dir(COSLAM_DATA_DIR) + "/mrclam/MRCLAM_Dataset6",
                map_data_dir,
                optimiser = "cmaes", out_dir = "out/calibrate", fixed;
    std::vector<int> train_robots{1, 2, 3}, test_robots{4, 5};
    std::string filter_seeds = "1";
    int particles = 100, lambda = 0, repeats = 1;
    long evals = 300;
    double sigma0 = 0.3, factor = 16.0, stop_error = NAN, penalty = 2.0, duration = 0.0;
    uint64_t seed = 1;
    int jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    bool compare = false, quiet = false, profile = false;
    std::string sweep_particles, sweep_filters, figures_ini;
    double select_margin = 0.05, select_z = 2.0;
    uint64_t figure_seed = 0;
    int map_every = 10;

    app.add_option("--source", source, "episodes: synth (simulated worlds) | mrclam (dataset robots, each alone)")
        ->check(CLI::IsMember({"synth", "mrclam"}));
    app.add_option("-c,--config", config_files,
                   "start parameters, applied in order: INI in coslam-replay's format ([slam] keys as coslam-robot reads them); "
                   "default: slam_params_default (synth) or coslam-replay's defaults (mrclam)");
    app.add_option("--world", world,
                   "synthetic world (host/synth/eval_worlds.h): paper | loop, 4 marker classes; paper-unique | "
                   "loop-unique: unique markers (known association)")
        ->check(CLI::IsMember({"paper", "loop", "paper-unique", "loop-unique"}));
    app.add_option("-f,--filter", filter, "filter of the synthetic episodes: ekf | fs1 | fs2 (refused with mrclam: [filter] type of -c)")
        ->check(CLI::IsMember({"ekf", "fs1", "fs2"}));
    app.add_option("-p,--particles", particles, "Fast-SLAM particles (synth; refused with mrclam: [filter] particles of -c)")->check(CLI::Range(1, 1000));
    app.add_option("--train-seeds", train_seeds, "synthetic training world seeds, e.g. 1-4 or 1,2,7");
    app.add_option("--test-seeds", test_seeds, "held-out synthetic world seeds (must not overlap the training ones)");
    app.add_option("--data", data_dir, "MRCLAM dataset folder (mrclam); default $COSLAM_DATA_DIR/mrclam/MRCLAM_Dataset6, "
                                     "the build's data folder when the variable is unset")
        ->capture_default_str();
    app.add_option("--train-robots", train_robots, "MRCLAM training robots")->delimiter(',')->check(CLI::Range(1, 255));
    app.add_option("--test-robots", test_robots, "MRCLAM held-out robots")->delimiter(',')->check(CLI::Range(1, 255));
    app.add_option("--filter-seeds", filter_seeds, "MRCLAM filter seeds per robot (Fast-SLAM particle noise), e.g. 1-3");
    app.add_option("--duration", duration, "MRCLAM: replay only the first DURATION s (0: all)");
    app.add_option("--map-data", map_data_dir,
                   "held-out dataset without robot truth (e.g. MRCLAM_Dataset1): all robots, maps scored after a rigid fit");
    app.add_option("--optimiser", optimiser, "cmaes | esch (NLopt GN_ESCH) | isres (NLopt GN_ISRES)")
        ->check(CLI::IsMember({"cmaes", "esch", "isres"}));
    app.add_option("--evals", evals, "budget: candidate evaluations (each runs every training episode)");
    app.add_option("--lambda", lambda, "population per generation (0: 4 + floor(3 ln n))");
    app.add_option("--sigma0", sigma0, "CMA-ES initial step in search coordinates (1 = a factor of --factor)");
    app.add_option("--factor", factor, "search box: each weight in [start / F, start * F]");
    app.add_option("--fixed", fixed, "weights held at their start, e.g. w5,w6");
    app.add_option("--stop-error", stop_error, "early stop when the position error passes this [m] (default synth 1, mrclam 3)");
    app.add_option("--penalty", penalty, "after an early stop every remaining sample counts PENALTY x stop-error");
    app.add_option("--seed", seed, "optimiser seed");
    app.add_option("-j,--jobs", jobs, "threads per process");
    app.add_flag("--compare", compare, "run cmaes, esch and isres on the same budget and report side by side");
    app.add_flag("--profile", profile,
                 "no search: fitness on the training episodes with each weight alone scaled by 1/4, 1/2, 1, 2, 4 "
                 "(identifiability)");
    app.add_option("--sweep-particles", sweep_particles,
                   "no search: run the held-out seeds (--test-seeds) with the start weights (-c) for each Fast-SLAM "
                   "particle count, e.g. 5,10,20,50,100,200,500, and select a count (paper Fig. 10; sweep.csv/json/txt)");
    app.add_option("--sweep-filters", sweep_filters, "--sweep-particles: fs1, fs2 or fs1,fs2 (default: -f if fs1/fs2, else both)");
    app.add_option("--select-margin", select_margin,
                   "--sweep-particles: a count is chosen when it is at most this fraction worse than the best");
    app.add_option("--select-z", select_z, "--sweep-particles: ... with this many standard errors of the paired difference");
    app.add_option("--figures", figures_ini,
                   "no search: paper Figs. 4 and 5, the held-out seeds traced with the start weights (hand-tuned) and "
                   "with those of this INI (e.g. calibrated.ini); figures_*.csv, figures.json");
    app.add_option("--figure-seed", figure_seed, "--figures: the held-out seed whose paths and maps are drawn (default: the first)");
    app.add_option("--map-every", map_every, "--figures: score the map every this many steps")->check(CLI::Range(1, 100000));
    app.add_option("--repeats", repeats, "--compare: optimiser seeds seed..seed+R-1");
    app.add_option("-o,--out", out_dir, "output folder (report.txt, report.json, calibrated.ini)");
    app.add_flag("-q,--quiet", quiet, "no progress lines");
    app.footer(mpi_enabled() ? "Built with MPI: mpirun -np K coslam-calibrate ... splits the episodes over K ranks."
                             : "Built without MPI (libopenmpi-dev missing at build time): threads only.");
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError &e) {
        if (rank == 0 || e.get_exit_code() != 0) {
            const int rc = app.exit(e);
            return rc == 0 ? 0 : 2;
        }
        return e.get_exit_code() == 0 ? 0 : 2;
    }

    if (rank == 0) {
        std::cerr << coslam::profile_line("coslam-calibrate") << "\n";
    }

    // ---- validation (every rank, same result)
    if (evals < 1 || evals > 10000000) {
        throw UsageError("--evals: " + std::to_string(evals) + " is outside [1, 1e7]");
    }
    if (lambda != 0 && (lambda < 4 || lambda > 10000)) {
        throw UsageError("--lambda: " + std::to_string(lambda) + " must be 0 (default) or in [4, 10000]");
    }
    require_finite_range(sigma0, 0.0, 2.0, true, "--sigma0");
    require_finite_range(factor, 1.0, 1e6, true, "--factor");
    require_finite_range(penalty, 1.0, 1e3, false, "--penalty");
    require_finite_range(duration, 0.0, 1e6, false, "--duration");
    if (jobs < 1 || jobs > 1024) {
        throw UsageError("--jobs: " + std::to_string(jobs) + " is outside [1, 1024]");
    }
    if (repeats < 1 || repeats > 100) {
        throw UsageError("--repeats: " + std::to_string(repeats) + " is outside [1, 100]");
    }
    if (std::isnan(stop_error) && app.count("--stop-error") == 0) {
        stop_error = source == "synth" ? 1.0 : 3.0;
    }
    require_finite_range(stop_error, 0.0, 1e6, true, "--stop-error");
    std::array<bool, kNW> searched;
    searched.fill(true);
    if (!fixed.empty()) {
        std::stringstream ss(fixed);
        std::string it;
        while (std::getline(ss, it, ',')) {
            bool ok = false;
            for (int i = 0; i < kNW; ++i) {
                if (it == weight_name(i) || it == weight_field(i)) {
                    searched[static_cast<size_t>(i)] = false;
                    ok = true;
                }
            }
            if (!ok) {
                throw UsageError("--fixed: unknown weight '" + it + "' (w1..w8 or the slam_params_t field name)");
            }
        }
    }

    // options of the other source would be ignored: refused
    {
        // -f/-p: an MRCLAM episode's filter and particles are the replay
        // configuration's ([filter] type, particles, [robotN] filter), the
        // one written to calibrated_replay.ini: set them with -c
        const char *const synth_only[] = {"--train-seeds", "--test-seeds", "--world", "--filter", "--particles"};
        const char *const mrclam_only[] = {"--data", "--train-robots", "--test-robots", "--filter-seeds", "--duration"};
        for (const char *o : source == "synth" ? std::vector<const char *>(std::begin(mrclam_only), std::end(mrclam_only))
                                               : std::vector<const char *>(std::begin(synth_only), std::end(synth_only))) {
            if (app.count(o) > 0) {
                const std::string name(o);
                const bool filter_opt = name == "--filter" || name == "--particles";
                throw UsageError(std::string(o) + " does not apply to --source " + source + " (it would be ignored)" +
                                 (filter_opt ? "; the replay's filter and particles come from the configuration: "
                                               "[filter] type = ekf | fastslam1 | fastslam2 and [filter] particles = N "
                                               "in a -c INI"
                                             : ""));
            }
        }
    }

    // ---- start parameters and episodes
    EpisodeContext ctx;
    ctx.stop_error_m = stop_error;
    ctx.penalty_factor = penalty;
    ctx.duration_s = duration;
    ReplayConfig cfg = coslam::replay::replay_config_default();
    if (source == "synth") {
        cfg.slam = slam_params_default();
    }
    for (const auto &f : config_files) {
        coslam::replay::replay_config_load(cfg, f);
    }
    coslam::replay::replay_config_validate(cfg);
    std::vector<Episode> train, test;
    std::shared_ptr<coslam::replay::Dataset> map_ds;
    if (source == "synth") {
        ctx.synth_base = cfg.slam;
        ctx.synth_particles = particles;
        eval_filter_parse(filter.c_str(), &ctx.synth_filter);
        eval_world_t wd;
        const bool unique = world.size() > 7 && world.compare(world.size() - 7, 7, "-unique") == 0;
        eval_world_parse(unique ? world.substr(0, world.size() - 7).c_str() : world.c_str(), &wd);
        const auto trs = parse_seed_list(train_seeds, "--train-seeds");
        const auto tes = parse_seed_list(test_seeds, "--test-seeds");
        for (uint64_t s : trs) {
            if (std::find(tes.begin(), tes.end(), s) != tes.end()) {
                throw UsageError("--test-seeds: seed " + std::to_string(s) + " is also a training seed");
            }
            train.push_back({Episode::Synth, wd, s, 0, unique});
        }
        for (uint64_t s : tes) {
            test.push_back({Episode::Synth, wd, s, 0, unique});
        }
    } else {
        const auto fss = parse_seed_list(filter_seeds, "--filter-seeds");
        for (int r : train_robots) {
            if (std::find(test_robots.begin(), test_robots.end(), r) != test_robots.end()) {
                throw UsageError("--test-robots: robot " + std::to_string(r) + " is also a training robot");
            }
        }
        auto ds = std::make_shared<coslam::replay::Dataset>(coslam::replay::load_dataset(data_dir));
        // the fitness is the position error against the robot's ground
        // truth: a robot without it would score nothing (Dataset 1 has no
        // robot truth; its maps are scored by --map-data)
        for (const std::vector<int> *rs : {&train_robots, &test_robots}) {
            for (int r : *rs) {
                const coslam::replay::RobotLog *rl = ds->robot(r);
                if (rl == nullptr) {
                    throw UsageError("--data " + data_dir + ": robot " + std::to_string(r) + " is not in the dataset");
                }
                if (rl->truth.empty()) {
                    throw UsageError("--data " + data_dir + ": robot " + std::to_string(r) +
                                     " has no ground truth (Dataset 1: use --map-data)");
                }
            }
        }
        for (int r : train_robots) {
            for (uint64_t s : fss) {
                train.push_back({Episode::Mrclam, EVAL_WORLD_PAPER, s, r});
            }
        }
        for (int r : test_robots) {
            for (uint64_t s : fss) {
                test.push_back({Episode::Mrclam, EVAL_WORLD_PAPER, s, r});
            }
        }
        ctx.dataset = ds;
        ctx.replay_cfg = cfg;
    }
    if (!map_data_dir.empty()) {
        map_ds = std::make_shared<coslam::replay::Dataset>(coslam::replay::load_dataset(map_data_dir));
    }
    Weights w0;
    slam_noise_to_array(&cfg.slam.noise, w0.data());
    const SearchSpace space = make_space(w0, factor, searched);
    const long population =
        lambda > 0 ? lambda : 4 + static_cast<long>(std::floor(3.0 * std::log(std::max(1, space.dim()))));
    if (!profile && evals < population + 1) {
        throw UsageError("--evals: " + std::to_string(evals) + " is less than the start and one generation (1 + " +
                         std::to_string(population) + " candidates)");
    }
    const Evaluator ev(ctx, jobs);

    if (!sweep_particles.empty() || !figures_ini.empty()) {
        if (source != "synth") {
            throw UsageError("--sweep-particles and --figures run synthetic episodes (--source synth)");
        }
        if (!sweep_particles.empty() && !figures_ini.empty()) {
            throw UsageError("--sweep-particles and --figures: one at a time");
        }
    }
    if (!sweep_particles.empty()) {
        require_finite_range(select_margin, 0.0, 10.0, false, "--select-margin");
        require_finite_range(select_z, 0.0, 10.0, false, "--select-z");
        SweepOptions so;
        for (uint64_t n : parse_seed_list(sweep_particles, "--sweep-particles")) {
            if (n < 1 || n > COSLAM_MAX_PARTICLES) {
                throw UsageError("--sweep-particles: " + std::to_string(n) + " is outside [1, " +
                                 std::to_string(COSLAM_MAX_PARTICLES) + "]");
            }
            so.counts.push_back(static_cast<int>(n));
        }
        std::sort(so.counts.begin(), so.counts.end());
        so.counts.erase(std::unique(so.counts.begin(), so.counts.end()), so.counts.end());
        if (sweep_filters.empty()) {
            sweep_filters = filter == "ekf" ? "fs1,fs2" : filter;
        }
        std::stringstream ss(sweep_filters);
        std::string it;
        while (std::getline(ss, it, ',')) {
            run_filter_t f;
            if ((it != "fs1" && it != "fs2") || eval_filter_parse(it.c_str(), &f) != 0) {
                throw UsageError("--sweep-filters: '" + it + "' is not fs1 or fs2");
            }
            so.filters.push_back(f);
        }
        so.margin = select_margin;
        so.z = select_z;
        so.out_dir = out_dir;
        if (rank == 0) {
            std::filesystem::create_directories(out_dir);
            std::cout << "particle sweep on " << test.size() << " held-out episodes, counts " << sweep_particles
                      << ", filters " << sweep_filters << "\n";
        }
        run_particle_sweep(ctx, test, w0, jobs, so);
        return 0;
    }
    if (!figures_ini.empty()) {
        ReplayConfig cal = cfg;
        coslam::replay::replay_config_load(cal, figures_ini);
        coslam::replay::replay_config_validate(cal);
        Weights w1;
        slam_noise_to_array(&cal.slam.noise, w1.data());
        if (app.count("--figure-seed") == 0) {
            figure_seed = test.front().seed;
        } else if (std::none_of(test.begin(), test.end(), [&](const Episode &e) { return e.seed == figure_seed; })) {
            throw UsageError("--figure-seed: " + std::to_string(figure_seed) + " is not one of --test-seeds");
        }
        if (rank == 0) {
            std::filesystem::create_directories(out_dir);
            run_figures(ctx, test, w0, w1, figure_seed, map_every, jobs, out_dir);
        }
        return 0;
    }

    if (rank == 0) {
        std::filesystem::create_directories(out_dir);
        std::cout << "coslam-calibrate: " << source << ", " << train.size() << " training / " << test.size()
                  << " held-out episodes, " << space.dim() << " weights searched in [start/" << factor << ", start*"
                  << factor << "], " << jobs << " thread(s) x " << mpi_size() << " process(es)"
                  << (mpi_enabled() ? "" : " (built without MPI)") << "\n";
    }
    const auto t0 = std::chrono::steady_clock::now();

    if (profile) {
        // one batch: the start, then each weight alone scaled
        const double scales[] = {0.25, 0.5, 2.0, 4.0};
        std::vector<Weights> cands{w0};
        for (int i = 0; i < kNW; ++i) {
            for (double sc : scales) {
                Weights w = w0;
                const size_t u = static_cast<size_t>(i);
                w[u] = (w0[u] > 0.0 ? w0[u] : zero_start_reference(i)) * sc;
                cands.push_back(w);
            }
        }
        const auto sc = ev.evaluate(cands, train);
        if (rank == 0) {
            json j;
            std::ostringstream os;
            os << "fitness profile on the training episodes (start " << fmt(Evaluator::fitness(sc[0]), 5)
               << " m; a weight starting at 0 is scaled from its zero-start reference)\n"
               << "weight  x1/4      x1/2      x2        x4\n";
            for (int i = 0; i < kNW; ++i) {
                os << std::left << std::setw(8) << weight_name(i);
                for (size_t k = 0; k < 4; ++k) {
                    const double f = Evaluator::fitness(sc[1 + 4 * static_cast<size_t>(i) + k]);
                    os << std::setw(10) << fmt(f, 5);
                    j[weight_field(i)].push_back({{"scale", scales[k]}, {"fitness_m", f}});
                }
                os << "\n";
            }
            j["start_fitness_m"] = Evaluator::fitness(sc[0]);
            std::cout << os.str();
            write_text_file(out_dir + "/profile.json", j.dump(2) + "\n");
            write_text_file(out_dir + "/profile.txt", os.str());
        }
        return 0;
    }

    std::vector<Optimiser> opts;
    if (compare) {
        opts = {Optimiser::Cmaes, Optimiser::Esch, Optimiser::Isres};
    } else {
        Optimiser o;
        optimiser_parse(optimiser, o);
        opts = {o};
    }
    json comp = json::array();
    SearchResult final_res;
    double best_overall = INFINITY;
    std::ostringstream comp_txt;
    for (Optimiser o : opts) {
        for (int rep = 0; rep < (compare ? repeats : 1); ++rep) {
            SearchOptions so;
            so.optimiser = o;
            so.max_evals = evals;
            so.lambda = lambda;
            so.sigma0 = sigma0;
            so.seed = seed + static_cast<uint64_t>(rep);
            so.on_generation = [&](const GenerationLog &g) {
                if (rank == 0 && !quiet) {
                    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
                    std::printf("[%s] gen %3d  evals %5ld  best %.5f  mean %.5f  best-ever %.5f  (%.1f s)\n",
                                optimiser_name(o), g.generation, g.evals, g.best, g.mean, g.best_ever, el);
                    (void)stdout_check_flush(); // a failure's reason kept for main's check
                }
            };
            const auto ts = std::chrono::steady_clock::now();
            SearchResult r = run_search(space, ev, train, so);
            const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - ts).count();
            if (compare) {
                const SetScore te = summarise(ev.evaluate({r.best}, test)[0]);
                comp.push_back({{"optimiser", optimiser_name(o)},
                                {"seed", so.seed},
                                {"evals", r.evals},
                                {"train_fitness_m", r.best_fitness},
                                {"test_fitness_m", te.fitness},
                                {"wall_s", wall},
                                {"weights", weights_json(r.best)}});
                comp_txt << std::left << std::setw(7) << optimiser_name(o) << " seed " << so.seed << "  evals "
                         << r.evals << "  train " << fmt(r.best_fitness, 5) << "  held-out " << fmt(te.fitness, 5)
                         << "  wall " << fmt(wall, 3) << " s\n";
            }
            if (r.best_fitness < best_overall) {
                best_overall = r.best_fitness;
                final_res = r;
                optimiser = optimiser_name(o);
            }
        }
    }
    const double search_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    // ---- held-out evaluation: start against result, training and test episodes
    const auto tr_sc = ev.evaluate({w0, final_res.best}, train);
    const auto te_sc = ev.evaluate({w0, final_res.best}, test);
    const SetScore tr0 = summarise(tr_sc[0]), tr1 = summarise(tr_sc[1]);
    const SetScore te0 = summarise(te_sc[0]), te1 = summarise(te_sc[1]);
    MapDataScore md0, md1;
    if (map_ds && rank == 0) {
        md0 = score_map_data(*map_ds, cfg, w0);
        md1 = score_map_data(*map_ds, cfg, final_res.best);
    }
    const double total_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (rank != 0) {
        return 0;
    }

    std::ostringstream rep;
    rep << "coslam-calibrate report\n"
        << "source " << source << (source == "synth" ? " (world " + world + ", filter " + filter + ")" : " (" + data_dir + ")")
        << ", optimiser " << optimiser << (compare ? " (best of --compare)" : "") << ", budget " << evals
        << " evaluations, seed " << seed << "\n"
        << "processes " << mpi_size() << ", threads per process " << jobs << ", search wall " << fmt(search_wall, 4)
        << " s, total wall " << fmt(total_wall, 4) << " s, episodes run " << ev.episodes_run() << "\n"
        << "stop: " << final_res.stop_reason << ", " << final_res.evals << " evaluations\n\n";
    if (compare) {
        rep << "optimiser comparison (same budget, same start):\n" << comp_txt.str() << "\n";
    }
    rep << "weight  field                       start         result        ratio   searched\n";
    for (int i = 0; i < kNW; ++i) {
        const size_t u = static_cast<size_t>(i);
        char line[200];
        std::snprintf(line, sizeof line, "%-7s %-27s %-13.6g %-13.6g %-7s %s\n", weight_name(i), weight_field(i),
                      w0[u], final_res.best[u], w0[u] > 0 ? fmt(final_res.best[u] / w0[u], 3).c_str() : "-",
                      space.searched[u] ? "yes" : "no (fixed)");
        rep << line;
    }
    rep << "\n                 fitness [m] start -> result   mean pos error [m] start -> result   stopped\n";
    auto row = [&](const char *name, const SetScore &a, const SetScore &b, size_t n) {
        char line[200];
        std::snprintf(line, sizeof line, "%-16s %.5f -> %.5f           %.5f -> %.5f                %d -> %d of %zu\n",
                      name, a.fitness, b.fitness, a.mean_err, b.mean_err, a.stopped, b.stopped, n);
        rep << line;
    };
    row("training", tr0, tr1, train.size());
    row("held-out", te0, te1, test.size());
    if (md0.valid) {
        rep << "held-out map data " << map_data_dir << " (all robots, rigid fit): landmark RMSE "
            << fmt(md0.fit_rmse_m) << " -> " << fmt(md1.fit_rmse_m) << " m, spurious/robot " << fmt(md0.spurious)
            << " -> " << fmt(md1.spurious) << ", missed/robot " << fmt(md0.missed) << " -> " << fmt(md1.missed)
            << "\n";
    }
    std::cout << "\n" << rep.str();

    json j;
    j["profile"] = coslam::profile_json(); // the build's capacities
    j["source"] = source;
    j["world"] = world;
    j["filter"] = source == "synth" ? filter : coslam::replay::filter_kind_name(cfg.filter.type);
    j["optimiser"] = optimiser;
    j["evals_budget"] = evals;
    j["evals"] = final_res.evals;
    j["seed"] = seed;
    j["processes"] = mpi_size();
    j["threads"] = jobs;
    j["search_wall_s"] = search_wall;
    j["total_wall_s"] = total_wall;
    j["factor"] = factor;
    j["stop_error_m"] = stop_error;
    j["penalty_factor"] = penalty;
    j["stop_reason"] = final_res.stop_reason;
    j["start"] = weights_json(w0);
    j["result"] = weights_json(final_res.best);
    j["best_fitness_m"] = final_res.best_fitness;
    for (int i = 0; i < kNW; ++i) {
        j["searched"][weight_field(i)] = static_cast<bool>(space.searched[static_cast<size_t>(i)]);
    }
    j["train"] = {{"start", set_json(tr0, train)}, {"result", set_json(tr1, train)}};
    j["test"] = {{"start", set_json(te0, test)}, {"result", set_json(te1, test)}};
    if (md0.valid) {
        j["map_data"] = {{"dir", map_data_dir},
                         {"start", {{"fit_rmse_m", md0.fit_rmse_m}, {"spurious", md0.spurious}, {"missed", md0.missed}}},
                         {"result", {{"fit_rmse_m", md1.fit_rmse_m}, {"spurious", md1.spurious}, {"missed", md1.missed}}}};
    }
    for (const auto &g : final_res.history) {
        j["history"].push_back({{"generation", g.generation}, {"evals", g.evals}, {"best", g.best}, {"mean", g.mean},
                                {"best_ever", g.best_ever}});
    }
    if (compare) {
        j["compare"] = comp;
    }
    write_text_file(out_dir + "/report.json", j.dump(2) + "\n");
    write_text_file(out_dir + "/report.txt", rep.str());

    ReplayConfig out_cfg = cfg;
    slam_noise_from_array(&out_cfg.slam.noise, final_res.best.data());
    {
        std::ofstream ini(out_dir + "/calibrated.ini");
        ini << "; coslam-calibrate result (" << optimiser << ", " << source << "; report.txt). The [slam]\n"
            << "; section as coslam-robot and coslam-replay read it (app/slam_params_ini.h).\n";
        write_slam_ini(ini, out_cfg.slam);
        close_checked(ini, out_dir + "/calibrated.ini");
    }
    if (source == "mrclam") {
        std::ofstream ini(out_dir + "/calibrated_replay.ini");
        coslam::replay::replay_config_write(out_cfg, ini);
        close_checked(ini, out_dir + "/calibrated_replay.ini");
    }
    std::cout << "wrote " << out_dir << "/report.txt, report.json, calibrated.ini"
              << (source == "mrclam" ? ", calibrated_replay.ini" : "") << "\n";
    return 0;
}

} // namespace

int main(int argc, char **argv)
{
#ifdef COSLAM_HAVE_MPI
    int provided = 0;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
#endif
    int rc = 0;
    try {
        rc = run(argc, argv);
    } catch (const coslam::replay::ReplayError &e) {
        // an unusable request: configuration file, dataset, robot ids
        if (mpi_rank() == 0) {
            std::cerr << "coslam-calibrate: " << e.what() << "\n";
        }
        rc = 2;
    } catch (const UsageError &e) {
        if (mpi_rank() == 0) {
            std::cerr << "coslam-calibrate: " << e.what() << "\n";
        }
        rc = 2;
    } catch (const std::exception &e) {
        std::cerr << "coslam-calibrate: error: " << e.what() << "\n";
        rc = 1;
#ifdef COSLAM_HAVE_MPI
        if (mpi_size() > 1) {
            MPI_Abort(MPI_COMM_WORLD, 1);
        }
#endif
    }
    // standard output checked (stdout_check.h): the progress lines and the
    // report lost to a full disk or a closed pipe are exit 1 (2 stays).
    // Before MPI_Finalize, whose flush would fail first and leave no reason.
    rc = coslam::cli::stdout_exit("coslam-calibrate", rc);
#ifdef COSLAM_HAVE_MPI
    MPI_Finalize();
#endif
    return rc;
}
