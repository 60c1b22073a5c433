#include "coslam/landmark.h"

#include <math.h>

coslam_status_t landmark_init(landmark_t *lm, const slam_params_t *params, pose2_t pose,
                              sighting_t z, uint32_t id, uint16_t src_mask)
{
    double gz[2][2];
    observe_inverse_jacobians(pose, z, 0, gz);
    const cov2_t q = observe_noise(params, z.range_m);
    const double w8 = params->noise.lm_init_var_m2;
    cov2_t c = cov2_congruence(gz, q);
    c.xx += w8;
    c.yy += w8;
    if (!cov2_is_pd(c)) {
        return COSLAM_E_NOT_PD;
    }
    lm->mean = observe_inverse(pose, z);
    lm->cov = c;
    lm->id = id;
    lm->exist = params->exist_init;
    lm->n_obs = 1;
    lm->src_mask = src_mask;
    lm->signature = z.signature;
    lm->confirmed_once = 0;
    lm->last_seen = 0;
    for (int i = 0; i < 6; ++i) {
        lm->anchor_cov[i] = 0.0f;
    }
    lm->anchor_xy[0] = (float)pose.x;
    lm->anchor_xy[1] = (float)pose.y;
    return COSLAM_OK;
}

cov3_t landmark_anchor(const landmark_t *lm)
{
    const float *c = lm->anchor_cov;
    cov3_t p;
    p.m[0][0] = c[0];
    p.m[0][1] = p.m[1][0] = c[1];
    p.m[0][2] = p.m[2][0] = c[2];
    p.m[1][1] = c[3];
    p.m[1][2] = p.m[2][1] = c[4];
    p.m[2][2] = c[5];
    return p;
}

void landmark_set_anchor(landmark_t *lm, const cov3_t *p, point2_t at)
{
    float *c = lm->anchor_cov;
    c[0] = (float)p->m[0][0];
    c[1] = (float)p->m[0][1];
    c[2] = (float)p->m[0][2];
    c[3] = (float)p->m[1][1];
    c[4] = (float)p->m[1][2];
    c[5] = (float)p->m[2][2];
    lm->anchor_xy[0] = (float)at.x;
    lm->anchor_xy[1] = (float)at.y;
}

cov2_t landmark_marginal(const landmark_t *lm)
{
    const cov3_t a = landmark_anchor(lm);
    double g[2][3] = {{1.0, 0.0, -(lm->mean.y - (double)lm->anchor_xy[1])},
                      {0.0, 1.0, lm->mean.x - (double)lm->anchor_xy[0]}};
    const cov2_t d = cov2_from_3x3(g, (double(*)[3])a.m);
    const cov2_t m = cov2_add(lm->cov, d);
    return cov2_is_pd(m) ? m : lm->cov;
}

coslam_status_t landmark_expect(const landmark_t *lm, const slam_params_t *params, pose2_t pose,
                                const cov3_t *pose_cov, lm_expect_t *e)
{
    const coslam_status_t st = observe_jacobians(pose, lm->mean, e->h_pose, e->h_lm);
    if (st != COSLAM_OK) {
        return st;
    }
    e->zhat = observe_predict(pose, lm->mean);
    e->zhat.signature = lm->signature;
    cov2_t s = cov2_add(cov2_congruence(e->h_lm, lm->cov), observe_noise(params, e->zhat.range_m));
    if (pose_cov != 0) {
        cov3_t pc = *pose_cov;
        s = cov2_add(s, cov2_from_3x3(e->h_pose, pc.m));
    }
    if (cov2_inverse(s, &e->s_inv) != COSLAM_OK) {
        return COSLAM_E_NOT_PD;
    }
    e->s = s;
    e->log_norm = -log(COSLAM_TWO_PI * sqrt(cov2_det(s)));
    return COSLAM_OK;
}

lm_d2_bound_t landmark_d2_bound_prepare(const landmark_t *lm, const slam_params_t *params, const cov3_t *pose_cov,
                                        sighting_t zhat)
{
    lm_d2_bound_t b = {zhat, 0.0, 0.0};
    const double r = zhat.range_m;
    if (!(r > 0.0)) {
        return b;
    }
    const double inv_r2 = 1.0 / (r * r);
    const cov2_t q = observe_noise(params, r);
    const double lm_tr = (double)lm->cov.xx + (double)lm->cov.yy;
    if (!(lm_tr >= 0.0)) {
        return b;
    }
    double s_rr = q.xx + lm_tr;
    double s_bb = q.yy + lm_tr * inv_r2;
    if (pose_cov != 0) {
        const double xy_tr = pose_cov->m[0][0] + pose_cov->m[1][1];
        if (!(xy_tr >= 0.0) || !(pose_cov->m[2][2] >= 0.0)) {
            return b;
        }
        s_rr += xy_tr;
        s_bb += (inv_r2 + 1.0) * (xy_tr + pose_cov->m[2][2]);
    }
    if (!(s_rr > 0.0) || !(s_bb > 0.0) || !isfinite(s_rr) || !isfinite(s_bb)) {
        return b;
    }
    /* a little slack for rounding in the exact computation */
    b.inv_s_rr = 1.0 / (s_rr * (1.0 + 1e-9));
    b.inv_s_bb = 1.0 / (s_bb * (1.0 + 1e-9));
    return b;
}

double landmark_d2_lower_bound(const lm_d2_bound_t *b, sighting_t z)
{
    double nu[2];
    observe_innovation(z, b->zhat, nu);
    const double br = nu[0] * nu[0] * b->inv_s_rr;
    const double bb = nu[1] * nu[1] * b->inv_s_bb;
    const double lb = br > bb ? br : bb;
    return isfinite(lb) ? lb : 0.0; /* NaN or inf: no bound */
}

double landmark_mahalanobis2(const lm_expect_t *e, sighting_t z)
{
    double nu[2];
    observe_innovation(z, e->zhat, nu);
    const cov2_t *si = &e->s_inv;
    return nu[0] * (si->xx * nu[0] + si->xy * nu[1]) + nu[1] * (si->xy * nu[0] + si->yy * nu[1]);
}

double landmark_log_lik(const lm_expect_t *e, double d2)
{
    return e->log_norm - 0.5 * d2;
}

cov2_t landmark_offset_floor(const slam_params_t *params, const lm_expect_t *e, cov2_t cov)
{
    const double r = e->zhat.range_m;
    const double vr = params->track_offset_range_var_per_m2 * r * r;
    const double vb = params->track_offset_bearing_var_rad2;
    if (!(vr > 0.0 || vb > 0.0)) {
        return cov;
    }
    /* the offset in the landmark's frame: H_lm^-1 diag(vr, vb) H_lm^-T */
    const double (*h)[2] = e->h_lm;
    const double det = h[0][0] * h[1][1] - h[0][1] * h[1][0];
    if (!(fabs(det) > 1e-12)) {
        return cov;
    }
    double hi[2][2] = {{h[1][1] / det, -h[0][1] / det}, {-h[1][0] / det, h[0][0] / det}};
    const cov2_t f = cov2_congruence(hi, cov2_make(vr, 0.0, vb));
    /* add the positive part of f - cov (eigenvalues clipped at 0) */
    const cov2_t d = cov2_make(f.xx - cov.xx, f.xy - cov.xy, f.yy - cov.yy);
    double lmin;
    double lmax;
    cov2_eigenvalues(d, &lmin, &lmax);
    if (!(lmax > 0.0)) {
        return cov;
    }
    if (lmin >= 0.0) {
        return f; /* cov + d */
    }
    cov2_t p;
    if (!cov2_eig_projector(d, lmax, &p)) {
        return cov; /* lmin < 0 <= lmax: not isotropic; only rounding gets here */
    }
    return cov2_add(cov, cov2_scale(p, lmax));
}

void landmark_update(landmark_t *lm, const slam_params_t *params, const lm_expect_t *e, sighting_t z)
{
    double nu[2];
    observe_innovation(z, e->zhat, nu);
    /* K = Sigma H^T S^-1 (2x2) */
    const cov2_t sg = lm->cov;
    const double (*h)[2] = e->h_lm;
    const double pht[2][2] = {
        {sg.xx * h[0][0] + sg.xy * h[0][1], sg.xx * h[1][0] + sg.xy * h[1][1]},
        {sg.xy * h[0][0] + sg.yy * h[0][1], sg.xy * h[1][0] + sg.yy * h[1][1]},
    };
    const cov2_t si = e->s_inv;
    double k[2][2];
    for (int r = 0; r < 2; ++r) {
        k[r][0] = pht[r][0] * si.xx + pht[r][1] * si.xy;
        k[r][1] = pht[r][0] * si.xy + pht[r][1] * si.yy;
    }
    lm->mean.x += k[0][0] * nu[0] + k[0][1] * nu[1];
    lm->mean.y += k[1][0] * nu[0] + k[1][1] * nu[1];
    /* Joseph form: (I - K H) Sigma (I - K H)^T + K Q K^T */
    double a[2][2];
    for (int r = 0; r < 2; ++r) {
        for (int c = 0; c < 2; ++c) {
            a[r][c] = (r == c ? 1.0 : 0.0) - (k[r][0] * h[0][c] + k[r][1] * h[1][c]);
        }
    }
    const cov2_t q = observe_noise(params, e->zhat.range_m);
    lm->cov = landmark_offset_floor(params, e, cov2_add(cov2_congruence(a, sg), cov2_congruence(k, q)));
    if (lm->n_obs < UINT16_MAX) {
        lm->n_obs++;
    }
}

int landmark_should_be_seen(const slam_params_t *params, sighting_t zhat)
{
    const double m = params->visibility_margin;
    return zhat.range_m >= params->sensor_min_range_m / m && zhat.range_m <= params->sensor_max_range_m * m &&
           fabs(zhat.bearing_rad) <= 0.5 * params->sensor_fov_rad * m;
}

int landmark_hidden(const view_profile_t *v, const lm_expect_t *e)
{
    if (v == NULL || !v->valid) {
        return 0;
    }
    return view_blocks(v, e->zhat.range_m, e->zhat.bearing_rad, 0.1 + 3.0 * sqrt(e->s.xx));
}

void exist_hit(float *exist, const slam_params_t *params)
{
    const float v = *exist + params->exist_hit;
    *exist = v > params->exist_max ? params->exist_max : v;
}

double landmark_miss_bearing_sd_max(const slam_params_t *params)
{
    return params->exist_miss_bearing_sd_frac * 0.5 * params->sensor_fov_rad;
}

int landmark_miss_is_certain(const slam_params_t *params, const lm_expect_t *e)
{
    /* compare variances: no square root, and a NaN variance is not certain */
    const double sd_max = landmark_miss_bearing_sd_max(params);
    return e->s.yy <= sd_max * sd_max;
}

int landmark_miss_would_count(const slam_params_t *params, const view_profile_t *v, const lm_expect_t *e)
{
    return landmark_should_be_seen(params, e->zhat) && !landmark_hidden(v, e) && landmark_miss_is_certain(params, e);
}

int exist_confirmed(float exist, uint8_t confirmed_once, const slam_params_t *params)
{
    return confirmed_once || exist >= params->exist_confirm;
}

int exist_miss(float *exist, uint8_t *confirmed_once, int certain, const slam_params_t *params)
{
    *confirmed_once = (uint8_t)exist_confirmed(*exist, *confirmed_once, params);
    if (params->exist_miss_confirmed > 0.0f && *confirmed_once) {
        /* one slow rate from exist_max to removal; uncertain misses say
         * nothing about a confirmed landmark */
        if (certain) {
            *exist -= params->exist_miss_confirmed;
        }
        return *exist < 0.0f;
    }
    if (*exist >= params->exist_confirm) {
        /* confirmed: may weaken down to the confirmation level, never below */
        const float v = *exist - params->exist_miss;
        *exist = v < params->exist_confirm ? params->exist_confirm : v;
        return 0;
    }
    *exist -= params->exist_miss;
    return *exist < 0.0f;
}

int landmark_is_confirmed(const landmark_t *lm, const slam_params_t *params)
{
    return lm->exist >= params->exist_confirm;
}

/* heap sort, descending by score (the heap keeps the minimum on top) */
static void pair_sift_down(assoc_pair_t *a, int start, int end)
{
    int root = start;
    while (2 * root + 1 <= end) {
        int child = 2 * root + 1;
        int sw = root;
        if (a[sw].score > a[child].score) {
            sw = child;
        }
        if (child + 1 <= end && a[sw].score > a[child + 1].score) {
            sw = child + 1;
        }
        if (sw == root) {
            return;
        }
        const assoc_pair_t t = a[root];
        a[root] = a[sw];
        a[sw] = t;
        root = sw;
    }
}

void assoc_greedy(assoc_pair_t *pairs, int n_pairs, int ns, int32_t *assign)
{
    for (int i = 0; i < ns; ++i) {
        assign[i] = -1;
    }
    for (int start = n_pairs / 2 - 1; start >= 0; --start) {
        pair_sift_down(pairs, start, n_pairs - 1);
    }
    for (int end = n_pairs - 1; end > 0; --end) {
        const assoc_pair_t t = pairs[0];
        pairs[0] = pairs[end];
        pairs[end] = t;
        pair_sift_down(pairs, 0, end - 1);
    }
    int n_assigned = 0;
    for (int p = 0; p < n_pairs && n_assigned < ns; ++p) {
        const int i = pairs[p].sighting;
        const int j = pairs[p].landmark;
        if (assign[i] >= 0) {
            continue;
        }
        int taken = 0;
        for (int k = 0; k < ns; ++k) {
            if (assign[k] == j) {
                taken = 1;
                break;
            }
        }
        if (!taken) {
            assign[i] = j;
            ++n_assigned;
        }
    }
}

assoc_class_t assoc_classify(const slam_params_t *params, double d2, double ll)
{
    if (!(d2 < params->new_landmark_chi2)) {
        return ASSOC_FAR;
    }
    if (d2 < params->gate_chi2 && ll >= params->new_landmark_log_lik) {
        return ASSOC_ADMISSIBLE;
    }
    return ASSOC_NEAR;
}

int assoc_unpaired_is_new(const assoc_pair_t *pairs, int n_pairs, int i, const int32_t *assign, int ns,
                          const uint8_t *n_near)
{
    if (n_near[i] != 0U) {
        return 0;
    }
    for (int p = 0; p < n_pairs; ++p) {
        if (pairs[p].sighting != i) {
            continue;
        }
        int taken = 0;
        for (int q = 0; q < ns; ++q) {
            if (q != i && assign[q] == pairs[p].landmark) {
                taken = 1;
                break;
            }
        }
        if (!taken) {
            return 0;
        }
    }
    return 1;
}
