/* GPIO roles driver against a fake GPIO controller and a fake clock that
 * record into fixed arrays and inject faults. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "gpio_roles.h"

/* ---- fake clock --------------------------------------------------------- */

static uint64_t fake_now;
static hal_status_t fake_clock_fail; /* HAL_OK = works */

static hal_status_t fc_now(hal_clock_t *d, uint64_t *t)
{
    (void)d;
    if (fake_clock_fail != HAL_OK) return fake_clock_fail;
    *t = fake_now;
    return HAL_OK;
}
static const hal_clock_ops_t fc_ops = {fc_now, NULL, NULL};
static hal_clock_t fake_clock = {&fc_ops, NULL};

/* ---- fake GPIO ---------------------------------------------------------- */

#define NL 16
#define LOG_CAP 4096

typedef struct {
    bool configured;
    hal_gpio_config_t cfg;
    bool input_active;           /* logical level the test applies */
    bool output_active;          /* logical level last written */
    hal_status_t read_fail;      /* HAL_OK = works */
    hal_status_t write_fail;
    hal_status_t configure_fail;
    unsigned n_writes;
} fline_t;

static fline_t fl[NL];
static struct {
    uint32_t line;
    bool active;
    uint64_t t_us;
} wlog[LOG_CAP];
static size_t n_wlog;
static unsigned n_release;

static hal_status_t fg_configure(hal_gpio_t *d, uint32_t line, const hal_gpio_config_t *cfg)
{
    (void)d;
    if (line >= NL) return HAL_E_NOT_FOUND;
    if (fl[line].configure_fail != HAL_OK) return fl[line].configure_fail;
    fl[line].configured = true;
    fl[line].cfg = *cfg;
    if (cfg->dir == HAL_GPIO_DIR_OUTPUT) fl[line].output_active = cfg->initial_active;
    return HAL_OK;
}
static hal_status_t fg_read(hal_gpio_t *d, uint32_t line, bool *active)
{
    (void)d;
    if (line >= NL) return HAL_E_NOT_FOUND;
    if (!fl[line].configured) return HAL_E_CLOSED;
    if (fl[line].read_fail != HAL_OK) return fl[line].read_fail;
    *active = fl[line].cfg.dir == HAL_GPIO_DIR_OUTPUT ? fl[line].output_active : fl[line].input_active;
    return HAL_OK;
}
static hal_status_t fg_write(hal_gpio_t *d, uint32_t line, bool active)
{
    (void)d;
    if (line >= NL) return HAL_E_NOT_FOUND;
    if (!fl[line].configured) return HAL_E_CLOSED;
    if (fl[line].cfg.dir != HAL_GPIO_DIR_OUTPUT) return HAL_E_ARG;
    if (fl[line].write_fail != HAL_OK) return fl[line].write_fail;
    fl[line].output_active = active;
    fl[line].n_writes++;
    if (n_wlog < LOG_CAP) {
        wlog[n_wlog].line = line;
        wlog[n_wlog].active = active;
        wlog[n_wlog].t_us = fake_now;
        n_wlog++;
    }
    return HAL_OK;
}
static hal_status_t fg_release(hal_gpio_t *d, uint32_t line)
{
    (void)d;
    if (line >= NL) return HAL_E_NOT_FOUND;
    fl[line].configured = false;
    n_release++;
    return HAL_OK;
}
static const hal_gpio_ops_t fg_ops = {NULL, fg_configure, fg_read, fg_write, NULL, fg_release, NULL};
static hal_gpio_t fake_gpio = {&fg_ops, NULL};

/* ---- fixture ------------------------------------------------------------ */

enum { L_BUMP0 = 1, L_BUMP1 = 2, L_ESTOP = 7, L_LED0 = 10, L_LED1 = 11 };
#define DEBOUNCE_US 20000u
#define ESTOP_RELEASE_US 500000u

static gpio_roles_t roles;

static gpio_roles_config_t std_cfg(void)
{
    gpio_roles_config_t c;
    memset(&c, 0, sizeof c);
    c.n_bumpers = 2;
    c.bumpers[0].line = L_BUMP0;
    c.bumpers[1].line = L_BUMP1;
    c.bumpers[1].active_low = true;
    c.bumper_debounce_us = DEBOUNCE_US;
    c.has_estop = true;
    c.estop.line = L_ESTOP;
    c.estop.active_low = true;
    c.estop_release_us = ESTOP_RELEASE_US;
    c.n_leds = 2;
    c.leds[0].line = L_LED0;
    c.leds[1].line = L_LED1;
    c.leds[1].active_low = true;
    return c;
}

static int setup(void **state)
{
    (void)state;
    memset(fl, 0, sizeof fl);
    n_wlog = 0;
    n_release = 0;
    fake_now = 1000000;
    fake_clock_fail = HAL_OK;
    const gpio_roles_config_t c = std_cfg();
    return gpio_roles_init(&roles, &c, &fake_gpio, &fake_clock) == HAL_OK ? 0 : -1;
}

/* advance time to t (absolute) calling update every step_us; returns the last status */
static gpio_roles_status_t run_until(uint64_t t_us, uint64_t step_us)
{
    gpio_roles_status_t st;
    memset(&st, 0, sizeof st);
    while (fake_now < t_us) {
        fake_now += step_us;
        (void)gpio_roles_update(&roles, &st);
    }
    return st;
}

static gpio_roles_status_t update_now(void)
{
    gpio_roles_status_t st;
    (void)gpio_roles_update(&roles, &st);
    return st;
}

/* release the e-stop for long enough that it clears */
static void clear_estop(void)
{
    fl[L_ESTOP].input_active = false;
    run_until(fake_now + ESTOP_RELEASE_US + 1000, 1000);
    assert_false(update_now().estop_active);
}

/* ---- tests: init ---------------------------------------------------------- */

static void test_init_configures_lines(void **state)
{
    (void)state;
    assert_true(fl[L_BUMP0].configured);
    assert_int_equal(fl[L_BUMP0].cfg.dir, HAL_GPIO_DIR_INPUT);
    assert_false(fl[L_BUMP0].cfg.active_low);
    assert_int_equal(fl[L_BUMP0].cfg.edges, HAL_GPIO_EDGE_NONE);
    assert_true(fl[L_BUMP1].cfg.active_low);
    assert_true(fl[L_ESTOP].configured);
    assert_true(fl[L_ESTOP].cfg.active_low);
    assert_int_equal(fl[L_LED0].cfg.dir, HAL_GPIO_DIR_OUTPUT);
    assert_false(fl[L_LED0].cfg.initial_active);
    assert_true(fl[L_LED1].cfg.active_low);
    /* the e-stop starts active: no motion before it is seen released */
    const gpio_roles_status_t st = update_now();
    assert_true(st.estop_active);
    assert_true(st.stop_requested);
}

static void test_init_rejects_bad_config(void **state)
{
    (void)state;
    gpio_roles_t r;
    gpio_roles_config_t c = std_cfg();
    c.n_bumpers = COSLAM_MAX_BUMPERS + 1;
    assert_int_equal(gpio_roles_init(&r, &c, &fake_gpio, &fake_clock), HAL_E_ARG);
    c = std_cfg();
    c.n_leds = COSLAM_MAX_STATUS_LEDS + 1;
    assert_int_equal(gpio_roles_init(&r, &c, &fake_gpio, &fake_clock), HAL_E_ARG);
    c = std_cfg();
    c.leds[1].line = L_BUMP0; /* one line, two roles */
    assert_int_equal(gpio_roles_init(&r, &c, &fake_gpio, &fake_clock), HAL_E_ARG);
    c = std_cfg();
    c.estop.line = L_LED0;
    assert_int_equal(gpio_roles_init(&r, &c, &fake_gpio, &fake_clock), HAL_E_ARG);
    assert_int_equal(gpio_roles_init(NULL, &c, &fake_gpio, &fake_clock), HAL_E_ARG);
    assert_int_equal(gpio_roles_init(&r, NULL, &fake_gpio, &fake_clock), HAL_E_ARG);
    assert_int_equal(gpio_roles_init(&r, &c, NULL, &fake_clock), HAL_E_ARG);
    assert_int_equal(gpio_roles_init(&r, &c, &fake_gpio, NULL), HAL_E_ARG);
}

static void test_init_failure_releases_claimed_lines(void **state)
{
    (void)state;
    gpio_roles_deinit(&roles);
    memset(fl, 0, sizeof fl);
    fl[L_LED1].configure_fail = HAL_E_BUSY; /* the last line to be claimed */
    gpio_roles_t r;
    const gpio_roles_config_t c = std_cfg();
    assert_int_equal(gpio_roles_init(&r, &c, &fake_gpio, &fake_clock), HAL_E_BUSY);
    for (unsigned i = 0; i < NL; ++i) assert_false(fl[i].configured);
    fake_clock_fail = HAL_E_IO;
    fl[L_LED1].configure_fail = HAL_OK;
    assert_int_equal(gpio_roles_init(&r, &c, &fake_gpio, &fake_clock), HAL_E_IO);
}

/* ---- tests: bumpers ----------------------------------------------------- */

static void test_bumper_press_after_debounce(void **state)
{
    (void)state;
    clear_estop();
    const uint64_t t_press = fake_now + 1000;
    run_until(t_press - 1000, 1000);
    fl[L_BUMP0].input_active = true;
    fake_now = t_press;
    gpio_roles_status_t st = update_now(); /* first sample of the press */
    assert_int_equal(st.bumpers_pressed, 0);
    st = run_until(t_press + DEBOUNCE_US - 1000, 1000);
    assert_int_equal(st.bumpers_pressed, 0);
    assert_false(st.stop_requested);
    st = run_until(t_press + DEBOUNCE_US, 1000); /* exactly the debounce time */
    assert_int_equal(st.bumpers_pressed, 1u);
    assert_int_equal(st.bumpers_latched, 1u);
    assert_true(st.stop_requested);
    assert_int_equal(roles.counters.bumper_presses, 1);
}

static void test_bumper_bounce_ignored(void **state)
{
    (void)state;
    clear_estop();
    /* contact bounce: the level flips every 5 ms for 200 ms, never holding 20 ms */
    for (int i = 0; i < 40; ++i) {
        fl[L_BUMP0].input_active = (i % 2) == 0;
        const gpio_roles_status_t st = run_until(fake_now + 5000, 1000);
        assert_int_equal(st.bumpers_latched, 0);
        assert_false(st.stop_requested);
    }
    assert_int_equal(roles.counters.bumper_presses, 0);
}

static void test_bumper_latched_until_released_and_acked(void **state)
{
    (void)state;
    clear_estop();
    fl[L_BUMP1].input_active = true;
    gpio_roles_status_t st = run_until(fake_now + DEBOUNCE_US + 2000, 1000);
    assert_int_equal(st.bumpers_latched, 2u);
    /* ack while pressed: refused, not remembered */
    assert_int_equal(gpio_roles_bumper_ack(&roles, 1), HAL_E_BUSY);
    fl[L_BUMP1].input_active = false;
    st = run_until(fake_now + 5000, 1000); /* released, not yet debounced */
    assert_int_equal(st.bumpers_pressed, 2u);
    assert_int_equal(gpio_roles_bumper_ack(&roles, 1), HAL_E_BUSY);
    st = run_until(fake_now + DEBOUNCE_US, 1000);
    assert_int_equal(st.bumpers_pressed, 0);
    assert_int_equal(st.bumpers_latched, 2u);
    assert_true(st.stop_requested); /* released is not enough */
    assert_int_equal(gpio_roles_bumper_ack(&roles, 1), HAL_OK);
    st = update_now();
    assert_int_equal(st.bumpers_latched, 0);
    assert_false(st.stop_requested);
    assert_int_equal(gpio_roles_bumper_ack(&roles, 1), HAL_OK); /* nothing latched: fine */
    assert_int_equal(gpio_roles_bumper_ack(&roles, 2), HAL_E_ARG);
}

static void test_bumper_ack_all(void **state)
{
    (void)state;
    clear_estop();
    fl[L_BUMP0].input_active = true;
    fl[L_BUMP1].input_active = true;
    run_until(fake_now + DEBOUNCE_US + 1000, 1000);
    fl[L_BUMP0].input_active = false;
    gpio_roles_status_t st = run_until(fake_now + DEBOUNCE_US + 1000, 1000);
    assert_int_equal(st.bumpers_latched, 3u);
    assert_int_equal(gpio_roles_bumper_ack(&roles, GPIO_ROLES_ALL_BUMPERS), HAL_E_BUSY);
    st = update_now();
    assert_int_equal(st.bumpers_latched, 2u); /* the released one was cleared */
}

static void test_bumper_read_error_is_failsafe(void **state)
{
    (void)state;
    clear_estop();
    fl[L_BUMP0].read_fail = HAL_E_IO;
    fake_now += 1000;
    gpio_roles_status_t st;
    assert_int_equal(gpio_roles_update(&roles, &st), HAL_E_IO);
    assert_false(st.stop_requested); /* one glitch is filtered */
    st = run_until(fake_now + DEBOUNCE_US, 1000);
    assert_true(st.stop_requested); /* a persistent fault latches */
    assert_true(roles.counters.bumper_read_errors >= 20);
}

/* ---- tests: e-stop ------------------------------------------------------ */

static void test_estop_immediate_and_release_hold(void **state)
{
    (void)state;
    clear_estop();
    fl[L_ESTOP].input_active = true;
    fake_now += 1;
    gpio_roles_status_t st = update_now();
    assert_true(st.estop_active); /* no debounce on activation */
    assert_true(st.stop_requested);
    assert_int_equal(roles.counters.estop_activations, 1);
    fl[L_ESTOP].input_active = false;
    const uint64_t t_rel = fake_now + 1000;
    st = run_until(t_rel, 1000);
    st = run_until(t_rel + ESTOP_RELEASE_US - 1000, 1000);
    assert_true(st.estop_active);
    /* a glitch restarts the hold */
    fl[L_ESTOP].input_active = true;
    fake_now += 1000;
    update_now();
    fl[L_ESTOP].input_active = false;
    const uint64_t t_rel2 = fake_now + 1000;
    st = run_until(t_rel2 + ESTOP_RELEASE_US - 1000, 1000);
    assert_true(st.estop_active);
    st = run_until(t_rel2 + ESTOP_RELEASE_US, 1000);
    assert_false(st.estop_active);
    assert_false(st.stop_requested);
}

static void test_estop_read_error_is_active(void **state)
{
    (void)state;
    clear_estop();
    fl[L_ESTOP].read_fail = HAL_E_IO;
    fake_now += 1000;
    gpio_roles_status_t st;
    assert_int_equal(gpio_roles_update(&roles, &st), HAL_E_IO);
    assert_true(st.estop_active);
    assert_true(st.stop_requested);
    assert_int_equal(roles.counters.estop_read_errors, 1);
    /* the line recovers: still held for the release time */
    fl[L_ESTOP].read_fail = HAL_OK;
    st = run_until(fake_now + ESTOP_RELEASE_US / 2, 1000);
    assert_true(st.estop_active);
}

static void test_no_estop_configured(void **state)
{
    (void)state;
    gpio_roles_deinit(&roles);
    gpio_roles_config_t c = std_cfg();
    c.has_estop = false;
    assert_int_equal(gpio_roles_init(&roles, &c, &fake_gpio, &fake_clock), HAL_OK);
    assert_false(fl[L_ESTOP].configured);
    const gpio_roles_status_t st = update_now();
    assert_false(st.estop_active);
    assert_false(st.stop_requested);
}

static void test_clock_failure_requests_stop(void **state)
{
    (void)state;
    clear_estop();
    fake_clock_fail = HAL_E_IO;
    gpio_roles_status_t st;
    assert_int_equal(gpio_roles_update(&roles, &st), HAL_E_IO);
    assert_true(st.stop_requested);
    assert_int_equal(st.stamp_us, 0);
    assert_int_equal(roles.counters.clock_errors, 1);
    assert_int_equal(gpio_roles_update(NULL, &st), HAL_E_ARG);
}

/* ---- tests: LEDs -------------------------------------------------------- */

/* expected level of a pattern started at t0, at time t */
static bool expect_level(gpio_roles_pattern_t p, uint64_t t0, uint64_t t)
{
    return ((p.bits >> (((t - t0) / p.slot_us) % p.n_slots)) & 1u) != 0u;
}

static void check_pattern(gpio_roles_pattern_t p, unsigned min_changes)
{
    fake_now += 12345;
    assert_int_equal(gpio_roles_led_set(&roles, 0, p), HAL_OK);
    const uint64_t t0 = fake_now;
    fl[L_LED0].n_writes = 0;
    bool shown = fl[L_LED0].output_active;
    unsigned changes = 0;
    for (uint64_t t = t0; t < t0 + 2000000u; t += 1000u) {
        fake_now = t;
        update_now();
        const bool want = expect_level(p, t0, t);
        assert_int_equal(fl[L_LED0].output_active, want);
        if (want != shown) ++changes;
        shown = want;
    }
    /* written exactly when the level changes */
    assert_int_equal(fl[L_LED0].n_writes, changes);
    assert_true(changes >= min_changes);
}

static void test_led_patterns(void **state)
{
    (void)state;
    check_pattern(GPIO_ROLES_PATTERN_ON, 1);
    check_pattern(GPIO_ROLES_PATTERN_BLINK_SLOW, 3);  /* 2 periods of 1 s */
    check_pattern(GPIO_ROLES_PATTERN_BLINK_FAST, 15); /* 8 periods of 250 ms */
    check_pattern(GPIO_ROLES_PATTERN_HEARTBEAT, 7);   /* 2 flashes per s */
    check_pattern(GPIO_ROLES_PATTERN_OFF, 0);
    const gpio_roles_pattern_t sos = {100000u, 0x15u | (0x1Bu << 6), 16u};
    check_pattern(sos, 12);
}

static void test_led_blink_timing_exact(void **state)
{
    (void)state;
    assert_int_equal(gpio_roles_led_set(&roles, 0, GPIO_ROLES_PATTERN_BLINK_SLOW), HAL_OK);
    const uint64_t t0 = fake_now;
    n_wlog = 0;
    run_until(t0 + 1600000u, 1000);
    /* on at t0 (first update after t0 is t0 + 1 ms), off at +0.5 s, on at +1 s, off at +1.5 s */
    assert_int_equal(n_wlog, 4);
    assert_true(wlog[0].active);
    assert_int_equal(wlog[0].t_us, t0 + 1000);
    assert_false(wlog[1].active);
    assert_int_equal(wlog[1].t_us, t0 + 500000);
    assert_true(wlog[2].active);
    assert_int_equal(wlog[2].t_us, t0 + 1000000);
    assert_int_equal(wlog[3].t_us, t0 + 1500000);
}

static void test_led_same_pattern_keeps_phase(void **state)
{
    (void)state;
    assert_int_equal(gpio_roles_led_set(&roles, 0, GPIO_ROLES_PATTERN_BLINK_SLOW), HAL_OK);
    const uint64_t t0 = fake_now;
    /* the application sets the same pattern in every loop */
    for (uint64_t t = t0; t < t0 + 1000000u; t += 1000u) {
        fake_now = t;
        assert_int_equal(gpio_roles_led_set(&roles, 0, GPIO_ROLES_PATTERN_BLINK_SLOW), HAL_OK);
        update_now();
    }
    assert_int_equal(roles.leds[0].start_us, t0);
    assert_false(fl[L_LED0].output_active); /* second half of the period */
}

static void test_led_active_low_and_bad_args(void **state)
{
    (void)state;
    /* LED 1 is active-low: the driver writes logical levels, the HAL inverts */
    assert_int_equal(gpio_roles_led_set(&roles, 1, GPIO_ROLES_PATTERN_ON), HAL_OK);
    fake_now += 1000;
    update_now();
    assert_true(fl[L_LED1].output_active);
    assert_true(fl[L_LED1].cfg.active_low);
    gpio_roles_pattern_t p = GPIO_ROLES_PATTERN_ON;
    p.n_slots = 0;
    assert_int_equal(gpio_roles_led_set(&roles, 0, p), HAL_E_ARG);
    p.n_slots = 33;
    assert_int_equal(gpio_roles_led_set(&roles, 0, p), HAL_E_ARG);
    p = GPIO_ROLES_PATTERN_ON;
    p.slot_us = 0;
    assert_int_equal(gpio_roles_led_set(&roles, 0, p), HAL_E_ARG);
    assert_int_equal(gpio_roles_led_set(&roles, 2, GPIO_ROLES_PATTERN_ON), HAL_E_ARG);
    fake_clock_fail = HAL_E_IO;
    assert_int_equal(gpio_roles_led_set(&roles, 0, GPIO_ROLES_PATTERN_BLINK_FAST), HAL_E_IO);
}

static void test_led_write_error_retried(void **state)
{
    (void)state;
    assert_int_equal(gpio_roles_led_set(&roles, 0, GPIO_ROLES_PATTERN_ON), HAL_OK);
    fl[L_LED0].write_fail = HAL_E_IO;
    fake_now += 1000;
    gpio_roles_status_t st;
    assert_int_equal(gpio_roles_update(&roles, &st), HAL_E_IO);
    assert_int_equal(gpio_roles_update(&roles, &st), HAL_E_IO);
    assert_int_equal(roles.counters.led_write_errors, 2);
    fl[L_LED0].write_fail = HAL_OK;
    assert_int_equal(gpio_roles_update(&roles, &st), HAL_OK);
    assert_true(fl[L_LED0].output_active);
    const unsigned w = fl[L_LED0].n_writes;
    assert_int_equal(gpio_roles_update(&roles, &st), HAL_OK);
    assert_int_equal(fl[L_LED0].n_writes, w); /* no rewrite once it took */
}

static void test_deinit_turns_leds_off_and_releases(void **state)
{
    (void)state;
    assert_int_equal(gpio_roles_led_set(&roles, 0, GPIO_ROLES_PATTERN_ON), HAL_OK);
    fake_now += 1000;
    update_now();
    assert_true(fl[L_LED0].output_active);
    gpio_roles_deinit(&roles);
    assert_false(fl[L_LED0].output_active);
    for (unsigned i = 0; i < NL; ++i) assert_false(fl[i].configured);
    gpio_roles_deinit(&roles); /* twice is harmless */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_init_configures_lines, setup),
        cmocka_unit_test_setup(test_init_rejects_bad_config, setup),
        cmocka_unit_test_setup(test_init_failure_releases_claimed_lines, setup),
        cmocka_unit_test_setup(test_bumper_press_after_debounce, setup),
        cmocka_unit_test_setup(test_bumper_bounce_ignored, setup),
        cmocka_unit_test_setup(test_bumper_latched_until_released_and_acked, setup),
        cmocka_unit_test_setup(test_bumper_ack_all, setup),
        cmocka_unit_test_setup(test_bumper_read_error_is_failsafe, setup),
        cmocka_unit_test_setup(test_estop_immediate_and_release_hold, setup),
        cmocka_unit_test_setup(test_estop_read_error_is_active, setup),
        cmocka_unit_test_setup(test_no_estop_configured, setup),
        cmocka_unit_test_setup(test_clock_failure_requests_stop, setup),
        cmocka_unit_test_setup(test_led_patterns, setup),
        cmocka_unit_test_setup(test_led_blink_timing_exact, setup),
        cmocka_unit_test_setup(test_led_same_pattern_keeps_phase, setup),
        cmocka_unit_test_setup(test_led_active_low_and_bad_args, setup),
        cmocka_unit_test_setup(test_led_write_error_retried, setup),
        cmocka_unit_test_setup(test_deinit_turns_leds_off_and_releases, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
