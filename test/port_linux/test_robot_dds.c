/*
 * Two coslam-robot processes (robots 0 and 1 of a fleet of 2) exchange map
 * messages over Cyclone DDS behind the authentication decorator, on
 * loopback, and merge; a rogue in this test process publishes on the same
 * topic without the fleet key, and its messages are refused and counted
 * while the maps stay what the geometry says.
 *
 * World (metres): robot 0 at (0, 0) facing +x, robot 1 at (2.5, 0) facing
 * -x; they see each other at 2.5 m straight ahead. Four landmarks between
 * them are seen by both; each robot also sees one landmark of its own that
 * lies 40 degrees off the other robot's axis, outside the other's camera
 * field of view (+-25 deg), so the other robot can only get it by merging.
 * The robots stand still (no drives). Their sightings come from two
 * synthetic landmark logs (the replay source, robot_sightings.h): every
 * 0.2 s the five landmarks (seeded noise: 1 cm, 0.3 deg) and, from t = 2 s,
 * the other robot (R records). Each robot's meeting pairs its sighting of
 * the other with the other's and merges the other's map.
 *
 * Isolation as test/link does it: Cyclone on 127.0.0.1 only, no multicast
 * (LT_DDS_LOOPBACK_XML in a file the robots get as [link] config, unicast
 * peer 127.0.0.1), domain 174 (test/link uses 171-173), a partition named
 * after this process. The fleet key is made here, mode 0600.
 *
 * The rogue (three DDS participants in this process, started after the two
 * robots are forked): every 100 ms, to each robot, a plain map message
 * (no trailer), one signed with another key under the fleet's key id, one
 * with another key id, one with a cut trailer, all with landmarks 10-30 m
 * away; and each genuine message it overhears, re-sent later (a replay).
 * Checked through the status JSON and the final snapshots:
 *  - each robot merged the other's map once, nothing refused by the merge;
 *    its map has the 6 landmarks where the geometry puts them in its frame,
 *    the other robot's private one with the other's provenance bit;
 *  - auth_rx_unauthenticated, _bad_mac, _wrong_key, _truncated, _replay
 *    are all >= 1; what the meeting received is exactly what the decorator
 *    delivered, no more than the peer sent; no landmark far away.
 */
#define LT_WITH_SODIUM 1
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
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "hal/hal_link_auth.h"
#include "hal/hal_link_dds.h"
#include "hal/hal_storage_linux.h"
#include "link_test_util.h"
#include "robot_snapshot.h"

#define DOMAIN 174u
#define KEY_ID 7u
#define ROGUE_ID 9u
#define N_LM 6

/* ---- helpers ------------------------------------------------------------ */

static uint64_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static uint64_t wall_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void sleep_ms(uint64_t ms)
{
    struct timespec ts = {(time_t)(ms / 1000u), (long)(ms % 1000u) * 1000000L};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

static void write_text(const char *path, const char *text, mode_t mode)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    assert_int_equal(chmod(path, mode), 0);
}

static char *slurp(const char *path, char *buf, size_t cap)
{
    buf[0] = '\0';
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return buf;
    }
    const size_t n = fread(buf, 1, cap - 1, f);
    buf[n] = '\0';
    fclose(f);
    return buf;
}

/* "key": N in a status JSON, or -1. */
static long json_value(const char *json, const char *key)
{
    char pat[80];
    snprintf(pat, sizeof pat, "\"%s\": ", key);
    const char *p = strstr(json, pat);
    return p != NULL ? strtol(p + strlen(pat), NULL, 10) : -1;
}

/* ---- the world and the two logs ------------------------------------------ */

static const point2_t shared_lm[4] = {{0.8, 0.25}, {1.1, -0.3}, {1.5, 0.35}, {1.8, -0.2}};
static const point2_t private_lm[2] = {{1.6, 0.75}, {0.9, -0.75}}; /* robot 0's, robot 1's */
static const pose2_t robot_pose[2] = {{0.0, 0.0, 0.0}, {2.5, 0.0, COSLAM_PI}};

/* World point p in robot r's map frame (its start pose). */
static point2_t in_frame(int r, point2_t p)
{
    const pose2_t *o = &robot_pose[r];
    const double dx = p.x - o->x, dy = p.y - o->y, c = cos(o->theta), s = sin(o->theta);
    const point2_t q = {c * dx + s * dy, -s * dx + c * dy};
    return q;
}

static void write_log(const char *path, int r, uint64_t seed)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "# robot %d: landmarks every 0.2 s, the other robot from t = 2 s\n", r);
    rng_t rng;
    rng_seed(&rng, seed);
    point2_t lm[5];
    for (int i = 0; i < 4; ++i) {
        lm[i] = shared_lm[i];
    }
    lm[4] = private_lm[r];
    for (int k = 1; k <= 100; ++k) {
        const double t = 0.2 * k;
        for (int i = 0; i < 5; ++i) {
            const point2_t q = in_frame(r, lm[i]);
            const double range = hypot(q.x, q.y) + rng_normal(&rng, 0.0, 0.01);
            const double bearing = atan2(q.y, q.x) + rng_normal(&rng, 0.0, 0.005);
            fprintf(f, "Z %.3f %d %.4f %.5f\n", t, i + 5 * r, range, bearing);
        }
        if (t > 1.99) {
            fprintf(f, "R %.3f %d %.4f %.5f\n", t, 1 - r, 2.5 + rng_normal(&rng, 0.0, 0.01),
                    rng_normal(&rng, 0.0, 0.005));
        }
    }
    fclose(f);
}

static pid_t spawn_robot(const char *dir, int r)
{
    char cfg[300], err[300], status[300];
    snprintf(cfg, sizeof cfg, "%s/r%d.ini", dir, r);
    snprintf(err, sizeof err, "%s/r%d.err", dir, r);
    snprintf(status, sizeof status, "%s/r%d.json", dir, r);
    const pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        const int fd = open(err, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int nul = open("/dev/null", O_WRONLY);
        if (fd < 0 || nul < 0) {
            _exit(127);
        }
        dup2(fd, 2);
        dup2(nul, 1);
        execl(COSLAM_ROBOT_BIN, COSLAM_ROBOT_BIN, "-c", cfg, "--status-file", status, (char *)NULL);
        _exit(127);
    }
    return pid;
}

static int wait_exit(pid_t pid, uint64_t timeout_ms)
{
    const uint64_t end = now_ms() + timeout_ms;
    int st = 0;
    for (;;) {
        if (waitpid(pid, &st, WNOHANG) == pid) {
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

/* ---- the rogue ------------------------------------------------------------ */

static hal_link_dds_t rogue, eve[2]; /* eve[i] has link id i: overhears what is sent to robot i */
static uint8_t buf[HAL_LINK_MAX_PAYLOAD], dgram[HAL_LINK_MAX_PAYLOAD];
static uint8_t captured[2][HAL_LINK_MAX_PAYLOAD]; /* a genuine datagram to robot i */
static size_t captured_len[2];
static uint32_t rogue_sent, replays_sent;

static void open_rogue(hal_link_dds_t *st, uint16_t id, const char *partition)
{
    static const char *peers[] = {"127.0.0.1", NULL};
    hal_link_dds_config_t c;
    memset(&c, 0, sizeof c);
    c.domain_id = DOMAIN;
    c.self_id = id;
    c.peers = peers;
    c.config = LT_DDS_LOOPBACK_XML;
    c.partition = partition;
    c.history_depth = 32;
    assert_int_equal(hal_link_dds_open(st, &c), HAL_OK);
}

static void rogue_send(uint16_t dest, const uint8_t *d, size_t len)
{
    assert_int_equal(hal_link_send(&rogue.link, dest, d, len, 0), HAL_OK);
    rogue_sent++;
}

/* One round: four forgeries to each robot, then whatever eve overheard,
 * re-sent under the genuine sender's link id (a replay). */
static void rogue_round(uint32_t round, const uint8_t *other_key)
{
    for (uint8_t r = 0; r < 2; ++r) {
        const size_t L = lt_encode(buf, ROGUE_ID, r, 5, 1000u * round + r);
        assert_true(L > 0u);
        /* far-away landmarks: a merge of any of these would show */
        rogue_send(r, buf, L);                                                                  /* unauthenticated */
        const uint64_t t = wall_us();
        size_t n = lt_sign(dgram, buf, L, other_key, KEY_ID, ROGUE_ID, t, t);
        rogue_send(r, dgram, n);                                                                /* bad MAC */
        n = lt_sign(dgram, buf, L, other_key, KEY_ID + 1u, ROGUE_ID, t + 1u, t);
        rogue_send(r, dgram, n);                                                                /* wrong key id */
        (void)lt_sign(dgram, buf, L, other_key, KEY_ID, ROGUE_ID, t + 2u, t);
        rogue_send(r, dgram, L + 30u);                                                          /* truncated */
    }
    for (int i = 0; i < 2; ++i) {
        hal_link_rx_info_t info;
        while (hal_link_recv(&eve[i].link, dgram, sizeof dgram, &info, 0) == HAL_OK) {
            if (info.src_id == (uint16_t)(1 - i)) {
                memcpy(captured[i], dgram, info.len);
                captured_len[i] = info.len;
            }
        }
    }
    /* replay the captured genuine message to robot i from eve[1 - i], whose
     * link id is the genuine sender's (the robot took the original by now) */
    for (int i = 0; i < 2; ++i) {
        if (captured_len[i] > 0u && round % 5u == 4u) {
            assert_int_equal(hal_link_send(&eve[1 - i].link, (uint16_t)i, captured[i], captured_len[i], 0), HAL_OK);
            replays_sent++;
        }
    }
}

/* ---- the test ------------------------------------------------------------- */

static robot_snapshot_t snap;

static void load_final_snapshot(const char *dir, int r)
{
    char store[300];
    snprintf(store, sizeof store, "%s/store%d", dir, r);
    hal_storage_linux_t st;
    assert_int_equal(hal_storage_linux_open(&st, store), HAL_OK);
    static uint8_t raw[ROBOT_SNAPSHOT_MAX_BYTES];
    size_t len = 0;
    assert_int_equal(hal_storage_read(&st.dev, ROBOT_SNAPSHOT_NAME_A, raw, sizeof raw, &len), HAL_OK);
    assert_int_equal(robot_snapshot_decode(raw, len, &snap), COSLAM_OK);
    hal_storage_close(&st.dev);
    assert_int_equal(snap.robot_id, r);
}

static void check_map(int r)
{
    const map_estimate_t *m = &snap.map;
    point2_t want[N_LM];
    for (int i = 0; i < 4; ++i) {
        want[i] = in_frame(r, shared_lm[i]);
    }
    want[4] = in_frame(r, private_lm[0]);
    want[5] = in_frame(r, private_lm[1]);
    fprintf(stderr, "robot %d: %u landmarks in its final snapshot:\n", r, (unsigned)m->n_landmarks);
    for (int k = 0; k < m->n_landmarks; ++k) {
        fprintf(stderr, "  (%7.3f, %7.3f) n_obs %3u src_mask 0x%x\n", m->lm[k].mean.x, m->lm[k].mean.y,
                (unsigned)m->lm[k].n_obs, (unsigned)m->lm[k].src_mask);
        /* nothing of the rogue's (10-30 m away, src bits of robots >= 2) */
        assert_true(hypot(m->lm[k].mean.x, m->lm[k].mean.y) < 4.0);
        assert_int_equal(m->lm[k].src_mask & ~3u, 0);
    }
    assert_int_equal(m->n_landmarks, N_LM);
    for (int i = 0; i < N_LM; ++i) {
        int found = -1;
        for (int k = 0; k < m->n_landmarks; ++k) {
            if (hypot(m->lm[k].mean.x - want[i].x, m->lm[k].mean.y - want[i].y) < 0.2) {
                found = k;
            }
        }
        if (found < 0) {
            fprintf(stderr, "robot %d: no landmark near (%.3f, %.3f)\n", r, want[i].x, want[i].y);
        }
        assert_true(found >= 0);
        if (i < 4) {
            /* seen by both: the other robot's provenance after the merge */
            assert_int_equal(m->lm[found].src_mask, 3);
        } else {
            /* a private one: its owner's bit (the other's came by merging) */
            assert_true((m->lm[found].src_mask & (1u << (i - 4))) != 0u);
        }
    }
}

static void two_robots_merge_over_dds(void **state)
{
    (void)state;
    char dir[] = "/tmp/coslam-robot-dds-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[400], text[2048];

    /* the fleet key, 0600, made from the kernel's random numbers */
    uint8_t key[32], other_key[32];
    randombytes_buf(key, sizeof key);
    randombytes_buf(other_key, sizeof other_key);
    char hex[65];
    for (int i = 0; i < 32; ++i) {
        snprintf(hex + 2 * i, 3, "%02x", key[i]);
    }
    snprintf(path, sizeof path, "%s/fleet.key", dir);
    snprintf(text, sizeof text, "%s\n", hex);
    write_text(path, text, 0600);
    snprintf(path, sizeof path, "%s/cyclone.xml", dir);
    write_text(path, LT_DDS_LOOPBACK_XML "\n", 0644);
    char partition[64];
    lt_partition(partition, sizeof partition, "robot-dds", (long)getpid());

    for (int r = 0; r < 2; ++r) {
        snprintf(path, sizeof path, "%s/r%d.log", dir, r);
        write_log(path, r, 77u + (uint64_t)r);
        snprintf(text, sizeof text,
                 "[robot]\nid = %d\nfleet_size = 2\nstatus_period_s = 0.5\nsnapshot_period_s = 0\nretry_period_s = 0.5\n"
                 "[laser]\ndevice =\n[can]\ninterface =\n[gpio]\nchip =\n"
                 "[camera]\nreplay_log = %s/r%d.log\nreplay_loop = false\n"
                 "[link]\ndomain = %u\npeers = 127.0.0.1\npartition = %s\nconfig = file://%s/cyclone.xml\n"
                 "[storage]\ndir = %s/store%d\n"
                 "[fleet]\nkey_file = %s/fleet.key\nkey_id = %u\n"
                 "[filter]\ntype = %s\n",
                 r, dir, r, DOMAIN, partition, dir, dir, r, dir, KEY_ID, r == 0 ? "ekf" : "fastslam2");
        snprintf(path, sizeof path, "%s/r%d.ini", dir, r);
        write_text(path, text, 0644);
    }

    const uint64_t t0 = now_ms();
    pid_t pid[2];
    for (int r = 0; r < 2; ++r) {
        pid[r] = spawn_robot(dir, r);
    }
    /* the rogue joins only now: Cyclone's threads do not survive a fork */
    open_rogue(&rogue, ROGUE_ID, partition);
    open_rogue(&eve[0], 0, partition);
    open_rogue(&eve[1], 1, partition);
    assert_int_equal(hal_link_dds_wait_matched(&rogue, 4, 10000000u), HAL_OK); /* 2 robots + 2 eves */

    static char json[2][65536];
    uint32_t round = 0;
    uint64_t merged_at = 0;
    while (now_ms() - t0 < 30000u) {
        rogue_round(round++, other_key);
        sleep_ms(100);
        long merged[2];
        for (int r = 0; r < 2; ++r) {
            snprintf(path, sizeof path, "%s/r%d.json", dir, r);
            merged[r] = json_value(slurp(path, json[r], sizeof json[r]), "mt_merged");
        }
        if (merged_at == 0u && merged[0] >= 1 && merged[1] >= 1) {
            merged_at = now_ms();
        }
        /* after the merges: a second more of forgeries and some replays */
        if (merged_at != 0u && now_ms() - merged_at > 1000u && replays_sent >= 4u) {
            break;
        }
    }
    const uint64_t t_merge = merged_at != 0u ? merged_at - t0 : 0u;
    for (int r = 0; r < 2; ++r) {
        kill(pid[r], SIGTERM);
    }
    int st[2];
    for (int r = 0; r < 2; ++r) {
        st[r] = wait_exit(pid[r], 5000);
    }
    hal_link_close(&rogue.link);
    hal_link_close(&eve[0].link);
    hal_link_close(&eve[1].link);

    static char log[65536];
    long sent[2];
    for (int r = 0; r < 2; ++r) {
        snprintf(path, sizeof path, "%s/r%d.err", dir, r);
        slurp(path, log, sizeof log);
        if (!(WIFEXITED(st[r]) && WEXITSTATUS(st[r]) == 0) || merged_at == 0u) {
            fprintf(stderr, "robot %d:\n%s\n", r, log);
        }
        assert_true(WIFEXITED(st[r]));
        assert_int_equal(WEXITSTATUS(st[r]), 0);
        assert_non_null(strstr(log, "authenticated with key id 7): up"));
        assert_non_null(strstr(log, "meeting: merged robot "));
        assert_non_null(strstr(log, " too uncertain to refute")); /* what the merge left out, said */
        assert_null(strstr(log, hex)); /* never printed */
        snprintf(path, sizeof path, "%s/r%d.json", dir, r); /* the one written at exit */
        slurp(path, json[r], sizeof json[r]);
        sent[r] = json_value(json[r], "auth_sent");
    }
    assert_true(merged_at != 0u);
    fprintf(stderr, "both merged %.1f s after the start; rogue: %u forged datagrams, %u replays\n",
            (double)t_merge * 1e-3, rogue_sent, replays_sent);
    for (int r = 0; r < 2; ++r) {
        const char *j = json[r];
        fprintf(stderr,
                "robot %d: mt_sent %ld mt_received %ld mt_merged %ld | auth delivered %ld refused %ld: "
                "unauthenticated %ld bad_mac %ld wrong_key %ld truncated %ld replay %ld | dds delivered %ld "
                "other_dest %ld own_id %ld\n",
                r, json_value(j, "mt_sent"), json_value(j, "mt_received"), json_value(j, "mt_merged"),
                json_value(j, "auth_delivered"), json_value(j, "auth_refused"),
                json_value(j, "auth_rx_unauthenticated"), json_value(j, "auth_rx_bad_mac"),
                json_value(j, "auth_rx_wrong_key"), json_value(j, "auth_rx_truncated"),
                json_value(j, "auth_rx_replay"), json_value(j, "dds_delivered"), json_value(j, "dds_rx_other_dest"),
                json_value(j, "dds_rx_own_id"));
        assert_non_null(strstr(j, "\"link\": \"up\""));
        assert_non_null(strstr(j, "\"link_mode\": \"auth\""));
        /* the merge: once, nothing refused on the way */
        assert_int_equal(json_value(j, "mt_merged"), 1);
        assert_int_equal(json_value(j, "mt_merge_failures"), 0);
        assert_int_equal(json_value(j, "mt_refused_range"), 0);
        assert_int_equal(json_value(j, "mt_refused_disagree"), 0);
        assert_int_equal(json_value(j, "mt_refused_lost"), 0);
        assert_int_equal(json_value(j, "mt_rx_errors"), 0);
        assert_int_equal(json_value(j, "mt_wrong_sender"), 0);
        /* the rogue: every kind refused and counted by its reason */
        assert_true(json_value(j, "auth_rx_unauthenticated") >= 1);
        assert_true(json_value(j, "auth_rx_bad_mac") >= 1);
        assert_true(json_value(j, "auth_rx_wrong_key") >= 1);
        assert_true(json_value(j, "auth_rx_truncated") >= 1);
        assert_true(json_value(j, "auth_rx_replay") >= 1);
        assert_int_equal(json_value(j, "auth_rx_sender_mismatch"), 0);
        assert_int_equal(json_value(j, "auth_rx_stale"), 0);
        assert_int_equal(json_value(j, "auth_rx_future"), 0);
        assert_int_equal(json_value(j, "dds_rx_invalid"), 0);
        /* only authentic messages reached the meeting, and only the peer's */
        assert_int_equal(json_value(j, "mt_received"), json_value(j, "auth_delivered"));
        assert_true(json_value(j, "auth_delivered") >= 1);
        assert_true(json_value(j, "auth_delivered") <= sent[1 - r]);
        load_final_snapshot(dir, r);
        check_map(r);
    }
    snprintf(text, sizeof text, "rm -rf '%s'", dir);
    assert_int_equal(system(text), 0);
}

int main(void)
{
    unsetenv("CYCLONEDDS_URI"); /* the DDS configuration is the test's own */
    if (sodium_init() < 0) {
        return 1;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(two_robots_merge_over_dds),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
