#include "app/slam_filter.h"

#include <stddef.h>

slam_filter_config_t slam_filter_config_default(void)
{
    slam_filter_config_t c;
    c.kind = SLAM_FILTER_FASTSLAM2;
    c.slam = slam_params_default();
    c.n_particles = (uint16_t)(COSLAM_MAX_PARTICLES < 100 ? COSLAM_MAX_PARTICLES : 100);
    c.seed = 1U;
    c.robot_id = 0U;
    const fastslam_config_t fc = fastslam_config_default();
    const ekfslam_config_t ec = ekfslam_config_default();
    c.resample_ess_fraction = fc.resample_ess_fraction;
    c.export_min_weight = fc.export_min_weight;
    c.assoc = ec.assoc;
    c.jcbb_max_nodes = ec.jcbb_max_nodes;
    c.fej = ec.fej;
    return c;
}

coslam_status_t slam_filter_init(slam_filter_t *f, const slam_filter_config_t *cfg, pose2_t pose0)
{
    if (f == NULL || cfg == NULL) {
        return COSLAM_E_ARG;
    }
    f->kind = cfg->kind;
    f->robot_id = cfg->robot_id;
    merge_coverage_init(&f->coverage);
    switch (cfg->kind) {
    case SLAM_FILTER_FASTSLAM1:
    case SLAM_FILTER_FASTSLAM2: {
        fastslam_config_t c = fastslam_config_default();
        c.slam = cfg->slam;
        c.n_particles = cfg->n_particles;
        c.proposal = cfg->kind == SLAM_FILTER_FASTSLAM2 ? FASTSLAM_PROPOSAL_OPTIMAL : FASTSLAM_PROPOSAL_MOTION;
        c.robot_id = cfg->robot_id;
        c.resample_ess_fraction = cfg->resample_ess_fraction;
        c.export_min_weight = cfg->export_min_weight;
        return fastslam_init(&f->u.fs, &c, pose0, cfg->seed);
    }
    case SLAM_FILTER_EKF: {
        ekfslam_config_t c = ekfslam_config_default();
        c.slam = cfg->slam;
        c.robot_id = cfg->robot_id;
        c.assoc = cfg->assoc;
        c.jcbb_max_nodes = cfg->jcbb_max_nodes;
        c.fej = cfg->fej;
        return ekfslam_init(&f->u.ekf, &c, pose0);
    }
    }
    return COSLAM_E_ARG;
}

coslam_status_t slam_filter_predict(slam_filter_t *f, odo_increment_t u)
{
    return f->kind == SLAM_FILTER_EKF ? ekfslam_predict(&f->u.ekf, u) : fastslam_predict(&f->u.fs, u);
}

coslam_status_t slam_filter_update(slam_filter_t *f, const sighting_t *z, int n)
{
    const coslam_status_t st =
        f->kind == SLAM_FILTER_EKF ? ekfslam_update(&f->u.ekf, z, n) : fastslam_update(&f->u.fs, z, n);
    pose2_t pose;
    cov3_t cov;
    slam_filter_pose(f, &pose, &cov);
    merge_coverage_note(&f->coverage, pose);
    return st;
}

void slam_filter_pose(const slam_filter_t *f, pose2_t *pose, cov3_t *cov)
{
    if (f->kind == SLAM_FILTER_EKF) {
        ekfslam_pose(&f->u.ekf, pose, cov);
    } else {
        fastslam_pose_estimate(&f->u.fs, pose, cov);
    }
}

coslam_status_t slam_filter_export(slam_filter_t *f, map_estimate_t *out)
{
    return f->kind == SLAM_FILTER_EKF ? ekfslam_export(&f->u.ekf, out) : fastslam_export(&f->u.fs, out);
}

coslam_status_t slam_filter_merge(slam_filter_t *f, const merge_body_map_t *bm, const merge_config_t *cfg,
                                  merge_scratch_t *scratch, merge_stats_t *stats)
{
    return f->kind == SLAM_FILTER_EKF ? merge_into_ekfslam(&f->u.ekf, bm, cfg, scratch, stats)
                                      : merge_into_fastslam(&f->u.fs, bm, cfg, scratch, stats);
}

const char *slam_filter_kind_name(slam_filter_kind_t kind)
{
    switch (kind) {
    case SLAM_FILTER_FASTSLAM1: return "fastslam1";
    case SLAM_FILTER_FASTSLAM2: return "fastslam2";
    case SLAM_FILTER_EKF: return "ekf";
    }
    return "?";
}

const slam_params_t *slam_filter_params(const slam_filter_t *f)
{
    return f->kind == SLAM_FILTER_EKF ? &f->u.ekf.cfg.slam : &f->u.fs.cfg.slam;
}

coslam_status_t slam_filter_merge_map(slam_filter_t *f, const map_estimate_t *in, const merge_geometry_t *g,
                                      const merge_config_t *cfg, const occ_grid_t *grid, slam_merge_work_t *w,
                                      merge_stats_t *stats, pose2_t *t_out, cov3_t *t_cov_out)
{
    if (f == NULL || in == NULL || g == NULL || cfg == NULL || w == NULL || stats == NULL) {
        return COSLAM_E_ARG;
    }
    const slam_params_t *sp = slam_filter_params(f);
    coslam_status_t st = merge_prepare(in, g, sp, cfg, &w->body, stats);
    if (st != COSLAM_OK) {
        return st;
    }
    if (t_out != NULL) {
        *t_out = w->body.t;
    }
    if (t_cov_out != NULL) {
        *t_cov_out = w->body.t_cov;
    }
    if (cfg->check) {
        st = slam_filter_export(f, &w->own);
        if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
            return st;
        }
        st = merge_check(&w->own, &f->coverage, grid, sp, f->robot_id, cfg, &w->body, &w->scratch, stats);
        if (st != COSLAM_OK) {
            return st;
        }
        if (t_out != NULL) {
            *t_out = w->body.t; /* refined by the shared landmarks */
        }

    }
    return slam_filter_merge(f, &w->body, cfg, &w->scratch, stats);
}
