// URG-04LX emulator: see urg_emulator.h for the model and its limits.
#include "urg/urg_emulator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace coslam::sim {

namespace {

constexpr uint32_t kMask24 = 0xFFFFFFu;
constexpr uint32_t kNonMeasurableCode = 19; // URG-04LX error table: "non-measurable step"
constexpr std::size_t kMaxCommandLine = 256;
constexpr double kPi = 3.14159265358979323846;

// Parse exactly s.size() decimal digits; -1 if any is not a digit.
long digits(const std::string &s)
{
    if (s.empty()) return -1;
    long v = 0;
    for (char c : s) {
        if (c < '0' || c > '9') return -1;
        v = v * 10 + (c - '0');
    }
    return v;
}

std::string dec(uint32_t v, int width)
{
    char buf[16];
    std::snprintf(buf, sizeof buf, "%0*u", width, v);
    return buf;
}

} // namespace

const hal_serial_ops_t UrgEmulator::kOps = {
    &UrgEmulator::op_set_baud, &UrgEmulator::op_write, &UrgEmulator::op_read,
    &UrgEmulator::op_flush_input, &UrgEmulator::op_close,
};

UrgEmulator::UrgEmulator(const UrgEmulatorConfig &cfg, RangeFn range_m)
    : cfg_(cfg), range_m_(std::move(range_m)), scip2_(cfg.start_in_scip2)
{
    if (!range_m_) throw std::invalid_argument("UrgEmulator: no range callback");
    if (cfg_.ares == 0 || cfg_.scan_rpm == 0 || cfg_.amin > cfg_.afrt || cfg_.afrt > cfg_.amax ||
        cfg_.amax > cfg_.max_step || cfg_.max_step > 9999 || cfg_.dmin_mm >= cfg_.dmax_mm ||
        cfg_.no_return_code >= cfg_.dmin_mm || cfg_.too_near_code >= cfg_.dmin_mm || !(cfg_.noise_sigma_m >= 0.0) ||
        !(cfg_.noise_rel >= 0.0))
        throw std::invalid_argument("UrgEmulator: inconsistent configuration");
    dev_.ops = &kOps;
    dev_.backend = this;
    rng_seed(&noise_rng_, cfg_.seed);
    rng_seed(&io_rng_, cfg_.seed ^ 0x9E3779B97F4A7C15ull);
    rng_seed(&fault_rng_, cfg_.seed ^ 0xD1B54A32D192ED03ull);
    rng_seed(&noise_line_rng_, cfg_.seed ^ 0x94D049BB133111EBull);
}

void UrgEmulator::set_unplugged(bool unplugged)
{
    if (unplugged && !unplugged_) {
        // power lost: everything in flight and all state is gone
        stats_.bytes_dropped += out_.size();
        out_.clear();
        in_.clear();
        md_active_ = false;
        laser_ = false;
        scip2_ = cfg_.start_in_scip2;
        delayed_.clear();
    }
    unplugged_ = unplugged;
}

void UrgEmulator::set_silent(bool silent)
{
    if (silent && !silent_) {
        for (const auto &d : delayed_) stats_.silent_bytes_lost += d.second.size();
        delayed_.clear(); // replies not yet on the wire are lost with it
        in_.clear();
    }
    silent_ = silent;
}

char UrgEmulator::sum(const std::string &s)
{
    unsigned v = 0;
    for (unsigned char c : s) v += c;
    return static_cast<char>((v & 0x3Fu) + 0x30u);
}

std::string UrgEmulator::encode(uint32_t v, int n)
{
    std::string out(static_cast<std::size_t>(n), '0');
    for (int i = 0; i < n; ++i) {
        out[static_cast<std::size_t>(i)] = static_cast<char>(((v >> (6 * (n - 1 - i))) & 0x3Fu) + 0x30u);
    }
    return out;
}

uint32_t UrgEmulator::timer_ms(uint64_t t_us) const
{
    return static_cast<uint32_t>((cfg_.timer_offset_ms + t_us / 1000u) & kMask24);
}

// ---------------------------------------------------------------------------
// The wire
// ---------------------------------------------------------------------------

hal_status_t UrgEmulator::op_set_baud(hal_serial_t *d, uint32_t baud)
{
    auto *self = static_cast<UrgEmulator *>(d->backend);
    if (self->closed_) return HAL_E_CLOSED;
    return baud > 0 ? HAL_OK : HAL_E_ARG; // USB-ACM: any rate
}

hal_status_t UrgEmulator::op_write(hal_serial_t *d, const uint8_t *data, size_t len, uint32_t)
{
    auto *self = static_cast<UrgEmulator *>(d->backend);
    if (self->closed_) return HAL_E_CLOSED;
    if (self->unplugged_) {
        self->stats_.unplugged_ops++;
        return HAL_E_IO;
    }
    if (self->silent_) {
        self->stats_.silent_bytes_lost += len; // written into a dead line
        return HAL_OK;
    }
    self->stats_.bytes_in += len;
    for (size_t i = 0; i < len; ++i) {
        const char c = static_cast<char>(data[i]);
        if (c == '\n' || c == '\r') {
            if (!self->in_.empty()) {
                const std::string line = self->in_;
                self->in_.clear();
                self->on_line(line);
            }
        } else if (self->in_.size() < kMaxCommandLine) {
            self->in_.push_back(c);
        }
    }
    return HAL_OK;
}

hal_status_t UrgEmulator::op_read(hal_serial_t *d, uint8_t *buf, size_t cap, size_t *n_read, uint32_t)
{
    auto *self = static_cast<UrgEmulator *>(d->backend);
    if (self->closed_) return HAL_E_CLOSED;
    if (self->unplugged_) {
        self->stats_.unplugged_ops++;
        return HAL_E_IO;
    }
    if (self->out_.empty()) return HAL_E_TIMEOUT; // simulated time does not pass in here
    size_t n = std::min(cap, self->out_.size());
    if (self->cfg_.max_read_chunk > 0) {
        const auto piece = 1u + rng_below(&self->io_rng_, static_cast<uint32_t>(self->cfg_.max_read_chunk));
        n = std::min<size_t>(n, piece);
    }
    for (size_t i = 0; i < n; ++i) {
        buf[i] = self->out_.front();
        self->out_.pop_front();
    }
    *n_read = n;
    return HAL_OK;
}

hal_status_t UrgEmulator::op_flush_input(hal_serial_t *d)
{
    auto *self = static_cast<UrgEmulator *>(d->backend);
    if (self->closed_) return HAL_E_CLOSED;
    self->stats_.bytes_dropped += self->out_.size();
    self->out_.clear();
    return HAL_OK;
}

void UrgEmulator::op_close(hal_serial_t *d)
{
    static_cast<UrgEmulator *>(d->backend)->closed_ = true;
}

void UrgEmulator::emit(const std::string &bytes)
{
    if (silent_) {
        stats_.silent_bytes_lost += bytes.size();
        return;
    }
    if (in_command_ && cfg_.reply_delay_us > 0) {
        delayed_.emplace_back(now_us_ + cfg_.reply_delay_us, bytes);
        return;
    }
    if (out_.size() + bytes.size() > cfg_.max_queued_bytes) {
        stats_.bytes_dropped += bytes.size();
        return;
    }
    out_.insert(out_.end(), bytes.begin(), bytes.end());
    stats_.bytes_out += bytes.size();
}

// ---------------------------------------------------------------------------
// Commands
// ---------------------------------------------------------------------------

void UrgEmulator::reply(const std::string &echo, const std::string &status, const std::string &body)
{
    emit(echo + "\n" + status + sum(status) + "\n" + body + "\n");
}

std::string UrgEmulator::info_lines(const std::vector<std::pair<std::string, std::string>> &kv) const
{
    std::string out;
    for (const auto &p : kv) {
        const std::string text = p.first + ":" + p.second;
        out += text + ";" + sum(text) + "\n"; // the ';' is not summed
    }
    return out;
}

void UrgEmulator::on_line(const std::string &line)
{
    stats_.commands++;
    run_until(now_us_);
    in_command_ = true;
    on_command(line);
    in_command_ = false;
}

void UrgEmulator::on_command(const std::string &line)
{
    if (!scip2_) {
        // SCIP 1.1 is not emulated beyond the switch command.
        if (line == "SCIP2.0") {
            scip2_ = true;
            emit("SCIP2.0\n0\n\n");
        } else {
            stats_.unknown_commands++;
        }
        return;
    }
    const std::string cmd = line.substr(0, line.find(';'));
    const std::string code = cmd.substr(0, 2);
    if (cmd == "VV") {
        reply(line, "00", info_lines({{"VEND", cfg_.vendor}, {"PROD", cfg_.product}, {"FIRM", cfg_.firmware},
                                      {"PROT", cfg_.protocol}, {"SERI", cfg_.serial}}));
    } else if (cmd == "PP") {
        reply(line, "00", info_lines({{"MODL", cfg_.model}, {"DMIN", std::to_string(cfg_.dmin_mm)},
                                      {"DMAX", std::to_string(cfg_.dmax_mm)}, {"ARES", std::to_string(cfg_.ares)},
                                      {"AMIN", std::to_string(cfg_.amin)}, {"AMAX", std::to_string(cfg_.amax)},
                                      {"AFRT", std::to_string(cfg_.afrt)}, {"SCAN", std::to_string(cfg_.scan_rpm)}}));
    } else if (cmd == "II") {
        char t[16];
        std::snprintf(t, sizeof t, "%06X", timer_ms(now_us_));
        reply(line, "00",
              info_lines({{"MODL", cfg_.model}, {"LASR", laser_ ? "ON" : "OFF"},
                          {"SCSP", "Initial(" + std::to_string(cfg_.scan_rpm) + "[rpm])"},
                          {"MESM", md_active_ ? "Measuring" : "IDLE"}, {"SBPS", "USB only"}, {"TIME", t},
                          {"STAT", "Sensor works well."}}));
    } else if (cmd == "BM") {
        reply(line, laser_ ? "02" : "00");
        laser_ = true;
    } else if (cmd == "QT" || cmd == "RS") {
        md_active_ = false;
        laser_ = false;
        reply(line, "00");
    } else if (code == "MD" || code == "GD") {
        handle_scan_cmd(line, code == "MD");
    } else {
        // includes "SCIP2.0" while already in SCIP 2.0
        stats_.unknown_commands++;
        reply(line, "0E");
    }
}

void UrgEmulator::handle_scan_cmd(const std::string &line, bool md)
{
    const std::size_t semi = line.find(';');
    const std::string cmd = line.substr(0, semi);
    if (cmd.size() != (md ? 15u : 12u)) {
        reply(line, "0C"); // insufficient / extra parameters
        return;
    }
    const long first = digits(cmd.substr(2, 4));
    const long last = digits(cmd.substr(6, 4));
    const long cluster = digits(cmd.substr(10, 2));
    const long interval = md ? digits(cmd.substr(12, 1)) : 0;
    const long scans = md ? digits(cmd.substr(13, 2)) : 0;
    const char *err = first < 0 ? "01" : last < 0 ? "02" : cluster < 0 ? "03" : interval < 0 ? "06" : scans < 0 ? "07"
                      : static_cast<uint32_t>(last) > cfg_.max_step ? "04"
                      : last < first ? "05"
                      : nullptr;
    if (err != nullptr) {
        reply(line, err);
        return;
    }
    ScanReq r;
    r.first = static_cast<uint32_t>(first);
    r.last = static_cast<uint32_t>(last);
    r.cluster = cluster == 0 ? 1u : static_cast<uint32_t>(cluster);
    if (!md) {
        if (!laser_) {
            reply(line, "10");
            return;
        }
        const uint64_t T = turn_us();
        const uint64_t done = now_us_ / T; // turns completed
        const ScanReq saved = md_req_;
        md_req_ = r;
        queue_scan(done > 0 ? done - 1 : 0, line, "00");
        md_req_ = saved;
        return;
    }
    reply(line, "00");
    md_req_ = r;
    md_prefix_ = cmd.substr(0, 13);
    md_suffix_ = semi == std::string::npos ? std::string() : line.substr(semi);
    md_skip_ = static_cast<uint32_t>(interval);
    md_total_ = static_cast<uint32_t>(scans);
    md_sent_ = 0;
    md_next_turn_ = (now_us_ + turn_us() - 1) / turn_us();
    md_active_ = true;
    laser_ = true;
}

// ---------------------------------------------------------------------------
// Scans
// ---------------------------------------------------------------------------

void UrgEmulator::set_time_us(uint64_t t_us)
{
    const uint64_t before = now_us_;
    if (t_us > now_us_) now_us_ = t_us;
    if (unplugged_) return;
    if (noise_bytes_per_ms_ > 0.0) {
        noise_carry_ += noise_bytes_per_ms_ * static_cast<double>(now_us_ - before) * 1e-3;
        std::string junk;
        while (noise_carry_ >= 1.0) {
            junk.push_back(static_cast<char>(rng_below(&noise_line_rng_, 256u)));
            noise_carry_ -= 1.0;
        }
        stats_.noise_bytes += junk.size();
        emit(junk);
    }
    while (!delayed_.empty() && delayed_.front().first <= now_us_) {
        emit(delayed_.front().second); // the replies due, before this step's scans
        delayed_.pop_front();
    }
    run_until(now_us_);
}

void UrgEmulator::run_until(uint64_t t_us)
{
    const uint64_t T = turn_us();
    while (md_active_ && (md_next_turn_ + 1) * T <= t_us) {
        const uint32_t remaining = md_total_ == 0 ? 0 : md_total_ - md_sent_ - 1;
        queue_scan(md_next_turn_, md_prefix_ + dec(remaining, 2) + md_suffix_, "99");
        md_sent_++;
        md_next_turn_ += md_skip_ + 1;
        if (md_total_ != 0 && md_sent_ >= md_total_) {
            md_active_ = false;
            laser_ = false; // MD switches the laser off after its last scan
        }
    }
}

uint32_t UrgEmulator::measure(uint32_t step)
{
    const double noise = rng_gauss(&noise_rng_); // one draw per step, always
    if (step < cfg_.amin || step > cfg_.amax) return kNonMeasurableCode;
    const double angle = (static_cast<double>(step) - cfg_.afrt) * 2.0 * kPi / cfg_.ares;
    const double r = range_m_(angle);
    if (!std::isfinite(r) || r < 0.0 || r * 1000.0 > cfg_.dmax_mm) return cfg_.no_return_code;
    const double sigma = std::max(cfg_.noise_sigma_m, cfg_.noise_rel * r);
    const long long mm = std::llround((r + sigma * noise) * 1000.0);
    if (mm < static_cast<long long>(cfg_.dmin_mm)) return cfg_.too_near_code;
    if (mm > static_cast<long long>(cfg_.dmax_mm)) return cfg_.no_return_code;
    return static_cast<uint32_t>(mm);
}

std::string UrgEmulator::scan_data(const ScanReq &r)
{
    std::string chars;
    for (uint32_t s = r.first; s <= r.last; s += r.cluster) {
        uint32_t best = 0;
        bool have_range = false;
        uint32_t first_code = 0;
        const uint32_t end = std::min(r.last, s + r.cluster - 1);
        for (uint32_t k = s; k <= end; ++k) {
            const uint32_t v = measure(k);
            if (v >= cfg_.dmin_mm) {
                if (!have_range || v < best) best = v;
                have_range = true;
            } else if (k == s) {
                first_code = v;
            }
        }
        chars += encode(have_range ? best : first_code, 3);
    }
    std::string lines;
    for (std::size_t off = 0; off < chars.size(); off += 64) {
        const std::string part = chars.substr(off, 64);
        lines += part + sum(part) + "\n";
    }
    return lines;
}

void UrgEmulator::queue_scan(uint64_t turn, const std::string &echo, const std::string &status)
{
    const std::string stamp = encode(timer_ms(turn * turn_us()), 4);
    std::string msg = echo + "\n" + status + sum(status) + "\n" + stamp + sum(stamp) + "\n" + scan_data(md_req_) + "\n";
    stats_.scans_sent++;
    emit(apply_fault(std::move(msg)));
}

std::string UrgEmulator::apply_fault(std::string msg)
{
    int kind = -1;
    if (!pending_faults_.empty()) {
        kind = static_cast<int>(pending_faults_.front());
        pending_faults_.pop_front();
    } else if (cfg_.p_bad_checksum > 0 || cfg_.p_truncated_line > 0 || cfg_.p_garbage > 0) {
        const double u = rng_uniform(&fault_rng_);
        if (u < cfg_.p_bad_checksum) kind = 0;
        else if (u < cfg_.p_bad_checksum + cfg_.p_truncated_line) kind = 1;
        else if (u < cfg_.p_bad_checksum + cfg_.p_truncated_line + cfg_.p_garbage) kind = 2;
    }
    if (kind < 0) return msg;
    stats_.faults[static_cast<std::size_t>(kind)]++;
    // split into lines (without their LF); the last entry is the empty line
    std::vector<std::string> lines;
    std::size_t start = 0;
    for (std::size_t i = 0; i < msg.size(); ++i) {
        if (msg[i] == '\n') {
            lines.push_back(msg.substr(start, i - start));
            start = i + 1;
        }
    }
    const std::size_t n_data = lines.size() >= 4 ? lines.size() - 4 : 0; // echo, status, stamp, ..., ""
    if (kind == 0 || kind == 1) {
        if (n_data == 0) return msg;
        std::string &l = lines[3 + rng_below(&fault_rng_, static_cast<uint32_t>(n_data))];
        if (kind == 0) {
            char &c = l.back();
            c = static_cast<char>(((c - 0x30) ^ 1) + 0x30); // another sum character
        } else {
            // keep 1..len-1 bytes: at least one byte lost, never an empty line
            l.resize(1 + rng_below(&fault_rng_, static_cast<uint32_t>(l.size() - 1)));
        }
    } else {
        // 1..8 bytes inside a non-empty line, the first outside ASCII, no LF
        std::string &l = lines[rng_below(&fault_rng_, static_cast<uint32_t>(lines.size() - 1))];
        const std::size_t at = rng_below(&fault_rng_, static_cast<uint32_t>(l.size()));
        std::string junk(1, static_cast<char>(0x80 + rng_below(&fault_rng_, 0x80)));
        const uint32_t extra = rng_below(&fault_rng_, 8);
        for (uint32_t i = 0; i < extra; ++i) {
            char c = '\n';
            while (c == '\n') c = static_cast<char>(1 + rng_below(&fault_rng_, 255));
            junk.push_back(c);
        }
        l.insert(at, junk);
    }
    std::string out;
    for (const auto &l : lines) out += l + "\n";
    return out;
}

} // namespace coslam::sim
