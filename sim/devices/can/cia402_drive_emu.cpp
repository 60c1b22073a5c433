#include "sim/can/cia402_drive_emu.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace coslam::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;

// CiA 301 abort codes (written out here on purpose: the emulator does not
// share the firmware's protocol tables, so a wrong constant there shows up
// as a failed exchange instead of cancelling out)
constexpr uint32_t kAbortCommand = 0x05040001u;
constexpr uint32_t kAbortReadOnly = 0x06010002u;
constexpr uint32_t kAbortNoObject = 0x06020000u;
constexpr uint32_t kAbortLength = 0x06070010u;
constexpr uint32_t kAbortNoSub = 0x06090011u;
constexpr uint32_t kAbortRange = 0x06090030u;

uint16_t get16(const uint8_t *p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t get32(const uint8_t *p)
{
    return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
           (static_cast<uint32_t>(p[3]) << 24);
}
void put16(uint8_t *p, uint16_t v)
{
    p[0] = static_cast<uint8_t>(v & 0xFF);
    p[1] = static_cast<uint8_t>(v >> 8);
}
void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>((v >> (8 * i)) & 0xFF);
}

} // namespace

Cia402DriveEmu::Cia402DriveEmu(hal_can_t *endpoint, const Cia402DriveEmuConfig &cfg) : ep_(endpoint), cfg_(cfg)
{
    if (ep_ == nullptr) throw std::invalid_argument("Cia402DriveEmu: no endpoint");
    if (cfg_.node_id < 1 || cfg_.node_id > 127) throw std::invalid_argument("Cia402DriveEmu: node id not in 1..127");
    if (!(cfg_.velocity_unit_rpm > 0.0) || !(cfg_.max_motor_rpm > 0.0) || !(cfg_.motor_time_constant_s > 0.0) ||
        !(cfg_.quick_stop_time_constant_s > 0.0) || !(cfg_.gear_ratio > 0.0) || !(cfg_.slip_sigma >= 0.0) ||
        cfg_.tpdo_period_us == 0) {
        throw std::invalid_argument("Cia402DriveEmu: bad configuration");
    }
    rng_seed(&rng_, cfg_.seed);
    rng_seed(&enc_rng_, cfg_.seed ^ 0x5DEECE66Dull);
}

double Cia402DriveEmu::true_wheel_speed_radps() const
{
    return true_motor_rpm() / cfg_.gear_ratio * 2.0 * kPi / 60.0;
}

uint16_t Cia402DriveEmu::statusword() const
{
    uint16_t sw = 0;
    switch (state_) {
    case State::NotReady: sw = 0x0000; break;
    case State::SwitchOnDisabled: sw = 0x0040; break;
    case State::ReadyToSwitchOn: sw = 0x0031; break;   // + voltage enabled
    case State::SwitchedOn: sw = 0x0033; break;
    case State::OperationEnabled: sw = 0x0037; break;
    case State::QuickStopActive: sw = 0x0017; break;
    case State::FaultReactionActive: sw = 0x001F; break;
    case State::Fault: sw = 0x0008; break;
    }
    sw |= 0x0200; // remote: controlled over the bus
    if (state_ == State::OperationEnabled && std::fabs(motor_rpm_ - cmd_rpm_) <= std::max(5.0, 0.01 * std::fabs(cmd_rpm_))) {
        sw |= 0x0400; // target reached
    }
    if (std::fabs(motor_rpm_) < 1.0) sw |= 0x1000; // pv: speed is zero
    return sw;
}

int32_t Cia402DriveEmu::velocity_actual_units() const
{
    const double rpm = enc_garbage_ ? (2.0 * rng_uniform(&enc_rng_) - 1.0) * cfg_.max_motor_rpm : motor_rpm_ * enc_scale_;
    const double u = std::round(rpm / cfg_.velocity_unit_rpm);
    if (u > 2147483647.0) return 2147483647;
    if (u < -2147483647.0) return -2147483647;
    return static_cast<int32_t>(u);
}

double Cia402DriveEmu::target_rpm() const
{
    const double rpm = static_cast<double>(target_velocity_) * cfg_.velocity_unit_rpm;
    return std::max(-cfg_.max_motor_rpm, std::min(cfg_.max_motor_rpm, rpm));
}

void Cia402DriveEmu::send(uint32_t id, const uint8_t *data, uint8_t dlc)
{
    if (silent_) return;
    hal_can_frame_t f{};
    f.id = id;
    f.dlc = dlc;
    if (dlc > 0) std::memcpy(f.data, data, dlc);
    if (hal_can_send(ep_, &f, 0) != HAL_OK) counters_.tx_failures++;
}

void Cia402DriveEmu::send_tpdo()
{
    uint8_t d[6];
    const uint16_t sw = statusword();
    put16(&d[0], sw);
    put32(&d[2], static_cast<uint32_t>(velocity_actual_units()));
    send(0x180u + cfg_.node_id, d, 6);
    last_tpdo_sw_ = sw;
    counters_.tpdos++;
}

void Cia402DriveEmu::send_emcy(uint16_t code, uint8_t reg)
{
    uint8_t d[8] = {0, 0, reg, 0, 0, 0, 0, 0};
    put16(&d[0], code);
    send(0x080u + cfg_.node_id, d, 8);
    counters_.emcys++;
}

void Cia402DriveEmu::sdo_abort(uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t d[8] = {0x80, 0, 0, sub, 0, 0, 0, 0};
    put16(&d[1], index);
    put32(&d[4], code);
    send(0x580u + cfg_.node_id, d, 8);
    counters_.sdo_aborts++;
}

void Cia402DriveEmu::reset_application()
{
    state_ = State::NotReady;
    controlword_ = 0;
    target_velocity_ = 0;
    mode_ = 0;
    error_register_ = 0;
    fault_pending_ = false;
    fault_code_ = 0;
    last_tpdo_sw_ = 0xFFFF;
    abort_option_ = 1;
}

void Cia402DriveEmu::reset_communication()
{
    hb_period_ms_ = cfg_.heartbeat_period_ms;
    consumer_ = 0;
    consumer_armed_ = false;
}

// The watched heartbeat stayed away: EMCY, the 0x6007 action, and the
// 0x1029 default reaction (OPERATIONAL -> PRE-OPERATIONAL).
void Cia402DriveEmu::consumer_timeout()
{
    counters_.consumer_timeouts++;
    consumer_armed_ = false;
    constexpr uint16_t kHeartbeatError = 0x8130;
    constexpr uint8_t kRegister = 0x11; // generic + communication
    switch (abort_option_) {
    case 1: raise_fault(kHeartbeatError, kRegister); break; // sends the EMCY
    case 2:
        if (state_ != State::Fault && state_ != State::FaultReactionActive && state_ != State::NotReady) {
            state_ = State::SwitchOnDisabled;
        }
        break;
    case 3:
        if (state_ == State::OperationEnabled) state_ = State::QuickStopActive;
        break;
    default: break;
    }
    if (abort_option_ != 1) {
        error_register_ = kRegister;
        if (nmt_ != Nmt::Stopped) send_emcy(kHeartbeatError, kRegister);
    }
    if (nmt_ == Nmt::Operational) nmt_ = Nmt::PreOperational;
}

void Cia402DriveEmu::power_cycle(uint64_t now_us)
{
    powered_ = true;
    now_us_ = now_us;
    last_step_us_ = now_us;
    reset_application();
    reset_communication();
    nmt_ = Nmt::Init;
    boot_at_us_ = now_us + cfg_.boot_delay_us;
}

void Cia402DriveEmu::raise_fault(uint16_t emcy_code, uint8_t error_register)
{
    if (!powered_ || nmt_ == Nmt::Init) return;
    fault_pending_ = true;
    fault_code_ = emcy_code;
    error_register_ = error_register;
    if (state_ != State::Fault && state_ != State::FaultReactionActive) state_ = State::FaultReactionActive;
    if (nmt_ != Nmt::Stopped) send_emcy(emcy_code, error_register);
}

void Cia402DriveEmu::apply_controlword(uint16_t cw)
{
    const uint16_t prev = controlword_;
    controlword_ = cw;
    const bool reset_edge = (cw & 0x80u) != 0u && (prev & 0x80u) == 0u;
    if (state_ == State::Fault) {
        if (reset_edge) {
            fault_pending_ = false;
            error_register_ = 0;
            state_ = State::SwitchOnDisabled;
            if (nmt_ != Nmt::Stopped) send_emcy(0x0000, 0);
        }
        return;
    }
    if (state_ == State::FaultReactionActive || state_ == State::NotReady) return;
    if ((cw & 0x80u) != 0u) return; // a fault reset outside FAULT does nothing
    const bool disable_voltage = (cw & 0x02u) == 0u;
    const bool quick_stop = (cw & 0x06u) == 0x02u;
    const bool shutdown = (cw & 0x07u) == 0x06u;
    const bool switch_on = (cw & 0x0Fu) == 0x07u;
    const bool enable = (cw & 0x0Fu) == 0x0Fu;
    switch (state_) {
    case State::SwitchOnDisabled:
        if (shutdown) state_ = State::ReadyToSwitchOn;
        break;
    case State::ReadyToSwitchOn:
        if (disable_voltage || quick_stop) {
            state_ = State::SwitchOnDisabled;
        } else if (switch_on) {
            state_ = State::SwitchedOn;
        } else if (enable) {
            state_ = State::OperationEnabled; // transitions 3 + 4 in one
        }
        break;
    case State::SwitchedOn:
        if (disable_voltage || quick_stop) {
            state_ = State::SwitchOnDisabled;
        } else if (shutdown) {
            state_ = State::ReadyToSwitchOn;
        } else if (enable) {
            state_ = State::OperationEnabled;
        }
        break;
    case State::OperationEnabled:
        if (disable_voltage) {
            state_ = State::SwitchOnDisabled;
        } else if (quick_stop) {
            state_ = State::QuickStopActive;
        } else if (shutdown) {
            state_ = State::ReadyToSwitchOn;
        } else if (switch_on) {
            state_ = State::SwitchedOn; // disable operation
        }
        break;
    case State::QuickStopActive:
        if (disable_voltage) state_ = State::SwitchOnDisabled;
        break;
    default: break;
    }
}

void Cia402DriveEmu::on_nmt(const hal_can_frame_t &f)
{
    if (f.dlc != 2 || (f.data[1] != 0 && f.data[1] != cfg_.node_id)) return;
    counters_.nmt_commands++;
    switch (f.data[0]) {
    case 0x01:
        if (nmt_ != Nmt::Init) {
            nmt_ = Nmt::Operational;
            next_tpdo_us_ = now_us_; // first TPDO right away
        }
        break;
    case 0x02:
        if (nmt_ != Nmt::Init) nmt_ = Nmt::Stopped;
        break;
    case 0x80:
        if (nmt_ != Nmt::Init) nmt_ = Nmt::PreOperational;
        break;
    case 0x81:
        reset_application();
        reset_communication();
        nmt_ = Nmt::Init;
        boot_at_us_ = now_us_ + cfg_.boot_delay_us;
        break;
    case 0x82:
        reset_communication();
        nmt_ = Nmt::Init;
        boot_at_us_ = now_us_ + cfg_.boot_delay_us;
        break;
    default: break;
    }
}

void Cia402DriveEmu::on_sdo(const hal_can_frame_t &f)
{
    if (f.dlc != 8) return;
    counters_.sdo_requests++;
    const uint8_t cmd = f.data[0];
    const uint16_t index = get16(&f.data[1]);
    const uint8_t sub = f.data[3];
    const uint8_t ccs = static_cast<uint8_t>(cmd >> 5);
    if (ccs == 4) return; // the client aborted: nothing to answer

    // the dictionary: size [bytes], writable
    struct Obj {
        uint8_t size;
        bool writable;
    };
    Obj obj{0, false};
    bool exists = true;
    bool sub_ok = sub == 0;
    switch (index) {
    case 0x1000: obj = {4, false}; break;
    case 0x1001: obj = {1, false}; break;
    case 0x1016:
        exists = cfg_.watchdog_objects;
        obj = {static_cast<uint8_t>(sub == 0 ? 1 : 4), sub == 1};
        sub_ok = sub <= 1;
        break;
    case 0x1017: obj = {2, true}; break;
    case 0x1018:
        obj = {static_cast<uint8_t>(sub == 0 ? 1 : 4), false};
        sub_ok = sub <= 4;
        break;
    case 0x6007:
        exists = cfg_.watchdog_objects;
        obj = {2, true};
        break;
    case 0x6040: obj = {2, true}; break;
    case 0x6041: obj = {2, false}; break;
    case 0x6060: obj = {1, true}; break;
    case 0x6061: obj = {1, false}; break;
    case 0x606C: obj = {4, false}; break;
    case 0x60FF: obj = {4, true}; break;
    default: exists = false; break;
    }

    if (ccs == 1) { // initiate download
        if ((cmd & 0x02u) == 0u) return sdo_abort(index, sub, kAbortCommand); // segmented: not supported
        if (!exists) return sdo_abort(index, sub, kAbortNoObject);
        if (!sub_ok) return sdo_abort(index, sub, kAbortNoSub);
        if (!obj.writable) return sdo_abort(index, sub, kAbortReadOnly);
        const uint8_t size = (cmd & 0x01u) != 0u ? static_cast<uint8_t>(4u - ((cmd >> 2) & 0x03u)) : obj.size;
        if (size != obj.size) return sdo_abort(index, sub, kAbortLength);
        uint32_t value = 0;
        for (uint8_t i = 0; i < size; ++i) value |= static_cast<uint32_t>(f.data[4 + i]) << (8 * i);
        switch (index) {
        case 0x1017:
            hb_period_ms_ = static_cast<uint16_t>(value);
            next_hb_us_ = now_us_ + static_cast<uint64_t>(hb_period_ms_) * 1000u;
            break;
        case 0x1016:
            consumer_ = value;
            consumer_armed_ = false; // starts at the watched node's next heartbeat
            break;
        case 0x6007: {
            const int16_t v = static_cast<int16_t>(value & 0xFFFF);
            if (v < 0 || v > 3) return sdo_abort(index, sub, kAbortRange);
            abort_option_ = v;
            break;
        }
        case 0x6040: apply_controlword(static_cast<uint16_t>(value)); break;
        case 0x6060:
            if (static_cast<int8_t>(value & 0xFF) != 3) return sdo_abort(index, sub, kAbortRange);
            mode_ = 3;
            break;
        case 0x60FF: target_velocity_ = static_cast<int32_t>(value); break;
        default: break;
        }
        uint8_t d[8] = {0x60, 0, 0, sub, 0, 0, 0, 0};
        put16(&d[1], index);
        send(0x580u + cfg_.node_id, d, 8);
        return;
    }
    if (ccs == 2) { // initiate upload
        if (!exists) return sdo_abort(index, sub, kAbortNoObject);
        if (!sub_ok) return sdo_abort(index, sub, kAbortNoSub);
        uint32_t value = 0;
        switch (index) {
        case 0x1000: value = 0x00020192u; break;
        case 0x1001: value = error_register_; break;
        case 0x1016: value = sub == 0 ? 1u : consumer_; break;
        case 0x1017: value = hb_period_ms_; break;
        case 0x1018: {
            const uint32_t ident[5] = {4, cfg_.vendor_id, cfg_.product_code, cfg_.revision, cfg_.serial};
            value = ident[sub];
            break;
        }
        case 0x6007: value = static_cast<uint16_t>(abort_option_); break;
        case 0x6040: value = controlword_; break;
        case 0x6041: value = statusword(); break;
        case 0x6060:
        case 0x6061: value = static_cast<uint8_t>(mode_); break;
        case 0x606C: value = static_cast<uint32_t>(velocity_actual_units()); break;
        case 0x60FF: value = static_cast<uint32_t>(target_velocity_); break;
        default: break;
        }
        uint8_t d[8] = {static_cast<uint8_t>(0x43u | ((4u - obj.size) << 2)), 0, 0, sub, 0, 0, 0, 0};
        put16(&d[1], index);
        put32(&d[4], value);
        for (uint8_t i = obj.size; i < 4; ++i) d[4 + i] = 0;
        send(0x580u + cfg_.node_id, d, 8);
        return;
    }
    sdo_abort(index, sub, kAbortCommand);
}

void Cia402DriveEmu::on_rpdo(const hal_can_frame_t &f)
{
    if (f.dlc != 6) return; // a real drive would send EMCY 0x8210; the master never does this
    counters_.rpdos++;
    target_velocity_ = static_cast<int32_t>(get32(&f.data[2]));
    apply_controlword(get16(&f.data[0]));
}

void Cia402DriveEmu::on_frame(const hal_can_frame_t &f)
{
    if ((f.flags & (HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR)) != 0u) return;
    const uint32_t watched = (consumer_ >> 16) & 0x7Fu;
    if (watched != 0 && (consumer_ & 0xFFFFu) != 0 && f.id == 0x700u + watched && f.dlc == 1 && nmt_ != Nmt::Init) {
        consumer_armed_ = true;
        consumer_last_us_ = now_us_;
    }
    if (f.id == 0x000) {
        on_nmt(f);
    } else if (f.id == 0x600u + cfg_.node_id) {
        if (nmt_ == Nmt::PreOperational || nmt_ == Nmt::Operational) on_sdo(f);
    } else if (f.id == 0x200u + cfg_.node_id) {
        if (nmt_ == Nmt::Operational) on_rpdo(f);
    }
}

void Cia402DriveEmu::advance(double dt_s)
{
    double cmd = 0.0;
    double tau = cfg_.motor_time_constant_s;
    if (state_ == State::OperationEnabled && mode_ == 3) {
        cmd = target_rpm();
    } else if (state_ == State::QuickStopActive || state_ == State::FaultReactionActive) {
        tau = cfg_.quick_stop_time_constant_s;
    }
    cmd_rpm_ = cmd;
    motor_rpm_ += (cmd - motor_rpm_) * (1.0 - std::exp(-dt_s / tau));
    if (std::fabs(motor_rpm_) < 1.0) {
        if (state_ == State::QuickStopActive) state_ = State::SwitchOnDisabled;
        if (state_ == State::FaultReactionActive) state_ = State::Fault;
    }
    slip_ = cfg_.slip_sigma > 0.0 ? rng_normal(&rng_, 0.0, cfg_.slip_sigma) : 0.0;
}

void Cia402DriveEmu::step(uint64_t now_us)
{
    if (!powered_) power_cycle(now_us);
    now_us_ = now_us;
    // the motor first runs to now on the old command; frames that arrived
    // meanwhile act from now on (their exact arrival inside the step is
    // not known to a drive polling its mailbox either)
    if (now_us > last_step_us_) advance(static_cast<double>(now_us - last_step_us_) * 1e-6);
    last_step_us_ = now_us;
    hal_can_frame_t f;
    for (;;) {
        const hal_status_t s = hal_can_receive(ep_, &f, 0);
        if (s == HAL_E_OVERFLOW) continue;
        if (s != HAL_OK) break;
        counters_.rx_frames++;
        on_frame(f);
    }

    if (consumer_armed_ && now_us > consumer_last_us_ + static_cast<uint64_t>(consumer_ & 0xFFFFu) * 1000u) {
        consumer_timeout();
    }
    if (nmt_ == Nmt::Init && now_us >= boot_at_us_) {
        const uint8_t boot = 0x00;
        send(0x700u + cfg_.node_id, &boot, 1);
        nmt_ = Nmt::PreOperational;
        state_ = State::SwitchOnDisabled; // self-test passed (transition 1)
        next_hb_us_ = now_us + static_cast<uint64_t>(hb_period_ms_) * 1000u;
    }
    if (nmt_ != Nmt::Init && hb_period_ms_ > 0 && now_us >= next_hb_us_) {
        const uint8_t st = static_cast<uint8_t>(nmt_);
        send(0x700u + cfg_.node_id, &st, 1);
        counters_.heartbeats++;
        const uint64_t period = static_cast<uint64_t>(hb_period_ms_) * 1000u;
        next_hb_us_ += period;
        if (next_hb_us_ <= now_us) next_hb_us_ = now_us + period;
    }
    if (nmt_ == Nmt::Operational) {
        constexpr uint16_t kEventBits = static_cast<uint16_t>(~(0x0400u | 0x1000u)); // not the speed flags
        const bool changed = ((statusword() ^ last_tpdo_sw_) & kEventBits) != 0u;
        if (changed || now_us >= next_tpdo_us_) {
            send_tpdo();
            next_tpdo_us_ = now_us + cfg_.tpdo_period_us;
        }
    }
}

} // namespace coslam::sim
