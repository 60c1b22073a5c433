/* Map snapshots of coslam-robot (robot_snapshot.h). */
#include "robot_snapshot.h"

#include <math.h>
#include <string.h>

#include "coslam/cov2.h"
#include "coslam/cov3.h"
#include "coslam/crc32.h"

static const char *const slot_names[2] = {ROBOT_SNAPSHOT_NAME_A, ROBOT_SNAPSHOT_NAME_B};

/* ---- byte order ---------------------------------------------------------- */

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

static void put_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; ++i) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

static void put_f64(uint8_t *p, double v)
{
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    put_u64(p, u);
}

static uint16_t get_u16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}

static uint32_t get_u32(const uint8_t *p)
{
    uint32_t v = 0;
    for (int i = 3; i >= 0; --i) {
        v = (v << 8) | p[i];
    }
    return v;
}

static uint64_t get_u64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; --i) {
        v = (v << 8) | p[i];
    }
    return v;
}

static double get_f64(const uint8_t *p)
{
    const uint64_t u = get_u64(p);
    double v;
    memcpy(&v, &u, sizeof v);
    return v;
}

/* ---- codec --------------------------------------------------------------- */

coslam_status_t robot_snapshot_encode(const robot_snapshot_t *s, uint8_t *buf, size_t cap, size_t *len)
{
    if (s == NULL || buf == NULL || len == NULL || s->map.n_landmarks > COSLAM_MAX_MSG_LANDMARKS) {
        return COSLAM_E_ARG;
    }
    *len = 0;
    const uint16_t n = s->map.n_landmarks;
    const size_t payload = ROBOT_SNAPSHOT_PAYLOAD_BYTES(n);
    const size_t total = ROBOT_SNAPSHOT_BYTES(n);
    if (cap < total) {
        return COSLAM_E_CAPACITY;
    }
    memset(buf, 0, total);
    memcpy(buf, "CSNP", 4);
    put_u16(buf + 4, (uint16_t)ROBOT_SNAPSHOT_VERSION);
    put_u16(buf + 6, (uint16_t)ROBOT_SNAPSHOT_HEADER_BYTES);
    put_u32(buf + 8, (uint32_t)payload);
    put_u64(buf + 12, s->seq);
    buf[20] = s->robot_id;
    buf[21] = s->filter_kind;
    buf[22] = s->clean_stop ? 1U : 0U;
    put_u32(buf + 24, s->msg_seq);
    put_u64(buf + 28, s->saved_unix_s);
    put_u32(buf + 36, crc32_update(0U, buf, 36U));
    uint8_t *p = buf + ROBOT_SNAPSHOT_HEADER_BYTES;
    put_f64(p + 0, s->map.pose.x);
    put_f64(p + 8, s->map.pose.y);
    put_f64(p + 16, s->map.pose.theta);
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            put_f64(p + 24 + 8 * (3 * r + c), s->map.pose_cov.m[r][c]);
        }
    }
    put_u16(p + 96, n);
    for (uint16_t i = 0; i < n; ++i) {
        const map_landmark_t *l = &s->map.lm[i];
        uint8_t *q = p + 98 + ROBOT_SNAPSHOT_LANDMARK_BYTES * (size_t)i;
        put_f64(q + 0, l->mean.x);
        put_f64(q + 8, l->mean.y);
        put_f64(q + 16, l->cov.xx);
        put_f64(q + 24, l->cov.xy);
        put_f64(q + 32, l->cov.yy);
        put_f64(q + 40, l->cov_rel.xx);
        put_f64(q + 48, l->cov_rel.xy);
        put_f64(q + 56, l->cov_rel.yy);
        put_u32(q + 64, l->id);
        put_u16(q + 68, l->n_obs);
        put_u16(q + 70, l->src_mask);
        q[72] = l->signature;
    }
    put_u32(p + payload, crc32_update(0U, p, payload));
    *len = total;
    return COSLAM_OK;
}

coslam_status_t robot_snapshot_decode(const uint8_t *buf, size_t len, robot_snapshot_t *out)
{
    if (buf == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    if (len < ROBOT_SNAPSHOT_HEADER_BYTES) {
        return COSLAM_E_MSG_TRUNCATED;
    }
    if (memcmp(buf, "CSNP", 4) != 0) {
        return COSLAM_E_MSG_MAGIC;
    }
    if (get_u16(buf + 4) != ROBOT_SNAPSHOT_VERSION) {
        return COSLAM_E_MSG_VERSION;
    }
    if (get_u16(buf + 6) != ROBOT_SNAPSHOT_HEADER_BYTES) {
        return COSLAM_E_MSG_LENGTH;
    }
    if (get_u32(buf + 36) != crc32_update(0U, buf, 36U)) {
        return COSLAM_E_MSG_CRC;
    }
    const size_t payload = get_u32(buf + 8);
    if (payload < ROBOT_SNAPSHOT_PAYLOAD_BYTES(0)) {
        return COSLAM_E_MSG_LENGTH;
    }
    if (len < ROBOT_SNAPSHOT_HEADER_BYTES + payload + 4U) {
        return COSLAM_E_MSG_TRUNCATED;
    }
    if (len > ROBOT_SNAPSHOT_HEADER_BYTES + payload + 4U) {
        return COSLAM_E_MSG_LENGTH;
    }
    const uint8_t *p = buf + ROBOT_SNAPSHOT_HEADER_BYTES;
    if (get_u32(p + payload) != crc32_update(0U, p, payload)) {
        return COSLAM_E_MSG_CRC;
    }
    const uint16_t n = get_u16(p + 96);
    if (n > COSLAM_MAX_MSG_LANDMARKS) {
        return COSLAM_E_MSG_COUNT;
    }
    if (payload != ROBOT_SNAPSHOT_PAYLOAD_BYTES(n)) {
        return COSLAM_E_MSG_LENGTH;
    }
    /* fields: the map is checked completely before *out is touched */
    static robot_snapshot_t tmp; /* 5 KB (default profile); one thread */
    memset(&tmp, 0, sizeof tmp);
    tmp.seq = get_u64(buf + 12);
    tmp.robot_id = buf[20];
    tmp.filter_kind = buf[21];
    tmp.msg_seq = get_u32(buf + 24);
    tmp.clean_stop = (uint8_t)(buf[22] & 1U);
    tmp.saved_unix_s = get_u64(buf + 28);
    tmp.map.pose.x = get_f64(p + 0);
    tmp.map.pose.y = get_f64(p + 8);
    tmp.map.pose.theta = get_f64(p + 16);
    int finite = isfinite(tmp.map.pose.x) && isfinite(tmp.map.pose.y) && isfinite(tmp.map.pose.theta);
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            tmp.map.pose_cov.m[r][c] = get_f64(p + 24 + 8 * (3 * r + c));
            finite = finite && isfinite(tmp.map.pose_cov.m[r][c]);
        }
    }
    if (!finite) {
        return COSLAM_E_MSG_NONFINITE;
    }
    /* the covariance seeds the EKF's P and every particle's pose marginal:
     * an asymmetric or indefinite one would be taken as it is */
    if (!cov3_is_psd(tmp.map.pose_cov)) {
        return COSLAM_E_MSG_COVARIANCE;
    }
    tmp.map.n_landmarks = n;
    for (uint16_t i = 0; i < n; ++i) {
        map_landmark_t *l = &tmp.map.lm[i];
        const uint8_t *q = p + 98 + ROBOT_SNAPSHOT_LANDMARK_BYTES * (size_t)i;
        l->mean.x = get_f64(q + 0);
        l->mean.y = get_f64(q + 8);
        l->cov.xx = get_f64(q + 16);
        l->cov.xy = get_f64(q + 24);
        l->cov.yy = get_f64(q + 32);
        l->cov_rel.xx = get_f64(q + 40);
        l->cov_rel.xy = get_f64(q + 48);
        l->cov_rel.yy = get_f64(q + 56);
        l->id = get_u32(q + 64);
        l->n_obs = get_u16(q + 68);
        l->src_mask = get_u16(q + 70);
        l->signature = q[72];
        if (!isfinite(l->mean.x) || !isfinite(l->mean.y) || !cov2_is_finite(l->cov) || !cov2_is_finite(l->cov_rel)) {
            return COSLAM_E_MSG_NONFINITE;
        }
        if (!cov2_is_pd(l->cov) || !cov2_is_pd(l->cov_rel)) {
            return COSLAM_E_MSG_COVARIANCE;
        }
        if (l->id == 0U) {
            return COSLAM_E_MSG_FIELD;
        }
    }
    *out = tmp;
    return COSLAM_OK;
}

/* ---- two generations ----------------------------------------------------- */

void robot_snapshots_init(robot_snapshots_t *s, hal_storage_t *storage)
{
    memset(s, 0, sizeof *s);
    s->storage = storage;
    s->newest = -1;
    s->failed_slot = -1;
    s->last_write = HAL_OK;
}

void robot_snapshots_set_storage(robot_snapshots_t *s, hal_storage_t *storage)
{
    s->storage = storage;
}

coslam_status_t robot_snapshots_read_newest(robot_snapshots_t *s, robot_snapshot_t *out, robot_snapshot_found_t *found,
                                            FILE *log)
{
    if (s == NULL || out == NULL || found == NULL) {
        return COSLAM_E_ARG;
    }
    found->slot = -1;
    found->seq = 0U;
    found->corrupt = 0U;
    if (s->storage == NULL) {
        return COSLAM_E_UNSUPPORTED;
    }
    static robot_snapshot_t cand; /* one thread at a time: the loop, or the writer for it */
    for (int k = 0; k < 2; ++k) {
        size_t len = 0;
        const hal_status_t hs = hal_storage_read(s->storage, slot_names[k], s->buf, sizeof s->buf, &len);
        if (hs == HAL_E_NOT_FOUND) {
            continue;
        }
        if (hs != HAL_OK) {
            found->corrupt++;
            if (log != NULL) {
                fprintf(log, "coslam-robot: snapshot: %s unreadable (%s)%s\n", slot_names[k], hal_status_str(hs),
                        hs == HAL_E_CORRUPT ? ": damaged, not used" : "");
            }
            continue;
        }
        const coslam_status_t cs = robot_snapshot_decode(s->buf, len, &cand);
        if (cs != COSLAM_OK) {
            found->corrupt++;
            if (log != NULL) {
                fprintf(log, "coslam-robot: snapshot: %s corrupt (%s): not used\n", slot_names[k],
                        coslam_status_str(cs));
            }
            continue;
        }
        if (found->slot < 0 || cand.seq > out->seq) {
            *out = cand;
            found->slot = k;
            found->seq = cand.seq;
        }
    }
    if (log != NULL) {
        fflush(log);
    }
    return found->slot < 0 ? COSLAM_E_EMPTY : COSLAM_OK;
}

const char *robot_snapshots_found(robot_snapshots_t *s, const robot_snapshot_found_t *found)
{
    s->corrupt_found += found->corrupt;
    if (found->slot < 0) {
        return NULL;
    }
    s->newest = found->slot;
    s->newest_seq = found->seq;
    return slot_names[found->slot];
}

coslam_status_t robot_snapshots_load(robot_snapshots_t *s, robot_snapshot_t *out, const char **name, FILE *log)
{
    robot_snapshot_found_t found;
    const coslam_status_t st = robot_snapshots_read_newest(s, out, &found, log);
    if (st == COSLAM_OK || st == COSLAM_E_EMPTY) {
        const char *n = robot_snapshots_found(s, &found);
        if (name != NULL && n != NULL) {
            *name = n;
        }
    }
    return st;
}

coslam_status_t robot_snapshots_prepare(robot_snapshots_t *s, robot_snapshot_t *snap, robot_snapshot_job_t *job)
{
    if (s == NULL || snap == NULL || job == NULL) {
        return COSLAM_E_ARG;
    }
    if (s->storage == NULL) {
        s->save_failures++;
        return COSLAM_E_UNSUPPORTED;
    }
    job->slot = s->newest == 0 ? 1 : 0; /* over the older generation */
    if (job->slot == s->failed_slot) {
        /* its last write failed (a directory, a file that cannot be
         * replaced there): over the newest instead (an atomic replace:
         * the newest is then the one written, or stays as it was), and
         * the failed one again now and then */
        if (++s->failed_slot_skips < ROBOT_SNAPSHOT_RETRY_FAILED_SLOT) {
            job->slot = 1 - job->slot;
        } else {
            s->failed_slot_skips = 0U;
        }
    }
    job->name = slot_names[job->slot];
    job->seq = s->newest_seq + 1U;
    snap->seq = job->seq;
    job->len = 0;
    if (robot_snapshot_encode(snap, s->buf, sizeof s->buf, &job->len) != COSLAM_OK) {
        s->save_failures++;
        return COSLAM_E_ARG;
    }
    return COSLAM_OK;
}

coslam_status_t robot_snapshots_commit(robot_snapshots_t *s, const robot_snapshot_job_t *job, hal_status_t written)
{
    if (s == NULL || job == NULL || job->slot < 0 || job->slot > 1) {
        return COSLAM_E_ARG;
    }
    s->last_write = written;
    if (written != HAL_OK) {
        s->save_failures++;
        if (s->failed_slot != job->slot) {
            s->failed_slot = job->slot;
            s->failed_slot_skips = 0U;
        }
        /* what happened, not only that it failed: the caller reacts to a
         * failed medium (I/O, closed) otherwise than to a full one */
        switch (written) {
        case HAL_E_OVERFLOW: return COSLAM_E_CAPACITY;
        case HAL_E_UNSUPPORTED: return COSLAM_E_UNSUPPORTED;
        case HAL_E_ARG: return COSLAM_E_ARG;
        default: return COSLAM_E_STORAGE;
        }
    }
    if (job->slot == s->failed_slot) {
        s->failed_slot = -1; /* writable again */
    }
    s->newest = job->slot;
    s->newest_seq = job->seq;
    s->saves++;
    return COSLAM_OK;
}

coslam_status_t robot_snapshots_save(robot_snapshots_t *s, robot_snapshot_t *snap, const char **name)
{
    robot_snapshot_job_t job;
    const coslam_status_t ps = robot_snapshots_prepare(s, snap, &job);
    if (ps != COSLAM_OK) {
        return ps;
    }
    const coslam_status_t cs = robot_snapshots_commit(s, &job, hal_storage_write(s->storage, job.name, s->buf, job.len));
    if (cs == COSLAM_OK && name != NULL) {
        *name = job.name;
    }
    return cs;
}
