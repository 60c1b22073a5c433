/*
 * coslam-bench-scale - time per filter step against the size of the map
 * (issue 13): the large world's field (host/synth/eval_worlds.h, 2
 * landmarks per m^2 of 4 classes, about 20 sightings per frame) with 1,024
 * and 2,048 landmarks, one seeded run per filter; every control step
 * (predict at 10 Hz, update at 5 Hz) is timed and binned by the number of
 * landmarks in the filter's map at that step (run_result_t.size_bin_us:
 * within a factor sqrt 2 of 64, 256, 1,024, 2,048). The sightings per frame
 * stay the same as the map grows, so the table isolates the map size.
 * EKF-SLAM runs the 1,024-landmark field (its state holds at most
 * COSLAM_EKF_MAX_LANDMARKS), Fast-SLAM 2.0 the 2,048-landmark one. Also the
 * run's accuracy (final position error, pose RMSE, spurious landmarks).
 * The worst step of each run (run_result_t.step_us_max) is in the table
 * too: the compressed EKF's global update lands in one step.
 * Writes <out>/scale_step_time.{md,json}.
 *   coslam-bench-scale [--out DIR] [--seed S] [--quick | --ekf]
 * --quick: Fast-SLAM 2.0 with 100 particles only; --ekf: EKF-SLAM only (one
 * or the other: both together are refused, exit 2). --seed S: a whole number >= 0.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bench_args.h"
#include "bench_report.h"
#include "eval_worlds.h"
#include "profile_print.h"
#include "stdout_check.h"

typedef struct {
    const char *name;
    run_filter_t filter;
    int n_particles;
    int n_landmarks; /* of the world */
} scale_case_t;

static const int k_bins[4] = {6, 8, 10, 11}; /* 64, 256, 1024, 2048 */

static int bench_scale_main(int argc, char **argv)
{
    const char *out = "out/bench";
    long seed = 1;
    int quick = 0;
    int ekf_only = 0;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
        else if (!strcmp(argv[i], "--seed") && i + 1 < argc) {
            if (bench_arg_long("coslam-bench-scale", "--seed", argv[++i], 0, LONG_MAX, &seed) != 0) return 2;
        } else if (!strcmp(argv[i], "--quick")) quick = 1;
        else if (!strcmp(argv[i], "--ekf")) ekf_only = 1;
        else { fprintf(stderr, "usage: coslam-bench-scale [--out DIR] [--seed S] [--quick | --ekf]\n"); return 2; }
    }
    if (quick && ekf_only) {
        fprintf(stderr, "coslam-bench-scale: --quick (Fast-SLAM 2.0, 100 particles) and --ekf (EKF-SLAM) are "
                        "alternatives: give one\n");
        return 2;
    }
    profile_print(stdout, "coslam-bench-scale");
    if (COSLAM_MAX_PARTICLES < 1000 || COSLAM_MAX_LANDMARKS < 2048 || COSLAM_EKF_MAX_LANDMARKS < 1024 ||
        COSLAM_MAX_SIGHTINGS < 40) {
        fprintf(stderr, "coslam-bench-scale: needs 1000 particles, 2048 landmarks (EKF-SLAM 1024) and 40 sightings "
                        "per frame, more than this build's profile %s has: build with PROFILE=host (make bench does)\n",
                COSLAM_PROFILE_NAME);
        return 2;
    }
    if (mkdir(out, 0775) != 0 && errno != EEXIST) {
        fprintf(stderr, "coslam-bench-scale: cannot create %s: %s\n", out, strerror(errno));
        return 1;
    }
    const scale_case_t all[] = {
        {"EKF-SLAM", RUN_EKFSLAM, 1, 1024},
        {"Fast-SLAM 2.0, 100 particles", RUN_FASTSLAM2, 100, 2048},
        {"Fast-SLAM 2.0, 1000 particles", RUN_FASTSLAM2, 1000, 2048},
    };
    const scale_case_t *cases = quick ? &all[1] : all;
    const int nc = quick || ekf_only ? 1 : 3;
    run_result_t *r = malloc(sizeof *r);
    double bin_us[3][4];
    int bin_n[3][4];
    double final_err[3], pose_rmse[3], max_ms[3];
    double idle_ms[3] = {0.0, 0.0, 0.0};
    int spurious[3], estimated[3], n_lm[3];
    if (r == NULL) {
        return 1;
    }
    for (int c = 0; c < nc; ++c) {
        const synth_config_t sc = eval_world_large_config((uint64_t)seed, cases[c].n_landmarks);
        run_opts_t o = run_opts_default(cases[c].filter);
        o.params = sc.truth;
        o.n_particles = cases[c].n_particles;
        o.filter_seed = 7919U * (uint64_t)seed + 17U;
        if (run_synth(&sc, &o, r) != 0) {
            fprintf(stderr, "coslam-bench-scale: run failed (%s)\n", cases[c].name);
            free(r);
            return 1;
        }
        for (int b = 0; b < 4; ++b) {
            bin_us[c][b] = r->size_bin_us[k_bins[b]];
            bin_n[c][b] = r->size_bin_steps[k_bins[b]];
        }
        max_ms[c] = 1e-3 * r->step_us_max;
        idle_ms[c] = 1e-3 * r->idle_us_mean;
        final_err[c] = r->final_pos_err_m;
        pose_rmse[c] = r->pose_rmse_m;
        spurious[c] = r->map.n_spurious;
        estimated[c] = r->map.n_estimated;
        n_lm[c] = r->n_final_landmarks;
        fprintf(stderr, "coslam-bench-scale: %s done (%d steps, %u capacity errors)\n", cases[c].name, r->n_steps,
                r->capacity_errors);
    }
    FILE *md = NULL;
    FILE *js = NULL;
    if (bench_report_open("coslam-bench-scale", out, "scale_step_time", &md, &js) != 0) {
        free(r);
        return 1;
    }
    FILE *sinks[2] = {stdout, md};
    for (int k = 0; k < 2; ++k) {
        FILE *f = sinks[k];
        fprintf(f, "Time per control step [ms] (predict at 10 Hz + update at 5 Hz, about 20 sightings per frame) "
                   "by the map's size at that step (within a factor sqrt 2; steps in brackets); growth exponent b "
                   "of t ~ L^b between the first and the last bin measured; worst: the slowest step of the run. Seed %ld.\n\n",
                seed);
        fprintf(f, "| filter | 64 | 256 | 1,024 | 2,048 | b | worst ms | final error m | pose RMSE m | spurious / exported | "
                   "landmarks at the end |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
        for (int c = 0; c < nc; ++c) {
            fprintf(f, "| %s |", cases[c].name);
            int first = -1, last = -1;
            for (int b = 0; b < 4; ++b) {
                if (bin_n[c][b] > 0) {
                    fprintf(f, " %.3f (%d) |", 1e-3 * bin_us[c][b], bin_n[c][b]);
                    first = first < 0 ? b : first;
                    last = b;
                } else {
                    fprintf(f, " n/a |");
                }
            }
            const double lf = pow(4.0, (double)first) * 64.0, ll = (last == 3 ? 2048.0 : pow(4.0, (double)last) * 64.0);
            if (first >= 0 && last > first) {
                fprintf(f, " %.2f |", log(bin_us[c][last] / bin_us[c][first]) / log(ll / lf));
            } else {
                fprintf(f, " n/a |");
            }
            fprintf(f, " %.1f | %.3f | %.3f | %d / %d | %d |\n", max_ms[c], final_err[c], pose_rmse[c], spurious[c], estimated[c],
                    n_lm[c]);
        }
        for (int c = 0; c < nc; ++c) {
            if (idle_ms[c] > 0.0) {
                fprintf(f, "\n%s: the compressed EKF's region switches and deferred completion run in the idle time after each step "
                           "(slam_filter_idle, as on the robot), not in the step times above: %.3f ms per step on average.\n",
                        cases[c].name, idle_ms[c]);
            }
        }
    }
    fprintf(js, "{\n  \"profile\": \"%s\",\n  \"seed\": %ld,\n  \"bins_landmarks\": [64, 256, 1024, 2048],\n"
                "  \"filters\": [\n", COSLAM_PROFILE_NAME, seed);
    for (int c = 0; c < nc; ++c) {
        /* a size bin no step fell in: null (it was 0) */
        double step_ms[4];
        for (int b = 0; b < 4; ++b) {
            step_ms[b] = bin_n[c][b] > 0 ? 1e-3 * bin_us[c][b] : NAN;
        }
        const double fig[] = {max_ms[c], final_err[c], pose_rmse[c]};
        static const char *const fig_keys[] = {"worst_step_ms", "final_error_m", "pose_rmse_m"};
        fprintf(js, "    {\"name\": \"%s\", \"world_landmarks\": %d, \"step_ms\": ", cases[c].name, cases[c].n_landmarks);
        bench_json_array(js, step_ms, 4, 4);
        fprintf(js, ", \"steps\": [%d, %d, %d, %d]", bin_n[c][0], bin_n[c][1], bin_n[c][2], bin_n[c][3]);
        bench_json_fields(js, fig_keys, fig, 3, 4);
        fprintf(js, ", \"spurious\": %d, \"exported\": %d, \"idle_ms_mean\": ", spurious[c], estimated[c]);
        bench_json_num(js, idle_ms[c], 4);
        fprintf(js, "}%s\n", c + 1 < nc ? "," : "");
    }
    fprintf(js, "  ]\n}\n");
    if (bench_report_close("coslam-bench-scale", out, "scale_step_time", md, js) != 0) {
        return 1;
    }
    free(r);
    return 0;
}

/* exit status with standard output checked (stdout_check.h) */
int main(int argc, char **argv)
{
    return stdout_check_exit("coslam-bench-scale", bench_scale_main(argc, argv));
}
