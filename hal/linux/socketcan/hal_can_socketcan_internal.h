/*
 * hal_can_socketcan_internal.h - entry points of the SocketCAN backend that
 * are not part of its public API: used by its tests (and by nothing else).
 */
#ifndef HAL_CAN_SOCKETCAN_INTERNAL_H
#define HAL_CAN_SOCKETCAN_INTERNAL_H

#include "hal/hal_can_socketcan.h"

#ifdef __cplusplus
extern "C" {
#endif

/**
 * Adopt an already open datagram socket `fd` that carries one
 * `struct can_frame` per datagram (a CAN_RAW socket, or in tests one end of
 * socketpair(AF_UNIX, SOCK_SEQPACKET)). Takes ownership of fd: it is closed
 * by hal_can_close(), and also on failure. No kernel CAN options are set
 * (filters are then applied in user space only); SO_TIMESTAMP and
 * SO_RXQ_OVFL are requested, and their absence is tolerated.
 * Returns HAL_OK; HAL_E_ARG NULL sc or fd < 0.
 */
hal_status_t hal_can_socketcan_open_fd(hal_can_socketcan_t *sc, int fd);

#ifdef __cplusplus
}
#endif

#endif /* HAL_CAN_SOCKETCAN_INTERNAL_H */
