// libFuzzer target for coslam-replay's INI loader (host/replay/
// replay_config.cpp on libinih, with the shared [slam] key table of
// firmware/app/src/slam_params_ini.c).
//
// Input: the INI text. Seeds: corpus/fuzz_replay_config/ (host/replay/
// mrclam6.ini and small hand-written files); dictionary ini.dict.
//
// Properties checked, beyond "no crash, no ASan/UBSan report":
//  - the only exception is ReplayError (std::invalid_argument from stoi,
//    std::out_of_range, bad_alloc, ... are bugs);
//  - accepted: replay_config_validate() holds, every [slam] key is finite
//    and inside its domain, and every double of [filter], [input], [merge],
//    [eval], [odometry] and the per-robot overrides is finite (no NaN or
//    inf accepted into a config);
//  - accepted: replay_config_write() output loads back and writes the same
//    text again (the documented round trip).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>

#include "fuzz_check.h"
#include "app/slam_params_ini.h"
#include "replay_config.h"
#include "replay_data.h"

using namespace coslam::replay;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

namespace {

void require(bool ok, const char *what)
{
    fuzz_require(ok ? 1 : 0, what);
}

void finite(double v, const char *what)
{
    require(std::isfinite(v), what);
}

void check(const ReplayConfig &c)
{
    replay_config_validate(c); // throws ReplayError if not: caught as a bug below
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        const slam_params_ini_key_t *k = slam_params_ini_key(i);
        const double v = slam_params_ini_get(&c.slam, k);
        require(std::isfinite(v), "slam key finite");
        require(k->min_open ? v > k->min : v >= k->min, "slam key >= min");
        require(v <= k->max, "slam key <= max");
    }
    require(slam_params_validate(&c.slam) == COSLAM_OK, "slam_params_validate");
    finite(c.odo.scale_v, "odometry.scale_v");
    finite(c.odo.scale_w, "odometry.scale_w");
    finite(c.odo.delay_s, "odometry.delay_s");
    finite(c.filter.ess_fraction, "filter.ess_fraction");
    finite(c.filter.export_min_weight, "filter.export_min_weight");
    finite(c.filter.predict_period_s, "filter.predict_period_s");
    require(c.filter.particles > 0, "filter.particles > 0");
    finite(c.input.min_range_m, "input.min_range_m");
    finite(c.input.max_range_m, "input.max_range_m");
    finite(c.input.known_id_gate_rad, "input.known_id_gate_rad");
    finite(c.input.known_id_gate_chi2, "input.known_id_gate_chi2");
    finite(c.input.known_id_log_lik, "input.known_id_log_lik");
    finite(c.merge.window_s, "merge.window_s");
    finite(c.merge.interval_s, "merge.interval_s");
    finite(c.merge.max_range_m, "merge.max_range_m");
    finite(c.merge.resend_s, "merge.resend_s");
    finite(c.eval.gate_m, "eval.gate_m");
    finite(c.eval.map_period_s, "eval.map_period_s");
    finite(c.eval.pose_period_s, "eval.pose_period_s");
    for (const auto &kv : c.robot) {
        finite(kv.second.odo.scale_v, "robot odometry scale_v");
        finite(kv.second.odo.scale_w, "robot odometry scale_w");
        finite(kv.second.odo.delay_s, "robot odometry delay_s");
    }
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    // libinih reads a file line by line up to its first NUL
    std::string text(reinterpret_cast<const char *>(data), size);
    text = text.substr(0, text.find('\0'));
    ReplayConfig cfg = replay_config_default();
    try {
        replay_config_load_string(cfg, text, "fuzz.ini");
    } catch (const ReplayError &e) {
        require(e.line() >= 0, "error line >= 0");
        return 0;
    } catch (const std::exception &e) {
        std::fprintf(stderr, "unexpected exception (not ReplayError): %s\n", e.what());
        std::abort();
    }
    try {
        check(cfg);
        std::ostringstream a;
        replay_config_write(cfg, a);
        ReplayConfig back = replay_config_default();
        replay_config_load_string(back, a.str(), "written.ini");
        std::ostringstream b;
        replay_config_write(back, b);
        if (a.str() != b.str()) {
            std::fprintf(stderr, "round trip differs:\n--- first\n%s\n--- second\n%s\n", a.str().c_str(),
                         b.str().c_str());
            std::abort();
        }
    } catch (const std::exception &e) {
        std::fprintf(stderr, "accepted config fails validation or its round trip: %s\n", e.what());
        std::abort();
    }
    return 0;
}
