/* app/health.c - the filter's health monitor (app/health.h). Reads only. */
#include "app/health.h"

#include <math.h>
#include <string.h>

#include "coslam/landmark.h"
#include "coslam/observe.h"

health_config_t health_config_default(void)
{
    health_config_t c;
    c.nis_max = 6.0;
    c.unassoc_max = 0.6;
    c.ess_min = 0.02;
    c.missed_max = 0.8;
    c.conflict_max = 0.25;
    c.free_logodds = -1.2;
    c.wall_logodds = 2.0;
    c.min_returns = 200U;
    c.min_sightings = 8U;
    c.odo = odo_check_config_default();
    return c;
}

coslam_status_t health_init(health_t *h, const health_config_t *cfg)
{
    if (h == NULL || cfg == NULL || !(cfg->nis_max > 0.0) || !(cfg->unassoc_max > 0.0) || cfg->unassoc_max > 1.0 ||
        !(cfg->ess_min >= 0.0) || cfg->ess_min >= 1.0 || cfg->min_sightings < 1U || !(cfg->missed_max > 0.0) ||
        cfg->missed_max > 1.0 || !(cfg->conflict_max > 0.0) || cfg->conflict_max > 1.0 || !(cfg->free_logodds < 0.0) ||
        cfg->min_returns < 1U) {
        return COSLAM_E_ARG;
    }
    memset(h, 0, sizeof *h);
    if (odo_check_init(&h->odo, &cfg->odo) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    h->cfg = *cfg;
    h->ess_frac = 1.0;
    h->worst_ess = 1.0;
    return COSLAM_OK;
}

/* The landmark at m is in view of pose p: its predicted sighting is one the
 * filter itself says should be seen (landmark_should_be_seen: inside the
 * visibility margin of the range and field of view, so that one at the
 * border is not expected), and no wall the laser has mapped stands between
 * (the camera cannot see through it). */
static int in_view(const health_t *h, const occ_grid_t *g, const slam_params_t *sp, pose2_t p, point2_t m)
{
    const double dx = m.x - p.x;
    const double dy = m.y - p.y;
    sighting_t zhat;
    memset(&zhat, 0, sizeof zhat);
    zhat.range_m = sqrt(dx * dx + dy * dy);
    zhat.bearing_rad = angle_wrap(atan2(dy, dx) - p.theta);
    if (!landmark_should_be_seen(sp, zhat)) {
        return 0;
    }
    return g == NULL || occ_grid_line_free(g, (point2_t){p.x, p.y}, m, h->cfg.wall_logodds, 0.2);
}

static void mark(health_t *h, uint8_t sig)
{
    h->in_view_sig[sig >> 3] = (uint8_t)(h->in_view_sig[sig >> 3] | (1U << (sig & 7U)));
}

static int marked(const health_t *h, uint8_t sig)
{
    return (((unsigned)h->in_view_sig[sig >> 3] >> (sig & 7U)) & 1U) != 0U;
}

static void judge(health_t *h, int frame_bad)
{
    const int bad = frame_bad || h->scan_bad || h->odo.bad;
    if (bad && !h->diverged) {
        h->episodes++;
    }
    h->diverged = bad;
}

void health_on_scan(health_t *h, const occ_grid_t *g, pose2_t sensor_pose, const double *range_m,
                    const double *angle_rad, size_t n)
{
    health_scan_t sc = {0U, 0U};
    const double c = cos(sensor_pose.theta);
    const double s = sin(sensor_pose.theta);
    for (size_t i = 0; i < n; ++i) {
        const double r = range_m[i];
        if (!isfinite(r) || r <= g->params.min_range_m || r >= g->params.max_range_m) {
            continue;
        }
        const double bx = r * cos(angle_rad[i]);
        const double by = r * sin(angle_rad[i]);
        int32_t ix, iy;
        if (!occ_grid_cell_of(g, sensor_pose.x + c * bx - s * by, sensor_pose.y + s * bx + c * by, &ix, &iy)) {
            continue;
        }
        /* the return contradicts the grid if it lies in known free
         * space (3x3 cells around it) or its ray crossed a known wall */
        double lmax = -INFINITY;
        int unknown = 0;
        for (int32_t dy = -1; dy <= 1; ++dy) {
            for (int32_t dx = -1; dx <= 1; ++dx) {
                const int32_t x = ix + dx;
                const int32_t y = iy + dy;
                if (x < 0 || y < 0 || x >= COSLAM_GRID_CELLS_X || y >= COSLAM_GRID_CELLS_Y) {
                    continue;
                }
                const double l = occ_grid_logodds(g, x, y);
                lmax = l > lmax ? l : lmax;
                unknown += l == 0.0;
            }
        }
        const point2_t a = {sensor_pose.x, sensor_pose.y};
        const point2_t e = {sensor_pose.x + c * bx - s * by, sensor_pose.y + s * bx + c * by};
        const int through_wall = (i % 4U) == 0U && !occ_grid_line_free(g, a, e, h->cfg.wall_logodds, 0.2);
        if (unknown == 9 && !through_wall) {
            continue;
        }
        if (sc.n_known < UINT16_MAX) {
            sc.n_known++;
        }
        if ((lmax <= h->cfg.free_logodds || through_wall) && sc.n_conflict < UINT16_MAX) {
            sc.n_conflict++;
        }
    }
    h->scan[h->scan_head] = sc;
    h->scan_head = (uint16_t)((h->scan_head + 1U) % COSLAM_APP_HEALTH_SCANS);
    if (h->scan_count < COSLAM_APP_HEALTH_SCANS) {
        h->scan_count++;
    }
    uint32_t known = 0, conflict = 0;
    for (uint16_t k = 0; k < h->scan_count; ++k) {
        known += h->scan[k].n_known;
        conflict += h->scan[k].n_conflict;
    }
    h->conflict_frac = known > 0U ? (double)conflict / (double)known : 0.0;
    h->scan_bad = known >= h->cfg.min_returns && h->conflict_frac > h->cfg.conflict_max;
    if (known >= h->cfg.min_returns && h->conflict_frac > h->worst_conflict) {
        h->worst_conflict = h->conflict_frac;
    }
    judge(h, h->frame_bad);
    if (h->diverged) {
        h->diverged_scans++;
    }
}

void health_on_motion_scan(health_t *h, uint64_t now_us, pose2_t odo_pose, const point2_t *pts, size_t n)
{
    (void)odo_check_on_scan(&h->odo, now_us, odo_pose, pts, n);
    judge(h, h->frame_bad);
}

/* The filter's update count (the core's ctr.updates). */
static uint32_t filter_updates(const slam_filter_t *f)
{
    return f->kind == SLAM_FILTER_EKF ? f->u.ekf.ctr.updates : f->u.fs.ctr.updates;
}

void health_before_update(health_t *h, const slam_filter_t *f, const occ_grid_t *g)
{
    h->updates_before = filter_updates(f);
    h->looked = 1;
    memset(h->in_view_sig, 0, sizeof h->in_view_sig);
    h->n_in_view = 0;
    const slam_params_t *sp = slam_filter_params(f);
    if (f->kind == SLAM_FILTER_EKF) {
        const ekfslam_t *e = &f->u.ekf;
        const pose2_t p = {e->x[0], e->x[1], e->x[2]};
        for (uint16_t j = 0; j < e->n_lm; ++j) {
            if (!ekfslam_landmark_live(e, j)) {
                continue; /* removed; out of the state when the local phase ends */
            }
            const point2_t m = ekfslam_landmark_mean(e, j);
            if (in_view(h, g, sp, p, m)) {
                mark(h, e->meta[j].signature);
                h->in_view[h->n_in_view++] = j;
            }
        }
        h->added_before = e->ctr.landmarks_added;
        return;
    }
    const fastslam_t *fs = &f->u.fs;
    uint16_t best = 0;
    for (uint16_t k = 1; k < fs->cfg.n_particles; ++k) {
        if (fs->particles[k].log_w > fs->particles[best].log_w) {
            best = k;
        }
    }
    const fastslam_particle_t *pt = &fs->particles[best];
    for (uint16_t j = 0; j < pt->n_lm; ++j) {
        const landmark_t *lm = fastslam_particle_lm(fs, best, j);
        if (in_view(h, g, sp, pt->pose, lm->mean)) {
            mark(h, lm->signature);
            h->in_view_id[h->n_in_view] = lm->id;
            h->in_view_obs[h->n_in_view] = lm->n_obs;
            h->n_in_view++;
        }
    }
    h->added_before = fs->ctr.landmarks_added;
}

void health_after_update(health_t *h, const slam_filter_t *f, const sighting_t *z, int n)
{
    const int same = h->looked && filter_updates(f) == h->updates_before + 1U;
    h->looked = 0;
    if (!same) {
        h->unjudged_frames++;
        return;
    }
    const slam_params_t *sp = slam_filter_params(f);
    health_frame_t fr;
    memset(&fr, 0, sizeof fr);
    fr.ess_frac = 1.0;
    if (f->kind == SLAM_FILTER_EKF) {
        /* the update's own indexing: plausible sightings, in order, up to
         * COSLAM_MAX_SIGHTINGS (ekfslam_update) */
        const ekfslam_scratch_t *sc = &f->u.ekf.scratch;
        int i = 0;
        for (int q = 0; q < n && i < COSLAM_MAX_SIGHTINGS; ++q) {
            if (!sighting_is_plausible(&z[q], sp)) {
                continue;
            }
            const int32_t j = sc->assign[i];
            if (j >= 0) {
                const double d2 = landmark_mahalanobis2(&sc->expect[j], z[q]);
                if (isfinite(d2)) {
                    fr.nis_sum += d2;
                    fr.n_paired++;
                }
            }
            /* held back (an ambiguous or too nonlinear revisit): the filter
             * waits for a clearer frame; neither paired nor unassociated */
            if (marked(h, z[q].signature) && !sc->held[i]) {
                fr.n_eligible++;
                if (j < 0) {
                    fr.n_unassoc++;
                }
            }
            ++i;
        }
        /* the update's matched[] is indexed like the state before it; a
         * landmark that was a held sighting's best pairing was seen, not
         * missed */
        for (uint16_t k = 0; k < h->n_in_view; ++k) {
            const int32_t lm = (int32_t)h->in_view[k];
            int seen = sc->matched[lm] != 0U;
            for (int s = 0; s < i && !seen; ++s) {
                seen = sc->held[s] != 0U && sc->best[s] == lm;
            }
            fr.n_expected++;
            if (!seen) {
                fr.n_missed++;
            }
        }
    } else {
        const fastslam_t *fs = &f->u.fs;
        uint32_t added = fs->ctr.landmarks_added - h->added_before;
        for (int q = 0; q < n; ++q) {
            if (sighting_is_plausible(&z[q], sp) && marked(h, z[q].signature)) {
                fr.n_eligible++;
            }
        }
        fr.n_unassoc = (uint16_t)(added < fr.n_eligible ? added : fr.n_eligible);
        /* seen: its sighting count grew in the (new) best particle; the
         * particles share identities, so this is exact while the best
         * particle's lineage holds and approximate across a resampling */
        uint16_t best = 0;
        for (uint16_t k = 1; k < fs->cfg.n_particles; ++k) {
            if (fs->particles[k].log_w > fs->particles[best].log_w) {
                best = k;
            }
        }
        const fastslam_particle_t *pt = &fs->particles[best];
        for (uint16_t k = 0; k < h->n_in_view; ++k) {
            fr.n_expected++;
            int seen = 0;
            for (uint16_t j = 0; j < pt->n_lm; ++j) {
                const landmark_t *lm = fastslam_particle_lm(fs, best, j);
                if (lm->id == h->in_view_id[k]) {
                    seen = lm->n_obs > h->in_view_obs[k];
                    break;
                }
            }
            if (!seen) {
                fr.n_missed++;
            }
        }
        fr.ess_frac = fs->cfg.n_particles > 0U ? fs->last_ess / (double)fs->cfg.n_particles : 1.0;
        if (!isfinite(fr.ess_frac)) {
            fr.ess_frac = 0.0;
        }
    }
    h->frame[h->head] = fr;
    h->head = (uint16_t)((h->head + 1U) % COSLAM_APP_HEALTH_WINDOW);
    if (h->count < COSLAM_APP_HEALTH_WINDOW) {
        h->count++;
    }
    h->frames++;
    uint32_t paired = 0, eligible = 0, unassoc = 0, expected = 0, missed = 0;
    double nis = 0.0, ess = 0.0;
    for (uint16_t k = 0; k < h->count; ++k) {
        paired += h->frame[k].n_paired;
        eligible += h->frame[k].n_eligible;
        unassoc += h->frame[k].n_unassoc;
        expected += h->frame[k].n_expected;
        missed += h->frame[k].n_missed;
        nis += h->frame[k].nis_sum;
        ess += h->frame[k].ess_frac;
    }
    h->mean_nis = paired > 0U ? nis / (double)paired : 0.0;
    h->unassoc_frac = eligible > 0U ? (double)unassoc / (double)eligible : 0.0;
    h->ess_frac = ess / (double)h->count;
    h->missed_frac = expected > 0U ? (double)missed / (double)expected : 0.0;
    const int missed_bad = expected >= h->cfg.min_sightings && h->missed_frac > h->cfg.missed_max;
    if (expected >= h->cfg.min_sightings && h->missed_frac > h->worst_missed) {
        h->worst_missed = h->missed_frac;
    }
    const int nis_bad = paired >= h->cfg.min_sightings && h->mean_nis > h->cfg.nis_max;
    const int unassoc_bad = eligible >= h->cfg.min_sightings && h->unassoc_frac > h->cfg.unassoc_max;
    const int ess_bad = f->kind != SLAM_FILTER_EKF && h->count == COSLAM_APP_HEALTH_WINDOW &&
                        h->ess_frac < h->cfg.ess_min;
    if (paired >= h->cfg.min_sightings && h->mean_nis > h->worst_nis) {
        h->worst_nis = h->mean_nis;
    }
    if (eligible >= h->cfg.min_sightings && h->unassoc_frac > h->worst_unassoc) {
        h->worst_unassoc = h->unassoc_frac;
    }
    if (h->count == COSLAM_APP_HEALTH_WINDOW && h->ess_frac < h->worst_ess) {
        h->worst_ess = h->ess_frac;
    }
    h->frame_bad = nis_bad || unassoc_bad || ess_bad || missed_bad;
    judge(h, h->frame_bad);
    if (h->diverged) {
        h->diverged_frames++;
    }
}
