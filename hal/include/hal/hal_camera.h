/*
 * hal/hal_camera.h - a camera delivering whole frames into caller buffers
 * (the landmark and robot-marker vision). See hal_common.h for the shared
 * conventions.
 *
 * Semantics:
 *  - The format is fixed by the backend when the instance is opened;
 *    get_format reports it. Pixel layouts (rows top to bottom, each row
 *    stride_bytes long, of which the first width_px * bytes-per-pixel are
 *    pixels):
 *      HAL_CAMERA_PIX_RGB24: 3 bytes per pixel, R, G, B.
 *      HAL_CAMERA_PIX_YUYV:  4 bytes per 2 pixels, Y0 U Y1 V (width even).
 *    frame_bytes = stride_bytes * height_px.
 *  - start/stop control streaming; both are idempotent. Frames captured
 *    while stopped are not kept.
 *  - grab returns the LATEST frame captured since the previous grab (or
 *    since start), waiting at most timeout_us for one. Older unread frames
 *    are dropped: a vision loop slower than the camera always sees the
 *    newest image, and gaps in `sequence` count the frames it skipped. The
 *    same frame is never returned twice.
 *  - stamp_us is the capture time (start of exposure if the backend knows
 *    it, else the driver's dequeue time), hal_clock time base.
 *
 * Backends: simulator (sim/hal: frames pushed by the simulator's
 * renderer), Linux V4L2 (hal/linux/v4l2, hal_camera_v4l2_open(): YUYV or
 * MJPEG webcams, mmap streaming; docs/camera-v4l2.md), null
 * (hal_camera_null()).
 */
#ifndef HAL_CAMERA_H
#define HAL_CAMERA_H

#include "hal/hal_common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    HAL_CAMERA_PIX_RGB24 = 1,
    HAL_CAMERA_PIX_YUYV = 2,
} hal_camera_pixfmt_t;

typedef struct {
    uint32_t width_px;
    uint32_t height_px;
    hal_camera_pixfmt_t pixfmt;
    uint32_t stride_bytes;   /**< bytes from one row to the next (>= width_px * bytes per pixel) */
    size_t frame_bytes;      /**< stride_bytes * height_px: the buffer size grab needs */
} hal_camera_format_t;

typedef struct {
    size_t len;              /**< frame size [bytes] (also set on HAL_E_OVERFLOW) */
    uint64_t stamp_us;       /**< capture time (hal_clock time base) */
    uint32_t sequence;       /**< capture counter since open; gaps = frames not grabbed */
} hal_camera_frame_info_t;

typedef struct hal_camera hal_camera_t;

typedef struct {
    /** HAL_OK with *fmt set; HAL_E_IO. Never blocks. */
    hal_status_t (*get_format)(hal_camera_t *dev, hal_camera_format_t *fmt);
    /** HAL_OK (also if already streaming); HAL_E_BUSY (device held by
     *  another user); HAL_E_IO. */
    hal_status_t (*start)(hal_camera_t *dev);
    /** HAL_OK (also if not streaming); HAL_E_IO. */
    hal_status_t (*stop)(hal_camera_t *dev);
    /** HAL_OK (frame in buf, *info set); HAL_E_TIMEOUT (no new frame within
     *  timeout_us); HAL_E_OVERFLOW (cap < frame size: nothing copied,
     *  info->len = size needed, the frame stays available); HAL_E_CLOSED
     *  (not streaming); HAL_E_IO. */
    hal_status_t (*grab)(hal_camera_t *dev, uint8_t *buf, size_t cap, hal_camera_frame_info_t *info,
                         uint32_t timeout_us);
    /** Stop and release the camera. The handle is unusable afterwards. */
    void (*close)(hal_camera_t *dev);
} hal_camera_ops_t;

struct hal_camera {
    const hal_camera_ops_t *ops;
    void *backend;   /**< backend-owned state */
};

/** Bytes per pixel row without padding, 0 for an unknown format or an odd
 *  YUYV width. */
static inline size_t hal_camera_row_bytes(hal_camera_pixfmt_t pixfmt, uint32_t width_px)
{
    switch (pixfmt) {
    case HAL_CAMERA_PIX_RGB24: return (size_t)width_px * 3u;
    case HAL_CAMERA_PIX_YUYV: return (width_px % 2u == 0u) ? (size_t)width_px * 2u : 0u;
    }
    return 0u;
}

/** The frame format. Returns HAL_OK, HAL_E_ARG (NULL), HAL_E_IO,
 *  HAL_E_UNSUPPORTED. Never blocks. */
static inline hal_status_t hal_camera_get_format(hal_camera_t *d, hal_camera_format_t *fmt)
{
    if (d == NULL || d->ops == NULL || fmt == NULL) return HAL_E_ARG;
    return d->ops->get_format ? d->ops->get_format(d, fmt) : HAL_E_UNSUPPORTED;
}

/** Start streaming. Returns HAL_OK, HAL_E_ARG, HAL_E_BUSY, HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_camera_start(hal_camera_t *d)
{
    if (d == NULL || d->ops == NULL) return HAL_E_ARG;
    return d->ops->start ? d->ops->start(d) : HAL_E_UNSUPPORTED;
}

/** Stop streaming. Returns HAL_OK, HAL_E_ARG, HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_camera_stop(hal_camera_t *d)
{
    if (d == NULL || d->ops == NULL) return HAL_E_ARG;
    return d->ops->stop ? d->ops->stop(d) : HAL_E_UNSUPPORTED;
}

/** Copy the latest new frame into buf (capacity cap bytes, at least
 *  format.frame_bytes), waiting at most timeout_us. Returns HAL_OK,
 *  HAL_E_TIMEOUT, HAL_E_OVERFLOW, HAL_E_CLOSED, HAL_E_ARG (NULL, cap 0),
 *  HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_camera_grab(hal_camera_t *d, uint8_t *buf, size_t cap, hal_camera_frame_info_t *info,
                                           uint32_t timeout_us)
{
    if (d == NULL || d->ops == NULL || buf == NULL || cap == 0 || info == NULL) return HAL_E_ARG;
    info->len = 0;
    return d->ops->grab ? d->ops->grab(d, buf, cap, info, timeout_us) : HAL_E_UNSUPPORTED;
}

static inline void hal_camera_close(hal_camera_t *d)
{
    if (d != NULL && d->ops != NULL && d->ops->close != NULL) d->ops->close(d);
}

/** The null camera (library coslam_hal_null): every operation returns
 *  HAL_E_UNSUPPORTED. Never NULL. */
hal_camera_t *hal_camera_null(void);

#ifdef __cplusplus
}
#endif

#endif /* HAL_CAMERA_H */
