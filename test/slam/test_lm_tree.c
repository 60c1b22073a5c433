/* The shared landmark tree of Fast-SLAM (lm_tree.h): copy-on-write
 * isolation between particles after resampling, reference counts back to an
 * empty pool once every map is released, pool exhaustion (COSLAM_E_CAPACITY
 * and a counter), and a randomized comparison against flat reference arrays
 * (contents, slot order, spatial query, reference counts recomputed from
 * scratch) over thousands of operations. */
#include "test_util.h"

#include <string.h>

#include "coslam/fastslam.h"
#include "coslam/lm_tree.h"
#include "coslam/rng.h"

static fastslam_t g_fs;
static lm_tree_pool_t g_pool;

static landmark_t make_lm(double x, double y, double var, uint32_t id)
{
    landmark_t lm;
    memset(&lm, 0, sizeof lm);
    lm.mean.x = x;
    lm.mean.y = y;
    lm.cov = cov2_make(var, 0.0, var);
    lm.id = id;
    lm.exist = 1.0f;
    lm.n_obs = 1;
    lm.src_mask = 1;
    return lm;
}

/* ---- invariants recomputed from scratch ----------------------------------- */

static uint32_t g_node_refs[LM_TREE_MAX_NODES];
static uint32_t g_leaf_refs[LM_TREE_MAX_LEAVES];

/* Every node's and leaf's count equals its number of parents, and the live
 * counts equal the distinct reachable nodes and leaves. */
static void check_refcounts(const lm_tree_pool_t *p, const lm_tree_idx_t *roots, int n_roots)
{
    memset(g_node_refs, 0, sizeof g_node_refs);
    memset(g_leaf_refs, 0, sizeof g_leaf_refs);
    uint32_t nodes = 0;
    uint32_t leaves = 0;
    /* breadth-first over distinct nodes: a node's children are counted once
     * per distinct parent, when the parent is first reached */
    static lm_tree_idx_t queue[LM_TREE_MAX_NODES];
    static uint8_t qlevel[LM_TREE_MAX_NODES];
    uint32_t qh = 0;
    uint32_t qt = 0;
    for (int r = 0; r < n_roots; ++r) {
        if (roots[r] == LM_TREE_NIL) {
            continue;
        }
        if (g_node_refs[roots[r]]++ == 0U) {
            queue[qt] = roots[r];
            qlevel[qt++] = 0;
        }
    }
    while (qh < qt) {
        const lm_tree_idx_t n = queue[qh];
        const int l = qlevel[qh++];
        ++nodes;
        for (unsigned c = 0; c < LM_TREE_FANOUT; ++c) {
            const lm_tree_idx_t ch = p->node[n].child[c];
            if (ch == LM_TREE_NIL) {
                continue;
            }
            if (l == LM_TREE_DEPTH - 1) {
                if (g_leaf_refs[ch]++ == 0U) {
                    ++leaves;
                }
            } else if (g_node_refs[ch]++ == 0U) {
                queue[qt] = ch;
                qlevel[qt++] = (uint8_t)(l + 1);
            }
        }
    }
    assert_int_equal(nodes, p->nodes_live);
    assert_int_equal(leaves, p->leaves_live);
    for (uint32_t i = 0; i < p->node_used; ++i) {
        if (g_node_refs[i] != 0U) {
            assert_int_equal(p->node[i].ref, g_node_refs[i]);
        }
    }
    for (uint32_t i = 0; i < p->leaf_used; ++i) {
        if (g_leaf_refs[i] != 0U) {
            assert_int_equal(p->leaf_ref[i], g_leaf_refs[i]);
        }
    }
}

static lm_tree_idx_t fs_roots(const fastslam_t *fs, lm_tree_idx_t *roots)
{
    for (uint16_t k = 0; k < fs->cfg.n_particles; ++k) {
        roots[k] = fs->particles[k].lm_root;
    }
    return (lm_tree_idx_t)fs->cfg.n_particles;
}

/* ---- Fast-SLAM level ------------------------------------------------------ */

static void test_cow_isolation_after_resampling(void **state)
{
    (void)state;
    fastslam_config_t c = fastslam_config_default();
    c.n_particles = 10;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 1U), COSLAM_OK);
    const int m = COSLAM_MAX_LANDMARKS < 40 ? COSLAM_MAX_LANDMARKS : 40;
    for (int j = 0; j < m; ++j) {
        const landmark_t lm = make_lm(j, -j, 0.1, 100U + (uint32_t)j);
        assert_int_equal(fastslam_particle_add(&g_fs, 0, &lm), COSLAM_OK);
    }
    const uint32_t nodes_one_map = g_fs.lm_pool.nodes_live;
    /* particle 0 takes all the weight: every particle now shares its map */
    for (uint16_t k = 1; k < 10; ++k) {
        g_fs.particles[k].log_w = -1000.0;
    }
    fastslam_resample(&g_fs);
    lm_tree_idx_t roots[COSLAM_MAX_PARTICLES];
    check_refcounts(&g_fs.lm_pool, roots, fs_roots(&g_fs, roots));
    for (uint16_t k = 0; k < 10; ++k) {
        assert_int_equal(g_fs.particles[k].n_lm, m);
        assert_int_equal(g_fs.particles[k].lm_root, g_fs.particles[0].lm_root);
    }
    assert_int_equal(g_fs.lm_pool.leaves_live, (uint32_t)m);
    assert_int_equal(g_fs.lm_pool.nodes_live, nodes_one_map);
    /* particle 3 changes landmark 5: only its copy changes, one path copied */
    landmark_t changed = *fastslam_particle_lm(&g_fs, 3, 5);
    changed.mean.x = 77.0;
    assert_int_equal(fastslam_particle_set(&g_fs, 3, 5, &changed), COSLAM_OK);
    ASSERT_NEAR(fastslam_particle_lm(&g_fs, 3, 5)->mean.x, 77.0, 0.0);
    for (uint16_t k = 0; k < 10; ++k) {
        if (k != 3) {
            ASSERT_NEAR(fastslam_particle_lm(&g_fs, k, 5)->mean.x, 5.0, 0.0);
        }
        for (uint16_t j = 0; j < m; ++j) {
            if (k != 3 || j != 5) {
                assert_ptr_equal(fastslam_particle_lm(&g_fs, k, j), fastslam_particle_lm(&g_fs, 0, j));
            }
        }
    }
    assert_int_equal(g_fs.lm_pool.leaves_live, (uint32_t)m + 1U);
    assert_int_equal(g_fs.lm_pool.nodes_live, nodes_one_map + (uint32_t)LM_TREE_DEPTH);
    check_refcounts(&g_fs.lm_pool, roots, fs_roots(&g_fs, roots));
    /* particle 7 adds one: particle 3's change is not seen there */
    const landmark_t extra = make_lm(1.0, 1.0, 0.1, 999U);
    assert_int_equal(fastslam_particle_add(&g_fs, 7, &extra), COSLAM_OK);
    assert_int_equal(g_fs.particles[7].n_lm, m + 1);
    assert_int_equal(g_fs.particles[0].n_lm, m);
    ASSERT_NEAR(fastslam_particle_lm(&g_fs, 7, 5)->mean.x, 5.0, 0.0);
    check_refcounts(&g_fs.lm_pool, roots, fs_roots(&g_fs, roots));
    /* the filter keeps running on the shared maps: updates write privately */
    const sighting_t z = {2.0, 0.1, 0};
    for (int t = 0; t < 20; ++t) {
        const odo_increment_t u = {0.02, 0.0, 0.01};
        assert_int_equal(fastslam_predict(&g_fs, u), COSLAM_OK);
        (void)fastslam_update(&g_fs, &z, 1);
        check_refcounts(&g_fs.lm_pool, roots, fs_roots(&g_fs, roots));
    }
    /* every particle released: the pool is empty again */
    for (uint16_t k = 0; k < 10; ++k) {
        fastslam_particle_clear(&g_fs, k);
    }
    assert_int_equal(g_fs.lm_pool.nodes_live, 0);
    assert_int_equal(g_fs.lm_pool.leaves_live, 0);
    assert_int_equal(g_fs.ctr.tree_capacity_drops, 0);
}

static void test_fastslam_pool_exhaustion(void **state)
{
    (void)state;
    fastslam_config_t c = fastslam_config_default();
    c.n_particles = 4;
    const pose2_t p0 = {0.0, 0.0, 0.0};
    assert_int_equal(fastslam_init(&g_fs, &c, p0, 2U), COSLAM_OK);
    /* a pool far below the worst case: 3 leaves */
    lm_tree_pool_init(&g_fs.lm_pool, 0U, 3U);
    const landmark_t lm = make_lm(1.0, 2.0, 0.1, 1U);
    for (int j = 0; j < 3; ++j) {
        assert_int_equal(fastslam_particle_add(&g_fs, 0, &lm), COSLAM_OK);
    }
    assert_int_equal(fastslam_particle_add(&g_fs, 0, &lm), COSLAM_E_CAPACITY);
    assert_int_equal(g_fs.ctr.tree_capacity_drops, 1);
    assert_int_equal(g_fs.lm_pool.capacity_drops, 1);
    assert_int_equal(g_fs.particles[0].n_lm, 3);
    /* sharing needs no leaves; a private copy does, and is refused */
    g_fs.particles[1].log_w = -1000.0;
    g_fs.particles[2].log_w = -1000.0;
    g_fs.particles[3].log_w = -1000.0;
    fastslam_resample(&g_fs);
    assert_int_equal(g_fs.particles[2].n_lm, 3);
    landmark_t moved = lm;
    moved.mean.x = 5.0;
    assert_int_equal(fastslam_particle_set(&g_fs, 2, 1, &moved), COSLAM_E_CAPACITY);
    assert_int_equal(g_fs.ctr.tree_capacity_drops, 2);
    ASSERT_NEAR(fastslam_particle_lm(&g_fs, 2, 1)->mean.x, 1.0, 0.0); /* unchanged */
    /* a prediction whose landmark process noise (w5) needs private copies
     * of the shared leaves: made, the drops counted and reported */
    g_fs.cfg.slam.noise.lm_process_var_m2_per_m = 0.01;
    const uint32_t drops = g_fs.ctr.tree_capacity_drops;
    const odo_increment_t u = {0.1, 0.0, 0.0};
    assert_int_equal(fastslam_predict(&g_fs, u), COSLAM_E_CAPACITY);
    assert_true(g_fs.ctr.tree_capacity_drops > drops);
    assert_int_equal(g_fs.ctr.predictions, 1);
    g_fs.cfg.slam.noise.lm_process_var_m2_per_m = 0.0;
    assert_int_equal(fastslam_predict(&g_fs, u), COSLAM_OK); /* nothing to write: nothing dropped */
    /* an update that would start a landmark reports the capacity */
    const sighting_t z = {2.0, 0.5, 3};
    assert_int_equal(fastslam_update(&g_fs, &z, 1), COSLAM_E_CAPACITY);
    assert_true(g_fs.ctr.tree_capacity_drops > 2U);
    /* the node pool: one map of the default depth needs LM_TREE_DEPTH nodes */
    lm_tree_pool_init(&g_pool, (uint32_t)LM_TREE_DEPTH - 1U, 0U);
    lm_tree_idx_t root = LM_TREE_NIL;
    assert_int_equal(lm_tree_set(&g_pool, &root, 0, &lm), COSLAM_E_CAPACITY);
    assert_int_equal(g_pool.capacity_drops, 1);
    assert_null(lm_tree_get(&g_pool, root, 0));
    /* all or nothing: no empty node was left in the map */
    assert_int_equal(root, LM_TREE_NIL);
    assert_int_equal(g_pool.nodes_live, 0);
    lm_tree_release(&g_pool, &root);
    assert_int_equal(g_pool.nodes_live, 0);
    assert_int_equal(g_pool.leaves_live, 0);
    /* a shared map: a private copy of the path needs LM_TREE_DEPTH nodes and
     * a leaf; with one node short nothing is copied, both maps stay shared */
    lm_tree_pool_init(&g_pool, 2U * (uint32_t)LM_TREE_DEPTH - 1U, 0U);
    lm_tree_idx_t a = LM_TREE_NIL;
    assert_int_equal(lm_tree_set(&g_pool, &a, 0, &lm), COSLAM_OK);
    lm_tree_idx_t b = a;
    lm_tree_retain(&g_pool, b);
    const uint32_t live = g_pool.nodes_live;
    landmark_t other = lm;
    other.mean.x = -4.0;
    assert_int_equal(lm_tree_set(&g_pool, &b, 1, &other), COSLAM_E_CAPACITY);
    assert_int_equal(g_pool.capacity_drops, 1);
    assert_int_equal(b, a);
    assert_int_equal(g_pool.node[a].ref, 2);
    assert_int_equal(g_pool.nodes_live, live);
    assert_null(lm_tree_get(&g_pool, b, 1));
    /* one node more, and the same set is made */
    lm_tree_release(&g_pool, &b);
    lm_tree_release(&g_pool, &a);
    assert_int_equal(g_pool.nodes_live, 0);
    lm_tree_pool_init(&g_pool, 2U * (uint32_t)LM_TREE_DEPTH, 0U);
    a = LM_TREE_NIL;
    assert_int_equal(lm_tree_set(&g_pool, &a, 0, &lm), COSLAM_OK);
    b = a;
    lm_tree_retain(&g_pool, b);
    assert_int_equal(lm_tree_set(&g_pool, &b, 1, &other), COSLAM_OK);
    assert_true(b != a);
    ASSERT_NEAR(lm_tree_get(&g_pool, b, 1)->mean.x, -4.0, 0.0);
    assert_null(lm_tree_get(&g_pool, a, 1));
    lm_tree_release(&g_pool, &b);
    lm_tree_release(&g_pool, &a);
    assert_int_equal(g_pool.nodes_live, 0);
    assert_int_equal(g_pool.leaves_live, 0);
}

/* The most parents a leaf can have: every one of COSLAM_MAX_PARTICLES maps
 * shares slot 0's leaf through a private level-1 node of its own (each map
 * wrote slot 1, which copied the node and bumped the leaf's count), and
 * lm_tree_move adds one for a moment. The count must hold that exactly
 * (lm_tree_leaf_ref_t is 8 bits in the default profile) and fall back to
 * zero, every leaf freed, when the maps go. */
static void test_leaf_ref_at_most_maps(void **state)
{
    (void)state;
    _Static_assert(COSLAM_MAX_PARTICLES + 1UL <= LM_TREE_LEAF_REF_MAX, "leaf reference count too narrow");
    static lm_tree_idx_t roots[COSLAM_MAX_PARTICLES];
    lm_tree_pool_init(&g_pool, 0U, 0U);
    const landmark_t shared = make_lm(1.0, 2.0, 0.01, 1U);
    roots[0] = LM_TREE_NIL;
    assert_int_equal(lm_tree_set(&g_pool, &roots[0], 0, &shared), COSLAM_OK);
    assert_int_equal(lm_tree_set(&g_pool, &roots[0], 1, &shared), COSLAM_OK);
    for (int k = 1; k < COSLAM_MAX_PARTICLES; ++k) {
        lm_tree_retain(&g_pool, roots[0]);
        roots[k] = roots[0];
        const landmark_t own = make_lm(3.0, (double)k, 0.01, 2U + (uint32_t)k);
        assert_int_equal(lm_tree_set(&g_pool, &roots[k], 1, &own), COSLAM_OK);
    }
    lm_tree_idx_t n = roots[0];
    for (int l = 0; l + 1 < LM_TREE_DEPTH; ++l) {
        n = g_pool.node[n].child[0];
    }
    const lm_tree_idx_t leaf = g_pool.node[n].child[0];
    assert_int_equal(g_pool.leaf_ref[leaf], COSLAM_MAX_PARTICLES);
    check_refcounts(&g_pool, roots, COSLAM_MAX_PARTICLES);
    /* the last map moves slot 0 into slot 1: parents N + 1, then back to N */
    assert_int_equal(lm_tree_move(&g_pool, &roots[COSLAM_MAX_PARTICLES - 1], 1, 0), COSLAM_OK);
    assert_int_equal(g_pool.leaf_ref[leaf], COSLAM_MAX_PARTICLES);
    ASSERT_NEAR(lm_tree_get(&g_pool, roots[COSLAM_MAX_PARTICLES - 1], 1)->mean.y, 2.0, 0.0);
    check_refcounts(&g_pool, roots, COSLAM_MAX_PARTICLES);
    for (int k = 0; k < COSLAM_MAX_PARTICLES; ++k) {
        ASSERT_NEAR(lm_tree_get(&g_pool, roots[k], k + 1 < COSLAM_MAX_PARTICLES ? 0U : 1U)->mean.x, 1.0, 0.0);
        lm_tree_release(&g_pool, &roots[k]);
    }
    assert_int_equal(g_pool.nodes_live, 0);
    assert_int_equal(g_pool.leaves_live, 0);
}

/* ---- randomized against flat arrays --------------------------------------- */

#define N_MAPS 12
#define M_CAP (COSLAM_MAX_LANDMARKS < 200 ? COSLAM_MAX_LANDMARKS : 200)

static landmark_t g_ref[N_MAPS][M_CAP];
static int g_n[N_MAPS];

static void check_map(const lm_tree_pool_t *p, lm_tree_idx_t root, int k)
{
    static const landmark_t *out[COSLAM_MAX_LANDMARKS];
    static uint16_t slots[COSLAM_MAX_LANDMARKS];
    const uint32_t n = lm_tree_gather(p, root, (uint32_t)g_n[k], out, slots);
    assert_int_equal(n, (uint32_t)g_n[k]);
    for (int j = 0; j < g_n[k]; ++j) {
        assert_int_equal(slots[j], j);
        assert_memory_equal(out[j], &g_ref[k][j], sizeof(landmark_t));
        assert_ptr_equal(lm_tree_get(p, root, (uint32_t)j), out[j]);
    }
    assert_null(lm_tree_get(p, root, (uint32_t)g_n[k]));
}

static int g_pruned; /* queries that skipped part of a map */

static void check_query(lm_tree_pool_t *p, lm_tree_idx_t root, int k, double x, double y, double r)
{
    static const landmark_t *out[COSLAM_MAX_LANDMARKS];
    static uint16_t slots[COSLAM_MAX_LANDMARKS];
    const uint32_t n = lm_tree_query(p, root, (uint32_t)g_n[k], x, y, r, out, slots);
    uint32_t c = 0;
    for (int j = 0; j < g_n[k]; ++j) {
        const landmark_t *lm = &g_ref[k][j];
        /* fastslam.c's reach test: a landmark it may call near */
        const double dx = lm->mean.x - x;
        const double dy = lm->mean.y - y;
        const double reach = r + 3.0 * sqrt(lm->cov.xx + lm->cov.yy) + 0.5;
        const int may_be_near = !(dx * dx + dy * dy > reach * reach);
        while (c < n && slots[c] < j) {
            ++c;
        }
        const int returned = c < n && slots[c] == j;
        if (may_be_near) {
            ASSERT_TRUE_MSG(returned, "map %d slot %d at (%g, %g) missing from query (%g, %g, %g)\n", k, j,
                            lm->mean.x, lm->mean.y, x, y, r);
        }
        if (returned) {
            assert_memory_equal(out[c], lm, sizeof *lm);
        }
    }
    for (uint32_t i = 1; i < n; ++i) {
        assert_true(slots[i] > slots[i - 1]);
    }
    g_pruned += n < (uint32_t)g_n[k];
}

/* lm_tree_select with a window test: every landmark whose mean lies in
 * the window must come back, in slot order, as it is; run before the
 * query cleans the map, so its boxes are often stale (a new or changed
 * path), and a stale box tested would miss a moved landmark. */
typedef struct {
    double x0, y0, x1, y1;
    int calls;
} window_t;

static int window_may_hold(const float box[4], void *ctx)
{
    window_t *w = (window_t *)ctx;
    w->calls++;
    if ((double)box[2] < w->x0 || (double)box[0] > w->x1 || (double)box[3] < w->y0 || (double)box[1] > w->y1) {
        return LM_TREE_BOX_NONE;
    }
    if ((double)box[0] >= w->x0 && (double)box[2] <= w->x1 && (double)box[1] >= w->y0 && (double)box[3] <= w->y1) {
        return LM_TREE_BOX_ALL;
    }
    return LM_TREE_BOX_SOME;
}

static int g_select_pruned; /* selections that skipped part of a map */
static int g_select_all;    /* landmarks taken under an LM_TREE_BOX_ALL answer */
static int g_select_stale;  /* selections on a map with stale boxes */

static void check_select(lm_tree_pool_t *p, lm_tree_idx_t root, int k, window_t *w)
{
    static const landmark_t *out[COSLAM_MAX_LANDMARKS];
    static uint16_t slots[COSLAM_MAX_LANDMARKS];
    static uint8_t all[COSLAM_MAX_LANDMARKS];
    const uint32_t n = lm_tree_select(p, root, (uint32_t)g_n[k], window_may_hold, w, out, slots, all);
    uint32_t c = 0;
    for (int j = 0; j < g_n[k]; ++j) {
        const landmark_t *lm = &g_ref[k][j];
        const int wanted = lm->mean.x >= w->x0 && lm->mean.x <= w->x1 && lm->mean.y >= w->y0 && lm->mean.y <= w->y1;
        while (c < n && slots[c] < j) {
            ++c;
        }
        const int returned = c < n && slots[c] == j;
        if (wanted) {
            ASSERT_TRUE_MSG(returned, "map %d slot %d at (%g, %g) missing from select [%g, %g] x [%g, %g]\n", k, j,
                            lm->mean.x, lm->mean.y, w->x0, w->x1, w->y0, w->y1);
        }
        if (returned) {
            assert_memory_equal(out[c], lm, sizeof *lm);
            assert_ptr_equal(out[c], lm_tree_get(p, root, (uint32_t)j));
            assert_true(all[c] <= 1U);
            if (all[c]) {
                /* taken untested: it must be wanted */
                ASSERT_TRUE_MSG(wanted, "map %d slot %d at (%g, %g) flagged, outside [%g, %g] x [%g, %g]\n", k, j,
                                lm->mean.x, lm->mean.y, w->x0, w->x1, w->y0, w->y1);
                g_select_all++;
            }
        }
    }
    assert_true(c <= n);
    for (uint32_t i = 1; i < n; ++i) {
        assert_true(slots[i] > slots[i - 1]);
    }
    if (n > 0U) {
        assert_true(slots[n - 1] < (uint32_t)g_n[k]);
    }
    g_select_pruned += n < (uint32_t)g_n[k];
    g_select_stale += root != LM_TREE_NIL && p->node[root].dirty;
}

static landmark_t random_lm(rng_t *rng, uint32_t id)
{
    /* coherent in space by slot, as a robot's map is, with outliers */
    const double x = rng_uniform(rng) < 0.8 ? 2.0 * (double)(id % 97) + rng_uniform(rng) : 200.0 * rng_uniform(rng) - 100.0;
    landmark_t lm = make_lm(x, 10.0 * rng_uniform(rng) - 5.0, 1e-4 + rng_uniform(rng) * rng_uniform(rng), id);
    if (rng_below(rng, 500) == 0) {
        lm.mean.y = NAN; /* must never be pruned */
    }
    if (rng_below(rng, 500) == 0) {
        lm.cov.xx = INFINITY;
    }
    return lm;
}

static void test_randomized_against_flat(void **state)
{
    (void)state;
    rng_t rng;
    rng_seed(&rng, 12345U);
    rng_t wrng;
    rng_seed(&wrng, 54321U);
    lm_tree_pool_init(&g_pool, 0U, 0U);
    lm_tree_idx_t root[N_MAPS];
    for (int k = 0; k < N_MAPS; ++k) {
        root[k] = LM_TREE_NIL;
        g_n[k] = 0;
    }
    const int ops = COSLAM_TEST_FULL ? 200000 : 20000;
    uint32_t next_id = 1;
    int counts[9] = {0};
    int largest = 0;
    for (int t = 0; t < ops; ++t) {
        const int k = (int)rng_below(&rng, N_MAPS);
        const int op = (int)rng_below(&rng, 9);
        counts[op]++;
        switch (op) {
        case 0:
        case 1:
        case 2: /* add */
            if (g_n[k] < M_CAP) {
                const landmark_t lm = random_lm(&rng, next_id++);
                assert_int_equal(lm_tree_set(&g_pool, &root[k], (uint32_t)g_n[k], &lm), COSLAM_OK);
                g_ref[k][g_n[k]++] = lm;
            }
            break;
        case 3: /* write in place through lm_tree_write */
            if (g_n[k] > 0) {
                const int j = (int)rng_below(&rng, (uint32_t)g_n[k]);
                landmark_t *lm = lm_tree_write(&g_pool, &root[k], (uint32_t)j);
                assert_non_null(lm);
                lm->mean.x += rng_normal(&rng, 0.0, 1.0);
                lm->cov.yy *= 0.9;
                lm->exist += 1.0f;
                lm_tree_changed(&g_pool, root[k], (uint32_t)j);
                g_ref[k][j].mean.x = lm->mean.x;
                g_ref[k][j].cov.yy = lm->cov.yy;
                g_ref[k][j].exist = lm->exist;
            }
            break;
        case 4: /* replace */
            if (g_n[k] > 0) {
                const int j = (int)rng_below(&rng, (uint32_t)g_n[k]);
                const landmark_t lm = random_lm(&rng, next_id++);
                assert_int_equal(lm_tree_set(&g_pool, &root[k], (uint32_t)j, &lm), COSLAM_OK);
                g_ref[k][j] = lm;
            }
            break;
        case 5: /* remove: the last moves into the hole */
            if (g_n[k] > 0) {
                const int j = (int)rng_below(&rng, (uint32_t)g_n[k]);
                const int last = g_n[k] - 1;
                if (j != last) {
                    assert_int_equal(lm_tree_move(&g_pool, &root[k], (uint32_t)j, (uint32_t)last), COSLAM_OK);
                    g_ref[k][j] = g_ref[k][last];
                } else {
                    assert_int_equal(lm_tree_clear(&g_pool, &root[k], (uint32_t)j), COSLAM_OK);
                }
                g_n[k]--;
            }
            break;
        case 6: /* copy a map (resampling) */
        case 7: {
            const int src = (int)rng_below(&rng, N_MAPS);
            if (src != k) {
                lm_tree_release(&g_pool, &root[k]);
                lm_tree_retain(&g_pool, root[src]);
                root[k] = root[src];
                memcpy(g_ref[k], g_ref[src], sizeof g_ref[k]);
                g_n[k] = g_n[src];
            }
            break;
        }
        default: /* release now and then */
            if (rng_below(&rng, 64) == 0) {
                lm_tree_release(&g_pool, &root[k]);
                g_n[k] = 0;
            }
            break;
        }
        largest = g_n[k] > largest ? g_n[k] : largest;
        check_map(&g_pool, root[k], k);
        {
            /* its own generator: the operations stay those of before */
            const double cx = 200.0 * rng_uniform(&wrng) - 10.0;
            const double cy = 10.0 * rng_uniform(&wrng) - 5.0;
            const int large = rng_below(&wrng, 4) == 0; /* subtrees inside it */
            const double hx = (large ? 100.0 : 10.0) * rng_uniform(&wrng);
            const double hy = (large ? 10.0 : 3.0) * rng_uniform(&wrng);
            window_t w = {cx - hx, cy - hy, cx + hx, cy + hy, 0};
            check_select(&g_pool, root[k], k, &w);
        }
        check_query(&g_pool, root[k], k, 200.0 * rng_uniform(&rng) - 10.0, 10.0 * rng_uniform(&rng) - 5.0,
                    5.0 * rng_uniform(&rng));
        if (t % 97 == 0) {
            for (int q = 0; q < N_MAPS; ++q) {
                check_map(&g_pool, root[q], q);
            }
            check_refcounts(&g_pool, root, N_MAPS);
        }
    }
    for (int op = 0; op < 9; ++op) {
        assert_true(counts[op] > ops / 20);
    }
    assert_true(largest >= M_CAP - M_CAP / 8); /* the maps grew deep into the tree */
    assert_true(g_pruned > ops / 2);           /* and the boxes do prune */
    assert_true(g_select_pruned > ops / 4);    /* in lm_tree_select too (about half) */
    assert_true(g_select_stale > ops / 4);     /* which often met stale boxes (about half) */
    assert_true(g_select_all > ops / 100);     /* and took subtrees whole (701) */
    check_refcounts(&g_pool, root, N_MAPS);
    /* the high-water mark stays far below the worst case: nodes are reused */
    assert_true(g_pool.node_used <= (uint32_t)(N_MAPS * LM_TREE_NODES_PER_MAP));
    assert_true(g_pool.leaf_used <= (uint32_t)(N_MAPS * M_CAP));
    for (int k = 0; k < N_MAPS; ++k) {
        lm_tree_release(&g_pool, &root[k]);
    }
    assert_int_equal(g_pool.nodes_live, 0);
    assert_int_equal(g_pool.leaves_live, 0);
    assert_int_equal(g_pool.capacity_drops, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cow_isolation_after_resampling),
        cmocka_unit_test(test_fastslam_pool_exhaustion),
        cmocka_unit_test(test_leaf_ref_at_most_maps),
        cmocka_unit_test(test_randomized_against_flat),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
