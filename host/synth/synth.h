/*
 * synth.h - seeded synthetic runs for the core tests and benchmarks.
 *
 * A robot drives `loops` times around a circle of radius loop_radius_m at
 * constant speed among n_landmarks point landmarks scattered (uniform, with
 * a minimum separation) in a ring of +- ring_half_width_m around the path.
 * Landmarks are non-unique: every sighting carries signature 0 (or one of
 * n_signatures classes) and the true identity is kept only for evaluation.
 *
 * Each control step yields a noisy odometry increment drawn from the
 * project's motion model (so the filter's model is the truth's model), and
 * every camera_every steps a camera frame: every landmark inside the sensor
 * footprint is detected with probability p_detect and sighted with the
 * range-bearing noise of the observation model; clutter_per_frame false
 * sightings (Poisson mean) are added uniformly over the footprint.
 *
 * Arena mode (arena_half_x_m > 0), the MRCLAM-like regime: landmarks
 * uniform in the rectangle [-arena_half_x_m, arena_half_x_m] x
 * [-arena_half_y_m, arena_half_y_m]; the robot starts at the centre facing
 * +x and wanders for wander_s seconds between random waypoints (0.5 m inside
 * the rectangle): it turns on the spot at turn_radps until it faces the
 * next waypoint, then drives to it at speed_mps, steering the residual.
 * With arena_clusters > 0 the landmarks stand in that many clusters (centres
 * uniform, at least 1.5 m apart; landmarks dealt round-robin, each within
 * cluster_radius_m of its centre and min_separation_m of the others).
 */
#ifndef COSLAM_TEST_SYNTH_H
#define COSLAM_TEST_SYNTH_H

#include <stdint.h>

#include "coslam/config.h"
#include "coslam/motion.h"
#include "coslam/observe.h"
#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "coslam/slam_params.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SYNTH_MAX_LANDMARKS 2048
#define SYNTH_MAX_Z 64

typedef struct {
    uint64_t seed;
    int n_landmarks;
    int n_signatures;           /**< 1 = all landmarks alike; 0 = unique (index mod 256):
                                     known data association, to test the filter maths alone */
    double loop_radius_m;
    double ring_half_width_m;
    double min_separation_m;
    double loops;               /**< turns around the circle */
    double speed_mps;
    double dt_s;
    int camera_every;           /**< a camera frame every k control steps */
    double p_detect;
    double clutter_per_frame;
    double arena_half_x_m;      /**< > 0: arena mode (rectangle, waypoints); the ring fields are unused */
    double arena_half_y_m;
    double wander_s;            /**< arena mode: duration of the run */
    double turn_radps;          /**< arena mode: on-the-spot turn rate */
    int arena_clusters;         /**< arena mode: > 0 puts the landmarks in this many clusters */
    double cluster_radius_m;    /**< a cluster's landmarks lie within this of its centre */
    slam_params_t truth;        /**< noise and sensor footprint of the truth */
} synth_config_t;

typedef struct {
    odo_increment_t u;          /**< measured (noisy) odometry of this step */
    pose2_t true_pose;          /**< true pose after the step */
    double t_s;
    int is_frame;
    int n_z;
    sighting_t z[SYNTH_MAX_Z];
    int32_t true_id[SYNTH_MAX_Z]; /**< index of the true landmark, -1 for clutter */
} synth_step_t;

typedef struct {
    synth_config_t cfg;
    rng_t rng;
    int n_lm;
    point2_t lm[SYNTH_MAX_LANDMARKS];
    uint8_t sig[SYNTH_MAX_LANDMARKS];
    int n_seen[SYNTH_MAX_LANDMARKS]; /**< detections so far */
    pose2_t pose;
    point2_t waypoint;          /**< arena mode: where the robot is going */
    int step;
    int n_steps;
} synth_world_t;

/** Signature of landmark index i: unique (index mod 256) when n_signatures
 *  <= 0, else drawn among n_signatures classes. */
uint8_t synth_signature(rng_t *rng, int n_signatures, int index);

/**
 * One camera frame: every landmark inside the footprint of `sp` seen from
 * `pose` is detected with probability p_detect and sighted with the
 * observation model's noise. Appends to z/true_id (up to cap) and counts
 * detections in n_seen[j]. Returns the number of sightings written.
 */
int synth_sight_landmarks(const slam_params_t *sp, rng_t *rng, pose2_t pose, const point2_t *lm, const uint8_t *sig,
                          int n_lm, double p_detect, sighting_t *z, int32_t *true_id, int cap, int *n_seen);

/** Paper-scale defaults: radius 4 m, 1.25 loops at 0.3 m/s, 10 Hz odometry,
 *  5 Hz camera, p_detect 0.9, no clutter, slam_params_default() noise. */
synth_config_t synth_config_default(uint64_t seed, int n_landmarks);

/** Build the world (landmarks, start pose (R, 0, pi/2) on the circle, or
 *  the arena's centre facing +x). */
void synth_init(synth_world_t *w, const synth_config_t *cfg);

/** Arena mode: put the robot at `start` with its own random stream `seed`
 *  (odometry noise, detections, waypoints) and draw its first waypoint. A
 *  team shares one world: copy the synth_world_t of the first robot (same
 *  landmarks) and place each copy. */
void synth_arena_place(synth_world_t *w, pose2_t start, uint64_t seed);

/** Advance one control step; returns 0 when the run is over. */
int synth_next(synth_world_t *w, synth_step_t *s);

/** Start pose of the run (the filters start here: the map frame is the world). */
pose2_t synth_start_pose(const synth_config_t *cfg);

#ifdef __cplusplus
}
#endif

#endif
