/*
 * hal/hal_gpio.h - digital lines of one GPIO controller, addressed by index
 * 0 .. line_count-1 (bumpers, e-stop, status LEDs). See hal_common.h for the
 * shared conventions.
 *
 * Semantics:
 *  - Logical levels: every value crossing this interface is logical,
 *    `active` = true. A line configured active-low reads active when the
 *    pin is electrically low, and write(active = true) drives it low.
 *    Edges are logical too: HAL_GPIO_EDGE_RISING is inactive -> active.
 *  - A line is unusable (HAL_E_CLOSED) until configure() succeeds; it may
 *    be reconfigured at any time (this drops its queued edges) and is
 *    given back by release().
 *  - Outputs can be read: read() returns the level last written.
 *  - Edges: an input configured with edges != HAL_GPIO_EDGE_NONE queues
 *    each selected edge with its stamp_us (hal_clock time base) from the
 *    moment configure() returns. wait_edge() pops the oldest queued edge,
 *    waiting at most timeout_us for one. The queue depth is the backend's
 *    (at least 16); when it overflows, newer edges are dropped and the next
 *    wait_edge() returns HAL_E_OVERFLOW once (queue emptied): the caller
 *    re-reads the level to resynchronise. Backends that cannot detect
 *    overflow (Linux GPIO uAPI v1) never return it.
 *
 * Backends: Linux libgpiod v1 (hal/linux, built when libgpiod-dev is
 * installed), simulator (sim/hal: the simulator drives inputs and reads
 * outputs), null (hal_gpio_null(): every operation HAL_E_UNSUPPORTED).
 */
#ifndef HAL_GPIO_H
#define HAL_GPIO_H

#include <stdbool.h>

#include "hal/hal_common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct hal_gpio hal_gpio_t;

typedef enum {
    HAL_GPIO_DIR_INPUT = 0,
    HAL_GPIO_DIR_OUTPUT = 1,
} hal_gpio_dir_t;

/** Edge selection mask (hal_gpio_config_t.edges) and edge kind
 *  (hal_gpio_event_t.edge: exactly one of RISING or FALLING). */
#define HAL_GPIO_EDGE_NONE 0u
#define HAL_GPIO_EDGE_RISING 1u   /**< logical inactive -> active */
#define HAL_GPIO_EDGE_FALLING 2u  /**< logical active -> inactive */
#define HAL_GPIO_EDGE_BOTH 3u

typedef struct {
    hal_gpio_dir_t dir;
    bool active_low;      /**< electrical low is the active level */
    bool initial_active;  /**< outputs: logical level driven by configure() */
    uint8_t edges;        /**< inputs: HAL_GPIO_EDGE_* to queue; outputs: NONE */
} hal_gpio_config_t;

typedef struct {
    uint8_t edge;         /**< HAL_GPIO_EDGE_RISING or HAL_GPIO_EDGE_FALLING */
    uint64_t stamp_us;    /**< when the edge happened (hal_clock time base) */
} hal_gpio_event_t;

typedef struct {
    /** Number of lines of this controller; HAL_OK, HAL_E_IO. */
    hal_status_t (*line_count)(hal_gpio_t *dev, uint32_t *n_lines);
    /** Claim/configure a line. HAL_OK; HAL_E_ARG (bad dir, edges on an
     *  output, unknown edge bits); HAL_E_NOT_FOUND (line >= line_count);
     *  HAL_E_BUSY (held by another user); HAL_E_UNSUPPORTED (the backend
     *  cannot do this configuration, e.g. edge detection); HAL_E_IO. On
     *  any error the line is left released. */
    hal_status_t (*configure)(hal_gpio_t *dev, uint32_t line, const hal_gpio_config_t *cfg);
    /** Logical level. HAL_OK; HAL_E_NOT_FOUND; HAL_E_CLOSED (not
     *  configured); HAL_E_IO. Never blocks. */
    hal_status_t (*read)(hal_gpio_t *dev, uint32_t line, bool *active);
    /** Drive an output. HAL_OK; HAL_E_ARG (line is an input);
     *  HAL_E_NOT_FOUND; HAL_E_CLOSED; HAL_E_IO. Never blocks. */
    hal_status_t (*write)(hal_gpio_t *dev, uint32_t line, bool active);
    /** Pop the oldest queued edge, waiting up to timeout_us for one.
     *  HAL_OK (*ev set); HAL_E_TIMEOUT (none within timeout_us);
     *  HAL_E_OVERFLOW (edges were lost, queue emptied, *ev untouched);
     *  HAL_E_ARG (line is an output or has no edges selected);
     *  HAL_E_NOT_FOUND; HAL_E_CLOSED; HAL_E_IO. */
    hal_status_t (*wait_edge)(hal_gpio_t *dev, uint32_t line, hal_gpio_event_t *ev, uint32_t timeout_us);
    /** Give a line back (an output stops being driven). HAL_OK (also for a
     *  line not configured); HAL_E_NOT_FOUND. */
    hal_status_t (*release)(hal_gpio_t *dev, uint32_t line);
    /** Release every line and the controller. The handle is unusable afterwards. */
    void (*close)(hal_gpio_t *dev);
} hal_gpio_ops_t;

struct hal_gpio {
    const hal_gpio_ops_t *ops;
    void *backend;   /**< backend-owned state */
};

/** Number of lines. Returns HAL_OK, HAL_E_ARG (NULL), HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_gpio_line_count(hal_gpio_t *d, uint32_t *n_lines)
{
    if (d == NULL || d->ops == NULL || n_lines == NULL) return HAL_E_ARG;
    return d->ops->line_count ? d->ops->line_count(d, n_lines) : HAL_E_UNSUPPORTED;
}

/** Configure a line (see the ops table for codes). cfg is read during the
 *  call only. May block briefly on the OS; no timeout. */
static inline hal_status_t hal_gpio_configure(hal_gpio_t *d, uint32_t line, const hal_gpio_config_t *cfg)
{
    if (d == NULL || d->ops == NULL || cfg == NULL) return HAL_E_ARG;
    if (cfg->dir != HAL_GPIO_DIR_INPUT && cfg->dir != HAL_GPIO_DIR_OUTPUT) return HAL_E_ARG;
    if ((cfg->edges & ~HAL_GPIO_EDGE_BOTH) != 0u) return HAL_E_ARG;
    if (cfg->dir == HAL_GPIO_DIR_OUTPUT && cfg->edges != HAL_GPIO_EDGE_NONE) return HAL_E_ARG;
    return d->ops->configure ? d->ops->configure(d, line, cfg) : HAL_E_UNSUPPORTED;
}

/** Read the logical level into *active. Never blocks. */
static inline hal_status_t hal_gpio_read(hal_gpio_t *d, uint32_t line, bool *active)
{
    if (d == NULL || d->ops == NULL || active == NULL) return HAL_E_ARG;
    return d->ops->read ? d->ops->read(d, line, active) : HAL_E_UNSUPPORTED;
}

/** Drive an output to a logical level. Never blocks. */
static inline hal_status_t hal_gpio_write(hal_gpio_t *d, uint32_t line, bool active)
{
    if (d == NULL || d->ops == NULL) return HAL_E_ARG;
    return d->ops->write ? d->ops->write(d, line, active) : HAL_E_UNSUPPORTED;
}

/** Pop the oldest queued edge of an input, waiting up to timeout_us
 *  (0 = poll, HAL_TIMEOUT_FOREVER). */
static inline hal_status_t hal_gpio_wait_edge(hal_gpio_t *d, uint32_t line, hal_gpio_event_t *ev,
                                              uint32_t timeout_us)
{
    if (d == NULL || d->ops == NULL || ev == NULL) return HAL_E_ARG;
    return d->ops->wait_edge ? d->ops->wait_edge(d, line, ev, timeout_us) : HAL_E_UNSUPPORTED;
}

/** Give a line back. */
static inline hal_status_t hal_gpio_release(hal_gpio_t *d, uint32_t line)
{
    if (d == NULL || d->ops == NULL) return HAL_E_ARG;
    return d->ops->release ? d->ops->release(d, line) : HAL_E_UNSUPPORTED;
}

static inline void hal_gpio_close(hal_gpio_t *d)
{
    if (d != NULL && d->ops != NULL && d->ops->close != NULL) d->ops->close(d);
}

/** The null GPIO controller (library coslam_hal_null): every operation
 *  returns HAL_E_UNSUPPORTED. Never NULL. */
hal_gpio_t *hal_gpio_null(void);

#ifdef __cplusplus
}
#endif

#endif /* HAL_GPIO_H */
