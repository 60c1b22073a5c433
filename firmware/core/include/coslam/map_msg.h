/*
 * coslam/map_msg.h - the map message two robots exchange when they meet
 * (../DESIGN "The map message"), and its byte codec for storage, tests and
 * any byte-oriented link.
 *
 * A message carries the sender's map estimate (map_estimate.h: pose, 3x3
 * pose covariance, landmarks as marginal Gaussians) and, when it has one,
 * the sender's range-bearing sighting of the receiver: the relative
 * measurement the receiver needs to put the sender's map into its own frame.
 *
 * Wire format (version 2; version 1 had 49-byte landmark records without
 * cov_rel and is refused with COSLAM_E_MSG_VERSION). Every multi-byte field
 * is little-endian and written byte by byte; f64 is an IEEE-754 binary64
 * sent as its 64-bit pattern, u64/u32/u16 are unsigned integers. There is
 * no padding.
 *
 *   off   size  type  field
 *   ----  ----  ----  ---------------------------------------------------------
 *     0     4   u8[4] magic "CSLM" = 0x43 0x53 0x4C 0x4D
 *     4     1   u8    version = MAP_MSG_VERSION (2)
 *     5     1   u8    sender_id    < COSLAM_MAX_ROBOTS
 *     6     1   u8    receiver_id  < COSLAM_MAX_ROBOTS, != sender_id, or
 *                                  MAP_MSG_BROADCAST (0xFF)
 *     7     1   u8    flags: bit 0 = sighting valid; bits 1..7 must be 0
 *     8     4   u32   total length L in bytes, CRC included: L = 142 + 73 n
 *    12     4   u32   seq
 *    16     8   u64   stamp_us
 *    24     8   f64   pose.x [m]
 *    32     8   f64   pose.y [m]
 *    40     8   f64   pose.theta [rad], in [-pi, pi]
 *    48     8   f64   pose_cov m[0][0] (xx)  [m^2]
 *    56     8   f64   pose_cov m[0][1] (xy)  [m^2]      the upper triangle
 *    64     8   f64   pose_cov m[0][2] (xt)  [m rad]    only: the lower one
 *    72     8   f64   pose_cov m[1][1] (yy)  [m^2]      is its mirror, so an
 *    80     8   f64   pose_cov m[1][2] (yt)  [m rad]    asymmetric matrix
 *    88     8   f64   pose_cov m[2][2] (tt)  [rad^2]    cannot be sent
 *    96     8   f64   sighting.range_m           all five sighting fields
 *   104     8   f64   sighting.bearing_rad       are zero bytes when flag
 *   112     8   f64   sighting.range_var_m2      bit 0 is clear
 *   120     8   f64   sighting.bearing_var_rad2
 *   128     8   u64   sighting.stamp_us
 *   136     2   u16   n = number of landmarks <= COSLAM_MAX_MSG_LANDMARKS
 *   138   73 n        landmarks, each (offsets relative to 138 + 73 i):
 *                       +0   f64  mean.x [m]            map frame
 *                       +8   f64  mean.y [m]
 *                      +16   f64  cov.xx [m^2]          map frame
 *                      +24   f64  cov.xy [m^2]
 *                      +32   f64  cov.yy [m^2]
 *                      +40   f64  cov_rel.xx [m^2]      relative to the
 *                      +48   f64  cov_rel.xy [m^2]      robot, robot body
 *                      +56   f64  cov_rel.yy [m^2]      frame (map_estimate.h)
 *                      +64   u32  id (!= 0)
 *                      +68   u16  n_obs
 *                      +70   u16  src_mask (!= 0, bits < COSLAM_MAX_ROBOTS)
 *                      +72   u8   signature
 *  138+73n  4   u32   CRC-32 (crc32.h: IEEE 802.3, reflected, init and final
 *                     XOR 0xFFFFFFFF) of bytes [0, 138 + 73 n)
 *
 * Validity (checked by map_msg_validate, by the encoder before it writes and
 * by the decoder before it writes *out; all three share one set of checks):
 *   - every f64 finite (COSLAM_E_MSG_NONFINITE);
 *   - pose covariance symmetric (bit-identical mirror entries) and positive
 *     definite (Cholesky), both covariances of each landmark (cov and
 *     cov_rel) positive definite (xx > 0, yy > 0, xx yy - xy^2 > 0),
 *     sighting variances > 0
 *     (COSLAM_E_MSG_COVARIANCE);
 *   - ids, flags, theta and bearing in [-pi, pi], range_m >= 0, landmark id
 *     != 0 ("no identity" in the filters), src_mask non-zero and inside the
 *     team, no valid sighting in a broadcast (COSLAM_E_MSG_FIELD);
 *   - landmark ids pairwise distinct (COSLAM_E_MSG_DUPLICATE).
 * Landmarks may come in any order; the filters export them sorted by id,
 * which the duplicate check detects in O(n) (else O(n^2) comparisons).
 *
 * Decoder rejection order (the first failing check decides the code):
 *   1. len < 12 (magic, version, length unreadable)   COSLAM_E_MSG_TRUNCATED
 *   2. magic != "CSLM"                                 COSLAM_E_MSG_MAGIC
 *   3. version != MAP_MSG_VERSION                      COSLAM_E_MSG_VERSION
 *   4. len < L (the message was cut short)             COSLAM_E_MSG_TRUNCATED
 *   5. len > L, or L < 142                             COSLAM_E_MSG_LENGTH
 *   6. CRC mismatch                                    COSLAM_E_MSG_CRC
 *   7. n > COSLAM_MAX_MSG_LANDMARKS                    COSLAM_E_MSG_COUNT
 *   8. L != 142 + 73 n                                 COSLAM_E_MSG_LENGTH
 *   9. field checks, group by group in wire order, each group checking
 *      NONFINITE, then FIELD, then COVARIANCE: header (flags, ids), pose,
 *      sighting (a cleared flag with non-zero sighting bytes is FIELD),
 *      landmarks one by one; then DUPLICATE over all landmark ids.
 * The CRC protects against corruption, not against a malicious sender: the
 * field checks are what keeps bad numbers out of the filter.
 */
#ifndef COSLAM_MAP_MSG_H
#define COSLAM_MAP_MSG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "coslam/config.h"
#include "coslam/map_estimate.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Protocol version this codec writes and accepts. */
#define MAP_MSG_VERSION 2U
/** receiver_id of a message addressed to every robot (carries no sighting). */
#define MAP_MSG_BROADCAST 0xFFU

/** Fixed part before the landmarks [bytes]. */
#define MAP_MSG_HEADER_BYTES 138U
/** One landmark on the wire [bytes]. */
#define MAP_MSG_LANDMARK_BYTES 73U
/** The trailing CRC-32 [bytes]. */
#define MAP_MSG_CRC_BYTES 4U
/** Encoded size of a message with n landmarks [bytes]. */
#define MAP_MSG_BYTES(n) (MAP_MSG_HEADER_BYTES + MAP_MSG_LANDMARK_BYTES * (size_t)(n) + MAP_MSG_CRC_BYTES)
/** Smallest message (no landmark): 142 bytes. */
#define MAP_MSG_MIN_BYTES MAP_MSG_BYTES(0U)
/** Largest message this build encodes or accepts: 4814 bytes for 64 landmarks,
 *  18830 for 256. */
#define MAP_MSG_MAX_BYTES MAP_MSG_BYTES(COSLAM_MAX_MSG_LANDMARKS)

/** The sender's sighting of the receiver (a robot-robot range-bearing measurement). */
typedef struct {
    bool valid;               /**< false: no sighting; the other fields are ignored
                                   on encode and decoded as zeros */
    double range_m;           /**< [m], >= 0 */
    double bearing_rad;       /**< [rad] in the sender's body frame, in [-pi, pi] */
    double range_var_m2;      /**< variance of range_m [m^2], > 0 */
    double bearing_var_rad2;  /**< variance of bearing_rad [rad^2], > 0 */
    uint64_t stamp_us;        /**< when it was taken, sender's clock [us] */
} map_msg_sighting_t;

/** One map message. sizeof is dominated by map (sizeof(map_landmark_t) = 80 bytes per
 *  landmark on x86-64 and the ARM EABI). */
typedef struct {
    uint8_t version;              /**< MAP_MSG_VERSION */
    uint8_t sender_id;            /**< < COSLAM_MAX_ROBOTS */
    uint8_t receiver_id;          /**< < COSLAM_MAX_ROBOTS and != sender_id, or MAP_MSG_BROADCAST */
    uint32_t seq;                 /**< sender's message counter (replay detection is the merge's job) */
    uint64_t stamp_us;            /**< time of the map estimate, sender's clock [us] */
    map_estimate_t map;           /**< the sender's map, in the sender's map frame */
    map_msg_sighting_t sighting;  /**< the sender's sighting of the receiver */
} map_msg_t;

/**
 * Reset a message to an empty broadcast: every field zero, version =
 * MAP_MSG_VERSION, receiver_id = MAP_MSG_BROADCAST, no sighting, no landmark.
 * The pose covariance is left zero, so the caller must fill it (a zero
 * covariance does not validate). O(sizeof(map_msg_t)).
 */
void map_msg_init(map_msg_t *msg);

/**
 * Check a message struct against every rule the decoder applies to the
 * fields (see the header comment): use it on a map_msg_t that arrived by
 * another path than map_msg_decode (for example as a DDS sample).
 *
 * @return COSLAM_OK; COSLAM_E_ARG if msg is NULL; COSLAM_E_MSG_VERSION,
 *         COSLAM_E_MSG_COUNT (n_landmarks above COSLAM_MAX_MSG_LANDMARKS),
 *         COSLAM_E_MSG_FIELD, COSLAM_E_MSG_NONFINITE,
 *         COSLAM_E_MSG_COVARIANCE (includes an asymmetric pose covariance)
 *         or COSLAM_E_MSG_DUPLICATE.
 * Time O(n) for landmarks sorted by id, O(n^2) id comparisons otherwise;
 * stack about 330 bytes on a Cortex-M7 (gcc -O2, most of it in the 3x3
 * Cholesky); reads msg only.
 */
coslam_status_t map_msg_validate(const map_msg_t *msg);

/**
 * Encoded size of msg [bytes] (MAP_MSG_BYTES(msg->map.n_landmarks)), or 0 if
 * msg is NULL or n_landmarks exceeds COSLAM_MAX_MSG_LANDMARKS. O(1).
 */
size_t map_msg_encoded_size(const map_msg_t *msg);

/**
 * Serialise a message into the caller's buffer in the layout above.
 *
 * The message is validated first (map_msg_validate), so a message this
 * function encodes is one map_msg_decode accepts, and decoding returns it
 * bit for bit (an invalid sighting's ignored fields come back as zeros).
 *
 * @param msg  read only.
 * @param buf  caller-owned output of cap bytes; MAP_MSG_MAX_BYTES always
 *             suffices. On error its content is unspecified (a prefix may
 *             have been written); no byte at or beyond buf + cap is touched.
 * @param cap  capacity of buf [bytes].
 * @param len  out: bytes written on success, 0 on error.
 * @return COSLAM_OK; COSLAM_E_ARG for a NULL pointer; any code of
 *         map_msg_validate; COSLAM_E_CAPACITY if cap is below the encoded
 *         size (the codec is stateless: counting such events is the
 *         caller's).
 * Time O(n) (plus the O(n^2) duplicate check for unsorted ids): about
 * 21 us for 64 landmarks (4814 bytes) on a desktop x86-64; stack about
 * 400 bytes on a Cortex-M7; never blocks.
 */
coslam_status_t map_msg_encode(const map_msg_t *msg, uint8_t *buf, size_t cap, size_t *len);

/**
 * Parse and validate one whole message of exactly len bytes.
 *
 * Everything is validated before anything is written: on error *out is left
 * untouched, so a rejected message is never partially applied. On success
 * the header fields, the sighting and out->map.lm[0 .. n) are written;
 * out->map.lm[n ..] are left as they were.
 *
 * @param buf  read only, len bytes; no byte outside [buf, buf + len) is read.
 * @param len  the size of the message as received [bytes].
 * @param out  caller-owned result.
 * @return COSLAM_OK; COSLAM_E_ARG for a NULL pointer; otherwise the code of
 *         the first failing check in the order listed in the header comment
 *         (TRUNCATED, MAGIC, VERSION, LENGTH, CRC, COUNT, FIELD, NONFINITE,
 *         COVARIANCE, DUPLICATE).
 * Time O(len) (plus O(n^2) id comparisons when ids are not sorted): about
 * 22 us for 64 landmarks (4814 bytes) on a desktop x86-64, 26 us with
 * unsorted ids; stack about 650 bytes on a Cortex-M7 (gcc -O2); never
 * blocks.
 */
coslam_status_t map_msg_decode(const uint8_t *buf, size_t len, map_msg_t *out);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_MAP_MSG_H */
