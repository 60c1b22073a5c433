// sim_hal/sim_camera.hpp - a simulated camera behind hal_camera_t. The
// simulator's renderer pushes finished frames (real pixels in the declared
// format); the firmware grabs the latest one, exactly as with a V4L2
// device that keeps only the newest buffer.
#ifndef COSLAM_SIM_HAL_SIM_CAMERA_HPP
#define COSLAM_SIM_HAL_SIM_CAMERA_HPP

#include <cstdint>
#include <vector>

#include "hal/hal_camera.h"
#include "sim_hal/sim_clock.hpp"

namespace coslam::sim {

class SimCamera {
public:
    /// A format with width, height > 0, a known pixfmt (even width for
    /// YUYV); stride 0 means "no padding"; frame_bytes is computed.
    /// Throws std::invalid_argument otherwise.
    SimCamera(SimClock &clock, uint32_t width_px, uint32_t height_px, hal_camera_pixfmt_t pixfmt,
              uint32_t stride_bytes = 0);
    SimCamera(const SimCamera &) = delete;
    SimCamera &operator=(const SimCamera &) = delete;

    hal_camera_t *handle() { return &handle_; }
    const hal_camera_format_t &format() const { return fmt_; }

    struct Stats {
        uint64_t captured = 0;             ///< frames accepted while streaming
        uint64_t dropped_stopped = 0;      ///< pushes while not streaming
        uint64_t dropped_unread = 0;       ///< captured frames replaced before a grab
        uint64_t rejected_size = 0;        ///< pushes whose size != frame_bytes
        uint64_t grabbed = 0;
    };

    // ---- simulator side (thread-safe) -----------------------------------
    /// Deliver a frame captured at stamp_us (normally now). Returns true if
    /// captured: false if not streaming or len != format().frame_bytes.
    bool push_frame(const uint8_t *data, size_t len, uint64_t stamp_us);
    bool streaming() const;
    Stats stats() const;

private:
    static hal_status_t op_get_format(hal_camera_t *dev, hal_camera_format_t *fmt);
    static hal_status_t op_start(hal_camera_t *dev);
    static hal_status_t op_stop(hal_camera_t *dev);
    static hal_status_t op_grab(hal_camera_t *dev, uint8_t *buf, size_t cap, hal_camera_frame_info_t *info,
                                uint32_t timeout_us);

    SimClock &clock_;
    hal_camera_format_t fmt_{};
    bool streaming_ = false;
    bool fresh_ = false;         // latest_ not grabbed yet
    std::vector<uint8_t> latest_;
    uint64_t latest_stamp_us_ = 0;
    uint32_t sequence_ = 0;      // of latest_
    Stats stats_;
    hal_camera_t handle_;
};

}  // namespace coslam::sim

#endif
