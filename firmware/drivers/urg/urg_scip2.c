/*
 * urg_scip2.c - SCIP 2.0 driver for Hokuyo URG laser range finders.
 * Contract, protocol summary and error policy: urg_scip2.h, docs/urg.md.
 */
#include "urg/urg_scip2.h"

#include <math.h>
#include <string.h>

#define LF ((uint8_t)0x0A)
#define MASK24 0xFFFFFFU
#define TWO_PI 6.28318530717958647692

/* ------------------------------------------------------------------------
 * Small pure helpers
 * --------------------------------------------------------------------- */

char urg_scip2_checksum(const char *text, size_t n)
{
    unsigned sum = 0U;
    for (size_t i = 0; i < n; ++i) {
        sum += (unsigned char)text[i];
    }
    return (char)((sum & 0x3FU) + 0x30U);
}

int32_t urg_scip2_decode(const char *chars, size_t n)
{
    if (chars == NULL || n < 1U || n > 4U) {
        return -1;
    }
    int32_t v = 0;
    for (size_t i = 0; i < n; ++i) {
        const unsigned char c = (unsigned char)chars[i];
        if (c < 0x30U || c > 0x6FU) {
            return -1;
        }
        v = (v << 6) | (int32_t)(c - 0x30U);
    }
    return v;
}

double urg_scip2_step_angle_rad(const urg_scip2_params_t *p, double step)
{
    if (p == NULL || p->ares == 0U) {
        return 0.0;
    }
    return (step - (double)p->afrt) * TWO_PI / (double)p->ares;
}

double urg_scip2_point_step(const urg_scip2_scan_t *scan, size_t i)
{
    const uint32_t c = scan->cluster == 0U ? 1U : scan->cluster;
    const uint32_t lo = (uint32_t)scan->first_step + (uint32_t)i * c;
    uint32_t hi = lo + c - 1U;
    if (hi > scan->last_step) {
        hi = scan->last_step;
    }
    return 0.5 * ((double)lo + (double)hi);
}

int urg_scip2_range_valid(const urg_scip2_params_t *p, uint32_t range_mm)
{
    return p != NULL && range_mm >= p->dmin_mm && range_mm <= p->dmax_mm;
}

coslam_status_t urg_scip2_scan_polar(const urg_scip2_params_t *p, const urg_scip2_scan_t *scan, unsigned flags,
                                     double *range_m, double *angle_rad, size_t cap, size_t *n_out)
{
    if (p == NULL || scan == NULL || range_m == NULL || angle_rad == NULL || n_out == NULL) {
        return COSLAM_E_ARG;
    }
    *n_out = 0;
    if (scan->n_points > cap) {
        return COSLAM_E_CAPACITY;
    }
    for (size_t i = 0; i < scan->n_points; ++i) {
        const uint32_t mm = scan->range_mm[i];
        if (urg_scip2_range_valid(p, mm)) {
            range_m[i] = (double)mm / 1000.0;
        } else if (mm == 0U && (flags & URG_SCIP2_POLAR_CODE0_NO_RETURN) != 0U) {
            range_m[i] = (double)INFINITY;
        } else {
            range_m[i] = (double)NAN;
        }
        angle_rad[i] = urg_scip2_step_angle_rad(p, urg_scip2_point_step(scan, i));
    }
    *n_out = scan->n_points;
    return COSLAM_OK;
}

urg_scip2_params_t urg_scip2_params_urg04lx(void)
{
    urg_scip2_params_t p;
    memset(&p, 0, sizeof p);
    memcpy(p.model, "URG-04LX", sizeof "URG-04LX");
    p.dmin_mm = 20U;
    p.dmax_mm = 5600U;
    p.ares = 1024U;
    p.amin = 44U;
    p.amax = 725U;
    p.afrt = 384U;
    p.scan_rpm = 600U;
    return p;
}

/* Write `value` as exactly `width` decimal digits (zero padded). */
static void put_dec(char *out, uint32_t value, size_t width)
{
    for (size_t i = width; i > 0U; --i) {
        out[i - 1U] = (char)('0' + (value % 10U));
        value /= 10U;
    }
}

/* Parse exactly n decimal digits; -1 if any is not a digit. */
static int32_t get_dec(const char *s, size_t n)
{
    int32_t v = 0;
    for (size_t i = 0; i < n; ++i) {
        if (s[i] < '0' || s[i] > '9') {
            return -1;
        }
        v = v * 10 + (int32_t)(s[i] - '0');
    }
    return v;
}

/* ------------------------------------------------------------------------
 * Set-up and accessors
 * --------------------------------------------------------------------- */

void urg_scip2_config_default(urg_scip2_config_t *cfg)
{
    COSLAM_ASSERT(cfg != NULL);
    cfg->reply_timeout_us = 1000000U;
    cfg->byte_timeout_us = 100000U;
    cfg->max_skipped_messages = 8U;
}

coslam_status_t urg_scip2_init(urg_scip2_t *u, hal_serial_t *serial, const urg_scip2_config_t *cfg)
{
    if (u == NULL || serial == NULL) {
        return COSLAM_E_ARG;
    }
    urg_scip2_config_t c;
    if (cfg != NULL) {
        c = *cfg;
    } else {
        urg_scip2_config_default(&c);
    }
    if (c.reply_timeout_us == 0U || c.byte_timeout_us == 0U) {
        return COSLAM_E_ARG;
    }
    memset(u, 0, sizeof *u);
    u->serial = serial;
    u->cfg = c;
    u->params = urg_scip2_params_urg04lx();
    u->last_byte_lf = 1; /* the stream starts at a line start */
    return COSLAM_OK;
}

const urg_scip2_stats_t *urg_scip2_stats(const urg_scip2_t *u)
{
    return u != NULL ? &u->stats : NULL;
}

uint32_t urg_scip2_rx_search_bytes(const urg_scip2_t *u)
{
    return u != NULL ? u->rx_searched : 0U;
}

const urg_scip2_params_t *urg_scip2_params(const urg_scip2_t *u)
{
    return u != NULL ? &u->params : NULL;
}

const char *urg_scip2_last_status(const urg_scip2_t *u)
{
    return u != NULL ? u->last_status : "";
}

int urg_scip2_is_streaming(const urg_scip2_t *u)
{
    return u != NULL && u->streaming;
}

/* ------------------------------------------------------------------------
 * Byte and line input
 * --------------------------------------------------------------------- */

/* The buffer's contents were replaced: nothing of them has been looked at. */
static void rx_marks_reset(urg_scip2_t *u)
{
    u->rx_scan = 0U;
    u->rx_line = 0U;
    u->rx_echo_ok = 0;
}

/* Next received byte, reading the HAL (waiting at most timeout_us) when the
 * buffer is empty. Returns COSLAM_OK, COSLAM_E_URG_TIMEOUT or COSLAM_E_URG_IO
 * (counted). */
static coslam_status_t next_byte(urg_scip2_t *u, uint32_t timeout_us, uint8_t *b)
{
    if (u->rx_pos >= u->rx_len) {
        size_t n = 0;
        const hal_status_t h = hal_serial_read(u->serial, u->rx, sizeof u->rx, &n, timeout_us);
        if (h == HAL_E_TIMEOUT || (h == HAL_OK && n == 0U)) {
            return COSLAM_E_URG_TIMEOUT;
        }
        if (h != HAL_OK || n > sizeof u->rx) {
            u->stats.err_io++;
            return COSLAM_E_URG_IO;
        }
        u->rx_pos = 0;
        u->rx_len = n;
        rx_marks_reset(u);
    }
    *b = u->rx[u->rx_pos++];
    u->last_byte_lf = (*b == LF);
    return COSLAM_OK;
}

/* Discard bytes up to and including the next empty line (an LF at the start
 * of a line). Used after an error (is_skip 0: counts resyncs and discarded
 * bytes) and to skip a stale reply whose first line has been read (is_skip 1:
 * counts messages_skipped). Returns COSLAM_OK or the input error; on a
 * timeout the resynchronisation stays pending for the next call. */
static coslam_status_t discard_to_empty_line(urg_scip2_t *u, uint32_t timeout_us, int is_skip)
{
    u->resync_pending = 1;
    u->resync_skip = 0;
    /* no reply is longer than the receive buffer: a peer that sends lines
     * but never an empty one (another device on the port) ends the call
     * after this many bytes instead of holding it for ever */
    uint32_t budget = URG_SCIP2_DISCARD_MAX;
    for (;;) {
        const int at_line_start = u->last_byte_lf;
        uint8_t b = 0;
        const coslam_status_t st = next_byte(u, timeout_us, &b);
        if (st != COSLAM_OK) {
            return st;
        }
        if (b == LF && at_line_start) {
            break;
        }
        if (!is_skip) {
            u->stats.bytes_discarded++;
        }
        if (--budget == 0U) {
            u->stats.err_garbage++; /* the resynchronisation stays pending */
            return COSLAM_E_URG_GARBAGE;
        }
    }
    u->resync_pending = 0;
    if (is_skip) {
        u->stats.messages_skipped++;
    } else {
        u->stats.resyncs++;
    }
    return COSLAM_OK;
}

/* Mark the current message broken: the next call discards the rest of it. */
static coslam_status_t fail_resync(urg_scip2_t *u, coslam_status_t st)
{
    u->resync_pending = 1;
    u->resync_skip = 0;
    return st;
}

/*
 * The receive buffer holds the end of a message: an empty line (an LF at the
 * start of a line) at or after rx_pos. Whether byte i ends a message depends
 * only on it and the byte before it (last_byte_lf, the last byte consumed, at
 * rx_pos), so what an earlier call found stays true as bytes are consumed or
 * appended: the search resumes at rx_scan and each byte is examined once per
 * message (it stops on the end it found, which a repeated call looks at
 * again). O(bytes new since the last call).
 */
static int message_end_buffered(urg_scip2_t *u)
{
    size_t i = u->rx_scan > u->rx_pos ? u->rx_scan : u->rx_pos;
    for (; i < u->rx_len; ++i) {
        u->rx_searched++;
        if (u->rx[i] == LF && (i == u->rx_pos ? u->last_byte_lf : u->rx[i - 1U] == LF)) {
            break;
        }
    }
    u->rx_scan = i;
    return i < u->rx_len;
}

/*
 * The line at rx_pos (a line start) is whole in the buffer, printable and at
 * most URG_SCIP2_LINE_MAX long: its length, or -1 (not whole yet, or a line
 * first_line will refuse as garbage). Resumes at rx_line: [rx_pos, rx_line),
 * when not empty, is a start of this same line (it holds no LF, so rx_pos
 * cannot have moved to another line start inside it) found printable and
 * short enough, and it still is (offsets from rx_pos only shrink). Stops on
 * the byte that decides, which a repeated call looks at again. O(bytes new
 * since the last call).
 */
static long buffered_line(urg_scip2_t *u)
{
    u->rx_echo_ok = 0;
    size_t i = u->rx_line > u->rx_pos ? u->rx_line : u->rx_pos;
    long len = -1;
    for (; i < u->rx_len; ++i) {
        u->rx_searched++;
        const uint8_t b = u->rx[i];
        if (b == LF) {
            len = (long)(i - u->rx_pos);
            break;
        }
        if (b < 0x20U || b > 0x7EU || i - u->rx_pos >= URG_SCIP2_LINE_MAX) {
            break;
        }
    }
    u->rx_line = i;
    return len;
}

/*
 * For urg_scip2_read_scan and urg_scip2_poll: finish a pending
 * resynchronisation and make sure a whole message is in the receive buffer,
 * reading what the port holds (each read waits at most timeout_us) but never
 * waiting inside a message. With `echo` (the poll of a begun command), a
 * message whose first line is whole and is not `echo` is skipped as it
 * streams in (a stale scan of any length costs no buffer), and a stray
 * empty line is consumed; *skipped counts both (the caller's budget).
 * COSLAM_OK: the parse that follows reads only buffered bytes, since no
 * parse reads past a message's empty line. COSLAM_E_URG_TIMEOUT: no whole
 * message yet, what came is kept (not counted). COSLAM_E_URG_GARBAGE: the
 * buffer filled without a message end (counted; discarded, resync pending).
 */
static coslam_status_t gather_message(urg_scip2_t *u, uint32_t timeout_us, const char *echo, size_t echo_len,
                                      unsigned *skipped)
{
    for (;;) {
        while (u->resync_pending && u->rx_pos < u->rx_len) {
            const int at_line_start = u->last_byte_lf;
            const uint8_t b = u->rx[u->rx_pos++];
            u->last_byte_lf = (b == LF);
            if (b == LF && at_line_start) {
                u->resync_pending = 0;
                if (u->resync_skip) {
                    u->stats.messages_skipped++;
                } else {
                    u->stats.resyncs++;
                }
                u->resync_skip = 0;
            } else if (!u->resync_skip) {
                u->stats.bytes_discarded++;
            }
        }
        /* the first line once: found whole and the echo, it is not looked
         * at again while more of its message comes (rx_pos stays on it) */
        if (!u->resync_pending && echo != NULL && u->last_byte_lf && !(u->rx_echo_ok && u->rx_line >= u->rx_pos)) {
            const long len = buffered_line(u);
            if (len == 0) {
                u->rx_pos++; /* a stray empty line: nothing to skip */
                (*skipped)++;
                continue;
            }
            if (len > 0 && ((size_t)len != echo_len || memcmp(&u->rx[u->rx_pos], echo, echo_len) != 0)) {
                u->rx_pos += (size_t)len + 1U; /* its first line; the rest as it comes */
                u->resync_pending = 1;
                u->resync_skip = 1;
                (*skipped)++;
                continue;
            }
            u->rx_echo_ok = len > 0;
        }
        if (!u->resync_pending && message_end_buffered(u)) {
            return COSLAM_OK;
        }
        if (u->rx_pos > 0U) {
            memmove(u->rx, u->rx + u->rx_pos, u->rx_len - u->rx_pos);
            u->rx_len -= u->rx_pos;
            /* the marks move with the bytes (below rx_pos they meant rx_pos,
             * and an echo verdict there was about a line now consumed) */
            u->rx_scan = u->rx_scan > u->rx_pos ? u->rx_scan - u->rx_pos : 0U;
            if (u->rx_line >= u->rx_pos) {
                u->rx_line -= u->rx_pos;
            } else {
                u->rx_line = 0U;
                u->rx_echo_ok = 0;
            }
            u->rx_pos = 0U;
        }
        if (u->rx_len == sizeof u->rx) {
            /* longer than any message: not SCIP, or two run together */
            u->stats.err_garbage++;
            u->stats.bytes_discarded += (uint32_t)u->rx_len;
            u->last_byte_lf = (u->rx[u->rx_len - 1U] == LF);
            u->rx_len = 0U;
            rx_marks_reset(u);
            return fail_resync(u, COSLAM_E_URG_GARBAGE);
        }
        size_t n = 0;
        const size_t room = sizeof u->rx - u->rx_len;
        const hal_status_t h = hal_serial_read(u->serial, u->rx + u->rx_len, room, &n, timeout_us);
        if (h == HAL_E_TIMEOUT || (h == HAL_OK && n == 0U)) {
            return COSLAM_E_URG_TIMEOUT;
        }
        if (h != HAL_OK || n > room) {
            u->stats.err_io++;
            return COSLAM_E_URG_IO;
        }
        u->rx_len += n;
    }
}

/* A line of the wrong length (u->line), counted. If it is the empty line
 * that ends a message (a line was lost and the message ended early), the
 * message is over and nothing is resynchronised, so the next one is read
 * whole; otherwise the rest of this one is discarded. */
static coslam_status_t bad_line(urg_scip2_t *u)
{
    u->stats.err_line++;
    return u->line_len == 0U ? COSLAM_E_URG_LINE : fail_resync(u, COSLAM_E_URG_LINE);
}

/*
 * Read one line (without its LF) into u->line / u->line_len. The first byte
 * waits at most first_timeout_us, later bytes cfg.byte_timeout_us. *began is
 * set when at least one byte of the line was consumed. Returns COSLAM_OK;
 * COSLAM_E_URG_TIMEOUT; COSLAM_E_URG_IO; COSLAM_E_URG_GARBAGE for a byte
 * outside printable ASCII or a line longer than URG_SCIP2_LINE_MAX (the
 * line is abandoned where the fault was seen; not counted here).
 */
static coslam_status_t get_line(urg_scip2_t *u, uint32_t first_timeout_us, int *began)
{
    u->line_len = 0;
    u->line[0] = '\0';
    *began = 0;
    for (;;) {
        uint8_t b = 0;
        const coslam_status_t st = next_byte(u, *began ? u->cfg.byte_timeout_us : first_timeout_us, &b);
        if (st != COSLAM_OK) {
            return st;
        }
        *began = 1;
        if (b == LF) {
            u->line[u->line_len] = '\0';
            return COSLAM_OK;
        }
        if (b < 0x20U || b > 0x7EU || u->line_len >= URG_SCIP2_LINE_MAX) {
            return COSLAM_E_URG_GARBAGE;
        }
        u->line[u->line_len++] = (char)b;
    }
}

/*
 * Read a line inside a message (not its first line). Any failure breaks the
 * message: it is counted, resynchronisation is scheduled, and the code is
 * returned.
 */
static coslam_status_t body_line(urg_scip2_t *u)
{
    int began = 0;
    const coslam_status_t st = get_line(u, u->cfg.byte_timeout_us, &began);
    if (st == COSLAM_OK) {
        return COSLAM_OK;
    }
    if (st == COSLAM_E_URG_TIMEOUT) {
        u->stats.err_timeout++;
    } else if (st == COSLAM_E_URG_GARBAGE) {
        u->stats.err_garbage++;
    }
    return fail_resync(u, st);
}

/*
 * Start reading a message: finish a pending resynchronisation, then read the
 * first line (the echo). *began reports whether any byte was consumed, so a
 * caller can tell "nothing arrived" from "a reply broke off".
 */
static coslam_status_t first_line(urg_scip2_t *u, uint32_t timeout_us, int *began)
{
    *began = 0;
    if (u->resync_pending) {
        const coslam_status_t st = discard_to_empty_line(u, timeout_us, 0);
        if (st != COSLAM_OK) {
            return st;
        }
    }
    const coslam_status_t st = get_line(u, timeout_us, began);
    if (st == COSLAM_E_URG_GARBAGE) {
        u->stats.err_garbage++;
        return fail_resync(u, st);
    }
    if (st == COSLAM_E_URG_TIMEOUT && *began) {
        u->stats.err_timeout++;
        return fail_resync(u, st);
    }
    return st;
}

/* Check a "SS<sum>" status line (u->line) and copy the 2 status chars. */
static coslam_status_t check_status_line(urg_scip2_t *u, char status[3])
{
    if (u->line_len != 3U) {
        return bad_line(u); /* the empty line: the status line was lost */
    }
    if (urg_scip2_checksum(u->line, 2) != u->line[2]) {
        u->stats.err_checksum++;
        return fail_resync(u, COSLAM_E_URG_CHECKSUM);
    }
    status[0] = u->line[0];
    status[1] = u->line[1];
    status[2] = '\0';
    return COSLAM_OK;
}

/* Read the empty line that ends a message. */
static coslam_status_t end_of_message(urg_scip2_t *u)
{
    const coslam_status_t st = body_line(u);
    if (st != COSLAM_OK) {
        return st;
    }
    if (u->line_len != 0U) {
        return bad_line(u);
    }
    return COSLAM_OK;
}

/* An error status ends its reply: read the empty line, then record the
 * status. If the reply goes on instead, it is malformed (most likely the
 * status itself is damaged): that error is returned and counted, not the
 * status, so one broken reply bumps one counter. */
static coslam_status_t status_error(urg_scip2_t *u, const char status[3])
{
    const coslam_status_t st = end_of_message(u);
    if (st != COSLAM_OK) {
        return st;
    }
    u->last_status[0] = status[0];
    u->last_status[1] = status[1];
    u->last_status[2] = '\0';
    u->stats.err_status++;
    return COSLAM_E_URG_STATUS;
}

/* ------------------------------------------------------------------------
 * Command / reply
 * --------------------------------------------------------------------- */

/* Send `cmd` (n chars, without LF) and its LF, the write waiting at most
 * timeout_us. */
static coslam_status_t send_cmd(urg_scip2_t *u, const char *cmd, size_t n, uint32_t timeout_us)
{
    char buf[24];
    COSLAM_ASSERT(n + 1U <= sizeof buf);
    memcpy(buf, cmd, n);
    buf[n] = '\n';
    const hal_status_t h = hal_serial_write(u->serial, (const uint8_t *)buf, n + 1U, timeout_us);
    if (h != HAL_OK) {
        u->stats.err_io++;
        return COSLAM_E_URG_IO;
    }
    return COSLAM_OK;
}

/*
 * Wait for the reply whose echo is `echo` (echo_len chars): complete replies
 * with another echo (stale scans, answers to earlier commands) are skipped,
 * up to cfg.max_skipped_messages. On COSLAM_OK u->line holds the echo.
 */
static coslam_status_t await_echo(urg_scip2_t *u, const char *echo, size_t echo_len)
{
    for (unsigned skipped = 0;; ++skipped) {
        int began = 0;
        const coslam_status_t st = first_line(u, u->cfg.reply_timeout_us, &began);
        if (st == COSLAM_E_URG_TIMEOUT && !began) {
            u->stats.err_timeout++; /* a reply was due */
            return st;
        }
        if (st != COSLAM_OK) {
            return st;
        }
        if (u->line_len == echo_len && memcmp(u->line, echo, echo_len) == 0) {
            return COSLAM_OK;
        }
        if (skipped >= u->cfg.max_skipped_messages) {
            u->stats.err_echo++;
            return fail_resync(u, COSLAM_E_URG_ECHO);
        }
        if (u->line_len == 0U) {
            continue; /* a stray empty line: nothing to skip */
        }
        const coslam_status_t sk = discard_to_empty_line(u, u->cfg.byte_timeout_us, 1);
        if (sk == COSLAM_E_URG_TIMEOUT) {
            u->stats.err_timeout++;
        }
        if (sk != COSLAM_OK) {
            return sk;
        }
    }
}

/* Read the echo `cmd` (n chars) and the status line of its reply. */
static coslam_status_t reply_status(urg_scip2_t *u, const char *cmd, size_t n, char status[3])
{
    coslam_status_t st = await_echo(u, cmd, n);
    if (st != COSLAM_OK) {
        return st;
    }
    st = body_line(u);
    if (st != COSLAM_OK) {
        return st;
    }
    return check_status_line(u, status);
}

/* Send `cmd` (without LF) and read its echo and status line. */
static coslam_status_t command(urg_scip2_t *u, const char *cmd, size_t n, char status[3])
{
    u->pend = URG_SCIP2_PEND_NONE; /* a command begun without waiting is abandoned */
    if (u->resync_pending) {
        /* the rest of a broken reply, before this command's reply can come:
         * after it, that reply would be taken for the rest and thrown away */
        const coslam_status_t rs = discard_to_empty_line(u, u->cfg.byte_timeout_us, 0);
        if (rs == COSLAM_E_URG_TIMEOUT) {
            /* its end was lost: nothing more of it will come */
            u->resync_pending = 0;
            u->last_byte_lf = 1;
            u->stats.resyncs++;
        } else if (rs != COSLAM_OK) {
            return rs;
        }
    }
    const coslam_status_t st = send_cmd(u, cmd, n, u->cfg.reply_timeout_us);
    if (st != COSLAM_OK) {
        return st;
    }
    return reply_status(u, cmd, n, status);
}

/* Commands whose whole reply is echo, status, empty line. ok1/ok2 are the
 * statuses taken as success. */
static coslam_status_t simple_command(urg_scip2_t *u, const char *cmd, const char *ok1, const char *ok2)
{
    if (u == NULL) {
        return COSLAM_E_ARG;
    }
    char status[3];
    coslam_status_t st = command(u, cmd, strlen(cmd), status);
    if (st != COSLAM_OK) {
        return st;
    }
    if (strcmp(status, ok1) != 0 && (ok2 == NULL || strcmp(status, ok2) != 0)) {
        return status_error(u, status);
    }
    return end_of_message(u);
}

/* Drop unread input and any broken reply: the stream starts afresh at a
 * line start. */
static void reset_input(urg_scip2_t *u)
{
    (void)hal_serial_flush_input(u->serial); /* unsupported flush is harmless */
    u->rx_pos = u->rx_len = 0;
    rx_marks_reset(u);
    u->last_byte_lf = 1;
    u->resync_pending = 0;
    u->resync_skip = 0;
    u->streaming = 0;
}

/* SCIP2.0's reply after its echo. SCIP 1.1 answers "0" without a sum; a
 * sensor already in SCIP 2.0 does not know the command and answers "0E" +
 * sum. */
static coslam_status_t scip2_rest(urg_scip2_t *u)
{
    coslam_status_t st = body_line(u);
    if (st != COSLAM_OK) {
        return st;
    }
    if (!(u->line_len == 1U && u->line[0] == '0')) {
        char status[3];
        st = check_status_line(u, status);
        if (st != COSLAM_OK) {
            return st;
        }
        if (strcmp(status, "0E") != 0) {
            return status_error(u, status);
        }
    }
    return end_of_message(u);
}

coslam_status_t urg_scip2_enter_scip2(urg_scip2_t *u)
{
    if (u == NULL) {
        return COSLAM_E_ARG;
    }
    u->pend = URG_SCIP2_PEND_NONE;
    reset_input(u);
    static const char cmd[] = "SCIP2.0";
    coslam_status_t st = send_cmd(u, cmd, sizeof cmd - 1U, u->cfg.reply_timeout_us);
    if (st != COSLAM_OK) {
        return st;
    }
    st = await_echo(u, cmd, sizeof cmd - 1U);
    if (st != COSLAM_OK) {
        return st;
    }
    return scip2_rest(u);
}

coslam_status_t urg_scip2_laser_on(urg_scip2_t *u)
{
    return simple_command(u, "BM", "00", "02");
}

coslam_status_t urg_scip2_laser_off(urg_scip2_t *u)
{
    const coslam_status_t st = simple_command(u, "QT", "00", NULL);
    if (st == COSLAM_OK) {
        u->streaming = 0;
    }
    return st;
}

/* ------------------------------------------------------------------------
 * VV / PP / II
 * --------------------------------------------------------------------- */

typedef struct {
    const char *key;  /* 4 letters */
    char *text;       /* destination, URG_SCIP2_TEXT_MAX bytes */
    int seen;
} info_field_t;

/*
 * Read "KEY:text;<sum>" lines up to the empty line, filling the fields whose
 * key matches (unknown keys are checked, then ignored). Every field must be
 * present.
 */
static coslam_status_t read_info_body(urg_scip2_t *u, info_field_t *fields, size_t n_fields)
{
    for (;;) {
        coslam_status_t st = body_line(u);
        if (st != COSLAM_OK) {
            return st;
        }
        const size_t len = u->line_len;
        if (len == 0U) {
            break;
        }
        /* shortest line: "KEY:" "" ";" sum -> 6 chars; the ';' sits right
         * before the sum (the sum itself may be a ';') and is not summed */
        if (len < 7U || u->line[len - 2U] != ';' || u->line[4] != ':') {
            return bad_line(u);
        }
        if (urg_scip2_checksum(u->line, len - 2U) != u->line[len - 1U]) {
            u->stats.err_checksum++;
            return fail_resync(u, COSLAM_E_URG_CHECKSUM);
        }
        for (size_t f = 0; f < n_fields; ++f) {
            if (memcmp(u->line, fields[f].key, 4U) != 0) {
                continue;
            }
            size_t n = len - 7U; /* text between ':' and ';' */
            if (n > URG_SCIP2_TEXT_MAX - 1U) {
                n = URG_SCIP2_TEXT_MAX - 1U;
                u->stats.fields_truncated++;
            }
            memcpy(fields[f].text, u->line + 5, n);
            fields[f].text[n] = '\0';
            fields[f].seen = 1;
        }
    }
    for (size_t f = 0; f < n_fields; ++f) {
        if (!fields[f].seen) {
            u->stats.err_field++;
            return COSLAM_E_URG_FIELD; /* message complete: no resync */
        }
    }
    return COSLAM_OK;
}

static coslam_status_t info_command(urg_scip2_t *u, const char *cmd, info_field_t *fields, size_t n_fields)
{
    char status[3];
    coslam_status_t st = command(u, cmd, 2U, status);
    if (st != COSLAM_OK) {
        return st;
    }
    if (strcmp(status, "00") != 0) {
        return status_error(u, status);
    }
    return read_info_body(u, fields, n_fields);
}

coslam_status_t urg_scip2_read_version(urg_scip2_t *u, urg_scip2_version_t *out)
{
    if (u == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    urg_scip2_version_t v;
    memset(&v, 0, sizeof v);
    info_field_t f[] = {
        {"VEND", v.vendor, 0}, {"PROD", v.product, 0}, {"FIRM", v.firmware, 0},
        {"PROT", v.protocol, 0}, {"SERI", v.serial, 0},
    };
    const coslam_status_t st = info_command(u, "VV", f, sizeof f / sizeof f[0]);
    if (st == COSLAM_OK) {
        *out = v;
    }
    return st;
}

/* A PP number: optional leading spaces, then 1..9 digits, nothing else. */
static int parse_u32(const char *s, uint32_t *out)
{
    while (*s == ' ') {
        ++s;
    }
    const size_t n = strlen(s);
    if (n == 0U || n > 9U) {
        return 0;
    }
    const int32_t v = get_dec(s, n);
    if (v < 0) {
        return 0;
    }
    *out = (uint32_t)v;
    return 1;
}

/* PP's reply after its status line: the fields, checked, into the instance
 * and *out (may be NULL). */
static coslam_status_t params_rest(urg_scip2_t *u, const char status[3], urg_scip2_params_t *out)
{
    if (strcmp(status, "00") != 0) {
        return status_error(u, status);
    }
    char text[8][URG_SCIP2_TEXT_MAX];
    memset(text, 0, sizeof text);
    info_field_t f[] = {
        {"MODL", text[0], 0}, {"DMIN", text[1], 0}, {"DMAX", text[2], 0}, {"ARES", text[3], 0},
        {"AMIN", text[4], 0}, {"AMAX", text[5], 0}, {"AFRT", text[6], 0}, {"SCAN", text[7], 0},
    };
    const coslam_status_t st = read_info_body(u, f, sizeof f / sizeof f[0]);
    if (st != COSLAM_OK) {
        return st;
    }
    urg_scip2_params_t p;
    memset(&p, 0, sizeof p);
    memcpy(p.model, text[0], sizeof p.model);
    uint32_t *num[7] = {&p.dmin_mm, &p.dmax_mm, &p.ares, &p.amin, &p.amax, &p.afrt, &p.scan_rpm};
    for (size_t i = 0; i < 7U; ++i) {
        if (!parse_u32(text[i + 1U], num[i])) {
            u->stats.err_field++;
            return COSLAM_E_URG_FIELD;
        }
    }
    if (p.dmin_mm >= p.dmax_mm || p.ares == 0U || p.amin > p.amax || p.afrt < p.amin || p.afrt > p.amax ||
        p.amax > 9999U) {
        u->stats.err_field++;
        return COSLAM_E_URG_FIELD;
    }
    u->params = p;
    u->have_params = 1;
    if (out != NULL) {
        *out = p;
    }
    return COSLAM_OK;
}

coslam_status_t urg_scip2_read_params(urg_scip2_t *u, urg_scip2_params_t *out)
{
    if (u == NULL) {
        return COSLAM_E_ARG;
    }
    char status[3];
    const coslam_status_t st = command(u, "PP", 2U, status);
    if (st != COSLAM_OK) {
        return st;
    }
    return params_rest(u, status, out);
}

coslam_status_t urg_scip2_read_info(urg_scip2_t *u, urg_scip2_info_t *out)
{
    if (u == NULL || out == NULL) {
        return COSLAM_E_ARG;
    }
    urg_scip2_info_t v;
    memset(&v, 0, sizeof v);
    info_field_t f[] = {
        {"MODL", v.model, 0}, {"LASR", v.laser, 0},   {"SCSP", v.speed, 0}, {"MESM", v.mode, 0},
        {"SBPS", v.bitrate, 0}, {"TIME", v.time, 0}, {"STAT", v.status, 0},
    };
    const coslam_status_t st = info_command(u, "II", f, sizeof f / sizeof f[0]);
    if (st == COSLAM_OK) {
        v.laser_on = strncmp(v.laser, "ON", 2) == 0;
        *out = v;
    }
    return st;
}

/* ------------------------------------------------------------------------
 * Scans
 * --------------------------------------------------------------------- */

/* Points of a scan of steps [first, last] merged by `cluster` (0 -> 1). */
static uint32_t scan_points(uint16_t first, uint16_t last, uint16_t cluster)
{
    const uint32_t c = cluster == 0U ? 1U : cluster;
    return ((uint32_t)last - first + 1U + c - 1U) / c;
}

static coslam_status_t check_range_args(urg_scip2_t *u, uint16_t first, uint16_t last, uint16_t cluster)
{
    if (first > last || last > 9999U || cluster > 99U) {
        return COSLAM_E_ARG;
    }
    if (u->have_params && last > u->params.ares) {
        return COSLAM_E_ARG;
    }
    if (scan_points(first, last, cluster) > COSLAM_MAX_SCAN_POINTS) {
        u->stats.err_capacity++;
        return COSLAM_E_CAPACITY;
    }
    return COSLAM_OK;
}

/* 24-bit sensor time -> 64-bit monotonic stamp. A forward step of less than
 * half the timer period is time passing (across a wrap if raw < last); a
 * larger one is a step backwards (sensor reset, stale scan): the stamp is
 * held and the counter bumped. */
static uint64_t unwrap_stamp(urg_scip2_t *u, uint32_t raw_ms)
{
    if (!u->have_stamp) {
        u->have_stamp = 1;
        u->stamp_ms = raw_ms;
    } else {
        const uint32_t d = (raw_ms - u->last_raw_ms) & MASK24;
        if (d >= URG_SCIP2_STAMP_PERIOD_MS / 2U) {
            u->stats.stamp_backwards++;
        } else {
            if (raw_ms < u->last_raw_ms) {
                u->stats.stamp_wraps++;
            }
            u->stamp_ms += d;
        }
    }
    u->last_raw_ms = raw_ms;
    return u->stamp_ms * 1000U;
}

/*
 * Read the body of a scan reply after its status line: time stamp line, data
 * lines, empty line. The data of n points is 3n characters cut into lines of
 * 64 (the last shorter), each with its own sum; values straddle lines, so the
 * characters are decoded as one joined stream.
 */
static coslam_status_t read_scan_data(urg_scip2_t *u, urg_scip2_scan_t *scan, uint32_t n_points)
{
    coslam_status_t st = body_line(u);
    if (st != COSLAM_OK) {
        return st;
    }
    if (u->line_len != 5U) {
        return bad_line(u); /* the empty line: the time stamp was lost */
    }
    if (urg_scip2_checksum(u->line, 4U) != u->line[4]) {
        u->stats.err_checksum++;
        return fail_resync(u, COSLAM_E_URG_CHECKSUM);
    }
    const int32_t raw = urg_scip2_decode(u->line, 4U);
    if (raw < 0) {
        u->stats.err_garbage++;
        return fail_resync(u, COSLAM_E_URG_GARBAGE);
    }

    const uint32_t expected = 3U * n_points;
    uint32_t got = 0U;
    uint32_t acc = 0U;
    unsigned acc_n = 0U;
    uint32_t idx = 0U;
    for (;;) {
        st = body_line(u);
        if (st != COSLAM_OK) {
            return st;
        }
        const size_t len = u->line_len;
        if (len == 0U) {
            if (got == expected) {
                break;
            }
            return bad_line(u); /* the message ended early */
        }
        const uint32_t left = expected - got;
        const uint32_t want = left < URG_SCIP2_DATA_LINE_CHARS ? left : URG_SCIP2_DATA_LINE_CHARS;
        if (want == 0U || len - 1U != want) {
            return bad_line(u);
        }
        if (urg_scip2_checksum(u->line, want) != u->line[want]) {
            u->stats.err_checksum++;
            return fail_resync(u, COSLAM_E_URG_CHECKSUM);
        }
        for (uint32_t i = 0; i < want; ++i) {
            const unsigned char c = (unsigned char)u->line[i];
            if (c < 0x30U || c > 0x6FU) {
                u->stats.err_garbage++;
                return fail_resync(u, COSLAM_E_URG_GARBAGE);
            }
            acc = (acc << 6) | (uint32_t)(c - 0x30U);
            if (++acc_n == 3U) {
                scan->range_mm[idx++] = acc;
                acc = 0U;
                acc_n = 0U;
            }
        }
        got += want;
    }
    COSLAM_ASSERT(idx == n_points);
    scan->raw_stamp_ms = (uint32_t)raw;
    scan->stamp_us = unwrap_stamp(u, (uint32_t)raw);
    scan->n_points = (uint16_t)n_points;
    u->stats.scans_ok++;
    return COSLAM_OK;
}

/* "MD"/"GD" + first(4) + last(4) + cluster(2) [+ interval(1) + scans(2)] */
static size_t format_scan_cmd(char *out, char c0, uint16_t first, uint16_t last, uint16_t cluster, int md,
                              uint8_t interval, uint8_t n_scans)
{
    out[0] = c0;
    out[1] = 'D';
    put_dec(out + 2, first, 4U);
    put_dec(out + 6, last, 4U);
    put_dec(out + 10, cluster, 2U);
    if (!md) {
        return 12U;
    }
    put_dec(out + 12, interval, 1U);
    put_dec(out + 13, n_scans, 2U);
    return 15U;
}

static void scan_header(urg_scip2_scan_t *scan, uint16_t first, uint16_t last, uint16_t cluster)
{
    scan->first_step = first;
    scan->last_step = last;
    scan->cluster = cluster == 0U ? 1U : cluster;
    scan->remaining = 0U;
    scan->n_points = 0U;
}

/* MD's acknowledgement after its status line (not "99"): streaming from
 * here on. */
static coslam_status_t md_rest(urg_scip2_t *u, const char status[3], const char *cmd, uint16_t first, uint16_t last,
                               uint16_t cluster, uint8_t n_scans)
{
    if (strcmp(status, "00") != 0) {
        return status_error(u, status);
    }
    const coslam_status_t st = end_of_message(u);
    if (st != COSLAM_OK) {
        return st;
    }
    memcpy(u->md_echo, cmd, 13U);
    u->md_echo[13] = '\0';
    u->md_first = first;
    u->md_last = last;
    u->md_cluster = cluster;
    u->md_n_scans = n_scans;
    u->streaming = 1;
    return COSLAM_OK;
}

coslam_status_t urg_scip2_start_md(urg_scip2_t *u, uint16_t first, uint16_t last, uint16_t cluster,
                                   uint8_t interval, uint8_t n_scans)
{
    if (u == NULL || interval > 9U || n_scans > 99U) {
        return COSLAM_E_ARG;
    }
    coslam_status_t st = check_range_args(u, first, last, cluster);
    if (st != COSLAM_OK) {
        return st;
    }
    char cmd[16];
    const size_t n = format_scan_cmd(cmd, 'M', first, last, cluster, 1, interval, n_scans);
    char status[3];
    u->streaming = 0;
    st = command(u, cmd, n, status);
    for (unsigned skipped = 0; st == COSLAM_OK && strcmp(status, "99") == 0; ++skipped) {
        /* a scan of an MD with this very command still running (a driver
         * restarted without QT): an unlimited MD's scans repeat the command
         * as their echo, so only the status tells them from the
         * acknowledgement. Skipped; the acknowledgement follows. */
        if (skipped >= u->cfg.max_skipped_messages) {
            u->stats.err_echo++;
            return fail_resync(u, COSLAM_E_URG_ECHO);
        }
        st = discard_to_empty_line(u, u->cfg.byte_timeout_us, 1);
        if (st == COSLAM_E_URG_TIMEOUT) {
            u->stats.err_timeout++; /* the stale scan broke off: counted as in await_echo */
        }
        if (st == COSLAM_OK) {
            st = reply_status(u, cmd, n, status);
        }
    }
    if (st != COSLAM_OK) {
        return st;
    }
    return md_rest(u, status, cmd, first, last, cluster, n_scans);
}

/* ------------------------------------------------------------------------
 * Commands without waiting (urg_scip2_begin_*, urg_scip2_poll)
 * --------------------------------------------------------------------- */

/* Send `cmd` (without LF) and note it as the command whose reply the polls
 * wait for. What is buffered is dropped first, and a pending
 * resynchronisation with it: no reply is due (nothing was pending), and the
 * rest of a broken or abandoned one, should it still come, begins with a
 * line that is not this echo and is skipped by the polls. The write does
 * not wait either: a port that cannot take the command now fails it
 * (COSLAM_E_URG_IO). */
static coslam_status_t begin(urg_scip2_t *u, uint8_t kind, const char *cmd, size_t n)
{
    COSLAM_ASSERT(n <= sizeof u->pend_cmd);
    u->pend = URG_SCIP2_PEND_NONE;
    if (u->resync_pending && !u->resync_skip) {
        u->stats.resyncs++; /* its end was lost, as command() counts it */
    }
    u->stats.bytes_discarded += (uint32_t)(u->rx_len - u->rx_pos);
    u->rx_pos = u->rx_len = 0U;
    rx_marks_reset(u);
    u->last_byte_lf = 1;
    u->resync_pending = 0;
    u->resync_skip = 0;
    const coslam_status_t st = send_cmd(u, cmd, n, 0U);
    if (st != COSLAM_OK) {
        return st;
    }
    memcpy(u->pend_cmd, cmd, n);
    u->pend_len = (uint8_t)n;
    u->pend_skipped = 0U;
    u->pend = kind;
    return COSLAM_OK;
}

coslam_status_t urg_scip2_begin_enter_scip2(urg_scip2_t *u)
{
    if (u == NULL) {
        return COSLAM_E_ARG;
    }
    reset_input(u);
    return begin(u, URG_SCIP2_PEND_SCIP2, "SCIP2.0", 7U);
}

coslam_status_t urg_scip2_begin_read_params(urg_scip2_t *u)
{
    if (u == NULL) {
        return COSLAM_E_ARG;
    }
    return begin(u, URG_SCIP2_PEND_PP, "PP", 2U);
}

coslam_status_t urg_scip2_begin_start_md(urg_scip2_t *u, uint16_t first, uint16_t last, uint16_t cluster,
                                         uint8_t interval, uint8_t n_scans)
{
    if (u == NULL) {
        return COSLAM_E_ARG;
    }
    u->pend = URG_SCIP2_PEND_NONE; /* refused or not, the one begun before is given up */
    if (interval > 9U || n_scans > 99U) {
        return COSLAM_E_ARG;
    }
    const coslam_status_t st = check_range_args(u, first, last, cluster);
    if (st != COSLAM_OK) {
        return st;
    }
    char cmd[16];
    const size_t n = format_scan_cmd(cmd, 'M', first, last, cluster, 1, interval, n_scans);
    u->streaming = 0;
    u->pend_first = first;
    u->pend_last = last;
    u->pend_cluster = cluster;
    u->pend_n_scans = n_scans;
    return begin(u, URG_SCIP2_PEND_MD, cmd, n);
}

/* The reply to the begun command, whose echo has been read: the rest of it,
 * from the buffer. *stale is set for an MD scan that repeats the command as
 * its echo (status "99": an MD of this very command still running). */
static coslam_status_t pend_rest(urg_scip2_t *u, int *stale)
{
    *stale = 0;
    if (u->pend == URG_SCIP2_PEND_SCIP2) {
        return scip2_rest(u);
    }
    coslam_status_t st = body_line(u);
    char status[3];
    if (st == COSLAM_OK) {
        st = check_status_line(u, status);
    }
    if (st != COSLAM_OK) {
        return st;
    }
    if (u->pend == URG_SCIP2_PEND_PP) {
        return params_rest(u, status, NULL);
    }
    if (strcmp(status, "99") == 0) {
        *stale = 1;
        return COSLAM_OK;
    }
    return md_rest(u, status, u->pend_cmd, u->pend_first, u->pend_last, u->pend_cluster, u->pend_n_scans);
}

/* One more stale reply skipped while a command waits: within
 * max_skipped_messages, as a waiting command's (stray empty lines count). */
static int pend_skip_ok(urg_scip2_t *u, unsigned n)
{
    if ((unsigned)u->pend_skipped + n > u->cfg.max_skipped_messages) {
        u->stats.err_echo++;
        u->pend = URG_SCIP2_PEND_NONE;
        return 0;
    }
    u->pend_skipped = (uint8_t)(u->pend_skipped + n);
    return 1;
}

coslam_status_t urg_scip2_poll(urg_scip2_t *u)
{
    if (u == NULL) {
        return COSLAM_E_ARG;
    }
    if (u->pend == URG_SCIP2_PEND_NONE) {
        return COSLAM_E_EMPTY;
    }
    for (;;) {
        unsigned skipped = 0U;
        coslam_status_t st = gather_message(u, 0U, u->pend_cmd, u->pend_len, &skipped);
        if (!pend_skip_ok(u, skipped)) {
            return COSLAM_E_URG_ECHO; /* the last one's rest is being skipped */
        }
        if (st == COSLAM_E_URG_TIMEOUT) {
            return st; /* not (whole) yet: not counted */
        }
        int began = 0;
        if (st == COSLAM_OK) {
            /* a whole message is buffered, its first line this echo (or one
             * first_line refuses): what follows reads only it */
            st = first_line(u, 0U, &began);
        }
        if (st != COSLAM_OK) {
            u->pend = URG_SCIP2_PEND_NONE;
            return st;
        }
        int stale = 0;
        st = pend_rest(u, &stale);
        if (st != COSLAM_OK || !stale) {
            u->pend = URG_SCIP2_PEND_NONE;
            return st;
        }
        /* a scan of an MD of this very command still running: skipped */
        if (!pend_skip_ok(u, 1U)) {
            return fail_resync(u, COSLAM_E_URG_ECHO);
        }
        st = discard_to_empty_line(u, 0U, 1);
        if (st != COSLAM_OK) {
            u->pend = URG_SCIP2_PEND_NONE;
            return st;
        }
    }
}

int urg_scip2_pending(const urg_scip2_t *u)
{
    return u != NULL && u->pend != URG_SCIP2_PEND_NONE;
}

void urg_scip2_abandon(urg_scip2_t *u)
{
    if (u == NULL || u->pend == URG_SCIP2_PEND_NONE) {
        return;
    }
    u->stats.err_timeout++; /* a reply was due */
    u->pend = URG_SCIP2_PEND_NONE;
    if (u->rx_pos < u->rx_len || !u->last_byte_lf) {
        /* part of a reply came: broken, as a waiting command's that stops
         * mid-message (the next command discards its rest) */
        (void)fail_resync(u, COSLAM_E_URG_TIMEOUT);
    }
}

coslam_status_t urg_scip2_read_scan(urg_scip2_t *u, urg_scip2_scan_t *scan, uint32_t timeout_us)
{
    if (u == NULL || scan == NULL) {
        return COSLAM_E_ARG;
    }
    if (!u->streaming || u->pend != URG_SCIP2_PEND_NONE) {
        return COSLAM_E_EMPTY; /* while a command is begun, what comes is its poll's */
    }
    scan_header(scan, u->md_first, u->md_last, u->md_cluster);
    for (;;) {
        coslam_status_t st = gather_message(u, timeout_us, NULL, 0U, NULL);
        if (st != COSLAM_OK) {
            return st;
        }
        int began = 0;
        st = first_line(u, 0U, &began);
        if (st != COSLAM_OK) {
            return st; /* idle timeout (not counted) or counted error */
        }
        if (u->line_len == 0U) {
            continue; /* stray empty line between messages */
        }
        if (u->line_len != 15U || memcmp(u->line, u->md_echo, 13U) != 0) {
            u->stats.err_echo++;
            return fail_resync(u, COSLAM_E_URG_ECHO);
        }
        const int32_t remaining = get_dec(u->line + 13, 2U);
        if (remaining < 0) {
            u->stats.err_echo++;
            return fail_resync(u, COSLAM_E_URG_ECHO);
        }
        st = body_line(u);
        if (st != COSLAM_OK) {
            return st;
        }
        char status[3];
        st = check_status_line(u, status);
        if (st != COSLAM_OK) {
            return st;
        }
        if (strcmp(status, "00") == 0) {
            /* a repeated acknowledgement, not a scan */
            st = end_of_message(u);
            if (st != COSLAM_OK) {
                return st;
            }
            u->stats.messages_skipped++;
            continue;
        }
        if (strcmp(status, "99") != 0) {
            if (remaining == 0 && u->md_n_scans != 0U) {
                u->streaming = 0; /* its last message: the sensor has stopped */
            }
            return status_error(u, status);
        }
        scan->remaining = (uint16_t)remaining;
        st = read_scan_data(u, scan, scan_points(u->md_first, u->md_last, u->md_cluster));
        if (remaining == 0 && u->md_n_scans != 0U) {
            u->streaming = 0; /* a finite MD's last scan, whole or not: the sensor has stopped */
        }
        if (st != COSLAM_OK) {
            scan->n_points = 0U;
            return st;
        }
        return COSLAM_OK;
    }
}

coslam_status_t urg_scip2_get_scan(urg_scip2_t *u, uint16_t first, uint16_t last, uint16_t cluster,
                                   urg_scip2_scan_t *scan)
{
    if (u == NULL || scan == NULL || u->streaming) {
        return COSLAM_E_ARG;
    }
    coslam_status_t st = check_range_args(u, first, last, cluster);
    if (st != COSLAM_OK) {
        return st;
    }
    scan_header(scan, first, last, cluster);
    char cmd[16];
    const size_t n = format_scan_cmd(cmd, 'G', first, last, cluster, 0, 0U, 0U);
    char status[3];
    st = command(u, cmd, n, status);
    if (st != COSLAM_OK) {
        return st;
    }
    if (strcmp(status, "00") != 0) {
        return status_error(u, status);
    }
    return read_scan_data(u, scan, scan_points(first, last, cluster));
}
