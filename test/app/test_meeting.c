/*
 * The meeting protocol (firmware/app meeting.h) against a fake link that
 * records every datagram sent and delivers injected ones: the send policy
 * (resend period, budget, range limit, meeting gap, budget renewal and the
 * implicit acknowledgement), the message's fields byte-exactly through the
 * codec, the merge geometry (exact sightings give the exact relative pose,
 * and the merged landmark lands where geometry says), odometry
 * compensation, pairing with the nearest own sighting, the stale window,
 * replays, screening (not for me, broadcast, corrupt bytes not clobbering
 * a pending message) and the event queue's overflow counter.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "app/meeting.h"

/* ---- fake link ---------------------------------------------------------- */

#define FAKE_MAX_DGRAMS 16

typedef struct {
    uint16_t peer;     /* destination (sent) or source (to receive) */
    uint64_t stamp_us; /* arrival stamp (to receive) */
    size_t len;
    uint8_t data[MAP_MSG_MAX_BYTES];
} fake_dgram_t;

typedef struct {
    hal_link_t handle;
    uint16_t self;
    fake_dgram_t sent[FAKE_MAX_DGRAMS];
    int n_sent;
    fake_dgram_t rx[FAKE_MAX_DGRAMS];
    int rx_head, rx_n;
    hal_status_t send_result;
} fake_link_t;

static hal_status_t fake_send(hal_link_t *dev, uint16_t dest, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    (void)timeout_us;
    fake_link_t *f = (fake_link_t *)dev->backend;
    if (f->send_result != HAL_OK) return f->send_result;
    assert_true(f->n_sent < FAKE_MAX_DGRAMS);
    fake_dgram_t *d = &f->sent[f->n_sent++];
    d->peer = dest;
    d->len = len;
    memcpy(d->data, data, len);
    return HAL_OK;
}

static hal_status_t fake_recv(hal_link_t *dev, uint8_t *buf, size_t cap, hal_link_rx_info_t *info, uint32_t timeout_us)
{
    (void)timeout_us;
    fake_link_t *f = (fake_link_t *)dev->backend;
    if (f->rx_n == 0) return HAL_E_TIMEOUT;
    const fake_dgram_t *d = &f->rx[f->rx_head];
    f->rx_head = (f->rx_head + 1) % FAKE_MAX_DGRAMS;
    f->rx_n--;
    info->len = d->len;
    info->src_id = d->peer;
    info->stamp_us = d->stamp_us;
    memcpy(buf, d->data, d->len < cap ? d->len : cap);
    return d->len <= cap ? HAL_OK : HAL_E_OVERFLOW;
}

static const hal_link_ops_t fake_ops = {NULL, fake_send, fake_recv, NULL};

static fake_link_t g_link;

static hal_link_t *fake_link_reset(uint16_t self)
{
    memset(&g_link, 0, sizeof g_link);
    g_link.handle.ops = &fake_ops;
    g_link.handle.backend = &g_link;
    g_link.self = self;
    g_link.send_result = HAL_OK;
    return &g_link.handle;
}

static void inject(const uint8_t *data, size_t len, uint16_t src, uint64_t stamp_us)
{
    assert_true(g_link.rx_n < FAKE_MAX_DGRAMS);
    fake_dgram_t *d = &g_link.rx[(g_link.rx_head + g_link.rx_n) % FAKE_MAX_DGRAMS];
    g_link.rx_n++;
    d->peer = src;
    d->stamp_us = stamp_us;
    d->len = len;
    memcpy(d->data, data, len);
}

/* ---- fixtures ---------------------------------------------------------------- */

static meeting_t g_m;
static slam_filter_t g_filter;
static map_msg_t g_msg;
static map_estimate_t g_est;
static uint8_t g_buf[MAP_MSG_MAX_BYTES];

static const pose2_t kOrigin = {0.0, 0.0, 0.0};

static void setup_robot0(meeting_config_t *cfg_out)
{
    slam_filter_config_t fc = slam_filter_config_default();
    fc.kind = SLAM_FILTER_EKF;
    fc.robot_id = 0;
    assert_int_equal(slam_filter_init(&g_filter, &fc, kOrigin), COSLAM_OK);
    meeting_config_t c = meeting_config_default();
    if (cfg_out) c = *cfg_out;
    /* the messages below carry near-exact sightings (1e-8 m^2, 1e-10 rad^2),
     * below the default plausibility floors (test_implausible_refused) */
    c.merge.min_var_m2 = 1e-9;
    c.merge.min_bearing_var_rad2 = 1e-11;
    assert_int_equal(meeting_init(&g_m, &c, 0, 2), COSLAM_OK);
}

/* A message from robot 1 to robot 0: robot 1 stands at `pose1` of its own
 * map frame, has one landmark at `lm_rel` relative to itself (src bit
 * `src_mask`), and saw robot 0 at (range, bearing) at sight_us. */
static size_t make_msg_from1(uint32_t seq, uint64_t stamp_us, uint64_t sight_us, double range, double bearing,
                             point2_t lm_rel, uint16_t src_mask, uint8_t receiver)
{
    map_msg_init(&g_msg);
    g_msg.sender_id = 1;
    g_msg.receiver_id = receiver;
    g_msg.seq = seq;
    g_msg.stamp_us = stamp_us;
    const pose2_t pose1 = {5.0, -3.0, 1.0}; /* arbitrary: the receiver must not need it */
    g_msg.map.pose = pose1;
    g_msg.map.pose_cov = cov3_diag(0.01, 0.01, 0.001);
    g_msg.map.n_landmarks = 1;
    map_landmark_t *l = &g_msg.map.lm[0];
    l->mean = pose2_apply(pose1, lm_rel);
    l->cov = cov2_make(0.02, 0.0, 0.02);
    l->cov_rel = cov2_make(0.001, 0.0, 0.001);
    l->id = 7;
    l->n_obs = 12;
    l->src_mask = src_mask;
    l->signature = 2;
    if (receiver != MAP_MSG_BROADCAST) {
        g_msg.sighting.valid = true;
        g_msg.sighting.range_m = range;
        g_msg.sighting.bearing_rad = bearing;
        g_msg.sighting.range_var_m2 = 1e-8;
        g_msg.sighting.bearing_var_rad2 = 1e-10;
        g_msg.sighting.stamp_us = sight_us;
    }
    size_t len = 0;
    assert_int_equal(map_msg_encode(&g_msg, g_buf, sizeof g_buf, &len), COSLAM_OK);
    return len;
}

/* Exact mutual sightings of two robots at world poses a (self) and b (other). */
static void mutual(pose2_t a, pose2_t b, double *r, double *b_in_a, double *a_in_b)
{
    const point2_t pb = pose2_apply_inverse(a, (point2_t){b.x, b.y});
    const point2_t pa = pose2_apply_inverse(b, (point2_t){a.x, a.y});
    *r = hypot(pb.x, pb.y);
    *b_in_a = atan2(pb.y, pb.x);
    *a_in_b = atan2(pa.y, pa.x);
}

static int count_events(meeting_event_kind_t kind, coslam_status_t status, meeting_event_t *last)
{
    int n = 0;
    meeting_event_t ev = {0};
    while (meeting_take_event(&g_m, &ev) == COSLAM_OK) {
        if (ev.kind == kind && ev.status == status) {
            n++;
            if (last) *last = ev;
        }
    }
    return n;
}

/* Robot 0 at the origin and robot 1 at kMeetB see each other at kMeetT;
 * robot 1's message (one landmark at kMeetLm relative to itself) is taken
 * from the link. */
static const pose2_t kMeetB = {2.0, 0.5, 160.0 * COSLAM_PI / 180.0};
static const point2_t kMeetLm = {1.5, -0.7};
static const uint64_t kMeetT = 20000000;

static void meet_robot1(hal_link_t *link)
{
    const pose2_t a = {0.0, 0.0, 0.0};
    double r, b1, b2;
    mutual(a, kMeetB, &r, &b1, &b2);
    const uint64_t t = kMeetT;
    meeting_on_sighting(&g_m, &g_filter, link, t + 4000, 1, r, b1, t, kOrigin, 0.0);
    const size_t len = make_msg_from1(1, t + 3000, t, r, b2, kMeetLm, 1U << 1, 0);
    inject(g_buf, len, 1, t + 3000 + g_m.cfg.link_latency_us);
    assert_int_equal(meeting_poll_link(&g_m, link), 1);
}

/* Robot 1's landmark is in robot 0's map, where it is in the world. */
static void assert_robot1_landmark_merged(void)
{
    assert_int_equal(slam_filter_export(&g_filter, &g_est), COSLAM_OK);
    assert_int_equal(g_est.n_landmarks, 1);
    const point2_t want = pose2_apply(kMeetB, kMeetLm);
    assert_true(fabs(g_est.lm[0].mean.x - want.x) < 1e-6);
    assert_true(fabs(g_est.lm[0].mean.y - want.y) < 1e-6);
}

/* Robot 0 with Fast-SLAM 2.0 (8 particles) and a merge budget of one unit:
 * every export and merge goes in parts. Its filter configuration. */
static slam_filter_config_t setup_robot0_fastslam_in_parts(void)
{
    meeting_config_t mc = meeting_config_default();
    mc.merge.step_units = 1U;
    setup_robot0(&mc);
    slam_filter_config_t fc = slam_filter_config_default();
    fc.kind = SLAM_FILTER_FASTSLAM2;
    fc.n_particles = 8;
    return fc;
}

/* Robot 0 (Fast-SLAM in parts, starting exactly at the origin) meets robot
 * 1 (meet_robot1). Its filter configuration. */
static slam_filter_config_t meet_robot1_in_parts(hal_link_t *link)
{
    slam_filter_config_t fc = setup_robot0_fastslam_in_parts();
    fc.slam.noise.init_xy_var_m2 = 0.0;
    fc.slam.noise.init_theta_var_rad2 = 0.0;
    assert_int_equal(slam_filter_init(&g_filter, &fc, kOrigin), COSLAM_OK);
    meet_robot1(link);
    return fc;
}

/* ---- tests -------------------------------------------------------------------- */

static void test_send_policy_and_message_fields(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    const uint64_t t0 = 10000000;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t0 + 3000, 1, 2.0, 0.25, t0, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_link.n_sent, 1);
    assert_int_equal(g_link.sent[0].peer, 1);
    map_msg_t got;
    assert_int_equal(map_msg_decode(g_link.sent[0].data, g_link.sent[0].len, &got), COSLAM_OK);
    assert_int_equal(got.sender_id, 0);
    assert_int_equal(got.receiver_id, 1);
    assert_int_equal(got.seq, 1);
    assert_int_equal(got.stamp_us, t0 + 3000);           /* export time */
    assert_true(got.sighting.valid);
    assert_int_equal(got.sighting.stamp_us, t0);          /* the frame's capture time */
    assert_true(got.sighting.range_m == 2.0);
    assert_true(got.sighting.bearing_rad == 0.25);
    assert_true(got.sighting.range_var_m2 == g_m.cfg.robot_range_var_m2);
    assert_true(got.sighting.bearing_var_rad2 == g_m.cfg.robot_bearing_var_rad2);
    /* not again within the resend period, then every period, at most max_sends */
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t0 + 500000, 1, 2.0, 0.25, t0 + 500000, kOrigin, 0.0),
                     COSLAM_OK);
    assert_int_equal(g_link.n_sent, 1);
    for (int i = 1; i <= 4; ++i) {
        const uint64_t t = t0 + (uint64_t)i * 1000000U + 3000U;
        assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.25, t - 3000U, kOrigin, 0.0),
                         COSLAM_OK);
    }
    assert_int_equal(g_link.n_sent, 3);
    assert_int_equal(g_m.ctr.sent, 3);
    /* out of view longer than the meeting gap: a new meeting, a new message */
    const uint64_t t2 = t0 + 4000000U + g_m.cfg.meeting_gap_us + 1000U;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t2, 1, 2.0, 0.25, t2, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_link.n_sent, 4);
    assert_int_equal(map_msg_decode(g_link.sent[3].data, g_link.sent[3].len, &got), COSLAM_OK);
    assert_int_equal(got.seq, 4);
    assert_int_equal(count_events(MEETING_EV_SENT, COSLAM_OK, NULL), 4);
}

static void test_sighting_checks_and_range_limit(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    /* beyond max_range_m: ignored, nothing recorded */
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, 1000, 1, 3.5, 0.0, 1000, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_link.n_sent, 0);
    meeting_sighting_t s;
    assert_int_equal(meeting_last_sighting(&g_m, 1, &s), COSLAM_E_EMPTY);
    /* bad input */
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, 1000, 0, 1.0, 0.0, 1000, kOrigin, 0.0), COSLAM_E_ARG);
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, 1000, 2, 1.0, 0.0, 1000, kOrigin, 0.0), COSLAM_E_ARG);
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, 1000, 1, NAN, 0.0, 1000, kOrigin, 0.0), COSLAM_E_ARG);
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, 1000, 1, 0.0, 0.0, 1000, kOrigin, 0.0), COSLAM_E_ARG);
    /* a link refusal is reported and counted, and uses up the slot */
    g_link.send_result = HAL_E_BUSY;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, 1000, 1, 1.0, 0.0, 1000, kOrigin, 0.0), COSLAM_E_LINK);
    assert_int_equal(g_m.ctr.send_failures, 1);
    assert_int_equal(meeting_last_sighting(&g_m, 1, &s), COSLAM_OK);
    assert_true(s.range_m == 1.0);
    /* config checks */
    meeting_config_t c = meeting_config_default();
    c.robot_range_var_m2 = 0.0;
    assert_int_equal(meeting_init(&g_m, &c, 0, 2), COSLAM_E_ARG);
    c = meeting_config_default();
    assert_int_equal(meeting_init(&g_m, &c, 2, 2), COSLAM_E_ARG);
    assert_int_equal(meeting_init(&g_m, &c, 0, 1), COSLAM_E_ARG);
    c.max_range_m = 0.0;
    assert_int_equal(meeting_init(&g_m, &c, 0, 2), COSLAM_E_ARG);
    /* a sighting variance its partners would refuse as implausible */
    c = meeting_config_default();
    c.robot_bearing_var_rad2 = 1.01 * c.merge.max_bearing_var_rad2;
    assert_int_equal(meeting_init(&g_m, &c, 0, 2), COSLAM_E_ARG);
    c.robot_bearing_var_rad2 = c.merge.max_bearing_var_rad2;
    assert_int_equal(meeting_init(&g_m, &c, 0, 2), COSLAM_OK);
}

static void test_budget_renewed_then_implicit_ack(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    uint64_t t = 1000000;
    for (int i = 0; i < 5; ++i, t += 1000000) {
        meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    }
    assert_int_equal(g_link.n_sent, 3);
    /* robot 1 sends its map without our provenance bit: it sees us and still
     * needs our map -> the budget is renewed */
    size_t len = make_msg_from1(1, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 2000);
    assert_int_equal(meeting_poll_link(&g_m, link), 1);
    assert_false(meeting_acked_all(&g_m));
    t += 100000;
    meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    assert_int_equal(g_link.n_sent, 4);
    /* (its map, now paired with that sighting, would be merged next, and
     * the link is not read while a message ready to merge waits: dropped
     * here, a merge would owe robot 1 an acknowledgement) */
    g_m.have_pending = 0U;
    /* now a message showing our bit: robot 1 has merged our map -> stop */
    t += 1000000;
    len = make_msg_from1(2, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, (1U << 1) | 1U, 0);
    inject(g_buf, len, 1, t + 2000);
    meeting_poll_link(&g_m, link);
    assert_true(meeting_acked_all(&g_m));
    for (int i = 0; i < 3; ++i) {
        t += 1000000;
        meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    }
    assert_int_equal(g_link.n_sent, 4);
}

/* Two robots that refuse each other's maps keep renewing each other's send
 * budget (each message lacks the other's bit); the resend period still
 * holds: 30 camera frames 100 ms apart, a message from robot 1 after each,
 * give one send a second (3), not one a frame (30, as before). */
static void test_renewed_budget_keeps_the_resend_period(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    uint64_t t = 1000000;
    for (uint32_t k = 0; k < 30; ++k, t += 100000) {
        meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
        const size_t len = make_msg_from1(k + 1U, t + 40000, t + 40000, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
        inject(g_buf, len, 1, t + 50000);
        (void)meeting_poll_link(&g_m, link);
        g_m.have_pending = 0U; /* (its merge is not the point here) */
        meeting_event_t ev;
        while (meeting_take_event(&g_m, &ev) == COSLAM_OK) {
        }
    }
    assert_int_equal(g_link.n_sent, 3);
}

/* A replayed old message changes nothing but the replay counter: robot 1's
 * seq 5 (holding our bit) replayed in a later meeting does not acknowledge
 * our map, so our sends go on; a message refused as stale does not count
 * as replacing the pending one. */
static void test_replay_neither_acks_nor_replaces(void **state)
{
    (void)state;
    static uint8_t old[MAP_MSG_MAX_BYTES];
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    uint64_t t = 1000000;
    size_t len = make_msg_from1(5, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, (1U << 1) | 1U, 0);
    memcpy(old, g_buf, len);
    const size_t old_len = len;
    inject(g_buf, len, 1, t + 2000);
    (void)meeting_poll_link(&g_m, link);
    len = make_msg_from1(6, t + 1000, t + 1000, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 3000);
    (void)meeting_poll_link(&g_m, link);
    g_m.have_pending = 0U;
    t += 100000000; /* a later meeting, past meeting_gap_us and remerge_period_us */
    meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    assert_int_equal(g_link.n_sent, 1);
    g_m.peer[1].sent_n_landmarks = 0; /* (the fixture's map is empty: any bit would acknowledge) */
    const uint32_t replays0 = g_m.ctr.replays;
    inject(old, old_len, 1, t + 10000);
    (void)meeting_poll_link(&g_m, link);
    assert_int_equal(g_m.ctr.replays, replays0 + 1U);
    assert_true(g_m.peer[1].acked_at_us < g_m.peer[1].meeting_start_us); /* not acknowledged */
    for (uint64_t i = 1; i <= 4; ++i) {
        const uint64_t ti = t + i * 1100000U;
        meeting_on_sighting(&g_m, &g_filter, link, ti, 1, 2.0, 0.0, ti, kOrigin, 0.0);
    }
    assert_int_equal(g_link.n_sent, 3); /* the meeting's budget, as without the replay */

    /* pending seq 7; seq 8 claims a sighting 1000 s old: stale, not a replacement */
    t += 100000000;
    len = make_msg_from1(7, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 2000);
    (void)meeting_poll_link(&g_m, link);
    assert_true(g_m.have_pending);
    const uint32_t replaced0 = g_m.ctr.pending_replaced; /* 1: seq 6 replaced seq 5 */
    assert_int_equal(replaced0, 1U);
    len = make_msg_from1(8, t + 1000000000ULL, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 5000);
    (void)meeting_poll_link(&g_m, link);
    assert_int_equal(g_m.ctr.stale, 1U);
    assert_int_equal(g_m.rx.seq, 7U);
    assert_int_equal(g_m.ctr.pending_replaced, replaced0);
}

/* Robot 0 sent its map, then merged robot 1's (in the same step), then
 * learned that robot 1 holds its map: robot 1 cannot know yet that robot 0
 * holds its map, so robot 0 owes it one more message (the acknowledgement)
 * and sends it at the next sighting after the resend period; then nothing
 * more. Before, robot 0 stopped at once and robot 1 waited out its linger. */
static void test_acknowledgement_owed_after_a_merge(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    meet_robot1(link); /* robot 0 sends (t + 4 ms), robot 1's map pending */
    assert_int_equal(g_link.n_sent, 1);
    const uint64_t t = kMeetT;
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 4000, kOrigin, 0.0), COSLAM_OK);
    assert_true(meeting_merged_all(&g_m));
    assert_true(meeting_owes_ack(&g_m));
    /* robot 1's next message holds our bit: it has our map */
    double r, b1, b2;
    mutual((pose2_t){0.0, 0.0, 0.0}, kMeetB, &r, &b1, &b2);
    const size_t len = make_msg_from1(2, t + 500000, t + 500000, r, b2, kMeetLm, (1U << 1) | 1U, 0);
    inject(g_buf, len, 1, t + 502000);
    meeting_poll_link(&g_m, link);
    assert_int_equal(g_m.ctr.ignored_recent, 1U); /* merged lately: not merged again ... */
    inject(g_buf, len, 1, t + 503000);            /* ... and its number is taken: */
    meeting_poll_link(&g_m, link);
    assert_int_equal(g_m.ctr.ignored_recent, 1U); /* the same message again is a replay */
    assert_int_equal(g_m.ctr.replays, 1U);
    g_m.peer[1].sent_n_landmarks = 0; /* (the fixture's own map was empty when sent) */
    assert_true(meeting_acked_all(&g_m));
    meeting_on_sighting(&g_m, &g_filter, link, t + 600000, 1, r, b1, t + 600000, kOrigin, 0.0);
    assert_int_equal(g_link.n_sent, 1); /* the resend period first */
    meeting_on_sighting(&g_m, &g_filter, link, t + 1100000, 1, r, b1, t + 1100000, kOrigin, 0.0);
    assert_int_equal(g_link.n_sent, 2); /* the acknowledgement */
    assert_false(meeting_owes_ack(&g_m));
    for (uint64_t k = 2; k < 6; ++k) {
        meeting_on_sighting(&g_m, &g_filter, link, t + k * 1100000U, 1, r, b1, t + k * 1100000U, kOrigin, 0.0);
    }
    assert_int_equal(g_link.n_sent, 2); /* acknowledged both ways: done */
}

/* Robot 1 restarted without its snapshot and numbers from 1 again, below
 * the 500 robot 0 remembers: its first two messages are replays, the third
 * in a row is taken as a restart (merge_session_t.rebased) and pending. */
static void test_restarted_peer_is_heard_again(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    uint64_t t = 1000000;
    size_t len = make_msg_from1(500, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 2000);
    (void)meeting_poll_link(&g_m, link);
    assert_true(g_m.have_pending);
    g_m.have_pending = 0U;
    t += 100000000;
    for (uint32_t seq = 1; seq <= 3; ++seq, t += 1000000) {
        len = make_msg_from1(seq, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
        inject(g_buf, len, 1, t + 2000);
        (void)meeting_poll_link(&g_m, link);
        assert_int_equal(g_m.have_pending, seq == 3U);
    }
    assert_int_equal(g_m.ctr.replays, 2U);
    assert_int_equal(g_m.session.rebased, 1U);
    assert_int_equal(g_m.rx.seq, 3U);
}

/* Robot 0 at the world origin, robot 1 at (2, 0.5, 160 deg); exact sightings.
 * The relative pose must come out exact, and robot 1's landmark must land in
 * robot 0's map where it is in the world. */
static void test_merge_geometry_exact(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    meet_robot1(link);
    const pose2_t b = kMeetB;
    const point2_t lm_rel = kMeetLm;
    const uint64_t t = kMeetT;
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 10000, kOrigin, 0.0), COSLAM_OK);
    meeting_event_t ev = {0};
    assert_int_equal(count_events(MEETING_EV_MERGED, COSLAM_OK, &ev), 1);
    assert_int_equal(ev.peer, 1);
    assert_int_equal(ev.own_sighting_us, t);
    assert_int_equal(ev.sender_sighting_us, t); /* arrival - latency - (stamp - sighting stamp) */
    assert_true(fabs(ev.other_in_self.x - b.x) < 1e-9);
    assert_true(fabs(ev.other_in_self.y - b.y) < 1e-9);
    assert_true(fabs(angle_wrap(ev.other_in_self.theta - b.theta)) < 1e-9);
    assert_int_equal(ev.stats.added, 1);
    assert_true(meeting_merged_all(&g_m));
    assert_robot1_landmark_merged();
    assert_int_equal(g_est.lm[0].src_mask, 1U << 1);
    assert_int_equal(g_est.lm[0].signature, 2);
    /* the rest of the meeting's messages are ignored (remerge period) */
    double r, b1, b2;
    mutual((pose2_t){0.0, 0.0, 0.0}, b, &r, &b1, &b2);
    const size_t len2 = make_msg_from1(2, t + 1003000, t + 1000000, r, b2, lm_rel, 1U << 1, 0);
    inject(g_buf, len2, 1, t + 1005000);
    meeting_poll_link(&g_m, link);
    assert_int_equal(g_m.ctr.ignored_recent, 1);
    assert_false(g_m.have_pending);
}

/* The own robot drove u = (1, 0.2, 90 deg) after its sighting: the relative
 * pose is moved into the current body frame, u^-1 (+) T. */
static void test_merge_compensates_own_motion(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    const pose2_t a = {0.0, 0.0, 0.0};
    const pose2_t b = {2.5, -0.4, -170.0 * COSLAM_PI / 180.0};
    double r, b1, b2;
    mutual(a, b, &r, &b1, &b2);
    const uint64_t t = 5000000;
    meeting_on_sighting(&g_m, &g_filter, link, t, 1, r, b1, t, kOrigin, 0.0);
    const size_t len = make_msg_from1(1, t, t, r, b2, (point2_t){0.5, 0.5}, 1U << 1, 0);
    inject(g_buf, len, 1, t + g_m.cfg.link_latency_us);
    meeting_poll_link(&g_m, link);
    const pose2_t moved = {1.0, 0.2, 0.5 * COSLAM_PI};
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 150000, moved, 1.3), COSLAM_OK);
    meeting_event_t ev = {0};
    assert_int_equal(count_events(MEETING_EV_MERGED, COSLAM_OK, &ev), 1);
    const pose2_t want = pose2_compose(pose2_inverse(moved), b);
    assert_true(fabs(ev.other_in_self.x - want.x) < 1e-9);
    assert_true(fabs(ev.other_in_self.y - want.y) < 1e-9);
    assert_true(fabs(angle_wrap(ev.other_in_self.theta - want.theta)) < 1e-9);
    /* the odometry covariance entered: 1.3 m of travel */
    assert_true(ev.other_in_self_cov.m[2][2] >= slam_filter_params(&g_filter)->noise.odo_theta_var_rad2_per_m * 1.3 * 0.999);
}

static void test_pairs_nearest_own_sighting(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    const uint64_t t = 8000000;
    meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    meeting_on_sighting(&g_m, &g_filter, link, t + 200000, 1, 2.0, 0.0, t + 200000, kOrigin, 0.0);
    meeting_on_sighting(&g_m, &g_filter, link, t + 400000, 1, 2.0, 0.0, t + 400000, kOrigin, 0.0);
    /* the sender's sighting at t + 190 ms: exported 5 ms later */
    const size_t len = make_msg_from1(1, 777000 + 5000, 777000, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 190000 + 5000 + g_m.cfg.link_latency_us);
    meeting_poll_link(&g_m, link);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 410000, kOrigin, 0.0), COSLAM_OK);
    meeting_event_t ev = {0};
    assert_int_equal(count_events(MEETING_EV_MERGED, COSLAM_OK, &ev), 1);
    assert_int_equal(ev.sender_sighting_us, t + 190000); /* only differences of the sender's clock are used */
    assert_int_equal(ev.own_sighting_us, t + 200000);
}

/* A camera faster than a third of the pairing window (30 Hz here) would
 * shorten the own sighting history to half a second; it is thinned in the
 * middle instead (hist_push), so that it still reaches 1.6 s back (16 x
 * 300 ms / 3) and a message whose sender sighted us 1.1 s ago (its export
 * went in parts) pairs with an own sighting close to that time. At 10 Hz
 * nothing is thinned: the plain ring of the last 16 sightings. */
static void test_history_reaches_back_at_fast_rates(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    const uint64_t t0 = 50000000;
    uint64_t t = t0;
    for (int i = 0; i < 30; ++i, t += 100000) { /* 10 Hz for 3 s */
        meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    }
    assert_int_equal(g_m.ctr.history_thinned, 0);
    assert_int_equal(g_m.peer[1].n_hist, COSLAM_APP_SIGHTING_HISTORY);
    meeting_sighting_t last;
    assert_int_equal(meeting_last_sighting(&g_m, 1, &last), COSLAM_OK);
    assert_int_equal(last.stamp_us, t - 100000);
    /* 30 Hz for 3 s */
    for (int i = 0; i < 90; ++i, t += 33333) {
        meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    }
    const uint64_t now = t - 33333;
    assert_int_equal(meeting_last_sighting(&g_m, 1, &last), COSLAM_OK);
    assert_int_equal(last.stamp_us, now); /* the newest always kept */
    /* the sender's sighting 1.1 s before now */
    const uint64_t t_s = now - 1100000;
    const size_t len = make_msg_from1(1, 2600000, 1500000, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, now + g_m.cfg.link_latency_us);
    meeting_poll_link(&g_m, link);
    assert_int_equal(meeting_poll(&g_m, &g_filter, now + 1000, kOrigin, 0.0), COSLAM_OK);
    meeting_event_t ev = {0};
    assert_int_equal(count_events(MEETING_EV_MERGED, COSLAM_OK, &ev), 1);
    assert_int_equal(ev.sender_sighting_us, t_s);
    const uint64_t dt = ev.own_sighting_us > t_s ? ev.own_sighting_us - t_s : t_s - ev.own_sighting_us;
    print_message("history at 30 Hz: paired 1.1 s back with an own sighting %.1f ms away; %u thinned\n",
                  (double)dt / 1000.0, (unsigned)g_m.ctr.history_thinned);
    assert_true(dt <= 60000U);
    assert_int_equal(g_m.ctr.stale, 0);
    assert_true(g_m.ctr.history_thinned > 50U);
}

/* A message whose sighting claims an age beyond the receiver's clock (a
 * stamp near 2^64: arrival - latency - age would wrap and land the sighting
 * at the arrival) is refused as stale at once, though an own sighting of
 * the sender was made at the arrival. */
static void test_absurd_age_is_stale(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    const uint64_t t = 20000000;
    const pose2_t a = {0.0, 0.0, 0.0};
    double r, b1, b2;
    mutual(a, kMeetB, &r, &b1, &b2);
    meeting_on_sighting(&g_m, &g_filter, link, t + 4000, 1, r, b1, t, kOrigin, 0.0);
    const size_t len = make_msg_from1(1, UINT64_MAX - 999U, 0U, r, b2, kMeetLm, 1U << 1, 0);
    inject(g_buf, len, 1, t + 3000 + g_m.cfg.link_latency_us);
    meeting_poll_link(&g_m, link);
    assert_false(g_m.have_pending);
    assert_int_equal(g_m.ctr.stale, 1);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 6000, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_m.ctr.merged, 0);
    assert_int_equal(count_events(MEETING_EV_REFUSED, COSLAM_E_MERGE_STALE, NULL), 1);
}

static void test_waits_then_stale(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    const uint64_t t = 30000000;
    const size_t len = make_msg_from1(1, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + g_m.cfg.link_latency_us);
    meeting_poll_link(&g_m, link);
    assert_true(g_m.have_pending);
    /* no own sighting yet: it waits while one may still come */
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 100000, kOrigin, 0.0), COSLAM_E_EMPTY);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + g_m.cfg.pair_window_us, kOrigin, 0.0), COSLAM_E_EMPTY);
    /* an own sighting too late for the window does not help; then stale */
    meeting_on_sighting(&g_m, &g_filter, link, t + 400000, 1, 2.0, 0.0, t + 400000, kOrigin, 0.0);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 400000, kOrigin, 0.0), COSLAM_E_MERGE_STALE);
    assert_false(g_m.have_pending);
    assert_int_equal(g_m.ctr.stale, 1);
    meeting_event_t ev = {0};
    assert_int_equal(count_events(MEETING_EV_REFUSED, COSLAM_E_MERGE_STALE, &ev), 1);
    assert_int_equal(ev.peer, 1);
    assert_false(meeting_merged_all(&g_m));
    /* a second message within the window of that sighting merges */
    const size_t len2 = make_msg_from1(2, t + 450000, t + 450000, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len2, 1, t + 450000 + g_m.cfg.link_latency_us);
    meeting_poll_link(&g_m, link);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 460000, kOrigin, 0.0), COSLAM_OK);
    assert_true(meeting_merged_all(&g_m));
}

static void test_replay_refused(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    meeting_config_t c = meeting_config_default();
    c.remerge_period_us = 0; /* so that the replay reaches the session check */
    setup_robot0(&c);
    const uint64_t t = 1000000;
    meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    const size_t len = make_msg_from1(5, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 2000);
    inject(g_buf, len, 1, t + 4000);
    /* the first is ready to merge: the duplicate stays in the link until it is */
    assert_int_equal(meeting_poll_link(&g_m, link), 1);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 5000, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(meeting_poll_link(&g_m, link), 1);
    assert_int_equal(g_m.ctr.replays, 1);
    meeting_event_t ev = {0};
    assert_int_equal(count_events(MEETING_EV_REFUSED, COSLAM_E_MERGE_REPLAY, &ev), 1);
    assert_int_equal(ev.seq, 5);
    assert_int_equal(g_m.ctr.merged, 1);
    /* the same message replayed after the merge: refused, the map unchanged */
    static map_estimate_t before;
    static map_estimate_t after;
    assert_int_equal(slam_filter_export(&g_filter, &before), COSLAM_OK);
    assert_true(before.n_landmarks >= 1);
    meeting_on_sighting(&g_m, &g_filter, link, t + 900000, 1, 2.0, 0.0, t + 900000, kOrigin, 0.0);
    inject(g_buf, len, 1, t + 1000000);
    meeting_poll_link(&g_m, link);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 1001000, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_m.ctr.replays, 2);
    assert_int_equal(g_m.ctr.merged, 1);
    assert_int_equal(slam_filter_export(&g_filter, &after), COSLAM_OK);
    assert_int_equal(after.n_landmarks, before.n_landmarks);
    assert_memory_equal(after.lm, before.lm, sizeof before.lm[0] * before.n_landmarks);
}

/* Finite but absurd numbers (a landmark 1e6 m away, a covariance of 1e-20
 * m^2, a sighting variance of 1e-300) pass the codec and are refused before
 * the merge: counted, the map unchanged. A message whose claimed sender is
 * not the link's sender is refused before anything else. */
static void test_implausible_refused(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    meeting_config_t c = meeting_config_default();
    c.remerge_period_us = 0;
    setup_robot0(&c);
    g_m.cfg.merge.min_var_m2 = merge_config_default().min_var_m2; /* the defaults, not the fixture's */
    g_m.cfg.merge.min_bearing_var_rad2 = merge_config_default().min_bearing_var_rad2;
    static map_estimate_t before;
    static map_estimate_t after;
    assert_int_equal(slam_filter_export(&g_filter, &before), COSLAM_OK);
    uint64_t t = 1000000;
    enum { N_BAD = 8 };
    for (int k = 0; k < N_BAD; ++k, t += 1000000) {
        meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
        make_msg_from1((uint32_t)(10 + k), t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
        g_msg.sighting.range_var_m2 = 0.01;
        g_msg.sighting.bearing_var_rad2 = 0.001;
        if (k == 0) {
            g_msg.map.lm[0].mean = (point2_t){1e6, -1e6};
        } else if (k == 1) {
            g_msg.map.lm[0].cov = cov2_make(1e-20, 0.0, 1e-20);
        } else if (k == 2) {
            g_msg.sighting.range_var_m2 = 1e-300;
        } else if (k == 3) {
            g_msg.map.lm[0].cov_rel = cov2_make(1e9, 0.0, 1e9);
        } else if (k == 4) {
            /* a sighting so uncertain that it passes the range check (48 m
             * against 2 m) and spreads the landmark over 1e6 m^2 */
            g_msg.sighting.range_m = 50.0;
            g_msg.sighting.range_var_m2 = 1e6;
            g_msg.sighting.bearing_var_rad2 = 1e6;
        } else if (k == 5) {
            g_msg.sighting.bearing_var_rad2 = 1.0; /* sd 57 deg: no camera sighting */
        } else if (k == 6) {
            g_msg.sighting.range_var_m2 = 1e5; /* sd 316 m */
        } else {
            /* each bound passed, but a landmark 500 m out under a heading sd
             * of 0.45 rad lands with a 5e4 m^2 axis in the body frame */
            g_msg.sighting.bearing_var_rad2 = 0.2;
            g_msg.map.lm[0].mean = pose2_apply(g_msg.map.pose, (point2_t){500.0, 0.0});
        }
        size_t len = 0;
        assert_int_equal(map_msg_encode(&g_msg, g_buf, sizeof g_buf, &len), COSLAM_OK);
        inject(g_buf, len, 1, t + 2000);
        meeting_poll_link(&g_m, link);
        if (k < N_BAD - 1) {
            /* refused on arrival (merge_message_plausible): nothing pending */
            assert_int_equal(g_m.ctr.refused_implausible, (uint32_t)k + 1U);
            assert_int_equal(meeting_poll(&g_m, &g_filter, t + 3000, kOrigin, 0.0), COSLAM_OK);
        } else {
            /* the transform's spread needs the receiver's own sighting: at the merge */
            assert_int_equal(meeting_poll(&g_m, &g_filter, t + 3000, kOrigin, 0.0), COSLAM_E_MERGE_IMPLAUSIBLE);
        }
        assert_int_equal(g_m.ctr.refused_implausible, (uint32_t)k + 1U);
    }
    assert_int_equal(g_m.ctr.merged, 0);
    assert_int_equal(count_events(MEETING_EV_REFUSED, COSLAM_E_MERGE_IMPLAUSIBLE, NULL), N_BAD);
    /* refused on arrival, it acknowledges nothing: a landmark at 1e6 m
     * carrying this robot's provenance bit (a plausible one would say the
     * sender holds our map, and our sends to it would stop) */
    meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    g_m.peer[1].sent_n_landmarks = 0;
    g_m.peer[1].acked = 0U;
    make_msg_from1(19, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, (1U << 1) | 1U, 0);
    g_msg.sighting.range_var_m2 = 0.01;
    g_msg.sighting.bearing_var_rad2 = 0.001;
    g_msg.map.lm[0].mean = (point2_t){1e6, -1e6};
    {
        size_t len = 0;
        assert_int_equal(map_msg_encode(&g_msg, g_buf, sizeof g_buf, &len), COSLAM_OK);
        inject(g_buf, len, 1, t + 2000);
        meeting_poll_link(&g_m, link);
    }
    assert_int_equal(g_m.ctr.refused_implausible, N_BAD + 1U);
    assert_int_equal(g_m.peer[1].acked, 0U);
    t += 1000000;
    /* a genuine message from robot 1 delivered with another link sender id */
    meeting_on_sighting(&g_m, &g_filter, link, t, 1, 2.0, 0.0, t, kOrigin, 0.0);
    make_msg_from1(20, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    g_msg.sighting.range_var_m2 = 0.01;
    g_msg.sighting.bearing_var_rad2 = 0.001;
    size_t len = 0;
    assert_int_equal(map_msg_encode(&g_msg, g_buf, sizeof g_buf, &len), COSLAM_OK);
    inject(g_buf, len, 5, t + 2000);
    meeting_poll_link(&g_m, link);
    assert_int_equal(g_m.ctr.wrong_sender, 1);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 3000, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_m.ctr.merged, 0);
    assert_int_equal(slam_filter_export(&g_filter, &after), COSLAM_OK);
    assert_int_equal(after.n_landmarks, before.n_landmarks);
    /* and the same message from the right sender merges */
    inject(g_buf, len, 1, t + 4000);
    meeting_poll_link(&g_m, link);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 5000, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_m.ctr.merged, 1);
}

/* A peer whose map was refused as disagreeing is not retried message by
 * message within the remerge period (a retry passes the test by chance). */
static void test_disagreeing_peer_not_retried(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    const uint64_t t = 3000000;
    g_m.peer[1].disagreed = 1U; /* as meeting_poll leaves it after COSLAM_E_MERGE_DISAGREE */
    g_m.peer[1].disagreed_at_us = t;
    meeting_on_sighting(&g_m, &g_filter, link, t + 100000, 1, 2.0, 0.0, t + 100000, kOrigin, 0.0);
    size_t len = make_msg_from1(7, t + 100000, t + 100000, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 102000);
    meeting_poll_link(&g_m, link);
    assert_int_equal(g_m.ctr.ignored_disagreed, 1);
    assert_false(g_m.have_pending);
    /* after the remerge period the peer is heard again */
    const uint64_t later = t + g_m.cfg.remerge_period_us + 1000000;
    meeting_on_sighting(&g_m, &g_filter, link, later, 1, 2.0, 0.0, later, kOrigin, 0.0);
    len = make_msg_from1(8, later, later, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, later + 2000);
    meeting_poll_link(&g_m, link);
    assert_int_equal(g_m.ctr.ignored_disagreed, 1);
    assert_true(g_m.have_pending);
}

/* A receiver lost in its own map (COSLAM_E_MERGE_LOST; here every
 * receiver, lost_sd_factor tiny): the merge is refused and counted once, in
 * refused_lost only; the event carries the check's figures; the map is
 * unchanged; and, the refusal being about the receiver, not the peer's map,
 * no hold-off: the peer's next message is merged again at once. */
static void test_lost_receiver_refused_without_hold_off(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    g_m.cfg.merge.lost_sd_factor = 1e-6;
    /* robot 0 holds the landmark robot 1 sends, where it is */
    const point2_t at = pose2_apply(kMeetB, kMeetLm);
    ekfslam_meta_t meta = {g_filter.u.ekf.next_id, g_filter.u.ekf.cfg.slam.exist_max, 20, 1U, 0, 0};
    meta.signature = 2;
    assert_int_equal(ekfslam_add_landmark_body(&g_filter.u.ekf, at, cov2_make(0.004, 0.0, 0.004), &meta), COSLAM_OK);
    (void)ekfslam_new_id(&g_filter.u.ekf);
    static map_estimate_t before;
    static map_estimate_t after;
    assert_int_equal(slam_filter_export(&g_filter, &before), COSLAM_OK);
    assert_int_equal(before.n_landmarks, 1);

    meet_robot1(link);
    const uint64_t t1 = kMeetT + 10000;
    assert_int_equal(meeting_poll(&g_m, &g_filter, t1, kOrigin, 0.0), COSLAM_E_MERGE_LOST);
    assert_int_equal(g_m.ctr.refused_lost, 1);
    assert_int_equal(g_m.ctr.refused_disagree + g_m.ctr.refused_range + g_m.ctr.merge_failures + g_m.ctr.merged, 0);
    assert_false(g_m.peer[1].disagreed);
    assert_false(g_m.peer[1].merged);
    meeting_event_t ev = {0};
    assert_int_equal(count_events(MEETING_EV_REFUSED, COSLAM_E_MERGE_LOST, &ev), 1);
    assert_int_equal(ev.peer, 1);
    assert_int_equal(ev.stats.pairs, 1);
    assert_true(fabs(ev.stats.placed_sd_m - sqrt(0.004)) < 1e-3);
    assert_int_equal(slam_filter_export(&g_filter, &after), COSLAM_OK);
    assert_int_equal(after.n_landmarks, 1);
    assert_true(memcmp(&after.lm[0].mean, &before.lm[0].mean, sizeof before.lm[0].mean) == 0);
    assert_true(memcmp(&after.lm[0].cov, &before.lm[0].cov, sizeof before.lm[0].cov) == 0);

    /* the next message, well within the remerge period: not held off */
    const uint64_t t2 = t1 + 1000000;
    double r, b1, b2;
    mutual(kOrigin, kMeetB, &r, &b1, &b2);
    meeting_on_sighting(&g_m, &g_filter, link, t2 + 4000, 1, r, b1, t2, kOrigin, 0.0);
    const size_t len = make_msg_from1(2, t2 + 3000, t2, r, b2, kMeetLm, 1U << 1, 0);
    inject(g_buf, len, 1, t2 + 3000 + g_m.cfg.link_latency_us);
    assert_int_equal(meeting_poll_link(&g_m, link), 1);
    assert_int_equal(g_m.ctr.ignored_recent + g_m.ctr.ignored_disagreed, 0);
    assert_true(g_m.have_pending);
    g_m.cfg.merge.lost_sd_factor = 1.0; /* placed again (within merge_refute_sd_m) */
    assert_int_equal(meeting_poll(&g_m, &g_filter, t2 + 10000, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_m.ctr.merged, 1);
    assert_int_equal(g_m.ctr.refused_lost, 1);
}

static void test_screening(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    const uint64_t t = 2000000;
    /* a good message becomes pending (waiting for the own sighting) ... */
    size_t len = make_msg_from1(1, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    inject(g_buf, len, 1, t + 2000);
    meeting_poll_link(&g_m, link);
    assert_true(g_m.have_pending);
    /* ... and stays so through corrupt bytes, a message for someone else and
     * a broadcast without a sighting */
    uint8_t bad[64];
    memcpy(bad, g_buf, sizeof bad);
    inject(bad, sizeof bad, 1, t + 3000); /* truncated */
    (void)make_msg_from1(2, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, 0);
    g_msg.receiver_id = 3; /* a robot this team does not have */
    assert_int_equal(map_msg_encode(&g_msg, g_buf, sizeof g_buf, &len), COSLAM_OK);
    inject(g_buf, len, 1, t + 4000);
    len = make_msg_from1(3, t, t, 2.0, 0.0, (point2_t){1.0, 0.0}, 1U << 1, MAP_MSG_BROADCAST);
    inject(g_buf, len, 1, t + 5000);
    assert_int_equal(meeting_poll_link(&g_m, link), 3);
    assert_int_equal(g_m.ctr.rx_errors, 1);
    assert_int_equal(g_m.ctr.not_for_me, 2);
    meeting_event_t ev = {0};
    int truncated = 0, degenerate = 0;
    while (meeting_take_event(&g_m, &ev) == COSLAM_OK) {
        truncated += ev.kind == MEETING_EV_REFUSED && ev.status == COSLAM_E_MSG_TRUNCATED;
        degenerate += ev.kind == MEETING_EV_REFUSED && ev.status == COSLAM_E_DEGENERATE;
    }
    assert_int_equal(truncated, 1);
    assert_int_equal(degenerate, 1);
    assert_true(g_m.have_pending);
    meeting_on_sighting(&g_m, &g_filter, link, t + 5500, 1, 2.0, 0.0, t, kOrigin, 0.0);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 6000, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_m.ctr.merged, 1);
}

/* Three robots meet at once: robot 0 sees robots 1 and 2, and their
 * messages, both ready to merge, arrive in the same poll. Both are merged.
 * Before, the second took the first's pending slot (pending_replaced) and
 * robot 1's map was lost; the robots stepping together, each of robot 1's
 * retries met robot 2's again, so robot 1's map was never merged in that
 * meeting (found by test_meeting_props, seed 26). */
static void test_ready_message_not_replaced_by_another_peer(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    slam_filter_config_t fc = slam_filter_config_default();
    fc.kind = SLAM_FILTER_EKF;
    assert_int_equal(slam_filter_init(&g_filter, &fc, kOrigin), COSLAM_OK);
    meeting_config_t c = meeting_config_default();
    c.merge.min_var_m2 = 1e-9;
    c.merge.min_bearing_var_rad2 = 1e-11;
    assert_int_equal(meeting_init(&g_m, &c, 0, 3), COSLAM_OK);
    const pose2_t a = {0.0, 0.0, 0.0};
    const pose2_t other[3] = {{0.0, 0.0, 0.0}, kMeetB, {-0.8, 1.9, -1.2}};
    const point2_t lm_rel[3] = {{0.0, 0.0}, {1.5, -0.7}, {1.2, 0.9}};
    const uint64_t t = kMeetT;
    for (uint8_t k = 1; k <= 2; ++k) {
        double r, b_in_a, a_in_b;
        mutual(a, other[k], &r, &b_in_a, &a_in_b);
        meeting_on_sighting(&g_m, &g_filter, link, t + 1000, k, r, b_in_a, t, kOrigin, 0.0);
        (void)make_msg_from1(1, t + 3000, t, r, a_in_b, lm_rel[k], (uint16_t)(1U << k), 0);
        g_msg.sender_id = k;
        size_t len = 0;
        assert_int_equal(map_msg_encode(&g_msg, g_buf, sizeof g_buf, &len), COSLAM_OK);
        inject(g_buf, len, k, t + 5000);
    }
    for (int step = 0; step < 3; ++step) {
        (void)meeting_poll_link(&g_m, link);
        (void)meeting_poll(&g_m, &g_filter, t + 6000 + 100000U * (uint64_t)step, kOrigin, 0.0);
    }
    assert_int_equal(g_m.ctr.received, 2);
    assert_int_equal(g_m.ctr.pending_replaced, 0);
    assert_int_equal(g_m.ctr.merged, 2);
    assert_true(g_m.peer[1].merged && g_m.peer[2].merged);
    assert_int_equal(slam_filter_export(&g_filter, &g_est), COSLAM_OK);
    assert_int_equal(g_est.n_landmarks, 2);
    for (int k = 1; k <= 2; ++k) {
        const point2_t want = pose2_apply(other[k], lm_rel[k]);
        int found = 0;
        for (uint16_t i = 0; i < g_est.n_landmarks; ++i) {
            found += hypot(g_est.lm[i].mean.x - want.x, g_est.lm[i].mean.y - want.y) < 1e-6;
        }
        assert_int_equal(found, 1);
    }
}

static void test_event_queue_overflow_counted(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    setup_robot0(NULL);
    uint8_t junk[16] = {0};
    for (int i = 0; i < COSLAM_APP_EVENT_QUEUE + 3; ++i) {
        inject(junk, sizeof junk, 1, 1000);
        meeting_poll_link(&g_m, link);
    }
    assert_int_equal(g_m.ctr.rx_errors, COSLAM_APP_EVENT_QUEUE + 3);
    assert_int_equal(g_m.ctr.events_dropped, 3);
    int n = 0;
    meeting_event_t ev = {0};
    while (meeting_take_event(&g_m, &ev) == COSLAM_OK) n++;
    assert_int_equal(n, COSLAM_APP_EVENT_QUEUE);
}

/* A Fast-SLAM receiver whose merge budget (merge.step_units) is smaller
 * than its own export: meeting_poll returns COSLAM_E_MERGE_PENDING and
 * queues nothing; the export, the check and the fusion run in idle time
 * while the robot drives on; the next meeting_poll queues the merge's
 * event. The landmark lands where the robot's pose at the message's
 * arrival puts it, not where the robot has driven to since. */
static void test_merge_waits_for_idle_time(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    const slam_filter_config_t fc = meet_robot1_in_parts(link);
    const pose2_t b = kMeetB;
    const uint64_t t = kMeetT;
    /* robot 0's own send is exported in idle time too, first: the merge
     * waits for the export table */
    assert_int_equal(g_m.send_waiting, 1);
    assert_int_equal(g_link.n_sent, 0);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 6000, kOrigin, 0.0), COSLAM_E_EMPTY);
    assert_true(g_m.have_pending);
    int sends = 0;
    while (g_link.n_sent == 0 && sends < 100) {
        slam_filter_idle(&g_filter);
        (void)meeting_send_due(&g_m, &g_filter, link, t + 7000);
        sends++;
    }
    assert_int_equal(g_link.n_sent, 1);
    assert_int_equal(g_m.ctr.send_waits, 1);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 10000, kOrigin, 0.0), COSLAM_E_MERGE_PENDING);
    assert_true(g_m.merge_waiting);
    assert_int_equal(count_events(MEETING_EV_MERGED, COSLAM_OK, NULL), 0);
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 20000, kOrigin, 0.0), COSLAM_E_MERGE_PENDING);
    int idles = 0;
    while (g_filter.merge_due != NULL && idles < 100) {
        const odo_increment_t u = {0.02, 0.0, 0.01};
        assert_int_equal(slam_filter_predict(&g_filter, u, 0.1), COSLAM_OK);
        slam_filter_idle(&g_filter);
        idles++;
    }
    assert_true(idles > 2 * fc.n_particles - 2);
    meeting_event_t ev = {0};
    assert_int_equal(meeting_poll(&g_m, &g_filter, t + 900000, kOrigin, 0.0), COSLAM_OK);
    assert_false(g_m.merge_waiting);
    assert_int_equal(count_events(MEETING_EV_MERGED, COSLAM_OK, &ev), 1);
    assert_int_equal(ev.peer, 1);
    assert_int_equal(ev.seq, 1);
    assert_int_equal(ev.n_landmarks, 1);
    assert_int_equal(ev.stamp_us, t + 10000); /* when it began: the transform's body frame */
    assert_int_equal(ev.own_sighting_us, t);
    assert_true(fabs(ev.other_in_self.x - b.x) < 1e-9);
    assert_true(ev.stats.added >= 1U);
    assert_int_equal(g_m.ctr.merged, 1);
    assert_true(meeting_merged_all(&g_m));
    assert_robot1_landmark_merged();
    assert_true(g_est.pose.x > 0.1); /* the robot did drive on meanwhile */
}

/* A send that falls due while a merge's check holds the export table
 * (waiting for its own export in parts) is not begun: begun later, it would
 * carry this sighting with the map and pose of that later moment. Its slot
 * is kept (send_busy); the next sighting after the merge sends, with the
 * pose of its own moment. */
static void test_send_not_begun_while_a_check_waits(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    (void)meet_robot1_in_parts(link);
    const uint64_t t = kMeetT;
    uint64_t now = t + 7000;
    while (g_link.n_sent == 0 && now < t + 1000000) { /* the first send, in parts */
        slam_filter_idle(&g_filter);
        (void)meeting_send_due(&g_m, &g_filter, link, now);
        now += 1000;
    }
    assert_int_equal(g_link.n_sent, 1);
    assert_int_equal(meeting_poll(&g_m, &g_filter, now, kOrigin, 0.0), COSLAM_E_MERGE_PENDING);
    assert_true(g_m.merge_waiting);
    /* a resend due 1.1 s after the meeting, while the check waits */
    const odo_increment_t u = {0.05, 0.0, 0.02};
    assert_int_equal(slam_filter_predict(&g_filter, u, 0.1), COSLAM_OK);
    const uint64_t t2 = t + 1100000;
    const uint8_t sends = g_m.peer[1].sends;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t2 + 3000, 1, 2.0, 0.3, t2, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_m.ctr.send_busy, 1);
    assert_int_equal(g_m.send_waiting, 0); /* nothing begun */
    assert_int_equal(g_m.peer[1].sends, sends); /* its slot kept */
    assert_int_equal(g_link.n_sent, 1);
    /* the robot drives on while the merge is decided and fused */
    int idles = 0;
    while ((g_filter.merge_due != NULL || g_m.merge_waiting) && idles < 200) {
        assert_int_equal(slam_filter_predict(&g_filter, u, 0.1), COSLAM_OK);
        slam_filter_idle(&g_filter);
        (void)meeting_poll(&g_m, &g_filter, now, kOrigin, 0.0);
        idles++;
    }
    assert_false(g_m.merge_waiting);
    /* the next sighting sends, with the map and pose of its moment */
    assert_int_equal(slam_filter_export(&g_filter, &g_est), COSLAM_OK);
    const pose2_t at_sighting = g_est.pose;
    assert_true(at_sighting.x > 0.2); /* the robot did drive on since the busy sighting */
    const uint64_t t3 = t + 1400000;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t3 + 3000, 1, 2.0, 0.3, t3, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_m.peer[1].sends, sends + 1);
    assert_int_equal(g_m.send_waiting, 1); /* begun at this sighting */
    now = t3 + 4000;
    while (g_link.n_sent == 1 && now < t3 + 1000000) {
        assert_int_equal(slam_filter_predict(&g_filter, u, 0.1), COSLAM_OK);
        slam_filter_idle(&g_filter);
        (void)meeting_send_due(&g_m, &g_filter, link, now);
        now += 10000;
    }
    assert_int_equal(g_link.n_sent, 2);
    map_msg_t got;
    assert_int_equal(map_msg_decode(g_link.sent[1].data, g_link.sent[1].len, &got), COSLAM_OK);
    assert_int_equal(got.sighting.stamp_us, t3);
    assert_true(fabs(got.map.pose.x - at_sighting.x) < 1e-9);
    assert_true(fabs(got.map.pose.y - at_sighting.y) < 1e-9);
    assert_true(fabs(angle_wrap(got.map.pose.theta - at_sighting.theta)) < 1e-9);
}

/* A Fast-SLAM robot whose map export does not fit one step's budget: the
 * sighting starts the export, the idle time runs it while the robot drives
 * on, meeting_send_due sends it. The message carries the map and the pose
 * of the sighting's moment (the export at once then, bit for bit up to the
 * codec) and is stamped with the time it goes out, so that the receiver's
 * estimate of the sighting's time (stamp_us - sighting.stamp_us before the
 * arrival) holds. A second send due meanwhile keeps its slot. */
static map_estimate_t g_seed;
static map_estimate_t g_ref;

static void test_send_exported_in_idle_time(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    slam_filter_config_t fc = setup_robot0_fastslam_in_parts();
    memset(&g_seed, 0, sizeof g_seed);
    g_seed.pose = (pose2_t){0.3, -0.2, 0.4};
    g_seed.pose_cov = cov3_diag(0.01, 0.01, 0.001);
    g_seed.n_landmarks = 5;
    for (uint16_t i = 0; i < g_seed.n_landmarks; ++i) {
        map_landmark_t *l = &g_seed.lm[i];
        l->mean = (point2_t){1.0 + 0.7 * i, -1.0 + 0.4 * i};
        l->cov = cov2_make(0.02, 0.0, 0.02);
        l->cov_rel = cov2_make(0.01, 0.001, 0.015);
        l->id = 10U + i;
        l->n_obs = 9;
        l->src_mask = 1U;
        l->signature = (uint8_t)(i % 4);
    }
    assert_int_equal(slam_filter_seed(&g_filter, &fc, &g_seed), COSLAM_OK);
    assert_int_equal(slam_filter_export(&g_filter, &g_ref), COSLAM_OK); /* the map at the sighting */
    assert_int_equal(g_ref.n_landmarks, 5);
    const uint64_t t = 30000000;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t + 3000, 1, 2.0, 0.25, t, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_link.n_sent, 0);
    assert_int_equal(g_m.send_waiting, 1);
    assert_int_equal(g_filter.sends_in_parts, 1U);
    /* due again a second later (resend period) while the first is exported */
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t + 1003000, 1, 2.0, 0.25, t + 1000000, kOrigin, 0.0),
                     COSLAM_OK);
    assert_int_equal(g_m.ctr.send_busy, 1);
    assert_int_equal(g_m.peer[1].sends, 1); /* its slot kept */
    int idles = 0;
    int more_calls = 0;
    int more = 1;
    uint64_t now = t + 1010000;
    while (g_link.n_sent == 0 && idles < 100) {
        const odo_increment_t u = {0.02, 0.0, 0.01};
        assert_int_equal(slam_filter_predict(&g_filter, u, 0.1), COSLAM_OK);
        more = slam_filter_idle(&g_filter);
        more_calls += more;
        now += 10000;
        (void)meeting_send_due(&g_m, &g_filter, link, now);
        idles++;
    }
    assert_int_equal(idles, 2 * fc.n_particles - 1);
    /* idle said "more to do" after every part but the last */
    assert_int_equal(more_calls, idles - 1);
    assert_int_equal(more, 0);
    assert_int_equal(g_link.n_sent, 1);
    assert_int_equal(g_m.send_waiting, 0);
    assert_int_equal(g_filter.sends_forced, 0U);
    map_msg_t got;
    assert_int_equal(map_msg_decode(g_link.sent[0].data, g_link.sent[0].len, &got), COSLAM_OK);
    assert_int_equal(got.stamp_us, now);
    assert_int_equal(got.sighting.stamp_us, t);
    assert_int_equal(got.map.n_landmarks, g_ref.n_landmarks);
    assert_true(fabs(got.map.pose.x - g_ref.pose.x) < 1e-9);
    assert_true(fabs(angle_wrap(got.map.pose.theta - g_ref.pose.theta)) < 1e-9);
    for (uint16_t i = 0; i < got.map.n_landmarks; ++i) {
        assert_int_equal(got.map.lm[i].id, g_ref.lm[i].id);
        assert_true(fabs(got.map.lm[i].mean.x - g_ref.lm[i].mean.x) < 1e-6);
        assert_true(fabs(got.map.lm[i].cov_rel.xx - g_ref.lm[i].cov_rel.xx) < 1e-6 * g_ref.lm[i].cov_rel.xx);
    }
    /* the robot did drive on meanwhile */
    pose2_t pose;
    cov3_t cov;
    slam_filter_pose(&g_filter, &pose, &cov);
    assert_true(pose.x - g_ref.pose.x > 0.2);
    /* the next send goes out at once when its export fits the budget */
    g_m.cfg.merge.step_units = 0U;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t + 2100000, 1, 2.0, 0.25, t + 2100000, kOrigin, 0.0),
                     COSLAM_OK);
    assert_int_equal(g_link.n_sent, 2);
}

/* An observer's export (coslam-robot's status count and periodic snapshot,
 * slam_filter_export_observe) goes in parts like a send's but yields: a
 * send due meanwhile aborts it (or drops its result not yet taken) and goes
 * ahead at once instead of waiting or finishing it; the observer begins
 * again and gets the export of its moment. */
static map_estimate_t g_obs;

static int idle_until_polled(const map_estimate_t *out, int max_calls)
{
    int calls = 0;
    coslam_status_t st = COSLAM_E_ARG;
    while (slam_filter_export_poll(&g_filter, out, &st) == 0 && calls < max_calls) {
        (void)slam_filter_idle(&g_filter);
        calls++;
    }
    assert_int_equal(st, COSLAM_OK);
    return calls;
}

static void test_observer_export_yields(void **state)
{
    (void)state;
    hal_link_t *link = fake_link_reset(0);
    slam_filter_config_t fc = setup_robot0_fastslam_in_parts();
    memset(&g_seed, 0, sizeof g_seed);
    g_seed.pose = (pose2_t){-0.4, 0.1, -0.3};
    g_seed.pose_cov = cov3_diag(0.01, 0.01, 0.001);
    g_seed.n_landmarks = 4;
    for (uint16_t i = 0; i < g_seed.n_landmarks; ++i) {
        map_landmark_t *l = &g_seed.lm[i];
        l->mean = (point2_t){0.5 + 0.9 * i, 1.0 - 0.3 * i};
        l->cov = cov2_make(0.03, 0.002, 0.02);
        l->cov_rel = cov2_make(0.01, 0.0, 0.01);
        l->id = 20U + i;
        l->n_obs = 9;
        l->src_mask = 1U;
        l->signature = (uint8_t)(i % 3);
    }
    assert_int_equal(slam_filter_seed(&g_filter, &fc, &g_seed), COSLAM_OK);
    assert_int_equal(slam_filter_export_poll(&g_filter, &g_obs, NULL), -1); /* nothing begun */
    /* 1. begun, then a send is due: the observer's export is aborted, the
     * send's goes in parts at once (no wait, no busy slot) */
    assert_int_equal(slam_filter_export_observe(&g_filter, &g_obs, 1U), COSLAM_E_MERGE_PENDING);
    assert_int_equal(g_filter.observes_in_parts, 1U);
    assert_int_equal(slam_filter_export_poll(&g_filter, &g_obs, NULL), 0);
    assert_int_equal(slam_filter_idle(&g_filter), 1);
    const uint64_t t = 40000000;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t + 3000, 1, 2.0, 0.25, t, kOrigin, 0.0), COSLAM_OK);
    assert_int_equal(g_filter.observes_yielded, 1U);
    assert_int_equal(slam_filter_export_poll(&g_filter, &g_obs, NULL), -1);
    assert_int_equal(g_m.send_waiting, 1);
    assert_int_equal(g_m.ctr.send_busy, 0);
    assert_int_equal(g_filter.sends_in_parts, 1U);
    /* an observer cannot begin while the send's export runs */
    assert_int_equal(slam_filter_export_observe(&g_filter, &g_obs, 1U), COSLAM_E_MERGE_BUSY);
    int calls = 0;
    while (g_link.n_sent == 0 && calls < 100) {
        (void)slam_filter_idle(&g_filter);
        (void)meeting_send_due(&g_m, &g_filter, link, t + 10000 * (uint64_t)(calls + 1));
        calls++;
    }
    assert_int_equal(g_link.n_sent, 1);
    assert_int_equal(g_filter.sends_forced, 0U);
    /* 2. the observer begins again and gets the export of its moment */
    const odo_increment_t u = {0.05, 0.01, 0.02};
    assert_int_equal(slam_filter_predict(&g_filter, u, 0.1), COSLAM_OK);
    assert_int_equal(slam_filter_export(&g_filter, &g_ref), COSLAM_OK);
    memset(&g_obs, 0, sizeof g_obs);
    assert_int_equal(slam_filter_export_observe(&g_filter, &g_obs, 1U), COSLAM_E_MERGE_PENDING);
    assert_int_equal(idle_until_polled(&g_obs, 100), 2 * fc.n_particles - 1);
    assert_int_equal(slam_filter_export_poll(&g_filter, &g_obs, NULL), -1); /* taken once */
    assert_int_equal(g_obs.n_landmarks, g_ref.n_landmarks);
    assert_true(fabs(g_obs.pose.x - g_ref.pose.x) < 1e-12);
    for (uint16_t i = 0; i < g_obs.n_landmarks; ++i) {
        assert_int_equal(g_obs.lm[i].id, g_ref.lm[i].id);
        assert_true(fabs(g_obs.lm[i].mean.y - g_ref.lm[i].mean.y) < 1e-12);
        assert_true(fabs(g_obs.lm[i].cov.xx - g_ref.lm[i].cov.xx) < 1e-12);
    }
    /* 3. done but not taken when a send is due: dropped, the send goes */
    assert_int_equal(slam_filter_export_observe(&g_filter, &g_obs, 1U), COSLAM_E_MERGE_PENDING);
    while (slam_filter_idle(&g_filter)) {
    }
    assert_int_equal(g_filter.send_state, 2);
    g_m.cfg.merge.step_units = 0U;
    assert_int_equal(meeting_on_sighting(&g_m, &g_filter, link, t + 5003000, 1, 2.0, 0.25, t + 5000000, kOrigin, 0.0),
                     COSLAM_OK);
    assert_int_equal(g_link.n_sent, 2);
    assert_int_equal(g_filter.observes_yielded, 2U);
    assert_int_equal(slam_filter_export_poll(&g_filter, &g_obs, NULL), -1);
    /* 4. a send's export is never preempted by an observer, and an
     * observer's export finished by an update is not a forced send */
    assert_int_equal(slam_filter_export_observe(&g_filter, &g_obs, 1U), COSLAM_E_MERGE_PENDING);
    sighting_t none[1];
    memset(none, 0, sizeof none);
    for (unsigned k = 0; k <= SLAM_FILTER_MERGE_MAX_UPDATES; ++k) {
        assert_int_equal(slam_filter_update(&g_filter, none, 0), COSLAM_OK);
    }
    assert_int_equal(slam_filter_export_poll(&g_filter, &g_obs, NULL), 1);
    assert_int_equal(g_filter.sends_forced, 0U);
    assert_int_equal(g_filter.observes_in_parts, 4U);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_send_policy_and_message_fields),
        cmocka_unit_test(test_sighting_checks_and_range_limit),
        cmocka_unit_test(test_budget_renewed_then_implicit_ack),
        cmocka_unit_test(test_renewed_budget_keeps_the_resend_period),
        cmocka_unit_test(test_replay_neither_acks_nor_replaces),
        cmocka_unit_test(test_restarted_peer_is_heard_again),
        cmocka_unit_test(test_acknowledgement_owed_after_a_merge),
        cmocka_unit_test(test_merge_geometry_exact),
        cmocka_unit_test(test_merge_compensates_own_motion),
        cmocka_unit_test(test_pairs_nearest_own_sighting),
        cmocka_unit_test(test_waits_then_stale),
        cmocka_unit_test(test_absurd_age_is_stale),
        cmocka_unit_test(test_history_reaches_back_at_fast_rates),
        cmocka_unit_test(test_replay_refused),
        cmocka_unit_test(test_implausible_refused),
        cmocka_unit_test(test_disagreeing_peer_not_retried),
        cmocka_unit_test(test_lost_receiver_refused_without_hold_off),
        cmocka_unit_test(test_screening),
        cmocka_unit_test(test_ready_message_not_replaced_by_another_peer),
        cmocka_unit_test(test_event_queue_overflow_counted),
        cmocka_unit_test(test_merge_waits_for_idle_time),
        cmocka_unit_test(test_send_exported_in_idle_time),
        cmocka_unit_test(test_send_not_begun_while_a_check_waits),
        cmocka_unit_test(test_observer_export_yields),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
