#include "coslam/map_merge.h"

#include <math.h>
#include <string.h>

merge_config_t merge_config_default(void)
{
    merge_config_t c;
    c.gate_chi2 = 9.21;
    c.grid_cell_m = 1.0;
    c.transform_uncertainty = 1U;
    c.reweight_particles = 0U;
    c.min_obs = 1U;
    c.fuse_eff_pairs = 2.0;
    c.peer_speed_mps = 0.3;
    c.peer_turn_radps = 0.5;
    c.range_check_chi2 = 9.0;
    c.max_extent_m = 1000.0;
    c.min_var_m2 = 1e-6;
    c.max_var_m2 = 1e4;
    c.min_bearing_var_rad2 = 1e-8;
    c.max_bearing_var_rad2 = 0.25;
    c.check = 1U;
    c.refine_iters = 3U;
    c.refine_eff_pairs = 2.0;
    c.agree_z = 2.33;
    c.veto_looks = 5U;
    c.max_contradict_fraction = 0.3;
    c.ambiguous_chi2 = 25.0;
    c.unresolved_chi2 = 9.21;
    c.refute_sd_factor = 1.0;
    c.lost_sd_factor = 1.0;
    c.step_units = 524288U;
    return c;
}

void merge_session_init(merge_session_t *s)
{
    memset(s, 0, sizeof *s);
}

coslam_status_t merge_session_accept(merge_session_t *s, uint8_t sender, uint32_t seq)
{
    if (s == NULL || sender >= COSLAM_MAX_ROBOTS) {
        return COSLAM_E_ARG;
    }
    if (s->seen[sender]) {
        /* serial-number comparison: newer iff 0 < seq - last < 2^31 */
        const uint32_t diff = seq - s->last_seq[sender];
        if (diff != 0U && diff < 0x80000000U) {
            if (diff > MERGE_SEQ_MAX_JUMP) {
                s->rejected_jumps++;
                return COSLAM_E_MERGE_REPLAY;
            }
        } else {
            /* not newer: taken only as the end of a restarted sender's run
             * of older numbers (MERGE_SEQ_REBASE_RUN) */
            const uint32_t step = seq - s->run_seq[sender];
            const int continues = diff != 0U && s->run_n[sender] > 0U && step != 0U && step <= MERGE_SEQ_MAX_JUMP;
            if (!continues || s->run_n[sender] + 1U < MERGE_SEQ_REBASE_RUN ||
                s->last_seq[sender] - seq <= MERGE_SEQ_REBASE_MIN_BEHIND) {
                s->rejected_replays++;
                if (diff != 0U) {
                    s->run_n[sender] = continues ? (uint8_t)(s->run_n[sender] + 1U) : 1U;
                    s->run_seq[sender] = seq;
                }
                return COSLAM_E_MERGE_REPLAY;
            }
            s->rebased++;
        }
    }
    s->seen[sender] = 1U;
    s->last_seq[sender] = seq;
    s->run_n[sender] = 0U;
    s->merges++;
    return COSLAM_OK;
}

static int sighting_ok(const robot_sighting_t *z)
{
    return isfinite(z->range_m) && isfinite(z->bearing_rad) && isfinite(z->range_var_m2) &&
           isfinite(z->bearing_var_rad2);
}

coslam_status_t merge_relative_pose(const robot_sighting_t *s_o, const robot_sighting_t *o_s, pose2_t *t, cov3_t *cov)
{
    if (!sighting_ok(s_o) || !sighting_ok(o_s)) {
        return COSLAM_E_NUMERIC;
    }
    if (!(s_o->range_m > 0.0) || !(o_s->range_m > 0.0) || !(s_o->range_var_m2 > 0.0) ||
        !(o_s->range_var_m2 > 0.0) || !(s_o->bearing_var_rad2 > 0.0) || !(o_s->bearing_var_rad2 > 0.0)) {
        return COSLAM_E_ARG;
    }
    /* the range is measured twice: inverse-variance weighted mean */
    const double w1 = 1.0 / s_o->range_var_m2;
    const double w2 = 1.0 / o_s->range_var_m2;
    const double a1 = w1 / (w1 + w2);
    const double a2 = w2 / (w1 + w2);
    const double r = a1 * s_o->range_m + a2 * o_s->range_m;
    const double b1 = s_o->bearing_rad;
    const double c = cos(b1);
    const double s = sin(b1);
    t->x = r * c;
    t->y = r * s;
    t->theta = angle_wrap(b1 + COSLAM_PI - o_s->bearing_rad);
    /* J w.r.t. (r1, b1, r2, b2), then J diag(var) J^T */
    const double jac[3][4] = {
        {c * a1, -r * s, c * a2, 0.0},
        {s * a1, r * c, s * a2, 0.0},
        {0.0, 1.0, 0.0, -1.0},
    };
    const double var[4] = {s_o->range_var_m2, s_o->bearing_var_rad2, o_s->range_var_m2, o_s->bearing_var_rad2};
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            double acc = 0.0;
            for (int q = 0; q < 4; ++q) {
                acc += jac[i][q] * var[q] * jac[k][q];
            }
            cov->m[i][k] = acc;
        }
    }
    return COSLAM_OK;
}

void merge_compensate(pose2_t *t, cov3_t *cov, odo_increment_t u, const cov3_t *u_cov, double extra_var_m2)
{
    const pose2_t up = {u.dx, u.dy, u.dtheta};
    const pose2_t ui = pose2_inverse(up);
    double ja[3][3];
    double jb[3][3];
    pose2_compose_jacobians(ui, *t, ja, jb);
    /* d inverse(u) / d u */
    const double c = cos(u.dtheta);
    const double s = sin(u.dtheta);
    double jinv[3][3] = {
        {-c, -s, s * u.dx - c * u.dy},
        {s, -c, c * u.dx + s * u.dy},
        {0.0, 0.0, -1.0},
    };
    double ju[3][3];
    mat3_mul(ja, jinv, ju);
    cov3_t nc = cov3_congruence(jb, *cov);
    if (u_cov != 0) {
        nc = cov3_add(nc, cov3_congruence(ju, *u_cov));
    }
    nc.m[0][0] += extra_var_m2;
    nc.m[1][1] += extra_var_m2;
    *t = pose2_compose(ui, *t);
    *cov = nc;
}

/* A landmark at rel (covariance rel_cov) in the sender's body frame, moved
 * into the receiver's body frame by t: mean t (+) rel, covariance
 * R rel_cov R^T + J_T t_cov J_T^T (t_cov may be NULL: no transform term). */
static void body_landmark(pose2_t t, const cov3_t *t_cov, point2_t rel, cov2_t rel_cov, point2_t *mean, cov2_t *cov)
{
    const double c = cos(t.theta);
    const double s = sin(t.theta);
    double rot[2][2] = {{c, -s}, {s, c}};
    *mean = pose2_apply(t, rel);
    *cov = cov2_congruence(rot, rel_cov);
    if (t_cov != 0) {
        double jt[2][3];
        pose2_apply_jacobians(t, rel, jt, 0);
        cov3_t tc = *t_cov;
        *cov = cov2_add(*cov, cov2_from_3x3(jt, tc.m));
    }
}

/* Both axes of a 2x2 covariance inside [lo, hi]. */
static int cov2_axes_within(cov2_t c, double lo, double hi)
{
    const double half_tr = 0.5 * (c.xx + c.yy);
    const double d = sqrt(0.25 * (c.xx - c.yy) * (c.xx - c.yy) + c.xy * c.xy);
    return half_tr - d >= lo && half_tr + d <= hi;
}

coslam_status_t merge_transform_map(const map_estimate_t *in, pose2_t t, const cov3_t *t_cov,
                                    const merge_config_t *cfg, merge_body_map_t *out, merge_stats_t *stats)
{
    out->n = 0;
    out->t = t;
    out->t_cov = (t_cov != 0 && cfg->transform_uncertainty) ? *t_cov : cov3_zero();
    if (!pose2_is_finite(t) || !pose2_is_finite(in->pose) || (t_cov != 0 && !cov3_is_finite(*t_cov))) {
        return COSLAM_E_NUMERIC;
    }
    /* paper mode: the map-frame covariance rotated from the other's map
     * frame into self's body frame, nothing else (eq. 3 with R, not T) */
    const double fth = t.theta - in->pose.theta;
    double rot_f[2][2] = {{cos(fth), -sin(fth)}, {sin(fth), cos(fth)}};
    for (uint16_t i = 0; i < in->n_landmarks && i < COSLAM_MAX_MSG_LANDMARKS; ++i) {
        const map_landmark_t *l = &in->lm[i];
        if (l->n_obs < cfg->min_obs) {
            if (stats != 0) {
                stats->skipped++;
            }
            continue;
        }
        const point2_t rel = pose2_apply_inverse(in->pose, l->mean);
        point2_t mb;
        cov2_t cb;
        cov2_t rel_cov;
        if (cfg->transform_uncertainty) {
            rel_cov = l->cov_rel;
            body_landmark(t, t_cov, rel, rel_cov, &mb, &cb);
        } else {
            mb = pose2_apply(t, rel);
            cb = cov2_congruence(rot_f, l->cov);
            /* the same, expressed in the sender's body frame */
            const double cp = cos(in->pose.theta);
            const double sp = sin(in->pose.theta);
            double rpt[2][2] = {{cp, sp}, {-sp, cp}};
            rel_cov = cov2_congruence(rpt, l->cov);
        }
        if (!cov2_is_pd(cb)) {
            return COSLAM_E_MSG_COVARIANCE;
        }
        if (!cov2_axes_within(cb, 0.0, cfg->max_var_m2)) {
            /* a transform wide enough to spread a landmark beyond what any
             * map may carry (a sighting far less certain than a camera
             * gives): the whole message is refused, nothing is applied */
            out->n = 0;
            return COSLAM_E_MERGE_IMPLAUSIBLE;
        }
        const uint16_t k = out->n++;
        out->mean[k] = mb;
        out->cov[k] = cb;
        out->src_mask[k] = l->src_mask;
        out->n_obs[k] = l->n_obs;
        out->signature[k] = l->signature;
        out->id[k] = l->id;
        out->rel[k] = rel;
        out->rel_cov[k] = rel_cov;
    }
    return COSLAM_OK;
}

/* ---- fusion rules ------------------------------------------------------- */

coslam_status_t merge_fuse_kalman(point2_t a, cov2_t sa, point2_t b, cov2_t sb, point2_t *x, cov2_t *s)
{
    cov2_t inv;
    if (cov2_inverse(cov2_add(sa, sb), &inv) != COSLAM_OK) {
        return COSLAM_E_NOT_PD;
    }
    /* K = S_a (S_a + S_b)^-1 (eq. 5), S = S_a - K S_a (eq. 4) */
    const double k00 = sa.xx * inv.xx + sa.xy * inv.xy;
    const double k01 = sa.xx * inv.xy + sa.xy * inv.yy;
    const double k10 = sa.xy * inv.xx + sa.yy * inv.xy;
    const double k11 = sa.xy * inv.xy + sa.yy * inv.yy;
    const double dx = b.x - a.x;
    const double dy = b.y - a.y;
    x->x = a.x + k00 * dx + k01 * dy;
    x->y = a.y + k10 * dx + k11 * dy;
    const double sxx = sa.xx - (k00 * sa.xx + k01 * sa.xy);
    const double sxy = sa.xy - (k00 * sa.xy + k01 * sa.yy);
    const double syx = sa.xy - (k10 * sa.xx + k11 * sa.xy);
    const double syy = sa.yy - (k10 * sa.xy + k11 * sa.yy);
    *s = cov2_make(sxx, 0.5 * (sxy + syx), syy);
    return COSLAM_OK;
}

static double ci_det(cov2_t ia, cov2_t ib, double w)
{
    const cov2_t info = cov2_add(cov2_scale(ia, w), cov2_scale(ib, 1.0 - w));
    return 1.0 / cov2_det(info);
}

coslam_status_t merge_fuse_ci(point2_t a, cov2_t sa, point2_t b, cov2_t sb, point2_t *x, cov2_t *s, double *w_out)
{
    cov2_t ia;
    cov2_t ib;
    if (cov2_inverse(sa, &ia) != COSLAM_OK || cov2_inverse(sb, &ib) != COSLAM_OK) {
        return COSLAM_E_NOT_PD;
    }
    /* det of the fused covariance is unimodal in w: golden-section search */
    double lo = 0.0;
    double hi = 1.0;
    const double g = 0.6180339887498949;
    double m1 = hi - g * (hi - lo);
    double m2 = lo + g * (hi - lo);
    double f1 = ci_det(ia, ib, m1);
    double f2 = ci_det(ia, ib, m2);
    for (int it = 0; it < 60; ++it) {
        if (f1 < f2) {
            hi = m2;
            m2 = m1;
            f2 = f1;
            m1 = hi - g * (hi - lo);
            f1 = ci_det(ia, ib, m1);
        } else {
            lo = m1;
            m1 = m2;
            f1 = f2;
            m2 = lo + g * (hi - lo);
            f2 = ci_det(ia, ib, m2);
        }
    }
    double w = 0.5 * (lo + hi);
    /* the end points are candidates too (one estimate may dominate) */
    if (ci_det(ia, ib, 1.0) <= ci_det(ia, ib, w)) {
        w = 1.0;
    } else if (ci_det(ia, ib, 0.0) <= ci_det(ia, ib, w)) {
        w = 0.0;
    }
    const cov2_t info = cov2_add(cov2_scale(ia, w), cov2_scale(ib, 1.0 - w));
    cov2_t sf;
    if (cov2_inverse(info, &sf) != COSLAM_OK) {
        return COSLAM_E_NOT_PD;
    }
    const double ya = ia.xx * a.x + ia.xy * a.y;
    const double yb = ia.xy * a.x + ia.yy * a.y;
    const double za = ib.xx * b.x + ib.xy * b.y;
    const double zb = ib.xy * b.x + ib.yy * b.y;
    const double vx = w * ya + (1.0 - w) * za;
    const double vy = w * yb + (1.0 - w) * zb;
    x->x = sf.xx * vx + sf.xy * vy;
    x->y = sf.xy * vx + sf.yy * vy;
    *s = sf;
    if (w_out != 0) {
        *w_out = w;
    }
    return COSLAM_OK;
}

/* ---- the grid hash over the incoming body map --------------------------- */

/* Bucket of (cell, signature): every lookup wants one signature, so a
 * chain holds (collisions aside) only the landmarks it may visit; the
 * order within one (cell, signature) is the same as with any hash
 * (descending index: entries are prepended). */
static uint32_t cell_hash(int32_t cx, int32_t cy, uint8_t sig)
{
    const uint32_t h = ((uint32_t)cx * 73856093U) ^ ((uint32_t)cy * 19349663U) ^ ((uint32_t)sig * 83492791U);
    return h % (uint32_t)COSLAM_MERGE_GRID_BUCKETS;
}

static int32_t cell_of(double v, double cell)
{
    const double c = floor(v / cell);
    if (c > 1e9) {
        return 1000000000;
    }
    if (c < -1e9) {
        return -1000000000;
    }
    return (int32_t)c;
}

/*
 * The cell must be at least the largest distance at which two landmarks can
 * still pass the gate, or the 3x3 neighbourhood misses duplicates: with the
 * incoming covariances the largest, sqrt(gate * 2 lambda_max) covers an own
 * covariance as large as the incoming one. Never below grid_cell_m.
 */
static double grid_cell_size(const merge_body_map_t *bm, const merge_config_t *cfg, double gate_chi2)
{
    double lmax_all = 0.0;
    for (uint16_t i = 0; i < bm->n; ++i) {
        double lo;
        double hi;
        cov2_eigenvalues(bm->cov[i], &lo, &hi);
        lmax_all = hi > lmax_all ? hi : lmax_all;
    }
    const double reach = sqrt(gate_chi2 * 2.0 * lmax_all);
    return reach > cfg->grid_cell_m ? reach : cfg->grid_cell_m;
}

static void grid_build(merge_scratch_t *sc, const merge_body_map_t *bm, double cell)
{
    sc->cell_m = cell;
    for (int b = 0; b < COSLAM_MERGE_GRID_BUCKETS; ++b) {
        sc->bucket_head[b] = -1;
    }
    int32_t x_lo = INT32_MAX;
    int32_t x_hi = INT32_MIN;
    int32_t y_lo = INT32_MAX;
    int32_t y_hi = INT32_MIN;
    for (uint16_t i = 0; i < bm->n; ++i) {
        const int32_t cx = cell_of(bm->mean[i].x, cell);
        const int32_t cy = cell_of(bm->mean[i].y, cell);
        const uint32_t h = cell_hash(cx, cy, bm->signature[i]);
        sc->cell_x[i] = cx;
        sc->cell_y[i] = cy;
        sc->next[i] = sc->bucket_head[h];
        sc->bucket_head[h] = (int32_t)i;
        x_lo = cx < x_lo ? cx : x_lo;
        x_hi = cx > x_hi ? cx : x_hi;
        y_lo = cy < y_lo ? cy : y_lo;
        y_hi = cy > y_hi ? cy : y_hi;
    }
    /* the occupancy bitmap: bins of occ_bin cells covering the incoming
     * cells and one more on each side, each incoming bin dilated by one
     * (a neighbour cell is at most one bin away) */
    for (int b = 0; b < MERGE_OCC_BINS; ++b) {
        sc->occ[b] = 0U;
    }
    if (bm->n == 0) {
        sc->occ_bin = 0; /* nothing can pair */
        return;
    }
    const int64_t span_x = (int64_t)x_hi - x_lo + 3;
    const int64_t span_y = (int64_t)y_hi - y_lo + 3;
    const int64_t span = span_x > span_y ? span_x : span_y;
    const int64_t bin = (span + MERGE_OCC_BINS - 1) / MERGE_OCC_BINS;
    sc->occ_bin = bin > INT32_MAX ? INT32_MAX : (int32_t)bin;
    sc->occ_x0 = x_lo - 1;
    sc->occ_y0 = y_lo - 1;
    for (uint16_t i = 0; i < bm->n; ++i) {
        const int bx = (int)(((int64_t)sc->cell_x[i] - sc->occ_x0) / sc->occ_bin);
        const int by = (int)(((int64_t)sc->cell_y[i] - sc->occ_y0) / sc->occ_bin);
        for (int y = by - 1; y <= by + 1; ++y) {
            if (y < 0 || y >= MERGE_OCC_BINS) {
                continue;
            }
            for (int x = bx - 1; x <= bx + 1; ++x) {
                if (x >= 0 && x < MERGE_OCC_BINS) {
                    sc->occ[y] |= (uint64_t)1U << x;
                }
            }
        }
    }
}

/* 0 if no incoming landmark lies in the 3x3 cells around point q (so q
 * can pair with none): the occupancy bitmap of grid_build. */
static int grid_may_pair(const merge_scratch_t *sc, point2_t q)
{
    if (sc->occ_bin <= 0) {
        return 0;
    }
    const int64_t dx = (int64_t)cell_of(q.x, sc->cell_m) - sc->occ_x0;
    const int64_t dy = (int64_t)cell_of(q.y, sc->cell_m) - sc->occ_y0;
    const int64_t lim = (int64_t)sc->occ_bin * MERGE_OCC_BINS;
    if (dx < 0 || dy < 0 || dx >= lim || dy >= lim) {
        return 0;
    }
    /* 0 <= dx, dy < 2^32 (cells are clamped to +-1e9): the same quotient
     * in 32 bits, and none for bins of one cell (the 64-bit division was
     * a third of the merge's per own landmark time) */
    uint32_t bx = (uint32_t)dx;
    uint32_t by = (uint32_t)dy;
    if (sc->occ_bin > 1) {
        bx /= (uint32_t)sc->occ_bin;
        by /= (uint32_t)sc->occ_bin;
    }
    return (int)((sc->occ[by] >> bx) & 1U);
}

/* What box_may_pair needs: the scratch's bitmap and a particle's pose
 * with its cos and sin (the ones its landmarks are moved with). */
typedef struct {
    const merge_scratch_t *sc;
    pose2_t pose;
    double c;
    double s;
} own_box_ctx_t;

/*
 * grid_may_pair for a whole tree box at once (lm_tree_box_fn): NONE only
 * if no point of world box b, moved into the particle's body frame, can
 * pair; ALL only if every point can. The body box is the axis-aligned one
 * around the rotated box, widened by 1 mm plus 1e-9 of the coordinates'
 * size (the rounding of the rotation here and in pose2_apply_inverse_cs is
 * about 1e-16 of it); its cells span every cell a point inside can have
 * (floor and the clamp of cell_of are monotone), so its bins every bin a
 * point can fall in. Any occupied bin among them keeps the subtree; all of
 * them occupied, and none outside the bitmap, takes it whole. A box not
 * finite (or empty) is always looked into. The landmarks' means also lie
 * 0.5 m or more inside the box (lm_tree.h): a further margin, not relied
 * on.
 */
static int box_may_pair(const float b[4], void *ctx)
{
    const own_box_ctx_t *o = (const own_box_ctx_t *)ctx;
    const merge_scratch_t *sc = o->sc;
    if (sc->occ_bin <= 0) {
        return LM_TREE_BOX_NONE;
    }
    const double lx = (double)b[0];
    const double ly = (double)b[1];
    const double hx = (double)b[2];
    const double hy = (double)b[3];
    const double big = 1e30;
    if (!(lx <= hx && ly <= hy && fabs(lx) < big && fabs(ly) < big && fabs(hx) < big && fabs(hy) < big)) {
        return LM_TREE_BOX_SOME;
    }
    const point2_t mid = {0.5 * (lx + hx), 0.5 * (ly + hy)};
    const double ex = 0.5 * (hx - lx);
    const double ey = 0.5 * (hy - ly);
    const point2_t q = pose2_apply_inverse_cs(o->pose, o->c, o->s, mid);
    const double ac = fabs(o->c);
    const double as = fabs(o->s);
    const double slack =
        1e-3 + 1e-9 * (fabs(mid.x) + fabs(mid.y) + fabs(o->pose.x) + fabs(o->pose.y) + ex + ey);
    const double wx = ac * ex + as * ey + slack;
    const double wy = as * ex + ac * ey + slack;
    const int64_t lim = (int64_t)sc->occ_bin * MERGE_OCC_BINS;
    int64_t dx_lo = (int64_t)cell_of(q.x - wx, sc->cell_m) - sc->occ_x0;
    int64_t dx_hi = (int64_t)cell_of(q.x + wx, sc->cell_m) - sc->occ_x0;
    int64_t dy_lo = (int64_t)cell_of(q.y - wy, sc->cell_m) - sc->occ_y0;
    int64_t dy_hi = (int64_t)cell_of(q.y + wy, sc->cell_m) - sc->occ_y0;
    if (dx_hi < 0 || dy_hi < 0 || dx_lo >= lim || dy_lo >= lim) {
        return LM_TREE_BOX_NONE;
    }
    /* part of the box off the bitmap: some points there cannot pair */
    int all = dx_lo >= 0 && dy_lo >= 0 && dx_hi < lim && dy_hi < lim;
    dx_lo = dx_lo < 0 ? 0 : dx_lo;
    dy_lo = dy_lo < 0 ? 0 : dy_lo;
    dx_hi = dx_hi >= lim ? lim - 1 : dx_hi;
    dy_hi = dy_hi >= lim ? lim - 1 : dy_hi;
    /* 0 <= d < 2^32 as in grid_may_pair: 32-bit quotients, none for bins
     * of one cell */
    uint32_t bx_lo = (uint32_t)dx_lo;
    uint32_t bx_hi = (uint32_t)dx_hi;
    uint32_t by_lo = (uint32_t)dy_lo;
    uint32_t by_hi = (uint32_t)dy_hi;
    if (sc->occ_bin > 1) {
        const uint32_t bin = (uint32_t)sc->occ_bin;
        bx_lo /= bin;
        bx_hi /= bin;
        by_lo /= bin;
        by_hi /= bin;
    }
    const uint64_t mask = (~(uint64_t)0 << bx_lo) & (~(uint64_t)0 >> (MERGE_OCC_BINS - 1U - bx_hi));
    int some = 0;
    for (uint32_t y = by_lo; y <= by_hi; ++y) {
        const uint64_t hit = sc->occ[y] & mask;
        some |= hit != 0U;
        all &= hit == mask;
        if (some && !all) {
            return LM_TREE_BOX_SOME;
        }
    }
    return all ? LM_TREE_BOX_ALL : some ? LM_TREE_BOX_SOME : LM_TREE_BOX_NONE;
}

/* Max-heap on d2: the entry at root moved down within p[0..end-1]. The
 * greedy one-to-one selection needs the pairs sorted by d2 (heap sort), and
 * the full pair table keeps its nearest pairs in this heap (collect_pair). */
static void pair_sift(merge_pair_t *p, int root, int end)
{
    for (;;) {
        int child = 2 * root + 1;
        if (child >= end) {
            return;
        }
        if (child + 1 < end && p[child + 1].d2 > p[child].d2) {
            child++;
        }
        if (p[root].d2 >= p[child].d2) {
            return;
        }
        const merge_pair_t t = p[root];
        p[root] = p[child];
        p[child] = t;
        root = child;
    }
}

static void sort_pairs(merge_pair_t *p, int n)
{
    for (int start = n / 2 - 1; start >= 0; --start) {
        pair_sift(p, start, n);
    }
    for (int end = n - 1; end > 0; --end) {
        const merge_pair_t t = p[0];
        p[0] = p[end];
        p[end] = t;
        pair_sift(p, 0, end);
    }
}

/* Visit every incoming landmark of signature `sig` in the 3x3 grid cells
 * around point q (covariance q_cov) with squared Mahalanobis distance below
 * gate (on q_cov + S_in); the visitor gets `tag` as its j. The cell is wide
 * enough for the gate (grid_cell_size). */
typedef void (*grid_visit_fn)(merge_scratch_t *sc, int32_t j, int32_t i, double d2, void *ctx);

static void grid_gated_at(merge_scratch_t *sc, const merge_body_map_t *bm, point2_t q, cov2_t q_cov, uint8_t sig,
                          int32_t tag, double gate, grid_visit_fn visit, void *ctx)
{
    const int32_t cx = cell_of(q.x, sc->cell_m);
    const int32_t cy = cell_of(q.y, sc->cell_m);
    for (int32_t dx = -1; dx <= 1; ++dx) {
        for (int32_t dy = -1; dy <= 1; ++dy) {
            for (int32_t i = sc->bucket_head[cell_hash(cx + dx, cy + dy, sig)]; i >= 0; i = sc->next[i]) {
                double d2;
                if (sc->cell_x[i] != cx + dx || sc->cell_y[i] != cy + dy || bm->signature[i] != sig) {
                    continue;
                }
                /* d2 >= |v|^2 / lambda_max(S) >= |v|^2 / trace(S): most
                 * neighbours of other cells fail this without an inverse */
                const double vx = bm->mean[i].x - q.x;
                const double vy = bm->mean[i].y - q.y;
                const double tr = q_cov.xx + q_cov.yy + bm->cov[i].xx + bm->cov[i].yy;
                if (vx * vx + vy * vy > gate * tr * (1.0 + 1e-9)) {
                    continue;
                }
                if (cov2_mahalanobis2(cov2_add(q_cov, bm->cov[i]), vx, vy, &d2) == COSLAM_OK && d2 < gate) {
                    visit(sc, tag, i, d2, ctx);
                }
            }
        }
    }
}

/* The same around own landmark j (its body-frame position and cov_rel). */
static void grid_gated(merge_scratch_t *sc, const merge_body_map_t *bm, int32_t j, double gate, grid_visit_fn visit,
                       void *ctx)
{
    grid_gated_at(sc, bm, sc->own_body[j], sc->own_cov[j], sc->own_sig[j], j, gate, visit, ctx);
}

typedef struct {
    int n_pairs;
    uint32_t drops;
} pair_ctx_t;

/* Appended while there is room; once full, the table becomes a max-heap on
 * d2 and keeps the MERGE_MAX_PAIRS nearest pairs (the one-to-one selection
 * takes pairs nearest first, so it is the same on them). Every pair not
 * kept is counted and its incoming landmark marked. */
static void collect_pair(merge_scratch_t *sc, int32_t j, int32_t i, double d2, void *ctx)
{
    pair_ctx_t *pc = (pair_ctx_t *)ctx;
    merge_pair_t *pairs = sc->pairs;
    if (pc->n_pairs < MERGE_MAX_PAIRS) {
        pairs[pc->n_pairs].own = j;
        pairs[pc->n_pairs].in = i;
        pairs[pc->n_pairs].d2 = d2;
        pc->n_pairs++;
        if (pc->n_pairs == MERGE_MAX_PAIRS) {
            for (int k = MERGE_MAX_PAIRS / 2 - 1; k >= 0; --k) {
                pair_sift(pairs, k, MERGE_MAX_PAIRS);
            }
        }
        return;
    }
    pc->drops++;
    if (!(d2 < pairs[0].d2)) {
        sc->pair_lost[i] = 1U;
        return;
    }
    sc->pair_lost[pairs[0].in] = 1U;
    pairs[0].own = j;
    pairs[0].in = i;
    pairs[0].d2 = d2;
    pair_sift(pairs, 0, MERGE_MAX_PAIRS);
}

/*
 * Duplicates between one own map (sc->own_body/own_cov/own_sig, n_own, in
 * the receiver's body frame) and the incoming map: candidates from the 3x3
 * grid cells around each own landmark, same signature, inside the gate;
 * then one-to-one by increasing distance into sc->match_of_in (an unpaired
 * one that lost a candidate to the table's size: MERGE_PAIR_LOST).
 * O(M_own + P log P) for P candidate pairs. Returns how many incoming
 * landmarks are MERGE_PAIR_LOST. The pairing of every other one is the one
 * the whole candidate set gives: the selection takes pairs nearest first,
 * and the pairs it did not keep are farther than every kept one.
 */
static uint32_t pair_and_select(merge_scratch_t *sc, const merge_body_map_t *bm, const merge_config_t *cfg, int n_own,
                                merge_stats_t *stats)
{
    pair_ctx_t pc = {0, 0U};
    for (uint16_t i = 0; i < bm->n; ++i) {
        sc->match_of_in[i] = -1;
        sc->match_d2[i] = INFINITY;
        sc->pair_lost[i] = 0U;
    }
    for (int j = 0; j < n_own; ++j) {
        sc->own_used[j] = 0;
        grid_gated(sc, bm, (int32_t)j, cfg->gate_chi2, collect_pair, &pc);
    }
    const int n_pairs = pc.n_pairs;
    sort_pairs(sc->pairs, n_pairs);
    for (int p = 0; p < n_pairs; ++p) {
        const int32_t i = sc->pairs[p].in;
        const int32_t j = sc->pairs[p].own;
        if (sc->match_of_in[i] >= 0 || sc->own_used[j]) {
            continue;
        }
        sc->match_of_in[i] = j;
        sc->match_d2[i] = sc->pairs[p].d2;
        sc->own_used[j] = 1;
    }
    uint32_t lost = 0U;
    if (pc.drops > 0U) {
        for (uint16_t i = 0; i < bm->n; ++i) {
            if (sc->match_of_in[i] < 0 && sc->pair_lost[i]) {
                sc->match_of_in[i] = MERGE_PAIR_LOST;
                lost++;
            }
        }
        if (stats != 0) {
            stats->pair_drops += pc.drops;
        }
    }
    return lost;
}

static int config_ok(const merge_config_t *cfg)
{
    return isfinite(cfg->gate_chi2) && cfg->gate_chi2 > 0.0 && isfinite(cfg->grid_cell_m) && cfg->grid_cell_m > 0.0 &&
           isfinite(cfg->refute_sd_factor) && cfg->refute_sd_factor >= 0.0 && isfinite(cfg->lost_sd_factor) &&
           cfg->lost_sd_factor >= 0.0;
}

/* Common start of a merge: statistics sink, grid over the incoming map. */
static merge_stats_t *begin_merge(merge_scratch_t *sc, const merge_body_map_t *bm, const merge_config_t *cfg,
                                  merge_stats_t *stats, merge_stats_t *local)
{
    if (stats == 0) {
        memset(local, 0, sizeof *local);
        stats = local;
    }
    grid_build(sc, bm, grid_cell_size(bm, cfg, cfg->gate_chi2));
    return stats;
}

/* Bookkeeping of an own landmark that absorbed incoming landmark i. */
static void absorb_meta(uint16_t *src_mask, uint16_t *n_obs, float *exist, const merge_body_map_t *bm, uint16_t i,
                        const slam_params_t *sp)
{
    /* sightings behind it: disjoint provenance adds; shared provenance (a
     * repeated meeting, a chain back to this robot) may already hold this
     * robot's count, so the larger one is kept (never counted twice, as
     * the fusion itself: Kalman or covariance intersection) */
    const uint32_t nobs = (*src_mask & bm->src_mask[i]) == 0U ? (uint32_t)*n_obs + bm->n_obs[i]
                          : (*n_obs > bm->n_obs[i] ? *n_obs : bm->n_obs[i]);
    *src_mask |= bm->src_mask[i];
    *n_obs = nobs > UINT16_MAX ? (uint16_t)UINT16_MAX : (uint16_t)nobs;
    if (*exist < sp->exist_confirm) {
        *exist = sp->exist_confirm; /* the sender confirmed it */
    }
}

/* Weight of each duplicate's information: the n duplicates of one message
 * count as at most fuse_eff_pairs independent ones (their errors relative
 * to the sender share its pose error; the message drops the correlation). */
static double duplicate_weight(const merge_scratch_t *sc, const merge_body_map_t *bm, const merge_config_t *cfg)
{
    if (!(cfg->fuse_eff_pairs > 0.0)) {
        return 1.0;
    }
    uint32_t n = 0;
    for (uint16_t i = 0; i < bm->n; ++i) {
        n += sc->match_of_in[i] >= 0;
    }
    return (double)n > cfg->fuse_eff_pairs ? cfg->fuse_eff_pairs / (double)n : 1.0;
}

/* ---- Fast-SLAM ---------------------------------------------------------- */

coslam_status_t merge_fastslam_begin(fastslam_t *fs, const merge_body_map_t *bm, const merge_config_t *cfg,
                                     merge_scratch_t *sc, const pose2_t *at)
{
    if (!config_ok(cfg)) {
        return COSLAM_E_ARG;
    }
    if (fs->merge_due_n > 0U) {
        return COSLAM_E_MERGE_BUSY; /* the particles due would lose the earlier merge */
    }
    grid_build(sc, bm, grid_cell_size(bm, cfg, cfg->gate_chi2));
    fs->merges++;
    /* one identity per incoming landmark, shared by the particles that add it */
    for (uint16_t i = 0; i < bm->n; ++i) {
        sc->new_id[i] = fastslam_new_id(fs);
    }
    for (uint16_t k = 0; k < fs->cfg.n_particles; ++k) {
        fs->particles[k].merge_pose = at != NULL ? at[k] : fs->particles[k].pose;
        fs->particles[k].merge_due = 1U;
    }
    fs->merge_due_n = fs->cfg.n_particles;
    return COSLAM_OK;
}

/* The merge into particle k, through the pose it had when the merge began. */
static coslam_status_t merge_particle(fastslam_t *fs, uint16_t k, const merge_body_map_t *bm,
                                      const merge_config_t *cfg, merge_scratch_t *sc, merge_stats_t *stats)
{
    const slam_params_t *sp = &fs->cfg.slam;
    coslam_status_t result = COSLAM_OK;
    fastslam_particle_t *p = &fs->particles[k];
    const pose2_t pose = p->merge_pose;
    const double c = cos(pose.theta);
    const double s = sin(pose.theta);
    double rt[2][2] = {{c, s}, {-s, c}}; /* world -> body */
    double r[2][2] = {{c, -s}, {s, c}};  /* body -> world */
    /* own map in this particle's body frame: the landmarks that can
     * pair with an incoming one (the others have none in their grid
     * neighbourhood), in slot order; own_idx maps them back and own[]
     * (compacted in place) holds them. Subtrees whose box has no point
     * that can pair are not read (box_may_pair); the rest is tested
     * landmark by landmark, so the candidates are the same as testing
     * every landmark */
    own_box_ctx_t bctx = {sc, pose, c, s};
    uint16_t n_sel = 0U;
    /* own_used (pair_and_select's, set there) holds meanwhile whether a
     * landmark lies in a box every point of which may pair */
    const landmark_t **own =
        fastslam_particle_select(fs, k, box_may_pair, &bctx, sc->own_idx, sc->own_used, &n_sel);
    int n_cand = 0;
    for (uint16_t t = 0; t < n_sel; ++t) {
        const landmark_t *lm = own[t];
        const point2_t body = pose2_apply_inverse_cs(pose, c, s, lm->mean);
        if (!sc->own_used[t] && !grid_may_pair(sc, body)) {
            continue;
        }
        sc->own_body[n_cand] = body;
        sc->own_cov[n_cand] = cov2_congruence(rt, lm->cov);
        sc->own_sig[n_cand] = lm->signature;
        sc->own_idx[n_cand] = sc->own_idx[t];
        own[n_cand] = lm;
        n_cand++;
    }
    if (pair_and_select(sc, bm, cfg, n_cand, stats) > 0U) {
        fs->ctr.merge_pair_drops++;
        result = COSLAM_E_CAPACITY;
    }
    const double dup_w = duplicate_weight(sc, bm, cfg);
    for (uint16_t i = 0; i < bm->n; ++i) {
        if (sc->match_of_in[i] == MERGE_PAIR_LOST) {
            stats->pair_lost++; /* an own landmark in its gate was not weighed: not added */
            continue;
        }
        const point2_t wm = pose2_apply_cs(pose, c, s, bm->mean[i]);
        const int32_t m = sc->match_of_in[i];
        const int32_t j = m >= 0 ? (int32_t)sc->own_idx[m] : -1;
        /* a duplicate's information scaled by dup_w: its covariance by 1 / dup_w */
        const cov2_t wc = cov2_scale(cov2_congruence(r, bm->cov[i]), j >= 0 ? 1.0 / dup_w : 1.0);
        if (j >= 0) {
            /* own[m] is still slot j as it was: each slot is written once
             * (the pairing is one to one), and a write leaves a leaf other
             * maps share unchanged. Maps are shared: the copy is written
             * back below */
            landmark_t fused = *own[m];
            landmark_t *lm = &fused;
            point2_t xm;
            cov2_t xc;
            coslam_status_t st;
            if (cfg->reweight_particles) {
                /* likelihood that the two are one point: N(b - a; 0, S_a + S_b) */
                const cov2_t sum = cov2_add(lm->cov, wc);
                p->log_w += -0.5 * sc->match_d2[i] - log(COSLAM_TWO_PI * sqrt(cov2_det(sum)));
            }
            if ((lm->src_mask & bm->src_mask[i]) == 0U) {
                st = merge_fuse_kalman(lm->mean, lm->cov, wm, wc, &xm, &xc);
            } else {
                st = merge_fuse_ci(lm->mean, lm->cov, wm, wc, &xm, &xc, 0);
                stats->fused_ci++;
            }
            if (st != COSLAM_OK || !cov2_is_pd(xc)) {
                stats->skipped++;
                continue;
            }
            lm->mean = xm;
            lm->cov = xc;
            absorb_meta(&lm->src_mask, &lm->n_obs, &lm->exist, bm, i, sp);
            if (fastslam_particle_set(fs, k, (uint16_t)j, lm) != COSLAM_OK) {
                stats->capacity_drops++;
                result = COSLAM_E_CAPACITY;
                continue;
            }
            stats->fused++;
        } else {
            landmark_t lm;
            memset(&lm, 0, sizeof lm);
            lm.mean = wm;
            lm.cov = wc;
            lm.id = sc->new_id[i];
            lm.exist = sp->exist_max; /* the sender confirmed it and the check let it in */
            lm.n_obs = bm->n_obs[i];
            lm.src_mask = bm->src_mask[i];
            lm.signature = bm->signature[i];
            /* placed through this particle's pose: its pose error is the
             * received landmark's anchor (marginal.h; the marginal is the
             * present one when the merge comes in parts) */
            landmark_set_anchor(&lm, &p->pose_marg, (point2_t){pose.x, pose.y});
            lm.last_seen = (uint16_t)fs->ctr.updates; /* a revisit only after closure_gap */
            if (fastslam_particle_add(fs, k, &lm) != COSLAM_OK) {
                stats->capacity_drops++;
                result = COSLAM_E_CAPACITY;
            } else {
                stats->added++;
            }
        }
    }
    return result;
}

coslam_status_t merge_fastslam_run(fastslam_t *fs, const merge_body_map_t *bm, const merge_config_t *cfg,
                                   merge_scratch_t *sc, merge_stats_t *stats, uint32_t budget, uint16_t *left)
{
    merge_stats_t local;
    if (stats == 0) {
        memset(&local, 0, sizeof local);
        stats = &local;
    }
    coslam_status_t result = COSLAM_OK;
    uint32_t spent = 0U;
    for (uint16_t k = 0; k < fs->cfg.n_particles && fs->merge_due_n > 0U; ++k) {
        fastslam_particle_t *p = &fs->particles[k];
        if (!p->merge_due) {
            continue;
        }
        if (budget > 0U && spent >= budget) {
            break;
        }
        spent += (uint32_t)p->n_lm + MERGE_UNITS_PER_INCOMING * bm->n;
        if (merge_particle(fs, k, bm, cfg, sc, stats) != COSLAM_OK) {
            result = COSLAM_E_CAPACITY;
        }
        p->merge_due = 0U;
        fs->merge_due_n--;
    }
    if (left != 0) {
        *left = fs->merge_due_n;
    }
    if (fs->merge_due_n == 0U && cfg->reweight_particles) {
        fastslam_reweighted(fs); /* resample if the agreement test was decisive */
    }
    return result;
}

coslam_status_t merge_into_fastslam(fastslam_t *fs, const merge_body_map_t *bm, const merge_config_t *cfg,
                                    merge_scratch_t *sc, merge_stats_t *stats)
{
    const coslam_status_t st = merge_fastslam_begin(fs, bm, cfg, sc, NULL);
    if (st != COSLAM_OK) {
        return st;
    }
    return merge_fastslam_run(fs, bm, cfg, sc, stats, 0U, 0);
}

/* ---- EKF-SLAM ----------------------------------------------------------- */

/* Duplicate i (paired with own landmark sc->match_of_in[i]) fused into the
 * EKF: its information in the receiver's body frame, scaled by dup_w, or
 * by covariance intersection where the provenances overlap. */
static void ekf_fuse_one(ekfslam_t *ekf, const merge_body_map_t *bm, const merge_scratch_t *sc, uint16_t i,
                         double dup_w, merge_stats_t *stats)
{
    const int32_t j = sc->match_of_in[i];
    ekfslam_meta_t *meta = &ekf->meta[j];
    /* the information the incoming landmark brings (receiver's body frame) */
    const double ct = cos(bm->t.theta);
    const double stt = sin(bm->t.theta);
    double rt[2][2] = {{ct, -stt}, {stt, ct}};
    cov2_t info;
    if (cov2_inverse(cov2_congruence(rt, bm->rel_cov[i]), &info) != COSLAM_OK) {
        stats->skipped++;
        return;
    }
    if ((meta->src_mask & bm->src_mask[i]) != 0U) {
        /* covariance intersection on the relative marginals, applied as
         * the information it adds over the own estimate,
         * (1 - w) (S_b^-1 - S_a^-1), clipped to its positive directions:
         * re-merging information already held adds (almost) nothing */
        point2_t rel;
        cov2_t sa;
        point2_t xm;
        cov2_t xc;
        cov2_t ia;
        cov2_t ib;
        double w;
        ekfslam_landmark_relative(ekf, (uint16_t)j, &rel, &sa);
        if (merge_fuse_ci(rel, sa, bm->mean[i], bm->cov[i], &xm, &xc, &w) != COSLAM_OK ||
            cov2_inverse(sa, &ia) != COSLAM_OK || cov2_inverse(bm->cov[i], &ib) != COSLAM_OK) {
            stats->skipped++;
            return;
        }
        stats->fused_ci++;
        info = cov2_scale(cov2_add(ib, cov2_scale(ia, -1.0)), 1.0 - w);
        double lo;
        double hi;
        cov2_eigenvalues(info, &lo, &hi);
        if (!(hi > 1e-12 * (ia.xx + ia.yy))) {
            meta->src_mask |= bm->src_mask[i];
            stats->fused++;
            return; /* nothing new */
        }
        if (lo < 0.0) {
            info = cov2_clamp_eigen(info, 0.0);
        }
    }
    if (ekfslam_merge_observe(ekf, (uint16_t)j, bm->t, bm->rel[i], cov2_scale(info, dup_w)) != COSLAM_OK) {
        stats->skipped++;
        return;
    }
    absorb_meta(&meta->src_mask, &meta->n_obs, &meta->exist, bm, i, &ekf->cfg.slam);
    stats->fused++;
}

/* Incoming landmark i, unpaired, appended to the EKF. */
static coslam_status_t ekf_add_one(ekfslam_t *ekf, const merge_body_map_t *bm, uint16_t i, merge_stats_t *stats)
{
    const slam_params_t *sp = &ekf->cfg.slam;
    ekfslam_meta_t meta;
    memset(&meta, 0, sizeof meta); /* padding too: a state copied or compared bytewise stays defined */
    meta.id = ekf->next_id;
    meta.exist = sp->exist_max; /* the sender confirmed it and the check let it in */
    meta.n_obs = bm->n_obs[i];
    meta.src_mask = bm->src_mask[i];
    meta.signature = bm->signature[i];
    const coslam_status_t st = ekfslam_merge_add(ekf, bm->t, bm->rel[i], bm->rel_cov[i], &meta);
    if (st == COSLAM_OK) {
        (void)ekfslam_new_id(ekf);
        stats->added++;
        return COSLAM_OK;
    }
    if (st == COSLAM_E_CAPACITY) {
        stats->capacity_drops++;
        return COSLAM_E_CAPACITY;
    }
    stats->skipped++;
    return COSLAM_OK;
}

coslam_status_t merge_ekfslam_begin(ekfslam_t *ekf, const merge_body_map_t *bm, const merge_config_t *cfg,
                                    merge_scratch_t *sc, merge_stats_t *stats)
{
    if (!config_ok(cfg)) {
        return COSLAM_E_ARG;
    }
    if (ekf->merging) {
        return COSLAM_E_MERGE_BUSY;
    }
    merge_stats_t local;
    stats = begin_merge(sc, bm, cfg, stats, &local);
    ekfslam_sync(ekf); /* compressed EKF: the whole state, once, before reading it all */
    const uint16_t n_own = ekf->n_lm;
    for (uint16_t j = 0; j < n_own; ++j) {
        ekfslam_landmark_relative(ekf, j, &sc->own_body[j], &sc->own_cov[j]);
        sc->own_sig[j] = ekf->meta[j].signature;
    }
    const uint32_t lost = pair_and_select(sc, bm, cfg, n_own, stats);
    sc->ekf_dup_w = duplicate_weight(sc, bm, cfg);
    if (ekfslam_merge_begin(ekf, &bm->t_cov) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    sc->ekf_next = 0U;
    sc->ekf_result = COSLAM_OK;
    if (lost > 0U) {
        ekf->ctr.merge_pair_drops++;
        sc->ekf_result = COSLAM_E_CAPACITY;
        stats->pair_lost += lost; /* neither fused nor added */
    }
    return COSLAM_OK;
}

coslam_status_t merge_ekfslam_run(ekfslam_t *ekf, const merge_body_map_t *bm, merge_scratch_t *sc,
                                  merge_stats_t *stats, uint32_t budget, int *done)
{
    merge_stats_t local;
    if (stats == 0) {
        memset(&local, 0, sizeof local);
        stats = &local;
    }
    if (!ekf->merging) {
        *done = 1;
        return COSLAM_E_ARG; /* nothing begun */
    }
    const double limit = (double)budget * MERGE_EKF_MADDS_PER_UNIT;
    double spent = 0.0;
    const uint32_t n = bm->n;
    /* duplicates first (they only update), then additions (they grow the
     * state); the pending columns are applied before an update that could
     * fill them, before the first addition and at the end, in parts and
     * whatever the budget, so the parts are the whole merge bit for bit */
    while (sc->ekf_next < 2U * n || ekf->merge_bn > 0) {
        if (budget > 0U && spent >= limit) {
            *done = 0;
            return sc->ekf_result; /* the status so far: E_CAPACITY once anything was left out */
        }
        const uint32_t k = sc->ekf_next;
        const int adding = k >= n; /* or every item done (k = 2n) */
        const uint16_t i = (uint16_t)(adding ? k - n : k);
        if (k < 2U * n && (adding == (sc->match_of_in[i] >= 0) || sc->match_of_in[i] == MERGE_PAIR_LOST)) {
            sc->ekf_next++; /* not this pass's */
            continue;
        }
        /* an update adds up to two columns and must not fill them (that
         * would apply them inside it, whatever the budget) */
        if (ekf->merge_bn > 0 && (adding || ekfslam_merge_room(ekf) <= 2)) {
            (void)ekfslam_merge_flush_run(ekf, budget > 0U ? limit - spent : 0.0, &spent);
            continue;
        }
        const double d = 6.0 + 2.0 * (double)ekf->n_lm; /* the state with tau */
        if (adding) {
            if (ekf_add_one(ekf, bm, i, stats) == COSLAM_E_CAPACITY) {
                sc->ekf_result = COSLAM_E_CAPACITY;
            }
            spent += 8.0 * d; /* the new rows from the pose's and tau's */
        } else {
            ekf_fuse_one(ekf, bm, sc, i, sc->ekf_dup_w, stats);
            spent += 2.0 * d * (8.0 + (double)ekf->merge_bn); /* two directions: P h, less the pending share */
        }
        sc->ekf_next++;
    }
    ekfslam_merge_end(ekf);
    *done = 1;
    return sc->ekf_result;
}

coslam_status_t merge_into_ekfslam(ekfslam_t *ekf, const merge_body_map_t *bm, const merge_config_t *cfg,
                                   merge_scratch_t *sc, merge_stats_t *stats)
{
    const coslam_status_t st = merge_ekfslam_begin(ekf, bm, cfg, sc, stats);
    if (st != COSLAM_OK) {
        return st;
    }
    int done = 0;
    return merge_ekfslam_run(ekf, bm, sc, stats, 0U, &done);
}

/* ---- one set-up for every caller ---------------------------------------- */

/* Step 0: values no robot of the team can produce. */
int merge_message_plausible(const map_estimate_t *in, const robot_sighting_t *b, const merge_config_t *cfg)
{
    if (in == 0 || b == 0 || cfg == 0) {
        return 0;
    }
    const double ext2 = cfg->max_extent_m * cfg->max_extent_m;
    if (!(in->pose.x * in->pose.x + in->pose.y * in->pose.y <= ext2)) {
        return 0;
    }
    if (!(b->range_var_m2 >= cfg->min_var_m2) || !(b->range_var_m2 <= cfg->max_var_m2) ||
        !(b->bearing_var_rad2 >= cfg->min_bearing_var_rad2) || !(b->bearing_var_rad2 <= cfg->max_bearing_var_rad2) ||
        !(b->range_m <= cfg->max_extent_m)) {
        return 0;
    }
    for (uint16_t i = 0; i < in->n_landmarks; ++i) {
        const map_landmark_t *l = &in->lm[i];
        if (!(l->mean.x * l->mean.x + l->mean.y * l->mean.y <= ext2) ||
            !cov2_axes_within(l->cov, cfg->min_var_m2, cfg->max_var_m2) ||
            !cov2_axes_within(l->cov_rel, cfg->min_var_m2, cfg->max_var_m2)) {
            return 0;
        }
    }
    return 1;
}

coslam_status_t merge_prepare(const map_estimate_t *in, const merge_geometry_t *g, const slam_params_t *own_params,
                              const merge_config_t *cfg, merge_body_map_t *out, merge_stats_t *stats)
{
    if (in == 0 || g == 0 || own_params == 0 || cfg == 0 || out == 0) {
        return COSLAM_E_ARG;
    }
    out->n = 0;
    if (!isfinite(g->own_travel_m) || !isfinite(g->sighting_dt_s) || !isfinite(g->own_motion.dx) ||
        !isfinite(g->own_motion.dy) || !isfinite(g->own_motion.dtheta)) {
        return COSLAM_E_NUMERIC;
    }
    if (!(cfg->peer_speed_mps >= 0.0) || !(cfg->peer_turn_radps >= 0.0) || !(cfg->range_check_chi2 >= 0.0) ||
        !(cfg->max_extent_m > 0.0) || !(cfg->min_var_m2 > 0.0) || !(cfg->max_var_m2 > cfg->min_var_m2) ||
        !(cfg->min_bearing_var_rad2 > 0.0) || !(cfg->max_bearing_var_rad2 > cfg->min_bearing_var_rad2)) {
        return COSLAM_E_ARG;
    }
    if (!merge_message_plausible(in, &g->other_sees_self, cfg)) {
        return COSLAM_E_MERGE_IMPLAUSIBLE;
    }
    const robot_sighting_t *a = &g->self_sees_other;
    const robot_sighting_t *b = &g->other_sees_self;
    pose2_t t;
    cov3_t tc;
    const coslam_status_t st = merge_relative_pose(a, b, &t, &tc);
    if (st != COSLAM_OK) {
        return st;
    }
    if (cfg->range_check_chi2 > 0.0) {
        /* both robots measured one distance; a misread marker does not agree */
        const double dr = a->range_m - b->range_m;
        if (!(dr * dr <= cfg->range_check_chi2 * (a->range_var_m2 + b->range_var_m2))) {
            return COSLAM_E_MERGE_RANGE;
        }
    }
    const double s_m = g->own_travel_m > 0.0 ? g->own_travel_m : 0.0;
    const cov3_t u_cov = cov3_diag(own_params->noise.odo_xy_var_m2_per_m * s_m,
                                   own_params->noise.odo_xy_var_m2_per_m * s_m,
                                   own_params->noise.odo_theta_var_rad2_per_m * s_m);
    const double dt = fabs(g->sighting_dt_s);
    const double dxy = cfg->peer_speed_mps * dt;
    const double dth = cfg->peer_turn_radps * dt;
    merge_compensate(&t, &tc, g->own_motion, &u_cov, dxy * dxy);
    tc.m[2][2] += dth * dth;
    return merge_transform_map(in, t, &tc, cfg, out, stats);
}

/* ---- coverage: where the receiver has looked ---------------------------- */

void merge_coverage_init(merge_coverage_t *c)
{
    memset(c, 0, sizeof *c);
    c->step_m = 0.3;
    c->step_rad = 0.2618; /* 15 deg */
}

void merge_coverage_note(merge_coverage_t *c, pose2_t pose)
{
    if (!pose2_is_finite(pose)) {
        return;
    }
    if (c->n > 0U) {
        const pose2_t last = c->pose[c->n - 1U];
        const double d = hypot(pose.x - last.x, pose.y - last.y);
        if (d < c->step_m && fabs(angle_wrap(pose.theta - last.theta)) < c->step_rad) {
            return;
        }
    }
    if (c->n == COSLAM_COVERAGE_KEYFRAMES) {
        /* full: keep every second keyframe, double the spacing */
        uint16_t k = 0;
        for (uint16_t i = 0; i < c->n; i += 2U) {
            c->pose[k++] = c->pose[i];
        }
        c->n = k;
        c->step_m *= 2.0;
        c->step_rad *= 2.0;
        c->thinned++;
    }
    c->pose[c->n++] = pose;
}

uint16_t merge_coverage_looks(const merge_coverage_t *c, const slam_params_t *p, const occ_grid_t *grid, point2_t pt)
{
    uint16_t looks = 0;
    for (uint16_t i = 0; i < c->n; ++i) {
        if (landmark_should_be_seen(p, observe_predict(c->pose[i], pt)) &&
            (grid == 0 || occ_grid_line_free(grid, (point2_t){c->pose[i].x, c->pose[i].y}, pt, 0.0, 0.1))) {
            looks++;
        }
    }
    return looks;
}

/* ---- check before trust ------------------------------------------------- */

double merge_refute_sd_m(const slam_params_t *p)
{
    /* a position sd s seen from range r gives about s / r of bearing,
     * smallest at the farthest range at which the landmark counts as in
     * view (landmark_should_be_seen) */
    return landmark_miss_bearing_sd_max(p) * p->sensor_max_range_m * p->visibility_margin;
}

/* Chi-square quantile of `dof` degrees of freedom at normal quantile z
 * (Wilson-Hilferty; within 1 % for dof >= 2 at the tails used here). */
static double chi2_bound(double dof, double z)
{
    const double a = 2.0 / (9.0 * dof);
    const double c = 1.0 - a + z * sqrt(a);
    return dof * c * c * c;
}

/* The incoming map moved by t (prior covariance), grid, pairs. */
static void check_pair(merge_scratch_t *sc, merge_body_map_t *bm, const merge_config_t *cfg, pose2_t t,
                       const cov3_t *t_cov, int n_own, merge_stats_t *stats)
{
    for (uint16_t i = 0; i < bm->n; ++i) {
        body_landmark(t, t_cov, bm->rel[i], bm->rel_cov[i], &bm->mean[i], &bm->cov[i]);
    }
    /* cells wide enough for the ambiguity searches too (merge_check step 3) */
    double gate = cfg->ambiguous_chi2 > cfg->gate_chi2 ? cfg->ambiguous_chi2 : cfg->gate_chi2;
    gate = cfg->unresolved_chi2 > gate ? cfg->unresolved_chi2 : gate;
    grid_build(sc, bm, grid_cell_size(bm, cfg, gate));
    pair_and_select(sc, bm, cfg, n_own, stats);
}

/* Mark (sc->drop = 2) every unpaired incoming landmark that lies within
 * ambiguous_chi2 of an own landmark left unpaired: through the grid built
 * by check_pair, O(M_own + candidates). */
static void mark_if_unpaired(merge_scratch_t *sc, int32_t j, int32_t i, double d2, void *ctx)
{
    (void)j;
    (void)d2;
    (void)ctx;
    if (sc->match_of_in[i] < 0) {
        sc->drop[i] = 2U;
    }
}

/* An unpaired incoming landmark with another incoming landmark of its
 * signature (paired or not) within unresolved_chi2 of it is ambiguous too:
 * the sender's own map cannot tell the two apart (they could be one object),
 * so adding it would plant a pair that stalls or misleads the receiver's
 * association. The distance is on the two relative covariances, the
 * sender's uncertainty of the two places, not on the transform's error,
 * which moves both alike (docs/map-merge.md). The grid's gate on the larger
 * body-frame covariances finds every such neighbour. */
typedef struct {
    const merge_body_map_t *bm;
    double gate;
} other_ctx_t;

static void mark_if_other(merge_scratch_t *sc, int32_t j, int32_t i, double d2_body, void *ctx)
{
    const other_ctx_t *oc = (const other_ctx_t *)ctx;
    const merge_body_map_t *bm = oc->bm;
    double d2;
    (void)d2_body; /* <= d2: the body-frame covariances hold the transform's too */
    if (i != j && cov2_mahalanobis2(cov2_add(bm->rel_cov[i], bm->rel_cov[j]), bm->rel[i].x - bm->rel[j].x,
                                    bm->rel[i].y - bm->rel[j].y, &d2) == COSLAM_OK && d2 < oc->gate) {
        sc->drop[j] = 2U;
    }
}

static void mark_ambiguous(merge_scratch_t *sc, const merge_body_map_t *bm, const merge_config_t *cfg, int n_own)
{
    for (int j = 0; j < n_own; ++j) {
        if (!sc->own_used[j]) {
            grid_gated(sc, bm, (int32_t)j, cfg->ambiguous_chi2, mark_if_unpaired, 0);
        }
    }
    if (!(cfg->unresolved_chi2 > 0.0)) {
        return;
    }
    other_ctx_t oc = {bm, cfg->unresolved_chi2};
    for (uint16_t i = 0; i < bm->n; ++i) {
        if (sc->match_of_in[i] < 0 && sc->drop[i] == 0U) {
            grid_gated_at(sc, bm, bm->mean[i], bm->cov[i], bm->signature[i], (int32_t)i, cfg->unresolved_chi2,
                          mark_if_other, &oc);
        }
    }
}

/* Residual of pair (i, j) under t and its information matrix W. */
static int pair_residual(const merge_scratch_t *sc, const merge_body_map_t *bm, int32_t i, int32_t j, pose2_t t,
                         double r[2], cov2_t *w, double jt[2][3])
{
    const double c = cos(t.theta);
    const double s = sin(t.theta);
    double rot[2][2] = {{c, -s}, {s, c}};
    const point2_t pred = pose2_apply(t, bm->rel[i]);
    r[0] = sc->own_body[j].x - pred.x;
    r[1] = sc->own_body[j].y - pred.y;
    pose2_apply_jacobians(t, bm->rel[i], jt, 0);
    return cov2_inverse(cov2_add(sc->own_cov[j], cov2_congruence(rot, bm->rel_cov[i])), w) == COSLAM_OK;
}

/* Over the current pairs at transform t: their NIS (returned) and count,
 * and, if h and g are not NULL, their part of the Gauss-Newton normal
 * equations, h += J^T W J, g += J^T W r. */
static double pairs_accumulate(const merge_scratch_t *sc, const merge_body_map_t *bm, pose2_t t, uint32_t *n_pairs,
                               double h[3][3], double g[3])
{
    double nis = 0.0;
    *n_pairs = 0;
    for (uint16_t i = 0; i < bm->n; ++i) {
        const int32_t j = sc->match_of_in[i];
        double r[2];
        double jt[2][3];
        cov2_t w;
        if (j < 0 || !pair_residual(sc, bm, (int32_t)i, j, t, r, &w, jt)) {
            continue;
        }
        (*n_pairs)++;
        const double wr[2] = {w.xx * r[0] + w.xy * r[1], w.xy * r[0] + w.yy * r[1]};
        nis += r[0] * wr[0] + r[1] * wr[1];
        if (h == 0 || g == 0) {
            continue;
        }
        for (int a = 0; a < 3; ++a) {
            const double wj0 = w.xx * jt[0][a] + w.xy * jt[1][a];
            const double wj1 = w.xy * jt[0][a] + w.yy * jt[1][a];
            g[a] += jt[0][a] * wr[0] + jt[1][a] * wr[1];
            for (int b = 0; b < 3; ++b) {
                h[a][b] += wj0 * jt[0][b] + wj1 * jt[1][b];
            }
        }
    }
    return nis;
}

int merge_refused_by_check(coslam_status_t st)
{
    return st == COSLAM_E_MERGE_DISAGREE || st == COSLAM_E_MERGE_LOST;
}

/* The smallest variance (largest axis) of the own landmarks paired, in the
 * receiver's body frame: how well the receiver places the best-placed
 * landmark the merge acts on. INFINITY with no pairs. */
static double own_placed_var(const merge_scratch_t *sc, const merge_body_map_t *bm)
{
    double best = INFINITY;
    for (uint16_t i = 0; i < bm->n; ++i) {
        const int32_t j = sc->match_of_in[i];
        if (j < 0) {
            continue;
        }
        double lmin;
        double lmax;
        cov2_eigenvalues(sc->own_cov[j], &lmin, &lmax);
        if (lmax < best) {
            best = lmax;
        }
    }
    return best;
}

static void keep_landmark(merge_body_map_t *bm, uint16_t from, uint16_t to)
{
    if (from == to) {
        return;
    }
    bm->mean[to] = bm->mean[from];
    bm->cov[to] = bm->cov[from];
    bm->src_mask[to] = bm->src_mask[from];
    bm->n_obs[to] = bm->n_obs[from];
    bm->signature[to] = bm->signature[from];
    bm->id[to] = bm->id[from];
    bm->rel[to] = bm->rel[from];
    bm->rel_cov[to] = bm->rel_cov[from];
}

coslam_status_t merge_check(const map_whole_t *own, const merge_coverage_t *coverage, const occ_grid_t *grid,
                            const slam_params_t *own_params, uint8_t own_id, const merge_config_t *cfg, merge_body_map_t *bm, merge_scratch_t *sc,
                            merge_stats_t *stats)
{
    if (own == 0 || own_params == 0 || cfg == 0 || bm == 0 || sc == 0 || stats == 0 || own_id >= COSLAM_MAX_ROBOTS ||
        !config_ok(cfg)) {
        return COSLAM_E_ARG;
    }
    stats->t_shift = (pose2_t){0.0, 0.0, 0.0};
    if (!cfg->check) {
        return COSLAM_OK;
    }
    const int n_own = own->n_landmarks; /* <= COSLAM_MAX_LANDMARKS by its type */
    for (int j = 0; j < n_own; ++j) {
        sc->own_body[j] = pose2_apply_inverse(own->pose, own->lm[j].mean);
        sc->own_cov[j] = own->lm[j].cov_rel;
        sc->own_sig[j] = own->lm[j].signature;
    }
    const pose2_t t0 = bm->t;
    const cov3_t c0 = bm->t_cov;
    cov3_t c0_inv;
    /* no transform uncertainty (paper mode): nothing to refine */
    const int can_refine = cov3_inverse(c0, &c0_inv) == COSLAM_OK;
    pose2_t t = t0;
    merge_stats_t tmp; /* each pairing's; the last one's pair drops are the check's */
    memset(&tmp, 0, sizeof tmp);
    check_pair(sc, bm, cfg, t, &c0, n_own, &tmp);
    for (uint8_t it = 0; can_refine && it < cfg->refine_iters; ++it) {
        /* Gauss-Newton on sum_pairs r^T W r + (t - t0)^T C0^-1 (t - t0) */
        double h[3][3];
        double g[3];
        const double d0[3] = {t0.x - t.x, t0.y - t.y, angle_wrap(t0.theta - t.theta)};
        double hp[3][3] = {{0.0}};
        double gp[3] = {0.0, 0.0, 0.0};
        uint32_t n_pairs = 0;
        (void)pairs_accumulate(sc, bm, t, &n_pairs, hp, gp);
        /* the pairs' errors are correlated through each robot's pose: their
         * information on T counts as that of at most refine_eff_pairs
         * independent pairs (docs/map-merge.md) */
        const double kappa =
            cfg->refine_eff_pairs > 0.0 && (double)n_pairs > cfg->refine_eff_pairs ? (double)n_pairs / cfg->refine_eff_pairs
                                                                                    : 1.0;
        for (int a = 0; a < 3; ++a) {
            g[a] = gp[a] / kappa;
            for (int b = 0; b < 3; ++b) {
                h[a][b] = c0_inv.m[a][b] + hp[a][b] / kappa;
                g[a] += c0_inv.m[a][b] * d0[b];
            }
        }
        if (n_pairs == 0U) {
            break;
        }
        cov3_t hc;
        cov3_t hinv;
        memcpy(hc.m, h, sizeof h);
        if (cov3_inverse(cov3_symmetrize(hc), &hinv) != COSLAM_OK) {
            break;
        }
        double delta[3];
        for (int a = 0; a < 3; ++a) {
            delta[a] = hinv.m[a][0] * g[0] + hinv.m[a][1] * g[1] + hinv.m[a][2] * g[2];
        }
        t.x += delta[0];
        t.y += delta[1];
        t.theta = angle_wrap(t.theta + delta[2]);
        memset(&tmp, 0, sizeof tmp);
        check_pair(sc, bm, cfg, t, &c0, n_own, &tmp);
    }
    stats->pair_drops = tmp.pair_drops;
    stats->t_shift = (pose2_t){t.x - t0.x, t.y - t0.y, angle_wrap(t.theta - t0.theta)};

    /* 2. joint agreement test over the pairs */
    uint32_t n_pairs = 0;
    double nis = pairs_accumulate(sc, bm, t, &n_pairs, 0, 0);
    if (can_refine) {
        const double d[3] = {t.x - t0.x, t.y - t0.y, angle_wrap(t.theta - t0.theta)};
        double d2 = 0.0;
        if (cov3_mahalanobis2(c0, d, &d2) == COSLAM_OK) {
            nis += d2;
        }
    }
    stats->pairs = n_pairs;
    stats->nis = nis;
    stats->nis_bound = n_pairs > 0U ? chi2_bound(2.0 * (double)n_pairs, cfg->agree_z) : 0.0;

    /* 2a. a receiver lost in its own map: the pairs' gates hold its own
     * uncertainty of where its landmarks are, so with none of them placed
     * they hold wrong assignments among identical landmarks as well, and
     * the joint test passes those (docs/map-merge.md) */
    const double placed = own_placed_var(sc, bm);
    stats->placed_sd_m = isfinite(placed) ? (float)sqrt(placed) : 0.0f;
    const double lost_sd = cfg->lost_sd_factor * merge_refute_sd_m(own_params);
    if (cfg->lost_sd_factor > 0.0 && isfinite(placed) && !(placed <= lost_sd * lost_sd)) {
        return COSLAM_E_MERGE_LOST;
    }
    if (n_pairs > 0U && !(nis <= stats->nis_bound)) {
        return COSLAM_E_MERGE_DISAGREE;
    }

    /* 3. what may be added */
    const uint16_t own_bit = (uint16_t)(1U << own_id);
    uint32_t vetoed = 0;
    uint32_t echoes = 0;
    uint32_t ambiguous = 0;
    uint32_t unrefutable = 0;
    uint32_t lost = 0;
    const double refute_sd = cfg->refute_sd_factor * merge_refute_sd_m(own_params);
    for (uint16_t i = 0; i < bm->n; ++i) {
        sc->drop[i] = 0U;
    }
    mark_ambiguous(sc, bm, cfg, n_own);
    for (uint16_t i = 0; i < bm->n; ++i) {
        if (sc->match_of_in[i] >= 0) {
            continue;
        }
        if (sc->match_of_in[i] == MERGE_PAIR_LOST) {
            lost++; /* an own landmark in its gate was not weighed */
            sc->drop[i] = 1U;
            continue;
        }
        if ((bm->src_mask[i] & own_bit) != 0U) {
            echoes++;
            sc->drop[i] = 1U;
            continue;
        }
        if (sc->drop[i] != 0U) {
            ambiguous++;
            continue;
        }
        /* where the receiver could never see that it is not there (docs/map-merge.md) */
        if (cfg->refute_sd_factor > 0.0) {
            double lmin;
            double lmax;
            cov2_eigenvalues(bm->cov[i], &lmin, &lmax);
            if (!(lmax <= refute_sd * refute_sd)) {
                unrefutable++;
                sc->drop[i] = 1U;
                continue;
            }
        }
        if (coverage != 0 && cfg->veto_looks > 0U &&
            merge_coverage_looks(coverage, own_params, grid, pose2_apply(own->pose, pose2_apply(t, bm->rel[i]))) >=
                cfg->veto_looks) {
            vetoed++;
            sc->drop[i] = 1U;
        }
    }
    stats->vetoed = vetoed;
    stats->echoes = echoes;
    stats->ambiguous = ambiguous;
    stats->unrefutable = unrefutable;
    stats->check_lost = lost;
    if (vetoed >= 2U && (double)vetoed > cfg->max_contradict_fraction * (double)(n_pairs + vetoed)) {
        return COSLAM_E_MERGE_DISAGREE;
    }

    /* 4. keep what is fused or added, moved by the refined transform */
    uint16_t k = 0;
    for (uint16_t i = 0; i < bm->n; ++i) {
        const int paired = sc->match_of_in[i] >= 0;
        if (!paired && sc->drop[i]) {
            continue;
        }
        /* the refined mean, the sightings' covariance: the landmarks' errors
         * within one map are correlated (the message drops that), so the
         * pairs' information on the transform is overcounted; the prior is
         * the conservative choice (docs/map-merge.md) */
        body_landmark(t, &c0, bm->rel[i], bm->rel_cov[i], &bm->mean[i], &bm->cov[i]);
        keep_landmark(bm, i, k);
        k++;
    }
    bm->n = k;
    bm->t = t;
    bm->t_cov = c0;
    return COSLAM_OK;
}
