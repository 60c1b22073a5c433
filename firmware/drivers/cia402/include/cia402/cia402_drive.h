/*
 * cia402/cia402_drive.h - one CiA 402 drive on CANopen, from the master's
 * side: bring-up (NMT, SDO configuration), the power state machine driven
 * by the statusword, target velocity by RPDO, supervision (heartbeat
 * consumer, TPDO timeout, EMCY) and a latched fault.
 *
 * Ownership and time: the state (cia402_drive_t) is caller-owned; the
 * driver keeps the hal_can_t pointer given to init and talks to the drive
 * only through it. It never reads a clock: the caller passes now_us (the
 * hal_clock time base, the same as received frames' stamp_us). It never
 * blocks: frames go out with hal_can_send(timeout 0) and the owner feeds
 * received frames in through cia402_drive_on_frame(). A typical loop (what
 * cia402_omni.h does for three drives):
 *
 *     while (hal_can_receive(can, &f, 0) == HAL_OK) cia402_drive_on_frame(&d, &f);
 *     cia402_drive_poll(&d, now_us);
 *
 * Bring-up (cia402_drive_start), each step one expedited SDO with
 * sdo_timeout_us:
 *   BOOT    NMT reset node [0x81, id]; wait boot_timeout_us for the boot-up
 *           heartbeat (0x700+id, [0x00])
 *   CONFIG  read 0x1018:1 vendor id, 0x1018:2 product code; write 0x1017
 *           heartbeat producer time (u16 ms); with a master node id, the
 *           drive-side watchdog: write 0x1016:1 = master id << 16 | consumer
 *           time (u32 ms) and 0x6007 = master_loss_action (i16); write
 *           0x6060 = 3 (profile velocity); read 0x6061 (must be 3); read
 *           0x6041 statusword; then NMT start [0x01, id]
 *   RUN     every poll: the controlword towards the goal (cia402.h) and the
 *           target velocity go out in RPDO1 when they change and at least
 *           every rpdo_period_us; TPDO1 updates statusword and velocity.
 * Heartbeat supervision starts when 0x1017 was written.
 *
 * Drive-side watchdog: the master (cia402_omni.h sends it) produces a
 * heartbeat as node master_node_id; the drive consumes it (0x1016) and, when
 * it stays away for master_timeout_ms (the master process crashed, hung, was
 * killed, or lost the bus), acts on its own: 0x6007 (quick stop by default),
 * an EMCY 0x8130 and, by the drive's 0x1029 default, NMT PRE-OPERATIONAL.
 * Without it a dead master leaves the wheels at their last target velocity.
 * A drive that lacks 0x1016 or 0x6007 aborts the SDO and the bring-up halts
 * (SDO_ABORT with the object's abort code): set master_node_id = 0 to run
 * such a drive without the watchdog, knowingly.
 *
 * Faults (latched, first cause kept, see cia402_fault_t): any failure in
 * BOOT/CONFIG halts the bring-up (phase HALTED). In RUN a fault makes the
 * driver command a quick stop (or disable voltage when the drive itself is
 * in FAULT) with target velocity 0 until cia402_drive_fault_reset():
 * a drive fault (EMCY, statusword FAULT) is cleared by the CiA 402 fault
 * reset (controlword 0x00 then 0x80, until the statusword leaves FAULT);
 * any other fault, and a fault latched by EMCY 0x8130 (the drive's
 * heartbeat consumer fired) or 0x8140 (it recovered from bus-off): by the
 * drive's 0x1029 default it is no longer OPERATIONAL, restarts the bring-up
 * from BOOT. Every EMCY with a
 * non-zero error code is a fault (0x0000, "error reset", is only counted).
 *
 * Memory: sizeof(cia402_drive_t) = 256 bytes on Cortex-M7, 272 on x86-64 (the
 * build reports it, build/cortexm/drivers); every call is O(1).
 */
#ifndef CIA402_CIA402_DRIVE_H
#define CIA402_CIA402_DRIVE_H

#include <stdint.h>

#include "cia402/canopen.h"
#include "cia402/cia402.h"
#include "coslam/status.h"
#include "hal/hal_can.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint8_t node_id;                /**< 1..127 */
    uint16_t heartbeat_period_ms;   /**< written to the drive's 0x1017, > 0 */
    uint32_t heartbeat_timeout_us;  /**< consumer time, > heartbeat_period_ms * 1000 */
    uint32_t sdo_timeout_us;        /**< per SDO request, > 0 */
    uint32_t boot_timeout_us;       /**< boot-up message after NMT reset, > 0 */
    uint32_t pdo_timeout_us;        /**< TPDO silence that is a fault in RUN; 0 = not checked */
    uint32_t rpdo_period_us;        /**< RPDO refresh period, > 0 */
    uint8_t master_node_id;         /**< the master's heartbeat node id the drive watches (0x1016:1),
                                         1..127 and not node_id; 0 = no drive-side watchdog */
    uint16_t master_timeout_ms;     /**< the drive's consumer time: no master heartbeat this long and
                                         it acts (0x6007); > 0 when master_node_id is set */
    int16_t master_loss_action;     /**< 0x6007: CIA402_ABORT_FAULT, _DISABLE_VOLTAGE or _QUICK_STOP */
} cia402_drive_config_t;

typedef enum {
    CIA402_DRIVE_IDLE = 0, /**< initialised, not started */
    CIA402_DRIVE_BOOT,     /**< NMT reset sent, waiting for the boot-up message */
    CIA402_DRIVE_CONFIG,   /**< SDO configuration steps */
    CIA402_DRIVE_RUN,      /**< NMT started, PDOs exchanged */
    CIA402_DRIVE_HALTED,   /**< bring-up failed; waits for cia402_drive_fault_reset */
} cia402_drive_phase_t;

typedef enum {
    CIA402_FAULT_NONE = 0,
    CIA402_FAULT_BOOT_TIMEOUT, /**< no boot-up message after NMT reset */
    CIA402_FAULT_SDO_TIMEOUT,  /**< a configuration SDO got no reply */
    CIA402_FAULT_SDO_ABORT,    /**< the drive aborted a configuration SDO (sdo_abort_code) */
    CIA402_FAULT_CONFIG,       /**< wrong mode display, or a malformed / mismatched SDO reply */
    CIA402_FAULT_HEARTBEAT,    /**< no heartbeat for heartbeat_timeout_us */
    CIA402_FAULT_NMT,          /**< the node rebooted or left OPERATIONAL */
    CIA402_FAULT_PDO_TIMEOUT,  /**< no TPDO for pdo_timeout_us */
    CIA402_FAULT_EMCY,         /**< emergency message with a non-zero code (emcy_code) */
    CIA402_FAULT_DEVICE,       /**< statusword shows FAULT or FAULT_REACTION_ACTIVE */
    CIA402_FAULT_BUS,          /**< the CAN HAL failed (hal_status) */
    CIA402_FAULT_LEFT_ENABLED, /**< the drive left OPERATION_ENABLED on its own while the goal
                                    was ENABLED, with no fault of its own (its quick-stop or
                                    STO input): not walked back to enabled behind the
                                    operator's back; a fault reset restarts it */
} cia402_fault_t;

typedef struct {
    cia402_fault_t reason;   /**< first cause since the last reset; NONE if healthy */
    uint64_t stamp_us;       /**< when reason was latched */
    uint16_t emcy_code;      /**< last EMCY error code received (kept across causes) */
    uint8_t emcy_register;   /**< its error register */
    uint32_t sdo_abort_code; /**< abort code of a failed configuration SDO */
    uint16_t sdo_index;      /**< its object (SDO_ABORT, SDO_TIMEOUT, CONFIG in the bring-up) */
    uint16_t statusword;     /**< statusword at the time of the last update */
    hal_status_t hal_status; /**< last failing HAL status (BUS) */
} cia402_fault_info_t;

typedef enum {
    CIA402_SDO_IDLE = 0,
    CIA402_SDO_BUSY,     /**< request queued or sent, waiting for the reply */
    CIA402_SDO_DONE,     /**< finished; value holds an uploaded value */
    CIA402_SDO_ABORTED,  /**< the drive aborted; abort_code holds the reason */
    CIA402_SDO_TIMEOUT,  /**< no reply in sdo_timeout_us (the driver sent an abort) */
    CIA402_SDO_ERROR,    /**< malformed or mismatched reply (the driver sent an abort) */
} cia402_sdo_state_t;

/** What cia402_drive_on_frame did with a frame. */
typedef enum {
    CIA402_RX_NOT_MINE = 0, /**< not addressed to / from this node */
    CIA402_RX_CONSUMED,     /**< this node's frame (possibly counted as malformed) */
    CIA402_RX_TPDO,         /**< a valid TPDO1: statusword and velocity updated */
} cia402_rx_t;

/* internal sub-states; read through the accessors */
typedef struct {
    cia402_sdo_state_t state;
    uint8_t upload;
    uint8_t sent;
    uint8_t internal;   /**< issued by the bring-up, not by the user */
    uint8_t size;
    uint16_t index;
    uint8_t subindex;
    uint32_t value;
    uint32_t abort_code;
    uint64_t deadline_us;
    hal_can_frame_t request;
} cia402_sdo_t;

typedef struct {
    cia402_drive_config_t cfg;
    hal_can_t *can;
    cia402_drive_phase_t phase;
    uint8_t step;            /**< bring-up step within BOOT/CONFIG */
    uint8_t step_sent;       /**< the step's NMT command went out */
    uint64_t step_deadline_us;
    cia402_sdo_t sdo;

    /* NMT / heartbeat */
    uint8_t hb_supervised;
    uint8_t nmt_confirmed;   /**< an OPERATIONAL heartbeat was seen in RUN */
    uint8_t nmt_state;       /**< last heartbeat state (canopen_nmt_state_t) */
    uint64_t last_hb_us;
    uint64_t run_since_us;

    /* power state and process data */
    uint16_t statusword;
    cia402_state_t state;
    int32_t velocity_actual; /**< drive units */
    uint64_t last_tpdo_us;
    cia402_goal_t goal;
    int32_t target_velocity; /**< drive units, applied only when OPERATION_ENABLED */
    uint16_t last_cw;        /**< last controlword sent */
    int32_t last_vel;        /**< last target velocity sent */
    uint8_t rpdo_sent;
    uint64_t last_rpdo_us;
    uint8_t reset_requested; /**< fault reset: 0 none, 1 requested, 2 bit 7 edge sent */
    uint8_t was_enabled;     /**< reached OPERATION_ENABLED since the goal became ENABLED */

    uint32_t vendor_id;
    uint32_t product_code;
    cia402_fault_info_t fault;
    uint16_t latched_emcy;   /**< the EMCY code that latched the fault (0: not an EMCY) */

    /* counters since init */
    uint32_t rx_frames;      /**< frames of this node consumed */
    uint32_t rx_malformed;   /**< frames of this node that failed to parse (ignored) */
    uint32_t rx_unexpected;  /**< valid frames that fit no pending exchange (ignored) */
    uint32_t tx_frames;      /**< frames sent */
    uint32_t tx_failures;    /**< hal_can_send failures (retried or, if fatal, a BUS fault) */
    uint32_t emcy_count;     /**< EMCY frames received */
    uint32_t fault_count;    /**< faults latched */
} cia402_drive_t;

/**
 * Defaults: heartbeat 100 ms / consumer 250 ms, SDO 50 ms, boot 2 s, PDO 100 ms, RPDO 10 ms;
 * drive-side watchdog on master node 127, 200 ms, quick stop.
 */
cia402_drive_config_t cia402_drive_config_default(uint8_t node_id);

/** COSLAM_OK or COSLAM_E_ARG for a value outside its documented range. */
coslam_status_t cia402_drive_config_check(const cia402_drive_config_t *cfg);

/**
 * Initialise *d (phase IDLE, goal DISABLED, velocity 0). No frame is sent.
 * Returns COSLAM_OK; COSLAM_E_ARG NULL or a bad config.
 */
coslam_status_t cia402_drive_init(cia402_drive_t *d, const cia402_drive_config_t *cfg, hal_can_t *can);

/**
 * (Re)start the bring-up at BOOT from any phase, clearing any latched fault
 * and setting goal DISABLED. The NMT reset goes out now (or at the next
 * poll if the HAL is busy). Returns COSLAM_OK; COSLAM_E_ARG NULL.
 */
coslam_status_t cia402_drive_start(cia402_drive_t *d, uint64_t now_us);

/**
 * Feed one received frame. Frames from other nodes return NOT_MINE and
 * change nothing. Uses frame->stamp_us as the reception time. May send an
 * SDO abort (malformed SDO reply). Never fails; bad frames are counted.
 */
cia402_rx_t cia402_drive_on_frame(cia402_drive_t *d, const hal_can_frame_t *frame);

/**
 * Advance timeouts, the bring-up and the power state machine; send what is
 * due. Returns COSLAM_OK; COSLAM_E_DRIVE_FAULT while a fault is latched
 * (see cia402_drive_fault); COSLAM_E_ARG NULL.
 */
coslam_status_t cia402_drive_poll(cia402_drive_t *d, uint64_t now_us);

/** Set the power goal (cia402.h). COSLAM_E_ARG NULL or unknown goal. */
coslam_status_t cia402_drive_set_goal(cia402_drive_t *d, cia402_goal_t goal);

/** Target velocity [drive units]; sent only while enabled, else 0. */
coslam_status_t cia402_drive_set_target_velocity(cia402_drive_t *d, int32_t velocity);

/**
 * Request a fault reset (see above). COSLAM_OK (also when nothing is
 * latched); COSLAM_E_ARG NULL. The goal becomes DISABLED: re-enable
 * explicitly.
 */
coslam_status_t cia402_drive_fault_reset(cia402_drive_t *d, uint64_t now_us);

/** Inject a BUS fault (the owner saw the HAL fail on receive). */
void cia402_drive_bus_error(cia402_drive_t *d, hal_status_t hal_status, uint64_t now_us);

/**
 * Start a user SDO read (upload) / write (download, size 1..4 bytes) in
 * RUN. The result is read with cia402_drive_sdo_state. Returns COSLAM_OK;
 * COSLAM_E_DRIVE_STATE not in RUN or an SDO is busy; COSLAM_E_ARG bad
 * arguments.
 */
coslam_status_t cia402_drive_sdo_read(cia402_drive_t *d, uint16_t index, uint8_t subindex, uint64_t now_us);
coslam_status_t cia402_drive_sdo_write(cia402_drive_t *d, uint16_t index, uint8_t subindex, uint32_t value,
                                       uint8_t size, uint64_t now_us);

/** State of the last user SDO; *value (DONE upload) and *abort_code (ABORTED) may be NULL. */
cia402_sdo_state_t cia402_drive_sdo_state(const cia402_drive_t *d, uint32_t *value, uint32_t *abort_code);

/** The latched fault (reason NONE if healthy). Never NULL for a non-NULL d. */
const cia402_fault_info_t *cia402_drive_fault(const cia402_drive_t *d);

/** 1 if in RUN, no fault, and the drive reports OPERATION_ENABLED. */
int cia402_drive_is_enabled(const cia402_drive_t *d);

/** Short static name of a fault reason ("HEARTBEAT"). */
const char *cia402_fault_str(cia402_fault_t reason);

#ifdef __cplusplus
}
#endif

#endif /* CIA402_CIA402_DRIVE_H */
