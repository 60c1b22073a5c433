// Fault injection (issue 12, item 5): the paper scenario (oracle camera, for
// speed) with one [[fault]] at a time, injected at the wire / device level
// (docs/sim.md "Faults"), on robot 1 (EKF-SLAM) after the robots merged
// (about 65 s) unless said otherwise.
//
// Claims, per fault:
//  1. the run completes; no NaN in any robot's pose or exported map (every
//     landmark mean and covariance, the pose and its covariance), sampled
//     every 0.5 s and at the end;
//  2. the fault was seen by the firmware: the node counter that belongs to
//     it moved (laser_lost / scan_errors, can_errors and drive_faults,
//     drive_faults, stop_steps, no frames, link drops, the health monitor);
//  3. recovery: from kRecoverS after the fault ended to the end of the run
//     the robot's position error stays below kPoseErrM; and every true
//     landmark its map held (matched within the evaluation gate) when the
//     fault started is still held at the end (nothing merged is lost);
//  4. a fault the filter cannot recover from (a kidnap: the landmarks are
//     not unique and the pose is wrong by metres; wheels that report five
//     times the true speed, or random speeds) is instead reported by the
//     health monitor within kDetectS: the scan-to-scan odometry check
//     (app/odo_check.h) sees the laser move differently from the wheels,
//     or scans that no motion explains.
// And the false-alarm checks: fault-free runs on seeds 1, 2, 3, where the
// health monitor must never report divergence on either robot; and
// fault-free runs in other worlds (a wider arena with wheel slip, a
// corridor where the laser cannot see motion along it), new seeds, where
// the odometry check must never fire.
//
// Why the bounds. kPoseErrM = 0.5 m: the EKF robot's position error in the
// fault-free run stays below 0.2 m (RMSE 0.07 m after the merge, seeds
// 1-3); a fault that leaves 0.5 m behind has left a bias the map did not
// correct. The faults last 5 s at 0.2 m/s: 1 m of travel without one of
// the inputs; kRecoverS = 10 s (50 camera frames, 2 m of travel) is enough
// for the landmarks in view to pull the pose back, and short enough that a
// filter that did not recover is not excused by the end of the run.
// kDetectS = 15 s: three health windows (5 s each, 25 frames).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

#include "sim/world/scenario.hpp"
#include "sim/world/simulation.hpp"

using namespace coslam::sim;

namespace {

const std::string kPaper = std::string(COSLAM_SOURCE_DIR) + "/sim/scenarios/paper.toml";
constexpr double kPoseErrM = 0.5;
constexpr double kRecoverS = 10.0;
constexpr double kDetectS = 15.0;
constexpr double kFaultAtS = 75.0;
constexpr double kFaultS = 5.0;

Scenario paper()
{
    Scenario sc = load_scenario_file(kPaper);
    sc.camera.source = CameraSource::Oracle;
    return sc;
}

bool finite_map(const map_estimate_t &m)
{
    if (!pose2_is_finite(m.pose)) return false;
    const double *pc = &m.pose_cov.m[0][0];
    for (int i = 0; i < 9; ++i)
        if (!std::isfinite(pc[i])) return false;
    for (int i = 0; i < m.n_landmarks; ++i) {
        const map_landmark_t &l = m.lm[i];
        if (!std::isfinite(l.mean.x) || !std::isfinite(l.mean.y) || !std::isfinite(l.cov.xx) ||
            !std::isfinite(l.cov.xy) || !std::isfinite(l.cov.yy))
            return false;
    }
    return true;
}

struct FaultRun {
    bool finite = true;
    double max_err_after_m = 0.0;   ///< from fault end + kRecoverS to the end
    double max_err_during_m = 0.0;  ///< from the fault start to its end + kRecoverS
    std::set<int> held_at_start, held_at_end;
    std::vector<double> diverged_at_s;
    robot_node_counters_t ctr{};
    SimLinkHub::Stats link{};
    double first_merge_s = -1.0;
    double map_rmse_end_m = 0.0;
    uint32_t rejected_controls = 0;       ///< the filter's (EKF-SLAM robot 1)
    urg_scip2_stats_t urg{};              ///< the laser driver's counters at the end
};

std::set<int> held(Simulation &sim, size_t k, map_estimate_t &buf, map_eval_t *ev_out = nullptr)
{
    (void)robot_node_export(&sim.node(k), &buf);
    std::vector<uint8_t> sig;
    for (const auto &l : sim.world().landmarks()) sig.push_back(l.signature);
    map_eval_t ev{};
    evaluate_map(buf, sim.truth_in_map(k), sig, sim.result().team_detections, sim.scenario().evaluation.min_seen,
                 sim.scenario().evaluation.gate_m, &ev);
    std::set<int> s;
    for (int i = 0; i < ev.n_estimated; ++i)
        if (ev.match[i] >= 0) s.insert(ev.match[i]);
    if (ev_out != nullptr) *ev_out = ev;
    return s;
}

FaultRun run_with(const Scenario &sc, size_t k, double fault_at_s, double fault_end_s, uint64_t seed = 1)
{
    SimulationOptions opt;
    opt.seed = seed;
    Simulation sim(sc, opt);
    FaultRun r;
    auto buf = std::make_unique<map_estimate_t>();
    const pose2_t start = sc.robots[k].start;
    const double end_s = sc.duration_s;
    bool started = false;
    for (double t = 0.5; t <= end_s + 1e-9; t += 0.5) {
        if (!started && t >= fault_at_s) {
            sim.advance_to(fault_at_s - 1e-3);
            r.held_at_start = held(sim, k, *buf);
            started = true;
        }
        sim.advance_to(t);
        for (size_t j = 0; j < sim.n_robots(); ++j) {
            (void)robot_node_export(&sim.node(j), buf.get());
            if (!finite_map(*buf)) r.finite = false;
        }
        pose2_t est;
        cov3_t cov;
        robot_node_pose(&sim.node(k), &est, &cov);
        const pose2_t truth = pose2_between(start, sim.robot(k).pose());
        const double e = std::hypot(est.x - truth.x, est.y - truth.y);
        if (!std::isfinite(e)) r.finite = false;
        if (std::getenv("COSLAM_FAULT_TRACE") != nullptr && t >= fault_at_s - 5.0 && t <= fault_end_s + 30.0) {
            const health_t &h = *robot_node_health(&sim.node(k));
            std::printf("  t %.1f err %.2f nis %.2f unassoc %.2f missed %.2f ess %.2f conflict %.2f odo in %.2f chi2 %.1f "
                        "L %.3f %.3f %.3f U %.3f %.3f %.3f dis %u mis %u%s\n",
                        t, e, h.mean_nis, h.unassoc_frac, h.missed_frac, h.ess_frac, h.conflict_frac,
                        h.odo.last_inlier_frac, h.odo.last_chi2, h.odo.last_laser.x, h.odo.last_laser.y, h.odo.last_laser.theta,
                        h.odo.last_odo.x, h.odo.last_odo.y, h.odo.last_odo.theta, h.odo.disagreements,
                        h.odo.mismatches, h.diverged ? " DIVERGED" : "");
        }
        if (t >= fault_end_s + kRecoverS) {
            r.max_err_after_m = std::fmax(r.max_err_after_m, e);
        } else if (t >= fault_at_s) {
            r.max_err_during_m = std::fmax(r.max_err_during_m, e);
        }
    }
    sim.run();
    map_eval_t ev{};
    r.held_at_end = held(sim, k, *buf, &ev);
    r.map_rmse_end_m = ev.rmse_m;
    if (!finite_map(*buf)) r.finite = false;
    r.diverged_at_s = sim.result().robots[k].diverged_at_s;
    r.ctr = sim.result().robots[k].node;
    r.link = sim.link().stats(static_cast<uint16_t>(k));
    r.first_merge_s = sim.result().robots[k].first_merge_s;
    if (sim.node(k).filter.kind == SLAM_FILTER_EKF) r.rejected_controls = sim.node(k).filter.u.ekf.ctr.rejected_controls;
    r.urg = *urg_scip2_stats(&sim.node(k).urg);
    return r;
}

FaultSpec fault(FaultKind kind, double at_s = kFaultAtS, double duration_s = kFaultS)
{
    FaultSpec f;
    f.robot = 1;
    f.kind = kind;
    f.at_s = at_s;
    f.duration_s = duration_s;
    return f;
}

void report(const char *name, const FaultRun &r)
{
    std::printf("[fault] %-15s max pos err during %.3f m, after recovery %.3f m; landmarks held %zu -> %zu; "
                "map RMSE end %.3f m; rejected controls %u; diverged %zu time(s)%s%.1f\n"
                "        counters: laser_lost %u connect_failures %u scan_errors %u can_errors %u drive_faults %u "
                "stop_steps %u frames %u; link tx_dropped_partition %llu; first merge %.1f s\n",
                name, r.max_err_during_m, r.max_err_after_m, r.held_at_start.size(), r.held_at_end.size(),
                r.map_rmse_end_m, r.rejected_controls, r.diverged_at_s.size(), r.diverged_at_s.empty() ? "" : ", first at ",
                r.diverged_at_s.empty() ? 0.0 : r.diverged_at_s.front(), r.ctr.laser_lost,
                r.ctr.laser_connect_failures, r.ctr.scan_errors, r.ctr.can_errors, r.ctr.drive_faults, r.ctr.stop_steps,
                r.ctr.frames, static_cast<unsigned long long>(r.link.tx_dropped_partition), r.first_merge_s);
}

// the common claims 1 and 3
void expect_recovered(const char *name, const FaultRun &r, double fault_end_s)
{
    report(name, r);
    EXPECT_TRUE(r.finite) << name;
    EXPECT_LT(r.max_err_after_m, kPoseErrM) << name << ": no recovery by " << fault_end_s + kRecoverS << " s";
    for (int j : r.held_at_start) EXPECT_TRUE(r.held_at_end.count(j)) << name << ": true landmark " << j << " lost";
}

FaultRun run_fault(const FaultSpec &f)
{
    Scenario sc = paper();
    sc.faults.push_back(f);
    return run_with(sc, static_cast<size_t>(f.robot), f.at_s, f.at_s + f.duration_s);
}

}  // namespace

// The reference: the same run without a fault, measured over the same spans.
TEST(SimFaults, FaultFreeReference)
{
    const FaultRun r = run_with(paper(), 1, kFaultAtS, kFaultAtS + kFaultS);
    expect_recovered("none", r, kFaultAtS + kFaultS);
    EXPECT_TRUE(r.diverged_at_s.empty());
    EXPECT_EQ(r.ctr.stalls, 0u);
}

TEST(SimFaults, LaserUnplugThenReplug)
{
    const FaultRun r = run_fault(fault(FaultKind::LaserUnplug));
    EXPECT_GE(r.ctr.laser_lost, 1u);          // noticed after laser_lost_us (2 s)
    EXPECT_GE(r.ctr.laser_connect_failures, 1u); // reconnects refused while unplugged
    EXPECT_GT(r.ctr.scan_errors, 0u);
    expect_recovered("laser_unplug", r, kFaultAtS + kFaultS);
}

// The URG's line goes silent for kFaultS (the port stays open, nothing
// comes through either way). The node counts the laser lost after 2 s
// without a scan and tries to connect every retry period; each try's
// replies never come, so it is given up after twice the reply timeout by
// the node's clock (the driver's err_timeout), without the control loop
// waiting for it (no stall). Restored, the next try connects.
TEST(SimFaults, LaserSilent)
{
    const FaultRun r = run_fault(fault(FaultKind::LaserSilent));
    std::printf("laser_silent: laser_lost %u, connect failures %u, urg err_timeout %u, stalls %u\n", r.ctr.laser_lost,
                r.ctr.laser_connect_failures, r.urg.err_timeout, r.ctr.stalls);
    EXPECT_EQ(r.ctr.laser_lost, 1u);
    EXPECT_GE(r.ctr.laser_connect_failures, 1u);
    EXPECT_GE(r.urg.err_timeout, 1u);   // tries given up by the deadline
    EXPECT_EQ(r.ctr.stalls, 0u);        // and never by waiting
    expect_recovered("laser_silent", r, kFaultAtS + kFaultS);
}

// A URG whose replies take 30 ms (a real sensor's are never inside the
// write, as the emulator's are by default): the connect runs over several
// control steps (a command is seen pending between steps) and completes;
// a stop while its MD is pending sends QT, so the sensor does not go on
// scanning after the robot has stopped.
TEST(SimFaults, LaserRepliesTakeTime)
{
    Scenario sc = paper();
    sc.laser.reply_delay_ms = 30.0;
    sc.duration_s = 4.0;
    {
        Simulation sim(sc);
        int pending_steps = 0;
        for (double t = 0.01; t < 1.0; t += 0.01) {
            sim.advance_to(t);
            pending_steps += urg_scip2_pending(&sim.node(0).urg) ? 1 : 0;
        }
        EXPECT_GE(pending_steps, 3); // SCIP2.0, PP and MD each waited at least a step
        EXPECT_TRUE(robot_node_laser_up(&sim.node(0)));
        sim.run();
        EXPECT_GT(sim.result().robots[0].node.scans, 20u);
        EXPECT_EQ(sim.result().robots[0].node.laser_connect_failures, 0u);
    }
    {
        Simulation sim(sc);
        bool md_pending = false;
        for (double t = 0.001; t < 1.0 && !md_pending; t += 0.001) {
            sim.advance_to(t);
            md_pending = sim.node(0).urg.pend == URG_SCIP2_PEND_MD;
        }
        ASSERT_TRUE(md_pending);
        EXPECT_TRUE(sim.robot(0).urg().streaming()); // the sensor took the MD already
        (void)robot_node_shutdown(&sim.node(0));
        EXPECT_FALSE(sim.robot(0).urg().streaming()); // QT
        EXPECT_FALSE(sim.robot(0).urg().laser_on());
        EXPECT_FALSE(urg_scip2_pending(&sim.node(0).urg));
    }
}

TEST(SimFaults, LaserGarbage)
{
    const FaultRun r = run_fault(fault(FaultKind::LaserGarbage));
    EXPECT_GT(r.ctr.scan_errors, 0u);
    expect_recovered("laser_garbage", r, kFaultAtS + kFaultS);
}

TEST(SimFaults, CanErrors)
{
    FaultSpec f = fault(FaultKind::CanErrors);
    f.loss = 0.3;
    const FaultRun r = run_fault(f);
    EXPECT_GT(r.ctr.can_errors, 0u);
    expect_recovered("can_errors", r, kFaultAtS + kFaultS);
}

TEST(SimFaults, DriveEmcy)
{
    const FaultRun r = run_fault(fault(FaultKind::DriveEmcy));
    std::printf("drive_emcy 5 s: drive_faults %u\n", r.ctr.drive_faults);
    EXPECT_GE(r.ctr.drive_faults, 1u);
    expect_recovered("drive_emcy", r, kFaultAtS + kFaultS);
    // one EMCY (1 ms) is one fault, counted once although the polls right
    // after its (asynchronous) reset still report it; before, it counted 2
    // and the robot stood for two retry periods
    const FaultRun one = run_fault(fault(FaultKind::DriveEmcy, kFaultAtS, 0.001));
    std::printf("drive_emcy 1 ms: drive_faults %u\n", one.ctr.drive_faults);
    EXPECT_EQ(one.ctr.drive_faults, 1u);
    expect_recovered("drive_emcy_once", one, kFaultAtS + 0.001);
}

// A new EMCY soon after the robot came back from the last one (inside the
// retry period after that reset) stops it at once: the grace a reset gets to
// clear its own fault applies only until the drive is running again.
TEST(SimFaults, DriveEmcyAgainAfterRecovery)
{
    Scenario sc = paper();
    sc.faults.push_back(fault(FaultKind::DriveEmcy, kFaultAtS, 0.001));
    sc.faults.push_back(fault(FaultKind::DriveEmcy, kFaultAtS + 1.5, 0.001));
    SimulationOptions opt;
    opt.seed = 1;
    Simulation sim(sc, opt);
    sim.advance_to(kFaultAtS + 1.45);  // reset after the sim's 1 s retry period, running again
    EXPECT_EQ(robot_node_state(&sim.node(1)), ROBOT_NODE_RUN);
    sim.advance_to(kFaultAtS + 1.6);
    EXPECT_EQ(robot_node_state(&sim.node(1)), ROBOT_NODE_FAULT);
    EXPECT_EQ(robot_node_counters(&sim.node(1))->drive_faults, 2u);
}

TEST(SimFaults, Estop)
{
    const FaultRun r = run_fault(fault(FaultKind::Estop));
    EXPECT_GE(r.ctr.stop_steps, 450u);  // 5 s of 10 ms steps, less the release debounce
    expect_recovered("estop", r, kFaultAtS + kFaultS);
}

// The control process stalls for 5 s (hung, stopped, or crashed and not yet
// restarted) while the robot drives. The drives' own watchdog (they watch the
// master heartbeat the process sends, docs/robot.md "Drive watchdog") stops
// the wheels within its 200 ms and the quick stop; without it the robot drove
// on blind at its last command. When the process runs again it finds the
// EMCY the drives sent (a drive fault), resets and brings them up again.
TEST(SimFaults, ControllerHang)
{
    Scenario sc = paper();
    sc.faults.push_back(fault(FaultKind::ControllerHang));
    SimulationOptions opt;
    opt.seed = 1;
    Simulation sim(sc, opt);
    auto wheel_rpm = [&] {
        double s = 0.0;
        for (int w = 0; w < 3; ++w) s += std::fabs(sim.robot(1).rig().drive(w).motor_rpm());
        return s;
    };
    sim.advance_to(kFaultAtS - 0.01);
    ASSERT_GT(wheel_rpm(), 100.0) << "the robot must be moving when its controller hangs";
    const pose2_t p0 = sim.robot(1).pose();
    sim.advance_to(kFaultAtS + 0.4); /* 200 ms watchdog + quick stop + margin */
    const pose2_t p1 = sim.robot(1).pose();
    EXPECT_LT(wheel_rpm(), 3.0);
    sim.advance_to(kFaultAtS + kFaultS - 0.01);
    const pose2_t p2 = sim.robot(1).pose();
    const double coast = std::hypot(p1.x - p0.x, p1.y - p0.y);
    const double hung = std::hypot(p2.x - p1.x, p2.y - p1.y);
    std::printf("controller_hang: %.3f m until the drives stopped, %.4f m in the remaining %.1f s\n", coast, hung,
                kFaultS - 0.4);
    EXPECT_LT(coast, 0.3 * 0.4);  /* below the top speed over the 0.4 s */
    EXPECT_LT(hung, 0.002);
    EXPECT_LT(std::fabs(angle_wrap(p2.theta - p1.theta)), 0.01);
    for (int w = 0; w < 3; ++w) EXPECT_EQ(sim.robot(1).rig().drive(w).counters().consumer_timeouts, 1u);

    const FaultRun r = run_fault(fault(FaultKind::ControllerHang));
    std::printf("controller_hang 5 s: drive_faults %u, stalls %u, stall_resets %u\n", r.ctr.drive_faults,
                r.ctr.stalls, r.ctr.stall_resets);
    EXPECT_GE(r.ctr.drive_faults, 1u);
    EXPECT_EQ(r.ctr.stalls, 1u);        /* the node saw its own 5 s gap */
    EXPECT_EQ(r.ctr.stall_resets, 1u);  /* and reset the drives at once, not after the retry period */
    expect_recovered("controller_hang", r, kFaultAtS + kFaultS);
}

TEST(SimFaults, CameraStall)
{
    const FaultRun r = run_fault(fault(FaultKind::CameraStall));
    // 120 s at 5 Hz is 600 frames; 5 s (25 frames) did not come
    EXPECT_LE(r.ctr.frames, 600u - 24u);
    expect_recovered("camera_stall", r, kFaultAtS + kFaultS);
}

// Wrong odometry. The EKF-SLAM robot takes increments that are physically
// possible (motion_is_plausible: up to 3 m/s, 2 pi rad/s) even when they
// are garbage or five times the truth, drifts metres in 5 s and then
// localises itself into a look-alike place among the non-unique markers
// (4 classes), where its innovations are normal: it does not recover. The
// odometry check reports it (the laser moved 0.07 m where the wheels said
// 0.5 m).
void expect_odometry_fault_reported(const FaultSpec &f, const char *name)
{
    const FaultRun r = run_fault(f);
    report(name, r);
    EXPECT_TRUE(r.finite);
    EXPECT_GT(r.max_err_during_m, 1.0);  // the fault is real: the estimate was thrown off
    if (r.diverged_at_s.empty()) {
        expect_recovered(name, r, f.at_s + f.duration_s);
    } else {
        EXPECT_GE(r.diverged_at_s.front(), f.at_s) << name;
        EXPECT_LE(r.diverged_at_s.front(), f.at_s + kDetectS) << name;
    }
}

TEST(SimFaults, OdometryGarbageIsReported)
{
    FaultSpec f = fault(FaultKind::OdometryWild);
    f.garbage = true;
    expect_odometry_fault_reported(f, "odometry_garbage");
}

TEST(SimFaults, OdometryScaledIsReported)
{
    FaultSpec f = fault(FaultKind::OdometryWild);
    f.scale = 5.0;
    expect_odometry_fault_reported(f, "odometry_x5");
}

// The partition cuts the first merge exchange (taken from the fault-free
// run, so that the test follows the path wherever a change moves it): the
// robots still merge once it heals.
TEST(SimFaults, LinkPartitionDuringMerge)
{
    const FaultRun ref = run_with(paper(), 1, kFaultAtS, kFaultAtS + kFaultS);
    ASSERT_GT(ref.first_merge_s, 3.0) << "the fault-free run must merge";
    const double at = ref.first_merge_s - 3.0;
    const FaultSpec f = fault(FaultKind::LinkPartition, at, 8.0);
    const FaultRun r = run_fault(f);
    std::printf("link_partition %.1f-%.1f s: first merge %.1f s (fault-free %.1f s)\n", at, at + 8.0, r.first_merge_s,
                ref.first_merge_s);
    EXPECT_GT(r.link.tx_dropped_partition, 0u);
    EXPECT_GE(r.first_merge_s, at + 8.0);
    report("link_partition", r);
    EXPECT_TRUE(r.finite);
    EXPECT_LT(r.max_err_after_m, kPoseErrM);
}

void expect_kidnap_reported(const pose2_t &to, const char *name)
{
    FaultSpec f = fault(FaultKind::Kidnap, kFaultAtS, 0.0);
    f.to = to;
    const FaultRun r = run_fault(f);
    report(name, r);
    EXPECT_TRUE(r.finite);
    ASSERT_FALSE(r.diverged_at_s.empty()) << name << ": never reported";
    EXPECT_LE(r.diverged_at_s.front(), kFaultAtS + kDetectS);
    EXPECT_GE(r.diverged_at_s.front(), kFaultAtS);
}

// Into the south-west corner, facing north (seed 1): the odometry check
// reports it at the next check (0.1 s later).
TEST(SimFaults, KidnapIsReportedAsDivergence)
{
    expect_kidnap_reported(pose2_t{-3.0, -2.5, 0.5 * COSLAM_PI}, "kidnap_sw");
}

// Kidnaps after which the filter re-localises among look-alike markers with
// normal innovations (seed 1, robot 1): mostly only the odometry check sees
// them, and it can be fooled when both scans show one long wall at a
// similar place. Four destinations at three moments of the run, where the
// robot is somewhere else each time: the rate is the claim, not any one
// kidnap (a change anywhere in the firmware moves the robot's path).
TEST(SimFaults, KidnapElsewhereIsReported)
{
    const struct {
        pose2_t to;
        const char *name;
    } dest[] = {{{2.5, -2.0, 0.5 * COSLAM_PI}, "se"},
                {{-3.0, 2.0, COSLAM_PI}, "nw"},
                {{3.5, 2.5, 0.0}, "ne"},
                {{-3.0, -2.5, 0.5 * COSLAM_PI}, "sw"}};
    int runs = 0, reported = 0;
    for (double at : {kFaultAtS, kFaultAtS + 10.0, kFaultAtS + 20.0}) {
        for (const auto &d : dest) {
            FaultSpec f = fault(FaultKind::Kidnap, at, 0.0);
            f.to = d.to;
            Scenario sc = paper();
            sc.faults.push_back(f);
            const FaultRun r = run_with(sc, 1, at, at);
            EXPECT_TRUE(r.finite);
            double first = -1.0;
            for (double t : r.diverged_at_s) {
                if (t >= at) {
                    first = t;
                    break;
                }
            }
            const bool ok = first >= 0.0 && first <= at + kDetectS;
            std::printf("kidnap_%s at %.0f s: %s %.1f s after\n", d.name, at, ok ? "reported" : "NOT reported",
                        first >= 0.0 ? first - at : -1.0);
            runs++;
            reported += ok ? 1 : 0;
        }
    }
    std::printf("kidnaps reported within %.0f s: %d of %d\n", kDetectS, reported, runs);
    EXPECT_GE(reported, 10) << "of " << runs;
}

class NoFault : public ::testing::TestWithParam<uint64_t> {};

TEST_P(NoFault, HealthMonitorRaisesNoFalseAlarm)
{
    const Scenario sc = paper();
    SimulationOptions opt;
    opt.seed = GetParam();
    Simulation sim(sc, opt);
    sim.run();
    for (size_t k = 0; k < sim.n_robots(); ++k) {
        const RobotRecord &rr = sim.result().robots[k];
        const odo_check_t &oc = rr.health.odo;
        std::printf("[health] seed %llu %s: worst mean NIS %.2f, unassociated %.2f, missed %.2f, ESS %.2f, scan conflicts %.3f; "
                    "odometry check: %u checks, %u unjudged, worst chi2 %.1f, worst inlier fraction %.2f, "
                    "worst drift sum %.1f, %u disagreements, %u mismatches\n",
                    static_cast<unsigned long long>(GetParam()), rr.name.c_str(), rr.health.worst_nis,
                    rr.health.worst_unassoc, rr.health.worst_missed, rr.health.worst_ess, rr.health.worst_conflict,
                    oc.checks, oc.unjudged, oc.worst_chi2, oc.worst_inlier_frac, oc.worst_cusum, oc.disagreements,
                    oc.mismatches);
        EXPECT_TRUE(rr.diverged_at_s.empty()) << rr.name << " diverged at " << rr.diverged_at_s.front() << " s";
        EXPECT_EQ(rr.node.diverged, 0u);
    }
}

INSTANTIATE_TEST_SUITE_P(Seeds, NoFault, ::testing::Values(1u, 2u, 3u));

// Worlds the odometry check was not tuned on: the paper scenario's text
// with another arena and other boxes (its wall landmarks stay where they
// are: only the laser's view matters here).
struct OtherWorld {
    const char *name;
    const char *arena;
    const char *boxes;
    bool slip;        ///< doubled odometry noise and wheel slip
    uint64_t seed;
    const char *landmarks = nullptr; ///< replaces the paper's (they must lie in the arena), nullptr: kept
};

class OdometryCheckQuiet : public ::testing::TestWithParam<OtherWorld> {};

std::string replace_between(std::string s, const std::string &from, const std::string &to, const std::string &with)
{
    const size_t a = s.find(from);
    const size_t b = s.find(to, a);
    if (a == std::string::npos || b == std::string::npos) throw std::runtime_error("scenario text changed: " + from);
    return s.replace(a, b + to.size() - a, with);
}

TEST_P(OdometryCheckQuiet, NoDisagreementOrMismatchWithoutAFault)
{
    const OtherWorld &w = GetParam();
    std::ifstream f(kPaper);
    std::stringstream ss;
    ss << f.rdbuf();
    std::string t = replace_between(ss.str(), "arena = [[", "]]", std::string("arena = ") + w.arena);
    t = replace_between(t, "boxes = [", "\n]", std::string("boxes = [") + w.boxes + "\n]");
    if (w.landmarks != nullptr) {
        t = replace_between(t, "landmarks = [", "\n]", std::string("landmarks = [") + w.landmarks + "\n]");
    }
    if (w.slip) {
        t = replace_between(t, "odo_xy_sd_m = ", "\n", "odo_xy_sd_m = 0.04\n");
        t = replace_between(t, "wheel_slip_sd = ", "\n", "wheel_slip_sd = 0.05\n");
    }
    Scenario sc = load_scenario_string(t);
    sc.camera.source = CameraSource::Oracle;
    sc.duration_s = 180.0;
    SimulationOptions opt;
    opt.seed = w.seed;
    Simulation sim(sc, opt);
    sim.run();
    for (size_t k = 0; k < sim.n_robots(); ++k) {
        const odo_check_t &oc = sim.result().robots[k].health.odo;
        std::printf("[odo] %s seed %llu %s: %u checks, %u unjudged, worst chi2 %.1f (bound %.1f), worst inlier "
                    "fraction %.2f (bound %.2f), worst drift sum %.1f (bound %.1f)\n",
                    w.name, static_cast<unsigned long long>(w.seed), sim.result().robots[k].name.c_str(), oc.checks,
                    oc.unjudged, oc.worst_chi2, oc.cfg.chi2_max, oc.worst_inlier_frac, oc.cfg.min_inlier_frac,
                    oc.worst_cusum, oc.cfg.cusum_h);
        EXPECT_GT(oc.agreements, oc.checks / 2);  // the check did run
        EXPECT_EQ(oc.disagreements, 0u);
        EXPECT_EQ(oc.mismatches, 0u);
    }
}

INSTANTIATE_TEST_SUITE_P(
    Worlds, OdometryCheckQuiet,
    ::testing::Values(OtherWorld{"wide_slip", "[[-6.0, -4.5], [6.0, -4.5], [6.0, 4.5], [-6.0, 4.5]]",
                                 "{ center = [2.5, 1.8], size = [1.0, 0.6] }, { center = [-2.5, -1.8], size = [0.6, 1.0] }, "
                                 "{ center = [3.5, -2.5], size = [0.4, 0.4] }, { center = [-3.5, 2.5], size = [0.4, 0.4] },",
                                 true, 11},
                      // the paper's markers on the corridor's walls (the scenario refuses
                      // a landmark outside the arena)
                      OtherWorld{"corridor", "[[-4.5, -1.6], [4.5, -1.6], [4.5, 1.6], [-4.5, 1.6]]", "", false, 12,
                                 "{ pos = [-3.75, 1.58], signature = 0 }, { pos = [-2.25, 1.58], signature = 1 }, "
                                 "{ pos = [-0.75, 1.58], signature = 2 }, { pos = [0.75, 1.58], signature = 3 }, "
                                 "{ pos = [2.25, 1.58], signature = 0 }, { pos = [3.75, 1.58], signature = 1 }, "
                                 "{ pos = [-3.75, -1.58], signature = 2 }, { pos = [-2.25, -1.58], signature = 3 }, "
                                 "{ pos = [-0.75, -1.58], signature = 0 }, { pos = [0.75, -1.58], signature = 1 }, "
                                 "{ pos = [2.25, -1.58], signature = 2 }, { pos = [3.75, -1.58], signature = 3 }, "
                                 "{ pos = [-4.48, -0.75], signature = 2 }, { pos = [-4.48, 0.75], signature = 3 }, "
                                 "{ pos = [4.48, -0.75], signature = 0 }, { pos = [4.48, 0.75], signature = 1 },"},
                      OtherWorld{"posts_slip", "[[-4.5, -3.5], [4.5, -3.5], [4.5, 3.5], [-4.5, 3.5]]",
                                 "{ center = [3.0, -1.5], size = [0.3, 0.3] }, { center = [-3.0, 1.5], size = [0.3, 0.3] }, "
                                 "{ center = [1.5, -2.5], size = [0.3, 0.3] }, { center = [-1.5, 2.5], size = [0.3, 0.3] },",
                                 true, 13}),
    [](const ::testing::TestParamInfo<OtherWorld> &i) { return std::string(i.param.name); });

TEST(SimFaults, ScenarioFaultTablesAreChecked)
{
    const std::string base = [] {
        std::ifstream f(kPaper);
        std::stringstream ss;
        ss << f.rdbuf();
        return ss.str();
    }();
    const Scenario ok = load_scenario_string(
        base + "\n[[fault]]\nrobot = 1\nkind = \"can_errors\"\nat_s = 3\nduration_s = 2\nloss = 0.2\n");
    ASSERT_EQ(ok.faults.size(), 1u);
    EXPECT_EQ(ok.faults[0].kind, FaultKind::CanErrors);
    EXPECT_DOUBLE_EQ(ok.faults[0].loss, 0.2);
    auto refused = [&](const std::string &t, const std::string &what) {
        try {
            (void)load_scenario_string(base + t);
            ADD_FAILURE() << "accepted: " << t;
        } catch (const ScenarioError &e) {
            EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("line "), std::string::npos) << e.what();
        }
    };
    refused("\n[[fault]]\nrobot = 1\nkind = \"meteor\"\nat_s = 3\nduration_s = 2\n", "unknown fault kind");
    refused("\n[[fault]]\nrobot = 1\nkind = \"estop\"\nat_s = 3\nduration_s = 2\nloss = 0.5\n", "unknown key");
    refused("\n[[fault]]\nrobot = 1\nkind = \"estop\"\nat_s = 3\nduraton_s = 2\n", "duration_s");
    refused("\n[[fault]]\nrobot = 7\nkind = \"estop\"\nat_s = 3\nduration_s = 2\n", "robot");
    refused("\n[[fault]]\nrobot = 0\nkind = \"kidnap\"\nat_s = 3\nto = [2.0, 1.3, 0]\n", "not free space");
    refused("\n[[fault]]\nrobot = 0\nkind = \"kidnap\"\nat_s = 3\nto = [40.0, 0.0, 0]\n", "not free space");
}
