// host/replay/replay_output.h - the run outputs of ../shared/DESIGN.md for a
// replay, written into one folder:
//   robot<k>_path.tum            estimated path, map frame (TUM: t x y z qx qy qz qw)
//   robot<k>_truth_path.tum      true path in the same map frame
//   robot<k>_map.csv             final map (id,x,y,cxx,cxy,cyy,signature,n_obs,src_mask)
//   robot<k>_map_before_merge.csv, robot<k>_map_after_merge.csv
//                                the map right before and after the merge that
//                                added the most landmarks (metrics.json: shown_merge_t_s)
//   robot<k>_truth_map.csv       true landmarks in the map frame (id,x,y)
//   errors.csv                   t,robot,pos_err_m,heading_err_rad,nees (nan: not measured)
//   map_errors.csv               t,robot,n_estimated,n_matched,n_spurious,n_missed,rmse_m
//   merge_events.csv             t,robot,sender,... one row per merge (robot = receiver)
//   metrics.json                 everything above summarised, the configuration,
//                                the input bookkeeping and the timings
#ifndef COSLAM_HOST_REPLAY_OUTPUT_H
#define COSLAM_HOST_REPLAY_OUTPUT_H

#include <iosfwd>
#include <string>

#include "replay_config.h"
#include "replay_data.h"
#include "replay_run.h"

namespace coslam::replay {

struct RunInfo {
    std::string command;   ///< how the run was started (for metrics.json)
    double load_s = 0.0;   ///< time to read the dataset
};

/// Write every output into `dir` (created). Throws ReplayError on I/O errors.
void write_run_outputs(const std::string &dir, const Dataset &ds, const ReplayConfig &cfg, const ReplayOptions &opt,
                       const ReplayResult &res, const RunInfo &info);

/// Human-readable summary (one line per robot, one per merge, the means).
void print_summary(std::ostream &out, const ReplayResult &res, const ReplayOptions &opt);

/// Limits are loud: one line per robot and counter for every input the core
/// refused (rejected_sightings, rejected_controls, numeric_faults) and every
/// capacity hit (lm_/sighting_/export_capacity_drops, with the capacity to
/// raise), and the dataset's skipped records. Returns true when a capacity
/// was hit (coslam-replay then exits with kExitCapacity unless
/// --allow-capacity-limits).
bool report_limits(std::ostream &err, const Dataset &ds, const ReplayResult &res);

/// coslam-replay's exit codes: 0 done; 2 bad input or usage (a data or
/// configuration file, an option, through cli::parse_usage); 3
/// (kExitCapacity) a capacity of the core was hit; 1 (kExitWrite) an output
/// file or standard output could not be written whole (a full disk, a closed
/// pipe: coslam::cli::WriteError, the path and the OS's reason on stderr);
/// 4 (kExitPlot) the figures asked for (no --no-plots) were not drawn, every
/// data output being written whole. When several apply: 1 before 3 before 4
/// (the most serious loss first); 2 stays 2 (nothing was run).
inline constexpr int kExitWrite = 1;
/// Exit code of a run that hit a capacity of the core.
inline constexpr int kExitCapacity = 3;
/// Exit code of a run whose figures could not be drawn (the plot script
/// failed or could not start); its data outputs are complete.
inline constexpr int kExitPlot = 4;

} // namespace coslam::replay

#endif
