// The V4L2 camera backend (hal/hal_camera_v4l2.h) in the camera
// conformance suite, over the in-memory V4L2 driver of
// test/hal_linux/v4l2/v4l2_fake.h linked in place of the backend's
// system-call seam (no camera on this machine). The fake's CLOCK_MONOTONIC
// is the harness clock: frames are stamped with it (MONOTONIC buffers) and
// a poll that times out consumes it, so stamps and timeouts are checked
// like the simulator's. Three set-ups:
//  - yuyv_rgb24:  a YUYV camera at the default 320x240 with padded rows,
//                 RGB24 out. The expected pixels are the backend's own
//                 BT.601 conversion of the bytes the camera sent (that
//                 conversion is checked against analytic values in
//                 test/hal_linux/v4l2/test_camera_v4l2);
//  - yuyv:        the same camera, YUYV out: the bytes sent, exactly;
//  - mjpeg_rgb24: an MJPEG-only camera at 160x120; frames are JPEGs made
//                 with TurboJPEG, expected = TurboJPEG's decode of them.
#include <linux/videodev2.h>
#include <turbojpeg.h>

#include <cstring>
#include <vector>

#include "conformance.hpp"
#include "hal/hal_camera_v4l2.h"
#include "v4l2_fake.h"

namespace {

hal_status_t fake_now(hal_clock_t *, uint64_t *now_us)
{
    *now_us = fake_v4l2.now_us;
    return HAL_OK;
}

const hal_clock_ops_t kFakeClockOps = {&fake_now, nullptr, nullptr};

void quiet(void *, const char *) {}

enum class Setup { yuyv_rgb24, yuyv, mjpeg_rgb24 };

struct V4l2FakeHarness : conf::CameraHarness {
    explicit V4l2FakeHarness(Setup s) : setup(s)
    {
        fake_v4l2_reset();
        hal_camera_v4l2_config_t cfg{};
        cfg.device = "/dev/video0";
        cfg.log = &quiet;
        if (s == Setup::mjpeg_rgb24) {
            fake_v4l2.formats[0] = V4L2_PIX_FMT_MJPEG;
            fake_v4l2.n_formats = 1;
            cfg.width_px = 160;
            cfg.height_px = 120;
        } else {
            fake_v4l2.row_pad_bytes = 64;
        }
        if (s == Setup::yuyv) cfg.output = HAL_CAMERA_PIX_YUYV;
        dev_ = hal_camera_v4l2_open(&cfg, &cam);
        EXPECT_NE(dev_, nullptr) << hal_status_str(cam.open_status);
        tj_enc = tjInitCompress();
        tj_dec = tjInitDecompress();
    }
    ~V4l2FakeHarness() override
    {
        if (dev_ != nullptr) hal_camera_close(dev_);
        EXPECT_EQ(fake_v4l2.live_mmaps, 0) << "buffers left mapped";
        EXPECT_EQ(fake_v4l2.live_fd, -1) << "device left open";
        tjDestroy(tj_enc);
        tjDestroy(tj_dec);
    }
    hal_camera_t *dev() override { return dev_; }
    hal_clock_t *clock() override { return &clk; }
    void let_time_pass_us(uint64_t us) override { fake_v4l2.now_us += us; }

    std::vector<uint8_t> capture(uint32_t seed, uint64_t *stamp_us) override
    {
        *stamp_us = fake_v4l2.now_us;
        const uint32_t w = cam.fmt.width_px;
        const uint32_t h = cam.fmt.height_px;
        std::vector<uint8_t> expected(cam.fmt.frame_bytes);
        if (setup == Setup::mjpeg_rgb24) {
            // a smooth seeded image (noise would not fit the driver's buffer as JPEG)
            std::vector<uint8_t> rgb(static_cast<size_t>(w) * h * 3u);
            const auto p = conf::pattern(3, seed);
            for (uint32_t y = 0; y < h; ++y) {
                for (uint32_t x = 0; x < w; ++x) {
                    uint8_t *px = &rgb[(static_cast<size_t>(y) * w + x) * 3u];
                    px[0] = static_cast<uint8_t>(p[0] + x * 2u);
                    px[1] = static_cast<uint8_t>(p[1] + y * 2u);
                    px[2] = static_cast<uint8_t>(p[2] + (x ^ y));
                }
            }
            unsigned char *jpeg = nullptr;
            unsigned long size = 0;
            EXPECT_EQ(tjCompress2(tj_enc, rgb.data(), static_cast<int>(w), 0, static_cast<int>(h), TJPF_RGB, &jpeg, &size,
                                  TJSAMP_422, 90, 0),
                      0);
            EXPECT_EQ(tjDecompress2(tj_dec, jpeg, size, expected.data(), static_cast<int>(w), 0, static_cast<int>(h),
                                    TJPF_RGB, 0),
                      0);
            fake_v4l2_push(jpeg, size, *stamp_us, 0);
            tjFree(jpeg);
            return expected;
        }
        const uint32_t in_stride = fake_v4l2.bytesperline;
        const std::vector<uint8_t> yuyv = conf::pattern(static_cast<size_t>(in_stride) * h, seed);
        if (setup == Setup::yuyv) {
            for (uint32_t y = 0; y < h; ++y) {
                std::memcpy(&expected[static_cast<size_t>(y) * cam.fmt.stride_bytes],
                            &yuyv[static_cast<size_t>(y) * in_stride], static_cast<size_t>(w) * 2u);
            }
        } else {
            hal_camera_v4l2_yuyv_to_rgb24(yuyv.data(), in_stride, expected.data(), cam.fmt.stride_bytes, w, h, false);
        }
        fake_v4l2_push(yuyv.data(), yuyv.size(), *stamp_us, 0);
        return expected;
    }

    Setup setup;
    hal_camera_v4l2_t cam{};
    hal_camera_t *dev_ = nullptr;
    hal_clock_t clk{&kFakeClockOps, nullptr};
    tjhandle tj_enc = nullptr;
    tjhandle tj_dec = nullptr;
};

}  // namespace

INSTANTIATE_TEST_SUITE_P(
    Linux, CameraConformance,
    ::testing::Values(conf::make_backend<conf::CameraHarness, V4l2FakeHarness>("v4l2_fake_yuyv_rgb24", Setup::yuyv_rgb24),
                      conf::make_backend<conf::CameraHarness, V4l2FakeHarness>("v4l2_fake_yuyv", Setup::yuyv),
                      conf::make_backend<conf::CameraHarness, V4l2FakeHarness>("v4l2_fake_mjpeg_rgb24",
                                                                               Setup::mjpeg_rgb24)),
    conf::BackendName());
