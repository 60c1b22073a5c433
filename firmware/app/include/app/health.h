/*
 * app/health.h - the filter's health monitor: does the estimate still
 * explain what the camera sees? It only READS the filter (the results of a
 * run are the same with or without it) and keeps a sliding window of the
 * last COSLAM_APP_HEALTH_WINDOW camera frames.
 *
 * Per frame (slam_filter_update_prepare, then health_before_update, then
 * slam_filter_update_apply, then health_after_update with the same
 * sightings; a frame the prepare says is held is not judged):
 *  - "in view": before the update, the landmarks of the map (EKF-SLAM: the
 *    state; Fast-SLAM: the particle of largest weight) whose predicted
 *    sighting from the pose estimate the filter says should be seen
 *    (landmark_should_be_seen: inside visibility_margin of the sensor's
 *    range and field of view) and whose line of sight crosses no wall of the
 *    occupancy grid (above wall_logodds; g NULL: not checked). A sighting is
 *    *eligible* when a landmark of its class is in view: the map says what
 *    it should be.
 *  - EKF-SLAM: each sighting paired by the association (JCBB) contributes
 *    its normalized innovation squared NIS = nu^T S^-1 nu against the
 *    prior expectation (the filter's scratch after the update holds the
 *    expectations computed from the prior and the pairing; read only). An
 *    eligible sighting left unpaired (a new landmark, or refused) is
 *    *unassociated*; sightings the association held back (ekfslam scratch
 *    held[]: an ambiguous or too nonlinear revisit, or an unpaired sighting
 *    with a loop-closing candidate) count as neither.
 *  - Fast-SLAM: no per-sighting innovation is exposed; an eligible sighting
 *    that starts a new landmark identity (ctr.landmarks_added moved) is
 *    unassociated (the k new identities of a frame are charged to its
 *    eligible sightings, at most one each), and the effective sample size
 *    after the update (last_ess / N) is kept.
 *  - every frame: the landmarks in view that no sighting was paired with
 *    (missed; EKF-SLAM: a held sighting's best landmark counts as seen;
 *    Fast-SLAM: in the best particle, by identity and count).
 * Over the window: mean NIS (2 dof: 2 when the filter is consistent),
 * unassociated fraction of the eligible sightings, missed fraction of the
 * landmarks in view, mean ESS fraction. Per laser scan (health_on_scan),
 * over COSLAM_APP_HEALTH_SCANS scans: the fraction of returns contradicting
 * the occupancy grid at the estimated pose.
 * DIVERGED while any of (thresholds in health_config_t, defaults and why in
 * docs/robot-app.md "Health monitor"):
 *   mean NIS > nis_max            with >= min_sightings paired sightings,
 *   unassociated > unassoc_max    with >= min_sightings eligible sightings,
 *   missed > missed_max           with >= min_sightings landmarks in view,
 *   mean ESS fraction < ess_min   (Fast-SLAM, a full window),
 *   scan conflicts > conflict_max with >= min_returns returns on known cells,
 *   the odometry check is bad: the laser saw a motion the wheels did not
 *   report, or scans that no motion explains (health_on_motion_scan,
 *   app/odo_check.h; held odo.hold_s after the event).
 * A filter that re-localised among look-alike (non-unique) markers has
 * normal landmark figures; the odometry check catches the moment the
 * wheels went wrong or the robot was carried (docs/sim.md "Faults").
 * `diverged` is a status flag (cleared when all are back within
 * bounds); `episodes` counts its rises, `diverged_frames` the frames spent
 * diverged. Caller-owned, no heap; per frame O(landmarks x sight-line cells
 * + landmarks in view x sightings).
 */
#ifndef COSLAM_APP_HEALTH_H
#define COSLAM_APP_HEALTH_H

#include <stdint.h>

#include "app/odo_check.h"
#include "app/slam_filter.h"
#include "coslam/occ_grid.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Laser scans in the scan window (2 s of a 10 Hz URG). */
#ifndef COSLAM_APP_HEALTH_SCANS
#define COSLAM_APP_HEALTH_SCANS 20
#endif
#if COSLAM_APP_HEALTH_SCANS < 2 || COSLAM_APP_HEALTH_SCANS > 1000
#error "COSLAM_APP_HEALTH_SCANS must be in [2, 1000]"
#endif

/** Frames in the sliding window (5 s of a 5 Hz camera). */
#ifndef COSLAM_APP_HEALTH_WINDOW
#define COSLAM_APP_HEALTH_WINDOW 25
#endif
#if COSLAM_APP_HEALTH_WINDOW < 2 || COSLAM_APP_HEALTH_WINDOW > 1000
#error "COSLAM_APP_HEALTH_WINDOW must be in [2, 1000]"
#endif

typedef struct {
    double nis_max;          /**< mean NIS above this: diverged (> 0) */
    double unassoc_max;      /**< unassociated fraction above this: diverged, in (0, 1] */
    double ess_min;          /**< Fast-SLAM: mean ESS / N below this: diverged, [0, 1) */
    double missed_max;       /**< fraction of the landmarks in view not seen above this: diverged, in (0, 1] */
    uint16_t min_sightings;  /**< sightings in the window before a ratio is judged, >= 1 */
    double conflict_max;     /**< scan returns in cells the grid holds free, fraction above this: diverged, in (0, 1] */
    double free_logodds;     /**< a cell is "known free" at or below this log-odds (< 0) */
    double wall_logodds;     /**< a cell is "known wall" above this log-odds (> 0); every 4th ray is traced */
    uint32_t min_returns;    /**< returns on known cells in the scan window before judging, >= 1 */
    odo_check_config_t odo;  /**< the scan-to-scan odometry check (app/odo_check.h) */
} health_config_t;

typedef struct {
    uint16_t n_paired;       /**< EKF-SLAM: paired sightings with a NIS */
    uint16_t n_eligible;
    uint16_t n_unassoc;
    uint16_t n_expected;     /**< landmarks in view before the update */
    uint16_t n_missed;       /**< of those, not paired with any sighting */
    double nis_sum;
    double ess_frac;
} health_frame_t;

typedef struct {
    uint16_t n_known;        /**< returns that fell on cells the grid knows */
    uint16_t n_conflict;     /**< of those, in known free space (3x3 cells around it all free) */
} health_scan_t;

typedef struct {
    health_config_t cfg;
    health_scan_t scan[COSLAM_APP_HEALTH_SCANS];
    uint16_t scan_head, scan_count;
    double conflict_frac;         /**< scan window: returns in known free space / returns on known cells */
    double worst_conflict;
    int scan_bad;
    odo_check_t odo;              /**< wheels against laser (health_on_motion_scan) */
    health_frame_t frame[COSLAM_APP_HEALTH_WINDOW];
    uint16_t head, count;
    /* before the current update */
    uint32_t added_before;
    uint32_t updates_before;      /**< the filter's update count health_before_update saw */
    int looked;                   /**< health_before_update ran for the coming update */
    uint32_t unjudged_frames;     /**< frames not judged: the update that came was not the one
                                       looked at (another update in between, or none looked at) */
    uint8_t in_view_sig[32];      /**< bit set of the classes in view (256 bits) */
    uint16_t n_in_view;
    uint16_t in_view[COSLAM_MAX_LANDMARKS];     /**< EKF-SLAM: their indices */
    uint32_t in_view_id[COSLAM_MAX_LANDMARKS];  /**< Fast-SLAM: identities in the best particle */
    uint16_t in_view_obs[COSLAM_MAX_LANDMARKS]; /**< Fast-SLAM: their sighting counts */
    /* the window's figures after the last frame */
    double mean_nis;              /**< 0 without paired sightings */
    double unassoc_frac;          /**< 0 without eligible sightings */
    double missed_frac;           /**< landmarks in view not seen; 0 without any in view */
    double ess_frac;              /**< 1 for EKF-SLAM */
    int frame_bad;                /**< the camera window's figures are out of bounds */
    int diverged;                 /**< status flag: frame_bad, scan_bad or odo.bad */
    uint32_t diverged_scans;
    uint32_t episodes;            /**< times diverged rose */
    uint32_t diverged_frames;
    uint32_t frames;
    /* worst window figures seen (for tuning and reports) */
    double worst_nis, worst_unassoc, worst_ess, worst_missed;
} health_t;

/** nis_max 6, unassoc_max 0.6, ess_min 0.02, missed_max 0.8, min_sightings 8, conflict_max 0.25,
 *  free_logodds -1.2, wall_logodds 2, min_returns 200 (docs/robot-app.md "Health monitor"). */
health_config_t health_config_default(void);

/** COSLAM_OK or COSLAM_E_ARG (NULL, thresholds out of range). */
coslam_status_t health_init(health_t *h, const health_config_t *cfg);

/**
 * One laser scan, BEFORE it is integrated into the grid: where the SLAM
 * pose says the returns are, has the grid seen free space (all 3x3 cells
 * around the end point at or below free_logodds)? A robot whose pose is
 * wrong (kidnapped, or localised into a look-alike place among non-unique
 * markers, where the innovations are fine) sees walls where its own grid
 * has driven through. Another robot crossing the view also lands there:
 * the threshold allows for it. O(n).
 */
void health_on_scan(health_t *h, const occ_grid_t *g, pose2_t sensor_pose, const double *range_m,
                    const double *angle_rad, size_t n);

/**
 * One laser scan for the odometry check (app/odo_check.h): `pts` in the
 * robot frame, `odo_pose` the odometry-only pose at the scan, now_us its
 * time. Updates odo.bad and the flag. O(1), or one check every
 * odo.period_s.
 */
void health_on_motion_scan(health_t *h, uint64_t now_us, pose2_t odo_pose, const point2_t *pts, size_t n);

/**
 * Between slam_filter_update_prepare and slam_filter_update_apply (so on
 * the state the update applies to, after any merge or held inputs it had
 * to finish first): note the landmark classes in view and the counters; g
 * is the laser's occupancy grid (may be NULL). O(landmarks x the sight
 * line's cells).
 */
void health_before_update(health_t *h, const slam_filter_t *f, const occ_grid_t *g);

/** After slam_filter_update_apply(f, z, n): the frame's figures, the window, the flag. A frame whose
 *  update is not exactly the one health_before_update looked at (the filter's update count moved by
 *  other than one since, or nothing was looked at) is not judged, and counted in unjudged_frames: its
 *  "in view" would describe another state. O(window + n x landmarks in view). */
void health_after_update(health_t *h, const slam_filter_t *f, const sighting_t *z, int n);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_APP_HEALTH_H */
