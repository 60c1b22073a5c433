// host/replay/bench_slam.h - one SLAM implementation under benchmark, fed a
// single robot's stream of (odometry increment, camera frame) steps.
//
// The MRCLAM benchmark (bench_mrclam.cpp) runs coslam's EKF-SLAM and
// Fast-SLAM and MRPT's CRangeBearingKFSLAM2D behind this interface on
// identical streams: the same odometry increments (after the odometry
// model) with the same covariance, the same sightings, the same evaluation.
#ifndef COSLAM_HOST_REPLAY_BENCH_SLAM_H
#define COSLAM_HOST_REPLAY_BENCH_SLAM_H

#include <memory>
#include <string>
#include <vector>

#include "coslam/cov3.h"
#include "coslam/map_estimate.h"
#include "coslam/motion.h"
#include "coslam/observe.h"
#include "stats.h"

namespace coslam::replay {

/// One step: the odometry since the previous step, then one camera frame.
/// The odometry comes in the robot's control-rate chunks (predict_period_s)
/// and as their composition with the compounded covariance, for a filter
/// that takes one prediction per frame.
struct StreamStep {
    double t_s = 0.0;
    std::vector<odo_increment_t> chunks; ///< control-rate increments since the last step
    std::vector<double> chunk_dt_s;      ///< the time each chunk covers [s]
    odo_increment_t u{};                 ///< their composition
    cov3_t u_cov{};                      ///< its covariance: the chunks' motion_noise_cov compounded
    std::vector<sighting_t> z;           ///< unknown identities (signature 0)
};

class SlamUnderTest {
public:
    virtual ~SlamUnderTest() = default;
    virtual std::string name() const = 0;
    /// Prediction with s.u, then the update with s.z. Timed by the caller.
    virtual void step(const StreamStep &s) = 0;
    virtual pose2_t pose() const = 0;
    /// Every landmark of the final map (confirmed ones for coslam).
    virtual void export_map(map_whole_t *out) = 0;
};

/// MRPT's EKF-SLAM settings (CRangeBearingKFSLAM2D::TOptions).
struct MrptSlamOptions {
    double std_range_m = 0.2;       ///< constant range noise (MRPT has no range-dependent model)
    double std_bearing_rad = 0.02;
    bool jcbb = false;              ///< data association: false = NN, true = JCBB
    double chi2_quantile = 0.99;    ///< individual compatibility test
    /// true: MRPT's own Gaussian odometry model with its default parameters
    /// (computeFromOdometry), as an MRPT user would run it; false: the
    /// odometry covariance coslam's filters get.
    bool own_motion_model = false;
};

/// True if this build has MRPT (the benchmark prints why not otherwise).
bool mrpt_available();
/// MRPT's EKF-SLAM, or nullptr when the build has no MRPT.
std::unique_ptr<SlamUnderTest> make_mrpt_slam(const MrptSlamOptions &opt);

} // namespace coslam::replay

#endif
