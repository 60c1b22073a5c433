#include "cia402/cia402.h"

#include <string.h>

#include "cia402/canopen.h"

cia402_state_t cia402_state_from_statusword(uint16_t sw)
{
    switch (sw & 0x4Fu) {
    case 0x00u: return CIA402_STATE_NOT_READY;
    case 0x40u: return CIA402_STATE_SWITCH_ON_DISABLED;
    case 0x0Fu: return CIA402_STATE_FAULT_REACTION_ACTIVE;
    case 0x08u: return CIA402_STATE_FAULT;
    default: break;
    }
    switch (sw & 0x6Fu) {
    case 0x21u: return CIA402_STATE_READY_TO_SWITCH_ON;
    case 0x23u: return CIA402_STATE_SWITCHED_ON;
    case 0x27u: return CIA402_STATE_OPERATION_ENABLED;
    case 0x07u: return CIA402_STATE_QUICK_STOP_ACTIVE;
    default: break;
    }
    return CIA402_STATE_UNKNOWN;
}

const char *cia402_state_str(cia402_state_t state)
{
    switch (state) {
    case CIA402_STATE_NOT_READY: return "NOT_READY_TO_SWITCH_ON";
    case CIA402_STATE_SWITCH_ON_DISABLED: return "SWITCH_ON_DISABLED";
    case CIA402_STATE_READY_TO_SWITCH_ON: return "READY_TO_SWITCH_ON";
    case CIA402_STATE_SWITCHED_ON: return "SWITCHED_ON";
    case CIA402_STATE_OPERATION_ENABLED: return "OPERATION_ENABLED";
    case CIA402_STATE_QUICK_STOP_ACTIVE: return "QUICK_STOP_ACTIVE";
    case CIA402_STATE_FAULT_REACTION_ACTIVE: return "FAULT_REACTION_ACTIVE";
    case CIA402_STATE_FAULT: return "FAULT";
    case CIA402_STATE_UNKNOWN: break;
    }
    return "UNKNOWN";
}

uint16_t cia402_controlword_for(cia402_state_t state, cia402_goal_t goal)
{
    switch (state) {
    case CIA402_STATE_SWITCH_ON_DISABLED:
        return goal == CIA402_GOAL_ENABLED ? CIA402_CW_SHUTDOWN                          /* 2 */
             : goal == CIA402_GOAL_QUICK_STOP ? CIA402_CW_QUICK_STOP : CIA402_CW_DISABLE_VOLTAGE;
    case CIA402_STATE_READY_TO_SWITCH_ON:
        return goal == CIA402_GOAL_ENABLED ? CIA402_CW_SWITCH_ON                         /* 3 */
             : goal == CIA402_GOAL_QUICK_STOP ? CIA402_CW_QUICK_STOP                     /* 7 */
                                              : CIA402_CW_DISABLE_VOLTAGE;               /* 7 */
    case CIA402_STATE_SWITCHED_ON:       /* transitions 4, 10, 10 */
    case CIA402_STATE_OPERATION_ENABLED: /* hold, 11, 9 */
        return goal == CIA402_GOAL_ENABLED ? CIA402_CW_ENABLE_OPERATION
             : goal == CIA402_GOAL_QUICK_STOP ? CIA402_CW_QUICK_STOP : CIA402_CW_DISABLE_VOLTAGE;
    case CIA402_STATE_QUICK_STOP_ACTIVE:
        /* stay in the quick stop (the drive ends it in SWITCH_ON_DISABLED),
         * or leave it at once by disabling the voltage (12) */
        return goal == CIA402_GOAL_QUICK_STOP ? CIA402_CW_QUICK_STOP : CIA402_CW_DISABLE_VOLTAGE;
    case CIA402_STATE_NOT_READY:
    case CIA402_STATE_FAULT_REACTION_ACTIVE:
    case CIA402_STATE_FAULT:
    case CIA402_STATE_UNKNOWN:
        break;
    }
    return CIA402_CW_DISABLE_VOLTAGE;
}

coslam_status_t cia402_rpdo_frame(hal_can_frame_t *f, uint8_t node_id, uint16_t controlword, int32_t target_velocity)
{
    if (f == NULL || !canopen_node_id_valid(node_id)) return COSLAM_E_ARG;
    memset(f, 0, sizeof *f);
    f->id = CANOPEN_COB_RPDO1 + node_id;
    f->dlc = CIA402_PDO_DLC;
    canopen_put_u16(&f->data[0], controlword);
    canopen_put_u32(&f->data[2], (uint32_t)target_velocity);
    return COSLAM_OK;
}

coslam_status_t cia402_tpdo_parse(const hal_can_frame_t *f, uint16_t *statusword, int32_t *velocity_actual)
{
    if (f == NULL || statusword == NULL || velocity_actual == NULL) return COSLAM_E_ARG;
    if (f->dlc != CIA402_PDO_DLC) return COSLAM_E_DRIVE_PROTOCOL;
    *statusword = canopen_get_u16(&f->data[0]);
    const uint32_t raw = canopen_get_u32(&f->data[2]);
    /* two's complement without implementation-defined conversion */
    *velocity_actual = raw <= (uint32_t)INT32_MAX ? (int32_t)raw : -(int32_t)(~raw) - 1;
    return COSLAM_OK;
}
