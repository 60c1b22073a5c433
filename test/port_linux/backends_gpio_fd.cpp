// coslam-robot's e2e GPIO backend (firmware/port/linux/robot_gpio_fd.h:
// line states on an inherited socket, --gpio-fd) in the GPIO conformance
// suite: the harness holds the device server's end of a socketpair, drives
// inputs with "P line level" and observes outputs from "O line level". The
// backend stamps edges with the real monotonic clock, so the harness is
// real time.
#include <sys/socket.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <map>

#include "conformance.hpp"
#include "hal/hal_clock_linux.h"
#include "robot_gpio_fd.h"

namespace {

struct GpioFdHarness : conf::GpioHarness {
    GpioFdHarness()
    {
        EXPECT_EQ(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv), 0);
        EXPECT_EQ(robot_gpio_fd_open(&g, sv[1], hal_clock_linux()), HAL_OK);
        close(sv[1]);  // the backend holds its dup, as after the robot's exec
    }
    ~GpioFdHarness() override
    {
        hal_gpio_close(&g.dev);
        close(sv[0]);
    }
    hal_gpio_t *dev() override { return &g.dev; }
    uint32_t input_line() const override { return 1; }
    uint32_t output_line() const override { return 2; }
    void drive_input(uint32_t line, bool high) override
    {
        uint64_t now = 0;
        (void)hal_clock_now_us(hal_clock_linux(), &now);
        char d[64];
        const int n = std::snprintf(d, sizeof d, "P %u %u %llu", static_cast<unsigned>(line), high ? 1u : 0u,
                                    static_cast<unsigned long long>(now));
        EXPECT_EQ(send(sv[0], d, static_cast<size_t>(n), 0), n);
    }
    bool observe_output(uint32_t line) override
    {
        char d[64];
        ssize_t m;
        while ((m = recv(sv[0], d, sizeof d - 1, MSG_DONTWAIT)) > 0) {
            d[m] = '\0';
            unsigned l = 0, v = 0;
            if (std::sscanf(d, "O %u %u", &l, &v) == 2) pins[l] = v != 0;
        }
        return pins[line];
    }
    size_t edge_queue_depth() const override { return ROBOT_GPIO_FD_QUEUE; }
    hal_clock_t *clock() override { return hal_clock_linux(); }
    void let_time_pass_us(uint64_t us) override { usleep(static_cast<useconds_t>(us)); }
    bool real_time() const override { return true; }
    int sv[2] = {-1, -1};
    robot_gpio_fd_t g{};
    std::map<unsigned, bool> pins;
};

}  // namespace

INSTANTIATE_TEST_SUITE_P(RobotE2e, GpioConformance,
                         ::testing::Values(conf::make_backend<conf::GpioHarness, GpioFdHarness>("gpio_fd")),
                         conf::BackendName());

// What the suite does not cover: the wire's own failures.
TEST(RobotGpioFd, BadDatagramsAreCountedAndThePeersCloseIsClosed)
{
    GpioFdHarness h;
    hal_gpio_config_t in{};
    in.dir = HAL_GPIO_DIR_INPUT;
    in.active_low = true;  // the e-stop: pins start low, so it starts active
    ASSERT_EQ(hal_gpio_configure(h.dev(), 1, &in), HAL_OK);
    bool active = false;
    ASSERT_EQ(hal_gpio_read(h.dev(), 1, &active), HAL_OK);
    EXPECT_TRUE(active);
    for (const char *bad : {"P 1", "P 99 1", "P 1 2", "X 1 1", "P 1 1 5 extra", "O 1 1"}) {
        ASSERT_GT(send(h.sv[0], bad, std::strlen(bad), 0), 0);
    }
    ASSERT_EQ(hal_gpio_read(h.dev(), 1, &active), HAL_OK);
    EXPECT_TRUE(active);  // none of them moved the pin
    EXPECT_EQ(h.g.bad, 6u);
    h.drive_input(1, true);
    ASSERT_EQ(hal_gpio_read(h.dev(), 1, &active), HAL_OK);
    EXPECT_FALSE(active);
    EXPECT_EQ(h.g.received, 1u);
    close(h.sv[0]);
    h.sv[0] = -1;
    EXPECT_EQ(hal_gpio_read(h.dev(), 1, &active), HAL_E_CLOSED);  // the device slot then reports it lost
}
