/*
 * Test helpers for the link backends (test/link): valid map messages from
 * a seed, an in-memory loopback "bus" of hal_link endpoints that carries
 * arbitrary bytes (so the decorator can be tested without DDS, and forged
 * datagrams injected from any link-layer sender), and the Cyclone settings
 * that keep a test on loopback and away from other processes.
 * Header-only (static functions), C11 and C++.
 */
#ifndef COSLAM_LINK_TEST_UTIL_H
#define COSLAM_LINK_TEST_UTIL_H

#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "coslam/map_msg.h"
#include "coslam/pose2.h"
#include "coslam/rng.h"
#include "hal/hal_link.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The most landmarks a message may have: COSLAM_MAX_MSG_LANDMARKS, which
 * config.h caps at what fits one datagram with a 64-byte trailer in every
 * profile (docs/map-message.md "Message and link"); checked again here. */
#define LT_MAX_LANDMARKS ((uint16_t)COSLAM_MAX_MSG_LANDMARKS)
#ifdef __cplusplus
static_assert(MAP_MSG_MAX_BYTES + HAL_LINK_TRAILER_RESERVE <= HAL_LINK_MAX_PAYLOAD, "largest message fits the link");
#else
_Static_assert(MAP_MSG_MAX_BYTES + HAL_LINK_TRAILER_RESERVE <= HAL_LINK_MAX_PAYLOAD, "largest message fits the link");
#endif

static inline double lt_uni(rng_t *r, double lo, double hi)
{
    return lo + (hi - lo) * rng_uniform(r);
}

/* A valid message from `sender` to `receiver` (MAP_MSG_BROADCAST: no
 * sighting) with n landmarks and seeded random values. */
static inline void lt_make_msg(map_msg_t *m, uint8_t sender, uint8_t receiver, uint16_t n, uint64_t seed)
{
    rng_t r;
    rng_seed(&r, seed);
    map_msg_init(m);
    m->sender_id = sender;
    m->receiver_id = receiver;
    m->seq = (uint32_t)rng_next_u64(&r);
    m->stamp_us = rng_next_u64(&r) >> 8;
    m->map.pose.x = lt_uni(&r, -50.0, 50.0);
    m->map.pose.y = lt_uni(&r, -50.0, 50.0);
    m->map.pose.theta = lt_uni(&r, -COSLAM_PI, COSLAM_PI);
    double a[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a[i][j] = lt_uni(&r, -0.3, 0.3);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j <= i; ++j) {
            double s = (i == j) ? 1e-3 : 0.0;
            for (int k = 0; k < 3; ++k) s += a[i][k] * a[j][k];
            m->map.pose_cov.m[i][j] = s;
            m->map.pose_cov.m[j][i] = s;
        }
    }
    if (receiver != MAP_MSG_BROADCAST) {
        m->sighting.valid = true;
        m->sighting.range_m = lt_uni(&r, 0.2, 6.0);
        m->sighting.bearing_rad = lt_uni(&r, -COSLAM_PI, COSLAM_PI);
        m->sighting.range_var_m2 = lt_uni(&r, 1e-4, 0.1);
        m->sighting.bearing_var_rad2 = lt_uni(&r, 1e-5, 0.05);
        m->sighting.stamp_us = m->stamp_us - (rng_next_u64(&r) % 100000u);
    }
    m->map.n_landmarks = n;
    uint32_t id = 1u + (uint32_t)(rng_next_u64(&r) % 100u);
    for (uint16_t i = 0; i < n; ++i) {
        map_landmark_t *l = &m->map.lm[i];
        l->mean.x = lt_uni(&r, -30.0, 30.0);
        l->mean.y = lt_uni(&r, -30.0, 30.0);
        const double sx = lt_uni(&r, 1e-3, 0.5), sy = lt_uni(&r, 1e-3, 0.5), rho = lt_uni(&r, -0.9, 0.9);
        l->cov.xx = sx * sx;
        l->cov.yy = sy * sy;
        l->cov.xy = rho * sx * sy;
        const double rx = lt_uni(&r, 1e-3, 0.3), ry = lt_uni(&r, 1e-3, 0.3), rr = lt_uni(&r, -0.9, 0.9);
        l->cov_rel.xx = rx * rx;
        l->cov_rel.yy = ry * ry;
        l->cov_rel.xy = rr * rx * ry;
        l->id = id;
        id += 1u + (uint32_t)(rng_next_u64(&r) % 1000u);
        l->n_obs = (uint16_t)(1u + rng_next_u64(&r) % 500u);
        l->src_mask = (uint16_t)(1u + rng_next_u64(&r) % ((1u << COSLAM_MAX_ROBOTS) - 1u));
        l->signature = (uint8_t)(rng_next_u64(&r) % 4u);
    }
}

/* The encoded bytes of lt_make_msg(...) into buf (MAP_MSG_MAX_BYTES); returns the length, 0 on failure. */
static inline size_t lt_encode(uint8_t *buf, uint8_t sender, uint8_t receiver, uint16_t n, uint64_t seed)
{
    static map_msg_t m; /* large: not on the stack; tests are single-threaded */
    lt_make_msg(&m, sender, receiver, n, seed);
    size_t len = 0;
    return map_msg_encode(&m, buf, MAP_MSG_MAX_BYTES, &len) == COSLAM_OK ? len : 0u;
}

/* ---- in-memory bus: endpoints with a FIFO each, arbitrary bytes --------- */

#define LT_BUS_ENDPOINTS 4
#define LT_BUS_QUEUE 16
#define LT_BUS_MAX 20000u /* above HAL_LINK_MAX_PAYLOAD: oversize datagrams can be injected */

typedef struct {
    uint16_t src;
    size_t len;
    uint8_t data[LT_BUS_MAX];
} lt_dgram_t;

typedef struct lt_bus lt_bus_t;

typedef struct {
    hal_link_t link;
    lt_bus_t *bus;
    uint16_t id;
    lt_dgram_t q[LT_BUS_QUEUE];
    int head, n;
    uint32_t dropped;
} lt_endpoint_t;

struct lt_bus {
    lt_endpoint_t ep[LT_BUS_ENDPOINTS];
    int count;
    uint64_t now_us; /* arrival stamps */
};

static inline lt_endpoint_t *lt_ep(hal_link_t *d)
{
    return (lt_endpoint_t *)d->backend;
}

static inline void lt_push(lt_endpoint_t *e, uint16_t src, const uint8_t *data, size_t len)
{
    if (e->n == LT_BUS_QUEUE || len > LT_BUS_MAX) {
        e->dropped++;
        return;
    }
    lt_dgram_t *g = &e->q[(e->head + e->n) % LT_BUS_QUEUE];
    g->src = src;
    g->len = len;
    memcpy(g->data, data, len);
    e->n++;
}

static inline hal_status_t lt_self_id(hal_link_t *d, uint16_t *id)
{
    *id = lt_ep(d)->id;
    return HAL_OK;
}

static inline hal_status_t lt_send(hal_link_t *d, uint16_t dest, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    (void)timeout_us;
    lt_endpoint_t *self = lt_ep(d);
    if (dest == self->id) return HAL_E_ARG;
    for (int i = 0; i < self->bus->count; ++i) {
        lt_endpoint_t *e = &self->bus->ep[i];
        if (e != self && (dest == HAL_LINK_BROADCAST || dest == e->id)) lt_push(e, self->id, data, len);
    }
    return HAL_OK;
}

static inline hal_status_t lt_recv(hal_link_t *d, uint8_t *buf, size_t cap, hal_link_rx_info_t *info, uint32_t timeout_us)
{
    (void)timeout_us; /* nothing arrives while waiting in a single-threaded test */
    lt_endpoint_t *e = lt_ep(d);
    if (e->n == 0) return HAL_E_TIMEOUT;
    lt_dgram_t *g = &e->q[e->head];
    e->head = (e->head + 1) % LT_BUS_QUEUE;
    e->n--;
    info->len = g->len;
    info->src_id = g->src;
    info->stamp_us = e->bus->now_us;
    memcpy(buf, g->data, g->len < cap ? g->len : cap);
    return g->len > cap ? HAL_E_OVERFLOW : HAL_OK;
}

static const hal_link_ops_t lt_ops = {lt_self_id, lt_send, lt_recv, NULL};

/* Endpoints with ids ids[0..n). */
static inline void lt_bus_init(lt_bus_t *bus, const uint16_t *ids, int n)
{
    memset(bus, 0, sizeof *bus);
    bus->count = n;
    for (int i = 0; i < n; ++i) {
        bus->ep[i].link.ops = &lt_ops;
        bus->ep[i].link.backend = &bus->ep[i];
        bus->ep[i].bus = bus;
        bus->ep[i].id = ids[i];
    }
}

/* Make a datagram arrive at endpoint i as if sent by link id src. */
static inline void lt_inject(lt_bus_t *bus, int i, uint16_t src, const uint8_t *data, size_t len)
{
    lt_push(&bus->ep[i], src, data, len);
}

/* ---- Cyclone DDS on loopback only --------------------------------------- */

/* Loopback interface, no multicast: tests need no network and reach no
 * other host. Discovery between processes then needs peers (127.0.0.1). */
#define LT_DDS_LOOPBACK_XML                                                                               \
    "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/>"       \
    "</Interfaces><AllowMulticast>false</AllowMulticast></General>"                                       \
    "<Discovery><MaxAutoParticipantIndex>60</MaxAutoParticipantIndex></Discovery>"                        \
    "<Tracing><Verbosity>severe</Verbosity><OutputFile>stderr</OutputFile></Tracing></Domain></CycloneDDS>"

/* A partition no other process uses: this test run's pid. */
static inline const char *lt_partition(char *buf, size_t cap, const char *what, long pid)
{
    snprintf(buf, cap, "coslam-test-%s-%ld", what, pid);
    return buf;
}

/* ---- an independent signer (hal_link_auth.h's trailer table) ----------- */
#ifdef LT_WITH_SODIUM
#include <sodium.h>

static inline void lt_le(uint8_t *p, uint64_t v, int n)
{
    for (int i = 0; i < n; ++i) p[i] = (uint8_t)(v >> (8 * i));
}

/* msg (len bytes) + a 52-byte trailer into out; returns the datagram length. */
static inline size_t lt_sign(uint8_t *out, const uint8_t *msg, size_t len, const uint8_t *key, uint8_t key_id,
                             uint16_t sender, uint64_t counter, uint64_t stamp_us)
{
    memmove(out, msg, len);
    uint8_t *t = out + len;
    t[0] = 1u;
    t[1] = key_id;
    lt_le(t + 2, sender, 2);
    lt_le(t + 4, counter, 8);
    lt_le(t + 12, stamp_us, 8);
    crypto_auth_hmacsha512256(t + 20, out, len + 20u, key);
    return len + 52u;
}
#endif

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_LINK_TEST_UTIL_H */
