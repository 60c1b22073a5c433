#include "coslam/cov3.h"

#include <math.h>

cov3_t cov3_zero(void)
{
    cov3_t r = {{{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}}};
    return r;
}

cov3_t cov3_diag(double a, double b, double c)
{
    cov3_t r = cov3_zero();
    r.m[0][0] = a;
    r.m[1][1] = b;
    r.m[2][2] = c;
    return r;
}

cov3_t cov3_add(cov3_t a, cov3_t b)
{
    cov3_t r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r.m[i][j] = a.m[i][j] + b.m[i][j];
        }
    }
    return r;
}

cov3_t cov3_symmetrize(cov3_t a)
{
    /* every element written once, from values read once: writing the
     * off-diagonal pairs into a copy of a and returning that cost a
     * store-forwarding stall per pair on x86-64, about an eighth of a
     * Fast-SLAM 2.0 step (perf, coslam-bench-scale --quick) */
    const double m01 = 0.5 * (a.m[0][1] + a.m[1][0]);
    const double m02 = 0.5 * (a.m[0][2] + a.m[2][0]);
    const double m12 = 0.5 * (a.m[1][2] + a.m[2][1]);
    const cov3_t r = {{{a.m[0][0], m01, m02}, {m01, a.m[1][1], m12}, {m02, m12, a.m[2][2]}}};
    return r;
}

double cov3_det(cov3_t a)
{
    double(*m)[3] = a.m;
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

int cov3_is_finite(cov3_t a)
{
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            if (!isfinite(a.m[i][j])) {
                return 0;
            }
        }
    }
    return 1;
}

coslam_status_t cov3_cholesky(cov3_t a, double l[3][3])
{
    if (!cov3_is_finite(a)) {
        return COSLAM_E_NOT_PD;
    }
    double t[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    for (int j = 0; j < 3; ++j) {
        double d = a.m[j][j];
        for (int k = 0; k < j; ++k) {
            d -= t[j][k] * t[j][k];
        }
        if (!(d > 0.0)) {
            return COSLAM_E_NOT_PD;
        }
        t[j][j] = sqrt(d);
        for (int i = j + 1; i < 3; ++i) {
            double s = a.m[i][j];
            for (int k = 0; k < j; ++k) {
                s -= t[i][k] * t[j][k];
            }
            t[i][j] = s / t[j][j];
        }
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            l[i][j] = t[i][j];
        }
    }
    return COSLAM_OK;
}

/* finite and symmetric to 1e-9 relative */
static int finite_symmetric(cov3_t a)
{
    if (!cov3_is_finite(a)) {
        return 0;
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = i + 1; j < 3; ++j) {
            const double tol = 1e-9 * (fabs(a.m[i][j]) + fabs(a.m[j][i])) + 1e-300;
            if (fabs(a.m[i][j] - a.m[j][i]) > tol) {
                return 0;
            }
        }
    }
    return 1;
}

int cov3_is_pd(cov3_t a)
{
    double l[3][3];
    return finite_symmetric(a) && cov3_cholesky(a, l) == COSLAM_OK;
}

int cov3_is_psd(cov3_t a)
{
    if (!finite_symmetric(a)) {
        return 0;
    }
    /* a + eps I is positive definite for every eigenvalue of a above -eps:
     * the rounding of a PSD matrix (a filter's pose covariance that has
     * not grown yet is exactly 0) passes, a real negative direction does
     * not. eps scales with the trace, so the test has no units. */
    const double tr = a.m[0][0] + a.m[1][1] + a.m[2][2];
    if (!(tr >= 0.0)) {
        return 0;
    }
    const double eps = 1e-9 * tr + 1e-300;
    for (int i = 0; i < 3; ++i) {
        a.m[i][i] += eps;
    }
    double l[3][3];
    return cov3_cholesky(a, l) == COSLAM_OK;
}

coslam_status_t cov3_inverse(cov3_t a, cov3_t *out)
{
    double l[3][3];
    const coslam_status_t st = cov3_cholesky(a, l);
    if (st != COSLAM_OK) {
        return st;
    }
    /* invert L (lower triangular), then a^-1 = L^-T L^-1 */
    double li[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    for (int i = 0; i < 3; ++i) {
        li[i][i] = 1.0 / l[i][i];
        for (int j = 0; j < i; ++j) {
            double s = 0.0;
            for (int k = j; k < i; ++k) {
                s -= l[i][k] * li[k][j];
            }
            li[i][j] = s / l[i][i];
        }
    }
    cov3_t r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double s = 0.0;
            for (int k = 0; k < 3; ++k) {
                s += li[k][i] * li[k][j];
            }
            r.m[i][j] = s;
        }
    }
    *out = cov3_symmetrize(r);
    return COSLAM_OK;
}

coslam_status_t cov3_mahalanobis2(cov3_t a, const double v[3], double *d2)
{
    double l[3][3];
    const coslam_status_t st = cov3_cholesky(a, l);
    if (st != COSLAM_OK) {
        return st;
    }
    /* solve L y = v; d2 = |y|^2 */
    double y[3];
    double s = 0.0;
    for (int i = 0; i < 3; ++i) {
        double t = v[i];
        for (int k = 0; k < i; ++k) {
            t -= l[i][k] * y[k];
        }
        y[i] = t / l[i][i];
        s += y[i] * y[i];
    }
    *d2 = s;
    return COSLAM_OK;
}

void mat3_mul(double a[3][3], double b[3][3], double c[3][3])
{
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
}

cov3_t cov3_congruence(double g[3][3], cov3_t a)
{
    double t[3][3];
    mat3_mul(g, a.m, t);
    cov3_t r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r.m[i][j] = t[i][0] * g[j][0] + t[i][1] * g[j][1] + t[i][2] * g[j][2];
        }
    }
    return cov3_symmetrize(r);
}
