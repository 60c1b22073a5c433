/* The core RNG: reproducibility, and its distributions against their moments. */
#include "test_util.h"

#include "coslam/rng.h"

static void test_same_seed_same_stream(void **state)
{
    (void)state;
    rng_t a;
    rng_t b;
    rng_seed(&a, 42U);
    rng_seed(&b, 42U);
    for (int i = 0; i < 10000; ++i) {
        assert_true(rng_next_u64(&a) == rng_next_u64(&b));
    }
    /* Gaussian (with its cached spare) too */
    for (int i = 0; i < 1001; ++i) {
        const double x = rng_gauss(&a);
        const double y = rng_gauss(&b);
        assert_memory_equal(&x, &y, sizeof x);
    }
    /* different seeds: different streams (adjacent seeds are decorrelated by splitmix64) */
    rng_seed(&a, 42U);
    rng_seed(&b, 43U);
    int equal = 0;
    for (int i = 0; i < 1000; ++i) {
        equal += rng_next_u64(&a) == rng_next_u64(&b);
    }
    assert_int_equal(equal, 0);
    /* seed 0 is valid */
    rng_seed(&a, 0U);
    assert_true(rng_next_u64(&a) != 0U || rng_next_u64(&a) != 0U);
}

static void test_uniform_moments(void **state)
{
    (void)state;
    rng_t r;
    rng_seed(&r, 1U);
    const int n = 400000;
    double s = 0.0;
    double s2 = 0.0;
    double mn = 1.0;
    double mx = 0.0;
    for (int i = 0; i < n; ++i) {
        const double u = rng_uniform(&r);
        assert_true(u >= 0.0 && u < 1.0);
        s += u;
        s2 += u * u;
        mn = u < mn ? u : mn;
        mx = u > mx ? u : mx;
    }
    /* mean 1/2 (sd 1/sqrt(12 n)), second moment 1/3; 5 sigma */
    ASSERT_NEAR(s / n, 0.5, 5.0 / sqrt(12.0 * n));
    ASSERT_NEAR(s2 / n, 1.0 / 3.0, 5.0 * sqrt(4.0 / 45.0 / n));
    assert_true(mn < 1e-4 && mx > 1.0 - 1e-4);
}

static void test_gauss_moments(void **state)
{
    (void)state;
    rng_t r;
    rng_seed(&r, 2U);
    const int n = 400000;
    double m[5] = {0, 0, 0, 0, 0};
    int tail = 0;
    for (int i = 0; i < n; ++i) {
        const double x = rng_gauss(&r);
        double p = 1.0;
        for (int k = 1; k <= 4; ++k) {
            p *= x;
            m[k] += p;
        }
        tail += fabs(x) > 3.0;
    }
    /* E x = 0, E x^2 = 1, E x^3 = 0, E x^4 = 3; sample sds 1, sqrt 2, sqrt 15, sqrt 96 over sqrt n */
    ASSERT_NEAR(m[1] / n, 0.0, 5.0 / sqrt(n));
    ASSERT_NEAR(m[2] / n, 1.0, 5.0 * sqrt(2.0 / n));
    ASSERT_NEAR(m[3] / n, 0.0, 5.0 * sqrt(15.0 / n));
    ASSERT_NEAR(m[4] / n, 3.0, 5.0 * sqrt(96.0 / n));
    /* P(|x| > 3) = 0.0026998 */
    const double p3 = 0.0026998;
    ASSERT_NEAR((double)tail / n, p3, 5.0 * sqrt(p3 * (1 - p3) / n));
    /* scaled normal */
    rng_seed(&r, 3U);
    double s = 0.0;
    double s2 = 0.0;
    for (int i = 0; i < n; ++i) {
        const double x = rng_normal(&r, 2.0, 0.5);
        s += x;
        s2 += (x - 2.0) * (x - 2.0);
    }
    ASSERT_NEAR(s / n, 2.0, 5.0 * 0.5 / sqrt(n));
    ASSERT_NEAR(s2 / n, 0.25, 5.0 * 0.25 * sqrt(2.0 / n));
}

static void test_below_is_uniform(void **state)
{
    (void)state;
    rng_t r;
    rng_seed(&r, 4U);
    enum { K = 7, N = 70000 };
    int count[K] = {0};
    for (int i = 0; i < N; ++i) {
        const uint32_t v = rng_below(&r, K);
        assert_true(v < K);
        count[v]++;
    }
    /* Pearson chi-square, 6 dof: 99.9 % quantile is 22.46 */
    double chi2 = 0.0;
    const double e = (double)N / K;
    for (int k = 0; k < K; ++k) {
        chi2 += (count[k] - e) * (count[k] - e) / e;
    }
    assert_true(chi2 < 22.46);
    /* n = 1 always 0; a huge n stays in range */
    assert_int_equal(rng_below(&r, 1U), 0);
    for (int i = 0; i < 1000; ++i) {
        assert_true(rng_below(&r, 0xFFFFFFFFU) < 0xFFFFFFFFU);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_same_seed_same_stream),
        cmocka_unit_test(test_uniform_moments),
        cmocka_unit_test(test_gauss_moments),
        cmocka_unit_test(test_below_is_uniform),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
