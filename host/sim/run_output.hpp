// host/sim/run_output.hpp - the files a simulated run leaves in out/<run>/
// (../shared/DESIGN.md "Outputs of a run"; details in docs/sim.md) and the
// one-screen summary coslam-sim prints.
//
// Frames: every file is in the WORLD frame, so that both robots and the
// true landmarks plot together: robot k's estimates (in its own map frame,
// which is its start pose) are moved by its true start pose. That move is
// for display and evaluation only; the robots never know it.
#ifndef COSLAM_HOST_SIM_RUN_OUTPUT_HPP
#define COSLAM_HOST_SIM_RUN_OUTPUT_HPP

#include <nlohmann/json.hpp>
#include <string>

#include "sim/world/simulation.hpp"

namespace coslam::sim {

/// Write every output file of the run into dir (created if missing).
/// Throws std::runtime_error if a file cannot be written.
void write_run_outputs(const Simulation &sim, const std::string &dir);

/// metrics.json content.
nlohmann::json run_metrics(const Simulation &sim);

/// One event of metrics.json's "merges": the check's figures ("check") for
/// every merge and for the refusals the check made (maps disagree,
/// receiver lost), the transform and the maps around it for merges.
nlohmann::json merge_json(const MergeRecord &m);

/// One merge of the summary, without a newline: "  merge t=52.3 s: robot0 <-
/// robot1 (16 landmarks: 7.0 fused, 9.0 added (per particle, mean of 100);
/// not added: ...), transform error ..., sightings 100 ms apart (robot1's
/// first)". particles: the receiver's (0 for EKF-SLAM: its counts are
/// landmarks); the sightings' time apart is unsigned, the first one named.
std::string merge_summary_line(const MergeRecord &m, const std::string &robot, const std::string &peer,
                               int particles);

/// The one-screen summary (errors before and after the merge, collisions,
/// speed), without a trailing newline.
std::string run_summary(const Simulation &sim, const std::string &out_dir);

}  // namespace coslam::sim

#endif
