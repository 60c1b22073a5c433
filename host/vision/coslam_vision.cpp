// coslam-vision: the robot's marker detector (firmware/vision) on image
// files or a live camera; one JSON line per frame on stdout:
//   {"source":"a.png","frame":0,"width":320,"height":240,"resized":false,"time_us":180.2,
//    "landmarks":[{"signature":2,"range_m":1.93,"bearing_rad":0.12,"range_var_m2":..,
//                  "bearing_var_rad2":..,"box":[x,y,w,h]}],
//    "robots":[{"robot_id":1,"range_m":..,"bearing_rad":..,...}]}
// Images of another size are resized to the camera model's 320x240 (the
// intrinsics assume the webcam's 50 deg field of view at that size);
// "resized" says so. An unreadable file gives {"source":..,"error":".."}
// and exit status 1 at the end.
//
//   coslam-vision [--lut F] [--model F] [--annotate DIR] IMAGE...
//   coslam-vision --camera N [--frames K] [--annotate DIR]
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "checked_file.hpp"
#include "cli_checks.hpp"
#include "vision_scenes.hpp"

using namespace coslam;
using namespace coslam::vision_host;

namespace {

nlohmann::json marker_json(const vision_marker_t &m)
{
    nlohmann::json j;
    if (m.kind == VISION_MARKER_ROBOT) {
        j["robot_id"] = m.index;
    } else {
        j["signature"] = m.index;
    }
    j["range_m"] = m.range_m;
    j["bearing_rad"] = m.bearing_rad;
    j["range_var_m2"] = m.range_var_m2;
    j["bearing_var_rad2"] = m.bearing_var_rad2;
    j["box"] = {m.x, m.y, m.w, m.h};
    return j;
}

class Runner {
public:
    Runner(vision_detector_t *det, std::string annotate) : det_(det), annotate_(std::move(annotate)) {}

    // Detect in a BGR image; print its JSON line.
    void frame(const cv::Mat &bgr, const std::string &source, int index)
    {
        nlohmann::json j;
        j["source"] = source;
        j["frame"] = index;
        j["width"] = bgr.cols;
        j["height"] = bgr.rows;
        const bool resize = bgr.cols != VISION_IMAGE_WIDTH_PX || bgr.rows != VISION_IMAGE_HEIGHT_PX;
        j["resized"] = resize;
        if (resize) {
            cv::resize(bgr, small_, cv::Size(VISION_IMAGE_WIDTH_PX, VISION_IMAGE_HEIGHT_PX), 0, 0, cv::INTER_AREA);
            cv::cvtColor(small_, rgb_, cv::COLOR_BGR2RGB);
        } else {
            cv::cvtColor(bgr, rgb_, cv::COLOR_BGR2RGB);
        }
        const auto t0 = std::chrono::steady_clock::now();
        const vision_status_t st = vision_detect_rgb(det_, rgb_.ptr<uint8_t>(0), static_cast<uint32_t>(rgb_.step[0]), &res_);
        j["time_us"] = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
        if (st != VISION_OK) j["status"] = vision_status_name(st);
        j["landmarks"] = nlohmann::json::array();
        j["robots"] = nlohmann::json::array();
        for (uint16_t i = 0; i < res_.n_markers; ++i) {
            j[res_.markers[i].kind == VISION_MARKER_ROBOT ? "robots" : "landmarks"].push_back(marker_json(res_.markers[i]));
        }
        if (res_.dropped > 0) j["dropped"] = res_.dropped;
        // a line at a time (a live stream); a failure's reason kept for main
        std::cout << j.dump() << '\n';
        (void)stdout_check_flush();
        if (!annotate_.empty()) {
            const std::string stem = std::filesystem::path(source).stem().string();
            char name[64];
            std::snprintf(name, sizeof name, "%06d_", index);
            const cv::Mat cls = classes_picture(vision_detector_classes(det_), VISION_IMAGE_WIDTH_PX, VISION_IMAGE_HEIGHT_PX);
            write_rgb_checked(annotate_ + "/" + name + stem + "_detections.png", annotate(rgb_, res_));
            write_rgb_checked(annotate_ + "/" + name + stem + "_classes.png", cls);
        }
    }

private:
    vision_detector_t *det_;
    std::string annotate_;
    cv::Mat small_, rgb_;
    vision_result_t res_{};
};

}  // namespace

static int vision_main(int argc, char **argv)
{
    CLI::App app{"coslam-vision: detect landmark and robot markers in images (one JSON line per frame)"};
    std::vector<std::string> files;
    std::string lut_path, model_path, annotate_dir;
    int camera = -1, frames = 0;
    app.add_option("images", files, "PNG/JPEG files");
    app.add_option("--lut", lut_path, "colour table (default: the shipped firmware/vision/data/colour_lut.bin)");
    app.add_option("--model", model_path, "range model (default: the shipped firmware/vision/data/range_model.txt)");
    app.add_option("--annotate", annotate_dir, "write annotated images (detections, colour classes) here");
    app.add_option("--camera", camera, "live camera index (OpenCV VideoCapture) instead of files");
    app.add_option("--frames", frames, "with --camera: stop after this many frames (0: until the stream ends)");
    if (const int rc = cli::parse_usage(app, argc, argv); rc >= 0) {
        return rc; // --help 0, a bad option or value 2
    }
    if (files.empty() && camera < 0) {
        std::cerr << "coslam-vision: give image files or --camera N\n";
        return 2;
    }
    int rc = 0;
    vision_detector_t *det = nullptr;
    try {
        static vision_lut_t lut;
        vision_range_model_t model;
        load_vision_data(lut_path, model_path, &lut, &model);
        const vision_config_t cfg = vision_config_default();
        if (vision_detector_create(&det, &cfg, &lut, &model) != VISION_OK) throw std::runtime_error("cannot create the detector");
        if (!annotate_dir.empty()) std::filesystem::create_directories(annotate_dir);
        Runner run(det, annotate_dir);
        if (camera >= 0) {
            cv::VideoCapture cap(camera);
            if (!cap.isOpened()) throw std::runtime_error("cannot open camera " + std::to_string(camera));
            cap.set(cv::CAP_PROP_FRAME_WIDTH, VISION_IMAGE_WIDTH_PX);
            cap.set(cv::CAP_PROP_FRAME_HEIGHT, VISION_IMAGE_HEIGHT_PX);
            cv::Mat bgr;
            for (int i = 0; frames == 0 || i < frames; ++i) {
                if (!cap.read(bgr) || bgr.empty()) break;
                run.frame(bgr, "camera" + std::to_string(camera), i);
                // standard output lost (a pipe closed, SIGPIPE ignored): a
                // live stream would go on for ever printing nowhere; stop,
                // main says it and exits 1
                if (std::ferror(stdout)) break;
            }
        }
        for (size_t i = 0; i < files.size(); ++i) {
            std::error_code ec;
            const cv::Mat bgr = std::filesystem::is_regular_file(files[i], ec) ? cv::imread(files[i], cv::IMREAD_COLOR) : cv::Mat();
            if (bgr.empty()) {
                std::cout << nlohmann::json{{"source", files[i]}, {"frame", i}, {"error", "cannot read the image"}}.dump()
                          << '\n';
                (void)stdout_check_flush();
                rc = 1;
                continue;
            }
            run.frame(bgr, files[i], static_cast<int>(i));
        }
    } catch (const std::exception &e) {
        std::cerr << "coslam-vision: " << e.what() << std::endl;
        rc = 1;
    }
    vision_detector_destroy(det);
    return rc;
}

// exit status with standard output checked (stdout_check.h)
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-vision", vision_main(argc, argv));
}
