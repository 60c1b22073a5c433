/*
 * hal_camera_v4l2_sys.h - the system-call seam of the V4L2 camera backend
 * (internal: the backend and its tests only).
 *
 * hal_camera_v4l2.c reaches the kernel and the clock only through these
 * functions. The library links hal_camera_v4l2_sys.c (thin libc calls);
 * the tests link test/hal_linux/v4l2/v4l2_fake.c instead, an in-memory
 * V4L2 capture driver. Link-time substitution of this seam, rather than
 * -Wl,--wrap of libc's open/ioctl/poll (the gpiod_fake.c way) or a table
 * of function pointers: wrapping libc would also catch GoogleTest's and
 * the sanitizers' own open/close/poll in the test binaries, and a pointer
 * table would put a test hook in the robot's build. Here the robot binary
 * calls libc directly through one extra call, and a fake missing one of
 * these functions fails the link.
 */
#ifndef HAL_CAMERA_V4L2_SYS_H
#define HAL_CAMERA_V4L2_SYS_H

#include <poll.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#ifdef __cplusplus
extern "C" {
#endif

/** open(2), close(2), ioctl(2), mmap(2) (whole-buffer, shared), munmap(2),
 *  poll(2): same results and errno as libc. */
int v4l2_sys_open(const char *path, int flags);
int v4l2_sys_close(int fd);
int v4l2_sys_ioctl(int fd, unsigned long request, void *arg);
void *v4l2_sys_mmap(size_t length, int prot, int flags, int fd, off_t offset);
int v4l2_sys_munmap(void *addr, size_t length);
int v4l2_sys_poll(struct pollfd *fds, nfds_t nfds, int timeout_ms);
/** CLOCK_MONOTONIC [us]: the clock of hal_clock_linux() and of V4L2
 *  MONOTONIC buffer stamps. */
uint64_t v4l2_sys_now_us(void);

#ifdef __cplusplus
}
#endif

#endif /* HAL_CAMERA_V4L2_SYS_H */
