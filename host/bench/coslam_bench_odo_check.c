/*
 * coslam-bench-odo-check: cost of the health monitor's scan-to-scan
 * odometry check (firmware/app odo_check.h). A robot drives an arc through
 * a 6 m x 4 m room with a box (the ray caster of test/app/room_scan.h: 401
 * rays over 140 deg, 4 m), one scan every 0.1 s, so a check (three ICP
 * starts) runs every fifth scan. Reports the thread CPU time per check and
 * per scan that only keeps its points, and the monitor's memory. Writes
 * <out>/odo_check.md.
 *   coslam-bench-odo-check [--out DIR] [--checks N]
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

static double cpu_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

int main(int argc, char **argv)
{
    const char *out = "out/bench";
    long checks = 400;
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--out") == 0 && i + 1 < argc) {
            out = argv[++i];
        } else if (strcmp(argv[i], "--checks") == 0 && i + 1 < argc) {
            if (bench_arg_long("coslam-bench-odo-check", "--checks", argv[++i], 1, 1000000, &checks) != 0) {
                return 2;
            }
        } else {
            fprintf(stderr, "usage: coslam-bench-odo-check [--out DIR] [--checks N]\n");
            return 2;
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
        return 1;
    }
    static point2_t pts[N_RAYS];
    pose2_t truth = {-1.0, -1.0, 0.0};
    const pose2_t step = {0.02, 0.0, 0.02};
    double t_check = 0.0, t_check_max = 0.0, t_keep = 0.0;
    long n_check = 0, n_keep = 0;
    for (long k = 0; n_check < checks; ++k) {
        truth = pose2_compose(truth, step);
        if (truth.x > 2.2 || truth.x < -2.2 || truth.y > 1.4 || truth.y < -1.4) {
            truth = (pose2_t){-1.0, -1.0, truth.theta}; /* stay in the room */
        }
        const size_t n = scan(&room, truth, pts);
        const double t0 = cpu_us();
        const int judged = odo_check_on_scan(&c, (uint64_t)(k + 1) * 100000U, truth, pts, n);
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
        return 1;
    }
    fputs(table, f);
    if (bench_file_close("coslam-bench-odo-check", f, path) != 0) {
        return 1;
    }
    return c.disagreements + c.mismatches == 0U ? 0 : 1;
}
