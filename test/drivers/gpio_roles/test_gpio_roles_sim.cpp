// The GPIO roles driver on the simulated HAL (SimGpio + SimClock): the same
// C driver the robot runs, with the simulator playing the wiring. A 2 s run
// at a 1 ms loop: e-stop wired normally-closed (active-low, pin high =
// released), a bouncing bumper hit, an LED on an active-low pin.
#include <gtest/gtest.h>

#include "gpio_roles.h"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_gpio.hpp"

using namespace coslam::sim;

TEST(GpioRolesOnSim, BumperHitEstopAndLedTimeline)
{
    SimClock clock(0);
    SimGpio gpio(clock, 8);
    gpio.set_input_level(2, true);  // e-stop loop closed: released
    gpio_roles_config_t cfg{};
    cfg.n_bumpers = 1;
    cfg.bumpers[0] = {0, false};
    cfg.bumper_debounce_us = 10000;
    cfg.has_estop = true;
    cfg.estop = {2, true};
    cfg.estop_release_us = 100000;
    cfg.n_leds = 1;
    cfg.leds[0] = {5, true};
    gpio_roles_t roles;
    ASSERT_EQ(gpio_roles_init(&roles, &cfg, gpio.handle(), clock.handle()), HAL_OK);
    ASSERT_EQ(gpio_roles_led_set(&roles, 0, GPIO_ROLES_PATTERN_BLINK_SLOW), HAL_OK);

    uint64_t first_move_us = 0, stop_at_us = 0, estop_at_us = 0;
    bool acked = false;
    for (uint64_t t = 1000; t <= 2000000; t += 1000) {
        clock.advance_to(t);
        // the world: bumper hit at 0.7 s, bouncing until 702 ms, released at 1.0 s;
        // the e-stop wire is cut at 1.5 s
        if (t >= 700000 && t < 703000) gpio.set_input_level(0, (t / 1000) % 2 == 0);
        if (t == 703000) gpio.set_input_level(0, true);
        if (t == 1000000) gpio.set_input_level(0, false);
        if (t == 1500000) gpio.set_input_level(2, false);

        gpio_roles_status_t st;
        ASSERT_EQ(gpio_roles_update(&roles, &st), HAL_OK);
        if (!st.stop_requested && first_move_us == 0) first_move_us = t;
        if (st.bumpers_latched != 0 && stop_at_us == 0) stop_at_us = t;
        if (st.estop_active && t > 1000000 && estop_at_us == 0) estop_at_us = t;
        if (t == 1100000) {  // the operator acknowledges after the release
            EXPECT_EQ(gpio_roles_bumper_ack(&roles, 0), HAL_OK);
            acked = true;
        }
        if (t > 1100000 && t < 1500000) {
            EXPECT_FALSE(st.stop_requested) << "t = " << t;
        }
        if (t >= 712000 && t <= 1100000) {
            EXPECT_TRUE(st.stop_requested) << "t = " << t;
        }
        // LED: blink 1 Hz from t = 0, active-low pin
        const bool led_on = (t / 500000) % 2 == 0;
        ASSERT_EQ(gpio.output_level(5), std::optional<bool>(!led_on)) << "t = " << t;
    }
    EXPECT_TRUE(acked);
    EXPECT_EQ(first_move_us, 101000u) << "released for 100 ms from its first released sample (1 ms)";
    EXPECT_EQ(stop_at_us, 712000u) << "latched 10 ms after the last bounce (702 ms)";
    EXPECT_EQ(estop_at_us, 1500000u) << "the cut wire stops at once";
    gpio_roles_deinit(&roles);
    EXPECT_FALSE(gpio.output_level(5).has_value());
}
