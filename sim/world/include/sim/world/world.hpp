// sim/world/world.hpp - the simulated arena: walls, obstacles, landmark
// markers and the robots' bodies, with the geometric queries the device
// emulators need (laser ray casting, camera line of sight, collisions).
//
// Geometry is 2-D, world frame, metres and radians (x east, y north,
// angles counter-clockwise). Walls are line segments (an arena polygon, box
// obstacles and free walls are all turned into segments); pillars are
// circles; robots are discs that move. Landmarks are points (coloured
// two-colour markers fixed on walls and obstacles): they never block a ray;
// a marker is seen if nothing blocks the line from the camera to it.
//
// Queries are O(walls + circles + bodies); the default arena has ~30 of them.
#ifndef COSLAM_SIM_WORLD_WORLD_HPP
#define COSLAM_SIM_WORLD_WORLD_HPP

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "coslam/pose2.h"

namespace coslam::sim {

struct WallSegment {
    Eigen::Vector2d a, b;
};

struct Pillar {
    Eigen::Vector2d c;
    double r = 0.0;
};

struct LandmarkMarker {
    int id = 0;              ///< index in landmarks(), the ground-truth identity
    Eigen::Vector2d p;
    uint8_t signature = 0;   ///< marker class (colour pair); not unique
};

struct RobotBody {
    int id = 0;
    pose2_t pose{0.0, 0.0, 0.0};
    double radius_m = 0.19;
};

class World {
public:
    /// Closed polygon of walls (e.g. the arena boundary), corners in order.
    void add_polygon(const std::vector<Eigen::Vector2d> &corners);
    void add_wall(const Eigen::Vector2d &a, const Eigen::Vector2d &b);
    /// Rectangle of size (w, h) centred at c, rotated by angle_rad.
    void add_box(const Eigen::Vector2d &c, const Eigen::Vector2d &size, double angle_rad);
    void add_pillar(const Eigen::Vector2d &c, double r);
    /// Returns the new landmark's id (its index).
    int add_landmark(const Eigen::Vector2d &p, uint8_t signature);
    /// Add or move robot `id`'s body.
    void set_body(int id, const pose2_t &pose, double radius_m);

    const std::vector<WallSegment> &walls() const { return walls_; }
    const std::vector<Pillar> &pillars() const { return pillars_; }
    const std::vector<LandmarkMarker> &landmarks() const { return landmarks_; }
    const std::vector<RobotBody> &bodies() const { return bodies_; }
    const RobotBody *body(int id) const;

    /// Distance along the unit direction `dir` from `o` to the first wall,
    /// pillar or robot body (other than body `exclude_body`), or +infinity
    /// if nothing is hit within max_m.
    double raycast(const Eigen::Vector2d &o, const Eigen::Vector2d &dir, double max_m, int exclude_body = -1,
                   bool hit_bodies = true) const;
    /// True if nothing (walls, pillars, bodies other than the two excluded)
    /// blocks the segment from a to b; the last `end_margin_m` before b is
    /// not checked (a marker on a wall is not hidden by its own wall).
    bool line_of_sight(const Eigen::Vector2d &a, const Eigen::Vector2d &b, int exclude_a, int exclude_b,
                       double end_margin_m = 0.05) const;
    /// Distance from p to the nearest wall or pillar surface (negative
    /// inside a pillar).
    double static_clearance(const Eigen::Vector2d &p) const;
    /// Distance from p to the nearest rim of a robot body other than
    /// exclude_body (+infinity if none; negative inside one).
    double body_clearance(const Eigen::Vector2d &p, int exclude_body) const;

private:
    std::vector<WallSegment> walls_;
    std::vector<Pillar> pillars_;
    std::vector<LandmarkMarker> landmarks_;
    std::vector<RobotBody> bodies_;
};

/// Point-to-segment distance.
double segment_distance(const Eigen::Vector2d &p, const WallSegment &s);

}  // namespace coslam::sim

#endif
