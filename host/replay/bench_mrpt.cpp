// host/replay/bench_mrpt.cpp - MRPT's EKF-SLAM (CRangeBearingKFSLAM2D)
// behind SlamUnderTest. Built only when CMake finds MRPT (mrpt-slam).
//
// Inputs as MRPT expects them: each step is a CActionCollection holding one
// CActionRobotMovement2D whose poseChange is the odometry increment as a
// Gaussian (the same mean and covariance coslam's filters get), and a
// CSensoryFrame holding one CObservationBearingRange with every sighting of
// the camera frame, landmark ID unknown (INVALID_LANDMARK_ID), so MRPT runs
// its own data association (NN or JCBB, Mahalanobis, chi-square gate).
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservationBearingRange.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/slam/CRangeBearingKFSLAM2D.h>

#include <algorithm>

#include <iostream>

#include "bench_slam.h"

namespace coslam::replay {

namespace {

class MrptSlam : public SlamUnderTest {
public:
    explicit MrptSlam(const MrptSlamOptions &o) : opt_(o)
    {
        slam_.options.std_sensor_range = static_cast<float>(o.std_range_m);
        slam_.options.std_sensor_yaw = static_cast<float>(o.std_bearing_rad);
        slam_.options.data_assoc_method = o.jcbb ? mrpt::slam::assocJCBB : mrpt::slam::assocNN;
        slam_.options.data_assoc_metric = mrpt::slam::metricMaha;
        slam_.options.data_assoc_IC_metric = mrpt::slam::metricMaha;
        slam_.options.data_assoc_IC_chi2_thres = o.chi2_quantile;
        slam_.KF_options.verbosity_level = mrpt::system::LVL_ERROR;
        slam_.KF_options.enable_profiler = false;
        slam_.reset();
    }

    std::string name() const override
    {
        return std::string("MRPT CRangeBearingKFSLAM2D (") + (opt_.jcbb ? "JCBB" : "NN") +
               (opt_.own_motion_model ? ", MRPT odometry model" : "") + ")";
    }

    void step(const StreamStep &s) override
    {
        auto acts = mrpt::obs::CActionCollection::Create();
        mrpt::obs::CActionRobotMovement2D act;
        act.estimationMethod = mrpt::obs::CActionRobotMovement2D::emOdometry;
        mrpt::math::CMatrixDouble33 cov;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                cov(i, j) = s.u_cov.m[i][j];
            }
        }
        // MRPT inverts nothing here, but keep the matrix PD for its checks
        for (int i = 0; i < 3; ++i) {
            cov(i, i) += 1e-12;
        }
        const mrpt::poses::CPose2D inc(s.u.dx, s.u.dy, s.u.dtheta);
        if (opt_.own_motion_model) {
            act.computeFromOdometry(inc, mrpt::obs::CActionRobotMovement2D::TMotionModelOptions());
        } else {
            act.poseChange = mrpt::poses::CPosePDFGaussian::Create(inc, cov);
        }
        act.rawOdometryIncrementReading = inc;
        acts->insert(act);

        auto sf = mrpt::obs::CSensoryFrame::Create();
        auto obs = mrpt::obs::CObservationBearingRange::Create();
        obs->minSensorDistance = 0.0f;
        obs->maxSensorDistance = 100.0f;
        obs->fieldOfView_yaw = static_cast<float>(2.0 * M_PI);
        obs->fieldOfView_pitch = 0.0f;
        obs->validCovariances = false;
        obs->sensor_std_range = static_cast<float>(opt_.std_range_m);
        obs->sensor_std_yaw = static_cast<float>(opt_.std_bearing_rad);
        obs->sensor_std_pitch = 0.0f;
        for (const auto &z : s.z) {
            mrpt::obs::CObservationBearingRange::TMeasurement m;
            m.range = static_cast<float>(z.range_m);
            m.yaw = static_cast<float>(z.bearing_rad);
            m.pitch = 0.0f;
            m.landmarkID = mrpt::obs::INVALID_LANDMARK_ID;
            obs->sensedData.push_back(m);
        }
        sf->insert(obs);
        slam_.processActionObservation(acts, sf);
    }

    pose2_t pose() const override
    {
        mrpt::poses::CPosePDFGaussian p;
        slam_.getCurrentRobotPose(p);
        return {p.mean.x(), p.mean.y(), p.mean.phi()};
    }

    void export_map(map_whole_t *out) override
    {
        mrpt::poses::CPosePDFGaussian p;
        std::vector<mrpt::math::TPoint2D> lms;
        std::map<unsigned int, mrpt::maps::CLandmark::TLandmarkID> ids;
        mrpt::math::CVectorDouble x;
        mrpt::math::CMatrixDouble cov;
        slam_.getCurrentState(p, lms, ids, x, cov);
        out->pose = {p.mean.x(), p.mean.y(), p.mean.phi()};
        out->pose_cov = cov3_zero();
        const size_t n = std::min(lms.size(), static_cast<size_t>(COSLAM_MAX_LANDMARKS));
        out->n_landmarks = static_cast<int>(n);
        for (size_t i = 0; i < n; ++i) {
            map_landmark_t &l = out->lm[i];
            const int r = static_cast<int>(3 + 2 * i);
            l = map_landmark_t{};
            l.mean = {lms[i].x, lms[i].y};
            l.cov = cov2_make(cov(r, r), cov(r, r + 1), cov(r + 1, r + 1));
            l.cov_rel = l.cov;
            l.id = static_cast<uint32_t>(i + 1);
            l.n_obs = 1;
            l.src_mask = 1;
        }
        dropped_ = lms.size() - n;
        if (dropped_ > 0) {
            std::cerr << "coslam-bench-mrclam: MRPT's map has " << lms.size() << " landmarks, " << dropped_
                      << " beyond COSLAM_MAX_LANDMARKS are not scored\n";
        }
    }

private:
    MrptSlamOptions opt_;
    mutable mrpt::slam::CRangeBearingKFSLAM2D slam_;
    size_t dropped_ = 0;
};

} // namespace

bool mrpt_available()
{
    return true;
}

std::unique_ptr<SlamUnderTest> make_mrpt_slam(const MrptSlamOptions &opt)
{
    return std::make_unique<MrptSlam>(opt);
}

} // namespace coslam::replay
