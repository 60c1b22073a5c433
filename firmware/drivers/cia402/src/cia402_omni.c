#include "cia402/cia402_omni.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

cia402_omni_config_t cia402_omni_config_default(void)
{
    cia402_omni_config_t c;
    memset(&c, 0, sizeof c);
    for (int k = 0; k < OMNI_WHEELS; ++k) c.node_id[k] = (uint8_t)(k + 1);
    c.drive = cia402_drive_config_default(1);
    c.kinematics = omni_kinematics_config_default();
    c.velocity_unit_rpm = 0.1;
    c.max_motor_rpm = 3000.0;
    c.set_hal_filters = 1;
    c.master_heartbeat_period_ms = 50;
    return c;
}

cia402_omni_watchdog_rule_t cia402_omni_watchdog_check(const cia402_omni_config_t *c, int *wheel)
{
    if (c == NULL || c->drive.master_node_id == 0u) return CIA402_OMNI_WATCHDOG_OK;
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        if (c->node_id[k] == c->drive.master_node_id) {
            if (wheel != NULL) *wheel = k;
            return CIA402_OMNI_WATCHDOG_MASTER_IS_WHEEL;
        }
    }
    if (c->master_heartbeat_period_ms == 0u) return CIA402_OMNI_WATCHDOG_NO_PERIOD;
    if ((uint32_t)c->drive.master_timeout_ms < 2u * (uint32_t)c->master_heartbeat_period_ms) {
        return CIA402_OMNI_WATCHDOG_TIMEOUT_SHORT;
    }
    return CIA402_OMNI_WATCHDOG_OK;
}

static coslam_status_t config_check(const cia402_omni_config_t *c)
{
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        cia402_drive_config_t dc = c->drive;
        dc.node_id = c->node_id[k];
        if (cia402_drive_config_check(&dc) != COSLAM_OK) return COSLAM_E_ARG;
        for (int j = 0; j < k; ++j) {
            if (c->node_id[j] == c->node_id[k]) return COSLAM_E_ARG;
        }
    }
    if (cia402_omni_watchdog_check(c, NULL) != CIA402_OMNI_WATCHDOG_OK) return COSLAM_E_ARG;
    if (omni_kinematics_config_check(&c->kinematics) != COSLAM_OK) return COSLAM_E_ARG;
    if (!isfinite(c->velocity_unit_rpm) || !(c->velocity_unit_rpm > 0.0)) return COSLAM_E_ARG;
    if (!isfinite(c->max_motor_rpm) || !(c->max_motor_rpm > 0.0)) return COSLAM_E_ARG;
    return COSLAM_OK;
}

coslam_status_t cia402_omni_init(cia402_omni_t *o, const cia402_omni_config_t *cfg, hal_can_t *can)
{
    if (o == NULL || cfg == NULL || can == NULL || config_check(cfg) != COSLAM_OK) return COSLAM_E_ARG;
    memset(o, 0, sizeof *o);
    o->cfg = *cfg;
    o->can = can;
    o->fault.wheel = -1;
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        cia402_drive_config_t dc = cfg->drive;
        dc.node_id = cfg->node_id[k];
        (void)cia402_drive_init(&o->drive[k], &dc, can);
    }
    return COSLAM_OK;
}

static int32_t rpm_to_units(const cia402_omni_t *o, double rpm)
{
    const double u = rpm / o->cfg.velocity_unit_rpm;
    if (!(u > -2147483647.0)) return -2147483647; /* also NaN, which saturation cannot produce */
    if (u > 2147483647.0) return 2147483647;
    return (int32_t)lround(u);
}

/* Push goal and target velocity into the drives according to the policy. */
static void apply_commands(cia402_omni_t *o)
{
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        cia402_drive_t *d = &o->drive[k];
        if (o->fault.wheel >= 0) {
            (void)cia402_drive_set_goal(d, CIA402_GOAL_QUICK_STOP);
            (void)cia402_drive_set_target_velocity(d, 0);
        } else {
            (void)cia402_drive_set_goal(d, o->enabled_goal ? CIA402_GOAL_ENABLED : CIA402_GOAL_DISABLED);
            (void)cia402_drive_set_target_velocity(d, rpm_to_units(o, o->cmd_rpm[k]));
        }
    }
}

coslam_status_t cia402_omni_start(cia402_omni_t *o, uint64_t now_us)
{
    if (o == NULL) return COSLAM_E_ARG;
    if (o->cfg.set_hal_filters) {
        static const uint32_t bases[4] = {CANOPEN_COB_EMCY, CANOPEN_COB_TPDO1, CANOPEN_COB_SDO_TX,
                                          CANOPEN_COB_HEARTBEAT};
        hal_can_filter_t flt[4 * OMNI_WHEELS];
        size_t n = 0;
        for (int k = 0; k < OMNI_WHEELS; ++k) {
            for (int b = 0; b < 4; ++b) {
                flt[n].id = bases[b] + o->cfg.node_id[k];
                flt[n].mask = HAL_CAN_STD_ID_MAX;
                flt[n].flags = 0;
                ++n;
            }
        }
        const hal_status_t s = hal_can_set_filters(o->can, flt, n);
        if (s != HAL_OK && s != HAL_E_UNSUPPORTED) return COSLAM_E_DRIVE_BUS;
    }
    /* frames queued before this start (a drive's power-on boot-up message,
     * sent before this process was there; the tail of a run before a
     * restart) answer nothing sent from now on: read and dropped, so that an
     * old boot-up is not taken for the answer to the NMT reset below */
    for (int n = 0; n < 4 * CIA402_OMNI_RX_BUDGET; ++n) {
        hal_can_frame_t f;
        const hal_status_t s = hal_can_receive(o->can, &f, 0);
        if (s == HAL_OK) {
            o->rx_stale++;
        } else if (s == HAL_E_OVERFLOW) {
            o->rx_overflows++;
        } else if (s == HAL_E_CORRUPT) {
            o->rx_errors++; /* a malformed frame: the ones behind it are still stale */
        } else {
            break;
        }
    }
    o->enabled_goal = 0;
    memset(o->cmd_rpm, 0, sizeof o->cmd_rpm);
    memset(o->meas_rpm, 0, sizeof o->meas_rpm);
    o->meas_mask = 0;
    o->odo_running = 0;
    o->odo_last_us = 0;
    o->odo_pending_us = 0;
    memset(&o->odo_acc, 0, sizeof o->odo_acc);
    memset(&o->fault, 0, sizeof o->fault);
    o->fault.wheel = -1;
    o->master_hb_on = o->cfg.drive.master_node_id != 0u;
    o->master_hb_next_us = now_us;
    for (int k = 0; k < OMNI_WHEELS; ++k) (void)cia402_drive_start(&o->drive[k], now_us);
    return COSLAM_OK;
}

/* Integrate from odo_last_us to odo_pending_us, the stamp of the newest
 * wheel speeds: trapezoidal rule on the motor speeds (exact for speeds
 * that ramp linearly between samples; forward kinematics is linear, so this
 * is the mean body velocity), held constant along an exact arc. */
static void odo_flush(cia402_omni_t *o)
{
    if (!o->odo_running || o->odo_pending_us <= o->odo_last_us) return;
    const double dt_s = (double)(o->odo_pending_us - o->odo_last_us) * 1e-6;
    double mean[OMNI_WHEELS];
    for (int k = 0; k < OMNI_WHEELS; ++k) mean[k] = 0.5 * (o->odo_prev_rpm[k] + o->meas_rpm[k]);
    odo_increment_t inc;
    if (omni_kinematics_odometry(&o->cfg.kinematics, mean, dt_s, &inc) == COSLAM_OK) {
        o->odo_acc = omni_kinematics_compose(o->odo_acc, inc);
    } else {
        o->odo_errors++;
    }
    memcpy(o->odo_prev_rpm, o->meas_rpm, sizeof o->meas_rpm);
    o->odo_last_us = o->odo_pending_us;
}

/* Samples further apart than this are not bridged [us]: the drives' PDO
 * timeout (a TPDO later than that is a fault anyway), else 100 ms. */
static uint64_t odo_max_gap_us(const cia402_omni_t *o)
{
    return o->cfg.drive.pdo_timeout_us > 0u ? (uint64_t)o->cfg.drive.pdo_timeout_us : 100000u;
}

/* A new velocity of wheel k, sampled at stamp_us. Speeds sampled at the
 * same stamp (the three drives answer the same cycle) form one sample. */
static void on_wheel_speed(cia402_omni_t *o, int k, uint64_t stamp_us)
{
    if (o->odo_running && stamp_us > o->odo_pending_us) {
        /* the bus (or one wheel) silent for longer than a late TPDO: the
         * motion in between is not known, and a silent wheel's last speed
         * must not stand for it. Nothing is integrated across; integration
         * starts again once all three wheels have reported. */
        const uint64_t gap = odo_max_gap_us(o);
        int stale = stamp_us - o->odo_pending_us > gap;
        for (int j = 0; j < OMNI_WHEELS; ++j) {
            if (j != k && stamp_us - o->meas_us[j] > gap) stale = 1;
        }
        if (stale) {
            o->odo_running = 0;
            o->meas_mask = 0;
            o->odo_gaps++;
        } else {
            odo_flush(o);
            o->odo_pending_us = stamp_us;
        }
    }
    o->meas_rpm[k] = (double)o->drive[k].velocity_actual * o->cfg.velocity_unit_rpm;
    o->meas_us[k] = stamp_us;
    /* a late member of a sample already integrated up to (a take came
     * between the three TPDOs of one cycle) still starts the next interval */
    if (o->odo_running && stamp_us == o->odo_last_us) o->odo_prev_rpm[k] = o->meas_rpm[k];
    o->meas_mask = (uint8_t)(o->meas_mask | (1u << k));
    if (!o->odo_running && o->meas_mask == (1u << OMNI_WHEELS) - 1u) {
        o->odo_running = 1;
        o->odo_last_us = stamp_us;
        o->odo_pending_us = stamp_us;
        memcpy(o->odo_prev_rpm, o->meas_rpm, sizeof o->meas_rpm);
    }
}

static void dispatch(cia402_omni_t *o, const hal_can_frame_t *f)
{
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        const cia402_rx_t r = cia402_drive_on_frame(&o->drive[k], f);
        if (r == CIA402_RX_NOT_MINE) continue;
        if (r == CIA402_RX_TPDO) on_wheel_speed(o, k, f->stamp_us);
        return;
    }
    o->rx_foreign++;
}

/* The master's heartbeat, when due; a refused send is retried at the next poll. */
static void master_heartbeat(cia402_omni_t *o, uint64_t now_us)
{
    if (!o->master_hb_on || now_us < o->master_hb_next_us) return;
    hal_can_frame_t f;
    (void)canopen_heartbeat_frame(&f, o->cfg.drive.master_node_id, CANOPEN_NMT_STATE_OPERATIONAL);
    if (hal_can_send(o->can, &f, 0) != HAL_OK) {
        o->master_hb_failures++;
        return;
    }
    o->master_hb_sent++;
    const uint64_t period = (uint64_t)o->cfg.master_heartbeat_period_ms * 1000u;
    o->master_hb_next_us += period;
    if (o->master_hb_next_us <= now_us) o->master_hb_next_us = now_us + period; /* late: no burst */
}

/* Refresh the fault report; 1 if a new fault was reported. */
static int update_fault(cia402_omni_t *o)
{
    uint8_t mask = 0;
    int first = -1;
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        const cia402_fault_info_t *fi = cia402_drive_fault(&o->drive[k]);
        if (fi->reason == CIA402_FAULT_NONE) continue;
        mask = (uint8_t)(mask | (1u << k));
        if (first < 0 || fi->stamp_us < cia402_drive_fault(&o->drive[first])->stamp_us) first = k;
    }
    o->fault.faulted_mask = mask;
    if (o->fault.wheel < 0 && first >= 0) {
        o->fault.wheel = (int8_t)first;
        o->fault.node_id = o->cfg.node_id[first];
        o->fault.info = *cia402_drive_fault(&o->drive[first]);
        o->enabled_goal = 0;
        memset(o->cmd_rpm, 0, sizeof o->cmd_rpm);
        return 1;
    }
    if (o->fault.wheel >= 0 && mask == 0u) {
        /* every wheel was reset: drop the report, stay disabled */
        o->fault.wheel = -1;
        o->fault.node_id = 0;
        memset(&o->fault.info, 0, sizeof o->fault.info);
    }
    return 0;
}

coslam_status_t cia402_omni_poll(cia402_omni_t *o, uint64_t now_us)
{
    if (o == NULL) return COSLAM_E_ARG;
    for (int n = 0; n < CIA402_OMNI_RX_BUDGET; ++n) {
        hal_can_frame_t f;
        const hal_status_t s = hal_can_receive(o->can, &f, 0);
        if (s == HAL_OK) {
            o->rx_frames++;
            dispatch(o, &f);
            continue;
        }
        if (s == HAL_E_TIMEOUT || s == HAL_E_BUSY) break; /* nothing now */
        if (s == HAL_E_OVERFLOW) {
            o->rx_overflows++;
            continue;
        }
        o->rx_errors++;
        if (s == HAL_E_CORRUPT) continue;
        /* the bus itself failed: no wheel can be trusted */
        for (int k = 0; k < OMNI_WHEELS; ++k) cia402_drive_bus_error(&o->drive[k], s, now_us);
        break;
    }
    master_heartbeat(o, now_us);
    int stop_now = update_fault(o);
    apply_commands(o);
    for (int k = 0; k < OMNI_WHEELS; ++k) (void)cia402_drive_poll(&o->drive[k], now_us);
    stop_now |= update_fault(o);
    if (stop_now) {
        /* send the stop in this cycle, not one period later */
        apply_commands(o);
        for (int k = 0; k < OMNI_WHEELS; ++k) (void)cia402_drive_poll(&o->drive[k], now_us);
    }
    return o->fault.wheel >= 0 ? COSLAM_E_DRIVE_FAULT : COSLAM_OK;
}

coslam_status_t cia402_omni_enable(cia402_omni_t *o, int enable)
{
    if (o == NULL) return COSLAM_E_ARG;
    if (o->fault.wheel >= 0) return COSLAM_E_DRIVE_FAULT;
    o->enabled_goal = enable != 0;
    apply_commands(o);
    return COSLAM_OK;
}

int cia402_omni_is_enabled(const cia402_omni_t *o)
{
    if (o == NULL) return 0;
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        if (!cia402_drive_is_enabled(&o->drive[k])) return 0;
    }
    return 1;
}

int cia402_omni_is_running(const cia402_omni_t *o)
{
    if (o == NULL) return 0;
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        if (o->drive[k].phase != CIA402_DRIVE_RUN) return 0;
    }
    return 1;
}

coslam_status_t cia402_omni_set_motor_rpm(cia402_omni_t *o, const double motor_rpm[OMNI_WHEELS])
{
    if (o == NULL || motor_rpm == NULL) return COSLAM_E_ARG;
    if (o->fault.wheel >= 0) {
        memset(o->cmd_rpm, 0, sizeof o->cmd_rpm);
        apply_commands(o);
        return COSLAM_E_DRIVE_FAULT;
    }
    double rpm[OMNI_WHEELS];
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        if (!isfinite(motor_rpm[k])) {
            memset(o->cmd_rpm, 0, sizeof o->cmd_rpm);
            apply_commands(o);
            return COSLAM_E_NUMERIC;
        }
        rpm[k] = motor_rpm[k];
    }
    if (omni_kinematics_saturate(rpm, o->cfg.max_motor_rpm) < 1.0) o->saturations++;
    memcpy(o->cmd_rpm, rpm, sizeof rpm);
    apply_commands(o);
    return COSLAM_OK;
}

coslam_status_t cia402_omni_set_body_velocity(cia402_omni_t *o, double vx_mps, double vy_mps, double w_radps)
{
    if (o == NULL) return COSLAM_E_ARG;
    double rpm[OMNI_WHEELS];
    const coslam_status_t st = omni_kinematics_inverse(&o->cfg.kinematics, vx_mps, vy_mps, w_radps, rpm);
    if (st != COSLAM_OK) {
        memset(o->cmd_rpm, 0, sizeof o->cmd_rpm);
        apply_commands(o);
        return st;
    }
    return cia402_omni_set_motor_rpm(o, rpm);
}

coslam_status_t cia402_omni_measured_velocity(const cia402_omni_t *o, double *vx_mps, double *vy_mps,
                                              double *w_radps)
{
    if (o == NULL) return COSLAM_E_ARG;
    if (o->meas_mask != (1u << OMNI_WHEELS) - 1u) {
        if (vx_mps != NULL) *vx_mps = 0.0;
        if (vy_mps != NULL) *vy_mps = 0.0;
        if (w_radps != NULL) *w_radps = 0.0;
        return COSLAM_E_EMPTY;
    }
    return omni_kinematics_forward(&o->cfg.kinematics, o->meas_rpm, vx_mps, vy_mps, w_radps);
}

coslam_status_t cia402_omni_take_odometry(cia402_omni_t *o, odo_increment_t *u, uint64_t *until_us)
{
    if (o == NULL || u == NULL) return COSLAM_E_ARG;
    memset(u, 0, sizeof *u);
    if (until_us != NULL) *until_us = 0;
    if (!o->odo_running && o->odo_last_us == 0u) return COSLAM_E_EMPTY; /* never started */
    odo_flush(o); /* nothing while stopped at a gap: what came before it is handed out */
    *u = o->odo_acc;
    if (until_us != NULL) *until_us = o->odo_last_us;
    memset(&o->odo_acc, 0, sizeof o->odo_acc);
    return COSLAM_OK;
}

coslam_status_t cia402_omni_release(cia402_omni_t *o)
{
    if (o == NULL) return COSLAM_E_ARG;
    o->master_hb_on = 0;
    coslam_status_t st = COSLAM_OK;
    for (int k = 0; k < OMNI_WHEELS; ++k) {
        hal_can_frame_t f;
        canopen_nmt_frame(&f, CANOPEN_NMT_RESET_COMM, o->cfg.node_id[k]);
        if (hal_can_send(o->can, &f, 0) != HAL_OK) st = COSLAM_E_DRIVE_BUS;
    }
    return st;
}

coslam_status_t cia402_omni_get_fault(const cia402_omni_t *o, cia402_omni_fault_t *out)
{
    if (o == NULL || out == NULL) return COSLAM_E_ARG;
    *out = o->fault;
    return o->fault.wheel >= 0 ? COSLAM_OK : COSLAM_E_EMPTY;
}

coslam_status_t cia402_omni_fault_reset(cia402_omni_t *o, uint64_t now_us)
{
    if (o == NULL) return COSLAM_E_ARG;
    o->enabled_goal = 0;
    memset(o->cmd_rpm, 0, sizeof o->cmd_rpm);
    for (int k = 0; k < OMNI_WHEELS; ++k) (void)cia402_drive_fault_reset(&o->drive[k], now_us);
    /* the report clears in poll once every wheel is clear; until then the
     * healthy wheels hold their quick stop */
    apply_commands(o);
    return COSLAM_OK;
}
