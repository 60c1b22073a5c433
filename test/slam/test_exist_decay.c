/* Decay of confirmed landmarks (slam_params_t.exist_miss_confirmed) in
 * both filters, in a small synthetic world: a robot shuttles back and forth
 * in front of three real markers with noisy odometry and sightings.
 *  - a wrong confirmed landmark (a "ghost", injected as a failed loop
 *    closure or a map merge would leave it) in plain view stops being
 *    exported and is removed after exactly the number of frames the rule
 *    predicts, while the real landmarks stay exported;
 *  - a real landmark occluded for K frames stays exported; one frame more
 *    only pauses its export; missed detections never matter;
 *  - an uncertain prediction (landmark or, in EKF-SLAM, pose after a blind
 *    turn) costs no evidence;
 *  - exist_miss_confirmed = 0 keeps the old rule (never removed). */
#include "test_util.h"

#include <string.h>

#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"
#include "coslam/motion.h"
#include "coslam/observe.h"
#include "coslam/rng.h"

enum { N_REAL = 3, N_PARTICLES = 20, WARM_UP = 30 };

static const point2_t k_real[N_REAL] = {{3.0, 0.9}, {3.5, 0.5}, {4.0, 0.1}};
/* an empty spot in plain view (bearing about -0.24 rad, range 2.5 m), more
 * than 1.4 m from every real marker */
static const point2_t k_ghost = {2.5, -0.6};

typedef struct {
    int ekf;          /* 1: EKF-SLAM (JCBB), 0: Fast-SLAM 1.0 */
    slam_params_t sp;
    rng_t rng;
    pose2_t truth;
    int frame;
    double p_detect;
    int occluded;     /* real marker hidden this frame, -1 for none */
    double turn_rad;  /* rotation per frame instead of the shuttle, if not 0 */
} world_t;

static fastslam_t g_fs;
static ekfslam_t g_ekf;
static map_estimate_t g_est;

static slam_params_t params(void)
{
    return slam_params_default();
}

static void world_init(world_t *w, int ekf, slam_params_t sp)
{
    memset(w, 0, sizeof *w);
    w->ekf = ekf;
    w->sp = sp;
    rng_seed(&w->rng, 42U);
    w->p_detect = 1.0;
    w->occluded = -1;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    w->truth = p0;
    if (ekf) {
        ekfslam_config_t c = ekfslam_config_default();
        c.slam = sp;
        assert_int_equal(ekfslam_init(&g_ekf, &c, p0), COSLAM_OK);
    } else {
        fastslam_config_t c = fastslam_config_default();
        c.slam = sp;
        c.n_particles = N_PARTICLES;
        assert_int_equal(fastslam_init(&g_fs, &c, p0, 7U), COSLAM_OK);
    }
}

/* One camera frame: move (8 frames forward by 5 cm, 8 back), odometry with
 * the model's noise, sightings of the visible real markers. */
static void step(world_t *w)
{
    odo_increment_t u = {(w->frame % 16) < 8 ? 0.05 : -0.05, 0.0, 0.0};
    if (w->turn_rad != 0.0) {
        u.dx = 0.0;
        u.dtheta = w->turn_rad;
    }
    ++w->frame;
    w->truth = motion_apply(w->truth, u);
    const odo_increment_t meas = motion_sample(&w->sp, u, &w->rng);
    sighting_t z[N_REAL];
    int n = 0;
    for (int i = 0; i < N_REAL; ++i) {
        const sighting_t zt = observe_predict(w->truth, k_real[i]);
        const int in_view = zt.range_m >= w->sp.sensor_min_range_m && zt.range_m <= w->sp.sensor_max_range_m &&
                            fabs(zt.bearing_rad) <= 0.5 * w->sp.sensor_fov_rad;
        /* draw every frame, so that occlusion does not shift the noise */
        const double u01 = rng_uniform(&w->rng);
        const cov2_t q = observe_noise(&w->sp, zt.range_m);
        const double er = rng_normal(&w->rng, 0.0, sqrt(q.xx));
        const double eb = rng_normal(&w->rng, 0.0, sqrt(q.yy));
        if (!in_view || i == w->occluded || u01 >= w->p_detect) {
            continue;
        }
        z[n].range_m = zt.range_m + er;
        z[n].bearing_rad = zt.bearing_rad + eb;
        z[n].signature = 0;
        ++n;
    }
    if (w->ekf) {
        assert_int_equal(ekfslam_predict(&g_ekf, meas), COSLAM_OK);
        assert_int_equal(ekfslam_update(&g_ekf, z, n), COSLAM_OK);
    } else {
        assert_int_equal(fastslam_predict(&g_fs, meas), COSLAM_OK);
        assert_int_equal(fastslam_update(&g_fs, z, n), COSLAM_OK);
    }
}

static void do_export(const world_t *w)
{
    if (w->ekf) {
        assert_int_equal(ekfslam_export(&g_ekf, &g_est), COSLAM_OK);
    } else {
        assert_int_equal(fastslam_export(&g_fs, &g_est), COSLAM_OK);
    }
}

static int exported(const world_t *w, uint32_t id)
{
    do_export(w);
    for (int i = 0; i < g_est.n_landmarks; ++i) {
        if (g_est.lm[i].id == id) {
            return 1;
        }
    }
    return 0;
}

/* in the map at all (Fast-SLAM: in some particle) */
static int present(const world_t *w, uint32_t id)
{
    if (w->ekf) {
        for (uint16_t j = 0; j < g_ekf.n_lm; ++j) {
            if (g_ekf.meta[j].id == id) {
                return 1;
            }
        }
        return 0;
    }
    for (uint16_t k = 0; k < g_fs.cfg.n_particles; ++k) {
        const fastslam_particle_t *p = &g_fs.particles[k];
        for (uint16_t j = 0; j < p->n_lm; ++j) {
            if (fastslam_particle_lm(&g_fs, k, j)->id == id) {
                return 1;
            }
        }
    }
    return 0;
}

static uint32_t removed(const world_t *w)
{
    return w->ekf ? g_ekf.ctr.landmarks_removed : g_fs.ctr.landmarks_removed;
}

/* identity of the exported landmark within 0.3 m of real marker i (0 if none) */
static uint32_t id_of_real(const world_t *w, int i)
{
    do_export(w);
    for (int k = 0; k < g_est.n_landmarks; ++k) {
        const double dx = g_est.lm[k].mean.x - k_real[i].x;
        const double dy = g_est.lm[k].mean.y - k_real[i].y;
        if (dx * dx + dy * dy < 0.09) {
            return g_est.lm[k].id;
        }
    }
    return 0U;
}

/* every real marker exported, nothing else but `extra` (0: nothing) */
static void assert_real_exported(const world_t *w, uint32_t extra)
{
    for (int i = 0; i < N_REAL; ++i) {
        ASSERT_TRUE_MSG(id_of_real(w, i) != 0U, "frame %d: real marker %d not exported\n", w->frame, i);
    }
    const int n_extra = extra != 0U && exported(w, extra);
    do_export(w);
    ASSERT_TRUE_MSG(g_est.n_landmarks == N_REAL + n_extra, "frame %d: %d landmarks exported\n", w->frame,
                    (int)g_est.n_landmarks);
}

static void warm_up(world_t *w)
{
    for (int f = 0; f < WARM_UP; ++f) {
        step(w);
    }
    /* every real marker sighted in every frame: at exist_max */
    assert_real_exported(w, 0U);
}

/* A wrong landmark at the ghost spot, confirmed at `exist`, with `var_m2`
 * position variance per axis, as a merge or a failed loop closure leaves it:
 * the same identity in every particle. Returns its identity. */
static uint32_t inject_ghost(const world_t *w, float exist, double var_m2)
{
    const cov2_t cov = cov2_make(var_m2, 0.0, var_m2);
    if (w->ekf) {
        pose2_t pose;
        cov3_t pc;
        ekfslam_pose(&g_ekf, &pose, &pc);
        ekfslam_meta_t meta;
        memset(&meta, 0, sizeof meta);
        meta.id = ekfslam_new_id(&g_ekf);
        meta.exist = exist;
        meta.n_obs = 10;
        meta.src_mask = 2U; /* received from robot 1 */
        meta.signature = 0;
        assert_int_equal(ekfslam_add_landmark_body(&g_ekf, pose2_apply_inverse(pose, k_ghost), cov, &meta), COSLAM_OK);
        return meta.id;
    }
    landmark_t lm;
    memset(&lm, 0, sizeof lm);
    lm.mean = k_ghost;
    lm.cov = cov;
    lm.id = fastslam_new_id(&g_fs);
    lm.exist = exist;
    lm.n_obs = 10;
    lm.src_mask = 2U;
    for (uint16_t k = 0; k < g_fs.cfg.n_particles; ++k) {
        assert_int_equal(fastslam_particle_add(&g_fs, k, &lm), COSLAM_OK);
    }
    return lm.id;
}

/* (a) a ghost at exist_max in plain view: exported while at least
 * exist_confirm, i.e. through K = (max - confirm) / r frames, removed when
 * below zero, at frame max / r + 1 (0.125 is exact: no rounding). */
static void ghost_dies(int ekf)
{
    world_t w;
    const slam_params_t sp = params();
    world_init(&w, ekf, sp);
    warm_up(&w);
    const uint32_t r0 = removed(&w);
    const uint32_t id = inject_ghost(&w, sp.exist_max, 0.01);
    assert_true(exported(&w, id));
    const int k_export = (int)((sp.exist_max - sp.exist_confirm) / sp.exist_miss_confirmed);
    const int k_remove = (int)(sp.exist_max / sp.exist_miss_confirmed) + 1;
    assert_int_equal(k_export, 40);
    assert_int_equal(k_remove, 81);
    for (int f = 1; f <= k_remove + 10; ++f) {
        step(&w);
        ASSERT_TRUE_MSG(exported(&w, id) == (f <= k_export), "frame %d after the ghost: exported %d\n", f,
                        exported(&w, id));
        ASSERT_TRUE_MSG(present(&w, id) == (f < k_remove), "frame %d after the ghost: present %d\n", f,
                        present(&w, id));
        assert_real_exported(&w, id);
    }
    /* Fast-SLAM counts one removal per particle */
    assert_int_equal(removed(&w) - r0, ekf ? 1U : (uint32_t)N_PARTICLES);
}

static void test_fastslam_ghost_dies(void **state)
{
    (void)state;
    ghost_dies(0);
}

static void test_ekfslam_ghost_dies(void **state)
{
    (void)state;
    ghost_dies(1);
}

/* (a') a ghost received in a merge sits at exist_confirm: the first certain
 * miss ends its export, it is removed after confirm / r + 1 = 41 frames */
static void ghost_from_merge_dies(int ekf)
{
    world_t w;
    const slam_params_t sp = params();
    world_init(&w, ekf, sp);
    warm_up(&w);
    const uint32_t id = inject_ghost(&w, sp.exist_confirm, 0.01);
    const int k_remove = (int)(sp.exist_confirm / sp.exist_miss_confirmed) + 1;
    for (int f = 1; f <= k_remove + 5; ++f) {
        step(&w);
        assert_false(exported(&w, id));
        ASSERT_TRUE_MSG(present(&w, id) == (f < k_remove), "frame %d: present %d\n", f, present(&w, id));
        assert_real_exported(&w, id);
    }
}

static void test_ghost_from_merge_dies(void **state)
{
    (void)state;
    ghost_from_merge_dies(0);
    ghost_from_merge_dies(1);
}

/* (b) a real marker hidden for K frames (a robot passing in front) stays
 * exported; hidden for K + 1 it drops out of the export but stays in the
 * map and is exported again at its next sighting; missed detections at
 * p_detect 0.6 never end an export. */
static void occlusion_survives(int ekf)
{
    world_t w;
    const slam_params_t sp = params();
    world_init(&w, ekf, sp);
    warm_up(&w);
    const int k_export = (int)((sp.exist_max - sp.exist_confirm) / sp.exist_miss_confirmed);
    uint32_t ids[N_REAL];
    for (int i = 0; i < N_REAL; ++i) {
        ids[i] = id_of_real(&w, i);
    }
    const uint32_t id0 = ids[0];
    w.occluded = 0;
    for (int f = 1; f <= k_export; ++f) {
        step(&w);
        assert_real_exported(&w, 0U);
    }
    assert_int_equal(id_of_real(&w, 0), id0);
    w.occluded = -1;
    for (int f = 0; f < 10; ++f) { /* back to exist_max */
        step(&w);
        assert_real_exported(&w, 0U);
    }
    w.occluded = 0;
    for (int f = 1; f <= k_export + 1; ++f) {
        step(&w);
        assert_true(exported(&w, id0) == (f <= k_export));
    }
    assert_true(present(&w, id0));
    w.occluded = -1;
    step(&w);
    assert_true(exported(&w, id0));
    assert_real_exported(&w, 0U);
    /* unreliable detection */
    w.p_detect = 0.6;
    for (int f = 0; f < 300; ++f) {
        step(&w);
        assert_real_exported(&w, 0U);
    }
    /* the same identities: never removed and restarted */
    for (int i = 0; i < N_REAL; ++i) {
        assert_int_equal(id_of_real(&w, i), ids[i]);
    }
}

static void test_fastslam_occlusion_survives(void **state)
{
    (void)state;
    occlusion_survives(0);
}

static void test_ekfslam_occlusion_survives(void **state)
{
    (void)state;
    occlusion_survives(1);
}

/* (c) exist_miss_confirmed = 0: the old rule, a confirmed ghost is exported
 * for ever (weakened to exist_confirm at exist_miss), never removed */
static void old_rule(int ekf)
{
    world_t w;
    slam_params_t sp = params();
    sp.exist_miss_confirmed = 0.0f;
    world_init(&w, ekf, sp);
    warm_up(&w);
    const uint32_t r0 = removed(&w);
    const uint32_t id = inject_ghost(&w, sp.exist_max, 0.01);
    for (int f = 0; f < 200; ++f) {
        step(&w);
        assert_true(exported(&w, id));
        assert_real_exported(&w, id);
    }
    assert_int_equal(removed(&w), r0);
    if (ekf) {
        ASSERT_NEAR(g_ekf.meta[g_ekf.n_lm - 1].exist, sp.exist_confirm, 0.0);
    } else {
        ASSERT_NEAR(fastslam_particle_lm(&g_fs, 0, (uint16_t)(g_fs.particles[0].n_lm - 1))->exist, sp.exist_confirm,
                    0.0);
    }
}

static void test_old_rule(void **state)
{
    (void)state;
    old_rule(0);
    old_rule(1);
}

/* (d) an uncertain prediction is no evidence: a ghost whose position is
 * known to 0.4 m only (bearing sd about 0.16 rad at 2.5 m, above
 * 0.25 * 25 deg = 0.11 rad) keeps its evidence */
static void uncertain_ghost_kept(int ekf)
{
    world_t w;
    const slam_params_t sp = params();
    world_init(&w, ekf, sp);
    warm_up(&w);
    const uint32_t id = inject_ghost(&w, sp.exist_max, 0.16);
    for (int f = 0; f < 100; ++f) {
        step(&w);
        assert_true(exported(&w, id));
        assert_real_exported(&w, id);
    }
}

static void test_uncertain_ghost_kept(void **state)
{
    (void)state;
    uncertain_ghost_kept(0);
    uncertain_ghost_kept(1);
}

/* (d') EKF-SLAM after a blind turn with a poor gyro: the heading is known to
 * about 0.3 rad, so no landmark can be predicted well enough for a miss to
 * count; a camera that then sees nothing for 100 frames does not erase the
 * map (with a certain pose the markers would be gone after 81 frames). */
static void test_ekfslam_drift_no_decay(void **state)
{
    (void)state;
    world_t w;
    const slam_params_t sp = params();
    world_init(&w, 1, sp);
    warm_up(&w);
    /* turn once around with nothing detected, heading noise 0.3 rad */
    const int n_turn = 40;
    const double dtheta = COSLAM_TWO_PI / n_turn;
    const double travel = sp.base_radius_m * dtheta * n_turn;
    g_ekf.cfg.slam.noise.odo_theta_var_rad2_per_m = 0.09 / travel;
    w.sp.noise.odo_theta_var_rad2_per_m = g_ekf.cfg.slam.noise.odo_theta_var_rad2_per_m;
    w.p_detect = 0.0;
    w.turn_rad = dtheta;
    for (int f = 0; f < n_turn; ++f) {
        step(&w);
    }
    w.turn_rad = 0.0;
    g_ekf.cfg.slam.noise.odo_theta_var_rad2_per_m = sp.noise.odo_theta_var_rad2_per_m;
    w.sp.noise.odo_theta_var_rad2_per_m = sp.noise.odo_theta_var_rad2_per_m;
    pose2_t pose;
    cov3_t pc;
    ekfslam_pose(&g_ekf, &pose, &pc);
    assert_true(pc.m[2][2] > 0.05);
    const uint32_t r0 = removed(&w);
    for (int f = 0; f < 100; ++f) {
        step(&w);
    }
    assert_int_equal(removed(&w), r0);
    assert_int_equal(g_ekf.n_lm, N_REAL);
    for (uint16_t j = 0; j < g_ekf.n_lm; ++j) {
        assert_true(g_ekf.meta[j].exist >= sp.exist_confirm);
    }
}

/* the new parameters' domains: exist_miss_confirmed finite and >= 0,
 * exist_miss_bearing_sd_frac finite and > 0 */
static void test_params_validate(void **state)
{
    (void)state;
    slam_params_t p = slam_params_default();
    assert_int_equal(slam_params_validate(&p), COSLAM_OK);
    p.exist_miss_confirmed = 0.0f;
    assert_int_equal(slam_params_validate(&p), COSLAM_OK);
    p.exist_miss_confirmed = -0.125f;
    assert_int_equal(slam_params_validate(&p), COSLAM_E_ARG);
    p.exist_miss_confirmed = NAN;
    assert_int_equal(slam_params_validate(&p), COSLAM_E_ARG);
    p = slam_params_default();
    p.exist_miss_bearing_sd_frac = 0.0;
    assert_int_equal(slam_params_validate(&p), COSLAM_E_ARG);
    p.exist_miss_bearing_sd_frac = INFINITY;
    assert_int_equal(slam_params_validate(&p), COSLAM_E_ARG);
    p.exist_miss_bearing_sd_frac = 4.0; /* larger than the view: no gate */
    assert_int_equal(slam_params_validate(&p), COSLAM_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_params_validate),
        cmocka_unit_test(test_fastslam_ghost_dies),
        cmocka_unit_test(test_ekfslam_ghost_dies),
        cmocka_unit_test(test_ghost_from_merge_dies),
        cmocka_unit_test(test_fastslam_occlusion_survives),
        cmocka_unit_test(test_ekfslam_occlusion_survives),
        cmocka_unit_test(test_old_rule),
        cmocka_unit_test(test_uncertain_ghost_kept),
        cmocka_unit_test(test_ekfslam_drift_no_decay),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
