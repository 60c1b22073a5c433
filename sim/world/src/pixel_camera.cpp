#include "sim/world/pixel_camera.hpp"

#include <cmath>
#include <stdexcept>

namespace coslam::sim {

namespace {

constexpr double kMatchBearingRad = 3.0 * COSLAM_PI / 180.0;
constexpr double kMatchRangeRel = 0.3;
constexpr size_t kTruthFrames = 8;

}  // namespace

const sighting_source_ops_t PixelCamera::kTapOps = {&PixelCamera::op_next_frame};

std::string default_vision_lut_path()
{
    return std::string(COSLAM_VISION_DATA_DIR) + "/colour_lut.bin";
}

std::string default_vision_model_path()
{
    return std::string(COSLAM_VISION_DATA_DIR) + "/range_model.txt";
}

PixelCamera::PixelCamera(SimClock &clock, const World &world, int self_id, const PixelCameraConfig &cfg)
    : world_(world), self_(self_id), cfg_(cfg),
      cam_(clock, cfg.render.width_px, cfg.render.height_px, HAL_CAMERA_PIX_RGB24), renderer_(world, cfg.render),
      next_us_(cfg.phase_us)
{
    const std::string lut_path = cfg.lut_path.empty() ? default_vision_lut_path() : cfg.lut_path;
    const std::string model_path = cfg.model_path.empty() ? default_vision_model_path() : cfg.model_path;
    static thread_local vision_lut_t lut;  // 32 KB: not on the stack
    vision_status_t st = vision_lut_load(&lut, lut_path.c_str());
    if (st != VISION_OK) throw std::runtime_error("pixel camera: colour table " + lut_path + ": " + vision_status_name(st));
    vision_range_model_t model;
    st = vision_range_model_load(&model, model_path.c_str());
    if (st != VISION_OK) throw std::runtime_error("pixel camera: range model " + model_path + ": " + vision_status_name(st));
    vision_config_t dc = cfg.detector;
    dc.width_px = cfg.render.width_px;
    dc.height_px = cfg.render.height_px;
    st = vision_detector_create(&det_, &dc, &lut, &model);
    if (st != VISION_OK) throw std::runtime_error(std::string("pixel camera: detector: ") + vision_status_name(st));
    frame_.assign(cam_.format().frame_bytes, 0);
    grab_buf_.assign(cam_.format().frame_bytes, 0);
    const hal_status_t hs = vision_source_init(&vs_, cam_.handle(), det_, grab_buf_.data(), grab_buf_.size());
    if (hs != HAL_OK) {
        vision_detector_destroy(det_);
        throw std::runtime_error(std::string("pixel camera: vision source: ") + hal_status_str(hs));
    }
    tap_.ops = &kTapOps;
    tap_.backend = this;
    detections_.assign(world.landmarks().size(), 0);
}

PixelCamera::~PixelCamera()
{
    vision_detector_destroy(det_);
}

void PixelCamera::set_time_us(uint64_t t_us, double vx, double vy, double w)
{
    while (next_us_ <= t_us) {
        const RobotBody *me = stalled_ ? nullptr : world_.body(self_);
        if (me != nullptr) {
            renderer_.render(me->pose, vx, vy, w, self_, frame_.data(), nullptr, &scratch_);
            // stamp: the start of the exposure (hal_camera.h), which ends now
            const uint64_t exp_us = static_cast<uint64_t>(cfg_.render.exposure_ms * 1000.0);
            const uint64_t stamp = next_us_ > exp_us ? next_us_ - exp_us : 0;
            if (cam_.push_frame(frame_.data(), frame_.size(), stamp)) {
                ++pushed_seq_;
                truth_.push_back(FrameTruth{pushed_seq_, scratch_,
                                            landmarks_in_filter_view(world_, self_, me->pose, cfg_.view_model)});
                if (truth_.size() > kTruthFrames) truth_.pop_front();
                stats_.frames++;
            }
        }
        next_us_ += cfg_.period_us;
    }
}

void PixelCamera::evaluate(const sighting_frame_t &f)
{
    const FrameTruth *ft = nullptr;
    for (const auto &t : truth_) {
        if (t.seq == f.sequence) ft = &t;
    }
    if (ft == nullptr) return;
    const std::vector<RenderedMarker> *truth = &ft->markers;
    detected_scratch_.assign(world_.landmarks().size(), 0);
    if (detections_.size() < world_.landmarks().size()) detections_.resize(world_.landmarks().size(), 0);
    auto near = [](const RenderedMarker &m, double r, double b) {
        return std::fabs(angle_wrap(b - m.bearing_rad)) < std::max(kMatchBearingRad, m.half_width_rad + COSLAM_PI / 180.0) &&
               std::fabs(r - m.range_m) < kMatchRangeRel * m.range_m;
    };
    for (uint16_t i = 0; i < f.n_landmarks; ++i) {
        const sighting_t &z = f.landmarks[i];
        stats_.landmark_sightings++;
        const RenderedMarker *best = nullptr;
        for (const auto &m : *truth) {
            if (m.kind != VISION_MARKER_LANDMARK || m.index != z.signature || !near(m, z.range_m, z.bearing_rad)) continue;
            if (best == nullptr || std::fabs(angle_wrap(z.bearing_rad - m.bearing_rad)) <
                                       std::fabs(angle_wrap(z.bearing_rad - best->bearing_rad))) {
                best = &m;
            }
        }
        if (best == nullptr) {
            stats_.false_markers++;
            continue;
        }
        stats_.landmark_matched++;
        detections_[static_cast<size_t>(best->landmark_id)]++;
        if (static_cast<size_t>(best->landmark_id) < detected_scratch_.size()) {
            detected_scratch_[static_cast<size_t>(best->landmark_id)] = 1;
        }
        const double er = (z.range_m - best->range_m) / best->range_m;
        const double eb = angle_wrap(z.bearing_rad - best->bearing_rad);
        stats_.range_rel_err_sum2 += er * er;
        stats_.bearing_err_sum2 += eb * eb;
    }
    tally_frame(tally_, ft->viewed, detected_scratch_);
    for (uint16_t i = 0; i < f.n_robots; ++i) {
        const robot_seen_t &r = f.robots[i];
        stats_.robot_sightings++;
        bool same = false, other = false;
        for (const auto &m : *truth) {
            if (m.kind != VISION_MARKER_ROBOT || !near(m, r.range_m, r.bearing_rad)) continue;
            (m.index == r.robot_id ? same : other) = true;
        }
        if (!same && other) stats_.robot_id_errors++;
        if (!same && !other) stats_.false_markers++;
    }
}

hal_status_t PixelCamera::op_next_frame(sighting_source_t *src, sighting_frame_t *out, uint32_t timeout_us)
{
    auto *self = static_cast<PixelCamera *>(src->backend);
    const hal_status_t st = sighting_source_next_frame(vision_source_handle(&self->vs_), out, timeout_us);
    if (st == HAL_OK) self->evaluate(*out);
    return st;
}

}  // namespace coslam::sim
