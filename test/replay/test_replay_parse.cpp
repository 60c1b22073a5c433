// test/replay/test_replay_parse.cpp - the replay's readers (landmark log,
// truth files, MRCLAM folders) on small hand-written files, every malformed
// case included; the INI configuration; the odometry model and its fit.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "replay_config.h"
#include "replay_data.h"
#include "replay_filter.h"
#include "replay_odometry.h"
#include "replay_truth.h"

using namespace coslam::replay;
namespace fs = std::filesystem;

namespace {

// A fresh temporary folder per test, removed afterwards.
class TempDir {
public:
    TempDir()
    {
        const auto *info = ::testing::UnitTest::GetInstance()->current_test_info();
        path_ = fs::temp_directory_path() /
                ("coslam_replay_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" +
                 std::to_string(::getpid()));
        fs::remove_all(path_);
        fs::create_directories(path_);
    }
    ~TempDir() { fs::remove_all(path_); }
    std::string file(const std::string &name, const std::string &text) const
    {
        std::ofstream(path_ / name) << text;
        return (path_ / name).string();
    }
    std::string str() const { return path_.string(); }
    fs::path path() const { return path_; }

private:
    fs::path path_;
};

// Parses `text` as robot 1's landmark log; returns the error message or "".
std::string log_error(const std::string &text)
{
    std::istringstream in(text);
    RobotLog r;
    r.id = 1;
    ParseReport rep;
    try {
        parse_landmark_log(in, "r1.log", r, rep);
    } catch (const ReplayError &e) {
        return e.what();
    }
    return "";
}

bool has(const std::string &s, const std::string &part)
{
    return s.find(part) != std::string::npos;
}

// A minimal valid MRCLAM folder: robots 1 and 2, landmarks 6 and 7.
void write_mrclam(const TempDir &d)
{
    const std::string hdr = "# UTIAS\r\n# x\r\n# y\r\n# z\r\n";
    d.file("Barcodes.dat", hdr + "  1 \t 5 \r\n  2 \t 14 \r\n  6 \t 63 \r\n  7 \t 81 \r\n");
    d.file("Landmark_Groundtruth.dat", hdr + " 6 1.0 2.0 0.0001 0.0002\r\n 7 3.0 -1.0 0.0001 0.0002\r\n");
    d.file("Robot1_Odometry.dat", hdr + "1000.00 0.1 0.0\r\n1000.50 0.1 0.2\r\n1001.00 0.0 0.0\r\n");
    d.file("Robot1_Measurement.dat",
           hdr + "1000.20 63 2.0 0.1\r\n1000.20 14 3.0 -0.2\r\n1000.70 99 1.5 0.0\r\n1000.90 5 1.0 0.0\r\n");
    d.file("Robot1_Groundtruth.dat", hdr + "999.50 0 0 0\r\n1000.00 0 0 0\r\n1001.00 0.1 0 0.1\r\n");
    d.file("Robot2_Odometry.dat", hdr + "1000.10 0.0 0.0\r\n");
    d.file("Robot2_Measurement.dat", hdr + "1000.30 5 3.1 0.2\r\n1000.30 81 2.5 0.0\r\n");
    d.file("Robot2_Groundtruth.dat", hdr + "1000.00 3 0 3.14159\r\n1001.00 3 0 3.14159\r\n");
}

} // namespace

TEST(LandmarkLog, ParsesEveryRecordTypeCommentsAndCrlf)
{
    const std::string text = "# a comment line\r\n"
                             "\r\n"
                             "V 0.0 0.2 -0.1   # trailing comment\r\n"
                             "O 0.5 0.01 0.002 0.003\n"
                             "Z 0.5 -1 2.5 0.3\n"
                             "Z 0.5 12 3.5 -0.4\n"
                             "R 0.6 2 1.75 0.05\n"
                             "   \t  \n";
    std::istringstream in(text);
    RobotLog r;
    r.id = 1;
    ParseReport rep;
    parse_landmark_log(in, "r1.log", r, rep);
    ASSERT_EQ(r.odo.size(), 2u);
    EXPECT_EQ(r.odo[0].kind, OdoRecord::Kind::Velocity);
    EXPECT_DOUBLE_EQ(r.odo[0].a, 0.2);
    EXPECT_DOUBLE_EQ(r.odo[0].b, -0.1);
    EXPECT_EQ(r.odo[1].kind, OdoRecord::Kind::Increment);
    EXPECT_DOUBLE_EQ(r.odo[1].c, 0.003);
    ASSERT_EQ(r.z.size(), 2u);
    EXPECT_EQ(r.z[0].landmark_id, -1);
    EXPECT_EQ(r.z[1].landmark_id, 12);
    EXPECT_DOUBLE_EQ(r.z[1].bearing_rad, -0.4);
    ASSERT_EQ(r.rz.size(), 1u);
    EXPECT_EQ(r.rz[0].other_robot, 2);
    EXPECT_DOUBLE_EQ(r.rz[0].range_m, 1.75);
    EXPECT_EQ(rep.lines_read, 5);
}

TEST(LandmarkLog, EveryMalformedLineNamesFileAndLine)
{
    // unknown record type
    EXPECT_TRUE(has(log_error("V 0 0 0\nX 1 2 3\n"), "r1.log:2: unknown record type 'X'"));
    // field counts of every record type
    EXPECT_TRUE(has(log_error("O 1 2 3\n"), "r1.log:1: expected O t dx dy dtheta"));
    EXPECT_TRUE(has(log_error("O 1 2 3 4 5\n"), "r1.log:1: expected O t dx dy dtheta"));
    EXPECT_TRUE(has(log_error("V 1 2\n"), "r1.log:1: expected V t v w"));
    EXPECT_TRUE(has(log_error("Z 1 2 3\n"), "r1.log:1: expected Z t id range bearing"));
    EXPECT_TRUE(has(log_error("R 1 2 3 4 5\n"), "r1.log:1: expected R t other_robot_id range bearing"));
    // not a number, not finite
    EXPECT_TRUE(has(log_error("# c\nV 1 abc 0\n"), "r1.log:2: field 3 (v) is not a number: 'abc'"));
    EXPECT_TRUE(has(log_error("V 1 0.1x 0\n"), "is not a number: '0.1x'"));
    EXPECT_TRUE(has(log_error("V 1 nan 0\n"), "r1.log:1: field 3 (v) is not finite"));
    EXPECT_TRUE(has(log_error("Z 1 3 inf 0\n"), "r1.log:1: field 4 (range) is not finite"));
    // an overflow is not finite; an underflow (subnormal) is a number
    EXPECT_TRUE(has(log_error("V 1e999 0 0\n"), "r1.log:1: field 2 (t) is not finite: '1e999'"));
    EXPECT_EQ(log_error("Z 1 3 1e-310 0\n"), "");
    // bounded stamps, bearings; short numbers and no raw bytes in messages
    EXPECT_TRUE(has(log_error("V -0.5 0 0\n"), "r1.log:1: time stamp -0.5 s outside [0, 1e+06]"));
    EXPECT_TRUE(has(log_error("V 1e7 0 0\n"), "r1.log:1: time stamp 1e+07 s outside [0, 1e+06]"));
    EXPECT_TRUE(has(log_error("Z 1 3 1 7\n"), "r1.log:1: bearing 7 rad outside [-2 pi, 2 pi]"));
    EXPECT_TRUE(has(log_error("Z 1 3 -1.7976931348623157e308 0\n"), "range must be positive, got -1.79769e+308"));
    EXPECT_TRUE(has(log_error("V 1 \x01\x7f 0\n"), "is not a number: '\\x01\\x7f'"));
    EXPECT_TRUE(has(log_error("V 1 0 0\n" + std::string(5000, 'x') + "\n"), "r1.log:2: line longer than 4096 bytes"));
    // ranges and ids
    EXPECT_TRUE(has(log_error("Z 1 3 0 0.1\n"), "r1.log:1: range must be positive"));
    EXPECT_TRUE(has(log_error("R 1 2 -1 0.1\n"), "r1.log:1: range must be positive"));
    EXPECT_TRUE(has(log_error("Z 1 2.5 1 0.1\n"), "r1.log:1: field 3 (id) is not an integer"));
    EXPECT_TRUE(has(log_error("Z 1 -2 1 0.1\n"), "r1.log:1: landmark id must be -1"));
    // time must not go backwards (equal is fine: one frame)
    EXPECT_EQ(log_error("Z 1 3 1 0\nZ 1 4 1 0\n"), "");
    EXPECT_TRUE(has(log_error("V 2 0 0\nZ 2 3 1 0\nO 1.5 0 0 0\n"), "r1.log:3: time goes backwards: 1.5 after 2"));
}

TEST(LandmarkLog, SelfSightingIsCountedAndSkipped)
{
    std::istringstream in("R 1 1 2.0 0.0\nR 1 2 2.0 0.0\n");
    RobotLog r;
    r.id = 1;
    ParseReport rep;
    parse_landmark_log(in, "r1.log", r, rep);
    EXPECT_EQ(rep.self_sightings, 1);
    ASSERT_EQ(r.rz.size(), 1u);
    EXPECT_EQ(r.rz[0].other_robot, 2);
}

TEST(TruthFiles, PathAndLandmarks)
{
    std::istringstream p("# t x y th\n0 1 2 0.5\n1 1.5 2 7.0\n");
    const auto path = parse_truth_path(p, "p.txt");
    ASSERT_EQ(path.size(), 2u);
    EXPECT_NEAR(path[1].pose.theta, 7.0 - 2.0 * M_PI, 1e-12); // wrapped
    std::istringstream bad("0 1 2\n");
    EXPECT_THROW(parse_truth_path(bad, "p.txt"), ReplayError);
    std::istringstream back("1 0 0 0\n0.5 0 0 0\n");
    try {
        parse_truth_path(back, "p.txt");
        FAIL();
    } catch (const ReplayError &e) {
        EXPECT_TRUE(has(e.what(), "p.txt:2: time goes backwards"));
        EXPECT_EQ(e.line(), 2);
    }
    std::istringstream l("6 1.0 2.0 0.1 0.1\n7 3 4\n");
    const auto lm = parse_truth_landmarks(l, "l.txt");
    ASSERT_EQ(lm.size(), 2u);
    EXPECT_EQ(lm[0].id, 6);
    EXPECT_DOUBLE_EQ(lm[1].pos.y, 4.0);
    std::istringstream dup("6 1 2\n6 1 2\n");
    try {
        parse_truth_landmarks(dup, "l.txt");
        FAIL();
    } catch (const ReplayError &e) {
        EXPECT_TRUE(has(e.what(), "l.txt:2: landmark 6 listed twice"));
    }
    std::istringstream few("6 1\n");
    EXPECT_THROW(parse_truth_landmarks(few, "l.txt"), ReplayError);
}

TEST(Mrclam, ReadsAFolderAndCountsUnknownBarcodes)
{
    TempDir d;
    write_mrclam(d);
    const Dataset ds = load_mrclam(d.str());
    EXPECT_EQ(ds.format, "mrclam");
    EXPECT_DOUBLE_EQ(ds.t0_s, 999.5); // the earliest stamp (robot 1's truth)
    ASSERT_EQ(ds.robots.size(), 2u);
    ASSERT_EQ(ds.landmarks.size(), 2u);
    const RobotLog &r1 = ds.robots[0];
    EXPECT_EQ(r1.id, 1);
    ASSERT_EQ(r1.odo.size(), 3u);
    EXPECT_NEAR(r1.odo[0].t_s, 0.5, 1e-9);
    EXPECT_NEAR(r1.odo[1].b, 0.2, 1e-12);
    // barcode 63 -> landmark 6; barcode 14 -> robot 2; 99 unknown; 5 = itself
    ASSERT_EQ(r1.z.size(), 1u);
    EXPECT_EQ(r1.z[0].landmark_id, 6);
    EXPECT_NEAR(r1.z[0].t_s, 0.7, 1e-9);
    ASSERT_EQ(r1.rz.size(), 1u);
    EXPECT_EQ(r1.rz[0].other_robot, 2);
    EXPECT_EQ(ds.report.unknown_barcode_rows, 1);
    EXPECT_EQ(ds.report.unknown_barcodes.at(99), 1);
    EXPECT_EQ(ds.report.self_sightings, 1);
    const RobotLog &r2 = ds.robots[1];
    ASSERT_EQ(r2.rz.size(), 1u);
    EXPECT_EQ(r2.rz[0].other_robot, 1);
    ASSERT_EQ(r2.z.size(), 1u);
    EXPECT_EQ(r2.z[0].landmark_id, 7);
    EXPECT_EQ(ds.robot(2), &ds.robots[1]);
    EXPECT_EQ(ds.robot(3), nullptr);
}

// A subject is a robot only if the folder has its odometry, a landmark only
// if the truth file lists it: one that is neither is skipped and named (not
// taken for a robot, as before), one that is both is refused.
TEST(Mrclam, SubjectNeitherRobotNorLandmarkIsSkippedAndNamed)
{
    {
        TempDir d;
        write_mrclam(d);
        // subject 8 (barcode 27): in Barcodes.dat, not in the truth, no robot files
        d.file("Barcodes.dat", "  1 \t 5 \r\n  2 \t 14 \r\n  6 \t 63 \r\n  7 \t 81 \r\n  8 \t 27 \r\n");
        d.file("Robot1_Measurement.dat", "1000.20 63 2.0 0.1\r\n1000.20 27 3.0 -0.2\r\n1000.40 27 3.0 -0.2\r\n");
        const Dataset ds = load_mrclam(d.str());
        EXPECT_EQ(ds.report.unknown_subject_rows, 2);
        EXPECT_EQ(ds.report.unknown_robot_sightings, 0);
        const RobotLog &r1 = ds.robots[0];
        EXPECT_EQ(r1.z.size(), 1u);
        EXPECT_TRUE(r1.rz.empty());
        bool named = false;
        for (const auto &n : ds.report.notes) {
            named = named || has(n, "subject 8 is neither in Landmark_Groundtruth.dat nor a robot");
        }
        EXPECT_TRUE(named);
    }
    {
        TempDir d;
        write_mrclam(d);
        d.file("Landmark_Groundtruth.dat", " 2 1.0 2.0\r\n 6 1.0 2.0\r\n 7 3.0 -1.0\r\n");
        try {
            (void)load_mrclam(d.str());
            FAIL();
        } catch (const ReplayError &e) {
            EXPECT_TRUE(has(e.what(), "subject 2 is listed as a landmark")) << e.what();
        }
    }
}

TEST(Mrclam, MissingFilesAreNamed)
{
    {
        TempDir d;
        write_mrclam(d);
        fs::remove(d.path() / "Barcodes.dat");
        try {
            load_mrclam(d.str());
            FAIL();
        } catch (const ReplayError &e) {
            EXPECT_TRUE(has(e.what(), "Barcodes.dat: missing file"));
        }
    }
    {
        TempDir d;
        write_mrclam(d);
        fs::remove(d.path() / "Robot2_Measurement.dat");
        try {
            load_mrclam(d.str());
            FAIL();
        } catch (const ReplayError &e) {
            EXPECT_TRUE(has(e.what(), "Robot2_Measurement.dat: missing file"));
        }
    }
    {
        TempDir d;
        write_mrclam(d);
        fs::remove(d.path() / "Landmark_Groundtruth.dat");
        EXPECT_THROW(load_mrclam(d.str()), ReplayError);
    }
    {
        // a missing ground truth is not an error: the robot is not evaluated
        TempDir d;
        write_mrclam(d);
        fs::remove(d.path() / "Robot2_Groundtruth.dat");
        const Dataset ds = load_mrclam(d.str());
        EXPECT_TRUE(ds.robots[1].truth.empty());
        ASSERT_EQ(ds.report.notes.size(), 1u);
        EXPECT_TRUE(has(ds.report.notes[0], "Robot2_Groundtruth.dat"));
    }
    EXPECT_THROW(load_mrclam("/nonexistent/folder"), ReplayError);
    TempDir empty;
    EXPECT_THROW(load_dataset(empty.str()), ReplayError);
}

TEST(Mrclam, MalformedLinesAndBackwardTime)
{
    const std::string hdr = "# a\n# b\n# c\n# d\n";
    struct Case {
        std::string file, text, expect;
    };
    const Case cases[] = {
        {"Robot1_Measurement.dat", hdr + "1000.2 63 2.0 0.1\n1000.3 63 2.0\n", "Robot1_Measurement.dat:6: expected t barcode range bearing"},
        {"Robot1_Measurement.dat", hdr + "1000.2 63 2.0 0.1\n1000.1 63 2.0 0.1\n", "Robot1_Measurement.dat:6: time goes backwards"},
        {"Robot1_Measurement.dat", hdr + "1000.2 6x3 2.0 0.1\n", "Robot1_Measurement.dat:5: field 2 (barcode) is not a number"},
        {"Robot1_Measurement.dat", hdr + "1000.2 63 -2.0 0.1\n", "Robot1_Measurement.dat:5: range must be positive"},
        {"Robot1_Odometry.dat", hdr + "1000.0 0.1\n", "Robot1_Odometry.dat:5: expected t v w"},
        {"Robot1_Odometry.dat", hdr + "1000.0 0.1 0\n999.0 0.1 0\n", "Robot1_Odometry.dat:6: time goes backwards"},
        {"Robot1_Groundtruth.dat", hdr + "1000.0 0 0 nan\n", "Robot1_Groundtruth.dat:5: field 4 (theta) is not finite"},
        {"Barcodes.dat", hdr + "1 5\n2 5\n", "Barcodes.dat:6: barcode 5 listed twice"},
        {"Barcodes.dat", hdr + "1 5 7\n", "Barcodes.dat:5: expected subject barcode"},
    };
    for (const auto &c : cases) {
        TempDir d;
        write_mrclam(d);
        d.file(c.file, c.text);
        try {
            load_mrclam(d.str());
            ADD_FAILURE() << "no error for " << c.file;
        } catch (const ReplayError &e) {
            EXPECT_TRUE(has(e.what(), c.expect)) << e.what() << "\n  expected: " << c.expect;
        }
    }
}

// A run of some robots (-r) reads only their files: a bad line in another
// robot's file stops nothing, the selected robot's records and t0 are those
// of a full read, the unread robot stays a robot (sightings of it are
// robot sightings), and a robot not in the folder is named.
TEST(Mrclam, OnlySelectedRobotsAreRead)
{
    TempDir d;
    write_mrclam(d);
    const Dataset full = load_mrclam(d.str());
    d.file("Robot1_Measurement.dat", "# a\n# b\n# c\n# d\n1000.2 63 2.0 0.1\n1000.3 63 2.0\n");
    EXPECT_THROW(load_mrclam(d.str()), ReplayError);
    const Dataset two = load_mrclam(d.str(), {2});
    EXPECT_DOUBLE_EQ(two.t0_s, full.t0_s); // robot 1's truth, first line only
    ASSERT_EQ(two.robots.size(), 1u);
    EXPECT_EQ(two.robots[0].id, 2);
    EXPECT_EQ(two.robots[0].odo.size(), full.robots[1].odo.size());
    EXPECT_DOUBLE_EQ(two.robots[0].odo[0].t_s, full.robots[1].odo[0].t_s);
    ASSERT_EQ(two.robots[0].rz.size(), 1u); // robot 1 is still a robot
    EXPECT_EQ(two.robots[0].rz[0].other_robot, 1);
    EXPECT_EQ(two.report.unknown_robot_sightings, 0);
    bool noted = false;
    for (const auto &n : two.report.notes) {
        noted = noted || has(n, "robot(s) 1 not selected");
    }
    EXPECT_TRUE(noted);
    // a first line without a stamp is noted and left out of t0
    d.file("Robot1_Groundtruth.dat", "# a\nnot-a-stamp 0 0 0\n");
    const Dataset late = load_mrclam(d.str(), {2});
    EXPECT_DOUBLE_EQ(late.t0_s, 1000.0); // robot 1's odometry
    bool named = false;
    for (const auto &n : late.report.notes) {
        named = named || has(n, "Robot1_Groundtruth.dat:2");
    }
    EXPECT_TRUE(named);
    try {
        load_mrclam(d.str(), {3});
        ADD_FAILURE() << "robot 3 is not in the folder";
    } catch (const ReplayError &e) {
        EXPECT_TRUE(has(e.what(), "no robot 3 in the folder (robots: 1, 2)")) << e.what();
    }
    // the landmark-log reader the same way
    const std::string out = (d.path() / "log").string();
    write_landmark_log(full, out);
    std::ofstream(d.path() / "log" / "robot1.log", std::ios::app) << "garbage line\n";
    EXPECT_THROW(load_landmark_log(out), ReplayError);
    const Dataset lg = load_landmark_log(out, {2});
    ASSERT_EQ(lg.robots.size(), 1u);
    EXPECT_EQ(lg.robots[0].rz.size(), 1u);
    EXPECT_EQ(lg.report.unknown_robot_sightings, 0);
    EXPECT_THROW(load_landmark_log(out, {4}), ReplayError);
}

// An unread robot's measurement rows that a full read skips (an unknown
// barcode, a sighting of itself) do not set t0 either.
TEST(Mrclam, UnreadRobotsSkippedRowsAreNotInT0)
{
    TempDir e;
    write_mrclam(e);
    e.file("Robot1_Measurement.dat", "# a\n# b\n# c\n# d\n998.0 99 2.0 0.1\n998.5 5 2.0 0.1\n1000.2 63 2.0 0.1\n");
    e.file("Robot1_Groundtruth.dat", "# a\n1000.0 0 0 0\n");
    const Dataset whole = load_mrclam(e.str());
    const Dataset part = load_mrclam(e.str(), {2});
    EXPECT_DOUBLE_EQ(whole.t0_s, 1000.0);
    EXPECT_DOUBLE_EQ(part.t0_s, whole.t0_s);
}

TEST(Mrclam, ConvertsToLandmarkLogExactly)
{
    TempDir d;
    write_mrclam(d);
    const Dataset a = load_mrclam(d.str());
    const std::string out = (d.path() / "log").string();
    write_landmark_log(a, out);
    const Dataset b = load_dataset(out); // auto-detected as a log
    EXPECT_EQ(b.format, "log");
    EXPECT_DOUBLE_EQ(b.t0_s, a.t0_s);
    ASSERT_EQ(b.robots.size(), a.robots.size());
    ASSERT_EQ(b.landmarks.size(), a.landmarks.size());
    for (size_t i = 0; i < a.robots.size(); ++i) {
        const RobotLog &x = a.robots[i];
        const RobotLog &y = b.robots[i];
        ASSERT_EQ(x.odo.size(), y.odo.size());
        for (size_t k = 0; k < x.odo.size(); ++k) {
            EXPECT_EQ(x.odo[k].t_s, y.odo[k].t_s); // bit for bit
            EXPECT_EQ(x.odo[k].a, y.odo[k].a);
            EXPECT_EQ(x.odo[k].b, y.odo[k].b);
        }
        ASSERT_EQ(x.z.size(), y.z.size());
        for (size_t k = 0; k < x.z.size(); ++k) {
            EXPECT_EQ(x.z[k].t_s, y.z[k].t_s);
            EXPECT_EQ(x.z[k].landmark_id, y.z[k].landmark_id);
            EXPECT_EQ(x.z[k].range_m, y.z[k].range_m);
            EXPECT_EQ(x.z[k].bearing_rad, y.z[k].bearing_rad);
        }
        ASSERT_EQ(x.rz.size(), y.rz.size());
        ASSERT_EQ(x.truth.size(), y.truth.size());
        for (size_t k = 0; k < x.truth.size(); ++k) {
            EXPECT_EQ(x.truth[k].pose.x, y.truth[k].pose.x);
            EXPECT_EQ(x.truth[k].pose.theta, y.truth[k].pose.theta);
        }
    }
    // a log folder without truth files still loads, with notes
    TempDir e;
    e.file("robot4.log", "V 0 0 0\n");
    const Dataset c = load_landmark_log(e.str());
    ASSERT_EQ(c.robots.size(), 1u);
    EXPECT_EQ(c.robots[0].id, 4);
    EXPECT_EQ(c.report.notes.size(), 2u);
    // a malformed log names its file
    e.file("robot4.log", "V 0 0 0\nZ 1 2 3\n");
    try {
        load_landmark_log(e.str());
        FAIL();
    } catch (const ReplayError &err) {
        EXPECT_TRUE(has(err.what(), "robot4.log:2: expected Z t id range bearing"));
    }
}

TEST(Config, DefaultsValidateAndRoundTrip)
{
    ReplayConfig a = replay_config_default();
    EXPECT_NO_THROW(replay_config_validate(a));
    {
        ReplayConfig z = a; // 0 sent the whole budget in consecutive frames
        z.merge.resend_s = 0.0;
        EXPECT_THROW(replay_config_validate(z), ReplayError);
    }
    a.filter.type = FilterKind::Ekf;
    a.robot[3].filter = FilterKind::FastSlam1;
    a.robot[3].has_filter = true;
    a.robot[2].odo = {0.9, 0.8, 0.1};
    a.robot[2].has_odo = true;
    a.slam.noise.bearing_var_rad2 = 1.0 / 7.0; // not representable in few digits
    std::ostringstream os;
    replay_config_write(a, os);
    ReplayConfig b = replay_config_default();
    replay_config_load_string(b, os.str(), "rt.ini");
    std::ostringstream os2;
    replay_config_write(b, os2);
    EXPECT_EQ(os.str(), os2.str());
    EXPECT_EQ(b.slam.noise.bearing_var_rad2, 1.0 / 7.0);
    EXPECT_EQ(b.filter_of(3), FilterKind::FastSlam1);
    EXPECT_EQ(b.filter_of(1), FilterKind::Ekf);
    EXPECT_EQ(b.odo_of(2).scale_w, 0.8);
    EXPECT_EQ(b.odo_of(1).scale_w, a.odo.scale_w);
}

// [merge] refute_sd_factor defaults to the core's value and is read.
TEST(Config, RefuteKeyIsRead)
{
    ReplayConfig c = replay_config_default();
    EXPECT_EQ(c.merge.core.refute_sd_factor, merge_config_default().refute_sd_factor);
    EXPECT_EQ(c.merge.core.refute_sd_factor, 1.0);
    replay_config_load_string(c, "[merge]\nrefute_sd_factor = 0\n", "r.ini");
    EXPECT_EQ(c.merge.core.refute_sd_factor, 0.0);
    // and lost_sd_factor (the lost receiver's bound, the same refute sd)
    EXPECT_EQ(c.merge.core.lost_sd_factor, merge_config_default().lost_sd_factor);
    EXPECT_EQ(c.merge.core.lost_sd_factor, 1.0);
    replay_config_load_string(c, "[merge]\nlost_sd_factor = 2.5\n", "r.ini");
    EXPECT_EQ(c.merge.core.lost_sd_factor, 2.5);
}

// The Fast-SLAM revisit keys and EKF-SLAM's innovation monitor default to the
// core's values and reach the filter.
TEST(Config, ClosureKeysReachTheFilter)
{
    const fastslam_config_t fc = fastslam_config_default();
    ReplayConfig c = replay_config_default();
    EXPECT_EQ(c.filter.closure_drift_ratio, fc.closure_drift_ratio);
    EXPECT_EQ(c.filter.closure_gap, fc.closure_gap);
    EXPECT_EQ(c.filter.closure_ambiguity_ll, fc.closure_ambiguity_ll);
    EXPECT_EQ(c.filter.closure_misses_per_support, fc.closure_misses_per_support);
    EXPECT_EQ(c.filter.closure_unsupported_every, fc.closure_unsupported_every);
    EXPECT_EQ(c.filter.closure_chance_max, fc.closure_chance_max);
    EXPECT_EQ(c.filter.nis_inflate, ekfslam_config_default().nis_inflate);
    replay_config_load_string(c, "[filter]\nclosure_drift_ratio = 0\nclosure_gap = 7\nclosure_ambiguity_ll = 1.5\n"
                              "closure_misses_per_support = 3.5\nclosure_unsupported_every = 5\nclosure_chance_max = 0.5\n",
                              "c.ini");
    RobotFilter f(FilterKind::FastSlam2, c, 0, pose2_t{0.0, 0.0, 0.0}, 1);
    EXPECT_EQ(f.app()->u.fs.cfg.closure_drift_ratio, 0.0);
    EXPECT_EQ(f.app()->u.fs.cfg.closure_gap, 7);
    EXPECT_EQ(f.app()->u.fs.cfg.closure_ambiguity_ll, 1.5);
    EXPECT_EQ(f.app()->u.fs.cfg.closure_misses_per_support, 3.5);
    EXPECT_EQ(f.app()->u.fs.cfg.closure_unsupported_every, 5);
    EXPECT_EQ(f.app()->u.fs.cfg.closure_chance_max, 0.5);
    EXPECT_EQ(c.filter.active_spread_madds, ekfslam_config_default().active_spread_madds);
    EXPECT_EQ(c.filter.mh_frames, ekfslam_config_default().mh_frames);
    replay_config_load_string(c, "[filter]\nnis_inflate = 0\nactive_spread_madds = 2000000\nmh_frames = 0\n", "n.ini");
    RobotFilter e(FilterKind::Ekf, c, 0, pose2_t{0.0, 0.0, 0.0}, 1);
    EXPECT_EQ(e.app()->u.ekf.cfg.nis_inflate, 0.0);
    EXPECT_EQ(e.app()->u.ekf.cfg.active_spread_madds, 2000000U);
    EXPECT_EQ(e.app()->u.ekf.cfg.mh_frames, 0U);
    EXPECT_EQ(e.app()->u.ekf.alt, &e.app()->u.ekf2.alt);
}

TEST(Config, ErrorsNameFileLineAndKey)
{
    auto err = [](const std::string &text) {
        ReplayConfig c = replay_config_default();
        try {
            replay_config_load_string(c, text, "x.ini");
        } catch (const ReplayError &e) {
            return std::string(e.what());
        }
        return std::string();
    };
    EXPECT_EQ(err("[slam]\nrange_var_m2 = 0.01\n"), "");
    EXPECT_TRUE(has(err("[slam]\n\nrange_var_m3 = 1\n"), "x.ini:3: unknown key 'range_var_m3' in [slam]"));
    EXPECT_TRUE(has(err("[nosuch]\na = 1\n"), "x.ini:2: unknown key 'a' in [nosuch]"));
    EXPECT_TRUE(has(err("[slam]\ngate_chi2 = abc\n"), "x.ini:2: [slam] gate_chi2: not a finite number"));
    EXPECT_TRUE(has(err("[filter]\nparticles = 2.5\n"), "x.ini:2: [filter] particles: expected an integer"));
    EXPECT_TRUE(has(err("[filter]\ntype = kalman\n"), "unknown filter 'kalman'"));
    EXPECT_TRUE(has(err("[filter]\nclosure_drift_ratio = -1\n"), "[filter] closure_drift_ratio"));
    EXPECT_TRUE(has(err("[filter]\nclosure_misses_per_support = -1\n"), "closure_misses_per_support"));
    EXPECT_TRUE(has(err("[filter]\nclosure_chance_max = -0.5\n"), "closure_chance_max"));
    EXPECT_TRUE(has(err("[filter]\nclosure_unsupported_every = 70000\n"), "closure_unsupported_every"));
    EXPECT_TRUE(has(err("[filter]\nclosure_gap = 70000\n"), "[filter] closure_gap"));
    EXPECT_TRUE(has(err("[filter]\nnis_inflate = -1\n"), "[filter] nis_inflate"));
    EXPECT_TRUE(has(err("[filter]\nactive_spread_madds = -1\n"), "[filter] active_spread_madds"));
    EXPECT_TRUE(has(err("[merge]\nenabled = maybe\n"), "expected a boolean"));
    EXPECT_TRUE(has(err("[merge]\nrefute_sd_factor = -0.5\n"), "[merge] agree_z"));
    EXPECT_TRUE(has(err("[merge]\nlost_sd_factor = -1\n"), "lost_sd_factor finite and >= 0"));
    EXPECT_TRUE(has(err("[merge]\nlost_sd_factor = nan\n"), "[merge] lost_sd_factor: not a finite number"));
    EXPECT_TRUE(has(err("[robot2]\nfoo = 1\n"), "x.ini:2: unknown key 'foo' in [robot2]"));
    EXPECT_TRUE(has(err("this is not ini\n"), "x.ini:1:"));
    // values that parse but are out of their domain
    EXPECT_TRUE(has(err("[slam]\nbearing_var_rad2 = 0\n"), "invalid configuration: [slam]"));
    EXPECT_TRUE(has(err("[odometry]\nscale_v = -1\n"), "invalid configuration: [odometry]"));
    EXPECT_TRUE(has(err("[robot4]\ndelay_s = 9\n"), "[robot4]"));
    EXPECT_TRUE(has(err("[input]\nmax_range_m = 0\n"), "[input]"));
    EXPECT_TRUE(has(err("[eval]\ngate_m = 0\n"), "[eval]"));
    EXPECT_TRUE(has(err("[eval]\npose_fit_min_matched = 1\n"), "[eval] pose_fit_min_matched"));
    // overflow is refused; an underflow to a subnormal is a finite value,
    // and the form this file writes for it reads back (fuzz_replay_config)
    EXPECT_TRUE(has(err("[merge]\nwindow_s = 1e999\n"), "not a finite number"));
    EXPECT_EQ(err("[merge]\nwindow_s = 0x1p-1074\n"), "");
    EXPECT_EQ(err("[merge]\nwindow_s = 4.94066e-324\n"), "");
    ReplayConfig c = replay_config_default();
    EXPECT_THROW(replay_config_load(c, "/nonexistent.ini"), ReplayError);
}

TEST(Odometry, ConstantVelocityIsAnExactArcAndSplitsAdditively)
{
    RobotLog log;
    log.id = 1;
    OdoRecord v;
    v.kind = OdoRecord::Kind::Velocity;
    v.t_s = 1.0;
    v.a = 0.5;
    v.b = 0.25;
    log.odo.push_back(v);
    const OdoTrack t(log, OdoModel{}, 11.0);
    // circle of radius v/w = 2 m: after 4 s, heading 1 rad
    const odo_increment_t u = t.increment(1.0, 5.0);
    EXPECT_NEAR(u.dtheta, 1.0, 1e-12);
    EXPECT_NEAR(u.dx, 2.0 * std::sin(1.0), 1e-12);
    EXPECT_NEAR(u.dy, 2.0 * (1.0 - std::cos(1.0)), 1e-12);
    // before the first record nothing moves; splitting composes exactly
    const odo_increment_t a = t.increment(0.0, 2.3);
    const odo_increment_t b = t.increment(2.3, 5.0);
    const odo_increment_t ab = odo_compose(a, b);
    const odo_increment_t whole = t.increment(0.0, 5.0);
    EXPECT_NEAR(ab.dx, whole.dx, 1e-12);
    EXPECT_NEAR(ab.dy, whole.dy, 1e-12);
    EXPECT_NEAR(ab.dtheta, whole.dtheta, 1e-12);
    EXPECT_NEAR(whole.dtheta, 1.0, 1e-12);
    // held until the end of the data, not beyond
    EXPECT_NEAR(t.increment(0.0, 20.0).dtheta, 2.5, 1e-12);
    // scale and delay: the command acts 0.5 s late at 80 %
    const OdoTrack m(log, OdoModel{0.8, 0.8, 0.5}, 11.0);
    EXPECT_NEAR(m.increment(0.0, 1.5).dtheta, 0.0, 1e-12);
    EXPECT_NEAR(m.increment(1.5, 5.5).dtheta, 0.8, 1e-12);
    EXPECT_DOUBLE_EQ(m.begin_s(), 1.5);
}

TEST(Odometry, IncrementRecordsAreReproducedAndSplitEvenly)
{
    RobotLog log;
    log.id = 1;
    for (int k = 0; k < 4; ++k) {
        OdoRecord o;
        o.kind = OdoRecord::Kind::Increment;
        o.t_s = 1.0 + k;
        o.a = 0.3;
        o.b = -0.05;
        o.c = 0.4;
        log.odo.push_back(o);
    }
    const OdoTrack t(log, OdoModel{}, 4.0);
    // the first record is applied at its stamp; each later one over the
    // second before it, reproducing the logged increment
    const odo_increment_t first = t.increment(0.5, 1.0);
    EXPECT_NEAR(first.dx, 0.3, 1e-12);
    EXPECT_NEAR(first.dtheta, 0.4, 1e-12);
    const odo_increment_t second = t.increment(1.0, 2.0);
    EXPECT_NEAR(second.dx, 0.3, 1e-12);
    EXPECT_NEAR(second.dy, -0.05, 1e-12);
    EXPECT_NEAR(second.dtheta, 0.4, 1e-12);
    const odo_increment_t half = t.increment(1.0, 1.5);
    EXPECT_NEAR(half.dtheta, 0.2, 1e-12);
    const odo_increment_t rest = t.increment(1.5, 2.0);
    const odo_increment_t both = odo_compose(half, rest);
    EXPECT_NEAR(both.dx, 0.3, 1e-12);
    EXPECT_NEAR(both.dy, -0.05, 1e-12);
}

TEST(Odometry, FitRecoversScaleAndDelayOfSyntheticData)
{
    // commands (v, w) at 100 Hz, a robot that realises 0.9 v and 0.85 w
    // 0.2 s late, truth sampled at 60 Hz
    RobotLog log;
    log.id = 1;
    const double sv = 0.9, sw = 0.85, delay = 0.2;
    for (int k = 0; k < 100 * 200; ++k) {
        OdoRecord o;
        o.t_s = 0.01 * k;
        o.a = 0.1 + 0.05 * std::sin(0.05 * o.t_s);
        o.b = 0.4 * std::sin(0.7 * o.t_s) + 0.2 * std::sin(0.13 * o.t_s);
        log.odo.push_back(o);
    }
    const OdoTrack truth_odo(log, OdoModel{sv, sw, delay}, 200.0);
    pose2_t p = {1.0, 2.0, 0.3};
    double t_prev = 0.0;
    for (int k = 0; k < 60 * 200; ++k) {
        const double t = k / 60.0;
        p = motion_apply(p, truth_odo.increment(t_prev, t));
        t_prev = t;
        log.truth.push_back({t, p});
    }
    const OdoFit f = fit_odometry(log, 1.0, 0.132);
    EXPECT_NEAR(f.model.delay_s, delay, 0.011);
    EXPECT_NEAR(f.model.scale_v, sv, 0.005);
    EXPECT_NEAR(f.model.scale_w, sw, 0.005);
    EXPECT_LT(f.resid_th_sd_rad, 1e-3);
    EXPECT_GT(f.windows, 150);
    // the raw (unit, undelayed) model drifts more than the fitted one
    EXPECT_GT(f.drift_raw_m, 5.0 * f.drift_fit_m);
    RobotLog none;
    EXPECT_THROW(fit_odometry(none), ReplayError);
}

TEST(Truth, InterpolatesAcrossTheWrapAndRefusesGaps)
{
    std::vector<TruthPose> path = {{0.0, {0.0, 0.0, 3.0}}, {1.0, {1.0, 0.0, -3.0}}, {3.0, {2.0, 0.0, 0.0}}};
    const TruthTrack t(path, 1.5);
    const auto mid = t.at(0.5);
    ASSERT_TRUE(mid.has_value());
    EXPECT_NEAR(mid->x, 0.5, 1e-12);
    // the shorter arc from 3.0 to -3.0 passes through pi
    EXPECT_NEAR(std::fabs(mid->theta), M_PI, 1e-9);
    EXPECT_FALSE(t.at(2.0).has_value()); // inside a 2 s gap
    EXPECT_FALSE(t.at(-0.1).has_value());
    EXPECT_FALSE(t.at(3.1).has_value());
    ASSERT_TRUE(t.at(3.0).has_value());
    MapFrame f{{1.0, 1.0, M_PI / 2}};
    const pose2_t in = f.pose_in_map({1.0, 2.0, M_PI / 2});
    EXPECT_NEAR(in.x, 1.0, 1e-12);
    EXPECT_NEAR(in.y, 0.0, 1e-12);
    EXPECT_NEAR(in.theta, 0.0, 1e-12);
}
