// host/replay/replay_filter.cpp - the core filters behind one interface.
#include "replay_filter.h"

#include <new>

#include "replay_data.h"

namespace coslam::replay {

RobotFilter::RobotFilter(FilterKind kind, const ReplayConfig &cfg, uint8_t core_robot_id, pose2_t pose0,
                         uint64_t seed)
    : kind_(kind), f_(static_cast<slam_filter_t *>(std::calloc(1, sizeof(slam_filter_t))))
{
    if (!f_) {
        throw std::bad_alloc();
    }
    slam_filter_config_t c = slam_filter_config_default();
    c.kind = kind == FilterKind::Ekf         ? SLAM_FILTER_EKF
             : kind == FilterKind::FastSlam1 ? SLAM_FILTER_FASTSLAM1
                                             : SLAM_FILTER_FASTSLAM2;
    c.slam = cfg.slam;
    c.robot_id = core_robot_id;
    c.n_particles = static_cast<uint16_t>(cfg.filter.particles);
    c.seed = seed;
    c.resample_ess_fraction = cfg.filter.ess_fraction;
    c.export_min_weight = cfg.filter.export_min_weight;
    c.closure_drift_ratio = cfg.filter.closure_drift_ratio;
    c.closure_gap = static_cast<uint16_t>(cfg.filter.closure_gap);
    c.closure_ambiguity_ll = cfg.filter.closure_ambiguity_ll;
    c.closure_misses_per_support = cfg.filter.closure_misses_per_support;
    c.closure_chance_max = cfg.filter.closure_chance_max;
    c.closure_unsupported_every = static_cast<uint16_t>(cfg.filter.closure_unsupported_every);
    c.assoc = cfg.filter.assoc;
    c.jcbb_max_nodes = cfg.filter.jcbb_max_nodes;
    c.fej = static_cast<uint8_t>(cfg.filter.fej);
    c.iekf_max_iters = static_cast<uint8_t>(cfg.filter.iekf_max_iters);
    c.nis_inflate = cfg.filter.nis_inflate;
    c.active_spread_madds = cfg.filter.active_spread_madds;
    c.mh_frames = cfg.filter.mh_frames;
    if (slam_filter_init(f_.get(), &c, pose0) != COSLAM_OK) {
        throw ReplayError(std::string(slam_filter_kind_name(c.kind)) + ": the core refused the configuration");
    }
}

RobotFilter::~RobotFilter() = default;

coslam_status_t RobotFilter::predict(odo_increment_t u, double dt_s)
{
    return slam_filter_predict(f_.get(), u, dt_s);
}

coslam_status_t RobotFilter::update(const sighting_t *z, int n)
{
    return slam_filter_update(f_.get(), z, n);
}

void RobotFilter::idle()
{
    slam_filter_idle(f_.get());
}

void RobotFilter::pose(pose2_t *mean, cov3_t *cov) const
{
    slam_filter_pose(f_.get(), mean, cov);
}

coslam_status_t RobotFilter::export_map(map_estimate_t *out)
{
    return slam_filter_export(f_.get(), out);
}

coslam_status_t RobotFilter::export_whole(map_whole_t *out)
{
    return slam_filter_export_whole(f_.get(), out);
}

std::optional<point2_t> RobotFilter::landmark_of_signature(uint8_t sig) const
{
    std::optional<point2_t> best;
    int best_obs = -1;
    if (const ekfslam_t *ekf = ekfslam()) {
        for (uint16_t j = 0; j < ekf->n_lm; ++j) {
            if (ekfslam_landmark_live(ekf, j) && ekf->meta[j].signature == sig && ekf->meta[j].n_obs > best_obs) {
                best_obs = ekf->meta[j].n_obs;
                best = ekfslam_landmark_mean(ekf, j);
            }
        }
        return best;
    }
    const fastslam_t *fs = fastslam();
    const uint16_t k = fastslam_best_particle(fs);
    const fastslam_particle_t &p = fs->particles[k];
    for (uint16_t j = 0; j < p.n_lm; ++j) {
        const landmark_t &lm = *fastslam_particle_lm(fs, k, j);
        if (lm.signature == sig && lm.n_obs > best_obs) {
            best_obs = lm.n_obs;
            best = lm.mean;
        }
    }
    return best;
}

std::map<std::string, long> RobotFilter::counters() const
{
    std::map<std::string, long> m;
    if (const ekfslam_t *ekf = ekfslam()) {
        const ekfslam_counters_t &c = ekf->ctr;
        m["predictions"] = c.predictions;
        m["updates"] = c.updates;
        m["landmarks_added"] = c.landmarks_added;
        m["landmarks_removed"] = c.landmarks_removed;
        m["removals_deferred"] = c.removals_deferred; /* decided in a compressed EKF's local phase */
        m["lm_capacity_drops"] = c.lm_capacity_drops;
        m["sighting_capacity_drops"] = c.sighting_capacity_drops;
        m["export_capacity_drops"] = c.export_capacity_drops;
        m["rejected_sightings"] = c.rejected_sightings;
        m["rejected_controls"] = c.rejected_controls;
        m["numeric_faults"] = c.numeric_faults;
        m["merge_pair_drops"] = c.merge_pair_drops;
        m["jcbb_budget_hits"] = c.jcbb_budget_hits;
        m["jcbb_ambiguous"] = c.jcbb_ambiguous;
        m["jcbb_closures_held"] = c.jcbb_closures_held;
        m["jcbb_closures_nonlinear"] = c.jcbb_closures_nonlinear;
        m["pairs_nonlinear"] = c.pairs_nonlinear;
        m["iekf_updates"] = c.iekf_updates;
        m["iekf_iterations"] = c.iekf_iterations;
        m["nis_inflations"] = c.nis_inflations;
        m["mh_forks"] = c.mh_forks;
        m["mh_reverted"] = c.mh_reverted;
        m["mh_decided_early"] = c.mh_decided_early;
        m["landmarks_in_state"] = ekfslam_n_landmarks(ekf);
        m["merges_in_parts"] = f_->merges_in_parts;
        m["merges_late_partial"] = f_->merges_late_partial;
        m["merges_forced"] = f_->merges_forced;
        m["inputs_held"] = f_->inputs_held;
        m["held_failures"] = f_->held_failures;
        m["holds_forced"] = f_->holds_forced;
    } else {
        const fastslam_counters_t &c = fastslam()->ctr;
        m["predictions"] = c.predictions;
        m["updates"] = c.updates;
        m["resamples"] = c.resamples;
        m["landmarks_added"] = c.landmarks_added;
        m["landmarks_removed"] = c.landmarks_removed;
        m["lm_capacity_drops"] = c.lm_capacity_drops;
        m["sighting_capacity_drops"] = c.sighting_capacity_drops;
        m["export_capacity_drops"] = c.export_capacity_drops;
        m["rejected_sightings"] = c.rejected_sightings;
        m["rejected_controls"] = c.rejected_controls;
        m["numeric_faults"] = c.numeric_faults;
        m["merge_pair_drops"] = c.merge_pair_drops;
        m["closures"] = c.closures;
        m["closure_moves"] = c.closure_moves;
        m["closures_unsupported"] = c.closures_unsupported;
        m["resamples_deferred"] = c.resamples_deferred;
        m["merges_in_parts"] = f_->merges_in_parts;
        m["merges_late_partial"] = f_->merges_late_partial;
        m["checks_waited"] = f_->checks_waited;
        m["sends_in_parts"] = f_->sends_in_parts;
        m["sends_forced"] = f_->sends_forced;
        m["merges_forced"] = f_->merges_forced;
    }
    uint64_t view_pairs = 0, view_misses = 0;
    slam_filter_view_counts(f_.get(), &view_pairs, &view_misses);
    m["view_pairs"] = view_pairs;   // the rate the miss weight stands for (docs/core-slam.md)
    m["view_misses"] = view_misses;
    m["coverage_keyframes"] = f_->coverage.n;
    m["coverage_thinned"] = f_->coverage.thinned;
    return m;
}

} // namespace coslam::replay
