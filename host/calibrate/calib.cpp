// host/calibrate/calib.cpp - see calib.h.
#include "calib.h"

#include <nlopt.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <time.h>

#include "cmaes.h"
#include "replay_run.h"

#ifdef COSLAM_HAVE_MPI
#include <mpi.h>
#endif

namespace coslam::calibrate {

namespace {
const char *const kNames[kNW] = {"w1", "w2", "w3", "w4", "w5", "w6", "w7", "w8"};
const char *const kFields[kNW] = {"range_var_m2",           "bearing_var_rad2", "odo_xy_var_m2_per_m",
                                  "odo_theta_var_rad2_per_m", "lm_process_var_m2_per_m", "init_xy_var_m2",
                                  "init_theta_var_rad2",    "lm_init_var_m2"};
const double kZeroRef[kNW] = {1e-4, 1e-4, 1e-4, 1e-4, 1e-5, 1e-4, 1e-4, 1e-4};
} // namespace

const char *weight_name(int i) { return kNames[i]; }
const char *weight_field(int i) { return kFields[i]; }
double zero_start_reference(int i) { return kZeroRef[i]; }

int SearchSpace::dim() const
{
    return static_cast<int>(std::count(searched.begin(), searched.end(), true));
}

Weights SearchSpace::to_weights(const std::vector<double> &y) const
{
    Weights w = start;
    size_t k = 0;
    for (int i = 0; i < kNW; ++i) {
        if (searched[static_cast<size_t>(i)]) {
            const double yi = std::clamp(y[k++], -1.0, 1.0);
            w[static_cast<size_t>(i)] = centre[static_cast<size_t>(i)] * std::pow(factor, yi);
        }
    }
    return w;
}

std::vector<double> SearchSpace::to_coords(const Weights &w) const
{
    std::vector<double> y;
    for (int i = 0; i < kNW; ++i) {
        if (searched[static_cast<size_t>(i)]) {
            const double v = w[static_cast<size_t>(i)] > 0.0 ? w[static_cast<size_t>(i)] : 1e-300;
            y.push_back(std::clamp(std::log(v / centre[static_cast<size_t>(i)]) / std::log(factor), -1.0, 1.0));
        }
    }
    return y;
}

std::vector<double> SearchSpace::start_coords() const { return std::vector<double>(static_cast<size_t>(dim()), 0.0); }

SearchSpace make_space(const Weights &start, double factor, const std::array<bool, kNW> &searched)
{
    SearchSpace s;
    s.start = start;
    s.factor = factor;
    s.searched = searched;
    for (int i = 0; i < kNW; ++i) {
        const size_t u = static_cast<size_t>(i);
        s.centre[u] = start[u] > 0.0 ? start[u] : kZeroRef[i];
    }
    return s;
}

std::string Episode::label() const
{
    if (kind == Synth) {
        return std::string(world == EVAL_WORLD_PAPER ? "paper" : "loop") + (unique ? "-unique" : "") + ":" +
               std::to_string(seed);
    }
    return "robot" + std::to_string(robot) + ":" + std::to_string(seed);
}

EpisodeScore score_errors(const std::vector<double> &err, double stop_error_m, double penalty_factor)
{
    EpisodeScore s;
    s.samples = static_cast<int>(err.size());
    if (err.empty()) {
        s.cost = penalty_factor * stop_error_m;
        s.mean_err_m = NAN;
        return s;
    }
    double sum_all = 0.0;
    double sum_cost = 0.0;
    for (size_t k = 0; k < err.size(); ++k) {
        const double e = std::isfinite(err[k]) ? err[k] : INFINITY;
        sum_all += e;
        if (s.stopped_at < 0) {
            if (e > stop_error_m) {
                // the paper's early stop: the episode ends here, each sample it
                // did not run counts at the penalty
                s.stopped_at = static_cast<int>(k);
                sum_cost += penalty_factor * stop_error_m * static_cast<double>(err.size() - k);
            } else {
                sum_cost += e;
            }
        }
    }
    s.cost = sum_cost / static_cast<double>(err.size());
    s.mean_err_m = sum_all / static_cast<double>(err.size());
    return s;
}

namespace {
// The world (truth noise fixed: the world's) and the filter options of a
// synthetic episode with candidate weights w.
void synth_setup(const EpisodeContext &ctx, const Episode &ep, const Weights &w, synth_config_t &sc, run_opts_t &o)
{
    sc = eval_world_config(ep.world, ep.seed);
    if (ep.unique) {
        sc.n_signatures = 0;
    }
    o = run_opts_default(ctx.synth_filter);
    o.params = ctx.synth_base;
    slam_noise_from_array(&o.params.noise, w.data());
    o.n_particles = ctx.synth_particles;
    o.filter_seed = 7919U * ep.seed + 17U; // as eval_world_run
}

double thread_cpu_s()
{
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}
} // namespace

EpisodeScore run_episode(const EpisodeContext &ctx, const Episode &ep, const Weights &w)
{
    const double cpu0 = thread_cpu_s();
    std::vector<double> err;
    if (ep.kind == Episode::Synth) {
        synth_config_t sc;
        run_opts_t o;
        synth_setup(ctx, ep, w, sc, o);
        run_result_t *res = new run_result_t;
        run_trace_t tr{};
        const int rc = run_synth_traced(&sc, &o, res, &tr);
        delete res;
        if (rc != 0) {
            run_trace_free(&tr);
            throw std::runtime_error("synthetic episode " + ep.label() + " failed to start");
        }
        err.reserve(static_cast<size_t>(tr.n));
        for (int k = 0; k < tr.n; ++k) {
            err.push_back(std::hypot(tr.est[k].x - tr.truth[k].x, tr.est[k].y - tr.truth[k].y));
        }
        run_trace_free(&tr);
    } else {
        replay::ReplayConfig cfg = ctx.replay_cfg;
        slam_noise_from_array(&cfg.slam.noise, w.data());
        cfg.merge.enabled = false; // one robot alone per episode
        cfg.filter.seed = ep.seed;
        replay::ReplayOptions opt;
        opt.robots = {ep.robot};
        opt.duration_s = ctx.duration_s;
        opt.record_history = true;
        const replay::ReplayResult rr = replay::run_replay(*ctx.dataset, cfg, opt);
        for (const auto &p : rr.robots.at(0).path) {
            if (p.has_truth) {
                err.push_back(std::hypot(p.est.x - p.truth.x, p.est.y - p.truth.y));
            }
        }
    }
    EpisodeScore s = score_errors(err, ctx.stop_error_m, ctx.penalty_factor);
    s.cpu_s = thread_cpu_s() - cpu0;
    return s;
}

SynthTrace run_synth_episode_traced(const EpisodeContext &ctx, const Episode &ep, const Weights &w, int map_every)
{
    if (ep.kind != Episode::Synth) {
        throw std::invalid_argument("run_synth_episode_traced: not a synthetic episode");
    }
    synth_config_t sc;
    run_opts_t o;
    synth_setup(ctx, ep, w, sc, o);
    o.trace_map_every = map_every;
    std::unique_ptr<run_result_t> res(new run_result_t);
    run_trace_t tr{};
    if (run_synth_traced(&sc, &o, res.get(), &tr) != 0) {
        run_trace_free(&tr);
        throw std::runtime_error("synthetic episode " + ep.label() + " failed to start");
    }
    SynthTrace out;
    for (int k = 0; k < tr.n; ++k) {
        out.t_s.push_back(tr.t[k]);
        out.est.push_back(tr.est[k]);
        out.truth.push_back(tr.truth[k]);
        out.err_m.push_back(std::hypot(tr.est[k].x - tr.truth[k].x, tr.est[k].y - tr.truth[k].y));
    }
    for (int k = 0; k < tr.n_map; ++k) {
        out.map_t_s.push_back(tr.map_t[k]);
        out.map_rmse_m.push_back(tr.map_rmse_m[k]);
        out.map_matched.push_back(tr.map_matched[k]);
        out.map_spurious.push_back(tr.map_spurious[k]);
    }
    run_trace_free(&tr);
    for (int i = 0; i < res->estimate.n_landmarks; ++i) {
        out.map_est.push_back(res->estimate.lm[i].mean);
    }
    out.final_rmse_m = res->map.rmse_m;
    out.final_matched = res->map.n_matched;
    out.final_spurious = res->map.n_spurious;
    out.final_missed = res->map.n_missed;
    // the truth: synth_init is deterministic in the configuration
    std::unique_ptr<synth_world_t> world(new synth_world_t);
    synth_init(world.get(), &sc);
    out.lm_truth.assign(world->lm, world->lm + world->n_lm);
    return out;
}

ParticleSelection select_particle_count(const std::vector<std::vector<double>> &cost, double margin, double z)
{
    if (cost.empty() || cost[0].empty()) {
        throw std::invalid_argument("select_particle_count: no counts or no episodes");
    }
    if (!(margin >= 0.0) || !(z >= 0.0)) {
        throw std::invalid_argument("select_particle_count: margin and z must be >= 0");
    }
    const size_t ne = cost[0].size();
    ParticleSelection sel;
    sel.counts.resize(cost.size());
    for (size_t i = 0; i < cost.size(); ++i) {
        if (cost[i].size() != ne) {
            throw std::invalid_argument("select_particle_count: every count needs the same episodes");
        }
        double sum = 0.0;
        for (double c : cost[i]) {
            if (!std::isfinite(c)) {
                throw std::invalid_argument("select_particle_count: a cost is not finite");
            }
            sum += c;
        }
        const double mean = sum / static_cast<double>(ne);
        double ss = 0.0;
        for (double c : cost[i]) {
            ss += (c - mean) * (c - mean);
        }
        sel.counts[i].mean = mean;
        sel.counts[i].se = ne > 1 ? std::sqrt(ss / static_cast<double>(ne - 1) / static_cast<double>(ne)) : 0.0;
        if (mean < sel.counts[sel.best].mean) {
            sel.best = i; // strict: the smaller count wins a tie
        }
    }
    sel.bound_m = margin * sel.counts[sel.best].mean;
    sel.chosen = sel.best;
    for (size_t i = cost.size(); i-- > 0;) {
        CountStats &c = sel.counts[i];
        double dsum = 0.0;
        for (size_t e = 0; e < ne; ++e) {
            dsum += cost[i][e] - cost[sel.best][e];
        }
        c.diff_mean = dsum / static_cast<double>(ne);
        double ss = 0.0;
        for (size_t e = 0; e < ne; ++e) {
            const double d = cost[i][e] - cost[sel.best][e] - c.diff_mean;
            ss += d * d;
        }
        c.diff_se = ne > 1 ? std::sqrt(ss / static_cast<double>(ne - 1) / static_cast<double>(ne)) : 0.0;
        c.upper = c.diff_mean + z * c.diff_se;
        c.passes = i == sel.best || c.upper <= sel.bound_m;
        if (c.passes) {
            sel.chosen = i; // walking down: ends at the smallest count that passes
        }
    }
    return sel;
}

// ---------------------------------------------------------------- MPI

int mpi_rank()
{
#ifdef COSLAM_HAVE_MPI
    int r = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &r);
    return r;
#else
    return 0;
#endif
}

int mpi_size()
{
#ifdef COSLAM_HAVE_MPI
    int s = 1;
    MPI_Comm_size(MPI_COMM_WORLD, &s);
    return s;
#else
    return 1;
#endif
}

bool mpi_enabled()
{
#ifdef COSLAM_HAVE_MPI
    return true;
#else
    return false;
#endif
}

// ---------------------------------------------------------------- evaluator

void parallel_for(size_t n, int threads, const std::function<void(size_t)> &task)
{
    std::atomic<size_t> next{0};
    std::atomic<bool> failed{false};
    std::string fail_msg;
    std::mutex fail_mu;
    auto worker = [&]() {
        for (;;) {
            const size_t k = next.fetch_add(1);
            if (k >= n || failed.load()) {
                return;
            }
            try {
                task(k);
            } catch (const std::exception &e) {
                std::lock_guard<std::mutex> lk(fail_mu);
                if (!failed) {
                    fail_msg = e.what();
                }
                failed = true;
            }
        }
    };
    const size_t nthr = std::min<size_t>(static_cast<size_t>(std::max(1, threads)), std::max<size_t>(1, n));
    std::vector<std::thread> pool;
    for (size_t i = 1; i < nthr; ++i) {
        pool.emplace_back(worker);
    }
    worker();
    for (auto &th : pool) {
        th.join();
    }
    if (failed) {
        throw std::runtime_error(fail_msg);
    }
}

Evaluator::Evaluator(const EpisodeContext &ctx, int threads) : ctx_(ctx), threads_(std::max(1, threads)) {}

std::vector<std::vector<EpisodeScore>> Evaluator::evaluate(const std::vector<Weights> &cands,
                                                           const std::vector<Episode> &eps) const
{
    const size_t ne = eps.size();
    const size_t nt = cands.size() * ne;
    const int rank = mpi_rank();
    const int size = mpi_size();
    // kSlot doubles per task: cost, mean error, stop index, samples, CPU time
    constexpr size_t kSlot = 5;
    std::vector<double> slots(nt * kSlot, 0.0);
    std::vector<size_t> mine;
    for (size_t t = 0; t < nt; ++t) {
        if (static_cast<int>(t % static_cast<size_t>(size)) == rank) {
            mine.push_back(t);
        }
    }
    parallel_for(mine.size(), threads_, [&](size_t k) {
        const size_t t = mine[k];
        const EpisodeScore s = run_episode(ctx_, eps[t % ne], cands[t / ne]);
        slots[kSlot * t + 0] = s.cost;
        slots[kSlot * t + 1] = s.mean_err_m;
        slots[kSlot * t + 2] = s.stopped_at;
        slots[kSlot * t + 3] = s.samples;
        slots[kSlot * t + 4] = s.cpu_s;
    });
#ifdef COSLAM_HAVE_MPI
    if (size > 1) {
        // x + 0.0 is exact: the sum over ranks is the owner's value
        MPI_Allreduce(MPI_IN_PLACE, slots.data(), static_cast<int>(slots.size()), MPI_DOUBLE, MPI_SUM,
                      MPI_COMM_WORLD);
    }
#endif
    episodes_run_ += static_cast<long>(nt);
    std::vector<std::vector<EpisodeScore>> out(cands.size(), std::vector<EpisodeScore>(ne));
    for (size_t t = 0; t < nt; ++t) {
        EpisodeScore &s = out[t / ne][t % ne];
        s.cost = slots[kSlot * t + 0];
        s.mean_err_m = slots[kSlot * t + 1];
        s.stopped_at = static_cast<int>(slots[kSlot * t + 2]);
        s.samples = static_cast<int>(slots[kSlot * t + 3]);
        s.cpu_s = slots[kSlot * t + 4];
    }
    return out;
}

double Evaluator::fitness(const std::vector<EpisodeScore> &s)
{
    double sum = 0.0;
    for (const auto &e : s) {
        sum += e.cost; // fixed order: deterministic
    }
    return s.empty() ? INFINITY : sum / static_cast<double>(s.size());
}

// ---------------------------------------------------------------- optimisers

const char *optimiser_name(Optimiser o)
{
    switch (o) {
    case Optimiser::Cmaes:
        return "cmaes";
    case Optimiser::Esch:
        return "esch";
    case Optimiser::Isres:
        return "isres";
    }
    return "?";
}

bool optimiser_parse(const std::string &s, Optimiser &o)
{
    if (s == "cmaes" || s == "cma-es") {
        o = Optimiser::Cmaes;
    } else if (s == "esch") {
        o = Optimiser::Esch;
    } else if (s == "isres") {
        o = Optimiser::Isres;
    } else {
        return false;
    }
    return true;
}

namespace {

struct GenTracker {
    const SearchOptions &opt;
    SearchResult &res;
    int gen = 0;
    double best = INFINITY, sum = 0.0;
    int n = 0;
    void add(double f)
    {
        best = std::min(best, f);
        sum += f;
        ++n;
    }
    void close()
    {
        if (n == 0) {
            return;
        }
        GenerationLog g{++gen, res.evals, best, sum / n, res.best_fitness};
        res.history.push_back(g);
        if (opt.on_generation) {
            opt.on_generation(g);
        }
        best = INFINITY;
        sum = 0.0;
        n = 0;
    }
};

struct NloptCtx {
    const SearchSpace *space;
    const Evaluator *ev;
    const std::vector<Episode> *train;
    SearchResult *res;
    GenTracker *gt;
    int pop;
    nlopt_opt opt;
    std::string error; ///< an exception inside the objective (C code in between: not thrown through it)
};

double nlopt_objective(unsigned n, const double *x, double *grad, void *data)
{
    (void)grad;
    auto *c = static_cast<NloptCtx *>(data);
    const std::vector<double> y(x, x + n);
    const Weights w = c->space->to_weights(y);
    double f = INFINITY;
    try {
        f = Evaluator::fitness(c->ev->evaluate({w}, *c->train)[0]);
    } catch (const std::exception &e) {
        c->error = e.what();
        nlopt_force_stop(c->opt);
        return f;
    }
    c->res->evals++;
    if (f < c->res->best_fitness) {
        c->res->best_fitness = f;
        c->res->best = w;
    }
    c->gt->add(f);
    if (c->gt->n >= c->pop) {
        c->gt->close();
    }
    return f;
}

} // namespace

SearchResult run_search(const SearchSpace &space, const Evaluator &ev, const std::vector<Episode> &train,
                        const SearchOptions &opt)
{
    SearchResult res;
    // The start is the first candidate (one evaluation of the budget): the
    // result is never worse than the start on the training episodes.
    res.best = space.start;
    res.best_fitness = Evaluator::fitness(ev.evaluate({space.start}, train)[0]);
    res.evals = 1;
    GenTracker gt{opt, res};
    const int n = space.dim();
    if (n == 0) {
        res.stop_reason = "nothing to search";
        return res;
    }
    if (opt.optimiser == Optimiser::Cmaes) {
        CmaesOptions co;
        co.lambda = opt.lambda;
        co.sigma0 = opt.sigma0;
        co.seed = opt.seed;
        co.lower = Eigen::VectorXd::Constant(n, -1.0);
        co.upper = Eigen::VectorXd::Constant(n, 1.0);
        Cmaes es(Eigen::VectorXd::Zero(n), co);
        res.stop_reason = "evaluation budget";
        while (res.evals + es.lambda() <= opt.max_evals) {
            const auto &X = es.ask();
            std::vector<Weights> cands;
            for (const auto &x : X) {
                const Eigen::VectorXd p = es.project(x);
                cands.push_back(space.to_weights(std::vector<double>(p.data(), p.data() + n)));
            }
            const auto sc = ev.evaluate(cands, train);
            std::vector<double> f(cands.size());
            for (size_t k = 0; k < cands.size(); ++k) {
                f[k] = Evaluator::fitness(sc[k]);
                res.evals++;
                gt.add(f[k]);
                if (f[k] < res.best_fitness) {
                    res.best_fitness = f[k];
                    res.best = cands[k];
                }
            }
            gt.close();
            es.tell_penalised(f);
            if (es.sigma() * std::sqrt(es.cov().diagonal().maxCoeff()) < 1e-4) {
                res.stop_reason = "step size below 1e-4 (converged)";
                break;
            }
            if (es.condition() > 1e14) {
                res.stop_reason = "condition of C above 1e14";
                break;
            }
        }
        return res;
    }
    const nlopt_algorithm alg = opt.optimiser == Optimiser::Esch ? NLOPT_GN_ESCH : NLOPT_GN_ISRES;
    nlopt_opt o = nlopt_create(alg, static_cast<unsigned>(n));
    const std::vector<double> lo(static_cast<size_t>(n), -1.0);
    const std::vector<double> hi(static_cast<size_t>(n), 1.0);
    nlopt_set_lower_bounds(o, lo.data());
    nlopt_set_upper_bounds(o, hi.data());
    const int pop = opt.lambda > 0 ? opt.lambda : 4 + static_cast<int>(std::floor(3.0 * std::log(n)));
    nlopt_set_population(o, static_cast<unsigned>(pop));
    nlopt_set_maxeval(o, static_cast<int>(std::max(1L, opt.max_evals - 1)));
    nlopt_srand(opt.seed); // NLopt's one global generator: set once, before the run
    NloptCtx c{&space, &ev, &train, &res, &gt, pop, o, {}};
    nlopt_set_min_objective(o, nlopt_objective, &c);
    std::vector<double> x = space.start_coords();
    double fmin = 0.0;
    const nlopt_result r = nlopt_optimize(o, x.data(), &fmin);
    gt.close();
    nlopt_destroy(o);
    if (!c.error.empty()) {
        throw std::runtime_error(c.error);
    }
    res.stop_reason = r == NLOPT_MAXEVAL_REACHED ? "evaluation budget" : ("nlopt result " + std::to_string(r));
    return res;
}

} // namespace coslam::calibrate
