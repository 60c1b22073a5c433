/*
 * app/robot_node.h - the robot application: one robot's firmware main loop.
 *
 * A robot_node_t talks to its hardware ONLY through HAL handles and the
 * drivers on top of them, plus the sighting source (app/sighting_source.h):
 *
 *   hal_clock   time (read once per step)
 *   hal_serial  URG laser      -> urg_scip2 (SCIP 2.0, MD streaming)
 *   hal_can     3 wheel drives -> cia402_omni (CiA 402, omni kinematics, odometry)
 *   hal_gpio    bumper, e-stop, status LED -> gpio_roles
 *   hal_link    the other robots -> meeting (map messages, merge)
 *   sighting_source  landmark and robot sightings (camera pipeline / simulator stand-in)
 *
 * One step (robot_node_step, every control period, e.g. 10 ms):
 *   1. GPIO roles: bumper / e-stop -> stop_requested;
 *   2. drive: poll the CAN driver; bring-up, enable, fault recovery;
 *   3. odometry: the increment since the last step -> dead-reckoning pose,
 *      odometer, and the filter's pending prediction (applied every
 *      filter_period_us and before every update or merge);
 *   4. laser: every new MD scan -> occupancy grid (at the SLAM pose); the
 *      latest one feeds the behaviour's obstacle checks (coslam/obstacle.h);
 *   5. sightings: a new frame -> filter update with the landmark sightings;
 *      each robot sighting -> meeting_on_sighting (may send the map);
 *   6. link: incoming map messages -> meeting_poll_link, meeting_poll
 *      (merge when paired with an own sighting);
 *   7. behaviour (app/behaviour.h) -> body velocity -> drive; zero while
 *      stop_requested, while the drive is not enabled, or without a scan;
 *   8. status LED: heartbeat running, fast blink stopped, slow blink booting.
 * A latched bumper is acknowledged automatically once it is released (the
 * robot stood still meanwhile); the behaviour then turns a quarter right.
 *
 * Degraded modes (for a robot whose devices may be missing; the simulator
 * uses none of them, the Linux port coslam-robot all):
 *  - laser_optional: the drive, odometry, filter and meeting run without
 *    the laser; the laser is connected in the background every
 *    retry_period_us (the base is commanded to stand still first, since a
 *    connect blocks up to three URG reply timeouts) and counted lost when
 *    no scan came for laser_lost_us (then reconnected). Without a recent
 *    scan there is no obstacle behaviour: the robot never translates and
 *    turns on the spot at most at blind_max_turn_radps.
 *  - gpio_optional: init succeeds when the GPIO lines cannot be claimed;
 *    robot_node_gpio_attach() claims them later (robot_node_gpio_detach()
 *    lets go of a controller that went away). While the configured bumper /
 *    e-stop roles are not attached the robot does not move, unless
 *    motion_without_gpio is set (the e-stop is a safety input).
 *  - robot_node_hold(): an external stop (shutdown, a supervisor).
 * With no CAN bus the drive bring-up fails: drive_errors if the driver
 * cannot start, else one drive fault (the bus fault, counted once while it
 * lasts and reset every retry_period_us): no odometry, no motion;
 * sightings, filter and meeting run. A robot configured without drives
 * (drive_absent) never starts the drive and counts no fault: a missing bus
 * is a fault only where one was configured.
 * In every mode a laser that went silent after start-up for laser_lost_us
 * (unplugged, garbled line) is counted in laser_lost and reconnected every
 * retry_period_us; without a scan the robot does not translate.
 *
 * Health monitor (app/health.h): every camera frame and laser scan, read
 * only; robot_node_diverged() and ctr.diverged report it.
 *
 * Start-up inside robot_node_step: the laser is connected first (SCIP2.0,
 * PP, MD over laser_fov_rad); these driver commands block up to the URG
 * driver's reply timeout on hardware (the emulator answers at once) and
 * are retried every retry_period_us on failure. Then the drive bring-up
 * (non-blocking). The filter starts at the identity pose: each robot's map
 * frame is its start pose.
 *
 * Timing: every other call is non-blocking (timeouts 0); a step costs one
 * filter update per camera frame plus, rarely, a map export or merge.
 * Memory: sizeof(robot_node_t) is about 600 KB in the default profile
 * (filter 390 KB, grid 80 KB, meeting 40 KB, scan buffers). Caller-owned,
 * no heap, no globals; several nodes coexist (the simulator runs a team in
 * one process). One thread per node.
 */
#ifndef COSLAM_APP_ROBOT_NODE_H
#define COSLAM_APP_ROBOT_NODE_H

#include <stdint.h>

#include "app/behaviour.h"
#include "app/health.h"
#include "app/meeting.h"
#include "app/sighting_source.h"
#include "app/slam_filter.h"
#include "cia402/cia402_omni.h"
#include "coslam/obstacle.h"
#include "coslam/occ_grid.h"
#include "gpio_roles.h"
#include "hal/hal_can.h"
#include "hal/hal_clock.h"
#include "hal/hal_gpio.h"
#include "hal/hal_link.h"
#include "hal/hal_serial.h"
#include "urg/urg_scip2.h"

#ifdef __cplusplus
extern "C" {
#endif

/** The devices of one robot. Every handle must outlive the node. */
typedef struct {
    hal_clock_t *clock;
    hal_serial_t *laser;          /**< URG on its serial line */
    hal_can_t *can;               /**< the drives' bus */
    hal_gpio_t *gpio;             /**< bumper, e-stop, LED lines (gpio config below) */
    hal_link_t *link;             /**< the team's link */
    sighting_source_t *sightings; /**< marker sightings */
} robot_node_io_t;

typedef struct {
    uint8_t robot_id;               /**< < n_robots; also the link id */
    uint8_t n_robots;               /**< team size, 2..COSLAM_MAX_ROBOTS */
    slam_filter_config_t filter;    /**< its robot_id is forced to robot_id */
    meeting_config_t meeting;
    behaviour_config_t behaviour;
    obstacle_params_t obstacle;     /**< cruise speed is taken from behaviour */
    occ_grid_params_t grid;
    point2_t grid_origin_m;         /**< map-frame corner of the grid [m] */
    pose2_t laser_in_robot;         /**< laser mounting pose [m, m, rad] */
    double laser_fov_rad;           /**< scanned field of view, centred on the laser's front */
    urg_scip2_config_t urg;
    cia402_omni_config_t drive;
    gpio_roles_config_t gpio;
    uint8_t status_led;             /**< index into gpio.leds (ignored without LEDs) */
    uint32_t filter_period_us;      /**< prediction period [us], > 0 */
    uint32_t scan_max_age_us;       /**< older obstacle decision: no translation [us] */
    uint32_t retry_period_us;       /**< laser connect / drive fault retries [us] */
    /* degraded modes (header comment); robot_node_config_default: all off,
     * laser_lost_us 2 s, blind_max_turn_radps 0.3 rad/s */
    uint8_t laser_optional;         /**< 1: run without the laser, connect it in the background */
    uint32_t laser_lost_us;         /**< laser_optional: no scan this long -> lost, reconnect [us]; 0: never */
    double blind_max_turn_radps;    /**< laser_optional: |w| limit without a recent scan [rad/s], >= 0 */
    uint8_t gpio_optional;          /**< 1: init succeeds without the GPIO lines */
    uint8_t motion_without_gpio;    /**< 1: move even while the GPIO roles are not attached */
    uint8_t drive_absent;           /**< 1: this robot has no drives on purpose (no CAN configured):
                                         the drive is never started and no drive fault or error is
                                         counted; no odometry, no motion (the node stays in
                                         ROBOT_NODE_DRIVE_UP); sightings, filter, meeting run */
    health_config_t health;         /**< the health monitor (app/health.h); health_config_default */
} robot_node_config_t;

typedef enum {
    ROBOT_NODE_LASER_UP = 1,  /**< connecting the laser */
    ROBOT_NODE_DRIVE_UP = 2,  /**< drive bring-up and enable */
    ROBOT_NODE_RUN = 3,       /**< running */
    ROBOT_NODE_FAULT = 4,     /**< drive fault: stopped, reset after retry_period_us */
    ROBOT_NODE_SHUTDOWN = 5,  /**< robot_node_shutdown() was called: stopped for good */
} robot_node_state_t;

typedef struct {
    uint32_t steps;
    uint32_t scans;               /**< laser scans used */
    uint32_t scan_errors;         /**< driver errors while reading scans */
    uint32_t laser_connect_failures;
    uint32_t grid_out_of_grid;    /**< scans with returns outside the grid */
    uint32_t frames;              /**< sighting frames used */
    uint32_t views;               /**< of them, with a view profile from a scan at most
                                       scan_max_age_us old (set_view; the others count
                                       every miss) */
    uint32_t frame_errors;        /**< sighting source errors */
    uint32_t sightings_dropped;   /**< reported by the source (frame full) */
    uint32_t filter_errors;       /**< predict/update returned an error */
    uint32_t odometry_errors;     /**< increments refused (non-finite) */
    uint32_t drive_faults;        /**< faults reported by the drive driver, each counted once until
                                       the driver reports clear (reset every retry_period_us) */
    uint32_t drive_errors;        /**< other drive driver errors */
    uint32_t stalls;              /**< this node did not poll the drives for longer than their
                                       watchdog (a late step, a blocking laser connect): the drives
                                       stopped the base themselves */
    uint32_t stall_resets;        /**< drive faults right after a stall, reset at once (the stall
                                       explains them) instead of after retry_period_us */
    uint32_t stop_steps;          /**< steps stopped by bumper / e-stop */
    uint32_t bumper_acks;         /**< bumper hits, acknowledged once released */
    uint32_t laser_lost;          /**< laser_optional: connected laser silent for laser_lost_us */
    uint32_t blind_steps;         /**< laser_optional: running steps without a recent scan */
    uint32_t hold_steps;          /**< running steps stopped by robot_node_hold or missing GPIO roles */
    uint32_t gpio_attach_failures;/**< robot_node_init (gpio_optional) / robot_node_gpio_attach failures */
    uint32_t diverged;            /**< health monitor: times the filter was judged diverged (app/health.h) */
    uint32_t can_errors;          /**< CAN frames the controller lost: HAL rx_overflow + rx_malformed counts */
    uint32_t robot_sightings_refused; /**< robot sightings not given to the meeting: an id outside the team
                                           (not below n_robots) or this robot's own (a robot does not see
                                           its own marker: a misread, or another robot wearing it), a range
                                           not finite and positive or a bearing not finite; or one the
                                           meeting refused (COSLAM_E_ARG, not a failed send: e.g. a
                                           non-finite odometry pose or travel) */
} robot_node_counters_t;

typedef struct {
    robot_node_config_t cfg;
    robot_node_io_t io;
    robot_node_state_t state;
    uint64_t now_us;
    uint64_t retry_at_us;
    uint64_t fault_reset_at_us;   /**< when the last drive fault reset was sent (0: none yet) */
    int drive_fault_latched;      /**< a counted drive fault not yet cleared (counted once) */
    uint64_t last_step_us;        /**< the previous step's start (0: none yet) */
    uint64_t stall_at_us;         /**< the last stall's end (0: none) */
    uint32_t stall_us;            /**< its length */
    /* drivers */
    urg_scip2_t urg;
    cia402_omni_t drive;
    int drive_started;
    gpio_roles_t gpio;
    int gpio_ok;
    gpio_roles_status_t gpio_status;
    /* laser data */
    urg_scip2_scan_t scan;
    double scan_range_m[COSLAM_MAX_SCAN_POINTS];
    double scan_angle_rad[COSLAM_MAX_SCAN_POINTS];
    point2_t scan_points_m[COSLAM_MAX_SCAN_POINTS]; /**< valid readings, robot frame */
    size_t scan_n_points;
    size_t scan_n;                /**< points of the last good scan (0: none yet) */
    uint64_t scan_us;             /**< when it was read */
    pose2_t scan_odo_pose;        /**< odometry pose then (the behaviour's heading; the view
                                       profile moves the scan's points to the frame's pose) */
    view_profile_t view;          /**< the last frame's view profile (slam_filter_set_view) */
    occ_grid_t grid;
    /* odometry */
    pose2_t odo_pose;
    double travel_m;
    odo_increment_t odo_pending;  /**< not yet given to the filter */
    uint64_t last_predict_us;
    /* estimation and cooperation */
    slam_filter_t filter;
    sighting_frame_t frame;
    meeting_t meeting;
    behaviour_t behaviour;
    behaviour_cmd_t cmd;
    robot_node_counters_t ctr;
    /* degraded modes */
    int laser_up;                 /**< the laser is connected and streaming */
    uint64_t laser_retry_at_us;   /**< laser_optional: next connect attempt */
    uint64_t laser_alive_us;      /**< laser_optional: connected at */
    uint8_t laser_phase;          /**< the connect's next command: 0 SCIP2.0, 1 PP, 2 MD */
    uint64_t laser_cmd_at_us;     /**< the connect's command under way was sent at */
    uint64_t laser_rx_search_bytes; /**< urg_scip2_rx_search_bytes since robot_node_init, across the
                                         driver's resets (robot_node_laser_rx_search_bytes) */
    uint32_t laser_rx_search_seen;  /**< the driver's own count when last added to it */
    int hold;                     /**< robot_node_hold */
    health_t health;              /**< the filter's health monitor (reads the filter only) */
} robot_node_t;

/** Defaults for robot `robot_id` of `n_robots`: slam_filter_config_default,
 *  meeting/behaviour/obstacle/grid defaults, grid origin (-5, -5) (10 m x
 *  10 m around the start), laser 0.12 m ahead of the centre scanning 140 deg
 *  (the paper's mounting), URG and drive defaults, GPIO lines: bumper 0
 *  (active high), e-stop 1 (active low: a normally-closed loop), LED 2;
 *  filter period 100 ms, scan age 300 ms, retry 1 s. */
robot_node_config_t robot_node_config_default(uint8_t robot_id, uint8_t n_robots);

/**
 * Check the configuration, initialise drivers, filter, grid, meeting and
 * behaviour; claims the GPIO lines (gpio_roles_init). No other I/O.
 * Returns COSLAM_OK; COSLAM_E_ARG (NULL handle, bad ids or parameters, a
 * component refused its configuration); COSLAM_E_UNSUPPORTED if the GPIO
 * lines could not be claimed.
 */
coslam_status_t robot_node_init(robot_node_t *n, const robot_node_config_t *cfg, const robot_node_io_t *io);

/**
 * One control step (see the header comment). Returns COSLAM_OK; or the
 * first error that this step could not absorb (it is also counted and the
 * node keeps going at the next step): a clock failure (COSLAM_E_ARG and
 * no step), a laser connect failure (COSLAM_E_URG_*), a drive fault
 * (COSLAM_E_DRIVE_FAULT).
 */
coslam_status_t robot_node_step(robot_node_t *n);

/** Idle time after a step (the rest of the step period): the filter's
 *  deferred work (slam_filter_idle): the compressed EKF's global update,
 *  the next part of a merge or an export in parts. Returns 1 if a merge or
 *  an export in parts is still due (coslam-robot calls it again while its
 *  period has time left), else 0. */
int robot_node_idle(robot_node_t *n);

/**
 * Start the filter from a saved map (slam_filter_seed: the robot did not
 * move while it was down, so it stands at map->pose) and continue the
 * meeting's message sequence numbers after msg_seq, so that the peers'
 * replay check (merge_session_accept) does not refuse the restarted robot.
 * Call after robot_node_init and before the first step. Dead reckoning
 * restarts at the identity (it is a control frame only).
 * Returns COSLAM_OK, COSLAM_E_CAPACITY (map cut, see slam_filter_seed),
 * COSLAM_E_ARG (NULL, or a map the filter refuses: the filter then starts
 * empty at the map's pose if that is finite, else as after init; the
 * sequence numbers still go on after msg_seq).
 * O(slam_filter_seed).
 */
coslam_status_t robot_node_restore(robot_node_t *n, const map_estimate_t *map, uint32_t msg_seq);

/** Sequence number of the last map message sent (0: none yet). O(1). */
uint32_t robot_node_msg_seq(const robot_node_t *n);

/**
 * Claim the configured GPIO lines now (gpio_roles_init): after an init
 * without them (gpio_optional) or a robot_node_gpio_detach. The e-stop
 * starts active, so the robot moves only once it has been seen released
 * for estop_release_us. Returns COSLAM_OK (attached, or already, or no role
 * configured); COSLAM_E_UNSUPPORTED (the lines could not be claimed;
 * counted in gpio_attach_failures); COSLAM_E_ARG (NULL, or a GPIO
 * configuration gpio_roles refuses). O(lines).
 */
coslam_status_t robot_node_gpio_attach(robot_node_t *n);

/** Let go of the GPIO roles (LEDs off, lines released; gpio_roles_deinit),
 *  e.g. before closing a controller that went away. No-op when not
 *  attached. O(lines). */
void robot_node_gpio_detach(robot_node_t *n);

/** 1 while the GPIO roles are attached (or none is configured). O(1). */
int robot_node_gpio_attached(const robot_node_t *n);

/** Hold (1) or release (0) the robot: while held every step commands zero
 *  velocity (counted in hold_steps); everything else runs. O(1). */
void robot_node_hold(robot_node_t *n, int hold);

/**
 * Stop for good: the pending odometry goes into the filter (so that an
 * export after this call has the final pose), zero velocity and the
 * drives' disable goal are commanded and sent (one cia402_omni_poll), the
 * laser's streaming is stopped (QT; blocks up to the URG reply timeout),
 * the GPIO roles are released (LEDs off). State ROBOT_NODE_SHUTDOWN; a
 * later robot_node_step only polls the drive (so that the disable
 * sequence can finish) and returns COSLAM_OK. Calling it again polls the
 * drive once more. Returns COSLAM_OK, COSLAM_E_ARG (NULL), or the drive's
 * error (COSLAM_E_DRIVE_FAULT: the base is being stopped anyway).
 */
coslam_status_t robot_node_shutdown(robot_node_t *n);

/**
 * After robot_node_shutdown and the polls that send the disable sequence:
 * let the drives go (cia402_omni_release: their watchdog is switched off,
 * the master heartbeat stops), so a clean stop does not end in their
 * watchdog's EMCY. Returns COSLAM_OK (also without drives); an error of
 * cia402_omni_release; COSLAM_E_ARG NULL.
 */
coslam_status_t robot_node_release_drives(robot_node_t *n);

/** 1 while the laser is connected and streaming. O(1). */
int robot_node_laser_up(const robot_node_t *n);

/** Current state. */
robot_node_state_t robot_node_state(const robot_node_t *n);

/** SLAM pose estimate and covariance, map frame (= the robot's start pose). */
void robot_node_pose(const robot_node_t *n, pose2_t *pose, cov3_t *cov);

/** Dead-reckoning pose (odometry only) and odometer [m]; either may be NULL. */
void robot_node_odometry(const robot_node_t *n, pose2_t *pose, double *travel_m);

/** Export the current map estimate into *out (slam_filter_export). */
coslam_status_t robot_node_export(robot_node_t *n, map_estimate_t *out);

/** Begin an observer's export of the map into *out in parts of the merge's
 *  step_units (slam_filter_export_observe: it yields to sends and merges;
 *  robot_node_idle runs the rest, robot_node_export_poll says when *out
 *  holds it). Returns as slam_filter_export_observe. */
coslam_status_t robot_node_export_observe(robot_node_t *n, map_estimate_t *out);

/** slam_filter_export_poll on the node's filter: 1 done (taken), 0 running,
 *  -1 none into *out (yielded: begin again). */
int robot_node_export_poll(robot_node_t *n, const map_estimate_t *out, coslam_status_t *st);

/** Oldest queued meeting event (sent, merged, refused): COSLAM_OK / COSLAM_E_EMPTY. */
coslam_status_t robot_node_take_event(robot_node_t *n, meeting_event_t *ev);

/** The occupancy grid (map frame). */
const occ_grid_t *robot_node_grid(const robot_node_t *n);

/** Behaviour mode of the last step. */
behaviour_mode_t robot_node_mode(const robot_node_t *n);

/** 1 while the health monitor judges the filter diverged (app/health.h). O(1). */
int robot_node_diverged(const robot_node_t *n);

/** The health monitor's state: window figures, worst figures, episodes. O(1). */
const health_t *robot_node_health(const robot_node_t *n);

/** Counters of the node, its meeting protocol and its drivers. */
const robot_node_counters_t *robot_node_counters(const robot_node_t *n);
const meeting_counters_t *robot_node_meeting_counters(const robot_node_t *n);
const urg_scip2_stats_t *robot_node_laser_stats(const robot_node_t *n);

/** The bytes the laser driver looked at while waiting for whole messages
 *  (urg_scip2_rx_search_bytes) since robot_node_init. A lost laser resets
 *  the driver, which starts its own 32-bit count again (and it wraps at
 *  2^32); this total goes on across both, so it never goes back. O(1). */
uint64_t robot_node_laser_rx_search_bytes(const robot_node_t *n);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_APP_ROBOT_NODE_H */
