/*
 * V4L2 backend of hal_camera.h. See hal/hal_camera_v4l2.h for the
 * behaviour behind the contract and docs/camera-v4l2.md for the reasons.
 * Every kernel call goes through the seam in hal_camera_v4l2_sys.h.
 */
#include "hal/hal_camera_v4l2.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <turbojpeg.h>

#include "hal_camera_v4l2_sys.h"

#define MAX_SIDE_PX 8192u
#define MAX_ENUM_FORMATS 64u
/* TurboJPEG: stop at the first warning (truncated or corrupt data): such a
 * frame is dropped anyway, so finishing its decode is wasted time. */
#define TJ_FLAGS TJFLAG_STOPONWARNING

/* ------------------------------------------------------------------------ */
/* YUYV -> RGB24                                                            */
/* ------------------------------------------------------------------------ */

/* v: a 16.16 fixed-point value plus 0.5 (rounding); 0..255 after the shift. */
static inline uint8_t sat_u8(int32_t v)
{
    if (v <= 0) return 0u;
    v >>= 16;
    return v > 255 ? 255u : (uint8_t)v;
}

void hal_camera_v4l2_yuyv_to_rgb24(const uint8_t *src, size_t src_stride_bytes, uint8_t *dst, size_t dst_stride_bytes,
                                   uint32_t width_px, uint32_t height_px, bool full_range)
{
    /* BT.601 coefficients (header) times 2^16, rounded. Limited range:
     * 255/219 for luma, 255/224 * (1.402, 0.344136, 0.714136, 1.772) for
     * chroma; full range: the JFIF ones. */
    const int32_t ky = full_range ? 65536 : 76309;
    const int32_t y_off = full_range ? 0 : 16;
    const int32_t k_rv = full_range ? 91881 : 104597;
    const int32_t k_gu = full_range ? 22554 : 25675;
    const int32_t k_gv = full_range ? 46802 : 53279;
    const int32_t k_bu = full_range ? 116130 : 132201;
    const int32_t half = 32768;
    for (uint32_t row = 0; row < height_px; ++row) {
        const uint8_t *s = src + (size_t)row * src_stride_bytes;
        uint8_t *d = dst + (size_t)row * dst_stride_bytes;
        for (uint32_t x = 0; x + 1u < width_px; x += 2u) {
            const int32_t u = (int32_t)s[1] - 128;
            const int32_t v = (int32_t)s[3] - 128;
            const int32_t r = k_rv * v + half;
            const int32_t g = half - k_gu * u - k_gv * v;
            const int32_t b = k_bu * u + half;
            const int32_t y0 = ky * ((int32_t)s[0] - y_off);
            const int32_t y1 = ky * ((int32_t)s[2] - y_off);
            d[0] = sat_u8(y0 + r);
            d[1] = sat_u8(y0 + g);
            d[2] = sat_u8(y0 + b);
            d[3] = sat_u8(y1 + r);
            d[4] = sat_u8(y1 + g);
            d[5] = sat_u8(y1 + b);
            s += 4;
            d += 6;
        }
    }
}

/* ------------------------------------------------------------------------ */
/* helpers                                                                  */
/* ------------------------------------------------------------------------ */

#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
static void say(const hal_camera_v4l2_t *c, const char *fmt, ...)
{
    char line[200];
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (c->cfg.log != NULL) {
        c->cfg.log(c->cfg.log_ctx, line);
    } else {
        fprintf(stderr, "hal_camera_v4l2 %s: %s\n", c->path, line);
    }
}

/* The device is gone (unplugged, driver unbound, queue in error). */
static bool gone_errno(int e)
{
    return e == ENODEV || e == ENXIO || e == EIO;
}

static hal_status_t errno_status(int e)
{
    switch (e) {
    case ENOENT:
    case ENODEV:
    case ENXIO:
        return HAL_E_NOT_FOUND;
    case EBUSY:
        return HAL_E_BUSY;
    case ENOTTY:
        return HAL_E_UNSUPPORTED;
    default:
        return HAL_E_IO;
    }
}

static int xioctl(hal_camera_v4l2_t *c, unsigned long request, void *arg)
{
    for (;;) {
        const int r = v4l2_sys_ioctl(c->fd, request, arg);
        if (r != -1 || errno != EINTR) return r;
        c->counters.eintr_retries++;
    }
}

static uint64_t timeval_us(const struct timeval *tv)
{
    if (tv->tv_sec < 0 || tv->tv_usec < 0) return 0u;
    return (uint64_t)tv->tv_sec * 1000000u + (uint64_t)tv->tv_usec;
}

/* ------------------------------------------------------------------------ */
/* format negotiation and buffers                                           */
/* ------------------------------------------------------------------------ */

/* Negotiate on c->fd. exact: a reopen, which must give the fixed size.
 * Sets c->in_* and *w, *h. HAL_E_UNSUPPORTED: nothing acceptable. */
static hal_status_t negotiate(hal_camera_v4l2_t *c, uint32_t *w, uint32_t *h, bool exact)
{
    struct v4l2_capability cap;
    memset(&cap, 0, sizeof cap);
    if (xioctl(c, VIDIOC_QUERYCAP, &cap) != 0) {
        return (errno == ENOTTY || errno == EINVAL) ? HAL_E_UNSUPPORTED : errno_status(errno);
    }
    const uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0u ? cap.device_caps : cap.capabilities;
    if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0u || (caps & V4L2_CAP_STREAMING) == 0u) return HAL_E_UNSUPPORTED;

    uint32_t offered[MAX_ENUM_FORMATS];
    uint32_t n_offered = 0;
    for (uint32_t i = 0; i < MAX_ENUM_FORMATS; ++i) {
        struct v4l2_fmtdesc d;
        memset(&d, 0, sizeof d);
        d.index = i;
        d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (xioctl(c, VIDIOC_ENUM_FMT, &d) != 0) {
            if (errno == EINVAL) break; /* end of the list */
            return errno_status(errno);
        }
        offered[n_offered++] = d.pixelformat;
    }

    for (uint32_t p = 0; p < HAL_CAMERA_V4L2_MAX_INPUTS && c->cfg.inputs[p] != HAL_CAMERA_V4L2_IN_NONE; ++p) {
        const hal_camera_v4l2_input_t in = c->cfg.inputs[p];
        if (in == HAL_CAMERA_V4L2_IN_MJPEG && c->cfg.output != HAL_CAMERA_PIX_RGB24) continue;
        const uint32_t yuyv[1] = {V4L2_PIX_FMT_YUYV};
        const uint32_t mjpeg[2] = {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_JPEG};
        const uint32_t *cand = in == HAL_CAMERA_V4L2_IN_YUYV ? yuyv : mjpeg;
        const uint32_t n_cand = in == HAL_CAMERA_V4L2_IN_YUYV ? 1u : 2u;
        for (uint32_t k = 0; k < n_cand; ++k) {
            const uint32_t fourcc = cand[k];
            bool listed = false;
            for (uint32_t i = 0; i < n_offered; ++i) listed = listed || offered[i] == fourcc;
            if (!listed) continue;

            struct v4l2_format f;
            memset(&f, 0, sizeof f);
            f.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
            f.fmt.pix.width = *w;
            f.fmt.pix.height = *h;
            f.fmt.pix.pixelformat = fourcc;
            f.fmt.pix.field = V4L2_FIELD_NONE;
            if (xioctl(c, VIDIOC_S_FMT, &f) != 0) {
                if (errno == EINVAL) continue;
                return errno_status(errno);
            }
            /* The active format, as the driver holds it. */
            memset(&f, 0, sizeof f);
            f.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
            if (xioctl(c, VIDIOC_G_FMT, &f) != 0) return errno_status(errno);
            const struct v4l2_pix_format *px = &f.fmt.pix;
            if (px->pixelformat != fourcc) continue;
            if (px->field != V4L2_FIELD_NONE && px->field != V4L2_FIELD_ANY) continue; /* interlaced */
            if (px->width == 0u || px->height == 0u || px->width > MAX_SIDE_PX || px->height > MAX_SIDE_PX) continue;
            if (exact && (px->width != *w || px->height != *h)) continue;
            if (fourcc == V4L2_PIX_FMT_YUYV) {
                if (px->width % 2u != 0u) continue;
                const uint32_t stride = px->bytesperline != 0u ? px->bytesperline : px->width * 2u;
                if (stride < px->width * 2u) continue;
                c->in_stride_bytes = stride;
                c->in_full_range =
                    px->priv == V4L2_PIX_FMT_PRIV_MAGIC && px->quantization == V4L2_QUANTIZATION_FULL_RANGE;
            } else {
                c->in_stride_bytes = 0u;
                c->in_full_range = true;
            }
            c->in_fourcc = fourcc;
            *w = px->width;
            *h = px->height;
            return HAL_OK;
        }
    }
    return HAL_E_UNSUPPORTED;
}

static void unmap_buffers(hal_camera_v4l2_t *c)
{
    for (uint32_t i = 0; i < c->n_bufs; ++i) {
        if (c->bufs[i].start != NULL) (void)v4l2_sys_munmap(c->bufs[i].start, c->bufs[i].length);
        c->bufs[i].start = NULL;
        c->bufs[i].length = 0u;
    }
    c->n_bufs = 0u;
}

/* REQBUFS + QUERYBUF + mmap. min_len: bytes a buffer must hold. */
static hal_status_t map_buffers(hal_camera_v4l2_t *c, size_t min_len)
{
    struct v4l2_requestbuffers rb;
    memset(&rb, 0, sizeof rb);
    rb.count = c->cfg.buffer_count;
    rb.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    rb.memory = V4L2_MEMORY_MMAP;
    if (xioctl(c, VIDIOC_REQBUFS, &rb) != 0) {
        return errno == EINVAL ? HAL_E_UNSUPPORTED : errno_status(errno); /* EINVAL: no mmap streaming */
    }
    uint32_t n = rb.count; /* the driver's answer (may differ from the request) */
    if (n < 2u) return HAL_E_IO; /* the latest-frame policy needs one buffer filling while one is held */
    if (n > HAL_CAMERA_V4L2_MAX_BUFFERS) n = HAL_CAMERA_V4L2_MAX_BUFFERS; /* the rest are never queued */
    for (uint32_t i = 0; i < n; ++i) {
        struct v4l2_buffer b;
        memset(&b, 0, sizeof b);
        b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        b.memory = V4L2_MEMORY_MMAP;
        b.index = i;
        if (xioctl(c, VIDIOC_QUERYBUF, &b) != 0) return errno_status(errno);
        if (b.length < min_len) return HAL_E_IO;
        void *p = v4l2_sys_mmap(b.length, PROT_READ | PROT_WRITE, MAP_SHARED, c->fd, (off_t)b.m.offset);
        if (p == MAP_FAILED) return HAL_E_IO;
        c->bufs[i].start = p;
        c->bufs[i].length = b.length;
        c->n_bufs = i + 1u;
    }
    return HAL_OK;
}

/* Release the device (mappings, descriptor); the format and the TurboJPEG
 * handle stay. Buffers still queued go with the descriptor. */
static void disconnect(hal_camera_v4l2_t *c)
{
    if (c->fd >= 0 && c->stream_on && !c->lost) {
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        (void)xioctl(c, VIDIOC_STREAMOFF, &type);
    }
    c->stream_on = false;
    c->held = -1;
    unmap_buffers(c);
    if (c->fd >= 0) (void)v4l2_sys_close(c->fd);
    c->fd = -1;
}

/* Open the device node, negotiate at w x h (exact: must get that size),
 * map the buffers. On failure nothing stays open. */
static hal_status_t connect_device(hal_camera_v4l2_t *c, uint32_t *w, uint32_t *h, bool exact)
{
    int fd;
    do {
        fd = v4l2_sys_open(c->path, O_RDWR | O_NONBLOCK | O_CLOEXEC);
    } while (fd < 0 && errno == EINTR);
    if (fd < 0) return errno_status(errno);
    c->fd = fd;
    hal_status_t st = negotiate(c, w, h, exact);
    if (st == HAL_OK) {
        const size_t min_len =
            c->in_fourcc == V4L2_PIX_FMT_YUYV ? (size_t)c->in_stride_bytes * (size_t)*h : (size_t)1u;
        st = map_buffers(c, min_len);
    }
    if (st != HAL_OK) disconnect(c);
    return st;
}

/* Queue every buffer and start the stream. Returns HAL_OK or the mapped
 * errno status; *gone set when the device has disappeared. */
static hal_status_t stream_on(hal_camera_v4l2_t *c, bool *gone)
{
    *gone = false;
    int e = 0;
    for (uint32_t i = 0; i < c->n_bufs && e == 0; ++i) {
        struct v4l2_buffer b;
        memset(&b, 0, sizeof b);
        b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        b.memory = V4L2_MEMORY_MMAP;
        b.index = i;
        if (xioctl(c, VIDIOC_QBUF, &b) != 0) e = errno;
    }
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (e == 0 && xioctl(c, VIDIOC_STREAMON, &type) != 0) e = errno;
    if (e != 0) {
        (void)xioctl(c, VIDIOC_STREAMOFF, &type); /* gives queued buffers back */
        *gone = gone_errno(e);
        return e == EBUSY ? HAL_E_BUSY : HAL_E_IO;
    }
    c->stream_on = true;
    c->held = -1;
    /* The next frame continues the reported sequence (set at the first
     * dequeue of this session: drivers count from 0 at STREAMON, or not). */
    c->seq_rebase = true;
    return HAL_OK;
}

static void go_lost(hal_camera_v4l2_t *c, int e)
{
    c->counters.disconnects++;
    say(c, "device lost (%s): reopening every %u ms", strerror(e), (unsigned)(c->cfg.reopen_period_us / 1000u));
    c->lost = true; /* before disconnect: no STREAMOFF on a dead device */
    disconnect(c);
    c->refusal_logged = false;
    c->next_reopen_us = v4l2_sys_now_us() + c->cfg.reopen_period_us;
}

/* A failed system call during streaming: the device is lost, or an I/O
 * error. Returns HAL_E_IO either way. */
static hal_status_t stream_failure(hal_camera_v4l2_t *c, int e)
{
    if (gone_errno(e)) {
        go_lost(c, e);
    } else {
        c->counters.io_errors++;
    }
    return HAL_E_IO;
}

/* Try to get the device back (at most once per reopen period unless
 * forced); streaming resumes if it was on. */
static void try_reopen(hal_camera_v4l2_t *c, bool force)
{
    const uint64_t now = v4l2_sys_now_us();
    if (!force && now < c->next_reopen_us) return;
    c->next_reopen_us = now + c->cfg.reopen_period_us;
    c->counters.reopen_attempts++;
    uint32_t w = c->fmt.width_px;
    uint32_t h = c->fmt.height_px;
    hal_status_t st = connect_device(c, &w, &h, true);
    if (st == HAL_OK && c->want_stream) {
        bool gone = false;
        st = stream_on(c, &gone);
        if (st != HAL_OK) disconnect(c);
    }
    if (st != HAL_OK) {
        if (st == HAL_E_UNSUPPORTED && !c->refusal_logged) {
            say(c, "device back but not at %ux%u in an accepted format: not used", (unsigned)c->fmt.width_px,
                (unsigned)c->fmt.height_px);
            c->refusal_logged = true;
        }
        return;
    }
    c->lost = false;
    c->counters.reopens++;
    say(c, "device reopened");
}

static hal_status_t requeue(hal_camera_v4l2_t *c, uint32_t index)
{
    struct v4l2_buffer b;
    memset(&b, 0, sizeof b);
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = index;
    if (xioctl(c, VIDIOC_QBUF, &b) != 0) return stream_failure(c, errno);
    return HAL_OK;
}

/* ------------------------------------------------------------------------ */
/* frames                                                                   */
/* ------------------------------------------------------------------------ */

/* Dequeue every finished buffer; keep the newest good one in c->held. */
static hal_status_t drain(hal_camera_v4l2_t *c)
{
    for (;;) {
        struct v4l2_buffer b;
        memset(&b, 0, sizeof b);
        b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        b.memory = V4L2_MEMORY_MMAP;
        if (xioctl(c, VIDIOC_DQBUF, &b) != 0) {
            if (errno == EAGAIN) return HAL_OK; /* nothing more finished */
            return stream_failure(c, errno);
        }
        if (b.index >= c->n_bufs) { /* never queued by us: a driver bug */
            c->counters.io_errors++;
            return HAL_E_IO;
        }
        if (c->seq_rebase) {
            c->seq_base = c->next_seq - b.sequence;
            c->seq_rebase = false;
        }
        const uint32_t seq = c->seq_base + b.sequence;
        c->next_seq = seq + 1u;
        if ((b.flags & V4L2_BUF_FLAG_ERROR) != 0u || b.bytesused == 0u) {
            c->counters.buffer_errors++;
            const hal_status_t st = requeue(c, b.index);
            if (st != HAL_OK) return st;
            continue;
        }
        if (c->held >= 0) {
            c->counters.frames_skipped++;
            const hal_status_t st = requeue(c, (uint32_t)c->held);
            c->held = -1;
            if (st != HAL_OK) return st;
        }
        c->held = (int)b.index;
        c->held_bytes = b.bytesused < c->bufs[b.index].length ? b.bytesused : (uint32_t)c->bufs[b.index].length;
        c->held_info.len = c->fmt.frame_bytes;
        c->held_info.sequence = seq;
        /* MONOTONIC stamps share hal_clock_linux's base; others (UNKNOWN,
         * COPY: not a capture time) are replaced by the dequeue time. */
        const uint64_t t = timeval_us(&b.timestamp);
        const bool mono = (b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
        c->held_info.stamp_us = (mono && t != 0u) ? t : v4l2_sys_now_us();
    }
}

/* Convert the held frame into buf and give its buffer back. HAL_E_CORRUPT:
 * dropped (counted); HAL_E_IO: the re-queue failed, the frame in buf is
 * still good but the device is lost. */
static hal_status_t deliver(hal_camera_v4l2_t *c, uint8_t *buf)
{
    const uint32_t index = (uint32_t)c->held;
    const uint8_t *src = (const uint8_t *)c->bufs[index].start;
    const size_t n = c->held_bytes;
    const uint32_t w = c->fmt.width_px;
    const uint32_t h = c->fmt.height_px;
    hal_status_t st = HAL_OK;
    if (c->in_fourcc == V4L2_PIX_FMT_YUYV) {
        const size_t need = (size_t)c->in_stride_bytes * (h - 1u) + (size_t)w * 2u;
        if (n < need) {
            c->counters.bad_size_frames++;
            st = HAL_E_CORRUPT;
        } else if (c->fmt.pixfmt == HAL_CAMERA_PIX_RGB24) {
            hal_camera_v4l2_yuyv_to_rgb24(src, c->in_stride_bytes, buf, c->fmt.stride_bytes, w, h, c->in_full_range);
        } else {
            for (uint32_t y = 0; y < h; ++y) {
                memcpy(buf + (size_t)y * c->fmt.stride_bytes, src + (size_t)y * c->in_stride_bytes, (size_t)w * 2u);
            }
        }
    } else {
        int jw = 0;
        int jh = 0;
        int subsamp = 0;
        int colorspace = 0;
        /* TurboJPEG's API takes non-const handles and sources. */
        unsigned char *jpeg = (unsigned char *)(uintptr_t)src;
        if (tjDecompressHeader3(c->tj, jpeg, (unsigned long)n, &jw, &jh, &subsamp, &colorspace) != 0) {
            c->counters.corrupt_frames++;
            st = HAL_E_CORRUPT;
        } else if ((uint32_t)jw != w || (uint32_t)jh != h) {
            c->counters.bad_size_frames++;
            st = HAL_E_CORRUPT;
        } else if (tjDecompress2(c->tj, jpeg, (unsigned long)n, buf, (int)w, (int)c->fmt.stride_bytes, (int)h, TJPF_RGB,
                                 TJ_FLAGS) != 0) {
            c->counters.corrupt_frames++;
            st = HAL_E_CORRUPT;
        }
    }
    c->held = -1;
    const hal_status_t q = requeue(c, index);
    if (st == HAL_OK && q != HAL_OK) return HAL_E_IO;
    return st;
}

/* Wait for the descriptor until deadline_us (UINT64_MAX: forever).
 * HAL_OK: something may be ready; HAL_E_TIMEOUT; HAL_E_IO: device lost. */
static hal_status_t wait_ready(hal_camera_v4l2_t *c, uint64_t now_us, uint64_t deadline_us)
{
    int ms = -1;
    if (deadline_us != UINT64_MAX) {
        const uint64_t left_ms = (deadline_us - now_us + 999u) / 1000u;
        ms = left_ms > (uint64_t)INT32_MAX ? INT32_MAX : (int)left_ms;
    }
    struct pollfd p;
    p.fd = c->fd;
    p.events = POLLIN;
    p.revents = 0;
    const int r = v4l2_sys_poll(&p, 1, ms);
    if (r < 0) {
        if (errno == EINTR) {
            c->counters.eintr_retries++;
            return HAL_OK;
        }
        return stream_failure(c, errno);
    }
    if (r == 0) return HAL_E_TIMEOUT;
    if ((p.revents & POLLIN) == 0 && (p.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
        /* Streaming with buffers queued, vb2 reports POLLERR only for a
         * queue in error: the device went away. */
        go_lost(c, ENODEV);
        return HAL_E_IO;
    }
    return HAL_OK;
}

/* ------------------------------------------------------------------------ */
/* ops                                                                      */
/* ------------------------------------------------------------------------ */

static hal_status_t v_get_format(hal_camera_t *dev, hal_camera_format_t *fmt)
{
    const hal_camera_v4l2_t *c = (const hal_camera_v4l2_t *)dev->backend;
    if (!c->is_open) return HAL_E_CLOSED;
    *fmt = c->fmt;
    return HAL_OK;
}

static hal_status_t v_start(hal_camera_t *dev)
{
    hal_camera_v4l2_t *c = (hal_camera_v4l2_t *)dev->backend;
    if (!c->is_open) return HAL_E_CLOSED;
    if (c->want_stream) return HAL_OK;
    if (c->lost) {
        try_reopen(c, true);
        if (c->lost) return HAL_E_IO;
    }
    bool gone = false;
    const hal_status_t st = stream_on(c, &gone);
    if (st != HAL_OK) {
        if (gone) {
            go_lost(c, ENODEV);
        } else if (st == HAL_E_IO) {
            c->counters.io_errors++;
        }
        return st;
    }
    c->want_stream = true;
    return HAL_OK;
}

static hal_status_t v_stop(hal_camera_t *dev)
{
    hal_camera_v4l2_t *c = (hal_camera_v4l2_t *)dev->backend;
    if (!c->is_open) return HAL_E_CLOSED;
    c->want_stream = false;
    c->held = -1;
    if (!c->stream_on || c->lost) return HAL_OK;
    c->stream_on = false;
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(c, VIDIOC_STREAMOFF, &type) != 0) {
        if (gone_errno(errno)) {
            go_lost(c, errno);
            return HAL_OK; /* a device that went away is stopped */
        }
        c->counters.io_errors++;
        return HAL_E_IO;
    }
    return HAL_OK;
}

static hal_status_t v_grab(hal_camera_t *dev, uint8_t *buf, size_t cap, hal_camera_frame_info_t *info,
                           uint32_t timeout_us)
{
    hal_camera_v4l2_t *c = (hal_camera_v4l2_t *)dev->backend;
    if (!c->is_open || !c->want_stream) return HAL_E_CLOSED;
    if (c->lost) {
        try_reopen(c, false);
        if (c->lost) return HAL_E_IO;
    }
    const uint64_t t0 = v4l2_sys_now_us();
    const uint64_t deadline = timeout_us == HAL_TIMEOUT_FOREVER ? UINT64_MAX : t0 + timeout_us;
    for (;;) {
        hal_status_t st = drain(c);
        if (st != HAL_OK) return st;
        if (c->held >= 0) {
            if (cap < c->fmt.frame_bytes) {
                *info = c->held_info; /* the frame stays held for the next grab */
                return HAL_E_OVERFLOW;
            }
            const hal_camera_frame_info_t fi = c->held_info;
            st = deliver(c, buf);
            if (st == HAL_OK || st == HAL_E_IO) {
                /* On HAL_E_IO the frame is good but its re-queue failed:
                 * return it; the loss shows at the next call. */
                *info = fi;
                c->counters.frames++;
                return HAL_OK;
            }
            /* dropped (HAL_E_CORRUPT): wait for the next one */
        }
        const uint64_t now = v4l2_sys_now_us();
        if (now >= deadline) {
            c->counters.timeouts++;
            return HAL_E_TIMEOUT;
        }
        st = wait_ready(c, now, deadline);
        if (st == HAL_E_IO) return st;
    }
}

static void v_close(hal_camera_t *dev)
{
    hal_camera_v4l2_t *c = (hal_camera_v4l2_t *)dev->backend;
    if (!c->is_open) return;
    disconnect(c);
    if (c->tj != NULL) (void)tjDestroy(c->tj);
    c->tj = NULL;
    c->is_open = false;
    c->want_stream = false;
    c->lost = false;
}

static const hal_camera_ops_t v4l2_ops = {v_get_format, v_start, v_stop, v_grab, v_close};

/* ------------------------------------------------------------------------ */
/* public                                                                   */
/* ------------------------------------------------------------------------ */

static hal_status_t apply_config(hal_camera_v4l2_t *c, const hal_camera_v4l2_config_t *cfg)
{
    if (cfg->device == NULL) return HAL_E_ARG;
    const size_t len = strlen(cfg->device);
    if (len == 0u || len > HAL_CAMERA_V4L2_PATH_MAX) return HAL_E_ARG;
    memcpy(c->path, cfg->device, len + 1u);
    c->cfg = *cfg;
    c->cfg.device = c->path;
    if (c->cfg.width_px == 0u) c->cfg.width_px = HAL_CAMERA_V4L2_DEFAULT_WIDTH_PX;
    if (c->cfg.height_px == 0u) c->cfg.height_px = HAL_CAMERA_V4L2_DEFAULT_HEIGHT_PX;
    if (c->cfg.width_px > MAX_SIDE_PX || c->cfg.height_px > MAX_SIDE_PX) return HAL_E_ARG;
    if (c->cfg.buffer_count == 0u) c->cfg.buffer_count = HAL_CAMERA_V4L2_DEFAULT_BUFFERS;
    if (c->cfg.buffer_count < 2u || c->cfg.buffer_count > HAL_CAMERA_V4L2_MAX_BUFFERS) return HAL_E_ARG;
    if ((int)c->cfg.output == 0) c->cfg.output = HAL_CAMERA_PIX_RGB24;
    if (c->cfg.output != HAL_CAMERA_PIX_RGB24 && c->cfg.output != HAL_CAMERA_PIX_YUYV) return HAL_E_ARG;
    if (c->cfg.reopen_period_us == 0u) c->cfg.reopen_period_us = HAL_CAMERA_V4L2_DEFAULT_REOPEN_US;
    if (c->cfg.inputs[0] == HAL_CAMERA_V4L2_IN_NONE) {
        c->cfg.inputs[0] = HAL_CAMERA_V4L2_IN_YUYV;
        c->cfg.inputs[1] = HAL_CAMERA_V4L2_IN_MJPEG;
    }
    for (uint32_t i = 0; i < HAL_CAMERA_V4L2_MAX_INPUTS; ++i) {
        const hal_camera_v4l2_input_t in = c->cfg.inputs[i];
        if (in != HAL_CAMERA_V4L2_IN_NONE && in != HAL_CAMERA_V4L2_IN_YUYV && in != HAL_CAMERA_V4L2_IN_MJPEG) {
            return HAL_E_ARG;
        }
    }
    return HAL_OK;
}

static bool may_decode_mjpeg(const hal_camera_v4l2_t *c)
{
    if (c->cfg.output != HAL_CAMERA_PIX_RGB24) return false;
    for (uint32_t i = 0; i < HAL_CAMERA_V4L2_MAX_INPUTS && c->cfg.inputs[i] != HAL_CAMERA_V4L2_IN_NONE; ++i) {
        if (c->cfg.inputs[i] == HAL_CAMERA_V4L2_IN_MJPEG) return true;
    }
    return false;
}

hal_camera_t *hal_camera_v4l2_open(const hal_camera_v4l2_config_t *cfg, hal_camera_v4l2_t *cam)
{
    if (cam == NULL) return NULL;
    memset(cam, 0, sizeof *cam);
    cam->fd = -1;
    cam->held = -1;
    hal_status_t st = cfg != NULL ? apply_config(cam, cfg) : HAL_E_ARG;
    uint32_t w = cam->cfg.width_px;
    uint32_t h = cam->cfg.height_px;
    if (st == HAL_OK && may_decode_mjpeg(cam)) {
        cam->tj = tjInitDecompress();
        if (cam->tj == NULL) st = HAL_E_IO;
    }
    if (st == HAL_OK) st = connect_device(cam, &w, &h, false);
    if (st != HAL_OK) {
        if (cam->tj != NULL) (void)tjDestroy(cam->tj);
        cam->tj = NULL;
        cam->open_status = st;
        return NULL;
    }
    cam->fmt.width_px = w;
    cam->fmt.height_px = h;
    cam->fmt.pixfmt = cam->cfg.output;
    cam->fmt.stride_bytes = (uint32_t)hal_camera_row_bytes(cam->cfg.output, w);
    cam->fmt.frame_bytes = (size_t)cam->fmt.stride_bytes * h;
    if (w != cam->cfg.width_px || h != cam->cfg.height_px) {
        say(cam, "asked %ux%u, the driver gives %ux%u: frames are %ux%u", (unsigned)cam->cfg.width_px,
            (unsigned)cam->cfg.height_px, (unsigned)w, (unsigned)h, (unsigned)w, (unsigned)h);
    }
    cam->dev.ops = &v4l2_ops;
    cam->dev.backend = cam;
    cam->is_open = true;
    cam->open_status = HAL_OK;
    return &cam->dev;
}

hal_status_t hal_camera_v4l2_get_counters(const hal_camera_v4l2_t *cam, hal_camera_v4l2_counters_t *out)
{
    if (cam == NULL || out == NULL) return HAL_E_ARG;
    *out = cam->counters;
    return HAL_OK;
}

bool hal_camera_v4l2_connected(const hal_camera_v4l2_t *cam)
{
    return cam != NULL && cam->is_open && !cam->lost && cam->fd >= 0;
}
