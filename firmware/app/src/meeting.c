#include "app/meeting.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

/* One map message of this build's profile, plus what a link decorator may
 * append (the authentication trailer), is one link datagram: a profile
 * whose message could not be sent does not build (config.h
 * COSLAM_LINK_MSG_LANDMARKS, docs/map-message.md). */
_Static_assert(MAP_MSG_MAX_BYTES + HAL_LINK_TRAILER_RESERVE <= HAL_LINK_MAX_PAYLOAD,
               "the largest map message (COSLAM_MAX_MSG_LANDMARKS) does not fit HAL_LINK_MAX_PAYLOAD");

meeting_config_t meeting_config_default(void)
{
    meeting_config_t c;
    c.robot_range_var_m2 = 0.05 * 0.05;
    c.robot_range_var_per_m2 = 0.0;
    c.robot_bearing_var_rad2 = 0.035 * 0.035;
    c.link_latency_us = 2000U;
    c.pair_window_us = 300000U;
    c.resend_period_us = 1000000U;
    c.max_sends = 3U;
    c.meeting_gap_us = 5000000U;
    c.remerge_period_us = 60000000U;
    c.max_range_m = 3.0;
    c.export_min_obs = 5U;
    c.merge = merge_config_default();
    return c;
}

void meeting_config_noise_from(meeting_config_t *c, const slam_params_t *p)
{
    if (c == NULL || p == NULL) {
        return;
    }
    c->robot_range_var_m2 = p->noise.range_var_m2;
    c->robot_range_var_per_m2 = p->noise.range_var_per_m2;
    c->robot_bearing_var_rad2 = p->noise.bearing_var_rad2;
}

/* Time from `then` to `now` [us], 0 if `then` is later (a stamp out of
 * order, or an arrival stamped before a decision made in the same step):
 * never a wrapped, huge interval. */
static uint64_t since_us(uint64_t now, uint64_t then)
{
    return now > then ? now - then : 0U;
}

static int finite_nonneg(double v)
{
    return isfinite(v) && v >= 0.0;
}

coslam_status_t meeting_init(meeting_t *m, const meeting_config_t *cfg, uint8_t self_id, uint8_t n_robots)
{
    if (m == NULL || cfg == NULL || n_robots < 2U || n_robots > COSLAM_MAX_ROBOTS || self_id >= n_robots) {
        return COSLAM_E_ARG;
    }
    if (!(isfinite(cfg->robot_range_var_m2) && cfg->robot_range_var_m2 > 0.0) ||
        !(isfinite(cfg->robot_bearing_var_rad2) && cfg->robot_bearing_var_rad2 > 0.0) ||
        /* what this robot sends as its sighting's variance must pass its
         * partners' plausibility bound (the same default everywhere) */
        !(cfg->robot_bearing_var_rad2 <= cfg->merge.max_bearing_var_rad2) ||
        !finite_nonneg(cfg->robot_range_var_per_m2) ||
        !finite_nonneg(cfg->merge.peer_speed_mps) || !finite_nonneg(cfg->merge.peer_turn_radps) ||
        !finite_nonneg(cfg->merge.range_check_chi2) || cfg->pair_window_us == 0U || cfg->export_min_obs == 0U ||
        !(isfinite(cfg->max_range_m) && cfg->max_range_m > 0.0)) {
        return COSLAM_E_ARG;
    }
    memset(m, 0, sizeof *m);
    m->cfg = *cfg;
    m->self_id = self_id;
    m->n_robots = n_robots;
    merge_session_init(&m->session);
    return COSLAM_OK;
}

/* Queue an event; a full queue overwrites the oldest (counted). */
static meeting_event_t *push_event(meeting_t *m, meeting_event_kind_t kind, uint64_t now_us, uint8_t peer,
                                   uint32_t seq, coslam_status_t status)
{
    if (m->ev_n == COSLAM_APP_EVENT_QUEUE) {
        m->ev_head = (uint8_t)((m->ev_head + 1U) % COSLAM_APP_EVENT_QUEUE);
        m->ev_n--;
        m->ctr.events_dropped++;
    }
    const unsigned slot = (m->ev_head + m->ev_n) % COSLAM_APP_EVENT_QUEUE;
    m->ev_n++;
    meeting_event_t *ev = &m->ev[slot];
    memset(ev, 0, sizeof *ev);
    ev->kind = kind;
    ev->stamp_us = now_us;
    ev->peer = peer;
    ev->seq = seq;
    ev->status = status;
    return ev;
}

coslam_status_t meeting_take_event(meeting_t *m, meeting_event_t *ev)
{
    if (m == NULL || ev == NULL) {
        return COSLAM_E_ARG;
    }
    if (m->ev_n == 0U) {
        return COSLAM_E_EMPTY;
    }
    *ev = m->ev[m->ev_head];
    m->ev_head = (uint8_t)((m->ev_head + 1U) % COSLAM_APP_EVENT_QUEUE);
    m->ev_n--;
    return COSLAM_OK;
}

/* Slot of the sighting `age` in peer p's ring (age 0 = newest). */
static unsigned hist_slot(const meeting_peer_t *p, unsigned age)
{
    return (p->head + COSLAM_APP_SIGHTING_HISTORY - 1U - age) % COSLAM_APP_SIGHTING_HISTORY;
}

static const meeting_sighting_t *hist_at(const meeting_peer_t *p, unsigned age)
{
    return &p->hist[hist_slot(p, age)];
}

/* Room in peer p's history for a sighting at stamp_us, the newest. The
 * history should reach back at least COSLAM_APP_SIGHTING_HISTORY times a
 * third of the pairing window (1.6 s at 300 ms: a message whose export in
 * parts or whose link took that long still finds a sighting to pair with),
 * whatever the camera's rate. So when it is full and spans less than that,
 * it keeps its oldest sighting and gives up the one whose neighbours are
 * closest together in time (within a third of the window at the rate
 * that makes this happen: the nearest sighting then stays within the
 * window); else the oldest goes, as a plain ring. At 10 Hz and the default
 * window the history is the plain ring of the last 16 sightings. */
static meeting_sighting_t *hist_push(meeting_t *m, meeting_peer_t *p, uint64_t stamp_us)
{
    const unsigned n = COSLAM_APP_SIGHTING_HISTORY;
    if (p->n_hist == n && n >= 3U) {
        const uint64_t reach = (uint64_t)n * (m->cfg.pair_window_us / 3U);
        const uint64_t oldest = hist_at(p, n - 1U)->stamp_us;
        if (stamp_us >= oldest && stamp_us - oldest < reach) {
            /* the middle sighting (age 1 .. n - 2) between the closest neighbours */
            unsigned drop = 1U;
            uint64_t best = UINT64_MAX;
            for (unsigned a = 1U; a + 1U < n; ++a) {
                const uint64_t gap = hist_at(p, a - 1U)->stamp_us - hist_at(p, a + 1U)->stamp_us;
                if (gap < best) {
                    best = gap;
                    drop = a;
                }
            }
            /* close the gap: the newer sightings move one slot back */
            for (unsigned a = drop; a > 0U; --a) {
                p->hist[hist_slot(p, a)] = p->hist[hist_slot(p, a - 1U)];
            }
            m->ctr.history_thinned++;
            return &p->hist[hist_slot(p, 0U)];
        }
    }
    meeting_sighting_t *s = &p->hist[p->head];
    p->head = (uint8_t)((p->head + 1U) % n);
    if (p->n_hist < n) {
        p->n_hist++;
    }
    return s;
}

coslam_status_t meeting_last_sighting(const meeting_t *m, uint8_t peer, meeting_sighting_t *out)
{
    if (m == NULL || out == NULL || peer >= COSLAM_MAX_ROBOTS) {
        return COSLAM_E_ARG;
    }
    const meeting_peer_t *p = &m->peer[peer];
    if (p->n_hist == 0U) {
        return COSLAM_E_EMPTY;
    }
    *out = *hist_at(p, 0U);
    return COSLAM_OK;
}

int meeting_merged_all(const meeting_t *m)
{
    for (uint8_t k = 0; k < m->n_robots; ++k) {
        if (k != m->self_id && !m->peer[k].merged) {
            return 0;
        }
    }
    return 1;
}

/* We merged j's map in this meeting after our last message to j (or in
 * the same step: the step sends before it merges): j cannot know yet (its
 * acknowledgement is our next message, holding its landmarks), so one more
 * message is due even if j already holds ours. */
static int owes_ack(const meeting_peer_t *p)
{
    return p->merged && p->merged_at_us >= p->meeting_start_us &&
           (!p->sent_any || p->last_sent_us <= p->merged_at_us);
}

int meeting_owes_ack(const meeting_t *m)
{
    for (uint8_t k = 0; k < m->n_robots; ++k) {
        if (k != m->self_id && owes_ack(&m->peer[k])) {
            return 1;
        }
    }
    return 0;
}

int meeting_acked_all(const meeting_t *m)
{
    for (uint8_t k = 0; k < m->n_robots; ++k) {
        if (k != m->self_id && !m->peer[k].acked) {
            return 0;
        }
    }
    return 1;
}

const meeting_counters_t *meeting_counters(const meeting_t *m)
{
    return &m->ctr;
}

/* Range variance of an own sighting of a robot at range_m. */
static double robot_range_var(const meeting_t *m, double range_m)
{
    return m->cfg.robot_range_var_m2 + m->cfg.robot_range_var_per_m2 * range_m * range_m;
}

/* Encode and send the map exported into m->send_map (status st) to
 * m->send_peer, with the sighting m->send_sighting. */
static coslam_status_t send_exported(meeting_t *m, hal_link_t *link, uint64_t now_us, coslam_status_t st)
{
    m->send_waiting = 0U;
    if (st != COSLAM_OK && st != COSLAM_E_CAPACITY) {
        m->ctr.send_failures++;
        return st;
    }
    const uint8_t peer = m->send_peer;
    const meeting_sighting_t *s = &m->send_sighting;
    map_msg_t *msg = &m->tx;
    map_msg_init(msg);
    msg->map = m->send_map;
    /* weakly supported landmarks stay home: they would spread to every
     * partner before this robot has had the chance to drop them */
    uint16_t kept = 0;
    for (uint16_t i = 0; i < msg->map.n_landmarks; ++i) {
        if (msg->map.lm[i].n_obs >= m->cfg.export_min_obs) {
            msg->map.lm[kept++] = msg->map.lm[i];
        } else {
            m->ctr.weak_not_sent++;
        }
    }
    msg->map.n_landmarks = kept;
    /* A robot that has not moved yet has a zero pose covariance, which the
     * codec refuses: floor it (the merge does not use it). */
    if (!cov3_is_pd(msg->map.pose_cov)) {
        for (int i = 0; i < 3; ++i) {
            msg->map.pose_cov.m[i][i] += 1e-9;
        }
    }
    msg->sender_id = m->self_id;
    msg->receiver_id = peer;
    msg->seq = ++m->tx_seq;
    msg->stamp_us = now_us;
    msg->sighting.valid = true;
    msg->sighting.range_m = s->range_m;
    msg->sighting.bearing_rad = angle_wrap(s->bearing_rad);
    msg->sighting.range_var_m2 = robot_range_var(m, s->range_m);
    msg->sighting.bearing_var_rad2 = m->cfg.robot_bearing_var_rad2;
    msg->sighting.stamp_us = s->stamp_us;
    size_t len = 0;
    st = map_msg_encode(msg, m->wire, sizeof m->wire, &len);
    if (st != COSLAM_OK) {
        m->ctr.send_failures++;
        return st;
    }
    if (hal_link_send(link, peer, m->wire, len, 0U) != HAL_OK) {
        m->ctr.send_failures++;
        return COSLAM_E_LINK;
    }
    m->ctr.sent++;
    m->peer[peer].sent_n_landmarks = msg->map.n_landmarks;
    meeting_event_t *ev = push_event(m, MEETING_EV_SENT, now_us, peer, msg->seq, COSLAM_OK);
    ev->n_landmarks = msg->map.n_landmarks;
    return COSLAM_OK;
}

/* Export the map for `peer` with the sighting just made and send it: now,
 * or, if the export goes in parts (slam_filter_export_send), from
 * meeting_send_due, with the map and pose of this moment. If the export
 * table is taken (a merge's check waits for its own export), nothing is
 * begun and COSLAM_E_MERGE_BUSY returned: an export begun later would pair
 * this sighting with the map and pose of that later moment, so the next
 * sighting tries, with its own. */
static coslam_status_t send_map(meeting_t *m, slam_filter_t *filter, hal_link_t *link, uint64_t now_us, uint8_t peer,
                                const meeting_sighting_t *s)
{
    const coslam_status_t st = slam_filter_export_send(filter, &m->send_map, m->cfg.merge.step_units);
    if (st == COSLAM_E_MERGE_BUSY) {
        return st;
    }
    m->send_peer = peer;
    m->send_sighting = *s;
    if (st == COSLAM_E_MERGE_PENDING) {
        m->send_waiting = 1U;
        m->ctr.send_waits++;
        return COSLAM_OK;
    }
    return send_exported(m, link, now_us, st);
}

coslam_status_t meeting_send_due(meeting_t *m, slam_filter_t *filter, hal_link_t *link, uint64_t now_us)
{
    if (m == NULL || filter == NULL || link == NULL) {
        return COSLAM_E_ARG;
    }
    coslam_status_t st = COSLAM_OK;
    if (m->send_waiting) {
        const int ready = slam_filter_export_poll(filter, &m->send_map, &st);
        if (ready == 0) {
            return COSLAM_E_MERGE_PENDING;
        }
        if (ready < 0) {
            st = COSLAM_E_EMPTY; /* a send's export is never aborted: counted as a failure */
        }
        return send_exported(m, link, now_us, st);
    }
    return COSLAM_OK;
}

coslam_status_t meeting_on_sighting(meeting_t *m, slam_filter_t *filter, hal_link_t *link, uint64_t now_us,
                                    uint8_t peer, double range_m, double bearing_rad, uint64_t stamp_us,
                                    pose2_t odo_pose, double travel_m)
{
    if (m == NULL || filter == NULL || link == NULL || peer >= m->n_robots || peer == m->self_id ||
        !isfinite(range_m) || !(range_m > 0.0) || !isfinite(bearing_rad) || !pose2_is_finite(odo_pose) ||
        !isfinite(travel_m)) {
        return COSLAM_E_ARG;
    }
    if (range_m > m->cfg.max_range_m) {
        return COSLAM_OK;
    }
    meeting_peer_t *p = &m->peer[peer];
    meeting_sighting_t *s = hist_push(m, p, stamp_us);
    s->stamp_us = stamp_us;
    s->range_m = range_m;
    s->bearing_rad = bearing_rad;
    s->odo_pose = odo_pose;
    s->travel_m = travel_m;
    if (!p->in_meeting || since_us(stamp_us, p->last_seen_us) > m->cfg.meeting_gap_us) {
        p->in_meeting = 1U;
        p->sends = 0U;
        p->meeting_start_us = stamp_us;
    }
    p->last_seen_us = stamp_us;
    /* the period holds from the last send whatever the budget: a renewed
     * budget (accept_message) must not let every frame send */
    const int owe_ack = owes_ack(p);
    if (p->sends >= m->cfg.max_sends || (p->sent_any && now_us - p->last_sent_us < m->cfg.resend_period_us) ||
        (p->acked && p->acked_at_us >= p->meeting_start_us && now_us - p->acked_at_us < m->cfg.remerge_period_us &&
         !owe_ack)) {
        /* an acknowledgement counts within its meeting only: holding some of
         * our landmarks from an earlier meeting is not holding our map now */
        return COSLAM_OK;
    }
    if (m->send_waiting && meeting_send_due(m, filter, link, now_us) == COSLAM_E_MERGE_PENDING) {
        /* the last send is still being exported: this one's slot is kept */
        m->ctr.send_busy++;
        return COSLAM_OK;
    }
    const coslam_status_t st = send_map(m, filter, link, now_us, peer, s);
    if (st == COSLAM_E_MERGE_BUSY) {
        /* the export table is a waiting merge check's: slot kept, the next
         * sighting tries again */
        m->ctr.send_busy++;
        return COSLAM_OK;
    }
    p->sends++; /* a failed send still uses up its slot: no retry storm */
    p->sent_any = 1U;
    p->last_sent_us = now_us;
    return st;
}

/* Screen one decoded message (in m->tx, used as decode scratch: sending
 * only uses it inside send_map); an accepted one becomes the pending one. */
static uint8_t peer_of(const hal_link_rx_info_t *info)
{
    return (uint8_t)(info->src_id < 0xFFU ? info->src_id : 0xFFU);
}

static void accept_message(meeting_t *m, const hal_link_rx_info_t *info)
{
    const map_msg_t *msg = &m->tx;
    const uint8_t from = msg->sender_id;
    if ((msg->receiver_id != m->self_id && msg->receiver_id != MAP_MSG_BROADCAST) || from >= m->n_robots) {
        m->ctr.not_for_me++;
        return;
    }
    if (info->src_id != (uint16_t)from) {
        /* the link knows who sent it: a message claiming another sender is
         * forged or misrouted, never merged */
        m->ctr.wrong_sender++;
        push_event(m, MEETING_EV_REFUSED, info->stamp_us, peer_of(info), msg->seq, COSLAM_E_MSG_FIELD);
        return;
    }
    if (!msg->sighting.valid) {
        m->ctr.not_for_me++;
        push_event(m, MEETING_EV_REFUSED, info->stamp_us, from, msg->seq, COSLAM_E_DEGENERATE);
        return;
    }
    meeting_peer_t *p = &m->peer[from];
    /* the sequence number first, and taken whatever follows (a merge, a
     * hold-off, a stale refusal): a replay (or a number too far ahead)
     * changes nothing here, not the acknowledgement, not the send budget,
     * and a message seen once cannot act again. The session counts it and
     * tracks a restarted sender's numbers (MERGE_SEQ_REBASE_RUN). */
    const coslam_status_t st = merge_session_accept(&m->session, from, msg->seq);
    if (st != COSLAM_OK) {
        m->ctr.replays++;
        push_event(m, MEETING_EV_REFUSED, info->stamp_us, from, msg->seq, st);
        return;
    }
    /* values no robot of the team can produce (merge_prepare's step 0):
     * refused before they act on anything here, the acknowledgement and
     * the send budget included */
    const robot_sighting_t seen_by_sender = {msg->sighting.range_m, msg->sighting.bearing_rad,
                                             msg->sighting.range_var_m2, msg->sighting.bearing_var_rad2};
    if (!merge_message_plausible(&msg->map, &seen_by_sender, &m->cfg.merge)) {
        m->ctr.refused_implausible++;
        meeting_event_t *ev =
            push_event(m, MEETING_EV_REFUSED, info->stamp_us, from, msg->seq, COSLAM_E_MERGE_IMPLAUSIBLE);
        ev->n_landmarks = msg->map.n_landmarks;
        return;
    }
    /* implicit acknowledgement: does the sender hold the map we last sent
     * it? It does if at least half as many of its landmarks carry our
     * provenance bit as that message had landmarks (ours fuse into its own
     * ones, so the counts are close, not equal). A few landmarks from an
     * older meeting are not our map. */
    const uint16_t own_bit = (uint16_t)(1U << m->self_id);
    uint32_t n_ours = 0;
    for (uint16_t i = 0; i < msg->map.n_landmarks; ++i) {
        if ((msg->map.lm[i].src_mask & own_bit) != 0U) {
            n_ours++;
        }
    }
    const int holds_ours = n_ours > 0U && 2U * n_ours >= p->sent_n_landmarks;
    if (holds_ours) {
        p->acked = 1U;
        p->acked_at_us = info->stamp_us;
    } else if (!(p->acked && since_us(info->stamp_us, p->acked_at_us) < m->cfg.remerge_period_us)) {
        p->sends = 0U; /* the sender sees us and still needs our map */
    }
    if ((p->merged && since_us(info->stamp_us, p->merged_at_us) < m->cfg.remerge_period_us) ||
        (m->merge_waiting && m->waiting_ev.peer == from)) {
        /* merged lately, or its merge is being decided in idle time */
        m->ctr.ignored_recent++;
        return;
    }
    /* maps that disagreed do not agree a second later: retrying each message
     * of the meeting would only let one through by chance (multiple tests) */
    if (p->disagreed && since_us(info->stamp_us, p->disagreed_at_us) < m->cfg.remerge_period_us) {
        m->ctr.ignored_disagreed++;
        return;
    }
    const uint64_t age_us = msg->stamp_us >= msg->sighting.stamp_us ? msg->stamp_us - msg->sighting.stamp_us : 0U;
    const uint64_t latency_us = m->cfg.link_latency_us;
    /* the sender's sighting on our clock: arrival - latency - age. A
     * claimed age beyond our clock's start (a sum age + latency could wrap
     * for ages near 2^64 and land the sighting at the arrival) is stale. */
    if (info->stamp_us < latency_us || info->stamp_us - latency_us < age_us) {
        m->ctr.stale++;
        meeting_event_t *ev = push_event(m, MEETING_EV_REFUSED, info->stamp_us, from, msg->seq, COSLAM_E_MERGE_STALE);
        ev->n_landmarks = msg->map.n_landmarks;
        return;
    }
    if (m->have_pending) {
        m->ctr.pending_replaced++; /* only once the newcomer is taken */
    }
    m->rx = *msg;
    m->have_pending = 1U;
    m->pending_sender_us = info->stamp_us - latency_us - age_us;
}

static uint64_t abs_diff(uint64_t a, uint64_t b)
{
    return a > b ? a - b : b - a;
}

/* The own sighting of the pending message's sender nearest to its
 * sighting time t_s (NULL if none), and their distance in time. */
static const meeting_sighting_t *pending_nearest(const meeting_t *m, uint64_t *dt_out)
{
    const meeting_peer_t *p = &m->peer[m->rx.sender_id];
    const meeting_sighting_t *best = NULL;
    uint64_t best_dt = UINT64_MAX;
    for (unsigned a = 0; a < p->n_hist; ++a) {
        const meeting_sighting_t *s = hist_at(p, a);
        const uint64_t dt = abs_diff(s->stamp_us, m->pending_sender_us);
        if (dt < best_dt) {
            best_dt = dt;
            best = s;
        }
    }
    *dt_out = best_dt;
    return best;
}

int meeting_poll_link(meeting_t *m, hal_link_t *link)
{
    if (m == NULL || link == NULL) {
        return 0;
    }
    int taken = 0;
    for (int i = 0; i < MEETING_RX_BUDGET; ++i) {
        uint64_t dt = 0U;
        if (m->have_pending && pending_nearest(m, &dt) != NULL && dt <= m->cfg.pair_window_us) {
            /* the pending message pairs with an own sighting: meeting_poll
             * merges it next. The next datagram could replace it (one
             * slot), and a message from another peer arriving in the same
             * poll would then cost this one its merge - with three robots
             * meeting at once, every time: the link keeps the rest until
             * it is merged */
            break;
        }
        hal_link_rx_info_t info = {0U, 0xFFFFU, 0U};
        const hal_status_t hs = hal_link_recv(link, m->wire, sizeof m->wire, &info, 0U);
        if (hs == HAL_E_TIMEOUT || hs == HAL_E_UNSUPPORTED) {
            break;
        }
        taken++;
        m->ctr.received++;
        if (hs != HAL_OK) {
            /* too long for this build (a larger profile's map), or a link fault */
            m->ctr.rx_errors++;
            push_event(m, MEETING_EV_REFUSED, info.stamp_us, peer_of(&info), 0U,
                       hs == HAL_E_OVERFLOW ? COSLAM_E_MSG_LENGTH : COSLAM_E_LINK);
            if (hs != HAL_E_OVERFLOW) {
                break;
            }
            continue;
        }
        const coslam_status_t st = map_msg_decode(m->wire, info.len, &m->tx);
        if (st != COSLAM_OK) {
            m->ctr.rx_errors++;
            push_event(m, MEETING_EV_REFUSED, info.stamp_us, peer_of(&info), 0U, st);
            continue;
        }
        accept_message(m, &info);
    }
    return taken;
}

/* A merge's outcome, decided at now_us, into the counters and the event
 * queue; `ev0` holds what was known before it (peer, seq, landmarks,
 * sighting times, and the time the merge began, whose body frame the
 * transform is in: the event's stamp). */
static coslam_status_t merge_outcome(meeting_t *m, const meeting_event_t *ev0, uint64_t now_us, coslam_status_t st,
                                     const merge_stats_t *stats, pose2_t t, cov3_t tc)
{
    const uint8_t from = ev0->peer;
    const int merged = st == COSLAM_OK || st == COSLAM_E_CAPACITY;
    if (!merged) {
        if (st == COSLAM_E_MERGE_RANGE) {
            m->ctr.refused_range++;
        } else if (st == COSLAM_E_MERGE_IMPLAUSIBLE) {
            m->ctr.refused_implausible++;
        } else if (st == COSLAM_E_MERGE_LOST) {
            /* the receiver's state, not the peer's map: no hold-off, the
             * next meeting after it is placed again may merge */
            m->ctr.refused_lost++;
        } else if (st == COSLAM_E_MERGE_DISAGREE) {
            m->ctr.refused_disagree++;
            m->peer[from].disagreed = 1U;
            m->peer[from].disagreed_at_us = now_us;
        } else {
            m->ctr.merge_failures++;
        }
    } else {
        m->ctr.merged++;
        m->peer[from].merged = 1U;
        m->peer[from].merged_at_us = now_us;
    }
    meeting_event_t *ev =
        push_event(m, merged ? MEETING_EV_MERGED : MEETING_EV_REFUSED, ev0->stamp_us, from, ev0->seq, st);
    ev->n_landmarks = ev0->n_landmarks;
    ev->own_sighting_us = ev0->own_sighting_us;
    ev->sender_sighting_us = ev0->sender_sighting_us;
    ev->other_in_self = t;
    ev->other_in_self_cov = tc;
    ev->stats = *stats;
    return st;
}

/* The outcome of the merge that waited, if decided (finish: decide it
 * now). COSLAM_E_EMPTY if none was taken. */
static coslam_status_t take_waiting(meeting_t *m, uint64_t now_us, int finish)
{
    if (!m->merge_waiting) {
        return COSLAM_E_EMPTY;
    }
    if (finish) {
        slam_merge_work_finish(&m->work);
    }
    coslam_status_t st = COSLAM_OK;
    merge_stats_t stats;
    pose2_t t;
    cov3_t tc;
    if (!slam_merge_work_outcome(&m->work, &st, &stats, &t, &tc)) {
        return COSLAM_E_EMPTY;
    }
    m->merge_waiting = 0U;
    return merge_outcome(m, &m->waiting_ev, now_us, st, &stats, t, tc);
}

coslam_status_t meeting_poll(meeting_t *m, slam_filter_t *filter, uint64_t now_us, pose2_t odo_pose, double travel_m)
{
    if (m == NULL || filter == NULL) {
        return COSLAM_E_ARG;
    }
    const coslam_status_t waited = take_waiting(m, now_us, 0);
    if (!m->have_pending) {
        if (waited != COSLAM_E_EMPTY) {
            return waited;
        }
        return m->merge_waiting ? COSLAM_E_MERGE_PENDING : COSLAM_OK;
    }
    const map_msg_t *msg = &m->rx;
    const uint8_t from = msg->sender_id;
    const uint64_t t_s = m->pending_sender_us;
    uint64_t best_dt = UINT64_MAX;
    const meeting_sighting_t *best = pending_nearest(m, &best_dt);
    if (best == NULL || best_dt > m->cfg.pair_window_us) {
        if (now_us <= t_s + m->cfg.pair_window_us) {
            return COSLAM_E_EMPTY; /* an own sighting may still come */
        }
        m->have_pending = 0U;
        m->ctr.stale++;
        meeting_event_t *ev = push_event(m, MEETING_EV_REFUSED, now_us, from, msg->seq, COSLAM_E_MERGE_STALE);
        ev->n_landmarks = msg->map.n_landmarks;
        ev->sender_sighting_us = t_s;
        return COSLAM_E_MERGE_STALE;
    }
    if (m->send_waiting) {
        return COSLAM_E_EMPTY; /* the filter's export table is the send's until it is out */
    }
    m->have_pending = 0U;
    /* merges never overlap: one still waiting for its check is decided first */
    (void)take_waiting(m, now_us, 1);

    /* 5. the one merge path: set-up, check, fusion */
    merge_geometry_t g;
    g.self_sees_other = (robot_sighting_t){best->range_m, best->bearing_rad, robot_range_var(m, best->range_m),
                                           m->cfg.robot_bearing_var_rad2};
    g.other_sees_self = (robot_sighting_t){msg->sighting.range_m, msg->sighting.bearing_rad,
                                           msg->sighting.range_var_m2, msg->sighting.bearing_var_rad2};
    const pose2_t moved = pose2_between(best->odo_pose, odo_pose);
    g.own_motion = (odo_increment_t){moved.x, moved.y, moved.theta};
    g.own_travel_m = travel_m > best->travel_m ? travel_m - best->travel_m : 0.0;
    g.sighting_dt_s = (double)best_dt * 1e-6;
    pose2_t t = {0.0, 0.0, 0.0};
    cov3_t tc = cov3_zero();
    merge_stats_t stats;
    memset(&stats, 0, sizeof stats);
    meeting_event_t ev0;
    memset(&ev0, 0, sizeof ev0);
    ev0.stamp_us = now_us;
    ev0.peer = from;
    ev0.seq = msg->seq;
    ev0.n_landmarks = msg->map.n_landmarks;
    ev0.own_sighting_us = best->stamp_us;
    ev0.sender_sighting_us = t_s;
    const coslam_status_t st = slam_filter_merge_map(filter, &msg->map, &g, &m->cfg.merge, m->grid, &m->work, &stats, &t, &tc);
    if (st == COSLAM_E_MERGE_PENDING) {
        m->merge_waiting = 1U;
        m->waiting_ev = ev0;
        return st;
    }
    return merge_outcome(m, &ev0, now_us, st, &stats, t, tc);
}

void meeting_set_grid(meeting_t *m, const occ_grid_t *grid)
{
    if (m != NULL) {
        m->grid = grid;
    }
}
