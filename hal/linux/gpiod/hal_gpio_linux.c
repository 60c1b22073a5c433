/* hal_gpio on libgpiod v1 (see hal/hal_gpio_linux.h). */
#include "hal/hal_gpio_linux.h"

#include <errno.h>
#include <gpiod.h>
#include <string.h>
#include <time.h>

static hal_gpio_linux_t *self_of(hal_gpio_t *dev)
{
    return (hal_gpio_linux_t *)dev->backend;
}

static hal_gpio_linux_line_t *line_of(hal_gpio_linux_t *g, uint32_t line)
{
    return line < g->n_lines ? &g->lines[line] : NULL;
}

static void release_line(hal_gpio_linux_line_t *l)
{
    if (l->configured && l->line != NULL) gpiod_line_release(l->line);
    l->configured = false;
}

static hal_status_t gl_line_count(hal_gpio_t *dev, uint32_t *n)
{
    hal_gpio_linux_t *g = self_of(dev);
    if (g->chip == NULL) return HAL_E_CLOSED;
    *n = g->n_lines;
    return HAL_OK;
}

static int request_type_of(const hal_gpio_config_t *cfg)
{
    if (cfg->dir == HAL_GPIO_DIR_OUTPUT) return GPIOD_LINE_REQUEST_DIRECTION_OUTPUT;
    switch (cfg->edges) {
    case HAL_GPIO_EDGE_RISING: return GPIOD_LINE_REQUEST_EVENT_RISING_EDGE;
    case HAL_GPIO_EDGE_FALLING: return GPIOD_LINE_REQUEST_EVENT_FALLING_EDGE;
    case HAL_GPIO_EDGE_BOTH: return GPIOD_LINE_REQUEST_EVENT_BOTH_EDGES;
    default: return GPIOD_LINE_REQUEST_DIRECTION_INPUT;
    }
}

static hal_status_t gl_configure(hal_gpio_t *dev, uint32_t line, const hal_gpio_config_t *cfg)
{
    hal_gpio_linux_t *g = self_of(dev);
    if (g->chip == NULL) return HAL_E_CLOSED;
    hal_gpio_linux_line_t *l = line_of(g, line);
    if (l == NULL) return HAL_E_NOT_FOUND;
    release_line(l);
    if (l->line == NULL) {
        l->line = gpiod_chip_get_line(g->chip, line);
        if (l->line == NULL) return errno == EINVAL ? HAL_E_NOT_FOUND : HAL_E_IO;
    }
    struct gpiod_line_request_config rq;
    memset(&rq, 0, sizeof rq);
    rq.consumer = g->consumer;
    rq.request_type = request_type_of(cfg);
    rq.flags = cfg->active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
    const bool init = cfg->dir == HAL_GPIO_DIR_OUTPUT && cfg->initial_active;
    if (gpiod_line_request(l->line, &rq, init ? 1 : 0) != 0) {
        if (errno == EBUSY) return HAL_E_BUSY;
        if (errno == EINVAL || errno == EOPNOTSUPP) return HAL_E_UNSUPPORTED;
        return HAL_E_IO;
    }
    l->configured = true;
    l->cfg = *cfg;
    l->out_active = init;
    return HAL_OK;
}

static hal_status_t gl_read(hal_gpio_t *dev, uint32_t line, bool *active)
{
    hal_gpio_linux_t *g = self_of(dev);
    if (g->chip == NULL) return HAL_E_CLOSED;
    hal_gpio_linux_line_t *l = line_of(g, line);
    if (l == NULL) return HAL_E_NOT_FOUND;
    if (!l->configured) return HAL_E_CLOSED;
    if (l->cfg.dir == HAL_GPIO_DIR_OUTPUT) {
        *active = l->out_active;
        return HAL_OK;
    }
    const int v = gpiod_line_get_value(l->line);
    if (v < 0) return HAL_E_IO;
    *active = v != 0;
    return HAL_OK;
}

static hal_status_t gl_write(hal_gpio_t *dev, uint32_t line, bool active)
{
    hal_gpio_linux_t *g = self_of(dev);
    if (g->chip == NULL) return HAL_E_CLOSED;
    hal_gpio_linux_line_t *l = line_of(g, line);
    if (l == NULL) return HAL_E_NOT_FOUND;
    if (!l->configured) return HAL_E_CLOSED;
    if (l->cfg.dir != HAL_GPIO_DIR_OUTPUT) return HAL_E_ARG;
    if (gpiod_line_set_value(l->line, active ? 1 : 0) != 0) return HAL_E_IO;
    l->out_active = active;
    return HAL_OK;
}

static uint64_t mono_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static hal_status_t gl_wait_edge(hal_gpio_t *dev, uint32_t line, hal_gpio_event_t *ev, uint32_t timeout_us)
{
    hal_gpio_linux_t *g = self_of(dev);
    if (g->chip == NULL) return HAL_E_CLOSED;
    hal_gpio_linux_line_t *l = line_of(g, line);
    if (l == NULL) return HAL_E_NOT_FOUND;
    if (!l->configured) return HAL_E_CLOSED;
    if (l->cfg.dir != HAL_GPIO_DIR_INPUT || l->cfg.edges == HAL_GPIO_EDGE_NONE) return HAL_E_ARG;

    const bool forever = timeout_us == HAL_TIMEOUT_FOREVER;
    const uint64_t deadline = mono_us() + timeout_us;
    bool first = true;
    for (;;) {
        /* remaining time (the whole timeout on the first pass, the rest after
         * an interruption); forever waits in one-hour slices */
        uint64_t left = 3600u * 1000000u;
        if (!forever) {
            const uint64_t now = mono_us();
            left = first ? timeout_us : (now >= deadline ? 0u : deadline - now);
        }
        first = false;
        struct timespec ts;
        ts.tv_sec = (time_t)(left / 1000000u);
        ts.tv_nsec = (long)((left % 1000000u) * 1000u);
        const int rc = gpiod_line_event_wait(l->line, &ts);
        if (rc < 0) {
            if (errno == EINTR) continue;
            return HAL_E_IO;
        }
        if (rc == 0) {
            if (forever) continue;
            return HAL_E_TIMEOUT;
        }
        struct gpiod_line_event e;
        if (gpiod_line_event_read(l->line, &e) != 0) return HAL_E_IO;
        ev->edge = (e.event_type == GPIOD_LINE_EVENT_RISING_EDGE) ? HAL_GPIO_EDGE_RISING : HAL_GPIO_EDGE_FALLING;
        ev->stamp_us = (uint64_t)e.ts.tv_sec * 1000000u + (uint64_t)e.ts.tv_nsec / 1000u;
        return HAL_OK;
    }
}

static hal_status_t gl_release(hal_gpio_t *dev, uint32_t line)
{
    hal_gpio_linux_t *g = self_of(dev);
    if (g->chip == NULL) return HAL_E_CLOSED;
    hal_gpio_linux_line_t *l = line_of(g, line);
    if (l == NULL) return HAL_E_NOT_FOUND;
    release_line(l);
    return HAL_OK;
}

static void gl_close(hal_gpio_t *dev)
{
    hal_gpio_linux_t *g = self_of(dev);
    if (g->chip == NULL) return;
    for (uint32_t i = 0; i < g->n_lines; ++i) release_line(&g->lines[i]);
    gpiod_chip_close(g->chip);
    g->chip = NULL;
}

static const hal_gpio_ops_t gpio_linux_ops = {gl_line_count, gl_configure, gl_read,  gl_write,
                                              gl_wait_edge,  gl_release,   gl_close};

hal_status_t hal_gpio_linux_open(hal_gpio_linux_t *g, const char *chip, const char *consumer)
{
    if (g == NULL || chip == NULL || consumer == NULL) return HAL_E_ARG;
    memset(g, 0, sizeof *g);
    g->dev.ops = &gpio_linux_ops;
    g->dev.backend = g;
    size_t n = strlen(consumer);
    if (n > HAL_GPIO_LINUX_CONSUMER_MAX) n = HAL_GPIO_LINUX_CONSUMER_MAX;
    memcpy(g->consumer, consumer, n);
    g->consumer[n] = '\0';
    errno = 0;
    g->chip = gpiod_chip_open_lookup(chip);
    if (g->chip == NULL) return (errno == ENOENT || errno == 0) ? HAL_E_NOT_FOUND : HAL_E_IO;
    const unsigned int lines = gpiod_chip_num_lines(g->chip);
    g->n_lines = lines < HAL_GPIO_LINUX_MAX_LINES ? (uint32_t)lines : HAL_GPIO_LINUX_MAX_LINES;
    return HAL_OK;
}
