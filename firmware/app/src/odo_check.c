/* app/odo_check.c - scan-to-scan check of the odometry (app/odo_check.h). */
#include "app/odo_check.h"

#include <math.h>
#include <string.h>

odo_check_config_t odo_check_config_default(void)
{
    odo_check_config_t c;
    c.period_s = 0.5;
    c.max_gap_s = 1.5;
    c.min_range_m = 0.1;
    c.max_range_m = 4.0;
    c.min_points = 12U;
    c.iters = 10U;
    c.match_start_m = 0.5;
    c.match_end_m = 0.1;
    c.neighbour_m = 0.25;
    c.inlier_m = 0.08;
    c.min_inlier_frac = 0.3;
    c.point_sd_m = 0.03;
    c.trans_sd_m = 0.03;
    c.trans_sd_frac = 0.1;
    c.rot_sd_rad = 0.035;
    c.rot_sd_frac = 0.1;
    c.chi2_max = 16.27;
    c.cusum_k = 1.0;
    c.cusum_h = 10.0;
    c.hold_s = 10.0;
    return c;
}

coslam_status_t odo_check_init(odo_check_t *c, const odo_check_config_t *cfg)
{
    if (c == NULL || cfg == NULL || !(cfg->period_s > 0.0) || !(cfg->max_gap_s >= 0.0) ||
        !isfinite(cfg->max_gap_s) || !(cfg->min_range_m >= 0.0) || !(cfg->max_range_m > cfg->min_range_m) ||
        !isfinite(cfg->max_range_m) || cfg->min_points < 3U || cfg->min_points > COSLAM_APP_ODO_CHECK_POINTS ||
        cfg->iters < 1U || !(cfg->match_end_m > 0.0) || !(cfg->match_start_m >= cfg->match_end_m) ||
        !isfinite(cfg->match_start_m) || !(cfg->neighbour_m > 0.0) || !isfinite(cfg->neighbour_m) ||
        !(cfg->inlier_m > 0.0) || !(cfg->min_inlier_frac > 0.0) || cfg->min_inlier_frac > 1.0 ||
        !(cfg->point_sd_m > 0.0) || !(cfg->trans_sd_m > 0.0) || !(cfg->trans_sd_frac >= 0.0) ||
        !(cfg->rot_sd_rad > 0.0) || !(cfg->rot_sd_frac >= 0.0) || !(cfg->chi2_max > 0.0) || !(cfg->cusum_k > 0.0) || !(cfg->cusum_h > 0.0) || !isfinite(cfg->cusum_h) || !(cfg->hold_s >= 0.0) ||
        !isfinite(cfg->hold_s)) {
        return COSLAM_E_ARG;
    }
    memset(c, 0, sizeof *c);
    c->cfg = *cfg;
    c->worst_inlier_frac = 1.0;
    return COSLAM_OK;
}

/* Normals: scan neighbours considered on each side, and the largest ratio
 * of the minor to the major spread of a line. */
#define ODO_NORMAL_SPAN 6U
#define ODO_NORMAL_FLATNESS 0.1

static int usable(const odo_check_config_t *cfg, point2_t q)
{
    const double r = hypot(q.x, q.y);
    return isfinite(r) && r >= cfg->min_range_m && r <= cfg->max_range_m;
}

void odo_check_thin(const odo_check_config_t *cfg, const point2_t *pts, size_t n, odo_scan_t *out)
{
    size_t total = 0;
    for (size_t i = 0; i < n; ++i) {
        total += (size_t)usable(cfg, pts[i]);
    }
    const size_t step = (total + COSLAM_APP_ODO_CHECK_POINTS - 1U) / COSLAM_APP_ODO_CHECK_POINTS;
    uint16_t k = 0;
    size_t seen = 0;
    for (size_t i = 0; i < n && k < COSLAM_APP_ODO_CHECK_POINTS; ++i) {
        if (!usable(cfg, pts[i])) {
            continue;
        }
        if (step <= 1U || seen % step == 0U) {
            out->p[k++] = pts[i];
        }
        ++seen;
    }
    out->n = k;
    /* normal: the direction of least spread (principal axes) of the scan
     * neighbours within neighbour_m, up to ODO_NORMAL_SPAN indices on each
     * side; none where fewer than 3 points or no line (a blob, a corner) */
    const double lim = cfg->neighbour_m * cfg->neighbour_m;
    for (uint16_t j = 0; j < k; ++j) {
        const uint16_t lo = j > ODO_NORMAL_SPAN ? (uint16_t)(j - ODO_NORMAL_SPAN) : 0U;
        const uint16_t hi = (uint16_t)(j + ODO_NORMAL_SPAN < k ? j + ODO_NORMAL_SPAN : k - 1U);
        double mx = 0.0, my = 0.0;
        unsigned m = 0;
        for (uint16_t i = lo; i <= hi; ++i) {
            const double dx = out->p[i].x - out->p[j].x, dy = out->p[i].y - out->p[j].y;
            if (dx * dx + dy * dy <= lim) {
                mx += out->p[i].x;
                my += out->p[i].y;
                ++m;
            }
        }
        out->normal[j].x = 0.0;
        out->normal[j].y = 0.0;
        if (m < 3U) {
            continue;
        }
        mx /= (double)m;
        my /= (double)m;
        double sxx = 0.0, sxy = 0.0, syy = 0.0;
        for (uint16_t i = lo; i <= hi; ++i) {
            const double dx = out->p[i].x - out->p[j].x, dy = out->p[i].y - out->p[j].y;
            if (dx * dx + dy * dy <= lim) {
                const double ex = out->p[i].x - mx, ey = out->p[i].y - my;
                sxx += ex * ex;
                sxy += ex * ey;
                syy += ey * ey;
            }
        }
        /* eigenvalues of [[sxx sxy] [sxy syy]]; the line's direction is the
         * major axis at angle phi */
        const double tr = sxx + syy;
        const double disc = sqrt(fmax(0.0, 0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy));
        const double lmin = 0.5 * tr - disc;
        const double lmax = 0.5 * tr + disc;
        if (!(lmax > 0.0) || lmin > ODO_NORMAL_FLATNESS * lmax) {
            continue;
        }
        const double phi = 0.5 * atan2(2.0 * sxy, sxx - syy);
        out->normal[j].x = -sin(phi);
        out->normal[j].y = cos(phi);
    }
}

/* Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi
 * rotations: a = V diag(val) V^T, eigenvectors in the columns of v. */
static void sym3_eigen(double a_in[3][3], double val[3], double v[3][3])
{
    double a[3][3];
    memcpy(a, a_in, sizeof a);
    for (int r = 0; r < 3; ++r) {
        for (int q = 0; q < 3; ++q) {
            v[r][q] = r == q ? 1.0 : 0.0;
        }
    }
    for (int sweep = 0; sweep < 30; ++sweep) {
        const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        if (off < 1e-24 * (a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2]) + 1e-300) {
            break;
        }
        for (int p = 0; p < 2; ++p) {
            for (int q = p + 1; q < 3; ++q) {
                if (a[p][q] == 0.0) {
                    continue;
                }
                const double theta = 0.5 * (a[q][q] - a[p][p]) / a[p][q];
                const double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                const double c = 1.0 / sqrt(t * t + 1.0);
                const double sn = t * c;
                for (int k = 0; k < 3; ++k) { /* A <- A J */
                    const double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - sn * akq;
                    a[k][q] = sn * akp + c * akq;
                }
                for (int k = 0; k < 3; ++k) { /* A <- J^T A */
                    const double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - sn * aqk;
                    a[q][k] = sn * apk + c * aqk;
                }
                for (int k = 0; k < 3; ++k) { /* V <- V J */
                    const double vkp = v[k][p], vkq = v[k][q];
                    v[k][p] = c * vkp - sn * vkq;
                    v[k][q] = sn * vkp + c * vkq;
                }
            }
        }
    }
    for (int r = 0; r < 3; ++r) {
        val[r] = a[r][r];
    }
}

/* out = sum over eigen-directions of h with eigenvalue >= h_min of
 * scale / lambda v v^T, plus big v v^T for the others (directions the scene
 * does not constrain: no step there, no judgement there). */
static void weak_pseudo_inverse(double h[3][3], double h_min, double scale, double big, double out[3][3])
{
    double val[3], v[3][3];
    sym3_eigen(h, val, v);
    memset(out, 0, 9 * sizeof out[0][0]);
    for (int e = 0; e < 3; ++e) {
        const double w = val[e] >= h_min ? scale / val[e] : big;
        for (int r = 0; r < 3; ++r) {
            for (int q = 0; q < 3; ++q) {
                out[r][q] += w * v[r][e] * v[q][e];
            }
        }
    }
}

/* Index of the reference point nearest to q, its squared distance in *d2. */
static uint16_t nearest(const odo_scan_t *ref, point2_t q, double *d2)
{
    uint16_t best = 0;
    double bd = INFINITY;
    for (uint16_t j = 0; j < ref->n; ++j) {
        const double dx = ref->p[j].x - q.x;
        const double dy = ref->p[j].y - q.y;
        const double d = dx * dx + dy * dy;
        if (d < bd) {
            bd = d;
            best = j;
        }
    }
    *d2 = bd;
    return best;
}

/* Matched points whose surface normals differ by more than 30 deg are not
 * paired (a corner's two walls). */
#define ODO_NORMAL_COS 0.866

/* Information (in units of one point's normal distance) below which a
 * direction of the registration counts as unconstrained: fewer than about
 * this many points pin it down, and a few mismatched ones could. */
#define ODO_MIN_SUPPORT 8.0

/* The drift test takes moves and turns at least this large. */
#define ODO_DRIFT_MIN_M 0.02
#define ODO_DRIFT_MIN_RAD 0.02

/* Visibility of the reference: the farthest return per bearing bin. */
#define ODO_VIS_BINS 90
#define ODO_VIS_MARGIN_M 0.3

static int bearing_bin(point2_t q)
{
    const double a = atan2(q.y, q.x) + 3.14159265358979323846;
    int b = (int)(a * (double)ODO_VIS_BINS / (2.0 * 3.14159265358979323846));
    return b < 0 ? 0 : (b >= ODO_VIS_BINS ? ODO_VIS_BINS - 1 : b);
}

static void visibility(const odo_scan_t *ref, double vis[ODO_VIS_BINS])
{
    for (int b = 0; b < ODO_VIS_BINS; ++b) {
        vis[b] = 0.0;
    }
    for (uint16_t j = 0; j < ref->n; ++j) {
        const int b = bearing_bin(ref->p[j]);
        vis[b] = fmax(vis[b], hypot(ref->p[j].x, ref->p[j].y));
    }
}

static void add_row(double h[3][3], double g[3], const double jr[3], double r)
{
    for (int a = 0; a < 3; ++a) {
        g[a] += jr[a] * r;
        for (int b = 0; b < 3; ++b) {
            h[a][b] += jr[a] * jr[b];
        }
    }
}

/* The Gauss-Newton sums of cur's points matched within dmax at pose t
 * (normal distance where the match has a normal, both coordinates where it
 * has not). With `vis` (the reference's free range per bearing bin,
 * visibility()), only the inliers count (and are counted), among the
 * points the reference could have seen (counted in *checkable). */
static size_t accumulate(const odo_check_config_t *cfg, const odo_scan_t *ref, const odo_scan_t *cur, pose2_t t,
                         double dmax, const double *vis, size_t *checkable, double h[3][3], double g[3])
{
    const int inliers_only = vis != NULL;
    memset(h, 0, 9 * sizeof h[0][0]);
    memset(g, 0, 3 * sizeof g[0]);
    const double c = cos(t.theta), s = sin(t.theta);
    const double lim = dmax * dmax;
    size_t m = 0;
    for (uint16_t i = 0; i < cur->n; ++i) {
        const point2_t p = cur->p[i];
        const point2_t q = {c * p.x - s * p.y + t.x, s * p.x + c * p.y + t.y};
        const double dth_x = -s * p.x - c * p.y;
        const double dth_y = c * p.x - s * p.y;
        if (inliers_only) {
            /* seen from the reference pose, is q in a direction where the
             * reference scan reached at least that far? (else it was out of
             * view, out of range or hidden: no evidence either way) */
            const double rq = hypot(q.x, q.y);
            const int b = bearing_bin(q);
            const double reach = fmax(vis[b], fmax(vis[(b + 1) % ODO_VIS_BINS], vis[(b + ODO_VIS_BINS - 1) % ODO_VIS_BINS]));
            if (reach < rq - ODO_VIS_MARGIN_M) {
                continue;
            }
        }
        double d2;
        const uint16_t j = nearest(ref, q, &d2);
        if (inliers_only) {
            /* checkable: nothing of the reference near it (a contradiction),
             * or near a reference surface, or explained by distance; a
             * point near a reference point without a surface (sparse,
             * oblique) is neither */
            const int near_surface = ref->normal[j].x != 0.0 || ref->normal[j].y != 0.0;
            if (d2 > lim || near_surface || d2 <= cfg->inlier_m * cfg->inlier_m) {
                ++*checkable;
            }
        }
        if (d2 > lim) {
            continue;
        }
        const point2_t nv = ref->normal[j];
        const int has_n = nv.x != 0.0 || nv.y != 0.0;
        const point2_t nc = cur->normal[i];
        if (has_n && (nc.x != 0.0 || nc.y != 0.0) &&
            fabs(nv.x * (c * nc.x - s * nc.y) + nv.y * (s * nc.x + c * nc.y)) < ODO_NORMAL_COS) {
            continue; /* surfaces of different directions: not the same surface */
        }
        const double ex = q.x - ref->p[j].x, ey = q.y - ref->p[j].y;
        if (has_n) {
            const double r = nv.x * ex + nv.y * ey;
            if (inliers_only && fabs(r) > cfg->inlier_m) {
                continue;
            }
            const double jr[3] = {nv.x, nv.y, nv.x * dth_x + nv.y * dth_y};
            add_row(h, g, jr, r);
        } else {
            /* no surface: an isolated return, or a wall seen so obliquely
             * that the thinned points are far apart; its point-to-point
             * distance would follow the sampling pattern, which moves with
             * the robot, so it only counts as explained or not */
            if (!inliers_only || d2 > cfg->inlier_m * cfg->inlier_m) {
                continue;
            }
        }
        ++m;
    }
    return m;
}

double odo_check_register(const odo_check_config_t *cfg, const odo_scan_t *ref, const odo_scan_t *cur, pose2_t guess,
                          pose2_t *out, cov3_t *info, size_t *n_checkable)
{
    pose2_t t = guess;
    const double shrink =
        cfg->iters > 1U ? pow(cfg->match_end_m / cfg->match_start_m, 1.0 / (double)(cfg->iters - 1U)) : 1.0;
    double dmax = cfg->match_start_m;
    double h[3][3], g[3];
    for (uint16_t it = 0; it < cfg->iters; ++it, dmax *= shrink) {
        if (accumulate(cfg, ref, cur, t, dmax, NULL, NULL, h, g) < 3U) {
            break;
        }
        /* Gauss-Newton step in the directions the matches constrain (at
         * least ODO_MIN_SUPPORT points' worth of information) only */
        double hi[3][3];
        weak_pseudo_inverse(h, ODO_MIN_SUPPORT, 1.0, 0.0, hi);
        double d[3];
        for (int r = 0; r < 3; ++r) {
            d[r] = -(hi[r][0] * g[0] + hi[r][1] * g[1] + hi[r][2] * g[2]);
        }
        t.x += d[0];
        t.y += d[1];
        t.theta = angle_wrap(t.theta + d[2]);
    }
    *out = t;
    double vis[ODO_VIS_BINS];
    visibility(ref, vis);
    size_t checkable = 0;
    const size_t in = accumulate(cfg, ref, cur, t, cfg->neighbour_m, vis, &checkable, h, g);
    if (n_checkable != NULL) {
        *n_checkable = checkable;
    }
    if (info != NULL) {
        for (int r = 0; r < 3; ++r) {
            for (int q = 0; q < 3; ++q) {
                info->m[r][q] = h[r][q];
            }
        }
    }
    return checkable > 0U ? (double)in / (double)checkable : 0.0;
}

/* e^T (P_L + P_U)^-1 e for laser motion l (information info, unit noise)
 * against odometry motion u. */
static double disagreement(const odo_check_config_t *cfg, pose2_t l, const cov3_t *info, pose2_t u, double z[2])
{
    /* the registration's covariance; unconstrained directions get a
     * variance that makes them irrelevant to the test */
    double plm[3][3], hm[3][3];
    memcpy(hm, info->m, sizeof hm);
    weak_pseudo_inverse(hm, ODO_MIN_SUPPORT, cfg->point_sd_m * cfg->point_sd_m, 1e6, plm);
    /* the odometry's error grows with the distance really travelled and
     * the angle really turned, which the (registered) laser measured */
    const double t_big = hypot(l.x, l.y);
    const double r_big = fabs(l.theta);
    const double st = cfg->trans_sd_m + cfg->trans_sd_frac * t_big;
    const double sr = cfg->rot_sd_rad + cfg->rot_sd_frac * r_big;
    cov3_t p;
    for (int r = 0; r < 3; ++r) {
        for (int q = 0; q < 3; ++q) {
            p.m[r][q] = plm[r][q];
        }
    }
    p.m[0][0] += st * st;
    p.m[1][1] += st * st;
    p.m[2][2] += sr * sr;
    cov3_t pi;
    if (cov3_inverse(cov3_symmetrize(p), &pi) != COSLAM_OK) {
        return 0.0;
    }
    const double e[3] = {l.x - u.x, l.y - u.y, angle_wrap(l.theta - u.theta)};
    /* drift: the error along the odometry's direction of travel and of
     * turning, over its sd (positive: the wheels report too little) */
    z[0] = 0.0;
    z[1] = 0.0;
    const double ut = hypot(u.x, u.y);
    if (ut >= ODO_DRIFT_MIN_M) {
        const double ux = u.x / ut, uy = u.y / ut;
        const double var = ux * ux * p.m[0][0] + 2.0 * ux * uy * p.m[0][1] + uy * uy * p.m[1][1];
        z[0] = (ux * e[0] + uy * e[1]) / sqrt(var);
    }
    if (fabs(u.theta) >= ODO_DRIFT_MIN_RAD) {
        z[1] = (u.theta > 0.0 ? e[2] : -e[2]) / sqrt(p.m[2][2]);
    }
    double chi2 = 0.0;
    for (int r = 0; r < 3; ++r) {
        for (int q = 0; q < 3; ++q) {
            chi2 += e[r] * pi.m[r][q] * e[q];
        }
    }
    return chi2;
}

/* Register cur onto ref from each guess (inverted: the inverse guesses);
 * the best inlier fraction among the registrations with enough checkable
 * points (ties to the first guess), its pose and information; -1 if none. */
static double best_registration(const odo_check_t *c, const odo_scan_t *ref, const odo_scan_t *cur,
                                const pose2_t *guesses, int ng, int inverted, pose2_t *best, cov3_t *best_info)
{
    double best_f = -1.0;
    for (int k = 0; k < ng; ++k) {
        pose2_t t;
        cov3_t info;
        size_t nc = 0;
        const pose2_t g = inverted ? pose2_inverse(guesses[k]) : guesses[k];
        const double f = odo_check_register(&c->cfg, ref, cur, g, &t, &info, &nc);
        if (nc >= c->cfg.min_points && f > best_f + 1e-9) {
            best_f = f;
            *best = t;
            *best_info = info;
        }
    }
    return best_f;
}

/* Compare the newest scan with the reference (header comment); returns 1
 * if judged. */
static int judge_pair(odo_check_t *c, uint64_t now_us, pose2_t odo_pose, double dt)
{
    c->checks++;
    if (c->ref.n < c->cfg.min_points || c->cur.n < c->cfg.min_points) {
        c->unjudged++;
        c->have_rate = 0;
        return 0;
    }
    const pose2_t u = pose2_between(c->ref_odo, odo_pose);
    pose2_t guesses[3] = {u, {0.0, 0.0, 0.0}, u};
    const int ng = c->have_rate ? 3 : 2;
    if (c->have_rate) {
        guesses[2].x = c->laser_rate.x * dt;
        guesses[2].y = c->laser_rate.y * dt;
        guesses[2].theta = c->laser_rate.theta * dt;
    }
    pose2_t best = u;
    cov3_t best_info = cov3_zero();
    const double best_f = best_registration(c, &c->ref, &c->cur, guesses, ng, 0, &best, &best_info);
    /* not judged that way: the other way, the reference onto the newest
     * scan. Only the newest scan's points the reference could have seen are
     * checked, so a robot carried from a cramped place into an open one
     * (every new return beyond the old ones) is not judged one way; the old
     * returns, which the new scan reaches past, are judged the other way.
     * Only then: judged both ways always, an obstacle that leaves the view
     * (the other robot, a person) would be a mismatch as it went too */
    pose2_t rev = u;
    cov3_t rev_info;
    const double rev_f = best_f < 0.0 ? best_registration(c, &c->cur, &c->ref, guesses, ng, 1, &rev, &rev_info) : -1.0;
    if (best_f < 0.0 && rev_f < 0.0) {
        /* no guess leaves enough points either scan could have seen of the
         * other: nothing to judge (a turn into open space) */
        c->unjudged++;
        c->have_rate = 0;
        return 0;
    }
    const double frac = best_f < 0.0 ? rev_f : best_f;
    c->last_inlier_frac = frac;
    c->worst_inlier_frac = fmin(c->worst_inlier_frac, frac);
    int bad = 0;
    if (frac < c->cfg.min_inlier_frac) {
        c->mismatches++;
        c->have_rate = 0;
        bad = 1;
    } else if (best_f < 0.0) {
        /* judged the other way only, and it fits: no motion to compare */
        c->agreements++;
        c->have_rate = 0;
    } else {
        c->last_laser = best;
        c->last_odo = u;
        double z[2];
        c->last_chi2 = disagreement(&c->cfg, best, &best_info, u, z);
        c->worst_chi2 = fmax(c->worst_chi2, c->last_chi2);
        int drift = 0;
        for (int k = 0; k < 2; ++k) {
            c->cusum[2 * k] = fmax(0.0, c->cusum[2 * k] + z[k] - c->cfg.cusum_k);
            c->cusum[2 * k + 1] = fmax(0.0, c->cusum[2 * k + 1] - z[k] - c->cfg.cusum_k);
            drift |= c->cusum[2 * k] > c->cfg.cusum_h || c->cusum[2 * k + 1] > c->cfg.cusum_h;
        }
        for (int k = 0; k < 4; ++k) {
            c->worst_cusum = fmax(c->worst_cusum, c->cusum[k]);
        }
        if (drift) {
            c->drifts++;
            memset(c->cusum, 0, sizeof c->cusum);
        }
        if (c->last_chi2 > c->cfg.chi2_max || drift) {
            c->disagreements++;
            bad = 1;
        } else {
            c->agreements++;
        }
        c->laser_rate.x = best.x / dt;
        c->laser_rate.y = best.y / dt;
        c->laser_rate.theta = best.theta / dt;
        c->have_rate = 1;
    }
    if (bad) {
        c->bad_until_us = now_us + (uint64_t)(c->cfg.hold_s * 1e6);
        c->bad = 1;
    }
    return 1;
}

int odo_check_on_scan(odo_check_t *c, uint64_t now_us, pose2_t odo_pose, const point2_t *pts, size_t n)
{
    if (c == NULL || (pts == NULL && n > 0U) || !pose2_is_finite(odo_pose)) {
        return 0;
    }
    c->bad = now_us < c->bad_until_us;
    const int in_order = c->have_ref && now_us >= c->ref_us;
    const double dt = in_order ? (double)(now_us - c->ref_us) * 1e-6 : 0.0;
    if (in_order && dt < c->cfg.period_s) {
        return 0;
    }
    odo_check_thin(&c->cfg, pts, n, &c->cur);
    int judged = 0;
    if (in_order && dt > c->cfg.period_s + c->cfg.max_gap_s) {
        c->stale_refs++;
        c->have_rate = 0;
    } else if (in_order) {
        judged = judge_pair(c, now_us, odo_pose, dt);
    }
    c->ref = c->cur;
    c->ref_odo = odo_pose;
    c->ref_us = now_us;
    c->have_ref = 1;
    return judged;
}
