// robot_camera_rig.hpp - coslam-robot's device slots with only the camera
// configured, on the in-memory V4L2 driver (test/hal_linux/v4l2/v4l2_fake.c
// linked in place of the backend's system-call seam) and its fake clock;
// the device reports go to a memory stream. Shared by test_robot_camera
// and coslam-bench-robot-camera.
#ifndef COSLAM_TEST_ROBOT_CAMERA_RIG_HPP
#define COSLAM_TEST_ROBOT_CAMERA_RIG_HPP

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "robot_devices.h"
#include "v4l2_fake.h"
#include "vision/vision.h"

namespace coslam {

constexpr int W = VISION_IMAGE_WIDTH_PX, H = VISION_IMAGE_HEIGHT_PX;
constexpr double kDeg = M_PI / 180.0;
constexpr uint64_t kFrameUs = 100000;  // 10 frames/s, the paper's camera

inline hal_status_t fake_now(hal_clock_t *, uint64_t *now_us)
{
    *now_us = fake_v4l2.now_us;
    return HAL_OK;
}
inline const hal_clock_ops_t kFakeClockOps = {&fake_now, nullptr, nullptr};

// The robot's devices with only the camera configured, on the fake driver's
// clock; the device reports go to a memory stream.
struct Rig {
    hal_clock_t clock{&kFakeClockOps, nullptr};
    robot_config_t cfg{};
    robot_devices_t dev{};
    char *log_text = nullptr;
    size_t log_len = 0;
    FILE *log = nullptr;
    coslam_status_t init_status = COSLAM_E_ARG;
    std::string init_message;
    explicit Rig(bool open = true)
    {
        fake_v4l2_reset();
        robot_config_default(&cfg);
        cfg.laser_device[0] = '\0';
        cfg.can_interface[0] = '\0';
        cfg.gpio_chip[0] = '\0';
        cfg.storage_dir[0] = '\0';
        cfg.fleet_key_file[0] = '\0';  // link off
        std::snprintf(cfg.camera_device, sizeof cfg.camera_device, "/dev/video0");
        std::snprintf(cfg.camera_colour_table, sizeof cfg.camera_colour_table, "%s/colour_lut.bin",
                      COSLAM_VISION_DATA_DIR);
        std::snprintf(cfg.camera_range_model, sizeof cfg.camera_range_model, "%s/range_model.txt",
                      COSLAM_VISION_DATA_DIR);
        log = open_memstream(&log_text, &log_len);
        char msg[256];
        init_status = robot_devices_init(&dev, &cfg, &clock, log, 1, msg, sizeof msg);
        init_message = msg;
        if (open) robot_devices_open_all(&dev, now());
    }
    ~Rig()
    {
        robot_devices_close_all(&dev);
        std::fclose(log);
        std::free(log_text);
    }
    uint64_t now() const { return fake_v4l2.now_us; }
    std::string log_so_far()
    {
        std::fflush(log);
        return std::string(log_text, log_len);
    }
    robot_dev_status_t &slot() { return dev.dev[ROBOT_DEV_CAMERA]; }
    sighting_source_t *src() { return &dev.sightings; }
    robot_camera_counters_t ctr() const { return robot_camera_counters(&dev.camera); }
    // one robot step's worth: the node asks for a frame, then the slot is
    // serviced. A reopen the service hands to the camera's opener thread is
    // waited for (the fake driver's clock stands still meanwhile) and taken
    // by a second service, so that the step sees its outcome as one step.
    hal_status_t step(sighting_frame_t *f)
    {
        const hal_status_t st = sighting_source_next_frame(src(), f, 0);
        robot_devices_service(&dev, now());
        if (slot().opening) {  // handed over, not yet taken (it may have returned already)
            if (robot_devices_wait_opens(&dev, 5000) != 0u) {
                std::fprintf(stderr, "robot_camera_rig: the camera's open attempt did not return in 5 s\n");
                std::abort();
            }
            robot_devices_service(&dev, now());
        }
        return st;
    }
    void advance(uint64_t us) { fake_v4l2.now_us += us; }
    bool push_yuyv(const std::vector<uint8_t> &yuyv) { return fake_v4l2_push(yuyv.data(), yuyv.size(), now(), 0); }
};

}  // namespace coslam

#endif
