/*
 * hal/hal_clock_linux.h - hal_clock on Linux: CLOCK_MONOTONIC.
 *
 * now_us is CLOCK_MONOTONIC in microseconds, unshifted, so stamps taken by
 * the kernel on the same clock (GPIO line events since Linux 5.7, V4L2
 * buffers) are directly comparable. sleep_until_us uses
 * clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME) and resumes after
 * signals. Stateless: one shared, thread-safe instance.
 */
#ifndef HAL_CLOCK_LINUX_H
#define HAL_CLOCK_LINUX_H

#include "hal/hal_clock.h"

#ifdef __cplusplus
extern "C" {
#endif

/** The Linux monotonic clock. Never NULL; close is a no-op. */
hal_clock_t *hal_clock_linux(void);

#ifdef __cplusplus
}
#endif

#endif /* HAL_CLOCK_LINUX_H */
