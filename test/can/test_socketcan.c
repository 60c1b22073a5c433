/*
 * The SocketCAN backend of hal_can.h without a CAN interface (no vcan in
 * the build machine): the data path runs over socketpair(AF_UNIX,
 * SOCK_SEQPACKET) carrying struct can_frame datagrams (the backend's
 * internal open-from-fd entry), and the interface lookup runs against
 * link-time fakes of socket/ioctl/bind/setsockopt (-Wl,--wrap=...), which
 * also inject failures. recvmsg is wrapped to inject the kernel's
 * SO_RXQ_OVFL drop counter. In pass-through mode the real kernel is asked.
 */
#define _GNU_SOURCE
#include "../slam/test_util.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <stdarg.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "hal/hal_can_socketcan.h"
#include "hal_can_socketcan_internal.h"

/* ------------------------------------------------------------------------ */
/* link-time fakes                                                          */
/* ------------------------------------------------------------------------ */

static struct {
    int fake;             /* 0: pass everything to the real calls */
    int socket_errno, ioctl_errno, bind_errno, sockopt_errno;
    int socket_calls;
    int socket_domain, socket_type, socket_protocol;
    int ifindex;
    char ifname[IFNAMSIZ];
    int fd, peer;         /* backend end, test end */
    struct sockaddr_can bound;
    int bound_len;
    can_err_mask_t err_mask;
    int err_mask_set;
    struct can_filter filters[32];
    int n_filters;
    uint32_t inject_drops; /* recvmsg: report this SO_RXQ_OVFL counter (0: none) */
    int if_down;           /* SIOCGIFFLAGS: the interface is down */
    int64_t stamp_shift_us; /* recvmsg: move the kernel's SCM_TIMESTAMP by this (a wall-clock step) */
} W;

int __real_socket(int domain, int type, int protocol);
int __wrap_socket(int domain, int type, int protocol);
int __real_ioctl(int fd, unsigned long request, ...);
int __wrap_ioctl(int fd, unsigned long request, ...);
int __real_bind(int fd, const struct sockaddr *addr, socklen_t len);
int __wrap_bind(int fd, const struct sockaddr *addr, socklen_t len);
int __real_setsockopt(int fd, int level, int name, const void *val, socklen_t len);
int __wrap_setsockopt(int fd, int level, int name, const void *val, socklen_t len);
ssize_t __real_recvmsg(int fd, struct msghdr *msg, int flags);
ssize_t __wrap_recvmsg(int fd, struct msghdr *msg, int flags);

int __wrap_socket(int domain, int type, int protocol)
{
    if (!W.fake) return __real_socket(domain, type, protocol);
    W.socket_calls++;
    W.socket_domain = domain;
    W.socket_type = type;
    W.socket_protocol = protocol;
    if (W.socket_errno != 0) {
        errno = W.socket_errno;
        return -1;
    }
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv) != 0) return -1;
    W.fd = sv[0];
    W.peer = sv[1];
    return sv[0];
}

int __wrap_ioctl(int fd, unsigned long request, ...)
{
    va_list ap;
    va_start(ap, request);
    void *arg = va_arg(ap, void *);
    va_end(ap);
    if (!W.fake || fd != W.fd) return __real_ioctl(fd, request, arg);
    if (request == SIOCGIFFLAGS) {
        struct ifreq *fl = (struct ifreq *)arg;
        fl->ifr_flags = (short)(W.if_down ? 0 : (IFF_UP | IFF_RUNNING));
        return 0;
    }
    if (request != SIOCGIFINDEX) {
        errno = ENOTTY;
        return -1;
    }
    struct ifreq *ifr = (struct ifreq *)arg;
    memcpy(W.ifname, ifr->ifr_name, IFNAMSIZ);
    if (W.ioctl_errno != 0) {
        errno = W.ioctl_errno;
        return -1;
    }
    ifr->ifr_ifindex = W.ifindex;
    return 0;
}

int __wrap_bind(int fd, const struct sockaddr *addr, socklen_t len)
{
    if (!W.fake || fd != W.fd) return __real_bind(fd, addr, len);
    memcpy(&W.bound, addr, len < sizeof W.bound ? len : sizeof W.bound);
    W.bound_len = (int)len;
    if (W.bind_errno != 0) {
        errno = W.bind_errno;
        return -1;
    }
    return 0;
}

int __wrap_setsockopt(int fd, int level, int name, const void *val, socklen_t len)
{
    if (!W.fake || fd != W.fd || level != SOL_CAN_RAW) return __real_setsockopt(fd, level, name, val, len);
    if (W.sockopt_errno != 0) {
        errno = W.sockopt_errno;
        return -1;
    }
    if (name == CAN_RAW_ERR_FILTER) {
        memcpy(&W.err_mask, val, sizeof W.err_mask);
        W.err_mask_set = 1;
    } else if (name == CAN_RAW_FILTER) {
        W.n_filters = (int)(len / sizeof(struct can_filter));
        memcpy(W.filters, val, len);
    }
    return 0;
}

ssize_t __wrap_recvmsg(int fd, struct msghdr *msg, int flags)
{
    const size_t cap = msg->msg_controllen;
    const ssize_t n = __real_recvmsg(fd, msg, flags);
    if (n > 0 && W.stamp_shift_us != 0) {
        for (struct cmsghdr *c = CMSG_FIRSTHDR(msg); c != NULL; c = CMSG_NXTHDR(msg, c)) {
            if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMP) {
                struct timeval tv;
                memcpy(&tv, CMSG_DATA(c), sizeof tv);
                const int64_t us = (int64_t)tv.tv_sec * 1000000 + tv.tv_usec + W.stamp_shift_us;
                tv.tv_sec = (time_t)(us / 1000000);
                tv.tv_usec = (suseconds_t)(us % 1000000);
                memcpy(CMSG_DATA(c), &tv, sizeof tv);
            }
        }
    }
    if (n > 0 && W.inject_drops != 0) {
        const size_t used = CMSG_ALIGN(msg->msg_controllen);
        if (used + CMSG_SPACE(sizeof(uint32_t)) <= cap) {
            struct cmsghdr *c = (struct cmsghdr *)((char *)msg->msg_control + used);
            c->cmsg_level = SOL_SOCKET;
            c->cmsg_type = SO_RXQ_OVFL;
            c->cmsg_len = CMSG_LEN(sizeof(uint32_t));
            memcpy(CMSG_DATA(c), &W.inject_drops, sizeof(uint32_t));
            msg->msg_controllen = used + CMSG_SPACE(sizeof(uint32_t));
        }
    }
    return n;
}

/* ------------------------------------------------------------------------ */
/* helpers                                                                  */
/* ------------------------------------------------------------------------ */

static uint64_t mono_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static int fd_is_open(int fd) { return fcntl(fd, F_GETFD) != -1 || errno != EBADF; }

static hal_can_socketcan_t g_sc;
static int g_peer = -1;

static int setup_pair(void **state)
{
    (void)state;
    memset(&W, 0, sizeof W);
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    assert_int_equal(hal_can_socketcan_open_fd(&g_sc, sv[0]), HAL_OK);
    g_peer = sv[1];
    return 0;
}

static int teardown_pair(void **state)
{
    (void)state;
    hal_can_close(&g_sc.can);
    if (g_peer >= 0) close(g_peer);
    g_peer = -1;
    return 0;
}

static void peer_write(uint32_t can_id, uint8_t len, const uint8_t *data)
{
    struct can_frame cf;
    memset(&cf, 0, sizeof cf);
    cf.can_id = can_id;
    cf.len = len;
    if (data != NULL) memcpy(cf.data, data, len > 8 ? 8 : len);
    assert_int_equal(write(g_peer, &cf, sizeof cf), (ssize_t)sizeof cf);
}

static void peer_read(struct can_frame *cf)
{
    struct pollfd p = {g_peer, POLLIN, 0};
    assert_int_equal(poll(&p, 1, 1000), 1);
    assert_int_equal(read(g_peer, cf, sizeof *cf), (ssize_t)sizeof *cf);
}

static hal_can_frame_t frame(uint32_t id, uint8_t flags, uint8_t dlc, const uint8_t *data)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.flags = flags;
    f.dlc = dlc;
    if (data != NULL) memcpy(f.data, data, dlc);
    return f;
}

/* ------------------------------------------------------------------------ */
/* the contract's inline wrappers                                           */
/* ------------------------------------------------------------------------ */

static void test_wrappers(void **state)
{
    (void)state;
    static const hal_can_ops_t none = {NULL, NULL, NULL, NULL, NULL};
    hal_can_t empty = {&none, NULL};
    hal_can_frame_t f = frame(0x123, 0, 2, (const uint8_t *)"\x01\x02");
    hal_can_status_t st;
    hal_can_filter_t flt = {0x100, 0x700, 0};
    assert_int_equal(hal_can_send(&empty, &f, 0), HAL_E_UNSUPPORTED);
    assert_int_equal(hal_can_receive(&empty, &f, 0), HAL_E_UNSUPPORTED);
    assert_int_equal(hal_can_set_filters(&empty, &flt, 1), HAL_E_UNSUPPORTED);
    assert_int_equal(hal_can_get_status(&empty, &st), HAL_E_UNSUPPORTED);
    hal_can_close(&empty); /* no-op */
    hal_can_close(NULL);
    /* invalid frames never reach a backend */
    f = frame(0x123, 0, 2, NULL);
    assert_int_equal(hal_can_send(NULL, &f, 0), HAL_E_ARG);
    assert_int_equal(hal_can_send(&empty, NULL, 0), HAL_E_ARG);
    f.dlc = 9;
    assert_int_equal(hal_can_send(&empty, &f, 0), HAL_E_ARG);
    f = frame(0x800, 0, 0, NULL);
    assert_int_equal(hal_can_send(&empty, &f, 0), HAL_E_ARG);
    f = frame(0x800, HAL_CAN_FLAG_EXT, 0, NULL);
    assert_int_equal(hal_can_send(&empty, &f, 0), HAL_E_UNSUPPORTED);
    f = frame(0x20000000, HAL_CAN_FLAG_EXT, 0, NULL);
    assert_int_equal(hal_can_send(&empty, &f, 0), HAL_E_ARG);
    f = frame(0x1, 0x04, 0, NULL);
    assert_int_equal(hal_can_send(&empty, &f, 0), HAL_E_ARG);
    assert_int_equal(hal_can_set_filters(&empty, NULL, 1), HAL_E_ARG);
    assert_int_equal(hal_can_receive(&empty, NULL, 0), HAL_E_ARG);
    assert_int_equal(hal_can_get_status(&empty, NULL), HAL_E_ARG);
    /* filter matching: format and masked id */
    f = frame(0x185, 0, 0, NULL);
    flt = (hal_can_filter_t){0x180, 0x780, 0};
    assert_true(hal_can_filter_match(&flt, &f));
    f.id = 0x205;
    assert_false(hal_can_filter_match(&flt, &f));
    f = frame(0x185, HAL_CAN_FLAG_EXT, 0, NULL);
    assert_false(hal_can_filter_match(&flt, &f));
    flt.flags = HAL_CAN_FLAG_EXT;
    assert_true(hal_can_filter_match(&flt, &f));
    /* the null backend */
    hal_can_t *null_can = hal_can_null();
    f = frame(0x1, 0, 0, NULL);
    assert_int_equal(hal_can_send(null_can, &f, 0), HAL_E_UNSUPPORTED);
    assert_int_equal(hal_can_receive(null_can, &f, 1000), HAL_E_UNSUPPORTED);
    assert_int_equal(hal_can_get_status(null_can, &st), HAL_E_UNSUPPORTED);
    assert_int_equal(hal_can_set_filters(null_can, NULL, 0), HAL_E_UNSUPPORTED);
    hal_can_close(null_can);
    /* status names */
    assert_string_equal(hal_status_str(HAL_E_NOT_FOUND), "HAL_E_NOT_FOUND");
}

/* ------------------------------------------------------------------------ */
/* open by interface name (fakes)                                           */
/* ------------------------------------------------------------------------ */

static void test_open_arguments(void **state)
{
    (void)state;
    memset(&W, 0, sizeof W);
    W.fake = 1;
    hal_can_socketcan_t sc;
    assert_int_equal(hal_can_socketcan_open(NULL, "can0"), HAL_E_ARG);
    assert_int_equal(hal_can_socketcan_open(&sc, NULL), HAL_E_ARG);
    assert_int_equal(hal_can_socketcan_open(&sc, ""), HAL_E_ARG);
    assert_int_equal(hal_can_socketcan_open(&sc, "abcdefghijklmno"), HAL_OK); /* 15 characters fit */
    hal_can_close(&sc.can);
    if (W.peer > 0) close(W.peer);
    const int calls = W.socket_calls;
    assert_int_equal(hal_can_socketcan_open(&sc, "abcdefghijklmnop"), HAL_E_ARG); /* 16 do not */
    assert_int_equal(W.socket_calls, calls);
    assert_int_equal(sc.fd, -1);
    assert_int_equal(hal_can_socketcan_open_fd(&sc, -1), HAL_E_ARG);
}

static void test_open_failures(void **state)
{
    (void)state;
    hal_can_socketcan_t sc;
    /* no SocketCAN in the kernel */
    memset(&W, 0, sizeof W);
    W.fake = 1;
    W.socket_errno = EAFNOSUPPORT;
    assert_int_equal(hal_can_socketcan_open(&sc, "can0"), HAL_E_UNSUPPORTED);
    W.socket_errno = EMFILE;
    assert_int_equal(hal_can_socketcan_open(&sc, "can0"), HAL_E_IO);
    /* unknown interface: the socket is closed again */
    memset(&W, 0, sizeof W);
    W.fake = 1;
    W.ioctl_errno = ENODEV;
    assert_int_equal(hal_can_socketcan_open(&sc, "nocan7"), HAL_E_NOT_FOUND);
    assert_string_equal(W.ifname, "nocan7");
    assert_false(fd_is_open(W.fd));
    assert_int_equal(sc.fd, -1);
    close(W.peer);
    /* other ioctl failure */
    memset(&W, 0, sizeof W);
    W.fake = 1;
    W.ioctl_errno = EPERM;
    assert_int_equal(hal_can_socketcan_open(&sc, "can0"), HAL_E_IO);
    assert_false(fd_is_open(W.fd));
    close(W.peer);
    /* the error filter refused */
    memset(&W, 0, sizeof W);
    W.fake = 1;
    W.sockopt_errno = ENOPROTOOPT;
    assert_int_equal(hal_can_socketcan_open(&sc, "can0"), HAL_E_IO);
    assert_false(fd_is_open(W.fd));
    close(W.peer);
    /* bind: interface down, vanished, other */
    const int errs[3] = {ENETDOWN, ENODEV, EADDRINUSE};
    const hal_status_t want[3] = {HAL_E_CLOSED, HAL_E_NOT_FOUND, HAL_E_IO};
    for (int i = 0; i < 3; ++i) {
        memset(&W, 0, sizeof W);
        W.fake = 1;
        W.bind_errno = errs[i];
        assert_int_equal(hal_can_socketcan_open(&sc, "can0"), want[i]);
        assert_false(fd_is_open(W.fd));
        close(W.peer);
    }
    /* an interface that is down binds without error (Linux only marks the
     * socket): refused as closed all the same, the socket closed */
    memset(&W, 0, sizeof W);
    W.fake = 1;
    W.if_down = 1;
    assert_int_equal(hal_can_socketcan_open(&sc, "can0"), HAL_E_CLOSED);
    assert_false(fd_is_open(W.fd));
    assert_int_equal(sc.fd, -1);
    close(W.peer);
}

static void test_open_by_name(void **state)
{
    (void)state;
    memset(&W, 0, sizeof W);
    W.fake = 1;
    W.ifindex = 7;
    hal_can_socketcan_t sc;
    assert_int_equal(hal_can_socketcan_open(&sc, "can1"), HAL_OK);
    assert_int_equal(W.socket_domain, PF_CAN);
    assert_int_equal(W.socket_type & 0xF, SOCK_RAW);
    assert_int_equal(W.socket_protocol, CAN_RAW);
    assert_string_equal(W.ifname, "can1");
    assert_int_equal(W.bound_len, (int)sizeof(struct sockaddr_can));
    assert_int_equal(W.bound.can_family, AF_CAN);
    assert_int_equal(W.bound.can_ifindex, 7);
    assert_true(W.err_mask_set);
    assert_int_equal(W.err_mask, CAN_ERR_CRTL | CAN_ERR_BUSOFF | CAN_ERR_RESTARTED);
    assert_int_equal(sc.kernel_can, 1);
    /* frames go out as struct can_frame */
    g_peer = W.peer;
    const uint8_t d[3] = {0xDE, 0xAD, 0x01};
    hal_can_frame_t f = frame(0x601, 0, 3, d);
    assert_int_equal(hal_can_send(&sc.can, &f, 0), HAL_OK);
    struct can_frame cf;
    peer_read(&cf);
    assert_int_equal(cf.can_id, 0x601);
    assert_int_equal(cf.len, 3);
    assert_memory_equal(cf.data, d, 3);
    /* filters reach the kernel with the format bit compared */
    const hal_can_filter_t flt[2] = {{0x180, 0x780, 0}, {0x1ABCDE00, 0x1FFFFF00, HAL_CAN_FLAG_EXT}};
    assert_int_equal(hal_can_set_filters(&sc.can, flt, 2), HAL_OK);
    assert_int_equal(W.n_filters, 2);
    assert_int_equal(W.filters[0].can_id, 0x180);
    assert_int_equal(W.filters[0].can_mask, 0x780 | CAN_EFF_FLAG);
    assert_int_equal(W.filters[1].can_id, 0x1ABCDE00 | CAN_EFF_FLAG);
    assert_int_equal(W.filters[1].can_mask, 0x1FFFFF00 | CAN_EFF_FLAG);
    /* no filter: one pass-all kernel filter (zero kernel filters would pass nothing) */
    assert_int_equal(hal_can_set_filters(&sc.can, NULL, 0), HAL_OK);
    assert_int_equal(W.n_filters, 1);
    assert_int_equal(W.filters[0].can_id, 0);
    assert_int_equal(W.filters[0].can_mask, 0);
    W.sockopt_errno = EINVAL;
    assert_int_equal(hal_can_set_filters(&sc.can, flt, 1), HAL_E_IO);
    hal_can_close(&sc.can);
    assert_false(fd_is_open(W.fd));
    close(W.peer);
    g_peer = -1;
}

static void test_real_kernel(void **state)
{
    (void)state;
    memset(&W, 0, sizeof W); /* pass-through: ask the running kernel */
    hal_can_socketcan_t sc;
    const hal_status_t s = hal_can_socketcan_open(&sc, "coslamnone0");
    /* without SocketCAN: unsupported; with it: no such interface */
    assert_true(s == HAL_E_UNSUPPORTED || s == HAL_E_NOT_FOUND);
    assert_int_equal(sc.fd, -1);
}

/* ------------------------------------------------------------------------ */
/* data path over a socketpair                                              */
/* ------------------------------------------------------------------------ */

static void test_send_formats(void **state)
{
    (void)state;
    struct can_frame cf;
    const uint8_t d8[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    hal_can_frame_t f = frame(0x7FF, 0, 8, d8);
    assert_int_equal(hal_can_send(&g_sc.can, &f, 0), HAL_OK);
    peer_read(&cf);
    assert_int_equal(cf.can_id, 0x7FF);
    assert_int_equal(cf.len, 8);
    assert_memory_equal(cf.data, d8, 8);
    f = frame(0x1ABCDEF0, HAL_CAN_FLAG_EXT, 1, d8);
    assert_int_equal(hal_can_send(&g_sc.can, &f, 0), HAL_OK);
    peer_read(&cf);
    assert_int_equal(cf.can_id, 0x1ABCDEF0u | CAN_EFF_FLAG);
    assert_int_equal(cf.len, 1);
    f = frame(0x123, HAL_CAN_FLAG_RTR, 4, NULL);
    assert_int_equal(hal_can_send(&g_sc.can, &f, 0), HAL_OK);
    peer_read(&cf);
    assert_int_equal(cf.can_id, 0x123u | CAN_RTR_FLAG);
    assert_int_equal(cf.len, 4);
    f = frame(0x000, 0, 0, NULL);
    assert_int_equal(hal_can_send(&g_sc.can, &f, 0), HAL_OK);
    peer_read(&cf);
    assert_int_equal(cf.can_id, 0);
    assert_int_equal(cf.len, 0);
}

static void test_receive_formats_and_stamps(void **state)
{
    (void)state;
    const uint8_t d[8] = {9, 8, 7, 6, 5, 4, 3, 2};
    const uint64_t before = mono_us();
    peer_write(0x585, 8, d);
    peer_write(0x12345 | CAN_EFF_FLAG, 2, d);
    peer_write(0x700 | CAN_RTR_FLAG, 1, NULL);
    hal_can_frame_t f;
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    const uint64_t after = mono_us();
    assert_int_equal(f.id, 0x585);
    assert_int_equal(f.flags, 0);
    assert_int_equal(f.dlc, 8);
    assert_memory_equal(f.data, d, 8);
    assert_true(f.stamp_us >= before && f.stamp_us <= after);
    uint64_t prev = f.stamp_us;
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x12345);
    assert_int_equal(f.flags, HAL_CAN_FLAG_EXT);
    assert_int_equal(f.dlc, 2);
    assert_true(f.stamp_us >= prev);
    prev = f.stamp_us;
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x700);
    assert_int_equal(f.flags, HAL_CAN_FLAG_RTR);
    assert_int_equal(f.dlc, 1);
    assert_true(f.stamp_us >= prev);
    /* the stamp is the kernel's receive time, not the read-out time */
    peer_write(0x181, 0, NULL);
    const uint64_t written = mono_us();
    usleep(30000);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    const uint64_t read_at = mono_us();
    assert_true(read_at - f.stamp_us >= 25000);
    assert_true(f.stamp_us <= written + 5000);
}

/* A wall-clock step between a frame's reception and its read-out: the
 * kernel's stamp (CLOCK_REALTIME) then says the frame is an hour old, or
 * from the future. Not believed: the read-out time, counted; a believable
 * age (0.5 s) is still taken from the kernel's stamp. */
static void test_receive_stamp_across_clock_step(void **state)
{
    (void)state;
    /* the believable one first: stamps never decrease, so after a read-out
     * stamp a 0.5 s old one would be clamped */
    const int64_t shifts[] = {-500000, -3600LL * 1000000, 3600LL * 1000000, -2500000, 1000};
    const int believed[] = {1, 0, 0, 0, 0};
    uint32_t unbelieved = 0;
    for (size_t k = 0; k < sizeof shifts / sizeof shifts[0]; ++k) {
        W.stamp_shift_us = shifts[k];
        peer_write(0x181, 0, NULL);
        const uint64_t before = mono_us();
        hal_can_frame_t f;
        assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
        const uint64_t after = mono_us();
        if (believed[k]) {
            assert_true(f.stamp_us + 450000 <= after && f.stamp_us + 550000 >= before);
        } else {
            unbelieved++;
            assert_true(f.stamp_us <= after);
            assert_true(f.stamp_us + 20000 >= before); /* about the read-out time */
        }
        assert_int_equal(g_sc.stamps_unbelieved, unbelieved);
    }
    W.stamp_shift_us = 0;
}

static void test_receive_timeouts(void **state)
{
    (void)state;
    hal_can_frame_t f;
    uint64_t t0 = mono_us();
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_TIMEOUT);
    assert_true(mono_us() - t0 < 200000); /* no wait (loose bound for loaded CI) */
    t0 = mono_us();
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 30000), HAL_E_TIMEOUT);
    const uint64_t waited = mono_us() - t0;
    assert_true(waited >= 30000);
    assert_true(waited < 500000);
    /* a frame already there is returned at once even with a long timeout */
    peer_write(0x100, 0, NULL);
    t0 = mono_us();
    assert_int_equal(hal_can_receive(&g_sc.can, &f, HAL_TIMEOUT_FOREVER), HAL_OK);
    assert_true(mono_us() - t0 < 500000);
}

static void test_send_timeout(void **state)
{
    (void)state;
    /* nobody reads the peer: the datagram queue fills up */
    hal_can_frame_t f = frame(0x200, 0, 8, NULL);
    int sent = 0;
    hal_status_t s = HAL_OK;
    while (sent < 100000 && (s = hal_can_send(&g_sc.can, &f, 0)) == HAL_OK) sent++;
    assert_int_equal(s, HAL_E_TIMEOUT);
    assert_true(sent > 0);
    const uint64_t t0 = mono_us();
    assert_int_equal(hal_can_send(&g_sc.can, &f, 20000), HAL_E_TIMEOUT);
    assert_true(mono_us() - t0 >= 20000);
    /* room again once the peer reads */
    struct can_frame cf;
    peer_read(&cf);
    assert_int_equal(hal_can_send(&g_sc.can, &f, 100000), HAL_OK);
}

static void test_error_frames(void **state)
{
    (void)state;
    hal_can_status_t st;
    hal_can_frame_t f;
    assert_int_equal(hal_can_get_status(&g_sc.can, &st), HAL_OK);
    assert_int_equal(st.state, HAL_CAN_STATE_ERROR_ACTIVE);
    assert_int_equal(st.counters_valid, 0);
    uint8_t e[8] = {0, CAN_ERR_CRTL_RX_WARNING, 0, 0, 0, 0, 97, 12};
    peer_write(CAN_ERR_FLAG | CAN_ERR_CRTL | CAN_ERR_CNT, 8, e);
    /* error frames are consumed, not returned */
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_TIMEOUT);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.state, HAL_CAN_STATE_ERROR_WARNING);
    assert_int_equal(st.tx_error_count, 97);
    assert_int_equal(st.rx_error_count, 12);
    assert_int_equal(st.counters_valid, 1);
    e[1] = CAN_ERR_CRTL_TX_PASSIVE | CAN_ERR_CRTL_TX_WARNING;
    e[6] = 130;
    peer_write(CAN_ERR_FLAG | CAN_ERR_CRTL | CAN_ERR_CNT, 8, e);
    peer_write(0x123, 0, NULL); /* a data frame behind it is delivered */
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x123);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.state, HAL_CAN_STATE_ERROR_PASSIVE);
    assert_int_equal(st.tx_error_count, 130);
    /* bus-off: sending is refused */
    peer_write(CAN_ERR_FLAG | CAN_ERR_BUSOFF, 8, NULL);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_TIMEOUT);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.state, HAL_CAN_STATE_BUS_OFF);
    assert_int_equal(st.bus_off_count, 1);
    f = frame(0x1, 0, 0, NULL);
    assert_int_equal(hal_can_send(&g_sc.can, &f, 0), HAL_E_IO);
    /* restarted: active again */
    peer_write(CAN_ERR_FLAG | CAN_ERR_RESTARTED, 8, NULL);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_TIMEOUT);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.state, HAL_CAN_STATE_ERROR_ACTIVE);
    f = frame(0x1, 0, 0, NULL);
    assert_int_equal(hal_can_send(&g_sc.can, &f, 0), HAL_OK);
    /* back to active through the controller flag */
    e[1] = CAN_ERR_CRTL_TX_PASSIVE;
    peer_write(CAN_ERR_FLAG | CAN_ERR_CRTL, 8, e);
    e[1] = CAN_ERR_CRTL_ACTIVE;
    peer_write(CAN_ERR_FLAG | CAN_ERR_CRTL, 8, e);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_TIMEOUT);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.state, HAL_CAN_STATE_ERROR_ACTIVE);
}

static void test_overflow_reporting(void **state)
{
    (void)state;
    hal_can_frame_t f;
    hal_can_status_t st;
    /* a controller RX overflow is a loss event */
    const uint8_t e[8] = {0, CAN_ERR_CRTL_RX_OVERFLOW, 0, 0, 0, 0, 0, 0};
    peer_write(CAN_ERR_FLAG | CAN_ERR_CRTL, 8, e);
    peer_write(0x181, 0, NULL);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_OVERFLOW);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x181);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.rx_overflow_count, 1);
    /* the kernel's socket drop counter: 3 lost; the frame read with the
     * news is held back and delivered by the next call */
    W.inject_drops = 3;
    peer_write(0x182, 0, NULL);
    peer_write(0x183, 0, NULL);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_OVERFLOW);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.rx_overflow_count, 4);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x182);
    /* same counter again: no new loss */
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x183);
    W.inject_drops = 5;
    peer_write(0x184, 0, NULL);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_OVERFLOW);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x184);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.rx_overflow_count, 6);
    W.inject_drops = 0;
}

static void test_malformed_datagrams(void **state)
{
    (void)state;
    hal_can_frame_t f;
    hal_can_status_t st;
    const uint8_t junk[5] = {1, 2, 3, 4, 5};
    assert_int_equal(write(g_peer, junk, sizeof junk), 5);
    peer_write(0x100, 9, NULL);    /* len > 8 */
    peer_write(0x900, 0, NULL);    /* bits above an 11-bit id */
    peer_write(0x101, 1, junk);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_CORRUPT);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_CORRUPT);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_CORRUPT);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x101);
    hal_can_get_status(&g_sc.can, &st);
    assert_int_equal(st.rx_malformed_count, 3);
}

static void test_filters(void **state)
{
    (void)state;
    hal_can_frame_t f;
    const hal_can_filter_t flt[2] = {{0x180, 0x780, 0}, {0x700, 0x7FF, 0}};
    assert_int_equal(hal_can_set_filters(&g_sc.can, flt, 2), HAL_OK);
    peer_write(0x185, 0, NULL);
    peer_write(0x205, 0, NULL);
    peer_write(0x185 | CAN_EFF_FLAG, 0, NULL);
    peer_write(0x701, 0, NULL);
    peer_write(0x700, 0, NULL);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x185);
    assert_int_equal(f.flags, 0);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x700);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_TIMEOUT);
    /* a filtered-out frame does not end a wait early */
    peer_write(0x205, 0, NULL);
    const uint64_t t0 = mono_us();
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 20000), HAL_E_TIMEOUT);
    assert_true(mono_us() - t0 >= 20000);
    hal_can_filter_t many[HAL_CAN_MAX_FILTERS + 1];
    memset(many, 0, sizeof many);
    assert_int_equal(hal_can_set_filters(&g_sc.can, many, HAL_CAN_MAX_FILTERS + 1), HAL_E_ARG);
    hal_can_filter_t bad = {0, 0, 0x80};
    assert_int_equal(hal_can_set_filters(&g_sc.can, &bad, 1), HAL_E_ARG);
    /* back to accept-all */
    assert_int_equal(hal_can_set_filters(&g_sc.can, NULL, 0), HAL_OK);
    peer_write(0x205, 0, NULL);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_OK);
    assert_int_equal(f.id, 0x205);
}

static void test_peer_gone_and_close(void **state)
{
    (void)state;
    hal_can_frame_t f = frame(0x1, 0, 0, NULL);
    close(g_peer);
    g_peer = -1;
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 10000), HAL_E_CLOSED);
    f = frame(0x1, 0, 0, NULL);
    assert_int_equal(hal_can_send(&g_sc.can, &f, 0), HAL_E_CLOSED);
    const int fd = g_sc.fd;
    hal_can_close(&g_sc.can);
    assert_false(fd_is_open(fd));
    assert_int_equal(hal_can_send(&g_sc.can, &f, 0), HAL_E_CLOSED);
    assert_int_equal(hal_can_receive(&g_sc.can, &f, 0), HAL_E_CLOSED);
    hal_can_close(&g_sc.can); /* twice is harmless */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_wrappers),
        cmocka_unit_test(test_open_arguments),
        cmocka_unit_test(test_open_failures),
        cmocka_unit_test(test_open_by_name),
        cmocka_unit_test(test_real_kernel),
        cmocka_unit_test_setup_teardown(test_send_formats, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_receive_formats_and_stamps, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_receive_stamp_across_clock_step, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_receive_timeouts, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_send_timeout, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_error_frames, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_overflow_reporting, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_malformed_datagrams, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_filters, setup_pair, teardown_pair),
        cmocka_unit_test_setup_teardown(test_peer_gone_and_close, setup_pair, teardown_pair),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
