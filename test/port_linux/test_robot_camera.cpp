// coslam-robot's camera (firmware/port/linux/robot_camera.h) through the
// robot's device slot (robot_devices.h): the real V4L2 backend and the real
// marker detector, with the in-memory V4L2 driver
// (test/hal_linux/v4l2/v4l2_fake.c) linked in place of the backend's
// system-call seam (no camera on this machine). Frames are rendered by the
// simulator's camera renderer (host/vision/vision_scenes: random poses in
// the paper's arena, another robot in most frames, posts, blur, lighting),
// converted to YUYV as a webcam sends them, and pushed into the fake
// driver; the sightings the robot node would get are compared with the
// renderer's ground truth. Then the failures: no device, a camera that
// only offers H.264, a camera at another size, a missing colour table,
// unplug and replug, a stalled camera, a short frame; each reported by
// name, counted, and recovered by the slot's reopen. And no allocation per
// frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "robot_camera_rig.hpp"
#include "robot_devices.h"
#include "v4l2_fake.h"
#include "vision_scenes.hpp"
// last: it defines malloc and friends, after every system header declared them
#include "alloc_counter.hpp"

using namespace coslam;
using namespace coslam::vision_host;

namespace {

std::vector<uint8_t> grey_yuyv()
{
    std::vector<uint8_t> rgb(static_cast<size_t>(W) * H * 3, 128);
    return rgb_to_yuyv(rgb.data(), W, H);
}

double quant(std::vector<double> v, double q) { return quantile(std::move(v), q); }

}  // namespace

// Rendered frames through V4L2 (YUYV, BT.601 limited range) -> RGB ->
// detector -> the robot's sighting frames, against the renderer's truth.
TEST(RobotCamera, RenderedFramesGiveTheTrueSightings)
{
    Rig r;
    ASSERT_EQ(r.init_status, COSLAM_OK) << r.init_message;
    ASSERT_EQ(r.slot().state, ROBOT_DEV_UP) << r.log_so_far();
    EXPECT_NE(r.log_so_far().find("camera (V4L2 /dev/video0, 320x240, markers): up"), std::string::npos)
        << r.log_so_far();
    const sim::Scenario sc = sim::load_scenario_file(paper_scenario_path());
    const int frames = 150;
    int clear = 0, clear_hit = 0, unmatched = 0, id_errors = 0, sightings = 0;
    std::vector<double> er_lm, er_rb, eb_lm, eb_rb;
    long allocs = 0;
    for (int i = 0; i < frames; ++i) {
        const Scene s = make_scene(sc, 7100 + static_cast<uint64_t>(i));
        const Frame fr = render_scene(s);
        const std::vector<uint8_t> yuyv = rgb_to_yuyv(fr.rgb.data(), W, H);
        r.advance(kFrameUs);
        const uint64_t stamp = r.now();
        ASSERT_TRUE(r.push_yuyv(yuyv));
        sighting_frame_t f;
        hal_status_t st = HAL_E_ARG;
        allocs += alloc_counter::kCounting ? alloc_counter::during([&] { st = r.step(&f); })
                                           : (st = r.step(&f), 0L);
        ASSERT_EQ(st, HAL_OK) << "frame " << i;
        EXPECT_EQ(f.stamp_us, stamp);
        EXPECT_EQ(f.sequence, static_cast<uint32_t>(i));
        EXPECT_EQ(f.dropped, 0);
        // every sighting must be some marker of the frame, of its class / id
        struct Seen {
            bool robot;
            int index;
            double range_m, bearing_rad;
            bool used;
        };
        std::vector<Seen> seen;
        for (int k = 0; k < f.n_landmarks; ++k)
            seen.push_back({false, f.landmarks[k].signature, f.landmarks[k].range_m, f.landmarks[k].bearing_rad, false});
        for (int k = 0; k < f.n_robots; ++k)
            seen.push_back({true, f.robots[k].robot_id, f.robots[k].range_m, f.robots[k].bearing_rad, false});
        sightings += static_cast<int>(seen.size());
        auto near = [](const sim::RenderedMarker &m, const Seen &z) {
            const double tol = std::max(m.half_width_rad + 1.0 * kDeg, 3.0 * kDeg);
            return std::fabs(z.bearing_rad - m.bearing_rad) < tol && std::fabs(z.range_m - m.range_m) < 0.3 * m.range_m;
        };
        for (const sim::RenderedMarker &m : fr.truth) {
            const bool robot = m.kind == VISION_MARKER_ROBOT;
            if (!expected(m, 0.95)) continue;
            ++clear;
            for (Seen &z : seen) {
                if (z.used || z.robot != robot || z.index != m.index || !near(m, z)) continue;
                z.used = true;
                ++clear_hit;
                (robot ? er_rb : er_lm).push_back(std::fabs(z.range_m - m.range_m) / m.range_m);
                (robot ? eb_rb : eb_lm).push_back(std::fabs(z.bearing_rad - m.bearing_rad) / kDeg);
                break;
            }
        }
        for (Seen &z : seen) {
            if (z.used) continue;
            bool any = false, same = false;
            for (const sim::RenderedMarker &m : fr.truth) {
                if (m.visible <= 0.0 || !near(m, z)) continue;
                any = true;
                same = same || ((m.kind == VISION_MARKER_ROBOT) == z.robot && m.index == z.index);
            }
            if (!any) ++unmatched;
            else if (!same) ++id_errors;
        }
    }
    const robot_camera_counters_t c = r.ctr();
    std::printf("robot camera: %d frames, %d sightings; clear markers %d, found %d (%.3f); not a marker %d, "
                "wrong class/id %d\n",
                frames, sightings, clear, clear_hit, clear ? double(clear_hit) / clear : 0.0, unmatched, id_errors);
    std::printf("  landmarks (%zu): |range err|/range p50 %.4f p90 %.4f max %.4f; |bearing err| p50 %.3f p90 %.3f "
                "max %.3f deg\n",
                er_lm.size(), quant(er_lm, 0.5), quant(er_lm, 0.9), quant(er_lm, 1.0), quant(eb_lm, 0.5),
                quant(eb_lm, 0.9), quant(eb_lm, 1.0));
    std::printf("  robots (%zu): |range err|/range p50 %.4f p90 %.4f max %.4f; |bearing err| p50 %.3f p90 %.3f "
                "max %.3f deg\n",
                er_rb.size(), quant(er_rb, 0.5), quant(er_rb, 0.9), quant(er_rb, 1.0), quant(eb_rb, 0.5),
                quant(eb_rb, 0.9), quant(eb_rb, 1.0));
    std::printf("  allocations in %d robot-side frame steps: %ld\n", frames, allocs);
    EXPECT_EQ(c.frames, static_cast<uint64_t>(frames));
    EXPECT_EQ(c.landmarks + c.robots, static_cast<uint64_t>(sightings));
    // Bounds (docs/robot.md "Camera"): the detector on RGB frames of the same
    // renderer (test_vision_detect, 150 frames) finds >= 95 % of the clear
    // markers with range p90 <= 3 %, bearing p90 <= 0.15 deg (landmarks) /
    // 1 deg (robots). The V4L2 path adds 4:2:2 chroma subsampling and 8-bit
    // YUV rounding, which move band edges by at most a pixel column: the
    // same rate, range p90 and max with 1 % more, bearings 0.1 deg more.
    ASSERT_GT(clear, 100);
    EXPECT_GE(double(clear_hit) / clear, 0.95);
    EXPECT_LE(unmatched, frames / 50);  // <= 0.02 false markers per frame
    EXPECT_EQ(id_errors, 0);
    ASSERT_FALSE(er_lm.empty());
    ASSERT_FALSE(er_rb.empty());
    EXPECT_LE(quant(er_lm, 0.9), 0.04);
    EXPECT_LE(quant(er_lm, 1.0), 0.06);
    EXPECT_LE(quant(eb_lm, 0.9), 0.25);
    EXPECT_LE(quant(er_rb, 0.9), 0.04);
    EXPECT_LE(quant(eb_rb, 0.9), 1.1);
    // no allocation per frame after start-up (V4L2 dequeue, YUYV -> RGB,
    // detection, the sighting frame, the slot)
    if (alloc_counter::kCounting) {
        EXPECT_EQ(allocs, 0);
    }
}

TEST(RobotCamera, NoDeviceIsReportedByNameAndReopened)
{
    Rig r(false);  // (resets the fake)
    fake_v4l2.present = false;
    robot_devices_open_all(&r.dev, r.now());
    EXPECT_EQ(r.slot().state, ROBOT_DEV_DOWN);
    const std::string log = r.log_so_far();
    EXPECT_NE(log.find("coslam-robot: camera (V4L2 /dev/video0, 320x240, markers): down: V4L2 open: "
                       "HAL_E_NOT_FOUND; localisation on odometry only; retrying every 5 s"),
              std::string::npos)
        << log;
    sighting_frame_t f;
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);  // the node sees "no frame", never an error
    fake_v4l2.present = true;
    r.advance(4000000);
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    EXPECT_EQ(r.slot().state, ROBOT_DEV_DOWN);  // not before the retry period
    r.advance(1000000);
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    EXPECT_EQ(r.slot().state, ROBOT_DEV_UP);
    EXPECT_NE(r.log_so_far().find("camera (V4L2 /dev/video0, 320x240, markers): back up after 1 failed attempt"),
              std::string::npos);
    ASSERT_TRUE(r.push_yuyv(grey_yuyv()));
    EXPECT_EQ(r.step(&f), HAL_OK);
    EXPECT_EQ(f.n_landmarks + f.n_robots, 0);  // an empty frame is still a frame
    EXPECT_EQ(r.ctr().open_failures, 1u);
    EXPECT_EQ(r.ctr().opens, 1u);
}

TEST(RobotCamera, BadFormatsAreRefusedWithTheReason)
{
    {  // a camera that only sends H.264
        Rig r(false);
        fake_v4l2.formats[0] = 0x34363248u;  // V4L2_PIX_FMT_H264 'H264'
        fake_v4l2.n_formats = 1;
        robot_devices_open_all(&r.dev, r.now());
        EXPECT_EQ(r.slot().state, ROBOT_DEV_DOWN);
        EXPECT_NE(r.log_so_far().find("down: V4L2 open: HAL_E_UNSUPPORTED"), std::string::npos) << r.log_so_far();
    }
    {  // a webcam that gives 640x480 whatever is asked
        Rig r(false);
        fake_v4l2.force_width = 640;
        fake_v4l2.force_height = 480;
        robot_devices_open_all(&r.dev, r.now());
        EXPECT_EQ(r.slot().state, ROBOT_DEV_DOWN);
        EXPECT_NE(r.log_so_far().find("the camera gives 640x480, configured 320x240"), std::string::npos)
            << r.log_so_far();
        EXPECT_EQ(r.ctr().bad_format, 1u);
        EXPECT_EQ(fake_v4l2.live_fd, -1);  // nothing stays open
    }
    {  // ... which is fine once the configuration says so
        Rig r(false);
        fake_v4l2.force_width = 640;
        fake_v4l2.force_height = 480;
        r.cfg.camera_width_px = 640;
        r.cfg.camera_height_px = 480;
        robot_devices_open_all(&r.dev, r.now());
        EXPECT_EQ(r.slot().state, ROBOT_DEV_UP) << r.log_so_far();
        EXPECT_NEAR(vision_detector_config(r.dev.camera.det)->focal_px, 2.0 * vision_config_default().focal_px, 1e-9);
    }
    {  // no colour table: named, the robot runs on odometry
        Rig r(false);
        std::snprintf(r.cfg.camera_colour_table, sizeof r.cfg.camera_colour_table, "/nonexistent/lut.bin");
        robot_devices_open_all(&r.dev, r.now());
        EXPECT_EQ(r.slot().state, ROBOT_DEV_DOWN);
        EXPECT_NE(r.log_so_far().find("colour table /nonexistent/lut.bin: No such file or directory"),
                  std::string::npos)
            << r.log_so_far();
        EXPECT_EQ(fake_v4l2.n_open, 0u);  // the device is not touched without a detector
    }
    {  // a short frame: dropped by the backend, no sighting frame, no loss
        Rig r;
        std::vector<uint8_t> y = grey_yuyv();
        y.resize(y.size() / 2);
        r.advance(kFrameUs);
        ASSERT_TRUE(r.push_yuyv(y));
        sighting_frame_t f;
        EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
        EXPECT_EQ(r.slot().state, ROBOT_DEV_UP);
        EXPECT_EQ(r.dev.camera.v4l2.counters.bad_size_frames, 1u);
    }
}

TEST(RobotCamera, UnplugAndReplugAreReopenedBySlot)
{
    Rig r;
    sighting_frame_t f;
    ASSERT_TRUE(r.push_yuyv(grey_yuyv()));
    ASSERT_EQ(r.step(&f), HAL_OK);
    fake_v4l2_unplug();
    r.advance(kFrameUs);
    EXPECT_EQ(r.step(&f), HAL_E_CLOSED);  // once; then the slot is down: "no frame"
    EXPECT_EQ(r.slot().state, ROBOT_DEV_DOWN);
    EXPECT_EQ(r.ctr().disconnects, 1u);
    EXPECT_NE(r.log_so_far().find("camera (V4L2 /dev/video0, 320x240, markers): lost"), std::string::npos)
        << r.log_so_far();
    EXPECT_EQ(fake_v4l2.live_mmaps, 0);
    fake_v4l2_replug();
    r.advance(5000000);
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    ASSERT_EQ(r.slot().state, ROBOT_DEV_UP) << r.log_so_far();
    r.advance(kFrameUs);
    ASSERT_TRUE(r.push_yuyv(grey_yuyv()));
    EXPECT_EQ(r.step(&f), HAL_OK);
    EXPECT_EQ(r.ctr().opens, 2u);
    EXPECT_EQ(r.ctr().frames, 2u);
}

// A frame the detector can take only in part (more colour runs than
// VISION_MAX_RUNS): still a frame, counted in detect_partial (the source
// counted it before, but the robot's camera counters and status had no
// field for it), said as a LIMIT line once per growth, and kept across a
// reopen like the other counters; so is foreign_robots (set by hand: the
// marker table has fewer robot ids than this build's COSLAM_MAX_ROBOTS).
TEST(RobotCamera, DetectorCapacityLossIsCountedAndSaid)
{
    Rig r;
    sighting_frame_t f;
    // red and blue in runs of two pixels (a YUYV chroma pair each), shifted
    // by a pair every row: 160 runs a row, 38 400 > VISION_MAX_RUNS
    std::vector<uint8_t> rgb(static_cast<size_t>(W) * H * 3);
    const uint8_t *red = vision_colour_srgb[VISION_COLOUR_RED], *blue = vision_colour_srgb[VISION_COLOUR_BLUE];
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            std::memcpy(&rgb[(static_cast<size_t>(y) * W + x) * 3], ((x / 2 + y) & 1) ? red : blue, 3);
        }
    }
    static_assert(W / 2 * H > VISION_MAX_RUNS, "the pattern must overflow the runs");
    ASSERT_TRUE(r.push_yuyv(rgb_to_yuyv(rgb.data(), W, H)));
    ASSERT_EQ(r.step(&f), HAL_OK);  // the part processed is still a frame
    EXPECT_EQ(r.ctr().detect_partial, 1u);
    EXPECT_EQ(r.ctr().frames, 1u);
    char *text = nullptr;
    size_t len = 0;
    FILE *out = open_memstream(&text, &len);
    uint64_t seen = 0;
    EXPECT_EQ(robot_camera_say_limits(&r.dev.camera, &seen, 2u, out), 1);
    EXPECT_EQ(robot_camera_say_limits(&r.dev.camera, &seen, 2u, out), 0);  // said once per growth
    std::fclose(out);
    const std::string said(text, len);
    std::free(text);
    EXPECT_NE(said.find("coslam-robot: LIMIT robot 2: 1 camera frames detected only in part"), std::string::npos)
        << said;
    EXPECT_NE(said.find("(cam_detect_partial; VISION_MAX_RUNS = "), std::string::npos) << said;
    EXPECT_EQ(std::count(said.begin(), said.end(), '\n'), 1);
    // kept across a reopen (folded at the close)
    r.dev.camera.vs.ctr.foreign_robots = 3;
    EXPECT_EQ(r.ctr().foreign_robots, 3u);
    fake_v4l2_unplug();
    r.advance(kFrameUs);
    EXPECT_EQ(r.step(&f), HAL_E_CLOSED);
    fake_v4l2_replug();
    r.advance(5000000);
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    ASSERT_EQ(r.slot().state, ROBOT_DEV_UP) << r.log_so_far();
    EXPECT_EQ(r.ctr().detect_partial, 1u);
    EXPECT_EQ(r.ctr().foreign_robots, 3u);
}

// A reopen that meets another frame size (the webcam replugged into a
// driver that forces 640x480): refused on the opener thread, counted by the
// loop (bad_format, open_failures), nothing left open, retried; back up once
// the camera gives the configured size again.
TEST(RobotCamera, ReopenAtAnotherSizeIsRefused)
{
    Rig r;
    sighting_frame_t f;
    ASSERT_EQ(r.slot().state, ROBOT_DEV_UP) << r.log_so_far();
    fake_v4l2_unplug();
    r.advance(kFrameUs);
    EXPECT_EQ(r.step(&f), HAL_E_CLOSED);
    ASSERT_EQ(r.slot().state, ROBOT_DEV_DOWN);
    fake_v4l2.force_width = 640;
    fake_v4l2.force_height = 480;
    fake_v4l2_replug();
    r.advance(5000000);
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    EXPECT_EQ(r.slot().state, ROBOT_DEV_DOWN);
    EXPECT_EQ(r.ctr().bad_format, 1u);
    EXPECT_EQ(r.ctr().open_failures, 1u);
    EXPECT_EQ(fake_v4l2.live_fd, -1);  // nothing stays open
    EXPECT_NE(r.log_so_far().find("the camera gives 640x480, configured 320x240"), std::string::npos)
        << r.log_so_far();
    fake_v4l2.force_width = 0;
    fake_v4l2.force_height = 0;
    r.advance(5000000);
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    EXPECT_EQ(r.slot().state, ROBOT_DEV_UP) << r.log_so_far();
    EXPECT_EQ(r.ctr().opens, 2u);
    EXPECT_EQ(r.ctr().bad_format, 1u);
}

TEST(RobotCamera, StalledCameraIsReopened)
{
    {
    Rig r;
    sighting_frame_t f;
    // silence shorter than stall_timeout_s (2 s): timeouts only
    for (int i = 0; i < 19; ++i) {
        r.advance(kFrameUs);
        EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    }
    EXPECT_EQ(r.slot().state, ROBOT_DEV_UP);
    EXPECT_EQ(r.dev.camera.vs.ctr.grab_timeouts, 19u);
    r.advance(kFrameUs);
    EXPECT_EQ(r.step(&f), HAL_E_CLOSED);
    EXPECT_EQ(r.slot().state, ROBOT_DEV_DOWN);
    EXPECT_EQ(r.ctr().stalls, 1u);
    EXPECT_EQ(fake_v4l2.live_fd, -1);  // closed
    r.advance(5000000);
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    EXPECT_EQ(r.slot().state, ROBOT_DEV_UP);
    ASSERT_TRUE(r.push_yuyv(grey_yuyv()));
    EXPECT_EQ(r.step(&f), HAL_OK);
    EXPECT_EQ(r.step(&f), HAL_E_TIMEOUT);
    }
    // stall_timeout_s = 0: never
    sighting_frame_t f;
    Rig q(false);
    q.cfg.camera_stall_us = 0;
    robot_devices_open_all(&q.dev, q.now());
    for (int i = 0; i < 100; ++i) {
        q.advance(kFrameUs);
        EXPECT_EQ(q.step(&f), HAL_E_TIMEOUT);
    }
    EXPECT_EQ(q.slot().state, ROBOT_DEV_UP);
    EXPECT_EQ(q.ctr().stalls, 0u);
}
