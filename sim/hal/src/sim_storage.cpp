// In-memory storage (see sim_storage.hpp).
#include "sim_hal/sim_storage.hpp"

#include <cstring>

namespace coslam::sim {

uint32_t sim_crc32(const uint8_t *data, size_t len)
{
    uint32_t crc = 0xFFFFFFFFu;
    for (size_t i = 0; i < len; ++i) {
        crc ^= data[i];
        for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xFFFFFFFFu;
}

SimStorage::SimStorage(size_t capacity_bytes) : capacity_(capacity_bytes)
{
    static const hal_storage_ops_t ops = {&SimStorage::op_write, &SimStorage::op_read, &SimStorage::op_remove,
                                          &SimStorage::op_exists, nullptr};
    handle_.ops = &ops;
    handle_.backend = this;
}

void SimStorage::fail_next_writes(unsigned n)
{
    std::lock_guard<std::mutex> lk(mutex_);
    fail_writes_ = n;
}

bool SimStorage::corrupt(const std::string &name)
{
    std::lock_guard<std::mutex> lk(mutex_);
    auto it = blobs_.find(name);
    if (it == blobs_.end() || it->second.data.empty()) return false;
    it->second.data[it->second.data.size() / 2] ^= 0x10u;
    return true;
}

size_t SimStorage::used_bytes() const
{
    std::lock_guard<std::mutex> lk(mutex_);
    return used_;
}

size_t SimStorage::blob_count() const
{
    std::lock_guard<std::mutex> lk(mutex_);
    return blobs_.size();
}

hal_status_t SimStorage::op_write(hal_storage_t *dev, const char *name, const uint8_t *data, size_t len)
{
    auto *self = static_cast<SimStorage *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->mutex_);
    if (self->fail_writes_ > 0) {
        --self->fail_writes_;
        return HAL_E_IO;
    }
    auto it = self->blobs_.find(name);
    const size_t freed = (it != self->blobs_.end()) ? it->second.data.size() : 0u;
    if (self->used_ - freed + len > self->capacity_) return HAL_E_OVERFLOW;
    Blob b{std::vector<uint8_t>(data, data + len), sim_crc32(data, len)};
    self->used_ = self->used_ - freed + len;
    self->blobs_[name] = std::move(b);
    return HAL_OK;
}

hal_status_t SimStorage::op_read(hal_storage_t *dev, const char *name, uint8_t *buf, size_t cap, size_t *len)
{
    auto *self = static_cast<SimStorage *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->mutex_);
    auto it = self->blobs_.find(name);
    if (it == self->blobs_.end()) return HAL_E_NOT_FOUND;
    const Blob &b = it->second;
    if (sim_crc32(b.data.data(), b.data.size()) != b.crc32) return HAL_E_CORRUPT;
    *len = b.data.size();
    if (cap < b.data.size()) return HAL_E_OVERFLOW;
    if (!b.data.empty()) std::memcpy(buf, b.data.data(), b.data.size());
    return HAL_OK;
}

hal_status_t SimStorage::op_remove(hal_storage_t *dev, const char *name)
{
    auto *self = static_cast<SimStorage *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->mutex_);
    auto it = self->blobs_.find(name);
    if (it == self->blobs_.end()) return HAL_E_NOT_FOUND;
    self->used_ -= it->second.data.size();
    self->blobs_.erase(it);
    return HAL_OK;
}

hal_status_t SimStorage::op_exists(hal_storage_t *dev, const char *name, bool *exists)
{
    auto *self = static_cast<SimStorage *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->mutex_);
    *exists = self->blobs_.count(name) != 0;
    return HAL_OK;
}

}  // namespace coslam::sim
