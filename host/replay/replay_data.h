// host/replay/replay_data.h - recorded multi-robot landmark data, as the
// replay consumes it, and the readers that load it.
//
// Two sources are read into one Dataset:
//   - an MRCLAM folder (UTIAS Multi-Robot Cooperative Localization and
//     Mapping dataset, Leung et al., IJRR 2011): Barcodes.dat,
//     Landmark_Groundtruth.dat, RobotN_{Odometry,Measurement,Groundtruth}.dat;
//   - a folder in the generic landmark log format of ../shared/DESIGN.md
//     (docs/replay.md): robot<k>.log with O/V/Z/R records, optional
//     robot<k>_truth.txt (t x y theta) and landmarks_truth.txt (id x y).
// write_landmark_log() writes any Dataset in the generic format, so a
// converted MRCLAM folder replays bit for bit like the original.
//
// Times are seconds relative to Dataset::t0_s (the earliest stamp of the
// source, kept in t0_s), so the doubles keep sub-microsecond resolution.
//
// Errors: every reader throws ReplayError with "file:line: what" for a
// malformed line (wrong field count, not a number, NaN/Inf, negative range,
// unknown record type), a missing file, or a time stamp smaller than the
// previous one in the same file (equal stamps are fine: one camera frame
// holds several sightings). Expected oddities of real data are not errors:
// unknown barcodes (false detections) and sightings of the robot itself are
// counted in ParseReport and skipped.
#ifndef COSLAM_HOST_REPLAY_DATA_H
#define COSLAM_HOST_REPLAY_DATA_H

#include <cstdint>
#include <iosfwd>
#include <map>
#include <stdexcept>
#include <filesystem>
#include <string>
#include <vector>

#include "coslam/config.h"
#include "coslam/pose2.h"

namespace coslam::replay {

/// Input limits (docs/replay.md, "Limits"), checked before anything is
/// allocated for the input they bound: a file larger than kMaxInputFileBytes
/// is refused before it is read (MRCLAM's largest file is about 10 MB), a
/// line longer than kMaxLineBytes at that line; time stamps, relative to the
/// dataset's t0, must lie in [0, kMaxSpanS] (11.6 days: the replay keeps
/// per-period series, so the span bounds its memory); robot ids are
/// 1..kMaxRobotId (each replayed robot takes one of the core's
/// COSLAM_MAX_ROBOTS slots); bearings must lie in [-2 pi, 2 pi] (wrapped
/// to (-pi, pi] on reading).
inline constexpr unsigned long long kMaxInputFileBytes = 256ULL << 20;

/// Refuses what is not a regular file (a directory opens as an empty stream
/// and used to read as an empty file: "is a directory, not a <what>") and a
/// file beyond kMaxInputFileBytes, with ReplayError naming the path. Returns
/// false when the path does not exist (the caller says whether that is an
/// error).
bool check_input_file(const std::filesystem::path &p, const char *what);
inline constexpr std::size_t kMaxLineBytes = 4096;
inline constexpr double kMaxSpanS = 1e6;
inline constexpr int kMaxRobotId = COSLAM_MAX_ROBOTS;
/// Consecutive odometry records further apart than kOdoGapWarnS are counted
/// and warned about (the last command is held across the gap; MRCLAM
/// Datasets 1 and 6 have gaps of up to 1.33 s, nothing longer); a gap longer
/// than kMaxOdoGapS is refused at its line (a stray record days later).
inline constexpr double kOdoGapWarnS = 2.0;
inline constexpr double kMaxOdoGapS = 3600.0;

/// A value for a message: %.6g, so 1e308 is not 309 digits.
std::string fmt_value(double v);
/// Text from a file for a message: non-printable bytes as \xNN, at most 40
/// characters (then "...").
std::string printable(const std::string &s);

/// Error of a reader or of the configuration; what() is "file:line: reason"
/// when a line is at fault, else "file: reason".
class ReplayError : public std::runtime_error {
public:
    ReplayError(const std::string &file, long line, const std::string &reason);
    explicit ReplayError(const std::string &message) : std::runtime_error(message) {}
    const std::string &file() const { return file_; }
    long line() const { return line_; } ///< 0 when no line is at fault

private:
    std::string file_;
    long line_ = 0;
};

/// One odometry record. A velocity record holds (v, w) from its time until
/// the next record; an increment record (dx, dy, dtheta) is the motion since
/// the previous record (robot frame at the previous record).
struct OdoRecord {
    enum class Kind : uint8_t { Velocity, Increment };
    double t_s = 0.0;
    Kind kind = Kind::Velocity;
    double a = 0.0; ///< v [m/s] or dx [m]
    double b = 0.0; ///< w [rad/s] or dy [m]
    double c = 0.0; ///< unused or dtheta [rad]
};

/// A range-bearing sighting of a landmark. landmark_id is the true identity
/// (kept for evaluation and --known-ids), -1 when the source does not know it.
struct LandmarkSighting {
    double t_s = 0.0;
    int landmark_id = -1;
    double range_m = 0.0;
    double bearing_rad = 0.0;
};

/// A range-bearing sighting of another robot (its marker centre).
struct RobotSighting {
    double t_s = 0.0;
    int other_robot = 0;
    double range_m = 0.0;
    double bearing_rad = 0.0;
};

struct TruthPose {
    double t_s = 0.0;
    pose2_t pose{}; ///< world frame
};

struct RobotLog {
    int id = 0;                        ///< robot id of the source (MRCLAM: 1..5)
    std::vector<OdoRecord> odo;        ///< time-ordered
    std::vector<LandmarkSighting> z;   ///< time-ordered
    std::vector<RobotSighting> rz;     ///< time-ordered
    std::vector<TruthPose> truth;      ///< time-ordered, may be empty
    std::string source;                ///< file(s) read, for messages
};

struct LandmarkTruth {
    int id = 0;
    point2_t pos{}; ///< world frame [m]
};

/// Gaps of more than kOdoGapWarnS between one robot's odometry records.
struct OdoGaps {
    long count = 0;
    double max_s = 0.0;  ///< the largest
    std::string where;   ///< file:line of the record after the largest
};

/// What a reader skipped or noticed, for the log and metrics.json.
struct ParseReport {
    long unknown_barcode_rows = 0;          ///< MRCLAM rows whose barcode is not in Barcodes.dat
    std::map<int, long> unknown_barcodes;   ///< barcode -> rows
    long self_sightings = 0;                ///< a robot "sighting" itself (skipped)
    long lines_read = 0;
    long unknown_robot_sightings = 0;       ///< R records naming a robot the dataset does not have
    long unknown_subject_rows = 0;          ///< MRCLAM sightings of a subject neither robot nor true landmark
    std::vector<std::string> notes;         ///< human-readable remarks (missing truth, ...)
    std::map<int, OdoGaps> odo_gaps;        ///< robot id -> its odometry gaps (robots with any)
};

struct Dataset {
    std::string source;                ///< folder read
    std::string format;                ///< "mrclam" or "log"
    double t0_s = 0.0;                 ///< absolute time of t = 0 (MRCLAM: Unix time)
    std::vector<RobotLog> robots;      ///< by increasing id
    std::vector<LandmarkTruth> landmarks;
    ParseReport report;

    const RobotLog *robot(int id) const;
    const LandmarkTruth *landmark(int id) const;
};

enum class DataFormat { Auto, Mrclam, Log };

/// Read an MRCLAM folder. Robots are every N with RobotN_Odometry.dat present
/// (its Measurement file must exist too; a missing Groundtruth file is noted
/// and the robot is replayed without evaluation).
///
/// `only` (empty: every robot) names the robots to read; each must be in the
/// folder (else ReplayError listing the folder's robots). The files of the
/// others are not parsed, so a bad line there stops nothing; their robots
/// stay subjects (sightings of them are robot sightings, as in a full read)
/// and the first stamp of each of their files still enters t0, so a
/// selected robot's times are those of a full read, bit for bit. A first
/// line without a stamp is noted and left out of t0.
Dataset load_mrclam(const std::string &dir, const std::vector<int> &only = {});

/// Read a generic landmark-log folder (robot<k>.log, optional truth files);
/// `only` as for load_mrclam (t0 is the folder's t0.txt either way).
Dataset load_landmark_log(const std::string &dir, const std::vector<int> &only = {});

/// Detect the format (Barcodes.dat -> MRCLAM, robot*.log -> log) and read.
Dataset load_dataset(const std::string &dir, DataFormat format = DataFormat::Auto,
                     const std::vector<int> &only = {});

/// Write `ds` as a generic landmark-log folder (created if missing).
/// Velocity odometry becomes V records, increments O records.
void write_landmark_log(const Dataset &ds, const std::string &dir);

/// Parsers on streams (the folder readers use them; tests call them on
/// hand-written text). `name` is the file name used in error messages.
/// A landmark log is read into `out` (odo, z, rz of robot `out.id`).
void parse_landmark_log(std::istream &in, const std::string &name, RobotLog &out, ParseReport &report);
/// `t x y theta` rows.
std::vector<TruthPose> parse_truth_path(std::istream &in, const std::string &name);
/// `id x y` rows (extra columns, e.g. MRCLAM's standard deviations, ignored).
std::vector<LandmarkTruth> parse_truth_landmarks(std::istream &in, const std::string &name);

/// Earliest time stamp in the dataset and the latest [s] (relative).
double dataset_begin_s(const Dataset &ds);
double dataset_end_s(const Dataset &ds);

} // namespace coslam::replay

#endif
