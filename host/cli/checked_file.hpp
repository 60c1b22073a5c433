// checked_file.hpp - output files of the host tools that are checked after
// writing: a write that failed (a full disk) is an error naming the file and
// the OS's reason, never a silently short file. Header only (coslam_cli).
#ifndef COSLAM_HOST_CLI_CHECKED_FILE_HPP
#define COSLAM_HOST_CLI_CHECKED_FILE_HPP

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>

#include "stdout_check.h"

namespace coslam::cli {

/// An output file that could not be opened or written whole. A distinct type
/// so a tool can give it its own exit status (coslam-replay: 1).
class WriteError : public std::runtime_error {
public:
    /// "cannot VERB PATH: REASON"; err is the errno of the failure (0: the
    /// OS gave none, "open or write failed").
    WriteError(const std::string &path, int err, const std::string &verb = "write")
        : std::runtime_error("cannot " + verb + " " + path + ": " +
                             (err != 0 ? std::string(std::strerror(err)) : std::string("open or write failed")))
    {
    }
};

/// Open path for writing (mode: e.g. std::ios::binary added); throw
/// WriteError with the OS's reason if it cannot be opened. errno is cleared
/// first, so a later close_checked names the reason of this file's failed
/// write, not that of an older call.
inline std::ofstream open_checked(const std::string &path, std::ios::openmode mode = std::ios::out)
{
    errno = 0;
    std::ofstream f(path, mode | std::ios::out);
    if (!f) {
        throw WriteError(path, errno);
    }
    return f;
}

/// Close f (if open) and throw WriteError (path and the OS's reason, e.g.
/// "No space left on device") if its open, any write or the final flush
/// failed. A stream that failed before the close keeps the errno of its
/// failed write (nothing between sets it on a failed stream).
inline void close_checked(std::ofstream &f, const std::string &path)
{
    const bool failed_before = !f;
    const int err_before = errno;
    errno = 0;
    if (f.is_open()) {
        f.close();
    }
    if (!f) {
        throw WriteError(path, errno != 0 ? errno : (failed_before ? err_before : 0));
    }
}

/// Write text to path, checked.
inline void write_text_file(const std::string &path, const std::string &text)
{
    std::ofstream f = open_checked(path);
    f << text;
    close_checked(f, path);
}

/// Flush standard output (std::cout and C's stdout) and say whether
/// anything written to it was lost: 0 if all of it went out, else the errno
/// of the failure, or STDOUT_CHECK_LOST_EARLIER when only an earlier write
/// failed (a std::endl of the tool's) and stdio kept no reason. A failed
/// write is sticky (std::cout's badbit, stdout's error flag), so a tool
/// calls this once, before it exits: its output to a full disk or to a pipe
/// closed with SIGPIPE ignored is then an error, not an exit 0 with the
/// output lost. C's half is stdout_check_flush_error (stdout_check.h,
/// shared with the C tools).
inline int stdout_flush_error()
{
    errno = 0;
    std::cout.flush(); // with sync_with_stdio (the default) also fflush(stdout)
    const int err = std::cout.good() ? 0 : errno;
    const int c_err = stdout_check_flush_error();
    if (c_err == 0 && std::cout.good()) {
        return 0;
    }
    return err != 0 ? err : (c_err != 0 ? c_err : STDOUT_CHECK_LOST_EARLIER);
}

/// The exit status of a C++ tool that would exit with rc, standard output
/// checked (stdout_flush_error): rc if nothing was lost; else "TOOL: cannot
/// write standard output: REASON" on stderr and 1, bad usage (2) staying 2
/// (stdout_check_status, stdout_check.h). The last call of main.
inline int stdout_exit(const char *tool, int rc)
{
    return stdout_check_status(tool, rc, stdout_flush_error());
}

} // namespace coslam::cli

#endif
