/*
 * hal/hal_gpio_linux.h - hal_gpio on one Linux GPIO chip through
 * libgpiod v1 (Debian bookworm: libgpiod-dev 1.6, GPIO character device
 * uAPI v1). Built only when pkg-config finds libgpiod
 * (COSLAM_HAVE_GPIOD=1 on the coslam_hal_linux target).
 *
 * Mapping of the contract:
 *  - line index = line offset on the chip; line_count = the chip's lines,
 *    capped at HAL_GPIO_LINUX_MAX_LINES (higher offsets: HAL_E_NOT_FOUND).
 *  - configure: gpiod_line_request() as input, output, or event line
 *    (rising/falling/both), with GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW. The
 *    kernel applies active-low to values and to edge kinds, so both stay
 *    logical. EBUSY (line used elsewhere) -> HAL_E_BUSY.
 *  - read on an output returns the value last written (cached, not the
 *    pin: the contract's read-back).
 *  - wait_edge: gpiod_line_event_wait() + gpiod_line_event_read(); the
 *    event time is the kernel's, CLOCK_MONOTONIC since Linux 5.7 (older
 *    kernels stamp with CLOCK_REALTIME: do not compare those with
 *    hal_clock_linux). uAPI v1 does not report queue overflow, so this
 *    backend never returns HAL_E_OVERFLOW.
 *
 * After hal_gpio_close every operation returns HAL_E_CLOSED.
 *
 * State is caller-owned (no heap in this file; libgpiod allocates the chip
 * object). Not thread-safe (one thread at a time).
 */
#ifndef HAL_GPIO_LINUX_H
#define HAL_GPIO_LINUX_H

#include "hal/hal_gpio.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Lines one instance can address. */
#ifndef HAL_GPIO_LINUX_MAX_LINES
#define HAL_GPIO_LINUX_MAX_LINES 64u
#endif

/** Consumer label shown by `gpioinfo` [characters, without NUL]. */
#define HAL_GPIO_LINUX_CONSUMER_MAX 31u

struct gpiod_chip;
struct gpiod_line;

typedef struct {
    struct gpiod_line *line;  /**< NULL until first configured */
    bool configured;
    hal_gpio_config_t cfg;
    bool out_active;          /**< last written logical level (outputs) */
} hal_gpio_linux_line_t;

typedef struct {
    hal_gpio_t dev;           /**< the handle to pass to hal_gpio_* */
    struct gpiod_chip *chip;  /**< NULL when closed */
    uint32_t n_lines;
    char consumer[HAL_GPIO_LINUX_CONSUMER_MAX + 1u];
    hal_gpio_linux_line_t lines[HAL_GPIO_LINUX_MAX_LINES];
} hal_gpio_linux_t;

/** Open a GPIO chip by path ("/dev/gpiochip0"), name ("gpiochip0"),
 *  label or number ("0"), as gpiod_chip_open_lookup() accepts; `consumer`
 *  labels the lines this instance requests (truncated to
 *  HAL_GPIO_LINUX_CONSUMER_MAX). Returns HAL_OK; HAL_E_ARG (NULL);
 *  HAL_E_NOT_FOUND (no such chip); HAL_E_IO. Release with
 *  hal_gpio_close(&g->dev). */
hal_status_t hal_gpio_linux_open(hal_gpio_linux_t *g, const char *chip, const char *consumer);

#ifdef __cplusplus
}
#endif

#endif /* HAL_GPIO_LINUX_H */
