#include "sim/world/camera_renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace coslam::sim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kTwoPi = 2.0 * COSLAM_PI;
constexpr int kMaxLayers = 24;
constexpr float kFloorShade = 0.85f;

std::array<float, 3> lin3(int r, int g, int b)
{
    return {srgb_to_linear(static_cast<float>(r) / 255.0f), srgb_to_linear(static_cast<float>(g) / 255.0f),
            srgb_to_linear(static_cast<float>(b) / 255.0f)};
}

double cross2(double ax, double ay, double bx, double by)
{
    return ax * by - ay * bx;
}

// Ray o + t d (|d| = 1) against segment [a, b]: t >= 0 or inf.
double ray_segment(double ox, double oy, double dx, double dy, const WallSegment &s)
{
    const double ex = s.b.x() - s.a.x(), ey = s.b.y() - s.a.y();
    const double den = cross2(dx, dy, ex, ey);
    if (std::fabs(den) < 1e-15) return kInf;
    const double wx = s.a.x() - ox, wy = s.a.y() - oy;
    const double t = cross2(wx, wy, ex, ey) / den;
    const double u = cross2(wx, wy, dx, dy) / den;
    if (t < 0.0 || u < 0.0 || u > 1.0) return kInf;
    return t;
}

// First crossing of a circle's rim with t > 0 from outside; inf if none or
// if the origin is inside (the camera inside its own body sees out).
double ray_circle(double ox, double oy, double dx, double dy, double cx, double cy, double r)
{
    const double px = ox - cx, py = oy - cy;
    const double b = px * dx + py * dy;
    const double c = px * px + py * py - r * r;
    if (c <= 0.0) return kInf;
    const double disc = b * b - c;
    if (disc < 0.0) return kInf;
    const double t = -b - std::sqrt(disc);
    return t > 0.0 ? t : kInf;
}

// Vertical pixel coverage of rows [v - 0.5, v + 0.5] by the interval [top, bot].
inline float coverage(double v, double top, double bot)
{
    const double a = std::max(v - 0.5, top), b = std::min(v + 0.5, bot);
    return b > a ? static_cast<float>(b - a) : 0.0f;
}

}  // namespace

float srgb_to_linear(float v)
{
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float lin)
{
    if (lin <= 0.0f) return 0.0f;
    if (lin >= 1.0f) return 1.0f;
    return lin <= 0.0031308f ? 12.92f * lin : 1.055f * std::pow(lin, 1.0f / 2.4f) - 0.055f;
}

struct CameraRenderer::Layer {
    double t;           // horizontal distance
    int marker;         // index into the truth markers (landmarks first, then bodies)
    bool robot;
    int colour_top, colour_bottom;
    float albedo;       // paper factor
    float shade;        // light on this point of the cylinder, with the illumination field
};

CameraRenderer::CameraRenderer(const World &world, const CameraRendererConfig &cfg) : world_(world), cfg_(cfg)
{
    rng_seed(&rng_, cfg.seed);
    for (int c = 1; c < VISION_N_COLOURS; ++c) {
        colour_lin_[static_cast<size_t>(c)] =
            lin3(vision_colour_srgb[c][0], vision_colour_srgb[c][1], vision_colour_srgb[c][2]);
    }
    light_dir_ = kTwoPi * rng_uniform(&rng_);
    for (double &p : field_phase_) p = kTwoPi * rng_uniform(&rng_);
    const double amin = cfg.marker_albedo_min, amax = cfg.marker_albedo_max;
    for (float &a : robot_albedo_) a = static_cast<float>(amin + (amax - amin) * rng_uniform(&rng_));
    update_world_properties();
    // posters: flat patches on walls, half of them in a marker colour
    static const int kPosterOther[][3] = {{230, 120, 30}, {40, 170, 190}, {120, 50, 150}, {230, 120, 170},
                                          {120, 70, 40},  {240, 240, 235}, {30, 30, 35}};
    for (size_t i = 0; i < world.walls().size(); ++i) {
        const WallSegment &s = world.walls()[i];
        const double len = (s.b - s.a).norm();
        const double expect = len * cfg.posters_per_m;
        int n = static_cast<int>(expect);
        if (rng_uniform(&rng_) < expect - n) ++n;
        for (int k = 0; k < n; ++k) {
            Poster p;
            p.segment = static_cast<int>(i);
            const double w = 0.08 + 0.3 * rng_uniform(&rng_);
            const double c = w / 2 + (len - w) * rng_uniform(&rng_);
            p.s0 = c - w / 2;
            p.s1 = c + w / 2;
            p.z0 = 0.05 + 0.6 * rng_uniform(&rng_);
            p.z1 = p.z0 + 0.05 + 0.3 * rng_uniform(&rng_);
            if (rng_uniform(&rng_) < 0.5) {
                const int col = 1 + static_cast<int>(rng_below(&rng_, VISION_N_COLOURS - 1));
                p.albedo = colour_lin_[static_cast<size_t>(col)];
                p.label = static_cast<uint8_t>(col);
            } else {
                const int *o = kPosterOther[rng_below(&rng_, sizeof kPosterOther / sizeof kPosterOther[0])];
                p.albedo = lin3(o[0], o[1], o[2]);
                p.label = VISION_COLOUR_NONE;
            }
            // keep clear of markers: a poster beside a band would merge with it
            bool clear = w <= len;
            const Eigen::Vector2d dir = (s.b - s.a) / len;
            for (const auto &lm : world.landmarks()) {
                const double along = (lm.p - s.a).dot(dir);
                const double off = std::fabs(cross2(dir.x(), dir.y(), lm.p.x() - s.a.x(), lm.p.y() - s.a.y()));
                if (off < 0.3 && along > p.s0 - 0.35 && along < p.s1 + 0.35) clear = false;
            }
            if (clear) posters_.push_back(p);
        }
    }
    for (float &g : gauss_) g = static_cast<float>(rng_gauss(&rng_));
    for (size_t i = 0; i < sin_table_.size(); ++i) {
        sin_table_[i] = static_cast<float>(std::sin(kTwoPi * static_cast<double>(i) / static_cast<double>(sin_table_.size() - 1)));
    }
    acc_.assign(static_cast<size_t>(cfg.width_px) * cfg.height_px * 3u, 0.0f);
    blurred_.assign(acc_.size(), 0.0f);
}

void CameraRenderer::update_world_properties()
{
    // Walls and landmarks may be added after construction: each one's paint
    // and paper factor is a function of (seed, its index), not of the order
    // things were added or rendered.
    static const int kWallPaints[][3] = {{205, 200, 190}, {185, 185, 180}, {170, 160, 140},
                                         {150, 155, 165}, {165, 135, 95},  {195, 190, 175}};
    constexpr uint32_t kNPaints = sizeof kWallPaints / sizeof kWallPaints[0];
    auto stream = [this](uint64_t kind, size_t i) {
        rng_t r;
        rng_seed(&r, cfg_.seed * 0x9E3779B97F4A7C15ull + kind * 0xBF58476D1CE4E5B9ull + static_cast<uint64_t>(i) + 1u);
        return r;
    };
    while (wall_albedo_.size() < world_.walls().size()) {
        rng_t r = stream(1, wall_albedo_.size());
        const int *p = kWallPaints[rng_below(&r, kNPaints)];
        wall_albedo_.push_back(lin3(p[0], p[1], p[2]));
    }
    const double amin = cfg_.marker_albedo_min, amax = cfg_.marker_albedo_max;
    while (landmark_albedo_.size() < world_.landmarks().size()) {
        rng_t r = stream(2, landmark_albedo_.size());
        landmark_albedo_.push_back(static_cast<float>(amin + (amax - amin) * rng_uniform(&r)));
    }
}

double CameraRenderer::illumination(double x, double y) const
{
    // 1 + var sin(2 pi x / 7 m + p0) sin(2 pi y / 5 m + p1), sines from a table
    auto sin_turns = [this](double turns) {
        const double t = turns - std::floor(turns);
        return static_cast<double>(sin_table_[static_cast<size_t>(t * static_cast<double>(sin_table_.size() - 1))]);
    };
    return 1.0 + cfg_.illumination_var * sin_turns(x / 7.0 + field_phase_[0] / kTwoPi) *
                     sin_turns(y / 5.0 + field_phase_[1] / kTwoPi);
}

void CameraRenderer::render(const pose2_t &pose, double vx, double vy, double w, int self_body, uint8_t *rgb,
                            uint8_t *labels, std::vector<RenderedMarker> *truth)
{
    const uint32_t W = cfg_.width_px, H = cfg_.height_px;
    const double f = cfg_.focal_px;
    update_world_properties();
    // per-frame randomness (always drawn in the same order: reproducible)
    const double g_draw = std::exp(std::log(cfg_.gain_min) +
                                   (std::log(cfg_.gain_max) - std::log(cfg_.gain_min)) * rng_uniform(&rng_));
    gain_ = forced_gain_ > 0.0 ? forced_gain_ : g_draw;
    forced_gain_ = 0.0;
    wb_[0] = 1.0 + rng_normal(&rng_, 0.0, cfg_.white_balance_sd);
    wb_[1] = 1.0;
    wb_[2] = 1.0 + rng_normal(&rng_, 0.0, cfg_.white_balance_sd);
    const double pitch = rng_normal(&rng_, 0.0, cfg_.pitch_jitter_deg) * COSLAM_PI / 180.0;
    const double cy = cfg_.cy_px + f * std::tan(pitch);
    uint64_t noise_state = rng_next_u64(&rng_) | 1u;

    // the view at mid-exposure (the exposure [-T, 0] ends at `pose`)
    const double T = cfg_.exposure_ms * 1e-3;
    const pose2_t mid = pose2_compose(pose, pose2_t{-vx * T / 2, -vy * T / 2, -w * T / 2});
    std::fill(acc_.begin(), acc_.end(), 0.0f);
    const size_t n_markers = world_.landmarks().size() + world_.bodies().size();
    std::vector<int> vis(n_markers, 0);
    render_subframe(mid, cy, self_body, 1.0f / static_cast<float>(cfg_.subcolumns), true, labels, &vis);

    // motion blur: during the exposure the image slides sideways by the turn
    // (w T f pixels) plus the sideways motion seen at 2 m (vy T f / 2): a
    // horizontal box of that length (fractional ends). The forward motion's
    // radial blur (< 1.5 px at the image edge, 0.3 m/s, markers beyond 1 m)
    // is left out.
    const cv::Mat acc(static_cast<int>(H), static_cast<int>(W), CV_32FC3, acc_.data());
    cv::Mat blurred(static_cast<int>(H), static_cast<int>(W), CV_32FC3, blurred_.data());
    const double slide = std::fabs(w * T * f + vy * T * f / 2.0);
    if (slide > 0.05) {
        const int half = static_cast<int>(std::ceil(slide / 2.0 - 0.5));
        cv::Mat k(1, 2 * half + 1, CV_32F);
        for (int i = -half; i <= half; ++i) {
            // overlap of pixel [i - 0.5, i + 0.5] with [-slide/2, slide/2]
            const double a = std::max(i - 0.5, -slide / 2), b = std::min(i + 0.5, slide / 2);
            k.at<float>(0, i + half) = static_cast<float>(std::max(0.0, b - a) / slide);
        }
        cv::filter2D(acc, motion_, -1, k, cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
    } else {
        acc.copyTo(motion_);
    }
    // optics
    if (cfg_.optical_blur_px > 0.0) {
        cv::GaussianBlur(motion_, blurred, cv::Size(0, 0), cfg_.optical_blur_px, cfg_.optical_blur_px, cv::BORDER_REPLICATE);
    } else {
        motion_.copyTo(blurred);
    }
    // exposure, sRGB, sensor noise, quantisation
    static std::array<float, 4097> srgb_lut = [] {
        std::array<float, 4097> t{};
        for (size_t i = 0; i < t.size(); ++i) t[i] = 255.0f * linear_to_srgb(static_cast<float>(i) / 4096.0f);
        return t;
    }();
    const double rmax2 = cfg_.cx_px * cfg_.cx_px + cfg_.cy_px * cfg_.cy_px;
    std::array<float, 257> sd_of{};  // noise sd per signal level
    for (size_t i = 0; i < sd_of.size(); ++i) {
        sd_of[i] = static_cast<float>(std::sqrt(cfg_.read_noise_dn * cfg_.read_noise_dn + cfg_.shot_noise_dn * static_cast<double>(i)));
    }
    if (vignette_.size() != static_cast<size_t>(W) * H) {
        vignette_.resize(static_cast<size_t>(W) * H);
        for (uint32_t v = 0; v < H; ++v) {
            for (uint32_t u = 0; u < W; ++u) {
                const double dx = u - cfg_.cx_px, dy = v - cfg_.cy_px;
                vignette_[static_cast<size_t>(v) * W + u] = static_cast<float>(1.0 - cfg_.vignetting * (dx * dx + dy * dy) / rmax2);
            }
        }
    }
    const float gc[3] = {static_cast<float>(gain_ * wb_[0] * 4096.0), static_cast<float>(gain_ * wb_[1] * 4096.0),
                         static_cast<float>(gain_ * wb_[2] * 4096.0)};
    for (uint32_t v = 0; v < H; ++v) {
        for (uint32_t u = 0; u < W; ++u) {
            const float vig = vignette_[static_cast<size_t>(v) * W + u];
            const size_t i = (static_cast<size_t>(v) * W + u) * 3u;
            for (int c = 0; c < 3; ++c) {
                const float x = std::min(std::max(blurred_[i + static_cast<size_t>(c)] * gc[c] * vig, 0.0f), 4096.0f);
                const float s = srgb_lut[static_cast<size_t>(x)];
                noise_state ^= noise_state << 13;
                noise_state ^= noise_state >> 7;
                noise_state ^= noise_state << 17;
                const float val = s + sd_of[static_cast<size_t>(s)] * gauss_[noise_state & 4095u] + 0.5f;
                rgb[i + static_cast<size_t>(c)] = static_cast<uint8_t>(std::min(std::max(val, 0.0f), 255.0f));
            }
        }
    }

    if (truth != nullptr) {
        truth->clear();
        const size_t nl = world_.landmarks().size();
        for (size_t m = 0; m < n_markers; ++m) {
            RenderedMarker r;
            Eigen::Vector2d p;
            double R;
            if (m < nl) {
                const auto &lm = world_.landmarks()[m];
                if (lm.signature >= VISION_N_LANDMARK_CLASSES) continue;
                p = lm.p;
                R = VISION_LANDMARK_RADIUS_M;
                r.kind = VISION_MARKER_LANDMARK;
                r.index = lm.signature;
                r.landmark_id = lm.id;
            } else {
                const auto &b = world_.bodies()[m - nl];
                if (b.id == self_body || b.id < 0 || b.id >= VISION_MAX_ROBOT_MARKERS) continue;
                p = Eigen::Vector2d(b.pose.x, b.pose.y);
                R = b.radius_m;
                r.kind = VISION_MARKER_ROBOT;
                r.index = b.id;
            }
            const point2_t rel = pose2_apply_inverse(mid, point2_t{p.x(), p.y()});
            if (rel.x <= R + 0.05 || std::hypot(rel.x, rel.y) > 12.0) continue;
            r.range_m = std::hypot(rel.x, rel.y);
            r.bearing_rad = std::atan2(rel.y, rel.x);
            r.u_px = cfg_.cx_px - f * rel.y / rel.x;
            const double near = rel.x - R;
            r.h_px = f * VISION_MARKER_HEIGHT_M / near;
            const double v_top = cy + (cfg_.camera_height_m - (VISION_MARKER_BOTTOM_M + VISION_MARKER_HEIGHT_M)) * f / near;
            const double v_bot = cy + (cfg_.camera_height_m - VISION_MARKER_BOTTOM_M) * f / near;
            r.whole_rows = v_top >= 0.0 && v_bot <= static_cast<double>(H) - 1.0;
            // silhouette in sub-columns, inside the image or not
            const double a = std::asin(std::min(1.0, R / r.range_m));
            const double b0 = r.bearing_rad - a, b1 = r.bearing_rad + a;
            r.half_width_rad = a;
            double cols = 0.0;
            r.u_min = -1e9;
            r.u_max = 1e9;
            if (b1 < COSLAM_PI / 2 && b0 > -COSLAM_PI / 2) {
                cols = (std::tan(b1) - std::tan(b0)) * f * cfg_.subcolumns;
                r.u_min = cfg_.cx_px - f * std::tan(b1);
                r.u_max = cfg_.cx_px - f * std::tan(b0);
            }
            r.visible = cols > 0.0 ? std::min(1.0, vis[m] / cols) : 0.0;
            truth->push_back(r);
        }
    }
}

void CameraRenderer::render_subframe(const pose2_t &cam, double cy, int self_body, float weight, bool want_labels,
                                     uint8_t *labels, std::vector<int> *vis_cols)
{
    const uint32_t W = cfg_.width_px, H = cfg_.height_px;
    const int S = cfg_.subcolumns;
    const double f = cfg_.focal_px, hc = cfg_.camera_height_m;
    const double cth = std::cos(cam.theta), sth = std::sin(cam.theta);
    const double lx = std::cos(light_dir_), ly = std::sin(light_dir_);
    const float amb = static_cast<float>(cfg_.ambient);
    const auto &walls = world_.walls();
    const auto &pillars = world_.pillars();
    const auto &lms = world_.landmarks();
    const auto &bodies = world_.bodies();
    const size_t nl = lms.size();
    static const std::array<float, 3> kPillar = lin3(140, 140, 140);
    static const std::array<float, 3> kSkirting = lin3(80, 75, 70);
    static const std::array<float, 3> kFloorA = lin3(105, 103, 100);
    static const std::array<float, 3> kFloorB = lin3(125, 122, 118);
    static const std::array<float, 3> kBody = lin3(60, 62, 66);
    static const std::array<float, 3> kSky = lin3(60, 60, 60);
    Layer layers[kMaxLayers];
    std::vector<double> inv_dv(H);
    for (uint32_t v = 0; v < H; ++v) inv_dv[v] = static_cast<double>(v) > cy ? 1.0 / (static_cast<double>(v) - cy) : 0.0;

    for (uint32_t j = 0; j < W * static_cast<uint32_t>(S); ++j) {
        const uint32_t px = j / static_cast<uint32_t>(S);
        const double u = static_cast<double>(px) - 0.5 + (static_cast<double>(j % static_cast<uint32_t>(S)) + 0.5) / S;
        const double cxr = f, cyr = cfg_.cx_px - u;
        const double L = std::hypot(cxr, cyr);
        const double dx = (cth * cxr - sth * cyr) / L, dy = (sth * cxr + cth * cyr) / L;
        const double ox = cam.x, oy = cam.y;
        // the wall or pillar that ends the ray
        double tw = kInf;
        int seg = -1, pil = -1;
        for (size_t i = 0; i < walls.size(); ++i) {
            const double t = ray_segment(ox, oy, dx, dy, walls[i]);
            if (t < tw) {
                tw = t;
                seg = static_cast<int>(i);
            }
        }
        for (size_t i = 0; i < pillars.size(); ++i) {
            const double t = ray_circle(ox, oy, dx, dy, pillars[i].c.x(), pillars[i].c.y(), pillars[i].r);
            if (t < tw) {
                tw = t;
                pil = static_cast<int>(i);
                seg = -1;
            }
        }
        // layers in front of it
        int nlay = 0;
        auto add_layer = [&](double t, int marker, bool robot, double ccx, double ccy, double R, int top, int bot,
                             float albedo) {
            if (nlay >= kMaxLayers) return;
            const double hx = ox + t * dx, hy = oy + t * dy;
            const double nx = (hx - ccx) / R, ny = (hy - ccy) / R;
            const float lam = static_cast<float>(std::max(0.0, nx * lx + ny * ly));
            const float shade = (amb + (1.0f - amb) * lam) * static_cast<float>(illumination(hx, hy));
            layers[nlay++] = Layer{t, marker, robot, top, bot, albedo, shade};
        };
        for (size_t i = 0; i < lms.size(); ++i) {
            const auto &lm = lms[i];
            const double t = ray_circle(ox, oy, dx, dy, lm.p.x(), lm.p.y(), VISION_LANDMARK_RADIUS_M);
            if (t >= tw) continue;
            int top = VISION_COLOUR_NONE, bot = VISION_COLOUR_NONE;
            if (lm.signature < VISION_N_LANDMARK_CLASSES) {
                top = vision_landmark_pairs[lm.signature].top;
                bot = vision_landmark_pairs[lm.signature].bottom;
            }
            add_layer(t, static_cast<int>(i), false, lm.p.x(), lm.p.y(), VISION_LANDMARK_RADIUS_M, top, bot,
                      landmark_albedo_[i]);
        }
        for (size_t i = 0; i < bodies.size(); ++i) {
            const auto &b = bodies[i];
            if (b.id == self_body) continue;
            const double t = ray_circle(ox, oy, dx, dy, b.pose.x, b.pose.y, b.radius_m);
            if (t >= tw) continue;
            int top = VISION_COLOUR_NONE, bot = VISION_COLOUR_NONE;
            if (b.id >= 0 && b.id < VISION_MAX_ROBOT_MARKERS) {
                top = vision_robot_pairs[b.id].top;
                bot = vision_robot_pairs[b.id].bottom;
            }
            add_layer(t, static_cast<int>(nl + i), true, b.pose.x, b.pose.y, b.radius_m, top, bot,
                      robot_albedo_[static_cast<size_t>(b.id) & 15u]);
        }
        std::sort(layers, layers + nlay, [](const Layer &a, const Layer &b) { return a.t > b.t; });
        if (vis_cols != nullptr && nlay > 0) (*vis_cols)[static_cast<size_t>(layers[nlay - 1].marker)]++;

        // the background surface of this column
        std::array<float, 3> wall{};
        float wall_shade = 1.0f;
        double s_along = 0.0;
        const Poster *col_posters[4];
        int n_posters = 0;
        if (seg >= 0) {
            const WallSegment &ws = walls[static_cast<size_t>(seg)];
            const double ex = ws.b.x() - ws.a.x(), ey = ws.b.y() - ws.a.y();
            const double len = std::hypot(ex, ey);
            double nx = -ey / len, ny = ex / len;
            if (nx * dx + ny * dy > 0.0) {
                nx = -nx;
                ny = -ny;
            }
            const double hx = ox + tw * dx, hy = oy + tw * dy;
            s_along = std::hypot(hx - ws.a.x(), hy - ws.a.y());
            wall = wall_albedo_[static_cast<size_t>(seg)];
            const float stripe = static_cast<float>(1.0 + 0.04 * std::sin(kTwoPi * s_along / 0.25));
            for (float &c : wall) c *= stripe;
            wall_shade = (amb + (1.0f - amb) * static_cast<float>(std::max(0.0, nx * lx + ny * ly))) *
                         static_cast<float>(illumination(hx, hy));
            for (const Poster &p : posters_) {
                if (p.segment == seg && s_along >= p.s0 && s_along <= p.s1 && n_posters < 4) col_posters[n_posters++] = &p;
            }
        } else if (pil >= 0) {
            const Pillar &pl = pillars[static_cast<size_t>(pil)];
            const double hx = ox + tw * dx, hy = oy + tw * dy;
            const double nx = (hx - pl.c.x()) / pl.r, ny = (hy - pl.c.y()) / pl.r;
            wall = kPillar;
            wall_shade = (amb + (1.0f - amb) * static_cast<float>(std::max(0.0, nx * lx + ny * ly))) *
                         static_cast<float>(illumination(hx, hy));
        } else {
            wall = kSky;
        }
        const bool label_col = want_labels && labels != nullptr && (j % static_cast<uint32_t>(S)) == 0u;

        for (uint32_t v = 0; v < H; ++v) {
            const double vd = static_cast<double>(v);
            float c[3];
            uint8_t lab = VISION_COLOUR_NONE;
            // floor or wall at the pixel centre
            // the pixel's ray (f, cx - u, cy - v) drops (v - cy) per L of horizontal travel
            const double t_floor = vd > cy ? hc * L * inv_dv[v] : kInf;
            if (t_floor < tw) {
                const double fx = ox + t_floor * dx, fy = oy + t_floor * dy;
                // 0.5 m tiles (offset keeps the integer division's sign away from the arena)
                const bool odd = (static_cast<long>(fx * 2.0 + 1000.0) + static_cast<long>(fy * 2.0 + 1000.0)) & 1L;
                const std::array<float, 3> &fa = odd ? kFloorA : kFloorB;
                const float sh = kFloorShade * static_cast<float>(illumination(fx, fy));
                for (int k = 0; k < 3; ++k) c[k] = fa[static_cast<size_t>(k)] * sh;
            } else {
                const double z = hc + tw * (cy - vd) / L;
                const std::array<float, 3> *alb = &wall;
                if (seg >= 0 && z < 0.08) alb = &kSkirting;
                for (int q = 0; q < n_posters; ++q) {
                    if (z >= col_posters[q]->z0 && z <= col_posters[q]->z1) {
                        alb = &col_posters[q]->albedo;
                        lab = col_posters[q]->label;
                    }
                }
                for (int k = 0; k < 3; ++k) c[k] = (*alb)[static_cast<size_t>(k)] * wall_shade;
            }
            // layers, far to near, with their vertical coverage
            for (int li = 0; li < nlay; ++li) {
                const Layer &lay = layers[li];
                const double sc = L / lay.t;  // rows per metre of height
                const double v_top = cy + (hc - (VISION_MARKER_BOTTOM_M + VISION_MARKER_HEIGHT_M)) * sc;
                const double v_mid = cy + (hc - (VISION_MARKER_BOTTOM_M + VISION_BAND_HEIGHT_M)) * sc;
                const double v_bot = cy + (hc - VISION_MARKER_BOTTOM_M) * sc;
                const double v_floor = lay.robot ? cy + hc * sc : v_bot;
                if (vd + 0.5 <= v_top || vd - 0.5 >= v_floor) continue;
                const float a_top = coverage(vd, v_top, v_mid);
                const float a_bot = coverage(vd, v_mid, v_bot);
                const float a_body = lay.robot ? coverage(vd, v_bot, v_floor) : 0.0f;
                const float keep = 1.0f - a_top - a_bot - a_body;
                const float sh = lay.shade * lay.albedo;
                const std::array<float, 3> &ct =
                    lay.colour_top != VISION_COLOUR_NONE ? colour_lin_[static_cast<size_t>(lay.colour_top)] : kPillar;
                const std::array<float, 3> &cb = lay.colour_bottom != VISION_COLOUR_NONE
                                                     ? colour_lin_[static_cast<size_t>(lay.colour_bottom)]
                                                     : kPillar;
                for (int k = 0; k < 3; ++k) {
                    const size_t kk = static_cast<size_t>(k);
                    c[k] = c[k] * keep + (a_top * ct[kk] + a_bot * cb[kk]) * sh + a_body * kBody[kk] * lay.shade;
                }
                if (vd >= v_top && vd < v_mid) lab = static_cast<uint8_t>(lay.colour_top);
                else if (vd >= v_mid && vd < v_bot) lab = static_cast<uint8_t>(lay.colour_bottom);
                else if (vd >= v_bot && vd < v_floor) lab = VISION_COLOUR_NONE;
            }
            float *dst = &acc_[(static_cast<size_t>(v) * W + px) * 3u];
            for (int k = 0; k < 3; ++k) dst[k] += weight * c[k];
            if (label_col) labels[static_cast<size_t>(v) * W + px] = lab;
        }
    }
}

}  // namespace coslam::sim
