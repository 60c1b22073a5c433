/* EKF-SLAM's map merge in parts (map_merge.h merge_ekfslam_begin / _run):
 * a merge of 80 incoming landmarks (50 duplicates, 30 new) into 160 own,
 * with the merge's columns applied every few updates (merge_batch 24), run
 * in parts of a small budget, is the whole merge bit for bit; between the
 * parts the filter refuses predictions and updates and leaves its state
 * as it is; readers between the tiles of a flush in parts see the
 * covariance the finished flush gives. Built on the large core: the
 * default profile has no compressed EKF, and there every update is
 * applied at once, nothing pends. */
#include "test_util.h"

#include <string.h>

#include "app/slam_filter.h"
#include "coslam/map_merge.h"
#include "coslam/rng.h"
#include "synth.h"

#define N_OWN 160
#define N_DUP 50
#define N_NEW 30

_Static_assert(N_OWN + N_NEW <= COSLAM_EKF_MAX_LANDMARKS && N_DUP + N_NEW <= COSLAM_MAX_MSG_LANDMARKS,
               "the case must fit the large core");

static ekfslam_t g_whole;
static ekfslam_t g_parts;
static merge_scratch_t g_sc;
static merge_body_map_t g_bm;

/* 160 own landmarks over 40 m x 40 m, four classes; the message holds 50
 * of them (every third, a few cm off) and 30 beyond the map's east edge. */
static void build_case_with(uint16_t merge_batch, int n_new)
{
    rng_t r;
    rng_seed(&r, 2027U);
    ekfslam_config_t c = ekfslam_config_default();
    c.merge_batch = merge_batch;
    c.slam.noise.init_xy_var_m2 = 0.01; /* every landmark correlated with the pose */
    c.slam.noise.init_theta_var_rad2 = 0.001;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(ekfslam_init(&g_whole, &c, p0), COSLAM_OK);
    point2_t own[N_OWN];
    for (int j = 0; j < N_OWN; ++j) {
        own[j] = (point2_t){-20.0 + 40.0 * rng_uniform(&r), -20.0 + 40.0 * rng_uniform(&r)};
        const ekfslam_meta_t meta = {(uint32_t)(j + 1), 10.0f, 10, 1U, (uint8_t)(j % 4), 0};
        const cov2_t cv = cov2_make(0.01 + 0.002 * (j % 5), 0.001, 0.012);
        assert_int_equal(ekfslam_add_landmark_body(&g_whole, own[j], cv, &meta), COSLAM_OK);
    }
    memset(&g_bm, 0, sizeof g_bm);
    g_bm.n = (uint16_t)(N_DUP + n_new);
    for (int i = 0; i < g_bm.n; ++i) {
        const int dup = i < N_DUP;
        const int j = 3 * i;
        g_bm.mean[i] = dup ? (point2_t){own[j].x + 0.05 * rng_gauss(&r), own[j].y + 0.05 * rng_gauss(&r)}
                           : (point2_t){25.0 + 10.0 * rng_uniform(&r), -20.0 + 40.0 * rng_uniform(&r)};
        g_bm.cov[i] = cov2_make(0.02, 0.002, 0.025);
        g_bm.rel[i] = g_bm.mean[i]; /* the transform is the identity */
        g_bm.rel_cov[i] = g_bm.cov[i];
        g_bm.src_mask[i] = 0x2U;
        g_bm.n_obs[i] = 6;
        g_bm.signature[i] = dup ? (uint8_t)(j % 4) : (uint8_t)(i % 4);
        g_bm.id[i] = 500U + (uint32_t)i;
    }
    g_bm.t = (pose2_t){0.0, 0.0, 0.0};
    g_bm.t_cov = cov3_diag(0.004, 0.004, 0.0004);
    memcpy(&g_parts, &g_whole, sizeof g_whole);
}

static void build_case(void)
{
    build_case_with(24U, N_NEW); /* several flushes in one merge */
}

static void assert_same_state(const ekfslam_t *a, const ekfslam_t *b)
{
    assert_int_equal(a->n_lm, b->n_lm);
    const int d = 3 + 2 * a->n_lm;
    assert_memory_equal(a->x, b->x, (size_t)d * sizeof(double));
    for (int r = 0; r < d; ++r) {
        assert_memory_equal(&a->p[(long)r * EKFSLAM_DIM], &b->p[(long)r * EKFSLAM_DIM], (size_t)d * sizeof(double));
    }
    assert_memory_equal(a->meta, b->meta, (size_t)a->n_lm * sizeof(ekfslam_meta_t));
    assert_int_equal(a->next_id, b->next_id);
    assert_int_equal(a->merge_bn, 0);
    assert_int_equal(b->merge_bn, 0);
    assert_false(a->merging || b->merging);
}

static void test_parts_are_the_whole_merge(void **state)
{
    (void)state;
    build_case();
    const merge_config_t mc = merge_config_default();
    merge_stats_t whole;
    memset(&whole, 0, sizeof whole);
    assert_int_equal(merge_into_ekfslam(&g_whole, &g_bm, &mc, &g_sc, &whole), COSLAM_OK);
    assert_int_equal(whole.fused, N_DUP);
    assert_int_equal(whole.added, N_NEW);

    merge_stats_t parts;
    memset(&parts, 0, sizeof parts);
    assert_int_equal(merge_ekfslam_begin(&g_parts, &g_bm, &mc, &g_sc, &parts), COSLAM_OK);
    /* a second merge while this one runs is refused */
    assert_int_equal(merge_ekfslam_begin(&g_parts, &g_bm, &mc, &g_sc, &parts), COSLAM_E_MERGE_BUSY);
    int calls = 0;
    int done = 0;
    int partial_checked = 0;
    const double scale = ekfslam_p(&g_parts, 3, 3);
    while (!done) {
        assert_int_equal(merge_ekfslam_run(&g_parts, &g_bm, &g_sc, &parts, 2000U, &done), COSLAM_OK);
        calls++;
        assert_true(calls < 10000);
        if (done) {
            break;
        }
        /* the filter waits: nothing it is given changes the state */
        const double x0 = g_parts.x[0];
        const odo_increment_t u = {0.05, 0.0, 0.01};
        assert_int_equal(ekfslam_predict(&g_parts, u), COSLAM_E_MERGE_BUSY);
        const sighting_t z = {2.0, 0.1, 1};
        assert_int_equal(ekfslam_update(&g_parts, &z, 1), COSLAM_E_MERGE_BUSY);
        assert_true(g_parts.x[0] == x0);
        if (g_parts.merge_flush_r0 > 0 && partial_checked < 3) {
            /* between the tiles of a flush: the readers see the covariance
             * of the finished flush (entries in done rows, in rows to do,
             * and across) */
            const int n = 3 + 2 * g_parts.n_lm;
            /* rows 15 and 16 are a duplicate's (own landmark 6), row 243
             * another's (120): both take the pending columns */
            const int rc[6][2] = {{0, 0}, {15, 16}, {15, 243}, {243, 15}, {243, 244}, {2, n - 1}};
            double before[6];
            for (int k = 0; k < 6; ++k) {
                before[k] = ekfslam_p(&g_parts, rc[k][0], rc[k][1]);
            }
            pose2_t pose;
            cov3_t cov_before;
            ekfslam_pose(&g_parts, &pose, &cov_before);
            assert_int_equal(ekfslam_merge_flush_run(&g_parts, 0.0, NULL), 1); /* the rest of it, now */
            assert_int_equal(g_parts.merge_flush_r0, 0);
            for (int k = 0; k < 6; ++k) {
                ASSERT_NEAR(ekfslam_p(&g_parts, rc[k][0], rc[k][1]), before[k], 1e-12 * scale);
            }
            cov3_t cov_after;
            ekfslam_pose(&g_parts, &pose, &cov_after);
            ASSERT_NEAR(cov_after.m[0][2], cov_before.m[0][2], 1e-12 * scale);
            ASSERT_NEAR(cov_after.m[2][2], cov_before.m[2][2], 1e-12 * scale);
            partial_checked++;
        }
    }
    print_message("EKF merge in parts: %d calls, %d flushes checked between their tiles\n", calls, partial_checked);
    assert_true(calls > 20);
    assert_true(partial_checked > 0);
    assert_int_equal(parts.fused, whole.fused);
    assert_int_equal(parts.added, whole.added);
    assert_int_equal(parts.fused_ci, whole.fused_ci);
    assert_same_state(&g_whole, &g_parts);
    /* the filter runs again */
    const odo_increment_t u = {0.05, 0.0, 0.01};
    assert_int_equal(ekfslam_predict(&g_parts, u), COSLAM_OK);
}

/* Two cases the review found: merge_batch 2 (the columns' room is 2 with
 * none pending: the merge must not wait for a flush that has nothing to
 * do, at once or in parts) and a message of duplicates only (the columns
 * left at the end are applied in parts too, not in the last call whole).
 * Each in parts is the whole merge bit for bit. */
static void test_small_batch_and_duplicates_only(void **state)
{
    (void)state;
    const uint16_t batches[2] = {2U, 24U};
    const int news[2] = {N_NEW, 0};
    for (int c = 0; c < 2; ++c) {
        build_case_with(batches[c], news[c]);
        const merge_config_t mc = merge_config_default();
        merge_stats_t whole;
        memset(&whole, 0, sizeof whole);
        assert_int_equal(merge_into_ekfslam(&g_whole, &g_bm, &mc, &g_sc, &whole), COSLAM_OK);
        assert_int_equal(whole.fused, N_DUP);
        assert_int_equal(whole.added, (uint32_t)news[c]);
        merge_stats_t parts;
        memset(&parts, 0, sizeof parts);
        assert_int_equal(merge_ekfslam_begin(&g_parts, &g_bm, &mc, &g_sc, &parts), COSLAM_OK);
        int done = 0;
        int calls = 0;
        int tail_in_parts = 0;
        while (!done) {
            assert_int_equal(merge_ekfslam_run(&g_parts, &g_bm, &g_sc, &parts, 2000U, &done), COSLAM_OK);
            assert_true(++calls < 100000);
            /* every item done, the last columns' flush under way */
            tail_in_parts += !done && g_sc.ekf_next >= 2U * g_bm.n && g_parts.merge_bn > 0;
        }
        print_message("merge_batch %u, %d new: %d calls, %d with the last flush under way\n", (unsigned)batches[c],
                      news[c], calls, tail_in_parts);
        if (news[c] == 0) {
            assert_true(tail_in_parts > 0);
        }
        assert_int_equal(parts.fused, whole.fused);
        assert_same_state(&g_whole, &g_parts);
    }
}

/* ---- through the robot's merge path, in a local phase ------------------- */

static slam_filter_t g_fa;
static slam_filter_t g_fb;
static slam_merge_work_t g_work;
static map_estimate_t g_msg;
static synth_world_t g_world;

/* An EKF-SLAM robot filter that has mapped 600+ steps of a ring world with
 * the compressed EKF (1 m regions, as test_cekf's cases) and stands in a
 * local phase. */
static void local_phase_filter(slam_filter_t *f)
{
    synth_config_t sc = synth_config_default(203U, 240);
    sc.n_signatures = 0;
    sc.loop_radius_m = 8.0;
    sc.ring_half_width_m = 2.5;
    slam_filter_config_t fc = slam_filter_config_default();
    fc.kind = SLAM_FILTER_EKF;
    fc.slam = sc.truth;
    fc.active_spread_madds = 60000U;
    assert_int_equal(slam_filter_init(f, &fc, synth_start_pose(&sc)), COSLAM_OK);
    f->u.ekf.cfg.active_radius_m = 1.0;
    f->u.ekf.cfg.active_min_landmarks = 16U;
    synth_init(&g_world, &sc);
    synth_step_t st;
    int steps = 0;
    while (synth_next(&g_world, &st) && steps < 3000) {
        ++steps;
        assert_int_equal(slam_filter_predict(f, st.u, sc.dt_s), COSLAM_OK);
        if (st.is_frame) {
            (void)slam_filter_update(f, st.z, st.n_z);
        }
        if (steps > 600 && f->u.ekf.cekf.local) {
            break;
        }
    }
    assert_true(f->u.ekf.cekf.local);
}

/* Both filters synced, compared entry by entry to 1e-9 (relative). */
static void assert_close_filters(slam_filter_t *fa, slam_filter_t *fb)
{
    ekfslam_sync(&fa->u.ekf);
    ekfslam_sync(&fb->u.ekf);
    const ekfslam_t *a = &fa->u.ekf;
    const ekfslam_t *b = &fb->u.ekf;
    assert_int_equal(a->n_lm, b->n_lm);
    const int d = 3 + 2 * a->n_lm;
    const double ps = ekfslam_p(a, 0, 0) + ekfslam_p(a, 3, 3);
    for (int r = 0; r < d; ++r) {
        ASSERT_NEAR(b->x[r], a->x[r], 1e-9 * fmax(1.0, fabs(a->x[r])));
        for (int c = 0; c < d; ++c) {
            ASSERT_NEAR(b->p[(long)r * EKFSLAM_DIM + c], a->p[(long)r * EKFSLAM_DIM + c], 1e-9 * ps);
        }
    }
}

/* The robot's inputs after the message: predictions, every third an update. */
static void robot_inputs(slam_filter_t *f, int n, int idle)
{
    for (int k = 0; k < n; ++k) {
        if (k % 3 == 2) {
            const sighting_t z[2] = {{2.0 + 0.1 * k, 0.3 - 0.05 * k, 0}, {3.0, -0.4 + 0.02 * k, 1}};
            (void)slam_filter_update(f, z, 2);
        } else {
            const odo_increment_t u = {0.02, 0.005, 0.01};
            (void)slam_filter_predict(f, u, 0.1);
        }
        if (idle) {
            (void)slam_filter_idle(f);
        }
    }
}

/* Exact mutual sightings of robots at `self` and `other` (map frame): range
 * sd 5 cm, bearing sd 2 deg. */
static merge_geometry_t mutual_geometry(pose2_t self, pose2_t other)
{
    merge_geometry_t g;
    memset(&g, 0, sizeof g);
    const point2_t o_in_s = pose2_apply_inverse(self, (point2_t){other.x, other.y});
    const point2_t s_in_o = pose2_apply_inverse(other, (point2_t){self.x, self.y});
    const double deg = COSLAM_PI / 180.0;
    g.self_sees_other = (robot_sighting_t){hypot(o_in_s.x, o_in_s.y), atan2(o_in_s.y, o_in_s.x), 0.05 * 0.05,
                                           (2.0 * deg) * (2.0 * deg)};
    g.other_sees_self = (robot_sighting_t){hypot(s_in_o.x, s_in_o.y), atan2(s_in_o.y, s_in_o.x), 0.05 * 0.05,
                                           (2.0 * deg) * (2.0 * deg)};
    return g;
}

/* A robot whose compressed EKF is in a local phase, rows of an earlier one
 * pending, merges a partner's map (its own, seen from a partner 1.5 m
 * ahead facing it, the provenance the partner's) through
 * slam_filter_merge_map in parts: the phase is ended and completed in
 * parts first (the check waits: COSLAM_E_MERGE_PENDING, the outcome taken
 * later), then the fusion in parts; its inputs meanwhile are held and
 * applied after. The state is the one of the merge at once followed by
 * the same inputs, up to rounding (the phase ends the deferred way, as the
 * filter ends its phases; at once it is ended whole). */
static map_estimate_t g_out_a;
static map_estimate_t g_out_b;

/* Two copies of a robot in a local phase (g_fa, g_fb) and the message: A's
 * own map (exported from a copy: an export syncs) as seen from a partner
 * 1.5 m ahead facing it (*po); *pa is A's pose. */
static void pair_in_local_phase(pose2_t *pa, pose2_t *po)
{
    local_phase_filter(&g_fa);
    memcpy(&g_fb, &g_fa, sizeof g_fa);
    memcpy(&g_whole, &g_fa.u.ekf, sizeof g_whole);
    assert_int_equal(ekfslam_export(&g_whole, &g_msg), COSLAM_OK);
    cov3_t ca;
    slam_filter_pose(&g_fa, pa, &ca);
    *po = pose2_compose(*pa, (pose2_t){1.5, 0.0, COSLAM_PI});
    g_msg.pose = *po;
}

static void merge_path_case(int variant)
{
    pose2_t pa;
    pose2_t po;
    pair_in_local_phase(&pa, &po);
    for (uint16_t i = 0; i < g_msg.n_landmarks; ++i) {
        g_msg.lm[i].src_mask = 0x2U;
        g_msg.lm[i].mean.x += 0.02; /* a little off: the fusion moves the map */
    }
    const merge_geometry_t g = mutual_geometry(pa, po);
    merge_config_t mc = merge_config_default();
    mc.check = variant == 2 ? 0U : mc.check;
    merge_stats_t sa;
    memset(&sa, 0, sizeof sa);
    mc.step_units = 0U;
    slam_merge_work_init(&g_work);
    assert_int_equal(slam_filter_merge_map(&g_fa, &g_msg, &g, &mc, NULL, &g_work, &sa, NULL, NULL), COSLAM_OK);
    assert_true(sa.fused > 10U);
    robot_inputs(&g_fa, 12, 0);

    merge_stats_t sb;
    memset(&sb, 0, sizeof sb);
    mc.step_units = 1000U;
    slam_merge_work_init(&g_work);
    if (variant == 1) {
        /* an observer's export under way: dropped for the merge, whose
         * local phase still goes in parts */
        assert_int_equal(slam_filter_export_observe(&g_fb, &g_out_b, 1000U), COSLAM_E_MERGE_PENDING);
    }
    assert_int_equal(slam_filter_merge_map(&g_fb, &g_msg, &g, &mc, NULL, &g_work, &sb, NULL, NULL),
                     COSLAM_E_MERGE_PENDING);
    assert_int_equal(g_fb.checks_waited, 1U);
    assert_int_equal(g_fb.observes_yielded, variant == 1 ? 1U : 0U);
    robot_inputs(&g_fb, 12, 1);
    int idles = 0;
    while ((g_fb.merge_due != NULL || g_fb.held_next < g_fb.n_held) && idles < 100000) {
        (void)slam_filter_idle(&g_fb);
        idles++;
    }
    coslam_status_t outcome = COSLAM_E_ARG;
    merge_stats_t so;
    assert_int_equal(slam_merge_work_outcome(&g_work, &outcome, &so, NULL, NULL), 1);
    assert_int_equal(outcome, COSLAM_OK);
    assert_int_equal(so.fused + g_fb.merge_late.fused, sa.fused);
    assert_int_equal(so.added + g_fb.merge_late.added, sa.added);
    assert_int_equal(g_fb.inputs_held, 12U);
    assert_int_equal(g_fb.merges_forced, 0U);
    assert_int_equal(g_fb.held_failures, 0U);
    print_message("merge path in a local phase (case %d): %u landmarks, %u fused, %d idle calls after the inputs\n",
                  variant, (unsigned)g_fa.u.ekf.n_lm, sa.fused, idles);
    assert_close_filters(&g_fa, &g_fb);
}

/* The same merge path refused as lost (COSLAM_E_MERGE_LOST; every receiver
 * lost under a tiny lost_sd_factor), its check waiting for the phase: the
 * outcome taken later is the refusal, with the check's figures; nothing of
 * the merge is left held (merge_due, the working memory's outcome), the
 * held inputs follow, and the filter ends where the same inputs without the
 * merge put it, up to rounding; the next merge begins. */
static void test_merge_path_lost_in_a_local_phase(void **state)
{
    (void)state;
    pose2_t pa;
    pose2_t po;
    pair_in_local_phase(&pa, &po);
    for (uint16_t i = 0; i < g_msg.n_landmarks; ++i) {
        g_msg.lm[i].src_mask = 0x2U;
    }
    const merge_geometry_t g = mutual_geometry(pa, po);
    merge_config_t mc = merge_config_default();
    mc.lost_sd_factor = 1e-6;
    mc.step_units = 1000U;
    merge_stats_t sb;
    memset(&sb, 0, sizeof sb);
    slam_merge_work_init(&g_work);
    assert_int_equal(slam_filter_merge_map(&g_fb, &g_msg, &g, &mc, NULL, &g_work, &sb, NULL, NULL),
                     COSLAM_E_MERGE_PENDING);
    assert_int_equal(g_fb.checks_waited, 1U);
    robot_inputs(&g_fb, 12, 1);
    robot_inputs(&g_fa, 12, 0);
    int idles = 0;
    while ((g_fb.merge_due != NULL || g_fb.held_next < g_fb.n_held) && idles < 100000) {
        (void)slam_filter_idle(&g_fb);
        idles++;
    }
    assert_null(g_fb.merge_due);
    assert_null(g_work.due);
    coslam_status_t outcome = COSLAM_E_ARG;
    merge_stats_t so;
    assert_int_equal(slam_merge_work_outcome(&g_work, &outcome, &so, NULL, NULL), 1);
    assert_int_equal(outcome, COSLAM_E_MERGE_LOST);
    assert_true(so.pairs > 10U);
    assert_true(so.placed_sd_m > 0.0f);
    assert_int_equal(so.fused + so.added + g_fb.merge_late.fused + g_fb.merge_late.added, 0);
    assert_int_equal(slam_merge_work_outcome(&g_work, NULL, NULL, NULL, NULL), 0); /* taken once */
    assert_int_equal(g_fb.inputs_held, 12U);
    assert_int_equal(g_fb.held_failures, 0U);
    assert_int_equal(g_fb.merges_forced, 0U);
    assert_close_filters(&g_fa, &g_fb);
    /* nothing held: the next merge begins (and is refused again) */
    memset(&sb, 0, sizeof sb);
    const coslam_status_t st = slam_filter_merge_map(&g_fb, &g_msg, &g, &mc, NULL, &g_work, &sb, NULL, NULL);
    assert_true(st == COSLAM_E_MERGE_LOST || st == COSLAM_E_MERGE_PENDING);
    slam_merge_work_finish(&g_work);
    if (st == COSLAM_E_MERGE_PENDING) {
        assert_int_equal(slam_merge_work_outcome(&g_work, &outcome, NULL, NULL, NULL), 1);
        assert_int_equal(outcome, COSLAM_E_MERGE_LOST);
    }
}

/* The robot's merge path in a local phase: plain, with an observer's
 * export under way when the message comes, and without the check. */
static void test_merge_path_in_a_local_phase(void **state)
{
    (void)state;
    for (int v = 0; v < 3; ++v) {
        merge_path_case(v);
    }
}


/* An observer's export (the status count, a snapshot) and a send's, in a
 * local phase: the phase completed in parts of the budget, the filter's
 * inputs held meanwhile and applied after; the map exported is the one of
 * the call that began it, as an export at once gives it (up to rounding),
 * and the filter ends where the export at once and the same inputs put it.
 * A send goes before an observer's export under way (that one is dropped
 * and begins again). */
static void test_exports_in_a_local_phase(void **state)
{
    (void)state;
    for (int yields = 1; yields >= 0; --yields) {
        local_phase_filter(&g_fa);
        memcpy(&g_fb, &g_fa, sizeof g_fa);
        assert_int_equal(slam_filter_export(&g_fa, &g_out_a), COSLAM_OK); /* at once */
        robot_inputs(&g_fa, 12, 0);
        const coslam_status_t st = yields ? slam_filter_export_observe(&g_fb, &g_out_b, 1000U)
                                          : slam_filter_export_send(&g_fb, &g_out_b, 1000U);
        assert_int_equal(st, COSLAM_E_MERGE_PENDING);
        assert_int_equal(slam_filter_export_busy(&g_fb), 1);
        robot_inputs(&g_fb, 12, 1);
        coslam_status_t est = COSLAM_E_ARG;
        int polls = 0;
        while (slam_filter_export_poll(&g_fb, &g_out_b, &est) == 0 && polls < 100000) {
            (void)slam_filter_idle(&g_fb);
            polls++;
        }
        assert_int_equal(est, COSLAM_OK);
        assert_true(polls > 3);
        while (g_fb.held_next < g_fb.n_held) {
            (void)slam_filter_idle(&g_fb);
        }
        assert_int_equal(g_fb.inputs_held, 12U);
        assert_int_equal(g_fb.held_failures, 0U);
        assert_int_equal(g_out_b.n_landmarks, g_out_a.n_landmarks);
        for (uint16_t i = 0; i < g_out_a.n_landmarks; ++i) {
            assert_int_equal(g_out_b.lm[i].id, g_out_a.lm[i].id);
            ASSERT_NEAR(g_out_b.lm[i].mean.x, g_out_a.lm[i].mean.x, 1e-9);
            ASSERT_NEAR(g_out_b.lm[i].cov.xx, g_out_a.lm[i].cov.xx, 1e-12);
        }
        assert_close_filters(&g_fa, &g_fb);
    }
    /* a send goes before an observer's export under way */
    local_phase_filter(&g_fb);
    assert_int_equal(slam_filter_export_observe(&g_fb, &g_out_b, 1000U), COSLAM_E_MERGE_PENDING);
    robot_inputs(&g_fb, 3, 0);
    const coslam_status_t st = slam_filter_export_send(&g_fb, &g_out_a, 1000U);
    assert_true(st == COSLAM_E_MERGE_PENDING || st == COSLAM_E_MERGE_BUSY);
    assert_int_equal(g_fb.observes_yielded, 1U);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parts_are_the_whole_merge),
        cmocka_unit_test(test_small_batch_and_duplicates_only),
        cmocka_unit_test(test_merge_path_in_a_local_phase),
        cmocka_unit_test(test_merge_path_lost_in_a_local_phase),
        cmocka_unit_test(test_exports_in_a_local_phase),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
