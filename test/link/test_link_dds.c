/*
 * The Cyclone DDS link (hal/hal_link_dds.h), robots as participants of one
 * process on a loopback-only domain (171) in a partition of this process:
 *  - datagrams (codec message + trailer of 0..64 bytes) round-trip byte for
 *    byte through the IDL sample, for 0..COSLAM_MAX_MSG_LANDMARKS
 *    landmarks, unicast and broadcast;
 *  - what the backend refuses at send (not a codec message, bad CRC, long
 *    trailer, to itself) and counts;
 *  - unicast filtering (rx_other_dest);
 *  - a rogue DDS writer on the same topic: samples whose fields do not
 *    encode, samples claiming the receiver's id: refused and counted;
 *  - the same rogue against robots behind the authentication decorator
 *    (hal_link_auth.h): forged, modified, truncated, unauthenticated,
 *    replayed and re-addressed samples all refused and counted per reason,
 *    a genuine robot's messages still delivered.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "hal/hal_link_auth.h"
#include "hal/hal_link_dds.h"
#define LT_WITH_SODIUM 1
#include "link_test_util.h"

#define DOMAIN 171u
#define ROBOT_A 1u
#define ROBOT_B 2u
#define ROBOT_C 3u
#define KEY_ID 1u
#define WAIT_US 2000000u

static char g_partition[64];
static hal_link_dds_t g_dds[3];
static uint8_t g_msg[HAL_LINK_DDS_MAX_DATAGRAM];
static uint8_t g_rx[HAL_LINK_MAX_PAYLOAD];
static uint8_t g_key[HAL_LINK_AUTH_KEY_BYTES];

static hal_link_t *open_robot(int i, uint16_t id)
{
    hal_link_dds_config_t c;
    memset(&c, 0, sizeof c);
    c.domain_id = DOMAIN;
    c.self_id = id;
    c.config = LT_DDS_LOOPBACK_XML;
    c.partition = g_partition;
    c.history_depth = 16;
    assert_int_equal(hal_link_dds_open(&g_dds[i], &c), HAL_OK);
    return &g_dds[i].link;
}

static void wait_all_matched(int n_links, uint32_t extra_readers)
{
    for (int i = 0; i < n_links; ++i) {
        assert_int_equal(hal_link_dds_wait_matched(&g_dds[i], (uint32_t)(n_links - 1) + extra_readers, WAIT_US), HAL_OK);
    }
}

static const hal_link_dds_counters_t *ctr(int i)
{
    return hal_link_dds_counters(&g_dds[i]);
}

/* ---- a rogue participant: plain Cyclone, same topic and partition ------- */

typedef struct {
    dds_entity_t pp, topic, writer, reader;
    coslam_msgs_msg_dds__MapMessage_ sample;
} rogue_t;

static rogue_t g_rogue;

static void rogue_open(rogue_t *r)
{
    r->pp = dds_create_participant(DOMAIN, NULL, NULL);
    assert_true(r->pp > 0);
    dds_qos_t *q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 32);
    dds_qset_partition1(q, g_partition);
    const dds_data_representation_id_t x1 = DDS_DATA_REPRESENTATION_XCDR1;
    dds_qset_data_representation(q, 1, &x1);
    r->topic = dds_create_topic(r->pp, &coslam_msgs_msg_dds__MapMessage__desc, HAL_LINK_DDS_DEFAULT_TOPIC, q, NULL);
    assert_true(r->topic > 0);
    r->writer = dds_create_writer(r->pp, r->topic, q, NULL);
    r->reader = dds_create_reader(r->pp, r->topic, q, NULL);
    dds_delete_qos(q);
    assert_true(r->writer > 0 && r->reader > 0);
}

static void rogue_write(rogue_t *r)
{
    assert_int_equal(dds_write(r->writer, &r->sample), DDS_RETCODE_OK);
}

/* Take the next sample the rogue overheard into r->sample (wait up to 2 s). */
static void rogue_capture(rogue_t *r)
{
    for (int k = 0; k < 2000; ++k) {
        void *b[1] = {&r->sample};
        dds_sample_info_t si;
        if (dds_take(r->reader, b, &si, 1, 1) == 1 && si.valid_data) return;
        dds_sleepfor(DDS_MSECS(1));
    }
    fail_msg("rogue captured nothing");
}

/* A valid sample (what robot `src` would send for lt_make_msg(..., seed)). */
static void sample_of(coslam_msgs_msg_dds__MapMessage_ *s, uint16_t src, uint16_t dest, uint16_t n, uint64_t seed)
{
    static map_msg_t m;
    lt_make_msg(&m, (uint8_t)src, (uint8_t)dest, n, seed);
    memset(s, 0, sizeof *s);
    s->link_src = src;
    s->link_dest = dest;
    s->version = m.version;
    s->sender_id = m.sender_id;
    s->receiver_id = m.receiver_id;
    s->sighting_valid = m.sighting.valid;
    s->seq = m.seq;
    s->stamp_us = m.stamp_us;
    s->pose_x = m.map.pose.x;
    s->pose_y = m.map.pose.y;
    s->pose_theta = m.map.pose.theta;
    const double(*c)[3] = m.map.pose_cov.m;
    const double up[6] = {c[0][0], c[0][1], c[0][2], c[1][1], c[1][2], c[2][2]};
    memcpy(s->pose_cov, up, sizeof up);
    s->sighting_range_m = m.sighting.range_m;
    s->sighting_bearing_rad = m.sighting.bearing_rad;
    s->sighting_range_var_m2 = m.sighting.range_var_m2;
    s->sighting_bearing_var_rad2 = m.sighting.bearing_var_rad2;
    s->sighting_stamp_us = m.sighting.stamp_us;
    s->n_landmarks = n;
    for (uint16_t i = 0; i < n; ++i) {
        const map_landmark_t *l = &m.map.lm[i];
        coslam_msgs_msg_dds__MapLandmark_ *o = &s->landmarks[i];
        o->mean_x = l->mean.x;
        o->mean_y = l->mean.y;
        o->cov_xx = l->cov.xx;
        o->cov_xy = l->cov.xy;
        o->cov_yy = l->cov.yy;
        o->cov_rel_xx = l->cov_rel.xx;
        o->cov_rel_xy = l->cov_rel.xy;
        o->cov_rel_yy = l->cov_rel.yy;
        o->id = l->id;
        o->n_obs = l->n_obs;
        o->src_mask = l->src_mask;
        o->signature = l->signature;
    }
}

/* ---- fixture ------------------------------------------------------------ */

static int teardown_links(void **state)
{
    (void)state;
    for (int i = 0; i < 3; ++i) hal_link_close(&g_dds[i].link);
    if (g_rogue.pp > 0) {
        dds_delete(g_rogue.pp);
        g_rogue.pp = 0;
    }
    return 0;
}

/* ---- tests -------------------------------------------------------------- */

static void test_roundtrip_byte_exact(void **state)
{
    (void)state;
    hal_link_t *a = open_robot(0, ROBOT_A), *b = open_robot(1, ROBOT_B);
    wait_all_matched(2, 0);
    const uint16_t counts[] = {0, 1, 7, LT_MAX_LANDMARKS};
    const size_t trailers[] = {0, 1, HAL_LINK_AUTH_TRAILER_BYTES, HAL_LINK_DDS_TRAILER_MAX};
    uint32_t sent = 0;
    for (size_t ci = 0; ci < 4; ++ci) {
        for (size_t ti = 0; ti < 4; ++ti) {
            for (int bc = 0; bc < 2; ++bc) {
                const uint64_t seed = 1000u + ci * 100u + ti * 10u + (uint64_t)bc;
                const size_t L = lt_encode(g_msg, (uint8_t)ROBOT_A, bc ? MAP_MSG_BROADCAST : (uint8_t)ROBOT_B,
                                           counts[ci], seed);
                assert_true(L > 0u);
                for (size_t k = 0; k < trailers[ti]; ++k) g_msg[L + k] = (uint8_t)(seed * 7u + k * 13u);
                const size_t len = L + trailers[ti];
                assert_int_equal(hal_link_send(a, bc ? HAL_LINK_BROADCAST : ROBOT_B, g_msg, len, 0), HAL_OK);
                sent++;
                hal_link_rx_info_t info;
                assert_int_equal(hal_link_recv(b, g_rx, sizeof g_rx, &info, WAIT_US), HAL_OK);
                assert_int_equal(info.len, len);
                assert_int_equal(info.src_id, ROBOT_A);
                assert_memory_equal(g_rx, g_msg, len);
            }
        }
    }
    assert_int_equal(ctr(0)->sent, sent);
    assert_int_equal(ctr(1)->delivered, sent);
    assert_int_equal(ctr(1)->rx_invalid + ctr(1)->rx_other_dest + ctr(1)->rx_own_id, 0);
    hal_link_rx_info_t info;
    assert_int_equal(hal_link_recv(a, g_rx, sizeof g_rx, &info, 50000), HAL_E_TIMEOUT); /* never its own */
}

static void test_send_refusals_counted(void **state)
{
    (void)state;
    hal_link_t *a = open_robot(0, ROBOT_A), *b = open_robot(1, ROBOT_B);
    wait_all_matched(2, 0);
    uint8_t junk[300];
    memset(junk, 0x5A, sizeof junk);
    assert_int_equal(hal_link_send(a, ROBOT_B, junk, sizeof junk, 0), HAL_E_ARG);
    size_t L = lt_encode(g_msg, (uint8_t)ROBOT_A, (uint8_t)ROBOT_B, 3, 77);
    g_msg[150] ^= 1u; /* in a landmark: the CRC no longer matches */
    assert_int_equal(hal_link_send(a, ROBOT_B, g_msg, L, 0), HAL_E_ARG);
    L = lt_encode(g_msg, (uint8_t)ROBOT_A, (uint8_t)ROBOT_B, 3, 77);
    assert_int_equal(hal_link_send(a, ROBOT_B, g_msg, L + HAL_LINK_DDS_TRAILER_MAX + 1u, 0), HAL_E_ARG);
    assert_int_equal(hal_link_send(a, ROBOT_A, g_msg, L, 0), HAL_E_ARG); /* to itself */
    assert_int_equal(ctr(0)->send_not_map, 2);
    assert_int_equal(ctr(0)->send_trailer_too_long, 1);
    assert_int_equal(ctr(0)->sent, 0);
    hal_link_rx_info_t info;
    assert_int_equal(hal_link_recv(b, g_rx, sizeof g_rx, &info, 100000), HAL_E_TIMEOUT);
    assert_int_equal(ctr(1)->delivered, 0);
    /* a short receive buffer: truncated copy, full length, discarded */
    assert_int_equal(hal_link_send(a, ROBOT_B, g_msg, L, 0), HAL_OK);
    uint8_t small[20];
    assert_int_equal(hal_link_recv(b, small, sizeof small, &info, WAIT_US), HAL_E_OVERFLOW);
    assert_int_equal(info.len, L);
    assert_memory_equal(small, g_msg, sizeof small);
    assert_int_equal(ctr(1)->rx_overflow, 1);
    assert_int_equal(hal_link_recv(b, g_rx, sizeof g_rx, &info, 50000), HAL_E_TIMEOUT);
}

static void test_unicast_filtered(void **state)
{
    (void)state;
    hal_link_t *a = open_robot(0, ROBOT_A), *b = open_robot(1, ROBOT_B), *c = open_robot(2, ROBOT_C);
    wait_all_matched(3, 0);
    const size_t L = lt_encode(g_msg, (uint8_t)ROBOT_A, (uint8_t)ROBOT_C, 2, 78);
    assert_int_equal(hal_link_send(a, ROBOT_C, g_msg, L, 0), HAL_OK);
    hal_link_rx_info_t info;
    assert_int_equal(hal_link_recv(c, g_rx, sizeof g_rx, &info, WAIT_US), HAL_OK);
    assert_memory_equal(g_rx, g_msg, L);
    assert_int_equal(hal_link_recv(b, g_rx, sizeof g_rx, &info, 100000), HAL_E_TIMEOUT);
    assert_int_equal(ctr(1)->rx_other_dest, 1);
    assert_int_equal(ctr(1)->delivered, 0);
}

static void test_rogue_samples_refused(void **state)
{
    (void)state;
    hal_link_t *b = open_robot(1, ROBOT_B);
    rogue_open(&g_rogue);
    assert_int_equal(hal_link_dds_wait_matched(&g_dds[1], 1, WAIT_US), HAL_OK);
    coslam_msgs_msg_dds__MapMessage_ *s = &g_rogue.sample;
    sample_of(s, 5, ROBOT_B, 3, 90);
    s->pose_x = NAN;
    rogue_write(&g_rogue);
    sample_of(s, 5, ROBOT_B, 3, 91);
    s->n_landmarks = COSLAM_MAX_MSG_LANDMARKS + 1u;
    rogue_write(&g_rogue);
    sample_of(s, 5, ROBOT_B, 3, 92);
    s->trailer_len = HAL_LINK_DDS_TRAILER_MAX + 1u;
    rogue_write(&g_rogue);
    sample_of(s, 5, ROBOT_B, 3, 93);
    s->pose_cov[1] = 1e3; /* not positive definite */
    rogue_write(&g_rogue);
    sample_of(s, ROBOT_B, ROBOT_B, 3, 94); /* claims to be the receiver */
    rogue_write(&g_rogue);
    /* and a well-formed one: a bare DDS link delivers it (why hal_link_auth exists) */
    sample_of(s, 5, ROBOT_B, 3, 95);
    rogue_write(&g_rogue);
    hal_link_rx_info_t info;
    assert_int_equal(hal_link_recv(b, g_rx, sizeof g_rx, &info, WAIT_US), HAL_OK);
    assert_int_equal(info.src_id, 5);
    const size_t L = lt_encode(g_msg, 5, (uint8_t)ROBOT_B, 3, 95);
    assert_int_equal(info.len, L);
    assert_memory_equal(g_rx, g_msg, L);
    assert_int_equal(ctr(1)->rx_invalid, 4);
    assert_int_equal(ctr(1)->rx_own_id, 1);
    assert_int_equal(ctr(1)->delivered, 1);
}

static uint64_t g_wall_us;
static uint64_t wall(void *ctx)
{
    (void)ctx;
    return g_wall_us;
}

static void test_rogue_against_authenticated_robots(void **state)
{
    (void)state;
    static hal_link_auth_t auth_a, auth_b;
    assert_int_equal(hal_link_auth_key_from_hex("8f3a6b1c2d4e5f60718293a4b5c6d7e8f90a1b2c3d4e5f6071829304a5b6c7d8", g_key),
                     HAL_OK);
    hal_link_auth_config_t ac;
    memset(&ac, 0, sizeof ac);
    memcpy(ac.key, g_key, sizeof g_key);
    ac.key_id = KEY_ID;
    ac.wall_clock_us = wall;
    g_wall_us = 1700000000000000u;
    hal_link_t *a = hal_link_auth_open(open_robot(0, ROBOT_A), &ac, &auth_a);
    hal_link_t *b = hal_link_auth_open(open_robot(1, ROBOT_B), &ac, &auth_b);
    assert_non_null(a);
    assert_non_null(b);
    rogue_open(&g_rogue);
    wait_all_matched(2, 1);
    const hal_link_auth_counters_t *cb = hal_link_auth_counters(&auth_b);
    hal_link_rx_info_t info;

    /* three genuine messages A -> B, overheard by the rogue */
    for (int k = 0; k < 3; ++k) {
        const size_t L = lt_encode(g_msg, (uint8_t)ROBOT_A, (uint8_t)ROBOT_B, (uint16_t)(2 + k), 200u + (uint64_t)k);
        g_wall_us += 1000u;
        assert_int_equal(hal_link_send(a, ROBOT_B, g_msg, L, 0), HAL_OK);
        assert_int_equal(hal_link_recv(b, g_rx, sizeof g_rx, &info, WAIT_US), HAL_OK);
        assert_int_equal(info.len, L);
        assert_memory_equal(g_rx, g_msg, L);
    }
    coslam_msgs_msg_dds__MapMessage_ captured[3];
    for (int k = 0; k < 3; ++k) {
        rogue_capture(&g_rogue);
        captured[k] = g_rogue.sample;
        assert_int_equal(captured[k].trailer_len, HAL_LINK_AUTH_TRAILER_BYTES);
    }
    coslam_msgs_msg_dds__MapMessage_ *s = &g_rogue.sample;
    /* replays: the newest verbatim, and an older one */
    *s = captured[2];
    rogue_write(&g_rogue);
    *s = captured[0];
    rogue_write(&g_rogue);
    /* modified: a field of the map changed, trailer kept */
    *s = captured[2];
    s->pose_x += 1.0;
    rogue_write(&g_rogue);
    /* truncated trailer, and no trailer */
    *s = captured[2];
    s->trailer_len = 30;
    rogue_write(&g_rogue);
    *s = captured[2];
    s->trailer_len = 0;
    rogue_write(&g_rogue);
    /* re-addressed: a genuine sample with another link sender */
    *s = captured[2];
    s->link_src = ROBOT_C;
    rogue_write(&g_rogue);
    /* forged: a fresh message under another key, and under the fleet's key id */
    {
        uint8_t other[HAL_LINK_AUTH_KEY_BYTES];
        memset(other, 0x42, sizeof other);
        sample_of(s, ROBOT_A, ROBOT_B, 4, 300);
        uint8_t dg[HAL_LINK_DDS_MAX_DATAGRAM];
        const size_t L = lt_encode(dg, (uint8_t)ROBOT_A, (uint8_t)ROBOT_B, 4, 300);
        lt_sign(dg, dg, L, other, KEY_ID, ROBOT_A, g_wall_us + 5000u, g_wall_us);
        s->trailer_len = HAL_LINK_AUTH_TRAILER_BYTES;
        memcpy(s->trailer, dg + L, HAL_LINK_AUTH_TRAILER_BYTES);
        rogue_write(&g_rogue);
    }
    /* a genuine robot goes on talking */
    const size_t L = lt_encode(g_msg, (uint8_t)ROBOT_A, (uint8_t)ROBOT_B, 5, 400);
    g_wall_us += 1000u;
    assert_int_equal(hal_link_send(a, ROBOT_B, g_msg, L, 0), HAL_OK);
    assert_int_equal(hal_link_recv(b, g_rx, sizeof g_rx, &info, WAIT_US), HAL_OK);
    assert_int_equal(info.src_id, ROBOT_A);
    assert_int_equal(info.len, L);
    assert_memory_equal(g_rx, g_msg, L);
    assert_int_equal(hal_link_recv(b, g_rx, sizeof g_rx, &info, 100000), HAL_E_TIMEOUT);

    assert_int_equal(cb->delivered, 4);
    assert_int_equal(cb->rx_replay, 2);
    assert_int_equal(cb->rx_bad_mac, 2); /* modified, forged */
    assert_int_equal(cb->rx_truncated, 1);
    assert_int_equal(cb->rx_unauthenticated, 1);
    assert_int_equal(cb->rx_sender_mismatch, 1);
    assert_int_equal(cb->rx_malformed + cb->rx_wrong_key + cb->rx_stale + cb->rx_future + cb->rx_oversize, 0);
    assert_int_equal(ctr(1)->delivered, 11); /* the DDS layer passed all of them up */
    hal_link_close(a);                       /* closes the DDS links too */
    hal_link_close(b);
}

static void test_open_arguments(void **state)
{
    (void)state;
    hal_link_dds_config_t c;
    memset(&c, 0, sizeof c);
    c.domain_id = DOMAIN;
    c.self_id = HAL_LINK_BROADCAST;
    assert_int_equal(hal_link_dds_open(&g_dds[0], &c), HAL_E_ARG);
    c.self_id = 1;
    c.domain_id = 233;
    assert_int_equal(hal_link_dds_open(&g_dds[0], &c), HAL_E_ARG);
    c.domain_id = DOMAIN;
    const char *bad_peers[] = {"127.0.0.1\"/><Evil", NULL};
    c.peers = bad_peers;
    assert_int_equal(hal_link_dds_open(&g_dds[0], &c), HAL_E_ARG);
    /* the domain is open with another configuration in this process */
    c.peers = NULL;
    c.config = LT_DDS_LOOPBACK_XML;
    c.partition = g_partition;
    assert_int_equal(hal_link_dds_open(&g_dds[0], &c), HAL_OK);
    c.config = "<CycloneDDS><Domain id=\"any\"/></CycloneDDS>";
    c.self_id = 2;
    assert_int_equal(hal_link_dds_open(&g_dds[1], &c), HAL_E_BUSY);
    hal_link_close(&g_dds[0].link);
    uint16_t id;
    assert_int_equal(hal_link_self_id(&g_dds[0].link, &id), HAL_E_CLOSED);
}

int main(void)
{
    unsetenv("CYCLONEDDS_URI"); /* hermetic: only the test's configuration */
    lt_partition(g_partition, sizeof g_partition, "dds", (long)getpid());
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_roundtrip_byte_exact, teardown_links),
        cmocka_unit_test_teardown(test_send_refusals_counted, teardown_links),
        cmocka_unit_test_teardown(test_unicast_filtered, teardown_links),
        cmocka_unit_test_teardown(test_rogue_samples_refused, teardown_links),
        cmocka_unit_test_teardown(test_rogue_against_authenticated_robots, teardown_links),
        cmocka_unit_test_teardown(test_open_arguments, teardown_links),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
