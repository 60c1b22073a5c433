// The libgpiod v1 GPIO backend in the GPIO conformance suite, against the
// link-time fake of libgpiod (gpiod_fake.h) since there is no gpio-sim
// here. The fake's monotonic time is the harness clock, so stamps and
// timeouts are checked like the simulator's.
#include "conformance.hpp"
#include "gpiod_fake.h"
#include "hal/hal_gpio_linux.h"

namespace {

hal_status_t fake_now(hal_clock_t *, uint64_t *now_us)
{
    *now_us = fake_gpiod.now_us;
    return HAL_OK;
}

const hal_clock_ops_t kFakeClockOps = {&fake_now, nullptr, nullptr};

struct LinuxGpioFakeHarness : conf::GpioHarness {
    LinuxGpioFakeHarness()
    {
        fake_gpiod_reset(16);
        fake_gpiod.now_us = 5000000;
        EXPECT_EQ(hal_gpio_linux_open(&g, "gpiochip0", "conformance"), HAL_OK);
    }
    ~LinuxGpioFakeHarness() override { hal_gpio_close(&g.dev); }
    hal_gpio_t *dev() override { return &g.dev; }
    uint32_t input_line() const override { return 4; }
    uint32_t output_line() const override { return 9; }
    void drive_input(uint32_t line, bool high) override { fake_gpiod_drive(line, high); }
    bool observe_output(uint32_t line) override { return fake_gpiod_pin(line); }
    hal_clock_t *clock() override { return &clk; }
    void let_time_pass_us(uint64_t us) override { fake_gpiod.now_us += us; }
    hal_gpio_linux_t g{};
    hal_clock_t clk{&kFakeClockOps, nullptr};
};

}  // namespace

INSTANTIATE_TEST_SUITE_P(Linux, GpioConformance,
                         ::testing::Values(conf::make_backend<conf::GpioHarness, LinuxGpioFakeHarness>("gpiod_fake")),
                         conf::BackendName());
