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

#include "coslam/map_merge.h"
#include "coslam/rng.h"

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
static void build_case(void)
{
    rng_t r;
    rng_seed(&r, 2027U);
    ekfslam_config_t c = ekfslam_config_default();
    c.merge_batch = 24U; /* several flushes in one merge */
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
    g_bm.n = N_DUP + N_NEW;
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parts_are_the_whole_merge),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
