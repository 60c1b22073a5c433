/*
 * vision/marker_spec.h - what the camera looks at and how it is mounted:
 * the ONE description shared by the simulator's renderer (sim/world
 * camera_renderer) and the detector (vision/vision.h). Change a number here
 * and both follow; the colour table (vision_lut) and the range model
 * (vision_range_model) must then be retrained/refitted (docs/vision.md).
 *
 * Markers (paper sec. 3.3, "two-colored markers"): two stacked colour bands
 * of equal height on a vertical cylinder.
 *
 *        z [m]
 *   0.45 +------+
 *        |      |   top band    (colour `top`)
 *   0.35 +------+   <- the camera's height: the horizon row
 *        |      |   bottom band (colour `bottom`)
 *   0.25 +------+
 *
 *  - landmark marker: a cylinder of radius VISION_LANDMARK_RADIUS_M whose
 *    axis is the landmark's point (the simulator puts the point 2 cm in
 *    front of a wall: the wall hides the back of the tube, which the eye
 *    never sees anyway). Its class, the filters' `signature`, is its colour
 *    pair (vision_landmark_pairs[signature]); markers are NOT unique;
 *  - robot marker: the two bands wrapped around the robot's round body
 *    (radius VISION_ROBOT_MARKER_RADIUS_M, the Robotino's 0.19 m), the same
 *    heights; the body below is dark grey. Each robot has its own pair
 *    (vision_robot_pairs[robot_id]), so a robot sighting carries the id.
 * The marker's total height VISION_MARKER_HEIGHT_M = 0.20 m is centred on
 * the camera's horizon, so a marker fits the image down to 0.29 m.
 *
 * Palette: the paper's four colours (it segmented "the color space into four
 * colors"), 60-120 deg apart in hue, plus "none" (everything else). 4
 * colours give 12 ordered pairs: 4 landmark classes and 8 robot markers.
 * The reference sRGB values are how the paper looks at the nominal exposure
 * under white light; the renderer scales them with light and shading.
 *
 * Camera (the Robotino's webcam, paper sec. 3): 320x240 RGB, horizontal
 * field of view 50 deg (the paper's value and the simulator's
 * camera.fov_deg), square pixels, pinhole without distortion, mounted at
 * the robot's centre at height 0.35 m, looking along the robot's x axis,
 * level (pitch 0: a pitched camera needs a new range fit).
 *   focal length f = (W/2) / tan(hfov/2) = 160 / tan(25 deg) = 343.12 px
 *   principal point (cx, cy) = (159.5, 119.5) (pixel centres are integers)
 *   a point at (x forward, y left, z up) in the camera frame, x > 0, maps to
 *   u = cx - f y / x,  v = cy - f (z - h_cam) / x.
 *   bearing of column u: atan2(cx - u, f) (counter-clockwise positive,
 *   as in app/sighting_source.h).
 */
#ifndef COSLAM_VISION_MARKER_SPEC_H
#define COSLAM_VISION_MARKER_SPEC_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- camera ------------------------------------------------------------ */
#define VISION_IMAGE_WIDTH_PX 320
#define VISION_IMAGE_HEIGHT_PX 240
#define VISION_HFOV_DEG 50.0
#define VISION_FOCAL_PX 343.1215   /* 160 / tan(25 deg) */
#define VISION_CX_PX 159.5
#define VISION_CY_PX 119.5
#define VISION_CAMERA_HEIGHT_M 0.35
#define VISION_CAMERA_PITCH_RAD 0.0
#define VISION_FRAME_PERIOD_MS 200.0  /* 5 Hz, as the simulator's camera.period_ms */

/* ---- markers ----------------------------------------------------------- */
#define VISION_MARKER_BOTTOM_M 0.25   /* lower edge of the bottom band */
#define VISION_BAND_HEIGHT_M 0.10     /* each band */
#define VISION_MARKER_HEIGHT_M 0.20   /* both bands */
#define VISION_LANDMARK_RADIUS_M 0.05
#define VISION_ROBOT_MARKER_RADIUS_M 0.19

/** Colour classes of the segmentation (the values of the colour table). */
typedef enum {
    VISION_COLOUR_NONE = 0,   /**< background: anything not a marker colour */
    VISION_COLOUR_RED = 1,
    VISION_COLOUR_YELLOW = 2,
    VISION_COLOUR_GREEN = 3,
    VISION_COLOUR_BLUE = 4,
} vision_colour_t;
#define VISION_N_COLOURS 5          /* including NONE */

/** Reference sRGB appearance of each class at the nominal exposure
 *  (index = vision_colour_t; NONE has none: {0, 0, 0}). */
static const uint8_t vision_colour_srgb[VISION_N_COLOURS][3] = {
    {0, 0, 0},
    {200, 35, 40},    /* red    (hue ~358 deg) */
    {230, 200, 40},   /* yellow (hue ~51 deg) */
    {40, 150, 70},    /* green  (hue ~136 deg) */
    {35, 75, 185},    /* blue   (hue ~224 deg) */
};

/** A colour pair: the top band over the bottom band. */
typedef struct {
    uint8_t top;      /**< vision_colour_t */
    uint8_t bottom;   /**< vision_colour_t */
} vision_pair_t;

#define VISION_N_LANDMARK_CLASSES 4   /* signatures 0..3 */
#define VISION_MAX_ROBOT_MARKERS 8    /* robot ids 0..7 */

/** Landmark class (signature) -> colour pair. */
static const vision_pair_t vision_landmark_pairs[VISION_N_LANDMARK_CLASSES] = {
    {VISION_COLOUR_RED, VISION_COLOUR_GREEN},
    {VISION_COLOUR_BLUE, VISION_COLOUR_YELLOW},
    {VISION_COLOUR_GREEN, VISION_COLOUR_BLUE},
    {VISION_COLOUR_YELLOW, VISION_COLOUR_RED},
};

/** Robot id -> colour pair (all 12 ordered pairs are used exactly once). */
static const vision_pair_t vision_robot_pairs[VISION_MAX_ROBOT_MARKERS] = {
    {VISION_COLOUR_RED, VISION_COLOUR_BLUE},    {VISION_COLOUR_GREEN, VISION_COLOUR_YELLOW},
    {VISION_COLOUR_BLUE, VISION_COLOUR_RED},    {VISION_COLOUR_YELLOW, VISION_COLOUR_GREEN},
    {VISION_COLOUR_RED, VISION_COLOUR_YELLOW},  {VISION_COLOUR_GREEN, VISION_COLOUR_RED},
    {VISION_COLOUR_BLUE, VISION_COLOUR_GREEN},  {VISION_COLOUR_YELLOW, VISION_COLOUR_BLUE},
};

typedef enum {
    VISION_MARKER_NONE = 0,
    VISION_MARKER_LANDMARK = 1,
    VISION_MARKER_ROBOT = 2,
} vision_marker_kind_t;

/** What a (top, bottom) colour pair is: VISION_MARKER_LANDMARK with *index
 *  = its signature, VISION_MARKER_ROBOT with *index = the robot id, or
 *  VISION_MARKER_NONE (index untouched). O(12), no state. */
static inline vision_marker_kind_t vision_pair_lookup(uint8_t top, uint8_t bottom, uint8_t *index)
{
    for (uint8_t i = 0; i < VISION_N_LANDMARK_CLASSES; ++i) {
        if (vision_landmark_pairs[i].top == top && vision_landmark_pairs[i].bottom == bottom) {
            if (index != 0) *index = i;
            return VISION_MARKER_LANDMARK;
        }
    }
    for (uint8_t i = 0; i < VISION_MAX_ROBOT_MARKERS; ++i) {
        if (vision_robot_pairs[i].top == top && vision_robot_pairs[i].bottom == bottom) {
            if (index != 0) *index = i;
            return VISION_MARKER_ROBOT;
        }
    }
    return VISION_MARKER_NONE;
}

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_VISION_MARKER_SPEC_H */
