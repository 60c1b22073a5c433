// libFuzzer target for coslam-replay's readers (host/replay/replay_data.cpp):
// the generic landmark log (docs/replay.md, ../shared/DESIGN.md), its truth
// files, and the MRCLAM folder reader.
//
// Input: byte 0 picks the reader, the rest is the text.
//   0  parse_landmark_log        (one robot log, robot id 1)
//   1  parse_truth_path
//   2  parse_truth_landmarks
//   3  load_mrclam: the text is cut at bytes 0x01 into the files
//      Barcodes.dat, Landmark_Groundtruth.dat, Robot1_Odometry.dat,
//      Robot1_Measurement.dat, Robot1_Groundtruth.dat, Robot2_Odometry.dat,
//      Robot2_Measurement.dat (a missing part: the file is absent), written
//      into a scratch folder
//   4  load_landmark_log: the same with robot1.log, robot1_truth.txt,
//      robot2.log, landmarks_truth.txt, t0.txt
// Seeds: corpus/fuzz_replay_data/ (corpus/make_seeds.py; slices of the
// formats' examples); dictionary replay_data.dict.
//
// Properties checked, beyond "no crash, no ASan/UBSan report":
//  - the only exception is ReplayError (a std::out_of_range from stoi, a
//    bad_alloc, ... is a bug), with a line >= 0;
//  - accepted: every number is finite, ranges > 0, landmark ids >= -1,
//    time stamps never decrease within a stream, no robot sights itself;
//  - accepted logs survive write_landmark_log + load_landmark_log: each
//    stream reads back with the same records (17 digits round-trip doubles).
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fuzz_check.h"
#include "replay_data.h"

namespace fs = std::filesystem;
using namespace coslam::replay;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

namespace {

void require(bool ok, const char *what)
{
    fuzz_require(ok ? 1 : 0, what);
}

const fs::path &scratch()
{
    static fs::path dir = [] {
        char tmpl[] = "/tmp/coslam-fuzz-replay-XXXXXX";
        const char *d = mkdtemp(tmpl);
        require(d != nullptr, "mkdtemp");
        return fs::path(d);
    }();
    return dir;
}

void check_robot(const RobotLog &r)
{
    double last = -INFINITY;
    for (const auto &o : r.odo) {
        require(std::isfinite(o.t_s) && std::isfinite(o.a) && std::isfinite(o.b) && std::isfinite(o.c),
                "odometry finite");
        require(o.t_s >= last, "odometry time order");
        last = o.t_s;
    }
    last = -INFINITY;
    for (const auto &z : r.z) {
        require(std::isfinite(z.t_s) && std::isfinite(z.range_m) && std::isfinite(z.bearing_rad),
                "sighting finite");
        require(z.range_m > 0.0 && z.landmark_id >= -1, "sighting range / id");
        require(z.t_s >= last, "sighting time order");
        last = z.t_s;
    }
    last = -INFINITY;
    for (const auto &s : r.rz) {
        require(std::isfinite(s.t_s) && std::isfinite(s.range_m) && std::isfinite(s.bearing_rad),
                "robot sighting finite");
        require(s.range_m > 0.0, "robot sighting range");
        require(s.other_robot != r.id, "robot sights itself");
        require(s.t_s >= last, "robot sighting time order");
        last = s.t_s;
    }
    last = -INFINITY;
    for (const auto &p : r.truth) {
        require(std::isfinite(p.t_s) && std::isfinite(p.pose.x) && std::isfinite(p.pose.y) &&
                    std::isfinite(p.pose.theta),
                "truth finite");
        require(p.t_s >= last, "truth time order");
        last = p.t_s;
    }
}

void check_landmarks(const std::vector<LandmarkTruth> &ls)
{
    for (const auto &l : ls) {
        require(std::isfinite(l.pos.x) && std::isfinite(l.pos.y), "landmark finite");
    }
}

bool same_odo(const OdoRecord &a, const OdoRecord &b)
{
    return a.t_s == b.t_s && a.kind == b.kind && a.a == b.a && a.b == b.b &&
           (a.kind == OdoRecord::Kind::Velocity || a.c == b.c);
}

// write_landmark_log + load_landmark_log give back every stream unchanged
void check_round_trip(const Dataset &ds)
{
    const fs::path out = scratch() / "rt";
    fs::remove_all(out);
    write_landmark_log(ds, out.string());
    const Dataset back = load_landmark_log(out.string());
    require(back.robots.size() == ds.robots.size(), "round trip: robots");
    for (size_t i = 0; i < ds.robots.size(); ++i) {
        const RobotLog &a_in = ds.robots[i];
        const RobotLog &b = back.robots[i];
        // the loader drops (and counts) sightings of robots the dataset
        // does not have; the parsed log still holds them
        RobotLog a = a_in;
        a.rz.clear();
        for (const auto &s : a_in.rz) {
            if (ds.robot(s.other_robot) != nullptr) {
                a.rz.push_back(s);
            }
        }
        require(static_cast<long>(a_in.rz.size() - a.rz.size()) <= back.report.unknown_robot_sightings,
                "round trip: dropped robot sightings counted");
        require(a.id == b.id && a.odo.size() == b.odo.size() && a.z.size() == b.z.size() &&
                    a.rz.size() == b.rz.size() && a.truth.size() == b.truth.size(),
                "round trip: record counts");
        for (size_t k = 0; k < a.odo.size(); ++k) {
            require(same_odo(a.odo[k], b.odo[k]), "round trip: odometry");
        }
        for (size_t k = 0; k < a.z.size(); ++k) {
            require(a.z[k].t_s == b.z[k].t_s && a.z[k].landmark_id == b.z[k].landmark_id &&
                        a.z[k].range_m == b.z[k].range_m && a.z[k].bearing_rad == b.z[k].bearing_rad,
                    "round trip: sightings");
        }
        for (size_t k = 0; k < a.rz.size(); ++k) {
            require(a.rz[k].t_s == b.rz[k].t_s && a.rz[k].other_robot == b.rz[k].other_robot &&
                        a.rz[k].range_m == b.rz[k].range_m && a.rz[k].bearing_rad == b.rz[k].bearing_rad,
                    "round trip: robot sightings");
        }
        for (size_t k = 0; k < a.truth.size(); ++k) {
            require(a.truth[k].t_s == b.truth[k].t_s && a.truth[k].pose.x == b.truth[k].pose.x &&
                        a.truth[k].pose.y == b.truth[k].pose.y,
                    "round trip: truth");
        }
    }
    require(back.landmarks.size() == ds.landmarks.size(), "round trip: landmarks");
    for (size_t k = 0; k < ds.landmarks.size(); ++k) {
        require(back.landmarks[k].id == ds.landmarks[k].id && back.landmarks[k].pos.x == ds.landmarks[k].pos.x &&
                    back.landmarks[k].pos.y == ds.landmarks[k].pos.y,
                "round trip: landmark positions");
    }
    require(back.t0_s == ds.t0_s, "round trip: t0");
}

void write_parts(const std::string &text, const std::vector<const char *> &names)
{
    const fs::path d = scratch() / "in";
    fs::remove_all(d);
    fs::create_directories(d);
    size_t start = 0;
    for (const char *name : names) {
        if (start > text.size()) {
            break;
        }
        size_t end = text.find('\x01', start);
        if (end == std::string::npos) {
            end = text.size();
        }
        std::ofstream(d / name, std::ios::binary) << text.substr(start, end - start);
        start = end + 1;
    }
}

void run(uint8_t mode, const std::string &text)
{
    switch (mode % 5U) {
    case 0: {
        std::istringstream in(text);
        Dataset ds;
        ds.robots.emplace_back();
        ds.robots[0].id = 1;
        parse_landmark_log(in, "robot1.log", ds.robots[0], ds.report);
        check_robot(ds.robots[0]);
        check_round_trip(ds);
        break;
    }
    case 1: {
        std::istringstream in(text);
        Dataset ds;
        ds.robots.emplace_back();
        ds.robots[0].id = 1;
        ds.robots[0].truth = parse_truth_path(in, "robot1_truth.txt");
        check_robot(ds.robots[0]);
        break;
    }
    case 2: {
        std::istringstream in(text);
        Dataset ds;
        ds.robots.emplace_back();
        ds.robots[0].id = 1;
        ds.landmarks = parse_truth_landmarks(in, "landmarks_truth.txt");
        check_landmarks(ds.landmarks);
        check_round_trip(ds);
        break;
    }
    case 3: {
        write_parts(text, {"Barcodes.dat", "Landmark_Groundtruth.dat", "Robot1_Odometry.dat",
                           "Robot1_Measurement.dat", "Robot1_Groundtruth.dat", "Robot2_Odometry.dat",
                           "Robot2_Measurement.dat"});
        const Dataset ds = load_mrclam((scratch() / "in").string());
        require(std::isfinite(ds.t0_s), "MRCLAM t0 finite");
        for (const auto &r : ds.robots) {
            check_robot(r);
        }
        check_landmarks(ds.landmarks);
        check_round_trip(ds);
        break;
    }
    default: {
        write_parts(text, {"robot1.log", "robot1_truth.txt", "robot2.log", "landmarks_truth.txt", "t0.txt"});
        const Dataset ds = load_landmark_log((scratch() / "in").string());
        require(std::isfinite(ds.t0_s), "log t0 finite");
        for (const auto &r : ds.robots) {
            check_robot(r);
        }
        check_landmarks(ds.landmarks);
        check_round_trip(ds);
        break;
    }
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) {
        return 0;
    }
    const std::string text(reinterpret_cast<const char *>(data) + 1, size - 1);
    try {
        run(data[0], text);
    } catch (const ReplayError &e) {
        require(e.line() >= 0, "error line >= 0");
    } catch (const std::exception &e) {
        std::fprintf(stderr, "unexpected exception (not ReplayError): %s\n", e.what());
        std::abort();
    }
    return 0;
}
