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
 *  - exist_miss_confirmed = 0 keeps the old rule (never removed);
 *  - a ghost the view profile (view.h) puts behind an obstacle is hidden,
 *    not missed, in the frame the profile is given for only; an obstacle
 *    behind it hides nothing;
 *  - the default miss weight is the detection formula's at p_detect 0.9.
 * The rule's arithmetic is checked at 0.125 (exact in binary, so the frame
 * counts are exact), the value for MRCLAM's camera. */
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
    double wall_m;    /* > 0: a view profile with a wall this far in the ghost's bearing, every frame */
    int view_once;    /* 1: that profile for the next frame only */
    double near_ghost_m; /* > 0: a sighting this far beside the ghost every frame */
} world_t;

static fastslam_t g_fs;
static ekfslam_t g_ekf;
static view_profile_t g_view; /* the filters keep a pointer to it until the update */
static map_estimate_t g_est;

static slam_params_t params(void)
{
    slam_params_t p = slam_params_default();
    p.exist_miss_confirmed = 0.125f;
    return p;
}

/* A wall of obstacle points wall_m from the robot's estimated pose, across
 * the ghost's bearing (+-0.1 rad: no real marker is within 0.35 rad of it
 * from the shuttle), as the laser would see it. */
static void set_wall_view(const world_t *w)
{
    pose2_t pose;
    cov3_t pc;
    if (w->ekf) {
        ekfslam_pose(&g_ekf, &pose, &pc);
    } else {
        fastslam_pose_estimate(&g_fs, &pose, &pc);
    }
    const double b0 = observe_predict(pose, k_ghost).bearing_rad;
    point2_t pts[21];
    for (int i = 0; i < 21; ++i) {
        const double b = b0 - 0.1 + 0.01 * i;
        pts[i].x = w->wall_m * cos(b);
        pts[i].y = w->wall_m * sin(b);
    }
    assert_int_equal(view_profile_build(&g_view, pts, 21, (pose2_t){0.0, 0.0, 0.0}), COSLAM_OK);
    if (w->ekf) {
        ekfslam_set_view(&g_ekf, &g_view);
    } else {
        fastslam_set_view(&g_fs, &g_view);
    }
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
    sighting_t z[N_REAL + 1];
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
    if (w->near_ghost_m > 0.0) {
        z[n] = observe_predict(w->truth, (point2_t){k_ghost.x, k_ghost.y + w->near_ghost_m});
        z[n].signature = 0;
        ++n;
    }
    if (w->ekf) {
        assert_int_equal(ekfslam_predict(&g_ekf, meas), COSLAM_OK);
    } else {
        assert_int_equal(fastslam_predict(&g_fs, meas), COSLAM_OK);
    }
    if (w->wall_m > 0.0) {
        set_wall_view(w);
        if (w->view_once) {
            w->wall_m = 0.0;
        }
    }
    if (w->ekf) {
        assert_int_equal(ekfslam_update(&g_ekf, z, n), COSLAM_OK);
    } else {
        assert_int_equal(fastslam_update(&g_fs, z, n), COSLAM_OK);
    }
}

static uint32_t hidden(const world_t *w)
{
    return w->ekf ? g_ekf.ctr.misses_hidden : g_fs.ctr.misses_hidden;
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

/* (e) a ghost behind a wall the laser sees (1.2 m, the ghost at about 2.5
 * m) is hidden, not missed: exported for 200 frames, one hidden miss per
 * frame (per particle in Fast-SLAM). A wall behind it (4 m) hides nothing:
 * it dies as in (a). A profile given once hides one frame only: removal
 * one frame later than in (a). */
static void hidden_by_view(int ekf)
{
    const int per = ekf ? 1 : N_PARTICLES;
    world_t w;
    const slam_params_t sp = params();
    const int k_remove = (int)(sp.exist_max / sp.exist_miss_confirmed) + 1;
    world_init(&w, ekf, sp);
    warm_up(&w);
    assert_int_equal(hidden(&w), 0U); /* no profile given: nothing hidden */
    uint32_t id = inject_ghost(&w, sp.exist_max, 0.01);
    w.wall_m = 1.2;
    for (int f = 1; f <= 200; ++f) {
        step(&w);
        ASSERT_TRUE_MSG(exported(&w, id), "frame %d behind the wall: not exported\n", f);
        assert_real_exported(&w, id);
    }
    assert_int_equal(hidden(&w), (uint32_t)(200 * per));

    world_init(&w, ekf, sp);
    warm_up(&w);
    id = inject_ghost(&w, sp.exist_max, 0.01);
    w.wall_m = 4.0;
    for (int f = 1; f <= k_remove; ++f) {
        step(&w);
        ASSERT_TRUE_MSG(present(&w, id) == (f < k_remove), "frame %d, wall behind: present %d\n", f,
                        present(&w, id));
    }
    assert_int_equal(hidden(&w), 0U);

    world_init(&w, ekf, sp);
    warm_up(&w);
    id = inject_ghost(&w, sp.exist_max, 0.01);
    w.wall_m = 1.2;
    w.view_once = 1;
    for (int f = 1; f <= k_remove + 1; ++f) {
        step(&w);
        ASSERT_TRUE_MSG(present(&w, id) == (f < k_remove + 1), "frame %d, one hidden frame: present %d\n", f,
                        present(&w, id));
    }
    assert_int_equal(hidden(&w), (uint32_t)per);
}

static void test_fastslam_hidden_by_view(void **state)
{
    (void)state;
    hidden_by_view(0);
}

static void test_ekfslam_hidden_by_view(void **state)
{
    (void)state;
    hidden_by_view(1);
}

/* (f) EKF-SLAM: a sighting beside an old ghost (not sighted since it was
 * placed, 0.2 m sd) that the association holds back as a possible revisit
 * (its one loop-closing pairing too weak to take alone) could be the
 * ghost's: no miss (misses_held), the ghost stays for 200 frames and
 * nothing new is mapped. Without the sighting it dies as in (a). The
 * offset (0.55 m beside it, about 2.5 sd) is where this seeded world holds
 * the sighting in most frames: 0.5 m pairs it, 0.6 m neither pairs nor holds. */
static void test_held_sighting_no_miss(void **state)
{
    (void)state;
    world_t w;
    const slam_params_t sp = params();
    const int k_remove = (int)(sp.exist_max / sp.exist_miss_confirmed) + 1;
    world_init(&w, 1, sp);
    warm_up(&w);
    uint32_t id = inject_ghost(&w, sp.exist_max, 0.04);
    const uint16_t n_lm = g_ekf.n_lm;
    w.near_ghost_m = 0.55;
    for (int f = 1; f <= 200; ++f) {
        step(&w);
        ASSERT_TRUE_MSG(exported(&w, id), "frame %d, held sighting beside it: not exported\n", f);
        assert_real_exported(&w, id);
    }
    assert_true(g_ekf.ctr.misses_held >= 100U);
    assert_int_equal(g_ekf.n_lm, n_lm);
    world_init(&w, 1, sp);
    warm_up(&w);
    id = inject_ghost(&w, sp.exist_max, 0.04);
    for (int f = 1; f <= k_remove; ++f) {
        step(&w);
    }
    assert_false(present(&w, id));
}

static void view_counts(const world_t *w, uint64_t *pairs, uint64_t *misses)
{
    *pairs = w->ekf ? g_ekf.ctr.view_pairs : g_fs.ctr.view_pairs;
    *misses = w->ekf ? g_ekf.ctr.view_misses : g_fs.ctr.view_misses;
}

/* The filter's own measure of the rate at which it finds its confirmed
 * landmarks where it expects them (view_pairs, view_misses): a camera that
 * detects each marker with p_detect 0.6 gives 0.6 within 4 binomial sd
 * (Fast-SLAM counts every particle, one frame's draw for all: the sd is
 * that of the frames' count); a ghost in plain view adds one miss a frame
 * (per particle) and no pair; one behind a wall the laser sees adds
 * neither. Without the pairs or the misses counted, with the hidden ones
 * counted as misses, or with the ghost counted as paired, it fails. */
static void counts_detection_rate(int ekf)
{
    const uint32_t per = ekf ? 1U : (uint32_t)N_PARTICLES;
    world_t w;
    const slam_params_t sp = params();
    world_init(&w, ekf, sp);
    warm_up(&w);
    w.p_detect = 0.6;
    uint64_t p0;
    uint64_t m0;
    view_counts(&w, &p0, &m0);
    enum { FRAMES = 300 };
    for (int f = 0; f < FRAMES; ++f) {
        step(&w);
    }
    uint64_t p1;
    uint64_t m1;
    view_counts(&w, &p1, &m1);
    const double n = (double)(p1 - p0 + m1 - m0);
    ASSERT_NEAR(n, (double)(FRAMES * N_REAL * per), 0.0); /* every real marker, every frame, in view */
    const double rate = (double)(p1 - p0) / n;
    const double sd = sqrt(0.6 * 0.4 / (n / per));
    print_message("%s: paired %.3f of the confirmed landmarks in view (camera 0.6, sd %.3f)\n",
                  ekf ? "EKF-SLAM" : "Fast-SLAM", rate, sd);
    ASSERT_NEAR(rate, 0.6, 4.0 * sd);

    /* a ghost in plain view: a miss a frame, per particle */
    w.p_detect = 1.0;
    (void)inject_ghost(&w, sp.exist_max, 0.01);
    view_counts(&w, &p0, &m0);
    for (int f = 0; f < 10; ++f) {
        step(&w);
    }
    view_counts(&w, &p1, &m1);
    /* every landmark counted once a frame; a Fast-SLAM 1.0 particle whose
     * sampled pose puts a real marker outside its gate misses it too */
    assert_int_equal(p1 - p0 + m1 - m0, 10U * (N_REAL + 1) * per);
    assert_true(p1 - p0 >= 10U * N_REAL * per * 95U / 100U);
    assert_true(m1 - m0 >= 10U * per);

    /* behind a wall the laser sees: neither */
    world_init(&w, ekf, sp);
    warm_up(&w);
    (void)inject_ghost(&w, sp.exist_max, 0.01);
    w.wall_m = 1.2;
    view_counts(&w, &p0, &m0);
    for (int f = 0; f < 10; ++f) {
        step(&w);
    }
    view_counts(&w, &p1, &m1);
    assert_int_equal(p1 - p0 + m1 - m0, 10U * N_REAL * per); /* the ghost in neither */
    assert_true(m1 - m0 <= 10U * N_REAL * per * 5U / 100U);
}

static void test_fastslam_counts_detection_rate(void **state)
{
    (void)state;
    counts_detection_rate(0);
}

static void test_ekfslam_counts_detection_rate(void **state)
{
    (void)state;
    counts_detection_rate(1);
}

/* The default miss weight is the existence filter's for the paper camera
 * (p_detect 0.9); MRCLAM's detection rate (about 1/3) gives its 0.125; more
 * reliable cameras weigh a miss more; outside (p_false, 1) no weight. */
static void test_miss_for_detection(void **state)
{
    (void)state;
    const slam_params_t d = slam_params_default();
    ASSERT_NEAR(d.exist_miss_confirmed, (float)slam_exist_miss_for_detection(0.9), 0.0);
    ASSERT_NEAR(slam_exist_miss_for_detection(0.9), log(0.985 / 0.1) / log(60.0), 1e-12);
    ASSERT_NEAR(slam_exist_miss_for_detection(1.0 / 3.0), 0.125, 0.002);
    double last = 0.0;
    for (double pd = 0.05; pd < 0.99; pd += 0.05) {
        const double m = slam_exist_miss_for_detection(pd);
        assert_true(m > last);
        last = m;
    }
    ASSERT_NEAR(slam_exist_miss_for_detection(1.0), -1.0, 0.0);
    ASSERT_NEAR(slam_exist_miss_for_detection(SLAM_EXIST_P_FALSE), -1.0, 0.0);
    ASSERT_NEAR(slam_exist_miss_for_detection(NAN), -1.0, 0.0);
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
        cmocka_unit_test(test_fastslam_hidden_by_view),
        cmocka_unit_test(test_ekfslam_hidden_by_view),
        cmocka_unit_test(test_miss_for_detection),
        cmocka_unit_test(test_fastslam_counts_detection_rate),
        cmocka_unit_test(test_ekfslam_counts_detection_rate),
        cmocka_unit_test(test_held_sighting_no_miss),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
