/*
 * coslam/view.h - what the camera could see in one frame: the nearest
 * obstacle around the robot per bearing, from the laser, so that a landmark
 * behind an obstacle is not counted as missed (landmark.h, exist_miss).
 *
 * The filters know landmarks, not walls: without a profile a marker on the
 * far face of a box, or one a partner robot stands in front of, is "missed"
 * every frame the robot looks its way, and a confirmed landmark dies after
 * exist_max / exist_miss_confirmed such frames. With a profile a miss
 * counts only where the line of sight was free: where the laser's nearest
 * return in the landmark's bearing bin is not in front of it
 * (docs/core-slam.md "Death of confirmed landmarks").
 *
 * COSLAM_VIEW_BINS bins (config.h) cover the full circle in the robot
 * frame, bin b = floor((bearing + pi) / (2 pi) * COSLAM_VIEW_BINS); a bin
 * no return fell in is free (+inf: out of the laser's reach or field).
 * A profile serves one frame: the filters clear theirs after each update.
 */
#ifndef COSLAM_VIEW_H
#define COSLAM_VIEW_H

#include <stddef.h>
#include <stdint.h>

#include "coslam/config.h"
#include "coslam/pose2.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint8_t valid;                     /**< 0: no profile, every miss counts */
    float near_m[COSLAM_VIEW_BINS];    /**< nearest return per bin [m], +inf none */
} view_profile_t;

/** No profile (valid 0): every miss counts, as without a laser. */
void view_profile_clear(view_profile_t *v);

/**
 * The profile of obstacle points `pts` (n of them, [m]) given in a frame
 * whose pose in the robot frame is `at` (identity: the robot frame; the
 * robot's motion since a scan: the scan's points moved to now). Points
 * that are not finite, or at the robot's centre, are skipped. Valid even
 * if no point was usable (then nothing blocks). COSLAM_E_ARG on a NULL
 * profile, NULL pts with n > 0, or a non-finite `at`; the profile is then
 * not valid.
 */
coslam_status_t view_profile_build(view_profile_t *v, const point2_t *pts, size_t n, pose2_t at);

/**
 * 1 if the profile holds an obstacle in front of a landmark predicted at
 * (range_m, bearing_rad) in the robot frame by more than margin_m: a
 * return in its bin nearer than range_m - margin_m. 0 if the profile is not
 * valid, the prediction not finite, or the line of sight free.
 */
int view_blocks(const view_profile_t *v, double range_m, double bearing_rad, double margin_m);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_VIEW_H */
