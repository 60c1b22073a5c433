// coslam-vision-eval: the detector on rendered frames with known markers
// (vision_scenes: the paper's arena, random poses, another robot in view in
// 60 % of the frames, thin occluding posts in 40 %, light gain 0.45-1.8,
// motion blur up to 0.8 rad/s), against the renderer's ground truth.
//
// Reports (stdout, and --json):
//  - detection rate of the markers that should be found: "clear" (at least
//    95 % of the silhouette showing, both edges' rows inside the image,
//    range 0.3-5 m) and "partial" (30-95 % showing), by range and by light;
//  - false markers per frame (a detection near no true marker), identity
//    errors (a detection at a true marker of another class or robot id);
//  - range error as a fraction of the range, and bearing error, of the
//    correctly identified detections: mean, sd, median and percentiles of
//    the magnitude, landmarks and robots apart;
//  - time per frame of the detector (this process, one thread).
// --images DIR writes example figures: exampleN.png = input | colour classes
// | detections (boxes, class or robot id and range; ticks under the true
// markers), frames with a robot and at least two landmarks detected.
//
//   coslam-vision-eval [--frames N] [--seed0 S] [--lut F] [--model F] [--images DIR] [--json F]
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "checked_file.hpp"
#include "cli_checks.hpp"
#include "vision_scenes.hpp"

using namespace coslam;
using namespace coslam::vision_host;

namespace {

constexpr double kRad2Deg = 180.0 / COSLAM_PI;

struct Rate {
    int n = 0, hit = 0;
    double value() const { return n > 0 ? static_cast<double>(hit) / n : std::nan(""); }
};

nlohmann::json dist(const std::vector<double> &v)
{
    nlohmann::json j;
    j["n"] = v.size();
    if (v.empty()) return j;
    double s = 0.0, s2 = 0.0;
    std::vector<double> a;
    for (double x : v) {
        s += x;
        s2 += x * x;
        a.push_back(std::fabs(x));
    }
    const double n = static_cast<double>(v.size());
    j["mean"] = s / n;
    j["sd"] = std::sqrt(std::max(0.0, s2 / n - (s / n) * (s / n)));
    j["rms"] = std::sqrt(s2 / n);
    j["abs_median"] = quantile(a, 0.5);
    j["abs_p90"] = quantile(a, 0.9);
    j["abs_p99"] = quantile(a, 0.99);
    j["abs_max"] = quantile(a, 1.0);
    return j;
}

std::string fmt_dist(const char *name, const nlohmann::json &j, double scale, const char *unit)
{
    char b[256];
    if (j["n"].get<size_t>() == 0) {
        std::snprintf(b, sizeof b, "  %-28s n=0\n", name);
        return b;
    }
    std::snprintf(b, sizeof b, "  %-28s n=%-5zu mean %+.3f%s sd %.3f%s |e| median %.3f%s p90 %.3f%s p99 %.3f%s max %.3f%s\n",
                  name, j["n"].get<size_t>(), j["mean"].get<double>() * scale, unit, j["sd"].get<double>() * scale, unit,
                  j["abs_median"].get<double>() * scale, unit, j["abs_p90"].get<double>() * scale, unit,
                  j["abs_p99"].get<double>() * scale, unit, j["abs_max"].get<double>() * scale, unit);
    return b;
}

}  // namespace

static int vision_eval_main(int argc, char **argv)
{
    CLI::App app{"coslam-vision-eval: detection statistics on rendered frames with known markers"};
    int frames = 400;
    uint64_t seed0 = 5000;
    std::string lut_path, model_path, images, json_path, blobs = "runs";
    int n_examples = 3;
    bool verbose = false, dump = false;
    app.add_option("--frames", frames, "rendered frames")->capture_default_str()->check(coslam::cli::int_in(1, 1000000));
    app.add_option("--seed0", seed0, "scene seed of the first frame")->capture_default_str();
    app.add_option("--lut", lut_path, "colour table (default: the shipped one)");
    app.add_option("--model", model_path, "range model (default: the shipped one; 'pinhole': uncalibrated)");
    app.add_option("--images", images, "write example figures here");
    app.add_option("--examples", n_examples, "how many example figures")
        ->capture_default_str()
        ->check(coslam::cli::int_in(0, 1000000));
    app.add_option("--json", json_path, "write the statistics as JSON");
    app.add_flag("--verbose", verbose, "print every missed clear marker and every false marker");
    app.add_flag("--dump", dump, "with --images: write the figures of every frame");
    app.add_option("--blobs", blobs, "runs | opencv")->check(CLI::IsMember({"runs", "opencv"}))->capture_default_str();
    if (const int rc = coslam::cli::parse_usage(app, argc, argv); rc >= 0) return rc;

    try {
        cv::setNumThreads(1);
        static vision_lut_t lut;
        vision_range_model_t model = vision_range_model_pinhole();
        load_vision_data(lut_path, model_path == "pinhole" ? "" : model_path, &lut, model_path == "pinhole" ? nullptr : &model);
        vision_config_t cfg = vision_config_default();
        cfg.blobs = blobs == "opencv" ? VISION_BLOBS_OPENCV : VISION_BLOBS_RUNS;
        vision_detector_t *det = nullptr;
        if (vision_detector_create(&det, &cfg, &lut, &model) != VISION_OK) throw std::runtime_error("detector");
        const sim::Scenario sc = sim::load_scenario_file(paper_scenario_path());
        if (!images.empty()) std::filesystem::create_directories(images);

        Rate clear, partial, clear_lm, clear_robot;
        std::map<std::string, Rate> by_range, by_gain, by_blur;
        int false_markers = 0, id_err_lm = 0, id_err_robot = 0, n_det = 0, frames_with_fp = 0;
        std::vector<double> er_lm, eb_lm, er_rb, eb_rb, er_part, eb_part, er_cut, eb_cut, times_us;
        int examples = 0;
        vision_result_t res;
        for (int i = 0; i < frames; ++i) {
            const Scene s = make_scene(sc, seed0 + static_cast<uint64_t>(i));
            const Frame f = render_scene(s);
            const auto t0 = std::chrono::steady_clock::now();
            vision_detect_rgb(det, f.rgb.data(), 3u * VISION_IMAGE_WIDTH_PX, &res);
            times_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
            const FrameMatch fm = match_frame(res, f.truth);
            n_det += res.n_markers;
            int fp_here = 0;
            for (uint16_t k = 0; k < res.n_markers; ++k) {
                const auto &h = fm.det[k];
                const vision_marker_t &d = res.markers[k];
                if (h.truth < 0) {
                    ++fp_here;
                    continue;
                }
                const auto &t = f.truth[static_cast<size_t>(h.truth)];
                if (!h.same_identity) {
                    (t.kind == VISION_MARKER_ROBOT || d.kind == VISION_MARKER_ROBOT ? id_err_robot : id_err_lm)++;
                    continue;
                }
                const double er = (d.range_m - t.range_m) / t.range_m;
                const double eb = angle_wrap(d.bearing_rad - t.bearing_rad);
                if (d.cut_side != 0) {
                    er_cut.push_back(er);
                    eb_cut.push_back(eb);
                } else if (expected(t, 0.95)) {
                    (t.kind == VISION_MARKER_ROBOT ? er_rb : er_lm).push_back(er);
                    (t.kind == VISION_MARKER_ROBOT ? eb_rb : eb_lm).push_back(eb);
                } else {
                    er_part.push_back(er);
                    eb_part.push_back(eb);
                }
            }
            false_markers += fp_here;
            if (verbose) {
                for (uint16_t k = 0; k < res.n_markers; ++k) {
                    if (fm.det[k].truth >= 0 && fm.det[k].same_identity) continue;
                    const vision_marker_t &d = res.markers[k];
                    std::printf("%s frame %d seed %llu: %s %d r %.2f b %.1f box %d,%d %dx%d\n",
                                fm.det[k].truth < 0 ? "false" : "identity", i, static_cast<unsigned long long>(s.seed),
                                d.kind == VISION_MARKER_ROBOT ? "robot" : "landmark", d.index, d.range_m,
                                d.bearing_rad * kRad2Deg, d.x, d.y, d.w, d.h);
                }
            }
            frames_with_fp += fp_here > 0;
            const char *gb = s.gain < 0.7 ? "gain 0.45-0.7" : s.gain < 1.2 ? "gain 0.7-1.2" : "gain 1.2-1.8";
            const char *bb = std::fabs(s.w) < 0.2 ? "turn < 0.2 rad/s" : "turn 0.2-0.8 rad/s";
            for (size_t j = 0; j < f.truth.size(); ++j) {
                const auto &t = f.truth[j];
                const bool found = fm.truth_det[j] >= 0;
                if (expected(t, 0.95)) {
                    clear.n++;
                    clear.hit += found;
                    Rate &k = t.kind == VISION_MARKER_ROBOT ? clear_robot : clear_lm;
                    k.n++;
                    k.hit += found;
                    const int rb = std::min(4, static_cast<int>(t.range_m));
                    char rn[32];
                    std::snprintf(rn, sizeof rn, "range %d-%d m", rb, rb + 1);
                    by_range[rn].n++;
                    by_range[rn].hit += found;
                    by_gain[gb].n++;
                    by_gain[gb].hit += found;
                    by_blur[bb].n++;
                    by_blur[bb].hit += found;
                    if (!found && verbose) {
                        const vision_blob_t *bl = nullptr;
                        const uint32_t nb = vision_detector_blobs(det, &bl);
                        std::printf("miss frame %d seed %llu: %s %d range %.2f bearing %.1f u %.1f h %.1f visible %.2f gain %.2f w %.2f; blobs near:",
                                    i, static_cast<unsigned long long>(s.seed), t.kind == VISION_MARKER_ROBOT ? "robot" : "landmark",
                                    t.index, t.range_m, t.bearing_rad * kRad2Deg, t.u_px, t.h_px, t.visible, s.gain, s.w);
                        for (uint32_t q = 0; q < nb; ++q) {
                            if (std::fabs(bl[q].cx - t.u_px) < 0.6 * t.h_px + 3)
                                std::printf(" [c%d x%d y%d w%d h%d a%u]", bl[q].colour, bl[q].x, bl[q].y, bl[q].w, bl[q].h, bl[q].area);
                        }
                        for (uint16_t q = 0; q < res.n_markers; ++q) {
                            if (std::fabs(res.markers[q].u_px - t.u_px) < 10)
                                std::printf(" {det %d/%d r %.2f b %.1f}", res.markers[q].kind, res.markers[q].index,
                                            res.markers[q].range_m, res.markers[q].bearing_rad * kRad2Deg);
                        }
                        std::printf(" rejected border %u range %u\n", res.rejected_border, res.rejected_range);
                    }
                } else if (expected(t, 0.3)) {
                    partial.n++;
                    partial.hit += found;
                }
            }
            // examples: frames with a robot and at least two landmarks detected
            if (!images.empty() && (examples < n_examples || dump)) {
                int lm = 0, rb = 0;
                for (uint16_t k = 0; k < res.n_markers; ++k) (res.markers[k].kind == VISION_MARKER_ROBOT ? rb : lm)++;
                if ((rb >= 1 && lm >= 2) || dump) {
                    const cv::Mat rgb(VISION_IMAGE_HEIGHT_PX, VISION_IMAGE_WIDTH_PX, CV_8UC3, const_cast<uint8_t *>(f.rgb.data()));
                    const cv::Mat cls = classes_picture(vision_detector_classes(det), VISION_IMAGE_WIDTH_PX, VISION_IMAGE_HEIGHT_PX);
                    const cv::Mat ann = annotate(rgb, res, &f.truth, 1);
                    cv::Mat row;
                    cv::hconcat(std::vector<cv::Mat>{rgb, cls, ann}, row);
                    char name[128];
                    std::snprintf(name, sizeof name, "%s/example%d.png", images.c_str(), examples + 1);
                    write_rgb_checked(name, row);
                    ++examples;
                }
            }
        }
        const double nf = frames;
        nlohmann::json j;
        j["frames"] = frames;
        j["seed0"] = seed0;
        j["colour_table"] = lut.method;
        j["blobs"] = blobs;
        j["detection_rate_clear"] = clear.value();
        j["detection_rate_clear_landmarks"] = clear_lm.value();
        j["detection_rate_clear_robots"] = clear_robot.value();
        j["clear_markers"] = clear.n;
        j["detection_rate_partial"] = partial.value();
        j["partial_markers"] = partial.n;
        for (auto *m : {&by_range, &by_gain, &by_blur}) {
            for (const auto &kv : *m) j["detection_rate_by"][kv.first] = {{"n", kv.second.n}, {"rate", kv.second.value()}};
        }
        j["detections"] = n_det;
        j["false_markers"] = false_markers;
        j["false_markers_per_frame"] = false_markers / nf;
        j["frames_with_false_markers"] = frames_with_fp;
        j["landmark_class_errors"] = id_err_lm;
        j["robot_identity_errors"] = id_err_robot;
        j["range_err_rel_landmarks"] = dist(er_lm);
        j["bearing_err_rad_landmarks"] = dist(eb_lm);
        j["range_err_rel_robots"] = dist(er_rb);
        j["bearing_err_rad_robots"] = dist(eb_rb);
        j["range_err_rel_partial"] = dist(er_part);
        j["bearing_err_rad_partial"] = dist(eb_part);
        j["range_err_rel_robots_cut_by_side"] = dist(er_cut);
        j["bearing_err_rad_robots_cut_by_side"] = dist(eb_cut);
        j["time_us"] = {{"mean", [&] { double s = 0; for (double t : times_us) s += t; return s / nf; }()},
                        {"median", quantile(times_us, 0.5)},
                        {"p99", quantile(times_us, 0.99)}};

        std::printf("coslam-vision-eval: %d rendered frames (seeds %llu..), colour table '%s', blobs %s\n", frames,
                    static_cast<unsigned long long>(seed0), lut.method, blobs.c_str());
        std::printf("detection rate, clear markers: %.4f (%d/%d; landmarks %.4f of %d, robots %.4f of %d)\n", clear.value(),
                    clear.hit, clear.n, clear_lm.value(), clear_lm.n, clear_robot.value(), clear_robot.n);
        std::printf("detection rate, partly hidden (30-95 %% showing): %.4f (%d/%d)\n", partial.value(), partial.hit, partial.n);
        for (auto *m : {&by_range, &by_gain, &by_blur}) {
            for (const auto &kv : *m) std::printf("  %-22s %.4f (%d)\n", kv.first.c_str(), kv.second.value(), kv.second.n);
        }
        std::printf("false markers: %d in %d frames (%.4f per frame); landmark class errors %d; robot identity errors %d\n",
                    false_markers, frames_with_fp, false_markers / nf, id_err_lm, id_err_robot);
        std::printf("errors of the correctly identified detections (clear markers; partly hidden ones; robots cut by an image side):\n");
        std::cout << fmt_dist("landmark range / range", j["range_err_rel_landmarks"], 100.0, "%")
                  << fmt_dist("landmark bearing", j["bearing_err_rad_landmarks"], kRad2Deg, "d")
                  << fmt_dist("robot range / range", j["range_err_rel_robots"], 100.0, "%")
                  << fmt_dist("robot bearing", j["bearing_err_rad_robots"], kRad2Deg, "d")
                  << fmt_dist("partial: range / range", j["range_err_rel_partial"], 100.0, "%")
                  << fmt_dist("partial: bearing", j["bearing_err_rad_partial"], kRad2Deg, "d")
                  << fmt_dist("robots cut by a side: range", j["range_err_rel_robots_cut_by_side"], 100.0, "%")
                  << fmt_dist("robots cut by a side: bearing", j["bearing_err_rad_robots_cut_by_side"], kRad2Deg, "d");
        std::printf("detector time per frame: mean %.0f us, median %.0f us, p99 %.0f us\n", j["time_us"]["mean"].get<double>(),
                    j["time_us"]["median"].get<double>(), j["time_us"]["p99"].get<double>());
        if (!json_path.empty()) {
            std::filesystem::path p(json_path);
            if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
            coslam::cli::write_text_file(json_path, j.dump(2) + "\n");
        }
        vision_detector_destroy(det);
    } catch (const std::exception &e) {
        std::cerr << "coslam-vision-eval: " << e.what() << std::endl;
        return 1;
    }
    return 0;
}

// exit status with standard output checked (stdout_check.h)
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-vision-eval", vision_eval_main(argc, argv));
}
