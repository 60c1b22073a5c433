/*
 * gpiod_fake.h - a link-time fake of the libgpiod v1 calls the Linux GPIO
 * backend makes (linked with -Wl,--wrap=gpiod_...; the real library is not
 * linked at all, so a call the fake does not cover fails the link).
 *
 * It models the kernel side of the GPIO uAPI v1: one chip, lines with an
 * electrical level driven by the test, requests with the ACTIVE_LOW flag
 * applied to values and edge kinds, a 16-event queue per event line that
 * drops silently when full (as the v1 kernel does), and a fake monotonic
 * time that a timed-out event wait consumes. Faults are injectable.
 */
#ifndef COSLAM_GPIOD_FAKE_H
#define COSLAM_GPIOD_FAKE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <time.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FAKE_GPIOD_MAX_LINES 80u
#define FAKE_GPIOD_QUEUE 16u

typedef struct {
    bool requested;
    int request_type;        /* GPIOD_LINE_REQUEST_* */
    int flags;               /* GPIOD_LINE_REQUEST_FLAG_* */
    char consumer[32];
    int default_val;
    bool pin_high;           /* electrical level (inputs: set by the test; outputs: driven) */
    struct {
        int type;
        uint64_t stamp_us;
    } queue[FAKE_GPIOD_QUEUE];
    unsigned q_len;
    /* fault injection: errno to fail the next such call with (0 = none) */
    int fail_request_errno;
    int fail_get_errno;
    int fail_set_errno;
} fake_gpiod_line_t;

typedef struct {
    bool chip_open;
    unsigned num_lines;
    int fail_open_errno;       /* gpiod_chip_open_lookup fails with this errno */
    char opened_name[64];
    uint64_t now_us;           /* fake CLOCK_MONOTONIC */
    fake_gpiod_line_t lines[FAKE_GPIOD_MAX_LINES];
    /* observations */
    unsigned n_wait_calls;
    struct timespec last_wait_timeout;
    unsigned pending_eintr;    /* the next n event waits fail with EINTR */
    unsigned n_releases;
    unsigned n_chip_close;
    unsigned n_set_value;
} fake_gpiod_t;

extern fake_gpiod_t fake_gpiod;

/** Reset to a closed chip with num_lines lines, all pins low, time 0. */
void fake_gpiod_reset(unsigned num_lines);
/** Drive an input pin's electrical level; queues the logical edge on an
 *  event line if selected, stamped now_us. */
void fake_gpiod_drive(unsigned offset, bool high);
/** Electrical level of a pin (what an output drives). */
bool fake_gpiod_pin(unsigned offset);

#ifdef __cplusplus
}
#endif

#endif
