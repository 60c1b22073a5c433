// The marker detector's candidate-pair capacity (vision_config.h
// VISION_MAX_PAIR_CANDIDATES), in a build of the detector where it is 4:
// a frame with five markers side by side (one candidate pair each) reports
// VISION_E_CAPACITY, counts the pair it skipped, and still gives the four
// it kept; the next frame, within the capacity, is whole again. The
// shipped build's capacity (8 x 512) is not reachable by a frame anyone
// can draw, so only a smaller build can show the path works.
#include <gtest/gtest.h>

#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "vision/marker_spec.h"
#include "vision/vision.h"

static_assert(VISION_MAX_PAIR_CANDIDATES == 4, "this test is built with a capacity of 4 candidate pairs");

namespace {

constexpr int W = VISION_IMAGE_WIDTH_PX, H = VISION_IMAGE_HEIGHT_PX;

// A grey frame with n flat two-band landmark markers (blue over yellow)
// side by side, 15 px wide and 40 px tall, 50 px apart.
cv::Mat markers(int n)
{
    cv::Mat rgb(H, W, CV_8UC3, cv::Scalar(128, 128, 128));
    const uint8_t *t = vision_colour_srgb[VISION_COLOUR_BLUE], *b = vision_colour_srgb[VISION_COLOUR_YELLOW];
    for (int k = 0; k < n; ++k) {
        const int x0 = 20 + 50 * k;
        cv::rectangle(rgb, cv::Point(x0, 100), cv::Point(x0 + 14, 119), cv::Scalar(t[0], t[1], t[2]), cv::FILLED);
        cv::rectangle(rgb, cv::Point(x0, 120), cv::Point(x0 + 14, 139), cv::Scalar(b[0], b[1], b[2]), cv::FILLED);
    }
    return rgb;
}

}  // namespace

TEST(DetectCapacity, PairCandidatesBeyondTheCapacityAreSkippedCountedAndSaid)
{
    vision_lut_t lut;
    ASSERT_EQ(vision_lut_load(&lut, (std::string(COSLAM_VISION_DATA_DIR) + "/colour_lut.bin").c_str()), VISION_OK);
    const vision_config_t cfg = vision_config_default();
    const vision_range_model_t model = vision_range_model_pinhole();
    vision_detector_t *det = nullptr;
    ASSERT_EQ(vision_detector_create(&det, &cfg, &lut, &model), VISION_OK);
    vision_result_t res;

    cv::Mat four = markers(4);
    ASSERT_EQ(vision_detect_rgb(det, four.ptr<uint8_t>(0), 3u * W, &res), VISION_OK); // at the capacity
    EXPECT_EQ(res.n_markers, 4);
    EXPECT_EQ(vision_detector_counters(det)->pairs_overflow, 0u);

    cv::Mat five = markers(5);
    EXPECT_EQ(vision_detect_rgb(det, five.ptr<uint8_t>(0), 3u * W, &res), VISION_E_CAPACITY);
    EXPECT_EQ(res.n_markers, 4); // the pairs kept are still measured
    EXPECT_EQ(vision_detector_counters(det)->pairs_overflow, 1u);
    for (int i = 0; i < res.n_markers; ++i) EXPECT_EQ(res.markers[i].kind, VISION_MARKER_LANDMARK);

    cv::Mat two = markers(2);
    EXPECT_EQ(vision_detect_rgb(det, two.ptr<uint8_t>(0), 3u * W, &res), VISION_OK);
    EXPECT_EQ(res.n_markers, 2);
    EXPECT_EQ(vision_detector_counters(det)->pairs_overflow, 1u);
    vision_detector_destroy(det);
}
