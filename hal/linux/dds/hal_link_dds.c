/*
 * hal_link on Cyclone DDS. See hal/hal_link_dds.h for the behaviour behind
 * the contract and docs/link-dds.md for the design.
 *
 * Memory. This file allocates nothing per datagram: the one sample (the IDL
 * struct, fixed size: DDS_TOPIC_FIXED_SIZE), the decoded map_msg_t and the
 * wire buffer live in the caller's hal_link_dds_t, and dds_take is given
 * that sample to fill (buf[0] != NULL, so no loan: without Cyclone's
 * shared-memory transport a loan is a heap block too). QoS objects are
 * allocated and freed during open only.
 * What Cyclone allocates itself, per sample, inside the library: on write,
 * the serialised copy ("serdata", heap, reference-counted) that the
 * writer's history cache keeps until every reliable reader acknowledged it;
 * on receive, a serdata per sample in the reader's history cache, from
 * fragments reassembled in its preallocated receive-buffer pool; dds_take
 * deserialises it into our sample (a fixed-size type needs no allocation)
 * and frees it. That is outside the robot's fixed-memory core and bounded
 * by the history depths.
 */
#define _POSIX_C_SOURCE 200809L

#include "hal/hal_link_dds.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <dds/dds.h>

typedef coslam_msgs_msg_dds__MapMessage_ sample_t;

/* The IDL bounds are the C bounds (the IDL is generated from a template
 * with the value CMake read from coslam/config.h; this catches a core built
 * with other capacities than the ones CMake saw). */
_Static_assert(coslam_msgs_msg_dds__MapMessage_Constants_MAX_LANDMARKS_ == COSLAM_MAX_MSG_LANDMARKS,
               "IDL landmark bound differs from COSLAM_MAX_MSG_LANDMARKS: rerun cmake");
_Static_assert(sizeof(((sample_t *)0)->landmarks) / sizeof(((sample_t *)0)->landmarks[0]) ==
                   COSLAM_MAX_MSG_LANDMARKS,
               "IDL landmark array differs from COSLAM_MAX_MSG_LANDMARKS");
_Static_assert(coslam_msgs_msg_dds__MapMessage_Constants_TRAILER_MAX_ == HAL_LINK_DDS_TRAILER_MAX &&
                   sizeof(((sample_t *)0)->trailer) == HAL_LINK_DDS_TRAILER_MAX,
               "IDL trailer bound differs from HAL_LINK_DDS_TRAILER_MAX");
_Static_assert(HAL_LINK_DDS_TRAILER_MAX <= HAL_LINK_TRAILER_RESERVE, "trailer within the link's reserve");
_Static_assert(HAL_LINK_DDS_MAX_DATAGRAM <= HAL_LINK_MAX_PAYLOAD,
               "the largest map message (COSLAM_MAX_MSG_LANDMARKS) plus the trailer exceeds HAL_LINK_MAX_PAYLOAD");

/* ------------------------------------------------------------------------ */
/* the process's domains                                                    */
/* ------------------------------------------------------------------------ */

/* A DDS domain is a process-wide object shared by every participant of
 * that domain id, and deleting it deletes them all: instances share it
 * through this reference-counted table. `handle` is 0 when the domain
 * already existed (created outside this backend): it is used, not owned. */
#define DOMAIN_SLOTS 8
static struct {
    int used;
    uint32_t domain_id;
    dds_entity_t handle;
    uint32_t refs;
    uint64_t config_hash;
} g_domains[DOMAIN_SLOTS];
static pthread_mutex_t g_domains_lock = PTHREAD_MUTEX_INITIALIZER;

static uint64_t fnv1a64(const char *s)
{
    uint64_t h = 1469598103934665603u;
    for (; *s != '\0'; ++s) {
        h ^= (uint8_t)*s;
        h *= 1099511628211u;
    }
    return h;
}

static hal_status_t domain_acquire(uint32_t domain_id, const char *config, int *slot_out)
{
    const uint64_t hash = fnv1a64(config);
    hal_status_t st = HAL_OK;
    pthread_mutex_lock(&g_domains_lock);
    int free_slot = -1, slot = -1;
    for (int i = 0; i < DOMAIN_SLOTS; ++i) {
        if (g_domains[i].used && g_domains[i].domain_id == domain_id) {
            slot = i;
        } else if (!g_domains[i].used && free_slot < 0) {
            free_slot = i;
        }
    }
    if (slot >= 0) {
        if (g_domains[slot].config_hash != hash) {
            st = HAL_E_BUSY;
        } else {
            g_domains[slot].refs++;
        }
    } else if (free_slot < 0) {
        st = HAL_E_BUSY;
    } else {
        const dds_entity_t d = dds_create_domain((dds_domainid_t)domain_id, config);
        if (d >= 0 || d == DDS_RETCODE_PRECONDITION_NOT_MET) {
            slot = free_slot;
            g_domains[slot].used = 1;
            g_domains[slot].domain_id = domain_id;
            g_domains[slot].handle = d >= 0 ? d : 0;
            g_domains[slot].refs = 1;
            g_domains[slot].config_hash = hash;
        } else {
            st = HAL_E_IO;
        }
    }
    pthread_mutex_unlock(&g_domains_lock);
    *slot_out = st == HAL_OK ? slot : -1;
    return st;
}

static void domain_release(int slot)
{
    if (slot < 0 || slot >= DOMAIN_SLOTS) return;
    pthread_mutex_lock(&g_domains_lock);
    if (g_domains[slot].used && --g_domains[slot].refs == 0) {
        if (g_domains[slot].handle > 0) {
            (void)dds_delete(g_domains[slot].handle);
        }
        g_domains[slot].used = 0;
    }
    pthread_mutex_unlock(&g_domains_lock);
}

/* ------------------------------------------------------------------------ */
/* helpers                                                                  */
/* ------------------------------------------------------------------------ */

static uint64_t mono_us(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_MONOTONIC, &ts) != 0) return 0;
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* Append s to buf (capacity cap, NUL-terminated); 0 if it does not fit. */
static int append(char *buf, size_t cap, const char *s)
{
    const size_t have = strlen(buf), add = strlen(s);
    if (have + add + 1u > cap) return 0;
    memcpy(buf + have, s, add + 1u);
    return 1;
}

/* A peer address goes into XML: allow host names, IPv4 and [IPv6] only. */
static int peer_ok(const char *p)
{
    if (p == NULL || *p == '\0' || strlen(p) > 255u) return 0;
    for (; *p != '\0'; ++p) {
        const char c = *p;
        const int ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                       c == ':' || c == '-' || c == '_' || c == '[' || c == ']';
        if (!ok) return 0;
    }
    return 1;
}

/* The domain's configuration: CYCLONEDDS_URI, cfg->config, peers. */
static hal_status_t build_config(char *out, size_t cap, const hal_link_dds_config_t *cfg)
{
    out[0] = '\0';
    const char *env = getenv("CYCLONEDDS_URI");
    int ok = 1;
    if (env != NULL && *env != '\0') ok = append(out, cap, env);
    if (ok && cfg->config != NULL && *cfg->config != '\0') {
        if (out[0] != '\0') ok = append(out, cap, ",");
        ok = ok && append(out, cap, cfg->config);
    }
    if (ok && cfg->peers != NULL && cfg->peers[0] != NULL) {
        if (out[0] != '\0') ok = append(out, cap, ",");
        ok = ok && append(out, cap, "<CycloneDDS><Domain id=\"any\"><Discovery>"
                                    "<ParticipantIndex>auto</ParticipantIndex><Peers>");
        for (size_t i = 0; ok && cfg->peers[i] != NULL; ++i) {
            if (!peer_ok(cfg->peers[i])) return HAL_E_ARG;
            ok = append(out, cap, "<Peer address=\"") && append(out, cap, cfg->peers[i]) && append(out, cap, "\"/>");
        }
        ok = ok && append(out, cap, "</Peers></Discovery></Domain></CycloneDDS>");
    }
    return ok ? HAL_OK : HAL_E_ARG;
}

/* Datagram -> sample. len was checked by the wrapper (1..HAL_LINK_MAX_PAYLOAD). */
static hal_status_t to_sample(hal_link_dds_t *st, uint16_t dest_id, const uint8_t *data, size_t len)
{
    if (len < 12u) {
        st->ctr.send_not_map++;
        return HAL_E_ARG;
    }
    const size_t msg_len = (size_t)data[8] | (size_t)data[9] << 8 | (size_t)data[10] << 16 | (size_t)data[11] << 24;
    if (msg_len > len || map_msg_decode(data, msg_len, &st->msg) != COSLAM_OK) {
        st->ctr.send_not_map++;
        return HAL_E_ARG;
    }
    const size_t trailer_len = len - msg_len;
    if (trailer_len > HAL_LINK_DDS_TRAILER_MAX) {
        st->ctr.send_trailer_too_long++;
        return HAL_E_ARG;
    }
    const map_msg_t *m = &st->msg;
    sample_t *s = &st->sample;
    s->link_src = st->self_id;
    s->link_dest = dest_id;
    s->version = m->version;
    s->sender_id = m->sender_id;
    s->receiver_id = m->receiver_id;
    s->sighting_valid = m->sighting.valid;
    s->seq = m->seq;
    s->stamp_us = m->stamp_us;
    s->pose_x = m->map.pose.x;
    s->pose_y = m->map.pose.y;
    s->pose_theta = m->map.pose.theta;
    s->pose_cov[0] = m->map.pose_cov.m[0][0];
    s->pose_cov[1] = m->map.pose_cov.m[0][1];
    s->pose_cov[2] = m->map.pose_cov.m[0][2];
    s->pose_cov[3] = m->map.pose_cov.m[1][1];
    s->pose_cov[4] = m->map.pose_cov.m[1][2];
    s->pose_cov[5] = m->map.pose_cov.m[2][2];
    s->sighting_range_m = m->sighting.range_m;
    s->sighting_bearing_rad = m->sighting.bearing_rad;
    s->sighting_range_var_m2 = m->sighting.range_var_m2;
    s->sighting_bearing_var_rad2 = m->sighting.bearing_var_rad2;
    s->sighting_stamp_us = m->sighting.stamp_us;
    s->n_landmarks = m->map.n_landmarks;
    for (uint16_t i = 0; i < m->map.n_landmarks; ++i) {
        const map_landmark_t *l = &m->map.lm[i];
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
    /* the fixed array is serialised whole: unused slots go out as zeros, not
     * as whatever an earlier message left there */
    memset(&s->landmarks[m->map.n_landmarks], 0,
           sizeof s->landmarks[0] * (size_t)(COSLAM_MAX_MSG_LANDMARKS - m->map.n_landmarks));
    s->trailer_len = (uint16_t)trailer_len;
    memcpy(s->trailer, data + msg_len, trailer_len);
    memset(s->trailer + trailer_len, 0, HAL_LINK_DDS_TRAILER_MAX - trailer_len);
    return HAL_OK;
}

/* Sample -> st->wire; returns the datagram length, 0 if the sample does not
 * make a valid codec message (its trailer too long, its fields invalid). */
static size_t from_sample(hal_link_dds_t *st)
{
    const sample_t *s = &st->sample;
    if (s->n_landmarks > COSLAM_MAX_MSG_LANDMARKS || s->trailer_len > HAL_LINK_DDS_TRAILER_MAX) return 0;
    map_msg_t *m = &st->msg;
    m->version = s->version;
    m->sender_id = s->sender_id;
    m->receiver_id = s->receiver_id;
    m->seq = s->seq;
    m->stamp_us = s->stamp_us;
    m->map.pose.x = s->pose_x;
    m->map.pose.y = s->pose_y;
    m->map.pose.theta = s->pose_theta;
    static const int idx[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int k = 0; k < 6; ++k) {
        m->map.pose_cov.m[idx[k][0]][idx[k][1]] = s->pose_cov[k];
        m->map.pose_cov.m[idx[k][1]][idx[k][0]] = s->pose_cov[k];
    }
    m->sighting.valid = s->sighting_valid;
    m->sighting.range_m = s->sighting_range_m;
    m->sighting.bearing_rad = s->sighting_bearing_rad;
    m->sighting.range_var_m2 = s->sighting_range_var_m2;
    m->sighting.bearing_var_rad2 = s->sighting_bearing_var_rad2;
    m->sighting.stamp_us = s->sighting_stamp_us;
    m->map.n_landmarks = s->n_landmarks;
    for (uint16_t i = 0; i < s->n_landmarks; ++i) {
        const coslam_msgs_msg_dds__MapLandmark_ *l = &s->landmarks[i];
        map_landmark_t *o = &m->map.lm[i];
        o->mean.x = l->mean_x;
        o->mean.y = l->mean_y;
        o->cov.xx = l->cov_xx;
        o->cov.xy = l->cov_xy;
        o->cov.yy = l->cov_yy;
        o->cov_rel.xx = l->cov_rel_xx;
        o->cov_rel.xy = l->cov_rel_xy;
        o->cov_rel.yy = l->cov_rel_yy;
        o->id = l->id;
        o->n_obs = l->n_obs;
        o->src_mask = l->src_mask;
        o->signature = l->signature;
    }
    size_t len = 0;
    if (map_msg_encode(m, st->wire, sizeof st->wire, &len) != COSLAM_OK) return 0;
    memcpy(st->wire + len, s->trailer, s->trailer_len);
    return len + s->trailer_len;
}

static void update_status_counters(hal_link_dds_t *st)
{
    dds_sample_lost_status_t lost;
    dds_sample_rejected_status_t rej;
    if (dds_get_sample_lost_status(st->reader, &lost) == DDS_RETCODE_OK) st->ctr.dds_lost = lost.total_count;
    if (dds_get_sample_rejected_status(st->reader, &rej) == DDS_RETCODE_OK) st->ctr.dds_rejected = rej.total_count;
}

/* ------------------------------------------------------------------------ */
/* operations                                                               */
/* ------------------------------------------------------------------------ */

static hal_link_dds_t *state_of(hal_link_t *dev)
{
    hal_link_dds_t *st = (hal_link_dds_t *)dev->backend;
    return st != NULL && st->open ? st : NULL;
}

static hal_status_t dds_self_id(hal_link_t *dev, uint16_t *id)
{
    hal_link_dds_t *st = state_of(dev);
    if (st == NULL) return HAL_E_CLOSED;
    *id = st->self_id;
    return HAL_OK;
}

static hal_status_t dds_send(hal_link_t *dev, uint16_t dest_id, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    (void)timeout_us; /* the writer's max_blocking_time bounds the wait (header) */
    hal_link_dds_t *st = state_of(dev);
    if (st == NULL) return HAL_E_CLOSED;
    if (dest_id == st->self_id) return HAL_E_ARG;
    const hal_status_t hs = to_sample(st, dest_id, data, len);
    if (hs != HAL_OK) return hs;
    const dds_return_t rc = dds_write(st->writer, &st->sample);
    if (rc == DDS_RETCODE_OK) {
        st->ctr.sent++;
        return HAL_OK;
    }
    if (rc == DDS_RETCODE_TIMEOUT) {
        st->ctr.send_busy++;
        return HAL_E_BUSY;
    }
    st->ctr.send_io++;
    return HAL_E_IO;
}

static hal_status_t dds_recv(hal_link_t *dev, uint8_t *buf, size_t cap, hal_link_rx_info_t *info, uint32_t timeout_us)
{
    hal_link_dds_t *st = state_of(dev);
    if (st == NULL) return HAL_E_CLOSED;
    const uint64_t deadline_us = mono_us() + timeout_us;
    unsigned skipped = 0;
    for (;;) {
        if (skipped > 0u && timeout_us != HAL_TIMEOUT_FOREVER &&
            (skipped >= HAL_LINK_DDS_SKIPPED_PER_CALL || (timeout_us > 0u && mono_us() >= deadline_us))) {
            return HAL_E_TIMEOUT; /* samples not for us do not hold the caller past its timeout */
        }
        void *samples[1] = {&st->sample};
        dds_sample_info_t si;
        const dds_return_t n = dds_take(st->reader, samples, &si, 1, 1);
        if (n < 0) {
            st->ctr.rx_io++;
            return HAL_E_IO;
        }
        if (n == 1) {
            const uint64_t now = mono_us();
            if (!si.valid_data) {
                st->ctr.rx_not_data++;
                skipped++;
                continue;
            }
            const sample_t *s = &st->sample;
            if (s->link_dest != st->self_id && s->link_dest != HAL_LINK_BROADCAST) {
                st->ctr.rx_other_dest++;
                skipped++;
                continue;
            }
            if (s->link_src == st->self_id) {
                st->ctr.rx_own_id++;
                skipped++;
                continue;
            }
            const size_t len = from_sample(st);
            if (len == 0u) {
                st->ctr.rx_invalid++;
                skipped++;
                continue;
            }
            info->len = len;
            info->src_id = s->link_src;
            info->stamp_us = now;
            st->ctr.delivered++;
            if (len > cap) {
                memcpy(buf, st->wire, cap);
                st->ctr.rx_overflow++;
                return HAL_E_OVERFLOW;
            }
            memcpy(buf, st->wire, len);
            return HAL_OK;
        }
        update_status_counters(st);
        dds_duration_t wait_ns = DDS_INFINITY;
        if (timeout_us != HAL_TIMEOUT_FOREVER) {
            const uint64_t now = mono_us();
            if (now >= deadline_us) return HAL_E_TIMEOUT;
            wait_ns = (dds_duration_t)(deadline_us - now) * 1000;
        }
        const dds_return_t w = dds_waitset_wait(st->waitset, NULL, 0, wait_ns);
        if (w < 0) {
            st->ctr.rx_io++;
            return HAL_E_IO;
        }
        /* w == 0: timed out; the next round takes a late arrival or returns */
    }
}

static void dds_close(hal_link_t *dev)
{
    hal_link_dds_t *st = (hal_link_dds_t *)dev->backend;
    if (st == NULL || !st->open) return;
    (void)dds_delete(st->participant); /* and every entity under it */
    domain_release(st->domain_slot);
    st->domain_slot = -1;
    st->open = 0;
}

static const hal_link_ops_t dds_ops = {
    .self_id = dds_self_id,
    .send = dds_send,
    .recv = dds_recv,
    .close = dds_close,
};

/* ------------------------------------------------------------------------ */
/* open                                                                     */
/* ------------------------------------------------------------------------ */

static dds_qos_t *endpoint_qos(const hal_link_dds_config_t *cfg)
{
    dds_qos_t *q = dds_create_qos();
    if (q == NULL) return NULL;
    const uint32_t depth = cfg->history_depth != 0u ? cfg->history_depth : HAL_LINK_DDS_DEFAULT_DEPTH;
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_USECS((int64_t)cfg->send_block_us));
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, depth > INT32_MAX ? INT32_MAX : (int32_t)depth);
    dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
    /* a robot never hears its own datagrams; other participants of this
     * process (other robots in a test) are heard */
    dds_qset_ignorelocal(q, DDS_IGNORELOCAL_PARTICIPANT);
    /* plain CDR, as rmw_cyclonedds writes it */
    const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
    dds_qset_data_representation(q, 1, &xcdr1);
    if (cfg->partition != NULL && *cfg->partition != '\0') dds_qset_partition1(q, cfg->partition);
    return q;
}

hal_status_t hal_link_dds_open(hal_link_dds_t *st, const hal_link_dds_config_t *cfg)
{
    if (st == NULL || cfg == NULL || cfg->self_id == HAL_LINK_BROADCAST || cfg->domain_id > 232u) return HAL_E_ARG;
    memset(&st->ctr, 0, sizeof st->ctr);
    st->open = 0;
    st->domain_slot = -1;
    st->self_id = cfg->self_id;
    st->link.ops = &dds_ops;
    st->link.backend = st;
    hal_status_t hs = build_config(st->config_xml, sizeof st->config_xml, cfg);
    if (hs != HAL_OK) return hs;
    hs = domain_acquire(cfg->domain_id, st->config_xml, &st->domain_slot);
    if (hs != HAL_OK) return hs;

    st->participant = dds_create_participant((dds_domainid_t)cfg->domain_id, NULL, NULL);
    if (st->participant < 0) {
        domain_release(st->domain_slot);
        st->domain_slot = -1;
        return HAL_E_IO;
    }
    hs = HAL_E_IO;
    dds_qos_t *q = endpoint_qos(cfg);
    if (q != NULL) {
        st->topic = dds_create_topic(st->participant, &coslam_msgs_msg_dds__MapMessage__desc,
                                     cfg->topic != NULL ? cfg->topic : HAL_LINK_DDS_DEFAULT_TOPIC, q, NULL);
        if (st->topic >= 0) {
            st->writer = dds_create_writer(st->participant, st->topic, q, NULL);
            st->reader = dds_create_reader(st->participant, st->topic, q, NULL);
        }
        dds_delete_qos(q);
        if (st->topic >= 0 && st->writer >= 0 && st->reader >= 0) {
            st->readcond = dds_create_readcondition(st->reader, DDS_ANY_STATE);
            st->waitset = dds_create_waitset(st->participant);
            if (st->readcond >= 0 && st->waitset >= 0 &&
                dds_waitset_attach(st->waitset, st->readcond, (dds_attach_t)st->readcond) == DDS_RETCODE_OK) {
                hs = HAL_OK;
            }
        }
    }
    if (hs != HAL_OK) {
        (void)dds_delete(st->participant);
        domain_release(st->domain_slot);
        st->domain_slot = -1;
        return hs;
    }
    st->open = 1;
    return HAL_OK;
}

const hal_link_dds_counters_t *hal_link_dds_counters(const hal_link_dds_t *st)
{
    return &st->ctr;
}

hal_status_t hal_link_dds_wait_matched(hal_link_dds_t *st, uint32_t n_readers, uint32_t timeout_us)
{
    if (st == NULL) return HAL_E_ARG;
    if (!st->open) return HAL_E_CLOSED;
    const uint64_t deadline_us = mono_us() + timeout_us;
    for (;;) {
        dds_publication_matched_status_t pm;
        if (dds_get_publication_matched_status(st->writer, &pm) != DDS_RETCODE_OK) return HAL_E_IO;
        if (pm.current_count >= n_readers) return HAL_OK;
        if (timeout_us != HAL_TIMEOUT_FOREVER && mono_us() >= deadline_us) return HAL_E_TIMEOUT;
        dds_sleepfor(DDS_MSECS(2));
    }
}

hal_status_t hal_link_dds_flush(hal_link_dds_t *st, uint32_t timeout_us)
{
    if (st == NULL) return HAL_E_ARG;
    if (!st->open) return HAL_E_CLOSED;
    const dds_duration_t t = timeout_us == HAL_TIMEOUT_FOREVER ? DDS_INFINITY : DDS_USECS((int64_t)timeout_us);
    const dds_return_t rc = dds_wait_for_acks(st->writer, t);
    if (rc == DDS_RETCODE_OK) return HAL_OK;
    return rc == DDS_RETCODE_TIMEOUT ? HAL_E_TIMEOUT : HAL_E_IO;
}
