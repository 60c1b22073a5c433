// data_dir.hpp - the folder holding the shared data (mrclam/...) for the host
// tools that read it by default (coslam-calibrate, coslam-bench-mrclam). The
// environment variable COSLAM_DATA_DIR, when set and not empty, overrides the
// build's default (the CMake define of the same name), as tools/run_replay.sh
// and tools/merge_table.sh read it (docs/replay.md). Header only (coslam_cli).
#ifndef COSLAM_HOST_CLI_DATA_DIR_HPP
#define COSLAM_HOST_CLI_DATA_DIR_HPP

#include <cstdlib>
#include <string>

namespace coslam::cli {

/// $COSLAM_DATA_DIR if set and not empty, else build_default.
inline std::string data_dir(const char *build_default)
{
    const char *env = std::getenv("COSLAM_DATA_DIR");
    return std::string(env != nullptr && env[0] != '\0' ? env : build_default);
}

} // namespace coslam::cli

#endif
