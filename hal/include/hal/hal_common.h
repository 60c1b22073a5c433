/*
 * hal/hal_common.h - what every HAL contract shares: the status codes and
 * the conventions.
 *
 * Conventions (all contracts):
 *  - A device is an instance handle `hal_<dev>_t` whose first member is a
 *    pointer to a const table of operations `hal_<dev>_ops_t`, followed by
 *    backend state. Several instances coexist (the simulator runs several
 *    robots in one process). Callers use the inline wrappers
 *    `hal_<dev>_<op>(dev, ...)`, never the table directly.
 *  - A backend that lacks an operation leaves its pointer NULL; the wrapper
 *    then returns HAL_E_UNSUPPORTED. Missing hardware is never a weak
 *    symbol: it is the null backend (`hal_<dev>_null()`), whose every
 *    operation returns HAL_E_UNSUPPORTED.
 *  - Units: SI at this edge too, with the unit in the name (timeout_us,
 *    stamp_us). Time comes only from hal_clock.
 *  - Buffers: the caller owns every buffer it passes; a backend never keeps
 *    a pointer to a caller buffer after the call returns.
 *  - Blocking: every operation that can wait takes timeout_us; 0 means
 *    "poll, never block". HAL_TIMEOUT_FOREVER blocks until done or error.
 *  - Thread safety: one instance is used by one thread at a time.
 */
#ifndef HAL_COMMON_H
#define HAL_COMMON_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    HAL_OK = 0,
    HAL_E_ARG = -1,          /**< invalid argument (NULL, size 0, out of range) */
    HAL_E_TIMEOUT = -2,      /**< nothing happened within timeout_us */
    HAL_E_IO = -3,           /**< the device or OS reported an I/O error */
    HAL_E_UNSUPPORTED = -4,  /**< the backend has no such operation or hardware */
    HAL_E_OVERFLOW = -5,     /**< data lost: a queue or buffer overflowed */
    HAL_E_CLOSED = -6,       /**< the device is not open / went away */
    HAL_E_BUSY = -7,         /**< the device cannot accept this now; retry */
    HAL_E_NOT_FOUND = -8,    /**< a named resource (file, line, device) does not exist */
    HAL_E_CORRUPT = -9,      /**< data failed an integrity check */
} hal_status_t;

/** Block until done (for timeout_us parameters). */
#define HAL_TIMEOUT_FOREVER UINT32_MAX

/** Short static name of a status, for logs ("HAL_E_TIMEOUT"). */
static inline const char *hal_status_str(hal_status_t s)
{
    switch (s) {
    case HAL_OK: return "HAL_OK";
    case HAL_E_ARG: return "HAL_E_ARG";
    case HAL_E_TIMEOUT: return "HAL_E_TIMEOUT";
    case HAL_E_IO: return "HAL_E_IO";
    case HAL_E_UNSUPPORTED: return "HAL_E_UNSUPPORTED";
    case HAL_E_OVERFLOW: return "HAL_E_OVERFLOW";
    case HAL_E_CLOSED: return "HAL_E_CLOSED";
    case HAL_E_BUSY: return "HAL_E_BUSY";
    case HAL_E_NOT_FOUND: return "HAL_E_NOT_FOUND";
    case HAL_E_CORRUPT: return "HAL_E_CORRUPT";
    }
    return "HAL_E_UNKNOWN";
}

#ifdef __cplusplus
}
#endif

#endif /* HAL_COMMON_H */
