/*
 * Map-message codec (coslam/map_msg.h, coslam/crc32.h):
 *  - CRC-32 check value and agreement with a bitwise reference;
 *  - the wire layout, three ways: a hand-built golden byte vector, an
 *    independent serialiser written here from the header's table (must match
 *    the codec byte for byte on random messages), and round trips;
 *  - every rejection path with its distinct code, on decode (bytes), on
 *    encode and in map_msg_validate (struct), and *out untouched on error;
 *  - a seeded mutation fuzz: the decoder never crashes or reads out of
 *    bounds (each input sits in an exact-size heap block; the _san variant
 *    runs it under ASan/UBSan) and either rejects or returns a message that
 *    re-encodes to the same bytes.
 * Built twice: against the default core and against a small-capacity core
 * (COSLAM_MAX_ROBOTS=8, COSLAM_MAX_MSG_LANDMARKS=4).
 */
#include <float.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "coslam/crc32.h"
#include "coslam/map_msg.h"
#include "coslam/rng.h"

#define CAP COSLAM_MAX_MSG_LANDMARKS

/* Wire offsets, written from the table in map_msg.h (not from the codec). */
enum {
    W_MAGIC = 0, W_VERSION = 4, W_SENDER = 5, W_RECEIVER = 6, W_FLAGS = 7, W_LENGTH = 8,
    W_SEQ = 12, W_STAMP = 16, W_X = 24, W_Y = 32, W_TH = 40,
    W_PXX = 48, W_PXY = 56, W_PXT = 64, W_PYY = 72, W_PYT = 80, W_PTT = 88,
    W_RANGE = 96, W_BEARING = 104, W_RVAR = 112, W_BVAR = 120, W_SSTAMP = 128,
    W_N = 136, W_LM = 138, W_LM_SIZE = 73,
    L_X = 0, L_Y = 8, L_XX = 16, L_XY = 24, L_YY = 32, L_RXX = 40, L_RXY = 48, L_RYY = 56,
    L_ID = 64, L_NOBS = 68, L_MASK = 70, L_SIG = 72,
    L_N_F64 = 8, /* f64 fields per landmark: mean (2), cov (3), cov_rel (3) */
};

/* ---------------------------------------------------------------------------
 * Test-side helpers: an independent little-endian writer and serialiser. */

static void wr_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void wr_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

static void wr_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; ++i) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

static void wr_f64(uint8_t *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, 8);
    wr_u64(p, u);
}

static uint32_t rd_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Bitwise CRC-32 (reflected 0xEDB88320), the textbook definition. */
static uint32_t ref_crc32(const uint8_t *d, size_t n)
{
    uint32_t c = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; ++i) {
        c ^= d[i];
        for (int k = 0; k < 8; ++k) {
            c = (c & 1u) ? (c >> 1) ^ 0xEDB88320u : c >> 1;
        }
    }
    return ~c;
}

/* Set the length field to len and recompute the CRC (len >= 16). */
static void refresh(uint8_t *buf, size_t len)
{
    wr_u32(buf + W_LENGTH, (uint32_t)len);
    wr_u32(buf + len - 4, ref_crc32(buf, len - 4));
}

/* Serialise without any validation, straight from the header's table; the
 * sighting fields are written as given even when not valid. Returns the size. */
static size_t raw_encode(const map_msg_t *m, uint8_t *buf)
{
    const map_estimate_t *e = &m->map;
    memcpy(buf + W_MAGIC, "CSLM", 4);
    buf[W_VERSION] = m->version;
    buf[W_SENDER] = m->sender_id;
    buf[W_RECEIVER] = m->receiver_id;
    buf[W_FLAGS] = m->sighting.valid ? 1 : 0;
    wr_u32(buf + W_SEQ, m->seq);
    wr_u64(buf + W_STAMP, m->stamp_us);
    wr_f64(buf + W_X, e->pose.x);
    wr_f64(buf + W_Y, e->pose.y);
    wr_f64(buf + W_TH, e->pose.theta);
    wr_f64(buf + W_PXX, e->pose_cov.m[0][0]);
    wr_f64(buf + W_PXY, e->pose_cov.m[0][1]);
    wr_f64(buf + W_PXT, e->pose_cov.m[0][2]);
    wr_f64(buf + W_PYY, e->pose_cov.m[1][1]);
    wr_f64(buf + W_PYT, e->pose_cov.m[1][2]);
    wr_f64(buf + W_PTT, e->pose_cov.m[2][2]);
    wr_f64(buf + W_RANGE, m->sighting.range_m);
    wr_f64(buf + W_BEARING, m->sighting.bearing_rad);
    wr_f64(buf + W_RVAR, m->sighting.range_var_m2);
    wr_f64(buf + W_BVAR, m->sighting.bearing_var_rad2);
    wr_u64(buf + W_SSTAMP, m->sighting.stamp_us);
    wr_u16(buf + W_N, e->n_landmarks);
    const size_t n = e->n_landmarks <= CAP ? e->n_landmarks : CAP;
    for (size_t i = 0; i < n; ++i) {
        uint8_t *p = buf + W_LM + W_LM_SIZE * i;
        const map_landmark_t *l = &e->lm[i];
        wr_f64(p + L_X, l->mean.x);
        wr_f64(p + L_Y, l->mean.y);
        wr_f64(p + L_XX, l->cov.xx);
        wr_f64(p + L_XY, l->cov.xy);
        wr_f64(p + L_YY, l->cov.yy);
        wr_f64(p + L_RXX, l->cov_rel.xx);
        wr_f64(p + L_RXY, l->cov_rel.xy);
        wr_f64(p + L_RYY, l->cov_rel.yy);
        wr_u32(p + L_ID, l->id);
        wr_u16(p + L_NOBS, l->n_obs);
        wr_u16(p + L_MASK, l->src_mask);
        p[L_SIG] = l->signature;
    }
    const size_t len = (size_t)W_LM + (size_t)W_LM_SIZE * n + 4;
    refresh(buf, len);
    return len;
}

static double uni(rng_t *r, double lo, double hi)
{
    return lo + (hi - lo) * rng_uniform(r);
}

static uint16_t team_mask(void)
{
    return (uint16_t)((1u << COSLAM_MAX_ROBOTS) - 1u);
}

/* A valid message with n landmarks, ids strictly increasing, random values. */
static void make_msg(map_msg_t *m, uint16_t n, uint64_t seed)
{
    rng_t r;
    rng_seed(&r, seed);
    map_msg_init(m);
    m->sender_id = 1;
    m->receiver_id = 2;
    m->seq = (uint32_t)rng_next_u64(&r);
    m->stamp_us = rng_next_u64(&r);
    m->map.pose.x = uni(&r, -50.0, 50.0);
    m->map.pose.y = uni(&r, -50.0, 50.0);
    m->map.pose.theta = uni(&r, -COSLAM_PI, COSLAM_PI);
    /* P = A A^T + 1e-3 I, symmetric by construction (both triangles equal) */
    double a[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            a[i][j] = uni(&r, -0.3, 0.3);
        }
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j <= i; ++j) {
            double s = (i == j) ? 1e-3 : 0.0;
            for (int k = 0; k < 3; ++k) {
                s += a[i][k] * a[j][k];
            }
            m->map.pose_cov.m[i][j] = s;
            m->map.pose_cov.m[j][i] = s;
        }
    }
    m->sighting.valid = true;
    m->sighting.range_m = uni(&r, 0.2, 6.0);
    m->sighting.bearing_rad = uni(&r, -COSLAM_PI, COSLAM_PI);
    m->sighting.range_var_m2 = uni(&r, 1e-4, 0.1);
    m->sighting.bearing_var_rad2 = uni(&r, 1e-5, 0.05);
    m->sighting.stamp_us = m->stamp_us - (rng_next_u64(&r) % 100000u);
    m->map.n_landmarks = n;
    uint32_t id = 1u + (uint32_t)(rng_next_u64(&r) % 100u);
    for (uint16_t i = 0; i < n; ++i) {
        map_landmark_t *l = &m->map.lm[i];
        l->mean.x = uni(&r, -30.0, 30.0);
        l->mean.y = uni(&r, -30.0, 30.0);
        const double sx = uni(&r, 1e-3, 0.5), sy = uni(&r, 1e-3, 0.5), rho = uni(&r, -0.95, 0.95);
        l->cov.xx = sx * sx;
        l->cov.yy = sy * sy;
        l->cov.xy = rho * sx * sy;
        /* relative covariance: drawn independently, so a codec that mixed
         * up cov and cov_rel would not round-trip */
        const double rx = uni(&r, 1e-3, 0.3), ry = uni(&r, 1e-3, 0.3), rr = uni(&r, -0.95, 0.95);
        l->cov_rel.xx = rx * rx;
        l->cov_rel.yy = ry * ry;
        l->cov_rel.xy = rr * rx * ry;
        l->id = id;
        id += 1u + (uint32_t)(rng_next_u64(&r) % 1000u);
        l->n_obs = (uint16_t)(1u + rng_next_u64(&r) % 500u);
        l->src_mask = (uint16_t)(1u + rng_next_u64(&r) % team_mask());
        l->signature = (uint8_t)(rng_next_u64(&r) % 4u);
    }
}

static int same_f64(double a, double b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

#define ASSERT_SAME_F64(a, b)                                                                  \
    do {                                                                                       \
        if (!same_f64((a), (b))) {                                                             \
            fail_msg("%s = %.17g differs (bit pattern) from %s = %.17g", #a, (a), #b, (b)); \
        }                                                                                      \
    } while (0)

/* Field-by-field, bit-exact equality (structs have padding: no memcmp). */
static void assert_msg_equal(const map_msg_t *a, const map_msg_t *b)
{
    assert_int_equal(a->version, b->version);
    assert_int_equal(a->sender_id, b->sender_id);
    assert_int_equal(a->receiver_id, b->receiver_id);
    assert_int_equal(a->seq, b->seq);
    assert_true(a->stamp_us == b->stamp_us);
    ASSERT_SAME_F64(a->map.pose.x, b->map.pose.x);
    ASSERT_SAME_F64(a->map.pose.y, b->map.pose.y);
    ASSERT_SAME_F64(a->map.pose.theta, b->map.pose.theta);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            ASSERT_SAME_F64(a->map.pose_cov.m[i][j], b->map.pose_cov.m[i][j]);
        }
    }
    assert_int_equal(a->sighting.valid, b->sighting.valid);
    ASSERT_SAME_F64(a->sighting.range_m, b->sighting.range_m);
    ASSERT_SAME_F64(a->sighting.bearing_rad, b->sighting.bearing_rad);
    ASSERT_SAME_F64(a->sighting.range_var_m2, b->sighting.range_var_m2);
    ASSERT_SAME_F64(a->sighting.bearing_var_rad2, b->sighting.bearing_var_rad2);
    assert_true(a->sighting.stamp_us == b->sighting.stamp_us);
    assert_int_equal(a->map.n_landmarks, b->map.n_landmarks);
    for (uint16_t i = 0; i < a->map.n_landmarks; ++i) {
        const map_landmark_t *x = &a->map.lm[i], *y = &b->map.lm[i];
        ASSERT_SAME_F64(x->mean.x, y->mean.x);
        ASSERT_SAME_F64(x->mean.y, y->mean.y);
        ASSERT_SAME_F64(x->cov.xx, y->cov.xx);
        ASSERT_SAME_F64(x->cov.xy, y->cov.xy);
        ASSERT_SAME_F64(x->cov.yy, y->cov.yy);
        ASSERT_SAME_F64(x->cov_rel.xx, y->cov_rel.xx);
        ASSERT_SAME_F64(x->cov_rel.xy, y->cov_rel.xy);
        ASSERT_SAME_F64(x->cov_rel.yy, y->cov_rel.yy);
        assert_int_equal(x->id, y->id);
        assert_int_equal(x->n_obs, y->n_obs);
        assert_int_equal(x->src_mask, y->src_mask);
        assert_int_equal(x->signature, y->signature);
    }
}

/* Message-sized scratch objects (too big for comfortable stack use in CI
 * thread stacks of the large profile): static, reset by each test. */
static map_msg_t g_a, g_b, g_sentinel;
/* Slack past the largest message: one extra landmark (test_reject_count) and
 * up to 16 inserted or appended bytes (the mutation fuzz), plus margin. */
#define BUF_SLACK (MAP_MSG_LANDMARK_BYTES + 64U)
static uint8_t g_buf[MAP_MSG_MAX_BYTES + BUF_SLACK];
static uint8_t g_buf2[MAP_MSG_MAX_BYTES + BUF_SLACK];

/* Decode a copy of bytes held in an exact-size heap block (so ASan sees any
 * read past the end), into a sentinel-filled output; on error assert the
 * output was not touched. */
static coslam_status_t decode_exact(const uint8_t *bytes, size_t len, map_msg_t *out)
{
    uint8_t *copy = malloc(len > 0 ? len : 1);
    assert_non_null(copy);
    if (len > 0) {
        memcpy(copy, bytes, len);
    }
    memset(out, 0xA5, sizeof *out);
    memset(&g_sentinel, 0xA5, sizeof g_sentinel);
    const coslam_status_t st = map_msg_decode(copy, len, out);
    free(copy);
    if (st != COSLAM_OK) {
        assert_memory_equal(out, &g_sentinel, sizeof *out);
    }
    return st;
}

/* Encode, decode, compare fields, re-encode, compare bytes. */
static void roundtrip(const map_msg_t *m)
{
    size_t len = 0;
    const size_t want = MAP_MSG_BYTES(m->map.n_landmarks);
    assert_int_equal(map_msg_encoded_size(m), want);
    assert_int_equal(map_msg_validate(m), COSLAM_OK);
    assert_int_equal(map_msg_encode(m, g_buf, want, &len), COSLAM_OK);
    assert_int_equal(len, want);
    /* the independent serialiser agrees byte for byte */
    assert_int_equal(raw_encode(m, g_buf2), want);
    assert_memory_equal(g_buf, g_buf2, want);
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_OK);
    assert_msg_equal(m, &g_b);
    size_t len2 = 0;
    assert_int_equal(map_msg_encode(&g_b, g_buf2, sizeof g_buf2, &len2), COSLAM_OK);
    assert_int_equal(len2, len);
    assert_memory_equal(g_buf, g_buf2, len);
}

/* ------------------------------------------------------------------------- */

static void test_crc32(void **state)
{
    (void)state;
    const uint8_t check[] = "123456789";
    assert_int_equal(crc32_update(0, check, 9), 0xCBF43926u);
    assert_int_equal(crc32_update(0, NULL, 0), 0u);
    assert_int_equal(crc32_update(0, (const uint8_t *)"a", 1), 0xE8B7BE43u);
    /* chaining at every split point equals the one-shot value */
    for (size_t k = 0; k <= 9; ++k) {
        assert_int_equal(crc32_update(crc32_update(0, check, k), check + k, 9 - k), 0xCBF43926u);
    }
    /* table-driven = bitwise definition on random data of every length */
    rng_t r;
    rng_seed(&r, 32);
    uint8_t d[300];
    for (size_t i = 0; i < sizeof d; ++i) {
        d[i] = (uint8_t)rng_next_u64(&r);
    }
    for (size_t n = 0; n <= sizeof d; ++n) {
        assert_int_equal(crc32_update(0, d, n), ref_crc32(d, n));
    }
}

static void test_sizes(void **state)
{
    (void)state;
    assert_int_equal(MAP_MSG_HEADER_BYTES, W_LM);
    assert_int_equal(MAP_MSG_LANDMARK_BYTES, W_LM_SIZE);
    assert_int_equal(MAP_MSG_MIN_BYTES, 142);
    assert_int_equal(MAP_MSG_LANDMARK_BYTES, 8 * L_N_F64 + 4 + 2 + 2 + 1);
    assert_int_equal(MAP_MSG_BYTES(2), 288);
    assert_int_equal(MAP_MSG_MAX_BYTES, 142 + 73 * CAP);
    assert_int_equal(MAP_MSG_VERSION, 2);
#if COSLAM_MAX_MSG_LANDMARKS == 64
    assert_int_equal(MAP_MSG_MAX_BYTES, 4814);
#elif COSLAM_MAX_MSG_LANDMARKS == 221 /* large and host: capped at the link (config.h) */
    assert_int_equal(MAP_MSG_MAX_BYTES, 16275);
    assert_true(MAP_MSG_MAX_BYTES + 64 <= 16384);
#endif
    map_msg_init(&g_a);
    assert_int_equal(g_a.version, MAP_MSG_VERSION);
    assert_int_equal(g_a.receiver_id, MAP_MSG_BROADCAST);
    assert_false(g_a.sighting.valid);
    assert_int_equal(g_a.map.n_landmarks, 0);
    assert_int_equal(map_msg_encoded_size(&g_a), 142);
    g_a.map.n_landmarks = CAP + 1;
    assert_int_equal(map_msg_encoded_size(&g_a), 0);
    assert_int_equal(map_msg_encoded_size(NULL), 0);
}

static void test_roundtrip_empty(void **state)
{
    (void)state;
    make_msg(&g_a, 0, 1);
    roundtrip(&g_a);
    /* broadcast, no sighting: the sighting comes back as zeros */
    g_a.receiver_id = MAP_MSG_BROADCAST;
    memset(&g_a.sighting, 0, sizeof g_a.sighting);
    roundtrip(&g_a);
}

static void test_roundtrip_one(void **state)
{
    (void)state;
    make_msg(&g_a, 1, 2);
    roundtrip(&g_a);
}

static void test_roundtrip_full(void **state)
{
    (void)state;
    for (uint64_t seed = 3; seed < 8; ++seed) {
        make_msg(&g_a, CAP, seed);
        roundtrip(&g_a);
    }
}

/* Values at the edges of every field's domain survive bit for bit. */
static void test_roundtrip_extremes(void **state)
{
    (void)state;
    const uint16_t n = CAP < 4 ? CAP : 4;
    make_msg(&g_a, n, 9);
    g_a.sender_id = COSLAM_MAX_ROBOTS - 1;
    g_a.receiver_id = 0;
    g_a.seq = UINT32_MAX;
    g_a.stamp_us = UINT64_MAX;
    g_a.map.pose.x = -0.0;
    g_a.map.pose.y = DBL_TRUE_MIN;
    g_a.map.pose.theta = -COSLAM_PI;
    g_a.sighting.range_m = 0.0;
    g_a.sighting.bearing_rad = COSLAM_PI;
    g_a.sighting.range_var_m2 = DBL_TRUE_MIN;
    g_a.sighting.bearing_var_rad2 = DBL_MAX;
    g_a.sighting.stamp_us = UINT64_MAX;
    map_landmark_t *l = g_a.map.lm;
    l[0].mean.x = -DBL_MAX;
    l[0].mean.y = DBL_MAX;
    l[0].cov = cov2_make(DBL_MAX, -0.0, DBL_MAX); /* det overflows to +inf: still PD */
    /* nearly singular (det about 2.2e-16): PD, and must survive bit for bit */
    l[0].cov_rel = cov2_make(1.0, nextafter(1.0, 0.0), 1.0);
    l[0].id = UINT32_MAX;
    l[0].n_obs = UINT16_MAX;
    l[0].src_mask = team_mask();
    l[0].signature = UINT8_MAX;
    if (n > 1) {
        l[1].id = 1; /* ids not sorted: the all-pairs duplicate check runs */
        l[1].n_obs = 0;
        l[1].signature = 0;
        l[1].cov = cov2_make(1e-150, 0.0, 1e-150);
        l[1].cov_rel = cov2_make(DBL_MAX, -0.0, DBL_MAX);
    }
    roundtrip(&g_a);
    g_a.map.pose.theta = COSLAM_PI;
    roundtrip(&g_a);
    /* tiny uncorrelated cov_rel (det 1e-300, well above the underflow limit) */
    l[0].cov_rel = cov2_make(1e-150, -0.0, 1e-150);
    roundtrip(&g_a);
}

/* The layout, proven by hand: every byte below was written from the table in
 * map_msg.h; only the CRC was computed elsewhere (Python's zlib.crc32 over
 * the 284 bytes before it, built there with struct.pack from the same
 * values). */
#define F64(b6, b7) 0, 0, 0, 0, 0, 0, b6, b7
static const uint8_t golden[288] = {
    'C', 'S', 'L', 'M',                           /* magic */
    2,                                            /* version */
    3,                                            /* sender */
    1,                                            /* receiver */
    0x01,                                         /* flags: sighting valid */
    0x20, 0x01, 0x00, 0x00,                       /* length 288 */
    0x04, 0x03, 0x02, 0x01,                       /* seq 0x01020304 */
    0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11, /* stamp 0x1122334455667788 */
    F64(0xF8, 0x3F),                              /* x 1.5 */
    F64(0x00, 0xC0),                              /* y -2.0 */
    F64(0xE0, 0x3F),                              /* theta 0.5 */
    F64(0xD0, 0x3F),                              /* P xx 0.25 */
    F64(0xA0, 0x3F),                              /* P xy 0.03125 */
    F64(0x00, 0x00),                              /* P xt 0 */
    F64(0xB0, 0x3F),                              /* P yy 0.0625 */
    F64(0x90, 0xBF),                              /* P yt -0.015625 */
    F64(0xC0, 0x3F),                              /* P tt 0.125 */
    F64(0x04, 0x40),                              /* range 2.5 */
    F64(0xE8, 0xBF),                              /* bearing -0.75 */
    F64(0x90, 0x3F),                              /* range var 0.015625 */
    F64(0x70, 0x3F),                              /* bearing var 0.00390625 */
    0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, /* sighting stamp 0x100000002 */
    0x02, 0x00,                                   /* n = 2 */
    /* landmark 0 */
    F64(0x08, 0x40),                              /* x 3.0 */
    F64(0xF0, 0xBF),                              /* y -1.0 */
    F64(0xE0, 0x3F),                              /* xx 0.5 */
    F64(0xC0, 0xBF),                              /* xy -0.125 */
    F64(0xD0, 0x3F),                              /* yy 0.25 */
    F64(0xD8, 0x3F),                              /* rel xx 0.375 */
    F64(0xB0, 0x3F),                              /* rel xy 0.0625 */
    F64(0xC0, 0x3F),                              /* rel yy 0.125 */
    0x07, 0x00, 0x00, 0x00,                       /* id 7 */
    0x0C, 0x00,                                   /* n_obs 12 */
    0x0A, 0x00,                                   /* src_mask 0x000A */
    0x02,                                         /* signature 2 */
    /* landmark 1 */
    F64(0x11, 0xC0),                              /* x -4.25 */
    F64(0x00, 0x00),                              /* y 0 */
    F64(0xF0, 0x3F),                              /* xx 1.0 */
    F64(0x00, 0x00),                              /* xy 0 */
    F64(0x00, 0x40),                              /* yy 2.0 */
    F64(0xE8, 0x3F),                              /* rel xx 0.75 */
    F64(0xE0, 0xBF),                              /* rel xy -0.5 */
    F64(0xF8, 0x3F),                              /* rel yy 1.5 */
    0x02, 0x01, 0x00, 0x00,                       /* id 258 */
    0x01, 0x00,                                   /* n_obs 1 */
    0x08, 0x00,                                   /* src_mask 0x0008 */
    0x00,                                         /* signature 0 */
    0xD3, 0x80, 0x80, 0x9C,                       /* CRC-32 0x9C8080D3 */
};

static void golden_msg(map_msg_t *m)
{
    map_msg_init(m);
    m->sender_id = 3;
    m->receiver_id = 1;
    m->seq = 0x01020304u;
    m->stamp_us = 0x1122334455667788ull;
    m->map.pose = (pose2_t){1.5, -2.0, 0.5};
    const double p[3][3] = {{0.25, 0.03125, 0.0}, {0.03125, 0.0625, -0.015625}, {0.0, -0.015625, 0.125}};
    memcpy(m->map.pose_cov.m, p, sizeof p);
    m->sighting = (map_msg_sighting_t){true, 2.5, -0.75, 0.015625, 0.00390625, 0x100000002ull};
    m->map.n_landmarks = 2;
    m->map.lm[0] = (map_landmark_t){{3.0, -1.0}, {0.5, -0.125, 0.25}, {0.375, 0.0625, 0.125}, 7, 12, 0x000A, 2};
    m->map.lm[1] = (map_landmark_t){{-4.25, 0.0}, {1.0, 0.0, 2.0}, {0.75, -0.5, 1.5}, 258, 1, 0x0008, 0};
}

static void test_golden_vector(void **state)
{
    (void)state;
    /* the CRC literal is the CRC of the hand-written bytes */
    assert_int_equal(ref_crc32(golden, 284), 0x9C8080D3u);
    assert_int_equal(rd_u32(golden + 284), 0x9C8080D3u);
    golden_msg(&g_a);
    size_t len = 0;
    memset(g_buf, 0xEE, sizeof g_buf);
    assert_int_equal(map_msg_encode(&g_a, g_buf, sizeof g_buf, &len), COSLAM_OK);
    assert_int_equal(len, sizeof golden);
    for (size_t i = 0; i < sizeof golden; ++i) {
        if (g_buf[i] != golden[i]) {
            fail_msg("byte %zu: encoded 0x%02X, golden 0x%02X", i, g_buf[i], golden[i]);
        }
    }
    assert_int_equal(g_buf[len], 0xEE); /* nothing written past the message */
    assert_int_equal(decode_exact(golden, sizeof golden, &g_b), COSLAM_OK);
    assert_msg_equal(&g_a, &g_b);
}

static void test_encode_args_and_capacity(void **state)
{
    (void)state;
    make_msg(&g_a, 3, 11);
    const size_t need = MAP_MSG_BYTES(3);
    size_t len = 123;
    assert_int_equal(map_msg_encode(NULL, g_buf, sizeof g_buf, &len), COSLAM_E_ARG);
    assert_int_equal(len, 0);
    assert_int_equal(map_msg_encode(&g_a, NULL, sizeof g_buf, &len), COSLAM_E_ARG);
    assert_int_equal(map_msg_encode(&g_a, g_buf, sizeof g_buf, NULL), COSLAM_E_ARG);
    assert_int_equal(map_msg_decode(NULL, 10, &g_b), COSLAM_E_ARG);
    assert_int_equal(map_msg_decode(g_buf, 10, NULL), COSLAM_E_ARG);
    assert_int_equal(map_msg_validate(NULL), COSLAM_E_ARG);
    /* one byte short: refused, and nothing at or past cap is written */
    memset(g_buf, 0xEE, sizeof g_buf);
    len = 123;
    assert_int_equal(map_msg_encode(&g_a, g_buf, need - 1, &len), COSLAM_E_CAPACITY);
    assert_int_equal(len, 0);
    for (size_t i = need - 1; i < sizeof g_buf; ++i) {
        assert_int_equal(g_buf[i], 0xEE);
    }
    assert_int_equal(map_msg_encode(&g_a, g_buf, need, &len), COSLAM_OK);
    assert_int_equal(len, need);
}

/* ---------------------------------------------------------------------------
 * Rejections expressible in the struct: each is checked three ways, with the
 * same code: map_msg_validate, map_msg_encode, and map_msg_decode of the
 * bytes the unvalidated serialiser writes for the bad struct. */

typedef struct {
    const char *name;
    void (*mutate)(map_msg_t *m);
    coslam_status_t code;
} struct_case_t;

static void m_version(map_msg_t *m) { m->version = 1; } /* the previous layout */
static void m_count(map_msg_t *m) { m->map.n_landmarks = CAP + 1; }
static void m_sender(map_msg_t *m) { m->sender_id = COSLAM_MAX_ROBOTS; }
static void m_sender_bcast(map_msg_t *m) { m->sender_id = MAP_MSG_BROADCAST; }
static void m_receiver(map_msg_t *m) { m->receiver_id = COSLAM_MAX_ROBOTS; }
static void m_receiver_self(map_msg_t *m) { m->receiver_id = m->sender_id; }
static void m_pose_nan(map_msg_t *m) { m->map.pose.x = NAN; }
static void m_pose_inf(map_msg_t *m) { m->map.pose.theta = -INFINITY; }
static void m_pcov_nan(map_msg_t *m) { m->map.pose_cov.m[1][2] = m->map.pose_cov.m[2][1] = NAN; }
static void m_pcov_inf(map_msg_t *m) { m->map.pose_cov.m[2][2] = INFINITY; }
static void m_theta_range(map_msg_t *m) { m->map.pose.theta = 3.2; }
static void m_theta_range2(map_msg_t *m) { m->map.pose.theta = nextafter(-COSLAM_PI, -4.0); }
static void m_pcov_neg(map_msg_t *m) { m->map.pose_cov.m[0][0] = -m->map.pose_cov.m[0][0]; }
static void m_pcov_zero(map_msg_t *m) { memset(&m->map.pose_cov, 0, sizeof m->map.pose_cov); }
static void m_pcov_indef(map_msg_t *m)
{
    /* all diagonal entries positive, all 2x2 minors of rows 0-1 positive, but det < 0 */
    const double p[3][3] = {{1.0, 0.9, 0.9}, {0.9, 1.0, -0.9}, {0.9, -0.9, 1.0}};
    memcpy(m->map.pose_cov.m, p, sizeof p);
}
static void m_sight_nan(map_msg_t *m) { m->sighting.bearing_rad = NAN; }
static void m_sight_inf(map_msg_t *m) { m->sighting.range_var_m2 = INFINITY; }
static void m_sight_bcast(map_msg_t *m) { m->receiver_id = MAP_MSG_BROADCAST; }
static void m_range_neg(map_msg_t *m) { m->sighting.range_m = -0.01; }
static void m_bearing_range(map_msg_t *m) { m->sighting.bearing_rad = -3.5; }
static void m_rvar_zero(map_msg_t *m) { m->sighting.range_var_m2 = 0.0; }
static void m_bvar_neg(map_msg_t *m) { m->sighting.bearing_var_rad2 = -1e-3; }
static void m_lm_nan(map_msg_t *m) { m->map.lm[2].mean.y = NAN; }
static void m_lm_cov_inf(map_msg_t *m) { m->map.lm[1].cov.xy = -INFINITY; }
static void m_lm_id0(map_msg_t *m) { m->map.lm[1].id = 0; }
static void m_lm_mask0(map_msg_t *m) { m->map.lm[0].src_mask = 0; }
#if COSLAM_MAX_ROBOTS < 16
static void m_lm_mask_out(map_msg_t *m) { m->map.lm[0].src_mask = (uint16_t)(1u << COSLAM_MAX_ROBOTS); }
#endif
static void m_lm_cov_zero(map_msg_t *m) { m->map.lm[2].cov.xx = 0.0; }
static void m_lm_cov_neg(map_msg_t *m) { m->map.lm[0].cov.yy = -0.1; }
static void m_lm_cov_indef(map_msg_t *m) { m->map.lm[1].cov = cov2_make(1.0, 1.0, 1.0); } /* det 0 */
static void m_lm_cov_indef2(map_msg_t *m) { m->map.lm[1].cov = cov2_make(1.0, -2.0, 1.0); }
static void m_lm_rel_nan(map_msg_t *m) { m->map.lm[2].cov_rel.yy = NAN; }
static void m_lm_rel_inf(map_msg_t *m) { m->map.lm[0].cov_rel.xy = INFINITY; }
static void m_lm_rel_zero(map_msg_t *m) { m->map.lm[1].cov_rel.xx = 0.0; }
static void m_lm_rel_neg(map_msg_t *m) { m->map.lm[2].cov_rel.yy = -1e-6; }
static void m_lm_rel_singular(map_msg_t *m) { m->map.lm[0].cov_rel = cov2_make(0.25, -0.125, 0.0625); }
static void m_lm_rel_indef(map_msg_t *m) { m->map.lm[2].cov_rel = cov2_make(0.1, 0.5, 0.2); }
static void m_lm_rel_all_zero(map_msg_t *m) { m->map.lm[1].cov_rel = cov2_make(0.0, 0.0, 0.0); }
static void m_dup_adjacent(map_msg_t *m) { m->map.lm[2].id = m->map.lm[1].id; }
static void m_dup_far(map_msg_t *m)
{
    /* unsorted: the all-pairs check must find lm[0] == lm[2] */
    m->map.lm[1].id = 1000000u;
    m->map.lm[2].id = m->map.lm[0].id;
}

static const struct_case_t struct_cases[] = {
    {"version", m_version, COSLAM_E_MSG_VERSION},
    {"count", m_count, COSLAM_E_MSG_COUNT},
    {"sender out of team", m_sender, COSLAM_E_MSG_FIELD},
    {"sender broadcast", m_sender_bcast, COSLAM_E_MSG_FIELD},
    {"receiver out of team", m_receiver, COSLAM_E_MSG_FIELD},
    {"receiver == sender", m_receiver_self, COSLAM_E_MSG_FIELD},
    {"pose NaN", m_pose_nan, COSLAM_E_MSG_NONFINITE},
    {"pose Inf", m_pose_inf, COSLAM_E_MSG_NONFINITE},
    {"pose cov NaN", m_pcov_nan, COSLAM_E_MSG_NONFINITE},
    {"pose cov Inf", m_pcov_inf, COSLAM_E_MSG_NONFINITE},
    {"theta > pi", m_theta_range, COSLAM_E_MSG_FIELD},
    {"theta < -pi", m_theta_range2, COSLAM_E_MSG_FIELD},
    {"pose cov negative variance", m_pcov_neg, COSLAM_E_MSG_COVARIANCE},
    {"pose cov zero", m_pcov_zero, COSLAM_E_MSG_COVARIANCE},
    {"pose cov indefinite", m_pcov_indef, COSLAM_E_MSG_COVARIANCE},
    {"sighting NaN", m_sight_nan, COSLAM_E_MSG_NONFINITE},
    {"sighting Inf", m_sight_inf, COSLAM_E_MSG_NONFINITE},
    {"sighting in a broadcast", m_sight_bcast, COSLAM_E_MSG_FIELD},
    {"negative range", m_range_neg, COSLAM_E_MSG_FIELD},
    {"bearing < -pi", m_bearing_range, COSLAM_E_MSG_FIELD},
    {"range variance 0", m_rvar_zero, COSLAM_E_MSG_COVARIANCE},
    {"bearing variance < 0", m_bvar_neg, COSLAM_E_MSG_COVARIANCE},
    {"landmark NaN", m_lm_nan, COSLAM_E_MSG_NONFINITE},
    {"landmark cov Inf", m_lm_cov_inf, COSLAM_E_MSG_NONFINITE},
    {"landmark id 0", m_lm_id0, COSLAM_E_MSG_FIELD},
    {"landmark src_mask 0", m_lm_mask0, COSLAM_E_MSG_FIELD},
#if COSLAM_MAX_ROBOTS < 16
    {"landmark src_mask outside team", m_lm_mask_out, COSLAM_E_MSG_FIELD},
#endif
    {"landmark cov xx 0", m_lm_cov_zero, COSLAM_E_MSG_COVARIANCE},
    {"landmark cov yy < 0", m_lm_cov_neg, COSLAM_E_MSG_COVARIANCE},
    {"landmark cov singular", m_lm_cov_indef, COSLAM_E_MSG_COVARIANCE},
    {"landmark cov indefinite", m_lm_cov_indef2, COSLAM_E_MSG_COVARIANCE},
    {"landmark cov_rel NaN", m_lm_rel_nan, COSLAM_E_MSG_NONFINITE},
    {"landmark cov_rel Inf", m_lm_rel_inf, COSLAM_E_MSG_NONFINITE},
    {"landmark cov_rel xx 0", m_lm_rel_zero, COSLAM_E_MSG_COVARIANCE},
    {"landmark cov_rel yy < 0", m_lm_rel_neg, COSLAM_E_MSG_COVARIANCE},
    {"landmark cov_rel singular", m_lm_rel_singular, COSLAM_E_MSG_COVARIANCE},
    {"landmark cov_rel indefinite", m_lm_rel_indef, COSLAM_E_MSG_COVARIANCE},
    {"landmark cov_rel all zero (unfilled)", m_lm_rel_all_zero, COSLAM_E_MSG_COVARIANCE},
    {"duplicate ids, sorted", m_dup_adjacent, COSLAM_E_MSG_DUPLICATE},
    {"duplicate ids, unsorted", m_dup_far, COSLAM_E_MSG_DUPLICATE},
};

static void test_reject_struct_cases(void **state)
{
    (void)state;
    for (size_t c = 0; c < sizeof struct_cases / sizeof struct_cases[0]; ++c) {
        const struct_case_t *k = &struct_cases[c];
        make_msg(&g_a, 3, 100 + c);
        k->mutate(&g_a);
        size_t len = 99;
        const coslam_status_t v = map_msg_validate(&g_a);
        const coslam_status_t e = map_msg_encode(&g_a, g_buf, sizeof g_buf, &len);
        if (v != k->code || e != k->code || len != 0) {
            fail_msg("%s: validate %s, encode %s (len %zu), want %s", k->name, coslam_status_str(v),
                     coslam_status_str(e), len, coslam_status_str(k->code));
        }
        if (k->code == COSLAM_E_MSG_COUNT) {
            continue; /* the struct cannot hold the extra landmark: see test_reject_count */
        }
        const size_t n = raw_encode(&g_a, g_buf);
        const coslam_status_t d = decode_exact(g_buf, n, &g_b);
        if (d != k->code) {
            fail_msg("%s: decode %s, want %s", k->name, coslam_status_str(d), coslam_status_str(k->code));
        }
    }
}

/* Within a landmark the checks run NONFINITE, then FIELD, then COVARIANCE,
 * with cov_rel in the same group as cov: when two faults meet, the earlier
 * class decides, on all three paths. */
static void expect_3ways(const char *name, coslam_status_t code)
{
    size_t len = 99;
    const coslam_status_t v = map_msg_validate(&g_a);
    const coslam_status_t e = map_msg_encode(&g_a, g_buf, sizeof g_buf, &len);
    const coslam_status_t d = decode_exact(g_buf, raw_encode(&g_a, g_buf), &g_b);
    if (v != code || e != code || d != code) {
        fail_msg("%s: validate %s, encode %s, decode %s, want %s", name, coslam_status_str(v),
                 coslam_status_str(e), coslam_status_str(d), coslam_status_str(code));
    }
}

static void test_landmark_check_order(void **state)
{
    (void)state;
    make_msg(&g_a, 2, 23);
    g_a.map.lm[1].cov_rel.xy = NAN;
    g_a.map.lm[1].id = 0;
    expect_3ways("cov_rel NaN + id 0", COSLAM_E_MSG_NONFINITE);
    make_msg(&g_a, 2, 23);
    g_a.map.lm[1].cov_rel.xx = -1.0;
    g_a.map.lm[1].src_mask = 0;
    expect_3ways("cov_rel not PD + src_mask 0", COSLAM_E_MSG_FIELD);
    make_msg(&g_a, 2, 23);
    g_a.map.lm[0].cov = cov2_make(1.0, 2.0, 1.0);
    g_a.map.lm[0].cov_rel.yy = -INFINITY;
    expect_3ways("cov not PD + cov_rel -Inf", COSLAM_E_MSG_NONFINITE);
    /* the first failing landmark decides: lm[0] COVARIANCE before lm[1] FIELD */
    make_msg(&g_a, 2, 23);
    g_a.map.lm[0].cov_rel = cov2_make(1.0, 1.0, 1.0);
    g_a.map.lm[1].id = 0;
    expect_3ways("lm[0] cov_rel singular, lm[1] id 0", COSLAM_E_MSG_COVARIANCE);
    /* cov_rel valid while cov is not, and the reverse: each is checked */
    make_msg(&g_a, 2, 23);
    g_a.map.lm[1].cov.yy = 0.0;
    expect_3ways("cov yy 0, cov_rel valid", COSLAM_E_MSG_COVARIANCE);
    make_msg(&g_a, 2, 23);
    g_a.map.lm[1].cov_rel.yy = 0.0;
    expect_3ways("cov valid, cov_rel yy 0", COSLAM_E_MSG_COVARIANCE);
}

/* The encoder refuses a pose covariance whose mirror entries differ, even by
 * one ulp or in the sign of zero: the wire carries the upper triangle only. */
static void test_reject_asymmetric(void **state)
{
    (void)state;
    make_msg(&g_a, 1, 21);
    g_a.map.pose_cov.m[1][0] = nextafter(g_a.map.pose_cov.m[0][1], 1.0);
    assert_int_equal(map_msg_validate(&g_a), COSLAM_E_MSG_COVARIANCE);
    size_t len = 1;
    assert_int_equal(map_msg_encode(&g_a, g_buf, sizeof g_buf, &len), COSLAM_E_MSG_COVARIANCE);
    make_msg(&g_a, 1, 21);
    g_a.map.pose_cov.m[0][2] = 0.0;
    g_a.map.pose_cov.m[2][0] = -0.0;
    assert_int_equal(map_msg_validate(&g_a), COSLAM_E_MSG_COVARIANCE);
    g_a.map.pose_cov.m[2][0] = 0.0;
    assert_int_equal(map_msg_validate(&g_a), COSLAM_OK);
}

/* An invalid sighting's fields are ignored on encode (written as zeros). */
static void test_invalid_sighting_is_zeroed(void **state)
{
    (void)state;
    make_msg(&g_a, 2, 22);
    g_a.sighting.valid = false;
    g_a.sighting.range_m = NAN; /* ignored: not on the wire */
    size_t len = 0;
    assert_int_equal(map_msg_encode(&g_a, g_buf, sizeof g_buf, &len), COSLAM_OK);
    assert_int_equal(g_buf[W_FLAGS], 0);
    for (size_t i = W_RANGE; i < W_N; ++i) {
        assert_int_equal(g_buf[i], 0);
    }
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_OK);
    assert_false(g_b.sighting.valid);
    assert_true(g_b.sighting.range_m == 0.0 && g_b.sighting.stamp_us == 0);
}

/* A valid message with n landmarks in g_buf; returns its length. */
static size_t good_wire(uint16_t n, uint64_t seed)
{
    make_msg(&g_a, n, seed);
    size_t len = 0;
    assert_int_equal(map_msg_encode(&g_a, g_buf, sizeof g_buf, &len), COSLAM_OK);
    return len;
}

static void test_reject_truncated(void **state)
{
    (void)state;
    const size_t len = good_wire(CAP < 3 ? CAP : 3, 31);
    for (size_t k = 0; k < len; ++k) {
        const coslam_status_t st = decode_exact(g_buf, k, &g_b);
        if (st != COSLAM_E_MSG_TRUNCATED) {
            fail_msg("prefix of %zu / %zu bytes: %s", k, len, coslam_status_str(st));
        }
    }
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_OK);
    /* a length field beyond the buffer reads as a cut-short message */
    wr_u32(g_buf + W_LENGTH, (uint32_t)len + 1);
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_TRUNCATED);
    wr_u32(g_buf + W_LENGTH, UINT32_MAX);
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_TRUNCATED);
}

static void test_reject_magic(void **state)
{
    (void)state;
    const size_t len = good_wire(1, 32);
    for (size_t i = 0; i < 4; ++i) {
        g_buf[i] ^= 0x20; /* case flip: "cSLM", ... */
        assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_MAGIC);
        g_buf[i] ^= 0x20;
    }
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_OK);
}

static void test_reject_version(void **state)
{
    (void)state;
    const size_t len = good_wire(1, 33);
    const uint8_t bad[] = {0, 1 /* previous layout, no cov_rel */, 3, 0x81, 0xFF};
    for (size_t i = 0; i < sizeof bad; ++i) {
        g_buf[W_VERSION] = bad[i];
        refresh(g_buf, len); /* even with a correct CRC */
        assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_VERSION);
    }
}

static void test_reject_length(void **state)
{
    (void)state;
    size_t len = good_wire(2, 34);
    /* trailing byte after a complete message */
    g_buf[len] = 0;
    assert_int_equal(decode_exact(g_buf, len + 1, &g_b), COSLAM_E_MSG_LENGTH);
    /* length field smaller than the buffer */
    wr_u32(g_buf + W_LENGTH, (uint32_t)len - W_LM_SIZE);
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_LENGTH);
    /* length field too small for a header, yet equal to the buffer */
    uint8_t tiny[20] = {'C', 'S', 'L', 'M', MAP_MSG_VERSION, 0, 1, 0, 20, 0, 0, 0};
    assert_int_equal(decode_exact(tiny, sizeof tiny, &g_b), COSLAM_E_MSG_LENGTH);
    /* consistent length and CRC, but the count says another size */
    len = good_wire(2, 34);
    wr_u16(g_buf + W_N, 1);
    refresh(g_buf, len);
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_LENGTH);
    /* a length that is not 142 + 73 n for any n */
    len = good_wire(2, 34);
    g_buf[len] = 0;
    refresh(g_buf, len + 1);
    assert_int_equal(decode_exact(g_buf, len + 1, &g_b), COSLAM_E_MSG_LENGTH);
}

/* Every single-bit error after the framing prefix is caught by the CRC. */
static void test_reject_crc(void **state)
{
    (void)state;
    const size_t len = good_wire(2, 35);
    memcpy(g_buf2, g_buf, len);
    for (size_t i = 12; i < len; ++i) {
        for (int b = 0; b < 8; ++b) {
            g_buf2[i] ^= (uint8_t)(1u << b);
            const coslam_status_t st = map_msg_decode(g_buf2, len, &g_b);
            if (st != COSLAM_E_MSG_CRC) {
                fail_msg("bit %d of byte %zu: %s", b, i, coslam_status_str(st));
            }
            g_buf2[i] ^= (uint8_t)(1u << b);
        }
    }
    g_buf2[len - 1] ^= 0x80;
    assert_int_equal(decode_exact(g_buf2, len, &g_b), COSLAM_E_MSG_CRC);
}

/* A sender with a larger capacity: n = CAP + 1 with consistent length and CRC. */
static void test_reject_count(void **state)
{
    (void)state;
    size_t len = good_wire(CAP, 36);
    /* append a copy of the last landmark with a fresh id */
    memcpy(g_buf2, g_buf, len - 4);
    uint8_t *extra = g_buf2 + len - 4;
    memcpy(extra, extra - W_LM_SIZE, W_LM_SIZE);
    wr_u32(extra + L_ID, rd_u32(extra - W_LM_SIZE + L_ID) + 1);
    len += W_LM_SIZE;
    wr_u16(g_buf2 + W_N, CAP + 1);
    refresh(g_buf2, len);
    assert_int_equal(decode_exact(g_buf2, len, &g_b), COSLAM_E_MSG_COUNT);
    /* count checked before the length/count agreement */
    len = good_wire(1, 36);
    wr_u16(g_buf + W_N, UINT16_MAX);
    refresh(g_buf, len);
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_COUNT);
}

/* Every f64 on the wire, set to NaN, +Inf or -Inf. */
static void test_reject_nonfinite_every_field(void **state)
{
    (void)state;
    const double bad[] = {NAN, -NAN, INFINITY, -INFINITY};
    const uint16_t n = CAP < 3 ? CAP : 3;
    const size_t len = good_wire(n, 37);
    memcpy(g_buf2, g_buf, len);
    size_t offs[64];
    size_t k = 0;
    for (size_t o = W_X; o < W_SSTAMP; o += 8) {
        offs[k++] = o;
    }
    for (size_t i = 0; i < n; ++i) {
        for (size_t o = 0; o < 8 * L_N_F64; o += 8) {
            offs[k++] = W_LM + W_LM_SIZE * i + o;
        }
    }
    assert_int_equal(k, 13 + L_N_F64 * n); /* every f64: 13 in the header, 8 per landmark */
    for (size_t j = 0; j < k; ++j) {
        for (size_t b = 0; b < sizeof bad / sizeof bad[0]; ++b) {
            memcpy(g_buf, g_buf2, len);
            wr_f64(g_buf + offs[j], bad[b]);
            refresh(g_buf, len);
            const coslam_status_t st = decode_exact(g_buf, len, &g_b);
            if (st != COSLAM_E_MSG_NONFINITE) {
                fail_msg("offset %zu = %g: %s", offs[j], bad[b], coslam_status_str(st));
            }
        }
    }
}

/* Wire-only faults: reserved flag bits, bytes of an absent sighting. */
static void test_reject_wire_fields(void **state)
{
    (void)state;
    size_t len = good_wire(1, 38);
    for (int b = 1; b < 8; ++b) {
        g_buf[W_FLAGS] = (uint8_t)(1u | (1u << b));
        refresh(g_buf, len);
        assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_FIELD);
    }
    make_msg(&g_a, 1, 38);
    g_a.receiver_id = MAP_MSG_BROADCAST;
    memset(&g_a.sighting, 0, sizeof g_a.sighting);
    assert_int_equal(map_msg_encode(&g_a, g_buf, sizeof g_buf, &len), COSLAM_OK);
    memcpy(g_buf2, g_buf, len);
    for (size_t i = W_RANGE; i < W_N; ++i) {
        memcpy(g_buf, g_buf2, len);
        g_buf[i] = 0x01;
        refresh(g_buf, len);
        const coslam_status_t st = decode_exact(g_buf, len, &g_b);
        if (st != COSLAM_E_MSG_FIELD) {
            fail_msg("absent sighting, byte %zu non-zero: %s", i, coslam_status_str(st));
        }
    }
    /* -0.0 is not the zero byte pattern either */
    memcpy(g_buf, g_buf2, len);
    wr_f64(g_buf + W_RANGE, -0.0);
    refresh(g_buf, len);
    assert_int_equal(decode_exact(g_buf, len, &g_b), COSLAM_E_MSG_FIELD);
}

/* One representative per rejection: ten distinct codes, each named. */
static void test_codes_distinct(void **state)
{
    (void)state;
    const coslam_status_t all[] = {
        COSLAM_E_MSG_TRUNCATED, COSLAM_E_MSG_MAGIC, COSLAM_E_MSG_VERSION, COSLAM_E_MSG_LENGTH,
        COSLAM_E_MSG_CRC, COSLAM_E_MSG_COUNT, COSLAM_E_MSG_NONFINITE, COSLAM_E_MSG_COVARIANCE,
        COSLAM_E_MSG_FIELD, COSLAM_E_MSG_DUPLICATE,
    };
    coslam_status_t got[10];
    size_t len = good_wire(3 <= CAP ? 3 : CAP, 40);
    memcpy(g_buf2, g_buf, len);
#define RESET() memcpy(g_buf, g_buf2, len)
    got[0] = decode_exact(g_buf, len - 1, &g_b);
    RESET();
    g_buf[0] = 'X';
    got[1] = decode_exact(g_buf, len, &g_b);
    RESET();
    g_buf[W_VERSION] = 9;
    got[2] = decode_exact(g_buf, len, &g_b);
    RESET();
    got[3] = decode_exact(g_buf, len + 1, &g_b);
    RESET();
    g_buf[W_SEQ] ^= 1;
    got[4] = decode_exact(g_buf, len, &g_b);
    RESET();
    wr_u16(g_buf + W_N, CAP + 1);
    refresh(g_buf, len);
    got[5] = decode_exact(g_buf, len, &g_b);
    RESET();
    wr_f64(g_buf + W_Y, INFINITY);
    refresh(g_buf, len);
    got[6] = decode_exact(g_buf, len, &g_b);
    RESET();
    wr_f64(g_buf + W_PYY, -1.0);
    refresh(g_buf, len);
    got[7] = decode_exact(g_buf, len, &g_b);
    RESET();
    g_buf[W_SENDER] = COSLAM_MAX_ROBOTS;
    refresh(g_buf, len);
    got[8] = decode_exact(g_buf, len, &g_b);
    RESET();
    wr_u32(g_buf + W_LM + W_LM_SIZE + L_ID, rd_u32(g_buf + W_LM + L_ID));
    refresh(g_buf, len);
    got[9] = decode_exact(g_buf, len, &g_b);
#undef RESET
    for (int i = 0; i < 10; ++i) {
        if (got[i] != all[i]) {
            fail_msg("case %d: %s, want %s", i, coslam_status_str(got[i]), coslam_status_str(all[i]));
        }
        assert_string_not_equal(coslam_status_str(all[i]), "E_UNKNOWN");
        for (int j = 0; j < i; ++j) {
            assert_int_not_equal(all[i], all[j]);
        }
    }
}

/* ---------------------------------------------------------------------------
 * Mutation fuzz. */

#ifndef COSLAM_TEST_FULL
#define COSLAM_TEST_FULL 0
#endif

static const double special_f64[] = {NAN, INFINITY, -INFINITY, 0.0, -0.0, -1.0, 1e308, -1e-300,
                                     DBL_TRUE_MIN, 4.0, -4.0, 3.2};

/* Mutate src (len bytes) into dst; returns the new length (<= len + 16). */
static size_t mutate(rng_t *r, const uint8_t *src, size_t len, uint8_t *dst, uint16_t n)
{
    memcpy(dst, src, len);
    size_t out = len;
    const uint32_t op = rng_below(r, 10);
    switch (op) {
    case 0: /* flip 1..8 random bits */
    {
        const uint32_t k = 1 + rng_below(r, 8);
        for (uint32_t i = 0; i < k; ++i) {
            dst[rng_below(r, (uint32_t)out)] ^= (uint8_t)(1u << rng_below(r, 8));
        }
        break;
    }
    case 1: /* random bytes */
    {
        const uint32_t k = 1 + rng_below(r, 4);
        for (uint32_t i = 0; i < k; ++i) {
            dst[rng_below(r, (uint32_t)out)] = (uint8_t)rng_next_u64(r);
        }
        break;
    }
    case 2: /* insert 1..16 bytes */
    {
        const size_t k = 1 + rng_below(r, 16);
        const size_t at = rng_below(r, (uint32_t)out + 1);
        memmove(dst + at + k, dst + at, out - at);
        for (size_t i = 0; i < k; ++i) {
            dst[at + i] = (uint8_t)rng_next_u64(r);
        }
        out += k;
        break;
    }
    case 3: /* delete 1..16 bytes */
    {
        const size_t k = 1 + rng_below(r, 16);
        if (k < out) {
            const size_t at = rng_below(r, (uint32_t)(out - k + 1));
            memmove(dst + at, dst + at + k, out - at - k);
            out -= k;
        }
        break;
    }
    case 4: /* truncate */
        out = rng_below(r, (uint32_t)out);
        break;
    case 5: /* append a landmark-sized chunk (sometimes a copy of one) */
        if (n > 0 && rng_below(r, 2) == 0) {
            memcpy(dst + out, src + W_LM + W_LM_SIZE * rng_below(r, n), 16);
        } else {
            for (size_t i = 0; i < 16; ++i) {
                dst[out + i] = (uint8_t)rng_next_u64(r);
            }
        }
        out += 16;
        break;
    case 6: /* a special value into an f64 slot of the header or a landmark */
    {
        size_t off;
        if (n > 0 && rng_below(r, 2) == 0) {
            off = W_LM + W_LM_SIZE * rng_below(r, n) + 8 * rng_below(r, L_N_F64);
        } else {
            off = W_X + 8 * rng_below(r, 13);
        }
        wr_f64(dst + off, special_f64[rng_below(r, sizeof special_f64 / sizeof special_f64[0])]);
        break;
    }
    case 7: /* duplicate or zero a landmark id */
        if (n > 0) {
            const size_t a = rng_below(r, n), b = rng_below(r, n);
            wr_u32(dst + W_LM + W_LM_SIZE * a + L_ID,
                   rng_below(r, 4) == 0 ? 0u : rd_u32(dst + W_LM + W_LM_SIZE * b + L_ID));
        }
        break;
    case 8: /* header bytes: ids, flags, count */
    {
        const size_t offs[] = {W_SENDER, W_RECEIVER, W_FLAGS, W_N, W_N + 1};
        dst[offs[rng_below(r, 5)]] = (uint8_t)(rng_below(r, 2) ? rng_next_u64(r) : rng_below(r, 20));
        break;
    }
    default: /* unchanged: the valid message itself */
        break;
    }
    return out;
}

static void test_fuzz_mutations(void **state)
{
    (void)state;
    const uint32_t iters = COSLAM_TEST_FULL ? 2000000u : 30000u;
    enum { NBASE = 6 };
    static uint8_t base[NBASE][MAP_MSG_MAX_BYTES];
    size_t base_len[NBASE];
    uint16_t base_n[NBASE];
    const uint16_t ns[NBASE] = {0, 1, 2, CAP < 3 ? CAP : 3, CAP, CAP < 7 ? CAP : 7};
    for (int i = 0; i < NBASE; ++i) {
        make_msg(&g_a, ns[i], 500 + (uint64_t)i);
        if (i == 2) { /* broadcast, no sighting */
            g_a.receiver_id = MAP_MSG_BROADCAST;
            memset(&g_a.sighting, 0, sizeof g_a.sighting);
        }
        if (i == 5 && ns[i] > 2) { /* unsorted ids */
            const uint32_t t = g_a.map.lm[0].id;
            g_a.map.lm[0].id = g_a.map.lm[ns[i] - 1].id;
            g_a.map.lm[ns[i] - 1].id = t;
        }
        assert_int_equal(map_msg_encode(&g_a, base[i], sizeof base[i], &base_len[i]), COSLAM_OK);
        base_n[i] = ns[i];
    }
    rng_t r;
    rng_seed(&r, 0xC0DEC);
    uint32_t hist[128] = {0};
    for (uint32_t it = 0; it < iters; ++it) {
        const uint32_t b = rng_below(&r, NBASE);
        size_t len = mutate(&r, base[b], base_len[b], g_buf, base_n[b]);
        /* half the time repair length and CRC, so the field checks are reached */
        if (rng_below(&r, 2) == 0 && len >= MAP_MSG_MIN_BYTES) {
            refresh(g_buf, len);
        }
        const coslam_status_t st = decode_exact(g_buf, len, &g_b);
        hist[-(int)st]++;
        if (st == COSLAM_OK) {
            size_t len2 = 0;
            const coslam_status_t e = map_msg_encode(&g_b, g_buf2, sizeof g_buf2, &len2);
            if (e != COSLAM_OK || len2 != len || memcmp(g_buf, g_buf2, len) != 0) {
                fail_msg("iteration %u: accepted input does not re-encode to itself (%s, %zu vs %zu)", it,
                         coslam_status_str(e), len2, len);
            }
        } else if (st > COSLAM_E_MSG_TRUNCATED || st < COSLAM_E_MSG_DUPLICATE) {
            fail_msg("iteration %u: unexpected code %d", it, (int)st);
        }
    }
    printf("fuzz: %u iterations:", iters);
    for (int c = 0; c < 128; ++c) {
        if (hist[c] != 0) {
            printf(" %s=%u", coslam_status_str((coslam_status_t)-c), hist[c]);
        }
    }
    printf("\n");
    /* the fuzz must reach acceptance and every field-level rejection */
    assert_true(hist[0] > 0);
    const coslam_status_t reached[] = {COSLAM_E_MSG_TRUNCATED, COSLAM_E_MSG_LENGTH, COSLAM_E_MSG_CRC,
                                       COSLAM_E_MSG_COUNT, COSLAM_E_MSG_NONFINITE, COSLAM_E_MSG_COVARIANCE,
                                       COSLAM_E_MSG_FIELD, COSLAM_E_MSG_DUPLICATE};
    for (size_t i = 0; i < sizeof reached / sizeof reached[0]; ++i) {
        if (hist[-(int)reached[i]] == 0) {
            fail_msg("the fuzz never produced %s", coslam_status_str(reached[i]));
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc32),
        cmocka_unit_test(test_sizes),
        cmocka_unit_test(test_roundtrip_empty),
        cmocka_unit_test(test_roundtrip_one),
        cmocka_unit_test(test_roundtrip_full),
        cmocka_unit_test(test_roundtrip_extremes),
        cmocka_unit_test(test_golden_vector),
        cmocka_unit_test(test_encode_args_and_capacity),
        cmocka_unit_test(test_reject_struct_cases),
        cmocka_unit_test(test_landmark_check_order),
        cmocka_unit_test(test_reject_asymmetric),
        cmocka_unit_test(test_invalid_sighting_is_zeroed),
        cmocka_unit_test(test_reject_truncated),
        cmocka_unit_test(test_reject_magic),
        cmocka_unit_test(test_reject_version),
        cmocka_unit_test(test_reject_length),
        cmocka_unit_test(test_reject_crc),
        cmocka_unit_test(test_reject_count),
        cmocka_unit_test(test_reject_nonfinite_every_field),
        cmocka_unit_test(test_reject_wire_fields),
        cmocka_unit_test(test_codes_distinct),
        cmocka_unit_test(test_fuzz_mutations),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
