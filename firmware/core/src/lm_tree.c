#include "coslam/lm_tree.h"

#include <math.h>

#define F_ ((uint32_t)LM_TREE_FANOUT)
#define D_ ((int)LM_TREE_DEPTH)
#define MASK_ (F_ - 1U)

/* Digit of `slot` at internal level l (0 = root). */
static uint32_t digit(uint32_t slot, int l)
{
    return (slot >> (LM_TREE_FANOUT_LOG2 * (unsigned)(D_ - 1 - l))) & MASK_;
}

void lm_tree_pool_init(lm_tree_pool_t *p, uint32_t node_limit, uint32_t leaf_limit)
{
    COSLAM_ASSERT(p != 0);
    p->node_limit = (node_limit == 0U || node_limit > LM_TREE_MAX_NODES) ? (uint32_t)LM_TREE_MAX_NODES : node_limit;
    p->leaf_limit = (leaf_limit == 0U || leaf_limit > LM_TREE_MAX_LEAVES) ? (uint32_t)LM_TREE_MAX_LEAVES : leaf_limit;
    p->node_used = 0U;
    p->leaf_used = 0U;
    p->nodes_live = 0U;
    p->leaves_live = 0U;
    p->node_free = LM_TREE_NIL;
    p->leaf_free = LM_TREE_NIL;
    p->capacity_drops = 0U;
}

/* ---- allocation: free list first, then the untouched part of the pool ---- */

static lm_tree_idx_t node_alloc(lm_tree_pool_t *p)
{
    lm_tree_idx_t i;
    if (p->node_free != LM_TREE_NIL) {
        i = p->node_free;
        p->node_free = p->node[i].child[0];
    } else if (p->node_used < p->node_limit) {
        i = (lm_tree_idx_t)p->node_used++;
    } else {
        p->capacity_drops++;
        return LM_TREE_NIL;
    }
    p->nodes_live++;
    p->node[i].ref = 1U;
    p->node[i].dirty = 1U;
    return i;
}

static void node_free(lm_tree_pool_t *p, lm_tree_idx_t i)
{
    p->node[i].ref = 0U;
    p->node[i].child[0] = p->node_free;
    p->node_free = i;
    p->nodes_live--;
}

static lm_tree_idx_t leaf_alloc(lm_tree_pool_t *p)
{
    lm_tree_idx_t i;
    if (p->leaf_free != LM_TREE_NIL) {
        i = p->leaf_free;
        p->leaf_free = p->leaf[i].next_free;
    } else if (p->leaf_used < p->leaf_limit) {
        i = (lm_tree_idx_t)p->leaf_used++;
    } else {
        p->capacity_drops++;
        return LM_TREE_NIL;
    }
    p->leaves_live++;
    p->leaf_ref[i] = 1U;
    return i;
}

static void leaf_unref(lm_tree_pool_t *p, lm_tree_idx_t i)
{
    COSLAM_ASSERT(p->leaf_ref[i] > 0U);
    if (--p->leaf_ref[i] == 0U) {
        p->leaf[i].next_free = p->leaf_free;
        p->leaf_free = i;
        p->leaves_live--;
    }
}

/* ---- boxes ---------------------------------------------------------------- */

static void box_empty(float b[4])
{
    b[0] = INFINITY;
    b[1] = INFINITY;
    b[2] = -INFINITY;
    b[3] = -INFINITY;
}

/* Union of b with the reach square of one landmark, rounded outwards. */
static void box_add_landmark(float b[4], const landmark_t *lm)
{
    const double r = 3.0 * sqrt(lm->cov.xx + lm->cov.yy) + 0.5;
    const double lo_x = lm->mean.x - r;
    const double lo_y = lm->mean.y - r;
    const double hi_x = lm->mean.x + r;
    const double hi_y = lm->mean.y + r;
    const double big = 1e30; /* beyond it a float box would round to infinity */
    if (!(fabs(lo_x) < big && fabs(lo_y) < big && fabs(hi_x) < big && fabs(hi_y) < big)) {
        b[0] = -INFINITY; /* not finite (or huge): never pruned */
        b[1] = -INFINITY;
        b[2] = INFINITY;
        b[3] = INFINITY;
        return;
    }
    /* slack: 1 mm plus 1e-6 relative covers float rounding (2^-24) */
    const float lx = (float)(lo_x - (1e-3 + 1e-6 * fabs(lo_x)));
    const float ly = (float)(lo_y - (1e-3 + 1e-6 * fabs(lo_y)));
    const float hx = (float)(hi_x + (1e-3 + 1e-6 * fabs(hi_x)));
    const float hy = (float)(hi_y + (1e-3 + 1e-6 * fabs(hi_y)));
    b[0] = lx < b[0] ? lx : b[0];
    b[1] = ly < b[1] ? ly : b[1];
    b[2] = hx > b[2] ? hx : b[2];
    b[3] = hy > b[3] ? hy : b[3];
}

static void box_add_box(float b[4], const float c[4])
{
    b[0] = c[0] < b[0] ? c[0] : b[0];
    b[1] = c[1] < b[1] ? c[1] : b[1];
    b[2] = c[2] > b[2] ? c[2] : b[2];
    b[3] = c[3] > b[3] ? c[3] : b[3];
}

static void node_recompute_box(lm_tree_pool_t *p, lm_tree_idx_t n, int level)
{
    lm_tree_node_t *nd = &p->node[n];
    box_empty(nd->box);
    for (uint32_t c = 0; c < F_; ++c) {
        const lm_tree_idx_t ch = nd->child[c];
        if (ch == LM_TREE_NIL) {
            continue;
        }
        if (level == D_ - 1) {
            box_add_landmark(nd->box, &p->leaf[ch].lm);
        } else {
            box_add_box(nd->box, p->node[ch].box);
        }
    }
}

/* Squared distance from (x, y) to box b; 0 inside, and 0 for NaN input
 * (never pruned). */
static double box_dist2(const float b[4], double x, double y)
{
    double dx = 0.0;
    double dy = 0.0;
    if (x < (double)b[0]) {
        dx = (double)b[0] - x;
    } else if (x > (double)b[2]) {
        dx = x - (double)b[2];
    }
    if (y < (double)b[1]) {
        dy = (double)b[1] - y;
    } else if (y > (double)b[3]) {
        dy = y - (double)b[3];
    }
    return dx * dx + dy * dy;
}

/* ---- paths ---------------------------------------------------------------- */

/*
 * Make the path to `slot` private to the map *root: path[l] gets the node at
 * level l. With `create`, missing nodes are allocated (empty). Returns the
 * link that holds the leaf (in path[D-1]), or NULL if a node was missing
 * (create = 0) or the pool ran out.
 */
static lm_tree_idx_t *private_path(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot, int create,
                                   lm_tree_idx_t path[LM_TREE_DEPTH])
{
    lm_tree_idx_t *link = root;
    for (int l = 0; l < D_; ++l) {
        lm_tree_idx_t n = *link;
        if (n == LM_TREE_NIL) {
            if (!create) {
                return 0;
            }
            n = node_alloc(p);
            if (n == LM_TREE_NIL) {
                return 0;
            }
            for (uint32_t c = 0; c < F_; ++c) {
                p->node[n].child[c] = LM_TREE_NIL;
            }
            box_empty(p->node[n].box);
            p->node[n].dirty = 1U;
            *link = n;
        } else if (p->node[n].ref > 1U) {
            const lm_tree_idx_t c = node_alloc(p);
            if (c == LM_TREE_NIL) {
                return 0;
            }
            p->node[c] = p->node[n];
            p->node[c].ref = 1U;
            for (uint32_t q = 0; q < F_; ++q) {
                const lm_tree_idx_t ch = p->node[c].child[q];
                if (ch == LM_TREE_NIL) {
                    continue;
                }
                if (l == D_ - 1) {
                    COSLAM_ASSERT(p->leaf_ref[ch] < LM_TREE_LEAF_REF_MAX);
                    p->leaf_ref[ch]++;
                } else {
                    p->node[ch].ref++;
                }
            }
            p->node[n].ref--;
            *link = c;
            n = c;
        }
        path[l] = n;
        link = &p->node[n].child[digit(slot, l)];
    }
    return link;
}

/* The boxes on a path are stale: recomputed by the next pruned query
 * (lm_tree_clean), once per node however many slots below it changed. */
static void mark_path(lm_tree_pool_t *p, const lm_tree_idx_t path[LM_TREE_DEPTH])
{
    for (int l = 0; l < D_; ++l) {
        p->node[path[l]].dirty = 1U;
    }
}

const landmark_t *lm_tree_get(const lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t slot)
{
    if (slot >= (uint32_t)COSLAM_MAX_LANDMARKS) {
        return 0;
    }
    lm_tree_idx_t n = root;
    for (int l = 0; l < D_ && n != LM_TREE_NIL; ++l) {
        n = p->node[n].child[digit(slot, l)];
    }
    return n == LM_TREE_NIL ? 0 : &p->leaf[n].lm;
}

landmark_t *lm_tree_write(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot)
{
    lm_tree_idx_t path[LM_TREE_DEPTH];
    lm_tree_idx_t *link = private_path(p, root, slot, 0, path);
    if (link == 0 || *link == LM_TREE_NIL) {
        return 0;
    }
    lm_tree_idx_t lf = *link;
    if (p->leaf_ref[lf] > 1U) {
        const lm_tree_idx_t c = leaf_alloc(p);
        if (c == LM_TREE_NIL) {
            return 0;
        }
        p->leaf[c].lm = p->leaf[lf].lm;
        p->leaf_ref[lf]--;
        *link = c;
        lf = c;
    }
    return &p->leaf[lf].lm;
}

void lm_tree_changed(lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t slot)
{
    lm_tree_idx_t n = root;
    for (int l = 0; l < D_ && n != LM_TREE_NIL; ++l) {
        p->node[n].dirty = 1U;
        n = p->node[n].child[digit(slot, l)];
    }
}

void lm_tree_clean(lm_tree_pool_t *p, lm_tree_idx_t root)
{
    if (root == LM_TREE_NIL || !p->node[root].dirty) {
        return;
    }
    /* post-order over the dirty nodes only: children's boxes first. A node
     * shared with other maps is recomputed in place, which is harmless: its
     * box is a function of its subtree, the same for every map holding it. */
    lm_tree_idx_t cur[LM_TREE_DEPTH];
    uint32_t pos[LM_TREE_DEPTH];
    int l = 0;
    cur[0] = root;
    pos[0] = 0U;
    while (l >= 0) {
        const lm_tree_idx_t n = cur[l];
        if (l < D_ - 1 && pos[l] < F_) {
            const lm_tree_idx_t ch = p->node[n].child[pos[l]++];
            if (ch != LM_TREE_NIL && p->node[ch].dirty) {
                ++l;
                cur[l] = ch;
                pos[l] = 0U;
            }
            continue;
        }
        node_recompute_box(p, n, l);
        p->node[n].dirty = 0U;
        --l;
    }
}

/*
 * What setting `slot` in *root takes from the pools, without touching them:
 * from the first level whose node is missing or shared, a new node at every
 * level below (a copied node shares its children, so they are copied too),
 * and then a new leaf; a wholly private path needs a leaf only if the slot
 * is empty or its leaf shared.
 */
static void set_needs(const lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t slot, uint32_t *nodes, uint32_t *leaves)
{
    lm_tree_idx_t n = root;
    for (int l = 0; l < D_; ++l) {
        if (n == LM_TREE_NIL || p->node[n].ref > 1U) {
            *nodes = (uint32_t)(D_ - l);
            *leaves = 1U;
            return;
        }
        n = p->node[n].child[digit(slot, l)];
    }
    *nodes = 0U;
    *leaves = (n == LM_TREE_NIL || p->leaf_ref[n] > 1U) ? 1U : 0U;
}

/*
 * lm_tree_set where the whole path to `slot` is already private to the map
 * (every node present, reference count 1), the common case once a map has
 * been written since it was last shared: one walk instead of three
 * (set_needs, private_path, mark_path), the same effect on the pools and
 * the boxes. Returns 0, having changed nothing, where the path is not
 * private or the pool has no leaf for an empty or shared slot; the caller
 * then takes the general path.
 */
static int set_private(lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t slot, const landmark_t *lm)
{
    lm_tree_idx_t path[LM_TREE_DEPTH];
    lm_tree_idx_t n = root;
    for (int l = 0; l < D_; ++l) {
        if (n == LM_TREE_NIL || p->node[n].ref != 1U) {
            return 0;
        }
        path[l] = n;
        n = p->node[n].child[digit(slot, l)];
    }
    lm_tree_idx_t *link = &p->node[path[D_ - 1]].child[digit(slot, D_ - 1)];
    if (*link != LM_TREE_NIL && p->leaf_ref[*link] == 1U) {
        p->leaf[*link].lm = *lm;
    } else {
        if (p->leaves_live >= p->leaf_limit) {
            return 0; /* the general path counts the refusal */
        }
        const lm_tree_idx_t c = leaf_alloc(p);
        COSLAM_ASSERT(c != LM_TREE_NIL);
        p->leaf[c].lm = *lm;
        if (*link != LM_TREE_NIL) {
            leaf_unref(p, *link);
        }
        *link = c;
    }
    mark_path(p, path);
    return 1;
}

/* lm_tree_set for any path (slot in range). */
static coslam_status_t set_general(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot, const landmark_t *lm)
{
    lm_tree_idx_t path[LM_TREE_DEPTH];
    /* all or nothing: a set the pools cannot finish changes no node (it
     * would otherwise leave the empty nodes it had made in the map) */
    uint32_t need_nodes;
    uint32_t need_leaves;
    set_needs(p, *root, slot, &need_nodes, &need_leaves);
    if (need_nodes > p->node_limit - p->nodes_live || need_leaves > p->leaf_limit - p->leaves_live) {
        p->capacity_drops++;
        return COSLAM_E_CAPACITY;
    }
    lm_tree_idx_t *link = private_path(p, root, slot, 1, path);
    if (link == 0) {
        return COSLAM_E_CAPACITY; /* not reached: the pools hold what set_needs counted */
    }
    if (*link != LM_TREE_NIL && p->leaf_ref[*link] == 1U) {
        p->leaf[*link].lm = *lm;
    } else {
        const lm_tree_idx_t c = leaf_alloc(p);
        if (c == LM_TREE_NIL) {
            return COSLAM_E_CAPACITY; /* not reached, as above */
        }
        p->leaf[c].lm = *lm;
        if (*link != LM_TREE_NIL) {
            leaf_unref(p, *link);
        }
        *link = c;
    }
    mark_path(p, path);
    return COSLAM_OK;
}

coslam_status_t lm_tree_set(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot, const landmark_t *lm)
{
    if (slot >= (uint32_t)COSLAM_MAX_LANDMARKS) {
        return COSLAM_E_ARG;
    }
    if (set_private(p, *root, slot, lm)) {
        return COSLAM_OK;
    }
    return set_general(p, root, slot, lm);
}

/* Empty the leaf link of a private path and free the nodes left empty. */
static void clear_private(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot, lm_tree_idx_t *link,
                          const lm_tree_idx_t path[LM_TREE_DEPTH])
{
    leaf_unref(p, *link);
    *link = LM_TREE_NIL;
    for (int l = D_ - 1; l >= 0; --l) {
        const lm_tree_node_t *nd = &p->node[path[l]];
        int empty = 1;
        for (uint32_t c = 0; c < F_ && empty; ++c) {
            empty = nd->child[c] == LM_TREE_NIL;
        }
        if (!empty) {
            /* this node and those above stay: their boxes are stale */
            for (int u = l; u >= 0; --u) {
                p->node[path[u]].dirty = 1U;
            }
            return;
        }
        node_free(p, path[l]);
        if (l == 0) {
            *root = LM_TREE_NIL;
        } else {
            p->node[path[l - 1]].child[digit(slot, l - 1)] = LM_TREE_NIL;
        }
    }
}

coslam_status_t lm_tree_clear(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t slot)
{
    if (lm_tree_get(p, *root, slot) == 0) {
        return COSLAM_OK;
    }
    lm_tree_idx_t path[LM_TREE_DEPTH];
    lm_tree_idx_t *link = private_path(p, root, slot, 0, path);
    if (link == 0) {
        return COSLAM_E_CAPACITY;
    }
    clear_private(p, root, slot, link, path);
    return COSLAM_OK;
}

coslam_status_t lm_tree_move(lm_tree_pool_t *p, lm_tree_idx_t *root, uint32_t dst, uint32_t src)
{
    COSLAM_ASSERT(dst != src);
    lm_tree_idx_t pd[LM_TREE_DEPTH];
    lm_tree_idx_t ps[LM_TREE_DEPTH];
    lm_tree_idx_t *ld = private_path(p, root, dst, 0, pd);
    if (ld == 0) {
        return COSLAM_E_CAPACITY;
    }
    lm_tree_idx_t *ls = private_path(p, root, src, 0, ps);
    if (ls == 0) {
        return COSLAM_E_CAPACITY; /* dst's path is private now: same content */
    }
    COSLAM_ASSERT(*ld != LM_TREE_NIL && *ls != LM_TREE_NIL);
    const lm_tree_idx_t moved = *ls;
    COSLAM_ASSERT(p->leaf_ref[moved] < LM_TREE_LEAF_REF_MAX);
    p->leaf_ref[moved]++;
    leaf_unref(p, *ld);
    *ld = moved;
    clear_private(p, root, src, ls, ps);
    mark_path(p, pd);
    return COSLAM_OK;
}

void lm_tree_retain(lm_tree_pool_t *p, lm_tree_idx_t root)
{
    if (root != LM_TREE_NIL) {
        COSLAM_ASSERT(p->node[root].ref < UINT16_MAX);
        p->node[root].ref++;
    }
}

void lm_tree_release(lm_tree_pool_t *p, lm_tree_idx_t *root)
{
    /* depth-first with an explicit stack: each freed node replaces itself by
     * at most F children, so the stack never exceeds 1 + D (F - 1) */
    lm_tree_idx_t stack[LM_TREE_STACK];
    uint8_t level[LM_TREE_STACK];
    int sp = 0;
    if (*root != LM_TREE_NIL) {
        stack[sp] = *root;
        level[sp++] = 0U;
    }
    *root = LM_TREE_NIL;
    while (sp > 0) {
        --sp;
        const lm_tree_idx_t n = stack[sp];
        const int l = level[sp];
        if (l == D_) {
            leaf_unref(p, n);
            continue;
        }
        COSLAM_ASSERT(p->node[n].ref > 0U);
        if (--p->node[n].ref != 0U) {
            continue;
        }
        for (uint32_t c = F_; c-- > 0U;) {
            const lm_tree_idx_t ch = p->node[n].child[c];
            if (ch != LM_TREE_NIL) {
                COSLAM_ASSERT(sp < (int)LM_TREE_STACK);
                stack[sp] = ch;
                level[sp++] = (uint8_t)(l + 1);
            }
        }
        p->node[n].ref = 1U; /* node_free expects a live node */
        node_free(p, n);
    }
}

/* lm_tree_query's test: ctx = {x, y, max_range^2}. */
static int box_in_reach(const float box[4], void *ctx)
{
    const double *q = (const double *)ctx;
    return box_dist2(box, q[0], q[1]) > q[2] ? LM_TREE_BOX_NONE : LM_TREE_BOX_SOME;
}

/* The slot-order traversal of every reader: `test` (NULL: none) is asked
 * about each node's box where the box is clean (a stale one may no longer
 * enclose what is below) and not below an LM_TREE_BOX_ALL answer; a
 * subtree it answers LM_TREE_BOX_NONE is skipped. all_out (may be NULL)
 * flags the landmarks taken under an LM_TREE_BOX_ALL answer. Inline, so
 * that each reader's constant test is inlined into its copy. */
static inline uint32_t walk(const lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t n_slots, lm_tree_box_fn test,
                            void *ctx, const landmark_t **out, uint16_t *slot_out, uint8_t *all_out)
{
    if (root == LM_TREE_NIL || n_slots == 0U) {
        return 0U;
    }
    uint8_t all[LM_TREE_DEPTH] = {0U}; /* all of it: gcc (arm, -O2) cannot see each level set before read */
    if (test != 0 && !p->node[root].dirty) {
        const int a = test(p->node[root].box, ctx);
        if (a == LM_TREE_BOX_NONE) {
            return 0U;
        }
        all[0] = a == LM_TREE_BOX_ALL ? 1U : 0U;
    }
    lm_tree_idx_t cur[LM_TREE_DEPTH];
    uint32_t pos[LM_TREE_DEPTH];
    uint32_t base[LM_TREE_DEPTH];
    uint32_t n = 0U;
    int l = 0;
    cur[0] = root;
    pos[0] = 0U;
    base[0] = 0U;
    while (l >= 0) {
        if (pos[l] == F_) {
            --l;
            continue;
        }
        const uint32_t q = pos[l]++;
        const uint32_t first = base[l] + (q << (LM_TREE_FANOUT_LOG2 * (unsigned)(D_ - 1 - l)));
        if (first >= n_slots) {
            pos[l] = F_; /* slots are dense: nothing further right */
            continue;
        }
        const lm_tree_idx_t ch = p->node[cur[l]].child[q];
        if (ch == LM_TREE_NIL) {
            continue;
        }
        if (l == D_ - 1) {
            out[n] = &p->leaf[ch].lm;
            if (slot_out != 0) {
                slot_out[n] = (uint16_t)first;
            }
            if (all_out != 0) {
                all_out[n] = all[l];
            }
            ++n;
            continue;
        }
        uint8_t below = all[l];
        if (test != 0 && !below && !p->node[ch].dirty) {
            const int a = test(p->node[ch].box, ctx);
            if (a == LM_TREE_BOX_NONE) {
                continue;
            }
            below = a == LM_TREE_BOX_ALL ? 1U : 0U;
        }
        ++l;
        cur[l] = ch;
        pos[l] = 0U;
        base[l] = first;
        all[l] = below;
    }
    return n;
}

uint32_t lm_tree_query(lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t n_slots, double x, double y,
                       double max_range_m, const landmark_t **out, uint16_t *slot_out)
{
    lm_tree_clean(p, root);
    const double r = max_range_m < 0.0 ? 0.0 : max_range_m;
    double q[3] = {x, y, r * r};
    return walk(p, root, n_slots, box_in_reach, q, out, slot_out, 0);
}

uint32_t lm_tree_gather(const lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t n_slots, const landmark_t **out,
                        uint16_t *slot_out)
{
    return walk(p, root, n_slots, 0, 0, out, slot_out, 0);
}

uint32_t lm_tree_select(const lm_tree_pool_t *p, lm_tree_idx_t root, uint32_t n_slots, lm_tree_box_fn may_hold,
                        void *ctx, const landmark_t **out, uint16_t *slot_out, uint8_t *all_out)
{
    return walk(p, root, n_slots, may_hold, ctx, out, slot_out, all_out);
}
