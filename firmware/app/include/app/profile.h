/*
 * app/profile.h - the capacity profile this build was made with
 * (coslam/config.h), as every tool reports it at start-up and in its
 * outputs: one choice per build (make PROFILE=default|large|host), shared
 * by the robot, the simulator, the replay, the calibration and the benches.
 */
#ifndef APP_PROFILE_H
#define APP_PROFILE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** The key capacities of this build (values of the config.h macros). */
typedef struct {
    const char *name;            /**< COSLAM_PROFILE_NAME: "default", "large" or "host" */
    uint32_t particles;          /**< COSLAM_MAX_PARTICLES */
    uint32_t landmarks;          /**< COSLAM_MAX_LANDMARKS (a Fast-SLAM particle's map) */
    uint32_t ekf_landmarks;      /**< COSLAM_EKF_MAX_LANDMARKS (the EKF-SLAM state) */
    uint32_t sightings;          /**< COSLAM_MAX_SIGHTINGS per frame */
    uint32_t msg_landmarks;      /**< COSLAM_MAX_MSG_LANDMARKS per map message */
    uint32_t msg_max_bytes;      /**< MAP_MSG_MAX_BYTES: the largest encoded map message */
    uint32_t link_payload_bytes; /**< HAL_LINK_MAX_PAYLOAD */
} app_profile_t;

/** This build's profile. O(1). */
app_profile_t app_profile(void);

/**
 * The one start-up line, without a newline, e.g. "profile default: 100
 * particles, 64 landmarks (EKF-SLAM 64), 16 sightings per frame, 64
 * landmarks per map message (4814 B, link payload 16384 B)". Returns what
 * snprintf returns (the length it needed; cap 192 is always enough).
 */
int app_profile_format(char *buf, size_t cap);

#ifdef __cplusplus
}
#endif

#endif /* APP_PROFILE_H */
