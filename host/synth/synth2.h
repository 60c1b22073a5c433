/*
 * synth2.h - seeded two-robot synthetic runs for the map merge (the paper's
 * experiment in miniature). Robot 0 starts at (-1, 0) facing west, robot 1
 * at (1, 0) facing east: they start back to back, so neither knows where
 * the other is. Each drives one loop of radius loop_radius_m turning left
 * (robot 0 through the south-west of the arena, robot 1 through the
 * north-east), turns on the spot to face the other, and stands: they see
 * each other 2 m apart and meet. Landmarks are scattered over the square
 * arena [-half, half]^2 (12 m x 12 m by default) with a minimum separation,
 * n_signatures classes; with the camera's 3 m range each robot maps mostly
 * its own half (robot 0 the south, robot 1 the north).
 *
 * Each step yields, per robot, the noisy odometry increment, on camera
 * frames its landmark sightings (as synth.h) and its sighting of the other
 * robot (range, bearing, with the robot-sighting noise) when the other is
 * inside its footprint. The filters start at the identity pose: each
 * robot's map frame is its own start pose (start_pose()).
 */
#ifndef COSLAM_TEST_SYNTH2_H
#define COSLAM_TEST_SYNTH2_H

#include "synth.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint64_t seed;
    int n_landmarks;
    int n_signatures;
    double half_m;              /**< arena half size */
    double min_separation_m;
    double loop_radius_m;
    double speed_mps;
    double turn_radps;          /**< on-the-spot turn rate */
    double stand_s;             /**< time standing face to face at the end */
    double dt_s;
    int camera_every;
    double p_detect;
    double robot_range_sd_m;    /**< robot-to-robot sighting noise */
    double robot_bearing_sd_rad;
    slam_params_t truth;
} synth2_config_t;

typedef struct {
    odo_increment_t u;
    pose2_t true_pose;          /**< world frame */
    int n_z;
    sighting_t z[SYNTH_MAX_Z];
    int32_t true_id[SYNTH_MAX_Z];
    int sees_other;             /**< 1 if the other robot was sighted this frame */
    sighting_t other;           /**< that sighting (range, bearing) */
} synth2_robot_step_t;

typedef struct {
    double t_s;
    int is_frame;
    int phase;                  /**< 0 loop, 1 turn, 2 stand */
    synth2_robot_step_t r[2];
} synth2_step_t;

typedef struct {
    synth2_config_t cfg;
    rng_t rng;
    int n_lm;
    point2_t lm[SYNTH_MAX_LANDMARKS];
    uint8_t sig[SYNTH_MAX_LANDMARKS];
    int n_seen[2][SYNTH_MAX_LANDMARKS];
    pose2_t pose[2];
    int step;
    int loop_steps;
    int turn_steps;
    int stand_steps;
} synth2_world_t;

synth2_config_t synth2_config_default(uint64_t seed, int n_landmarks);
void synth2_init(synth2_world_t *w, const synth2_config_t *cfg);
int synth2_next(synth2_world_t *w, synth2_step_t *s);
/** World pose of robot k's map frame (its start pose). */
pose2_t synth2_start_pose(int k);

#ifdef __cplusplus
}
#endif

#endif
