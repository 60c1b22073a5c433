/* Compressed EKF (ekfslam_config_t.active_radius_m) against the full EKF:
 * both run side by side on the same seeded synthetic inputs (known
 * identities: unique signatures, so both associate alike); after every
 * global update, and at forced ones (export), x and P must agree to 1e-9
 * relative. Between global updates the readers of passive entries
 * (ekfslam_landmark, ekfslam_p) must give the full EKF's values, including
 * the cross-covariances of landmarks added in the local phase with the
 * passive part (P_mB = G_r phi_r P_A0B). With the global update spread
 * over later steps (active_spread_madds > 0, small budgets here so that
 * entries stay pending for several frames, two generations of them at
 * once, and some completions are forced), every third global update is
 * compared whole after ekfslam_sync (which completes the pending entries);
 * at the others and every third frame with entries pending the whole state
 * is compared through a synced copy, and through the readers (which add
 * the pending corrections) a sample of the landmarks' means and 2x2
 * blocks, of the active rows (P_AA, and P_AB from the stored P_A0B and its
 * pending entries) and of each generation's pending entries; exports and
 * merges while entries are pending, a backlog that fills every generation
 * (the oldest completed at once) and removals that move flagged rows are
 * covered too. Needs COSLAM_EKF_MAX_ACTIVE > 0: built against the large
 * profile. */
#include "test_util.h"

#include <stdlib.h>
#include <string.h>

#include "coslam/ekfslam.h"
#include "eval_worlds.h"
#include "synth.h"

static ekfslam_t g_full;
static ekfslam_t g_cekf;
static synth_world_t g_world;
static map_estimate_t g_map;

#define REL_TOL 1e-9

typedef struct {
    int global_updates;   /* comparisons after a global update */
    int forced;           /* comparisons after an export */
    int local_updates;    /* updates run in a local phase */
    int local_adds;       /* landmarks added inside a local phase */
    int local_removals;   /* removals decided in a local phase (dead until it ends) */
    int dead_checks;      /* comparisons while the compressed EKF held dead landmarks */
    int passive_checks;   /* passive entries read between global updates */
    int new_passive;      /* ... of those, new landmark x passive landmark */
    int pending_checks;   /* comparisons without sync while rows were pending */
    int pending_entries;  /* ... pending entries read through ekfslam_p */
    int two_gens;         /* ... with two generations pending */
    int deferred;         /* updates that left their share of the completion to the next predict */
    int active_pending;   /* ... in a local phase with pending P_A'B' entries */
    int forced_pending;   /* exports or merges while entries were pending */
    int wide;             /* local updates with more pairings than one pass takes (EKFSLAM_BATCH) */
    uint32_t step_rows;   /* deferred rows completed inside predicts and updates */
    uint32_t idle_rows;   /* ... in ekfslam_idle between them (run_pair's `idle`) */
    uint32_t idle_globals; /* local phases ended (and the next started) in ekfslam_idle */
    double worst;         /* largest relative difference seen */
} tally_t;

static double scale_of(const ekfslam_t *e)
{
    const int d = 3 + 2 * e->n_lm;
    double s = 0.0;
    for (int r = 0; r < d; ++r) {
        const double v = fabs(e->p[(long)r * EKFSLAM_DIM + r]);
        s = v > s ? v : s;
    }
    return s;
}

/* Landmark j of the compressed EKF (b) in the full EKF (a): the one with
 * its identity, -1 if j is dead. The full EKF takes a removed landmark out
 * at once, its last one moving into the place; the compressed EKF keeps it,
 * dead, until its local phase ends (ekfslam.c "Removal in a local phase"):
 * the same landmarks, in another order after a removal. */
static int g_to_a[COSLAM_EKF_MAX_LANDMARKS];

static void map_landmarks(const ekfslam_t *a, const ekfslam_t *b)
{
    assert_int_equal(a->n_lm, ekfslam_n_landmarks(b));
    int dead = 0;
    for (uint16_t j = 0; j < b->n_lm; ++j) {
        g_to_a[j] = -1;
        if (!ekfslam_landmark_live(b, j)) {
            dead++;
            continue;
        }
        if (j < a->n_lm && a->meta[j].id == b->meta[j].id) {
            g_to_a[j] = j; /* no removal since this one came */
            continue;
        }
        for (uint16_t k = 0; k < a->n_lm && g_to_a[j] < 0; ++k) {
            if (a->meta[k].id == b->meta[j].id) {
                g_to_a[j] = k;
            }
        }
        ASSERT_TRUE_MSG(g_to_a[j] >= 0, "landmark %u (id %u) not in the full EKF\n", j, (unsigned)b->meta[j].id);
    }
    assert_int_equal(dead, b->n_dead);
}

/* State r of b (map_landmarks) in a, -1 for a dead landmark's. */
static int a_row(int r)
{
    if (r < 3) {
        return r;
    }
    const int k = g_to_a[(r - 3) / 2];
    return k < 0 ? -1 : 3 + 2 * k + ((r - 3) & 1);
}

/* whole state (both synced): x and P entry by entry, landmarks matched by
 * identity (map_landmarks) */
static void compare_all(const ekfslam_t *a, const ekfslam_t *b, tally_t *t)
{
    assert_int_equal(a->n_lm, b->n_lm);
    map_landmarks(a, b);
    const int d = 3 + 2 * a->n_lm;
    const double ps = scale_of(a);
    for (int r = 0; r < d; ++r) {
        const int ra = a_row(r);
        const double dx = fabs(a->x[ra] - b->x[r]) / fmax(1.0, fabs(a->x[ra]));
        ASSERT_TRUE_MSG(dx <= REL_TOL, "x[%d]: %.15g vs %.15g\n", r, a->x[ra], b->x[r]);
        t->worst = fmax(t->worst, dx);
        for (int c = 0; c < d; ++c) {
            const double pa = a->p[(long)ra * EKFSLAM_DIM + a_row(c)];
            const double pb = b->p[(long)r * EKFSLAM_DIM + c];
            const double dp = fabs(pa - pb) / ps;
            ASSERT_TRUE_MSG(dp <= REL_TOL, "P(%d,%d): %.15g vs %.15g (scale %.3g)\n", r, c, pa, pb, ps);
            t->worst = fmax(t->worst, dp);
        }
    }
}

/* landmark j of the compressed EKF, through the readers, against the full
 * EKF's (after map_landmarks; a dead one is skipped) */
static void compare_landmark(const ekfslam_t *full, const ekfslam_t *ce, uint16_t j, double ps)
{
    if (g_to_a[j] < 0) {
        return;
    }
    point2_t mf, mc;
    cov2_t cf, cc;
    ekfslam_landmark(full, (uint16_t)g_to_a[j], &mf, &cf);
    ekfslam_landmark(ce, j, &mc, &cc);
    ASSERT_NEAR(mc.x, mf.x, REL_TOL * fmax(1.0, fabs(mf.x)));
    ASSERT_NEAR(mc.y, mf.y, REL_TOL * fmax(1.0, fabs(mf.y)));
    ASSERT_NEAR(cc.xx, cf.xx, REL_TOL * ps);
    ASSERT_NEAR(cc.xy, cf.xy, REL_TOL * ps);
    ASSERT_NEAR(cc.yy, cf.yy, REL_TOL * ps);
}

/* in a local phase: passive landmarks through the public readers */
static void compare_passive(const ekfslam_t *full, const ekfslam_t *ce, tally_t *t)
{
    const ekfslam_cekf_t *ck = &ce->cekf;
    map_landmarks(full, ce);
    t->dead_checks += ce->n_dead > 0U;
    const double ps = scale_of(full);
    int passive = -1;
    for (uint16_t j = 0; j < ce->n_lm; ++j) {
        if (ck->slot[j] >= 0 || g_to_a[j] < 0) {
            continue;
        }
        passive = j;
        compare_landmark(full, ce, j, ps);
        /* pose-landmark and a few landmark-landmark cross terms */
        const int a = 3 + 2 * j;
        for (int r = 0; r < 3 + 2 * ce->n_lm; r += 7) {
            if (a_row(r) >= 0) {
                ASSERT_NEAR(ekfslam_p(ce, r, a + 1), ekfslam_p(full, a_row(r), a_row(a + 1)), REL_TOL * ps);
            }
        }
        t->passive_checks++;
    }
    if (passive < 0) {
        return;
    }
    /* landmarks added in this phase (active rows beyond A0) against a passive one */
    const int a = 3 + 2 * passive;
    for (int k = ck->na0; k < ck->na; ++k) {
        const int r = a_row(ck->idx[k]);
        if (r < 0) {
            continue;
        }
        ASSERT_NEAR(ekfslam_p(ce, ck->idx[k], a), ekfslam_p(full, r, a_row(a)), REL_TOL * ps);
        ASSERT_NEAR(ekfslam_p(ce, a + 1, ck->idx[k]), ekfslam_p(full, a_row(a + 1), r), REL_TOL * ps);
        t->new_passive++;
    }
}

/* Landmarks flagged in some generation of pending entries, and whether
 * landmark j is one of them. */
static int n_flagged(const ekfslam_t *e)
{
    int n = 0;
    for (int g = 0; g < EKFSLAM_PEND_GENS; ++g) {
        n += e->cekf.gen[g].n;
    }
    return n;
}

static int flagged(const ekfslam_t *e, int j)
{
    int f = 0;
    for (int g = 0; g < EKFSLAM_PEND_GENS; ++g) {
        f |= e->cekf.gen[g].flag[j] != 0U;
    }
    return f;
}

/* Generations with pending entries. */
static int gens_busy(const ekfslam_t *e)
{
    int n = 0;
    for (int g = 0; g < EKFSLAM_PEND_GENS; ++g) {
        n += e->cekf.gen[g].n > 0;
    }
    return n;
}

/* In a local phase: active landmarks with pending entries (P_A'B'). */
static int active_flagged(const ekfslam_t *e)
{
    int n = 0;
    for (uint16_t j = 0; e->cekf.local && j < e->n_lm; ++j) {
        n += e->cekf.slot[j] >= 0 && flagged(e, j);
    }
    return n;
}

/* Landmark j's flag in the youngest generation with pending entries. */
static uint8_t newest_flag(const ekfslam_t *e, int j)
{
    int best = -1;
    for (int g = 0; g < EKFSLAM_PEND_GENS; ++g) {
        if (e->cekf.gen[g].n > 0 && (best < 0 || e->cekf.gen[g].seq > e->cekf.gen[best].seq)) {
            best = g;
        }
    }
    return best < 0 ? 0U : e->cekf.gen[best].flag[j];
}

static ekfslam_t g_copy;

/* With entries pending (no sync): the whole state through a synced copy
 * (ekfslam_sync completes every pending entry and ends the phase), and
 * through the readers, which add the pending corrections, a sample of the
 * landmarks' means and 2x2 blocks, of the active rows (P_AA stored, P_AB
 * from the stored P_A0B and its pending entries) and of the pending
 * entries of each generation. */
static void compare_final(const ekfslam_t *full, const ekfslam_t *ce, tally_t *t)
{
    const ekfslam_cekf_t *ck = &ce->cekf;
    map_landmarks(full, ce);
    t->dead_checks += ce->n_dead > 0U;
    const int d = 3 + 2 * ce->n_lm;
    const double ps = scale_of(full);
    for (uint16_t j = (uint16_t)(t->pending_checks % 3); j < ce->n_lm; j = (uint16_t)(j + 3)) {
        compare_landmark(full, ce, j, ps);
    }
    for (int k = t->pending_checks % 4; k < (ck->local ? ck->na : 3); k += 4) {
        const int r = ck->idx[k];
        for (int c = t->pending_checks % 5; c < d; c += 5) {
            if (a_row(r) < 0 || a_row(c) < 0) {
                continue; /* a dead landmark's */
            }
            const double pf = full->p[(long)a_row(r) * EKFSLAM_DIM + a_row(c)];
            const double pc = ekfslam_p(ce, r, c);
            ASSERT_TRUE_MSG(fabs(pc - pf) <= REL_TOL * ps, "P(%d,%d): %.15g vs %.15g (%d flagged)\n", r, c, pc, pf,
                            n_flagged(ce));
        }
    }
    for (int g = 0; g < EKFSLAM_PEND_GENS; ++g) {
        const ekfslam_pend_t *gen = &ck->gen[g];
        for (int t1 = 0; t1 < gen->n; t1 += 5) {
            for (int t2 = t1 + 1; t2 < gen->n; t2 += 11) {
                const int r = 3 + 2 * gen->list[t1];
                const int c = 4 + 2 * gen->list[t2];
                if (a_row(r) < 0 || a_row(c) < 0) {
                    continue;
                }
                ASSERT_NEAR(ekfslam_p(ce, r, c), full->p[(long)a_row(r) * EKFSLAM_DIM + a_row(c)], REL_TOL * ps);
                t->pending_entries++;
            }
        }
    }
    g_copy = *ce;
    ekfslam_sync(&g_copy);
    assert_int_equal(n_flagged(&g_copy), 0);
    compare_all(full, &g_copy, t);
    t->pending_checks++;
    t->two_gens += gens_busy(ce) > 1;
    t->active_pending += active_flagged(ce) > 0;
}

/* ekfslam_idle after every predict and update of the compressed EKF, as
 * the robot calls it (slam_filter_idle's shares), when `idle_shares` > 0 */
static int g_idle_shares;

static void idle_after(tally_t *t)
{
    if (g_idle_shares > 0) {
        const uint32_t rows = g_cekf.ctr.cekf_spread_rows;
        const uint32_t globals = g_cekf.ctr.cekf_global_updates;
        ekfslam_idle(&g_cekf, (uint32_t)g_idle_shares);
        t->idle_rows += g_cekf.ctr.cekf_spread_rows - rows;
        t->idle_globals += g_cekf.ctr.cekf_global_updates - globals;
        /* ahead by at most two shares, and a row's worth of overshoot */
        assert_true(g_cekf.cekf.spread_owed <= 0.0);
    }
}

static void run_pair(const synth_config_t *sc, ekfslam_config_t cfg, double radius_m, int export_every, tally_t *t)
{
    memset(t, 0, sizeof *t);
    const pose2_t start = synth_start_pose(sc);
    cfg.active_radius_m = 0.0;
    assert_int_equal(ekfslam_init(&g_full, &cfg, start), COSLAM_OK);
    cfg.active_radius_m = radius_m;
    cfg.active_min_landmarks = 16U;
    assert_int_equal(ekfslam_init(&g_cekf, &cfg, start), COSLAM_OK);
    synth_init(&g_world, sc);
    synth_step_t st;
    int step = 0;
    while (synth_next(&g_world, &st)) {
        ++step;
        uint32_t rows = g_cekf.ctr.cekf_spread_rows;
        assert_int_equal(ekfslam_predict(&g_full, st.u), ekfslam_predict(&g_cekf, st.u));
        t->step_rows += g_cekf.ctr.cekf_spread_rows - rows;
        /* a predict pays what updates left (less what idle time paid ahead) */
        assert_true(g_idle_shares > 0 ? g_cekf.cekf.spread_owed <= 0.0 : g_cekf.cekf.spread_owed == 0.0);
        idle_after(t);
        if (!st.is_frame) {
            continue;
        }
        const uint32_t globals = g_cekf.ctr.cekf_global_updates;
        const uint32_t removed = g_cekf.ctr.removals_deferred;
        const uint16_t n_before = g_cekf.n_lm;
        const uint32_t added = g_cekf.ctr.landmarks_added;
        const int was_local = g_cekf.cekf.local;
        rows = g_cekf.ctr.cekf_spread_rows;
        assert_int_equal(ekfslam_update(&g_full, st.z, st.n_z), ekfslam_update(&g_cekf, st.z, st.n_z));
        t->step_rows += g_cekf.ctr.cekf_spread_rows - rows;
        /* unique signatures: a sighting pairs or starts a landmark */
        if (was_local && g_cekf.cekf.local && st.n_z - (int)(g_cekf.ctr.landmarks_added - added) > EKFSLAM_BATCH) {
            t->wide++;
        }
        assert_int_equal(g_full.n_lm, ekfslam_n_landmarks(&g_cekf));
        assert_int_equal(g_full.ctr.landmarks_removed, g_cekf.ctr.landmarks_removed);
        if (g_cekf.cekf.spread_owed > 0.0) {
            t->deferred++; /* its pairings took its share: the next predict completes it */
        }
        idle_after(t);
        if (g_cekf.cekf.local) {
            t->local_updates++;
            if (g_cekf.ctr.cekf_global_updates == globals && g_cekf.n_lm > n_before) {
                t->local_adds++;
            }
        }
        if (g_cekf.ctr.removals_deferred > removed) {
            t->local_removals++;
        }
        if (g_cekf.cekf.local && step % 20 == 0) {
            compare_passive(&g_full, &g_cekf, t);
        }
        if (g_cekf.ctr.cekf_global_updates > globals &&
            (cfg.active_spread_madds == 0U || t->global_updates % 3 == 0 || n_flagged(&g_cekf) == 0)) {
            /* the update itself may have started the next phase: compare
             * through a sync of that one (also exact; it completes the
             * pending rows too) */
            ekfslam_sync(&g_cekf);
            assert_int_equal(n_flagged(&g_cekf), 0);
            compare_all(&g_full, &g_cekf, t);
            t->global_updates++;
        } else if (n_flagged(&g_cekf) > 0) {
            if (export_every > 0 && (t->pending_checks + t->forced_pending) % 9 == 8) {
                /* what reads the whole state completes the pending entries */
                if (t->forced_pending % 2 == 0) {
                    (void)ekfslam_export(&g_full, &g_map);
                    (void)ekfslam_export(&g_cekf, &g_map);
                } else {
                    assert_int_equal(ekfslam_merge_begin(&g_full, NULL), COSLAM_OK);
                    assert_int_equal(ekfslam_merge_begin(&g_cekf, NULL), COSLAM_OK);
                    ekfslam_merge_end(&g_full);
                    ekfslam_merge_end(&g_cekf);
                }
                assert_int_equal(n_flagged(&g_cekf), 0);
                assert_int_equal(g_cekf.cekf.local, 0);
                compare_all(&g_full, &g_cekf, t);
                t->forced_pending++;
            } else if (g_cekf.ctr.cekf_global_updates > globals) {
                t->global_updates++;
                compare_final(&g_full, &g_cekf, t);
            } else if (step % 3 == 0) {
                compare_final(&g_full, &g_cekf, t);
            }
        } else if (export_every > 0 && g_cekf.cekf.local && step % export_every == 0) {
            (void)ekfslam_export(&g_full, &g_map);
            (void)ekfslam_export(&g_cekf, &g_map);
            assert_int_equal(g_cekf.cekf.local, 0);
            compare_all(&g_full, &g_cekf, t);
            t->forced++;
        }
    }
    ekfslam_sync(&g_cekf);
    compare_all(&g_full, &g_cekf, t);
    print_message("cekf: %d global updates, %d forced, %d local updates (%d of more than %d pairings), %d local "
                  "adds, %d removals (%d checks with dead landmarks), %d passive "
                  "reads (%d new x passive), %d checks with entries pending (%d with two generations, %d with active ones; "
                  "%d pending entries; %u rows spread, %u completions forced, %d exports/merges while pending), %d "
                  "landmarks, worst rel diff %.2g\n",
                  t->global_updates, t->forced, t->local_updates, t->wide, EKFSLAM_BATCH, t->local_adds, t->local_removals, t->dead_checks, t->passive_checks,
                  t->new_passive, t->pending_checks, t->two_gens, t->active_pending, t->pending_entries,
                  g_cekf.ctr.cekf_spread_rows,
                  g_cekf.ctr.cekf_spread_forced, t->forced_pending, g_cekf.n_lm, t->worst);
}

static synth_config_t world(uint64_t seed)
{
    synth_config_t sc = synth_config_default(seed, 240);
    sc.n_signatures = 0; /* unique: the association is known */
    sc.loop_radius_m = 8.0;
    sc.ring_half_width_m = 2.5;
    sc.loops = 1.1; /* a loop closure too */
    return sc;
}

/* JCBB, FEJ: the defaults */
/* The defaults with the world's model and a small completion budget: a
 * few landmark rows per step */
static ekfslam_config_t spread_config(const synth_config_t *sc)
{
    ekfslam_config_t cfg = ekfslam_config_default();
    cfg.slam = sc->truth;
    cfg.active_spread_madds = 60000U;
    return cfg;
}

static void test_exact_default(void **state)
{
    (void)state;
    const synth_config_t sc = world(101U);
    tally_t t;
    run_pair(&sc, spread_config(&sc), 1.0, 70, &t);
    /* the run must exercise what it claims to test */
    assert_true(t.global_updates >= 5);
    assert_true(t.forced >= 3);
    assert_true(t.local_updates > 100);
    assert_true(t.wide > 20); /* frames whose pairings take more than one pass */
    assert_true(t.local_adds >= 5);
    assert_true(t.passive_checks > 100);
    assert_true(t.new_passive > 10);
    assert_true(t.pending_checks > 50);
    assert_true(t.pending_entries > 1000);
    assert_true(t.two_gens > 5);       /* a global update while the last one's entries were pending */
    assert_true(t.active_pending > 20); /* P_A'B' pending in a local phase */
    assert_true(t.forced_pending >= 4); /* exports and merges completing them */
    assert_true(g_cekf.ctr.cekf_spread_rows > 500U);
    assert_true(g_cekf.ctr.cekf_spread_forced >= 3U);
    assert_true(t.deferred > 50);
    assert_true(g_cekf.n_lm >= 150);
}

/* Idle time (ekfslam_idle after every predict and update, with
 * slam_filter_idle's shares): the region switches there, and the deferred
 * completion; still exact against the full EKF through every check of
 * run_pair (through synced copies while entries are pending, and at the
 * exports), the steps themselves complete almost none of it, and the
 * regions change in idle time, not in the updates. */
static void test_exact_idle(void **state)
{
    (void)state;
    const synth_config_t sc = world(101U);
    tally_t t;
    g_idle_shares = 4;
    run_pair(&sc, spread_config(&sc), 1.0, 70, &t);
    g_idle_shares = 0;
    print_message("cekf idle: %u rows completed in idle time, %u in the steps; %u regions left in idle time, %d "
                  "in updates\n",
                  t.idle_rows, t.step_rows, t.idle_globals, t.global_updates);
    assert_true(t.idle_globals >= 10U);
    assert_true((uint32_t)t.global_updates * 5U < t.idle_globals);
    assert_true(t.pending_checks > 20);
    assert_true(t.forced >= 3);
    assert_true(t.idle_rows > 500U);
    assert_true(t.step_rows * 10U < t.idle_rows);
}

/* the w5 runs' filter: NN, no FEJ, landmark process noise */
static ekfslam_config_t w5_config(const synth_config_t *sc)
{
    ekfslam_config_t cfg = ekfslam_config_default();
    cfg.slam = sc->truth;
    cfg.slam.noise.lm_process_var_m2_per_m = 1e-4;
    cfg.assoc = EKFSLAM_ASSOC_NN;
    cfg.fej = 0U;
    return cfg;
}

/* world 7 with clutter, half a loop: tentative landmarks die (test_exact_w5_clutter, test_dead_make_room) */
static synth_config_t clutter_world(void)
{
    synth_config_t sc = world(7U);
    sc.clutter_per_frame = 0.5;
    sc.loops = 0.5;
    return sc;
}

/* NN, no FEJ, landmark process noise (w5 reaches the passive part through
 * w5_sum), clutter (tentative landmarks die in local phases: dead until the
 * phase ends, and the readers checked while they are; then out, the
 * pending rows moving with the swap) */
static void test_exact_w5_clutter(void **state)
{
    (void)state;
    const synth_config_t sc = clutter_world();
    ekfslam_config_t cfg = w5_config(&sc);
    tally_t t;
    run_pair(&sc, cfg, 1.5, 0, &t);
    assert_true(t.global_updates >= 3);
    assert_true(t.local_updates > 50);
    assert_true(t.local_removals >= 20);
    assert_true(t.dead_checks >= 10);
    /* a removal does not end the phase (when it did: 132 global updates
     * for 132 removals, 262 local updates) */
    assert_true(t.global_updates * 3 < t.local_removals);
    assert_true(t.passive_checks > 50);
}

/* The same without clutter, the global update spread: w5_sum reaches the
 * landmarks' 2x2 blocks at once, the rest of P_BB later. */
static void test_exact_w5_spread(void **state)
{
    (void)state;
    synth_config_t sc = world(7U);
    sc.loops = 0.5;
    ekfslam_config_t cfg = w5_config(&sc);
    cfg.active_spread_madds = 20000U;
    tally_t t;
    run_pair(&sc, cfg, 1.5, 0, &t);
    assert_true(t.global_updates >= 3);
    assert_true(t.local_updates > 50);
    assert_true(t.pending_checks > 10);
    assert_true(g_cekf.ctr.cekf_spread_rows > 100U);
}

/* A backlog: about one landmark row per step, so that global updates come
 * while both generations are pending and the oldest must be completed at
 * once. */
static void test_exact_backlog(void **state)
{
    (void)state;
    const synth_config_t sc = world(101U);
    ekfslam_config_t cfg = ekfslam_config_default();
    cfg.slam = sc.truth;
    cfg.active_spread_madds = 1U;
    tally_t t;
    run_pair(&sc, cfg, 0.7, 0, &t);
    print_message("cekf backlog: %u global updates with every generation pending\n", g_cekf.ctr.cekf_spread_gens_full);
    assert_true(t.two_gens > 10);
    assert_true(t.active_pending > 20);
    assert_true(g_cekf.ctr.cekf_spread_gens_full >= 3U);
}

/* Landmark j of the compressed EKF out of both filters (the full EKF's
 * with the same identity; none if j is dead, which the full EKF removed
 * already). */
static void remove_both(uint16_t j)
{
    if (ekfslam_landmark_live(&g_cekf, j)) {
        uint16_t k = 0;
        while (k < g_full.n_lm && g_full.meta[k].id != g_cekf.meta[j].id) {
            ++k;
        }
        assert_true(k < g_full.n_lm);
        ekfslam_remove_landmark(&g_full, k);
    }
    ekfslam_remove_landmark(&g_cekf, j);
}

/* Removals while rows are pending, white box: a removal from outside in a
 * local phase ends it as the periodic global update does (the filter's
 * own dead landmarks go with it), and the last landmark's pending rows
 * must move with it into the removed one's place. */
static void test_removal_moves_pending(void **state)
{
    (void)state;
    const synth_config_t sc = world(101U);
    ekfslam_config_t cfg = ekfslam_config_default();
    cfg.slam = sc.truth;
    cfg.active_spread_madds = 60000U;
    const pose2_t start = synth_start_pose(&sc);
    cfg.active_radius_m = 0.0;
    assert_int_equal(ekfslam_init(&g_full, &cfg, start), COSLAM_OK);
    cfg.active_radius_m = 1.0;
    cfg.active_min_landmarks = 16U;
    assert_int_equal(ekfslam_init(&g_cekf, &cfg, start), COSLAM_OK);
    synth_init(&g_world, &sc);
    synth_step_t st;
    int step = 0;
    while (synth_next(&g_world, &st)) {
        ++step;
        (void)ekfslam_predict(&g_full, st.u);
        (void)ekfslam_predict(&g_cekf, st.u);
        if (st.is_frame) {
            (void)ekfslam_update(&g_full, st.z, st.n_z);
            (void)ekfslam_update(&g_cekf, st.z, st.n_z);
        }
        if (step > 600 && g_cekf.cekf.local && n_flagged(&g_cekf) > 20) {
            break;
        }
    }
    const ekfslam_cekf_t *ck = &g_cekf.cekf;
    assert_true(ck->local && n_flagged(&g_cekf) > 20);
    tally_t t;
    memset(&t, 0, sizeof t);
    /* the first removal ends the phase; remove from the end until the last
     * landmark is pending */
    int removed = 0;
    do {
        remove_both((uint16_t)(g_cekf.n_lm - 1));
        removed++;
    } while (g_cekf.n_lm > 0 && !flagged(&g_cekf, g_cekf.n_lm - 1));
    assert_false(ck->local);
    assert_int_equal(g_cekf.n_dead, 0);
    assert_true(n_flagged(&g_cekf) > 20);
    compare_final(&g_full, &g_cekf, &t);
    /* a landmark flagged B, then one flagged A (active in the phase the
     * removal ended), the last (flagged) moving into their places; then
     * one not flagged if any */
    for (uint8_t f = EKFSLAM_PEND_B; f <= EKFSLAM_PEND_A; ++f) {
        uint16_t j = 0;
        while (j < g_cekf.n_lm - 1 && newest_flag(&g_cekf, j) != f) {
            ++j;
        }
        assert_true(j < g_cekf.n_lm - 1);
        assert_true(flagged(&g_cekf, g_cekf.n_lm - 1));
        const uint8_t moving = newest_flag(&g_cekf, g_cekf.n_lm - 1);
        remove_both(j);
        assert_int_equal(newest_flag(&g_cekf, j), moving);
        compare_final(&g_full, &g_cekf, &t);
        removed++;
    }
    uint16_t j = 0;
    while (j < g_cekf.n_lm && flagged(&g_cekf, j)) {
        ++j;
    }
    if (j < g_cekf.n_lm) {
        remove_both(j);
        compare_final(&g_full, &g_cekf, &t);
        removed++;
    }
    /* the next frames start a phase from there */
    for (int frames = 0; frames < 10 && synth_next(&g_world, &st);) {
        (void)ekfslam_predict(&g_full, st.u);
        (void)ekfslam_predict(&g_cekf, st.u);
        if (st.is_frame) {
            assert_int_equal(ekfslam_update(&g_full, st.z, st.n_z), ekfslam_update(&g_cekf, st.z, st.n_z));
            frames++;
        }
    }
    ekfslam_sync(&g_cekf);
    compare_all(&g_full, &g_cekf, &t);
    print_message("cekf removal: %d removed, %d pending entries read, worst rel diff %.2g\n", removed,
                  t.pending_entries, t.worst);
}

/* The compression must pay: in a local phase the update touches N_A states */
static void test_local_phase_is_small(void **state)
{
    (void)state;
    synth_config_t sc = world(3U);
    sc.loop_radius_m = 14.0; /* the region is a small part of the ring */
    sc.loops = 1.0;
    ekfslam_config_t cfg = ekfslam_config_default();
    cfg.slam = sc.truth;
    cfg.active_radius_m = 1.0;
    cfg.active_min_landmarks = 16U;
    cfg.active_spread_madds = 6000U; /* slow: the generations back up */
    assert_int_equal(ekfslam_init(&g_cekf, &cfg, synth_start_pose(&sc)), COSLAM_OK);
    synth_init(&g_world, &sc);
    synth_step_t st;
    int local = 0;
    int frames = 0;
    while (synth_next(&g_world, &st)) {
        (void)ekfslam_predict(&g_cekf, st.u);
        if (st.is_frame) {
            (void)ekfslam_update(&g_cekf, st.z, st.n_z);
            frames++;
            if (g_cekf.cekf.local) {
                local++;
                /* the region's landmarks only (about 0.55 per m^2 within ~8 m) */
                ASSERT_TRUE_MSG((g_cekf.cekf.na - 3) / 2 <= 70, "%d active of %d\n", (g_cekf.cekf.na - 3) / 2,
                                g_cekf.n_lm);
            }
        }
    }
    assert_true(g_cekf.n_lm > 140);
    /* most frames run locally; a region lasts several frames */
    assert_true(local > frames / 2);
    assert_true(g_cekf.ctr.cekf_global_updates * 4U < (uint32_t)local);
    assert_int_equal(g_cekf.ctr.cekf_active_overflows, 0);
}

/* The evaluation's loop world as coslam-eval-worlds runs it (4 marker
 * classes, JCBB: the association is not known): the compressed filter
 * closes the loop with the same pairings, so the states stay equal. */
static void test_exact_loop_world(void **state)
{
    (void)state;
    for (uint64_t seed = 1U; seed <= 2U; ++seed) {
        const synth_config_t sc = eval_world_config(EVAL_WORLD_LOOP, seed);
        ekfslam_config_t cfg = ekfslam_config_default();
        cfg.slam = sc.truth;
        /* seed 1: the whole global update at once; seed 2: spread */
        cfg.active_spread_madds = seed == 1U ? 0U : 100000U;
        tally_t t;
        run_pair(&sc, cfg, 1.0, 0, &t);
        assert_true(t.global_updates >= 5);
        assert_true(t.local_updates > 100);
        if (seed == 1U) {
            assert_int_equal(g_cekf.ctr.cekf_spread_rows, 0U);
        } else {
            assert_true(t.pending_checks > 20);
        }
    }
}

/* A merge's updates kept pending and applied to P together (merge_batch,
 * ekfslam.c "A merge's updates together") against each applied at once
 * (merge_batch 1): the same map (a run of the full filter), the same merge
 * of duplicates (information in both directions, through an uncertain
 * transform), additions, and duplicates of the added landmarks after them.
 * The readers between the updates (ekfslam_landmark_relative, ekfslam_p,
 * ekfslam_pose), which add the pending columns' share, agree with the
 * filter that applied them, and so do x and P at the end, to 1e-9
 * relative. */
static void test_merge_batched(void **state)
{
    (void)state;
    const synth_config_t sc = world(202U);
    ekfslam_config_t cfg = spread_config(&sc);
    cfg.active_radius_m = 0.0;
    assert_int_equal(ekfslam_init(&g_full, &cfg, synth_start_pose(&sc)), COSLAM_OK);
    synth_init(&g_world, &sc);
    synth_step_t st;
    int steps = 0;
    while (synth_next(&g_world, &st) && steps < 1500) {
        ++steps;
        assert_int_equal(ekfslam_predict(&g_full, st.u), COSLAM_OK);
        if (st.is_frame) {
            (void)ekfslam_update(&g_full, st.z, st.n_z);
        }
    }
    assert_true(g_full.n_lm >= 60);
    memcpy(&g_cekf, &g_full, sizeof g_full);
    g_full.cfg.merge_batch = 1U;  /* each at once */
    g_cekf.cfg.merge_batch = 16U; /* several flushes in this merge */
    const pose2_t t_hat = {0.4, -0.3, 0.2};
    const cov3_t t_cov = cov3_diag(0.01, 0.02, 0.001);
    assert_int_equal(ekfslam_merge_begin(&g_full, &t_cov), COSLAM_OK);
    assert_int_equal(ekfslam_merge_begin(&g_cekf, &t_cov), COSLAM_OK);
    const pose2_t t_inv = pose2_inverse(t_hat);
    int pending_seen = 0;
    int reads = 0;
    const double ps = scale_of(&g_full);
    const uint16_t n_own = g_full.n_lm;
    for (int pass = 0; pass < 2; ++pass) {
        const uint16_t j0 = pass == 0 ? 0U : n_own;
        const uint16_t j1 = pass == 0 ? n_own : g_full.n_lm;
        for (uint16_t j = j0; j < j1; j = (uint16_t)(j + (pass == 0 ? 2U : 1U))) {
            point2_t rel;
            cov2_t rel_cov;
            ekfslam_landmark_relative(&g_full, j, &rel, &rel_cov);
            const point2_t off = {rel.x + 0.03 * ((j % 5) - 2.0), rel.y - 0.02 * ((j % 3) - 1.0)};
            const point2_t rel_other = pose2_apply(t_inv, off);
            cov2_t info;
            assert_int_equal(cov2_inverse(cov2_make(0.02 + 0.001 * (j % 7), 0.004, 0.03), &info), COSLAM_OK);
            assert_int_equal(ekfslam_merge_observe(&g_full, j, t_hat, rel_other, info), COSLAM_OK);
            assert_int_equal(ekfslam_merge_observe(&g_cekf, j, t_hat, rel_other, info), COSLAM_OK);
            pending_seen += g_cekf.merge_bn > 0;
            assert_int_equal(g_full.merge_bn, 0);
            if (j % 3 == 0) {
                /* the readers, with columns pending */
                const uint16_t k = (uint16_t)((j * 7U) % g_full.n_lm);
                point2_t mf, mc;
                cov2_t cf, cc;
                ekfslam_landmark_relative(&g_full, k, &mf, &cf);
                ekfslam_landmark_relative(&g_cekf, k, &mc, &cc);
                ASSERT_NEAR(mc.x, mf.x, REL_TOL);
                ASSERT_NEAR(mc.y, mf.y, REL_TOL);
                ASSERT_NEAR(cc.xx, cf.xx, REL_TOL * ps);
                ASSERT_NEAR(cc.xy, cf.xy, REL_TOL * ps);
                ASSERT_NEAR(cc.yy, cf.yy, REL_TOL * ps);
                const int a = 3 + 2 * k;
                ASSERT_NEAR(ekfslam_p(&g_cekf, 0, a), ekfslam_p(&g_full, 0, a), REL_TOL * ps);
                ASSERT_NEAR(ekfslam_p(&g_cekf, a + 1, 2), ekfslam_p(&g_full, a + 1, 2), REL_TOL * ps);
                pose2_t pf, pc;
                cov3_t qf, qc;
                ekfslam_pose(&g_full, &pf, &qf);
                ekfslam_pose(&g_cekf, &pc, &qc);
                ASSERT_NEAR(qc.m[0][2], qf.m[0][2], REL_TOL * ps);
                reads++;
            }
        }
        if (pass == 0) {
            /* additions: the pending columns go in first */
            for (int i = 0; i < 6; ++i) {
                ekfslam_meta_t meta = {(uint32_t)(90000 + i), 10.0f, 5, 2U, (uint8_t)i, 0};
                const point2_t rel_other = {2.0 + 0.5 * i, -1.0 + 0.3 * i};
                const cov2_t noise = cov2_make(0.05, 0.01, 0.04);
                assert_int_equal(ekfslam_merge_add(&g_full, t_hat, rel_other, noise, &meta), COSLAM_OK);
                assert_int_equal(ekfslam_merge_add(&g_cekf, t_hat, rel_other, noise, &meta), COSLAM_OK);
                assert_int_equal(g_cekf.merge_bn, 0);
            }
        }
    }
    ekfslam_merge_end(&g_full);
    ekfslam_merge_end(&g_cekf);
    assert_int_equal(g_cekf.merge_bn, 0);
    tally_t t;
    memset(&t, 0, sizeof t);
    compare_all(&g_full, &g_cekf, &t);
    print_message("merge batched: %u landmarks, %d updates with columns pending, %d reads between, worst rel diff "
                  "%.2g\n",
                  (unsigned)g_full.n_lm, pending_seen, reads, t.worst);
    assert_true(pending_seen > 20);
    assert_true(reads > 10);
}

/* ekfslam_sync_run (a merge in parts begins with it): a local phase ended
 * the deferred way and its rows completed in parts of a small budget is
 * the state ekfslam_sync gives at once, up to rounding, and leaves no
 * phase and no pending row; with every generation busy (a backlog), the
 * oldest's rows are completed in parts before the phase ends (nothing is
 * completed at once: cekf_spread_gens_full stays). */
static void test_sync_in_parts(void **state)
{
    (void)state;
    const synth_config_t sc = world(203U);
    ekfslam_config_t cfg = spread_config(&sc);
    cfg.active_radius_m = 1.0; /* as run_pair's cases */
    cfg.active_min_landmarks = 16U;
    assert_int_equal(ekfslam_init(&g_cekf, &cfg, synth_start_pose(&sc)), COSLAM_OK);
    synth_init(&g_world, &sc);
    synth_step_t st;
    int steps = 0;
    while (synth_next(&g_world, &st) && steps < 3000) {
        ++steps;
        assert_int_equal(ekfslam_predict(&g_cekf, st.u), COSLAM_OK);
        if (st.is_frame) {
            (void)ekfslam_update(&g_cekf, st.z, st.n_z);
        }
        if (steps > 600 && g_cekf.cekf.local && gens_busy(&g_cekf) == EKFSLAM_PEND_GENS) {
            break; /* in a local phase, every generation's rows pending (a backlog) */
        }
    }
    assert_true(g_cekf.cekf.local);
    assert_int_equal(gens_busy(&g_cekf), EKFSLAM_PEND_GENS);
    memcpy(&g_full, &g_cekf, sizeof g_cekf);
    ekfslam_sync(&g_full);
    int calls = 1;
    double spent = 0.0;
    const uint32_t gens_full = g_cekf.ctr.cekf_spread_gens_full;
    while (!ekfslam_sync_run(&g_cekf, 20000.0, &spent)) {
        calls++;
        assert_true(calls < 100000);
    }
    assert_false(g_cekf.cekf.local);
    assert_int_equal(gens_busy(&g_cekf), 0);
    assert_int_equal(g_cekf.ctr.cekf_spread_gens_full, gens_full);
    tally_t t;
    memset(&t, 0, sizeof t);
    compare_all(&g_full, &g_cekf, &t);
    print_message("sync in parts: %u landmarks, %d calls, %.3g multiply-adds, worst rel diff %.2g\n",
                  (unsigned)g_cekf.n_lm, calls, spent, t.worst);
    assert_true(calls > 3);
    /* synced: a second run is done at once and changes nothing */
    assert_int_equal(ekfslam_sync_run(&g_cekf, 20000.0, NULL), 1);
}

/* A full map with dead landmarks in it (removed in a local phase, still
 * in the state): a new landmark takes the place they leave (the phase
 * ends and they go first), so nothing is refused for capacity. */
static void test_dead_make_room(void **state)
{
    (void)state;
    const synth_config_t sc = clutter_world();
    ekfslam_config_t cfg = w5_config(&sc);
    cfg.active_radius_m = 1.5;
    cfg.active_min_landmarks = 16U;
    assert_int_equal(ekfslam_init(&g_cekf, &cfg, synth_start_pose(&sc)), COSLAM_OK);
    synth_init(&g_world, &sc);
    synth_step_t st;
    while (synth_next(&g_world, &st) && !(g_cekf.cekf.local && g_cekf.n_dead > 0U)) {
        (void)ekfslam_predict(&g_cekf, st.u);
        if (st.is_frame) {
            (void)ekfslam_update(&g_cekf, st.z, st.n_z);
        }
    }
    assert_true(g_cekf.cekf.local && g_cekf.n_dead > 0U);
    uint32_t dead_id[COSLAM_EKF_MAX_LANDMARKS];
    int n_dead = 0;
    for (uint16_t j = 0; j < g_cekf.n_lm; ++j) {
        if (!ekfslam_landmark_live(&g_cekf, j)) {
            dead_id[n_dead++] = g_cekf.meta[j].id;
        }
    }
    assert_int_equal(n_dead, g_cekf.n_dead);
    /* fill the state with landmarks far out of view (their own classes) */
    for (int i = 0; g_cekf.n_lm < COSLAM_EKF_MAX_LANDMARKS; ++i) {
        ekfslam_meta_t meta = {ekfslam_new_id(&g_cekf), 5.0f, 5, 1, (uint8_t)(200 + i % 50), 0};
        const point2_t far = {60.0 + 0.5 * (i % 20), 60.0 + 0.5 * (i / 20)};
        assert_int_equal(ekfslam_add_landmark_body(&g_cekf, far, cov2_make(0.01, 0.0, 0.01), &meta), COSLAM_OK);
    }
    assert_int_equal(g_cekf.n_dead, n_dead); /* still there: nothing ended with them */
    const uint32_t drops = g_cekf.ctr.lm_capacity_drops;
    ekfslam_meta_t meta = {ekfslam_new_id(&g_cekf), 5.0f, 5, 1, 250, 0};
    const point2_t far = {80.0, 80.0};
    assert_int_equal(ekfslam_add_landmark_body(&g_cekf, far, cov2_make(0.01, 0.0, 0.01), &meta), COSLAM_OK);
    assert_int_equal(g_cekf.ctr.lm_capacity_drops, drops);
    assert_int_equal(g_cekf.n_dead, 0);
    assert_int_equal(g_cekf.n_lm, COSLAM_EKF_MAX_LANDMARKS - n_dead + 1);
    for (uint16_t j = 0; j < g_cekf.n_lm; ++j) {
        for (int q = 0; q < n_dead; ++q) {
            assert_true(g_cekf.meta[j].id != dead_id[q]);
        }
    }
    assert_true(g_cekf.meta[g_cekf.n_lm - 1].id == meta.id);
}

static void test_config(void **state)
{
    (void)state;
    ekfslam_config_t cfg = ekfslam_config_default();
    const pose2_t p0 = {0.0, 0.0, 0.0};
    cfg.active_radius_m = -1.0;
    assert_int_equal(ekfslam_init(&g_cekf, &cfg, p0), COSLAM_E_ARG);
    cfg.active_radius_m = NAN;
    assert_int_equal(ekfslam_init(&g_cekf, &cfg, p0), COSLAM_E_ARG);
    cfg.active_radius_m = 2.0;
    assert_int_equal(ekfslam_init(&g_cekf, &cfg, p0), COSLAM_EKF_MAX_ACTIVE > 0 ? COSLAM_OK : COSLAM_E_ARG);
}

/* argv[1]: the cases to run (a cmocka pattern, "*" for all), argv[2]: the
 * cases to skip. CTest runs the five long exact runs each as its own entry
 * (test/slam/CMakeLists.txt), so that under qemu-aarch64 (about 24x slower)
 * no entry comes near its timeout and two of them run at once. */
int main(int argc, char **argv)
{
    if (argc > 1) {
        cmocka_set_test_filter(argv[1]);
    }
    if (argc > 2) {
        cmocka_set_skip_filter(argv[2]);
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config),
        cmocka_unit_test(test_exact_default),
        cmocka_unit_test(test_exact_idle),
        cmocka_unit_test(test_exact_w5_clutter),
        cmocka_unit_test(test_exact_w5_spread),
        cmocka_unit_test(test_exact_backlog),
        cmocka_unit_test(test_removal_moves_pending),
        cmocka_unit_test(test_exact_loop_world),
        cmocka_unit_test(test_local_phase_is_small),
        cmocka_unit_test(test_merge_batched),
        cmocka_unit_test(test_sync_in_parts),
        cmocka_unit_test(test_dead_make_room),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
