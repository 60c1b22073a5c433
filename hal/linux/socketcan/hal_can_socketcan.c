/*
 * SocketCAN backend of hal_can.h. See hal/hal_can_socketcan.h for the
 * behaviour behind the contract.
 */
#define _GNU_SOURCE

#include "hal/hal_can_socketcan.h"
#include "hal_can_socketcan_internal.h"

#include <errno.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

/* ------------------------------------------------------------------------ */
/* time                                                                     */
/* ------------------------------------------------------------------------ */

static uint64_t clock_us(clockid_t id)
{
    struct timespec ts;
    if (clock_gettime(id, &ts) != 0) return 0;
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* Deadline helper: remaining poll() timeout [ms] rounded up, -1 forever. */
static int remaining_ms(uint32_t timeout_us, uint64_t deadline_us)
{
    if (timeout_us == HAL_TIMEOUT_FOREVER) return -1;
    const uint64_t now = clock_us(CLOCK_MONOTONIC);
    if (now >= deadline_us) return 0;
    const uint64_t ms = (deadline_us - now + 999u) / 1000u;
    return ms > (uint64_t)INT32_MAX ? INT32_MAX : (int)ms;
}

static hal_status_t errno_status(int e)
{
    switch (e) {
    case ENETDOWN:
    case ENODEV:
    case ENXIO:
    case EPIPE:
    case ECONNRESET:
    case EBADF:
        return HAL_E_CLOSED;
    default:
        return HAL_E_IO;
    }
}

/* ------------------------------------------------------------------------ */
/* frames                                                                   */
/* ------------------------------------------------------------------------ */

static void to_kernel(const hal_can_frame_t *f, struct can_frame *cf)
{
    memset(cf, 0, sizeof *cf);
    cf->can_id = f->id;
    if ((f->flags & HAL_CAN_FLAG_EXT) != 0u) cf->can_id |= CAN_EFF_FLAG;
    if ((f->flags & HAL_CAN_FLAG_RTR) != 0u) cf->can_id |= CAN_RTR_FLAG;
    cf->len = f->dlc;
    if ((f->flags & HAL_CAN_FLAG_RTR) == 0u) memcpy(cf->data, f->data, f->dlc);
}

/* 0 if the kernel frame is not a valid classic frame. */
static int from_kernel(const struct can_frame *cf, hal_can_frame_t *f)
{
    if (cf->len > HAL_CAN_MAX_DLC) return 0;
    memset(f, 0, sizeof *f);
    if ((cf->can_id & CAN_EFF_FLAG) != 0u) {
        f->flags |= HAL_CAN_FLAG_EXT;
        f->id = cf->can_id & CAN_EFF_MASK;
    } else {
        if ((cf->can_id & CAN_ERR_MASK & ~CAN_SFF_MASK) != 0u) return 0; /* stray bits in an 11-bit id */
        f->id = cf->can_id & CAN_SFF_MASK;
    }
    if ((cf->can_id & CAN_RTR_FLAG) != 0u) f->flags |= HAL_CAN_FLAG_RTR;
    f->dlc = cf->len;
    if ((f->flags & HAL_CAN_FLAG_RTR) == 0u) memcpy(f->data, cf->data, cf->len);
    return 1;
}

static int accepted(const hal_can_socketcan_t *sc, const hal_can_frame_t *f)
{
    if (sc->filter_count == 0) return 1;
    for (size_t i = 0; i < sc->filter_count; ++i) {
        if (hal_can_filter_match(&sc->filters[i], f)) return 1;
    }
    return 0;
}

/* Track the controller state from an error frame. Returns 1 if it reports
 * lost frames (controller RX overflow). */
static int take_error_frame(hal_can_socketcan_t *sc, const struct can_frame *cf)
{
    hal_can_status_t *st = &sc->status;
    int lost = 0;
    if ((cf->can_id & CAN_ERR_CNT) != 0u && cf->len >= 8u) {
        st->tx_error_count = cf->data[6];
        st->rx_error_count = cf->data[7];
        st->counters_valid = 1;
    }
    if ((cf->can_id & CAN_ERR_CRTL) != 0u && cf->len >= 2u) {
        const uint8_t c = cf->data[1];
        if ((c & CAN_ERR_CRTL_RX_OVERFLOW) != 0u) lost = 1;
        if ((c & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0u) {
            st->state = HAL_CAN_STATE_ERROR_PASSIVE;
        } else if ((c & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) != 0u) {
            st->state = HAL_CAN_STATE_ERROR_WARNING;
        } else if ((c & CAN_ERR_CRTL_ACTIVE) != 0u) {
            st->state = HAL_CAN_STATE_ERROR_ACTIVE;
        }
    }
    if ((cf->can_id & CAN_ERR_BUSOFF) != 0u) {
        if (st->state != HAL_CAN_STATE_BUS_OFF) st->bus_off_count++;
        st->state = HAL_CAN_STATE_BUS_OFF;
    } else if ((cf->can_id & CAN_ERR_RESTARTED) != 0u) {
        st->state = HAL_CAN_STATE_ERROR_ACTIVE;
    }
    return lost;
}

/* ------------------------------------------------------------------------ */
/* ops                                                                      */
/* ------------------------------------------------------------------------ */

static hal_status_t sc_send(hal_can_t *dev, const hal_can_frame_t *frame, uint32_t timeout_us)
{
    hal_can_socketcan_t *sc = (hal_can_socketcan_t *)dev->backend;
    if (sc->fd < 0) return HAL_E_CLOSED;
    if (sc->status.state == HAL_CAN_STATE_BUS_OFF) return HAL_E_IO;
    struct can_frame cf;
    to_kernel(frame, &cf);
    const uint64_t deadline = clock_us(CLOCK_MONOTONIC) + timeout_us;
    for (;;) {
        const ssize_t n = send(sc->fd, &cf, sizeof cf, MSG_DONTWAIT | MSG_NOSIGNAL);
        if (n == (ssize_t)sizeof cf) return HAL_OK;
        if (n >= 0) return HAL_E_IO; /* a partial datagram cannot happen on a datagram socket */
        const int e = errno;
        if (e == EINTR) continue;
        if (e != EAGAIN && e != EWOULDBLOCK && e != ENOBUFS) return errno_status(e);
        const int ms = remaining_ms(timeout_us, deadline);
        if (ms == 0) return HAL_E_TIMEOUT;
        /* ENOBUFS (the interface queue is full) is not signalled by poll():
         * retry after a millisecond. EAGAIN (socket buffer full) is. */
        struct pollfd p = {sc->fd, POLLOUT, 0};
        const int r = poll(&p, 1, e == ENOBUFS ? 1 : ms);
        if (r < 0 && errno != EINTR) return HAL_E_IO;
    }
}

/* Read one datagram; classify it. Returns HAL_OK with *f set for a data or
 * remote frame that passed the filters, HAL_E_BUSY for "consumed, nothing to
 * deliver" (error frame, filtered frame), or an error. */
static hal_status_t read_one(hal_can_socketcan_t *sc, hal_can_frame_t *f, int *lost)
{
    struct can_frame cf;
    struct iovec iov = {&cf, sizeof cf};
    union {
        char buf[CMSG_SPACE(sizeof(struct timeval)) + CMSG_SPACE(sizeof(uint32_t)) + 64];
        struct cmsghdr align;
    } ctl;
    struct msghdr msg;
    memset(&msg, 0, sizeof msg);
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = ctl.buf;
    msg.msg_controllen = sizeof ctl.buf;
    const ssize_t n = recvmsg(sc->fd, &msg, MSG_DONTWAIT);
    if (n < 0) {
        const int e = errno;
        if (e == EAGAIN || e == EWOULDBLOCK || e == EINTR) return HAL_E_BUSY;
        return errno_status(e);
    }
    if (n == 0) return HAL_E_CLOSED; /* SOCK_SEQPACKET peer closed */

    /* the real-time clock first: the age of the kernel's stamp is then
     * measured up to a moment no later than now_mono, so the converted
     * stamp is never earlier than the reception (an early stamp once broke
     * "stamp >= sent" under emulation) */
    const uint64_t now_real = clock_us(CLOCK_REALTIME);
    const uint64_t now_mono = clock_us(CLOCK_MONOTONIC);
    uint64_t stamp = now_mono;
    for (struct cmsghdr *c = CMSG_FIRSTHDR(&msg); c != NULL; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level != SOL_SOCKET) continue;
        if (c->cmsg_type == SCM_TIMESTAMP && c->cmsg_len >= CMSG_LEN(sizeof(struct timeval))) {
            struct timeval tv;
            memcpy(&tv, CMSG_DATA(c), sizeof tv);
            const uint64_t rx_real = (uint64_t)tv.tv_sec * 1000000u + (uint64_t)tv.tv_usec;
            if (rx_real > now_real || now_real - rx_real > HAL_CAN_SOCKETCAN_MAX_AGE_US) {
                /* received after now, or queued longer than believable:
                 * the wall clock stepped between the reception and now
                 * (or the loop stalled); the read-out time, counted */
                sc->stamps_unbelieved++;
            } else {
                const uint64_t age = now_real - rx_real;
                stamp = age < now_mono ? now_mono - age : 0u;
            }
        } else if (c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(uint32_t))) {
            uint32_t drops;
            memcpy(&drops, CMSG_DATA(c), sizeof drops);
            if (drops != sc->kernel_drops) {
                sc->status.rx_overflow_count += drops - sc->kernel_drops;
                sc->kernel_drops = drops;
                *lost = 1;
            }
        }
    }
    if (stamp < sc->last_stamp_us) stamp = sc->last_stamp_us;

    if ((size_t)n != sizeof cf || (msg.msg_flags & MSG_TRUNC) != 0) {
        sc->status.rx_malformed_count++;
        return HAL_E_CORRUPT;
    }
    if ((cf.can_id & CAN_ERR_FLAG) != 0u) {
        if (take_error_frame(sc, &cf)) {
            sc->status.rx_overflow_count++;
            *lost = 1;
        }
        return HAL_E_BUSY;
    }
    if (!from_kernel(&cf, f)) {
        sc->status.rx_malformed_count++;
        return HAL_E_CORRUPT;
    }
    /* a frame on the wire means the controller is back from bus-off */
    if (sc->status.state == HAL_CAN_STATE_BUS_OFF) sc->status.state = HAL_CAN_STATE_ERROR_ACTIVE;
    if (!accepted(sc, f)) return HAL_E_BUSY;
    f->stamp_us = stamp;
    sc->last_stamp_us = stamp;
    return HAL_OK;
}

static hal_status_t sc_receive(hal_can_t *dev, hal_can_frame_t *frame, uint32_t timeout_us)
{
    hal_can_socketcan_t *sc = (hal_can_socketcan_t *)dev->backend;
    if (sc->fd < 0) return HAL_E_CLOSED;
    if (sc->has_pending) {
        *frame = sc->pending;
        sc->has_pending = 0;
        return HAL_OK;
    }
    const uint64_t deadline = clock_us(CLOCK_MONOTONIC) + timeout_us;
    for (;;) {
        int lost = 0;
        hal_can_frame_t f;
        const hal_status_t s = read_one(sc, &f, &lost);
        if (lost) {
            /* report the loss first; a frame read with it is held back */
            if (s == HAL_OK) {
                sc->pending = f;
                sc->has_pending = 1;
            }
            return HAL_E_OVERFLOW;
        }
        if (s == HAL_OK) {
            *frame = f;
            return HAL_OK;
        }
        if (s != HAL_E_BUSY) return s;
        /* nothing deliverable was read: wait for more */
        const int ms = remaining_ms(timeout_us, deadline);
        struct pollfd p = {sc->fd, POLLIN, 0};
        const int r = poll(&p, 1, ms);
        if (r < 0) {
            if (errno == EINTR) continue;
            return HAL_E_IO;
        }
        if (r == 0) {
            if (remaining_ms(timeout_us, deadline) == 0) return HAL_E_TIMEOUT;
            continue;
        }
        if ((p.revents & POLLNVAL) != 0) return HAL_E_CLOSED;
        if ((p.revents & POLLIN) == 0 && (p.revents & (POLLHUP | POLLERR)) != 0) {
            return (p.revents & POLLHUP) != 0 ? HAL_E_CLOSED : HAL_E_IO;
        }
    }
}

static hal_status_t sc_set_filters(hal_can_t *dev, const hal_can_filter_t *filters, size_t count)
{
    hal_can_socketcan_t *sc = (hal_can_socketcan_t *)dev->backend;
    if (sc->fd < 0) return HAL_E_CLOSED;
    if (count > HAL_CAN_MAX_FILTERS) return HAL_E_ARG;
    for (size_t i = 0; i < count; ++i) {
        if ((filters[i].flags & (uint8_t)~HAL_CAN_FLAG_EXT) != 0u) return HAL_E_ARG;
    }
    if (sc->kernel_can) {
        struct can_filter kf[HAL_CAN_MAX_FILTERS];
        size_t n = count;
        if (count == 0) {
            kf[0].can_id = 0; /* one filter that passes everything */
            kf[0].can_mask = 0;
            n = 1;
        }
        for (size_t i = 0; i < count; ++i) {
            const int ext = (filters[i].flags & HAL_CAN_FLAG_EXT) != 0u;
            const uint32_t idmask = ext ? CAN_EFF_MASK : CAN_SFF_MASK;
            kf[i].can_id = (filters[i].id & idmask) | (ext ? CAN_EFF_FLAG : 0u);
            kf[i].can_mask = (filters[i].mask & idmask) | CAN_EFF_FLAG;
        }
        if (setsockopt(sc->fd, SOL_CAN_RAW, CAN_RAW_FILTER, kf, (socklen_t)(n * sizeof kf[0])) != 0) {
            return HAL_E_IO;
        }
    }
    if (count > 0) memcpy(sc->filters, filters, count * sizeof filters[0]);
    sc->filter_count = count;
    return HAL_OK;
}

static hal_status_t sc_get_status(hal_can_t *dev, hal_can_status_t *status)
{
    const hal_can_socketcan_t *sc = (const hal_can_socketcan_t *)dev->backend;
    *status = sc->status;
    return HAL_OK;
}

static void sc_close(hal_can_t *dev)
{
    hal_can_socketcan_t *sc = (hal_can_socketcan_t *)dev->backend;
    if (sc->fd >= 0) (void)close(sc->fd);
    sc->fd = -1;
}

static const hal_can_ops_t socketcan_ops = {
    .send = sc_send,
    .receive = sc_receive,
    .set_filters = sc_set_filters,
    .get_status = sc_get_status,
    .close = sc_close,
};

/* ------------------------------------------------------------------------ */
/* open                                                                     */
/* ------------------------------------------------------------------------ */

static void init_state(hal_can_socketcan_t *sc, int fd, int kernel_can)
{
    memset(sc, 0, sizeof *sc);
    sc->can.ops = &socketcan_ops;
    sc->can.backend = sc;
    sc->fd = fd;
    sc->kernel_can = kernel_can;
    sc->status.state = HAL_CAN_STATE_ERROR_ACTIVE;
    const int one = 1;
    /* both are optional: without them stamps are taken at read-out and only
     * controller-reported losses are seen */
    (void)setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &one, sizeof one);
    (void)setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof one);
}

hal_status_t hal_can_socketcan_open_fd(hal_can_socketcan_t *sc, int fd)
{
    if (sc == NULL) {
        if (fd >= 0) (void)close(fd);
        return HAL_E_ARG;
    }
    if (fd < 0) {
        sc->fd = -1;
        sc->can.ops = NULL;
        return HAL_E_ARG;
    }
    init_state(sc, fd, 0);
    return HAL_OK;
}

hal_status_t hal_can_socketcan_open(hal_can_socketcan_t *sc, const char *ifname)
{
    if (sc == NULL) return HAL_E_ARG;
    sc->fd = -1;
    sc->can.ops = NULL;
    if (ifname == NULL) return HAL_E_ARG;
    const size_t len = strnlen(ifname, IFNAMSIZ);
    if (len == 0 || len >= IFNAMSIZ) return HAL_E_ARG;

    const int fd = socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
    if (fd < 0) {
        const int e = errno;
        return (e == EAFNOSUPPORT || e == EPROTONOSUPPORT) ? HAL_E_UNSUPPORTED : HAL_E_IO;
    }
    hal_status_t st;
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    memcpy(ifr.ifr_name, ifname, len + 1u);
    if (ioctl(fd, SIOCGIFINDEX, &ifr) != 0) {
        st = errno == ENODEV ? HAL_E_NOT_FOUND : HAL_E_IO;
        goto fail;
    }
    /* controller state changes come as error frames; receive() consumes them */
    const can_err_mask_t err_mask = CAN_ERR_CRTL | CAN_ERR_BUSOFF | CAN_ERR_RESTARTED;
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) != 0) {
        st = HAL_E_IO;
        goto fail;
    }
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(fd, (const struct sockaddr *)&addr, sizeof addr) != 0) {
        const int e = errno;
        st = e == ENODEV ? HAL_E_NOT_FOUND : e == ENETDOWN ? HAL_E_CLOSED : HAL_E_IO;
        goto fail;
    }
    /* binding to an interface that is down succeeds: the kernel only sets a
     * pending ENETDOWN on the socket (net/can/raw.c), which then fails the
     * first send or receive once, even after the interface came up. So ask
     * the interface, and clear a pending error. */
    if (ioctl(fd, SIOCGIFFLAGS, &ifr) == 0 && (ifr.ifr_flags & IFF_UP) == 0) {
        st = HAL_E_CLOSED;
        goto fail;
    }
    int pending = 0;
    socklen_t pending_len = sizeof pending;
    (void)getsockopt(fd, SOL_SOCKET, SO_ERROR, &pending, &pending_len);
    init_state(sc, fd, 1);
    return HAL_OK;

fail:
    (void)close(fd);
    sc->fd = -1;
    return st;
}
