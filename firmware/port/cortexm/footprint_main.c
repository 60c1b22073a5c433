/*
 * Minimal bare-metal image for the Cortex-M cross check (tools/cross_core.sh).
 * It owns the state a robot holds statically - one filter, the map message
 * buffers (outgoing and incoming, and the map a send exports in parts), and
 * the merge's scratch - and calls the
 * public API, so that the linker keeps the code and .bss shows the real
 * footprint of the default configuration. Build with -DFOOTPRINT_FASTSLAM or
 * -DFOOTPRINT_EKFSLAM: a robot runs one filter.
 */
#include <string.h>

#include "coslam/ekfslam.h"
#include "coslam/fastslam.h"
#include "coslam/map_estimate.h"
#include "coslam/map_merge.h"
#include "coslam/map_msg.h"

int main(void);

#if defined(FOOTPRINT_FASTSLAM)
static fastslam_t g_filter;
#elif defined(FOOTPRINT_EKFSLAM)
static ekfslam_t g_filter;
#else
#error "define FOOTPRINT_FASTSLAM or FOOTPRINT_EKFSLAM"
#endif
static map_msg_t g_out;
static map_msg_t g_in;
static map_estimate_t g_send; /* the meeting's send export, done in parts (meeting_t.send_map) */
static uint8_t g_wire[MAP_MSG_MAX_BYTES];
static merge_body_map_t g_body;
static merge_scratch_t g_merge_scratch;
static map_whole_t g_own;
static merge_coverage_t g_coverage;

int main(void)
{
    const pose2_t start = {0.0, 0.0, 0.0};
    const odo_increment_t u = {0.01, 0.0, 0.001};
    const sighting_t z = {2.0, 0.1, 0};
    const merge_config_t mcfg = merge_config_default();
    merge_stats_t stats;
    memset(&stats, 0, sizeof stats);
    merge_coverage_init(&g_coverage);
    merge_coverage_note(&g_coverage, start);
    size_t len = 0U;
#if defined(FOOTPRINT_FASTSLAM)
    const fastslam_config_t cfg = fastslam_config_default();
    if (fastslam_init(&g_filter, &cfg, start, 1U) != COSLAM_OK) {
        return 1;
    }
    (void)fastslam_predict(&g_filter, u);
    (void)fastslam_update(&g_filter, &z, 1);
    map_msg_init(&g_out);
    (void)fastslam_export(&g_filter, &g_out.map);
    (void)fastslam_export_whole(&g_filter, &g_own);
    if (fastslam_export_begin(&g_filter) == COSLAM_OK) {
        int done = 0;
        uint32_t spent = 0U;
        while (!done && fastslam_export_run_msg(&g_filter, &g_send, mcfg.step_units, &done, &spent) == COSLAM_OK) {
        }
    }
#else
    const ekfslam_config_t cfg = ekfslam_config_default();
    if (ekfslam_init(&g_filter, &cfg, start) != COSLAM_OK) {
        return 1;
    }
    (void)ekfslam_predict(&g_filter, u);
    (void)ekfslam_update(&g_filter, &z, 1);
    map_msg_init(&g_out);
    (void)ekfslam_export(&g_filter, &g_out.map);
    (void)ekfslam_export_whole(&g_filter, &g_own);
    (void)ekfslam_export(&g_filter, &g_send);
#endif
    (void)map_msg_encode(&g_out, g_wire, sizeof g_wire, &len);
    if (map_msg_decode(g_wire, len, &g_in) == COSLAM_OK) {
        const robot_sighting_t a = {2.0, 0.0, 0.01, 0.001};
        merge_geometry_t g;
        g.self_sees_other = a;
        g.other_sees_self = a;
        g.own_motion = u;
        g.own_travel_m = 0.01;
        g.sighting_dt_s = 0.1;
        if (merge_prepare(&g_in.map, &g, &cfg.slam, &mcfg, &g_body, &stats) == COSLAM_OK &&
            merge_check(&g_own, &g_coverage, NULL, &cfg.slam, 0U, &mcfg, &g_body, &g_merge_scratch, &stats) ==
                COSLAM_OK) {
#if defined(FOOTPRINT_FASTSLAM)
            (void)merge_into_fastslam(&g_filter, &g_body, &mcfg, &g_merge_scratch, &stats);
#else
            (void)merge_into_ekfslam(&g_filter, &g_body, &mcfg, &g_merge_scratch, &stats);
#endif
        }
    }
    return (int)stats.added;
}
