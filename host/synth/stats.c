#include "stats.h"

#include <math.h>
#include <stdint.h>
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

void nees_pose_parts(pose2_t est, cov3_t cov, pose2_t truth, double *xy, double *theta)
{
    const cov2_t p = {cov.m[0][0], 0.5 * (cov.m[0][1] + cov.m[1][0]), cov.m[1][1]};
    const point2_t e = {est.x, est.y};
    const point2_t t = {truth.x, truth.y};
    const double dth = angle_wrap(est.theta - truth.theta);
    *xy = nees_point(e, p, t);
    *theta = cov.m[2][2] > 0.0 ? dth * dth / cov.m[2][2] : NAN;
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

/* ---- assign_gated (stats.h) ---- */

typedef struct {
    int64_t key;
    int j;
} cell_item_t;

static int cell_item_cmp(const void *a, const void *b)
{
    const cell_item_t *x = (const cell_item_t *)a;
    const cell_item_t *y = (const cell_item_t *)b;
    return x->key < y->key ? -1 : x->key > y->key ? 1 : (x->j > y->j) - (x->j < y->j);
}

typedef struct {
    int i, j;
    double d2;
} gated_pair_t;

static int gated_pair_cmp(const void *a, const void *b)
{
    const gated_pair_t *x = (const gated_pair_t *)a;
    const gated_pair_t *y = (const gated_pair_t *)b;
    if (x->d2 != y->d2) {
        return x->d2 < y->d2 ? -1 : 1;
    }
    return x->i != y->i ? (x->i > y->i) - (x->i < y->i) : (x->j > y->j) - (x->j < y->j);
}

static int64_t cell_key(double x, double y, double cell)
{
    /* clamped: a landmark a million cells away shares an edge cell, which
     * only costs distance checks */
    double cx = floor(x / cell);
    double cy = floor(y / cell);
    cx = cx < -1e6 ? -1e6 : cx > 1e6 ? 1e6 : cx;
    cy = cy < -1e6 ? -1e6 : cy > 1e6 ? 1e6 : cy;
    return (int64_t)(cx + 2e6) * 8000000 + (int64_t)(cy + 2e6);
}

static int uf_find(int *uf, int x)
{
    while (uf[x] != x) {
        uf[x] = uf[uf[x]];
        x = uf[x];
    }
    return x;
}

int assign_gated(const point2_t *est, const uint8_t *est_sig, int n, const point2_t *truth,
                 const uint8_t *truth_sig, int n_truth, double gate_m, int *match)
{
    for (int i = 0; i < n; ++i) {
        match[i] = -1;
    }
    if (n <= 0 || n_truth <= 0 || !(gate_m > 0.0)) {
        return 0;
    }
    const double gate2 = gate_m * gate_m;
    int greedy = 0;
    size_t cap = (size_t)n * 4 + 16;
    size_t np = 0;
    /* everything on the heap is freed at out: (host code) */
    int *root = NULL, *count = NULL, *loc = NULL, *r2c = NULL, *row_est = NULL, *col_truth = NULL;
    size_t *by_root = NULL;
    double *cost = NULL;
    cell_item_t *cells = (cell_item_t *)malloc(sizeof *cells * (size_t)n_truth);
    gated_pair_t *pairs = (gated_pair_t *)malloc(sizeof *pairs * cap);
    int *uf = (int *)malloc(sizeof(int) * (size_t)(n + n_truth));
    int *taken = (int *)calloc((size_t)n_truth, sizeof(int));
    if (cells == NULL || pairs == NULL || uf == NULL || taken == NULL) {
        greedy = -1;
        goto out;
    }
    for (int j = 0; j < n_truth; ++j) {
        cells[j].key = cell_key(truth[j].x, truth[j].y, gate_m);
        cells[j].j = j;
    }
    qsort(cells, (size_t)n_truth, sizeof *cells, cell_item_cmp);
    /* candidates: the 3 x 3 cells around each estimate */
    for (int i = 0; i < n; ++i) {
        if (!(isfinite(est[i].x) && isfinite(est[i].y))) {
            continue;
        }
        for (int dx = -1; dx <= 1; ++dx) {
            for (int dy = -1; dy <= 1; ++dy) {
                const int64_t key = cell_key(est[i].x + dx * gate_m, est[i].y + dy * gate_m, gate_m);
                int lo = 0, hi = n_truth;
                while (lo < hi) {
                    const int mid = lo + (hi - lo) / 2;
                    if (cells[mid].key < key) {
                        lo = mid + 1;
                    } else {
                        hi = mid;
                    }
                }
                for (int k = lo; k < n_truth && cells[k].key == key; ++k) {
                    const int j = cells[k].j;
                    if (est_sig != NULL && truth_sig != NULL && est_sig[i] != truth_sig[j]) {
                        continue;
                    }
                    const double ex = est[i].x - truth[j].x;
                    const double ey = est[i].y - truth[j].y;
                    const double d2 = ex * ex + ey * ey;
                    if (!(d2 < gate2)) {
                        continue;
                    }
                    int dup = 0; /* a clamped edge cell can be visited twice */
                    for (size_t q = np; q > 0 && pairs[q - 1].i == i; --q) {
                        dup |= pairs[q - 1].j == j;
                    }
                    if (dup) {
                        continue;
                    }
                    if (np == cap) {
                        cap *= 2;
                        gated_pair_t *p2 = (gated_pair_t *)realloc(pairs, sizeof *pairs * cap);
                        if (p2 == NULL) {
                            greedy = -1;
                            goto out;
                        }
                        pairs = p2;
                    }
                    pairs[np].i = i;
                    pairs[np].j = j;
                    pairs[np].d2 = d2;
                    np++;
                }
            }
        }
    }
    /* components: estimates 0..n-1, true landmarks n..n+n_truth-1 */
    for (int k = 0; k < n + n_truth; ++k) {
        uf[k] = k;
    }
    for (size_t q = 0; q < np; ++q) {
        const int a = uf_find(uf, pairs[q].i);
        const int b = uf_find(uf, n + pairs[q].j);
        if (a != b) {
            uf[a] = b;
        }
    }
    /* pairs sorted by component root, then by distance (greedy order) */
    {
        root = (int *)malloc(sizeof(int) * (np > 0 ? np : 1));
        if (root == NULL) {
            greedy = -1;
            goto out;
        }
        qsort(pairs, np, sizeof *pairs, gated_pair_cmp);
        for (size_t q = 0; q < np; ++q) {
            root[q] = uf_find(uf, pairs[q].i);
        }
        /* stable counting by root: a bucket per root, pairs in distance order */
        count = (int *)calloc((size_t)(n + n_truth) + 1, sizeof(int));
        by_root = (size_t *)malloc(sizeof(size_t) * (np > 0 ? np : 1));
        loc = (int *)malloc(sizeof(int) * (size_t)(n + n_truth));
        if (count == NULL || by_root == NULL || loc == NULL) {
            greedy = -1;
            goto out;
        }
        for (size_t q = 0; q < np; ++q) {
            count[root[q] + 1]++;
        }
        for (int k = 0; k < n + n_truth; ++k) {
            count[k + 1] += count[k];
        }
        for (size_t q = 0; q < np; ++q) {
            by_root[count[root[q]]++] = q;
        }
        /* count[r] is now the end of root r's bucket; its start is the end of r - 1 */
        for (int k = 0; k < n + n_truth; ++k) {
            loc[k] = -1;
        }
        size_t start = 0;
        for (int r = 0; r < n + n_truth; ++r) {
            const size_t end = (size_t)count[r];
            if (end == start) {
                continue;
            }
            /* rows and columns of this component */
            int nr = 0, nc = 0;
            for (size_t q = start; q < end; ++q) {
                const gated_pair_t *p = &pairs[by_root[q]];
                if (loc[p->i] < 0) {
                    loc[p->i] = nr++;
                }
                if (loc[n + p->j] < 0) {
                    loc[n + p->j] = nc++;
                }
            }
            if (nr + nc > ASSIGN_GATED_OPT_MAX) {
                greedy++;
                for (size_t q = start; q < end; ++q) {
                    const gated_pair_t *p = &pairs[by_root[q]];
                    if (match[p->i] < 0 && !taken[p->j]) {
                        match[p->i] = p->j;
                        taken[p->j] = 1;
                    }
                }
            } else {
                /* square problem (nr + nc): estimates + dummies x truths + dummies;
                 * staying unmatched costs u, a non-candidate pair "big". u is
                 * large enough that one more pair always beats any saving in
                 * distance (most pairs first, then the least sum of d2: what
                 * the single square problem with "big" non-pairs gave) */
                const int sz = nr + nc;
                const double u = gate2 * (double)(sz + 1);
                const double big = 4.0 * u * (double)(sz + 1);
                cost = (double *)malloc(sizeof(double) * (size_t)sz * (size_t)sz);
                r2c = (int *)malloc(sizeof(int) * (size_t)sz);
                row_est = (int *)malloc(sizeof(int) * (size_t)nr);
                col_truth = (int *)malloc(sizeof(int) * (size_t)nc);
                if (cost == NULL || r2c == NULL || row_est == NULL || col_truth == NULL) {
                    greedy = -1;
                    goto out;
                }
                for (int a = 0; a < sz; ++a) {
                    for (int b = 0; b < sz; ++b) {
                        cost[(size_t)a * (size_t)sz + (size_t)b] = (a < nr && b < nc) ? big : (a >= nr && b >= nc) ? 0.0 : u;
                    }
                }
                for (size_t q = start; q < end; ++q) {
                    const gated_pair_t *p = &pairs[by_root[q]];
                    row_est[loc[p->i]] = p->i;
                    col_truth[loc[n + p->j]] = p->j;
                    cost[(size_t)loc[p->i] * (size_t)sz + (size_t)loc[n + p->j]] = p->d2;
                }
                hungarian(cost, sz, sz, r2c);
                for (int a = 0; a < nr; ++a) {
                    const int b = r2c[a];
                    if (b < nc && cost[(size_t)a * (size_t)sz + (size_t)b] < gate2) {
                        match[row_est[a]] = col_truth[b];
                        taken[col_truth[b]] = 1;
                    }
                }
                free(cost);
                free(r2c);
                free(row_est);
                free(col_truth);
                cost = NULL;
                r2c = row_est = col_truth = NULL;
            }
            start = end;
        }
    }
out:
    if (greedy < 0) {
        for (int i = 0; i < n; ++i) {
            match[i] = -1;
        }
    }
    free(cells);
    free(pairs);
    free(uf);
    free(taken);
    free(root);
    free(count);
    free(by_root);
    free(loc);
    free(cost);
    free(r2c);
    free(row_est);
    free(col_truth);
    return greedy;
}

void eval_map(const map_estimate_t *est, const point2_t *truth, const int *n_seen, int n_truth, int min_seen,
              double gate_m, map_eval_t *out)
{
    eval_map_signed(est, truth, NULL, n_seen, n_truth, min_seen, gate_m, out);
}

static void eval_map_lm(const map_landmark_t *lm, int n, const point2_t *truth, const uint8_t *truth_sig,
                        const int *n_seen, int n_truth, int min_seen, double gate_m, map_eval_t *out);

void eval_map_signed(const map_estimate_t *est, const point2_t *truth, const uint8_t *truth_sig, const int *n_seen,
                     int n_truth, int min_seen, double gate_m, map_eval_t *out)
{
    eval_map_lm(est->lm, est->n_landmarks, truth, truth_sig, n_seen, n_truth, min_seen, gate_m, out);
}

void eval_map_whole(const map_whole_t *est, const point2_t *truth, const int *n_seen, int n_truth, int min_seen,
                   double gate_m, map_eval_t *out)
{
    eval_map_lm(est->lm, est->n_landmarks, truth, NULL, n_seen, n_truth, min_seen, gate_m, out);
}

static void eval_map_lm(const map_landmark_t *lm, int n, const point2_t *truth, const uint8_t *truth_sig,
                        const int *n_seen, int n_truth, int min_seen, double gate_m, map_eval_t *out)
{
    memset(out, 0, sizeof *out);
    out->n_estimated = n;
    for (int i = 0; i < n; ++i) {
        out->match[i] = -1;
    }
    if (n == 0 && n_truth == 0) {
        return;
    }
    /* gated, per component (assign_gated): most pairs, then least sum of d2 */
    point2_t *mean = (point2_t *)calloc((size_t)(n > 0 ? n : 1), sizeof(point2_t));
    int *r2c = (int *)calloc((size_t)(n > 0 ? n : 1), sizeof(int));
    uint8_t *sig = (uint8_t *)calloc((size_t)(n > 0 ? n : 1), sizeof(uint8_t));
    for (int i = 0; i < n; ++i) {
        mean[i] = lm[i].mean;
        sig[i] = lm[i].signature;
    }
    (void)assign_gated(mean, truth_sig != NULL ? sig : NULL, n, truth, truth_sig, n_truth, gate_m, r2c);
    free(sig);
    int *truth_matched = (int *)calloc((size_t)(n_truth > 0 ? n_truth : 1), sizeof(int));
    double se = 0.0;
    double nees = 0.0;
    for (int i = 0; i < n; ++i) {
        const int j = r2c[i];
        if (j >= 0) {
            out->match[i] = j;
            truth_matched[j] = 1;
            const double dx = lm[i].mean.x - truth[j].x;
            const double dy = lm[i].mean.y - truth[j].y;
            const double e2 = dx * dx + dy * dy;
            se += e2;
            if (sqrt(e2) > out->max_err_m) {
                out->max_err_m = sqrt(e2);
            }
            nees += nees_point(lm[i].mean, lm[i].cov, truth[j]);
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
    free(mean);
}

/* ---- eval_map_rigid (stats.h: method and cost) ---- */

/* Truth bucketed into square cells of side >= gate, so every true landmark
 * within the gate of a point lies in the 3 x 3 cells around it. */
typedef struct {
    const point2_t *pt;
    double x0;
    double y0;
    double inv_cell; /* 1 / cell side */
    int nx;
    int ny;
    int *start; /* nx * ny + 1 offsets into item */
    int *item;
} rigid_grid_t;

/* Translation votes of one rotation step: cells of side h with their vote
 * count (2 bytes, so the grid stays in cache; cleared after each step);
 * `peak` lists the cells that reached the count worth a look. */
typedef struct {
    double x0;
    double y0;
    double h;
    int nx;
    int ny;
    uint16_t *count;
    int *peak;
    int n_peak;
} rigid_votes_t;

typedef struct {
    pose2_t t;
    point2_t c_world; /* the estimate's centroid moved by t */
    int votes;
} rigid_hyp_t;

typedef struct {
    int i;
    int j;
    double d2;
} rigid_cand_t;

static int rigid_grid_build(rigid_grid_t *g, const point2_t *truth, int n, double gate_m)
{
    enum { MAX_CELLS = 4096 };
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (int j = 0; j < n; ++j) {
        if (isfinite(truth[j].x) && isfinite(truth[j].y)) {
            x0 = fmin(x0, truth[j].x);
            y0 = fmin(y0, truth[j].y);
            x1 = fmax(x1, truth[j].x);
            y1 = fmax(y1, truth[j].y);
        }
    }
    if (!(x0 <= x1)) {
        x0 = y0 = x1 = y1 = 0.0; /* no finite truth: one empty cell */
    }
    double cell = gate_m;
    while (((x1 - x0) / cell + 1.0) * ((y1 - y0) / cell + 1.0) > (double)MAX_CELLS) {
        cell *= 2.0;
    }
    g->pt = truth;
    g->x0 = x0;
    g->y0 = y0;
    g->inv_cell = 1.0 / cell;
    g->nx = (int)floor((x1 - x0) / cell) + 1;
    g->ny = (int)floor((y1 - y0) / cell) + 1;
    const size_t nc = (size_t)g->nx * (size_t)g->ny;
    g->start = (int *)calloc(nc + 1, sizeof(int));
    g->item = (int *)malloc(sizeof(int) * (size_t)(n > 0 ? n : 1));
    int *fill = (int *)calloc(nc, sizeof(int));
    if (g->start == NULL || g->item == NULL || fill == NULL) {
        free(fill);
        return -1;
    }
    /* counting sort of the truth by cell */
    for (int pass = 0; pass < 2; ++pass) {
        for (int j = 0; j < n; ++j) {
            if (!(isfinite(truth[j].x) && isfinite(truth[j].y))) {
                continue;
            }
            const int cx = (int)floor((truth[j].x - x0) / cell);
            const int cy = (int)floor((truth[j].y - y0) / cell);
            const size_t c = (size_t)cy * (size_t)g->nx + (size_t)cx;
            if (pass == 0) {
                g->start[c + 1]++;
            } else {
                g->item[g->start[c] + fill[c]++] = j;
            }
        }
        if (pass == 0) {
            for (size_t c = 0; c < nc; ++c) {
                g->start[c + 1] += g->start[c];
            }
        }
    }
    free(fill);
    return 0;
}

static int rigid_cand_cmp(const void *pa, const void *pb)
{
    const rigid_cand_t *a = (const rigid_cand_t *)pa;
    const rigid_cand_t *b = (const rigid_cand_t *)pb;
    if (a->d2 != b->d2) {
        return a->d2 < b->d2 ? -1 : 1;
    }
    if (a->i != b->i) {
        return a->i < b->i ? -1 : 1;
    }
    return (a->j > b->j) - (a->j < b->j);
}

static int rigid_double_cmp(const void *pa, const void *pb)
{
    const double a = *(const double *)pa;
    const double b = *(const double *)pb;
    return (a > b) - (a < b);
}

/* Insert h into the list (n entries, capacity cap, most votes first). A
 * transform that moves the estimate (radius r_m about its centroid) by less
 * than sep_m from a listed one is the same hypothesis: the one with more
 * votes stays (the first on a tie). */
static void rigid_keep(rigid_hyp_t *list, int *n, int cap, rigid_hyp_t h, double r_m, double sep_m)
{
    int at = -1;
    for (int k = 0; k < *n; ++k) {
        const double sep = hypot(h.c_world.x - list[k].c_world.x, h.c_world.y - list[k].c_world.y) +
                           fabs(angle_wrap(h.t.theta - list[k].t.theta)) * r_m;
        if (sep < sep_m) {
            if (h.votes <= list[k].votes) {
                return;
            }
            at = k;
            break;
        }
    }
    if (at < 0) {
        if (*n < cap) {
            at = (*n)++;
        } else if (h.votes > list[cap - 1].votes) {
            at = cap - 1;
        } else {
            return;
        }
    }
    /* slot `at` is free; h moves up past those with fewer votes */
    while (at > 0 && h.votes > list[at - 1].votes) {
        list[at] = list[at - 1];
        --at;
    }
    list[at] = h;
}

/* Least-squares rigid transform (no scale) taking e[pe[k]] onto
 * truth[pt[k]], m >= 2: with p, q the pairs about their centroids,
 * theta = atan2(sum(p_x q_y - p_y q_x), sum(p_x q_x + p_y q_y)) and
 * t = q_bar - R(theta) p_bar (2-D Procrustes / Kabsch). */
static pose2_t rigid_procrustes(const point2_t *e, const point2_t *truth, const int *pe, const int *pt, int m)
{
    double ex = 0.0, ey = 0.0, tx = 0.0, ty = 0.0;
    for (int k = 0; k < m; ++k) {
        ex += e[pe[k]].x;
        ey += e[pe[k]].y;
        tx += truth[pt[k]].x;
        ty += truth[pt[k]].y;
    }
    ex /= m;
    ey /= m;
    tx /= m;
    ty /= m;
    double sc = 0.0, ss = 0.0;
    for (int k = 0; k < m; ++k) {
        const double px = e[pe[k]].x - ex;
        const double py = e[pe[k]].y - ey;
        const double qx = truth[pt[k]].x - tx;
        const double qy = truth[pt[k]].y - ty;
        sc += px * qx + py * qy;
        ss += px * qy - py * qx;
    }
    const double th = atan2(ss, sc);
    const double c = cos(th);
    const double s = sin(th);
    pose2_t t;
    t.x = tx - (c * ex - s * ey);
    t.y = ty - (s * ex + c * ey);
    t.theta = angle_wrap(th);
    return t;
}

/* What the refinement works on: the estimates, the truth and its grid,
 * and scratch for rigid_match. */
typedef struct {
    const point2_t *e;
    int n;
    const point2_t *truth;
    int n_truth;
    const rigid_grid_t *grid;
    double gate2;
    rigid_cand_t *cand; /* n * n_truth */
    point2_t *pm;       /* n: the estimates moved */
    char *used_e;       /* n */
    int *t_of;          /* n_truth: index into pe/pt of the truth's match, or -1 */
    int *pe;            /* matched pairs: estimate index ... */
    int *pt;            /* ... and its true landmark */
    int *match_e;       /* n: the estimate's true landmark, or -1 */
    int *uf;            /* n + n_truth: union-find parents (estimates, then truth) */
    int *comp;          /* n + n_truth: component number of a root, or -1 */
    int *c_start;       /* n * n_truth + 1 */
    int *c_item;        /* n * n_truth: candidates by component */
    int *loc;           /* n + n_truth: row / column in the component's problem, or -1 */
} rigid_work_t;

/* Components of the candidate graph up to this many estimates and true
 * landmarks get the optimal assignment (hungarian); larger ones keep the
 * greedy one with exchanges. */
#define RIGID_OPT_MAX 16

static int rigid_find(int *uf, int x)
{
    while (uf[x] != x) {
        uf[x] = uf[uf[x]];
        x = uf[x];
    }
    return x;
}

/* Replace the matching inside each small connected component of the
 * candidate graph (nc candidates) by the optimal one: least summed squared
 * distance plus gate^2 per unmatched estimate, eval_map's cost. */
static void rigid_match_optimal(const rigid_work_t *w, size_t nc)
{
    const int nn = w->n + w->n_truth;
    for (int x = 0; x < nn; ++x) {
        w->uf[x] = x;
        w->comp[x] = -1;
        w->loc[x] = -1;
    }
    for (size_t k = 0; k < nc; ++k) {
        const int a = rigid_find(w->uf, w->cand[k].i);
        const int b = rigid_find(w->uf, w->n + w->cand[k].j);
        if (a != b) {
            w->uf[a] = b;
        }
    }
    int n_comp = 0;
    for (size_t k = 0; k < nc; ++k) {
        const int r = rigid_find(w->uf, w->cand[k].i);
        if (w->comp[r] < 0) {
            w->comp[r] = n_comp;
            w->c_start[n_comp + 1] = 0;
            n_comp++;
        }
        w->c_start[w->comp[r] + 1]++;
    }
    w->c_start[0] = 0;
    for (int c = 0; c < n_comp; ++c) {
        w->c_start[c + 1] += w->c_start[c];
    }
    for (size_t k = 0; k < nc; ++k) {
        const int c = w->comp[rigid_find(w->uf, w->cand[k].i)];
        w->c_item[w->c_start[c]++] = (int)k; /* c_start[c] ends at the next component's start */
    }
    for (int c = n_comp; c > 0; --c) {
        w->c_start[c] = w->c_start[c - 1];
    }
    w->c_start[0] = 0;
    double cost[RIGID_OPT_MAX * 2 * RIGID_OPT_MAX];
    int row_e[RIGID_OPT_MAX];
    int col_t[RIGID_OPT_MAX];
    int r2c[RIGID_OPT_MAX];
    for (int c = 0; c < n_comp; ++c) {
        int nr = 0, ncol = 0, fits = 1;
        for (int q = w->c_start[c]; q < w->c_start[c + 1] && fits; ++q) {
            const rigid_cand_t *cd = &w->cand[w->c_item[q]];
            if (w->loc[cd->i] < 0) {
                if (nr == RIGID_OPT_MAX) {
                    fits = 0;
                    break;
                }
                w->loc[cd->i] = nr;
                row_e[nr++] = cd->i;
            }
            if (w->loc[w->n + cd->j] < 0) {
                if (ncol == RIGID_OPT_MAX) {
                    fits = 0;
                    break;
                }
                w->loc[w->n + cd->j] = ncol;
                col_t[ncol++] = cd->j;
            }
        }
        if (fits && nr >= 2 && ncol >= 1) {
            /* nr x (ncol + nr): real columns, then one "unmatched" column per row */
            const int m = ncol + nr;
            const double big = 1e9 * w->gate2;
            for (int r = 0; r < nr; ++r) {
                for (int k = 0; k < m; ++k) {
                    cost[r * m + k] = k < ncol ? big : w->gate2;
                }
            }
            for (int q = w->c_start[c]; q < w->c_start[c + 1]; ++q) {
                const rigid_cand_t *cd = &w->cand[w->c_item[q]];
                cost[w->loc[cd->i] * m + w->loc[w->n + cd->j]] = cd->d2;
            }
            hungarian(cost, nr, m, r2c);
            for (int r = 0; r < nr; ++r) {
                const int k = r2c[r];
                w->match_e[row_e[r]] = (k < ncol && cost[r * m + k] < w->gate2) ? col_t[k] : -1;
            }
        }
        for (int r = 0; r < nr; ++r) {
            w->loc[row_e[r]] = -1;
        }
        for (int k = 0; k < ncol; ++k) {
            w->loc[w->n + col_t[k]] = -1;
        }
    }
}

/* The 3 x 3 cells around p, clipped; 0 if none can hold truth within the
 * gate (also for NaN). */
static int rigid_grid_block(const rigid_grid_t *g, point2_t p, int *cx0, int *cx1, int *cy0, int *cy1)
{
    /* cell coordinates + 1, so that truncation is floor */
    const double ux = (p.x - g->x0) * g->inv_cell + 1.0;
    const double uy = (p.y - g->y0) * g->inv_cell + 1.0;
    if (!(ux >= 0.0 && ux < (double)(g->nx + 2) && uy >= 0.0 && uy < (double)(g->ny + 2))) {
        return 0;
    }
    const int cx = (int)ux - 1;
    const int cy = (int)uy - 1;
    *cx0 = cx > 0 ? cx - 1 : 0;
    *cx1 = cx + 1 < g->nx ? cx + 1 : g->nx - 1;
    *cy0 = cy > 0 ? cy - 1 : 0;
    *cy1 = cy + 1 < g->ny ? cy + 1 : g->ny - 1;
    return 1;
}

static double rigid_d2(point2_t a, point2_t b)
{
    const double dx = a.x - b.x;
    const double dy = a.y - b.y;
    return dx * dx + dy * dy;
}

/* One-to-one matching of the estimate moved by t within the gate: greedy,
 * closest pairs first, then pairwise exchanges while they lower the summed
 * squared distance, then the optimal assignment inside every small group
 * of candidate pairs (rigid_match_optimal). Greedy alone crosses pairs
 * inside a tight cluster, and the least squares then turns the map towards
 * the crossing. Fills w->pe / w->pt; returns the number of pairs, *sse
 * their summed squared distance. */
static int rigid_match(const rigid_work_t *w, pose2_t t, double *sse)
{
    const rigid_grid_t *g = w->grid;
    const double c_th = cos(t.theta);
    const double s_th = sin(t.theta);
    size_t nc = 0;
    for (int i = 0; i < w->n; ++i) {
        const point2_t p = {c_th * w->e[i].x - s_th * w->e[i].y + t.x, s_th * w->e[i].x + c_th * w->e[i].y + t.y};
        w->pm[i] = p;
        w->used_e[i] = 0;
        int cx0, cx1, cy0, cy1;
        if (!rigid_grid_block(g, p, &cx0, &cx1, &cy0, &cy1)) {
            continue;
        }
        for (int y = cy0; y <= cy1; ++y) {
            const int row = y * g->nx;
            for (int k = g->start[row + cx0]; k < g->start[row + cx1 + 1]; ++k) {
                const int j = g->item[k];
                const double d2 = rigid_d2(p, g->pt[j]);
                if (d2 < w->gate2) {
                    w->cand[nc].i = i;
                    w->cand[nc].j = j;
                    w->cand[nc].d2 = d2;
                    nc++;
                }
            }
        }
    }
    qsort(w->cand, nc, sizeof *w->cand, rigid_cand_cmp);
    for (int j = 0; j < w->n_truth; ++j) {
        w->t_of[j] = -1;
    }
    int m = 0;
    for (size_t k = 0; k < nc; ++k) {
        if (w->used_e[w->cand[k].i] || w->t_of[w->cand[k].j] >= 0) {
            continue;
        }
        w->used_e[w->cand[k].i] = 1;
        w->t_of[w->cand[k].j] = m;
        w->pe[m] = w->cand[k].i;
        w->pt[m] = w->cand[k].j;
        m++;
    }
    /* exchanges: the candidates (sorted) list each estimate's true
     * neighbours; a few passes settle a cluster */
    for (int pass = 0; pass < 4; ++pass) {
        int changed = 0;
        for (size_t k = 0; k < nc; ++k) {
            const int i1 = w->cand[k].i;
            const int j2 = w->cand[k].j;
            const int k2 = w->t_of[j2];
            if (!w->used_e[i1] || k2 < 0 || w->pe[k2] == i1) {
                continue;
            }
            int k1 = 0;
            while (w->pe[k1] != i1) {
                ++k1;
            }
            const int i2 = w->pe[k2];
            const int j1 = w->pt[k1];
            const double d_21 = rigid_d2(w->pm[i2], w->truth[j1]);
            if (d_21 < w->gate2 && w->cand[k].d2 + d_21 < rigid_d2(w->pm[i1], w->truth[j1]) +
                                                            rigid_d2(w->pm[i2], w->truth[j2]) - 1e-12) {
                w->pt[k1] = j2;
                w->pt[k2] = j1;
                w->t_of[j2] = k1;
                w->t_of[j1] = k2;
                changed = 1;
            }
        }
        if (!changed) {
            break;
        }
    }
    /* small clusters of candidates: the optimal assignment instead */
    for (int i = 0; i < w->n; ++i) {
        w->match_e[i] = -1;
    }
    for (int k = 0; k < m; ++k) {
        w->match_e[w->pe[k]] = w->pt[k];
    }
    rigid_match_optimal(w, nc);
    m = 0;
    double s = 0.0;
    for (int i = 0; i < w->n; ++i) {
        if (w->match_e[i] >= 0) {
            w->pe[m] = i;
            w->pt[m] = w->match_e[i];
            s += rigid_d2(w->pm[i], w->truth[w->match_e[i]]);
            m++;
        }
    }
    *sse = s;
    return m;
}

/* From t: match, least squares, repeat (up to EVAL_RIGID_ITERATIONS rounds,
 * until it stops moving). Returns the least cost seen - eval_map's: squared
 * error of the matched pairs plus gate^2 per unmatched estimate - with its
 * transform and match count. */
static double rigid_refine(const rigid_work_t *w, pose2_t t, pose2_t *t_best, int *m_best)
{
    double best = INFINITY;
    for (int it = 0; it < EVAL_RIGID_ITERATIONS; ++it) {
        double sse;
        const int m = rigid_match(w, t, &sse);
        const double cost = sse + w->gate2 * (w->n - m);
        if (cost < best) {
            best = cost;
            *t_best = t;
            *m_best = m;
        }
        if (m < 2) {
            break;
        }
        const pose2_t t2 = rigid_procrustes(w->e, w->truth, w->pe, w->pt, m);
        const int converged = fabs(t2.x - t.x) < 1e-9 && fabs(t2.y - t.y) < 1e-9 &&
                              fabs(angle_wrap(t2.theta - t.theta)) < 1e-12;
        t = t2;
        if (converged) {
            break;
        }
    }
    return best;
}

/* eval_map's answer when no fit exists: nothing matched. */
static void rigid_unmatched(int n, const int *n_seen, int n_truth, int min_seen, map_eval_t *out)
{
    memset(out, 0, sizeof *out);
    out->n_estimated = n;
    out->n_spurious = n;
    for (int i = 0; i < n; ++i) {
        out->match[i] = -1;
    }
    for (int j = 0; j < n_truth; ++j) {
        if (n_seen == NULL || n_seen[j] >= min_seen) {
            out->n_missed++;
        }
    }
}

/* One rotation step of the sweep: every (estimate, true landmark) pair
 * votes for the translation that puts the rotated, centred estimate on the
 * true landmark; blocks of 2 x 2 cells (side 2 h) with the most votes
 * become hypotheses. qh: the rotated, centred estimates / h; vh: the voting
 * true landmarks relative to the grid origin / h (cell coordinates). */
static void rigid_vote_step(rigid_votes_t *v, const point2_t *qh, int nq, const point2_t *vh, int nv, double th,
                            point2_t ce, rigid_hyp_t *keep, int *n_keep, double r_m, double sep_m)
{
    /* a block beating the last kept hypothesis holds a cell with a quarter
     * of its votes: only cells reaching that count are looked at */
    const int need0 = *n_keep == EVAL_RIGID_KEEP ? keep[EVAL_RIGID_KEEP - 1].votes + 1 : 2;
    const int look = (need0 + 3) / 4;
    v->n_peak = 0;
    for (int i = 0; i < nq; ++i) {
        for (int k = 0; k < nv; ++k) {
            const double ux = vh[k].x - qh[i].x;
            const double uy = vh[k].y - qh[i].y;
            if (!(ux >= 0.0 && ux < (double)v->nx && uy >= 0.0 && uy < (double)v->ny)) {
                continue;
            }
            const int c = (int)uy * v->nx + (int)ux;
            const int cnt = v->count[c] + (v->count[c] != UINT16_MAX);
            v->count[c] = (uint16_t)cnt;
            if (cnt == look) {
                v->peak[v->n_peak++] = c;
            }
        }
    }
    const double cth = cos(th);
    const double sth = sin(th);
    for (int k = 0; k < v->n_peak; ++k) {
        const int c = v->peak[k];
        const int need = *n_keep == EVAL_RIGID_KEEP ? keep[EVAL_RIGID_KEEP - 1].votes + 1 : 2;
        if (4 * v->count[c] < need) {
            continue;
        }
        const int cx = c % v->nx;
        const int cy = c / v->nx;
        for (int by = cy - 1; by <= cy; ++by) {
            for (int bx = cx - 1; bx <= cx; ++bx) {
                if (bx < 0 || by < 0 || bx + 1 >= v->nx || by + 1 >= v->ny) {
                    continue;
                }
                const int b = by * v->nx + bx;
                const int votes = v->count[b] + v->count[b + 1] + v->count[b + v->nx] + v->count[b + v->nx + 1];
                if (votes < need) {
                    continue;
                }
                /* the block's centre; world = R(th) (e - ce) + t_c: the
                 * estimate's frame is at t_c - R(th) ce */
                rigid_hyp_t h;
                h.c_world.x = v->x0 + (bx + 1) * v->h;
                h.c_world.y = v->y0 + (by + 1) * v->h;
                h.t.x = h.c_world.x - (cth * ce.x - sth * ce.y);
                h.t.y = h.c_world.y - (sth * ce.x + cth * ce.y);
                h.t.theta = angle_wrap(th);
                h.votes = votes;
                rigid_keep(keep, n_keep, EVAL_RIGID_KEEP, h, r_m, sep_m);
            }
        }
    }
    memset(v->count, 0, sizeof(uint16_t) * (size_t)v->nx * (size_t)v->ny);
}

static coslam_status_t rigid_fit_lm(const map_landmark_t *lm, int n, pose2_t pose, const point2_t *truth,
                                    const int *n_seen, int n_truth, int min_seen, double gate_m, pose2_t *fit,
                                    map_eval_t *out)
{
    const pose2_t identity = {0.0, 0.0, 0.0};
    if (fit != NULL) {
        *fit = identity;
    }
    if (out != NULL) {
        memset(out, 0, sizeof *out);
    }
    if ((lm == NULL && n > 0) || out == NULL || n_truth < 0 || (truth == NULL && n_truth > 0) ||
        !isfinite(gate_m) || !(gate_m > 0.0) || n < 0 || n > COSLAM_MAX_LANDMARKS) {
        return COSLAM_E_ARG;
    }
    const double gate2 = gate_m * gate_m;
    if (n < 2 || n_truth < 2) {
        rigid_unmatched(n, n_seen, n_truth, min_seen, out);
        return COSLAM_OK;
    }

    coslam_status_t st = COSLAM_OK;
    rigid_grid_t grid = {0};
    rigid_votes_t votes = {0};
    point2_t *e = (point2_t *)malloc(sizeof(point2_t) * (size_t)n);
    point2_t *pc = (point2_t *)malloc(sizeof(point2_t) * (size_t)n);
    point2_t *q = (point2_t *)malloc(sizeof(point2_t) * (size_t)n);
    double *rad = (double *)malloc(sizeof(double) * (size_t)n);
    point2_t *vt = (point2_t *)malloc(sizeof(point2_t) * (size_t)n_truth);
    rigid_cand_t *cand = (rigid_cand_t *)malloc(sizeof(rigid_cand_t) * (size_t)n * (size_t)n_truth);
    char *used_e = (char *)malloc((size_t)n);
    int *t_of = (int *)malloc(sizeof(int) * (size_t)n_truth);
    int *match_e = (int *)malloc(sizeof(int) * (size_t)n);
    int *uf = (int *)malloc(sizeof(int) * (size_t)(n + n_truth));
    int *comp = (int *)malloc(sizeof(int) * (size_t)(n + n_truth));
    int *loc = (int *)malloc(sizeof(int) * (size_t)(n + n_truth));
    int *c_start = (int *)malloc(sizeof(int) * ((size_t)n * (size_t)n_truth + 1u));
    int *c_item = (int *)malloc(sizeof(int) * (size_t)n * (size_t)n_truth);
    int *pe = (int *)malloc(sizeof(int) * (size_t)n);
    int *pt = (int *)malloc(sizeof(int) * (size_t)n);
    map_whole_t *moved = (map_whole_t *)malloc(sizeof *moved);
    if (e == NULL || pc == NULL || q == NULL || rad == NULL || vt == NULL || cand == NULL || used_e == NULL ||
        t_of == NULL || match_e == NULL || uf == NULL || comp == NULL || loc == NULL || c_start == NULL ||
        c_item == NULL || pe == NULL || pt == NULL || moved == NULL ||
        rigid_grid_build(&grid, truth, n_truth, gate_m) != 0) {
        st = COSLAM_E_CAPACITY;
        goto done;
    }

    /* 1. the finite estimates about their centroid; the true landmarks that
     * can be in the map (sighted at least once, if n_seen says) */
    point2_t ce = {0.0, 0.0};
    int n_fin = 0;
    for (int i = 0; i < n; ++i) {
        e[i] = lm[i].mean;
        if (isfinite(e[i].x) && isfinite(e[i].y)) {
            ce.x += e[i].x;
            ce.y += e[i].y;
            n_fin++;
        }
    }
    int n_vt = 0;
    double tx0 = INFINITY, ty0 = INFINITY, tx1 = -INFINITY, ty1 = -INFINITY;
    for (int j = 0; j < n_truth; ++j) {
        if (isfinite(truth[j].x) && isfinite(truth[j].y) && (n_seen == NULL || n_seen[j] > 0)) {
            vt[n_vt++] = truth[j];
            tx0 = fmin(tx0, truth[j].x);
            ty0 = fmin(ty0, truth[j].y);
            tx1 = fmax(tx1, truth[j].x);
            ty1 = fmax(ty1, truth[j].y);
        }
    }
    if (n_fin < 2 || n_vt < 2) {
        rigid_unmatched(n, n_seen, n_truth, min_seen, out);
        goto done;
    }
    ce.x /= n_fin;
    ce.y /= n_fin;
    int k_fin = 0;
    for (int i = 0; i < n; ++i) {
        if (isfinite(e[i].x) && isfinite(e[i].y)) {
            pc[k_fin].x = e[i].x - ce.x;
            pc[k_fin].y = e[i].y - ce.y;
            rad[k_fin] = hypot(pc[k_fin].x, pc[k_fin].y);
            k_fin++;
        }
    }
    qsort(rad, (size_t)n_fin, sizeof *rad, rigid_double_cmp);
    const double r_max = rad[n_fin - 1];
    /* the radius the rotation step is sized for: a far outlier must not
     * multiply the steps (its votes only smear) */
    const double r_m = fmax(rad[(n_fin - 1) * 9 / 10], gate_m);

    /* 2. rotation sweep: steps of gate / r_m leave a landmark at r_m at most
     * gate / 2 from where the right rotation puts it, so the right votes
     * spread over about one 2 x 2 block of gate / 2 cells; the refinement
     * takes out the rest (twice the steps found the same fits in the tests
     * and on MRCLAM, at twice the cost) */
    int steps = (int)ceil(2.0 * COSLAM_PI * r_m / gate_m);
    steps = steps < 16 ? 16 : (steps > EVAL_RIGID_MAX_STEPS ? EVAL_RIGID_MAX_STEPS : steps);
    double h = 0.5 * gate_m;
    const double margin = r_max + gate_m;
    while (((tx1 - tx0 + 2.0 * margin) / h + 1.0) * ((ty1 - ty0 + 2.0 * margin) / h + 1.0) >
           (double)EVAL_RIGID_MAX_CELLS) {
        h *= 2.0; /* coarser rather than larger than the cap */
    }
    votes.x0 = tx0 - margin;
    votes.y0 = ty0 - margin;
    votes.h = h;
    votes.nx = (int)((tx1 - tx0 + 2.0 * margin) / h) + 1;
    votes.ny = (int)((ty1 - ty0 + 2.0 * margin) / h) + 1;
    const size_t n_cells = (size_t)votes.nx * (size_t)votes.ny;
    votes.count = (uint16_t *)calloc(n_cells, sizeof(uint16_t));
    votes.peak = (int *)malloc(sizeof(int) * (size_t)n_fin * (size_t)n_vt);
    if (votes.count == NULL || votes.peak == NULL) {
        st = COSLAM_E_CAPACITY;
        goto done;
    }
    for (int k = 0; k < n_vt; ++k) {
        vt[k].x = (vt[k].x - votes.x0) / h;
        vt[k].y = (vt[k].y - votes.y0) / h;
    }
    rigid_hyp_t keep[EVAL_RIGID_KEEP];
    int n_keep = 0;
    for (int s = 0; s < steps; ++s) {
        const double th = -COSLAM_PI + COSLAM_TWO_PI * s / steps;
        const double c = cos(th) / h;
        const double sn = sin(th) / h;
        for (int i = 0; i < n_fin; ++i) {
            q[i].x = c * pc[i].x - sn * pc[i].y;
            q[i].y = sn * pc[i].x + c * pc[i].y;
        }
        rigid_vote_step(&votes, q, n_fin, vt, n_vt, th, ce, keep, &n_keep, r_m, 0.5 * gate_m);
    }

    /* 3. refine each kept hypothesis on all estimates; the least cost wins */
    const rigid_work_t w = {e,  n,  truth,   n_truth, &grid,   gate2,  cand, q,  used_e,
                            t_of, pe, pt, match_e, uf,      comp, c_start, c_item, loc};
    pose2_t best_t = identity;
    double best_cost = INFINITY;
    int best_m = 0;
    for (int k = 0; k < n_keep; ++k) {
        pose2_t t;
        int m = 0;
        const double cost = rigid_refine(&w, keep[k].t, &t, &m);
        if (cost < best_cost) {
            best_cost = cost;
            best_t = t;
            best_m = m;
        }
    }
    /* 4. polish: the matching makes the cost piecewise, so the refinement
     * stops at the first fixed point. A pattern search restarts it from the
     * best fit turned (about the estimate's centroid) and moved by half a
     * sweep step / half a gate, then by half of that, twice. */
    double step_m = 0.5 * gate_m;
    double step_rad = 0.5 * gate_m / r_m;
    int n_polish = 0;
    for (int level = 0; level < 3 && best_m >= 2; ++level) {
        int moved_on = 1;
        while (moved_on && n_polish < EVAL_RIGID_POLISH) {
            moved_on = 0;
            for (int d = 0; d < 6 && n_polish < EVAL_RIGID_POLISH; ++d) {
                const double sign = (d % 2 == 0) ? 1.0 : -1.0;
                pose2_t t0 = best_t;
                if (d < 2) {
                    /* turn by +-step about the centroid's image c: t' = R_d (t - c) + c */
                    const point2_t c = pose2_apply(best_t, ce);
                    const double a = sign * step_rad;
                    const double ca = cos(a), sa = sin(a);
                    t0.x = ca * (best_t.x - c.x) - sa * (best_t.y - c.y) + c.x;
                    t0.y = sa * (best_t.x - c.x) + ca * (best_t.y - c.y) + c.y;
                    t0.theta = angle_wrap(best_t.theta + a);
                } else if (d < 4) {
                    t0.x += sign * step_m;
                } else {
                    t0.y += sign * step_m;
                }
                pose2_t t;
                int m = 0;
                const double cost = rigid_refine(&w, t0, &t, &m);
                n_polish++;
                if (cost < best_cost - 1e-12) {
                    best_cost = cost;
                    best_t = t;
                    best_m = m;
                    moved_on = 1;
                    break;
                }
            }
        }
        step_m *= 0.5;
        step_rad *= 0.5;
    }
    if (best_m < 2) {
        /* no two estimates agree with two true landmarks: no fit */
        rigid_unmatched(n, n_seen, n_truth, min_seen, out);
        goto done;
    }

    /* 5. eval_map on the estimate moved by the fit */
    moved->n_landmarks = (uint16_t)n;
    moved->pose = pose2_compose(best_t, pose);
    double rot[2][2] = {{cos(best_t.theta), -sin(best_t.theta)}, {sin(best_t.theta), cos(best_t.theta)}};
    for (int i = 0; i < n; ++i) {
        moved->lm[i] = lm[i];
        moved->lm[i].mean = pose2_apply(best_t, lm[i].mean);
        moved->lm[i].cov = cov2_congruence(rot, lm[i].cov);
    }
    eval_map_whole(moved, truth, n_seen, n_truth, min_seen, gate_m, out);
    if (fit != NULL) {
        *fit = best_t;
    }

done:
    free(grid.start);
    free(grid.item);
    free(votes.count);
    free(votes.peak);
    free(e);
    free(pc);
    free(q);
    free(rad);
    free(vt);
    free(cand);
    free(used_e);
    free(t_of);
    free(match_e);
    free(uf);
    free(comp);
    free(loc);
    free(c_start);
    free(c_item);
    free(pe);
    free(pt);
    free(moved);
    return st;
}


coslam_status_t eval_map_rigid(const map_estimate_t *est, const point2_t *truth, const int *n_seen, int n_truth,
                               int min_seen, double gate_m, pose2_t *fit, map_eval_t *out)
{
    /* n = -1: rigid_fit_lm resets the outputs and refuses */
    const int n = est != NULL && est->n_landmarks <= COSLAM_MAX_MSG_LANDMARKS ? est->n_landmarks : -1;
    return rigid_fit_lm(est != NULL ? est->lm : NULL, n, est != NULL ? est->pose : (pose2_t){0.0, 0.0, 0.0}, truth,
                        n_seen, n_truth, min_seen, gate_m, fit, out);
}

coslam_status_t eval_map_rigid_whole(const map_whole_t *est, const point2_t *truth, const int *n_seen, int n_truth,
                                    int min_seen, double gate_m, pose2_t *fit, map_eval_t *out)
{
    return rigid_fit_lm(est != NULL ? est->lm : NULL, est != NULL ? est->n_landmarks : -1,
                        est != NULL ? est->pose : (pose2_t){0.0, 0.0, 0.0}, truth, n_seen, n_truth, min_seen, gate_m,
                        fit, out);
}
