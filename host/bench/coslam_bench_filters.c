/*
 * coslam-bench-filters - time per filter step of the SLAM core on seeded
 * synthetic runs (host/synth), for EKF-SLAM and Fast-SLAM 1.0/2.0 with 100
 * and 1000 particles, at 15, 64 and 150 landmarks. A benchmark, not a test:
 * it prints a table and writes it to <out>/core_step_time.{md,json}.
 *   coslam-bench-filters [--out DIR] [--seeds N]
 * Time per step = wall time of one predict (10 Hz odometry) plus, every
 * second step, one update (5 Hz camera), averaged over the run; the max is
 * the slowest single step. Built against the large-capacity core.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "slam_run.h"
#include "bench_args.h"
#include "bench_report.h"
#include "profile_print.h"
#include "stdout_check.h"

typedef struct {
    const char *name;
    run_filter_t filter;
    int n_particles;
} bench_filter_t;

static int bench_filters_main(int argc, char **argv)
{
    const char *out = "out/bench";
    int seeds = 3;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
        else if (!strcmp(argv[i], "--seeds") && i + 1 < argc) {
            if (bench_arg_int("coslam-bench-filters", "--seeds", argv[++i], 1, 100, &seeds) != 0) return 2;
        } else { fprintf(stderr, "usage: coslam-bench-filters [--out DIR] [--seeds N]\n"); return 2; }
    }
    profile_print(stdout, "coslam-bench-filters");
    if (COSLAM_MAX_PARTICLES < 1000 || COSLAM_MAX_LANDMARKS < 150) {
        fprintf(stderr, "coslam-bench-filters: needs 1000 particles and 150 landmarks, more than this build's profile "
                        "%s has: build with PROFILE=host (make bench does)\n", COSLAM_PROFILE_NAME);
        return 2;
    }
    if (mkdir(out, 0775) != 0 && errno != EEXIST) {
        fprintf(stderr, "coslam-bench-filters: cannot create %s: %s\n", out, strerror(errno));
        return 1;
    }
    const bench_filter_t filters[] = {
        {"EKF-SLAM", RUN_EKFSLAM, 0},
        {"Fast-SLAM 1.0, 100 particles", RUN_FASTSLAM1, 100},
        {"Fast-SLAM 1.0, 1000 particles", RUN_FASTSLAM1, 1000},
        {"Fast-SLAM 2.0, 100 particles", RUN_FASTSLAM2, 100},
        {"Fast-SLAM 2.0, 1000 particles", RUN_FASTSLAM2, 1000},
    };
    const int counts[3] = {15, 64, 150};
    const int nf = (int)(sizeof filters / sizeof filters[0]);
    double mean_us[8][3];
    double max_us[8][3];
    double lm_rmse[8][3];
    run_result_t *r = malloc(sizeof *r);
    for (int f = 0; f < nf; ++f) {
        for (int c = 0; c < 3; ++c) {
            double sm = 0.0, mx = 0.0, rm = 0.0;
            for (int s = 0; s < seeds; ++s) {
                synth_config_t sc = synth_config_default(500U + (uint64_t)s, counts[c]);
                sc.loop_radius_m = 2.5;
                sc.ring_half_width_m = 2.0;
                sc.n_signatures = 4;
                run_opts_t o = run_opts_default(filters[f].filter);
                o.params = sc.truth;
                o.n_particles = filters[f].n_particles > 0 ? filters[f].n_particles : 1;
                if (run_synth(&sc, &o, r) != 0) {
                    fprintf(stderr, "coslam-bench-filters: run failed\n");
                    return 1;
                }
                sm += r->step_us_mean;
                mx = r->step_us_max > mx ? r->step_us_max : mx;
                rm += r->map.rmse_m;
            }
            mean_us[f][c] = sm / seeds;
            max_us[f][c] = mx;
            lm_rmse[f][c] = rm / seeds;
            fprintf(stderr, ".");
        }
    }
    fprintf(stderr, "\n");
    FILE *md = NULL;
    FILE *js = NULL;
    if (bench_report_open("coslam-bench-filters", out, "core_step_time", &md, &js) != 0) {
        return 1;
    }
    FILE *sinks[2] = {stdout, md};
    for (int k = 0; k < 2; ++k) {
        FILE *o = sinks[k];
        fprintf(o, "Time per control step (predict at 10 Hz + update at 5 Hz), mean over %d seeded runs "
                   "(max single step in brackets), microseconds; growth exponent b of t ~ L^b from 15 to 150 landmarks.\n\n",
                seeds);
        fprintf(o, "| filter | 15 landmarks | 64 landmarks | 150 landmarks | growth b |\n|---|---|---|---|---|\n");
        for (int f = 0; f < nf; ++f) {
            const double b = log(mean_us[f][2] / mean_us[f][0]) / log(150.0 / 15.0);
            fprintf(o, "| %s | %.1f (%.0f) | %.1f (%.0f) | %.1f (%.0f) | %.2f |\n", filters[f].name, mean_us[f][0],
                    max_us[f][0], mean_us[f][1], max_us[f][1], mean_us[f][2], max_us[f][2], b);
        }
        fprintf(o, "\nLandmark RMSE of the same runs [m]:\n\n| filter | 15 | 64 | 150 |\n|---|---|---|---|\n");
        for (int f = 0; f < nf; ++f) {
            fprintf(o, "| %s | %.3f | %.3f | %.3f |\n", filters[f].name, lm_rmse[f][0], lm_rmse[f][1], lm_rmse[f][2]);
        }
    }
    fprintf(js, "{\n  \"profile\": \"%s\",\n  \"seeds\": %d,\n  \"landmarks\": [15, 64, 150],\n  \"filters\": [\n", COSLAM_PROFILE_NAME, seeds);
    for (int f = 0; f < nf; ++f) {
        fprintf(js, "    {\"name\": \"%s\", \"step_us_mean\": ", filters[f].name);
        bench_json_array(js, mean_us[f], 3, 2);
        fputs(", \"step_us_max\": ", js);
        bench_json_array(js, max_us[f], 3, 1);
        fputs(", \"landmark_rmse_m\": ", js);
        bench_json_array(js, lm_rmse[f], 3, 4);
        fprintf(js, "}%s\n", f + 1 < nf ? "," : "");
    }
    fprintf(js, "  ]\n}\n");
    if (bench_report_close("coslam-bench-filters", out, "core_step_time", md, js) != 0) {
        return 1;
    }
    free(r);
    return 0;
}

/* exit status with standard output checked (stdout_check.h) */
int main(int argc, char **argv)
{
    return stdout_check_exit("coslam-bench-filters", bench_filters_main(argc, argv));
}
