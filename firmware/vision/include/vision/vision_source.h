/*
 * vision/vision_source.h - the app's sighting source (app/sighting_source.h)
 * backed by a camera (hal/hal_camera.h) and the marker detector
 * (vision/vision.h): the real pipeline behind the seam the simulator's
 * stand-in also implements, so robot_node runs unchanged on pixels.
 *
 * next_frame(timeout_us): grabs the camera's newest frame (hal_camera_grab,
 * waiting at most timeout_us), detects markers, and hands out
 *   - landmark sightings (range, bearing, signature = the colour pair's class),
 *   - robot sightings (robot id from the robot marker's colour pair),
 * with the frame's stamp and sequence. Sightings beyond the frame's capacity
 * (COSLAM_MAX_SIGHTINGS, COSLAM_MAX_ROBOTS) and markers the detector dropped
 * are counted in `dropped`. The detector's per-sighting variances do not fit
 * sighting_t (range, bearing, signature only); the filters use their
 * configured noise model (slam_params), which docs/vision.md relates to the
 * detector's fit; last_result() keeps them for callers who want them.
 *
 * Returns of next_frame: HAL_OK; HAL_E_TIMEOUT (no new frame); HAL_E_CLOSED
 * (the camera is not streaming: start failed or it went away); HAL_E_IO (the
 * camera failed, the frame format is unusable, or the buffer is too small);
 * HAL_E_ARG.
 *
 * Memory: the caller owns the vision_source_t, the detector and the frame
 * buffer (>= the camera's frame_bytes); nothing is allocated here.
 */
#ifndef COSLAM_VISION_VISION_SOURCE_H
#define COSLAM_VISION_VISION_SOURCE_H

#include <stddef.h>
#include <stdint.h>

#include "app/sighting_source.h"
#include "hal/hal_camera.h"
#include "vision/vision.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint64_t frames;          /**< frames detected */
    uint64_t grab_timeouts;
    uint64_t grab_errors;     /**< grab returned anything but OK/TIMEOUT */
    uint64_t detect_partial;  /**< detector capacity reached (VISION_E_CAPACITY) */
    uint64_t landmarks;       /**< landmark sightings handed out */
    uint64_t robots;          /**< robot sightings handed out */
    uint64_t dropped;         /**< sightings that did not fit a frame */
    uint64_t foreign_robots;  /**< robot markers with an id >= COSLAM_MAX_ROBOTS */
} vision_source_counters_t;

typedef struct {
    sighting_source_t src;    /**< the handle the app uses (vision_source_handle) */
    hal_camera_t *camera;
    vision_detector_t *det;
    uint8_t *buf;
    size_t cap;
    hal_camera_format_t fmt;
    vision_result_t result;   /**< markers of the last frame, with variances */
    vision_source_counters_t ctr;
} vision_source_t;

/** Bind camera, detector and frame buffer, read the camera's format and
 *  start streaming. Returns HAL_OK; HAL_E_ARG (NULL, cap too small for the
 *  format, a format size other than the detector's); the camera's start
 *  error (the source is still usable: next_frame then retries the start and
 *  reports HAL_E_CLOSED); the camera's get_format error (the format was not
 *  read: every next_frame then fails with HAL_E_IO, counted in grab_errors,
 *  until the source is initialised again, as the robot's device retry
 *  does). */
hal_status_t vision_source_init(vision_source_t *vs, hal_camera_t *camera, vision_detector_t *det, uint8_t *buf,
                                size_t cap);
static inline sighting_source_t *vision_source_handle(vision_source_t *vs)
{
    return &vs->src;
}

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_VISION_VISION_SOURCE_H */
