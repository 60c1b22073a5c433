#include "cia402/cia402_drive.h"

#include <stddef.h>
#include <string.h>

/* bring-up steps of the CONFIG phase, in order */
enum {
    STEP_VENDOR = 0,
    STEP_PRODUCT,
    STEP_HEARTBEAT,
    STEP_MASTER_WATCH, /* skipped without a master node id */
    STEP_LOSS_ACTION,  /* skipped without a master node id */
    STEP_MODE,
    STEP_MODE_CHECK,
    STEP_STATUSWORD,
    STEP_NMT_START,
};

/* elapsed time, 0 if `since` lies in the future (a frame stamped after now) */
static uint64_t elapsed_us(uint64_t now_us, uint64_t since_us)
{
    return now_us > since_us ? now_us - since_us : 0u;
}

cia402_drive_config_t cia402_drive_config_default(uint8_t node_id)
{
    cia402_drive_config_t c;
    c.node_id = node_id;
    c.heartbeat_period_ms = 100;
    c.heartbeat_timeout_us = 250000;
    c.sdo_timeout_us = 50000;
    c.boot_timeout_us = 2000000;
    c.pdo_timeout_us = 100000;
    c.rpdo_period_us = 10000;
    c.master_node_id = 127;
    c.master_timeout_ms = 200;
    c.master_loss_action = CIA402_ABORT_QUICK_STOP;
    return c;
}

coslam_status_t cia402_drive_config_check(const cia402_drive_config_t *c)
{
    if (c == NULL || !canopen_node_id_valid(c->node_id)) return COSLAM_E_ARG;
    if (c->heartbeat_period_ms == 0u) return COSLAM_E_ARG;
    if ((uint64_t)c->heartbeat_timeout_us <= (uint64_t)c->heartbeat_period_ms * 1000u) return COSLAM_E_ARG;
    if (c->sdo_timeout_us == 0u || c->boot_timeout_us == 0u || c->rpdo_period_us == 0u) return COSLAM_E_ARG;
    if (c->master_node_id != 0u) {
        if (!canopen_node_id_valid(c->master_node_id) || c->master_node_id == c->node_id) return COSLAM_E_ARG;
        if (c->master_timeout_ms == 0u) return COSLAM_E_ARG;
        if (c->master_loss_action < CIA402_ABORT_FAULT || c->master_loss_action > CIA402_ABORT_QUICK_STOP) {
            return COSLAM_E_ARG;
        }
    }
    return COSLAM_OK;
}

const char *cia402_fault_str(cia402_fault_t reason)
{
    switch (reason) {
    case CIA402_FAULT_NONE: return "NONE";
    case CIA402_FAULT_BOOT_TIMEOUT: return "BOOT_TIMEOUT";
    case CIA402_FAULT_SDO_TIMEOUT: return "SDO_TIMEOUT";
    case CIA402_FAULT_SDO_ABORT: return "SDO_ABORT";
    case CIA402_FAULT_CONFIG: return "CONFIG";
    case CIA402_FAULT_HEARTBEAT: return "HEARTBEAT";
    case CIA402_FAULT_NMT: return "NMT";
    case CIA402_FAULT_PDO_TIMEOUT: return "PDO_TIMEOUT";
    case CIA402_FAULT_EMCY: return "EMCY";
    case CIA402_FAULT_DEVICE: return "DEVICE";
    case CIA402_FAULT_BUS: return "BUS";
    case CIA402_FAULT_LEFT_ENABLED: return "LEFT_ENABLED";
    }
    return "UNKNOWN";
}

/* ------------------------------------------------------------------------ */

static void latch(cia402_drive_t *d, cia402_fault_t reason, uint64_t now_us)
{
    if (d->fault.reason != CIA402_FAULT_NONE) return; /* the first cause is kept */
    d->fault.reason = reason;
    d->latched_emcy = reason == CIA402_FAULT_EMCY ? d->fault.emcy_code : 0u; /* later EMCYs overwrite emcy_code */
    d->fault.stamp_us = now_us;
    d->fault.statusword = d->statusword;
    d->fault_count++;
    d->reset_requested = 0;
    if (d->phase == CIA402_DRIVE_BOOT || d->phase == CIA402_DRIVE_CONFIG) d->phase = CIA402_DRIVE_HALTED;
}

/* Send one frame without waiting. A full queue is retried by the caller
 * (counted); an error that will not go away latches a BUS fault. */
static hal_status_t send(cia402_drive_t *d, const hal_can_frame_t *f, uint64_t now_us)
{
    const hal_status_t s = hal_can_send(d->can, f, 0);
    if (s == HAL_OK) {
        d->tx_frames++;
        return s;
    }
    d->tx_failures++;
    d->fault.hal_status = s;
    if (s != HAL_E_TIMEOUT && s != HAL_E_BUSY) latch(d, CIA402_FAULT_BUS, now_us);
    return s;
}

static void sdo_begin(cia402_drive_t *d, int upload, uint16_t index, uint8_t sub, uint32_t value, uint8_t size,
                      int internal)
{
    cia402_sdo_t *s = &d->sdo;
    memset(s, 0, sizeof *s);
    s->state = CIA402_SDO_BUSY;
    s->upload = (uint8_t)(upload != 0);
    s->internal = (uint8_t)(internal != 0);
    s->index = index;
    s->subindex = sub;
    s->size = size;
    s->value = upload ? 0u : value;
    if (upload) {
        (void)canopen_sdo_upload_frame(&s->request, d->cfg.node_id, index, sub);
    } else {
        (void)canopen_sdo_download_frame(&s->request, d->cfg.node_id, index, sub, value, size);
    }
}

/* Send a pending request; expire a sent one. */
static void sdo_progress(cia402_drive_t *d, uint64_t now_us)
{
    cia402_sdo_t *s = &d->sdo;
    if (s->state != CIA402_SDO_BUSY) return;
    if (!s->sent) {
        if (send(d, &s->request, now_us) == HAL_OK) {
            s->sent = 1;
            s->deadline_us = now_us + d->cfg.sdo_timeout_us;
        }
        return;
    }
    if (now_us >= s->deadline_us) {
        hal_can_frame_t f;
        (void)canopen_sdo_abort_frame(&f, d->cfg.node_id, s->index, s->subindex, CANOPEN_SDO_ABORT_TIMEOUT);
        (void)send(d, &f, now_us);
        s->state = CIA402_SDO_TIMEOUT;
    }
}

static void sdo_fail(cia402_drive_t *d, uint32_t abort_code, uint64_t now_us)
{
    hal_can_frame_t f;
    (void)canopen_sdo_abort_frame(&f, d->cfg.node_id, d->sdo.index, d->sdo.subindex, abort_code);
    (void)send(d, &f, now_us);
    d->sdo.state = CIA402_SDO_ERROR;
}

static void on_sdo_reply(cia402_drive_t *d, const hal_can_frame_t *f)
{
    cia402_sdo_t *s = &d->sdo;
    if (s->state != CIA402_SDO_BUSY || !s->sent) {
        d->rx_unexpected++;
        return;
    }
    canopen_sdo_reply_t r;
    if (canopen_sdo_parse_reply(f, &r) != COSLAM_OK) {
        d->rx_malformed++;
        sdo_fail(d, CANOPEN_SDO_ABORT_COMMAND, f->stamp_us);
        return;
    }
    if (r.kind == CANOPEN_SDO_REPLY_ABORT) {
        /* an abort for another object is still the end of this transfer */
        s->abort_code = r.abort_code;
        s->state = CIA402_SDO_ABORTED;
        return;
    }
    if (r.index != s->index || r.subindex != s->subindex) {
        sdo_fail(d, CANOPEN_SDO_ABORT_GENERAL, f->stamp_us);
        return;
    }
    switch (r.kind) {
    case CANOPEN_SDO_REPLY_DOWNLOAD_ACK:
        if (s->upload) {
            sdo_fail(d, CANOPEN_SDO_ABORT_COMMAND, f->stamp_us);
        } else {
            s->state = CIA402_SDO_DONE;
        }
        break;
    case CANOPEN_SDO_REPLY_UPLOAD:
        if (!s->upload) {
            sdo_fail(d, CANOPEN_SDO_ABORT_COMMAND, f->stamp_us);
        } else {
            s->value = r.value;
            s->size = r.size;
            s->state = CIA402_SDO_DONE;
        }
        break;
    case CANOPEN_SDO_REPLY_SEGMENTED: /* only expedited transfers are supported */
    case CANOPEN_SDO_REPLY_ABORT:
    default:
        sdo_fail(d, CANOPEN_SDO_ABORT_COMMAND, f->stamp_us);
        break;
    }
}

static void on_heartbeat(cia402_drive_t *d, const hal_can_frame_t *f)
{
    canopen_nmt_state_t st;
    if (canopen_heartbeat_parse(f, &st) != COSLAM_OK) {
        d->rx_malformed++;
        return;
    }
    d->last_hb_us = f->stamp_us;
    d->nmt_state = (uint8_t)st;
    if (st == CANOPEN_NMT_STATE_BOOTUP) {
        if (d->phase == CIA402_DRIVE_BOOT && d->step_sent) {
            d->phase = CIA402_DRIVE_CONFIG;
            d->step = STEP_VENDOR;
            d->sdo.state = CIA402_SDO_IDLE;
        } else if (d->phase == CIA402_DRIVE_CONFIG || d->phase == CIA402_DRIVE_RUN) {
            latch(d, CIA402_FAULT_NMT, f->stamp_us); /* it rebooted behind our back */
        } else {
            d->rx_unexpected++;
        }
        return;
    }
    if (d->phase != CIA402_DRIVE_RUN) return;
    if (st == CANOPEN_NMT_STATE_OPERATIONAL) {
        d->nmt_confirmed = 1;
    } else if (d->nmt_confirmed) {
        latch(d, CIA402_FAULT_NMT, f->stamp_us);
    }
}

static void on_emcy(cia402_drive_t *d, const hal_can_frame_t *f)
{
    canopen_emcy_t e;
    if (canopen_emcy_parse(f, &e) != COSLAM_OK) {
        d->rx_malformed++;
        return;
    }
    d->emcy_count++;
    if (e.error_code == 0u) return; /* "error reset / no error" */
    d->fault.emcy_code = e.error_code;
    d->fault.emcy_register = e.error_register;
    if (d->phase != CIA402_DRIVE_IDLE) latch(d, CIA402_FAULT_EMCY, f->stamp_us);
}

static cia402_rx_t on_tpdo(cia402_drive_t *d, const hal_can_frame_t *f)
{
    uint16_t sw;
    int32_t vel;
    if (cia402_tpdo_parse(f, &sw, &vel) != COSLAM_OK) {
        d->rx_malformed++;
        return CIA402_RX_CONSUMED;
    }
    if (d->phase != CIA402_DRIVE_RUN) {
        d->rx_unexpected++; /* a PDO before NMT start: stale, ignore */
        return CIA402_RX_CONSUMED;
    }
    d->statusword = sw;
    d->state = cia402_state_from_statusword(sw);
    d->velocity_actual = vel;
    d->last_tpdo_us = f->stamp_us;
    d->fault.statusword = sw;
    if (d->state == CIA402_STATE_FAULT || d->state == CIA402_STATE_FAULT_REACTION_ACTIVE) {
        latch(d, CIA402_FAULT_DEVICE, f->stamp_us);
    } else if (d->goal == CIA402_GOAL_ENABLED && d->state == CIA402_STATE_OPERATION_ENABLED) {
        d->was_enabled = 1;
    } else if (d->goal == CIA402_GOAL_ENABLED && d->was_enabled) {
        /* out of OPERATION_ENABLED by the drive's own hand (its quick-stop
         * or STO input): stopped, not re-enabled by the master */
        latch(d, CIA402_FAULT_LEFT_ENABLED, f->stamp_us);
    }
    return CIA402_RX_TPDO;
}

cia402_rx_t cia402_drive_on_frame(cia402_drive_t *d, const hal_can_frame_t *frame)
{
    if (d == NULL || frame == NULL) return CIA402_RX_NOT_MINE;
    uint8_t node = 0;
    const canopen_fn_t fn = canopen_classify(frame, &node);
    if (node != d->cfg.node_id) return CIA402_RX_NOT_MINE;
    switch (fn) {
    case CANOPEN_FN_SDO_TX:
        d->rx_frames++;
        on_sdo_reply(d, frame);
        return CIA402_RX_CONSUMED;
    case CANOPEN_FN_HEARTBEAT:
        d->rx_frames++;
        on_heartbeat(d, frame);
        return CIA402_RX_CONSUMED;
    case CANOPEN_FN_EMCY:
        d->rx_frames++;
        on_emcy(d, frame);
        return CIA402_RX_CONSUMED;
    case CANOPEN_FN_TPDO1:
        d->rx_frames++;
        return on_tpdo(d, frame);
    default:
        /* our own request COB-IDs (another master?) and everything else */
        return CIA402_RX_NOT_MINE;
    }
}

/* ------------------------------------------------------------------------ */

coslam_status_t cia402_drive_init(cia402_drive_t *d, const cia402_drive_config_t *cfg, hal_can_t *can)
{
    if (d == NULL || can == NULL || cia402_drive_config_check(cfg) != COSLAM_OK) return COSLAM_E_ARG;
    memset(d, 0, sizeof *d);
    d->cfg = *cfg;
    d->can = can;
    d->phase = CIA402_DRIVE_IDLE;
    d->state = CIA402_STATE_UNKNOWN;
    d->goal = CIA402_GOAL_DISABLED;
    d->fault.hal_status = HAL_OK;
    return COSLAM_OK;
}

coslam_status_t cia402_drive_start(cia402_drive_t *d, uint64_t now_us)
{
    if (d == NULL) return COSLAM_E_ARG;
    d->phase = CIA402_DRIVE_BOOT;
    d->step = 0;
    d->step_sent = 0;
    memset(&d->sdo, 0, sizeof d->sdo);
    memset(&d->fault, 0, sizeof d->fault);
    d->fault.hal_status = HAL_OK;
    d->reset_requested = 0;
    d->hb_supervised = 0;
    d->nmt_confirmed = 0;
    d->state = CIA402_STATE_UNKNOWN;
    d->statusword = 0;
    d->velocity_actual = 0;
    d->goal = CIA402_GOAL_DISABLED;
    d->was_enabled = 0;
    d->target_velocity = 0;
    d->rpdo_sent = 0;
    (void)cia402_drive_poll(d, now_us);
    return COSLAM_OK;
}

static void poll_boot(cia402_drive_t *d, uint64_t now_us)
{
    if (!d->step_sent) {
        hal_can_frame_t f;
        canopen_nmt_frame(&f, CANOPEN_NMT_RESET_NODE, d->cfg.node_id);
        if (send(d, &f, now_us) == HAL_OK) {
            d->step_sent = 1;
            d->step_deadline_us = now_us + d->cfg.boot_timeout_us;
        }
        return;
    }
    if (now_us >= d->step_deadline_us) latch(d, CIA402_FAULT_BOOT_TIMEOUT, now_us);
}

static void config_start_step(cia402_drive_t *d)
{
    switch (d->step) {
    case STEP_VENDOR: sdo_begin(d, 1, CIA402_OD_IDENTITY, 1, 0, 0, 1); break;
    case STEP_PRODUCT: sdo_begin(d, 1, CIA402_OD_IDENTITY, 2, 0, 0, 1); break;
    case STEP_HEARTBEAT:
        sdo_begin(d, 0, CIA402_OD_HEARTBEAT_PRODUCER, 0, d->cfg.heartbeat_period_ms, 2, 1);
        break;
    case STEP_MASTER_WATCH:
        sdo_begin(d, 0, CIA402_OD_CONSUMER_HEARTBEAT, 1,
                  ((uint32_t)d->cfg.master_node_id << 16) | (uint32_t)d->cfg.master_timeout_ms, 4, 1);
        break;
    case STEP_LOSS_ACTION:
        sdo_begin(d, 0, CIA402_OD_ABORT_CONNECTION, 0, (uint32_t)(uint16_t)d->cfg.master_loss_action, 2, 1);
        break;
    case STEP_MODE: sdo_begin(d, 0, CIA402_OD_MODES_OF_OPERATION, 0, CIA402_MODE_PROFILE_VELOCITY, 1, 1); break;
    case STEP_MODE_CHECK: sdo_begin(d, 1, CIA402_OD_MODES_DISPLAY, 0, 0, 0, 1); break;
    case STEP_STATUSWORD: sdo_begin(d, 1, CIA402_OD_STATUSWORD, 0, 0, 0, 1); break;
    default: break;
    }
}

/* A bring-up step failed: its object is kept with the fault. */
static void config_fail(cia402_drive_t *d, cia402_fault_t reason, uint64_t now_us)
{
    d->fault.sdo_index = d->sdo.index;
    latch(d, reason, now_us);
}

/* Take the finished SDO of the current step; 0 if the bring-up stopped. */
static int config_finish_step(cia402_drive_t *d, uint64_t now_us)
{
    cia402_sdo_t *s = &d->sdo;
    s->state = CIA402_SDO_IDLE;
    switch (d->step) {
    case STEP_VENDOR: d->vendor_id = s->value; break;
    case STEP_PRODUCT: d->product_code = s->value; break;
    case STEP_HEARTBEAT:
        d->hb_supervised = 1;
        d->last_hb_us = now_us;
        break;
    case STEP_MASTER_WATCH:
    case STEP_LOSS_ACTION:
    case STEP_MODE: break;
    case STEP_MODE_CHECK:
        if ((s->value & 0xFFu) != (uint32_t)CIA402_MODE_PROFILE_VELOCITY) {
            config_fail(d, CIA402_FAULT_CONFIG, now_us);
            return 0;
        }
        break;
    case STEP_STATUSWORD:
        d->statusword = (uint16_t)(s->value & 0xFFFFu);
        d->state = cia402_state_from_statusword(d->statusword);
        break;
    default: break;
    }
    d->step++;
    return 1;
}

static void poll_config(cia402_drive_t *d, uint64_t now_us)
{
    cia402_sdo_t *s = &d->sdo;
    switch (s->state) {
    case CIA402_SDO_DONE:
        if (!config_finish_step(d, now_us)) return;
        break;
    case CIA402_SDO_ABORTED:
        d->fault.sdo_abort_code = s->abort_code;
        config_fail(d, CIA402_FAULT_SDO_ABORT, now_us);
        return;
    case CIA402_SDO_TIMEOUT: config_fail(d, CIA402_FAULT_SDO_TIMEOUT, now_us); return;
    case CIA402_SDO_ERROR: config_fail(d, CIA402_FAULT_CONFIG, now_us); return;
    case CIA402_SDO_IDLE:
    case CIA402_SDO_BUSY: break;
    }
    if (d->step == STEP_NMT_START) {
        hal_can_frame_t f;
        canopen_nmt_frame(&f, CANOPEN_NMT_START, d->cfg.node_id);
        if (send(d, &f, now_us) == HAL_OK) {
            d->phase = CIA402_DRIVE_RUN;
            d->run_since_us = now_us;
            d->last_tpdo_us = now_us;
            d->nmt_confirmed = 0;
            d->rpdo_sent = 0;
        }
        return;
    }
    if (s->state == CIA402_SDO_IDLE) {
        if (d->cfg.master_node_id == 0u && (d->step == STEP_MASTER_WATCH || d->step == STEP_LOSS_ACTION)) {
            d->step = STEP_MODE; /* no drive-side watchdog configured */
        }
        config_start_step(d);
    }
    sdo_progress(d, now_us);
}

static void supervise(cia402_drive_t *d, uint64_t now_us)
{
    if (d->hb_supervised && elapsed_us(now_us, d->last_hb_us) > d->cfg.heartbeat_timeout_us) {
        latch(d, CIA402_FAULT_HEARTBEAT, now_us);
    }
    if (d->phase != CIA402_DRIVE_RUN) return;
    if (!d->nmt_confirmed) {
        if (elapsed_us(now_us, d->run_since_us) > d->cfg.heartbeat_timeout_us) latch(d, CIA402_FAULT_NMT, now_us);
    } else if (d->cfg.pdo_timeout_us > 0u && elapsed_us(now_us, d->last_tpdo_us) > d->cfg.pdo_timeout_us) {
        latch(d, CIA402_FAULT_PDO_TIMEOUT, now_us);
    }
}

static int drive_in_fault(const cia402_drive_t *d)
{
    return d->state == CIA402_STATE_FAULT || d->state == CIA402_STATE_FAULT_REACTION_ACTIVE;
}

static void poll_run(cia402_drive_t *d, uint64_t now_us)
{
    if (d->sdo.state == CIA402_SDO_BUSY) sdo_progress(d, now_us);

    uint16_t cw;
    int32_t vel = 0;
    if (d->fault.reason != CIA402_FAULT_NONE) {
        const int device = d->fault.reason == CIA402_FAULT_EMCY || d->fault.reason == CIA402_FAULT_DEVICE;
        if (d->reset_requested && device && !drive_in_fault(d)) {
            /* the drive left FAULT (or never entered it): the reset is done */
            memset(&d->fault, 0, sizeof d->fault);
            d->fault.hal_status = HAL_OK;
            d->reset_requested = 0;
            cw = cia402_controlword_for(d->state, d->goal);
        } else if (d->reset_requested && device && d->state == CIA402_STATE_FAULT) {
            /* fault reset acts on the rising edge of bit 7: bit 7 low first
             * (stage 1, unless it was low already), then high (stage 2),
             * held until the drive leaves FAULT */
            const int low_first = d->reset_requested == 1 && (!d->rpdo_sent || (d->last_cw & CIA402_CW_FAULT_RESET) != 0u);
            cw = low_first ? CIA402_CW_DISABLE_VOLTAGE : CIA402_CW_FAULT_RESET;
        } else if (drive_in_fault(d)) {
            cw = CIA402_CW_DISABLE_VOLTAGE;
        } else {
            cw = cia402_controlword_for(d->state, CIA402_GOAL_QUICK_STOP);
        }
    } else {
        cw = cia402_controlword_for(d->state, d->goal);
        if (d->goal == CIA402_GOAL_ENABLED && d->state == CIA402_STATE_OPERATION_ENABLED) vel = d->target_velocity;
    }

    const int due = !d->rpdo_sent || cw != d->last_cw || vel != d->last_vel ||
                    elapsed_us(now_us, d->last_rpdo_us) >= d->cfg.rpdo_period_us;
    if (!due) return;
    hal_can_frame_t f;
    (void)cia402_rpdo_frame(&f, d->cfg.node_id, cw, vel);
    if (send(d, &f, now_us) == HAL_OK) {
        if (cw == CIA402_CW_FAULT_RESET) d->reset_requested = 2;
        d->last_cw = cw;
        d->last_vel = vel;
        d->rpdo_sent = 1;
        d->last_rpdo_us = now_us;
    }
}

coslam_status_t cia402_drive_poll(cia402_drive_t *d, uint64_t now_us)
{
    if (d == NULL) return COSLAM_E_ARG;
    switch (d->phase) {
    case CIA402_DRIVE_IDLE:
    case CIA402_DRIVE_HALTED: break;
    case CIA402_DRIVE_BOOT: poll_boot(d, now_us); break;
    case CIA402_DRIVE_CONFIG:
        supervise(d, now_us);
        if (d->phase == CIA402_DRIVE_CONFIG) poll_config(d, now_us);
        break;
    case CIA402_DRIVE_RUN:
        if (d->fault.reason == CIA402_FAULT_NONE) supervise(d, now_us);
        poll_run(d, now_us);
        break;
    }
    return d->fault.reason == CIA402_FAULT_NONE ? COSLAM_OK : COSLAM_E_DRIVE_FAULT;
}

coslam_status_t cia402_drive_set_goal(cia402_drive_t *d, cia402_goal_t goal)
{
    if (d == NULL) return COSLAM_E_ARG;
    if (goal != CIA402_GOAL_DISABLED && goal != CIA402_GOAL_ENABLED && goal != CIA402_GOAL_QUICK_STOP) {
        return COSLAM_E_ARG;
    }
    if (goal != CIA402_GOAL_ENABLED) d->was_enabled = 0;
    d->goal = goal;
    return COSLAM_OK;
}

coslam_status_t cia402_drive_set_target_velocity(cia402_drive_t *d, int32_t velocity)
{
    if (d == NULL) return COSLAM_E_ARG;
    d->target_velocity = velocity;
    return COSLAM_OK;
}

coslam_status_t cia402_drive_fault_reset(cia402_drive_t *d, uint64_t now_us)
{
    if (d == NULL) return COSLAM_E_ARG;
    d->goal = CIA402_GOAL_DISABLED;
    d->was_enabled = 0;
    d->target_velocity = 0;
    const cia402_fault_t r = d->fault.reason;
    if (r == CIA402_FAULT_NONE) return COSLAM_OK;
    /* its heartbeat consumer fired (0x8130), or it came back from bus-off
     * (0x8140): by the drive's 0x1029 default it left OPERATIONAL and takes
     * no PDOs, so only a new bring-up brings it back. Classified by the
     * EMCY that latched the fault, not a later one */
    const int comm = r == CIA402_FAULT_EMCY &&
                     (d->latched_emcy == CANOPEN_EMCY_HEARTBEAT || d->latched_emcy == CANOPEN_EMCY_BUS_OFF_RECOVERED);
    if (d->phase == CIA402_DRIVE_RUN && !comm && (r == CIA402_FAULT_EMCY || r == CIA402_FAULT_DEVICE)) {
        d->reset_requested = 1;
        return COSLAM_OK;
    }
    return cia402_drive_start(d, now_us);
}

void cia402_drive_bus_error(cia402_drive_t *d, hal_status_t hal_status, uint64_t now_us)
{
    if (d == NULL || d->phase == CIA402_DRIVE_IDLE) return;
    d->fault.hal_status = hal_status;
    latch(d, CIA402_FAULT_BUS, now_us);
}

static coslam_status_t user_sdo_allowed(const cia402_drive_t *d)
{
    if (d->phase != CIA402_DRIVE_RUN || d->sdo.state == CIA402_SDO_BUSY) return COSLAM_E_DRIVE_STATE;
    return COSLAM_OK;
}

coslam_status_t cia402_drive_sdo_read(cia402_drive_t *d, uint16_t index, uint8_t subindex, uint64_t now_us)
{
    if (d == NULL) return COSLAM_E_ARG;
    const coslam_status_t st = user_sdo_allowed(d);
    if (st != COSLAM_OK) return st;
    sdo_begin(d, 1, index, subindex, 0, 0, 0);
    sdo_progress(d, now_us);
    return COSLAM_OK;
}

coslam_status_t cia402_drive_sdo_write(cia402_drive_t *d, uint16_t index, uint8_t subindex, uint32_t value,
                                       uint8_t size, uint64_t now_us)
{
    if (d == NULL || size < 1u || size > 4u) return COSLAM_E_ARG;
    const coslam_status_t st = user_sdo_allowed(d);
    if (st != COSLAM_OK) return st;
    sdo_begin(d, 0, index, subindex, value, size, 0);
    sdo_progress(d, now_us);
    return COSLAM_OK;
}

cia402_sdo_state_t cia402_drive_sdo_state(const cia402_drive_t *d, uint32_t *value, uint32_t *abort_code)
{
    if (d == NULL || d->sdo.internal) return CIA402_SDO_IDLE;
    if (value != NULL) *value = d->sdo.value;
    if (abort_code != NULL) *abort_code = d->sdo.abort_code;
    return d->sdo.state;
}

const cia402_fault_info_t *cia402_drive_fault(const cia402_drive_t *d)
{
    return d == NULL ? NULL : &d->fault;
}

int cia402_drive_is_enabled(const cia402_drive_t *d)
{
    return d != NULL && d->phase == CIA402_DRIVE_RUN && d->fault.reason == CIA402_FAULT_NONE &&
           d->state == CIA402_STATE_OPERATION_ENABLED;
}
