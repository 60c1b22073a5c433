// Simulated camera (see sim_camera.hpp).
#include "sim_hal/sim_camera.hpp"

#include <cstring>
#include <stdexcept>

namespace coslam::sim {

SimCamera::SimCamera(SimClock &clock, uint32_t width_px, uint32_t height_px, hal_camera_pixfmt_t pixfmt,
                     uint32_t stride_bytes)
    : clock_(clock)
{
    const size_t row = hal_camera_row_bytes(pixfmt, width_px);
    if (width_px == 0 || height_px == 0 || row == 0) throw std::invalid_argument("SimCamera: bad format");
    if (stride_bytes == 0) stride_bytes = static_cast<uint32_t>(row);
    if (stride_bytes < row) throw std::invalid_argument("SimCamera: stride shorter than a row");
    fmt_.width_px = width_px;
    fmt_.height_px = height_px;
    fmt_.pixfmt = pixfmt;
    fmt_.stride_bytes = stride_bytes;
    fmt_.frame_bytes = static_cast<size_t>(stride_bytes) * height_px;
    latest_.resize(fmt_.frame_bytes);
    static const hal_camera_ops_t ops = {&SimCamera::op_get_format, &SimCamera::op_start, &SimCamera::op_stop,
                                         &SimCamera::op_grab, nullptr};
    handle_.ops = &ops;
    handle_.backend = this;
}

bool SimCamera::push_frame(const uint8_t *data, size_t len, uint64_t stamp_us)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    if (data == nullptr || len != fmt_.frame_bytes) {
        ++stats_.rejected_size;
        return false;
    }
    if (!streaming_) {
        ++stats_.dropped_stopped;
        return false;
    }
    if (fresh_) ++stats_.dropped_unread;
    std::memcpy(latest_.data(), data, len);
    latest_stamp_us_ = stamp_us;
    ++sequence_;
    ++stats_.captured;
    fresh_ = true;
    clock_.notify_locked();
    return true;
}

bool SimCamera::streaming() const
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    return streaming_;
}

SimCamera::Stats SimCamera::stats() const
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    return stats_;
}

hal_status_t SimCamera::op_get_format(hal_camera_t *dev, hal_camera_format_t *fmt)
{
    *fmt = static_cast<SimCamera *>(dev->backend)->fmt_;
    return HAL_OK;
}

hal_status_t SimCamera::op_start(hal_camera_t *dev)
{
    auto *self = static_cast<SimCamera *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    self->streaming_ = true;
    return HAL_OK;
}

hal_status_t SimCamera::op_stop(hal_camera_t *dev)
{
    auto *self = static_cast<SimCamera *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    self->streaming_ = false;
    self->fresh_ = false;  // frames captured while streaming are not kept across a stop
    self->clock_.notify_locked();
    return HAL_OK;
}

hal_status_t SimCamera::op_grab(hal_camera_t *dev, uint8_t *buf, size_t cap, hal_camera_frame_info_t *info,
                                uint32_t timeout_us)
{
    auto *self = static_cast<SimCamera *>(dev->backend);
    std::unique_lock<std::mutex> lk(self->clock_.mutex());
    if (!self->streaming_) return HAL_E_CLOSED;
    const uint64_t deadline = SimClock::deadline_after(self->clock_.now_locked(), timeout_us);
    const std::function<bool()> ready = [self] { return self->fresh_ || !self->streaming_; };
    self->clock_.wait_until(lk, deadline, ready);
    if (!self->streaming_) return HAL_E_CLOSED;
    if (!self->fresh_) return HAL_E_TIMEOUT;
    info->len = self->fmt_.frame_bytes;
    info->stamp_us = self->latest_stamp_us_;
    info->sequence = self->sequence_;
    if (cap < self->fmt_.frame_bytes) return HAL_E_OVERFLOW;
    std::memcpy(buf, self->latest_.data(), self->fmt_.frame_bytes);
    self->fresh_ = false;
    ++self->stats_.grabbed;
    return HAL_OK;
}

}  // namespace coslam::sim
