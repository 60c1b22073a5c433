/* The snapshot's storage write on a thread of its own (robot_snapshot_writer.h). */
#include "robot_snapshot_writer.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

enum { W_IDLE = 0, W_BUSY = 1, W_DONE = 2 };

static uint64_t mono_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000U + (uint64_t)ts.tv_nsec / 1000U;
}

/* wait_ms from now on CLOCK_MONOTONIC (the condition variables' clock). */
static struct timespec deadline_in(uint32_t wait_ms)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    ts.tv_sec += (time_t)(wait_ms / 1000U);
    ts.tv_nsec += (long)(wait_ms % 1000U) * 1000000L;
    if (ts.tv_nsec >= 1000000000L) {
        ts.tv_sec++;
        ts.tv_nsec -= 1000000000L;
    }
    return ts;
}

/* Under mu: wait until the write handed over has ended or wait_ms passed. */
static void wait_written(robot_snapshot_writer_t *w, uint32_t wait_ms)
{
    if (w->state != W_BUSY || wait_ms == 0U) {
        return;
    }
    const struct timespec end = deadline_in(wait_ms);
    while (w->state == W_BUSY) {
        if (pthread_cond_timedwait(&w->done_cv, &w->mu, &end) == ETIMEDOUT) {
            break;
        }
    }
}

static void *writer_main(void *arg)
{
    robot_snapshot_writer_t *w = arg;
    (void)pthread_mutex_lock(&w->mu);
    for (;;) {
        while (!w->quit && w->state != W_BUSY) {
            (void)pthread_cond_wait(&w->job_cv, &w->mu);
        }
        if (w->state != W_BUSY) {
            break; /* quit, nothing handed over */
        }
        /* the job's fields are the control loop's again only after W_DONE */
        (void)pthread_mutex_unlock(&w->mu);
        const uint64_t t0 = mono_us();
        hal_status_t r = HAL_OK;
        if (w->is_read) {
            w->read_result = robot_snapshots_read_newest(w->snaps, w->read_out, &w->read_found, stderr);
        } else {
            r = hal_storage_write(w->storage, w->name, w->buf, w->len);
        }
        const uint64_t t1 = mono_us();
        (void)pthread_mutex_lock(&w->mu);
        w->result = r;
        w->write_us = t1 - t0;
        w->state = W_DONE;
        (void)pthread_cond_broadcast(&w->done_cv);
    }
    (void)pthread_mutex_unlock(&w->mu);
    return NULL;
}

/* Destroy the first `made` of: the mutex, job_cv, done_cv. */
static void destroy_sync(robot_snapshot_writer_t *w, int made)
{
    if (made >= 3) {
        (void)pthread_cond_destroy(&w->done_cv);
    }
    if (made >= 2) {
        (void)pthread_cond_destroy(&w->job_cv);
    }
    if (made >= 1) {
        (void)pthread_mutex_destroy(&w->mu);
    }
}

int robot_snapshot_writer_start(robot_snapshot_writer_t *w)
{
    if (w == NULL) {
        return EINVAL;
    }
    if (w->started) {
        return 0;
    }
    w->quit = 0;
    w->state = W_IDLE;
    pthread_condattr_t ca;
    int e = pthread_condattr_init(&ca);
    if (e != 0) {
        return e;
    }
    int made = 0; /* the mutex, job_cv, done_cv made so far */
    e = pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    if (e == 0 && (e = pthread_mutex_init(&w->mu, NULL)) == 0) {
        made = 1;
    }
    if (e == 0 && (e = pthread_cond_init(&w->job_cv, &ca)) == 0) {
        made = 2;
    }
    if (e == 0 && (e = pthread_cond_init(&w->done_cv, &ca)) == 0) {
        made = 3;
    }
    (void)pthread_condattr_destroy(&ca);
    if (e == 0) {
        /* signals go to the control loop, never to the writer (the mask is
         * inherited by the thread) */
        sigset_t all;
        sigset_t old;
        (void)sigfillset(&all);
        (void)pthread_sigmask(SIG_SETMASK, &all, &old);
        e = pthread_create(&w->thread, NULL, writer_main, w);
        (void)pthread_sigmask(SIG_SETMASK, &old, NULL);
    }
    if (e != 0) {
        destroy_sync(w, made);
    }
    w->started = e == 0;
    return e;
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
    if (!w->started) {
        return ESRCH;
    }
    (void)pthread_mutex_lock(&w->mu);
    if (w->state != W_IDLE) {
        (void)pthread_mutex_unlock(&w->mu);
        return EBUSY;
    }
    w->is_read = 0;
    w->storage = storage;
    memcpy(w->name, name, strlen(name) + 1U);
    if (len > 0U) {
        memcpy(w->buf, data, len);
    }
    w->len = len;
    w->state = W_BUSY;
    (void)pthread_cond_signal(&w->job_cv);
    (void)pthread_mutex_unlock(&w->mu);
    return 0;
}

int robot_snapshot_writer_submit_read(robot_snapshot_writer_t *w, robot_snapshots_t *snaps, robot_snapshot_t *out)
{
    if (w == NULL || snaps == NULL || out == NULL) {
        return EINVAL;
    }
    if (!w->started) {
        return ESRCH;
    }
    (void)pthread_mutex_lock(&w->mu);
    if (w->state != W_IDLE) {
        (void)pthread_mutex_unlock(&w->mu);
        return EBUSY;
    }
    w->is_read = 1;
    w->snaps = snaps;
    w->read_out = out;
    w->read_result = COSLAM_E_EMPTY;
    w->state = W_BUSY;
    (void)pthread_cond_signal(&w->job_cv);
    (void)pthread_mutex_unlock(&w->mu);
    return 0;
}

int robot_snapshot_writer_take(robot_snapshot_writer_t *w, uint32_t wait_ms, hal_status_t *result,
                               uint64_t *write_us)
{
    if (w == NULL || !w->started) {
        return -1;
    }
    (void)pthread_mutex_lock(&w->mu);
    wait_written(w, wait_ms);
    int r = -1;
    if (w->state == W_BUSY) {
        r = 0;
    } else if (w->state == W_DONE) {
        if (result != NULL) {
            *result = w->result;
        }
        if (write_us != NULL) {
            *write_us = w->write_us;
        }
        w->state = W_IDLE;
        r = 1;
    }
    (void)pthread_mutex_unlock(&w->mu);
    return r;
}

int robot_snapshot_writer_busy(robot_snapshot_writer_t *w)
{
    if (w == NULL || !w->started) {
        return 0;
    }
    (void)pthread_mutex_lock(&w->mu);
    const int busy = w->state != W_IDLE;
    (void)pthread_mutex_unlock(&w->mu);
    return busy;
}

int robot_snapshot_writer_stop(robot_snapshot_writer_t *w, uint32_t wait_ms)
{
    if (w == NULL || !w->started) {
        return 0;
    }
    (void)pthread_mutex_lock(&w->mu);
    w->quit = 1;
    (void)pthread_cond_signal(&w->job_cv);
    wait_written(w, wait_ms);
    const int stuck = w->state == W_BUSY;
    (void)pthread_mutex_unlock(&w->mu);
    w->started = 0;
    if (stuck) {
        (void)pthread_detach(w->thread);
        return -1;
    }
    (void)pthread_join(w->thread, NULL);
    destroy_sync(w, 3);
    w->state = W_IDLE;
    return 0;
}
