/*
 * Minimal bare-metal image for the Cortex-M cross check (tools/cross_core.sh).
 * It owns the state a robot would hold statically and calls the public API,
 * so that the linker keeps the code and the .bss shows the real footprint of
 * the default configuration. Build with -DFOOTPRINT_FASTSLAM or
 * -DFOOTPRINT_EKFSLAM: a robot runs one filter.
 */
#include "coslam/fastslam.h"
#include "coslam/ekfslam.h"
#include "coslam/map_estimate.h"

int main(void);

#if defined(FOOTPRINT_FASTSLAM)
static fastslam_t g_filter;
#elif defined(FOOTPRINT_EKFSLAM)
static ekfslam_t g_filter;
#else
#error "define FOOTPRINT_FASTSLAM or FOOTPRINT_EKFSLAM"
#endif
static map_estimate_t g_estimate;

int main(void)
{
    const pose2_t start = {0.0, 0.0, 0.0};
    const odo_increment_t u = {0.01, 0.0, 0.001};
    const sighting_t z = {2.0, 0.1, 0};
#if defined(FOOTPRINT_FASTSLAM)
    const fastslam_config_t cfg = fastslam_config_default();
    if (fastslam_init(&g_filter, &cfg, start, 1U) != COSLAM_OK) {
        return 1;
    }
    (void)fastslam_predict(&g_filter, u);
    (void)fastslam_update(&g_filter, &z, 1);
    (void)fastslam_export(&g_filter, &g_estimate);
#else
    const ekfslam_config_t cfg = ekfslam_config_default();
    if (ekfslam_init(&g_filter, &cfg, start) != COSLAM_OK) {
        return 1;
    }
    (void)ekfslam_predict(&g_filter, u);
    (void)ekfslam_update(&g_filter, &z, 1);
    (void)ekfslam_export(&g_filter, &g_estimate);
#endif
    return (int)g_estimate.n_landmarks;
}
