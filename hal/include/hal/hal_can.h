/*
 * hal/hal_can.h - a classic CAN 2.0 controller (the Robotino's drive bus:
 * three CiA 402 motor controllers). Follows the template of hal_serial.h;
 * the shared conventions are in hal_common.h.
 *
 * Frames (hal_can_frame_t): an 11-bit (CAN 2.0A) or, with HAL_CAN_FLAG_EXT,
 * a 29-bit (CAN 2.0B) identifier, 0..8 data bytes, optionally a remote
 * request (HAL_CAN_FLAG_RTR: dlc is the requested length, data is unused).
 * No CAN FD. On receive the backend sets stamp_us; on send it is ignored.
 *
 * Time: stamp_us is the receive time in microseconds of the backend's
 * monotonic clock, the same time base as the platform's hal_clock (Linux:
 * CLOCK_MONOTONIC; simulator: the simulated clock). Stamps of successive
 * received frames never decrease.
 *
 * Semantics:
 *  - send: hands one frame to the controller's transmit queue; returns
 *    HAL_OK once the backend accepted it (not necessarily on the wire or
 *    acknowledged yet). If the queue is full it waits at most timeout_us for
 *    room. Frames sent through one handle reach the bus in send order. A
 *    handle never receives its own frames.
 *  - receive: takes the oldest received frame that passed the acceptance
 *    filters, waiting at most timeout_us for one. Frames come in bus order.
 *    If received frames were lost (queue overflow) since the previous call,
 *    this call returns HAL_E_OVERFLOW and no frame, once per loss event;
 *    the lost frames are counted in hal_can_status_t.rx_overflow_count and
 *    the next call continues with the frames that were kept.
 *  - set_filters: acceptance filters; see hal_can_filter_t. After open a
 *    handle accepts every frame (no filter). Frames that were already queued
 *    when filters change may still be delivered.
 *  - get_status: controller error state and counters (see hal_can_status_t).
 *  - close: releases the controller; the handle is unusable afterwards.
 */
#ifndef HAL_CAN_H
#define HAL_CAN_H

#include "hal/hal_common.h"

#include <string.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Data bytes of a classic CAN frame. */
#define HAL_CAN_MAX_DLC 8u
/** Largest 11-bit (standard) identifier. */
#define HAL_CAN_STD_ID_MAX 0x7FFu
/** Largest 29-bit (extended) identifier. */
#define HAL_CAN_EXT_ID_MAX 0x1FFFFFFFu
/** Largest number of acceptance filters any backend must accept. */
#define HAL_CAN_MAX_FILTERS 16u

/** hal_can_frame_t.flags: the identifier is 29-bit (CAN 2.0B). */
#define HAL_CAN_FLAG_EXT 0x01u
/** hal_can_frame_t.flags: remote transmission request (no data bytes). */
#define HAL_CAN_FLAG_RTR 0x02u

typedef struct {
    uint64_t stamp_us;                 /**< receive time [us], backend's monotonic clock; ignored on send */
    uint32_t id;                       /**< identifier, 0..0x7FF, or 0..0x1FFFFFFF with HAL_CAN_FLAG_EXT */
    uint8_t flags;                     /**< HAL_CAN_FLAG_* bits; others must be 0 */
    uint8_t dlc;                       /**< data length [bytes], 0..8 */
    uint8_t data[HAL_CAN_MAX_DLC];     /**< payload; bytes at and after dlc are unspecified */
} hal_can_frame_t;

/**
 * Acceptance filter. A frame passes a filter when it has the same format
 * (HAL_CAN_FLAG_EXT set or clear in both) and (frame.id & mask) ==
 * (id & mask); mask 0 passes every frame of that format. A frame is
 * accepted when it passes at least one filter of the set.
 */
typedef struct {
    uint32_t id;     /**< identifier bits to compare */
    uint32_t mask;   /**< 1 bits are compared, 0 bits are "don't care" */
    uint8_t flags;   /**< HAL_CAN_FLAG_EXT: filter 29-bit frames, else 11-bit frames */
} hal_can_filter_t;

/** Controller fault confinement state (ISO 11898-1). */
typedef enum {
    HAL_CAN_STATE_ERROR_ACTIVE = 0,  /**< normal: both error counters < 96 */
    HAL_CAN_STATE_ERROR_WARNING = 1, /**< an error counter reached 96 */
    HAL_CAN_STATE_ERROR_PASSIVE = 2, /**< an error counter reached 128 */
    HAL_CAN_STATE_BUS_OFF = 3,       /**< TEC > 255: the controller takes no part in bus traffic */
} hal_can_state_t;

typedef struct {
    hal_can_state_t state;
    uint16_t tx_error_count;     /**< TEC, valid when counters_valid */
    uint16_t rx_error_count;     /**< REC, valid when counters_valid */
    uint8_t counters_valid;      /**< 1 if the backend knows TEC/REC, else both are 0 */
    uint32_t rx_overflow_count;  /**< received frames lost because a queue was full, since open */
    uint32_t rx_malformed_count; /**< received frames dropped as malformed (backend specific), since open */
    uint32_t bus_off_count;      /**< times the controller entered bus-off, since open */
} hal_can_status_t;

typedef struct hal_can hal_can_t;

typedef struct {
    /**
     * Queue `frame` for transmission, waiting at most timeout_us for room.
     * HAL_OK accepted; HAL_E_TIMEOUT no room in time (frame not queued);
     * HAL_E_IO controller error, e.g. bus-off (frame not queued);
     * HAL_E_CLOSED interface down or gone; HAL_E_UNSUPPORTED a remote frame
     * on a backend that cannot send them.
     */
    hal_status_t (*send)(hal_can_t *dev, const hal_can_frame_t *frame, uint32_t timeout_us);
    /**
     * Take the oldest accepted frame into *frame, waiting at most
     * timeout_us. HAL_OK a frame; HAL_E_TIMEOUT none in time;
     * HAL_E_OVERFLOW frames were lost (no frame this call, see above);
     * HAL_E_CORRUPT a malformed frame was dropped (counted; no frame this
     * call); HAL_E_IO read error; HAL_E_CLOSED interface down or gone.
     */
    hal_status_t (*receive)(hal_can_t *dev, hal_can_frame_t *frame, uint32_t timeout_us);
    /**
     * Replace the acceptance filters by filters[0..count) (copied; count 0:
     * accept everything). HAL_OK; HAL_E_ARG count above the backend's
     * capacity (at least HAL_CAN_MAX_FILTERS) or a malformed filter;
     * HAL_E_IO the controller refused. Never blocks.
     */
    hal_status_t (*set_filters)(hal_can_t *dev, const hal_can_filter_t *filters, size_t count);
    /** Fill *status. HAL_OK; HAL_E_IO the state could not be read. Never blocks. */
    hal_status_t (*get_status)(hal_can_t *dev, hal_can_status_t *status);
    /** Release the controller. The handle is unusable afterwards. */
    void (*close)(hal_can_t *dev);
} hal_can_ops_t;

struct hal_can {
    const hal_can_ops_t *ops;
    void *backend;   /**< backend-owned state */
};

/** 1 if `f` is a frame the HAL may send: known flags, dlc <= 8, id in range of its format. */
static inline int hal_can_frame_is_valid(const hal_can_frame_t *f)
{
    if (f == NULL) return 0;
    if ((f->flags & (uint8_t)~(HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR)) != 0u) return 0;
    if (f->dlc > HAL_CAN_MAX_DLC) return 0;
    return f->id <= (((f->flags & HAL_CAN_FLAG_EXT) != 0u) ? HAL_CAN_EXT_ID_MAX : HAL_CAN_STD_ID_MAX);
}

/** 1 if frame `f` passes filter `flt` (see hal_can_filter_t). For backends and fakes. */
static inline int hal_can_filter_match(const hal_can_filter_t *flt, const hal_can_frame_t *f)
{
    if (((flt->flags ^ f->flags) & HAL_CAN_FLAG_EXT) != 0u) return 0;
    return ((f->id ^ flt->id) & flt->mask) == 0u;
}

/** HAL_E_ARG for NULL or an invalid frame (hal_can_frame_is_valid), else as the op. */
static inline hal_status_t hal_can_send(hal_can_t *d, const hal_can_frame_t *frame, uint32_t timeout_us)
{
    if (d == NULL || d->ops == NULL || !hal_can_frame_is_valid(frame)) return HAL_E_ARG;
    return d->ops->send ? d->ops->send(d, frame, timeout_us) : HAL_E_UNSUPPORTED;
}

/** HAL_E_ARG for NULL; *frame is zeroed before the op runs. */
static inline hal_status_t hal_can_receive(hal_can_t *d, hal_can_frame_t *frame, uint32_t timeout_us)
{
    if (d == NULL || d->ops == NULL || frame == NULL) return HAL_E_ARG;
    memset(frame, 0, sizeof *frame);
    return d->ops->receive ? d->ops->receive(d, frame, timeout_us) : HAL_E_UNSUPPORTED;
}

/** HAL_E_ARG for NULL filters with count > 0; HAL_E_UNSUPPORTED if the backend cannot filter. */
static inline hal_status_t hal_can_set_filters(hal_can_t *d, const hal_can_filter_t *filters, size_t count)
{
    if (d == NULL || d->ops == NULL || (filters == NULL && count > 0)) return HAL_E_ARG;
    return d->ops->set_filters ? d->ops->set_filters(d, filters, count) : HAL_E_UNSUPPORTED;
}

/** HAL_E_ARG for NULL; *status is zeroed before the op runs. */
static inline hal_status_t hal_can_get_status(hal_can_t *d, hal_can_status_t *status)
{
    if (d == NULL || d->ops == NULL || status == NULL) return HAL_E_ARG;
    memset(status, 0, sizeof *status);
    return d->ops->get_status ? d->ops->get_status(d, status) : HAL_E_UNSUPPORTED;
}

static inline void hal_can_close(hal_can_t *d)
{
    if (d != NULL && d->ops != NULL && d->ops->close != NULL) d->ops->close(d);
}

/** The null backend (no CAN hardware): every operation returns HAL_E_UNSUPPORTED. */
static inline hal_can_t *hal_can_null(void)
{
    static const hal_can_ops_t null_ops = {NULL, NULL, NULL, NULL, NULL};
    static hal_can_t null_dev = {&null_ops, NULL};
    return &null_dev;
}

#ifdef __cplusplus
}
#endif

#endif /* HAL_CAN_H */
