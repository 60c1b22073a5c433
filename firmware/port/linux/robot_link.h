/*
 * robot_link.h - where coslam-robot gets its inter-robot link.
 *
 * robot_open_link() is the ONE place that chooses the link backend:
 * Cyclone DDS (hal_link_dds.h, docs/link-dds.md) behind the authentication
 * decorator (hal_link_auth.h, docs/security.md), keyed with the fleet key
 * from [fleet] key_file. The policy (docs/robot.md, "The link"):
 *
 *   [fleet] key_file      [link] insecure   link
 *   set, key good         false             DDS + authentication
 *   set, key bad          false             REFUSED: the robot does not start
 *                                           (missing, unreadable, not a
 *                                           regular file, group-writable or
 *                                           world-accessible, not 64 hex digits)
 *   empty                 false             off: the null link; warned at
 *                                           start and on every status line
 *   (not read)            true              DDS WITHOUT authentication; warned
 *                                           at start and on every status line
 * A build without Cyclone DDS has no link (off, "not built"); a build with
 * DDS but without libsodium has the insecure mode only (off otherwise). The
 * key is never printed; robot_open_link's messages say what is wrong with
 * the file, never what is in it.
 *
 * The stack handed to the robot node, fixed for its whole life:
 *
 *   node -> auth decorator -> slot -> hal_link_dds instance
 *
 * "slot" is the device proxy of robot_devices.c (it answers "down" while
 * the DDS instance is closed), so DDS can fail to open, be retried and come
 * back (robot_link_backend_open_device / _close, called by the device slot) while
 * the decorator - its key, its send counter and the per-sender replay
 * state - stays open from start to exit. In insecure mode the node gets the
 * slot itself; with the link off it gets hal_link_null().
 *
 * Memory: robot_link_t is caller-owned (about 40 KB: the DDS sample and the
 * decorator's buffer); no heap here (Cyclone allocates its own). One thread.
 */
#ifndef COSLAM_PORT_ROBOT_LINK_H
#define COSLAM_PORT_ROBOT_LINK_H

#include <stddef.h>
#include <stdint.h>

#include "coslam/status.h"
#include "hal/hal_link.h"
#include "robot_config.h"

#if COSLAM_HAVE_DDS
#include "hal/hal_link_dds.h"
#endif
#if COSLAM_HAVE_LINK_AUTH
#include "hal/hal_link_auth.h"
#endif

#ifdef __cplusplus
extern "C" {
#endif

/** What robot_open_link decided. */
typedef enum {
    ROBOT_LINK_OFF = 0,       /**< no link (null link): see robot_link_t.off_reason */
    ROBOT_LINK_AUTH = 1,      /**< DDS behind the authentication decorator */
    ROBOT_LINK_INSECURE = 2,  /**< DDS without authentication ([link] insecure = true) */
} robot_link_mode_t;

/** DDS and authentication counters, summed over every DDS instance this
 *  run opened (a reopened backend starts its own counters at zero), so all
 *  of them only grow. Zero for the parts a build or a mode does not have. */
typedef struct {
    /* hal_link_dds_counters_t, same names */
    uint32_t dds_sent, dds_send_not_map, dds_send_trailer_too_long, dds_send_busy, dds_send_io;
    uint32_t dds_delivered, dds_rx_overflow, dds_rx_other_dest, dds_rx_own_id, dds_rx_invalid;
    uint32_t dds_rx_not_data, dds_lost, dds_rejected, dds_rx_io;
    /* hal_link_auth_counters_t, same names: every refusal by its reason */
    uint32_t auth_sent, auth_send_not_map, auth_send_wrong_sender, auth_send_too_long, auth_send_inner_failed;
    uint32_t auth_delivered, auth_rx_overflow, auth_rx_malformed, auth_rx_unauthenticated, auth_rx_truncated;
    uint32_t auth_rx_wrong_key, auth_rx_bad_mac, auth_rx_sender_mismatch, auth_rx_stale, auth_rx_future;
    uint32_t auth_rx_replay, auth_rx_oversize;
    uint32_t auth_refused;    /**< sum of the auth_rx_ refusal counters (not rx_overflow) */
} robot_link_counters_t;

typedef struct {
    robot_link_mode_t mode;
    const char *off_reason;   /**< static; ROBOT_LINK_OFF: why ("no fleet key", ...) */
    hal_link_t *slot;         /**< the device proxy below the decorator (not owned) */
    hal_link_t *node_link;    /**< what the node gets: decorator, slot or null link */
    int backend_open;         /**< the DDS instance is open */
    char what[320];           /**< description for the logs */
#if COSLAM_HAVE_DDS
    hal_link_dds_t dds;
    hal_link_dds_config_t dds_cfg;
    const char *peers[ROBOT_CONFIG_MAX_PEERS + 1u];
    char peer_text[ROBOT_CONFIG_PATH_MAX + 1u];
    hal_link_dds_counters_t dds_closed;  /**< summed counters of closed instances */
#endif
#if COSLAM_HAVE_LINK_AUTH
    hal_link_auth_t auth;
    int auth_open;
#endif
} robot_link_t;

/**
 * Apply the link policy of cfg (header comment) for robot cfg->robot_id:
 * read and check the fleet key, open the authentication decorator over
 * `slot` (the device proxy: its self_id must answer cfg->robot_id at once),
 * fill l->what. Does NOT open DDS (robot_link_backend_open_device does, so
 * that a failure there is a device retried like the others).
 * Returns COSLAM_OK (l->mode says what was chosen; for ROBOT_LINK_OFF,
 * l->off_reason why); COSLAM_E_ARG with msg: the robot must not start (a
 * key file is configured but missing, unreadable, too open or invalid;
 * NULL arguments); COSLAM_E_LINK with msg: the decorator could not open
 * (libsodium failed to initialise). The message names the file and the reason, never the
 * key. The key read from the file is wiped from every buffer of this
 * module before return; the decorator keeps its own copy until close.
 */
coslam_status_t robot_open_link(robot_link_t *l, const robot_config_t *cfg, hal_link_t *slot, char *msg,
                                size_t msg_cap);

/** The handle for robot_node_init: never NULL, the same for l's life. */
hal_link_t *robot_link_handle(robot_link_t *l);

/**
 * Open the DDS instance (first attempt and retries by the device slot), in
 * two parts, so that the DDS open (which blocks: Cyclone starts its threads
 * and sockets) can run on a thread of its own while the control loop goes
 * on (robot_devices.c's openers): _open_device (any one thread, while the
 * backend is closed: it writes only the DDS instance, which nothing reads
 * until _opened) returns HAL_OK; HAL_E_UNSUPPORTED (link off: nothing to
 * open); or the code of hal_link_dds_open (HAL_E_ARG bad setting,
 * HAL_E_BUSY, HAL_E_IO Cyclone refused), with a reason in words in
 * `reason`. On HAL_OK the loop then calls _opened, which makes the
 * instance the open one.
 */
hal_status_t robot_link_backend_open_device(robot_link_t *l, char *reason, size_t reason_cap);
void robot_link_backend_opened(robot_link_t *l);

/** The open DDS instance's handle, or NULL (closed, or no DDS). */
hal_link_t *robot_link_backend(robot_link_t *l);

/** Close the DDS instance (device lost or stopping); its counters are
 *  kept. The decorator stays open: it sees "down" from the slot. */
void robot_link_backend_close(robot_link_t *l);

/** Wait at most timeout_us until what was sent is acknowledged (before a
 *  clean exit, so that the last map messages are not lost). No-op when
 *  the backend is closed. */
void robot_link_flush(robot_link_t *l, uint32_t timeout_us);

/** Close everything; the decorator wipes the key. */
void robot_close_link(robot_link_t *l);

/** Status value of the mode: "auth", "insecure", "off(no_fleet_key)",
 *  "off(no_dds_in_build)", "off(no_auth_in_build)". Static. */
const char *robot_link_mode_name(const robot_link_t *l);

/** The warning for the log and every status line, or NULL when the link
 *  is authenticated: "link: off (no fleet key)", "link: INSECURE ...". */
const char *robot_link_warning(const robot_link_t *l);

/** The counters (header of robot_link_counters_t). */
void robot_link_counters(const robot_link_t *l, robot_link_counters_t *out);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_LINK_H */
