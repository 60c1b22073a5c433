/*
 * vision/vision.h - marker detection in camera frames (paper sec. 3.3,
 * "Landmark Detection"): colour table per pixel -> colour classes -> blobs
 * per colour -> markers (two blobs of a known colour pair, stacked) ->
 * sightings (range, bearing, their variances; the landmark class or the
 * robot id). What the markers and the camera are: vision/marker_spec.h.
 * How the table and the range model were made: docs/vision.md.
 *
 * C API over a C++17/OpenCV implementation. Memory: the detector is created
 * once (vision_detector_create allocates every buffer it will ever use);
 * vision_detect_* never allocates (checked by test_vision_detect, which
 * counts malloc calls) and never blocks. Not thread-safe per detector; any
 * number of detectors may run in parallel.
 *
 * Pipeline of one frame (W x H pixels):
 *  1. colour classes: class(x) = LUT[r>>3][g>>3][b>>3] (a 32x32x32 table,
 *     baked from the paper's GRNN colour classifier by coslam-vision-train);
 *  2. blobs: 8-connected components of each colour (VISION_BLOBS_RUNS: a
 *     one-pass run-length labelling with union-find into preallocated
 *     arrays, all colours at once; VISION_BLOBS_OPENCV:
 *     cv::connectedComponentsWithStats per colour, the same blobs, but
 *     OpenCV allocates its label table and statistics inside every call);
 *     blobs smaller than min_blob_area_px are noise;
 *  3. markers: a blob `a` over a blob `b` whose colours are a marker's
 *     (top, bottom) pair, horizontally overlapping (>= min_overlap of the
 *     narrower), vertically adjacent (gap <= max_gap_px + max_gap_rel *
 *     min(h_a, h_b), overlap <= the same), band heights and widths within a
 *     factor band_ratio_max, total height / width within the kind's range;
 *     a marker touching the image's top or bottom row has no measurable
 *     height and is dropped (counted), so is one touching a side (its
 *     centre is unknown) - except a robot cut on one side only: its body is
 *     a cylinder of known radius R, so its centre lies asin(R / r) beyond
 *     the visible edge (r from the height), bearing variance + (0.5 deg)^2
 *     (a robot at 2.5 m is 9 deg wide: without this the robots' field of
 *     view for each other would shrink by 4.5 deg a side); candidates are taken best first (smallest gap and band
 *     mismatch), each blob in one marker at most; a robot id seen twice in
 *     a frame keeps its larger marker;
 *  4. sightings: bearing = atan2(cx - u_c, f) with u_c the markers' pixel
 *     centroid column; range from the marker's pixel height h, from the top
 *     edge of the upper band to the bottom edge of the lower one, placed to
 *     a fraction of a pixel by the coverage of the edge rows in the RGB
 *     image (median over the central columns; the blobs' box where the
 *     contrast is too low):
 *       r_p = f * VISION_MARKER_HEIGHT_M / (h cos(bearing))   (pinhole: the
 *             image of a vertical edge scales with the depth along the
 *             optical axis, the distance along the ray times cos(bearing))
 *       r   = c0 + c1 r_p + c2 r_p^2     (fitted: the near surface is R in
 *             front of the axis, c0 ~ R; band edges blur by a fixed
 *             fraction of a pixel, which bends 1/h: the quadratic term)
 *     (the paper "calibrated a non-linear function of region size"),
 *     variances var_r = range_sd_m^2 + (range_sd_rel r)^2, var_b =
 *     bearing_sd_rad^2 from the fit's residuals (coslam-vision-fit); the
 *     model is per kind (a landmark tube and a robot's body differ in
 *     radius). Sightings outside [min_range_m, max_range_m] are dropped
 *     (counted).
 */
#ifndef COSLAM_VISION_VISION_H
#define COSLAM_VISION_VISION_H

#include <stddef.h>
#include <stdint.h>

#include "vision/marker_spec.h"
#include "vision/vision_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Status codes of the vision library (0 OK, errors negative; the range
 *  -100..-119 is the vision's, next to coslam/status.h's module ranges). */
typedef enum {
    VISION_OK = 0,
    VISION_E_ARG = -100,       /**< NULL, size 0, value out of its domain */
    VISION_E_IO = -101,        /**< a file cannot be opened, read or written */
    VISION_E_FORMAT = -102,    /**< a file has a bad magic, version, size or syntax */
    VISION_E_CRC = -103,       /**< a file failed its integrity check */
    VISION_E_CAPACITY = -104,  /**< a fixed capacity was reached: the result is partial (counted) */
    VISION_E_NOMEM = -105,     /**< start-up allocation failed */
} vision_status_t;

/** Short static name of a status ("VISION_E_CRC"). */
const char *vision_status_name(vision_status_t st);

/* ---- colour table -------------------------------------------------------
 * File format (little-endian), written by coslam-vision-train:
 *   offset  size  field
 *        0     4  magic "CVLT"
 *        4     2  version (1)
 *        6     1  bits per channel b (5: 32 bins of 8 levels)
 *        7     1  number of classes (VISION_N_COLOURS)
 *        8     4  table size N = 2^(3b) bytes
 *       12     4  reserved, 0
 *       16    32  how it was made, ASCII, NUL-padded ("grnn sigma=10.0")
 *       48     N  class per bin, bin = (r >> (8-b)) << 2b | (g >> (8-b)) << b | (b >> (8-b))
 *     48+N     4  CRC-32 (IEEE, coslam/crc32.h) of bytes [0, 48+N)
 * Total 32 820 bytes for b = 5.                                              */
#define VISION_LUT_BITS 5
#define VISION_LUT_SIZE (1u << (3 * VISION_LUT_BITS))
#define VISION_LUT_HEADER_BYTES 48u
#define VISION_LUT_FILE_BYTES (VISION_LUT_HEADER_BYTES + VISION_LUT_SIZE + 4u)

typedef struct {
    uint8_t table[VISION_LUT_SIZE];   /**< vision_colour_t per bin */
    char method[32];                  /**< NUL-terminated description */
} vision_lut_t;

/** Bin of an sRGB pixel. */
static inline uint32_t vision_lut_bin(uint8_t r, uint8_t g, uint8_t b)
{
    return ((uint32_t)(r >> (8 - VISION_LUT_BITS)) << (2 * VISION_LUT_BITS)) |
           ((uint32_t)(g >> (8 - VISION_LUT_BITS)) << VISION_LUT_BITS) | (uint32_t)(b >> (8 - VISION_LUT_BITS));
}

/** Serialise into buf (cap >= VISION_LUT_FILE_BYTES). Returns VISION_OK or
 *  VISION_E_ARG. */
vision_status_t vision_lut_encode(const vision_lut_t *lut, uint8_t *buf, size_t cap);
/** Parse a file image. Returns VISION_OK; VISION_E_ARG (NULL);
 *  VISION_E_FORMAT (length, magic, version, bits, class count, a class id
 *  >= VISION_N_COLOURS); VISION_E_CRC. *lut is untouched on error. */
vision_status_t vision_lut_decode(vision_lut_t *lut, const uint8_t *buf, size_t len);
/** Read / write a table file. Errors as decode, plus VISION_E_IO. */
vision_status_t vision_lut_load(vision_lut_t *lut, const char *path);
vision_status_t vision_lut_save(const vision_lut_t *lut, const char *path);

/* ---- range model ---------------------------------------------------------
 * A text file written by coslam-vision-fit, `key = value` lines, `#`
 * comments (the fit's residuals are reported there):
 *   format = coslam-vision-range 1
 *   landmark.c = c0 c1 c2            r = c0 + c1 r_p + c2 r_p^2, r_p = f H / (h cos(bearing))
 *   landmark.range_sd_m = s0         range variance s0^2 + (s1 r)^2
 *   landmark.range_sd_rel = s1
 *   landmark.bearing_sd_deg = sb
 *   robot.* likewise
 * Unknown keys, missing keys and bad numbers are VISION_E_FORMAT.          */
typedef struct {
    double c[3];              /**< r = c0 + c1 r_p + c2 r_p^2 [m] */
    double range_sd_m;        /**< constant part of the range sd [m] */
    double range_sd_rel;      /**< part proportional to the range */
    double bearing_sd_rad;
} vision_range_fit_t;

typedef struct {
    vision_range_fit_t landmark;
    vision_range_fit_t robot;
} vision_range_model_t;

/** The uncalibrated model: r = r_p + the marker's radius (the pixel height
 *  is the near surface's), sd 0.05 m + 5 %, 1 deg. */
vision_range_model_t vision_range_model_pinhole(void);
vision_status_t vision_range_model_load(vision_range_model_t *m, const char *path);
/** `header` (may be NULL) is written as comment lines first. */
vision_status_t vision_range_model_save(const vision_range_model_t *m, const char *path, const char *header);
/** The pinhole distance r_p along the ray of a marker h_px > 0 high at
 *  bearing_rad (|bearing| < 90 deg), focal length focal_px. */
double vision_range_pinhole(double focal_px, double h_px, double bearing_rad);
/** r from a pixel height h_px > 0 at bearing_rad, focal length focal_px. */
double vision_range_from_height(const vision_range_fit_t *fit, double focal_px, double h_px, double bearing_rad);

/* ---- detector ------------------------------------------------------------ */
typedef enum {
    VISION_BLOBS_RUNS = 0,     /**< own run-length labelling: no allocation per frame (default) */
    VISION_BLOBS_OPENCV = 1,   /**< cv::connectedComponentsWithStats per colour (allocates inside OpenCV) */
} vision_blob_method_t;

typedef struct {
    uint32_t width_px, height_px;     /**< frame size (default 320 x 240) */
    double focal_px, cx_px, cy_px;    /**< intrinsics (default marker_spec.h) */
    uint32_t min_blob_area_px;        /**< smaller blobs are noise (4) */
    uint32_t min_height_px;           /**< markers lower than this are not measured (6) */
    double max_gap_px;                /**< band gap allowance, constant part (2) */
    double max_gap_rel;               /**< ... times the lower band height (0.3) */
    double min_overlap;               /**< horizontal overlap / narrower width (0.5) */
    double band_ratio_max;            /**< band heights and widths agree within this factor (2) */
    double landmark_hw_min, landmark_hw_max;  /**< height/width of a landmark marker (1.0, 8.0; 2.0 unoccluded) */
    double robot_hw_min, robot_hw_max;        /**< of a robot marker (0.2, 1.4; 0.53 far, 0.75 at 0.6 m) */
    double min_range_m, max_range_m;  /**< sightings outside are dropped (0.3, 5.0 as the filters' sensor range) */
    vision_blob_method_t blobs;
} vision_config_t;

vision_config_t vision_config_default(void);

/** One marker seen in a frame. */
typedef struct {
    vision_marker_kind_t kind;  /**< VISION_MARKER_LANDMARK or VISION_MARKER_ROBOT */
    uint8_t index;              /**< landmark signature or robot id */
    double range_m;             /**< from the camera (robot centre) to the marker's axis */
    double bearing_rad;         /**< counter-clockwise from the optical axis */
    double range_var_m2;
    double bearing_var_rad2;
    double u_px;                /**< centroid column */
    double h_px;                /**< pixel height used for the range (sub-pixel) */
    uint16_t x, y, w, h;        /**< bounding box of both bands */
    uint8_t cut_side;           /**< 0; 1 / 2: a robot cut by the left / right side, placed from its visible edge */
} vision_marker_t;

typedef struct {
    uint16_t n_markers;
    vision_marker_t markers[VISION_MAX_MARKERS];
    uint16_t dropped;            /**< markers beyond VISION_MAX_MARKERS (also counted) */
    uint16_t rejected_border;    /**< pairs touching the image border (not measurable) */
    uint16_t edge_robots;        /**< robot markers cut by a side, placed from their visible edge */
    uint16_t rejected_range;     /**< markers outside [min_range_m, max_range_m] */
    uint16_t rejected_duplicate; /**< robot markers of an id already seen larger in this frame */
    uint32_t n_runs;             /**< runs labelled (VISION_BLOBS_RUNS) */
    uint32_t n_blobs;            /**< blobs kept (all colours) */
} vision_result_t;

/** A blob of the last frame (debugging, annotation, tests). */
typedef struct {
    uint8_t colour;              /**< vision_colour_t */
    uint16_t x, y, w, h;
    uint32_t area;
    double cx, cy;               /**< centroid */
} vision_blob_t;

/** Counters since creation. */
typedef struct {
    uint64_t frames;
    uint64_t runs_overflow;      /**< frames whose runs exceeded VISION_MAX_RUNS */
    uint64_t blobs_overflow;     /**< blobs beyond VISION_MAX_BLOBS, summed */
    uint64_t markers_overflow;   /**< markers beyond VISION_MAX_MARKERS, summed */
    uint64_t pairs_overflow;     /**< candidate pairs beyond VISION_MAX_PAIR_CANDIDATES, summed */
    uint64_t markers;            /**< markers reported */
} vision_counters_t;

typedef struct vision_detector vision_detector_t;

/** Create a detector: copies cfg, lut and model, allocates every buffer.
 *  model NULL: vision_range_model_pinhole(). Returns VISION_OK with *out
 *  set; VISION_E_ARG (NULL out/cfg/lut, size 0, non-positive focal
 *  length, min > max); VISION_E_NOMEM. */
vision_status_t vision_detector_create(vision_detector_t **out, const vision_config_t *cfg, const vision_lut_t *lut,
                                       const vision_range_model_t *model);
/** Release; NULL is a no-op. */
void vision_detector_destroy(vision_detector_t *det);

/** Detect markers in an RGB24 frame (rows top to bottom, stride_bytes >=
 *  3 * width). Returns VISION_OK with *out filled; VISION_E_ARG;
 *  VISION_E_CAPACITY (runs, blobs or candidate pairs overflowed: *out holds
 *  what was found in the part processed, counted; a pair overflow can leave
 *  out a real marker, since pairs are taken in blob order). Time: O(W H) plus O(blobs^2) pairing;
 *  about 0.3 ms for 320x240 on one x86-64 core (docs/vision.md). */
vision_status_t vision_detect_rgb(vision_detector_t *det, const uint8_t *rgb, uint32_t stride_bytes,
                                  vision_result_t *out);
/** Same for YUYV 4:2:2 (converted to RGB in a preallocated buffer first). */
vision_status_t vision_detect_yuyv(vision_detector_t *det, const uint8_t *yuyv, uint32_t stride_bytes,
                                   vision_result_t *out);

/** The colour class image of the last frame (width x height bytes, row
 *  stride = width), valid until the next detect; NULL before the first. */
const uint8_t *vision_detector_classes(const vision_detector_t *det);
/** The blobs of the last frame; returns their number, *blobs set. */
uint32_t vision_detector_blobs(const vision_detector_t *det, const vision_blob_t **blobs);
const vision_counters_t *vision_detector_counters(const vision_detector_t *det);
const vision_config_t *vision_detector_config(const vision_detector_t *det);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_VISION_VISION_H */
