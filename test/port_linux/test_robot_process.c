/*
 * coslam-robot as a separate process, on real OS interfaces (files, a
 * missing serial device, a missing CAN interface, a missing GPIO chip):
 *   degraded      no device at all: every one is reported by name, the node
 *                 runs, status lines come, SIGTERM stops it with status 0;
 *   sigterm       with the landmark-log replay source: SIGTERM stops it
 *                 within a bound, status 0, the final snapshot is on disk,
 *                 complete, and the next start loads exactly it;
 *   observers_in_parts  a merge budget of one work unit: the status
 *                 count's and the periodic snapshot's exports go in parts
 *                 over several idle calls a step, and both still come;
 *   kill_restart  SIGKILL at seeded random moments (20 times in CI, 120 with
 *                 COSLAM_TEST_LEVEL=full), snapshots every 20 ms so that
 *                 many kills land in a write: after every kill both
 *                 generations on disk are complete (storage CRC and
 *                 snapshot CRC), every start loads the newest one (its
 *                 sequence number never goes back), no start reports a
 *                 damaged snapshot, and the map goes on growing.
 *   slow_storage  fsync blocks while a gate file exists (fsync_gate.so):
 *                 the control loop goes on stepping and reporting while a
 *                 snapshot's write is held for seconds (status lines keep
 *                 coming, no step waits for the storage, the snapshots that
 *                 fall due meanwhile are skipped and counted), the write
 *                 lands when the gate opens, and a write that never returns
 *                 costs the final snapshot but not the clean stop.
 *   no_opener_thread  pthread_create fails while a file exists
 *                 (thread_gate.so): the devices are down with that reason,
 *                 never opened in the loop's thread, the loop steps, and
 *                 they come up once threads can be made.
 *   no_writer_thread  the snapshot writer's thread cannot be started
 *                 (thread_gate.so) while fsync is held (fsync_gate.so): no
 *                 snapshot is written in the loop's thread (counted and
 *                 said instead), the loop steps, the thread is started
 *                 again at the retry period and the snapshots resume; the
 *                 final one without a thread is skipped, said, or written
 *                 on a thread made at the stop.
 *   final_stuck   the writer thread runs all along and fsync hangs at the
 *                 stop (fsync_gate.so): the final snapshot waited for at
 *                 most 5 s, said, counted, exit 0, the generations intact.
 *   start_read_stuck  the start-up read of snapshot.a hangs (fsync_gate.so's
 *                 read gate): the robot starts within 5 s and a margin
 *                 with a new map, said and counted; the read's outcome is
 *                 taken when it returns and the snapshots are saved after
 *                 it; still hung at the stop: a bounded stop.
 * Usage: test_robot_process <case> (one CTest entry per case).
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <grp.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "hal/hal_storage_linux.h"
#include "robot_snapshot.h"

/* ---- helpers ---------------------------------------------------------------- */

static uint64_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static void sleep_ms(uint64_t ms)
{
    struct timespec ts = {(time_t)(ms / 1000u), (long)(ms % 1000u) * 1000000L};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

static void make_dir(char *dir, size_t cap)
{
    snprintf(dir, cap, "/tmp/coslam-robot-test-XXXXXX");
    assert_non_null(mkdtemp(dir));
}

static void remove_dir(const char *dir)
{
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
}

/* A landmark log: the robot stands at the origin and sees six landmarks at
 * 5 Hz for 20 s (seeded noise: 2 cm, 1 deg). */
static void write_log(const char *path)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "# coslam-robot test: six landmarks seen from the origin, 5 Hz\n");
    const point2_t lm[6] = {{2.0, 0.5}, {2.5, -0.8}, {3.0, 1.2}, {1.5, -0.3}, {3.5, 0.2}, {2.2, 1.6}};
    rng_t rng;
    rng_seed(&rng, 99);
    for (int k = 0; k < 100; ++k) {
        const double t = 0.2 * k;
        for (int i = 0; i < 6; ++i) {
            const double r = hypot(lm[i].x, lm[i].y) + rng_normal(&rng, 0.0, 0.02);
            const double b = atan2(lm[i].y, lm[i].x) + rng_normal(&rng, 0.0, 0.0175);
            if (fabs(b) < 0.43) {
                fprintf(f, "Z %.3f %d %.4f %.5f\n", t, i, r, b);
            }
        }
        fprintf(f, "O %.3f 0 0 0\n", t + 0.1); /* odometry records are ignored */
    }
    fclose(f);
}

static void write_config(const char *dir, const char *body)
{
    char path[300];
    snprintf(path, sizeof path, "%s/robot.ini", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(body, f);
    fclose(f);
}

/* Start coslam-robot -c dir/robot.ini [-v] [args] as user `uid` ((uid_t)-1:
 * this process's); stderr into `err_path`. */
static pid_t spawn_robot_as(const char *dir, const char *err_path, const char *a1, const char *a2, int verbose,
                            uid_t uid)
{
    char cfg[300];
    snprintf(cfg, sizeof cfg, "%s/robot.ini", dir);
    const pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        /* a failed assertion leaves the robot behind: it goes with this
         * process, not on running (a stuck storage would keep it forever) */
        (void)prctl(PR_SET_PDEATHSIG, SIGKILL);
        const int fd = open(err_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int nul = open("/dev/null", O_WRONLY);
        if (fd < 0 || nul < 0) {
            _exit(127);
        }
        dup2(fd, 2);
        dup2(nul, 1);
        if (uid != (uid_t)-1 && (setgroups(0, NULL) != 0 || setgid((gid_t)uid) != 0 || setuid(uid) != 0 ||
                                 prctl(PR_SET_PDEATHSIG, SIGKILL) != 0)) {
            _exit(126); /* another user's credentials clear the death signal: set again */
        }
        char *argv[8];
        int n = 0;
        argv[n++] = (char *)COSLAM_ROBOT_BIN;
        argv[n++] = (char *)"-c";
        argv[n++] = cfg;
        if (verbose) argv[n++] = (char *)"-v";
        if (a1 != NULL) argv[n++] = (char *)a1;
        if (a2 != NULL) argv[n++] = (char *)a2;
        argv[n] = NULL;
        execv(COSLAM_ROBOT_BIN, argv);
        _exit(127);
    }
    return pid;
}

/* Start coslam-robot -c dir/robot.ini -v [args]; stderr into `err_path`. */
static pid_t spawn_robot(const char *dir, const char *err_path, const char *a1, const char *a2)
{
    return spawn_robot_as(dir, err_path, a1, a2, 1, (uid_t)-1);
}

/* Wait at most timeout_ms; returns the wait status, or -1 (then killed). */
static int wait_exit(pid_t pid, uint64_t timeout_ms)
{
    const uint64_t end = now_ms() + timeout_ms;
    int st = 0;
    for (;;) {
        const pid_t r = waitpid(pid, &st, WNOHANG);
        if (r == pid) {
            return st;
        }
        if (now_ms() > end) {
            kill(pid, SIGKILL);
            waitpid(pid, &st, 0);
            return -1;
        }
        sleep_ms(5);
    }
}

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    static char buf[1 << 20];
    const size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = '\0';
    fclose(f);
    return buf;
}

/* What is on disk. */
typedef struct {
    int present;        /* generations present */
    int invalid;        /* present but failing a check (storage CRC or snapshot CRC / fields) */
    uint64_t newest;    /* newest valid sequence number (0: none) */
    int landmarks;      /* of the newest */
    uint32_t obs;       /* sum of n_obs of the newest */
    int temporaries;    /* ".snapshot.?.tmp" left by a kill during a write */
    uint32_t msg_seq;   /* of the newest: last map message numbered */
    int clean_stop;     /* of the newest: written at a clean stop, no doubt about later sends */
} disk_t;

static robot_snapshot_t snap;

static disk_t scan_disk(const char *dir)
{
    disk_t d;
    memset(&d, 0, sizeof d);
    char store_dir[300];
    snprintf(store_dir, sizeof store_dir, "%s/store", dir);
    struct stat sb;
    if (stat(store_dir, &sb) != 0) {
        return d;
    }
    hal_storage_linux_t st;
    assert_int_equal(hal_storage_linux_open_reader(&st, store_dir), HAL_OK); /* the robot may hold it */
    static uint8_t buf[ROBOT_SNAPSHOT_MAX_BYTES];
    const char *names[2] = {ROBOT_SNAPSHOT_NAME_A, ROBOT_SNAPSHOT_NAME_B};
    for (int k = 0; k < 2; ++k) {
        size_t len = 0;
        const hal_status_t hs = hal_storage_read(&st.dev, names[k], buf, sizeof buf, &len);
        if (hs == HAL_E_NOT_FOUND) {
            continue;
        }
        d.present++;
        if (hs != HAL_OK || robot_snapshot_decode(buf, len, &snap) != COSLAM_OK) {
            d.invalid++;
            continue;
        }
        if (snap.seq > d.newest) {
            d.newest = snap.seq;
            d.landmarks = snap.map.n_landmarks;
            d.msg_seq = snap.msg_seq;
            d.clean_stop = snap.clean_stop;
            d.obs = 0;
            for (int i = 0; i < snap.map.n_landmarks; ++i) {
                d.obs += snap.map.lm[i].n_obs;
            }
        }
    }
    hal_storage_close(&st.dev);
    DIR *dd = opendir(store_dir);
    assert_non_null(dd);
    struct dirent *e;
    while ((e = readdir(dd)) != NULL) {
        if (strstr(e->d_name, ".tmp") != NULL) {
            d.temporaries++;
        }
    }
    closedir(dd);
    return d;
}

/* "snapshot: loaded snapshot.x seq=N" in a log: N, or 0. */
static uint64_t loaded_seq(const char *log)
{
    const char *p = strstr(log, "snapshot: loaded ");
    if (p == NULL) {
        return 0;
    }
    const char *q = strstr(p, "seq=");
    return q != NULL ? strtoull(q + 4, NULL, 10) : 0;
}

static const char *base_config =
    "[robot]\nstatus_period_s = %s\nsnapshot_period_s = %s\nretry_period_s = 0.3\n"
    "[laser]\ndevice = %s/%s\nreply_timeout_s = 0.1\n"
    "[can]\ninterface = nosuchcan0\n"
    "[gpio]\nchip = %s/no-gpiochip\n"
    "[camera]\n%s\n"
    "[storage]\ndir = %s\n"
    "[fleet]\nkey_file =\n" /* no fleet key: no link (these tests are about one robot) */
    "[filter]\ntype = %s\nparticles = 30\n";

/* The configuration, with `extra` lines after it. */
static void config_with(const char *dir, const char *laser, const char *status_s, const char *snap_s,
                        const char *camera, const char *store, const char *filter, const char *extra)
{
    char body[4096];
    snprintf(body, sizeof body, base_config, status_s, snap_s, dir, laser, dir, camera, store, filter);
    strncat(body, extra, sizeof body - strlen(body) - 1U);
    write_config(dir, body);
}

static void config(const char *dir, const char *laser, const char *status_s, const char *snap_s, const char *camera,
                   const char *store, const char *filter)
{
    config_with(dir, laser, status_s, snap_s, camera, store, filter, "");
}

/* The landmark-log replay camera (the log written to dir/lm.log, looped)
 * and the storage at dir/store: their configuration values. */
typedef struct {
    char camera[300];
    char store[300];
} replay_rig_t;

static void replay_rig(const char *dir, replay_rig_t *rig)
{
    snprintf(rig->camera, sizeof rig->camera, "replay_log = %s/lm.log\nreplay_loop = true", dir);
    snprintf(rig->store, sizeof rig->store, "%s/store", dir);
    char logp[300];
    snprintf(logp, sizeof logp, "%s/lm.log", dir);
    write_log(logp);
}

/* A fresh directory with the replay camera and a store, a Fast-SLAM 2.0
 * robot without laser (status and snapshot periods, `extra` lines), and
 * the path its stderr goes to (dir/err). */
static void replay_robot_dir(char dir[64], const char *status_s, const char *snap_s, const char *extra, char err[300])
{
    make_dir(dir, 64);
    replay_rig_t rig;
    replay_rig(dir, &rig);
    config_with(dir, "no-laser", status_s, snap_s, rig.camera, rig.store, "fastslam2", extra);
    snprintf(err, 300, "%s/err", dir);
}

/* A fresh directory and its configuration (status every 0.2 s, no
 * camera, the store at dir/store) with the text `from` replaced by `to`. */
static void edited_config(char dir[64], const char *snap_s, const char *laser, const char *filter, const char *from,
                          const char *to)
{
    make_dir(dir, 64);
    char store[300];
    snprintf(store, sizeof store, "%s/store", dir);
    char body[4096];
    snprintf(body, sizeof body, base_config, "0.2", snap_s, dir, laser, dir, "", store, filter);
    char *at = strstr(body, from);
    assert_non_null(at);
    char edited[4096];
    snprintf(edited, sizeof edited, "%.*s%s%s", (int)(at - body), body, to, at + strlen(from));
    write_config(dir, edited);
}

/* The URG emulator on a pty at dir/urg (urg_pty_bridge). */
static pid_t spawn_bridge(const char *dir)
{
    char link[300];
    snprintf(link, sizeof link, "%s/urg", dir);
    const pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        (void)prctl(PR_SET_PDEATHSIG, SIGKILL);
        execl(COSLAM_URG_BRIDGE, COSLAM_URG_BRIDGE, link, (char *)NULL);
        _exit(127);
    }
    struct stat sb;
    for (int i = 0; i < 400 && lstat(link, &sb) != 0; ++i) {
        sleep_ms(5);
    }
    assert_int_equal(lstat(link, &sb), 0);
    return pid;
}

static void stop_bridge(pid_t pid)
{
    kill(pid, SIGTERM);
    const int st = wait_exit(pid, 3000);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
}

/* SIGTERM to the robot: it must exit with status 0 within timeout_ms (its
 * log printed if not). Returns its log; *dt_ms (if not NULL) how long it
 * took. */
static const char *stop_robot_within(pid_t pid, const char *err_path, uint64_t timeout_ms, uint64_t *dt_ms)
{
    const uint64_t t0 = now_ms();
    kill(pid, SIGTERM);
    const int st = wait_exit(pid, timeout_ms);
    if (dt_ms != NULL) {
        *dt_ms = now_ms() - t0;
    }
    const char *log = slurp(err_path);
    if (!(WIFEXITED(st) && WEXITSTATUS(st) == 0)) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 0);
    return log;
}

static const char *stop_robot(pid_t pid, const char *err_path)
{
    return stop_robot_within(pid, err_path, 5000, NULL);
}

/* The last value of `key=` in the log, or -1. */
static long last_value(const char *log, const char *key)
{
    long v = -1;
    char pat[64];
    snprintf(pat, sizeof pat, " %s=", key);
    for (const char *p = strstr(log, pat); p != NULL; p = strstr(p + 1, pat)) {
        v = strtol(p + strlen(pat), NULL, 10);
    }
    return v;
}

/* ---- degraded: no device at all -------------------------------------------- */

static void degraded(void **state)
{
    (void)state;
    char dir[64];
    make_dir(dir, sizeof dir);
    /* no storage either: its parent directory does not exist */
#if COSLAM_HAVE_CAMERA
    /* the shipped colour table and range model: the camera device itself is missing */
    const char *camera = "device = /dev/no-such-video9\ncolour_table = " COSLAM_VISION_DATA_DIR
                         "/colour_lut.bin\nrange_model = " COSLAM_VISION_DATA_DIR "/range_model.txt";
#else
    const char *camera = "device = /dev/no-such-video9";
#endif
    config(dir, "no-laser", "0.4", "0.5", camera, "/nonexistent-coslam/parent/store", "fastslam2");
    char err[300];
    snprintf(err, sizeof err, "%s/err", dir);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    sleep_ms(1500);
    assert_int_equal(waitpid(pid, NULL, WNOHANG), 0); /* still running */
    const char *log = stop_robot(pid, err);
    /* each missing device by name, with what it is and why */
    assert_non_null(strstr(log, "coslam-robot: laser (URG on "));
    assert_non_null(strstr(log, "no-laser at 115200 baud): down: "));
    assert_non_null(strstr(log, "coslam-robot: can (CiA 402 drives on SocketCAN nosuchcan0): down: "));
    /* the missing bus is not a wheel's fault */
    assert_non_null(strstr(log, "drive fault 1: no CAN bus (can down, see its line)"));
    assert_null(strstr(log, "(CANopen node"));
    assert_non_null(strstr(log, "coslam-robot: gpio (bumper / e-stop / LED on "));
#if COSLAM_HAVE_CAMERA
    assert_non_null(strstr(log, "coslam-robot: camera (V4L2 /dev/no-such-video9, 320x240, markers): down: V4L2 open: "
                                "HAL_E_NOT_FOUND; localisation on odometry only; retrying every"));
#else
    assert_non_null(strstr(log, "coslam-robot: camera (/dev/no-such-video9): not available"));
#endif
    assert_non_null(strstr(log, "localisation on odometry only"));
    assert_non_null(strstr(log, "coslam-robot: link (null"));
#if COSLAM_HAVE_DDS && COSLAM_HAVE_LINK_AUTH
    assert_non_null(strstr(log, "WARNING link: off (no fleet key)"));
    assert_non_null(strstr(log, "WARNING: link: off (no fleet key)\n")); /* every status line */
#else
    assert_non_null(strstr(log, "WARNING link: off (built without"));
    assert_non_null(strstr(log, "WARNING: link: off (built without"));
#endif
    assert_non_null(strstr(log, "coslam-robot: storage (snapshots in /nonexistent-coslam/parent/store): down: "));
    assert_non_null(strstr(log, "no motion until they are back (gpio.required = true)"));
    assert_non_null(strstr(log, "no obstacle behaviour"));
    /* retried (verbose), kept running, reported */
    assert_non_null(strstr(log, "still down"));
    assert_non_null(strstr(log, "coslam-robot: status t="));
    assert_non_null(strstr(log, COSLAM_HAVE_CAMERA ? "laser=down can=down gpio=down camera=down link=absent storage=down"
                                                   : "laser=down can=down gpio=down camera=absent link=absent storage=down"));
    assert_non_null(strstr(log, "SIGTERM: stopping"));
    assert_non_null(strstr(log, "(no final snapshot)"));
    assert_null(strstr(log, "runtime error"));
    assert_null(strstr(log, "AddressSanitizer"));
    remove_dir(dir);
}

/* ---- SIGTERM: bounded stop, final snapshot -------------------------------- */

static void sigterm(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0.5", "30", "", err);
    char status_path[300];
    snprintf(status_path, sizeof status_path, "%s/status.json", dir);
    const pid_t pid2 = spawn_robot(dir, err, "--status-file", status_path);
    sleep_ms(2000);
    uint64_t dt = 0;
    const char *log = stop_robot_within(pid2, err, 5000, &dt);
    fprintf(stderr, "sigterm: exit after %llu ms\n", (unsigned long long)dt);
    assert_true(dt < 2000); /* the bound: well under a second in practice */
    const char *fin = strstr(log, "(final)");
    assert_non_null(fin);
    const char *sv = strstr(log, "snapshot: saved ");
    assert_non_null(sv);
    const disk_t d = scan_disk(dir);
    assert_int_equal(d.invalid, 0);
    assert_true(d.newest >= 1);
    assert_true(d.landmarks >= 4); /* the six landmarks, those in view */
    /* the final one is the newest on disk, and the next start loads it */
    char want[64];
    snprintf(want, sizeof want, "seq=%llu landmarks=%d (final)", (unsigned long long)d.newest, d.landmarks);
    assert_non_null(strstr(log, want));
    const char *json = slurp(status_path);
    assert_non_null(strstr(json, "\"state\": \""));
    assert_non_null(strstr(json, "\"camera\": \"up\""));
    assert_null(strstr(json, "status_dropped")); /* every pair fits the report */
    /* counters that used to reach neither the line nor the file */
    for (const char *const *k = (const char *const[]){"\"diverged\"", "\"can_errors\"", "\"mt_pending_replaced\"",
                                                      "\"mt_refused_implausible\"", "\"mt_ignored_disagreed\"",
                                                      "\"mt_weak_not_sent\"", "\"mt_send_busy\"", "\"mt_rebased\"",
                                                      "\"lm_capacity_drops\"", "\"rejected_sightings\"",
                                                      "\"numeric_faults\"", "\"urg_err_capacity\"",
                                                      "\"urg_bytes_discarded\"", "\"stalls\"", "\"stall_resets\"",
                                                      "\"health_unjudged\"", "\"can_stamps_unbelieved\"",
                                                      "\"urg_rx_search_bytes\"", "\"merge_pair_drops\"",
                                                      "\"tree_capacity_drops\"", "\"drive_odo_gaps\"",
                                                      "\"drive_saturations\"",
                                                      "\"drive_rx_overflows\"", "\"drive_rx_foreign\"",
                                                      "\"drive_hb_failures\"", "\"mh_forks\"", "\"mh_reverted\"",
                                                      "\"cekf_active_overflows\"", NULL};
         *k != NULL; ++k) {
        if (strstr(json, *k) == NULL) {
            fprintf(stderr, "status file lacks %s\n", *k);
        }
        assert_non_null(strstr(json, *k));
    }
    assert_null(strstr(log, "LIMIT status"));
    assert_int_equal(d.clean_stop, 1); /* the final one: no map sent after it */
    const pid_t pid3 = spawn_robot(dir, err, "--once", "1");
    const int st3 = wait_exit(pid3, 5000);
    assert_true(WIFEXITED(st3) && WEXITSTATUS(st3) == 0);
    log = slurp(err);
    assert_true(loaded_seq(log) == d.newest);
    assert_null(strstr(log, "not from a clean stop")); /* numbered on without a margin */
    remove_dir(dir);
}

/* ---- SIGHUP, SIGPIPE: the same clean stop ------------------------------------ */

/* A dropped SSH session (SIGHUP) stops the robot as SIGTERM does: drives
 * stopped, a final snapshot, exit 0. A dead pipe reader (SIGPIPE) does not
 * stop it at all. Before, both killed the process with the drives running
 * and no snapshot. */
static void sighup_sigpipe(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0.5", "30", "", err);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    sleep_ms(1500);
    kill(pid, SIGPIPE);
    kill(pid, SIGXFSZ);
    sleep_ms(300);
    int st = 0;
    assert_int_equal(waitpid(pid, &st, WNOHANG), 0); /* still running */
    kill(pid, SIGHUP);
    st = wait_exit(pid, 5000);
    const char *log = slurp(err);
    if (!(WIFEXITED(st) && WEXITSTATUS(st) == 0)) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 0);
    assert_non_null(strstr(log, "SIGHUP: stopping"));
    assert_non_null(strstr(log, "(final)"));
    const disk_t d = scan_disk(dir);
    assert_int_equal(d.invalid, 0);
    assert_true(d.newest >= 1);
    /* a stray SIGUSR1 (default: the process ends on the spot, wheels
     * turning) stops it cleanly too */
    const pid_t pid2 = spawn_robot(dir, err, NULL, NULL);
    sleep_ms(800);
    kill(pid2, SIGUSR1);
    st = wait_exit(pid2, 5000);
    log = slurp(err);
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 0);
    assert_non_null(strstr(log, "SIGUSR1: stopping"));
    assert_non_null(strstr(log, "(final)"));
    remove_dir(dir);
}

/* ---- limits said while the robot runs, status line off ---------------------- */

/* Sightings the filter refuses (500 m, beyond sighting_max_range_m) are
 * said on stderr within about a second although the status line is off
 * (status_period_s = 0). Before, every limit and warning line waited for a
 * status report: with none, until the robot stopped. */
static void limits_without_status(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0", "30", "", err);
    char logp[300];
    snprintf(logp, sizeof logp, "%s/lm.log", dir);
    FILE *f = fopen(logp, "w"); /* one landmark, and one sighting at 500 m a frame */
    assert_non_null(f);
    for (int k = 0; k < 50; ++k) {
        fprintf(f, "Z %.3f 0 2.0 0.1\nZ %.3f 1 500.0 0.0\nO %.3f 0 0 0\n", 0.2 * k, 0.2 * k, 0.2 * k + 0.1);
    }
    fclose(f);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    sleep_ms(2500);
    const char *log = slurp(err); /* still running */
    const int said = strstr(log, "(rejected_sightings)") != NULL;
    (void)stop_robot(pid, err);
    assert_true(said);
    remove_dir(dir);
}

/* ---- the map's observers in parts ------------------------------------------- */

/* With a merge budget of one work unit, the status count's and the periodic
 * snapshot's export cannot fit one call: it goes in parts
 * (slam_filter_export_observe) through several idle calls a step, and the
 * snapshots and status counts still come. */
static void observers_in_parts(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0.3", "0.5", "[merge]\nstep_units = 1\n", err);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    sleep_ms(2500);
    const char *log = stop_robot(pid, err);
    const long steps = last_value(log, "steps");
    const long idle = last_value(log, "idle_calls");
    const long observes = last_value(log, "observes_in_parts");
    fprintf(stderr, "observers in parts: %ld steps, %ld idle calls, %ld observer exports in parts, landmarks %ld\n",
            steps, idle, observes, last_value(log, "landmarks"));
    assert_true(observes >= 3);       /* status every 0.3 s, snapshot every 0.5 s: all in parts */
    assert_true(idle > steps);        /* several idle calls a step while parts remain */
    assert_true(last_value(log, "landmarks") >= 4);
    assert_non_null(strstr(log, "(periodic)"));
    assert_int_equal(last_value(log, "sends_forced"), 0);
    const disk_t d = scan_disk(dir);
    assert_int_equal(d.invalid, 0);
    assert_true(d.newest >= 3); /* periodic ones and the final one */
    remove_dir(dir);
}

/* ---- kill and restart ------------------------------------------------------ */

static void kill_restart(void **state)
{
    (void)state;
    char dir[64];
    make_dir(dir, sizeof dir);
    replay_rig_t rig;
    replay_rig(dir, &rig);
    /* a snapshot every 20 ms: many kills land inside a write; the laser is
     * the URG emulator on a pty, streaming across the restarts */
    config(dir, "urg", "0", "0.02", rig.camera, rig.store, "ekf");
    const pid_t bridge = spawn_bridge(dir);
    char err[300];
    snprintf(err, sizeof err, "%s/err", dir);
    const int kills = COSLAM_TEST_FULL ? 120 : 20;
    rng_t rng;
    rng_seed(&rng, 2024);
    int loads = 0;
    int before_load = 0;
    int during_write = 0;
    int torn = 0;
    uint64_t first_seq = 0;
    uint32_t first_obs = 0;
    uint64_t prev = 0;
    for (int k = 0; k < kills; ++k) {
        const disk_t before = scan_disk(dir);
        assert_int_equal(before.invalid, 0);
        assert_true(before.newest >= prev); /* never backwards */
        prev = before.newest;
        const pid_t pid = spawn_robot(dir, err, NULL, NULL);
        /* mostly short lives, some long enough for a few frames; the
         * shortest 60 ms: a start takes 45-85 ms here since coslam-robot
         * loads OpenCV for its camera (28-70 ms before), and kills before
         * the snapshot is loaded test nothing */
        const uint64_t life = k % 5 == 4 ? 600u + rng_below(&rng, 900u) : 60u + rng_below(&rng, 300u);
        sleep_ms(life);
        kill(pid, SIGKILL);
        int st = 0;
        waitpid(pid, &st, 0);
        assert_true(WIFSIGNALED(st) && WTERMSIG(st) == SIGKILL);
        const char *log = slurp(err);
        if (strstr(log, "corrupt") != NULL || strstr(log, "unreadable") != NULL) {
            torn++;
            fprintf(stderr, "kill %d: a start saw a damaged snapshot:\n%s\n", k, log);
        }
        const uint64_t got = loaded_seq(log);
        if (before.newest > 0) {
            if (got > 0) {
                loads++;
                if (got != before.newest) {
                    fprintf(stderr, "kill %d: loaded seq %llu, newest on disk was %llu\n%s\n", k,
                            (unsigned long long)got, (unsigned long long)before.newest, log);
                }
                assert_true(got == before.newest);
                if (first_seq == 0) {
                    first_seq = got;
                    first_obs = before.obs;
                }
            } else {
                /* killed before it got that far (no "snapshot:" line yet) */
                assert_null(strstr(log, "snapshot: none found"));
                before_load++;
            }
        }
        const disk_t after = scan_disk(dir);
        assert_int_equal(after.invalid, 0);
        assert_true(after.newest >= before.newest);
        during_write += after.temporaries > 0;
        if (got > 0) {
            /* started from a snapshot a kill left: its map messages go on
             * beyond those the peers may have seen, but (nothing sent:
             * no link here) the snapshots keep the number and the doubt,
             * so crash after crash adds no margin to margin */
            char want[96];
            snprintf(want, sizeof want, "map messages numbered on from %u)", ROBOT_SNAPSHOT_SEQ_MARGIN);
            assert_non_null(strstr(log, want));
            assert_int_equal(after.msg_seq, 0);
            assert_int_equal(after.clean_stop, 0);
        }
    }
    /* a last, clean run: the map went on */
    const pid_t pid = spawn_robot(dir, err, "--once", "100");
    const int st = wait_exit(pid, 10000);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    const disk_t end = scan_disk(dir);
    assert_int_equal(end.invalid, 0);
    const char *last_log = slurp(err);
    const long scans = last_value(last_log, "scans");
    stop_bridge(bridge);
    fprintf(stderr,
            "kill-restart: %d SIGKILLs, %d starts loaded the newest snapshot, %d were killed before loading, "
            "%d kills left a half-written temporary file (killed inside a snapshot write), %d torn loads; "
            "snapshot seq %llu -> %llu; landmarks %d; sightings fused %u -> %u; laser scans in the last run %ld\n",
            kills, loads, before_load, during_write, torn, (unsigned long long)first_seq,
            (unsigned long long)end.newest, end.landmarks, first_obs, end.obs, scans);
    assert_int_equal(torn, 0);
    assert_true(loads >= kills / 2);
    assert_true(end.landmarks >= 4);
    assert_true(end.obs > first_obs); /* mapping goes on across restarts */
    remove_dir(dir);
}

/* ---- the laser on a pty: the URG emulator byte for byte ------------------- */

static void laser_pty(void **state)
{
    (void)state;
    char dir[64];
    make_dir(dir, sizeof dir);
    char store[300];
    snprintf(store, sizeof store, "%s/store", dir);
    config(dir, "urg", "0.5", "30", "", store, "ekf");
    const pid_t bridge = spawn_bridge(dir);
    char err[300];
    snprintf(err, sizeof err, "%s/err", dir);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    sleep_ms(2500);
    kill(pid, SIGTERM);
    const int st = wait_exit(pid, 5000);
    stop_bridge(bridge);
    const char *log = slurp(err);
    if (!(WIFEXITED(st) && WEXITSTATUS(st) == 0) || last_value(log, "scans") < 10) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    assert_non_null(strstr(log, "/urg at 115200 baud): up"));
    assert_int_equal(last_value(log, "laser_streaming"), 0); /* after the shutdown */
    /* 10 scans per second for about 2.5 s, every one decoded */
    assert_true(last_value(log, "scans") >= 10);
    assert_true(last_value(log, "urg_scans_ok") >= 10);
    assert_int_equal(last_value(log, "scan_errors"), 0);
    assert_int_equal(last_value(log, "laser_lost"), 0);
    /* every scan message (about 1,260 bytes over the 140 degrees) was
     * looked at while the driver waited for it whole */
    assert_true(last_value(log, "urg_rx_search_bytes") >= 1000L * last_value(log, "urg_scans_ok"));
    fprintf(stderr, "laser_pty: %ld scans in 2.5 s, %ld bytes searched\n", last_value(log, "scans"),
            last_value(log, "urg_rx_search_bytes"));
    remove_dir(dir);
}

/* Poll the log at `err` every 50 ms until `key` reaches `at_least`, at most
 * `deadline_ms`: the last value seen (-1: none yet). */
static long wait_value(const char *err, const char *key, long at_least, unsigned deadline_ms)
{
    long v = -1;
    for (unsigned t = 0; t <= deadline_ms; t += 50U) {
        FILE *f = fopen(err, "r"); /* not there until the robot's first line */
        if (f != NULL) {
            fclose(f);
            v = last_value(slurp(err), key);
        }
        if (v >= at_least) {
            break;
        }
        sleep_ms(50);
    }
    return v;
}

/* ---- a carried robot: the health monitor's warning line ------------------- */

/* The six landmarks of write_log for 6 s, then the robot is carried off
 * (the wheels, absent here, report nothing) and faces a bare wall: the
 * camera's frames go on (each holds a sighting of the fleet's other robot,
 * id 1: a replay log refuses ids outside the fleet), the mapped landmarks,
 * in plain view by the map, go unseen. */
static void write_carried_log(const char *path)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "# coslam-robot test: six landmarks, then the robot is carried to a bare wall, 5 Hz\n");
    const point2_t lm[6] = {{2.0, 0.5}, {2.5, -0.8}, {3.0, 1.2}, {1.5, -0.3}, {3.5, 0.2}, {2.2, 1.6}};
    rng_t rng;
    rng_seed(&rng, 7);
    for (int k = 0; k < 100; ++k) {
        const double t = 0.2 * k;
        if (k >= 30) {
            fprintf(f, "R %.3f 1 2.0000 0.10000\n", t);
        }
        for (int i = 0; i < 6 && k < 30; ++i) {
            const double r = hypot(lm[i].x, lm[i].y) + rng_normal(&rng, 0.0, 0.02);
            const double b = atan2(lm[i].y, lm[i].x) + rng_normal(&rng, 0.0, 0.0175);
            if (fabs(b) < 0.43) {
                fprintf(f, "Z %.3f %d %.4f %.5f\n", t, i, r, b);
            }
        }
        fprintf(f, "O %.3f 0 0 0\n", t + 0.1);
    }
    fclose(f);
}

/* The warning line a diverged filter prints (once per episode), on the
 * real process: the map of the first 6 s stops explaining the sightings,
 * and the monitor says so by name, in the status line's counters too.
 * (No laser here: the wall is a story; the monitor's landmark measures
 * alone judge, by the missed fraction.) */
static void diverged_warning(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0.5", "30", "", err);
    char logp[300];
    snprintf(logp, sizeof logp, "%s/lm.log", dir);
    write_carried_log(logp);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    /* the carry is at 6 s of the log; the missed fraction of the 25-frame
     * window passes 0.8 about 21 frames (4 s) later. Until the log has
     * played 5 s nothing may be judged diverged; then wait for the line,
     * at most until the log loops back (20 s of log) */
    const long frames_before = wait_value(err, "frames", 25, 15000);
    const char *log = slurp(err);
    const long before = last_value(log, "diverged");
    const int warned_before = strstr(log, "judges the filter diverged") != NULL;
    for (int t = 0; t < 300 && strstr(slurp(err), "judges the filter diverged") == NULL; ++t) {
        if (last_value(slurp(err), "frames") >= 95) {
            break;
        }
        sleep_ms(50);
    }
    sleep_ms(300);
    log = stop_robot(pid, err);
    const char *w = strstr(log, "coslam-robot: warning: robot 0: the health monitor judges the filter diverged "
                                "(episode 1; diverged)");
    fprintf(stderr, "diverged_warning: diverged %ld at %ld frames (before the carry), %ld at the end (%ld frames); "
            "warning line %s\n",
            before, frames_before, last_value(log, "diverged"), last_value(log, "frames"),
            w != NULL ? "printed" : "missing");
    if (w == NULL) {
        fprintf(stderr, "%s\n", log);
    }
    /* read before 15 carried frames: the missed fraction of the window is
     * then at most 15 / 25, below the 0.8 that makes it diverged */
    assert_true(frames_before >= 25 && frames_before < 45);
    assert_int_equal(before, 0);
    assert_false(warned_before);
    assert_non_null(w);
    assert_true(last_value(log, "diverged") >= 1);
    /* the status line carries the filter's own find rate: the first 6 s
     * find the map where it is expected, the carried frames do not */
    fprintf(stderr, "diverged_warning: view_pairs %ld, view_misses %ld\n", last_value(log, "view_pairs"),
            last_value(log, "view_misses"));
    assert_true(last_value(log, "view_pairs") > 0);
    assert_true(last_value(log, "view_misses") > 0);
    const char *eol = strchr(w, '\n');
    assert_non_null(eol);
    assert_null(strstr(eol, "(episode 1;")); /* once per episode */
    remove_dir(dir);
}

/* ---- a laser that goes silent: its reconnects do not hold the loop --------- */

/* The laser's line goes quiet (the bridge stopped: the pty stays open, no
 * byte comes back, as from a sensor that lost power behind its cable). The
 * robot counts it lost after laser_lost_s and tries to connect again every
 * retry period. A connect that waited for its replies held the control
 * loop for the reply timeout (1 s here) at every try; it must not: no
 * step is late by half of that. When the line answers again (the bridge
 * catches up on what it owes: scans and the tries' replies, all stale by
 * then), the scans come back. The phases wait for the log, not the clock. */
static void laser_silent(void **state)
{
    (void)state;
    char dir[64];
    edited_config(dir, "30", "urg", "ekf", "reply_timeout_s = 0.1", "reply_timeout_s = 1.0");
    const pid_t bridge = spawn_bridge(dir);
    char err[300];
    snprintf(err, sizeof err, "%s/err", dir);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    const long scans_up = wait_value(err, "scans", 5, 10000);
    const long late_up = last_value(slurp(err), "late_max_us");
    kill(bridge, SIGSTOP);
    /* lost after 2 s of silence, then a try fails after 2 x 1 s */
    const long failures = wait_value(err, "laser_connect_failures", 1, 15000);
    /* the status line that counts the failed try is written before the
     * step's lateness is taken: two status periods more */
    sleep_ms(500);
    const char *log = slurp(err);
    const long late_silent = last_value(log, "late_max_us");
    const long lost = last_value(log, "laser_lost");
    const long timeouts = last_value(log, "urg_err_timeout");
    kill(bridge, SIGCONT);
    const long scans_end = wait_value(err, "scans", scans_up + 6, 15000);
    log = stop_robot(pid, err);
    stop_bridge(bridge);
    fprintf(stderr,
            "laser_silent: scans %ld when it went quiet, %ld at the end; late_max_us %ld before, %ld while silent; "
            "laser_lost %ld, connect_failures %ld (%ld at the end), urg_err_timeout %ld, urg_err_echo %ld, "
            "urg_messages_skipped %ld\n",
            scans_up, scans_end, late_up, late_silent, lost, failures, last_value(log, "laser_connect_failures"),
            timeouts, last_value(log, "urg_err_echo"), last_value(log, "urg_messages_skipped"));
    if (lost != 1 || late_silent < 0 || late_silent >= 500000 || scans_end < scans_up + 6) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(scans_up >= 5);
    /* the judgement needs a loop that was on time before the line went quiet */
    if (!(late_up >= 0 && late_up < 500000)) {
        fprintf(stderr, "laser_silent: a step was %ld us late before the line went quiet: nothing to judge\n", late_up);
    }
    assert_true(late_up >= 0 && late_up < 500000);
    assert_int_equal(lost, 1);
    assert_true(failures >= 1);                            /* a try ran into its deadline */
    assert_true(timeouts >= 1);                            /* counted by the driver */
    assert_true(late_silent >= 0 && late_silent < 500000); /* no try held the loop (1 s reply timeout) */
    assert_true(scans_end >= scans_up + 6);                /* connected again, scanning */
    remove_dir(dir);
}

/* ---- a device open that blocks holds its own slot, not the loop ----------- */

/* The robot with the camera's landmark log at dir/lm.fifo: spawned while
 * it is missing (the camera down, retried every 0.3 s), and once the loop
 * runs, made a FIFO, so that the next retry's open waits for a writer. */
static pid_t spawn_fifo_camera_robot(char dir[64], char err[300], char fifo[300])
{
    make_dir(dir, 64);
    char camera[400];
    snprintf(fifo, 300, "%s/lm.fifo", dir);
    snprintf(camera, sizeof camera, "replay_log = %s\nreplay_loop = true", fifo);
    char store[300];
    snprintf(store, sizeof store, "%s/store", dir);
    config(dir, "no-laser", "0.2", "30", camera, store, "fastslam2");
    snprintf(err, 300, "%s/err", dir);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    assert_true(wait_value(err, "steps", 20, 10000) >= 20); /* the loop runs, the camera down */
    assert_int_equal(mkfifo(fifo, 0600), 0);
    return pid;
}

/* Device opens in the loop's retries run on the device's opener thread
 * (robot_devices.h): one that takes long is said with its length, and the
 * control loop goes on meanwhile. The camera's landmark log is first
 * missing (the camera is down, retried every 0.3 s), then a FIFO: the next
 * retry's open waits for a writer, which comes 1 s later (and the log it
 * writes cannot be rewound, so that try fails); then the FIFO is replaced
 * by the log as a file, and the camera comes up. Before the openers, the
 * same run said "held the control loop for 944 ms" with a step 935,126 us
 * late. */
static void slow_open_said(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    char fifo[300];
    const pid_t pid = spawn_fifo_camera_robot(dir, err, fifo);
    const long opening = wait_value(err, "dev_opening", 1, 3000); /* a retry waits in the FIFO's open */
    const long steps_open = wait_value(err, "steps", 0, 0);
    sleep_ms(1000);
    const long steps_waiting = wait_value(err, "steps", 0, 0) - steps_open;
    char tmp[300];
    snprintf(tmp, sizeof tmp, "%s/lm.tmp", dir);
    write_log(tmp);
    int w = -1;
    for (int i = 0; i < 40 && w < 0; ++i) { /* ENXIO until the robot's open waits in it */
        w = open(fifo, O_WRONLY | O_NONBLOCK);
        if (w < 0) {
            sleep_ms(100);
        }
    }
    assert_true(w >= 0);
    /* the robot refuses the FIFO as soon as its open returns, and may close
     * it before this line arrives: EPIPE then, not a signal */
    void (*old_pipe)(int) = signal(SIGPIPE, SIG_IGN);
    const char line[] = "Z 0.0 0 2.0 0.1\n";
    const ssize_t wrote = write(w, line, sizeof line - 1);
    assert_true(wrote == (ssize_t)(sizeof line - 1) || (wrote < 0 && errno == EPIPE));
    (void)signal(SIGPIPE, old_pipe);
    close(w);
    assert_int_equal(rename(tmp, fifo), 0); /* the next retry finds the log as a file */
    const long slow = wait_value(err, "dev_slow_opens", 1, 5000);
    (void)wait_value(err, "frames", 3, 5000);
    const char *log = stop_robot(pid, err);
    const char *key = "this open attempt took ";
    const char *said = strstr(log, key);
    const long took_ms = said != NULL ? strtol(said + strlen(key), NULL, 10) : -1;
    fprintf(stderr,
            "slow_open: dev_opening %ld, %ld steps in the second after; said %s, %ld ms; dev_slow_opens %ld, "
            "dev_open_max_ms %ld, late_max_us %ld, frames %ld\n",
            opening, steps_waiting, said != NULL ? "yes" : "no", took_ms, slow, last_value(log, "dev_open_max_ms"),
            last_value(log, "late_max_us"), last_value(log, "frames"));
    if (said == NULL) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(opening >= 1); /* the camera's (the laser, CAN and GPIO are retried too) */
    assert_true(steps_waiting >= 20);                 /* the loop stepped on while the open waited */
    assert_non_null(said);
    assert_non_null(strstr(said, "on the device's opener thread: the control loop went on"));
    assert_true(took_ms >= 500);                      /* the writer came 1 s after the FIFO */
    assert_true(slow >= 1);
    assert_true(last_value(log, "dev_open_max_ms") >= took_ms);
    assert_true(last_value(log, "late_max_us") < 500000); /* no step waited for it (944 ms before) */
    assert_null(strstr(log, "held the control loop"));
    assert_non_null(strstr(log, ": back up after "));
    assert_true(last_value(log, "frames") >= 3);      /* and then the camera came up */
    /* the attempt that opened the FIFO is refused by name ("read error" before) */
    assert_non_null(strstr(log, "lm.fifo: not a regular file (a FIFO): a replay log must be a file (it is checked "
                                "whole, then rewound)"));
    assert_null(strstr(log, "lm.fifo: read error"));
    remove_dir(dir);
}

/* An open that never returns (a FIFO with no writer: a hung device) is said
 * after ROBOT_DEVICES_HUNG_OPEN_MS, keeps only its own device down, and does
 * not keep the robot from stopping: the stop waits for it 1 s, says so and
 * exits 0. */
static void hung_open_left(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    char fifo[300];
    const pid_t pid = spawn_fifo_camera_robot(dir, err, fifo);
    const long hung = wait_value(err, "dev_hung_opens", 1, 10000);
    uint64_t stop_ms = 0U;
    const char *log = stop_robot_within(pid, err, 5000, &stop_ms);
    fprintf(stderr, "hung_open: dev_hung_opens %ld, dev_opening %ld, late_max_us %ld; stop %llu ms\n", hung,
            last_value(log, "dev_opening"), last_value(log, "late_max_us"), (unsigned long long)stop_ms);
    assert_int_equal(hung, 1);
    assert_non_null(strstr(log, "an open attempt has run for 5 s and not returned"));
    assert_true(last_value(log, "dev_opening") >= 1); /* the camera's, still running (others may be) */
    assert_true(last_value(log, "late_max_us") < 500000);
    assert_non_null(strstr(log, "left to the process's exit"));
    assert_true(stop_ms < 4000);
    remove_dir(dir);
}

/* The start-up's first opens run on the openers too, bounded: the landmark
 * log a FIFO that never gets a writer (any open that blocks) leaves the
 * camera down, said, and the robot starts and runs without it. Before, the
 * start-up opened in the main thread, and the FIFO's open held it, no step
 * ever ran, until a signal. */
static void start_open_fifo(void **state)
{
    (void)state;
    char dir[64];
    make_dir(dir, sizeof dir);
    char fifo[300];
    snprintf(fifo, sizeof fifo, "%s/lm.fifo", dir);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    char camera[400];
    snprintf(camera, sizeof camera, "replay_log = %s\nreplay_loop = true", fifo);
    char store[300];
    snprintf(store, sizeof store, "%s/store", dir);
    config(dir, "no-laser", "0.2", "30", camera, store, "fastslam2");
    char err[300];
    snprintf(err, sizeof err, "%s/err", dir);
    const uint64_t t0 = now_ms();
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    const long steps = wait_value(err, "steps", 20, 8000);
    const uint64_t took_ms = now_ms() - t0;
    uint64_t stop_ms = 0U;
    const char *log = stop_robot_within(pid, err, 5000, &stop_ms);
    fprintf(stderr, "start_open_fifo: %ld steps %llu ms after the spawn; dev_opening %ld; stop %llu ms\n", steps,
            (unsigned long long)took_ms, last_value(log, "dev_opening"), (unsigned long long)stop_ms);
    if (steps < 20) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(steps >= 20); /* the loop runs */
    assert_non_null(strstr(log, "coslam-robot: camera (landmark-log replay "));
    assert_non_null(strstr(log, "down: its open has not returned within 2000 ms of the start (a FIFO without a "
                                "writer? a hung device?): the robot starts without it"));
    assert_non_null(strstr(log, "camera=down"));
    assert_true(last_value(log, "dev_opening") >= 1);
    assert_non_null(strstr(log, "snapshot: none found: starting a new map")); /* the storage opened meanwhile */
    assert_non_null(strstr(log, "left to the process's exit"));                /* the stop did not wait for it */
    assert_true(stop_ms < 4000);
    remove_dir(dir);
}

/* ---- a storage that comes back slow to read -------------------------------- */

static pid_t spawn_robot_shimmed(const char *dir, const char *err, const char *var, const char *path, int verbose);

/* The storage comes back (its directory appears) while its newest
 * generation cannot be read at once: snapshot.a (not a snapshot: damaged)
 * is held in the read's fstat while a gate file exists (fsync_gate.so,
 * COSLAM_TEST_READ_GATE), as a medium that has just returned may be slow.
 * (It was a FIFO, whose open waited for a writer, until the storage's
 * opens became non-blocking: a FIFO is now refused at once.) The read
 * runs on the writer thread: the loop goes on, the status shows the read in
 * flight (snap_writing_ms), a periodic snapshot meanwhile is skipped and
 * said; once the read returns, the damaged generation is said and this
 * run's snapshots are saved. (Before, the read ran in the loop: the step
 * waited as long as the FIFO had no writer.) */
static void storage_back_read(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    make_dir(dir, sizeof dir);
    char mnt[200];
    char store[300];
    snprintf(mnt, sizeof mnt, "%s/mnt", dir);
    snprintf(store, sizeof store, "%s/store", mnt); /* no mnt/: the storage is down (not made) */
    config(dir, "no-laser", "0.2", "1", "", store, "fastslam2");
    snprintf(err, sizeof err, "%s/err", dir);
    char gate[300];
    snprintf(gate, sizeof gate, "%s/read.gate", dir);
    FILE *g = fopen(gate, "w");
    assert_non_null(g);
    fclose(g);
    const pid_t pid = spawn_robot_shimmed(dir, err, "COSLAM_TEST_READ_GATE", gate, 1);
    assert_true(wait_value(err, "steps", 20, 10000) >= 20); /* the loop runs, the storage down */
    char blob[400];
    snprintf(blob, sizeof blob, "%s/snapshot.a", store);
    assert_int_equal(mkdir(mnt, 0700), 0);
    assert_int_equal(mkdir(store, 0700), 0);
    FILE *b = fopen(blob, "w");
    assert_non_null(b);
    fputs("not a snapshot\n", b);
    fclose(b);
    const long reading = wait_value(err, "snap_writing_ms", 1500, 6000); /* the read waits in the gate */
    const long skips = wait_value(err, "snap_busy_skips", 1, 3000);
    assert_int_equal(unlink(gate), 0); /* that releases the read */
    const long saves = wait_value(err, "snap_saves", 1, 5000);
    const char *log = stop_robot(pid, err);
    const char *key = "storage back; none on disk (read in ";
    const char *said = strstr(log, key);
    const long read_ms = said != NULL ? strtol(said + strlen(key), NULL, 10) : -1;
    fprintf(stderr,
            "storage_back_read: snap_writing_ms %ld while the read waited, snap_busy_skips %ld, read said %ld ms, "
            "snap_saves %ld, late_max_us %ld\n",
            reading, skips, read_ms, saves, last_value(log, "late_max_us"));
    if (said == NULL) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(reading >= 1500);
    assert_true(skips >= 1);
    assert_non_null(strstr(log, "the read of the storage that came back has run for"));
    assert_non_null(strstr(log, "snapshot.a unreadable (HAL_E_CORRUPT): damaged, not used"));
    assert_non_null(said);
    assert_true(read_ms >= 1500);
    assert_true(saves >= 1);
    assert_true(last_value(log, "late_max_us") < 500000); /* no step waited for the read */
    remove_dir(dir);
}

/* ---- a storage down at the stop; a storage another robot holds ------------- */

/* dir/robot.ini with its retry period replaced (the base's is 0.3 s). */
static void set_retry_period(const char *dir, const char *period)
{
    char path[300];
    snprintf(path, sizeof path, "%s/robot.ini", dir);
    const char *text = slurp(path);
    const char *at = strstr(text, "retry_period_s = 0.3\n");
    assert_non_null(at);
    char body[4096];
    snprintf(body, sizeof body, "%.*sretry_period_s = %s\n%s", (int)(at - text), text, period,
             at + strlen("retry_period_s = 0.3\n"));
    write_config(dir, body);
}

/* Both generations unwritable (directories where the blobs go): the first
 * periodic write fails and the storage is down until its retry, 30 s
 * later. The medium is mended before the stop: the stop tries the storage
 * again at once and writes the final snapshot. (Before: "storage down,
 * final snapshot not written".) */
static void final_snapshot_reopens_storage(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    make_dir(dir, sizeof dir);
    char store[300];
    snprintf(store, sizeof store, "%s/store", dir);
    char blob_a[400];
    char blob_b[400];
    snprintf(blob_a, sizeof blob_a, "%s/snapshot.a", store);
    snprintf(blob_b, sizeof blob_b, "%s/snapshot.b", store);
    assert_int_equal(mkdir(store, 0700), 0);
    assert_int_equal(mkdir(blob_a, 0700), 0);
    assert_int_equal(mkdir(blob_b, 0700), 0);
    config(dir, "no-laser", "0.2", "0.5", "", store, "fastslam2");
    set_retry_period(dir, "30");
    snprintf(err, sizeof err, "%s/err", dir);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    const long failures = wait_value(err, "snap_failures", 1, 10000);
    assert_true(failures >= 1);
    assert_int_equal(rmdir(blob_a), 0);
    assert_int_equal(rmdir(blob_b), 0);
    const char *log = stop_robot(pid, err);
    fprintf(stderr, "final_reopen: snap_failures %ld before the stop\n", failures);
    if (strstr(log, "storage back for the final snapshot") == NULL) {
        fprintf(stderr, "%s\n", log);
    }
    assert_non_null(strstr(log, "storage back for the final snapshot"));
    /* the failed write said with the storage's status and the OS's reason
     * (it was "(E_UNSUPPORTED, storage HAL_E_IO)" for any failure) */
    assert_non_null(strstr(log, "periodic snapshot not written to snapshot."));
    assert_non_null(strstr(log, ": Is a directory (HAL_E_IO)\n"));
    assert_non_null(strstr(log, "down: the snapshot write failed: Is a directory (HAL_E_IO)"));
    assert_null(strstr(log, "(E_UNSUPPORTED, storage"));
    assert_non_null(strstr(log, "(final)"));
    assert_null(strstr(log, "(no final snapshot)"));
    const disk_t d = scan_disk(dir);
    assert_int_equal(d.invalid, 0);
    assert_true(d.newest >= 1);
    remove_dir(dir);
}

/* Two robots on one storage directory would replace each other's
 * temporaries and interleave their generations: the second is refused the
 * directory (its storage down, said with the reason), the first keeps it. */
static void storage_held_by_another_robot(void **state)
{
    (void)state;
    char dir_a[64];
    char dir_b[64];
    char err_a[300];
    char err_b[300];
    make_dir(dir_a, sizeof dir_a);
    make_dir(dir_b, sizeof dir_b);
    char store[300];
    snprintf(store, sizeof store, "%s/store", dir_a);
    config(dir_a, "no-laser", "0.2", "0.5", "", store, "fastslam2");
    config(dir_b, "no-laser", "0.2", "0.5", "", store, "fastslam2");
    snprintf(err_a, sizeof err_a, "%s/err", dir_a);
    snprintf(err_b, sizeof err_b, "%s/err", dir_b);
    const pid_t a = spawn_robot(dir_a, err_a, NULL, NULL);
    assert_true(wait_value(err_a, "snap_saves", 1, 10000) >= 1);
    const pid_t b = spawn_robot(dir_b, err_b, NULL, NULL);
    assert_true(wait_value(err_b, "steps", 20, 10000) >= 20);
    char *log_b = strdup(stop_robot(b, err_b)); /* stop_robot's text is overwritten by the next */
    assert_non_null(log_b);
    const char *log_a = stop_robot(a, err_a);
    if (strstr(log_b, "locked by another process") == NULL) {
        fprintf(stderr, "%s\n", log_b);
    }
    assert_non_null(strstr(log_b, "locked by another process"));
    assert_int_equal(last_value(log_b, "snap_saves"), 0);
    assert_non_null(strstr(log_b, "(no final snapshot)"));
    assert_null(strstr(log_a, "locked by another process"));
    assert_non_null(strstr(log_a, "(final)"));
    const disk_t d = scan_disk(dir_a);
    assert_int_equal(d.invalid, 0);
    assert_true(d.newest >= 2);
    free(log_b);
    remove_dir(dir_b);
    remove_dir(dir_a);
}

/* ---- a storage that blocks ------------------------------------------------- */

static void touch(const char *path)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fclose(f);
}

/* The robot with the shim `so` preloaded (fsync_gate.so, thread_gate.so),
 * its variable `var` set to `path` (verbose: with -v). */
static pid_t spawn_robot_preloaded(const char *dir, const char *err, const char *so, const char *var,
                                   const char *path, int verbose)
{
    static char asan[512];
    const char *old = getenv("ASAN_OPTIONS");
    /* the shim comes before the sanitizer runtime in a SANITIZE=1 build */
    snprintf(asan, sizeof asan, "%s%sverify_asan_link_order=0", old != NULL ? old : "", old != NULL ? ":" : "");
    static char old_asan[512];
    snprintf(old_asan, sizeof old_asan, "%s", old != NULL ? old : "");
    setenv("ASAN_OPTIONS", asan, 1);
    setenv("LD_PRELOAD", so, 1);
    setenv(var, path, 1);
    const pid_t pid = spawn_robot_as(dir, err, NULL, NULL, verbose, (uid_t)-1);
    unsetenv("LD_PRELOAD");
    unsetenv(var);
    if (old_asan[0] != '\0') {
        setenv("ASAN_OPTIONS", old_asan, 1);
    } else {
        unsetenv("ASAN_OPTIONS");
    }
    return pid;
}

/* spawn_robot with fsync_gate.so preloaded, its variable `var` set to `path`. */
static pid_t spawn_robot_shimmed(const char *dir, const char *err, const char *var, const char *path, int verbose)
{
    return spawn_robot_preloaded(dir, err, COSLAM_FSYNC_GATE, var, path, verbose);
}

/* spawn_robot with fsync held while `gate` exists (fsync_gate.so). */
static pid_t spawn_robot_gated(const char *dir, const char *err, const char *gate)
{
    return spawn_robot_shimmed(dir, err, "COSLAM_TEST_FSYNC_GATE", gate, 1);
}

/* spawn_robot_gated, the gate shut as soon as the storage is up (said at
 * start-up, before the loop's first snapshot): the storage open's probe
 * file is fsync'ed too, and a gate shut before would hold that instead. */
static pid_t spawn_robot_gated_once_up(const char *dir, const char *err, const char *gate)
{
    (void)unlink(err); /* not the last run's line */
    const pid_t pid = spawn_robot_gated(dir, err, gate);
    for (int i = 0; i < 2000; ++i) {
        FILE *f = fopen(err, "r");
        if (f != NULL) {
            fclose(f);
            if (strstr(slurp(err), "/store): up\n") != NULL) {
                break;
            }
        }
        sleep_ms(2);
    }
    touch(gate);
    return pid;
}

static void slow_storage(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0.2", "0.3", "", err);
    char gate[300];
    snprintf(gate, sizeof gate, "%s/gate", dir);

    /* the first periodic snapshot (0.3 s) is held at its fsync for seconds */
    pid_t pid = spawn_robot_gated_once_up(dir, err, gate);
    assert_int_equal(last_value(slurp(err), "snap_saves"), -1); /* before the first status line and snapshot */
    sleep_ms(2500);
    const char *log = slurp(err);
    const long steps = last_value(log, "steps");
    const long writing = last_value(log, "snap_writing_ms");
    const long skips = last_value(log, "snap_busy_skips");
    const long late = last_value(log, "late_max_us");
    fprintf(stderr, "slow storage: %ld steps, write in flight %ld ms, %ld snapshots skipped, late_max_us %ld\n", steps,
            writing, skips, late);
    assert_true(writing >= 1000);    /* status lines came while the write was held */
    assert_true(steps >= 100);       /* and the loop stepped */
    assert_true(late >= 0 && late < 1000000); /* no step waited for the storage (held 2 s) */
    assert_true(skips >= 2);
    assert_non_null(strstr(log, "periodic snapshot skipped"));
    assert_int_equal(last_value(log, "snap_saves"), 0);
    assert_int_equal(scan_disk(dir).newest, 0); /* nothing renamed into place yet */

    /* the gate opens: the held write lands, the next ones follow */
    assert_int_equal(unlink(gate), 0);
    sleep_ms(800);
    log = stop_robot(pid, err);
    const char *first = strstr(log, "saved snapshot.a seq=1 ");
    assert_non_null(first);
    const char *w = strstr(first, "(periodic) in ");
    assert_non_null(w);
    const double held_ms = strtod(w + 14, NULL);
    fprintf(stderr, "slow storage: the held write took %.0f ms\n", held_ms);
    assert_true(held_ms >= 1500.0);
    disk_t d = scan_disk(dir);
    assert_int_equal(d.invalid, 0);
    assert_true(d.newest >= 2);
    char want[64];
    snprintf(want, sizeof want, "seq=%llu landmarks=%d (final)", (unsigned long long)d.newest, d.landmarks);
    assert_non_null(strstr(log, want));

    /* a write that never returns: no final snapshot, but a clean stop */
    const uint64_t before = d.newest;
    pid = spawn_robot_gated_once_up(dir, err, gate);
    sleep_ms(1000);
    uint64_t dt = 0;
    log = stop_robot_within(pid, err, 10000, &dt); /* the final snapshot waits 5 s for the stuck write */
    fprintf(stderr, "slow storage: stuck write, exit after %llu ms\n", (unsigned long long)dt);
    assert_true(loaded_seq(log) == before);
    assert_non_null(strstr(log, "does not return (storage stuck): no final snapshot"));
    assert_non_null(strstr(log, "(no final snapshot)"));
    assert_int_equal(unlink(gate), 0);
    d = scan_disk(dir);
    assert_int_equal(d.invalid, 0);
    assert_true(d.newest == before); /* the generations on disk as they were */
    remove_dir(dir);
}

/* ---- a storage directory that cannot be written ---------------------------- */

/* A fresh directory for a robot without laser or camera, its storage at
 * dir/store (not made), Fast-SLAM 2.0 (status and snapshot periods), and
 * the path its stderr goes to (dir/err). */
static void store_robot_dir(char dir[64], char store[300], const char *status_s, const char *snap_s, char err[300])
{
    make_dir(dir, 64);
    snprintf(store, 300, "%s/store", dir);
    config(dir, "no-laser", status_s, snap_s, "", store, "fastslam2");
    snprintf(err, 300, "%s/err", dir);
}

/* How often `needle` is in `text`. */
static int count_of(const char *text, const char *needle)
{
    int n = 0;
    for (const char *p = strstr(text, needle); p != NULL; p = strstr(p + 1, needle)) {
        n++;
    }
    return n;
}

/* A storage directory that opens but takes no file (read-only; as root,
 * whom a mode does not stop, the robot runs as nobody): down once, said
 * with the OS's reason, and retried on the retry period without a word
 * (it went up and down at every snapshot, said each time); writable
 * again, it comes back once and the snapshots are saved. Without -v:
 * what an operator sees. */
static void storage_read_only_steady(void **state)
{
    (void)state;
    char dir[64];
    char store[300];
    char err[300];
    store_robot_dir(dir, store, "0.2", "0.3", err); /* retry every 0.3 s, snapshot every 0.3 s */
    assert_int_equal(chmod(dir, 0755), 0); /* nobody reads the configuration */
    assert_int_equal(mkdir(store, 0755), 0);
    assert_int_equal(chmod(store, 0555), 0);
    const pid_t pid = spawn_robot_as(dir, err, NULL, NULL, 0, geteuid() == 0 ? (uid_t)65534 : (uid_t)-1);
    /* about ten retries and ten periodic snapshots while it cannot be written */
    assert_true(wait_value(err, "snap_failures", 10, 15000) >= 10);
    char down[400];
    snprintf(down, sizeof down, "coslam-robot: storage (snapshots in %s): down: cannot write in the directory: "
             "Permission denied", store);
    char *ro = strdup(slurp(err));
    assert_non_null(ro);
    assert_int_equal(chmod(store, 0777), 0);
    assert_true(wait_value(err, "snap_saves", 1, 10000) >= 1);
    const char *log = stop_robot(pid, err);
    char storage[400];
    snprintf(storage, sizeof storage, "coslam-robot: storage (snapshots in %s): ", store);
    fprintf(stderr, "storage_read_only: %d storage lines while read-only, %ld failed snapshots\n",
            count_of(ro, storage), last_value(ro, "snap_failures"));
    if (count_of(ro, down) != 1 || count_of(ro, storage) != 1) {
        fprintf(stderr, "%s\n", ro);
    }
    assert_int_equal(count_of(ro, down), 1);
    assert_int_equal(count_of(ro, storage), 1); /* nothing else about it: not up, not down again */
    assert_null(strstr(ro, "storage back"));
    assert_true(last_value(ro, "snap_failures") >= 10);
    assert_non_null(strstr(ro, " storage=down "));
    assert_null(strstr(ro, " storage=up "));
    /* writable again: back once, saved, the final snapshot written */
    assert_int_equal(count_of(log, "back up after "), 1);
    assert_null(strstr(log, "(no final snapshot)"));
    const disk_t d = scan_disk(dir);
    assert_int_equal(d.invalid, 0);
    assert_true(d.newest >= 1);
    free(ro);
    remove_dir(dir);
}

/* ---- the status file -------------------------------------------------------- */

/* A --status-file that cannot be written (its directory is missing) is
 * said once, with the path and the OS's reason, then counted
 * (status_file_failures, in the status line and the file) instead of said
 * every period, as it was; the write that works again is said once. */
static void status_file_failures_counted(void **state)
{
    (void)state;
    char dir[64];
    char store[300];
    char err[300];
    store_robot_dir(dir, store, "0.1", "30", err);
    char sub[300];
    snprintf(sub, sizeof sub, "%s/monitor", dir);
    char path[320];
    snprintf(path, sizeof path, "%s/status.json", sub);
    const pid_t pid = spawn_robot(dir, err, "--status-file", path);
    const long failing = wait_value(err, "status_file_failures", 5, 10000);
    assert_true(failing >= 5);
    assert_int_equal(mkdir(sub, 0755), 0);
    struct stat sb;
    for (int i = 0; i < 100 && stat(path, &sb) != 0; ++i) {
        sleep_ms(50);
    }
    assert_int_equal(stat(path, &sb), 0);
    sleep_ms(500); /* a few more periods, written */
    char *log = strdup(stop_robot(pid, err));
    assert_non_null(log);
    char said[512];
    snprintf(said, sizeof said, "coslam-robot: status file %s: cannot write: No such file or directory", path);
    fprintf(stderr, "status_file: %ld failures before the directory came; %d lines about the file\n", failing,
            count_of(log, "status file "));
    if (count_of(log, said) != 1) {
        fprintf(stderr, "%s\n", log);
    }
    assert_int_equal(count_of(log, said), 1);
    assert_int_equal(count_of(log, " written again after "), 1);
    assert_int_equal(count_of(log, "status file "), 2);
    assert_true(last_value(log, "status_file_failures") >= failing);
    const char *json = slurp(path);
    const char *k = strstr(json, "\"status_file_failures\": ");
    assert_non_null(k);
    assert_true(strtol(k + strlen("\"status_file_failures\": "), NULL, 10) >= failing);
    free(log);
    remove_dir(dir);
}

/* No CAN configured ([can] interface empty): the drives' bring-up fails
 * on the missing bus, which the node counts once as a drive fault; it was
 * printed as "drive fault 1: wheel 0 (CANopen node 1): BUS, EMCY code
 * 0x0000 ...", a drive's fault on a robot that has no drives. Now the
 * start-up says once that no CAN is configured, and no drive fault line
 * comes, however many retry periods pass. */
static void no_can_said_once(void **state)
{
    (void)state;
    char dir[64];
    edited_config(dir, "0", "no-laser", "fastslam2", "interface = nosuchcan0\n", "interface =\n");
    char err[300];
    snprintf(err, sizeof err, "%s/err", dir);
    const pid_t pid = spawn_robot(dir, err, NULL, NULL);
    assert_true(wait_value(err, "node_steps", 150, 10000) >= 150); /* several retry periods (0.3 s) */
    const char *log = stop_robot(pid, err);
    assert_int_equal(count_of(log, "coslam-robot: can: not configured\n"), 1);
    assert_int_equal(count_of(log, "no CAN configured ([can] interface is empty): no drives: no motion, no "
                                   "odometry (not a fault: drive_faults stays 0)"),
                     1);
    assert_int_equal(count_of(log, "drive fault"), 0);
    assert_null(strstr(log, "EMCY"));
    assert_non_null(strstr(log, " can=absent "));
    assert_int_equal(last_value(log, "drive_faults"), 0); /* no drives on purpose: no fault (was 1) */
    assert_int_equal(last_value(log, "drive_errors"), 0);
    remove_dir(dir);
}

/* One run of a medium whose fsync fails while dir/fsync-fails exists
 * (fsync_gate.so; with `above`, only for files of more than that many
 * bytes): a working medium first, then ten snapshot periods failing, then
 * working again until one more save. */
typedef struct {
    char dir[64];
    char storage[400]; /* the start of the storage's lines */
    char *bad;         /* the log while fsync failed (malloc'ed) */
    const char *log;   /* the whole log */
    size_t before;     /* where the failing part began in the log */
    long failures;     /* snap_failures while it failed */
} fsync_run_t;

static void fsync_failing_run(fsync_run_t *r, const char *above)
{
    make_dir(r->dir, sizeof r->dir);
    char store[300];
    snprintf(store, sizeof store, "%s/store", r->dir);
    config(r->dir, "no-laser", "0.2", "0.3", "", store, "fastslam2"); /* retry every 0.3 s, snapshot every 0.3 s */
    char err[300];
    snprintf(err, sizeof err, "%s/err", r->dir);
    char fail[300];
    snprintf(fail, sizeof fail, "%s/fsync-fails", r->dir);
    if (above != NULL) {
        setenv("COSLAM_TEST_FSYNC_FAIL_ABOVE", above, 1);
    }
    const pid_t pid = spawn_robot_shimmed(r->dir, err, "COSLAM_TEST_FSYNC_FAIL", fail, 0); /* without -v */
    unsetenv("COSLAM_TEST_FSYNC_FAIL_ABOVE");
    assert_true(wait_value(err, "snap_saves", 1, 10000) >= 1); /* a working medium first */
    r->before = strlen(slurp(err));
    touch(fail);
    r->failures = wait_value(err, "snap_failures", 10, 15000); /* ten snapshot periods, ten retries */
    r->bad = strdup(slurp(err) + r->before);
    assert_non_null(r->bad);
    assert_int_equal(unlink(fail), 0);
    const long saves = last_value(r->bad, "snap_saves");
    assert_true(wait_value(err, "snap_saves", saves + 1, 10000) > saves);
    r->log = stop_robot(pid, err);
    snprintf(r->storage, sizeof r->storage, "coslam-robot: storage (snapshots in %s): ", store);
    if (count_of(r->bad, "back up after ") != 0 || count_of(r->bad, r->storage) > 2) {
        fprintf(stderr, "%s\n", r->bad);
    }
}

/* A medium that takes the bytes but fails their fsync (fsync_gate.so: EIO
 * while dir/fsync-fails exists) goes down once, said with "fsync", and
 * stays down: the retry's probe file is fsync'ed too. Before, the probe
 * was not, so every retry brought it "back up", and every snapshot's write
 * took it down again: two lines a snapshot period. The fsync failures are
 * counted (storage_fsync_failures). When fsync works again: back once. */
static void storage_fsync_fails_steady(void **state)
{
    (void)state;
    fsync_run_t r;
    fsync_failing_run(&r, NULL);
    const char *bad = r.bad;
    fprintf(stderr, "storage_fsync_fails: %d storage lines while fsync failed (%d back up), snap_failures %ld, "
            "storage_fsync_failures %ld\n",
            count_of(bad, r.storage), count_of(bad, "back up after "), r.failures,
            last_value(bad, "storage_fsync_failures"));
    assert_true(r.failures >= 10);
    assert_int_equal(count_of(bad, "back up after "), 0); /* no flapping */
    assert_non_null(strstr(bad, "snapshot not written to snapshot."));
    assert_non_null(strstr(bad, ": fsync: Input/output error (HAL_E_IO)"));
    assert_non_null(strstr(bad, "down: the snapshot write failed: fsync: Input/output error"));
    /* the first retry says why once; nothing else about it while it lasts */
    assert_int_equal(count_of(bad, "still down (cannot write in the directory: fsync: Input/output error (the "
                                   "probe file .coslam-write-probe)"), 1);
    assert_true(count_of(bad, r.storage) <= 2);
    assert_true(last_value(bad, "storage_fsync_failures") >= 5); /* the write, then every retry's probe */
    assert_non_null(strstr(bad, " storage=down "));
    assert_int_equal(count_of(r.log + r.before, "back up after "), 1); /* fsync works again: back once */
    assert_true(last_value(r.log, "storage_fsync_failures") >= last_value(bad, "storage_fsync_failures"));
    free(r.bad);
    remove_dir(r.dir);
}

/* A medium that takes a small write but fails larger ones at fsync
 * (fsync_gate.so: EIO for a file of more than 64 bytes while
 * dir/fsync-fails exists): the storage's one-byte probe file works, every
 * snapshot (over 200 bytes) does not. Before, every retry's probe brought
 * the storage "back up" and every snapshot took it down again: flapping,
 * two lines a period. Now, after a failed save, a retry comes back only
 * when a save of that size works: down once, said once why, counted
 * (storage_save_probes_failed); when large fsyncs work again: back once. */
static void storage_big_fsync_fails_steady(void **state)
{
    (void)state;
    fsync_run_t r;
    fsync_failing_run(&r, "64");
    const char *bad = r.bad;
    fprintf(stderr, "storage_big_fsync_fails: %d storage lines while large fsyncs failed (%d back up), "
            "snap_failures %ld, storage_save_probes_failed %ld, storage_fsync_failures %ld\n",
            count_of(bad, r.storage), count_of(bad, "back up after "), r.failures,
            last_value(bad, "storage_save_probes_failed"), last_value(bad, "storage_fsync_failures"));
    assert_true(r.failures >= 10);
    assert_int_equal(count_of(bad, "back up after "), 0); /* no flapping (5 before) */
    assert_non_null(strstr(bad, "down: the snapshot write failed: fsync: Input/output error"));
    /* the first retry says why once; nothing else about it while it lasts */
    assert_int_equal(count_of(bad, "still down (a save of "), 1);
    assert_non_null(strstr(bad, "(the size of the snapshot that failed) still fails: fsync: Input/output error "
                                "(HAL_E_IO); the probe file alone works: back when such a save works)"));
    assert_true(count_of(bad, r.storage) <= 2);
    assert_true(last_value(bad, "storage_save_probes_failed") >= 5); /* every retry's save */
    assert_true(last_value(bad, "storage_fsync_failures") >= 5);
    assert_non_null(strstr(bad, " storage=down "));
    assert_int_equal(count_of(r.log + r.before, "back up after "), 1); /* large fsyncs work again: back once */
    assert_null(strstr(r.log + r.before, "coslam-save-probe:")); /* nothing left to say about the probe blob */
    free(r.bad);
    remove_dir(r.dir);
}

/* ---- no thread can be made ------------------------------------------------- */

/* 1 if the last status line of `log` holds `needle` (" camera=up"). */
static int last_status_has(const char *log, const char *needle)
{
    const char *line = NULL;
    for (const char *p = strstr(log, "coslam-robot: status "); p != NULL; p = strstr(p + 1, "coslam-robot: status ")) {
        line = p;
    }
    if (line == NULL) {
        return 0;
    }
    const char *end = strchr(line, '\n');
    const char *at = strstr(line, needle);
    return at != NULL && (end == NULL || at < end);
}

/* No thread can be made from the start (thread_gate.so: pthread_create
 * fails with EAGAIN while dir/no-threads exists), so no device's opener
 * thread starts, and the camera's landmark log is a FIFO that never gets a
 * writer (an open that never returns). Before, a slot whose opener could
 * not be started opened in the caller's thread: the FIFO's open held the
 * start-up, no step ever ran. Now each such device is down, said with the
 * thread's failure, counted (dev_opener_failures) and tried again every
 * retry period without ever opening in the loop's thread; the loop steps.
 * The log then becomes a file and threads can be made again: the openers
 * start at the next retry, and the camera and the storage come up. */
static void no_opener_thread(void **state)
{
    (void)state;
    char dir[64];
    make_dir(dir, sizeof dir);
    char fifo[300];
    snprintf(fifo, sizeof fifo, "%s/lm.fifo", dir);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    char camera[400];
    snprintf(camera, sizeof camera, "replay_log = %s\nreplay_loop = true", fifo);
    char store[300];
    snprintf(store, sizeof store, "%s/store", dir);
    config(dir, "no-laser", "0.2", "30", camera, store, "fastslam2");
    char gate[300];
    snprintf(gate, sizeof gate, "%s/no-threads", dir);
    touch(gate);
    char err[300];
    snprintf(err, sizeof err, "%s/err", dir);
    const uint64_t t0 = now_ms();
    const pid_t pid = spawn_robot_preloaded(dir, err, COSLAM_THREAD_GATE, "COSLAM_TEST_THREAD_FAIL", gate, 1);
    const long steps = wait_value(err, "steps", 20, 8000);
    const uint64_t took_ms = now_ms() - t0;
    const long failed_first = wait_value(err, "dev_opener_failures", 1, 2000);
    sleep_ms(1000); /* three retry periods (0.3 s), still no thread */
    const long failed_later = wait_value(err, "dev_opener_failures", failed_first + 1, 2000);
    char *gated = strdup(slurp(err));
    assert_non_null(gated);
    /* the log a file, then threads again: the next retries open on the openers */
    char tmp[300];
    snprintf(tmp, sizeof tmp, "%s/lm.tmp", dir);
    write_log(tmp);
    assert_int_equal(rename(tmp, fifo), 0);
    assert_int_equal(unlink(gate), 0);
    const long frames = wait_value(err, "frames", 3, 5000);
    const long failed_end = wait_value(err, "dev_opener_failures", 0, 0);
    sleep_ms(500); /* a status line after the storage's return */
    uint64_t stop_ms = 0U;
    const char *log = stop_robot_within(pid, err, 5000, &stop_ms);
    fprintf(stderr,
            "no_opener_thread: %ld steps %llu ms after the spawn; dev_opener_failures %ld, %ld 1 s later, %ld at the "
            "end; frames %ld; stop %llu ms\n",
            steps, (unsigned long long)took_ms, failed_first, failed_later, failed_end, frames,
            (unsigned long long)stop_ms);
    if (steps < 20 || strstr(log, ": back up after ") == NULL) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(steps >= 20); /* the loop runs: no open held it (before: no step at all) */
    assert_true(took_ms < 8000);
    /* down, said with the thread's failure, while no thread can be made */
    assert_non_null(strstr(gated, "coslam-robot: camera (landmark-log replay "));
    assert_non_null(strstr(gated, "down: its opener thread could not be started (Resource temporarily "
                                  "unavailable): not opened in the control loop's thread"));
    assert_non_null(strstr(gated, "/store): down: its opener thread could not be started (Resource temporarily "
                                  "unavailable)"));
    assert_true(last_status_has(gated, " camera=down"));
    assert_true(last_status_has(gated, " storage=down"));
    assert_true(failed_first >= 2);           /* the camera's and the storage's at least */
    assert_true(failed_later > failed_first); /* tried again at the retry period */
    assert_int_equal(last_value(gated, "frames"), 0);
    free(gated);
    /* and up once threads can be made */
    assert_true(frames >= 3);
    assert_non_null(strstr(log, "coslam-robot: camera (landmark-log replay "));
    assert_non_null(strstr(log, ": back up after "));
    assert_true(last_status_has(log, " camera=up"));
    assert_true(last_status_has(log, " storage=up"));
    assert_null(strstr(log, "held the control loop"));
    assert_true(last_value(log, "late_max_us") < 500000);
    assert_true(stop_ms < 4000);
    remove_dir(dir);
}

/* ---- no thread for the snapshot writer ------------------------------------ */

/* The robot with fsync_gate.so and thread_gate.so preloaded, its start-up
 * held in the read of snapshot.a (COSLAM_TEST_READ_GATE) until its storage
 * is up; then `threads` is made (pthread_create fails), and `fsync` too if
 * not NULL (fsync waits while it exists), and the read goes on. So the
 * device openers, started before the read, run, and the snapshot writer,
 * started after it, cannot be started. */
static pid_t spawn_robot_no_writer(const char *dir, const char *err, const char *threads, const char *fsync)
{
    char read_gate[300];
    snprintf(read_gate, sizeof read_gate, "%s/read.gate", dir);
    touch(read_gate);
    char so[1024];
    snprintf(so, sizeof so, "%s %s", COSLAM_FSYNC_GATE, COSLAM_THREAD_GATE);
    setenv("COSLAM_TEST_READ_GATE", read_gate, 1);
    setenv("COSLAM_TEST_FSYNC_GATE", fsync != NULL ? fsync : "/nonexistent/coslam-fsync-gate", 1);
    (void)unlink(err); /* not the last run's line */
    const pid_t pid = spawn_robot_preloaded(dir, err, so, "COSLAM_TEST_THREAD_FAIL", threads, 1);
    unsetenv("COSLAM_TEST_READ_GATE");
    unsetenv("COSLAM_TEST_FSYNC_GATE");
    int up = 0;
    for (int i = 0; i < 2000 && !up; ++i) {
        FILE *f = fopen(err, "r");
        if (f != NULL) {
            fclose(f);
            up = strstr(slurp(err), "/store): up\n") != NULL;
        }
        if (!up) {
            sleep_ms(2);
        }
    }
    assert_true(up);
    touch(threads);
    if (fsync != NULL) {
        touch(fsync);
    }
    assert_int_equal(unlink(read_gate), 0);
    return pid;
}

/* The snapshot writer's thread cannot be started (thread_gate.so; the
 * devices' openers, started before, run) and fsync is held (fsync_gate.so:
 * a slow or hung medium). Before, the robot said so once and then wrote
 * every snapshot in the control loop's thread: the first periodic one held
 * the loop in fsync for as long as the medium did (here no step after
 * 0.3 s). Now no snapshot is written without the thread: each is counted
 * (snap_no_writer_skips), the failure is said once, the thread is started
 * again every retry period (snap_writer_start_failures), the loop steps on;
 * once a thread can be made the snapshots resume (the next one waits in
 * fsync on the thread, the loop still stepping). At the stop with no
 * thread: no final snapshot, said, the stop bounded, the generations as
 * they were; with a thread to be had at the stop: the final snapshot is
 * written on it. */
static void no_writer_thread(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0.2", "0.3", "", err);
    /* a first run leaves both generations on disk (the next start reads them) */
    pid_t pid = spawn_robot(dir, err, NULL, NULL);
    assert_true(wait_value(err, "snap_saves", 1, 8000) >= 1);
    (void)stop_robot(pid, err);
    const disk_t d0 = scan_disk(dir);
    assert_int_equal(d0.present, 2);
    assert_int_equal(d0.invalid, 0);
    char threads[300];
    snprintf(threads, sizeof threads, "%s/no-threads", dir);
    char fsync[300];
    snprintf(fsync, sizeof fsync, "%s/fsync.gate", dir);

    /* no writer thread, fsync held: the loop steps, nothing is written */
    pid = spawn_robot_no_writer(dir, err, threads, fsync);
    const long steps = wait_value(err, "steps", 150, 6000);
    if (steps < 150) {
        fprintf(stderr, "%s\n", slurp(err));
    }
    assert_true(steps >= 150); /* before: stuck at about 30, the loop in fsync */
    const long skipped = wait_value(err, "snap_no_writer_skips", 3, 3000);
    const long failed = wait_value(err, "snap_writer_start_failures", 3, 3000);
    char *gated = strdup(slurp(err));
    assert_non_null(gated);
    /* threads again, fsync still held: the writer starts at its next retry,
     * the next snapshot goes to it and waits in fsync, the loop steps on */
    assert_int_equal(unlink(threads), 0);
    const long writing = wait_value(err, "snap_writing_ms", 500, 5000);
    assert_int_equal(unlink(fsync), 0);
    const long saves = wait_value(err, "snap_saves", 1, 5000);
    uint64_t stop_ms = 0U;
    const char *log = stop_robot_within(pid, err, 5000, &stop_ms);
    fprintf(stderr,
            "no_writer_thread: %ld steps, snap_no_writer_skips %ld, snap_writer_start_failures %ld, late_max_us %ld "
            "without a thread; snap_writing_ms %ld once it started (fsync held), snap_saves %ld, late_max_us %ld; "
            "stop %llu ms\n",
            steps, skipped, failed, last_value(gated, "late_max_us"), writing, saves, last_value(log, "late_max_us"),
            (unsigned long long)stop_ms);
    const char *said = "coslam-robot: snapshot: no writer thread (Resource temporarily unavailable): snapshots are "
                       "not written until one can be started";
    assert_non_null(strstr(gated, said));
    assert_int_equal(count_of(gated, said), 1); /* said once, then counted */
    assert_non_null(strstr(gated, "periodic snapshot not written (snap_no_writer_skips="));
    assert_true(skipped >= 3);
    assert_true(failed >= 3); /* started again at the retry period (0.3 s) */
    assert_int_equal(last_value(gated, "snap_saves"), 0);
    assert_true(last_status_has(gated, " storage=up"));
    assert_true(last_value(gated, "late_max_us") < 500000);
    free(gated);
    assert_non_null(strstr(log, "coslam-robot: snapshot: writer thread started after "));
    assert_true(writing >= 500); /* the write on the thread, held in fsync */
    assert_true(saves >= 1);
    assert_non_null(strstr(log, "(final) in "));
    assert_true(last_value(log, "late_max_us") < 500000);
    const disk_t d1 = scan_disk(dir);
    assert_int_equal(d1.invalid, 0);
    assert_true(d1.newest >= d0.newest + 2);

    /* no thread at the stop, fsync held: no final snapshot, said, a bounded stop */
    pid = spawn_robot_no_writer(dir, err, threads, fsync);
    assert_true(wait_value(err, "snap_no_writer_skips", 1, 4000) >= 1);
    log = stop_robot_within(pid, err, 4000, &stop_ms);
    fprintf(stderr, "no_writer_thread: no thread at the stop: exit after %llu ms\n", (unsigned long long)stop_ms);
    assert_non_null(strstr(log, "no writer thread at the stop (Resource temporarily unavailable): no final snapshot"));
    assert_non_null(strstr(log, "(no final snapshot)"));
    assert_true(stop_ms < 3000); /* before: the final snapshot's fsync held the stop */
    assert_int_equal(unlink(threads), 0);
    assert_int_equal(unlink(fsync), 0);
    const disk_t d2 = scan_disk(dir);
    assert_int_equal(d2.invalid, 0);
    assert_true(d2.newest == d1.newest); /* the generations on disk as they were */

    /* a thread to be had at the stop (none in the loop: its retry 30 s away):
     * the final snapshot is written on it */
    set_retry_period(dir, "30");
    pid = spawn_robot_no_writer(dir, err, threads, NULL);
    assert_true(wait_value(err, "snap_no_writer_skips", 1, 4000) >= 1);
    assert_int_equal(unlink(threads), 0);
    log = stop_robot_within(pid, err, 4000, &stop_ms);
    assert_non_null(strstr(log, "coslam-robot: snapshot: writer thread started after 1 failed attempts"));
    assert_non_null(strstr(log, "(final) in "));
    assert_null(strstr(log, "(no final snapshot)"));
    const disk_t d3 = scan_disk(dir);
    assert_int_equal(d3.invalid, 0);
    assert_true(d3.newest == d2.newest + 1);
    assert_true(d3.clean_stop);
    remove_dir(dir);
}

/* ---- a medium that hangs at the stop, or at the start ---------------------- */

/* The stop's wait for each snapshot job (robot_main.c FINAL_SNAPSHOT_WAIT_MS),
 * and the start's for its read (START_READ_WAIT_MS). */
#define STOP_JOB_WAIT_MS 5000u
#define START_READ_WAIT_MS 5000u

/* SIGTERM to the robot; its wait status within timeout_ms (-1: killed
 * then), *dt_ms how long it took, its log into *log. */
static int term_robot(pid_t pid, const char *err, uint64_t timeout_ms, uint64_t *dt_ms, const char **log)
{
    const uint64_t t0 = now_ms();
    kill(pid, SIGTERM);
    const int st = wait_exit(pid, timeout_ms);
    *dt_ms = now_ms() - t0;
    *log = slurp(err);
    return st;
}

/* The writer thread runs all along; fsync hangs from just before the
 * SIGTERM (fsync_gate.so: an SD card whose fsync never returns, an NFS
 * mount gone). Before, the stop ended the writer thread and wrote the
 * final snapshot itself: the process hung in fsync for as long as the
 * medium did (here until the shim's 30 s). Now the final snapshot goes to
 * the writer thread and is waited for at most 5 s: said, counted
 * (snap_final_timeouts), exit 0, and the generations on disk are as they
 * were (the cut write was a temporary file); the next start loads the
 * newest. No periodic snapshot (snapshot_period_s = 0): the write held is
 * the final one, not a periodic one in flight at the stop. */
static void final_stuck(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0.2", "0", "", err);
    /* two short runs leave both generations on disk (their final snapshots) */
    for (int k = 0; k < 2; ++k) {
        const pid_t first = spawn_robot(dir, err, "--once", "30");
        const int st = wait_exit(first, 8000);
        assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    }
    const disk_t d0 = scan_disk(dir);
    assert_int_equal(d0.present, 2);
    assert_int_equal(d0.invalid, 0);
    assert_int_equal(d0.newest, 2);
    char gate[300];
    snprintf(gate, sizeof gate, "%s/fsync.gate", dir);
    const pid_t pid = spawn_robot_gated(dir, err, gate); /* no gate yet: fsync works */
    assert_true(wait_value(err, "steps", 50, 8000) >= 50);
    touch(gate);
    uint64_t dt = 0U;
    const char *log = NULL;
    const int st = term_robot(pid, err, STOP_JOB_WAIT_MS + 4000u, &dt, &log);
    fprintf(stderr, "final_stuck: fsync held at the stop: exit after %llu ms (wait status %d), snap_final_timeouts %ld\n",
            (unsigned long long)dt, st, last_value(log, "snap_final_timeouts"));
    if (!(st != -1 && WIFEXITED(st) && WEXITSTATUS(st) == 0) || strstr(log, "final snapshot still being") == NULL) {
        fprintf(stderr, "%s\n", log);
    }
    assert_true(st != -1); /* before: still in fsync when killed */
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 0);
    assert_true(dt >= STOP_JOB_WAIT_MS - 100u); /* it did wait for the write */
    assert_true(dt < STOP_JOB_WAIT_MS + 2000u);
    assert_true(loaded_seq(log) == d0.newest);
    assert_non_null(strstr(log, "coslam-robot: snapshot: final snapshot still being written after 5."));
    char want[128];
    snprintf(want, sizeof want, "the newest complete generation on disk stays seq=%llu", (unsigned long long)d0.newest);
    assert_non_null(strstr(log, want));
    assert_non_null(strstr(log, "(no final snapshot)"));
    assert_null(strstr(log, "(final) in "));
    assert_int_equal(last_value(log, "snap_final_timeouts"), 1);
    assert_int_equal(unlink(gate), 0);
    const disk_t d1 = scan_disk(dir);
    assert_int_equal(d1.present, 2);
    assert_int_equal(d1.invalid, 0);
    assert_true(d1.newest == d0.newest); /* the generations on disk as they were */
    /* and the next start loads the newest */
    const pid_t next = spawn_robot(dir, err, "--once", "1");
    const int st2 = wait_exit(next, 8000);
    assert_true(WIFEXITED(st2) && WEXITSTATUS(st2) == 0);
    assert_true(loaded_seq(slurp(err)) == d0.newest);
    remove_dir(dir);
}

/* The start-up read of the snapshots hangs (snapshot.a held in the read's
 * fstat while a gate file exists, fsync_gate.so's read gate). Before, it
 * ran in the main thread before the loop: no step until the medium
 * answered. Now it runs on a thread of its own and is waited for at most
 * 5 s: the robot starts with a new map, said and counted
 * (snap_start_read_timeouts); the read stays in flight (snap_writing_ms,
 * periodic snapshots skipped and said), and once it returns what it found
 * is taken, so this run's snapshots are saved after the generations on
 * disk. A read still hung at the stop: waited for 5 s, no final snapshot,
 * exit 0, the generations as they were. */
static void start_read_stuck(void **state)
{
    (void)state;
    char dir[64];
    char err[300];
    replay_robot_dir(dir, "0.2", "0.3", "", err);
    pid_t pid = spawn_robot(dir, err, NULL, NULL);
    assert_true(wait_value(err, "snap_saves", 2, 8000) >= 2);
    (void)stop_robot(pid, err);
    const disk_t d0 = scan_disk(dir);
    assert_int_equal(d0.present, 2);
    assert_int_equal(d0.invalid, 0);
    char gate[300];
    snprintf(gate, sizeof gate, "%s/read.gate", dir);

    /* the start-up read held: the robot starts without the map */
    touch(gate);
    (void)unlink(err);
    const uint64_t t0 = now_ms();
    pid = spawn_robot_shimmed(dir, err, "COSLAM_TEST_READ_GATE", gate, 1);
    const long steps = wait_value(err, "steps", 20, START_READ_WAIT_MS + 4000u);
    const uint64_t took_ms = now_ms() - t0;
    const long skips = wait_value(err, "snap_busy_skips", 1, 3000);
    /* the loop steps on while the read is held (late_max_us holds the
     * start itself: the first step is due from before the start-up) */
    const long steps_now = last_value(slurp(err), "steps");
    const long steps_later = wait_value(err, "steps", steps_now + 50, 2000);
    char *held = strdup(slurp(err));
    assert_non_null(held);
    fprintf(stderr,
            "start_read_stuck: %ld steps %llu ms after the spawn, %ld later, snap_busy_skips %ld, snap_writing_ms "
            "%ld\n",
            steps, (unsigned long long)took_ms, steps_later, skips, last_value(held, "snap_writing_ms"));
    if (steps < 20 || strstr(held, "start-up read of the snapshots has not returned") == NULL) {
        fprintf(stderr, "%s\n", held);
    }
    assert_true(steps >= 20); /* before: no step while the read was held */
    assert_true(took_ms < START_READ_WAIT_MS + 4000u);
    assert_non_null(strstr(held, "coslam-robot: snapshot: the start-up read of the snapshots has not returned "
                                 "within 5.0 s"));
    assert_null(strstr(held, "snapshot: loaded "));
    assert_int_equal(last_value(held, "snap_start_read_timeouts"), 1);
    assert_true(skips >= 1);
    assert_non_null(strstr(held, "the start-up read of the snapshots has run for"));
    assert_int_equal(last_value(held, "snap_saves"), 0);
    assert_true(last_value(held, "snap_writing_ms") >= 1000);
    assert_true(last_status_has(held, " storage=up"));
    assert_true(steps_later >= steps_now + 50);
    free(held);
    /* the medium answers: the read taken, the snapshots saved after it */
    assert_int_equal(unlink(gate), 0);
    const long saves = wait_value(err, "snap_saves", 1, 5000);
    const char *log = stop_robot(pid, err);
    assert_true(saves >= 1);
    char want[160];
    snprintf(want, sizeof want, "seq=%llu kept, not loaded (this run began a new map)", (unsigned long long)d0.newest);
    assert_non_null(strstr(log, "coslam-robot: snapshot: the start-up read has returned after "));
    assert_non_null(strstr(log, want));
    assert_non_null(strstr(log, "(final) in "));
    const disk_t d1 = scan_disk(dir);
    assert_int_equal(d1.invalid, 0);
    assert_true(d1.newest >= d0.newest + 2); /* after the generations on disk, not over them */
    assert_true(d1.clean_stop);

    /* still held at the stop: a bounded stop, no final snapshot */
    touch(gate);
    (void)unlink(err);
    pid = spawn_robot_shimmed(dir, err, "COSLAM_TEST_READ_GATE", gate, 1);
    assert_true(wait_value(err, "snap_start_read_timeouts", 1, START_READ_WAIT_MS + 4000u) >= 1);
    uint64_t dt = 0U;
    log = stop_robot_within(pid, err, STOP_JOB_WAIT_MS + 4000u, &dt);
    fprintf(stderr, "start_read_stuck: the read still held at the stop: exit after %llu ms\n",
            (unsigned long long)dt);
    assert_true(dt < STOP_JOB_WAIT_MS + 2000u);
    assert_non_null(strstr(log, "a snapshot read has run for "));
    assert_non_null(strstr(log, "does not return (storage stuck): no final snapshot"));
    assert_non_null(strstr(log, "(no final snapshot)"));
    assert_int_equal(last_value(log, "snap_final_timeouts"), 1);
    assert_int_equal(unlink(gate), 0);
    const disk_t d2 = scan_disk(dir);
    assert_int_equal(d2.invalid, 0);
    assert_true(d2.newest == d1.newest);
    remove_dir(dir);
}

int main(int argc, char **argv)
{
    if (argc > 1) {
        cmocka_set_test_filter(argv[1]);
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(degraded),
        cmocka_unit_test(sigterm),
        cmocka_unit_test(sighup_sigpipe),
        cmocka_unit_test(limits_without_status),
        cmocka_unit_test(observers_in_parts),
        cmocka_unit_test(kill_restart),
        cmocka_unit_test(laser_pty),
        cmocka_unit_test(laser_silent),
        cmocka_unit_test(diverged_warning),
        cmocka_unit_test(slow_open_said),
        cmocka_unit_test(hung_open_left),
        cmocka_unit_test(start_open_fifo),
        cmocka_unit_test(storage_back_read),
        cmocka_unit_test(final_snapshot_reopens_storage),
        cmocka_unit_test(storage_held_by_another_robot),
        cmocka_unit_test(slow_storage),
        cmocka_unit_test(status_file_failures_counted),
        cmocka_unit_test(storage_read_only_steady),
        cmocka_unit_test(storage_fsync_fails_steady),
        cmocka_unit_test(storage_big_fsync_fails_steady),
        cmocka_unit_test(no_can_said_once),
        cmocka_unit_test(no_opener_thread),
        cmocka_unit_test(no_writer_thread),
        cmocka_unit_test(final_stuck),
        cmocka_unit_test(start_read_stuck),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
