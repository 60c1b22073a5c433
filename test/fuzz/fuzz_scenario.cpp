// libFuzzer target for the simulator's TOML scenario loader
// (sim/world/src/scenario.cpp on toml++).
//
// Input: the TOML text. Seeds: corpus/fuzz_scenario/ (sim/scenarios/
// paper.toml and small hand-written scenarios); dictionary scenario.dict.
//
// Properties checked, beyond "no crash, no ASan/UBSan report":
//  - the only exception is ScenarioError (toml++'s parse_error is turned
//    into one; std::out_of_range, bad_alloc, ... are bugs);
//  - accepted: every number is finite, durations and periods > 0,
//    probabilities in [0, 1], standard deviations >= 0, particles > 0,
//    sizes and radii > 0.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_check.h"
#include "sim/world/scenario.hpp"

using namespace coslam::sim;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

namespace {



void require(bool ok, const char *what)
{
    fuzz_require(ok ? 1 : 0, what);
}

void pos(double v, const char *what)
{
    require(std::isfinite(v) && v > 0.0, what);
}
void nonneg(double v, const char *what)
{
    require(std::isfinite(v) && v >= 0.0, what);
}
void prob(double v, const char *what)
{
    require(std::isfinite(v) && v >= 0.0 && v <= 1.0, what);
}
void fin(double v, const char *what)
{
    require(std::isfinite(v), what);
}

void check(const Scenario &s)
{
    pos(s.duration_s, "duration_s");
    pos(s.physics_dt_ms, "physics_dt_ms");
    pos(s.control_period_ms, "control_period_ms");
    pos(s.sample_period_s, "sample_period_s");
    pos(s.path_period_s, "path_period_s");
    for (const auto &p : s.world.arena) {
        fin(p.x(), "arena x");
        fin(p.y(), "arena y");
    }
    for (const auto &b : s.world.boxes) {
        fin(b.center.x(), "box centre");
        fin(b.center.y(), "box centre");
        pos(b.size.x(), "box size");
        pos(b.size.y(), "box size");
        fin(b.angle_deg, "box angle");
    }
    for (const auto &p : s.world.pillars) {
        fin(p.center.x(), "pillar centre");
        fin(p.center.y(), "pillar centre");
        pos(p.radius_m, "pillar radius");
    }
    for (const auto &w : s.world.walls) {
        fin(w.from.x() + w.from.y() + w.to.x() + w.to.y(), "wall");
    }
    for (const auto &l : s.world.landmarks) {
        fin(l.pos.x(), "landmark x");
        fin(l.pos.y(), "landmark y");
    }
    const CameraSpec &c = s.camera;
    pos(c.period_ms, "camera.period_ms");
    pos(c.fov_deg, "camera.fov_deg");
    nonneg(c.min_range_m, "camera.min_range_m");
    pos(c.max_range_m, "camera.max_range_m");
    prob(c.p_detect, "camera.p_detect");
    prob(c.robot_p_detect, "camera.robot_p_detect");
    nonneg(c.range_sd_m, "camera.range_sd_m");
    nonneg(c.range_sd_rel, "camera.range_sd_rel");
    nonneg(c.bearing_sd_deg, "camera.bearing_sd_deg");
    nonneg(c.robot_range_sd_m, "camera.robot_range_sd_m");
    nonneg(c.robot_bearing_sd_deg, "camera.robot_bearing_sd_deg");
    pos(s.laser.fov_deg, "laser.fov_deg");
    nonneg(s.laser.noise_sd_m, "laser.noise_sd_m");
    nonneg(s.laser.noise_rel, "laser.noise_rel");
    fin(s.laser.mount.x + s.laser.mount.y + s.laser.mount.theta, "laser.mount");
    nonneg(s.link.range_m, "link.range_m");
    nonneg(s.link.latency_ms, "link.latency_ms");
    nonneg(s.link.jitter_ms, "link.jitter_ms");
    prob(s.link.loss, "link.loss");
    nonneg(s.noise.odo_xy_sd_m, "noise.odo_xy_sd_m");
    nonneg(s.noise.odo_theta_sd_deg, "noise.odo_theta_sd_deg");
    nonneg(s.noise.wheel_slip_sd, "noise.wheel_slip_sd");
    fin(s.behaviour.explore_s + s.behaviour.cruise_mps + s.behaviour.max_turn_dps + s.behaviour.seek_turn_dps +
            s.behaviour.linger_s + s.behaviour.goal_tol_m + s.behaviour.bypass_s,
        "behaviour");
    fin(s.meeting.pair_window_ms + s.meeting.resend_s + s.meeting.meeting_gap_s + s.meeting.remerge_s +
            s.meeting.peer_speed_mps + s.meeting.peer_turn_dps + s.meeting.max_range_m + s.meeting.gate_chi2,
        "meeting");
    pos(s.evaluation.gate_m, "evaluation.gate_m");
    for (const auto &r : s.robots) {
        fin(r.start.x, "robot start x");
        fin(r.start.y, "robot start y");
        fin(r.start.theta, "robot start theta");
        require(r.particles > 0, "robot particles > 0");
        pos(r.radius_m, "robot radius");
        nonneg(r.noise.odo_xy_sd_m, "robot noise.odo_xy_sd_m");
        nonneg(r.noise.odo_theta_sd_deg, "robot noise.odo_theta_sd_deg");
        nonneg(r.noise.wheel_slip_sd, "robot noise.wheel_slip_sd");
        if (r.explore_s) {
            fin(*r.explore_s, "robot explore_s");
        }
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const std::string text(reinterpret_cast<const char *>(data), size);
    try {
        const Scenario s = load_scenario_string(text, "fuzz.toml");
        check(s);
    } catch (const ScenarioError &) {
        return 0;
    } catch (const std::exception &e) {
        std::fprintf(stderr, "unexpected exception (not ScenarioError): %s\n", e.what());
        std::abort();
    }
    return 0;
}
