// host/calibrate/calib.h - the pieces of coslam-calibrate (docs/calibration.md):
// the search space of the paper's eight noise weights (eq. 6), the episodes
// a candidate is scored on, the parallel evaluator (threads, and MPI ranks
// when built with MPI), the three optimisers (CMA-ES, NLopt GN_ESCH,
// NLopt GN_ISRES), the particle-count rule and the traced episode of the
// figures (experiments.h runs those two).
//
// Fitness of a candidate w (paper Sec. 2.3): the mean over its episodes of
// the mean distance between the estimated and the true robot position.
// An episode whose error passes `stop_error_m` is stopped there with a
// penalty: every remaining sample counts as penalty_factor * stop_error_m.
// run_synth and run_replay have no per-step hook to end an episode from
// outside, so the stop is emulated on the recorded path (the figure is
// exactly what a stopped episode would score; only the time is not saved).
#ifndef COSLAM_CALIBRATE_CALIB_H
#define COSLAM_CALIBRATE_CALIB_H

#include "checked_file.hpp"

#include <array>
#include <cstdint>
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "coslam/slam_params.h"
#include "eval_worlds.h"
#include "replay_config.h"
#include "replay_data.h"

namespace coslam::calibrate {

constexpr int kNW = SLAM_NOISE_N_WEIGHTS;
using Weights = std::array<double, kNW>;

/// Names w1..w8 and the slam_params_t field of each.
const char *weight_name(int i);
const char *weight_field(int i);

/// Where a weight that starts at 0 is searched (its log needs a scale):
/// w5 1e-5 m^2/m, w6 1e-4 m^2, w7 1e-4 rad^2, w8 1e-4 m^2 (docs/calibration.md).
double zero_start_reference(int i);

/// Log-space box around the start: weight i in [s_i / F, s_i * F] with
/// s_i = start (or zero_start_reference if the start is 0). Search
/// coordinates y_i in [-1, 1]: w_i = s_i * F^(y_i). Fixed weights keep
/// their start value and are not coordinates.
struct SearchSpace {
    Weights start{};
    Weights centre{};
    double factor = 16.0;
    std::array<bool, kNW> searched{};
    int dim() const;
    Weights to_weights(const std::vector<double> &y) const;
    std::vector<double> to_coords(const Weights &w) const; ///< clamped to [-1, 1]
    std::vector<double> start_coords() const;
};
SearchSpace make_space(const Weights &start, double factor, const std::array<bool, kNW> &searched);

/// One episode: a synthetic world and seed, or one MRCLAM robot alone.
struct Episode {
    enum Kind { Synth, Mrclam } kind = Synth;
    eval_world_t world = EVAL_WORLD_PAPER;
    uint64_t seed = 1;
    int robot = 0;
    /// Synthetic: unique landmark signatures (known association) instead of
    /// the world's 4 classes: the filter maths alone, no association errors.
    bool unique = false;
    std::string label() const;
};

struct EpisodeScore {
    double cost = 0.0;       ///< fitness contribution (mean error with the stop penalty) [m]
    double mean_err_m = 0.0; ///< mean position error over the whole episode [m]
    int stopped_at = -1;     ///< sample index of the early stop, -1: ran to the end
    int samples = 0;
    double cpu_s = 0.0;      ///< CPU time of the episode on its thread [s] (measured, not deterministic)
};

/// Everything an episode needs besides the candidate weights.
struct EpisodeContext {
    // synthetic
    run_filter_t synth_filter = RUN_EKFSLAM;
    int synth_particles = 100;
    slam_params_t synth_base{};         ///< filter params; the 8 weights are replaced by the candidate
    // MRCLAM
    std::shared_ptr<const replay::Dataset> dataset;
    replay::ReplayConfig replay_cfg;    ///< slam.noise's 8 weights replaced by the candidate
    double duration_s = 0.0;            ///< > 0: replay only that long
    // early stop
    double stop_error_m = 1.0;
    double penalty_factor = 2.0;
};

/// Cost of a path of position errors with the emulated early stop.
EpisodeScore score_errors(const std::vector<double> &err_m, double stop_error_m, double penalty_factor);

/// Run one episode with weights w. Thread-safe (no shared mutable state).
EpisodeScore run_episode(const EpisodeContext &ctx, const Episode &ep, const Weights &w);

/// Runs task(k) for every k in [0, n) once, on `threads` threads (this
/// one included), in no fixed order: each task must write only its own
/// output. The first exception stops the tasks not yet started and is
/// rethrown as std::runtime_error with its message.
void parallel_for(size_t n, int threads, const std::function<void(size_t)> &task);

/// Evaluates candidates x episodes on threads of this process and, with
/// MPI, across ranks: task t = (candidate, episode) goes to rank t mod size,
/// then to whichever thread of that rank is free; each task writes its own
/// slot and the slots are summed over ranks (every other rank contributes
/// exactly 0.0), so every rank gets bit-identical scores whatever the
/// process and thread counts. Fitness is then averaged in episode order.
class Evaluator {
public:
    Evaluator(const EpisodeContext &ctx, int threads);
    /// scores[c][e]; collective under MPI (every rank must call it, same arguments).
    std::vector<std::vector<EpisodeScore>> evaluate(const std::vector<Weights> &cands,
                                                    const std::vector<Episode> &eps) const;
    static double fitness(const std::vector<EpisodeScore> &s);
    int threads() const { return threads_; }
    long episodes_run() const { return episodes_run_; }

private:
    const EpisodeContext &ctx_;
    int threads_;
    mutable long episodes_run_ = 0;
};

/// Particle-count selection (issue 14 item 2, docs/calibration.md
/// "Particle count"). cost[i][e]: episode e's cost (mean position error
/// with the early-stop penalty) at the i-th count, counts in ascending
/// order, the same episodes (seeds) in the same order for every count.
/// best = the count with the lowest mean cost (the smaller on a tie).
/// Episodes are paired by seed: d_e = cost[i][e] - cost[best][e], with
/// mean dbar and standard error se = sd(d) / sqrt(n) (sd with n - 1; 0 for
/// n = 1). A count passes when dbar + z * se <= margin * mean(best): with
/// about 97.7 % one-sided confidence (z = 2) it is at most `margin` worse
/// than the best (a non-inferiority test). chosen = the smallest count
/// that passes; the best always passes (d = 0), so there is always one.
struct CountStats {
    double mean = 0.0;      ///< mean cost over the episodes [m]
    double se = 0.0;        ///< its standard error over the episodes [m]
    double diff_mean = 0.0; ///< dbar against the best [m]
    double diff_se = 0.0;   ///< se of the paired difference [m]
    double upper = 0.0;     ///< dbar + z * se [m]
    bool passes = false;
};
struct ParticleSelection {
    size_t best = 0;
    size_t chosen = 0;
    double bound_m = 0.0;   ///< margin * mean(best)
    std::vector<CountStats> counts;
};
/// Throws std::invalid_argument for no counts, no episodes, ragged rows,
/// a non-finite cost, margin < 0 or z < 0.
ParticleSelection select_particle_count(const std::vector<std::vector<double>> &cost, double margin, double z);

/// One synthetic episode with its traces, for the paper's Fig. 4 and 5
/// (coslam-calibrate --figures): the position error every step, the map
/// error every map_every steps (run_trace_t), the final map and the truth.
struct SynthTrace {
    std::vector<double> t_s, err_m;
    std::vector<pose2_t> est, truth;
    std::vector<double> map_t_s, map_rmse_m; ///< NaN: no landmark matched yet
    std::vector<int> map_matched, map_spurious;
    std::vector<point2_t> map_est;           ///< final exported landmark means
    std::vector<point2_t> lm_truth;          ///< the world's landmarks
    double final_rmse_m = 0.0;               ///< final map (run_result_t.map)
    int final_matched = 0, final_spurious = 0, final_missed = 0;
};
SynthTrace run_synth_episode_traced(const EpisodeContext &ctx, const Episode &ep, const Weights &w, int map_every);

/// MPI helpers (no-ops without MPI).
int mpi_rank();
int mpi_size();
bool mpi_enabled();

enum class Optimiser { Cmaes, Esch, Isres };
const char *optimiser_name(Optimiser o);
bool optimiser_parse(const std::string &s, Optimiser &o);

struct GenerationLog {
    int generation;
    long evals;
    double best;       ///< best fitness this generation
    double mean;       ///< mean fitness this generation
    double best_ever;
};

struct SearchResult {
    Weights best{};
    double best_fitness = 0.0;
    long evals = 0;
    std::vector<GenerationLog> history;
    std::string stop_reason;
};

struct SearchOptions {
    Optimiser optimiser = Optimiser::Cmaes;
    long max_evals = 400; ///< including the start, evaluated first
    int lambda = 0;       ///< population; 0: CMA-ES default 4 + floor(3 ln n)
    double sigma0 = 0.3;  ///< CMA-ES initial step in search coordinates ([-1, 1] per weight)
    uint64_t seed = 1;
    bool quiet = false;
    /// Called on every rank after each generation (rank 0 prints).
    std::function<void(const GenerationLog &)> on_generation;
};

SearchResult run_search(const SearchSpace &space, const Evaluator &ev, const std::vector<Episode> &train,
                        const SearchOptions &opt);

/// Output files checked after writing (host/cli/checked_file.hpp).
using coslam::cli::close_checked;
using coslam::cli::write_text_file;

} // namespace coslam::calibrate

#endif
