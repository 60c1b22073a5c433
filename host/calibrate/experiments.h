// host/calibrate/experiments.h - the paper's experiments around the
// calibration (issue 14; docs/calibration.md "Particle count" and
// "Figures 4 and 5"): the particle-count sweep (paper Fig. 10) and the
// hand-tuned against calibrated traces (paper Figs. 4 and 5).
#ifndef COSLAM_CALIBRATE_EXPERIMENTS_H
#define COSLAM_CALIBRATE_EXPERIMENTS_H

#include <string>
#include <vector>

#include "calib.h"

namespace coslam::calibrate {

struct SweepOptions {
    std::vector<int> counts;            ///< ascending, each in [1, COSLAM_MAX_PARTICLES]
    std::vector<run_filter_t> filters;  ///< RUN_FASTSLAM1 and/or RUN_FASTSLAM2
    double margin = 0.05;               ///< select_particle_count
    double z = 2.0;
    std::string out_dir;
};

/// For each filter and count: the episodes with weights w (one
/// EpisodeContext and Evaluator per count: threads and MPI ranks as in the
/// search), then select_particle_count on the episodes' costs. Rank 0
/// writes sweep.csv, sweep.json and sweep.txt into out_dir and prints the
/// table and the chosen count per filter. Collective under MPI.
void run_particle_sweep(const EpisodeContext &base, const std::vector<Episode> &eps, const Weights &w, int jobs,
                        const SweepOptions &opt);

/// Figures 4 and 5: every episode traced with the hand-tuned weights and
/// with the calibrated ones (rank 0 only, `jobs` threads). Writes into
/// out_dir: figures_error.csv (the position and landmark error over time,
/// means over the episodes, every map_every steps), figures_path.csv and
/// figures_map.csv (paths, final maps and the truth of episode
/// `figure_seed`), figures.json (per episode and mean figures).
void run_figures(const EpisodeContext &ctx, const std::vector<Episode> &eps, const Weights &hand,
                 const Weights &calibrated, uint64_t figure_seed, int map_every, int jobs, const std::string &out_dir);

} // namespace coslam::calibrate

#endif
