#include "sim/can/omni_can_rig.hpp"

#include <stdexcept>
#include <string>

namespace coslam::sim {

OmniCanRig::OmniCanRig(CanBus::Clock now_us, const OmniCanRigConfig &cfg)
    : cfg_(cfg), bus_(std::move(now_us), cfg.bus), robot_(bus_.attach("robot"))
{
    if (omni_kinematics_config_check(&cfg_.kinematics) != COSLAM_OK) {
        throw std::invalid_argument("OmniCanRig: bad kinematics");
    }
    for (std::size_t k = 0; k < drives_.size(); ++k) {
        Cia402DriveEmuConfig dc = cfg_.drive;
        dc.node_id = cfg_.node_id[k];
        dc.seed = cfg_.drive.seed + k;
        dc.gear_ratio = cfg_.kinematics.gear_ratio;
        drives_[k] = std::make_unique<Cia402DriveEmu>(bus_.attach("drive" + std::to_string(dc.node_id)), dc);
    }
}

void OmniCanRig::step(uint64_t now_us)
{
    for (auto &d : drives_) d->step(now_us);
}

void OmniCanRig::true_body_velocity(double &vx_mps, double &vy_mps, double &w_radps) const
{
    double rpm[OMNI_WHEELS];
    for (std::size_t k = 0; k < drives_.size(); ++k) rpm[k] = drives_[k]->true_motor_rpm();
    if (omni_kinematics_forward(&cfg_.kinematics, rpm, &vx_mps, &vy_mps, &w_radps) != COSLAM_OK) {
        vx_mps = vy_mps = w_radps = 0.0;
    }
}

} // namespace coslam::sim
