/*
 * robot_camera.h - coslam-robot's camera: the V4L2 backend
 * (hal/hal_camera_v4l2.h) feeding the marker detector (vision/vision.h)
 * through the vision sighting source (vision/vision_source.h), so the
 * robot node gets landmark and robot sightings from pixels through the
 * same sighting_source_t as every other source. Built when the build has
 * the V4L2 backend and firmware/vision (COSLAM_HAVE_CAMERA); the device
 * slot is robot_devices.c's ROBOT_DEV_CAMERA.
 *
 * Life cycle:
 *   robot_camera_open_* (every open attempt of the slot, below) the first
 *                       time: loads the colour table and the range model
 *                       and creates the detector and the frame buffer (the
 *                       only allocations, once per process); then opens the
 *                       V4L2 device, checks its size and starts streaming.
 *   next_frame          (the node, every step) grab + detect; never
 *                       allocates. Losses are answered HAL_E_CLOSED so the
 *                       slot closes the camera and reopens it every retry
 *                       period (robot_devices.h):
 *                         - the device went away (the backend reports it
 *                           disconnected after ENODEV / EIO / POLLERR);
 *                         - no frame for cfg->camera_stall_us while
 *                           streaming (a stalled UVC camera): `stalls`.
 *                       A frame the detector or the backend refuses is
 *                       HAL_E_IO (counted by the backend, the source and
 *                       the slot); a step without a frame HAL_E_TIMEOUT.
 *   robot_camera_close  (slot down, exit) stops and closes the device;
 *                       keeps the detector and the buffer for a reopen.
 *   robot_camera_free   (exit) releases the detector and the buffer.
 *
 * Frame size: the detector is made for cfg->camera_width_px x
 * camera_height_px with the default camera's intrinsics scaled to that
 * width (the same 50 deg horizontal field of view, marker_spec.h; the
 * principal point at the image centre). A camera that opens at another
 * size (webcams have a fixed list of sizes) is refused: `bad_format`, the
 * slot reports "gives WxH, configured WxH" and retries.
 *
 * One instance; one thread but for robot_camera_open_device (below). Not
 * async-signal-safe.
 */
#ifndef COSLAM_PORT_ROBOT_CAMERA_H
#define COSLAM_PORT_ROBOT_CAMERA_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "app/sighting_source.h"
#include "hal/hal_camera_v4l2.h"
#include "hal/hal_clock.h"
#include "robot_config.h"
#include "vision/vision_source.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Counters of the robot's camera since start (never reset). */
typedef struct {
    uint32_t opens;          /**< successful opens */
    uint32_t open_failures;  /**< failed ones (device, size, files) */
    uint32_t bad_format;     /**< the camera opened at another size than configured */
    uint32_t disconnects;    /**< the device went away while streaming */
    uint32_t stalls;         /**< no frame for camera_stall_us while streaming */
    uint64_t frames;         /**< frames detected (all opens) */
    uint64_t landmarks;      /**< landmark sightings handed out (all opens) */
    uint64_t robots;         /**< robot sightings handed out (all opens) */
    uint64_t errors;         /**< next_frame answers other than OK / TIMEOUT */
    uint64_t detect_partial; /**< frames the detector processed only in part: its capacity (runs,
                                  blobs or candidate pairs, vision_config.h) was reached, markers in
                                  the rest were lost (VISION_E_CAPACITY; all opens) */
    uint64_t foreign_robots; /**< robot markers with an id no robot of this build can have
                                  (>= COSLAM_MAX_ROBOTS), not handed out (all opens) */
} robot_camera_counters_t;

typedef struct {
    sighting_source_t src;            /**< the handle (src.backend = this) */
    const robot_config_t *cfg;
    hal_clock_t *clock;
    hal_camera_v4l2_t v4l2;           /**< backend state */
    hal_camera_t *camera;             /**< &v4l2.dev while open, else NULL */
    vision_detector_t *det;           /**< made at the first open, kept */
    uint8_t *buf;                     /**< frame buffer (RGB24), made with the detector */
    size_t cap;
    vision_source_t vs;               /**< camera + detector -> sighting frames */
    uint64_t last_frame_us;           /**< last frame, or the open [us] */
    robot_camera_counters_t ctr;      /**< frames, landmarks, robots, detect_partial, foreign_robots: of
                                           closed opens only */
    /* an open's device part hands over in these (read by _open_finish) */
    hal_camera_t *opened;             /**< the device opened and streaming, not yet taken */
    int open_bad_format;              /**< that open was refused for its frame size */
} robot_camera_t;

/** Set up *c (closed, nothing allocated). */
void robot_camera_init(robot_camera_t *c, const robot_config_t *cfg, hal_clock_t *clock);

/**
 * Open (see the file comment), in three parts, so that the part that blocks
 * (a UVC camera takes 0.1-0.5 s to start streaming; the first open also
 * loads the colour table and the range model) can run on a thread of its
 * own while the control loop goes on (robot_devices.c's openers):
 *   _prepare   (the loop) closes the camera; HAL_E_ARG for NULL;
 *   _device    (any one thread, while the camera is closed: nothing else
 *              touches what it writes then: det, buf, cap, v4l2, vs,
 *              opened, open_bad_format) makes the detector at the first
 *              call that gets this far, opens the V4L2 device, checks the
 *              size, starts streaming; closes the device again on any
 *              failure. HAL_E_NOT_FOUND (no device, no colour table),
 *              HAL_E_CORRUPT (a bad colour table or range model), HAL_E_ARG
 *              (a frame size other than configured), the V4L2 backend's open
 *              status, HAL_E_IO; msg names the file or device;
 *   _finish    (the loop) with the status of the parts before: counts it,
 *              and on success makes the camera the open one. Returns that
 *              status. Nothing stays open after a failure.
 */
hal_status_t robot_camera_open_prepare(robot_camera_t *c, char *msg, size_t msg_cap);
hal_status_t robot_camera_open_device(robot_camera_t *c, char *msg, size_t msg_cap);
hal_status_t robot_camera_open_finish(robot_camera_t *c, hal_status_t st);

/** Stop and close the device (no-op when closed). */
void robot_camera_close(robot_camera_t *c);

/** Close, and release the detector and the buffer. */
void robot_camera_free(robot_camera_t *c);

/** The counters, with the current open's source counters folded in. */
robot_camera_counters_t robot_camera_counters(const robot_camera_t *c);

/** The camera's LIMIT line: when detect_partial has grown beyond *seen,
 *  one line on `out` ("coslam-robot: LIMIT robot R: N camera frames
 *  detected only in part: ..., with the detector's capacities of this
 *  build), *seen updated; returns 1 if a line was said, else 0. A loss of
 *  markers is said like the filter's capacity losses (robot_main.c). */
int robot_camera_say_limits(const robot_camera_t *c, uint64_t *seen, unsigned robot_id, FILE *out);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_CAMERA_H */
