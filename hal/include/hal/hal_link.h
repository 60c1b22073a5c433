/*
 * hal/hal_link.h - the inter-robot link: datagrams between robots of one
 * team, addressed by robot id (see hal_common.h for the conventions).
 *
 * The link is UNRELIABLE. A datagram that was accepted by send() may be
 * lost (out of radio range, interference, a full receive queue), and
 * datagrams from one sender may arrive out of order (real transports; the
 * simulator keeps order). A datagram is never split, merged, corrupted or
 * duplicated: it arrives whole, once, or not at all. Protocols above it
 * (the map exchange) carry their own sequence numbers and retry.
 *
 * Semantics:
 *  - self_id: this robot's id, fixed for the life of the instance.
 *  - send: one datagram of 1..HAL_LINK_MAX_PAYLOAD bytes to robot
 *    `dest_id`, or to every other robot in reach with HAL_LINK_BROADCAST.
 *    A robot never receives its own datagrams. HAL_OK means "accepted for
 *    transmission", not "delivered". The data is copied before return.
 *  - recv: pops the oldest received datagram into buf, with the sender's
 *    id and the arrival stamp_us (hal_clock time base of the receiver);
 *    waits at most timeout_us for one. A datagram longer than cap is
 *    discarded after its first cap bytes are copied, and reported as
 *    HAL_E_OVERFLOW with info->len set to its full length (like a
 *    truncated UDP read): size the buffer with HAL_LINK_MAX_PAYLOAD.
 *
 * Backends: simulator hub (sim/hal: range limit, latency, seeded loss),
 * null (hal_link_null()), Cyclone DDS (hal/linux/dds, hal_link_dds.h:
 * carries codec map messages plus a trailer of at most 64 bytes only,
 * anything else is HAL_E_ARG; docs/link-dds.md). Decorator: authentication
 * (hal/linux/auth, hal_link_auth.h: signs sent map messages, refuses and
 * counts unauthenticated ones; docs/security.md), in front of any backend.
 */
#ifndef HAL_LINK_H
#define HAL_LINK_H

#include "hal/hal_common.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest datagram payload [bytes]: one map message of every profile plus
 *  HAL_LINK_TRAILER_RESERVE fits in one datagram (no fragmentation layer;
 *  larger maps send their best COSLAM_MAX_MSG_LANDMARKS landmarks). */
#ifndef HAL_LINK_MAX_PAYLOAD
#define HAL_LINK_MAX_PAYLOAD 16384u
#endif
#if HAL_LINK_MAX_PAYLOAD < 8192u || HAL_LINK_MAX_PAYLOAD > 65000u
#error "HAL_LINK_MAX_PAYLOAD must be in [8192, 65000]"
#endif

/** Bytes a decorator may append to a protocol's datagram (the
 *  authentication trailer, hal_link_auth.h: 52; the DDS backend carries up
 *  to 64). A protocol's largest datagram plus this must fit
 *  HAL_LINK_MAX_PAYLOAD: the map message's does by a compile-time assertion
 *  in every build (firmware/app meeting.c, hal/linux/auth, hal/linux/dds;
 *  coslam/config.h COSLAM_LINK_MSG_LANDMARKS, docs/map-message.md). */
#define HAL_LINK_TRAILER_RESERVE 64u

/** Destination id meaning "every other robot in reach". Not a robot id. */
#define HAL_LINK_BROADCAST 0xFFFFu

typedef struct hal_link hal_link_t;

typedef struct {
    size_t len;          /**< datagram length [bytes] (may exceed cap on HAL_E_OVERFLOW) */
    uint16_t src_id;     /**< sender's robot id */
    uint64_t stamp_us;   /**< arrival time (receiver's hal_clock time base) */
} hal_link_rx_info_t;

typedef struct {
    /** This robot's id; HAL_OK. */
    hal_status_t (*self_id)(hal_link_t *dev, uint16_t *id);
    /** HAL_OK (accepted, not necessarily delivered); HAL_E_ARG (dest is
     *  this robot); HAL_E_BUSY (transmit queue full after timeout_us);
     *  HAL_E_CLOSED; HAL_E_IO. Unknown robot ids are accepted and lost. */
    hal_status_t (*send)(hal_link_t *dev, uint16_t dest_id, const uint8_t *data, size_t len,
                         uint32_t timeout_us);
    /** HAL_OK (*info set, info->len <= cap); HAL_E_TIMEOUT (nothing within
     *  timeout_us); HAL_E_OVERFLOW (datagram longer than cap: first cap
     *  bytes copied, info set, datagram discarded); HAL_E_CLOSED; HAL_E_IO. */
    hal_status_t (*recv)(hal_link_t *dev, uint8_t *buf, size_t cap, hal_link_rx_info_t *info,
                         uint32_t timeout_us);
    /** Leave the link. The handle is unusable afterwards. */
    void (*close)(hal_link_t *dev);
} hal_link_ops_t;

struct hal_link {
    const hal_link_ops_t *ops;
    void *backend;   /**< backend-owned state */
};

/** This robot's id. Returns HAL_OK, HAL_E_ARG (NULL), HAL_E_UNSUPPORTED. Never blocks. */
static inline hal_status_t hal_link_self_id(hal_link_t *d, uint16_t *id)
{
    if (d == NULL || d->ops == NULL || id == NULL) return HAL_E_ARG;
    return d->ops->self_id ? d->ops->self_id(d, id) : HAL_E_UNSUPPORTED;
}

/** Send one datagram of len bytes (1..HAL_LINK_MAX_PAYLOAD) to dest_id or
 *  HAL_LINK_BROADCAST. data is read during the call only. Waits at most
 *  timeout_us for room in the transmit queue. Returns HAL_OK, HAL_E_ARG
 *  (NULL, len 0 or too long, dest = self), HAL_E_BUSY, HAL_E_CLOSED,
 *  HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_link_send(hal_link_t *d, uint16_t dest_id, const uint8_t *data, size_t len,
                                         uint32_t timeout_us)
{
    if (d == NULL || d->ops == NULL || data == NULL || len == 0 || len > HAL_LINK_MAX_PAYLOAD) return HAL_E_ARG;
    return d->ops->send ? d->ops->send(d, dest_id, data, len, timeout_us) : HAL_E_UNSUPPORTED;
}

/** Receive one datagram into buf (capacity cap bytes), waiting at most
 *  timeout_us. Returns HAL_OK, HAL_E_TIMEOUT, HAL_E_OVERFLOW, HAL_E_ARG
 *  (NULL, cap 0), HAL_E_CLOSED, HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_link_recv(hal_link_t *d, uint8_t *buf, size_t cap, hal_link_rx_info_t *info,
                                         uint32_t timeout_us)
{
    if (d == NULL || d->ops == NULL || buf == NULL || cap == 0 || info == NULL) return HAL_E_ARG;
    info->len = 0;
    return d->ops->recv ? d->ops->recv(d, buf, cap, info, timeout_us) : HAL_E_UNSUPPORTED;
}

static inline void hal_link_close(hal_link_t *d)
{
    if (d != NULL && d->ops != NULL && d->ops->close != NULL) d->ops->close(d);
}

/** The null link (library coslam_hal_null): every operation returns
 *  HAL_E_UNSUPPORTED. Never NULL. */
hal_link_t *hal_link_null(void);

#ifdef __cplusplus
}
#endif

#endif /* HAL_LINK_H */
