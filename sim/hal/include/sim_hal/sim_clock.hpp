// sim_hal/sim_clock.hpp - simulated time behind hal_clock_t, and the world
// lock and wait machinery every simulated HAL device shares.
//
// Time model (docs/hal.md, "Simulated time"):
//  - Time is a uint64 [us] owned by the simulator. It moves only when the
//    simulator calls advance_to()/advance_by(), so a run goes as fast as the
//    host computes, independent of the wall clock.
//  - Firmware code that blocks (hal_clock_sleep_until_us, or a HAL wait with
//    timeout_us > 0) never advances time itself. Its wait is honoured by the
//    scheduling model the simulator picked:
//     * none (default): cooperative polling. A wait whose condition is not
//       already met returns at once: sleep_until_us gives HAL_E_BUSY,
//       device waits give HAL_E_TIMEOUT. Firmware stepped by the simulator
//       (node_step(now) style) uses timeout 0 and never notices.
//     * step hook (set_step_hook): single thread, firmware owns the loop.
//       While a wait is unmet the clock calls hook(deadline_us) repeatedly;
//       the hook steps the world (physics, device emulators) and advances
//       the clock by at most deadline - now per call. The wait ends as soon
//       as its condition holds or the deadline is reached; a hook call that
//       neither advances time nor satisfies the condition ends the wait
//       unmet (no spinning).
//     * lock-step (set_lockstep(true)): each robot's firmware runs in its
//       own thread and really blocks. Each such thread holds a
//       LockstepParticipant for as long as it runs. The simulator thread
//       calls wait_quiescent() until every participant is blocked with
//       nothing to do, then advances time (to next_wake_us() or its own
//       next physics step). Simulated time therefore never passes while a
//       firmware thread is computing, i.e. firmware runs infinitely fast.
//  - One SimClock is one world: every device built on it shares its mutex
//    (the world lock), so the simulator thread and firmware threads see a
//    consistent world. All public members are thread-safe.
#ifndef COSLAM_SIM_HAL_SIM_CLOCK_HPP
#define COSLAM_SIM_HAL_SIM_CLOCK_HPP

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "hal/hal_clock.h"

namespace coslam::sim {

class SimClock {
public:
    using StepHook = std::function<void(uint64_t deadline_us)>;

    explicit SimClock(uint64_t start_us = 0);
    SimClock(const SimClock &) = delete;
    SimClock &operator=(const SimClock &) = delete;
    ~SimClock();

    /// The C handle for firmware. Thread-safe; shareable by all robots.
    hal_clock_t *handle() { return &handle_; }

    // ---- simulator side -------------------------------------------------
    uint64_t now_us() const;
    /// Move time forward to t_us and wake waiters whose condition or
    /// deadline is now met. Returns false (time unchanged) if t_us < now.
    bool advance_to(uint64_t t_us);
    void advance_by(uint64_t dt_us);
    /// Cooperative single-thread model (see above). An empty hook restores
    /// the default polling model.
    void set_step_hook(StepHook hook);
    /// Threaded lock-step model on/off. Turning it off wakes every waiter.
    void set_lockstep(bool on);
    /// Lock-step: wait (real time, at most real_timeout) until there is at
    /// least one participant and every participant is blocked in a wait
    /// whose condition is unmet and whose deadline is in the future. True
    /// when reached; the world then stays still until time is advanced.
    bool wait_quiescent(std::chrono::milliseconds real_timeout);
    /// Registered lock-step participants (firmware threads).
    size_t participants() const;

    /// RAII registration of one firmware thread as a lock-step participant.
    /// Create it before the thread can block (best: in the spawning thread,
    /// before std::thread starts, and move it into the thread, so no
    /// quiescence is seen before every robot is up); destroy it when the
    /// thread ends (an ended thread never blocks, so it must stop counting).
    class LockstepParticipant {
    public:
        explicit LockstepParticipant(SimClock &clock);
        LockstepParticipant(const LockstepParticipant &) = delete;
        LockstepParticipant &operator=(const LockstepParticipant &) = delete;
        ~LockstepParticipant();

    private:
        SimClock &clock_;
    };
    /// Earliest deadline among blocked waits, UINT64_MAX if none.
    uint64_t next_wake_us() const;
    /// Number of threads blocked in a wait (lock-step model).
    size_t waiting() const;

    // ---- device side (simulated HAL backends) --------------------------
    std::mutex &mutex() const { return mutex_; }
    /// Current time; the caller holds mutex().
    uint64_t now_locked() const { return now_us_; }
    /// Device state changed (a frame, an edge, a datagram): wake waiters so
    /// they re-check. The caller holds mutex().
    void notify_locked() { cv_.notify_all(); }
    /// Wait until ready() or now >= deadline_us under the current model.
    /// The caller holds lk (on mutex()); ready() is evaluated under it,
    /// possibly from another thread (lock-step). next_event_us, if given,
    /// returns the simulated time at which ready() will next become true by
    /// itself (a datagram in flight), UINT64_MAX if unknown: schedulers
    /// then stop time exactly there. Returns ready().
    bool wait_until(std::unique_lock<std::mutex> &lk, uint64_t deadline_us, const std::function<bool()> &ready,
                    const std::function<uint64_t()> *next_event_us = nullptr);
    /// now + timeout_us, saturating; HAL_TIMEOUT_FOREVER gives UINT64_MAX.
    static uint64_t deadline_after(uint64_t now_us, uint32_t timeout_us);

private:
    struct Waiter {
        uint64_t deadline_us;
        const std::function<bool()> *ready;
        const std::function<uint64_t()> *next_event_us;
        uint64_t wake_us() const;
    };
    bool quiescent_locked() const;

    static hal_status_t op_now_us(hal_clock_t *dev, uint64_t *now_us);
    static hal_status_t op_sleep_until_us(hal_clock_t *dev, uint64_t deadline_us);

    mutable std::mutex mutex_;
    mutable std::condition_variable cv_;
    uint64_t now_us_;
    StepHook hook_;
    bool lockstep_ = false;
    std::vector<Waiter *> waiters_;
    size_t participants_ = 0;
    hal_clock_t handle_;
};

/// Lock-step driver for tests and simple runs: turns lock-step on and runs
/// a thread that, whenever the participants are quiescent, advances the
/// clock to the earliest wake-up, by at most max_step_us (0 = no limit)
/// per step. A real simulator does the same in its own loop, interleaving
/// physics steps. Stops (and turns lock-step off) on destruction.
class SimLockstepDriver {
public:
    SimLockstepDriver(SimClock &clock, uint64_t max_step_us);
    SimLockstepDriver(const SimLockstepDriver &) = delete;
    SimLockstepDriver &operator=(const SimLockstepDriver &) = delete;
    ~SimLockstepDriver();

private:
    void run();
    SimClock &clock_;
    uint64_t max_step_us_;
    std::mutex stop_mutex_;
    bool stop_ = false;
    std::thread thread_;
};

}  // namespace coslam::sim

#endif
