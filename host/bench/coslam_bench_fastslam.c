/*
 * coslam-bench-fastslam - Fast-SLAM at scale: time per control step of
 * Fast-SLAM 2.0 (100 and 1000 particles) against the map size (64, 256,
 * 1024, 2048 landmarks), the shared landmark tree of the core ("tree")
 * against the former flat array per particle ("flat", host/bench/ref), same
 * workload, same run (bench_fs_driver.h). A benchmark, not a test: prints a
 * table and writes <out>/fastslam_scale.{md,json}.
 *   coslam-bench-fastslam [--out DIR] [--seeds N] [--steps N] [--no-flat] [--cpu-time]
 * --cpu-time times with the thread's CPU clock instead of the wall clock
 * (for a shared machine: other processes' load does not count).
 * Built against a core of 1000 particles x 2048 landmarks.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bench_fs.h"
#include "profile_print.h"
#include "bench_args.h"
#include "bench_report.h"
#include "stdout_check.h"

int bench_fs_cpu_clock = 0;

#define N_M 4
#define N_P 2

typedef struct {
    double step, step_max, update, rs, rs_max, sight, err;
    int resamples;
} cell_t;

static int run(int impl, const bench_fs_case_t *base, int seeds, cell_t *out)
{
    memset(out, 0, sizeof *out);
    for (int s = 0; s < seeds; ++s) {
        bench_fs_case_t c = *base;
        c.seed = 900U + (uint64_t)s;
        bench_fs_result_t r;
        const int st = impl ? bench_fs_new_run(&c, &r) : bench_fs_ref_run(&c, &r);
        if (st != 0) {
            return st;
        }
        out->step += r.step_us_mean / seeds;
        out->update += r.update_us_mean / seeds;
        out->rs += r.resample_us_mean / seeds;
        out->sight += r.sightings_per_frame / seeds;
        out->err += r.final_pos_err_m / seeds;
        out->resamples += r.resamples;
        out->step_max = r.step_us_max > out->step_max ? r.step_us_max : out->step_max;
        out->rs_max = r.resample_us_max > out->rs_max ? r.resample_us_max : out->rs_max;
    }
    return 0;
}

static int bench_fastslam_main(int argc, char **argv)
{
    const char *out = "out/bench";
    int seeds = 2;
    int steps = 600;
    int flat = 1;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
        else if (!strcmp(argv[i], "--seeds") && i + 1 < argc) {
            if (bench_arg_int("coslam-bench-fastslam", "--seeds", argv[++i], 1, 100, &seeds) != 0) return 2;
        } else if (!strcmp(argv[i], "--steps") && i + 1 < argc) {
            if (bench_arg_int("coslam-bench-fastslam", "--steps", argv[++i], 2, 100000, &steps) != 0) return 2;
        } else if (!strcmp(argv[i], "--no-flat")) flat = 0;
        else if (!strcmp(argv[i], "--cpu-time")) bench_fs_cpu_clock = 1;
        else {
            fprintf(stderr, "usage: coslam-bench-fastslam [--out DIR] [--seeds N] [--steps N] [--no-flat] [--cpu-time]\n");
            return 2;
        }
    }
    profile_print(stdout, "coslam-bench-fastslam");
    if (mkdir(out, 0775) != 0 && errno != EEXIST) {
        fprintf(stderr, "coslam-bench-fastslam: cannot create %s: %s\n", out, strerror(errno));
        return 1;
    }
    const int ms[N_M] = {64, 256, 1024, 2048};
    const int ps[N_P] = {100, 1000};
    static cell_t cell[2][N_P][N_M]; /* [flat, tree] */
    /* warm-up, untimed: the first touch of the largest state (page faults)
     * must not land in either implementation's first cell */
    {
        const bench_fs_case_t w = {ps[N_P - 1], ms[N_M - 1], 2, 1U, 1};
        bench_fs_result_t r;
        if ((flat && bench_fs_ref_run(&w, &r) != 0) || bench_fs_new_run(&w, &r) != 0) {
            fprintf(stderr, "coslam-bench-fastslam: warm-up failed\n");
            return 1;
        }
    }
    for (int p = 0; p < N_P; ++p) {
        for (int k = 0; k < N_M; ++k) {
            const bench_fs_case_t c = {ps[p], ms[k], steps, 0U, 1};
            for (int impl = flat ? 0 : 1; impl < 2; ++impl) {
                if (run(impl, &c, seeds, &cell[impl][p][k]) != 0) {
                    fprintf(stderr, "coslam-bench-fastslam: run failed (N %d, M %d)\n", ps[p], ms[k]);
                    return 1;
                }
                fprintf(stderr, ".");
            }
        }
    }
    fprintf(stderr, "\n");
    FILE *md = NULL;
    FILE *js = NULL;
    if (bench_report_open("coslam-bench-fastslam", out, "fastslam_scale", &md, &js) != 0) {
        return 1;
    }
    FILE *sinks[2] = {stdout, md};
    for (int o = 0; o < 2; ++o) {
        FILE *f = sinks[o];
        fprintf(f, "Fast-SLAM 2.0 per control step (predict at 10 Hz, update at 5 Hz, resampling when ESS < N/2) "
                   "against the map size, microseconds of %s, mean over %d runs of %d steps (max single step in "
                   "brackets); resampling alone: mean (max). flat = one landmark array per particle (before), "
                   "tree = shared landmark tree (now). Ratio t(2048)/t(64): %.2f for growth in log M.\n\n",
                bench_fs_cpu_clock ? "thread CPU time" : "wall time", seeds, steps, log(2048.0) / log(64.0));
        fprintf(f, "| particles | landmarks | sightings/frame | step flat | step tree | resample flat | resample tree "
                   "| update tree | step speed-up |\n|---|---|---|---|---|---|---|---|---|\n");
        for (int p = 0; p < N_P; ++p) {
            for (int k = 0; k < N_M; ++k) {
                const cell_t *a = &cell[0][p][k];
                const cell_t *b = &cell[1][p][k];
                if (flat) {
                    fprintf(f, "| %d | %d | %.1f | %.1f (%.0f) | %.1f (%.0f) | %.1f (%.0f) | %.1f (%.0f) | %.1f | %.1fx |\n",
                            ps[p], ms[k], b->sight, a->step, a->step_max, b->step, b->step_max, a->rs, a->rs_max, b->rs,
                            b->rs_max, b->update, a->step / b->step);
                } else {
                    fprintf(f, "| %d | %d | %.1f | - | %.1f (%.0f) | - | %.1f (%.0f) | %.1f | - |\n", ps[p], ms[k],
                            b->sight, b->step, b->step_max, b->rs, b->rs_max, b->update);
                }
            }
        }
        fprintf(f, "\nRatio t(2048)/t(64) of the mean step:");
        for (int p = 0; p < N_P; ++p) {
            fprintf(f, " %d particles: tree %.2f", ps[p], cell[1][p][N_M - 1].step / cell[1][p][0].step);
            if (flat) {
                fprintf(f, ", flat %.2f", cell[0][p][N_M - 1].step / cell[0][p][0].step);
            }
            fprintf(f, p + 1 < N_P ? ";" : ".\n");
        }
    }
    fprintf(js, "{\n  \"clock\": \"%s\",\n  \"seeds\": %d,\n  \"steps\": %d,\n  \"landmarks\": [64, 256, 1024, 2048],\n  \"runs\": [\n",
            bench_fs_cpu_clock ? "thread_cpu" : "wall", seeds, steps);
    for (int impl = flat ? 0 : 1; impl < 2; ++impl) {
        for (int p = 0; p < N_P; ++p) {
            const cell_t *c = cell[impl][p];
            static const char *const keys[] = {"step_us_mean", "step_us_max", "resample_us_mean", "update_us_mean",
                                               "final_pos_err_m"};
            const int decimals[] = {2, 0, 2, 2, 3};
            fprintf(js, "    {\"impl\": \"%s\", \"particles\": %d", impl ? "tree" : "flat", ps[p]);
            for (int q = 0; q < 5; ++q) {
                double v[N_M];
                for (int k = 0; k < N_M; ++k) {
                    v[k] = q == 0 ? c[k].step : q == 1 ? c[k].step_max : q == 2 ? c[k].rs : q == 3 ? c[k].update : c[k].err;
                }
                fprintf(js, ", \"%s\": ", keys[q]);
                bench_json_array(js, v, N_M, decimals[q]);
            }
            fprintf(js, "}%s\n", (impl == 1 && p == N_P - 1) ? "" : ",");
        }
    }
    fprintf(js, "  ]\n}\n");
    if (bench_report_close("coslam-bench-fastslam", out, "fastslam_scale", md, js) != 0) {
        return 1;
    }
    return 0;
}

/* exit status with standard output checked (stdout_check.h) */
int main(int argc, char **argv)
{
    return stdout_check_exit("coslam-bench-fastslam", bench_fastslam_main(argc, argv));
}
