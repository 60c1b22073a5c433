/* White-box tests of the V4L2 camera backend (hal/hal_camera_v4l2.h)
 * against the in-memory driver of v4l2_fake.h: format negotiation, the
 * YUYV -> RGB24 conversion against BT.601 analytic values, MJPEG decode,
 * latest-frame semantics and sequence gaps, timestamps, and every failure
 * path (EINTR, EAGAIN, timeouts, unplug and reopen, error buffers, corrupt
 * JPEG, unsupported formats, a driver that changes the size). */
#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>
#include <turbojpeg.h>

#include "hal/hal_camera_v4l2.h"
#include "v4l2_fake.h"

/* ---- helpers ------------------------------------------------------------- */

static hal_camera_v4l2_t cam;
static char log_lines[16][200];
static unsigned n_log;

static void capture_log(void *ctx, const char *line)
{
    (void)ctx;
    if (n_log < 16u) snprintf(log_lines[n_log], sizeof log_lines[0], "%s", line);
    n_log++;
}

static hal_camera_v4l2_config_t config(void)
{
    hal_camera_v4l2_config_t c;
    memset(&c, 0, sizeof c);
    c.device = "/dev/video0";
    c.log = capture_log;
    return c;
}

static int setup(void **state)
{
    (void)state;
    fake_v4l2_reset();
    memset(&cam, 0, sizeof cam);
    n_log = 0;
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    if (cam.is_open) hal_camera_close(&cam.dev);
    /* nothing may stay open or mapped */
    if (fake_v4l2.live_mmaps != 0 || fake_v4l2.live_fd >= 0 || fake_v4l2.dead_fd >= 0) return -1;
    return 0;
}

static uint8_t clamp_round(double v)
{
    if (v <= 0.0) return 0;
    if (v >= 255.0) return 255;
    return (uint8_t)floor(v + 0.5);
}

/* The BT.601 equations of the header, in double. */
static void ref_rgb(int y, int u, int v, bool full, double out[3])
{
    const double yy = full ? (double)y : 255.0 / 219.0 * (double)(y - 16);
    const double k = full ? 1.0 : 255.0 / 224.0;
    out[0] = yy + k * 1.402 * (double)(v - 128);
    out[1] = yy - k * 0.344136 * (double)(u - 128) - k * 0.714136 * (double)(v - 128);
    out[2] = yy + k * 1.772 * (double)(u - 128);
}

/* RGB -> limited-range BT.601 Y, U, V (rounded), the inverse of ref_rgb. */
static void rgb_to_yuv(int r, int g, int b, int *y, int *u, int *v)
{
    const double ey = 0.299 * r + 0.587 * g + 0.114 * b;
    *y = (int)floor(16.0 + 219.0 / 255.0 * ey + 0.5);
    *u = (int)floor(128.0 + 224.0 / 255.0 * (b - ey) / 1.772 + 0.5);
    *v = (int)floor(128.0 + 224.0 / 255.0 * (r - ey) / 1.402 + 0.5);
}

/* A YUYV frame from an RGB test card: 8 vertical colour bars (even widths,
 * so both pixels of a pair share one colour) over a grey ramp. */
static const uint8_t bars[8][3] = {{255, 255, 255}, {255, 255, 0}, {0, 255, 255}, {0, 255, 0},
                                   {255, 0, 255},   {255, 0, 0},   {0, 0, 255},   {0, 0, 0}};

static void card_rgb(uint32_t w, uint32_t h, uint32_t x, uint32_t y, int rgb[3])
{
    if (y < h / 2u) {
        const uint8_t *c = bars[(x * 8u) / w];
        for (int k = 0; k < 3; ++k) rgb[k] = c[k];
    } else {
        const int g = (int)((x / 2u * 2u) * 255u / (w - 1u)); /* a pair has one value */
        rgb[0] = rgb[1] = rgb[2] = g;
    }
}

static void make_yuyv_card(uint8_t *dst, uint32_t w, uint32_t h, uint32_t stride)
{
    for (uint32_t y = 0; y < h; ++y) {
        for (uint32_t x = 0; x < w; x += 2u) {
            int rgb[3];
            card_rgb(w, h, x, y, rgb);
            int yy, u, v;
            rgb_to_yuv(rgb[0], rgb[1], rgb[2], &yy, &u, &v);
            uint8_t *p = dst + (size_t)y * stride + (size_t)x * 2u;
            p[0] = (uint8_t)yy;
            p[1] = (uint8_t)u;
            p[2] = (uint8_t)yy;
            p[3] = (uint8_t)v;
        }
    }
}

static uint8_t frame_in[640 * 480 * 3];
static uint8_t frame_out[640 * 480 * 3];
static uint8_t frame_ref[640 * 480 * 3];

static hal_camera_t *open_default(void)
{
    const hal_camera_v4l2_config_t c = config();
    hal_camera_t *d = hal_camera_v4l2_open(&c, &cam);
    assert_non_null(d);
    return d;
}

static void push_card(uint64_t stamp_us)
{
    const uint32_t w = fake_v4l2.width, h = fake_v4l2.height, stride = fake_v4l2.bytesperline;
    memset(frame_in, 0xEE, (size_t)stride * h); /* row padding must not leak */
    make_yuyv_card(frame_in, w, h, stride);
    assert_true(fake_v4l2_push(frame_in, (size_t)stride * h, stamp_us, 0));
}

/* A frame whose first byte tells which it is (YUYV passthrough not needed:
 * the first RGB pixel's R is Y-derived). */
static bool push_marked(uint8_t y_value, uint64_t stamp_us)
{
    const size_t n = (size_t)fake_v4l2.bytesperline * fake_v4l2.height;
    for (size_t i = 0; i < n; i += 2) {
        frame_in[i] = y_value;
        frame_in[i + 1] = 128;
    }
    return fake_v4l2_push(frame_in, n, stamp_us, 0);
}

static uint8_t marked_r(uint8_t y_value)
{
    double rgb[3];
    ref_rgb(y_value, 128, 128, false, rgb);
    return clamp_round(rgb[0]);
}

static size_t jpeg_of(uint8_t *out, size_t cap, const uint8_t *rgb, uint32_t w, uint32_t h, int quality)
{
    tjhandle tj = tjInitCompress();
    assert_non_null(tj);
    unsigned char *buf = out;
    unsigned long size = cap;
    assert_int_equal(tjCompress2(tj, rgb, (int)w, 0, (int)h, TJPF_RGB, &buf, &size, TJSAMP_422, quality,
                                 TJFLAG_NOREALLOC),
                     0);
    tjDestroy(tj);
    return size;
}

static void rgb_card(uint8_t *rgb, uint32_t w, uint32_t h)
{
    for (uint32_t y = 0; y < h; ++y) {
        for (uint32_t x = 0; x < w; ++x) {
            int c[3];
            card_rgb(w, h, x, y, c);
            for (int k = 0; k < 3; ++k) rgb[((size_t)y * w + x) * 3u + (size_t)k] = (uint8_t)c[k];
        }
    }
}

static hal_camera_v4l2_counters_t counters(void)
{
    hal_camera_v4l2_counters_t k;
    assert_int_equal(hal_camera_v4l2_get_counters(&cam, &k), HAL_OK);
    return k;
}

/* ---- YUYV -> RGB24 ------------------------------------------------------- */

static void test_yuyv_known_values(void **state)
{
    (void)state;
    /* limited range: black, white, mid grey, 100 % red / green / blue and
     * 75 % yellow (BT.601 colour bar values, R'G'B' 0..255). Expected
     * bytes worked by hand from the header's equations. */
    static const struct {
        uint8_t y, u, v;
        uint8_t rgb[3];
    } lim[] = {
        {16, 128, 128, {0, 0, 0}},        {235, 128, 128, {255, 255, 255}},
        {126, 128, 128, {128, 128, 128}}, /* 1.164383 * 110 = 128.08 */
        {81, 90, 240, {255, 0, 0}},       /* gives 254, 0, 0: see the literal check below */
        {145, 54, 34, {0, 255, 0}},       {41, 240, 110, {0, 0, 255}},
        {162, 44, 142, {191, 191, 0}},
    };
    for (size_t i = 0; i < sizeof lim / sizeof lim[0]; ++i) {
        const uint8_t in[4] = {lim[i].y, lim[i].u, lim[i].y, lim[i].v};
        uint8_t out[6];
        hal_camera_v4l2_yuyv_to_rgb24(in, 4, out, 6, 2, 1, false);
        double r[3];
        ref_rgb(lim[i].y, lim[i].u, lim[i].v, false, r);
        for (int k = 0; k < 3; ++k) {
            /* exact against the analytic value, and within 1 of the colour
             * the BT.601 table names (its Y/U/V are themselves rounded) */
            assert_int_equal(out[k], clamp_round(r[k]));
            assert_int_equal(out[3 + k], out[k]);
            assert_true(abs((int)out[k] - (int)lim[i].rgb[k]) <= 1);
        }
    }
    /* literal bytes, independent of ref_rgb: red (81,90,240) */
    {
        const uint8_t in[4] = {81, 90, 81, 240};
        uint8_t out[6];
        hal_camera_v4l2_yuyv_to_rgb24(in, 4, out, 6, 2, 1, false);
        /* R = 1.164383*65 + 1.596027*112 = 254.44; G = 75.68 + 0.391762*38
         * - 0.812968*112 = -0.47; B = 75.68 - 2.017232*38 = -0.97 */
        assert_int_equal(out[0], 254);
        assert_int_equal(out[1], 0);
        assert_int_equal(out[2], 0);
    }
    /* saturation at both ends */
    {
        const uint8_t in[4] = {255, 255, 0, 0};
        uint8_t out[6];
        hal_camera_v4l2_yuyv_to_rgb24(in, 4, out, 6, 2, 1, false);
        /* Y=255,U=255,V=0: R = 278.3 - 204.3 = 74.0; G = 278.3 - 49.75 +
         * 104.06 -> 255; B = 278.3 + 256.2 -> 255 */
        assert_int_equal(out[0], 74);
        assert_int_equal(out[1], 255);
        assert_int_equal(out[2], 255);
        /* Y=0: R = -18.63 - 204.29 -> 0; G = -18.63 - 49.75 + 104.06 =
         * 35.68 -> 36; B = -18.63 + 2.017232*127 = 237.56 -> 238 */
        assert_int_equal(out[3], 0);
        assert_int_equal(out[4], 36);
        assert_int_equal(out[5], 238);
    }
}

static void test_yuyv_full_range_values(void **state)
{
    (void)state;
    /* JFIF: Y passes through for grey; red (76, 85, 255) -> (255, 0, 0) */
    const uint8_t in[8] = {0, 128, 255, 128, 76, 85, 76, 255};
    uint8_t out[12];
    hal_camera_v4l2_yuyv_to_rgb24(in, 8, out, 12, 4, 1, true);
    const uint8_t want[12] = {0, 0, 0, 255, 255, 255, 254, 0, 0, 254, 0, 0};
    /* red: R = 76 + 1.402*127 = 254.05 -> 254; G = 76 + 0.344136*43 -
     * 0.714136*127 = 0.10 -> 0; B = 76 - 1.772*43 = -0.2 -> 0 */
    assert_memory_equal(out, want, sizeof want);
}

static void test_yuyv_matches_equations_everywhere(void **state)
{
    (void)state;
    /* every (Y, U, V): exact unless the analytic value is within 0.004 of
     * a rounding tie, never off by more than 1. Why 0.004: each 16.16
     * coefficient is within 2^-17 of its real value and multiplies at
     * most 239 (luma) or 128 (chroma), so G, the worst, is off by at most
     * 2^-17 * (239 + 128 + 128) = 0.0038. Measured: 8949 (limited) and
     * 17599 (full range) of 50 million values, all within 0.0017. */
    for (int full = 0; full < 2; ++full) {
        unsigned off_by_one = 0;
        for (int y = 0; y < 256; ++y) {
            for (int u = 0; u < 256; ++u) {
                for (int v = 0; v < 256; ++v) {
                    const uint8_t in[4] = {(uint8_t)y, (uint8_t)u, (uint8_t)y, (uint8_t)v};
                    uint8_t out[6];
                    hal_camera_v4l2_yuyv_to_rgb24(in, 4, out, 6, 2, 1, full != 0);
                    double r[3];
                    ref_rgb(y, u, v, full != 0, r);
                    for (int k = 0; k < 3; ++k) {
                        const int want = clamp_round(r[k]);
                        if (out[k] != want) {
                            const double frac = r[k] - floor(r[k]);
                            assert_true(fabs(frac - 0.5) < 0.004);
                            assert_true(abs(out[k] - want) == 1);
                            off_by_one++;
                        }
                    }
                }
            }
        }
        assert_true(off_by_one < 50000u); /* under 0.1 % of the 50 million values */
    }
}

static void test_yuyv_strides(void **state)
{
    (void)state;
    /* padded source rows and destination rows: padding untouched */
    uint8_t src[2][12];
    memset(src, 0x77, sizeof src);
    const uint8_t row[8] = {16, 128, 235, 128, 126, 128, 126, 128};
    memcpy(src[0], row, 8);
    memcpy(src[1], row, 8);
    uint8_t dst[2][16];
    memset(dst, 0xAB, sizeof dst);
    hal_camera_v4l2_yuyv_to_rgb24(&src[0][0], 12, &dst[0][0], 16, 4, 2, false);
    const uint8_t want[12] = {0, 0, 0, 255, 255, 255, 128, 128, 128, 128, 128, 128};
    for (int r = 0; r < 2; ++r) {
        assert_memory_equal(dst[r], want, 12);
        for (int k = 12; k < 16; ++k) assert_int_equal(dst[r][k], 0xAB);
    }
}

/* ---- open and negotiation --------------------------------------------- */

static void test_open_negotiates_defaults(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    hal_camera_format_t f;
    assert_int_equal(hal_camera_get_format(d, &f), HAL_OK);
    assert_int_equal(f.width_px, 320);
    assert_int_equal(f.height_px, 240);
    assert_int_equal(f.pixfmt, HAL_CAMERA_PIX_RGB24);
    assert_int_equal(f.stride_bytes, 960);
    assert_int_equal(f.frame_bytes, 960u * 240u);
    assert_int_equal(cam.open_status, HAL_OK);
    assert_int_equal(fake_v4l2.requested_fourcc, V4L2_PIX_FMT_YUYV); /* YUYV preferred by default */
    assert_int_equal(fake_v4l2.requested_width, 320);
    assert_int_equal(fake_v4l2.requested_count, 4);
    assert_int_equal(fake_v4l2.live_mmaps, 4);
    assert_true((fake_v4l2.open_flags & O_NONBLOCK) != 0);
    assert_false(fake_v4l2.streaming);
    assert_int_equal(n_log, 0); /* size as asked: nothing to say */
    assert_true(hal_camera_v4l2_connected(&cam));
    hal_camera_close(d);
    assert_int_equal(fake_v4l2.live_mmaps, 0);
    assert_int_equal(fake_v4l2.live_fd, -1);
    assert_false(hal_camera_v4l2_connected(&cam));
    /* the handle after close: operations say so */
    assert_int_equal(hal_camera_start(d), HAL_E_CLOSED);
    hal_camera_close(d); /* twice: harmless */
}

static void test_open_follows_preference_order(void **state)
{
    (void)state;
    hal_camera_v4l2_config_t c = config();
    c.inputs[0] = HAL_CAMERA_V4L2_IN_MJPEG;
    c.inputs[1] = HAL_CAMERA_V4L2_IN_YUYV;
    c.width_px = 160;
    c.height_px = 120;
    c.buffer_count = 3;
    assert_non_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.in_fourcc, V4L2_PIX_FMT_MJPEG);
    assert_int_equal(fake_v4l2.requested_count, 3);
    assert_non_null(cam.tj);
    assert_int_equal(cam.fmt.width_px, 160);
}

static void test_open_accepts_jpeg_fourcc(void **state)
{
    (void)state;
    fake_v4l2.formats[0] = V4L2_PIX_FMT_JPEG;
    fake_v4l2.n_formats = 1;
    open_default();
    assert_int_equal(cam.in_fourcc, V4L2_PIX_FMT_JPEG);
}

static void test_open_unsupported_format_fails_clearly(void **state)
{
    (void)state;
    fake_v4l2.formats[0] = V4L2_PIX_FMT_H264;
    fake_v4l2.formats[1] = V4L2_PIX_FMT_GREY;
    fake_v4l2.n_formats = 2;
    const hal_camera_v4l2_config_t c = config();
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_UNSUPPORTED);
    assert_int_equal(fake_v4l2.n_s_fmt, 0); /* never asked for what is not listed */
    assert_int_equal(fake_v4l2.live_fd, -1);
    assert_int_equal(fake_v4l2.live_mmaps, 0);
    assert_null(cam.tj);
}

static void test_open_yuyv_output_needs_yuyv_device(void **state)
{
    (void)state;
    fake_v4l2.formats[0] = V4L2_PIX_FMT_MJPEG;
    fake_v4l2.n_formats = 1;
    hal_camera_v4l2_config_t c = config();
    c.output = HAL_CAMERA_PIX_YUYV;
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_UNSUPPORTED);
}

static void test_open_errors(void **state)
{
    (void)state;
    hal_camera_v4l2_config_t c = config();
    /* arguments */
    assert_null(hal_camera_v4l2_open(NULL, &cam));
    assert_int_equal(cam.open_status, HAL_E_ARG);
    assert_null(hal_camera_v4l2_open(&c, NULL));
    c.device = NULL;
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_ARG);
    c = config();
    c.buffer_count = HAL_CAMERA_V4L2_MAX_BUFFERS + 1u;
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_ARG);
    c = config();
    c.output = (hal_camera_pixfmt_t)7;
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_ARG);
    assert_int_equal(fake_v4l2.n_open, 0);
    /* the device */
    c = config();
    fake_v4l2.present = false;
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_NOT_FOUND);
    fake_v4l2.present = true;
    fake_v4l2.open_errno = EACCES;
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_IO);
    fake_v4l2.open_errno = 0;
    fake_v4l2.s_fmt_errno = EBUSY; /* streaming for someone else */
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_BUSY);
    assert_int_equal(fake_v4l2.live_fd, -1);
    fake_v4l2.s_fmt_errno = 0;
    fake_v4l2.device_caps = V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_STREAMING; /* not a camera */
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_UNSUPPORTED);
    fake_v4l2.device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_READWRITE; /* no streaming I/O */
    assert_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(cam.open_status, HAL_E_UNSUPPORTED);
    fake_v4l2.device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
    fake_v4l2.open_eintr = 2; /* retried */
    assert_non_null(hal_camera_v4l2_open(&c, &cam));
    assert_int_equal(fake_v4l2.live_mmaps, 4);
}

static void test_open_driver_changes_size(void **state)
{
    (void)state;
    fake_v4l2.force_width = 352;
    fake_v4l2.force_height = 288;
    hal_camera_t *d = open_default();
    hal_camera_format_t f;
    assert_int_equal(hal_camera_get_format(d, &f), HAL_OK);
    assert_int_equal(f.width_px, 352);
    assert_int_equal(f.height_px, 288);
    assert_int_equal(f.frame_bytes, 352u * 3u * 288u);
    assert_int_equal(n_log, 1);
    assert_non_null(strstr(log_lines[0], "352x288"));
    /* frames come at that size */
    assert_int_equal(hal_camera_start(d), HAL_OK);
    push_card(5);
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, f.frame_bytes, &info, 0), HAL_OK);
    assert_int_equal(info.len, f.frame_bytes);
    assert_int_equal(n_log, 1); /* once */
}

/* ---- frames ---------------------------------------------------------- */

static void test_grab_yuyv_card_exact(void **state)
{
    (void)state;
    fake_v4l2.row_pad_bytes = 32; /* bytesperline > width * 2 */
    hal_camera_t *d = open_default();
    assert_int_equal(cam.in_stride_bytes, 320u * 2u + 32u);
    assert_int_equal(hal_camera_start(d), HAL_OK);
    push_card(1234567);
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(info.len, 320u * 240u * 3u);
    /* byte-exact against the analytic equations, and within 2 of the test
     * card's RGB (the YUV encoding rounds to 8 bits) */
    for (uint32_t y = 0; y < 240; ++y) {
        for (uint32_t x = 0; x < 320; ++x) {
            const uint8_t *p = fake_v4l2_buffer_mem(0) + (size_t)y * cam.in_stride_bytes + (x / 2u) * 4u;
            double r[3];
            ref_rgb(p[(x % 2u) * 2u], p[1], p[3], false, r);
            int card[3];
            card_rgb(320, 240, x, y, card);
            for (int k = 0; k < 3; ++k) {
                const uint8_t got = frame_out[((size_t)y * 320u + x) * 3u + (size_t)k];
                assert_int_equal(got, clamp_round(r[k]));
                assert_true(abs((int)got - card[k]) <= 2);
            }
        }
    }
    assert_int_equal(counters().frames, 1);
}

static void test_grab_yuyv_passthrough(void **state)
{
    (void)state;
    fake_v4l2.row_pad_bytes = 16;
    hal_camera_v4l2_config_t c = config();
    c.output = HAL_CAMERA_PIX_YUYV;
    c.inputs[0] = HAL_CAMERA_V4L2_IN_MJPEG; /* skipped: no YUYV output from MJPEG */
    c.inputs[1] = HAL_CAMERA_V4L2_IN_YUYV;
    hal_camera_t *d = hal_camera_v4l2_open(&c, &cam);
    assert_non_null(d);
    assert_null(cam.tj);
    assert_int_equal(cam.fmt.stride_bytes, 640);
    assert_int_equal(hal_camera_start(d), HAL_OK);
    push_card(10);
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, cam.fmt.frame_bytes, &info, 0), HAL_OK);
    for (uint32_t y = 0; y < 240; ++y) {
        assert_memory_equal(frame_out + (size_t)y * 640u, frame_in + (size_t)y * (640u + 16u), 640);
    }
}

static void test_grab_latest_and_sequence_gaps(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    hal_camera_frame_info_t info;
    assert_true(push_marked(50, 100));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    const uint32_t s0 = info.sequence;
    assert_int_equal(s0, 0);
    /* three frames before the next grab: the newest is returned */
    assert_true(push_marked(60, 200));
    assert_true(push_marked(70, 300));
    assert_true(push_marked(80, 400));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(frame_out[0], marked_r(80));
    assert_int_equal(info.stamp_us, 400);
    assert_int_equal(info.sequence - s0, 3); /* gap of 2 */
    assert_int_equal(counters().frames_skipped, 2);
    /* the same frame is never returned twice */
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    /* more frames than buffers: the driver drops (no buffer queued), its
     * counter still counts them, so the gap shows them too */
    for (int i = 0; i < 6; ++i) (void)push_marked((uint8_t)(90 + i), 500u + (uint64_t)i);
    assert_int_equal(fake_v4l2.frames_dropped, 2); /* 4 buffers */
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(info.sequence - s0, 7);      /* the 4th of 6 is the newest buffered */
    assert_int_equal(frame_out[0], marked_r(93));
    /* stop/start: sequence continues, frames while stopped are not kept */
    assert_int_equal(hal_camera_stop(d), HAL_OK);
    assert_false(push_marked(20, 600));
    assert_int_equal(hal_camera_start(d), HAL_OK);
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    assert_true(push_marked(30, 700));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    /* one past the last frame dequeued (the driver's 7); the two it
     * dropped before the stop are not seen by anyone */
    assert_int_equal(info.sequence - s0, 8);
    assert_int_equal(counters().frames_skipped, 5);
}

static void test_overflow_keeps_frame(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    assert_true(push_marked(100, 100));
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, 10, &info, 0), HAL_E_OVERFLOW);
    assert_int_equal(info.len, 320u * 240u * 3u);
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(frame_out[0], marked_r(100));
    assert_int_equal(info.stamp_us, 100);
    /* a held frame is superseded by a newer one */
    assert_true(push_marked(110, 200));
    assert_int_equal(hal_camera_grab(d, frame_out, 10, &info, 0), HAL_E_OVERFLOW);
    assert_true(push_marked(120, 300));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(frame_out[0], marked_r(120));
    assert_int_equal(counters().frames_skipped, 1);
}

static void test_timestamps(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    hal_camera_frame_info_t info;
    /* MONOTONIC: the driver's stamp, seconds and microseconds */
    assert_true(push_marked(50, 123456789012u));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(info.stamp_us, 123456789012u);
    /* COPY (an output stamp, not a capture time) and UNKNOWN: dequeue time */
    fake_v4l2.ts_flags = V4L2_BUF_FLAG_TIMESTAMP_COPY;
    fake_v4l2.now_us = 77000001u;
    assert_true(push_marked(50, 5));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(info.stamp_us, 77000001u);
    fake_v4l2.ts_flags = V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN;
    fake_v4l2.now_us = 88000002u;
    assert_true(push_marked(50, 5));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(info.stamp_us, 88000002u);
}

static void test_timeouts(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_CLOSED); /* not started */
    assert_int_equal(hal_camera_start(d), HAL_OK);
    assert_int_equal(hal_camera_start(d), HAL_OK); /* idempotent */
    assert_int_equal(fake_v4l2.n_streamon, 1);
    /* timeout 0: never waits */
    const unsigned polls = fake_v4l2.n_poll;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    assert_int_equal(fake_v4l2.n_poll, polls);
    /* 2.5 ms: one poll of 3 ms (rounded up), the time has passed */
    const uint64_t t0 = fake_v4l2.now_us;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 2500), HAL_E_TIMEOUT);
    assert_int_equal(fake_v4l2.last_poll_timeout_ms, 3);
    assert_true(fake_v4l2.now_us - t0 >= 2500u);
    /* spurious wake-up (POLLIN, then DQBUF EAGAIN): waits on, times out */
    fake_v4l2.spurious_pollin = 1;
    const uint64_t t1 = fake_v4l2.now_us;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 10000), HAL_E_TIMEOUT);
    assert_true(fake_v4l2.now_us - t1 >= 10000u);
    assert_int_equal(counters().timeouts, 3);
    assert_int_equal(hal_camera_stop(d), HAL_OK);
    assert_int_equal(hal_camera_stop(d), HAL_OK);
    assert_int_equal(fake_v4l2.n_streamoff, 1);
}

static void push_on_poll(void *ctx)
{
    (void)ctx;
    if (fake_v4l2.n_poll == 3u) (void)push_marked(99, fake_v4l2.now_us);
}

static void test_eintr_retried(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    /* a frame arriving during the wait, after two interrupted polls and
     * with an interrupted DQBUF: all retried, the frame comes through */
    fake_v4l2.poll_eintr = 2;
    fake_v4l2.on_poll = push_on_poll;
    fake_v4l2.n_poll = 0;
    fake_v4l2.dqbuf_eintr = 1;
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, HAL_TIMEOUT_FOREVER), HAL_OK);
    assert_int_equal(frame_out[0], marked_r(99));
    assert_int_equal(fake_v4l2.n_poll, 3);
    assert_int_equal(fake_v4l2.last_poll_timeout_ms, -1);
    assert_int_equal(counters().eintr_retries, 3);
}

static void test_error_buffers_dropped(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    hal_camera_frame_info_t info;
    const size_t n = (size_t)fake_v4l2.bytesperline * fake_v4l2.height;
    memset(frame_in, 16, n);
    assert_true(fake_v4l2_push(frame_in, n, 10, V4L2_BUF_FLAG_ERROR));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    /* an error frame newer than a good one does not hide it */
    assert_true(push_marked(40, 20));
    assert_true(fake_v4l2_push(frame_in, n, 30, V4L2_BUF_FLAG_ERROR));
    assert_true(fake_v4l2_push(frame_in, 0, 40, 0)); /* empty */
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(info.stamp_us, 20);
    /* a short YUYV frame is dropped */
    assert_true(fake_v4l2_push(frame_in, n / 2u, 50, 0));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    const hal_camera_v4l2_counters_t k = counters();
    assert_int_equal(k.buffer_errors, 3);
    assert_int_equal(k.bad_size_frames, 1);
    assert_int_equal(k.frames, 1);
    /* every buffer went back to the driver */
    assert_int_equal(fake_v4l2.n_queued, 4);
}

static hal_camera_t *open_mjpeg(uint32_t w, uint32_t h)
{
    fake_v4l2.formats[0] = V4L2_PIX_FMT_MJPEG;
    fake_v4l2.n_formats = 1;
    hal_camera_v4l2_config_t c = config();
    c.width_px = w;
    c.height_px = h;
    hal_camera_t *d = hal_camera_v4l2_open(&c, &cam);
    assert_non_null(d);
    assert_int_equal(cam.in_fourcc, V4L2_PIX_FMT_MJPEG);
    assert_int_equal(hal_camera_start(d), HAL_OK);
    return d;
}

static uint8_t jpeg[200000];

static void test_mjpeg_decoded(void **state)
{
    (void)state;
    hal_camera_t *d = open_mjpeg(320, 240);
    rgb_card(frame_ref, 320, 240);
    const size_t n = jpeg_of(jpeg, sizeof jpeg, frame_ref, 320, 240, 95);
    assert_true(fake_v4l2_push(jpeg, n, 4242, 0));
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(info.stamp_us, 4242);
    /* exactly what TurboJPEG decodes from the same bytes ... */
    tjhandle tj = tjInitDecompress();
    static uint8_t want[320 * 240 * 3];
    assert_int_equal(tjDecompress2(tj, jpeg, n, want, 320, 0, 240, TJPF_RGB, 0), 0);
    tjDestroy(tj);
    assert_memory_equal(frame_out, want, sizeof want);
    /* ... and close to the card away from the bar edges (JPEG is lossy) */
    unsigned far = 0;
    for (uint32_t y = 0; y < 240; ++y) {
        for (uint32_t x = 0; x < 320; ++x) {
            if (x % 40u < 4u || x % 40u > 35u || (y > 112u && y < 128u)) continue;
            for (int k = 0; k < 3; ++k) {
                const size_t i = ((size_t)y * 320u + x) * 3u + (size_t)k;
                if (abs((int)frame_out[i] - (int)frame_ref[i]) > 8) far++;
            }
        }
    }
    assert_int_equal(far, 0);
}

static void test_mjpeg_corrupt_and_wrong_size_dropped(void **state)
{
    (void)state;
    hal_camera_t *d = open_mjpeg(160, 120);
    rgb_card(frame_ref, 160, 120);
    const size_t n = jpeg_of(jpeg, sizeof jpeg, frame_ref, 160, 120, 80);
    hal_camera_frame_info_t info;
    /* not a JPEG at all */
    memset(frame_in, 0x5A, 1000);
    assert_true(fake_v4l2_push(frame_in, 1000, 1, 0));
    /* truncated: header fine, data cut */
    assert_true(fake_v4l2_push(jpeg, n / 2u, 2, 0));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    /* the frame counted as corrupt is the newest one dequeued (the older
     * was superseded before decoding) */
    hal_camera_v4l2_counters_t k = counters();
    assert_int_equal(k.corrupt_frames, 1);
    assert_int_equal(k.frames_skipped, 1);
    assert_true(fake_v4l2_push(jpeg, n / 2u, 3, 0));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    /* garbage in the entropy-coded data */
    memcpy(frame_in, jpeg, n);
    for (size_t i = n / 3u; i < n - 2u; i += 7u) frame_in[i] = 0xFF;
    assert_true(fake_v4l2_push(frame_in, n, 4, 0));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    k = counters();
    assert_int_equal(k.corrupt_frames, 3);
    /* a JPEG of another size (the driver changed it mid-stream) */
    static uint8_t big[320 * 240 * 3];
    rgb_card(big, 320, 240);
    const size_t nb = jpeg_of(frame_in, sizeof frame_in, big, 320, 240, 50);
    assert_true(fake_v4l2_push(frame_in, nb, 5, 0));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    assert_int_equal(counters().bad_size_frames, 1);
    /* a wrong-sized frame superseded by a good one: the good one */
    assert_true(fake_v4l2_push(frame_in, nb, 6, 0));
    assert_true(fake_v4l2_push(jpeg, n, 7, 0));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 1000), HAL_OK);
    assert_int_equal(info.stamp_us, 7);
    assert_int_equal(counters().frames, 1);
}

/* Remove the DHT (Huffman table) segments, as many UVC cameras send
 * Motion-JPEG; returns the new length. */
static size_t strip_dht(uint8_t *out, const uint8_t *in, size_t n)
{
    size_t o = 2, i = 2;
    memcpy(out, in, 2);
    while (i + 4u <= n && in[i] == 0xFF) {
        const unsigned m = in[i + 1];
        if (m == 0xDA) break; /* start of scan: the rest is entropy-coded data */
        const size_t len = ((size_t)in[i + 2] << 8 | in[i + 3]) + 2u;
        if (m != 0xC4) {
            memcpy(out + o, in + i, len);
            o += len;
        }
        i += len;
    }
    memcpy(out + o, in + i, n - i);
    return o + n - i;
}

static void test_mjpeg_without_huffman_tables(void **state)
{
    (void)state;
    hal_camera_t *d = open_mjpeg(160, 120);
    rgb_card(frame_ref, 160, 120);
    const size_t n = jpeg_of(jpeg, sizeof jpeg, frame_ref, 160, 120, 85);
    const size_t m = strip_dht(frame_in, jpeg, n);
    assert_true(m < n);
    assert_true(fake_v4l2_push(frame_in, m, 9, 0));
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    /* libjpeg-turbo falls back to the standard tables, which the encoder used */
    tjhandle tj = tjInitDecompress();
    static uint8_t want[160 * 120 * 3];
    assert_int_equal(tjDecompress2(tj, jpeg, n, want, 160, 0, 120, TJPF_RGB, 0), 0);
    tjDestroy(tj);
    assert_memory_equal(frame_out, want, sizeof want);
}

static size_t jpeg_len;

static void push_jpeg_on_poll(void *ctx)
{
    (void)ctx;
    (void)fake_v4l2_push(jpeg, jpeg_len, fake_v4l2.now_us, 0);
    fake_v4l2.on_poll = NULL;
}

static void test_mjpeg_good_after_corrupt_in_one_wait(void **state)
{
    (void)state;
    hal_camera_t *d = open_mjpeg(160, 120);
    rgb_card(frame_ref, 160, 120);
    jpeg_len = jpeg_of(jpeg, sizeof jpeg, frame_ref, 160, 120, 80);
    memset(frame_in, 0, 500);
    assert_true(fake_v4l2_push(frame_in, 500, 1, 0)); /* corrupt, ready at once */
    /* the grab drops it and waits on; the good frame arrives during the wait */
    fake_v4l2.on_poll = push_jpeg_on_poll;
    const uint64_t t = fake_v4l2.now_us;
    hal_camera_frame_info_t info;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 50000), HAL_OK);
    assert_int_equal(info.stamp_us, t);
    assert_int_equal(counters().corrupt_frames, 1);
    assert_int_equal(counters().frames, 1);
}

static void unplug_on_poll(void *ctx)
{
    (void)ctx;
    fake_v4l2_unplug();
}

static void test_unplug_reported_and_reopened(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    hal_camera_frame_info_t info;
    assert_true(push_marked(50, 10));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    const uint32_t s0 = info.sequence;
    /* unplugged while the grab waits: POLLERR -> HAL_E_IO, released */
    fake_v4l2.on_poll = unplug_on_poll;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 100000), HAL_E_IO);
    fake_v4l2.on_poll = NULL;
    assert_false(hal_camera_v4l2_connected(&cam));
    assert_int_equal(fake_v4l2.live_mmaps, 0);
    assert_int_equal(fake_v4l2.dead_fd, -1); /* the dead descriptor was closed */
    assert_int_equal(counters().disconnects, 1);
    assert_int_equal(n_log, 1);
    /* within the reopen period: no attempt, HAL_E_IO at once */
    const unsigned opens = fake_v4l2.n_open;
    fake_v4l2.now_us += 500000u;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 100000), HAL_E_IO);
    assert_int_equal(fake_v4l2.n_open, opens);
    /* after it: one attempt, device still absent */
    fake_v4l2.now_us += 600000u;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_IO);
    assert_int_equal(fake_v4l2.n_open, opens + 1u);
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_IO);
    assert_int_equal(fake_v4l2.n_open, opens + 1u); /* rate-limited */
    /* get_format still answers (the format is fixed) */
    hal_camera_format_t f;
    assert_int_equal(hal_camera_get_format(d, &f), HAL_OK);
    assert_int_equal(f.width_px, 320);
    /* plugged back: the next attempt reopens and streams again */
    fake_v4l2_replug();
    fake_v4l2.now_us += 1000000u;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    assert_true(hal_camera_v4l2_connected(&cam));
    assert_true(fake_v4l2.streaming);
    assert_int_equal(fake_v4l2.live_mmaps, 4);
    assert_true(push_marked(77, 2000));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(frame_out[0], marked_r(77));
    assert_true(info.sequence > s0); /* never goes back */
    const hal_camera_v4l2_counters_t k = counters();
    assert_int_equal(k.reopen_attempts, 2);
    assert_int_equal(k.reopens, 1);
    assert_int_equal(n_log, 2);
}

static void test_unplug_on_dqbuf_and_stop_start(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    hal_camera_frame_info_t info;
    /* gone between grabs: DQBUF fails ENODEV */
    fake_v4l2_unplug();
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_IO);
    assert_int_equal(counters().disconnects, 1);
    /* stop while lost is fine; then grab says not streaming */
    assert_int_equal(hal_camera_stop(d), HAL_OK);
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_CLOSED);
    /* start tries at once (not rate-limited): absent -> HAL_E_IO */
    assert_int_equal(hal_camera_start(d), HAL_E_IO);
    fake_v4l2_replug();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    assert_true(fake_v4l2.streaming);
    assert_true(push_marked(66, 1));
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_OK);
    assert_int_equal(frame_out[0], marked_r(66));
}

static void test_reopen_refuses_other_size(void **state)
{
    (void)state;
    hal_camera_t *d = open_default();
    assert_int_equal(hal_camera_start(d), HAL_OK);
    hal_camera_frame_info_t info;
    fake_v4l2_unplug();
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_IO);
    /* another camera comes back on the node, 640x480 only */
    fake_v4l2_replug();
    fake_v4l2.force_width = 640;
    fake_v4l2.force_height = 480;
    for (int i = 0; i < 3; ++i) {
        fake_v4l2.now_us += 1000000u;
        assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_IO);
        assert_int_equal(fake_v4l2.live_fd, -1); /* released again */
        assert_int_equal(fake_v4l2.live_mmaps, 0);
    }
    assert_int_equal(counters().reopen_attempts, 3);
    assert_int_equal(counters().reopens, 0);
    assert_int_equal(n_log, 2); /* lost + one refusal, not one per attempt */
    /* the right camera again */
    fake_v4l2.force_width = 0;
    fake_v4l2.force_height = 0;
    fake_v4l2.now_us += 1000000u;
    assert_int_equal(hal_camera_grab(d, frame_out, sizeof frame_out, &info, 0), HAL_E_TIMEOUT);
    assert_true(hal_camera_v4l2_connected(&cam));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_yuyv_known_values),
        cmocka_unit_test(test_yuyv_full_range_values),
        cmocka_unit_test(test_yuyv_matches_equations_everywhere),
        cmocka_unit_test(test_yuyv_strides),
        cmocka_unit_test_setup_teardown(test_open_negotiates_defaults, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_follows_preference_order, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_accepts_jpeg_fourcc, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_unsupported_format_fails_clearly, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_yuyv_output_needs_yuyv_device, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_errors, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_driver_changes_size, setup, teardown),
        cmocka_unit_test_setup_teardown(test_grab_yuyv_card_exact, setup, teardown),
        cmocka_unit_test_setup_teardown(test_grab_yuyv_passthrough, setup, teardown),
        cmocka_unit_test_setup_teardown(test_grab_latest_and_sequence_gaps, setup, teardown),
        cmocka_unit_test_setup_teardown(test_overflow_keeps_frame, setup, teardown),
        cmocka_unit_test_setup_teardown(test_timestamps, setup, teardown),
        cmocka_unit_test_setup_teardown(test_timeouts, setup, teardown),
        cmocka_unit_test_setup_teardown(test_eintr_retried, setup, teardown),
        cmocka_unit_test_setup_teardown(test_error_buffers_dropped, setup, teardown),
        cmocka_unit_test_setup_teardown(test_mjpeg_decoded, setup, teardown),
        cmocka_unit_test_setup_teardown(test_mjpeg_corrupt_and_wrong_size_dropped, setup, teardown),
        cmocka_unit_test_setup_teardown(test_mjpeg_good_after_corrupt_in_one_wait, setup, teardown),
        cmocka_unit_test_setup_teardown(test_mjpeg_without_huffman_tables, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unplug_reported_and_reopened, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unplug_on_dqbuf_and_stop_start, setup, teardown),
        cmocka_unit_test_setup_teardown(test_reopen_refuses_other_size, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
