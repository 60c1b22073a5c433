/*
 * app/behaviour.h - how the robot moves: explore with the paper's obstacle
 * behaviour, then go to a rendezvous point and look for the other robots
 * until every map has been merged, then explore again.
 *
 * The base is omnidirectional, but the robot drives like a unicycle (body
 * velocity (v, 0, w)) so that its camera, which looks along the body x axis,
 * looks where it goes. Turning and translating: the robot translates only
 * while its heading error e is below straight_band_rad, at
 * v = cruise (1 - |e| / straight_band_rad): a tight arc would sweep the
 * body out of the straight corridor the obstacle behaviour checks.
 *
 *   WANDER  drive straight ahead at cruise speed, holding the heading; when
 *           the obstacle behaviour (coslam/obstacle.h on the latest laser
 *           scan, corridor along the body x axis) reports an obstacle, turn
 *           right parallel to it (target heading = heading + dpsi) on the
 *           spot, then go on at the behaviour's speed and hold the new
 *           heading. (Translating during the turn, as the behaviour's
 *           cruise * cos(dpsi) allows, made the robot orbit round pillars:
 *           the tangent keeps the pillar in the corridor.) Running parallel
 *           to an obstacle line that lies inside the corridor (nearer than
 *           half the robot's width plus the margin), the robot slides away
 *           sideways at slide_mps (the base is omnidirectional): turning
 *           away would make the line a receding one, for which the
 *           right-turn rule asks for a half turn. For the same reason a
 *           line within heading_tol_rad of the motion counts as parallel
 *           even when it leans away to the left (dpsi near -pi). After explore_s: RETURN, unless the rendezvous is
 *           done (below).
 *   RETURN  head for the rendezvous point (map frame, from the SLAM pose).
 *           With every new scan the robot picks, among the directions
 *           -probe_max_rad..+probe_max_rad in steps of probe_step_rad
 *           (inside the laser's view), the one closest to the goal bearing
 *           whose corridor the obstacle behaviour finds clear (the same
 *           check along that direction, with probe_margin_m more room each
 *           side, since the robot turns into it: the core supports any
 *           motion direction), and holds it; all blocked: a quarter turn right.
 *           Obstacles ahead are handled as in WANDER, followed by bypass_s
 *           of straight driving. Slows within 0.5 m; within goal_tol_m: SEEK.
 *   SEEK    turn on the spot at seek_turn_radps until a peer is in view: FACE.
 *   FACE    turn towards the peer (w = face_gain * bearing) and stand, so
 *           that the peer, turning too, sees this robot and both sightings
 *           are mutual. Peer out of view for peer_timeout_s: SEEK.
 * The rendezvous is done once every peer's map is merged and every peer has
 * shown that it holds this robot's map (meeting.h, implicit
 * acknowledgement) - or linger_s after the own merges, whichever comes
 * first; from any mode the robot then WANDERs until the end.
 * A bumper hit (input `bumped`, once per hit) starts a quarter turn right
 * on the spot before anything else.
 * Guard, below all modes: a translation that would bring the body (half the
 * robot's width from its centre) within reach of a scan point it is
 * approaching within guard_horizon_s is not commanded (the turn is); held
 * back for guard_patience_s, the robot turns a quarter right as after a
 * bump. It catches what the corridor checks miss: a box corner beside the
 * robot, a slide towards the wrong side.
 * Headings are tracked in the odometry frame (dead reckoning), which is
 * smooth, unlike the SLAM pose; only the rendezvous point needs the map pose.
 * Without a recent scan the robot does not translate (it may turn).
 *
 * Obstacle checks run once per scan (the scan does not change between two),
 * along the heading the robot had when the scan was taken.
 * Pure logic over the inputs (no HAL, no heap); caller-owned state; O(1)
 * per step, O(scan points) once per scan, O(directions * scan points) once
 * per scan in RETURN.
 */
#ifndef COSLAM_APP_BEHAVIOUR_H
#define COSLAM_APP_BEHAVIOUR_H

#include <stddef.h>
#include <stdint.h>

#include "coslam/obstacle.h"
#include "coslam/pose2.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    BEHAVIOUR_WANDER = 1,
    BEHAVIOUR_RETURN = 2,
    BEHAVIOUR_SEEK = 3,
    BEHAVIOUR_FACE = 4,
} behaviour_mode_t;

typedef struct {
    double cruise_mps;        /**< forward speed [m/s], > 0 */
    double turn_gain;         /**< w = turn_gain * heading error [1/s], > 0 */
    double max_turn_radps;    /**< |w| limit [rad/s], > 0 */
    double heading_tol_rad;   /**< an avoidance turn is complete within this [rad], > 0 */
    double straight_band_rad; /**< translate only for heading errors below this [rad], > 0 */
    double probe_max_rad;     /**< RETURN: directions checked with the laser, +- this [rad], > 0 */
    double probe_step_rad;    /**< RETURN: between two checked directions [rad], > 0 */
    double probe_margin_m;    /**< RETURN: extra corridor margin each side for those checks [m], >= 0 */
    double slide_mps;         /**< sideways speed away from a parallel obstacle inside the corridor [m/s], >= 0 */
    double guard_horizon_s;   /**< guard: look this far ahead along the command [s], > 0 */
    double guard_patience_s;  /**< guard: held back this long -> quarter turn right [s], > 0 */
    double explore_s;         /**< WANDER this long before the rendezvous [s]; < 0: never */
    point2_t rendezvous_m;    /**< rendezvous point, map frame [m] */
    double goal_tol_m;        /**< rendezvous reached within this [m], > 0 */
    double bypass_s;          /**< straight run after an avoidance turn on the way back [s], >= 0 */
    double seek_turn_radps;   /**< SEEK turn rate [rad/s], != 0 (sign = direction) */
    double face_gain;         /**< FACE: w = face_gain * bearing [1/s], > 0 */
    double peer_timeout_s;    /**< a peer unseen this long is out of view [s], > 0 */
    double linger_s;          /**< wait for the peers' merges at most this long [s], >= 0 */
} behaviour_config_t;

/** The latest laser scan, in the laser frame (angle order), and what the
 *  obstacle behaviour needs to evaluate it. n = 0: no scan. */
typedef struct {
    const obstacle_params_t *params;
    pose2_t laser_in_robot;
    const double *range_m;
    const double *angle_rad;
    size_t n;
    uint64_t stamp_us;         /**< when it was taken (a new value = a new scan) */
    double heading_rad;        /**< odometry heading of the robot then [rad] */
    const point2_t *points_m;  /**< the valid readings as points in the robot frame then (guard) */
    size_t n_points;
} behaviour_scan_t;

typedef struct {
    uint64_t now_us;
    pose2_t odo_pose;          /**< dead-reckoning pose (control frame) */
    pose2_t map_pose;          /**< SLAM pose estimate (map frame) */
    int scan_ok;               /**< `scan` is recent enough to drive on */
    behaviour_scan_t scan;
    int bumped;                /**< a bumper hit was acknowledged since the last step */
    int peer_in_view;          /**< a peer was sighted within peer_timeout_s */
    double peer_bearing_rad;   /**< its bearing now, robot frame [rad] */
    int merged_all;            /**< every peer's map has been merged */
    int acked_all;             /**< every peer holds this robot's map */
} behaviour_input_t;

typedef struct {
    double vx_mps;   /**< body velocity command, robot frame */
    double vy_mps;
    double w_radps;
} behaviour_cmd_t;

typedef struct {
    behaviour_config_t cfg;
    behaviour_mode_t mode;
    int started;
    uint64_t start_us;
    double hold_heading_rad;   /**< heading held / turned to (odometry frame) */
    int turning;               /**< an avoidance turn is in progress */
    uint64_t straight_until_us;/**< RETURN: no goal seeking before this */
    uint64_t planned_scan_us;  /**< RETURN: scan the held direction was chosen on */
    int rendezvous_done;
    int merged_seen;
    uint64_t merged_since_us;
    obstacle_cmd_t ahead;      /**< last evaluation along the body x axis */
    int ahead_hit;             /**< it found an obstacle */
    uint64_t ahead_scan_us;    /**< scan it was made on */
    uint32_t avoid_turns;      /**< obstacle-triggered turns started */
    uint32_t bump_turns;       /**< bumper-triggered turns */
    uint32_t slides;           /**< steps sliding away from a parallel obstacle */
    uint32_t near_parallel;    /**< lines leaning away by less than heading_tol taken as parallel */
    uint32_t guard_stops;      /**< steps whose translation the guard refused */
    int guard_held;            /**< the guard holds the robot back ... */
    uint64_t guard_since_us;   /**< ... since then */
    uint32_t goal_blocked;     /**< RETURN steps with the goal corridor blocked */
    uint32_t mode_changes;
} behaviour_t;

/** Defaults: cruise 0.2 m/s, gain 1.5 /s, 0.8 rad/s, tolerance 5 deg,
 *  straight band 30 deg, probe +-60 deg in 10 deg steps with 0.1 m more
 *  margin, slide 0.05 m/s, guard 0.3 s / 1 s, explore 90 s, rendezvous (0, 0) (the
 *  start), 0.25 m, bypass 1 s, seek 0.4 rad/s, face gain 1.5 /s, peer
 *  timeout 1 s, linger 10 s. */
behaviour_config_t behaviour_config_default(void);

/** Returns COSLAM_OK, or COSLAM_E_ARG for NULL or a parameter outside its
 *  domain (see the fields). The first step starts the clock of explore_s. */
coslam_status_t behaviour_init(behaviour_t *b, const behaviour_config_t *cfg);

/** One control step: mode transitions, then the velocity command. Returns
 *  the mode the command belongs to. */
behaviour_mode_t behaviour_step(behaviour_t *b, const behaviour_input_t *in, behaviour_cmd_t *out);

/** "wander", "return", "seek", "face" (static strings). */
const char *behaviour_mode_name(behaviour_mode_t mode);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_APP_BEHAVIOUR_H */
