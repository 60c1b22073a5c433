// host/calibrate/cmaes.cpp - see cmaes.h (Hansen 2016 tutorial, Fig. 6).
#include "cmaes.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace coslam::calibrate {

uint64_t Rng::next_u64()
{
    uint64_t z = (s_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

double Rng::uniform()
{
    // 53 random bits, shifted off 0
    return (static_cast<double>(next_u64() >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

double Rng::normal()
{
    if (has_spare_) {
        has_spare_ = false;
        return spare_;
    }
    const double u1 = uniform();
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    const double a = 2.0 * M_PI * u2;
    spare_ = r * std::sin(a);
    has_spare_ = true;
    return r * std::cos(a);
}

Cmaes::Cmaes(const Eigen::VectorXd &x0, const CmaesOptions &opt)
    : n_(static_cast<int>(x0.size())), m_(x0), sigma_(opt.sigma0), lower_(opt.lower), upper_(opt.upper),
      rng_(opt.seed), best_f_(std::numeric_limits<double>::infinity())
{
    if (n_ < 1 || !(opt.sigma0 > 0.0) || !std::isfinite(opt.sigma0)) {
        throw std::invalid_argument("cmaes: need n >= 1 and a finite sigma0 > 0");
    }
    if (lower_.size() != 0 && (lower_.size() != n_ || upper_.size() != n_)) {
        throw std::invalid_argument("cmaes: bounds must have the dimension of x0");
    }
    const double n = n_;
    // Table 1 of the tutorial
    lambda_ = opt.lambda > 0 ? opt.lambda : 4 + static_cast<int>(std::floor(3.0 * std::log(n)));
    if (lambda_ < 2) {
        throw std::invalid_argument("cmaes: lambda must be >= 2");
    }
    mu_ = lambda_ / 2;
    w_.resize(mu_);
    for (int i = 0; i < mu_; ++i) {
        w_(i) = std::log((lambda_ + 1) / 2.0) - std::log(i + 1.0);
    }
    w_ /= w_.sum();
    mueff_ = 1.0 / w_.squaredNorm();
    cc_ = (4.0 + mueff_ / n) / (n + 4.0 + 2.0 * mueff_ / n);
    cs_ = (mueff_ + 2.0) / (n + mueff_ + 5.0);
    c1_ = 2.0 / ((n + 1.3) * (n + 1.3) + mueff_);
    cmu_ = std::min(1.0 - c1_, 2.0 * (mueff_ - 2.0 + 1.0 / mueff_) / ((n + 2.0) * (n + 2.0) + mueff_));
    damps_ = 1.0 + 2.0 * std::max(0.0, std::sqrt((mueff_ - 1.0) / (n + 1.0)) - 1.0) + cs_;
    chin_ = std::sqrt(n) * (1.0 - 1.0 / (4.0 * n) + 1.0 / (21.0 * n * n));
    C_ = Eigen::MatrixXd::Identity(n_, n_);
    B_ = Eigen::MatrixXd::Identity(n_, n_);
    D_ = Eigen::VectorXd::Ones(n_);
    pc_ = Eigen::VectorXd::Zero(n_);
    ps_ = Eigen::VectorXd::Zero(n_);
    best_x_ = m_;
}

Eigen::VectorXd Cmaes::project(const Eigen::VectorXd &x) const
{
    if (lower_.size() == 0) {
        return x;
    }
    return x.cwiseMax(lower_).cwiseMin(upper_);
}

const std::vector<Eigen::VectorXd> &Cmaes::ask()
{
    x_.assign(static_cast<size_t>(lambda_), Eigen::VectorXd());
    y_.assign(static_cast<size_t>(lambda_), Eigen::VectorXd());
    for (int k = 0; k < lambda_; ++k) {
        Eigen::VectorXd z(n_);
        for (int i = 0; i < n_; ++i) {
            z(i) = rng_.normal();
        }
        y_[static_cast<size_t>(k)] = B_ * D_.cwiseProduct(z);      // y ~ N(0, C)
        x_[static_cast<size_t>(k)] = m_ + sigma_ * y_[static_cast<size_t>(k)]; // x ~ N(m, sigma^2 C)
    }
    return x_;
}

void Cmaes::tell_penalised(const std::vector<double> &f)
{
    std::vector<double> g(f.size());
    for (size_t k = 0; k < f.size() && k < x_.size(); ++k) {
        const double d2 = (x_[k] - project(x_[k])).squaredNorm();
        g[k] = f[k] * (1.0 + d2);
    }
    tell(g);
}

void Cmaes::tell(const std::vector<double> &f)
{
    if (static_cast<int>(f.size()) != lambda_ || static_cast<int>(x_.size()) != lambda_) {
        throw std::invalid_argument("cmaes: tell() needs the fitness of the last ask()");
    }
    std::vector<int> idx(static_cast<size_t>(lambda_));
    std::iota(idx.begin(), idx.end(), 0);
    // stable: ties keep sampling order, so the result does not depend on the sort
    std::stable_sort(idx.begin(), idx.end(), [&](int a, int b) {
        const double fa = std::isnan(f[static_cast<size_t>(a)]) ? INFINITY : f[static_cast<size_t>(a)];
        const double fb = std::isnan(f[static_cast<size_t>(b)]) ? INFINITY : f[static_cast<size_t>(b)];
        return fa < fb;
    });
    const size_t i0 = static_cast<size_t>(idx[0]);
    if (f[i0] < best_f_) {
        best_f_ = f[i0];
        best_x_ = x_[i0];
    }
    const double n = n_;
    // selection and recombination (eq. 39-41, c_m = 1)
    Eigen::VectorXd yw = Eigen::VectorXd::Zero(n_);
    for (int i = 0; i < mu_; ++i) {
        yw += w_(i) * y_[static_cast<size_t>(idx[static_cast<size_t>(i)])];
    }
    m_ += sigma_ * yw;
    // step-size control (eq. 43): C^{-1/2} = B D^{-1} B^T
    const Eigen::VectorXd cinv_yw = B_ * (B_.transpose() * yw).cwiseQuotient(D_);
    ps_ = (1.0 - cs_) * ps_ + std::sqrt(cs_ * (2.0 - cs_) * mueff_) * cinv_yw;
    // covariance adaptation (eq. 45, 47) with h_sigma (Sec. B.2)
    const double ps_norm = ps_.norm();
    const double denom = std::sqrt(1.0 - std::pow(1.0 - cs_, 2.0 * (gen_ + 1)));
    const bool hsig = ps_norm / denom / chin_ < 1.4 + 2.0 / (n + 1.0);
    pc_ = (1.0 - cc_) * pc_ + (hsig ? std::sqrt(cc_ * (2.0 - cc_) * mueff_) : 0.0) * yw;
    Eigen::MatrixXd rank_mu = Eigen::MatrixXd::Zero(n_, n_);
    for (int i = 0; i < mu_; ++i) {
        const Eigen::VectorXd &y = y_[static_cast<size_t>(idx[static_cast<size_t>(i)])];
        rank_mu += w_(i) * y * y.transpose();
    }
    const double dh = hsig ? 0.0 : cc_ * (2.0 - cc_);
    C_ = (1.0 - c1_ - cmu_) * C_ + c1_ * (pc_ * pc_.transpose() + dh * C_) + cmu_ * rank_mu;
    // eq. 44
    sigma_ *= std::exp((cs_ / damps_) * (ps_norm / chin_ - 1.0));
    ++gen_;
    eigen_update();
}

void Cmaes::eigen_update()
{
    // enforce symmetry, then C = B diag(D^2) B^T
    Eigen::MatrixXd Cs = 0.5 * (C_ + C_.transpose());
    C_ = Cs;
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(C_);
    B_ = es.eigenvectors();
    D_ = es.eigenvalues().cwiseMax(1e-300).cwiseSqrt();
}

double Cmaes::condition() const
{
    const double dmax = D_.maxCoeff();
    const double dmin = D_.minCoeff();
    return dmax * dmax / (dmin * dmin);
}

} // namespace coslam::calibrate
