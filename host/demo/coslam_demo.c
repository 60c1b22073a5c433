/*
 * coslam-demo - core-only demonstration (the `make sim` job until the
 * simulator lands): one seeded synthetic loop, run through EKF-SLAM and
 * Fast-SLAM; writes TUM paths, map CSVs, metrics.json and a figure.
 *   coslam-demo [--out DIR] [--seed N] [--landmarks N]
 * Exit status: 0 done; 1 DIR not created, an output file not written whole
 * ("coslam-demo: cannot write <path>: <OS reason>", checked_file.h; the
 * run stops there) or standard output lost (stdout_check.h), or a run
 * failed; 2 usage.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <math.h>

#include "slam_run.h"
#include "checked_file.h"
#include "profile_print.h"
#include "stdout_check.h"

#define DEMO_TOOL "coslam-demo"

static int mkdir_p(const char *path)
{
    char tmp[1024];
    snprintf(tmp, sizeof tmp, "%s", path);
    for (char *p = tmp + 1; *p; ++p) {
        if (*p == '/') {
            *p = 0;
            if (mkdir(tmp, 0775) != 0 && errno != EEXIST) return -1;
            *p = '/';
        }
    }
    return (mkdir(tmp, 0775) != 0 && errno != EEXIST) ? -1 : 0;
}

/* write_tum, write_map: 0, or -1 with the file named on stderr */
static int write_tum(const char *path, const pose2_t *poses, const double *t, int n)
{
    FILE *f = checked_file_open(DEMO_TOOL, path);
    if (!f) return -1;
    fprintf(f, "# t x y z qx qy qz qw\n");
    for (int i = 0; i < n; ++i) {
        fprintf(f, "%.3f %.6f %.6f 0 0 0 %.9f %.9f\n", t[i], poses[i].x, poses[i].y, sin(0.5 * poses[i].theta),
                cos(0.5 * poses[i].theta));
    }
    return checked_file_close(DEMO_TOOL, f, path);
}

static int write_map(const char *path, const map_estimate_t *m)
{
    FILE *f = checked_file_open(DEMO_TOOL, path);
    if (!f) return -1;
    fprintf(f, "id,x,y,cxx,cxy,cyy\n");
    for (int i = 0; i < m->n_landmarks; ++i) {
        const map_landmark_t *l = &m->lm[i];
        fprintf(f, "%u,%.6f,%.6f,%.9g,%.9g,%.9g\n", l->id, l->mean.x, l->mean.y, l->cov.xx, l->cov.xy, l->cov.yy);
    }
    return checked_file_close(DEMO_TOOL, f, path);
}

static int demo_main(int argc, char **argv)
{
    const char *out = "out/demo";
    uint64_t seed = 1;
    int n_lm = 30;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
        else if (!strcmp(argv[i], "--seed") && i + 1 < argc) seed = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--landmarks") && i + 1 < argc) n_lm = atoi(argv[++i]);
        else { fprintf(stderr, "usage: coslam-demo [--out DIR] [--seed N] [--landmarks N]\n"); return 2; }
    }
    profile_print(stderr, "coslam-demo");
    if (mkdir_p(out) != 0) { fprintf(stderr, "coslam-demo: cannot create %s: %s\n", out, strerror(errno)); return 1; }
    synth_config_t sc = synth_config_default(seed, n_lm);
    sc.n_signatures = 4;
    sc.loop_radius_m = 2.5; /* paper scale, as in the core tests */
    sc.ring_half_width_m = 2.0;
    const run_filter_t filters[2] = {RUN_EKFSLAM, RUN_FASTSLAM2};
    const char *names[2] = {"ekfslam", "fastslam2"};
    char path[1200];
    char mj_path[1200];
    snprintf(mj_path, sizeof mj_path, "%s/metrics.json", out);
    FILE *mj = checked_file_open(DEMO_TOOL, mj_path);
    if (!mj) return 1;
    fprintf(mj, "{\n  \"seed\": %llu,\n  \"landmarks\": %d,\n  \"filters\": {\n", (unsigned long long)seed, n_lm);
    for (int k = 0; k < 2; ++k) {
        run_opts_t o = run_opts_default(filters[k]);
        o.params = sc.truth;
        run_result_t *r = malloc(sizeof *r);
        run_trace_t tr = {0};
        if (!r || run_synth_traced(&sc, &o, r, &tr) != 0) {
            fprintf(stderr, "coslam-demo: run failed\n");
            run_trace_free(&tr);
            free(r);
            fclose(mj);
            return 1;
        }
        int bad = 0;
        snprintf(path, sizeof path, "%s/robot0_%s_path.tum", out, names[k]);
        bad = bad || write_tum(path, tr.est, tr.t, tr.n) != 0;
        snprintf(path, sizeof path, "%s/robot0_truth_path.tum", out);
        bad = bad || write_tum(path, tr.truth, tr.t, tr.n) != 0;
        snprintf(path, sizeof path, "%s/robot0_%s_map.csv", out, names[k]);
        bad = bad || write_map(path, &r->estimate) != 0;
        if (bad) {
            run_trace_free(&tr);
            free(r);
            fclose(mj);
            return 1;
        }
        fprintf(mj, "    \"%s\": {\"pose_rmse_m\": %.4f, \"heading_rmse_rad\": %.4f, \"odometry_rmse_m\": %.4f, "
                    "\"landmark_rmse_m\": %.4f, \"landmarks\": %d, \"spurious\": %d, \"missed\": %d, "
                    "\"landmark_nees\": %.3f, \"pose_nees\": %.3f, \"step_us\": %.2f}%s\n",
                names[k], r->pose_rmse_m, r->heading_rmse_rad, r->odo_rmse_m, r->map.rmse_m, r->map.n_estimated,
                r->map.n_spurious, r->map.n_missed, r->map.nees_mean, r->pose_nees_mean, r->step_us_mean,
                k == 0 ? "," : "");
        printf("%-10s pose RMSE %.3f m (odometry %.3f m), landmark RMSE %.3f m, %d landmarks, %d spurious\n",
               names[k], r->pose_rmse_m, r->odo_rmse_m, r->map.rmse_m, r->map.n_estimated, r->map.n_spurious);
        run_trace_free(&tr);
        free(r);
    }
    fprintf(mj, "  }\n}\n");
    if (checked_file_close(DEMO_TOOL, mj, mj_path) != 0) return 1;
    /* the truth map */
    synth_world_t *w = malloc(sizeof *w);
    if (!w) { fprintf(stderr, "coslam-demo: out of memory\n"); return 1; }
    synth_init(w, &sc);
    snprintf(path, sizeof path, "%s/truth_map.csv", out);
    FILE *f = checked_file_open(DEMO_TOOL, path);
    if (!f) { free(w); return 1; }
    fprintf(f, "id,x,y\n");
    for (int j = 0; j < w->n_lm; ++j) fprintf(f, "%d,%.6f,%.6f\n", j, w->lm[j].x, w->lm[j].y);
    free(w);
    if (checked_file_close(DEMO_TOOL, f, path) != 0) return 1;
    printf("results in %s/\n", out);
    return 0;
}

/* exit status with standard output checked (stdout_check.h) */
int main(int argc, char **argv)
{
    return stdout_check_exit(DEMO_TOOL, demo_main(argc, argv));
}
