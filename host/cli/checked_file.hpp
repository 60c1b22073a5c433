// checked_file.hpp - output files of the host tools that are checked after
// writing: a write that failed (a full disk) is an error naming the file,
// never a silently short file. Header only (coslam_cli).
#ifndef COSLAM_HOST_CLI_CHECKED_FILE_HPP
#define COSLAM_HOST_CLI_CHECKED_FILE_HPP

#include <fstream>
#include <stdexcept>
#include <string>

namespace coslam::cli {

/// Close f (if open) and throw "cannot write PATH (open or write failed)"
/// if its open or any write failed.
inline void close_checked(std::ofstream &f, const std::string &path)
{
    if (f.is_open()) {
        f.close();
    }
    if (!f) {
        throw std::runtime_error("cannot write " + path + " (open or write failed)");
    }
}

/// Write text to path, checked.
inline void write_text_file(const std::string &path, const std::string &text)
{
    std::ofstream f(path);
    f << text;
    close_checked(f, path);
}

} // namespace coslam::cli

#endif
