// hal_clock contract conformance (see hal/hal_clock.h).
#include "conformance.hpp"

using conf::now_of;

TEST_P(ClockConformance, ArgumentsChecked)
{
    EXPECT_EQ(hal_clock_now_us(h->dev(), nullptr), HAL_E_ARG);
    uint64_t t = 0;
    EXPECT_EQ(hal_clock_now_us(nullptr, &t), HAL_E_ARG);
    EXPECT_EQ(hal_clock_sleep_until_us(nullptr, 0), HAL_E_ARG);
}

TEST_P(ClockConformance, NowIsMonotonic)
{
    uint64_t prev = now_of(h->dev());
    for (int i = 0; i < 10000; ++i) {
        const uint64_t t = now_of(h->dev());
        ASSERT_GE(t, prev) << "clock went backwards at read " << i;
        prev = t;
    }
}

TEST_P(ClockConformance, TimePassesInMicroseconds)
{
    const uint64_t t0 = now_of(h->dev());
    h->let_time_pass_us(5000);
    const uint64_t dt = now_of(h->dev()) - t0;
    EXPECT_GE(dt, 5000u);
    if (h->real_time()) {
        EXPECT_LT(dt, 2000000u) << "a 5 ms pause read as seconds: wrong unit?";
    } else {
        EXPECT_EQ(dt, 5000u) << "simulated time must move exactly as told";
    }
}

TEST_P(ClockConformance, SleepUntilPastOrNowReturnsAtOnce)
{
    const uint64_t t0 = now_of(h->dev());
    EXPECT_EQ(hal_clock_sleep_until_us(h->dev(), t0), HAL_OK);
    EXPECT_EQ(hal_clock_sleep_until_us(h->dev(), 0), HAL_OK);
    if (t0 > 1000) {
        EXPECT_EQ(hal_clock_sleep_until_us(h->dev(), t0 - 1000), HAL_OK);
    }
    const uint64_t dt = now_of(h->dev()) - t0;
    if (h->real_time()) {
        EXPECT_LT(dt, 100000u);
    } else {
        EXPECT_EQ(dt, 0u) << "a past deadline must not advance simulated time";
    }
}

TEST_P(ClockConformance, SleepUntilFutureReachesDeadline)
{
    const uint64_t deadline = now_of(h->dev()) + 3000;
    ASSERT_EQ(hal_clock_sleep_until_us(h->dev(), deadline), HAL_OK);
    const uint64_t t = now_of(h->dev());
    EXPECT_GE(t, deadline);
    if (h->real_time()) {
        EXPECT_LT(t - deadline, 500000u) << "overslept by more than 0.5 s";
    } else {
        EXPECT_EQ(t, deadline) << "a simulated sleep ends exactly at its deadline";
    }
}

TEST_P(ClockConformance, PeriodicLoopDoesNotDrift)
{
    const uint64_t period_us = 1000;
    const uint64_t start = now_of(h->dev());
    uint64_t next = start;
    for (int i = 0; i < 20; ++i) {
        next += period_us;
        ASSERT_EQ(hal_clock_sleep_until_us(h->dev(), next), HAL_OK);
        ASSERT_GE(now_of(h->dev()), next);
    }
    // absolute deadlines: the 20th wake-up is due at start + 20 ms, whatever
    // the per-iteration lateness was
    EXPECT_EQ(next, start + 20 * period_us);
}
