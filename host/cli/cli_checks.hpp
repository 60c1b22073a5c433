// host/cli/cli_checks.hpp - CLI11 validators every host tool uses for its
// numeric options. CLI::Range lets "nan" through (every comparison with NaN
// is false) and prints bounds as long decimals; these do not.
#ifndef COSLAM_HOST_CLI_CHECKS_HPP
#define COSLAM_HOST_CLI_CHECKS_HPP

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace coslam::cli {

inline std::string fmt_g(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

/// A finite number in [lo, hi] ((lo, hi] with lo_open): nan, inf and
/// overflowing text are refused with the allowed range in the message.
inline CLI::Validator finite_in(double lo, double hi, bool lo_open = false)
{
    const std::string desc = std::string(lo_open ? "(" : "[") + fmt_g(lo) + ", " + fmt_g(hi) + "]";
    return CLI::Validator(
        [lo, hi, lo_open, desc](std::string &s) -> std::string {
            errno = 0;
            char *end = nullptr;
            const double v = std::strtod(s.c_str(), &end);
            if (end == s.c_str() || *end != '\0' || !std::isfinite(v) || (errno == ERANGE && std::fabs(v) > 1.0)) {
                return "not a finite number: " + s.substr(0, 40);
            }
            if (!(lo_open ? v > lo : v >= lo) || !(v <= hi)) {
                return "value " + fmt_g(v) + " outside " + desc;
            }
            return std::string();
        },
        "FLOAT in " + desc, "FINITE_IN");
}

/// An integer in [lo, hi] (the text must be an integer: "1e3", "5.0" are refused).
inline CLI::Validator int_in(long long lo, long long hi)
{
    const std::string desc = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    return CLI::Validator(
        [lo, hi, desc](std::string &s) -> std::string {
            errno = 0;
            char *end = nullptr;
            const long long v = std::strtoll(s.c_str(), &end, 10);
            if (end == s.c_str() || *end != '\0' || errno == ERANGE) {
                return "not an integer: " + s.substr(0, 40);
            }
            if (v < lo || v > hi) {
                return "value " + std::to_string(v) + " outside " + desc;
            }
            return std::string();
        },
        "INT in " + desc, "INT_IN");
}

/// app.parse with the house's exit statuses: returns -1 when parsed (go
/// on), else the status to exit with: 0 for --help, 2 for a bad option or
/// value (a usage error; CLI11 says which). CLI11_PARSE would exit with
/// CLI11's own codes (105 for a value a check refused).
inline int parse_usage(CLI::App &app, int argc, char **argv)
{
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError &e) {
        return app.exit(e) == 0 ? 0 : 2;
    }
    return -1;
}

} // namespace coslam::cli

#endif
