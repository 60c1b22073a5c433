/* The view profile (view.h): the nearest laser return per bearing bin, and
 * whether it stands in front of a landmark. */
#include "test_util.h"

#include <string.h>

#include "coslam/view.h"

static const pose2_t k_id = {0.0, 0.0, 0.0};

/* a wall at 2 m straight ahead blocks a landmark at 3 m, not one on its face
 * (2.05 m, margin 0.1) nor one in another direction */
static void test_blocks(void **state)
{
    (void)state;
    view_profile_t v;
    const point2_t p[3] = {{2.0, 0.0}, {2.0, 0.02}, {2.0, -0.02}};
    assert_int_equal(view_profile_build(&v, p, 3, k_id), COSLAM_OK);
    assert_int_equal(v.valid, 1);
    assert_true(view_blocks(&v, 3.0, 0.0, 0.1));
    assert_false(view_blocks(&v, 2.05, 0.0, 0.1));
    assert_false(view_blocks(&v, 3.0, COSLAM_PI / 2.0, 0.1));
    assert_false(view_blocks(&v, 3.0, -0.2, 0.1)); /* 0.2 rad away: bins of 2.8 deg */
    /* the nearest return of the bin counts */
    const point2_t q[2] = {{4.0, 0.0}, {1.0, 0.001}};
    assert_int_equal(view_profile_build(&v, q, 2, k_id), COSLAM_OK);
    assert_true(view_blocks(&v, 1.5, 0.0, 0.1));
    assert_false(view_blocks(&v, 1.05, 0.0, 0.1));
}

/* bearings wrap: 3 pi and -pi + x are pi + x's bin (a bin edge is where
 * it is: a return just across one blocks nothing, as at any bin edge) */
static void test_wrap(void **state)
{
    (void)state;
    view_profile_t v;
    const point2_t p[2] = {{-2.0, 1e-3}, {-2.0, -1e-3}}; /* bearings pi - 5e-4 and -pi + 5e-4 */
    assert_int_equal(view_profile_build(&v, p, 2, k_id), COSLAM_OK);
    assert_true(view_blocks(&v, 3.0, COSLAM_PI - 1e-4, 0.1));
    assert_true(view_blocks(&v, 3.0, -COSLAM_PI + 1e-4, 0.1));
    assert_true(view_blocks(&v, 3.0, 3.0 * COSLAM_PI - 1e-4, 0.1));
    assert_true(view_blocks(&v, 3.0, -3.0 * COSLAM_PI + 1e-4, 0.1));
    assert_false(view_blocks(&v, 3.0, 0.0, 0.1));
    assert_false(view_blocks(&v, 3.0, COSLAM_PI / 2.0, 0.1));
}

/* points given in another frame are moved into the robot's: the robot
 * turned 90 deg left since the scan, so what was ahead is now on its right */
static void test_moved(void **state)
{
    (void)state;
    view_profile_t v;
    const point2_t p[1] = {{2.0, 0.0}};
    const pose2_t since = {0.0, 0.0, -COSLAM_PI / 2.0};
    assert_int_equal(view_profile_build(&v, p, 1, since), COSLAM_OK);
    assert_true(view_blocks(&v, 3.0, -COSLAM_PI / 2.0, 0.1));
    assert_false(view_blocks(&v, 3.0, 0.0, 0.1));
    /* and translated: the scan 1 m behind the robot's present position */
    const pose2_t back = {-1.0, 0.0, 0.0};
    assert_int_equal(view_profile_build(&v, p, 1, back), COSLAM_OK);
    assert_true(view_blocks(&v, 1.5, 0.0, 0.1));   /* now 1 m ahead */
    assert_false(view_blocks(&v, 1.05, 0.0, 0.1));
}

/* bad input: refused and not valid; bad points skipped; an empty or
 * invalid profile and non-finite predictions block nothing */
static void test_bad_input(void **state)
{
    (void)state;
    view_profile_t v;
    const point2_t p[4] = {{NAN, 0.0}, {INFINITY, 0.0}, {0.0, 0.0}, {2.0, 0.0}};
    assert_int_equal(view_profile_build(&v, p, 4, k_id), COSLAM_OK);
    assert_true(view_blocks(&v, 3.0, 0.0, 0.1));
    assert_false(view_blocks(&v, 3.0, 0.1, 0.1)); /* NaN / inf / centre points gave nothing */
    assert_false(view_blocks(&v, NAN, 0.0, 0.1));
    assert_false(view_blocks(&v, 3.0, NAN, 0.1));
    assert_false(view_blocks(&v, 3.0, 0.0, NAN));
    assert_false(view_blocks(NULL, 3.0, 0.0, 0.1));
    assert_int_equal(view_profile_build(&v, NULL, 0, k_id), COSLAM_OK);
    assert_int_equal(v.valid, 1);
    assert_false(view_blocks(&v, 3.0, 0.0, 0.1));
    assert_int_equal(view_profile_build(&v, NULL, 3, k_id), COSLAM_E_ARG);
    assert_int_equal(v.valid, 0);
    assert_int_equal(view_profile_build(&v, p + 3, 1, (pose2_t){0.0, NAN, 0.0}), COSLAM_E_ARG);
    assert_int_equal(v.valid, 0);
    assert_false(view_blocks(&v, 3.0, 0.0, 0.1));
    assert_int_equal(view_profile_build(NULL, p, 1, k_id), COSLAM_E_ARG);
    assert_int_equal(view_profile_build(&v, p + 3, 1, k_id), COSLAM_OK);
    view_profile_clear(&v);
    assert_false(view_blocks(&v, 3.0, 0.0, 0.1));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_blocks),
        cmocka_unit_test(test_wrap),
        cmocka_unit_test(test_moved),
        cmocka_unit_test(test_bad_input),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
