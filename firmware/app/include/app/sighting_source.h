/*
 * app/sighting_source.h - where the robot app gets its marker sightings:
 * landmark sightings (range, bearing, signature) and sightings of other
 * robots (robot id, range, bearing), one frame at a time.
 *
 * This is the seam between the app and the vision pipeline. Implementations:
 * the vision source (firmware/vision/vision_source.h: a hal_camera_t plus
 * the marker detector, camera frame -> colour table -> blobs -> markers),
 * which the simulator runs on rendered pixels by default; the simulator's
 * geometric STAND-IN (sim/world/sighting_oracle.hpp, `--camera oracle`:
 * sightings from the world's geometry, no image); and coslam-robot's
 * test-only sources (a landmark-log replay, a live stream from the
 * end-to-end device server; firmware/port/linux/robot_sightings.h).
 *
 * Same shape as a HAL contract (hal/hal_common.h): a handle whose first
 * member points at a const ops table, an inline wrapper that returns
 * HAL_E_UNSUPPORTED for a missing op. One instance per robot; used by one
 * thread at a time.
 *
 * Frame semantics:
 *  - next_frame hands out the newest frame completed since the previous
 *    call (never the same frame twice; skipped frames show as gaps in
 *    `sequence`). A frame with no sighting is still a frame: the filters
 *    use it as negative evidence.
 *  - stamp_us is the capture time, in the hal_clock time base.
 *  - The camera sits at the robot's centre looking along the robot's x
 *    axis: range [m] from the robot centre, bearing [rad] counter-clockwise
 *    from the robot's x axis, in [-pi, pi].
 *  - Landmark signature = the marker class (colour pair); markers are not
 *    unique (several markers share a signature). Robot markers are unique:
 *    a robot sighting carries the seen robot's id.
 *  - Sightings beyond the frame's capacity are dropped and counted in
 *    `dropped` (never silently).
 */
#ifndef COSLAM_APP_SIGHTING_SOURCE_H
#define COSLAM_APP_SIGHTING_SOURCE_H

#include <stdint.h>

#include "coslam/config.h"
#include "coslam/observe.h"
#include "hal/hal_common.h"

#ifdef __cplusplus
extern "C" {
#endif

/** A sighting of another robot's marker. */
typedef struct {
    uint8_t robot_id;    /**< id of the robot seen (< COSLAM_MAX_ROBOTS) */
    double range_m;      /**< [m], from this robot's centre to the other's centre */
    double bearing_rad;  /**< [rad], this robot's frame, counter-clockwise, [-pi, pi] */
} robot_seen_t;

/** The sightings of one camera frame. */
typedef struct {
    uint64_t stamp_us;                            /**< capture time, hal_clock time base */
    uint32_t sequence;                            /**< frame counter of the source */
    uint16_t n_landmarks;
    sighting_t landmarks[COSLAM_MAX_SIGHTINGS];   /**< range, bearing, signature */
    uint16_t n_robots;
    robot_seen_t robots[COSLAM_MAX_ROBOTS];
    uint16_t dropped;                             /**< sightings that did not fit this frame */
} sighting_frame_t;

typedef struct sighting_source sighting_source_t;

typedef struct {
    /** HAL_OK: *out holds a frame newer than the previous one; HAL_E_TIMEOUT:
     *  no new frame within timeout_us (*out untouched); HAL_E_CLOSED: the
     *  source is gone; HAL_E_IO: the pipeline failed. */
    hal_status_t (*next_frame)(sighting_source_t *src, sighting_frame_t *out, uint32_t timeout_us);
} sighting_source_ops_t;

struct sighting_source {
    const sighting_source_ops_t *ops;
    void *backend;  /**< implementation-owned state */
};

/** Newest frame since the previous call, waiting at most timeout_us (0:
 *  poll). Returns HAL_OK, HAL_E_TIMEOUT, HAL_E_CLOSED, HAL_E_IO, HAL_E_ARG
 *  (NULL), HAL_E_UNSUPPORTED. */
static inline hal_status_t sighting_source_next_frame(sighting_source_t *s, sighting_frame_t *out,
                                                      uint32_t timeout_us)
{
    if (s == NULL || s->ops == NULL || out == NULL) return HAL_E_ARG;
    return s->ops->next_frame ? s->ops->next_frame(s, out, timeout_us) : HAL_E_UNSUPPORTED;
}

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_APP_SIGHTING_SOURCE_H */
