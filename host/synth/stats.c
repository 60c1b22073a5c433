#include "stats.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* inverse of the standard normal CDF (Acklam's rational approximation, |err| < 1.2e-9) */
static double norm_quantile(double p)
{
    static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                               1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00};
    static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                               6.680131188771972e+01, -1.328068155288572e+01};
    static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                               -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00};
    static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                               3.754408661907416e+00};
    const double pl = 0.02425;
    if (p < pl) {
        const double q = sqrt(-2.0 * log(p));
        return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
               ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
    }
    if (p > 1.0 - pl) {
        const double q = sqrt(-2.0 * log(1.0 - p));
        return -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
               ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
    }
    const double q = p - 0.5;
    const double r = q * q;
    return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
           (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
}

double chi2_quantile(double p, double dof)
{
    const double z = norm_quantile(p);
    const double h = 2.0 / (9.0 * dof);
    const double t = 1.0 - h + z * sqrt(h);
    return dof * t * t * t;
}

void nees_band95(int k, int d, double *lo, double *hi)
{
    const double dof = (double)k * d;
    *lo = chi2_quantile(0.025, dof) / k;
    *hi = chi2_quantile(0.975, dof) / k;
}

double nees_pose(pose2_t est, cov3_t cov, pose2_t truth)
{
    const double e[3] = {est.x - truth.x, est.y - truth.y, angle_wrap(est.theta - truth.theta)};
    double d2;
    if (cov3_mahalanobis2(cov3_symmetrize(cov), e, &d2) != COSLAM_OK) {
        return NAN;
    }
    return d2;
}

double nees_point(point2_t est, cov2_t cov, point2_t truth)
{
    double d2;
    if (cov2_mahalanobis2(cov, est.x - truth.x, est.y - truth.y, &d2) != COSLAM_OK) {
        return NAN;
    }
    return d2;
}

void hungarian(const double *cost, int n, int m, int *row_to_col)
{
    /* Shortest augmenting paths with row/column potentials (Kuhn-Munkres),
     * 1-based internally; p[j] = row matched to column j, 0 = none. */
    double *u = calloc((size_t)n + 1, sizeof *u);
    double *v = calloc((size_t)m + 1, sizeof *v);
    double *minv = malloc(((size_t)m + 1) * sizeof *minv);
    int *p = calloc((size_t)m + 1, sizeof *p);
    int *way = calloc((size_t)m + 1, sizeof *way);
    char *used = malloc((size_t)m + 1);
    for (int i = 1; i <= n; ++i) {
        p[0] = i;
        int j0 = 0;
        for (int j = 0; j <= m; ++j) {
            minv[j] = INFINITY;
            used[j] = 0;
        }
        do {
            used[j0] = 1;
            const int i0 = p[j0];
            double delta = INFINITY;
            int j1 = 0;
            for (int j = 1; j <= m; ++j) {
                if (used[j]) {
                    continue;
                }
                const double cur = cost[(long)(i0 - 1) * m + (j - 1)] - u[i0] - v[j];
                if (cur < minv[j]) {
                    minv[j] = cur;
                    way[j] = j0;
                }
                if (minv[j] < delta) {
                    delta = minv[j];
                    j1 = j;
                }
            }
            for (int j = 0; j <= m; ++j) {
                if (used[j]) {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
        } while (p[j0] != 0);
        do {
            const int j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
        } while (j0 != 0);
    }
    for (int j = 1; j <= m; ++j) {
        if (p[j] != 0) {
            row_to_col[p[j] - 1] = j - 1;
        }
    }
    free(u);
    free(v);
    free(minv);
    free(p);
    free(way);
    free(used);
}

void eval_map(const map_estimate_t *est, const point2_t *truth, const int *n_seen, int n_truth, int min_seen,
              double gate_m, map_eval_t *out)
{
    memset(out, 0, sizeof *out);
    const int n = est->n_landmarks;
    out->n_estimated = n;
    for (int i = 0; i < n; ++i) {
        out->match[i] = -1;
    }
    /* square problem: rows = estimates + dummies, cols = truths + dummies */
    const int sz = (n > n_truth ? n : n_truth);
    if (sz == 0) {
        return;
    }
    const double big = 1e6;
    const double gate2 = gate_m * gate_m;
    double *cost = (double *)malloc(sizeof(double) * (size_t)sz * (size_t)sz);
    int *r2c = (int *)malloc(sizeof(int) * (size_t)sz);
    for (int i = 0; i < sz; ++i) {
        for (int j = 0; j < sz; ++j) {
            double c = gate2; /* unmatched costs as much as a pair at the gate */
            if (i < n && j < n_truth) {
                const double dx = est->lm[i].mean.x - truth[j].x;
                const double dy = est->lm[i].mean.y - truth[j].y;
                const double d2 = dx * dx + dy * dy;
                c = d2 < gate2 ? d2 : big;
            }
            cost[(long)i * sz + j] = c;
        }
    }
    hungarian(cost, sz, sz, r2c);
    int *truth_matched = (int *)calloc((size_t)(n_truth > 0 ? n_truth : 1), sizeof(int));
    double se = 0.0;
    double nees = 0.0;
    for (int i = 0; i < n; ++i) {
        const int j = r2c[i];
        if (j < n_truth && cost[(long)i * sz + j] < gate2) {
            out->match[i] = j;
            truth_matched[j] = 1;
            const double dx = est->lm[i].mean.x - truth[j].x;
            const double dy = est->lm[i].mean.y - truth[j].y;
            const double e2 = dx * dx + dy * dy;
            se += e2;
            if (sqrt(e2) > out->max_err_m) {
                out->max_err_m = sqrt(e2);
            }
            nees += nees_point(est->lm[i].mean, est->lm[i].cov, truth[j]);
            out->n_matched++;
        } else {
            out->n_spurious++;
        }
    }
    for (int j = 0; j < n_truth; ++j) {
        if (!truth_matched[j] && (n_seen == NULL || n_seen[j] >= min_seen)) {
            out->n_missed++;
        }
    }
    out->rmse_m = out->n_matched > 0 ? sqrt(se / out->n_matched) : 0.0;
    out->nees_mean = out->n_matched > 0 ? nees / out->n_matched : 0.0;
    free(truth_matched);
    free(r2c);
    free(cost);
}
