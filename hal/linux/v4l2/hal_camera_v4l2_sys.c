/* The libc side of the V4L2 backend's system-call seam
 * (hal_camera_v4l2_sys.h). */
#include "hal_camera_v4l2_sys.h"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include "hal/hal_clock_linux.h"

int v4l2_sys_open(const char *path, int flags)
{
    return open(path, flags);
}

int v4l2_sys_close(int fd)
{
    return close(fd);
}

int v4l2_sys_ioctl(int fd, unsigned long request, void *arg)
{
    return ioctl(fd, request, arg);
}

void *v4l2_sys_mmap(size_t length, int prot, int flags, int fd, off_t offset)
{
    return mmap(NULL, length, prot, flags, fd, offset);
}

int v4l2_sys_munmap(void *addr, size_t length)
{
    return munmap(addr, length);
}

int v4l2_sys_poll(struct pollfd *fds, nfds_t nfds, int timeout_ms)
{
    return poll(fds, nfds, timeout_ms);
}

uint64_t v4l2_sys_now_us(void)
{
    uint64_t t = 0;
    (void)hal_clock_now_us(hal_clock_linux(), &t);
    return t;
}
