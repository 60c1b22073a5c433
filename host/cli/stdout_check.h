/* host/cli/stdout_check.h - standard output checked at the end of a host
 * tool, C and C++ alike (coslam_cli, header only). What a tool prints is
 * one of its outputs: lost to a full disk or to a pipe closed while SIGPIPE
 * is ignored, it is an error ("<tool>: cannot write standard output: <OS
 * reason>", exit 1), never an exit 0 with the results gone. A failed write
 * is sticky (stdout's error flag), so a tool checks once, as it returns
 * from main:
 *
 *     int main(int argc, char **argv)
 *     {
 *         return stdout_check_exit("coslam-x", x_main(argc, argv));
 *     }
 *
 * C++ tools call coslam::cli::stdout_exit (checked_file.hpp), which flushes
 * std::cout first and ends here. */
#ifndef COSLAM_HOST_CLI_STDOUT_CHECK_H
#define COSLAM_HOST_CLI_STDOUT_CHECK_H

#include <errno.h>
#include <stdio.h>
#include <string.h>

/* Exit status of a tool whose standard output could not be written whole,
 * the same as for an output file that could not (README: "cannot write
 * <path>: <OS reason>" and exit 1). */
#define STDOUT_CHECK_EXIT_WRITE 1
/* Bad usage: kept when standard output failed too (nothing was run; the
 * lost output is said as well). */
#define STDOUT_CHECK_EXIT_USAGE 2
/* stdout_check_flush_error: a write failed before this flush and its errno
 * is gone: stdio keeps only the error flag. That is a flush of the tool's
 * not made through stdout_check_flush (std::endl), or stdio writing its
 * full buffer (output longer than the buffer, 4 KiB on a file: a long
 * --help). Said as "a write failed", not as an OS reason it was not. */
#define STDOUT_CHECK_LOST_EARLIER (-1)

/* The errno of the first failed stdout_check_flush (0: none failed). One
 * per program in C++; one per file in C (static inline), where a tool
 * flushes and checks in the file of its main. */
#ifdef __cplusplus
inline int *stdout_check_kept_errno(void)
#else
static inline int *stdout_check_kept_errno(void)
#endif
{
    static int kept;
    return &kept;
}

/* Flush stdout now, for output that must go out at once (a start-up line,
 * a progress line, a streamed record): 0, or -1 if the flush failed, whose
 * errno is then kept for stdout_check_exit (stdio keeps only the error
 * flag, so the final check could no longer say why). */
static inline int stdout_check_flush(void)
{
    errno = 0;
    if (fflush(stdout) == 0) {
        return 0;
    }
    int *kept = stdout_check_kept_errno();
    if (*kept == 0 && errno != 0) {
        *kept = errno;
    }
    return -1;
}

/* Flush C's stdout: 0 if all that was written to it went out; else the
 * errno of this flush's failure or of the first failed
 * stdout_check_flush, or STDOUT_CHECK_LOST_EARLIER if only another,
 * earlier flush failed (the error flag set, nothing left to write). */
static inline int stdout_check_flush_error(void)
{
    errno = 0;
    const int rc = fflush(stdout);
    const int err = errno;
    if (rc == 0 && !ferror(stdout)) {
        return 0;
    }
    if (rc != 0 && err != 0) {
        return err;
    }
    const int kept = *stdout_check_kept_errno();
    return kept != 0 ? kept : STDOUT_CHECK_LOST_EARLIER;
}

/* The exit status of a tool that would exit with rc, its standard output
 * having failed with err (0: it did not; else an errno or
 * STDOUT_CHECK_LOST_EARLIER): rc when err is 0; else "<tool>: cannot write
 * standard output: <strerror(err) or 'a write failed'>" on stderr and
 * STDOUT_CHECK_EXIT_WRITE, except that bad usage (STDOUT_CHECK_EXIT_USAGE)
 * stays. Every other code yields to the lost output (coslam-sim's and
 * coslam-replay's 3, a capacity hit; coslam-bench-odo-check's 3, a drive
 * flagged), as a lost output file does. */
static inline int stdout_check_status(const char *tool, int rc, int err)
{
    if (err == 0) {
        return rc;
    }
    fprintf(stderr, "%s: cannot write standard output: %s\n", tool,
            err > 0 ? strerror(err) : "a write failed");
    return rc == STDOUT_CHECK_EXIT_USAGE ? rc : STDOUT_CHECK_EXIT_WRITE;
}

/* stdout_check_status with stdout flushed here: the last call of a C
 * tool's main. */
static inline int stdout_check_exit(const char *tool, int rc)
{
    return stdout_check_status(tool, rc, stdout_check_flush_error());
}

#endif /* COSLAM_HOST_CLI_STDOUT_CHECK_H */
