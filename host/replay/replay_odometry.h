// host/replay/replay_odometry.h - what the odometry log says the robot did,
// through a model of the log's known defects, and the fit of that model
// against ground truth.
//
// MRCLAM logs the *velocity command* (v, w), not wheel encoders. Integrated
// as is, it overstates the motion by 5-9 % and leads the true motion by
// about 0.2 s (docs/replay.md has the measurements). The model:
//   - the command logged at t acts on the robot from t + delay_s;
//   - the robot realises scale_v * v and scale_w * w;
//   - a command is held until the next record (DESIGN.md, V records).
// Increment records (O) get the same scales and delay; each is spread over
// the interval since the previous record as a constant body velocity (so it
// can be split exactly at any time); the first one is applied at its stamp.
#ifndef COSLAM_HOST_REPLAY_ODOMETRY_H
#define COSLAM_HOST_REPLAY_ODOMETRY_H

#include <string>
#include <vector>

#include "coslam/motion.h"
#include "coslam/pose2.h"
#include "replay_data.h"

namespace coslam::replay {

struct OdoModel {
    double scale_v = 1.0; ///< realised / commanded forward speed (and dx, dy of O records)
    double scale_w = 1.0; ///< realised / commanded turn rate (and dtheta of O records)
    double delay_s = 0.0; ///< the command acts this long after its stamp [s]
};

/// Odometry of one robot as piecewise-constant body velocities, queried for
/// the increment between any two times. Immutable after construction.
class OdoTrack {
public:
    /// `end_s`: the last velocity record is held until this time (the end of
    /// the robot's data). O(n) construction for n records.
    OdoTrack(const RobotLog &log, const OdoModel &model, double end_s);

    /// Increment from t_a to t_b (t_a <= t_b) in the robot frame at t_a,
    /// dtheta unwrapped. Zero outside the logged interval. O(log n + k) for k
    /// records inside the interval.
    odo_increment_t increment(double t_a, double t_b) const;

    /// Time from which the odometry describes the robot (first record + delay).
    double begin_s() const { return begin_s_; }
    bool empty() const { return segs_.empty(); }

private:
    struct Seg {
        double t0;      ///< start [s] (model time: stamp + delay)
        double t1;      ///< end [s]; t1 == t0: an impulse `u` applied at t0
        double vx, vy, w;
        odo_increment_t u;
    };
    std::vector<Seg> segs_;
    double begin_s_ = 0.0;
};

/// u1 then u2 (u2 expressed in the frame at the end of u1), dtheta unwrapped.
odo_increment_t odo_compose(odo_increment_t u1, odo_increment_t u2);

/// Result of fitting OdoModel for one robot against its ground truth.
struct OdoFit {
    int robot = 0;
    OdoModel model;
    int windows = 0;            ///< windows used
    double window_s = 0.0;
    double raw_scale_v = 0.0;   ///< scales at zero delay (what plain integration overstates)
    double raw_scale_w = 0.0;
    double resid_xy_sd_m = 0.0; ///< per-window residual sd (each of dx, dy) after the fit
    double resid_th_sd_rad = 0.0;
    double mean_travel_m = 0.0; ///< mean wheel travel per window
    double w3_m2_per_m = 0.0;   ///< implied odometry noise weights (slam_params.h w3, w4)
    double w4_rad2_per_m = 0.0;
    double drift_raw_m = 0.0;   ///< dead-reckoning position RMSE over 30 s windows, raw commands
    double drift_fit_m = 0.0;   ///< the same with the fitted model
};

/// Fit scale_v, scale_w and delay_s: over consecutive windows of `window_s`
/// the true motion (from ground truth, robot frame at the window start) is
/// compared with the integrated commands shifted by a candidate delay; the
/// scales are the least-squares ratios, and the delay (grid over
/// [-0.5, 0.5] s, step 0.01 s) minimises the residual
/// sum |s_v u_xy - g_xy|^2 + b^2 (s_w u_th - g_th)^2, b = base_radius_m.
/// Windows in which the truth has a gap (> 0.5 s) are skipped.
/// Throws ReplayError if the robot has no ground truth or odometry.
OdoFit fit_odometry(const RobotLog &log, double window_s = 1.0, double base_radius_m = 0.132);

} // namespace coslam::replay

#endif
