/*
 * gpio_roles.h - the robot's GPIO roles: bumper switches, an emergency-stop
 * input and status LEDs, on top of hal_gpio and hal_clock only.
 *
 * Model: the application calls gpio_roles_update() periodically (at least
 * every bumper_debounce_us / 2; 1-10 ms is typical). Each update reads the
 * clock once, samples every input, runs the filters below, drives the LEDs
 * and reports a gpio_roles_status_t. Nothing blocks; there is no heap and
 * no global state: the caller owns gpio_roles_t.
 *
 *  - Bumpers (debounced, latched). A bumper's level counts only after it
 *    has been sampled unchanged for bumper_debounce_us (for presses and
 *    releases alike), so contact bounce and single glitches are ignored.
 *    A debounced press LATCHES the bumper: stop_requested stays true until
 *    the bumper is released (debounced) AND the application acknowledges
 *    it with gpio_roles_bumper_ack(). An ack while still pressed is refused
 *    (HAL_E_BUSY), not remembered: the operator acknowledges a cleared
 *    obstacle, not an expected one.
 *  - Emergency stop (fail-safe). Active at once on the first sample that
 *    reads active, OR fails to read (a broken wire or a dead GPIO chip must
 *    stop the robot), with no debounce. It clears only after
 *    estop_release_us of consecutive released readings; any active or
 *    failed reading restarts that wait. It also starts active at init, so
 *    the robot moves only after the e-stop has been seen released for
 *    estop_release_us. Wire it normally-closed and configure active_low as
 *    the circuit needs so that a cut wire reads active.
 *  - Bumper read errors are fail-safe too: a failed read is sampled as
 *    "pressed", so a persistent fault latches after the debounce time while
 *    a single glitch is filtered.
 *  - Status LEDs show a pattern: a bit string of n_slots slots of slot_us
 *    each, repeated; bit k set = LED on in slot k. The phase starts when a
 *    new pattern is set (setting the same pattern again keeps the phase, so
 *    it may be set in every loop). A line is written only when its level
 *    changes; a failed write is counted and retried at the next update.
 *  - stop_requested = e-stop active OR any bumper latched OR the clock
 *    failed. The drive driver must honour it.
 *
 * Memory: sizeof(gpio_roles_t) = 384 bytes with the default capacities (4
 * bumpers, 4 LEDs) on x86-64; code 2.2 KiB on Cortex-M7 (-O2). Every call
 * is O(COSLAM_MAX_BUMPERS + COSLAM_MAX_STATUS_LEDS), init O((B + L)^2) for
 * the duplicate-line check.
 */
#ifndef COSLAM_GPIO_ROLES_H
#define COSLAM_GPIO_ROLES_H

#include <stdbool.h>
#include <stdint.h>

#include "coslam/config.h"
#include "hal/hal_clock.h"
#include "hal/hal_gpio.h"

#ifdef __cplusplus
extern "C" {
#endif

/** One GPIO line and its polarity. */
typedef struct {
    uint32_t line;
    bool active_low;
} gpio_roles_line_t;

/** An LED pattern (see the header comment). n_slots in [1, 32];
 *  slot_us >= 1; only bits below n_slots are used. */
typedef struct {
    uint32_t slot_us;
    uint32_t bits;
    uint8_t n_slots;
} gpio_roles_pattern_t;

/** Standard patterns. */
#define GPIO_ROLES_PATTERN_OFF ((gpio_roles_pattern_t){1000000u, 0x0u, 1u})
#define GPIO_ROLES_PATTERN_ON ((gpio_roles_pattern_t){1000000u, 0x1u, 1u})
/** 1 Hz, 50 % duty (e.g. "idle"). */
#define GPIO_ROLES_PATTERN_BLINK_SLOW ((gpio_roles_pattern_t){500000u, 0x1u, 2u})
/** 4 Hz, 50 % duty (e.g. "stopped: acknowledge needed"). */
#define GPIO_ROLES_PATTERN_BLINK_FAST ((gpio_roles_pattern_t){125000u, 0x1u, 2u})
/** Two 100 ms flashes per second (e.g. "running"). */
#define GPIO_ROLES_PATTERN_HEARTBEAT ((gpio_roles_pattern_t){100000u, 0x5u, 10u})

/** gpio_roles_bumper_ack(): acknowledge every bumper. */
#define GPIO_ROLES_ALL_BUMPERS 0xFFu

typedef struct {
    uint8_t n_bumpers;                                    /**< 0..COSLAM_MAX_BUMPERS */
    gpio_roles_line_t bumpers[COSLAM_MAX_BUMPERS];
    uint32_t bumper_debounce_us;                          /**< hold time of a level [us] */
    bool has_estop;
    gpio_roles_line_t estop;
    uint32_t estop_release_us;                            /**< released time before the e-stop clears [us] */
    uint8_t n_leds;                                       /**< 0..COSLAM_MAX_STATUS_LEDS */
    gpio_roles_line_t leds[COSLAM_MAX_STATUS_LEDS];
} gpio_roles_config_t;

/** Counters; they only grow. */
typedef struct {
    uint32_t bumper_read_errors;
    uint32_t estop_read_errors;
    uint32_t led_write_errors;
    uint32_t clock_errors;
    uint32_t bumper_presses;      /**< debounced presses (latch events) */
    uint32_t estop_activations;   /**< inactive -> active transitions */
} gpio_roles_counters_t;

typedef struct {
    uint32_t bumpers_pressed;     /**< bit i: bumper i pressed (debounced) */
    uint32_t bumpers_latched;     /**< bit i: bumper i latched (release + ack needed) */
    bool estop_active;
    bool stop_requested;          /**< the drive must stop */
    uint64_t stamp_us;            /**< clock reading of this update (0 if the clock failed) */
} gpio_roles_status_t;

/* Internal state; read-only for callers (tests, telemetry). */
typedef struct {
    bool raw;              /**< last sample (true = pressed or read error) */
    uint64_t raw_since_us; /**< time the last sample's level was first seen */
    bool stable;           /**< debounced level */
    bool latched;
} gpio_roles_bumper_state_t;

typedef struct {
    gpio_roles_pattern_t pattern;
    uint64_t start_us;     /**< phase origin of the pattern */
    bool written;          /**< `level` is what the line shows */
    bool level;
} gpio_roles_led_state_t;

typedef struct {
    hal_gpio_t *gpio;
    hal_clock_t *clock;
    gpio_roles_config_t cfg;
    gpio_roles_bumper_state_t bumpers[COSLAM_MAX_BUMPERS];
    gpio_roles_led_state_t leds[COSLAM_MAX_STATUS_LEDS];
    bool estop_active;
    bool estop_clearing;         /**< released readings since estop_clear_since_us */
    uint64_t estop_clear_since_us;
    uint64_t last_now_us;        /**< last good clock reading */
    gpio_roles_counters_t counters;
} gpio_roles_t;

/** The roles a line can have (gpio_roles_line_conflict). */
typedef enum { GPIO_ROLE_BUMPER, GPIO_ROLE_ESTOP, GPIO_ROLE_LED } gpio_role_t;

/** A line given two roles: true, with the line and its first two roles in
 *  the order bumpers, e-stop, LEDs (outputs may be NULL); false if every
 *  line has one role. gpio_roles_init refuses such a config; a config
 *  reader calls this to name the keys. O((B + L)^2). */
bool gpio_roles_line_conflict(const gpio_roles_config_t *cfg, uint32_t *line, gpio_role_t *first,
                              gpio_role_t *second);

/** Check cfg and claim its lines: bumpers and e-stop as inputs (no edge
 *  events: sampled by update), LEDs as outputs driven off. r, gpio and
 *  clock must outlive the instance; cfg is copied. The e-stop (if any)
 *  starts active.
 *  Returns HAL_OK; HAL_E_ARG (NULL, counts over capacity, a line used
 *  twice); or the error of the clock read or of the first line that failed
 *  to configure (lines claimed before it are released again). */
hal_status_t gpio_roles_init(gpio_roles_t *r, const gpio_roles_config_t *cfg, hal_gpio_t *gpio, hal_clock_t *clock);

/** Sample inputs, run the filters, drive the LEDs, fill *out (valid on
 *  every return). Never blocks.
 *  Returns HAL_OK; HAL_E_IO if a read or write failed in this update (the
 *  fail-safe interpretation was applied and counted); the clock's error
 *  if it could not be read (out->stop_requested is then true and nothing
 *  else was evaluated); HAL_E_ARG (NULL). */
hal_status_t gpio_roles_update(gpio_roles_t *r, gpio_roles_status_t *out);

/** Acknowledge a latched bumper (index, or GPIO_ROLES_ALL_BUMPERS), using
 *  the debounced state of the last update; no I/O.
 *  Returns HAL_OK (cleared, or was not latched); HAL_E_BUSY (still pressed:
 *  for ALL, at least one stayed latched, the released ones were cleared);
 *  HAL_E_ARG (NULL or index >= n_bumpers). */
hal_status_t gpio_roles_bumper_ack(gpio_roles_t *r, uint8_t index);

/** Show `pattern` on LED `index` from the next update on. Returns HAL_OK;
 *  HAL_E_ARG (NULL, bad index, n_slots outside [1, 32] or slot_us 0); the
 *  clock's error (pattern unchanged). */
hal_status_t gpio_roles_led_set(gpio_roles_t *r, uint8_t index, gpio_roles_pattern_t pattern);

/** Turn the LEDs off and release every line. The instance must be
 *  initialised again before further use. */
void gpio_roles_deinit(gpio_roles_t *r);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_GPIO_ROLES_H */
