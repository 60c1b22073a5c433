// Simulated GPIO controller (see sim_gpio.hpp).
#include "sim_hal/sim_gpio.hpp"

#include <stdexcept>

namespace coslam::sim {

SimGpio::SimGpio(SimClock &clock, uint32_t n_lines, size_t edge_queue_depth)
    : clock_(clock), depth_(edge_queue_depth), lines_(n_lines)
{
    if (n_lines == 0 || edge_queue_depth == 0) throw std::invalid_argument("SimGpio: n_lines and depth must be >= 1");
    static const hal_gpio_ops_t ops = {&SimGpio::op_line_count, &SimGpio::op_configure, &SimGpio::op_read,
                                       &SimGpio::op_write,      &SimGpio::op_wait_edge, &SimGpio::op_release,
                                       nullptr};
    handle_.ops = &ops;
    handle_.backend = this;
}

SimGpio::Line *SimGpio::line_locked(uint32_t line)
{
    return line < lines_.size() ? &lines_[line] : nullptr;
}

bool SimGpio::set_input_level(uint32_t line, bool high)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    Line *l = line_locked(line);
    if (l == nullptr) return false;
    const bool old_high = l->pin_in_high;
    l->pin_in_high = high;
    if (old_high == high || !l->configured || l->cfg.dir != HAL_GPIO_DIR_INPUT) return true;
    const bool active = high != l->cfg.active_low;
    const uint8_t edge = active ? HAL_GPIO_EDGE_RISING : HAL_GPIO_EDGE_FALLING;
    if ((l->cfg.edges & edge) == 0u) return true;
    if (l->edges.size() >= depth_) {
        l->overflow = true;
        ++dropped_;
    } else {
        l->edges.push_back(hal_gpio_event_t{edge, clock_.now_locked()});
    }
    clock_.notify_locked();
    return true;
}

std::optional<bool> SimGpio::output_level(uint32_t line) const
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    if (line >= lines_.size()) return std::nullopt;
    const Line &l = lines_[line];
    if (!l.configured || l.cfg.dir != HAL_GPIO_DIR_OUTPUT) return std::nullopt;
    return l.out_active != l.cfg.active_low;
}

void SimGpio::inject_read_error(uint32_t line, bool on)
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    if (Line *l = line_locked(line)) l->read_error = on;
}

uint64_t SimGpio::edges_dropped() const
{
    std::lock_guard<std::mutex> lk(clock_.mutex());
    return dropped_;
}

hal_status_t SimGpio::op_line_count(hal_gpio_t *dev, uint32_t *n)
{
    auto *self = static_cast<SimGpio *>(dev->backend);
    *n = static_cast<uint32_t>(self->lines_.size());
    return HAL_OK;
}

hal_status_t SimGpio::op_configure(hal_gpio_t *dev, uint32_t line, const hal_gpio_config_t *cfg)
{
    auto *self = static_cast<SimGpio *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    Line *l = self->line_locked(line);
    if (l == nullptr) return HAL_E_NOT_FOUND;
    l->configured = true;
    l->cfg = *cfg;
    l->edges.clear();
    l->overflow = false;
    l->out_active = (cfg->dir == HAL_GPIO_DIR_OUTPUT) ? cfg->initial_active : false;
    self->clock_.notify_locked();
    return HAL_OK;
}

hal_status_t SimGpio::op_read(hal_gpio_t *dev, uint32_t line, bool *active)
{
    auto *self = static_cast<SimGpio *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    Line *l = self->line_locked(line);
    if (l == nullptr) return HAL_E_NOT_FOUND;
    if (!l->configured) return HAL_E_CLOSED;
    if (l->read_error) return HAL_E_IO;
    *active = (l->cfg.dir == HAL_GPIO_DIR_OUTPUT) ? l->out_active : (l->pin_in_high != l->cfg.active_low);
    return HAL_OK;
}

hal_status_t SimGpio::op_write(hal_gpio_t *dev, uint32_t line, bool active)
{
    auto *self = static_cast<SimGpio *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    Line *l = self->line_locked(line);
    if (l == nullptr) return HAL_E_NOT_FOUND;
    if (!l->configured) return HAL_E_CLOSED;
    if (l->cfg.dir != HAL_GPIO_DIR_OUTPUT) return HAL_E_ARG;
    l->out_active = active;
    return HAL_OK;
}

hal_status_t SimGpio::op_wait_edge(hal_gpio_t *dev, uint32_t line, hal_gpio_event_t *ev, uint32_t timeout_us)
{
    auto *self = static_cast<SimGpio *>(dev->backend);
    std::unique_lock<std::mutex> lk(self->clock_.mutex());
    Line *l = self->line_locked(line);
    if (l == nullptr) return HAL_E_NOT_FOUND;
    if (!l->configured) return HAL_E_CLOSED;
    if (l->cfg.dir != HAL_GPIO_DIR_INPUT || l->cfg.edges == HAL_GPIO_EDGE_NONE) return HAL_E_ARG;
    const uint64_t deadline = SimClock::deadline_after(self->clock_.now_locked(), timeout_us);
    // Re-fetch the line inside the predicate: a release from another thread
    // ends the wait (HAL_E_CLOSED below).
    const std::function<bool()> ready = [self, line] {
        const Line &x = self->lines_[line];
        return !x.configured || x.overflow || !x.edges.empty();
    };
    self->clock_.wait_until(lk, deadline, ready);
    if (!l->configured) return HAL_E_CLOSED;
    if (l->overflow) {
        l->overflow = false;
        l->edges.clear();
        return HAL_E_OVERFLOW;
    }
    if (l->edges.empty()) return HAL_E_TIMEOUT;
    *ev = l->edges.front();
    l->edges.pop_front();
    return HAL_OK;
}

hal_status_t SimGpio::op_release(hal_gpio_t *dev, uint32_t line)
{
    auto *self = static_cast<SimGpio *>(dev->backend);
    std::lock_guard<std::mutex> lk(self->clock_.mutex());
    Line *l = self->line_locked(line);
    if (l == nullptr) return HAL_E_NOT_FOUND;
    l->configured = false;
    l->edges.clear();
    l->overflow = false;
    self->clock_.notify_locked();
    return HAL_OK;
}

}  // namespace coslam::sim
