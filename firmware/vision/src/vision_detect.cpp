// The marker detector (vision.h): colour table -> blobs -> markers -> sightings.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <new>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "vision/vision.h"

namespace {

// A run: columns [x0, x1] of row y, one colour.
struct Run {
    uint16_t y, x0, x1;
    uint8_t colour;
};

// Statistics of one component while labelling.
struct Acc {
    uint16_t x0, y0, x1, y1;
    uint32_t area;
    double sx, sy;
    uint8_t colour;
};

// A candidate marker: blob a (top) over blob b (bottom).
struct Candidate {
    uint16_t a, b;
    double score;
};

}  // namespace

struct vision_detector {
    vision_config_t cfg{};
    vision_lut_t lut{};
    vision_range_model_t model{};
    vision_counters_t ctr{};
    bool have_frame = false;
    const uint8_t *frame = nullptr;   // RGB of the frame being detected (not owned)
    uint32_t frame_stride = 0;

    cv::Mat rgb;          // YUYV input converted here (CV_8UC3)
    cv::Mat classes;      // CV_8U class image, stride = width
    // run labelling (VISION_BLOBS_RUNS)
    std::vector<Run> runs;
    std::vector<uint32_t> parent;
    std::vector<int32_t> comp_of_root;
    std::vector<Acc> accs;
    // OpenCV labelling (VISION_BLOBS_OPENCV)
    cv::Mat mask, labels, stats, centroids;
    // blobs and pairing
    std::vector<vision_blob_t> blobs;
    std::vector<Candidate> cands;
    std::vector<uint8_t> used;
};

namespace {

uint32_t find_root(std::vector<uint32_t> &parent, uint32_t i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];  // path halving
        i = parent[i];
    }
    return i;
}

void unite(std::vector<uint32_t> &parent, uint32_t a, uint32_t b)
{
    a = find_root(parent, a);
    b = find_root(parent, b);
    if (a == b) return;
    if (a < b) {
        parent[b] = a;
    } else {
        parent[a] = b;
    }
}

// Colour classes of every pixel through the table.
void classify(vision_detector *d, const uint8_t *rgb, uint32_t stride)
{
    const uint32_t w = d->cfg.width_px, h = d->cfg.height_px;
    const uint8_t *lut = d->lut.table;
    for (uint32_t y = 0; y < h; ++y) {
        const uint8_t *src = rgb + static_cast<size_t>(y) * stride;
        uint8_t *dst = d->classes.ptr<uint8_t>(static_cast<int>(y));
        for (uint32_t x = 0; x < w; ++x, src += 3) dst[x] = lut[vision_lut_bin(src[0], src[1], src[2])];
    }
}

// One-pass run-length labelling of every colour at once (8-connected, same
// colour). Returns false if the runs overflowed (rows after that are not
// labelled). Fills d->blobs with the blobs of at least min_blob_area_px.
bool blobs_runs(vision_detector *d, vision_result_t *out, bool *blob_overflow)
{
    const uint32_t w = d->cfg.width_px, h = d->cfg.height_px;
    d->runs.clear();
    bool overflow = false;
    size_t prev_begin = 0, prev_end = 0;  // runs of the previous row
    for (uint32_t y = 0; y < h && !overflow; ++y) {
        const uint8_t *row = d->classes.ptr<uint8_t>(static_cast<int>(y));
        const size_t row_begin = d->runs.size();
        size_t j = prev_begin;
        uint32_t x = 0;
        while (x < w) {
            const uint8_t c = row[x];
            if (c == VISION_COLOUR_NONE) {
                ++x;
                continue;
            }
            const uint32_t x0 = x;
            while (x < w && row[x] == c) ++x;
            const uint32_t x1 = x - 1;
            if (d->runs.size() >= VISION_MAX_RUNS) {
                overflow = true;
                break;
            }
            const uint32_t id = static_cast<uint32_t>(d->runs.size());
            d->runs.push_back(Run{static_cast<uint16_t>(y), static_cast<uint16_t>(x0), static_cast<uint16_t>(x1), c});
            d->parent[id] = id;
            // previous-row runs touching [x0-1, x1+1]; j only moves forward
            while (j < prev_end && d->runs[j].x1 + 1u < x0) ++j;
            for (size_t k = j; k < prev_end && d->runs[k].x0 <= x1 + 1u; ++k) {
                if (d->runs[k].colour == c) unite(d->parent, id, static_cast<uint32_t>(k));
            }
        }
        prev_begin = row_begin;
        prev_end = d->runs.size();
    }
    const size_t n = d->runs.size();
    out->n_runs = static_cast<uint32_t>(n);
    // accumulate per root
    d->accs.clear();
    for (size_t i = 0; i < n; ++i) {
        const uint32_t r = find_root(d->parent, static_cast<uint32_t>(i));
        const Run &run = d->runs[i];
        const uint32_t len = static_cast<uint32_t>(run.x1 - run.x0 + 1);
        int32_t c = d->comp_of_root[r];
        if (r == i) {  // roots have the smallest index of their component: first seen here
            c = static_cast<int32_t>(d->accs.size());
            d->comp_of_root[r] = c;
            d->accs.push_back(Acc{run.x0, run.y, run.x1, run.y, 0, 0.0, 0.0, run.colour});
        }
        Acc &a = d->accs[static_cast<size_t>(c)];
        a.x0 = std::min(a.x0, run.x0);
        a.x1 = std::max(a.x1, run.x1);
        a.y0 = std::min(a.y0, run.y);
        a.y1 = std::max(a.y1, run.y);
        a.area += len;
        a.sx += 0.5 * (run.x0 + run.x1) * len;
        a.sy += static_cast<double>(run.y) * len;
    }
    d->blobs.clear();
    for (const Acc &a : d->accs) {
        if (a.area < d->cfg.min_blob_area_px) continue;
        if (d->blobs.size() >= VISION_MAX_BLOBS) {
            *blob_overflow = true;
            d->ctr.blobs_overflow++;
            continue;
        }
        d->blobs.push_back(vision_blob_t{a.colour, a.x0, a.y0, static_cast<uint16_t>(a.x1 - a.x0 + 1),
                                         static_cast<uint16_t>(a.y1 - a.y0 + 1), a.area, a.sx / a.area,
                                         a.sy / a.area});
    }
    return !overflow;
}

// The same blobs through cv::connectedComponentsWithStats, colour by colour.
void blobs_opencv(vision_detector *d, bool *blob_overflow)
{
    d->blobs.clear();
    for (uint8_t c = 1; c < VISION_N_COLOURS; ++c) {
        cv::compare(d->classes, cv::Scalar(c), d->mask, cv::CMP_EQ);
        const int n = cv::connectedComponentsWithStats(d->mask, d->labels, d->stats, d->centroids, 8, CV_32S);
        for (int i = 1; i < n; ++i) {
            const int *s = d->stats.ptr<int>(i);
            if (static_cast<uint32_t>(s[cv::CC_STAT_AREA]) < d->cfg.min_blob_area_px) continue;
            if (d->blobs.size() >= VISION_MAX_BLOBS) {
                *blob_overflow = true;
                d->ctr.blobs_overflow++;
                continue;
            }
            const double *cen = d->centroids.ptr<double>(i);
            d->blobs.push_back(vision_blob_t{c, static_cast<uint16_t>(s[cv::CC_STAT_LEFT]),
                                             static_cast<uint16_t>(s[cv::CC_STAT_TOP]),
                                             static_cast<uint16_t>(s[cv::CC_STAT_WIDTH]),
                                             static_cast<uint16_t>(s[cv::CC_STAT_HEIGHT]),
                                             static_cast<uint32_t>(s[cv::CC_STAT_AREA]), cen[0], cen[1]});
        }
    }
}

double ratio_dev(double a, double b)
{
    return std::fabs(std::log(a / b));
}

// Coverage of pixel p by a surface of colour `fg` in front of `bg`: the
// projection of p - bg on fg - bg (unclamped but for gross outliers, so that
// the noise of fully covered or empty pixels averages out).
double coverage_of(const uint8_t *p, const double fg[3], const double bg[3], double inv_norm2)
{
    double dot = 0.0;
    for (int k = 0; k < 3; ++k) dot += (p[k] - bg[k]) * (fg[k] - bg[k]);
    return std::clamp(dot * inv_norm2, -0.5, 1.5);
}

// Sub-pixel height of a marker (paper sec. 3.3's "region size", refined):
// in the central columns of the two bands, the outer edges are placed by
// the coverage of the rows around them (the sensor integrates the band over
// the pixel; the optical blur spreads that over neighbouring rows but keeps
// the sum): top edge = (y0 + 0.5) - sum of the top band's coverage of rows
// y0-2..y0, bottom edge likewise. Median over the columns. Falls back to
// the integer box height where the contrast is too low (< 10 levels).
double subpixel_height(const vision_detector *d, const vision_blob_t &a, const vision_blob_t &b, double h_int)
{
    const int H = static_cast<int>(d->cfg.height_px);
    const int y0 = a.y, yb = b.y + b.h - 1;
    if (y0 - 3 < 0 || yb + 3 >= H || d->frame == nullptr) return h_int;
    const int left = std::max(a.x, b.x), right = std::min(a.x + a.w, b.x + b.w) - 1;
    const int width = right - left + 1;
    const int c0 = left + width / 4, c1 = right - width / 4;
    const int step = std::max(1, (c1 - c0 + 1) / 16);
    double hs[32];
    int n = 0;
    const int ya = y0 + a.h / 2, yc = b.y + b.h / 2;   // band references: their middle rows
    for (int x = c0; x <= c1 && n < 32; x += step) {
        auto px = [&](int y) { return d->frame + static_cast<size_t>(y) * d->frame_stride + 3u * static_cast<size_t>(x); };
        double fg_t[3], bg_t[3], fg_b[3], bg_b[3];
        for (int k = 0; k < 3; ++k) {
            fg_t[k] = px(ya)[k];
            bg_t[k] = px(y0 - 3)[k];
            fg_b[k] = px(yc)[k];
            bg_b[k] = px(yb + 3)[k];
        }
        double nt = 0.0, nb = 0.0;
        for (int k = 0; k < 3; ++k) {
            nt += (fg_t[k] - bg_t[k]) * (fg_t[k] - bg_t[k]);
            nb += (fg_b[k] - bg_b[k]) * (fg_b[k] - bg_b[k]);
        }
        if (nt < 100.0 || nb < 100.0) continue;
        double st = 0.0, sb = 0.0;
        for (int y = y0 - 2; y <= y0; ++y) st += coverage_of(px(y), fg_t, bg_t, 1.0 / nt);
        for (int y = yb; y <= yb + 2; ++y) sb += coverage_of(px(y), fg_b, bg_b, 1.0 / nb);
        const double top = y0 + 0.5 - st, bot = yb - 0.5 + sb;
        hs[n++] = bot - top;
    }
    if (n == 0) return h_int;
    std::sort(hs, hs + n);
    const double med = (n % 2 == 1) ? hs[n / 2] : 0.5 * (hs[n / 2 - 1] + hs[n / 2]);
    return (med > 0.5 * h_int && med < 1.5 * h_int) ? med : h_int;
}

// Pair blobs into markers and turn them into sightings.
void pair_markers(vision_detector *d, vision_result_t *out)
{
    const vision_config_t &cfg = d->cfg;
    const size_t nb = d->blobs.size();
    const double log_band = std::log(cfg.band_ratio_max);
    d->cands.clear();
    for (size_t i = 0; i < nb; ++i) {
        const vision_blob_t &a = d->blobs[i];
        for (size_t k = 0; k < nb; ++k) {
            const vision_blob_t &b = d->blobs[k];
            if (k == i || b.colour == a.colour) continue;
            uint8_t idx = 0;
            const vision_marker_kind_t kind = vision_pair_lookup(a.colour, b.colour, &idx);
            if (kind == VISION_MARKER_NONE) continue;
            const double ha = a.h, hb = b.h;
            const double gap = static_cast<double>(b.y) - static_cast<double>(a.y + a.h);
            const double allow = cfg.max_gap_px + cfg.max_gap_rel * std::min(ha, hb);
            if (gap > allow || gap < -allow) continue;
            const double left = std::max(a.x, b.x), right = std::min(a.x + a.w, b.x + b.w);
            if (right - left < cfg.min_overlap * std::min(a.w, b.w)) continue;
            const double dh = ratio_dev(ha, hb), dw = ratio_dev(a.w, b.w);
            if (dh > log_band || dw > log_band) continue;
            const double H = static_cast<double>(b.y + b.h) - a.y;
            const double W = static_cast<double>(std::max(a.x + a.w, b.x + b.w)) - std::min(a.x, b.x);
            const double hw = H / W;
            if (kind == VISION_MARKER_LANDMARK && (hw < cfg.landmark_hw_min || hw > cfg.landmark_hw_max)) continue;
            if (kind == VISION_MARKER_ROBOT && (hw < cfg.robot_hw_min || hw > cfg.robot_hw_max)) continue;
            if (H < cfg.min_height_px) continue;
            const double score = std::fabs(gap) / std::max(1.0, std::min(ha, hb)) + dh + 0.5 * dw;
            if (d->cands.size() >= d->cands.capacity()) {  // never grow: count and skip
                d->ctr.pairs_overflow++;
                continue;
            }
            d->cands.push_back(Candidate{static_cast<uint16_t>(i), static_cast<uint16_t>(k), score});
        }
    }
    std::sort(d->cands.begin(), d->cands.end(),
              [](const Candidate &p, const Candidate &q) { return p.score < q.score; });
    std::fill(d->used.begin(), d->used.begin() + static_cast<long>(nb), 0);
    const double f = cfg.focal_px;
    for (const Candidate &c : d->cands) {
        if (d->used[c.a] || d->used[c.b]) continue;
        d->used[c.a] = d->used[c.b] = 1;
        const vision_blob_t &a = d->blobs[c.a];
        const vision_blob_t &b = d->blobs[c.b];
        const uint32_t x0 = std::min(a.x, b.x), x1 = std::max(a.x + a.w, b.x + b.w);
        const uint32_t y0 = a.y, y1 = static_cast<uint32_t>(b.y + b.h);
        uint8_t idx = 0;
        const vision_marker_kind_t kind = vision_pair_lookup(a.colour, b.colour, &idx);
        const bool cut_left = x0 == 0, cut_right = x1 >= cfg.width_px;
        // rows cut: no height, no range. Sides cut: no centre, except for a
        // robot cut on one side only (below)
        if (y0 == 0 || y1 >= cfg.height_px || (cut_left && cut_right) ||
            ((cut_left || cut_right) && (kind != VISION_MARKER_ROBOT || x1 - x0 < 3u))) {
            out->rejected_border++;
            continue;
        }
        const vision_range_fit_t &fit = kind == VISION_MARKER_ROBOT ? d->model.robot : d->model.landmark;
        const double h_px = subpixel_height(d, a, b, static_cast<double>(y1 - y0));
        double u = (a.cx * a.area + b.cx * b.area) / static_cast<double>(a.area + b.area);
        double bearing = std::atan2(cfg.cx_px - u, f);
        double r = vision_range_from_height(&fit, f, h_px, bearing);
        double extra_bearing_var = 0.0;
        if (cut_left || cut_right) {
            // A robot's body is a cylinder of known radius R: its silhouette's
            // visible edge is tangent at asin(R / r) from the centre's bearing
            // (r from the height, which the cut does not change). Two
            // rounds: the range depends a little on the bearing (cos).
            const double u_edge = cut_left ? static_cast<double>(x1) - 0.5 : static_cast<double>(x0) - 0.5;
            const double b_edge = std::atan2(cfg.cx_px - u_edge, f);
            for (int it = 0; it < 2; ++it) {
                const double half = std::asin(std::min(1.0, VISION_ROBOT_MARKER_RADIUS_M / std::max(r, 0.2)));
                bearing = cut_left ? b_edge + half : b_edge - half;
                r = vision_range_from_height(&fit, f, h_px, bearing);
            }
            u = cfg.cx_px - f * std::tan(bearing);
            extra_bearing_var = (0.5 * 3.14159265358979 / 180.0) * (0.5 * 3.14159265358979 / 180.0);
            out->edge_robots++;
        }
        if (!(r >= cfg.min_range_m && r <= cfg.max_range_m)) {
            out->rejected_range++;
            continue;
        }
        vision_marker_t m;
        m.kind = kind;
        m.index = idx;
        m.range_m = r;
        m.bearing_rad = bearing;
        m.range_var_m2 = fit.range_sd_m * fit.range_sd_m + (fit.range_sd_rel * r) * (fit.range_sd_rel * r);
        m.bearing_var_rad2 = fit.bearing_sd_rad * fit.bearing_sd_rad + extra_bearing_var;
        m.u_px = u;
        m.h_px = h_px;
        m.x = static_cast<uint16_t>(x0);
        m.y = static_cast<uint16_t>(y0);
        m.w = static_cast<uint16_t>(x1 - x0);
        m.h = static_cast<uint16_t>(y1 - y0);
        m.cut_side = static_cast<uint8_t>(cut_left ? 1 : cut_right ? 2 : 0);
        if (kind == VISION_MARKER_ROBOT) {  // robot markers are unique: keep the larger
            bool replaced = false, smaller = false;
            for (uint16_t q = 0; q < out->n_markers; ++q) {
                vision_marker_t &o = out->markers[q];
                if (o.kind != VISION_MARKER_ROBOT || o.index != idx) continue;
                if (static_cast<uint32_t>(o.w) * o.h < static_cast<uint32_t>(m.w) * m.h) {
                    o = m;
                    replaced = true;
                } else {
                    smaller = true;
                }
            }
            if (replaced || smaller) {
                out->rejected_duplicate++;  // one of the two is dropped: counted
                continue;
            }
        }
        if (out->n_markers >= VISION_MAX_MARKERS) {
            out->dropped++;
            d->ctr.markers_overflow++;
            continue;
        }
        out->markers[out->n_markers++] = m;
    }
    d->ctr.markers += out->n_markers;
}

vision_status_t detect(vision_detector *d, vision_result_t *out)
{
    std::memset(out, 0, sizeof *out);
    bool runs_ok = true, blob_overflow = false;
    if (d->cfg.blobs == VISION_BLOBS_OPENCV) {
        blobs_opencv(d, &blob_overflow);
    } else {
        runs_ok = blobs_runs(d, out, &blob_overflow);
        if (!runs_ok) d->ctr.runs_overflow++;
    }
    out->n_blobs = static_cast<uint32_t>(d->blobs.size());
    const uint64_t pairs_overflow0 = d->ctr.pairs_overflow;
    pair_markers(d, out);
    const bool pairs_overflow = d->ctr.pairs_overflow != pairs_overflow0;
    d->ctr.frames++;
    d->have_frame = true;
    return (runs_ok && !blob_overflow && !pairs_overflow) ? VISION_OK : VISION_E_CAPACITY;
}

}  // namespace

extern "C" {

vision_config_t vision_config_default(void)
{
    vision_config_t c;
    c.width_px = VISION_IMAGE_WIDTH_PX;
    c.height_px = VISION_IMAGE_HEIGHT_PX;
    c.focal_px = VISION_FOCAL_PX;
    c.cx_px = VISION_CX_PX;
    c.cy_px = VISION_CY_PX;
    c.min_blob_area_px = 4;
    c.min_height_px = 6;
    c.max_gap_px = 2.0;
    c.max_gap_rel = 0.3;
    c.min_overlap = 0.5;
    c.band_ratio_max = 2.0;
    c.landmark_hw_min = 1.0;
    c.landmark_hw_max = 8.0;
    c.robot_hw_min = 0.2;
    c.robot_hw_max = 1.4;
    c.min_range_m = 0.3;
    c.max_range_m = 5.0;
    c.blobs = VISION_BLOBS_RUNS;
    return c;
}

vision_status_t vision_detector_create(vision_detector_t **out, const vision_config_t *cfg, const vision_lut_t *lut,
                                       const vision_range_model_t *model)
{
    if (out == nullptr || cfg == nullptr || lut == nullptr) return VISION_E_ARG;
    *out = nullptr;
    if (cfg->width_px == 0 || cfg->height_px == 0 || cfg->width_px > 4096 || cfg->height_px > 4096 ||
        !(cfg->focal_px > 0.0) || !(cfg->max_range_m > cfg->min_range_m) || !(cfg->band_ratio_max >= 1.0) ||
        !(cfg->landmark_hw_max > cfg->landmark_hw_min) || !(cfg->robot_hw_max > cfg->robot_hw_min) ||
        (cfg->blobs != VISION_BLOBS_RUNS && cfg->blobs != VISION_BLOBS_OPENCV)) {
        return VISION_E_ARG;
    }
    for (size_t i = 0; i < VISION_LUT_SIZE; ++i) {
        if (lut->table[i] >= VISION_N_COLOURS) return VISION_E_ARG;
    }
    try {
        auto *d = new vision_detector;
        d->cfg = *cfg;
        d->lut = *lut;
        d->model = model != nullptr ? *model : vision_range_model_pinhole();
        const int w = static_cast<int>(cfg->width_px), h = static_cast<int>(cfg->height_px);
        d->rgb.create(h, w, CV_8UC3);
        d->classes.create(h, w, CV_8U);
        d->classes.setTo(0);
        d->runs.reserve(VISION_MAX_RUNS);
        d->parent.assign(VISION_MAX_RUNS, 0);
        d->comp_of_root.assign(VISION_MAX_RUNS, -1);
        d->accs.reserve(VISION_MAX_RUNS);
        d->mask.create(h, w, CV_8U);
        d->labels.create(h, w, CV_32S);
        d->blobs.reserve(VISION_MAX_BLOBS);
        d->cands.reserve(static_cast<size_t>(VISION_MAX_PAIR_CANDIDATES));
        d->used.assign(VISION_MAX_BLOBS, 0);
        *out = d;
    } catch (const std::bad_alloc &) {
        return VISION_E_NOMEM;
    } catch (const cv::Exception &) {
        return VISION_E_NOMEM;
    }
    return VISION_OK;
}

void vision_detector_destroy(vision_detector_t *det)
{
    delete det;
}

vision_status_t vision_detect_rgb(vision_detector_t *det, const uint8_t *rgb, uint32_t stride_bytes,
                                  vision_result_t *out)
{
    if (det == nullptr || rgb == nullptr || out == nullptr || stride_bytes < 3u * det->cfg.width_px) return VISION_E_ARG;
    classify(det, rgb, stride_bytes);
    det->frame = rgb;
    det->frame_stride = stride_bytes;
    const vision_status_t st = detect(det, out);
    det->frame = nullptr;
    return st;
}

vision_status_t vision_detect_yuyv(vision_detector_t *det, const uint8_t *yuyv, uint32_t stride_bytes,
                                   vision_result_t *out)
{
    if (det == nullptr || yuyv == nullptr || out == nullptr || stride_bytes < 2u * det->cfg.width_px ||
        det->cfg.width_px % 2u != 0u) {
        return VISION_E_ARG;
    }
    const cv::Mat src(static_cast<int>(det->cfg.height_px), static_cast<int>(det->cfg.width_px), CV_8UC2,
                      const_cast<uint8_t *>(yuyv), stride_bytes);
    cv::cvtColor(src, det->rgb, cv::COLOR_YUV2RGB_YUYV);
    det->frame = det->rgb.ptr<uint8_t>(0);
    det->frame_stride = static_cast<uint32_t>(det->rgb.step[0]);
    classify(det, det->frame, det->frame_stride);
    const vision_status_t st = detect(det, out);
    det->frame = nullptr;
    return st;
}

const uint8_t *vision_detector_classes(const vision_detector_t *det)
{
    return (det != nullptr && det->have_frame) ? det->classes.ptr<uint8_t>(0) : nullptr;
}

uint32_t vision_detector_blobs(const vision_detector_t *det, const vision_blob_t **blobs)
{
    if (det == nullptr || blobs == nullptr) return 0;
    *blobs = det->blobs.data();
    return static_cast<uint32_t>(det->blobs.size());
}

const vision_counters_t *vision_detector_counters(const vision_detector_t *det)
{
    return det != nullptr ? &det->ctr : nullptr;
}

const vision_config_t *vision_detector_config(const vision_detector_t *det)
{
    return det != nullptr ? &det->cfg : nullptr;
}

}  // extern "C"
