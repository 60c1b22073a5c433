/*
 * hal_serial_linux.c - termios backend of hal_serial_t. Contract:
 * hal/hal_serial.h (semantics) and hal/hal_serial_linux.h (this backend).
 */
#define _DEFAULT_SOURCE 1 /* CRTSCTS, TIOCEXCL */
#define _POSIX_C_SOURCE 200809L

#include "hal/hal_serial_linux.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <string.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

static hal_serial_linux_t *state_of(hal_serial_t *dev)
{
    return (hal_serial_linux_t *)dev->backend;
}

/* termios speed constant for a rate, or 0 if there is none. */
static speed_t speed_of(uint32_t baud)
{
    switch (baud) {
    case 1200: return B1200;
    case 2400: return B2400;
    case 4800: return B4800;
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 500000: return B500000;
    case 576000: return B576000;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 1152000: return B1152000;
    case 1500000: return B1500000;
    case 2000000: return B2000000;
    case 2500000: return B2500000;
    case 3000000: return B3000000;
    case 3500000: return B3500000;
    case 4000000: return B4000000;
    default: return (speed_t)0;
    }
}

static uint64_t now_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000U + (uint64_t)ts.tv_nsec / 1000U;
}

/* Milliseconds for poll() left until deadline_us (rounded up), -1 forever. */
static int poll_ms(uint32_t timeout_us, uint64_t deadline_us)
{
    if (timeout_us == HAL_TIMEOUT_FOREVER) {
        return -1;
    }
    const uint64_t t = now_us();
    if (t >= deadline_us) {
        return 0;
    }
    const uint64_t ms = (deadline_us - t + 999U) / 1000U;
    return ms > 0x7FFFFFFFU ? 0x7FFFFFFF : (int)ms;
}

/* Wait for `events` on fd. HAL_OK when ready, else TIMEOUT/CLOSED/IO. */
static hal_status_t wait_fd(int fd, short events, uint32_t timeout_us, uint64_t deadline_us)
{
    for (;;) {
        struct pollfd p = {.fd = fd, .events = events, .revents = 0};
        const int r = poll(&p, 1, poll_ms(timeout_us, deadline_us));
        if (r < 0) {
            if (errno == EINTR) {
                continue;
            }
            return HAL_E_IO;
        }
        if (r == 0) {
            return HAL_E_TIMEOUT;
        }
        if ((p.revents & POLLNVAL) != 0) {
            return HAL_E_CLOSED;
        }
        if ((p.revents & events) != 0) {
            return HAL_OK;
        }
        if ((p.revents & POLLHUP) != 0) {
            return HAL_E_CLOSED;
        }
        return HAL_E_IO; /* POLLERR */
    }
}

static hal_status_t apply_raw(int fd, speed_t speed)
{
    struct termios t;
    if (tcgetattr(fd, &t) != 0) {
        return HAL_E_IO;
    }
    t.c_iflag &= ~(tcflag_t)(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON | IXOFF | IXANY);
    t.c_oflag &= ~(tcflag_t)OPOST;
    t.c_lflag &= ~(tcflag_t)(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
    t.c_cflag &= ~(tcflag_t)(CSIZE | PARENB | CSTOPB | CRTSCTS);
    t.c_cflag |= (tcflag_t)(CS8 | CREAD | CLOCAL);
    t.c_cc[VMIN] = 0;
    t.c_cc[VTIME] = 0;
    if (cfsetispeed(&t, speed) != 0 || cfsetospeed(&t, speed) != 0) {
        return HAL_E_ARG;
    }
    if (tcsetattr(fd, TCSANOW, &t) != 0) {
        return errno == EINVAL ? HAL_E_ARG : HAL_E_IO;
    }
    return HAL_OK;
}

static hal_status_t linux_set_baud(hal_serial_t *dev, uint32_t baud)
{
    hal_serial_linux_t *s = state_of(dev);
    if (s->fd < 0) {
        return HAL_E_CLOSED;
    }
    const speed_t sp = speed_of(baud);
    if (sp == (speed_t)0) {
        return HAL_E_ARG;
    }
    const hal_status_t st = apply_raw(s->fd, sp);
    if (st == HAL_OK) {
        s->baud = baud;
    }
    return st;
}

static hal_status_t linux_write(hal_serial_t *dev, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    hal_serial_linux_t *s = state_of(dev);
    if (s->fd < 0) {
        return HAL_E_CLOSED;
    }
    const uint64_t deadline = now_us() + timeout_us;
    size_t off = 0;
    while (off < len) {
        const ssize_t n = write(s->fd, data + off, len - off);
        if (n > 0) {
            off += (size_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
            return (errno == EIO || errno == EPIPE || errno == ENODEV) ? HAL_E_CLOSED : HAL_E_IO;
        }
        const hal_status_t w = wait_fd(s->fd, POLLOUT, timeout_us, deadline);
        if (w != HAL_OK) {
            return w; /* HAL_E_TIMEOUT: the first `off` bytes were sent */
        }
    }
    return HAL_OK;
}

static hal_status_t linux_read(hal_serial_t *dev, uint8_t *buf, size_t cap, size_t *n_read, uint32_t timeout_us)
{
    hal_serial_linux_t *s = state_of(dev);
    if (s->fd < 0) {
        return HAL_E_CLOSED;
    }
    const uint64_t deadline = now_us() + timeout_us;
    int ready = 0; /* poll() reported the descriptor readable */
    for (;;) {
        const ssize_t n = read(s->fd, buf, cap);
        if (n > 0) {
            *n_read = (size_t)n;
            return HAL_OK;
        }
        if (n == 0) {
            /* raw mode with VMIN = VTIME = 0 returns 0 for "nothing yet";
             * 0 right after poll() said readable is a hang-up */
            if (ready) {
                return HAL_E_CLOSED;
            }
        } else if (errno == EINTR) {
            continue;
        } else if (errno != EAGAIN && errno != EWOULDBLOCK) {
            return (errno == EIO || errno == ENODEV) ? HAL_E_CLOSED : HAL_E_IO;
        }
        const hal_status_t w = wait_fd(s->fd, POLLIN, timeout_us, deadline);
        if (w != HAL_OK) {
            return w;
        }
        ready = 1;
    }
}

static hal_status_t linux_flush_input(hal_serial_t *dev)
{
    hal_serial_linux_t *s = state_of(dev);
    if (s->fd < 0) {
        return HAL_E_CLOSED;
    }
    return tcflush(s->fd, TCIFLUSH) == 0 ? HAL_OK : HAL_E_IO;
}

static void linux_close(hal_serial_t *dev)
{
    hal_serial_linux_t *s = state_of(dev);
    if (s == NULL || s->fd < 0) {
        return;
    }
    if (s->have_saved) {
        (void)tcsetattr(s->fd, TCSANOW, &s->saved);
    }
    (void)close(s->fd);
    s->fd = -1;
    s->have_saved = 0;
}

static const hal_serial_ops_t linux_ops = {
    .set_baud = linux_set_baud,
    .write = linux_write,
    .read = linux_read,
    .flush_input = linux_flush_input,
    .close = linux_close,
};

hal_status_t hal_serial_linux_open(hal_serial_t *dev, hal_serial_linux_t *state, const char *path, uint32_t baud)
{
    if (dev == NULL || state == NULL || path == NULL) {
        return HAL_E_ARG;
    }
    memset(state, 0, sizeof *state);
    state->fd = -1;
    dev->ops = NULL;
    dev->backend = NULL;
    const speed_t sp = speed_of(baud);
    if (sp == (speed_t)0) {
        return HAL_E_ARG;
    }
    const int fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        switch (errno) {
        case ENOENT:
        case ENODEV:
        case ENXIO:
        case ENOTDIR: return HAL_E_NOT_FOUND;
        case EBUSY: return HAL_E_BUSY;
        default: return HAL_E_IO;
        }
    }
    if (!isatty(fd)) {
        (void)close(fd);
        return HAL_E_UNSUPPORTED;
    }
    if (tcgetattr(fd, &state->saved) == 0) {
        state->have_saved = 1;
    }
    (void)ioctl(fd, TIOCEXCL); /* keep other processes off the port */
    const hal_status_t st = apply_raw(fd, sp);
    if (st != HAL_OK) {
        (void)close(fd);
        state->have_saved = 0;
        return st;
    }
    (void)tcflush(fd, TCIOFLUSH); /* drop what arrived before we owned the port */
    state->fd = fd;
    state->baud = baud;
    dev->ops = &linux_ops;
    dev->backend = state;
    return HAL_OK;
}

int hal_serial_linux_fd(const hal_serial_t *dev)
{
    if (dev == NULL || dev->ops != &linux_ops || dev->backend == NULL) {
        return -1;
    }
    return ((const hal_serial_linux_t *)dev->backend)->fd;
}
