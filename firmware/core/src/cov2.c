#include "coslam/cov2.h"

#include <math.h>

cov2_t cov2_make(double xx, double xy, double yy)
{
    cov2_t r = {xx, xy, yy};
    return r;
}

cov2_t cov2_add(cov2_t a, cov2_t b)
{
    return cov2_make(a.xx + b.xx, a.xy + b.xy, a.yy + b.yy);
}

cov2_t cov2_scale(cov2_t a, double k)
{
    return cov2_make(a.xx * k, a.xy * k, a.yy * k);
}

double cov2_det(cov2_t a)
{
    return a.xx * a.yy - a.xy * a.xy;
}

double cov2_trace(cov2_t a)
{
    return a.xx + a.yy;
}

int cov2_is_finite(cov2_t a)
{
    return isfinite(a.xx) && isfinite(a.xy) && isfinite(a.yy);
}

int cov2_is_pd(cov2_t a)
{
    return cov2_is_finite(a) && a.xx > 0.0 && a.yy > 0.0 && cov2_det(a) > 0.0;
}

coslam_status_t cov2_inverse(cov2_t a, cov2_t *out)
{
    if (!cov2_is_pd(a)) {
        return COSLAM_E_NOT_PD;
    }
    const double inv_det = 1.0 / cov2_det(a);
    const cov2_t inv = cov2_make(a.yy * inv_det, -a.xy * inv_det, a.xx * inv_det);
    /* a determinant that overflows (entries >= ~1e154) gives inv_det = 0:
     * not an inverse */
    if (!(isfinite(inv_det) && inv_det > 0.0 && cov2_is_pd(inv))) {
        return COSLAM_E_NUMERIC;
    }
    *out = inv;
    return COSLAM_OK;
}

coslam_status_t cov2_cholesky(cov2_t a, double l[3])
{
    if (!cov2_is_pd(a)) {
        return COSLAM_E_NOT_PD;
    }
    const double l0 = sqrt(a.xx);
    const double l1 = a.xy / l0;
    const double rem = a.yy - l1 * l1;
    if (!(rem > 0.0)) {
        return COSLAM_E_NOT_PD;
    }
    l[0] = l0;
    l[1] = l1;
    l[2] = sqrt(rem);
    return COSLAM_OK;
}

coslam_status_t cov2_mahalanobis2(cov2_t a, double vx, double vy, double *d2)
{
    cov2_t inv;
    const coslam_status_t st = cov2_inverse(a, &inv);
    if (st != COSLAM_OK) {
        return st;
    }
    *d2 = vx * (inv.xx * vx + inv.xy * vy) + vy * (inv.xy * vx + inv.yy * vy);
    return COSLAM_OK;
}

cov2_t cov2_congruence(double j[2][2], cov2_t a)
{
    /* t = J A, then (J A) J^T; only the unique entries are formed. */
    const double t00 = j[0][0] * a.xx + j[0][1] * a.xy;
    const double t01 = j[0][0] * a.xy + j[0][1] * a.yy;
    const double t10 = j[1][0] * a.xx + j[1][1] * a.xy;
    const double t11 = j[1][0] * a.xy + j[1][1] * a.yy;
    return cov2_make(t00 * j[0][0] + t01 * j[0][1],
                     t00 * j[1][0] + t01 * j[1][1],
                     t10 * j[1][0] + t11 * j[1][1]);
}

cov2_t cov2_from_3x3(double j[2][3], double p[3][3])
{
    double t[2][3];
    for (int r = 0; r < 2; ++r) {
        for (int c = 0; c < 3; ++c) {
            t[r][c] = j[r][0] * p[0][c] + j[r][1] * p[1][c] + j[r][2] * p[2][c];
        }
    }
    double o[2][2];
    for (int r = 0; r < 2; ++r) {
        for (int c = 0; c < 2; ++c) {
            o[r][c] = t[r][0] * j[c][0] + t[r][1] * j[c][1] + t[r][2] * j[c][2];
        }
    }
    return cov2_make(o[0][0], 0.5 * (o[0][1] + o[1][0]), o[1][1]);
}

void cov2_eigenvalues(cov2_t a, double *lam_min, double *lam_max)
{
    const double half_tr = 0.5 * (a.xx + a.yy);
    const double half_diff = 0.5 * (a.xx - a.yy);
    const double r = sqrt(half_diff * half_diff + a.xy * a.xy);
    *lam_min = half_tr - r;
    *lam_max = half_tr + r;
}

int cov2_eig_projector(cov2_t a, double lmax, cov2_t *proj)
{
    /* eigenvector of lmax: (xy, lmax - xx) or (lmax - yy, xy), whichever is larger */
    double vx = a.xy;
    double vy = lmax - a.xx;
    const double ux = lmax - a.yy;
    const double uy = a.xy;
    if (ux * ux + uy * uy > vx * vx + vy * vy) {
        vx = ux;
        vy = uy;
    }
    const double n2 = vx * vx + vy * vy;
    if (!(n2 > 0.0)) {
        return 0; /* isotropic */
    }
    *proj = cov2_make(vx * vx / n2, vx * vy / n2, vy * vy / n2);
    return 1;
}

cov2_t cov2_clamp_eigen(cov2_t a, double min_eig)
{
    double lmin;
    double lmax;
    cov2_eigenvalues(a, &lmin, &lmax);
    if (lmin >= min_eig) {
        return a;
    }
    cov2_t c;
    if (!cov2_eig_projector(a, lmax, &c)) {
        /* isotropic: a = lmin I */
        const double l = lmin < min_eig ? min_eig : lmin;
        return cov2_make(l, 0.0, l);
    }
    const double l1 = lmax < min_eig ? min_eig : lmax;
    const double l2 = min_eig;
    /* A = l1 v v^T + l2 (I - v v^T) */
    return cov2_make(l2 + (l1 - l2) * c.xx, (l1 - l2) * c.xy, l2 + (l1 - l2) * c.yy);
}
