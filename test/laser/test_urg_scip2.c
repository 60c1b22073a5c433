/* SCIP 2.0 driver against a scripted fake serial: byte-exact command frames,
 * byte-exact replies (published examples where they exist), split reads at
 * every byte, and each corruption class counted with the driver recovering
 * on the next message. */
#include <stdlib.h>
#include <string.h>

#include "test_util.h"

#include "fake_serial.h"
#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "urg/urg_scip2.h"

/* ---------------------------------------------------------------------------
 * A reply encoder written for the tests (independent of the driver code).
 * ------------------------------------------------------------------------ */

static char sum_of(const char *s, size_t n)
{
    unsigned v = 0;
    for (size_t i = 0; i < n; ++i) v += (unsigned char)s[i];
    return (char)((v & 0x3FU) + 0x30U);
}

static void enc(char *out, uint32_t v, int n_chars)
{
    for (int i = 0; i < n_chars; ++i) {
        out[i] = (char)(((v >> (6 * (n_chars - 1 - i))) & 0x3FU) + 0x30U);
    }
}

typedef enum { CORRUPT_NONE, CORRUPT_SUM, CORRUPT_SHORT_LINE, CORRUPT_GARBAGE, CORRUPT_DROP_LINE,
               CORRUPT_EXTRA_LINE, CORRUPT_STAMP_LEN } corrupt_t;

/* A scan message "echo LF status LF stamp LF data... LF LF" into out; the
 * corruption (if any) hits data line `bad_line`. Returns its length. */
static size_t build_scan(char *out, const char *echo, const char *status, uint32_t stamp_ms, const uint32_t *vals,
                         size_t n, corrupt_t corrupt, size_t bad_line)
{
    size_t k = 0;
    k += (size_t)sprintf(out + k, "%s\n%s%c\n", echo, status, sum_of(status, 2));
    char st[5];
    enc(st, stamp_ms, 4);
    st[4] = sum_of(st, 4);
    memcpy(out + k, st, 5);
    k += 5;
    if (corrupt == CORRUPT_STAMP_LEN) {
        out[k++] = '0';
    }
    out[k++] = '\n';
    static char data[3 * 4096];
    for (size_t i = 0; i < n; ++i) enc(data + 3 * i, vals[i], 3);
    const size_t total = 3 * n;
    size_t line = 0;
    for (size_t off = 0; off < total; off += 64, ++line) {
        size_t len = total - off < 64 ? total - off : 64;
        const char *p = data + off;
        if (line == bad_line && corrupt == CORRUPT_DROP_LINE) continue;
        if (line == bad_line && corrupt == CORRUPT_SHORT_LINE) len -= 1;
        memcpy(out + k, p, len);
        char s = sum_of(p, len);
        if (line == bad_line && corrupt == CORRUPT_SUM) s = (char)(s == '0' ? '1' : s - 1);
        if (line == bad_line && corrupt == CORRUPT_GARBAGE) out[k + 5] = (char)0xFF;
        out[k + len] = s;
        out[k + len + 1] = '\n';
        k += len + 2;
        if (line == bad_line && corrupt == CORRUPT_EXTRA_LINE) {
            memcpy(out + k, "0000\n", 5); /* "000" + its sum '0'... a 4th data line */
            out[k + 3] = sum_of("000", 3);
            k += 5;
        }
    }
    out[k++] = '\n';
    out[k] = '\0';
    return k;
}

/* PP's reply of a URG-04LX (the published example) */
#define PP04_REPLY                                                                                                     \
    "PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nDMIN:20;4\nDMAX:5600;_\nARES:1024;\\\n"                     \
    "AMIN:44;7\nAMAX:725;o\nAFRT:384;6\nSCAN:600;e\n\n"

#define N04 682 /* URG-04LX: steps 44..725 */
static uint32_t vals04[N04];
static char msg[16384];
static char msg2[16384];

static void fill_vals(uint32_t seed)
{
    for (size_t i = 0; i < N04; ++i) {
        vals04[i] = (uint32_t)((i * 37U + seed * 101U) % 5600U) + 20U;
    }
    vals04[0] = 0;      /* error code 0 */
    vals04[1] = 19;     /* highest error code */
    vals04[2] = 20;     /* DMIN itself: a range */
    vals04[3] = 5600;   /* DMAX */
    vals04[4] = 262143; /* largest 18-bit value */
}

typedef struct {
    fake_serial_t fake;
    urg_scip2_t urg;
    urg_scip2_scan_t scan;
} fixture_t;

static int setup(void **state)
{
    fixture_t *f = calloc(1, sizeof *f);
    assert_non_null(f);
    fake_init(&f->fake);
    assert_int_equal(urg_scip2_init(&f->urg, &f->fake.dev, NULL), COSLAM_OK);
    fill_vals(1);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    free(*state);
    return 0;
}

static void assert_written(const fake_serial_t *f, const char *expect)
{
    const size_t n = strlen(expect);
    ASSERT_TRUE_MSG(f->n_written == n && memcmp(f->written, expect, n) == 0, "written \"%.*s\" expected \"%s\"\n",
                    (int)f->n_written, (const char *)f->written, expect);
}

/* start MD 44..725 and script its acknowledgement */
static void start_md04(fixture_t *f, uint8_t n_scans)
{
    char echo[32];
    sprintf(echo, "MD00440725010%02u\n00P\n\n", n_scans);
    fake_add_str(&f->fake, 1, echo);
    assert_int_equal(urg_scip2_start_md(&f->urg, 44, 725, 1, 0, n_scans), COSLAM_OK);
    char frame[32];
    sprintf(frame, "MD00440725010%02u\n", n_scans);
    assert_written(&f->fake, frame);
    assert_true(urg_scip2_is_streaming(&f->urg));
}

static void expect_scan04(const urg_scip2_scan_t *s, uint32_t stamp_ms)
{
    assert_int_equal(s->n_points, N04);
    assert_int_equal(s->first_step, 44);
    assert_int_equal(s->last_step, 725);
    assert_int_equal(s->raw_stamp_ms, stamp_ms);
    assert_memory_equal(s->range_mm, vals04, sizeof vals04);
}

/* ---------------------------------------------------------------------------
 * Pure helpers against the specification's examples
 * ------------------------------------------------------------------------ */

static void test_checksum_and_decode_vectors(void **state)
{
    (void)state;
    assert_int_equal(urg_scip2_checksum("00", 2), 'P');
    assert_int_equal(urg_scip2_checksum("99", 2), 'b');
    assert_int_equal(urg_scip2_checksum("DMIN:20", 7), '4');
    assert_int_equal(urg_scip2_checksum("DMAX:5600", 9), '_');
    assert_int_equal(urg_scip2_checksum("AMAX:725", 8), 'o');
    assert_int_equal(urg_scip2_checksum("PROT:SCIP 2.0", 13), 'N');
    assert_int_equal(urg_scip2_decode("1Dh", 3), 5432);     /* spec fig. 5 */
    assert_int_equal(urg_scip2_decode("CB", 2), 1234);      /* spec fig. 3 */
    assert_int_equal(urg_scip2_decode("m2@0", 4), 16000000); /* spec fig. 7 */
    assert_int_equal(urg_scip2_decode("ooo", 3), 262143);
    assert_int_equal(urg_scip2_decode("000", 3), 0);
    assert_int_equal(urg_scip2_decode("0/0", 3), -1); /* '/' = 0x2F below the alphabet */
    assert_int_equal(urg_scip2_decode("0p0", 3), -1); /* 'p' = 0x70 above it */
    assert_int_equal(urg_scip2_decode("00000", 5), -1);
    assert_int_equal(urg_scip2_decode("0", 0), -1);
}

static void test_angles_and_validity(void **state)
{
    (void)state;
    const urg_scip2_params_t p = urg_scip2_params_urg04lx();
    ASSERT_NEAR(urg_scip2_step_angle_rad(&p, 384), 0.0, 0.0);
    ASSERT_NEAR(urg_scip2_step_angle_rad(&p, 44), -340.0 * 2.0 * COSLAM_PI / 1024.0, 1e-12);
    ASSERT_NEAR(urg_scip2_step_angle_rad(&p, 725), 341.0 * 2.0 * COSLAM_PI / 1024.0, 1e-12);
    /* 682 steps cover 681 * 360/1024 = 239.4 deg between first and last step */
    ASSERT_NEAR((urg_scip2_step_angle_rad(&p, 725) - urg_scip2_step_angle_rad(&p, 44)) * 180.0 / COSLAM_PI,
                681.0 * 360.0 / 1024.0, 1e-9);
    ASSERT_NEAR(urg_scip2_step_angle_rad(&p, 640), COSLAM_PI / 2.0, 1e-12); /* 256 steps = 90 deg, left */
    assert_false(urg_scip2_range_valid(&p, 0));
    assert_false(urg_scip2_range_valid(&p, 19));
    assert_true(urg_scip2_range_valid(&p, 20));
    assert_true(urg_scip2_range_valid(&p, 5600));
    assert_false(urg_scip2_range_valid(&p, 5601));
}

/* ---------------------------------------------------------------------------
 * Commands: frames and replies
 * ------------------------------------------------------------------------ */

static void test_enter_scip2(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 0, "stale bytes from before\n"); /* dropped by the flush */
    fake_add_str(&f->fake, 1, "SCIP2.0\n0\n\n");
    assert_int_equal(urg_scip2_enter_scip2(&f->urg), COSLAM_OK);
    assert_written(&f->fake, "SCIP2.0\n");
    assert_int_equal(f->fake.n_flushes, 1);
    /* already in SCIP 2.0: "0E" + sum 'e' */
    fake_add_str(&f->fake, 2, "SCIP2.0\n0Ee\n\n");
    f->fake.n_written = 0;
    assert_int_equal(urg_scip2_enter_scip2(&f->urg), COSLAM_OK);
    assert_written(&f->fake, "SCIP2.0\n");
    /* no answer at all */
    assert_int_equal(urg_scip2_enter_scip2(&f->urg), COSLAM_E_URG_TIMEOUT);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_timeout, 1);
}

static void test_version_published_example(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1,
                 "VV\n00P\nVEND:Hokuyo Automatic Co.,Ltd.;[\nPROD:SOKUIKI Sensor URG-04LX;[\n"
                 "FIRM:3.1.00(18/Jan./2007);`\nPROT:SCIP 2.0;N\nSERI:H0614967;V\n\n");
    urg_scip2_version_t v;
    assert_int_equal(urg_scip2_read_version(&f->urg, &v), COSLAM_OK);
    assert_written(&f->fake, "VV\n");
    assert_string_equal(v.vendor, "Hokuyo Automatic Co.,Ltd.");
    assert_string_equal(v.product, "SOKUIKI Sensor URG-04LX");
    assert_string_equal(v.firmware, "3.1.00(18/Jan./2007)");
    assert_string_equal(v.protocol, "SCIP 2.0");
    assert_string_equal(v.serial, "H0614967");
}

static void test_params_published_example(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1,
                 "PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nDMIN:20;4\nDMAX:5600;_\nARES:1024;\\\n"
                 "AMIN:44;7\nAMAX:725;o\nAFRT:384;6\nSCAN:600;e\n\n");
    urg_scip2_params_t p;
    assert_int_equal(urg_scip2_read_params(&f->urg, &p), COSLAM_OK);
    assert_written(&f->fake, "PP\n");
    assert_string_equal(p.model, "URG-04LX(Hokuyo Automatic Co.,Ltd.)");
    assert_int_equal(p.dmin_mm, 20);
    assert_int_equal(p.dmax_mm, 5600);
    assert_int_equal(p.ares, 1024);
    assert_int_equal(p.amin, 44);
    assert_int_equal(p.amax, 725);
    assert_int_equal(p.afrt, 384);
    assert_int_equal(p.scan_rpm, 600);
    assert_int_equal(urg_scip2_params(&f->urg)->amax, 725);
    assert_int_equal(p.amax - p.amin + 1, 682);
}

static void test_params_bad_fields(void **state)
{
    fixture_t *f = *state;
    /* a field with a wrong sum: CHECKSUM, and the rest of the reply is
     * discarded before the next command's reply is read */
    fake_add_str(&f->fake, 1, "PP\n00P\nMODL:X;i\nDMIN:20;5\nDMAX:5600;_\n\n");
    assert_int_equal(urg_scip2_read_params(&f->urg, NULL), COSLAM_E_URG_CHECKSUM);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_checksum, 1);
    /* DMIN missing: FIELD */
    char body[256];
    sprintf(body, "PP\n00P\nMODL:X;%c\nDMAX:5600;_\nARES:1024;\\\nAMIN:44;7\nAMAX:725;o\nAFRT:384;6\nSCAN:600;e\n\n",
            sum_of("MODL:X", 6));
    fake_add_str(&f->fake, 2, body);
    assert_int_equal(urg_scip2_read_params(&f->urg, NULL), COSLAM_E_URG_FIELD);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_field, 1);
    assert_int_equal(urg_scip2_stats(&f->urg)->resyncs, 1);
    /* a non-numeric DMIN: FIELD; the old parameters stay */
    sprintf(body, "PP\n00P\nMODL:X;%c\nDMIN:2x;%c\nDMAX:5600;_\nARES:1024;\\\nAMIN:44;7\nAMAX:725;o\nAFRT:384;6\n"
                  "SCAN:600;e\n\n",
            sum_of("MODL:X", 6), sum_of("DMIN:2x", 7));
    fake_add_str(&f->fake, 3, body);
    assert_int_equal(urg_scip2_read_params(&f->urg, NULL), COSLAM_E_URG_FIELD);
    assert_int_equal(urg_scip2_params(&f->urg)->dmin_mm, 20);
}

static void test_info_published_example(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1,
                 "II\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nLASR:OFF;7\n"
                 "SCSP:Initial(600[rpm])<-Default setting by user;A\nMESM:IDLE;:\n"
                 "SBPS:19200[bps]<-Default setting by user;A\nTIME:081615;N\nSTAT:Sensor works well.;8\n\n");
    urg_scip2_info_t info;
    assert_int_equal(urg_scip2_read_info(&f->urg, &info), COSLAM_OK);
    assert_written(&f->fake, "II\n");
    assert_string_equal(info.laser, "OFF");
    assert_int_equal(info.laser_on, 0);
    assert_string_equal(info.mode, "IDLE");
    assert_string_equal(info.time, "081615");
    assert_string_equal(info.status, "Sensor works well.");
}

static void test_laser_on_off(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1, "BM\n00P\n\n");
    fake_add_str(&f->fake, 2, "BM\n02R\n\n"); /* already on: success */
    fake_add_str(&f->fake, 3, "BM\n01Q\n\n"); /* laser malfunction */
    fake_add_str(&f->fake, 4, "QT\n00P\n\n");
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_E_URG_STATUS);
    assert_string_equal(urg_scip2_last_status(&f->urg), "01");
    assert_int_equal(urg_scip2_laser_off(&f->urg), COSLAM_OK);
    assert_written(&f->fake, "BM\nBM\nBM\nQT\n");
    assert_int_equal(urg_scip2_stats(&f->urg)->err_status, 1);
    assert_int_equal(urg_scip2_stats(&f->urg)->resyncs, 0);
}

static void test_write_failure_is_io(void **state)
{
    fixture_t *f = *state;
    f->fake.write_result = HAL_E_CLOSED;
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_E_URG_IO);
    f->fake.write_result = HAL_OK;
    f->fake.read_result = HAL_E_IO;
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_E_URG_IO);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_io, 2);
}

/* ---------------------------------------------------------------------------
 * Scans
 * ------------------------------------------------------------------------ */

static void test_gd_byte_exact(void **state)
{
    fixture_t *f = *state;
    /* 3 points: 5432 ("1Dh"), 1234 ("0CB"), error code 0 ("000"); stamp
     * 16,000,000 ms ("m2@0") */
    fake_add_str(&f->fake, 1, "GD0044004601\n00P\nm2@0?\n1Dh0CB000R\n\n");
    assert_int_equal(urg_scip2_get_scan(&f->urg, 44, 46, 1, &f->scan), COSLAM_OK);
    assert_written(&f->fake, "GD0044004601\n");
    assert_int_equal(f->scan.n_points, 3);
    assert_int_equal(f->scan.range_mm[0], 5432);
    assert_int_equal(f->scan.range_mm[1], 1234);
    assert_int_equal(f->scan.range_mm[2], 0);
    assert_int_equal(f->scan.raw_stamp_ms, 16000000);
    assert_true(f->scan.stamp_us == 16000000ULL * 1000ULL);
    /* polar: code 0 is NaN, or +inf (no return) on request */
    const urg_scip2_params_t p = urg_scip2_params_urg04lx();
    double r[3], a[3];
    size_t n = 0;
    assert_int_equal(urg_scip2_scan_polar(&p, &f->scan, 0, r, a, 3, &n), COSLAM_OK);
    assert_int_equal(n, 3);
    ASSERT_NEAR(r[0], 5.432, 1e-12);
    ASSERT_NEAR(r[1], 1.234, 1e-12);
    assert_true(isnan(r[2]));
    ASSERT_NEAR(a[1], (45.0 - 384.0) * 2.0 * COSLAM_PI / 1024.0, 1e-12);
    assert_int_equal(urg_scip2_scan_polar(&p, &f->scan, URG_SCIP2_POLAR_CODE0_NO_RETURN, r, a, 3, &n), COSLAM_OK);
    assert_true(isinf(r[2]) && r[2] > 0);
    assert_int_equal(urg_scip2_scan_polar(&p, &f->scan, 0, r, a, 2, &n), COSLAM_E_CAPACITY);
    assert_int_equal(n, 0);
}

static void test_gd_laser_off_status(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1, "GD0044072501\n10Q\n\n");
    assert_int_equal(urg_scip2_get_scan(&f->urg, 44, 725, 1, &f->scan), COSLAM_E_URG_STATUS);
    assert_string_equal(urg_scip2_last_status(&f->urg), "10");
    assert_int_equal(f->scan.n_points, 0);
    /* a full GD right after works */
    const size_t n = build_scan(msg, "GD0044072501", "00", 1234, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 2, msg, n);
    assert_int_equal(urg_scip2_get_scan(&f->urg, 44, 725, 1, &f->scan), COSLAM_OK);
    expect_scan04(&f->scan, 1234);
}

static void test_md_scan_decodes(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    const size_t n = build_scan(msg, "MD0044072501000", "99", 5000, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 5000);
    /* the data of 682 points spans 2046 chars = 31 full lines + 62 */
    assert_int_equal(urg_scip2_stats(&f->urg)->scans_ok, 1);
    /* point 340 is step 384, the front */
    const urg_scip2_params_t p = urg_scip2_params_urg04lx();
    ASSERT_NEAR(urg_scip2_step_angle_rad(&p, urg_scip2_point_step(&f->scan, 340)), 0.0, 0.0);
    /* nothing more: an idle timeout, not an error */
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_TIMEOUT);
    const urg_scip2_stats_t *s = urg_scip2_stats(&f->urg);
    assert_int_equal(s->err_timeout + s->err_line + s->err_checksum + s->err_garbage + s->err_echo, 0);
}

static void test_md_every_split_point(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    fill_vals(7);
    const size_t n = build_scan(msg, "MD0044072501000", "99", 42, vals04, N04, CORRUPT_NONE, 0);
    for (size_t cut = 1; cut < n; ++cut) {
        fake_add(&f->fake, 1, msg, n);
        f->fake.cut = f->fake.pos + cut; /* one read ends exactly at `cut` */
        memset(&f->scan, 0xAB, sizeof f->scan);
        const coslam_status_t st = urg_scip2_read_scan(&f->urg, &f->scan, 0);
        ASSERT_TRUE_MSG(st == COSLAM_OK, "split at %zu: %s\n", cut, coslam_status_str(st));
        expect_scan04(&f->scan, 42);
        /* fake_add appends; the stream is consumed to its end each time */
        assert_int_equal(f->fake.pos, f->fake.stream_len);
        f->fake.stream_len = f->fake.pos = 0;
        f->fake.n_segments = 0;
        f->fake.cut = 0;
    }
    /* and one byte per read */
    fake_add(&f->fake, 1, msg, n);
    f->fake.max_chunk = 1;
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 42);
    assert_true(f->fake.n_reads >= n);
    assert_int_equal(urg_scip2_stats(&f->urg)->scans_ok, n);
}

/* A corrupt scan followed by a good one: the first fails with `expect` and
 * bumps `counter`, the second decodes. */
static void corrupt_then_good(fixture_t *f, corrupt_t c, size_t bad_line, coslam_status_t expect,
                              const uint32_t *counter)
{
    start_md04(f, 0);
    size_t n = build_scan(msg, "MD0044072501000", "99", 100, vals04, N04, c, bad_line);
    fake_add(&f->fake, 1, msg, n);
    n = build_scan(msg2, "MD0044072501000", "99", 200, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg2, n);
    const uint32_t before = *counter;
    const coslam_status_t st = urg_scip2_read_scan(&f->urg, &f->scan, 0);
    ASSERT_TRUE_MSG(st == expect, "got %s, expected %s\n", coslam_status_str(st), coslam_status_str(expect));
    assert_int_equal(f->scan.n_points, 0);
    assert_int_equal(*counter, before + 1);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 200);
    assert_int_equal(urg_scip2_stats(&f->urg)->scans_ok, 1);
    /* the stream is fully consumed: nothing left over */
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_TIMEOUT);
}

static void test_corrupt_checksum(void **state)
{
    fixture_t *f = *state;
    corrupt_then_good(f, CORRUPT_SUM, 5, COSLAM_E_URG_CHECKSUM, &f->urg.stats.err_checksum);
    assert_int_equal(urg_scip2_stats(&f->urg)->resyncs, 1);
    /* lines 6..30 (64 chars + sum + LF) and line 31 (62 + sum + LF) */
    assert_int_equal(urg_scip2_stats(&f->urg)->bytes_discarded, 25 * 66 + 64);
}

static void test_corrupt_checksum_last_line(void **state)
{
    fixture_t *f = *state;
    corrupt_then_good(f, CORRUPT_SUM, 31, COSLAM_E_URG_CHECKSUM, &f->urg.stats.err_checksum);
}

static void test_short_line(void **state)
{
    fixture_t *f = *state;
    corrupt_then_good(f, CORRUPT_SHORT_LINE, 3, COSLAM_E_URG_LINE, &f->urg.stats.err_line);
}

static void test_missing_line(void **state)
{
    fixture_t *f = *state;
    /* the message ends early: detected at its empty line, no resync needed */
    corrupt_then_good(f, CORRUPT_DROP_LINE, 31, COSLAM_E_URG_LINE, &f->urg.stats.err_line);
    assert_int_equal(urg_scip2_stats(&f->urg)->resyncs, 0);
}

static void test_extra_line(void **state)
{
    fixture_t *f = *state;
    corrupt_then_good(f, CORRUPT_EXTRA_LINE, 31, COSLAM_E_URG_LINE, &f->urg.stats.err_line);
    assert_int_equal(urg_scip2_stats(&f->urg)->resyncs, 1);
}

static void test_garbage_in_line(void **state)
{
    fixture_t *f = *state;
    corrupt_then_good(f, CORRUPT_GARBAGE, 10, COSLAM_E_URG_GARBAGE, &f->urg.stats.err_garbage);
}

static void test_stamp_line_length(void **state)
{
    fixture_t *f = *state;
    corrupt_then_good(f, CORRUPT_STAMP_LEN, 0, COSLAM_E_URG_LINE, &f->urg.stats.err_line);
}

static void test_garbage_between_messages(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    const uint8_t junk[] = {0x00, 0xFF, 0x93, 'x', 0x7F};
    fake_add(&f->fake, 1, junk, sizeof junk);
    size_t n = build_scan(msg, "MD0044072501000", "99", 100, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n); /* glued to the junk: lost with it */
    n = build_scan(msg2, "MD0044072501000", "99", 200, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg2, n);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_GARBAGE);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 200);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_garbage, 1);
    /* an overlong line (no LF for > URG_SCIP2_LINE_MAX bytes) is garbage too */
    char longline[300];
    memset(longline, 'A', sizeof longline);
    fake_add(&f->fake, 2, longline, sizeof longline);
    fake_add_str(&f->fake, 2, "\n\n");
    n = build_scan(msg, "MD0044072501000", "99", 300, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 2, msg, n);
    f->fake.released = 1;
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_GARBAGE);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 300);
}

static void test_echo_mismatch_in_stream(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    size_t n = build_scan(msg, "MD0044072001000", "99", 100, vals04, N04, CORRUPT_NONE, 0); /* other range */
    fake_add(&f->fake, 1, msg, n);
    n = build_scan(msg2, "MD0044072501000", "99", 200, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg2, n);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_ECHO);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 200);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_echo, 1);
}

/* A scan arriving over several control steps (a 115,200 baud line carries
 * one in about 190 ms): each call takes what has come and returns at once,
 * an idle timeout (not counted), until the whole message is in; then it is
 * decoded, nothing lost. The driver never waits inside a message. */
static void test_scan_arriving_over_calls(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    const size_t n = build_scan(msg, "MD0044072501000", "99", 100, vals04, N04, CORRUPT_NONE, 0);
    const size_t piece = 200U;
    const unsigned n_pieces = (unsigned)((n + piece - 1U) / piece);
    for (unsigned k = 0; k < n_pieces; ++k) {
        /* piece k comes with the k-th call (the MD write was the first) */
        const size_t at = (size_t)k * piece;
        fake_add(&f->fake, 2U + k, msg + at, n - at < piece ? n - at : piece);
    }
    for (unsigned k = 0; k < n_pieces; ++k) {
        f->fake.released = k + 1U;
        const unsigned reads = f->fake.n_reads;
        const coslam_status_t st = urg_scip2_read_scan(&f->urg, &f->scan, 0);
        /* one read that took the new bytes, one that found nothing more */
        assert_true(f->fake.n_reads - reads <= 2U);
        if (k + 1U < n_pieces) {
            ASSERT_TRUE_MSG(st == COSLAM_E_URG_TIMEOUT, "piece %u: %s\n", k, coslam_status_str(st));
        } else {
            assert_int_equal(st, COSLAM_OK);
        }
    }
    expect_scan04(&f->scan, 100);
    const urg_scip2_stats_t *s = urg_scip2_stats(&f->urg);
    assert_int_equal(s->err_timeout + s->err_line + s->err_checksum + s->err_garbage + s->err_echo, 0);
    assert_int_equal(s->resyncs, 0);
    assert_int_equal(f->fake.pos, f->fake.stream_len);
}

/* A scan that breaks off and never ends runs into the next one: the two are
 * refused as one reply, counted once, and the scan after them is read. */
static void test_scan_broken_off(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    size_t n = build_scan(msg, "MD0044072501000", "99", 100, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, 1000); /* the first 1000 bytes, and never the rest */
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_TIMEOUT);
    n = build_scan(msg2, "MD0044072501000", "99", 200, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg2, n);
    n = build_scan(msg, "MD0044072501000", "99", 300, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    const urg_scip2_stats_t *s = urg_scip2_stats(&f->urg);
    const coslam_status_t st = urg_scip2_read_scan(&f->urg, &f->scan, 0);
    assert_true(st == COSLAM_E_URG_LINE || st == COSLAM_E_URG_CHECKSUM);
    assert_int_equal(f->scan.n_points, 0);
    assert_int_equal(s->err_timeout + s->err_line + s->err_checksum + s->err_garbage + s->err_echo, 1);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 300);
    assert_int_equal(s->resyncs, 1);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_TIMEOUT);
}

/* Bytes that never make a message end (not SCIP) fill the buffer: refused,
 * counted once, discarded; a scan after them is read. */
static void test_no_message_end_fills_the_buffer(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    static char junk[URG_SCIP2_RX_CAP + 10];
    memset(junk, 'A', sizeof junk);
    fake_add(&f->fake, 1, junk, sizeof junk);
    const char end[] = "\n\n";
    fake_add(&f->fake, 1, end, 2U);
    const size_t n = build_scan(msg, "MD0044072501000", "99", 400, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_GARBAGE);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_garbage, 1);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 400);
    assert_int_equal(urg_scip2_stats(&f->urg)->bytes_discarded, sizeof junk + 1U);
}

static void test_dmin_error_codes(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    for (uint32_t i = 0; i < 20; ++i) vals04[100 + i] = i; /* every error code */
    vals04[200] = 5601;                                    /* beyond DMAX */
    const size_t n = build_scan(msg, "MD0044072501000", "99", 1, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    static double r[N04], a[N04];
    size_t k = 0;
    assert_int_equal(urg_scip2_scan_polar(urg_scip2_params(&f->urg), &f->scan, 0, r, a, N04, &k), COSLAM_OK);
    assert_int_equal(k, N04);
    for (size_t i = 100; i < 120; ++i) {
        assert_true(isnan(r[i]));
        ASSERT_NEAR(a[i], ((double)(44 + i) - 384.0) * 2.0 * COSLAM_PI / 1024.0, 1e-12);
    }
    assert_true(isnan(r[200]));
    assert_true(isnan(r[0]) && isnan(r[1]));
    ASSERT_NEAR(r[2], 0.020, 1e-15);
    ASSERT_NEAR(r[3], 5.600, 1e-15);
    assert_true(isnan(r[4]));
    ASSERT_NEAR(r[5], vals04[5] / 1000.0, 1e-15);
}

static void test_timestamp_wrap(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    const uint32_t raw[] = {16777000, 16777100, 84, 184, 100 /* backwards */, 200};
    const uint64_t want_ms[] = {16777000, 16777100, 16777216ULL + 84, 16777216ULL + 184, 16777216ULL + 184,
                                16777216ULL + 284};
    for (size_t i = 0; i < 6; ++i) {
        const size_t n = build_scan(msg, "MD0044072501000", "99", raw[i], vals04, N04, CORRUPT_NONE, 0);
        fake_add(&f->fake, 1, msg, n);
        assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
        assert_int_equal(f->scan.raw_stamp_ms, raw[i]);
        ASSERT_TRUE_MSG(f->scan.stamp_us == want_ms[i] * 1000ULL, "scan %zu: stamp %llu us, want %llu\n", i,
                        (unsigned long long)f->scan.stamp_us, (unsigned long long)(want_ms[i] * 1000ULL));
    }
    assert_int_equal(urg_scip2_stats(&f->urg)->stamp_wraps, 1);
    assert_int_equal(urg_scip2_stats(&f->urg)->stamp_backwards, 1);
}

/* A finite MD of 2 scans of steps 44..53 in clusters of 3 (points 44-46,
 * 47-49, 50-52, 53) with ranges v, started; its last scan damaged by
 * `last`. */
static void finite_md_two_scans(fixture_t *f, const uint32_t v[4], corrupt_t last)
{
    fake_add_str(&f->fake, 1, "MD0044005303002\n00P\n\n");
    assert_int_equal(urg_scip2_start_md(&f->urg, 44, 53, 3, 0, 2), COSLAM_OK);
    assert_written(&f->fake, "MD0044005303002\n");
    size_t n = build_scan(msg, "MD0044005303001", "99", 10, v, 4, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    n = build_scan(msg2, "MD0044005303000", "99", 110, v, 4, last, 0);
    fake_add(&f->fake, 1, msg2, n);
}

static void test_md_finite_and_cluster(void **state)
{
    fixture_t *f = *state;
    const uint32_t v[4] = {100, 200, 300, 400};
    finite_md_two_scans(f, v, CORRUPT_NONE);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    assert_int_equal(f->scan.n_points, 4);
    assert_int_equal(f->scan.remaining, 1);
    assert_int_equal(f->scan.cluster, 3);
    ASSERT_NEAR(urg_scip2_point_step(&f->scan, 0), 45.0, 0.0);
    ASSERT_NEAR(urg_scip2_point_step(&f->scan, 2), 51.0, 0.0);
    ASSERT_NEAR(urg_scip2_point_step(&f->scan, 3), 53.0, 0.0);
    assert_true(urg_scip2_is_streaming(&f->urg));
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    assert_int_equal(f->scan.remaining, 0);
    assert_memory_equal(f->scan.range_mm, v, sizeof v);
    assert_false(urg_scip2_is_streaming(&f->urg));
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_EMPTY);
}

static void test_qt_skips_scans_in_flight(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    /* two scans were already on the way when QT was sent */
    size_t n = build_scan(msg, "MD0044072501000", "99", 1, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 2, msg, n);
    fake_add(&f->fake, 2, msg, n);
    fake_add_str(&f->fake, 2, "QT\n00P\n\n");
    assert_int_equal(urg_scip2_laser_off(&f->urg), COSLAM_OK);
    assert_false(urg_scip2_is_streaming(&f->urg));
    assert_int_equal(urg_scip2_stats(&f->urg)->messages_skipped, 2);
    assert_int_equal(f->fake.pos, f->fake.stream_len);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_EMPTY);
    assert_int_equal(urg_scip2_get_scan(&f->urg, 44, 725, 1, &f->scan), COSLAM_E_URG_TIMEOUT); /* no reply scripted */
}

/* A driver restarted without QT while the sensor still streams an
 * unlimited MD with the same command: a scan (echo = the command, status
 * 99) may come before the acknowledgement. It is skipped, not read as the
 * reply. */
static void test_md_restart_skips_running_scans(void **state)
{
    fixture_t *f = *state;
    const size_t n = build_scan(msg, "MD0044072501000", "99", 7, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    fake_add(&f->fake, 1, msg, n);
    fake_add_str(&f->fake, 1, "MD0044072501000\n00P\n\n");
    const size_t n2 = build_scan(msg2, "MD0044072501000", "99", 8, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg2, n2);
    assert_int_equal(urg_scip2_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_OK);
    assert_true(urg_scip2_is_streaming(&f->urg));
    assert_int_equal(urg_scip2_stats(&f->urg)->messages_skipped, 2);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_line, 0);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 8);
}

/* A finite MD whose last scan is corrupt has still ended: the sensor has
 * stopped, so the driver is not left "streaming" with nothing to come. */
static void test_md_finite_last_scan_corrupt(void **state)
{
    fixture_t *f = *state;
    const uint32_t v[4] = {100, 200, 300, 400};
    finite_md_two_scans(f, v, CORRUPT_SUM);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_CHECKSUM);
    assert_false(urg_scip2_is_streaming(&f->urg));
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_EMPTY);
    /* a GD is allowed again */
    fake_add_str(&f->fake, 2, "GD0044005303\n10Q\n\n");
    assert_int_equal(urg_scip2_get_scan(&f->urg, 44, 53, 3, &f->scan), COSLAM_E_URG_STATUS);
}

/* A reply whose status line was lost (echo, then the empty line) ends
 * there: reported, and the next reply is read whole, not thrown away by a
 * resynchronisation that has nothing left to skip. The same for a scan that
 * lost everything after its status. */
static void test_lost_status_line_keeps_next_message(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1, "BM\n\n");
    fake_add_str(&f->fake, 2, "BM\n00P\n\n");
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_E_URG_LINE);
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_OK);
    fake_add_str(&f->fake, 3, "MD0044072501000\n00P\n\n");
    assert_int_equal(urg_scip2_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_OK);
    fake_add_str(&f->fake, 3, "MD0044072501000\n99b\n\n");
    const size_t n = build_scan(msg, "MD0044072501000", "99", 300, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 3, msg, n);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_LINE);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 300);
    assert_int_equal(urg_scip2_stats(&f->urg)->resyncs, 0);
}

/* A peer that sends lines but never an empty one (another device on the
 * port): a command gives up after URG_SCIP2_DISCARD_MAX bytes with GARBAGE,
 * counted, instead of reading for ever; the next call goes on resyncing. */
static void test_endless_lines_bounded(void **state)
{
    fixture_t *f = *state;
    static char lines[24000];
    size_t n = 0;
    while (n + 40U < sizeof lines) {
        n += (size_t)snprintf(lines + n, sizeof lines - n, "$GPGGA,123519,4807.038,N,01131.000,E\n");
    }
    fake_add(&f->fake, 1, lines, n);
    assert_int_equal(urg_scip2_enter_scip2(&f->urg), COSLAM_E_URG_GARBAGE);
    const urg_scip2_stats_t *st = urg_scip2_stats(&f->urg);
    assert_int_equal(st->err_garbage, 1);
    assert_true(f->fake.pos <= URG_SCIP2_DISCARD_MAX + URG_SCIP2_RX_CAP); /* the budget and one buffer */
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_E_URG_GARBAGE);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_garbage, 2);
}

/* A reply whose final empty line was lost: the command reports a timeout,
 * and the next command's reply, whole, is read (not taken for the rest of
 * the broken one and thrown away). */
static void test_lost_reply_end_keeps_next_reply(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1, "BM\n00P\n"); /* the final LF lost */
    fake_add_str(&f->fake, 2, "QT\n00P\n\n");
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_E_URG_TIMEOUT);
    assert_int_equal(urg_scip2_laser_off(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_timeout, 1);
    assert_int_equal(urg_scip2_stats(&f->urg)->resyncs, 1);
}

/* A stale scan of a running MD that breaks off while start_md skips it is
 * a dropped reply: counted in err_timeout, as in every other command. */
static void test_md_restart_broken_stale_scan_counted(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1, "MD0044072501000\n99b\n0000");
    assert_int_equal(urg_scip2_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_E_URG_TIMEOUT);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_timeout, 1);
}

static void test_md_refused_and_bad_args(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1, "MD0044072501000\n04T\n\n"); /* end step out of range */
    assert_int_equal(urg_scip2_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_E_URG_STATUS);
    assert_string_equal(urg_scip2_last_status(&f->urg), "04");
    assert_false(urg_scip2_is_streaming(&f->urg));
    assert_int_equal(urg_scip2_start_md(&f->urg, 100, 99, 1, 0, 0), COSLAM_E_ARG);
    assert_int_equal(urg_scip2_start_md(&f->urg, 0, 100, 100, 0, 0), COSLAM_E_ARG);
    assert_int_equal(urg_scip2_start_md(&f->urg, 0, 100, 1, 10, 0), COSLAM_E_ARG);
    assert_int_equal(urg_scip2_start_md(&f->urg, 0, 100, 1, 0, 100), COSLAM_E_ARG);
    /* more points than COSLAM_MAX_SCAN_POINTS: refused and counted */
    assert_int_equal(urg_scip2_start_md(&f->urg, 0, COSLAM_MAX_SCAN_POINTS, 1, 0, 0), COSLAM_E_CAPACITY);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_capacity, 1);
    /* the same steps in clusters of 2 fit */
    char ack[64];
    sprintf(ack, "MD0000%04u02000\n00P\n\n", COSLAM_MAX_SCAN_POINTS);
    fake_add_str(&f->fake, 2, ack);
    assert_int_equal(urg_scip2_start_md(&f->urg, 0, COSLAM_MAX_SCAN_POINTS, 2, 0, 0), COSLAM_OK);
    assert_int_equal(urg_scip2_get_scan(&f->urg, 0, 10, 1, &f->scan), COSLAM_E_ARG); /* GD while MD runs */
    assert_int_equal(f->fake.n_writes, 2); /* refused calls sent nothing */
}

static void test_stream_status_error(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    /* hardware trouble "50" in place of "99": reported, and the next scan works */
    fake_add_str(&f->fake, 1, "MD0044072501000\n50U\n\n");
    const size_t n = build_scan(msg, "MD0044072501000", "99", 7, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_STATUS);
    assert_string_equal(urg_scip2_last_status(&f->urg), "50");
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 7);
}

/* Mutation fuzz: a small scan message with 1-4 random byte flips, deletions
 * or insertions, then two good messages. Whatever the damage, every call
 * returns, every failure is counted, and the last good message decodes
 * exactly (the driver resynchronises). One driver instance for all rounds. */
/* 1-4 random mutations of buf[0..n): a byte changed, removed or inserted
 * (buf has room for 4 more); the new length. */
static size_t mutate(char *buf, size_t n, rng_t *rng)
{
    const int n_mut = 1 + (int)rng_below(rng, 4);
    for (int m = 0; m < n_mut && n > 2; ++m) {
        const size_t at = rng_below(rng, (uint32_t)n);
        switch (rng_below(rng, 3)) {
        case 0: buf[at] = (char)rng_below(rng, 256); break;
        case 1: memmove(buf + at, buf + at + 1, n - at - 1); --n; break;
        default: memmove(buf + at + 1, buf + at, n - at); buf[at] = (char)rng_below(rng, 256); ++n; break;
        }
    }
    return n;
}

static void test_fuzz_mutated_messages(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1, "MD0044007301000\n00P\n\n");
    assert_int_equal(urg_scip2_start_md(&f->urg, 44, 73, 1, 0, 0), COSLAM_OK);
    rng_t rng;
    rng_seed(&rng, 0xF022);
    uint32_t v[30];
    const int rounds = COSLAM_TEST_FULL ? 50000 : 3000;
    for (int round = 0; round < rounds; ++round) {
        for (int i = 0; i < 30; ++i) v[i] = 20 + rng_below(&rng, 5000);
        size_t n = build_scan(msg, "MD0044007301000", "99", 1000 + (uint32_t)round, v, 30, CORRUPT_NONE, 0);
        n = mutate(msg, n, &rng);
        f->fake.stream_len = f->fake.pos = 0;
        f->fake.n_segments = 0;
        fake_add(&f->fake, 0, msg, n);
        for (int k = 0; k < 2; ++k) {
            n = build_scan(msg2, "MD0044007301000", "99", 5000 + (uint32_t)k, v, 30, CORRUPT_NONE, 0);
            fake_add(&f->fake, 0, msg2, n);
        }
        const urg_scip2_stats_t before = *urg_scip2_stats(&f->urg);
        uint32_t last_ok_stamp = 0;
        int calls = 0, failures = 0;
        coslam_status_t st;
        while ((st = urg_scip2_read_scan(&f->urg, &f->scan, 0)) != COSLAM_E_URG_TIMEOUT) {
            ASSERT_TRUE_MSG(++calls <= 12, "round %d: no end\n", round);
            if (st == COSLAM_OK) {
                last_ok_stamp = f->scan.raw_stamp_ms;
            } else {
                ++failures;
            }
        }
        ASSERT_TRUE_MSG(last_ok_stamp == 5001, "round %d: last good stamp %u\n", round, last_ok_stamp);
        assert_memory_equal(f->scan.range_mm, v, sizeof v);
        const urg_scip2_stats_t *a = urg_scip2_stats(&f->urg);
        const uint32_t errs = (a->err_checksum - before.err_checksum) + (a->err_line - before.err_line) +
                              (a->err_garbage - before.err_garbage) + (a->err_echo - before.err_echo) +
                              (a->err_status - before.err_status);
        ASSERT_TRUE_MSG(errs == (uint32_t)failures, "round %d: %d failures, %u counted (sum %u line %u garbage %u echo %u status %u)\n", round, failures, errs, a->err_checksum - before.err_checksum, a->err_line - before.err_line, a->err_garbage - before.err_garbage, a->err_echo - before.err_echo, a->err_status - before.err_status);
        assert_int_equal(f->fake.pos, f->fake.stream_len);
    }
    const urg_scip2_stats_t *a = urg_scip2_stats(&f->urg);
    print_message("fuzz: %d rounds, ok %u, checksum %u, line %u, garbage %u, echo %u, status %u, resyncs %u\n", rounds,
                  a->scans_ok, a->err_checksum, a->err_line, a->err_garbage, a->err_echo, a->err_status, a->resyncs);
    /* the mutations did reach every class of check */
    assert_true(a->err_checksum > 0 && a->err_line > 0 && a->err_garbage > 0 && a->err_echo > 0);
    /* B always decodes (checked per round); A is lost only when the damage
     * swallowed the empty line that ends the mutated message */
    assert_true(a->scans_ok >= (uint32_t)rounds + (uint32_t)rounds / 2U);
}

/* The poll of a begun command until it ends, at most 4 polls (the fake
 * delivers what it holds at once); still waiting: abandoned. */
static coslam_status_t poll_to_end(fixture_t *f)
{
    for (int i = 0; i < 4; ++i) {
        const coslam_status_t st = urg_scip2_poll(&f->urg);
        if (st != COSLAM_E_URG_TIMEOUT) {
            return st;
        }
    }
    urg_scip2_abandon(&f->urg);
    return COSLAM_E_URG_TIMEOUT;
}

static uint32_t err_sum(const urg_scip2_stats_t *a)
{
    return a->err_timeout + a->err_io + a->err_checksum + a->err_line + a->err_garbage + a->err_echo +
           a->err_status + a->err_field + a->err_capacity;
}

/* The commands without waiting under the same mutations: a mutated PP
 * reply (after a stale scan), then two clean ones for two more begun PPs.
 * Every command that fails bumps exactly one error counter, none that
 * succeeds does, and the last always succeeds: the driver recovers. */
static void test_fuzz_poll_mutated_replies(void **state)
{
    fixture_t *f = *state;
    rng_t rng;
    rng_seed(&rng, 0xB00C);
    uint32_t v[30];
    const int rounds = COSLAM_TEST_FULL ? 20000 : 2000;
    int failed = 0;
    for (int round = 0; round < rounds; ++round) {
        for (int i = 0; i < 30; ++i) v[i] = 20 + rng_below(&rng, 5000);
        size_t n = build_scan(msg, "MD0044007301000", "99", 100 + (uint32_t)round, v, 30, CORRUPT_NONE, 0);
        memcpy(msg + n, PP04_REPLY, strlen(PP04_REPLY));
        n += strlen(PP04_REPLY);
        n = mutate(msg, n, &rng);
        f->fake.stream_len = f->fake.pos = 0;
        f->fake.n_segments = 0;
        f->fake.n_writes = 0;
        f->fake.n_written = 0;
        fake_add(&f->fake, 1, msg, n);
        fake_add_str(&f->fake, 2, PP04_REPLY);
        fake_add_str(&f->fake, 3, PP04_REPLY);
        coslam_status_t st = COSLAM_OK;
        for (int c = 0; c < 3; ++c) {
            const uint32_t before = err_sum(urg_scip2_stats(&f->urg));
            assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
            st = poll_to_end(f);
            const uint32_t counted = err_sum(urg_scip2_stats(&f->urg)) - before;
            ASSERT_TRUE_MSG(counted == (st == COSLAM_OK ? 0U : 1U), "round %d command %d: %s, %u counted\n", round,
                            c, coslam_status_str(st), counted);
            failed += st != COSLAM_OK;
            assert_false(urg_scip2_pending(&f->urg));
        }
        ASSERT_TRUE_MSG(st == COSLAM_OK, "round %d: no recovery (%s)\n", round, coslam_status_str(st));
        assert_int_equal(urg_scip2_params(&f->urg)->ares, 1024);
    }
    const urg_scip2_stats_t *a = urg_scip2_stats(&f->urg);
    print_message("poll fuzz: %d rounds, %d commands failed; timeout %u, checksum %u, line %u, garbage %u, echo %u, "
                  "field %u, skipped %u\n",
                  rounds, failed, a->err_timeout, a->err_checksum, a->err_line, a->err_garbage, a->err_echo,
                  a->err_field, a->messages_skipped);
    assert_true(failed > 0 && a->err_checksum > 0 && a->err_line + a->err_field > 0);
}

/* ---------------------------------------------------------------------------
 * The wait for a whole message with small reads
 * ------------------------------------------------------------------------ */

/* The wait for a whole message resumes where the last read left off: a
 * 682-point MD scan (2137 bytes) fed one byte per read costs each byte about
 * one look (urg_scip2_rx_search_bytes), not one per read after it. Before,
 * every read rescanned the buffer from the message's start: about n^2/2 =
 * 2.3 million looks for this scan. The same for a broken scan resynchronised
 * before a good one, and for the poll of a begun MD, which also checks the
 * first line of what comes (a stale scan with another echo skipped as it
 * streams, one with this very echo skipped once whole, then the
 * acknowledgement). */
static void test_wait_for_message_linear_in_small_reads(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    f->fake.max_chunk = 1;
    size_t n = build_scan(msg, "MD0044072501000", "99", 77, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    uint32_t before = urg_scip2_rx_search_bytes(&f->urg);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 77);
    uint32_t looked = urg_scip2_rx_search_bytes(&f->urg) - before;
    print_message("one byte per read: %u bytes looked at for a %zu-byte scan\n", looked, n);
    ASSERT_TRUE_MSG(looked <= 2U * n, "%u bytes looked at for a %zu-byte scan\n", looked, n);

    /* a bad sum in line 5, then a good scan: the rest of the first is
     * discarded, not searched again */
    size_t total = build_scan(msg, "MD0044072501000", "99", 78, vals04, N04, CORRUPT_SUM, 5);
    fake_add(&f->fake, 1, msg, total);
    n = build_scan(msg2, "MD0044072501000", "99", 79, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg2, n);
    total += n;
    before = urg_scip2_rx_search_bytes(&f->urg);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_CHECKSUM);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 79);
    looked = urg_scip2_rx_search_bytes(&f->urg) - before;
    ASSERT_TRUE_MSG(looked <= 2U * total, "%u bytes looked at for %zu bytes\n", looked, total);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_URG_TIMEOUT);

    /* the poll of a begun MD */
    assert_int_equal(urg_scip2_begin_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_OK);
    total = build_scan(msg, "MD0044072001000", "99", 80, vals04, N04 - 5U, CORRUPT_NONE, 0);
    fake_add(&f->fake, 0, msg, total);
    n = build_scan(msg2, "MD0044072501000", "99", 81, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 0, msg2, n);
    total += n;
    fake_add_str(&f->fake, 0, "MD0044072501000\n00P\n\n");
    total += 21U;
    const urg_scip2_stats_t s0 = *urg_scip2_stats(&f->urg);
    before = urg_scip2_rx_search_bytes(&f->urg);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_OK);
    looked = urg_scip2_rx_search_bytes(&f->urg) - before;
    print_message("one byte per read, polled: %u bytes looked at for %zu bytes\n", looked, total);
    ASSERT_TRUE_MSG(looked <= 2U * total, "%u bytes looked at for %zu bytes\n", looked, total);
    assert_int_equal(urg_scip2_stats(&f->urg)->messages_skipped, s0.messages_skipped + 2U);
    assert_true(urg_scip2_is_streaming(&f->urg));
    assert_int_equal(f->fake.pos, f->fake.stream_len);
}

/* What one run of a stream through a fresh driver gave: the MD start's
 * result, then every urg_scip2_read_scan call until the stream ran dry. */
#define PROP_CALLS_MAX 64
typedef struct {
    coslam_status_t st;
    uint32_t raw_stamp_ms;
    uint16_t remaining;
    uint16_t n_points;
    uint32_t ranges_hash; /* FNV-1a of range_mm[0..n_points) */
} prop_call_t;

typedef struct {
    coslam_status_t start;
    prop_call_t call[PROP_CALLS_MAX];
    size_t n_calls;
    urg_scip2_stats_t stats;
    size_t consumed;
    uint32_t searched;
} prop_run_t;

static uint32_t ranges_hash(const urg_scip2_scan_t *s)
{
    uint32_t h = 2166136261U;
    for (size_t i = 0; i < s->n_points; ++i) {
        h = (h ^ s->range_mm[i]) * 16777619U;
    }
    return h;
}

/* Feed `n` bytes of `s` (readable after the MD command) to a fresh driver:
 * the MD started waiting or begun and polled, then scans read until none
 * is left. rand_chunk 0: every read takes all that is there (the stream
 * "whole"); else 1..rand_chunk bytes per read, drawn from `seed`. */
static void prop_feed(fixture_t *f, const char *s, size_t n, int polled, size_t rand_chunk, uint32_t seed,
                      prop_run_t *out)
{
    memset(out, 0, sizeof *out);
    fake_init(&f->fake);
    assert_int_equal(urg_scip2_init(&f->urg, &f->fake.dev, NULL), COSLAM_OK);
    fake_add(&f->fake, 1, s, n);
    f->fake.rand_chunk = rand_chunk;
    f->fake.chunk_state = seed;
    if (polled) {
        assert_int_equal(urg_scip2_begin_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_OK);
        out->start = poll_to_end(f);
    } else {
        out->start = urg_scip2_start_md(&f->urg, 44, 725, 1, 0, 0);
    }
    for (;;) {
        assert_true(out->n_calls < PROP_CALLS_MAX);
        prop_call_t *c = &out->call[out->n_calls++];
        c->st = urg_scip2_read_scan(&f->urg, &f->scan, 0);
        if (c->st == COSLAM_E_URG_TIMEOUT || c->st == COSLAM_E_EMPTY) {
            break;
        }
        c->n_points = f->scan.n_points;
        if (c->st == COSLAM_OK) {
            c->raw_stamp_ms = f->scan.raw_stamp_ms;
            c->remaining = f->scan.remaining;
            c->ranges_hash = ranges_hash(&f->scan);
        }
    }
    out->stats = *urg_scip2_stats(&f->urg);
    out->consumed = f->fake.pos;
    out->searched = urg_scip2_rx_search_bytes(&f->urg);
}

static char prop_stream[FAKE_STREAM_CAP];

/* One scan message of 1..682 random readings (of 44..725: its echo), with
 * the given damage, at the end of prop_stream. */
static size_t prop_scan(size_t k, rng_t *rng, const char *echo, corrupt_t c, uint32_t stamp)
{
    const size_t n_pts = rng_below(rng, 2) ? N04 : 1U + rng_below(rng, N04);
    uint32_t v[N04];
    for (size_t i = 0; i < n_pts; ++i) v[i] = rng_below(rng, 6000U);
    return k + build_scan(prop_stream + k, echo, "99", stamp, v, n_pts, c, rng_below(rng, 33U));
}

/* A random stream: up to two stale replies, MD's acknowledgement, then 4-11
 * items: good scans, scans with each kind of damage, mutated scans, scans
 * broken off, scans of another MD, stray empty lines, random bytes, and now
 * and then bytes without a message end that fill the buffer. */
static size_t prop_stream_make(rng_t *rng)
{
    size_t k = 0;
    uint32_t stamp = rng_below(rng, 1000U);
    for (uint32_t i = rng_below(rng, 3U); i > 0; --i) {
        switch (rng_below(rng, 3U)) {
        case 0: k = prop_scan(k, rng, "MD0044072001000", CORRUPT_NONE, stamp += 100U); break;
        case 1: k = prop_scan(k, rng, "MD0044072501000", CORRUPT_NONE, stamp += 100U); break;
        default: prop_stream[k++] = '\n'; break;
        }
    }
    memcpy(prop_stream + k, "MD0044072501000\n00P\n\n", 21U);
    k += 21U;
    for (uint32_t i = 4U + rng_below(rng, 8U); i > 0 && k < 40000U; --i) {
        stamp += 100U;
        switch (rng_below(rng, 10U)) {
        case 0:
        case 1:
        case 2: k = prop_scan(k, rng, "MD0044072501000", CORRUPT_NONE, stamp); break;
        case 3: k = prop_scan(k, rng, "MD0044072501000", (corrupt_t)(1U + rng_below(rng, 6U)), stamp); break;
        case 4: {
            const size_t at = k;
            k = prop_scan(k, rng, "MD0044072501000", CORRUPT_NONE, stamp);
            k = at + mutate(prop_stream + at, k - at, rng);
            break;
        }
        case 5: {
            const size_t at = k;
            k = prop_scan(k, rng, "MD0044072501000", CORRUPT_NONE, stamp);
            k = at + 1U + rng_below(rng, (uint32_t)(k - at - 1U)); /* broken off */
            break;
        }
        case 6: k = prop_scan(k, rng, "MD0044072001000", CORRUPT_NONE, stamp); break;
        case 7: prop_stream[k++] = '\n'; break;
        case 8:
            for (uint32_t j = 1U + rng_below(rng, 40U); j > 0; --j) {
                prop_stream[k++] = (char)rng_below(rng, 256U);
            }
            break;
        default:
            if (rng_below(rng, 4U) == 0U) {
                memset(prop_stream + k, 'A', URG_SCIP2_RX_CAP + 10U);
                k += URG_SCIP2_RX_CAP + 10U;
            }
            break;
        }
    }
    return k;
}

/* The parse does not depend on how the bytes are cut into reads: the same
 * random stream fed whole and in random reads of 1..N bytes (N from 1 to
 * 700, seeded) gives the same results call for call (status, stamp,
 * remaining scans, readings), the same counters and the same bytes taken
 * from the port; the MD started waiting or begun and polled. And in both,
 * the wait for whole messages looks at each byte about once. */
static void test_chunked_reads_parse_as_whole(void **state)
{
    fixture_t *f = *state;
    static const size_t chunk_max[] = {1U, 2U, 3U, 7U, 64U, 700U};
    rng_t rng;
    rng_seed(&rng, 0xC4A2);
    static prop_run_t whole, cut;
    urg_scip2_stats_t sum;
    memset(&sum, 0, sizeof sum);
    uint32_t calls = 0U;
    const int rounds = COSLAM_TEST_FULL ? 1500 : 150;
    for (int round = 0; round < rounds; ++round) {
        const size_t n = prop_stream_make(&rng);
        const int polled = (int)rng_below(&rng, 2U);
        const size_t cmax = chunk_max[rng_below(&rng, sizeof chunk_max / sizeof chunk_max[0])];
        prop_feed(f, prop_stream, n, polled, 0U, 0U, &whole);
        prop_feed(f, prop_stream, n, polled, cmax, (uint32_t)round * 2654435761U, &cut);
        ASSERT_TRUE_MSG(cut.start == whole.start, "round %d (reads of 1..%zu%s): start %s, whole %s\n", round, cmax,
                        polled ? ", polled" : "", coslam_status_str(cut.start), coslam_status_str(whole.start));
        ASSERT_TRUE_MSG(cut.n_calls == whole.n_calls, "round %d (reads of 1..%zu): %zu calls, whole %zu\n", round,
                        cmax, cut.n_calls, whole.n_calls);
        for (size_t i = 0; i < whole.n_calls; ++i) {
            ASSERT_TRUE_MSG(memcmp(&cut.call[i], &whole.call[i], sizeof whole.call[i]) == 0,
                            "round %d (reads of 1..%zu) call %zu: %s, whole %s\n", round, cmax, i,
                            coslam_status_str(cut.call[i].st), coslam_status_str(whole.call[i].st));
        }
        ASSERT_TRUE_MSG(memcmp(&cut.stats, &whole.stats, sizeof whole.stats) == 0,
                        "round %d (reads of 1..%zu): counters differ\n", round, cmax);
        assert_int_equal(cut.consumed, whole.consumed);
        ASSERT_TRUE_MSG(whole.searched <= 2U * n && cut.searched <= 2U * n,
                        "round %d: %u and %u bytes looked at for %zu\n", round, whole.searched, cut.searched, n);
        calls += (uint32_t)whole.n_calls;
        sum.scans_ok += whole.stats.scans_ok;
        sum.err_checksum += whole.stats.err_checksum;
        sum.err_line += whole.stats.err_line;
        sum.err_garbage += whole.stats.err_garbage;
        sum.err_echo += whole.stats.err_echo;
        sum.resyncs += whole.stats.resyncs;
        sum.messages_skipped += whole.stats.messages_skipped;
    }
    print_message("chunked = whole: %d rounds, %u calls; ok %u, checksum %u, line %u, garbage %u, echo %u, "
                  "resyncs %u, skipped %u\n",
                  rounds, calls, sum.scans_ok, sum.err_checksum, sum.err_line, sum.err_garbage, sum.err_echo,
                  sum.resyncs, sum.messages_skipped);
    /* the streams reached every path they are meant to */
    assert_true(sum.scans_ok > 0U && sum.err_checksum > 0U && sum.err_line > 0U && sum.err_garbage > 0U &&
                sum.err_echo > 0U && sum.resyncs > 0U && sum.messages_skipped > 0U);
}

static void test_init_args(void **state)
{
    (void)state;
    urg_scip2_t u;
    fake_serial_t fk;
    fake_init(&fk);
    urg_scip2_config_t c;
    urg_scip2_config_default(&c);
    assert_int_equal(urg_scip2_init(NULL, &fk.dev, &c), COSLAM_E_ARG);
    assert_int_equal(urg_scip2_init(&u, NULL, &c), COSLAM_E_ARG);
    c.byte_timeout_us = 0;
    assert_int_equal(urg_scip2_init(&u, &fk.dev, &c), COSLAM_E_ARG);
    assert_int_equal(urg_scip2_read_scan(NULL, NULL, 0), COSLAM_E_ARG);
    assert_int_equal(urg_scip2_laser_on(NULL), COSLAM_E_ARG);
}

/* ---------------------------------------------------------------------------
 * The set-up without waiting (urg_scip2_begin_*, urg_scip2_poll)
 * ------------------------------------------------------------------------ */

/* The robot's connect: SCIP2.0, PP, MD, each reply arriving in two halves,
 * the second held back until the test releases it. Every poll before that
 * returns "not yet" without counting anything and without reading past what
 * has come; the frames written are byte-exact; the result is the waiting
 * calls' (parameters read, streaming, the first scan decodes). */
static void test_connect_without_waiting(void **state)
{
    fixture_t *f = *state;
    const char *replies[3] = {"SCIP2.0\n0\n\n", PP04_REPLY, "MD0044072501000\n00P\n\n"};
    const urg_scip2_stats_t before = *urg_scip2_stats(&f->urg);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_EMPTY); /* nothing begun */
    for (unsigned k = 0; k < 3; ++k) {
        const size_t half = strlen(replies[k]) / 2U;
        fake_add(&f->fake, k + 1U, replies[k], half); /* readable once its command is written */
        f->fake.n_written = 0;
        coslam_status_t st = k == 0U ? urg_scip2_begin_enter_scip2(&f->urg)
                             : k == 1U ? urg_scip2_begin_read_params(&f->urg)
                                       : urg_scip2_begin_start_md(&f->urg, 44, 725, 1, 0, 0);
        assert_int_equal(st, COSLAM_OK);
        assert_written(&f->fake, k == 0U ? "SCIP2.0\n" : k == 1U ? "PP\n" : "MD0044072501000\n");
        for (int i = 0; i < 3; ++i) {
            assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_URG_TIMEOUT);
            assert_true(urg_scip2_pending(&f->urg));
        }
        assert_memory_equal(urg_scip2_stats(&f->urg), &before, sizeof before); /* nothing counted */
        fake_add_str(&f->fake, 0U, replies[k] + half); /* the rest */
        assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_OK);
        assert_false(urg_scip2_pending(&f->urg));
        assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_EMPTY);
    }
    assert_int_equal(f->fake.n_flushes, 1); /* SCIP2.0 drops unread input, as the waiting call */
    assert_int_equal(urg_scip2_params(&f->urg)->afrt, 384);
    assert_int_equal(urg_scip2_params(&f->urg)->scan_rpm, 600);
    assert_true(urg_scip2_is_streaming(&f->urg));
    assert_memory_equal(urg_scip2_stats(&f->urg), &before, sizeof before);
    const size_t n = build_scan(msg, "MD0044072501000", "99", 1234, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 0, msg, n);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_OK);
    expect_scan04(&f->scan, 1234);
}

/* Replies to something else are skipped as a waiting command skips them:
 * a scan of an earlier MD before PP's reply, and, while MD starts, a scan
 * of an MD of this very command still running (same echo, status "99")
 * before its acknowledgement. Counted as skipped messages only. */
static void test_poll_skips_stale_replies(void **state)
{
    fixture_t *f = *state;
    size_t n = build_scan(msg, "MD0044072501000", "99", 10, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 1, msg, n);
    fake_add_str(&f->fake, 1, PP04_REPLY);
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_stats(&f->urg)->messages_skipped, 1);
    assert_int_equal(urg_scip2_params(&f->urg)->ares, 1024);

    n = build_scan(msg, "MD0044072501000", "99", 20, vals04, N04, CORRUPT_NONE, 0);
    fake_add(&f->fake, 2, msg, n);
    fake_add_str(&f->fake, 2, "MD0044072501000\n00P\n\n");
    assert_int_equal(urg_scip2_begin_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_stats(&f->urg)->messages_skipped, 2);
    assert_true(urg_scip2_is_streaming(&f->urg));
    assert_int_equal(urg_scip2_stats(&f->urg)->err_echo, 0);
}

/* No reply, or only stale ones: the caller gives up by its clock
 * (abandon: one timeout counted, as a waiting command's); the reply that
 * comes late is skipped by the next command, which gets its own. More
 * stale replies than max_skipped_messages end the command (counted). A
 * refusal and a broken reply end it with the waiting call's code. */
static void test_poll_gives_up_and_fails_as_the_waiting_call(void **state)
{
    fixture_t *f = *state;
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    for (int i = 0; i < 5; ++i) {
        assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_URG_TIMEOUT);
    }
    assert_int_equal(urg_scip2_stats(&f->urg)->err_timeout, 0);
    urg_scip2_abandon(&f->urg);
    assert_false(urg_scip2_pending(&f->urg));
    assert_int_equal(urg_scip2_stats(&f->urg)->err_timeout, 1);
    urg_scip2_abandon(&f->urg); /* nothing begun: nothing counted */
    assert_int_equal(urg_scip2_stats(&f->urg)->err_timeout, 1);
    fake_add_str(&f->fake, 0, PP04_REPLY);                 /* the late reply */
    fake_add_str(&f->fake, 2, "BM\n00P\n\n");              /* the next command's */
    assert_int_equal(urg_scip2_laser_on(&f->urg), COSLAM_OK); /* a waiting command skips it too */
    assert_int_equal(urg_scip2_stats(&f->urg)->messages_skipped, 1);

    /* stale replies beyond max_skipped_messages */
    const unsigned max = f->urg.cfg.max_skipped_messages;
    for (unsigned i = 0; i <= max; ++i) {
        fake_add_str(&f->fake, 3, "BM\n00P\n\n");
    }
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_URG_ECHO);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_echo, 1);
    assert_false(urg_scip2_pending(&f->urg));

    /* refused: MD while the laser is broken ("50" + sum) */
    char refusal[32];
    sprintf(refusal, "MD0044072501000\n50%c\n\n", sum_of("50", 2));
    fake_add_str(&f->fake, 4, refusal);
    assert_int_equal(urg_scip2_begin_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_URG_STATUS);
    assert_string_equal(urg_scip2_last_status(&f->urg), "50");
    assert_false(urg_scip2_is_streaming(&f->urg));

    /* a PP reply whose sum is wrong */
    fake_add_str(&f->fake, 5, "PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);M\n\n");
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_URG_CHECKSUM);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_checksum, 1);

    /* arguments refused before anything is sent, as start_md's */
    const unsigned writes = f->fake.n_writes;
    assert_int_equal(urg_scip2_begin_start_md(&f->urg, 725, 44, 1, 0, 0), COSLAM_E_ARG);
    assert_int_equal(urg_scip2_begin_start_md(&f->urg, 44, 725, 1, 10, 0), COSLAM_E_ARG);
    assert_int_equal(f->fake.n_writes, writes);
    assert_int_equal(urg_scip2_begin_read_params(NULL), COSLAM_E_ARG);
    assert_int_equal(urg_scip2_poll(NULL), COSLAM_E_ARG);
}

/* A reply that breaks off costs only itself, as for the waiting commands:
 * abandoned with part of it buffered (its end lost), the next begun
 * command still gets its own reply; and a begin after a waiting command
 * whose reply's end was lost does too (the rest, should it come later,
 * begins with a line that is not the echo and is skipped). */
static void test_poll_after_a_broken_reply(void **state)
{
    fixture_t *f = *state;
    fake_add_str(&f->fake, 1, "PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\n"); /* end lost */
    fake_add_str(&f->fake, 2, "MD0044072501000\n00P\n\n");
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_URG_TIMEOUT);
    urg_scip2_abandon(&f->urg);
    assert_int_equal(urg_scip2_begin_start_md(&f->urg, 44, 725, 1, 0, 0), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_OK);
    assert_true(urg_scip2_is_streaming(&f->urg));

    /* a waiting command whose reply's final LF is lost, then a begun one */
    fixture_t *g = f;
    fake_init(&g->fake);
    assert_int_equal(urg_scip2_init(&g->urg, &g->fake.dev, NULL), COSLAM_OK);
    fake_add_str(&g->fake, 1, "BM\n00P\n");
    fake_add_str(&g->fake, 2, PP04_REPLY);
    assert_int_equal(urg_scip2_laser_on(&g->urg), COSLAM_E_URG_TIMEOUT);
    assert_int_equal(urg_scip2_begin_read_params(&g->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&g->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_params(&g->urg)->ares, 1024);
    assert_int_equal(urg_scip2_stats(&g->urg)->resyncs, 1); /* counted as command() counts it */

    /* the rest of an abandoned reply arriving late is skipped as stale */
    fake_init(&g->fake);
    assert_int_equal(urg_scip2_init(&g->urg, &g->fake.dev, NULL), COSLAM_OK);
    fake_add_str(&g->fake, 1, "PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\n");
    assert_int_equal(urg_scip2_begin_read_params(&g->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&g->urg), COSLAM_E_URG_TIMEOUT);
    urg_scip2_abandon(&g->urg);
    fake_add_str(&g->fake, 2, "DMIN:20;4\nDMAX:5600;_\n\nMD0044072501000\n00P\n\n");
    assert_int_equal(urg_scip2_begin_start_md(&g->urg, 44, 725, 1, 0, 0), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&g->urg), COSLAM_OK);
    assert_true(urg_scip2_is_streaming(&g->urg));
    assert_int_equal(urg_scip2_stats(&g->urg)->messages_skipped, 1);
}

/* A stale message longer than the receive buffer (a scan of a bigger MD
 * left running by another tool) is skipped as it streams in, as a waiting
 * command skips it; stray empty lines count against max_skipped_messages
 * in both. */
static void test_poll_skips_what_a_waiting_command_skips(void **state)
{
    fixture_t *f = *state;
    static char big[URG_SCIP2_RX_CAP + 400];
    size_t n = (size_t)sprintf(big, "ME0000108001000\n99b\n");
    while (n < URG_SCIP2_RX_CAP + 200U) {
        memcpy(big + n, "0123456789012345678901234567890123456789012345678901234567890123X\n", 66);
        n += 66;
    }
    big[n++] = '\n';
    fake_add(&f->fake, 1, big, n);
    fake_add_str(&f->fake, 1, PP04_REPLY);
    assert_int_equal(urg_scip2_read_params(&f->urg, NULL), COSLAM_OK);
    fake_add(&f->fake, 2, big, n);
    fake_add_str(&f->fake, 2, PP04_REPLY);
    f->fake.max_chunk = 700; /* it streams in over several reads */
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_OK);
    const urg_scip2_stats_t *st = urg_scip2_stats(&f->urg);
    assert_int_equal(st->messages_skipped, 2);
    assert_int_equal(st->err_garbage, 0);
    assert_int_equal(st->bytes_discarded, 0);

    const unsigned max = f->urg.cfg.max_skipped_messages;
    char lines[64];
    memset(lines, '\n', max + 1U);
    lines[max + 1U] = '\0';
    fake_add_str(&f->fake, 3, lines);
    fake_add_str(&f->fake, 3, PP04_REPLY);
    assert_int_equal(urg_scip2_read_params(&f->urg, NULL), COSLAM_E_URG_ECHO);
    fake_add_str(&f->fake, 4, lines);
    fake_add_str(&f->fake, 4, PP04_REPLY);
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_E_URG_ECHO);
    assert_int_equal(urg_scip2_stats(&f->urg)->err_echo, 2);
}

/* While a command is begun, what comes is its poll's: read_scan of a
 * running MD takes none of it. A refused begin gives up the one before. */
static void test_one_command_at_a_time(void **state)
{
    fixture_t *f = *state;
    start_md04(f, 0);
    fake_add_str(&f->fake, 2, PP04_REPLY);
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_read_scan(&f->urg, &f->scan, 0), COSLAM_E_EMPTY);
    assert_int_equal(urg_scip2_poll(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_begin_read_params(&f->urg), COSLAM_OK);
    assert_int_equal(urg_scip2_begin_start_md(&f->urg, 44, 725, 1, 10, 0), COSLAM_E_ARG);
    assert_false(urg_scip2_pending(&f->urg));
}

int main(void)
{
#define T(fn) cmocka_unit_test_setup_teardown(fn, setup, teardown)
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_checksum_and_decode_vectors),
        cmocka_unit_test(test_angles_and_validity),
        cmocka_unit_test(test_init_args),
        T(test_enter_scip2),
        T(test_version_published_example),
        T(test_params_published_example),
        T(test_params_bad_fields),
        T(test_info_published_example),
        T(test_laser_on_off),
        T(test_write_failure_is_io),
        T(test_gd_byte_exact),
        T(test_gd_laser_off_status),
        T(test_md_scan_decodes),
        T(test_md_every_split_point),
        T(test_corrupt_checksum),
        T(test_corrupt_checksum_last_line),
        T(test_short_line),
        T(test_missing_line),
        T(test_extra_line),
        T(test_garbage_in_line),
        T(test_stamp_line_length),
        T(test_garbage_between_messages),
        T(test_echo_mismatch_in_stream),
        T(test_scan_arriving_over_calls),
        T(test_scan_broken_off),
        T(test_no_message_end_fills_the_buffer),
        T(test_dmin_error_codes),
        T(test_timestamp_wrap),
        T(test_md_finite_and_cluster),
        T(test_qt_skips_scans_in_flight),
        T(test_md_refused_and_bad_args),
        T(test_endless_lines_bounded),
        T(test_lost_reply_end_keeps_next_reply),
        T(test_md_restart_broken_stale_scan_counted),
        T(test_stream_status_error),
        T(test_md_restart_skips_running_scans),
        T(test_md_finite_last_scan_corrupt),
        T(test_lost_status_line_keeps_next_message),
        T(test_fuzz_mutated_messages),
        T(test_connect_without_waiting),
        T(test_poll_skips_stale_replies),
        T(test_poll_gives_up_and_fails_as_the_waiting_call),
        T(test_poll_after_a_broken_reply),
        T(test_poll_skips_what_a_waiting_command_skips),
        T(test_one_command_at_a_time),
        T(test_fuzz_poll_mutated_replies),
        T(test_wait_for_message_linear_in_small_reads),
        T(test_chunked_reads_parse_as_whole),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
