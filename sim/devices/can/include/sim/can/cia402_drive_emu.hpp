// sim/can/cia402_drive_emu.hpp - an emulated CANopen CiA 402 wheel drive
// (servo controller + geared motor + omni wheel) on a simulated CAN bus.
//
// It talks only through its own hal_can_t endpoint and answers real frames:
//  - NMT (0x000): start, stop, pre-operational, reset node, reset
//    communication. After power-on or a reset it sends the boot-up message
//    (0x700+id, [0x00]) boot_delay_us later and is pre-operational.
//  - SDO server (0x600+id -> 0x580+id), expedited only, object dictionary:
//      0x1000 u32 ro device type 0x00020192      0x1001 u8 ro error register
//      0x1016:0 u8 ro 1, :1 u32 rw consumer heartbeat (node << 16 | ms)
//      0x1017 u16 rw heartbeat producer [ms]     0x1018:1..4 u32 ro identity
//      0x6007 i16 rw abort connection option (0..3; default 1)
//      0x6040 u16 rw controlword                 0x6041 u16 ro statusword
//      0x6060 i8  rw modes of operation (3 only) 0x6061 i8 ro mode display
//      0x606C i32 ro velocity actual             0x60FF i32 rw target velocity
//    with the CiA 301 abort codes for unknown objects/sub-indices, read-only
//    writes, length mismatches, values out of range and segmented transfers.
//  - RPDO1 (0x200+id, dlc 6: controlword, target velocity), in OPERATIONAL.
//  - TPDO1 (0x180+id, dlc 6: statusword, velocity actual), in OPERATIONAL,
//    every tpdo_period_us and at once when the statusword changes.
//  - heartbeat (0x700+id, [NMT state]) every 0x1017 ms (0 = none, the
//    power-on default unless heartbeat_period_ms is set).
//  - EMCY (0x080+id) on a fault ([code LE, error register, 0 x 5]) and the
//    "error reset" EMCY (code 0) when a fault reset clears it.
//  - heartbeat consumer (CiA 301): with 0x1016:1 set, monitoring starts at
//    the first heartbeat of that node afterwards (any NMT state but Init);
//    no heartbeat for the consumer time and the drive sends EMCY 0x8130
//    (error register 0x11), takes the 0x6007 action (1 fault: FAULT_REACTION
//    -> FAULT; 2 disable voltage: SWITCH_ON_DISABLED, the motor coasts; 3
//    quick stop from OPERATION_ENABLED) and, as 0x1029:1 = 0 (the CiA 301
//    default), goes OPERATIONAL -> PRE-OPERATIONAL. Monitoring starts again
//    at the next heartbeat; a reset (node or communication) clears 0x1016.
// CiA 402 power state machine as in firmware cia402.h; in
// OPERATION_ENABLED with mode 3 the motor follows the target velocity
// (clamped to max_motor_rpm); otherwise it is commanded to 0. Quick stop and
// fault reaction brake on the quick-stop time constant and end in
// SWITCH_ON_DISABLED / FAULT when the motor is below 1 rpm.
//
// Motor: first-order lag towards the commanded speed with time constant
// motor_time_constant_s, integrated exactly over each step. Wheel: the
// encoder (velocity actual) sees the motor; the floor sees the motor speed
// times (1 + slip), slip ~ N(0, slip_sigma^2) drawn per step from a seeded
// core RNG: true_motor_rpm() / true_wheel_speed_radps() are what the
// simulator's physics should use.
//
// Fault injection: raise_fault() (EMCY + FAULT_REACTION_ACTIVE -> FAULT,
// cleared by a fault reset), set_silent() (the transmitter dies: no
// heartbeat, TPDO, SDO reply or EMCY; it still hears the bus),
// power_cycle() (reboot: boot-up message, pre-operational, everything reset).
//
// Time: step(now_us) does everything up to now_us; call it every simulated
// millisecond or so. Frames it sends carry the bus clock's stamp.
#ifndef COSLAM_SIM_CIA402_DRIVE_EMU_HPP
#define COSLAM_SIM_CIA402_DRIVE_EMU_HPP

#include <cstdint>

#include "coslam/rng.h"
#include "hal/hal_can.h"

namespace coslam::sim {

struct Cia402DriveEmuConfig {
    uint8_t node_id = 1;
    uint32_t vendor_id = 0x000000C0u;
    uint32_t product_code = 0x00000402u;
    uint32_t revision = 0x00010000u;
    uint32_t serial = 1;
    uint32_t tpdo_period_us = 10000;       ///< TPDO1 event timer
    uint16_t heartbeat_period_ms = 0;      ///< 0x1017 after power-on / reset
    uint32_t boot_delay_us = 2000;         ///< power-on or reset -> boot-up message
    double velocity_unit_rpm = 0.1;        ///< motor rpm per velocity unit of 0x60FF / 0x606C
    double max_motor_rpm = 3000.0;         ///< 0x60FF is clamped to this
    double motor_time_constant_s = 0.05;   ///< first-order lag while enabled / coasting
    double quick_stop_time_constant_s = 0.02;
    double gear_ratio = 16.0;              ///< motor turns per wheel turn
    double slip_sigma = 0.0;               ///< relative slip noise per step (0: none)
    uint64_t seed = 1;                     ///< slip noise RNG seed
    bool watchdog_objects = true;          ///< false: no 0x1016 / 0x6007 (an older drive: writes abort)
};

class Cia402DriveEmu {
public:
    enum class Nmt : uint8_t { Init = 0xFF, BootUp = 0x00, Stopped = 0x04, Operational = 0x05, PreOperational = 0x7F };
    enum class State : uint8_t {
        NotReady, SwitchOnDisabled, ReadyToSwitchOn, SwitchedOn, OperationEnabled, QuickStopActive,
        FaultReactionActive, Fault
    };

    /// `endpoint` is this drive's bus endpoint (not owned). Powers on at the first step().
    Cia402DriveEmu(hal_can_t *endpoint, const Cia402DriveEmuConfig &cfg);

    /// Process received frames, advance the motor to now_us, send what is due.
    void step(uint64_t now_us);

    // fault injection
    void raise_fault(uint16_t emcy_code = 0x2310, uint8_t error_register = 0x03);
    void set_silent(bool silent) { silent_ = silent; }
    void power_cycle(uint64_t now_us);
    /// Encoder fault: velocity actual (0x606C, TPDO1) reports scale times
    /// the motor speed, or (garbage) a uniform random value within
    /// +-max_motor_rpm per reading; scale 1 and no garbage: healthy. The
    /// motor itself and the floor are not affected.
    void set_encoder_fault(double scale, bool garbage)
    {
        enc_scale_ = scale;
        enc_garbage_ = garbage;
    }

    // observation (ground truth)
    double motor_rpm() const { return motor_rpm_; }               ///< encoder speed
    double true_motor_rpm() const { return motor_rpm_ * (1.0 + slip_); }
    double true_wheel_speed_radps() const;                          ///< wheel rate the floor sees
    double commanded_rpm() const { return cmd_rpm_; }
    State state() const { return state_; }
    Nmt nmt() const { return nmt_; }
    uint16_t statusword() const;
    uint16_t controlword() const { return controlword_; }
    int8_t mode() const { return mode_; }
    uint16_t heartbeat_period_ms() const { return hb_period_ms_; }
    uint32_t consumer_heartbeat() const { return consumer_; }  ///< 0x1016:1
    int16_t abort_option() const { return abort_option_; }     ///< 0x6007
    bool silent() const { return silent_; }
    const Cia402DriveEmuConfig &config() const { return cfg_; }

    struct Counters {
        uint64_t rx_frames = 0, sdo_requests = 0, sdo_aborts = 0, rpdos = 0, tpdos = 0, heartbeats = 0, emcys = 0,
                 nmt_commands = 0, tx_failures = 0, consumer_timeouts = 0;
    };
    const Counters &counters() const { return counters_; }

private:
    void reset_application();
    void reset_communication();
    void on_frame(const hal_can_frame_t &f);
    void on_nmt(const hal_can_frame_t &f);
    void on_sdo(const hal_can_frame_t &f);
    void on_rpdo(const hal_can_frame_t &f);
    void apply_controlword(uint16_t cw);
    void advance(double dt_s);
    void send(uint32_t id, const uint8_t *data, uint8_t dlc);
    void send_tpdo();
    void send_emcy(uint16_t code, uint8_t reg);
    void sdo_abort(uint16_t index, uint8_t sub, uint32_t code);
    void consumer_timeout();
    int32_t velocity_actual_units() const;
    double target_rpm() const;

    hal_can_t *ep_;
    Cia402DriveEmuConfig cfg_;
    rng_t rng_{};
    bool powered_ = false;
    bool silent_ = false;
    uint64_t now_us_ = 0;
    uint64_t last_step_us_ = 0;
    Nmt nmt_ = Nmt::Init;
    uint64_t boot_at_us_ = 0;
    uint64_t next_hb_us_ = 0;
    uint64_t next_tpdo_us_ = 0;
    uint16_t hb_period_ms_ = 0;
    uint32_t consumer_ = 0;         // 0x1016:1
    bool consumer_armed_ = false;   // a heartbeat of the watched node came since 0x1016 was set
    uint64_t consumer_last_us_ = 0;
    int16_t abort_option_ = 1;      // 0x6007
    State state_ = State::NotReady;
    uint16_t controlword_ = 0;
    int32_t target_velocity_ = 0;
    int8_t mode_ = 0;
    uint8_t error_register_ = 0;
    bool fault_pending_ = false;
    uint16_t fault_code_ = 0;
    uint16_t last_tpdo_sw_ = 0xFFFF;
    double motor_rpm_ = 0.0;
    double cmd_rpm_ = 0.0;
    double slip_ = 0.0;
    double enc_scale_ = 1.0;
    bool enc_garbage_ = false;
    mutable rng_t enc_rng_{};
    Counters counters_;
};

} // namespace coslam::sim

#endif // COSLAM_SIM_CIA402_DRIVE_EMU_HPP
