/* host/cli/checked_file.h - output files of the C host tools, checked
 * (coslam_cli, header only; the C++ tools have checked_file.hpp): a file
 * that cannot be opened, or whose writes or final flush failed (a full
 * disk), is "<tool>: cannot write <path>: <OS reason>" on stderr, never a
 * silently short file and an exit 0. stdio keeps a failed write in the
 * file's error flag, so a tool writes with plain fprintf and checks once,
 * at the close:
 *
 *     FILE *f = checked_file_open("coslam-x", path);
 *     if (f == NULL) return 1;
 *     fprintf(f, ...);
 *     if (checked_file_close("coslam-x", f, path) != 0) return 1;
 *
 * The tools then exit 1 (README), as for standard output lost
 * (stdout_check.h). */
#ifndef COSLAM_HOST_CLI_CHECKED_FILE_H
#define COSLAM_HOST_CLI_CHECKED_FILE_H

#include <errno.h>
#include <stdio.h>
#include <string.h>

/* Open path for writing: the stream, or NULL with "<tool>: cannot write
 * <path>: <OS reason>" on stderr. */
static inline FILE *checked_file_open(const char *tool, const char *path)
{
    errno = 0;
    FILE *f = fopen(path, "w");
    if (f == NULL) {
        fprintf(stderr, "%s: cannot write %s: %s\n", tool, path, errno != 0 ? strerror(errno) : "open failed");
    }
    return f;
}

/* Close f, written to path: a write or the final flush that failed (a full
 * disk) is said as "<tool>: cannot write <path>: <OS reason>", or "a write
 * failed" where stdio kept no reason (a write made as the buffer filled,
 * the close's flush then having nothing left to fail on). Returns 0, or -1
 * on an error. f NULL: nothing to do. f is closed either way. */
static inline int checked_file_close(const char *tool, FILE *f, const char *path)
{
    if (f == NULL) {
        return 0;
    }
    const int bad = ferror(f);
    errno = 0;
    const int rc = fclose(f);
    if (rc != 0 || bad) {
        fprintf(stderr, "%s: cannot write %s: %s\n", tool, path, errno != 0 ? strerror(errno) : "a write failed");
        return -1;
    }
    return 0;
}

#endif /* COSLAM_HOST_CLI_CHECKED_FILE_H */
