// sim_hal/sim_gpio.hpp - a simulated GPIO controller behind hal_gpio_t.
//
// The simulator plays the wiring: it drives the electrical level of input
// pins (a bumper switch closing, an e-stop wire cut) and reads the level the
// firmware drives on outputs (LEDs). Edges are stamped with the SimClock
// time at which the simulator changed the pin. Every line starts released
// with its input pin electrically low (pull-down).
#ifndef COSLAM_SIM_HAL_SIM_GPIO_HPP
#define COSLAM_SIM_HAL_SIM_GPIO_HPP

#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include "hal/hal_gpio.h"
#include "sim_hal/sim_clock.hpp"

namespace coslam::sim {

class SimGpio {
public:
    /// n_lines >= 1; edge_queue_depth >= 1 edges per line before overflow.
    SimGpio(SimClock &clock, uint32_t n_lines, size_t edge_queue_depth = 16);
    SimGpio(const SimGpio &) = delete;
    SimGpio &operator=(const SimGpio &) = delete;

    hal_gpio_t *handle() { return &handle_; }

    // ---- simulator side (thread-safe) -----------------------------------
    /// Set the electrical level the world applies to a pin. On a configured
    /// input, a change queues the (logical) edge if selected. False if the
    /// line does not exist.
    bool set_input_level(uint32_t line, bool high);
    /// Electrical level driven by the firmware on an output; nullopt if the
    /// line is not configured as an output (floating).
    std::optional<bool> output_level(uint32_t line) const;
    /// Fault injection: reads of this line fail with HAL_E_IO while on.
    void inject_read_error(uint32_t line, bool on);
    /// Edges dropped because a line's queue was full (all lines).
    uint64_t edges_dropped() const;
    size_t edge_queue_depth() const { return depth_; }

private:
    struct Line {
        bool configured = false;
        hal_gpio_config_t cfg{};
        bool pin_in_high = false;   // level applied by the world
        bool out_active = false;    // logical level written by firmware
        bool read_error = false;
        bool overflow = false;
        std::deque<hal_gpio_event_t> edges;
    };
    Line *line_locked(uint32_t line);

    static hal_status_t op_line_count(hal_gpio_t *dev, uint32_t *n);
    static hal_status_t op_configure(hal_gpio_t *dev, uint32_t line, const hal_gpio_config_t *cfg);
    static hal_status_t op_read(hal_gpio_t *dev, uint32_t line, bool *active);
    static hal_status_t op_write(hal_gpio_t *dev, uint32_t line, bool active);
    static hal_status_t op_wait_edge(hal_gpio_t *dev, uint32_t line, hal_gpio_event_t *ev, uint32_t timeout_us);
    static hal_status_t op_release(hal_gpio_t *dev, uint32_t line);

    SimClock &clock_;
    size_t depth_;
    std::vector<Line> lines_;
    uint64_t dropped_ = 0;
    hal_gpio_t handle_;
};

}  // namespace coslam::sim

#endif
