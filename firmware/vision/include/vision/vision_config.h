/*
 * vision/vision_config.h - capacities of the detector (vision/vision.h).
 * Defaults here; a build or a test may define its own before including.
 * Memory: the detector allocates its buffers once, at
 * vision_detector_create, from these numbers and the image size (about
 * 20 * VISION_MAX_RUNS + 4 * width * height bytes; 0.6 MB at 320x240).
 */
#ifndef COSLAM_VISION_CONFIG_H
#define COSLAM_VISION_CONFIG_H

/** Runs (maximal horizontal stretches of one colour class) per frame. A
 *  rendered or real 320x240 frame has 300-3000; past the capacity the rows
 *  left are not labelled and the frame reports VISION_E_CAPACITY. */
#ifndef VISION_MAX_RUNS
#define VISION_MAX_RUNS 16384
#endif

/** Blobs (connected components of one colour, at least
 *  vision_config_t.min_blob_area_px pixels) considered for pairing. */
#ifndef VISION_MAX_BLOBS
#define VISION_MAX_BLOBS 512
#endif

/** Candidate blob pairs (a top blob and a bottom blob that may be one
 *  marker) per frame; past it, the pairs left are skipped, counted
 *  (pairs_overflow), and the frame reports VISION_E_CAPACITY. A marker is
 *  one candidate, so 8 per blob is far more than a frame holds. */
#ifndef VISION_MAX_PAIR_CANDIDATES
#define VISION_MAX_PAIR_CANDIDATES (8 * VISION_MAX_BLOBS)
#endif

/** Markers reported per frame (landmarks and robots together). */
#ifndef VISION_MAX_MARKERS
#define VISION_MAX_MARKERS 32
#endif

#if VISION_MAX_RUNS < 64 || VISION_MAX_RUNS > 1048576
#error "VISION_MAX_RUNS must be in [64, 2^20]"
#endif
#if VISION_MAX_BLOBS < 8 || VISION_MAX_BLOBS > 65535
#error "VISION_MAX_BLOBS must be in [8, 65535]"
#endif
#if VISION_MAX_PAIR_CANDIDATES < 1 || VISION_MAX_PAIR_CANDIDATES > 8 * 65535
#error "VISION_MAX_PAIR_CANDIDATES must be in [1, 8 * 65535]"
#endif
#if VISION_MAX_MARKERS < 1 || VISION_MAX_MARKERS > 255
#error "VISION_MAX_MARKERS must be in [1, 255]"
#endif

#endif /* COSLAM_VISION_CONFIG_H */
