/*
 * Map merge over seeded two-robot runs (host/synth/synth2.h): two robots
 * start back to back, map separate halves of a 12 m arena (south and
 * north) with a 3 m camera, turn, see each other 2 m apart, exchange maps
 * and merge, each into its own filter.
 *
 * Consistency of the merge is tested where the inputs are consistent:
 * EKF-SLAM robots with known association (unique signatures), so that the
 * own maps entering the merge are consistent (docs/core-slam.md) and any
 * inconsistency measured after the merge is the merge's. The same runs
 * with the paper's eq. 3 (covariance rotated, transform uncertainty
 * ignored) must come out inconsistent: that is the paper's Fig. 7 bias.
 * The filter combinations (Fast-SLAM <-> EKF-SLAM) and non-unique markers
 * are tested for function and accuracy.
 */
#include "test_util.h"

#include <stdlib.h>
#include <string.h>

#include "merge_run.h"

#if COSLAM_TEST_FULL
#define SEEDS 200
#define SEEDS_COMBO 40
#else
#define SEEDS 50
#define SEEDS_COMBO 8
#endif

typedef struct {
    double nees_sum;      /* sum over merges of the mean NEES of added + fused landmarks */
    int merges;
    double nees_before_sum; /* sum over merges of the receiver's own map NEES before it */
    double t_nees_sum;    /* one transform per meeting */
    int meetings;
    double t_se;          /* squared position errors of the sightings' transforms */
    double t_se_refined;  /* and of the refined ones */
    double rel_self;      /* squared errors of the common landmarks, relative to the receiver */
    double rel_recv;
    double rel_merged;
    int n_common;
    int added;
    int spurious_before;
    int spurious_after;
    int refused;          /* robot-merges refused by the check (maps disagree) */
} merge_agg_t;

static void run_many(run_filter_t a, run_filter_t b, int n_signatures, uint8_t transform_uncertainty, int seeds,
                     merge_agg_t *g)
{
    memset(g, 0, sizeof *g);
    merge_run_result_t *res = malloc(sizeof *res);
    assert_non_null(res);
    for (int s = 0; s < seeds; ++s) {
        synth2_config_t sc = synth2_config_default(4000U + (uint64_t)s, 60);
        sc.n_signatures = n_signatures;
        merge_run_opts_t o = merge_run_opts_default(a, b);
        o.params = sc.truth;
        o.filter_seed = 50U + (uint64_t)s;
        o.merge.transform_uncertainty = transform_uncertainty;
        /* the paper's eq. 3 mode is compared for its fusion only: its
         * overconfident transform fails the check before trust */
        o.merge.check = transform_uncertainty;
        assert_int_equal(merge_run(&sc, &o, res), 0);
        /* the sightings' transform is evaluated whether or not the check
         * then refuses the maps */
        g->t_nees_sum += res->r[0].t_nees;
        g->meetings++;
        for (int k = 0; k < 2; ++k) {
            g->t_se += res->r[k].t_err_m * res->r[k].t_err_m;
            g->t_se_refined += res->r[k].t_err_refined_m * res->r[k].t_err_refined_m;
        }
        for (int k = 0; k < 2; ++k) {
            const merge_robot_result_t *r = &res->r[k];
            if (!r->merged) {
                /* only the check may refuse these meetings (maps that
                 * disagree, or a receiver lost in its own map) */
                assert_true(merge_refused_by_check(r->status));
                g->refused++;
                continue;
            }
            const int n = r->n_added_eval + r->n_common;
            if (n > 0) {
                g->nees_sum += (r->after_nees_added * r->n_added_eval + r->nees_common_merged) / n;
                g->nees_before_sum += r->before.nees_mean;
                g->merges++;
            }
            g->rel_self += r->se_rel_self;
            g->rel_recv += r->se_rel_received;
            g->rel_merged += r->se_rel_merged;
            g->n_common += r->n_common;
            g->added += (int)r->stats.added;
            g->spurious_before += r->before.n_spurious;
            g->spurious_after += r->after.n_spurious;
        }
    }
    free(res);
}

static void print_agg(const char *name, const merge_agg_t *g)
{
    printf("%s: %d merges (%d refused), landmark NEES after merge %.2f (the receivers' own maps before it %.2f), "
           "transform NEES %.2f, RMS error %.3f m (refined "
           "%.3f m), common landmarks %d: relative RMSE own %.3f received %.3f merged %.3f, added %d, spurious "
           "%d -> %d\n",
           name, g->merges, g->refused, g->nees_sum / g->merges, g->nees_before_sum / g->merges,
           g->t_nees_sum / g->meetings,
           sqrt(g->t_se / (2 * g->meetings)), sqrt(g->t_se_refined / (2 * g->meetings)), g->n_common,
           sqrt(g->rel_self / g->n_common), sqrt(g->rel_recv / g->n_common), sqrt(g->rel_merged / g->n_common),
           g->added, g->spurious_before, g->spurious_after);
}

static void test_merge_consistent(void **state)
{
    (void)state;
    merge_agg_t ours;
    merge_agg_t paper;
    run_many(RUN_EKFSLAM, RUN_EKFSLAM, 0, 1, SEEDS, &ours);
    run_many(RUN_EKFSLAM, RUN_EKFSLAM, 0, 0, SEEDS, &paper);
    print_agg("with transform uncertainty", &ours);
    print_agg("paper eq. 3 (rotation only)", &paper);
    double lo2, hi2, lo3, hi3;
    nees_band95(ours.merges, 2, &lo2, &hi2);
    nees_band95(ours.meetings, 3, &lo3, &hi3);
    printf("  bands: landmarks [%.2f, %.2f], transform [%.2f, %.2f]\n", lo2, hi2, lo3, hi3);
    const double a = ours.nees_sum / ours.merges;
    const double p = paper.nees_sum / paper.merges;
    const double t = ours.t_nees_sum / ours.meetings;
    ASSERT_TRUE_MSG(a >= lo2 && a <= hi2, "merged landmark NEES %.2f outside [%.2f, %.2f]\n", a, lo2, hi2);
    ASSERT_TRUE_MSG(t >= lo3 && t <= hi3, "transform NEES %.2f outside [%.2f, %.2f]\n", t, lo3, hi3);
    /* the paper's eq. 3 is overconfident: well above the band */
    ASSERT_TRUE_MSG(p > hi2, "paper-mode NEES %.2f unexpectedly consistent\n", p);
    /* the shared landmarks make the transform better than the sightings alone */
    ASSERT_TRUE_MSG(ours.t_se_refined < ours.t_se, "refined transform no better than the sightings'\n");
    /* merged landmarks no worse than the better of the two estimates (relative
     * to the receiving robot: its own drift is common to both and no merge
     * can remove it) */
    ASSERT_TRUE_MSG(ours.rel_merged <= ours.rel_self && ours.rel_merged <= ours.rel_recv,
                    "merged error above the better input\n");
    /* consistent maps fail the 99 % agreement test 1 % of the time: at most
     * 1 % + 3 binomial sd of the robot-merges (and never all) */
    const int tests = ours.merges + ours.refused;
    ASSERT_TRUE_MSG(ours.refused <= (int)(0.01 * tests + 3.0 * sqrt(0.01 * 0.99 * tests)) + 1,
                    "%d of %d consistent merges refused\n", ours.refused, tests);
    assert_true(ours.added > 0 && ours.n_common > 0);
}

/* Every combination of filters merges, with non-unique markers. */
static void combo(run_filter_t a, run_filter_t b, const char *name)
{
    merge_agg_t g;
    run_many(a, b, 4, 1, SEEDS_COMBO, &g);
    print_agg(name, &g);
    assert_int_equal(g.merges + g.refused, 2 * SEEDS_COMBO);
    /* refusals of these correct maps are false alarms: 1 % for consistent
     * inputs, more for a Fast-SLAM party whose exported covariances are too
     * confident (issue 9); at most one in ten */
    ASSERT_TRUE_MSG(g.refused * 10 <= 2 * SEEDS_COMBO, "%d of %d merges refused\n", g.refused, 2 * SEEDS_COMBO);
    assert_true(g.added >= 10 * (2 * SEEDS_COMBO - g.refused) / 2); /* each merging robot learns the other half */
    /* the merged estimate of a common landmark, relative to the receiver, is
     * at least as good as what was received. Not yet for a Fast-SLAM
     * receiver: its exported covariances are 10-40x too confident (landmark
     * NEES printed above; the honest export is issue 9), so the fusion
     * weights favour its own map and the merged error sits up to 10 % above
     * the better input */
    if (a == RUN_EKFSLAM) {
        ASSERT_TRUE_MSG(g.rel_merged <= g.rel_recv, "merged error above the received one\n");
    } else {
        const double best = g.rel_self < g.rel_recv ? g.rel_self : g.rel_recv;
        ASSERT_TRUE_MSG(g.rel_merged <= 1.1 * 1.1 * best, "merged error more than 10 %% above the better input\n");
    }
}

static void test_fastslam_receives_ekf(void **state)
{
    (void)state;
    combo(RUN_FASTSLAM2, RUN_EKFSLAM, "Fast-SLAM 2.0 <-> EKF-SLAM, 4 marker classes");
}

static void test_fastslam_pair(void **state)
{
    (void)state;
    combo(RUN_FASTSLAM1, RUN_FASTSLAM1, "Fast-SLAM 1.0 <-> Fast-SLAM 1.0, 4 marker classes");
}

static void test_ekf_pair_nonunique(void **state)
{
    (void)state;
    combo(RUN_EKFSLAM, RUN_EKFSLAM, "EKF-SLAM <-> EKF-SLAM, 4 marker classes");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_merge_consistent),
        cmocka_unit_test(test_fastslam_receives_ekf),
        cmocka_unit_test(test_fastslam_pair),
        cmocka_unit_test(test_ekf_pair_nonunique),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
