#include "vision_scenes.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "checked_file.hpp"
#include "coslam/rng.h"
#include "sim/world/pixel_camera.hpp"

namespace coslam::vision_host {

namespace {

constexpr double kDeg = COSLAM_PI / 180.0;

}  // namespace

std::string paper_scenario_path()
{
    return std::string(COSLAM_SOURCE_DIR) + "/sim/scenarios/paper.toml";
}

void build_world(const sim::Scenario &sc, sim::World &world)
{
    if (!sc.world.arena.empty()) world.add_polygon(sc.world.arena);
    for (const auto &b : sc.world.boxes) world.add_box(b.center, b.size, b.angle_deg * kDeg);
    for (const auto &p : sc.world.pillars) world.add_pillar(p.center, p.radius_m);
    for (const auto &w : sc.world.walls) world.add_wall(w.from, w.to);
    for (const auto &l : sc.world.landmarks) world.add_landmark(l.pos, static_cast<uint8_t>(l.signature));
}

Scene make_scene(const sim::Scenario &sc, uint64_t seed, const SceneOptions &opt)
{
    Scene s;
    s.seed = seed;
    rng_t rng;
    rng_seed(&rng, seed * 0x9E3779B97F4A7C15ull + 17u);
    build_world(sc, s.world);
    // the arena's bounding box
    double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
    for (const auto &p : sc.world.arena) {
        x0 = std::min(x0, p.x());
        x1 = std::max(x1, p.x());
        y0 = std::min(y0, p.y());
        y1 = std::max(y1, p.y());
    }
    for (int tries = 0; tries < 1000; ++tries) {
        const Eigen::Vector2d p(x0 + (x1 - x0) * rng_uniform(&rng), y0 + (y1 - y0) * rng_uniform(&rng));
        if (s.world.static_clearance(p) < 0.35) continue;
        s.cam = pose2_t{p.x(), p.y(), angle_wrap(2.0 * COSLAM_PI * rng_uniform(&rng))};
        break;
    }
    s.self_id = static_cast<int>(rng_below(&rng, VISION_MAX_ROBOT_MARKERS));
    s.world.set_body(s.self_id, s.cam, VISION_ROBOT_MARKER_RADIUS_M);
    if (rng_uniform(&rng) < opt.p_other_robot) {
        const int other = (s.self_id + 1 + static_cast<int>(rng_below(&rng, VISION_MAX_ROBOT_MARKERS - 1))) %
                          VISION_MAX_ROBOT_MARKERS;
        for (int tries = 0; tries < 50; ++tries) {
            const double r = 0.6 + 3.9 * rng_uniform(&rng);
            const double b = (rng_uniform(&rng) - 0.5) * 56.0 * kDeg;
            const point2_t q = pose2_apply(s.cam, point2_t{r * std::cos(b), r * std::sin(b)});
            const Eigen::Vector2d pq(q.x, q.y);
            if (s.world.static_clearance(pq) < VISION_ROBOT_MARKER_RADIUS_M + 0.02) continue;
            s.world.set_body(other, pose2_t{q.x, q.y, 2.0 * COSLAM_PI * rng_uniform(&rng)}, VISION_ROBOT_MARKER_RADIUS_M);
            break;
        }
    }
    if (rng_uniform(&rng) < opt.p_posts) {
        const int n = 1 + static_cast<int>(rng_below(&rng, 3));
        for (int k = 0; k < n; ++k) {
            const double r = 0.5 + 2.5 * rng_uniform(&rng);
            const double b = (rng_uniform(&rng) - 0.5) * 50.0 * kDeg;
            const point2_t q = pose2_apply(s.cam, point2_t{r * std::cos(b), r * std::sin(b)});
            s.world.add_pillar(Eigen::Vector2d(q.x, q.y), 0.03 + 0.12 * rng_uniform(&rng));
        }
    }
    const bool turning = rng_uniform(&rng) < 0.5;
    s.w = turning ? (2.0 * rng_uniform(&rng) - 1.0) * opt.max_turn_rps : 0.0;
    const double v = opt.max_speed_mps * rng_uniform(&rng), vd = 2.0 * COSLAM_PI * rng_uniform(&rng);
    s.vx = v * std::cos(vd);
    s.vy = v * std::sin(vd);
    s.gain = std::exp(std::log(opt.gain_min) + (std::log(opt.gain_max) - std::log(opt.gain_min)) * rng_uniform(&rng));
    return s;
}

Frame render_scene(const Scene &s, const sim::CameraRendererConfig &base)
{
    sim::CameraRendererConfig cfg = base;
    cfg.seed = s.seed;
    sim::CameraRenderer r(s.world, cfg);
    Frame f;
    f.rgb.assign(static_cast<size_t>(cfg.width_px) * cfg.height_px * 3u, 0);
    f.labels.assign(static_cast<size_t>(cfg.width_px) * cfg.height_px, 0);
    r.set_next_gain(s.gain);
    r.render(s.cam, s.vx, s.vy, s.w, s.self_id, f.rgb.data(), f.labels.data(), &f.truth);
    f.gain = r.last_gain();
    return f;
}

bool expected(const sim::RenderedMarker &m, double min_visible, double min_range_m, double max_range_m)
{
    if (min_visible >= 0.95 && (m.u_min < 2.0 || m.u_max > VISION_IMAGE_WIDTH_PX - 3.0)) return false;
    return m.whole_rows && m.visible >= min_visible && m.range_m >= min_range_m && m.range_m <= max_range_m;
}

FrameMatch match_frame(const vision_result_t &res, const std::vector<sim::RenderedMarker> &truth)
{
    FrameMatch fm;
    fm.det.assign(res.n_markers, FrameMatch::Hit{});
    fm.truth_det.assign(truth.size(), -1);
    auto close = [](const vision_marker_t &d, const sim::RenderedMarker &t) {
        return std::fabs(angle_wrap(d.bearing_rad - t.bearing_rad)) < std::max(3.0 * kDeg, t.half_width_rad + kDeg) &&
               std::fabs(d.range_m - t.range_m) < 0.3 * t.range_m;
    };
    // same identity first, nearest in bearing
    for (uint16_t i = 0; i < res.n_markers; ++i) {
        const vision_marker_t &d = res.markers[i];
        int best = -1;
        double best_b = 1e9;
        for (size_t j = 0; j < truth.size(); ++j) {
            const auto &t = truth[j];
            if (t.kind != d.kind || t.index != d.index || fm.truth_det[j] >= 0 || !close(d, t)) continue;
            const double eb = std::fabs(angle_wrap(d.bearing_rad - t.bearing_rad));
            if (eb < best_b) {
                best_b = eb;
                best = static_cast<int>(j);
            }
        }
        if (best >= 0) {
            fm.det[i] = FrameMatch::Hit{best, true};
            fm.truth_det[static_cast<size_t>(best)] = i;
        }
    }
    for (uint16_t i = 0; i < res.n_markers; ++i) {
        if (fm.det[i].truth >= 0) continue;
        for (size_t j = 0; j < truth.size(); ++j) {
            if (close(res.markers[i], truth[j])) {
                fm.det[i] = FrameMatch::Hit{static_cast<int>(j), false};
                break;
            }
        }
    }
    return fm;
}

cv::Scalar class_bgr(uint8_t c)
{
    switch (c) {
    case VISION_COLOUR_RED: return cv::Scalar(40, 40, 220);
    case VISION_COLOUR_YELLOW: return cv::Scalar(30, 220, 240);
    case VISION_COLOUR_GREEN: return cv::Scalar(60, 180, 40);
    case VISION_COLOUR_BLUE: return cv::Scalar(220, 80, 30);
    default: return cv::Scalar(40, 40, 40);
    }
}

cv::Mat classes_picture(const uint8_t *classes, int w, int h)
{
    cv::Mat out(h, w, CV_8UC3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const cv::Scalar b = class_bgr(classes[static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x)]);
            out.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(b[2]), static_cast<uint8_t>(b[1]), static_cast<uint8_t>(b[0]));
        }
    }
    return out;
}

cv::Mat annotate(const cv::Mat &rgb, const vision_result_t &res, const std::vector<sim::RenderedMarker> *truth, int scale)
{
    cv::Mat bgr;
    cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
    cv::Mat big;
    cv::resize(bgr, big, cv::Size(), scale, scale, cv::INTER_NEAREST);
    const int s = scale;
    if (truth != nullptr) {
        for (const auto &t : *truth) {
            if (!expected(t, 0.3)) continue;
            const int u = static_cast<int>(std::lround(s * t.u_px));
            cv::line(big, cv::Point(u, big.rows - 6 * s), cv::Point(u, big.rows - 1), cv::Scalar(255, 255, 255), 1);
        }
    }
    const double font = s == 1 ? 0.6 : 0.9;
    for (uint16_t i = 0; i < res.n_markers; ++i) {
        const vision_marker_t &m = res.markers[i];
        const cv::Scalar col = m.kind == VISION_MARKER_ROBOT ? cv::Scalar(255, 0, 255) : cv::Scalar(0, 255, 255);
        cv::rectangle(big, cv::Rect(s * m.x - 1, s * m.y - 1, s * m.w + 2, s * m.h + 2), col, 1);
        char txt[64];
        if (s == 1) {
            std::snprintf(txt, sizeof txt, "%s%d %.1fm", m.kind == VISION_MARKER_ROBOT ? "R" : "L", m.index, m.range_m);
        } else {
            std::snprintf(txt, sizeof txt, "%s%d %.2fm %.1fd", m.kind == VISION_MARKER_ROBOT ? "R" : "L", m.index,
                          m.range_m, m.bearing_rad * 180.0 / COSLAM_PI);
        }
        const int ty = s * m.y - 3 > 8 * s ? s * m.y - 3 : s * (m.y + m.h) + 10 * s;
        const cv::Point at(std::max(0, s * m.x - 4 * s), ty);
        cv::putText(big, txt, at, cv::FONT_HERSHEY_PLAIN, font, cv::Scalar(0, 0, 0), 3);
        cv::putText(big, txt, at, cv::FONT_HERSHEY_PLAIN, font, col, 1);
    }
    cv::Mat out;
    cv::cvtColor(big, out, cv::COLOR_BGR2RGB);
    return out;
}

void write_rgb_checked(const std::string &path, const cv::Mat &rgb)
{
    cv::Mat bgr;
    cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
    // encoded in memory, then written as a checked file: cv::imwrite gives
    // no reason for a failed write, and may not notice a full disk
    const std::string ext = std::filesystem::path(path).extension().string();
    std::vector<uchar> bytes;
    bool encoded = false;
    try {
        encoded = cv::imencode(ext, bgr, bytes, {cv::IMWRITE_PNG_COMPRESSION, 9});
    } catch (const cv::Exception &) {
        encoded = false;
    }
    if (!encoded) {
        throw std::runtime_error("cannot write " + path + ": no image encoder for '" + ext + "' (use .png or .jpg)");
    }
    std::ofstream f = cli::open_checked(path);
    f.write(reinterpret_cast<const char *>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    cli::close_checked(f, path);
}

bool write_rgb(const std::string &path, const cv::Mat &rgb)
{
    try {
        write_rgb_checked(path, rgb);
        return true;
    } catch (const std::exception &) {
        return false;
    }
}

void load_vision_data(const std::string &lut_path, const std::string &model_path, vision_lut_t *lut,
                      vision_range_model_t *model)
{
    const std::string lp = lut_path.empty() ? sim::default_vision_lut_path() : lut_path;
    const std::string mp = model_path.empty() ? sim::default_vision_model_path() : model_path;
    vision_status_t st = vision_lut_load(lut, lp.c_str());
    if (st != VISION_OK) throw std::runtime_error("colour table " + lp + ": " + vision_status_name(st));
    if (model != nullptr) {
        st = vision_range_model_load(model, mp.c_str());
        if (st != VISION_OK) throw std::runtime_error("range model " + mp + ": " + vision_status_name(st));
    }
}

std::vector<uint8_t> rgb_to_yuyv(const uint8_t *rgb, int w, int h)
{
    std::vector<uint8_t> out(static_cast<size_t>(w) * static_cast<size_t>(h) * 2u);
    auto clamp8 = [](double v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); };
    for (size_t p = 0; p + 1 < static_cast<size_t>(w) * static_cast<size_t>(h); p += 2) {
        double cb = 0.0, cr = 0.0;
        for (size_t q = 0; q < 2; ++q) {
            const double r = rgb[3 * (p + q)], g = rgb[3 * (p + q) + 1], b = rgb[3 * (p + q) + 2];
            out[2 * (p + q)] = clamp8(16.0 + 0.257 * r + 0.504 * g + 0.098 * b);
            cb += 128.0 - 0.148 * r - 0.291 * g + 0.439 * b;
            cr += 128.0 + 0.439 * r - 0.368 * g - 0.071 * b;
        }
        out[2 * p + 1] = clamp8(cb / 2.0);
        out[2 * p + 3] = clamp8(cr / 2.0);
    }
    return out;
}

double quantile(std::vector<double> v, double q)
{
    if (v.empty()) return std::nan("");
    std::sort(v.begin(), v.end());
    const double pos = q * static_cast<double>(v.size() - 1);
    const size_t i = static_cast<size_t>(pos);
    const double fr = pos - static_cast<double>(i);
    return i + 1 < v.size() ? v[i] * (1.0 - fr) + v[i + 1] * fr : v[i];
}

}  // namespace coslam::vision_host
