#include "colour_train.hpp"

#include <algorithm>
#include <cmath>

#include "coslam/pose2.h"
#include "coslam/rng.h"

namespace coslam::vision_host {

namespace {

double bin_centre(uint32_t i)
{
    return (static_cast<double>(i) + 0.5) * static_cast<double>(1u << (8 - VISION_LUT_BITS)) - 0.5;
}

void rgb_to_hsv(double r, double g, double b, double *h, double *s, double *v)
{
    const double mx = std::max({r, g, b}), mn = std::min({r, g, b});
    *v = mx / 255.0;
    *s = mx > 0.0 ? (mx - mn) / mx : 0.0;
    double hh = 0.0;
    if (mx > mn) {
        if (mx == r) {
            hh = 60.0 * (g - b) / (mx - mn);
        } else if (mx == g) {
            hh = 60.0 * (b - r) / (mx - mn) + 120.0;
        } else {
            hh = 60.0 * (r - g) / (mx - mn) + 240.0;
        }
    }
    if (hh < 0.0) hh += 360.0;
    *h = hh;
}

double hue_dist(double a, double b)
{
    const double d = std::fabs(a - b);
    return std::min(d, 360.0 - d);
}

}  // namespace

void interior_pixels(const uint8_t *rgb, const uint8_t *labels, int w, int h, std::vector<Pixel> *out)
{
    for (int y = 1; y < h - 1; ++y) {
        for (int x = 1; x < w - 1; ++x) {
            const size_t i = static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x);
            const uint8_t l = labels[i];
            bool same = true;
            for (int dy = -1; dy <= 1 && same; ++dy) {
                for (int dx = -1; dx <= 1; ++dx) {
                    if (labels[static_cast<size_t>(static_cast<long>(i) + dy * w + dx)] != l) {
                        same = false;
                        break;
                    }
                }
            }
            if (same) out->push_back(Pixel{rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2], l});
        }
    }
}

void all_pixels(const uint8_t *rgb, const uint8_t *labels, int w, int h, std::vector<Pixel> *out)
{
    const size_t n = static_cast<size_t>(w) * static_cast<size_t>(h);
    for (size_t i = 0; i < n; ++i) out->push_back(Pixel{rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2], labels[i]});
}

double ClassScores::mean_f1() const
{
    double s = 0.0;
    for (int c = 1; c < VISION_N_COLOURS; ++c) s += f1(c);
    return s / (VISION_N_COLOURS - 1);
}

ClassScores score_lut(const vision_lut_t &lut, const std::vector<Pixel> &px)
{
    ClassScores s;
    for (const Pixel &p : px) {
        const uint8_t c = lut.table[vision_lut_bin(p.r, p.g, p.b)];
        if (c == p.label) {
            s.tp[c] += 1;
        } else {
            s.fp[c] += 1;
            s.fn[p.label] += 1;
        }
    }
    return s;
}

std::vector<Sample> subsample(const std::vector<Pixel> &px, size_t per_bin, uint64_t seed,
                              std::array<double, VISION_N_COLOURS> *class_total)
{
    // a reservoir per (class, bin)
    std::vector<std::vector<uint32_t>> keep(static_cast<size_t>(VISION_N_COLOURS) * VISION_LUT_SIZE);
    std::vector<uint32_t> seen(keep.size(), 0);
    rng_t rng;
    rng_seed(&rng, seed);
    class_total->fill(0.0);
    for (uint32_t i = 0; i < px.size(); ++i) {
        const Pixel &p = px[i];
        (*class_total)[p.label] += 1.0;
        const size_t k = static_cast<size_t>(p.label) * VISION_LUT_SIZE + vision_lut_bin(p.r, p.g, p.b);
        const uint32_t n = ++seen[k];
        if (keep[k].size() < per_bin) {
            keep[k].push_back(i);
        } else {
            const uint32_t j = rng_below(&rng, n);
            if (j < per_bin) keep[k][j] = i;
        }
    }
    std::vector<Sample> out;
    for (size_t k = 0; k < keep.size(); ++k) {
        for (uint32_t i : keep[k]) {
            const Pixel &p = px[i];
            out.push_back(Sample{p.r, p.g, p.b, p.label, static_cast<double>(seen[k]) / static_cast<double>(keep[k].size())});
        }
    }
    return out;
}

namespace {

uint8_t argmax_class(const std::array<double, VISION_N_COLOURS> &score, const GrnnParams &p)
{
    double best = 0.0;
    uint8_t cls = VISION_COLOUR_NONE;  // nothing within reach: none
    for (int c = 0; c < VISION_N_COLOURS; ++c) {
        const double s = score[static_cast<size_t>(c)] * p.weight[static_cast<size_t>(c)];
        if (s > best) {
            best = s;
            cls = static_cast<uint8_t>(c);
        }
    }
    return cls;
}

}  // namespace

uint8_t grnn_classify(const std::vector<Sample> &train, const GrnnParams &p, double r, double g, double b)
{
    // kernels cut at 4 sigma: exp(-8) = 3e-4 of the peak
    const double inv = 1.0 / (2.0 * p.sigma * p.sigma), cut2 = 16.0 * p.sigma * p.sigma;
    std::array<double, VISION_N_COLOURS> score{};
    for (const Sample &x : train) {
        const double dr = r - x.r, dg = g - x.g, db = b - x.b;
        const double d2 = dr * dr + dg * dg + db * db;
        if (d2 > cut2) continue;
        score[x.label] += x.weight * std::exp(-d2 * inv);
    }
    return argmax_class(score, p);
}

void grnn_bake(const std::vector<Sample> &train, const GrnnParams &p, vision_lut_t *lut)
{
    // bucket the samples by bin so that a bin only visits its neighbourhood
    constexpr uint32_t n = 1u << VISION_LUT_BITS;
    const double step = static_cast<double>(1u << (8 - VISION_LUT_BITS));
    std::vector<std::vector<uint32_t>> bucket(VISION_LUT_SIZE);
    for (uint32_t i = 0; i < train.size(); ++i) bucket[vision_lut_bin(train[i].r, train[i].g, train[i].b)].push_back(i);
    const int reach = static_cast<int>(std::ceil(4.0 * p.sigma / step)) + 1;
    const double inv = 1.0 / (2.0 * p.sigma * p.sigma), cut2 = 16.0 * p.sigma * p.sigma;
    for (uint32_t ri = 0; ri < n; ++ri) {
        for (uint32_t gi = 0; gi < n; ++gi) {
            for (uint32_t bi = 0; bi < n; ++bi) {
                const double r = bin_centre(ri), g = bin_centre(gi), b = bin_centre(bi);
                std::array<double, VISION_N_COLOURS> score{};
                for (int a = -reach; a <= reach; ++a) {
                    const int ra = static_cast<int>(ri) + a;
                    if (ra < 0 || ra >= static_cast<int>(n)) continue;
                    for (int c = -reach; c <= reach; ++c) {
                        const int gc = static_cast<int>(gi) + c;
                        if (gc < 0 || gc >= static_cast<int>(n)) continue;
                        for (int d = -reach; d <= reach; ++d) {
                            const int bd = static_cast<int>(bi) + d;
                            if (bd < 0 || bd >= static_cast<int>(n)) continue;
                            const auto &bk = bucket[(static_cast<uint32_t>(ra) << (2 * VISION_LUT_BITS)) |
                                                    (static_cast<uint32_t>(gc) << VISION_LUT_BITS) |
                                                    static_cast<uint32_t>(bd)];
                            for (uint32_t k : bk) {
                                const Sample &x = train[k];
                                const double dr = r - x.r, dg = g - x.g, db = b - x.b;
                                const double d2 = dr * dr + dg * dg + db * db;
                                if (d2 > cut2) continue;
                                score[x.label] += x.weight * std::exp(-d2 * inv);
                            }
                        }
                    }
                }
                lut->table[(ri << (2 * VISION_LUT_BITS)) | (gi << VISION_LUT_BITS) | bi] = argmax_class(score, p);
            }
        }
    }
}

uint8_t hsv_classify(const HsvParams &p, double r, double g, double b)
{
    double h, s, v;
    rgb_to_hsv(r, g, b, &h, &s, &v);
    if (s < p.s_min || v < p.v_min) return VISION_COLOUR_NONE;
    uint8_t cls = VISION_COLOUR_NONE;
    double best = 1e9;
    for (int c = 1; c < VISION_N_COLOURS; ++c) {
        const double d = hue_dist(h, p.hue_deg[static_cast<size_t>(c)]);
        if (d <= p.half_deg[static_cast<size_t>(c)] && d < best) {
            best = d;
            cls = static_cast<uint8_t>(c);
        }
    }
    return cls;
}

void hsv_bake(const HsvParams &p, vision_lut_t *lut)
{
    for (uint32_t i = 0; i < VISION_LUT_SIZE; ++i) {
        const uint32_t ri = i >> (2 * VISION_LUT_BITS), gi = (i >> VISION_LUT_BITS) & ((1u << VISION_LUT_BITS) - 1u),
                       bi = i & ((1u << VISION_LUT_BITS) - 1u);
        lut->table[i] = hsv_classify(p, bin_centre(ri), bin_centre(gi), bin_centre(bi));
    }
}

HsvParams hsv_fit(const std::vector<Sample> &train)
{
    std::vector<double> hh(train.size()), ss(train.size()), vv(train.size());
    for (size_t i = 0; i < train.size(); ++i) rgb_to_hsv(train[i].r, train[i].g, train[i].b, &hh[i], &ss[i], &vv[i]);
    HsvParams base;
    std::array<std::vector<double>, VISION_N_COLOURS> spread;
    for (int c = 1; c < VISION_N_COLOURS; ++c) {
        double sx = 0.0, sy = 0.0;
        for (size_t i = 0; i < train.size(); ++i) {
            if (train[i].label != c) continue;
            sx += std::cos(hh[i] * COSLAM_PI / 180.0);
            sy += std::sin(hh[i] * COSLAM_PI / 180.0);
        }
        double m = std::atan2(sy, sx) * 180.0 / COSLAM_PI;
        if (m < 0.0) m += 360.0;
        base.hue_deg[static_cast<size_t>(c)] = m;
        for (size_t i = 0; i < train.size(); ++i) {
            if (train[i].label == c) spread[static_cast<size_t>(c)].push_back(hue_dist(hh[i], m));
        }
        std::sort(spread[static_cast<size_t>(c)].begin(), spread[static_cast<size_t>(c)].end());
    }
    // grid: hue percentile, s_min, v_min; weighted mean F1 on the training pixels
    HsvParams best = base;
    double best_f1 = -1.0;
    for (double pct : {0.9, 0.95, 0.98, 0.995}) {
        HsvParams p = base;
        for (int c = 1; c < VISION_N_COLOURS; ++c) {
            const auto &sp = spread[static_cast<size_t>(c)];
            p.half_deg[static_cast<size_t>(c)] = sp.empty() ? 0.0 : sp[static_cast<size_t>(pct * static_cast<double>(sp.size() - 1))];
        }
        for (double smin = 0.15; smin <= 0.71; smin += 0.05) {
            for (double vmin = 0.05; vmin <= 0.41; vmin += 0.05) {
                p.s_min = smin;
                p.v_min = vmin;
                ClassScores sc;
                for (size_t i = 0; i < train.size(); ++i) {
                    const double w = train[i].weight;
                    uint8_t cls = VISION_COLOUR_NONE;
                    if (ss[i] >= smin && vv[i] >= vmin) {
                        double bd = 1e9;
                        for (int c = 1; c < VISION_N_COLOURS; ++c) {
                            const double d = hue_dist(hh[i], p.hue_deg[static_cast<size_t>(c)]);
                            if (d <= p.half_deg[static_cast<size_t>(c)] && d < bd) {
                                bd = d;
                                cls = static_cast<uint8_t>(c);
                            }
                        }
                    }
                    if (cls == train[i].label) {
                        sc.tp[cls] += w;
                    } else {
                        sc.fp[cls] += w;
                        sc.fn[train[i].label] += w;
                    }
                }
                if (sc.mean_f1() > best_f1) {
                    best_f1 = sc.mean_f1();
                    best = p;
                }
            }
        }
    }
    return best;
}

}  // namespace coslam::vision_host
