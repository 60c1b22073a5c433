/* A thread that runs one job at a time for the control loop (robot_worker.h). */
#include "robot_worker.h"

#include <errno.h>
#include <signal.h>

enum { W_IDLE = 0, W_BUSY = 1, W_DONE = 2 };

static uint64_t mono_us(void)
{
    struct timespec ts;
    (void)clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000U + (uint64_t)ts.tv_nsec / 1000U;
}

struct timespec robot_worker_deadline(uint32_t wait_ms)
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

/* Under mu: wait until the job handed over has ended or `end` has come. */
static void wait_ended(robot_worker_t *w, const struct timespec *end)
{
    while (w->state == W_BUSY) {
        if (pthread_cond_timedwait(&w->done_cv, &w->mu, end) == ETIMEDOUT) {
            break;
        }
    }
}

static void *worker_main(void *arg)
{
    robot_worker_t *w = arg;
    (void)pthread_mutex_lock(&w->mu);
    for (;;) {
        while (!w->quit && w->state != W_BUSY) {
            (void)pthread_cond_wait(&w->job_cv, &w->mu);
        }
        if (w->state != W_BUSY) {
            break; /* quit, nothing handed over */
        }
        /* the job is this thread's until W_DONE */
        (void)pthread_mutex_unlock(&w->mu);
        const uint64_t t0 = mono_us();
        w->run(w->ctx);
        const uint64_t t1 = mono_us();
        (void)pthread_mutex_lock(&w->mu);
        w->run_us = t1 - t0;
        w->state = W_DONE;
        (void)pthread_cond_broadcast(&w->done_cv);
    }
    (void)pthread_mutex_unlock(&w->mu);
    return NULL;
}

/* Destroy the first `made` of: the mutex, job_cv, done_cv. */
static void destroy_sync(robot_worker_t *w, int made)
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

int robot_worker_start(robot_worker_t *w, void (*run)(void *ctx), void *ctx)
{
    if (w == NULL || run == NULL) {
        return EINVAL;
    }
    if (w->started) {
        return 0;
    }
    w->run = run;
    w->ctx = ctx;
    w->quit = 0;
    w->stuck = 0;
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
        /* signals go to the control loop, never to a worker (the mask is
         * inherited by the thread) */
        sigset_t all;
        sigset_t old;
        (void)sigfillset(&all);
        (void)pthread_sigmask(SIG_SETMASK, &all, &old);
        e = pthread_create(&w->thread, NULL, worker_main, w);
        (void)pthread_sigmask(SIG_SETMASK, &old, NULL);
    }
    if (e != 0) {
        destroy_sync(w, made);
    }
    w->started = e == 0;
    return e;
}

int robot_worker_submit(robot_worker_t *w)
{
    if (w == NULL || !w->started) {
        return ESRCH;
    }
    (void)pthread_mutex_lock(&w->mu);
    if (w->state != W_IDLE) {
        (void)pthread_mutex_unlock(&w->mu);
        return EBUSY;
    }
    w->state = W_BUSY;
    (void)pthread_cond_signal(&w->job_cv);
    (void)pthread_mutex_unlock(&w->mu);
    return 0;
}

int robot_worker_take(robot_worker_t *w, uint32_t wait_ms, uint64_t *run_us)
{
    if (w == NULL || !w->started) {
        return -1;
    }
    (void)pthread_mutex_lock(&w->mu);
    if (w->state == W_BUSY && wait_ms > 0U) {
        const struct timespec end = robot_worker_deadline(wait_ms);
        wait_ended(w, &end);
    }
    int r = -1;
    if (w->state == W_BUSY) {
        r = 0;
    } else if (w->state == W_DONE) {
        if (run_us != NULL) {
            *run_us = w->run_us;
        }
        w->state = W_IDLE;
        r = 1;
    }
    (void)pthread_mutex_unlock(&w->mu);
    return r;
}

int robot_worker_busy(robot_worker_t *w)
{
    if (w == NULL || !w->started) {
        return 0;
    }
    (void)pthread_mutex_lock(&w->mu);
    const int busy = w->state != W_IDLE;
    (void)pthread_mutex_unlock(&w->mu);
    return busy;
}

int robot_worker_running(robot_worker_t *w)
{
    if (w == NULL || !w->started) {
        return 0;
    }
    (void)pthread_mutex_lock(&w->mu);
    const int running = w->state == W_BUSY;
    (void)pthread_mutex_unlock(&w->mu);
    return running;
}

int robot_worker_wait(robot_worker_t *w, const struct timespec *end)
{
    if (w == NULL || !w->started) {
        return 0;
    }
    (void)pthread_mutex_lock(&w->mu);
    wait_ended(w, end);
    const int running = w->state == W_BUSY;
    (void)pthread_mutex_unlock(&w->mu);
    return running;
}

void robot_worker_quit(robot_worker_t *w)
{
    if (w == NULL || !w->started) {
        return;
    }
    (void)pthread_mutex_lock(&w->mu);
    w->quit = 1;
    (void)pthread_cond_signal(&w->job_cv);
    (void)pthread_mutex_unlock(&w->mu);
}

int robot_worker_join(robot_worker_t *w, const struct timespec *end)
{
    if (w == NULL || !w->started) {
        return 0;
    }
    (void)pthread_mutex_lock(&w->mu);
    w->quit = 1;
    (void)pthread_cond_signal(&w->job_cv);
    wait_ended(w, end);
    const int stuck = w->state == W_BUSY;
    (void)pthread_mutex_unlock(&w->mu);
    w->started = 0;
    if (stuck) {
        w->stuck = 1;
        (void)pthread_detach(w->thread); /* its mutex stays: the thread still uses it */
        return -1;
    }
    (void)pthread_join(w->thread, NULL);
    destroy_sync(w, 3);
    return w->state == W_DONE ? 1 : 0;
}

int robot_worker_stop(robot_worker_t *w, uint32_t wait_ms)
{
    const struct timespec end = robot_worker_deadline(wait_ms);
    robot_worker_quit(w);
    return robot_worker_join(w, &end);
}
