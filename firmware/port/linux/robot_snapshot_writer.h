/*
 * robot_snapshot_writer.h - the storage write of a map snapshot on a thread
 * of its own, so that a slow medium never holds coslam-robot's control loop.
 *
 * The Linux storage backend replaces a blob atomically: temporary file,
 * fsync, rename, fsync of the directory (hal/linux/posix). On an SD card or
 * eMMC an fsync takes tens of milliseconds and, while the card collects
 * garbage, seconds; written from the control loop, the drives would keep
 * their last command for that long (docs/robot.md "Map snapshots"). The
 * loop prepares the snapshot (export in parts, encode: robot_snapshots_
 * prepare) and hands the bytes to this writer; it takes the outcome on a
 * later step and commits it (robot_snapshots_commit).
 *
 * One write at a time: a submit while the last write's outcome has not been
 * taken is refused (EBUSY), and the caller counts the snapshot it could not
 * take. The bytes are copied in, so the caller's buffer is free when submit
 * returns. The storage handle must stay open until the outcome is taken
 * (robot_main.c closes the storage device only through a failed write's
 * outcome, or at the end).
 *
 * No heap of its own: the copy lives in the struct (static in robot_main.c);
 * the thread's stack is the C library's. Thread-safety: every function is
 * called from one thread (the control loop); the writer thread touches only
 * the job it was given. It also does the reads of the newest generation
 * when the storage comes back (robot_snapshot_writer_submit_read).
 */
#ifndef COSLAM_PORT_ROBOT_SNAPSHOT_WRITER_H
#define COSLAM_PORT_ROBOT_SNAPSHOT_WRITER_H

#include <stddef.h>
#include <stdint.h>

#include "hal/hal_storage.h"
#include "robot_snapshot.h"
#include "robot_worker.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    robot_worker_t worker;   /**< the thread (robot_worker.h) */
    hal_storage_t *storage;  /**< the job's */
    char name[HAL_STORAGE_NAME_MAX + 1u];
    size_t len;
    hal_status_t result;     /**< the job's storage write status (once ended) */
    /* a read job instead (robot_snapshot_writer_submit_read) */
    int is_read;
    robot_snapshots_t *snaps;
    robot_snapshot_t *read_out;
    robot_snapshot_found_t read_found; /**< its outcome (once ended) */
    coslam_status_t read_result;       /**< robot_snapshots_read_newest's return (once ended) */
    uint8_t buf[ROBOT_SNAPSHOT_MAX_BYTES];
} robot_snapshot_writer_t;

/** Start the thread. Returns 0 (also when it runs already), or an errno
 *  value (no thread: nothing can be handed over; the caller does not write
 *  in its own thread, which a slow or hung medium would hold, but counts
 *  the snapshots not written and calls this again later: docs/robot.md
 *  "Map snapshots"). May be called again after a failure. */
int robot_snapshot_writer_start(robot_snapshot_writer_t *w);

/** 1 while the thread runs (started, not stopped). */
int robot_snapshot_writer_started(const robot_snapshot_writer_t *w);

/**
 * Hand a write over: `len` bytes of `data` (copied) to blob `name` of
 * `storage`. Returns 0 (the write goes on in the thread); EBUSY (a write
 * whose outcome has not been taken); E2BIG (len > ROBOT_SNAPSHOT_MAX_BYTES);
 * EINVAL (NULL, a name that is too long); ESRCH (the thread is not running).
 */
int robot_snapshot_writer_submit(robot_snapshot_writer_t *w, hal_storage_t *storage, const char *name,
                                 const uint8_t *data, size_t len);

/**
 * Hand a read over instead: robot_snapshots_read_newest(snaps, out, ...,
 * stderr) on the thread (when the storage comes back: the reads of a medium
 * that has just returned may be as slow as its writes). Until the outcome
 * is taken the caller must not touch snaps->buf, snaps->storage or *out.
 * The outcome comes through robot_snapshot_writer_take (*result HAL_OK,
 * *write_us how long the reads took), then in w->read_result and
 * w->read_found. Returns as robot_snapshot_writer_submit (EINVAL: NULL).
 */
int robot_snapshot_writer_submit_read(robot_snapshot_writer_t *w, robot_snapshots_t *snaps, robot_snapshot_t *out);

/**
 * The outcome of the write handed over, waiting for it at most wait_ms
 * (0: only look). Returns 1 (taken: *result, *write_us set, the writer is
 * idle again); 0 (still writing); -1 (nothing handed over).
 */
int robot_snapshot_writer_take(robot_snapshot_writer_t *w, uint32_t wait_ms, hal_status_t *result,
                               uint64_t *write_us);

/** 1 while a write has been handed over and its outcome not taken. */
int robot_snapshot_writer_busy(robot_snapshot_writer_t *w);

/**
 * Stop the thread; a write still running is waited for at most wait_ms.
 * Returns 0 (joined; an outcome not taken is dropped: take it first); -1
 * (the write still runs after wait_ms, a storage that does not return: the
 * thread is detached and left to it; `w` and the storage handle must stay
 * valid until the process ends). Idempotent.
 */
int robot_snapshot_writer_stop(robot_snapshot_writer_t *w, uint32_t wait_ms);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_SNAPSHOT_WRITER_H */
