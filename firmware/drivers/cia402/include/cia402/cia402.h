/*
 * cia402/cia402.h - the CiA 402 (IEC 61800-7-201) drive profile as this
 * driver uses it: object indices, the power state machine (statusword ->
 * state, state + goal -> controlword) and the fixed PDO mapping.
 *
 * Power state machine (statusword 0x6041, bits 0-3, 5, 6):
 *     state                    mask   value
 *     NOT_READY_TO_SWITCH_ON   0x4F   0x00
 *     SWITCH_ON_DISABLED       0x4F   0x40
 *     READY_TO_SWITCH_ON       0x6F   0x21
 *     SWITCHED_ON              0x6F   0x23
 *     OPERATION_ENABLED        0x6F   0x27
 *     QUICK_STOP_ACTIVE        0x6F   0x07
 *     FAULT_REACTION_ACTIVE    0x4F   0x0F
 *     FAULT                    0x4F   0x08
 * Controlword 0x6040 commands: shutdown 0x06 (-> READY), switch on 0x07
 * (-> SWITCHED_ON), enable operation 0x0F (-> OPERATION_ENABLED), disable
 * voltage 0x00 (-> SWITCH_ON_DISABLED), quick stop 0x02 (ENABLED ->
 * QUICK_STOP_ACTIVE, else -> SWITCH_ON_DISABLED), fault reset: a rising
 * edge of bit 7 (0x00 then 0x80; FAULT -> SWITCH_ON_DISABLED).
 *
 * Mode of operation: 3, profile velocity (pv). Chosen over velocity mode
 * (vl, 2) because pv is what servo drives of the Robotino class implement,
 * its target (0x60FF) and actual (0x606C) velocities are 32-bit (vl uses
 * 16-bit objects), and it uses the plain state machine above.
 *
 * Fixed PDO mapping (the drive emulator in sim/devices/can mirrors it; a
 * real drive is configured to it, see docs/can-drive.md):
 *     RPDO1 0x200+node, dlc 6: controlword u16 LE | target velocity i32 LE
 *     TPDO1 0x180+node, dlc 6: statusword u16 LE  | velocity actual i32 LE
 * Velocities are in drive units; cia402_omni.h converts them to rpm.
 *
 * All functions are pure and O(1).
 */
#ifndef CIA402_CIA402_H
#define CIA402_CIA402_H

#include <stdint.h>

#include "coslam/status.h"
#include "hal/hal_can.h"

#ifdef __cplusplus
extern "C" {
#endif

/* object dictionary (CiA 301 communication, CiA 402 profile) */
#define CIA402_OD_DEVICE_TYPE 0x1000u          /**< u32 */
#define CIA402_OD_ERROR_REGISTER 0x1001u       /**< u8 */
#define CIA402_OD_CONSUMER_HEARTBEAT 0x1016u   /**< sub 1..n u32: node id << 16 | consumer time [ms] */
#define CIA402_OD_HEARTBEAT_PRODUCER 0x1017u   /**< u16 [ms], 0 = off */
#define CIA402_OD_IDENTITY 0x1018u             /**< sub 1 vendor, 2 product, 3 revision, 4 serial (u32) */
#define CIA402_OD_ABORT_CONNECTION 0x6007u     /**< i16: the drive's action on a communication loss */
#define CIA402_OD_CONTROLWORD 0x6040u          /**< u16 */
#define CIA402_OD_STATUSWORD 0x6041u           /**< u16 */
#define CIA402_OD_MODES_OF_OPERATION 0x6060u   /**< i8 */
#define CIA402_OD_MODES_DISPLAY 0x6061u        /**< i8 */
#define CIA402_OD_VELOCITY_ACTUAL 0x606Cu      /**< i32, drive velocity units */
#define CIA402_OD_TARGET_VELOCITY 0x60FFu      /**< i32, drive velocity units */

#define CIA402_MODE_PROFILE_VELOCITY 3

/* 0x6007 abort connection option codes (0 = no action; negative: manufacturer's) */
#define CIA402_ABORT_FAULT 1           /**< fault signal: FAULT_REACTION_ACTIVE, then FAULT */
#define CIA402_ABORT_DISABLE_VOLTAGE 2 /**< power stage off: the motor coasts */
#define CIA402_ABORT_QUICK_STOP 3      /**< brake on the quick-stop ramp */

/* CiA 301 emergency error codes the driver acts on */
#define CANOPEN_EMCY_HEARTBEAT 0x8130u          /**< life guard or heartbeat consumer error */
#define CANOPEN_EMCY_BUS_OFF_RECOVERED 0x8140u  /**< recovered from bus-off */

/* controlword commands */
#define CIA402_CW_DISABLE_VOLTAGE 0x0000u
#define CIA402_CW_QUICK_STOP 0x0002u
#define CIA402_CW_SHUTDOWN 0x0006u
#define CIA402_CW_SWITCH_ON 0x0007u
#define CIA402_CW_ENABLE_OPERATION 0x000Fu
#define CIA402_CW_FAULT_RESET 0x0080u

/* statusword bits beyond the state */
#define CIA402_SW_VOLTAGE_ENABLED 0x0010u
#define CIA402_SW_WARNING 0x0080u
#define CIA402_SW_REMOTE 0x0200u
#define CIA402_SW_TARGET_REACHED 0x0400u
#define CIA402_SW_PV_SPEED_ZERO 0x1000u

/** PDO data length of RPDO1 and TPDO1. */
#define CIA402_PDO_DLC 6u

typedef enum {
    CIA402_STATE_NOT_READY = 0,
    CIA402_STATE_SWITCH_ON_DISABLED,
    CIA402_STATE_READY_TO_SWITCH_ON,
    CIA402_STATE_SWITCHED_ON,
    CIA402_STATE_OPERATION_ENABLED,
    CIA402_STATE_QUICK_STOP_ACTIVE,
    CIA402_STATE_FAULT_REACTION_ACTIVE,
    CIA402_STATE_FAULT,
    CIA402_STATE_UNKNOWN, /**< a bit pattern the table above does not define */
} cia402_state_t;

/** Where the master wants a drive's power state to go. */
typedef enum {
    CIA402_GOAL_DISABLED = 0,  /**< SWITCH_ON_DISABLED (voltage off, motor free) */
    CIA402_GOAL_ENABLED,       /**< OPERATION_ENABLED (follows the target velocity) */
    CIA402_GOAL_QUICK_STOP,    /**< brake on the quick-stop ramp, then SWITCH_ON_DISABLED */
} cia402_goal_t;

/** Decode the power state from a statusword (table above). */
cia402_state_t cia402_state_from_statusword(uint16_t statusword);

/** Short static name ("OPERATION_ENABLED"). */
const char *cia402_state_str(cia402_state_t state);

/**
 * The controlword that moves a drive in `state` one step towards `goal`
 * (or holds it there). FAULT and FAULT_REACTION_ACTIVE give
 * DISABLE_VOLTAGE: leaving FAULT needs an explicit fault reset (bit 7
 * rising edge), which the caller decides on. QUICK_STOP_ACTIVE with goal
 * ENABLED gives DISABLE_VOLTAGE (the drive then restarts from
 * SWITCH_ON_DISABLED), NOT_READY and UNKNOWN give DISABLE_VOLTAGE.
 */
uint16_t cia402_controlword_for(cia402_state_t state, cia402_goal_t goal);

/** RPDO1 frame for node_id: controlword, target velocity (COSLAM_E_ARG bad node id / NULL). */
coslam_status_t cia402_rpdo_frame(hal_can_frame_t *f, uint8_t node_id, uint16_t controlword,
                                  int32_t target_velocity);

/** Parse TPDO1: COSLAM_E_DRIVE_PROTOCOL unless dlc is 6; COSLAM_E_ARG NULL. */
coslam_status_t cia402_tpdo_parse(const hal_can_frame_t *f, uint16_t *statusword, int32_t *velocity_actual);

#ifdef __cplusplus
}
#endif

#endif /* CIA402_CIA402_H */
