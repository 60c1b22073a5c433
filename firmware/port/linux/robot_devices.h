/*
 * robot_devices.h - the devices of coslam-robot: the only place (with
 * robot_link.c and robot_sightings.c) where HAL backends are chosen, and
 * the keeper of their up / down state.
 *
 *   laser    termios serial (hal_serial_linux_open), [laser] device, baud
 *   can      SocketCAN (hal_can_socketcan_open), [can] interface
 *   gpio     libgpiod v1 (hal_gpio_linux_open), [gpio] chip; absent from
 *            builds without libgpiod
 *   camera   robot_open_sightings (robot_sightings.h) chooses; a [camera]
 *            device is V4L2 + the marker detector (robot_camera.h), absent
 *            from builds without them (COSLAM_HAVE_CAMERA)
 *   link     robot_open_link (robot_link.h): Cyclone DDS behind the
 *            authentication decorator; absent when the link policy turns
 *            it off (no fleet key, a build without DDS)
 *   storage  files in a directory (hal_storage_linux_open), [storage] dir
 *   clock    CLOCK_MONOTONIC (hal_clock_linux)
 *
 * The robot node keeps the handles it was given for its whole life, so the
 * laser, CAN, GPIO, camera and link handles it gets are PROXIES owned here:
 * while the device is up each operation is passed to the backend; while it
 * is down every operation answers HAL_E_CLOSED ("not open / went away"; the
 * camera: HAL_E_TIMEOUT, no frame; the link: send HAL_E_CLOSED, receive
 * HAL_E_TIMEOUT, nothing arrives). The link proxy sits BELOW the
 * authentication decorator (robot_link.h), which stays open while DDS
 * comes and goes. A device that is missing or fails to
 * open is reported on the log by name with the reason, and opened again
 * every retry period; its return is logged. A device that goes away while
 * up (its backend answers HAL_E_CLOSED, or HAL_E_IO ROBOT_DEVICES_IO_LIMIT
 * times in a row) is marked lost at once (the proxy answers HAL_E_CLOSED
 * from then on), and closed and reported by robot_devices_service().
 * CAN acceptance filters set while the bus is down are kept and installed
 * when it opens. Unconfigured devices (empty name) are reported once as
 * "not configured" and never tried.
 *
 * Opens in the loop's retries run on a thread per device (the opener) so
 * that a slow or hung open never holds the control loop (a device whose
 * opener thread cannot be started is not opened at all, but down with
 * that reason and retried, the thread started again first): while the slot is
 * not up no proxy touches the device's backend, so the opener owns it for
 * the attempt; the loop takes the outcome at a later service and does the
 * bookkeeping (docs/robot.md "Devices"). What the opener writes is only
 * read by the loop after that take (the worker's mutex orders it): the
 * backend states no proxy reads while the slot is not up, the opener's
 * result and reason, and the replay source it opens into its own
 * replay_opening (the loop reads `replay` at any time; the opener once
 * wrote it there, a data race ThreadSanitizer reported, docs/robot.md).
 *
 * No heap beyond what the backends hold (libgpiod's chip object) and the
 * opener threads' stacks. The API is for one thread (the loop).
 */
#ifndef COSLAM_PORT_ROBOT_DEVICES_H
#define COSLAM_PORT_ROBOT_DEVICES_H

#include <stdint.h>
#include <stdio.h>

#include "app/robot_node.h"
#include "hal/hal_can.h"
#include "hal/hal_can_socketcan.h"
#include "hal/hal_clock.h"
#include "hal/hal_gpio.h"
#include "hal/hal_serial.h"
#include "hal/hal_serial_linux.h"
#include "hal/hal_storage.h"
#include "hal/hal_storage_linux.h"
#include "robot_config.h"
#include "robot_gpio_fd.h"
#include "robot_link.h"
#include "robot_sightings.h"
#include "robot_worker.h"

#if COSLAM_HAVE_GPIOD
#include "hal/hal_gpio_linux.h"
#endif
#if COSLAM_HAVE_CAMERA
#include "robot_camera.h"
#endif

#ifdef __cplusplus
extern "C" {
#endif

/** Consecutive HAL_E_IO answers after which a device counts as gone. */
#define ROBOT_DEVICES_IO_LIMIT 50u

/** A retry's open attempt that takes at least this long [ms] on its
 *  opener thread is reported (a quarter of the drives' 200 ms watchdog,
 *  from when the loop itself waited for it; docs/robot.md "Known
 *  trips"). */
#define ROBOT_DEVICES_SLOW_OPEN_MS 50u

/** An open attempt still running after this long [ms] is said once: a hung
 *  device (a driver stuck in an ioctl, a FIFO with no writer) keeps its own
 *  slot down until the attempt returns, never the loop or another slot. */
#define ROBOT_DEVICES_HUNG_OPEN_MS 5000u

/** robot_devices_open_all waits this long [ms] for the first open attempts
 *  (on the openers, all together); one that has not returned by then (a
 *  FIFO without a writer as the landmark log, a driver stuck in an ioctl)
 *  leaves its device down and the robot starts without it. Longer than
 *  any healthy open measured (a UVC camera 0.1-0.5 s, Cyclone DDS). */
#define ROBOT_DEVICES_START_OPEN_MS 2000u

/** The blob a storage retry saves after a failed snapshot save
 *  (robot_devices_storage_save_failed), removed when written. */
#define ROBOT_DEVICES_SAVE_PROBE "coslam-save-probe"

/** robot_devices_close_all waits this long [ms] for a running open attempt. */
#define ROBOT_DEVICES_CLOSE_WAIT_MS 1000u

typedef enum {
    ROBOT_DEV_LASER = 0,
    ROBOT_DEV_CAN = 1,
    ROBOT_DEV_GPIO = 2,
    ROBOT_DEV_CAMERA = 3,
    ROBOT_DEV_LINK = 4,
    ROBOT_DEV_STORAGE = 5,
    ROBOT_DEV_COUNT = 6,
} robot_dev_t;

/** What a device slot is doing. */
/** Longest reason of a failed open, in words [bytes with the NUL]: a
 *  path of ROBOT_CONFIG_PATH_MAX and the OS's reason fit. */
#define ROBOT_DEVICES_REASON_MAX 320u

typedef enum {
    ROBOT_DEV_UP = 0,       /**< open and working */
    ROBOT_DEV_DOWN = 1,     /**< configured, not open: retried every retry period */
    ROBOT_DEV_ABSENT = 2,   /**< not configured, or no backend for it: never tried */
} robot_dev_state_t;

typedef struct {
    const char *name;            /**< "laser", "can", ... */
    robot_dev_state_t state;
    int lost;                    /**< an operation saw it go away: closed at the next service */
    hal_status_t last_error;     /**< reason of the last failure (HAL_OK: none) */
    char reason[ROBOT_DEVICES_REASON_MAX]; /**< and in words */
    char what[320];              /**< what it is: path, interface, backend */
    uint32_t io_in_row;          /**< consecutive HAL_E_IO answers */
    uint32_t opens;              /**< successful opens */
    uint32_t open_failures;
    uint32_t losses;             /**< went away while up */
    uint32_t open_max_ms;        /**< the longest open attempt of the loop's retries [ms] */
    uint32_t slow_opens;         /**< those of ROBOT_DEVICES_SLOW_OPEN_MS or more (reported) */
    uint32_t hung_opens;         /**< attempts still running after ROBOT_DEVICES_HUNG_OPEN_MS (reported) */
    uint32_t opener_start_failures; /**< attempts that found no opener thread and could not start one
                                         (reported; each a failed attempt, never opened in the loop) */
    int opening;                 /**< an attempt runs on the slot's opener thread (the slot is DOWN) */
    int hung_said;               /**< ... and has been said to hang */
    int start_open_late;         /**< ... the first one, begun at start-up (robot_devices_open_all) */
    uint64_t open_began_us;      /**< when it was handed over */
    uint64_t next_try_us;        /**< next open attempt (DOWN) */
} robot_dev_status_t;

struct robot_devices;

/** A slot's opener: a thread (robot_worker.h) that runs the blocking part
 *  of the loop's open attempts (robot_devices.c), one at a time. */
typedef struct {
    robot_worker_t worker;
    struct robot_devices *d;
    robot_dev_t id;
    hal_status_t result;         /**< the attempt's outcome (once ended) */
    char reason[ROBOT_DEVICES_REASON_MAX]; /**< and in words */
} robot_dev_opener_t;

typedef struct robot_devices {
    const robot_config_t *cfg;
    hal_clock_t *clock;
    FILE *log;
    int verbose;
    uint32_t retry_us;
    robot_dev_status_t dev[ROBOT_DEV_COUNT];
    /* proxies handed to the robot node */
    hal_serial_t laser;
    hal_can_t can;
    hal_gpio_t gpio;
    sighting_source_t sightings;
    /* backends */
    hal_serial_t laser_dev;
    hal_serial_linux_t laser_state;
    hal_can_socketcan_t can_state;   /**< reset by each open (the opener's while the slot is not up) */
    uint64_t can_stamps_unbelieved_past; /**< can_state.stamps_unbelieved of the sessions closed before
                                              (robot_devices_can_stamps_unbelieved; the loop's) */
    hal_can_filter_t can_filters[HAL_CAN_MAX_FILTERS];
    size_t can_filter_count;
#if COSLAM_HAVE_GPIOD
    hal_gpio_linux_t gpio_state;
#endif
    robot_gpio_fd_t gpio_fd_state;   /**< --gpio-fd (e2e tests only) */
    robot_sightings_kind_t camera_kind;
    robot_replay_t replay;           /**< the loop's: the source while the camera slot is up (the loop reads it
                                          whatever the slot's state: robot_live_say_refusals) */
    robot_replay_t replay_opening;   /**< the camera opener's: an attempt opens the source here, and the loop
                                          moves it into `replay` once the outcome is taken (open_finish) */
    uint32_t live_bad_past;          /**< replay.live_bad of the streams closed before (robot_devices_live_counters) */
    uint32_t live_robots_refused_past; /**< replay.live_robots_refused of the streams closed before */
#if COSLAM_HAVE_CAMERA
    robot_camera_t camera;           /**< the camera (camera_kind ROBOT_SIGHTINGS_CAMERA) */
#endif
    hal_link_t link_slot;            /**< the link proxy (below the decorator) */
    robot_link_t link;               /**< policy, DDS instance, decorator */
    hal_storage_linux_t storage_state;
    int storage_probe_fsync_failed;  /**< the storage open's probe failed at its fsync (the opener's, taken by the loop) */
    uint32_t storage_fsync_failures; /**< fsyncs the storage failed: probes and snapshot writes (the loop's) */
    size_t storage_save_probe_bytes; /**< a snapshot save of this size failed (0: none since the last good one):
                                          the storage's open also saves a blob of that size and comes back only
                                          if it works (the loop's; read by the opener after the submit) */
    int storage_save_probe_failed;   /**< the open's save probe failed (the opener's, taken by the loop) */
    uint32_t storage_save_probes_failed; /**< retries the save probe kept down (the loop's) */
    robot_dev_opener_t opener[ROBOT_DEV_COUNT];
} robot_devices_t;

/** Set up the slots and proxies and apply the link policy (robot_open_link:
 *  the fleet key is read here; DDS is not opened yet). `log` gets the
 *  device reports (stderr in coslam-robot); verbose adds every failed
 *  retry. Returns COSLAM_OK; otherwise the robot must not start (exit 2
 *  for COSLAM_E_ARG): robot_open_link's code, its reason in msg. */
coslam_status_t robot_devices_init(robot_devices_t *d, const robot_config_t *cfg, hal_clock_t *clock, FILE *log,
                                   int verbose, char *msg, size_t msg_cap);

/** First attempt at every device (start-up: the loop does not run yet).
 *  Starts an opener thread for every configured device and hands each
 *  first attempt to it (a device whose opener cannot be started, e.g.
 *  pthread_create fails, is down with that reason, HAL_E_BUSY, counted in
 *  opener_start_failures; it is never opened in the caller's thread, and
 *  each retry tries to start the opener again before its open);
 *  waits for them all until one deadline, ROBOT_DEVICES_START_OPEN_MS
 *  after the hand-over. Each device is reported by name (up, down with the
 *  reason, not configured). An attempt still running at the deadline
 *  leaves its device down, said ("its open has not returned within ...:
 *  the robot starts without it"); it goes on on its opener, and
 *  robot_devices_service takes its outcome like a retry's ("up (its open
 *  begun at the start has returned)"), or says it hung. */
void robot_devices_open_all(robot_devices_t *d, uint64_t now_us);

/**
 * Close and report lost devices; retry the down ones whose time has come
 * (a return is reported). A retry runs on the device's opener thread: this
 * call hands it over and a later call takes its outcome, so the loop never
 * waits for an open. Returns a bit mask (1 << robot_dev_t)
 * of the devices whose state changed in this call.
 */
unsigned robot_devices_service(robot_devices_t *d, uint64_t now_us);

/** Try device id again now, not at its next retry, and wait at most
 *  wait_ms for the attempt (the stop's final snapshot: the storage down
 *  since a failed write). Other devices whose retry is due are serviced
 *  too. Returns 1 if the device is up. */
int robot_devices_reopen_now(robot_devices_t *d, robot_dev_t id, uint64_t now_us, uint32_t wait_ms);

/** Open attempts running on opener threads now (not those that have
 *  returned and wait for the next service to take them). */
unsigned robot_devices_opening(const robot_devices_t *d);

/** Wait at most wait_ms until every running open attempt has returned (its
 *  outcome is taken by the next robot_devices_service). Tests and benches
 *  on a fake clock; never the control loop. Returns how many still run. */
unsigned robot_devices_wait_opens(robot_devices_t *d, uint32_t wait_ms);

/** Mark device `id` down with `why` (e.g. the GPIO lines could not be
 *  claimed although the chip opened): closed, reported, retried later. */
void robot_devices_fail(robot_devices_t *d, robot_dev_t id, hal_status_t why, const char *reason, uint64_t now_us);

/** Stop the opener threads (an attempt still running is waited for up to
 *  ROBOT_DEVICES_CLOSE_WAIT_MS; one that does not return is said and left
 *  to the process's exit, its device not released), close everything (the
 *  proxies answer HAL_E_CLOSED afterwards) and release what the camera
 *  allocated at its first open. */
void robot_devices_close_all(robot_devices_t *d);

/** The handles for robot_node_init (proxies, the link, the clock). */
robot_node_io_t robot_devices_io(robot_devices_t *d);

/** The live sighting stream's refusals (--sightings-fd; robot_sightings.h)
 *  since the start: the totals of the streams closed before plus, while the
 *  slot is up, the open one's. A reopen starts the stream's own counters
 *  (robot_live_open), so these are what the status reports: they never go
 *  back. Either pointer may be NULL. */
void robot_devices_live_counters(const robot_devices_t *d, uint32_t *live_bad, uint32_t *live_robots_refused);

/** The CAN backend's kernel stamps not believed (hal_can_socketcan.h
 *  `stamps_unbelieved`: in the future or older than
 *  HAL_CAN_SOCKETCAN_MAX_AGE_US, the read-out time used) since the start:
 *  the sessions closed before plus, while the slot is up, the open one's.
 *  Each open starts the backend's own count again (on the opener thread,
 *  while the slot is not up, so the open session's is read only while
 *  it is up), so this is what the status reports: it never goes back. */
uint64_t robot_devices_can_stamps_unbelieved(const robot_devices_t *d);

/** A snapshot save of `bytes` failed (ws HAL_E_IO or HAL_E_CLOSED: the
 *  medium, `reason` in words): the storage goes down as robot_devices_fail,
 *  and its retries come back only when a save of that size works, not on
 *  the probe file alone (a medium whose one-byte probe is fsync'ed but
 *  whose larger writes fail at fsync flapped up and down): each retry's
 *  open also saves a blob of `bytes` (ROBOT_DEVICES_SAVE_PROBE) the way a
 *  snapshot is saved, then removes it; one that fails keeps the storage
 *  down, said once, counted in storage_save_probes_failed. */
void robot_devices_storage_save_failed(robot_devices_t *d, size_t bytes, hal_status_t ws, const char *reason,
                                       uint64_t now_us);

/** The storage for snapshots: the Linux directory while up, else NULL. */
hal_storage_t *robot_devices_storage(robot_devices_t *d);

/** "up", "down" or "absent". */
const char *robot_dev_state_name(robot_dev_state_t s);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_DEVICES_H */
