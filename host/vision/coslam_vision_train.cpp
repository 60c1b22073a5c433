// coslam-vision-train: the colour table the robot loads (docs/vision.md).
//
// Labelled pixels come from rendered frames (vision_scenes: the paper's
// arena, random poses, light gain 0.45-1.8, white balance, shading, blur,
// noise; the label of a pixel is the surface it shows) or from real images
// with label images (--labelled DIR: NAME.png and NAME_labels.png, the
// latter 8-bit with the class ids 0-4 of vision/marker_spec.h).
// Three disjoint frame sets: training (GRNN samples, HSV fit), validation
// (the GRNN kernel width and class weighting), held-out test (the
// comparison that decides which classifier is written).
//
//   coslam-vision-train [--lut FILE] [--report FILE] [--train N] [--val N] [--test N]
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "checked_file.hpp"
#include "cli_checks.hpp"
#include "colour_train.hpp"
#include "vision_scenes.hpp"

using namespace coslam;
using namespace coslam::vision_host;

namespace {

const char *kNames[VISION_N_COLOURS] = {"none", "red", "yellow", "green", "blue"};

void render_pixels(const sim::Scenario &sc, uint64_t seed0, int n, std::vector<Pixel> *interior, std::vector<Pixel> *all)
{
    for (int i = 0; i < n; ++i) {
        const Scene s = make_scene(sc, seed0 + static_cast<uint64_t>(i));
        const Frame f = render_scene(s);
        interior_pixels(f.rgb.data(), f.labels.data(), VISION_IMAGE_WIDTH_PX, VISION_IMAGE_HEIGHT_PX, interior);
        if (all != nullptr) all_pixels(f.rgb.data(), f.labels.data(), VISION_IMAGE_WIDTH_PX, VISION_IMAGE_HEIGHT_PX, all);
    }
}

void load_labelled(const std::string &dir, std::vector<Pixel> *out)
{
    for (const auto &e : std::filesystem::directory_iterator(dir)) {
        const std::string p = e.path().string();
        if (p.size() < 4 || p.substr(p.size() - 4) != ".png" || p.find("_labels.png") != std::string::npos) continue;
        const std::string lp = p.substr(0, p.size() - 4) + "_labels.png";
        cv::Mat bgr = cv::imread(p, cv::IMREAD_COLOR), lab = cv::imread(lp, cv::IMREAD_GRAYSCALE);
        if (bgr.empty() || lab.empty() || bgr.size() != lab.size()) {
            std::cerr << "coslam-vision-train: skipping " << p << " (no matching " << lp << ")\n";
            continue;
        }
        cv::Mat rgb;
        cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
        interior_pixels(rgb.ptr<uint8_t>(0), lab.ptr<uint8_t>(0), rgb.cols, rgb.rows, out);
    }
}

std::string table(const ClassScores &a, const ClassScores &b, const char *na, const char *nb)
{
    std::ostringstream s;
    char line[256];
    std::snprintf(line, sizeof line, "| class | %s precision | %s recall | %s precision | %s recall |\n|---|---|---|---|---|\n",
                  na, na, nb, nb);
    s << line;
    for (int c = 0; c < VISION_N_COLOURS; ++c) {
        std::snprintf(line, sizeof line, "| %s | %.4f | %.4f | %.4f | %.4f |\n", kNames[c], a.precision(c), a.recall(c),
                      b.precision(c), b.recall(c));
        s << line;
    }
    std::snprintf(line, sizeof line, "| mean F1 (4 colours) | %.4f | | %.4f | |\n", a.mean_f1(), b.mean_f1());
    s << line;
    return s.str();
}

}  // namespace

static int vision_train_main(int argc, char **argv)
{
    CLI::App app{"coslam-vision-train: train the GRNN colour classifier and the HSV baseline, write the colour table"};
    std::string lut_path = std::string(COSLAM_SOURCE_DIR) + "/firmware/vision/data/colour_lut.bin";
    std::string report_path = "out/vision/colour_report.md";
    std::string labelled;
    int n_train = 60, n_val = 30, n_test = 100;
    size_t per_bin = 4;
    app.add_option("--lut", lut_path, "colour table to write")->capture_default_str();
    app.add_option("--report", report_path, "report (markdown)")->capture_default_str();
    const struct {
        const char *name;
        int *frames;
        const char *help;
    } frame_counts[] = {{"--train", &n_train, "rendered training frames (seeds 1000..)"},
                        {"--val", &n_val, "rendered validation frames (seeds 2000..)"},
                        {"--test", &n_test, "rendered held-out test frames (seeds 3000..)"}};
    for (const auto &c : frame_counts) {
        app.add_option(c.name, *c.frames, c.help)->capture_default_str()->check(coslam::cli::int_in(1, 100000));
    }
    app.add_option("--per-bin", per_bin, "GRNN samples per class and colour-table bin")
        ->capture_default_str()
        ->check(coslam::cli::int_in(1, 100000));
    app.add_option("--labelled", labelled, "also train on real labelled images in DIR (NAME.png + NAME_labels.png)");
    if (const int rc = coslam::cli::parse_usage(app, argc, argv); rc >= 0) return rc;

    try {
        const auto t0 = std::chrono::steady_clock::now();
        const sim::Scenario sc = sim::load_scenario_file(paper_scenario_path());
        std::vector<Pixel> train, val, test, test_all;
        render_pixels(sc, 1000, n_train, &train, nullptr);
        if (!labelled.empty()) load_labelled(labelled, &train);
        render_pixels(sc, 2000, n_val, &val, nullptr);
        render_pixels(sc, 3000, n_test, &test, &test_all);
        std::array<size_t, VISION_N_COLOURS> counts{};
        for (const Pixel &p : train) counts[p.label]++;
        std::printf("labelled training pixels (interior):");
        for (int c = 0; c < VISION_N_COLOURS; ++c) std::printf(" %s %zu", kNames[c], counts[static_cast<size_t>(c)]);
        std::printf("\n");

        std::array<double, VISION_N_COLOURS> totals{};
        const std::vector<Sample> samples = subsample(train, per_bin, 7, &totals);
        std::printf("GRNN samples: %zu (at most %zu per class and colour-table bin)\n", samples.size(), per_bin);

        // GRNN: kernel width and class weighting on the validation frames
        std::ostringstream val_table;
        val_table << "| sigma | weighting | validation mean F1 |\n|---|---|---|\n";
        static vision_lut_t grnn_lut, lut;
        GrnnParams best;
        double best_f1 = -1.0;
        std::string best_weighting;
        for (const char *weighting : {"balanced", "empirical"}) {
            for (double sigma : {3.0, 4.5, 6.0, 8.0, 11.0, 16.0}) {
                GrnnParams p;
                p.sigma = sigma;
                for (int c = 0; c < VISION_N_COLOURS; ++c) {
                    const double tot = totals[static_cast<size_t>(c)];
                    p.weight[static_cast<size_t>(c)] = std::string(weighting) == "empirical" ? 1.0 : (tot > 0 ? 1.0 / tot : 0.0);
                }
                grnn_bake(samples, p, &lut);
                const double f1 = score_lut(lut, val).mean_f1();
                char line[128];
                std::snprintf(line, sizeof line, "| %.1f | %s | %.4f |\n", sigma, weighting, f1);
                val_table << line;
                std::printf("GRNN sigma %5.1f %-9s validation mean F1 %.4f\n", sigma, weighting, f1);
                if (f1 > best_f1) {
                    best_f1 = f1;
                    best = p;
                    best_weighting = weighting;
                    grnn_lut = lut;
                }
            }
        }
        std::snprintf(grnn_lut.method, sizeof grnn_lut.method, "grnn sigma=%.1f %s", best.sigma, best_weighting.c_str());

        // HSV baseline
        static vision_lut_t hsv_lut;
        const HsvParams hp = hsv_fit(samples);
        hsv_bake(hp, &hsv_lut);
        std::snprintf(hsv_lut.method, sizeof hsv_lut.method, "hsv s>=%.2f v>=%.2f", hp.s_min, hp.v_min);

        // held-out comparison
        const ClassScores g = score_lut(grnn_lut, test), h = score_lut(hsv_lut, test);
        const ClassScores ga = score_lut(grnn_lut, test_all), ha = score_lut(hsv_lut, test_all);
        const bool grnn_wins = g.mean_f1() >= h.mean_f1();
        const vision_lut_t &chosen = grnn_wins ? grnn_lut : hsv_lut;
        errno = 0;
        const vision_status_t st = vision_lut_save(&chosen, lut_path.c_str());
        if (st == VISION_E_IO) throw coslam::cli::WriteError(lut_path, errno);
        if (st != VISION_OK) throw std::runtime_error("cannot write " + lut_path + ": " + vision_status_name(st));

        std::ostringstream rep;
        rep << "# Colour classification: GRNN vs HSV thresholds\n\n";
        rep << "Generated by `coslam-vision-train` (" << n_train << " training, " << n_val << " validation, " << n_test
            << " held-out test frames; GRNN on " << samples.size() << " weighted samples, at most " << per_bin
            << " per class and colour-table bin).\n\n";
        rep << "Training pixels (interior):";
        for (int c = 0; c < VISION_N_COLOURS; ++c) rep << " " << kNames[c] << " " << counts[static_cast<size_t>(c)];
        rep << ".\n\n## GRNN model selection (validation frames)\n\n" << val_table.str();
        rep << "\nChosen: sigma " << best.sigma << ", " << best_weighting << " class weights.\n\n";
        char hl[256];
        std::snprintf(hl, sizeof hl,
                      "HSV baseline fitted on the training pixels: s >= %.2f, v >= %.2f, hue windows red %.0f+-%.0f, "
                      "yellow %.0f+-%.0f, green %.0f+-%.0f, blue %.0f+-%.0f deg.\n\n",
                      hp.s_min, hp.v_min, hp.hue_deg[1], hp.half_deg[1], hp.hue_deg[2], hp.half_deg[2], hp.hue_deg[3],
                      hp.half_deg[3], hp.hue_deg[4], hp.half_deg[4]);
        rep << hl;
        rep << "## Held-out test frames, interior pixels\n\n" << table(g, h, "GRNN", "HSV");
        rep << "\n## Held-out test frames, every pixel (band edges included)\n\n" << table(ga, ha, "GRNN", "HSV");
        rep << "\nWritten: " << (grnn_wins ? "GRNN" : "HSV") << " (`" << chosen.method << "`) to `" << lut_path << "`.\n";
        const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        rep << "\nTime: " << secs << " s.\n";
        std::filesystem::path rp(report_path);
        if (rp.has_parent_path()) std::filesystem::create_directories(rp.parent_path());
        coslam::cli::write_text_file(report_path, rep.str());
        std::cout << rep.str();
    } catch (const std::exception &e) {
        std::cerr << "coslam-vision-train: " << e.what() << std::endl;
        return 1;
    }
    return 0;
}

// exit status with standard output checked (stdout_check.h)
int main(int argc, char **argv)
{
    return coslam::cli::stdout_exit("coslam-vision-train", vision_train_main(argc, argv));
}
