// coslam-vision, the command: image files in, one JSON line per frame out,
// annotated images on request, an unreadable file reported and the exit
// status 1.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "vision_scenes.hpp"

using namespace coslam;
using namespace coslam::vision_host;

namespace {

int run(const std::string &cmd, std::vector<nlohmann::json> *lines)
{
    FILE *p = popen(cmd.c_str(), "r");
    if (p == nullptr) return -1;
    char buf[65536];
    while (std::fgets(buf, sizeof buf, p) != nullptr) lines->push_back(nlohmann::json::parse(buf));
    const int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

}  // namespace

TEST(VisionCli, ImagesToJsonLinesAndAnnotations)
{
    const std::string dir = ::testing::TempDir() + "/coslam_vision_cli";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    // a rendered frame with a robot and at least two landmarks detected
    const sim::Scenario sc = sim::load_scenario_file(paper_scenario_path());
    static vision_lut_t lut;
    vision_range_model_t m;
    load_vision_data("", "", &lut, &m);
    const vision_config_t c = vision_config_default();
    vision_detector_t *det = nullptr;
    ASSERT_EQ(vision_detector_create(&det, &c, &lut, &m), VISION_OK);
    vision_result_t res;
    Frame f;
    size_t n_lm = 0, n_rb = 0;
    for (uint64_t seed = 5000; seed < 5100 && (n_lm < 2 || n_rb < 1); ++seed) {
        f = render_scene(make_scene(sc, seed));
        vision_detect_rgb(det, f.rgb.data(), 3u * VISION_IMAGE_WIDTH_PX, &res);
        n_lm = n_rb = 0;
        for (uint16_t k = 0; k < res.n_markers; ++k) (res.markers[k].kind == VISION_MARKER_ROBOT ? n_rb : n_lm)++;
    }
    vision_detector_destroy(det);
    ASSERT_GE(n_lm, 2u);
    ASSERT_GE(n_rb, 1u);
    const cv::Mat rgb(VISION_IMAGE_HEIGHT_PX, VISION_IMAGE_WIDTH_PX, CV_8UC3, const_cast<uint8_t *>(f.rgb.data()));
    ASSERT_TRUE(write_rgb(dir + "/scene.png", rgb));
    // the same at 640x480 (a webcam's default size): resized to the model's 320x240
    cv::Mat big;
    cv::resize(rgb, big, cv::Size(640, 480), 0, 0, cv::INTER_LINEAR);
    ASSERT_TRUE(write_rgb(dir + "/big.jpg", big));
    std::vector<nlohmann::json> out;
    const int rc = run(std::string(COSLAM_VISION_CLI) + " " + dir + "/scene.png " + dir + "/big.jpg " + dir +
                           "/missing.png --annotate " + dir + "/ann 2>/dev/null",
                       &out);
    EXPECT_EQ(rc, 1);  // the missing file
    ASSERT_EQ(out.size(), 3u);
    // the first frame: what the detector found in-process
    const auto &j0 = out[0];
    EXPECT_EQ(j0["frame"], 0);
    EXPECT_EQ(j0["resized"], false);
    ASSERT_EQ(j0["landmarks"].size(), n_lm);
    ASSERT_EQ(j0["robots"].size(), n_rb);
    for (size_t k = 0, l = 0; k < res.n_markers; ++k) {
        if (res.markers[k].kind != VISION_MARKER_LANDMARK) continue;
        EXPECT_EQ(j0["landmarks"][l]["signature"], res.markers[k].index);
        EXPECT_NEAR(j0["landmarks"][l]["range_m"].get<double>(), res.markers[k].range_m, 1e-9);
        ++l;
    }
    for (const auto &l : j0["landmarks"]) {
        EXPECT_TRUE(l.contains("signature"));
        EXPECT_GT(l["range_m"].get<double>(), 0.3);
        EXPECT_GT(l["range_var_m2"].get<double>(), 0.0);
        EXPECT_EQ(l["box"].size(), 4u);
    }
    // the resized JPEG finds the same markers, about the same ranges
    const auto &j1 = out[1];
    EXPECT_EQ(j1["resized"], true);
    EXPECT_EQ(j1["width"], 640);
    EXPECT_EQ(j1["landmarks"].size() + j1["robots"].size(), n_lm + n_rb);
    EXPECT_TRUE(out[2].contains("error"));
    EXPECT_TRUE(std::filesystem::exists(dir + "/ann/000000_scene_detections.png"));
    EXPECT_TRUE(std::filesystem::exists(dir + "/ann/000000_scene_classes.png"));
    EXPECT_TRUE(std::filesystem::exists(dir + "/ann/000001_big_detections.png"));
}
