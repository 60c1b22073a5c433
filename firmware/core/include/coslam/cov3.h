/*
 * coslam/cov3.h - symmetric 3x3 matrices (pose covariances) and the few
 * general 3x3 operations the filters need. Row-major double[3][3].
 *
 * Functions taking a symmetric input read both triangles; functions producing
 * a symmetric output write both triangles, averaged so that the result is
 * exactly symmetric. All O(1), stateless.
 */
#ifndef COSLAM_COV3_H
#define COSLAM_COV3_H

#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double m[3][3];
} cov3_t;

cov3_t cov3_zero(void);
cov3_t cov3_diag(double a, double b, double c);
cov3_t cov3_add(cov3_t a, cov3_t b);
/** Replace a by (a + a^T) / 2. */
cov3_t cov3_symmetrize(cov3_t a);
double cov3_det(cov3_t a);
int cov3_is_finite(cov3_t a);
/** 1 if finite, symmetric to 1e-9 relative, and positive definite (Cholesky succeeds). */
int cov3_is_pd(cov3_t a);
/** 1 if finite, symmetric to 1e-9 relative, and positive semi-definite to
 *  rounding: a + 1e-9 trace(a) I is positive definite (Cholesky succeeds),
 *  so a zero matrix passes and an indefinite one (xx = yy = 0.01, xy = 1)
 *  does not. */
int cov3_is_psd(cov3_t a);

/** Cholesky a = L L^T, L lower triangular (upper part zeroed). E_NOT_PD otherwise. */
coslam_status_t cov3_cholesky(cov3_t a, double l[3][3]);

/** Inverse of a PD matrix via Cholesky. E_NOT_PD otherwise, *out untouched. */
coslam_status_t cov3_inverse(cov3_t a, cov3_t *out);

/** Squared Mahalanobis distance v^T a^-1 v. E_NOT_PD if a is not PD. */
coslam_status_t cov3_mahalanobis2(cov3_t a, const double v[3], double *d2);

/** G a G^T for a general 3x3 G (symmetrised). */
cov3_t cov3_congruence(double g[3][3], cov3_t a);

/** General 3x3 product c = a b (c may alias neither a nor b). */
void mat3_mul(double a[3][3], double b[3][3], double c[3][3]);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_COV3_H */
