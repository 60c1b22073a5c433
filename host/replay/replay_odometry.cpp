// host/replay/replay_odometry.cpp - odometry model, integration and fit.
#include "replay_odometry.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "replay_truth.h"

namespace coslam::replay {

odo_increment_t odo_compose(odo_increment_t u1, odo_increment_t u2)
{
    const double c = std::cos(u1.dtheta);
    const double s = std::sin(u1.dtheta);
    odo_increment_t u;
    u.dx = u1.dx + c * u2.dx - s * u2.dy;
    u.dy = u1.dy + s * u2.dx + c * u2.dy;
    u.dtheta = u1.dtheta + u2.dtheta;
    return u;
}

namespace {

// Constant body velocity (vx, vy, w) over dt that produces increment u
// exactly (the inverse of motion_from_body_velocity).
void velocity_for_increment(odo_increment_t u, double dt, double *vx, double *vy, double *w)
{
    *w = u.dtheta / dt;
    const double th = u.dtheta;
    double a;
    double b;
    if (std::fabs(th) < 1e-6) {
        a = dt * (1.0 - th * th / 6.0);
        b = dt * (0.5 * th);
    } else {
        a = std::sin(th) / *w;
        const double sh = std::sin(0.5 * th);
        b = 2.0 * sh * sh / *w;
    }
    // [a -b; b a] (vx, vy) = (dx, dy)
    const double det = a * a + b * b;
    *vx = (a * u.dx + b * u.dy) / det;
    *vy = (-b * u.dx + a * u.dy) / det;
}

} // namespace

OdoTrack::OdoTrack(const RobotLog &log, const OdoModel &m, double end_s)
{
    const auto &o = log.odo;
    segs_.reserve(o.size());
    for (size_t i = 0; i < o.size(); ++i) {
        Seg s{};
        if (o[i].kind == OdoRecord::Kind::Velocity) {
            s.t0 = o[i].t_s + m.delay_s;
            const double t_next = i + 1 < o.size() ? o[i + 1].t_s : std::max(end_s, o[i].t_s);
            s.t1 = t_next + m.delay_s;
            s.vx = m.scale_v * o[i].a;
            s.vy = 0.0;
            s.w = m.scale_w * o[i].b;
        } else {
            const odo_increment_t u = {m.scale_v * o[i].a, m.scale_v * o[i].b, m.scale_w * o[i].c};
            const double t_prev = i > 0 ? o[i - 1].t_s : o[i].t_s;
            s.t0 = t_prev + m.delay_s;
            s.t1 = o[i].t_s + m.delay_s;
            if (s.t1 > s.t0) {
                velocity_for_increment(u, s.t1 - s.t0, &s.vx, &s.vy, &s.w);
            } else {
                s.t0 = s.t1;
                s.u = u;
            }
        }
        if (s.t1 < s.t0) {
            s.t1 = s.t0;
        }
        // a velocity record of zero length carries nothing
        if (s.t1 == s.t0 && o[i].kind == OdoRecord::Kind::Velocity) {
            continue;
        }
        segs_.push_back(s);
    }
    begin_s_ = segs_.empty() ? 0.0 : segs_.front().t0;
}

odo_increment_t OdoTrack::increment(double t_a, double t_b) const
{
    odo_increment_t acc = {0.0, 0.0, 0.0};
    if (segs_.empty() || !(t_b > t_a)) {
        return acc;
    }
    // first segment that ends after t_a (impulses: at or after t_a)
    auto it = std::lower_bound(segs_.begin(), segs_.end(), t_a, [](const Seg &s, double v) { return s.t1 < v; });
    for (; it != segs_.end() && it->t0 <= t_b; ++it) {
        if (it->t1 == it->t0) {
            // impulse: applied if its time lies in (t_a, t_b]
            if (it->t0 > t_a && it->t0 <= t_b) {
                acc = odo_compose(acc, it->u);
            }
            continue;
        }
        const double lo = std::max(t_a, it->t0);
        const double hi = std::min(t_b, it->t1);
        if (hi > lo) {
            acc = odo_compose(acc, motion_from_body_velocity(it->vx, it->vy, it->w, hi - lo));
        }
    }
    return acc;
}

namespace {

struct Window {
    double t;
    odo_increment_t g; // true increment
};

double drift_rmse(const RobotLog &log, const OdoModel &m, const TruthTrack &tt, double end_s)
{
    const OdoTrack track(log, m, end_s);
    const double win = 30.0;
    const double step = 0.5;
    double se = 0.0;
    int n = 0;
    for (double t = tt.begin_s(); t + win <= tt.end_s(); t += win) {
        auto p0 = tt.at(t);
        if (!p0) {
            continue;
        }
        pose2_t p = *p0;
        for (double s = t; s < t + win - 1e-9; s += step) {
            p = motion_apply(p, track.increment(s, s + step));
        }
        const auto p1 = tt.at(t + win);
        if (!p1) {
            continue;
        }
        se += (p.x - p1->x) * (p.x - p1->x) + (p.y - p1->y) * (p.y - p1->y);
        n++;
    }
    return n > 0 ? std::sqrt(se / n) : std::numeric_limits<double>::quiet_NaN();
}

} // namespace

OdoFit fit_odometry(const RobotLog &log, double window_s, double b)
{
    if (log.truth.empty()) {
        throw ReplayError(log.source, 0, "robot " + std::to_string(log.id) + " has no ground truth to fit against");
    }
    if (log.odo.empty()) {
        throw ReplayError(log.source, 0, "robot " + std::to_string(log.id) + " has no odometry");
    }
    const TruthTrack tt(log.truth);
    const double end_s = std::max(log.odo.back().t_s, tt.end_s());
    // truth windows inside both the odometry and the truth
    const double t_begin = std::max(log.odo.front().t_s + 1.0, tt.begin_s());
    const double t_end = std::min(log.odo.back().t_s - 1.0, tt.end_s());
    std::vector<Window> wins;
    for (double t = t_begin; t + window_s <= t_end; t += window_s) {
        const auto a = tt.at(t);
        const auto c = tt.at(t + window_s);
        if (!a || !c) {
            continue;
        }
        const pose2_t d = pose2_between(*a, *c);
        // unwrapped heading change: the truth is sampled at 60 Hz, so the
        // wrapped difference of the end poses is the change unless the robot
        // turned more than half a turn in a window
        wins.push_back({t, {d.x, d.y, angle_wrap(c->theta - a->theta)}});
    }
    OdoFit best;
    best.robot = log.id;
    best.window_s = window_s;
    double best_r = std::numeric_limits<double>::infinity();
    OdoModel unit;
    for (int k = -50; k <= 50; ++k) {
        unit.delay_s = 0.01 * k;
        const OdoTrack track(log, unit, end_s);
        double sxy = 0.0, sxx = 0.0, sth = 0.0, stt = 0.0;
        std::vector<odo_increment_t> us(wins.size());
        for (size_t i = 0; i < wins.size(); ++i) {
            const odo_increment_t u = track.increment(wins[i].t, wins[i].t + window_s);
            us[i] = u;
            sxy += u.dx * wins[i].g.dx + u.dy * wins[i].g.dy;
            sxx += u.dx * u.dx + u.dy * u.dy;
            sth += u.dtheta * wins[i].g.dtheta;
            stt += u.dtheta * u.dtheta;
        }
        const double sv = sxx > 0.0 ? sxy / sxx : 1.0;
        const double sw = stt > 0.0 ? sth / stt : 1.0;
        double r = 0.0;
        for (size_t i = 0; i < wins.size(); ++i) {
            const double ex = sv * us[i].dx - wins[i].g.dx;
            const double ey = sv * us[i].dy - wins[i].g.dy;
            const double et = sw * us[i].dtheta - wins[i].g.dtheta;
            r += ex * ex + ey * ey + b * b * et * et;
        }
        if (k == 0) {
            best.raw_scale_v = sv;
            best.raw_scale_w = sw;
        }
        if (r < best_r) {
            best_r = r;
            best.model = {sv, sw, unit.delay_s};
        }
    }
    // residuals and implied noise at the fitted model
    const OdoTrack track(log, best.model, end_s);
    double sxy2 = 0.0, sth2 = 0.0, travel = 0.0;
    for (const auto &w : wins) {
        const odo_increment_t u = track.increment(w.t, w.t + window_s);
        // residual in the robot frame of the window start
        const double ex = u.dx - w.g.dx;
        const double ey = u.dy - w.g.dy;
        const double et = u.dtheta - w.g.dtheta;
        sxy2 += 0.5 * (ex * ex + ey * ey);
        sth2 += et * et;
        travel += motion_travel_m(w.g, b);
    }
    const double n = static_cast<double>(wins.size());
    best.windows = static_cast<int>(wins.size());
    if (n > 0) {
        best.resid_xy_sd_m = std::sqrt(sxy2 / n);
        best.resid_th_sd_rad = std::sqrt(sth2 / n);
        best.mean_travel_m = travel / n;
        best.w3_m2_per_m = travel > 0.0 ? sxy2 / travel : 0.0;
        best.w4_rad2_per_m = travel > 0.0 ? sth2 / travel : 0.0;
    }
    best.drift_raw_m = drift_rmse(log, OdoModel{}, tt, end_s);
    best.drift_fit_m = drift_rmse(log, best.model, tt, end_s);
    return best;
}

} // namespace coslam::replay
