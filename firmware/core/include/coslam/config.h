/*
 * coslam/config.h - the one place where the core's capacities are set.
 *
 * Every static array in firmware/core is sized by a macro from this file.
 * Two profiles exist:
 *   - default  (COSLAM_PROFILE_LARGE undefined): the paper's scale,
 *              100 particles, 64 landmarks per map.
 *   - large    (-DCOSLAM_PROFILE_LARGE=1):       1000 particles, 256 landmarks.
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

#if defined(COSLAM_PROFILE_LARGE) && COSLAM_PROFILE_LARGE
#define COSLAM_PROFILE_NAME_ "large"
#ifndef COSLAM_MAX_PARTICLES
#define COSLAM_MAX_PARTICLES 1000
#endif
#ifndef COSLAM_MAX_LANDMARKS
#define COSLAM_MAX_LANDMARKS 256
#endif
#else
#define COSLAM_PROFILE_NAME_ "default"
/** Particles in a Fast-SLAM filter (static pool). */
#ifndef COSLAM_MAX_PARTICLES
#define COSLAM_MAX_PARTICLES 100
#endif
/** Landmarks in one Fast-SLAM particle's map, and in the EKF-SLAM state. */
#ifndef COSLAM_MAX_LANDMARKS
#define COSLAM_MAX_LANDMARKS 64
#endif
#endif

/** Name of the selected profile, for reports. */
#define COSLAM_PROFILE_NAME COSLAM_PROFILE_NAME_

/** Sightings (landmark observations) accepted in one filter update. */
#ifndef COSLAM_MAX_SIGHTINGS
#define COSLAM_MAX_SIGHTINGS 16
#endif

/** Landmarks carried by one map estimate / map message. */
#ifndef COSLAM_MAX_MSG_LANDMARKS
#define COSLAM_MAX_MSG_LANDMARKS COSLAM_MAX_LANDMARKS
#endif

/** Distinct landmark identities the Fast-SLAM export can combine over the
 *  particles (hash table size). Identities beyond it are counted and skipped. */
#ifndef COSLAM_MAX_EXPORT_IDS
#define COSLAM_MAX_EXPORT_IDS (4 * COSLAM_MAX_LANDMARKS)
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
#if COSLAM_MAX_MSG_LANDMARKS < 1 || COSLAM_MAX_MSG_LANDMARKS > 65535
#error "COSLAM_MAX_MSG_LANDMARKS must be in [1, 65535]"
#endif
#if COSLAM_MAX_EXPORT_IDS < COSLAM_MAX_LANDMARKS
#error "COSLAM_MAX_EXPORT_IDS must be at least COSLAM_MAX_LANDMARKS"
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
