#include "sim/world/sighting_oracle.hpp"

#include <cmath>
#include <cstring>

namespace coslam::sim {

const sighting_source_ops_t SightingOracle::kOps = {&SightingOracle::op_next_frame};

SightingOracle::SightingOracle(const World &world, int self_id, const SightingOracleConfig &cfg)
    : world_(world), self_(self_id), cfg_(cfg), next_us_(cfg.phase_us)
{
    rng_seed(&rng_, cfg.seed);
    src_.ops = &kOps;
    src_.backend = this;
    detections_.assign(world.landmarks().size(), 0);
}

void SightingOracle::set_time_us(uint64_t t_us)
{
    while (next_us_ <= t_us) {
        if (stalled_) {
            ++stalled_frames_;
            ++frame_seq_;
        } else {
            capture(next_us_);
        }
        next_us_ += cfg_.period_us;
    }
}

void SightingOracle::capture(uint64_t stamp_us)
{
    const RobotBody *me = world_.body(self_);
    if (me == nullptr) {
        return;
    }
    if (detections_.size() < world_.landmarks().size()) {
        detections_.resize(world_.landmarks().size(), 0);
    }
    sighting_frame_t f;
    std::memset(&f, 0, sizeof f);
    f.stamp_us = stamp_us;
    f.sequence = ++frame_seq_;
    const Eigen::Vector2d cam(me->pose.x, me->pose.y);
    latest_viewed_ = landmarks_in_filter_view(world_, self_, me->pose, cfg_.view_model);
    latest_detected_.assign(world_.landmarks().size(), 0);
    const double half_fov = 0.5 * cfg_.fov_rad;
    auto in_view = [&](const Eigen::Vector2d &p, double &r, double &b) {
        const point2_t rel = pose2_apply_inverse(me->pose, point2_t{p.x(), p.y()});
        r = std::hypot(rel.x, rel.y);
        b = std::atan2(rel.y, rel.x);
        return r >= cfg_.min_range_m && r <= cfg_.max_range_m && std::fabs(b) <= half_fov;
    };
    for (const auto &lm : world_.landmarks()) {
        double r = 0.0, b = 0.0;
        if (!in_view(lm.p, r, b) || !world_.line_of_sight(cam, lm.p, self_, -1)) continue;
        if (rng_uniform(&rng_) >= cfg_.p_detect) continue;
        const double sd_r = std::sqrt(cfg_.range_sd_m * cfg_.range_sd_m + std::pow(cfg_.range_sd_rel * r, 2));
        const double zr = std::fmax(0.01, r + rng_normal(&rng_, 0.0, sd_r));
        const double zb = angle_wrap(b + rng_normal(&rng_, 0.0, cfg_.bearing_sd_rad));
        detections_[static_cast<size_t>(lm.id)]++;
        if (f.n_landmarks >= COSLAM_MAX_SIGHTINGS) {
            f.dropped++;
            dropped_++;
            continue;
        }
        f.landmarks[f.n_landmarks++] = sighting_t{zr, zb, lm.signature};
        latest_detected_[static_cast<size_t>(lm.id)] = 1;
    }
    for (const auto &other : world_.bodies()) {
        if (other.id == self_) continue;
        const Eigen::Vector2d p(other.pose.x, other.pose.y);
        double r = 0.0, b = 0.0;
        if (!in_view(p, r, b) || !world_.line_of_sight(cam, p, self_, other.id, 0.0)) continue;
        if (rng_uniform(&rng_) >= cfg_.robot_p_detect) continue;
        const double zr = std::fmax(0.01, r + rng_normal(&rng_, 0.0, cfg_.robot_range_sd_m));
        const double zb = angle_wrap(b + rng_normal(&rng_, 0.0, cfg_.robot_bearing_sd_rad));
        if (f.n_robots >= COSLAM_MAX_ROBOTS) {
            f.dropped++;
            dropped_++;
            continue;
        }
        f.robots[f.n_robots++] = robot_seen_t{static_cast<uint8_t>(other.id), zr, zb};
        robot_sightings_++;
    }
    latest_ = f;
    have_frame_ = true;
    frames_++;
}

hal_status_t SightingOracle::op_next_frame(sighting_source_t *src, sighting_frame_t *out, uint32_t)
{
    auto *self = static_cast<SightingOracle *>(src->backend);
    if (!self->have_frame_) {
        return HAL_E_TIMEOUT;
    }
    *out = self->latest_;
    self->have_frame_ = false;
    tally_frame(self->tally_, self->latest_viewed_, self->latest_detected_);
    return HAL_OK;
}

}  // namespace coslam::sim
