// host/calibrate/cmaes.h - a compact (mu/mu_w, lambda)-CMA-ES.
//
// N. Hansen, "The CMA Evolution Strategy: A Tutorial", arXiv:1604.00772
// (2016), Table 1 and Fig. 6 (the algorithm box): default strategy
// parameters, weighted recombination of the mu best, cumulative step-size
// adaptation (CSA, eq. 43-44), rank-one (eq. 24, with the h_sigma stall of
// Sec. B.2) and rank-mu (eq. 30) covariance updates. Positive weights only
// (the original mu/mu_w scheme, no active CMA).
//
// Ask/tell: ask() returns lambda points, tell() takes their fitness (lower
// is better) in the same order. The caller evaluates the population however
// it likes (threads, MPI), which is why this is not a minimize(f) loop.
//
// Box bounds (optional): a point outside is evaluated by the caller at its
// projection into the box (project()) and the fitness is inflated by the
// squared distance to the box, f * (1 + |x - proj(x)|^2) (Hansen's
// "repair + penalty" in its simplest form; fitness must be > 0 for that,
// which a mean position error is). tell_penalised() does that.
//
// Deterministic: own RNG (splitmix64 + Box-Muller), no std::*_distribution
// (whose output differs between standard libraries).
#ifndef COSLAM_CALIBRATE_CMAES_H
#define COSLAM_CALIBRATE_CMAES_H

#include <Eigen/Dense>
#include <cstdint>
#include <vector>

namespace coslam::calibrate {

/// Deterministic uniform/normal generator (splitmix64).
class Rng {
public:
    explicit Rng(uint64_t seed) : s_(seed) {}
    uint64_t next_u64();
    double uniform(); ///< in (0, 1)
    double normal();  ///< standard normal (Box-Muller, one of the pair cached)

private:
    uint64_t s_;
    bool has_spare_ = false;
    double spare_ = 0.0;
};

struct CmaesOptions {
    int lambda = 0;        ///< population size; 0: 4 + floor(3 ln n) (Table 1)
    double sigma0 = 0.3;   ///< initial step size (coordinates of the search space)
    uint64_t seed = 1;
    Eigen::VectorXd lower; ///< box bounds; empty: unbounded
    Eigen::VectorXd upper;
};

class Cmaes {
public:
    Cmaes(const Eigen::VectorXd &x0, const CmaesOptions &opt);

    /// Sample the next population (lambda points). Call tell() before the next ask().
    const std::vector<Eigen::VectorXd> &ask();
    /// Fitness of the points of the last ask(), same order; lower is better.
    void tell(const std::vector<double> &fitness);
    /// Projection of x into the bounds (x itself when unbounded).
    Eigen::VectorXd project(const Eigen::VectorXd &x) const;
    /// tell() with f_i given at project(x_i): applies f_i (1 + |x_i - proj(x_i)|^2).
    void tell_penalised(const std::vector<double> &f_at_projection);

    int lambda() const { return lambda_; }
    int mu() const { return mu_; }
    int generation() const { return gen_; }
    double sigma() const { return sigma_; }
    const Eigen::VectorXd &mean() const { return m_; }
    const Eigen::MatrixXd &cov() const { return C_; }
    /// Best point ever told and its fitness (as told, penalty included).
    const Eigen::VectorXd &best_x() const { return best_x_; }
    double best_f() const { return best_f_; }
    /// Condition number of C (max/min eigenvalue).
    double condition() const;

private:
    void eigen_update();

    int n_;
    int lambda_;
    int mu_;
    Eigen::VectorXd w_;
    double mueff_, cc_, cs_, c1_, cmu_, damps_, chin_;
    Eigen::VectorXd m_;
    double sigma_;
    Eigen::MatrixXd C_, B_;
    Eigen::VectorXd D_; ///< sqrt of C's eigenvalues
    Eigen::VectorXd pc_, ps_;
    Eigen::VectorXd lower_, upper_;
    std::vector<Eigen::VectorXd> x_, y_;
    Rng rng_;
    int gen_ = 0;
    Eigen::VectorXd best_x_;
    double best_f_;
};

} // namespace coslam::calibrate

#endif
