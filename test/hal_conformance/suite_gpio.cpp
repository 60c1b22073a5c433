// hal_gpio contract conformance (see hal/hal_gpio.h).
#include "conformance.hpp"

using conf::now_of;

namespace {

hal_gpio_config_t input_cfg(bool active_low, uint8_t edges)
{
    hal_gpio_config_t c{};
    c.dir = HAL_GPIO_DIR_INPUT;
    c.active_low = active_low;
    c.edges = edges;
    return c;
}

hal_gpio_config_t output_cfg(bool active_low, bool initial_active)
{
    hal_gpio_config_t c{};
    c.dir = HAL_GPIO_DIR_OUTPUT;
    c.active_low = active_low;
    c.initial_active = initial_active;
    return c;
}

bool read_line(hal_gpio_t *g, uint32_t line)
{
    bool v = false;
    EXPECT_EQ(hal_gpio_read(g, line, &v), HAL_OK);
    return v;
}

}  // namespace

TEST_P(GpioConformance, LineCountCoversTestLines)
{
    uint32_t n = 0;
    ASSERT_EQ(hal_gpio_line_count(h->dev(), &n), HAL_OK);
    EXPECT_GT(n, h->input_line());
    EXPECT_GT(n, h->output_line());
}

TEST_P(GpioConformance, LineOutOfRangeIsNotFound)
{
    uint32_t n = 0;
    ASSERT_EQ(hal_gpio_line_count(h->dev(), &n), HAL_OK);
    const hal_gpio_config_t in = input_cfg(false, HAL_GPIO_EDGE_BOTH);
    bool v;
    hal_gpio_event_t ev;
    for (uint32_t line : {n, n + 1, UINT32_MAX}) {
        EXPECT_EQ(hal_gpio_configure(h->dev(), line, &in), HAL_E_NOT_FOUND);
        EXPECT_EQ(hal_gpio_read(h->dev(), line, &v), HAL_E_NOT_FOUND);
        EXPECT_EQ(hal_gpio_write(h->dev(), line, true), HAL_E_NOT_FOUND);
        EXPECT_EQ(hal_gpio_wait_edge(h->dev(), line, &ev, 0), HAL_E_NOT_FOUND);
        EXPECT_EQ(hal_gpio_release(h->dev(), line), HAL_E_NOT_FOUND);
    }
}

TEST_P(GpioConformance, UnconfiguredLineIsClosed)
{
    bool v;
    hal_gpio_event_t ev;
    EXPECT_EQ(hal_gpio_read(h->dev(), h->input_line(), &v), HAL_E_CLOSED);
    EXPECT_EQ(hal_gpio_write(h->dev(), h->output_line(), true), HAL_E_CLOSED);
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), h->input_line(), &ev, 0), HAL_E_CLOSED);
}

TEST_P(GpioConformance, BadConfigurationsRejected)
{
    hal_gpio_config_t c = output_cfg(false, false);
    c.edges = HAL_GPIO_EDGE_RISING;
    EXPECT_EQ(hal_gpio_configure(h->dev(), h->output_line(), &c), HAL_E_ARG) << "edges on an output";
    c = input_cfg(false, 4);
    EXPECT_EQ(hal_gpio_configure(h->dev(), h->input_line(), &c), HAL_E_ARG) << "unknown edge bit";
    // (an out-of-range dir is checked by the wrapper too; that test is in C,
    // test_gpio_linux, since such an enum value is undefined behaviour in C++)
    EXPECT_EQ(hal_gpio_configure(h->dev(), h->input_line(), nullptr), HAL_E_ARG);
    EXPECT_EQ(hal_gpio_read(h->dev(), h->input_line(), nullptr), HAL_E_ARG);
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), h->input_line(), nullptr, 0), HAL_E_ARG);
}

TEST_P(GpioConformance, InputActiveHighFollowsPin)
{
    const hal_gpio_config_t c = input_cfg(false, HAL_GPIO_EDGE_NONE);
    h->drive_input(h->input_line(), false);
    ASSERT_EQ(hal_gpio_configure(h->dev(), h->input_line(), &c), HAL_OK);
    EXPECT_FALSE(read_line(h->dev(), h->input_line()));
    h->drive_input(h->input_line(), true);
    EXPECT_TRUE(read_line(h->dev(), h->input_line()));
    h->drive_input(h->input_line(), false);
    EXPECT_FALSE(read_line(h->dev(), h->input_line()));
}

TEST_P(GpioConformance, InputActiveLowInverts)
{
    const hal_gpio_config_t c = input_cfg(true, HAL_GPIO_EDGE_NONE);
    h->drive_input(h->input_line(), true);
    ASSERT_EQ(hal_gpio_configure(h->dev(), h->input_line(), &c), HAL_OK);
    EXPECT_FALSE(read_line(h->dev(), h->input_line())) << "high pin on an active-low line is inactive";
    h->drive_input(h->input_line(), false);
    EXPECT_TRUE(read_line(h->dev(), h->input_line()));
}

TEST_P(GpioConformance, OutputDrivesPinAndReadsBack)
{
    for (bool active_low : {false, true}) {
        SCOPED_TRACE(active_low ? "active-low" : "active-high");
        const hal_gpio_config_t c = output_cfg(active_low, true);
        ASSERT_EQ(hal_gpio_configure(h->dev(), h->output_line(), &c), HAL_OK);
        EXPECT_EQ(h->observe_output(h->output_line()), !active_low) << "initial_active honoured";
        EXPECT_TRUE(read_line(h->dev(), h->output_line()));
        ASSERT_EQ(hal_gpio_write(h->dev(), h->output_line(), false), HAL_OK);
        EXPECT_EQ(h->observe_output(h->output_line()), active_low);
        EXPECT_FALSE(read_line(h->dev(), h->output_line()));
        ASSERT_EQ(hal_gpio_write(h->dev(), h->output_line(), true), HAL_OK);
        EXPECT_EQ(h->observe_output(h->output_line()), !active_low);
        EXPECT_TRUE(read_line(h->dev(), h->output_line()));
    }
    const hal_gpio_config_t off = output_cfg(false, false);
    ASSERT_EQ(hal_gpio_configure(h->dev(), h->output_line(), &off), HAL_OK);
    EXPECT_FALSE(h->observe_output(h->output_line()));
}

TEST_P(GpioConformance, WriteToInputIsArg)
{
    const hal_gpio_config_t c = input_cfg(false, HAL_GPIO_EDGE_NONE);
    ASSERT_EQ(hal_gpio_configure(h->dev(), h->input_line(), &c), HAL_OK);
    EXPECT_EQ(hal_gpio_write(h->dev(), h->input_line(), true), HAL_E_ARG);
}

TEST_P(GpioConformance, WaitEdgeNeedsEdgeInput)
{
    hal_gpio_event_t ev;
    const hal_gpio_config_t in = input_cfg(false, HAL_GPIO_EDGE_NONE);
    ASSERT_EQ(hal_gpio_configure(h->dev(), h->input_line(), &in), HAL_OK);
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), h->input_line(), &ev, 0), HAL_E_ARG);
    const hal_gpio_config_t out = output_cfg(false, false);
    ASSERT_EQ(hal_gpio_configure(h->dev(), h->output_line(), &out), HAL_OK);
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), h->output_line(), &ev, 0), HAL_E_ARG);
}

TEST_P(GpioConformance, EdgesQueuedInOrderWithStamps)
{
    const uint32_t in = h->input_line();
    h->drive_input(in, false);
    const hal_gpio_config_t c = input_cfg(false, HAL_GPIO_EDGE_BOTH);
    ASSERT_EQ(hal_gpio_configure(h->dev(), in, &c), HAL_OK);
    hal_clock_t *clk = h->clock();
    const uint64_t t0 = clk ? now_of(clk) : 0;
    h->drive_input(in, true);
    h->let_time_pass_us(1000);
    h->drive_input(in, false);
    h->let_time_pass_us(1000);
    h->drive_input(in, true);
    const uint64_t t1 = clk ? now_of(clk) : 0;
    hal_gpio_event_t ev[3];
    for (auto &e : ev) ASSERT_EQ(hal_gpio_wait_edge(h->dev(), in, &e, 0), HAL_OK);
    EXPECT_EQ(ev[0].edge, HAL_GPIO_EDGE_RISING);
    EXPECT_EQ(ev[1].edge, HAL_GPIO_EDGE_FALLING);
    EXPECT_EQ(ev[2].edge, HAL_GPIO_EDGE_RISING);
    EXPECT_LE(ev[0].stamp_us, ev[1].stamp_us);
    EXPECT_LE(ev[1].stamp_us, ev[2].stamp_us);
    if (clk != nullptr) {
        EXPECT_GE(ev[0].stamp_us, t0);
        EXPECT_LE(ev[2].stamp_us, t1);
        EXPECT_GE(ev[1].stamp_us - ev[0].stamp_us, 1000u) << "stamps are in microseconds";
    }
    hal_gpio_event_t none;
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), in, &none, 0), HAL_E_TIMEOUT) << "queue drained";
}

TEST_P(GpioConformance, EdgeSelectionFilters)
{
    const uint32_t in = h->input_line();
    for (uint8_t sel : {uint8_t{HAL_GPIO_EDGE_RISING}, uint8_t{HAL_GPIO_EDGE_FALLING}}) {
        SCOPED_TRACE(sel == HAL_GPIO_EDGE_RISING ? "rising only" : "falling only");
        h->drive_input(in, false);
        const hal_gpio_config_t c = input_cfg(false, sel);
        ASSERT_EQ(hal_gpio_configure(h->dev(), in, &c), HAL_OK);
        for (int i = 0; i < 3; ++i) {
            h->drive_input(in, true);
            h->let_time_pass_us(100);
            h->drive_input(in, false);
            h->let_time_pass_us(100);
        }
        hal_gpio_event_t ev;
        for (int i = 0; i < 3; ++i) {
            ASSERT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 0), HAL_OK);
            EXPECT_EQ(ev.edge, sel);
        }
        EXPECT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 0), HAL_E_TIMEOUT);
    }
}

TEST_P(GpioConformance, EdgesAreLogicalOnActiveLow)
{
    const uint32_t in = h->input_line();
    h->drive_input(in, true);  // inactive
    const hal_gpio_config_t c = input_cfg(true, HAL_GPIO_EDGE_BOTH);
    ASSERT_EQ(hal_gpio_configure(h->dev(), in, &c), HAL_OK);
    h->drive_input(in, false);  // becomes active
    hal_gpio_event_t ev;
    ASSERT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 0), HAL_OK);
    EXPECT_EQ(ev.edge, HAL_GPIO_EDGE_RISING) << "pin fell, line became active: logical rising";
    h->let_time_pass_us(10);
    h->drive_input(in, true);
    ASSERT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 0), HAL_OK);
    EXPECT_EQ(ev.edge, HAL_GPIO_EDGE_FALLING);
}

TEST_P(GpioConformance, WaitEdgeTimesOut)
{
    const uint32_t in = h->input_line();
    h->drive_input(in, false);
    const hal_gpio_config_t c = input_cfg(false, HAL_GPIO_EDGE_BOTH);
    ASSERT_EQ(hal_gpio_configure(h->dev(), in, &c), HAL_OK);
    hal_clock_t *clk = h->clock();
    const uint64_t t0 = clk ? now_of(clk) : 0;
    hal_gpio_event_t ev;
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 2000), HAL_E_TIMEOUT);
    if (clk != nullptr) {
        EXPECT_GE(now_of(clk) - t0, 2000u) << "returned before the timeout";
    }
}

TEST_P(GpioConformance, ReconfigureDropsQueuedEdges)
{
    const uint32_t in = h->input_line();
    h->drive_input(in, false);
    const hal_gpio_config_t c = input_cfg(false, HAL_GPIO_EDGE_BOTH);
    ASSERT_EQ(hal_gpio_configure(h->dev(), in, &c), HAL_OK);
    h->drive_input(in, true);
    h->let_time_pass_us(10);
    h->drive_input(in, false);
    ASSERT_EQ(hal_gpio_configure(h->dev(), in, &c), HAL_OK);
    hal_gpio_event_t ev;
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 0), HAL_E_TIMEOUT);
}

TEST_P(GpioConformance, ReleaseClosesLine)
{
    const hal_gpio_config_t c = input_cfg(false, HAL_GPIO_EDGE_NONE);
    ASSERT_EQ(hal_gpio_configure(h->dev(), h->input_line(), &c), HAL_OK);
    EXPECT_EQ(hal_gpio_release(h->dev(), h->input_line()), HAL_OK);
    bool v;
    EXPECT_EQ(hal_gpio_read(h->dev(), h->input_line(), &v), HAL_E_CLOSED);
    EXPECT_EQ(hal_gpio_release(h->dev(), h->input_line()), HAL_OK) << "release is idempotent";
    ASSERT_EQ(hal_gpio_configure(h->dev(), h->input_line(), &c), HAL_OK) << "a released line can be claimed again";
}

TEST_P(GpioConformance, OverflowReportedOnceThenRecovers)
{
    const size_t depth = h->edge_queue_depth();
    if (depth == 0) GTEST_SKIP() << "backend cannot detect edge overflow";
    const uint32_t in = h->input_line();
    h->drive_input(in, false);
    const hal_gpio_config_t c = input_cfg(false, HAL_GPIO_EDGE_BOTH);
    ASSERT_EQ(hal_gpio_configure(h->dev(), in, &c), HAL_OK);
    bool level = false;
    for (size_t i = 0; i < depth + 5; ++i) {
        level = !level;
        h->drive_input(in, level);
        h->let_time_pass_us(10);
    }
    hal_gpio_event_t ev;
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 0), HAL_E_OVERFLOW);
    EXPECT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 0), HAL_E_TIMEOUT) << "queue emptied after overflow";
    EXPECT_EQ(read_line(h->dev(), in), level) << "the level is still right after overflow";
    h->drive_input(in, !level);
    ASSERT_EQ(hal_gpio_wait_edge(h->dev(), in, &ev, 0), HAL_OK);
    EXPECT_EQ(ev.edge, level ? HAL_GPIO_EDGE_FALLING : HAL_GPIO_EDGE_RISING);
}
