#include "sim/world/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <toml++/toml.h>

namespace coslam::sim {

namespace {

constexpr double kDeg = COSLAM_PI / 180.0;

std::string fmt_xy(const Eigen::Vector2d &p)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "(%.3g, %.3g)", p.x(), p.y());
    return buf;
}

std::string fmt_g(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

double point_segment_distance(const Eigen::Vector2d &p, const Eigen::Vector2d &a, const Eigen::Vector2d &b)
{
    const Eigen::Vector2d ab = b - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    return (a + t * ab - p).norm();
}

bool inside_polygon(const Eigen::Vector2d &p, const std::vector<Eigen::Vector2d> &poly)
{
    bool in = false;
    for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
        if ((poly[i].y() > p.y()) != (poly[j].y() > p.y()) &&
            p.x() < (poly[j].x() - poly[i].x()) * (p.y() - poly[i].y()) / (poly[j].y() - poly[i].y()) + poly[i].x()) {
            in = !in;
        }
    }
    return in;
}

// Twice the signed area of a polygon (shoelace); 0 for a degenerate one.
double polygon_area2(const std::vector<Eigen::Vector2d> &poly)
{
    double a = 0.0;
    for (size_t k = 0, j = poly.size() - 1; k < poly.size(); j = k++) {
        a += poly[j].x() * poly[k].y() - poly[k].x() * poly[j].y();
    }
    return a;
}

double cross3(const Eigen::Vector2d &a, const Eigen::Vector2d &b, const Eigen::Vector2d &c)
{
    return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

// q on the segment a-b, given that a, b, q are collinear
bool on_segment(const Eigen::Vector2d &a, const Eigen::Vector2d &b, const Eigen::Vector2d &q)
{
    return q.x() >= std::min(a.x(), b.x()) && q.x() <= std::max(a.x(), b.x()) && q.y() >= std::min(a.y(), b.y()) &&
           q.y() <= std::max(a.y(), b.y());
}

// Segments a-b and c-d share a point (crossing, touching or overlapping).
bool segments_meet(const Eigen::Vector2d &a, const Eigen::Vector2d &b, const Eigen::Vector2d &c, const Eigen::Vector2d &d)
{
    const double d1 = cross3(c, d, a), d2 = cross3(c, d, b), d3 = cross3(a, b, c), d4 = cross3(a, b, d);
    if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) {
        return true;
    }
    return (d1 == 0 && on_segment(c, d, a)) || (d2 == 0 && on_segment(c, d, b)) || (d3 == 0 && on_segment(a, b, c)) ||
           (d4 == 0 && on_segment(a, b, d));
}

// The arena must be a simple polygon: no repeated corner, no edge that
// meets another (only neighbours share their corner, and do not fold back),
// a non-zero area. inside_polygon's even-odd test on a self-intersecting
// outline leaves holes and islands nobody drew. Empty string: simple.
std::string arena_defect(const std::vector<Eigen::Vector2d> &poly)
{
    const size_t n = poly.size();
    auto edge = [&](size_t i) { return "edge " + std::to_string(i) + " " + fmt_xy(poly[i]) + "-" + fmt_xy(poly[(i + 1) % n]); };
    for (size_t i = 0; i < n; ++i) {
        if (poly[i] == poly[(i + 1) % n]) {
            return "corners " + std::to_string(i) + " and " + std::to_string((i + 1) % n) + " are the same point " +
                   fmt_xy(poly[i]);
        }
    }
    for (size_t i = 0; i < n; ++i) {
        for (size_t j = i + 1; j < n; ++j) {
            const Eigen::Vector2d &a = poly[i], &b = poly[(i + 1) % n], &c = poly[j], &d = poly[(j + 1) % n];
            const bool next = j == i + 1, prev = i == 0 && j == n - 1;
            if (next || prev) {
                // neighbours share one corner; they must not run back over each other
                const Eigen::Vector2d &shared = next ? b : a, &u = next ? a : b, &v = next ? d : c;
                if (cross3(u, shared, v) == 0.0 && (u - shared).dot(v - shared) > 0.0) {
                    return edge(i) + " and " + edge(j) + " fold back over each other";
                }
                continue;
            }
            if (segments_meet(a, b, c, d)) {
                return edge(i) + " and " + edge(j) + " cross";
            }
        }
    }
    if (polygon_area2(poly) == 0.0) {
        return "the corners enclose no area";
    }
    return std::string();
}

// Reads the keys of one table and rejects the ones nobody asked for.
class Reader {
public:
    Reader(const toml::table &t, std::string path) : t_(t), path_(std::move(path)) {}

    [[noreturn]] void fail(const std::string &key, const std::string &what) const
    {
        // the line of the offending key when the file has it
        const toml::node *n = t_.get(key);
        const auto line = n != nullptr ? n->source().begin.line : t_.source().begin.line;
        throw ScenarioError((line > 0 ? "line " + std::to_string(line) + ": " : std::string()) + where(key) + ": " +
                            what);
    }

    std::string where(const std::string &key) const { return path_.empty() ? key : path_ + "." + key; }

    const toml::node *get(const std::string &key)
    {
        used_.insert(key);
        return t_.get(key);
    }

    void num(const std::string &key, double &out, double lo = -INFINITY, double hi = INFINITY)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return;
        const auto v = n->value<double>();
        if (!v || !n->is_number()) fail(key, "expected a number");
        if (!std::isfinite(*v) || *v < lo || *v > hi) {
            std::ostringstream s;
            s << "value " << *v << " outside [" << lo << ", " << hi << "]";
            fail(key, s.str());
        }
        out = *v;
    }
    void num(const std::string &key, std::optional<double> &out, double lo = -INFINITY, double hi = INFINITY)
    {
        if (t_.get(key) == nullptr) {
            used_.insert(key);
            return;
        }
        double v = 0.0;
        num(key, v, lo, hi);
        out = v;
    }
    void integer(const std::string &key, int &out, int lo, int hi)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return;
        // is_integer first: value<int64_t>() of a float like 1e308 is UB
        // (found by fuzz_scenario)
        if (!n->is_integer()) fail(key, "expected an integer");
        const auto v = n->value_exact<int64_t>();
        if (!v) fail(key, "expected an integer");
        if (*v < lo || *v > hi) fail(key, "value " + std::to_string(*v) + " outside [" + std::to_string(lo) + ", " +
                                              std::to_string(hi) + "]");
        out = static_cast<int>(*v);
    }
    void u64(const std::string &key, uint64_t &out)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return;
        if (!n->is_integer()) fail(key, "expected a non-negative integer");
        const auto v = n->value_exact<int64_t>();
        if (!v || *v < 0) fail(key, "expected a non-negative integer");
        out = static_cast<uint64_t>(*v);
    }
    void boolean(const std::string &key, bool &out)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return;
        const auto v = n->value<bool>();
        if (!v || !n->is_boolean()) fail(key, "expected true or false");
        out = *v;
    }
    void str(const std::string &key, std::string &out)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return;
        const auto v = n->value<std::string>();
        if (!v || !n->is_string()) fail(key, "expected a string");
        out = *v;
    }
    std::vector<double> numbers(const toml::node &n, const std::string &key, size_t count)
    {
        const toml::array *a = n.as_array();
        if (a == nullptr || a->size() != count) fail(key, "expected an array of " + std::to_string(count) + " numbers");
        std::vector<double> v;
        for (const auto &e : *a) {
            const auto x = e.value<double>();
            if (!x || !e.is_number() || !std::isfinite(*x)) fail(key, "expected finite numbers");
            v.push_back(*x);
        }
        return v;
    }
    void vec2(const std::string &key, Eigen::Vector2d &out)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return;
        const auto v = numbers(*n, key, 2);
        out = Eigen::Vector2d(v[0], v[1]);
    }
    /// [x, y, heading_deg] -> pose with heading in rad.
    void pose_deg(const std::string &key, pose2_t &out)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return;
        const auto v = numbers(*n, key, 3);
        out = pose2_t{v[0], v[1], angle_wrap(v[2] * kDeg)};
    }
    const toml::table *table(const std::string &key)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return nullptr;
        if (!n->is_table()) fail(key, "expected a table");
        return n->as_table();
    }
    const toml::array *array(const std::string &key)
    {
        const toml::node *n = get(key);
        if (n == nullptr) return nullptr;
        if (!n->is_array()) fail(key, "expected an array");
        return n->as_array();
    }
    void require(const std::string &key) const
    {
        if (t_.get(key) == nullptr) fail(key, "missing");
    }
    void done() const
    {
        for (const auto &kv : t_) {
            const std::string k(kv.first.str());
            if (used_.count(k) == 0) fail(k, "unknown key");
        }
    }

private:
    const toml::table &t_;
    std::string path_;
    std::set<std::string> used_;
};

const toml::table &as_table(const toml::node &n, const std::string &where)
{
    if (!n.is_table()) throw ScenarioError(where + ": expected a table");
    return *n.as_table();
}

void read_world(const toml::table &t, WorldSpec &w)
{
    Reader r(t, "world");
    if (const toml::array *a = r.array("arena")) {
        w.arena.clear();
        for (size_t i = 0; i < a->size(); ++i) {
            const auto v = r.numbers((*a)[i], "arena[" + std::to_string(i) + "]", 2);
            w.arena.emplace_back(v[0], v[1]);
        }
        if (w.arena.size() < 3) r.fail("arena", "a polygon needs at least 3 corners");
        const std::string defect = arena_defect(w.arena);
        if (!defect.empty()) {
            r.fail("arena", defect + ": the arena must be a simple polygon (corners in order around it)");
        }
    }
    if (const toml::array *a = r.array("boxes")) {
        for (size_t i = 0; i < a->size(); ++i) {
            const std::string p = "world.boxes[" + std::to_string(i) + "]";
            Reader b(as_table((*a)[i], p), p);
            BoxSpec s;
            b.require("center");
            b.require("size");
            b.vec2("center", s.center);
            b.vec2("size", s.size);
            b.num("angle_deg", s.angle_deg);
            if (s.size.x() <= 0.0 || s.size.y() <= 0.0) b.fail("size", "must be positive");
            b.done();
            w.boxes.push_back(s);
        }
    }
    if (const toml::array *a = r.array("pillars")) {
        for (size_t i = 0; i < a->size(); ++i) {
            const std::string p = "world.pillars[" + std::to_string(i) + "]";
            Reader b(as_table((*a)[i], p), p);
            PillarSpec s;
            b.require("center");
            b.vec2("center", s.center);
            b.num("radius_m", s.radius_m, 1e-3, 100.0);
            b.done();
            w.pillars.push_back(s);
        }
    }
    if (const toml::array *a = r.array("walls")) {
        for (size_t i = 0; i < a->size(); ++i) {
            const std::string p = "world.walls[" + std::to_string(i) + "]";
            Reader b(as_table((*a)[i], p), p);
            WallSpec s;
            b.require("from");
            b.require("to");
            b.vec2("from", s.from);
            b.vec2("to", s.to);
            if (s.from == s.to) {
                // a point: it stops no ray, no robot, and no start check sees it
                b.fail("to", fmt_xy(s.to) + " is the same point as from: a wall needs a length");
            }
            b.done();
            w.walls.push_back(s);
        }
    }
    if (const toml::array *a = r.array("landmarks")) {
        for (size_t i = 0; i < a->size(); ++i) {
            const std::string p = "world.landmarks[" + std::to_string(i) + "]";
            Reader b(as_table((*a)[i], p), p);
            LandmarkSpec s;
            b.require("pos");
            b.vec2("pos", s.pos);
            b.integer("signature", s.signature, 0, 255);
            b.done();
            if (w.arena.size() >= 3 && !inside_polygon(s.pos, w.arena)) {
                b.fail("pos", fmt_xy(s.pos) + " is outside the arena (no robot can reach or see it there)");
            }
            w.landmarks.push_back(s);
        }
    }
    r.done();
}

void read_camera(const toml::table &t, CameraSpec &c)
{
    Reader r(t, "camera");
    std::string source;
    r.str("source", source);
    if (!source.empty()) {
        try {
            c.source = parse_camera_source(source);
        } catch (const ScenarioError &) {
            r.fail("source", "expected \"pixels\" or \"oracle\"");
        }
    }
    r.num("period_ms", c.period_ms, 1.0, 10000.0);
    r.num("fov_deg", c.fov_deg, 1.0, 360.0);
    r.num("min_range_m", c.min_range_m, 0.0, 1000.0);
    r.num("max_range_m", c.max_range_m, 0.01, 1000.0);
    r.num("p_detect", c.p_detect, 0.0, 1.0);
    r.num("range_sd_m", c.range_sd_m, 0.0, 10.0);
    r.num("range_sd_rel", c.range_sd_rel, 0.0, 10.0);
    r.num("bearing_sd_deg", c.bearing_sd_deg, 0.0, 90.0);
    r.num("robot_p_detect", c.robot_p_detect, 0.0, 1.0);
    r.num("robot_range_sd_m", c.robot_range_sd_m, 0.0, 10.0);
    r.num("robot_bearing_sd_deg", c.robot_bearing_sd_deg, 0.0, 90.0);
    r.done();
    if (c.max_range_m <= c.min_range_m) throw ScenarioError("camera.max_range_m: must exceed min_range_m");
}

void read_laser(const toml::table &t, LaserSpec &l)
{
    Reader r(t, "laser");
    r.num("fov_deg", l.fov_deg, 1.0, 240.0);
    r.pose_deg("mount", l.mount);
    r.num("noise_sd_m", l.noise_sd_m, 0.0, 1.0);
    r.num("noise_rel", l.noise_rel, 0.0, 1.0);
    r.num("reply_delay_ms", l.reply_delay_ms, 0.0, 99.0);
    r.done();
}

void read_link(const toml::table &t, LinkSpec &l)
{
    Reader r(t, "link");
    r.num("range_m", l.range_m, 0.0, 1e9);
    r.num("latency_ms", l.latency_ms, 0.0, 60000.0);
    r.num("jitter_ms", l.jitter_ms, 0.0, 60000.0);
    r.num("loss", l.loss, 0.0, 1.0);
    r.done();
}

void read_truth_noise(const toml::table &t, TruthNoiseSpec &n, const std::string &path)
{
    Reader r(t, path);
    r.num("odo_xy_sd_m", n.odo_xy_sd_m, 0.0, 10.0);
    r.num("odo_theta_sd_deg", n.odo_theta_sd_deg, 0.0, 90.0);
    r.num("wheel_slip_sd", n.wheel_slip_sd, 0.0, 1.0);
    r.done();
}

void read_filter_noise(const toml::table &t, FilterNoiseSpec &n, const std::string &path)
{
    Reader r(t, path);
    r.num("range_sd_m", n.range_sd_m, 1e-6, 10.0);
    r.num("range_sd_rel", n.range_sd_rel, 0.0, 10.0);
    r.num("bearing_sd_deg", n.bearing_sd_deg, 1e-6, 90.0);
    r.num("odo_xy_sd_m", n.odo_xy_sd_m, 0.0, 10.0);
    r.num("odo_theta_sd_deg", n.odo_theta_sd_deg, 0.0, 90.0);
    r.num("init_xy_sd_m", n.init_xy_sd_m, 0.0, 100.0);
    r.num("init_theta_sd_deg", n.init_theta_sd_deg, 0.0, 180.0);
    r.num("lm_init_sd_m", n.lm_init_sd_m, 0.0, 100.0);
    r.num("robot_range_sd_m", n.robot_range_sd_m, 1e-6, 10.0);
    r.num("robot_bearing_sd_deg", n.robot_bearing_sd_deg, 1e-6, 90.0);
    r.done();
}

void read_behaviour(const toml::table &t, BehaviourSpec &b)
{
    Reader r(t, "behaviour");
    // the firmware's "< 0: never" is not offered here: a robot that never
    // returns is explore_s beyond duration_s
    r.num("explore_s", b.explore_s, 0.0, 1e6);
    r.num("cruise_mps", b.cruise_mps, 0.01, 2.0);
    r.num("max_turn_dps", b.max_turn_dps, 1.0, 720.0);
    r.num("seek_turn_dps", b.seek_turn_dps, -360.0, 360.0);
    r.num("linger_s", b.linger_s, 0.0, 1e6);
    r.num("goal_tol_m", b.goal_tol_m, 0.01, 100.0);
    r.num("bypass_s", b.bypass_s, 0.0, 1e6);
    r.done();
    if (b.seek_turn_dps == 0.0) throw ScenarioError("behaviour.seek_turn_dps: must not be 0");
}

void read_meeting(const toml::table &t, MeetingSpec &m)
{
    Reader r(t, "meeting");
    r.num("pair_window_ms", m.pair_window_ms, 0.001, 1e6);
    // the robot holds both in microseconds (uint32_t): at most 4000 s, as
    // robot.ini's [merge] resend_s and gap_s; a resend period of 0 would
    // send the map again at every step until max_sends
    r.num("resend_s", m.resend_s, 0.001, 4000.0);
    r.integer("max_sends", m.max_sends, 0, 255);
    r.num("meeting_gap_s", m.meeting_gap_s, 0.0, 4000.0);
    r.num("remerge_s", m.remerge_s, 0.0, 1e6);
    r.num("peer_speed_mps", m.peer_speed_mps, 0.0, 100.0);
    r.num("peer_turn_dps", m.peer_turn_dps, 0.0, 10000.0);
    r.num("max_range_m", m.max_range_m, 0.01, 1000.0);
    r.boolean("transform_uncertainty", m.transform_uncertainty);
    r.num("gate_chi2", m.gate_chi2, 0.01, 1000.0);
    r.integer("step_units", m.step_units, -1, 2147483647);
    r.done();
}

void read_robot(const toml::table &t, size_t i, const Scenario &sc, RobotSpec &rs)
{
    const std::string p = "robot[" + std::to_string(i) + "]";
    Reader r(t, p);
    rs.name = "robot" + std::to_string(i);
    rs.noise = sc.noise;
    r.str("name", rs.name);
    r.require("start");
    r.pose_deg("start", rs.start);
    std::string f = "fastslam2";
    r.str("filter", f);
    try {
        rs.filter = parse_filter_kind(f);
    } catch (const ScenarioError &e) {
        r.fail("filter", e.what());
    }
    r.integer("particles", rs.particles, 1, COSLAM_MAX_PARTICLES);
    r.num("radius_m", rs.radius_m, 0.01, 10.0);
    r.num("explore_s", rs.explore_s, 0.0, 1e6);
    if (const toml::table *n = r.table("noise")) read_truth_noise(*n, rs.noise, p + ".noise");
    if (const toml::table *n = r.table("filter_noise")) read_filter_noise(*n, rs.filter_noise, p + ".filter_noise");
    r.done();
}

// The free space a kidnapped robot lands in, as a start pose is checked.
bool point_is_free(const Scenario &sc, const Eigen::Vector2d &p, double radius, std::string &why)
{
    const WorldSpec &w = sc.world;
    if (w.arena.size() >= 3) {
        if (!inside_polygon(p, w.arena)) {
            why = "outside the arena";
            return false;
        }
        for (size_t k = 0, j = w.arena.size() - 1; k < w.arena.size(); j = k++) {
            if (point_segment_distance(p, w.arena[j], w.arena[k]) < radius) {
                why = "the body (radius " + fmt_g(radius) + " m) overlaps the arena wall";
                return false;
            }
        }
    }
    for (size_t b = 0; b < w.boxes.size(); ++b) {
        const BoxSpec &bx = w.boxes[b];
        const double a = -bx.angle_deg * kDeg;
        const Eigen::Vector2d d = p - bx.center;
        const Eigen::Vector2d q(std::cos(a) * d.x() - std::sin(a) * d.y(), std::sin(a) * d.x() + std::cos(a) * d.y());
        if (std::fabs(q.x()) < 0.5 * bx.size.x() + radius && std::fabs(q.y()) < 0.5 * bx.size.y() + radius) {
            why = "the body overlaps box " + std::to_string(b) + " at " + fmt_xy(bx.center);
            return false;
        }
    }
    for (size_t k = 0; k < w.pillars.size(); ++k) {
        if ((p - w.pillars[k].center).norm() < w.pillars[k].radius_m + radius) {
            why = "the body overlaps pillar " + std::to_string(k) + " at " + fmt_xy(w.pillars[k].center);
            return false;
        }
    }
    for (size_t k = 0; k < w.walls.size(); ++k) {
        const WallSpec &ws = w.walls[k];
        if (point_segment_distance(p, ws.from, ws.to) < radius) {
            why = "the body overlaps wall " + std::to_string(k) + " " + fmt_xy(ws.from) + "-" + fmt_xy(ws.to);
            return false;
        }
    }
    return true;
}

// A robot must start inside the arena, clear of the arena's edge, walls,
// boxes, pillars (point_is_free) and the other robots (its body radius
// around its start position).
void check_start_poses(const Scenario &sc)
{
    for (size_t i = 0; i < sc.robots.size(); ++i) {
        const RobotSpec &r = sc.robots[i];
        const Eigen::Vector2d p(r.start.x, r.start.y);
        const std::string who = "robot[" + std::to_string(i) + "].start " + fmt_xy(p);
        std::string why;
        if (!point_is_free(sc, p, r.radius_m, why)) {
            throw ScenarioError(who + ": " + why);
        }
        for (size_t j = 0; j < i; ++j) {
            const RobotSpec &o = sc.robots[j];
            if ((p - Eigen::Vector2d(o.start.x, o.start.y)).norm() < r.radius_m + o.radius_m) {
                throw ScenarioError(who + ": the body overlaps robot[" + std::to_string(j) + "]");
            }
        }
    }
}

void read_fault(const toml::table &t, size_t i, const Scenario &sc, FaultSpec &f)
{
    const std::string p = "fault[" + std::to_string(i) + "]";
    Reader r(t, p);
    f.line = static_cast<int>(t.source().begin.line);
    r.require("robot");
    r.require("kind");
    r.require("at_s");
    r.integer("robot", f.robot, 0, static_cast<int>(sc.robots.size()) - 1);
    std::string kind;
    r.str("kind", kind);
    static const std::pair<const char *, FaultKind> kinds[] = {
        {"laser_unplug", FaultKind::LaserUnplug}, {"laser_garbage", FaultKind::LaserGarbage},
        {"laser_silent", FaultKind::LaserSilent},
        {"can_errors", FaultKind::CanErrors},     {"drive_emcy", FaultKind::DriveEmcy},
        {"estop", FaultKind::Estop},              {"camera_stall", FaultKind::CameraStall},
        {"link_partition", FaultKind::LinkPartition}, {"kidnap", FaultKind::Kidnap},
        {"odometry_wild", FaultKind::OdometryWild}, {"controller_hang", FaultKind::ControllerHang}};
    bool found = false;
    for (const auto &k : kinds) {
        if (kind == k.first) {
            f.kind = k.second;
            found = true;
        }
    }
    if (!found) {
        r.fail("kind", "unknown fault kind '" + kind +
                           "' (laser_unplug, laser_garbage, laser_silent, can_errors, drive_emcy, estop, camera_stall, "
                           "link_partition, kidnap, odometry_wild, controller_hang)");
    }
    r.num("at_s", f.at_s, 0.0, kMaxDurationS);
    if (f.at_s >= sc.duration_s) {
        // it would never happen (--duration can still shorten a run later:
        // the summary then says "not reached")
        std::ostringstream s;
        s << "at_s " << f.at_s << " is at or after the run's end (duration_s " << sc.duration_s << " s)";
        r.fail("at_s", s.str());
    }
    if (f.kind != FaultKind::Kidnap) r.require("duration_s");
    r.num("duration_s", f.duration_s, 0.0, kMaxDurationS);
    if (f.kind != FaultKind::Kidnap && f.duration_s * 1000.0 < sc.physics_dt_ms) {
        // faults are switched at physics steps: a shorter one is switched
        // on and off in the same step and never acts
        std::ostringstream s;
        s << "duration_s " << f.duration_s << " s is shorter than one physics step (timing.physics_dt_ms "
          << sc.physics_dt_ms << " ms): the fault would end before it acts";
        r.fail("duration_s", s.str());
    }
    // kind-specific keys: only the kind's own are read, so another kind's
    // key is refused by done() as unknown
    switch (f.kind) {
    case FaultKind::LaserGarbage: r.num("bytes_per_ms", f.bytes_per_ms, 0.1, 1000.0); break;
    case FaultKind::CanErrors: r.num("loss", f.loss, 0.0, 1.0); break;
    case FaultKind::DriveEmcy:
        r.integer("wheel", f.wheel, 0, 2);
        r.integer("emcy_code", f.emcy_code, 1, 0xFFFF);
        break;
    case FaultKind::OdometryWild:
        r.num("scale", f.scale, -1000.0, 1000.0);
        r.boolean("garbage", f.garbage);
        break;
    case FaultKind::Kidnap: {
        r.require("to");
        r.pose_deg("to", f.to);
        std::string why;
        const double radius = sc.robots[static_cast<size_t>(f.robot)].radius_m;
        if (!point_is_free(sc, Eigen::Vector2d(f.to.x, f.to.y), radius, why)) {
            r.fail("to", fmt_xy(Eigen::Vector2d(f.to.x, f.to.y)) + " is not free space: " + why);
        }
        break;
    }
    default: break;
    }
    r.done();
}

Scenario parse(const toml::table &root, const std::string &source)
{
    Scenario sc;
    sc.source = source;
    Reader r(root, "");
    r.str("name", sc.name);
    r.str("description", sc.description);
    r.num("duration_s", sc.duration_s, 0.001, kMaxDurationS);
    r.u64("seed", sc.seed);
    if (const toml::table *t = r.table("timing")) {
        Reader tr(*t, "timing");
        tr.num("physics_dt_ms", sc.physics_dt_ms, 0.1, 100.0);
        // at most the robots' master heartbeat period (50 ms): the heartbeat
        // goes out from the step, and the drives' watchdog stops a robot
        // whose steps come less often (docs/robot.md "Drive watchdog")
        tr.num("control_period_ms", sc.control_period_ms, 0.1, 50.0);
        tr.num("sample_period_s", sc.sample_period_s, 0.01, 1e6);
        tr.num("path_period_s", sc.path_period_s, 0.001, 1e6);
        tr.done();
    }
    if (const toml::table *t = r.table("world")) read_world(*t, sc.world);
    if (const toml::table *t = r.table("camera")) read_camera(*t, sc.camera);
    if (const toml::table *t = r.table("laser")) read_laser(*t, sc.laser);
    if (const toml::table *t = r.table("link")) read_link(*t, sc.link);
    if (const toml::table *t = r.table("noise")) read_truth_noise(*t, sc.noise, "noise");
    if (const toml::table *t = r.table("behaviour")) read_behaviour(*t, sc.behaviour);
    if (const toml::table *t = r.table("meeting")) read_meeting(*t, sc.meeting);
    if (const toml::table *t = r.table("evaluation")) {
        Reader er(*t, "evaluation");
        er.num("gate_m", sc.evaluation.gate_m, 0.001, 100.0);
        er.integer("min_seen", sc.evaluation.min_seen, 1, 1000000);
        er.done();
    }
    const toml::array *robots = r.array("robot");
    if (robots == nullptr || robots->size() < 2) {
        throw ScenarioError("robot: at least two [[robot]] tables are needed (the meeting needs a team)");
    }
    if (robots->size() > COSLAM_MAX_ROBOTS) {
        throw ScenarioError("robot: at most " + std::to_string(COSLAM_MAX_ROBOTS) + " robots");
    }
    for (size_t i = 0; i < robots->size(); ++i) {
        RobotSpec rs;
        read_robot(as_table((*robots)[i], "robot[" + std::to_string(i) + "]"), i, sc, rs);
        sc.robots.push_back(rs);
    }
    if (const toml::array *faults = r.array("fault")) {
        for (size_t i = 0; i < faults->size(); ++i) {
            FaultSpec f;
            read_fault(as_table((*faults)[i], "fault[" + std::to_string(i) + "]"), i, sc, f);
            sc.faults.push_back(f);
        }
    }
    r.done();
    check_start_poses(sc);
    if (std::fmod(sc.control_period_ms + 1e-9, sc.physics_dt_ms) > 1e-6) {
        throw ScenarioError("timing.control_period_ms: must be a multiple of physics_dt_ms");
    }
    if (std::fabs(sc.physics_dt_ms * 1000.0 - std::round(sc.physics_dt_ms * 1000.0)) > 1e-9) {
        throw ScenarioError("timing.physics_dt_ms: must be a whole number of microseconds");
    }
    return sc;
}

}  // namespace

CameraSource parse_camera_source(const std::string &s)
{
    if (s == "pixels") return CameraSource::Pixels;
    if (s == "oracle") return CameraSource::Oracle;
    throw ScenarioError("camera source '" + s + "': expected pixels or oracle");
}

const char *camera_source_name(CameraSource s)
{
    return s == CameraSource::Pixels ? "pixels" : "oracle";
}

const char *fault_kind_name(FaultKind k)
{
    switch (k) {
    case FaultKind::LaserUnplug: return "laser_unplug";
    case FaultKind::LaserGarbage: return "laser_garbage";
    case FaultKind::LaserSilent: return "laser_silent";
    case FaultKind::CanErrors: return "can_errors";
    case FaultKind::DriveEmcy: return "drive_emcy";
    case FaultKind::Estop: return "estop";
    case FaultKind::CameraStall: return "camera_stall";
    case FaultKind::LinkPartition: return "link_partition";
    case FaultKind::Kidnap: return "kidnap";
    case FaultKind::OdometryWild: return "odometry_wild";
    case FaultKind::ControllerHang: return "controller_hang";
    }
    return "?";
}

slam_filter_kind_t parse_filter_kind(const std::string &s)
{
    if (s == "fastslam1") return SLAM_FILTER_FASTSLAM1;
    if (s == "fastslam2") return SLAM_FILTER_FASTSLAM2;
    if (s == "ekf") return SLAM_FILTER_EKF;
    throw ScenarioError("unknown filter '" + s + "' (fastslam1, fastslam2 or ekf)");
}

Scenario load_scenario_string(const std::string &toml_text, const std::string &source)
{
    toml::table root;
    try {
        root = toml::parse(toml_text, source);
    } catch (const toml::parse_error &e) {
        std::ostringstream s;
        s << source << ":" << e.source().begin.line << ":" << e.source().begin.column << ": " << e.description();
        throw ScenarioError(s.str());
    }
    try {
        return parse(root, source);
    } catch (const ScenarioError &e) {
        throw ScenarioError(source + ": " + e.what());
    }
}

Scenario load_scenario_file(const std::string &path)
{
    // a directory opens as an empty stream on Linux: said, not read as an
    // empty scenario
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (ec) {
        throw ScenarioError(path + ": cannot open: " + ec.message());
    }
    if (std::filesystem::is_directory(st)) {
        throw ScenarioError(path + ": is a directory, not a scenario file");
    }
    if (!std::filesystem::is_regular_file(st)) {
        throw ScenarioError(path + ": not a regular file");
    }
    std::ifstream f(path);
    if (!f) {
        throw ScenarioError(path + ": cannot open");
    }
    std::stringstream ss;
    ss << f.rdbuf();
    if (f.bad()) {
        throw ScenarioError(path + ": read error");
    }
    return load_scenario_string(ss.str(), path);
}

}  // namespace coslam::sim
