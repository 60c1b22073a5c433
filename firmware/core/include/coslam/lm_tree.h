/*
 * coslam/lm_tree.h - landmark maps shared between Fast-SLAM particles:
 * a balanced tree with copy-on-write and reference counts over a static
 * pool (Montemerlo et al., "FastSLAM", AAAI 2002, sec. 4: log-time
 * FastSLAM; Thrun, Burgard, Fox, "Probabilistic Robotics", sec. 13.8).
 *
 * One map is a complete tree of fan-out LM_TREE_FANOUT over the landmark
 * slots 0 .. COSLAM_MAX_LANDMARKS-1 (slot j's path is the base-F digits of
 * j, most significant first), LM_TREE_DEPTH internal levels above the
 * leaves. A leaf holds one landmark_t. Maps are dense (slots 0 .. n-1 used),
 * so only the prefix of the tree exists: empty subtrees are LM_TREE_NIL.
 *
 * Sharing: every node and leaf carries a reference count (number of
 * parents: maps' roots and internal nodes pointing at it). Copying a map is
 * copying its root index and bumping one count: O(1). Writing slot j first
 * makes the path to j private (each shared node on it is copied, its
 * children's counts bumped, the original's count dropped), then the leaf:
 * O(F * D) time, at most D nodes + 1 leaf allocated. Releasing a map drops
 * counts top-down and frees what reaches zero, iteratively with an explicit
 * stack of at most 1 + D * (F - 1) entries (no recursion).
 *
 * Spatial pruning: each internal node keeps an axis-aligned box containing,
 * for every landmark below it, the square of half-width
 * 3 sqrt(cov.xx + cov.yy) + 0.5 m around its mean (widened by a small slack
 * for float rounding; an infinite box if any of it is not finite). Fast-SLAM
 * considers a landmark "near" the robot only if its distance from the pose is
 * at most max_range + 3 sqrt(cov.xx + cov.yy) + 0.5 (fastslam.c); a subtree
 * whose box lies farther than max_range from the pose therefore holds no near
 * landmark and lm_tree_query() skips it. The query returns a superset of the
 * near landmarks, in slot order, so the filter's exact test and everything
 * after it run on the same landmarks in the same order as a flat array.
 * Boxes are kept exact, lazily: a change marks the nodes on its path stale
 * (lm_tree_changed), and the next pruned query recomputes each stale node
 * once (lm_tree_clean), so a burst of changes (a map merge writes most
 * landmarks of every particle) costs one recomputation per node, not one
 * per change.
 *
 * Pool sizing (the choice: the worst case always fits). A map holds at
 * most COSLAM_MAX_LANDMARKS distinct leaves and LM_TREE_NODES_PER_MAP
 * internal nodes, and every live node or leaf is reachable from some map,
 * so COSLAM_MAX_PARTICLES maps never need more than
 *   LM_TREE_MAX_LEAVES = COSLAM_MAX_PARTICLES * COSLAM_MAX_LANDMARKS leaves
 *   LM_TREE_MAX_NODES  = COSLAM_MAX_PARTICLES * LM_TREE_NODES_PER_MAP nodes,
 * even when no particle shares anything (a copy-on-write allocates only
 * when the original stays referenced by another map, so the bound holds
 * after every operation). These are the defaults: Fast-SLAM then never runs
 * out of tree storage. Either may be lowered (-DLM_TREE_MAX_LEAVES=...) to
 * trade RAM for the expectation that particles share most of their maps;
 * running out then returns COSLAM_E_CAPACITY and bumps
 * lm_tree_pool_t.capacity_drops (and Fast-SLAM's tree_capacity_drops).
 * Tests may also lower the limits at run time (lm_tree_pool_init).
 *
 * Memory (default profile, F = 8, 100 particles x 64 landmarks): leaves
 * 100 * 64 * (88 + 1) B (an 8-bit reference count, lm_tree_leaf_ref_t),
 * nodes 100 * 9 * 36 B. A pool serves at most COSLAM_MAX_PARTICLES maps at
 * once: the reference counts are sized for that.
 */
#ifndef COSLAM_LM_TREE_H
#define COSLAM_LM_TREE_H

#include <stdint.h>

#include "coslam/config.h"
#include "coslam/landmark.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Fan-out of the tree: 8 (log2 3 bits). 2, 4, 8, 16 or 32. Larger = fewer
 *  levels (shorter paths to copy) but more children to copy per level. */
#ifndef LM_TREE_FANOUT_LOG2
#define LM_TREE_FANOUT_LOG2 3
#endif
#define LM_TREE_FANOUT (1UL << LM_TREE_FANOUT_LOG2)
#if LM_TREE_FANOUT_LOG2 < 1 || LM_TREE_FANOUT_LOG2 > 5
#error "LM_TREE_FANOUT_LOG2 must be in [1, 5]"
#endif

#define LM_TREE_POW_(l) (1UL << (LM_TREE_FANOUT_LOG2 * (l)))
/** Internal levels: the smallest D >= 1 with F^D >= COSLAM_MAX_LANDMARKS. */
#define LM_TREE_DEPTH                                                                                              \
    ((COSLAM_MAX_LANDMARKS + 0UL) <= LM_TREE_POW_(1)   ? 1                                                  \
     : (COSLAM_MAX_LANDMARKS + 0UL) <= LM_TREE_POW_(2) ? 2                                                  \
     : (COSLAM_MAX_LANDMARKS + 0UL) <= LM_TREE_POW_(3) ? 3                                                  \
     : (COSLAM_MAX_LANDMARKS + 0UL) <= LM_TREE_POW_(4) ? 4                                                  \
     : (COSLAM_MAX_LANDMARKS + 0UL) <= LM_TREE_POW_(5) ? 5                                                  \
     : (COSLAM_MAX_LANDMARKS + 0UL) <= LM_TREE_POW_(6) ? 6                                                  \
     : (COSLAM_MAX_LANDMARKS + 0UL) <= LM_TREE_POW_(7) ? 7                                                  \
                                                              : 16)
#if LM_TREE_DEPTH > 7
#error "LM_TREE_FANOUT too small for COSLAM_MAX_LANDMARKS (depth > 7)"
#endif
#define LM_TREE_LEVEL_NODES_(l)                                                                                    \
    ((l) <= LM_TREE_DEPTH ? ((COSLAM_MAX_LANDMARKS + 0UL) + LM_TREE_POW_(l) - 1UL) / LM_TREE_POW_(l) : 0UL)
/** Internal nodes of one full map (levels 1 .. D above the leaves). */
#define LM_TREE_NODES_PER_MAP                                                                                      \
    (LM_TREE_LEVEL_NODES_(1) + LM_TREE_LEVEL_NODES_(2) + LM_TREE_LEVEL_NODES_(3) + LM_TREE_LEVEL_NODES_(4) +       \
     LM_TREE_LEVEL_NODES_(5) + LM_TREE_LEVEL_NODES_(6) + LM_TREE_LEVEL_NODES_(7))

/** Leaf pool: default = the worst case (see above). */
#ifndef LM_TREE_MAX_LEAVES
#define LM_TREE_MAX_LEAVES ((COSLAM_MAX_PARTICLES + 0UL) * (COSLAM_MAX_LANDMARKS + 0UL))
#endif
/** Internal-node pool: default = the worst case (see above). */
#ifndef LM_TREE_MAX_NODES
#define LM_TREE_MAX_NODES ((COSLAM_MAX_PARTICLES + 0UL) * LM_TREE_NODES_PER_MAP)
#endif
#if LM_TREE_MAX_LEAVES < 1 || LM_TREE_MAX_NODES < 1
#error "LM_TREE_MAX_LEAVES and LM_TREE_MAX_NODES must be at least 1"
#endif
#if LM_TREE_MAX_LEAVES > 0xFFFFFFFEUL || LM_TREE_MAX_NODES > 0xFFFFFFFEUL
#error "LM_TREE_MAX_LEAVES / LM_TREE_MAX_NODES too large for 32-bit indices"
#endif
#if COSLAM_MAX_PARTICLES > 65534
#error "reference counts are 16 bits: COSLAM_MAX_PARTICLES must be below 65535"
#endif

/** Index into the node or the leaf pool (the level tells which). 16 bits
 *  when both pools are small enough (the default profile), else 32. */
#if LM_TREE_MAX_LEAVES < 0xFFFFUL && LM_TREE_MAX_NODES < 0xFFFFUL
typedef uint16_t lm_tree_idx_t;
#define LM_TREE_NIL ((lm_tree_idx_t)0xFFFFU)
#else
typedef uint32_t lm_tree_idx_t;
#define LM_TREE_NIL ((lm_tree_idx_t)0xFFFFFFFFUL)
#endif

/** Reference count of a leaf: the level-1 nodes pointing at it. A pool
 *  serves at most COSLAM_MAX_PARTICLES maps at once (Fast-SLAM: one per
 *  particle, copied in place by resampling), each map holds a leaf in one
 *  slot at most and reaches one level-1 node per slot, so a leaf has at
 *  most COSLAM_MAX_PARTICLES parents, one more for a moment inside
 *  lm_tree_move. 8 bits when that fits (the default profile: 100 x 64
 *  leaves, 6,400 B less than 16 bits), else 16. */
#if COSLAM_MAX_PARTICLES + 1 < 0xFF
typedef uint8_t lm_tree_leaf_ref_t;
#define LM_TREE_LEAF_REF_MAX 0xFFU
#else
typedef uint16_t lm_tree_leaf_ref_t;
#define LM_TREE_LEAF_REF_MAX 0xFFFFU
#endif

/** Explicit stack bound of the iterative release. */
#define LM_TREE_STACK (1UL + LM_TREE_DEPTH * (LM_TREE_FANOUT - 1UL))

typedef struct {
    float box[4];                          /**< [m] lo_x, lo_y, hi_x, hi_y (see above) */
    lm_tree_idx_t child[LM_TREE_FANOUT];   /**< nodes, or leaves at the last level;
                                                child[0] links the free list */
    uint16_t ref;                          /**< parents; 0 = free */
    uint8_t dirty;                         /**< box stale (see lm_tree_clean) */
} lm_tree_node_t;

typedef union {
    landmark_t lm;
    lm_tree_idx_t next_free;
} lm_tree_leaf_t;

typedef struct {
    uint32_t node_limit;      /**< usable nodes, <= LM_TREE_MAX_NODES */
    uint32_t leaf_limit;      /**< usable leaves, <= LM_TREE_MAX_LEAVES */
    uint32_t node_used;       /**< high-water mark: nodes [0, node_used) were handed out */
    uint32_t leaf_used;
    uint32_t nodes_live;      /**< nodes in use now */
    uint32_t leaves_live;
    lm_tree_idx_t node_free;  /**< free lists below the high-water marks */
    lm_tree_idx_t leaf_free;
    uint32_t capacity_drops;  /**< allocations refused: pool exhausted */
    lm_tree_node_t node[LM_TREE_MAX_NODES];
    lm_tree_leaf_ref_t leaf_ref[LM_TREE_MAX_LEAVES]; /**< see lm_tree_leaf_ref_t */
    lm_tree_leaf_t leaf[LM_TREE_MAX_LEAVES];
} lm_tree_pool_t;

/**
 * Empty the pool (every map built from it becomes invalid): O(1). Limits of
 * 0 or above the array sizes mean the array sizes.
 */
void lm_tree_pool_init(lm_tree_pool_t *p, uint32_t node_limit, uint32_t leaf_limit);

/** Landmark in slot `slot` of map `root`, NULL if the slot is empty or
 *  beyond COSLAM_MAX_LANDMARKS. O(D). */
const landmark_t *lm_tree_get(const lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t slot);

/**
 * Make slot `slot` (which must hold a landmark) private to map *root and
 * return it for writing; NULL (COSLAM_E_CAPACITY, counted) if the pool ran
 * out. After changing its mean or covariance call lm_tree_changed(). O(F D).
 */
landmark_t *lm_tree_write(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot);

/** The landmark in `slot` moved or changed its covariance: mark the boxes on
 *  its path stale. O(D). */
void lm_tree_changed(lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t slot);

/** Recompute the stale boxes of map `root` (done by lm_tree_query). O(F) per
 *  stale node. */
void lm_tree_clean(lm_tree_pool_t *p, lm_tree_idx_t root);

/**
 * Store *lm in slot `slot` (existing or empty; the path is created as
 * needed; boxes marked stale). COSLAM_E_CAPACITY (counted once) if the
 * pools cannot hold what it needs: checked first, so nothing changes then,
 * no node made or copied. O(F D).
 */
coslam_status_t lm_tree_set(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot, const landmark_t *lm);

/**
 * Slot `dst` takes the landmark of slot `src` (the leaf is shared, not
 * copied), then `src` is emptied (nodes left empty are freed). Both slots
 * must hold landmarks, dst != src. COSLAM_E_CAPACITY (counted) if the pool
 * ran out: nothing changed then. O(F D).
 */
coslam_status_t lm_tree_move(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t dst, uint32_t src);

/** Empty slot `slot` (no-op if empty). COSLAM_E_CAPACITY (counted) if the
 *  path could not be made private. O(F D). */
coslam_status_t lm_tree_clear(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot);

/** Another reference to map `root` (copying a map): O(1). */
void lm_tree_retain(lm_tree_pool_t *p, lm_tree_idx_t root);

/** Drop the reference *root and set it to NIL; frees what is no longer
 *  shared. O(freed nodes and leaves), no recursion. */
void lm_tree_release(lm_tree_pool_t *p, lm_tree_idx_t *root);

/**
 * Landmarks of slots 0 .. n_slots-1 that may lie within reach of (x, y), in
 * slot order, into out[] and their slots into slot_out[] (may be NULL);
 * returns how many. Whole subtrees whose box is farther than max_range_m
 * from (x, y) are skipped: a superset of the near landmarks (see above).
 * Cleans stale boxes first (lm_tree_clean). O(M) at most; O(D F K) for K
 * landmarks in reach when the map is spatially coherent.
 */
uint32_t lm_tree_query(lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t n_slots, double x, double y,
                       double max_range_m, const landmark_t **out, uint16_t *slot_out);

/** Box test of lm_tree_select: box is (lo_x, lo_y, hi_x, hi_y) [m], world
 *  frame, enclosing the reach square (see above) of every landmark below a
 *  node, so their means too. Returns one of LM_TREE_BOX_*. */
typedef int (*lm_tree_box_fn)(const float box[4], void *ctx);
/** No landmark whose mean lies in the box is wanted: the subtree is skipped. */
#define LM_TREE_BOX_NONE 0
/** Some may be: look inside. */
#define LM_TREE_BOX_SOME 1
/** Every landmark whose mean lies in the box is wanted: the subtree is
 *  taken without further tests, its landmarks flagged in all_out. */
#define LM_TREE_BOX_ALL 2

/**
 * Landmarks of slots 0 .. n_slots-1 in slot order into out[] and their
 * slots into slot_out[] (may be NULL), but for whole subtrees whose box
 * may_hold answers LM_TREE_BOX_NONE; returns how many. all_out[] (may be
 * NULL) gets 1 for a landmark taken under an LM_TREE_BOX_ALL answer, else
 * 0. A stale box (changed since the last lm_tree_clean) is never tested:
 * its subtree is looked into, and its children's boxes tested as they are
 * (a clean box encloses its subtree whatever lies below it). So the result
 * is a superset, in slot order, of the landmarks may_hold would not rule
 * out, whether or not the map was cleaned; the pool is not changed. O(M)
 * at most; with clean boxes and a spatially coherent map O(F D K) for K
 * landmarks kept, plus one may_hold call per node looked at.
 */
uint32_t lm_tree_select(const lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t n_slots, lm_tree_box_fn may_hold,
                        void *ctx, const landmark_t **out, uint16_t *slot_out, uint8_t *all_out);

/** All landmarks of slots 0 .. n_slots-1 in slot order (out[], slot_out[]
 *  may be NULL); returns how many. O(M). */
uint32_t lm_tree_gather(const lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t n_slots, const landmark_t **out,
                        uint16_t *slot_out);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_LM_TREE_H */
