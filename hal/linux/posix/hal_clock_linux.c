/* hal_clock on CLOCK_MONOTONIC (see hal/hal_clock_linux.h). */
#include "hal/hal_clock_linux.h"

#include <errno.h>
#include <time.h>

static hal_status_t linux_now_us(hal_clock_t *dev, uint64_t *now_us)
{
    (void)dev;
    struct timespec ts;
    if (clock_gettime(CLOCK_MONOTONIC, &ts) != 0) return HAL_E_IO;
    *now_us = (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
    return HAL_OK;
}

static hal_status_t linux_sleep_until_us(hal_clock_t *dev, uint64_t deadline_us)
{
    (void)dev;
    /* Round the deadline up to the next microsecond boundary that now_us
     * reports as >= deadline_us: deadline_us * 1000 ns is exactly that. */
    struct timespec ts;
    ts.tv_sec = (time_t)(deadline_us / 1000000u);
    ts.tv_nsec = (long)((deadline_us % 1000000u) * 1000u);
    for (;;) {
        const int rc = clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
        if (rc == 0) return HAL_OK;
        if (rc != EINTR) return HAL_E_IO;
    }
}

static const hal_clock_ops_t linux_clock_ops = {linux_now_us, linux_sleep_until_us, NULL};
static hal_clock_t linux_clock = {&linux_clock_ops, NULL};

hal_clock_t *hal_clock_linux(void)
{
    return &linux_clock;
}
