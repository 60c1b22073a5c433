/*
 * hal/hal_can_socketcan.h - the Linux SocketCAN backend of hal_can.h.
 *
 * One raw CAN socket (PF_CAN, SOCK_RAW, CAN_RAW) bound to one interface
 * ("can0", "vcan0", ...). The state is caller-owned (static or on the
 * stack; no heap) and holds the hal_can_t handle: use &sc->can.
 *
 * Behaviour behind the contract:
 *  - timeouts: poll() with the remaining time rounded up to whole
 *    milliseconds, so a wait never ends early; HAL_TIMEOUT_FOREVER blocks.
 *  - stamps: the kernel receive time (SO_TIMESTAMP, CLOCK_REALTIME) is
 *    turned into CLOCK_MONOTONIC microseconds by subtracting the frame's
 *    age from the monotonic time at read-out (so a wall-clock step cannot
 *    jump the stamps); without a kernel stamp the read-out time is used.
 *    A wall-clock step between a frame's reception and its read-out would
 *    still move that frame's age: a kernel stamp later than the read-out
 *    or older than HAL_CAN_SOCKETCAN_MAX_AGE_US is not believed, the
 *    read-out time is used and `stamps_unbelieved` counts it. Stamps are
 *    clamped to never decrease.
 *  - error state: controller error frames (CAN_ERR_CRTL, CAN_ERR_BUSOFF,
 *    CAN_ERR_RESTARTED, with TEC/REC when the driver sets CAN_ERR_CNT) are
 *    consumed by receive() to track hal_can_status_t; they are never
 *    returned as frames. A send while bus-off returns HAL_E_IO.
 *  - overflow: the kernel's socket drop counter (SO_RXQ_OVFL) and
 *    controller RX-overflow error frames are loss events (HAL_E_OVERFLOW).
 *  - filters: given to the kernel (CAN_RAW_FILTER) and also applied in user
 *    space, so the contract holds for every frame already queued.
 *  - remote frames are supported.
 */
#ifndef HAL_CAN_SOCKETCAN_H
#define HAL_CAN_SOCKETCAN_H

#include "hal/hal_can.h"

#ifdef __cplusplus
extern "C" {
#endif

/** The oldest kernel receive stamp believed at read-out [us]: a frame
 *  waits in the socket queue for the next read (a control period, a few
 *  ms); an age beyond 2 s is a wall-clock step (NTP, the operator), or a
 *  stalled loop whose stamps mean nothing for the drive anyway. */
#define HAL_CAN_SOCKETCAN_MAX_AGE_US 2000000u

typedef struct {
    hal_can_t can;                   /**< the handle; can.backend points back here */
    int fd;                          /**< the socket, -1 when closed */
    int kernel_can;                  /**< 1: a real CAN_RAW socket (kernel filters apply) */
    hal_can_filter_t filters[HAL_CAN_MAX_FILTERS];
    size_t filter_count;             /**< 0: accept everything */
    hal_can_status_t status;
    uint32_t kernel_drops;           /**< last SO_RXQ_OVFL counter seen */
    uint64_t last_stamp_us;          /**< for the non-decreasing stamp guarantee */
    uint32_t stamps_unbelieved;      /**< kernel stamps in the future or older than
                                          HAL_CAN_SOCKETCAN_MAX_AGE_US (read-out time used) */
    hal_can_frame_t pending;         /**< frame held back while an overflow is reported */
    int has_pending;
} hal_can_socketcan_t;

/**
 * Open interface `ifname` (1..15 characters) into the caller-owned *sc.
 * Does not block beyond the system calls. On success &sc->can is ready,
 * with no acceptance filter.
 * Returns HAL_OK; HAL_E_ARG NULL or a bad name length; HAL_E_UNSUPPORTED
 * the kernel has no SocketCAN (EAFNOSUPPORT, EPROTONOSUPPORT);
 * HAL_E_NOT_FOUND no interface of that name; HAL_E_CLOSED the interface is
 * down; HAL_E_IO any other system error. On failure nothing stays open and
 * sc->fd is -1.
 */
hal_status_t hal_can_socketcan_open(hal_can_socketcan_t *sc, const char *ifname);

#ifdef __cplusplus
}
#endif

#endif /* HAL_CAN_SOCKETCAN_H */
