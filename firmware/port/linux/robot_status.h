/*
 * robot_status.h - the status report of coslam-robot: one list of
 * key = value pairs, written as one grep-able line on stderr
 * ("coslam-robot: status t=12.0 state=run ... ") and, for monitoring, as a
 * JSON object to a file replaced atomically (temporary file in the same
 * directory, then rename(2)).
 *
 * Keys (all counters only grow; see docs/robot.md for each):
 *   t uptime [s]; id; state (node state); mode (behaviour);
 *   laser can gpio camera link storage: up | down | absent;
 *   steps overruns late_max_us cpu_pct: the main loop (CPU over the last
 *     report period, user + system, percent of one core);
 *   laser_streaming (1 while the node has the laser connected);
 *   the robot node's counters (robot_node_counters_t, same names), and
 *     diverged_now (the health monitor's judgement now);
 *   drive_odo_gaps drive_saturations drive_rx_overflows drive_rx_foreign
 *     drive_hb_failures: the drive driver's (cia402_omni_t odo_gaps,
 *     saturations, rx_overflows, rx_foreign, master_hb_failures);
 *   can_stamps_unbelieved (the SocketCAN backend's kernel stamps not
 *     believed, robot_devices_can_stamps_unbelieved: since the start,
 *     across the bus's reopens);
 *   mt_* the meeting's counters (meeting_counters_t), mt_rebased;
 *   the filter's loss counters (slam_filter_limits: lm_capacity_drops,
 *     sighting_capacity_drops, export_capacity_drops, rejected_controls,
 *     rejected_sightings, numeric_faults, merge_pair_drops,
 *     tree_capacity_drops), 0 when nothing was lost;
 *   view_pairs view_misses (slam_filter_view_counts: the filter's
 *     confirmed landmarks a miss would count, found or not; their ratio is
 *     the rate the miss weight stands for, docs/core-slam.md);
 *   urg_* the laser driver's (scans_ok, the err_ counters, resyncs,
 *     bytes_discarded, messages_skipped, fields_truncated, stamp_backwards;
 *     urg_rx_search_bytes, the bytes it looked at waiting for whole
 *     messages, robot_node_laser_rx_search_bytes: since the start, across
 *     the driver's resets at a lost laser);
 *   link_mode: auth | insecure | off(no_fleet_key) | off(no_dds_in_build)
 *     | off(no_auth_in_build); on stderr a link that is not authenticated
 *     also ends every line with "WARNING: link: ..." (robot_link_warning);
 *   dds_* the DDS link's counters (hal_link_dds_counters_t names, summed
 *     over reopened instances); link_opens link_open_failures link_losses;
 *   auth_* the authentication decorator's (hal_link_auth_counters_t
 *     names: every refusal by its reason; auth_refused their sum);
 *   landmarks x y theta (SLAM pose, map frame [m, m, rad]);
 *   snap_seq snap_saves snap_failures; snap_writing_ms (how long the
 *     snapshot write in flight has taken so far, 0 if none),
 *     snap_write_max_ms, snap_busy_skips (periodic snapshots not taken
 *     because the last write still ran), snap_no_writer_skips (snapshots
 *     not written because the writer thread was not running: it could not
 *     be started), snap_writer_start_failures (its starts that failed),
 *     snap_final_timeouts (the stop's snapshot jobs not returned within
 *     its 5 s wait: no final snapshot), snap_start_read_timeouts (the
 *     start-up read of the snapshots not returned within 5 s: a new map);
 *   status_file_failures (--status-file writes that failed);
 *   cam_* the camera's counters (robot_camera_counters_t names) when a
 *     V4L2 camera is configured.
 */
#ifndef COSLAM_PORT_ROBOT_STATUS_H
#define COSLAM_PORT_ROBOT_STATUS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "app/robot_node.h"
#include "robot_devices.h"
#include "robot_snapshot.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Longest list of pairs (179 with every device and the camera, counted
 *  from robot_status_collect; the last slot is kept for "status_dropped",
 *  below). */
#define ROBOT_STATUS_MAX_KV 192
/** Longest value text [characters, without NUL]. */
#define ROBOT_STATUS_VALUE_MAX 31u

typedef struct {
    const char *key;                       /**< static string */
    char value[ROBOT_STATUS_VALUE_MAX + 1u];
    int is_text;                           /**< JSON string (else a number) */
} robot_status_kv_t;

typedef struct {
    robot_status_kv_t kv[ROBOT_STATUS_MAX_KV];
    int n;
    uint32_t dropped;                      /**< pairs beyond ROBOT_STATUS_MAX_KV - 1 (never expected; then
                                                the report ends with status_dropped=N) */
} robot_status_t;

/** What the main loop knows beside the node. */
typedef struct {
    double uptime_s;
    uint64_t steps;                        /**< loop iterations */
    uint32_t overruns;                     /**< steps that ended after the next deadline */
    uint32_t late_max_us;                  /**< largest lateness */
    double cpu_pct;                        /**< over the last report period */
    uint16_t landmarks;                    /**< exported landmarks (the observers' last export) */
    uint64_t idle_calls;                   /**< robot_node_idle calls (several a step while parts remain) */
    uint32_t snap_writing_ms;              /**< age of the snapshot write in flight, 0 if none */
    uint32_t status_file_failures;         /**< --status-file writes that failed (the first one of a run
                                                of failures is said, the rest only counted) */
} robot_loop_stats_t;

/** Gather the report (the node's counters read as they are now). O(pairs). */
void robot_status_collect(robot_status_t *s, robot_node_t *node, const robot_devices_t *dev,
                          const robot_snapshots_t *snaps, const robot_loop_stats_t *loop);

/** "key=value key=value ..." into buf (truncated to cap, terminated).
 *  Returns the length written. */
size_t robot_status_line(const robot_status_t *s, char *buf, size_t cap);

/** Write the JSON object to `path` atomically ("<path>.tmp", rename).
 *  Returns 0, or -1 with errno set. */
int robot_status_write_json(const robot_status_t *s, const char *path);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_STATUS_H */
