// coslam-bench-robot-camera (`make bench`): the CPU time of coslam-robot's
// camera path per frame, through the robot's own device slot
// (robot_devices.h): the real V4L2 backend (dequeue, requeue), YUYV -> RGB,
// the marker detector and the sighting frame the node takes, on the
// in-memory V4L2 driver (no camera on this machine; the driver's copy of
// the frame, which a real camera's DMA does, is outside the timing).
// Frames: 100 rendered scenes of the paper's arena (the simulator's camera
// renderer), converted to YUYV as a webcam sends them, cycled 5 times.
// CPU time is the process's (CLOCK_PROCESS_CPUTIME_ID) around each robot
// step; the figure at a frame rate is what the camera adds to
// coslam-robot's CPU use (tools/robot_cpu.sh measures the rest).
//   coslam-bench-robot-camera [--out DIR]      -> DIR/robot_camera.md
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "checked_file.hpp"
#include "robot_camera_rig.hpp"
#include "vision_scenes.hpp"

using namespace coslam;
using namespace coslam::vision_host;

namespace {

double cpu_us()
{
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) * 1e6 + static_cast<double>(ts.tv_nsec) * 1e-3;
}

}  // namespace

static int bench_robot_camera_main(int argc, char **argv)
{
    std::string out = "out/bench";
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--out") == 0 && i + 1 < argc) {
            out = argv[++i];
        } else {
            std::fprintf(stderr, "usage: coslam-bench-robot-camera [--out DIR]\n");
            return 2;
        }
    }
    Rig r;
    if (r.init_status != COSLAM_OK || r.slot().state != ROBOT_DEV_UP) {
        std::fprintf(stderr, "coslam-bench-robot-camera: camera slot not up: %s\n%s", r.init_message.c_str(),
                     r.log_so_far().c_str());
        return 1;
    }
    const sim::Scenario sc = sim::load_scenario_file(paper_scenario_path());
    std::vector<std::vector<uint8_t>> frames;
    for (int i = 0; i < 100; ++i) {
        const Frame fr = render_scene(make_scene(sc, 9100 + static_cast<uint64_t>(i)));
        frames.push_back(rgb_to_yuyv(fr.rgb.data(), W, H));
    }
    std::vector<double> us;
    long sightings = 0;
    for (int pass = 0; pass < 5; ++pass) {
        for (const auto &y : frames) {
            r.advance(kFrameUs);
            if (!r.push_yuyv(y)) {
                std::fprintf(stderr, "coslam-bench-robot-camera: the driver refused a frame\n");
                return 1;
            }
            sighting_frame_t f;
            const double t0 = cpu_us();
            const hal_status_t st = r.step(&f);
            const double t1 = cpu_us();
            if (st != HAL_OK) {
                std::fprintf(stderr, "coslam-bench-robot-camera: no frame (%d)\n%s", static_cast<int>(st),
                             r.log_so_far().c_str());
                return 1;
            }
            sightings += f.n_landmarks + f.n_robots;
            if (pass > 0) us.push_back(t1 - t0);  // pass 0 warms the caches
        }
    }
    std::sort(us.begin(), us.end());
    double mean = 0.0;
    for (double v : us) mean += v;
    mean /= static_cast<double>(us.size());
    const double p50 = us[us.size() / 2], p99 = us[us.size() * 99 / 100], mx = us.back();
    char md[1024];
    std::snprintf(md, sizeof md,
                  "# coslam-robot's camera path per 320x240 YUYV frame\n\n"
                  "V4L2 backend (in-memory driver) + YUYV->RGB + marker detector + sighting frame, through the\n"
                  "robot's device slot; %zu timed frames (100 rendered scenes, 4 passes after a warm-up pass),\n"
                  "%ld sightings in all. Process CPU time per robot step that took a frame.\n\n"
                  "| mean [us] | p50 [us] | p99 [us] | max [us] | CPU at 10 frames/s | at 30 frames/s |\n"
                  "|---|---|---|---|---|---|\n"
                  "| %.0f | %.0f | %.0f | %.0f | %.2f %% of one core | %.2f %% |\n",
                  us.size(), sightings, mean, p50, p99, mx, mean * 10.0 * 1e-4, mean * 30.0 * 1e-4);
    std::fputs(md, stdout);
    const std::string path = out + "/robot_camera.md";
    try {
        coslam::cli::write_text_file(path, md);
    } catch (const coslam::cli::WriteError &e) {
        std::fprintf(stderr, "coslam-bench-robot-camera: %s\n", e.what());
        return 1;
    }
    return 0;
}

// exit status with standard output checked (stdout_check.h)
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-bench-robot-camera", bench_robot_camera_main(argc, argv));
}
