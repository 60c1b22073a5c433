/*
 * hal/hal_serial_linux.h - Linux backend of hal_serial_t (hal_serial.h).
 *
 * The port is put in raw mode (8N1, no echo, no line editing, no flow
 * control, no CR/LF translation, no signals) and opened non-blocking; every
 * wait is a poll() on the descriptor, so timeouts follow the HAL contract:
 * 0 polls, HAL_TIMEOUT_FOREVER blocks, other values wait at most timeout_us
 * rounded up to the next millisecond (poll's resolution). The settings found
 * at open are restored by close. Works for USB-ACM (/dev/ttyACM*, the URG),
 * USB-serial and RS-232 ports, and pseudo-terminals (tests).
 *
 * Not async-signal-safe; one instance per thread at a time (HAL rule).
 */
#ifndef HAL_SERIAL_LINUX_H
#define HAL_SERIAL_LINUX_H

#include <termios.h>

#include "hal/hal_serial.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Backend state; owned by the caller, must outlive the handle's use. */
typedef struct {
    int fd;                /**< -1 when closed */
    struct termios saved;  /**< settings before open, restored by close */
    int have_saved;        /**< 1 if `saved` holds valid settings */
    uint32_t baud;         /**< current line rate [baud] */
} hal_serial_linux_t;

/**
 * Open the serial device at `path` (e.g. "/dev/ttyACM0") at `baud` and make
 * `dev` a handle on it (dev->backend = state). Blocking: no (open is
 * O_NONBLOCK). Returns:
 *   HAL_OK;
 *   HAL_E_ARG        NULL argument, or a baud rate termios cannot express
 *                    (supported: 1200 ... 4000000 standard rates);
 *   HAL_E_NOT_FOUND  no such device (ENOENT, ENODEV, ENXIO);
 *   HAL_E_BUSY       the device is in use (EBUSY) or locked (EACCES/EPERM
 *                    are reported as HAL_E_IO);
 *   HAL_E_UNSUPPORTED the path is not a terminal;
 *   HAL_E_IO         any other OS error (errno is left as the OS set it).
 * On failure nothing stays open and `dev` is not usable.
 */
hal_status_t hal_serial_linux_open(hal_serial_t *dev, hal_serial_linux_t *state, const char *path, uint32_t baud);

/** The file descriptor behind an open handle (for select/epoll loops), or -1. */
int hal_serial_linux_fd(const hal_serial_t *dev);

#ifdef __cplusplus
}
#endif

#endif /* HAL_SERIAL_LINUX_H */
