/*
 * fsync_gate.so - LD_PRELOAD shim for test_robot_process slow_storage: while
 * the file named by COSLAM_TEST_FSYNC_GATE exists, fsync(2) waits (polling
 * every millisecond, at most 30 s), as an SD card's fsync does while it
 * collects garbage. While the file named by COSLAM_TEST_FSYNC_FAIL exists,
 * fsync(2) fails at once with EIO, as on a medium whose write-back fails
 * (the write before it succeeded). Without the variables fsync is the C
 * library's.
 */
#include <errno.h>
#include <dlfcn.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

int fsync(int fd)
{
    static int (*real_fsync)(int);
    if (real_fsync == NULL) {
        real_fsync = (int (*)(int))dlsym(RTLD_NEXT, "fsync");
    }
    const char *fail = getenv("COSLAM_TEST_FSYNC_FAIL");
    if (fail != NULL && access(fail, F_OK) == 0) {
        errno = EIO;
        return -1;
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
