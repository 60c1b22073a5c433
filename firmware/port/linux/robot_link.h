/*
 * robot_link.h - where coslam-robot gets its inter-robot link.
 *
 * robot_open_link() is the ONE place that chooses the link backend. Today
 * it returns the null link (hal_link_null(): every operation
 * HAL_E_UNSUPPORTED): the robot maps alone, its meeting protocol counts
 * the failed sends and nothing arrives. The Cyclone DDS backend and the
 * authentication decorator (hal/linux/dds, hal/linux/auth; issue 10 parts
 * 2-3) plug in here, with [link] domain and peers and [fleet] key_file from
 * the configuration; nothing else in the port changes.
 */
#ifndef COSLAM_PORT_ROBOT_LINK_H
#define COSLAM_PORT_ROBOT_LINK_H

#include <stddef.h>

#include "hal/hal_link.h"
#include "robot_config.h"

#ifdef __cplusplus
extern "C" {
#endif

/**
 * Open the link of robot cfg->robot_id. Never NULL: a backend that cannot
 * open gives the null link. *what (may be NULL) receives a short static
 * description for the logs ("null (no DDS link in this build)"). Never
 * logs the fleet key.
 */
hal_link_t *robot_open_link(const robot_config_t *cfg, const char **what);

/** Release what robot_open_link opened. */
void robot_close_link(hal_link_t *link);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_LINK_H */
