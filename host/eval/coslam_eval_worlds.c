/*
 * coslam-eval-worlds - the filters of the core on seeded synthetic worlds
 * (host/synth), one row per seed: final pose error, pose RMSE, landmark
 * RMSE, spurious landmarks and the NEES of the exported map. The instrument
 * of docs/consistency.md; the CI tests (test/slam/test_worlds.c) run the
 * same worlds through the same runner.
 *
 *   coslam-eval-worlds [--world paper|loop|large|arena] [--filter ekf|fs1|fs2]
 *                      [-p N] [--seeds N] [--seed0 S] [--out DIR]
 *                      [--active-radius R]
 *                      [--write-log DIR]   (the world of seed0 as a landmark
 *                                           log for coslam-replay, no runs)
 *
 * --active-radius R sets EKF-SLAM's active_radius_m (0: the full EKF; the
 * default is the profile's, ekfslam_config_default()). The step time by
 * map size (run_result_t.size_bin_us, bins of 2^k landmarks) goes to
 * stderr, one line per seed.
 *
 * Worlds (eval_worlds.h): "paper" is the paper's scale (20 m loop among 64
 * landmarks of 4 classes), "loop" one large loop (radius 8 m, 160 landmarks
 * of 4 classes, 1.15 turns: the robot comes back to where it started after
 * 50 m), "large" 1,024 landmarks, "arena" MRCLAM's regime (15 identical
 * landmarks in clusters, one or two sightings per frame; its maps are also
 * scored after the best rigid fit, as coslam-replay scores MRCLAM).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "eval_worlds.h"
#include "profile_print.h"

/* The world of `seed` as a landmark log (docs/replay.md: robot1.log with
 * O and Z records, robot1_truth.txt, landmarks_truth.txt, t0.txt), for
 * coslam-replay: odometry increments per control step as measured (noisy),
 * sightings with the true landmark index as id. Returns 0 on success. */
static int write_log(eval_world_t wk, uint64_t seed, const char *dir)
{
    if (mkdir(dir, 0775) != 0 && errno != EEXIST) {
        fprintf(stderr, "coslam-eval-worlds: cannot create %s: %s\n", dir, strerror(errno));
        return 1;
    }
    const synth_config_t sc = eval_world_config(wk, seed);
    synth_world_t *w = malloc(sizeof *w);
    synth_step_t *st = malloc(sizeof *st);
    char path[4096];
    FILE *f[4] = {NULL, NULL, NULL, NULL};
    const char *names[4] = {"robot1.log", "robot1_truth.txt", "landmarks_truth.txt", "t0.txt"};
    int rc = 0;
    for (int k = 0; k < 4; ++k) {
        snprintf(path, sizeof path, "%s/%s", dir, names[k]);
        f[k] = fopen(path, "w");
        if (f[k] == NULL) {
            fprintf(stderr, "coslam-eval-worlds: cannot write %s: %s\n", path, strerror(errno));
            rc = 1;
        }
    }
    if (w == NULL || st == NULL || rc != 0) {
        rc = 1;
        goto out;
    }
    synth_init(w, &sc);
    const pose2_t p0 = synth_start_pose(&sc);
    fprintf(f[1], "%.17g %.17g %.17g %.17g\n", 0.0, p0.x, p0.y, p0.theta);
    int n_z = 0;
    while (synth_next(w, st)) {
        fprintf(f[0], "O %.17g %.17g %.17g %.17g\n", st->t_s, st->u.dx, st->u.dy, st->u.dtheta);
        fprintf(f[1], "%.17g %.17g %.17g %.17g\n", st->t_s, st->true_pose.x, st->true_pose.y, st->true_pose.theta);
        for (int i = 0; st->is_frame && i < st->n_z; ++i) {
            fprintf(f[0], "Z %.17g %d %.17g %.17g\n", st->t_s, (int)st->true_id[i], st->z[i].range_m,
                    st->z[i].bearing_rad);
            n_z++;
        }
    }
    for (int j = 0; j < w->n_lm; ++j) {
        fprintf(f[2], "%d %.17g %.17g\n", j, w->lm[j].x, w->lm[j].y);
    }
    fprintf(f[3], "0\n");
    fprintf(stderr, "coslam-eval-worlds: wrote %s (%d steps, %d sightings, %d landmarks)\n", dir, w->n_steps, n_z,
            w->n_lm);
out:
    for (int k = 0; k < 4; ++k) {
        if (f[k] != NULL && fclose(f[k]) != 0) {
            rc = 1;
        }
    }
    free(w);
    free(st);
    return rc;
}

static void usage(void)
{
    fprintf(stderr, "usage: coslam-eval-worlds [--world paper|loop|large|arena] [--filter ekf|fs1|fs2] [-p N] [--seeds N] "
                    "[--seed0 S] [--out DIR] [--trace] [--active-radius R] [--write-log DIR]\n");
}

int main(int argc, char **argv)
{
    const char *world = "loop";
    const char *filter = "ekf";
    const char *out = NULL;
    int particles = 100;
    int trace = 0;
    const char *log_dir = NULL;
    int seeds = 10;
    long seed0 = 1;
    double active_radius_m = -1.0;
    for (int i = 1; i < argc; ++i) {
        const int more = i + 1 < argc;
        if (!strcmp(argv[i], "--world") && more) world = argv[++i];
        else if (!strcmp(argv[i], "--filter") && more) filter = argv[++i];
        else if (!strcmp(argv[i], "-p") && more) particles = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--seeds") && more) seeds = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--seed0") && more) seed0 = atol(argv[++i]);
        else if (!strcmp(argv[i], "--out") && more) out = argv[++i];
        else if (!strcmp(argv[i], "--trace")) trace = 1;
        else if (!strcmp(argv[i], "--write-log") && more) log_dir = argv[++i];
        else if (!strcmp(argv[i], "--active-radius") && more) active_radius_m = atof(argv[++i]);
        else { usage(); return 2; }
    }
    profile_print(stderr, "coslam-eval-worlds");
    eval_world_t wk;
    run_filter_t fk;
    if (eval_world_parse(world, &wk) != 0 || eval_filter_parse(filter, &fk) != 0 || seeds < 1 || seeds > 1000 ||
        seed0 < 0 || particles < 1 || particles > COSLAM_MAX_PARTICLES) {
        fprintf(stderr, "coslam-eval-worlds: bad argument (world paper|loop|large|arena, filter ekf|fs1|fs2, 1 <= p <= %d, "
                        "1 <= seeds <= 1000, seed0 >= 0)\n", COSLAM_MAX_PARTICLES);
        usage();
        return 2;
    }
    if (log_dir != NULL) {
        /* the world of seed0 as a landmark log for coslam-replay, no runs */
        return write_log(wk, (uint64_t)seed0, log_dir);
    }
    FILE *md = NULL;
    if (out != NULL) {
        if (mkdir(out, 0775) != 0 && errno != EEXIST) {
            fprintf(stderr, "coslam-eval-worlds: cannot create %s: %s\n", out, strerror(errno));
            return 1;
        }
        char path[4096];
        snprintf(path, sizeof path, "%s/%s_%s_%d.md", out, world, filter, fk == RUN_EKFSLAM ? 0 : particles);
        md = fopen(path, "w");
        if (md == NULL) {
            fprintf(stderr, "coslam-eval-worlds: cannot write %s: %s\n", path, strerror(errno));
            return 1;
        }
    }
    run_result_t *r = malloc(sizeof *r);
    if (r == NULL) {
        return 1;
    }
    eval_summary_t sum;
    eval_summary_init(&sum);
    int n_fit = 0;
    int fit_clean = 0;
    int fit_spurious = 0;
    double fit_rmse = 0.0;
    char line[512];
    snprintf(line, sizeof line, "| seed | final err m | pose RMSE m | odo RMSE m | lm RMSE m | landmarks | spurious | "
                                "missed | lm sd m | lm NEES | pose NEES | step ms mean / max | closed |\n"
                                "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    fputs(line, stdout);
    if (md) fputs(line, md);
    for (int s = 0; s < seeds; ++s) {
        const uint64_t seed = (uint64_t)seed0 + (uint64_t)s;
        if (eval_world_run_ekf_radius(wk, fk, particles, seed, active_radius_m, r) != 0) {
            fprintf(stderr, "coslam-eval-worlds: run failed (seed %llu)\n", (unsigned long long)seed);
            free(r);
            return 1;
        }
        eval_summary_add(&sum, r);
        if (trace) {
            /* position error every 5 s of the run */
            const synth_config_t sc = eval_world_config(wk, seed);
            const run_opts_t o = eval_world_opts(wk, fk, particles, seed, active_radius_m);
            run_trace_t tr;
            run_result_t *r2 = malloc(sizeof *r2);
            if (r2 != NULL && run_synth_traced(&sc, &o, r2, &tr) == 0) {
                printf("trace seed %llu:", (unsigned long long)seed);
                for (int k = 0; k < tr.n; k += 50) {
                    printf(" %.0f:%.2f", tr.t[k], hypot(tr.est[k].x - tr.truth[k].x, tr.est[k].y - tr.truth[k].y));
                }
                printf("\n");
                run_trace_free(&tr);
            }
            free(r2);
        }
        double sd = 0.0;
        for (int i = 0; i < r->estimate.n_landmarks; ++i) {
            sd += r->estimate.lm[i].cov.xx + r->estimate.lm[i].cov.yy;
        }
        sd = r->estimate.n_landmarks > 0 ? sqrt(sd / r->estimate.n_landmarks) : 0.0;
        snprintf(line, sizeof line, "| %llu | %.3f | %.3f | %.3f | %.3f | %d | %d | %d | %.3f | %.2f | %.2f | %.2f / %.1f | %s |\n",
                 (unsigned long long)seed, r->final_pos_err_m, r->pose_rmse_m, r->odo_rmse_m, r->map.rmse_m,
                 r->map.n_estimated, r->map.n_spurious, r->map.n_missed, sd, r->map.nees_mean, r->pose_nees_mean,
                 1e-3 * r->step_us_mean, 1e-3 * r->step_us_max,
                 eval_closed(r) ? "yes" : "no");
        fputs(line, stdout);
        if (md) fputs(line, md);
        if (r->has_map_fit) {
            /* the map as coslam-replay scores MRCLAM: after the best rigid fit */
            snprintf(line, sizeof line, "|  | after rigid fit: lm RMSE %.3f m, spurious %d, missed %d |\n", r->map_fit.rmse_m,
                     r->map_fit.n_spurious, r->map_fit.n_missed);
            fputs(line, stdout);
            if (md) fputs(line, md);
            fit_spurious += r->map_fit.n_spurious;
            fit_clean += r->map_fit.n_spurious == 0;
            fit_rmse += r->map_fit.rmse_m;
            n_fit++;
        }
        fflush(stdout);
        fprintf(stderr, "seed %llu: %u global updates; step ms by map size (steps):", (unsigned long long)seed,
                (unsigned)r->ekf_global_updates);
        for (int k = 0; k < RUN_SIZE_BINS; ++k) {
            if (r->size_bin_steps[k] > 0) {
                fprintf(stderr, " %d: %.2f (%d)", 1 << k, 1e-3 * r->size_bin_us[k],
                        r->size_bin_steps[k]);
            }
        }
        fprintf(stderr, "\n");
    }
    snprintf(line, sizeof line,
             "\n%s, %s, %d particles: closed %d/%d; mean pose RMSE %.3f m; median landmark NEES %.2f (mean of "
             "runs %.2f); spurious %.1f %%\n",
             world, filter, fk == RUN_EKFSLAM ? 0 : particles,
             sum.closed, sum.n, sum.pose_rmse_sum / sum.n, eval_summary_median_nees(&sum), sum.nees_sum / sum.n,
             100.0 * sum.spurious / (sum.estimated > 0 ? sum.estimated : 1));
    fputs(line, stdout);
    if (md) fputs(line, md);
    if (n_fit > 0) {
        snprintf(line, sizeof line,
                 "after rigid fit: no spurious landmark in %d/%d runs; spurious %.2f per run; mean landmark RMSE %.3f m\n",
                 fit_clean, n_fit, (double)fit_spurious / n_fit, fit_rmse / n_fit);
        fputs(line, stdout);
        if (md) fputs(line, md);
    }
    if (md) {
        fclose(md);
    }
    free(r);
    return 0;
}
