// coslam-vision-fit: the range model the detector loads (vision.h, "range
// model"), fitted from calibration samples (docs/vision.md).
//
// A calibration sample is a detected marker with its true range: the
// detector (colour table given, uncalibrated pinhole model, no range limit)
// runs on rendered frames (vision_scenes, seeds 4000..; on a real robot: a
// marker at measured distances, --samples FILE with `kind h_px range_m
// bearing_rad bearing_err_rad` lines); detections are matched to the renderer's truth
// (correct identity, clear markers only: >= 95 % showing, inside the image).
// Per kind (landmark tube, robot body):
//   r_p = f H / (h_px cos b),  r = c0 + c1 r_p + c2 r_p^2   (least squares; samples
//   beyond 5 MAD of the first fit's residuals are dropped and it is redone)
//   residual variance e^2 ~ s0^2 + s1^2 r^2        (least squares on the
//   squared residuals, coefficients kept >= 0)
//   bearing sd = RMS bearing error
// The residuals per range bin go to stdout and into the model file's header.
//
//   coslam-vision-fit [--out FILE] [--frames N] [--lut F] [--samples F] [--dump-samples F]
#include <CLI/CLI.hpp>
#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include <opencv2/core.hpp>

#include "checked_file.hpp"
#include "cli_checks.hpp"
#include "vision_scenes.hpp"

using namespace coslam;
using namespace coslam::vision_host;

namespace {

struct CalSample {
    int kind;         // vision_marker_kind_t
    double h_px, range_m, bearing_rad, bearing_err_rad;   // bearing: the measured one
};

double rp_of(const CalSample &c)
{
    return vision_range_pinhole(VISION_FOCAL_PX, c.h_px, c.bearing_rad);
}

struct KindFit {
    vision_range_fit_t fit{};
    size_t n = 0, dropped = 0;
    std::string table;
};

KindFit fit_kind(const std::vector<CalSample> &all, int kind, double max_range_m)
{
    KindFit kf;
    std::vector<CalSample> s;
    for (const auto &c : all) {
        if (c.kind == kind && c.range_m <= max_range_m) s.push_back(c);
    }
    if (s.size() < 10) throw std::runtime_error("fewer than 10 calibration samples of a marker kind");
    auto lsq = [](const std::vector<CalSample> &v) {
        Eigen::MatrixXd A(v.size(), 3);
        Eigen::VectorXd y(v.size());
        for (size_t i = 0; i < v.size(); ++i) {
            const double rp = rp_of(v[i]);
            A(static_cast<Eigen::Index>(i), 0) = 1.0;
            A(static_cast<Eigen::Index>(i), 1) = rp;
            A(static_cast<Eigen::Index>(i), 2) = rp * rp;
            y(static_cast<Eigen::Index>(i)) = v[i].range_m;
        }
        return Eigen::Vector3d(A.colPivHouseholderQr().solve(y));
    };
    Eigen::Vector3d c = lsq(s);
    // robust: drop samples beyond 5 MAD, refit
    std::vector<double> res;
    for (const auto &x : s) {
        const double rp = rp_of(x);
        res.push_back(std::fabs(x.range_m - (c[0] + c[1] * rp + c[2] * rp * rp)));
    }
    const double mad = quantile(res, 0.5);
    std::vector<CalSample> kept;
    for (size_t i = 0; i < s.size(); ++i) {
        if (res[i] <= 5.0 * 1.4826 * mad) kept.push_back(s[i]);
    }
    kf.dropped = s.size() - kept.size();
    c = lsq(kept);
    kf.n = kept.size();
    kf.fit.c[0] = c[0];
    kf.fit.c[1] = c[1];
    kf.fit.c[2] = c[2];
    // variance model on the squared residuals of EVERY sample (the outliers
    // too: the filters must not be surprised by them): e^2 = a + b r^2, a, b >= 0
    std::vector<double> e(s.size()), r(s.size());
    double sb2 = 0.0;
    for (size_t i = 0; i < s.size(); ++i) {
        const double rp = rp_of(s[i]);
        e[i] = s[i].range_m - (c[0] + c[1] * rp + c[2] * rp * rp);
        r[i] = s[i].range_m;
        sb2 += s[i].bearing_err_rad * s[i].bearing_err_rad;
    }
    Eigen::MatrixXd A(s.size(), 2);
    Eigen::VectorXd y(s.size());
    for (size_t i = 0; i < s.size(); ++i) {
        A(static_cast<Eigen::Index>(i), 0) = 1.0;
        A(static_cast<Eigen::Index>(i), 1) = r[i] * r[i];
        y(static_cast<Eigen::Index>(i)) = e[i] * e[i];
    }
    Eigen::Vector2d ab = A.colPivHouseholderQr().solve(y);
    if (ab[0] < 0.0) {  // only the proportional part
        double num = 0, den = 0;
        for (size_t i = 0; i < s.size(); ++i) {
            num += r[i] * r[i] * e[i] * e[i];
            den += std::pow(r[i], 4);
        }
        ab = Eigen::Vector2d(0.0, num / den);
    } else if (ab[1] < 0.0) {
        double m = 0;
        for (double x : e) m += x * x;
        ab = Eigen::Vector2d(m / static_cast<double>(e.size()), 0.0);
    }
    kf.fit.range_sd_m = std::sqrt(ab[0]);
    kf.fit.range_sd_rel = std::sqrt(ab[1]);
    kf.fit.bearing_sd_rad = std::sqrt(sb2 / static_cast<double>(s.size()));
    // residuals per range bin
    std::ostringstream t;
    t << "(every sample, the dropped outliers included)\n";
    t << "range bin [m]   n    mean [m]  RMS [m]  RMS/r    model sd [m]\n";
    for (int b = 0; b < 6; ++b) {
        double s1 = 0, s2 = 0, rr = 0;
        int n = 0;
        for (size_t i = 0; i < s.size(); ++i) {
            if (r[i] < b || r[i] >= b + 1) continue;
            s1 += e[i];
            s2 += e[i] * e[i];
            rr += e[i] * e[i] / (r[i] * r[i]);
            ++n;
        }
        if (n == 0) continue;
        const double rc = b + 0.5;
        char line[160];
        std::snprintf(line, sizeof line, "%d-%d           %-4d %+.4f   %.4f   %.4f   %.4f\n", b, b + 1, n, s1 / n,
                      std::sqrt(s2 / n), std::sqrt(rr / n), std::sqrt(ab[0] + ab[1] * rc * rc));
        t << line;
    }
    kf.table = t.str();
    return kf;
}

}  // namespace

static int vision_fit_main(int argc, char **argv)
{
    CLI::App app{"coslam-vision-fit: fit the range model (pixel height -> range) and its noise from calibration samples"};
    std::string out = std::string(COSLAM_SOURCE_DIR) + "/firmware/vision/data/range_model.txt";
    std::string lut_path, samples_in, samples_out;
    int frames = 600;
    uint64_t seed0 = 4000;
    double max_range = 6.0;
    app.add_option("--out", out, "range model file to write")->capture_default_str();
    app.add_option("--frames", frames, "rendered calibration frames")
        ->capture_default_str()
        ->check(coslam::cli::int_in(1, 1000000));
    app.add_option("--seed0", seed0, "scene seed of the first frame")->capture_default_str();
    app.add_option("--lut", lut_path, "colour table (default: the shipped one)");
    app.add_option("--max-range", max_range, "samples farther are not fitted [m]")->capture_default_str();
    app.add_option("--samples", samples_in,
                   "fit these samples instead (lines: kind (1 landmark, 2 robot) h_px range_m bearing_rad bearing_err_rad)");
    app.add_option("--dump-samples", samples_out, "write the samples used");
    if (const int rc = coslam::cli::parse_usage(app, argc, argv); rc >= 0) return rc;

    try {
        std::vector<CalSample> samples;
        if (!samples_in.empty()) {
            std::ifstream in(samples_in);
            if (!in) throw std::runtime_error("cannot read " + samples_in);
            std::string line;
            while (std::getline(in, line)) {
                if (line.empty() || line[0] == '#') continue;
                std::istringstream ls(line);
                CalSample c{};
                if (!(ls >> c.kind >> c.h_px >> c.range_m >> c.bearing_rad >> c.bearing_err_rad) || c.h_px <= 0) {
                    throw std::runtime_error("bad sample line: " + line);
                }
                samples.push_back(c);
            }
        } else {
            cv::setNumThreads(1);
            static vision_lut_t lut;
            load_vision_data(lut_path, "", &lut, nullptr);
            vision_config_t cfg = vision_config_default();
            cfg.min_range_m = 0.0;
            cfg.max_range_m = 1000.0;
            vision_detector_t *det = nullptr;
            if (vision_detector_create(&det, &cfg, &lut, nullptr) != VISION_OK) throw std::runtime_error("detector");
            const sim::Scenario sc = sim::load_scenario_file(paper_scenario_path());
            vision_result_t res;
            for (int i = 0; i < frames; ++i) {
                const Scene s = make_scene(sc, seed0 + static_cast<uint64_t>(i));
                const Frame f = render_scene(s);
                vision_detect_rgb(det, f.rgb.data(), 3u * VISION_IMAGE_WIDTH_PX, &res);
                const FrameMatch fm = match_frame(res, f.truth);
                for (uint16_t k = 0; k < res.n_markers; ++k) {
                    if (fm.det[k].truth < 0 || !fm.det[k].same_identity) continue;
                    const auto &t = f.truth[static_cast<size_t>(fm.det[k].truth)];
                    if (!expected(t, 0.95, 0.0, 1000.0)) continue;
                    samples.push_back(CalSample{res.markers[k].kind, res.markers[k].h_px, t.range_m, res.markers[k].bearing_rad,
                                                angle_wrap(res.markers[k].bearing_rad - t.bearing_rad)});
                }
            }
            vision_detector_destroy(det);
        }
        if (!samples_out.empty()) {
            std::ofstream o = coslam::cli::open_checked(samples_out);
            o << "# kind h_px range_m bearing_rad bearing_err_rad\n";
            for (const auto &c : samples)
                o << c.kind << " " << c.h_px << " " << c.range_m << " " << c.bearing_rad << " " << c.bearing_err_rad << "\n";
            coslam::cli::close_checked(o, samples_out);
        }
        const KindFit lm = fit_kind(samples, VISION_MARKER_LANDMARK, max_range);
        const KindFit rb = fit_kind(samples, VISION_MARKER_ROBOT, max_range);
        vision_range_model_t m{lm.fit, rb.fit};
        std::ostringstream h;
        h << "Range model of the coslam marker detector (docs/vision.md), written by coslam-vision-fit\n";
        h << "from " << (samples_in.empty() ? std::to_string(frames) + " rendered frames (seeds " + std::to_string(seed0) + "..)"
                                           : samples_in)
          << ", samples up to " << max_range << " m.\n";
        h << "r_p = " << VISION_FOCAL_PX << " px * " << VISION_MARKER_HEIGHT_M
          << " m / (h_px cos(bearing));  r = c0 + c1 r_p + c2 r_p^2\n";
        const struct {
            const char *name;
            const KindFit *k;
        } kinds[2] = {{"landmark", &lm}, {"robot", &rb}};
        for (const auto &k : kinds) {
            char line[256];
            std::snprintf(line, sizeof line,
                          "%s: %zu samples (%zu outliers beyond 5 MAD not fitted); range sd = sqrt(%.4f^2 + (%.4f r)^2) m, "
                          "bearing sd %.3f deg\n",
                          k.name, k.k->n, k.k->dropped, k.k->fit.range_sd_m, k.k->fit.range_sd_rel,
                          k.k->fit.bearing_sd_rad * 180.0 / COSLAM_PI);
            h << line << "residuals (true - model) of the " << k.name << " fit:\n" << k.k->table;
        }
        std::string header = h.str();
        if (!header.empty() && header.back() == '\n') header.pop_back();
        errno = 0;
        const vision_status_t st = vision_range_model_save(&m, out.c_str(), header.c_str());
        if (st == VISION_E_IO) throw coslam::cli::WriteError(out, errno);
        if (st != VISION_OK) throw std::runtime_error("cannot write " + out + ": " + vision_status_name(st));
        std::cout << header << "\nwritten: " << out << "\n";
    } catch (const std::exception &e) {
        std::cerr << "coslam-vision-fit: " << e.what() << std::endl;
        return 1;
    }
    return 0;
}

// exit status with standard output checked (stdout_check.h)
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-vision-fit", vision_fit_main(argc, argv));
}
