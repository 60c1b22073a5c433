/*
 * coslam-robot - the robot firmware on Linux: the robot node
 * (firmware/app) on the Linux backends (robot_devices.h), one INI file
 * (robot_config.h), map snapshots (robot_snapshot.h), a status report
 * (robot_status.h), the link to the other robots (robot_link.h: Cyclone
 * DDS behind the authentication decorator). docs/robot.md has the details and the decisions.
 *
 *   coslam-robot [-c FILE] [--dry-run] [--once N] [--status-file PATH]
 *                [--print-config] [-v] [--can-fd N] [--sightings-fd N] [--gpio-fd N]
 *
 * --can-fd, --sightings-fd and --gpio-fd are for end-to-end tests only
 * (docs/e2e.md): file descriptors inherited from the device server
 * coslam-sim-devices, a socketpair carrying struct can_frame in place of the
 * SocketCAN socket, the live sighting stream standing in for the camera, and
 * the bumper / e-stop / LED line states in place of a GPIO chip
 * (robot_gpio_fd.h).
 *
 * Exit status: 0 after a clean stop (SIGTERM, SIGINT, SIGHUP, SIGQUIT,
 * SIGUSR1, SIGUSR2, SIGALRM, --once, --dry-run; SIGPIPE and SIGXFSZ are
 * ignored), also one whose final snapshot was given up because the storage
 * did not return within FINAL_SNAPSHOT_WAIT_MS (said, counted in
 * snap_final_timeouts, the last line ends "(no final snapshot)"; the drives
 * were stopped and released all the same); 2 for a bad command line or
 * configuration (including a configured fleet key file that is missing,
 * unreadable, too open or invalid); 1 when the node cannot start, or when
 * the clock failed while it ran (after the same clean stop).
 *
 * Main loop: one robot_node_step per step_period on an absolute monotonic
 * schedule (hal_clock_linux: clock_nanosleep(TIMER_ABSTIME) on
 * CLOCK_MONOTONIC). A step that ends after the next deadline is an overrun:
 * counted, and the schedule skips the missed deadlines (never a burst of
 * catch-up steps). Between steps: device service (lost devices closed,
 * missing ones retried), GPIO roles attached when the chip is there,
 * snapshot and status when due (their map export goes in parts and yields
 * to the robot's own sends and merges; the snapshot's storage write runs on
 * the writer thread, robot_snapshot_writer.h), and, while at least half the
 * period is left, the filter's deferred work (robot_node_idle, again while
 * parts of a merge or an export remain).
 */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "app/profile.h"
#include "app/robot_node.h"
#include "hal/hal_clock_linux.h"
#include "robot_config.h"
#include "robot_devices.h"
#include "robot_link.h"
#include "robot_snapshot.h"
#include "robot_snapshot_writer.h"
#include "robot_status.h"

static volatile sig_atomic_t stop_signal = 0;

static void on_signal(int sig)
{
    stop_signal = sig;
}

typedef struct {
    const char *config_path;
    const char *status_file;
    int dry_run;
    int print_config;
    long once;
    int verbose;
    int can_fd;        /* e2e tests: inherited CAN socket (docs/e2e.md); -1 none */
    int sightings_fd;  /* e2e tests: inherited live sighting stream; -1 none */
    int gpio_fd;       /* e2e tests: inherited GPIO line states; -1 none */
} options_t;

static void usage(FILE *out)
{
    fprintf(out,
            "usage: coslam-robot [-c FILE] [--dry-run] [--once N] [--status-file PATH] [--print-config] [-v]\n"
            "  -c FILE             configuration (default " ROBOT_CONFIG_DEFAULT_PATH ")\n"
            "  --dry-run           load the configuration, open the devices, print what is up, exit\n"
            "  --once N            run N steps, then stop as on SIGTERM (tests)\n"
            "  --status-file PATH  also write the status report there as JSON (atomically)\n"
            "  --print-config      print the effective configuration as INI and exit\n"
            "  -v                  verbose: every snapshot and every failed device retry\n"
            "  --can-fd N          (e2e tests) CAN frames on inherited socket N instead of [can] interface\n"
            "  --sightings-fd N    (e2e tests) live sightings on inherited socket N, a camera stand-in\n"
            "  --gpio-fd N         (e2e tests) GPIO line states on inherited socket N instead of [gpio] chip\n");
}

static int parse_args(int argc, char **argv, options_t *o)
{
    memset(o, 0, sizeof *o);
    o->config_path = ROBOT_CONFIG_DEFAULT_PATH;
    o->once = -1;
    o->can_fd = -1;
    o->sightings_fd = -1;
    o->gpio_fd = -1;
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (strcmp(a, "-c") == 0 && i + 1 < argc) {
            o->config_path = argv[++i];
        } else if (strcmp(a, "--dry-run") == 0) {
            o->dry_run = 1;
        } else if (strcmp(a, "--print-config") == 0) {
            o->print_config = 1;
        } else if (strcmp(a, "--once") == 0 && i + 1 < argc) {
            char *end = NULL;
            errno = 0;
            o->once = strtol(argv[++i], &end, 10);
            if (errno != 0 || end == argv[i] || *end != '\0' || o->once < 0) {
                fprintf(stderr, "coslam-robot: --once needs a step count >= 0, got '%s'\n", argv[i]);
                return -1;
            }
        } else if ((strcmp(a, "--can-fd") == 0 || strcmp(a, "--sightings-fd") == 0 || strcmp(a, "--gpio-fd") == 0) &&
                   i + 1 < argc) {
            char *end = NULL;
            errno = 0;
            const long v = strtol(argv[++i], &end, 10);
            if (errno != 0 || end == argv[i] || *end != '\0' || v < 0 || v > 65535) {
                fprintf(stderr, "coslam-robot: %s needs a file descriptor, got '%s'\n", a, argv[i]);
                return -1;
            }
            if (a[2] == 'c') {
                o->can_fd = (int)v;
            } else if (a[2] == 'g') {
                o->gpio_fd = (int)v;
            } else {
                o->sightings_fd = (int)v;
            }
        } else if (strcmp(a, "--status-file") == 0 && i + 1 < argc) {
            o->status_file = argv[++i];
        } else if (strcmp(a, "-v") == 0) {
            o->verbose = 1;
        } else if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 1;
        } else {
            fprintf(stderr, "coslam-robot: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return -1;
        }
    }
    return 0;
}

static double cpu_seconds(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0) {
        return 0.0;
    }
    return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)ru.ru_stime.tv_usec;
}

/* The big state: static storage (robot_node_t is about 600 KB). */
static robot_config_t cfg;
static robot_devices_t dev;
static robot_node_t node;
static robot_snapshots_t snaps;
static robot_snapshot_t snap;

/* The snapshots' storage writes and reads run on the writer thread
 * (robot_snapshot_writer.h): an fsync on a slow card never holds the
 * control loop. One job at a time; its outcome is taken and committed on
 * a later step (finish_snapshot_write). Without the thread (it could not be
 * started) a snapshot is not written, but counted and said (the loop never
 * writes one itself: a hung medium would hold it for ever), and the thread
 * is started again every retry period (writer_running). The final one is
 * handed to it by the stop and waited for at most FINAL_SNAPSHOT_WAIT_MS
 * (final_snapshot_on_writer; when the thread did not run, it is started
 * once more, or the final snapshot is skipped: final_snapshot_no_writer).
 * No snapshot is read or written in the main thread. */
static robot_snapshot_writer_t writer;
/* The writer thread's starts that failed: the last one's errno (0: it
 * runs, or none failed yet), when the next is due, and how many failed
 * since it last ran. */
static struct {
    int err;
    uint64_t next_try_us;
    uint32_t failing;
} writer_retry;
typedef struct {
    int active;                /* a write (or the read below) handed over, outcome not taken */
    int is_read;               /* ... the read of the newest generation when the storage came back */
    int at_start;              /* ... the start-up read, on start_reader (not the writer): it did not
                                  return within START_READ_WAIT_MS */
    robot_snapshot_job_t job;
    uint16_t landmarks;
    uint64_t since_us;         /* handed over at (monotonic) */
    const char *why;
} snapshot_write_t;
static snapshot_write_t writing;
/* How long the stop waits for each snapshot job on the writer thread: a
 * periodic one still being written, the read of a storage that came back,
 * the final snapshot's write. One that has not returned by then is left to
 * the thread and the process exits without a final snapshot. */
#define FINAL_SNAPSHOT_WAIT_MS 5000U
/* How long the start waits for the read of the snapshots (load_snapshot). */
#define START_READ_WAIT_MS 5000U
/* How long the stop waits for the storage to reopen for the final snapshot. */
#define FINAL_REOPEN_WAIT_MS 1000U

/* The start-up read of the snapshots runs on a thread of its own
 * (robot_worker.h), waited for at most START_READ_WAIT_MS, so that a hung
 * medium at start-up does not hold the robot before it ever runs
 * (load_snapshot). Not the writer: its start, its retries and what happens
 * without it stay as they were. Started first thing, before the devices'
 * openers, and ended once its read is taken. A read that has not returned
 * in time is the snapshot job in flight (writing.at_start): it owns snaps'
 * buffer and the storage until it returns, the snapshots wait for it, and
 * its outcome becomes the generation bookkeeping then (start_read_taken). */
static robot_worker_t start_reader;
static struct {
    robot_snapshot_t loaded;
    robot_snapshot_found_t found;
    coslam_status_t result;
} start_read;

/* The start-up read, on start_reader. */
static void start_read_job(void *ctx)
{
    (void)ctx;
    start_read.result = robot_snapshots_read_newest(&snaps, &start_read.loaded, &start_read.found, stderr);
}
static robot_status_t status;

/* Map-message sequence numbers across restarts. A snapshot carries the
 * last one sent and whether maps may have been sent after it (any periodic
 * snapshot: the robot may crash later). A start from such a snapshot
 * numbers on ROBOT_SNAPSHOT_SEQ_MARGIN beyond it, so that the peers, who
 * remember the later numbers, do not refuse its maps as replays. Until the
 * robot sends, its snapshots keep the number it was restored from and the
 * doubt, so that restarts without sends (a crash loop) do not add margin
 * to margin towards the jump a peer refuses (MERGE_SEQ_MAX_JUMP). */
static struct {
    uint32_t base;     /* msg_seq of the snapshot restored */
    uint32_t resumed;  /* the number the node went on from */
    int unknown;       /* maps may have been sent beyond base before this start */
} seq_book;

/* msg_seq, and clean_stop kept only if the doubt is gone, into s (whose
 * clean_stop says whether this is the final snapshot). */
static void snap_seq_to_save(robot_snapshot_t *s)
{
    const uint32_t now_seq = robot_node_msg_seq(&node);
    if (seq_book.unknown && now_seq == seq_book.resumed) {
        s->msg_seq = seq_book.base; /* nothing sent since: the doubt stays */
        s->clean_stop = 0U;
        return;
    }
    s->msg_seq = now_seq;
}

/* The map's observers: the status count and the periodic snapshot. Their
 * export goes in parts into snap.map (robot_node_export_observe: the
 * merge's step_units per call, the rest in idle time) and yields to the
 * robot's own sends and merges, so an observer never takes a whole export's
 * time in one step (215 ms at 1,000 particles and 1,024 landmarks). What
 * fell due waits for it; a status report that waited OBSERVE_WAIT_US goes
 * out with the last count. */
#define OBSERVE_WAIT_US 2000000U
typedef struct {
    int running;        /* an export into snap.map under way */
    int want_snap;      /* a periodic snapshot waits for it */
    int want_line;      /* a status line waits for it */
    int want_file;      /* a status file waits for it */
    uint64_t status_due_us; /* when the waiting status report fell due */
    uint16_t landmarks; /* the last export's count */
} map_observer_t;

static map_observer_t observer;

/* A snapshot's write ended with `ws` after write_us: the generations
 * updated, reported per `verbose` (failures always), a failed medium
 * reported to the devices (closed, retried). Returns 0 if it was saved. */
static int commit_snapshot(int verbose, const char *why, const robot_snapshot_job_t *job, uint16_t landmarks,
                           hal_status_t ws, uint64_t write_us, uint64_t now_us)
{
    if (write_us > snaps.write_max_us) {
        snaps.write_max_us = write_us;
    }
    const coslam_status_t cs = robot_snapshots_commit(&snaps, job, ws);
    if (cs != COSLAM_OK) {
        /* the storage's own status and the OS's reason (the commit's
         * COSLAM_E_STORAGE / E_CAPACITY / E_UNSUPPORTED say only the class) */
        char os[128];
        const int e = dev.storage_state.last_errno;
        /* the bytes went to the medium but their fsync failed: counted,
         * and the storage goes down; its retry's probe fsyncs too, so it
         * stays down until an fsync works (no up-down flapping) */
        const int at_fsync = ws != HAL_OK && dev.storage_state.last_fsync_failed;
        if (at_fsync) {
            dev.storage_fsync_failures++;
        }
        (void)snprintf(os, sizeof os, "%s%s%s%s%s", at_fsync ? "fsync: " : "", e != 0 ? strerror(e) : "",
                       e != 0 ? " (" : "", hal_status_str(ws), e != 0 ? ")" : "");
        fprintf(stderr, "coslam-robot: snapshot: %s snapshot not written to %s: %s\n", why, job->name, os);
        if (ws == HAL_E_IO || ws == HAL_E_CLOSED) {
            char reason[160];
            (void)snprintf(reason, sizeof reason, "the snapshot write failed: %s", os);
            robot_devices_storage_save_failed(&dev, job->len, ws, reason, now_us);
        }
        return -1;
    }
    if (verbose) {
        fprintf(stderr, "coslam-robot: snapshot: saved %s seq=%llu landmarks=%u (%s) in %.1f ms\n", job->name,
                (unsigned long long)job->seq, (unsigned)landmarks, why, (double)write_us * 1e-3);
    }
    return 0;
}

/* Save snap.map, the export just made, as the next generation: handed to
 * the writer thread (the outcome comes with finish_snapshot_write; never
 * written here). Returns 0 if handed over. */
static int save_snapshot_map(int verbose, const char *why, uint64_t now_us)
{
    if (writing.active) {
        /* the writer owns snaps' buffer until its outcome is taken (the
         * read of a storage that came back, begun after this snapshot's
         * export): the snapshot is skipped, as one behind a slow write */
        snaps.busy_skips++;
        fprintf(stderr, "coslam-robot: snapshot: the storage is still being read (for %.1f s): %s snapshot skipped "
                        "(snap_busy_skips=%lu)\n",
                (double)(now_us - writing.since_us) * 1e-6, why, (unsigned long)snaps.busy_skips);
        return -1;
    }
    hal_storage_t *st = robot_devices_storage(&dev);
    robot_snapshots_set_storage(&snaps, st);
    if (st == NULL) {
        if (verbose) {
            fprintf(stderr, "coslam-robot: snapshot: storage down, %s snapshot not written\n", why);
        }
        snaps.save_failures++;
        return -1;
    }
    snap.robot_id = cfg.robot_id;
    snap.filter_kind = (uint8_t)cfg.node.filter.kind;
    snap_seq_to_save(&snap);
    snap.saved_unix_s = (uint64_t)time(NULL);
    robot_snapshot_job_t job;
    const coslam_status_t ps = robot_snapshots_prepare(&snaps, &snap, &job);
    if (ps != COSLAM_OK) {
        fprintf(stderr, "coslam-robot: snapshot: %s snapshot not written (%s)\n", why, coslam_status_str(ps));
        return -1;
    }
    const int e = robot_snapshot_writer_submit(&writer, st, job.name, snaps.buf, job.len);
    if (e != 0) {
        /* not reached: the callers hand over only with the thread running
         * and no job in flight. Never written here instead (the loop's or
         * the stop's thread: a hung medium would hold it) */
        snaps.save_failures++;
        fprintf(stderr, "coslam-robot: snapshot: writer thread refused the %s snapshot (%s): not written\n", why,
                strerror(e));
        return -1;
    }
    writing.active = 1;
    writing.job = job;
    writing.landmarks = snap.map.n_landmarks;
    writing.since_us = now_us;
    writing.why = why;
    return 0;
}

/* The storage came back: what the read of its newest generation gave
 * (robot_snapshots_read_newest's return, what it found, read_us) becomes
 * the generation bookkeeping, so that this run's saves come after the
 * snapshots on disk; reported. */
static void newest_read(coslam_status_t rs, const robot_snapshot_found_t *found, uint64_t read_us)
{
    const char *name = robot_snapshots_found(&snaps, found);
    char took[64] = "";
    if (read_us >= 50000U) {
        /* a medium that slow is said (on the writer thread: the loop went on) */
        (void)snprintf(took, sizeof took, " (read in %.0f ms on the writer thread)", (double)read_us * 1e-3);
    }
    if (rs == COSLAM_OK && name != NULL) {
        fprintf(stderr, "coslam-robot: snapshot: storage back; newest on disk %s seq=%llu kept, this run's map "
                        "is saved after it%s\n",
                name, (unsigned long long)found->seq, took);
    } else if (rs == COSLAM_E_EMPTY) {
        fprintf(stderr, "coslam-robot: snapshot: storage back; none on disk%s\n", took);
    } else {
        fprintf(stderr, "coslam-robot: snapshot: storage back; cannot read (%s)%s\n", coslam_status_str(rs), took);
    }
}

/* The storage came back: its newest generation is read on the writer
 * thread, which owns snaps' buffer until the outcome is taken
 * (finish_snapshot_write); never here (a medium that has just come back
 * may hang). The caller has the thread running and no job in flight.
 * Returns 0 if handed over, else -1 (not read: the caller tries again). */
static int storage_back(uint64_t now_us)
{
    static robot_snapshot_t newest;
    robot_snapshots_set_storage(&snaps, robot_devices_storage(&dev));
    if (writing.active || robot_snapshot_writer_submit_read(&writer, &snaps, &newest) != 0) {
        return -1;
    }
    writing.active = 1;
    writing.is_read = 1;
    writing.since_us = now_us;
    writing.why = "read";
    return 0;
}

/* The start-up read that did not return in time has returned (after
 * read_us): what it found becomes the generation bookkeeping, so that this
 * run's saves come after the snapshots on disk; reported. The map is not
 * loaded: the run has begun a new one. */
static void start_read_taken(uint64_t read_us)
{
    const coslam_status_t rs = start_read.result;
    const char *name = NULL;
    if (rs == COSLAM_OK || rs == COSLAM_E_EMPTY) {
        name = robot_snapshots_found(&snaps, &start_read.found); /* as robot_snapshots_load */
    }
    if (rs == COSLAM_OK && name != NULL) {
        fprintf(stderr, "coslam-robot: snapshot: the start-up read has returned after %.1f s: newest on disk %s "
                        "seq=%llu kept, not loaded (this run began a new map), which is saved after it\n",
                (double)read_us * 1e-6, name, (unsigned long long)start_read.found.seq);
    } else if (rs == COSLAM_E_EMPTY) {
        fprintf(stderr, "coslam-robot: snapshot: the start-up read has returned after %.1f s: none on disk\n",
                (double)read_us * 1e-6);
    } else {
        fprintf(stderr, "coslam-robot: snapshot: the start-up read has returned after %.1f s: cannot read (%s)\n",
                (double)read_us * 1e-6, coslam_status_str(rs));
    }
}

/* The periodic write in flight: its outcome, if it is there (waiting at
 * most wait_ms), committed and reported. Returns 1 when no write is in
 * flight any more. */
static int finish_snapshot_write(int verbose, uint32_t wait_ms, uint64_t now_us)
{
    if (!writing.active) {
        return 1;
    }
    hal_status_t ws = HAL_OK;
    uint64_t write_us = 0U;
    if (writing.at_start) {
        /* the start-up read, on its own thread */
        if (robot_worker_take(&start_reader, wait_ms, &write_us) == 0) {
            return 0;
        }
        writing.active = 0;
        writing.is_read = 0;
        writing.at_start = 0;
        (void)robot_worker_stop(&start_reader, 0U); /* idle: joined at once */
        start_read_taken(write_us);
        return 1;
    }
    if (robot_snapshot_writer_take(&writer, wait_ms, &ws, &write_us) == 0) {
        return 0;
    }
    writing.active = 0;
    if (writing.is_read) {
        writing.is_read = 0;
        newest_read(writer.read_result, &writer.read_found, write_us);
        return 1;
    }
    (void)commit_snapshot(verbose, writing.why, &writing.job, writing.landmarks, ws, write_us, now_us);
    return 1;
}

/* Export now (whole, in this step) and hand the next generation to the
 * writer thread: the final snapshot. */
static int save_snapshot(int verbose, const char *why, uint64_t now_us)
{
    memset(&snap, 0, sizeof snap);
    snap.clean_stop = 1U; /* the final snapshot: nothing is sent after it (snap_seq_to_save) */
    observer.running = 0; /* an observer's export into snap.map is finished by this one */
    const coslam_status_t es = robot_node_export(&node, &snap.map);
    if (es != COSLAM_OK && es != COSLAM_E_CAPACITY) {
        fprintf(stderr, "coslam-robot: snapshot: export failed (%s)\n", coslam_status_str(es));
        snaps.save_failures++;
        return -1;
    }
    (void)robot_node_export_poll(&node, &snap.map, NULL); /* the observer's, finished above: taken */
    observer.landmarks = snap.map.n_landmarks;
    return save_snapshot_map(verbose, why, now_us);
}

/* The writer thread runs, or is started again once its retry is due
 * (every retry_period_s, as a device's opener). A start that fails is
 * counted (snap_writer_start_failures), said when its reason is new, and
 * the snapshots meanwhile are not written (no_writer_skip). Returns 1 if
 * the thread runs. */
static int writer_running(uint64_t now_us)
{
    if (robot_snapshot_writer_started(&writer)) {
        return 1;
    }
    if (now_us < writer_retry.next_try_us) {
        return 0;
    }
    writer_retry.next_try_us = now_us + dev.retry_us;
    const int e = robot_snapshot_writer_start(&writer);
    if (e != 0) {
        snaps.writer_start_failures++;
        writer_retry.failing++;
        if (e != writer_retry.err) {
            fprintf(stderr,
                    "coslam-robot: snapshot: no writer thread (%s): snapshots are not written until one can be "
                    "started (never in the control loop's thread, which a slow or hung medium would hold); tried "
                    "again every %.1f s; the snapshots not written are counted (snap_no_writer_skips)\n",
                    strerror(e), (double)dev.retry_us * 1e-6);
        }
        writer_retry.err = e;
        return 0;
    }
    if (writer_retry.failing > 0U) {
        fprintf(stderr,
                "coslam-robot: snapshot: writer thread started after %lu failed attempts: snapshots are written "
                "again (%lu not written meanwhile, snap_no_writer_skips)\n",
                (unsigned long)writer_retry.failing, (unsigned long)snaps.no_writer_skips);
    }
    writer_retry.err = 0;
    writer_retry.failing = 0U;
    return 1;
}

/* A snapshot not written because the writer thread does not run: counted;
 * said with -v (the thread's failure itself was said, writer_running). */
static void no_writer_skip(int verbose, const char *why)
{
    snaps.no_writer_skips++;
    if (verbose) {
        fprintf(stderr, "coslam-robot: snapshot: no writer thread (%s): %s snapshot not written "
                        "(snap_no_writer_skips=%lu)\n",
                strerror(writer_retry.err), why, (unsigned long)snaps.no_writer_skips);
    }
}

/* The stop: the snapshot job handed over (writing) has not returned
 * within its wait (storage stuck): said, counted (snap_final_timeouts),
 * the thread left to it; the process exits without a final snapshot. The
 * generations on disk stay whole: a write goes to a temporary file that
 * is renamed over the older generation only once written and fsync'ed
 * (hal_storage_linux), so the exit cuts at most that temporary file. */
static void final_stuck(hal_clock_t *clock)
{
    uint64_t now = writing.since_us;
    (void)hal_clock_now_us(clock, &now);
    snaps.final_timeouts++;
    if (!writing.is_read && writing.why != NULL && strcmp(writing.why, "final") == 0) {
        fprintf(stderr,
                "coslam-robot: snapshot: final snapshot still being written after %.1f s (storage stuck): not "
                "waited for any longer, the process exits without it (snap_final_timeouts=%lu); the newest "
                "complete generation on disk stays seq=%llu (the write goes to a temporary file, renamed over %s "
                "only once written whole)\n",
                (double)(now - writing.since_us) * 1e-6, (unsigned long)snaps.final_timeouts,
                (unsigned long long)snaps.newest_seq, writing.job.name);
    } else {
        fprintf(stderr,
                "coslam-robot: snapshot: a snapshot %s has run for %.1f s and does not return (storage stuck): "
                "no final snapshot\n",
                writing.is_read ? "read" : "write", (double)(now - writing.since_us) * 1e-6);
    }
    (void)robot_snapshot_writer_stop(&writer, 0U);
    if (writing.at_start) {
        (void)robot_worker_stop(&start_reader, 0U); /* the start-up read: left to its thread */
    }
    /* the thread still uses the storage: left open to it until exit */
    dev.dev[ROBOT_DEV_STORAGE].state = ROBOT_DEV_DOWN;
}

/* The stop's final snapshot with the writer thread running and nothing in
 * flight: the storage tried again if it is down (robot_devices_reopen_now,
 * at most FINAL_REOPEN_WAIT_MS), the read of a storage that came back
 * (read_due, or reopened now) and the final snapshot's write go to the
 * thread, each waited for at most FINAL_SNAPSHOT_WAIT_MS; one that has not
 * returned by then is said, counted and left to the thread (final_stuck),
 * and the stop goes on without a final snapshot. Neither runs in this
 * thread: a medium that hangs at the stop (an NFS mount gone, an SD card
 * whose fsync never returns) would keep the process from ever exiting.
 * Returns 0 if it was saved. */
static int final_snapshot_on_writer(hal_clock_t *clock, int read_due)
{
    uint64_t now = 0U;
    (void)hal_clock_now_us(clock, &now);
    if (robot_devices_storage(&dev) == NULL &&
        robot_devices_reopen_now(&dev, ROBOT_DEV_STORAGE, now, FINAL_REOPEN_WAIT_MS)) {
        /* down since a failed write or a lost medium, and back: the final
         * snapshot is not skipped for a retry not yet due; the generations
         * on disk first, so that it comes after them */
        fprintf(stderr, "coslam-robot: snapshot: storage back for the final snapshot\n");
        read_due = 1;
    }
    (void)hal_clock_now_us(clock, &now);
    if (read_due && robot_devices_storage(&dev) != NULL) {
        if (storage_back(now) != 0) {
            /* not reached: the thread runs, nothing is in flight */
            (void)robot_snapshot_writer_stop(&writer, FINAL_SNAPSHOT_WAIT_MS);
            return -1;
        }
        if (!finish_snapshot_write(1, FINAL_SNAPSHOT_WAIT_MS, now)) {
            final_stuck(clock);
            return -1;
        }
        (void)hal_clock_now_us(clock, &now);
    }
    const uint32_t saves = snaps.saves;
    if (save_snapshot(1, "final", now) == 0) {
        (void)hal_clock_now_us(clock, &now);
        if (!finish_snapshot_write(1, FINAL_SNAPSHOT_WAIT_MS, now)) {
            final_stuck(clock);
            return -1;
        }
    }
    (void)robot_snapshot_writer_stop(&writer, FINAL_SNAPSHOT_WAIT_MS);
    return snaps.saves > saves ? 0 : -1;
}

/* The stop's final snapshot when the writer thread did not run at the end
 * of the loop (it could not be started). It is started once more, at once;
 * if it starts, the final snapshot goes to it as with the thread running
 * all along (final_snapshot_on_writer: the read of a storage that came
 * back, read_due, first; each waited for at most FINAL_SNAPSHOT_WAIT_MS).
 * If it does not, there is no final snapshot: it is not written in this
 * thread, which a hung medium would hold for ever (the stop must end: the
 * drives are released, and a service manager would kill the process
 * anyway); said and counted. The generations on disk stay as they were.
 * Returns 0 if it was saved. */
static int final_snapshot_no_writer(hal_clock_t *clock, int read_due)
{
    uint64_t now = 0U;
    (void)hal_clock_now_us(clock, &now);
    writer_retry.next_try_us = now; /* due now, whatever the retry period */
    if (!writer_running(now)) {
        snaps.no_writer_skips++;
        fprintf(stderr,
                "coslam-robot: snapshot: no writer thread at the stop (%s): no final snapshot (not written in "
                "this thread, which a slow or hung medium would hold; snap_no_writer_skips=%lu); the newest on "
                "disk stays seq=%llu\n",
                strerror(writer_retry.err), (unsigned long)snaps.no_writer_skips,
                (unsigned long long)snaps.newest_seq);
        return -1;
    }
    return final_snapshot_on_writer(clock, read_due);
}

/* The observers' export: begin it, or see whether it is done. Returns 1
 * when snap.map holds a new export (status into *es), else 0. */
static int observe_map(coslam_status_t *es)
{
    if (observer.running) {
        const int r = robot_node_export_poll(&node, &snap.map, es);
        if (r == 0) {
            return 0;
        }
        observer.running = 0;
        if (r == 1) {
            return 1;
        }
        /* yielded to a send or a merge: begin again */
    }
    memset(&snap, 0, sizeof snap);
    *es = robot_node_export_observe(&node, &snap.map);
    if (*es == COSLAM_E_MERGE_PENDING) {
        observer.running = 1;
        return 0;
    }
    return *es != COSLAM_E_MERGE_BUSY; /* busy: the export table is taken, try next step */
}

/* At start: the newest generation, read on start_reader and waited for at
 * most START_READ_WAIT_MS. With `restore` the node starts from it; else (a
 * dry run) it is only named. A read that has not returned by then: a new
 * map, said and counted (snap_start_read_timeouts), the read left in
 * flight (writing.at_start: the loop takes it when the medium answers, and
 * this run's snapshots come after what it found). No thread for the read:
 * not read here (a hung medium would hold the start for ever), a new map,
 * said and counted (snap_no_writer_skips). Returns 1 if the generations
 * are still to be read then: the loop reads them on the writer thread, as
 * for a storage that came back (storage_back). */
static int load_snapshot(int restore)
{
    hal_storage_t *st = robot_devices_storage(&dev);
    robot_snapshots_set_storage(&snaps, st);
    if (st == NULL) {
        (void)robot_worker_stop(&start_reader, 0U); /* idle: nothing to read */
        fprintf(stderr, "coslam-robot: snapshot: storage down: starting a new map\n");
        return 0;
    }
    const int started = robot_worker_start(&start_reader, start_read_job, NULL); /* 0 at once if it runs */
    if (started != 0 || robot_worker_submit(&start_reader) != 0) {
        snaps.no_writer_skips++;
        fprintf(stderr,
                "coslam-robot: snapshot: no thread for the start-up read (%s): the snapshots are not read in this "
                "thread, which a hung medium would hold: starting a new map; they are read on the writer thread "
                "once it runs, and this run's snapshots are saved after them (snap_no_writer_skips=%lu)\n",
                strerror(started != 0 ? started : ESRCH),
                (unsigned long)snaps.no_writer_skips);
        return 1;
    }
    uint64_t handed_us = 0U;
    (void)hal_clock_now_us(dev.clock, &handed_us);
    uint64_t read_us = 0U;
    if (robot_worker_take(&start_reader, START_READ_WAIT_MS, &read_us) != 1) {
        snaps.start_read_timeouts++;
        fprintf(stderr,
                "coslam-robot: snapshot: the start-up read of the snapshots has not returned within %.1f s (a hung "
                "medium?): starting a new map, not restored (snap_start_read_timeouts=%lu); the read goes on on its "
                "own thread, the snapshots wait for it and are saved after what it finds\n",
                (double)START_READ_WAIT_MS * 1e-3, (unsigned long)snaps.start_read_timeouts);
        writing.active = 1;
        writing.is_read = 1;
        writing.at_start = 1;
        writing.since_us = handed_us;
        writing.why = "read";
        return 0;
    }
    (void)robot_worker_stop(&start_reader, 0U); /* idle: joined at once */
    robot_snapshot_t *loaded = &start_read.loaded;
    const char *name = NULL;
    const coslam_status_t ls = start_read.result;
    if (ls == COSLAM_OK || ls == COSLAM_E_EMPTY) {
        name = robot_snapshots_found(&snaps, &start_read.found); /* as robot_snapshots_load */
    }
    if (ls == COSLAM_E_EMPTY) {
        fprintf(stderr, "coslam-robot: snapshot: none found: starting a new map\n");
        return 0;
    }
    if (ls != COSLAM_OK) {
        fprintf(stderr, "coslam-robot: snapshot: cannot read (%s): starting a new map\n", coslam_status_str(ls));
        return 0;
    }
    if (!restore) {
        fprintf(stderr, "coslam-robot: snapshot: newest on disk %s seq=%llu (dry run: not loaded)\n", name,
                (unsigned long long)loaded->seq);
        return 0;
    }
    if (loaded->robot_id != cfg.robot_id) {
        fprintf(stderr, "coslam-robot: snapshot: %s seq=%llu was saved by robot %u, this is robot %u: not loaded, "
                        "starting a new map\n",
                name, (unsigned long long)loaded->seq, (unsigned)loaded->robot_id, (unsigned)cfg.robot_id);
        return 0;
    }
    /* after a crash, maps sent since this snapshot have later sequence
     * numbers that the peers remember: go on beyond them */
    const uint32_t msg_seq = loaded->msg_seq + (loaded->clean_stop ? 0U : ROBOT_SNAPSHOT_SEQ_MARGIN);
    const coslam_status_t rs = robot_node_restore(&node, &loaded->map, msg_seq);
    /* the message numbers go on either way (robot_node_restore) */
    seq_book.base = loaded->msg_seq;
    seq_book.resumed = msg_seq;
    seq_book.unknown = !loaded->clean_stop;
    if (rs != COSLAM_OK && rs != COSLAM_E_CAPACITY) {
        fprintf(stderr, "coslam-robot: snapshot: %s seq=%llu refused by the filter (%s): starting a new map; map "
                        "messages numbered on from %lu\n",
                name, (unsigned long long)loaded->seq, coslam_status_str(rs), (unsigned long)msg_seq);
        return 0;
    }
    char restart[96] = "";
    if (!loaded->clean_stop) {
        (void)snprintf(restart, sizeof restart, " (not from a clean stop: map messages numbered on from %lu)",
                       (unsigned long)msg_seq);
    }
    fprintf(stderr,
            "coslam-robot: snapshot: loaded %s seq=%llu landmarks=%u pose=(%.3f, %.3f, %.4f)%s%s\n", name,
            (unsigned long long)loaded->seq, (unsigned)loaded->map.n_landmarks, loaded->map.pose.x, loaded->map.pose.y,
            loaded->map.pose.theta, rs == COSLAM_E_CAPACITY ? " (cut to this build's capacity)" : "", restart);
    return 0;
}

/* The meeting's events: merges and refusals always (they change or keep
 * the map: worth a line each), sends with -v. Draining the queue also
 * keeps mt_events_dropped at zero. */
static void log_meeting_events(int verbose)
{
    meeting_event_t ev;
    while (robot_node_take_event(&node, &ev) == COSLAM_OK) {
        if (ev.kind == MEETING_EV_MERGED) {
            /* what the merge did and left out, as coslam-sim prints it */
            char what[384];
            (void)slam_filter_merge_format(
                &ev.stats, node.filter.kind == SLAM_FILTER_EKF ? 1U : node.filter.u.fs.cfg.n_particles, what,
                sizeof what);
            fprintf(stderr, "coslam-robot: meeting: merged robot %u's map (seq %lu, %u landmarks: %s%s)\n",
                    (unsigned)ev.peer, (unsigned long)ev.seq, (unsigned)ev.n_landmarks, what,
                    ev.status == COSLAM_OK ? "" : "; partly: capacity");
        } else if (ev.kind == MEETING_EV_REFUSED) {
            fprintf(stderr, "coslam-robot: meeting: refused a map from robot %u (seq %lu): %s\n", (unsigned)ev.peer,
                    (unsigned long)ev.seq, coslam_status_str(ev.status));
        } else if (verbose) {
            fprintf(stderr, "coslam-robot: meeting: sent the map to robot %u (seq %lu, %u landmarks)\n",
                    (unsigned)ev.peer, (unsigned long)ev.seq, (unsigned)ev.n_landmarks);
        }
    }
}

/* Limits are loud: a line (the same as coslam-replay's and coslam-sim's,
 * slam_filter_limit_format) whenever a loss counter of the filter has grown
 * since the last status report, and for sightings the camera source could
 * not fit in a frame. */
static void log_limits(void)
{
    static const char *seen_counter[SLAM_FILTER_N_LIMITS];
    static uint32_t seen_value[SLAM_FILTER_N_LIMITS];
    static uint32_t seen_dropped;
    static uint32_t seen_sends_forced;
    static uint32_t seen_forced;
    slam_filter_limit_t lim[SLAM_FILTER_N_LIMITS];
    const int n = slam_filter_limits(&node.filter, lim);
    for (int i = 0; i < n; ++i) {
        int k = 0;
        while (k < SLAM_FILTER_N_LIMITS && seen_counter[k] != NULL && seen_counter[k] != lim[i].counter) {
            ++k;
        }
        if (k == SLAM_FILTER_N_LIMITS || (seen_counter[k] != NULL && seen_value[k] >= lim[i].value)) {
            continue;
        }
        seen_counter[k] = lim[i].counter;
        seen_value[k] = lim[i].value;
        char line[512];
        (void)slam_filter_limit_format(&lim[i], (unsigned)cfg.robot_id, line, sizeof line);
        fprintf(stderr, "coslam-robot: %s\n", line);
    }
    if (node.ctr.sightings_dropped > seen_dropped) {
        seen_dropped = node.ctr.sightings_dropped;
        fprintf(stderr,
                "coslam-robot: LIMIT robot %u: %lu sightings dropped by the camera source: more in one frame than fit "
                "(sightings_dropped; COSLAM_MAX_SIGHTINGS = %d in this build, profile %s)\n",
                (unsigned)cfg.robot_id, (unsigned long)seen_dropped, (int)COSLAM_MAX_SIGHTINGS, COSLAM_PROFILE_NAME);
    }
    /* the e2e live stream's robot sightings outside the fleet: said once */
    (void)robot_live_say_refusals(&dev.replay, stderr);
#if COSLAM_HAVE_CAMERA
    /* the marker detector ran out of room in a frame: markers lost */
    static uint64_t seen_partial;
    if (dev.camera_kind == ROBOT_SIGHTINGS_CAMERA) {
        (void)robot_camera_say_limits(&dev.camera, &seen_partial, (unsigned)cfg.robot_id, stderr);
    }
#endif
    /* the health monitor judged the filter diverged (reported, not acted on:
     * docs/robot-app.md) */
    static uint32_t seen_diverged;
    if (node.ctr.diverged > seen_diverged) {
        seen_diverged = node.ctr.diverged;
        fprintf(stderr,
                "coslam-robot: warning: robot %u: the health monitor judges the filter diverged (episode %lu; "
                "diverged): its pose and map are not to be trusted until it says otherwise (diverged_now)\n",
                (unsigned)cfg.robot_id, (unsigned long)seen_diverged);
    }
    /* this process stalled past the drives' watchdog: they stopped the base */
    static uint32_t seen_stalls;
    if (node.ctr.stalls > seen_stalls) {
        seen_stalls = node.ctr.stalls;
        fprintf(stderr,
                "coslam-robot: robot %u: warning: this process did not poll the drives for %.0f ms, longer than "
                "their watchdog (%u ms): they stopped the base themselves; the drive fault that follows is reset "
                "at once (stalls %lu)\n",
                (unsigned)cfg.robot_id, (double)node.stall_us * 1e-3, (unsigned)cfg.node.drive.drive.master_timeout_ms,
                (unsigned long)seen_stalls);
    }
    /* a drive fault: which wheel and why (counted once per fault, robot_node) */
    static uint32_t seen_drive_faults;
    static uint32_t seen_stall_resets;
    if (node.ctr.drive_faults > seen_drive_faults) {
        seen_drive_faults = node.ctr.drive_faults;
        const int at_once = node.ctr.stall_resets > seen_stall_resets; /* right after a stall */
        seen_stall_resets = node.ctr.stall_resets;
        cia402_omni_fault_t df;
        const robot_dev_state_t can = dev.dev[ROBOT_DEV_CAN].state;
        const int got = cia402_omni_get_fault(&node.drive, &df) == COSLAM_OK;
        if (got && df.info.reason == CIA402_FAULT_BUS && can != ROBOT_DEV_UP) {
            /* no bus, not a drive's fault: no wheel or EMCY to name. Absent
             * (no [can] interface): said once at start-up; down: said here */
            if (can == ROBOT_DEV_DOWN) {
                fprintf(stderr,
                        "coslam-robot: robot %u: drive fault %lu: no CAN bus (can down, see its line): the drives "
                        "cannot be reached; no motion, no odometry until it is back (drive_faults)\n",
                        (unsigned)cfg.robot_id, (unsigned long)seen_drive_faults);
            }
        } else if (got) {
            const char *hint = "";
            if (df.info.reason == CIA402_FAULT_EMCY && df.info.emcy_code == CANOPEN_EMCY_HEARTBEAT) {
                hint = " (the drive's watchdog fired: it missed this process's heartbeat for "
                       "[can] watchdog_timeout_ms; the control loop stalled or frames were lost)";
            } else if (df.info.reason == CIA402_FAULT_SDO_ABORT &&
                       (df.info.sdo_index == CIA402_OD_CONSUMER_HEARTBEAT ||
                        df.info.sdo_index == CIA402_OD_ABORT_CONNECTION)) {
                hint = df.info.sdo_abort_code == CANOPEN_SDO_ABORT_VALUE_RANGE
                           ? " (the drive does not take this [can] watchdog_action: try another)"
                           : " (the drive refused the watchdog set-up; [can] master_node_id = 0 runs it "
                             "without the drive-side watchdog, and then a dead process leaves the wheels turning)";
            }
            fprintf(stderr,
                    "coslam-robot: robot %u: drive fault %lu: wheel %d (CANopen node %u): %s, EMCY code 0x%04x "
                    "register 0x%02x, statusword 0x%04x, SDO abort 0x%08lx on 0x%04x; stopped, reset %s%.1f s "
                    "(drive_faults)%s\n",
                    (unsigned)cfg.robot_id, (unsigned long)seen_drive_faults, (int)df.wheel, (unsigned)df.node_id,
                    cia402_fault_str(df.info.reason), (unsigned)df.info.emcy_code, (unsigned)df.info.emcy_register,
                    (unsigned)df.info.statusword, (unsigned long)df.info.sdo_abort_code,
                    (unsigned)df.info.sdo_index, at_once ? "at once (after this process's stall), not in " : "in ",
                    (double)cfg.node.retry_period_us * 1e-6, hint);
        } else {
            fprintf(stderr, "coslam-robot: robot %u: drive fault %lu (cleared before it was read; drive_faults)\n",
                    (unsigned)cfg.robot_id, (unsigned long)seen_drive_faults);
        }
    }
    /* nothing is lost, but a step paid for the rest of a merge or a send */
    if (node.filter.merges_forced > seen_forced) {
        seen_forced = node.filter.merges_forced;
        fprintf(stderr,
                "coslam-robot: robot %u: %lu merges in parts finished at once by an update, an export or (EKF-SLAM) "
                "more inputs than it may hold: the idle time did not suffice (merges_forced; lower [merge] "
                "step_units, now %lu)\n",
                (unsigned)cfg.robot_id, (unsigned long)seen_forced, (unsigned long)node.meeting.cfg.merge.step_units);
    }
    if (node.filter.sends_forced > seen_sends_forced) {
        seen_sends_forced = node.filter.sends_forced;
        fprintf(stderr,
                "coslam-robot: robot %u: %lu map exports for a send finished at once by an update or a merge: the "
                "idle time did not suffice (sends_forced; lower [merge] step_units, now %lu)\n",
                (unsigned)cfg.robot_id, (unsigned long)seen_sends_forced,
                (unsigned long)node.meeting.cfg.merge.step_units);
    }
}

/* --status-file: its writes that failed, in all and since the last one
 * that succeeded. */
static struct {
    uint32_t failures;
    uint32_t failing;
} status_file;

/* Write the JSON status to path. A file that cannot be written is said at
 * its first failure with the path and the OS's reason; the failures after
 * it are only counted (status_file_failures in the status), so that a
 * monitor path gone bad does not fill the log every period; the first
 * write that works again is said once. */
static void write_status_file(const char *path)
{
    if (robot_status_write_json(&status, path) == 0) {
        if (status_file.failing > 0U) {
            fprintf(stderr, "coslam-robot: status file %s: written again after %lu failed write%s\n", path,
                    (unsigned long)status_file.failing, status_file.failing == 1U ? "" : "s");
            status_file.failing = 0U;
        }
        return;
    }
    const int e = errno;
    status_file.failures++;
    if (status_file.failing++ == 0U) {
        fprintf(stderr,
                "coslam-robot: status file %s: cannot write: %s; the robot runs on; later failures are counted "
                "(status_file_failures), not said, until a write works again\n",
                path, strerror(e));
    }
}

static void report_status(const options_t *o, int to_stderr, const robot_loop_stats_t *loop)
{
    log_limits();
    robot_loop_stats_t with_file = *loop;
    with_file.status_file_failures = status_file.failures;
    robot_status_collect(&status, &node, &dev, &snaps, &with_file);
    if (to_stderr) {
        static char line[8192];
        if (robot_status_line(&status, line, sizeof line) + 1U >= sizeof line) {
            static int said;
            if (!said) {
                said = 1;
                fprintf(stderr, "coslam-robot: LIMIT status: the status line is cut at %zu characters "
                                "(robot_main.c report_status)\n", sizeof line - 1U);
            }
        }
        /* a link that is off or unauthenticated is said on every line */
        const char *warn = robot_link_warning(&dev.link);
        fprintf(stderr, "coslam-robot: status %s%s%s\n", line, warn != NULL ? " WARNING: " : "",
                warn != NULL ? warn : "");
        fflush(stderr);
    }
    if (o->status_file != NULL) {
        write_status_file(o->status_file);
    }
}

static void print_devices(FILE *out)
{
    for (int i = 0; i < ROBOT_DEV_COUNT; ++i) {
        const robot_dev_status_t *s = &dev.dev[i];
        fprintf(out, "%-8s %-6s %s%s%s\n", s->name, robot_dev_state_name(s->state), s->what,
                s->reason[0] != '\0' ? " - " : "", s->reason);
    }
}

int main(int argc, char **argv)
{
    options_t opt;
    const int pa = parse_args(argc, argv, &opt);
    if (pa != 0) {
        return pa > 0 ? 0 : 2;
    }
    robot_config_default(&cfg);
    char msg[ROBOT_CONFIG_MSG_MAX + 64u];
    if (robot_config_load(&cfg, opt.config_path, msg, sizeof msg) != COSLAM_OK) {
        fprintf(stderr, "coslam-robot: %s\n", msg);
        return 2;
    }
    cfg.can_fd = opt.can_fd;
    cfg.camera_live_fd = opt.sightings_fd;
    cfg.gpio_fd = opt.gpio_fd;
    if (opt.print_config) {
        robot_config_print(&cfg, stdout);
        return 0;
    }

    /* every signal that would end the process stops it cleanly instead:
     * drives stopped, final snapshot. SIGHUP comes when the terminal of a
     * hand-started robot goes (a dropped SSH session), SIGQUIT from Ctrl-\;
     * SIGUSR1, SIGUSR2 and SIGALRM (a stray kill -USR1, a script's alarm)
     * would end it without a word by default;
     * SIGPIPE (stderr piped into a reader that died) is ignored: a lost
     * log line is no reason to leave the wheels turning */
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    (void)sigemptyset(&sa.sa_mask);
    static const int stop_signals[] = {SIGTERM, SIGINT, SIGHUP, SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM};
    for (size_t i = 0; i < sizeof stop_signals / sizeof stop_signals[0]; ++i) {
        (void)sigaction(stop_signals[i], &sa, NULL);
    }
    struct sigaction ign;
    memset(&ign, 0, sizeof ign);
    ign.sa_handler = SIG_IGN;
    (void)sigemptyset(&ign.sa_mask);
    (void)sigaction(SIGPIPE, &ign, NULL);
    (void)sigaction(SIGXFSZ, &ign, NULL); /* a file size limit: the write fails (EFBIG), said as any */

    hal_clock_t *clock = hal_clock_linux();
    int clock_failed = 0; /* the loop ended because the clock failed: exit 1 */
    uint64_t now = 0;
    if (hal_clock_now_us(clock, &now) != HAL_OK) {
        fprintf(stderr, "coslam-robot: the monotonic clock failed\n");
        return 1;
    }
    const uint64_t t_start = now;
    fprintf(stderr, "coslam-robot: robot %u of %u, %s filter, profile %s, config %s\n", (unsigned)cfg.robot_id,
            (unsigned)cfg.fleet_size, slam_filter_kind_name(cfg.node.filter.kind), COSLAM_PROFILE_NAME,
            opt.config_path);
    (void)app_profile_format(msg, sizeof msg);
    fprintf(stderr, "coslam-robot: %s\n", msg);
    const coslam_status_t ds = robot_devices_init(&dev, &cfg, clock, stderr, opt.verbose, msg, sizeof msg);
    if (ds != COSLAM_OK) {
        /* the link policy refused (a configured fleet key that cannot be
         * used): running unauthenticated instead would be wrong */
        fprintf(stderr, "coslam-robot: %s: %s\n", opt.config_path, msg);
        robot_devices_close_all(&dev);
        return ds == COSLAM_E_ARG ? 2 : 1;
    }
    /* the start-up read's thread before the devices' openers (load_snapshot
     * starts it again if this fails) */
    (void)robot_worker_start(&start_reader, start_read_job, NULL);
    robot_devices_open_all(&dev, now);
    robot_snapshots_init(&snaps, robot_devices_storage(&dev));

    const robot_node_io_t io = robot_devices_io(&dev);
    /* no CAN configured ([can] interface empty, no --can-fd): no drives on
     * purpose, not a fault; a configured bus that is down is one */
    cfg.node.drive_absent = dev.dev[ROBOT_DEV_CAN].state == ROBOT_DEV_ABSENT ? 1U : 0U;
    const coslam_status_t is = robot_node_init(&node, &cfg.node, &io);
    if (is != COSLAM_OK) {
        fprintf(stderr, "coslam-robot: the robot node refused the configuration (robot_node_init: %s)\n",
                coslam_status_str(is));
        robot_devices_close_all(&dev);
        return is == COSLAM_E_ARG ? 2 : 1;
    }
    if (!robot_node_gpio_attached(&node) && dev.dev[ROBOT_DEV_GPIO].state == ROBOT_DEV_UP) {
        robot_devices_fail(&dev, ROBOT_DEV_GPIO, HAL_E_BUSY, "the bumper / e-stop / LED lines could not be claimed",
                           now);
    }
    if (!robot_node_gpio_attached(&node)) {
        fprintf(stderr, "coslam-robot: gpio: no bumper, no e-stop: %s\n",
                cfg.gpio_required ? "no motion until they are back (gpio.required = true)"
                                  : "moving anyway (gpio.required = false)");
    }
    if (dev.dev[ROBOT_DEV_LASER].state != ROBOT_DEV_UP) {
        fprintf(stderr, "coslam-robot: laser: no obstacle behaviour: the robot turns on the spot only "
                        "(at most %.2f rad/s), no translation\n",
                cfg.node.blind_max_turn_radps);
    }
    if (dev.dev[ROBOT_DEV_CAN].state == ROBOT_DEV_ABSENT) {
        /* no drives on purpose (drive_absent): not a drive fault */
        fprintf(stderr, "coslam-robot: can: no CAN configured ([can] interface is empty): no drives: no motion, no "
                        "odometry (not a fault: drive_faults stays 0)\n");
    } else if (dev.dev[ROBOT_DEV_CAN].state != ROBOT_DEV_UP) {
        fprintf(stderr, "coslam-robot: can: no drives: no motion, no odometry\n");
    }
    if (cfg.can_interface[0] != '\0' || opt.can_fd >= 0) {
        const cia402_drive_config_t *wd = &cfg.node.drive.drive;
        if (wd->master_node_id != 0U) {
            fprintf(stderr,
                    "coslam-robot: can: drive watchdog: heartbeat as node %u every %u ms; a drive that misses it for "
                    "%u ms stops its wheel (%s)\n",
                    (unsigned)wd->master_node_id, (unsigned)cfg.node.drive.master_heartbeat_period_ms,
                    (unsigned)wd->master_timeout_ms,
                    wd->master_loss_action == CIA402_ABORT_FAULT             ? "fault"
                    : wd->master_loss_action == CIA402_ABORT_DISABLE_VOLTAGE ? "disable_voltage"
                                                                             : "quick_stop");
        } else {
            fprintf(stderr, "coslam-robot: can: warning: no drive watchdog ([can] master_node_id = 0): if this "
                            "process dies or hangs, the wheels keep their last command\n");
        }
    }
    const int start_unread = load_snapshot(!opt.dry_run);

    if (opt.dry_run) {
        printf("coslam-robot dry run: robot %u of %u, config %s\n", (unsigned)cfg.robot_id, (unsigned)cfg.fleet_size,
               opt.config_path);
        print_devices(stdout);
        printf("snapshot newest seq %llu\n", (unsigned long long)snaps.newest_seq);
        if (writing.active) {
            /* the start-up read did not return (said): left to its thread,
             * and the storage left open to it until the exit */
            (void)robot_worker_stop(&start_reader, 0U);
            dev.dev[ROBOT_DEV_STORAGE].state = ROBOT_DEV_DOWN;
        }
        robot_devices_close_all(&dev);
        return 0;
    }

    (void)writer_running(now); /* said if it cannot be started; tried again at the retry period */
    const uint64_t period = cfg.step_period_us;
    /* a positive period below a microsecond is a microsecond, not 0 (off) */
    const uint64_t status_us = cfg.status_period_s > 0.0 ? (uint64_t)fmax(1.0, cfg.status_period_s * 1e6) : 0U;
    const uint64_t file_us = status_us > 0U ? status_us : 10000000U;
    const uint64_t snap_us = cfg.snapshot_period_s > 0.0 ? (uint64_t)fmax(1.0, cfg.snapshot_period_s * 1e6) : 0U;
    robot_loop_stats_t loop;
    memset(&loop, 0, sizeof loop);
    uint64_t next = now + period;
    uint64_t next_status = now + status_us;
    uint64_t next_file = now + file_us;
    uint64_t next_limits = now + 1000000U; /* limit and warning lines: every second, status or not */
    uint64_t next_snap = now + snap_us;
    uint64_t gpio_try = now;
    double cpu_mark = cpu_seconds();
    uint64_t cpu_mark_us = now;
    int storage_was_up = robot_devices_storage(&dev) != NULL;
    /* the storage came back, or the start could not read it: its newest
     * generation is read (on the writer) */
    int storage_read_due = start_unread;
    coslam_status_t last_step = COSLAM_OK;

    while (!stop_signal && (opt.once < 0 || loop.steps < (uint64_t)opt.once)) {
        /* devices: close the lost ones (GPIO roles let go first), retry the rest */
        if (dev.dev[ROBOT_DEV_GPIO].lost) {
            robot_node_gpio_detach(&node);
        }
        (void)hal_clock_now_us(clock, &now);
        (void)robot_devices_service(&dev, now);
        if (dev.dev[ROBOT_DEV_GPIO].state == ROBOT_DEV_UP && !robot_node_gpio_attached(&node) && now >= gpio_try) {
            if (robot_node_gpio_attach(&node) == COSLAM_OK) {
                fprintf(stderr, "coslam-robot: gpio: bumper / e-stop / LED roles attached\n");
            } else {
                robot_devices_fail(&dev, ROBOT_DEV_GPIO, HAL_E_BUSY,
                                   "the bumper / e-stop / LED lines could not be claimed", now);
            }
            gpio_try = now + dev.retry_us;
        }
        const int storage_up = robot_devices_storage(&dev) != NULL;
        if (storage_up && !storage_was_up) {
            storage_read_due = 1;
        }
        storage_read_due = storage_read_due && storage_up;
        if (storage_read_due && writer_running(now) && storage_back(now) == 0) {
            /* without the thread the read waits for it (never in the loop);
             * the snapshots it orders are not written meanwhile either; a
             * job in flight (the start-up read) is waited for too */
            storage_read_due = 0;
        }
        storage_was_up = storage_up;

        const coslam_status_t st = robot_node_step(&node);
        if (st != last_step && opt.verbose) {
            fprintf(stderr, "coslam-robot: step: %s\n", coslam_status_str(st));
        }
        last_step = st;
        loop.steps++;
        log_meeting_events(opt.verbose);

        (void)hal_clock_now_us(clock, &now);
        (void)finish_snapshot_write(opt.verbose, 0U, now);
        /* the map's observers: what falls due waits for their export in parts */
        if (snap_us > 0U && now >= next_snap) {
            next_snap = now + snap_us;
            if (writing.active) {
                /* the last one's write still runs: a medium this slow is
                 * reported, not queued behind */
                snaps.busy_skips++;
                fprintf(stderr,
                        "coslam-robot: snapshot: the %s has run for %.1f s (slow or stuck storage): periodic "
                        "snapshot skipped (snap_busy_skips=%lu)\n",
                        writing.at_start  ? "start-up read of the snapshots"
                        : writing.is_read ? "read of the storage that came back"
                                          : "last snapshot's write",
                        (double)(now - writing.since_us) * 1e-6, (unsigned long)snaps.busy_skips);
            } else if (!writer_running(now)) {
                no_writer_skip(opt.verbose, "periodic");
            } else {
                observer.want_snap = 1;
            }
        }
        if (!(observer.want_line || observer.want_file)) {
            observer.status_due_us = now;
        }
        if (now >= next_limits) {
            /* a capacity hit is said within a second, also with the status
             * line off (status_period_s = 0) */
            log_limits();
            next_limits = now + 1000000U;
        }
        if (status_us > 0U && now >= next_status) {
            observer.want_line = 1;
            next_status = now + status_us;
        }
        if (opt.status_file != NULL && now >= next_file) {
            observer.want_file = 1;
            next_file = now + file_us;
        }
        int fresh = 0; /* snap.map holds an export made for them now */
        if (observer.want_snap || observer.want_line || observer.want_file) {
            coslam_status_t es = COSLAM_OK;
            fresh = observe_map(&es);
            if (fresh) {
                if (es != COSLAM_OK && es != COSLAM_E_CAPACITY) {
                    fprintf(stderr, "coslam-robot: map export failed (%s)\n", coslam_status_str(es));
                    if (observer.want_snap) {
                        snaps.save_failures++;
                    }
                } else {
                    observer.landmarks = snap.map.n_landmarks;
                    if (observer.want_snap) {
                        (void)save_snapshot_map(opt.verbose, "periodic", now);
                    }
                }
                observer.want_snap = 0;
            }
        }
        if ((observer.want_line || observer.want_file) && (fresh || now - observer.status_due_us >= OBSERVE_WAIT_US)) {
            const double cpu = cpu_seconds();
            loop.cpu_pct = now > cpu_mark_us ? 100.0 * (cpu - cpu_mark) / ((double)(now - cpu_mark_us) * 1e-6) : 0.0;
            cpu_mark = cpu;
            cpu_mark_us = now;
            loop.uptime_s = (double)(now - t_start) * 1e-6;
            loop.landmarks = observer.landmarks;
            loop.snap_writing_ms = writing.active ? (uint32_t)((now - writing.since_us) / 1000U) : 0U;
            report_status(&opt, observer.want_line, &loop);
            observer.want_line = 0;
            observer.want_file = 0;
        }

        /* the filter's deferred work in the step's idle time, while at
         * least half the period is left and parts of a merge or an export
         * remain (robot_node_idle) */
        (void)hal_clock_now_us(clock, &now);
        while (now < next && next - now > period / 2U) {
            const int more = robot_node_idle(&node);
            loop.idle_calls++;
            (void)hal_clock_now_us(clock, &now);
            if (!more) {
                break;
            }
        }
        /* the schedule: absolute deadlines; an overrun skips the missed ones */
        if (now > next) {
            const uint64_t late = now - next;
            loop.overruns++;
            if (late > loop.late_max_us) {
                loop.late_max_us = late > UINT32_MAX ? UINT32_MAX : (uint32_t)late;
            }
            next += (late / period + 1U) * period;
        }
        if (hal_clock_sleep_until_us(clock, next) != HAL_OK) {
            fprintf(stderr, "coslam-robot: the monotonic clock failed while sleeping: stopping (exit 1)\n");
            clock_failed = 1;
            break;
        }
        next += period;
    }

    /* clean stop: drives stopped, final snapshot, devices closed */
    const int sig = (int)stop_signal;
    if (sig != 0) {
        const char *name = sig == SIGTERM ? "SIGTERM"
                           : sig == SIGINT ? "SIGINT"
                           : sig == SIGHUP ? "SIGHUP"
                           : sig == SIGQUIT ? "SIGQUIT"
                           : sig == SIGUSR1 ? "SIGUSR1"
                           : sig == SIGUSR2 ? "SIGUSR2"
                           : sig == SIGALRM ? "SIGALRM"
                                            : "signal";
        fprintf(stderr, "coslam-robot: %s: stopping\n", name);
    }
    (void)robot_node_shutdown(&node);
    (void)hal_clock_now_us(clock, &now);
    for (int i = 0; i < 10; ++i) {
        /* let the drives' disable sequence go out (the node only polls the drive now) */
        next = now + period;
        (void)hal_clock_sleep_until_us(clock, next);
        (void)robot_node_step(&node);
        now = next;
    }
    /* the drives are disabled: switch their watchdog off before the
     * heartbeat stops, or every clean stop ends in its EMCY */
    (void)robot_node_release_drives(&node);
    (void)hal_clock_now_us(clock, &now);
    /* a periodic write still in flight ends first (its generation is the
     * one the final snapshot must come after) */
    int saved = -1;
    if (!finish_snapshot_write(1, FINAL_SNAPSHOT_WAIT_MS, now)) {
        final_stuck(clock);
        (void)hal_clock_now_us(clock, &now);
    } else if (!robot_snapshot_writer_started(&writer)) {
        /* no writer thread at the end of the loop (it could not be
         * started): bounded, never a write in this thread */
        saved = final_snapshot_no_writer(clock, storage_read_due);
        (void)hal_clock_now_us(clock, &now);
    } else {
        /* on the writer thread, each job waited for at most
         * FINAL_SNAPSHOT_WAIT_MS (was: the thread ended, then the read and
         * the write here, unbounded) */
        saved = final_snapshot_on_writer(clock, storage_read_due);
        (void)hal_clock_now_us(clock, &now);
    }
    loop.uptime_s = (double)(now - t_start) * 1e-6;
    loop.landmarks = observer.landmarks;
    loop.cpu_pct = 100.0 * cpu_seconds() / (loop.uptime_s > 0.0 ? loop.uptime_s : 1.0);
    /* the last map messages: acknowledged by the peers before DDS goes */
    robot_link_flush(&dev.link, 200000U);
    report_status(&opt, 1, &loop);
    robot_devices_close_all(&dev);
    fprintf(stderr, "coslam-robot: stopped after %llu steps, %lu overruns%s\n", (unsigned long long)loop.steps,
            (unsigned long)loop.overruns, saved == 0 ? "" : " (no final snapshot)");
    return clock_failed ? 1 : 0; /* a failure: systemd's Restart=on-failure starts it again */
}
