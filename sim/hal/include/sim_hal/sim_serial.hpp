// sim_hal/sim_serial.hpp - a byte pipe behind hal_serial_t: the firmware
// end is the handle, the other end is plain C++ for a device emulator (or
// a test) to talk through. Bytes written by the peer become readable by the
// firmware at once; `max_chunk` can split reads to exercise stream
// reassembly in parsers.
#ifndef COSLAM_SIM_HAL_SIM_SERIAL_HPP
#define COSLAM_SIM_HAL_SIM_SERIAL_HPP

#include <cstdint>
#include <deque>
#include <vector>

#include "hal/hal_serial.h"
#include "sim_hal/sim_clock.hpp"

namespace coslam::sim {

class SimSerialPort {
public:
    /// rx_capacity: bytes buffered towards the firmware before the peer's
    /// writes are refused (counted in rx_overflow_bytes()).
    explicit SimSerialPort(SimClock &clock, size_t rx_capacity = 65536);
    SimSerialPort(const SimSerialPort &) = delete;
    SimSerialPort &operator=(const SimSerialPort &) = delete;

    hal_serial_t *handle() { return &handle_; }

    // ---- peer side (thread-safe) ----------------------------------------
    /// Queue bytes for the firmware to read; returns how many fit.
    size_t peer_write(const uint8_t *data, size_t len);
    /// Take up to max bytes the firmware wrote (oldest first).
    std::vector<uint8_t> peer_read(size_t max = SIZE_MAX);
    /// At most n bytes per firmware read() (0 = no limit).
    void set_max_chunk(size_t n);
    uint32_t baud() const;
    uint64_t rx_overflow_bytes() const;

private:
    static hal_status_t op_set_baud(hal_serial_t *dev, uint32_t baud);
    static hal_status_t op_write(hal_serial_t *dev, const uint8_t *data, size_t len, uint32_t timeout_us);
    static hal_status_t op_read(hal_serial_t *dev, uint8_t *buf, size_t cap, size_t *n_read, uint32_t timeout_us);
    static hal_status_t op_flush_input(hal_serial_t *dev);

    SimClock &clock_;
    size_t rx_capacity_;
    size_t max_chunk_ = 0;
    uint32_t baud_ = 115200;
    uint64_t rx_overflow_ = 0;
    std::deque<uint8_t> to_fw_;
    std::deque<uint8_t> from_fw_;
    hal_serial_t handle_;
};

}  // namespace coslam::sim

#endif
