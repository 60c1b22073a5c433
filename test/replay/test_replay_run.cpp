// test/replay/test_replay_run.cpp - the replay loop end to end:
//  - a seeded synthetic two-robot meeting (host/synth/synth2.h) written as a
//    landmark log and replayed: both robots merge, the transform matches the
//    truth, the outputs are written and complete (runs everywhere);
//  - the first 120 s of robots 1 and 3 of MRCLAM Dataset 6, both filters,
//    with bounds on pose and landmark error and a merge whose transform
//    error is bounded (skipped with a message when the data is absent);
//  - the sighting noise fitted against Dataset 6's ground truth (fit_noise)
//    is a plausible, valid sensor model; without truth it is an error;
//  - the detection rate over the filter's view (fit_detection) on synthetic
//    frames with a known rate, with the logged-frames-only truncation, and
//    with landmarks outside the view model left out.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>

#include "coslam/landmark.h"
#include "coslam/observe.h"
#include "replay_config.h"
#include "replay_data.h"
#include "replay_noise.h"
#include "replay_output.h"
#include "replay_run.h"
#include "stats.h"
#include "synth2.h"

using namespace coslam::replay;
namespace fs = std::filesystem;

namespace {

std::string data_dir()
{
    const char *env = std::getenv("COSLAM_DATA_DIR");
    return std::string(env != nullptr ? env : COSLAM_DATA_DIR) + "/mrclam/MRCLAM_Dataset6";
}

fs::path temp_dir(const std::string &name)
{
    const fs::path p = fs::temp_directory_path() / ("coslam_replay_run_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
}

// Write a synth2 meeting as a landmark-log folder (robots 1 and 2).
void write_synth2(const fs::path &dir, uint64_t seed)
{
    fs::create_directories(dir);
    auto w = std::make_unique<synth2_world_t>();
    auto st = std::make_unique<synth2_step_t>();
    synth2_config_t c = synth2_config_default(seed, 40);
    synth2_init(w.get(), &c);
    std::ofstream log[2] = {std::ofstream(dir / "robot1.log"), std::ofstream(dir / "robot2.log")};
    std::ofstream truth[2] = {std::ofstream(dir / "robot1_truth.txt"), std::ofstream(dir / "robot2_truth.txt")};
    for (int k = 0; k < 2; ++k) {
        log[k] << std::setprecision(17);
        truth[k] << std::setprecision(17);
        log[k] << "O 0 0 0 0\n";
        const pose2_t s = synth2_start_pose(k);
        truth[k] << 0.0 << ' ' << s.x << ' ' << s.y << ' ' << s.theta << '\n';
    }
    int step = 0;
    while (synth2_next(w.get(), st.get())) {
        step++;
        const double t = step * c.dt_s;
        for (int k = 0; k < 2; ++k) {
            const synth2_robot_step_t &r = st->r[k];
            log[k] << "O " << t << ' ' << r.u.dx << ' ' << r.u.dy << ' ' << r.u.dtheta << '\n';
            truth[k] << t << ' ' << r.true_pose.x << ' ' << r.true_pose.y << ' ' << r.true_pose.theta << '\n';
            if (!st->is_frame) {
                continue;
            }
            for (int i = 0; i < r.n_z; ++i) {
                log[k] << "Z " << t << ' ' << r.true_id[i] + 1 << ' ' << r.z[i].range_m << ' ' << r.z[i].bearing_rad
                       << '\n';
            }
            if (r.sees_other) {
                log[k] << "R " << t << ' ' << (2 - k) << ' ' << r.other.range_m << ' ' << r.other.bearing_rad
                       << '\n';
            }
        }
    }
    std::ofstream lm(dir / "landmarks_truth.txt");
    lm << std::setprecision(17);
    for (int j = 0; j < w->n_lm; ++j) {
        lm << j + 1 << ' ' << w->lm[j].x << ' ' << w->lm[j].y << '\n';
    }
}

// The synthetic world's own noise, so the filters' model is the truth's.
ReplayConfig synth_config()
{
    ReplayConfig cfg = replay_config_default();
    cfg.slam = slam_params_default();
    cfg.odo = OdoModel{};
    cfg.input.max_range_m = 100.0;
    cfg.eval.gate_m = 1.0;
    cfg.filter.particles = 100;
    return cfg;
}

} // namespace

TEST(ReplaySynthetic, TwoRobotMeetingMergesBothWaysWithTheTrueTransform)
{
    const fs::path dir = temp_dir("synth");
    write_synth2(dir, 11);
    const Dataset ds = load_dataset(dir.string());
    ASSERT_EQ(ds.robots.size(), 2u);
    for (const FilterKind kind : {FilterKind::Ekf, FilterKind::FastSlam2}) {
        ReplayConfig cfg = synth_config();
        cfg.filter.type = kind;
        ReplayOptions opt;
        int progress_calls = 0;
        double last = -1.0;
        opt.progress = [&](double f) {
            EXPECT_GE(f, last);
            last = f;
            progress_calls++;
        };
        const ReplayResult res = run_replay(ds, cfg, opt);
        EXPECT_GT(progress_calls, 1);
        EXPECT_DOUBLE_EQ(last, 1.0);
        ASSERT_EQ(res.robots.size(), 2u);
        // one meeting: two merges (each robot receives), then the interval holds
        int merged = 0;
        for (const auto &e : res.merges) {
            ASSERT_EQ(e.status, COSLAM_OK) << coslam_status_str(e.status);
            ASSERT_TRUE(e.has_truth);
            merged++;
            // robot sightings have 5 cm / 1 deg noise at 2 m: a few cm
            EXPECT_LT(e.t_err_m, 0.2) << filter_kind_name(kind);
            EXPECT_LT(e.t_err_rad, 0.1);
            EXPECT_LT(e.t_nees, 16.3); // chi-square 3 dof, 99.9 %
            EXPECT_GT(e.stats.added, 0u);
            EXPECT_GT(e.after.n_estimated, e.before.n_estimated);
        }
        EXPECT_EQ(merged, 2) << filter_kind_name(kind);
        if (std::getenv("REPLAY_TEST_VERBOSE") != nullptr) {
            print_summary(std::cout, res, opt);
        }
        for (const auto &r : res.robots) {
            EXPECT_GT(r.pose_samples, 100);
            EXPECT_LT(r.pose_rmse_m, 0.3) << filter_kind_name(kind) << " robot " << r.id;
            EXPECT_TRUE(r.final_score.valid);
            // the merged map carries the sender's own drift relative to its
            // pose at the meeting (docs/map-merge.md): 0.14-0.46 m measured
            EXPECT_LT(r.final_score.rmse_m, 0.6) << filter_kind_name(kind) << " robot " << r.id << " "
                                                  << r.final_score.n_estimated << " " << r.final_score.n_spurious;
            EXPECT_LE(r.final_score.n_spurious, 2);
            ASSERT_TRUE(r.map_before_merge);
            EXPECT_GT(r.t_first_merge_s, 0.0);
            EXPECT_EQ(r.map_after_merge->n_landmarks - r.map_before_merge->n_landmarks, r.shown_merge_gain);
        }
    }
    fs::remove_all(dir);
}

// The pose in the map's fitted frame (RobotResult::pose_fit_rmse_m) does
// not depend on the frame the map is kept in: robot 1 of the synthetic
// meeting starts at heading 180 deg, so its start frame is the world turned
// half round. Run once in the start frame and once in the world frame
// (--start-at-truth), each alone: the same estimates up to that frame, so
// the same fitted pose error; composing the fit the wrong way round would
// give metres in the start frame and nothing in the world frame.
TEST(ReplaySynthetic, PoseInTheFittedMapIgnoresTheMapFrame)
{
    const fs::path dir = temp_dir("synth_fitpose");
    write_synth2(dir, 11);
    const Dataset ds = load_dataset(dir.string());
    ReplayConfig cfg = synth_config();
    cfg.filter.type = FilterKind::Ekf;
    cfg.merge.enabled = false;
    cfg.eval.pose_fit_min_matched = 4;
    ReplayOptions start_frame;
    ReplayOptions world_frame;
    world_frame.start_at_truth = true;
    const ReplayResult a = run_replay(ds, cfg, start_frame);
    const ReplayResult b = run_replay(ds, cfg, world_frame);
    ASSERT_EQ(a.robots.size(), 2u);
    ASSERT_EQ(b.robots.size(), 2u);
    for (size_t k = 0; k < 2; ++k) {
        const RobotResult &ra = a.robots[k];
        const RobotResult &rb = b.robots[k];
        EXPECT_GT(ra.pose_fit_samples, 5) << "robot " << ra.id;
        EXPECT_EQ(ra.pose_fit_samples, rb.pose_fit_samples) << "robot " << ra.id;
        EXPECT_LT(ra.pose_fit_rmse_m, 0.3) << "robot " << ra.id;
        EXPECT_NEAR(ra.pose_fit_rmse_m, rb.pose_fit_rmse_m, 0.01) << "robot " << ra.id;
        EXPECT_NEAR(ra.heading_fit_rmse_rad, rb.heading_fit_rmse_rad, 0.005) << "robot " << ra.id;
    }
    // at least 60 landmarks to match: no sample, and none is made up
    cfg.eval.pose_fit_min_matched = 60;
    const ReplayResult c = run_replay(ds, cfg, start_frame);
    for (const auto &r : c.robots) {
        EXPECT_EQ(r.pose_fit_samples, 0) << "robot " << r.id;
        EXPECT_EQ(r.pose_fit_rmse_m, 0.0);
    }
    fs::remove_all(dir);
}

// A robot whose ground truth begins after its first odometry record is
// scored from the first truth sample on, in a frame placed there so that
// its estimate of that moment is the truth. The filters run as before (the
// truth is only an observer): the other robot's figures are bit for bit
// those of the full truth, and robot 1's are those of the motion since.
TEST(ReplaySynthetic, TruthBeginningLateIsScoredFromItsFirstSample)
{
    const fs::path dir = temp_dir("synth_late_truth");
    write_synth2(dir / "full", 11);
    fs::create_directories(dir / "late");
    for (const char *f : {"robot1.log", "robot2.log", "robot2_truth.txt", "landmarks_truth.txt"}) {
        fs::copy_file(dir / "full" / f, dir / "late" / f);
    }
    {
        // robot 1's truth from t = 5 s on
        std::ifstream in(dir / "full" / "robot1_truth.txt");
        std::ofstream out(dir / "late" / "robot1_truth.txt");
        out << std::setprecision(17);
        double t, x, y, th;
        while (in >> t >> x >> y >> th) {
            if (t >= 5.0 - 1e-9) {
                out << t << ' ' << x << ' ' << y << ' ' << th << '\n';
            }
        }
    }
    ReplayConfig cfg = synth_config();
    cfg.filter.type = FilterKind::Ekf;
    const ReplayResult full = run_replay(load_dataset((dir / "full").string()), cfg, ReplayOptions{});
    const ReplayResult late = run_replay(load_dataset((dir / "late").string()), cfg, ReplayOptions{});
    ASSERT_EQ(late.robots.size(), 2u);
    const RobotResult &f1 = full.robots[0];
    const RobotResult &l1 = late.robots[0];
    EXPECT_EQ(f1.t_frame_s, f1.t_start_s);
    EXPECT_TRUE(l1.has_truth);
    // the first prediction step at or after the first truth sample
    EXPECT_GE(l1.t_frame_s, 5.0 - 1e-6);
    EXPECT_LE(l1.t_frame_s, 5.0 + cfg.filter.predict_period_s + 1e-6);
    // scored from then on: fewer samples, but most of them
    EXPECT_GT(l1.pose_samples, f1.pose_samples / 2);
    EXPECT_LT(l1.pose_samples, f1.pose_samples);
    EXPECT_LT(l1.pose_rmse_m, 0.3);
    EXPECT_TRUE(l1.final_score.valid);
    EXPECT_LT(l1.final_score.rmse_m, 0.6);
    EXPECT_EQ(l1.final_score.n_estimated, f1.final_score.n_estimated);
    // the frame differs from the start frame by the estimate's error at 5 s
    // in the true frame: centimetres, not metres
    const pose2_t d = pose2_between(f1.frame.origin, l1.frame.origin);
    EXPECT_LT(std::hypot(d.x, d.y), 0.3);
    EXPECT_LT(std::fabs(d.theta), 0.1);
    // robot 2 is untouched
    EXPECT_EQ(late.robots[1].pose_rmse_m, full.robots[1].pose_rmse_m);
    EXPECT_EQ(late.robots[1].final_score.rmse_m, full.robots[1].final_score.rmse_m);
    EXPECT_EQ(late.merges.size(), full.merges.size());
    bool noted = false;
    for (const auto &n : late.notes) {
        noted = noted || n.find("ground truth begins after its start") != std::string::npos;
    }
    EXPECT_TRUE(noted);
    // a replay that ends before the truth begins leaves the robot unscored, and says so
    ReplayOptions short_run;
    short_run.duration_s = 4.0;
    const ReplayResult cut = run_replay(load_dataset((dir / "late").string()), cfg, short_run);
    EXPECT_FALSE(cut.robots[0].has_truth);
    EXPECT_EQ(cut.robots[0].pose_samples, 0);
    bool never = false;
    for (const auto &n : cut.notes) {
        never = never || n.find("never overlapped") != std::string::npos;
    }
    EXPECT_TRUE(never);
    fs::remove_all(dir);
}

// The replay runs EKF-SLAM's merges in parts as the robot does: with a
// budget of one unit each merge takes many idle calls, the filters' inputs
// are held meanwhile, and the map after each merge is scored once it is
// done, not by finishing it at once (merges_forced stays 0). The maps end
// as with the merges at once (the same merges, the same inputs after them).
TEST(ReplaySynthetic, EkfMergesInPartsAreNotForcedByTheEvaluation)
{
    const fs::path dir = temp_dir("synth_ekf_parts");
    write_synth2(dir, 11);
    const Dataset ds = load_dataset(dir.string());
    ReplayConfig cfg = synth_config();
    cfg.filter.type = FilterKind::Ekf;
    cfg.merge.core.step_units = 0U;
    const ReplayResult once = run_replay(ds, cfg, ReplayOptions{});
    cfg.merge.core.step_units = 1U;
    const ReplayResult parts = run_replay(ds, cfg, ReplayOptions{});
    ASSERT_EQ(parts.merges.size(), once.merges.size());
    ASSERT_EQ(parts.robots.size(), 2u);
    for (size_t k = 0; k < parts.merges.size(); ++k) {
        EXPECT_EQ(parts.merges[k].status, once.merges[k].status);
        EXPECT_TRUE(parts.merges[k].after.valid);
        EXPECT_EQ(parts.merges[k].after.n_estimated, once.merges[k].after.n_estimated);
    }
    for (size_t k = 0; k < 2; ++k) {
        const auto &c = parts.robots[k].counters;
        EXPECT_GT(c.at("merges_in_parts"), 0) << "robot " << k;
        EXPECT_GT(c.at("inputs_held"), 0) << "robot " << k;
        EXPECT_EQ(c.at("merges_forced"), 0) << "robot " << k;
        EXPECT_EQ(c.at("holds_forced"), 0) << "robot " << k;
        EXPECT_EQ(parts.robots[k].final_score.n_estimated, once.robots[k].final_score.n_estimated);
        EXPECT_NEAR(parts.robots[k].final_score.rmse_m, once.robots[k].final_score.rmse_m, 1e-9);
    }
    fs::remove_all(dir);
}

// The parts of a pose NEES: the position's on its 2x2 block, the heading's
// on its variance (wrapped), neither with the cross terms, so with a
// position-heading correlation they do not add up to the whole.
TEST(PoseNees, PartsOfACorrelatedCovariance)
{
    cov3_t c{};
    c.m[0][0] = 0.04;
    c.m[1][1] = 0.09;
    c.m[0][1] = c.m[1][0] = 0.018; // correlation 0.3
    c.m[2][2] = 0.01;
    c.m[0][2] = c.m[2][0] = 0.01; // position x - heading, correlation 0.5
    const pose2_t truth = {1.0, 2.0, 3.1};
    const pose2_t est = {1.2, 1.7, -3.1}; // heading error 2 pi - 6.2 across the wrap
    double xy = 0.0, th = 0.0;
    nees_pose_parts(est, c, truth, &xy, &th);
    const double ex = 0.2, ey = -0.3, det = 0.04 * 0.09 - 0.018 * 0.018;
    EXPECT_NEAR(xy, (0.09 * ex * ex - 2.0 * 0.018 * ex * ey + 0.04 * ey * ey) / det, 1e-12);
    const double eth = 2.0 * M_PI - 6.2;
    EXPECT_NEAR(th, eth * eth / 0.01, 1e-9);
    EXPECT_GT(std::fabs(xy + th - nees_pose(est, c, truth)), 0.1);
    c.m[2][2] = 0.0; // not positive: no heading part
    nees_pose_parts(est, c, truth, &xy, &th);
    EXPECT_TRUE(std::isnan(th));
    EXPECT_TRUE(std::isfinite(xy));
}

TEST(ReplaySynthetic, OutputsAreCompleteAndReadable)
{
    const fs::path dir = temp_dir("synth_out");
    write_synth2(dir / "data", 12);
    const Dataset ds = load_dataset((dir / "data").string());
    ReplayConfig cfg = synth_config();
    cfg.filter.type = FilterKind::Ekf;
    ReplayOptions opt;
    const ReplayResult res = run_replay(ds, cfg, opt);
    write_run_outputs((dir / "out").string(), ds, cfg, opt, res, RunInfo{"test", 0.0});
    for (const char *f : {"robot1_path.tum", "robot1_truth_path.tum", "robot1_map.csv", "robot1_truth_map.csv",
                          "robot1_map_before_merge.csv", "robot1_map_after_merge.csv", "robot2_path.tum",
                          "errors.csv", "map_errors.csv", "merge_events.csv", "metrics.json"}) {
        EXPECT_TRUE(fs::exists(dir / "out" / f)) << f;
    }
    std::ifstream jf(dir / "out" / "metrics.json");
    const nlohmann::json j = nlohmann::json::parse(jf);
    EXPECT_EQ(j["robots"].size(), 2u);
    EXPECT_EQ(j["merges"]["merged"].get<int>(), 2);
    EXPECT_NEAR(j["robots"][0]["pose"]["rmse_m"].get<double>(), res.robots[0].pose_rmse_m, 1e-12);
    // the pose NEES's position (2 dof) and heading (1 dof) parts
    EXPECT_NEAR(j["robots"][0]["pose"]["nees_xy_mean"].get<double>(), res.robots[0].pose_nees_xy_mean, 1e-12);
    EXPECT_NEAR(j["robots"][0]["pose"]["nees_heading_mean"].get<double>(), res.robots[0].pose_nees_heading_mean,
                1e-12);
    EXPECT_GT(res.robots[0].pose_nees_xy_mean, 0.0);
    EXPECT_GT(res.robots[0].pose_nees_heading_mean, 0.0);
    EXPECT_TRUE(j["merges"]["events"][0].contains("t_err_m"));
    // TUM rows: t x y z qx qy qz qw with a unit quaternion
    std::ifstream tum(dir / "out" / "robot1_path.tum");
    std::string line;
    std::getline(tum, line); // comment
    double t, x, y, z, qx, qy, qz, qw;
    tum >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
    EXPECT_NEAR(qz * qz + qw * qw, 1.0, 1e-9);
    // merge_events.csv has the t column tools/plot_run.py marks merges with
    std::ifstream me(dir / "out" / "merge_events.csv");
    std::getline(me, line);
    EXPECT_EQ(line.rfind("t,robot,sender,", 0), 0u);
    // a converted dataset replays identically
    write_landmark_log(ds, (dir / "copy").string());
    const ReplayResult res2 = run_replay(load_dataset((dir / "copy").string()), cfg, opt);
    EXPECT_EQ(res2.robots[0].pose_rmse_m, res.robots[0].pose_rmse_m);
    EXPECT_EQ(res2.merges.size(), res.merges.size());
    fs::remove_all(dir);
}

// Where nothing was measured the outputs say so: nan in the CSVs, null in
// metrics.json, never a -1 a plot would draw (errors.csv nees, the merge
// transform errors without truth, merge times without a merge, EKF-SLAM's
// particles). The merge counts name their unit (sums over the particles).
TEST(ReplaySynthetic, OutputsSayNotMeasuredAsNanAndNull)
{
    const fs::path dir = temp_dir("synth_unmeasured");
    write_synth2(dir / "data", 12);
    fs::remove(dir / "data" / "robot1_truth.txt"); // robot 1's merges have no true transform
    const Dataset ds = load_dataset((dir / "data").string());
    ReplayConfig cfg = synth_config();
    cfg.filter.type = FilterKind::Ekf;
    ReplayOptions opt;
    ReplayResult res = run_replay(ds, cfg, opt);
    ASSERT_FALSE(res.merges.empty());
    // a pose covariance without an inverse: the sample has no NEES
    ASSERT_TRUE(res.robots[1].has_truth);
    ASSERT_TRUE(res.robots[1].path.at(3).has_truth);
    res.robots[1].path.at(3).cov = cov3_t{};
    write_run_outputs((dir / "out").string(), ds, cfg, opt, res, RunInfo{"test", 0.0});
    // the columns of a CSV by name, each row's cells as text
    auto read = [](const fs::path &p) {
        std::ifstream f(p);
        std::string line;
        std::getline(f, line);
        std::vector<std::string> head;
        std::stringstream hs(line);
        for (std::string c; std::getline(hs, c, ',');) head.push_back(c);
        std::vector<std::map<std::string, std::string>> rows;
        while (std::getline(f, line)) {
            std::stringstream ls(line);
            std::map<std::string, std::string> row;
            size_t i = 0;
            for (std::string c; std::getline(ls, c, ',') && i < head.size(); ++i) row[head[i]] = c;
            rows.push_back(row);
        }
        return std::make_pair(head, rows);
    };
    const auto [mh, merges] = read(dir / "out" / "merge_events.csv");
    EXPECT_NE(std::find(mh.begin(), mh.end(), "fused_particle_sum"), mh.end());
    EXPECT_NE(std::find(mh.begin(), mh.end(), "added_particle_sum"), mh.end());
    ASSERT_EQ(merges.size(), res.merges.size());
    for (const auto &m : merges) {
        for (const char *c : {"t_err_m", "t_err_rad", "t_nees"}) {
            EXPECT_EQ(m.at(c), "nan") << c << " of a merge without truth";
        }
    }
    const auto [eh, errors] = read(dir / "out" / "errors.csv");
    int nees_nan = 0;
    for (const auto &e : errors) {
        const std::string &n = e.at("nees");
        nees_nan += n == "nan";
        EXPECT_TRUE(n == "nan" || std::stod(n) >= 0.0) << "a sentinel NEES: " << n;
    }
    EXPECT_EQ(nees_nan, 1) << "the sample with a singular covariance";
    std::ifstream jf(dir / "out" / "metrics.json");
    const nlohmann::json j = nlohmann::json::parse(jf);
    for (const auto &r : j["robots"]) {
        EXPECT_TRUE(r["particles"].is_null()) << "EKF-SLAM has no particles";
    }
    EXPECT_TRUE(j["merges"]["events"][0].contains("fused_particle_sum"));
    // a run that ends before any merge: no merge times, no merge shown
    opt.duration_s = 1.0;
    const ReplayResult early = run_replay(ds, cfg, opt);
    ASSERT_TRUE(early.merges.empty());
    write_run_outputs((dir / "early").string(), ds, cfg, opt, early, RunInfo{"test", 0.0});
    std::ifstream ef(dir / "early" / "metrics.json");
    const nlohmann::json je = nlohmann::json::parse(ef);
    for (const auto &r : je["robots"]) {
        EXPECT_TRUE(r["first_merge_t_s"].is_null());
        EXPECT_TRUE(r["shown_merge_t_s"].is_null());
        EXPECT_TRUE(r["shown_merge_added"].is_null());
    }
    fs::remove_all(dir);
}

TEST(ReplaySynthetic, RequestErrors)
{
    const fs::path dir = temp_dir("synth_err");
    write_synth2(dir, 13);
    const Dataset ds = load_dataset(dir.string());
    ReplayConfig cfg = synth_config();
    ReplayOptions opt;
    opt.robots = {1, 7};
    try {
        run_replay(ds, cfg, opt);
        FAIL();
    } catch (const ReplayError &e) {
        EXPECT_NE(std::string(e.what()).find("no robot 7"), std::string::npos);
    }
    opt.robots = {1, 1};
    EXPECT_THROW(run_replay(ds, cfg, opt), ReplayError);
    opt.robots = {1};
    cfg.slam.gate_chi2 = -1.0;
    EXPECT_THROW(run_replay(ds, cfg, opt), ReplayError);
    // no merges without a partner; a single robot replays alone
    cfg = synth_config();
    const ReplayResult r = run_replay(ds, cfg, opt);
    EXPECT_EQ(r.robots.size(), 1u);
    EXPECT_TRUE(r.merges.empty());
    fs::remove_all(dir);
}

namespace {

// Rewrite one record of a log file: the k-th line starting with `tag`
// (negative k counts from the end) gets `edit` applied to its fields.
void edit_record(const fs::path &file, char tag, int k, const std::function<void(std::vector<double> &)> &edit)
{
    std::ifstream in(file);
    std::vector<std::string> lines;
    std::vector<size_t> idx;
    for (std::string l; std::getline(in, l);) {
        if (!l.empty() && l[0] == tag) {
            idx.push_back(lines.size());
        }
        lines.push_back(l);
    }
    ASSERT_FALSE(idx.empty());
    const size_t at = idx[k >= 0 ? static_cast<size_t>(k) : idx.size() - static_cast<size_t>(-k)];
    std::istringstream ss(lines[at].substr(1));
    std::vector<double> f;
    for (double v; ss >> v;) {
        f.push_back(v);
    }
    edit(f);
    std::ostringstream os;
    os << std::setprecision(17) << tag;
    for (const double v : f) {
        os << ' ' << v;
    }
    lines[at] = os.str();
    std::ofstream out(file);
    for (const auto &l : lines) {
        out << l << '\n';
    }
}

} // namespace

// --known-ids on a log whose sightings carry no identity is refused with a
// message, not replayed into garbage.
TEST(ReplaySynthetic, KnownIdsRefusesLogsWithoutIdentities)
{
    const fs::path dir = temp_dir("synth_noids");
    write_synth2(dir, 14);
    {
        std::ifstream in(dir / "robot1.log");
        std::vector<std::string> lines;
        for (std::string l; std::getline(in, l);) {
            if (!l.empty() && l[0] == 'Z') {
                std::istringstream ss(l.substr(1));
                double t = 0.0, id = 0.0, r = 0.0, b = 0.0;
                ss >> t >> id >> r >> b;
                std::ostringstream os;
                os << std::setprecision(17) << "Z " << t << " -1 " << r << ' ' << b;
                l = os.str();
            }
            lines.push_back(l);
        }
        std::ofstream out(dir / "robot1.log");
        for (const auto &l : lines) {
            out << l << '\n';
        }
    }
    const Dataset ds = load_dataset(dir.string());
    ReplayOptions opt;
    opt.known_ids = true;
    try {
        (void)run_replay(ds, synth_config(), opt);
        FAIL() << "--known-ids accepted a log without identities";
    } catch (const ReplayError &e) {
        EXPECT_NE(std::string(e.what()).find("carry no identity"), std::string::npos) << e.what();
    }
    // without --known-ids the same data replays
    EXPECT_NO_THROW((void)run_replay(ds, synth_config(), ReplayOptions{}));
    fs::remove_all(dir);
}

TEST(ReplaySynthetic, MisreadRobotMarkerIsRefusedByTheRangeCheck)
{
    const fs::path dir = temp_dir("synth_range");
    write_synth2(dir, 11);
    // robot 1's first sighting of robot 2 reads 2 m too far
    edit_record(dir / "robot1.log", 'R', 0, [](std::vector<double> &f) { f[2] += 2.0; });
    const Dataset ds = load_dataset(dir.string());
    ReplayConfig cfg = synth_config();
    cfg.filter.type = FilterKind::Ekf;
    const ReplayResult res = run_replay(ds, cfg, ReplayOptions{});
    // each robot pairs the misread sighting with the other's: refused by both
    // receivers (merge_prepare's range check), nothing merged from it
    EXPECT_EQ(res.meetings_refused_range, 2);
    // the next mutual sightings still give the meeting, with a good transform
    int ok = 0;
    for (const auto &e : res.merges) {
        if (e.status == COSLAM_E_MERGE_RANGE) {
            EXPECT_EQ(e.after.n_estimated, e.before.n_estimated);
            continue;
        }
        EXPECT_EQ(e.status, COSLAM_OK);
        // a good transform: its error within what its covariance says (NEES
        // below the 99 % point of chi-square with 3 dof). The error itself
        // depends on which sightings pair up: 0.06 / 0.09 m when the robots
        // resent every frame, 0.229 m / 5.9 deg (NEES 6.7) / 0.023 m since
        // the resend period holds (a later pair of sightings)
        std::printf("merge t %.2f robot %d <- %d: transform error %.3f m %.2f deg, NEES %.2f\n", e.t_s, e.receiver,
                    e.sender, e.t_err_m, e.t_err_rad * 180.0 / M_PI, e.t_nees);
        EXPECT_LT(e.t_nees, 11.34);
        EXPECT_LT(e.t_err_m, 0.3);
        ok++;
    }
    EXPECT_EQ(ok, 2);
    fs::remove_all(dir);
}

TEST(ReplaySynthetic, KnownIdsGateDropsAMisreadAndOnlyIt)
{
    const fs::path dir = temp_dir("synth_known");
    write_synth2(dir, 11);
    ReplayConfig cfg = synth_config();
    cfg.filter.type = FilterKind::Ekf;
    ReplayOptions opt;
    opt.known_ids = true;
    opt.robots = {1};
    const ReplayResult clean = run_replay(load_dataset(dir.string()), cfg, opt);
    EXPECT_EQ(clean.robots[0].sightings_known_id_dropped, 0);
    // a late sighting of a mapped landmark gets a bearing 2 rad off: a
    // misread barcode, as in MRCLAM
    edit_record(dir / "robot1.log", 'Z', -1, [](std::vector<double> &f) { f[3] = angle_wrap(f[3] + 2.0); });
    const ReplayResult res = run_replay(load_dataset(dir.string()), cfg, opt);
    EXPECT_EQ(res.robots[0].sightings_known_id_dropped, 1);
    EXPECT_EQ(res.robots[0].sightings_used, clean.robots[0].sightings_used - 1);
    EXPECT_EQ(res.robots[0].final_map->n_landmarks, clean.robots[0].final_map->n_landmarks);
    // with the gate off the misread reaches the filter
    cfg.input.known_id_gate_rad = 0.0;
    const ReplayResult open = run_replay(load_dataset(dir.string()), cfg, opt);
    EXPECT_EQ(open.robots[0].sightings_known_id_dropped, 0);
    EXPECT_EQ(open.robots[0].sightings_used, clean.robots[0].sightings_used);
    fs::remove_all(dir);
}

class Mrclam120 : public ::testing::TestWithParam<FilterKind> {};

TEST_P(Mrclam120, TwoRobotsFirst120sBoundedErrorsAndAMerge)
{
    const std::string dir = data_dir();
    if (!fs::is_directory(dir)) {
        GTEST_SKIP() << "MRCLAM Dataset 6 not found at " << dir
                     << " (set COSLAM_DATA_DIR to the folder holding mrclam/MRCLAM_Dataset6)";
    }
    static const Dataset ds = load_mrclam(dir);
    ReplayConfig cfg = replay_config_default();
    replay_config_load(cfg, std::string(COSLAM_SOURCE_DIR) + "/host/replay/mrclam6.ini");
    cfg.filter.type = GetParam();
    cfg.filter.particles = 100;
    const bool ekf = GetParam() == FilterKind::Ekf;
    ReplayOptions opt;
    opt.robots = {1, 3};
    opt.duration_s = 120.0;
    const ReplayResult res = run_replay(ds, cfg, opt);
    ASSERT_EQ(res.robots.size(), 2u);
    for (const auto &r : res.robots) {
        SCOPED_TRACE("robot " + std::to_string(r.id) + " " + filter_kind_name(r.filter));
        EXPECT_GT(r.pose_samples, 1100); // 10 Hz over 120 s, truth all along
        // Bounds: EKF-SLAM is deterministic and measured 0.31 / 0.11 m pose,
        // 0.55 / 0.20 m landmark RMSE, no spurious landmark. Fast-SLAM 2.0
        // with 100 particles measured, over seeds 1-5, at most 0.53 m pose,
        // 0.81 m landmark RMSE and 3 spurious landmarks (robot 1, which sees
        // the south-west clusters only from 4-6 m). Dead reckoning alone
        // drifts 0.2 m per 30 s (docs/replay.md).
        EXPECT_LT(r.pose_rmse_m, ekf ? 0.45 : 0.7);
        EXPECT_LT(r.heading_rmse_rad, ekf ? 0.2 : 0.3);
        EXPECT_TRUE(r.final_score.valid);
        // 4: with Fast-SLAM, robot 1 sights robot 3 once at the second
        // meeting (48 s) and the meeting protocol gets no message of robot 3
        // paired with it (docs/replay.md "Merge protocol"); EKF-SLAM's gets 5+
        EXPECT_GE(r.final_score.n_matched, ekf ? 5 : 4);
        EXPECT_LT(r.final_score.rmse_m, ekf ? 0.75 : 1.0);
        // EKF-SLAM: 1 until its association held back ambiguous loop
        // closures (docs/consistency.md); since then 2 on one robot here,
        // while on the held-out Dataset 1 the five robots' spurious
        // landmarks fell from 17 to 5.
        EXPECT_LE(r.final_score.n_spurious, ekf ? 2 : 4);
    }
    int ok = 0;
    for (const auto &e : res.merges) {
        if (e.status != COSLAM_OK) {
            continue;
        }
        ok++;
        ASSERT_TRUE(e.has_truth);
        // The transform comes from the two robot sightings alone, with the
        // camera model of the config at their ~3 m: range sd 0.24 m each,
        // 0.17 m fused; lateral 3 m x 0.04 rad = 0.12 m; heading from two
        // bearings sqrt(2) x 0.04 = 0.057 rad. 0.4 m is about 2 sigma of the
        // position error, 0.15 rad 2.5 sigma of the heading; measured
        // 0.08-0.17 m and 0.1-1.8 deg over the four merges.
        EXPECT_LT(e.t_err_m, 0.4);
        EXPECT_LT(e.t_err_rad, 0.15);
        EXPECT_LT(e.t_nees, 11.3); // chi-square 3 dof, 99 %
        EXPECT_LT(e.after.rmse_m, 1.0);
    }
    EXPECT_GE(ok, 2) << "robots 1 and 3 meet at 17 s and 48 s";
}

INSTANTIATE_TEST_SUITE_P(Filters, Mrclam120, ::testing::Values(FilterKind::Ekf, FilterKind::FastSlam2),
                         [](const ::testing::TestParamInfo<FilterKind> &i) {
                             return std::string(i.param == FilterKind::Ekf ? "Ekf" : "FastSlam2");
                         });

// The sighting noise measured against the Vicon truth of Dataset 6
// (coslam-replay fit-noise): the camera's bearing sd is a fraction of a
// degree to a few degrees, the range model's coefficients are valid
// variances, and the gross outliers (misread barcodes) are a small minority.
TEST(MrclamNoise, FitNoiseDataset6GivesPlausibleSensorModel)
{
    const std::string dir = data_dir();
    if (!fs::is_directory(dir)) {
        GTEST_SKIP() << "MRCLAM Dataset 6 not found at " << dir
                     << " (set COSLAM_DATA_DIR to the folder holding mrclam/MRCLAM_Dataset6)";
    }
    const Dataset ds = load_mrclam(dir);
    const NoiseFit fit = fit_noise(ds);
    ASSERT_EQ(fit.robots.size(), ds.robots.size());
    const NoiseStats &o = fit.overall;
    EXPECT_GT(o.used, 1000);
    const double bearing_sd = std::sqrt(o.bearing_var_rad2);
    EXPECT_GT(bearing_sd, 0.005);
    EXPECT_LT(bearing_sd, 0.2);
    EXPECT_TRUE(std::isfinite(o.range_var_m2));
    EXPECT_TRUE(std::isfinite(o.range_var_per_m2));
    EXPECT_GE(o.range_var_m2, 0.0);
    EXPECT_GE(o.range_var_per_m2, 0.0);
    EXPECT_LT(o.rejected_fraction(), 0.2);
    for (const NoiseStats &s : fit.robots) {
        ASSERT_TRUE(s.has_truth) << "robot " << s.robot;
        EXPECT_LT(s.rejected_fraction(), 0.2) << "robot " << s.robot;
        EXPECT_GT(std::sqrt(s.bearing_var_rad2), 0.005) << "robot " << s.robot;
        EXPECT_LT(std::sqrt(s.bearing_var_rad2), 0.2) << "robot " << s.robot;
    }
    // the written fragment is a valid replay configuration
    std::ostringstream ini;
    write_noise_ini(fit, ds, ini);
    ReplayConfig cfg = replay_config_default();
    replay_config_load_string(cfg, ini.str(), "fit-noise.ini");
    EXPECT_NO_THROW(replay_config_validate(cfg));
    EXPECT_NEAR(cfg.slam.noise.range_var_per_m2, o.range_var_per_m2, 1e-5 * o.range_var_per_m2);
    EXPECT_NEAR(cfg.slam.noise.bearing_var_rad2, o.bearing_var_rad2, 1e-5 * o.bearing_var_rad2);

    // the residual correlation along tracks: tau, factor >= 1, the inflated model is factor times the fit
    EXPECT_GT(fit.tracks, 0);
    ASSERT_EQ(fit.range_corr.rho.size(), 20u);
    ASSERT_EQ(fit.bearing_corr.rho.size(), 20u);
    EXPECT_GT(fit.range_corr.pairs[0], 100);
    for (const NoiseCorrelation *c : {&fit.range_corr, &fit.bearing_corr}) {
        EXPECT_TRUE(std::isfinite(c->tau));
        EXPECT_GE(c->tau, 1.0);
        EXPECT_GE(c->factor, 1.0);
        // a track offset cannot inflate by more than the track length
        EXPECT_LE(c->factor, static_cast<double>(fit.samples) / static_cast<double>(fit.tracks) + 1e-9);
        EXPECT_GE(c->lags_summed, 0);
        EXPECT_LE(c->lags_summed, 20);
    }
    const double tr = fit.range_corr.factor, tb = fit.bearing_corr.factor;
    EXPECT_DOUBLE_EQ(fit.range_var_m2_eff, tr * o.range_var_m2);
    EXPECT_DOUBLE_EQ(fit.range_var_per_m2_eff, tr * o.range_var_per_m2);
    EXPECT_DOUBLE_EQ(fit.bearing_var_rad2_eff, tb * o.bearing_var_rad2);
    std::ostringstream ini_eff;
    write_noise_ini(fit, ds, ini_eff, true);
    ReplayConfig cfg_eff = replay_config_default();
    replay_config_load_string(cfg_eff, ini_eff.str(), "fit-noise-inflated.ini");
    EXPECT_NO_THROW(replay_config_validate(cfg_eff));
    EXPECT_NEAR(cfg_eff.slam.noise.range_var_per_m2, fit.range_var_per_m2_eff, 1e-5 * fit.range_var_per_m2_eff);
    EXPECT_NEAR(cfg_eff.slam.noise.bearing_var_rad2, fit.bearing_var_rad2_eff, 1e-5 * fit.bearing_var_rad2_eff);
    EXPECT_NEAR(cfg_eff.slam.noise.range_var_m2, std::max(fit.range_var_m2_eff, 1e-6), 1e-5);
}

// The autocorrelation estimate on a synthetic track: a constant error shared
// by a whole track (fully correlated) gives rho ~1 at every lag and tau
// 1 + 2 K; alternating errors give rho_1 < 0 and tau 1.
TEST(MrclamNoise, ResidualCorrelationTau)
{
    Dataset ds;
    ds.source = "synthetic";
    ds.landmarks.push_back({6, {0.0, 0.0}});
    ds.landmarks.push_back({7, {0.0, 0.0}});
    RobotLog r;
    r.id = 1;
    for (int i = 0; i <= 1000; ++i) {
        r.truth.push_back({0.1 * i, {-2.0, 0.0, 0.0}});
    }
    // landmark 6: tracks of 30 sightings 0.1 s apart, separated by 5 s, each
    // with its own constant range error; landmark 7 alternates (bearing too).
    for (int tr = 0; tr < 3; ++tr) {
        const double e = (tr % 2 == 0 ? 0.05 : -0.05) * (1 + tr);
        for (int i = 0; i < 30; ++i) {
            r.z.push_back({tr * 8.0 + 0.1 * i, 6, 2.0 + e, 0.0});
        }
    }
    for (int i = 0; i < 60; ++i) {
        const double s = i % 2 == 0 ? 1.0 : -1.0;
        r.z.push_back({30.0 + 0.1 * i, 7, 2.0 + 0.05 * s, 0.01 * s});
    }
    std::stable_sort(r.z.begin(), r.z.end(), [](const auto &a, const auto &b) { return a.t_s < b.t_s; });
    ds.robots.push_back(r);
    NoiseFitOptions opt;
    opt.reject_sd = 1e9;
    const NoiseFit fit = fit_noise(ds, opt);
    EXPECT_EQ(fit.tracks, 4);
    EXPECT_EQ(fit.samples, 150);
    // bearing: only landmark 7 has an error, alternating -> rho_1 < 0, tau 1
    EXPECT_LT(fit.bearing_corr.rho[0], 0.0);
    EXPECT_EQ(fit.bearing_corr.lags_summed, 0);
    EXPECT_DOUBLE_EQ(fit.bearing_corr.tau, 1.0);
    EXPECT_DOUBLE_EQ(fit.bearing_corr.factor, 1.0); /* rho_1 < 0: no offset to inflate for */
    EXPECT_GE(fit.range_corr.tau, 1.0);
    EXPECT_GT(fit.range_corr.factor, 1.0);
    EXPECT_DOUBLE_EQ(fit.bearing_var_rad2_eff, fit.bearing_corr.factor * fit.overall.bearing_var_rad2);
}

// Without robot ground truth (Dataset 1) there is nothing to measure against:
// a clear error, not a fit of nothing.
TEST(MrclamNoise, FitNoiseWithoutRobotTruthThrows)
{
    Dataset ds;
    ds.source = "no-truth";
    ds.landmarks.push_back({6, {1.0, 2.0}});
    RobotLog r;
    r.id = 1;
    r.z.push_back({0.0, 6, 2.0, 0.1});
    ds.robots.push_back(r);
    EXPECT_THROW(fit_noise(ds), ReplayError);
    ds.robots[0].truth.push_back({0.0, {0.0, 0.0, 0.0}});
    ds.landmarks.clear();
    EXPECT_THROW(fit_noise(ds), ReplayError);
}

namespace {

// A robot standing still at the origin facing +x, truth every 0.1 s, and
// landmarks at (range, bearing) from it: the replay's view (MRCLAM: range
// 1.11..5.4 m, |bearing| <= 0.36 rad) holds the first `n_in` of them.
struct ViewWorld {
    Dataset ds;
    slam_params_t params = replay_config_default().slam;
    std::vector<int> in_view_ids;
    std::vector<int> out_of_view_ids;
};

ViewWorld view_world(int frames)
{
    ViewWorld w;
    w.ds.source = "synthetic-view";
    RobotLog r;
    r.id = 1;
    for (int i = 0; i <= frames; ++i) {
        r.truth.push_back({0.1 * i, {0.0, 0.0, 0.0}});
    }
    w.ds.robots.push_back(r);
    // in view: 2, 3 and 4 m, inside the field of view
    const double in_view[3][2] = {{2.0, 0.0}, {3.0, 0.2}, {4.0, -0.3}};
    // out of view: beyond sensor_max_range_m x margin (5.4 m), outside the
    // field of view (|bearing| > 0.36 rad), nearer than min / margin (1.11 m)
    const double out_view[3][2] = {{8.0, 0.0}, {3.0, 1.0}, {0.5, 0.0}};
    int id = 6;
    for (const auto &rb : in_view) {
        w.ds.landmarks.push_back({id, {rb[0] * std::cos(rb[1]), rb[0] * std::sin(rb[1])}});
        w.in_view_ids.push_back(id++);
    }
    for (const auto &rb : out_view) {
        w.ds.landmarks.push_back({id, {rb[0] * std::cos(rb[1]), rb[0] * std::sin(rb[1])}});
        w.out_of_view_ids.push_back(id++);
    }
    // the world is what the test says it is
    for (const auto &lm : w.ds.landmarks) {
        const sighting_t z = observe_predict({0.0, 0.0, 0.0}, lm.pos);
        const bool in = std::find(w.in_view_ids.begin(), w.in_view_ids.end(), lm.id) != w.in_view_ids.end();
        EXPECT_EQ(landmark_should_be_seen(&w.params, z) != 0, in) << "landmark " << lm.id;
    }
    return w;
}

void add_sighting(RobotLog &r, double t, const LandmarkTruth &lm)
{
    const sighting_t z = observe_predict({0.0, 0.0, 0.0}, lm.pos);
    r.z.push_back({t, lm.id, z.range_m, z.bearing_rad});
}

} // namespace

// Every in-view landmark detected with probability 0.5 in each of 3000
// frames; every frame is logged (each holds a sighting of another robot, as
// if the camera logged empty frames too), so p_d over them is the rate
// itself: within 4 binomial sd of 0.5. The out-of-view landmarks are never
// detected: counted in view, they would pull p_d to 1/4.
TEST(MrclamNoise, DetectionRateOverViewMatchesKnownRate)
{
    const int frames = 3000;
    ViewWorld w = view_world(frames);
    RobotLog &r = w.ds.robots[0];
    std::mt19937_64 rng(20261207);
    std::bernoulli_distribution coin(0.5);
    for (int i = 0; i < frames; ++i) {
        const double t = 0.1 * i + 0.05;
        for (const LandmarkTruth &lm : w.ds.landmarks) {
            if (std::find(w.in_view_ids.begin(), w.in_view_ids.end(), lm.id) != w.in_view_ids.end() && coin(rng)) {
                add_sighting(r, t, lm);
            }
        }
        r.rz.push_back({t, 2, 3.0, 0.1});
    }
    const DetectionFit fit = fit_detection(w.ds, w.params);
    ASSERT_EQ(fit.robots.size(), 1u);
    const DetectionStats &o = fit.overall;
    EXPECT_EQ(o.frames, frames);
    EXPECT_EQ(o.used, frames);
    EXPECT_EQ(o.other, frames);
    EXPECT_EQ(o.in_view, 3L * frames);
    EXPECT_EQ(o.out_of_view, 0);
    const double sd = std::sqrt(0.25 / static_cast<double>(o.in_view));
    EXPECT_NEAR(o.p_d(), 0.5, 4.0 * sd);
    // nothing truncated (every frame has another sighting): the same estimate
    EXPECT_NEAR(o.p_d_truncated, o.p_d(), 1e-6);
    EXPECT_DOUBLE_EQ(fit.exist_miss_confirmed, slam_exist_miss_for_detection(o.p_d()));
    EXPECT_GT(fit.exist_miss_confirmed, 0.0);
    // the range table: one landmark per 1 m bin at 2, 3 and 4 m
    ASSERT_EQ(o.bins.size(), 5u);
    for (size_t b = 0; b < 2; ++b) {
        EXPECT_EQ(o.bins[b].in_view, 0) << b;
    }
    long detected = 0;
    for (size_t b = 2; b < 5; ++b) {
        EXPECT_DOUBLE_EQ(o.bins[b].r_lo_m, static_cast<double>(b));
        EXPECT_EQ(o.bins[b].in_view, frames) << b;
        EXPECT_NEAR(static_cast<double>(o.bins[b].detected) / frames, 0.5, 4.0 * std::sqrt(0.25 / frames)) << b;
        detected += o.bins[b].detected;
    }
    EXPECT_EQ(detected, o.detected);

    // the INI fit-noise writes carries exist_miss_confirmed, and run -c takes it
    const NoiseFit nf = fit_noise(w.ds);
    std::ostringstream ini;
    write_noise_ini(nf, w.ds, ini, false, &fit);
    EXPECT_NE(ini.str().find("exist_miss_confirmed = "), std::string::npos) << ini.str();
    ReplayConfig cfg = replay_config_default();
    replay_config_load_string(cfg, ini.str(), "fit-noise.ini");
    EXPECT_NO_THROW(replay_config_validate(cfg));
    EXPECT_NEAR(cfg.slam.exist_miss_confirmed, fit.exist_miss_confirmed, 1e-5);
}

// As MRCLAM logs: a frame with no detection is not in the log. Three
// landmarks in view at p = 0.5, nothing else seen: the frames logged are
// those with k >= 1, and detected / in view is biased up (E[k | k >= 1] / 3
// = 4/7 = 0.571); the zero-truncated estimate recovers 0.5 within 4 sd (its
// Fisher information at n = 3, p = 1/2 is 7.84 per logged frame, against 12
// for a binomial).
TEST(MrclamNoise, DetectionRateTruncatedToLoggedFrames)
{
    const int frames = 4000;
    ViewWorld w = view_world(frames);
    RobotLog &r = w.ds.robots[0];
    std::mt19937_64 rng(7);
    std::bernoulli_distribution coin(0.5);
    long logged = 0;
    for (int i = 0; i < frames; ++i) {
        const double t = 0.1 * i + 0.05;
        bool any = false;
        for (int id : w.in_view_ids) {
            if (coin(rng)) {
                add_sighting(r, t, *w.ds.landmark(id));
                any = true;
            }
        }
        logged += any ? 1 : 0;
    }
    const DetectionFit fit = fit_detection(w.ds, w.params);
    const DetectionStats &o = fit.overall;
    EXPECT_EQ(o.frames, logged);
    EXPECT_EQ(o.other, 0);
    EXPECT_EQ(o.in_view, 3L * logged);
    EXPECT_NEAR(o.p_d(), 4.0 / 7.0, 4.0 * std::sqrt(0.25 / static_cast<double>(o.in_view)));
    EXPECT_GT(o.p_d(), 0.53);
    EXPECT_NEAR(o.p_d_truncated, 0.5, 4.0 / std::sqrt(7.84 * static_cast<double>(logged)));
    EXPECT_DOUBLE_EQ(fit.exist_miss_confirmed_truncated, slam_exist_miss_for_detection(o.p_d_truncated));
}

// Landmarks the view model calls out of view (beyond the range, outside the
// field of view, too near) are not landmark-frames in view even when they
// are detected in every frame: they are counted apart (out_of_view). The one
// landmark in view is detected in every other frame: p_d is 1/2 exactly
// (with the three others counted in view it would be 7/8).
TEST(MrclamNoise, DetectionRateLeavesOutLandmarksOutsideTheView)
{
    const int frames = 200;
    ViewWorld w = view_world(frames);
    RobotLog &r = w.ds.robots[0];
    for (int i = 0; i < frames; ++i) {
        const double t = 0.1 * i + 0.05;
        if (i % 2 == 0) {
            add_sighting(r, t, *w.ds.landmark(w.in_view_ids[0]));
        }
        for (int id : w.out_of_view_ids) {
            add_sighting(r, t, *w.ds.landmark(id));
        }
    }
    // only the first landmark stays in view
    w.ds.landmarks.erase(std::remove_if(w.ds.landmarks.begin(), w.ds.landmarks.end(),
                                        [&](const LandmarkTruth &lm) {
                                            return lm.id == w.in_view_ids[1] || lm.id == w.in_view_ids[2];
                                        }),
                         w.ds.landmarks.end());
    const DetectionFit fit = fit_detection(w.ds, w.params);
    const DetectionStats &o = fit.overall;
    EXPECT_EQ(o.frames, frames);
    EXPECT_EQ(o.in_view, frames);
    EXPECT_EQ(o.detected, frames / 2);
    EXPECT_EQ(o.out_of_view, 3L * frames);
    EXPECT_EQ(o.other, frames); // an out-of-view detection would have the frame logged anyway
    EXPECT_DOUBLE_EQ(o.p_d(), 0.5);
    EXPECT_DOUBLE_EQ(fit.exist_miss_confirmed, slam_exist_miss_for_detection(0.5));

    // robot without truth: n/a, not zeros; no truth anywhere: an error
    RobotLog r2;
    r2.id = 2;
    r2.z.push_back({0.0, w.in_view_ids[0], 2.0, 0.0});
    w.ds.robots.push_back(r2);
    const DetectionFit fit2 = fit_detection(w.ds, w.params);
    ASSERT_EQ(fit2.robots.size(), 2u);
    EXPECT_FALSE(fit2.robots[1].has_truth);
    EXPECT_EQ(fit2.robots[1].frames, 1);
    EXPECT_EQ(fit2.robots[1].in_view, 0);
    EXPECT_EQ(fit2.overall.frames, frames);
    w.ds.robots.erase(w.ds.robots.begin());
    EXPECT_THROW(fit_detection(w.ds, w.params), ReplayError);
}
