#include "sim/world/world.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace coslam::sim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double cross(const Eigen::Vector2d &a, const Eigen::Vector2d &b)
{
    return a.x() * b.y() - a.y() * b.x();
}

// Ray o + t d (t >= 0) against segment [a, b]: smallest t, or inf.
double ray_segment(const Eigen::Vector2d &o, const Eigen::Vector2d &d, const WallSegment &s)
{
    const Eigen::Vector2d e = s.b - s.a;
    const double den = cross(d, e);
    if (std::fabs(den) < 1e-15) {
        return kInf; // parallel (a grazing ray along a wall sees its end points via the neighbours)
    }
    const Eigen::Vector2d w = s.a - o;
    const double t = cross(w, e) / den;
    const double u = cross(w, d) / den;
    if (t < 0.0 || u < 0.0 || u > 1.0) {
        return kInf;
    }
    return t;
}

// Ray against a circle: the first crossing of its rim with t >= 0 (a ray
// starting inside hits the rim on the way out).
double ray_circle(const Eigen::Vector2d &o, const Eigen::Vector2d &d, const Eigen::Vector2d &c, double r)
{
    const Eigen::Vector2d oc = o - c;
    const double b = oc.dot(d);
    const double cc = oc.squaredNorm() - r * r;
    const double disc = b * b - cc;
    if (disc < 0.0) {
        return kInf;
    }
    const double sq = std::sqrt(disc);
    const double t0 = -b - sq;
    const double t1 = -b + sq;
    if (t0 >= 0.0) {
        return t0;
    }
    return t1 >= 0.0 ? t1 : kInf;
}

}  // namespace

double segment_distance(const Eigen::Vector2d &p, const WallSegment &s)
{
    const Eigen::Vector2d e = s.b - s.a;
    const double l2 = e.squaredNorm();
    double t = l2 > 0.0 ? (p - s.a).dot(e) / l2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return (s.a + t * e - p).norm();
}

void World::add_polygon(const std::vector<Eigen::Vector2d> &corners)
{
    for (size_t i = 0; i < corners.size(); ++i) {
        add_wall(corners[i], corners[(i + 1) % corners.size()]);
    }
}

void World::add_wall(const Eigen::Vector2d &a, const Eigen::Vector2d &b)
{
    walls_.push_back(WallSegment{a, b});
}

void World::add_box(const Eigen::Vector2d &c, const Eigen::Vector2d &size, double angle_rad)
{
    const double cs = std::cos(angle_rad), sn = std::sin(angle_rad);
    const Eigen::Vector2d ux(cs, sn), uy(-sn, cs);
    const double hx = 0.5 * size.x(), hy = 0.5 * size.y();
    add_polygon({c - hx * ux - hy * uy, c + hx * ux - hy * uy, c + hx * ux + hy * uy, c - hx * ux + hy * uy});
}

void World::add_pillar(const Eigen::Vector2d &c, double r)
{
    pillars_.push_back(Pillar{c, r});
}

int World::add_landmark(const Eigen::Vector2d &p, uint8_t signature)
{
    const int id = static_cast<int>(landmarks_.size());
    landmarks_.push_back(LandmarkMarker{id, p, signature});
    return id;
}

void World::set_body(int id, const pose2_t &pose, double radius_m)
{
    for (auto &b : bodies_) {
        if (b.id == id) {
            b.pose = pose;
            b.radius_m = radius_m;
            return;
        }
    }
    bodies_.push_back(RobotBody{id, pose, radius_m});
}

const RobotBody *World::body(int id) const
{
    for (const auto &b : bodies_) {
        if (b.id == id) return &b;
    }
    return nullptr;
}

double World::raycast(const Eigen::Vector2d &o, const Eigen::Vector2d &dir, double max_m, int exclude_body,
                      bool hit_bodies) const
{
    double best = kInf;
    for (const auto &w : walls_) best = std::min(best, ray_segment(o, dir, w));
    for (const auto &p : pillars_) best = std::min(best, ray_circle(o, dir, p.c, p.r));
    if (hit_bodies) {
        for (const auto &b : bodies_) {
            if (b.id == exclude_body) continue;
            best = std::min(best, ray_circle(o, dir, Eigen::Vector2d(b.pose.x, b.pose.y), b.radius_m));
        }
    }
    return best <= max_m ? best : kInf;
}

bool World::line_of_sight(const Eigen::Vector2d &a, const Eigen::Vector2d &b, int exclude_a, int exclude_b,
                          double end_margin_m) const
{
    const Eigen::Vector2d d = b - a;
    const double len = d.norm();
    if (len <= end_margin_m) {
        return true;
    }
    const Eigen::Vector2d u = d / len;
    const double reach = len - end_margin_m;
    for (const auto &w : walls_) {
        if (ray_segment(a, u, w) <= reach) return false;
    }
    for (const auto &p : pillars_) {
        if (ray_circle(a, u, p.c, p.r) <= reach) return false;
    }
    for (const auto &bd : bodies_) {
        if (bd.id == exclude_a || bd.id == exclude_b) continue;
        if (ray_circle(a, u, Eigen::Vector2d(bd.pose.x, bd.pose.y), bd.radius_m) <= reach) return false;
    }
    return true;
}

double World::static_clearance(const Eigen::Vector2d &p) const
{
    double best = kInf;
    for (const auto &w : walls_) best = std::min(best, segment_distance(p, w));
    for (const auto &pl : pillars_) best = std::min(best, (p - pl.c).norm() - pl.r);
    return best;
}

double World::body_clearance(const Eigen::Vector2d &p, int exclude_body) const
{
    double best = kInf;
    for (const auto &b : bodies_) {
        if (b.id == exclude_body) continue;
        best = std::min(best, (p - Eigen::Vector2d(b.pose.x, b.pose.y)).norm() - b.radius_m);
    }
    return best;
}

}  // namespace coslam::sim
