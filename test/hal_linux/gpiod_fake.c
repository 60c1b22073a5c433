/* Link-time fake of libgpiod v1 (see gpiod_fake.h). */
#include "gpiod_fake.h"

#include <errno.h>
#include <gpiod.h>
#include <string.h>

fake_gpiod_t fake_gpiod;

/* Opaque handles: the chip is the fake itself, a line is its slot. */
#define CHIP_HANDLE ((struct gpiod_chip *)(void *)&fake_gpiod)

static fake_gpiod_line_t *slot(struct gpiod_line *line)
{
    return (fake_gpiod_line_t *)(void *)line;
}

static bool active_low(const fake_gpiod_line_t *l)
{
    return (l->flags & GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW) != 0;
}

static bool is_event_request(int t)
{
    return t == GPIOD_LINE_REQUEST_EVENT_RISING_EDGE || t == GPIOD_LINE_REQUEST_EVENT_FALLING_EDGE ||
           t == GPIOD_LINE_REQUEST_EVENT_BOTH_EDGES;
}

void fake_gpiod_reset(unsigned num_lines)
{
    memset(&fake_gpiod, 0, sizeof fake_gpiod);
    fake_gpiod.num_lines = num_lines;
}

void fake_gpiod_drive(unsigned offset, bool high)
{
    fake_gpiod_line_t *l = &fake_gpiod.lines[offset];
    const bool was = l->pin_high;
    l->pin_high = high;
    if (was == high || !l->requested || !is_event_request(l->request_type)) return;
    const bool logical = high != active_low(l);
    const int type = logical ? GPIOD_LINE_EVENT_RISING_EDGE : GPIOD_LINE_EVENT_FALLING_EDGE;
    if (l->request_type == GPIOD_LINE_REQUEST_EVENT_RISING_EDGE && type != GPIOD_LINE_EVENT_RISING_EDGE) return;
    if (l->request_type == GPIOD_LINE_REQUEST_EVENT_FALLING_EDGE && type != GPIOD_LINE_EVENT_FALLING_EDGE) return;
    if (l->q_len >= FAKE_GPIOD_QUEUE) return; /* the v1 kernel drops silently */
    l->queue[l->q_len].type = type;
    l->queue[l->q_len].stamp_us = fake_gpiod.now_us;
    l->q_len++;
}

bool fake_gpiod_pin(unsigned offset)
{
    return fake_gpiod.lines[offset].pin_high;
}

/* ---- wrapped libgpiod v1 API ------------------------------------------ */

struct gpiod_chip *__wrap_gpiod_chip_open_lookup(const char *descr);
void __wrap_gpiod_chip_close(struct gpiod_chip *chip);
unsigned int __wrap_gpiod_chip_num_lines(struct gpiod_chip *chip);
struct gpiod_line *__wrap_gpiod_chip_get_line(struct gpiod_chip *chip, unsigned int offset);
int __wrap_gpiod_line_request(struct gpiod_line *line, const struct gpiod_line_request_config *config,
                              int default_val);
void __wrap_gpiod_line_release(struct gpiod_line *line);
int __wrap_gpiod_line_get_value(struct gpiod_line *line);
int __wrap_gpiod_line_set_value(struct gpiod_line *line, int value);
int __wrap_gpiod_line_event_wait(struct gpiod_line *line, const struct timespec *timeout);
int __wrap_gpiod_line_event_read(struct gpiod_line *line, struct gpiod_line_event *event);

struct gpiod_chip *__wrap_gpiod_chip_open_lookup(const char *descr)
{
    if (fake_gpiod.fail_open_errno != 0) {
        errno = fake_gpiod.fail_open_errno;
        return NULL;
    }
    strncpy(fake_gpiod.opened_name, descr, sizeof fake_gpiod.opened_name - 1);
    fake_gpiod.chip_open = true;
    return CHIP_HANDLE;
}

void __wrap_gpiod_chip_close(struct gpiod_chip *chip)
{
    if (chip == CHIP_HANDLE) {
        fake_gpiod.chip_open = false;
        fake_gpiod.n_chip_close++;
    }
}

unsigned int __wrap_gpiod_chip_num_lines(struct gpiod_chip *chip)
{
    return chip == CHIP_HANDLE ? fake_gpiod.num_lines : 0u;
}

struct gpiod_line *__wrap_gpiod_chip_get_line(struct gpiod_chip *chip, unsigned int offset)
{
    if (chip != CHIP_HANDLE || offset >= fake_gpiod.num_lines) {
        errno = EINVAL;
        return NULL;
    }
    return (struct gpiod_line *)(void *)&fake_gpiod.lines[offset];
}

int __wrap_gpiod_line_request(struct gpiod_line *line, const struct gpiod_line_request_config *config,
                              int default_val)
{
    fake_gpiod_line_t *l = slot(line);
    if (l->fail_request_errno != 0) {
        errno = l->fail_request_errno;
        l->fail_request_errno = 0;
        return -1;
    }
    if (l->requested) {
        errno = EBUSY;
        return -1;
    }
    l->requested = true;
    l->request_type = config->request_type;
    l->flags = config->flags;
    strncpy(l->consumer, config->consumer ? config->consumer : "", sizeof l->consumer - 1);
    l->default_val = default_val;
    l->q_len = 0;
    if (config->request_type == GPIOD_LINE_REQUEST_DIRECTION_OUTPUT) l->pin_high = (default_val != 0) != active_low(l);
    return 0;
}

void __wrap_gpiod_line_release(struct gpiod_line *line)
{
    fake_gpiod_line_t *l = slot(line);
    l->requested = false;
    l->q_len = 0;
    fake_gpiod.n_releases++;
}

int __wrap_gpiod_line_get_value(struct gpiod_line *line)
{
    fake_gpiod_line_t *l = slot(line);
    if (!l->requested) {
        errno = EPERM;
        return -1;
    }
    if (l->fail_get_errno != 0) {
        errno = l->fail_get_errno;
        return -1;
    }
    return (l->pin_high != active_low(l)) ? 1 : 0;
}

int __wrap_gpiod_line_set_value(struct gpiod_line *line, int value)
{
    fake_gpiod_line_t *l = slot(line);
    fake_gpiod.n_set_value++;
    if (!l->requested || l->request_type != GPIOD_LINE_REQUEST_DIRECTION_OUTPUT) {
        errno = EPERM;
        return -1;
    }
    if (l->fail_set_errno != 0) {
        errno = l->fail_set_errno;
        return -1;
    }
    l->pin_high = (value != 0) != active_low(l);
    return 0;
}

int __wrap_gpiod_line_event_wait(struct gpiod_line *line, const struct timespec *timeout)
{
    fake_gpiod_line_t *l = slot(line);
    fake_gpiod.n_wait_calls++;
    fake_gpiod.last_wait_timeout = *timeout;
    if (fake_gpiod.pending_eintr > 0) {
        fake_gpiod.pending_eintr--;
        errno = EINTR;
        return -1;
    }
    if (!l->requested || !is_event_request(l->request_type)) {
        errno = EPERM;
        return -1;
    }
    if (l->q_len > 0) return 1;
    /* nothing arrives while we wait: the whole timeout passes */
    fake_gpiod.now_us += (uint64_t)timeout->tv_sec * 1000000u + (uint64_t)timeout->tv_nsec / 1000u;
    return 0;
}

int __wrap_gpiod_line_event_read(struct gpiod_line *line, struct gpiod_line_event *event)
{
    fake_gpiod_line_t *l = slot(line);
    if (l->q_len == 0) {
        errno = EAGAIN;
        return -1;
    }
    event->event_type = l->queue[0].type;
    event->ts.tv_sec = (time_t)(l->queue[0].stamp_us / 1000000u);
    event->ts.tv_nsec = (long)((l->queue[0].stamp_us % 1000000u) * 1000u);
    memmove(&l->queue[0], &l->queue[1], (l->q_len - 1u) * sizeof l->queue[0]);
    l->q_len--;
    return 0;
}
