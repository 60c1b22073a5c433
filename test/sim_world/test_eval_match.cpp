// test/sim_world/test_eval_match.cpp - the evaluation's landmark matching
// (assign_gated, host/synth/stats.h) against one square assignment problem
// solved whole (the former method), and the simulator's memory bound.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "coslam/rng.h"
#include "sim/world/scenario.hpp"
#include "sim/world/simulation.hpp"
#include "stats.h"

namespace {

struct Outcome {
    int pairs = 0;
    double sum_d2 = 0.0;
};

double d2(point2_t a, point2_t b)
{
    return (a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y);
}

// Reference: one square problem over everything, non-candidates prohibitive.
Outcome reference(const std::vector<point2_t> &e, const std::vector<uint8_t> &es, const std::vector<point2_t> &t,
                  const std::vector<uint8_t> &ts, double gate)
{
    const int n = static_cast<int>(e.size()), nt = static_cast<int>(t.size());
    const int sz = std::max(n, nt);
    const double g2 = gate * gate, big = 1e9;
    std::vector<double> cost(static_cast<size_t>(sz * sz), g2);
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < nt; ++j) {
            const double v = d2(e[i], t[j]);
            cost[static_cast<size_t>(i * sz + j)] = (es[i] == ts[j] && v < g2) ? v : big;
        }
    }
    std::vector<int> r2c(static_cast<size_t>(sz));
    hungarian(cost.data(), sz, sz, r2c.data());
    Outcome o;
    for (int i = 0; i < n; ++i) {
        const int j = r2c[static_cast<size_t>(i)];
        if (j < nt && cost[static_cast<size_t>(i * sz + j)] < g2) {
            o.pairs++;
            o.sum_d2 += cost[static_cast<size_t>(i * sz + j)];
        }
    }
    return o;
}

TEST(AssignGated, SameAsOneSquareProblemOnClutteredMaps)
{
    rng_t rng;
    rng_seed(&rng, 20261202u);
    for (int trial = 0; trial < 400; ++trial) {
        const int nt = 1 + static_cast<int>(rng_uniform(&rng) * 14);
        const int n = static_cast<int>(rng_uniform(&rng) * 16);
        const double gate = 0.3 + rng_uniform(&rng) * 0.5;
        std::vector<point2_t> t, e;
        std::vector<uint8_t> ts, es;
        for (int j = 0; j < nt; ++j) {
            // clusters: several true landmarks within a gate of each other
            t.push_back({std::floor(rng_uniform(&rng) * 3) * 2.0 + rng_uniform(&rng) * 0.8,
                         rng_uniform(&rng) * 0.8});
            ts.push_back(static_cast<uint8_t>(rng_uniform(&rng) * 2));
        }
        for (int i = 0; i < n; ++i) {
            const point2_t base = t[static_cast<size_t>(rng_uniform(&rng) * nt)];
            e.push_back({base.x + rng_normal(&rng, 0.0, 0.3), base.y + rng_normal(&rng, 0.0, 0.3)});
            es.push_back(static_cast<uint8_t>(rng_uniform(&rng) * 2));
        }
        std::vector<int> match(static_cast<size_t>(std::max(n, 1)), -2);
        ASSERT_EQ(assign_gated(e.data(), es.data(), n, t.data(), ts.data(), nt, gate, match.data()), 0);
        Outcome got;
        std::vector<int> used(static_cast<size_t>(nt), 0);
        for (int i = 0; i < n; ++i) {
            const int j = match[static_cast<size_t>(i)];
            if (j < 0) {
                ASSERT_EQ(j, -1);
                continue;
            }
            ASSERT_LT(j, nt);
            ASSERT_EQ(used[static_cast<size_t>(j)]++, 0) << "a true landmark matched twice";
            ASSERT_EQ(es[static_cast<size_t>(i)], ts[static_cast<size_t>(j)]);
            ASSERT_LT(d2(e[i], t[j]), gate * gate);
            got.pairs++;
            got.sum_d2 += d2(e[i], t[j]);
        }
        const Outcome ref = reference(e, es, t, ts, gate);
        ASSERT_EQ(got.pairs, ref.pairs) << "trial " << trial;
        ASSERT_NEAR(got.sum_d2, ref.sum_d2, 1e-9) << "trial " << trial;
    }
}

TEST(AssignGated, TenThousandLandmarksIsCheapAndExact)
{
    // a 100 x 100 grid of landmarks 1 m apart, estimates 0.1 m off: every
    // one matched, far beyond what one 10,000^2 problem could be solved in
    const int side = 100;
    std::vector<point2_t> t, e;
    for (int i = 0; i < side; ++i) {
        for (int j = 0; j < side; ++j) {
            t.push_back({1.0 * i, 1.0 * j});
            e.push_back({1.0 * i + 0.1, 1.0 * j - 0.05});
        }
    }
    std::vector<int> match(e.size());
    ASSERT_EQ(assign_gated(e.data(), nullptr, static_cast<int>(e.size()), t.data(), nullptr,
                           static_cast<int>(t.size()), 0.3, match.data()),
              0);
    for (size_t i = 0; i < e.size(); ++i) {
        ASSERT_EQ(match[i], static_cast<int>(i));
    }
}

TEST(SimulationMemory, SeriesAndTruthHistoryStayBounded)
{
    // the default scenario with tiny bounds: 120 s of 10 ms control steps is
    // 12,000 truth entries and 1,200 path points at 0.1 s without them
    coslam::sim::Scenario sc = coslam::sim::load_scenario_file(COSLAM_SOURCE_DIR "/sim/scenarios/paper.toml");
    sc.camera.source = coslam::sim::CameraSource::Oracle;
    coslam::sim::SimulationOptions opt;
    opt.duration_s = 120.0;
    opt.max_series = 64;
    opt.truth_hist_keep = 1024;
    coslam::sim::Simulation sim(sc, opt);
    sim.run(nullptr, 1.0);
    const auto &res = sim.result();
    for (const auto &r : res.robots) {
        EXPECT_LE(r.est_path.size(), 64u);
        EXPECT_GE(r.est_path.size(), 32u);
        EXPECT_EQ(r.est_path.size(), r.truth_path.size());
        EXPECT_LE(r.errors.size(), 64u);
        // thinned series still span the run
        EXPECT_GT(r.est_path.back().first, 100.0);
        EXPECT_TRUE(std::isfinite(r.pose_rmse_m));
        EXPECT_LT(r.pose_rmse_m, 1.0);
    }
}

} // namespace
