/*
 * Property test of the SLAM core (issue 12, item 6; docs/fuzzing.md):
 * N random filter and merge operations, adversarial values included, on
 * three filters at once - EKF-SLAM, Fast-SLAM 1.0 and Fast-SLAM 2.0 with a
 * few particles - through the one filter interface every tool uses
 * (app/slam_filter.h), plus the cov2 / cov3 operations directly.
 *
 * Usage: test_property_filters [n_ops [seed [absurd]]]   (defaults 20000, 1)
 *   absurd: also absurd but finite values (1e308, DBL_MAX, 1e300, 1e6 m of
 *   odometry in one step); absurd-predict, absurd-update, absurd-merge,
 *   absurd-cov: only in that operation. See adversarial(), docs/fuzzing.md.
 *
 * Operations, drawn from an explicit seed (xorshift64*, printed on failure
 * so that `test_property_filters <n> <seed>` replays the run):
 *   predict   one odometry increment into every filter; 1 in 5 with an
 *             adversarial component (NaN, +-inf, +-1e308, DBL_MAX, 1e-300,
 *             subnormal 5e-324, -0, 1e6, -1);
 *   update    0 .. COSLAM_MAX_SIGHTINGS + 2 sightings of a fixed world of
 *             landmarks, seen from the true pose with noise; 1 in 5 with
 *             adversarial ranges / bearings;
 *   export    map_estimate of each filter;
 *   merge     one filter's export, as the map of a robot standing 1.5 m in
 *             front facing back, merged into another (slam_filter_merge_map,
 *             the robot's merge path); 1 in 3 with adversarial content (means,
 *             variances negative / NaN / 1e-300 / 1e300, pose covariance,
 *             sighting variances, landmark count);
 *   cov       cov2 / cov3 operations on random and adversarial matrices.
 * Properties, after every operation:
 *   - every covariance the filters hold or export is finite, symmetric and
 *     positive semi-definite within a relative tolerance (EKF: the whole P,
 *     by Cholesky with a 1e-9 relative jitter, every 16th operation and
 *     O(D^2) checks in between; Fast-SLAM: every particle's pose marginal,
 *     pending covariance and every landmark covariance; the pose estimate;
 *     every exported cov, cov_rel and pose_cov);
 *   - every Fast-SLAM weight is finite, >= 0, and they sum to 1;
 *   - a refused input leaves the state unchanged: a predict that returns an
 *     error, a merge that returns an error other than COSLAM_E_CAPACITY
 *     (EKF: x and P bit-identical; Fast-SLAM: poses, weights, marginals and
 *     landmark count of every particle bit-identical);
 *   - cov2 / cov3: a factorisation or inverse that succeeds is right
 *     (L L^T = A, A A^-1 = I within tolerance) and PD in gives PD out;
 *     cov2_clamp_eigen of a finite symmetric matrix has eigenvalues
 *     >= min_eig.
 */
#include <float.h>
#include <inttypes.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app/slam_filter.h"
#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/map_merge.h"
#include "coslam/pose2.h"

/* ------------------------------------------------------------------ rng */
static uint64_t g_rng;
static uint64_t g_seed;
static long g_op;
static const char *g_what = "init";

static uint64_t rnd_u64(void)
{
    g_rng ^= g_rng >> 12;
    g_rng ^= g_rng << 25;
    g_rng ^= g_rng >> 27;
    return g_rng * 2685821657736338717ULL;
}
static double rnd_unit(void) { return (double)(rnd_u64() >> 11) * (1.0 / 9007199254740992.0); }
static double rnd_uniform(double a, double b) { return a + (b - a) * rnd_unit(); }
static unsigned rnd_below(unsigned n) { return (unsigned)(rnd_u64() % n); }
static double rnd_normal(void)
{
    const double u1 = rnd_unit() + 1e-300;
    const double u2 = rnd_unit();
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

/* Adversarial values. The first ones are what the core promises to refuse
 * or survive today (non-finite, tiny, subnormal, zero, negative); the
 * "absurd but finite" ones after them (g_absurd: command-line mode
 * "absurd") need the plausibility bounds of issue 12 item 1. */
static int g_absurd;
static const char *g_absurd_only = ""; /* "absurd-<op>": only in that operation */
static const char *g_op_name = "";

static double adversarial(void)
{
    static const double v[] = {NAN,  INFINITY, -INFINITY, 1e-300, 5e-324, -0.0,  0.0,
                               -1.0, 1e-20,    -1e-300,   4.9e-324, /* absurd: */ 1e308,
                               -1e308, DBL_MAX, 1e6,      1e300};
    const unsigned n_safe = 11U;
    const int on = g_absurd && (g_absurd_only[0] == '\0' || strcmp(g_absurd_only, g_op_name) == 0);
    const unsigned n = on ? (unsigned)(sizeof v / sizeof v[0]) : n_safe;
    return v[rnd_below(n)];
}

/* ------------------------------------------------------------ failures */
static odo_increment_t g_last_u;

static void fail(const char *fmt, const char *detail, double a, double b)
{
    if (strncmp(g_what, "predict", 7) == 0) {
        fprintf(stderr, "  last odometry increment: dx %.17g dy %.17g dtheta %.17g\n", g_last_u.dx, g_last_u.dy,
                g_last_u.dtheta);
    }
    fprintf(stderr,
            "PROPERTY FAILED: %s (%s: %.17g, %.17g)\n  at operation %ld (%s), seed %" PRIu64
            "\n  replay: test_property_filters %ld %" PRIu64 "%s%s%s\n",
            fmt, detail, a, b, g_op, g_what, g_seed, g_op + 1, g_seed, g_absurd ? " absurd" : "",
            g_absurd_only[0] != '\0' ? "-" : "", g_absurd_only);
    exit(1);
}

/* --------------------------------------------------------- matrix checks */
static int sym_ok(double a, double b, double scale)
{
    return fabs(a - b) <= 1e-9 * scale + 1e-300;
}

static void check_cov2(cov2_t c, const char *where)
{
    if (!cov2_is_finite(c)) {
        fail("covariance not finite", where, c.xx, c.yy);
    }
    const double s = fabs(c.xx) + fabs(c.yy);
    if (c.xx < -1e-12 * s || c.yy < -1e-12 * s) {
        fail("negative variance", where, c.xx, c.yy);
    }
    if (c.xx * c.yy - c.xy * c.xy < -1e-9 * (c.xx * c.yy + c.xy * c.xy) - 1e-300) {
        fail("2x2 covariance not PSD", where, c.xx * c.yy, c.xy * c.xy);
    }
}

/* Cholesky of A + jitter I (jitter = 1e-9 * max diag): PSD within tolerance. */
static int psd_dense(const double *a, int n, int stride, double *work)
{
    double dmax = 0.0;
    for (int i = 0; i < n; ++i) {
        dmax = fmax(dmax, fabs(a[i * stride + i]));
    }
    const double jitter = 1e-9 * dmax + 1e-300;
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j <= i; ++j) {
            double s = 0.5 * (a[i * stride + j] + a[j * stride + i]) + (i == j ? jitter : 0.0);
            for (int k = 0; k < j; ++k) {
                s -= work[i * n + k] * work[j * n + k];
            }
            if (i == j) {
                if (!(s > 0.0)) {
                    return 0;
                }
                work[i * n + i] = sqrt(s);
            } else {
                work[i * n + j] = s / work[j * n + j];
            }
        }
    }
    return 1;
}

static void check_cov3(const cov3_t *c, const char *where)
{
    if (!cov3_is_finite(*c)) {
        fail("3x3 covariance not finite", where, c->m[0][0], c->m[2][2]);
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < i; ++j) {
            if (!sym_ok(c->m[i][j], c->m[j][i], sqrt(fabs(c->m[i][i] * c->m[j][j])) + fabs(c->m[i][j]))) {
                fail("3x3 covariance not symmetric", where, c->m[i][j], c->m[j][i]);
            }
        }
    }
    double work[9];
    if (!psd_dense(&c->m[0][0], 3, 3, work)) {
        fail("3x3 covariance not PSD", where, c->m[0][0], c->m[2][2]);
    }
}

/* ---------------------------------------------------------------- world */
enum { N_WORLD = 24 };
static point2_t g_world[N_WORLD];
static uint8_t g_world_sig[N_WORLD];
static pose2_t g_truth;

/* -------------------------------------------------------------- filters */
enum { N_FILTERS = 3, FS_PARTICLES = 8 };
static slam_filter_t g_f[N_FILTERS];
static slam_filter_t g_before; /* snapshot for the "refused: unchanged" checks (fields compared) */
static slam_filter_config_t g_cfg[N_FILTERS];
static slam_merge_work_t g_work;
static map_estimate_t g_map;
static map_estimate_t g_in;
static double g_chol[EKFSLAM_DIM * EKFSLAM_DIM];
static long g_merges_ok;
static long g_merges_refused;
static unsigned g_max_lm[N_FILTERS];
static const char *const k_names[N_FILTERS] = {"EKF-SLAM", "Fast-SLAM 1.0", "Fast-SLAM 2.0"};

static void check_map(const map_estimate_t *m, const char *where)
{
    check_cov3(&m->pose_cov, where);
    if (m->n_landmarks > COSLAM_MAX_MSG_LANDMARKS) {
        fail("exported landmark count above capacity", where, m->n_landmarks, COSLAM_MAX_MSG_LANDMARKS);
    }
    for (uint16_t j = 0; j < m->n_landmarks; ++j) {
        if (!isfinite(m->lm[j].mean.x) || !isfinite(m->lm[j].mean.y)) {
            fail("exported landmark mean not finite", where, m->lm[j].mean.x, m->lm[j].mean.y);
        }
        check_cov2(m->lm[j].cov, where);
        check_cov2(m->lm[j].cov_rel, where);
    }
}

static ekfslam_t g_ekf_synced;
/* the refused-input snapshot of a compressed EKF with entries pending */
static int g_snap_readers;
static pose2_t g_snap_pose;
static cov3_t g_snap_pose_cov;
static point2_t g_snap_lm[COSLAM_EKF_MAX_LANDMARKS];
static cov2_t g_snap_lm_cov[COSLAM_EKF_MAX_LANDMARKS];

/* Has the compressed EKF a local phase open or entries pending? */
static int ekf_pending(const ekfslam_t *e)
{
    int n = e->cekf.local != 0U;
    for (int g = 0; g < EKFSLAM_PEND_GENS; ++g) {
        n += e->cekf.gen[g].n > 0;
    }
    return n > 0;
}

static void check_filter(int i, int full)
{
    slam_filter_t *f = &g_f[i];
    const char *name = k_names[i];
    pose2_t pose;
    cov3_t pc;
    slam_filter_pose(f, &pose, &pc);
    if (!isfinite(pose.x) || !isfinite(pose.y) || !isfinite(pose.theta)) {
        fail("pose estimate not finite", name, pose.x, pose.y);
    }
    check_cov3(&pc, name);
    if (f->kind == SLAM_FILTER_EKF) {
        /* the compressed EKF (profiles with COSLAM_EKF_MAX_ACTIVE > 0) keeps
         * P's entries outside its active part with corrections pending: the
         * covariance is what ekfslam_sync makes of a copy */
        const ekfslam_t *e = &f->u.ekf;
        g_max_lm[i] = e->n_lm > g_max_lm[i] ? e->n_lm : g_max_lm[i];
        if (ekf_pending(e)) {
            if (!full) {
                /* a copy costs the whole state: only on the full checks;
                 * the pose (above) and the landmarks through the readers */
                for (uint16_t j = 0; j < e->n_lm; ++j) {
                    point2_t m;
                    cov2_t c;
                    ekfslam_landmark(e, j, &m, &c);
                    if (!isfinite(m.x) || !isfinite(m.y)) {
                        fail("EKF landmark not finite", name, m.x, m.y);
                    }
                    check_cov2(c, name);
                }
                return;
            }
            g_ekf_synced = *e;
            ekfslam_sync(&g_ekf_synced);
            e = &g_ekf_synced;
        }
        const int d = 3 + 2 * (int)e->n_lm;
        for (int r = 0; r < d; ++r) {
            const double prr = e->p[r * EKFSLAM_DIM + r];
            if (!isfinite(e->x[r]) || !isfinite(prr) || prr < 0.0) {
                fail("EKF state or variance not finite / negative", name, e->x[r], prr);
            }
            for (int c = 0; c < r; ++c) {
                const double a = e->p[r * EKFSLAM_DIM + c];
                const double b = e->p[c * EKFSLAM_DIM + r];
                const double pcc = e->p[c * EKFSLAM_DIM + c];
                if (!isfinite(a) || !sym_ok(a, b, sqrt(prr * pcc) + fabs(a))) {
                    fail("EKF P not symmetric", name, a, b);
                }
                if (a * a > prr * pcc * (1.0 + 1e-9) + 1e-300) {
                    fail("EKF P has |P_rc|^2 > P_rr P_cc (not PSD)", name, a * a, prr * pcc);
                }
            }
        }
        for (uint16_t j = 0; j < e->n_lm; ++j) {
            point2_t m;
            cov2_t c;
            ekfslam_landmark(e, j, &m, &c);
            check_cov2(c, name);
        }
        if (full && !psd_dense(e->p, d, EKFSLAM_DIM, g_chol)) {
            fail("EKF P not PSD (Cholesky with 1e-9 relative jitter)", name, d, 0);
        }
    } else {
        const fastslam_t *fs = &f->u.fs;
        double w[COSLAM_MAX_PARTICLES];
        fastslam_weights(fs, w);
        double sum = 0.0;
        for (uint16_t k = 0; k < fs->cfg.n_particles; ++k) {
            if (!isfinite(w[k]) || w[k] < 0.0 || !isfinite(fs->particles[k].log_w)) {
                fail("Fast-SLAM weight not finite / negative", name, w[k], fs->particles[k].log_w);
            }
            sum += w[k];
            const fastslam_particle_t *p = &fs->particles[k];
            if (!isfinite(p->pose.x) || !isfinite(p->pose.y) || !isfinite(p->pose.theta)) {
                fail("particle pose not finite", name, p->pose.x, p->pose.y);
            }
            g_max_lm[i] = p->n_lm > g_max_lm[i] ? p->n_lm : g_max_lm[i];
            check_cov3(&p->pose_marg, name);
            check_cov3(&p->pending_cov, name);
            for (uint16_t j = 0; j < p->n_lm; ++j) {
                const landmark_t *lm = fastslam_particle_lm(fs, k, j);
                if (!isfinite(lm->mean.x) || !isfinite(lm->mean.y) || !isfinite((double)lm->exist)) {
                    fail("particle landmark not finite", name, lm->mean.x, (double)lm->exist);
                }
                check_cov2(lm->cov, name);
            }
        }
        if (fabs(sum - 1.0) > 1e-9) {
            fail("Fast-SLAM weights do not sum to 1", name, sum, 1.0);
        }
    }
}

/* Refused input: the filter's state must be bit-identical to the snapshot. */
static void check_unchanged(int i, const char *why)
{
    const slam_filter_t *a = &g_before;
    const slam_filter_t *b = &g_f[i];
    if (b->kind == SLAM_FILTER_EKF) {
        const ekfslam_t *x = &a->u.ekf;
        const ekfslam_t *y = &b->u.ekf;
        if (x->n_lm != y->n_lm) {
            fail("refused input changed the EKF landmark count", why, x->n_lm, y->n_lm);
        }
        if (g_snap_readers) {
            /* entries were pending: a refused predict or merge may still
             * complete some (its share of the deferred work, ekfslam_sync),
             * which changes how P is stored, not the estimate; so the
             * estimate through the const readers, to rounding (completions
             * add in another order) */
            pose2_t pose;
            cov3_t pc;
            ekfslam_pose(y, &pose, &pc);
            const double tp[3] = {pose.x - g_snap_pose.x, pose.y - g_snap_pose.y, pose.theta - g_snap_pose.theta};
            for (int r = 0; r < 3; ++r) {
                if (!(fabs(tp[r]) <= 1e-9 * (1.0 + fabs(pose.x) + fabs(pose.y)))) {
                    fail("refused input changed the EKF pose", why, r, tp[r]);
                }
                for (int c = 0; c < 3; ++c) {
                    const double sc = sqrt(fabs(pc.m[r][r] * pc.m[c][c]));
                    if (!(fabs(pc.m[r][c] - g_snap_pose_cov.m[r][c]) <= 1e-9 * sc)) {
                        fail("refused input changed the EKF pose covariance", why, pc.m[r][c], g_snap_pose_cov.m[r][c]);
                    }
                }
            }
            for (uint16_t j = 0; j < y->n_lm; ++j) {
                point2_t m;
                cov2_t c;
                ekfslam_landmark(y, j, &m, &c);
                const cov2_t c0 = g_snap_lm_cov[j];
                const double sc = sqrt(fabs(c0.xx * c0.yy));
                if (!(hypot(m.x - g_snap_lm[j].x, m.y - g_snap_lm[j].y) <= 1e-9 * (1.0 + hypot(m.x, m.y))) ||
                    !(fabs(c.xx - c0.xx) <= 1e-9 * c0.xx) || !(fabs(c.yy - c0.yy) <= 1e-9 * c0.yy) ||
                    !(fabs(c.xy - c0.xy) <= 1e-9 * sc)) {
                    fail("refused input changed an EKF landmark", why, j, m.x - g_snap_lm[j].x);
                }
            }
            return;
        }
        const int d = 3 + 2 * (int)x->n_lm;
        for (int r = 0; r < d; ++r) {
            if (memcmp(&x->x[r], &y->x[r], sizeof(double)) != 0) {
                fail("refused input changed the EKF state", why, x->x[r], y->x[r]);
            }
            if (memcmp(&x->p[r * EKFSLAM_DIM], &y->p[r * EKFSLAM_DIM], (size_t)d * sizeof(double)) != 0) {
                fail("refused input changed the EKF covariance", why, r, d);
            }
        }
    } else {
        const fastslam_t *x = &a->u.fs;
        const fastslam_t *y = &b->u.fs;
        for (uint16_t k = 0; k < x->cfg.n_particles; ++k) {
            const fastslam_particle_t *p = &x->particles[k];
            const fastslam_particle_t *q = &y->particles[k];
            if (memcmp(&p->pose, &q->pose, sizeof p->pose) != 0 || memcmp(&p->log_w, &q->log_w, sizeof p->log_w) ||
                memcmp(&p->pose_marg, &q->pose_marg, sizeof p->pose_marg) != 0 ||
                memcmp(&p->pending_cov, &q->pending_cov, sizeof p->pending_cov) != 0 || p->n_lm != q->n_lm ||
                p->lm_root != q->lm_root) {
                fail("refused input changed a particle", why, k, q->n_lm);
            }
        }
    }
}

static void snapshot(int i)
{
    g_before.kind = g_f[i].kind;
    if (g_f[i].kind == SLAM_FILTER_EKF) {
        const ekfslam_t *e = &g_f[i].u.ekf;
        g_before.u.ekf.n_lm = e->n_lm;
        g_snap_readers = ekf_pending(e);
        if (g_snap_readers) {
            /* the compressed EKF with entries pending (profiles with
             * COSLAM_EKF_MAX_ACTIVE > 0): what its const readers say */
            ekfslam_pose(e, &g_snap_pose, &g_snap_pose_cov);
            for (uint16_t j = 0; j < e->n_lm; ++j) {
                ekfslam_landmark(e, j, &g_snap_lm[j], &g_snap_lm_cov[j]);
            }
        } else {
            const int d = 3 + 2 * (int)e->n_lm;
            memcpy(g_before.u.ekf.x, e->x, (size_t)d * sizeof(double));
            for (int r = 0; r < d; ++r) {
                memcpy(&g_before.u.ekf.p[r * EKFSLAM_DIM], &e->p[r * EKFSLAM_DIM], (size_t)d * sizeof(double));
            }
        }
    } else {
        g_before.u.fs.cfg = g_f[i].u.fs.cfg;
        memcpy(g_before.u.fs.particles, g_f[i].u.fs.particles, sizeof g_before.u.fs.particles);
    }
}

/* ----------------------------------------------------------- operations */

static void op_predict(void)
{
    g_op_name = "predict";
    const double v = rnd_uniform(0.0, 0.08);
    odo_increment_t u = {v, rnd_normal() * 0.002, rnd_uniform(-0.15, 0.15)};
    int adv = rnd_below(5) == 0;
    if (adv) {
        switch (rnd_below(3)) {
        case 0: u.dx = adversarial(); break;
        case 1: u.dy = adversarial(); break;
        default: u.dtheta = adversarial(); break;
        }
        g_what = "predict (adversarial)";
    } else {
        g_what = "predict";
        g_truth = pose2_compose(g_truth, (pose2_t){u.dx, u.dy, u.dtheta});
        /* stay in the world: turn back towards the middle */
        if (fabs(g_truth.x) > 6.0 || fabs(g_truth.y) > 6.0) {
            g_truth.theta = atan2(-g_truth.y, -g_truth.x);
        }
    }
    g_last_u = u;
    /* the control period, or a time span so long that only the filters'
     * own bound (MOTION_MAX_INCREMENT_S) stands between an absurd increment
     * and the covariance */
    const double dt = rnd_below(2) == 0 ? 0.1 : 1e6;
    for (int i = 0; i < N_FILTERS; ++i) {
        snapshot(i);
        const coslam_status_t st = slam_filter_predict(&g_f[i], u, dt);
        if (st != COSLAM_OK) {
            check_unchanged(i, "predict refused");
        }
        check_filter(i, 0);
    }
}

static void op_update(void)
{
    g_op_name = "update";
    sighting_t z[COSLAM_MAX_SIGHTINGS + 2];
    int n = 0;
    const int adv = rnd_below(5) == 0;
    g_what = adv ? "update (adversarial)" : "update";
    const int want = (int)rnd_below(COSLAM_MAX_SIGHTINGS + 3);
    for (int j = 0; j < N_WORLD && n < want; ++j) {
        const point2_t rel = pose2_apply_inverse(g_truth, g_world[j]);
        const double r = hypot(rel.x, rel.y);
        const double b = atan2(rel.y, rel.x);
        if (r < 0.3 || r > 4.5 || fabs(b) > 0.7) {
            continue;
        }
        z[n].range_m = r * (1.0 + 0.02 * rnd_normal());
        z[n].bearing_rad = b + 0.02 * rnd_normal();
        z[n].signature = g_world_sig[j];
        ++n;
    }
    while (n < want && rnd_below(4) == 0) { /* clutter */
        z[n].range_m = rnd_uniform(0.3, 4.5);
        z[n].bearing_rad = rnd_uniform(-0.7, 0.7);
        z[n].signature = (uint8_t)rnd_below(4);
        ++n;
    }
    if (adv && n > 0) {
        const int k = (int)rnd_below((unsigned)n);
        if (rnd_below(2) == 0) {
            z[k].range_m = adversarial();
        } else {
            z[k].bearing_rad = adversarial();
        }
    }
    for (int i = 0; i < N_FILTERS; ++i) {
        (void)slam_filter_update(&g_f[i], z, n);
        check_filter(i, 0);
    }
}

static void op_export(void)
{
    g_what = "export";
    for (int i = 0; i < N_FILTERS; ++i) {
        const coslam_status_t st = slam_filter_export(&g_f[i], &g_map);
        if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
            fail("export failed", k_names[i], st, 0);
        }
        check_map(&g_map, k_names[i]);
        check_filter(i, 1);
    }
}

static cov2_t adv_cov2(cov2_t c)
{
    switch (rnd_below(4)) {
    case 0: c.xx = adversarial(); break;
    case 1: c.yy = adversarial(); break;
    case 2: c.xy = adversarial(); break;
    default: c = cov2_make(-c.xx, c.xy, c.yy); break;
    }
    return c;
}

/* Sender = a robot standing D m in front of `from`'s pose, facing back: its
 * map is `from`'s export with its pose moved there (landmarks relative to it
 * rotated by pi: the covariances of a 180 degree rotation are unchanged). */
static void op_merge(void)
{
    g_op_name = "merge";
    const int from = (int)rnd_below(N_FILTERS);
    int into = (int)rnd_below(N_FILTERS - 1);
    if (into >= from) {
        ++into;
    }
    const double dist = 1.5;
    if (slam_filter_export(&g_f[from], &g_in) != COSLAM_OK) {
        return;
    }
    const pose2_t sender = pose2_compose(g_in.pose, (pose2_t){dist, 0.0, 3.14159265358979323846});
    g_in.pose = sender;
    for (uint16_t j = 0; j < g_in.n_landmarks; ++j) {
        g_in.lm[j].src_mask = (uint16_t)(1U << 1);
        if (g_in.lm[j].n_obs < 5U) {
            g_in.lm[j].n_obs = 5U;
        }
    }
    merge_geometry_t g;
    memset(&g, 0, sizeof g);
    g.self_sees_other = (robot_sighting_t){dist, 0.0, 1e-4, 1e-4};
    g.other_sees_self = (robot_sighting_t){dist, 0.0, 1e-4, 1e-4};
    const int adv = rnd_below(3) == 0;
    g_what = adv ? "merge (adversarial)" : "merge";
    if (adv) {
        const uint16_t n = g_in.n_landmarks;
        const uint16_t j = n > 0 ? (uint16_t)rnd_below(n) : 0U;
        switch (rnd_below(9)) {
        case 0: if (n) g_in.lm[j].mean.x = adversarial(); break;
        case 1: if (n) g_in.lm[j].cov = adv_cov2(g_in.lm[j].cov); break;
        case 2: if (n) g_in.lm[j].cov_rel = adv_cov2(g_in.lm[j].cov_rel); break;
        case 3: g_in.pose_cov.m[rnd_below(3)][rnd_below(3)] = adversarial(); break;
        case 4: g.self_sees_other.range_var_m2 = adversarial(); break;
        case 5: g.other_sees_self.bearing_var_rad2 = adversarial(); break;
        case 6: g.self_sees_other.range_m = adversarial(); break;
        case 7: g_in.pose.theta = adversarial(); break;
        default: g.own_travel_m = adversarial(); break;
        }
    }
    merge_config_t cfg = merge_config_default();
    merge_stats_t stats;
    snapshot(into);
    const coslam_status_t st =
        slam_filter_merge_map(&g_f[into], &g_in, &g, &cfg, NULL, &g_work, &stats, NULL, NULL);
    if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
        check_unchanged(into, "merge refused");
        g_merges_refused++;
    } else {
        g_merges_ok++;
    }
    check_filter(into, 1);
}

static cov2_t rnd_cov2(int adv)
{
    const double a = rnd_uniform(1e-6, 2.0);
    const double b = rnd_uniform(1e-6, 2.0);
    const double rho = rnd_uniform(-0.99, 0.99);
    cov2_t c = cov2_make(a, rho * sqrt(a * b), b);
    return adv ? adv_cov2(c) : c;
}

static cov3_t rnd_cov3(int adv)
{
    double g[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            g[i][j] = rnd_normal();
        }
    }
    cov3_t c = cov3_diag(1e-6, 1e-6, 1e-6);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            for (int k = 0; k < 3; ++k) {
                c.m[i][j] += g[i][k] * g[j][k];
            }
        }
    }
    if (adv) {
        const int i = (int)rnd_below(3);
        const int j = (int)rnd_below(3);
        c.m[i][j] = adversarial();
        c.m[j][i] = c.m[i][j];
    }
    return c;
}

static void op_cov(void)
{
    g_op_name = "cov";
    const int adv = rnd_below(3) == 0;
    g_what = adv ? "cov2/cov3 (adversarial)" : "cov2/cov3";
    const cov2_t a = rnd_cov2(adv);
    const cov2_t b = rnd_cov2(0);
    const int a_pd = cov2_is_pd(a) && fabs(a.xx) + fabs(a.yy) < 1e100;
    if (a_pd) {
        check_cov2(cov2_add(a, b), "cov2_add of PD");
        check_cov2(cov2_scale(a, rnd_uniform(0.0, 10.0)), "cov2_scale of PD");
        const double th = rnd_uniform(-4.0, 4.0);
        double r[2][2] = {{cos(th), -sin(th)}, {sin(th), cos(th)}};
        check_cov2(cov2_congruence(r, a), "cov2_congruence of PD");
    }
    cov2_t inv = {0.0, 0.0, 0.0};
    const cov2_t sentinel = {123.0, 456.0, 789.0};
    inv = sentinel;
    const coslam_status_t si = cov2_inverse(a, &inv);
    if (si == COSLAM_OK) {
        if (!cov2_is_pd(inv)) {
            fail("cov2_inverse accepted, result not PD", "cov2", inv.xx, inv.yy);
        }
        const double e00 = a.xx * inv.xx + a.xy * inv.xy;
        const double e01 = a.xx * inv.xy + a.xy * inv.yy;
        const double e11 = a.xy * inv.xy + a.yy * inv.yy;
        const double cond = (fabs(a.xx) + fabs(a.yy)) * (fabs(inv.xx) + fabs(inv.yy));
        if (fabs(e00 - 1.0) > 1e-9 * cond || fabs(e11 - 1.0) > 1e-9 * cond || fabs(e01) > 1e-9 * cond) {
            fail("cov2_inverse: A A^-1 != I", "cov2", e00, e11);
        }
    } else if (memcmp(&inv, &sentinel, sizeof inv) != 0) {
        fail("cov2_inverse refused but wrote *out", "cov2", inv.xx, inv.yy);
    }
    double l[3];
    if (cov2_cholesky(a, l) == COSLAM_OK) {
        if (!(l[0] > 0.0) || !(l[2] > 0.0)) {
            fail("cov2_cholesky: diagonal not positive", "cov2", l[0], l[2]);
        }
        const double s = fabs(a.xx) + fabs(a.yy);
        if (fabs(l[0] * l[0] - a.xx) > 1e-9 * s || fabs(l[0] * l[1] - a.xy) > 1e-9 * s ||
            fabs(l[1] * l[1] + l[2] * l[2] - a.yy) > 1e-9 * s) {
            fail("cov2_cholesky: L L^T != A", "cov2", l[0] * l[0], a.xx);
        }
    }
    if (cov2_is_finite(a)) {
        const double min_eig = rnd_uniform(1e-12, 1e-3);
        const cov2_t c = cov2_clamp_eigen(a, min_eig);
        double lo = 0.0;
        double hi = 0.0;
        cov2_eigenvalues(c, &lo, &hi);
        if (cov2_is_finite(c) && lo < min_eig * (1.0 - 1e-6) - 1e-12 * fabs(hi)) {
            fail("cov2_clamp_eigen: eigenvalue below min_eig", "cov2", lo, min_eig);
        }
    }
    const cov3_t p = rnd_cov3(adv);
    double l3[3][3];
    if (cov3_cholesky(p, l3) == COSLAM_OK) {
        double s = 0.0;
        for (int i = 0; i < 3; ++i) {
            s += fabs(p.m[i][i]);
        }
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j <= i; ++j) {
                double v = 0.0;
                for (int k = 0; k < 3; ++k) {
                    v += l3[i][k] * l3[j][k];
                }
                if (!isfinite(v) || fabs(v - p.m[i][j]) > 1e-9 * s) {
                    fail("cov3_cholesky: L L^T != A", "cov3", v, p.m[i][j]);
                }
            }
        }
    }
    cov3_t p_inv;
    if (cov3_inverse(p, &p_inv) == COSLAM_OK) {
        if (!cov3_is_finite(p_inv)) {
            fail("cov3_inverse accepted, result not finite", "cov3", p_inv.m[0][0], p_inv.m[2][2]);
        }
    }
    double pmax = 0.0;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            pmax = fmax(pmax, fabs(p.m[i][j]));
        }
    }
    /* (sums and products of entries near DBL_MAX overflow: arithmetic, not
     * a defect; the filters must refuse such values before they get there) */
    if (cov3_is_pd(p) && pmax < 1e100) {
        check_cov3(&p, "cov3 PD input");
        const cov3_t q = cov3_symmetrize(cov3_add(p, rnd_cov3(0)));
        check_cov3(&q, "cov3_add of PD");
        double jm[3][3];
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                jm[i][j] = rnd_normal();
            }
        }
        const cov3_t cg = cov3_symmetrize(cov3_congruence(jm, p));
        check_cov3(&cg, "cov3_congruence of PD");
    }
}

/* --------------------------------------------------------------- main */
static void setup(void)
{
    for (int j = 0; j < N_WORLD; ++j) {
        g_world[j] = (point2_t){rnd_uniform(-7.0, 7.0), rnd_uniform(-7.0, 7.0)};
        g_world_sig[j] = (uint8_t)rnd_below(4);
    }
    g_truth = (pose2_t){0.0, 0.0, 0.0};
    const slam_filter_kind_t kinds[N_FILTERS] = {SLAM_FILTER_EKF, SLAM_FILTER_FASTSLAM1, SLAM_FILTER_FASTSLAM2};
    for (int i = 0; i < N_FILTERS; ++i) {
        g_cfg[i] = slam_filter_config_default();
        g_cfg[i].kind = kinds[i];
        g_cfg[i].n_particles = FS_PARTICLES;
        g_cfg[i].seed = g_seed + (uint64_t)i;
        g_cfg[i].robot_id = 0U;
        if (slam_filter_init(&g_f[i], &g_cfg[i], g_truth) != COSLAM_OK) {
            fail("slam_filter_init failed", k_names[i], i, 0);
        }
        check_filter(i, 1);
    }
}

int main(int argc, char **argv)
{
    const long n_ops = argc > 1 ? strtol(argv[1], NULL, 10) : 20000L;
    g_seed = argc > 2 ? strtoull(argv[2], NULL, 10) : 1ULL;
    g_absurd = argc > 3 && strncmp(argv[3], "absurd", 6) == 0;
    if (g_absurd && argv[3][6] == '-') {
        g_absurd_only = argv[3] + 7;
    }
    g_rng = g_seed * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL;
    if (g_rng == 0U) {
        g_rng = 1U;
    }
    g_op = -1;
    setup();
    long counts[5] = {0, 0, 0, 0, 0};
    for (g_op = 0; g_op < n_ops; ++g_op) {
        const unsigned r = rnd_below(100);
        if (r < 30) {
            op_predict();
            counts[0]++;
        } else if (r < 60) {
            op_update();
            counts[1]++;
        } else if (r < 68) {
            op_export();
            counts[2]++;
        } else if (r < 76) {
            op_merge();
            counts[3]++;
        } else {
            op_cov();
            counts[4]++;
        }
        /* a fresh start now and then, so that long runs do not only test
         * full maps */
        if (g_op % 5000 == 4999) {
            g_what = "restart";
            for (int i = 0; i < N_FILTERS; ++i) {
                g_truth = (pose2_t){0.0, 0.0, 0.0};
                if (slam_filter_init(&g_f[i], &g_cfg[i], g_truth) != COSLAM_OK) {
                    fail("slam_filter_init failed", k_names[i], i, 0);
                }
            }
        }
    }
    printf("property test%s: %ld operations, seed %" PRIu64 ": %ld predict, %ld update, %ld export, %ld merge, %ld "
           "cov2/cov3 - every property held\n",
           g_absurd ? " (absurd values too)" : "", n_ops, g_seed, counts[0], counts[1], counts[2], counts[3], counts[4]);
    printf("  merges fused %ld, refused %ld; most landmarks held: EKF-SLAM %u, Fast-SLAM 1.0 %u, Fast-SLAM 2.0 %u "
           "(per particle)\n",
           g_merges_ok, g_merges_refused, g_max_lm[0], g_max_lm[1], g_max_lm[2]);
    return 0;
}
