// The app's sighting source on a camera (firmware/vision vision_source.h),
// against the simulator's camera backend (SimCamera, hal_camera_t):
// frames become sighting frames (landmark class, robot id, stamp,
// sequence), no frame is a timeout, a stopped camera is restarted, formats
// the detector cannot take are refused, sightings beyond the frame's
// capacity are dropped and counted.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "sim_hal/sim_camera.hpp"
#include "sim_hal/sim_clock.hpp"
#include "vision/vision_source.h"
#include "vision_scenes.hpp"

using namespace coslam;
using namespace coslam::sim;
using namespace coslam::vision_host;

namespace {

constexpr int W = VISION_IMAGE_WIDTH_PX, H = VISION_IMAGE_HEIGHT_PX;

void draw_marker(cv::Mat &rgb, int x0, int x1, int y0, int y1, vision_pair_t pair)
{
    const int ym = (y0 + y1) / 2;
    const uint8_t *t = vision_colour_srgb[pair.top], *b = vision_colour_srgb[pair.bottom];
    cv::rectangle(rgb, cv::Point(x0, y0), cv::Point(x1, ym - 1), cv::Scalar(t[0], t[1], t[2]), cv::FILLED);
    cv::rectangle(rgb, cv::Point(x0, ym), cv::Point(x1, y1 - 1), cv::Scalar(b[0], b[1], b[2]), cv::FILLED);
}

struct Rig {
    SimClock clock{0};
    SimCamera cam{clock, W, H, HAL_CAMERA_PIX_RGB24};
    vision_detector_t *det = nullptr;
    std::vector<uint8_t> buf = std::vector<uint8_t>(static_cast<size_t>(W) * H * 3);
    vision_source_t vs{};
    Rig()
    {
        static vision_lut_t lut;
        vision_range_model_t m;
        load_vision_data("", "", &lut, &m);
        const vision_config_t c = vision_config_default();
        EXPECT_EQ(vision_detector_create(&det, &c, &lut, &m), VISION_OK);
    }
    ~Rig() { vision_detector_destroy(det); }
    bool push(const cv::Mat &rgb, uint64_t stamp) { return cam.push_frame(rgb.ptr<uint8_t>(0), rgb.total() * 3, stamp); }
};

}  // namespace

TEST(VisionSource, FramesBecomeSightingFrames)
{
    Rig r;
    ASSERT_EQ(vision_source_init(&r.vs, r.cam.handle(), r.det, r.buf.data(), r.buf.size()), HAL_OK);
    EXPECT_TRUE(r.cam.streaming());  // init starts the camera
    sighting_source_t *src = vision_source_handle(&r.vs);
    sighting_frame_t f;
    EXPECT_EQ(sighting_source_next_frame(src, &f, 0), HAL_E_TIMEOUT);  // nothing captured yet
    cv::Mat rgb(H, W, CV_8UC3, cv::Scalar(128, 128, 128));
    draw_marker(rgb, 60, 74, 100, 140, vision_landmark_pairs[2]);   // landmark class 2, left
    draw_marker(rgb, 170, 290, 95, 145, vision_robot_pairs[1]);     // robot 1, right
    ASSERT_TRUE(r.push(rgb, 123456));
    ASSERT_EQ(sighting_source_next_frame(src, &f, 0), HAL_OK);
    EXPECT_EQ(f.stamp_us, 123456u);
    EXPECT_EQ(f.sequence, 1u);
    ASSERT_EQ(f.n_landmarks, 1);
    EXPECT_EQ(f.landmarks[0].signature, 2);
    EXPECT_GT(f.landmarks[0].bearing_rad, 0.0);  // left of the axis: counter-clockwise
    EXPECT_GT(f.landmarks[0].range_m, 1.0);
    ASSERT_EQ(f.n_robots, 1);
    EXPECT_EQ(f.robots[0].robot_id, 1);
    EXPECT_LT(f.robots[0].bearing_rad, 0.0);
    EXPECT_EQ(f.dropped, 0);
    EXPECT_EQ(sighting_source_next_frame(src, &f, 0), HAL_E_TIMEOUT);  // never the same frame twice
    // an empty frame is still a frame (negative evidence for the filters)
    const cv::Mat grey(H, W, CV_8UC3, cv::Scalar(128, 128, 128));
    ASSERT_TRUE(r.push(grey, 200000));
    ASSERT_EQ(sighting_source_next_frame(src, &f, 0), HAL_OK);
    EXPECT_EQ(f.n_landmarks + f.n_robots, 0);
    EXPECT_EQ(f.sequence, 2u);
    EXPECT_EQ(r.vs.ctr.frames, 2u);
    EXPECT_EQ(r.vs.ctr.landmarks, 1u);
    EXPECT_EQ(r.vs.ctr.robots, 1u);
}

TEST(VisionSource, SightingsBeyondTheFramesCapacityAreCounted)
{
    if (COSLAM_MAX_SIGHTINGS >= 22) {
        GTEST_SKIP() << "22 markers in one image exceed only the default profile's " << 16
                     << " sightings per frame; this build has " << COSLAM_MAX_SIGHTINGS;
    }
    Rig r;
    ASSERT_EQ(vision_source_init(&r.vs, r.cam.handle(), r.det, r.buf.data(), r.buf.size()), HAL_OK);
    cv::Mat rgb(H, W, CV_8UC3, cv::Scalar(128, 128, 128));
    // 2 rows of 11 narrow landmark markers: 22 > COSLAM_MAX_SIGHTINGS (16)
    int n = 0;
    for (int row = 0; row < 2; ++row) {
        for (int i = 0; i < 11; ++i, ++n) {
            const int x = 10 + 27 * i, y = 30 + 100 * row;
            draw_marker(rgb, x, x + 9, y, y + 40, vision_landmark_pairs[n % VISION_N_LANDMARK_CLASSES]);
        }
    }
    ASSERT_TRUE(r.push(rgb, 1));
    sighting_frame_t f;
    ASSERT_EQ(sighting_source_next_frame(vision_source_handle(&r.vs), &f, 0), HAL_OK);
    EXPECT_EQ(r.vs.result.n_markers, 22);
    EXPECT_EQ(f.n_landmarks, COSLAM_MAX_SIGHTINGS);
    EXPECT_EQ(f.dropped, 22 - COSLAM_MAX_SIGHTINGS);
    EXPECT_EQ(r.vs.ctr.dropped, static_cast<uint64_t>(22 - COSLAM_MAX_SIGHTINGS));
}

TEST(VisionSource, AStoppedCameraIsRestartedAndBadFormatsRefused)
{
    Rig r;
    ASSERT_EQ(vision_source_init(&r.vs, r.cam.handle(), r.det, r.buf.data(), r.buf.size()), HAL_OK);
    ASSERT_EQ(hal_camera_stop(r.cam.handle()), HAL_OK);
    sighting_frame_t f;
    // next_frame finds it stopped, starts it again: no frame yet
    EXPECT_EQ(sighting_source_next_frame(vision_source_handle(&r.vs), &f, 0), HAL_E_TIMEOUT);
    EXPECT_TRUE(r.cam.streaming());
    // a frame buffer too small for the format, a size the detector was not made for
    vision_source_t vs2;
    EXPECT_EQ(vision_source_init(&vs2, r.cam.handle(), r.det, r.buf.data(), r.buf.size() - 1), HAL_E_ARG);
    SimCamera big(r.clock, 640, 480, HAL_CAMERA_PIX_RGB24);
    std::vector<uint8_t> bigbuf(640u * 480u * 3u);
    EXPECT_EQ(vision_source_init(&vs2, big.handle(), r.det, bigbuf.data(), bigbuf.size()), HAL_E_ARG);
    EXPECT_EQ(vision_source_init(nullptr, r.cam.handle(), r.det, r.buf.data(), r.buf.size()), HAL_E_ARG);
    // the null camera: its errors come through
    EXPECT_EQ(vision_source_init(&vs2, hal_camera_null(), r.det, r.buf.data(), r.buf.size()), HAL_E_UNSUPPORTED);
}

TEST(VisionSource, YuyvCamerasWork)
{
    SimClock clock{0};
    SimCamera cam(clock, W, H, HAL_CAMERA_PIX_YUYV);
    static vision_lut_t lut;
    vision_range_model_t m;
    load_vision_data("", "", &lut, &m);
    const vision_config_t c = vision_config_default();
    vision_detector_t *det = nullptr;
    ASSERT_EQ(vision_detector_create(&det, &c, &lut, &m), VISION_OK);
    std::vector<uint8_t> buf(static_cast<size_t>(W) * H * 2);
    vision_source_t vs;
    ASSERT_EQ(vision_source_init(&vs, cam.handle(), det, buf.data(), buf.size()), HAL_OK);
    cv::Mat rgb(H, W, CV_8UC3, cv::Scalar(128, 128, 128));
    draw_marker(rgb, 150, 164, 100, 140, vision_landmark_pairs[3]);
    const std::vector<uint8_t> yuyv = rgb_to_yuyv(rgb.ptr<uint8_t>(0), W, H);
    ASSERT_TRUE(cam.push_frame(yuyv.data(), yuyv.size(), 5));
    sighting_frame_t f;
    ASSERT_EQ(sighting_source_next_frame(vision_source_handle(&vs), &f, 0), HAL_OK);
    ASSERT_EQ(f.n_landmarks, 1);
    EXPECT_EQ(f.landmarks[0].signature, 3);
    vision_detector_destroy(det);
}
