// host/replay/replay_run.cpp - the replay loop, meetings, evaluation.
#include "replay_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <set>

#include "app/meeting.h"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_link.hpp"
#include "coslam/motion.h"
#include "coslam/observe.h"
#include "replay_filter.h"
#include "replay_odometry.h"

namespace coslam::replay {

namespace {

using Clock = std::chrono::steady_clock;

double us_since(Clock::time_point t0)
{
    return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
}

struct Frame {
    double t_s;
    std::vector<int> zi; // indices into RobotLog::z
    std::vector<int> ri; // indices into RobotLog::rz
};

struct Robot {
    const RobotLog *log = nullptr;
    int idx = 0;
    uint8_t core_id = 0;
    std::unique_ptr<OdoTrack> odo;
    std::unique_ptr<TruthTrack> truth;
    std::unique_ptr<RobotFilter> filter;
    std::vector<Frame> frames;
    double t_filter = 0.0;
    double next_tick = 0.0;
    double next_pose_t = 0.0;
    long pose_tick = 0;   ///< pose samples so far
    long path_stride = 1; ///< every path_stride-th sample is recorded
    double next_map_t = 0.0;
    double pending_us = 0.0;
    double step_us_sum = 0.0;
    std::unique_ptr<meeting_t> meeting;  // the robot's meeting protocol
    hal_link_t *link = nullptr;
    // a merge whose check waits for the own export in parts (meeting_t
    // merge_waiting): the map before it, for its event when it comes
    struct Waiting {
        uint8_t peer = 0;
        uint32_t seq = 0;
        MapScore before;
        std::shared_ptr<map_whole_t> before_map;
        double merge_us = 0.0;
    };
    std::optional<Waiting> waiting;
    // a merge whose map after it is not scored yet (an EKF-SLAM merge in
    // parts still running): its event and the map before it
    struct AfterPending {
        size_t event = 0;
        std::shared_ptr<map_whole_t> before_map;
    };
    std::optional<AfterPending> after_pending;
    pose2_t odo_pose{0.0, 0.0, 0.0};     // dead reckoning, as the robot keeps it
    double travel_m = 0.0;               // odometer (wheel travel)
    // pose error sums
    double se_xy = 0.0;
    double se_th = 0.0;
    // ... and in the map's fitted frame, at the map evaluations
    double se_fit_xy = 0.0;
    double se_fit_th = 0.0;
    long fit_skipped = 0; // map evaluations above [eval] pose_fit_max_landmarks
    double nees_sum = 0.0;
    long nees_n = 0;
    double nees_xy_sum = 0.0; // the position and heading parts (docs/replay.md "Consistency")
    long nees_xy_n = 0;
    double nees_th_sum = 0.0;
    long nees_th_n = 0;
    // no ground truth at the start, but later: the frame is placed at the
    // first moment truth exists (Replay::place_frame_late)
    bool frame_pending = false;
    bool skip_pose_at_placement = false;
    RobotResult res;
};

bool near_equal(double a, double b)
{
    return std::fabs(a - b) <= 1e-9 * std::max(1.0, std::fabs(a));
}

std::vector<Frame> build_frames(const RobotLog &log)
{
    std::vector<Frame> out;
    size_t iz = 0;
    size_t ir = 0;
    while (iz < log.z.size() || ir < log.rz.size()) {
        const double tz = iz < log.z.size() ? log.z[iz].t_s : std::numeric_limits<double>::infinity();
        const double tr = ir < log.rz.size() ? log.rz[ir].t_s : std::numeric_limits<double>::infinity();
        const double t = std::min(tz, tr);
        Frame f{t, {}, {}};
        while (iz < log.z.size() && near_equal(log.z[iz].t_s, t)) {
            f.zi.push_back(static_cast<int>(iz++));
        }
        while (ir < log.rz.size() && near_equal(log.rz[ir].t_s, t)) {
            f.ri.push_back(static_cast<int>(ir++));
        }
        out.push_back(std::move(f));
    }
    return out;
}

} // namespace

namespace {

// The figures MapScore and FitScore share, from one evaluation.
template <typename Score> Score fill_score(Score s, const map_eval_t &ev, map_eval_t *detail)
{
    s.n_matched = ev.n_matched;
    s.n_spurious = ev.n_spurious;
    s.n_missed = ev.n_missed;
    s.rmse_m = ev.rmse_m;
    s.max_err_m = ev.max_err_m;
    s.nees_mean = ev.nees_mean;
    // evaluated: the counts hold; the errors only if n_matched > 0 (measured())
    s.valid = true;
    if (detail != nullptr) {
        *detail = ev;
    }
    return s;
}

} // namespace

MapScore score_map(const map_whole_t &est, const std::vector<point2_t> &truth, const std::vector<int> &n_seen,
                   const EvalConfig &ec, map_eval_t *detail)
{
    MapScore s;
    if (truth.empty()) {
        s.n_estimated = est.n_landmarks;
        return s;
    }
    auto ev = std::make_unique<map_eval_t>();
    eval_map_whole(&est, truth.data(), n_seen.empty() ? nullptr : n_seen.data(), static_cast<int>(truth.size()),
                  ec.min_seen, ec.gate_m, ev.get());
    s.n_estimated = ev->n_estimated;
    return fill_score(s, *ev, detail);
}

FitScore score_map_fit(const map_whole_t &est, const std::vector<point2_t> &truth_world,
                       const std::vector<int> &n_seen, const EvalConfig &ec, map_eval_t *detail)
{
    FitScore s;
    if (truth_world.empty()) {
        return s;
    }
    auto ev = std::make_unique<map_eval_t>();
    const bool seen = n_seen.size() == truth_world.size();
    if (eval_map_rigid_whole(&est, truth_world.data(), seen ? n_seen.data() : nullptr, static_cast<int>(truth_world.size()),
                       ec.min_seen, ec.gate_m, &s.transform, ev.get()) != COSLAM_OK) {
        return s;
    }
    return fill_score(s, *ev, detail);
}

namespace {

class Replay {
public:
    Replay(const Dataset &ds, const ReplayConfig &cfg, const ReplayOptions &opt) : ds_(ds), cfg_(cfg), opt_(opt)
    {
        replay_config_validate(cfg_);
        if (opt_.known_ids) {
            // the identity decides the association (InputConfig)
            cfg_.slam.gate_chi2 = cfg_.input.known_id_gate_chi2;
            cfg_.slam.new_landmark_chi2 = std::max(cfg_.slam.new_landmark_chi2, cfg_.input.known_id_gate_chi2);
            cfg_.slam.new_landmark_log_lik = cfg_.input.known_id_log_lik;
            cfg_.merge.core.gate_chi2 = std::max(cfg_.merge.core.gate_chi2, cfg_.input.known_id_gate_chi2);
            replay_config_validate(cfg_);
        }
        setup();
    }

    ReplayResult run();

private:
    void setup();
    void advance(Robot &r, double t);
    void sample(Robot &r);
    void place_frame(Robot &r, pose2_t origin, double t);
    void place_frame_late(Robot &r);
    void process_frame(Robot &r, const Frame &f);
    void on_robot_sighting(Robot &r, const RobotSighting &s);
    void poll_meeting(Robot &r);
    void score_after(Robot &recv);
    void record_event(Robot &recv, const meeting_event_t &e, const MapScore *before,
                      const std::shared_ptr<map_whole_t> &before_map, double merge_us);
    uint64_t stamp_us(double t_s) const;
    double time_s(uint64_t stamp) const;
    MapScore score_now(Robot &r, std::shared_ptr<map_whole_t> *keep = nullptr);
    void score_pose_in_fit(Robot &r, const map_whole_t &est);
    std::optional<pose2_t> truth_in_map(const Robot &r, double t) const;

    const Dataset &ds_;
    ReplayConfig cfg_;
    ReplayOptions opt_;
    std::vector<std::unique_ptr<Robot>> robots_;
    std::map<int, int> truth_index_; // landmark id -> index into ds_.landmarks
    std::vector<point2_t> truth_world_; // for the rigid-fit scores, which need no robot truth
    // the robots' clock and link: the simulator's radio hub, every datagram
    // delivered at once and in order (the recorded robots were in reach)
    std::unique_ptr<sim::SimClock> clock_;
    std::unique_ptr<sim::SimLinkHub> link_;
    ReplayResult out_;
};

void Replay::setup()
{
    std::vector<int> ids = opt_.robots;
    if (ids.empty()) {
        for (const auto &r : ds_.robots) {
            ids.push_back(r.id);
        }
    }
    if (ids.empty()) {
        throw ReplayError("the dataset has no robots");
    }
    for (const auto &l : ds_.landmarks) {
        truth_world_.push_back(l.pos);
    }
    if (ids.size() > COSLAM_MAX_ROBOTS) {
        throw ReplayError("at most " + std::to_string(COSLAM_MAX_ROBOTS) + " robots per replay");
    }
    std::set<int> uniq(ids.begin(), ids.end());
    if (uniq.size() != ids.size()) {
        throw ReplayError("a robot is listed twice");
    }
    for (size_t i = 0; i < ds_.landmarks.size(); ++i) {
        truth_index_[ds_.landmarks[i].id] = static_cast<int>(i);
    }
    double t_begin = std::numeric_limits<double>::infinity();
    double t_end = -std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < ids.size(); ++i) {
        const RobotLog *log = ds_.robot(ids[i]);
        if (log == nullptr) {
            std::string have;
            for (const auto &r : ds_.robots) {
                have += (have.empty() ? "" : ", ") + std::to_string(r.id);
            }
            throw ReplayError("no robot " + std::to_string(ids[i]) + " in " + ds_.source + " (robots: " + have + ")");
        }
        if (opt_.known_ids) {
            long unknown = 0;
            for (const auto &z : log->z) {
                if (z.landmark_id != -1 && (z.landmark_id < 1 || z.landmark_id > 255)) {
                    throw ReplayError("--known-ids needs landmark ids in 1..255 (they become the signature); robot " +
                                      std::to_string(log->id) + " sights landmark " + std::to_string(z.landmark_id));
                }
                unknown += z.landmark_id == -1;
            }
            if (!log->z.empty() && unknown == static_cast<long>(log->z.size())) {
                throw ReplayError("--known-ids: robot " + std::to_string(log->id) + "'s " +
                                  std::to_string(log->z.size()) +
                                  " landmark sightings carry no identity (all -1); replay without --known-ids");
            }
            if (unknown > 0) {
                out_.notes.push_back("robot " + std::to_string(log->id) + ": " + std::to_string(unknown) +
                                     " sightings without identity (-1) treated as non-unique under --known-ids");
            }
        }
        auto r = std::make_unique<Robot>();
        r->log = log;
        r->idx = static_cast<int>(i);
        r->core_id = static_cast<uint8_t>(i);
        r->frames = build_frames(*log);
        double start = log->odo.empty() ? (r->frames.empty() ? 0.0 : r->frames.front().t_s) : log->odo.front().t_s;
        double end = start;
        if (!log->odo.empty()) {
            end = std::max(end, log->odo.back().t_s);
        }
        if (!r->frames.empty()) {
            end = std::max(end, r->frames.back().t_s);
        }
        r->res.t_start_s = start;
        t_begin = std::min(t_begin, start);
        t_end = std::max(t_end, end);
        r->odo = std::make_unique<OdoTrack>(*log, cfg_.odo_of(log->id), end);
        r->truth = std::make_unique<TruthTrack>(log->truth);
        robots_.push_back(std::move(r));
    }
    if (opt_.duration_s > 0.0) {
        t_end = std::min(t_end, t_begin + opt_.duration_s);
    }
    out_.t_begin_s = t_begin;
    out_.t_end_s = t_end;
    clock_ = std::make_unique<sim::SimClock>(stamp_us(t_begin));
    sim::SimLinkParams lp;
    lp.range_m = std::numeric_limits<double>::infinity();
    lp.latency_us = 0;
    lp.rx_queue_depth = 1U << 16;
    link_ = std::make_unique<sim::SimLinkHub>(*clock_, robots_.size(), lp);

    for (auto &rp : robots_) {
        Robot &r = *rp;
        RobotResult &res = r.res;
        res.id = r.log->id;
        res.filter = cfg_.filter_of(res.id);
        const auto p_start = r.truth->at(res.t_start_s);
        pose2_t pose0 = {0.0, 0.0, 0.0};
        if (opt_.start_at_truth) {
            if (!p_start) {
                throw ReplayError("robot " + std::to_string(res.id) + ": no ground truth at its start (t = " +
                                  std::to_string(res.t_start_s) + " s) for --start-at-truth");
            }
            pose0 = *p_start;
            res.frame.origin = {0.0, 0.0, 0.0};
            res.has_truth = true;
        } else if (p_start) {
            res.frame.origin = *p_start;
            res.has_truth = true;
        } else if (!r.log->truth.empty() && r.log->truth.back().t_s > res.t_start_s) {
            // truth begins after the robot's first odometry record (or has
            // a gap there): the frame is placed when truth begins
            r.frame_pending = true;
            out_.notes.push_back("robot " + std::to_string(res.id) + ": ground truth begins after its start (t = " +
                                 fmt_value(res.t_start_s) + " s); its map frame is placed where its estimate is at "
                                 "the first truth sample, and it is scored from then on");
        } else {
            out_.notes.push_back("robot " + std::to_string(res.id) + ": no ground truth at its start, not evaluated");
        }
        if (res.has_truth) {
            place_frame(r, res.frame.origin, res.t_start_s);
        }
        res.n_seen.assign(ds_.landmarks.size(), 0);
        r.filter = std::make_unique<RobotFilter>(res.filter, cfg_, r.core_id, pose0,
                                                 cfg_.filter.seed + static_cast<uint64_t>(res.id));
        r.t_filter = res.t_start_s;
        if (cfg_.merge.enabled && robots_.size() >= 2) {
            // the robot's meeting protocol, with the replay's settings
            meeting_config_t mc = meeting_config_default();
            // the camera model of the config (the robot does the same)
            meeting_config_noise_from(&mc, &cfg_.slam);
            mc.link_latency_us = 0U;
            mc.pair_window_us = static_cast<uint32_t>(std::llround(cfg_.merge.window_s * 1e6));
            mc.remerge_period_us = static_cast<uint32_t>(std::llround(cfg_.merge.interval_s * 1e6));
            mc.max_range_m = cfg_.merge.max_range_m;
            mc.export_min_obs = static_cast<uint16_t>(cfg_.merge.export_min_obs);
            mc.max_sends = static_cast<uint8_t>(cfg_.merge.max_sends);
            mc.resend_period_us = static_cast<uint32_t>(std::llround(cfg_.merge.resend_s * 1e6));
            mc.merge = cfg_.merge.core;
            r.meeting = std::make_unique<meeting_t>();
            if (meeting_init(r.meeting.get(), &mc, r.core_id, static_cast<uint8_t>(robots_.size())) != COSLAM_OK) {
                throw ReplayError("meeting_init refused the [merge] configuration");
            }
            r.link = link_->endpoint(static_cast<uint16_t>(r.idx));
        }
        r.next_tick = res.t_start_s + cfg_.filter.predict_period_s;
        r.next_pose_t = res.t_start_s;
        r.next_map_t = res.t_start_s + cfg_.eval.map_period_s;
    }
}

// Adds est's squared position and heading errors against truth to the sums;
// returns the squared position error.
double add_pose_error(pose2_t est, pose2_t truth, double &se_xy, double &se_th)
{
    const double ex = est.x - truth.x;
    const double ey = est.y - truth.y;
    const double eh = angle_wrap(est.theta - truth.theta);
    se_xy += ex * ex + ey * ey;
    se_th += eh * eh;
    return ex * ex + ey * ey;
}

std::optional<pose2_t> Replay::truth_in_map(const Robot &r, double t) const
{
    if (!r.res.has_truth) {
        return std::nullopt;
    }
    const auto p = r.truth->at(t);
    if (!p) {
        return std::nullopt;
    }
    return r.res.frame.pose_in_map(*p);
}

MapScore Replay::score_now(Robot &r, std::shared_ptr<map_whole_t> *keep)
{
    // the whole map: a message holds at most COSLAM_MAX_MSG_LANDMARKS, and
    // scoring only those would hide the rest
    auto est = std::make_shared<map_whole_t>();
    r.filter->export_whole(est.get());
    const MapScore s = score_map(*est, r.res.truth_landmarks, r.res.n_seen, cfg_.eval);
    if (keep != nullptr) {
        *keep = std::move(est);
    }
    return s;
}

// The pose in the frame of the map's best rigid fit to the true landmarks
// at this moment: how well the robot knows where it is in its own map,
// whatever that map's frame (a merge may move a robot's whole map and pose
// towards its partner's frame, which the pose error in the start frame,
// pose.rmse_m, counts as error). Needs robot truth and a fit that matched
// at least [eval] pose_fit_min_matched landmarks.
void Replay::score_pose_in_fit(Robot &r, const map_whole_t &est)
{
    if (!r.res.has_truth || truth_world_.empty()) {
        return;
    }
    const auto tw = r.truth->at(r.t_filter);
    if (!tw) {
        return;
    }
    if (est.n_landmarks > cfg_.eval.pose_fit_max_landmarks) {
        r.fit_skipped++;
        return;
    }
    const FitScore fit = score_map_fit(est, truth_world_, r.res.n_seen, cfg_.eval);
    if (!fit.valid || fit.n_matched < cfg_.eval.pose_fit_min_matched) {
        return;
    }
    pose2_t est_pose;
    cov3_t cov;
    r.filter->pose(&est_pose, &cov);
    (void)add_pose_error(pose2_compose(fit.transform, est_pose), *tw, r.se_fit_xy, r.se_fit_th);
    r.res.pose_fit_samples++;
}

void Replay::place_frame(Robot &r, pose2_t origin, double t)
{
    RobotResult &res = r.res;
    res.frame.origin = origin;
    res.has_truth = true;
    res.t_frame_s = t;
    res.truth_landmarks.clear();
    res.truth_ids.clear();
    for (const auto &l : ds_.landmarks) {
        res.truth_landmarks.push_back(res.frame.point_in_map(l.pos));
        res.truth_ids.push_back(l.id);
    }
}

// A robot whose ground truth begins after its start: at the first moment
// truth exists, the map frame is placed so that the filter's estimate of
// that moment is the truth (origin = truth (+) estimate^-1). The frame then
// carries the estimate's error of that moment, as the start frame carries
// none; the pose errors are of the motion since.
void Replay::place_frame_late(Robot &r)
{
    const auto tw = r.truth->at(r.t_filter);
    if (!tw) {
        return;
    }
    pose2_t est;
    cov3_t cov;
    r.filter->pose(&est, &cov);
    r.frame_pending = false;
    r.skip_pose_at_placement = true; /* its error is zero by construction */
    place_frame(r, pose2_compose(*tw, pose2_inverse(est)), r.t_filter);
}

void Replay::sample(Robot &r)
{
    const double eps = 1e-9;
    if (r.frame_pending) {
        place_frame_late(r);
    }
    while (r.t_filter >= r.next_pose_t - eps) {
        pose2_t est;
        cov3_t cov;
        r.filter->pose(&est, &cov);
        auto tr = truth_in_map(r, r.t_filter);
        if (r.skip_pose_at_placement) {
            tr.reset(); /* the moment the frame was placed at: not a measurement */
        }
        if (tr) {
            r.res.final_pos_err_m = std::sqrt(add_pose_error(est, *tr, r.se_xy, r.se_th));
            r.res.pose_samples++;
            const double n = nees_pose(est, cov, *tr);
            if (std::isfinite(n)) {
                r.nees_sum += n;
                r.nees_n++;
            }
            double n_xy, n_th;
            nees_pose_parts(est, cov, *tr, &n_xy, &n_th);
            if (std::isfinite(n_xy)) {
                r.nees_xy_sum += n_xy;
                r.nees_xy_n++;
            }
            if (std::isfinite(n_th)) {
                r.nees_th_sum += n_th;
                r.nees_th_n++;
            }
        }
        // the recorded path (not the statistics above) is thinned to every
        // other point, its stride doubled, when it reaches kMaxPathPoints:
        // memory bounded whatever the span
        if (opt_.record_history && r.pose_tick++ % r.path_stride == 0) {
            if (r.res.path.size() >= kMaxPathPoints) {
                size_t w = 0;
                for (size_t i = 0; i < r.res.path.size(); i += 2) {
                    r.res.path[w++] = r.res.path[i];
                }
                r.res.path.resize(w);
                r.path_stride *= 2;
            }
            if ((r.pose_tick - 1) % r.path_stride == 0) {
                r.res.path.push_back({r.t_filter, est, cov, tr.has_value(), tr.value_or(pose2_t{0.0, 0.0, 0.0})});
            }
        }
        r.next_pose_t += cfg_.eval.pose_period_s;
    }
    r.skip_pose_at_placement = false;
    // the map evaluation is an observer: it waits while an export in parts
    // holds the filter's export table (evaluating now would finish that
    // export at once, which the robot, with no evaluations, never does)
    while (r.t_filter >= r.next_map_t - eps && !slam_filter_export_busy(r.filter->app())) {
        if (opt_.record_history || r.res.has_truth) {
            std::shared_ptr<map_whole_t> m;
            const MapScore s = score_now(r, &m);
            if (opt_.record_history) {
                r.res.map_series.push_back({r.t_filter, s});
            }
            score_pose_in_fit(r, *m);
        }
        r.next_map_t += cfg_.eval.map_period_s;
    }
    if (r.after_pending && !slam_filter_export_busy(r.filter->app())) {
        score_after(r);
    }
}

void Replay::advance(Robot &r, double t)
{
    const double eps = 1e-9;
    while (r.t_filter < t - eps) {
        const double t_next = std::min(t, r.next_tick);
        const odo_increment_t u = r.odo->increment(r.t_filter, t_next);
        const auto t0 = Clock::now();
        const coslam_status_t st = r.filter->predict(u, t_next - r.t_filter);
        r.pending_us += us_since(t0);
        const auto t1 = Clock::now();
        r.filter->idle(); // the rest of the robot's step period, not timed as the step
        r.res.filter_s += us_since(t1) * 1e-6;
        if (st != COSLAM_E_ARG && st != COSLAM_E_NUMERIC) {
            // dead reckoning (the meeting's compensation) takes only what
            // the filter took: a refused increment moves neither
            r.odo_pose = motion_apply(r.odo_pose, u);
            r.travel_m += motion_travel_m(u, cfg_.slam.base_radius_m);
        }
        r.res.predictions++;
        r.t_filter = t_next;
        if (t_next >= r.next_tick - eps) {
            r.next_tick += cfg_.filter.predict_period_s;
        }
        sample(r);
    }
}

void Replay::process_frame(Robot &r, const Frame &f)
{
    advance(r, f.t_s);
    const RobotLog &log = *r.log;
    // every sighting goes to the core, which counts what exceeds its capacity
    std::vector<sighting_t> z;
    z.reserve(f.zi.size());
    pose2_t est{};
    cov3_t cov{};
    if (opt_.known_ids && cfg_.input.known_id_gate_rad > 0.0) {
        r.filter->pose(&est, &cov);
    }
    for (const int i : f.zi) {
        const LandmarkSighting &s = log.z[static_cast<size_t>(i)];
        if (s.range_m < cfg_.input.min_range_m || s.range_m > cfg_.input.max_range_m) {
            r.res.sightings_range_dropped++;
            continue;
        }
        sighting_t q;
        q.range_m = s.range_m;
        q.bearing_rad = s.bearing_rad;
        q.signature = 0;
        if (opt_.known_ids && s.landmark_id > 0) {
            q.signature = static_cast<uint8_t>(s.landmark_id);
            if (cfg_.input.known_id_gate_rad > 0.0) {
                const auto lm = r.filter->landmark_of_signature(q.signature);
                if (lm) {
                    const sighting_t pred = observe_predict(est, *lm);
                    if (std::fabs(angle_wrap(q.bearing_rad - pred.bearing_rad)) > cfg_.input.known_id_gate_rad) {
                        r.res.sightings_known_id_dropped++;
                        continue;
                    }
                }
            }
        }
        z.push_back(q);
        r.res.sightings_used++;
        const auto it = truth_index_.find(s.landmark_id);
        if (it != truth_index_.end()) {
            r.res.n_seen[static_cast<size_t>(it->second)]++;
        }
    }
    const auto t0 = Clock::now();
    const coslam_status_t st = r.filter->update(z.data(), static_cast<int>(z.size()));
    const double update_us = us_since(t0);
    const auto t1 = Clock::now();
    r.filter->idle();
    r.res.filter_s += us_since(t1) * 1e-6;
    if (st == COSLAM_E_CAPACITY) {
        r.res.capacity_errors++;
    }
    r.res.updates++;
    r.res.frames++;
    const double step = r.pending_us + update_us;
    r.res.filter_s += step * 1e-6;
    r.step_us_sum += step;
    r.res.step_us_max = std::max(r.res.step_us_max, step);
    r.pending_us = 0.0;
    for (const int i : f.ri) {
        on_robot_sighting(r, log.rz[static_cast<size_t>(i)]);
    }
    if (r.meeting) {
        poll_meeting(r);
    }
}

uint64_t Replay::stamp_us(double t_s) const
{
    // the robots' clock: microseconds from one second before the replay starts
    return static_cast<uint64_t>(std::llround((t_s - out_.t_begin_s + 1.0) * 1e6));
}

double Replay::time_s(uint64_t stamp) const
{
    return static_cast<double>(stamp) * 1e-6 + out_.t_begin_s - 1.0;
}

void Replay::on_robot_sighting(Robot &r, const RobotSighting &s)
{
    Robot *o = nullptr;
    for (auto &p : robots_) {
        if (p->log->id == s.other_robot) {
            o = p.get();
        }
    }
    if (o == nullptr) {
        return; // a robot that is not part of this replay
    }
    r.res.robot_sightings++;
    if (!r.meeting) {
        return;
    }
    const uint64_t now = stamp_us(s.t_s);
    clock_->advance_to(now);
    (void)meeting_on_sighting(r.meeting.get(), r.filter->app(), r.link, now, static_cast<uint8_t>(o->idx),
                              s.range_m, s.bearing_rad, now, r.odo_pose, r.travel_m);
}

void Replay::poll_meeting(Robot &r)
{
    meeting_t *m = r.meeting.get();
    const uint64_t now = stamp_us(r.t_filter);
    clock_->advance_to(now);
    if (m->send_waiting) {
        (void)meeting_send_due(m, r.filter->app(), r.link, now); // an export done in idle time
    }
    (void)meeting_poll_link(m, r.link);
    MapScore before;
    std::shared_ptr<map_whole_t> before_map;
    const bool pending = m->have_pending != 0U;
    if (pending && !slam_filter_export_busy(r.filter->app())) {
        before = score_now(r, &before_map); // (an observer: not while an export in parts runs)
    }
    const auto t0 = Clock::now();
    const coslam_status_t pst = meeting_poll(m, r.filter->app(), now, r.odo_pose, r.travel_m);
    const double merge_us = us_since(t0);
    meeting_event_t ev;
    std::optional<Robot::Waiting> waited;
    while (meeting_take_event(m, &ev) == COSLAM_OK) {
        if (ev.kind == MEETING_EV_SENT) {
            continue;
        }
        if (r.waiting && ev.peer == r.waiting->peer && ev.seq == r.waiting->seq) {
            // the outcome of the merge that waited: the map before it, and
            // the time of the call that began it (the rest was idle time)
            waited = std::move(r.waiting);
            r.waiting.reset();
            record_event(r, ev, &waited->before, waited->before_map, waited->merge_us);
        } else {
            record_event(r, ev, pending ? &before : nullptr, before_map, merge_us);
        }
    }
    if (pst == COSLAM_E_MERGE_PENDING && pending && m->merge_waiting) {
        r.waiting = Robot::Waiting{m->waiting_ev.peer, m->waiting_ev.seq, before, before_map, merge_us};
    }
}

void Replay::record_event(Robot &recv, const meeting_event_t &e, const MapScore *before,
                          const std::shared_ptr<map_whole_t> &before_map, double merge_us)
{
    if (e.peer >= robots_.size()) {
        out_.merges_failed++; // undecodable datagram: cannot happen on this link
        return;
    }
    Robot &send = *robots_[e.peer];
    score_after(recv); // the last merge's map, if it was still running (this one finished it)
    MergeEvent ev;
    ev.t_s = time_s(e.stamp_us);
    ev.receiver = recv.log->id;
    ev.sender = send.log->id;
    ev.t_receiver_sighting_s = e.own_sighting_us > 0U ? time_s(e.own_sighting_us) : ev.t_s;
    ev.t_sender_sighting_s = e.sender_sighting_us > 0U ? time_s(e.sender_sighting_us) : ev.t_s;
    ev.seq = e.seq;
    ev.status = e.status;
    ev.transform = e.other_in_self;
    ev.transform_cov = e.other_in_self_cov;
    ev.stats = e.stats;
    ev.merge_us = merge_us;
    if (const fastslam_t *fs = recv.filter->fastslam()) {
        ev.particles_due = fs->merge_due_n;
    }
    const bool merged = e.kind == MEETING_EV_MERGED;
    switch (e.status) {
    case COSLAM_OK:
    case COSLAM_E_CAPACITY:
        break;
    case COSLAM_E_MERGE_RANGE:
        out_.meetings_refused_range++;
        break;
    case COSLAM_E_MERGE_REPLAY:
        out_.merges_refused_replay++;
        break;
    case COSLAM_E_MERGE_DISAGREE:
        out_.merges_refused_disagree++;
        break;
    case COSLAM_E_MERGE_LOST:
        out_.merges_refused_lost++;
        break;
    case COSLAM_E_MERGE_IMPLAUSIBLE:
        out_.merges_refused_implausible++;
        break;
    case COSLAM_E_MERGE_STALE:
        out_.merges_stale++;
        return; // no own sighting came: nothing was evaluated
    default:
        out_.merges_failed++;
        break;
    }
    const auto tr = recv.truth->at(ev.t_s);
    const auto ts = send.truth->at(ev.t_sender_sighting_s);
    if (tr && ts && (merged || merge_refused_by_check(e.status))) {
        ev.has_truth = true;
        ev.transform_true = pose2_between(*tr, *ts);
        ev.t_err_m = std::hypot(ev.transform.x - ev.transform_true.x, ev.transform.y - ev.transform_true.y);
        ev.t_err_rad = std::fabs(angle_wrap(ev.transform.theta - ev.transform_true.theta));
        ev.t_nees = nees_pose(ev.transform, ev.transform_cov, ev.transform_true);
    }
    if (before != nullptr) {
        ev.before = *before;
    }
    if (!merged) {
        ev.after = ev.before;
        out_.merges.push_back(ev);
        return;
    }
    // the receiver now holds what the sender had seen
    for (size_t j = 0; j < recv.res.n_seen.size(); ++j) {
        recv.res.n_seen[j] += send.res.n_seen[j];
    }
    if (recv.res.t_first_merge_s < 0.0) {
        recv.res.t_first_merge_s = ev.t_s;
    }
    out_.merges.push_back(ev);
    recv.after_pending = Robot::AfterPending{out_.merges.size() - 1, before_map};
    if (!slam_filter_export_busy(recv.filter->app())) {
        score_after(recv);
    }
    // else an EKF-SLAM merge in parts (or the inputs it held) is still
    // running: the map after it is scored once it is done, as the robot
    // runs (scoring now would finish it at once)
}

// The map after the merge of recv.after_pending, scored now.
void Replay::score_after(Robot &recv)
{
    if (!recv.after_pending) {
        return;
    }
    const Robot::AfterPending p = std::move(*recv.after_pending);
    recv.after_pending.reset();
    MergeEvent &ev = out_.merges[p.event];
    std::shared_ptr<map_whole_t> after;
    ev.after = score_now(recv, &after);
    const int gain = after->n_landmarks - (p.before_map ? p.before_map->n_landmarks : 0);
    if (gain > recv.res.shown_merge_gain) {
        recv.res.map_before_merge = p.before_map;
        recv.res.map_after_merge = after;
        recv.res.t_shown_merge_s = ev.t_s;
        recv.res.shown_merge_gain = gain;
    }
}

ReplayResult Replay::run()
{
    const auto wall0 = Clock::now();
    struct Ev {
        double t;
        int robot;
        int frame;
    };
    std::vector<Ev> evs;
    for (const auto &r : robots_) {
        for (size_t k = 0; k < r->frames.size(); ++k) {
            const double t = r->frames[k].t_s;
            if (t < r->res.t_start_s) {
                r->res.sightings_before_start += static_cast<long>(r->frames[k].zi.size());
                r->res.robot_sightings_before_start += static_cast<long>(r->frames[k].ri.size());
                continue;
            }
            if (t > out_.t_end_s) {
                break;
            }
            evs.push_back({t, r->idx, static_cast<int>(k)});
        }
    }
    std::stable_sort(evs.begin(), evs.end(), [](const Ev &a, const Ev &b) {
        return a.t < b.t || (a.t == b.t && a.robot < b.robot);
    });
    const double span = std::max(1e-9, out_.t_end_s - out_.t_begin_s);
    for (size_t i = 0; i < evs.size(); ++i) {
        Robot &r = *robots_[static_cast<size_t>(evs[i].robot)];
        process_frame(r, r.frames[static_cast<size_t>(evs[i].frame)]);
        if (opt_.progress && (i % 256) == 0) {
            opt_.progress((evs[i].t - out_.t_begin_s) / span);
        }
    }
    for (auto &rp : robots_) {
        Robot &r = *rp;
        advance(r, out_.t_end_s);
        if (r.meeting && r.meeting->merge_waiting) {
            // a merge whose check still waits for idle time: decided now, so
            // that its event is recorded before the final map is scored
            slam_merge_work_finish(&r.meeting->work);
            poll_meeting(r);
        }
        score_after(r); // a merge still running at the end (its map now, the merge finished)
        RobotResult &res = r.res;
        if (r.frame_pending) {
            out_.notes.push_back("robot " + std::to_string(res.id) +
                                 ": its ground truth never overlapped the replayed span, not evaluated");
        }
        res.final_score = score_now(r, &res.final_map);
        res.final_score.fit = score_map_fit(*res.final_map, truth_world_, res.n_seen, cfg_.eval);
        if (opt_.record_history && (res.map_series.empty() || res.map_series.back().t_s < r.t_filter)) {
            res.map_series.push_back({r.t_filter, res.final_score});
        }
        if (res.pose_samples > 0) {
            res.pose_rmse_m = std::sqrt(r.se_xy / res.pose_samples);
            res.heading_rmse_rad = std::sqrt(r.se_th / res.pose_samples);
        }
        if (r.fit_skipped > 0) {
            out_.notes.push_back("robot " + std::to_string(res.id) + ": the pose in the fitted map was not scored at " +
                                 std::to_string(r.fit_skipped) + " map evaluations, the map holding more than " +
                                 std::to_string(cfg_.eval.pose_fit_max_landmarks) +
                                 " landmarks ([eval] pose_fit_max_landmarks)");
        }
        if (res.pose_fit_samples > 0) {
            res.pose_fit_rmse_m = std::sqrt(r.se_fit_xy / res.pose_fit_samples);
            res.heading_fit_rmse_rad = std::sqrt(r.se_fit_th / res.pose_fit_samples);
        }
        res.pose_nees_mean = r.nees_n > 0 ? r.nees_sum / static_cast<double>(r.nees_n) : 0.0;
        res.pose_nees_xy_mean = r.nees_xy_n > 0 ? r.nees_xy_sum / static_cast<double>(r.nees_xy_n) : 0.0;
        res.pose_nees_heading_mean = r.nees_th_n > 0 ? r.nees_th_sum / static_cast<double>(r.nees_th_n) : 0.0;
        res.step_us_mean = res.frames > 0 ? r.step_us_sum / static_cast<double>(res.frames) : 0.0;
        res.counters = r.filter->counters();
        {
            slam_filter_limit_t lim[SLAM_FILTER_N_LIMITS];
            const int nl = slam_filter_limits(r.filter->app(), lim);
            res.limits.assign(lim, lim + nl);
        }
        if (r.meeting) {
            const meeting_counters_t *mc = meeting_counters(r.meeting.get());
            res.counters["meeting_sent"] = mc->sent;
            res.counters["meeting_weak_not_sent"] = mc->weak_not_sent;
            res.counters["meeting_received"] = mc->received;
            res.counters["meeting_merged"] = mc->merged;
            res.counters["meeting_refused_range"] = mc->refused_range;
            res.counters["meeting_refused_disagree"] = mc->refused_disagree;
            res.counters["meeting_refused_lost"] = mc->refused_lost;
            res.counters["meeting_ignored_disagreed"] = mc->ignored_disagreed;
            res.counters["meeting_replays"] = mc->replays;
            res.counters["meeting_stale"] = mc->stale;
            res.counters["meeting_ignored_recent"] = mc->ignored_recent;
            res.counters["meeting_merge_failures"] = mc->merge_failures;
        }
        out_.robots.push_back(std::move(res));
    }
    if (opt_.progress) {
        opt_.progress(1.0);
    }
    out_.wall_s = std::chrono::duration<double>(Clock::now() - wall0).count();
    return std::move(out_);
}

} // namespace

ReplayResult run_replay(const Dataset &ds, const ReplayConfig &cfg, const ReplayOptions &opt)
{
    Replay rp(ds, cfg, opt);
    return rp.run();
}

} // namespace coslam::replay
