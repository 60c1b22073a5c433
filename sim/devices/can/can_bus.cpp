#include "sim/can/can_bus.hpp"

#include <algorithm>
#include <iterator>
#include <stdexcept>

namespace coslam::sim {

struct CanBus::Endpoint {
    hal_can_t handle{};
    CanBus *bus = nullptr;
    std::size_t index = 0;
    std::string name;
    std::deque<hal_can_frame_t> rx;
    std::vector<hal_can_filter_t> filters;
    hal_can_status_t status{};
    bool overflow_pending = false;
    bool closed = false;
};

namespace {
CanBus::Endpoint &endpoint_of(hal_can_t *dev) { return *static_cast<CanBus::Endpoint *>(dev->backend); }
} // namespace

struct CanBusOps {
    static hal_status_t send(hal_can_t *dev, const hal_can_frame_t *frame, uint32_t /*timeout_us*/)
    {
        CanBus::Endpoint &ep = endpoint_of(dev);
        return ep.bus->send_from(ep, *frame);
    }

    static hal_status_t receive(hal_can_t *dev, hal_can_frame_t *frame, uint32_t timeout_us)
    {
        CanBus::Endpoint &ep = endpoint_of(dev);
        if (ep.closed) return HAL_E_CLOSED;
        if (ep.overflow_pending) {
            ep.overflow_pending = false;
            return HAL_E_OVERFLOW;
        }
        if (ep.rx.empty() && timeout_us > 0 && ep.bus->wait_hook_) {
            ep.bus->wait_hook_(timeout_us);
            if (ep.closed) return HAL_E_CLOSED;
            if (ep.overflow_pending) {
                ep.overflow_pending = false;
                return HAL_E_OVERFLOW;
            }
        }
        if (ep.rx.empty()) return HAL_E_TIMEOUT;
        *frame = ep.rx.front();
        ep.rx.pop_front();
        return HAL_OK;
    }

    static hal_status_t set_filters(hal_can_t *dev, const hal_can_filter_t *filters, size_t count)
    {
        CanBus::Endpoint &ep = endpoint_of(dev);
        if (ep.closed) return HAL_E_CLOSED;
        if (count > HAL_CAN_MAX_FILTERS) return HAL_E_ARG;
        for (size_t i = 0; i < count; ++i) {
            if ((filters[i].flags & ~HAL_CAN_FLAG_EXT) != 0u) return HAL_E_ARG;
        }
        ep.filters.assign(filters, filters + count);
        return HAL_OK;
    }

    static hal_status_t get_status(hal_can_t *dev, hal_can_status_t *status)
    {
        *status = endpoint_of(dev).status;
        return HAL_OK;
    }

    static void close(hal_can_t *dev)
    {
        CanBus::Endpoint &ep = endpoint_of(dev);
        ep.closed = true;
        ep.rx.clear();
    }
};

namespace {
const hal_can_ops_t kOps = {
    CanBusOps::send, CanBusOps::receive, CanBusOps::set_filters, CanBusOps::get_status, CanBusOps::close,
};

bool accepts(const CanBus::Endpoint &ep, const hal_can_frame_t &f)
{
    if (ep.filters.empty()) return true;
    for (const hal_can_filter_t &flt : ep.filters) {
        if (hal_can_filter_match(&flt, &f)) return true;
    }
    return false;
}
} // namespace

CanBus::CanBus(Clock now_us) : CanBus(std::move(now_us), Config{}) {}

CanBus::CanBus(Clock now_us, Config cfg) : clock_(std::move(now_us)), cfg_(cfg)
{
    if (!clock_) throw std::invalid_argument("CanBus: no clock");
    if (cfg_.rx_queue_capacity == 0) throw std::invalid_argument("CanBus: rx_queue_capacity must be >= 1");
}

CanBus::~CanBus() = default;

hal_can_t *CanBus::attach(const std::string &name)
{
    auto ep = std::make_unique<Endpoint>();
    ep->bus = this;
    ep->index = endpoints_.size();
    ep->name = name;
    ep->status.state = HAL_CAN_STATE_ERROR_ACTIVE;
    ep->status.counters_valid = 1;
    ep->handle.ops = &kOps;
    ep->handle.backend = ep.get();
    endpoints_.push_back(std::move(ep));
    return &endpoints_.back()->handle;
}

void CanBus::set_bus_off(hal_can_t *dev, bool off)
{
    if (dev == nullptr || dev->ops != &kOps) throw std::invalid_argument("CanBus::set_bus_off: not an endpoint");
    Endpoint &ep = endpoint_of(dev);
    if (ep.bus != this) throw std::invalid_argument("CanBus::set_bus_off: endpoint of another bus");
    if (off) {
        if (ep.status.state != HAL_CAN_STATE_BUS_OFF) ep.status.bus_off_count++;
        ep.status.state = HAL_CAN_STATE_BUS_OFF;
        ep.status.tx_error_count = 256;
    } else {
        ep.status.state = HAL_CAN_STATE_ERROR_ACTIVE;
        ep.status.tx_error_count = 0;
    }
}

void CanBus::set_error_rate(double p, uint64_t seed)
{
    if (error_rate_ <= 0.0 && p > 0.0) rng_seed(&error_rng_, seed);
    error_rate_ = p > 0.0 ? (p < 1.0 ? p : 1.0) : 0.0;
}

hal_status_t CanBus::send_from(Endpoint &from, const hal_can_frame_t &frame)
{
    if (from.closed) return HAL_E_CLOSED;
    if (from.status.state == HAL_CAN_STATE_BUS_OFF) return HAL_E_IO;
    hal_can_frame_t f = frame;
    f.stamp_us = clock_();
    if ((f.flags & HAL_CAN_FLAG_RTR) != 0u) std::fill(std::begin(f.data), std::end(f.data), uint8_t{0});
    for (std::size_t i = f.dlc; i < HAL_CAN_MAX_DLC; ++i) f.data[i] = 0;
    ++frames_on_bus_;
    if (error_rate_ > 0.0 && rng_uniform(&error_rng_) < error_rate_) {
        // destroyed on the wire: every other controller saw an error frame
        ++frames_destroyed_;
        for (auto &ep : endpoints_) {
            if (ep.get() != &from && !ep->closed) ep->status.rx_malformed_count++;
        }
        return HAL_OK;
    }
    if (monitor_) monitor_(from.index, f);
    for (auto &ep : endpoints_) {
        if (ep.get() == &from || ep->closed || !accepts(*ep, f)) continue;
        if (ep->rx.size() >= cfg_.rx_queue_capacity) {
            ep->status.rx_overflow_count++;
            ep->overflow_pending = true;
            continue;
        }
        ep->rx.push_back(f);
    }
    return HAL_OK;
}

} // namespace coslam::sim
