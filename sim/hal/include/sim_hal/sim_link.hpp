// sim_hal/sim_link.hpp - the simulated inter-robot radio: one hub, one
// hal_link_t endpoint per robot.
//
// Channel model, applied per (datagram, receiver) at send time t:
//  1. range: dropped if the distance between the robots' positions (as last
//     supplied by the simulator with set_position) exceeds range_m;
//  2. loss: dropped with probability loss_prob. The draw is a hash of
//     (seed, sender, sender's send counter, receiver), not a shared random
//     stream, so the outcome does not depend on the order in which robot
//     threads happen to send: runs are reproducible from the seed alone;
//  3. latency: delivered at t + latency_us + U[0, jitter_us] (same hash
//     scheme), but never before an earlier datagram of the same
//     (sender, receiver) pair: the simulated link keeps per-pair order.
//  At its delivery time a datagram enters the receiver's queue of
//  rx_queue_depth datagrams; if that is full it is dropped and counted. The
//  arrival stamp is the delivery time, whenever the firmware polls.
//  Range is evaluated at send time only (robots move little in ~ms).
// All counters are per endpoint and never reset.
#ifndef COSLAM_SIM_HAL_SIM_LINK_HPP
#define COSLAM_SIM_HAL_SIM_LINK_HPP

#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "hal/hal_link.h"
#include "sim_hal/sim_clock.hpp"

namespace coslam::sim {

struct SimLinkParams {
    double range_m = 10.0;            ///< max distance for delivery; infinity = unlimited
    uint64_t latency_us = 2000;       ///< fixed one-way latency
    uint64_t jitter_us = 0;           ///< extra uniform latency in [0, jitter_us]
    double loss_prob = 0.0;           ///< independent loss per datagram and receiver, [0, 1]
    uint64_t seed = 1;                ///< seed of the loss and jitter draws
    size_t rx_queue_depth = 32;       ///< datagrams waiting per receiver
};

class SimLinkHub {
public:
    struct Stats {
        uint64_t sent = 0;                ///< send() calls accepted
        uint64_t tx_dropped_range = 0;    ///< copies not delivered: out of range
        uint64_t tx_dropped_loss = 0;     ///< copies not delivered: random loss
        uint64_t tx_dropped_unknown = 0;  ///< unicasts to an unknown or closed robot
        uint64_t tx_dropped_partition = 0;///< copies not delivered: sender or receiver partitioned
        uint64_t rx_delivered = 0;        ///< datagrams handed to the firmware whole
        uint64_t rx_dropped_full = 0;     ///< arrivals dropped: receive queue full
        uint64_t rx_truncated = 0;        ///< recv() into a too-small buffer (HAL_E_OVERFLOW)
    };

    /// Robots with the given distinct ids (none equal to HAL_LINK_BROADCAST).
    /// Throws std::invalid_argument on bad ids or parameters.
    SimLinkHub(SimClock &clock, const std::vector<uint16_t> &robot_ids, SimLinkParams params = {});
    /// Robots 0 .. n_robots-1.
    SimLinkHub(SimClock &clock, size_t n_robots, SimLinkParams params = {});
    SimLinkHub(const SimLinkHub &) = delete;
    SimLinkHub &operator=(const SimLinkHub &) = delete;
    ~SimLinkHub();

    /// The endpoint of a robot; nullptr for an unknown id.
    hal_link_t *endpoint(uint16_t robot_id);

    // ---- simulator side (thread-safe) -----------------------------------
    void set_position(uint16_t robot_id, double x_m, double y_m);
    void set_range_m(double range_m);
    /// Fault: cut robot_id off the link (true): every datagram it sends or
    /// that is sent to it is dropped (counted at the sender,
    /// tx_dropped_partition); false heals the partition.
    void set_partitioned(uint16_t robot_id, bool partitioned);
    void set_loss_prob(double loss_prob);
    Stats stats(uint16_t robot_id) const;
    /// Datagrams sent but not yet delivered into a receive queue.
    size_t in_flight() const;

private:
    struct Packet {
        uint64_t deliver_at_us;
        uint16_t src;
        std::shared_ptr<const std::vector<uint8_t>> data;
    };
    using Key = std::tuple<uint64_t, uint16_t, uint64_t>;  // deliver_at, src, src sequence
    struct Endpoint {
        SimLinkHub *hub = nullptr;
        uint16_t id = 0;
        double x_m = 0.0, y_m = 0.0;
        bool closed = false;
        bool partitioned = false;
        uint64_t send_count = 0;
        std::map<Key, Packet> in_flight;
        std::deque<Packet> rx;
        std::map<uint16_t, uint64_t> last_deliver_from;  // per-sender FIFO floor
        Stats stats;
        hal_link_t handle{};
    };
    Endpoint *find_locked(uint16_t id);
    void pump_locked(Endpoint &ep);
    uint64_t draw(uint16_t src, uint64_t seq, uint16_t dst, uint64_t salt) const;

    static hal_status_t op_self_id(hal_link_t *dev, uint16_t *id);
    static hal_status_t op_send(hal_link_t *dev, uint16_t dest_id, const uint8_t *data, size_t len,
                                uint32_t timeout_us);
    static hal_status_t op_recv(hal_link_t *dev, uint8_t *buf, size_t cap, hal_link_rx_info_t *info,
                                uint32_t timeout_us);
    static void op_close(hal_link_t *dev);

    SimClock &clock_;
    SimLinkParams params_;
    std::vector<std::unique_ptr<Endpoint>> eps_;
};

}  // namespace coslam::sim

#endif
