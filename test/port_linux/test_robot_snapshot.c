/*
 * coslam-robot map snapshots: the codec round trip is byte-exact, every
 * damaged byte is caught, the two generations fall back to the older one
 * when the newest is torn or corrupt (reported by name), and seeding a
 * filter from a snapshot gives back the same exported map (means, cov_rel,
 * pose, bookkeeping; cov as documented in slam_filter_seed) for EKF-SLAM
 * and Fast-SLAM, and through robot_node_restore. The writer thread takes a
 * write the caller hands over without holding the caller, however long the
 * storage blocks, writes the bytes it was given, reports failures, and can
 * be stopped with a write that does not return.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "app/robot_node.h"
#include "app/slam_filter.h"
#include "coslam/cov3.h"
#include "coslam/rng.h"
#include "hal/hal_clock_linux.h"
#include "hal/hal_storage_linux.h"
#include "robot_snapshot.h"
#include "robot_snapshot_writer.h"

/* ---- a map to save: a filter driven round landmarks --------------------- */

#define N_LM 8

static slam_filter_t filter_a;
static slam_filter_t filter_b;
static map_estimate_t map_a;
static map_estimate_t map_b;
static map_estimate_t map_c;

/* Drive a circle of radius 1 m among N_LM landmarks on a ring of 2.5 m,
 * camera at 5 Hz, seeded noise; export. */
static void build_map(slam_filter_t *f, slam_filter_kind_t kind, map_estimate_t *out)
{
    slam_filter_config_t c = slam_filter_config_default();
    c.kind = kind;
    c.n_particles = 50;
    c.seed = 7;
    c.robot_id = 1;
    assert_int_equal(slam_filter_init(f, &c, (pose2_t){0.0, 0.0, 0.0}), COSLAM_OK);
    rng_t rng;
    rng_seed(&rng, 42);
    point2_t lm[N_LM];
    for (int i = 0; i < N_LM; ++i) {
        const double a = COSLAM_TWO_PI * i / N_LM;
        lm[i] = (point2_t){2.5 * cos(a), 2.5 * sin(a) + 1.0};
    }
    pose2_t truth = {0.0, 0.0, 0.0};
    const slam_params_t *sp = slam_filter_params(f);
    for (int k = 0; k < 300; ++k) {
        const odo_increment_t u = motion_from_body_velocity(0.2, 0.0, 0.2, 0.2);
        truth = motion_apply(truth, u);
        const odo_increment_t noisy = {u.dx + rng_normal(&rng, 0.0, 0.005), u.dy + rng_normal(&rng, 0.0, 0.005),
                                       u.dtheta + rng_normal(&rng, 0.0, 0.005)};
        assert_int_equal(slam_filter_predict(f, noisy, 0.2), COSLAM_OK);
        sighting_t z[N_LM];
        int nz = 0;
        for (int i = 0; i < N_LM; ++i) {
            sighting_t s = observe_predict(truth, lm[i]);
            if (s.range_m < sp->sensor_min_range_m || s.range_m > sp->sensor_max_range_m ||
                fabs(s.bearing_rad) > 0.5 * sp->sensor_fov_rad) {
                continue;
            }
            s.range_m += rng_normal(&rng, 0.0, 0.02);
            s.bearing_rad += rng_normal(&rng, 0.0, 0.02);
            s.signature = (uint8_t)(i % 3);
            z[nz++] = s;
        }
        const coslam_status_t st = slam_filter_update(f, z, nz);
        assert_true(st == COSLAM_OK || st == COSLAM_E_CAPACITY);
    }
    assert_int_equal(slam_filter_export(f, out), COSLAM_OK);
    assert_true(out->n_landmarks >= 4);
}

static robot_snapshot_t snap_in;
static robot_snapshot_t snap_out;
static uint8_t buf[ROBOT_SNAPSHOT_MAX_BYTES];
static uint8_t buf2[ROBOT_SNAPSHOT_MAX_BYTES];

static void assert_same_bits(double a, double b)
{
    assert_memory_equal(&a, &b, sizeof a);
}

static void assert_maps_identical(const map_estimate_t *a, const map_estimate_t *b)
{
    assert_same_bits(a->pose.x, b->pose.x);
    assert_same_bits(a->pose.y, b->pose.y);
    assert_same_bits(a->pose.theta, b->pose.theta);
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            assert_same_bits(a->pose_cov.m[r][c], b->pose_cov.m[r][c]);
        }
    }
    assert_int_equal(a->n_landmarks, b->n_landmarks);
    for (int i = 0; i < a->n_landmarks; ++i) {
        const map_landmark_t *x = &a->lm[i];
        const map_landmark_t *y = &b->lm[i];
        assert_same_bits(x->mean.x, y->mean.x);
        assert_same_bits(x->mean.y, y->mean.y);
        assert_same_bits(x->cov.xx, y->cov.xx);
        assert_same_bits(x->cov.xy, y->cov.xy);
        assert_same_bits(x->cov.yy, y->cov.yy);
        assert_same_bits(x->cov_rel.xx, y->cov_rel.xx);
        assert_same_bits(x->cov_rel.xy, y->cov_rel.xy);
        assert_same_bits(x->cov_rel.yy, y->cov_rel.yy);
        assert_int_equal(x->id, y->id);
        assert_int_equal(x->n_obs, y->n_obs);
        assert_int_equal(x->src_mask, y->src_mask);
        assert_int_equal(x->signature, y->signature);
    }
}

static void codec_round_trip_is_byte_exact(void **state)
{
    (void)state;
    memset(&snap_in, 0, sizeof snap_in);
    build_map(&filter_a, SLAM_FILTER_EKF, &snap_in.map);
    snap_in.seq = 123456789012ULL;
    snap_in.robot_id = 1;
    snap_in.filter_kind = SLAM_FILTER_EKF;
    snap_in.msg_seq = 77;
    snap_in.clean_stop = 1;
    snap_in.saved_unix_s = 1700000000ULL;
    size_t len = 0;
    assert_int_equal(robot_snapshot_encode(&snap_in, buf, sizeof buf, &len), COSLAM_OK);
    assert_int_equal(len, ROBOT_SNAPSHOT_BYTES(snap_in.map.n_landmarks));
    assert_int_equal(robot_snapshot_decode(buf, len, &snap_out), COSLAM_OK);
    assert_maps_identical(&snap_in.map, &snap_out.map);
    assert_true(snap_out.seq == snap_in.seq);
    assert_int_equal(snap_out.robot_id, 1);
    assert_int_equal(snap_out.filter_kind, SLAM_FILTER_EKF);
    assert_int_equal(snap_out.msg_seq, 77);
    assert_int_equal(snap_out.clean_stop, 1);
    assert_int_equal(buf[22], 1); /* the flags byte, bit 0 */
    assert_true(snap_out.saved_unix_s == snap_in.saved_unix_s);
    size_t len2 = 0;
    assert_int_equal(robot_snapshot_encode(&snap_out, buf2, sizeof buf2, &len2), COSLAM_OK);
    assert_int_equal(len2, len);
    assert_memory_equal(buf, buf2, len);
    /* too small a buffer */
    assert_int_equal(robot_snapshot_encode(&snap_in, buf2, len - 1, &len2), COSLAM_E_CAPACITY);
}

static void every_damage_is_caught(void **state)
{
    (void)state;
    size_t len = 0;
    assert_int_equal(robot_snapshot_encode(&snap_in, buf, sizeof buf, &len), COSLAM_OK);
    /* every single-bit flip */
    for (size_t i = 0; i < len; ++i) {
        for (int b = 0; b < 8; ++b) {
            buf[i] ^= (uint8_t)(1u << b);
            const coslam_status_t st = robot_snapshot_decode(buf, len, &snap_out);
            if (st == COSLAM_OK) {
                fprintf(stderr, "bit %d of byte %zu not caught\n", b, i);
            }
            assert_int_not_equal(st, COSLAM_OK);
            buf[i] ^= (uint8_t)(1u << b);
        }
    }
    /* every truncation (a torn write), and trailing bytes */
    for (size_t n = 0; n < len; ++n) {
        assert_int_not_equal(robot_snapshot_decode(buf, n, &snap_out), COSLAM_OK);
    }
    assert_int_equal(robot_snapshot_decode(buf, len + 1, &snap_out), COSLAM_E_MSG_LENGTH);
    assert_int_equal(robot_snapshot_decode(buf, len, &snap_out), COSLAM_OK);
}

/* ---- two generations on real files --------------------------------------- */

static char dir[64];
static hal_storage_linux_t store;
static robot_snapshots_t gens;

static void write_raw(const char *name, const uint8_t *data, size_t n)
{
    char path[128];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    const int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, data, n), (ssize_t)n);
    close(fd);
}

static size_t read_raw(const char *name, uint8_t *data, size_t cap)
{
    char path[128];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    const int fd = open(path, O_RDONLY);
    assert_true(fd >= 0);
    const ssize_t n = read(fd, data, cap);
    close(fd);
    assert_true(n > 0);
    return (size_t)n;
}

static char log_text[8192];

static coslam_status_t load_logged(robot_snapshot_t *out, const char **name)
{
    FILE *log = fmemopen(log_text, sizeof log_text, "w");
    assert_non_null(log);
    const coslam_status_t st = robot_snapshots_load(&gens, out, name, log);
    fclose(log);
    return st;
}

static void generations_fall_back_to_the_older(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/coslam-snap-XXXXXX");
    assert_non_null(mkdtemp(dir));
    assert_int_equal(hal_storage_linux_open(&store, dir), HAL_OK);
    robot_snapshots_init(&gens, &store.dev);
    const char *name = NULL;
    assert_int_equal(load_logged(&snap_out, &name), COSLAM_E_EMPTY);
    /* three saves: a (1), b (2), a (3) */
    for (int k = 1; k <= 3; ++k) {
        snap_in.map.pose.x = (double)k;
        assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_OK);
        assert_true(snap_in.seq == (uint64_t)k);
        assert_string_equal(name, k % 2 == 1 ? ROBOT_SNAPSHOT_NAME_A : ROBOT_SNAPSHOT_NAME_B);
    }
    robot_snapshots_init(&gens, &store.dev);
    assert_int_equal(load_logged(&snap_out, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_A);
    assert_true(snap_out.seq == 3);
    assert_true(snap_out.map.pose.x == 3.0);
    assert_string_equal(log_text, "");

    /* torn newest (the file cut short under the storage layer) */
    static uint8_t raw[ROBOT_SNAPSHOT_MAX_BYTES + 64];
    const size_t n = read_raw(ROBOT_SNAPSHOT_NAME_A, raw, sizeof raw);
    write_raw(ROBOT_SNAPSHOT_NAME_A, raw, n / 2);
    robot_snapshots_init(&gens, &store.dev);
    assert_int_equal(load_logged(&snap_out, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_B);
    assert_true(snap_out.seq == 2);
    assert_true(snap_out.map.pose.x == 2.0);
    assert_non_null(strstr(log_text, "snapshot.a unreadable (HAL_E_CORRUPT)"));
    assert_int_equal(gens.corrupt_found, 1);
    /* the next save replaces the damaged generation, after the loaded one */
    snap_in.map.pose.x = 4.0;
    assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_A);
    assert_true(snap_in.seq == 3);

    /* corrupt newest with an intact storage envelope: our own CRC catches it */
    size_t len = 0;
    snap_in.seq = 9;
    assert_int_equal(robot_snapshot_encode(&snap_in, buf, sizeof buf, &len), COSLAM_OK);
    buf[len / 2] ^= 0x10;
    assert_int_equal(hal_storage_write(&store.dev, ROBOT_SNAPSHOT_NAME_B, buf, len), HAL_OK);
    robot_snapshots_init(&gens, &store.dev);
    assert_int_equal(load_logged(&snap_out, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_A);
    assert_true(snap_out.seq == 3);
    assert_non_null(strstr(log_text, "snapshot.b corrupt (E_MSG_CRC)"));

    /* both damaged: nothing to load, both reported */
    write_raw(ROBOT_SNAPSHOT_NAME_A, (const uint8_t *)"CSB1", 4);
    robot_snapshots_init(&gens, &store.dev);
    assert_int_equal(load_logged(&snap_out, &name), COSLAM_E_EMPTY);
    assert_non_null(strstr(log_text, "snapshot.a"));
    assert_non_null(strstr(log_text, "snapshot.b"));
    /* no storage */
    robot_snapshots_init(&gens, NULL);
    assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_E_UNSUPPORTED);
    assert_int_equal(gens.save_failures, 1);
    /* failed writes on the Linux backend, each with what happened (all but
     * the full medium were E_UNSUPPORTED): a storage opened to read only
     * cannot write (E_UNSUPPORTED); a full medium, here the file size
     * limit (EFBIG), is E_CAPACITY; a storage closed under the robot is
     * E_STORAGE */
    hal_storage_linux_t reader;
    assert_int_equal(hal_storage_linux_open_reader(&reader, dir), HAL_OK);
    robot_snapshots_init(&gens, &reader.dev);
    assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_E_UNSUPPORTED);
    assert_int_equal(gens.last_write, HAL_E_UNSUPPORTED);
    hal_storage_close(&reader.dev);
    robot_snapshots_init(&gens, &store.dev);
    struct rlimit old_lim;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &old_lim), 0);
    struct rlimit lim = old_lim;
    lim.rlim_cur = 64U; /* below a snapshot's size */
    void (*old_xfsz)(int) = signal(SIGXFSZ, SIG_IGN);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
    const coslam_status_t full = robot_snapshots_save(&gens, &snap_in, &name);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &old_lim), 0);
    (void)signal(SIGXFSZ, old_xfsz);
    assert_int_equal(full, COSLAM_E_CAPACITY);
    assert_int_equal(gens.last_write, HAL_E_OVERFLOW);
    assert_int_equal(store.last_errno, EFBIG);
    hal_storage_linux_t closed;
    assert_int_equal(hal_storage_linux_open_reader(&closed, dir), HAL_OK);
    hal_storage_close(&closed.dev);
    robot_snapshots_init(&gens, &closed.dev);
    gens.storage = &closed.dev; /* the handle kept after its close */
    assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_E_STORAGE);
    assert_int_equal(gens.last_write, HAL_E_CLOSED);

    hal_storage_close(&store.dev);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

/* The pose covariance seeds the EKF's P and every particle's pose marginal:
 * one that is not symmetric, or not positive semi-definite (xy = 1 with
 * xx = yy = 0.01: a negative variance along x - y), is refused like other
 * corrupt content (it was taken when finite with a non-negative diagonal),
 * and the older generation is loaded, the refusal said and counted. */
static void pose_covariance_must_be_psd(void **state)
{
    (void)state;
    size_t len = 0;
    robot_snapshot_t s = snap_in;
    s.map.pose_cov = cov3_diag(0.01, 0.01, 0.001);
    s.map.pose_cov.m[0][1] = s.map.pose_cov.m[1][0] = 1.0;
    assert_int_equal(robot_snapshot_encode(&s, buf, sizeof buf, &len), COSLAM_OK);
    assert_int_equal(robot_snapshot_decode(buf, len, &snap_out), COSLAM_E_MSG_COVARIANCE);
    /* asymmetric, though each triangle alone would be fine */
    s.map.pose_cov = cov3_diag(0.04, 0.04, 0.01);
    s.map.pose_cov.m[0][2] = 0.001;
    assert_int_equal(robot_snapshot_encode(&s, buf, sizeof buf, &len), COSLAM_OK);
    assert_int_equal(robot_snapshot_decode(buf, len, &snap_out), COSLAM_E_MSG_COVARIANCE);
    /* indefinite only in the heading block */
    s.map.pose_cov = cov3_diag(0.04, 0.04, 0.01);
    s.map.pose_cov.m[1][2] = s.map.pose_cov.m[2][1] = 0.03;
    assert_int_equal(robot_snapshot_encode(&s, buf, sizeof buf, &len), COSLAM_OK);
    assert_int_equal(robot_snapshot_decode(buf, len, &snap_out), COSLAM_E_MSG_COVARIANCE);
    /* taken: zero (a robot that has not moved), and singular PSD v v^T
     * with the rounding of its products */
    s.map.pose_cov = cov3_zero();
    assert_int_equal(robot_snapshot_encode(&s, buf, sizeof buf, &len), COSLAM_OK);
    assert_int_equal(robot_snapshot_decode(buf, len, &snap_out), COSLAM_OK);
    const double v[3] = {0.1, -0.3, 0.07};
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            s.map.pose_cov.m[r][c] = v[r] * v[c];
        }
    }
    assert_int_equal(robot_snapshot_encode(&s, buf, sizeof buf, &len), COSLAM_OK);
    assert_int_equal(robot_snapshot_decode(buf, len, &snap_out), COSLAM_OK);

    /* the newest generation with an indefinite one: the older is loaded */
    snprintf(dir, sizeof dir, "/tmp/coslam-snap-XXXXXX");
    assert_non_null(mkdtemp(dir));
    assert_int_equal(hal_storage_linux_open(&store, dir), HAL_OK);
    robot_snapshots_init(&gens, &store.dev);
    const char *name = NULL;
    s.map.pose_cov = cov3_diag(0.01, 0.01, 0.001);
    assert_int_equal(robot_snapshots_save(&gens, &s, &name), COSLAM_OK); /* a, seq 1 */
    s.map.pose_cov.m[0][1] = s.map.pose_cov.m[1][0] = 1.0;
    assert_int_equal(robot_snapshots_save(&gens, &s, &name), COSLAM_OK); /* b, seq 2: encoded as given */
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_B);
    robot_snapshots_init(&gens, &store.dev);
    assert_int_equal(load_logged(&snap_out, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_A);
    assert_true(snap_out.seq == 1);
    assert_true(snap_out.map.pose_cov.m[0][1] == 0.0);
    assert_non_null(strstr(log_text, "snapshot.b corrupt (E_MSG_COVARIANCE): not used"));
    assert_int_equal(gens.corrupt_found, 1);
    hal_storage_close(&store.dev);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

/* One generation that cannot be written (snapshot.a a directory): the
 * saves go to the other one, and the broken one is tried again every
 * ROBOT_SNAPSHOT_RETRY_FAILED_SLOT saves; once it is writable again the
 * generations alternate as before. (Before, every save went to the broken
 * slot, the older generation, and failed: none was ever saved.) */
static void an_unwritable_generation_is_passed_over(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/coslam-snap-XXXXXX");
    assert_non_null(mkdtemp(dir));
    char sub[300];
    snprintf(sub, sizeof sub, "%s/%s", dir, ROBOT_SNAPSHOT_NAME_A);
    assert_int_equal(mkdir(sub, 0700), 0);
    assert_int_equal(hal_storage_linux_open(&store, dir), HAL_OK);
    robot_snapshots_init(&gens, &store.dev);
    const char *name = NULL;
    assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_E_STORAGE); /* a: fails */
    /* the storage keeps the OS's reason (the robot says it): the rename
     * over a directory */
    assert_int_equal(gens.last_write, HAL_E_IO);
    assert_int_equal(store.last_errno, EISDIR);
    int saved = 0;
    int tried_a = 0;
    for (int k = 0; k < 20; ++k) {
        name = NULL;
        const coslam_status_t st = robot_snapshots_save(&gens, &snap_in, &name);
        if (st == COSLAM_OK) {
            assert_string_equal(name, ROBOT_SNAPSHOT_NAME_B);
            saved++;
        } else {
            assert_int_equal(st, COSLAM_E_STORAGE);
            tried_a++;
        }
    }
    assert_int_equal(tried_a, 2);   /* every 8th save tries a again */
    assert_int_equal(saved, 18);
    robot_snapshots_init(&gens, &store.dev);
    assert_int_equal(load_logged(&snap_out, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_B);
    assert_true(snap_out.seq == 18);
    /* a writable again: the generations alternate */
    assert_int_equal(rmdir(sub), 0);
    gens.failed_slot = 0;
    gens.failed_slot_skips = ROBOT_SNAPSHOT_RETRY_FAILED_SLOT - 1U;
    assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_A);
    assert_int_equal(gens.failed_slot, -1);
    assert_int_equal(store.last_errno, 0);
    assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_B);
    hal_storage_close(&store.dev);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

/* ---- the writer thread ------------------------------------------------------ */

/* A storage in front of the real one whose writes wait at a gate the test
 * opens, and may be told to fail. */
typedef struct {
    hal_storage_t dev;
    hal_storage_t *inner;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int open;          /* writes pass */
    int entered;       /* writes that reached the gate */
    int finished;      /* writes that returned */
    hal_status_t fault;
} gated_t;

static gated_t gated;

static hal_status_t gated_write(hal_storage_t *d, const char *name, const uint8_t *data, size_t len)
{
    gated_t *g = d->backend;
    pthread_mutex_lock(&g->mu);
    g->entered++;
    pthread_cond_broadcast(&g->cv);
    while (!g->open) {
        pthread_cond_wait(&g->cv, &g->mu);
    }
    const hal_status_t fault = g->fault;
    pthread_mutex_unlock(&g->mu);
    const hal_status_t r = fault != HAL_OK ? fault : hal_storage_write(g->inner, name, data, len);
    pthread_mutex_lock(&g->mu);
    g->finished++;
    pthread_cond_broadcast(&g->cv);
    pthread_mutex_unlock(&g->mu);
    return r;
}

static hal_status_t gated_read(hal_storage_t *d, const char *name, uint8_t *buf, size_t cap, size_t *len)
{
    return hal_storage_read(((gated_t *)d->backend)->inner, name, buf, cap, len);
}

static const hal_storage_ops_t gated_ops = {.write = gated_write, .read = gated_read};

static void gate_set(int open, hal_status_t fault)
{
    pthread_mutex_lock(&gated.mu);
    gated.open = open;
    gated.fault = fault;
    pthread_cond_broadcast(&gated.cv);
    pthread_mutex_unlock(&gated.mu);
}

/* Wait until `*counter` reaches n (the writer thread got there). */
static void gate_wait(const int *counter, int n)
{
    pthread_mutex_lock(&gated.mu);
    while (*counter < n) {
        pthread_cond_wait(&gated.cv, &gated.mu);
    }
    pthread_mutex_unlock(&gated.mu);
}

static robot_snapshot_writer_t writer;
static robot_snapshot_writer_t writer2;

static void writer_does_not_hold_the_caller(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/coslam-snapw-XXXXXX");
    assert_non_null(mkdtemp(dir));
    assert_int_equal(hal_storage_linux_open(&store, dir), HAL_OK);
    memset(&gated, 0, sizeof gated);
    gated.dev.ops = &gated_ops;
    gated.dev.backend = &gated;
    gated.inner = &store.dev;
    pthread_mutex_init(&gated.mu, NULL);
    pthread_cond_init(&gated.cv, NULL);
    robot_snapshots_init(&gens, &gated.dev);
    const char *name = NULL;

    /* not started: nothing taken */
    assert_int_equal(robot_snapshot_writer_submit(&writer, &gated.dev, "x", buf, 1), ESRCH);
    assert_int_equal(robot_snapshot_writer_take(&writer, 0, NULL, NULL), -1);
    assert_int_equal(robot_snapshot_writer_start(&writer), 0);
    assert_int_equal(robot_snapshot_writer_take(&writer, 10, NULL, NULL), -1); /* nothing handed over */

    /* generation 1, written in the caller's thread */
    gate_set(1, HAL_OK);
    snap_in.map.pose.x = 1.0;
    assert_int_equal(robot_snapshots_save(&gens, &snap_in, &name), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_A);

    /* generation 2 through the writer while the storage blocks */
    gate_set(0, HAL_OK);
    snap_in.map.pose.x = 2.0;
    robot_snapshot_job_t job;
    assert_int_equal(robot_snapshots_prepare(&gens, &snap_in, &job), COSLAM_OK);
    assert_string_equal(job.name, ROBOT_SNAPSHOT_NAME_B);
    assert_true(job.seq == 2);
    assert_true(gens.newest_seq == 1); /* nothing changes before the commit */
    assert_int_equal(robot_snapshot_writer_submit(&writer, &gated.dev, job.name, gens.buf, job.len), 0);
    gate_wait(&gated.entered, 2); /* the thread is inside the storage write, and we are not */
    memset(gens.buf, 0xA5, job.len); /* the caller's buffer is free: the writer copied it */
    hal_status_t ws = HAL_E_IO;
    uint64_t write_us = 0;
    assert_int_equal(robot_snapshot_writer_take(&writer, 0, &ws, &write_us), 0);
    assert_int_equal(robot_snapshot_writer_take(&writer, 50, &ws, &write_us), 0); /* still blocked after 50 ms */
    assert_int_equal(robot_snapshot_writer_busy(&writer), 1);
    assert_int_equal(robot_snapshot_writer_submit(&writer, &gated.dev, job.name, gens.buf, job.len), EBUSY);
    assert_int_equal(gated.entered, 2); /* the refused one never reached the storage */
    gate_set(1, HAL_OK);
    assert_int_equal(robot_snapshot_writer_take(&writer, 5000, &ws, &write_us), 1);
    assert_int_equal(ws, HAL_OK);
    assert_true(write_us >= 50000U); /* it was held at the gate for more than the 50 ms above */
    assert_int_equal(robot_snapshot_writer_busy(&writer), 0);
    assert_int_equal(robot_snapshots_commit(&gens, &job, ws), COSLAM_OK);
    assert_true(gens.newest == 1 && gens.newest_seq == 2 && gens.saves == 2);
    /* on disk: the bytes handed over, not what the buffer holds now */
    robot_snapshots_t check;
    robot_snapshots_init(&check, &store.dev);
    assert_int_equal(robot_snapshots_load(&check, &snap_out, &name, NULL), COSLAM_OK);
    assert_string_equal(name, ROBOT_SNAPSHOT_NAME_B);
    assert_true(snap_out.seq == 2 && snap_out.map.pose.x == 2.0);

    /* a failed write: counted, the generations as they were */
    gate_set(1, HAL_E_IO);
    snap_in.map.pose.x = 3.0;
    assert_int_equal(robot_snapshots_prepare(&gens, &snap_in, &job), COSLAM_OK);
    assert_int_equal(robot_snapshot_writer_submit(&writer, &gated.dev, job.name, gens.buf, job.len), 0);
    assert_int_equal(robot_snapshot_writer_take(&writer, 5000, &ws, &write_us), 1);
    assert_int_equal(ws, HAL_E_IO);
    assert_int_equal(robot_snapshots_commit(&gens, &job, ws), COSLAM_E_STORAGE); /* was E_UNSUPPORTED */
    assert_true(gens.newest == 1 && gens.newest_seq == 2 && gens.save_failures == 1);
    assert_int_equal(gens.last_write, HAL_E_IO);
    robot_snapshots_init(&check, &store.dev);
    assert_int_equal(robot_snapshots_load(&check, &snap_out, &name, NULL), COSLAM_OK);
    assert_true(snap_out.seq == 2 && snap_out.map.pose.x == 2.0);
    /* each failure says what happened: a full medium is E_CAPACITY, a
     * storage that cannot write E_UNSUPPORTED, a failed or closed medium
     * E_STORAGE (all were E_UNSUPPORTED but the full one) */
    assert_int_equal(robot_snapshots_commit(&gens, &job, HAL_E_OVERFLOW), COSLAM_E_CAPACITY);
    assert_int_equal(robot_snapshots_commit(&gens, &job, HAL_E_UNSUPPORTED), COSLAM_E_UNSUPPORTED);
    assert_int_equal(robot_snapshots_commit(&gens, &job, HAL_E_CLOSED), COSLAM_E_STORAGE);
    assert_int_equal(robot_snapshots_commit(&gens, &job, HAL_E_BUSY), COSLAM_E_STORAGE);
    assert_int_equal(robot_snapshots_commit(&gens, &job, HAL_E_TIMEOUT), COSLAM_E_STORAGE);
    assert_int_equal(robot_snapshots_commit(&gens, &job, HAL_E_ARG), COSLAM_E_ARG);
    assert_true(gens.newest == 1 && gens.newest_seq == 2 && gens.save_failures == 7);
    assert_string_equal(coslam_status_str(COSLAM_E_STORAGE), "E_STORAGE");
    /* too large, bad name */
    assert_int_equal(robot_snapshot_writer_submit(&writer, &gated.dev, job.name, gens.buf, sizeof gens.buf + 1U),
                     E2BIG);
    assert_int_equal(robot_snapshot_writer_submit(&writer, &gated.dev, "a-name-longer-than-thirty-one-chars", gens.buf,
                                                  1U),
                     EINVAL);
    /* an idle writer stops at once, and twice */
    assert_int_equal(robot_snapshot_writer_stop(&writer, 0), 0);
    assert_int_equal(robot_snapshot_writer_stop(&writer, 0), 0);
    assert_int_equal(robot_snapshot_writer_take(&writer, 0, NULL, NULL), -1);

    /* a write that does not return: stop gives up after its wait, the thread is left to it */
    assert_int_equal(robot_snapshot_writer_start(&writer2), 0);
    gate_set(0, HAL_OK);
    const int entered = gated.entered;
    assert_int_equal(robot_snapshots_prepare(&gens, &snap_in, &job), COSLAM_OK);
    assert_int_equal(robot_snapshot_writer_submit(&writer2, &gated.dev, job.name, gens.buf, job.len), 0);
    gate_wait(&gated.entered, entered + 1);
    assert_int_equal(robot_snapshot_writer_stop(&writer2, 100), -1);
    const int finished = gated.finished;
    gate_set(1, HAL_OK);
    gate_wait(&gated.finished, finished + 1); /* the detached thread ends its write */
    robot_snapshots_init(&check, &store.dev);
    assert_int_equal(robot_snapshots_load(&check, &snap_out, &name, NULL), COSLAM_OK);
    assert_true(snap_out.seq == 3 && snap_out.map.pose.x == 3.0);
    usleep(20000); /* and leaves the writer's lock before the storage goes */

    hal_storage_close(&store.dev);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

/* ---- seeding -------------------------------------------------------------- */

static void assert_near(double a, double b, double tol, const char *what)
{
    if (!(fabs(a - b) <= tol)) {
        fprintf(stderr, "%s: %.17g vs %.17g (tol %g)\n", what, a, b, tol);
    }
    assert_true(fabs(a - b) <= tol);
}

static void assert_cov_near(cov2_t a, cov2_t b, double rel, const char *what)
{
    const double scale = fmax(fabs(a.xx) + fabs(a.yy), 1e-12);
    assert_near(a.xx, b.xx, rel * scale, what);
    assert_near(a.xy, b.xy, rel * scale, what);
    assert_near(a.yy, b.yy, rel * scale, what);
}

/* B (export after seeding from A) against A: everything but `cov` as saved;
 * `cov` as G P G^T + R cov_rel R^T (slam_filter_seed). */
static void check_seeded(const map_estimate_t *a, const map_estimate_t *b, double rel)
{
    assert_near(a->pose.x, b->pose.x, 1e-12, "pose.x");
    assert_near(a->pose.y, b->pose.y, 1e-12, "pose.y");
    assert_near(a->pose.theta, b->pose.theta, 1e-12, "pose.theta");
    const double ps = a->pose_cov.m[0][0] + a->pose_cov.m[1][1] + a->pose_cov.m[2][2];
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            assert_near(a->pose_cov.m[r][c], b->pose_cov.m[r][c], rel * ps, "pose_cov");
        }
    }
    assert_int_equal(a->n_landmarks, b->n_landmarks);
    const double c = cos(a->pose.theta);
    const double s = sin(a->pose.theta);
    for (int i = 0; i < a->n_landmarks; ++i) {
        const map_landmark_t *x = &a->lm[i];
        const map_landmark_t *y = &b->lm[i];
        assert_int_equal(x->id, y->id);
        assert_int_equal(x->n_obs, y->n_obs);
        assert_int_equal(x->src_mask, y->src_mask);
        assert_int_equal(x->signature, y->signature);
        assert_near(x->mean.x, y->mean.x, 1e-9, "mean.x");
        assert_near(x->mean.y, y->mean.y, 1e-9, "mean.y");
        assert_cov_near(x->cov_rel, y->cov_rel, rel, "cov_rel");
        /* cov = G P G^T + R C R^T, G = [1 0 -(my - py); 0 1 (mx - px)] */
        double g[2][3] = {{1.0, 0.0, -(x->mean.y - a->pose.y)}, {0.0, 1.0, x->mean.x - a->pose.x}};
        double p[3][3];
        memcpy(p, a->pose_cov.m, sizeof p);
        const cov2_t gpg = cov2_from_3x3(g, p);
        double rm[2][2] = {{c, -s}, {s, c}};
        const cov2_t want = cov2_add(gpg, cov2_congruence(rm, x->cov_rel));
        assert_cov_near(want, y->cov, rel, "cov");
    }
}

static void check_fixed_point(const map_estimate_t *b, const map_estimate_t *c)
{
    assert_int_equal(b->n_landmarks, c->n_landmarks);
    for (int i = 0; i < b->n_landmarks; ++i) {
        assert_near(b->lm[i].mean.x, c->lm[i].mean.x, 1e-9, "fixed point mean");
        assert_cov_near(b->lm[i].cov, c->lm[i].cov, 1e-6, "fixed point cov");
        assert_cov_near(b->lm[i].cov_rel, c->lm[i].cov_rel, 1e-6, "fixed point cov_rel");
        assert_int_equal(b->lm[i].id, c->lm[i].id);
    }
}

static void seed_and_compare(slam_filter_kind_t kind, double rel)
{
    build_map(&filter_a, kind, &map_a);
    slam_filter_config_t c = slam_filter_config_default();
    c.kind = kind;
    c.n_particles = 50;
    c.robot_id = 1;
    assert_int_equal(slam_filter_seed(&filter_b, &c, &map_a), COSLAM_OK);
    assert_int_equal(slam_filter_export(&filter_b, &map_b), COSLAM_OK);
    check_seeded(&map_a, &map_b, rel);
    /* seeding from that export gives it again */
    assert_int_equal(slam_filter_seed(&filter_b, &c, &map_b), COSLAM_OK);
    assert_int_equal(slam_filter_export(&filter_b, &map_c), COSLAM_OK);
    check_fixed_point(&map_b, &map_c);
    /* the seeded filter goes on: a prediction and an empty frame keep every
     * landmark, and new identities do not collide with the saved ones */
    assert_int_equal(slam_filter_predict(&filter_b, (odo_increment_t){0.01, 0.0, 0.0}, 0.1), COSLAM_OK);
    const coslam_status_t st = slam_filter_update(&filter_b, NULL, 0);
    assert_true(st == COSLAM_OK);
    assert_int_equal(slam_filter_export(&filter_b, &map_c), COSLAM_OK);
    assert_int_equal(map_c.n_landmarks, map_b.n_landmarks);
    uint32_t max_id = 0;
    for (int i = 0; i < map_a.n_landmarks; ++i) {
        max_id = map_a.lm[i].id > max_id ? map_a.lm[i].id : max_id;
    }
    const uint32_t next = kind == SLAM_FILTER_EKF ? filter_b.u.ekf.next_id : filter_b.u.fs.next_id;
    assert_true(next > max_id);
}

static void seed_ekf(void **state)
{
    (void)state;
    seed_and_compare(SLAM_FILTER_EKF, 1e-9);
}

static void seed_fastslam2(void **state)
{
    (void)state;
    /* the anchors hold floats: relative precision 1e-6 */
    seed_and_compare(SLAM_FILTER_FASTSLAM2, 1e-6);
}

static void seed_fastslam1(void **state)
{
    (void)state;
    seed_and_compare(SLAM_FILTER_FASTSLAM1, 1e-6);
}

static void seed_refuses_bad_maps(void **state)
{
    (void)state;
    build_map(&filter_a, SLAM_FILTER_EKF, &map_a);
    slam_filter_config_t c = slam_filter_config_default();
    c.kind = SLAM_FILTER_EKF;
    map_b = map_a;
    map_b.lm[0].cov_rel.xx = -1.0;
    assert_int_equal(slam_filter_seed(&filter_b, &c, &map_b), COSLAM_E_ARG);
    assert_int_equal(slam_filter_export(&filter_b, &map_c), COSLAM_OK);
    assert_int_equal(map_c.n_landmarks, 0); /* started empty at the pose */
    map_b = map_a;
    map_b.lm[1].id = 0;
    assert_int_equal(slam_filter_seed(&filter_b, &c, &map_b), COSLAM_E_ARG);
    /* a pose covariance that is not one: indefinite (|xy| > sqrt(xx yy)),
     * and asymmetric; either would go into P or every particle's marginal */
    for (int bad = 0; bad < 2; ++bad) {
        map_b = map_a;
        map_b.pose_cov = cov3_diag(0.01, 0.01, 0.001);
        map_b.pose_cov.m[0][1] = bad == 0 ? 1.0 : 0.001;
        map_b.pose_cov.m[1][0] = bad == 0 ? 1.0 : 0.0;
        assert_int_equal(slam_filter_seed(&filter_b, &c, &map_b), COSLAM_E_ARG);
    }
    map_b = map_a;
    map_b.pose.x = NAN;
    assert_int_equal(slam_filter_seed(&filter_b, &c, &map_b), COSLAM_E_ARG);
    /* an EKF map into Fast-SLAM: the map estimate is the common format */
    c.kind = SLAM_FILTER_FASTSLAM2;
    c.n_particles = 20;
    assert_int_equal(slam_filter_seed(&filter_b, &c, &map_a), COSLAM_OK);
    assert_int_equal(slam_filter_export(&filter_b, &map_c), COSLAM_OK);
    assert_int_equal(map_c.n_landmarks, map_a.n_landmarks);
}

/* ---- through the robot node ------------------------------------------------ */

static robot_node_t node;

static void node_restore(void **state)
{
    (void)state;
    build_map(&filter_a, SLAM_FILTER_FASTSLAM2, &map_a);
    static const hal_serial_ops_t no_serial = {0};
    static hal_serial_t serial = {&no_serial, NULL};
    static const sighting_source_ops_t no_frames = {0};
    static sighting_source_t sightings = {&no_frames, NULL};
    robot_node_io_t io = {hal_clock_linux(), &serial, hal_can_null(), hal_gpio_null(), hal_link_null(), &sightings};
    robot_node_config_t cfg = robot_node_config_default(1, 2);
    cfg.filter.n_particles = 50;
    cfg.laser_optional = 1;
    /* no GPIO lines: refused unless optional */
    assert_int_equal(robot_node_init(&node, &cfg, &io), COSLAM_E_UNSUPPORTED);
    cfg.gpio_optional = 1;
    assert_int_equal(robot_node_init(&node, &cfg, &io), COSLAM_OK);
    assert_false(robot_node_gpio_attached(&node));
    assert_int_equal(robot_node_counters(&node)->gpio_attach_failures, 1);
    /* a map the filter refuses: a new map, but the numbers go on (else
     * every peer takes the robot's messages for replays) */
    map_c = map_a;
    map_c.lm[0].cov_rel.xx = -1.0;
    assert_int_equal(robot_node_restore(&node, &map_c, 5000), COSLAM_E_ARG);
    assert_int_equal(robot_node_msg_seq(&node), 5000);
    assert_int_equal(robot_node_restore(&node, &map_a, 41), COSLAM_OK);
    assert_int_equal(robot_node_msg_seq(&node), 41);
    assert_int_equal(robot_node_export(&node, &map_b), COSLAM_OK);
    check_seeded(&map_a, &map_b, 1e-6);
    pose2_t pose;
    cov3_t cov;
    robot_node_pose(&node, &pose, &cov);
    assert_near(pose.x, map_a.pose.x, 1e-12, "node pose");
    /* a few steps with nothing attached: no crash, the map stays */
    for (int k = 0; k < 5; ++k) {
        (void)robot_node_step(&node);
    }
    /* no CAN bus: the drive reports its fault, the node stops anyway */
    const coslam_status_t sd = robot_node_shutdown(&node);
    assert_true(sd == COSLAM_OK || sd == COSLAM_E_DRIVE_FAULT);
    assert_int_equal(robot_node_state(&node), ROBOT_NODE_SHUTDOWN);
    assert_int_equal(robot_node_step(&node), COSLAM_OK);
    assert_int_equal(robot_node_export(&node, &map_c), COSLAM_OK);
    assert_int_equal(map_c.n_landmarks, map_a.n_landmarks);
}

int main(int argc, char **argv)
{
    if (argc > 1) {
        cmocka_set_test_filter(argv[1]);
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(codec_round_trip_is_byte_exact),
        cmocka_unit_test(every_damage_is_caught),
        cmocka_unit_test(generations_fall_back_to_the_older),
        cmocka_unit_test(pose_covariance_must_be_psd),
        cmocka_unit_test(an_unwritable_generation_is_passed_over),
        cmocka_unit_test(writer_does_not_hold_the_caller),
        cmocka_unit_test(seed_ekf),
        cmocka_unit_test(seed_fastslam2),
        cmocka_unit_test(seed_fastslam1),
        cmocka_unit_test(seed_refuses_bad_maps),
        cmocka_unit_test(node_restore),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
