/*
 * libFuzzer target for the map-message decoder (optional: built only when
 * clang with libFuzzer is installed, see CMakeLists.txt).
 *
 * Each input is decoded twice:
 *   1. as is: reaches the framing checks (magic, version, length, CRC);
 *   2. overlaid: the input (after its first byte) XORed onto one of a few
 *      valid messages, then length field and CRC repaired, so that the
 *      fuzzer starts from valid messages and spends its time in the field
 *      checks instead of guessing CRCs (no seed corpus needed).
 * Property: the decoder returns OK or a COSLAM_E_MSG_* code; an accepted
 * input re-encodes to exactly the same bytes (so decode -> encode -> decode
 * is the identity); an accepted message satisfies every validity rule of
 * map_msg.h, re-checked here independently (finite, PD covariances with
 * bit-identical mirror entries, theta and bearing in [-pi, pi], ids
 * non-zero and distinct, src_mask non-zero); *out is untouched on error.
 * Out-of-bounds reads are caught by ASan (libFuzzer hands over an
 * exact-size buffer; the overlaid copy is an exact-size heap block).
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "coslam/crc32.h"
#include "coslam/map_msg.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static map_msg_t g_out;
static map_msg_t g_sentinel;
static uint8_t g_buf[MAP_MSG_MAX_BYTES];

static void put_le(uint8_t *p, uint32_t v, unsigned n)
{
    for (unsigned i = 0; i < n; ++i) {
        p[i] = (uint8_t)(v >> (8U * i));
    }
}

static int pd2(cov2_t c)
{
    return isfinite(c.xx) && isfinite(c.xy) && isfinite(c.yy) && c.xx > 0.0 && c.yy > 0.0 &&
           c.xx * c.yy - c.xy * c.xy > 0.0;
}

/* What the decoder promises of an accepted message (map_msg.h, "Validity"),
 * checked here independently of map_msg_validate. */
static void check_valid(const map_msg_t *m)
{
    const map_estimate_t *e = &m->map;
    if (!isfinite(e->pose.x) || !isfinite(e->pose.y) || !(fabs(e->pose.theta) <= 3.14159265358979324)) {
        abort();
    }
    for (int i = 0; i < 3; ++i) {
        if (!(e->pose_cov.m[i][i] > 0.0)) {
            abort(); /* a PD covariance has a positive diagonal */
        }
        for (int j = 0; j < 3; ++j) {
            if (!isfinite(e->pose_cov.m[i][j]) || memcmp(&e->pose_cov.m[i][j], &e->pose_cov.m[j][i], sizeof(double))) {
                abort();
            }
        }
    }
    if (e->n_landmarks > COSLAM_MAX_MSG_LANDMARKS) {
        abort();
    }
    for (uint16_t j = 0; j < e->n_landmarks; ++j) {
        const map_landmark_t *l = &e->lm[j];
        if (!isfinite(l->mean.x) || !isfinite(l->mean.y) || !pd2(l->cov) || !pd2(l->cov_rel) || l->id == 0U ||
            l->src_mask == 0U) {
            abort();
        }
        for (uint16_t k = 0; k < j; ++k) {
            if (e->lm[k].id == l->id) {
                abort(); /* duplicate identity accepted */
            }
        }
    }
    if (m->sighting.valid && (!(m->sighting.range_m >= 0.0) || !(m->sighting.range_var_m2 > 0.0) ||
                              !(m->sighting.bearing_var_rad2 > 0.0) || !(fabs(m->sighting.bearing_rad) <= 3.14159265358979324))) {
        abort();
    }
}

static void check(const uint8_t *data, size_t size)
{
    memset(&g_out, 0x5A, sizeof g_out);
    const coslam_status_t st = map_msg_decode(data, size, &g_out);
    if (st == COSLAM_OK) {
        check_valid(&g_out);
        size_t len = 0;
        if (map_msg_encode(&g_out, g_buf, sizeof g_buf, &len) != COSLAM_OK || len != size ||
            memcmp(g_buf, data, size) != 0) {
            abort(); /* accepted, but not the canonical encoding of what it decoded to */
        }
    } else {
        if (st > COSLAM_E_MSG_TRUNCATED || st < COSLAM_E_MSG_DUPLICATE) {
            abort(); /* not a message error code */
        }
        if (memcmp(&g_out, &g_sentinel, sizeof g_out) != 0) {
            abort(); /* partially applied */
        }
    }
}

/* Valid messages to overlay inputs on: 0, 1, 3 and the maximum number of
 * landmarks; the second one is a broadcast without a sighting. */
enum { N_TEMPLATES = 4 };
static uint8_t g_tpl[N_TEMPLATES][MAP_MSG_MAX_BYTES];
static size_t g_tpl_len[N_TEMPLATES];

static void make_templates(void)
{
    static map_msg_t m;
    const uint16_t ns[N_TEMPLATES] = {0U, 1U, COSLAM_MAX_MSG_LANDMARKS < 3 ? COSLAM_MAX_MSG_LANDMARKS : 3U,
                                      COSLAM_MAX_MSG_LANDMARKS};
    for (int t = 0; t < N_TEMPLATES; ++t) {
        map_msg_init(&m);
        m.sender_id = 1U;
        m.receiver_id = t == 1 ? (uint8_t)MAP_MSG_BROADCAST : 2U;
        m.seq = 7U;
        m.stamp_us = 1000000U;
        m.map.pose = (pose2_t){1.0, 2.0, 0.5};
        const double p[3][3] = {{0.1, 0.01, 0.0}, {0.01, 0.2, 0.02}, {0.0, 0.02, 0.05}};
        memcpy(m.map.pose_cov.m, p, sizeof p);
        if (t != 1) {
            m.sighting = (map_msg_sighting_t){true, 1.5, -0.25, 0.01, 0.003, 999000U};
        }
        m.map.n_landmarks = ns[t];
        for (uint16_t i = 0; i < ns[t]; ++i) {
            const double x = (double)i;
            m.map.lm[i] = (map_landmark_t){{x, -0.5 * x},
                                           {0.04 + 0.001 * x, 0.001, 0.03},
                                           {0.02, -0.004, 0.01 + 0.0005 * x},
                                           10U + 3U * i,
                                           (uint16_t)(i + 1U),
                                           3U,
                                           (uint8_t)(i % 3U)};
        }
        if (map_msg_encode(&m, g_tpl[t], sizeof g_tpl[t], &g_tpl_len[t]) != COSLAM_OK) {
            abort();
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready = 0;
    if (!ready) {
        make_templates();
        ready = 1;
    }
    memset(&g_sentinel, 0x5A, sizeof g_sentinel);
    /* 1. the input as is */
    check(data, size);
    if (size == 0U) {
        return 0;
    }
    /* 2. the rest of the input XORed onto a valid message (data[0] picks it),
     *    extra bytes appended; length and CRC repaired unless bit 7 is set */
    const size_t t = data[0] % N_TEMPLATES;
    const size_t tl = g_tpl_len[t];
    const size_t n = size - 1U;
    const size_t len = n > tl ? n : tl;
    uint8_t *copy = malloc(len);
    if (copy == NULL) {
        return 0;
    }
    memcpy(copy, g_tpl[t], tl);
    for (size_t i = 0; i < n; ++i) {
        copy[i] = i < tl ? (uint8_t)(copy[i] ^ data[1U + i]) : data[1U + i];
    }
    if ((data[0] & 0x80U) == 0U && len >= MAP_MSG_MIN_BYTES) {
        put_le(copy + 8, (uint32_t)len, 4);
        put_le(copy + len - 4, crc32_update(0U, copy, len - 4), 4);
    }
    check(copy, len);
    free(copy);
    return 0;
}
