/* The e2e tests' GPIO backend on an inherited socket (robot_gpio_fd.h). */
#include "robot_gpio_fd.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

static robot_gpio_fd_t *of(hal_gpio_t *d)
{
    return (robot_gpio_fd_t *)d->backend;
}

static bool logical(const robot_gpio_fd_line_t *l)
{
    return l->pin_high != l->cfg.active_low;
}

static void queue_edge(robot_gpio_fd_line_t *l, uint8_t edge, uint64_t stamp_us)
{
    if ((l->cfg.edges & edge) == 0U) {
        return;
    }
    if (l->q_len == ROBOT_GPIO_FD_QUEUE) {
        l->overflowed = true; /* newer edges dropped, as hal_gpio.h says */
        return;
    }
    hal_gpio_event_t *ev = &l->queue[(l->q_head + l->q_len) % ROBOT_GPIO_FD_QUEUE];
    ev->edge = edge;
    ev->stamp_us = stamp_us;
    l->q_len++;
}

/* One "P line level [stamp_us]" datagram. */
static void apply(robot_gpio_fd_t *g, const char *text)
{
    unsigned line = 0U, level = 0U;
    unsigned long long stamp = 0U;
    char tail = '\0';
    const int n = sscanf(text, "P %u %u %llu %c", &line, &level, &stamp, &tail);
    if ((n != 2 && n != 3) || line >= ROBOT_GPIO_FD_LINES || level > 1U) {
        g->bad++;
        return;
    }
    uint64_t stamp_us = (uint64_t)stamp;
    if (n == 2) {
        (void)hal_clock_now_us(g->clock, &stamp_us);
    }
    g->received++;
    robot_gpio_fd_line_t *l = &g->lines[line];
    const bool high = level == 1U;
    if (l->configured && l->cfg.dir == HAL_GPIO_DIR_OUTPUT) {
        g->bad++; /* the server does not drive our outputs */
        return;
    }
    if (high == l->pin_high) {
        return;
    }
    const bool was = l->configured && logical(l);
    l->pin_high = high;
    if (l->configured) {
        queue_edge(l, logical(l) && !was ? HAL_GPIO_EDGE_RISING : HAL_GPIO_EDGE_FALLING, stamp_us);
    }
}

/* Read what the server sent, without waiting. */
static hal_status_t drain(robot_gpio_fd_t *g)
{
    if (g->fd < 0 || g->peer_closed) {
        return HAL_E_CLOSED;
    }
    for (;;) {
        char buf[64];
        const ssize_t n = recv(g->fd, buf, sizeof buf - 1U, MSG_DONTWAIT);
        if (n > 0) {
            buf[n] = '\0';
            apply(g, buf);
            continue;
        }
        if (n == 0) {
            g->peer_closed = true;
            return HAL_E_CLOSED;
        }
        if (errno == EINTR) {
            continue;
        }
        return errno == EAGAIN || errno == EWOULDBLOCK ? HAL_OK : HAL_E_IO;
    }
}

static hal_status_t send_level(robot_gpio_fd_t *g, uint32_t line, bool high)
{
    char buf[32];
    const int n = snprintf(buf, sizeof buf, "O %u %u", (unsigned)line, high ? 1U : 0U);
    ssize_t w;
    do {
        w = send(g->fd, buf, (size_t)n, MSG_DONTWAIT | MSG_NOSIGNAL);
    } while (w < 0 && errno == EINTR);
    if (w < 0) {
        return errno == EPIPE || errno == ECONNRESET ? HAL_E_CLOSED : HAL_E_IO;
    }
    g->sent++;
    return HAL_OK;
}

static hal_status_t op_line_count(hal_gpio_t *d, uint32_t *n)
{
    *n = ROBOT_GPIO_FD_LINES;
    return drain(of(d));
}

static hal_status_t op_configure(hal_gpio_t *d, uint32_t line, const hal_gpio_config_t *cfg)
{
    robot_gpio_fd_t *g = of(d);
    if (line >= ROBOT_GPIO_FD_LINES) {
        return HAL_E_NOT_FOUND;
    }
    const hal_status_t st = drain(g);
    if (st != HAL_OK) {
        return st;
    }
    robot_gpio_fd_line_t *l = &g->lines[line];
    l->cfg = *cfg;
    l->q_len = 0U;
    l->q_head = 0U;
    l->overflowed = false;
    l->configured = true;
    if (cfg->dir == HAL_GPIO_DIR_OUTPUT) {
        l->pin_high = cfg->initial_active != cfg->active_low;
        const hal_status_t ws = send_level(g, line, l->pin_high);
        if (ws != HAL_OK) {
            l->configured = false;
            return ws;
        }
    }
    return HAL_OK;
}

static hal_status_t checked_line(robot_gpio_fd_t *g, uint32_t line, robot_gpio_fd_line_t **out)
{
    if (line >= ROBOT_GPIO_FD_LINES) {
        return HAL_E_NOT_FOUND;
    }
    const hal_status_t st = drain(g);
    if (st != HAL_OK) {
        return st;
    }
    *out = &g->lines[line];
    return (*out)->configured ? HAL_OK : HAL_E_CLOSED;
}

static hal_status_t op_read(hal_gpio_t *d, uint32_t line, bool *active)
{
    robot_gpio_fd_line_t *l = NULL;
    const hal_status_t st = checked_line(of(d), line, &l);
    if (st == HAL_OK) {
        *active = logical(l);
    }
    return st;
}

static hal_status_t op_write(hal_gpio_t *d, uint32_t line, bool active)
{
    robot_gpio_fd_t *g = of(d);
    robot_gpio_fd_line_t *l = NULL;
    const hal_status_t st = checked_line(g, line, &l);
    if (st != HAL_OK) {
        return st;
    }
    if (l->cfg.dir != HAL_GPIO_DIR_OUTPUT) {
        return HAL_E_ARG;
    }
    const bool high = active != l->cfg.active_low;
    if (high == l->pin_high) {
        return HAL_OK; /* no change on the pin: nothing to tell */
    }
    l->pin_high = high;
    return send_level(g, line, high);
}

static hal_status_t op_wait_edge(hal_gpio_t *d, uint32_t line, hal_gpio_event_t *ev, uint32_t timeout_us)
{
    robot_gpio_fd_t *g = of(d);
    robot_gpio_fd_line_t *l = NULL;
    hal_status_t st = checked_line(g, line, &l);
    if (st != HAL_OK) {
        return st;
    }
    if (l->cfg.dir != HAL_GPIO_DIR_INPUT || l->cfg.edges == HAL_GPIO_EDGE_NONE) {
        return HAL_E_ARG;
    }
    uint64_t start = 0;
    (void)hal_clock_now_us(g->clock, &start);
    for (;;) {
        if (l->overflowed) {
            l->overflowed = false;
            l->q_len = 0U;
            return HAL_E_OVERFLOW;
        }
        if (l->q_len > 0U) {
            *ev = l->queue[l->q_head];
            l->q_head = (l->q_head + 1U) % ROBOT_GPIO_FD_QUEUE;
            l->q_len--;
            return HAL_OK;
        }
        uint64_t now = start;
        (void)hal_clock_now_us(g->clock, &now);
        if (now - start >= timeout_us) {
            return HAL_E_TIMEOUT;
        }
        struct pollfd p = {g->fd, POLLIN, 0};
        const uint64_t left_ms = (timeout_us - (now - start) + 999U) / 1000U;
        if (poll(&p, 1, (int)left_ms) < 0 && errno != EINTR) {
            return HAL_E_IO;
        }
        st = drain(g);
        if (st != HAL_OK) {
            return st;
        }
    }
}

static hal_status_t op_release(hal_gpio_t *d, uint32_t line)
{
    robot_gpio_fd_t *g = of(d);
    if (line >= ROBOT_GPIO_FD_LINES) {
        return HAL_E_NOT_FOUND;
    }
    g->lines[line].configured = false;
    g->lines[line].q_len = 0U;
    return HAL_OK;
}

static void op_close(hal_gpio_t *d)
{
    robot_gpio_fd_t *g = of(d);
    if (g->fd >= 0) {
        (void)close(g->fd);
        g->fd = -1;
    }
}

static const hal_gpio_ops_t ops = {op_line_count, op_configure, op_read, op_write, op_wait_edge, op_release, op_close};

hal_status_t robot_gpio_fd_open(robot_gpio_fd_t *g, int fd, hal_clock_t *clock)
{
    if (g == NULL || clock == NULL || fd < 0) {
        return HAL_E_ARG;
    }
    memset(g, 0, sizeof *g);
    g->dev.ops = &ops;
    g->dev.backend = g;
    g->clock = clock;
    g->fd = dup(fd);
    return g->fd >= 0 ? HAL_OK : HAL_E_IO;
}
