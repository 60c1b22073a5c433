/*
 * A fake hal_can_t for driver tests: every sent frame is recorded in a fixed
 * array; received frames come from a scripted FIFO the test fills; send and
 * receive failures can be injected. Header-only, one instance per test.
 */
#ifndef COSLAM_TEST_FAKE_CAN_H
#define COSLAM_TEST_FAKE_CAN_H

#include <string.h>

#include "hal/hal_can.h"

#define FAKE_CAN_CAP 512

typedef struct {
    hal_can_t can;
    hal_can_frame_t sent[FAKE_CAN_CAP];
    size_t n_sent;
    hal_can_frame_t rx[FAKE_CAN_CAP];
    size_t rx_head, rx_tail;
    hal_status_t send_status;    /**< returned by send (HAL_OK: record the frame) */
    int send_fail_count;         /**< fail this many sends with send_status, then succeed */
    hal_status_t receive_status; /**< if not HAL_OK: returned once by the next receive */
    hal_can_filter_t filters[HAL_CAN_MAX_FILTERS];
    size_t n_filters;
    int filters_set;
} fake_can_t;

static hal_status_t fake_can_send(hal_can_t *dev, const hal_can_frame_t *f, uint32_t timeout_us)
{
    fake_can_t *fc = (fake_can_t *)dev->backend;
    (void)timeout_us;
    if (fc->send_fail_count > 0) {
        fc->send_fail_count--;
        return fc->send_status;
    }
    if (fc->n_sent >= FAKE_CAN_CAP) return HAL_E_TIMEOUT;
    fc->sent[fc->n_sent++] = *f;
    return HAL_OK;
}

static hal_status_t fake_can_receive(hal_can_t *dev, hal_can_frame_t *f, uint32_t timeout_us)
{
    fake_can_t *fc = (fake_can_t *)dev->backend;
    (void)timeout_us;
    if (fc->receive_status != HAL_OK) {
        const hal_status_t s = fc->receive_status;
        fc->receive_status = HAL_OK;
        return s;
    }
    if (fc->rx_head == fc->rx_tail) return HAL_E_TIMEOUT;
    *f = fc->rx[fc->rx_head % FAKE_CAN_CAP];
    fc->rx_head++;
    return HAL_OK;
}

static hal_status_t fake_can_set_filters(hal_can_t *dev, const hal_can_filter_t *flt, size_t n)
{
    fake_can_t *fc = (fake_can_t *)dev->backend;
    if (n > HAL_CAN_MAX_FILTERS) return HAL_E_ARG;
    if (n > 0) memcpy(fc->filters, flt, n * sizeof *flt);
    fc->n_filters = n;
    fc->filters_set = 1;
    return HAL_OK;
}

static const hal_can_ops_t fake_can_ops = {
    .send = fake_can_send,
    .receive = fake_can_receive,
    .set_filters = fake_can_set_filters,
    .get_status = NULL,
    .close = NULL,
};

static inline void fake_can_init(fake_can_t *fc)
{
    memset(fc, 0, sizeof *fc);
    fc->can.ops = &fake_can_ops;
    fc->can.backend = fc;
    fc->send_status = HAL_OK;
    fc->receive_status = HAL_OK;
}

/** Queue a frame for the driver to receive, stamped stamp_us. */
static inline void fake_can_push(fake_can_t *fc, uint32_t id, const uint8_t *data, uint8_t dlc, uint64_t stamp_us)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.dlc = dlc;
    if (dlc > 0) memcpy(f.data, data, dlc);
    f.stamp_us = stamp_us;
    fc->rx[fc->rx_tail % FAKE_CAN_CAP] = f;
    fc->rx_tail++;
}

static inline void fake_can_clear_sent(fake_can_t *fc) { fc->n_sent = 0; }

#endif /* COSLAM_TEST_FAKE_CAN_H */
