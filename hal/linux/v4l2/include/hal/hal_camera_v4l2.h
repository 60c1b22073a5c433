/*
 * hal/hal_camera_v4l2.h - the Linux V4L2 backend of hal_camera.h (USB
 * webcams through uvcvideo, or any V4L2 single-planar capture device).
 * Kernel UAPI only (<linux/videodev2.h>, no libv4l2); MJPEG is decoded by
 * libjpeg-turbo's TurboJPEG API. docs/camera-v4l2.md has the details and
 * how it was tested.
 *
 * Behaviour behind the contract:
 *  - format: negotiated at open and then fixed. The device must offer video
 *    capture and streaming I/O (VIDIOC_QUERYCAP). The first input format of
 *    cfg->inputs that the device lists (VIDIOC_ENUM_FMT) and accepts
 *    (VIDIOC_S_FMT, read back with VIDIOC_G_FMT) is used, at the requested
 *    size. If the driver picks another size, that size is the format
 *    get_format reports (logged once). Output rows are packed
 *    (stride_bytes = width_px * bytes per pixel).
 *  - conversion: YUYV -> RGB24 in integer BT.601 (see
 *    hal_camera_v4l2_yuyv_to_rgb24), limited range unless the driver
 *    reports full range; MJPEG -> RGB24 by tjDecompress2 straight into the
 *    caller's buffer; YUYV output only from a YUYV device (copied).
 *  - streaming: mmap buffers (VIDIOC_REQBUFS/QUERYBUF, mmap) made at open;
 *    start queues them all and VIDIOC_STREAMON, stop VIDIOC_STREAMOFF.
 *  - grab: dequeues every finished buffer without blocking (the descriptor
 *    is O_NONBLOCK), keeps the newest and re-queues the others (counted in
 *    frames_skipped), then poll()s for the rest of timeout_us (rounded up
 *    to whole milliseconds) if none was ready. `sequence` is the driver's
 *    frame counter (which also counts frames the driver dropped for lack of
 *    a buffer), made monotonic across stop/start and reopens. The contents
 *    of buf are unspecified unless grab returns HAL_OK.
 *  - stamps: V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC buffer stamps are
 *    CLOCK_MONOTONIC, the time base of hal_clock_linux(), and are used as
 *    they are (start of exposure with V4L2_BUF_FLAG_TSTAMP_SRC_SOE, as
 *    uvcvideo sets, else end of frame). Any other stamp type is replaced by
 *    the dequeue time read from the same clock.
 *  - failures: EINTR is retried (counted); an empty queue (EAGAIN) and a
 *    wait that ends with no frame are HAL_E_TIMEOUT; a buffer the driver
 *    flags V4L2_BUF_FLAG_ERROR, a corrupt or wrongly sized MJPEG frame and
 *    a short YUYV frame are dropped and counted, never returned. When the
 *    device goes away (ENODEV, ENXIO, EIO, POLLERR/POLLHUP) grab returns
 *    HAL_E_IO, counts a disconnect, unmaps and closes; later calls return
 *    HAL_E_IO until a reopen succeeds. Reopens are tried from grab (and
 *    start) at most once per reopen_period_us; a reopened device must give
 *    the same output size (else it is refused and tried again later);
 *    streaming resumes by itself. The handle stays valid throughout.
 *
 * Memory: all state is in the caller-owned hal_camera_v4l2_t; the only
 * resources made at open are the mmap'd driver buffers and the TurboJPEG
 * handle (when MJPEG may be negotiated). No heap use per frame in this
 * backend (libjpeg-turbo's decoder keeps its own per-image work memory:
 * docs/camera-v4l2.md).
 *
 * Not thread-safe (HAL rule: one thread per instance). Library
 * coslam_hal_camera_v4l2 (built when libturbojpeg0-dev and linux-libc-dev
 * are installed: COSLAM_HAVE_V4L2).
 */
#ifndef HAL_CAMERA_V4L2_H
#define HAL_CAMERA_V4L2_H

#include <stdbool.h>

#include "hal/hal_camera.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Driver buffers one instance can map (REQBUFS may grant more: the
 *  extra ones are never queued). */
#ifndef HAL_CAMERA_V4L2_MAX_BUFFERS
#define HAL_CAMERA_V4L2_MAX_BUFFERS 8u
#endif
#if HAL_CAMERA_V4L2_MAX_BUFFERS < 2u || HAL_CAMERA_V4L2_MAX_BUFFERS > 32u
#error "HAL_CAMERA_V4L2_MAX_BUFFERS must be 2..32"
#endif

/** Entries of the input-format preference list. */
#define HAL_CAMERA_V4L2_MAX_INPUTS 4u
/** Longest device path [characters, without NUL]. */
#define HAL_CAMERA_V4L2_PATH_MAX 63u

/** Defaults applied to zero fields of the config. */
#define HAL_CAMERA_V4L2_DEFAULT_WIDTH_PX 320u
#define HAL_CAMERA_V4L2_DEFAULT_HEIGHT_PX 240u
#define HAL_CAMERA_V4L2_DEFAULT_BUFFERS 4u
#define HAL_CAMERA_V4L2_DEFAULT_REOPEN_US 1000000u

/** Formats accepted from the device. */
typedef enum {
    HAL_CAMERA_V4L2_IN_NONE = 0,   /**< ends the list */
    HAL_CAMERA_V4L2_IN_YUYV = 1,   /**< V4L2_PIX_FMT_YUYV (4:2:2 packed) */
    HAL_CAMERA_V4L2_IN_MJPEG = 2,  /**< V4L2_PIX_FMT_MJPEG or V4L2_PIX_FMT_JPEG */
} hal_camera_v4l2_input_t;

/** A log line (no newline); NULL sink in the config = stderr. */
typedef void (*hal_camera_v4l2_log_fn)(void *ctx, const char *line);

/** Open parameters. Zero fields take the defaults, so a zeroed struct with
 *  only `device` set opens 320x240 RGB24 from YUYV or MJPEG. */
typedef struct {
    const char *device;           /**< e.g. "/dev/video0" (copied at open) */
    uint32_t width_px;            /**< requested size; 0: 320 */
    uint32_t height_px;           /**< 0: 240 */
    /** Preference order, HAL_CAMERA_V4L2_IN_NONE-terminated; all NONE:
     *  {YUYV, MJPEG} (YUYV first: no decode cost and no JPEG artefacts; a
     *  camera whose YUYV is too slow at the size can be told MJPEG first). */
    hal_camera_v4l2_input_t inputs[HAL_CAMERA_V4L2_MAX_INPUTS];
    uint32_t buffer_count;        /**< driver buffers to request, 2..MAX_BUFFERS; 0: 4 */
    hal_camera_pixfmt_t output;   /**< 0 or RGB24 (the vision code's format); YUYV only from a YUYV device */
    uint32_t reopen_period_us;    /**< minimum time between reopen attempts; 0: 1 s */
    hal_camera_v4l2_log_fn log;   /**< NULL: lines go to stderr */
    void *log_ctx;
} hal_camera_v4l2_config_t;

/** Event counters since open (never reset; wrap after 2^64). */
typedef struct {
    uint64_t frames;            /**< frames returned by grab (HAL_OK) */
    uint64_t frames_skipped;    /**< dequeued but superseded by a newer frame before a grab took it */
    uint64_t buffer_errors;     /**< buffers the driver flagged V4L2_BUF_FLAG_ERROR, or empty */
    uint64_t corrupt_frames;    /**< MJPEG frames the decoder rejected */
    uint64_t bad_size_frames;   /**< MJPEG of another size, YUYV shorter than the format */
    uint64_t timeouts;          /**< grabs that returned HAL_E_TIMEOUT */
    uint64_t eintr_retries;     /**< system calls repeated after EINTR */
    uint64_t io_errors;         /**< other system call failures reported as HAL_E_IO */
    uint64_t disconnects;       /**< times the device went away */
    uint64_t reopen_attempts;   /**< reopen tries after a disconnect */
    uint64_t reopens;           /**< successful reopens */
} hal_camera_v4l2_counters_t;

typedef struct {
    void *start;                /**< mmap'd driver memory, NULL if not mapped */
    size_t length;              /**< [bytes] */
} hal_camera_v4l2_buffer_t;

/** Backend state; owned by the caller, must outlive the handle's use.
 *  Fields are read-only for the caller. */
typedef struct {
    hal_camera_t dev;                    /**< the handle; dev.backend points back here */
    hal_status_t open_status;            /**< result of the last hal_camera_v4l2_open */
    char path[HAL_CAMERA_V4L2_PATH_MAX + 1u];
    hal_camera_v4l2_config_t cfg;        /**< copy with defaults applied (device -> path) */
    hal_camera_format_t fmt;             /**< the output format, fixed at open */
    /* negotiated with the driver (may change at a reopen, the size not) */
    int fd;                              /**< -1 when closed or lost */
    uint32_t in_fourcc;                  /**< V4L2_PIX_FMT_YUYV / _MJPEG / _JPEG */
    uint32_t in_stride_bytes;            /**< YUYV bytesperline */
    bool in_full_range;                  /**< YUYV quantization: full (JPEG) instead of limited range */
    hal_camera_v4l2_buffer_t bufs[HAL_CAMERA_V4L2_MAX_BUFFERS];
    uint32_t n_bufs;
    /* streaming */
    bool is_open;                        /**< between a successful open and close */
    bool want_stream;                    /**< start() called, stop() not since */
    bool stream_on;                      /**< VIDIOC_STREAMON in force */
    bool lost;                           /**< device gone; reopen pending */
    bool refusal_logged;                 /**< a refused reopen was logged this episode */
    uint64_t next_reopen_us;
    int held;                            /**< index of a dequeued buffer kept for the next grab, -1 none */
    uint32_t held_bytes;
    hal_camera_frame_info_t held_info;
    uint32_t seq_base;                   /**< added to the driver's sequence in this stream session */
    bool seq_rebase;                     /**< set seq_base at the session's first dequeue */
    uint32_t next_seq;                   /**< one past the last sequence reported */
    void *tj;                            /**< TurboJPEG decompressor, NULL if not needed */
    hal_camera_v4l2_counters_t counters;
} hal_camera_v4l2_t;

/**
 * Open the V4L2 device cfg->device into the caller-owned *cam and negotiate
 * the format (see the file comment). Blocking: only for the system calls
 * (the device is opened O_NONBLOCK); not streaming until hal_camera_start.
 * Returns &cam->dev, or NULL on failure with cam->open_status set to:
 *   HAL_E_ARG         NULL argument, no device path or longer than
 *                     HAL_CAMERA_V4L2_PATH_MAX, size 0 after defaults or
 *                     over 8192, buffer_count over MAX_BUFFERS or 1, an
 *                     unknown output or input format;
 *   HAL_E_NOT_FOUND   no such device (ENOENT, ENODEV, ENXIO);
 *   HAL_E_BUSY        the device is streaming for another user (EBUSY);
 *   HAL_E_UNSUPPORTED not a V4L2 device, no video capture or no streaming
 *                     I/O, or none of cfg->inputs offered and accepted (a
 *                     camera with only H.264 or GREY, or YUYV output asked
 *                     of an MJPEG-only camera);
 *   HAL_E_IO          any other system or TurboJPEG failure.
 * On failure nothing stays open or mapped. Success: open_status HAL_OK.
 * *cam must not hold an open camera (close it first: it is overwritten).
 * Memory: maps the driver buffers; one TurboJPEG handle if MJPEG is in the
 * preference list and the output is RGB24.
 */
hal_camera_t *hal_camera_v4l2_open(const hal_camera_v4l2_config_t *cfg, hal_camera_v4l2_t *cam);

/** Copy of the counters. Returns HAL_OK; HAL_E_ARG (NULL). O(1). */
hal_status_t hal_camera_v4l2_get_counters(const hal_camera_v4l2_t *cam, hal_camera_v4l2_counters_t *out);

/** True while the device is open and not lost. */
bool hal_camera_v4l2_connected(const hal_camera_v4l2_t *cam);

/**
 * YUYV (Y0 U Y1 V per pixel pair) to RGB24, ITU-R BT.601, integer
 * arithmetic with 16 fractional bits, rounded to nearest, clamped to
 * 0..255. Limited ("studio") range, Y 16..235 and U, V 16..240
 * (full_range false):
 *   R = 1.164383 (Y-16)                     + 1.596027 (V-128)
 *   G = 1.164383 (Y-16) - 0.391762 (U-128)  - 0.812968 (V-128)
 *   B = 1.164383 (Y-16) + 2.017232 (U-128)
 * Full range (JFIF, full_range true):
 *   R = Y + 1.402 (V-128),  G = Y - 0.344136 (U-128) - 0.714136 (V-128),
 *   B = Y + 1.772 (U-128).
 * Both pixels of a pair share U and V. width_px must be even (an odd last
 * column is not written). O(width*height), no memory.
 */
void hal_camera_v4l2_yuyv_to_rgb24(const uint8_t *src, size_t src_stride_bytes, uint8_t *dst, size_t dst_stride_bytes,
                                   uint32_t width_px, uint32_t height_px, bool full_range);

#ifdef __cplusplus
}
#endif

#endif /* HAL_CAMERA_V4L2_H */
