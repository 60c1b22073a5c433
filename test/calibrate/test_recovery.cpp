// test_recovery.cpp - the calibration recovers known noise (issue 14).
//
// Synthetic episodes (host/synth, the paper world of eval_worlds.h) are
// generated with known weights: the world's truth, slam_params_default()
// (w1..w4 as in docs/noise-model.md; w5..w8 = 0: static landmarks, start
// pose known exactly, no unmodelled initialisation error). The filter
// (EKF-SLAM) starts 4x off in each of w1..w4, alternately above and below;
// w5..w8 start at 0 and are searched around their zero-start references
// (calib.h). CMA-ES on the training seeds, then:
//  - w2 (bearing), w3 (odometry x/y) and w4 (odometry heading) must land
//    within a factor kTol of the truth: these are the identifiable weights
//    (docs/calibration.md, "Identifiability": the fitness rises clearly
//    when one of them is off by 2x);
//  - w1 (range variance at 0 m) is small next to the 3 %-of-range term
//    (range_var_per_m2) the filter keeps; w5..w8 have a truth of 0 which a
//    log-space search cannot reach, and at these values they barely move
//    the position error: printed, not asserted;
//  - the fitness on held-out seeds is lower than at the start.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "calib.h"

using namespace coslam::calibrate;

namespace {
// within this factor of the truth. docs/calibration.md, "Recovery": over
// 16 seeds the fitness profile of w2..w4 is flat to a few per cent between
// 1/2x and 2x of the truth (the position-error optimum is not sharper than
// that), measured landing 1.14x / 0.49x / 1.70x (160 evaluations) and
// 1.42x / 0.60x / 1.42x (250); 2.5 leaves room for the
// search's own spread while still failing a search that stays 4x off.
constexpr double kTol = 2.5;
} // namespace

TEST(Recovery, KnownNoiseFrom4xOff)
{
    EpisodeContext ctx;
    ctx.synth_filter = RUN_EKFSLAM;
    ctx.synth_base = slam_params_default();
    ctx.stop_error_m = 1.0;
    ctx.penalty_factor = 2.0;
    Weights truth;
    slam_noise_to_array(&ctx.synth_base.noise, truth.data());
    Weights start = truth;
    const double off[4] = {4.0, 0.25, 4.0, 0.25};
    for (int i = 0; i < 4; ++i) {
        start[static_cast<size_t>(i)] *= off[i];
    }
    std::array<bool, kNW> searched;
    searched.fill(true);
    const SearchSpace space = make_space(start, 16.0, searched);
    std::vector<Episode> train, test;
    // 16 seeds: with 6 the search fits those seeds' association luck and
    // lands up to 3x off (docs/calibration.md)
    const int n_train = COSLAM_TEST_FULL ? 24 : 16;
    for (int s = 1; s <= n_train; ++s) {
        train.push_back({Episode::Synth, EVAL_WORLD_PAPER, static_cast<uint64_t>(s), 0});
    }
    for (int s = 201; s <= 208; ++s) {
        test.push_back({Episode::Synth, EVAL_WORLD_PAPER, static_cast<uint64_t>(s), 0});
    }
    const Evaluator ev(ctx, 2);
    SearchOptions so;
    so.optimiser = Optimiser::Cmaes;
    so.max_evals = COSLAM_TEST_FULL ? 600 : 160;
    so.seed = 1;
    so.on_generation = [](const GenerationLog &g) {
        std::printf("gen %3d evals %4ld best %.5f mean %.5f best-ever %.5f\n", g.generation, g.evals, g.best, g.mean,
                    g.best_ever);
    };
    const SearchResult r = run_search(space, ev, train, so);
    std::printf("weight  truth        start        result       result/truth\n");
    for (int i = 0; i < kNW; ++i) {
        const size_t u = static_cast<size_t>(i);
        std::printf("%-7s %-12.4g %-12.4g %-12.4g %s\n", weight_name(i), truth[u], start[u], r.best[u],
                    truth[u] > 0 ? std::to_string(r.best[u] / truth[u]).c_str() : "(truth 0)");
    }
    for (int i : {1, 2, 3}) {
        const size_t u = static_cast<size_t>(i);
        const double ratio = r.best[u] / truth[u];
        EXPECT_LT(ratio, kTol) << weight_name(i);
        EXPECT_GT(ratio, 1.0 / kTol) << weight_name(i);
    }
    const auto te = ev.evaluate({start, r.best, truth}, test);
    const double f0 = Evaluator::fitness(te[0]), f1 = Evaluator::fitness(te[1]), ft = Evaluator::fitness(te[2]);
    std::printf("held-out fitness: start %.5f, calibrated %.5f, truth %.5f\n", f0, f1, ft);
    EXPECT_LT(f1, f0);
}
