/* A scripted fake hal_serial_t for driver tests. Writes are recorded into a
 * fixed array; replies are script segments that become readable once the
 * driver has made `gate` writes (or the test released them). Reads are cut
 * at `max_chunk` bytes and never cross the absolute stream offset `cut`, so
 * a test can split a reply at any byte; with `rand_chunk` each read is also
 * cut at 1..rand_chunk bytes drawn from `chunk_state` (a seeded LCG, so a
 * run repeats). No heap. */
#ifndef COSLAM_TEST_FAKE_SERIAL_H
#define COSLAM_TEST_FAKE_SERIAL_H

#include <string.h>

#include "hal/hal_serial.h"

#define FAKE_WRITE_CAP 4096
#define FAKE_STREAM_CAP 65536
#define FAKE_SEGMENTS 64

typedef struct {
    hal_serial_t dev;
    uint8_t written[FAKE_WRITE_CAP];
    size_t n_written;
    unsigned n_writes;
    /* the reply stream: bytes [seg_start[i], seg_start[i+1]) gated by gate[i] */
    uint8_t stream[FAKE_STREAM_CAP];
    size_t stream_len;
    size_t seg_start[FAKE_SEGMENTS];
    unsigned gate[FAKE_SEGMENTS];
    size_t n_segments;
    size_t pos;         /* next byte to deliver */
    unsigned released;  /* extra gate credit granted by the test */
    size_t max_chunk;   /* 0: unlimited */
    size_t cut;         /* reads stop at this stream offset once (0: none) */
    size_t rand_chunk;  /* 0: off; else each read takes at most 1..rand_chunk bytes */
    uint32_t chunk_state; /* the LCG drawing those sizes (the test seeds it) */
    unsigned n_reads;
    unsigned n_flushes;
    hal_status_t write_result; /* HAL_OK or an error to inject */
    hal_status_t read_result;  /* HAL_OK or an error to inject */
} fake_serial_t;

static size_t fake_available_end(const fake_serial_t *f)
{
    size_t end = f->pos;
    for (size_t i = 0; i < f->n_segments; ++i) {
        const size_t s_end = (i + 1 < f->n_segments) ? f->seg_start[i + 1] : f->stream_len;
        if (f->gate[i] <= f->n_writes + f->released && s_end > end && f->seg_start[i] <= end) {
            end = s_end;
        }
    }
    return end;
}

static hal_status_t fake_write(hal_serial_t *d, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    (void)timeout_us;
    fake_serial_t *f = (fake_serial_t *)d->backend;
    if (f->write_result != HAL_OK) {
        return f->write_result;
    }
    if (f->n_written + len > FAKE_WRITE_CAP) {
        return HAL_E_OVERFLOW;
    }
    memcpy(f->written + f->n_written, data, len);
    f->n_written += len;
    f->n_writes++;
    return HAL_OK;
}

static hal_status_t fake_read(hal_serial_t *d, uint8_t *buf, size_t cap, size_t *n_read, uint32_t timeout_us)
{
    (void)timeout_us;
    fake_serial_t *f = (fake_serial_t *)d->backend;
    f->n_reads++;
    if (f->read_result != HAL_OK) {
        return f->read_result;
    }
    size_t end = fake_available_end(f);
    if (f->cut > f->pos && f->cut < end) {
        end = f->cut;
    }
    if (end <= f->pos) {
        return HAL_E_TIMEOUT;
    }
    size_t n = end - f->pos;
    if (n > cap) n = cap;
    if (f->max_chunk != 0 && n > f->max_chunk) n = f->max_chunk;
    if (f->rand_chunk != 0) {
        f->chunk_state = f->chunk_state * 1664525U + 1013904223U; /* Numerical Recipes LCG */
        const size_t lim = 1U + (size_t)(f->chunk_state >> 8) % f->rand_chunk;
        if (n > lim) n = lim;
    }
    memcpy(buf, f->stream + f->pos, n);
    f->pos += n;
    *n_read = n;
    return HAL_OK;
}

static hal_status_t fake_flush(hal_serial_t *d)
{
    fake_serial_t *f = (fake_serial_t *)d->backend;
    f->n_flushes++;
    f->pos = fake_available_end(f);
    return HAL_OK;
}

static const hal_serial_ops_t fake_ops = {
    .set_baud = NULL, .write = fake_write, .read = fake_read, .flush_input = fake_flush, .close = NULL,
};

static void fake_init(fake_serial_t *f)
{
    memset(f, 0, sizeof *f);
    f->dev.ops = &fake_ops;
    f->dev.backend = f;
}

/* Append reply bytes that become readable after the driver's gate-th write. */
static void fake_add(fake_serial_t *f, unsigned gate, const void *bytes, size_t n)
{
    if (f->n_segments >= FAKE_SEGMENTS || f->stream_len + n > FAKE_STREAM_CAP) {
        return; /* the tests size their scripts well below the caps */
    }
    f->seg_start[f->n_segments] = f->stream_len;
    f->gate[f->n_segments] = gate;
    f->n_segments++;
    memcpy(f->stream + f->stream_len, bytes, n);
    f->stream_len += n;
}

static void fake_add_str(fake_serial_t *f, unsigned gate, const char *s)
{
    fake_add(f, gate, s, strlen(s));
}

#endif
