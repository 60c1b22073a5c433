/*
 * fsync_gate.so - LD_PRELOAD shim for test_robot_process slow_storage: while
 * the file named by COSLAM_TEST_FSYNC_GATE exists, fsync(2) waits (polling
 * every millisecond, at most 30 s), as an SD card's fsync does while it
 * collects garbage. While the file named by COSLAM_TEST_FSYNC_FAIL exists,
 * fsync(2) fails at once with EIO, as on a medium whose write-back fails
 * (the write before it succeeded); with COSLAM_TEST_FSYNC_FAIL_ABOVE=N
 * set as well, only the fsync of a regular file of more than N bytes
 * fails (a medium that takes a small write and fails larger ones: the
 * storage's one-byte probe file works, a snapshot does not). Without the
 * variables fsync is the C library's.
 *
 * Reads: while the file named by COSLAM_TEST_READ_GATE exists, fstat(2) of
 * an open file named snapshot.a waits the same way (the storage's read
 * opens a blob, fstats it, then reads it), as a medium that has just come
 * back is slow to read. Without the variable fstat is the C library's.
 */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <dlfcn.h>
#include <stdlib.h>
#include <time.h>
#include <sys/stat.h>
#include <unistd.h>

int fsync(int fd)
{
    static int (*real_fsync)(int);
    if (real_fsync == NULL) {
        real_fsync = (int (*)(int))dlsym(RTLD_NEXT, "fsync");
    }
    const char *fail = getenv("COSLAM_TEST_FSYNC_FAIL");
    if (fail != NULL && access(fail, F_OK) == 0) {
        const char *above = getenv("COSLAM_TEST_FSYNC_FAIL_ABOVE");
        struct stat sb;
        if (above == NULL ||
            (fstat(fd, &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size > (off_t)strtol(above, NULL, 10))) {
            errno = EIO;
            return -1;
        }
    }
    const char *gate = getenv("COSLAM_TEST_FSYNC_GATE");
    if (gate != NULL) {
        const struct timespec ms = {0, 1000000L};
        for (int i = 0; i < 30000 && access(gate, F_OK) == 0; ++i) {
            (void)nanosleep(&ms, NULL);
        }
    }
    return real_fsync != NULL ? real_fsync(fd) : -1;
}

/* 1 if fd is an open file whose name is snapshot.a (its /proc link). */
static int is_gated_blob(int fd)
{
    char link[64];
    char path[4096];
    (void)snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    const ssize_t n = readlink(link, path, sizeof path - 1U);
    if (n <= 0) {
        return 0;
    }
    path[n] = '\0';
    const char *base = strrchr(path, '/');
    return base != NULL && strcmp(base + 1, "snapshot.a") == 0;
}

int fstat(int fd, struct stat *sb)
{
    static int (*real_fstat)(int, struct stat *);
    if (real_fstat == NULL) {
        real_fstat = (int (*)(int, struct stat *))dlsym(RTLD_NEXT, "fstat");
    }
    const char *gate = getenv("COSLAM_TEST_READ_GATE");
    if (gate != NULL && access(gate, F_OK) == 0 && is_gated_blob(fd)) {
        const struct timespec ms = {0, 1000000L};
        for (int i = 0; i < 30000 && access(gate, F_OK) == 0; ++i) {
            (void)nanosleep(&ms, NULL);
        }
    }
    if (real_fstat == NULL) {
        errno = ENOSYS;
        return -1;
    }
    return real_fstat(fd, sb);
}
