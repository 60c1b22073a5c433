/*
 * coslam-eval-worlds - the filters of the core on seeded synthetic worlds
 * (host/synth), one row per seed: final pose error, pose RMSE, landmark
 * RMSE, spurious landmarks and the NEES of the exported map. The instrument
 * of docs/consistency.md; the CI tests (test/slam/test_worlds.c) run the
 * same worlds through the same runner.
 *
 *   coslam-eval-worlds [--world paper|loop|large|arena] [--filter ekf|fs1|fs2]
 *                      [-p N] [--seeds N] [--seed0 S] [--out DIR]
 *                      [--active-radius R] [--mh-frames N]
 *                      [--write-log DIR]   (the world of seed0 as a landmark
 *                                           log for coslam-replay, no runs)
 *
 * --active-radius R sets EKF-SLAM's active_radius_m (0: the full EKF; the
 * default is the profile's, ekfslam_config_default()); --mh-frames N its
 * mh_frames (0: revisits not kept as two hypotheses; default 50). The step time by
 * map size (run_result_t.size_bin_us, bins of 2^k landmarks) goes to
 * stderr, one line per seed.
 *
 * Numbers are read whole (a malformed or out-of-range value is refused with
 * the option named, exit 2: -p 1..COSLAM_MAX_PARTICLES, --seeds 1..1000,
 * --seed0 >= 0, --active-radius finite >= 0, --mh-frames 0..100000, --robots 1..9); --help prints
 * the usage and exits 0. A write error on the .md table or the log files
 * is said with the file's path, exit 1.
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
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bench_args.h"
#include "checked_file.h"
#include "eval_worlds.h"
#include "profile_print.h"
#include "stdout_check.h"

/* Closes f (NULL: nothing to do); a write error or a failed close is said
 * with the file's path (checked_file.h). Returns 0, or 1 on an error. */
static int close_checked(FILE *f, const char *path)
{
    return checked_file_close("coslam-eval-worlds", f, path) != 0 ? 1 : 0;
}

/* The world of `seed` as a landmark log (docs/replay.md: robot<k>.log with
 * O, Z and R records, robot<k>_truth.txt, landmarks_truth.txt, t0.txt), for
 * coslam-replay: odometry increments per control step as measured (noisy),
 * sightings with the true landmark index as id. The arena takes a team of
 * n_robots (1-9): each starts at its own random pose (0.5 m inside the
 * arena, 1 m apart), wanders with its own random stream, and on its camera
 * frames also sights the other robots inside its footprint (with the
 * landmarks' detection probability and noise) as R records, from which
 * coslam-replay's meetings and merges follow. Returns 0 on success. */
static int write_log(eval_world_t wk, uint64_t seed, const char *dir, int n_robots)
{
    enum { MAX_TEAM = 9 };
    if (n_robots < 1 || n_robots > MAX_TEAM || (n_robots > 1 && wk != EVAL_WORLD_ARENA)) {
        fprintf(stderr, "coslam-eval-worlds: --robots takes 1-%d, more than 1 only in the arena\n", MAX_TEAM);
        return 2;
    }
    if (mkdir(dir, 0775) != 0 && errno != EEXIST) {
        fprintf(stderr, "coslam-eval-worlds: cannot create %s: %s\n", dir, strerror(errno));
        return 1;
    }
    const synth_config_t sc = eval_world_config(wk, seed);
    synth_world_t *w = malloc(sizeof(*w) * (size_t)n_robots);
    synth_step_t *st = malloc(sizeof(*st) * (size_t)n_robots);
    char path[4096];
    FILE *f_log[MAX_TEAM] = {NULL};
    FILE *f_truth[MAX_TEAM] = {NULL};
    FILE *f_lm = NULL;
    FILE *f_t0 = NULL;
    int rc = 0;
    for (int k = 0; k < n_robots; ++k) {
        snprintf(path, sizeof path, "%s/robot%d.log", dir, k + 1);
        f_log[k] = fopen(path, "w");
        rc |= f_log[k] == NULL;
        snprintf(path, sizeof path, "%s/robot%d_truth.txt", dir, k + 1);
        f_truth[k] = fopen(path, "w");
        rc |= f_truth[k] == NULL;
    }
    snprintf(path, sizeof path, "%s/landmarks_truth.txt", dir);
    f_lm = fopen(path, "w");
    snprintf(path, sizeof path, "%s/t0.txt", dir);
    f_t0 = fopen(path, "w");
    if (w == NULL || st == NULL || rc != 0 || f_lm == NULL || f_t0 == NULL) {
        fprintf(stderr, "coslam-eval-worlds: cannot write the log in %s: %s\n", dir, strerror(errno));
        rc = 1;
        goto out;
    }
    synth_init(&w[0], &sc);
    rng_t team;
    rng_seed(&team, seed * 7919U + 104729U);
    if (n_robots > 1) {
        /* random start poses, 1 m apart; each robot its own stream */
        for (int k = 0; k < n_robots; ++k) {
            if (k > 0) {
                memcpy(&w[k], &w[0], sizeof w[0]);
            }
            pose2_t p0;
            int ok;
            do {
                p0.x = (2.0 * rng_uniform(&team) - 1.0) * (sc.arena_half_x_m - 0.5);
                p0.y = (2.0 * rng_uniform(&team) - 1.0) * (sc.arena_half_y_m - 0.5);
                p0.theta = angle_wrap(COSLAM_TWO_PI * rng_uniform(&team));
                ok = 1;
                for (int q = 0; q < k; ++q) {
                    ok = ok && hypot(p0.x - w[q].pose.x, p0.y - w[q].pose.y) >= 1.0;
                }
            } while (!ok);
            synth_arena_place(&w[k], p0, seed * 1000U + (uint64_t)k + 1U);
        }
    }
    for (int k = 0; k < n_robots; ++k) {
        fprintf(f_truth[k], "%.17g %.17g %.17g %.17g\n", 0.0, w[k].pose.x, w[k].pose.y, w[k].pose.theta);
    }
    int n_z = 0;
    int n_rz = 0;
    for (;;) {
        int more = 1;
        for (int k = 0; k < n_robots; ++k) {
            more = synth_next(&w[k], &st[k]) && more;
        }
        if (!more) {
            break;
        }
        for (int k = 0; k < n_robots; ++k) {
            const synth_step_t *s = &st[k];
            fprintf(f_log[k], "O %.17g %.17g %.17g %.17g\n", s->t_s, s->u.dx, s->u.dy, s->u.dtheta);
            fprintf(f_truth[k], "%.17g %.17g %.17g %.17g\n", s->t_s, s->true_pose.x, s->true_pose.y,
                    s->true_pose.theta);
            for (int i = 0; s->is_frame && i < s->n_z; ++i) {
                fprintf(f_log[k], "Z %.17g %d %.17g %.17g\n", s->t_s, (int)s->true_id[i], s->z[i].range_m,
                        s->z[i].bearing_rad);
                n_z++;
            }
            if (!s->is_frame || n_robots < 2) {
                continue;
            }
            /* the other robots in view, sighted as the landmarks are
             * (footprint, detection, noise) */
            point2_t others[MAX_TEAM];
            int other_id[MAX_TEAM];
            int n_other = 0;
            for (int q = 0; q < n_robots; ++q) {
                if (q != k) {
                    others[n_other] = (point2_t){st[q].true_pose.x, st[q].true_pose.y};
                    other_id[n_other++] = q + 1;
                }
            }
            static const uint8_t no_sig[MAX_TEAM] = {0};
            sighting_t rz[MAX_TEAM];
            int32_t which[MAX_TEAM];
            int seen[MAX_TEAM] = {0};
            const int n = synth_sight_landmarks(&sc.truth, &team, s->true_pose, others, no_sig, n_other, sc.p_detect,
                                                rz, which, MAX_TEAM, seen);
            for (int i = 0; i < n; ++i) {
                fprintf(f_log[k], "R %.17g %d %.17g %.17g\n", s->t_s, other_id[which[i]], rz[i].range_m,
                        rz[i].bearing_rad);
            }
            n_rz += n;
        }
    }
    for (int j = 0; j < w[0].n_lm; ++j) {
        fprintf(f_lm, "%d %.17g %.17g\n", j, w[0].lm[j].x, w[0].lm[j].y);
    }
    fprintf(f_t0, "0\n");
    fprintf(stderr, "coslam-eval-worlds: wrote %s (%d robot(s), %d steps, %d landmark sightings, %d robot sightings, "
                    "%d landmarks)\n", dir, n_robots, w[0].n_steps, n_z, n_rz, w[0].n_lm);
out:
    for (int k = 0; k < MAX_TEAM; ++k) {
        snprintf(path, sizeof path, "%s/robot%d.log", dir, k + 1);
        rc |= close_checked(f_log[k], path);
        snprintf(path, sizeof path, "%s/robot%d_truth.txt", dir, k + 1);
        rc |= close_checked(f_truth[k], path);
    }
    snprintf(path, sizeof path, "%s/landmarks_truth.txt", dir);
    rc |= close_checked(f_lm, path);
    snprintf(path, sizeof path, "%s/t0.txt", dir);
    rc |= close_checked(f_t0, path);
    free(w);
    free(st);
    return rc;
}

static void usage(FILE *to)
{
    fprintf(to, "usage: coslam-eval-worlds [--world paper|loop|large|arena] [--filter ekf|fs1|fs2] [-p N] [--seeds N] "
                "[--seed0 S] [--out DIR] [--trace] [--active-radius R] [--mh-frames N] [--write-log DIR [--robots N]]\n");
}

/* Whole-number options: the benches' parser (host/cli/bench_args.h). */
static int parse_long(const char *opt, const char *s, long lo, long hi, long *out)
{
    return bench_arg_long("coslam-eval-worlds", opt, s, lo, hi, out);
}

static int parse_int(const char *opt, const char *s, int lo, int hi, int *out)
{
    return bench_arg_int("coslam-eval-worlds", opt, s, lo, hi, out);
}

/* The whole of `s` as a finite number >= 0; else says which option and
 * returns -1. */
static int parse_nonneg(const char *opt, const char *s, double *out)
{
    char *end = NULL;
    errno = 0;
    const double v = strtod(s, &end);
    if (end == s || *end != '\0' || errno == ERANGE || !isfinite(v) || v < 0.0) {
        fprintf(stderr, "coslam-eval-worlds: %s '%s': expected a finite number >= 0\n", opt, s);
        return -1;
    }
    *out = v;
    return 0;
}

static int eval_worlds_main(int argc, char **argv)
{
    const char *world = "loop";
    const char *filter = "ekf";
    const char *out = NULL;
    int particles = 100;
    int trace = 0;
    const char *log_dir = NULL;
    int n_robots = 1;
    int seeds = 10;
    long seed0 = 1;
    double active_radius_m = -1.0;
    int mh_frames = -1;
    for (int i = 1; i < argc; ++i) {
        const int more = i + 1 < argc;
        int bad = 0;
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) { usage(stdout); return 0; }
        else if (!strcmp(argv[i], "--world") && more) world = argv[++i];
        else if (!strcmp(argv[i], "--filter") && more) filter = argv[++i];
        else if (!strcmp(argv[i], "-p") && more) {
            bad = parse_int("-p", argv[i + 1], 1, COSLAM_MAX_PARTICLES, &particles);
            ++i;
        } else if (!strcmp(argv[i], "--seeds") && more) {
            bad = parse_int("--seeds", argv[i + 1], 1, 1000, &seeds);
            ++i;
        } else if (!strcmp(argv[i], "--seed0") && more) {
            bad = parse_long("--seed0", argv[i + 1], 0, LONG_MAX, &seed0);
            ++i;
        } else if (!strcmp(argv[i], "--out") && more) out = argv[++i];
        else if (!strcmp(argv[i], "--trace")) trace = 1;
        else if (!strcmp(argv[i], "--write-log") && more) log_dir = argv[++i];
        else if (!strcmp(argv[i], "--robots") && more) {
            bad = parse_int("--robots", argv[i + 1], 1, 9, &n_robots);
            ++i;
        } else if (!strcmp(argv[i], "--mh-frames") && more) {
            bad = parse_int("--mh-frames", argv[i + 1], 0, 100000, &mh_frames);
            ++i;
        } else if (!strcmp(argv[i], "--active-radius") && more) {
            bad = parse_nonneg("--active-radius", argv[i + 1], &active_radius_m);
            ++i;
        } else {
            fprintf(stderr, "coslam-eval-worlds: %s: unknown option, or its value missing\n", argv[i]);
            usage(stderr);
            return 2;
        }
        if (bad) {
            usage(stderr);
            return 2;
        }
    }
    profile_print(stderr, "coslam-eval-worlds");
    eval_world_t wk;
    run_filter_t fk;
    if (eval_world_parse(world, &wk) != 0 || eval_filter_parse(filter, &fk) != 0 || seeds < 1 || seeds > 1000 ||
        seed0 < 0 || particles < 1 || particles > COSLAM_MAX_PARTICLES) {
        fprintf(stderr, "coslam-eval-worlds: bad argument (world paper|loop|large|arena, filter ekf|fs1|fs2, 1 <= p <= %d, "
                        "1 <= seeds <= 1000, seed0 >= 0)\n", COSLAM_MAX_PARTICLES);
        usage(stderr);
        return 2;
    }
    if (n_robots != 1 && log_dir == NULL) {
        fprintf(stderr, "coslam-eval-worlds: --robots is for --write-log (a team log); the runs here are one robot\n");
        usage(stderr);
        return 2;
    }
    if (log_dir != NULL) {
        /* the world of seed0 as a landmark log for coslam-replay, no runs */
        return write_log(wk, (uint64_t)seed0, log_dir, n_robots);
    }
    FILE *md = NULL;
    char md_path[4096] = "";
    if (out != NULL) {
        if (mkdir(out, 0775) != 0 && errno != EEXIST) {
            fprintf(stderr, "coslam-eval-worlds: cannot create %s: %s\n", out, strerror(errno));
            return 1;
        }
        snprintf(md_path, sizeof md_path, "%s/%s_%s_%d.md", out, world, filter, fk == RUN_EKFSLAM ? 0 : particles);
        md = fopen(md_path, "w");
        if (md == NULL) {
            fprintf(stderr, "coslam-eval-worlds: cannot write %s: %s\n", md_path, strerror(errno));
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
    double fit_pose = 0.0;
    char line[512];
    snprintf(line, sizeof line, "| seed | final err m | pose RMSE m | odo RMSE m | lm RMSE m | landmarks | spurious | "
                                "missed | lm sd m | lm NEES | pose NEES | step ms mean / max | closed |\n"
                                "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    fputs(line, stdout);
    if (md) fputs(line, md);
    for (int s = 0; s < seeds; ++s) {
        const uint64_t seed = (uint64_t)seed0 + (uint64_t)s;
        run_opts_t o = eval_world_opts(wk, fk, particles, seed, active_radius_m);
        o.ekf_mh_frames = mh_frames;
        const synth_config_t sc = eval_world_config(wk, seed);
        if (run_synth(&sc, &o, r) != 0) {
            fprintf(stderr, "coslam-eval-worlds: run failed (seed %llu)\n", (unsigned long long)seed);
            free(r);
            return 1;
        }
        eval_summary_add(&sum, r);
        if (trace) {
            /* position error every 5 s of the run */
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
            snprintf(line, sizeof line, "|  | after rigid fit: lm RMSE %.3f m, spurious %d, missed %d, pose RMSE %.3f m |\n",
                     r->map_fit.rmse_m, r->map_fit.n_spurious, r->map_fit.n_missed, r->pose_rmse_fit_m);
            fputs(line, stdout);
            if (md) fputs(line, md);
            fit_spurious += r->map_fit.n_spurious;
            fit_clean += r->map_fit.n_spurious == 0;
            fit_rmse += r->map_fit.rmse_m;
            fit_pose += r->pose_rmse_fit_m;
            n_fit++;
        }
        (void)stdout_check_flush(); /* the row before the seed's stderr line */
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
                 "after rigid fit: no spurious landmark in %d/%d runs; spurious %.2f per run; mean landmark RMSE %.3f m; "
                 "mean pose RMSE in the fitted map %.3f m\n",
                 fit_clean, n_fit, (double)fit_spurious / n_fit, fit_rmse / n_fit, fit_pose / n_fit);
        fputs(line, stdout);
        if (md) fputs(line, md);
    }
    free(r);
    if (md != NULL && close_checked(md, md_path) != 0) {
        return 1;
    }
    return 0;
}

/* exit status with standard output checked (stdout_check.h) */
int main(int argc, char **argv)
{
    return stdout_check_exit("coslam-eval-worlds", eval_worlds_main(argc, argv));
}
