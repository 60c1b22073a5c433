// sim/world/sim_robot.hpp - one simulated Robotino: its devices on the wire
// and its body in the world.
//
// Devices (each behind the HAL handle its firmware driver expects):
//  - laser: UrgEmulator (real SCIP 2.0 bytes) whose ranges are rays cast in
//    the world from the laser's true pose (walls, pillars, other robots);
//  - drives: OmniCanRig (CAN bus + three CiA 402 drive emulators);
//  - GPIO: SimGpio, line 0 bumper (high while the body touches anything),
//    line 1 e-stop (normally-closed loop: high = released, held high),
//    line 2 status LED (driven by the firmware);
//  - link: its endpoint on the team's SimLinkHub (positions fed each step);
//  - camera and sightings, one of (SimRobotConfig.camera):
//    pixels: PixelCamera (pixel_camera.hpp): frames rendered from the true
//    pose into a SimCamera, the real detector (firmware/vision) on them;
//    oracle: SightingOracle, the geometric stand-in (sighting_oracle.hpp).
// Physics, per step dt: the true body velocity comes from the drives' true
// (slipping) wheel speeds through the omni kinematics; the increment it
// gives over dt is perturbed by Gaussian floor slip drawn with the core's
// motion model (motion_sample: variance odo_xy / odo_theta per metre of
// wheel travel, the paper's injected odometry noise), then applied. A step
// that would bring the body closer to a wall, pillar or robot than its
// radius is not translated (only turned): a collision, counted once per
// contact episode (touches less than 0.5 s apart are one episode).
#ifndef COSLAM_SIM_WORLD_SIM_ROBOT_HPP
#define COSLAM_SIM_WORLD_SIM_ROBOT_HPP

#include <cstdint>
#include <memory>

#include "app/robot_node.h"
#include "coslam/rng.h"
#include "coslam/slam_params.h"
#include "sim/can/omni_can_rig.hpp"
#include "sim/world/pixel_camera.hpp"
#include "sim/world/scenario.hpp"
#include "sim/world/sighting_oracle.hpp"
#include "sim/world/world.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_gpio.hpp"
#include "sim_hal/sim_link.hpp"
#include "urg/urg_emulator.h"

namespace coslam::sim {

struct SimRobotConfig {
    int id = 0;
    pose2_t start{0, 0, 0};
    double radius_m = 0.19;
    double odo_xy_var_m2_per_m = 0.02 * 0.02;       ///< injected floor slip
    double odo_theta_var_rad2_per_m = 0.0175 * 0.0175;
    double wheel_slip_sd = 0.0;                     ///< drive emulators' per-step slip
    pose2_t laser_mount{0.12, 0.0, 0.0};
    double laser_noise_sd_m = 0.01;
    double laser_noise_rel = 0.01;
    uint64_t laser_reply_delay_us = 0;              ///< URG emulator reply_delay_us
    CameraSource camera = CameraSource::Pixels;
    SightingOracleConfig oracle;          ///< camera == Oracle
    PixelCameraConfig pixels;             ///< camera == Pixels
    uint64_t seed_motion = 1, seed_laser = 2, seed_drive = 3;
};

class SimRobot {
public:
    static constexpr uint32_t kBumperLine = 0, kEstopLine = 1, kLedLine = 2, kGpioLines = 4;

    SimRobot(SimClock &clock, World &world, SimLinkHub &hub, const SimRobotConfig &cfg);
    SimRobot(const SimRobot &) = delete;
    SimRobot &operator=(const SimRobot &) = delete;

    /// The handles for this robot's firmware (robot_node_init).
    robot_node_io_t io();

    /// Advance the devices and the body to now_us over the last dt_s.
    void physics_step(uint64_t now_us, double dt_s);

    int id() const { return cfg_.id; }
    const pose2_t &pose() const { return pose_; }
    bool in_contact() const { return contact_; }
    uint32_t wall_collisions() const { return wall_collisions_; }
    uint32_t robot_collisions() const { return robot_collisions_; }
    /// Physics steps spent touching something.
    uint64_t contact_steps() const { return contact_steps_; }
    double min_wall_clearance_m() const { return min_wall_clearance_m_; }
    double distance_m() const { return distance_m_; }

    /// Fault (kidnap): move the true body to `to` if the body fits there
    /// (clear of walls, boxes, pillars and robots); false (nothing moved)
    /// otherwise. The devices see the world from there at the next step.
    bool teleport(const pose2_t &to);
    /// Fault: the camera (stand-in or pixel camera) stops delivering frames.
    void set_camera_stalled(bool stalled);

    OmniCanRig &rig() { return rig_; }
    UrgEmulator &urg() { return *urg_; }
    SimGpio &gpio() { return gpio_; }
    /// The camera stand-in; throws std::logic_error unless camera == Oracle.
    SightingOracle &oracle();
    /// The pixel camera, nullptr unless camera == Pixels.
    PixelCamera *pixel_camera() { return pixels_.get(); }
    const PixelCamera *pixel_camera() const { return pixels_.get(); }
    /// Times true landmark j was detected (from either source).
    const std::vector<int> &detections() const;
    /// Detections over the filter's view (from either source).
    const DetectionTally &detection_tally() const;

private:
    double laser_range(double angle_rad) const;

    SimClock &clock_;
    World &world_;
    SimLinkHub &hub_;
    SimRobotConfig cfg_;
    slam_params_t truth_noise_;
    rng_t motion_rng_;
    pose2_t pose_;
    OmniCanRig rig_;
    std::unique_ptr<UrgEmulator> urg_;
    SimGpio gpio_;
    std::unique_ptr<SightingOracle> oracle_;
    std::unique_ptr<PixelCamera> pixels_;
    double vx_ = 0.0, vy_ = 0.0, w_ = 0.0;   ///< true body velocity (robot frame) of the last step
    static constexpr uint64_t kEpisodeGapUs = 500000;
    bool contact_ = false;
    uint64_t last_wall_contact_us_ = 0;
    uint64_t last_robot_contact_us_ = 0;
    uint64_t contact_steps_ = 0;
    uint32_t wall_collisions_ = 0;
    uint32_t robot_collisions_ = 0;
    double min_wall_clearance_m_;
    double distance_m_ = 0.0;
};

}  // namespace coslam::sim

#endif
