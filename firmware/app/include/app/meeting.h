/*
 * app/meeting.h - the meeting protocol: when two robots see each other they
 * exchange map messages over the link and each merges the other's map
 * (paper sec. 2.1; geometry and maths in coslam/map_merge.h).
 *
 * Sending (meeting_on_sighting, called with every sighting of a peer robot
 * right after the frame's filter update):
 *  - Only sightings of j within max_range_m count (the transform from the
 *    mutual sightings degrades with range: bearing noise times distance).
 *  - A meeting with peer j starts at the first sighting of j after j was
 *    out of view for meeting_gap_us. During a meeting the robot sends j its
 *    map at most max_sends times, resend_period_us apart, each time on a
 *    frame in which it sees j (the link is unreliable: retries, not acks).
 *  - Implicit acknowledgement: a message from j in which at least half as
 *    many landmarks carry this robot's provenance bit as the last message
 *    sent to j had landmarks ends the sending to j for that meeting; a
 *    message from j without our bit renews the budget (j still needs it).
 *  - The message (coslam/map_msg.h) is addressed to j and carries:
 *      map        the sender's map estimate exported NOW (pose, pose
 *                 covariance, landmarks with cov and cov_rel), map frame;
 *                 a Fast-SLAM export that does not fit one step's budget
 *                 (merge.step_units) is done in the idle time after the
 *                 following steps and sent by meeting_send_due, the map
 *                 and pose still those of this moment;
 *      stamp_us   the time the message goes out (sender's clock);
 *      sighting   the sender's sighting of j in the frame just processed:
 *                 range, bearing (sender's body frame), their variances
 *                 (robot_range_var_m2 + robot_range_var_per_m2 range^2,
 *                 robot_bearing_var_rad2) and the
 *                 frame's capture stamp_us (sender's clock).
 *    So the exported pose is the sender's pose at its sighting of j, up to
 *    one control period (the export begins after the frame's update in the
 *    same control step), and stamp_us - sighting.stamp_us is the
 *    sighting's age when the message leaves. Only differences
 *    of the sender's stamps are used by the receiver, never its absolute
 *    clock: robots need no common time base.
 *
 * Receiving (meeting_poll_link, then meeting_poll):
 *  1. decode (every COSLAM_E_MSG_* refusal is counted and logged); drop
 *     messages not addressed to this robot, or without a sighting;
 *  2. ignore the sender while the merge of its map is being decided in
 *     idle time (merge_waiting), and for remerge_period_us after its map
 *     was merged (the remaining retries of the same meeting), or refused
 *     because the maps disagreed (a retry would pass the test only by
 *     chance);
 *  3. merge_session_accept: sequence number newer than the last accepted
 *     one from that sender, else refused as a replay (counted);
 *  4. the message waits (one pending slot; a newer one replaces it,
 *     counted) until this robot has its own sighting of the sender close in
 *     time to the sender's sighting. Once it pairs with one, the link is
 *     not read until meeting_poll has merged it: another peer's message
 *     arriving in the same poll would otherwise replace it, and with
 *     three robots meeting at once one of them could lose every retry. The sender's sighting time in this
 *     robot's clock is estimated as
 *         t_s = arrival_us - link_latency_us - (stamp_us - sighting.stamp_us);
 *     the own sighting nearest to t_s is used if |t_own - t_s| <=
 *     pair_window_us. If none comes before now > t_s + pair_window_us the
 *     message is dropped as stale (COSLAM_E_MERGE_STALE, counted). The own
 *     sightings of a peer are kept in a history of
 *     COSLAM_APP_SIGHTING_HISTORY that reaches at least that many times
 *     pair_window_us / 3 back (1.6 s by default) whatever the camera's
 *     rate: sightings that come faster are thinned in the middle, never
 *     the newest (history_thinned);
 *  5. slam_filter_merge_map, the one merge path (app/slam_filter.h): the
 *     two sightings, this robot's odometry since its own sighting (noise
 *     from the filter's own parameters) and |t_own - t_s| go to
 *     merge_prepare; then merge_check against the own map and coverage,
 *     then the fusion. The filter's pose must be current (the caller
 *     predicts with all odometry before meeting_poll). A refused merge
 *     (ranges or maps disagree) is an event with its reason and changes
 *     nothing.
 * Sending exports only landmarks with at least export_min_obs sightings
 * (never tentative ones: the filters export confirmed landmarks only).
 * Every send, merge and refusal is queued as a meeting_event_t.
 *
 * Memory: meeting_t holds two map messages, the wire buffer and the merge
 * scratch (about 40 KB in the default profile). Caller-owned, no heap, no
 * globals. Calls never block (link timeouts 0). One thread at a time.
 */
#ifndef COSLAM_APP_MEETING_H
#define COSLAM_APP_MEETING_H

#include <stdint.h>

#include "app/slam_filter.h"
#include "coslam/config.h"
#include "coslam/map_merge.h"
#include "coslam/map_msg.h"
#include "coslam/pose2.h"
#include "coslam/status.h"
#include "hal/hal_link.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Datagrams taken from the link per meeting_poll_link call (a time budget). */
#define MEETING_RX_BUDGET 8

typedef struct {
    double robot_range_var_m2;       /**< variance of own robot sightings' range [m^2], > 0 */
    double robot_range_var_per_m2;   /**< plus this * range^2 (distance from blob size) [1], >= 0 */
    double robot_bearing_var_rad2;   /**< and bearing [rad^2], > 0 */
    uint32_t link_latency_us;        /**< nominal one-way link latency [us] */
    uint32_t pair_window_us;         /**< largest |own sighting - sender's sighting| [us], > 0 */
    uint32_t resend_period_us;       /**< between two messages to one peer [us] */
    uint8_t max_sends;               /**< messages per meeting and peer (0: never send) */
    uint32_t meeting_gap_us;         /**< a peer unseen this long ends the meeting [us] */
    uint32_t remerge_period_us;      /**< after merging a peer, ignore it this long [us] */
    double max_range_m;              /**< peers sighted farther away do not start or feed a meeting [m], > 0 */
    uint16_t export_min_obs;         /**< landmarks sent must have this many sightings (>= 1) */
    merge_config_t merge;            /**< set-up, check and fusion (map_merge.h) */
} meeting_config_t;

/** An own sighting of a peer, with the odometry state at that moment. */
typedef struct {
    uint64_t stamp_us;     /**< capture time, own clock */
    double range_m;
    double bearing_rad;
    pose2_t odo_pose;      /**< own dead-reckoning pose then */
    double travel_m;       /**< own odometer (wheel travel) then [m] */
} meeting_sighting_t;

typedef struct {
    meeting_sighting_t hist[COSLAM_APP_SIGHTING_HISTORY]; /**< ring, newest at head - 1 (thinned
                                                                 when sightings come fast, meeting.c hist_push) */
    uint8_t n_hist;
    uint8_t head;
    uint8_t in_meeting;
    uint8_t sends;          /**< messages sent in the current meeting */
    uint64_t last_seen_us;
    uint8_t sent_any;       /**< a message was ever sent to it (last_sent_us is valid) */
    uint64_t last_sent_us;
    uint8_t merged;         /**< this peer's map was merged at least once */
    uint64_t merged_at_us;
    uint8_t acked;          /**< the peer's last message showed it holds our map */
    uint64_t acked_at_us;
    uint64_t meeting_start_us; /**< first sighting of the current meeting */
    uint16_t sent_n_landmarks; /**< landmarks in the last message sent to it */
    uint8_t disagreed;         /**< its map was refused as disagreeing ... */
    uint64_t disagreed_at_us;  /**< ... then: its messages are ignored for remerge_period_us */
} meeting_peer_t;

typedef enum {
    MEETING_EV_SENT = 1,    /**< a map message went out */
    MEETING_EV_MERGED = 2,  /**< a peer's map was merged (status may be COSLAM_E_CAPACITY: partly) */
    MEETING_EV_REFUSED = 3, /**< an incoming message was refused (status says why) */
} meeting_event_kind_t;

typedef struct {
    meeting_event_kind_t kind;
    uint64_t stamp_us;          /**< when (own clock); for a merge, when it began (the
                                     moment of the body frame of other_in_self), also
                                     if its check waited for idle time */
    uint8_t peer;               /**< the other robot (0xFF: unknown, undecodable message) */
    uint32_t seq;               /**< the message's sequence number */
    coslam_status_t status;     /**< COSLAM_OK, or the reason of a refusal / partial merge */
    uint16_t n_landmarks;       /**< landmarks in the message */
    /* MERGED only */
    uint64_t own_sighting_us;   /**< own sighting paired with the sender's */
    uint64_t sender_sighting_us;/**< sender's sighting, estimated in own clock */
    pose2_t other_in_self;      /**< sender at its sighting, in own body frame at stamp_us */
    cov3_t other_in_self_cov;
    merge_stats_t stats;        /**< MERGED and refusals by the check */
} meeting_event_t;

typedef struct {
    uint32_t sent;              /**< messages handed to the link */
    uint32_t send_failures;     /**< export/encode/link refusals */
    uint32_t received;          /**< datagrams taken from the link */
    uint32_t rx_errors;         /**< link errors and undecodable messages */
    uint32_t not_for_me;        /**< addressed to another robot, or without a sighting */
    uint32_t wrong_sender;      /**< claimed sender != the link's sender id (refused) */
    uint32_t ignored_recent;    /**< from a peer merged within remerge_period_us, or whose
                                     merge is being decided (merge_waiting) */
    uint32_t replays;           /**< refused by the merge session (old sequence number) */
    uint32_t pending_replaced;  /**< a pending message replaced by a newer one */
    uint32_t stale;             /**< no own sighting within the window */
    uint32_t merged;            /**< maps merged */
    uint32_t merge_failures;    /**< relative pose / transform / merge failed */
    uint32_t refused_range;     /**< the mutual ranges disagree (COSLAM_E_MERGE_RANGE) */
    uint32_t refused_implausible; /**< values no robot produces (COSLAM_E_MERGE_IMPLAUSIBLE) */
    uint32_t refused_disagree;  /**< the maps disagree (COSLAM_E_MERGE_DISAGREE) */
    uint32_t refused_lost;      /**< this robot was lost in its own map (COSLAM_E_MERGE_LOST) */
    uint32_t ignored_disagreed; /**< from a peer whose map disagreed within remerge_period_us */
    uint32_t weak_not_sent;     /**< landmarks left out of sent maps (below export_min_obs) */
    uint32_t send_waits;        /**< sends whose export waited or went in parts (meeting_send_due) */
    uint32_t send_busy;         /**< sends due while the filter's export table was taken (the last
                                     send's export, or a merge check's): nothing begun, the slot
                                     kept, the next sighting tries again with its own moment */
    uint32_t events_dropped;    /**< events overwritten before they were read */
    uint32_t history_thinned;   /**< own sightings of a peer dropped from the middle of its
                                     history, which sightings faster than a third of
                                     pair_window_us would otherwise shorten (meeting.c hist_push) */
} meeting_counters_t;

typedef struct {
    meeting_config_t cfg;
    uint8_t self_id;
    uint8_t n_robots;
    uint32_t tx_seq;
    meeting_peer_t peer[COSLAM_MAX_ROBOTS];
    merge_session_t session;
    uint8_t have_pending;
    uint64_t pending_sender_us;  /**< t_s of the pending message */
    /** A merge whose check waits for the own export in parts
     *  (COSLAM_E_MERGE_PENDING, app/slam_filter.h): its event so far, the
     *  outcome filled in when meeting_poll takes it from `work`. */
    uint8_t merge_waiting;
    meeting_event_t waiting_ev;
    /** 1: a send whose export runs in idle time (slam_filter_export_send),
     *  begun at its sighting; meeting_send_due sends it when the export is
     *  done. A send due while the export table is taken is not begun
     *  (send_busy). */
    uint8_t send_waiting;
    uint8_t send_peer;
    meeting_sighting_t send_sighting;  /**< the sighting the message carries */
    map_estimate_t send_map;           /**< the export for it */
    map_msg_t rx;
    map_msg_t tx;
    uint8_t wire[MAP_MSG_MAX_BYTES];
    slam_merge_work_t work;
    const occ_grid_t *grid;      /**< occlusion for the merge check (meeting_set_grid), or NULL */
    meeting_event_t ev[COSLAM_APP_EVENT_QUEUE];
    uint8_t ev_head;
    uint8_t ev_n;
    meeting_counters_t ctr;
} meeting_t;

/** Defaults: robot sighting sd 0.05 m and 2 deg, latency 2 ms, window
 *  300 ms, resend 1 s, 3 sends, gap 5 s, remerge 60 s, range 3 m,
 *  export_min_obs 5, merge_config_default(). */
meeting_config_t meeting_config_default(void);

/** Set the noise of the own robot sightings from the filter's camera model
 *  (the one settings source): robot markers are seen by the same camera as
 *  landmarks, so robot_range_var_m2 = w1 (range_var_m2),
 *  robot_range_var_per_m2 = range_var_per_m2 and robot_bearing_var_rad2 =
 *  w2 (bearing_var_rad2), as coslam-replay does. Without this call the
 *  meeting keeps meeting_config_default()'s own copy of the default camera
 *  noise, which no settings file changes. No-op for NULL. O(1). */
void meeting_config_noise_from(meeting_config_t *c, const slam_params_t *p);

/** Initialise for robot self_id in a team of n_robots (ids 0..n-1). No I/O.
 *  Returns COSLAM_OK; COSLAM_E_ARG (NULL, ids out of range, non-positive
 *  variances or window, negative or non-finite bounds). O(sizeof). */
coslam_status_t meeting_init(meeting_t *m, const meeting_config_t *cfg, uint8_t self_id, uint8_t n_robots);

/**
 * Record an own sighting of robot `peer` (frame capture stamp_us; range,
 * bearing in the own body frame) with the odometry state at that moment,
 * and send the map to `peer` if the send policy says so (header comment);
 * a sighting beyond max_range_m is ignored (COSLAM_OK, nothing recorded):
 * the filter is exported, encoded and sent with timeout 0.
 * Returns COSLAM_OK (recorded; sent or not due); COSLAM_E_ARG (NULL, peer
 * out of range or self, non-finite values); or the error of a failed send
 * (export/encode status, COSLAM_E_UNSUPPORTED for a link refusal),
 * counted in send_failures. O(export + encode) when sending, else O(1).
 */
coslam_status_t meeting_on_sighting(meeting_t *m, slam_filter_t *filter, hal_link_t *link, uint64_t now_us,
                                    uint8_t peer, double range_m, double bearing_rad, uint64_t stamp_us,
                                    pose2_t odo_pose, double travel_m);

/**
 * A send whose export went in parts (Fast-SLAM, merge.step_units:
 * slam_filter_export_send): send it
 * once the export is done. Call it after every step while send_waiting is
 * set (meeting_on_sighting also does). The message is stamped with the
 * time it goes out (stamp_us = now_us, so the receiver's estimate of the
 * sighting's time stays right) and carries the map as it was exported at
 * the sighting. Returns COSLAM_OK (sent, or nothing waits),
 * COSLAM_E_MERGE_PENDING (still exporting), or the send's error (counted
 * in send_failures). While the export runs, meeting_poll holds a message
 * to merge back (COSLAM_E_EMPTY). O(encode) when sending, else O(1).
 */
coslam_status_t meeting_send_due(meeting_t *m, slam_filter_t *filter, hal_link_t *link, uint64_t now_us);

/**
 * Take up to MEETING_RX_BUDGET datagrams from the link (timeout 0), decode
 * and screen them (steps 1-4 of the header comment); an accepted message
 * becomes the pending one. Returns the number of datagrams taken (>= 0).
 * O(datagrams * decode).
 */
int meeting_poll_link(meeting_t *m, hal_link_t *link);

/**
 * Try to merge the pending message (steps 4-6): merge now, keep waiting,
 * or drop it as stale. odo_pose / travel_m: the own odometry state now;
 * the filter's pose must be up to date. Returns COSLAM_OK (merged or
 * nothing to do), COSLAM_E_EMPTY (still waiting), COSLAM_E_MERGE_PENDING
 * (the merge's check waits for the own export, done in the filter's idle
 * time: merge_waiting is set, and a later meeting_poll queues the event
 * with the outcome and returns it), or the refusal / merge status (also
 * queued as an event). A message to merge while a merge waits finishes
 * that one first. Call it after every step while have_pending or
 * merge_waiting is set. O(merge).
 */
coslam_status_t meeting_poll(meeting_t *m, slam_filter_t *filter, uint64_t now_us, pose2_t odo_pose,
                             double travel_m);

/** Oldest queued event into *ev: COSLAM_OK, or COSLAM_E_EMPTY. O(1). */
coslam_status_t meeting_take_event(meeting_t *m, meeting_event_t *ev);

/** The newest own sighting of `peer`: COSLAM_OK, or COSLAM_E_EMPTY. O(1). */
coslam_status_t meeting_last_sighting(const meeting_t *m, uint8_t peer, meeting_sighting_t *out);

/** 1 if the map of every other robot of the team has been merged. O(n). */
int meeting_merged_all(const meeting_t *m);

/** 1 if every other robot has shown (implicit acknowledgement, see above)
 *  that it holds this robot's map. O(n). */
int meeting_acked_all(const meeting_t *m);

/** 1 if this robot merged some peer's map in the current meeting after its
 *  last message to that peer: the peer sees that only in a next message
 *  (its implicit acknowledgement), which meeting_on_sighting then sends
 *  even though the peer holds this robot's map already (budget and resend
 *  period permitting). The behaviour stays for it (robot_node). O(n). */
int meeting_owes_ack(const meeting_t *m);

/** Counters of this instance. */
const meeting_counters_t *meeting_counters(const meeting_t *m);

/** The occupancy grid (map frame) the merge check may use to tell a spot
 *  hidden behind an obstacle from one looked at; NULL (the default after
 *  meeting_init) when the robot has no laser. Not copied. */
void meeting_set_grid(meeting_t *m, const occ_grid_t *grid);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_APP_MEETING_H */
