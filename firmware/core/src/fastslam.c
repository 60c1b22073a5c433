#include "coslam/fastslam.h"

#include <math.h>
#include <string.h>

#include "coslam/marginal.h"

fastslam_config_t fastslam_config_default(void)
{
    fastslam_config_t c;
    c.slam = slam_params_default();
    c.n_particles = COSLAM_MAX_PARTICLES < 100 ? (uint16_t)COSLAM_MAX_PARTICLES : 100U;
    c.proposal = FASTSLAM_PROPOSAL_MOTION;
    c.resample_ess_fraction = 0.5;
    c.export_min_weight = 0.5;
    c.robot_id = 0;
    return c;
}

static coslam_status_t config_validate(const fastslam_config_t *c)
{
    if (slam_params_validate(&c->slam) != COSLAM_OK) {
        return COSLAM_E_ARG;
    }
    if (c->n_particles < 1 || c->n_particles > COSLAM_MAX_PARTICLES) {
        return COSLAM_E_ARG;
    }
    if (c->proposal != FASTSLAM_PROPOSAL_MOTION && c->proposal != FASTSLAM_PROPOSAL_OPTIMAL) {
        return COSLAM_E_ARG;
    }
    if (!(c->resample_ess_fraction > 0.0 && c->resample_ess_fraction <= 1.0) ||
        !(c->export_min_weight > 0.0 && c->export_min_weight <= 1.0) || c->robot_id >= COSLAM_MAX_ROBOTS) {
        return COSLAM_E_ARG;
    }
    return COSLAM_OK;
}

/* Draw x ~ N(0, C) for a symmetric PSD 3x3 C. A semi-definite Cholesky
 * (zero pivots give zero columns) handles the common singular case of a
 * robot that has not moved. */
static void sample_gauss3(rng_t *rng, const cov3_t *c, double out[3])
{
    double l[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};
    for (int j = 0; j < 3; ++j) {
        double d = c->m[j][j];
        for (int k = 0; k < j; ++k) {
            d -= l[j][k] * l[j][k];
        }
        if (!(d > 1e-300)) {
            continue; /* zero pivot: column stays zero */
        }
        l[j][j] = sqrt(d);
        for (int i = j + 1; i < 3; ++i) {
            double s = c->m[i][j];
            for (int k = 0; k < j; ++k) {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = s / l[j][j];
        }
    }
    const double n[3] = {rng_gauss(rng), rng_gauss(rng), rng_gauss(rng)};
    for (int i = 0; i < 3; ++i) {
        out[i] = l[i][0] * n[0] + l[i][1] * n[1] + l[i][2] * n[2];
    }
}

uint32_t fastslam_new_id(fastslam_t *fs)
{
    const uint32_t id = fs->next_id++;
    if (fs->next_id == 0U) {
        fs->next_id = 1U; /* 0 means "no identity" */
    }
    return id;
}

coslam_status_t fastslam_init(fastslam_t *fs, const fastslam_config_t *cfg, pose2_t pose0, uint64_t seed)
{
    COSLAM_ASSERT(fs != 0 && cfg != 0);
    if (config_validate(cfg) != COSLAM_OK || !pose2_is_finite(pose0)) {
        return COSLAM_E_ARG;
    }
    memset(&fs->ctr, 0, sizeof fs->ctr);
    fs->cfg = *cfg;
    rng_seed(&fs->rng, seed);
    fs->next_id = 1U;
    fs->last_ess = (double)cfg->n_particles;
    lm_tree_pool_init(&fs->lm_pool, 0U, 0U);
    for (uint16_t k = 0; k < COSLAM_MAX_PARTICLES; ++k) {
        fs->particles[k].lm_root = LM_TREE_NIL;
        fs->particles[k].n_lm = 0;
    }
    const cov3_t p0 = cov3_diag(cfg->slam.noise.init_xy_var_m2, cfg->slam.noise.init_xy_var_m2,
                                cfg->slam.noise.init_theta_var_rad2);
    for (uint16_t k = 0; k < cfg->n_particles; ++k) {
        fastslam_particle_t *p = &fs->particles[k];
        double d[3];
        sample_gauss3(&fs->rng, &p0, d);
        p->pose.x = pose0.x + d[0];
        p->pose.y = pose0.y + d[1];
        p->pose.theta = angle_wrap(pose0.theta + d[2]);
        p->pending_cov = cov3_zero();
        p->pose_marg = p0;
        p->log_w = 0.0;
        p->n_lm = 0;
    }
    return COSLAM_OK;
}

coslam_status_t fastslam_predict(fastslam_t *fs, odo_increment_t u)
{
    if (!motion_is_plausible(&fs->cfg.slam, u, MOTION_MAX_INCREMENT_S)) {
        fs->ctr.rejected_controls++;
        return COSLAM_E_NUMERIC;
    }
    const slam_params_t *sp = &fs->cfg.slam;
    const uint16_t n = fs->cfg.n_particles;
    fs->ctr.predictions++;
    const cov3_t r = motion_noise_cov(sp, u);
    const int fs1 = fs->cfg.proposal == FASTSLAM_PROPOSAL_MOTION;
    for (uint16_t k = 0; k < n; ++k) {
        fastslam_particle_t *p = &fs->particles[k];
        double g[3][3];
        double v[3][3];
        motion_jacobians(p->pose, u, g, v);
        const cov3_t vrv = cov3_congruence(v, r);
        p->pose_marg = cov3_add(cov3_congruence(g, p->pose_marg), vrv);
        if (fs1) {
            p->pose = motion_apply(p->pose, motion_sample(sp, u, &fs->rng));
        } else {
            /* Fast-SLAM 2.0: propagate the proposal mean; accumulate the
             * linearised motion covariance, the pose is sampled at the update. */
            p->pending_cov = cov3_add(cov3_congruence(g, p->pending_cov), vrv);
            p->pose = motion_apply(p->pose, u);
        }
    }
    const double w5 = sp->noise.lm_process_var_m2_per_m;
    if (w5 > 0.0) {
        const double add = w5 * motion_travel_m(u, sp->base_radius_m);
        for (uint16_t k = 0; k < n; ++k) {
            fastslam_particle_t *p = &fs->particles[k];
            for (uint16_t j = 0; j < p->n_lm; ++j) {
                landmark_t *lm = lm_tree_write(&fs->lm_pool, &p->lm_root, j);
                if (lm == 0) {
                    fs->ctr.tree_capacity_drops++;
                    continue;
                }
                lm->cov.xx += add;
                lm->cov.yy += add;
                lm_tree_changed(&fs->lm_pool, p->lm_root, j);
            }
        }
    }
    return COSLAM_OK;
}

/* Sample the Fast-SLAM 2.0 pose from pending_cov, if not done yet. */
static void fs2_commit_pose(fastslam_t *fs, fastslam_particle_t *p)
{
    double d[3];
    sample_gauss3(&fs->rng, &p->pending_cov, d);
    p->pose.x += d[0];
    p->pose.y += d[1];
    p->pose.theta = angle_wrap(p->pose.theta + d[2]);
    p->pending_cov = cov3_zero();
}

/*
 * Fast-SLAM 2.0 proposal: fold the matched sightings, one by one, into the
 * Gaussian N(pose, pending_cov) (an EKF update of the pose with the landmark
 * uncertainty in the noise), add each predictive log-likelihood to the
 * weight, then sample the pose. Thrun et al. 2005, table 13.3.
 */
static void fs2_improve_and_sample(fastslam_t *fs, fastslam_particle_t *p, const sighting_t *z, int ns,
                                   const int32_t *assign)
{
    const slam_params_t *sp = &fs->cfg.slam;
    for (int i = 0; i < ns; ++i) {
        if (assign[i] < 0) {
            continue;
        }
        const landmark_t *lm = lm_tree_get(&fs->lm_pool, p->lm_root, (uint32_t)assign[i]);
        lm_expect_t e;
        if (landmark_expect(lm, sp, p->pose, &p->pending_cov, &e) != COSLAM_OK) {
            fs->ctr.numeric_faults++;
            continue;
        }
        const double d2 = landmark_mahalanobis2(&e, z[i]);
        p->log_w += landmark_log_lik(&e, d2);
        double nu[2];
        observe_innovation(z[i], e.zhat, nu);
        /* K = C Hp^T S^-1 (3x2) */
        double(*c)[3] = p->pending_cov.m;
        double cht[3][2];
        for (int r = 0; r < 3; ++r) {
            for (int q = 0; q < 2; ++q) {
                cht[r][q] = c[r][0] * e.h_pose[q][0] + c[r][1] * e.h_pose[q][1] + c[r][2] * e.h_pose[q][2];
            }
        }
        double k[3][2];
        for (int r = 0; r < 3; ++r) {
            k[r][0] = cht[r][0] * e.s_inv.xx + cht[r][1] * e.s_inv.xy;
            k[r][1] = cht[r][0] * e.s_inv.xy + cht[r][1] * e.s_inv.yy;
        }
        p->pose.x += k[0][0] * nu[0] + k[0][1] * nu[1];
        p->pose.y += k[1][0] * nu[0] + k[1][1] * nu[1];
        p->pose.theta = angle_wrap(p->pose.theta + k[2][0] * nu[0] + k[2][1] * nu[1]);
        /* C -= K (C Hp^T)^T */
        cov3_t nc;
        for (int r = 0; r < 3; ++r) {
            for (int q = 0; q < 3; ++q) {
                nc.m[r][q] = c[r][q] - (k[r][0] * cht[q][0] + k[r][1] * cht[q][1]);
            }
        }
        nc = cov3_symmetrize(nc);
        /* guard against rounding: keep the diagonal non-negative */
        for (int r = 0; r < 3; ++r) {
            if (nc.m[r][r] < 0.0) {
                nc.m[r][r] = 0.0;
            }
        }
        p->pending_cov = nc;
    }
    fs2_commit_pose(fs, p);
}

/* A sighting's share of the pose-marginal update (marginal.h). */
typedef struct {
    cov3_t anchor;
    point2_t at;
    double hp[2][3];
    cov2_t n;
    double key;
} marg_obs_t;

/* Remove landmark j from particle p, keeping order irrelevant (the last
 * moves into the hole, as in a flat array). 0 if the tree pool ran out (the
 * map is then unchanged). */
static int particle_remove(fastslam_t *fs, fastslam_particle_t *p, uint16_t j)
{
    const uint16_t last = (uint16_t)(p->n_lm - 1U);
    const coslam_status_t st = j != last ? lm_tree_move(&fs->lm_pool, &p->lm_root, j, last)
                                         : lm_tree_clear(&fs->lm_pool, &p->lm_root, j);
    if (st != COSLAM_OK) {
        fs->ctr.tree_capacity_drops++;
        return 0;
    }
    p->n_lm = last;
    return 1;
}

coslam_status_t fastslam_particle_add(fastslam_t *fs, uint16_t k, const landmark_t *lm)
{
    fastslam_particle_t *p = &fs->particles[k];
    if (p->n_lm >= COSLAM_MAX_LANDMARKS) {
        fs->ctr.lm_capacity_drops++;
        return COSLAM_E_CAPACITY;
    }
    if (lm_tree_set(&fs->lm_pool, &p->lm_root, p->n_lm, lm) != COSLAM_OK) {
        fs->ctr.tree_capacity_drops++;
        return COSLAM_E_CAPACITY;
    }
    p->n_lm++;
    return COSLAM_OK;
}

const landmark_t *fastslam_particle_lm(const fastslam_t *fs, uint16_t k, uint16_t j)
{
    const fastslam_particle_t *p = &fs->particles[k];
    COSLAM_ASSERT(j < p->n_lm);
    return lm_tree_get(&fs->lm_pool, p->lm_root, j);
}

const landmark_t *const *fastslam_particle_landmarks(fastslam_t *fs, uint16_t k)
{
    const fastslam_particle_t *p = &fs->particles[k];
    const uint32_t n = lm_tree_gather(&fs->lm_pool, p->lm_root, p->n_lm, fs->scratch.view, 0);
    COSLAM_ASSERT(n == p->n_lm);
    (void)n;
    return fs->scratch.view;
}

coslam_status_t fastslam_particle_set(fastslam_t *fs, uint16_t k, uint16_t j, const landmark_t *lm)
{
    fastslam_particle_t *p = &fs->particles[k];
    if (j >= p->n_lm) {
        return COSLAM_E_ARG;
    }
    if (lm_tree_set(&fs->lm_pool, &p->lm_root, j, lm) != COSLAM_OK) {
        fs->ctr.tree_capacity_drops++;
        return COSLAM_E_CAPACITY;
    }
    return COSLAM_OK;
}

void fastslam_particle_clear(fastslam_t *fs, uint16_t k)
{
    lm_tree_release(&fs->lm_pool, &fs->particles[k].lm_root);
    fs->particles[k].n_lm = 0;
}

/* One particle's share of an update. Returns COSLAM_E_CAPACITY if its map filled up. */
static coslam_status_t update_particle(fastslam_t *fs, uint16_t k, const sighting_t *z, int ns,
                                       double max_range_m)
{
    const slam_params_t *sp = &fs->cfg.slam;
    fastslam_scratch_t *sc = &fs->scratch;
    fastslam_particle_t *p = &fs->particles[k];
    const int fs2 = fs->cfg.proposal == FASTSLAM_PROPOSAL_OPTIMAL;
    const cov3_t *pose_cov = fs2 ? &p->pending_cov : 0;
    coslam_status_t result = COSLAM_OK;

    /* 1. expected sightings of the landmarks near the sensor; the tree hands
     *    out, in slot order, every landmark that can pass the reach test
     *    below (lm_tree.h), the others are neither near nor matched */
    int n_pairs = 0;
    for (int i = 0; i < ns; ++i) {
        sc->n_near[i] = 0U;
    }
    const uint32_t n_cand = lm_tree_query(&fs->lm_pool, p->lm_root, p->n_lm, p->pose.x, p->pose.y, max_range_m,
                                          sc->view, sc->view_slot);
    uint16_t n_near_list = 0;
    for (uint32_t c = 0; c < n_cand; ++c) {
        const uint16_t j = sc->view_slot[c];
        const landmark_t *lm = sc->view[c];
        const double dx = lm->mean.x - p->pose.x;
        const double dy = lm->mean.y - p->pose.y;
        const double reach = max_range_m + 3.0 * sqrt(lm->cov.xx + lm->cov.yy) + 0.5;
        sc->near[j] = 0;
        sc->matched[j] = 0;
        if (dx * dx + dy * dy > reach * reach) {
            continue;
        }
        /* outside the camera's view no miss is counted, so the landmark
         * matters only if some sighting can come near it: skip it when a
         * cheap lower bound on every same-class sighting's distance is
         * beyond the new-landmark band (the decisions are unchanged; most
         * landmarks within reach are outside the field of view) */
        {
            const sighting_t zhat = observe_predict(p->pose, lm->mean);
            if (!landmark_should_be_seen(sp, zhat)) {
                const lm_d2_bound_t bound = landmark_d2_bound_prepare(lm, sp, pose_cov, zhat);
                int reachable = 0;
                for (int i = 0; i < ns && !reachable; ++i) {
                    reachable = z[i].signature == lm->signature &&
                                landmark_d2_lower_bound(&bound, z[i]) < sp->new_landmark_chi2;
                }
                if (!reachable) {
                    continue;
                }
            }
        }
        if (landmark_expect(lm, sp, p->pose, pose_cov, &sc->expect[j]) != COSLAM_OK) {
            fs->ctr.numeric_faults++;
            continue;
        }
        sc->near[j] = 1;
        sc->near_list[n_near_list++] = j;
        /* 2. gated candidate pairs, scored by log-likelihood */
        for (int i = 0; i < ns; ++i) {
            if (z[i].signature != lm->signature) {
                continue;
            }
            const double d2 = landmark_mahalanobis2(&sc->expect[j], z[i]);
            const double ll = landmark_log_lik(&sc->expect[j], d2);
            const assoc_class_t cls = assoc_classify(sp, d2, ll);
            if (cls == ASSOC_ADMISSIBLE) {
                assoc_pair_t *pr = &sc->pairs[n_pairs++];
                pr->score = ll;
                pr->sighting = i;
                pr->landmark = j;
            } else if (cls == ASSOC_NEAR && sc->n_near[i] < UINT8_MAX) {
                sc->n_near[i]++;
            }
        }
    }
    assoc_greedy(sc->pairs, n_pairs, ns, sc->assign);
    uint8_t make_new[COSLAM_MAX_SIGHTINGS];
    for (int i = 0; i < ns; ++i) {
        make_new[i] = sc->assign[i] < 0 && assoc_unpaired_is_new(sc->pairs, n_pairs, i, sc->assign, ns, sc->n_near);
    }

    /* 3. weights and landmark updates */
    marg_obs_t mobs[COSLAM_MAX_SIGHTINGS];
    int n_mobs = 0;
    if (fs2) {
        fs2_improve_and_sample(fs, p, z, ns, sc->assign);
    }
    for (int i = 0; i < ns; ++i) {
        const int32_t j = sc->assign[i];
        if (j < 0) {
            p->log_w += sp->new_landmark_log_lik;
            continue;
        }
        const landmark_t *lmc = lm_tree_get(&fs->lm_pool, p->lm_root, (uint32_t)j);
        lm_expect_t e;
        const lm_expect_t *ep = &sc->expect[j];
        if (fs2) {
            /* landmark update at the sampled pose, pose now known */
            if (landmark_expect(lmc, sp, p->pose, 0, &e) != COSLAM_OK) {
                fs->ctr.numeric_faults++;
                continue;
            }
            ep = &e;
        } else {
            p->log_w += landmark_log_lik(ep, landmark_mahalanobis2(ep, z[i]));
        }
        /* this particle's own copy of the landmark (copy-on-write) */
        landmark_t *lm = lm_tree_write(&fs->lm_pool, &p->lm_root, (uint32_t)j);
        if (lm == 0) {
            fs->ctr.tree_capacity_drops++;
            result = COSLAM_E_CAPACITY;
            sc->matched[j] = 1; /* not updated, but not missed either */
            continue;
        }
        /* pose marginal: the sighting bounds the drift since the landmark's
         * anchor; applied below, after the frame's other sightings */
        {
            marg_obs_t *mo = &mobs[n_mobs++];
            mo->n = cov2_add(cov2_congruence((double(*)[2])ep->h_lm, lm->cov), observe_noise(sp, ep->zhat.range_m));
            mo->anchor = landmark_anchor(lm);
            mo->at = (point2_t){lm->anchor_xy[0], lm->anchor_xy[1]};
            memcpy(mo->hp, ep->h_pose, sizeof mo->hp);
            mo->key = mo->anchor.m[0][0] + mo->anchor.m[1][1];
        }
        landmark_update(lm, sp, ep, z[i]);
        exist_hit(&lm->exist, sp);
        lm_tree_changed(&fs->lm_pool, p->lm_root, (uint32_t)j);
        sc->matched[j] = 1;
    }
    /* Each sighting leaves the pose marginal at least its landmark's
     * anchor (carried forward): take the loosest anchors first, so that the
     * tightest one sets the floor (insertion sort, n <= sightings). */
    for (int a = 1; a < n_mobs; ++a) {
        for (int b = a; b > 0 && mobs[b].key > mobs[b - 1].key; --b) {
            const marg_obs_t tmp = mobs[b];
            mobs[b] = mobs[b - 1];
            mobs[b - 1] = tmp;
        }
    }
    for (int a = 0; a < n_mobs; ++a) {
        if (marginal_pose_observe(&p->pose_marg, p->pose, &mobs[a].anchor, mobs[a].at, mobs[a].hp, mobs[a].n) !=
            COSLAM_OK) {
            fs->ctr.numeric_faults++;
        }
    }

    /* 5. negative evidence (before adding, so that freed slots can be reused);
     *    iterate downwards because removal swaps in the last landmark (which
     *    was visited already); only near landmarks can be missed */
    for (int c = (int)n_near_list - 1; c >= 0; --c) {
        const uint16_t j = sc->near_list[c];
        if (sc->matched[j]) {
            continue;
        }
        const lm_expect_t *ep = &sc->expect[j];
        if (!landmark_should_be_seen(sp, ep->zhat)) {
            continue;
        }
        /* on a copy: the shared landmark is written only if it changed */
        const landmark_t *lmc = lm_tree_get(&fs->lm_pool, p->lm_root, j);
        float exist = lmc->exist;
        uint8_t confirmed_once = lmc->confirmed_once;
        if (exist_miss(&exist, &confirmed_once, landmark_miss_is_certain(sp, ep), sp)) {
            if (particle_remove(fs, p, j)) {
                fs->ctr.landmarks_removed++;
            } else {
                result = COSLAM_E_CAPACITY;
            }
        } else if (memcmp(&exist, &lmc->exist, sizeof exist) != 0 || confirmed_once != lmc->confirmed_once) {
            landmark_t *lm = lm_tree_write(&fs->lm_pool, &p->lm_root, j);
            if (lm == 0) {
                fs->ctr.tree_capacity_drops++;
                result = COSLAM_E_CAPACITY;
                continue;
            }
            lm->exist = exist; /* the box does not depend on it: not changed */
            lm->confirmed_once = confirmed_once;
        }
    }

    /* 4. new landmarks from unmatched, unambiguous sightings */
    for (int i = 0; i < ns; ++i) {
        if (!make_new[i]) {
            continue;
        }
        if (sc->new_id[i] == 0U) {
            sc->new_id[i] = fastslam_new_id(fs);
            fs->ctr.landmarks_added++;
        }
        landmark_t lm;
        if (landmark_init(&lm, sp, p->pose, z[i], sc->new_id[i], (uint16_t)(1U << fs->cfg.robot_id)) !=
            COSLAM_OK) {
            fs->ctr.numeric_faults++;
            continue;
        }
        landmark_set_anchor(&lm, &p->pose_marg, (point2_t){p->pose.x, p->pose.y});
        if (fastslam_particle_add(fs, k, &lm) != COSLAM_OK) {
            result = COSLAM_E_CAPACITY;
        }
    }
    return result;
}

static double normalise_log_weights(fastslam_t *fs)
{
    const uint16_t n = fs->cfg.n_particles;
    double mx = -INFINITY;
    for (uint16_t k = 0; k < n; ++k) {
        if (fs->particles[k].log_w > mx) {
            mx = fs->particles[k].log_w;
        }
    }
    if (!isfinite(mx)) {
        /* every weight collapsed or is NaN: restart from uniform weights */
        fs->ctr.numeric_faults++;
        for (uint16_t k = 0; k < n; ++k) {
            fs->particles[k].log_w = 0.0;
        }
        return (double)n;
    }
    double sum = 0.0;
    double sum2 = 0.0;
    for (uint16_t k = 0; k < n; ++k) {
        double lw = fs->particles[k].log_w - mx;
        if (!isfinite(lw)) {
            lw = -1e300;
        }
        fs->particles[k].log_w = lw;
        const double w = exp(lw);
        sum += w;
        sum2 += w * w;
    }
    return sum * sum / sum2;
}

void fastslam_reweighted(fastslam_t *fs)
{
    fs->last_ess = normalise_log_weights(fs);
    if (fs->last_ess < fs->cfg.resample_ess_fraction * (double)fs->cfg.n_particles) {
        fastslam_resample(fs);
    }
}

void fastslam_weights(const fastslam_t *fs, double *out)
{
    const uint16_t n = fs->cfg.n_particles;
    double mx = -INFINITY;
    for (uint16_t k = 0; k < n; ++k) {
        if (fs->particles[k].log_w > mx) {
            mx = fs->particles[k].log_w;
        }
    }
    double sum = 0.0;
    for (uint16_t k = 0; k < n; ++k) {
        out[k] = exp(fs->particles[k].log_w - mx);
        sum += out[k];
    }
    for (uint16_t k = 0; k < n; ++k) {
        out[k] /= sum;
    }
}

/* O(1) plus freeing what only dst held: the map is shared, not copied. */
static void copy_particle(lm_tree_pool_t *pool, fastslam_particle_t *dst, const fastslam_particle_t *src)
{
    dst->pose = src->pose;
    dst->pending_cov = src->pending_cov;
    dst->pose_marg = src->pose_marg;
    dst->log_w = src->log_w;
    dst->n_lm = src->n_lm;
    lm_tree_release(pool, &dst->lm_root);
    lm_tree_retain(pool, src->lm_root);
    dst->lm_root = src->lm_root;
}

void fastslam_resample(fastslam_t *fs)
{
    const uint16_t n = fs->cfg.n_particles;
    double *w = fs->scratch.weights;
    uint16_t *copies = fs->scratch.copies;
    fastslam_weights(fs, w);
    /* low-variance sampler: one random offset, N equally spaced pointers */
    const double step = 1.0 / (double)n;
    double u = rng_uniform(&fs->rng) * step;
    double c = w[0];
    uint16_t i = 0;
    for (uint16_t k = 0; k < n; ++k) {
        copies[k] = 0;
    }
    for (uint16_t m = 0; m < n; ++m) {
        while (u > c && i + 1 < n) {
            ++i;
            c += w[i];
        }
        copies[i]++;
        u += step;
    }
    /* In place: a particle drawn c > 1 times is copied into slots of
     * particles drawn 0 times. Those slots are never sources, and sources
     * are never overwritten, so the order of copying does not matter. */
    uint16_t free_slot = 0;
    for (uint16_t k = 0; k < n; ++k) {
        while (copies[k] > 1) {
            while (copies[free_slot] != 0) {
                ++free_slot;
            }
            copy_particle(&fs->lm_pool, &fs->particles[free_slot], &fs->particles[k]);
            copies[free_slot] = 1; /* now occupied; never a source of copies */
            copies[k]--;
        }
    }
    for (uint16_t k = 0; k < n; ++k) {
        fs->particles[k].log_w = 0.0;
    }
    fs->ctr.resamples++;
}

coslam_status_t fastslam_update(fastslam_t *fs, const sighting_t *z_in, int n_in)
{
    COSLAM_ASSERT(fs != 0 && (z_in != 0 || n_in == 0));
    coslam_status_t result = COSLAM_OK;
    /* valid sightings into a local copy */
    sighting_t z[COSLAM_MAX_SIGHTINGS];
    int ns = 0;
    double max_range_m = fs->cfg.slam.sensor_max_range_m;
    for (int i = 0; i < n_in; ++i) {
        if (!sighting_is_plausible(&z_in[i], &fs->cfg.slam)) {
            fs->ctr.rejected_sightings++;
            if (result == COSLAM_OK) {
                result = COSLAM_E_NUMERIC;
            }
            continue;
        }
        if (ns >= COSLAM_MAX_SIGHTINGS) {
            fs->ctr.sighting_capacity_drops++;
            result = COSLAM_E_CAPACITY;
            continue;
        }
        z[ns] = z_in[i];
        if (z[ns].range_m > max_range_m) {
            max_range_m = z[ns].range_m;
        }
        fs->scratch.new_id[ns] = 0U;
        ++ns;
    }
    fs->ctr.updates++;
    for (uint16_t k = 0; k < fs->cfg.n_particles; ++k) {
        if (update_particle(fs, k, z, ns, max_range_m) == COSLAM_E_CAPACITY) {
            result = COSLAM_E_CAPACITY;
        }
    }
    fastslam_reweighted(fs);
    return result;
}

uint16_t fastslam_best_particle(const fastslam_t *fs)
{
    uint16_t best = 0;
    for (uint16_t k = 1; k < fs->cfg.n_particles; ++k) {
        if (fs->particles[k].log_w > fs->particles[best].log_w) {
            best = k;
        }
    }
    return best;
}

void fastslam_pose_estimate(const fastslam_t *fs, pose2_t *mean, cov3_t *cov)
{
    const uint16_t n = fs->cfg.n_particles;
    double mx = -INFINITY;
    for (uint16_t k = 0; k < n; ++k) {
        if (fs->particles[k].log_w > mx) {
            mx = fs->particles[k].log_w;
        }
    }
    double sw = 0.0;
    double sx = 0.0;
    double sy = 0.0;
    double ss = 0.0;
    double scs = 0.0;
    for (uint16_t k = 0; k < n; ++k) {
        const fastslam_particle_t *p = &fs->particles[k];
        const double w = exp(p->log_w - mx);
        sw += w;
        sx += w * p->pose.x;
        sy += w * p->pose.y;
        ss += w * sin(p->pose.theta);
        scs += w * cos(p->pose.theta);
    }
    pose2_t m = {sx / sw, sy / sw, atan2(ss, scs)};
    m.theta = angle_wrap(m.theta);
    cov3_t c = cov3_zero();
    cov3_t g = cov3_zero();
    for (uint16_t k = 0; k < n; ++k) {
        const fastslam_particle_t *p = &fs->particles[k];
        const double w = exp(p->log_w - mx) / sw;
        const double d[3] = {p->pose.x - m.x, p->pose.y - m.y, angle_wrap(p->pose.theta - m.theta)};
        for (int r = 0; r < 3; ++r) {
            for (int q = 0; q < 3; ++q) {
                c.m[r][q] += w * (d[r] * d[q] + p->pending_cov.m[r][q]);
                g.m[r][q] += w * (d[r] * d[q] + p->pose_marg.m[r][q]);
            }
        }
    }
    *mean = m;
    *cov = cov3_loewner_max(cov3_symmetrize(c), cov3_symmetrize(g));
}

/* Slot of identity `id` in the export table, inserting (zeroed) if absent; -1 if full. */
static int export_slot(fastslam_export_scratch_t *t, uint32_t id, int insert)
{
    uint32_t h = (id * 2654435761U) % (uint32_t)COSLAM_MAX_EXPORT_IDS;
    for (int probe = 0; probe < COSLAM_MAX_EXPORT_IDS; ++probe) {
        if (t->id[h] == id) {
            return (int)h;
        }
        if (t->id[h] == 0U) {
            if (!insert) {
                return -1;
            }
            t->id[h] = id;
            t->w[h] = 0.0;
            t->mx[h] = 0.0;
            t->my[h] = 0.0;
            t->cxx[h] = 0.0;
            t->cxy[h] = 0.0;
            t->cyy[h] = 0.0;
            t->rx[h] = 0.0;
            t->ry[h] = 0.0;
            t->rxx[h] = 0.0;
            t->rxy[h] = 0.0;
            t->ryy[h] = 0.0;
            t->nobs[h] = 0.0;
            t->src_mask[h] = 0U;
            t->signature[h] = 0U;
            return (int)h;
        }
        h = (h + 1U) % (uint32_t)COSLAM_MAX_EXPORT_IDS;
    }
    return -1;
}

/* Order export candidates: by weight (descending) for selection, then by id. */
static void sort_u32_by_key(uint32_t *v, int n, const fastslam_export_scratch_t *t, int by_weight)
{
    /* insertion sort: n <= COSLAM_MAX_EXPORT_IDS, and exports are rare */
    for (int i = 1; i < n; ++i) {
        const uint32_t x = v[i];
        int j = i - 1;
        while (j >= 0) {
            const int before = by_weight ? (t->w[v[j]] < t->w[x]) : (t->id[v[j]] > t->id[x]);
            if (!before) {
                break;
            }
            v[j + 1] = v[j];
            --j;
        }
        v[j + 1] = x;
    }
}

/* Both passes of the export: per identity, weight, mean and covariance
 * (map and relative) into the export table; the pose estimate. */
static coslam_status_t export_accumulate(fastslam_t *fs, pose2_t *pose, cov3_t *pose_cov)
{
    const uint16_t n = fs->cfg.n_particles;
    const slam_params_t *sp = &fs->cfg.slam;
    fastslam_export_scratch_t *t = &fs->export_scratch;
    double *w = fs->scratch.weights;
    coslam_status_t result = COSLAM_OK;
    fastslam_weights(fs, w);
    fastslam_pose_estimate(fs, pose, pose_cov);

    memset(t->id, 0, sizeof t->id);
    /* pass 1: total weight and weighted mean per identity */
    for (uint16_t k = 0; k < n; ++k) {
        const fastslam_particle_t *p = &fs->particles[k];
        const landmark_t *const *lms = fastslam_particle_landmarks(fs, k);
        for (uint16_t j = 0; j < p->n_lm; ++j) {
            const landmark_t *lm = lms[j];
            if (!landmark_is_confirmed(lm, sp)) {
                continue;
            }
            const int s = export_slot(t, lm->id, 1);
            if (s < 0) {
                fs->ctr.export_capacity_drops++;
                result = COSLAM_E_CAPACITY;
                continue;
            }
            t->w[s] += w[k];
            t->mx[s] += w[k] * lm->mean.x;
            t->my[s] += w[k] * lm->mean.y;
            const point2_t rel = pose2_apply_inverse(p->pose, lm->mean);
            t->rx[s] += w[k] * rel.x;
            t->ry[s] += w[k] * rel.y;
            t->nobs[s] += w[k] * (double)lm->n_obs;
            t->src_mask[s] |= lm->src_mask;
            t->signature[s] = lm->signature;
        }
    }
    for (int s = 0; s < COSLAM_MAX_EXPORT_IDS; ++s) {
        if (t->id[s] != 0U && t->w[s] > 0.0) {
            t->mx[s] /= t->w[s];
            t->my[s] /= t->w[s];
            t->rx[s] /= t->w[s];
            t->ry[s] /= t->w[s];
        }
    }
    /* pass 2: covariance = within-particle covariance + spread of the means */
    for (uint16_t k = 0; k < n; ++k) {
        const fastslam_particle_t *p = &fs->particles[k];
        const double c = cos(p->pose.theta);
        const double sn = sin(p->pose.theta);
        double rt[2][2] = {{c, sn}, {-sn, c}}; /* R^T: map -> this particle's body frame */
        const landmark_t *const *lms = fastslam_particle_landmarks(fs, k);
        for (uint16_t j = 0; j < p->n_lm; ++j) {
            const landmark_t *lm = lms[j];
            if (!landmark_is_confirmed(lm, sp)) {
                continue;
            }
            const int s = export_slot(t, lm->id, 0);
            if (s < 0) {
                continue; /* counted in pass 1 */
            }
            const double dx = lm->mean.x - t->mx[s];
            const double dy = lm->mean.y - t->my[s];
            const cov2_t g = landmark_marginal(lm);
            t->cxx[s] += w[k] * (g.xx + dx * dx);
            t->cxy[s] += w[k] * (g.xy + dx * dy);
            t->cyy[s] += w[k] * (g.yy + dy * dy);
            /* relative to this particle's pose, in its body frame: sensor
             * noise plus the pose drift since the landmark's anchor
             * (marginal_relative_drift) */
            const point2_t rel = pose2_apply_inverse(p->pose, lm->mean);
            const cov3_t anchor = landmark_anchor(lm);
            const cov2_t cr = cov2_add(cov2_congruence(rt, lm->cov),
                                       marginal_relative_drift(&p->pose_marg, p->pose, &anchor,
                                                               (point2_t){lm->anchor_xy[0], lm->anchor_xy[1]}, rel));
            const double ex = rel.x - t->rx[s];
            const double ey = rel.y - t->ry[s];
            t->rxx[s] += w[k] * (cr.xx + ex * ex);
            t->rxy[s] += w[k] * (cr.xy + ex * ey);
            t->ryy[s] += w[k] * (cr.yy + ey * ey);
        }
    }
    return result;
}

/* Identities exported: weight >= export_min_weight, into t->sel; their count. */
static int export_select(fastslam_t *fs)
{
    const fastslam_export_scratch_t *t = &fs->export_scratch;
    uint32_t *sel = fs->export_scratch.sel;
    int n_sel = 0;
    for (int s = 0; s < COSLAM_MAX_EXPORT_IDS; ++s) {
        if (t->id[s] != 0U && t->w[s] >= fs->cfg.export_min_weight - 1e-12) {
            sel[n_sel++] = (uint32_t)s;
        }
    }
    return n_sel;
}

/* Table slots sel[0..n) into lm, normalised. */
static void export_fill(const fastslam_export_scratch_t *t, const uint32_t *sel, int n, map_landmark_t *lm)
{
    for (int i = 0; i < n; ++i) {
        const uint32_t s = sel[i];
        map_landmark_t *o = &lm[i];
        const double inv_w = 1.0 / t->w[s];
        o->mean.x = t->mx[s];
        o->mean.y = t->my[s];
        o->cov = cov2_make(t->cxx[s] * inv_w, t->cxy[s] * inv_w, t->cyy[s] * inv_w);
        o->cov_rel = cov2_make(t->rxx[s] * inv_w, t->rxy[s] * inv_w, t->ryy[s] * inv_w);
        o->id = t->id[s];
        const double nobs = t->nobs[s] * inv_w + 0.5;
        o->n_obs = nobs >= 65535.0 ? (uint16_t)65535U : (uint16_t)nobs;
        o->src_mask = t->src_mask[s];
        o->signature = t->signature[s];
    }
}

/* Combine, select, keep the heaviest `cap` (the rest counted), fill lm by
 * identity; the pose estimate into pose and cov. */
static coslam_status_t export_capped(fastslam_t *fs, pose2_t *pose, cov3_t *cov, map_landmark_t *lm, int cap,
                                     uint16_t *n_out)
{
    fastslam_export_scratch_t *t = &fs->export_scratch;
    coslam_status_t result = export_accumulate(fs, pose, cov);
    int n_sel = export_select(fs);
    if (n_sel > cap) {
        sort_u32_by_key(t->sel, n_sel, t, 1);
        fs->ctr.export_capacity_drops += (uint32_t)(n_sel - cap);
        n_sel = cap;
        result = COSLAM_E_CAPACITY;
    }
    sort_u32_by_key(t->sel, n_sel, t, 0);
    export_fill(t, t->sel, n_sel, lm);
    *n_out = (uint16_t)n_sel;
    return result;
}

coslam_status_t fastslam_export(fastslam_t *fs, map_estimate_t *out)
{
    /* more than a message carries: the heaviest landmarks go */
    return export_capped(fs, &out->pose, &out->pose_cov, out->lm, COSLAM_MAX_MSG_LANDMARKS, &out->n_landmarks);
}

coslam_status_t fastslam_export_whole(fastslam_t *fs, map_whole_t *out)
{
    return export_capped(fs, &out->pose, &out->pose_cov, out->lm, COSLAM_MAX_LANDMARKS, &out->n_landmarks);
}
