/* Linux file storage: the on-disk format byte for byte, integrity checks,
 * crash leftovers, and out-of-space via RLIMIT_FSIZE (EFBIG). Contract
 * behaviour is in test/hal_conformance. */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "hal/hal_storage_linux.h"

static char root[256];
static char dir[300];
static hal_storage_linux_t st;

static int setup(void **state)
{
    (void)state;
    snprintf(root, sizeof root, "/tmp/coslam_st_XXXXXX");
    if (mkdtemp(root) == NULL) return -1;
    snprintf(dir, sizeof dir, "%s/blobs", root);
    return hal_storage_linux_open(&st, dir) == HAL_OK ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    hal_storage_close(&st.dev);
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", root);
    return system(cmd) == 0 ? 0 : -1;
}

static size_t slurp(const char *name, uint8_t *buf, size_t cap)
{
    char path[400];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    const size_t n = fread(buf, 1, cap, f);
    fclose(f);
    return n;
}

static void spit(const char *name, const uint8_t *buf, size_t n)
{
    char path[400];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(buf, 1, n, f), n);
    fclose(f);
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void test_file_format(void **state)
{
    (void)state;
    const uint8_t msg[] = "123456789"; /* CRC-32 check value 0xCBF43926 */
    assert_int_equal(hal_storage_write(&st.dev, "check", msg, 9), HAL_OK);
    uint8_t f[64];
    assert_int_equal(slurp("check", f, sizeof f), 16 + 9);
    assert_memory_equal(f, "CSB1", 4);
    assert_int_equal(le32(f + 4), 9);
    assert_int_equal(le32(f + 8), 0xCBF43926u);
    assert_memory_equal(f + 16, msg, 9);
    /* no temporary left behind */
    char path[400];
    snprintf(path, sizeof path, "%s/.check.tmp", dir);
    assert_int_equal(access(path, F_OK), -1);
}

static void expect_read(const char *name, hal_status_t want)
{
    uint8_t buf[64];
    size_t len = 0;
    assert_int_equal(hal_storage_read(&st.dev, name, buf, sizeof buf, &len), want);
}

static void test_damage_detected(void **state)
{
    (void)state;
    const uint8_t msg[20] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20};
    assert_int_equal(hal_storage_write(&st.dev, "m", msg, sizeof msg), HAL_OK);
    uint8_t good[64];
    const size_t n = slurp("m", good, sizeof good);
    uint8_t bad[64];

    memcpy(bad, good, n); /* payload bit flip */
    bad[16 + 7] ^= 0x01;
    spit("m", bad, n);
    expect_read("m", HAL_E_CORRUPT);

    memcpy(bad, good, n); /* header length changed (header CRC catches it) */
    bad[4] = 19;
    spit("m", bad, n);
    expect_read("m", HAL_E_CORRUPT);

    spit("m", good, n - 1); /* truncated */
    expect_read("m", HAL_E_CORRUPT);

    memcpy(bad, good, n); /* trailing garbage */
    bad[n] = 0;
    spit("m", bad, n + 1);
    expect_read("m", HAL_E_CORRUPT);

    spit("m", good, 10); /* not even a header */
    expect_read("m", HAL_E_CORRUPT);

    spit("m", (const uint8_t *)"CSB2xxxxxxxxxxxx", 16); /* wrong magic */
    expect_read("m", HAL_E_CORRUPT);

    spit("m", good, n); /* restored: fine again */
    expect_read("m", HAL_OK);
}

static void test_crash_leftover_ignored(void **state)
{
    (void)state;
    const uint8_t old[4] = {9, 8, 7, 6};
    assert_int_equal(hal_storage_write(&st.dev, "map", old, sizeof old), HAL_OK);
    /* a power cut during the next write leaves a partial temporary */
    spit(".map.tmp", (const uint8_t *)"CSB1\x40", 5);
    uint8_t buf[8];
    size_t len = 0;
    assert_int_equal(hal_storage_read(&st.dev, "map", buf, sizeof buf, &len), HAL_OK);
    assert_int_equal(len, 4);
    assert_memory_equal(buf, old, 4);
    /* and the next write simply replaces the leftover */
    const uint8_t fresh[2] = {1, 2};
    assert_int_equal(hal_storage_write(&st.dev, "map", fresh, sizeof fresh), HAL_OK);
    assert_int_equal(hal_storage_read(&st.dev, "map", buf, sizeof buf, &len), HAL_OK);
    assert_int_equal(len, 2);
}

static void test_no_space_keeps_old_blob(void **state)
{
    (void)state;
    const uint8_t old[100] = {42};
    assert_int_equal(hal_storage_write(&st.dev, "big", old, sizeof old), HAL_OK);
    /* file size limit: writes past it fail with EFBIG (SIGXFSZ ignored) */
    signal(SIGXFSZ, SIG_IGN);
    struct rlimit saved, lim;
    getrlimit(RLIMIT_FSIZE, &saved);
    lim = saved;
    lim.rlim_cur = 1000;
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
    static uint8_t huge[5000];
    const hal_status_t s = hal_storage_write(&st.dev, "big", huge, sizeof huge);
    setrlimit(RLIMIT_FSIZE, &saved);
    assert_int_equal(s, HAL_E_OVERFLOW);
    uint8_t buf[200];
    size_t len = 0;
    assert_int_equal(hal_storage_read(&st.dev, "big", buf, sizeof buf, &len), HAL_OK);
    assert_int_equal(len, 100);
    assert_memory_equal(buf, old, 100);
    char path[400];
    snprintf(path, sizeof path, "%s/.big.tmp", dir);
    assert_int_equal(access(path, F_OK), -1); /* failed temporary removed */
    /* the backend's own blob limit */
    st.max_blob_bytes = 10;
    assert_int_equal(hal_storage_write(&st.dev, "big", huge, 11), HAL_E_OVERFLOW);
}

static void test_open_errors_and_closed(void **state)
{
    (void)state;
    hal_storage_linux_t other;
    assert_int_equal(hal_storage_linux_open(&other, "/nonexistent_coslam_dir/a/b"), HAL_E_NOT_FOUND);
    assert_int_equal(hal_storage_linux_open(NULL, dir), HAL_E_ARG);
    assert_int_equal(hal_storage_linux_open(&other, ""), HAL_E_ARG);
    /* one writer per directory: a second open is refused until the first
     * closes; a reader opens beside it, and cannot write */
    assert_int_equal(hal_storage_linux_open(&other, dir), HAL_E_BUSY);
    assert_int_equal(hal_storage_linux_open_reader(&other, dir), HAL_OK);
    const uint8_t y = 2;
    assert_int_equal(hal_storage_write(&other.dev, "y", &y, 1), HAL_E_UNSUPPORTED);
    hal_storage_close(&other.dev);
    /* a directory blob is not a blob */
    char sub[400];
    snprintf(sub, sizeof sub, "%s/adir", dir);
    assert_int_equal(mkdir(sub, 0755), 0);
    expect_read("adir", HAL_E_CORRUPT);
    hal_storage_close(&st.dev);
    const uint8_t x = 1;
    assert_int_equal(hal_storage_write(&st.dev, "x", &x, 1), HAL_E_CLOSED);
    expect_read("x", HAL_E_CLOSED);
    assert_int_equal(hal_storage_linux_open(&st, dir), HAL_OK); /* for teardown: the lock went with the close */
}

/* A FIFO where a blob or its temporary should be (planted, or left by a
 * tool) must not hang the robot: open(2) of a FIFO waits for the other end.
 * The alarm kills the test, instead of hanging it, if a call blocks. */
static void test_fifo_does_not_block(void **state)
{
    (void)state;
    char path[400];
    snprintf(path, sizeof path, "%s/map", dir);
    assert_int_equal(mkfifo(path, 0644), 0);
    snprintf(path, sizeof path, "%s/.cal.tmp", dir);
    assert_int_equal(mkfifo(path, 0644), 0);
    alarm(10);
    expect_read("map", HAL_E_CORRUPT); /* not a blob, as a directory is not */
    const uint8_t x = 1;
    assert_int_equal(hal_storage_write(&st.dev, "cal", &x, 1), HAL_E_IO); /* refused, loudly */
    assert_int_equal(st.last_errno, ENXIO);
    alarm(0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_file_format, setup, teardown),
        cmocka_unit_test_setup_teardown(test_damage_detected, setup, teardown),
        cmocka_unit_test_setup_teardown(test_crash_leftover_ignored, setup, teardown),
        cmocka_unit_test_setup_teardown(test_no_space_keeps_old_blob, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_errors_and_closed, setup, teardown),
        cmocka_unit_test_setup_teardown(test_fifo_does_not_block, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
