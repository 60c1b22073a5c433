/* The snapshot's storage write on a thread of its own (robot_snapshot_writer.h). */
#include "robot_snapshot_writer.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

/* The job, on the worker thread. */
static void run_job(void *ctx)
{
    robot_snapshot_writer_t *w = ctx;
    if (w->is_read) {
        w->read_result = robot_snapshots_read_newest(w->snaps, w->read_out, &w->read_found, stderr);
    } else {
        w->result = hal_storage_write(w->storage, w->name, w->buf, w->len);
    }
}

int robot_snapshot_writer_start(robot_snapshot_writer_t *w)
{
    return w == NULL ? EINVAL : robot_worker_start(&w->worker, run_job, w);
}

int robot_snapshot_writer_started(const robot_snapshot_writer_t *w)
{
    return w != NULL && w->worker.started;
}

int robot_snapshot_writer_submit(robot_snapshot_writer_t *w, hal_storage_t *storage, const char *name,
                                 const uint8_t *data, size_t len)
{
    if (w == NULL || storage == NULL || name == NULL || (data == NULL && len > 0U)) {
        return EINVAL;
    }
    if (strlen(name) > HAL_STORAGE_NAME_MAX) {
        return EINVAL;
    }
    if (len > sizeof w->buf) {
        return E2BIG;
    }
    if (!w->worker.started) {
        return ESRCH;
    }
    if (robot_worker_busy(&w->worker)) {
        return EBUSY; /* the job's fields are the thread's: not touched */
    }
    w->is_read = 0;
    w->storage = storage;
    memcpy(w->name, name, strlen(name) + 1U);
    if (len > 0U) {
        memcpy(w->buf, data, len);
    }
    w->len = len;
    return robot_worker_submit(&w->worker);
}

int robot_snapshot_writer_submit_read(robot_snapshot_writer_t *w, robot_snapshots_t *snaps, robot_snapshot_t *out)
{
    if (w == NULL || snaps == NULL || out == NULL) {
        return EINVAL;
    }
    if (!w->worker.started) {
        return ESRCH;
    }
    if (robot_worker_busy(&w->worker)) {
        return EBUSY;
    }
    w->is_read = 1;
    w->snaps = snaps;
    w->read_out = out;
    w->read_result = COSLAM_E_EMPTY;
    return robot_worker_submit(&w->worker);
}

int robot_snapshot_writer_take(robot_snapshot_writer_t *w, uint32_t wait_ms, hal_status_t *result,
                               uint64_t *write_us)
{
    if (w == NULL) {
        return -1;
    }
    uint64_t us = 0U;
    const int r = robot_worker_take(&w->worker, wait_ms, &us);
    if (r == 1) {
        if (result != NULL) {
            *result = w->is_read ? HAL_OK : w->result;
        }
        if (write_us != NULL) {
            *write_us = us;
        }
    }
    return r;
}

int robot_snapshot_writer_busy(robot_snapshot_writer_t *w)
{
    return w == NULL ? 0 : robot_worker_busy(&w->worker);
}

int robot_snapshot_writer_stop(robot_snapshot_writer_t *w, uint32_t wait_ms)
{
    if (w == NULL) {
        return 0;
    }
    const int r = robot_worker_stop(&w->worker, wait_ms);
    return r > 0 ? 0 : r; /* an outcome not taken is dropped */
}
