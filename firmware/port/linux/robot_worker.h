/*
 * robot_worker.h - a thread that runs one job at a time for coslam-robot's
 * control loop, so that a call that may block (a storage write, a device
 * open) never holds the loop: the snapshot writer (robot_snapshot_writer.h)
 * and the device openers (robot_devices.h) are built on it.
 *
 * The job is the owner's: it writes the job's inputs, then submits; from
 * then until the outcome is taken the thread owns them (and what the job
 * touches) and the loop must leave them alone; the thread calls
 * run(ctx), which writes the outputs; take hands them back. The hand-over
 * is under the worker's mutex, which orders every write on either side.
 *
 * The condition variables run on CLOCK_MONOTONIC; signals are blocked in
 * the thread (SIGTERM always reaches the loop). A job that never returns
 * is left to the thread at stop (detached): its owner must then keep what
 * the job uses until the process ends.
 *
 * One owner thread calls every function. No heap (the thread's stack is
 * the C library's).
 */
#ifndef COSLAM_PORT_ROBOT_WORKER_H
#define COSLAM_PORT_ROBOT_WORKER_H

#include <pthread.h>
#include <stdint.h>
#include <time.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t job_cv;   /**< a job handed over, or quit */
    pthread_cond_t done_cv;  /**< a job ended */
    int started;             /**< the thread runs */
    int stuck;               /**< left at stop with its job running (detached) */
    int quit;
    int state;               /**< 0 idle, 1 a job handed over, 2 ended and not taken */
    void (*run)(void *ctx);
    void *ctx;
    uint64_t run_us;         /**< how long the last run took (CLOCK_MONOTONIC) */
} robot_worker_t;

/** Start the thread that will call run(ctx) for each job. Returns 0, or an
 *  errno value (pthread_create's, or the mutex's or a condition variable's
 *  init's): no thread, nothing left made, and the owner decides (the device
 *  openers leave their device down and call this again at its retry; the
 *  snapshot writer's owner counts the snapshots it could not hand over and
 *  calls this again at the retry period). May be called again
 *  after a failure; 0 at once when the thread runs. */
int robot_worker_start(robot_worker_t *w, void (*run)(void *ctx), void *ctx);

/** Hand a job over (its inputs written). Returns 0; EBUSY (the last job's
 *  outcome has not been taken); ESRCH (not started). */
int robot_worker_submit(robot_worker_t *w);

/** The job's outcome, waiting at most wait_ms (0: only look). Returns 1
 *  (taken: the outputs are the owner's again, *run_us how long it ran; the
 *  worker is idle); 0 (still running); -1 (nothing handed over, or not
 *  started). run_us may be NULL. */
int robot_worker_take(robot_worker_t *w, uint32_t wait_ms, uint64_t *run_us);

/** 1 while a job has been handed over and its outcome not taken. */
int robot_worker_busy(robot_worker_t *w);

/** 1 while a job handed over still runs (not yet ended). */
int robot_worker_running(robot_worker_t *w);

/** Wait until `end` for a job handed over to end, without taking its
 *  outcome. Returns 1 if it still runs. */
int robot_worker_wait(robot_worker_t *w, const struct timespec *end);

/** wait_ms from now on CLOCK_MONOTONIC: a deadline for robot_worker_join. */
struct timespec robot_worker_deadline(uint32_t wait_ms);

/** Tell the thread to end after its job, if one runs (the first half of a
 *  stop; for stopping several workers against one deadline). */
void robot_worker_quit(robot_worker_t *w);

/** The second half: wait until `end` for a running job, then join the
 *  thread. Returns 1 (joined; a job ended whose outcome was not taken: its
 *  outputs are the owner's to read), 0 (joined, nothing untaken); -1 (the
 *  job still runs: the thread is detached and left to it, `stuck` set).
 *  Idempotent (0 when not started). */
int robot_worker_join(robot_worker_t *w, const struct timespec *end);

/** quit + join with a deadline wait_ms from now; returns as join. */
int robot_worker_stop(robot_worker_t *w, uint32_t wait_ms);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_WORKER_H */
