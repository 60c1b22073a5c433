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
 */
#include <errno.h>
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
