#include "coslam/ekfslam.h"

#include <math.h>
#include <string.h>

#define D_ EKFSLAM_DIM
#define P_(e, r, c) ((e)->p[(long)(r) * D_ + (c)])

ekfslam_config_t ekfslam_config_default(void)
{
    ekfslam_config_t c;
    c.slam = slam_params_default();
    c.robot_id = 0;
    c.assoc = EKFSLAM_ASSOC_JCBB;
    c.jcbb_max_nodes = 20000U;
    c.jcbb_ambiguity_d2 = 9.21;
    c.jcbb_single_closure_d2 = 4.61;
    c.jcbb_min_closure_pairs = 1U;
    c.jcbb_closure_gap = 25U;
    c.jcbb_closure_max_spread = 0.7;
    c.fej = 1U;
    c.iekf_max_iters = 0U;
    c.nis_inflate = 3.0;
#if COSLAM_EKF_MAX_ACTIVE >= 128
    c.active_radius_m = 3.0;
#else
    c.active_radius_m = 0.0;
#endif
    c.active_min_landmarks = 128U;
    c.active_spread_madds = 8000000U;
    c.merge_batch = 128U;
    c.mh_frames = 50U;
    c.mh_min_sightings = 8U;
    return c;
}

uint32_t ekfslam_new_id(ekfslam_t *ekf)
{
    const uint32_t id = ekf->next_id++;
    if (ekf->next_id == 0U) {
        ekf->next_id = 1U;
    }
    return id;
}

static int dim(const ekfslam_t *ekf)
{
    return 3 + 2 * (int)ekf->n_lm;
}

/* States in use: the pose and landmarks, plus the transform error tau at
 * the reserved tail of the stride while a merge runs. */
#define TAU_ EKFSLAM_STATE_MAX

static int n_active(const ekfslam_t *ekf)
{
    return dim(ekf) + (ekf->merging ? 3 : 0);
}

static int active_idx(const ekfslam_t *ekf, int k)
{
    const int d = dim(ekf);
    return k < d ? k : TAU_ + (k - d);
}

/* ---- Compressed EKF (Guivant and Nebot 2001) -----------------------------
 *
 * A local phase starts (cekf_select) with the whole state current: A0 =
 * the pose and every landmark that can come within reach of the sensor
 * while the robot stays within active_radius_m of where it is, B = the
 * rest; phi = I, psi = 0, theta = 0. Write P_AB(k) etc. for the values the
 * full EKF would hold after k steps, P_A0B = P_A0B(0) for the stored ones.
 * Invariants (A grows by the landmarks added in the phase, rows of phi):
 *   P_AB(k) = phi(k) P_A0B                                        (1)
 *   P_BB(k) = P_BB(0) - P_BA0 psi(k) P_A0B + w5_sum(k) I           (2)
 *   x_B(k)  = x_B(0) + P_BA0 theta(k)                              (3)
 * Prediction, x_A' = f(x_A), F = blockdiag(F_A, I): P_AB' = F_A P_AB, so
 * phi' = F_A phi (only the pose rows change); P_BB' = P_BB + w5 I on the
 * landmarks (lm_process_var_m2_per_m, O(1) through w5_sum, exact: no step
 * of the local phase reads P_BB). Update with H = [H_A 0], S = H_A P_AA
 * H_A^T + Q (only P_AA: S is exact), K_A = P_AA H_A^T S^-1, K_B = P_BA H_A^T
 * S^-1 = P_BA0 phi^T H_A^T S^-1 by (1):
 *   x_B' = x_B + K_B nu          => theta' = theta + (H_A phi)^T S^-1 nu
 *   P_AB' = (I - K_A H_A) P_AB   => phi'   = phi - K_A (H_A phi)
 *   P_BB' = P_BB - K_B S K_B^T   => psi'   = psi + (H_A phi)^T S^-1 (H_A phi)
 * (the Joseph form's AB and BB blocks reduce to these for the optimal
 * gain: -K_A PHt_B^T - PHt_A K_B^T + K_A S K_B^T = -K_A H P_AB). x_A and
 * P_AA are updated in place as by the full EKF. Each step is O(N_A^2)
 * (N_A = |A|, phi is N_A x N_A0). A landmark m = g(x_r, z) added in the
 * phase has P_mB = G_r P_rB = G_r phi_r P_A0B: its phi rows are G_r
 * times the pose's. The global update (ekfslam_sync) applies (3), (2), (1)
 * in that order (each reads the stored P_A0B before (1) overwrites it),
 * O(N_B^2 N_A0), after which every entry is what the full EKF holds up to
 * rounding; the periodic one leaves most of (1) and (2) for later steps ("The
 * deferred part of a global update" below). Between, readers of a passive
 * entry evaluate (1)-(3) for it (x_now, p_now). The full EKF's association reads the landmarks within
 * reach (max range + 3 sigma + 0.5 m) only; cekf_prepare forces a global
 * update before an update that could have a passive landmark within reach,
 * so the same landmarks are seen, with the same numbers. */

static pose2_t robot_pose(const ekfslam_t *ekf);

/* Side of the square tiles in which the symmetric updates of P and psi run
 * (update_one, batch_flush). */
#define EKF_TILE 32

#define ADIM_ EKFSLAM_ACTIVE_DIM
#define PHI_(e, k, i) ((e)->cekf.phi[(long)(k) * ADIM_ + (i)])
#define PSI_(e, i, k) ((e)->cekf.psi[(long)(i) * ADIM_ + (k)])

/* In a local phase (never where COSLAM_EKF_MAX_ACTIVE is 0: the compiler
 * then drops the compressed paths). */
static int in_local(const ekfslam_t *ekf)
{
    return COSLAM_EKF_MAX_ACTIVE > 0 && ekf->cekf.local;
}

/* Active position of state r in a local phase, -1 if passive. */
static int act_pos(const ekfslam_t *ekf, int r)
{
    if (r < 3) {
        return r;
    }
    const int32_t s = ekf->cekf.slot[(r - 3) / 2];
    return s < 0 ? -1 : (int)s + ((r - 3) & 1);
}

static int is_current(const ekfslam_t *ekf, int r)
{
    return !in_local(ekf) || act_pos(ekf, r) >= 0;
}

/* ---- The deferred part of a global update ---------------------------------
 *
 * The global update's (2), P_BB -= P_BA0 psi P_A0B, costs O(N_B^2 N_A0),
 * 300 ms at 800 landmarks (N_A0 ~ 340 states, N_B ~ 1200), and its (1),
 * P_AB = phi P_A0B, O(N_B N_A N_A0), 50-65 ms. The local phase that
 * follows reads or writes of P only the block of its own active part A',
 * P_A'A' (its updates), and, in the reach tests, each landmark's variance;
 * the rows P_A0'B' it needs only at its own end ((1) and (3) read them),
 * and its const readers. So the periodic global update (cekf_prepare,
 * active_spread_madds > 0) does at once (3), P_BB's w5_sum I and (1) for
 * the pose rows only (sync_spread, O(N_B N_A0)), and leaves a generation
 * (ekfslam_pend_t) of pending entries: with u_b = P_A0,b for b in B and
 * u_a = phi_a - e_a for a in A (e_a: the unit row of a's position in A0,
 * none for a landmark added in the phase, whose B columns are zeroed),
 *   entry (b, c), both B:  P(b, c) - u_b^T psi u_c               (2)
 *   entry (a, b), a in A:  P(a, b) + u_a^T u_b = phi_a P_A0,b      (1)
 * (P(a, b) = P_ab(0) = (e_a)^T u_b for a in A0). Both only add to the
 * stored value, so generations overlap and the order of completion does
 * not matter. A generation is kept per landmark (flag B or A, the u rows
 * of its x and y states, the phase's psi); an entry is pending while its
 * two landmarks are flagged, not both A and, in a local phase, not both
 * active.
 *
 * cekf_select completes the pending entries between landmarks of the new
 * active part A' (O(|A'|^2 N_A0), not O(|A'| N_B N_A0)): from then on the
 * phase may read and write P_A'A'. Its other entries stay pending, which
 * is exact because no local step reads or rewrites P_A'B' or P_B'B' (the
 * updates change them through phi, psi and theta only; predict's w5 on
 * the diagonal adds, so it commutes), and x_now's (3) adds their share
 * through per-generation sums (cekf_drift). Each predict and update
 * completes whole landmark rows for about active_spread_madds
 * multiply-adds (cekf_spread), the active landmarks' first: their rows
 * (P_A0'B') must be final when the phase ends. The next periodic global
 * update completes what is left of them (pend_done_active), takes a free
 * generation (EKFSLAM_PEND_GENS; if none, the oldest is completed first,
 * counted in cekf_spread_forced) and reads only final entries. Whatever
 * reads or rewrites pending entries otherwise completes them all first
 * (cekf_finish): ekfslam_sync (exports, merges, a full active part), a
 * frame that runs the full EKF (cekf_prepare). A removal (outside a
 * local phase, or ekfslam_remove_landmark, which ends it) moves the last
 * landmark's flags and u rows with it ("Removal in a local phase"). Const
 * readers add the corrections themselves (p_final, col_final). The reach
 * tests read the stored variance: it is the value (A landmarks' own
 * blocks are never pending) or larger (psi is positive semi-definite), so
 * they stay safe bounds;
 * cekf_select's only picks A', and any A' gives the same numbers; a
 * passive landmark with pending entries against A0' has no drift_gain
 * (-1) until they are complete and is always tested exactly. */

#define GPSI_(g, i, k) ((g)->psi[(long)(i) * ADIM_ + (k)])

/* Generation g's landmarks j and k (both flagged) have pending entries. */
static int pend_pair(const ekfslam_t *ekf, const ekfslam_pend_t *g, int j, int k)
{
    if (g->flag[j] == EKFSLAM_PEND_A && g->flag[k] == EKFSLAM_PEND_A) {
        return 0;
    }
    return !(in_local(ekf) && ekf->cekf.slot[j] >= 0 && ekf->cekf.slot[k] >= 0);
}

static double dot_n(const double *a, const double *b, int n)
{
    /* four partial sums: one running sum waits for each addition to finish
     * (a dependency chain the FPU cannot overlap); the compressed EKF's
     * deferred completion is mostly these products */
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    int i = 0;
    for (; i + 4 <= n; i += 4) {
        s0 += a[i] * b[i];
        s1 += a[i + 1] * b[i + 1];
        s2 += a[i + 2] * b[i + 2];
        s3 += a[i + 3] * b[i + 3];
    }
    for (; i < n; ++i) {
        s0 += a[i] * b[i];
    }
    return (s0 + s1) + (s2 + s3);
}

/* Generation g's correction of entry (r, c) (landmark states), 0 if none.
 * O(N_A0^2). */
static double pend_corr(const ekfslam_t *ekf, const ekfslam_pend_t *g, int r, int c)
{
    const int j = (r - 3) / 2;
    const int k = (c - 3) / 2;
    if (!g->flag[j] || !g->flag[k] || !pend_pair(ekf, g, j, k)) {
        return 0.0;
    }
    const double *ur = g->u[r - 3];
    const double *uc = g->u[c - 3];
    if (g->flag[j] == EKFSLAM_PEND_B && g->flag[k] == EKFSLAM_PEND_B) {
        double acc = 0.0;
        for (int i = 0; i < g->n0; ++i) {
            acc += ur[i] * dot_n(&g->psi[(long)i * ADIM_], uc, g->n0);
        }
        return -acc;
    }
    return dot_n(ur, uc, g->n0);
}

static double merge_corr(const ekfslam_t *ekf, int r, int c);
static void merge_flush(ekfslam_t *ekf);

/* P(r, c) with the pending corrections. */
static double p_final(const ekfslam_t *ekf, int r, int c)
{
    double v = P_(ekf, r, c);
    if (ekf->merge_bn > 0) {
        v -= merge_corr(ekf, r, c);
    }
    if (COSLAM_EKF_MAX_ACTIVE == 0 || r < 3 || c < 3 || r >= dim(ekf) || c >= dim(ekf)) {
        return v;
    }
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        if (ekf->cekf.gen[gi].n > 0) {
            v += pend_corr(ekf, &ekf->cekf.gen[gi], r, c);
        }
    }
    return v;
}

/* pend_w[q] = psi u_(2j+q) */
static void pend_weights(ekfslam_t *ekf, const ekfslam_pend_t *g, int j)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    for (int q = 0; q < 2; ++q) {
        const double *u = g->u[2 * j + q];
        for (int i = 0; i < g->n0; ++i) {
            ck->pend_w[q][i] = dot_n(&g->psi[(long)i * ADIM_], u, g->n0);
        }
    }
}

/* Add generation g's correction to the 2x2 block of landmarks j and k
 * (and its mirror); pend_w holds psi u_j if both are B. O(N_A0). */
static void pend_block(ekfslam_t *ekf, const ekfslam_pend_t *g, int j, int k)
{
    const int both_b = g->flag[j] == EKFSLAM_PEND_B && g->flag[k] == EKFSLAM_PEND_B;
    const double *w0 = both_b ? ekf->cekf.pend_w[0] : g->u[2 * j];
    const double *w1 = both_b ? ekf->cekf.pend_w[1] : g->u[2 * j + 1];
    const double sign = both_b ? -1.0 : 1.0;
    const double *u0 = g->u[2 * k];
    const double *u1 = g->u[2 * k + 1];
    double c00 = 0.0, c01 = 0.0, c10 = 0.0, c11 = 0.0;
    for (int i = 0; i < g->n0; ++i) {
        c00 += w0[i] * u0[i];
        c01 += w0[i] * u1[i];
        c10 += w1[i] * u0[i];
        c11 += w1[i] * u1[i];
    }
    const int a = 3 + 2 * j;
    const int b = 3 + 2 * k; /* k = j: the 2x2 block, symmetric as written */
    const double v00 = P_(ekf, a, b) + sign * c00;
    const double v01 = P_(ekf, a, b + 1) + sign * c01;
    const double v10 = P_(ekf, a + 1, b) + sign * c10;
    const double v11 = P_(ekf, a + 1, b + 1) + sign * c11;
    P_(ekf, a, b) = v00;
    P_(ekf, b, a) = v00;
    P_(ekf, a, b + 1) = v01;
    P_(ekf, b + 1, a) = v01;
    P_(ekf, a + 1, b) = v10;
    P_(ekf, b, a + 1) = v10;
    P_(ekf, a + 1, b + 1) = v11;
    P_(ekf, b + 1, a + 1) = v11;
}

/* Multiply-adds of completing landmark j's rows in generation g. */
static double pend_cost(const ekfslam_pend_t *g, int j)
{
    const double n0 = (double)g->n0;
    if (g->flag[j] == EKFSLAM_PEND_A) {
        return 4.0 * n0 * (double)g->n_b;
    }
    return 2.0 * n0 * n0 + 4.0 * n0 * (double)g->n;
}

/* Unflag the landmark at list[t] (the last one moves to t); a generation
 * without B landmarks has nothing pending and is emptied. */
static void pend_unflag(ekfslam_pend_t *g, int t)
{
    const int j = g->list[t];
    if (g->flag[j] == EKFSLAM_PEND_B) {
        g->n_b--;
    }
    g->flag[j] = 0U;
    g->list[t] = g->list[--g->n];
    if (g->n_b == 0) {
        for (int t2 = 0; t2 < g->n; ++t2) {
            g->flag[g->list[t2]] = 0U;
        }
        g->n = 0;
    }
}

/* Complete the rows (and columns) of the landmark at list[t] of generation
 * g against every landmark it has pending entries with (itself included),
 * and unflag it. O(N_A0^2 + N_pend N_A0). */
static void pend_row(ekfslam_t *ekf, ekfslam_pend_t *g, int t)
{
    const int j = g->list[t];
    if (g->flag[j] == EKFSLAM_PEND_B) {
        pend_weights(ekf, g, j);
    }
    for (int t2 = 0; t2 < g->n; ++t2) {
        const int k = g->list[t2];
        if (pend_pair(ekf, g, j, k)) {
            pend_block(ekf, g, j, k);
        }
    }
    pend_unflag(g, t);
}

/* Complete every pending entry (before anything reads or rewrites them). */
static void cekf_finish(ekfslam_t *ekf)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    if (COSLAM_EKF_MAX_ACTIVE == 0) {
        return;
    }
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        ekfslam_pend_t *g = &ck->gen[gi];
        g->drift_on = 0U;
        if (g->n == 0) {
            continue;
        }
        ekf->ctr.cekf_spread_forced++;
        while (g->n > 0) {
            pend_row(ekf, g, g->n - 1);
        }
    }
}

/* Complete the rows of every flagged active landmark (the phase ends: its
 * rows P_AB must be final). */
static void pend_done_active(ekfslam_t *ekf)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    int done = 0;
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        ekfslam_pend_t *g = &ck->gen[gi];
        /* downwards: what moves into t was looked at already */
        for (int t = g->n - 1; t >= 0; --t) {
            if (t < g->n && ck->slot[g->list[t]] >= 0) {
                pend_row(ekf, g, t);
                done = 1;
            }
        }
        g->drift_on = 0U;
    }
    if (done) {
        ekf->ctr.cekf_spread_forced++;
    }
}

/* The oldest generation with pending entries, -1 if none. */
static int pend_oldest(const ekfslam_cekf_t *ck)
{
    int best = -1;
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        if (ck->gen[gi].n > 0 && (best < 0 || ck->gen[gi].seq < ck->gen[best].seq)) {
            best = gi;
        }
    }
    return best;
}

/* |P_bA0| from the stored (final) entries. */
static double drift_gain_of(const ekfslam_t *ekf, int j)
{
    const ekfslam_cekf_t *ck = &ekf->cekf;
    const double *rx = &ekf->p[(long)(3 + 2 * j) * D_];
    const double *ry = rx + D_;
    double acc = 0.0;
    for (int i = 0; i < ck->na0; ++i) {
        acc += rx[ck->idx[i]] * rx[ck->idx[i]] + ry[ck->idx[i]] * ry[ck->idx[i]];
    }
    return sqrt(acc);
}

/* x_now's sums over the flagged states of A0' (see ekfslam_pend_t), after
 * theta or the flags changed; once no active landmark is flagged, the
 * missing drift gains. O(N_A0' N_A0 + N_A0^2) per generation with flagged
 * active landmarks. */
static void cekf_drift(ekfslam_t *ekf)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    if (!in_local(ekf)) {
        return;
    }
    int any = 0;
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        ekfslam_pend_t *g = &ck->gen[gi];
        g->drift_on = 0U;
        if (g->n == 0) {
            continue;
        }
        const int n0 = g->n0;
        for (int i = 0; i < n0; ++i) {
            g->drift_a[i] = 0.0;
            g->drift_b[i] = 0.0;
        }
        for (int i = 3; i < ck->na0; ++i) {
            const int r = ck->idx[i];
            const uint8_t f = g->flag[(r - 3) / 2];
            if (!f) {
                continue;
            }
            g->drift_on = 1U;
            double *dst = f == EKFSLAM_PEND_A ? g->drift_a : g->drift_b;
            const double *u = g->u[r - 3];
            const double th = ck->theta[i];
            for (int k = 0; k < n0; ++k) {
                dst[k] += th * u[k];
            }
        }
        if (g->drift_on) {
            any = 1;
            for (int i = 0; i < n0; ++i) {
                g->drift_bpsi[i] = dot_n(&g->psi[(long)i * ADIM_], g->drift_b, n0);
            }
        }
    }
    if (!any && ck->gain_stale) {
        for (uint16_t j = 0; j < ekf->n_lm; ++j) {
            if (ck->slot[j] < 0 && ck->drift_gain[j] < 0.0) {
                ck->drift_gain[j] = drift_gain_of(ekf, j);
            }
        }
        ck->gain_stale = 0U;
    }
}

/* Multiply-adds of one update in a local phase, counted as the update one
 * pairing at a time did them: P_AA's entries (5 each), psi's (2), phi's
 * (2); 0 outside a local phase, where nothing is pending. It sets the
 * completion's pace (cekf_spread), which the one pass (batch_flush) left
 * as it was. */
static double local_update_madds(const ekfslam_t *ekf)
{
    if (!in_local(ekf)) {
        return 0.0;
    }
    const double d = (double)ekf->cekf.na;
    const double n0 = (double)ekf->cekf.na0;
    return 2.5 * d * (d + 1.0) + n0 * (n0 + 1.0) + 2.0 * d * n0;
}

/* Complete deferred rows for about `budget` multiply-adds (at least one
 * row): the flagged active landmarks' first in a local phase, then the
 * oldest generation's. Returns the multiply-adds spent. */
static double spread_rows(ekfslam_t *ekf, double budget)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    double spent = 0.0;
    int act = in_local(ekf);
    while (spent < budget) {
        int gi = -1;
        int t = -1;
        if (act) {
            for (int g2 = 0; g2 < EKFSLAM_PEND_GENS && gi < 0; ++g2) {
                const ekfslam_pend_t *g = &ck->gen[g2];
                for (int t2 = 0; t2 < g->n; ++t2) {
                    if (ck->slot[g->list[t2]] >= 0) {
                        gi = g2;
                        t = t2;
                        break;
                    }
                }
            }
            act = gi >= 0;
        }
        if (gi < 0) {
            gi = pend_oldest(ck);
            if (gi < 0) {
                break;
            }
            t = ck->gen[gi].n - 1;
        }
        ekfslam_pend_t *g = &ck->gen[gi];
        spent += pend_cost(g, g->list[t]);
        pend_row(ekf, g, t);
        ekf->ctr.cekf_spread_rows++;
    }
    return spent;
}

/* The share of one predict or update: active_spread_madds per generation
 * with pending entries (a backlog, the robot leaving regions quickly, is
 * worked off faster, before the next global update would have to complete
 * the oldest at once). */
static double spread_share(const ekfslam_t *ekf)
{
    int busy = 0;
    for (int g2 = 0; g2 < EKFSLAM_PEND_GENS; ++g2) {
        busy += ekf->cekf.gen[g2].n > 0;
    }
    return (double)ekf->cfg.active_spread_madds * (double)busy;
}

/* A predict or update's share: whole landmark rows for about
 * active_spread_madds multiply-adds per busy generation (spread_rows). An
 * update runs it after its pairings and does only what its share leaves
 * after their own multiply-adds (`own_madds`); what it leaves is owed and
 * paid by the next predict (`pay_owed`), so a frame with many pairings is
 * not also the one that completes deferred rows, and the pace of the
 * completion stays the same. Rows completed ahead in idle time
 * (ekfslam_idle) are a credit (spread_owed < 0) that the steps use up
 * before doing any themselves. Which rows are completed when does not
 * change the numbers (they only add to entries no local step reads). */
static void cekf_spread(ekfslam_t *ekf, double own_madds, int pay_owed)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    if (COSLAM_EKF_MAX_ACTIVE == 0 || pend_oldest(ck) < 0) {
        ck->spread_owed = 0.0;
        return;
    }
    /* owed < 0: completed ahead in idle time (ekfslam_idle) */
    const double share = spread_share(ekf);
    const double owed = ck->spread_owed + share;
    const double own_budget = share - own_madds;
    const double budget = pay_owed || owed < own_budget ? owed : own_budget;
    const double spent = budget > 0.0 ? spread_rows(ekf, budget) : 0.0;
    if (pend_oldest(ck) < 0) {
        ck->spread_owed = 0.0; /* all done: no debt, no credit */
    } else if (owed <= 0.0) {
        ck->spread_owed = owed; /* what is left of the credit */
    } else {
        ck->spread_owed = owed > spent ? owed - spent : 0.0;
    }
    cekf_drift(ekf);
}


/* x_r now, (3) for a passive state (with the pending entries' share). */
static double x_now(const ekfslam_t *ekf, int r)
{
    if (is_current(ekf, r)) {
        return ekf->x[r];
    }
    const ekfslam_cekf_t *ck = &ekf->cekf;
    /* four partial sums, as dot_n */
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    int i = 0;
    for (; i + 4 <= ck->na0; i += 4) {
        s0 += P_(ekf, ck->idx[i], r) * ck->theta[i];
        s1 += P_(ekf, ck->idx[i + 1], r) * ck->theta[i + 1];
        s2 += P_(ekf, ck->idx[i + 2], r) * ck->theta[i + 2];
        s3 += P_(ekf, ck->idx[i + 3], r) * ck->theta[i + 3];
    }
    for (; i < ck->na0; ++i) {
        s0 += P_(ekf, ck->idx[i], r) * ck->theta[i];
    }
    double acc = (s0 + s1) + (s2 + s3);
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        const ekfslam_pend_t *g = &ck->gen[gi];
        const uint8_t f = g->flag[(r - 3) / 2];
        if (!g->drift_on || !f) {
            continue;
        }
        const double *u = g->u[r - 3];
        if (f == EKFSLAM_PEND_B) {
            acc += dot_n(u, g->drift_a, g->n0) - dot_n(u, g->drift_bpsi, g->n0);
        } else {
            acc += dot_n(u, g->drift_b, g->n0);
        }
    }
    return ekf->x[r] + acc;
}

/* out[i] = P(idx[i], b) for i < na0 with the pending corrections (b a
 * passive state). O(N_A0' N_A0 + N_A0^2). */
static void col_final(const ekfslam_t *ekf, int b, double *out)
{
    const ekfslam_cekf_t *ck = &ekf->cekf;
    for (int i = 0; i < ck->na0; ++i) {
        out[i] = P_(ekf, ck->idx[i], b);
    }
    const int jb = (b - 3) / 2;
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        const ekfslam_pend_t *g = &ck->gen[gi];
        if (g->n == 0 || !g->flag[jb]) {
            continue;
        }
        const double *ub = g->u[b - 3];
        double wb[ADIM_];
        if (g->flag[jb] == EKFSLAM_PEND_B) {
            for (int i = 0; i < g->n0; ++i) {
                wb[i] = dot_n(&g->psi[(long)i * ADIM_], ub, g->n0);
            }
        }
        for (int i = 3; i < ck->na0; ++i) {
            const int r = ck->idx[i];
            const int j = (r - 3) / 2;
            if (!g->flag[j] || !pend_pair(ekf, g, j, jb)) {
                continue;
            }
            if (g->flag[j] == EKFSLAM_PEND_B && g->flag[jb] == EKFSLAM_PEND_B) {
                out[i] -= dot_n(g->u[r - 3], wb, g->n0);
            } else {
                out[i] += dot_n(g->u[r - 3], ub, g->n0);
            }
        }
    }
}

/* P(r, c) now, (1) or (2) where passive states are involved. */
static double p_now(const ekfslam_t *ekf, int r, int c)
{
    const ekfslam_cekf_t *ck = &ekf->cekf;
    if (!in_local(ekf)) {
        return p_final(ekf, r, c);
    }
    const int kr = act_pos(ekf, r);
    const int kc = act_pos(ekf, c);
    if (kr >= 0 && kc >= 0) {
        return P_(ekf, r, c);
    }
    double cb[ADIM_];
    if (kr >= 0 || kc >= 0) {
        const int k = kr >= 0 ? kr : kc;
        col_final(ekf, kr >= 0 ? c : r, cb);
        double acc = 0.0;
        for (int i = 0; i < ck->na0; ++i) {
            acc += PHI_(ekf, k, i) * cb[i];
        }
        return acc;
    }
    double cr[ADIM_];
    col_final(ekf, r, cr);
    col_final(ekf, c, cb);
    double acc = 0.0;
    for (int i = 0; i < ck->na0; ++i) {
        acc += cr[i] * dot_n(&ck->psi[(long)i * ADIM_], cb, ck->na0);
    }
    return p_final(ekf, r, c) - acc + (r == c ? ck->w5_sum : 0.0);
}

/* u = P_A0,blk (stored values), zero beyond the block's nb columns */
static void gather_block(ekfslam_t *ekf, const int *blk, int nb)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    for (int i = 0; i < ck->na0; ++i) {
        const double *row = &ekf->p[(long)ck->idx[i] * D_];
        for (int q = 0; q < EKFSLAM_SYNC_BLOCK; ++q) {
            ck->u[i][q] = q < nb ? row[blk[q]] : 0.0;
        }
    }
}

/* The passive states from r on, at most EKFSLAM_SYNC_BLOCK of them, into
 * blk, and their columns of A0's rows into u (gather_block); their count,
 * and *next = where the next block starts. */
static int passive_block(ekfslam_t *ekf, int r, int d, int *blk, int *next)
{
    int n = 0;
    for (; r < d && n < EKFSLAM_SYNC_BLOCK; ++r) {
        if (act_pos(ekf, r) < 0) {
            blk[n++] = r;
        }
    }
    *next = r;
    gather_block(ekf, blk, n);
    return n;
}

/* w[q][k] = (m u)[k][q] for the first n rows of m (phi or psi, na0
 * columns) and the gathered block u */
static void block_products(ekfslam_t *ekf, const double *m, int n)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    for (int k = 0; k < n; ++k) {
        const double *mk = &m[(long)k * ADIM_];
        double acc[EKFSLAM_SYNC_BLOCK] = {0.0};
        for (int i = 0; i < ck->na0; ++i) {
            for (int q = 0; q < EKFSLAM_SYNC_BLOCK; ++q) {
                acc[q] += mk[i] * ck->u[i][q];
            }
        }
        for (int q = 0; q < EKFSLAM_SYNC_BLOCK; ++q) {
            ck->w[q][k] = acc[q];
        }
    }
}

/* (3): x_B += P_BA0 theta. O(N_B N_A0). */
static void sync_x(ekfslam_t *ekf)
{
    const int d = dim(ekf);
    for (int r = 3; r < d; ++r) {
        if (act_pos(ekf, r) < 0) {
            ekf->x[r] = x_now(ekf, r);
        }
    }
}

/* (1): P_AB = phi P_A0B, a block of columns at a time (A0's part of them
 * read first); ends the local phase. O(N_B N_A N_A0). */
static void sync_ab_end(ekfslam_t *ekf)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    const int d = dim(ekf);
    const int na = ck->na;
    const int32_t *idx = ck->idx;
    int blk[EKFSLAM_SYNC_BLOCK];
    for (int b = 3, next; b < d; b = next) {
        const int nb = passive_block(ekf, b, d, blk, &next);
        block_products(ekf, ck->phi, na); /* w = (phi P_A0,blk)^T */
        for (int k = 0; k < na; ++k) {
            for (int q = 0; q < nb; ++q) {
                P_(ekf, idx[k], blk[q]) = ck->w[q][k];
                P_(ekf, blk[q], idx[k]) = ck->w[q][k];
            }
        }
    }
    ck->local = 0U;
    ekf->ctr.cekf_global_updates++;
}

/* The periodic global update, spread ("The deferred part of a global
 * update" above): the flagged active rows completed, (3), w5_sum on P_BB's
 * diagonal, (1) for the pose rows, the rest a new generation of pending
 * entries (the oldest completed first if none is free). O(N_B N_A0) plus
 * what was left of the active rows. */
static void sync_spread(ekfslam_t *ekf)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    pend_done_active(ekf);
    int gi = -1;
    for (int g2 = 0; g2 < EKFSLAM_PEND_GENS && gi < 0; ++g2) {
        gi = ck->gen[g2].n == 0 ? g2 : -1;
    }
    if (gi < 0) {
        gi = pend_oldest(ck);
        ekfslam_pend_t *old = &ck->gen[gi];
        ekf->ctr.cekf_spread_forced++;
        ekf->ctr.cekf_spread_gens_full++;
        while (old->n > 0) {
            pend_row(ekf, old, old->n - 1);
        }
    }
    sync_x(ekf);
    ekfslam_pend_t *g = &ck->gen[gi];
    const int n0 = ck->na0;
    const int na = ck->na;
    g->n0 = n0;
    g->n = 0;
    g->n_b = 0;
    g->seq = ++ck->pend_seq;
    g->drift_on = 0U;
    for (int i = 0; i < n0; ++i) {
        memcpy(&g->psi[(long)i * ADIM_], &ck->psi[(long)i * ADIM_], (size_t)n0 * sizeof(double));
    }
    for (uint16_t j = 0; j < ekf->n_lm; ++j) {
        const int a = 3 + 2 * j;
        const int s = ck->slot[j];
        for (int q = 0; q < 2; ++q) {
            double *u = g->u[2 * j + q];
            if (s < 0) {
                /* u = P_A0,a+q as row a+q's A0 columns: P is stored symmetric */
                const double *row = &ekf->p[(long)(a + q) * D_];
                for (int i = 0; i < n0; ++i) {
                    u[i] = row[ck->idx[i]];
                }
            } else {
                memcpy(u, &ck->phi[(long)(s + q) * ADIM_], (size_t)n0 * sizeof(double));
                if (s + q < n0) {
                    u[s + q] -= 1.0;
                }
            }
        }
        if (s < 0) {
            P_(ekf, a, a) += ck->w5_sum;
            P_(ekf, a + 1, a + 1) += ck->w5_sum;
            g->n_b++;
        }
        g->flag[j] = s < 0 ? EKFSLAM_PEND_B : EKFSLAM_PEND_A;
        g->list[g->n++] = j;
    }
    /* (1) for the pose rows; the B columns of landmarks added in the phase
     * zeroed (their correction is all of (1)) */
    for (uint16_t j = 0; j < ekf->n_lm; ++j) {
        if (ck->slot[j] >= 0) {
            continue;
        }
        for (int q = 0; q < 2; ++q) {
            const int b = 3 + 2 * j + q;
            const double *ub = g->u[b - 3];
            for (int r = 0; r < 3; ++r) {
                const double v = dot_n(&ck->phi[(long)r * ADIM_], ub, n0);
                P_(ekf, r, b) = v;
                P_(ekf, b, r) = v;
            }
            for (int k = n0; k < na; ++k) {
                P_(ekf, ck->idx[k], b) = 0.0;
                P_(ekf, b, ck->idx[k]) = 0.0;
            }
        }
    }
    if (g->n_b == 0) {
        for (int t = 0; t < g->n; ++t) {
            g->flag[g->list[t]] = 0U;
        }
        g->n = 0;
    }
    ck->local = 0U;
    ekf->ctr.cekf_global_updates++;
}

static void sync_global(ekfslam_t *ekf);
static void dead_flush(ekfslam_t *ekf);

/* ekfslam_sync but the dead landmarks stay in the state (an update's
 * start: its association reads the indices the caller saw before it). */
static void sync_whole(ekfslam_t *ekf)
{
    merge_flush(ekf); /* a merge's updates still pending (none outside a merge) */
    cekf_finish(ekf); /* an earlier global update's rest: this phase's P_BB(0) */
    if (in_local(ekf)) {
        sync_global(ekf);
    }
}

void ekfslam_sync(ekfslam_t *ekf)
{
    sync_whole(ekf);
    dead_flush(ekf);
}

/* The whole global update: (3), (2), (1); ends the local phase. */
static void sync_global(ekfslam_t *ekf)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    const int d = dim(ekf);
    const int n0 = ck->na0;
    const int32_t *idx = ck->idx;
    int blk[EKFSLAM_SYNC_BLOCK];
    sync_x(ekf);
    /* (2): P_BB -= P_BA0 psi P_A0B, + w5_sum on the diagonal. Each row's
     * upper part as axpys with the (contiguous) rows of A0, a block of rows
     * at a time, mirrored below; the axpys also write garbage into the
     * rows' active columns, which (1) overwrites next. Rows of A0 are only
     * read. */
    for (int r = 3, next; r < d; r = next) {
        const int nb = passive_block(ekf, r, d, blk, &next);
        block_products(ekf, ck->psi, n0); /* w = (psi P_A0,blk)^T */
        for (int i = 0; i < n0; ++i) {
            const double *ua = &ekf->p[(long)idx[i] * D_];
            for (int q = 0; q < nb; ++q) {
                const double wi = ck->w[q][i];
                double *row = &ekf->p[(long)blk[q] * D_];
                for (int c = blk[q]; c < d; ++c) {
                    row[c] -= wi * ua[c];
                }
            }
        }
        for (int q = 0; q < nb; ++q) {
            P_(ekf, blk[q], blk[q]) += ck->w5_sum;
        }
        for (int c = blk[0] + 1; c < d; ++c) {
            if (act_pos(ekf, c) >= 0) {
                continue;
            }
            for (int q = 0; q < nb && blk[q] < c; ++q) {
                P_(ekf, c, blk[q]) = P_(ekf, blk[q], c);
            }
        }
    }
    sync_ab_end(ekf);
}

/* End a local phase: spread (sync_spread) where active_spread_madds
 * allows, else the whole global update. Outside a local phase, with
 * spreading on, nothing: pending entries stay pending. The dead landmarks
 * stay until the caller's dead_flush. */
static void cekf_end_phase(ekfslam_t *ekf)
{
    if (ekf->cfg.active_spread_madds == 0U) {
        sync_whole(ekf);
    } else if (in_local(ekf)) {
        sync_spread(ekf);
    }
}

/* No generation is free for the next global update's pending rows. */
static int gens_all_busy(const ekfslam_cekf_t *ck)
{
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        if (ck->gen[gi].n == 0) {
            return 0;
        }
    }
    return 1;
}

int ekfslam_sync_run(ekfslam_t *ekf, double budget, double *spent)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    double s = 0.0;
    int done = 1;
    if (COSLAM_EKF_MAX_ACTIVE > 0 && ekf->cfg.active_spread_madds > 0U) {
        /* every generation busy (a backlog): sync_spread would complete
         * the oldest at once, so its rows go first, a budget a call */
        while (in_local(ekf) && gens_all_busy(ck) && !(budget > 0.0 && s >= budget)) {
            s += spread_rows(ekf, budget > 0.0 ? budget - s : HUGE_VAL);
        }
        if (in_local(ekf) && !gens_all_busy(ck)) {
            /* the phase ends as the filter ends it itself: P_BB's share
             * deferred to a generation of pending rows, O(N_B N_A0) now */
            sync_spread(ekf);
            dead_flush(ekf);
            s += 2.0 * (double)ekf->n_lm * (double)ck->na0;
        }
        if (!in_local(ekf) && pend_oldest(ck) >= 0) {
            s += spread_rows(ekf, budget > 0.0 ? (budget > s ? budget - s : 1.0) : HUGE_VAL);
        }
        ck->spread_owed = 0.0; /* what the steps owe is paid here */
        done = !in_local(ekf) && pend_oldest(ck) < 0;
    }
    if (done) {
        ekfslam_sync(ekf); /* nothing left but a merge's columns, if any */
    }
    if (spent != 0) {
        *spent += s;
    }
    return done;
}

/* Reach of the association's near test (ekfslam_update) for landmark state
 * a with landmark variance trace var_m (plus the pose's, var_r). */
static double near_reach(double max_range_m, double var_m, double var_r)
{
    return max_range_m + 3.0 * sqrt(var_m + var_r) + 0.5 + 1e-6; /* + rounding */
}

/* Start a local phase around the robot if the compression is on and the
 * active part fits; else the full EKF runs this frame. O(L N_A). */
static void cekf_select(ekfslam_t *ekf, double max_range_m)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    const double radius = ekf->cfg.active_radius_m;
    if (COSLAM_EKF_MAX_ACTIVE == 0 || !(radius > 0.0) || ekf->merging || ekf->n_lm < ekf->cfg.active_min_landmarks) {
        return;
    }
    const pose2_t pose = robot_pose(ekf);
    const double var_r = P_(ekf, 0, 0) + P_(ekf, 1, 1);
    int n = 0;
    for (uint16_t j = 0; j < ekf->n_lm; ++j) {
        const int a = 3 + 2 * j;
        const double reach = radius + near_reach(max_range_m, P_(ekf, a, a) + P_(ekf, a + 1, a + 1), var_r);
        /* a dead landmark (removed in the phase this update's start ended)
         * stays passive until this phase ends and takes it out */
        const int in = !ekf->lm_dead[j] && hypot(ekf->x[a] - pose.x, ekf->x[a + 1] - pose.y) <= reach;
        ck->slot[j] = in ? 0 : -1;
        n += in;
    }
    if (n > COSLAM_EKF_MAX_ACTIVE) {
        ekf->ctr.cekf_active_overflows++;
        return;
    }
    int k = 3;
    for (int q = 0; q < 3; ++q) {
        ck->idx[q] = q;
    }
    for (uint16_t j = 0; j < ekf->n_lm; ++j) {
        if (ck->slot[j] == 0) {
            ck->slot[j] = k;
            ck->idx[k] = 3 + 2 * j;
            ck->idx[k + 1] = 4 + 2 * j;
            k += 2;
        }
    }
    ck->na = k;
    ck->na0 = k;
    ck->local = 1U; /* act_pos and pend_pair below need the slots */
    /* the entries between the new active landmarks must be final: this
     * phase reads and writes P_A'A' (each pair once, itself included) */
    int gen_act[EKFSLAM_PEND_GENS];
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        ekfslam_pend_t *g = &ck->gen[gi];
        int m = 0;
        for (int t = 0; t < g->n; ++t) {
            if (ck->slot[g->list[t]] >= 0) {
                ck->pend_act[m++] = g->list[t];
            }
        }
        gen_act[gi] = m;
        for (int t = 0; t < m; ++t) {
            const int j = ck->pend_act[t];
            if (g->flag[j] == EKFSLAM_PEND_B) {
                pend_weights(ekf, g, j);
            }
            for (int t2 = t; t2 < m; ++t2) {
                const int kk = ck->pend_act[t2];
                if (!(g->flag[j] == EKFSLAM_PEND_A && g->flag[kk] == EKFSLAM_PEND_A)) {
                    pend_block(ekf, g, j, kk);
                }
            }
        }
        g->drift_on = 0U; /* theta = 0 */
    }
    /* |P_bA0| bounds how far theta moves passive landmark b, (3); unknown
     * (-1) while b has pending entries against A0 */
    ck->gain_stale = 0U;
    for (uint16_t j = 0; j < ekf->n_lm; ++j) {
        if (ck->slot[j] >= 0) {
            continue;
        }
        int pending = 0;
        for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
            pending |= gen_act[gi] > 0 && ck->gen[gi].flag[j];
        }
        ck->drift_gain[j] = pending ? -1.0 : drift_gain_of(ekf, j);
        ck->gain_stale |= (uint8_t)pending;
    }
    for (int r = 0; r < k; ++r) {
        for (int c = 0; c < k; ++c) {
            PHI_(ekf, r, c) = r == c ? 1.0 : 0.0;
            PSI_(ekf, r, c) = 0.0;
        }
        ck->theta[r] = 0.0;
    }
    ck->w5_sum = 0.0;
    ck->centre.x = pose.x;
    ck->centre.y = pose.y;
}

/* Before an update: end the local phase if the robot left its region or a
 * passive landmark may be within reach (bounds first: the stale position
 * moved by at most drift_gain |theta|, the stale variance plus w5_sum is an
 * upper bound; then the exact position, O(N_A), for the few that pass);
 * then start one if none runs. */
/* In a local phase: has the robot left its region (more than
 * active_radius_m from the centre), or can a passive landmark come within
 * the association's reach (max_range_m)? */
static int cekf_leaving(const ekfslam_t *ekf, double max_range_m)
{
    const ekfslam_cekf_t *ck = &ekf->cekf;
    const pose2_t pose = robot_pose(ekf);
    int leave = hypot(pose.x - ck->centre.x, pose.y - ck->centre.y) > ekf->cfg.active_radius_m;
    const double var_r = P_(ekf, 0, 0) + P_(ekf, 1, 1);
    double tn = 0.0;
    for (int i = 0; i < ck->na0; ++i) {
        tn += ck->theta[i] * ck->theta[i];
    }
    tn = sqrt(tn);
    for (uint16_t j = 0; j < ekf->n_lm && !leave; ++j) {
        if (ck->slot[j] >= 0 || ekf->lm_dead[j]) {
            continue;
        }
        const int a = 3 + 2 * j;
        const double reach =
            near_reach(max_range_m, P_(ekf, a, a) + P_(ekf, a + 1, a + 1) + 2.0 * ck->w5_sum, var_r);
        if (ck->drift_gain[j] >= 0.0 &&
            hypot(ekf->x[a] - pose.x, ekf->x[a + 1] - pose.y) - ck->drift_gain[j] * tn > reach) {
            continue;
        }
        leave = hypot(x_now(ekf, a) - pose.x, x_now(ekf, a + 1) - pose.y) <= reach;
    }
    return leave;
}

static void cekf_prepare(ekfslam_t *ekf, double max_range_m)
{
    if (in_local(ekf) && cekf_leaving(ekf, max_range_m)) {
        cekf_end_phase(ekf);
    }
    if (!in_local(ekf)) {
        cekf_select(ekf, max_range_m);
        if (!in_local(ekf)) {
            cekf_finish(ekf); /* this frame runs the full EKF */
        }
    }
}

static void idle_one(ekfslam_t *ekf, uint32_t shares);

void ekfslam_idle(ekfslam_t *ekf, uint32_t shares)
{
    COSLAM_ASSERT(ekf != 0);
    idle_one(ekf, shares);
    if (ekf->mh_left > 0U) {
        idle_one(ekf->alt, shares); /* the other hypothesis of a revisit */
    }
}

static void idle_one(ekfslam_t *ekf, uint32_t shares)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    if (COSLAM_EKF_MAX_ACTIVE == 0) {
        return;
    }
    /* a region left: the next one now, not in the next update (the update
     * finds the robot inside it and goes on) */
    if (in_local(ekf) && cekf_leaving(ekf, ekf->cfg.slam.sensor_max_range_m)) {
        cekf_end_phase(ekf);
        dead_flush(ekf);
        cekf_select(ekf, ekf->cfg.slam.sensor_max_range_m);
    }
    if (pend_oldest(ck) < 0) {
        return;
    }
    /* ahead by at most two steps' shares: if the idle time stops, the
     * steps take up the pace again at once */
    const double room = ck->spread_owed + 2.0 * spread_share(ekf);
    const double want = (double)shares * (double)ekf->cfg.active_spread_madds;
    const double budget = want < room ? want : room;
    if (budget > 0.0) {
        ck->spread_owed -= spread_rows(ekf, budget);
        if (pend_oldest(ck) < 0) {
            ck->spread_owed = 0.0;
        }
        cekf_drift(ekf);
    }
}

/* ---- One pass for a frame's pairings (a local phase) -----------------------
 *
 * Pairing k of a frame updates, with P and phi as the pairings before it
 * left them (the sequential EKF, relinearised at each pairing):
 *   P_AA -= K_k (P H_k^T)^T,  phi -= K_k (H_k phi),
 *   psi += (H_k phi)^T S_k^-1 (H_k phi),  theta += (H_k phi)^T S_k^-1 nu_k.
 * Each is a rank-2 change of a whole block, and applied one pairing at a
 * time they walk P_AA, phi and psi once per pairing (6-9 ms for 20
 * pairings over 430 active states, the slowest steps of the large world).
 * So the pairings' columns are kept (ekfslam_cekf_t bk, bp, bh, bs) and
 * applied together (batch_flush), up to EKFSLAM_BATCH at a time; what a
 * pairing reads before then - the 5 x 5 block of its pose and landmark
 * (sparse_hph), the 5 rows of P and of phi it multiplies - is the stored
 * value less the pending pairings' share. x and theta change at once. The
 * same updates in another order of the sums: the numbers agree up to
 * rounding. */

/* Pending pairings' share of P_AA entry (pa, pb), active positions. */
static double batch_p_corr(const ekfslam_t *ekf, int pa, int pb)
{
    const ekfslam_cekf_t *ck = &ekf->cekf;
    double acc = 0.0;
    for (int t = 0; t < 2 * ck->bn; ++t) {
        acc += ck->bk[t][pa] * ck->bp[t][pb];
    }
    return acc;
}

/* out0[l] = sum_{t < nt} w0[t] m[t][l] and out1[l] the same with w1, for
 * l < len (rows of m at stride `stride`): two rows of output, eight
 * columns at a time held in registers over all t, so each value of m is
 * read once for both and the sixteen sums are independent chains (the
 * additions' latency hidden; eight, one row, left the x86-64 build waiting
 * for them). Each output is summed over t in order. A single row passes
 * w1 = w0 and ignores out1. */
static inline void combine_rows(const double *restrict w0, const double *restrict w1, const double *restrict m,
                                long stride, int nt, int len, double *restrict out0, double *restrict out1)
{
    int l = 0;
    for (; l + 8 <= len; l += 8) {
        double a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0, a4 = 0.0, a5 = 0.0, a6 = 0.0, a7 = 0.0;
        double b0 = 0.0, b1 = 0.0, b2 = 0.0, b3 = 0.0, b4 = 0.0, b5 = 0.0, b6 = 0.0, b7 = 0.0;
        for (int t = 0; t < nt; ++t) {
            const double u = w0[t];
            const double v = w1[t];
            const double *mt = m + (long)t * stride + l;
            a0 += u * mt[0];
            a1 += u * mt[1];
            a2 += u * mt[2];
            a3 += u * mt[3];
            a4 += u * mt[4];
            a5 += u * mt[5];
            a6 += u * mt[6];
            a7 += u * mt[7];
            b0 += v * mt[0];
            b1 += v * mt[1];
            b2 += v * mt[2];
            b3 += v * mt[3];
            b4 += v * mt[4];
            b5 += v * mt[5];
            b6 += v * mt[6];
            b7 += v * mt[7];
        }
        out0[l] = a0;
        out0[l + 1] = a1;
        out0[l + 2] = a2;
        out0[l + 3] = a3;
        out0[l + 4] = a4;
        out0[l + 5] = a5;
        out0[l + 6] = a6;
        out0[l + 7] = a7;
        out1[l] = b0;
        out1[l + 1] = b1;
        out1[l + 2] = b2;
        out1[l + 3] = b3;
        out1[l + 4] = b4;
        out1[l + 5] = b5;
        out1[l + 6] = b6;
        out1[l + 7] = b7;
    }
    for (; l < len; ++l) {
        double a = 0.0;
        double b = 0.0;
        for (int t = 0; t < nt; ++t) {
            a += w0[t] * m[(long)t * stride + l];
            b += w1[t] * m[(long)t * stride + l];
        }
        out0[l] = a;
        out1[l] = b;
    }
}

/* combine_rows with rows at the constant stride ADIM_ (a frame's
 * pairings), or at any stride (a merge's columns): the constant keeps the
 * rows' offsets out of the loop (the large world's EKF-SLAM frames were 45 %
 * slower with one function for both). */
static void batch_combine(const double *w0, const double *w1, const double *m, int nt, int len, double *out0,
                          double *out1)
{
    combine_rows(w0, w1, m, ADIM_, nt, len, out0, out1);
}

static void stride_combine(const double *w0, const double *w1, const double *m, long stride, int nt, int len,
                           double *out0, double *out1)
{
    combine_rows(w0, w1, m, stride, nt, len, out0, out1);
}

/* Pending columns a symmetric block update combines at most: a frame's
 * pairings (2 EKFSLAM_BATCH) or a merge's updates (EKF_MERGE_BATCH). */
#define EKF_MERGE_BATCH 128
#define EKF_SYM_MAX_T (2 * EKFSLAM_BATCH > EKF_MERGE_BATCH ? 2 * EKFSLAM_BATCH : EKF_MERGE_BATCH)

/* Where row / column k of a symmetric block update lies in `mat`: ix[k],
 * or, where ix is null, k below `split` and tail + (k - split) from it. */
typedef struct {
    const int32_t *ix;
    int split;
    long tail;
} sym_map_t;

static long sym_at(const sym_map_t *m, int k)
{
    return m->ix != 0 ? m->ix[k] : k < m->split ? k : m->tail + (k - m->split);
}

/* A symmetric n x n block of `mat` (rows and columns at `map`; row stride
 * `stride`) plus sign sum_t w_t^T m_t over pending rows w, m (row t at
 * wr + t * vstride, mr + t * vstride): each entry of the upper triangle
 * once, written to both halves, in tiles (the mirrored writes walk a
 * column of the row-major matrix, so a tile keeps them within a few rows
 * at a time). nt <= EKF_SYM_MAX_T. */
static void batch_sym_update(double *mat, long stride, const sym_map_t *map, int n, const double *wr,
                             const double *mr, long vstride, int nt, double sign, int r_begin, int r_end)
{
    double w[2][EKF_SYM_MAX_T];
    double acc[2][EKF_TILE];
    long at_c[EKF_TILE]; /* the tile's columns in mat */
    /* the tiles of rows [r_begin, r_end) (r_begin a multiple of EKF_TILE):
     * each tile writes its rows from their diagonal on and the mirrors of
     * those entries, which no other tile reads, so the tiles may be done
     * in separate calls with the same result bit for bit */
    const int r_stop = r_end < n ? r_end : n;
    for (int r0 = r_begin; r0 < r_stop; r0 += EKF_TILE) {
        const int r1 = r0 + EKF_TILE < n ? r0 + EKF_TILE : n;
        for (int c0 = r0; c0 < n; c0 += EKF_TILE) {
            const int c1 = c0 + EKF_TILE < n ? c0 + EKF_TILE : n;
            for (int c = c0; c < c1; ++c) {
                at_c[c - c0] = sym_at(map, c);
            }
            /* two rows at a time over the columns from the first row's
             * diagonal on; the second row's entry left of its diagonal is
             * the first row's mirror and is not written */
            for (int r = r0; r < r1; r += 2) {
                const int two = r + 1 < r1;
                const int cb = r > c0 ? r : c0;
                for (int t = 0; t < nt; ++t) {
                    w[0][t] = wr[(long)t * vstride + r];
                    w[1][t] = wr[(long)t * vstride + (two ? r + 1 : r)];
                }
                if (vstride == ADIM_) {
                    batch_combine(w[0], w[1], &mr[cb], nt, c1 - cb, acc[0], acc[1]);
                } else {
                    stride_combine(w[0], w[1], &mr[cb], vstride, nt, c1 - cb, acc[0], acc[1]);
                }
                for (int h = 0; h <= two; ++h) {
                    const int rr = r + h;
                    const long pr = sym_at(map, rr);
                    double *row = &mat[pr * stride];
                    for (int c = cb > rr ? cb : rr; c < c1; ++c) {
                        const long pc = at_c[c - c0];
                        const double val = row[pc] + sign * acc[h][c - cb];
                        row[pc] = val;
                        mat[pc * stride + pr] = val;
                    }
                }
            }
        }
    }
}

/* Apply the pending pairings: P_AA -= sum_t bk_t bp_t^T, psi += sum_t
 * bh_t^T bs_t, phi -= sum_t bk_t bh_t. */
static void batch_flush(ekfslam_t *ekf)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    const int nt = 2 * ck->bn;
    if (COSLAM_EKF_MAX_ACTIVE == 0 || nt == 0) {
        return; /* the first: the compiler drops the rest without an active part */
    }
    const int na = ck->na;
    const int n0 = ck->na0;
    const sym_map_t active = {ck->idx, 0, 0};
    const sym_map_t plain = {0, n0, 0};
    batch_sym_update(ekf->p, D_, &active, na, ck->bk[0], ck->bp[0], ADIM_, nt, -1.0, 0, na);
    batch_sym_update(ck->psi, ADIM_, &plain, n0, ck->bh[0], ck->bs[0], ADIM_, nt, 1.0, 0, n0);
    double w[2][2 * EKFSLAM_BATCH];
    double acc[2][ADIM_];
    for (int r = 0; r < na; r += 2) {
        const int two = r + 1 < na;
        for (int t = 0; t < nt; ++t) {
            w[0][t] = ck->bk[t][r];
            w[1][t] = ck->bk[t][two ? r + 1 : r];
        }
        batch_combine(w[0], w[1], ck->bh[0], nt, n0, acc[0], acc[1]);
        for (int h = 0; h <= two; ++h) {
            double *restrict row = &ck->phi[(long)(r + h) * ADIM_];
            for (int i = 0; i < n0; ++i) {
                row[i] -= acc[h][i];
            }
        }
    }
    ck->bn = 0;
}

/* Pairing of landmark j (expectation e, innovation nu) in a local phase:
 * its columns, x and theta now; P_AA, phi and psi at the next batch_flush. */
static void batch_add(ekfslam_t *ekf, uint16_t j, const lm_expect_t *e, const double nu[2])
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    if (ck->bn == EKFSLAM_BATCH) {
        batch_flush(ekf);
    }
    const int na = ck->na;
    const int n0 = ck->na0;
    const int32_t *ix = ck->idx;
    const int s = ck->slot[j];
    const int a = 3 + 2 * j;
    const int pos[5] = {0, 1, 2, s, s + 1};
    double h[2][5];
    for (int q = 0; q < 2; ++q) {
        h[q][0] = e->h_pose[q][0];
        h[q][1] = e->h_pose[q][1];
        h[q][2] = e->h_pose[q][2];
        h[q][3] = e->h_lm[q][0];
        h[q][4] = e->h_lm[q][1];
    }
    const int t0 = 2 * ck->bn;
    /* the pending pairings seen through this one's H: g = H bp^T, gk = H bk^T */
    double g[2][2 * EKFSLAM_BATCH];
    double gk[2][2 * EKFSLAM_BATCH];
    for (int t = 0; t < t0; ++t) {
        for (int q = 0; q < 2; ++q) {
            double ap = 0.0;
            double ak = 0.0;
            for (int v = 0; v < 5; ++v) {
                ap += h[q][v] * ck->bp[t][pos[v]];
                ak += h[q][v] * ck->bk[t][pos[v]];
            }
            g[q][t] = ap;
            gk[q][t] = ak;
        }
    }
    double *restrict p0 = ck->bp[t0];
    double *restrict p1 = ck->bp[t0 + 1];
    double *restrict k0 = ck->bk[t0];
    double *restrict k1 = ck->bk[t0 + 1];
    /* P H^T from the five rows of P that H reads (P is symmetric: a row,
     * not five strided columns) */
    const double *rw[5] = {&ekf->p[0], &ekf->p[(long)D_], &ekf->p[2L * D_], &ekf->p[(long)a * D_],
                           &ekf->p[(long)(a + 1) * D_]};
    for (int r = 0; r < na; ++r) {
        const long c = ix[r];
        const double v0 = rw[0][c];
        const double v1 = rw[1][c];
        const double v2 = rw[2][c];
        const double v3 = rw[3][c];
        const double v4 = rw[4][c];
        p0[r] = v0 * h[0][0] + v1 * h[0][1] + v2 * h[0][2] + v3 * h[0][3] + v4 * h[0][4];
        p1[r] = v0 * h[1][0] + v1 * h[1][1] + v2 * h[1][2] + v3 * h[1][3] + v4 * h[1][4];
    }
    for (int t = 0; t < t0; ++t) {
        const double *restrict kt = ck->bk[t];
        const double g0 = g[0][t];
        const double g1 = g[1][t];
        for (int r = 0; r < na; ++r) {
            p0[r] -= kt[r] * g0;
            p1[r] -= kt[r] * g1;
        }
    }
    const cov2_t si = e->s_inv;
    for (int r = 0; r < na; ++r) {
        k0[r] = p0[r] * si.xx + p1[r] * si.xy;
        k1[r] = p0[r] * si.xy + p1[r] * si.yy;
    }
    for (int r = 0; r < na; ++r) {
        ekf->x[ix[r]] += k0[r] * nu[0] + k1[r] * nu[1];
    }
    ekf->x[2] = angle_wrap(ekf->x[2]);
    /* H phi over A0, phi less the pending pairings' K bh */
    double *restrict h0 = ck->bh[t0];
    double *restrict h1 = ck->bh[t0 + 1];
    for (int i = 0; i < n0; ++i) {
        double v0 = 0.0;
        double v1 = 0.0;
        for (int v = 0; v < 5; ++v) {
            const double ph = PHI_(ekf, pos[v], i);
            v0 += h[0][v] * ph;
            v1 += h[1][v] * ph;
        }
        h0[i] = v0;
        h1[i] = v1;
    }
    for (int t = 0; t < t0; ++t) {
        const double *restrict ht = ck->bh[t];
        const double c0 = gk[0][t];
        const double c1 = gk[1][t];
        for (int i = 0; i < n0; ++i) {
            h0[i] -= c0 * ht[i];
            h1[i] -= c1 * ht[i];
        }
    }
    double *restrict s0 = ck->bs[t0];
    double *restrict s1 = ck->bs[t0 + 1];
    const double sinu0 = si.xx * nu[0] + si.xy * nu[1];
    const double sinu1 = si.xy * nu[0] + si.yy * nu[1];
    for (int i = 0; i < n0; ++i) {
        s0[i] = si.xx * h0[i] + si.xy * h1[i];
        s1[i] = si.xy * h0[i] + si.yy * h1[i];
        ck->theta[i] += h0[i] * sinu0 + h1[i] * sinu1;
    }
    ck->bn++;
}

coslam_status_t ekfslam_init(ekfslam_t *ekf, const ekfslam_config_t *cfg, pose2_t pose0)
{
    COSLAM_ASSERT(ekf != 0 && cfg != 0);
    if (slam_params_validate(&cfg->slam) != COSLAM_OK || cfg->robot_id >= COSLAM_MAX_ROBOTS || cfg->fej > 1U ||
        (cfg->assoc != EKFSLAM_ASSOC_NN && cfg->assoc != EKFSLAM_ASSOC_JCBB) || cfg->jcbb_max_nodes < 1U ||
        !(cfg->jcbb_ambiguity_d2 >= 0.0 && cfg->jcbb_ambiguity_d2 < 1e6) ||
        !(cfg->jcbb_single_closure_d2 >= 0.0 && cfg->jcbb_single_closure_d2 <= cfg->jcbb_ambiguity_d2) ||
        cfg->jcbb_min_closure_pairs < 1U || cfg->mh_min_sightings < 1U ||
        !(cfg->jcbb_closure_max_spread > 0.0) || !(cfg->active_radius_m >= 0.0 && cfg->active_radius_m < 1e6) ||
        (cfg->active_radius_m > 0.0 && COSLAM_EKF_MAX_ACTIVE == 0) ||
        !(cfg->nis_inflate >= 0.0 && cfg->nis_inflate < 1e6) || !pose2_is_finite(pose0)) {
        return COSLAM_E_ARG;
    }
    ekf->cfg = *cfg;
    ekf->n_lm = 0;
    ekf->n_dead = 0U;
    ekf->merging = 0U;
    ekf->merge_bn = 0;
    ekf->merge_len = 0;
    ekf->merge_flush_r0 = 0;
    ekf->nis_avg = 0.0;
    ekf->cekf.local = 0U;
    ekf->cekf.bn = 0;
    ekf->cekf.gain_stale = 0U;
    ekf->cekf.pend_seq = 0U;
    ekf->cekf.spread_owed = 0.0;
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        ekf->cekf.gen[gi].n = 0;
        ekf->cekf.gen[gi].n_b = 0;
        ekf->cekf.gen[gi].drift_on = 0U;
        memset(ekf->cekf.gen[gi].flag, 0, sizeof ekf->cekf.gen[gi].flag);
    }
    ekf->next_id = 1U;
    memset(&ekf->ctr, 0, sizeof ekf->ctr);
    ekf->view = 0;
    ekf->alt = 0;
    ekf->mh_left = 0U;
    ekf->mh_forbid = 0U;
    ekf->mh_sum = 0.0;
    ekf->mh_sum_alt = 0.0;
    ekf->frame_score = 0.0;
    ekf->x[0] = pose0.x;
    ekf->x[1] = pose0.y;
    ekf->x[2] = angle_wrap(pose0.theta);
    ekf->pose_prior.x = ekf->x[0];
    ekf->pose_prior.y = ekf->x[1];
    ekf->pose_prior.theta = ekf->x[2];
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            P_(ekf, r, c) = 0.0;
        }
    }
    P_(ekf, 0, 0) = cfg->slam.noise.init_xy_var_m2;
    P_(ekf, 1, 1) = cfg->slam.noise.init_xy_var_m2;
    P_(ekf, 2, 2) = cfg->slam.noise.init_theta_var_rad2;
    return COSLAM_OK;
}

static pose2_t robot_pose(const ekfslam_t *ekf)
{
    const pose2_t p = {ekf->x[0], ekf->x[1], ekf->x[2]};
    return p;
}

void ekfslam_pose(const ekfslam_t *ekf, pose2_t *pose, cov3_t *cov)
{
    *pose = robot_pose(ekf);
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            /* the pose is never passive: only a merge's pending columns
             * (p_final) stand between it and the stored P */
            cov->m[r][c] = ekf->merge_bn > 0 ? p_final(ekf, r, c) : P_(ekf, r, c);
        }
    }
}

void ekfslam_landmark(const ekfslam_t *ekf, uint16_t j, point2_t *mean, cov2_t *cov)
{
    COSLAM_ASSERT(j < ekf->n_lm);
    const int a = 3 + 2 * j;
    *mean = ekfslam_landmark_mean(ekf, j);
    *cov = cov2_make(p_now(ekf, a, a), 0.5 * (p_now(ekf, a, a + 1) + p_now(ekf, a + 1, a)), p_now(ekf, a + 1, a + 1));
}

point2_t ekfslam_landmark_mean(const ekfslam_t *ekf, uint16_t j)
{
    COSLAM_ASSERT(j < ekf->n_lm);
    const point2_t m = {x_now(ekf, 3 + 2 * j), x_now(ekf, 4 + 2 * j)};
    return m;
}

double ekfslam_p(const ekfslam_t *ekf, int r, int c)
{
    return p_now(ekf, r, c);
}

static coslam_status_t predict_one(ekfslam_t *ekf, odo_increment_t u)
{
    if (ekf->merging) {
        return COSLAM_E_MERGE_BUSY; /* a merge in parts runs on the state as it was */
    }
    if (!motion_is_plausible(&ekf->cfg.slam, u, MOTION_MAX_INCREMENT_S)) {
        ekf->ctr.rejected_controls++;
        return COSLAM_E_NUMERIC;
    }
    cekf_spread(ekf, 0.0, 1);
    const slam_params_t *sp = &ekf->cfg.slam;
    const pose2_t pose = robot_pose(ekf);
    double g[3][3];
    double v[3][3];
    motion_jacobians(pose, u, g, v);
    const pose2_t np = motion_apply(pose, u);
    if (ekf->cfg.fej) {
        /* FEJ: the position rows of G use the displacement from the
         * previous predicted pose, not from the updated one */
        g[0][2] = -(np.y - ekf->pose_prior.y);
        g[1][2] = np.x - ekf->pose_prior.x;
    }
    ekf->pose_prior = np;
    ekf->x[0] = np.x;
    ekf->x[1] = np.y;
    ekf->x[2] = np.theta;
    /* the landmarks: all, or the active ones in a local phase */
    const int local = in_local(ekf);
    const int n = local ? ekf->cekf.na : dim(ekf);
    const int32_t *ix = ekf->cekf.idx;
    /* P_rr = G P_rr G^T + V R V^T */
    cov3_t prr;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            prr.m[r][c] = P_(ekf, r, c);
        }
    }
    prr = cov3_add(cov3_congruence(g, prr), cov3_congruence(v, motion_noise_cov(sp, u)));
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            P_(ekf, r, c) = prr.m[r][c];
        }
    }
    /* P_rm = G P_rm, P_mr = P_rm^T */
    for (int kk = 3; kk < n; ++kk) {
        const int c = local ? ix[kk] : kk;
        const double a0 = P_(ekf, 0, c);
        const double a1 = P_(ekf, 1, c);
        const double a2 = P_(ekf, 2, c);
        for (int r = 0; r < 3; ++r) {
            const double val = g[r][0] * a0 + g[r][1] * a1 + g[r][2] * a2;
            P_(ekf, r, c) = val;
            P_(ekf, c, r) = val;
        }
    }
    const double w5 = sp->noise.lm_process_var_m2_per_m;
    if (w5 > 0.0) {
        const double add = w5 * motion_travel_m(u, sp->base_radius_m);
        for (int kk = 3; kk < n; ++kk) {
            const int c = local ? ix[kk] : kk;
            P_(ekf, c, c) += add;
        }
        ekf->cekf.w5_sum += add; /* the passive landmarks' share, (2) */
    }
    if (local) {
        /* phi' = F_A phi: the pose rows */
        for (int i = 0; i < ekf->cekf.na0; ++i) {
            const double a0 = PHI_(ekf, 0, i);
            const double a1 = PHI_(ekf, 1, i);
            const double a2 = PHI_(ekf, 2, i);
            for (int r = 0; r < 3; ++r) {
                PHI_(ekf, r, i) = g[r][0] * a0 + g[r][1] * a1 + g[r][2] * a2;
            }
        }
    }
    ekf->ctr.predictions++;
    return COSLAM_OK;
}

/* H_a P H_b^T for two sightings' Jacobians, each non-zero only on the pose
 * and its landmark (ja, jb): O(1). With a = b it is the innovation
 * covariance without Q. */
static void sparse_hph(const ekfslam_t *ekf, const lm_expect_t *ea, uint16_t ja, const lm_expect_t *eb, uint16_t jb,
                       double s[2][2])
{
    const int ia[5] = {0, 1, 2, 3 + 2 * ja, 4 + 2 * ja};
    const int ib[5] = {0, 1, 2, 3 + 2 * jb, 4 + 2 * jb};
    double ha[2][5];
    double hb[2][5];
    for (int q = 0; q < 2; ++q) {
        for (int r = 0; r < 3; ++r) {
            ha[q][r] = ea->h_pose[q][r];
            hb[q][r] = eb->h_pose[q][r];
        }
        ha[q][3] = ea->h_lm[q][0];
        ha[q][4] = ea->h_lm[q][1];
        hb[q][3] = eb->h_lm[q][0];
        hb[q][4] = eb->h_lm[q][1];
    }
    /* the block P_(ia, ib), less the pending pairings' share (batch_add) */
    double blk[5][5];
    for (int r1 = 0; r1 < 5; ++r1) {
        for (int r2 = 0; r2 < 5; ++r2) {
            blk[r1][r2] = P_(ekf, ia[r1], ib[r2]);
        }
    }
    if (COSLAM_EKF_MAX_ACTIVE > 0 && ekf->cekf.bn > 0) {
        for (int r1 = 0; r1 < 5; ++r1) {
            for (int r2 = 0; r2 < 5; ++r2) {
                blk[r1][r2] -= batch_p_corr(ekf, act_pos(ekf, ia[r1]), act_pos(ekf, ib[r2]));
            }
        }
    }
    /* t = blk Hb^T (5 x 2), then Ha t */
    double t[5][2];
    for (int r1 = 0; r1 < 5; ++r1) {
        for (int q = 0; q < 2; ++q) {
            double acc = 0.0;
            for (int r2 = 0; r2 < 5; ++r2) {
                acc += blk[r1][r2] * hb[q][r2];
            }
            t[r1][q] = acc;
        }
    }
    for (int q1 = 0; q1 < 2; ++q1) {
        for (int q2 = 0; q2 < 2; ++q2) {
            double acc = 0.0;
            for (int r1 = 0; r1 < 5; ++r1) {
                acc += ha[q1][r1] * t[r1][q2];
            }
            s[q1][q2] = acc;
        }
    }
}

/* Expected sighting of landmark j with the full innovation covariance
 * S = H P H^T + Q, H = [H_r 0 .. H_m .. 0]. */
static coslam_status_t expect_at(const ekfslam_t *ekf, uint16_t j, pose2_t pose, point2_t m, pose2_t lin_pose,
                                 point2_t lin_m, lm_expect_t *e)
{
    const slam_params_t *sp = &ekf->cfg.slam;
    const coslam_status_t st = observe_jacobians(lin_pose, lin_m, e->h_pose, e->h_lm);
    if (st != COSLAM_OK || observe_jacobians(pose, m, NULL, NULL) != COSLAM_OK) {
        return COSLAM_E_DEGENERATE;
    }
    e->zhat = observe_predict(pose, m);
    e->zhat.signature = ekf->meta[j].signature;
    double s[2][2];
    sparse_hph(ekf, e, j, e, j, s);
    const cov2_t sc = cov2_add(cov2_make(s[0][0], 0.5 * (s[0][1] + s[1][0]), s[1][1]),
                               observe_noise(sp, e->zhat.range_m));
    if (cov2_inverse(sc, &e->s_inv) != COSLAM_OK) {
        return COSLAM_E_NOT_PD;
    }
    e->s = sc;
    e->log_norm = -log(COSLAM_TWO_PI * sqrt(cov2_det(sc)));
    return COSLAM_OK;
}

static coslam_status_t expect_landmark(const ekfslam_t *ekf, uint16_t j, lm_expect_t *e)
{
    const pose2_t pose = robot_pose(ekf);
    const int a = 3 + 2 * j;
    const point2_t m = {ekf->x[a], ekf->x[a + 1]};
    /* FEJ: linearise at the predicted pose and the landmark's first estimate */
    const pose2_t lin_pose = ekf->cfg.fej ? ekf->pose_prior : pose;
    const point2_t lin_m = ekf->cfg.fej ? ekf->lm_first[j] : m;
    return expect_at(ekf, j, pose, m, lin_pose, lin_m, e);
}

/*
 * Iterated EKF (Bell and Cathey 1993; Gauss-Newton on the update's cost):
 * relinearise the sighting of landmark j at the iterate
 *   x_{i+1} = x_0 + K_i (z - h(x_i) - H_i (x_0 - x_i)),  K_i = P H_i^T S_i^-1,
 * with P the prior covariance, until the step is below 1e-6. Only the pose
 * and the landmark enter h, so each iteration is O(1). On return e holds the
 * expectation linearised at the last iterate and nu the innovation that,
 * applied as one EKF step from x_0 with e's Jacobians, gives the next
 * iterate: the ordinary update then finishes the iteration. Returns the
 * number of iterations taken.
 */
static int iterate_linearisation(const ekfslam_t *ekf, uint16_t j, sighting_t z, int max_iters, lm_expect_t *e,
                                 double nu[2])
{
    const int a = 3 + 2 * j;
    const int ix[5] = {0, 1, 2, a, a + 1};
    double x0[5];
    double xi[5];
    for (int r = 0; r < 5; ++r) {
        x0[r] = ekf->x[ix[r]];
        xi[r] = x0[r];
    }
    int it = 0;
    for (;;) {
        lm_expect_t ei;
        const pose2_t pose = {xi[0], xi[1], xi[2]};
        const point2_t m = {xi[3], xi[4]};
        if (expect_at(ekf, j, pose, m, pose, m, &ei) != COSLAM_OK) {
            return it; /* keep the last good linearisation */
        }
        double nui[2];
        observe_innovation(z, ei.zhat, nui);
        const double dx[5] = {x0[0] - xi[0], x0[1] - xi[1], angle_wrap(x0[2] - xi[2]), x0[3] - xi[3], x0[4] - xi[4]};
        for (int q = 0; q < 2; ++q) {
            nui[q] -= ei.h_pose[q][0] * dx[0] + ei.h_pose[q][1] * dx[1] + ei.h_pose[q][2] * dx[2] +
                      ei.h_lm[q][0] * dx[3] + ei.h_lm[q][1] * dx[4];
        }
        *e = ei;
        nu[0] = nui[0];
        nu[1] = nui[1];
        if (it >= max_iters) {
            return it;
        }
        /* the next iterate's pose and landmark: x_0 + K nu */
        double step2 = 0.0;
        for (int r = 0; r < 5; ++r) {
            double pht[2];
            for (int q = 0; q < 2; ++q) {
                pht[q] = P_(ekf, ix[r], 0) * ei.h_pose[q][0] + P_(ekf, ix[r], 1) * ei.h_pose[q][1] +
                         P_(ekf, ix[r], 2) * ei.h_pose[q][2] + P_(ekf, ix[r], a) * ei.h_lm[q][0] +
                         P_(ekf, ix[r], a + 1) * ei.h_lm[q][1];
            }
            const double k0 = pht[0] * ei.s_inv.xx + pht[1] * ei.s_inv.xy;
            const double k1 = pht[0] * ei.s_inv.xy + pht[1] * ei.s_inv.yy;
            double xn = x0[r] + k0 * nui[0] + k1 * nui[1];
            double d = xn - xi[r];
            if (r == 2) {
                xn = angle_wrap(xn);
                d = angle_wrap(d);
            }
            step2 += d * d;
            xi[r] = xn;
        }
        ++it;
        if (!(step2 > 1e-12)) {
            /* converged: one more linearisation at the fixed point */
            max_iters = it;
        }
    }
}

/*
 * EKF update of the whole state with one sighting of landmark j.
 * With PHt = P H^T (D x 2), S = H PHt + Q, K = PHt S^-1:
 *   x += K nu
 *   P = (I - K H) P (I - K H)^T + K Q K^T
 *     = P - K PHt^T - PHt K^T + K S K^T          (Joseph form, O(D^2))
 */
static coslam_status_t update_one(ekfslam_t *ekf, uint16_t j, sighting_t z, int iterate, double *d2)
{
    lm_expect_t e;
    coslam_status_t st = expect_landmark(ekf, j, &e);
    if (st != COSLAM_OK) {
        ekf->ctr.numeric_faults++;
        return st;
    }
    double nu[2];
    observe_innovation(z, e.zhat, nu);
    *d2 = landmark_mahalanobis2(&e, z);
    if (iterate) {
        ekf->ctr.iekf_updates++;
        ekf->ctr.iekf_iterations += (uint32_t)iterate_linearisation(ekf, j, z, (int)ekf->cfg.iekf_max_iters, &e, nu);
    }
    if (in_local(ekf)) {
        batch_add(ekf, j, &e, nu); /* the active part, with the frame's other pairings */
        return COSLAM_OK;
    }
    /* the whole state */
    const int d = dim(ekf);
    const int a = 3 + 2 * j;
    double(*pht)[2] = ekf->scratch.pht;
    double(*k)[2] = ekf->scratch.k;
    for (int r = 0; r < d; ++r) {
        const double *row = &ekf->p[(long)r * D_];
        for (int q = 0; q < 2; ++q) {
            pht[r][q] = row[0] * e.h_pose[q][0] + row[1] * e.h_pose[q][1] + row[2] * e.h_pose[q][2] +
                        row[a] * e.h_lm[q][0] + row[a + 1] * e.h_lm[q][1];
        }
    }
    const cov2_t si = e.s_inv;
    for (int r = 0; r < d; ++r) {
        k[r][0] = pht[r][0] * si.xx + pht[r][1] * si.xy;
        k[r][1] = pht[r][0] * si.xy + pht[r][1] * si.yy;
    }
    for (int r = 0; r < d; ++r) {
        ekf->x[r] += k[r][0] * nu[0] + k[r][1] * nu[1];
    }
    ekf->x[2] = angle_wrap(ekf->x[2]);
    const cov2_t s = e.s;
    /* P -= delta, each entry computed once and written to both halves; in
     * tiles, so that the mirrored writes (a column of the row-major P)
     * stay within a few rows (pages) at a time. The order of the entries
     * changes nothing: each is written once per update. */
    for (int r0 = 0; r0 < d; r0 += EKF_TILE) {
        const int r1 = r0 + EKF_TILE < d ? r0 + EKF_TILE : d;
        for (int c0 = r0; c0 < d; c0 += EKF_TILE) {
            const int c1 = c0 + EKF_TILE < d ? c0 + EKF_TILE : d;
            for (int r = r0; r < r1; ++r) {
                /* ks = K_r S */
                const double ks0 = k[r][0] * s.xx + k[r][1] * s.xy;
                const double ks1 = k[r][0] * s.xy + k[r][1] * s.yy;
                for (int c = r > c0 ? r : c0; c < c1; ++c) {
                    const double delta = k[r][0] * pht[c][0] + k[r][1] * pht[c][1] + pht[r][0] * k[c][0] +
                                         pht[r][1] * k[c][1] - (ks0 * k[c][0] + ks1 * k[c][1]);
                    const double val = P_(ekf, r, c) - delta;
                    P_(ekf, r, c) = val;
                    P_(ekf, c, r) = val;
                }
            }
        }
    }
    return COSLAM_OK;
}

/*
 * Append a landmark at m (map frame) whose error is gr * (pose error) +
 * gt * (tau error, only while merging) + noise (covariance `noise`, map
 * frame), independent of the rest. Cross-covariances with every active
 * state follow: P_m* = G P_(r,tau)*. O(D).
 */
static coslam_status_t add_landmark(ekfslam_t *ekf, point2_t m, double gr[2][3], double gt[2][3], cov2_t noise,
                                    const ekfslam_meta_t *meta)
{
    if (ekf->n_lm >= COSLAM_EKF_MAX_LANDMARKS && ekf->n_dead > 0U) {
        cekf_end_phase(ekf); /* the dead make room */
        dead_flush(ekf);
    }
    if (ekf->n_lm >= COSLAM_EKF_MAX_LANDMARKS) {
        ekf->ctr.lm_capacity_drops++;
        return COSLAM_E_CAPACITY;
    }
    if (!cov2_is_finite(noise) || !isfinite(m.x) || !isfinite(m.y)) {
        ekf->ctr.numeric_faults++;
        return COSLAM_E_NUMERIC;
    }
    if (in_local(ekf) && ekf->cekf.na + 2 > ADIM_) {
        sync_whole(ekf); /* the active part is full */
    }
    COSLAM_ASSERT(!(in_local(ekf) && ekf->merging));
    const int local = in_local(ekf);
    const int n_act = local ? ekf->cekf.na : n_active(ekf);
    const int a = dim(ekf); /* new rows/columns a, a+1 */
    /* the sources: pose (0..2) and, if given, tau */
    int src[6] = {0, 1, 2, TAU_, TAU_ + 1, TAU_ + 2};
    double g[2][6];
    for (int q = 0; q < 2; ++q) {
        for (int r = 0; r < 3; ++r) {
            g[q][r] = gr[q][r];
            g[q][3 + r] = gt != 0 ? gt[q][r] : 0.0;
        }
    }
    const int n_src = gt != 0 && ekf->merging ? 6 : 3;
    for (int k = 0; k < n_act; ++k) {
        const int col = local ? ekf->cekf.idx[k] : active_idx(ekf, k);
        for (int q = 0; q < 2; ++q) {
            double val = 0.0;
            for (int r = 0; r < n_src; ++r) {
                val += g[q][r] * P_(ekf, src[r], col);
            }
            P_(ekf, a + q, col) = val;
            P_(ekf, col, a + q) = val;
        }
    }
    double pmm[2][2] = {{noise.xx, noise.xy}, {noise.xy, noise.yy}};
    for (int q1 = 0; q1 < 2; ++q1) {
        for (int q2 = 0; q2 < 2; ++q2) {
            for (int r1 = 0; r1 < n_src; ++r1) {
                for (int r2 = 0; r2 < n_src; ++r2) {
                    pmm[q1][q2] += g[q1][r1] * P_(ekf, src[r1], src[r2]) * g[q2][r2];
                }
            }
        }
    }
    const double sym = 0.5 * (pmm[0][1] + pmm[1][0]);
    P_(ekf, a, a) = pmm[0][0];
    P_(ekf, a, a + 1) = sym;
    P_(ekf, a + 1, a) = sym;
    P_(ekf, a + 1, a + 1) = pmm[1][1];
    ekf->x[a] = m.x;
    ekf->x[a + 1] = m.y;
    if (local) {
        /* active from now on; P_mB = G_r phi_r P_A0B: phi rows G_r phi_r */
        ekfslam_cekf_t *ck = &ekf->cekf;
        const int kn = ck->na;
        ck->slot[ekf->n_lm] = kn;
        ck->idx[kn] = a;
        ck->idx[kn + 1] = a + 1;
        for (int i = 0; i < ck->na0; ++i) {
            for (int q = 0; q < 2; ++q) {
                PHI_(ekf, kn + q, i) = gr[q][0] * PHI_(ekf, 0, i) + gr[q][1] * PHI_(ekf, 1, i) + gr[q][2] * PHI_(ekf, 2, i);
            }
        }
        ck->na = kn + 2;
    }
    ekf->lm_first[ekf->n_lm] = m;
    ekf->meta[ekf->n_lm] = *meta;
    ekf->meta[ekf->n_lm].last_seen = ekf->ctr.updates;
    ekf->lm_confirmed_once[ekf->n_lm] = 0U; /* set by exist_miss() if meta->exist confirms it */
    ekf->lm_dead[ekf->n_lm] = 0U;
    ekf->n_lm++;
    return COSLAM_OK;
}

static coslam_status_t add_landmark_body(ekfslam_t *ekf, point2_t m_body, cov2_t cov_body, const ekfslam_meta_t *meta)
{
    if (!cov2_is_finite(cov_body) || !isfinite(m_body.x) || !isfinite(m_body.y)) {
        ekf->ctr.numeric_faults++;
        return COSLAM_E_NUMERIC;
    }
    const pose2_t pose = robot_pose(ekf);
    double gr[2][3];
    double gb[2][2];
    pose2_apply_jacobians(pose, m_body, gr, gb);
    return add_landmark(ekf, pose2_apply(pose, m_body), gr, 0, cov2_congruence(gb, cov_body), meta);
}

/* Removal of landmark j, last moving to j: the pending flags and u rows
 * follow the rows of P, in every generation. O(N_pend + N_A0). */
static void pend_remove(ekfslam_t *ekf, uint16_t j, uint16_t last)
{
    ekfslam_cekf_t *ck = &ekf->cekf;
    if (COSLAM_EKF_MAX_ACTIVE == 0) {
        return;
    }
    for (int gi = 0; gi < EKFSLAM_PEND_GENS; ++gi) {
        ekfslam_pend_t *g = &ck->gen[gi];
        if (g->n == 0) {
            continue;
        }
        for (int t = 0; t < g->n && g->flag[j]; ++t) {
            if (g->list[t] == j) {
                pend_unflag(g, t); /* may empty g */
            }
        }
        if (j == last || !g->flag[last]) {
            continue;
        }
        for (int t = 0; t < g->n; ++t) {
            if (g->list[t] == last) {
                g->list[t] = j;
                break;
            }
        }
        g->flag[j] = g->flag[last];
        g->flag[last] = 0U;
        for (int q = 0; q < 2; ++q) {
            memcpy(g->u[2 * j + q], g->u[2 * last + q], (size_t)g->n0 * sizeof(double));
        }
    }
}

/* ---- Removal in a local phase -------------------------------------------
 *
 * Taking landmark j out of the state in a local phase would lose P_jB(0),
 * which (1)-(3) read for every passive entry until the phase ends; so a
 * removal used to end the phase, and a step with one paid the global
 * update (50 ms on average at 700-1,000 landmarks on the bench's stream,
 * against 3.3 ms for the others). Instead the filter's own removals
 * (misses) mark j dead: no association, miss test, reach test or export
 * reads it from then on, and it stays in the state, updated like any
 * unobserved landmark, until the phase ends for its own reasons; then
 * dead_flush takes them out: in ekfslam_sync, ekfslam_sync_run, the idle
 * time's region switch, and at the end of an update whose start ended the
 * phase (not at its start: the association, and the caller's health
 * checks, read the indices the caller saw before the update). If the next
 * phase starts there first, they go at its end. Removing a landmark from a
 * Gaussian is marginalising it, which does not change the other states'
 * joint distribution, then or later: the result is the full EKF's up to
 * rounding and the order of the landmarks (the full EKF moves the last
 * one into j at once). Outside a local phase a removal is immediate, as
 * before. */

/* Landmark j out of the state now, the last moving to j (not in a local
 * phase). */
static void remove_now(ekfslam_t *ekf, uint16_t j)
{
    COSLAM_ASSERT(j < ekf->n_lm && !in_local(ekf));
    const uint16_t last = (uint16_t)(ekf->n_lm - 1);
    pend_remove(ekf, j, last);
    if (j != last) {
        const int d = dim(ekf);
        const int a = 3 + 2 * j;
        const int b = 3 + 2 * last;
        ekf->x[a] = ekf->x[b];
        ekf->x[a + 1] = ekf->x[b + 1];
        /* rows first, then columns: the (a, a) block ends up as (b, b) */
        for (int q = 0; q < 2; ++q) {
            memcpy(&ekf->p[(long)(a + q) * D_], &ekf->p[(long)(b + q) * D_], (size_t)d * sizeof(double));
        }
        for (int r = 0; r < d; ++r) {
            P_(ekf, r, a) = P_(ekf, r, b);
            P_(ekf, r, a + 1) = P_(ekf, r, b + 1);
        }
        ekf->meta[j] = ekf->meta[last];
        ekf->lm_first[j] = ekf->lm_first[last];
        ekf->lm_confirmed_once[j] = ekf->lm_confirmed_once[last];
        ekf->lm_dead[j] = ekf->lm_dead[last];
    }
    ekf->lm_dead[last] = 0U;
    ekf->n_lm = last;
}

/* The dead landmarks out of the state, once no local phase runs; highest
 * index first (each removal moves the last landmark, already visited). */
static void dead_flush(ekfslam_t *ekf)
{
    if (ekf->n_dead == 0U || in_local(ekf)) {
        return;
    }
    for (int j = (int)ekf->n_lm - 1; j >= 0; --j) {
        if (ekf->lm_dead[j]) {
            remove_now(ekf, (uint16_t)j);
        }
    }
    ekf->n_dead = 0U;
}

/* The filter's removal of landmark j: dead in a local phase, else now. */
static void remove_landmark(ekfslam_t *ekf, uint16_t j)
{
    COSLAM_ASSERT(j < ekf->n_lm && !ekf->lm_dead[j]);
    if (in_local(ekf)) {
        ekf->lm_dead[j] = 1U;
        ekf->n_dead++;
        ekf->ctr.removals_deferred++;
        return;
    }
    cekf_end_phase(ekf); /* pending rows stay pending (pend_remove) */
    remove_now(ekf, j);
}

/* ---- Joint compatibility branch and bound ------------------------------ */

/* The cross block of candidate pairs pb and pa of the joint innovation
 * covariance, H_b P H_a^T (the Q term belongs to the diagonal blocks only;
 * it depends on the pairs' landmarks only): the search
 * asks for the same blocks at many nodes, so they are kept once computed
 * (same numbers). */
static void joint_block(ekfslam_t *ekf, int pb, int pa, double s[2][2])
{
    ekfslam_scratch_t *sc = &ekf->scratch;
    const uint16_t jb = (uint16_t)sc->pairs[pb].landmark;
    const uint16_t ja = (uint16_t)sc->pairs[pa].landmark;
    if (sc->cross_n == 0) {
        sparse_hph(ekf, &sc->expect[jb], jb, &sc->expect[ja], ja, s);
        return;
    }
    const int ib = sc->cross_ix[jb];
    const int ia = sc->cross_ix[ja];
    if (!sc->cross_ok[ib][ia]) {
        sparse_hph(ekf, &sc->expect[jb], jb, &sc->expect[ja], ja, sc->cross[ib][ia]);
        sc->cross_ok[ib][ia] = 1U;
    }
    for (int q1 = 0; q1 < 2; ++q1) {
        for (int q2 = 0; q2 < 2; ++q2) {
            s[q1][q2] = sc->cross[ib][ia][q1][q2];
        }
    }
}

/* Rows of the candidate landmarks in the cross table; none if there are
 * more than EKFSLAM_JCBB_CROSS (then joint_block computes every block). */
static void cross_table_init(ekfslam_scratch_t *sc, int n_pairs)
{
    for (int q = 0; q < n_pairs; ++q) {
        sc->cross_ix[sc->pairs[q].landmark] = -1;
    }
    int n = 0;
    for (int q = 0; q < n_pairs && n <= EKFSLAM_JCBB_CROSS; ++q) {
        int16_t *ix = &sc->cross_ix[sc->pairs[q].landmark];
        if (*ix < 0) {
            *ix = (int16_t)n++;
        }
    }
    sc->cross_n = n <= EKFSLAM_JCBB_CROSS ? n : 0;
    for (int b = 0; b < sc->cross_n; ++b) {
        for (int a = 0; a < sc->cross_n; ++a) {
            sc->cross_ok[b][a] = 0U;
        }
    }
}

/*
 * Try to extend the hypothesis of k pairings (Cholesky factor L of its joint
 * S in chol[0..2k), y = L^-1 nu) by pair `pi`. Writes rows 2k, 2k+1 and
 * returns the new joint squared Mahalanobis distance, or INFINITY if the
 * joint covariance is not positive definite.
 */
static double jcbb_extend(ekfslam_t *ekf, const sighting_t *z, int k, int pi, double *logdet_inc)
{
    ekfslam_scratch_t *sc = &ekf->scratch;
    const assoc_pair_t *pa = &sc->pairs[pi];
    const lm_expect_t *ea = &sc->expect[pa->landmark];
    const int n = 2 * k;
    double(*l)[EKFSLAM_JCBB_DIM] = sc->chol;
    /* w = L^-1 c, c = S_(H, a); stored as the new rows' left part */
    for (int q = 0; q < 2; ++q) {
        for (int r = 0; r < n; ++r) {
            l[n + q][r] = 0.0;
        }
    }
    for (int b = 0; b < k; ++b) {
        double s[2][2];
        joint_block(ekf, sc->hyp_pair[b], pi, s);
        for (int q1 = 0; q1 < 2; ++q1) {
            for (int q2 = 0; q2 < 2; ++q2) {
                l[n + q2][2 * b + q1] = s[q1][q2]; /* c^T for now */
            }
        }
    }
    for (int q = 0; q < 2; ++q) {
        for (int r = 0; r < n; ++r) {
            double acc = l[n + q][r];
            for (int m = 0; m < r; ++m) {
                acc -= l[r][m] * l[n + q][m];
            }
            l[n + q][r] = acc / l[r][r];
        }
    }
    /* Schur complement d' = S_aa - w^T w and its 2x2 Cholesky */
    double d00 = ea->s.xx;
    double d01 = ea->s.xy;
    double d11 = ea->s.yy;
    for (int r = 0; r < n; ++r) {
        d00 -= l[n][r] * l[n][r];
        d01 -= l[n][r] * l[n + 1][r];
        d11 -= l[n + 1][r] * l[n + 1][r];
    }
    if (!(d00 > 0.0)) {
        return INFINITY;
    }
    const double l00 = sqrt(d00);
    const double l10 = d01 / l00;
    const double rem = d11 - l10 * l10;
    if (!(rem > 0.0)) {
        return INFINITY;
    }
    const double l11 = sqrt(rem);
    *logdet_inc = 2.0 * (log(l00) + log(l11));
    l[n][n] = l00;
    l[n][n + 1] = 0.0;
    l[n + 1][n] = l10;
    l[n + 1][n + 1] = l11;
    /* y_a = l^-1 (nu_a - w^T y) */
    double nu[2];
    observe_innovation(z[pa->sighting], ea->zhat, nu);
    double d2 = 0.0;
    for (int r = 0; r < n; ++r) {
        nu[0] -= l[n][r] * sc->y[r];
        nu[1] -= l[n + 1][r] * sc->y[r];
        d2 += sc->y[r] * sc->y[r];
    }
    const double y0 = nu[0] / l00;
    const double y1 = (nu[1] - l10 * y0) / l11;
    sc->y[n] = y0;
    sc->y[n + 1] = y1;
    return d2 + y0 * y0 + y1 * y1;
}

static int landmark_in_hyp(const ekfslam_scratch_t *sc, int ns, int32_t j)
{
    for (int i = 0; i < ns; ++i) {
        if (sc->hyp[i] == j) {
            return 1;
        }
    }
    return 0;
}

/* Joint hypotheses are ranked by likelihood: the joint Gaussian density of
 * the paired sightings' innovations, times the new-landmark density p0 for
 * each sighting that had a candidate but is left unpaired. (Ranking by the
 * number of pairings, as plain JCBB does, prefers a wrong pairing of a
 * first-seen marker with an old identical one whenever the pose is
 * uncertain enough for it to be jointly compatible.) */
static void jcbb_leaf(ekfslam_t *ekf, int ns, int k, double score)
{
    ekfslam_scratch_t *sc = &ekf->scratch;
    if (score > sc->best_score) {
        sc->second_score = sc->best_score;
        sc->second_pairings = sc->best_pairings;
        for (int q = 0; q < ns; ++q) {
            sc->second[q] = sc->best[q];
        }
        sc->best_score = score;
        sc->best_pairings = k;
        for (int q = 0; q < ns; ++q) {
            sc->best[q] = sc->hyp[q];
        }
    } else if (score > sc->second_score) {
        sc->second_score = score;
        sc->second_pairings = k;
        for (int q = 0; q < ns; ++q) {
            sc->second[q] = sc->hyp[q];
        }
    }
}

/* 1 if landmark j is the one candidate, loop-closing, of a sighting that
 * the association held back as a possible revisit (held[i] == 1; JCBB
 * only). A held sighting with two or more candidates (a map that holds an
 * area twice) protects none of them. */
static int held_revisit_of(const ekfslam_scratch_t *sc, int ns, int32_t j)
{
    for (int i = 0; i < ns; ++i) {
        const int q = sc->cand_begin[i];
        if (sc->held[i] == 1U && sc->cand_begin[i + 1] == q + 1 && sc->pairs[q].landmark == j && sc->closure[j]) {
            return 1;
        }
    }
    return 0;
}

/* A pairing is a loop closure if its landmark was not sighted for a while
 * (a revisit) and the robot-landmark uncertainty, not the sensor, dominates
 * its innovation: det S > 4 det Q (its error ellipse more than twice the
 * sensor's in area). */
static int pair_is_closure(const ekfslam_t *ekf, int32_t j)
{
    if (ekf->ctr.updates - ekf->meta[j].last_seen <= ekf->cfg.jcbb_closure_gap) {
        return 0;
    }
    const lm_expect_t *e = &ekf->scratch.expect[j];
    const cov2_t q = observe_noise(&ekf->cfg.slam, e->zhat.range_m);
    return cov2_det(e->s) > 4.0 * cov2_det(q);
}

/* The linearisation of a range-bearing sighting holds while the
 * robot-landmark offset is well known against its length: with an offset
 * standard deviation s (largest axis of its covariance, correlations
 * included) at range r, the bearing's Jacobian varies by about s / r over
 * the uncertainty. Returns s / r. */
static double pair_spread(const ekfslam_t *ekf, int32_t j)
{
    const int a = 3 + 2 * (int)j;
    const double cxx = P_(ekf, 0, 0) + P_(ekf, a, a) - 2.0 * P_(ekf, 0, a);
    const double cyy = P_(ekf, 1, 1) + P_(ekf, a + 1, a + 1) - 2.0 * P_(ekf, 1, a + 1);
    const double cxy = P_(ekf, 0, 1) + P_(ekf, a, a + 1) - P_(ekf, 0, a + 1) - P_(ekf, 1, a);
    const double half_tr = 0.5 * (cxx + cyy);
    const double d = sqrt(0.25 * (cxx - cyy) * (cxx - cyy) + cxy * cxy);
    const double lmax = half_tr + d;
    const double r = ekf->scratch.expect[j].zhat.range_m;
    if (!(lmax >= 0.0) || !(r > 1e-6)) {
        return INFINITY;
    }
    return sqrt(lmax) / r;
}

/* Pass 1, hypothesis so far decided for sightings 0..i-1: does it read
 * sighting q < i otherwise than the best one, and not weakly (a pairing
 * alone less likely than a new landmark does not compete)? */
static int alt_reading(const ekfslam_t *ekf, int q)
{
    const ekfslam_scratch_t *sc = &ekf->scratch;
    return sc->hyp[q] != sc->best[q] &&
           !(sc->hyp[q] >= 0 && sc->pairs[sc->hyp_pi[q]].score < ekf->cfg.slam.new_landmark_log_lik);
}

/* Pass 1 asks, for each sighting whose best pairing closes a loop, only
 * whether some hypothesis reads it otherwise with a score within the
 * margin of the best (then it is held back): the lowest threshold a leaf
 * below this node could still decide, +INFINITY if none (the subtree
 * cannot change a decision and is skipped). A sighting already decided
 * below i (q >= i) may still read either way: the lower margin applies. */
static double pass1_floor(const ekfslam_t *ekf, int ns, int i)
{
    const ekfslam_scratch_t *sc = &ekf->scratch;
    double floor = INFINITY;
    for (int q = 0; q < ns; ++q) {
        if (!sc->need_alt[q]) {
            continue;
        }
        if (q >= i) {
            return sc->best_score - fmax(sc->margin_other, sc->margin_none);
        }
        if (alt_reading(ekf, q)) {
            const double t = sc->best_score - (sc->hyp[q] >= 0 ? sc->margin_other : sc->margin_none);
            floor = fmin(floor, t);
        }
    }
    return floor;
}

static void jcbb_search(ekfslam_t *ekf, const sighting_t *z, int ns, int i, int k, double d2, double logdet,
                        int n_unpaired, int n_closure)
{
    ekfslam_scratch_t *sc = &ekf->scratch;
    if (sc->nodes >= ekf->cfg.jcbb_max_nodes || (sc->pass == 1U && sc->n_need_alt == 0)) {
        return;
    }
    sc->nodes++;
    /* branch and bound: the score so far plus the most the remaining
     * sightings can add (ub_rest) must beat the best (pass 0) or a
     * threshold that decides a sighting still in question (pass 1,
     * pass1_floor) */
    {
        const double partial = -0.5 * (d2 + logdet) - (double)k * log(COSLAM_TWO_PI) +
                               (double)n_unpaired * ekf->cfg.slam.new_landmark_log_lik;
        const double floor = sc->pass == 0U ? sc->best_score : pass1_floor(ekf, ns, i);
        if (partial + sc->ub_rest[i] <= floor) {
            return;
        }
    }
    if (i == ns) {
        if (n_closure > 0 && n_closure < (int)ekf->cfg.jcbb_min_closure_pairs) {
            sc->closures_short++; /* too few loop-closing pairings to trust */
            return;
        }
        const double score = -0.5 * (d2 + logdet) - (double)k * log(COSLAM_TWO_PI) +
                             (double)n_unpaired * ekf->cfg.slam.new_landmark_log_lik;
        if (sc->pass == 0U) {
            jcbb_leaf(ekf, ns, k, score);
        } else {
            /* second pass: alternatives for the sightings in question; a
             * weak pairing (alone less likely than a new landmark) is not
             * a competing reading */
            for (int q = 0; q < ns; ++q) {
                if (!sc->need_alt[q] || !alt_reading(ekf, q)) {
                    continue;
                }
                const int other = sc->hyp[q] >= 0;
                double *alt = other ? &sc->alt_other[q] : &sc->alt_none[q];
                if (score > *alt) {
                    *alt = score;
                }
                if (score > sc->best_score - (other ? sc->margin_other : sc->margin_none)) {
                    sc->need_alt[q] = 0U; /* held back: no need to look further */
                    sc->n_need_alt--;
                }
            }
        }
        return;
    }
    for (int pi = sc->cand_begin[i]; pi < sc->cand_begin[i + 1]; ++pi) {
        const int32_t j = sc->pairs[pi].landmark;
        if (landmark_in_hyp(sc, i, j)) {
            continue;
        }
        double inc = 0.0;
        const double d2n = jcbb_extend(ekf, z, k, pi, &inc);
        if (d2n < sc->chi2_joint[k + 1]) {
            sc->hyp[i] = j;
            sc->hyp_pi[i] = pi;
            sc->hyp_pair[k] = pi;
            jcbb_search(ekf, z, ns, i + 1, k + 1, d2n, logdet + inc, n_unpaired,
                        n_closure + sc->closure[j]);
            sc->hyp[i] = -1;
        }
    }
    sc->hyp[i] = -1;
    jcbb_search(ekf, z, ns, i + 1, k, d2, logdet,
                n_unpaired + (sc->cand_begin[i + 1] > sc->cand_begin[i] ? 1 : 0), n_closure);
}

/* Chi-square quantiles for 2, 4, ..., 2 ns dof at the confidence of the
 * individual gate (Wilson-Hilferty, inverted at 2 dof to find the normal
 * quantile, so that the 1-pair joint gate equals gate_chi2). */
static void jcbb_thresholds(ekfslam_t *ekf, int ns)
{
    const double g = ekf->cfg.slam.gate_chi2;
    const double h2 = 2.0 / 9.0 / 2.0;
    const double zq = (cbrt(g / 2.0) - 1.0 + h2) / sqrt(h2);
    ekf->scratch.chi2_joint[0] = 0.0;
    ekf->scratch.chi2_joint[1] = g;
    for (int k = 2; k <= ns; ++k) {
        const double dof = 2.0 * k;
        const double h = 2.0 / (9.0 * dof);
        const double t = 1.0 - h + zq * sqrt(h);
        ekf->scratch.chi2_joint[k] = dof * t * t * t;
    }
}

/* Order the candidate pairs by sighting, then by individual distance, and
 * run the search; result in scratch.assign. */
static void jcbb_associate(ekfslam_t *ekf, const sighting_t *z, int ns, int n_pairs)
{
    ekfslam_scratch_t *sc = &ekf->scratch;
    /* insertion sort by (sighting, -score): pair counts are small */
    for (int a = 1; a < n_pairs; ++a) {
        const assoc_pair_t v = sc->pairs[a];
        int b = a - 1;
        while (b >= 0 && (sc->pairs[b].sighting > v.sighting ||
                          (sc->pairs[b].sighting == v.sighting && sc->pairs[b].score < v.score))) {
            sc->pairs[b + 1] = sc->pairs[b];
            --b;
        }
        sc->pairs[b + 1] = v;
    }
    int pi = 0;
    for (int i = 0; i <= ns; ++i) {
        while (pi < n_pairs && sc->pairs[pi].sighting < i) {
            ++pi;
        }
        sc->cand_begin[i] = pi;
    }
    sc->cand_begin[ns] = n_pairs;
    cross_table_init(sc, n_pairs);
    jcbb_thresholds(ekf, ns);
    for (int i = 0; i < ns; ++i) {
        sc->hyp[i] = -1;
        sc->best[i] = -1;
    }
    sc->best_pairings = 0;
    sc->best_score = -INFINITY;
    sc->second_pairings = -1;
    sc->second_score = -INFINITY;
    /* Upper bound of each sighting's share of the score: unpaired, the
     * new-landmark density; paired, the Gaussian density at zero innovation
     * with the smallest conditional covariance possible, the sensor noise
     * Q (the conditional innovation covariance is Q plus a PSD term). */
    sc->ub_rest[ns] = 0.0;
    for (int i = ns - 1; i >= 0; --i) {
        double ub = sc->cand_begin[i + 1] > sc->cand_begin[i] ? ekf->cfg.slam.new_landmark_log_lik : 0.0;
        for (int q = sc->cand_begin[i]; q < sc->cand_begin[i + 1]; ++q) {
            const lm_expect_t *e = &sc->expect[sc->pairs[q].landmark];
            const double r0 = fmin(e->zhat.range_m, z[i].range_m);
            const cov2_t qn = observe_noise(&ekf->cfg.slam, r0 > 0.0 ? r0 : 0.0);
            const double b = -log(COSLAM_TWO_PI) - 0.5 * log(cov2_det(qn));
            if (b > ub) {
                ub = b;
            }
        }
        sc->ub_rest[i] = sc->ub_rest[i + 1] + ub;
    }
    /* loop-closing candidates, once per update (the search asks often) */
    for (int q = 0; q < n_pairs; ++q) {
        const int32_t j = sc->pairs[q].landmark;
        sc->closure[j] = (uint8_t)pair_is_closure(ekf, j);
    }
    sc->nodes = 0U;
    sc->closures_short = 0U;
    sc->pass = 0U;
    jcbb_search(ekf, z, ns, 0, 0, 0.0, 0.0, 0, 0);
    if (sc->closures_short > 0U) {
        ekf->ctr.jcbb_closures_held++;
    }
    /* A loop-closing pairing is used only if it is decisively the most
     * likely reading of its sighting (by ambiguity_d2 / 2 in log-likelihood)
     * against both pairing it with another landmark and with none; else the
     * sighting is held back (neither paired nor new). Pairings with
     * landmarks in view lately are left to the joint likelihood: holding
     * them back starves the filter where identical markers stand close
     * (MRCLAM's clusters) while their pose error is already small. */
    const double margin = 0.5 * ekf->cfg.jcbb_ambiguity_d2;
    int n_with_cand = 0;
    for (int i = 0; i < ns; ++i) {
        n_with_cand += sc->cand_begin[i + 1] > sc->cand_begin[i];
    }
    /* against "no pairing": one sighting alone cannot reach the full margin
     * once the pose is uncertain, so it needs the smaller one */
    const double margin_none = n_with_cand >= 2 ? margin : 0.5 * ekf->cfg.jcbb_single_closure_d2;
    /* second pass: for each sighting whose best pairing closes a loop,
     * whether a hypothesis reads it differently (pairs it with another
     * landmark, or with none) within the margin; the other sightings'
     * alternatives decide nothing and are not searched (pass1_floor) */
    sc->n_need_alt = 0;
    sc->margin_other = margin;
    sc->margin_none = margin_none;
    for (int i = 0; i < ns; ++i) {
        sc->alt_other[i] = -INFINITY;
        sc->alt_none[i] = -INFINITY;
        sc->need_alt[i] = (uint8_t)(ekf->cfg.jcbb_ambiguity_d2 > 0.0 && sc->best[i] >= 0 && sc->closure[sc->best[i]]);
        sc->n_need_alt += sc->need_alt[i];
    }
    /* each pass has the budget; a cut search has not ruled out the
     * alternatives, so the frame's loop-closing pairings are held back
     * (and after a cut first pass the second decides nothing: not run) */
    int cut = sc->nodes >= ekf->cfg.jcbb_max_nodes;
    if (sc->n_need_alt > 0 && !cut) {
        sc->pass = 1U;
        sc->nodes = 0U;
        jcbb_search(ekf, z, ns, 0, 0, 0.0, 0.0, 0, 0);
        cut = cut || (sc->nodes >= ekf->cfg.jcbb_max_nodes && sc->n_need_alt > 0);
    }
    if (cut) {
        ekf->ctr.jcbb_budget_hits++;
    }
    int ambiguous = 0;
    int nonlinear = 0;
    for (int i = 0; i < ns; ++i) {
        sc->held[i] = 0U;
        sc->assign[i] = sc->best[i];
        if (sc->best[i] >= 0 && sc->closure[sc->best[i]] &&
            (cut || sc->alt_other[i] > sc->best_score - margin ||
             sc->alt_none[i] > sc->best_score - margin_none)) {
            sc->assign[i] = -1;
            sc->held[i] = 1U;
            ambiguous = 1;
        } else if (sc->best[i] >= 0 && pair_spread(ekf, sc->best[i]) > ekf->cfg.jcbb_closure_max_spread) {
            /* a pairing whose linearisation fails: one EKF step would turn
             * the robot by far more than the sighting supports; wait until
             * the robot is farther from the landmark or knows more. Mostly
             * a revisit; any pairing once the pose has lost its landmarks
             * (an inflated pose block, opened gates) */
            sc->assign[i] = -1;
            sc->held[i] = sc->closure[sc->best[i]] ? 1U : 2U; /* 2: not a revisit */
            nonlinear |= sc->closure[sc->best[i]] ? 1 : 2;
        }
        if (sc->assign[i] < 0 && !sc->held[i]) {
            /* unpaired but it had a loop-closing candidate: not new either,
             * wait for a frame that closes the loop with enough pairings */
            for (int q = sc->cand_begin[i]; q < sc->cand_begin[i + 1]; ++q) {
                if (sc->closure[sc->pairs[q].landmark]) {
                    sc->held[i] = 1U;
                    break;
                }
            }
        }
    }
    if (ambiguous) {
        ekf->ctr.jcbb_ambiguous++;
    }
    if (nonlinear & 1) {
        ekf->ctr.jcbb_closures_nonlinear++;
    }
    if (nonlinear & 2) {
        ekf->ctr.pairs_nonlinear++;
    }
}

/* Revisits as two hypotheses (ekfslam_config_t.mh_frames; docs/
 * consistency.md "EKF-SLAM's revisits as two hypotheses"). A loop-closing
 * pairing is decided by the frame it comes in, against leaving its sighting
 * unpaired (jcbb_associate); in a dense field of identical markers, after a
 * metre of drift, the one pairing left after the holds is sometimes a
 * chance alignment, and the EKF then moves the robot metres the wrong way,
 * for good. What tells a right revisit from a chance one is what the next
 * frames see: after a right one, the old landmarks that come into view
 * are where the corrected map has them. So the frame that would close
 * forks the filter: this one closes; a copy (alt) is the hypothesis that
 * nothing here is a revisit: no loop-closing pairing is a candidate in it,
 * and its sightings start landmarks. Both take the same inputs for
 * mh_frames updates, each frame scored by its best reading (JCBB's
 * log-likelihood; a sighting without any candidate as a new landmark,
 * new_landmark_log_lik, so that both score every sighting); then the one
 * whose frames sum higher is kept (a tie keeps the revisit). */
static coslam_status_t update_body(ekfslam_t *ekf, const sighting_t *z, int ns, double max_range_m,
                                   coslam_status_t result);
static coslam_status_t update_frame(ekfslam_t *ekf, const sighting_t *z_in, int n_in);

/* The frame's best reading (jcbb_associate) as a log-likelihood of all its
 * sightings: a sighting without candidates counts as a new landmark. */
static double frame_score(const ekfslam_t *ekf, int ns)
{
    const ekfslam_scratch_t *sc = &ekf->scratch;
    const double p0 = ekf->cfg.slam.new_landmark_log_lik;
    int n_none = 0;
    for (int i = 0; i < ns; ++i) {
        n_none += sc->cand_begin[i + 1] == sc->cand_begin[i];
    }
    /* a search cut before any leaf: every sighting unpaired, a reading
     * every search has */
    const double best = isfinite(sc->best_score) ? sc->best_score : (double)(ns - n_none) * p0;
    return best + (double)n_none * p0;
}

/* 1 if this frame's reading applies a loop-closing pairing and the filter
 * may fork on it (storage, not forked already, not itself the other
 * hypothesis, enough sightings to compare the two by). */
static int mh_should_fork(const ekfslam_t *ekf, int ns)
{
    if (ekf->alt == 0 || ekf->mh_forbid || ekf->mh_left > 0U || ekf->cfg.mh_frames == 0U) {
        return 0;
    }
    const ekfslam_scratch_t *sc = &ekf->scratch;
    int closing = 0;
    uint32_t n_cand = 0U;
    for (int i = 0; i < ns; ++i) {
        n_cand += sc->cand_begin[i + 1] > sc->cand_begin[i] ? 1U : 0U;
        closing |= sc->assign[i] >= 0 && sc->closure[sc->assign[i]];
    }
    return closing && n_cand >= ekf->cfg.mh_min_sightings;
}

/* The other hypothesis: this filter as it is before the frame's updates
 * (its association is redone without loop-closing candidates). Its new
 * landmarks get identities this one cannot reach in mh_frames updates,
 * so that an identity never names two landmarks, whichever is kept. */
static void mh_fork(ekfslam_t *ekf, const sighting_t *z, int ns, double max_range_m)
{
    ekfslam_t *alt = ekf->alt;
    *alt = *ekf;
    alt->alt = 0;
    alt->mh_forbid = 1U;
    alt->mh_left = 0U;
    alt->next_id = ekf->next_id + (ekf->cfg.mh_frames + 1U) * (uint32_t)COSLAM_MAX_SIGHTINGS;
    if (alt->next_id == 0U) {
        alt->next_id = 1U;
    }
    (void)update_body(alt, z, ns, max_range_m, COSLAM_OK);
    ekf->mh_sum = ekf->frame_score;
    ekf->mh_sum_alt = alt->frame_score;
    ekf->mh_left = ekf->cfg.mh_frames;
    ekf->ctr.mh_forks++;
}

/* mh_frames updates after the fork: keep the hypothesis whose frames
 * scored higher. Going back to the other one keeps this filter's
 * configuration, counters, storage and view. */
static void mh_decide(ekfslam_t *ekf)
{
    ekf->mh_left = 0U;
    if (ekf->mh_sum >= ekf->mh_sum_alt) {
        return;
    }
    ekfslam_t *alt = ekf->alt;
    const ekfslam_config_t cfg = ekf->cfg;
    const ekfslam_counters_t ctr = ekf->ctr;
    const view_profile_t *view = ekf->view;
    *ekf = *alt;
    ekf->cfg = cfg;
    ekf->ctr = ctr;
    ekf->ctr.mh_reverted++;
    ekf->alt = alt;
    ekf->view = view;
    ekf->mh_forbid = 0U;
    ekf->mh_left = 0U;
}

/* A change from outside (a merge, a landmark added or removed) while a
 * fork runs: the fork ends keeping this hypothesis, the one the caller has
 * been reading (its landmark indices stay valid). */
static void mh_end_early(ekfslam_t *ekf)
{
    if (ekf->mh_left > 0U) {
        ekf->mh_left = 0U;
        ekf->ctr.mh_decided_early++;
    }
}

void ekfslam_set_alt(ekfslam_t *ekf, ekfslam_t *alt)
{
    COSLAM_ASSERT(ekf != 0 && alt != ekf);
    ekf->alt = alt;
    ekf->mh_left = 0U;
}

coslam_status_t ekfslam_predict(ekfslam_t *ekf, odo_increment_t u)
{
    COSLAM_ASSERT(ekf != 0);
    const coslam_status_t r = predict_one(ekf, u);
    if (ekf->mh_left > 0U) {
        (void)predict_one(ekf->alt, u);
    }
    return r;
}

coslam_status_t ekfslam_add_landmark_body(ekfslam_t *ekf, point2_t m_body, cov2_t cov_body,
                                          const ekfslam_meta_t *meta)
{
    COSLAM_ASSERT(ekf != 0);
    mh_end_early(ekf);
    return add_landmark_body(ekf, m_body, cov_body, meta);
}

void ekfslam_remove_landmark(ekfslam_t *ekf, uint16_t j)
{
    COSLAM_ASSERT(ekf != 0 && j < ekf->n_lm);
    mh_end_early(ekf);
    if (!ekf->lm_dead[j]) {
        ekf->lm_dead[j] = 1U;
        ekf->n_dead++;
    }
    cekf_end_phase(ekf); /* pending rows stay pending (pend_remove) */
    dead_flush(ekf);     /* j with the filter's own dead, if any */
}

coslam_status_t ekfslam_update(ekfslam_t *ekf, const sighting_t *z_in, int n_in)
{
    COSLAM_ASSERT(ekf != 0 && (z_in != 0 || n_in == 0));
    if (ekf->merging) {
        ekf->view = 0; /* the frame's view goes with the frame */
        return COSLAM_E_MERGE_BUSY; /* a merge in parts runs on the state as it was */
    }
    const int forked = ekf->mh_left > 0U;
    if (forked) {
        ekf->alt->view = ekf->view;
        (void)update_frame(ekf->alt, z_in, n_in);
    }
    const coslam_status_t r = update_frame(ekf, z_in, n_in);
    if (forked) {
        ekf->mh_sum += ekf->frame_score;
        ekf->mh_sum_alt += ekf->alt->frame_score;
        if (--ekf->mh_left == 0U) {
            mh_decide(ekf);
        }
    }
    return r;
}

static coslam_status_t update_frame(ekfslam_t *ekf, const sighting_t *z_in, int n_in)
{
    const slam_params_t *sp = &ekf->cfg.slam;
    coslam_status_t result = COSLAM_OK;
    sighting_t z[COSLAM_MAX_SIGHTINGS];
    int ns = 0;
    double max_range_m = sp->sensor_max_range_m;
    for (int i = 0; i < n_in; ++i) {
        if (!sighting_is_plausible(&z_in[i], sp)) {
            ekf->ctr.rejected_sightings++;
            if (result == COSLAM_OK) {
                result = COSLAM_E_NUMERIC;
            }
            continue;
        }
        if (ns >= COSLAM_MAX_SIGHTINGS) {
            ekf->ctr.sighting_capacity_drops++;
            result = COSLAM_E_CAPACITY;
            continue;
        }
        z[ns] = z_in[i];
        if (z[ns].range_m > max_range_m) {
            max_range_m = z[ns].range_m;
        }
        ++ns;
    }
    ekf->ctr.updates++;
    cekf_prepare(ekf, max_range_m);
    return update_body(ekf, z, ns, max_range_m, result);
}

/* The frame after its sightings were checked (update_frame): association,
 * the updates, misses and new landmarks. Also the other hypothesis's
 * first frame (mh_fork), on the state as it was before this one. */
static coslam_status_t update_body(ekfslam_t *ekf, const sighting_t *z, int ns, double max_range_m,
                                   coslam_status_t result)
{
    const slam_params_t *sp = &ekf->cfg.slam;
    ekfslam_scratch_t *sc = &ekf->scratch;
    for (int i = 0; i < ns; ++i) {
        sc->n_near[i] = 0U;
    }

    /* 1-2. expectations and gated, likelihood-ranked candidate pairs */
    const pose2_t pose = robot_pose(ekf);
    const int jcbb = ekf->cfg.assoc == EKFSLAM_ASSOC_JCBB;
    int n_pairs = 0;
    for (uint16_t j = 0; j < ekf->n_lm; ++j) {
        sc->near[j] = 0;
        sc->matched[j] = 0;
        if (in_local(ekf) && ekf->cekf.slot[j] < 0) {
            continue; /* passive: out of reach (cekf_prepare) */
        }
        if (ekf->lm_dead[j]) {
            continue; /* removed in this local phase (remove_landmark) */
        }
        const int a = 3 + 2 * j;
        const double dx = ekf->x[a] - pose.x;
        const double dy = ekf->x[a + 1] - pose.y;
        const double reach = max_range_m + 3.0 * sqrt(P_(ekf, a, a) + P_(ekf, a + 1, a + 1) + P_(ekf, 0, 0) +
                                                      P_(ekf, 1, 1)) + 0.5;
        if (dx * dx + dy * dy > reach * reach) {
            continue;
        }
        if (expect_landmark(ekf, j, &sc->expect[j]) != COSLAM_OK) {
            ekf->ctr.numeric_faults++;
            continue;
        }
        sc->near[j] = 1;
        /* the hypothesis without the revisit (mh_frames): no loop-closing candidate */
        const int forbidden = ekf->mh_forbid && pair_is_closure(ekf, j);
        for (int i = 0; i < ns; ++i) {
            if (z[i].signature != ekf->meta[j].signature || forbidden) {
                continue;
            }
            const double d2 = landmark_mahalanobis2(&sc->expect[j], z[i]);
            const double ll = landmark_log_lik(&sc->expect[j], d2);
            /* JCBB: every pairing inside the gate is a candidate, also one
             * alone less likely than a new landmark (a vague prediction):
             * JCBB scores hypotheses jointly against p0 itself, and with
             * the pose fixed by the frame's other pairings this one can be
             * likely. Such a weak pairing is not a competing reading of
             * the sighting in the ambiguity test (jcbb_associate). */
            const assoc_class_t cls = assoc_classify(sp, d2, jcbb ? (double)INFINITY : ll);
            if (cls == ASSOC_ADMISSIBLE) {
                assoc_pair_t *pr = &sc->pairs[n_pairs++];
                pr->score = ll;
                pr->sighting = i;
                pr->landmark = j;
            } else if (cls == ASSOC_NEAR && sc->n_near[i] < UINT8_MAX) {
                sc->n_near[i]++;
            }
        }
    }
    ekf->frame_score = 0.0;
    if (jcbb) {
        jcbb_associate(ekf, z, ns, n_pairs);
        ekf->frame_score = frame_score(ekf, ns);
    } else {
        assoc_greedy(sc->pairs, n_pairs, ns, sc->assign);
        for (int i = 0; i < ns; ++i) {
            sc->held[i] = 0U;
        }
    }
    /* decide now which unpaired sightings start landmarks (needs the pairs) */
    uint8_t make_new[COSLAM_MAX_SIGHTINGS];
    for (int i = 0; i < ns; ++i) {
        make_new[i] = sc->assign[i] < 0 && !sc->held[i] &&
                      assoc_unpaired_is_new(sc->pairs, n_pairs, i, sc->assign, ns, sc->n_near);
    }
    if (jcbb && mh_should_fork(ekf, ns)) {
        mh_fork(ekf, z, ns, max_range_m); /* before this frame changes the state */
    }

    /* 3. sequential updates, relinearised at the current state; a
     * loop-closing pairing whose bearing's second-order term, about
     * (s / r)^2 for an offset standard deviation s at range r, exceeds the
     * bearing's standard deviation is iterated (iterate_linearisation) */
    const double iekf_spread = sqrt(sqrt(sp->noise.bearing_var_rad2));
    int n_updated = 0;
    double d2_sum = 0.0;
    for (int i = 0; i < ns; ++i) {
        const int32_t j = sc->assign[i];
        if (j < 0) {
            continue;
        }
        /* a revisit's pairing relinearised (iterate_linearisation): its
         * prior offset is uncertain against the range */
        if (ekf->cfg.iekf_max_iters > 0U) {
            batch_flush(ekf); /* pair_spread and the iteration read P */
        }
        const int closing = pair_is_closure(ekf, j); /* last_seen and the frame's S: the same after the update */
        const int iterate = ekf->cfg.iekf_max_iters > 0U && closing && pair_spread(ekf, j) > iekf_spread;
        double d2 = 0.0;
        if (update_one(ekf, (uint16_t)j, z[i], iterate, &d2) == COSLAM_OK) {
            ++n_updated;
            d2_sum += d2;
            ekfslam_meta_t *m = &ekf->meta[j];
            if (!closing && exist_confirmed(m->exist, ekf->lm_confirmed_once[j], sp) &&
                landmark_miss_would_count(sp, ekf->view, &sc->expect[j])) {
                ekf->ctr.view_pairs++; /* from the frame's prediction, as the misses below */
            }
            m->last_seen = ekf->ctr.updates;
            exist_hit(&m->exist, sp);
            if (m->n_obs < UINT16_MAX) {
                m->n_obs++;
            }
        }
        sc->matched[j] = 1;
    }
    batch_flush(ekf);
    cekf_spread(ekf, (double)n_updated * local_update_madds(ekf), 0);
    /* Innovation monitor (Bar-Shalom, Li and Kirubarajan 2001, 5.4 and
     * 11.7: the innovation sequence tests the filter's consistency, and
     * process noise is raised when it fails). r = sum d^2 / (2 n) is 1 on
     * average for a consistent filter; its running average m (weight 0.2,
     * about 9 frames) exceeds 3 with probability 1e-4 per frame when n = 1
     * (Monte Carlo of chi^2(2 n) / (2 n); 99.9 % point 2.5, 99 % 2.0) and
     * never in 1e6 frames for n >= 2. Above the threshold the pose's
     * covariance (the part the sightings test most directly) is scaled by
     * m / threshold, at most 4: adding (lambda - 1) P_rr to P_rr keeps P
     * positive semi-definite and is process noise, which the compressed
     * EKF carries as it carries the prediction's (pose rows only, always
     * active). Cause seen on MRCLAM Dataset 1 (robot 5 after its merges,
     * docs/map-merge.md): a pose held too firmly against a close landmark
     * while turning; the innovations grew for 3 s before the heading left. */
    if (n_updated > 0 && isfinite(d2_sum)) {
        ekf->nis_avg = 0.8 * ekf->nis_avg + 0.2 * d2_sum / (2.0 * n_updated);
        if (ekf->cfg.nis_inflate > 0.0 && ekf->nis_avg > ekf->cfg.nis_inflate) {
            double lam = ekf->nis_avg / ekf->cfg.nis_inflate;
            lam = lam > 4.0 ? 4.0 : lam;
            for (int r = 0; r < 3; ++r) {
                for (int q = 0; q < 3; ++q) {
                    P_(ekf, r, q) *= lam;
                }
            }
            ekf->ctr.nis_inflations++;
        }
    }

    /* 4. negative evidence, highest index first (removal swaps in the last) */
    for (int j = (int)ekf->n_lm - 1; j >= 0; --j) {
        if (!sc->near[j] || sc->matched[j]) {
            continue;
        }
        const lm_expect_t *ep = &sc->expect[j];
        if (!landmark_should_be_seen(sp, ep->zhat)) {
            continue;
        }
        if (landmark_hidden(ekf->view, ep)) {
            ekf->ctr.misses_hidden++; /* behind an obstacle the laser saw: not missed */
            continue;
        }
        if (held_revisit_of(sc, ns, j)) {
            /* a sighting held back as a possible revisit of it: the frame
             * does not say it is gone (without this, at the paper camera's
             * miss weight the old map died in the frames before a revisit
             * was recognised) */
            ekf->ctr.misses_held++;
            continue;
        }
        const int certain = landmark_miss_is_certain(sp, ep);
        if (certain && exist_confirmed(ekf->meta[j].exist, ekf->lm_confirmed_once[j], sp)) {
            ekf->ctr.view_misses++;
        }
        if (exist_miss(&ekf->meta[j].exist, &ekf->lm_confirmed_once[j], certain, sp)) {
            remove_landmark(ekf, (uint16_t)j);
            ekf->ctr.landmarks_removed++;
        }
    }

    /* 5. new landmarks: the sighting in Cartesian form in the robot frame */
    for (int i = 0; i < ns; ++i) {
        if (!make_new[i]) {
            continue;
        }
        const pose2_t origin = {0.0, 0.0, 0.0};
        double gz[2][2];
        observe_inverse_jacobians(origin, z[i], 0, gz);
        cov2_t cb = cov2_congruence(gz, observe_noise(sp, z[i].range_m));
        cb.xx += sp->noise.lm_init_var_m2;
        cb.yy += sp->noise.lm_init_var_m2;
        ekfslam_meta_t meta;
        meta.id = ekf->next_id; /* committed below only if the add succeeds */
        meta.exist = sp->exist_init;
        meta.n_obs = 1;
        meta.src_mask = (uint16_t)(1U << ekf->cfg.robot_id);
        meta.signature = z[i].signature;
        const coslam_status_t st = add_landmark_body(ekf, observe_inverse(origin, z[i]), cb, &meta);
        if (st == COSLAM_OK) {
            (void)ekfslam_new_id(ekf);
            ekf->ctr.landmarks_added++;
        } else if (st == COSLAM_E_CAPACITY) {
            result = COSLAM_E_CAPACITY;
        }
    }
    cekf_drift(ekf); /* theta moved: x_now's sums */
    dead_flush(ekf); /* the phase this frame's start ended, if no other began */
    ekf->view = 0; /* one frame's */
    return result;
}

void ekfslam_set_view(ekfslam_t *ekf, const view_profile_t *v)
{
    COSLAM_ASSERT(ekf != 0);
    ekf->view = v != 0 && v->valid ? v : 0;
}

/* Jacobian of rel = R^T (m_j - p) w.r.t. (x, y, theta, m_jx, m_jy). */
static void relative_jacobian(const ekfslam_t *ekf, uint16_t j, double jac[2][5], point2_t *rel)
{
    const pose2_t pose = robot_pose(ekf);
    const point2_t m = ekfslam_landmark_mean(ekf, j);
    const double c = cos(pose.theta);
    const double s = sin(pose.theta);
    const double dx = m.x - pose.x;
    const double dy = m.y - pose.y;
    jac[0][0] = -c;
    jac[0][1] = -s;
    jac[0][2] = -s * dx + c * dy;
    jac[0][3] = c;
    jac[0][4] = s;
    jac[1][0] = s;
    jac[1][1] = -c;
    jac[1][2] = -c * dx - s * dy;
    jac[1][3] = -s;
    jac[1][4] = c;
    if (rel != 0) {
        rel->x = c * dx + s * dy;
        rel->y = -s * dx + c * dy;
    }
}

/* Cov(R^T (m - p)) with the pose-landmark cross-covariance: J [P_pp P_pm;
 * P_mp P_mm] J^T, J = [d rel / d pose, R^T]. */
static cov2_t landmark_relative_cov(const ekfslam_t *ekf, uint16_t j)
{
    const int a = 3 + 2 * j;
    double jac[2][5];
    relative_jacobian(ekf, j, jac, 0);
    const int idx[5] = {0, 1, 2, a, a + 1};
    double o[2][2] = {{0.0, 0.0}, {0.0, 0.0}};
    for (int r1 = 0; r1 < 5; ++r1) {
        for (int r2 = 0; r2 < 5; ++r2) {
            const double pv = p_now(ekf, idx[r1], idx[r2]);
            for (int q1 = 0; q1 < 2; ++q1) {
                for (int q2 = 0; q2 < 2; ++q2) {
                    o[q1][q2] += jac[q1][r1] * pv * jac[q2][r2];
                }
            }
        }
    }
    return cov2_make(o[0][0], 0.5 * (o[0][1] + o[1][0]), o[1][1]);
}

void ekfslam_landmark_relative(const ekfslam_t *ekf, uint16_t j, point2_t *mean_body, cov2_t *cov_body)
{
    COSLAM_ASSERT(j < ekf->n_lm);
    double jac[2][5];
    relative_jacobian(ekf, j, jac, mean_body);
    *cov_body = landmark_relative_cov(ekf, j);
}

/* Scalar EKF update z = sum_q h[q] x[idx[q]] + v (linearised) with
 * innovation nu and noise variance r, over every active state, symmetric
 * Joseph form. O(D^2). */
static coslam_status_t scalar_update(ekfslam_t *ekf, const int *idx, const double *h, int nh, double nu, double r)
{
    const int n_act = n_active(ekf);
    double(*pht)[2] = ekf->scratch.pht;
    double(*k)[2] = ekf->scratch.k;
    for (int kk = 0; kk < n_act; ++kk) {
        const int row = active_idx(ekf, kk);
        double acc = 0.0;
        for (int q = 0; q < nh; ++q) {
            acc += P_(ekf, row, idx[q]) * h[q];
        }
        pht[kk][0] = acc;
    }
    double s = r;
    for (int q = 0; q < nh; ++q) {
        double acc = 0.0;
        for (int q2 = 0; q2 < nh; ++q2) {
            acc += P_(ekf, idx[q], idx[q2]) * h[q2];
        }
        s += h[q] * acc;
    }
    if (!(s > 0.0) || !isfinite(s) || !isfinite(nu)) {
        ekf->ctr.numeric_faults++;
        return COSLAM_E_NOT_PD;
    }
    for (int kk = 0; kk < n_act; ++kk) {
        k[kk][0] = pht[kk][0] / s;
        ekf->x[active_idx(ekf, kk)] += k[kk][0] * nu;
    }
    ekf->x[2] = angle_wrap(ekf->x[2]);
    for (int k1 = 0; k1 < n_act; ++k1) {
        const int row = active_idx(ekf, k1);
        for (int k2 = k1; k2 < n_act; ++k2) {
            const int col = active_idx(ekf, k2);
            /* P - K Ph^T - Ph K^T + K s K^T */
            const double delta = k[k1][0] * pht[k2][0] + pht[k1][0] * k[k2][0] - k[k1][0] * s * k[k2][0];
            const double val = P_(ekf, row, col) - delta;
            P_(ekf, row, col) = val;
            P_(ekf, col, row) = val;
        }
    }
    return COSLAM_OK;
}

/* ---- A merge's updates together -----------------------------------------
 *
 * A merge updates the whole state once per direction of information of
 * each duplicate (ekfslam_merge_observe: two scalar updates, each a rank-1
 * change P -= w w^T with w = P h / sqrt(s)). Applied one at a time, each
 * walks the whole of P: at 1,024 landmarks, 33 MB per update, and 222 of
 * them for one message took 1.4 s. So, as for a frame's pairings in a local
 * phase, the columns w_t are kept (in cekf.phi, free while merging) and
 * applied together (merge_flush), up to cfg.merge_batch (at most
 * EKF_MERGE_BATCH) at a time; what an
 * update reads before then - the rows of P that h touches, the entries of
 * S - is the stored value less the pending columns' share (merge_corr, and
 * p_final for every other reader). x changes at once, so each update is
 * linearised where the sequential EKF would linearise it: the same updates
 * in another order of the sums, equal up to rounding. Where cekf.phi holds
 * fewer than two columns of the state (no compressed EKF compiled in) the
 * update is applied at once, as before. Columns are pending only between
 * ekfslam_merge_begin and _end: ekfslam_merge_add and _end apply them (so
 * do ekfslam_sync and everything built on it), the readers add their
 * share; the filter's steps never see any. */
/* Active position of state index r while merging (tau after the state). */
static int merge_pos(const ekfslam_t *ekf, int r)
{
    const int d = dim(ekf);
    return r < d ? r : d + (r - TAU_);
}

/* Columns the merge may keep pending at the present size of the state. */
static int merge_cap(const ekfslam_t *ekf)
{
    if (COSLAM_EKF_MAX_ACTIVE == 0) {
        return 0; /* no phi buffer: the compiler drops the batched path */
    }
    long cap = (long)ADIM_ * ADIM_ / n_active(ekf);
    if (cap > (long)ekf->cfg.merge_batch) {
        cap = (long)ekf->cfg.merge_batch;
    }
    return cap < EKF_MERGE_BATCH ? (int)cap : EKF_MERGE_BATCH;
}

/* The pending columns' share of P(r, c). */
static double merge_corr(const ekfslam_t *ekf, int r, int c)
{
    const int pr = merge_pos(ekf, r);
    const int pc = merge_pos(ekf, c);
    if ((pr < pc ? pr : pc) < ekf->merge_flush_r0) {
        return 0.0; /* a flush in parts has applied the columns there already */
    }
    const long len = ekf->merge_len;
    const double *w = ekf->cekf.phi;
    double acc = 0.0;
    for (int t = 0; t < ekf->merge_bn; ++t) {
        acc += w[t * len + pr] * w[t * len + pc];
    }
    return acc;
}

/* P -= sum_t w_t w_t^T over the active positions (tau after the state),
 * in tiles of EKF_TILE rows from merge_flush_r0 on until about `budget`
 * multiply-adds are spent (the tile that crosses it is finished; 0: all).
 * Returns the multiply-adds spent (a tile's: its rows times the columns
 * from its first row on times the columns pending). Until the last tile
 * the columns stay pending and merge_flush_r0 says how far they are
 * applied (merge_corr). */
static double merge_flush_part(ekfslam_t *ekf, double budget)
{
    if (ekf->merge_bn == 0) {
        return 0.0;
    }
    const sym_map_t map = {0, dim(ekf), TAU_};
    const int n = ekf->merge_len;
    double spent = 0.0;
    int r0 = ekf->merge_flush_r0;
    while (r0 < n && (budget <= 0.0 || spent < budget)) {
        batch_sym_update(ekf->p, D_, &map, n, ekf->cekf.phi, ekf->cekf.phi, n, ekf->merge_bn, -1.0, r0,
                         r0 + EKF_TILE);
        spent += (double)EKF_TILE * (double)(n - r0) * (double)ekf->merge_bn;
        r0 += EKF_TILE;
    }
    if (r0 >= n) {
        ekf->merge_bn = 0;
        ekf->merge_flush_r0 = 0;
    } else {
        ekf->merge_flush_r0 = r0;
    }
    return spent;
}

static void merge_flush(ekfslam_t *ekf)
{
    (void)merge_flush_part(ekf, 0.0);
}

int ekfslam_merge_room(const ekfslam_t *ekf)
{
    const int cap = merge_cap(ekf);
    if (cap < 2) {
        return INT32_MAX; /* each update applied at once: nothing pends */
    }
    return ekf->merge_flush_r0 > 0 ? 0 : cap - ekf->merge_bn;
}

int ekfslam_merge_flush_run(ekfslam_t *ekf, double budget, double *spent)
{
    const double s = merge_flush_part(ekf, budget);
    if (spent != 0) {
        *spent += s;
    }
    return ekf->merge_bn == 0;
}

/* The merge's scalar update z = h^T x[idx] + v (innovation nu, noise
 * variance r): x at once, P's change kept as the column w = P h / sqrt(s). */
static coslam_status_t merge_scalar_update(ekfslam_t *ekf, const int *idx, const double *h, int nh, double nu,
                                           double r)
{
    const int n = n_active(ekf);
    const int cap = merge_cap(ekf);
    if (cap < 2) {
        return scalar_update(ekf, idx, h, nh, nu, r);
    }
    if (ekf->merge_flush_r0 > 0 || (ekf->merge_bn > 0 && ekf->merge_len != n)) {
        merge_flush(ekf); /* the rest of a flush in parts, or a resized state */
    }
    ekf->merge_len = n;
    const long len = n;
    double *restrict ph = &ekf->cekf.phi[ekf->merge_bn * len];
    /* P h from the rows of P that h reads (P is symmetric) */
    const int d = dim(ekf);
    for (int k = 0; k < n; ++k) {
        ph[k] = 0.0;
    }
    for (int q = 0; q < nh; ++q) {
        const double *row = &ekf->p[(long)idx[q] * D_];
        const double hq = h[q];
        for (int k = 0; k < d; ++k) {
            ph[k] += hq * row[k];
        }
        for (int k = d; k < n; ++k) {
            ph[k] += hq * row[TAU_ + (k - d)];
        }
    }
    /* less the pending columns' share: sum_t w_t (w_t^T h) */
    const double *w = ekf->cekf.phi;
    for (int t = 0; t < ekf->merge_bn; ++t) {
        const double *wt = &w[t * len];
        double g = 0.0;
        for (int q = 0; q < nh; ++q) {
            g += wt[merge_pos(ekf, idx[q])] * h[q];
        }
        for (int k = 0; k < n; ++k) {
            ph[k] -= g * wt[k];
        }
    }
    double sv = r;
    for (int q = 0; q < nh; ++q) {
        sv += h[q] * ph[merge_pos(ekf, idx[q])];
    }
    if (!(sv > 0.0) || !isfinite(sv) || !isfinite(nu)) {
        ekf->ctr.numeric_faults++;
        return COSLAM_E_NOT_PD;
    }
    const double gain = nu / sv;
    const double scale = 1.0 / sqrt(sv);
    for (int k = 0; k < n; ++k) {
        ekf->x[active_idx(ekf, k)] += ph[k] * gain;
        ph[k] *= scale;
    }
    ekf->x[2] = angle_wrap(ekf->x[2]);
    if (++ekf->merge_bn == cap) {
        merge_flush(ekf);
    }
    return COSLAM_OK;
}

/* Unit eigenvector of a symmetric 2x2 for eigenvalue lam (axis e if a * I). */
static void eigvec2(cov2_t a, double lam, int e, double *vx, double *vy)
{
    double x = a.xy;
    double y = lam - a.xx;
    const double ux = lam - a.yy;
    const double uy = a.xy;
    if (ux * ux + uy * uy > x * x + y * y) {
        x = ux;
        y = uy;
    }
    const double n = sqrt(x * x + y * y);
    if (!(n > 0.0)) {
        *vx = e == 0 ? 1.0 : 0.0;
        *vy = e == 0 ? 0.0 : 1.0;
        return;
    }
    *vx = x / n;
    *vy = y / n;
}

coslam_status_t ekfslam_merge_begin(ekfslam_t *ekf, const cov3_t *t_cov)
{
    if (ekf->merging) {
        return COSLAM_E_ARG;
    }
    if (t_cov != 0 && !cov3_is_finite(*t_cov)) {
        return COSLAM_E_NUMERIC;
    }
    mh_end_early(ekf); /* the merge's pairings were read from this hypothesis */
    ekfslam_sync(ekf); /* the merge runs on the whole state */
    const int d = dim(ekf);
    for (int q = 0; q < 3; ++q) {
        ekf->x[TAU_ + q] = 0.0;
        for (int col = 0; col < d; ++col) {
            P_(ekf, TAU_ + q, col) = 0.0;
            P_(ekf, col, TAU_ + q) = 0.0;
        }
        for (int q2 = 0; q2 < 3; ++q2) {
            P_(ekf, TAU_ + q, TAU_ + q2) = t_cov != 0 ? t_cov->m[q][q2] : 0.0;
        }
    }
    ekf->merging = 1U;
    return COSLAM_OK;
}

void ekfslam_merge_end(ekfslam_t *ekf)
{
    merge_flush(ekf);
    /* marginalising tau out of a Gaussian = forgetting its rows and columns */
    ekf->merging = 0U;
}

static pose2_t merge_t_now(const ekfslam_t *ekf, pose2_t t_hat)
{
    pose2_t t = t_hat;
    t.x += ekf->x[TAU_];
    t.y += ekf->x[TAU_ + 1];
    t.theta = angle_wrap(t.theta + ekf->x[TAU_ + 2]);
    return t;
}

coslam_status_t ekfslam_merge_observe(ekfslam_t *ekf, uint16_t j, pose2_t t_hat, point2_t rel_other, cov2_t info)
{
    COSLAM_ASSERT(j < ekf->n_lm);
    if (!ekf->merging) {
        return COSLAM_E_ARG;
    }
    if (!cov2_is_finite(info)) {
        ekf->ctr.numeric_faults++;
        return COSLAM_E_NUMERIC;
    }
    const int a = 3 + 2 * j;
    const int idx[8] = {0, 1, 2, a, a + 1, TAU_, TAU_ + 1, TAU_ + 2};
    double lmin;
    double lmax;
    cov2_eigenvalues(info, &lmin, &lmax);
    const double lam[2] = {lmax, lmin};
    for (int e = 0; e < 2; ++e) {
        if (!(lam[e] > 1e-12 * lmax) || !(lam[e] > 0.0)) {
            continue; /* no information in this direction */
        }
        double vx;
        double vy;
        eigvec2(info, lam[e], e, &vx, &vy);
        /* residual R^T (m_j - p) - (t (+) rel), and its Jacobian */
        double jac[2][5];
        point2_t rel_self;
        relative_jacobian(ekf, j, jac, &rel_self);
        const pose2_t t = merge_t_now(ekf, t_hat);
        const point2_t in_body = pose2_apply(t, rel_other);
        double jt[2][3];
        pose2_apply_jacobians(t, rel_other, jt, 0);
        double h[8];
        for (int q = 0; q < 5; ++q) {
            h[q] = vx * jac[0][q] + vy * jac[1][q];
        }
        for (int q = 0; q < 3; ++q) {
            h[5 + q] = -(vx * jt[0][q] + vy * jt[1][q]);
        }
        const double nu = -(vx * (rel_self.x - in_body.x) + vy * (rel_self.y - in_body.y));
        const coslam_status_t s = merge_scalar_update(ekf, idx, h, 8, nu, 1.0 / lam[e]);
        if (s != COSLAM_OK) {
            return s;
        }
    }
    return COSLAM_OK;
}

coslam_status_t ekfslam_merge_add(ekfslam_t *ekf, pose2_t t_hat, point2_t rel_other, cov2_t noise_other,
                                  const ekfslam_meta_t *meta)
{
    if (!ekf->merging) {
        return COSLAM_E_ARG;
    }
    merge_flush(ekf); /* add_landmark builds the new rows from whole rows of P */
    const pose2_t pose = robot_pose(ekf);
    const pose2_t t = merge_t_now(ekf, t_hat);
    const point2_t b = pose2_apply(t, rel_other);
    double gr[2][3];
    double gb[2][2];
    pose2_apply_jacobians(pose, b, gr, gb);
    double jt[2][3];
    double jrel[2][2];
    pose2_apply_jacobians(t, rel_other, jt, jrel);
    /* d m / d tau = R_pose J_t; noise: R_pose R_t noise R_t^T R_pose^T */
    double gt[2][3];
    for (int q = 0; q < 2; ++q) {
        for (int r = 0; r < 3; ++r) {
            gt[q][r] = gb[q][0] * jt[0][r] + gb[q][1] * jt[1][r];
        }
    }
    double rr[2][2];
    for (int q = 0; q < 2; ++q) {
        for (int r = 0; r < 2; ++r) {
            rr[q][r] = gb[q][0] * jrel[0][r] + gb[q][1] * jrel[1][r];
        }
    }
    return add_landmark(ekf, pose2_apply(pose, b), gr, gt, cov2_congruence(rr, noise_other), meta);
}

/* Stable insertion sort of state indices by `before` (exports are rare). */
static void sort_order(const ekfslam_t *ekf, uint16_t *order, int n,
                       int (*before)(const ekfslam_t *, uint16_t, uint16_t))
{
    for (int i = 1; i < n; ++i) {
        const uint16_t v = order[i];
        int k = i - 1;
        while (k >= 0 && before(ekf, v, order[k])) {
            order[k + 1] = order[k];
            --k;
        }
        order[k + 1] = v;
    }
}

static int more_observed(const ekfslam_t *ekf, uint16_t a, uint16_t b)
{
    return ekf->meta[a].n_obs > ekf->meta[b].n_obs;
}

static int smaller_id(const ekfslam_t *ekf, uint16_t a, uint16_t b)
{
    return ekf->meta[a].id < ekf->meta[b].id;
}

/* Confirmed landmarks in state order into `order`; their count. */
static int confirmed_order(const ekfslam_t *ekf, uint16_t *order)
{
    int n = 0;
    for (uint16_t j = 0; j < ekf->n_lm; ++j) {
        if (ekf->meta[j].exist >= ekf->cfg.slam.exist_confirm) {
            order[n++] = j;
        }
    }
    return n;
}

/* Landmarks order[0..n) into lm[0..n). */
static void export_fill(const ekfslam_t *ekf, map_landmark_t *lm, const uint16_t *order, int n)
{
    for (int i = 0; i < n; ++i) {
        const uint16_t j = order[i];
        map_landmark_t *o = &lm[i];
        ekfslam_landmark(ekf, j, &o->mean, &o->cov);
        o->cov_rel = landmark_relative_cov(ekf, j);
        /* rounding must not make an exported covariance indefinite: the
         * codec refuses such a message */
        o->cov = cov2_clamp_eigen(o->cov, 1e-12);
        o->cov_rel = cov2_clamp_eigen(o->cov_rel, 1e-12);
        o->id = ekf->meta[j].id;
        o->n_obs = ekf->meta[j].n_obs;
        o->src_mask = ekf->meta[j].src_mask;
        o->signature = ekf->meta[j].signature;
    }
}

/* The pose, and the confirmed landmarks, at most `cap` (the most observed,
 * state order breaking ties; the rest counted), by identity into lm; their
 * number. */
static coslam_status_t export_capped(ekfslam_t *ekf, pose2_t *pose, cov3_t *pose_cov, map_landmark_t *lm, int cap,
                                     uint16_t *n_out)
{
    ekfslam_sync(ekf);
    ekfslam_pose(ekf, pose, pose_cov);
    uint16_t *order = ekf->scratch.order;
    coslam_status_t result = COSLAM_OK;
    int n = confirmed_order(ekf, order);
    if (n > cap) {
        sort_order(ekf, order, n, more_observed);
        ekf->ctr.export_capacity_drops += (uint32_t)(n - cap);
        n = cap;
        result = COSLAM_E_CAPACITY;
    }
    sort_order(ekf, order, n, smaller_id);
    export_fill(ekf, lm, order, n);
    *n_out = (uint16_t)n;
    return result;
}

coslam_status_t ekfslam_export(ekfslam_t *ekf, map_estimate_t *out)
{
    /* more than a message carries (the cap follows the link, config.h):
     * the most observed landmarks go */
    return export_capped(ekf, &out->pose, &out->pose_cov, out->lm, COSLAM_MAX_MSG_LANDMARKS, &out->n_landmarks);
}

coslam_status_t ekfslam_export_whole(ekfslam_t *ekf, map_whole_t *out)
{
    return export_capped(ekf, &out->pose, &out->pose_cov, out->lm, COSLAM_MAX_LANDMARKS, &out->n_landmarks);
}
