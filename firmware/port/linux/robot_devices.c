/* Device slots, backends and proxies of coslam-robot (robot_devices.h). */
#include "robot_devices.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "hal_can_socketcan_internal.h" /* --can-fd: e2e tests only */
#include "robot_link.h"
#include "robot_snapshot.h" /* ROBOT_SNAPSHOT_MAX_BYTES: the storage's save probe */

/* snprintf that may truncate on purpose (messages, labels): always terminated. */
__attribute__((format(printf, 3, 4))) static void put_text(char *dst, size_t cap, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    (void)vsnprintf(dst, cap, fmt, ap);
    va_end(ap);
}

static const char *const dev_names[ROBOT_DEV_COUNT] = {"laser", "can", "gpio", "camera", "link", "storage"};

const char *robot_dev_state_name(robot_dev_state_t s)
{
    switch (s) {
    case ROBOT_DEV_UP: return "up";
    case ROBOT_DEV_DOWN: return "down";
    case ROBOT_DEV_ABSENT: return "absent";
    }
    return "?";
}

static const char *hal_reason(hal_status_t s)
{
    switch (s) {
    case HAL_E_NOT_FOUND: return "no such device";
    case HAL_E_BUSY: return "in use";
    case HAL_E_IO: return "I/O error";
    case HAL_E_UNSUPPORTED: return "not supported";
    case HAL_E_CLOSED: return "went away or is down";
    case HAL_E_CORRUPT: return "bad content";
    case HAL_E_ARG: return "bad setting";
    default: return "failed";
    }
}

/* A backend answered `s` while the device was up: count it, and mark the
 * device lost when it is gone (closed now, reported by the next service). */
static hal_status_t watch(robot_devices_t *d, robot_dev_t id, hal_status_t s)
{
    robot_dev_status_t *st = &d->dev[id];
    if (s == HAL_E_IO) {
        st->io_in_row++;
    } else if (s != HAL_E_CLOSED) {
        st->io_in_row = 0U;
    }
    if (s == HAL_E_CLOSED || st->io_in_row >= ROBOT_DEVICES_IO_LIMIT) {
        if (!st->lost) {
            st->lost = 1;
            st->last_error = s;
        }
        return HAL_E_CLOSED;
    }
    return s;
}

static int usable(const robot_devices_t *d, robot_dev_t id)
{
    return d->dev[id].state == ROBOT_DEV_UP && !d->dev[id].lost;
}

/* ---- laser proxy --------------------------------------------------------- */

static robot_devices_t *of_serial(hal_serial_t *s)
{
    return (robot_devices_t *)s->backend;
}

static hal_status_t px_set_baud(hal_serial_t *s, uint32_t baud)
{
    robot_devices_t *d = of_serial(s);
    return usable(d, ROBOT_DEV_LASER) ? watch(d, ROBOT_DEV_LASER, hal_serial_set_baud(&d->laser_dev, baud))
                                      : HAL_E_CLOSED;
}

static hal_status_t px_write(hal_serial_t *s, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    robot_devices_t *d = of_serial(s);
    return usable(d, ROBOT_DEV_LASER)
               ? watch(d, ROBOT_DEV_LASER, hal_serial_write(&d->laser_dev, data, len, timeout_us))
               : HAL_E_CLOSED;
}

static hal_status_t px_read(hal_serial_t *s, uint8_t *buf, size_t cap, size_t *n_read, uint32_t timeout_us)
{
    robot_devices_t *d = of_serial(s);
    return usable(d, ROBOT_DEV_LASER)
               ? watch(d, ROBOT_DEV_LASER, hal_serial_read(&d->laser_dev, buf, cap, n_read, timeout_us))
               : HAL_E_CLOSED;
}

static hal_status_t px_flush(hal_serial_t *s)
{
    robot_devices_t *d = of_serial(s);
    return usable(d, ROBOT_DEV_LASER) ? watch(d, ROBOT_DEV_LASER, hal_serial_flush_input(&d->laser_dev))
                                      : HAL_E_CLOSED;
}

static const hal_serial_ops_t laser_proxy_ops = {px_set_baud, px_write, px_read, px_flush, NULL};

/* ---- CAN proxy ----------------------------------------------------------- */

static robot_devices_t *of_can(hal_can_t *c)
{
    return (robot_devices_t *)c->backend;
}

static hal_status_t pc_send(hal_can_t *c, const hal_can_frame_t *f, uint32_t timeout_us)
{
    robot_devices_t *d = of_can(c);
    return usable(d, ROBOT_DEV_CAN) ? watch(d, ROBOT_DEV_CAN, hal_can_send(&d->can_state.can, f, timeout_us))
                                    : HAL_E_CLOSED;
}

static hal_status_t pc_receive(hal_can_t *c, hal_can_frame_t *f, uint32_t timeout_us)
{
    robot_devices_t *d = of_can(c);
    return usable(d, ROBOT_DEV_CAN) ? watch(d, ROBOT_DEV_CAN, hal_can_receive(&d->can_state.can, f, timeout_us))
                                    : HAL_E_CLOSED;
}

static hal_status_t pc_set_filters(hal_can_t *c, const hal_can_filter_t *filters, size_t count)
{
    robot_devices_t *d = of_can(c);
    if (count > HAL_CAN_MAX_FILTERS) {
        return HAL_E_ARG;
    }
    /* kept for the next open; the drive driver sets them once at start */
    if (count > 0U) {
        memcpy(d->can_filters, filters, count * sizeof filters[0]);
    }
    d->can_filter_count = count;
    return usable(d, ROBOT_DEV_CAN)
               ? watch(d, ROBOT_DEV_CAN, hal_can_set_filters(&d->can_state.can, filters, count))
               : HAL_OK;
}

static hal_status_t pc_get_status(hal_can_t *c, hal_can_status_t *status)
{
    robot_devices_t *d = of_can(c);
    return usable(d, ROBOT_DEV_CAN) ? watch(d, ROBOT_DEV_CAN, hal_can_get_status(&d->can_state.can, status))
                                    : HAL_E_CLOSED;
}

static const hal_can_ops_t can_proxy_ops = {pc_send, pc_receive, pc_set_filters, pc_get_status, NULL};

/* ---- GPIO proxy ---------------------------------------------------------- */

static robot_devices_t *of_gpio(hal_gpio_t *g)
{
    return (robot_devices_t *)g->backend;
}

static hal_gpio_t *gpio_backend(robot_devices_t *d)
{
    if (d->cfg->gpio_fd >= 0) {
        return &d->gpio_fd_state.dev;
    }
#if COSLAM_HAVE_GPIOD
    return &d->gpio_state.dev;
#else
    (void)d;
    return hal_gpio_null();
#endif
}

static hal_status_t pg_line_count(hal_gpio_t *g, uint32_t *n)
{
    robot_devices_t *d = of_gpio(g);
    return usable(d, ROBOT_DEV_GPIO) ? watch(d, ROBOT_DEV_GPIO, hal_gpio_line_count(gpio_backend(d), n))
                                     : HAL_E_CLOSED;
}

static hal_status_t pg_configure(hal_gpio_t *g, uint32_t line, const hal_gpio_config_t *cfg)
{
    robot_devices_t *d = of_gpio(g);
    return usable(d, ROBOT_DEV_GPIO) ? watch(d, ROBOT_DEV_GPIO, hal_gpio_configure(gpio_backend(d), line, cfg))
                                     : HAL_E_CLOSED;
}

static hal_status_t pg_read(hal_gpio_t *g, uint32_t line, bool *active)
{
    robot_devices_t *d = of_gpio(g);
    return usable(d, ROBOT_DEV_GPIO) ? watch(d, ROBOT_DEV_GPIO, hal_gpio_read(gpio_backend(d), line, active))
                                     : HAL_E_CLOSED;
}

static hal_status_t pg_write(hal_gpio_t *g, uint32_t line, bool active)
{
    robot_devices_t *d = of_gpio(g);
    return usable(d, ROBOT_DEV_GPIO) ? watch(d, ROBOT_DEV_GPIO, hal_gpio_write(gpio_backend(d), line, active))
                                     : HAL_E_CLOSED;
}

static hal_status_t pg_wait_edge(hal_gpio_t *g, uint32_t line, hal_gpio_event_t *ev, uint32_t timeout_us)
{
    robot_devices_t *d = of_gpio(g);
    return usable(d, ROBOT_DEV_GPIO)
               ? watch(d, ROBOT_DEV_GPIO, hal_gpio_wait_edge(gpio_backend(d), line, ev, timeout_us))
               : HAL_E_CLOSED;
}

static hal_status_t pg_release(hal_gpio_t *g, uint32_t line)
{
    robot_devices_t *d = of_gpio(g);
    /* releasing a line of a closed chip is done: the chip gave it back */
    return usable(d, ROBOT_DEV_GPIO) ? hal_gpio_release(gpio_backend(d), line) : HAL_OK;
}

static const hal_gpio_ops_t gpio_proxy_ops = {pg_line_count, pg_configure, pg_read, pg_write,
                                              pg_wait_edge,  pg_release,   NULL};

/* ---- camera proxy -------------------------------------------------------- */

static hal_status_t ps_next_frame(sighting_source_t *s, sighting_frame_t *out, uint32_t timeout_us)
{
    robot_devices_t *d = (robot_devices_t *)s->backend;
    if (!usable(d, ROBOT_DEV_CAMERA)) {
        return HAL_E_TIMEOUT; /* no camera: no frame, which is not an error */
    }
    sighting_source_t *src = &d->replay.src;
#if COSLAM_HAVE_CAMERA
    if (d->camera_kind == ROBOT_SIGHTINGS_CAMERA) {
        src = &d->camera.src;
    }
#endif
    const hal_status_t st = sighting_source_next_frame(src, out, timeout_us);
    return st == HAL_E_TIMEOUT || st == HAL_OK ? st : watch(d, ROBOT_DEV_CAMERA, st);
}

static const sighting_source_ops_t sightings_proxy_ops = {ps_next_frame};

/* ---- link proxy (below the authentication decorator) ------------------- */

static robot_devices_t *of_link(hal_link_t *l)
{
    return (robot_devices_t *)l->backend;
}

static hal_status_t pl_self_id(hal_link_t *l, uint16_t *id)
{
    /* fixed, and answered while DDS is down: the decorator reads it at open */
    *id = of_link(l)->cfg->robot_id;
    return HAL_OK;
}

static hal_status_t pl_send(hal_link_t *l, uint16_t dest_id, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    robot_devices_t *d = of_link(l);
    hal_link_t *b = robot_link_backend(&d->link);
    return usable(d, ROBOT_DEV_LINK) && b != NULL
               ? watch(d, ROBOT_DEV_LINK, hal_link_send(b, dest_id, data, len, timeout_us))
               : HAL_E_CLOSED;
}

static hal_status_t pl_recv(hal_link_t *l, uint8_t *buf, size_t cap, hal_link_rx_info_t *info, uint32_t timeout_us)
{
    robot_devices_t *d = of_link(l);
    hal_link_t *b = robot_link_backend(&d->link);
    if (!usable(d, ROBOT_DEV_LINK) || b == NULL) {
        return HAL_E_TIMEOUT; /* link down: nothing arrives, which is not an error */
    }
    const hal_status_t st = hal_link_recv(b, buf, cap, info, timeout_us);
    return st == HAL_E_TIMEOUT || st == HAL_OK || st == HAL_E_OVERFLOW ? st : watch(d, ROBOT_DEV_LINK, st);
}

/* no close: the slot closes the backend, robot_close_link the rest */
static const hal_link_ops_t link_proxy_ops = {pl_self_id, pl_send, pl_recv, NULL};

/* ---- slots --------------------------------------------------------------- */

static void say(robot_devices_t *d, const char *name, const robot_dev_status_t *st, const char *text)
{
    if (d->log != NULL) {
        if (st->what[0] != '\0') {
            fprintf(d->log, "coslam-robot: %s (%s): %s\n", name, st->what, text);
        } else {
            fprintf(d->log, "coslam-robot: %s: %s\n", name, text);
        }
        fflush(d->log);
    }
}

static void set_down(robot_devices_t *d, robot_dev_t id, hal_status_t why, const char *reason, uint64_t now_us)
{
    robot_dev_status_t *st = &d->dev[id];
    st->state = ROBOT_DEV_DOWN;
    st->last_error = why;
    st->open_failures++;
    st->next_try_us = now_us + d->retry_us;
    put_text(st->reason, sizeof st->reason, "%s", reason);
}

/* The loop's part before an open attempt: the camera's detector (made at
 * the first call that gets this far, with the colour table and the range
 * model). Anything else but HAL_OK ends the attempt (open_finish). */
static hal_status_t open_prepare(robot_devices_t *d, robot_dev_t id, char *reason, size_t reason_cap)
{
#if COSLAM_HAVE_CAMERA
    if (id == ROBOT_DEV_CAMERA && d->camera_kind == ROBOT_SIGHTINGS_CAMERA) {
        return robot_camera_open_prepare(&d->camera, reason, reason_cap);
    }
#else
    (void)d;
    (void)id;
    (void)reason;
    (void)reason_cap;
#endif
    return HAL_OK;
}

/* A file the storage open writes and removes to see that the directory
 * takes one. */
#define STORAGE_PROBE ".coslam-write-probe"

/* Whether the storage directory `dir` takes a file: HAL_OK, or the OS's
 * reason in `reason`. A directory that opens and locks but cannot be
 * written (read-only, a read-only mount, full) was up until the first
 * snapshot's write failed, then down, then up again at the retry, then
 * down at the next write: said four lines a snapshot period. With the
 * probe its open fails: down once, said with the reason, retried on the
 * retry period without a word until it works. The probe is fsync'ed: a
 * medium that takes the bytes but fails their fsync (a card whose
 * write-back fails) was up at every retry and down at the next snapshot's
 * write, said at each; now it stays down (*fsync_failed set, counted by
 * the loop in storage_fsync_failures). On the opener thread, so a slow
 * fsync holds neither the loop nor (beyond ROBOT_DEVICES_START_OPEN_MS)
 * the start. */
static hal_status_t storage_writable(const char *dir, char *reason, size_t reason_cap, int *fsync_failed)
{
    *fsync_failed = 0;
    char path[ROBOT_CONFIG_PATH_MAX + sizeof STORAGE_PROBE + 2u];
    put_text(path, sizeof path, "%s/%s", dir, STORAGE_PROBE);
    /* O_NOFOLLOW: a link there is never written through */
    const int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOFOLLOW, 0644);
    int e = fd < 0 ? errno : 0;
    if (fd >= 0) {
        if (write(fd, "x", 1U) != 1) {
            e = errno != 0 ? errno : EIO;
        } else if (fsync(fd) != 0) {
            e = errno;
            *fsync_failed = 1;
        }
        if (close(fd) != 0 && e == 0) {
            e = errno;
        }
        (void)unlink(path);
    }
    if (e == 0) {
        return HAL_OK;
    }
    const hal_status_t s = e == ENOSPC || e == EDQUOT ? HAL_E_OVERFLOW : HAL_E_IO;
    put_text(reason, reason_cap, "cannot write in the directory: %s%s (the probe file %s) (%s)",
             *fsync_failed ? "fsync: " : "", strerror(e), STORAGE_PROBE, hal_status_str(s));
    return s;
}

/* A save of `bytes` through the just opened storage `st`, as a snapshot's
 * (temporary, fsync, rename, directory fsync), then removed: HAL_OK, or
 * why not in `reason` (*fsync_failed set when it failed at an fsync). On
 * the opener thread, after a snapshot save of that size failed. */
static hal_status_t storage_saves(hal_storage_linux_t *st, size_t bytes, char *reason, size_t reason_cap,
                                  int *fsync_failed)
{
    static uint8_t zeros[ROBOT_SNAPSHOT_MAX_BYTES]; /* read only (by every opener at once, harmless) */
    const size_t n = bytes < sizeof zeros ? bytes : sizeof zeros;
    const hal_status_t s = hal_storage_write(&st->dev, ROBOT_DEVICES_SAVE_PROBE, zeros, n);
    if (s == HAL_OK) {
        (void)hal_storage_remove(&st->dev, ROBOT_DEVICES_SAVE_PROBE);
        return HAL_OK;
    }
    *fsync_failed = st->last_fsync_failed;
    const int e = st->last_errno;
    put_text(reason, reason_cap,
             "a save of %zu bytes (the size of the snapshot that failed) still fails: %s%s (%s); the probe file "
             "alone works: back when such a save works",
             n, *fsync_failed ? "fsync: " : "", e != 0 ? strerror(e) : "no OS reason", hal_status_str(s));
    return s;
}

/* The part of an open attempt that blocks. It writes only device id's
 * backend state, which no proxy and no status read touches while the slot
 * is not up, and the replay source in replay_opening (never `replay`,
 * which the loop reads at any time): so it runs on the slot's opener
 * thread while the loop goes on (or in the loop, without an opener). */
static hal_status_t open_backend(robot_devices_t *d, robot_dev_t id, char *reason, size_t reason_cap)
{
    const robot_config_t *c = d->cfg;
    hal_status_t s = HAL_E_UNSUPPORTED;
    switch (id) {
    case ROBOT_DEV_LASER:
        s = hal_serial_linux_open(&d->laser_dev, &d->laser_state, c->laser_device, c->laser_baud);
        break;
    case ROBOT_DEV_CAN:
        if (c->can_fd >= 0) {
            /* e2e tests: a socketpair from the device server stands in for
             * the SocketCAN socket (only the open differs); the inherited fd
             * stays ours for a reopen, the backend owns the dup */
            const int fd = dup(c->can_fd);
            s = fd >= 0 ? hal_can_socketcan_open_fd(&d->can_state, fd) : HAL_E_IO;
        } else {
            s = hal_can_socketcan_open(&d->can_state, c->can_interface);
        }
        break;
    case ROBOT_DEV_GPIO:
        if (c->gpio_fd >= 0) {
            s = robot_gpio_fd_open(&d->gpio_fd_state, c->gpio_fd, d->clock); /* e2e tests */
            break;
        }
#if COSLAM_HAVE_GPIOD
        s = hal_gpio_linux_open(&d->gpio_state, c->gpio_chip, "coslam-robot");
#endif
        break;
    case ROBOT_DEV_CAMERA:
        if (d->camera_kind == ROBOT_SIGHTINGS_REPLAY || d->camera_kind == ROBOT_SIGHTINGS_LIVE) {
            robot_sightings_kind_t k =
                robot_open_sightings(&d->replay_opening, c, d->clock, &s, reason, reason_cap);
            (void)k;
        }
#if COSLAM_HAVE_CAMERA
        if (d->camera_kind == ROBOT_SIGHTINGS_CAMERA) {
            s = robot_camera_open_device(&d->camera, reason, reason_cap);
        }
#endif
        break;
    case ROBOT_DEV_STORAGE:
        errno = 0;
        s = hal_storage_linux_open(&d->storage_state, c->storage_dir);
        if (s == HAL_E_BUSY) {
            put_text(reason, reason_cap,
                     "the directory is locked by another process (another coslam-robot on the same storage?) "
                     "(HAL_E_BUSY)");
        } else if (s != HAL_OK && errno != 0) {
            /* the OS's reason ("Not a directory", "No such file or
             * directory" for a missing parent), not only the HAL's class */
            put_text(reason, reason_cap, "%s (%s)", strerror(errno), hal_status_str(s));
        } else if (s == HAL_OK) {
            d->storage_save_probe_failed = 0;
            s = storage_writable(c->storage_dir, reason, reason_cap, &d->storage_probe_fsync_failed);
            if (s == HAL_OK && d->storage_save_probe_bytes > 0U) {
                s = storage_saves(&d->storage_state, d->storage_save_probe_bytes, reason, reason_cap,
                                  &d->storage_probe_fsync_failed);
                d->storage_save_probe_failed = s != HAL_OK;
            }
            if (s != HAL_OK) {
                hal_storage_close(&d->storage_state.dev);
            }
        }
        break;
    case ROBOT_DEV_LINK:
        s = robot_link_backend_open_device(&d->link, reason, reason_cap);
        break;
    default:
        break;
    }
    return s;
}

/* The loop's part after an open attempt whose parts before gave s (and
 * `why`): the device's own counters, the CAN filters, the slot's state.
 * Returns 1 if up. */
static int open_finish(robot_devices_t *d, robot_dev_t id, hal_status_t s, const char *why, uint64_t now_us)
{
    robot_dev_status_t *st = &d->dev[id];
    char reason[ROBOT_DEVICES_REASON_MAX];
    put_text(reason, sizeof reason, "%s", why != NULL ? why : "");
#if COSLAM_HAVE_CAMERA
    if (id == ROBOT_DEV_CAMERA && d->camera_kind == ROBOT_SIGHTINGS_CAMERA) {
        s = robot_camera_open_finish(&d->camera, s);
    }
#endif
    if (id == ROBOT_DEV_CAMERA &&
        (d->camera_kind == ROBOT_SIGHTINGS_REPLAY || d->camera_kind == ROBOT_SIGHTINGS_LIVE)) {
        /* the opener's source published: from here on the loop's */
        if (s == HAL_OK) {
            robot_replay_move(&d->replay, &d->replay_opening);
        } else {
            robot_replay_close(&d->replay_opening);
        }
    }
    if (id == ROBOT_DEV_LINK && s == HAL_OK) {
        robot_link_backend_opened(&d->link);
    }
    if (id == ROBOT_DEV_STORAGE && d->storage_probe_fsync_failed) {
        d->storage_probe_fsync_failed = 0;
        d->storage_fsync_failures++;
    }
    if (id == ROBOT_DEV_STORAGE && d->storage_save_probe_failed) {
        d->storage_save_probe_failed = 0;
        d->storage_save_probes_failed++;
    }
    if (id == ROBOT_DEV_STORAGE && s == HAL_OK) {
        d->storage_save_probe_bytes = 0U; /* a save of that size worked (or none had failed) */
    }
    if (id == ROBOT_DEV_CAN && s == HAL_OK && d->can_filter_count > 0U) {
        /* the filters the drive driver set (kept while the bus was down) */
        const hal_status_t fs = hal_can_set_filters(&d->can_state.can, d->can_filters, d->can_filter_count);
        if (fs != HAL_OK && fs != HAL_E_UNSUPPORTED) {
            hal_can_close(&d->can_state.can);
            s = fs;
        }
    }
    if (s == HAL_OK) {
        st->state = ROBOT_DEV_UP;
        st->lost = 0;
        st->io_in_row = 0U;
        st->opens++;
        st->last_error = HAL_OK;
        st->reason[0] = '\0';
        return 1;
    }
    if (reason[0] == '\0') {
        put_text(reason, sizeof reason, "%s (%s)", hal_reason(s), hal_status_str(s));
    }
    set_down(d, id, s, reason, now_us);
    return 0;
}

/* ---- openers: the blocking part of the loop's retries on a thread -------- */

/* The attempt, on the slot's opener thread. */
static void opener_run(void *ctx)
{
    robot_dev_opener_t *o = (robot_dev_opener_t *)ctx;
    o->result = open_backend(o->d, o->id, o->reason, sizeof o->reason);
}

/* Start slot id's opener if its thread is not running (at start-up, and
 * again at each retry after a start failed). Returns 0; otherwise the
 * errno of the failed start, said in `reason`: the device then stays down
 * (counted, retried at the retry period). Its open never runs in the
 * caller's thread instead: a hung V4L2, serial or CAN open would hold the
 * start-up or the control loop for ever (docs/robot.md "Known trips"). */
static int opener_start(robot_devices_t *d, robot_dev_t id, char *reason, size_t reason_cap)
{
    robot_dev_opener_t *o = &d->opener[id];
    if (o->worker.started) {
        return 0;
    }
    o->d = d;
    o->id = id;
    const int e = robot_worker_start(&o->worker, opener_run, o);
    if (e != 0) {
        d->dev[id].opener_start_failures++;
        put_text(reason, reason_cap,
                 "its opener thread could not be started (%s): not opened in the control loop's thread, which a "
                 "hung open would hold (HAL_E_BUSY)",
                 strerror(e));
    }
    return e;
}

/* Stop every opener (close_all): all are told to quit first, then each is
 * waited for until one shared deadline, so that several hung devices do not
 * add up their waits. An attempt that returns in time is finished as the
 * loop would (and closed with the rest); one that does not is said and
 * left: the thread owns its device until the process exits. */
static void openers_stop(robot_devices_t *d)
{
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        robot_worker_quit(&d->opener[i].worker);
    }
    const struct timespec end = robot_worker_deadline(ROBOT_DEVICES_CLOSE_WAIT_MS);
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        const robot_dev_t id = (robot_dev_t)i;
        robot_dev_opener_t *o = &d->opener[i];
        if (!o->worker.started) {
            continue;
        }
        const int joined = robot_worker_join(&o->worker, &end);
        if (joined < 0) {
            char text[320];
            put_text(text, sizeof text,
                     "an open attempt has not returned %u ms after the stop; left to the process's exit (the device "
                     "is not released)",
                     ROBOT_DEVICES_CLOSE_WAIT_MS);
            say(d, d->dev[id].name, &d->dev[id], text);
            continue;
        }
        if (d->dev[id].opening) {
            d->dev[id].opening = 0;
            if (joined > 0) { /* the attempt ended, its outcome not taken */
                (void)open_finish(d, id, o->result, o->reason, 0U); /* up: closed with the rest */
            }
        }
    }
}

unsigned robot_devices_opening(const robot_devices_t *d)
{
    unsigned n = 0U;
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        /* only the worker's mutex is written here: the opener is the
         * caller's, const for the status reader */
        robot_worker_t *w = (robot_worker_t *)&d->opener[i].worker;
        n += d->dev[i].opening && robot_worker_running(w) ? 1U : 0U;
    }
    return n;
}

unsigned robot_devices_wait_opens(robot_devices_t *d, uint32_t wait_ms)
{
    unsigned running = 0U;
    const struct timespec end = robot_worker_deadline(wait_ms);
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        if (d->dev[i].opening) {
            running += robot_worker_wait(&d->opener[i].worker, &end) ? 1U : 0U;
        }
    }
    return running;
}

static void close_dev(robot_devices_t *d, robot_dev_t id)
{
    switch (id) {
    case ROBOT_DEV_LASER: hal_serial_close(&d->laser_dev); break;
    case ROBOT_DEV_CAN:
        /* the session's count into the total: the next open (on the
         * opener, the slot down) starts it again */
        d->can_stamps_unbelieved_past += d->can_state.stamps_unbelieved;
        d->can_state.stamps_unbelieved = 0U;
        hal_can_close(&d->can_state.can);
        break;
    case ROBOT_DEV_GPIO: hal_gpio_close(gpio_backend(d)); break;
    case ROBOT_DEV_CAMERA:
        /* the stream's counters into the totals: its reopen starts them
         * again (robot_devices_live_counters) */
        d->live_bad_past += d->replay.live_bad;
        d->live_robots_refused_past += d->replay.live_robots_refused;
        d->replay.live_bad = 0U;
        d->replay.live_robots_refused = 0U;
        robot_replay_close(&d->replay);
#if COSLAM_HAVE_CAMERA
        robot_camera_close(&d->camera);
#endif
        break;
    case ROBOT_DEV_STORAGE: hal_storage_close(&d->storage_state.dev); break;
    case ROBOT_DEV_LINK: robot_link_backend_close(&d->link); break;
    default: break;
    }
}

coslam_status_t robot_devices_init(robot_devices_t *d, const robot_config_t *cfg, hal_clock_t *clock, FILE *log,
                                   int verbose, char *msg, size_t msg_cap)
{
    memset(d, 0, sizeof *d);
    d->cfg = cfg;
    d->clock = clock;
    d->log = log;
    d->verbose = verbose;
    d->retry_us = (uint32_t)(cfg->retry_period_s * 1e6);
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        d->dev[i].name = dev_names[i];
        d->dev[i].state = ROBOT_DEV_ABSENT;
    }
    d->laser.ops = &laser_proxy_ops;
    d->laser.backend = d;
    d->can.ops = &can_proxy_ops;
    d->can.backend = d;
    d->gpio.ops = &gpio_proxy_ops;
    d->gpio.backend = d;
    d->sightings.ops = &sightings_proxy_ops;
    d->sightings.backend = d;
#if COSLAM_HAVE_CAMERA
    robot_camera_init(&d->camera, cfg, clock);
#endif
    d->link_slot.ops = &link_proxy_ops;
    d->link_slot.backend = d;
    robot_dev_status_t *st = d->dev;
    put_text(st[ROBOT_DEV_LASER].what, sizeof st[0].what, "URG on %s at %lu baud", cfg->laser_device,
                   (unsigned long)cfg->laser_baud);
    if (cfg->can_fd >= 0) {
        put_text(st[ROBOT_DEV_CAN].what, sizeof st[0].what, "CiA 402 drives on inherited CAN fd %d (e2e test)",
                 cfg->can_fd);
    } else {
        put_text(st[ROBOT_DEV_CAN].what, sizeof st[0].what, "CiA 402 drives on SocketCAN %s", cfg->can_interface);
    }
    if (cfg->gpio_fd >= 0) {
        put_text(st[ROBOT_DEV_GPIO].what, sizeof st[0].what, "bumper / e-stop / LED on inherited fd %d (e2e test)",
                 cfg->gpio_fd);
    } else {
        put_text(st[ROBOT_DEV_GPIO].what, sizeof st[0].what, "bumper / e-stop / LED on %s", cfg->gpio_chip);
    }
    put_text(st[ROBOT_DEV_STORAGE].what, sizeof st[0].what, "snapshots in %s", cfg->storage_dir);
    /* the link policy and the fleet key: before anything opens */
    const coslam_status_t ls = robot_open_link(&d->link, cfg, &d->link_slot, msg, msg_cap);
    put_text(st[ROBOT_DEV_LINK].what, sizeof st[0].what, "%s", d->link.what);
    return ls;
}

/* Hand the blocking part of device id's open to its opener thread (started
 * by opener_start; the preparation done): 1 if the opener took it, 0 if it
 * would not (the reason in `reason`: the attempt has failed, the caller
 * never opens in its own thread). */
static int opener_submit(robot_devices_t *d, robot_dev_t id, uint64_t now_us, char *reason, size_t reason_cap)
{
    robot_dev_opener_t *o = &d->opener[id];
    robot_dev_status_t *st = &d->dev[id];
    o->reason[0] = '\0';
    const int e = robot_worker_submit(&o->worker);
    if (e != 0) {
        /* not reached: a slot hands over only with its opener started and
         * idle (`opening` clear); said, never run here, if it ever is */
        put_text(reason, reason_cap, "its opener thread would not take the open (%s) (HAL_E_BUSY)", strerror(e));
        return 0;
    }
    st->opening = 1;
    st->hung_said = 0;
    st->open_began_us = now_us;
    return 1;
}

/* The report of a slot's first open that ended down (`reason`): the
 * device's consequence and the retry. */
static void say_first_down(robot_devices_t *d, robot_dev_t id, const char *reason)
{
    char text[ROBOT_DEVICES_REASON_MAX + 96u];
    const char *then = "";
    if (id == ROBOT_DEV_CAMERA && d->camera_kind == ROBOT_SIGHTINGS_CAMERA) {
        then = "; localisation on odometry only";
    }
    put_text(text, sizeof text, "down: %s%s; retrying every %g s", reason, then, d->cfg->retry_period_s);
    say(d, d->dev[id].name, &d->dev[id], text);
}

void robot_devices_open_all(robot_devices_t *d, uint64_t now_us)
{
    const robot_config_t *c = d->cfg;
    robot_dev_status_t *st = d->dev;
    const char *names[ROBOT_DEV_COUNT] = {c->laser_device, c->can_fd >= 0 ? "fd" : c->can_interface,
                                          c->gpio_fd >= 0 ? "fd" : c->gpio_chip, "", "", c->storage_dir};
    char text[320];
    int want[ROBOT_DEV_COUNT] = {0};
    /* 1: what each slot is; a configured one is down until its first
     * attempt has ended up */
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        const robot_dev_t id = (robot_dev_t)i;
        if (id == ROBOT_DEV_CAMERA) {
            d->camera_kind = robot_sightings_kind(c);
            if (d->camera_kind == ROBOT_SIGHTINGS_NONE) {
                put_text(st[id].what, sizeof st[id].what, "none");
                say(d, "camera", &st[id], "not configured: localisation on odometry only");
                continue;
            }
            if (d->camera_kind == ROBOT_SIGHTINGS_NO_CAMERA) {
                put_text(st[id].what, sizeof st[id].what, "%s", c->camera_device);
                say(d, "camera", &st[id],
                    "not available (built without the V4L2 backend or firmware/vision): localisation on odometry "
                    "only");
                continue;
            }
            if (d->camera_kind == ROBOT_SIGHTINGS_CAMERA) {
                put_text(st[id].what, sizeof st[id].what, "V4L2 %s, %ux%u, markers", c->camera_device,
                         (unsigned)c->camera_width_px, (unsigned)c->camera_height_px);
            } else if (d->camera_kind == ROBOT_SIGHTINGS_LIVE) {
                put_text(st[id].what, sizeof st[id].what,
                         "live sightings on fd %d (e2e device server, a camera stand-in)", c->camera_live_fd);
            } else {
                put_text(st[id].what, sizeof st[id].what, "landmark-log replay %s (test/bench source, not a camera)",
                         c->camera_replay_log);
            }
        } else if (id == ROBOT_DEV_LINK) {
            if (d->link.mode == ROBOT_LINK_OFF) {
                st[id].state = ROBOT_DEV_ABSENT;
                put_text(text, sizeof text, "absent; WARNING %s: this robot maps alone and merges no maps",
                         robot_link_warning(&d->link));
                say(d, "link", &st[id], text);
                continue;
            }
        } else {
#if !COSLAM_HAVE_GPIOD
            if (id == ROBOT_DEV_GPIO && c->gpio_fd < 0) {
                say(d, "gpio", &st[id], "not available (built without libgpiod): no bumper, no e-stop");
                continue;
            }
#endif
            if (names[i][0] == '\0') {
                st[i].what[0] = '\0';
                say(d, dev_names[i], &st[i], "not configured");
                continue;
            }
        }
        want[i] = 1;
        st[i].state = ROBOT_DEV_DOWN;
    }
    /* 2: the first attempts, handed to the openers together. An open that
     * blocks (a FIFO without a writer as the landmark log, a hung driver)
     * used to hold the start-up in this thread until a signal; now the
     * start waits for them until one deadline (docs/robot.md "Known
     * trips"). A slot whose opener thread cannot be started is down
     * (said with why, retried); it is never opened here. */
    int handed[ROBOT_DEV_COUNT] = {0};
    int no_thread[ROBOT_DEV_COUNT] = {0};
    hal_status_t result[ROBOT_DEV_COUNT];
    char reason[ROBOT_DEV_COUNT][ROBOT_DEVICES_REASON_MAX];
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        result[i] = HAL_E_UNSUPPORTED;
        reason[i][0] = '\0';
        if (want[i]) {
            no_thread[i] = opener_start(d, (robot_dev_t)i, reason[i], sizeof reason[i]) != 0;
        }
    }
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        if (!want[i]) {
            continue;
        }
        const robot_dev_t id = (robot_dev_t)i;
        if (no_thread[i]) {
            result[i] = HAL_E_BUSY;
            continue;
        }
        hal_status_t s = open_prepare(d, id, reason[i], sizeof reason[i]);
        if (s == HAL_OK && opener_submit(d, id, now_us, reason[i], sizeof reason[i])) {
            handed[i] = 1;
            continue;
        }
        result[i] = s == HAL_OK ? HAL_E_BUSY : s;
    }
    const struct timespec end = robot_worker_deadline(ROBOT_DEVICES_START_OPEN_MS);
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        if (handed[i]) {
            (void)robot_worker_wait(&d->opener[i].worker, &end);
        }
    }
    /* 3: the outcomes, reported in slot order */
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        if (!want[i]) {
            continue;
        }
        const robot_dev_t id = (robot_dev_t)i;
        robot_dev_opener_t *o = &d->opener[i];
        if (handed[i] && robot_worker_take(&o->worker, 0U, NULL) != 1) {
            /* still blocked: the robot starts without it; the attempt goes
             * on, and the loop's service takes its outcome (or says it
             * hung) as for a retry. Not a failed attempt yet. */
            put_text(st[i].reason, sizeof st[i].reason,
                     "its open has not returned within %u ms of the start (a FIFO without a writer? a hung device?)",
                     ROBOT_DEVICES_START_OPEN_MS);
            st[i].last_error = HAL_E_TIMEOUT;
            st[i].start_open_late = 1;
            put_text(text, sizeof text,
                     "down: %s: the robot starts without it; the attempt goes on on the device's opener thread "
                     "(dev_opening)",
                     st[i].reason);
            say(d, dev_names[i], &st[i], text);
        } else {
            if (handed[i]) { /* returned in time: its outcome, as if opened here */
                st[i].opening = 0;
                result[i] = o->result;
                put_text(reason[i], sizeof reason[i], "%s", o->reason);
            }
            if (open_finish(d, id, result[i], reason[i], now_us)) {
                say(d, dev_names[i], &st[i], "up");
            } else {
                say_first_down(d, id, st[i].reason);
            }
        }
        if (id == ROBOT_DEV_LINK && robot_link_warning(&d->link) != NULL) {
            put_text(text, sizeof text, "WARNING %s: maps from anyone on the topic are merged",
                     robot_link_warning(&d->link));
            say(d, "link", &st[id], text);
        }
    }
}

void robot_devices_fail(robot_devices_t *d, robot_dev_t id, hal_status_t why, const char *reason, uint64_t now_us)
{
    robot_dev_status_t *st = &d->dev[id];
    if (st->state != ROBOT_DEV_UP) {
        return;
    }
    close_dev(d, id);
    set_down(d, id, why, reason, now_us);
    char text[320];
    put_text(text, sizeof text, "down: %s; retrying every %g s", reason, d->cfg->retry_period_s);
    say(d, st->name, st, text);
}

void robot_devices_storage_save_failed(robot_devices_t *d, size_t bytes, hal_status_t ws, const char *reason,
                                       uint64_t now_us)
{
    if (d->dev[ROBOT_DEV_STORAGE].state != ROBOT_DEV_UP) {
        return;
    }
    /* written while the storage's opener is idle (the slot is up): its
     * next attempt reads it after the submit */
    d->storage_save_probe_bytes = bytes > 0U ? bytes : 1U;
    robot_devices_fail(d, ROBOT_DEV_STORAGE, ws, reason, now_us);
}

/* An open attempt of the loop's retries took took_ms on the slot's opener
 * thread (the loop went on): kept, and said when slow. */
static void note_open_time(robot_devices_t *d, robot_dev_t id, uint64_t took_ms)
{
    robot_dev_status_t *st = &d->dev[id];
    if (took_ms > st->open_max_ms) {
        st->open_max_ms = took_ms > UINT32_MAX ? UINT32_MAX : (uint32_t)took_ms;
    }
    if (took_ms < ROBOT_DEVICES_SLOW_OPEN_MS) {
        return;
    }
    st->slow_opens++;
    char text[320];
    put_text(text, sizeof text,
             "this open attempt took %llu ms (on the device's opener thread: the control loop went on)",
             (unsigned long long)took_ms);
    say(d, st->name, st, text);
}

/* A retry's parts before ended with s (and why): finished and reported
 * (a return always, a failure with -v). Returns the changed-mask bit. */
static unsigned open_outcome(robot_devices_t *d, robot_dev_t id, hal_status_t s, const char *why, uint64_t now_us)
{
    robot_dev_status_t *st = &d->dev[id];
    const uint32_t failures = st->open_failures;
    char text[ROBOT_DEVICES_REASON_MAX + 16u];
    char said[ROBOT_DEVICES_REASON_MAX];
    put_text(said, sizeof said, "%s", st->reason);
    if (open_finish(d, id, s, why, now_us)) {
        if (st->start_open_late) {
            put_text(text, sizeof text, "up (its open begun at the start has returned)");
        } else {
            put_text(text, sizeof text, "back up after %lu failed attempt%s", (unsigned long)failures,
                     failures == 1U ? "" : "s");
        }
        st->start_open_late = 0;
        say(d, st->name, st, text);
        return 1U << id;
    }
    st->start_open_late = 0;
    /* a retry that fails for a reason other than the one said last is
     * said once (a storage down at a failed write: then why it cannot be
     * written); the same reason again only with -v */
    if (d->verbose || strcmp(st->reason, said) != 0) {
        put_text(text, sizeof text, "still down (%s)", st->reason);
        say(d, st->name, st, text);
    }
    return 0U;
}

unsigned robot_devices_service(robot_devices_t *d, uint64_t now_us)
{
    unsigned changed = 0U;
    char text[320];
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        const robot_dev_t id = (robot_dev_t)i;
        robot_dev_status_t *st = &d->dev[i];
        if (st->state == ROBOT_DEV_UP && st->lost) {
            close_dev(d, id);
            st->losses++;
            st->state = ROBOT_DEV_DOWN;
            st->next_try_us = now_us + d->retry_us;
            put_text(st->reason, sizeof st->reason, "lost: %s (%s)", hal_reason(st->last_error),
                           hal_status_str(st->last_error));
            put_text(text, sizeof text, "%s; retrying every %g s", st->reason, d->cfg->retry_period_s);
            say(d, st->name, st, text);
            changed |= 1U << i;
            continue;
        }
        robot_dev_opener_t *o = &d->opener[i];
        if (st->opening) {
            uint64_t took_us = 0U;
            if (robot_worker_take(&o->worker, 0U, &took_us) == 1) {
                st->opening = 0;
                note_open_time(d, id, took_us / 1000U);
                changed |= open_outcome(d, id, o->result, o->reason, now_us);
            } else if (!st->hung_said && now_us - st->open_began_us >= ROBOT_DEVICES_HUNG_OPEN_MS * 1000ULL) {
                /* limits are loud: the device stays down until it returns */
                st->hung_said = 1;
                st->hung_opens++;
                put_text(text, sizeof text,
                         "an open attempt has run for %u s and not returned (a hung device?); the device stays down "
                         "until it does; the control loop goes on",
                         ROBOT_DEVICES_HUNG_OPEN_MS / 1000U);
                say(d, st->name, st, text);
            }
            continue;
        }
        if (st->state != ROBOT_DEV_DOWN || now_us < st->next_try_us) {
            continue;
        }
        char why[ROBOT_DEVICES_REASON_MAX];
        why[0] = '\0';
        /* a slot whose opener thread could not be started tries again now;
         * still none: a failed attempt, retried at the next period. The
         * open never runs here: the loop must not wait for a device. */
        hal_status_t s = opener_start(d, id, why, sizeof why) == 0 ? HAL_OK : HAL_E_BUSY;
        if (s == HAL_OK) {
            s = open_prepare(d, id, why, sizeof why);
            if (s == HAL_OK && opener_submit(d, id, now_us, why, sizeof why)) {
                continue;
            }
            s = s == HAL_OK ? HAL_E_BUSY : s;
        }
        changed |= open_outcome(d, id, s, why, now_us);
    }
    return changed;
}

int robot_devices_reopen_now(robot_devices_t *d, robot_dev_t id, uint64_t now_us, uint32_t wait_ms)
{
    robot_dev_status_t *st = &d->dev[id];
    if (st->state != ROBOT_DEV_DOWN) {
        return st->state == ROBOT_DEV_UP && !st->lost;
    }
    if (!st->opening) {
        st->next_try_us = now_us; /* due now: handed over by the service */
    }
    (void)robot_devices_service(d, now_us);
    if (st->opening) {
        (void)robot_devices_wait_opens(d, wait_ms);
        (void)robot_devices_service(d, now_us);
    }
    return st->state == ROBOT_DEV_UP;
}

void robot_devices_close_all(robot_devices_t *d)
{
    openers_stop(d);
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        if (d->dev[i].state == ROBOT_DEV_UP) {
            close_dev(d, (robot_dev_t)i);
            d->dev[i].state = ROBOT_DEV_DOWN;
        }
    }
    robot_close_link(&d->link); /* the decorator too: wipes the key */
#if COSLAM_HAVE_CAMERA
    if (!d->opener[ROBOT_DEV_CAMERA].worker.stuck) {
        robot_camera_free(&d->camera); /* else the opener may still use the detector */
    }
#endif
}

robot_node_io_t robot_devices_io(robot_devices_t *d)
{
    robot_node_io_t io;
    io.clock = d->clock;
    io.laser = &d->laser;
    io.can = &d->can;
    io.gpio = &d->gpio;
    io.link = robot_link_handle(&d->link);
    io.sightings = &d->sightings;
    return io;
}

void robot_devices_live_counters(const robot_devices_t *d, uint32_t *live_bad, uint32_t *live_robots_refused)
{
    /* the open stream's only while up, lost or not: while down its opener
     * may be writing them (robot_live_open starts them at 0), and a lost
     * stream's are added to the totals at its close, not before (with
     * usable() a report between the loss and the close dipped) */
    const int up = d->dev[ROBOT_DEV_CAMERA].state == ROBOT_DEV_UP;
    if (live_bad != NULL) {
        *live_bad = d->live_bad_past + (up ? d->replay.live_bad : 0U);
    }
    if (live_robots_refused != NULL) {
        *live_robots_refused = d->live_robots_refused_past + (up ? d->replay.live_robots_refused : 0U);
    }
}

uint64_t robot_devices_can_stamps_unbelieved(const robot_devices_t *d)
{
    /* up, lost or not: the opener runs only while the slot is down, and a
     * lost slot's session is added at its close (robot_devices_service) */
    const int up = d->dev[ROBOT_DEV_CAN].state == ROBOT_DEV_UP;
    return d->can_stamps_unbelieved_past + (up ? d->can_state.stamps_unbelieved : 0U);
}

hal_storage_t *robot_devices_storage(robot_devices_t *d)
{
    return usable(d, ROBOT_DEV_STORAGE) ? &d->storage_state.dev : NULL;
}
