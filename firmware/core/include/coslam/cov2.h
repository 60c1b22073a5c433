/*
 * coslam/cov2.h - symmetric 2x2 matrices (landmark covariances, innovation
 * covariances). Stored as the three unique entries, so symmetry holds by
 * construction; positive definiteness is checked where it matters.
 *
 * All functions are O(1), stateless, and use only their arguments.
 * Units follow the quantity stored (m^2 for a landmark position covariance,
 * mixed m^2 / m rad / rad^2 for a range-bearing innovation covariance).
 */
#ifndef COSLAM_COV2_H
#define COSLAM_COV2_H

#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double xx;
    double xy;
    double yy;
} cov2_t;

cov2_t cov2_make(double xx, double xy, double yy);
cov2_t cov2_add(cov2_t a, cov2_t b);
cov2_t cov2_scale(cov2_t a, double k);
double cov2_det(cov2_t a);
double cov2_trace(cov2_t a);

/** 1 if all entries are finite and the matrix is positive definite. */
int cov2_is_pd(cov2_t a);

/** 1 if all entries are finite. */
int cov2_is_finite(cov2_t a);

/**
 * Inverse of a positive definite matrix.
 * Returns COSLAM_E_NOT_PD (and leaves *out untouched) otherwise.
 */
coslam_status_t cov2_inverse(cov2_t a, cov2_t *out);

/**
 * Cholesky factor: a = L L^T with L = [l[0] 0; l[1] l[2]], l[0], l[2] > 0.
 * Returns COSLAM_E_NOT_PD when a is not positive definite.
 */
coslam_status_t cov2_cholesky(cov2_t a, double l[3]);

/** Squared Mahalanobis distance v^T a^-1 v; COSLAM_E_NOT_PD if a is not PD. */
coslam_status_t cov2_mahalanobis2(cov2_t a, double vx, double vy, double *d2);

/** J a J^T for a general 2x2 J (rotation of a covariance is J = R). j is read only. */
cov2_t cov2_congruence(double j[2][2], cov2_t a);

/** J P J^T for a 2x3 J and a symmetric 3x3 P (row-major, both read only). */
cov2_t cov2_from_3x3(double j[2][3], double p[3][3]);

/** Eigenvalues, lam_min <= lam_max. */
void cov2_eigenvalues(cov2_t a, double *lam_min, double *lam_max);

/**
 * v v^T / |v|^2 for the eigenvector v of symmetric `a` belonging to its
 * larger eigenvalue `lmax` (from cov2_eigenvalues). 0 if `a` is isotropic
 * (every direction is one), `proj` untouched.
 */
int cov2_eig_projector(cov2_t a, double lmax, cov2_t *proj);

/**
 * Nearest matrix with every eigenvalue >= min_eig (eigenvalue clamping).
 * Used to keep covariances positive definite against rounding.
 */
cov2_t cov2_clamp_eigen(cov2_t a, double min_eig);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_COV2_H */
