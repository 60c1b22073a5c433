/*
 * coslam/status.h - the one status enum of the firmware, and the assert hook.
 *
 * Convention: 0 is success, every error is negative and named. Expected
 * conditions (bad input, full pool, rejected message) return a code; broken
 * invariants (a NULL state pointer, a corrupted index) hit COSLAM_ASSERT,
 * which the integrator may redefine (default: the C library's assert, which
 * compiles out under NDEBUG).
 */
#ifndef COSLAM_STATUS_H
#define COSLAM_STATUS_H

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    COSLAM_OK = 0,
    COSLAM_E_ARG = -1,          /**< argument out of its documented domain */
    COSLAM_E_CAPACITY = -2,     /**< a fixed-size pool is full (counter bumped) */
    COSLAM_E_NUMERIC = -3,      /**< NaN/Inf input or a result that is not finite */
    COSLAM_E_NOT_PD = -4,       /**< a covariance is not positive definite */
    COSLAM_E_EMPTY = -5,        /**< nothing to do / nothing to report */
    COSLAM_E_DEGENERATE = -6,   /**< geometry with no unique answer */
    COSLAM_E_STALE = -7,        /**< inputs too far apart in time */
    /* map message codec (map_msg.h) */
    COSLAM_E_MSG_TRUNCATED = -20,
    COSLAM_E_MSG_MAGIC = -21,
    COSLAM_E_MSG_VERSION = -22,
    COSLAM_E_MSG_LENGTH = -23,
    COSLAM_E_MSG_CRC = -24,
    COSLAM_E_MSG_COUNT = -25,
    COSLAM_E_MSG_NONFINITE = -26,
    COSLAM_E_MSG_COVARIANCE = -27,
    COSLAM_E_MSG_FIELD = -28,
    COSLAM_E_MSG_DUPLICATE = -29,
    /* merge (map_merge.h) */
    COSLAM_E_MERGE_SELF = -40,
    COSLAM_E_MERGE_STALE = -41,
    COSLAM_E_MERGE_REPLAY = -42,
    COSLAM_E_MERGE_DISAGREE = -43, /**< the two maps disagree where both have looked: merge refused */
    COSLAM_E_MERGE_RANGE = -44,    /**< the two mutual range sightings disagree: merge refused */
    COSLAM_E_MERGE_IMPLAUSIBLE = -45, /**< the message holds values no robot can produce: merge refused */
    COSLAM_E_MERGE_BUSY = -46,     /**< a merge in parts is still due (map_merge.h): finish it first */
    COSLAM_E_MERGE_PENDING = -47,  /**< the merge's check waits for the own export in parts: its
                                        outcome comes later; or an input an EKF-SLAM merge in parts
                                        holds, applied when it is done (app/slam_filter.h) */
    COSLAM_E_MERGE_LOST = -48,     /**< the receiver places none of the own landmarks the merge
                                        pairs (lost in its own map): merge refused (map_merge.h
                                        lost_sd_factor) */
    /* laser range finder driver (urg_scip2.h) */
    COSLAM_E_URG_TIMEOUT = -60,   /**< no reply / reply stopped arriving within the timeout */
    COSLAM_E_URG_IO = -61,        /**< the serial HAL reported an error (closed, I/O) */
    COSLAM_E_URG_CHECKSUM = -62,  /**< a reply line failed its SCIP sum check */
    COSLAM_E_URG_LINE = -63,      /**< a reply line has the wrong length or is missing */
    COSLAM_E_URG_GARBAGE = -64,   /**< bytes that cannot be SCIP (non-ASCII, overlong line) */
    COSLAM_E_URG_ECHO = -65,      /**< the reply does not echo the command sent */
    COSLAM_E_URG_STATUS = -66,    /**< the sensor answered with an error status */
    COSLAM_E_URG_FIELD = -67,     /**< a VV/PP/II field is missing or unparsable */
    /* CAN drive driver (firmware/drivers/cia402) */
    COSLAM_E_DRIVE_TIMEOUT = -70,  /**< a drive did not answer in time (SDO, boot-up) */
    COSLAM_E_DRIVE_ABORT = -71,    /**< the drive aborted an SDO transfer (abort code kept) */
    COSLAM_E_DRIVE_FAULT = -72,    /**< a drive fault is latched; the base is stopped */
    COSLAM_E_DRIVE_BUS = -73,      /**< the CAN HAL reported an error (HAL status kept) */
    COSLAM_E_DRIVE_STATE = -74,    /**< not allowed now (busy, not started, not enabled) */
    COSLAM_E_DRIVE_PROTOCOL = -75, /**< a malformed or unexpected CANopen frame */
    /* robot app (firmware/app) */
    COSLAM_E_LINK = -80,           /**< the inter-robot link refused or failed a datagram */
    COSLAM_E_STORAGE = -81,        /**< the storage failed a write or a read (I/O, closed, busy);
                                        the HAL status says which (a full medium is E_CAPACITY) */
    COSLAM_E_UNSUPPORTED = -90, /**< feature or hardware not available */
} coslam_status_t;

/** A short, static, human-readable name for a status ("E_CAPACITY", ...). */
const char *coslam_status_str(coslam_status_t status);

#ifndef COSLAM_ASSERT
#include <assert.h>
#define COSLAM_ASSERT(x) assert(x)
#endif

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_STATUS_H */
