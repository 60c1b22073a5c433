#include "coslam/marginal.h"

#include <math.h>

/* P - Phi A Phi^T, the drift since the anchor, negative directions clipped
 * to zero; *clipped set if any was. */
static cov3_t drift_since(const cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy, cov3_t *shared,
                          int *clipped)
{
    /* the anchoring pose error carried forward: a heading error at the
     * anchor moves the robot's position by its rotation about the anchor */
    double phi[3][3] = {{1.0, 0.0, -(pose.y - anchor_xy.y)}, {0.0, 1.0, pose.x - anchor_xy.x}, {0.0, 0.0, 1.0}};
    *shared = cov3_congruence(phi, *anchor);
    cov3_t q;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            q.m[i][j] = p->m[i][j] - shared->m[i][j];
        }
    }
    /* clip only if q is not positive definite (the common case is) */
    double chol[3][3];
    *clipped = cov3_cholesky(q, chol) != COSLAM_OK;
    return *clipped ? cov3_clamp_psd(q) : q;
}

cov3_t marginal_drift(const cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy)
{
    if (!cov3_is_finite(*p) || !cov3_is_finite(*anchor)) {
        return cov3_zero();
    }
    cov3_t shared;
    int clipped;
    return drift_since(p, pose, anchor, anchor_xy, &shared, &clipped);
}

cov2_t marginal_relative_drift_cs(const cov3_t *p, pose2_t pose, double c, double s, const cov3_t *anchor,
                                  point2_t anchor_xy, point2_t rel)
{
    if (!cov3_is_finite(*p) || !cov3_is_finite(*anchor)) {
        return cov2_make(0.0, 0.0, 0.0);
    }
    cov3_t shared;
    int clipped;
    cov3_t d = drift_since(p, pose, anchor, anchor_xy, &shared, &clipped);
    /* b = R^T (m - t): d b / d t = -R^T, d b / d theta = (b_y, -b_x) */
    double j[2][3] = {{-c, -s, rel.y}, {s, -c, -rel.x}};
    return cov2_from_3x3(j, d.m);
}

cov2_t marginal_relative_drift(const cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy, point2_t rel)
{
    return marginal_relative_drift_cs(p, pose, cos(pose.theta), sin(pose.theta), anchor, anchor_xy, rel);
}

coslam_status_t marginal_pose_observe(cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy,
                                      double hp[2][3], cov2_t n)
{
    if (!cov3_is_finite(*p) || !cov3_is_finite(*anchor) || !cov2_is_pd(n)) {
        return COSLAM_E_NOT_PD;
    }
    cov3_t shared;
    int clipped;
    cov3_t qc = drift_since(p, pose, anchor, anchor_xy, &shared, &clipped);
    /* Kalman update of the drift with the sighting: z = Hp d + noise n */
    const cov2_t s2 = cov2_add(cov2_from_3x3(hp, qc.m), n);
    cov2_t si;
    if (cov2_inverse(s2, &si) != COSLAM_OK) {
        return COSLAM_E_NOT_PD;
    }
    double c[3][2];
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 2; ++k) {
            c[i][k] = qc.m[i][0] * hp[k][0] + qc.m[i][1] * hp[k][1] + qc.m[i][2] * hp[k][2];
        }
    }
    cov3_t np;
    for (int i = 0; i < 3; ++i) {
        const double ci0 = c[i][0] * si.xx + c[i][1] * si.xy;
        const double ci1 = c[i][0] * si.xy + c[i][1] * si.yy;
        for (int j = 0; j < 3; ++j) {
            np.m[i][j] = shared.m[i][j] + qc.m[i][j] - (ci0 * c[j][0] + ci1 * c[j][1]);
        }
    }
    np = cov3_symmetrize(np);
    /* without clipping P' = shared + post(d) <= shared + q = P; clipping
     * can raise a direction above the prior: then keep the covariance
     * intersection of the prior and the update */
    *p = clipped ? cov3_ci(*p, np) : np;
    return COSLAM_OK;
}

coslam_status_t marginal_pose_observe_gain(cov3_t *p, pose2_t pose, const cov3_t *anchor, point2_t anchor_xy,
                                           double hp[2][3], cov2_t n, double k[3][2])
{
    if (!cov3_is_finite(*p) || !cov3_is_finite(*anchor) || !cov2_is_pd(n)) {
        return COSLAM_E_NOT_PD;
    }
    cov3_t shared;
    int clipped;
    cov3_t qc = drift_since(p, pose, anchor, anchor_xy, &shared, &clipped);
    /* the drift after the correction the particle made, d - K (Hp d + v):
     * (I - K Hp) Q (I - K Hp)^T + K n K^T (Joseph form, any gain) */
    double a[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            a[i][j] = (i == j ? 1.0 : 0.0) - (k[i][0] * hp[0][j] + k[i][1] * hp[1][j]);
        }
    }
    const cov3_t aq = cov3_congruence(a, qc);
    double kt[3][2];
    for (int i = 0; i < 3; ++i) {
        kt[i][0] = k[i][0] * n.xx + k[i][1] * n.xy;
        kt[i][1] = k[i][0] * n.xy + k[i][1] * n.yy;
    }
    cov3_t np;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            np.m[i][j] = shared.m[i][j] + aq.m[i][j] + kt[i][0] * k[j][0] + kt[i][1] * k[j][1];
        }
    }
    np = cov3_symmetrize(np);
    /* a gain larger than the drift warrants (a landmark anchored a step or
     * two ago) leaves more than the prior in some direction: the particle
     * moved further than the sighting justified, and P says so (callers
     * bound a frame's sightings together: marginal_bound) */
    *p = clipped ? cov3_ci(*p, np) : np;
    return COSLAM_OK;
}

void marginal_bound(const cov3_t *before, cov3_t *p)
{
    if (!cov3_is_finite(*before) || !cov3_is_finite(*p)) {
        return;
    }
    cov3_t room;
    double chol[3][3];
    /* within: before - p PSD (a relative margin for rounding) */
    const double eps = 1e-12 * (before->m[0][0] + before->m[1][1] + before->m[2][2]);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            room.m[i][j] = before->m[i][j] - p->m[i][j] + (i == j ? eps : 0.0);
        }
    }
    if (cov3_cholesky(room, chol) != COSLAM_OK) {
        *p = cov3_ci(*before, *p);
    }
}

/* det of w a + (1 - w) b, symmetric 3x3 given by their upper triangles */
static double det3_mix(const cov3_t *a, const cov3_t *b, double w)
{
    double m[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            m[i][j] = w * a->m[i][j] + (1.0 - w) * b->m[i][j];
        }
    }
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

/* w in [0, 1] maximising f(w) = det(w ia + (1 - w) ib). f is a cubic in w
 * (det(ib + w (ia - ib)), 3x3): its coefficients from four values, then the
 * end points and the stationary points inside (0, 1) compared. log f is
 * concave on [0, 1] for PD ia, ib, so the best of these is the maximum.
 * Ties go to 1, then to 0 (keep a bound whole rather than mix). */
static double ci_weight(const cov3_t *ia, const cov3_t *ib)
{
    const double f0 = det3_mix(ia, ib, 0.0);
    const double f1 = det3_mix(ia, ib, 1.0);
    const double fm = det3_mix(ia, ib, -1.0);
    const double f2 = det3_mix(ia, ib, 2.0);
    /* f(w) = c0 + c1 w + c2 w^2 + c3 w^3 */
    const double c2 = 0.5 * (f1 + fm) - f0;
    const double c13 = 0.5 * (f1 - fm); /* c1 + c3 */
    const double c3 = (f2 - f0 - 4.0 * c2 - 2.0 * c13) / 6.0;
    const double c1 = c13 - c3;
    double best_w = 1.0;
    double best_f = f1;
    if (f0 > best_f) {
        best_w = 0.0;
        best_f = f0;
    }
    /* f'(w) = c1 + 2 c2 w + 3 c3 w^2 = 0 */
    double roots[2];
    int n_roots = 0;
    const double a = 3.0 * c3;
    const double b = 2.0 * c2;
    const double scale = fabs(a) + fabs(b) + fabs(c1);
    if (fabs(a) <= 1e-12 * scale) {
        if (b != 0.0) {
            roots[n_roots++] = -c1 / b;
        }
    } else {
        const double disc = b * b - 4.0 * a * c1;
        if (disc >= 0.0) {
            /* the stable pair of formulas (no cancellation) */
            const double q = -0.5 * (b + (b >= 0.0 ? sqrt(disc) : -sqrt(disc)));
            roots[n_roots++] = q / a;
            if (q != 0.0) {
                roots[n_roots++] = c1 / q;
            }
        }
    }
    for (int k = 0; k < n_roots; ++k) {
        const double w = roots[k];
        if (w > 0.0 && w < 1.0) {
            const double fw = det3_mix(ia, ib, w);
            if (fw > best_f) {
                best_w = w;
                best_f = fw;
            }
        }
    }
    return best_w;
}

cov3_t cov3_ci(cov3_t a, cov3_t b)
{
    cov3_t ia;
    cov3_t ib;
    if (cov3_inverse(a, &ia) != COSLAM_OK || cov3_inverse(b, &ib) != COSLAM_OK) {
        /* a singular bound: keep the one with the smaller trace */
        return a.m[0][0] + a.m[1][1] + a.m[2][2] <= b.m[0][0] + b.m[1][1] + b.m[2][2] ? a : b;
    }
    const double w = ci_weight(&ia, &ib);
    cov3_t info;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            info.m[i][j] = w * ia.m[i][j] + (1.0 - w) * ib.m[i][j];
        }
    }
    cov3_t out;
    if (cov3_inverse(cov3_symmetrize(info), &out) != COSLAM_OK) {
        return a;
    }
    return out;
}

cov2_t cov2_loewner_max(cov2_t a, cov2_t b)
{
    double l[3];
    if (cov2_cholesky(a, l) != COSLAM_OK || !cov2_is_finite(b)) {
        return cov2_add(a, b);
    }
    /* c = L^-1 b L^-T, L = [l0 0; l1 l2] */
    const double i00 = 1.0 / l[0];
    const double i11 = 1.0 / l[2];
    const double i10 = -l[1] * i00 * i11;
    double li[2][2] = {{i00, 0.0}, {i10, i11}};
    const cov2_t c = cov2_congruence(li, b);
    double lo, hi;
    cov2_eigenvalues(c, &lo, &hi);
    if (lo <= 1.0 + 1e-6 && hi <= 1.0 + 1e-6) {
        return a; /* b inside a, up to rounding */
    }
    double lm[2][2] = {{l[0], 0.0}, {l[1], l[2]}};
    return cov2_congruence(lm, cov2_clamp_eigen(c, 1.0));
}

void cov3_eigen(cov3_t a, double lam[3], double v[3][3])
{
    double m[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            m[i][j] = 0.5 * (a.m[i][j] + a.m[j][i]);
            v[i][j] = i == j ? 1.0 : 0.0;
        }
    }
    for (int sweep = 0; sweep < 32; ++sweep) {
        const double off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
        const double diag = m[0][0] * m[0][0] + m[1][1] * m[1][1] + m[2][2] * m[2][2];
        if (off <= 1e-30 * diag || off == 0.0) {
            break;
        }
        for (int p = 0; p < 2; ++p) {
            for (int q = p + 1; q < 3; ++q) {
                if (m[p][q] == 0.0) {
                    continue;
                }
                /* rotation zeroing m[p][q] (Golub and Van Loan, sec. 8.5) */
                const double theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
                const double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                const double c = 1.0 / sqrt(t * t + 1.0);
                const double s = t * c;
                for (int k = 0; k < 3; ++k) {
                    const double mkp = m[k][p];
                    const double mkq = m[k][q];
                    m[k][p] = c * mkp - s * mkq;
                    m[k][q] = s * mkp + c * mkq;
                }
                for (int k = 0; k < 3; ++k) {
                    const double mpk = m[p][k];
                    const double mqk = m[q][k];
                    m[p][k] = c * mpk - s * mqk;
                    m[q][k] = s * mpk + c * mqk;
                }
                for (int k = 0; k < 3; ++k) {
                    const double vkp = v[k][p];
                    const double vkq = v[k][q];
                    v[k][p] = c * vkp - s * vkq;
                    v[k][q] = s * vkp + c * vkq;
                }
            }
        }
    }
    for (int i = 0; i < 3; ++i) {
        lam[i] = m[i][i];
    }
}

cov3_t cov3_clamp_eigen(cov3_t a, double min_eig)
{
    double lam[3];
    double v[3][3];
    cov3_eigen(a, lam, v);
    cov3_t out;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double s = 0.0;
            for (int k = 0; k < 3; ++k) {
                s += v[i][k] * (lam[k] > min_eig ? lam[k] : min_eig) * v[j][k];
            }
            out.m[i][j] = s;
        }
    }
    return out;
}

/* unit eigenvector of the symmetric m for its simple eigenvalue lam: the
 * largest cross product of two rows of m - lam I; 0 if all vanish */
static int sym3_eigenvector(double m[3][3], double lam, double v[3])
{
    double r[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r[i][j] = m[i][j] - (i == j ? lam : 0.0);
        }
    }
    double best = 0.0;
    for (int a = 0; a < 2; ++a) {
        for (int b = a + 1; b < 3; ++b) {
            const double c[3] = {r[a][1] * r[b][2] - r[a][2] * r[b][1], r[a][2] * r[b][0] - r[a][0] * r[b][2],
                                 r[a][0] * r[b][1] - r[a][1] * r[b][0]};
            const double n2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
            if (n2 > best) {
                best = n2;
                const double inv = 1.0 / sqrt(n2);
                v[0] = c[0] * inv;
                v[1] = c[1] * inv;
                v[2] = c[2] * inv;
            }
        }
    }
    return best > 0.0 && isfinite(best);
}

cov3_t cov3_clamp_psd(cov3_t a)
{
    double m[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            m[i][j] = 0.5 * (a.m[i][j] + a.m[j][i]);
        }
    }
    /* eigenvalues: a = q I + p B, det(lam I - B) = lam^3 - 3 lam - 2 r,
     * lam = 2 cos(phi + 2 pi k / 3), phi = acos(r) / 3 (Smith 1961) */
    const double off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
    const double q = (m[0][0] + m[1][1] + m[2][2]) / 3.0;
    const double d0 = m[0][0] - q;
    const double d1 = m[1][1] - q;
    const double d2 = m[2][2] - q;
    const double p = sqrt((d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * off) / 6.0);
    if (p == 0.0 && isfinite(q)) {
        /* a multiple of I (a zero drift, where the anchor is the present
         * pose marginal): kept, or zero, as cov3_clamp_eigen gives it */
        const double v = q > 0.0 ? q : 0.0;
        return cov3_diag(v, v, v);
    }
    if (!(p > 0.0) || !isfinite(p)) {
        return cov3_clamp_eigen(a, 0.0); /* not finite */
    }
    const double ip = 1.0 / p;
    const double b00 = d0 * ip, b11 = d1 * ip, b22 = d2 * ip;
    const double b01 = m[0][1] * ip, b02 = m[0][2] * ip, b12 = m[1][2] * ip;
    double r = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02));
    r = r < -1.0 ? -1.0 : (r > 1.0 ? 1.0 : r);
    const double phi = acos(r) / 3.0;
    const double l2 = q + 2.0 * p * cos(phi);                       /* largest */
    const double l0 = q + 2.0 * p * cos(phi + 2.0 * COSLAM_PI / 3.0); /* smallest */
    const double l1 = 3.0 * q - l0 - l2;
    const double scale = fabs(l0) + fabs(l2);
    cov3_t out;
    double v[3];
    if (l0 >= 0.0) {
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                out.m[i][j] = m[i][j];
            }
        }
        return out;
    }
    if (l1 >= 0.0) {
        /* one negative: remove it, a - l0 v0 v0^T */
        if (l1 - l0 <= 1e-6 * scale || !sym3_eigenvector(m, l0, v)) {
            return cov3_clamp_eigen(a, 0.0);
        }
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                out.m[i][j] = m[i][j] - l0 * v[i] * v[j];
            }
        }
        return out;
    }
    if (l2 > 0.0) {
        /* two negative: what is left is the positive one, l2 v2 v2^T */
        if (l2 - l1 <= 1e-6 * scale || !sym3_eigenvector(m, l2, v)) {
            return cov3_clamp_eigen(a, 0.0);
        }
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                out.m[i][j] = l2 * v[i] * v[j];
            }
        }
        return out;
    }
    return cov3_zero();
}

cov3_t cov3_loewner_max(cov3_t a, cov3_t b)
{
    double l[3][3];
    if (cov3_cholesky(a, l) != COSLAM_OK || !cov3_is_finite(b)) {
        return cov3_symmetrize(cov3_add(a, b));
    }
    /* li = L^-1 (lower triangular) */
    double li[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    for (int j = 0; j < 3; ++j) {
        li[j][j] = 1.0 / l[j][j];
        for (int i = j + 1; i < 3; ++i) {
            double s = 0.0;
            for (int k = j; k < i; ++k) {
                s += l[i][k] * li[k][j];
            }
            li[i][j] = -s / l[i][i];
        }
    }
    const cov3_t c = cov3_congruence(li, b);
    double lam[3];
    double u[3][3];
    cov3_eigen(c, lam, u);
    if (lam[0] <= 1.0 + 1e-6 && lam[1] <= 1.0 + 1e-6 && lam[2] <= 1.0 + 1e-6) {
        return a; /* b inside a, up to rounding */
    }
    return cov3_congruence(l, cov3_clamp_eigen(c, 1.0));
}
