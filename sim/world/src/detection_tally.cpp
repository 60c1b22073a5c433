#include "sim/world/detection_tally.hpp"

#include <cmath>
#include <limits>

#include "coslam/landmark.h"
#include "coslam/observe.h"

namespace coslam::sim {

std::vector<ViewedLandmark> landmarks_in_filter_view(const World &world, int self, const pose2_t &pose,
                                                     const slam_params_t &view_model)
{
    std::vector<ViewedLandmark> out;
    const Eigen::Vector2d cam(pose.x, pose.y);
    for (const auto &lm : world.landmarks()) {
        const sighting_t zhat = observe_predict(pose, point2_t{lm.p.x(), lm.p.y()});
        if (!landmark_should_be_seen(&view_model, zhat)) continue;
        out.push_back(ViewedLandmark{lm.id, world.line_of_sight(cam, lm.p, self, -1)});
    }
    return out;
}

void tally_frame(DetectionTally &t, const std::vector<ViewedLandmark> &viewed, const std::vector<uint8_t> &detected)
{
    t.frames++;
    for (const auto &v : viewed) {
        const bool hit = v.id >= 0 && static_cast<size_t>(v.id) < detected.size() && detected[static_cast<size_t>(v.id)];
        t.in_view++;
        t.detected += hit;
        if (v.clear) {
            t.in_view_clear++;
            t.detected_clear += hit;
        }
    }
}

double detection_rate(const DetectionTally &t)
{
    return t.in_view > 0 ? static_cast<double>(t.detected) / static_cast<double>(t.in_view)
                         : std::numeric_limits<double>::quiet_NaN();
}

double detection_rate_clear(const DetectionTally &t)
{
    return t.in_view_clear > 0 ? static_cast<double>(t.detected_clear) / static_cast<double>(t.in_view_clear)
                               : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace coslam::sim
