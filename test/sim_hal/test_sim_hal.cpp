// Backend-specific tests of the simulated HAL: the channel model of the
// link hub, the three blocking models of the simulated clock, capacities
// and fault injection. (Contract behaviour is in test/hal_conformance.)
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>

#include "sim_hal/sim_camera.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_gpio.hpp"
#include "sim_hal/sim_link.hpp"
#include "sim_hal/sim_serial.hpp"
#include "sim_hal/sim_storage.hpp"

using namespace coslam::sim;

namespace {

std::vector<uint8_t> bytes(std::initializer_list<uint8_t> l) { return std::vector<uint8_t>(l); }

hal_status_t send(hal_link_t *l, uint16_t to, const std::vector<uint8_t> &m)
{
    return hal_link_send(l, to, m.data(), m.size(), 0);
}

struct Got {
    hal_status_t st;
    hal_link_rx_info_t info;
    std::vector<uint8_t> data;
};

Got recv(hal_link_t *l, uint32_t timeout_us = 0)
{
    Got g{};
    g.data.resize(HAL_LINK_MAX_PAYLOAD);
    g.st = hal_link_recv(l, g.data.data(), g.data.size(), &g.info, timeout_us);
    g.data.resize(g.st == HAL_OK ? g.info.len : 0);
    return g;
}

}  // namespace

// ---------------------------------------------------------------------------
// Clock models
// ---------------------------------------------------------------------------

TEST(SimClock, PollModelNeverBlocksNorAdvances)
{
    SimClock clk(500);
    EXPECT_EQ(hal_clock_sleep_until_us(clk.handle(), 400), HAL_OK);
    EXPECT_EQ(hal_clock_sleep_until_us(clk.handle(), 500), HAL_OK);
    EXPECT_EQ(hal_clock_sleep_until_us(clk.handle(), 501), HAL_E_BUSY) << "no scheduler: cannot wait";
    EXPECT_EQ(clk.now_us(), 500u);
    SimGpio gpio(clk, 2);
    hal_gpio_config_t c{};
    c.dir = HAL_GPIO_DIR_INPUT;
    c.edges = HAL_GPIO_EDGE_BOTH;
    ASSERT_EQ(hal_gpio_configure(gpio.handle(), 0, &c), HAL_OK);
    hal_gpio_event_t ev;
    EXPECT_EQ(hal_gpio_wait_edge(gpio.handle(), 0, &ev, 1000000), HAL_E_TIMEOUT);
    EXPECT_EQ(clk.now_us(), 500u) << "a device wait must not move time by itself";
}

TEST(SimClock, AdvanceRefusesToGoBack)
{
    SimClock clk(100);
    EXPECT_FALSE(clk.advance_to(99));
    EXPECT_EQ(clk.now_us(), 100u);
    EXPECT_TRUE(clk.advance_to(100));
    clk.advance_by(UINT64_MAX);
    EXPECT_EQ(clk.now_us(), UINT64_MAX) << "saturates";
}

TEST(SimClock, HookStepsWorldUntilDeadline)
{
    SimClock clk;
    std::vector<uint64_t> targets;
    clk.set_step_hook([&](uint64_t deadline) {
        targets.push_back(deadline);
        clk.advance_to(std::min(deadline, clk.now_us() + 300));  // a 300 us physics step
    });
    ASSERT_EQ(hal_clock_sleep_until_us(clk.handle(), 1000), HAL_OK);
    EXPECT_EQ(clk.now_us(), 1000u) << "the last step is cut at the deadline";
    EXPECT_EQ(targets.size(), 4u);  // 300, 600, 900, 1000
    for (uint64_t t : targets) EXPECT_EQ(t, 1000u);
}

TEST(SimClock, HookWithoutProgressEndsWait)
{
    SimClock clk;
    int calls = 0;
    clk.set_step_hook([&](uint64_t) { ++calls; });
    EXPECT_EQ(hal_clock_sleep_until_us(clk.handle(), 10), HAL_E_BUSY);
    EXPECT_EQ(calls, 1) << "no spinning on a stuck world";
}

TEST(SimClock, HookStopsAtDeviceEventTime)
{
    // a datagram in flight bounds the hook's target, so a 1 s receive wait
    // returns at the arrival instant, not after a 1 s jump
    SimClock clk;
    clk.set_step_hook([&](uint64_t deadline) { clk.advance_to(deadline); });
    SimLinkParams p;
    p.latency_us = 1500;
    SimLinkHub hub(clk, 2, p);
    ASSERT_EQ(send(hub.endpoint(0), 1, bytes({9})), HAL_OK);
    Got g = recv(hub.endpoint(1), 1000000);
    ASSERT_EQ(g.st, HAL_OK);
    EXPECT_EQ(g.info.stamp_us, 1500u);
    EXPECT_EQ(clk.now_us(), 1500u);
}

TEST(SimClock, HookEventEndsEdgeWaitEarly)
{
    SimClock clk;
    SimGpio gpio(clk, 1);
    clk.set_step_hook([&](uint64_t deadline) {
        const uint64_t next = std::min(deadline, clk.now_us() + 100);
        clk.advance_to(next);
        if (next == 700) gpio.set_input_level(0, true);  // the bumper closes at 700 us
    });
    hal_gpio_config_t c{};
    c.dir = HAL_GPIO_DIR_INPUT;
    c.edges = HAL_GPIO_EDGE_RISING;
    ASSERT_EQ(hal_gpio_configure(gpio.handle(), 0, &c), HAL_OK);
    hal_gpio_event_t ev;
    ASSERT_EQ(hal_gpio_wait_edge(gpio.handle(), 0, &ev, 5000), HAL_OK);
    EXPECT_EQ(ev.stamp_us, 700u);
    EXPECT_EQ(clk.now_us(), 700u) << "the wait ends at the event, not the timeout";
}

// Two robot threads in lock-step: A sends a ping every 10 ms of simulated
// time; B answers each. Simulated time never moves while a thread computes,
// so the round-trip times are exact however slow the host is.
TEST(SimClock, LockstepTwoRobotPingPong)
{
    SimClock clk;
    SimLinkParams p;
    p.latency_us = 3000;
    SimLinkHub hub(clk, 2, p);
    std::vector<uint64_t> rtt;
    {
        SimLockstepDriver driver(clk, 0);
        auto pa = std::make_unique<SimClock::LockstepParticipant>(clk);
        auto pb = std::make_unique<SimClock::LockstepParticipant>(clk);
        std::thread a([&, me = std::move(pa)] {
            hal_link_t *l = hub.endpoint(0);
            uint64_t next = 0;
            for (uint8_t i = 0; i < 5; ++i) {
                next += 10000;
                ASSERT_EQ(hal_clock_sleep_until_us(clk.handle(), next), HAL_OK);
                uint64_t t0 = 0;
                hal_clock_now_us(clk.handle(), &t0);
                EXPECT_EQ(t0, next);
                ASSERT_EQ(send(l, 1, bytes({i})), HAL_OK);
                Got g = recv(l, HAL_TIMEOUT_FOREVER);
                ASSERT_EQ(g.st, HAL_OK);
                ASSERT_EQ(g.data, bytes({static_cast<uint8_t>(i + 100)}));
                rtt.push_back(g.info.stamp_us - t0);
            }
            ASSERT_EQ(send(l, 1, bytes({255})), HAL_OK);  // tell B to stop
        });
        std::thread b([&, me = std::move(pb)] {
            hal_link_t *l = hub.endpoint(1);
            for (;;) {
                Got g = recv(l, HAL_TIMEOUT_FOREVER);
                ASSERT_EQ(g.st, HAL_OK);
                if (g.data[0] == 255) break;
                ASSERT_EQ(send(l, 0, bytes({static_cast<uint8_t>(g.data[0] + 100)})), HAL_OK);
            }
        });
        a.join();
        b.join();
    }
    ASSERT_EQ(rtt.size(), 5u);
    for (uint64_t r : rtt) EXPECT_EQ(r, 6000u) << "round trip = 2 x latency, exactly";
    EXPECT_EQ(clk.now_us(), 59000u) << "last ping 50 ms, pong back 56 ms, stop arrives 59 ms";
    EXPECT_EQ(clk.participants(), 0u);
}

// ---------------------------------------------------------------------------
// Link hub channel model
// ---------------------------------------------------------------------------

TEST(SimLink, LatencyAndStampByDeliveryTime)
{
    SimClock clk(1000);
    SimLinkParams p;
    p.latency_us = 2500;
    SimLinkHub hub(clk, 2, p);
    ASSERT_EQ(send(hub.endpoint(0), 1, bytes({1, 2})), HAL_OK);
    clk.advance_by(2499);
    EXPECT_EQ(recv(hub.endpoint(1)).st, HAL_E_TIMEOUT) << "delivered early";
    clk.advance_by(5000);  // firmware polls late: stamp is still the arrival time
    Got g = recv(hub.endpoint(1));
    ASSERT_EQ(g.st, HAL_OK);
    EXPECT_EQ(g.info.stamp_us, 3500u);
    EXPECT_EQ(g.info.src_id, 0u);
}

TEST(SimLink, RangeLimitFromPositions)
{
    SimClock clk;
    SimLinkParams p;
    p.range_m = 5.0;
    p.latency_us = 10;
    SimLinkHub hub(clk, 3, p);
    hub.set_position(0, 0.0, 0.0);
    hub.set_position(1, 3.0, 4.0);   // exactly 5 m: in range
    hub.set_position(2, 3.0, 4.01);  // just out
    ASSERT_EQ(send(hub.endpoint(0), HAL_LINK_BROADCAST, bytes({7})), HAL_OK);
    clk.advance_by(10);
    EXPECT_EQ(recv(hub.endpoint(1)).st, HAL_OK);
    EXPECT_EQ(recv(hub.endpoint(2)).st, HAL_E_TIMEOUT);
    EXPECT_EQ(hub.stats(0).tx_dropped_range, 1u);
    hub.set_position(2, 1.0, 1.0);  // robots move: now in range
    ASSERT_EQ(send(hub.endpoint(0), 2, bytes({8})), HAL_OK);
    clk.advance_by(10);
    EXPECT_EQ(recv(hub.endpoint(2)).st, HAL_OK);
}

TEST(SimLink, SeededLossRateAndReproducibility)
{
    auto run = [](uint64_t seed, std::vector<bool> *pattern_out) {
        SimClock clk;
        SimLinkParams p;
        p.loss_prob = 0.3;
        p.seed = seed;
        p.latency_us = 1;
        p.rx_queue_depth = 10000;
        SimLinkHub hub(clk, 2, p);
        const int n = 4000;
        for (int i = 0; i < n; ++i) {
            ASSERT_EQ(send(hub.endpoint(0), 1, bytes({static_cast<uint8_t>(i)})), HAL_OK);
            clk.advance_by(1);
            pattern_out->push_back(recv(hub.endpoint(1)).st == HAL_OK);
        }
        const SimLinkHub::Stats s = hub.stats(0);
        EXPECT_EQ(s.sent, static_cast<uint64_t>(n));
        EXPECT_EQ(s.tx_dropped_loss + hub.stats(1).rx_delivered, static_cast<uint64_t>(n)) << "every loss counted";
    };
    std::vector<bool> a, b, c;
    run(42, &a);
    run(42, &b);
    run(43, &c);
    EXPECT_EQ(a, b) << "same seed, same losses";
    EXPECT_NE(a, c) << "another seed, other losses";
    const double delivered = static_cast<double>(std::count(a.begin(), a.end(), true)) / static_cast<double>(a.size());
    // binomial sd for n = 4000, p = 0.7: 0.0072; allow 4 sd
    EXPECT_NEAR(delivered, 0.7, 0.03);
}

TEST(SimLink, LossIndependentOfThreadInterleaving)
{
    // the loss draw depends on (seed, sender, its counter, receiver) only:
    // interleaving the two senders differently gives the same per-sender outcome
    auto run = [](bool a_first) {
        SimClock clk;
        SimLinkParams p;
        p.loss_prob = 0.5;
        p.latency_us = 1;
        p.rx_queue_depth = 1000;
        SimLinkHub hub(clk, 3, p);
        for (int i = 0; i < 100; ++i) {
            const std::vector<uint8_t> ma = bytes({0, static_cast<uint8_t>(i)});
            const std::vector<uint8_t> mb = bytes({1, static_cast<uint8_t>(i)});
            if (a_first) {
                send(hub.endpoint(0), 2, ma);
                send(hub.endpoint(1), 2, mb);
            } else {
                send(hub.endpoint(1), 2, mb);
                send(hub.endpoint(0), 2, ma);
            }
        }
        clk.advance_by(1);
        std::vector<std::vector<uint8_t>> got;
        for (Got g = recv(hub.endpoint(2)); g.st == HAL_OK; g = recv(hub.endpoint(2))) got.push_back(g.data);
        return got;
    };
    auto x = run(true), y = run(false);
    EXPECT_EQ(x, y) << "same set, and same delivery order (ties broken by sender id)";
    EXPECT_GT(x.size(), 60u);
    EXPECT_LT(x.size(), 140u);
}

TEST(SimLink, JitterKeepsPerPairOrder)
{
    SimClock clk;
    SimLinkParams p;
    p.latency_us = 1000;
    p.jitter_us = 5000;
    p.rx_queue_depth = 1000;
    SimLinkHub hub(clk, 2, p);
    for (int i = 0; i < 200; ++i) {
        ASSERT_EQ(send(hub.endpoint(0), 1, bytes({static_cast<uint8_t>(i)})), HAL_OK);
        clk.advance_by(100);
    }
    clk.advance_by(10000);
    uint64_t last_stamp = 0, max_delay = 0, min_delay = UINT64_MAX;
    for (int i = 0; i < 200; ++i) {
        Got g = recv(hub.endpoint(1));
        ASSERT_EQ(g.st, HAL_OK);
        ASSERT_EQ(g.data[0], static_cast<uint8_t>(i)) << "reordered";
        EXPECT_GE(g.info.stamp_us, last_stamp);
        last_stamp = g.info.stamp_us;
        const uint64_t delay = g.info.stamp_us - static_cast<uint64_t>(i) * 100;
        max_delay = std::max(max_delay, delay);
        min_delay = std::min(min_delay, delay);
    }
    EXPECT_GE(min_delay, 1000u);
    EXPECT_GT(max_delay, 3000u) << "jitter has an effect";
}

TEST(SimLink, FullReceiveQueueDropsAndCounts)
{
    SimClock clk;
    SimLinkParams p;
    p.latency_us = 5;
    p.rx_queue_depth = 4;
    SimLinkHub hub(clk, 2, p);
    for (uint8_t i = 0; i < 10; ++i) ASSERT_EQ(send(hub.endpoint(0), 1, bytes({i})), HAL_OK);
    clk.advance_by(5);
    for (uint8_t i = 0; i < 4; ++i) {
        Got g = recv(hub.endpoint(1));
        ASSERT_EQ(g.st, HAL_OK);
        EXPECT_EQ(g.data[0], i) << "the oldest arrivals are kept";
    }
    EXPECT_EQ(recv(hub.endpoint(1)).st, HAL_E_TIMEOUT);
    EXPECT_EQ(hub.stats(1).rx_dropped_full, 6u);
}

TEST(SimLink, ClosedEndpoint)
{
    SimClock clk;
    SimLinkHub hub(clk, 2);
    hal_link_close(hub.endpoint(1));
    EXPECT_EQ(send(hub.endpoint(0), 1, bytes({1})), HAL_OK) << "unreliable: accepted and lost";
    EXPECT_EQ(hub.stats(0).tx_dropped_unknown, 1u);
    EXPECT_EQ(send(hub.endpoint(1), 0, bytes({1})), HAL_E_CLOSED);
    EXPECT_EQ(recv(hub.endpoint(1)).st, HAL_E_CLOSED);
}

TEST(SimLink, BadConstruction)
{
    SimClock clk;
    EXPECT_THROW(SimLinkHub(clk, std::vector<uint16_t>{1, 1}), std::invalid_argument);
    EXPECT_THROW(SimLinkHub(clk, std::vector<uint16_t>{HAL_LINK_BROADCAST}), std::invalid_argument);
    SimLinkParams p;
    p.loss_prob = 1.5;
    EXPECT_THROW(SimLinkHub(clk, 2, p), std::invalid_argument);
    SimLinkHub hub(clk, 2);
    EXPECT_EQ(hub.endpoint(9), nullptr);
    EXPECT_THROW(hub.set_loss_prob(std::nan("")), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Devices: capacities and fault injection
// ---------------------------------------------------------------------------

TEST(SimGpio, OverflowCountedAndReadErrorInjected)
{
    SimClock clk;
    SimGpio gpio(clk, 2, 4);
    hal_gpio_config_t c{};
    c.dir = HAL_GPIO_DIR_INPUT;
    c.edges = HAL_GPIO_EDGE_BOTH;
    ASSERT_EQ(hal_gpio_configure(gpio.handle(), 1, &c), HAL_OK);
    for (int i = 0; i < 10; ++i) gpio.set_input_level(1, i % 2 == 0);
    EXPECT_EQ(gpio.edges_dropped(), 6u);
    gpio.inject_read_error(1, true);
    bool v;
    EXPECT_EQ(hal_gpio_read(gpio.handle(), 1, &v), HAL_E_IO);
    gpio.inject_read_error(1, false);
    EXPECT_EQ(hal_gpio_read(gpio.handle(), 1, &v), HAL_OK);
    EXPECT_FALSE(gpio.output_level(1).has_value()) << "an input does not drive its pin";
    EXPECT_FALSE(gpio.set_input_level(2, true)) << "no such line";
}

TEST(SimStorage, CapacityFaultsAndCorruption)
{
    SimStorage st(100);
    std::vector<uint8_t> a(60, 1), b(50, 2);
    ASSERT_EQ(hal_storage_write(st.handle(), "a", a.data(), a.size()), HAL_OK);
    EXPECT_EQ(hal_storage_write(st.handle(), "b", b.data(), b.size()), HAL_E_OVERFLOW) << "60 + 50 > 100";
    EXPECT_EQ(hal_storage_write(st.handle(), "a", b.data(), b.size()), HAL_OK) << "replacing frees the old blob";
    EXPECT_EQ(st.used_bytes(), 50u);
    st.fail_next_writes(1);
    EXPECT_EQ(hal_storage_write(st.handle(), "a", a.data(), a.size()), HAL_E_IO);
    std::vector<uint8_t> buf(100);
    size_t len = 0;
    ASSERT_EQ(hal_storage_read(st.handle(), "a", buf.data(), buf.size(), &len), HAL_OK);
    EXPECT_EQ(std::vector<uint8_t>(buf.begin(), buf.begin() + static_cast<long>(len)), b) << "old blob intact";
    ASSERT_TRUE(st.corrupt("a"));
    EXPECT_EQ(hal_storage_read(st.handle(), "a", buf.data(), buf.size(), &len), HAL_E_CORRUPT);
    ASSERT_EQ(hal_storage_write(st.handle(), "a", a.data(), a.size()), HAL_OK) << "rewrite heals";
    EXPECT_EQ(hal_storage_read(st.handle(), "a", buf.data(), buf.size(), &len), HAL_OK);
    // CRC-32 check value of "123456789"
    const uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    EXPECT_EQ(sim_crc32(check, sizeof check), 0xCBF43926u);
}

TEST(SimCamera, StatsAndFormatValidation)
{
    SimClock clk;
    EXPECT_THROW(SimCamera(clk, 3, 2, HAL_CAMERA_PIX_YUYV), std::invalid_argument) << "odd YUYV width";
    EXPECT_THROW(SimCamera(clk, 4, 2, HAL_CAMERA_PIX_RGB24, 11), std::invalid_argument) << "stride < row";
    SimCamera cam(clk, 4, 2, HAL_CAMERA_PIX_RGB24);
    EXPECT_EQ(cam.format().frame_bytes, 24u);
    std::vector<uint8_t> f(24, 3);
    EXPECT_FALSE(cam.push_frame(f.data(), f.size(), 0)) << "not streaming";
    ASSERT_EQ(hal_camera_start(cam.handle()), HAL_OK);
    EXPECT_FALSE(cam.push_frame(f.data(), 23, 0));
    EXPECT_TRUE(cam.push_frame(f.data(), f.size(), 1));
    EXPECT_TRUE(cam.push_frame(f.data(), f.size(), 2));
    const SimCamera::Stats s = cam.stats();
    EXPECT_EQ(s.dropped_stopped, 1u);
    EXPECT_EQ(s.rejected_size, 1u);
    EXPECT_EQ(s.captured, 2u);
    EXPECT_EQ(s.dropped_unread, 1u);
}

TEST(SimSerial, ChunkingAndOverflow)
{
    SimClock clk;
    SimSerialPort port(clk, 8);
    port.set_max_chunk(3);
    const uint8_t m[10] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
    EXPECT_EQ(port.peer_write(m, sizeof m), 8u);
    EXPECT_EQ(port.rx_overflow_bytes(), 2u);
    uint8_t buf[16];
    size_t n = 0;
    ASSERT_EQ(hal_serial_read(port.handle(), buf, sizeof buf, &n, 0), HAL_OK);
    EXPECT_EQ(n, 3u);
    ASSERT_EQ(hal_serial_set_baud(port.handle(), 19200), HAL_OK);
    EXPECT_EQ(port.baud(), 19200u);
    EXPECT_EQ(hal_serial_set_baud(port.handle(), 0), HAL_E_ARG);
}

TEST(SimClock, LockstepWaitForeverWokenByOutsideEvent)
{
    // the firmware thread waits forever for an edge; the driver has nothing
    // to advance to; a simulator-side push wakes it, stamped with sim time
    SimClock clk(42);
    SimGpio gpio(clk, 1);
    hal_gpio_config_t c{};
    c.dir = HAL_GPIO_DIR_INPUT;
    c.edges = HAL_GPIO_EDGE_RISING;
    ASSERT_EQ(hal_gpio_configure(gpio.handle(), 0, &c), HAL_OK);
    hal_gpio_event_t ev{};
    hal_status_t st = HAL_E_IO;
    {
        SimLockstepDriver driver(clk, 0);
        auto me = std::make_unique<SimClock::LockstepParticipant>(clk);
        std::thread fw([&, p = std::move(me)] { st = hal_gpio_wait_edge(gpio.handle(), 0, &ev, HAL_TIMEOUT_FOREVER); });
        ASSERT_TRUE(clk.wait_quiescent(std::chrono::seconds(5)));
        std::this_thread::sleep_for(std::chrono::milliseconds(20));  // the driver idles, time stays
        EXPECT_EQ(clk.now_us(), 42u);
        clk.advance_to(1000);
        gpio.set_input_level(0, true);
        fw.join();
    }
    EXPECT_EQ(st, HAL_OK);
    EXPECT_EQ(ev.stamp_us, 1000u);
}
