// host/vision/colour_train.hpp - the colour classifiers behind the colour
// table (vision_lut_t), trained on labelled pixels:
//  - GRNN (the paper's, after Specht 1991): a Gaussian-kernel Parzen
//    estimator over labelled pixels x_i (sRGB, 0..255) with one-hot targets:
//        y_c(x) = sum_i [c_i = c] exp(-|x - x_i|^2 / (2 sigma^2)) / sum_i exp(...)
//    over every labelled pixel i, class(x) = argmax_c y_c(x) (the classes
//    with their empirical priors, or re-weighted to equal priors:
//    "balanced"); a colour with no training pixel within 4 sigma is "none"
//    (the kernels are cut there). The sums run over a weighted stratified
//    subsample that estimates them (subsample()).
//  - HSV thresholds (the plain baseline): saturation >= s_min, value >=
//    v_min, and the hue within a class's window (centre = circular mean of
//    the class's hues, half-width = a percentile of their spread), nearest
//    centre wins; else none.
// Either is baked into the 32x32x32 table by evaluating it at the bins'
// centres, so the robot pays one look-up per pixel.
#ifndef COSLAM_HOST_VISION_COLOUR_TRAIN_HPP
#define COSLAM_HOST_VISION_COLOUR_TRAIN_HPP

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "vision/vision.h"

namespace coslam::vision_host {

struct Pixel {
    uint8_t r, g, b, label;
};

/// Interior pixels of a labelled frame: those whose 3x3 neighbourhood has
/// one label (a person labelling pixels marks regions, not their edges).
void interior_pixels(const uint8_t *rgb, const uint8_t *labels, int w, int h, std::vector<Pixel> *out);
/// Every pixel of a labelled frame.
void all_pixels(const uint8_t *rgb, const uint8_t *labels, int w, int h, std::vector<Pixel> *out);

/// Per-class counts of a classification.
struct ClassScores {
    std::array<double, VISION_N_COLOURS> tp{}, fp{}, fn{};
    double precision(int c) const { return tp[c] + fp[c] > 0 ? tp[c] / (tp[c] + fp[c]) : 1.0; }
    double recall(int c) const { return tp[c] + fn[c] > 0 ? tp[c] / (tp[c] + fn[c]) : 1.0; }
    double f1(int c) const
    {
        const double p = precision(c), r = recall(c);
        return p + r > 0 ? 2 * p * r / (p + r) : 0.0;
    }
    /// Mean F1 over the four marker colours.
    double mean_f1() const;
};

/// Score a table on pixels.
ClassScores score_lut(const vision_lut_t &lut, const std::vector<Pixel> &px);

/// A training sample: a pixel standing for `weight` labelled pixels.
struct Sample {
    uint8_t r, g, b, label;
    double weight;
};

/// Stratified subsample for the GRNN: at most per_bin pixels of each
/// (class, colour-table bin), each weighted by (pixels of that class and
/// bin) / (kept), so that the weighted sum over the samples estimates the
/// sum over every labelled pixel (the full GRNN) while every colour seen in
/// training keeps a sample (the background's rare colours included).
/// class_total[c]: the pixels of class c.
std::vector<Sample> subsample(const std::vector<Pixel> &px, size_t per_bin, uint64_t seed,
                              std::array<double, VISION_N_COLOURS> *class_total);

struct GrnnParams {
    double sigma = 8.0;                              ///< kernel width [sRGB units]
    std::array<double, VISION_N_COLOURS> weight{};   ///< per class: 1 = empirical priors; 1/total = balanced
};

/// GRNN class of one colour.
uint8_t grnn_classify(const std::vector<Sample> &train, const GrnnParams &p, double r, double g, double b);
/// The GRNN baked into a table (evaluated at the bins' centres).
void grnn_bake(const std::vector<Sample> &train, const GrnnParams &p, vision_lut_t *lut);

struct HsvParams {
    std::array<double, VISION_N_COLOURS> hue_deg{};     ///< window centres (0..360)
    std::array<double, VISION_N_COLOURS> half_deg{};    ///< window half-widths
    double s_min = 0.3, v_min = 0.15;                   ///< [0, 1]
};

/// Fit the HSV windows and thresholds on the weighted samples (so that
/// precision counts the background's true share).
HsvParams hsv_fit(const std::vector<Sample> &train);
uint8_t hsv_classify(const HsvParams &p, double r, double g, double b);
void hsv_bake(const HsvParams &p, vision_lut_t *lut);

}  // namespace coslam::vision_host

#endif
