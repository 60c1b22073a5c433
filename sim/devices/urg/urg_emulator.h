// sim/devices/urg/urg_emulator.h - a Hokuyo URG-04LX on the wire.
//
// UrgEmulator is the sensor end of a serial line: serial() returns a
// hal_serial_t that the robot-side firmware (the urg_scip2 driver) uses as if
// it were /dev/ttyACM0. Bytes written to it are parsed as SCIP commands;
// replies are real SCIP 2.0 bytes (echo, status + sum, sum-checked lines,
// 3- and 4-character encodings, 64-character data lines, empty line).
//
// Time: the emulator has no clock of its own. The caller advances simulated
// time with set_time_us(); scans falling due up to that time are queued
// then. A read never waits: with nothing queued it returns HAL_E_TIMEOUT at
// once (the simulated time does not move inside a call).
//
// Scans: the motor turns at SCAN rpm (600: 100 ms a turn); turn k covers
// [k T, (k+1) T) from simulated time 0, its time stamp is the 24-bit
// millisecond timer at the turn's start ((timer_offset_ms + t/1000) mod
// 2^24, so a large offset exercises the wrap), and its message is queued at
// the end of the turn. MD streams every (interval+1)-th turn after the
// command; GD answers with the last completed turn. Ranges come from the
// caller's range_m(angle_rad) (angle in the sensor frame, counter-clockwise,
// 0 = front = step AFRT), plus seeded Gaussian noise of standard deviation
// max(noise_sigma_m, noise_rel * range), rounded to mm. A NaN/inf/too-far
// range is sent as error code no_return_code; too near as too_near_code;
// steps outside [AMIN, AMAX] as code 19 ("non-measurable step"). Clusters
// send the smallest non-error reading of their steps.
//
// Faults (for driver tests): a queued fault, or one drawn per scan with the
// configured probabilities, corrupts the next scan message: BadChecksum
// changes one data line's sum character; TruncatedLine cuts one data line
// short (bytes lost before its LF); Garbage inserts 1..8 random bytes (at
// least one outside printable ASCII, never LF) inside one line. Each costs
// the driver exactly that one scan.
//
// Reads can be chopped into random pieces (max_read_chunk) to exercise split
// reads; the chopping has its own RNG so it never changes the ranges.
#ifndef COSLAM_SIM_URG_EMULATOR_H
#define COSLAM_SIM_URG_EMULATOR_H

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "coslam/rng.h"
#include "hal/hal_serial.h"

namespace coslam::sim {

struct UrgEmulatorConfig {
    // PP parameters (URG-04LX)
    std::string model = "URG-04LX(Hokuyo Automatic Co.,Ltd.)";
    uint32_t dmin_mm = 20;
    uint32_t dmax_mm = 5600;
    uint32_t ares = 1024;
    uint32_t amin = 44;
    uint32_t amax = 725;
    uint32_t afrt = 384;
    uint32_t scan_rpm = 600;
    uint32_t max_step = 768; // largest step MD/GD accept
    // VV text
    std::string vendor = "Hokuyo Automatic Co.,Ltd.";
    std::string product = "SOKUIKI Sensor URG-04LX";
    std::string firmware = "3.1.00(18/Jan./2007)";
    std::string protocol = "SCIP 2.0";
    std::string serial = "H0614967";
    // start-up: SCIP 1.1 (only "SCIP2.0" is understood) or SCIP 2.0
    bool start_in_scip2 = false;
    // measurement model
    uint64_t seed = 1;
    double noise_sigma_m = 0.01; // [m]
    double noise_rel = 0.01;     // sigma per metre of range (URG-04LX: 1 % beyond 1 m)
    uint32_t no_return_code = 0; // sent for no return / beyond DMAX (code 0: "object beyond range")
    uint32_t too_near_code = 6;  // sent below DMIN (code 6: "others")
    uint32_t timer_offset_ms = 0;
    // faults: probability per scan message of each kind (at most one per scan)
    double p_bad_checksum = 0.0;
    double p_truncated_line = 0.0;
    double p_garbage = 0.0;
    // reads: 0 = as much as asked, else a random piece of 1..max_read_chunk bytes
    std::size_t max_read_chunk = 0;
    // queued output beyond this is dropped (counted), like a full USB buffer
    std::size_t max_queued_bytes = 1u << 20;
    // a command's reply comes this long after the command [us] (0: at once,
    // inside the write); keep it below one scan period (100 ms at 600 rpm)
    // so that an MD's acknowledgement precedes its first scan
    uint64_t reply_delay_us = 0;
};

enum class UrgFault : int { BadChecksum = 0, TruncatedLine = 1, Garbage = 2 };

class UrgEmulator {
public:
    using RangeFn = std::function<double(double angle_rad)>;

    struct Stats {
        uint64_t commands = 0;          // command lines received
        uint64_t unknown_commands = 0;  // answered "0E" (or ignored in SCIP 1.1)
        uint64_t scans_sent = 0;        // MD/GD scan messages queued
        std::array<uint64_t, 3> faults{}; // injected, by UrgFault
        uint64_t bytes_in = 0;
        uint64_t bytes_out = 0;
        uint64_t bytes_dropped = 0;     // output lost to max_queued_bytes or flush
        uint64_t noise_bytes = 0;       // random bytes put on the line (set_line_noise)
        uint64_t unplugged_ops = 0;     // reads/writes refused while unplugged (HAL_E_IO)
        uint64_t silent_bytes_lost = 0; // both ways while the line was silent (set_silent)
    };

    UrgEmulator(const UrgEmulatorConfig &cfg, RangeFn range_m);
    UrgEmulator(const UrgEmulator &) = delete;
    UrgEmulator &operator=(const UrgEmulator &) = delete;

    /// The robot-side end of the line (valid for the emulator's lifetime).
    hal_serial_t *serial() { return &dev_; }

    /// Advance simulated time to t_us (never backwards: earlier values are
    /// ignored) and queue every scan that completed by then.
    void set_time_us(uint64_t t_us);
    void advance_us(uint64_t dt_us) { set_time_us(now_us_ + dt_us); }
    uint64_t time_us() const { return now_us_; }

    /// Fault: unplug (true): the serial device errors (reads and writes
    /// HAL_E_IO, like the tty of a removed USB device), queued output is
    /// lost and the sensor loses power. Replug (false): a fresh sensor in
    /// its start-up state (start_in_scip2, laser off, no MD) that the
    /// driver has to connect again.
    void set_unplugged(bool unplugged);
    bool unplugged() const { return unplugged_; }
    /// Fault: the line goes silent (true), as a cut RS-232 cable or a
    /// sensor hung behind a live USB adapter: the port stays open, what
    /// the driver writes is lost and nothing comes back (the sensor's scans
    /// and replies meanwhile are lost too). Restored (false): the sensor as
    /// it was (an MD still running keeps streaming).
    void set_silent(bool silent);
    bool silent() const { return silent_; }
    /// Fault: put bytes_per_ms random bytes (any value, LF included) on the
    /// line per millisecond of simulated time, between and inside the
    /// sensor's messages (a noisy cable); 0 = off. Own seeded RNG.
    void set_line_noise(double bytes_per_ms) { noise_bytes_per_ms_ = bytes_per_ms > 0.0 ? bytes_per_ms : 0.0; }
    /// Corrupt the next scan message with `f` (queued faults come first).
    void inject(UrgFault f) { pending_faults_.push_back(f); }

    /// The 24-bit sensor timer at simulated time t [ms].
    uint32_t timer_ms(uint64_t t_us) const;
    /// Rotation period [us].
    uint64_t turn_us() const { return 60000000ull / cfg_.scan_rpm; }

    const Stats &stats() const { return stats_; }
    const UrgEmulatorConfig &config() const { return cfg_; }
    bool scip2() const { return scip2_; }
    bool laser_on() const { return laser_; }
    bool streaming() const { return md_active_; }
    std::size_t queued_bytes() const { return out_.size(); }

    /// SCIP sum character of a text (public for tests).
    static char sum(const std::string &s);
    /// n-character SCIP encoding of v (n = 2, 3, 4).
    static std::string encode(uint32_t v, int n);

private:
    struct ScanReq {
        uint32_t first = 0, last = 0, cluster = 1;
    };

    // hal_serial_t ops
    static hal_status_t op_set_baud(hal_serial_t *d, uint32_t baud);
    static hal_status_t op_write(hal_serial_t *d, const uint8_t *data, size_t len, uint32_t timeout_us);
    static hal_status_t op_read(hal_serial_t *d, uint8_t *buf, size_t cap, size_t *n_read, uint32_t timeout_us);
    static hal_status_t op_flush_input(hal_serial_t *d);
    static void op_close(hal_serial_t *d);
    static const hal_serial_ops_t kOps;

    void on_line(const std::string &line);
    void on_command(const std::string &line);
    void reply(const std::string &echo, const std::string &status, const std::string &body = std::string());
    std::string info_lines(const std::vector<std::pair<std::string, std::string>> &kv) const;
    void handle_scan_cmd(const std::string &line, bool md);
    void queue_scan(uint64_t turn, const std::string &echo, const std::string &status);
    std::string scan_data(const ScanReq &r);
    uint32_t measure(uint32_t step);
    std::string apply_fault(std::string msg);
    void emit(const std::string &bytes);
    void run_until(uint64_t t_us);

    UrgEmulatorConfig cfg_;
    RangeFn range_m_;
    hal_serial_t dev_;
    rng_t noise_rng_;
    rng_t io_rng_;
    rng_t fault_rng_;
    std::deque<uint8_t> out_;
    std::string in_;
    bool closed_ = false;
    bool scip2_;
    bool laser_ = false;
    uint64_t now_us_ = 0;
    // MD state
    bool md_active_ = false;
    ScanReq md_req_;
    std::string md_prefix_; // "MDssssddddcci"
    std::string md_suffix_; // ";string" echoed back, if any
    uint32_t md_skip_ = 0;  // interval
    uint32_t md_total_ = 0; // 0: unlimited
    uint32_t md_sent_ = 0;
    uint64_t md_next_turn_ = 0;
    std::deque<UrgFault> pending_faults_;
    Stats stats_;
    bool unplugged_ = false;
    bool silent_ = false;
    bool in_command_ = false; // on_line runs: its output is a reply (reply_delay_us)
    std::deque<std::pair<uint64_t, std::string>> delayed_; // replies and when they come
    double noise_bytes_per_ms_ = 0.0;
    double noise_carry_ = 0.0;
    rng_t noise_line_rng_;
};

} // namespace coslam::sim

#endif
