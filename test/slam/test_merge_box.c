/* box_may_pair (the merge's test of a whole tree box) against
 * grid_may_pair (the test of one landmark): white-box, map_merge.c
 * included. Random incoming maps (bins of one cell and of several), random
 * particle poses (any heading, far from the origin too) and random world
 * boxes; wherever a point of a box (its corners, its edges, points inside)
 * moved into the body frame may pair, the box must not be rejected, or the
 * merge would lose a candidate; where a box is taken whole, every such
 * point must pair, or the merge would gain one. Each answer must also be
 * common enough for the test to mean something. */
#include "test_util.h"

#include <string.h>

#include "coslam/rng.h"
#include "../../firmware/core/src/map_merge.c"

static merge_scratch_t g_sc;
static merge_body_map_t g_bm;

static void random_incoming(rng_t *r, int n, double spread_m, double var_m2)
{
    memset(&g_bm, 0, sizeof g_bm);
    g_bm.n = (uint16_t)n;
    const double cx = 20.0 * rng_uniform(r) - 10.0;
    const double cy = 20.0 * rng_uniform(r) - 10.0;
    for (int i = 0; i < n; ++i) {
        /* two clusters: the bitmap has empty bins between them */
        const double ox = i % 2 == 0 ? 0.0 : spread_m;
        g_bm.mean[i] = (point2_t){cx + ox + 4.0 * rng_uniform(r), cy + 4.0 * rng_uniform(r)};
        g_bm.cov[i] = cov2_make(var_m2, 0.0, var_m2);
        g_bm.signature[i] = (uint8_t)(i % 2);
    }
}

static void test_box_may_pair_covers_grid_may_pair(void **state)
{
    (void)state;
    rng_t r;
    rng_seed(&r, 4242U);
    const merge_config_t mc = merge_config_default();
    int rejected = 0;
    int kept = 0;
    int whole = 0;
    int points_may_pair = 0;
    for (int trial = 0; trial < 400; ++trial) {
        /* a large spread makes bins of several cells */
        const double spread = trial % 3 == 0 ? 300.0 * rng_uniform(&r) : 30.0 * rng_uniform(&r);
        const int n = 1 + (int)rng_below(&r, COSLAM_MAX_MSG_LANDMARKS < 16 ? COSLAM_MAX_MSG_LANDMARKS : 16);
        random_incoming(&r, n, spread, 0.001 + 0.05 * rng_uniform(&r));
        grid_build(&g_sc, &g_bm, grid_cell_size(&g_bm, &mc, mc.gate_chi2));
        const double far = trial % 5 == 0 ? 1e5 : 0.0;
        const pose2_t pose = {far + 10.0 * rng_gauss(&r), -far + 10.0 * rng_gauss(&r),
                              COSLAM_PI * (2.0 * rng_uniform(&r) - 1.0)};
        const double c = cos(pose.theta);
        const double s = sin(pose.theta);
        own_box_ctx_t ctx = {&g_sc, pose, c, s};
        for (int b = 0; b < 200; ++b) {
            /* a box somewhere around the incoming map as the particle sees it */
            const point2_t near = g_bm.mean[rng_below(&r, (uint32_t)n)];
            const point2_t at = pose2_apply(pose, (point2_t){near.x + 16.0 * rng_uniform(&r) - 8.0,
                                                             near.y + 16.0 * rng_uniform(&r) - 8.0});
            const double wx = 6.0 * rng_uniform(&r) * rng_uniform(&r);
            const double wy = 6.0 * rng_uniform(&r) * rng_uniform(&r);
            /* through volatile: gcc 12.2 -O3 (the host profile's Release
             * test build) used the unrounded doubles for the box's points
             * below, not the floats box_may_pair reads */
            volatile float vbox[4] = {(float)(at.x - wx), (float)(at.y - wy), (float)(at.x + wx), (float)(at.y + wy)};
            const float box[4] = {vbox[0], vbox[1], vbox[2], vbox[3]};
            const int may = box_may_pair(box, &ctx);
            rejected += may == LM_TREE_BOX_NONE;
            kept += may == LM_TREE_BOX_SOME;
            whole += may == LM_TREE_BOX_ALL;
            for (int q = 0; q < 40; ++q) {
                double u;
                double v;
                if (q < 4) { /* the corners */
                    u = q & 1 ? 1.0 : 0.0;
                    v = q & 2 ? 1.0 : 0.0;
                } else if (q < 20) { /* the edges */
                    u = rng_uniform(&r);
                    v = q & 1 ? 1.0 : 0.0;
                    if (q & 2) {
                        const double t = u;
                        u = v;
                        v = t;
                    }
                } else {
                    u = rng_uniform(&r);
                    v = rng_uniform(&r);
                }
                const point2_t w = {(double)box[0] + u * ((double)box[2] - (double)box[0]),
                                    (double)box[1] + v * ((double)box[3] - (double)box[1])};
                if (grid_may_pair(&g_sc, pose2_apply_inverse_cs(pose, c, s, w))) {
                    points_may_pair++;
                    ASSERT_TRUE_MSG(may != LM_TREE_BOX_NONE,
                                    "trial %d: box [%g, %g] x [%g, %g] rejected, its point (%g, %g) may pair\n", trial,
                                    (double)box[0], (double)box[2], (double)box[1], (double)box[3], w.x, w.y);
                } else {
                    ASSERT_TRUE_MSG(may != LM_TREE_BOX_ALL,
                                    "trial %d: box [%g, %g] x [%g, %g] taken whole, its point (%g, %g) cannot pair\n",
                                    trial, (double)box[0], (double)box[2], (double)box[1], (double)box[3], w.x, w.y);
                }
            }
        }
    }
    /* not vacuous: both answers are common, and many points may pair */
    /* default profile: 47,600 of 80,000 rejected, 28,388 kept, 4,012 whole */
    assert_true(rejected > 400 * 200 / 10);
    assert_true(kept > 400 * 200 / 10);
    assert_true(whole > 400 * 200 / 40);
    assert_true(points_may_pair > 400 * 200);
    /* a box not finite or empty is always looked into */
    own_box_ctx_t ctx = {&g_sc, (pose2_t){0.0, 0.0, 0.0}, 1.0, 0.0};
    const float inf_box[4] = {-INFINITY, -INFINITY, INFINITY, INFINITY};
    const float empty_box[4] = {INFINITY, INFINITY, -INFINITY, -INFINITY};
    const float nan_box[4] = {NAN, 0.0f, 1.0f, 1.0f};
    assert_int_equal(box_may_pair(inf_box, &ctx), LM_TREE_BOX_SOME);
    assert_int_equal(box_may_pair(empty_box, &ctx), LM_TREE_BOX_SOME);
    assert_int_equal(box_may_pair(nan_box, &ctx), LM_TREE_BOX_SOME);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_box_may_pair_covers_grid_may_pair),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
