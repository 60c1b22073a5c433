/*
 * hal/hal_clock.h - the monotonic clock: the only source of time for the
 * firmware (see hal_common.h for the shared conventions).
 *
 * Semantics:
 *  - now_us: microseconds since an arbitrary epoch fixed for the life of
 *    the instance (boot, or simulation start). Monotonic: two successive
 *    reads on the same instance never go backwards, and it does not jump
 *    with wall-clock changes. It wraps after 584 000 years; callers may
 *    subtract stamps without overflow checks.
 *  - sleep_until_us: returns once now_us >= deadline_us. A deadline in the
 *    past (or now) returns HAL_OK at once, without yielding. An absolute
 *    deadline (not a duration) lets a periodic loop run at a fixed rate
 *    without accumulating drift: `next += period; sleep_until_us(next)`.
 *  - Time base: every stamp_us in the HAL (GPIO edges, camera frames, link
 *    datagrams) is in the time base of the platform's hal_clock.
 *
 * Backends:
 *  - Linux (hal/linux): CLOCK_MONOTONIC, clock_nanosleep(TIMER_ABSTIME).
 *  - Simulator (sim/hal): simulated time advanced by the simulator, faster
 *    than real time. sleep_until_us advances nothing by itself: it is
 *    honoured by the simulator's scheduler (a step hook, or the threaded
 *    lock-step scheduler). Without a scheduler a future deadline returns
 *    HAL_E_BUSY. See docs/hal.md, "Simulated time".
 *  - Null (hal_clock_null()): every operation returns HAL_E_UNSUPPORTED.
 */
#ifndef HAL_CLOCK_H
#define HAL_CLOCK_H

#include "hal/hal_common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct hal_clock hal_clock_t;

typedef struct {
    /** Read the time [us]. HAL_OK with *now_us set; HAL_E_IO if the OS
     *  clock failed (*now_us untouched). Never blocks. */
    hal_status_t (*now_us)(hal_clock_t *dev, uint64_t *now_us);
    /** Block until now_us >= deadline_us.
     *  HAL_OK: the deadline has been reached (also for a past deadline).
     *  HAL_E_BUSY: the backend cannot block now and the deadline has not
     *      been reached (simulator without a scheduler); the caller returns
     *      to its own scheduler and calls again later.
     *  HAL_E_IO: the OS sleep failed (not for signal interruptions, which
     *      are retried inside). */
    hal_status_t (*sleep_until_us)(hal_clock_t *dev, uint64_t deadline_us);
    /** Release the instance. The handle is unusable afterwards. */
    void (*close)(hal_clock_t *dev);
} hal_clock_ops_t;

struct hal_clock {
    const hal_clock_ops_t *ops;
    void *backend;   /**< backend-owned state */
};

/** Read the monotonic time [us]. Returns HAL_OK, HAL_E_ARG (NULL dev or
 *  now_us), HAL_E_IO, HAL_E_UNSUPPORTED. Never blocks; O(1). */
static inline hal_status_t hal_clock_now_us(hal_clock_t *d, uint64_t *now_us)
{
    if (d == NULL || d->ops == NULL || now_us == NULL) return HAL_E_ARG;
    return d->ops->now_us ? d->ops->now_us(d, now_us) : HAL_E_UNSUPPORTED;
}

/** Block until the clock reads at least deadline_us [us, same time base as
 *  now_us]. Returns HAL_OK, HAL_E_ARG (NULL dev), HAL_E_BUSY (cannot block
 *  now, deadline not reached), HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_clock_sleep_until_us(hal_clock_t *d, uint64_t deadline_us)
{
    if (d == NULL || d->ops == NULL) return HAL_E_ARG;
    return d->ops->sleep_until_us ? d->ops->sleep_until_us(d, deadline_us) : HAL_E_UNSUPPORTED;
}

static inline void hal_clock_close(hal_clock_t *d)
{
    if (d != NULL && d->ops != NULL && d->ops->close != NULL) d->ops->close(d);
}

/** The null clock (library coslam_hal_null): a static instance whose every
 *  operation returns HAL_E_UNSUPPORTED. Never NULL. */
hal_clock_t *hal_clock_null(void);

#ifdef __cplusplus
}
#endif

#endif /* HAL_CLOCK_H */
