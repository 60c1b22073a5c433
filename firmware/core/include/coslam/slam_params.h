/*
 * coslam/slam_params.h - the noise model (the paper's eight weights, eq. 6)
 * and the parameters both filters share: sensor footprint for negative
 * evidence, association gates, landmark existence bookkeeping.
 *
 * The eight weights, as this project defines them (docs/noise-model.md):
 *   w1 range_var_m2            Q = diag(w1, w2), range [m^2]
 *   w2 bearing_var_rad2                           bearing [rad^2]
 *   w3 odo_xy_var_m2_per_m     R = diag(w3 s, w3 s, w4 s) on an odometry
 *   w4 odo_theta_var_rad2_per_m    increment (robot frame), where s is the
 *                              wheel travel of the increment [m]:
 *                              s = |(dx, dy)| + base_radius_m |dtheta|.
 *                              The paper adds R once per step; scaling by the
 *                              travel keeps the model independent of the
 *                              odometry rate and zero when the robot stands.
 *   w5 lm_process_var_m2_per_m landmark random-walk variance added per metre
 *                              of wheel travel (0 for static landmarks).
 *   w6 init_xy_var_m2          initial pose covariance P0 = diag(w6, w6, w7)
 *   w7 init_theta_var_rad2
 *   w8 lm_init_var_m2          variance added to a new landmark's covariance
 *                              on top of the propagated sighting noise
 *                              (unmodelled initialisation error).
 * range_var_per_m2 is an optional ninth term: range variance growing with the
 * square of the range, as for a camera that infers distance from blob size.
 */
#ifndef COSLAM_SLAM_PARAMS_H
#define COSLAM_SLAM_PARAMS_H

#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SLAM_NOISE_N_WEIGHTS 8

typedef struct {
    double range_var_m2;             /**< w1 */
    double bearing_var_rad2;         /**< w2 */
    double odo_xy_var_m2_per_m;      /**< w3 */
    double odo_theta_var_rad2_per_m; /**< w4 */
    double lm_process_var_m2_per_m;  /**< w5 */
    double init_xy_var_m2;           /**< w6 */
    double init_theta_var_rad2;      /**< w7 */
    double lm_init_var_m2;           /**< w8 */
    double range_var_per_m2;         /**< extra: range variance += this * range^2 [1] */
} slam_noise_t;

typedef struct {
    slam_noise_t noise;
    /** Converts rotation to wheel travel in the motion noise [m]; Robotino: 0.132. */
    double base_radius_m;

    /* Sensor footprint: where a landmark "should be seen" (negative evidence). */
    double sensor_min_range_m;
    double sensor_max_range_m;
    double sensor_fov_rad;           /**< full field of view, centred on the x axis */
    /** Landmarks count as "should be seen" only inside this fraction of the
     *  range and half-FOV, so that estimates near the border are not punished. */
    double visibility_margin;

    /* Data association */
    /** Squared Mahalanobis gate for matching a sighting to a landmark (2 dof). */
    double gate_chi2;
    /** A sighting unmatched but closer than this (squared Mahalanobis) to some
     *  landmark is ambiguous and dropped instead of starting a new landmark.
     *  Set equal to gate_chi2 to disable the ambiguity band. */
    double new_landmark_chi2;
    /** Fast-SLAM: log of the likelihood p0 assigned to a sighting that starts
     *  a new landmark (or is dropped), [log(1/(m rad))]. */
    double new_landmark_log_lik;

    /* Landmark existence (counter in "hits"): a landmark starts at exist_init,
     * gains exist_hit per sighting, loses evidence each update in which it
     * should have been seen but was not (a "miss"). Confirmed (exported) while
     * at or above exist_confirm, tentative below; removed when below zero.
     * Capped at exist_max. See exist_miss() in landmark.h and
     * docs/core-slam.md, "Existence". */
    float exist_init;
    float exist_hit;
    /** Evidence lost per miss by a tentative landmark: one never confirmed
     *  (clutter must fade fast). */
    float exist_miss;
    float exist_confirm;
    float exist_max;
    /** Evidence lost per certain miss (exist_miss_bearing_sd_frac) by a
     *  landmark that is or was confirmed (own, or received in a map merge,
     *  which places it at exist_confirm). It keeps this rate all the way
     *  down: below exist_confirm it is no longer exported, below zero it is
     *  removed. So a wrong confirmed landmark (failed loop closure,
     *  misassociation, a wrong map received from another robot) dies instead
     *  of being exported forever, while a real one that is occluded or
     *  missed for a while survives: from evidence e it stays exported through
     *  floor((e - exist_confirm) / exist_miss_confirmed) consecutive certain
     *  misses and stays in the map through floor(e / exist_miss_confirmed).
     *  Set from the camera's detection probability by
     *  slam_exist_miss_for_detection() (a binary Bayes filter on the
     *  landmark's existence, docs/core-slam.md "Death of confirmed
     *  landmarks"): the default camera detects a marker in view with
     *  probability 0.9, which gives 0.5587 (K = 8 certain misses exported,
     *  removed at the 18th: 3.6 s of looking at it at 5 Hz); MRCLAM's camera
     *  (about a third) 0.125, its value since Dataset 6 chose it; flat
     *  markers (the robot app, the simulator) SLAM_EXIST_MISS_FLAT_MARKERS,
     *  below what their measured rate gives, because one marker's misses
     *  are not independent. A marker
     *  hidden behind an obstacle is not missed where the robot has a view
     *  profile from its laser (view.h); without one (no laser, the replay)
     *  every certain miss counts. 0 restores the old rule: confirmed
     *  landmarks never fall below exist_confirm (weakening to it at
     *  exist_miss) and are never removed. */
    float exist_miss_confirmed;
    /** A miss of a confirmed (or once confirmed) landmark counts only if its
     *  prediction is certain: the bearing standard deviation of the
     *  predicted sighting, sqrt(S_bb) of the innovation covariance
     *  (lm_expect_t.s: landmark and, where the filter has it, pose
     *  uncertainty plus sensor noise), is at most this fraction of the half
     *  field of view. Otherwise the sighting might have fallen outside the
     *  view or been refused by the association (whose acceptance shrinks as
     *  S grows), and after a long drift every landmark would die. Default
     *  0.25: two sigma cover half the half field of view (+-6.25 deg of the
     *  50 deg camera, whose own bearing noise is 2 deg). > 0. */
    double exist_miss_bearing_sd_frac;

    /* Plausibility of the inputs (motion.h motion_is_plausible, observe.h
     * sighting_is_plausible): what the robot and its camera can physically
     * do. An odometry increment or a sighting beyond these is refused and
     * counted (rejected_controls / rejected_sightings), never filtered. */
    /** Fastest the base can move [m/s] (Robotino: about 2.8 m/s at full
     *  wheel speed; default 3). */
    double max_speed_mps;
    /** Fastest the base can turn [rad/s] (default 2 pi: one turn a second). */
    double max_turn_radps;
    /** Farthest a landmark or robot can be sighted [m] (default 20 m: a
     *  marker is a few pixels tall there). Not the negative-evidence
     *  footprint sensor_max_range_m, which may be set tighter. */
    double sighting_max_range_m;

    /* Sighting errors shared by a whole track (Fast-SLAM's landmarks). A
     * camera's range and bearing errors on one landmark are mostly an
     * offset that persists while the robot keeps seeing it from about the
     * same place (MRCLAM: lag-1 correlation 0.94 in range, 0.60 in bearing,
     * docs/replay.md "fit-noise"); fused as independent, n such sightings
     * shrink the landmark's covariance n-fold while its error does not
     * shrink. So after each update a landmark's covariance is kept at least
     * the offset's covariance at that sighting (range variance
     * track_offset_range_var_per_m2 * r^2, bearing variance
     * track_offset_bearing_var_rad2, through the sighting's geometry), by
     * adding the positive part of the difference: process noise, so it
     * stays a covariance. 0 and 0 (the default): off. */
    double track_offset_range_var_per_m2;
    double track_offset_bearing_var_rad2;
} slam_params_t;

/** The noise weights as an array w[0..7] = (w1..w8), for calibration. */
void slam_noise_to_array(const slam_noise_t *noise, double w[SLAM_NOISE_N_WEIGHTS]);
void slam_noise_from_array(slam_noise_t *noise, const double w[SLAM_NOISE_N_WEIGHTS]);

/** The chance that a landmark that is not there is paired with some sighting
 *  in a frame that has it in view (slam_exist_miss_for_detection): chosen so
 *  that MRCLAM's detection rate (about 1/3, Dataset 6; fit-noise measures
 *  0.29-0.36) gives the 0.125 that Dataset 6 chose; every other camera's
 *  miss weight follows from its own detection probability. */
#define SLAM_EXIST_P_FALSE 0.015

/** exist_miss_confirmed for flat markers on walls and box faces (the robot
 *  app's default, the simulator's). Their detection rate over the filter's
 *  view is measured (the simulator's cameras 0.91-0.999, the filters' own
 *  view_pairs / view_misses 0.88-0.98), but at the weight it gives the
 *  simulator loses real markers: an estimate a few decimetres off is
 *  missed from viewpoint after viewpoint, not independently. So MRCLAM's
 *  weight is kept (docs/core-slam.md "The rate, measured three ways"). */
#define SLAM_EXIST_MISS_FLAT_MARKERS 0.125f

/**
 * exist_miss_confirmed for a camera that detects a marker in view with
 * probability p_detect: the landmark's existence as a binary Bayes filter in
 * log odds (Thrun, Burgard and Fox 2005, 4.2), in which a sighting paired
 * with the landmark adds log(p_detect / p_false) and a certain miss
 * log((1 - p_detect) / (1 - p_false)), p_false = SLAM_EXIST_P_FALSE; with
 * exist_hit as the unit the miss weighs
 *   log((1 - p_false) / (1 - p_detect)) / log(p_detect / p_false).
 * 0.9 -> 0.5587, 1/3 -> 0.1259, 0.33 -> 0.1247. Returns -1 unless
 * p_false < p_detect < 1 (at 1 a single miss would be certain death).
 */
double slam_exist_miss_for_detection(double p_detect);

/**
 * Defaults for the simulated Robotino with the paper's camera: range sd
 * 0.05 m, bearing sd 2 deg, 50 deg FOV, 0.3-5 m range. See docs/noise-model.md.
 */
slam_params_t slam_params_default(void);

/** COSLAM_OK if every field is finite and inside its domain, else COSLAM_E_ARG. */
coslam_status_t slam_params_validate(const slam_params_t *p);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_SLAM_PARAMS_H */
