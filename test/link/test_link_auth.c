/*
 * The authentication decorator (hal/hal_link_auth.h) over an in-memory bus
 * (link_test_util.h) that carries any bytes from any claimed sender:
 *  - the trailer's layout byte for byte against an independent signer
 *    written from the header's table (libsodium directly);
 *  - genuine messages delivered byte-exact without their trailer;
 *  - forged (wrong key), other fleet (key id), modified (every region),
 *    truncated, unauthenticated, malformed, replayed (twice, old counter,
 *    after the sender restarts with a frozen clock), wrong sender ids
 *    (link vs trailer vs message), stale and future stamps: each refused,
 *    counted under its own reason and skipped by the same recv call;
 *  - send-side refusals, buffer overflow, counters across a restart;
 *  - the key helpers (hex, key file and its permissions) and the key wipe.
 */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cmocka.h>
#include <sodium.h>

#include "hal/hal_link_auth.h"
#define LT_WITH_SODIUM 1
#include "link_test_util.h"

#define ROBOT_A 1u
#define ROBOT_B 2u
#define ROBOT_C 3u
#define KEY_ID 7u

static const char *const KEY_HEX = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

/* ---- fixture ------------------------------------------------------------ */

typedef struct {
    uint64_t now_us;
} wall_t;

static uint64_t wall_read(void *ctx)
{
    return ((wall_t *)ctx)->now_us;
}

static lt_bus_t g_bus;
static hal_link_auth_t g_auth_a, g_auth_b;
static hal_link_t *g_a, *g_b; /* decorated endpoints of robots A and B; C is a bare endpoint */
static wall_t g_wall_a, g_wall_b;
static uint8_t g_key[HAL_LINK_AUTH_KEY_BYTES];
static uint8_t g_msg[MAP_MSG_MAX_BYTES];
static uint8_t g_dg[HAL_LINK_MAX_PAYLOAD + 64];
static uint8_t g_rx[HAL_LINK_MAX_PAYLOAD];

static hal_link_auth_config_t config_for(wall_t *w)
{
    hal_link_auth_config_t c;
    memset(&c, 0, sizeof c);
    memcpy(c.key, g_key, sizeof c.key);
    c.key_id = KEY_ID;
    c.window_us = 5000000u;
    c.wall_clock_us = wall_read;
    c.clock_ctx = w;
    return c;
}

static int setup(void **state)
{
    (void)state;
    const uint16_t ids[3] = {ROBOT_A, ROBOT_B, ROBOT_C};
    lt_bus_init(&g_bus, ids, 3);
    assert_int_equal(hal_link_auth_key_from_hex(KEY_HEX, g_key), HAL_OK);
    g_wall_a.now_us = 1700000000000000u;
    g_wall_b.now_us = 1700000000000000u + 1234u; /* clocks a little apart */
    hal_link_auth_config_t ca = config_for(&g_wall_a), cb = config_for(&g_wall_b);
    g_a = hal_link_auth_open(&g_bus.ep[0].link, &ca, &g_auth_a);
    g_b = hal_link_auth_open(&g_bus.ep[1].link, &cb, &g_auth_b);
    assert_non_null(g_a);
    assert_non_null(g_b);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    hal_link_close(g_a);
    hal_link_close(g_b);
    return 0;
}

/* the independent signer: lt_sign (link_test_util.h) */
static size_t sign(uint8_t *out, const uint8_t *msg, size_t len, const uint8_t *key, uint8_t key_id, uint16_t sender,
                   uint64_t counter, uint64_t stamp_us)
{
    return lt_sign(out, msg, len, key, key_id, sender, counter, stamp_us);
}

static void le(uint8_t *p, uint64_t v, int n)
{
    lt_le(p, v, n);
}

/* A's message to B, n landmarks. */
static size_t msg_a(uint16_t n, uint64_t seed)
{
    const size_t len = lt_encode(g_msg, (uint8_t)ROBOT_A, (uint8_t)ROBOT_B, n, seed);
    assert_true(len > 0u);
    return len;
}

static hal_status_t recv_b(hal_link_rx_info_t *info)
{
    return hal_link_recv(g_b, g_rx, sizeof g_rx, info, 0);
}

static const hal_link_auth_counters_t *cb(void)
{
    return hal_link_auth_counters(&g_auth_b);
}

/* Refusal counters of B, summed. */
static uint32_t refused_b(void)
{
    const hal_link_auth_counters_t *c = cb();
    return c->rx_malformed + c->rx_unauthenticated + c->rx_truncated + c->rx_wrong_key + c->rx_bad_mac +
           c->rx_sender_mismatch + c->rx_stale + c->rx_future + c->rx_replay + c->rx_oversize;
}

/* ---- tests -------------------------------------------------------------- */

static void test_trailer_layout_and_genuine_delivery(void **state)
{
    (void)state;
    const size_t len = msg_a(5, 11);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len, 0), HAL_OK);
    /* what went over the inner link: message + 52-byte trailer, exactly as the
     * independent signer makes it (first counter = the wall clock) */
    lt_endpoint_t *eb = &g_bus.ep[1];
    assert_int_equal(eb->n, 1);
    const lt_dgram_t *wire = &eb->q[eb->head];
    assert_int_equal(wire->len, len + HAL_LINK_AUTH_TRAILER_BYTES);
    const size_t n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_A, g_wall_a.now_us, g_wall_a.now_us);
    assert_int_equal(n, wire->len);
    assert_memory_equal(wire->data, g_dg, n);

    hal_link_rx_info_t info;
    assert_int_equal(recv_b(&info), HAL_OK);
    assert_int_equal(info.len, len);
    assert_int_equal(info.src_id, ROBOT_A);
    assert_memory_equal(g_rx, g_msg, len); /* delivered without the trailer, byte-exact */
    map_msg_t m;
    assert_int_equal(map_msg_decode(g_rx, info.len, &m), COSLAM_OK);
    assert_int_equal(cb()->delivered, 1);
    assert_int_equal(refused_b(), 0);
    assert_int_equal(hal_link_auth_counters(&g_auth_a)->sent, 1);
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
}

/* The profile's largest map message (COSLAM_MAX_MSG_LANDMARKS landmarks,
 * MAP_MSG_MAX_BYTES) is one datagram: signed, it passes the link's payload
 * check, arrives whole and decodes to the same message (the compile-time tie
 * of config.h, hal_link.h and hal_link_auth.c, exercised at run time). */
static void test_largest_message_round_trips(void **state)
{
    (void)state;
    const size_t len = msg_a(LT_MAX_LANDMARKS, 29);
    assert_int_equal(len, MAP_MSG_MAX_BYTES);
    assert_true(len + HAL_LINK_AUTH_TRAILER_BYTES <= HAL_LINK_MAX_PAYLOAD);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len, 0), HAL_OK);
    assert_int_equal(g_bus.ep[1].q[g_bus.ep[1].head].len, len + HAL_LINK_AUTH_TRAILER_BYTES);
    hal_link_rx_info_t info;
    assert_int_equal(recv_b(&info), HAL_OK);
    assert_int_equal(info.len, len);
    assert_memory_equal(g_rx, g_msg, len);
    static map_msg_t m;
    assert_int_equal(map_msg_decode(g_rx, info.len, &m), COSLAM_OK);
    assert_int_equal(m.map.n_landmarks, COSLAM_MAX_MSG_LANDMARKS);
    static uint8_t again[MAP_MSG_MAX_BYTES];
    size_t len2 = 0;
    assert_int_equal(map_msg_encode(&m, again, sizeof again, &len2), COSLAM_OK);
    assert_int_equal(len2, len);
    assert_memory_equal(again, g_msg, len);
    assert_int_equal(refused_b(), 0);
}

static void test_forged_wrong_key_and_other_fleet(void **state)
{
    (void)state;
    const size_t len = msg_a(3, 12);
    uint8_t other_key[HAL_LINK_AUTH_KEY_BYTES];
    memcpy(other_key, g_key, sizeof other_key);
    other_key[31] ^= 0x01u;
    size_t n = sign(g_dg, g_msg, len, other_key, KEY_ID, ROBOT_A, g_wall_a.now_us, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n);
    n = sign(g_dg, g_msg, len, g_key, KEY_ID + 1u, ROBOT_A, g_wall_a.now_us + 1u, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n);
    hal_link_rx_info_t info;
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_bad_mac, 1);
    assert_int_equal(cb()->rx_wrong_key, 1);
    assert_int_equal(cb()->delivered, 0);
}

static void test_every_modified_byte_region_refused(void **state)
{
    (void)state;
    const size_t len = msg_a(4, 13);
    const size_t n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_A, g_wall_a.now_us, g_wall_a.now_us);
    /* a byte of: magic..header, the pose, a landmark, the CRC, trailer sender,
     * counter, stamp, MAC first and last */
    const size_t at[] = {5, 30, 200, len - 1u, len + 2u, len + 4u, len + 12u, len + 20u, n - 1u};
    for (size_t i = 0; i < sizeof at / sizeof at[0]; ++i) {
        uint8_t bad[sizeof g_dg];
        memcpy(bad, g_dg, n);
        bad[at[i]] ^= 0x40u;
        lt_inject(&g_bus, 1, ROBOT_A, bad, n);
    }
    hal_link_rx_info_t info;
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_bad_mac, sizeof at / sizeof at[0]);
    /* the unmodified one still passes afterwards */
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n);
    assert_int_equal(recv_b(&info), HAL_OK);
    assert_memory_equal(g_rx, g_msg, len);
    assert_int_equal(refused_b(), sizeof at / sizeof at[0]);
}

static void test_truncated_unauthenticated_malformed(void **state)
{
    (void)state;
    const size_t len = msg_a(2, 14);
    const size_t n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_A, g_wall_a.now_us, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n - 1u);  /* last MAC byte cut */
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, len + 20u); /* MAC cut */
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, len - 10u); /* into the message */
    lt_inject(&g_bus, 1, ROBOT_A, g_msg, len);      /* a plain codec message: no trailer */
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, 11u);       /* not even a codec header */
    uint8_t junk[64];
    memset(junk, 0xA5, sizeof junk);
    lt_inject(&g_bus, 1, ROBOT_A, junk, sizeof junk); /* no magic */
    uint8_t longer[sizeof g_dg];
    memcpy(longer, g_dg, n);
    longer[n] = 0;
    lt_inject(&g_bus, 1, ROBOT_A, longer, n + 1u); /* a byte after the trailer */
    memcpy(longer, g_dg, n);
    longer[len] = 2u; /* unknown trailer format */
    lt_inject(&g_bus, 1, ROBOT_A, longer, n);
    hal_link_rx_info_t info;
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_truncated, 3);
    assert_int_equal(cb()->rx_unauthenticated, 1);
    assert_int_equal(cb()->rx_malformed, 4);
    assert_int_equal(cb()->rx_bad_mac, 0);
    assert_int_equal(cb()->delivered, 0);
}

static void test_replays_refused(void **state)
{
    (void)state;
    hal_link_rx_info_t info;
    const size_t len1 = msg_a(1, 15), len2 = msg_a(2, 16);
    /* the same datagram twice */
    const size_t n1 = sign(g_dg, g_msg, len2, g_key, KEY_ID, ROBOT_A, g_wall_a.now_us + 10u, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n1);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n1);
    assert_int_equal(recv_b(&info), HAL_OK);
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_replay, 1);
    /* an older counter (a message captured earlier, played after a newer one) */
    (void)lt_encode(g_msg, (uint8_t)ROBOT_A, (uint8_t)ROBOT_B, 1, 15);
    const size_t n0 = sign(g_dg, g_msg, len1, g_key, KEY_ID, ROBOT_A, g_wall_a.now_us + 5u, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n0);
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_replay, 2);
    /* replay state is per sender: C's counter is independent of A's */
    const size_t lc = lt_encode(g_msg, (uint8_t)ROBOT_C, (uint8_t)ROBOT_B, 1, 17);
    const size_t nc = sign(g_dg, g_msg, lc, g_key, KEY_ID, ROBOT_C, g_wall_a.now_us + 1u, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_C, g_dg, nc);
    assert_int_equal(recv_b(&info), HAL_OK);
    assert_int_equal(info.src_id, ROBOT_C);
    assert_int_equal(cb()->delivered, 2);
}

static void test_wrong_sender_ids_refused(void **state)
{
    (void)state;
    hal_link_rx_info_t info;
    const size_t len = msg_a(2, 18); /* map sender = A */
    /* genuine datagram of A, but arriving with link sender C */
    size_t n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_A, g_wall_a.now_us, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_C, g_dg, n);
    /* C holds the key and signs as C a map claiming to be A's */
    n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_C, g_wall_a.now_us + 1u, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_C, g_dg, n);
    /* trailer says A, link says A, message says C */
    const size_t lc = lt_encode(g_msg, (uint8_t)ROBOT_C, (uint8_t)ROBOT_B, 1, 19);
    n = sign(g_dg, g_msg, lc, g_key, KEY_ID, ROBOT_A, g_wall_a.now_us + 2u, g_wall_a.now_us);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n);
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_sender_mismatch, 3);
    assert_int_equal(cb()->delivered, 0);
    /* and the send side refuses to sign another robot's message */
    assert_int_equal(hal_link_send(g_b, ROBOT_A, g_msg, lc, 0), HAL_E_ARG);
    assert_int_equal(hal_link_auth_counters(&g_auth_b)->send_wrong_sender, 1);
}

static void test_time_window(void **state)
{
    (void)state;
    hal_link_rx_info_t info;
    const size_t len = msg_a(1, 20);
    const uint64_t now = g_wall_b.now_us, w = 5000000u;
    size_t n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_A, 100u, now - w - 1u);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n);
    n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_A, 101u, now + w + 1u);
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n);
    n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_A, 102u, now - w); /* on the edge: accepted */
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n);
    assert_int_equal(recv_b(&info), HAL_OK);
    assert_int_equal(cb()->rx_stale, 1);
    assert_int_equal(cb()->rx_future, 1);
    /* a genuine message held back until the window has passed */
    assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len, 0), HAL_OK);
    g_wall_b.now_us += w + 2000u;
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_stale, 2);
}

static void test_one_recv_skips_refused_to_genuine(void **state)
{
    (void)state;
    const size_t len = msg_a(6, 21);
    lt_inject(&g_bus, 1, ROBOT_A, g_msg, len);                        /* unauthenticated */
    size_t n = sign(g_dg, g_msg, len, g_key, KEY_ID, ROBOT_A, 1u, 1u); /* stale */
    lt_inject(&g_bus, 1, ROBOT_A, g_dg, n);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len, 0), HAL_OK); /* genuine, third */
    hal_link_rx_info_t info;
    assert_int_equal(hal_link_recv(g_b, g_rx, sizeof g_rx, &info, 1000), HAL_OK);
    assert_memory_equal(g_rx, g_msg, len);
    assert_int_equal(refused_b(), 2);
    assert_int_equal(cb()->rx_unauthenticated, 1);
    assert_int_equal(cb()->rx_stale, 1);
}

/* An inner link that always has a forgery ready (the right key id, a MAC
 * under another key): one receive call checks a bounded number and returns
 * (timeout 0, as the robot polls, or a short one), so a flood cannot hold
 * the robot's control step. */
static uint32_t g_flood_calls;
static size_t g_flood_len;
static hal_status_t flood_self_id(hal_link_t *dev, uint16_t *id)
{
    (void)dev;
    *id = ROBOT_B;
    return HAL_OK;
}
static hal_status_t flood_recv(hal_link_t *dev, uint8_t *buf, size_t cap, hal_link_rx_info_t *info, uint32_t timeout_us)
{
    (void)dev;
    (void)timeout_us;
    g_flood_calls++;
    assert_true(g_flood_len <= cap);
    memcpy(buf, g_dg, g_flood_len);
    info->len = g_flood_len;
    info->src_id = ROBOT_A;
    info->stamp_us = 0;
    return HAL_OK;
}
static const hal_link_ops_t flood_ops = {flood_self_id, NULL, flood_recv, NULL};

static void test_flood_of_forgeries_is_bounded(void **state)
{
    (void)state;
    uint8_t other[HAL_LINK_AUTH_KEY_BYTES];
    memset(other, 0x5a, sizeof other);
    const size_t len = msg_a(LT_MAX_LANDMARKS, 5);
    g_flood_len = sign(g_dg, g_msg, len, other, KEY_ID, ROBOT_A, 1u, g_wall_b.now_us);
    hal_link_t inner = {&flood_ops, NULL};
    static hal_link_auth_t auth;
    hal_link_auth_config_t c = config_for(&g_wall_b);
    hal_link_t *l = hal_link_auth_open(&inner, &c, &auth);
    assert_non_null(l);
    hal_link_rx_info_t info;
    const uint32_t waits[2] = {0u, 1000u};
    for (int i = 0; i < 2; ++i) {
        g_flood_calls = 0;
        assert_int_equal(hal_link_recv(l, g_rx, sizeof g_rx, &info, waits[i]), HAL_E_TIMEOUT);
        assert_true(g_flood_calls >= 1u && g_flood_calls <= HAL_LINK_AUTH_REFUSED_PER_CALL);
    }
    assert_true(hal_link_auth_counters(&auth)->rx_bad_mac >= 2u);
    hal_link_close(l);
}

static void test_overflow_and_oversize(void **state)
{
    (void)state;
    const size_t len = msg_a(3, 22);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len, 0), HAL_OK);
    hal_link_rx_info_t info;
    uint8_t small[40];
    assert_int_equal(hal_link_recv(g_b, small, sizeof small, &info, 0), HAL_E_OVERFLOW);
    assert_int_equal(info.len, len);
    assert_int_equal(info.src_id, ROBOT_A);
    assert_memory_equal(small, g_msg, sizeof small);
    assert_int_equal(cb()->rx_overflow, 1);
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT); /* discarded, not re-delivered */
    /* a datagram above HAL_LINK_MAX_PAYLOAD from the inner link */
    static uint8_t huge[HAL_LINK_MAX_PAYLOAD + 10u];
    memset(huge, 1, sizeof huge);
    lt_inject(&g_bus, 1, ROBOT_A, huge, sizeof huge);
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_oversize, 1);
}

static void test_send_refusals(void **state)
{
    (void)state;
    const hal_link_auth_counters_t *ca = hal_link_auth_counters(&g_auth_a);
    uint8_t junk[100];
    memset(junk, 0x11, sizeof junk);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, junk, sizeof junk, 0), HAL_E_ARG);
    const size_t len = msg_a(2, 23);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len - 1u, 0), HAL_E_ARG); /* length field != len */
    assert_int_equal(ca->send_not_map, 2);
    /* a (header-only) message too long for its trailer to fit a datagram */
    static uint8_t big[HAL_LINK_MAX_PAYLOAD];
    memcpy(big, g_msg, 12);
    const uint32_t L = HAL_LINK_MAX_PAYLOAD - 10u;
    le(big + 8, L, 4);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, big, L, 0), HAL_E_ARG);
    assert_int_equal(ca->send_too_long, 1);
    assert_int_equal(hal_link_send(g_a, ROBOT_A, g_msg, len, 0), HAL_E_ARG); /* to itself: the inner link's refusal */
    assert_int_equal(ca->send_inner_failed, 1);
    assert_int_equal(ca->sent, 0);
    assert_int_equal(g_bus.ep[1].n, 0);
}

static void test_counter_monotonic_and_survives_restart(void **state)
{
    (void)state;
    hal_link_rx_info_t info;
    const size_t len = msg_a(1, 24);
    /* frozen clock: counters still increase, all accepted */
    for (int i = 0; i < 3; ++i) assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len, 0), HAL_OK);
    for (int i = 0; i < 3; ++i) assert_int_equal(recv_b(&info), HAL_OK);
    /* A restarts (new state, counter forgotten) 1 ms later: its counter starts
     * at its wall clock, above everything it sent before */
    hal_link_close(g_a);
    g_wall_a.now_us += 1000u;
    hal_link_auth_config_t ca = config_for(&g_wall_a);
    g_a = hal_link_auth_open(&g_bus.ep[0].link, &ca, &g_auth_a);
    assert_non_null(g_a);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len, 0), HAL_OK);
    assert_int_equal(recv_b(&info), HAL_OK);
    assert_int_equal(cb()->delivered, 4);
    assert_int_equal(refused_b(), 0);
    /* a restart whose clock stepped back is refused until the clock passes
     * the old counter: documented (docs/security.md) */
    hal_link_close(g_a);
    g_wall_a.now_us -= 2000u;
    ca = config_for(&g_wall_a);
    g_a = hal_link_auth_open(&g_bus.ep[0].link, &ca, &g_auth_a);
    assert_int_equal(hal_link_send(g_a, ROBOT_B, g_msg, len, 0), HAL_OK);
    assert_int_equal(recv_b(&info), HAL_E_TIMEOUT);
    assert_int_equal(cb()->rx_replay, 1);
}

static void test_broadcast_and_self_id(void **state)
{
    (void)state;
    const size_t len = lt_encode(g_msg, (uint8_t)ROBOT_A, MAP_MSG_BROADCAST, 2, 25);
    assert_int_equal(hal_link_send(g_a, HAL_LINK_BROADCAST, g_msg, len, 0), HAL_OK);
    hal_link_rx_info_t info;
    assert_int_equal(recv_b(&info), HAL_OK);
    assert_memory_equal(g_rx, g_msg, len);
    assert_int_equal(g_bus.ep[2].n, 1); /* C got it too (undecorated: message + trailer) */
    assert_int_equal(g_bus.ep[2].q[g_bus.ep[2].head].len, len + HAL_LINK_AUTH_TRAILER_BYTES);
    uint16_t id = 0;
    assert_int_equal(hal_link_self_id(g_a, &id), HAL_OK);
    assert_int_equal(id, ROBOT_A);
}

static void test_open_arguments_and_key_wipe(void **state)
{
    (void)state;
    hal_link_auth_config_t c = config_for(&g_wall_a);
    static hal_link_auth_t st;
    assert_null(hal_link_auth_open(NULL, &c, &st));
    assert_null(hal_link_auth_open(&g_bus.ep[2].link, NULL, &st));
    assert_null(hal_link_auth_open(&g_bus.ep[2].link, &c, NULL));
    g_bus.ep[2].id = 300; /* not a map message sender id */
    assert_null(hal_link_auth_open(&g_bus.ep[2].link, &c, &st));
    g_bus.ep[2].id = ROBOT_C;
    hal_link_t *l = hal_link_auth_open(&g_bus.ep[2].link, &c, &st);
    assert_non_null(l);
    assert_memory_equal(st.key, g_key, sizeof g_key);
    hal_link_close(l);
    static const uint8_t zero[HAL_LINK_AUTH_KEY_BYTES];
    assert_memory_equal(st.key, zero, sizeof zero);
    uint16_t id;
    assert_int_equal(hal_link_self_id(l, &id), HAL_E_CLOSED);
    assert_int_equal(hal_link_send(l, ROBOT_A, g_msg, 200, 0), HAL_E_CLOSED);
}

static void test_key_helpers(void **state)
{
    (void)state;
    uint8_t k[HAL_LINK_AUTH_KEY_BYTES];
    assert_int_equal(hal_link_auth_key_from_hex(KEY_HEX, k), HAL_OK);
    for (unsigned i = 0; i < sizeof k; ++i) assert_int_equal(k[i], i);
    char buf[100];
    snprintf(buf, sizeof buf, "  %s\n", KEY_HEX);
    assert_int_equal(hal_link_auth_key_from_hex(buf, k), HAL_OK);
    assert_int_equal(hal_link_auth_key_from_hex("0011", k), HAL_E_ARG);
    snprintf(buf, sizeof buf, "%sff", KEY_HEX);
    assert_int_equal(hal_link_auth_key_from_hex(buf, k), HAL_E_ARG);
    snprintf(buf, sizeof buf, "%s", KEY_HEX);
    buf[10] = 'g';
    assert_int_equal(hal_link_auth_key_from_hex(buf, k), HAL_E_ARG);
    static const uint8_t zero[HAL_LINK_AUTH_KEY_BYTES];
    assert_memory_equal(k, zero, sizeof zero); /* wiped on error */

    char path[] = "/tmp/coslam-key-XXXXXX";
    const int fd = mkstemp(path); /* mode 0600 */
    assert_true(fd >= 0);
    assert_int_equal(write(fd, KEY_HEX, 64), 64);
    assert_int_equal(write(fd, "\n", 1), 1);
    close(fd);
    memset(k, 0, sizeof k);
    assert_int_equal(hal_link_auth_key_from_file(path, k), HAL_OK);
    for (unsigned i = 0; i < sizeof k; ++i) assert_int_equal(k[i], i);
    assert_int_equal(hal_link_auth_key_parse(path, k), HAL_OK);
    assert_int_equal(hal_link_auth_key_parse(KEY_HEX, k), HAL_OK);
    assert_int_equal(chmod(path, 0644), 0);
    assert_int_equal(hal_link_auth_key_from_file(path, k), HAL_E_ARG); /* readable by others */
    unlink(path);
    assert_int_equal(hal_link_auth_key_from_file(path, k), HAL_E_NOT_FOUND);
    assert_int_equal(hal_link_auth_key_parse("/nonexistent/fleet.key", k), HAL_E_NOT_FOUND);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_trailer_layout_and_genuine_delivery, setup, teardown),
        cmocka_unit_test_setup_teardown(test_largest_message_round_trips, setup, teardown),
        cmocka_unit_test_setup_teardown(test_forged_wrong_key_and_other_fleet, setup, teardown),
        cmocka_unit_test_setup_teardown(test_every_modified_byte_region_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_truncated_unauthenticated_malformed, setup, teardown),
        cmocka_unit_test_setup_teardown(test_replays_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_wrong_sender_ids_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_time_window, setup, teardown),
        cmocka_unit_test_setup_teardown(test_one_recv_skips_refused_to_genuine, setup, teardown),
        cmocka_unit_test_setup_teardown(test_overflow_and_oversize, setup, teardown),
        cmocka_unit_test_setup_teardown(test_flood_of_forgeries_is_bounded, setup, teardown),
        cmocka_unit_test_setup_teardown(test_send_refusals, setup, teardown),
        cmocka_unit_test_setup_teardown(test_counter_monotonic_and_survives_restart, setup, teardown),
        cmocka_unit_test_setup_teardown(test_broadcast_and_self_id, setup, teardown),
        cmocka_unit_test_setup_teardown(test_open_arguments_and_key_wipe, setup, teardown),
        cmocka_unit_test(test_key_helpers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
