/*
 * hal/hal_link_auth.h - authenticated map messages: a hal_link decorator
 * that signs what this robot sends and refuses, on receipt, everything not
 * sent by a robot of its own fleet (libsodium; threat model and key
 * handling in docs/security.md).
 *
 * It stands in front of any hal_link backend (DDS, simulator hub, a test
 * loopback) and is itself a hal_link: the application sends and receives
 * plain codec map messages (coslam/map_msg.h) through it, unaware of it.
 *
 * Send: the datagram must be exactly one codec message (magic "CSLM", the
 * total length L at offset 8 equal to len) whose sender_id (offset 5) is
 * this robot's id. The decorator appends a trailer of
 * HAL_LINK_AUTH_TRAILER_BYTES and hands message + trailer to the inner link:
 *
 *   off  size  field (relative to L; integers little-endian)
 *     0     1  format = HAL_LINK_AUTH_FORMAT (1)
 *     1     1  key_id: which fleet key (its version), from the config
 *     2     2  sender_id (u16) = this robot's link id
 *     4     8  counter (u64): strictly increasing per sender, also across
 *              restarts: max(previous + 1, wall clock [us since 1970])
 *    12     8  stamp_us (u64): wall clock at sending [us since 1970]
 *    20    32  MAC: HMAC-SHA-512-256 (libsodium crypto_auth) under the fleet
 *              key over bytes [0, L + 20): message and trailer header
 *
 * Receive: each datagram from the inner link is checked in this order, and
 * the first failing check refuses it, counts it in that reason's counter
 * and goes on with the next datagram (until the timeout, or, unless the
 * timeout is HAL_TIMEOUT_FOREVER, after HAL_LINK_AUTH_REFUSED_PER_CALL
 * refusals in one call, so that a flood of forgeries cannot hold the
 * caller: HAL_E_TIMEOUT, the rest is taken by the next call):
 *   1. a codec message header: len >= 12, magic "CSLM"      rx_malformed
 *   2. a trailer at all: len == L                           rx_unauthenticated
 *   3. the whole trailer: len < L + 52 (incl. len < L)      rx_truncated
 *      nothing after it: len > L + 52                       rx_malformed
 *   4. format byte                                          rx_malformed
 *   5. key_id is this fleet's                               rx_wrong_key
 *   6. MAC (constant-time compare)                          rx_bad_mac
 *   7. trailer sender_id == link sender id (info.src_id)
 *      == the map message's sender_id (offset 5)            rx_sender_mismatch
 *   8. |wall clock - stamp_us| <= window_us                 rx_stale / rx_future
 *   9. counter > the last accepted counter of that sender   rx_replay
 * A datagram that passes is delivered without its trailer (len = L, the
 * plain codec message) and its counter becomes the sender's last one.
 * Checks 1-5 are cheap and come before the MAC; nothing is trusted before
 * check 6 except to decide how to refuse.
 *
 * Time: the window needs the fleet's wall clocks within window_us of each
 * other (NTP/chrony); the link's own stamps (monotonic) are not used here.
 *
 * Memory: the state is caller-owned; no heap. One datagram buffer of
 * HAL_LINK_MAX_PAYLOAD bytes serves both directions (one thread per
 * instance, hal_common.h), plus one u64 per possible sender id.
 * Time: one HMAC per datagram sent or received past check 5 (about 9 us
 * for a 4.9 KB message on a desktop x86-64).
 *
 * Return codes of the operations (through the hal_link_* wrappers):
 *  - self_id: HAL_OK (the inner link's id, read at open); HAL_E_CLOSED.
 *  - send: HAL_OK; HAL_E_ARG (not exactly one codec message, not this
 *    robot's message, too long with the trailer: each counted; or the inner
 *    link's HAL_E_ARG, e.g. dest = self); otherwise the inner link's code
 *    (HAL_E_BUSY, HAL_E_CLOSED, HAL_E_IO), counted in send_inner_failed.
 *    A refused send does not consume a counter value unless it reached the
 *    inner link.
 *  - recv: HAL_OK (authentic, info->len = L); HAL_E_OVERFLOW (authentic but
 *    longer than cap: first cap bytes, info->len = L, discarded);
 *    HAL_E_TIMEOUT (no authentic datagram within timeout_us); the inner
 *    link's HAL_E_CLOSED, HAL_E_IO, HAL_E_UNSUPPORTED. The inner link's
 *    HAL_E_OVERFLOW (datagram above HAL_LINK_MAX_PAYLOAD) is counted
 *    (rx_oversize) and skipped.
 *  - close: wipes the key (sodium_memzero) and closes the inner link.
 */
#ifndef HAL_LINK_AUTH_H
#define HAL_LINK_AUTH_H

#include <stdint.h>

#include "hal/hal_link.h"

/** Refused datagrams one receive call checks at most (each costs an HMAC). */
#define HAL_LINK_AUTH_REFUSED_PER_CALL 16u

#ifdef __cplusplus
extern "C" {
#endif

#define HAL_LINK_AUTH_KEY_BYTES 32u      /**< fleet key [bytes] */
#define HAL_LINK_AUTH_MAC_BYTES 32u      /**< HMAC-SHA-512-256 tag [bytes] */
#define HAL_LINK_AUTH_HEADER_BYTES 20u   /**< trailer before the MAC [bytes] */
#define HAL_LINK_AUTH_TRAILER_BYTES (HAL_LINK_AUTH_HEADER_BYTES + HAL_LINK_AUTH_MAC_BYTES) /**< 52 */
#define HAL_LINK_AUTH_FORMAT 1u          /**< trailer format byte */
/** Default acceptance window around the receiver's wall clock [us]. */
#define HAL_LINK_AUTH_DEFAULT_WINDOW_US 30000000u
/** Sender ids tracked for replay: map messages carry u8 sender ids. */
#define HAL_LINK_AUTH_MAX_SENDERS 256u

/** The decorator's configuration (copied by open; wipe yours afterwards). */
typedef struct {
    uint8_t key[HAL_LINK_AUTH_KEY_BYTES];  /**< the fleet key (hal_link_auth_key_parse) */
    uint8_t key_id;                        /**< version of that key, sent in the clear */
    uint64_t window_us;                    /**< 0 = HAL_LINK_AUTH_DEFAULT_WINDOW_US */
    /** Wall clock [us since 1970]; NULL = CLOCK_REALTIME. Tests inject time. */
    uint64_t (*wall_clock_us)(void *ctx);
    void *clock_ctx;
} hal_link_auth_config_t;

/** Per-instance counters: every refused datagram is in exactly one rx_
 *  reason counter; every refused send in one send_ counter. */
typedef struct {
    uint32_t sent;                /**< signed and accepted by the inner link */
    uint32_t send_not_map;        /**< not exactly one codec message (HAL_E_ARG) */
    uint32_t send_wrong_sender;   /**< its sender_id is not this robot (HAL_E_ARG) */
    uint32_t send_too_long;       /**< len + trailer > HAL_LINK_MAX_PAYLOAD (HAL_E_ARG) */
    uint32_t send_inner_failed;   /**< the inner link's send failed (its code returned) */
    uint32_t delivered;           /**< authentic datagrams returned by recv */
    uint32_t rx_overflow;         /**< of those, longer than the caller's buffer */
    uint32_t rx_malformed;        /**< no codec header, extra bytes, unknown format */
    uint32_t rx_unauthenticated;  /**< no trailer at all */
    uint32_t rx_truncated;        /**< shorter than message + trailer */
    uint32_t rx_wrong_key;        /**< another key id (other fleet or key version) */
    uint32_t rx_bad_mac;          /**< forged or modified */
    uint32_t rx_sender_mismatch;  /**< trailer, link and message sender ids differ */
    uint32_t rx_stale;            /**< stamp older than the window */
    uint32_t rx_future;           /**< stamp newer than the window */
    uint32_t rx_replay;           /**< counter not above the sender's last accepted */
    uint32_t rx_oversize;         /**< the inner link reported HAL_E_OVERFLOW */
} hal_link_auth_counters_t;

/** Instance state, caller-owned (18.2 KiB). Opaque: use the functions. */
typedef struct {
    hal_link_t link;          /**< the handle; link.backend points back here */
    hal_link_t *inner;
    int open;
    uint16_t self_id;
    uint8_t key[HAL_LINK_AUTH_KEY_BYTES];
    uint8_t key_id;
    uint64_t window_us;
    uint64_t (*wall_clock_us)(void *ctx);
    void *clock_ctx;
    uint64_t tx_counter;                                 /**< last counter sent */
    uint64_t last_counter[HAL_LINK_AUTH_MAX_SENDERS];    /**< 0: none accepted yet */
    hal_link_auth_counters_t ctr;
    uint8_t buf[HAL_LINK_MAX_PAYLOAD];
} hal_link_auth_t;

/**
 * Put the decorator in front of `inner` (which must stay valid until
 * close), with state in the caller-owned *st. Reads the inner link's id,
 * which must fit a map message sender id (<= 254).
 * Returns &st->link, or NULL if an argument is NULL, libsodium cannot be
 * initialised (sodium_init), or the inner link's id is not readable or
 * above 254. Never blocks. On NULL nothing is kept (the key is not copied).
 */
hal_link_t *hal_link_auth_open(hal_link_t *inner, const hal_link_auth_config_t *cfg, hal_link_auth_t *st);

/** The instance's counters (never NULL for a non-NULL st). */
const hal_link_auth_counters_t *hal_link_auth_counters(const hal_link_auth_t *st);

/**
 * Parse a fleet key given as exactly 64 hexadecimal digits (leading and
 * trailing white space allowed) into key. Returns HAL_OK or HAL_E_ARG
 * (NULL, wrong length, non-hex). On error key is zeroed. The text is never
 * logged or printed by this module.
 */
hal_status_t hal_link_auth_key_from_hex(const char *hex, uint8_t key[HAL_LINK_AUTH_KEY_BYTES]);

/**
 * Read a fleet key file: 64 hex digits, white space around them allowed.
 * The file must not be readable or writable by group or others (as ssh
 * requires of private keys): mode & 077 != 0 is refused.
 * Returns HAL_OK; HAL_E_ARG (NULL, bad content, permissions too open, not
 * a regular file); HAL_E_NOT_FOUND (no such file); HAL_E_IO. Stack copies
 * of the key material are wiped (sodium_memzero) before return.
 */
hal_status_t hal_link_auth_key_from_file(const char *path, uint8_t key[HAL_LINK_AUTH_KEY_BYTES]);

/**
 * The config file's key setting: 64 hex digits are the key itself, any
 * other text is the path of a key file (hal_link_auth_key_from_file).
 * Returns the code of the function it calls.
 */
hal_status_t hal_link_auth_key_parse(const char *spec, uint8_t key[HAL_LINK_AUTH_KEY_BYTES]);

#ifdef __cplusplus
}
#endif

#endif /* HAL_LINK_AUTH_H */
