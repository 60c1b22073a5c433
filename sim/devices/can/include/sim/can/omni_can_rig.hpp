// sim/can/omni_can_rig.hpp - the simulated drive side of one robot: a CAN
// bus, the robot's endpoint (hand it to the firmware's cia402_omni driver),
// and three emulated CiA 402 wheel drives, plus the ground-truth body
// velocity the physics integrates (from the true, slipping wheel speeds,
// through the same omni kinematics the firmware uses).
#ifndef COSLAM_SIM_OMNI_CAN_RIG_HPP
#define COSLAM_SIM_OMNI_CAN_RIG_HPP

#include <array>
#include <cstdint>
#include <memory>

#include "omni/omni_kinematics.h"
#include "sim/can/can_bus.hpp"
#include "sim/can/cia402_drive_emu.hpp"

namespace coslam::sim {

struct OmniCanRigConfig {
    std::array<uint8_t, OMNI_WHEELS> node_id{{1, 2, 3}};
    /// Template for the three drives: node_id is taken from node_id[k],
    /// seed becomes seed + k, gear_ratio from the kinematics.
    Cia402DriveEmuConfig drive{};
    omni_kinematics_config_t kinematics = omni_kinematics_config_default();
    CanBus::Config bus{};
};

class OmniCanRig {
public:
    explicit OmniCanRig(CanBus::Clock now_us, const OmniCanRigConfig &cfg = OmniCanRigConfig{});

    hal_can_t *robot_can() { return robot_; }
    CanBus &bus() { return bus_; }
    Cia402DriveEmu &drive(int k) { return *drives_.at(static_cast<std::size_t>(k)); }

    /// Step the three drives to now_us (the firmware polls on its own).
    void step(uint64_t now_us);

    /// Ground truth: body velocity from the true wheel speeds [m/s, m/s, rad/s].
    void true_body_velocity(double &vx_mps, double &vy_mps, double &w_radps) const;

private:
    OmniCanRigConfig cfg_;
    CanBus bus_;
    hal_can_t *robot_;
    std::array<std::unique_ptr<Cia402DriveEmu>, OMNI_WHEELS> drives_;
};

} // namespace coslam::sim

#endif // COSLAM_SIM_OMNI_CAN_RIG_HPP
