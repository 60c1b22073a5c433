/*
 * robot_sightings.h - where coslam-robot gets its marker sightings
 * (app/sighting_source.h).
 *
 * robot_open_sightings() is the one place that chooses the source:
 *  - --sightings-fd N (cfg->camera_live_fd): the live stream of the e2e
 *    device server (robot_live_open below), END-TO-END TESTS ONLY: a
 *    stand-in for the camera where there is no V4L2 device (docs/e2e.md);
 *  - [camera] replay_log set: the landmark-log replay below, a TEST AND
 *    BENCH SOURCE, NOT A CAMERA;
 *  - [camera] device set: the camera, V4L2 + the marker detector
 *    (robot_camera.h), opened by the device slot (robot_devices.c); in a
 *    build without the V4L2 backend or firmware/vision it is reported "not
 *    available" once and the robot localises on odometry only;
 *  - neither: no camera configured.
 *
 * The replay source plays a landmark log in the format of DESIGN.md
 * ("Landmark log format"), one record per line, '#' comments:
 *   Z t id range bearing            a landmark sighting (id: -1 unknown, else
 *                                   the true id; used for nothing here: the
 *                                   robot sees non-unique markers, signature 0)
 *   R t other_robot_id range bearing  a sighting of another robot of the
 *                                   fleet (not this one: [robot] id, fleet_size)
 *   O t dx dy dth / V t v w         odometry: ignored (the drives give it)
 * t [s] counts from the moment the source was opened; records with the same
 * t form one frame, handed out when the clock reaches it (stamp = open time
 * + t); frames whose time passed while the caller was away are skipped
 * (their sequence numbers show the gap). t must not decrease. With loop
 * set the log starts again 0.2 s after its last record. The whole file is
 * checked when it is opened, so a bad log is refused at once with
 * FILE:LINE.
 *
 * Memory: caller-owned state, no heap (stdio's FILE buffer aside).
 */
#ifndef COSLAM_PORT_ROBOT_SIGHTINGS_H
#define COSLAM_PORT_ROBOT_SIGHTINGS_H

#include <stdint.h>
#include <stdio.h>

#include "app/sighting_source.h"
#include "hal/hal_clock.h"
#include "robot_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Gap between the end of a looped log and its start again [us]. */
#define ROBOT_REPLAY_LOOP_GAP_US 200000u

/** One parsed record of the log. */
typedef struct {
    char tag;             /**< 'Z' or 'R' */
    uint64_t t_us;        /**< log time [us] */
    int32_t id;           /**< landmark id or robot id */
    double range_m;
    double bearing_rad;
} robot_replay_record_t;

typedef struct {
    sighting_source_t src;        /**< the handle (src.backend = this) */
    FILE *f;
    char path[ROBOT_CONFIG_PATH_MAX + 1u];
    int loop;
    hal_clock_t *clock;
    uint64_t base_us;             /**< clock time of log t = 0 in the current pass */
    uint64_t last_t_us;           /**< largest t of the log */
    unsigned line;                /**< lines read in the current pass */
    int have_next;
    robot_replay_record_t next;   /**< one record of lookahead */
    int building_n;               /**< records in `building` */
    uint64_t building_t_us;
    sighting_frame_t building;    /**< the frame being collected */
    int ready;
    sighting_frame_t out;         /**< the newest complete frame not handed out */
    uint32_t sequence;            /**< frames completed */
    /* counters */
    uint32_t frames_given;
    uint32_t frames_skipped;      /**< completed but replaced by a newer one before a call */
    uint32_t records;             /**< Z and R records played */
    uint32_t ignored_records;     /**< O and V records */
    uint32_t loops;
    /* live mode (robot_live_open): frames come from a datagram socket */
    int live;                     /**< 1: this is the live source, f is unused */
    int live_fd;                  /**< our dup of the inherited socket */
    uint32_t live_bad;            /**< datagrams refused (bad text, no T line) */
    uint8_t own_id;               /**< live: [robot] id (an R record of it is refused) */
    uint8_t fleet_size;           /**< live: [robot] fleet_size (an R record of an id not below it is refused) */
    uint32_t live_robots_refused; /**< R records refused: this robot's own id, or not in the fleet */
    char live_refused_why[160];   /**< the first refusal's reason */
    int live_refusals_said;       /**< robot_live_say_refusals has said it */
} robot_replay_t;

/**
 * Open and check the log at `path` for robot `own_id` of a fleet of
 * `fleet_size` ([robot] id, fleet_size); t = 0 is now (clock). Returns
 * HAL_OK; HAL_E_NOT_FOUND (no such file); HAL_E_IO (unreadable);
 * HAL_E_CORRUPT (a bad line: msg "PATH:LINE: reason"; an R record of
 * own_id, or of an id not below fleet_size, is a bad line); HAL_E_ARG
 * (NULL). msg receives the reason of any failure.
 */
hal_status_t robot_replay_open(robot_replay_t *r, const char *path, int loop, uint8_t own_id, uint8_t fleet_size,
                               hal_clock_t *clock, char *msg, size_t msg_cap);

/**
 * The live sighting stream (END-TO-END TESTS ONLY: a stand-in for the camera
 * where there is no V4L2 device; docs/e2e.md). `fd` is an inherited
 * SOCK_SEQPACKET (or SOCK_DGRAM) socket; it is dup'ed, so the inherited one
 * stays open for a reopen after a failure. One datagram is one frame, text:
 *   T stamp_us                       capture time, CLOCK_MONOTONIC [us]
 *   S t signature range bearing      a marker of class `signature` (0..255)
 *   Z t id range bearing             the landmark-log records above (t is
 *   R t other_robot_id range bearing the sender's simulated time, ignored)
 * A datagram without its T line or with a bad line is refused and counted
 * (live_bad). An R record of own_id, or of an id not below fleet_size
 * ([robot] id, fleet_size), is refused as the landmark log refuses it at
 * open: the record only (the frame's other sightings are kept), counted
 * in live_robots_refused, the first reason kept for
 * robot_live_say_refusals. next_frame never waits: it drains what is
 * queued and hands out the newest frame (older ones count in
 * frames_skipped). The peer's close answers HAL_E_CLOSED. Returns HAL_OK;
 * HAL_E_ARG (NULL, fd < 0); HAL_E_IO (dup failed: msg says why).
 */
hal_status_t robot_live_open(robot_replay_t *r, int fd, uint8_t own_id, uint8_t fleet_size, hal_clock_t *clock,
                             char *msg, size_t msg_cap);

/** The live stream's refused robot sightings, said once on `out` (the
 *  first one's reason; the rest are only counted): 1 if said now, else 0
 *  (none refused, said already, or not the live source). A reopen of the
 *  stream (robot_live_open) starts its counters and this again; the totals
 *  the robot reports are kept by its device slot
 *  (robot_devices_live_counters). */
int robot_live_say_refusals(robot_replay_t *r, FILE *out);

/** Close the file (the handle then answers HAL_E_CLOSED). */
void robot_replay_close(robot_replay_t *r);

/** Hand the source opened in `from` over to `to` (a closed source): `to`
 *  becomes it, its handle (to->src) pointing at `to`; `from` is left
 *  closed (its file and socket belong to `to` now). A device slot opens
 *  into a private source on its opener thread and publishes it this way on
 *  the loop's thread, so that what the loop reads is never written by the
 *  opener (robot_devices.h). */
void robot_replay_move(robot_replay_t *to, robot_replay_t *from);

/** What robot_open_sightings chose. */
typedef enum {
    ROBOT_SIGHTINGS_NONE = 0,    /**< no camera configured */
    ROBOT_SIGHTINGS_NO_CAMERA,   /**< a camera is configured, but this build has no camera pipeline */
    ROBOT_SIGHTINGS_CAMERA,      /**< the camera: V4L2 + marker detector (robot_camera.h) */
    ROBOT_SIGHTINGS_REPLAY,      /**< the landmark-log replay (test / bench) */
    ROBOT_SIGHTINGS_LIVE,        /**< the live stream of the e2e device server (--sightings-fd) */
} robot_sightings_kind_t;

/** The kind robot_open_sightings would choose for cfg, without opening
 *  anything (the start-up hands the open to the camera slot's opener). */
robot_sightings_kind_t robot_sightings_kind(const robot_config_t *cfg);

/**
 * Choose and open the sighting source for cfg (header comment). Returns
 * the kind (cfg->camera_live_fd >= 0 first: the live stream); for
 * ROBOT_SIGHTINGS_REPLAY and ROBOT_SIGHTINGS_LIVE *st is the open status of the
 * replay (HAL_OK or its error, with msg), else HAL_E_UNSUPPORTED (the
 * camera is opened by the caller: robot_camera_open_*).
 */
robot_sightings_kind_t robot_open_sightings(robot_replay_t *r, const robot_config_t *cfg, hal_clock_t *clock,
                                            hal_status_t *st, char *msg, size_t msg_cap);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_SIGHTINGS_H */
