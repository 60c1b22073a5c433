// sim/can/can_bus.hpp - a simulated classic CAN bus behind hal_can.h.
//
// Any number of endpoints attach to one bus; each endpoint is a hal_can_t
// (the robot's firmware gets one, every emulated device another). A frame
// sent by one endpoint is delivered, in send order, to every other
// endpoint whose acceptance filters pass it (never back to the sender),
// stamped with the simulated clock at the moment of sending (zero
// propagation delay; arbitration and bit timing are not modelled).
//
// Time: the clock is a caller-provided function (the simulator's clock,
// advanced by the caller). Nothing here advances time. A receive with
// timeout_us > 0 on an empty queue calls the optional wait hook once (which
// may advance the clock and step devices) and then returns HAL_E_TIMEOUT
// if still nothing arrived; without a hook it returns HAL_E_TIMEOUT at once.
//
// Capacity: each endpoint's receive queue holds rx_queue_capacity frames;
// a frame arriving at a full queue is dropped, counted in that endpoint's
// rx_overflow_count, and reported by its next receive as HAL_E_OVERFLOW.
//
// Fault injection: set_bus_off() puts one endpoint's controller bus-off
// (its sends fail with HAL_E_IO, its status reports BUS_OFF, TEC 256).
//
// Bus errors: set_error_rate(p) destroys each frame put on the bus with
// probability p (a CRC / bit error seen by every node: no endpoint receives
// it; the error-signalling controllers count it in rx_malformed_count, the
// bus in frames_destroyed). The frame is not retransmitted (the drives'
// PDOs are cyclic, the next one carries the news). Seeded, own RNG.
//
// Threading: single-threaded; the bus and its endpoints belong to the
// thread that runs the simulation. Endpoints live as long as the bus.
#ifndef COSLAM_SIM_CAN_BUS_HPP
#define COSLAM_SIM_CAN_BUS_HPP

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "coslam/rng.h"
#include "hal/hal_can.h"

namespace coslam::sim {

class CanBus {
public:
    using Clock = std::function<uint64_t()>;
    using WaitHook = std::function<void(uint32_t timeout_us)>;
    /// Sees every frame put on the bus: sender's endpoint index, stamped frame.
    using Monitor = std::function<void(std::size_t from, const hal_can_frame_t &frame)>;

    struct Config {
        std::size_t rx_queue_capacity = 256; ///< frames per endpoint, >= 1
    };

    explicit CanBus(Clock now_us);
    CanBus(Clock now_us, Config cfg);
    ~CanBus();
    CanBus(const CanBus &) = delete;
    CanBus &operator=(const CanBus &) = delete;

    /// A new endpoint. The handle stays valid (and owned by the bus) for the
    /// bus's lifetime; hal_can_close() detaches it (it then neither sends nor
    /// receives: HAL_E_CLOSED).
    hal_can_t *attach(const std::string &name);

    void set_wait_hook(WaitHook hook) { wait_hook_ = std::move(hook); }
    void set_monitor(Monitor monitor) { monitor_ = std::move(monitor); }

    /// Put endpoint `ep` bus-off (true) or back to error-active (false).
    void set_bus_off(hal_can_t *ep, bool off);

    /// Destroy each frame with probability p in [0, 1] (0: off); seed for the draws.
    void set_error_rate(double p, uint64_t seed);
    uint64_t frames_destroyed() const { return frames_destroyed_; }

    std::size_t endpoint_count() const { return endpoints_.size(); }
    uint64_t frames_on_bus() const { return frames_on_bus_; }
    uint64_t now_us() const { return clock_(); }

    struct Endpoint; // implementation detail, public for the C callbacks

private:
    friend struct CanBusOps;
    hal_status_t send_from(Endpoint &ep, const hal_can_frame_t &frame);

    Clock clock_;
    Config cfg_;
    std::vector<std::unique_ptr<Endpoint>> endpoints_;
    WaitHook wait_hook_;
    Monitor monitor_;
    uint64_t frames_on_bus_ = 0;
    double error_rate_ = 0.0;
    rng_t error_rng_{};
    uint64_t frames_destroyed_ = 0;
};

} // namespace coslam::sim

#endif // COSLAM_SIM_CAN_BUS_HPP
