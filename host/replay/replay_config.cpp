// host/replay/replay_config.cpp - defaults and the INI reader/writer.
#include "replay_config.h"

#include <ini.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <iomanip>
#include <memory>
#include <ostream>
#include <sstream>
#include <vector>

#include "app/slam_params_ini.h"
#include "mrclam_model.h"
#include "replay_data.h"

namespace coslam::replay {

FilterKind filter_kind_from_string(const std::string &s)
{
    if (s == "fastslam1" || s == "fs1") {
        return FilterKind::FastSlam1;
    }
    if (s == "fastslam2" || s == "fs2") {
        return FilterKind::FastSlam2;
    }
    if (s == "ekf" || s == "ekfslam") {
        return FilterKind::Ekf;
    }
    throw ReplayError("unknown filter '" + s + "' (expected fastslam1, fastslam2 or ekf)");
}

const char *filter_kind_name(FilterKind k)
{
    switch (k) {
    case FilterKind::FastSlam1:
        return "fastslam1";
    case FilterKind::FastSlam2:
        return "fastslam2";
    case FilterKind::Ekf:
        return "ekf";
    }
    return "?";
}

FilterKind ReplayConfig::filter_of(int id) const
{
    const auto it = robot.find(id);
    return it != robot.end() && it->second.has_filter ? it->second.filter : filter.type;
}

OdoModel ReplayConfig::odo_of(int id) const
{
    const auto it = robot.find(id);
    return it != robot.end() && it->second.has_odo ? it->second.odo : odo;
}

ReplayConfig replay_config_default()
{
    // Fitted to MRCLAM Dataset 6 (docs/replay.md, "Parameters"): measured
    // sensor statistics, then a search over the filter's gates with EKF-SLAM
    // on the five single-robot replays.
    ReplayConfig c;
    c.slam = mrclam_slam_params(); // host/synth/mrclam_model.c, each value's reason there

    c.filter.type = FilterKind::Ekf;
    c.filter.particles = 100;
    // velocity-command odometry: mean of the five robots' fits
    c.odo = {0.93, 0.93, 0.24};
    // sightings beyond 6 m (range sd > 0.5 m) confused the association
    c.input.max_range_m = 6.0;
    // merging: duplicates gated at 50 (7 sigma): the two maps carry
    // different drift; only landmarks the sender saw 10 times are imported
    c.merge.core.gate_chi2 = 50.0;
    c.merge.core.min_obs = 10;
    // the sender's possible motion between the two sightings
    c.merge.core.peer_speed_mps = 0.2;
    c.merge.core.peer_turn_radps = 0.5;
    // evaluation: landmark clusters are 1.5 m or more apart
    c.eval.gate_m = 1.0;
    return c;
}

namespace {

// A value outside its key's domain: the message is complete as it is.
struct DomainError : std::invalid_argument {
    using std::invalid_argument::invalid_argument;
};

struct Key {
    std::string section;
    std::string key;
    std::function<void(const std::string &)> set; // throws std::invalid_argument with the reason
    std::function<std::string()> get;
};

// Shortest decimal text that reads back as exactly v.
std::string fmt(double v)
{
    for (int prec = 6; prec <= 17; ++prec) {
        std::ostringstream os;
        os << std::setprecision(prec) << v;
        if (std::strtod(os.str().c_str(), nullptr) == v) {
            return os.str();
        }
    }
    return std::to_string(v);
}

std::string fmt_float(float v)
{
    for (int prec = 6; prec <= 9; ++prec) {
        std::ostringstream os;
        os << std::setprecision(prec) << static_cast<double>(v);
        if (static_cast<float>(std::strtod(os.str().c_str(), nullptr)) == v) {
            return os.str();
        }
    }
    return std::to_string(v);
}

double parse_double(const std::string &s)
{
    errno = 0;
    char *end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    // ERANGE also flags an underflow to a subnormal or zero, which is a
    // finite value: "4.94066e-324" is what this file writes for 0x1p-1074
    // (fuzz_replay_config's round trip); an overflow is +-HUGE_VAL (inf)
    if (end == s.c_str() || *end != '\0' || (errno == ERANGE && std::fabs(v) >= HUGE_VAL) || !std::isfinite(v)) {
        throw std::invalid_argument("not a finite number: '" + s + "'");
    }
    return v;
}

long parse_long(const std::string &s, long lo, long hi)
{
    const double v = parse_double(s);
    if (v != std::floor(v) || v < static_cast<double>(lo) || v > static_cast<double>(hi)) {
        throw std::invalid_argument("expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                                    "], got '" + s + "'");
    }
    return static_cast<long>(v);
}

bool parse_bool(const std::string &s)
{
    if (s == "1" || s == "true" || s == "yes" || s == "on") {
        return true;
    }
    if (s == "0" || s == "false" || s == "no" || s == "off") {
        return false;
    }
    throw std::invalid_argument("expected a boolean (0/1, true/false), got '" + s + "'");
}

Key dkey(const char *sec, const char *key, double *v)
{
    return {sec, key, [v](const std::string &s) { *v = parse_double(s); }, [v] { return fmt(*v); }};
}

template <typename T> Key ikey(const char *sec, const char *key, T *v, long lo, long hi)
{
    return {sec, key, [v, lo, hi](const std::string &s) { *v = static_cast<T>(parse_long(s, lo, hi)); },
            [v] { return std::to_string(static_cast<long long>(*v)); }};
}

Key bkey(const char *sec, const char *key, bool *v)
{
    return {sec, key, [v](const std::string &s) { *v = parse_bool(s); }, [v] { return std::string(*v ? "1" : "0"); }};
}

// [slam]: the one key table of slam_params_t (app/slam_params_ini.h), shared
// with coslam-robot: same names, same parser, same domains.
Key slam_key(slam_params_t *p, const slam_params_ini_key_t *k)
{
    return {"slam", k->name,
            [p, k](const std::string &s) {
                char msg[160];
                const coslam_status_t st = slam_params_ini_set(p, k->name, s.c_str(), msg, sizeof msg);
                if (st == COSLAM_E_ARG) {
                    throw DomainError(std::string("invalid configuration: [slam] ") + k->name + ": " + msg);
                }
                if (st != COSLAM_OK) {
                    throw std::invalid_argument(msg);
                }
            },
            [p, k] {
                const double v = slam_params_ini_get(p, k);
                return k->type == SLAM_PARAMS_INI_FLOAT ? fmt_float(static_cast<float>(v)) : fmt(v);
            }};
}

std::vector<Key> keys_of(ReplayConfig &c)
{
    std::vector<Key> k;
    for (size_t i = 0; i < slam_params_ini_count(); ++i) {
        k.push_back(slam_key(&c.slam, slam_params_ini_key(i)));
    }
    std::vector<Key> rest = {
        dkey("odometry", "scale_v", &c.odo.scale_v),
        dkey("odometry", "scale_w", &c.odo.scale_w),
        dkey("odometry", "delay_s", &c.odo.delay_s),
        {"filter", "type", [&c](const std::string &s) { c.filter.type = filter_kind_from_string(s); },
         [&c] { return std::string(filter_kind_name(c.filter.type)); }},
        ikey("filter", "particles", &c.filter.particles, 1, COSLAM_MAX_PARTICLES),
        dkey("filter", "ess_fraction", &c.filter.ess_fraction),
        dkey("filter", "export_min_weight", &c.filter.export_min_weight),
        dkey("filter", "closure_drift_ratio", &c.filter.closure_drift_ratio),
        ikey("filter", "closure_gap", &c.filter.closure_gap, 0, 65535),
        dkey("filter", "closure_ambiguity_ll", &c.filter.closure_ambiguity_ll),
        dkey("filter", "closure_misses_per_support", &c.filter.closure_misses_per_support),
        dkey("filter", "closure_chance_max", &c.filter.closure_chance_max),
        ikey("filter", "closure_unsupported_every", &c.filter.closure_unsupported_every, 0, 65535),
        {"filter", "assoc",
         [&c](const std::string &s) {
             if (s == "jcbb") {
                 c.filter.assoc = EKFSLAM_ASSOC_JCBB;
             } else if (s == "nn") {
                 c.filter.assoc = EKFSLAM_ASSOC_NN;
             } else {
                 throw std::invalid_argument("expected jcbb or nn, got '" + s + "'");
             }
         },
         [&c] { return std::string(c.filter.assoc == EKFSLAM_ASSOC_JCBB ? "jcbb" : "nn"); }},
        ikey("filter", "jcbb_max_nodes", &c.filter.jcbb_max_nodes, 1, 100000000),
        ikey("filter", "fej", &c.filter.fej, 0, 1),
        ikey("filter", "iekf_max_iters", &c.filter.iekf_max_iters, 0, 255),
        dkey("filter", "nis_inflate", &c.filter.nis_inflate),
        ikey("filter", "active_spread_madds", &c.filter.active_spread_madds, 0, 4294967295L),
        ikey("filter", "mh_frames", &c.filter.mh_frames, 0, 100000),
        ikey("filter", "seed", &c.filter.seed, 0, 2000000000),
        dkey("filter", "predict_period_s", &c.filter.predict_period_s),
        dkey("input", "min_range_m", &c.input.min_range_m),
        dkey("input", "max_range_m", &c.input.max_range_m),
        dkey("input", "known_id_gate_rad", &c.input.known_id_gate_rad),
        dkey("input", "known_id_gate_chi2", &c.input.known_id_gate_chi2),
        dkey("input", "known_id_log_lik", &c.input.known_id_log_lik),
        bkey("merge", "enabled", &c.merge.enabled),
        dkey("merge", "window_s", &c.merge.window_s),
        dkey("merge", "interval_s", &c.merge.interval_s),
        dkey("merge", "gate_chi2", &c.merge.core.gate_chi2),
        dkey("merge", "grid_cell_m", &c.merge.core.grid_cell_m),
        ikey("merge", "transform_uncertainty", &c.merge.core.transform_uncertainty, 0, 1),
        ikey("merge", "reweight_particles", &c.merge.core.reweight_particles, 0, 1),
        ikey("merge", "min_obs", &c.merge.core.min_obs, 0, 65535),
        dkey("merge", "range_check_chi2", &c.merge.core.range_check_chi2),
        dkey("merge", "sender_speed_mps", &c.merge.core.peer_speed_mps),
        dkey("merge", "sender_turn_radps", &c.merge.core.peer_turn_radps),
        dkey("merge", "max_range_m", &c.merge.max_range_m),
        ikey("merge", "export_min_obs", &c.merge.export_min_obs, 1, 65535),
        ikey("merge", "max_sends", &c.merge.max_sends, 0, 255),
        dkey("merge", "resend_s", &c.merge.resend_s),
        ikey("merge", "check", &c.merge.core.check, 0, 1),
        dkey("merge", "fuse_eff_pairs", &c.merge.core.fuse_eff_pairs),
        ikey("merge", "refine_iters", &c.merge.core.refine_iters, 0, 50),
        dkey("merge", "refine_eff_pairs", &c.merge.core.refine_eff_pairs),
        dkey("merge", "agree_z", &c.merge.core.agree_z),
        ikey("merge", "veto_looks", &c.merge.core.veto_looks, 0, 65535),
        dkey("merge", "max_contradict_fraction", &c.merge.core.max_contradict_fraction),
        dkey("merge", "ambiguous_chi2", &c.merge.core.ambiguous_chi2),
        dkey("merge", "unresolved_chi2", &c.merge.core.unresolved_chi2),
        dkey("merge", "refute_sd_factor", &c.merge.core.refute_sd_factor),
        dkey("merge", "lost_sd_factor", &c.merge.core.lost_sd_factor),
        ikey("merge", "step_units", &c.merge.core.step_units, 0, 4294967295L),
        dkey("eval", "gate_m", &c.eval.gate_m),
        ikey("eval", "min_seen", &c.eval.min_seen, 0, 1000000),
        dkey("eval", "map_period_s", &c.eval.map_period_s),
        dkey("eval", "pose_period_s", &c.eval.pose_period_s),
        ikey("eval", "pose_fit_min_matched", &c.eval.pose_fit_min_matched, 2, 1000000),
        ikey("eval", "pose_fit_max_landmarks", &c.eval.pose_fit_max_landmarks, 0, 1000000),
    };
    k.insert(k.end(), rest.begin(), rest.end());
    return k;
}

struct LoadState {
    ReplayConfig *cfg;
    std::vector<Key> keys;
    std::string error;
};

int on_ini(void *user, const char *section, const char *name, const char *value)
{
    auto *st = static_cast<LoadState *>(user);
    const std::string sec(section);
    const std::string key(name);
    const std::string val(value);
    try {
        if (sec.rfind("robot", 0) == 0) {
            const long id = parse_long(sec.substr(5), 0, 1000000);
            RobotOverride &o = st->cfg->robot[static_cast<int>(id)];
            if (key == "filter") {
                o.filter = filter_kind_from_string(val);
                o.has_filter = true;
                return 1;
            }
            if (key == "scale_v" || key == "scale_w" || key == "delay_s") {
                if (!o.has_odo) {
                    o.odo = st->cfg->odo;
                    o.has_odo = true;
                }
                const double v = parse_double(val);
                (key == "scale_v" ? o.odo.scale_v : key == "scale_w" ? o.odo.scale_w : o.odo.delay_s) = v;
                return 1;
            }
            st->error = "unknown key '" + key + "' in [" + sec + "] (filter, scale_v, scale_w, delay_s)";
            return 0;
        }
        for (const auto &k : st->keys) {
            if (k.section == sec && k.key == key) {
                k.set(val);
                return 1;
            }
        }
        st->error = "unknown key '" + key + "' in [" + sec + "]";
    } catch (const DomainError &e) {
        st->error = e.what();
    } catch (const std::exception &e) {
        st->error = "[" + sec + "] " + key + ": " + e.what();
    }
    return 0;
}

void check_result(const LoadState &st, int rc, const std::string &name)
{
    if (rc == -1) {
        throw ReplayError(name, 0, "cannot open the config file");
    }
    if (rc == -2) {
        throw ReplayError(name, 0, "out of memory while reading the config");
    }
    if (rc > 0) {
        throw ReplayError(name, rc, st.error.empty() ? "INI syntax error" : st.error);
    }
}

} // namespace

void replay_config_load(ReplayConfig &cfg, const std::string &path)
{
    // a directory opens and reads as an empty file (fgets fails, which the
    // INI reader takes for the end): refused, as is a read error
    if (!check_input_file(path, "config file")) {
        throw ReplayError(path, 0, "cannot open the config file: no such file");
    }
    struct Closer {
        void operator()(std::FILE *f) const { std::fclose(f); }
    };
    const std::unique_ptr<std::FILE, Closer> f(std::fopen(path.c_str(), "r"));
    if (!f) {
        throw ReplayError(path, 0, std::string("cannot open the config file: ") + std::strerror(errno));
    }
    LoadState st{&cfg, keys_of(cfg), {}};
    errno = 0;
    const int rc = ini_parse_file(f.get(), on_ini, &st);
    if (std::ferror(f.get()) != 0) {
        const int err = errno;
        throw ReplayError(path, 0, std::string("read error: ") + (err != 0 ? std::strerror(err) : "I/O error"));
    }
    check_result(st, rc, path);
    replay_config_validate(cfg);
}

void replay_config_load_string(ReplayConfig &cfg, const std::string &text, const std::string &name)
{
    LoadState st{&cfg, keys_of(cfg), {}};
    check_result(st, ini_parse_string(text.c_str(), on_ini, &st), name);
    replay_config_validate(cfg);
}

void replay_config_write(const ReplayConfig &cfg_in, std::ostream &out)
{
    ReplayConfig cfg = cfg_in;
    const auto keys = keys_of(cfg);
    std::string sec;
    out << "; coslam-replay configuration (docs/replay.md explains every value)\n";
    for (const auto &k : keys) {
        if (k.section != sec) {
            sec = k.section;
            out << "\n[" << sec << "]\n";
        }
        out << k.key << " = " << k.get() << "\n";
    }
    for (const auto &[id, o] : cfg.robot) {
        out << "\n[robot" << id << "]\n";
        if (o.has_filter) {
            out << "filter = " << filter_kind_name(o.filter) << "\n";
        }
        if (o.has_odo) {
            out << "scale_v = " << fmt(o.odo.scale_v) << "\nscale_w = " << fmt(o.odo.scale_w)
                << "\ndelay_s = " << fmt(o.odo.delay_s) << "\n";
        }
    }
}

void replay_config_validate(const ReplayConfig &c)
{
    auto bad = [](const std::string &what) { throw ReplayError("invalid configuration: " + what); };
    if (slam_params_validate(&c.slam) != COSLAM_OK) {
        bad("[slam] parameters out of their domain (slam_params_validate: variances >= 0, sighting noise > 0, "
            "max range > min range, 0 < fov <= 2 pi, 0 < margin <= 1, new_landmark_chi2 >= gate_chi2, "
            "exist_init <= exist_confirm <= exist_max, exist_miss_confirmed >= 0, exist_miss_bearing_sd_frac > 0)");
    }
    auto odo_ok = [](const OdoModel &m) {
        return m.scale_v > 0.0 && m.scale_w > 0.0 && std::fabs(m.delay_s) <= 5.0;
    };
    if (!odo_ok(c.odo)) {
        bad("[odometry] scales must be > 0 and |delay_s| <= 5");
    }
    for (const auto &[id, o] : c.robot) {
        if (o.has_odo && !odo_ok(o.odo)) {
            bad("[robot" + std::to_string(id) + "] scales must be > 0 and |delay_s| <= 5");
        }
    }
    if (!(c.filter.ess_fraction > 0.0 && c.filter.ess_fraction <= 1.0)) {
        bad("[filter] ess_fraction must be in (0, 1]");
    }
    if (!(c.filter.export_min_weight > 0.0 && c.filter.export_min_weight <= 1.0)) {
        bad("[filter] export_min_weight must be in (0, 1]");
    }
    if (!(c.filter.closure_drift_ratio >= 0.0 && c.filter.closure_drift_ratio < 1e12 &&
          c.filter.closure_ambiguity_ll >= 0.0 && c.filter.closure_ambiguity_ll < 1e12 &&
          c.filter.closure_misses_per_support >= 0.0 && c.filter.closure_misses_per_support < 1e12 &&
          c.filter.closure_chance_max >= 0.0 && c.filter.closure_chance_max < 1e12)) {
        bad("[filter] closure_drift_ratio, closure_ambiguity_ll, closure_misses_per_support and closure_chance_max must "
            "be finite and >= 0");
    }
    if (!(c.filter.nis_inflate >= 0.0 && c.filter.nis_inflate < 1e6)) {
        bad("[filter] nis_inflate must be in [0, 1e6) (0: off)");
    }
    // the periods bound the replay's loops: a period too small for its
    // clock (1e-300 s added to 100 s) stopped the run from advancing, and
    // the map series (one score per map_period_s) grew without bound
    if (!(c.filter.predict_period_s >= kMinPredictPeriodS && c.filter.predict_period_s <= kMaxPredictPeriodS)) {
        bad("[filter] predict_period_s = " + fmt_value(c.filter.predict_period_s) + " outside [" +
            fmt_value(kMinPredictPeriodS) + ", " + fmt_value(kMaxPredictPeriodS) + "] s");
    }
    if (!(c.input.min_range_m >= 0.0 && c.input.max_range_m > c.input.min_range_m)) {
        bad("[input] need 0 <= min_range_m < max_range_m");
    }
    if (!(c.input.known_id_gate_rad >= 0.0)) {
        bad("[input] known_id_gate_rad must be >= 0");
    }
    if (!(c.input.known_id_gate_chi2 > 0.0)) {
        bad("[input] known_id_gate_chi2 must be > 0");
    }
    if (!(c.merge.window_s >= 0.0 && c.merge.interval_s >= 0.0)) {
        bad("[merge] window_s and interval_s must be >= 0");
    }
    if (!(c.merge.core.gate_chi2 > 0.0 && c.merge.core.grid_cell_m > 0.0 && c.merge.core.range_check_chi2 >= 0.0)) {
        bad("[merge] gate_chi2 and grid_cell_m must be > 0, range_check_chi2 >= 0");
    }
    if (!(c.merge.core.peer_speed_mps >= 0.0 && c.merge.core.peer_turn_radps >= 0.0)) {
        bad("[merge] sender_speed_mps and sender_turn_radps must be >= 0");
    }
    if (!(c.merge.max_range_m > 0.0 && std::isfinite(c.merge.max_range_m) && c.merge.window_s > 0.0 &&
          c.merge.window_s < 4000.0 && c.merge.interval_s < 4000.0 && c.merge.resend_s >= 0.001 &&
          c.merge.resend_s < 4000.0)) {
        bad("[merge] max_range_m must be finite and > 0, 0 < window_s < 4000, interval_s < 4000, "
            "0.001 <= resend_s < 4000 (0 sent the whole budget in consecutive frames)");
    }
    if (!(std::isfinite(c.merge.core.agree_z) && c.merge.core.max_contradict_fraction >= 0.0 &&
          c.merge.core.max_contradict_fraction <= 1.0 && c.merge.core.ambiguous_chi2 >= 0.0 &&
          c.merge.core.unresolved_chi2 >= 0.0 && std::isfinite(c.merge.core.refute_sd_factor) &&
          c.merge.core.refute_sd_factor >= 0.0 && std::isfinite(c.merge.core.lost_sd_factor) &&
          c.merge.core.lost_sd_factor >= 0.0)) {
        bad("[merge] agree_z must be finite, 0 <= max_contradict_fraction <= 1, ambiguous_chi2 >= 0, "
            "unresolved_chi2 >= 0, refute_sd_factor and lost_sd_factor finite and >= 0");
    }
    if (!(c.eval.gate_m > 0.0)) {
        bad("[eval] gate_m must be > 0");
    }
    if (!(c.eval.map_period_s >= kMinMapPeriodS && c.eval.map_period_s <= kMaxEvalPeriodS)) {
        bad("[eval] map_period_s = " + fmt_value(c.eval.map_period_s) + " outside [" + fmt_value(kMinMapPeriodS) +
            ", " + fmt_value(kMaxEvalPeriodS) + "] s");
    }
    if (!(c.eval.pose_period_s >= kMinPosePeriodS && c.eval.pose_period_s <= kMaxEvalPeriodS)) {
        bad("[eval] pose_period_s = " + fmt_value(c.eval.pose_period_s) + " outside [" + fmt_value(kMinPosePeriodS) +
            ", " + fmt_value(kMaxEvalPeriodS) + "] s");
    }
}

} // namespace coslam::replay
