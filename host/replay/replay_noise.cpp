// host/replay/replay_noise.cpp - sighting noise measured against ground truth.
#include "replay_noise.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <ostream>
#include <set>

#include "coslam/landmark.h"
#include "coslam/observe.h"
#include "replay_truth.h"

namespace coslam::replay {

namespace {

// sd of a normal distribution = 1.4826 * its median absolute deviation
constexpr double kMadToSd = 1.4826;

struct Residual {
    double r_true;  ///< true range [m]
    double dr;      ///< measured - true range [m]
    double db;      ///< measured - true bearing, wrapped [rad]
    double t_s;     ///< time of the sighting [s]
    int landmark;   ///< true landmark identity
    int robot;      ///< robot id
    bool inlier = true;
};

double median(std::vector<double> v)
{
    if (v.empty()) {
        return 0.0;
    }
    const size_t mid = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
    const double hi = v[mid];
    if (v.size() % 2 == 1) {
        return hi;
    }
    const double lo = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid));
    return 0.5 * (lo + hi);
}

struct Robust {
    double centre = 0.0;
    double sd = 0.0;
};

Robust robust_of(const std::vector<double> &v)
{
    Robust r;
    r.centre = median(v);
    std::vector<double> dev(v.size());
    for (size_t i = 0; i < v.size(); ++i) {
        dev[i] = std::fabs(v[i] - r.centre);
    }
    r.sd = kMadToSd * median(std::move(dev));
    return r;
}

// A zero robust sd (e.g. quantised residuals, tiny groups) says nothing about
// outliers, so it rejects nothing rather than everything off the median.
bool is_outlier(double x, const Robust &r, double k) { return r.sd > 0.0 && std::fabs(x - r.centre) > k * r.sd; }

int bin_of(double r, double bin_m) { return static_cast<int>(std::floor(r / bin_m)); }

// Mark gross outliers of one robot's residuals; a sighting is rejected when
// its range or its bearing is off (a misread barcode spoils both). Range is
// judged within its range bin because the model's sd grows with the range:
// one sd for all ranges would cut the far tail and keep near outliers.
long reject_outliers(std::vector<Residual> &res, const NoiseFitOptions &opt)
{
    std::vector<double> db(res.size()), dr(res.size());
    std::map<int, std::vector<size_t>> bins;
    for (size_t i = 0; i < res.size(); ++i) {
        db[i] = res[i].db;
        dr[i] = res[i].dr;
        bins[bin_of(res[i].r_true, opt.bin_m)].push_back(i);
    }
    const Robust rb = robust_of(db);
    const Robust rr_all = robust_of(dr);
    for (const auto &[bin, idx] : bins) {
        (void)bin;
        Robust rr = rr_all; // too few samples for a bin's own MAD
        if (static_cast<int>(idx.size()) >= opt.min_bin_count) {
            std::vector<double> v;
            v.reserve(idx.size());
            for (size_t i : idx) {
                v.push_back(res[i].dr);
            }
            rr = robust_of(v);
        }
        for (size_t i : idx) {
            res[i].inlier = !is_outlier(res[i].dr, rr, opt.reject_sd) && !is_outlier(res[i].db, rb, opt.reject_sd);
        }
    }
    return static_cast<long>(std::count_if(res.begin(), res.end(), [](const Residual &r) { return !r.inlier; }));
}

struct RangeModel {
    double a = 0.0; ///< range_var_m2
    double b = 0.0; ///< range_var_per_m2
};

// Weighted least squares y = a + b x with a, b >= 0: the optimum is either
// the unconstrained one (if feasible) or on an edge (a = 0 or b = 0), so the
// best feasible of these candidates is the constrained optimum.
RangeModel nnls2(const std::vector<NoiseBin> &bins, const std::vector<double> &w)
{
    double s = 0.0, sx = 0.0, sxx = 0.0, sy = 0.0, sxy = 0.0;
    for (size_t i = 0; i < bins.size(); ++i) {
        const double x = bins[i].r2_mean_m2;
        const double y = bins[i].var_m2;
        s += w[i];
        sx += w[i] * x;
        sxx += w[i] * x * x;
        sy += w[i] * y;
        sxy += w[i] * x * y;
    }
    std::vector<RangeModel> cand;
    const double det = s * sxx - sx * sx;
    if (det > 1e-12 * s * sxx) {
        const double b = (s * sxy - sx * sy) / det;
        const double a = (sy - b * sx) / s;
        if (a >= 0.0 && b >= 0.0) {
            cand.push_back({a, b});
        }
    }
    cand.push_back({0.0, sxx > 0.0 ? std::max(0.0, sxy / sxx) : 0.0});
    cand.push_back({s > 0.0 ? std::max(0.0, sy / s) : 0.0, 0.0});
    auto cost = [&](const RangeModel &m) {
        double c = 0.0;
        for (size_t i = 0; i < bins.size(); ++i) {
            const double e = bins[i].var_m2 - m.a - m.b * bins[i].r2_mean_m2;
            c += w[i] * e * e;
        }
        return c;
    };
    return *std::min_element(cand.begin(), cand.end(),
                             [&](const RangeModel &p, const RangeModel &q) { return cost(p) < cost(q); });
}

// A bin variance from n samples has variance 2 var^2 / (n - 1): the first
// pass weights by n - 1 alone, the second by the inverse variance at the
// first pass's model (so the few noisy far bins do not dominate).
RangeModel fit_range_model(const std::vector<NoiseBin> &bins)
{
    std::vector<double> w(bins.size());
    for (size_t i = 0; i < bins.size(); ++i) {
        w[i] = static_cast<double>(bins[i].n - 1);
    }
    RangeModel m = nnls2(bins, w);
    for (size_t i = 0; i < bins.size(); ++i) {
        double pred = m.a + m.b * bins[i].r2_mean_m2;
        if (!(pred > 0.0)) {
            pred = std::max(bins[i].var_m2, 1e-12);
        }
        w[i] = static_cast<double>(bins[i].n - 1) / (2.0 * pred * pred);
    }
    return nnls2(bins, w);
}

// Biases, variances and the range model of the inliers of `res` into `s`.
void fit_stats(const std::vector<Residual> &res, const NoiseFitOptions &opt, NoiseStats &s)
{
    double n = 0.0, sr = 0.0, sb = 0.0;
    for (const auto &x : res) {
        if (x.inlier) {
            n += 1.0;
            sr += x.dr;
            sb += x.db;
        }
    }
    if (n < 2.0) {
        return;
    }
    s.range_bias_m = sr / n;
    s.bearing_bias_rad = sb / n;
    double vr = 0.0, vb = 0.0;
    struct Acc {
        double n = 0.0, r = 0.0, r2 = 0.0, d = 0.0, d2 = 0.0;
    };
    std::map<int, Acc> acc;
    for (const auto &x : res) {
        if (!x.inlier) {
            continue;
        }
        vr += (x.dr - s.range_bias_m) * (x.dr - s.range_bias_m);
        vb += (x.db - s.bearing_bias_rad) * (x.db - s.bearing_bias_rad);
        Acc &a = acc[bin_of(x.r_true, opt.bin_m)];
        a.n += 1.0;
        a.r += x.r_true;
        a.r2 += x.r_true * x.r_true;
        a.d += x.dr;
        a.d2 += x.dr * x.dr;
    }
    s.range_sd_m = std::sqrt(vr / (n - 1.0));
    s.bearing_var_rad2 = vb / (n - 1.0);
    for (const auto &[bin, a] : acc) {
        (void)bin;
        if (a.n < opt.min_bin_count || a.n < 2.0) {
            continue;
        }
        NoiseBin nb;
        nb.n = static_cast<long>(a.n);
        nb.r_mean_m = a.r / a.n;
        nb.r2_mean_m2 = a.r2 / a.n;
        // variance about the bin's own mean: a range-dependent bias is not noise
        nb.var_m2 = std::max(0.0, (a.d2 - a.d * a.d / a.n) / (a.n - 1.0));
        s.bins.push_back(nb);
    }
    if (s.bins.empty()) {
        // no bin is populated enough for a slope: a constant variance
        s.range_var_m2 = s.range_sd_m * s.range_sd_m;
        s.range_var_per_m2 = 0.0;
        return;
    }
    const RangeModel m = fit_range_model(s.bins);
    s.range_var_m2 = m.a;
    s.range_var_per_m2 = m.b;
}

// Residuals of one robot's sightings; counts what was skipped into `s`.
std::vector<Residual> residuals_of(const Dataset &ds, const RobotLog &log, const NoiseFitOptions &opt, NoiseStats &s)
{
    std::vector<Residual> res;
    const TruthTrack tt(log.truth, opt.max_gap_s);
    for (const auto &z : log.z) {
        s.sightings++;
        const LandmarkTruth *lm = z.landmark_id >= 0 ? ds.landmark(z.landmark_id) : nullptr;
        if (lm == nullptr) {
            s.unknown_id++;
            continue;
        }
        if (z.range_m < opt.min_range_m || z.range_m > opt.max_range_m) {
            s.out_of_range++;
            continue;
        }
        const auto pose = tt.at(z.t_s);
        if (!pose) {
            s.no_truth++;
            continue;
        }
        const point2_t p = pose2_apply_inverse(*pose, lm->pos);
        const double r = std::hypot(p.x, p.y);
        res.push_back({r, z.range_m - r, angle_wrap(z.bearing_rad - std::atan2(p.y, p.x)), z.t_s, z.landmark_id,
                       log.id});
    }
    s.used = static_cast<long>(res.size());
    return res;
}

// Autocorrelation at lags 1..max_lag of zero-mean (bias-removed, normalised)
// series, pairs within a track only, pooled over the tracks; tau by the
// initial-positive-sequence rule.
NoiseCorrelation correlation_of(const std::vector<std::vector<double>> &tracks, int max_lag)
{
    NoiseCorrelation c;
    const size_t K = static_cast<size_t>(std::max(max_lag, 0));
    c.rho.assign(K, 0.0);
    c.pairs.assign(K, 0);
    std::vector<double> ck(K, 0.0);
    double c0 = 0.0;
    long n0 = 0;
    for (const auto &x : tracks) {
        for (size_t i = 0; i < x.size(); ++i) {
            c0 += x[i] * x[i];
            n0++;
            for (size_t k = 1; k <= K && i + k < x.size(); ++k) {
                ck[k - 1] += x[i] * x[i + k];
                c.pairs[k - 1]++;
            }
        }
    }
    if (n0 < 2 || !(c0 > 0.0)) {
        return c;
    }
    const double var = c0 / static_cast<double>(n0);
    for (size_t k = 0; k < K; ++k) {
        if (c.pairs[k] > 0) {
            c.rho[k] = ck[k] / static_cast<double>(c.pairs[k]) / var;
        }
    }
    double sum = 0.0;
    for (size_t k = 0; k < K; ++k) {
        if (c.pairs[k] == 0 || !(c.rho[k] > 0.0)) {
            break;
        }
        sum += c.rho[k];
        c.lags_summed++;
    }
    c.tau = 1.0 + 2.0 * sum;
    return c;
}

// The correlation of the inliers' normalised residuals within tracks (one
// robot, one landmark, consecutive sightings at most track_gap_s apart),
// and the model inflated by it, into `fit`.
void fit_correlation(const std::vector<Residual> &pooled, const NoiseFitOptions &opt, NoiseFit &fit)
{
    const NoiseStats &o = fit.overall;
    std::map<std::pair<int, int>, std::vector<const Residual *>> seq;
    for (const auto &x : pooled) {
        if (x.inlier) {
            seq[{x.robot, x.landmark}].push_back(&x);
        }
    }
    const double sd_b = std::sqrt(o.bearing_var_rad2);
    std::vector<std::vector<double>> tr_r, tr_b;
    for (auto &[key, v] : seq) {
        (void)key;
        std::stable_sort(v.begin(), v.end(), [](const Residual *a, const Residual *b) { return a->t_s < b->t_s; });
        for (size_t i = 0; i < v.size(); ++i) {
            if (i == 0 || v[i]->t_s - v[i - 1]->t_s > opt.track_gap_s) {
                tr_r.emplace_back();
                tr_b.emplace_back();
                fit.tracks++;
            }
            const double var_r = o.range_var_m2 + o.range_var_per_m2 * v[i]->r_true * v[i]->r_true;
            const double sd_r = var_r > 0.0 ? std::sqrt(var_r) : 1.0;
            tr_r.back().push_back((v[i]->dr - o.range_bias_m) / sd_r);
            tr_b.back().push_back(sd_b > 0.0 ? (v[i]->db - o.bearing_bias_rad) / sd_b : 0.0);
            fit.samples++;
        }
    }
    fit.range_corr = correlation_of(tr_r, opt.max_lag);
    fit.bearing_corr = correlation_of(tr_b, opt.max_lag);
    // per-track offset model (replay_noise.h): factor (1 - rho_1) + n rho_1
    const double n_track = fit.tracks > 0 ? static_cast<double>(fit.samples) / static_cast<double>(fit.tracks) : 1.0;
    for (NoiseCorrelation *c : {&fit.range_corr, &fit.bearing_corr}) {
        const double r1 = c->rho.empty() ? 0.0 : std::clamp(c->rho[0], 0.0, 1.0);
        c->factor = std::max(1.0, (1.0 - r1) + n_track * r1);
    }
    fit.range_var_m2_eff = fit.range_corr.factor * o.range_var_m2;
    fit.range_var_per_m2_eff = fit.range_corr.factor * o.range_var_per_m2;
    fit.bearing_var_rad2_eff = fit.bearing_corr.factor * o.bearing_var_rad2;
}

// One logged frame's in-view count n, detections among them k, and whether
// something else in it would have had it logged anyway (replay_noise.h).
struct FrameCount {
    long n;
    long k;
    bool other;
    bool operator<(const FrameCount &o) const
    {
        return n != o.n ? n < o.n : (k != o.k ? k < o.k : other < o.other);
    }
};

// Frames as the replay groups them (replay_run.cpp build_frames): the
// sightings of one stamp, landmarks and robots together.
bool same_stamp(double a, double b) { return std::fabs(a - b) <= 1e-9 * std::max(1.0, std::fabs(a)); }

// log(1 - (1 - p)^n), accurate for small p.
double log_any_detected(double p, long n)
{
    return std::log(-std::expm1(static_cast<double>(n) * std::log1p(-p)));
}

// The zero-truncated maximum likelihood p (replay_noise.h): golden-section
// search of the log likelihood over (0, 1); a binomial term and the
// truncation term are each unimodal in p and so is their sum over frames in
// practice (checked in the tests against the truth). NaN without frames.
double p_truncated(const std::map<FrameCount, long> &frames)
{
    long in_view = 0;
    for (const auto &[f, c] : frames) {
        in_view += f.n * c;
    }
    if (in_view == 0) {
        return std::nan("");
    }
    auto ll = [&](double p) {
        double s = 0.0;
        for (const auto &[f, c] : frames) {
            if (f.n == 0) {
                continue;
            }
            double l = static_cast<double>(f.k) * std::log(p) + static_cast<double>(f.n - f.k) * std::log1p(-p);
            if (!f.other) {
                l -= log_any_detected(p, f.n);
            }
            s += static_cast<double>(c) * l;
        }
        return s;
    };
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    double a = 1e-9, b = 1.0 - 1e-9;
    double x1 = b - g * (b - a), x2 = a + g * (b - a);
    double f1 = ll(x1), f2 = ll(x2);
    for (int i = 0; i < 200 && b - a > 1e-12; ++i) {
        if (f1 < f2) {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = ll(x2);
        } else {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = ll(x1);
        }
    }
    return 0.5 * (a + b);
}

void add_counts(DetectionStats &to, const DetectionStats &s)
{
    to.frames += s.frames;
    to.no_truth += s.no_truth;
    to.used += s.used;
    to.other += s.other;
    to.in_view += s.in_view;
    to.detected += s.detected;
    to.out_of_view += s.out_of_view;
    if (to.bins.size() < s.bins.size()) {
        const size_t n0 = to.bins.size();
        to.bins.resize(s.bins.size());
        for (size_t i = n0; i < to.bins.size(); ++i) {
            to.bins[i].r_lo_m = s.bins[i].r_lo_m;
        }
    }
    for (size_t i = 0; i < s.bins.size(); ++i) {
        to.bins[i].in_view += s.bins[i].in_view;
        to.bins[i].detected += s.bins[i].detected;
    }
}

// The counts of one robot with truth into `s`, its frames' (n, k, other) into `fc`.
void detection_of(const Dataset &ds, const RobotLog &log, const slam_params_t &params, const DetectionOptions &opt,
                  DetectionStats &s, std::map<FrameCount, long> &fc)
{
    const TruthTrack tt(log.truth, opt.max_gap_s);
    size_t iz = 0, ir = 0;
    std::set<int> seen;
    while (iz < log.z.size() || ir < log.rz.size()) {
        const double inf = std::numeric_limits<double>::infinity();
        const double t = std::min(iz < log.z.size() ? log.z[iz].t_s : inf, ir < log.rz.size() ? log.rz[ir].t_s : inf);
        s.frames++;
        bool other = false;
        seen.clear();
        for (; iz < log.z.size() && same_stamp(log.z[iz].t_s, t); ++iz) {
            const LandmarkSighting &z = log.z[iz];
            if (z.landmark_id >= 0 && ds.landmark(z.landmark_id) != nullptr && z.range_m >= opt.min_range_m &&
                z.range_m <= opt.max_range_m) {
                seen.insert(z.landmark_id);
            } else {
                other = true;
            }
        }
        for (; ir < log.rz.size() && same_stamp(log.rz[ir].t_s, t); ++ir) {
            other = true;
        }
        const auto pose = tt.at(t);
        if (!pose) {
            s.no_truth++;
            continue;
        }
        s.used++;
        FrameCount f{0, 0, false};
        for (const LandmarkTruth &lm : ds.landmarks) {
            const sighting_t zhat = observe_predict(*pose, lm.pos);
            const bool detected = seen.count(lm.id) != 0;
            if (!landmark_should_be_seen(&params, zhat)) {
                if (detected) {
                    s.out_of_view++;
                    other = true;
                }
                continue;
            }
            const size_t b = static_cast<size_t>(std::floor(zhat.range_m / opt.bin_m));
            while (s.bins.size() <= b) {
                DetectionBin nb;
                nb.r_lo_m = static_cast<double>(s.bins.size()) * opt.bin_m;
                s.bins.push_back(nb);
            }
            f.n++;
            s.in_view++;
            s.bins[b].in_view++;
            if (detected) {
                f.k++;
                s.detected++;
                s.bins[b].detected++;
            }
        }
        f.other = other;
        s.other += other ? 1 : 0;
        fc[f]++;
    }
}

} // namespace

DetectionFit fit_detection(const Dataset &ds, const slam_params_t &params, const DetectionOptions &opt)
{
    if (ds.landmarks.empty()) {
        throw ReplayError(ds.source, 0,
                          "no landmark ground truth: the detection rate is counted over the true landmarks in view "
                          "(Landmark_Groundtruth.dat or landmarks_truth.txt)");
    }
    if (std::none_of(ds.robots.begin(), ds.robots.end(), [](const RobotLog &r) { return !r.truth.empty(); })) {
        throw ReplayError(ds.source, 0,
                          "no robot has ground truth: the detection rate is counted from the true robot poses "
                          "(RobotN_Groundtruth.dat or robot<k>_truth.txt)");
    }
    if (!(opt.bin_m > 0.0)) {
        throw ReplayError("fit_detection: bin_m must be > 0");
    }
    DetectionFit fit;
    fit.bin_m = opt.bin_m;
    fit.overall.has_truth = true;
    std::map<FrameCount, long> all;
    for (const RobotLog &log : ds.robots) {
        DetectionStats s;
        s.robot = log.id;
        s.has_truth = !log.truth.empty();
        std::map<FrameCount, long> fc;
        detection_of(ds, log, params, opt, s, fc); // without truth: frames counted, all no_truth
        if (s.has_truth) {
            s.p_d_truncated = p_truncated(fc);
            for (const auto &[f, c] : fc) {
                all[f] += c;
            }
            add_counts(fit.overall, s);
        }
        fit.robots.push_back(std::move(s));
    }
    fit.overall.p_d_truncated = p_truncated(all);
    fit.exist_miss_confirmed = slam_exist_miss_for_detection(fit.overall.p_d());
    fit.exist_miss_confirmed_truncated = slam_exist_miss_for_detection(fit.overall.p_d_truncated);
    return fit;
}

NoiseFit fit_noise(const Dataset &ds, const NoiseFitOptions &opt)
{
    if (ds.landmarks.empty()) {
        throw ReplayError(ds.source, 0,
                          "no landmark ground truth: the sighting noise is measured against the true landmark "
                          "positions (Landmark_Groundtruth.dat or landmarks_truth.txt)");
    }
    const bool any_truth =
        std::any_of(ds.robots.begin(), ds.robots.end(), [](const RobotLog &r) { return !r.truth.empty(); });
    if (!any_truth) {
        throw ReplayError(ds.source, 0,
                          "no robot has ground truth: the sighting noise (and fit-noise's detection rate) is measured "
                          "against the true robot poses "
                          "(RobotN_Groundtruth.dat or robot<k>_truth.txt)");
    }
    NoiseFit fit;
    std::vector<Residual> pooled;
    for (const auto &log : ds.robots) {
        NoiseStats s;
        s.robot = log.id;
        s.has_truth = !log.truth.empty();
        if (s.has_truth) {
            std::vector<Residual> res = residuals_of(ds, log, opt, s);
            // per robot: cameras differ (robot 1's bearing noise is larger)
            s.rejected = reject_outliers(res, opt);
            fit_stats(res, opt, s);
            pooled.insert(pooled.end(), res.begin(), res.end());
        } else {
            s.sightings = static_cast<long>(log.z.size());
        }
        NoiseStats &o = fit.overall;
        o.sightings += s.sightings;
        o.unknown_id += s.unknown_id;
        o.no_truth += s.no_truth;
        o.out_of_range += s.out_of_range;
        o.used += s.used;
        o.rejected += s.rejected;
        fit.robots.push_back(std::move(s));
    }
    fit.overall.has_truth = true;
    if (fit.overall.used - fit.overall.rejected < 2) {
        throw ReplayError(ds.source, 0,
                          "no usable sighting: none has a known landmark identity at a time with robot ground truth");
    }
    fit_stats(pooled, opt, fit.overall);
    fit_correlation(pooled, opt, fit);
    return fit;
}

void write_noise_ini(const NoiseFit &fit, const Dataset &ds, std::ostream &out, bool inflate,
                     const DetectionFit *det)
{
    const NoiseStats &o = fit.overall;
    const double rv0 = inflate ? fit.range_var_m2_eff : o.range_var_m2;
    const double rv1 = inflate ? fit.range_var_per_m2_eff : o.range_var_per_m2;
    const double bv = inflate ? fit.bearing_var_rad2_eff : o.bearing_var_rad2;
    // The filter needs a positive variance at every range (slam_params_validate),
    // but the fit may put the constant term at its bound 0 when the range noise
    // is all proportional. A floor of (1 mm)^2 and (1 mrad)^2 keeps the file
    // valid and is negligible next to the proportional term at the camera's
    // ranges (>= 1 m).
    constexpr double kRangeVarFloor = 1e-6;
    constexpr double kBearingVarFloor = 1e-6;
    const double range_var = std::max(rv0, kRangeVarFloor);
    const double bearing_var = std::max(bv, kBearingVarFloor);
    const auto old = out.flags();
    const auto prec = out.precision();
    out << "; coslam-replay: sighting noise measured against ground truth (coslam-replay fit-noise)\n"
        << "; dataset " << ds.source << ": " << o.used << " sightings, " << o.rejected
        << " gross outliers rejected; var(range) = range_var_m2 + range_var_per_m2 * r^2\n"
        << std::setprecision(3) << "; biases (not in the variances): range " << o.range_bias_m << " m, bearing "
        << o.bearing_bias_rad << " rad\n"
        << std::setprecision(4);
    if (inflate) {
        // (comment lines kept short: the INI reader's lines end at 200 characters)
        out << "; inflated for a per-track offset: var_eff = var_fitted * ((1 - rho_1) + n rho_1),\n"
            << "; n = mean track length; factors range " << fit.range_corr.factor << ", bearing "
            << fit.bearing_corr.factor << "; rho_1 = lag-1 autocorrelation of the normalised\n"
            << "; residuals along tracks of one landmark seen by one robot; tau_range "
            << fit.range_corr.tau << " (" << fit.range_corr.lags_summed << " lags), tau_bearing "
            << fit.bearing_corr.tau << " (" << fit.bearing_corr.lags_summed << " lags)\n"
            << std::setprecision(6) << "; fitted: range_var_m2 " << o.range_var_m2 << " range_var_per_m2 "
            << o.range_var_per_m2 << " bearing_var_rad2 " << o.bearing_var_rad2 << "\n";
    }
    out << (range_var != rv0 ? "; range_var_m2 fitted at its bound 0, written as the floor (1 mm)^2\n" : "")
        << (bearing_var != bv ? "; bearing_var_rad2 below the floor (1 mrad)^2, written as the floor\n" : "")
        << "[slam]\n"
        << std::setprecision(6) << "range_var_m2 = " << range_var << "\n"
        << "range_var_per_m2 = " << rv1 << "\n"
        << "bearing_var_rad2 = " << bearing_var << "\n";
    if (det != nullptr) {
        const DetectionStats &d = det->overall;
        out << std::setprecision(4) << "; detection rate over the filter's view (landmark_should_be_seen from the true "
            << "pose): p_d = " << d.detected << " / " << d.in_view << " = " << d.p_d() << "\n"
            << "; (logged frames only, each with a detection: biased upward; zero-truncated estimate "
            << d.p_d_truncated << ")\n";
        if (det->exist_miss_confirmed >= 0.0) {
            out << "; exist_miss_confirmed = log((1 - p_f) / (1 - p_d)) / log(p_d / p_f), p_f = " << SLAM_EXIST_P_FALSE
                << " (slam_exist_miss_for_detection)\n"
                << std::setprecision(6) << "exist_miss_confirmed = " << det->exist_miss_confirmed << "\n";
        } else {
            out << "; exist_miss_confirmed not written: slam_exist_miss_for_detection needs p_f = "
                << SLAM_EXIST_P_FALSE << " < p_d < 1\n";
        }
    }
    out.flags(old);
    out.precision(prec);
}

} // namespace coslam::replay
