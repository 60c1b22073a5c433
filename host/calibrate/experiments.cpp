// host/calibrate/experiments.cpp - see experiments.h.
#include "experiments.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include "stdout_check.h"

namespace coslam::calibrate {

namespace {

const char *filter_label(run_filter_t f)
{
    return f == RUN_FASTSLAM1 ? "fs1" : f == RUN_FASTSLAM2 ? "fs2" : "ekf";
}

double mean_of(const std::vector<double> &v)
{
    double s = 0.0;
    for (double x : v) {
        s += x;
    }
    return v.empty() ? NAN : s / static_cast<double>(v.size());
}

double se_of(const std::vector<double> &v)
{
    if (v.size() < 2) {
        return 0.0;
    }
    const double m = mean_of(v);
    double ss = 0.0;
    for (double x : v) {
        ss += (x - m) * (x - m);
    }
    return std::sqrt(ss / static_cast<double>(v.size() - 1) / static_cast<double>(v.size()));
}

} // namespace

void run_particle_sweep(const EpisodeContext &base, const std::vector<Episode> &eps, const Weights &w, int jobs,
                        const SweepOptions &opt)
{
    using nlohmann::json;
    const bool root = mpi_rank() == 0;
    std::ostringstream csv, txt;
    csv << "filter,particles,episodes,mean_pos_err_m,pos_err_se_m,mean_cost_m,cost_se_m,lost,cpu_s_per_episode,"
           "diff_mean_m,diff_se_m,upper_m,passes,best,chosen\n";
    json j;
    j["margin"] = opt.margin;
    j["z"] = opt.z;
    j["counts"] = opt.counts;
    for (const auto &e : eps) {
        j["episodes"].push_back(e.label());
    }
    for (run_filter_t f : opt.filters) {
        std::vector<std::vector<EpisodeScore>> scores;
        std::vector<std::vector<double>> cost;
        for (int n : opt.counts) {
            EpisodeContext ctx = base; // one context per count (the Evaluator keeps a reference)
            ctx.synth_filter = f;
            ctx.synth_particles = n;
            const Evaluator ev(ctx, jobs);
            scores.push_back(ev.evaluate({w}, eps)[0]);
            std::vector<double> c;
            for (const auto &s : scores.back()) {
                c.push_back(s.cost);
            }
            cost.push_back(c);
            if (root) {
                std::printf("[sweep] %s N=%d: mean cost %.5f m\n", filter_label(f), n, mean_of(c));
                (void)stdout_check_flush(); // a failure's reason kept for main's check
            }
        }
        const ParticleSelection sel = select_particle_count(cost, opt.margin, opt.z);
        json jf;
        jf["best"] = opt.counts[sel.best];
        jf["chosen"] = opt.counts[sel.chosen];
        jf["bound_m"] = sel.bound_m;
        txt << filter_label(f) << " (" << eps.size() << " episodes)\n"
            << "  N     mean pos err [m]  se       cost [m]  lost  CPU/episode [s]  cost - best [m] (se)   passes\n";
        for (size_t i = 0; i < opt.counts.size(); ++i) {
            std::vector<double> err, cpu;
            int lost = 0;
            for (const auto &s : scores[i]) {
                err.push_back(s.mean_err_m);
                cpu.push_back(s.cpu_s);
                lost += s.stopped_at >= 0;
            }
            const CountStats &c = sel.counts[i];
            char line[256];
            std::snprintf(line, sizeof line, "%s,%d,%zu,%.6g,%.6g,%.6g,%.6g,%d,%.6g,%.6g,%.6g,%.6g,%d,%d,%d\n",
                          filter_label(f), opt.counts[i], eps.size(), mean_of(err), se_of(err), c.mean, c.se, lost,
                          mean_of(cpu), c.diff_mean, c.diff_se, c.upper, c.passes ? 1 : 0, i == sel.best ? 1 : 0,
                          i == sel.chosen ? 1 : 0);
            csv << line;
            std::snprintf(line, sizeof line, "  %-5d %.5f           %.5f  %.5f   %-5d %-16.4g %+.5f (%.5f)     %s%s%s\n",
                          opt.counts[i], mean_of(err), se_of(err), c.mean, lost, mean_of(cpu), c.diff_mean, c.diff_se,
                          c.passes ? "yes" : "no", i == sel.best ? "  best" : "", i == sel.chosen ? "  CHOSEN" : "");
            txt << line;
            json jc{{"particles", opt.counts[i]},  {"mean_pos_err_m", mean_of(err)}, {"pos_err_se_m", se_of(err)},
                    {"mean_cost_m", c.mean},       {"cost_se_m", c.se},              {"lost", lost},
                    {"cpu_s_per_episode", mean_of(cpu)}, {"diff_mean_m", c.diff_mean}, {"diff_se_m", c.diff_se},
                    {"upper_m", c.upper},          {"passes", c.passes}};
            for (size_t e = 0; e < eps.size(); ++e) {
                jc["episodes"].push_back({{"episode", eps[e].label()},
                                          {"cost_m", scores[i][e].cost},
                                          {"mean_pos_err_m", scores[i][e].mean_err_m},
                                          {"stopped_at", scores[i][e].stopped_at},
                                          {"cpu_s", scores[i][e].cpu_s}});
            }
            jf["counts"].push_back(jc);
        }
        char line[256];
        std::snprintf(line, sizeof line,
                      "%s: chosen N = %d (best N = %d, mean cost %.5f m; rule: smallest N with paired mean "
                      "difference + %.3g se <= %.3g x best = %.5f m)\n",
                      filter_label(f), opt.counts[sel.chosen], opt.counts[sel.best], sel.counts[sel.best].mean, opt.z,
                      opt.margin, sel.bound_m);
        txt << line << "\n";
        j["filters"][filter_label(f)] = jf;
    }
    if (root) {
        std::cout << "\n" << txt.str();
        write_text_file(opt.out_dir + "/sweep.csv", csv.str());
        write_text_file(opt.out_dir + "/sweep.json", j.dump(2) + "\n");
        write_text_file(opt.out_dir + "/sweep.txt", txt.str());
        std::cout << "wrote " << opt.out_dir << "/sweep.csv, sweep.json, sweep.txt\n";
    }
}

void run_figures(const EpisodeContext &ctx, const std::vector<Episode> &eps, const Weights &hand,
                 const Weights &calibrated, uint64_t figure_seed, int map_every, int jobs, const std::string &out_dir)
{
    using nlohmann::json;
    const Weights *sets[2] = {&hand, &calibrated};
    const char *names[2] = {"hand", "calibrated"};
    const size_t ne = eps.size();
    std::vector<SynthTrace> tr(2 * ne);
    parallel_for(tr.size(), jobs,
                 [&](size_t k) { tr[k] = run_synth_episode_traced(ctx, eps[k % ne], *sets[k / ne], map_every); });

    // error over time: mean over the episodes at each map checkpoint
    size_t nmap = SIZE_MAX;
    for (const auto &t : tr) {
        nmap = std::min(nmap, t.map_t_s.size());
    }
    std::ofstream ce(out_dir + "/figures_error.csv");
    ce << "t_s,pos_err_hand_m,pos_err_calibrated_m,lm_rmse_hand_m,lm_rmse_calibrated_m,lm_matched_hand,"
          "lm_matched_calibrated,spurious_hand,spurious_calibrated\n";
    for (size_t k = 0; k < nmap; ++k) {
        double pos[2] = {0, 0}, lm[2] = {0, 0}, matched[2] = {0, 0}, spur[2] = {0, 0};
        int nlm[2] = {0, 0};
        for (size_t s = 0; s < 2; ++s) {
            for (size_t e = 0; e < ne; ++e) {
                const SynthTrace &t = tr[s * ne + e];
                const size_t step = (k + 1) * static_cast<size_t>(map_every) - 1; // the checkpoint's step
                pos[s] += t.err_m.at(step);
                if (std::isfinite(t.map_rmse_m[k])) {
                    lm[s] += t.map_rmse_m[k];
                    nlm[s]++;
                }
                matched[s] += t.map_matched[k];
                spur[s] += t.map_spurious[k];
            }
        }
        const double n = static_cast<double>(ne);
        char line[300];
        std::snprintf(line, sizeof line, "%.3f,%.6g,%.6g,%.6g,%.6g,%.4g,%.4g,%.4g,%.4g\n", tr[0].map_t_s[k],
                      pos[0] / n, pos[1] / n, nlm[0] ? lm[0] / nlm[0] : NAN, nlm[1] ? lm[1] / nlm[1] : NAN,
                      matched[0] / n, matched[1] / n, spur[0] / n, spur[1] / n);
        ce << line;
    }
    close_checked(ce, out_dir + "/figures_error.csv");

    // paths and maps of one episode
    size_t fe = 0;
    for (size_t e = 0; e < ne; ++e) {
        if (eps[e].seed == figure_seed) {
            fe = e;
        }
    }
    std::ofstream cp(out_dir + "/figures_path.csv");
    cp << "set,t_s,x_m,y_m\n";
    std::ofstream cm(out_dir + "/figures_map.csv");
    cm << "set,x_m,y_m\n";
    const SynthTrace &t0 = tr[fe];
    for (size_t k = 0; k < t0.truth.size(); k += 5) {
        cp << "truth," << t0.t_s[k] << "," << t0.truth[k].x << "," << t0.truth[k].y << "\n";
    }
    for (const auto &p : t0.lm_truth) {
        cm << "truth," << p.x << "," << p.y << "\n";
    }
    json j;
    j["figure_episode"] = eps[fe].label();
    j["map_every_steps"] = map_every;
    for (size_t s = 0; s < 2; ++s) {
        const SynthTrace &t = tr[s * ne + fe];
        for (size_t k = 0; k < t.est.size(); k += 5) {
            cp << names[s] << "," << t.t_s[k] << "," << t.est[k].x << "," << t.est[k].y << "\n";
        }
        for (const auto &p : t.map_est) {
            cm << names[s] << "," << p.x << "," << p.y << "\n";
        }
        std::vector<double> pos, rmse, spur, missed;
        json je;
        for (size_t e = 0; e < ne; ++e) {
            const SynthTrace &te = tr[s * ne + e];
            pos.push_back(mean_of(te.err_m));
            rmse.push_back(te.final_rmse_m);
            spur.push_back(te.final_spurious);
            missed.push_back(te.final_missed);
            je.push_back({{"episode", eps[e].label()},
                          {"mean_pos_err_m", pos.back()},
                          {"final_lm_rmse_m", te.final_rmse_m},
                          {"final_matched", te.final_matched},
                          {"final_spurious", te.final_spurious},
                          {"final_missed", te.final_missed}});
        }
        j[names[s]] = {{"mean_pos_err_m", mean_of(pos)},    {"pos_err_se_m", se_of(pos)},
                       {"final_lm_rmse_m", mean_of(rmse)},  {"final_lm_rmse_se_m", se_of(rmse)},
                       {"final_spurious", mean_of(spur)},   {"final_missed", mean_of(missed)},
                       {"episodes", je}};
        std::printf("[figures] %-10s held-out mean position error %.5f m (se %.5f), final landmark RMSE %.5f m "
                    "(se %.5f), spurious %.2f, missed %.2f per episode\n",
                    names[s], mean_of(pos), se_of(pos), mean_of(rmse), se_of(rmse), mean_of(spur), mean_of(missed));
    }
    // paired differences calibrated - hand (the same seeds)
    std::vector<double> dpos, dlm;
    for (size_t e = 0; e < ne; ++e) {
        dpos.push_back(mean_of(tr[ne + e].err_m) - mean_of(tr[e].err_m));
        dlm.push_back(tr[ne + e].final_rmse_m - tr[e].final_rmse_m);
    }
    j["paired_calibrated_minus_hand"] = {{"pos_err_m", mean_of(dpos)}, {"pos_err_se_m", se_of(dpos)},
                                         {"lm_rmse_m", mean_of(dlm)},  {"lm_rmse_se_m", se_of(dlm)}};
    std::printf("[figures] calibrated - hand, paired over %zu episodes: position %+.5f m (se %.5f), landmark RMSE "
                "%+.5f m (se %.5f)\n",
                ne, mean_of(dpos), se_of(dpos), mean_of(dlm), se_of(dlm));
    close_checked(cp, out_dir + "/figures_path.csv");
    close_checked(cm, out_dir + "/figures_map.csv");
    write_text_file(out_dir + "/figures.json", j.dump(2) + "\n");
    std::cout << "wrote " << out_dir << "/figures_error.csv, figures_path.csv, figures_map.csv, figures.json\n";
}

} // namespace coslam::calibrate
