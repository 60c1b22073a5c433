/*
 * The consistency and loop-closure worlds of docs/consistency.md (the same
 * runs as coslam-eval-worlds): exported-map NEES, loop closure and the
 * accuracy of Fast-SLAM 2.0 against EKF-SLAM, with non-unique landmarks
 * (4 classes) and the filters given the truth's noise model.
 *
 * Bounds and why:
 *  - landmark NEES of the exported map (2 dof, ideal 2): the median over
 *    the runs of each run's mean must lie in [1, 4] (issue 9). The median,
 *    because one run whose association failed has a mean NEES of 50-200
 *    (its map is wrong, not its covariance) and the run counts below police
 *    those;
 *  - loop closure (final position error < 0.5 m and at most 2 % spurious
 *    landmarks): EKF-SLAM in at least 8 of 10 runs of the long loop and of
 *    the paper world;
 *  - Fast-SLAM 2.0 with 100 particles: mean pose RMSE at most 1.3x EKF-SLAM's
 *    on the paper world.
 *  - Fast-SLAM 2.0 (100 particles) on the long loop: at least 8 of the 10
 *    CI runs, issue 9's goal (8 measured; 6 before the pose marginal
 *    followed the proposal's gain, marginal_pose_observe_gain, and 4
 *    before the revisit closure of fastslam.c "Revisits": this bound
 *    polices both), at least 16 of the 30 held-out ones (19 measured, 18
 *    and 12 before; the bound leaves three runs of margin, as the CI one
 *    leaves none: issue 9 asks 8 of 10, docs/consistency.md).
 * The arena world (MRCLAM's regime) is bounded after a rigid fit, below.
 * CI runs world seeds 1-10; COSLAM_TEST_FULL adds the held-out seeds
 * 101-130, never used while choosing anything.
 */
#include "test_util.h"

#include <stdlib.h>

#include "eval_worlds.h"

#if COSLAM_TEST_FULL
#define WORLD_SEEDS 30
#define WORLD_SEED0 101U
#else
#define WORLD_SEEDS 10
#define WORLD_SEED0 1U
#endif

static void run_set(eval_world_t w, run_filter_t f, int particles, int n_seeds, eval_summary_t *out)
{
    run_result_t *r = malloc(sizeof *r);
    assert_non_null(r);
    eval_summary_init(out);
    for (int k = 0; k < n_seeds; ++k) {
        assert_int_equal(eval_world_run(w, f, particles, WORLD_SEED0 + (uint64_t)k, r), 0);
        eval_summary_add(out, r);
    }
    char name[64];
    if (f == RUN_EKFSLAM) {
        snprintf(name, sizeof name, "EKF-SLAM");
    } else {
        snprintf(name, sizeof name, "Fast-SLAM %s, %d particles", f == RUN_FASTSLAM2 ? "2.0" : "1.0", particles);
    }
    printf("%s, %s: closed %d/%d, mean pose RMSE %.3f m, median landmark NEES %.2f, spurious %d of %d\n",
           w == EVAL_WORLD_PAPER ? "paper" : "loop", name, out->closed, out->n, out->pose_rmse_sum / out->n,
           eval_summary_median_nees(out), out->spurious, out->estimated);
    free(r);
}

static void assert_nees(const eval_summary_t *s)
{
    const double m = eval_summary_median_nees(s);
    ASSERT_TRUE_MSG(m >= 1.0 && m <= 4.0, "median landmark NEES %.2f outside [1, 4]\n", m);
}

static void test_paper_world(void **state)
{
    (void)state;
    static eval_summary_t ekf, fs100, fs1000;
    run_set(EVAL_WORLD_PAPER, RUN_EKFSLAM, 0, WORLD_SEEDS, &ekf);
    run_set(EVAL_WORLD_PAPER, RUN_FASTSLAM2, 100, WORLD_SEEDS, &fs100);
    run_set(EVAL_WORLD_PAPER, RUN_FASTSLAM2, 1000, WORLD_SEEDS, &fs1000);
    assert_nees(&ekf);
    assert_nees(&fs100);
    assert_nees(&fs1000);
    ASSERT_TRUE_MSG(ekf.closed * 10 >= 8 * ekf.n, "EKF-SLAM closed %d of %d\n", ekf.closed, ekf.n);
    const double ratio = fs100.pose_rmse_sum / ekf.pose_rmse_sum;
    printf("Fast-SLAM 2.0 (100) / EKF-SLAM pose RMSE: %.2f\n", ratio);
    ASSERT_TRUE_MSG(ratio <= 1.3, "Fast-SLAM 2.0 pose RMSE %.2fx EKF-SLAM's\n", ratio);
}

static void test_long_loop(void **state)
{
    (void)state;
    static eval_summary_t ekf, fs100, fs1000;
    run_set(EVAL_WORLD_LOOP, RUN_EKFSLAM, 0, WORLD_SEEDS, &ekf);
    run_set(EVAL_WORLD_LOOP, RUN_FASTSLAM2, 100, WORLD_SEEDS, &fs100);
#if COSLAM_TEST_FULL
    run_set(EVAL_WORLD_LOOP, RUN_FASTSLAM2, 1000, WORLD_SEEDS, &fs1000); /* 14 s a run */
#else
    (void)fs1000;
#endif
    ASSERT_TRUE_MSG(ekf.closed * 10 >= 8 * ekf.n, "EKF-SLAM closed the loop %d of %d\n", ekf.closed, ekf.n);
    assert_nees(&ekf);
#if COSLAM_TEST_FULL
    ASSERT_TRUE_MSG(fs100.closed >= 16, "Fast-SLAM 2.0 (100) closed the loop %d of %d\n", fs100.closed, fs100.n);
#else
    ASSERT_TRUE_MSG(fs100.closed >= 8, "Fast-SLAM 2.0 (100) closed the loop %d of %d\n", fs100.closed, fs100.n);
#endif
}

/* The arena (MRCLAM's regime, 15 identical landmarks in clusters, one or
 * two sightings per frame, the filters on coslam-replay's MRCLAM model):
 * its maps scored as coslam-replay scores MRCLAM, after the best rigid fit.
 * Regression bounds, not goals: measured (seeds 1-10 / held-out 101-130)
 * EKF-SLAM 1.70 / 1.10 spurious landmarks per run, landmark RMSE 0.23 /
 * 0.17 m (0.60 / 1.40 and 0.32 / 0.20 m before jcbb_single_closure_d2);
 * Fast-SLAM 2.0 (100) 0.10 / 0.10 and 0.150 / 0.149 m (0.30 / 0.20 and
 * 0.149 / 0.147 m before marginal_pose_observe_gain). The path moved by
 * the map's fit (the robot's error in its own map): EKF-SLAM 1.40 / 1.50 m,
 * Fast-SLAM 2.0 0.35 / 0.50 m (0.36 / 0.47 m before). Issue 8 asks at most 1 spurious landmark per
 * robot on MRCLAM; EKF-SLAM does not reach it here. */
static void arena_set(run_filter_t f, int particles, double max_spurious_per_run, double max_rmse_m,
                      double max_pose_m)
{
    run_result_t *r = malloc(sizeof *r);
    assert_non_null(r);
    int spurious = 0;
    int clean = 0;
    double rmse = 0.0;
    double pose = 0.0;
    for (int k = 0; k < WORLD_SEEDS; ++k) {
        assert_int_equal(eval_world_run(EVAL_WORLD_ARENA, f, particles, WORLD_SEED0 + (uint64_t)k, r), 0);
        assert_true(r->has_map_fit);
        spurious += r->map_fit.n_spurious;
        clean += r->map_fit.n_spurious == 0;
        rmse += r->map_fit.rmse_m;
        pose += r->pose_rmse_fit_m;
    }
    printf("arena, %s: after rigid fit %d of %d runs without a spurious landmark, %.2f per run, landmark RMSE %.3f m, "
           "pose RMSE in the fitted map %.3f m\n",
           f == RUN_EKFSLAM ? "EKF-SLAM" : "Fast-SLAM 2.0 (100)", clean, WORLD_SEEDS, (double)spurious / WORLD_SEEDS,
           rmse / WORLD_SEEDS, pose / WORLD_SEEDS);
    ASSERT_TRUE_MSG(spurious <= max_spurious_per_run * WORLD_SEEDS, "%d spurious landmarks in %d runs\n", spurious,
                    WORLD_SEEDS);
    ASSERT_TRUE_MSG(rmse <= max_rmse_m * WORLD_SEEDS, "landmark RMSE %.3f m\n", rmse / WORLD_SEEDS);
    ASSERT_TRUE_MSG(pose <= max_pose_m * WORLD_SEEDS, "pose RMSE in the fitted map %.3f m\n", pose / WORLD_SEEDS);
    free(r);
}

static void test_arena(void **state)
{
    (void)state;
    arena_set(RUN_EKFSLAM, 0, 2.0, 0.4, 2.0);
    arena_set(RUN_FASTSLAM2, 100, 1.0, 0.3, 0.8);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_paper_world),
        cmocka_unit_test(test_long_loop),
        cmocka_unit_test(test_arena),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
