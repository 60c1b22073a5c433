/*
 * hal/hal_storage_linux.h - hal_storage as files in one directory.
 *
 * Layout: blob `name` is the file <dir>/<name>: a 16-byte header then the
 * payload. Header (little-endian): magic "CSB1", payload length u32,
 * CRC-32 (IEEE) of the payload u32, CRC-32 of the first 12 header bytes
 * u32. A read whose header or payload fails its CRC, or whose file length
 * disagrees with the header, is HAL_E_CORRUPT.
 *
 * Atomic replace: write goes to <dir>/.<name>.tmp (names never start with
 * '.', so temporaries cannot collide with blobs), fsync, rename over
 * <dir>/<name>, fsync the directory. rename(2) is atomic on POSIX file
 * systems, so a power cut leaves the old or the new file, and at worst a
 * stale temporary that the next write of that name overwrites.
 *
 * Errors: ENOSPC/EDQUOT/EFBIG -> HAL_E_OVERFLOW; a payload over
 * max_blob_bytes -> HAL_E_OVERFLOW; other OS errors -> HAL_E_IO. A write
 * keeps the errno of its failed call in last_errno (the OS's reason).
 *
 * After hal_storage_close every operation returns HAL_E_CLOSED.
 *
 * One writer per directory, enforced: the open takes an exclusive
 * flock(2) on the directory, held until close (or the process ends), so a
 * second open of the same directory, in this process or another, is
 * HAL_E_BUSY (readers: hal_storage_linux_open_reader). State is caller-owned (no heap); not thread-safe (one thread
 * at a time, as every HAL instance).
 */
#ifndef HAL_STORAGE_LINUX_H
#define HAL_STORAGE_LINUX_H

#include "hal/hal_storage.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest blob the backend accepts by default [bytes]. */
#define HAL_STORAGE_LINUX_MAX_BLOB (64u * 1024u * 1024u)

typedef struct {
    hal_storage_t dev;        /**< the handle to pass to hal_storage_* */
    int dir_fd;               /**< open directory, -1 when closed */
    size_t max_blob_bytes;    /**< writes above this are HAL_E_OVERFLOW */
    int reader;               /**< opened by hal_storage_linux_open_reader: reads only */
    int last_errno;           /**< the OS's errno of the last write's failed call (0: the last
                                   write succeeded, or failed without one: closed, a reader,
                                   over max_blob_bytes), so a caller can say why (strerror) */
    int last_fsync_failed;    /**< 1: the last write failed at an fsync (of the file or of the
                                   directory): the medium took the bytes but does not say they
                                   are on it (0: succeeded, or failed at another call) */
} hal_storage_linux_t;

/** Open (creating it, one level, mode 0755, if missing) the directory
 *  `dir` as a blob store. Returns HAL_OK and a ready st->dev; HAL_E_ARG
 *  (NULL); HAL_E_NOT_FOUND (a parent directory is missing); HAL_E_BUSY
 *  (another instance holds the directory); HAL_E_IO.
 *  Release with hal_storage_close(&st->dev). */
hal_status_t hal_storage_linux_open(hal_storage_linux_t *st, const char *dir);

/** Open an existing directory for reading only, without the lock (tools
 *  and tests that look at a store a writer may hold): writes and removes
 *  are HAL_E_UNSUPPORTED. Returns HAL_OK; HAL_E_ARG; HAL_E_NOT_FOUND;
 *  HAL_E_IO. */
hal_status_t hal_storage_linux_open_reader(hal_storage_linux_t *st, const char *dir);

#ifdef __cplusplus
}
#endif

#endif /* HAL_STORAGE_LINUX_H */
