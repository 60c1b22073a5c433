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
    c.closure_drift_ratio = 4.0;
    c.closure_gap = 25U;
    c.closure_ambiguity_ll = 2.302585093; /* ln 10 */
    c.closure_misses_per_support = 2.0;
    c.closure_chance_max = 1.0;
    c.closure_unsupported_every = 2U;
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
    if (!(c->closure_drift_ratio >= 0.0 && c->closure_drift_ratio < 1e12) ||
        !(c->closure_ambiguity_ll >= 0.0 && c->closure_ambiguity_ll < 1e12) ||
        !(c->closure_misses_per_support >= 0.0 && c->closure_misses_per_support < 1e12) ||
        !(c->closure_chance_max >= 0.0 && c->closure_chance_max < 1e12)) {
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
    fs->view = 0;
    fs->cfg = *cfg;
    rng_seed(&fs->rng, seed);
    fs->next_id = 1U;
    fs->merges = 0U;
    fs->merge_due_n = 0U;
    fs->export_due = 0U;
    fs->export_scratch.job_pass = 0U;
    fs->last_ess = (double)cfg->n_particles;
    lm_tree_pool_init(&fs->lm_pool, 0U, 0U);
    for (uint16_t k = 0; k < COSLAM_MAX_PARTICLES; ++k) {
        fs->particles[k].lm_root = LM_TREE_NIL;
        fs->particles[k].n_lm = 0;
        fs->particles[k].merge_due = 0U;
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
    const uint32_t tree_drops = fs->ctr.tree_capacity_drops;
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
    /* the tree pool ran out: the prediction stands, some landmark lacks its
     * process noise (counted) */
    return fs->ctr.tree_capacity_drops != tree_drops ? COSLAM_E_CAPACITY : COSLAM_OK;
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
    double(*gain)[3][2] = fs->scratch.gain;
    for (int i = 0; i < ns; ++i) {
        memset(gain[i], 0, sizeof gain[i]); /* no correction unless made below */
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
        memcpy(gain[i], k, sizeof k);
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
    double (*k)[2]; /* the pose gain the particle applied (Fast-SLAM 2.0), else 0 */
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

const landmark_t **fastslam_particle_select(fastslam_t *fs, uint16_t k, lm_tree_box_fn may_hold, void *ctx,
                                            uint16_t *slot_out, uint8_t *all_out, uint16_t *n)
{
    const fastslam_particle_t *p = &fs->particles[k];
    *n = (uint16_t)lm_tree_select(&fs->lm_pool, p->lm_root, p->n_lm, may_hold, ctx, fs->scratch.view, slot_out,
                                  all_out);
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


/* ---- Revisits: loop closure by the drift since an old landmark's anchor --
 *
 * A depleted particle set cannot close a long loop by itself: its particles
 * share one ancestor for the whole loop, each is sure of its pose relative to
 * the landmarks it saw last, and those landmarks share its drift. At the
 * revisit the old landmarks are then predicted where the drift puts them,
 * outside the gate, and the sightings start copies (docs/consistency.md,
 * "Not solved", the trace of seed 8). What the particle does know is how
 * much it may have drifted since an old landmark was started: its pose
 * marginal P and the landmark's anchor A (marginal.h) give the drift since
 * then, D = P - Phi A Phi^T.
 *
 * So a sighting that would start a landmark is tried again against the
 * landmarks of its class that have not been sighted for closure_gap updates
 * and whose drift term Hp D Hp^T outweighs the sighting's own innovation
 * covariance S (trace (Hp D Hp^T) S^-1 > closure_drift_ratio), with S + Hp D
 * Hp^T in the gate; the best one inside it closes the loop if no other
 * explains the sighting within closure_ambiguity_ll.
 *
 * The closure is the linear-Gaussian update of a path whose errors are a
 * random walk, as an EKF would do it, with the particle's marginals standing
 * in for its correlations:
 *  - the drift since the old anchor, prior D, sighting nu = z - h(pose, m)
 *    with noise S: the pose moves by D g, g = Hp^T (S + Hp D Hp^T)^-1 nu;
 *  - a landmark l started later from anchor (A_l, a_l) shares the part of
 *    that drift accumulated before its anchor, W_l = A_l - Phi A Phi^T
 *    (clipped >= 0; Phi carries the old anchor's heading error to a_l); its
 *    anchor's error moves by W_l Phi_l^T g (Phi_l carries a_l's heading error
 *    to the pose), and the landmark with it: G_l times that, G_l = d m_l /
 *    d(anchor pose), a rotation about a_l. Landmarks started before the old
 *    anchor (W_l = 0) and the old landmark itself stay;
 *  - the sighting's weight is its likelihood under S + Hp D Hp^T (the
 *    particles that found the revisit compete with those that did not on
 *    the evidence, not on the corrected state);
 *  - the pose marginal learns the drift (marginal_pose_observe).
 * The moved landmarks keep their covariances and anchors (conservative: the
 * closure does not shrink what they share). The FS2 proposal then runs on
 * the frame's other pairings from the corrected pose.
 * Only sightings that would otherwise start a landmark are tried: pairings
 * that the ordinary gate accepts keep the ordinary update. Only landmarks
 * built from this robot's own sightings are revisits, and only they move:
 * one that a merge fused or brought in holds a partner's errors, not its
 * anchor's. And none after the filter's first merge (fastslam_t.merges):
 * the merge moves part of the map into the partner's frame, which the own
 * landmarks' anchors do not describe (on the arena teams the closures of
 * merged robots moved them 2-5 cm farther from their maps; re-anchoring at
 * a merge would be the next step). Tried and not
 * kept: widening every old landmark's gate in the ordinary association and
 * routing its pairings through the closure (the long loop closes more often,
 * but in the arena's clusters of identical landmarks the widened gates pair
 * wrongly: 10.8 spurious landmarks per run instead of 0.2); requiring two
 * closures in one frame (never happens on the long loop).
 */

/* Revisits the frame supports (closure_misses_per_support,
 * closure_unsupported_every; docs/consistency.md). Traced on the long loop's
 * held-out seeds, most closures of the runs that failed were wrong: a
 * sighting of a landmark never mapped closed on an old one of its class
 * 1-2 m away, inside a gate the drift had widened, and moved the pose by
 * that much. No single-sighting statistic (likelihood, d2, drift, size of
 * the move) told them from the right ones. What does is the rest of the
 * frame: from the pose a right closure gives, the old landmarks around the
 * revisit explain other sightings, and those it puts in view are sighted.
 * So a particle closes a revisit only if, from that pose (every landmark
 * where the closure would move it), a landmark not sighted for closure_gap
 * updates explains at least one other sighting of the frame (gate_chi2),
 * and the confirmed landmarks it puts certainly in view with no sighting
 * near them, and that were not so from the present pose, number at most
 * closure_misses_per_support per supporting sighting. A right closure at
 * the edge of the old map has no support yet; so every
 * closure_unsupported_every-th particle closes without it, the others
 * start a landmark and wait, and the frames that follow weigh the two.
 * Support is asked only where a chance pairing is likely: where the
 * widened gate holds closure_chance_max other landmarks of the class.
 * Elsewhere (small drift, sparse classes) a lone sighting closes as
 * before: asked everywhere, the split left the particle set divided at
 * the merges that follow a revisit, and the merged maps were worse.
 */

/* A sighting's noise about the drift (marginal.h): Hm cov Hm^T + Q. */
static cov2_t sighting_noise(const lm_expect_t *e, const landmark_t *lm, const slam_params_t *sp)
{
    return cov2_add(cov2_congruence((double(*)[2])e->h_lm, lm->cov), observe_noise(sp, e->zhat.range_m));
}

/* The expectation with `add` in its innovation covariance; 0 if not PD. */
static int expect_widened(lm_expect_t *e, cov2_t add)
{
    const cov2_t s = cov2_add(e->s, add);
    cov2_t si;
    if (cov2_inverse(s, &si) != COSLAM_OK || !(cov2_det(s) > 0.0)) {
        return 0;
    }
    e->s = s;
    e->s_inv = si;
    e->log_norm = -log(COSLAM_TWO_PI * sqrt(cov2_det(s)));
    return 1;
}

/* Updates since landmark lm was last sighted (modulo 2^16, as last_seen). */
static uint16_t unseen_for(const fastslam_t *fs, const landmark_t *lm)
{
    return (uint16_t)((uint16_t)fs->ctr.updates - lm->last_seen);
}

/* Landmark lm (at the predicted pose: expectation e) as a revisit: its
 * expectation widened by the drift since its anchor into *ew. 0 if it is not
 * one (seen recently, holding a partner's information, a merge happened, or
 * the drift is small against S). */
static int revisit_expect(const fastslam_t *fs, const fastslam_particle_t *p, const landmark_t *lm,
                          const lm_expect_t *e, lm_expect_t *ew)
{
    if (unseen_for(fs, lm) <= fs->cfg.closure_gap || lm->src_mask != (uint16_t)(1U << fs->cfg.robot_id) ||
        fs->merges > 0U) {
        return 0;
    }
    const cov3_t a = landmark_anchor(lm);
    const cov3_t d = marginal_drift(&p->pose_marg, p->pose, &a, (point2_t){lm->anchor_xy[0], lm->anchor_xy[1]});
    const cov2_t add = cov2_from_3x3((double(*)[3])e->h_pose, (double(*)[3])d.m); /* Hp D Hp^T */
    const cov2_t si = e->s_inv;
    const double ratio = add.xx * si.xx + 2.0 * add.xy * si.xy + add.yy * si.yy;
    if (!(ratio > fs->cfg.closure_drift_ratio)) {
        return 0;
    }
    *ew = *e;
    return expect_widened(ew, add);
}

/* Sightings that would start a landmark, tried as revisits: closure_j[i]
 * the old landmark sighting i closes on, else -1. */
static void find_revisits(const fastslam_t *fs, const fastslam_particle_t *p, const sighting_t *z, int ns,
                          const uint8_t *make_new, uint16_t n_near_list, int32_t *closure_j)
{
    const fastslam_scratch_t *sc = &fs->scratch;
    const slam_params_t *sp = &fs->cfg.slam;
    for (int i = 0; i < ns; ++i) {
        closure_j[i] = -1;
    }
    for (int i = 0; i < ns; ++i) {
        if (!make_new[i]) {
            continue;
        }
        double best = -INFINITY;
        double second = -INFINITY;
        int32_t best_j = -1;
        for (uint16_t c = 0; c < n_near_list; ++c) {
            const uint16_t j = sc->near_list[c];
            const landmark_t *lm = lm_tree_get(&fs->lm_pool, p->lm_root, j);
            if (lm->signature != z[i].signature) {
                continue;
            }
            int taken = 0;
            for (int q = 0; q < ns && !taken; ++q) {
                taken = sc->assign[q] == (int32_t)j || closure_j[q] == (int32_t)j;
            }
            lm_expect_t ew;
            if (taken || !revisit_expect(fs, p, lm, &sc->expect[j], &ew)) {
                continue;
            }
            const double d2 = landmark_mahalanobis2(&ew, z[i]);
            if (!(d2 < sp->gate_chi2)) {
                continue;
            }
            const double ll = landmark_log_lik(&ew, d2);
            if (ll > best) {
                second = best;
                best = ll;
                best_j = (int32_t)j;
            } else if (ll > second) {
                second = ll;
            }
        }
        if (best_j >= 0 && !(best - second < fs->cfg.closure_ambiguity_ll)) {
            closure_j[i] = best_j;
        }
    }
}

/* A revisit's correction: sighting z on old landmark `old` at the
 * particle's pose (with its pending motion), the drift D since the old
 * anchor, g = Hp^T (S + Hp D Hp^T)^-1 nu, and the corrected pose. */
typedef struct {
    lm_expect_t e;    /* at the present pose, drift not included */
    cov3_t d;         /* drift since the old anchor */
    cov3_t a_old;     /* the old landmark's anchor */
    point2_t at_old;
    double g[3];
    double ll;        /* the sighting's log-likelihood under the drift */
    cov2_t s_inv;     /* inverse of the widened innovation covariance */
    pose2_t pose;     /* the corrected pose */
} revisit_fix_t;

/* 0 if the geometry failed (nothing is changed then). */
static int revisit_fix(const fastslam_t *fs, const fastslam_particle_t *p, const landmark_t *old, sighting_t z,
                       revisit_fix_t *f)
{
    const slam_params_t *sp = &fs->cfg.slam;
    f->a_old = landmark_anchor(old);
    f->at_old = (point2_t){old->anchor_xy[0], old->anchor_xy[1]};
    if (landmark_expect(old, sp, p->pose, &p->pending_cov, &f->e) != COSLAM_OK) {
        return 0;
    }
    f->d = marginal_drift(&p->pose_marg, p->pose, &f->a_old, f->at_old);
    lm_expect_t ew = f->e;
    if (!expect_widened(&ew, cov2_from_3x3(f->e.h_pose, (double(*)[3])f->d.m))) {
        return 0;
    }
    double nu[2];
    observe_innovation(z, ew.zhat, nu);
    f->ll = landmark_log_lik(&ew, landmark_mahalanobis2(&ew, z));
    f->s_inv = ew.s_inv;
    const double sn0 = ew.s_inv.xx * nu[0] + ew.s_inv.xy * nu[1];
    const double sn1 = ew.s_inv.xy * nu[0] + ew.s_inv.yy * nu[1];
    for (int i = 0; i < 3; ++i) {
        f->g[i] = f->e.h_pose[0][i] * sn0 + f->e.h_pose[1][i] * sn1;
    }
    const cov3_t *d = &f->d;
    f->pose = p->pose;
    f->pose.x += d->m[0][0] * f->g[0] + d->m[0][1] * f->g[1] + d->m[0][2] * f->g[2];
    f->pose.y += d->m[1][0] * f->g[0] + d->m[1][1] * f->g[1] + d->m[1][2] * f->g[2];
    f->pose.theta = angle_wrap(p->pose.theta + d->m[2][0] * f->g[0] + d->m[2][1] * f->g[1] + d->m[2][2] * f->g[2]);
    return 1;
}

/* How the closure moves own landmark lc (its anchor's share of the drift,
 * see "Revisits" above; at_now is the pose before the closure): 1 and the
 * move in *dx, *dy, or 0 where it does not move (started before the old
 * anchor, or by under 0.1 mm). */
static int revisit_move(const landmark_t *lc, const revisit_fix_t *f, point2_t at_now, double *dx, double *dy)
{
    const point2_t al = {lc->anchor_xy[0], lc->anchor_xy[1]};
    /* W_l: the drift from the old anchor to l's (marginal.h) */
    const cov3_t al_cov = landmark_anchor(lc);
    const cov3_t w = marginal_drift(&al_cov, (pose2_t){al.x, al.y, 0.0}, &f->a_old, f->at_old);
    if (!(w.m[0][0] + w.m[1][1] + w.m[2][2] > 1e-12)) {
        return 0;
    }
    /* Phi_l^T g, Phi_l carrying a_l's heading error to the pose */
    const double *g = f->g;
    const double pg[3] = {g[0], g[1], -(at_now.y - al.y) * g[0] + (at_now.x - al.x) * g[1] + g[2]};
    double da[3];
    for (int r = 0; r < 3; ++r) {
        da[r] = w.m[r][0] * pg[0] + w.m[r][1] * pg[1] + w.m[r][2] * pg[2];
    }
    *dx = da[0] - (lc->mean.y - al.y) * da[2];
    *dy = da[1] + (lc->mean.x - al.x) * da[2];
    return (*dx * *dx + *dy * *dy > 1e-8) && isfinite(*dx) && isfinite(*dy);
}

/* 1 if some sighting of the frame other than `skip`, of lm's class, lies
 * within chi2 of the expectation e. */
static int sighting_near(const sighting_t *z, int ns, int skip, const landmark_t *lm, const lm_expect_t *e, double chi2)
{
    for (int k = 0; k < ns; ++k) {
        if (k != skip && z[k].signature == lm->signature && landmark_mahalanobis2(e, z[k]) < chi2) {
            return 1;
        }
    }
    return 0;
}

/* A certain miss from expectation e: in view, well placed, no sighting near. */
static int certain_miss(const fastslam_t *fs, const sighting_t *z, int ns, int skip, const landmark_t *lm,
                        const lm_expect_t *e)
{
    const slam_params_t *sp = &fs->cfg.slam;
    return landmark_should_be_seen(sp, e->zhat) && landmark_miss_is_certain(sp, e) && !landmark_hidden(fs->view, e) &&
           !sighting_near(z, ns, skip, lm, e, sp->new_landmark_chi2);
}

/* The particle's other landmarks of sighting z's class (in the query's
 * view, n_view) that the gate of revisit f (old landmark j, S + Hp D Hp^T)
 * holds: the pairings a lone sighting could make by chance. */
static uint32_t chance_pairings(const fastslam_t *fs, const fastslam_particle_t *p, sighting_t z, uint16_t j,
                                const revisit_fix_t *f, uint32_t n_view)
{
    const fastslam_scratch_t *sc = &fs->scratch;
    uint32_t n = 0U;
    for (uint32_t c = 0; c < n_view; ++c) {
        const landmark_t *lm = sc->view[c];
        if (sc->view_slot[c] == j || lm->signature != z.signature) {
            continue;
        }
        double nu[2];
        observe_innovation(z, observe_predict(p->pose, lm->mean), nu);
        const cov2_t *si = &f->s_inv;
        n += si->xx * nu[0] * nu[0] + 2.0 * si->xy * nu[0] * nu[1] + si->yy * nu[1] * nu[1] < fs->cfg.slam.gate_chi2;
    }
    return n;
}

/* Does the frame support closing sighting i on old landmark j (see
 * closure_misses_per_support)? Checked from the pose the closure would
 * give, with the particle's landmarks of the query (scratch view, n_view)
 * where the closure would move them. A landmark out of the query's reach
 * is neither support nor a miss. */
static int revisit_supported(const fastslam_t *fs, const fastslam_particle_t *p, const sighting_t *z, int ns, int i,
                             uint16_t j, uint32_t n_view)
{
    const fastslam_scratch_t *sc = &fs->scratch;
    const slam_params_t *sp = &fs->cfg.slam;
    revisit_fix_t f;
    if (!revisit_fix(fs, p, lm_tree_get(&fs->lm_pool, p->lm_root, j), z[i], &f)) {
        return 0;
    }
    const point2_t at_now = {p->pose.x, p->pose.y};
    /* where no other landmark of the class is in the widened gate, a
     * chance pairing is unlikely and a lone sighting is trusted as before */
    if (!((double)chance_pairings(fs, p, z[i], j, &f, n_view) >= fs->cfg.closure_chance_max)) {
        return 1;
    }
    const uint16_t own = (uint16_t)(1U << fs->cfg.robot_id);
    uint8_t supports[COSLAM_MAX_SIGHTINGS];
    memset(supports, 0, sizeof supports);
    uint32_t misses = 0U;
    for (uint32_t c = 0; c < n_view; ++c) {
        const landmark_t *lm = sc->view[c];
        if (sc->view_slot[c] == j || lm->src_mask != own) {
            continue;
        }
        landmark_t moved = *lm;
        double dx;
        double dy;
        if (revisit_move(lm, &f, at_now, &dx, &dy)) {
            moved.mean.x += dx;
            moved.mean.y += dy;
        }
        lm_expect_t eq;
        if (landmark_expect(&moved, sp, f.pose, 0, &eq) != COSLAM_OK) {
            continue;
        }
        /* support: an old landmark explains another sighting */
        if (unseen_for(fs, lm) > fs->cfg.closure_gap) {
            for (int k = 0; k < ns; ++k) {
                if (k != i && !supports[k] && z[k].signature == lm->signature &&
                    landmark_mahalanobis2(&eq, z[k]) < sp->gate_chi2) {
                    supports[k] = 1U;
                }
            }
        }
        /* a miss the closure makes (not one from the present pose) */
        if (lm->exist >= sp->exist_confirm && certain_miss(fs, z, ns, i, lm, &eq)) {
            lm_expect_t e0;
            if (landmark_expect(lm, sp, p->pose, 0, &e0) != COSLAM_OK || !certain_miss(fs, z, ns, i, lm, &e0)) {
                misses++;
            }
        }
    }
    uint32_t support = 0U;
    for (int k = 0; k < ns; ++k) {
        support += supports[k];
    }
    return support > 0U && !((double)misses > fs->cfg.closure_misses_per_support * (double)support);
}

/* Close the loop on old landmark j with sighting z (see above); returns the
 * sighting's log-likelihood under the drift, or new_landmark_log_lik if the
 * geometry failed (nothing changed then). */
static double close_revisit(fastslam_t *fs, fastslam_particle_t *p, uint16_t j, sighting_t z)
{
    const slam_params_t *sp = &fs->cfg.slam;
    revisit_fix_t f;
    if (!revisit_fix(fs, p, lm_tree_get(&fs->lm_pool, p->lm_root, j), z, &f)) {
        fs->ctr.numeric_faults++;
        return sp->new_landmark_log_lik;
    }
    const point2_t at_now = {p->pose.x, p->pose.y};
    p->pose = f.pose;
    fs->ctr.closures++;
    /* every own landmark by its anchor's share of the drift */
    const uint16_t own = (uint16_t)(1U << fs->cfg.robot_id);
    /* all of them in one walk of the tree (the scratch view is free after
     * the near list; a write copies a leaf, never frees the one read) */
    const landmark_t *const *all = fastslam_particle_landmarks(fs, (uint16_t)(p - fs->particles));
    for (uint16_t l = 0; l < p->n_lm; ++l) {
        const landmark_t *lc = all[l];
        if (lc->src_mask != own) {
            continue; /* a partner's errors, not this drift */
        }
        double dx;
        double dy;
        if (!revisit_move(lc, &f, at_now, &dx, &dy)) {
            continue;
        }
        landmark_t *lw = lm_tree_write(&fs->lm_pool, &p->lm_root, l);
        if (lw == 0) {
            fs->ctr.tree_capacity_drops++;
            continue;
        }
        lw->mean.x += dx;
        lw->mean.y += dy;
        lm_tree_changed(&fs->lm_pool, p->lm_root, l);
        fs->ctr.closure_moves++;
    }
    /* the pose marginal learns the drift */
    const landmark_t *o2 = lm_tree_get(&fs->lm_pool, p->lm_root, j);
    lm_expect_t e2;
    if (landmark_expect(o2, sp, p->pose, 0, &e2) == COSLAM_OK) {
        if (marginal_pose_observe(&p->pose_marg, p->pose, &f.a_old, f.at_old, e2.h_pose, sighting_noise(&e2, o2, sp)) !=
            COSLAM_OK) {
            fs->ctr.numeric_faults++;
        }
    }
    return f.ll;
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
    const uint32_t tree_drops = fs->ctr.tree_capacity_drops; /* any dropped write: COSLAM_E_CAPACITY */

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

    /* 3. revisits (Fast-SLAM 2.0, see "Revisits" above): closed first,
     *    then the proposal from the corrected pose with the other pairings */
    int32_t closure_j[COSLAM_MAX_SIGHTINGS];
    double closure_ll[COSLAM_MAX_SIGHTINGS];
    int32_t proposal_assign[COSLAM_MAX_SIGHTINGS];
    for (int i = 0; i < ns; ++i) {
        closure_j[i] = -1;
    }
    if (fs2 && fs->cfg.closure_drift_ratio > 0.0) {
        find_revisits(fs, p, z, ns, make_new, n_near_list, closure_j);
        /* support from the frame, checked before any closure moves the
         * particle (and while the query's view is the scratch) */
        const uint16_t every = fs->cfg.closure_unsupported_every;
        const int closes_anyway = every > 0U && k % every == (uint16_t)(every - 1U);
        for (int i = 0; i < ns && !closes_anyway; ++i) {
            if (closure_j[i] >= 0 && !revisit_supported(fs, p, z, ns, i, (uint16_t)closure_j[i], n_cand)) {
                closure_j[i] = -1; /* make_new[i] still set: a landmark is started */
                fs->ctr.closures_unsupported++;
            }
        }
    }
    for (int i = 0; i < ns; ++i) {
        proposal_assign[i] = sc->assign[i];
        if (closure_j[i] >= 0) {
            sc->assign[i] = closure_j[i];
            make_new[i] = 0;
            closure_ll[i] = close_revisit(fs, p, (uint16_t)closure_j[i], z[i]);
        }
    }

    /* 4. weights and landmark updates */
    marg_obs_t mobs[COSLAM_MAX_SIGHTINGS];
    int n_mobs = 0;
    if (fs2) {
        fs2_improve_and_sample(fs, p, z, ns, proposal_assign);
    }
    for (int i = 0; i < ns; ++i) {
        const int32_t j = sc->assign[i];
        if (j < 0) {
            p->log_w += sp->new_landmark_log_lik;
            continue;
        }
        if (closure_j[i] >= 0) {
            p->log_w += closure_ll[i]; /* the proposal left it out */
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
         * anchor; applied below, after the frame's other sightings (a
         * revisit's was applied when it closed) */
        if (closure_j[i] < 0) {
            marg_obs_t *mo = &mobs[n_mobs++];
            mo->n = sighting_noise(ep, lm, sp);
            mo->anchor = landmark_anchor(lm);
            mo->at = (point2_t){lm->anchor_xy[0], lm->anchor_xy[1]};
            memcpy(mo->hp, ep->h_pose, sizeof mo->hp);
            /* Fast-SLAM 2.0 moved the pose by the proposal's gain on this
             * sighting (its prior: the motion since the last sample, not
             * the drift since the anchor), and the marginal keeps the
             * drift that correction left; Fast-SLAM 1.0 keeps the Kalman
             * form (marginal.h) */
            mo->k = fs2 && proposal_assign[i] == j ? sc->gain[i] : 0;
            mo->key = mo->anchor.m[0][0] + mo->anchor.m[1][1];
        }
        if (closure_j[i] < 0 && exist_confirmed(lm->exist, lm->confirmed_once, sp) &&
            landmark_miss_would_count(sp, fs->view, &sc->expect[j])) {
            fs->ctr.view_pairs++; /* from the pose before the frame, as the misses below */
        }
        landmark_update(lm, sp, ep, z[i]);
        lm->last_seen = (uint16_t)fs->ctr.updates;
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
    const cov3_t marg_frame = p->pose_marg;
    for (int a = 0; a < n_mobs; ++a) {
        marg_obs_t *mo = &mobs[a];
        const coslam_status_t mst =
            mo->k != 0 ? marginal_pose_observe_gain(&p->pose_marg, p->pose, &mo->anchor, mo->at, mo->hp, mo->n, mo->k)
                       : marginal_pose_observe(&p->pose_marg, p->pose, &mo->anchor, mo->at, mo->hp, mo->n);
        if (mst != COSLAM_OK) {
            fs->ctr.numeric_faults++;
        }
    }
    /* the frame's sightings together never grow P (one may: a gain above
     * what its drift warrants); bounded once a frame, not per sighting,
     * which costs a covariance intersection each time (docs/consistency.md) */
    marginal_bound(&marg_frame, &p->pose_marg);

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
        if (landmark_hidden(fs->view, ep)) {
            fs->ctr.misses_hidden++; /* behind an obstacle the laser saw: not missed */
            continue;
        }
        /* on a copy: the shared landmark is written only if it changed */
        const landmark_t *lmc = lm_tree_get(&fs->lm_pool, p->lm_root, j);
        float exist = lmc->exist;
        uint8_t confirmed_once = lmc->confirmed_once;
        const int certain = landmark_miss_is_certain(sp, ep);
        if (certain && exist_confirmed(exist, confirmed_once, sp)) {
            fs->ctr.view_misses++;
        }
        if (exist_miss(&exist, &confirmed_once, certain, sp)) {
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

    /* 6. new landmarks from unmatched, unambiguous sightings */
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
        lm.last_seen = (uint16_t)fs->ctr.updates;
        if (fastslam_particle_add(fs, k, &lm) != COSLAM_OK) {
            result = COSLAM_E_CAPACITY;
        }
    }
    if (fs->ctr.tree_capacity_drops != tree_drops) {
        result = COSLAM_E_CAPACITY; /* e.g. a revisit closure could not move some landmark */
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
        if (fs->merge_due_n > 0U || fs->export_due) {
            /* a merge or an export in parts keeps its particles where they
             * are until it has reached every one (map_merge.h,
             * fastslam_export_begin): resampled later */
            fs->ctr.resamples_deferred++;
            return;
        }
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
    fs->view = 0; /* one frame's */
    fastslam_reweighted(fs);
    return result;
}

void fastslam_set_view(fastslam_t *fs, const view_profile_t *v)
{
    COSLAM_ASSERT(fs != 0);
    fs->view = v != 0 && v->valid ? v : 0;
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
            t->w2[h] = 0.0;
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

/* An export begins: the particles' weights, poses and pose marginals and
 * the pose estimate as they are now; the identity table emptied. */
static void export_start(fastslam_t *fs)
{
    fastslam_export_scratch_t *t = &fs->export_scratch;
    fastslam_weights(fs, t->job_w);
    fastslam_pose_estimate(fs, &t->job_est, &t->job_est_cov);
    for (uint16_t k = 0; k < fs->cfg.n_particles; ++k) {
        t->job_pose[k] = fs->particles[k].pose;
        t->job_marg[k] = fs->particles[k].pose_marg;
    }
    memset(t->id, 0, sizeof t->id);
    t->job_result = COSLAM_OK;
    t->job_next = 0U;
    t->job_pass = 1U;
}

/* One pass over particle k's confirmed landmarks, each at the pose, weight
 * and pose marginal the particle had when the export began.
 * Pass 1: total weight and weighted mean per identity.
 * Pass 2: covariance = within-particle covariance + spread of the means. */
static void export_particle(fastslam_t *fs, uint16_t k, int pass)
{
    const slam_params_t *sp = &fs->cfg.slam;
    fastslam_export_scratch_t *t = &fs->export_scratch;
    const fastslam_particle_t *p = &fs->particles[k];
    const double wk = t->job_w[k];
    const pose2_t pose = t->job_pose[k];
    const double c = cos(pose.theta);
    const double sn = sin(pose.theta);
    double rt[2][2] = {{c, sn}, {-sn, c}}; /* R^T: map -> this particle's body frame */
    const landmark_t *const *lms = fastslam_particle_landmarks(fs, k);
    for (uint16_t j = 0; j < p->n_lm; ++j) {
        const landmark_t *lm = lms[j];
        if (!landmark_is_confirmed(lm, sp)) {
            continue;
        }
        const point2_t rel = pose2_apply_inverse_cs(pose, c, sn, lm->mean);
        if (pass == 1) {
            const int s = export_slot(t, lm->id, 1);
            if (s < 0) {
                fs->ctr.export_capacity_drops++;
                t->job_result = COSLAM_E_CAPACITY;
                continue;
            }
            t->w[s] += wk;
            t->mx[s] += wk * lm->mean.x;
            t->my[s] += wk * lm->mean.y;
            t->rx[s] += wk * rel.x;
            t->ry[s] += wk * rel.y;
            t->nobs[s] += wk * (double)lm->n_obs;
            t->src_mask[s] |= lm->src_mask;
            t->signature[s] = lm->signature;
            continue;
        }
        const int s = export_slot(t, lm->id, 0);
        if (s < 0) {
            continue; /* counted in pass 1 (or confirmed since) */
        }
        const double dx = lm->mean.x - t->mx[s];
        const double dy = lm->mean.y - t->my[s];
        const cov2_t g = landmark_marginal(lm);
        t->w2[s] += wk;
        t->cxx[s] += wk * (g.xx + dx * dx);
        t->cxy[s] += wk * (g.xy + dx * dy);
        t->cyy[s] += wk * (g.yy + dy * dy);
        /* relative to this particle's pose, in its body frame: sensor
         * noise plus the pose drift since the landmark's anchor
         * (marginal_relative_drift) */
        const cov3_t anchor = landmark_anchor(lm);
        const cov2_t cr = cov2_add(cov2_congruence(rt, lm->cov),
                                   marginal_relative_drift_cs(&t->job_marg[k], pose, c, sn, &anchor,
                                                              (point2_t){lm->anchor_xy[0], lm->anchor_xy[1]}, rel));
        const double ex = rel.x - t->rx[s];
        const double ey = rel.y - t->ry[s];
        t->rxx[s] += wk * (cr.xx + ex * ex);
        t->rxy[s] += wk * (cr.xy + ex * ey);
        t->ryy[s] += wk * (cr.yy + ey * ey);
    }
}

/* Between the passes: the sums of pass 1 into means. */
static void export_means(fastslam_export_scratch_t *t)
{
    for (int s = 0; s < COSLAM_MAX_EXPORT_IDS; ++s) {
        if (t->id[s] != 0U && t->w[s] > 0.0) {
            t->mx[s] /= t->w[s];
            t->my[s] /= t->w[s];
            t->rx[s] /= t->w[s];
            t->ry[s] /= t->w[s];
        }
    }
}

/* Both passes from where the export is, particle by particle, until
 * `budget` units are spent (0: no budget; at least one particle); 1 when
 * both are done. */
static int export_advance(fastslam_t *fs, uint32_t budget, uint32_t *spent_out)
{
    fastslam_export_scratch_t *t = &fs->export_scratch;
    const uint16_t n = fs->cfg.n_particles;
    uint32_t spent = 0U;
    while (t->job_pass == 1U || t->job_pass == 2U) {
        if (budget > 0U && spent >= budget) {
            *spent_out = spent;
            return 0;
        }
        const uint16_t k = t->job_next;
        const uint32_t n_lm = fs->particles[k].n_lm;
        export_particle(fs, k, t->job_pass);
        spent += FASTSLAM_EXPORT_UNITS_PARTICLE +
                 n_lm * (t->job_pass == 1U ? FASTSLAM_EXPORT_UNITS_PASS1 : FASTSLAM_EXPORT_UNITS_PASS2);
        if (++t->job_next == n) {
            t->job_next = 0U;
            if (t->job_pass == 1U) {
                export_means(t);
                t->job_pass = 2U;
            } else {
                t->job_pass = 3U; /* both done: select and fill */
            }
        }
    }
    *spent_out = spent;
    return 1;
}

/* Identities exported: weight >= export_min_weight, into t->sel; their count. */
static int export_select(fastslam_t *fs)
{
    const fastslam_export_scratch_t *t = &fs->export_scratch;
    uint32_t *sel = fs->export_scratch.sel;
    int n_sel = 0;
    for (int s = 0; s < COSLAM_MAX_EXPORT_IDS; ++s) {
        if (t->id[s] != 0U && t->w[s] >= fs->cfg.export_min_weight - 1e-12 && t->w2[s] > 0.0) {
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
        const double inv_w2 = 1.0 / t->w2[s]; /* inv_w unless the filter ran between the passes */
        o->mean.x = t->mx[s];
        o->mean.y = t->my[s];
        o->cov = cov2_make(t->cxx[s] * inv_w2, t->cxy[s] * inv_w2, t->cyy[s] * inv_w2);
        o->cov_rel = cov2_make(t->rxx[s] * inv_w2, t->rxy[s] * inv_w2, t->ryy[s] * inv_w2);
        o->id = t->id[s];
        const double nobs = t->nobs[s] * inv_w + 0.5;
        o->n_obs = nobs >= 65535.0 ? (uint16_t)65535U : (uint16_t)nobs;
        o->src_mask = t->src_mask[s];
        o->signature = t->signature[s];
    }
}

/* The passes done: select, keep the heaviest `cap` (the rest counted), fill
 * lm by identity; the pose estimate into pose and cov. Ends the export. */
static coslam_status_t export_finish(fastslam_t *fs, pose2_t *pose, cov3_t *cov, map_landmark_t *lm, int cap,
                                     uint16_t *n_out)
{
    fastslam_export_scratch_t *t = &fs->export_scratch;
    coslam_status_t result = t->job_result;
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
    *pose = t->job_est;
    *cov = t->job_est_cov;
    t->job_pass = 0U;
    fs->export_due = 0U;
    return result;
}

/* The whole export in one call. */
static coslam_status_t export_capped(fastslam_t *fs, pose2_t *pose, cov3_t *cov, map_landmark_t *lm, int cap,
                                     uint16_t *n_out)
{
    if (fs->export_due) {
        return COSLAM_E_MERGE_BUSY; /* its table would be lost */
    }
    export_start(fs);
    uint32_t spent = 0U;
    (void)export_advance(fs, 0U, &spent);
    return export_finish(fs, pose, cov, lm, cap, n_out);
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

coslam_status_t fastslam_export_begin(fastslam_t *fs)
{
    if (fs == NULL) {
        return COSLAM_E_ARG;
    }
    if (fs->export_due) {
        return COSLAM_E_MERGE_BUSY;
    }
    export_start(fs);
    fs->export_due = 1U;
    return COSLAM_OK;
}

/* The next part of the export under way; ends it into (pose, cov, lm,
 * cap, n_out) once both passes are done. */
static coslam_status_t export_run(fastslam_t *fs, uint32_t budget, int *done, uint32_t *spent, pose2_t *pose,
                                  cov3_t *cov, map_landmark_t *lm, int cap, uint16_t *n_out)
{
    if (done == NULL || spent == NULL || !fs->export_due) {
        return COSLAM_E_ARG;
    }
    *done = export_advance(fs, budget, spent);
    return *done ? export_finish(fs, pose, cov, lm, cap, n_out) : COSLAM_OK;
}

coslam_status_t fastslam_export_run(fastslam_t *fs, map_whole_t *out, uint32_t budget, int *done, uint32_t *spent)
{
    if (fs == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    return export_run(fs, budget, done, spent, &out->pose, &out->pose_cov, out->lm, COSLAM_MAX_LANDMARKS,
                      &out->n_landmarks);
}

coslam_status_t fastslam_export_run_msg(fastslam_t *fs, map_estimate_t *out, uint32_t budget, int *done,
                                        uint32_t *spent)
{
    if (fs == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    return export_run(fs, budget, done, spent, &out->pose, &out->pose_cov, out->lm, COSLAM_MAX_MSG_LANDMARKS,
                      &out->n_landmarks);
}

void fastslam_export_abort(fastslam_t *fs)
{
    if (fs != NULL) {
        fs->export_scratch.job_pass = 0U;
        fs->export_due = 0U;
    }
}
