/*
 * coslam-bench-odo-check: cost of the health monitor's scan-to-scan
 * odometry check (firmware/app odo_check.h). A robot drives an arc through
 * a 6 m x 4 m room with a box (the ray caster of test/app/room_scan.h: 401
 * rays over 140 deg, 4 m), one scan every 0.1 s, so a check (three ICP
 * starts) runs every fifth scan. Reports the thread CPU time per check and
 * per scan that only keeps its points, and the monitor's memory. Writes
 * <out>/odo_check.md.
 *   coslam-bench-odo-check [--out DIR] [--checks N] [--odo-scale-pct P]
 * Exit status (also in --help): 0 done, nothing flagged; 1 the report or
 * standard output could not be written (or the monitor not set up); 2 bad
 * usage; 3 the check flagged the drive (disagreements or mismatches), the
 * report written. 1 and 3 were both 1: a caller (make bench) could not
 * tell a lost report from a false alarm of the monitor.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "app/odo_check.h"
#include "room_scan.h"
#include "profile_print.h"
#include "bench_args.h"
#include "bench_report.h"
#include "stdout_check.h"

/* Exit codes: kExitFlagged is a finding (a fault-free drive flagged is a
 * false report of the monitor), not a failure of the bench. */
enum { kExitOk = 0, kExitWrite = 1, kExitUsage = 2, kExitFlagged = 3 };

static const char kUsage[] = "usage: coslam-bench-odo-check [--out DIR] [--checks N] [--odo-scale-pct P]\n";

static void print_help(void)
{
    printf("%s"
           "Thread CPU time of the scan-to-scan odometry check (firmware/app odo_check.h) on a drive\n"
           "through a simulated room; the table on stdout and in DIR/odo_check.md.\n"
           "  --out DIR          report folder (default out/bench)\n"
           "  --checks N         judged checks to time, [1, 1000000] (default 400)\n"
           "  --odo-scale-pct P  odometry given to the check: P %% of the true motion, [10, 1000]\n"
           "                     (default 100, fault-free; 300: wheels reporting 3x, which it must flag)\n"
           "  -h, --help         this text\n"
           "exit status:\n"
           "  0  done, the check flagged nothing\n"
           "  1  the report could not be written ('cannot write PATH: REASON'; the table is on stdout),\n"
           "     nor stdout ('cannot write standard output: REASON'), or the monitor could not be set\n"
           "     up; before 3 when both apply\n"
           "  2  bad usage (an unknown option, a value not a whole number or out of its range)\n"
           "  3  the check flagged the drive (disagreements or mismatches; fault-free: a false report),\n"
           "     the report written\n",
           kUsage);
}

static double cpu_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

static int bench_odo_check_main(int argc, char **argv)
{
    const char *out = "out/bench";
    long checks = 400;
    int odo_scale_pct = 100;
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--out") == 0 && i + 1 < argc) {
            out = argv[++i];
        } else if (strcmp(argv[i], "--checks") == 0 && i + 1 < argc) {
            if (bench_arg_long("coslam-bench-odo-check", "--checks", argv[++i], 1, 1000000, &checks) != 0) {
                return kExitUsage;
            }
        } else if (strcmp(argv[i], "--odo-scale-pct") == 0 && i + 1 < argc) {
            if (bench_arg_int("coslam-bench-odo-check", "--odo-scale-pct", argv[++i], 10, 1000, &odo_scale_pct) != 0) {
                return kExitUsage;
            }
        } else if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            print_help();
            return kExitOk;
        } else {
            fprintf(stderr, "%s", kUsage);
            return kExitUsage;
        }
    }
    profile_print(stdout, "coslam-bench-odo-check");
    room_t room;
    memset(&room, 0, sizeof room);
    add_box(&room, -3.0, -2.0, 3.0, 2.0);
    add_box(&room, 1.0, 0.4, 1.6, 1.0);
    static odo_check_t c;
    const odo_check_config_t cfg = odo_check_config_default();
    if (odo_check_init(&c, &cfg) != COSLAM_OK) {
        fprintf(stderr, "coslam-bench-odo-check: odo_check_init refused the default configuration\n");
        return kExitWrite;
    }
    static point2_t pts[N_RAYS];
    pose2_t truth = {-1.0, -1.0, 0.0};
    pose2_t odo = truth; /* what the wheels report: truth unless scaled */
    const double odo_scale = (double)odo_scale_pct / 100.0;
    const pose2_t step = {0.02, 0.0, 0.02};
    double t_check = 0.0, t_check_max = 0.0, t_keep = 0.0;
    long n_check = 0, n_keep = 0;
    for (long k = 0; n_check < checks; ++k) {
        const pose2_t before = truth;
        truth = pose2_compose(truth, step);
        if (truth.x > 2.2 || truth.x < -2.2 || truth.y > 1.4 || truth.y < -1.4) {
            truth = (pose2_t){-1.0, -1.0, truth.theta}; /* stay in the room */
        }
        if (odo_scale_pct == 100) {
            odo = truth; /* fault-free: exactly the figures timed before the option */
        } else {
            pose2_t d = pose2_between(before, truth);
            d.x *= odo_scale;
            d.y *= odo_scale;
            d.theta *= odo_scale;
            odo = pose2_compose(odo, d);
        }
        const size_t n = scan(&room, truth, pts);
        const double t0 = cpu_us();
        const int judged = odo_check_on_scan(&c, (uint64_t)(k + 1) * 100000U, odo, pts, n);
        const double dt = cpu_us() - t0;
        if (judged) {
            t_check += dt;
            t_check_max = dt > t_check_max ? dt : t_check_max;
            ++n_check;
        } else {
            t_keep += dt;
            ++n_keep;
        }
    }
    char path[512];
    snprintf(path, sizeof path, "%s/odo_check.md", out);
    errno = 0;
    FILE *f = fopen(path, "w");
    const int open_errno = errno; /* the printf below may change errno */
    const double mean = t_check / (double)n_check;
    char table[1024];
    snprintf(table, sizeof table,
             "| checks | CPU per check, mean / max [us] | per other scan [us] | CPU share at 10 scans/s | sizeof(odo_check_t) [B] | "
             "points per scan | flagged |\n|---|---|---|---|---|---|---|\n| %ld | %.0f / %.0f | %.1f | %.2f %% | %zu | %d | %u |\n",
             n_check, mean, t_check_max, n_keep > 0 ? t_keep / (double)n_keep : 0.0,
             100.0 * (2.0 * mean + 8.0 * (n_keep > 0 ? t_keep / (double)n_keep : 0.0)) / 1e6, sizeof(odo_check_t),
             COSLAM_APP_ODO_CHECK_POINTS, c.disagreements + c.mismatches);
    printf("%s", table);
    if (f == NULL) {
        fprintf(stderr, "coslam-bench-odo-check: cannot write %s: %s (the table is above)\n", path, strerror(open_errno));
        return kExitWrite;
    }
    fputs(table, f);
    if (checked_file_close("coslam-bench-odo-check", f, path) != 0) {
        return kExitWrite;
    }
    if (c.disagreements + c.mismatches != 0U) {
        fprintf(stderr,
                "coslam-bench-odo-check: the check flagged the drive (%u disagreements, %u mismatches%s): exit %d\n",
                c.disagreements, c.mismatches, odo_scale_pct == 100 ? ", fault-free: false reports" : "",
                kExitFlagged);
        return kExitFlagged;
    }
    return kExitOk;
}

/* exit status with standard output checked (stdout_check.h) */
int main(int argc, char **argv)
{
    return stdout_check_exit("coslam-bench-odo-check", bench_odo_check_main(argc, argv));
}
