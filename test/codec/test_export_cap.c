/*
 * The exported map is capped at COSLAM_MAX_MSG_LANDMARKS (config.h: what one
 * link datagram holds) below the map capacity: built against the small core
 * (4 landmarks per message), an EKF-SLAM map of 10 confirmed landmarks
 * exports its 4 most observed ones, ordered by identity, returns
 * COSLAM_E_CAPACITY and counts the 6 left out (docs/map-message.md
 * "Message and link").
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "coslam/ekfslam.h"

static ekfslam_t g_ekf;
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ekf_exports_most_observed),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
