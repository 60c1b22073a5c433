/*
 * robot_snapshot.h - map snapshots of coslam-robot: the exported map
 * estimate and the pose, kept in two generations through hal_storage, so
 * that a restarted robot goes on with its map.
 *
 * Format (version 1). Little-endian, written byte by byte, no padding; f64
 * is the IEEE-754 binary64 bit pattern:
 *
 *   off  size  field
 *     0     4  magic "CSNP"
 *     4     2  u16 version = ROBOT_SNAPSHOT_VERSION (1)
 *     6     2  u16 header length = 40
 *     8     4  u32 payload length P = 170 + 73 n
 *    12     8  u64 sequence number (grows by one per save, over both files)
 *    20     1  u8  robot id that saved it
 *    21     1  u8  filter kind (slam_filter_kind_t; informative: a map
 *                  estimate is the filters' common format)
 *    22     1  u8  flags: bit 0 = written at a clean stop (the final
 *                  snapshot: every map message sent is in msg_seq); the
 *                  other bits 0 (readers ignore them)
 *    23     1  u8  reserved, 0
 *    24     4  u32 last map-message sequence number sent (meeting)
 *    28     8  u64 save time, seconds since 1970 (for people; never used)
 *    36     4  u32 CRC-32 (coslam/crc32.h) of bytes [0, 36)
 *    40     P  payload:
 *                +0   3 f64  pose x [m], y [m], theta [rad] (map frame)
 *               +24   9 f64  pose covariance, row-major (all nine entries)
 *               +96   2 u16  n = landmarks, <= COSLAM_MAX_MSG_LANDMARKS
 *               +98  73 n    landmarks in the map message's record layout
 *                            (coslam/map_msg.h): mean x, y; cov xx, xy, yy;
 *                            cov_rel xx, xy, yy (f64); id u32; n_obs u16;
 *                            src_mask u16; signature u8
 *            +98+73n  72     reserved (zero) for later fields
 *  40+P     4  u32 CRC-32 of the payload
 *
 * So P = 170 + 73 n (the 72 reserved bytes keep room for a grid reference or
 * counters without a new version). Decoding checks, in order: length,
 * magic, version, header length, header CRC, payload length against the
 * buffer, payload CRC, n against this build's capacity and against P, then
 * the fields (every f64 finite, the pose covariance symmetric and positive
 * semi-definite (cov3_is_psd), landmark covariances positive definite,
 * landmark id non-zero). The storage backend (hal/linux) adds its own
 * header and CRC and replaces the file atomically (temporary file, fsync,
 * rename, fsync of the directory); this format makes a snapshot checkable
 * on its own (copied off the robot, read by a test) and carries the
 * sequence number.
 *
 * Two generations: snapshots alternate between the blobs "snapshot.a" and
 * "snapshot.b"; a save overwrites the older one. Loading reads both, keeps
 * the valid one with the larger sequence number and reports every
 * unreadable or corrupt one by name: a damaged newest one falls back to
 * the older generation.
 *
 * No heap: robot_snapshots_t holds the encode buffer
 * (ROBOT_SNAPSHOT_MAX_BYTES). One thread: the write itself may go to
 * another (robot_snapshots_prepare, robot_snapshot_writer.h,
 * robot_snapshots_commit), these functions are the control loop's.
 */
#ifndef COSLAM_PORT_ROBOT_SNAPSHOT_H
#define COSLAM_PORT_ROBOT_SNAPSHOT_H

#include <stdint.h>
#include <stdio.h>

#include "coslam/map_estimate.h"
#include "coslam/status.h"
#include "hal/hal_storage.h"

#ifdef __cplusplus
extern "C" {
#endif

#define ROBOT_SNAPSHOT_VERSION 1u
#define ROBOT_SNAPSHOT_HEADER_BYTES 40u
#define ROBOT_SNAPSHOT_LANDMARK_BYTES 73u
#define ROBOT_SNAPSHOT_RESERVED_BYTES 72u
/** Payload of n landmarks [bytes]. */
#define ROBOT_SNAPSHOT_PAYLOAD_BYTES(n) \
    (98u + ROBOT_SNAPSHOT_LANDMARK_BYTES * (size_t)(n) + ROBOT_SNAPSHOT_RESERVED_BYTES)
/** Whole snapshot of n landmarks [bytes]. */
#define ROBOT_SNAPSHOT_BYTES(n) (ROBOT_SNAPSHOT_HEADER_BYTES + ROBOT_SNAPSHOT_PAYLOAD_BYTES(n) + 4u)
/** Largest snapshot of this build [bytes]. */
#define ROBOT_SNAPSHOT_MAX_BYTES ROBOT_SNAPSHOT_BYTES(COSLAM_MAX_MSG_LANDMARKS)

/** A robot restored from a snapshot not written at a clean stop (a crash,
 *  a power cut: maps may have been sent after it, with sequence numbers
 *  beyond msg_seq that the peers remember) continues its map-message
 *  sequence numbers this far ahead, so that its first messages are not
 *  refused as replays. Covers 2,048 sends since the last periodic snapshot
 *  (68 a second at the default 30 s), and stays far below the jump a peer
 *  accepts (MERGE_SEQ_MAX_JUMP, 65,536). */
#define ROBOT_SNAPSHOT_SEQ_MARGIN 2048u

/** The two generations. */
#define ROBOT_SNAPSHOT_NAME_A "snapshot.a"
#define ROBOT_SNAPSHOT_NAME_B "snapshot.b"

/** A generation whose write failed is tried again after this many saves
 *  into the other one (robot_snapshots_prepare). */
#define ROBOT_SNAPSHOT_RETRY_FAILED_SLOT 8u

typedef struct {
    uint64_t seq;            /**< sequence number (set by robot_snapshots_save) */
    uint8_t robot_id;
    uint8_t filter_kind;
    uint32_t msg_seq;        /**< last map-message sequence number sent */
    uint8_t clean_stop;      /**< written at a clean stop (flags bit 0): nothing was sent after it */
    uint64_t saved_unix_s;   /**< save time (informative) */
    map_estimate_t map;      /**< exported map with the pose */
} robot_snapshot_t;

/** Encode into buf (cap bytes). COSLAM_OK (*len set); COSLAM_E_CAPACITY
 *  (cap too small); COSLAM_E_ARG (NULL, more landmarks than
 *  COSLAM_MAX_MSG_LANDMARKS). Never fails on content. O(n). */
coslam_status_t robot_snapshot_encode(const robot_snapshot_t *s, uint8_t *buf, size_t cap, size_t *len);

/**
 * Decode and check (header comment). COSLAM_OK; COSLAM_E_MSG_TRUNCATED
 * (shorter than its lengths say), COSLAM_E_MSG_MAGIC, COSLAM_E_MSG_VERSION,
 * COSLAM_E_MSG_LENGTH (lengths inconsistent, trailing bytes), COSLAM_E_MSG_CRC
 * (header or payload CRC), COSLAM_E_MSG_COUNT (more landmarks than this
 * build holds), COSLAM_E_MSG_NONFINITE, COSLAM_E_MSG_COVARIANCE,
 * COSLAM_E_MSG_FIELD (landmark id 0); COSLAM_E_ARG (NULL). *out is only
 * written on COSLAM_OK. O(n).
 */
coslam_status_t robot_snapshot_decode(const uint8_t *buf, size_t len, robot_snapshot_t *out);

/** The two generations in one store. */
typedef struct {
    hal_storage_t *storage;   /**< NULL: no storage (saves fail with COSLAM_E_UNSUPPORTED) */
    int newest;               /**< slot of the newest valid snapshot: 0 (a), 1 (b), -1 none */
    int failed_slot;          /**< the slot whose last write failed (-1 none): saves go to the
                                   other one, so one unwritable blob never stops every save */
    uint32_t failed_slot_skips; /**< saves since that failure: the failed slot is tried again
                                   every ROBOT_SNAPSHOT_RETRY_FAILED_SLOT saves */
    uint64_t newest_seq;      /**< its sequence number */
    uint32_t saves;
    uint32_t save_failures;
    uint32_t corrupt_found;   /**< corrupt or unreadable generations found by loads */
    hal_status_t last_write;  /**< status of the last storage write */
    uint32_t busy_skips;      /**< periodic snapshots not taken: the last one's write still ran
                                   (robot_snapshot_writer.h; set by the caller) */
    uint64_t write_max_us;    /**< longest storage write seen (set by the caller) */
    uint32_t no_writer_skips; /**< snapshots not written: the writer thread was not running
                                   (robot_snapshot_writer.h; set by the caller) */
    uint32_t writer_start_failures; /**< attempts to start the writer thread that failed (set by
                                         the caller) */
    uint32_t final_timeouts;  /**< the stop's snapshot jobs given up: not returned within the
                                   stop's wait, no final snapshot (set by the caller) */
    uint32_t start_read_timeouts; /**< start-up reads not returned within the start's wait: a
                                       new map begun (set by the caller) */
    uint8_t buf[ROBOT_SNAPSHOT_MAX_BYTES];
} robot_snapshots_t;

/** Bind to a store (may be NULL for now: robot_snapshots_set_storage). */
void robot_snapshots_init(robot_snapshots_t *s, hal_storage_t *storage);

/** Use another store (storage came up or went away); the generation
 *  bookkeeping is kept. */
void robot_snapshots_set_storage(robot_snapshots_t *s, hal_storage_t *storage);

/**
 * Read both generations; the valid one with the larger sequence number
 * goes to *out. Each generation that exists but cannot be read or fails
 * its checks is reported on `log` (may be NULL) by name with the reason,
 * and counted. Returns COSLAM_OK (*out holds the newest; *name, if not
 * NULL, its blob name); COSLAM_E_EMPTY (no valid snapshot); COSLAM_E_ARG
 * (NULL); COSLAM_E_UNSUPPORTED (no storage). O(2 reads).
 */
coslam_status_t robot_snapshots_load(robot_snapshots_t *s, robot_snapshot_t *out, const char **name, FILE *log);

/** What robot_snapshots_read_newest found (its bookkeeping, not yet in s). */
typedef struct {
    int slot;              /**< 0 (a), 1 (b): the newest valid generation; -1 none */
    uint64_t seq;          /**< its sequence number */
    uint32_t corrupt;      /**< generations that exist but could not be used (reported) */
} robot_snapshot_found_t;

/**
 * robot_snapshots_load in two halves, so that the reads can run on the
 * writer thread (robot_snapshot_writer.h) when the storage comes back:
 * _read_newest does the storage reads and checks; it uses s->buf and reads
 * s->storage, and writes nothing else of s (the status line reads the
 * rest meanwhile); its return and *out as robot_snapshots_load's, *found
 * what it found. _found (the loop, afterwards) makes that the generation
 * bookkeeping (newest, newest_seq, corrupt_found) and returns the newest
 * blob's name (NULL: none).
 */
coslam_status_t robot_snapshots_read_newest(robot_snapshots_t *s, robot_snapshot_t *out, robot_snapshot_found_t *found,
                                            FILE *log);
const char *robot_snapshots_found(robot_snapshots_t *s, const robot_snapshot_found_t *found);

/** A save in two halves, for a write that runs elsewhere (a writer
 *  thread, robot_snapshot_writer.h): which blob, which sequence number,
 *  how many bytes of robot_snapshots_t.buf. */
typedef struct {
    int slot;              /**< 0 (a) or 1 (b): the older generation */
    const char *name;      /**< its blob name */
    uint64_t seq;          /**< newest_seq + 1 */
    size_t len;            /**< encoded bytes in buf */
} robot_snapshot_job_t;

/**
 * First half of robot_snapshots_save: snap->seq = newest_seq + 1, encoded
 * into s->buf, *job says where it goes. Nothing is written and the
 * generation bookkeeping is unchanged until robot_snapshots_commit; prepare
 * no other save before that (it would pick the same blob). Returns
 * COSLAM_OK; COSLAM_E_ARG (NULL, too many landmarks to encode);
 * COSLAM_E_UNSUPPORTED (no storage). Failures are counted in save_failures.
 */
coslam_status_t robot_snapshots_prepare(robot_snapshots_t *s, robot_snapshot_t *snap, robot_snapshot_job_t *job);

/**
 * Second half: the storage write of *job ended with `written`. HAL_OK makes
 * it the newest generation (saves counted); anything else is counted in
 * save_failures and leaves the generations as they were (the write is an
 * atomic replace). last_write = written. Returns what robot_snapshots_save
 * would: COSLAM_OK; COSLAM_E_CAPACITY (HAL_E_OVERFLOW: the medium is full);
 * COSLAM_E_UNSUPPORTED (HAL_E_UNSUPPORTED: the storage cannot write, e.g. a
 * reader or the null backend); COSLAM_E_ARG (NULL, bad slot, HAL_E_ARG);
 * COSLAM_E_STORAGE (any other failed write: HAL_E_IO, HAL_E_CLOSED,
 * HAL_E_BUSY, ...; last_write says which).
 */
coslam_status_t robot_snapshots_commit(robot_snapshots_t *s, const robot_snapshot_job_t *job, hal_status_t written);

/**
 * Save *snap as the next generation (prepare, write, commit in this call): snap->seq = newest_seq + 1, written
 * over the older blob (atomic replace by the storage backend). Returns
 * COSLAM_OK (*name, if not NULL, the blob written); COSLAM_E_ARG (NULL, or
 * too many landmarks to encode); COSLAM_E_CAPACITY (the medium is full:
 * HAL_E_OVERFLOW); COSLAM_E_UNSUPPORTED (no storage, or one that cannot
 * write); COSLAM_E_STORAGE (the write failed: I/O, closed, ...; as
 * robot_snapshots_commit). last_write holds the HAL status of the write. Failures are
 * counted in save_failures; the previous generations stay as they were.
 */
coslam_status_t robot_snapshots_save(robot_snapshots_t *s, robot_snapshot_t *snap, const char **name);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_PORT_ROBOT_SNAPSHOT_H */
