// Simulated clock and the shared wait machinery (see sim_clock.hpp).
#include "sim_hal/sim_clock.hpp"

#include <algorithm>
#include <limits>

namespace coslam::sim {

namespace {
constexpr uint64_t kNever = std::numeric_limits<uint64_t>::max();
}  // namespace

SimClock::SimClock(uint64_t start_us) : now_us_(start_us)
{
    static const hal_clock_ops_t ops = {&SimClock::op_now_us, &SimClock::op_sleep_until_us, nullptr};
    handle_.ops = &ops;
    handle_.backend = this;
}

SimClock::~SimClock()
{
    // A waiter still blocked here would be a bug in the owner (threads must
    // be joined before the world is destroyed); release them anyway.
    std::lock_guard<std::mutex> lk(mutex_);
    lockstep_ = false;
    cv_.notify_all();
}

uint64_t SimClock::now_us() const
{
    std::lock_guard<std::mutex> lk(mutex_);
    return now_us_;
}

bool SimClock::advance_to(uint64_t t_us)
{
    std::lock_guard<std::mutex> lk(mutex_);
    if (t_us < now_us_) return false;
    now_us_ = t_us;
    cv_.notify_all();
    return true;
}

void SimClock::advance_by(uint64_t dt_us)
{
    std::lock_guard<std::mutex> lk(mutex_);
    now_us_ = (dt_us > kNever - now_us_) ? kNever : now_us_ + dt_us;
    cv_.notify_all();
}

void SimClock::set_step_hook(StepHook hook)
{
    std::lock_guard<std::mutex> lk(mutex_);
    hook_ = std::move(hook);
}

void SimClock::set_lockstep(bool on)
{
    std::lock_guard<std::mutex> lk(mutex_);
    lockstep_ = on;
    cv_.notify_all();
}

uint64_t SimClock::Waiter::wake_us() const
{
    const uint64_t ev = next_event_us != nullptr ? (*next_event_us)() : kNever;
    return std::min(deadline_us, ev);
}

bool SimClock::quiescent_locked() const
{
    if (participants_ == 0 || waiters_.size() < participants_) return false;
    for (const Waiter *w : waiters_) {
        if ((*w->ready)() || w->wake_us() <= now_us_) return false;  // about to wake
    }
    return true;
}

bool SimClock::wait_quiescent(std::chrono::milliseconds real_timeout)
{
    std::unique_lock<std::mutex> lk(mutex_);
    return cv_.wait_for(lk, real_timeout, [&] { return quiescent_locked(); });
}

size_t SimClock::participants() const
{
    std::lock_guard<std::mutex> lk(mutex_);
    return participants_;
}

SimClock::LockstepParticipant::LockstepParticipant(SimClock &clock) : clock_(clock)
{
    std::lock_guard<std::mutex> lk(clock_.mutex_);
    ++clock_.participants_;
}

SimClock::LockstepParticipant::~LockstepParticipant()
{
    std::lock_guard<std::mutex> lk(clock_.mutex_);
    --clock_.participants_;
    clock_.cv_.notify_all();  // the others may be quiescent now
}

uint64_t SimClock::next_wake_us() const
{
    std::lock_guard<std::mutex> lk(mutex_);
    uint64_t t = kNever;
    for (const Waiter *w : waiters_) t = std::min(t, w->wake_us());
    return t;
}

size_t SimClock::waiting() const
{
    std::lock_guard<std::mutex> lk(mutex_);
    return waiters_.size();
}

uint64_t SimClock::deadline_after(uint64_t now_us, uint32_t timeout_us)
{
    if (timeout_us == HAL_TIMEOUT_FOREVER) return kNever;
    return (timeout_us > kNever - now_us) ? kNever : now_us + timeout_us;
}

bool SimClock::wait_until(std::unique_lock<std::mutex> &lk, uint64_t deadline_us, const std::function<bool()> &ready,
                          const std::function<uint64_t()> *next_event_us)
{
    for (;;) {
        if (ready()) return true;
        if (now_us_ >= deadline_us) return false;
        if (lockstep_) {
            Waiter w{deadline_us, &ready, next_event_us};
            waiters_.push_back(&w);
            cv_.notify_all();  // the scheduler may now see quiescence
            cv_.wait(lk, [&] { return !lockstep_ || ready() || now_us_ >= w.wake_us(); });
            waiters_.erase(std::find(waiters_.begin(), waiters_.end(), &w));
            cv_.notify_all();
            continue;
        }
        if (!hook_) return false;  // polling model: nobody can move time for us
        const StepHook hook = hook_;  // the hook may replace itself
        const uint64_t before = now_us_;
        const uint64_t ev = next_event_us != nullptr ? (*next_event_us)() : kNever;
        const uint64_t target = std::max(std::min(deadline_us, ev), now_us_);
        lk.unlock();
        hook(target);
        lk.lock();
        if (now_us_ == before && !ready()) return false;  // the hook made no progress
    }
}

hal_status_t SimClock::op_now_us(hal_clock_t *dev, uint64_t *now_us)
{
    auto *self = static_cast<SimClock *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->mutex_);
    *now_us = self->now_us_;
    return HAL_OK;
}

hal_status_t SimClock::op_sleep_until_us(hal_clock_t *dev, uint64_t deadline_us)
{
    auto *self = static_cast<SimClock *>(dev->backend);
    std::unique_lock<std::mutex> lk(self->mutex_);
    static const std::function<bool()> never = [] { return false; };
    self->wait_until(lk, deadline_us, never);
    return self->now_us_ >= deadline_us ? HAL_OK : HAL_E_BUSY;
}

// ---------------------------------------------------------------------------

SimLockstepDriver::SimLockstepDriver(SimClock &clock, uint64_t max_step_us)
    : clock_(clock), max_step_us_(max_step_us)
{
    clock_.set_lockstep(true);
    thread_ = std::thread([this] { run(); });
}

SimLockstepDriver::~SimLockstepDriver()
{
    {
        std::lock_guard<std::mutex> lk(stop_mutex_);
        stop_ = true;
    }
    thread_.join();
    clock_.set_lockstep(false);
}

void SimLockstepDriver::run()
{
    for (;;) {
        {
            std::lock_guard<std::mutex> lk(stop_mutex_);
            if (stop_) return;
        }
        if (!clock_.wait_quiescent(std::chrono::milliseconds(5))) continue;
        const uint64_t now = clock_.now_us();
        uint64_t next = clock_.next_wake_us();
        if (max_step_us_ > 0 && (next == kNever || next - now > max_step_us_)) next = now + max_step_us_;
        if (next == kNever) {
            // everyone waits forever for an event only a non-participant can
            // cause: nothing to advance; do not spin on the quiescent state
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
            continue;
        }
        clock_.advance_to(next);
    }
}

}  // namespace coslam::sim
