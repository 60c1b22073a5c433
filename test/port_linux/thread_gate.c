/*
 * thread_gate.so - LD_PRELOAD shim for test_robot_process no_opener_thread:
 * while the file named by COSLAM_TEST_THREAD_FAIL exists, pthread_create(3)
 * makes no thread and returns EAGAIN, as it does at the process's thread
 * limit (RLIMIT_NPROC) or when no stack can be mapped. Every thread the
 * robot makes then fails to start: its device openers and its snapshot
 * writer (robot_worker.h). Without the variable, or once the file is gone,
 * pthread_create is the C library's.
 */
#include <dlfcn.h>
#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <unistd.h>

int pthread_create(pthread_t *thread, const pthread_attr_t *attr, void *(*start)(void *), void *arg)
{
    typedef int (*create_fn)(pthread_t *, const pthread_attr_t *, void *(*)(void *), void *);
    static create_fn real_create;
    if (real_create == NULL) {
        real_create = (create_fn)dlsym(RTLD_NEXT, "pthread_create");
    }
    const char *gate = getenv("COSLAM_TEST_THREAD_FAIL");
    if (gate != NULL && access(gate, F_OK) == 0) {
        return EAGAIN;
    }
    return real_create != NULL ? real_create(thread, attr, start, arg) : ENOSYS;
}
