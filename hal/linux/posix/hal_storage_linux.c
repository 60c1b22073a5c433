/* hal_storage as files in a directory (see hal/hal_storage_linux.h). */
#include "hal/hal_storage_linux.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#define HDR_BYTES 16u
#define TMP_NAME_MAX (HAL_STORAGE_NAME_MAX + 6u) /* "." name ".tmp" NUL */

static uint32_t crc32_ieee(uint32_t crc, const uint8_t *p, size_t n)
{
    crc = ~crc;
    for (size_t i = 0; i < n; ++i) {
        crc ^= p[i];
        for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static hal_status_t errno_status(int e)
{
    switch (e) {
    case ENOSPC:
    case EDQUOT:
    case EFBIG: return HAL_E_OVERFLOW;
    case ENOENT: return HAL_E_NOT_FOUND;
    default: return HAL_E_IO;
    }
}

/* A failed call of a write: its errno kept for the caller (last_errno). */
static hal_status_t write_failed(hal_storage_linux_t *st, int e)
{
    st->last_errno = e;
    return errno_status(e);
}

static hal_status_t write_all(hal_storage_linux_t *st, int fd, const uint8_t *p, size_t n)
{
    while (n > 0) {
        const ssize_t w = write(fd, p, n);
        if (w < 0) {
            if (errno == EINTR) continue;
            return write_failed(st, errno);
        }
        p += (size_t)w;
        n -= (size_t)w;
    }
    return HAL_OK;
}

/* Reads exactly n bytes; HAL_E_CORRUPT if the file ends first. */
static hal_status_t read_all(int fd, uint8_t *p, size_t n)
{
    while (n > 0) {
        const ssize_t r = read(fd, p, n);
        if (r < 0) {
            if (errno == EINTR) continue;
            return HAL_E_IO;
        }
        if (r == 0) return HAL_E_CORRUPT;
        p += (size_t)r;
        n -= (size_t)r;
    }
    return HAL_OK;
}

static hal_storage_linux_t *self_of(hal_storage_t *dev)
{
    return (hal_storage_linux_t *)dev->backend;
}

static hal_status_t linux_write(hal_storage_t *dev, const char *name, const uint8_t *data, size_t len)
{
    hal_storage_linux_t *st = self_of(dev);
    st->last_errno = 0;
    st->last_fsync_failed = 0;
    if (st->dir_fd < 0) return HAL_E_CLOSED;
    if (st->reader) return HAL_E_UNSUPPORTED;
    if (len > st->max_blob_bytes || len > UINT32_MAX) return HAL_E_OVERFLOW;
    char tmp[TMP_NAME_MAX];
    (void)snprintf(tmp, sizeof tmp, ".%s.tmp", name);

    uint8_t hdr[HDR_BYTES];
    memcpy(hdr, "CSB1", 4);
    put_u32(hdr + 4, (uint32_t)len);
    put_u32(hdr + 8, crc32_ieee(0, data, len));
    put_u32(hdr + 12, crc32_ieee(0, hdr, 12));

    /* O_NONBLOCK: a FIFO in the temporary's place (no reader) fails with
     * ENXIO instead of waiting for one; no effect on a regular file */
    const int fd = openat(st->dir_fd, tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NONBLOCK, 0644);
    if (fd < 0) return write_failed(st, errno);
    hal_status_t s = write_all(st, fd, hdr, sizeof hdr);
    if (s == HAL_OK && len > 0) s = write_all(st, fd, data, len);
    if (s == HAL_OK && fsync(fd) != 0) {
        s = write_failed(st, errno);
        st->last_fsync_failed = 1;
    }
    if (close(fd) != 0 && s == HAL_OK) s = write_failed(st, errno);
    if (s == HAL_OK && renameat(st->dir_fd, tmp, st->dir_fd, name) != 0) s = write_failed(st, errno);
    if (s != HAL_OK) {
        (void)unlinkat(st->dir_fd, tmp, 0);
        return s == HAL_E_NOT_FOUND ? HAL_E_IO : s;
    }
    /* make the rename itself durable */
    if (fsync(st->dir_fd) != 0) {
        st->last_errno = errno;
        st->last_fsync_failed = 1;
        return HAL_E_IO;
    }
    return HAL_OK;
}

static hal_status_t linux_read(hal_storage_t *dev, const char *name, uint8_t *buf, size_t cap, size_t *len)
{
    hal_storage_linux_t *st = self_of(dev);
    if (st->dir_fd < 0) return HAL_E_CLOSED;
    /* O_NONBLOCK: a FIFO under the blob's name opens at once (and is
     * refused below as not a regular file) instead of waiting for a writer
     * for ever; it changes nothing for a regular file */
    const int fd = openat(st->dir_fd, name, O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) return errno == ENOENT ? HAL_E_NOT_FOUND : HAL_E_IO;
    hal_status_t s = HAL_OK;
    struct stat sb;
    uint8_t hdr[HDR_BYTES];
    uint32_t n = 0;
    if (fstat(fd, &sb) != 0) {
        s = HAL_E_IO;
    } else if (!S_ISREG(sb.st_mode)) {
        s = HAL_E_CORRUPT;
    } else {
        s = read_all(fd, hdr, sizeof hdr);
    }
    if (s == HAL_OK) {
        n = get_u32(hdr + 4);
        if (memcmp(hdr, "CSB1", 4) != 0 || get_u32(hdr + 12) != crc32_ieee(0, hdr, 12) ||
            (uint64_t)sb.st_size != (uint64_t)n + HDR_BYTES) {
            s = HAL_E_CORRUPT;
        }
    }
    if (s == HAL_OK) {
        *len = n;
        if (cap < n) {
            s = HAL_E_OVERFLOW;
        } else if (n > 0) {
            s = read_all(fd, buf, n);
            if (s == HAL_OK && crc32_ieee(0, buf, n) != get_u32(hdr + 8)) s = HAL_E_CORRUPT;
        }
        if (s != HAL_OK && s != HAL_E_OVERFLOW) *len = 0;
    }
    (void)close(fd);
    return s;
}

static hal_status_t linux_remove(hal_storage_t *dev, const char *name)
{
    hal_storage_linux_t *st = self_of(dev);
    if (st->dir_fd < 0) return HAL_E_CLOSED;
    if (st->reader) return HAL_E_UNSUPPORTED;
    if (unlinkat(st->dir_fd, name, 0) != 0) return errno == ENOENT ? HAL_E_NOT_FOUND : HAL_E_IO;
    if (fsync(st->dir_fd) != 0) return HAL_E_IO;
    return HAL_OK;
}

static hal_status_t linux_exists(hal_storage_t *dev, const char *name, bool *exists)
{
    hal_storage_linux_t *st = self_of(dev);
    if (st->dir_fd < 0) return HAL_E_CLOSED;
    struct stat sb;
    if (fstatat(st->dir_fd, name, &sb, 0) == 0) {
        *exists = true;
        return HAL_OK;
    }
    if (errno == ENOENT) {
        *exists = false;
        return HAL_OK;
    }
    return HAL_E_IO;
}

static void linux_close(hal_storage_t *dev)
{
    hal_storage_linux_t *st = self_of(dev);
    if (st->dir_fd >= 0) (void)close(st->dir_fd);
    st->dir_fd = -1;
}

static const hal_storage_ops_t linux_storage_ops = {linux_write, linux_read, linux_remove, linux_exists,
                                                     linux_close};

/* Open dir; `lock`: take the one-writer lock. */
static hal_status_t open_dir(hal_storage_linux_t *st, const char *dir, int lock)
{
    if (st == NULL || dir == NULL || dir[0] == '\0') return HAL_E_ARG;
    st->dev.ops = &linux_storage_ops;
    st->dev.backend = st;
    st->dir_fd = -1;
    st->reader = !lock;
    st->max_blob_bytes = HAL_STORAGE_LINUX_MAX_BLOB;
    st->last_errno = 0;
    if (lock && mkdir(dir, 0755) != 0 && errno != EEXIST) return errno == ENOENT ? HAL_E_NOT_FOUND : HAL_E_IO;
    const int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) return errno == ENOENT ? HAL_E_NOT_FOUND : HAL_E_IO;
    /* one writer per directory: two processes on one store would replace
     * each other's temporaries and interleave their generations. The lock
     * goes with the descriptor (close, exit, a crash). */
    if (lock && flock(fd, LOCK_EX | LOCK_NB) != 0) {
        const int e = errno;
        (void)close(fd);
        return e == EWOULDBLOCK ? HAL_E_BUSY : HAL_E_IO;
    }
    st->dir_fd = fd;
    return HAL_OK;
}

hal_status_t hal_storage_linux_open(hal_storage_linux_t *st, const char *dir)
{
    return open_dir(st, dir, 1);
}

hal_status_t hal_storage_linux_open_reader(hal_storage_linux_t *st, const char *dir)
{
    return open_dir(st, dir, 0);
}
