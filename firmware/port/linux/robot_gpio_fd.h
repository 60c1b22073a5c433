/*
 * robot_gpio_fd.h - END-TO-END TESTS ONLY (docs/e2e.md): a GPIO backend
 * (hal/hal_gpio.h) on an inherited socket from the e2e device server
 * (coslam-robot --gpio-fd N), standing in for a GPIO chip on a machine
 * without one (no gpio-sim here). The libgpiod fake of the GPIO tests is
 * linked into a test executable with -Wl,--wrap and cannot be shared
 * across processes; this carries the same line states over the wire
 * instead, as --can-fd carries CAN frames.
 *
 * Wire: a SOCK_SEQPACKET (or SOCK_DGRAM) socket, one text datagram per
 * change, electrical levels (the backend applies active-low, as the kernel
 * does):
 *   server -> robot   "P line level [stamp_us]"
 *                                      input pin `line` went to `level` (0
 *                                      low, 1 high) at stamp_us
 *                                      (CLOCK_MONOTONIC, the robot's clock
 *                                      base; absent: when the robot reads it)
 *   robot -> server   "O line level"   output `line` is driven to `level`
 *                                      (at configure and at every write)
 * Pins start low. Every operation first drains the socket, without
 * waiting. Bad datagrams are refused and counted (`bad`). The peer's close
 * makes every operation answer HAL_E_CLOSED (the device slot then reports
 * the GPIO lost and retries).
 *
 * Semantics otherwise as hal_gpio.h: ROBOT_GPIO_FD_LINES lines; a queue of
 * ROBOT_GPIO_FD_QUEUE edges per input, HAL_E_OVERFLOW once when it
 * overflowed. Caller-owned state, no heap.
 */
#ifndef COSLAM_PORT_ROBOT_GPIO_FD_H
#define COSLAM_PORT_ROBOT_GPIO_FD_H

#include <stdbool.h>
#include <stdint.h>

#include "hal/hal_clock.h"
#include "hal/hal_gpio.h"

#ifdef __cplusplus
extern "C" {
#endif

#define ROBOT_GPIO_FD_LINES 16u
#define ROBOT_GPIO_FD_QUEUE 16u

typedef struct {
    bool configured;
    hal_gpio_config_t cfg;
    bool pin_high;                               /**< electrical level */
    hal_gpio_event_t queue[ROBOT_GPIO_FD_QUEUE]; /**< FIFO of logical edges */
    uint32_t q_head, q_len;
    bool overflowed;
} robot_gpio_fd_line_t;

typedef struct {
    hal_gpio_t dev;            /**< the handle; dev.backend = this */
    int fd;                    /**< owned (a dup of the inherited one); -1 closed */
    bool peer_closed;
    hal_clock_t *clock;
    robot_gpio_fd_line_t lines[ROBOT_GPIO_FD_LINES];
    uint32_t received;         /**< good datagrams from the server */
    uint32_t bad;              /**< refused datagrams */
    uint32_t sent;             /**< output datagrams */
} robot_gpio_fd_t;

/** Adopt `fd` (dup'ed: the inherited one stays for a reopen). Returns
 *  HAL_OK; HAL_E_ARG (NULL, fd < 0); HAL_E_IO (dup failed). */
hal_status_t robot_gpio_fd_open(robot_gpio_fd_t *g, int fd, hal_clock_t *clock);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_GPIO_FD_H */
