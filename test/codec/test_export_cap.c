/*
 * The exported map is capped at COSLAM_MAX_MSG_LANDMARKS (config.h: what one
 * link datagram holds) below the map capacity: built against the small core
 * (4 landmarks per message), an EKF-SLAM map of 10 confirmed landmarks
 * exports its 4 most observed ones, ordered by identity, returns
 * COSLAM_E_CAPACITY and counts the 6 left out (docs/map-message.md
 * "Message and link"). The whole map is still there: *_export_whole gives
 * every landmark in identity order (the merge check, evaluation, map
 * files) and counts nothing.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"
#include "coslam/map_merge.h"

static ekfslam_t g_ekf;
static fastslam_t g_fs;
static map_whole_t g_whole;
static map_estimate_t g_out;

static void test_ekf_exports_most_observed(void **state)
{
    (void)state;
    _Static_assert(COSLAM_MAX_MSG_LANDMARKS == 4, "the small core of test/codec");
    const ekfslam_config_t c = ekfslam_config_default();
    assert_int_equal(ekfslam_init(&g_ekf, &c, (pose2_t){0.0, 0.0, 0.0}), COSLAM_OK);
    /* ids 1..10, observations 3, 17, 5, 40, 2, 9, 31, 8, 12, 1: the four
     * most observed are ids 4 (40), 7 (31), 2 (17) and 9 (12) */
    const uint16_t n_obs[10] = {3, 17, 5, 40, 2, 9, 31, 8, 12, 1};
    for (int j = 0; j < 10; ++j) {
        const ekfslam_meta_t meta = {(uint32_t)(j + 1), 10.0f, n_obs[j], 1, 0, 0};
        const point2_t at = {1.0 + 0.7 * j, (j % 2) ? 0.5 : -0.5};
        assert_int_equal(ekfslam_add_landmark_body(&g_ekf, at, cov2_make(0.01, 0.0, 0.01), &meta), COSLAM_OK);
    }
    assert_int_equal(ekfslam_export(&g_ekf, &g_out), COSLAM_E_CAPACITY);
    assert_int_equal(g_out.n_landmarks, 4);
    const uint32_t want[4] = {2, 4, 7, 9};
    for (int i = 0; i < 4; ++i) {
        assert_int_equal(g_out.lm[i].id, want[i]);
    }
    assert_int_equal(g_ekf.ctr.export_capacity_drops, 6);
}

static void test_ekf_whole_map(void **state)
{
    (void)state;
    const ekfslam_config_t c = ekfslam_config_default();
    assert_int_equal(ekfslam_init(&g_ekf, &c, (pose2_t){0.0, 0.0, 0.0}), COSLAM_OK);
    /* ids added in the order 10, 9, .., 1: state order is not identity order */
    for (int j = 0; j < 10; ++j) {
        const ekfslam_meta_t meta = {(uint32_t)(10 - j), 10.0f, (uint16_t)(j + 1), 1, 0, 0};
        const point2_t at = {1.0 + 0.7 * j, (j % 2) ? 0.5 : -0.5};
        assert_int_equal(ekfslam_add_landmark_body(&g_ekf, at, cov2_make(0.01, 0.0, 0.01), &meta), COSLAM_OK);
    }
    assert_int_equal(ekfslam_export_whole(&g_ekf, &g_whole), COSLAM_OK);
    assert_int_equal(g_whole.n_landmarks, 10);
    for (int i = 0; i < 10; ++i) {
        assert_int_equal(g_whole.lm[i].id, (uint32_t)(i + 1));
        /* the landmark of id k was added k-th from the end, at j = 10 - k */
        const int j = 9 - i;
        assert_float_equal(g_whole.lm[i].mean.x, 1.0 + 0.7 * j, 1e-9);
        assert_int_equal(g_whole.lm[i].n_obs, j + 1);
    }
    assert_int_equal(g_ekf.ctr.export_capacity_drops, 0);
    /* the message's 4 are the whole map's 4 most observed, bit for bit */
    assert_int_equal(ekfslam_export(&g_ekf, &g_out), COSLAM_E_CAPACITY);
    assert_int_equal(g_out.n_landmarks, 4);
    for (int i = 0; i < 4; ++i) {
        assert_int_equal(g_out.lm[i].id, (uint32_t)(i + 1));
        assert_true(g_out.lm[i].mean.x == g_whole.lm[i].mean.x && g_out.lm[i].mean.y == g_whole.lm[i].mean.y);
        assert_true(g_out.lm[i].cov_rel.xx == g_whole.lm[i].cov_rel.xx && g_out.lm[i].cov.yy == g_whole.lm[i].cov.yy);
    }
}

/* The merge check compares with the whole own map: an incoming duplicate of
 * an own landmark the message leaves out (id 10, the least observed) pairs
 * with it, so the merge fuses it instead of adding a second copy. */
static merge_body_map_t g_bm;
static merge_scratch_t g_sc;

static void test_merge_check_sees_the_whole_map(void **state)
{
    test_ekf_whole_map(state); /* g_ekf: 10 landmarks, the message holds ids 1..4 */
    map_estimate_t in;
    memset(&in, 0, sizeof in);
    in.pose_cov = cov3_diag(1e-4, 1e-4, 1e-5);
    in.n_landmarks = 1;
    in.lm[0].mean = (point2_t){1.0, -0.5}; /* own id 10: j = 0 */
    in.lm[0].cov = cov2_make(0.01, 0.0, 0.01);
    in.lm[0].cov_rel = in.lm[0].cov;
    in.lm[0].id = 1;
    in.lm[0].n_obs = 20;
    in.lm[0].src_mask = 2;
    const merge_config_t mc = merge_config_default();
    const cov3_t tc = cov3_diag(1e-4, 1e-4, 1e-5);
    merge_stats_t st;
    memset(&st, 0, sizeof st);
    assert_int_equal(merge_transform_map(&in, (pose2_t){0.0, 0.0, 0.0}, &tc, &mc, &g_bm, &st), COSLAM_OK);
    assert_int_equal(g_whole.n_landmarks, 10);
    assert_int_equal(merge_check(&g_whole, NULL, NULL, &g_ekf.cfg.slam, 0U, &mc, &g_bm, &g_sc, &st), COSLAM_OK);
    assert_int_equal(st.pairs, 1);
    assert_int_equal(g_bm.n, 1);
    const uint16_t before = g_ekf.n_lm;
    assert_int_equal(merge_into_ekfslam(&g_ekf, &g_bm, &mc, &g_sc, &st), COSLAM_OK);
    assert_int_equal(st.fused, 1);
    assert_int_equal(st.added, 0);
    assert_int_equal(g_ekf.n_lm, before);
}

static void test_fastslam_whole_map(void **state)
{
    (void)state;
    fastslam_config_t c = fastslam_config_default();
    c.n_particles = 3;
    assert_int_equal(fastslam_init(&g_fs, &c, (pose2_t){0.0, 0.0, 0.0}, 7U), COSLAM_OK);
    /* 7 confirmed landmarks in every particle, ids 7..1 in slot order */
    for (uint16_t k = 0; k < 3; ++k) {
        for (int j = 0; j < 7; ++j) {
            landmark_t lm = {0};
            lm.mean = (point2_t){1.0 + j, 0.1 * k};
            lm.cov = cov2_make(0.01, 0.0, 0.01);
            lm.id = (uint32_t)(7 - j);
            lm.exist = 10.0f;
            lm.n_obs = 20;
            lm.confirmed_once = 1;
            assert_int_equal(fastslam_particle_add(&g_fs, k, &lm), COSLAM_OK);
        }
    }
    assert_int_equal(fastslam_export(&g_fs, &g_out), COSLAM_E_CAPACITY);
    assert_int_equal(g_out.n_landmarks, 4);
    assert_int_equal(g_fs.ctr.export_capacity_drops, 3);
    assert_int_equal(fastslam_export_whole(&g_fs, &g_whole), COSLAM_OK);
    assert_int_equal(g_whole.n_landmarks, 7);
    for (int i = 0; i < 7; ++i) {
        /* id k sits at x = 1 + (7 - k); y is the mean of 0, 0.1, 0.2 */
        assert_int_equal(g_whole.lm[i].id, (uint32_t)(i + 1));
        assert_float_equal(g_whole.lm[i].mean.x, 1.0 + (6 - i), 1e-9);
        assert_float_equal(g_whole.lm[i].mean.y, 0.1, 1e-9);
    }
    assert_int_equal(g_fs.ctr.export_capacity_drops, 3); /* the whole map dropped nothing */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ekf_exports_most_observed),
        cmocka_unit_test(test_ekf_whole_map),
        cmocka_unit_test(test_fastslam_whole_map),
        cmocka_unit_test(test_merge_check_sees_the_whole_map),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
