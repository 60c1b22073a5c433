// hal_camera contract conformance (see hal/hal_camera.h).
#include "conformance.hpp"

using conf::now_of;

namespace {

hal_camera_format_t format_of(hal_camera_t *c)
{
    hal_camera_format_t f{};
    EXPECT_EQ(hal_camera_get_format(c, &f), HAL_OK);
    return f;
}

struct Grab {
    hal_status_t st;
    hal_camera_frame_info_t info;
    std::vector<uint8_t> data;
};

Grab grab(hal_camera_t *c, uint32_t timeout_us, size_t cap)
{
    Grab g{};
    g.data.resize(cap);
    g.st = hal_camera_grab(c, g.data.data(), cap, &g.info, timeout_us);
    if (g.st != HAL_OK) g.data.clear();
    return g;
}

}  // namespace

TEST_P(CameraConformance, FormatIsConsistent)
{
    const hal_camera_format_t f = format_of(h->dev());
    EXPECT_GT(f.width_px, 0u);
    EXPECT_GT(f.height_px, 0u);
    ASSERT_TRUE(f.pixfmt == HAL_CAMERA_PIX_RGB24 || f.pixfmt == HAL_CAMERA_PIX_YUYV);
    const size_t row = hal_camera_row_bytes(f.pixfmt, f.width_px);
    ASSERT_GT(row, 0u) << "YUYV needs an even width";
    EXPECT_GE(f.stride_bytes, row);
    EXPECT_EQ(f.frame_bytes, static_cast<size_t>(f.stride_bytes) * f.height_px);
    EXPECT_EQ(hal_camera_get_format(h->dev(), nullptr), HAL_E_ARG);
}

TEST_P(CameraConformance, GrabWhileStoppedIsClosed)
{
    const hal_camera_format_t f = format_of(h->dev());
    EXPECT_EQ(grab(h->dev(), 0, f.frame_bytes).st, HAL_E_CLOSED);
    ASSERT_EQ(hal_camera_start(h->dev()), HAL_OK);
    ASSERT_EQ(hal_camera_stop(h->dev()), HAL_OK);
    EXPECT_EQ(grab(h->dev(), 0, f.frame_bytes).st, HAL_E_CLOSED);
}

TEST_P(CameraConformance, StartStopIdempotent)
{
    EXPECT_EQ(hal_camera_stop(h->dev()), HAL_OK);
    EXPECT_EQ(hal_camera_start(h->dev()), HAL_OK);
    EXPECT_EQ(hal_camera_start(h->dev()), HAL_OK);
    EXPECT_EQ(hal_camera_stop(h->dev()), HAL_OK);
    EXPECT_EQ(hal_camera_stop(h->dev()), HAL_OK);
}

TEST_P(CameraConformance, GrabTimesOutWithoutFrame)
{
    const hal_camera_format_t f = format_of(h->dev());
    ASSERT_EQ(hal_camera_start(h->dev()), HAL_OK);
    hal_clock_t *clk = h->clock();
    const uint64_t t0 = clk ? now_of(clk) : 0;
    EXPECT_EQ(grab(h->dev(), 0, f.frame_bytes).st, HAL_E_TIMEOUT);
    EXPECT_EQ(grab(h->dev(), 5000, f.frame_bytes).st, HAL_E_TIMEOUT);
    if (clk != nullptr) {
        EXPECT_GE(now_of(clk) - t0, 5000u);
    }
}

TEST_P(CameraConformance, GrabReturnsExactFrameAndStamp)
{
    const hal_camera_format_t f = format_of(h->dev());
    ASSERT_EQ(hal_camera_start(h->dev()), HAL_OK);
    uint64_t stamp = 0;
    const auto frame = h->capture(7, &stamp);
    ASSERT_EQ(frame.size(), f.frame_bytes);
    Grab g = grab(h->dev(), 0, f.frame_bytes);
    ASSERT_EQ(g.st, HAL_OK);
    EXPECT_EQ(g.info.len, f.frame_bytes);
    EXPECT_EQ(g.info.stamp_us, stamp);
    EXPECT_TRUE(g.data == frame) << "pixels altered";
}

TEST_P(CameraConformance, GrabReturnsLatestAndCountsSkipped)
{
    const hal_camera_format_t f = format_of(h->dev());
    ASSERT_EQ(hal_camera_start(h->dev()), HAL_OK);
    uint64_t s1, s2, s3;
    h->capture(1, &s1);
    Grab g1 = grab(h->dev(), 0, f.frame_bytes);
    ASSERT_EQ(g1.st, HAL_OK);
    h->let_time_pass_us(1000);
    h->capture(2, &s2);
    h->let_time_pass_us(1000);
    const auto third = h->capture(3, &s3);
    Grab g = grab(h->dev(), 0, f.frame_bytes);
    ASSERT_EQ(g.st, HAL_OK);
    EXPECT_TRUE(g.data == third) << "not the latest frame";
    EXPECT_EQ(g.info.stamp_us, s3);
    EXPECT_EQ(g.info.sequence - g1.info.sequence, 2u) << "sequence gap must count the skipped frame";
    EXPECT_GT(s3, s1);
}

TEST_P(CameraConformance, SameFrameNeverTwice)
{
    const hal_camera_format_t f = format_of(h->dev());
    ASSERT_EQ(hal_camera_start(h->dev()), HAL_OK);
    uint64_t s;
    h->capture(4, &s);
    ASSERT_EQ(grab(h->dev(), 0, f.frame_bytes).st, HAL_OK);
    EXPECT_EQ(grab(h->dev(), 0, f.frame_bytes).st, HAL_E_TIMEOUT);
}

TEST_P(CameraConformance, SmallBufferIsOverflowAndKeepsFrame)
{
    const hal_camera_format_t f = format_of(h->dev());
    ASSERT_EQ(hal_camera_start(h->dev()), HAL_OK);
    uint64_t s;
    const auto frame = h->capture(5, &s);
    Grab small = grab(h->dev(), 0, f.frame_bytes - 1);
    EXPECT_EQ(small.st, HAL_E_OVERFLOW);
    EXPECT_EQ(small.info.len, f.frame_bytes);
    Grab g = grab(h->dev(), 0, f.frame_bytes);
    ASSERT_EQ(g.st, HAL_OK) << "the frame stays available after HAL_E_OVERFLOW";
    EXPECT_TRUE(g.data == frame);
}

TEST_P(CameraConformance, FramesWhileStoppedAreNotKept)
{
    const hal_camera_format_t f = format_of(h->dev());
    ASSERT_EQ(hal_camera_start(h->dev()), HAL_OK);
    uint64_t s;
    h->capture(6, &s);
    ASSERT_EQ(hal_camera_stop(h->dev()), HAL_OK);
    h->capture(7, &s);
    ASSERT_EQ(hal_camera_start(h->dev()), HAL_OK);
    EXPECT_EQ(grab(h->dev(), 0, f.frame_bytes).st, HAL_E_TIMEOUT);
}

TEST_P(CameraConformance, ArgumentsChecked)
{
    hal_camera_frame_info_t info;
    uint8_t b;
    EXPECT_EQ(hal_camera_grab(h->dev(), nullptr, 10, &info, 0), HAL_E_ARG);
    EXPECT_EQ(hal_camera_grab(h->dev(), &b, 0, &info, 0), HAL_E_ARG);
    EXPECT_EQ(hal_camera_grab(h->dev(), &b, 1, nullptr, 0), HAL_E_ARG);
    EXPECT_EQ(hal_camera_start(nullptr), HAL_E_ARG);
}
