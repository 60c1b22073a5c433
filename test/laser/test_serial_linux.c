/* Linux serial backend over a pseudo-terminal pair: the test holds the
 * master end, the backend opens the slave. Round trips are byte-exact for
 * all 256 byte values (raw mode), reads split at the caller's capacity,
 * timeouts are honoured, flush_input drops pending bytes, close restores the
 * terminal settings and makes the handle return HAL_E_CLOSED. */
#define _DEFAULT_SOURCE 1
#define _XOPEN_SOURCE 700

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "test_util.h"

#include "hal/hal_serial_linux.h"

typedef struct {
    int master;
    char slave_path[128];
    hal_serial_t dev;
    hal_serial_linux_t st;
} pty_fixture_t;

static double mono_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec / 1e6;
}

static int setup(void **state)
{
    pty_fixture_t *f = calloc(1, sizeof *f);
    assert_non_null(f);
    f->master = posix_openpt(O_RDWR | O_NOCTTY);
    assert_true(f->master >= 0);
    assert_int_equal(grantpt(f->master), 0);
    assert_int_equal(unlockpt(f->master), 0);
    const char *name = ptsname(f->master);
    assert_non_null(name);
    strncpy(f->slave_path, name, sizeof f->slave_path - 1U);
    /* the master side raw too, so the test sees the bytes unmodified */
    struct termios t;
    assert_int_equal(tcgetattr(f->master, &t), 0);
    cfmakeraw(&t);
    assert_int_equal(tcsetattr(f->master, TCSANOW, &t), 0);
    assert_int_equal(hal_serial_linux_open(&f->dev, &f->st, f->slave_path, 115200), HAL_OK);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    pty_fixture_t *f = *state;
    hal_serial_close(&f->dev);
    if (f->master >= 0) {
        close(f->master);
    }
    free(f);
    return 0;
}

/* read exactly n bytes from the master, waiting up to 1 s in total */
static void master_read_exact(int fd, uint8_t *buf, size_t n)
{
    size_t got = 0;
    const double t0 = mono_ms();
    while (got < n) {
        struct pollfd p = {.fd = fd, .events = POLLIN, .revents = 0};
        assert_true(poll(&p, 1, 100) >= 0);
        if (p.revents & POLLIN) {
            const ssize_t r = read(fd, buf + got, n - got);
            assert_true(r > 0);
            got += (size_t)r;
        }
        assert_true(mono_ms() - t0 < 1000.0);
    }
}

/* read exactly n bytes through the HAL with a given per-call capacity */
static void hal_read_exact(hal_serial_t *d, uint8_t *buf, size_t n, size_t cap, size_t *calls)
{
    size_t got = 0;
    *calls = 0;
    while (got < n) {
        size_t k = 0;
        const size_t c = (n - got) < cap ? (n - got) : cap;
        assert_int_equal(hal_serial_read(d, buf + got, c, &k, 500000), HAL_OK);
        assert_true(k >= 1 && k <= c);
        got += k;
        ++*calls;
    }
}

static void test_round_trip_all_bytes(void **state)
{
    pty_fixture_t *f = *state;
    uint8_t out[256], in[256];
    for (int i = 0; i < 256; ++i) {
        out[i] = (uint8_t)i;
    }
    /* HAL -> master */
    assert_int_equal(hal_serial_write(&f->dev, out, sizeof out, 500000), HAL_OK);
    master_read_exact(f->master, in, sizeof in);
    assert_memory_equal(in, out, sizeof out);
    /* master -> HAL */
    memset(in, 0, sizeof in);
    assert_int_equal(write(f->master, out, sizeof out), (ssize_t)sizeof out);
    size_t calls = 0;
    hal_read_exact(&f->dev, in, sizeof in, sizeof in, &calls);
    assert_memory_equal(in, out, sizeof out);
}

static void test_split_reads(void **state)
{
    pty_fixture_t *f = *state;
    const char *msg = "MD0044072501000\n99b\n0Dh1c\n0123456789abcdefghijklmnopqrstuvwxyz\n\n";
    const size_t n = strlen(msg);
    assert_int_equal(write(f->master, msg, n), (ssize_t)n);
    uint8_t in[128];
    size_t calls = 0;
    hal_read_exact(&f->dev, in, n, 7, &calls);
    assert_memory_equal(in, msg, n);
    assert_true(calls >= (n + 6) / 7); /* a read never exceeds its capacity */
}

static void test_timeouts(void **state)
{
    pty_fixture_t *f = *state;
    uint8_t b[4];
    size_t k = 99;
    double t0 = mono_ms();
    assert_int_equal(hal_serial_read(&f->dev, b, sizeof b, &k, 0), HAL_E_TIMEOUT);
    assert_int_equal(k, 0);
    assert_true(mono_ms() - t0 < 50.0);
    t0 = mono_ms();
    assert_int_equal(hal_serial_read(&f->dev, b, sizeof b, &k, 60000), HAL_E_TIMEOUT);
    const double dt = mono_ms() - t0;
    ASSERT_TRUE_MSG(dt >= 55.0 && dt < 600.0, "60 ms timeout took %.1f ms\n", dt);
    /* a byte arriving later than the timeout is still there afterwards */
    assert_int_equal(write(f->master, "z", 1), 1);
    assert_int_equal(hal_serial_read(&f->dev, b, sizeof b, &k, 500000), HAL_OK);
    assert_int_equal(k, 1);
    assert_int_equal(b[0], 'z');
}

static void test_flush_input(void **state)
{
    pty_fixture_t *f = *state;
    assert_int_equal(write(f->master, "stale bytes", 11), 11);
    /* wait until they have reached the slave's input queue */
    struct pollfd p = {.fd = hal_serial_linux_fd(&f->dev), .events = POLLIN, .revents = 0};
    assert_int_equal(poll(&p, 1, 1000), 1);
    assert_int_equal(hal_serial_flush_input(&f->dev), HAL_OK);
    uint8_t b[32];
    size_t k = 0;
    assert_int_equal(hal_serial_read(&f->dev, b, sizeof b, &k, 20000), HAL_E_TIMEOUT);
    assert_int_equal(write(f->master, "new", 3), 3);
    size_t calls = 0;
    hal_read_exact(&f->dev, b, 3, sizeof b, &calls);
    assert_memory_equal(b, "new", 3);
}

static void test_set_baud(void **state)
{
    pty_fixture_t *f = *state;
    assert_int_equal(hal_serial_set_baud(&f->dev, 19200), HAL_OK);
    assert_int_equal(f->st.baud, 19200);
    assert_int_equal(hal_serial_set_baud(&f->dev, 12345), HAL_E_ARG);
    assert_int_equal(f->st.baud, 19200);
}

static void test_close_restores_and_closes(void **state)
{
    pty_fixture_t *f = *state;
    /* a second descriptor on the slave, opened before the HAL's exclusive
     * lock matters: reopen after closing the HAL handle */
    hal_serial_close(&f->dev);
    assert_int_equal(hal_serial_linux_fd(&f->dev), -1);
    int fd2 = open(f->slave_path, O_RDWR | O_NOCTTY);
    assert_true(fd2 >= 0);
    struct termios before;
    assert_int_equal(tcgetattr(fd2, &before), 0);
    /* set a cooked mode, open through the HAL, check raw, close, check restored */
    before.c_lflag |= (tcflag_t)(ICANON | ECHO);
    before.c_oflag |= (tcflag_t)OPOST;
    assert_int_equal(tcsetattr(fd2, TCSANOW, &before), 0);
    assert_int_equal(hal_serial_linux_open(&f->dev, &f->st, f->slave_path, 9600), HAL_OK);
    struct termios during;
    assert_int_equal(tcgetattr(fd2, &during), 0);
    assert_int_equal(during.c_lflag & (ICANON | ECHO), 0);
    assert_int_equal(during.c_oflag & OPOST, 0);
    assert_int_equal(during.c_cflag & CSIZE, CS8);
    assert_int_equal(cfgetospeed(&during), B9600);
    hal_serial_close(&f->dev);
    struct termios after;
    assert_int_equal(tcgetattr(fd2, &after), 0);
    assert_int_equal(after.c_lflag & (ICANON | ECHO), ICANON | ECHO);
    assert_int_equal(after.c_oflag & OPOST, OPOST);
    close(fd2);
    /* every operation on the closed handle reports HAL_E_CLOSED */
    uint8_t b[2];
    size_t k = 0;
    assert_int_equal(hal_serial_read(&f->dev, b, sizeof b, &k, 0), HAL_E_CLOSED);
    assert_int_equal(hal_serial_write(&f->dev, b, 1, 0), HAL_E_CLOSED);
    assert_int_equal(hal_serial_flush_input(&f->dev), HAL_E_CLOSED);
    assert_int_equal(hal_serial_set_baud(&f->dev, 9600), HAL_E_CLOSED);
    hal_serial_close(&f->dev); /* idempotent */
}

static void test_peer_hangup(void **state)
{
    pty_fixture_t *f = *state;
    close(f->master);
    f->master = -1;
    uint8_t b[4];
    size_t k = 0;
    const hal_status_t st = hal_serial_read(&f->dev, b, sizeof b, &k, 200000);
    ASSERT_TRUE_MSG(st == HAL_E_CLOSED, "read after hang-up: %s\n", hal_status_str(st));
}

static void test_open_errors(void **state)
{
    (void)state;
    hal_serial_t d;
    hal_serial_linux_t s;
    assert_int_equal(hal_serial_linux_open(&d, &s, "/dev/ttyDOES_NOT_EXIST_42", 115200), HAL_E_NOT_FOUND);
    assert_int_equal(hal_serial_linux_open(&d, &s, "/nonexistent_dir/ttyUSB0", 115200), HAL_E_NOT_FOUND);
    assert_int_equal(hal_serial_linux_open(&d, &s, "/dev/null", 115200), HAL_E_UNSUPPORTED);
    assert_int_equal(hal_serial_linux_open(&d, &s, "/dev/null", 12345), HAL_E_ARG);
    assert_int_equal(hal_serial_linux_open(NULL, &s, "/dev/null", 9600), HAL_E_ARG);
    assert_int_equal(hal_serial_linux_open(&d, NULL, "/dev/null", 9600), HAL_E_ARG);
    assert_int_equal(hal_serial_linux_open(&d, &s, NULL, 9600), HAL_E_ARG);
    assert_int_equal(hal_serial_linux_fd(&d), -1);
    /* the failed handle is unusable, not dangerous */
    uint8_t b[1];
    size_t k = 0;
    assert_int_equal(hal_serial_read(&d, b, 1, &k, 0), HAL_E_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_round_trip_all_bytes, setup, teardown),
        cmocka_unit_test_setup_teardown(test_split_reads, setup, teardown),
        cmocka_unit_test_setup_teardown(test_timeouts, setup, teardown),
        cmocka_unit_test_setup_teardown(test_flush_input, setup, teardown),
        cmocka_unit_test_setup_teardown(test_set_baud, setup, teardown),
        cmocka_unit_test_setup_teardown(test_close_restores_and_closes, setup, teardown),
        cmocka_unit_test_setup_teardown(test_peer_hangup, setup, teardown),
        cmocka_unit_test(test_open_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
