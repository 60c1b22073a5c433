/*
 * Authenticated map messages: hal_link decorator. See hal/hal_link_auth.h
 * for the trailer and the checks, docs/security.md for the threat model.
 */
#define _POSIX_C_SOURCE 200809L

#include "hal/hal_link_auth.h"

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <sodium.h>

#include "coslam/map_msg.h"

_Static_assert(HAL_LINK_AUTH_KEY_BYTES == crypto_auth_hmacsha512256_KEYBYTES, "key size");
_Static_assert(HAL_LINK_AUTH_MAC_BYTES == crypto_auth_hmacsha512256_BYTES, "tag size");
/* the largest map message of this build's profile, signed, is one datagram */
_Static_assert(HAL_LINK_AUTH_TRAILER_BYTES <= HAL_LINK_TRAILER_RESERVE, "trailer within the link's reserve");
_Static_assert(MAP_MSG_MAX_BYTES + HAL_LINK_AUTH_TRAILER_BYTES <= HAL_LINK_MAX_PAYLOAD,
               "the largest map message (COSLAM_MAX_MSG_LANDMARKS) plus the trailer exceeds HAL_LINK_MAX_PAYLOAD");

/* Codec header fields the decorator reads (coslam/map_msg.h wire format). */
#define OFF_SENDER 5u
#define OFF_LENGTH 8u
#define HDR_MIN 12u

/* ------------------------------------------------------------------------ */
/* helpers                                                                  */
/* ------------------------------------------------------------------------ */

static uint64_t clock_us(clockid_t id)
{
    struct timespec ts;
    if (clock_gettime(id, &ts) != 0) return 0;
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static uint64_t realtime_us(void *ctx)
{
    (void)ctx;
    return clock_us(CLOCK_REALTIME);
}

static uint64_t wall_now(const hal_link_auth_t *st)
{
    return st->wall_clock_us(st->clock_ctx);
}

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void put_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; ++i) p[i] = (uint8_t)(v >> (8 * i));
}

static uint16_t get_u16(const uint8_t *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get_u64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; --i) v = v << 8 | p[i];
    return v;
}

static int is_codec_header(const uint8_t *d, size_t len)
{
    return len >= HDR_MIN && d[0] == 0x43u && d[1] == 0x53u && d[2] == 0x4Cu && d[3] == 0x4Du;
}

/* ------------------------------------------------------------------------ */
/* operations                                                               */
/* ------------------------------------------------------------------------ */

static hal_link_auth_t *state_of(hal_link_t *dev)
{
    hal_link_auth_t *st = (hal_link_auth_t *)dev->backend;
    return st != NULL && st->open ? st : NULL;
}

static hal_status_t auth_self_id(hal_link_t *dev, uint16_t *id)
{
    hal_link_auth_t *st = state_of(dev);
    if (st == NULL) return HAL_E_CLOSED;
    *id = st->self_id;
    return HAL_OK;
}

static hal_status_t auth_send(hal_link_t *dev, uint16_t dest_id, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    hal_link_auth_t *st = state_of(dev);
    if (st == NULL) return HAL_E_CLOSED;
    if (!is_codec_header(data, len) || get_u32(data + OFF_LENGTH) != len) {
        st->ctr.send_not_map++;
        return HAL_E_ARG;
    }
    if (data[OFF_SENDER] != st->self_id) {
        st->ctr.send_wrong_sender++;
        return HAL_E_ARG;
    }
    if (len + HAL_LINK_AUTH_TRAILER_BYTES > sizeof st->buf) {
        st->ctr.send_too_long++;
        return HAL_E_ARG;
    }
    const uint64_t now = wall_now(st);
    /* never reuse a counter: a restarted robot starts at its wall clock */
    st->tx_counter = now > st->tx_counter ? now : st->tx_counter + 1u;
    uint8_t *b = st->buf;
    memcpy(b, data, len);
    uint8_t *t = b + len;
    t[0] = (uint8_t)HAL_LINK_AUTH_FORMAT;
    t[1] = st->key_id;
    put_u16(t + 2, st->self_id);
    put_u64(t + 4, st->tx_counter);
    put_u64(t + 12, now);
    crypto_auth_hmacsha512256(t + HAL_LINK_AUTH_HEADER_BYTES, b, len + HAL_LINK_AUTH_HEADER_BYTES, st->key);
    const hal_status_t hs = hal_link_send(st->inner, dest_id, b, len + HAL_LINK_AUTH_TRAILER_BYTES, timeout_us);
    if (hs != HAL_OK) {
        st->ctr.send_inner_failed++;
        return hs;
    }
    st->ctr.sent++;
    return HAL_OK;
}

/* The checks of the header comment, in order: NULL if the datagram passes
 * (*counter set), else the counter of the reason to bump. */
static uint32_t *verify(hal_link_auth_t *st, const uint8_t *d, size_t len, uint16_t link_src, uint64_t *counter)
{
    hal_link_auth_counters_t *c = &st->ctr;
    if (!is_codec_header(d, len)) return &c->rx_malformed;
    const size_t L = get_u32(d + OFF_LENGTH);
    if (len == L) return &c->rx_unauthenticated;
    if (len < L || len - L < HAL_LINK_AUTH_TRAILER_BYTES) return &c->rx_truncated;
    if (len - L > HAL_LINK_AUTH_TRAILER_BYTES) return &c->rx_malformed;
    const uint8_t *t = d + L;
    if (t[0] != HAL_LINK_AUTH_FORMAT) return &c->rx_malformed;
    if (t[1] != st->key_id) return &c->rx_wrong_key;
    if (crypto_auth_hmacsha512256_verify(t + HAL_LINK_AUTH_HEADER_BYTES, d, L + HAL_LINK_AUTH_HEADER_BYTES,
                                         st->key) != 0) {
        return &c->rx_bad_mac;
    }
    /* authentic from here on: what is left is whether it is acceptable */
    const uint16_t sender = get_u16(t + 2);
    if (sender != link_src || sender != d[OFF_SENDER]) return &c->rx_sender_mismatch;
    const uint64_t stamp = get_u64(t + 12), now = wall_now(st);
    if (now > stamp && now - stamp > st->window_us) return &c->rx_stale;
    if (stamp > now && stamp - now > st->window_us) return &c->rx_future;
    *counter = get_u64(t + 4);
    if (*counter <= st->last_counter[sender]) return &c->rx_replay;
    return NULL;
}

static hal_status_t auth_recv(hal_link_t *dev, uint8_t *buf, size_t cap, hal_link_rx_info_t *info, uint32_t timeout_us)
{
    hal_link_auth_t *st = state_of(dev);
    if (st == NULL) return HAL_E_CLOSED;
    const uint64_t deadline_us = clock_us(CLOCK_MONOTONIC) + timeout_us;
    unsigned refused_n = 0;
    for (;;) {
        if (refused_n > 0u && timeout_us != HAL_TIMEOUT_FOREVER &&
            (refused_n >= HAL_LINK_AUTH_REFUSED_PER_CALL ||
             (timeout_us > 0u && clock_us(CLOCK_MONOTONIC) >= deadline_us))) {
            /* a stream of refused datagrams (a flood of forgeries costs an
             * HMAC each) must not hold the caller past its timeout, nor
             * for more than a bounded number of checks: the rest waits
             * for the next call */
            return HAL_E_TIMEOUT;
        }
        uint32_t wait_us = timeout_us;
        if (timeout_us != HAL_TIMEOUT_FOREVER) {
            const uint64_t now = clock_us(CLOCK_MONOTONIC);
            const uint64_t left = now < deadline_us ? deadline_us - now : 0u;
            wait_us = left >= HAL_TIMEOUT_FOREVER ? HAL_TIMEOUT_FOREVER - 1u : (uint32_t)left;
        }
        hal_link_rx_info_t in;
        const hal_status_t hs = hal_link_recv(st->inner, st->buf, sizeof st->buf, &in, wait_us);
        if (hs == HAL_E_OVERFLOW) {
            st->ctr.rx_oversize++; /* longer than any datagram this decorator makes */
            refused_n++;
            continue;
        }
        if (hs != HAL_OK) return hs; /* HAL_E_TIMEOUT, HAL_E_CLOSED, HAL_E_IO, ... */
        uint64_t counter = 0;
        uint32_t *refused = verify(st, st->buf, in.len, in.src_id, &counter);
        if (refused != NULL) {
            (*refused)++;
            refused_n++;
            continue;
        }
        st->last_counter[in.src_id] = counter;
        const size_t L = in.len - HAL_LINK_AUTH_TRAILER_BYTES;
        info->len = L;
        info->src_id = in.src_id;
        info->stamp_us = in.stamp_us;
        st->ctr.delivered++;
        if (L > cap) {
            memcpy(buf, st->buf, cap);
            st->ctr.rx_overflow++;
            return HAL_E_OVERFLOW;
        }
        memcpy(buf, st->buf, L);
        return HAL_OK;
    }
}

static void auth_close(hal_link_t *dev)
{
    hal_link_auth_t *st = (hal_link_auth_t *)dev->backend;
    if (st == NULL || !st->open) return;
    sodium_memzero(st->key, sizeof st->key);
    sodium_memzero(st->buf, sizeof st->buf);
    st->open = 0;
    hal_link_close(st->inner);
}

static const hal_link_ops_t auth_ops = {
    .self_id = auth_self_id,
    .send = auth_send,
    .recv = auth_recv,
    .close = auth_close,
};

hal_link_t *hal_link_auth_open(hal_link_t *inner, const hal_link_auth_config_t *cfg, hal_link_auth_t *st)
{
    if (inner == NULL || cfg == NULL || st == NULL || sodium_init() < 0) return NULL;
    uint16_t id = 0;
    if (hal_link_self_id(inner, &id) != HAL_OK || id > 254u) return NULL;
    memset(st, 0, sizeof *st);
    st->link.ops = &auth_ops;
    st->link.backend = st;
    st->inner = inner;
    st->self_id = id;
    memcpy(st->key, cfg->key, sizeof st->key);
    st->key_id = cfg->key_id;
    st->window_us = cfg->window_us != 0u ? cfg->window_us : HAL_LINK_AUTH_DEFAULT_WINDOW_US;
    st->wall_clock_us = cfg->wall_clock_us != NULL ? cfg->wall_clock_us : realtime_us;
    st->clock_ctx = cfg->clock_ctx;
    st->open = 1;
    return &st->link;
}

const hal_link_auth_counters_t *hal_link_auth_counters(const hal_link_auth_t *st)
{
    return &st->ctr;
}

/* ------------------------------------------------------------------------ */
/* keys                                                                     */
/* ------------------------------------------------------------------------ */

static int is_space(char c)
{
    return c == ' ' || c == '\t' || c == '\n' || c == '\r';
}

/* Exactly 64 hex digits in [s, s + n), white space around them allowed. */
static hal_status_t key_from_text(const char *s, size_t n, uint8_t key[HAL_LINK_AUTH_KEY_BYTES])
{
    while (n > 0u && is_space(*s)) {
        ++s;
        --n;
    }
    while (n > 0u && is_space(s[n - 1u])) --n;
    size_t bin_len = 0;
    const char *end = NULL;
    if (n != 2u * HAL_LINK_AUTH_KEY_BYTES ||
        sodium_hex2bin(key, HAL_LINK_AUTH_KEY_BYTES, s, n, NULL, &bin_len, &end) != 0 ||
        bin_len != HAL_LINK_AUTH_KEY_BYTES || end != s + n) {
        sodium_memzero(key, HAL_LINK_AUTH_KEY_BYTES);
        return HAL_E_ARG;
    }
    return HAL_OK;
}

hal_status_t hal_link_auth_key_from_hex(const char *hex, uint8_t key[HAL_LINK_AUTH_KEY_BYTES])
{
    if (hex == NULL || key == NULL) return HAL_E_ARG;
    return key_from_text(hex, strlen(hex), key);
}

hal_status_t hal_link_auth_key_from_file(const char *path, uint8_t key[HAL_LINK_AUTH_KEY_BYTES])
{
    if (path == NULL || key == NULL) return HAL_E_ARG;
    const int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) return errno == ENOENT ? HAL_E_NOT_FOUND : HAL_E_IO;
    struct stat sb;
    hal_status_t hs = HAL_OK;
    char text[256];
    size_t n = 0;
    if (fstat(fd, &sb) != 0) {
        hs = HAL_E_IO;
    } else if (!S_ISREG(sb.st_mode) || (sb.st_mode & 077) != 0) {
        hs = HAL_E_ARG;
    } else {
        for (;;) {
            const ssize_t r = read(fd, text + n, sizeof text - n);
            if (r < 0 && errno == EINTR) continue;
            if (r < 0) {
                hs = HAL_E_IO;
                break;
            }
            if (r == 0) break;
            n += (size_t)r;
            if (n == sizeof text) {
                hs = HAL_E_ARG; /* far longer than a key */
                break;
            }
        }
    }
    (void)close(fd);
    if (hs == HAL_OK) hs = key_from_text(text, n, key);
    sodium_memzero(text, sizeof text);
    return hs;
}

hal_status_t hal_link_auth_key_parse(const char *spec, uint8_t key[HAL_LINK_AUTH_KEY_BYTES])
{
    if (spec == NULL || key == NULL) return HAL_E_ARG;
    if (hal_link_auth_key_from_hex(spec, key) == HAL_OK) return HAL_OK;
    return hal_link_auth_key_from_file(spec, key);
}
