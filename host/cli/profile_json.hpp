// host/cli/profile_json.hpp - the build's capacity profile (app/profile.h)
// as a JSON object, the "profile" entry of every tool's metrics.json /
// report.json (header only; needs nlohmann_json and coslam_app_filter).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "app/profile.h"

namespace coslam {

inline nlohmann::json profile_json()
{
    const app_profile_t p = app_profile();
    return {{"name", p.name},
            {"particles", p.particles},
            {"landmarks", p.landmarks},
            {"ekf_landmarks", p.ekf_landmarks},
            {"sightings_per_frame", p.sightings},
            {"msg_landmarks", p.msg_landmarks},
            {"msg_max_bytes", p.msg_max_bytes},
            {"link_payload_bytes", p.link_payload_bytes}};
}

/// The start-up line: "<tool>: profile ...".
inline std::string profile_line(const char *tool)
{
    char buf[192];
    (void)app_profile_format(buf, sizeof buf);
    return std::string(tool) + ": " + buf;
}

} // namespace coslam
