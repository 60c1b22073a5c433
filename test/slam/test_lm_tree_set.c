/* lm_tree_set's one-walk path for a map whose path to the slot is already
 * private (set_private) against the general path (set_general) alone:
 * white-box, lm_tree.c included. Two pools run the same random operations
 * (adds, replaces, writes in place, moves, clears, map copies and releases,
 * pruned queries, pools small enough to run out), one setting through
 * lm_tree_set, the other through set_general only; after every operation
 * the pools must be equal byte for byte: nodes (boxes, children, reference
 * counts, stale flags), leaves and their counts, free lists, high-water
 * marks, live counts and refusals. */
#include "test_util.h"

#include <string.h>

#include "coslam/rng.h"
#include "../../firmware/core/src/lm_tree.c"

#define N_MAPS 8
#define M_CAP (COSLAM_MAX_LANDMARKS < 100 ? COSLAM_MAX_LANDMARKS : 100)

static lm_tree_pool_t g_a; /* lm_tree_set */
static lm_tree_pool_t g_b; /* set_general */

static landmark_t random_lm(rng_t *rng, uint32_t id)
{
    landmark_t lm;
    memset(&lm, 0, sizeof lm);
    lm.mean.x = 100.0 * rng_uniform(rng);
    lm.mean.y = 10.0 * rng_uniform(rng) - 5.0;
    lm.cov = cov2_make(0.01 + rng_uniform(rng), 0.0, 0.01 + rng_uniform(rng));
    lm.id = id;
    lm.exist = 1.0f;
    lm.n_obs = (uint16_t)(id % 7U);
    return lm;
}

static void check_equal(void)
{
    assert_int_equal(g_a.node_limit, g_b.node_limit);
    assert_int_equal(g_a.leaf_limit, g_b.leaf_limit);
    assert_int_equal(g_a.node_used, g_b.node_used);
    assert_int_equal(g_a.leaf_used, g_b.leaf_used);
    assert_int_equal(g_a.nodes_live, g_b.nodes_live);
    assert_int_equal(g_a.leaves_live, g_b.leaves_live);
    assert_int_equal(g_a.node_free, g_b.node_free);
    assert_int_equal(g_a.leaf_free, g_b.leaf_free);
    assert_int_equal(g_a.capacity_drops, g_b.capacity_drops);
    /* the pools were zeroed first: padding compares too */
    assert_true(memcmp(g_a.node, g_b.node, g_a.node_used * sizeof g_a.node[0]) == 0);
    assert_true(memcmp(g_a.leaf_ref, g_b.leaf_ref, g_a.leaf_used * sizeof g_a.leaf_ref[0]) == 0);
    assert_true(memcmp(g_a.leaf, g_b.leaf, g_a.leaf_used * sizeof g_a.leaf[0]) == 0);
}

static void run(uint32_t seed, uint32_t node_limit, uint32_t leaf_limit, int ops, int *n_private, int *n_refused)
{
    rng_t rng;
    rng_seed(&rng, seed);
    memset(&g_a, 0, sizeof g_a);
    memset(&g_b, 0, sizeof g_b);
    lm_tree_pool_init(&g_a, node_limit, leaf_limit);
    lm_tree_pool_init(&g_b, node_limit, leaf_limit);
    lm_tree_idx_t ra[N_MAPS];
    lm_tree_idx_t rb[N_MAPS];
    int n[N_MAPS];
    for (int k = 0; k < N_MAPS; ++k) {
        ra[k] = LM_TREE_NIL;
        rb[k] = LM_TREE_NIL;
        n[k] = 0;
    }
    uint32_t next_id = 1U;
    for (int t = 0; t < ops; ++t) {
        const int k = (int)rng_below(&rng, N_MAPS);
        const uint32_t op = rng_below(&rng, 10);
        if (op <= 4U) { /* add (0-2) or replace (3-4) */
            const uint32_t slot = (op <= 2U || n[k] == 0) ? (uint32_t)n[k] : rng_below(&rng, (uint32_t)n[k]);
            if (slot >= (uint32_t)M_CAP) {
                continue;
            }
            const landmark_t lm = random_lm(&rng, next_id++);
            uint32_t need_nodes;
            uint32_t need_leaves;
            set_needs(&g_a, ra[k], slot, &need_nodes, &need_leaves);
            *n_private += need_nodes == 0U;
            const coslam_status_t sa = lm_tree_set(&g_a, &ra[k], slot, &lm);
            const coslam_status_t sb = set_general(&g_b, &rb[k], slot, &lm);
            assert_int_equal(sa, sb);
            *n_refused += sa != COSLAM_OK;
            if (sa == COSLAM_OK && slot == (uint32_t)n[k]) {
                n[k]++;
            }
        } else if (op == 5U && n[k] > 0) { /* write in place */
            const uint32_t j = rng_below(&rng, (uint32_t)n[k]);
            landmark_t *la = lm_tree_write(&g_a, &ra[k], j);
            landmark_t *lb = lm_tree_write(&g_b, &rb[k], j);
            assert_true((la == 0) == (lb == 0));
            if (la != 0) {
                la->mean.x += 1.0;
                lb->mean.x += 1.0;
                lm_tree_changed(&g_a, ra[k], j);
                lm_tree_changed(&g_b, rb[k], j);
            }
        } else if (op == 6U && n[k] > 0) { /* remove: the last moves into the hole */
            const uint32_t j = rng_below(&rng, (uint32_t)n[k]);
            const uint32_t last = (uint32_t)n[k] - 1U;
            coslam_status_t sa;
            coslam_status_t sb;
            if (j != last) {
                sa = lm_tree_move(&g_a, &ra[k], j, last);
                sb = lm_tree_move(&g_b, &rb[k], j, last);
            } else {
                sa = lm_tree_clear(&g_a, &ra[k], j);
                sb = lm_tree_clear(&g_b, &rb[k], j);
            }
            assert_int_equal(sa, sb);
            if (sa == COSLAM_OK) {
                n[k]--;
            }
        } else if (op == 7U) { /* copy a map (resampling) */
            const int src = (int)rng_below(&rng, N_MAPS);
            if (src != k) {
                lm_tree_release(&g_a, &ra[k]);
                lm_tree_release(&g_b, &rb[k]);
                lm_tree_retain(&g_a, ra[src]);
                lm_tree_retain(&g_b, rb[src]);
                ra[k] = ra[src];
                rb[k] = rb[src];
                n[k] = n[src];
            }
        } else if (op == 8U) { /* a pruned query recomputes the stale boxes */
            const landmark_t *out[M_CAP];
            const double x = 100.0 * rng_uniform(&rng);
            const uint32_t qa = lm_tree_query(&g_a, ra[k], (uint32_t)n[k], x, 0.0, 5.0, out, 0);
            const uint32_t qb = lm_tree_query(&g_b, rb[k], (uint32_t)n[k], x, 0.0, 5.0, out, 0);
            assert_int_equal(qa, qb);
        } else if (rng_below(&rng, 32) == 0U) { /* release now and then */
            lm_tree_release(&g_a, &ra[k]);
            lm_tree_release(&g_b, &rb[k]);
            n[k] = 0;
        }
        check_equal();
    }
}

static void test_set_private_equals_general(void **state)
{
    (void)state;
    const int ops = COSLAM_TEST_FULL ? 40000 : 8000;
    int n_private = 0;
    int n_refused = 0;
    run(7U, 0U, 0U, ops, &n_private, &n_refused);
    assert_int_equal(n_refused, 0);
    assert_true(n_private > ops / 10); /* the one-walk path was taken often */
    /* pools that run out: the one-walk path declines an empty or shared
     * slot when no leaf is left, and the general path refuses and counts */
    int p2 = 0;
    int r2 = 0;
    run(11U, 60U, 150U, ops, &p2, &r2);
    assert_true(p2 > ops / 20);
    assert_true(r2 > 0);
    assert_true(g_a.capacity_drops > 0U);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_set_private_equals_general),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
