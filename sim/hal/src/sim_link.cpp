// Simulated inter-robot link (see sim_link.hpp).
#include "sim_hal/sim_link.hpp"

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace coslam::sim {

namespace {
constexpr uint64_t kNever = std::numeric_limits<uint64_t>::max();
constexpr uint64_t kSaltLoss = 1;
constexpr uint64_t kSaltJitter = 2;

uint64_t splitmix64(uint64_t x)
{
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

std::vector<uint16_t> iota_ids(size_t n)
{
    std::vector<uint16_t> ids(n);
    for (size_t i = 0; i < n; ++i) ids[i] = static_cast<uint16_t>(i);
    return ids;
}

void check_params(const SimLinkParams &p)
{
    if (!(p.range_m >= 0.0) || !(p.loss_prob >= 0.0 && p.loss_prob <= 1.0) || p.rx_queue_depth == 0)
        throw std::invalid_argument("SimLinkHub: bad parameters");
}
}  // namespace

SimLinkHub::SimLinkHub(SimClock &clock, size_t n_robots, SimLinkParams params)
    : SimLinkHub(clock, iota_ids(n_robots), params)
{
}

SimLinkHub::SimLinkHub(SimClock &clock, const std::vector<uint16_t> &robot_ids, SimLinkParams params)
    : clock_(clock), params_(params)
{
    check_params(params_);
    static const hal_link_ops_t ops = {&SimLinkHub::op_self_id, &SimLinkHub::op_send, &SimLinkHub::op_recv,
                                       &SimLinkHub::op_close};
    for (uint16_t id : robot_ids) {
        if (id == HAL_LINK_BROADCAST || find_locked(id) != nullptr)
            throw std::invalid_argument("SimLinkHub: robot ids must be distinct and not HAL_LINK_BROADCAST");
        auto ep = std::make_unique<Endpoint>();
        ep->hub = this;
        ep->id = id;
        ep->handle.ops = &ops;
        ep->handle.backend = ep.get();
        eps_.push_back(std::move(ep));
    }
}

SimLinkHub::~SimLinkHub() = default;

hal_link_t *SimLinkHub::endpoint(uint16_t robot_id)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    Endpoint *ep = find_locked(robot_id);
    return ep != nullptr ? &ep->handle : nullptr;
}

SimLinkHub::Endpoint *SimLinkHub::find_locked(uint16_t id)
{
    for (auto &ep : eps_)
        if (ep->id == id) return ep.get();
    return nullptr;
}

void SimLinkHub::set_position(uint16_t robot_id, double x_m, double y_m)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    if (Endpoint *ep = find_locked(robot_id)) {
        ep->x_m = x_m;
        ep->y_m = y_m;
    }
}

void SimLinkHub::set_range_m(double range_m)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    SimLinkParams p = params_;
    p.range_m = range_m;
    check_params(p);
    params_ = p;
}

void SimLinkHub::set_partitioned(uint16_t robot_id, bool partitioned)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    if (Endpoint *ep = find_locked(robot_id)) ep->partitioned = partitioned;
}

void SimLinkHub::set_loss_prob(double loss_prob)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    SimLinkParams p = params_;
    p.loss_prob = loss_prob;
    check_params(p);
    params_ = p;
}

SimLinkHub::Stats SimLinkHub::stats(uint16_t robot_id) const
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    for (const auto &ep : eps_)
        if (ep->id == robot_id) return ep->stats;
    return Stats{};
}

size_t SimLinkHub::in_flight() const
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    size_t n = 0;
    for (const auto &ep : eps_) n += ep->in_flight.size();
    return n;
}

uint64_t SimLinkHub::draw(uint16_t src, uint64_t seq, uint16_t dst, uint64_t salt) const
{
    uint64_t h = splitmix64(params_.seed);
    h = splitmix64(h ^ src);
    h = splitmix64(h ^ seq);
    h = splitmix64(h ^ dst);
    return splitmix64(h ^ salt);
}

void SimLinkHub::pump_locked(Endpoint &ep)
{
    const uint64_t now = clock_.now_locked();
    while (!ep.in_flight.empty() && ep.in_flight.begin()->second.deliver_at_us <= now) {
        auto it = ep.in_flight.begin();
        if (ep.rx.size() < params_.rx_queue_depth) {
            ep.rx.push_back(std::move(it->second));
        } else {
            ++ep.stats.rx_dropped_full;
        }
        ep.in_flight.erase(it);
    }
}

hal_status_t SimLinkHub::op_self_id(hal_link_t *dev, uint16_t *id)
{
    *id = static_cast<Endpoint *>(dev->backend)->id;
    return HAL_OK;
}

hal_status_t SimLinkHub::op_send(hal_link_t *dev, uint16_t dest_id, const uint8_t *data, size_t len,
                                 uint32_t timeout_us)
{
    (void)timeout_us;  // the simulated transmit queue never fills
    auto *ep = static_cast<Endpoint *>(dev->backend);
    SimLinkHub *hub = ep->hub;
    std::lock_guard<std::mutex> lk(hub->clock_.mutex());
    if (ep->closed) return HAL_E_CLOSED;
    if (dest_id == ep->id || len == 0 || len > HAL_LINK_MAX_PAYLOAD) return HAL_E_ARG;
    const uint64_t seq = ep->send_count++;
    ++ep->stats.sent;
    std::vector<Endpoint *> targets;
    if (dest_id == HAL_LINK_BROADCAST) {
        for (auto &other : hub->eps_)
            if (other.get() != ep && !other->closed) targets.push_back(other.get());
    } else {
        Endpoint *dst = hub->find_locked(dest_id);
        if (dst == nullptr || dst->closed) {
            ++ep->stats.tx_dropped_unknown;
            return HAL_OK;  // unreliable link: accepted and lost
        }
        targets.push_back(dst);
    }
    const uint64_t now = hub->clock_.now_locked();
    const SimLinkParams &p = hub->params_;
    auto payload = std::make_shared<const std::vector<uint8_t>>(data, data + len);
    for (Endpoint *dst : targets) {
        hub->pump_locked(*dst);  // bounds in-flight memory
        if (ep->partitioned || dst->partitioned) {
            ++ep->stats.tx_dropped_partition;
            continue;
        }
        const double d = std::hypot(dst->x_m - ep->x_m, dst->y_m - ep->y_m);
        if (d > p.range_m) {
            ++ep->stats.tx_dropped_range;
            continue;
        }
        if (p.loss_prob > 0.0) {
            const double u = static_cast<double>(hub->draw(ep->id, seq, dst->id, kSaltLoss) >> 11) * 0x1.0p-53;
            if (u < p.loss_prob) {
                ++ep->stats.tx_dropped_loss;
                continue;
            }
        }
        uint64_t at = now + p.latency_us;
        if (p.jitter_us > 0) at += hub->draw(ep->id, seq, dst->id, kSaltJitter) % (p.jitter_us + 1);
        uint64_t &floor = dst->last_deliver_from[ep->id];
        if (at < floor) at = floor;
        floor = at;
        dst->in_flight.emplace(Key{at, ep->id, seq}, Packet{at, ep->id, payload});
    }
    hub->clock_.notify_locked();
    return HAL_OK;
}

hal_status_t SimLinkHub::op_recv(hal_link_t *dev, uint8_t *buf, size_t cap, hal_link_rx_info_t *info,
                                 uint32_t timeout_us)
{
    auto *ep = static_cast<Endpoint *>(dev->backend);
    SimLinkHub *hub = ep->hub;
    SimClock &clock = hub->clock_;
    std::unique_lock<std::mutex> lk(clock.mutex());
    if (ep->closed) return HAL_E_CLOSED;
    hub->pump_locked(*ep);
    if (ep->rx.empty()) {
        const uint64_t deadline = SimClock::deadline_after(clock.now_locked(), timeout_us);
        const std::function<bool()> ready = [ep, &clock] {
            return ep->closed || !ep->rx.empty() ||
                   (!ep->in_flight.empty() && ep->in_flight.begin()->second.deliver_at_us <= clock.now_locked());
        };
        const std::function<uint64_t()> next_event = [ep] {
            return ep->in_flight.empty() ? kNever : ep->in_flight.begin()->second.deliver_at_us;
        };
        clock.wait_until(lk, deadline, ready, &next_event);
        if (ep->closed) return HAL_E_CLOSED;
        hub->pump_locked(*ep);
        if (ep->rx.empty()) return HAL_E_TIMEOUT;
    }
    Packet pk = std::move(ep->rx.front());
    ep->rx.pop_front();
    const std::vector<uint8_t> &bytes = *pk.data;
    info->len = bytes.size();
    info->src_id = pk.src;
    info->stamp_us = pk.deliver_at_us;
    std::memcpy(buf, bytes.data(), bytes.size() < cap ? bytes.size() : cap);
    if (bytes.size() > cap) {
        ++ep->stats.rx_truncated;
        return HAL_E_OVERFLOW;
    }
    ++ep->stats.rx_delivered;
    return HAL_OK;
}

void SimLinkHub::op_close(hal_link_t *dev)
{
    auto *ep = static_cast<Endpoint *>(dev->backend);
    std::lock_guard<std::mutex> lk(ep->hub->clock_.mutex());
    ep->closed = true;
    ep->in_flight.clear();
    ep->rx.clear();
    ep->hub->clock_.notify_locked();
}

}  // namespace coslam::sim
