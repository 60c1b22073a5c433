/* In-memory V4L2 capture driver behind the backend's seam (v4l2_fake.h). */
#include "v4l2_fake.h"

#include <errno.h>
#include <linux/videodev2.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "hal_camera_v4l2_sys.h"

fake_v4l2_t fake_v4l2;

static uint8_t fake_mem[FAKE_V4L2_MAX_BUFS][FAKE_V4L2_BUF_BYTES];

/* mmap offsets: page-aligned, one slot per buffer */
#define OFFSET_STRIDE 0x100000u

static void driver_reset(void)
{
    fake_v4l2_t *f = &fake_v4l2;
    f->fmt_set = false;
    f->n_bufs = 0;
    f->streaming = false;
    f->sequence = 0;
    f->n_queued = 0;
    f->n_done = 0;
    memset(f->bufs, 0, sizeof f->bufs);
}

void fake_v4l2_reset(void)
{
    memset(&fake_v4l2, 0, sizeof fake_v4l2);
    fake_v4l2_t *f = &fake_v4l2;
    f->present = true;
    f->device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
    f->formats[0] = V4L2_PIX_FMT_YUYV;
    f->formats[1] = V4L2_PIX_FMT_MJPEG;
    f->n_formats = 2;
    f->quantization = V4L2_QUANTIZATION_LIM_RANGE;
    f->min_buffers = 2;
    f->ts_flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
    f->now_us = 1000000u;
    f->live_fd = -1;
    f->dead_fd = -1;
    f->next_fd = 40;
    driver_reset();
}

uint8_t *fake_v4l2_buffer_mem(unsigned i)
{
    return fake_mem[i];
}

bool fake_v4l2_push(const uint8_t *data, size_t len, uint64_t stamp_us, uint32_t flags)
{
    fake_v4l2_t *f = &fake_v4l2;
    if (!f->streaming || f->live_fd < 0) return false;
    const uint32_t seq = f->sequence++;
    if (f->n_queued == 0) {
        f->frames_dropped++;
        return false;
    }
    if (len > f->sizeimage || len > FAKE_V4L2_BUF_BYTES) {
        fprintf(stderr, "v4l2_fake: frame of %zu bytes > buffer %u\n", len, (unsigned)f->sizeimage);
        abort();
    }
    const unsigned i = f->queued[0];
    memmove(&f->queued[0], &f->queued[1], (f->n_queued - 1u) * sizeof f->queued[0]);
    f->n_queued--;
    memcpy(fake_mem[i], data, len);
    f->bufs[i].state = 2;
    f->bufs[i].bytesused = (uint32_t)len;
    f->bufs[i].flags = f->ts_flags | flags;
    f->bufs[i].sequence = seq;
    f->bufs[i].stamp_us = stamp_us;
    f->done[f->n_done++] = i;
    return true;
}

void fake_v4l2_unplug(void)
{
    fake_v4l2_t *f = &fake_v4l2;
    f->present = false;
    if (f->live_fd >= 0) f->dead_fd = f->live_fd;
    f->live_fd = -1;
    driver_reset();
}

void fake_v4l2_replug(void)
{
    fake_v4l2.present = true;
    driver_reset();
}

/* ---- the seam ------------------------------------------------------------ */

int v4l2_sys_open(const char *path, int flags)
{
    fake_v4l2_t *f = &fake_v4l2;
    (void)path;
    f->n_open++;
    f->open_flags = flags;
    if (f->open_eintr > 0) {
        f->open_eintr--;
        errno = EINTR;
        return -1;
    }
    if (f->open_errno != 0) {
        errno = f->open_errno;
        return -1;
    }
    if (!f->present) {
        errno = ENOENT;
        return -1;
    }
    if (f->live_fd >= 0) {
        errno = EBUSY;
        return -1;
    }
    driver_reset();
    f->live_fd = f->next_fd++;
    return f->live_fd;
}

int v4l2_sys_close(int fd)
{
    fake_v4l2_t *f = &fake_v4l2;
    f->n_close++;
    if (fd == f->dead_fd) {
        f->dead_fd = -1;
        return 0;
    }
    if (fd != f->live_fd || fd < 0) {
        errno = EBADF;
        return -1;
    }
    f->live_fd = -1;
    driver_reset(); /* the kernel frees the queue with the last descriptor */
    return 0;
}

static bool listed(uint32_t fourcc)
{
    for (unsigned i = 0; i < fake_v4l2.n_formats; ++i) {
        if (fake_v4l2.formats[i] == fourcc) return true;
    }
    return false;
}

static void fill_fmt(struct v4l2_format *fmt)
{
    const fake_v4l2_t *f = &fake_v4l2;
    memset(&fmt->fmt, 0, sizeof fmt->fmt);
    fmt->fmt.pix.width = f->width;
    fmt->fmt.pix.height = f->height;
    fmt->fmt.pix.pixelformat = f->fourcc;
    fmt->fmt.pix.field = V4L2_FIELD_NONE;
    fmt->fmt.pix.bytesperline = f->bytesperline;
    fmt->fmt.pix.sizeimage = f->sizeimage;
    fmt->fmt.pix.colorspace = V4L2_COLORSPACE_SRGB;
    fmt->fmt.pix.priv = V4L2_PIX_FMT_PRIV_MAGIC;
    fmt->fmt.pix.quantization = f->quantization;
}

static int fail(int e)
{
    errno = e;
    return -1;
}

static void to_app(void)
{
    fake_v4l2_t *f = &fake_v4l2;
    for (unsigned i = 0; i < f->n_bufs; ++i) f->bufs[i].state = 0;
    f->n_queued = 0;
    f->n_done = 0;
}

int v4l2_sys_ioctl(int fd, unsigned long request, void *arg)
{
    fake_v4l2_t *f = &fake_v4l2;
    if (fd == f->dead_fd && fd >= 0) return fail(ENODEV);
    if (fd != f->live_fd || fd < 0) return fail(EBADF);
    switch (request) {
    case VIDIOC_QUERYCAP: {
        struct v4l2_capability *c = arg;
        memset(c, 0, sizeof *c);
        strcpy((char *)c->driver, "v4l2_fake");
        strcpy((char *)c->card, "Fake webcam");
        c->device_caps = f->device_caps;
        c->capabilities = f->device_caps | V4L2_CAP_DEVICE_CAPS;
        return 0;
    }
    case VIDIOC_ENUM_FMT: {
        struct v4l2_fmtdesc *d = arg;
        if (d->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || d->index >= f->n_formats) return fail(EINVAL);
        d->pixelformat = f->formats[d->index];
        d->flags = d->pixelformat == V4L2_PIX_FMT_MJPEG ? V4L2_FMT_FLAG_COMPRESSED : 0u;
        return 0;
    }
    case VIDIOC_S_FMT: {
        struct v4l2_format *fmt = arg;
        f->n_s_fmt++;
        if (fmt->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
        if (f->s_fmt_errno != 0) return fail(f->s_fmt_errno);
        if (f->streaming || f->n_bufs > 0) return fail(EBUSY);
        f->requested_width = fmt->fmt.pix.width;
        f->requested_height = fmt->fmt.pix.height;
        f->requested_fourcc = fmt->fmt.pix.pixelformat;
        f->fourcc = listed(fmt->fmt.pix.pixelformat) ? fmt->fmt.pix.pixelformat : f->formats[0];
        uint32_t w = f->force_width != 0u ? f->force_width : fmt->fmt.pix.width;
        uint32_t h = f->force_height != 0u ? f->force_height : fmt->fmt.pix.height;
        if (w > FAKE_V4L2_MAX_SIDE_PX) w = FAKE_V4L2_MAX_SIDE_PX;
        if (h > FAKE_V4L2_MAX_SIDE_PX * 3u / 4u) h = FAKE_V4L2_MAX_SIDE_PX * 3u / 4u;
        if (w < 2u) w = 2u;
        if (h < 1u) h = 1u;
        if (f->fourcc == V4L2_PIX_FMT_YUYV) w &= ~1u;
        f->width = w;
        f->height = h;
        if (f->fourcc == V4L2_PIX_FMT_YUYV) {
            f->bytesperline = w * 2u + f->row_pad_bytes;
            f->sizeimage = f->bytesperline * h;
        } else {
            f->bytesperline = 0;
            f->sizeimage = w * h * 2u;
        }
        if (f->sizeimage > FAKE_V4L2_BUF_BYTES) f->sizeimage = FAKE_V4L2_BUF_BYTES;
        f->fmt_set = true;
        fill_fmt(fmt);
        return 0;
    }
    case VIDIOC_G_FMT: {
        struct v4l2_format *fmt = arg;
        if (fmt->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || !f->fmt_set) return fail(EINVAL);
        fill_fmt(fmt);
        return 0;
    }
    case VIDIOC_REQBUFS: {
        struct v4l2_requestbuffers *rb = arg;
        f->n_reqbufs++;
        f->requested_count = rb->count;
        if (rb->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || rb->memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
        if (f->streaming) return fail(EBUSY);
        if (rb->count == 0) {
            f->n_bufs = 0;
            return 0;
        }
        uint32_t n = rb->count < f->min_buffers ? f->min_buffers : rb->count;
        if (n > FAKE_V4L2_MAX_BUFS) n = FAKE_V4L2_MAX_BUFS;
        f->n_bufs = n;
        memset(f->bufs, 0, sizeof f->bufs);
        rb->count = n;
        return 0;
    }
    case VIDIOC_QUERYBUF: {
        struct v4l2_buffer *b = arg;
        if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->index >= f->n_bufs) return fail(EINVAL);
        b->length = f->sizeimage;
        b->m.offset = b->index * OFFSET_STRIDE;
        b->memory = V4L2_MEMORY_MMAP;
        b->flags = f->bufs[b->index].mapped ? V4L2_BUF_FLAG_MAPPED : 0u;
        return 0;
    }
    case VIDIOC_QBUF: {
        struct v4l2_buffer *b = arg;
        if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP || b->index >= f->n_bufs) {
            return fail(EINVAL);
        }
        if (f->bufs[b->index].state != 0) return fail(EINVAL); /* already queued */
        f->bufs[b->index].state = 1;
        f->queued[f->n_queued++] = b->index;
        return 0;
    }
    case VIDIOC_DQBUF: {
        struct v4l2_buffer *b = arg;
        f->n_dqbuf++;
        if (f->dqbuf_eintr > 0) {
            f->dqbuf_eintr--;
            return fail(EINTR);
        }
        if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
        if (!f->streaming) return fail(EINVAL);
        if (f->n_done == 0) return fail(EAGAIN);
        const unsigned i = f->done[0];
        memmove(&f->done[0], &f->done[1], (f->n_done - 1u) * sizeof f->done[0]);
        f->n_done--;
        f->bufs[i].state = 0;
        b->index = i;
        b->bytesused = f->bufs[i].bytesused;
        b->flags = f->bufs[i].flags | V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_DONE;
        b->field = V4L2_FIELD_NONE;
        b->timestamp.tv_sec = (time_t)(f->bufs[i].stamp_us / 1000000u);
        b->timestamp.tv_usec = (suseconds_t)(f->bufs[i].stamp_us % 1000000u);
        b->sequence = f->bufs[i].sequence;
        b->length = f->sizeimage;
        b->m.offset = i * OFFSET_STRIDE;
        return 0;
    }
    case VIDIOC_STREAMON: {
        const int *type = arg;
        if (*type != V4L2_BUF_TYPE_VIDEO_CAPTURE || f->n_bufs == 0) return fail(EINVAL);
        f->n_streamon++;
        if (!f->streaming) f->sequence = 0;
        f->streaming = true;
        return 0;
    }
    case VIDIOC_STREAMOFF: {
        const int *type = arg;
        if (*type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
        f->n_streamoff++;
        f->streaming = false;
        to_app();
        return 0;
    }
    default:
        f->unknown_ioctls++;
        return fail(ENOTTY);
    }
}

void *v4l2_sys_mmap(size_t length, int prot, int flags, int fd, off_t offset)
{
    fake_v4l2_t *f = &fake_v4l2;
    (void)prot;
    if (fd != f->live_fd || fd < 0 || (flags & MAP_SHARED) == 0) {
        errno = EINVAL;
        return MAP_FAILED;
    }
    const unsigned i = (unsigned)((uint64_t)offset / OFFSET_STRIDE);
    if ((uint64_t)offset % OFFSET_STRIDE != 0u || i >= f->n_bufs || length > FAKE_V4L2_BUF_BYTES) {
        errno = EINVAL;
        return MAP_FAILED;
    }
    f->n_mmap++;
    f->live_mmaps++;
    f->bufs[i].mapped = true;
    return fake_mem[i];
}

int v4l2_sys_munmap(void *addr, size_t length)
{
    fake_v4l2_t *f = &fake_v4l2;
    (void)length;
    for (unsigned i = 0; i < FAKE_V4L2_MAX_BUFS; ++i) {
        if (addr == (void *)fake_mem[i]) {
            f->n_munmap++;
            f->live_mmaps--;
            f->bufs[i].mapped = false;
            return 0;
        }
    }
    errno = EINVAL;
    return -1;
}

int v4l2_sys_poll(struct pollfd *fds, nfds_t nfds, int timeout_ms)
{
    fake_v4l2_t *f = &fake_v4l2;
    f->n_poll++;
    f->last_poll_timeout_ms = timeout_ms;
    if (f->on_poll != NULL) f->on_poll(f->on_poll_ctx);
    if (nfds != 1) return fail(EINVAL);
    fds[0].revents = 0;
    if (f->poll_eintr > 0) {
        f->poll_eintr--;
        return fail(EINTR);
    }
    if (fds[0].fd == f->dead_fd && fds[0].fd >= 0) {
        fds[0].revents = POLLERR | POLLHUP;
        return 1;
    }
    if (fds[0].fd != f->live_fd || fds[0].fd < 0) {
        fds[0].revents = POLLNVAL;
        return 1;
    }
    if (!f->streaming) {
        fds[0].revents = POLLERR;
        return 1;
    }
    if (f->n_done > 0) {
        fds[0].revents = POLLIN | POLLRDNORM;
        return 1;
    }
    if (f->spurious_pollin > 0) {
        f->spurious_pollin--;
        fds[0].revents = POLLIN;
        return 1;
    }
    if (timeout_ms < 0) {
        fprintf(stderr, "v4l2_fake: poll would block forever (nothing will ever arrive)\n");
        abort();
    }
    f->now_us += (uint64_t)timeout_ms * 1000u;
    return 0;
}

uint64_t v4l2_sys_now_us(void)
{
    return fake_v4l2.now_us;
}
