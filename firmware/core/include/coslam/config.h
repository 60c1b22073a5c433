/*
 * coslam/config.h - the one place where the core's capacities are set.
 *
 * Every static array in firmware/core is sized by a macro from this file.
 * Three profiles exist, one per build (make PROFILE=..., CMake
 * COSLAM_PROFILE): every library and binary of a build uses the same one
 * and prints it at start-up (app/profile.h; README "Profiles"):
 *   - default (neither macro below): the paper's scale, the robot's
 *             profile: 100 particles, 64 landmarks, 16 sightings per frame.
 *   - large   (-DCOSLAM_PROFILE_LARGE=1): 1000 particles, 256 landmarks,
 *             16 sightings; messages capped at 221 landmarks (the link).
 *   - host    (-DCOSLAM_PROFILE_HOST=1): host tools at scale: 1000
 *             particles, 2048 landmarks (EKF-SLAM 1024), 64 sightings;
 *             messages capped at 221 landmarks (the link).
 * Any single macro can be overridden on the compiler command line
 * (-DCOSLAM_MAX_PARTICLES=500) or by pointing COSLAM_CONFIG_HEADER at a header
 * of your own that is included first (tests and benchmarks do this).
 *
 * Running out of any capacity is never a silent drop: the call returns
 * COSLAM_E_CAPACITY and bumps a per-instance counter (see status.h).
 */
#ifndef COSLAM_CONFIG_H
#define COSLAM_CONFIG_H

#ifdef COSLAM_CONFIG_HEADER
#include COSLAM_CONFIG_HEADER
#endif

#if defined(COSLAM_PROFILE_LARGE) && COSLAM_PROFILE_LARGE && defined(COSLAM_PROFILE_HOST) && COSLAM_PROFILE_HOST
#error "choose one profile: COSLAM_PROFILE_LARGE or COSLAM_PROFILE_HOST (make PROFILE=...)"
#endif

#if defined(COSLAM_PROFILE_HOST) && COSLAM_PROFILE_HOST
#define COSLAM_PROFILE_NAME_ "host"
#ifndef COSLAM_MAX_PARTICLES
#define COSLAM_MAX_PARTICLES 1000
#endif
#ifndef COSLAM_MAX_LANDMARKS
#define COSLAM_MAX_LANDMARKS 2048
#endif
#ifndef COSLAM_MAX_SIGHTINGS
#define COSLAM_MAX_SIGHTINGS 64
#endif
/* EKF-SLAM's dense covariance grows with the square of its landmarks
 * (8 (2L + 6)^2 bytes: 134 MB at 2048, 34 MB at 1024) and its update with
 * the square of the state: the host profile's EKF keeps 1024 (the issue-13
 * scale, 10 ms per step), Fast-SLAM the full 2048. */
#ifndef COSLAM_EKF_MAX_LANDMARKS
#define COSLAM_EKF_MAX_LANDMARKS 1024
#endif
/* The compressed EKF's active part (ekfslam.h): at 2 landmarks per m^2
 * the region around the sensor holds 100-200 of them (docs/core-slam.md). */
#ifndef COSLAM_EKF_MAX_ACTIVE
#define COSLAM_EKF_MAX_ACTIVE 256
#endif
#elif defined(COSLAM_PROFILE_LARGE) && COSLAM_PROFILE_LARGE
#define COSLAM_PROFILE_NAME_ "large"
#ifndef COSLAM_MAX_PARTICLES
#define COSLAM_MAX_PARTICLES 1000
#endif
#ifndef COSLAM_MAX_LANDMARKS
#define COSLAM_MAX_LANDMARKS 256
#endif
#ifndef COSLAM_EKF_MAX_ACTIVE
#define COSLAM_EKF_MAX_ACTIVE 64
#endif
#else
#define COSLAM_PROFILE_NAME_ "default"
/** Particles in a Fast-SLAM filter (static pool). */
#ifndef COSLAM_MAX_PARTICLES
#define COSLAM_MAX_PARTICLES 100
#endif
/** Landmarks in one Fast-SLAM particle's map (and, unless
 *  COSLAM_EKF_MAX_LANDMARKS says otherwise, in the EKF-SLAM state). */
#ifndef COSLAM_MAX_LANDMARKS
#define COSLAM_MAX_LANDMARKS 64
#endif
#endif

/** Name of the selected profile, for reports. A core built with capacities
 *  of its own (a benchmark's) names itself with -DCOSLAM_PROFILE_NAME=... */
#ifndef COSLAM_PROFILE_NAME
#define COSLAM_PROFILE_NAME COSLAM_PROFILE_NAME_
#endif

/** Sightings (landmark observations) accepted in one filter update. */
#ifndef COSLAM_MAX_SIGHTINGS
#define COSLAM_MAX_SIGHTINGS 16
#endif

/** Landmarks in the EKF-SLAM state: its own capacity, because its memory
 *  (the dense covariance) grows with the square of it. At most
 *  COSLAM_MAX_LANDMARKS; running out is counted and reported like the
 *  Fast-SLAM map's (lm_capacity_drops, naming this macro). */
#ifndef COSLAM_EKF_MAX_LANDMARKS
#define COSLAM_EKF_MAX_LANDMARKS COSLAM_MAX_LANDMARKS
#endif

/** Landmarks in the compressed EKF's active part (ekfslam_config_t.
 *  active_radius_m): its auxiliary matrices take 16 (3 + 2 N)^2 bytes. 0
 *  (the default profile, at most 64 landmarks, where the full update is
 *  cheap) leaves the compression out: active_radius_m must then be 0. */
#ifndef COSLAM_EKF_MAX_ACTIVE
#define COSLAM_EKF_MAX_ACTIVE 0
#endif

/** Global updates of the compressed EKF whose deferred part may be
 *  pending at once (ekfslam.c "The deferred part of a global update"):
 *  each takes 16 COSLAM_EKF_MAX_LANDMARKS (3 + 2 COSLAM_EKF_MAX_ACTIVE)
 *  bytes of u rows plus 8 (3 + 2 COSLAM_EKF_MAX_ACTIVE)^2 of psi (8.4 and
 *  2.1 MB in the host profile). A global update that finds all of them
 *  pending completes the oldest at once (ekfslam_counters_t.
 *  cekf_spread_gens_full). 2 where the compression is compiled in, else 1
 *  (its buffers then sized 1). */
#ifndef COSLAM_EKF_PEND_GENS
#define COSLAM_EKF_PEND_GENS (COSLAM_EKF_MAX_ACTIVE > 0 ? 2 : 1)
#endif

/**
 * Landmarks that fit one map message in one link datagram: the largest n
 * with map_msg.h's MAP_MSG_BYTES(n) = 142 + 73 n plus the 64 bytes a link
 * decorator may append (the authentication trailer, HAL_LINK_TRAILER_RESERVE)
 * within HAL_LINK_MAX_PAYLOAD = 16384: n = 221 (16,275 B + 64). The core
 * does not include the HAL; the link code and the robot app hold this number
 * to the link with compile-time assertions (hal_link_auth.c, hal_link_dds.c,
 * meeting.c), so a build whose message cannot fit does not compile.
 */
#define COSLAM_LINK_MSG_LANDMARKS 221

/** Landmarks carried by one map estimate / map message: the map capacity,
 *  capped at what fits the link (COSLAM_LINK_MSG_LANDMARKS). A larger map
 *  sends its best landmarks (the filters' export chooses, docs/map-message.md)
 *  and counts the rest (export_capacity_drops, a LIMIT line). */
#ifndef COSLAM_MAX_MSG_LANDMARKS
#if COSLAM_MAX_LANDMARKS < COSLAM_LINK_MSG_LANDMARKS
#define COSLAM_MAX_MSG_LANDMARKS COSLAM_MAX_LANDMARKS
#else
#define COSLAM_MAX_MSG_LANDMARKS COSLAM_LINK_MSG_LANDMARKS
#endif
#endif

/** Distinct landmark identities the Fast-SLAM export can combine over the
 *  particles (hash table size). Identities beyond it are counted and skipped. */
#ifndef COSLAM_MAX_EXPORT_IDS
#define COSLAM_MAX_EXPORT_IDS (4 * COSLAM_MAX_LANDMARKS)
#endif

/** Candidate duplicate pairs one merge considers per map (map_merge.c): an
 *  (own, incoming) pair of one marker class inside the duplicate gate.
 *  Beyond it the nearest are kept (the pairing of the rest is then exact)
 *  and an incoming landmark left unpaired that lost a candidate is neither
 *  fused nor added, counted (merge_pair_drops, a LIMIT line). About 16
 *  bytes each (merge_scratch_t). */
#ifndef COSLAM_MERGE_MAX_PAIRS
#define COSLAM_MERGE_MAX_PAIRS (4 * COSLAM_MAX_MSG_LANDMARKS)
#endif

/** Occupancy grid size in cells (x, y) and cell edge [mm] (log-odds grid). */
#ifndef COSLAM_GRID_CELLS_X
#define COSLAM_GRID_CELLS_X 200
#endif
#ifndef COSLAM_GRID_CELLS_Y
#define COSLAM_GRID_CELLS_Y 200
#endif
#ifndef COSLAM_GRID_CELL_MM
#define COSLAM_GRID_CELL_MM 50
#endif

/** Range readings in one laser scan (URG-04LX: 682 steps; UTM-30LX: 1081). */
#ifndef COSLAM_MAX_SCAN_POINTS
#define COSLAM_MAX_SCAN_POINTS 1081
#endif

/** Bearing bins of the view profile (view.h): the obstacles around the robot
 *  that the laser saw, so that a landmark behind one is not counted as
 *  missed. 128 bins of 2.8 deg; 4 bytes each, one profile per filter. */
#ifndef COSLAM_VIEW_BINS
#define COSLAM_VIEW_BINS 128
#endif

/** Robots in a team; bounds robot ids and the per-landmark provenance mask. */
#ifndef COSLAM_MAX_ROBOTS
#define COSLAM_MAX_ROBOTS 16
#endif

/** Bumper inputs and status LEDs handled by the GPIO roles driver
 *  (firmware/drivers/gpio_roles); each is a bit in a uint32_t mask. */
#ifndef COSLAM_MAX_BUMPERS
#define COSLAM_MAX_BUMPERS 4
#endif
#ifndef COSLAM_MAX_STATUS_LEDS
#define COSLAM_MAX_STATUS_LEDS 4
#endif

/** Robot app (firmware/app): own sightings of each peer robot kept to pair
 *  with an incoming map message (meeting.h), and merge events queued until
 *  the application reads them. */
#ifndef COSLAM_APP_SIGHTING_HISTORY
#define COSLAM_APP_SIGHTING_HISTORY 16
#endif
#ifndef COSLAM_APP_EVENT_QUEUE
#define COSLAM_APP_EVENT_QUEUE 16
#endif

/*
 * Range checks. The upper bounds keep index types (uint16_t landmark and
 * particle indices, uint16_t provenance mask) valid, not memory sensible.
 */
#if COSLAM_MAX_PARTICLES < 1 || COSLAM_MAX_PARTICLES > 65535
#error "COSLAM_MAX_PARTICLES must be in [1, 65535]"
#endif
#if COSLAM_MAX_LANDMARKS < 1 || COSLAM_MAX_LANDMARKS > 65535
#error "COSLAM_MAX_LANDMARKS must be in [1, 65535]"
#endif
#if COSLAM_MAX_SIGHTINGS < 1 || COSLAM_MAX_SIGHTINGS > 255
#error "COSLAM_MAX_SIGHTINGS must be in [1, 255]"
#endif
#if COSLAM_EKF_MAX_LANDMARKS < 1 || COSLAM_EKF_MAX_LANDMARKS > COSLAM_MAX_LANDMARKS
#error "COSLAM_EKF_MAX_LANDMARKS must be in [1, COSLAM_MAX_LANDMARKS]"
#endif
#if COSLAM_EKF_MAX_ACTIVE < 0 || COSLAM_EKF_MAX_ACTIVE > COSLAM_EKF_MAX_LANDMARKS
#error "COSLAM_EKF_MAX_ACTIVE must be in [0, COSLAM_EKF_MAX_LANDMARKS]"
#endif
#if COSLAM_EKF_PEND_GENS < 1 || COSLAM_EKF_PEND_GENS > 8
#error "COSLAM_EKF_PEND_GENS must be in [1, 8]"
#endif
#if COSLAM_MAX_MSG_LANDMARKS < 1 || COSLAM_MAX_MSG_LANDMARKS > 65535
#error "COSLAM_MAX_MSG_LANDMARKS must be in [1, 65535]"
#endif
#if COSLAM_MERGE_MAX_PAIRS < COSLAM_MAX_MSG_LANDMARKS || COSLAM_MERGE_MAX_PAIRS > 16777216
#error "COSLAM_MERGE_MAX_PAIRS must be in [COSLAM_MAX_MSG_LANDMARKS, 2^24]"
#endif
#if COSLAM_MAX_EXPORT_IDS < COSLAM_MAX_LANDMARKS
#error "COSLAM_MAX_EXPORT_IDS must be at least COSLAM_MAX_LANDMARKS"
#endif
#if COSLAM_VIEW_BINS < 8 || COSLAM_VIEW_BINS > 4096
#error "COSLAM_VIEW_BINS must be in [8, 4096]"
#endif
#if COSLAM_GRID_CELLS_X < 8 || COSLAM_GRID_CELLS_X > 4096 || COSLAM_GRID_CELLS_Y < 8 || COSLAM_GRID_CELLS_Y > 4096
#error "COSLAM_GRID_CELLS_X/Y must be in [8, 4096]"
#endif
#if COSLAM_GRID_CELL_MM < 5 || COSLAM_GRID_CELL_MM > 1000
#error "COSLAM_GRID_CELL_MM must be in [5, 1000]"
#endif
#if COSLAM_MAX_SCAN_POINTS < 16 || COSLAM_MAX_SCAN_POINTS > 4096
#error "COSLAM_MAX_SCAN_POINTS must be in [16, 4096]"
#endif
#if COSLAM_MAX_ROBOTS < 2 || COSLAM_MAX_ROBOTS > 16
#error "COSLAM_MAX_ROBOTS must be in [2, 16] (provenance is a 16-bit mask)"
#endif

#if COSLAM_MAX_BUMPERS < 1 || COSLAM_MAX_BUMPERS > 32
#error "COSLAM_MAX_BUMPERS must be in [1, 32] (a uint32_t mask)"
#endif
#if COSLAM_MAX_STATUS_LEDS < 1 || COSLAM_MAX_STATUS_LEDS > 32
#error "COSLAM_MAX_STATUS_LEDS must be in [1, 32]"
#endif

#if COSLAM_APP_SIGHTING_HISTORY < 1 || COSLAM_APP_SIGHTING_HISTORY > 255
#error "COSLAM_APP_SIGHTING_HISTORY must be in [1, 255]"
#endif
#if COSLAM_APP_EVENT_QUEUE < 1 || COSLAM_APP_EVENT_QUEUE > 255
#error "COSLAM_APP_EVENT_QUEUE must be in [1, 255]"
#endif

#endif /* COSLAM_CONFIG_H */
