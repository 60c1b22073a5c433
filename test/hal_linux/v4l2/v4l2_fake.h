/*
 * v4l2_fake.h - an in-memory V4L2 capture driver behind the V4L2 camera
 * backend's system-call seam (hal/linux/v4l2/hal_camera_v4l2_sys.h): the
 * tests link v4l2_fake.c instead of hal_camera_v4l2_sys.c, so the real
 * backend code runs against it without a device.
 *
 * What it models (as videobuf2 + uvcvideo behave):
 *  - one device node: present or not (open: ENOENT), one opener at a time
 *    (EBUSY); QUERYCAP with configurable capabilities; ENUM_FMT over a
 *    configurable list; S_FMT/G_FMT that substitutes the first listed
 *    format for an unlisted one, honours or overrides the size (a driver
 *    that changes the size), pads YUYV rows, reports the quantization;
 *  - REQBUFS (raised to min_buffers), QUERYBUF, mmap of static memory,
 *    QBUF/DQBUF with a FIFO of queued and of finished buffers, DQBUF
 *    EAGAIN when none is finished, STREAMON (frame counter to 0) and
 *    STREAMOFF (all buffers back to the application);
 *  - frames pushed by the test fill the oldest queued buffer with the
 *    given bytes, stamp and flags; with none queued the frame is dropped
 *    but still counted in `sequence` (a gap), as uvcvideo does;
 *  - poll: POLLIN when a buffer is finished, POLLERR when not streaming or
 *    after an unplug; a poll with nothing ready consumes its timeout of
 *    fake CLOCK_MONOTONIC time (now_us) and returns 0;
 *  - unplug: the open descriptor's ioctls fail ENODEV, poll reports
 *    POLLERR|POLLHUP, the node is gone; replug brings a fresh device
 *    (same description) under a new descriptor number;
 *  - faults: EINTR on the next n polls / DQBUFs / opens, spurious POLLIN,
 *    EBUSY on S_FMT, an on_poll hook that runs at every poll (push a frame
 *    or unplug "while the backend waits").
 * Not thread-safe; one global device (tests reset it).
 */
#ifndef COSLAM_V4L2_FAKE_H
#define COSLAM_V4L2_FAKE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FAKE_V4L2_MAX_BUFS 16u
#define FAKE_V4L2_MAX_FORMATS 4u
#define FAKE_V4L2_BUF_BYTES (640u * 480u * 2u)
#define FAKE_V4L2_MAX_SIDE_PX 640u

typedef struct {
    /* --- the device, set by the test (reset: a YUYV+MJPEG webcam) ------ */
    bool present;                        /**< the node exists */
    uint32_t device_caps;                /**< V4L2_CAP_* */
    uint32_t formats[FAKE_V4L2_MAX_FORMATS];
    unsigned n_formats;
    uint32_t force_width, force_height;  /**< != 0: S_FMT gives this size whatever is asked */
    uint32_t row_pad_bytes;              /**< extra bytes per YUYV row (bytesperline) */
    uint32_t quantization;               /**< V4L2_QUANTIZATION_* reported by G_FMT */
    uint32_t min_buffers;                /**< REQBUFS grants at least this many */
    uint32_t ts_flags;                   /**< timestamp type/source flags of every buffer */
    /* --- faults ---------------------------------------------------------- */
    int open_errno;                      /**< open fails with this (0: none) */
    unsigned open_eintr;                 /**< the next n opens fail EINTR */
    unsigned poll_eintr;                 /**< the next n polls fail EINTR */
    unsigned dqbuf_eintr;                /**< the next n DQBUFs fail EINTR */
    unsigned spurious_pollin;            /**< the next n polls say POLLIN with nothing finished */
    int s_fmt_errno;                     /**< S_FMT fails with this (0: none) */
    void (*on_poll)(void *ctx);          /**< runs at the start of every poll */
    void *on_poll_ctx;
    /* --- driver state ---------------------------------------------------- */
    uint64_t now_us;                     /**< fake CLOCK_MONOTONIC */
    int live_fd;                         /**< the open descriptor, -1 none */
    int dead_fd;                         /**< a descriptor left open across an unplug, -1 none */
    int next_fd;
    uint32_t fourcc, width, height, bytesperline, sizeimage;
    bool fmt_set;
    unsigned n_bufs;
    bool streaming;
    uint32_t sequence;                   /**< frames captured this session */
    struct {
        int state;                       /**< 0 application, 1 queued, 2 finished */
        uint32_t bytesused, flags, sequence;
        uint64_t stamp_us;
        bool mapped;
    } bufs[FAKE_V4L2_MAX_BUFS];
    unsigned queued[FAKE_V4L2_MAX_BUFS], n_queued;    /**< FIFO of queued indices */
    unsigned done[FAKE_V4L2_MAX_BUFS], n_done;        /**< FIFO of finished indices */
    /* --- observations ---------------------------------------------------- */
    unsigned n_open, n_close, n_poll, n_mmap, n_munmap, n_streamon, n_streamoff, n_s_fmt, n_reqbufs;
    unsigned n_dqbuf;
    int live_mmaps;                      /**< mmaps not yet unmapped */
    int open_flags;                      /**< flags of the last open */
    int last_poll_timeout_ms;
    uint32_t requested_width, requested_height, requested_fourcc, requested_count;
    unsigned frames_dropped;             /**< pushed frames that found no queued buffer */
    unsigned unknown_ioctls;
} fake_v4l2_t;

extern fake_v4l2_t fake_v4l2;

/** Reset to a present, closed 640x480-max webcam offering YUYV then MJPEG,
 *  capture + streaming, limited range, MONOTONIC|SOE stamps, time 1 s. */
void fake_v4l2_reset(void);

/** The camera captures a frame of `len` bytes (<= the buffer length):
 *  returns true if it went into a buffer (streaming and one queued).
 *  flags are ORed into the buffer's (e.g. V4L2_BUF_FLAG_ERROR). */
bool fake_v4l2_push(const uint8_t *data, size_t len, uint64_t stamp_us, uint32_t flags);

/** Unplug: the node goes, the open descriptor dies (ENODEV, POLLERR). */
void fake_v4l2_unplug(void);
/** Plug the same device back (a fresh driver state). */
void fake_v4l2_replug(void);

/** Memory behind buffer i (for white-box checks). */
uint8_t *fake_v4l2_buffer_mem(unsigned i);

#ifdef __cplusplus
}
#endif

#endif
