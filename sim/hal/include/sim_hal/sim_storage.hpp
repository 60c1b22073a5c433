// sim_hal/sim_storage.hpp - in-memory named-blob storage behind
// hal_storage_t, with a capacity and fault injection. Independent of the
// SimClock (storage has no timing); thread-safe by its own mutex.
#ifndef COSLAM_SIM_HAL_SIM_STORAGE_HPP
#define COSLAM_SIM_HAL_SIM_STORAGE_HPP

#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "hal/hal_storage.h"

namespace coslam::sim {

class SimStorage {
public:
    /// capacity_bytes: total payload bytes the medium holds; a write that
    /// would exceed it (counting the replaced blob as freed) fails with
    /// HAL_E_OVERFLOW.
    explicit SimStorage(size_t capacity_bytes = 4u << 20);
    SimStorage(const SimStorage &) = delete;
    SimStorage &operator=(const SimStorage &) = delete;

    hal_storage_t *handle() { return &handle_; }

    // ---- simulator / test side -----------------------------------------
    /// The next n writes fail with HAL_E_IO, leaving the old blob intact
    /// (a power cut before the atomic rename).
    void fail_next_writes(unsigned n);
    /// Flip one bit of a stored blob, as media decay would; later reads
    /// return HAL_E_CORRUPT. False if absent or empty.
    bool corrupt(const std::string &name);
    size_t used_bytes() const;
    size_t blob_count() const;

private:
    struct Blob {
        std::vector<uint8_t> data;
        uint32_t crc32;
    };
    static hal_status_t op_write(hal_storage_t *dev, const char *name, const uint8_t *data, size_t len);
    static hal_status_t op_read(hal_storage_t *dev, const char *name, uint8_t *buf, size_t cap, size_t *len);
    static hal_status_t op_remove(hal_storage_t *dev, const char *name);
    static hal_status_t op_exists(hal_storage_t *dev, const char *name, bool *exists);

    mutable std::mutex mutex_;
    size_t capacity_;
    size_t used_ = 0;
    unsigned fail_writes_ = 0;
    std::map<std::string, Blob> blobs_;
    hal_storage_t handle_;
};

/// CRC-32 (IEEE 802.3, reflected, init and final xor 0xFFFFFFFF).
uint32_t sim_crc32(const uint8_t *data, size_t len);

}  // namespace coslam::sim

#endif
