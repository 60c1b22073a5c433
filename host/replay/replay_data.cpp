// host/replay/replay_data.cpp - MRCLAM and landmark-log readers, log writer.
#include "replay_data.h"
#include "checked_file.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <limits>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <utility>

namespace fs = std::filesystem;

namespace coslam::replay {

ReplayError::ReplayError(const std::string &file, long line, const std::string &reason)
    : std::runtime_error(line > 0 ? file + ":" + std::to_string(line) + ": " + reason : file + ": " + reason),
      file_(file), line_(line)
{
}

const RobotLog *Dataset::robot(int id) const
{
    for (const auto &r : robots) {
        if (r.id == id) {
            return &r;
        }
    }
    return nullptr;
}

const LandmarkTruth *Dataset::landmark(int id) const
{
    for (const auto &l : landmarks) {
        if (l.id == id) {
            return &l;
        }
    }
    return nullptr;
}

std::string fmt_value(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

std::string printable(const std::string &s)
{
    std::string out;
    for (size_t i = 0; i < s.size(); ++i) {
        if (out.size() >= 40) {
            out += "...";
            break;
        }
        const unsigned char c = static_cast<unsigned char>(s[i]);
        if (c >= 0x20 && c < 0x7f) {
            out += static_cast<char>(c);
        } else {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02x", c);
            out += buf;
        }
    }
    return out;
}

namespace {

// One data line split into fields: comments ('#' to the end) and CR removed.
// A line longer than kMaxLineBytes is an error at that line (read in bounded
// pieces: a file without newlines is not read whole into memory).
struct LineReader {
    LineReader(std::istream &in_, std::string name_) : in(in_), name(std::move(name_)) {}
    std::istream &in;
    std::string name;
    long line_no = 0;
    std::vector<std::string> fields;

    bool next()
    {
        std::string line;
        char buf[kMaxLineBytes + 2];
        while (true) {
            errno = 0;
            in.getline(buf, sizeof buf);
            if (in.bad()) {
                // not the end of the file: a read error (EIO, a directory)
                const int err = errno;
                throw ReplayError(name, 0,
                                  "read error" + (line_no > 0 ? " after line " + std::to_string(line_no) : "") +
                                      ": " + (err != 0 ? std::strerror(err) : "I/O error"));
            }
            if (in.eof() && in.gcount() == 0) {
                return false;
            }
            ++line_no;
            if (in.fail()) {
                if (in.gcount() >= static_cast<std::streamsize>(sizeof buf - 1)) {
                    fail("line longer than " + std::to_string(kMaxLineBytes) + " bytes (not a text data file?)");
                }
                return false;
            }
            // gcount includes the newline getline consumed (not stored)
            const auto n = static_cast<size_t>(in.gcount()) - (in.eof() ? 0U : 1U);
            if (std::memchr(buf, '\0', n) != nullptr) {
                fail("NUL byte in the line (not a text data file?)");
            }
            line.assign(buf, n);
            const auto hash = line.find('#');
            if (hash != std::string::npos) {
                line.erase(hash);
            }
            fields.clear();
            std::istringstream ss(line);
            std::string f;
            while (ss >> f) {
                fields.push_back(f);
            }
            if (!fields.empty()) {
                return true;
            }
        }
        return false;
    }

    [[noreturn]] void fail(const std::string &reason) const { throw ReplayError(name, line_no, reason); }

    double num(size_t i, const char *what) const
    {
        const std::string &s = fields.at(i);
        errno = 0;
        char *end = nullptr;
        const double v = std::strtod(s.c_str(), &end);
        if (end == s.c_str() || *end != '\0') {
            fail(std::string("field ") + std::to_string(i + 1) + " (" + what + ") is not a number: '" + printable(s) +
                 "'");
        }
        if (!std::isfinite(v) || (errno == ERANGE && std::fabs(v) > 1.0)) {
            fail(std::string("field ") + std::to_string(i + 1) + " (" + what + ") is not finite: '" + printable(s) +
                 "'");
        }
        // ERANGE with |v| <= 1: an underflow (subnormal or 0), still a number
        return v;
    }

    int integer(size_t i, const char *what) const
    {
        const double v = num(i, what);
        if (v != std::floor(v) || std::fabs(v) > 1e9) {
            fail(std::string("field ") + std::to_string(i + 1) + " (" + what + ") is not an integer: '" +
                 printable(fields.at(i)) + "'");
        }
        return static_cast<int>(v);
    }

    void expect_fields(size_t n_min, size_t n_max, const char *layout) const
    {
        if (fields.size() < n_min || fields.size() > n_max) {
            fail("expected " + std::string(layout) + " (" + std::to_string(n_min) +
                 (n_max != n_min ? "-" + std::to_string(n_max) : std::string()) + " fields), got " +
                 std::to_string(fields.size()));
        }
    }
};

// Checks that time stamps never decrease within one file and, for files
// with relative stamps (landmark logs; MRCLAM's absolute stamps are checked
// once t0 is known), that they lie in [0, kMaxSpanS].
struct MonotonicTime {
    explicit MonotonicTime(bool relative_ = false) : relative(relative_) {}
    bool relative;
    double last = -std::numeric_limits<double>::infinity();
    void check(const LineReader &r, double t)
    {
        if (t < last) {
            std::ostringstream os;
            os << std::setprecision(15) << "time goes backwards: " << t << " after " << last;
            r.fail(os.str());
        }
        if (relative && !(t >= 0.0 && t <= kMaxSpanS)) {
            r.fail("time stamp " + fmt_value(t) + " s outside [0, " + fmt_value(kMaxSpanS) +
                   "] (stamps are relative to t0.txt; docs/replay.md, Limits)");
        }
        last = t;
    }
};

// Gaps between consecutive odometry records: counted above kOdoGapWarnS,
// refused above kMaxOdoGapS (the filter would hold the last command across it).
struct OdoGapCheck {
    double last = std::numeric_limits<double>::quiet_NaN();
    void check(const LineReader &r, double t, ParseReport &report, int robot_id)
    {
        const double gap = t - last;
        last = t;
        if (!(gap > kOdoGapWarnS)) {
            return; // also the first record (NaN)
        }
        if (gap > kMaxOdoGapS) {
            r.fail("odometry gap of " + fmt_value(gap) + " s since the previous odometry record, more than the " +
                   fmt_value(kMaxOdoGapS) + " s limit (docs/replay.md, Limits)");
        }
        OdoGaps &g = report.odo_gaps[robot_id];
        g.count++;
        if (gap > g.max_s) {
            g.max_s = gap;
            g.where = r.name + ":" + std::to_string(r.line_no);
        }
    }
};

void check_range(const LineReader &r, double range_m)
{
    if (!(range_m > 0.0)) {
        r.fail("range must be positive, got " + fmt_value(range_m));
    }
}

// A bearing in [-2 pi, 2 pi], wrapped to (-pi, pi]; beyond that it is a fault.
double check_bearing(const LineReader &r, double b)
{
    if (!(std::fabs(b) <= 2.0 * M_PI)) {
        r.fail("bearing " + fmt_value(b) + " rad outside [-2 pi, 2 pi]");
    }
    return angle_wrap(b);
}

// A robot id from a file name ("robot17.log"): 1..kMaxRobotId.
int robot_id_from_name(const fs::path &dir, const std::string &digits, const std::string &file)
{
    if (digits.size() > 6 || std::stol(digits) < 1 || std::stol(digits) > kMaxRobotId) {
        throw ReplayError((dir / file).string(), 0,
                          "robot id " + printable(digits) + " outside 1.." + std::to_string(kMaxRobotId) +
                              " (the core's COSLAM_MAX_ROBOTS)");
    }
    return static_cast<int>(std::stol(digits));
}

// What every reader ends with: a robot without odometry is an error (it
// cannot be replayed; an empty file is usually a failed recording), R
// records naming a robot the dataset does not have are counted and dropped.
void finish_dataset(Dataset &ds, const std::vector<int> &folder_ids)
{
    // robots of the folder, read or not: a sighting of an unread one is a
    // sighting of a robot that is not replayed, not of one that is unknown
    const std::set<int> have(folder_ids.begin(), folder_ids.end());
    for (auto &r : ds.robots) {
        if (r.odo.empty()) {
            throw ReplayError(r.source, 0, "no odometry records (empty or truncated log?)");
        }
        const auto n0 = r.rz.size();
        r.rz.erase(std::remove_if(r.rz.begin(), r.rz.end(),
                                  [&have](const RobotSighting &s) { return have.count(s.other_robot) == 0; }),
                   r.rz.end());
        ds.report.unknown_robot_sightings += static_cast<long>(n0 - r.rz.size());
    }
    if (ds.report.unknown_robot_sightings > 0) {
        ds.report.notes.push_back(std::to_string(ds.report.unknown_robot_sightings) +
                                  " sightings of robots that are not in the dataset skipped");
    }
}

} // namespace

bool check_input_file(const fs::path &p, const char *what)
{
    std::error_code ec;
    const fs::file_status st = fs::status(p, ec);
    if (st.type() == fs::file_type::not_found) {
        return false;
    }
    if (ec) {
        throw ReplayError(p.string(), 0, "cannot stat: " + ec.message());
    }
    if (st.type() == fs::file_type::directory) {
        throw ReplayError(p.string(), 0, std::string("is a directory, not a ") + what);
    }
    if (st.type() != fs::file_type::regular) {
        throw ReplayError(p.string(), 0, "not a regular file");
    }
    const auto size = fs::file_size(p, ec);
    if (ec) {
        throw ReplayError(p.string(), 0, "cannot read its size: " + ec.message());
    }
    if (size > kMaxInputFileBytes) {
        throw ReplayError(p.string(), 0,
                          "file of " + std::to_string(size) + " bytes, more than the " +
                              std::to_string(kMaxInputFileBytes >> 20) + " MiB limit (docs/replay.md, Limits)");
    }
    return true;
}

namespace {

std::ifstream open_checked(const fs::path &p)
{
    std::ifstream f(p);
    if (!f) {
        throw ReplayError(p.string(), 0, std::string("cannot open: ") + std::strerror(errno));
    }
    return f;
}

std::ifstream open_or_throw(const fs::path &p)
{
    if (!check_input_file(p, "data file")) {
        throw ReplayError(p.string(), 0, "missing file");
    }
    return open_checked(p);
}

// An optional file (ground truth, t0.txt): nullopt if it does not exist; if
// it exists it must be a readable regular file.
std::optional<std::ifstream> open_optional(const fs::path &p)
{
    if (!check_input_file(p, "data file")) {
        return std::nullopt;
    }
    return open_checked(p);
}

// The robots of a folder to read: all, or those of `only`, each of which
// must be in the folder.
std::set<int> robots_to_read(const std::string &dir, const std::vector<int> &ids, const std::vector<int> &only)
{
    if (only.empty()) {
        return std::set<int>(ids.begin(), ids.end());
    }
    for (const int id : only) {
        if (std::find(ids.begin(), ids.end(), id) == ids.end()) {
            std::string have;
            for (const int i : ids) {
                have += (have.empty() ? "" : ", ") + std::to_string(i);
            }
            throw ReplayError(dir, 0, "no robot " + std::to_string(id) + " in the folder (robots: " + have + ")");
        }
    }
    return std::set<int>(only.begin(), only.end());
}

// "robots 1, 3 not selected: their files not read" (nothing if all are read)
void note_unread(ParseReport &report, const std::vector<int> &ids, const std::set<int> &selected)
{
    std::string list;
    for (const int id : ids) {
        if (selected.count(id) == 0) {
            list += (list.empty() ? "" : ", ") + std::to_string(id);
        }
    }
    if (!list.empty()) {
        report.notes.push_back("robot(s) " + list + " not selected: their files not read");
    }
}

// The stamp of the first record of a file that is not read further (a robot
// not selected), for t0; nullopt, with a note, if it has none.
// For a measurement file (`keep` not NULL) the first row a full read keeps:
// a barcode keep() accepts (known, not the robot itself), as t0 is taken
// from the kept rows.
std::optional<double> first_stamp(const fs::path &p, ParseReport &report,
                                  const std::function<bool(int barcode)> *keep = nullptr)
{
    try {
        auto f = open_optional(p);
        if (!f) {
            return std::nullopt; // missing: what a full read would say is its own business
        }
        LineReader r{*f, p.string()};
        while (r.next()) {
            if (keep == nullptr || (r.fields.size() >= 2 && (*keep)(r.integer(1, "barcode")))) {
                return r.num(0, "t");
            }
        }
    } catch (const ReplayError &e) {
        report.notes.push_back(std::string(e.what()) + " (robot not selected: file not read further, not in t0)");
    }
    return std::nullopt;
}

// Raw MRCLAM row tables with absolute times, shifted after t0 is known.
struct RawRobot {
    int id = 0;
    std::vector<std::array<double, 3>> odo;   // t v w
    std::vector<std::array<double, 4>> meas;  // t subject range bearing (subject -1: unknown)
    std::vector<std::array<double, 4>> truth; // t x y theta
    bool has_truth = false;
    std::string source;
};

} // namespace

void parse_landmark_log(std::istream &in, const std::string &name, RobotLog &out, ParseReport &report)
{
    LineReader r{in, name};
    MonotonicTime mono(true);
    OdoGapCheck gaps;
    while (r.next()) {
        report.lines_read++;
        const std::string &tag = r.fields[0];
        if (tag == "O") {
            r.expect_fields(5, 5, "O t dx dy dtheta");
            OdoRecord o;
            o.t_s = r.num(1, "t");
            mono.check(r, o.t_s);
            gaps.check(r, o.t_s, report, out.id);
            o.kind = OdoRecord::Kind::Increment;
            o.a = r.num(2, "dx");
            o.b = r.num(3, "dy");
            o.c = r.num(4, "dtheta");
            out.odo.push_back(o);
        } else if (tag == "V") {
            r.expect_fields(4, 4, "V t v w");
            OdoRecord o;
            o.t_s = r.num(1, "t");
            mono.check(r, o.t_s);
            gaps.check(r, o.t_s, report, out.id);
            o.kind = OdoRecord::Kind::Velocity;
            o.a = r.num(2, "v");
            o.b = r.num(3, "w");
            out.odo.push_back(o);
        } else if (tag == "Z") {
            r.expect_fields(5, 5, "Z t id range bearing");
            LandmarkSighting z;
            z.t_s = r.num(1, "t");
            mono.check(r, z.t_s);
            z.landmark_id = r.integer(2, "id");
            if (z.landmark_id < -1) {
                r.fail("landmark id must be -1 (unknown) or >= 0, got " + std::to_string(z.landmark_id));
            }
            z.range_m = r.num(3, "range");
            z.bearing_rad = check_bearing(r, r.num(4, "bearing"));
            check_range(r, z.range_m);
            out.z.push_back(z);
        } else if (tag == "R") {
            r.expect_fields(5, 5, "R t other_robot_id range bearing");
            RobotSighting s;
            s.t_s = r.num(1, "t");
            mono.check(r, s.t_s);
            s.other_robot = r.integer(2, "other_robot_id");
            s.range_m = r.num(3, "range");
            s.bearing_rad = check_bearing(r, r.num(4, "bearing"));
            check_range(r, s.range_m);
            if (s.other_robot == out.id) {
                report.self_sightings++;
                continue;
            }
            out.rz.push_back(s);
        } else {
            r.fail("unknown record type '" + tag + "' (expected O, V, Z or R)");
        }
    }
}

std::vector<TruthPose> parse_truth_path(std::istream &in, const std::string &name)
{
    LineReader r{in, name};
    MonotonicTime mono(true);
    std::vector<TruthPose> out;
    while (r.next()) {
        r.expect_fields(4, 4, "t x y theta");
        TruthPose p;
        p.t_s = r.num(0, "t");
        mono.check(r, p.t_s);
        p.pose = {r.num(1, "x"), r.num(2, "y"), angle_wrap(r.num(3, "theta"))};
        out.push_back(p);
    }
    return out;
}

std::vector<LandmarkTruth> parse_truth_landmarks(std::istream &in, const std::string &name)
{
    LineReader r{in, name};
    std::vector<LandmarkTruth> out;
    std::set<int> seen;
    while (r.next()) {
        r.expect_fields(3, 5, "id x y [x_sd y_sd]");
        LandmarkTruth l;
        l.id = r.integer(0, "id");
        if (!seen.insert(l.id).second) {
            r.fail("landmark " + std::to_string(l.id) + " listed twice");
        }
        l.pos = {r.num(1, "x"), r.num(2, "y")};
        out.push_back(l);
    }
    return out;
}

Dataset load_mrclam(const std::string &dir, const std::vector<int> &only)
{
    const fs::path d(dir);
    if (!fs::is_directory(d)) {
        throw ReplayError(dir, 0, "not a folder");
    }
    Dataset ds;
    ds.source = dir;
    ds.format = "mrclam";

    // Barcodes.dat: subject -> barcode
    std::map<int, int> barcode_to_subject;
    {
        const fs::path p = d / "Barcodes.dat";
        auto f = open_or_throw(p);
        LineReader r{f, p.string()};
        while (r.next()) {
            r.expect_fields(2, 2, "subject barcode");
            const int subject = r.integer(0, "subject");
            const int barcode = r.integer(1, "barcode");
            if (!barcode_to_subject.emplace(barcode, subject).second) {
                r.fail("barcode " + std::to_string(barcode) + " listed twice");
            }
        }
        if (barcode_to_subject.empty()) {
            // every sighting would be skipped as an unknown barcode
            throw ReplayError(p.string(), 0, "no records (empty file?): the barcodes identify every sighting");
        }
    }
    {
        const fs::path p = d / "Landmark_Groundtruth.dat";
        auto f = open_or_throw(p);
        ds.landmarks = parse_truth_landmarks(f, p.string());
        if (ds.landmarks.empty()) {
            // every landmark sighting would be skipped as of an unknown subject
            throw ReplayError(p.string(), 0, "no records (empty file?): it tells landmarks from robots");
        }
    }
    std::set<int> landmark_subjects;
    for (const auto &l : ds.landmarks) {
        landmark_subjects.insert(l.id);
    }

    // robots: every RobotN_Odometry.dat
    std::vector<int> ids;
    const std::regex odo_re("Robot([0-9]+)_Odometry\\.dat");
    for (const auto &e : fs::directory_iterator(d)) {
        std::smatch m;
        const std::string fn = e.path().filename().string();
        if (std::regex_match(fn, m, odo_re)) {
            ids.push_back(robot_id_from_name(d, m[1].str(), fn));
        }
    }
    std::sort(ids.begin(), ids.end());
    if (ids.empty()) {
        throw ReplayError(dir, 0, "no RobotN_Odometry.dat in the folder: not an MRCLAM dataset");
    }

    const std::set<int> selected = robots_to_read(dir, ids, only);
    note_unread(ds.report, ids, selected);

    std::vector<RawRobot> raw;
    double t0 = std::numeric_limits<double>::infinity();
    for (const int id : ids) {
        RawRobot rr;
        rr.id = id;
        const std::string base = "Robot" + std::to_string(id) + "_";
        if (selected.count(id) == 0) {
            const std::function<bool(int)> kept = [&](int barcode) {
                const auto it = barcode_to_subject.find(barcode);
                return it != barcode_to_subject.end() && it->second != id;
            };
            for (const char *file : {"Odometry.dat", "Measurement.dat", "Groundtruth.dat"}) {
                const bool meas = std::string(file) == "Measurement.dat";
                if (const auto t = first_stamp(d / (base + file), ds.report, meas ? &kept : nullptr)) {
                    t0 = std::min(t0, *t);
                }
            }
            continue;
        }
        {
            const fs::path p = d / (base + "Odometry.dat");
            auto f = open_or_throw(p);
            LineReader r{f, p.string()};
            MonotonicTime mono;
            OdoGapCheck gaps;
            while (r.next()) {
                ds.report.lines_read++;
                r.expect_fields(3, 3, "t v w");
                const double t = r.num(0, "t");
                mono.check(r, t);
                gaps.check(r, t, ds.report, id);
                rr.odo.push_back({t, r.num(1, "v"), r.num(2, "w")});
            }
            rr.source = p.string();
        }
        {
            const fs::path p = d / (base + "Measurement.dat");
            auto f = open_or_throw(p);
            LineReader r{f, p.string()};
            MonotonicTime mono;
            while (r.next()) {
                ds.report.lines_read++;
                r.expect_fields(4, 4, "t barcode range bearing");
                const double t = r.num(0, "t");
                mono.check(r, t);
                const int barcode = r.integer(1, "barcode");
                const double range = r.num(2, "range");
                const double bearing = check_bearing(r, r.num(3, "bearing"));
                check_range(r, range);
                const auto it = barcode_to_subject.find(barcode);
                if (it == barcode_to_subject.end()) {
                    ds.report.unknown_barcode_rows++;
                    ds.report.unknown_barcodes[barcode]++;
                    continue;
                }
                if (it->second == id) {
                    ds.report.self_sightings++;
                    continue;
                }
                rr.meas.push_back({t, static_cast<double>(it->second), range, bearing});
            }
        }
        {
            const fs::path p = d / (base + "Groundtruth.dat");
            auto f = open_optional(p);
            if (f) {
                LineReader r{*f, p.string()};
                MonotonicTime mono;
                while (r.next()) {
                    ds.report.lines_read++;
                    r.expect_fields(4, 4, "t x y theta");
                    const double t = r.num(0, "t");
                    mono.check(r, t);
                    rr.truth.push_back({t, r.num(1, "x"), r.num(2, "y"), r.num(3, "theta")});
                }
                rr.has_truth = true;
            } else {
                ds.report.notes.push_back("robot " + std::to_string(id) + ": no " + p.filename().string() +
                                          ", replayed without evaluation");
            }
        }
        for (const auto *tab : {&rr.odo}) {
            if (!tab->empty()) {
                t0 = std::min(t0, tab->front()[0]);
            }
        }
        if (!rr.meas.empty()) {
            t0 = std::min(t0, rr.meas.front()[0]);
        }
        if (!rr.truth.empty()) {
            t0 = std::min(t0, rr.truth.front()[0]);
        }
        raw.push_back(std::move(rr));
    }
    if (!std::isfinite(t0)) {
        t0 = 0.0;
    }
    ds.t0_s = t0;
    for (const auto &rr : raw) {
        double last = -std::numeric_limits<double>::infinity();
        for (const auto &o : rr.odo) last = std::max(last, o[0]);
        for (const auto &m : rr.meas) last = std::max(last, m[0]);
        for (const auto &g : rr.truth) last = std::max(last, g[0]);
        if (last - t0 > kMaxSpanS) {
            throw ReplayError(rr.source, 0,
                              "records span " + fmt_value(last - t0) + " s from the dataset's first stamp, more than "
                              "the " + fmt_value(kMaxSpanS) + " s limit (docs/replay.md, Limits)");
        }
    }
    // A subject is a landmark if Landmark_Groundtruth.dat lists it, a robot
    // if the folder has its RobotN_Odometry.dat; one that is neither (a
    // landmark left out of the truth file, a robot not recorded) cannot be
    // told apart, so its sightings are skipped and named, never guessed.
    const std::set<int> robot_subjects(ids.begin(), ids.end());
    for (const int id : ids) {
        if (landmark_subjects.count(id) != 0) {
            throw ReplayError((d / "Landmark_Groundtruth.dat").string(), 0,
                              "subject " + std::to_string(id) + " is listed as a landmark, but the folder has "
                              "Robot" + std::to_string(id) + "_Odometry.dat");
        }
    }
    std::map<int, long> neither;
    for (auto &rr : raw) {
        const auto n0 = rr.meas.size();
        rr.meas.erase(std::remove_if(rr.meas.begin(), rr.meas.end(),
                                     [&](const std::array<double, 4> &m) {
                                         const int subject = static_cast<int>(m[1]);
                                         if (landmark_subjects.count(subject) != 0 ||
                                             robot_subjects.count(subject) != 0) {
                                             return false;
                                         }
                                         neither[subject]++;
                                         return true;
                                     }),
                      rr.meas.end());
        ds.report.unknown_subject_rows += static_cast<long>(n0 - rr.meas.size());
    }
    for (const auto &[subject, n] : neither) {
        ds.report.notes.push_back("subject " + std::to_string(subject) + " is neither in Landmark_Groundtruth.dat nor "
                                  "a robot of this folder (no Robot" + std::to_string(subject) +
                                  "_Odometry.dat): its " + std::to_string(n) + " sightings skipped");
    }
    for (const auto &rr : raw) {
        RobotLog rl;
        rl.id = rr.id;
        rl.source = rr.source;
        rl.odo.reserve(rr.odo.size());
        for (const auto &o : rr.odo) {
            OdoRecord rec;
            rec.t_s = o[0] - t0;
            rec.kind = OdoRecord::Kind::Velocity;
            rec.a = o[1];
            rec.b = o[2];
            rl.odo.push_back(rec);
        }
        for (const auto &m : rr.meas) {
            const int subject = static_cast<int>(m[1]);
            if (landmark_subjects.count(subject) != 0) {
                rl.z.push_back({m[0] - t0, subject, m[2], m[3]});
            } else {
                rl.rz.push_back({m[0] - t0, subject, m[2], m[3]});
            }
        }
        for (const auto &g : rr.truth) {
            rl.truth.push_back({g[0] - t0, {g[1], g[2], angle_wrap(g[3])}});
        }
        ds.robots.push_back(std::move(rl));
    }
    finish_dataset(ds, ids);
    return ds;
}

Dataset load_landmark_log(const std::string &dir, const std::vector<int> &only)
{
    const fs::path d(dir);
    if (!fs::is_directory(d)) {
        throw ReplayError(dir, 0, "not a folder");
    }
    Dataset ds;
    ds.source = dir;
    ds.format = "log";
    std::vector<int> ids;
    const std::regex log_re("robot([0-9]+)\\.log");
    for (const auto &e : fs::directory_iterator(d)) {
        std::smatch m;
        const std::string fn = e.path().filename().string();
        if (std::regex_match(fn, m, log_re)) {
            ids.push_back(robot_id_from_name(d, m[1].str(), fn));
        }
    }
    std::sort(ids.begin(), ids.end());
    if (ids.empty()) {
        throw ReplayError(dir, 0, "no robot<k>.log in the folder: not a landmark-log dataset");
    }
    const std::set<int> selected = robots_to_read(dir, ids, only);
    note_unread(ds.report, ids, selected);
    for (const int id : ids) {
        if (selected.count(id) == 0) {
            continue;
        }
        RobotLog rl;
        rl.id = id;
        const fs::path p = d / ("robot" + std::to_string(id) + ".log");
        auto f = open_or_throw(p);
        rl.source = p.string();
        parse_landmark_log(f, p.string(), rl, ds.report);
        const fs::path tp = d / ("robot" + std::to_string(id) + "_truth.txt");
        auto tf = open_optional(tp);
        if (tf) {
            rl.truth = parse_truth_path(*tf, tp.string());
        } else {
            ds.report.notes.push_back("robot " + std::to_string(id) + ": no " + tp.filename().string() +
                                      ", replayed without evaluation");
        }
        ds.robots.push_back(std::move(rl));
    }
    const fs::path lp = d / "landmarks_truth.txt";
    auto lf = open_optional(lp);
    if (lf) {
        ds.landmarks = parse_truth_landmarks(*lf, lp.string());
    } else {
        ds.report.notes.push_back("no landmarks_truth.txt: map errors are not evaluated");
    }
    // t0 of the source is kept if the writer recorded it
    const fs::path mp = d / "t0.txt";
    auto mf = open_optional(mp);
    if (mf) {
        LineReader r{*mf, mp.string()};
        if (r.next()) {
            ds.t0_s = r.num(0, "t0");
        }
    }
    finish_dataset(ds, ids);
    return ds;
}

Dataset load_dataset(const std::string &dir, DataFormat format, const std::vector<int> &only)
{
    if (format == DataFormat::Auto) {
        const fs::path d(dir);
        if (!fs::is_directory(d)) {
            throw ReplayError(dir, 0, "no such folder");
        }
        if (fs::exists(d / "Barcodes.dat")) {
            format = DataFormat::Mrclam;
        } else {
            for (const auto &e : fs::directory_iterator(d)) {
                const std::string fn = e.path().filename().string();
                if (fn.rfind("robot", 0) == 0 && e.path().extension() == ".log") {
                    format = DataFormat::Log;
                    break;
                }
            }
        }
        if (format == DataFormat::Auto) {
            throw ReplayError(dir, 0, "neither an MRCLAM folder (Barcodes.dat) nor a landmark log (robot<k>.log)");
        }
    }
    return format == DataFormat::Mrclam ? load_mrclam(dir, only) : load_landmark_log(dir, only);
}

void write_landmark_log(const Dataset &ds, const std::string &dir)
{
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
        throw coslam::cli::WriteError(dir, ec.value(), "create the output folder");
    }
    const fs::path d(dir);
    // checked (host/cli/checked_file.hpp): a failed open or write throws
    // coslam::cli::WriteError naming the file and the OS's reason
    auto open = [](const fs::path &p) {
        std::ofstream f = coslam::cli::open_checked(p.string());
        f << std::setprecision(17);
        return f;
    };
    auto close_file = [](std::ofstream &f, const fs::path &p) { coslam::cli::close_checked(f, p.string()); };
    for (const auto &r : ds.robots) {
        const fs::path log_path = d / ("robot" + std::to_string(r.id) + ".log");
        auto f = open(log_path);
        f << "# robot " << r.id << " converted from " << ds.source << " (" << ds.format << ")\n"
          << "# O t dx dy dtheta | V t v w | Z t id range bearing | R t other_robot range bearing\n";
        // merge the three time-ordered streams; at equal times odometry first
        size_t io = 0, iz = 0, ir = 0;
        const double inf = std::numeric_limits<double>::infinity();
        while (io < r.odo.size() || iz < r.z.size() || ir < r.rz.size()) {
            const double to = io < r.odo.size() ? r.odo[io].t_s : inf;
            const double tz = iz < r.z.size() ? r.z[iz].t_s : inf;
            const double tr = ir < r.rz.size() ? r.rz[ir].t_s : inf;
            if (to <= tz && to <= tr) {
                const auto &o = r.odo[io++];
                if (o.kind == OdoRecord::Kind::Velocity) {
                    f << "V " << o.t_s << ' ' << o.a << ' ' << o.b << '\n';
                } else {
                    f << "O " << o.t_s << ' ' << o.a << ' ' << o.b << ' ' << o.c << '\n';
                }
            } else if (tz <= tr) {
                const auto &z = r.z[iz++];
                f << "Z " << z.t_s << ' ' << z.landmark_id << ' ' << z.range_m << ' ' << z.bearing_rad << '\n';
            } else {
                const auto &s = r.rz[ir++];
                f << "R " << s.t_s << ' ' << s.other_robot << ' ' << s.range_m << ' ' << s.bearing_rad << '\n';
            }
        }
        close_file(f, log_path);
        if (!r.truth.empty()) {
            const fs::path truth_path = d / ("robot" + std::to_string(r.id) + "_truth.txt");
            auto g = open(truth_path);
            g << "# t x y theta (world frame)\n";
            for (const auto &p : r.truth) {
                g << p.t_s << ' ' << p.pose.x << ' ' << p.pose.y << ' ' << p.pose.theta << '\n';
            }
            close_file(g, truth_path);
        }
    }
    if (!ds.landmarks.empty()) {
        const fs::path lm_path = d / "landmarks_truth.txt";
        auto f = open(lm_path);
        f << "# id x y (world frame)\n";
        for (const auto &l : ds.landmarks) {
            f << l.id << ' ' << l.pos.x << ' ' << l.pos.y << '\n';
        }
        close_file(f, lm_path);
    }
    const fs::path t0_path = d / "t0.txt";
    auto f = open(t0_path);
    f << "# absolute time of t = 0 in the source\n" << ds.t0_s << '\n';
    close_file(f, t0_path);
}

double dataset_begin_s(const Dataset &ds)
{
    double t = std::numeric_limits<double>::infinity();
    for (const auto &r : ds.robots) {
        if (!r.odo.empty()) {
            t = std::min(t, r.odo.front().t_s);
        }
        if (!r.z.empty()) {
            t = std::min(t, r.z.front().t_s);
        }
        if (!r.rz.empty()) {
            t = std::min(t, r.rz.front().t_s);
        }
    }
    return std::isfinite(t) ? t : 0.0;
}

double dataset_end_s(const Dataset &ds)
{
    double t = -std::numeric_limits<double>::infinity();
    for (const auto &r : ds.robots) {
        if (!r.odo.empty()) {
            t = std::max(t, r.odo.back().t_s);
        }
        if (!r.z.empty()) {
            t = std::max(t, r.z.back().t_s);
        }
        if (!r.rz.empty()) {
            t = std::max(t, r.rz.back().t_s);
        }
    }
    return std::isfinite(t) ? t : 0.0;
}

} // namespace coslam::replay
