/*
 * hal/hal_serial.h - a byte-stream serial port (the Hokuyo URG's USB-ACM or
 * RS-232 link). This contract is also the template the other HAL headers
 * follow (see hal_common.h for the shared conventions).
 *
 * Semantics:
 *  - write: queues all `len` bytes or fails; returns HAL_OK when every byte
 *    was accepted by the backend (not necessarily on the wire yet).
 *  - read: returns as soon as at least one byte is available, copying up to
 *    `cap` bytes into `buf` and the count into *n_read; waits at most
 *    timeout_us for the first byte (HAL_E_TIMEOUT, *n_read = 0, if none).
 *    A stream has no message boundaries: a reply may arrive split over many
 *    reads, and one read may hold the tail of one reply and the head of the
 *    next.
 *  - flush_input: drops every byte received but not yet read (used to
 *    resynchronise a protocol after an error).
 */
#ifndef HAL_SERIAL_H
#define HAL_SERIAL_H

#include "hal/hal_common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct hal_serial hal_serial_t;

typedef struct {
    /** Set the line rate [baud]; HAL_E_ARG for a rate the backend cannot do.
     *  USB-ACM devices accept any rate and ignore it. */
    hal_status_t (*set_baud)(hal_serial_t *dev, uint32_t baud);
    hal_status_t (*write)(hal_serial_t *dev, const uint8_t *data, size_t len, uint32_t timeout_us);
    hal_status_t (*read)(hal_serial_t *dev, uint8_t *buf, size_t cap, size_t *n_read, uint32_t timeout_us);
    hal_status_t (*flush_input)(hal_serial_t *dev);
    /** Release the port. The handle is unusable afterwards. */
    void (*close)(hal_serial_t *dev);
} hal_serial_ops_t;

struct hal_serial {
    const hal_serial_ops_t *ops;
    void *backend;   /**< backend-owned state */
};

static inline hal_status_t hal_serial_set_baud(hal_serial_t *d, uint32_t baud)
{
    if (d == NULL || d->ops == NULL) return HAL_E_ARG;
    return d->ops->set_baud ? d->ops->set_baud(d, baud) : HAL_E_UNSUPPORTED;
}

static inline hal_status_t hal_serial_write(hal_serial_t *d, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    if (d == NULL || d->ops == NULL || (data == NULL && len > 0)) return HAL_E_ARG;
    return d->ops->write ? d->ops->write(d, data, len, timeout_us) : HAL_E_UNSUPPORTED;
}

static inline hal_status_t hal_serial_read(hal_serial_t *d, uint8_t *buf, size_t cap, size_t *n_read,
                                           uint32_t timeout_us)
{
    if (d == NULL || d->ops == NULL || buf == NULL || cap == 0 || n_read == NULL) return HAL_E_ARG;
    *n_read = 0;
    return d->ops->read ? d->ops->read(d, buf, cap, n_read, timeout_us) : HAL_E_UNSUPPORTED;
}

static inline hal_status_t hal_serial_flush_input(hal_serial_t *d)
{
    if (d == NULL || d->ops == NULL) return HAL_E_ARG;
    return d->ops->flush_input ? d->ops->flush_input(d) : HAL_E_UNSUPPORTED;
}

static inline void hal_serial_close(hal_serial_t *d)
{
    if (d != NULL && d->ops != NULL && d->ops->close != NULL) d->ops->close(d);
}

#ifdef __cplusplus
}
#endif

#endif /* HAL_SERIAL_H */
