#include "app/profile.h"

#include <stdio.h>

#include "coslam/config.h"
#include "coslam/map_msg.h"
#include "hal/hal_link.h"

app_profile_t app_profile(void)
{
    const app_profile_t p = {COSLAM_PROFILE_NAME,
                             (uint32_t)COSLAM_MAX_PARTICLES,
                             (uint32_t)COSLAM_MAX_LANDMARKS,
                             (uint32_t)COSLAM_EKF_MAX_LANDMARKS,
                             (uint32_t)COSLAM_MAX_SIGHTINGS,
                             (uint32_t)COSLAM_MAX_MSG_LANDMARKS,
                             (uint32_t)MAP_MSG_MAX_BYTES,
                             (uint32_t)HAL_LINK_MAX_PAYLOAD};
    return p;
}

int app_profile_format(char *buf, size_t cap)
{
    const app_profile_t p = app_profile();
    return snprintf(buf, cap,
                    "profile %s: %lu particles, %lu landmarks (EKF-SLAM %lu), %lu sightings per frame, %lu landmarks "
                    "per map message (%lu B, link payload %lu B)",
                    p.name, (unsigned long)p.particles, (unsigned long)p.landmarks, (unsigned long)p.ekf_landmarks,
                    (unsigned long)p.sightings, (unsigned long)p.msg_landmarks, (unsigned long)p.msg_max_bytes,
                    (unsigned long)p.link_payload_bytes);
}
