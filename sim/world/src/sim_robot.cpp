#include "sim/world/sim_robot.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "coslam/motion.h"

namespace coslam::sim {

namespace {

OmniCanRigConfig rig_config(const SimRobotConfig &c)
{
    OmniCanRigConfig rc;
    rc.drive.slip_sigma = c.wheel_slip_sd;
    rc.drive.seed = c.seed_drive;
    return rc;
}

UrgEmulatorConfig urg_config(const SimRobotConfig &c)
{
    UrgEmulatorConfig uc;
    uc.seed = c.seed_laser;
    uc.noise_sigma_m = c.laser_noise_sd_m;
    uc.noise_rel = c.laser_noise_rel;
    uc.reply_delay_us = c.laser_reply_delay_us;
    return uc;
}

}  // namespace

SimRobot::SimRobot(SimClock &clock, World &world, SimLinkHub &hub, const SimRobotConfig &cfg)
    : clock_(clock), world_(world), hub_(hub), cfg_(cfg), pose_(cfg.start),
      rig_([&clock] { return clock.now_us(); }, rig_config(cfg)), gpio_(clock, kGpioLines),
      min_wall_clearance_m_(std::numeric_limits<double>::infinity())
{
    if (cfg.camera == CameraSource::Oracle) {
        oracle_ = std::make_unique<SightingOracle>(world, cfg.id, cfg.oracle);
    } else {
        pixels_ = std::make_unique<PixelCamera>(clock, world, cfg.id, cfg.pixels);
    }
    truth_noise_ = slam_params_default();
    truth_noise_.noise.odo_xy_var_m2_per_m = cfg.odo_xy_var_m2_per_m;
    truth_noise_.noise.odo_theta_var_rad2_per_m = cfg.odo_theta_var_rad2_per_m;
    rng_seed(&motion_rng_, cfg.seed_motion);
    urg_ = std::make_unique<UrgEmulator>(urg_config(cfg), [this](double a) { return laser_range(a); });
    world_.set_body(cfg.id, pose_, cfg.radius_m);
    gpio_.set_input_level(kEstopLine, true); // the e-stop loop is closed: released
    hub_.set_position(static_cast<uint16_t>(cfg.id), pose_.x, pose_.y);
}

robot_node_io_t SimRobot::io()
{
    robot_node_io_t io;
    io.clock = clock_.handle();
    io.laser = urg_->serial();
    io.can = rig_.robot_can();
    io.gpio = gpio_.handle();
    io.link = hub_.endpoint(static_cast<uint16_t>(cfg_.id));
    io.sightings = oracle_ ? oracle_->source() : pixels_->source();
    return io;
}

SightingOracle &SimRobot::oracle()
{
    if (!oracle_) throw std::logic_error("SimRobot::oracle(): this robot's camera is the pixel camera");
    return *oracle_;
}

const DetectionTally &SimRobot::detection_tally() const
{
    return pixels_ ? pixels_->detection_tally() : oracle_->detection_tally();
}

const std::vector<int> &SimRobot::detections() const
{
    return oracle_ ? oracle_->detections() : pixels_->detections();
}

bool SimRobot::teleport(const pose2_t &to)
{
    const Eigen::Vector2d p(to.x, to.y);
    if (!pose2_is_finite(to) || world_.static_clearance(p) < cfg_.radius_m ||
        world_.body_clearance(p, cfg_.id) < cfg_.radius_m) {
        return false;
    }
    pose_ = to;
    world_.set_body(cfg_.id, pose_, cfg_.radius_m);
    hub_.set_position(static_cast<uint16_t>(cfg_.id), pose_.x, pose_.y);
    return true;
}

void SimRobot::set_camera_stalled(bool stalled)
{
    if (oracle_) oracle_->set_stalled(stalled);
    if (pixels_) pixels_->set_stalled(stalled);
}

double SimRobot::laser_range(double angle_rad) const
{
    const pose2_t s = pose2_compose(pose_, cfg_.laser_mount);
    const double th = s.theta + angle_rad;
    return world_.raycast(Eigen::Vector2d(s.x, s.y), Eigen::Vector2d(std::cos(th), std::sin(th)), 30.0, cfg_.id);
}

void SimRobot::physics_step(uint64_t now_us, double dt_s)
{
    rig_.step(now_us);
    double vx = 0.0, vy = 0.0, w = 0.0;
    rig_.true_body_velocity(vx, vy, w);
    vx_ = vx;
    vy_ = vy;
    w_ = w;
    odo_increment_t u = motion_from_body_velocity(vx, vy, w, dt_s);
    if (u.dx != 0.0 || u.dy != 0.0 || u.dtheta != 0.0) {
        u = motion_sample(&truth_noise_, u, &motion_rng_);
    }
    const pose2_t next = motion_apply(pose_, u);
    const Eigen::Vector2d p(next.x, next.y);
    const bool wall = world_.static_clearance(p) < cfg_.radius_m;
    const bool robot = world_.body_clearance(p, cfg_.id) < cfg_.radius_m;
    // one collision per contact episode: touches less than kEpisodeGapUs apart
    // are the same episode (a blocked robot's slip makes contact flicker)
    if (wall) {
        if (now_us - last_wall_contact_us_ > kEpisodeGapUs || wall_collisions_ == 0) wall_collisions_++;
        last_wall_contact_us_ = now_us;
    }
    if (robot) {
        if (now_us - last_robot_contact_us_ > kEpisodeGapUs || robot_collisions_ == 0) robot_collisions_++;
        last_robot_contact_us_ = now_us;
    }
    contact_ = wall || robot;
    if (contact_) contact_steps_++;
    if (contact_) {
        pose_.theta = next.theta; // blocked: the wheels spin, the body only turns
    } else {
        distance_m_ += std::hypot(next.x - pose_.x, next.y - pose_.y);
        pose_ = next;
    }
    min_wall_clearance_m_ =
        std::fmin(min_wall_clearance_m_, world_.static_clearance(Eigen::Vector2d(pose_.x, pose_.y)) - cfg_.radius_m);
    world_.set_body(cfg_.id, pose_, cfg_.radius_m);
    gpio_.set_input_level(kBumperLine, contact_);
    urg_->set_time_us(now_us);
    if (oracle_) {
        oracle_->set_time_us(now_us);
    } else {
        pixels_->set_time_us(now_us, vx_, vy_, w_);
    }
    hub_.set_position(static_cast<uint16_t>(cfg_.id), pose_.x, pose_.y);
}

}  // namespace coslam::sim
