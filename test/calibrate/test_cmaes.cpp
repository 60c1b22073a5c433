// test_cmaes.cpp - the CMA-ES of host/calibrate (Hansen 2016) on functions
// whose minimum is known, in 8-D like the paper's eight weights; the
// emulated early stop of an episode (calib.h score_errors); the log-space
// search box.
#include <gtest/gtest.h>

#include <cmath>

#include "calib.h"
#include "cmaes.h"

using namespace coslam::calibrate;

namespace {

// f(x) = sum 10^(6 (i-1)/(n-1)) (R x)_i^2: condition 1e6, axes rotated by a
// fixed random orthogonal R, so a separable method cannot solve it.
Eigen::MatrixXd rotation(int n, uint64_t seed)
{
    Rng rng(seed);
    Eigen::MatrixXd A(n, n);
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            A(i, j) = rng.normal();
        }
    }
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(A);
    return qr.householderQ();
}

double ellipsoid(const Eigen::MatrixXd &R, const Eigen::VectorXd &x)
{
    const Eigen::VectorXd y = R * x;
    const int n = static_cast<int>(x.size());
    double f = 0.0;
    for (int i = 0; i < n; ++i) {
        f += std::pow(1e6, static_cast<double>(i) / (n - 1)) * y(i) * y(i);
    }
    return f;
}

double rosenbrock(const Eigen::VectorXd &x)
{
    double f = 0.0;
    for (int i = 0; i + 1 < x.size(); ++i) {
        f += 100.0 * std::pow(x(i + 1) - x(i) * x(i), 2) + std::pow(1.0 - x(i), 2);
    }
    return f;
}

template <class F> double minimise(Cmaes &es, F f, int max_gen, double ftol)
{
    double best = INFINITY;
    for (int g = 0; g < max_gen && best > ftol; ++g) {
        const auto &X = es.ask();
        std::vector<double> v;
        for (const auto &x : X) {
            v.push_back(f(x));
        }
        es.tell(v);
        best = es.best_f();
    }
    return best;
}

} // namespace

TEST(Cmaes, RotatedEllipsoid8D)
{
    const int n = 8;
    const Eigen::MatrixXd R = rotation(n, 42);
    CmaesOptions o;
    o.sigma0 = 0.5;
    o.seed = 7;
    Cmaes es(Eigen::VectorXd::Constant(n, 1.0), o);
    EXPECT_EQ(es.lambda(), 10); // 4 + floor(3 ln 8)
    const double f = minimise(es, [&](const Eigen::VectorXd &x) { return ellipsoid(R, x); }, 2000, 1e-10);
    std::printf("ellipsoid: f %.3g after %d generations, condition of C %.3g\n", f, es.generation(), es.condition());
    EXPECT_LT(f, 1e-10);
    // C learnt the Hessian's shape: its condition approaches 1e6
    EXPECT_GT(es.condition(), 1e4);
    EXPECT_LT(es.best_x().norm(), 1e-3);
}

TEST(Cmaes, Rosenbrock8D)
{
    const int n = 8;
    CmaesOptions o;
    o.sigma0 = 0.5;
    o.seed = 3;
    Cmaes es(Eigen::VectorXd::Zero(n), o);
    const double f = minimise(es, rosenbrock, 5000, 1e-10);
    std::printf("rosenbrock: f %.3g after %d generations\n", f, es.generation());
    EXPECT_LT(f, 1e-10);
    EXPECT_LT((es.best_x() - Eigen::VectorXd::Ones(n)).norm(), 1e-4);
}

TEST(Cmaes, BoundedOptimumOnTheBox)
{
    // minimum of |x - c|^2 + 1 with c outside [-1, 1]^8: the projection of c
    const int n = 8;
    Eigen::VectorXd c = Eigen::VectorXd::Constant(n, 0.5);
    c(0) = 3.0;
    c(5) = -2.0;
    CmaesOptions o;
    o.sigma0 = 0.3;
    o.lower = Eigen::VectorXd::Constant(n, -1.0);
    o.upper = Eigen::VectorXd::Constant(n, 1.0);
    Cmaes es(Eigen::VectorXd::Zero(n), o);
    for (int g = 0; g < 400; ++g) {
        const auto &X = es.ask();
        std::vector<double> v;
        for (const auto &x : X) {
            v.push_back((es.project(x) - c).squaredNorm() + 1.0);
        }
        es.tell_penalised(v);
    }
    const Eigen::VectorXd p = es.project(es.mean());
    EXPECT_NEAR(p(0), 1.0, 1e-3);
    EXPECT_NEAR(p(5), -1.0, 1e-3);
    EXPECT_NEAR(p(2), 0.5, 1e-3);
}

TEST(Cmaes, DeterministicForASeed)
{
    CmaesOptions o;
    o.seed = 11;
    Cmaes a(Eigen::VectorXd::Zero(8), o), b(Eigen::VectorXd::Zero(8), o);
    minimise(a, rosenbrock, 50, 0.0);
    minimise(b, rosenbrock, 50, 0.0);
    EXPECT_EQ(a.best_f(), b.best_f());
    EXPECT_TRUE(a.mean() == b.mean());
}

TEST(Calib, EarlyStopPenalty)
{
    // runs to the end: the mean
    EpisodeScore s = score_errors({0.1, 0.2, 0.3}, 1.0, 2.0);
    EXPECT_DOUBLE_EQ(s.cost, 0.2);
    EXPECT_EQ(s.stopped_at, -1);
    // passes 1 m at sample 2: samples 2 and 3 count 2 m each
    s = score_errors({0.1, 0.5, 1.5, 0.2}, 1.0, 2.0);
    EXPECT_EQ(s.stopped_at, 2);
    EXPECT_DOUBLE_EQ(s.cost, (0.1 + 0.5 + 2.0 + 2.0) / 4.0);
    EXPECT_DOUBLE_EQ(s.mean_err_m, (0.1 + 0.5 + 1.5 + 0.2) / 4.0);
    // a diverged filter (nan) stops too
    s = score_errors({0.1, NAN}, 1.0, 2.0);
    EXPECT_EQ(s.stopped_at, 1);
    EXPECT_DOUBLE_EQ(s.cost, (0.1 + 2.0) / 2.0);
}

TEST(Calib, LogSpaceBox)
{
    Weights w0{0.01, 0.04, 1e-3, 2e-3, 0.0, 0.0, 1e-2, 0.0};
    std::array<bool, kNW> searched;
    searched.fill(true);
    searched[6] = false;
    const SearchSpace sp = make_space(w0, 16.0, searched);
    EXPECT_EQ(sp.dim(), 7);
    const Weights mid = sp.to_weights(sp.start_coords());
    EXPECT_DOUBLE_EQ(mid[0], 0.01);
    EXPECT_DOUBLE_EQ(mid[4], zero_start_reference(4)); // zero start: searched around the reference
    EXPECT_DOUBLE_EQ(mid[6], 1e-2);                    // fixed
    std::vector<double> y(7, 1.0);
    y[1] = -1.0;
    const Weights hi = sp.to_weights(y);
    EXPECT_NEAR(hi[0], 0.16, 1e-12);
    EXPECT_NEAR(hi[1], 0.04 / 16.0, 1e-12);
    const auto back = sp.to_coords(hi);
    EXPECT_NEAR(back[0], 1.0, 1e-12);
    EXPECT_NEAR(back[1], -1.0, 1e-12);
}
