/*
 * hal/hal_storage.h - persistent named blobs (saved maps, calibration,
 * parameters). See hal_common.h for the shared conventions.
 *
 * Semantics:
 *  - Names: 1..HAL_STORAGE_NAME_MAX characters from [A-Za-z0-9_.-], not
 *    starting with '.'; checked by the wrappers (HAL_E_ARG otherwise), so
 *    every backend sees the same namespace. Names are case-sensitive.
 *  - write: atomic replace. After HAL_OK a later read returns exactly the
 *    new bytes; after any failure, or a power cut during the call, a later
 *    read returns either the complete old blob (or HAL_E_NOT_FOUND if
 *    there was none) or the complete new one, never a mix. Zero-length
 *    blobs are allowed.
 *  - read: copies the whole blob into the caller's buffer. If cap is too
 *    small it returns HAL_E_OVERFLOW with *len = the size needed, and the
 *    buffer content is unspecified; the caller may retry with a larger one.
 *  - Integrity: backends that can detect a damaged blob (checksum) return
 *    HAL_E_CORRUPT from read; the blob stays until replaced or removed.
 *  - Blocking: all calls are synchronous and may take as long as the
 *    medium needs (a flash erase, an fsync); there is no timeout.
 *
 * Backends: Linux files in a directory (hal/linux: write to a temporary
 * file, fsync, rename), simulator (sim/hal: in memory, with a capacity and
 * fault injection), null (hal_storage_null(): HAL_E_UNSUPPORTED).
 */
#ifndef HAL_STORAGE_H
#define HAL_STORAGE_H

#include <stdbool.h>

#include "hal/hal_common.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Longest blob name [characters, without the terminating NUL]. */
#define HAL_STORAGE_NAME_MAX 31u

typedef struct hal_storage hal_storage_t;

typedef struct {
    /** HAL_OK; HAL_E_OVERFLOW (no room on the medium or larger than the
     *  backend's blob limit; old blob intact); HAL_E_IO (old blob intact,
     *  except in one case: the Linux backend's rename succeeded and the
     *  directory's fsync then failed, so a read returns the new blob but
     *  its durability across a power cut is not known). A caller keeps its
     *  record of what was written as if the write had failed, which errs
     *  towards the older state. */
    hal_status_t (*write)(hal_storage_t *dev, const char *name, const uint8_t *data, size_t len);
    /** HAL_OK (*len = blob size, bytes in buf); HAL_E_NOT_FOUND;
     *  HAL_E_OVERFLOW (cap < size; *len = size needed); HAL_E_CORRUPT;
     *  HAL_E_IO. */
    hal_status_t (*read)(hal_storage_t *dev, const char *name, uint8_t *buf, size_t cap, size_t *len);
    /** HAL_OK; HAL_E_NOT_FOUND; HAL_E_IO. */
    hal_status_t (*remove)(hal_storage_t *dev, const char *name);
    /** HAL_OK with *exists set; HAL_E_IO. */
    hal_status_t (*exists)(hal_storage_t *dev, const char *name, bool *exists);
    /** Release the instance (stored blobs persist). The handle is unusable afterwards. */
    void (*close)(hal_storage_t *dev);
} hal_storage_ops_t;

struct hal_storage {
    const hal_storage_ops_t *ops;
    void *backend;   /**< backend-owned state */
};

/** True if `name` is a valid blob name (see above). O(HAL_STORAGE_NAME_MAX). */
static inline bool hal_storage_name_valid(const char *name)
{
    if (name == NULL || name[0] == '\0' || name[0] == '.') return false;
    for (size_t i = 0; i <= HAL_STORAGE_NAME_MAX; ++i) {
        const char c = name[i];
        if (c == '\0') return true;
        const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                        c == '.' || c == '-';
        if (!ok) return false;
    }
    return false; /* longer than HAL_STORAGE_NAME_MAX */
}

/** Atomically replace (or create) blob `name` with len bytes of data (data
 *  may be NULL when len is 0; it is read during the call only). Returns
 *  HAL_OK, HAL_E_ARG (bad name, NULL data with len > 0), HAL_E_OVERFLOW,
 *  HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_storage_write(hal_storage_t *d, const char *name, const uint8_t *data, size_t len)
{
    if (d == NULL || d->ops == NULL || !hal_storage_name_valid(name) || (data == NULL && len > 0)) return HAL_E_ARG;
    return d->ops->write ? d->ops->write(d, name, data, len) : HAL_E_UNSUPPORTED;
}

/** Read blob `name` into buf (capacity cap bytes; buf may be NULL when cap
 *  is 0, to ask for the size). *len receives the blob size on HAL_OK and
 *  HAL_E_OVERFLOW, 0 otherwise. Returns HAL_OK, HAL_E_ARG, HAL_E_NOT_FOUND,
 *  HAL_E_OVERFLOW, HAL_E_CORRUPT, HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_storage_read(hal_storage_t *d, const char *name, uint8_t *buf, size_t cap,
                                            size_t *len)
{
    if (d == NULL || d->ops == NULL || !hal_storage_name_valid(name) || (buf == NULL && cap > 0) || len == NULL)
        return HAL_E_ARG;
    *len = 0;
    return d->ops->read ? d->ops->read(d, name, buf, cap, len) : HAL_E_UNSUPPORTED;
}

/** Delete blob `name`. Returns HAL_OK, HAL_E_ARG, HAL_E_NOT_FOUND, HAL_E_IO,
 *  HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_storage_remove(hal_storage_t *d, const char *name)
{
    if (d == NULL || d->ops == NULL || !hal_storage_name_valid(name)) return HAL_E_ARG;
    return d->ops->remove ? d->ops->remove(d, name) : HAL_E_UNSUPPORTED;
}

/** *exists = whether blob `name` is stored. Returns HAL_OK, HAL_E_ARG,
 *  HAL_E_IO, HAL_E_UNSUPPORTED. */
static inline hal_status_t hal_storage_exists(hal_storage_t *d, const char *name, bool *exists)
{
    if (d == NULL || d->ops == NULL || !hal_storage_name_valid(name) || exists == NULL) return HAL_E_ARG;
    *exists = false;
    return d->ops->exists ? d->ops->exists(d, name, exists) : HAL_E_UNSUPPORTED;
}

static inline void hal_storage_close(hal_storage_t *d)
{
    if (d != NULL && d->ops != NULL && d->ops->close != NULL) d->ops->close(d);
}

/** The null storage (library coslam_hal_null): every operation returns
 *  HAL_E_UNSUPPORTED. Never NULL. */
hal_storage_t *hal_storage_null(void);

#ifdef __cplusplus
}
#endif

#endif /* HAL_STORAGE_H */
