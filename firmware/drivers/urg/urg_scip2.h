/*
 * urg/urg_scip2.h - Hokuyo URG laser range finder driver, SCIP 2.0 protocol.
 *
 * Talks to the sensor only through a hal_serial_t (USB-ACM or RS-232 on the
 * robot, the URG emulator in the simulator). No heap, no globals: the caller
 * owns the urg_scip2_t state and every output struct. One instance per
 * sensor; an instance is used by one thread at a time.
 *
 * Protocol summary (details and sources in docs/urg.md):
 *  - Command: ASCII, "<2-letter code><parameters>LF". The reply is a message:
 *      echo of the command                     LF
 *      status (2 chars) + sum (1 char)         LF
 *      body lines, each "<payload><sum>"       LF   (per command)
 *      empty line                              LF   (end of message)
 *  - Sum of a line = low 6 bits of the byte sum of the payload, + 0x30.
 *    In VV/PP/II lines "<field>;<sum>" the ';' is not summed.
 *  - Scan data ("MD"/"GD", 3-character encoding): the value list is cut into
 *    lines of 64 data characters (the last one shorter), each followed by its
 *    sum; the lines are joined, then every 3 characters give one 18-bit value
 *    ((c0-0x30)<<12 | (c1-0x30)<<6 | (c2-0x30)). A value can straddle lines.
 *  - Time stamp: 4-character encoding (24 bits) of the sensor's 1 ms timer,
 *    which wraps every 2^24 ms (4 h 39 min). The driver unwraps it into a
 *    64-bit monotonic stamp_us.
 *  - Readings below DMIN (20 mm on the URG-04LX) are error codes, not ranges.
 *
 * Errors and recovery: a reply line that fails its sum, has the wrong length,
 * holds non-SCIP bytes, or stops arriving mid-message drops that reply (the
 * call returns the named COSLAM_E_URG_* code and bumps the matching counter in
 * urg_scip2_stats_t). The driver then resynchronises: the next call first
 * discards bytes up to and including the next empty line (the end of the
 * broken message), so the following message parses normally.
 *
 * Timeouts: the driver has no clock. Every wait is one hal_serial_read call
 * with a timeout. Commands (set-up, GD, QT): the first byte of a reply waits
 * at most config.reply_timeout_us, and once a message has begun each further
 * wait is bounded by config.byte_timeout_us, so a command blocks at most
 * about reply_timeout + (number of chunks) * byte_timeout.
 * Scans of a running MD (urg_scip2_read_scan, called from a control loop
 * with timeout_us 0) never wait inside a message: the call takes what the
 * port holds and decodes a scan only once its whole message is in the
 * receive buffer. (With timeout_us > 0 each read may wait that long, and
 * a message arriving in pieces keeps the call reading until it is in.) A message
 * still arriving (a 115,200 baud line carries a URG-04LX scan in about
 * 190 ms) stays buffered for the next call, which returns
 * COSLAM_E_URG_TIMEOUT meanwhile, not counted. A message that breaks off
 * and never ends runs into the next one: the two fail as one reply (counted
 * once, by what the parse meets, or as garbage when the two overflow the
 * buffer) and the driver resynchronises after them;
 * a sensor gone silent is for the caller's clock to notice.
 * The wait for a whole message resumes where the last read left off, so a
 * message costs O(its length) however small the reads are (one byte per
 * read from a USB-serial adapter included); urg_scip2_rx_search_bytes()
 * counts the bytes it looked at.
 *
 * Memory: sizeof(urg_scip2_t) is about URG_SCIP2_RX_CAP + 0.4 KB (3.8 KB
 * with COSLAM_MAX_SCAN_POINTS 1081); sizeof(urg_scip2_scan_t) is
 * 4 * COSLAM_MAX_SCAN_POINTS + 32 bytes. No call allocates.
 */
#ifndef URG_SCIP2_H
#define URG_SCIP2_H

#include <stddef.h>
#include <stdint.h>

#include "coslam/config.h"
#include "coslam/status.h"
#include "hal/hal_serial.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Longest reply line accepted, payload + sum, without the LF [bytes].
 *  The longest URG-04LX line (II "SCSP:...;s") is about 50 bytes. */
#define URG_SCIP2_LINE_MAX 128
/** Data characters per scan-data line (SCIP 2.0: 64). */
#define URG_SCIP2_DATA_LINE_CHARS 64
/** The longest MD message [bytes]: echo (15 + LF), status (3 + LF), time
 *  stamp (5 + LF), COSLAM_MAX_SCAN_POINTS readings of 3 characters in lines
 *  of 64 plus sum and LF, and the empty line. */
#define URG_SCIP2_MD_MSG_MAX                                                                                  \
    (16 + 4 + 6 + 3 * COSLAM_MAX_SCAN_POINTS +                                                             \
     2 * ((3 * COSLAM_MAX_SCAN_POINTS + URG_SCIP2_DATA_LINE_CHARS - 1) / URG_SCIP2_DATA_LINE_CHARS) + 1)
/** Receive buffer [bytes]: one whole MD message and the start of the next,
 *  so that urg_scip2_read_scan can wait for a whole message without
 *  blocking. */
#define URG_SCIP2_RX_CAP (URG_SCIP2_MD_MSG_MAX + 128)
/** Bytes one resynchronisation (the rest of a broken or stale message, up
 *  to the next empty line) may discard before the call gives up with
 *  COSLAM_E_URG_GARBAGE (counted in err_garbage; the resynchronisation
 *  stays pending): twice the longest message, so that a peer that sends
 *  lines but never an empty one cannot hold a command for ever. */
#define URG_SCIP2_DISCARD_MAX (2U * URG_SCIP2_RX_CAP)
/** Characters kept of one VV/PP/II text field (longer text is truncated and
 *  counted in stats.fields_truncated). */
#define URG_SCIP2_TEXT_MAX 64
/** Largest value of a 3-character encoded reading (18 bits). */
#define URG_SCIP2_VALUE_MAX 262143U
/** Period of the sensor's 24-bit millisecond timer [ms]. */
#define URG_SCIP2_STAMP_PERIOD_MS 16777216U

/** Flags for urg_scip2_scan_polar(). */
#define URG_SCIP2_POLAR_CODE0_NO_RETURN 1U /**< error code 0 ("object beyond range") -> +INFINITY */

/** Sensor parameters from the PP command. */
typedef struct {
    char model[URG_SCIP2_TEXT_MAX]; /**< MODL, NUL-terminated */
    uint32_t dmin_mm;               /**< DMIN: smaller readings are error codes [mm] */
    uint32_t dmax_mm;               /**< DMAX: largest valid reading [mm] */
    uint32_t ares;                  /**< ARES: steps per full turn */
    uint32_t amin;                  /**< AMIN: first measuring step */
    uint32_t amax;                  /**< AMAX: last measuring step */
    uint32_t afrt;                  /**< AFRT: step on the sensor's front axis */
    uint32_t scan_rpm;              /**< SCAN: motor speed [rpm] */
} urg_scip2_params_t;

/** Version information from the VV command (NUL-terminated text). */
typedef struct {
    char vendor[URG_SCIP2_TEXT_MAX];   /**< VEND */
    char product[URG_SCIP2_TEXT_MAX];  /**< PROD */
    char firmware[URG_SCIP2_TEXT_MAX]; /**< FIRM */
    char protocol[URG_SCIP2_TEXT_MAX]; /**< PROT */
    char serial[URG_SCIP2_TEXT_MAX];   /**< SERI */
} urg_scip2_version_t;

/** Status information from the II command (NUL-terminated text). */
typedef struct {
    char model[URG_SCIP2_TEXT_MAX];  /**< MODL */
    char laser[URG_SCIP2_TEXT_MAX];  /**< LASR ("ON" / "OFF") */
    char speed[URG_SCIP2_TEXT_MAX];  /**< SCSP */
    char mode[URG_SCIP2_TEXT_MAX];   /**< MESM */
    char bitrate[URG_SCIP2_TEXT_MAX];/**< SBPS */
    char time[URG_SCIP2_TEXT_MAX];   /**< TIME */
    char status[URG_SCIP2_TEXT_MAX]; /**< STAT */
    int laser_on;                    /**< 1 if LASR starts with "ON" */
} urg_scip2_info_t;

/** One scan, as decoded from an MD or GD reply. */
typedef struct {
    uint64_t stamp_us;       /**< sensor time at step 0, unwrapped, monotonic [us] */
    uint32_t raw_stamp_ms;   /**< the 24-bit timer value as sent [ms] */
    uint16_t first_step;     /**< requested first step */
    uint16_t last_step;      /**< requested last step */
    uint16_t cluster;        /**< steps merged per point (>= 1) */
    uint16_t remaining;      /**< MD: scans still to come (0 when unlimited); GD: 0 */
    uint16_t n_points;       /**< valid entries in range_mm (0 after an error) */
    /** Raw readings [mm]; a value below params.dmin_mm is an error code. */
    uint32_t range_mm[COSLAM_MAX_SCAN_POINTS];
} urg_scip2_scan_t;

/** Per-instance counters. Every dropped reply bumps exactly one err_ counter. */
typedef struct {
    uint32_t scans_ok;          /**< scans decoded and returned */
    uint32_t err_timeout;       /**< reply began but stopped arriving / never came */
    uint32_t err_io;            /**< serial HAL errors */
    uint32_t err_checksum;      /**< lines failing the sum check */
    uint32_t err_line;          /**< lines of wrong length, missing or extra lines */
    uint32_t err_garbage;       /**< lines with non-SCIP bytes or overlong lines */
    uint32_t err_echo;          /**< replies not echoing the command */
    uint32_t err_status;        /**< error statuses from the sensor */
    uint32_t err_field;         /**< VV/PP/II fields missing or unparsable */
    uint32_t err_capacity;      /**< scans requested beyond COSLAM_MAX_SCAN_POINTS */
    uint32_t resyncs;           /**< resynchronisations completed */
    uint32_t bytes_discarded;   /**< bytes thrown away while resynchronising */
    uint32_t messages_skipped;  /**< complete stale replies skipped (e.g. old scans) */
    uint32_t fields_truncated;  /**< VV/PP/II texts cut to URG_SCIP2_TEXT_MAX - 1 */
    uint32_t stamp_wraps;       /**< 24-bit timer wraps unwrapped */
    uint32_t stamp_backwards;   /**< stamps that went backwards (held, not added) */
} urg_scip2_stats_t;

typedef struct {
    uint32_t reply_timeout_us;    /**< wait for the first byte of a command reply [us] */
    uint32_t byte_timeout_us;     /**< wait for more bytes once a reply has begun [us] */
    uint8_t max_skipped_messages; /**< stale replies a command may skip before E_URG_ECHO */
} urg_scip2_config_t;

/** Driver state. Owned by the caller; fields are private to urg_scip2.c. */
typedef struct {
    hal_serial_t *serial;
    urg_scip2_config_t cfg;
    urg_scip2_params_t params;
    int have_params;
    /* receive buffer */
    uint8_t rx[URG_SCIP2_RX_CAP];
    size_t rx_pos;
    size_t rx_len;
    int last_byte_lf;   /* the last consumed byte was LF */
    int resync_pending; /* discard up to the next empty line before parsing */
    int resync_skip;    /* ... and it is a stale message being skipped (counted in
                           messages_skipped, not as a resync) */
    /* How far the wait for a whole message (gather_message) has looked, so
     * that each call and each read resumes there instead of starting again
     * at rx_pos (which made a message fed in small reads cost the square of
     * its length). Indices into rx, kept right by the compaction and reset
     * with the buffer; below rx_pos they mean rx_pos. */
    size_t rx_scan;       /* [rx_pos, rx_scan) holds no message end */
    size_t rx_line;       /* [rx_pos, rx_line) is a printable start of the
                             first line, without LF (polls only) */
    int rx_echo_ok;       /* the first line ends at rx_line and is the
                             command's echo (valid while rx_line >= rx_pos) */
    uint32_t rx_searched; /* urg_scip2_rx_search_bytes() */
    /* the line being assembled */
    char line[URG_SCIP2_LINE_MAX + 1];
    size_t line_len;
    /* continuous mode (MD) */
    int streaming;
    char md_echo[16]; /* "MDssssddddcci" (13 chars) of the running MD */
    uint16_t md_first;
    uint16_t md_last;
    uint16_t md_cluster;
    uint8_t md_n_scans; /* 0: until QT */
    /* time stamp unwrap */
    int have_stamp;
    uint32_t last_raw_ms;
    uint64_t stamp_ms;
    char last_status[3]; /* last error status received, e.g. "10" */
    /* the command begun without waiting (urg_scip2_begin_*) */
    uint8_t pend;         /* URG_SCIP2_PEND_*: what the polls wait for */
    uint8_t pend_len;
    uint8_t pend_skipped; /* stale replies skipped meanwhile */
    uint8_t pend_n_scans;
    char pend_cmd[16];    /* its echo */
    uint16_t pend_first;
    uint16_t pend_last;
    uint16_t pend_cluster;
    urg_scip2_stats_t stats;
} urg_scip2_t;

/** What a begun command is (urg_scip2_t.pend; private). */
enum { URG_SCIP2_PEND_NONE = 0, URG_SCIP2_PEND_SCIP2, URG_SCIP2_PEND_PP, URG_SCIP2_PEND_MD };

/* ---------------------------------------------------------------------------
 * Set-up
 * ------------------------------------------------------------------------ */

/** Defaults: reply 1 s, byte 100 ms, 8 skipped messages. O(1). */
void urg_scip2_config_default(urg_scip2_config_t *cfg);

/**
 * Initialise `u` to talk over `serial` (caller-owned; must outlive `u`). No
 * I/O. cfg NULL means defaults. Returns COSLAM_OK, COSLAM_E_ARG (NULL u or
 * serial, zero timeouts). O(1).
 */
coslam_status_t urg_scip2_init(urg_scip2_t *u, hal_serial_t *serial, const urg_scip2_config_t *cfg);

/** The URG-04LX parameters (DMIN 20, DMAX 5600, ARES 1024, AMIN 44, AMAX 725,
 *  AFRT 384, SCAN 600), for use before or instead of PP. O(1). */
urg_scip2_params_t urg_scip2_params_urg04lx(void);

/* ---------------------------------------------------------------------------
 * Commands. Each sends one command and reads its reply message; stale
 * replies (e.g. scans of an earlier MD) are skipped, up to
 * cfg.max_skipped_messages. Blocking, see "Timeouts" above.
 * Common returns: COSLAM_OK; COSLAM_E_ARG (NULL); COSLAM_E_URG_IO (HAL write
 * or read failed); COSLAM_E_URG_TIMEOUT; COSLAM_E_URG_CHECKSUM / _LINE /
 * _GARBAGE / _ECHO (reply corrupt: counted, resynchronised);
 * COSLAM_E_URG_STATUS (the sensor refused; urg_scip2_last_status() has it).
 * ------------------------------------------------------------------------ */

/**
 * Switch the sensor to SCIP 2.0 ("SCIP2.0"). Drops any unread input first
 * (hal_serial_flush_input). Accepts status "0" (switched, per the spec) and
 * "0E" with a valid sum (the sensor was already in SCIP 2.0 and does not
 * know the command).
 */
coslam_status_t urg_scip2_enter_scip2(urg_scip2_t *u);

/** VV: version information into *out. Also COSLAM_E_URG_FIELD if a line is
 *  not "<KEY>:<text>;<sum>". */
coslam_status_t urg_scip2_read_version(urg_scip2_t *u, urg_scip2_version_t *out);

/**
 * PP: sensor parameters into *out (out may be NULL) and into the instance,
 * which then uses them for step limits and angles. COSLAM_E_URG_FIELD if a
 * numeric field is missing, not a number, or inconsistent (dmin >= dmax,
 * ares 0, amin > amax, afrt outside [amin, amax]).
 */
coslam_status_t urg_scip2_read_params(urg_scip2_t *u, urg_scip2_params_t *out);

/** II: status information into *out. */
coslam_status_t urg_scip2_read_info(urg_scip2_t *u, urg_scip2_info_t *out);

/** BM: laser on. Status "00" and "02" (already on) are success. */
coslam_status_t urg_scip2_laser_on(urg_scip2_t *u);

/**
 * QT: laser off; also ends MD streaming. Scan messages that arrive before
 * the QT reply are read and skipped (counted in messages_skipped).
 */
coslam_status_t urg_scip2_laser_off(urg_scip2_t *u);

/**
 * MD: start continuous 3-character scans of steps [first, last], `cluster`
 * steps per point (0 or 1: none), skipping `interval` scans between sent
 * ones (0..9), `n_scans` scans (0: until QT; else 1..99). Reads the "00"
 * acknowledgement. Then call urg_scip2_read_scan() for each scan.
 * COSLAM_E_ARG for first > last, last > 9999, cluster > 99, interval > 9,
 * n_scans > 99, or (with PP params) last > ares; COSLAM_E_CAPACITY (+counter)
 * if the scan would exceed COSLAM_MAX_SCAN_POINTS.
 */
coslam_status_t urg_scip2_start_md(urg_scip2_t *u, uint16_t first, uint16_t last, uint16_t cluster,
                                   uint8_t interval, uint8_t n_scans);

/**
 * Read the next MD scan into *scan. Waits at most timeout_us for its first
 * byte (0: only what has already arrived). Returns COSLAM_OK (scan filled,
 * stats.scans_ok bumped); COSLAM_E_URG_TIMEOUT if no scan has begun (not an
 * error: no counter; bytes of an earlier broken reply may have been
 * discarded by the pending resynchronisation); COSLAM_E_EMPTY if MD is not
 * running; the corrupt-reply codes above, with scan->n_points = 0.
 * A scan-message status other than "99" (e.g. "5x" hardware trouble) is
 * COSLAM_E_URG_STATUS. When a finite MD ends (remaining 0), streaming stops.
 */
coslam_status_t urg_scip2_read_scan(urg_scip2_t *u, urg_scip2_scan_t *scan, uint32_t timeout_us);

/**
 * GD: one scan of steps [first, last] with `cluster` (as for MD). The laser
 * must be on (BM), else COSLAM_E_URG_STATUS with last status "10". Not
 * allowed while MD runs (COSLAM_E_ARG). Same returns as urg_scip2_start_md
 * and urg_scip2_read_scan.
 */
coslam_status_t urg_scip2_get_scan(urg_scip2_t *u, uint16_t first, uint16_t last, uint16_t cluster,
                                   urg_scip2_scan_t *scan);

/* ---------------------------------------------------------------------------
 * The same set-up without waiting, for a control loop that must not block
 * (the robot's reconnect of a lost laser). urg_scip2_begin_* sends the
 * command and returns; urg_scip2_poll, called every step, reads what the
 * port holds (every read with timeout 0) and parses the reply only once
 * the whole message is in the receive buffer, so no call waits. The driver
 * has no clock: the caller gives up on a reply that is late by its own
 * clock (urg_scip2_abandon). One command at a time: a begin, or a waiting
 * command, abandons the one begun before (not counted).
 * ------------------------------------------------------------------------ */

/** Begin SCIP2.0, as urg_scip2_enter_scip2 (drops any unread input first). */
coslam_status_t urg_scip2_begin_enter_scip2(urg_scip2_t *u);

/** Begin PP, as urg_scip2_read_params (the parameters go into the instance). */
coslam_status_t urg_scip2_begin_read_params(urg_scip2_t *u);

/** Begin MD, as urg_scip2_start_md (same arguments and refusals). */
coslam_status_t urg_scip2_begin_start_md(urg_scip2_t *u, uint16_t first, uint16_t last, uint16_t cluster,
                                         uint8_t interval, uint8_t n_scans);

/**
 * The reply to the begun command, if it has come. COSLAM_E_URG_TIMEOUT: not
 * yet (not counted; still pending). COSLAM_E_EMPTY: nothing begun. Else the
 * command is over and this is its result, as the waiting call would return
 * it (COSLAM_OK, the corrupt-reply codes, COSLAM_E_URG_STATUS, _FIELD;
 * replies to something else are skipped and counted as a waiting command
 * skips them). O(bytes arrived).
 */
coslam_status_t urg_scip2_poll(urg_scip2_t *u);

/** 1 while a begun command waits for its reply. */
int urg_scip2_pending(const urg_scip2_t *u);

/** Give up the begun command (the caller's deadline passed): counted in
 *  err_timeout, as a waiting command that timed out. A reply that comes
 *  later is skipped as stale by the next command. */
void urg_scip2_abandon(urg_scip2_t *u);

/* ---------------------------------------------------------------------------
 * Accessors and pure helpers (O(1) unless stated, no I/O)
 * ------------------------------------------------------------------------ */

/** Counters of this instance. */
const urg_scip2_stats_t *urg_scip2_stats(const urg_scip2_t *u);

/**
 * Bytes of the receive buffer examined since urg_scip2_init while waiting
 * for a whole message: the search for its empty line and, while a begun
 * command is polled, for its first line. A measure of the receive path's
 * cost, not an event, so it is kept apart from urg_scip2_stats_t (whose
 * counters stay still while a message is only arriving); wraps at 2^32.
 * 0 for NULL.
 */
uint32_t urg_scip2_rx_search_bytes(const urg_scip2_t *u);

/** Parameters in use (PP values once read, URG-04LX defaults before). */
const urg_scip2_params_t *urg_scip2_params(const urg_scip2_t *u);

/** The last non-success status the sensor sent (2 chars + NUL, "" if none). */
const char *urg_scip2_last_status(const urg_scip2_t *u);

/** 1 while an MD is running. */
int urg_scip2_is_streaming(const urg_scip2_t *u);

/** SCIP sum character of n bytes: ((sum of bytes) & 0x3F) + 0x30. O(n). */
char urg_scip2_checksum(const char *text, size_t n);

/**
 * Decode n (1..4) SCIP characters: each minus 0x30 gives 6 bits, most
 * significant first. Returns the value, or -1 if a character is outside
 * [0x30, 0x6F] or n is out of range.
 */
int32_t urg_scip2_decode(const char *chars, size_t n);

/** Angle of a (fractional) step in the sensor frame [rad]:
 *  (step - afrt) * 2 pi / ares, counter-clockwise positive (x forward,
 *  y left, sensor upright). 0 if ares is 0. */
double urg_scip2_step_angle_rad(const urg_scip2_params_t *p, double step);

/** Centre step of point i of a scan (the middle of its cluster; the last
 *  cluster may be partial). */
double urg_scip2_point_step(const urg_scip2_scan_t *scan, size_t i);

/** 1 if a raw reading is a range (dmin <= mm <= dmax), 0 if an error code or
 *  beyond dmax. */
int urg_scip2_range_valid(const urg_scip2_params_t *p, uint32_t range_mm);

/**
 * Convert a scan to polar form in the sensor frame: range_m[i] = mm / 1000
 * for valid readings, NAN for error codes and readings beyond dmax, +INFINITY
 * for code 0 if flags has URG_SCIP2_POLAR_CODE0_NO_RETURN (the URG-04LX error
 * table says code 0 is "object possibly beyond range": a no-return ray).
 * angle_rad[i] from urg_scip2_point_step(). Returns COSLAM_OK;
 * COSLAM_E_ARG (NULL); COSLAM_E_CAPACITY if cap < n_points (nothing
 * written). O(n_points).
 */
coslam_status_t urg_scip2_scan_polar(const urg_scip2_params_t *p, const urg_scip2_scan_t *scan, unsigned flags,
                                     double *range_m, double *angle_rad, size_t cap, size_t *n_out);

#ifdef __cplusplus
}
#endif

#endif /* URG_SCIP2_H */
