/*
 * cia402/cia402_omni.h - the Robotino drive base: three CiA 402 wheel
 * drives on one CAN bus, commanded by body velocity, reporting wheel
 * odometry for the SLAM filter, stopped as a whole when one wheel fails.
 *
 * Ownership and time: caller-owned state (no heap, no globals); the driver
 * keeps the hal_can_t pointer given to init and reads frames only through
 * it, non-blocking (timeout 0). It never reads a clock: now_us is passed in
 * (hal_clock time base; the HAL stamps received frames in the same base).
 * Call cia402_omni_poll() periodically (1-10 ms); it drains up to
 * CIA402_OMNI_RX_BUDGET frames (the rest stay queued in the HAL for the
 * next poll), dispatches them to the wheel drives, runs their state
 * machines and sends what is due.
 *
 * Units: the drives' velocity objects are in drive units of
 * velocity_unit_rpm motor rpm each (default 0.1 rpm); body velocity in
 * m/s and rad/s in the robot frame (omni/omni_kinematics.h).
 *
 * Fault policy: when any wheel latches a fault (cia402_drive.h: EMCY,
 * drive FAULT, heartbeat loss, PDO timeout, NMT, bus error, failed
 * bring-up), every wheel is commanded to quick stop with target velocity
 * 0, velocity commands are refused (COSLAM_E_DRIVE_FAULT), and the first
 * fault is reported by cia402_omni_get_fault() until cia402_omni_fault_reset().
 *
 * Master heartbeat: from cia402_omni_start() on, every poll that is due sends
 * the master's heartbeat (0x700 + drive.master_node_id, [0x05 OPERATIONAL])
 * every master_heartbeat_period_ms, faults or not. The drives watch it
 * (cia402_drive.h "Drive-side watchdog"): when the process that polls this
 * driver dies or stalls for drive.master_timeout_ms, each drive stops its
 * wheel by itself. Poll at least every master_heartbeat_period_ms.
 *
 * Odometry: each TPDO (velocity actual of one wheel) is a speed sample at
 * its receive stamp; samples with the same stamp form one sample of all
 * wheels. Between two sample stamps the motor speeds are averaged
 * (trapezoidal rule: exact for linear ramps, where holding the older
 * sample would lag by half a TPDO period), turned into a body velocity and
 * integrated exactly along the arc (omni_kinematics_odometry); the pieces
 * are concatenated (omni_kinematics_compose). Integration starts once all
 * three wheels have reported. A wheel (or the bus) silent for longer than
 * the PDO timeout (100 ms if not checked) is not bridged: nothing is
 * integrated across the gap, a silent wheel's last speed never stands for
 * its motion, and integration starts again once all three have reported
 * (odo_gaps). cia402_omni_take_odometry() hands out the
 * increment accumulated up to the newest sample stamp, and that stamp.
 *
 * Memory: sizeof(cia402_omni_t) = 1128 bytes on Cortex-M7, 1176 on x86-64 (the
 * build reports it, build/cortexm/drivers); poll is O(frames received).
 */
#ifndef CIA402_CIA402_OMNI_H
#define CIA402_CIA402_OMNI_H

#include <stdint.h>

#include "cia402/cia402_drive.h"
#include "coslam/motion.h"
#include "coslam/status.h"
#include "hal/hal_can.h"
#include "omni/omni_kinematics.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Frames taken from the HAL per poll at most (a time budget, not a capacity). */
#ifndef CIA402_OMNI_RX_BUDGET
#define CIA402_OMNI_RX_BUDGET 64
#endif
#if CIA402_OMNI_RX_BUDGET < 1 || CIA402_OMNI_RX_BUDGET > 4096
#error "CIA402_OMNI_RX_BUDGET must be in [1, 4096]"
#endif

typedef struct {
    uint8_t node_id[OMNI_WHEELS];    /**< distinct, 1..127; default 1, 2, 3 */
    cia402_drive_config_t drive;     /**< timing for all three (its node_id is ignored) */
    omni_kinematics_config_t kinematics;
    double velocity_unit_rpm;        /**< motor rpm per drive velocity unit, > 0; default 0.1 */
    double max_motor_rpm;            /**< command saturation, > 0; default 3000 */
    int set_hal_filters;             /**< 1: start() installs acceptance filters for the 12 COB-IDs */
    uint16_t master_heartbeat_period_ms; /**< with drive.master_node_id (not a wheel's id): > 0 and
                                              drive.master_timeout_ms >= 2 x this; default 50 */
} cia402_omni_config_t;

typedef struct {
    int8_t wheel;                 /**< wheel 0..2 that faulted first; -1 if none */
    uint8_t node_id;              /**< its node id */
    cia402_fault_info_t info;     /**< its fault as latched */
    uint8_t faulted_mask;         /**< bit k: wheel k has a latched fault now */
} cia402_omni_fault_t;

typedef struct {
    cia402_omni_config_t cfg;
    hal_can_t *can;
    cia402_drive_t drive[OMNI_WHEELS];
    int enabled_goal;                     /**< 1 if enable was requested */
    double cmd_rpm[OMNI_WHEELS];          /**< commanded motor speeds after saturation */
    double meas_rpm[OMNI_WHEELS];         /**< last measured motor speeds (at odo_pending_us) */
    uint64_t meas_us[OMNI_WHEELS];        /**< stamp of each wheel's last speed */
    uint8_t meas_mask;                    /**< bit k: wheel k reported since start (or the last gap) */
    int odo_running;
    double odo_prev_rpm[OMNI_WHEELS];     /**< motor speeds at odo_last_us */
    uint64_t odo_last_us;                 /**< integrated up to here */
    uint64_t odo_pending_us;              /**< stamp of the newest sample */
    odo_increment_t odo_acc;              /**< since the last take */
    cia402_omni_fault_t fault;
    uint8_t master_hb_on;                 /**< started: the master heartbeat is produced */
    uint64_t master_hb_next_us;           /**< when the next one is due */
    /* counters since init */
    uint32_t master_hb_sent;              /**< master heartbeats sent */
    uint32_t master_hb_failures;          /**< master heartbeats the HAL refused (retried at the next poll) */
    uint32_t rx_frames;                   /**< frames received from the HAL */
    uint32_t rx_stale;                    /**< frames queued before a start, dropped by it */
    uint32_t rx_foreign;                  /**< frames no wheel claimed */
    uint32_t rx_overflows;                /**< HAL_E_OVERFLOW reports (frames lost in the HAL) */
    uint32_t rx_errors;                   /**< other HAL receive errors */
    uint32_t saturations;                 /**< commands scaled down to max_motor_rpm */
    uint32_t odo_errors;                  /**< integration steps refused (non-finite) */
    uint32_t odo_gaps;                    /**< samples not bridged: a wheel or the bus silent for
                                               longer than the PDO timeout (odometry restarted) */
} cia402_omni_t;

/** A rule of the drive-side watchdog that a configuration breaks. */
typedef enum {
    CIA402_OMNI_WATCHDOG_OK = 0,
    CIA402_OMNI_WATCHDOG_MASTER_IS_WHEEL, /**< drive.master_node_id is a wheel's node id */
    CIA402_OMNI_WATCHDOG_NO_PERIOD,       /**< master_heartbeat_period_ms is 0 */
    CIA402_OMNI_WATCHDOG_TIMEOUT_SHORT,   /**< drive.master_timeout_ms < 2 x master_heartbeat_period_ms */
} cia402_omni_watchdog_rule_t;

/**
 * The first watchdog rule cfg breaks (OK without a master node id, or when
 * none is broken); *wheel (may be NULL) gets the wheel of MASTER_IS_WHEEL.
 * cia402_omni_init refuses what this reports; a configuration reader can
 * name the keys.
 */
cia402_omni_watchdog_rule_t cia402_omni_watchdog_check(const cia402_omni_config_t *cfg, int *wheel);

/** Defaults: nodes 1, 2, 3; cia402_drive_config_default timing (master 127); master heartbeat 50 ms; Robotino kinematics. */
cia402_omni_config_t cia402_omni_config_default(void);

/**
 * Initialise *o; nothing is sent. Returns COSLAM_OK; COSLAM_E_ARG NULL, bad
 * or duplicate node ids, bad timing, bad kinematics, bad unit or limit.
 */
coslam_status_t cia402_omni_init(cia402_omni_t *o, const cia402_omni_config_t *cfg, hal_can_t *can);

/**
 * Start (or restart) the bring-up of all three drives (cia402_drive_start),
 * clear faults, odometry and commands. With set_hal_filters, installs the
 * filters first (a backend without filters is fine). Frames already queued
 * in the HAL (at most 4 x CIA402_OMNI_RX_BUDGET) are read and dropped
 * (rx_stale): they were sent before this bring-up, such as the drives'
 * power-on boot-up messages, which would otherwise pass for the answers to
 * the NMT resets. Returns COSLAM_OK;
 * COSLAM_E_DRIVE_BUS the HAL refused the filters; COSLAM_E_ARG NULL.
 */
coslam_status_t cia402_omni_start(cia402_omni_t *o, uint64_t now_us);

/**
 * Receive, dispatch, supervise, send. Returns COSLAM_OK; COSLAM_E_DRIVE_FAULT
 * while a fault is reported (the base is being stopped); COSLAM_E_ARG NULL.
 * Never blocks.
 */
coslam_status_t cia402_omni_poll(cia402_omni_t *o, uint64_t now_us);

/**
 * Ask all drives to enable (1) or to disable (0). Returns COSLAM_OK;
 * COSLAM_E_DRIVE_FAULT while a fault is reported (nothing changes).
 */
coslam_status_t cia402_omni_enable(cia402_omni_t *o, int enable);

/** 1 when all three drives are in RUN, fault-free and OPERATION_ENABLED. */
int cia402_omni_is_enabled(const cia402_omni_t *o);

/** 1 when all three drives finished the bring-up (phase RUN). */
int cia402_omni_is_running(const cia402_omni_t *o);

/**
 * Command a body velocity (vx, vy [m/s], w [rad/s], robot frame) through
 * the inverse kinematics; speeds beyond max_motor_rpm are scaled down
 * together (direction kept; counted in saturations). Takes effect while
 * enabled. Returns COSLAM_OK; COSLAM_E_NUMERIC non-finite input (the
 * command becomes 0); COSLAM_E_DRIVE_FAULT a fault is reported (command 0).
 */
coslam_status_t cia402_omni_set_body_velocity(cia402_omni_t *o, double vx_mps, double vy_mps, double w_radps);

/** Command motor speeds directly [rpm]; as set_body_velocity otherwise. */
coslam_status_t cia402_omni_set_motor_rpm(cia402_omni_t *o, const double motor_rpm[OMNI_WHEELS]);

/** Body velocity from the last measured wheel speeds. Outputs may be NULL. COSLAM_E_EMPTY before all reported. */
coslam_status_t cia402_omni_measured_velocity(const cia402_omni_t *o, double *vx_mps, double *vy_mps,
                                              double *w_radps);

/**
 * The odometry increment accumulated since the previous take (robot frame
 * at the previous take's end stamp), and the stamp it reaches [us]; resets
 * the accumulator. Returns COSLAM_OK (also while integration waits after a
 * gap: the motion before it, then zero); COSLAM_E_EMPTY before integration
 * first started (*u zero, *until_us 0). until_us may be NULL.
 */
coslam_status_t cia402_omni_take_odometry(cia402_omni_t *o, odo_increment_t *u, uint64_t *until_us);

/**
 * The master leaves, after a clean stop's disable sequence went out: NMT
 * reset communication [0x82, id] to each wheel, which puts its object 0x1016
 * back to the power-on default (no heartbeat consumer), so its watchdog does
 * not fire when the master heartbeat stops, and the master heartbeat stops
 * here. The drives keep their power state (disabled by then); a later
 * cia402_omni_start brings them up again. Returns COSLAM_OK;
 * COSLAM_E_DRIVE_BUS if a send failed (the watchdog then fires as after a
 * crash: they stop); COSLAM_E_ARG NULL.
 */
coslam_status_t cia402_omni_release(cia402_omni_t *o);

/** COSLAM_OK and the report if a fault is reported, else COSLAM_E_EMPTY (out->wheel = -1). */
coslam_status_t cia402_omni_get_fault(const cia402_omni_t *o, cia402_omni_fault_t *out);

/**
 * Reset every wheel's fault (cia402_drive_fault_reset), zero the command and
 * leave the drives disabled; the report clears once no wheel is faulted.
 * Re-enable with cia402_omni_enable(). Returns COSLAM_OK; COSLAM_E_ARG NULL.
 */
coslam_status_t cia402_omni_fault_reset(cia402_omni_t *o, uint64_t now_us);

#ifdef __cplusplus
}
#endif

#endif /* CIA402_CIA402_OMNI_H */
