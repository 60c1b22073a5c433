/* White-box tests of the libgpiod v1 GPIO backend against the link-time
 * fake (gpiod_fake.h): what the backend asks the kernel for, how it maps
 * kernel errors and events, and how it converts timeouts and stamps. */
#include <errno.h>
#include <gpiod.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "gpiod_fake.h"
#include "hal/hal_gpio_linux.h"

static hal_gpio_linux_t g;

static int setup(void **state)
{
    (void)state;
    fake_gpiod_reset(8);
    return hal_gpio_linux_open(&g, "gpiochip3", "coslam-test") == HAL_OK ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    hal_gpio_close(&g.dev);
    return 0;
}

static hal_gpio_config_t cfg(hal_gpio_dir_t dir, bool active_low, bool init, uint8_t edges)
{
    hal_gpio_config_t c;
    memset(&c, 0, sizeof c);
    c.dir = dir;
    c.active_low = active_low;
    c.initial_active = init;
    c.edges = edges;
    return c;
}

static void test_open_and_close(void **state)
{
    (void)state;
    assert_true(fake_gpiod.chip_open);
    assert_string_equal(fake_gpiod.opened_name, "gpiochip3");
    uint32_t n = 0;
    assert_int_equal(hal_gpio_line_count(&g.dev, &n), HAL_OK);
    assert_int_equal(n, 8);
    const hal_gpio_config_t in = cfg(HAL_GPIO_DIR_INPUT, false, false, HAL_GPIO_EDGE_NONE);
    assert_int_equal(hal_gpio_configure(&g.dev, 2, &in), HAL_OK);
    assert_int_equal(hal_gpio_configure(&g.dev, 5, &in), HAL_OK);
    hal_gpio_close(&g.dev);
    assert_false(fake_gpiod.chip_open);
    assert_int_equal(fake_gpiod.n_chip_close, 1);
    assert_int_equal(fake_gpiod.n_releases, 2);
    assert_false(fake_gpiod.lines[2].requested);
    /* after close: every op says so, close again is harmless */
    assert_int_equal(hal_gpio_line_count(&g.dev, &n), HAL_E_CLOSED);
    hal_gpio_close(&g.dev);
    assert_int_equal(fake_gpiod.n_chip_close, 1);
}

static void test_open_errors(void **state)
{
    (void)state;
    hal_gpio_linux_t other;
    fake_gpiod.fail_open_errno = ENOENT;
    assert_int_equal(hal_gpio_linux_open(&other, "nochip", "x"), HAL_E_NOT_FOUND);
    fake_gpiod.fail_open_errno = EACCES;
    assert_int_equal(hal_gpio_linux_open(&other, "gpiochip0", "x"), HAL_E_IO);
    fake_gpiod.fail_open_errno = 0;
    assert_int_equal(hal_gpio_linux_open(NULL, "gpiochip0", "x"), HAL_E_ARG);
    assert_int_equal(hal_gpio_linux_open(&other, NULL, "x"), HAL_E_ARG);
}

static void test_line_count_capped(void **state)
{
    (void)state;
    hal_gpio_close(&g.dev);
    fake_gpiod_reset(HAL_GPIO_LINUX_MAX_LINES + 10u);
    assert_int_equal(hal_gpio_linux_open(&g, "0", "c"), HAL_OK);
    uint32_t n = 0;
    assert_int_equal(hal_gpio_line_count(&g.dev, &n), HAL_OK);
    assert_int_equal(n, HAL_GPIO_LINUX_MAX_LINES);
    const hal_gpio_config_t in = cfg(HAL_GPIO_DIR_INPUT, false, false, 0);
    assert_int_equal(hal_gpio_configure(&g.dev, HAL_GPIO_LINUX_MAX_LINES, &in), HAL_E_NOT_FOUND);
}

static void test_wrapper_rejects_bad_direction(void **state)
{
    (void)state;
    hal_gpio_config_t c = cfg(HAL_GPIO_DIR_INPUT, false, false, 0);
    c.dir = (hal_gpio_dir_t)7; /* fine in C; the wrapper must refuse it */
    assert_int_equal(hal_gpio_configure(&g.dev, 1, &c), HAL_E_ARG);
    assert_false(fake_gpiod.lines[1].requested);
}

static void test_request_parameters(void **state)
{
    (void)state;
    /* what the kernel is asked for, per configuration */
    const struct {
        hal_gpio_config_t c;
        int type;
        int flags;
        int default_val;
    } cases[] = {
        {cfg(HAL_GPIO_DIR_INPUT, false, false, HAL_GPIO_EDGE_NONE), GPIOD_LINE_REQUEST_DIRECTION_INPUT, 0, 0},
        {cfg(HAL_GPIO_DIR_INPUT, true, false, HAL_GPIO_EDGE_RISING), GPIOD_LINE_REQUEST_EVENT_RISING_EDGE,
         GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW, 0},
        {cfg(HAL_GPIO_DIR_INPUT, false, false, HAL_GPIO_EDGE_FALLING), GPIOD_LINE_REQUEST_EVENT_FALLING_EDGE, 0, 0},
        {cfg(HAL_GPIO_DIR_INPUT, false, false, HAL_GPIO_EDGE_BOTH), GPIOD_LINE_REQUEST_EVENT_BOTH_EDGES, 0, 0},
        {cfg(HAL_GPIO_DIR_OUTPUT, false, true, 0), GPIOD_LINE_REQUEST_DIRECTION_OUTPUT, 0, 1},
        {cfg(HAL_GPIO_DIR_OUTPUT, true, false, 0), GPIOD_LINE_REQUEST_DIRECTION_OUTPUT,
         GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW, 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        assert_int_equal(hal_gpio_configure(&g.dev, 1, &cases[i].c), HAL_OK);
        const fake_gpiod_line_t *l = &fake_gpiod.lines[1];
        assert_true(l->requested);
        assert_int_equal(l->request_type, cases[i].type);
        assert_int_equal(l->flags, cases[i].flags);
        assert_int_equal(l->default_val, cases[i].default_val);
        assert_string_equal(l->consumer, "coslam-test");
    }
    /* each reconfigure released the previous request first (else EBUSY) */
    assert_int_equal(fake_gpiod.n_releases, 5);
}

static void test_consumer_truncated(void **state)
{
    (void)state;
    hal_gpio_close(&g.dev);
    fake_gpiod_reset(2);
    assert_int_equal(hal_gpio_linux_open(&g, "0", "a-consumer-label-that-is-far-too-long-for-gpioinfo"), HAL_OK);
    assert_int_equal(strlen(g.consumer), HAL_GPIO_LINUX_CONSUMER_MAX);
}

static void test_kernel_errors_mapped(void **state)
{
    (void)state;
    const hal_gpio_config_t in = cfg(HAL_GPIO_DIR_INPUT, false, false, 0);
    fake_gpiod.lines[3].fail_request_errno = EBUSY;
    assert_int_equal(hal_gpio_configure(&g.dev, 3, &in), HAL_E_BUSY);
    bool v;
    assert_int_equal(hal_gpio_read(&g.dev, 3, &v), HAL_E_CLOSED); /* failed configure leaves it released */
    fake_gpiod.lines[3].fail_request_errno = EOPNOTSUPP;
    assert_int_equal(hal_gpio_configure(&g.dev, 3, &in), HAL_E_UNSUPPORTED);
    fake_gpiod.lines[3].fail_request_errno = EIO;
    assert_int_equal(hal_gpio_configure(&g.dev, 3, &in), HAL_E_IO);
    assert_int_equal(hal_gpio_configure(&g.dev, 3, &in), HAL_OK);
    fake_gpiod.lines[3].fail_get_errno = EIO;
    assert_int_equal(hal_gpio_read(&g.dev, 3, &v), HAL_E_IO);
    const hal_gpio_config_t out = cfg(HAL_GPIO_DIR_OUTPUT, false, false, 0);
    assert_int_equal(hal_gpio_configure(&g.dev, 4, &out), HAL_OK);
    fake_gpiod.lines[4].fail_set_errno = EIO;
    assert_int_equal(hal_gpio_write(&g.dev, 4, true), HAL_E_IO);
    assert_int_equal(hal_gpio_read(&g.dev, 4, &v), HAL_OK);
    assert_false(v); /* the cached read-back did not take the failed write */
}

static void test_wait_timeout_conversion(void **state)
{
    (void)state;
    const hal_gpio_config_t in = cfg(HAL_GPIO_DIR_INPUT, false, false, HAL_GPIO_EDGE_BOTH);
    assert_int_equal(hal_gpio_configure(&g.dev, 0, &in), HAL_OK);
    hal_gpio_event_t ev;
    assert_int_equal(hal_gpio_wait_edge(&g.dev, 0, &ev, 0), HAL_E_TIMEOUT);
    assert_int_equal(fake_gpiod.last_wait_timeout.tv_sec, 0);
    assert_int_equal(fake_gpiod.last_wait_timeout.tv_nsec, 0);
    assert_int_equal(hal_gpio_wait_edge(&g.dev, 0, &ev, 2500000), HAL_E_TIMEOUT);
    /* ~2.5 s minus the few us spent before the call */
    assert_int_equal(fake_gpiod.last_wait_timeout.tv_sec, 2);
    assert_true(fake_gpiod.last_wait_timeout.tv_nsec > 490000000L);
    assert_true(fake_gpiod.last_wait_timeout.tv_nsec <= 500000000L);
    /* EINTR is retried, not reported */
    fake_gpiod.pending_eintr = 2;
    const unsigned calls = fake_gpiod.n_wait_calls;
    assert_int_equal(hal_gpio_wait_edge(&g.dev, 0, &ev, 1000), HAL_E_TIMEOUT);
    assert_int_equal(fake_gpiod.n_wait_calls, calls + 3);
}

static void test_event_mapping(void **state)
{
    (void)state;
    const hal_gpio_config_t in = cfg(HAL_GPIO_DIR_INPUT, true, false, HAL_GPIO_EDGE_BOTH);
    fake_gpiod_drive(6, true); /* inactive on an active-low line */
    assert_int_equal(hal_gpio_configure(&g.dev, 6, &in), HAL_OK);
    fake_gpiod.now_us = 1234567890123ull;
    fake_gpiod_drive(6, false);
    hal_gpio_event_t ev;
    assert_int_equal(hal_gpio_wait_edge(&g.dev, 6, &ev, 0), HAL_OK);
    assert_int_equal(ev.edge, HAL_GPIO_EDGE_RISING);
    assert_int_equal(ev.stamp_us, 1234567890123ull);
    bool v = false;
    assert_int_equal(hal_gpio_read(&g.dev, 6, &v), HAL_OK);
    assert_true(v);
    /* an output line: its pin follows writes, active-low inverted */
    const hal_gpio_config_t out = cfg(HAL_GPIO_DIR_OUTPUT, true, true, 0);
    assert_int_equal(hal_gpio_configure(&g.dev, 7, &out), HAL_OK);
    assert_false(fake_gpiod_pin(7));
    assert_int_equal(hal_gpio_write(&g.dev, 7, false), HAL_OK);
    assert_true(fake_gpiod_pin(7));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_open_and_close, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_errors, setup, teardown),
        cmocka_unit_test_setup_teardown(test_line_count_capped, setup, teardown),
        cmocka_unit_test_setup_teardown(test_wrapper_rejects_bad_direction, setup, teardown),
        cmocka_unit_test_setup_teardown(test_request_parameters, setup, teardown),
        cmocka_unit_test_setup_teardown(test_consumer_truncated, setup, teardown),
        cmocka_unit_test_setup_teardown(test_kernel_errors_mapped, setup, teardown),
        cmocka_unit_test_setup_teardown(test_wait_timeout_conversion, setup, teardown),
        cmocka_unit_test_setup_teardown(test_event_mapping, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
