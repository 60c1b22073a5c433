/* GPIO roles: bumpers, e-stop, status LEDs (see gpio_roles.h). */
#include "gpio_roles.h"

#include <string.h>

bool gpio_roles_line_conflict(const gpio_roles_config_t *cfg, uint32_t *line, gpio_role_t *first,
                              gpio_role_t *second)
{
    uint32_t lines[COSLAM_MAX_BUMPERS + COSLAM_MAX_STATUS_LEDS + 1];
    gpio_role_t roles[sizeof lines / sizeof lines[0]];
    size_t n = 0;
    for (uint8_t i = 0; i < cfg->n_bumpers; ++i) {
        roles[n] = GPIO_ROLE_BUMPER;
        lines[n++] = cfg->bumpers[i].line;
    }
    if (cfg->has_estop) {
        roles[n] = GPIO_ROLE_ESTOP;
        lines[n++] = cfg->estop.line;
    }
    for (uint8_t i = 0; i < cfg->n_leds; ++i) {
        roles[n] = GPIO_ROLE_LED;
        lines[n++] = cfg->leds[i].line;
    }
    for (size_t i = 0; i < n; ++i) {
        for (size_t j = i + 1; j < n; ++j) {
            if (lines[i] == lines[j]) {
                if (line != NULL) *line = lines[i];
                if (first != NULL) *first = roles[i];
                if (second != NULL) *second = roles[j];
                return true;
            }
        }
    }
    return false;
}

static bool pattern_valid(const gpio_roles_pattern_t *p)
{
    return p->n_slots >= 1u && p->n_slots <= 32u && p->slot_us >= 1u;
}

static bool pattern_equal(const gpio_roles_pattern_t *a, const gpio_roles_pattern_t *b)
{
    const uint32_t mask = (a->n_slots >= 32u) ? 0xFFFFFFFFu : ((1u << a->n_slots) - 1u);
    return a->slot_us == b->slot_us && a->n_slots == b->n_slots && (a->bits & mask) == (b->bits & mask);
}

/* LED level at time now: slot k = floor((now - start) / slot_us) mod n_slots. */
static bool pattern_level(const gpio_roles_pattern_t *p, uint64_t start_us, uint64_t now_us)
{
    const uint64_t elapsed = now_us >= start_us ? now_us - start_us : 0u;
    const uint64_t slot = (elapsed / p->slot_us) % p->n_slots;
    return ((p->bits >> slot) & 1u) != 0u;
}

static void release_all(gpio_roles_t *r)
{
    for (uint8_t i = 0; i < r->cfg.n_bumpers; ++i) (void)hal_gpio_release(r->gpio, r->cfg.bumpers[i].line);
    for (uint8_t i = 0; i < r->cfg.n_leds; ++i) (void)hal_gpio_release(r->gpio, r->cfg.leds[i].line);
    if (r->cfg.has_estop) (void)hal_gpio_release(r->gpio, r->cfg.estop.line);
}

hal_status_t gpio_roles_init(gpio_roles_t *r, const gpio_roles_config_t *cfg, hal_gpio_t *gpio, hal_clock_t *clock)
{
    if (r == NULL || cfg == NULL || gpio == NULL || clock == NULL) return HAL_E_ARG;
    if (cfg->n_bumpers > COSLAM_MAX_BUMPERS || cfg->n_leds > COSLAM_MAX_STATUS_LEDS) return HAL_E_ARG;
    if (gpio_roles_line_conflict(cfg, NULL, NULL, NULL)) return HAL_E_ARG;

    memset(r, 0, sizeof *r);
    r->gpio = gpio;
    r->clock = clock;
    r->cfg = *cfg;
    uint64_t now = 0;
    const hal_status_t cs = hal_clock_now_us(clock, &now);
    if (cs != HAL_OK) return cs;
    r->last_now_us = now;

    /* claim lines in a fixed order; on failure give back what was claimed */
    hal_gpio_config_t in;
    memset(&in, 0, sizeof in);
    in.dir = HAL_GPIO_DIR_INPUT;
    in.edges = HAL_GPIO_EDGE_NONE;
    hal_gpio_config_t out;
    memset(&out, 0, sizeof out);
    out.dir = HAL_GPIO_DIR_OUTPUT;
    out.initial_active = false;
    hal_status_t s = HAL_OK;
    uint8_t nb = 0, nl = 0;
    bool estop_claimed = false;
    for (; nb < cfg->n_bumpers && s == HAL_OK; ++nb) {
        in.active_low = cfg->bumpers[nb].active_low;
        s = hal_gpio_configure(gpio, cfg->bumpers[nb].line, &in);
    }
    if (s == HAL_OK && cfg->has_estop) {
        in.active_low = cfg->estop.active_low;
        s = hal_gpio_configure(gpio, cfg->estop.line, &in);
        estop_claimed = s == HAL_OK;
    }
    for (; nl < cfg->n_leds && s == HAL_OK; ++nl) {
        out.active_low = cfg->leds[nl].active_low;
        s = hal_gpio_configure(gpio, cfg->leds[nl].line, &out);
    }
    if (s != HAL_OK) {
        /* nb/nl count the failed line too; releasing it is harmless */
        r->cfg.n_bumpers = nb;
        r->cfg.n_leds = nl;
        r->cfg.has_estop = estop_claimed;
        release_all(r);
        return s;
    }
    for (uint8_t i = 0; i < cfg->n_bumpers; ++i) r->bumpers[i].raw_since_us = now;
    for (uint8_t i = 0; i < cfg->n_leds; ++i) {
        r->leds[i].pattern = GPIO_ROLES_PATTERN_OFF;
        r->leds[i].start_us = now;
        r->leds[i].written = true; /* configured with initial_active = false */
        r->leds[i].level = false;
    }
    r->estop_active = cfg->has_estop; /* fail-safe start */
    return HAL_OK;
}

/* Debounce one bumper sample (gpio_roles.h: a level counts after it has
 * been sampled unchanged for bumper_debounce_us). */
static void bumper_sample(gpio_roles_t *r, gpio_roles_bumper_state_t *b, bool raw, uint64_t now)
{
    if (raw != b->raw) {
        b->raw = raw;
        b->raw_since_us = now;
    }
    if (b->raw != b->stable && now - b->raw_since_us >= r->cfg.bumper_debounce_us) {
        b->stable = b->raw;
        if (b->stable) {
            b->latched = true;
            r->counters.bumper_presses++;
        }
    }
}

static void estop_sample(gpio_roles_t *r, bool raw_active, uint64_t now)
{
    if (raw_active) {
        if (!r->estop_active) r->counters.estop_activations++;
        r->estop_active = true;
        r->estop_clearing = false;
        return;
    }
    if (!r->estop_active) return;
    if (!r->estop_clearing) {
        r->estop_clearing = true;
        r->estop_clear_since_us = now;
    }
    if (now - r->estop_clear_since_us >= r->cfg.estop_release_us) {
        r->estop_active = false;
        r->estop_clearing = false;
    }
}

static void fill_status(const gpio_roles_t *r, gpio_roles_status_t *out, uint64_t stamp_us)
{
    memset(out, 0, sizeof *out);
    for (uint8_t i = 0; i < r->cfg.n_bumpers; ++i) {
        if (r->bumpers[i].stable) out->bumpers_pressed |= 1u << i;
        if (r->bumpers[i].latched) out->bumpers_latched |= 1u << i;
    }
    out->estop_active = r->estop_active;
    out->stop_requested = r->estop_active || out->bumpers_latched != 0u;
    out->stamp_us = stamp_us;
}

hal_status_t gpio_roles_update(gpio_roles_t *r, gpio_roles_status_t *out)
{
    if (r == NULL || out == NULL) return HAL_E_ARG;
    uint64_t now = 0;
    const hal_status_t cs = hal_clock_now_us(r->clock, &now);
    if (cs != HAL_OK) {
        r->counters.clock_errors++;
        fill_status(r, out, 0);
        out->stop_requested = true; /* no time, no filters: stop */
        return cs;
    }
    if (now < r->last_now_us) now = r->last_now_us; /* a contract breach must not underflow the filters */
    r->last_now_us = now;
    hal_status_t result = HAL_OK;

    for (uint8_t i = 0; i < r->cfg.n_bumpers; ++i) {
        bool active = false;
        if (hal_gpio_read(r->gpio, r->cfg.bumpers[i].line, &active) != HAL_OK) {
            r->counters.bumper_read_errors++;
            result = HAL_E_IO;
            active = true; /* fail-safe */
        }
        bumper_sample(r, &r->bumpers[i], active, now);
    }

    if (r->cfg.has_estop) {
        bool active = false;
        if (hal_gpio_read(r->gpio, r->cfg.estop.line, &active) != HAL_OK) {
            r->counters.estop_read_errors++;
            result = HAL_E_IO;
            active = true; /* fail-safe */
        }
        estop_sample(r, active, now);
    }

    for (uint8_t i = 0; i < r->cfg.n_leds; ++i) {
        gpio_roles_led_state_t *led = &r->leds[i];
        const bool level = pattern_level(&led->pattern, led->start_us, now);
        if (led->written && led->level == level) continue;
        if (hal_gpio_write(r->gpio, r->cfg.leds[i].line, level) == HAL_OK) {
            led->written = true;
            led->level = level;
        } else {
            r->counters.led_write_errors++;
            led->written = false; /* unknown: write again next time */
            result = HAL_E_IO;
        }
    }

    fill_status(r, out, now);
    return result;
}

hal_status_t gpio_roles_bumper_ack(gpio_roles_t *r, uint8_t index)
{
    if (r == NULL) return HAL_E_ARG;
    uint8_t first = index, last = index;
    if (index == GPIO_ROLES_ALL_BUMPERS) {
        if (r->cfg.n_bumpers == 0u) return HAL_OK;
        first = 0;
        last = (uint8_t)(r->cfg.n_bumpers - 1u);
    } else if (index >= r->cfg.n_bumpers) {
        return HAL_E_ARG;
    }
    hal_status_t s = HAL_OK;
    for (uint8_t i = first; i <= last; ++i) {
        gpio_roles_bumper_state_t *b = &r->bumpers[i];
        if (!b->latched) continue;
        if (b->stable) {
            s = HAL_E_BUSY;
        } else {
            b->latched = false;
        }
    }
    return s;
}

hal_status_t gpio_roles_led_set(gpio_roles_t *r, uint8_t index, gpio_roles_pattern_t pattern)
{
    if (r == NULL || index >= r->cfg.n_leds || !pattern_valid(&pattern)) return HAL_E_ARG;
    gpio_roles_led_state_t *led = &r->leds[index];
    if (pattern_equal(&led->pattern, &pattern)) return HAL_OK; /* keep the phase */
    uint64_t now = 0;
    const hal_status_t cs = hal_clock_now_us(r->clock, &now);
    if (cs != HAL_OK) {
        r->counters.clock_errors++;
        return cs;
    }
    led->pattern = pattern;
    led->start_us = now;
    return HAL_OK;
}

void gpio_roles_deinit(gpio_roles_t *r)
{
    if (r == NULL || r->gpio == NULL) return;
    for (uint8_t i = 0; i < r->cfg.n_leds; ++i) (void)hal_gpio_write(r->gpio, r->cfg.leds[i].line, false);
    release_all(r);
    r->gpio = NULL;
}
