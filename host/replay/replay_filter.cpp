// host/replay/replay_filter.cpp - the core filters behind one interface.
#include "replay_filter.h"

#include "replay_data.h"

namespace coslam::replay {

RobotFilter::RobotFilter(FilterKind kind, const ReplayConfig &cfg, uint8_t core_robot_id, pose2_t pose0,
                         uint64_t seed)
    : kind_(kind)
{
    if (kind == FilterKind::Ekf) {
        ekf_ = std::make_unique<ekfslam_t>();
        ekfslam_config_t c = ekfslam_config_default();
        c.slam = cfg.slam;
        c.robot_id = core_robot_id;
        c.assoc = cfg.filter.assoc;
        c.jcbb_max_nodes = cfg.filter.jcbb_max_nodes;
        c.fej = static_cast<uint8_t>(cfg.filter.fej);
        if (ekfslam_init(ekf_.get(), &c, pose0) != COSLAM_OK) {
            throw ReplayError("ekfslam_init refused the configuration");
        }
    } else {
        fs_ = std::make_unique<fastslam_t>();
        fastslam_config_t c = fastslam_config_default();
        c.slam = cfg.slam;
        c.robot_id = core_robot_id;
        c.n_particles = static_cast<uint16_t>(cfg.filter.particles);
        c.proposal = kind == FilterKind::FastSlam2 ? FASTSLAM_PROPOSAL_OPTIMAL : FASTSLAM_PROPOSAL_MOTION;
        c.resample_ess_fraction = cfg.filter.ess_fraction;
        c.export_min_weight = cfg.filter.export_min_weight;
        if (fastslam_init(fs_.get(), &c, pose0, seed) != COSLAM_OK) {
            throw ReplayError("fastslam_init refused the configuration");
        }
    }
}

RobotFilter::~RobotFilter() = default;

coslam_status_t RobotFilter::predict(odo_increment_t u)
{
    return ekf_ ? ekfslam_predict(ekf_.get(), u) : fastslam_predict(fs_.get(), u);
}

coslam_status_t RobotFilter::update(const sighting_t *z, int n)
{
    return ekf_ ? ekfslam_update(ekf_.get(), z, n) : fastslam_update(fs_.get(), z, n);
}

void RobotFilter::pose(pose2_t *mean, cov3_t *cov) const
{
    if (ekf_) {
        ekfslam_pose(ekf_.get(), mean, cov);
    } else {
        fastslam_pose_estimate(fs_.get(), mean, cov);
    }
}

coslam_status_t RobotFilter::export_map(map_estimate_t *out)
{
    return ekf_ ? ekfslam_export(ekf_.get(), out) : fastslam_export(fs_.get(), out);
}

coslam_status_t RobotFilter::merge(const merge_body_map_t &bm, const merge_config_t &cfg, merge_scratch_t &scratch,
                                   merge_stats_t &stats)
{
    return ekf_ ? merge_into_ekfslam(ekf_.get(), &bm, &cfg, &scratch, &stats)
                : merge_into_fastslam(fs_.get(), &bm, &cfg, &scratch, &stats);
}

std::optional<point2_t> RobotFilter::landmark_of_signature(uint8_t sig) const
{
    std::optional<point2_t> best;
    int best_obs = -1;
    if (ekf_) {
        for (uint16_t j = 0; j < ekf_->n_lm; ++j) {
            if (ekf_->meta[j].signature == sig && ekf_->meta[j].n_obs > best_obs) {
                best_obs = ekf_->meta[j].n_obs;
                best = point2_t{ekf_->x[3 + 2 * j], ekf_->x[4 + 2 * j]};
            }
        }
        return best;
    }
    const fastslam_particle_t &p = fs_->particles[fastslam_best_particle(fs_.get())];
    for (uint16_t j = 0; j < p.n_lm; ++j) {
        if (p.lm[j].signature == sig && p.lm[j].n_obs > best_obs) {
            best_obs = p.lm[j].n_obs;
            best = p.lm[j].mean;
        }
    }
    return best;
}

std::map<std::string, long> RobotFilter::counters() const
{
    std::map<std::string, long> m;
    if (ekf_) {
        const ekfslam_counters_t &c = ekf_->ctr;
        m["predictions"] = c.predictions;
        m["updates"] = c.updates;
        m["landmarks_added"] = c.landmarks_added;
        m["landmarks_removed"] = c.landmarks_removed;
        m["lm_capacity_drops"] = c.lm_capacity_drops;
        m["sighting_capacity_drops"] = c.sighting_capacity_drops;
        m["export_capacity_drops"] = c.export_capacity_drops;
        m["rejected_sightings"] = c.rejected_sightings;
        m["rejected_controls"] = c.rejected_controls;
        m["numeric_faults"] = c.numeric_faults;
        m["jcbb_budget_hits"] = c.jcbb_budget_hits;
        m["landmarks_in_state"] = ekf_->n_lm;
    } else {
        const fastslam_counters_t &c = fs_->ctr;
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
    }
    return m;
}

} // namespace coslam::replay
