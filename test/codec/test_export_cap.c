/*
 * The exported map is capped at COSLAM_MAX_MSG_LANDMARKS (config.h: what one
 * link datagram holds) below the map capacity: built against the small core
 * (4 landmarks per message), an EKF-SLAM map of 10 confirmed landmarks
 * exports its 4 most observed ones, ordered by identity, returns
 * COSLAM_E_CAPACITY and counts the 6 left out (docs/map-message.md
 * "Message and link"). The whole map is still reachable, a message's worth
 * at a time: *_export_page gives every landmark once, in identity order,
 * for evaluation and map files, and counts nothing.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"

static ekfslam_t g_ekf;
static fastslam_t g_fs;
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

static void test_ekf_pages_hold_the_whole_map(void **state)
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
    const int want_n[4] = {4, 4, 2, 0};
    uint32_t next_id = 1;
    for (uint16_t page = 0; page < 4; ++page) {
        uint16_t total = 0;
        assert_int_equal(ekfslam_export_page(&g_ekf, &g_out, page, &total), COSLAM_OK);
        assert_int_equal(total, 10);
        assert_int_equal(g_out.n_landmarks, want_n[page]);
        for (int i = 0; i < g_out.n_landmarks; ++i) {
            assert_int_equal(g_out.lm[i].id, next_id);
            /* the landmark of id k was added k-th from the end, at j = 10 - k */
            const int j = 10 - (int)next_id;
            assert_float_equal(g_out.lm[i].mean.x, 1.0 + 0.7 * j, 1e-9);
            assert_int_equal(g_out.lm[i].n_obs, j + 1);
            ++next_id;
        }
    }
    assert_int_equal(next_id, 11);
    assert_int_equal(g_ekf.ctr.export_capacity_drops, 0);
    /* pages k > 0 reuse page 0's order; an export in between takes it over */
    assert_int_equal(ekfslam_export(&g_ekf, &g_out), COSLAM_E_CAPACITY);
    assert_int_equal(ekfslam_export_page(&g_ekf, &g_out, 1, NULL), COSLAM_OK);
    assert_int_equal(g_out.n_landmarks, 0);
}

static void test_fastslam_pages_hold_the_whole_map(void **state)
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
    const int want_n[3] = {4, 3, 0};
    uint32_t next_id = 1;
    for (uint16_t page = 0; page < 3; ++page) {
        uint16_t total = 0;
        assert_int_equal(fastslam_export_page(&g_fs, &g_out, page, &total), COSLAM_OK);
        assert_int_equal(total, 7);
        assert_int_equal(g_out.n_landmarks, want_n[page]);
        for (int i = 0; i < g_out.n_landmarks; ++i) {
            assert_int_equal(g_out.lm[i].id, next_id);
            /* id k sits at x = 1 + (7 - k); y is the mean of 0, 0.1, 0.2 */
            assert_float_equal(g_out.lm[i].mean.x, 1.0 + (7 - (int)next_id), 1e-9);
            assert_float_equal(g_out.lm[i].mean.y, 0.1, 1e-9);
            ++next_id;
        }
    }
    assert_int_equal(next_id, 8);
    assert_int_equal(g_fs.ctr.export_capacity_drops, 3); /* the pages counted nothing */
    /* pages k > 0 reuse page 0's table; an export in between takes it over */
    assert_int_equal(fastslam_export(&g_fs, &g_out), COSLAM_E_CAPACITY);
    assert_int_equal(fastslam_export_page(&g_fs, &g_out, 1, NULL), COSLAM_OK);
    assert_int_equal(g_out.n_landmarks, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ekf_exports_most_observed),
        cmocka_unit_test(test_ekf_pages_hold_the_whole_map),
        cmocka_unit_test(test_fastslam_pages_hold_the_whole_map),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
