#include "coslam/map_msg.h"

#include <float.h>
#include <math.h>
#include <string.h>

#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/crc32.h"
#include "coslam/pose2.h"

/* f64 fields travel as the 64-bit pattern of an IEEE-754 binary64. This
 * assumes double is binary64 (checked here) and that a double and a uint64_t
 * share the byte order in memory, true of every current FPU (ARMv7-M FPv5,
 * x86-64, AArch64, RISC-V). */
_Static_assert(sizeof(double) == 8 && DBL_MANT_DIG == 53 && DBL_MAX_EXP == 1024,
               "the map message needs IEEE-754 binary64 doubles");
_Static_assert(MAP_MSG_MAX_BYTES <= 0xFFFFFFFFU, "the length field is 32 bits");

static const uint8_t map_msg_magic[4] = {0x43U, 0x53U, 0x4CU, 0x4DU}; /* "CSLM" */

/* Wire offsets used directly by the decoder; the rest is sequential. */
#define OFF_VERSION 4U
#define OFF_LENGTH 8U
#define OFF_SIGHTING 96U
#define OFF_COUNT 136U
#define PREFIX_BYTES 12U        /* magic .. length: enough to frame a message */
#define SIGHTING_BYTES 40U      /* range, bearing, 2 variances, stamp */
#define LM_OFF_ID 64U           /* after mean (2 f64), cov and cov_rel (3 f64 each) */
#define LM_OFF_SIGNATURE 72U    /* the record's last byte */
#define FLAG_SIGHTING 0x01U
_Static_assert(LM_OFF_SIGNATURE + 1U == MAP_MSG_LANDMARK_BYTES, "landmark record layout");

/* ------------------------------------------------------------------------- */
/* Little-endian byte I/O: explicit shifts, independent of the host's order. */

static uint8_t *put_u8(uint8_t *p, uint8_t v)
{
    p[0] = v;
    return p + 1;
}

static uint8_t *put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFFU);
    p[1] = (uint8_t)(v >> 8);
    return p + 2;
}

static uint8_t *put_u32(uint8_t *p, uint32_t v)
{
    for (unsigned i = 0; i < 4U; ++i) {
        p[i] = (uint8_t)((v >> (8U * i)) & 0xFFU);
    }
    return p + 4;
}

static uint8_t *put_u64(uint8_t *p, uint64_t v)
{
    for (unsigned i = 0; i < 8U; ++i) {
        p[i] = (uint8_t)((v >> (8U * i)) & 0xFFU);
    }
    return p + 8;
}

static uint8_t *put_f64(uint8_t *p, double v)
{
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    return put_u64(p, bits);
}

static uint16_t get_u16(const uint8_t *p)
{
    return (uint16_t)((unsigned)p[0] | ((unsigned)p[1] << 8));
}

static uint32_t get_u32(const uint8_t *p)
{
    uint32_t v = 0U;
    for (unsigned i = 0; i < 4U; ++i) {
        v |= (uint32_t)p[i] << (8U * i);
    }
    return v;
}

static uint64_t get_u64(const uint8_t *p)
{
    uint64_t v = 0U;
    for (unsigned i = 0; i < 8U; ++i) {
        v |= (uint64_t)p[i] << (8U * i);
    }
    return v;
}

static double get_f64(const uint8_t *p)
{
    const uint64_t bits = get_u64(p);
    double v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

static uint64_t f64_bits(double v)
{
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    return bits;
}

/* ------------------------------------------------------------------------- */
/* Field checks shared by map_msg_validate (struct) and map_msg_decode (wire).
 * Each group checks NONFINITE, then FIELD, then COVARIANCE. */

static coslam_status_t check_ids(uint8_t sender_id, uint8_t receiver_id)
{
    if (sender_id >= COSLAM_MAX_ROBOTS) {
        return COSLAM_E_MSG_FIELD;
    }
    if (receiver_id != MAP_MSG_BROADCAST && (receiver_id >= COSLAM_MAX_ROBOTS || receiver_id == sender_id)) {
        return COSLAM_E_MSG_FIELD;
    }
    return COSLAM_OK;
}

static coslam_status_t check_pose(const pose2_t *pose, const cov3_t *cov)
{
    if (!pose2_is_finite(*pose) || !cov3_is_finite(*cov)) {
        return COSLAM_E_MSG_NONFINITE;
    }
    if (pose->theta < -COSLAM_PI || pose->theta > COSLAM_PI) {
        return COSLAM_E_MSG_FIELD;
    }
    /* Only the upper triangle is sent: the lower one must be its exact
     * mirror, or the receiver would get a different matrix. */
    for (int i = 0; i < 3; ++i) {
        for (int j = i + 1; j < 3; ++j) {
            if (f64_bits(cov->m[i][j]) != f64_bits(cov->m[j][i])) {
                return COSLAM_E_MSG_COVARIANCE;
            }
        }
    }
    if (!cov3_is_pd(*cov)) {
        return COSLAM_E_MSG_COVARIANCE;
    }
    return COSLAM_OK;
}

static coslam_status_t check_sighting(const map_msg_sighting_t *s, uint8_t receiver_id)
{
    if (!s->valid) {
        return COSLAM_OK;
    }
    if (!isfinite(s->range_m) || !isfinite(s->bearing_rad) || !isfinite(s->range_var_m2) ||
        !isfinite(s->bearing_var_rad2)) {
        return COSLAM_E_MSG_NONFINITE;
    }
    if (receiver_id == MAP_MSG_BROADCAST) {
        return COSLAM_E_MSG_FIELD; /* a sighting of whom? */
    }
    if (s->range_m < 0.0 || s->bearing_rad < -COSLAM_PI || s->bearing_rad > COSLAM_PI) {
        return COSLAM_E_MSG_FIELD;
    }
    if (!(s->range_var_m2 > 0.0) || !(s->bearing_var_rad2 > 0.0)) {
        return COSLAM_E_MSG_COVARIANCE;
    }
    return COSLAM_OK;
}

static coslam_status_t check_landmark(const map_landmark_t *lm)
{
    if (!isfinite(lm->mean.x) || !isfinite(lm->mean.y) || !cov2_is_finite(lm->cov) ||
        !cov2_is_finite(lm->cov_rel)) {
        return COSLAM_E_MSG_NONFINITE;
    }
    if (lm->id == 0U || lm->src_mask == 0U || ((uint32_t)lm->src_mask >> COSLAM_MAX_ROBOTS) != 0U) {
        return COSLAM_E_MSG_FIELD;
    }
    if (!cov2_is_pd(lm->cov) || !cov2_is_pd(lm->cov_rel)) {
        return COSLAM_E_MSG_COVARIANCE;
    }
    return COSLAM_OK;
}

/* Landmark ids, either from a struct or straight from the wire. */
typedef struct {
    const map_landmark_t *lm; /* used when wire is NULL */
    const uint8_t *wire;      /* first landmark on the wire */
} id_view_t;

static uint32_t id_at(const id_view_t *v, size_t i)
{
    if (v->wire != NULL) {
        return get_u32(v->wire + MAP_MSG_LANDMARK_BYTES * i + LM_OFF_ID);
    }
    return v->lm[i].id;
}

/* Strictly increasing ids (what both filters export) prove uniqueness in one
 * pass; otherwise compare all pairs. No scratch memory either way. */
static coslam_status_t check_unique_ids(const id_view_t *v, size_t n)
{
    size_t i = 1;
    while (i < n && id_at(v, i - 1) < id_at(v, i)) {
        ++i;
    }
    if (i >= n) {
        return COSLAM_OK;
    }
    for (size_t a = 0; a + 1 < n; ++a) {
        const uint32_t id = id_at(v, a);
        for (size_t b = a + 1; b < n; ++b) {
            if (id_at(v, b) == id) {
                return COSLAM_E_MSG_DUPLICATE;
            }
        }
    }
    return COSLAM_OK;
}

/* ------------------------------------------------------------------------- */

void map_msg_init(map_msg_t *msg)
{
    COSLAM_ASSERT(msg != NULL);
    memset(msg, 0, sizeof *msg);
    msg->version = (uint8_t)MAP_MSG_VERSION;
    msg->receiver_id = (uint8_t)MAP_MSG_BROADCAST;
}

coslam_status_t map_msg_validate(const map_msg_t *msg)
{
    if (msg == NULL) {
        return COSLAM_E_ARG;
    }
    if (msg->version != MAP_MSG_VERSION) {
        return COSLAM_E_MSG_VERSION;
    }
    if (msg->map.n_landmarks > COSLAM_MAX_MSG_LANDMARKS) {
        return COSLAM_E_MSG_COUNT;
    }
    coslam_status_t st = check_ids(msg->sender_id, msg->receiver_id);
    if (st == COSLAM_OK) {
        st = check_pose(&msg->map.pose, &msg->map.pose_cov);
    }
    if (st == COSLAM_OK) {
        st = check_sighting(&msg->sighting, msg->receiver_id);
    }
    for (uint16_t i = 0; i < msg->map.n_landmarks && st == COSLAM_OK; ++i) {
        st = check_landmark(&msg->map.lm[i]);
    }
    if (st == COSLAM_OK) {
        const id_view_t v = {msg->map.lm, NULL};
        st = check_unique_ids(&v, msg->map.n_landmarks);
    }
    return st;
}

size_t map_msg_encoded_size(const map_msg_t *msg)
{
    if (msg == NULL || msg->map.n_landmarks > COSLAM_MAX_MSG_LANDMARKS) {
        return 0U;
    }
    return MAP_MSG_BYTES(msg->map.n_landmarks);
}

coslam_status_t map_msg_encode(const map_msg_t *msg, uint8_t *buf, size_t cap, size_t *len)
{
    if (len == NULL) {
        return COSLAM_E_ARG;
    }
    *len = 0U;
    if (msg == NULL || buf == NULL) {
        return COSLAM_E_ARG;
    }
    const coslam_status_t st = map_msg_validate(msg);
    if (st != COSLAM_OK) {
        return st;
    }
    const size_t size = MAP_MSG_BYTES(msg->map.n_landmarks);
    if (cap < size) {
        return COSLAM_E_CAPACITY;
    }
    const map_estimate_t *m = &msg->map;
    const map_msg_sighting_t *s = &msg->sighting;
    uint8_t *p = buf;
    for (unsigned i = 0; i < 4U; ++i) {
        p = put_u8(p, map_msg_magic[i]);
    }
    p = put_u8(p, msg->version);
    p = put_u8(p, msg->sender_id);
    p = put_u8(p, msg->receiver_id);
    p = put_u8(p, s->valid ? (uint8_t)FLAG_SIGHTING : (uint8_t)0U);
    p = put_u32(p, (uint32_t)size);
    p = put_u32(p, msg->seq);
    p = put_u64(p, msg->stamp_us);
    p = put_f64(p, m->pose.x);
    p = put_f64(p, m->pose.y);
    p = put_f64(p, m->pose.theta);
    for (int i = 0; i < 3; ++i) {
        for (int j = i; j < 3; ++j) {
            p = put_f64(p, m->pose_cov.m[i][j]);
        }
    }
    COSLAM_ASSERT(p == buf + OFF_SIGHTING);
    if (s->valid) {
        p = put_f64(p, s->range_m);
        p = put_f64(p, s->bearing_rad);
        p = put_f64(p, s->range_var_m2);
        p = put_f64(p, s->bearing_var_rad2);
        p = put_u64(p, s->stamp_us);
    } else {
        memset(p, 0, SIGHTING_BYTES);
        p += SIGHTING_BYTES;
    }
    p = put_u16(p, m->n_landmarks);
    COSLAM_ASSERT(p == buf + MAP_MSG_HEADER_BYTES);
    for (uint16_t k = 0; k < m->n_landmarks; ++k) {
        const map_landmark_t *lm = &m->lm[k];
        p = put_f64(p, lm->mean.x);
        p = put_f64(p, lm->mean.y);
        p = put_f64(p, lm->cov.xx);
        p = put_f64(p, lm->cov.xy);
        p = put_f64(p, lm->cov.yy);
        p = put_f64(p, lm->cov_rel.xx);
        p = put_f64(p, lm->cov_rel.xy);
        p = put_f64(p, lm->cov_rel.yy);
        p = put_u32(p, lm->id);
        p = put_u16(p, lm->n_obs);
        p = put_u16(p, lm->src_mask);
        p = put_u8(p, lm->signature);
    }
    const size_t body = (size_t)(p - buf);
    COSLAM_ASSERT(body + MAP_MSG_CRC_BYTES == size);
    (void)put_u32(p, crc32_update(0U, buf, body));
    *len = size;
    return COSLAM_OK;
}

/* ------------------------------------------------------------------------- */

/* Everything of the fixed part, parsed from bytes [0, MAP_MSG_HEADER_BYTES). */
typedef struct {
    uint8_t flags;
    uint8_t sender_id;
    uint8_t receiver_id;
    uint32_t seq;
    uint64_t stamp_us;
    pose2_t pose;
    cov3_t pose_cov;
    map_msg_sighting_t sighting;
    uint16_t n;
} wire_header_t;

static void read_header(const uint8_t *buf, wire_header_t *h)
{
    const uint8_t *p = buf + 5;
    h->sender_id = p[0];
    h->receiver_id = p[1];
    h->flags = p[2];
    p = buf + 12;
    h->seq = get_u32(p);
    h->stamp_us = get_u64(p + 4);
    p += 12;
    h->pose.x = get_f64(p);
    h->pose.y = get_f64(p + 8);
    h->pose.theta = get_f64(p + 16);
    p += 24;
    for (int i = 0; i < 3; ++i) {
        for (int j = i; j < 3; ++j) {
            h->pose_cov.m[i][j] = get_f64(p);
            h->pose_cov.m[j][i] = h->pose_cov.m[i][j];
            p += 8;
        }
    }
    h->sighting.valid = (h->flags & FLAG_SIGHTING) != 0U;
    h->sighting.range_m = get_f64(p);
    h->sighting.bearing_rad = get_f64(p + 8);
    h->sighting.range_var_m2 = get_f64(p + 16);
    h->sighting.bearing_var_rad2 = get_f64(p + 24);
    h->sighting.stamp_us = get_u64(p + 32);
    h->n = get_u16(buf + OFF_COUNT);
}

static void read_landmark(const uint8_t *p, map_landmark_t *lm)
{
    lm->mean.x = get_f64(p);
    lm->mean.y = get_f64(p + 8);
    lm->cov.xx = get_f64(p + 16);
    lm->cov.xy = get_f64(p + 24);
    lm->cov.yy = get_f64(p + 32);
    lm->cov_rel.xx = get_f64(p + 40);
    lm->cov_rel.xy = get_f64(p + 48);
    lm->cov_rel.yy = get_f64(p + 56);
    lm->id = get_u32(p + LM_OFF_ID);
    lm->n_obs = get_u16(p + 68);
    lm->src_mask = get_u16(p + 70);
    lm->signature = p[LM_OFF_SIGNATURE];
}

/* Framing checks 1-8 of the header comment. */
static coslam_status_t check_frame(const uint8_t *buf, size_t len)
{
    if (len < PREFIX_BYTES) {
        return COSLAM_E_MSG_TRUNCATED;
    }
    if (memcmp(buf, map_msg_magic, sizeof map_msg_magic) != 0) {
        return COSLAM_E_MSG_MAGIC;
    }
    if (buf[OFF_VERSION] != MAP_MSG_VERSION) {
        return COSLAM_E_MSG_VERSION;
    }
    const uint32_t length = get_u32(buf + OFF_LENGTH);
    if ((uint64_t)len < (uint64_t)length) {
        return COSLAM_E_MSG_TRUNCATED;
    }
    if ((uint64_t)len > (uint64_t)length || len < MAP_MSG_MIN_BYTES) {
        return COSLAM_E_MSG_LENGTH;
    }
    /* from here len == length, and the fixed part and CRC are in bounds */
    const size_t body = len - MAP_MSG_CRC_BYTES;
    if (crc32_update(0U, buf, body) != get_u32(buf + body)) {
        return COSLAM_E_MSG_CRC;
    }
    const uint16_t n = get_u16(buf + OFF_COUNT);
    if (n > COSLAM_MAX_MSG_LANDMARKS) {
        return COSLAM_E_MSG_COUNT;
    }
    if (len != MAP_MSG_BYTES(n)) {
        return COSLAM_E_MSG_LENGTH;
    }
    return COSLAM_OK;
}

coslam_status_t map_msg_decode(const uint8_t *buf, size_t len, map_msg_t *out)
{
    if (buf == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    coslam_status_t st = check_frame(buf, len);
    if (st != COSLAM_OK) {
        return st;
    }
    /* Pass 1: parse into locals and validate; *out is not touched. */
    wire_header_t h;
    read_header(buf, &h);
    if ((h.flags & (uint8_t)~FLAG_SIGHTING) != 0U) {
        return COSLAM_E_MSG_FIELD;
    }
    st = check_ids(h.sender_id, h.receiver_id);
    if (st == COSLAM_OK) {
        st = check_pose(&h.pose, &h.pose_cov);
    }
    if (st == COSLAM_OK && !h.sighting.valid) {
        /* canonical form: one byte string per message */
        for (size_t i = 0; i < SIGHTING_BYTES; ++i) {
            if (buf[OFF_SIGHTING + i] != 0U) {
                st = COSLAM_E_MSG_FIELD;
                break;
            }
        }
    }
    if (st == COSLAM_OK) {
        st = check_sighting(&h.sighting, h.receiver_id);
    }
    const uint8_t *lm_wire = buf + MAP_MSG_HEADER_BYTES;
    for (uint16_t i = 0; i < h.n && st == COSLAM_OK; ++i) {
        map_landmark_t lm;
        read_landmark(lm_wire + MAP_MSG_LANDMARK_BYTES * i, &lm);
        st = check_landmark(&lm);
    }
    if (st == COSLAM_OK) {
        const id_view_t v = {NULL, lm_wire};
        st = check_unique_ids(&v, h.n);
    }
    if (st != COSLAM_OK) {
        return st;
    }
    /* Pass 2: everything holds; write the result. */
    out->version = buf[OFF_VERSION];
    out->sender_id = h.sender_id;
    out->receiver_id = h.receiver_id;
    out->seq = h.seq;
    out->stamp_us = h.stamp_us;
    out->map.pose = h.pose;
    out->map.pose_cov = h.pose_cov;
    out->map.n_landmarks = h.n;
    out->sighting = h.sighting;
    for (uint16_t i = 0; i < h.n; ++i) {
        read_landmark(lm_wire + MAP_MSG_LANDMARK_BYTES * i, &out->map.lm[i]);
    }
    return COSLAM_OK;
}
