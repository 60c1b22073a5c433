/*
 * coslam-bench-merge - time of the map merge (the robot's path: transform,
 * check before trust against the own map, fusion) into Fast-SLAM for
 * (particles N, landmarks M) = (100, 64), (1000, 256), (1000, 1024), and
 * into EKF-SLAM for M = 64, 256 and one message into 1,024. Own maps hold M landmarks; the incoming
 * map holds M landmarks, half of them duplicates of own ones; and (1000,
 * 1024) receiving one message as the link carries it (221 landmarks). Also times a
 * naive all-pairs duplicate search (O(N M^2), the paper's complexity) for
 * comparison, and the merge in parts of merge_config_t.step_units as the
 * robot runs it (the first part with the transform and the check in the
 * step the message arrives, the rest in idle time): its calls and the
 * largest one. Built against a core with 2048 landmarks per map and 1024
 * per message. The own maps are built just before each merge, untimed, and
 * their trees' boxes cleaned, as the robot's are when a message comes (its
 * filter's update queries clean them). Writes <out>/merge_time.{md,json}.
 *   coslam-bench-merge [--out DIR] [--reps N] [--no-naive]
 * --no-naive leaves out the naive search (most of the run's time; for
 * profiling the merge).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "coslam/map_merge.h"
#include "profile_print.h"
#include "bench_args.h"
#include "bench_report.h"
#include "stdout_check.h"

static double now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

static fastslam_t g_fs;
static ekfslam_t g_ekf;
static merge_scratch_t g_sc;
static merge_body_map_t g_bm;
static map_estimate_t g_in;
static map_whole_t g_own;
static map_whole_t g_own_fs; /* the filter's own export (timed only; g_own is what the check reads) */
static merge_coverage_t g_cov;

/* M landmarks on a jittered grid 0.7 m apart (distinct, 4 classes). */
static point2_t site(int i, rng_t *r)
{
    const int cols = 48;
    point2_t p = {0.7 * (i % cols) - 16.0 + 0.1 * rng_gauss(r), 0.7 * (i / cols) - 8.0 + 0.1 * rng_gauss(r)};
    return p;
}

/* m incoming landmarks: even i a duplicate of own landmark i, odd i a new
 * one beyond the m_own own sites. */
static void build_incoming(int m, int m_own, rng_t *r)
{
    memset(&g_in, 0, sizeof g_in);
    g_in.pose.x = 0.0;
    g_in.pose.y = 0.0;
    g_in.pose.theta = 0.0;
    g_in.pose_cov = cov3_diag(0.01, 0.01, 0.001);
    g_in.n_landmarks = (uint16_t)m;
    for (int i = 0; i < m; ++i) {
        map_landmark_t *l = &g_in.lm[i];
        /* even: a duplicate of own landmark i; odd: a new one beyond the own grid */
        l->mean = site(i % 2 == 0 ? i : m_own + i, r);
        l->cov = cov2_make(0.01, 0.0, 0.01);
        l->cov_rel = l->cov;
        l->id = (uint32_t)(i + 1);
        l->n_obs = 10;
        l->src_mask = 2;
        l->signature = (uint8_t)(i % 4);
        if (i % 2 == 1) {
            l->signature = (uint8_t)((m_own + i) % 4);
        }
    }
}

/* The own map as the filter exports it (the check compares against it). */
static void build_own_export(int m, rng_t *r)
{
    memset(&g_own, 0, sizeof g_own);
    g_own.pose_cov = cov3_diag(0.01, 0.01, 0.001);
    g_own.n_landmarks = (uint16_t)m;
    for (int j = 0; j < m; ++j) {
        map_landmark_t *l = &g_own.lm[j];
        l->mean = site(j, r);
        l->cov = cov2_make(0.01, 0.0, 0.01);
        l->cov_rel = l->cov;
        l->id = (uint32_t)(j + 1);
        l->n_obs = 10;
        l->src_mask = 1;
        l->signature = (uint8_t)(j % 4);
    }
    /* the robot looked from 64 places (its keyframes), along the own map's
     * south edge facing south: every look is tested, none vetoes */
    merge_coverage_init(&g_cov);
    for (int k = 0; k < 64; ++k) {
        merge_coverage_note(&g_cov, (pose2_t){0.5 * k - 16.0, -9.0, -0.5 * COSLAM_PI + 0.01 * k});
    }
}

/* Every particle holds the same M landmarks (the sites of build_incoming's duplicates). */
static void build_own_maps(int n, int m, rng_t *r)
{
    fastslam_config_t fc = fastslam_config_default();
    fc.n_particles = (uint16_t)n;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    fastslam_init(&g_fs, &fc, p0, 1U);
    for (uint16_t k = 0; k < n; ++k) {
        rng_seed(r, 7U);
        for (int j = 0; j < m; ++j) {
            landmark_t lm;
            memset(&lm, 0, sizeof lm);
            lm.mean = site(j, r);
            lm.cov = cov2_make(0.01, 0.0, 0.01);
            lm.id = (uint32_t)(j + 1);
            lm.exist = 10.0f;
            lm.n_obs = 10;
            lm.src_mask = 1;
            lm.signature = (uint8_t)(j % 4);
            fastslam_particle_add(&g_fs, k, &lm);
        }
        /* the tree's boxes clean, as the robot's are when a message comes
         * (each update's query cleans them; the merge skips subtrees by
         * them and looks into every stale one) */
        lm_tree_clean(&g_fs.lm_pool, g_fs.particles[k].lm_root);
    }
}

/* The own export the check reads and the incoming map of one case, and the
 * transform between them (identity, small uncertainty). */
static const pose2_t k_t = {0.0, 0.0, 0.0};
static const cov3_t k_tc = {{{1e-4, 0.0, 0.0}, {0.0, 1e-4, 0.0}, {0.0, 0.0, 1e-5}}};

static void build_message(int m, int m_in, rng_t *r)
{
    rng_seed(r, 7U);
    build_own_export(m, r);
    rng_seed(r, 7U);
    build_incoming(m_in, m, r);
}

static double naive_pairs_us(int n_particles, int m)
{
    /* all pairs per particle: the paper's O(N M^2) */
    const double t0 = now_us();
    volatile double sink = 0.0;
    for (int k = 0; k < n_particles; ++k) {
        const fastslam_particle_t *p = &g_fs.particles[k];
        const landmark_t *const *lms = fastslam_particle_landmarks(&g_fs, (uint16_t)k);
        for (uint16_t i = 0; i < g_bm.n; ++i) {
            double best = INFINITY;
            for (uint16_t j = 0; j < p->n_lm; ++j) {
                double d2;
                const point2_t w = pose2_apply(p->pose, g_bm.mean[i]);
                const landmark_t *lm = lms[j];
                if (cov2_mahalanobis2(cov2_add(lm->cov, g_bm.cov[i]), w.x - lm->mean.x,
                                      w.y - lm->mean.y, &d2) == COSLAM_OK &&
                    d2 < best) {
                    best = d2;
                }
            }
            sink += best;
        }
    }
    (void)m;
    (void)sink;
    return now_us() - t0;
}

/* EKF-SLAM with m landmarks at the bench's sites, and a message of m_in
 * (merge_batch: 0 the default). */
static void build_ekf_case(int m, int m_in, uint16_t merge_batch, rng_t *r)
{
    ekfslam_config_t ec = ekfslam_config_default();
    if (merge_batch > 0U) {
        ec.merge_batch = merge_batch;
    }
    const pose2_t p0 = {0.0, 0.0, 0.0};
    ekfslam_init(&g_ekf, &ec, p0);
    rng_seed(r, 7U);
    for (int j = 0; j < m; ++j) {
        ekfslam_meta_t meta = {(uint32_t)(j + 1), 10.0f, 10, 1, (uint8_t)(j % 4), 0};
        ekfslam_add_landmark_body(&g_ekf, site(j, r), cov2_make(0.01, 0.0, 0.01), &meta);
    }
    build_message(m, m_in, r);
}

/* merge_time.json's timed fields, in the order main fills them */
static const char *const k_fs_keys[] = {"merge_us", "part_max_us", "own_export_us", "export_pass1_ns",
                                        "export_pass2_ns", "send_max_us", "naive_search_us"};
static const char *const k_ekf_keys[] = {"merge_us", "merge_each_at_once_us", "part_first_us", "part_max_us"};

static int bench_merge_main(int argc, char **argv)
{
    const char *out = "out/bench";
    int reps = 3;
    int naive = 1;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) {
            if (bench_arg_int("coslam-bench-merge", "--reps", argv[++i], 1, 100, &reps) != 0) return 2;
        } else if (!strcmp(argv[i], "--no-naive")) naive = 0;
        else { fprintf(stderr, "usage: coslam-bench-merge [--out DIR] [--reps N] [--no-naive]\n"); return 2; }
    }
    profile_print(stdout, "coslam-bench-merge");
    if (mkdir(out, 0775) != 0 && errno != EEXIST) {
        fprintf(stderr, "coslam-bench-merge: cannot create %s: %s\n", out, strerror(errno));
        return 1;
    }
    /* (particles, own landmarks, incoming landmarks); the last: a merge as the
     * link carries it, one message of COSLAM_LINK_MSG_LANDMARKS */
    const int cases[4][3] = {{100, 64, 64}, {1000, 256, 256}, {1000, 1024, 1024}, {1000, 1024, COSLAM_LINK_MSG_LANDMARKS}};
    double fs_us[4];
    double part_us[4]; /* the largest call of the merge in parts */
    int part_calls[4];
    double export_us[4]; /* the own whole map the check compares with, in one call */
    double export_ns_per_lm[4][2]; /* its two passes, per landmark visited */
    double send_us[4];             /* the largest call of the send export in parts */
    int send_calls[4];
    double naive_us[4];
    rng_t r;
    rng_seed(&r, 1U);
    const merge_config_t mc = merge_config_default();
    for (int c = 0; c < 4; ++c) {
        const int n = cases[c][0];
        const int m = cases[c][1];
        const int m_in = cases[c][2];
        double best = INFINITY;
        for (int rep = 0; rep < reps; ++rep) {
            build_own_maps(n, m, &r);
            build_message(m, m_in, &r);
            merge_stats_t st;
            memset(&st, 0, sizeof st);
            const double t0 = now_us();
            merge_transform_map(&g_in, k_t, &k_tc, &mc, &g_bm, &st);
            merge_check(&g_own, &g_cov, NULL, &g_fs.cfg.slam, 0U, &mc, &g_bm, &g_sc, &st);
            merge_into_fastslam(&g_fs, &g_bm, &mc, &g_sc, &st);
            const double dt = now_us() - t0;
            best = dt < best ? dt : best;
            const int dups = (m_in + 1) / 2;
            if (rep == 0 && (st.fused != (uint32_t)(n * dups) || st.added != (uint32_t)(n * (m_in - dups)))) {
                fprintf(stderr,
                        "coslam-bench-merge: N=%d M=%d in %d fused %u added %u (expected %d and %d; the check left "
                        "out %u ambiguous, %u vetoed)\n",
                        n, m, m_in, st.fused, st.added, n * dups, n * (m_in - dups), st.ambiguous, st.vetoed);
            }
        }
        fs_us[c] = best;
        /* the robot's merge path in parts of mc.step_units
         * (slam_filter_merge_map, then slam_filter_idle after each step):
         * the own export for the check (fastslam_export_begin / _run), then
         * the check and the fusion (merge_fastslam_begin / _run), each call
         * spending about step_units; the first call also does the
         * transform. The check reads g_own as in the whole merge above (the
         * export lands in g_own_fs: the same map, built apart) */
        part_us[c] = INFINITY;
        export_us[c] = INFINITY;
        for (int rep = 0; rep < reps; ++rep) {
            build_own_maps(n, m, &r);
            const double te = now_us();
            fastslam_export_whole(&g_fs, &g_own_fs);
            const double dte = now_us() - te;
            export_us[c] = dte < export_us[c] ? dte : export_us[c];
            build_message(m, m_in, &r);
            merge_stats_t st;
            memset(&st, 0, sizeof st);
            uint16_t left = 0;
            int exported = 0;
            int calls = 0;
            double worst = 0.0;
            do {
                const double t0 = now_us();
                uint32_t budget = mc.step_units;
                if (calls == 0) {
                    merge_transform_map(&g_in, k_t, &k_tc, &mc, &g_bm, &st);
                    fastslam_export_begin(&g_fs);
                }
                if (!exported) {
                    uint32_t spent = 0U;
                    fastslam_export_run(&g_fs, &g_own_fs, mc.step_units, &exported, &spent);
                    if (exported) {
                        merge_check(&g_own, &g_cov, NULL, &g_fs.cfg.slam, 0U, &mc, &g_bm, &g_sc, &st);
                        merge_fastslam_begin(&g_fs, &g_bm, &mc, &g_sc, g_fs.export_scratch.job_pose);
                        budget = spent < budget ? budget - spent : 1U;
                    }
                }
                if (exported) {
                    merge_fastslam_run(&g_fs, &g_bm, &mc, &g_sc, &st, budget, &left);
                }
                const double dt = now_us() - t0;
                worst = dt > worst ? dt : worst;
                calls++;
            } while (!exported || left > 0U);
            part_us[c] = worst < part_us[c] ? worst : part_us[c];
            part_calls[c] = calls;
            const int dups = (m_in + 1) / 2;
            if (rep == 0 && (st.fused != (uint32_t)(n * dups) || st.added != (uint32_t)(n * (m_in - dups)))) {
                fprintf(stderr, "coslam-bench-merge: in parts, N=%d M=%d in %d fused %u added %u (expected %d and %d)\n",
                        n, m, m_in, st.fused, st.added, n * dups, n * (m_in - dups));
            }
        }
        /* the meeting's send export in parts of mc.step_units (the map a
         * message carries, fastslam_export_run_msg): calls and the largest */
        build_own_maps(n, m, &r);
        send_us[c] = 0.0;
        send_calls[c] = 0;
        fastslam_export_begin(&g_fs);
        for (int sent = 0; !sent;) {
            uint32_t spent = 0U;
            const double t0 = now_us();
            fastslam_export_run_msg(&g_fs, &g_in, mc.step_units, &sent, &spent);
            const double dt = now_us() - t0;
            send_us[c] = dt > send_us[c] ? dt : send_us[c];
            send_calls[c]++;
        }
        /* the export's cost per landmark in each pass (one particle a call),
         * against which FASTSLAM_EXPORT_UNITS_* are set */
        build_own_maps(n, m, &r);
        fastslam_export_begin(&g_fs);
        double pass_us[2] = {0.0, 0.0};
        int exported = 0;
        while (!exported) {
            const int pass = g_fs.export_scratch.job_pass;
            uint32_t spent = 0U;
            const double t0 = now_us();
            fastslam_export_run(&g_fs, &g_own_fs, 1U, &exported, &spent);
            pass_us[pass == 1 ? 0 : 1] += now_us() - t0;
        }
        for (int q = 0; q < 2; ++q) {
            export_ns_per_lm[c][q] = 1000.0 * pass_us[q] / ((double)n * m);
        }
        /* the naive search on the state before a merge */
        naive_us[c] = NAN;
        if (naive) {
            build_own_maps(n, m, &r);
            naive_us[c] = naive_pairs_us(n, m);
        }
        fprintf(stderr, ".");
    }
    /* EKF-SLAM */
    /* (own landmarks, incoming): the last, one message into a large map */
    const int ekf_m[3][2] = {{64, 64}, {256, 256}, {1024, COSLAM_LINK_MSG_LANDMARKS}};
    /* each case twice: the merge's updates applied together (the default
     * merge_batch) and each at once (merge_batch 1, as before) */
    double ekf_us[3][2];
    /* the robot's merge path in parts of mc.step_units (slam_filter_merge_map,
     * then slam_filter_idle): the first call the transform, the own export
     * for the check (with the compressed EKF's sync), the check and the
     * fusion's first part (merge_ekfslam_begin / _run), then one part a call */
    int ekf_calls[3];
    double ekf_first_us[3];
    double ekf_part_us[3];
    uint32_t ekf_fused[3][2];
    for (int c = 0; c < 3; ++c) {
        ekf_first_us[c] = INFINITY;
        ekf_part_us[c] = INFINITY;
        for (int rep = 0; rep < reps; ++rep) {
            build_ekf_case(ekf_m[c][0], ekf_m[c][1], 0U, &r);
            merge_stats_t st;
            memset(&st, 0, sizeof st);
            double t0 = now_us();
            merge_transform_map(&g_in, k_t, &k_tc, &mc, &g_bm, &st);
            ekfslam_export_whole(&g_ekf, &g_own_fs);
            merge_check(&g_own_fs, &g_cov, NULL, &g_ekf.cfg.slam, 0U, &mc, &g_bm, &g_sc, &st);
            merge_ekfslam_begin(&g_ekf, &g_bm, &mc, &g_sc, &st);
            int done = 0;
            merge_ekfslam_run(&g_ekf, &g_bm, &g_sc, &st, mc.step_units, &done);
            const double first = now_us() - t0;
            int calls = 1;
            double worst = 0.0;
            while (!done) {
                t0 = now_us();
                merge_ekfslam_run(&g_ekf, &g_bm, &g_sc, &st, mc.step_units, &done);
                const double dt = now_us() - t0;
                worst = dt > worst ? dt : worst;
                calls++;
            }
            ekf_calls[c] = calls;
            ekf_first_us[c] = first < ekf_first_us[c] ? first : ekf_first_us[c];
            ekf_part_us[c] = worst < ekf_part_us[c] ? worst : ekf_part_us[c];
            ekf_fused[c][0] = st.fused;
            ekf_fused[c][1] = st.added;
            fprintf(stderr, ".");
        }
    }
    for (int c = 0; c < 3; ++c) {
        for (int once = 0; once < 2; ++once) {
            build_ekf_case(ekf_m[c][0], ekf_m[c][1], once ? 1U : 0U, &r);
            merge_stats_t st;
            memset(&st, 0, sizeof st);
            const double t0 = now_us();
            merge_transform_map(&g_in, k_t, &k_tc, &mc, &g_bm, &st);
            merge_check(&g_own, &g_cov, NULL, &g_ekf.cfg.slam, 0U, &mc, &g_bm, &g_sc, &st);
            merge_into_ekfslam(&g_ekf, &g_bm, &mc, &g_sc, &st);
            ekf_us[c][once] = now_us() - t0;
            fprintf(stderr, ".");
        }
    }
    fprintf(stderr, "\n");
    FILE *md = NULL;
    FILE *js = NULL;
    if (bench_report_open("coslam-bench-merge", out, "merge_time", &md, &js) != 0) {
        return 1;
    }
    FILE *sinks[2] = {stdout, md};
    for (int k = 0; k < 2; ++k) {
        FILE *o = sinks[k];
        fprintf(o, "Map merge time (transform + check before trust + duplicates + fusion), best of %d runs; M own "
                   "landmarks per particle, M_in incoming (half duplicates), 64 keyframes of coverage. The last row is "
                   "a merge as the link carries it: one message holds at most %d landmarks.\n\n", reps,
                COSLAM_LINK_MSG_LANDMARKS);
        fprintf(o, "| Fast-SLAM (N, M, M_in) | merge [ms] | per particle and incoming landmark [ns] | own export "
                   "for the check, one call [ms] | merge path in parts of %u units (export, check, fusion): calls | "
                   "largest call [ms] | naive all-pairs duplicate search alone [ms] |\n|---|---|---|---|---|---|---|\n",
                mc.step_units);
        for (int c = 0; c < 4; ++c) {
            char naive_ms[32] = "-"; /* --no-naive: not measured */
            if (isfinite(naive_us[c])) {
                snprintf(naive_ms, sizeof naive_ms, "%.1f", naive_us[c] / 1000.0);
            }
            fprintf(o, "| (%d, %d, %d) | %.2f | %.1f | %.2f | %d | %.2f | %s |\n", cases[c][0], cases[c][1],
                    cases[c][2], fs_us[c] / 1000.0, 1000.0 * fs_us[c] / ((double)cases[c][0] * cases[c][2]),
                    export_us[c] / 1000.0, part_calls[c], part_us[c] / 1000.0, naive_ms);
        }
        fprintf(o, "\nThe merge column is the transform, the check and the fusion in one call; the robot's merge path "
                   "first exports its own whole map for the check (every particle's every landmark, O(N M)). In parts, "
                   "the export, then the check and the fusion, are spread over calls of about step_units each "
                   "(slam_filter_merge_map, then slam_filter_idle). The export's passes per landmark visited, against "
                   "which FASTSLAM_EXPORT_UNITS_PASS1 = %u and _PASS2 = %u units are set (the fusion's unit: about "
                   "8.5 ns on the machine they were fitted on):\n\n| (N, M) | pass 1 [ns] | pass 2 [ns] |\n|---|---|---|\n",
                FASTSLAM_EXPORT_UNITS_PASS1, FASTSLAM_EXPORT_UNITS_PASS2);
        for (int c = 0; c < 3; ++c) {
            fprintf(o, "| (%d, %d) | %.1f | %.1f |\n", cases[c][0], cases[c][1], export_ns_per_lm[c][0],
                    export_ns_per_lm[c][1]);
        }
        fprintf(o, "\nThe meeting's export of the map it sends (at most %d landmarks), in parts of %u units "
                   "(slam_filter_export_send):\n\n| (N, M) | calls | largest call [ms] |\n|---|---|---|\n",
                COSLAM_MAX_MSG_LANDMARKS, mc.step_units);
        for (int c = 0; c < 3; ++c) {
            fprintf(o, "| (%d, %d) | %d | %.2f |\n", cases[c][0], cases[c][1], send_calls[c], send_us[c] / 1000.0);
        }
        fprintf(o, "\n| EKF-SLAM (M, M_in) | merge [ms] | each update at once (merge_batch 1) [ms] | ratio | "
                   "merge path in parts of %u units: calls | first call (export, check, first part) [ms] | "
                   "largest later call [ms] | fused, added |\n|---|---|---|---|---|---|---|---|\n",
                mc.step_units);
        for (int c = 0; c < 3; ++c) {
            fprintf(o, "| (%d, %d) | %.2f | %.2f | %.1f | %d | %.2f | %.2f | %u, %u |\n", ekf_m[c][0], ekf_m[c][1],
                    ekf_us[c][0] / 1000.0, ekf_us[c][1] / 1000.0, ekf_us[c][1] / ekf_us[c][0], ekf_calls[c],
                    ekf_first_us[c] / 1000.0, ekf_part_us[c] / 1000.0, ekf_fused[c][0], ekf_fused[c][1]);
        }
        fprintf(o, "\nThe EKF-SLAM merge: a sequential update per direction of each duplicate's information, over "
                   "the whole state, its changes to P applied together up to merge_batch at a time (O(M^2) per "
                   "update either way). In parts (merge_ekfslam_run), the duplicates and additions go a few a call "
                   "and the changes to P in tiles of rows, at %.0f multiply-adds a unit; the robot holds the "
                   "filter's inputs meanwhile (slam_filter).\n",
                MERGE_EKF_MADDS_PER_UNIT);
    }
    /* naive_search_us is null with --no-naive (not measured) */
    fprintf(js, "{\"fastslam\": [");
    for (int c = 0; c < 4; ++c) {
        const double fs[] = {fs_us[c], part_us[c], export_us[c], export_ns_per_lm[c][0], export_ns_per_lm[c][1],
                             send_us[c], naive_us[c]};
        fprintf(js, "%s{\"particles\": %d, \"landmarks\": %d, \"incoming\": %d, \"part_calls\": %d, \"send_calls\": %d",
                c ? ", " : "", cases[c][0], cases[c][1], cases[c][2], part_calls[c], send_calls[c]);
        bench_json_fields(js, k_fs_keys, fs, 7, 1);
        fputc('}', js);
    }
    fprintf(js, "], \"ekfslam\": [");
    for (int c = 0; c < 3; ++c) {
        const double ek[] = {ekf_us[c][0], ekf_us[c][1], ekf_first_us[c], ekf_part_us[c]};
        fprintf(js, "%s{\"landmarks\": %d, \"incoming\": %d, \"part_calls\": %d", c ? ", " : "", ekf_m[c][0],
                ekf_m[c][1], ekf_calls[c]);
        bench_json_fields(js, k_ekf_keys, ek, 4, 1);
        fputc('}', js);
    }
    fprintf(js, "]}\n");
    if (bench_report_close("coslam-bench-merge", out, "merge_time", md, js) != 0) {
        return 1;
    }
    return 0;
}

/* exit status with standard output checked (stdout_check.h) */
int main(int argc, char **argv)
{
    return stdout_check_exit("coslam-bench-merge", bench_merge_main(argc, argv));
}
