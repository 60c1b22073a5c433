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
    return c;
}

void merge_session_init(merge_session_t *s)
{
    memset(s, 0, sizeof *s);
}

coslam_status_t merge_session_accept(merge_session_t *s, uint8_t sender, uint32_t seq)
{
    if (sender >= COSLAM_MAX_ROBOTS) {
        return COSLAM_E_ARG;
    }
    if (s->seen[sender]) {
        /* serial-number comparison: newer iff 0 < seq - last < 2^31 */
        const uint32_t diff = seq - s->last_seq[sender];
        if (diff == 0U || diff >= 0x80000000U) {
            s->rejected_replays++;
            return COSLAM_E_MERGE_REPLAY;
        }
    }
    s->seen[sender] = 1U;
    s->last_seq[sender] = seq;
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

coslam_status_t merge_transform_map(const map_estimate_t *in, pose2_t t, const cov3_t *t_cov,
                                    const merge_config_t *cfg, merge_body_map_t *out, merge_stats_t *stats)
{
    out->n = 0;
    out->t = t;
    out->t_cov = (t_cov != 0 && cfg->transform_uncertainty) ? *t_cov : cov3_zero();
    if (!pose2_is_finite(t) || !pose2_is_finite(in->pose) || (t_cov != 0 && !cov3_is_finite(*t_cov))) {
        return COSLAM_E_NUMERIC;
    }
    const double c = cos(t.theta);
    const double s = sin(t.theta);
    double rot[2][2] = {{c, -s}, {s, c}};
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
        const point2_t mb = pose2_apply(t, rel);
        cov2_t cb;
        cov2_t rel_cov;
        if (cfg->transform_uncertainty) {
            rel_cov = l->cov_rel;
            cb = cov2_congruence(rot, l->cov_rel);
            if (t_cov != 0) {
                double jt[2][3];
                pose2_apply_jacobians(t, rel, jt, 0);
                cov3_t tc = *t_cov;
                cb = cov2_add(cb, cov2_from_3x3(jt, tc.m));
            }
        } else {
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

static uint32_t cell_hash(int32_t cx, int32_t cy)
{
    const uint32_t h = ((uint32_t)cx * 73856093U) ^ ((uint32_t)cy * 19349663U);
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
static double grid_cell_size(const merge_body_map_t *bm, const merge_config_t *cfg)
{
    double lmax_all = 0.0;
    for (uint16_t i = 0; i < bm->n; ++i) {
        double lo;
        double hi;
        cov2_eigenvalues(bm->cov[i], &lo, &hi);
        lmax_all = hi > lmax_all ? hi : lmax_all;
    }
    const double reach = sqrt(cfg->gate_chi2 * 2.0 * lmax_all);
    return reach > cfg->grid_cell_m ? reach : cfg->grid_cell_m;
}

static void grid_build(merge_scratch_t *sc, const merge_body_map_t *bm, double cell)
{
    sc->cell_m = cell;
    for (int b = 0; b < COSLAM_MERGE_GRID_BUCKETS; ++b) {
        sc->bucket_head[b] = -1;
    }
    for (uint16_t i = 0; i < bm->n; ++i) {
        const int32_t cx = cell_of(bm->mean[i].x, cell);
        const int32_t cy = cell_of(bm->mean[i].y, cell);
        const uint32_t h = cell_hash(cx, cy);
        sc->cell_x[i] = cx;
        sc->cell_y[i] = cy;
        sc->next[i] = sc->bucket_head[h];
        sc->bucket_head[h] = (int32_t)i;
    }
}

/* Greedy one-to-one selection needs the pairs sorted by d2 (heap sort). */
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

/*
 * Duplicates between one own map (sc->own_body/own_cov/own_sig, n_own, in
 * the receiver's body frame) and the incoming map: candidates from the 3x3
 * grid cells around each own landmark, same signature, inside the gate;
 * then one-to-one by increasing distance into sc->match_of_in.
 * O(M_own + P log P) for P candidate pairs.
 */
static void pair_and_select(merge_scratch_t *sc, const merge_body_map_t *bm, const merge_config_t *cfg, int n_own,
                            merge_stats_t *stats)
{
    int n_pairs = 0;
    for (uint16_t i = 0; i < bm->n; ++i) {
        sc->match_of_in[i] = -1;
        sc->match_d2[i] = INFINITY;
    }
    for (int j = 0; j < n_own; ++j) {
        sc->own_used[j] = 0;
        const int32_t cx = cell_of(sc->own_body[j].x, sc->cell_m);
        const int32_t cy = cell_of(sc->own_body[j].y, sc->cell_m);
        for (int32_t dx = -1; dx <= 1; ++dx) {
            for (int32_t dy = -1; dy <= 1; ++dy) {
                for (int32_t i = sc->bucket_head[cell_hash(cx + dx, cy + dy)]; i >= 0; i = sc->next[i]) {
                    if (sc->cell_x[i] != cx + dx || sc->cell_y[i] != cy + dy || bm->signature[i] != sc->own_sig[j]) {
                        continue;
                    }
                    double d2;
                    if (cov2_mahalanobis2(cov2_add(sc->own_cov[j], bm->cov[i]), bm->mean[i].x - sc->own_body[j].x,
                                          bm->mean[i].y - sc->own_body[j].y, &d2) != COSLAM_OK ||
                        !(d2 < cfg->gate_chi2)) {
                        continue;
                    }
                    if (n_pairs < MERGE_MAX_PAIRS) {
                        sc->pairs[n_pairs].own = j;
                        sc->pairs[n_pairs].in = i;
                        sc->pairs[n_pairs].d2 = d2;
                        n_pairs++;
                    } else if (stats != 0) {
                        stats->skipped++;
                    }
                }
            }
        }
    }
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
}

static int config_ok(const merge_config_t *cfg)
{
    return isfinite(cfg->gate_chi2) && cfg->gate_chi2 > 0.0 && isfinite(cfg->grid_cell_m) && cfg->grid_cell_m > 0.0;
}

/* Common start of a merge: statistics sink, grid over the incoming map. */
static merge_stats_t *begin_merge(merge_scratch_t *sc, const merge_body_map_t *bm, const merge_config_t *cfg,
                                  merge_stats_t *stats, merge_stats_t *local)
{
    if (stats == 0) {
        memset(local, 0, sizeof *local);
        stats = local;
    }
    grid_build(sc, bm, grid_cell_size(bm, cfg));
    return stats;
}

/* Bookkeeping of an own landmark that absorbed incoming landmark i. */
static void absorb_meta(uint16_t *src_mask, uint16_t *n_obs, float *exist, const merge_body_map_t *bm, uint16_t i,
                        const slam_params_t *sp)
{
    *src_mask |= bm->src_mask[i];
    const uint32_t nobs = (uint32_t)*n_obs + bm->n_obs[i];
    *n_obs = nobs > UINT16_MAX ? (uint16_t)UINT16_MAX : (uint16_t)nobs;
    if (*exist < sp->exist_confirm) {
        *exist = sp->exist_confirm; /* the sender confirmed it */
    }
}

/* ---- Fast-SLAM ---------------------------------------------------------- */

coslam_status_t merge_into_fastslam(fastslam_t *fs, const merge_body_map_t *bm, const merge_config_t *cfg,
                                    merge_scratch_t *sc, merge_stats_t *stats)
{
    if (!config_ok(cfg)) {
        return COSLAM_E_ARG;
    }
    merge_stats_t local;
    stats = begin_merge(sc, bm, cfg, stats, &local);
    const slam_params_t *sp = &fs->cfg.slam;
    coslam_status_t result = COSLAM_OK;
    /* one identity per incoming landmark, shared by the particles that add it */
    for (uint16_t i = 0; i < bm->n; ++i) {
        sc->new_id[i] = fastslam_new_id(fs);
    }
    for (uint16_t k = 0; k < fs->cfg.n_particles; ++k) {
        fastslam_particle_t *p = &fs->particles[k];
        const double c = cos(p->pose.theta);
        const double s = sin(p->pose.theta);
        double rt[2][2] = {{c, s}, {-s, c}}; /* world -> body */
        double r[2][2] = {{c, -s}, {s, c}};  /* body -> world */
        /* own map in this particle's body frame */
        for (uint16_t j = 0; j < p->n_lm; ++j) {
            sc->own_body[j] = pose2_apply_inverse(p->pose, p->lm[j].mean);
            sc->own_cov[j] = cov2_congruence(rt, p->lm[j].cov);
            sc->own_sig[j] = p->lm[j].signature;
        }
        pair_and_select(sc, bm, cfg, p->n_lm, stats);
        for (uint16_t i = 0; i < bm->n; ++i) {
            const point2_t wm = pose2_apply(p->pose, bm->mean[i]);
            const cov2_t wc = cov2_congruence(r, bm->cov[i]);
            const int32_t j = sc->match_of_in[i];
            if (j >= 0) {
                landmark_t *lm = &p->lm[j];
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
                stats->fused++;
            } else {
                landmark_t lm;
                memset(&lm, 0, sizeof lm);
                lm.mean = wm;
                lm.cov = wc;
                lm.id = sc->new_id[i];
                lm.exist = sp->exist_confirm; /* the sender confirmed it */
                lm.n_obs = bm->n_obs[i];
                lm.src_mask = bm->src_mask[i];
                lm.signature = bm->signature[i];
                if (fastslam_particle_add(fs, k, &lm) != COSLAM_OK) {
                    stats->capacity_drops++;
                    result = COSLAM_E_CAPACITY;
                } else {
                    stats->added++;
                }
            }
        }
    }
    if (cfg->reweight_particles) {
        fastslam_reweighted(fs); /* resample if the agreement test was decisive */
    }
    return result;
}

/* ---- EKF-SLAM ----------------------------------------------------------- */

coslam_status_t merge_into_ekfslam(ekfslam_t *ekf, const merge_body_map_t *bm, const merge_config_t *cfg,
                                   merge_scratch_t *sc, merge_stats_t *stats)
{
    if (!config_ok(cfg)) {
        return COSLAM_E_ARG;
    }
    merge_stats_t local;
    stats = begin_merge(sc, bm, cfg, stats, &local);
    const slam_params_t *sp = &ekf->cfg.slam;
    coslam_status_t result = COSLAM_OK;
    const uint16_t n_own = ekf->n_lm;
    for (uint16_t j = 0; j < n_own; ++j) {
        ekfslam_landmark_relative(ekf, j, &sc->own_body[j], &sc->own_cov[j]);
        sc->own_sig[j] = ekf->meta[j].signature;
    }
    pair_and_select(sc, bm, cfg, n_own, stats);
    if (ekfslam_merge_begin(ekf, &bm->t_cov) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    /* duplicates first (they only update), then additions (they grow the state) */
    for (uint16_t i = 0; i < bm->n; ++i) {
        const int32_t j = sc->match_of_in[i];
        if (j < 0) {
            continue;
        }
        ekfslam_meta_t *meta = &ekf->meta[j];
        /* the information the incoming landmark brings (receiver's body frame) */
        const double ct = cos(bm->t.theta);
        const double stt = sin(bm->t.theta);
        double rt[2][2] = {{ct, -stt}, {stt, ct}};
        cov2_t info;
        if (cov2_inverse(cov2_congruence(rt, bm->rel_cov[i]), &info) != COSLAM_OK) {
            stats->skipped++;
            continue;
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
                continue;
            }
            stats->fused_ci++;
            info = cov2_scale(cov2_add(ib, cov2_scale(ia, -1.0)), 1.0 - w);
            double lo;
            double hi;
            cov2_eigenvalues(info, &lo, &hi);
            if (!(hi > 1e-12 * (ia.xx + ia.yy))) {
                meta->src_mask |= bm->src_mask[i];
                stats->fused++;
                continue; /* nothing new */
            }
            if (lo < 0.0) {
                info = cov2_clamp_eigen(info, 0.0);
            }
        }
        if (ekfslam_merge_observe(ekf, (uint16_t)j, bm->t, bm->rel[i], info) != COSLAM_OK) {
            stats->skipped++;
            continue;
        }
        absorb_meta(&meta->src_mask, &meta->n_obs, &meta->exist, bm, i, sp);
        stats->fused++;
    }
    for (uint16_t i = 0; i < bm->n; ++i) {
        if (sc->match_of_in[i] >= 0) {
            continue;
        }
        ekfslam_meta_t meta;
        meta.id = ekf->next_id;
        meta.exist = sp->exist_confirm;
        meta.n_obs = bm->n_obs[i];
        meta.src_mask = bm->src_mask[i];
        meta.signature = bm->signature[i];
        const coslam_status_t st = ekfslam_merge_add(ekf, bm->t, bm->rel[i], bm->rel_cov[i], &meta);
        if (st == COSLAM_OK) {
            (void)ekfslam_new_id(ekf);
            stats->added++;
        } else if (st == COSLAM_E_CAPACITY) {
            result = COSLAM_E_CAPACITY;
            stats->capacity_drops++;
        } else {
            stats->skipped++;
        }
    }
    ekfslam_merge_end(ekf);
    return result;
}
