// Simulated serial byte pipe (see sim_serial.hpp).
#include "sim_hal/sim_serial.hpp"

#include <algorithm>

namespace coslam::sim {

SimSerialPort::SimSerialPort(SimClock &clock, size_t rx_capacity) : clock_(clock), rx_capacity_(rx_capacity)
{
    static const hal_serial_ops_t ops = {&SimSerialPort::op_set_baud, &SimSerialPort::op_write,
                                         &SimSerialPort::op_read, &SimSerialPort::op_flush_input, nullptr};
    handle_.ops = &ops;
    handle_.backend = this;
}

size_t SimSerialPort::peer_write(const uint8_t *data, size_t len)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    const size_t room = rx_capacity_ - to_fw_.size();
    const size_t n = std::min(room, len);
    to_fw_.insert(to_fw_.end(), data, data + n);
    rx_overflow_ += len - n;
    if (n > 0) clock_.notify_locked();
    return n;
}

std::vector<uint8_t> SimSerialPort::peer_read(size_t max)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    const size_t n = std::min(max, from_fw_.size());
    std::vector<uint8_t> out(from_fw_.begin(), from_fw_.begin() + static_cast<std::ptrdiff_t>(n));
    from_fw_.erase(from_fw_.begin(), from_fw_.begin() + static_cast<std::ptrdiff_t>(n));
    return out;
}

void SimSerialPort::set_max_chunk(size_t n)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    max_chunk_ = n;
}

uint32_t SimSerialPort::baud() const
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    return baud_;
}

uint64_t SimSerialPort::rx_overflow_bytes() const
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    return rx_overflow_;
}

hal_status_t SimSerialPort::op_set_baud(hal_serial_t *dev, uint32_t baud)
{
    auto *self = static_cast<SimSerialPort *>(dev->backend);
    if (baud == 0) return HAL_E_ARG;
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    self->baud_ = baud;
    return HAL_OK;
}

hal_status_t SimSerialPort::op_write(hal_serial_t *dev, const uint8_t *data, size_t len, uint32_t timeout_us)
{
    (void)timeout_us;  // the pipe towards the peer is unbounded: never blocks
    auto *self = static_cast<SimSerialPort *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    self->from_fw_.insert(self->from_fw_.end(), data, data + len);
    return HAL_OK;
}

hal_status_t SimSerialPort::op_read(hal_serial_t *dev, uint8_t *buf, size_t cap, size_t *n_read,
                                    uint32_t timeout_us)
{
    auto *self = static_cast<SimSerialPort *>(dev->backend);
    std::unique_lock<std::mutex> lk(self->clock_.mutex());
    if (self->to_fw_.empty()) {
        const uint64_t deadline = SimClock::deadline_after(self->clock_.now_locked(), timeout_us);
        const std::function<bool()> ready = [self] { return !self->to_fw_.empty(); };
        if (!self->clock_.wait_until(lk, deadline, ready)) return HAL_E_TIMEOUT;
    }
    size_t n = std::min(cap, self->to_fw_.size());
    if (self->max_chunk_ > 0) n = std::min(n, self->max_chunk_);
    std::copy_n(self->to_fw_.begin(), n, buf);
    self->to_fw_.erase(self->to_fw_.begin(), self->to_fw_.begin() + static_cast<std::ptrdiff_t>(n));
    *n_read = n;
    return HAL_OK;
}

hal_status_t SimSerialPort::op_flush_input(hal_serial_t *dev)
{
    auto *self = static_cast<SimSerialPort *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    self->to_fw_.clear();
    return HAL_OK;
}

}  // namespace coslam::sim
