// hal_can contract conformance (see hal/hal_can.h): frames arrive byte-exact
// and in order, with never-decreasing stamps; a handle never hears itself;
// invalid frames and too many filters are refused; acceptance filters
// compare the format and the masked id; a lost frame is reported once as
// HAL_E_OVERFLOW and counted; a fresh handle is error-active.
#include "conformance.hpp"

#include <cstring>

namespace {

// A frame with dlc as given, even an invalid one (dlc > 8, for the refusal
// tests); the payload fills at most the HAL_CAN_MAX_DLC bytes data[] holds.
hal_can_frame_t frame(uint32_t id, uint8_t flags, uint8_t dlc, uint8_t seed)
{
    hal_can_frame_t f;
    std::memset(&f, 0, sizeof f);
    f.id = id;
    f.flags = flags;
    f.dlc = dlc;
    if ((flags & HAL_CAN_FLAG_RTR) == 0u) {
        const uint8_t n = dlc < HAL_CAN_MAX_DLC ? dlc : static_cast<uint8_t>(HAL_CAN_MAX_DLC);
        for (uint8_t i = 0; i < n; ++i) f.data[i] = static_cast<uint8_t>(seed * 31u + i * 7u);
    }
    return f;
}

void expect_same(const hal_can_frame_t &a, const hal_can_frame_t &b)
{
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(a.flags, b.flags);
    EXPECT_EQ(a.dlc, b.dlc);
    if ((a.flags & HAL_CAN_FLAG_RTR) == 0u) {
        EXPECT_EQ(std::memcmp(a.data, b.data, a.dlc), 0);
    }
}

/// Receive with a short wait that lets time pass in simulated backends.
hal_status_t recv(conf::CanHarness *h, hal_can_frame_t *f)
{
    hal_status_t st = hal_can_receive(h->dev(), f, 0);
    for (int i = 0; i < 50 && st == HAL_E_TIMEOUT; ++i) {
        h->let_time_pass_us(1000);
        st = hal_can_receive(h->dev(), f, 0);
    }
    return st;
}

}  // namespace

TEST_P(CanConformance, SentFramesReachThePeerExactAndInOrder)
{
    const hal_can_frame_t sent[] = {frame(0x123, 0, 8, 1), frame(0x1ABCDEF0, HAL_CAN_FLAG_EXT, 3, 2),
                                    frame(0x000, 0, 0, 3), frame(0x7FF, HAL_CAN_FLAG_RTR, 4, 4)};
    for (const auto &f : sent) ASSERT_EQ(hal_can_send(h->dev(), &f, 10000), HAL_OK);
    for (const auto &f : sent) {
        hal_can_frame_t got;
        ASSERT_TRUE(h->peer_recv(&got, 100000));
        expect_same(got, f);
    }
}

TEST_P(CanConformance, ReceivedFramesInOrderWithStamps)
{
    hal_clock_t *clk = h->clock();
    const uint64_t t0 = clk ? conf::now_of(clk) : 0;
    for (uint8_t i = 0; i < 6; ++i) {
        h->peer_send(frame(0x100u + i, 0, i, i));
        h->let_time_pass_us(500);
    }
    uint64_t last = 0;
    for (uint8_t i = 0; i < 6; ++i) {
        hal_can_frame_t got;
        ASSERT_EQ(recv(h.get(), &got), HAL_OK) << "frame " << int(i);
        expect_same(got, frame(0x100u + i, 0, i, i));
        EXPECT_GE(got.stamp_us, last);
        last = got.stamp_us;
        if (clk != nullptr) {
            EXPECT_GE(got.stamp_us, t0);
            EXPECT_LE(got.stamp_us, conf::now_of(clk));
        }
    }
    hal_can_frame_t none;
    EXPECT_EQ(hal_can_receive(h->dev(), &none, 0), HAL_E_TIMEOUT);
}

TEST_P(CanConformance, AHandleNeverHearsItself)
{
    const hal_can_frame_t f = frame(0x321, 0, 2, 9);
    ASSERT_EQ(hal_can_send(h->dev(), &f, 10000), HAL_OK);
    h->let_time_pass_us(2000);
    hal_can_frame_t got;
    EXPECT_EQ(hal_can_receive(h->dev(), &got, 0), HAL_E_TIMEOUT);
    ASSERT_TRUE(h->peer_recv(&got, 100000));
}

TEST_P(CanConformance, InvalidFramesRefusedFullFilterSetAccepted)
{
    hal_can_frame_t f = frame(0x800, 0, 1, 0); // beyond 11 bits
    EXPECT_EQ(hal_can_send(h->dev(), &f, 0), HAL_E_ARG);
    f = frame(0x123, 0, 9, 0); // dlc > 8
    EXPECT_EQ(hal_can_send(h->dev(), &f, 0), HAL_E_ARG);
    f = frame(0x123, 0x80, 1, 0); // unknown flag
    EXPECT_EQ(hal_can_send(h->dev(), &f, 0), HAL_E_ARG);
    f = frame(0x20000000, HAL_CAN_FLAG_EXT, 1, 0); // beyond 29 bits
    EXPECT_EQ(hal_can_send(h->dev(), &f, 0), HAL_E_ARG);
    hal_can_frame_t got;
    EXPECT_FALSE(h->peer_recv(&got, 2000)); // nothing reached the bus
    hal_can_filter_t many[HAL_CAN_MAX_FILTERS + 1];
    std::memset(many, 0, sizeof many);
    // at least HAL_CAN_MAX_FILTERS are supported
    EXPECT_EQ(hal_can_set_filters(h->dev(), many, HAL_CAN_MAX_FILTERS), HAL_OK);
    EXPECT_EQ(hal_can_set_filters(h->dev(), nullptr, 0), HAL_OK);
}

TEST_P(CanConformance, FiltersCompareFormatAndMaskedId)
{
    const hal_can_filter_t flt[] = {{0x180, 0x7F0, 0}, {0x00012300, 0x1FFFFF00, HAL_CAN_FLAG_EXT}};
    ASSERT_EQ(hal_can_set_filters(h->dev(), flt, 2), HAL_OK);
    h->peer_send(frame(0x185, 0, 1, 1));                   // pass (std, 0x18x)
    h->peer_send(frame(0x195, 0, 1, 2));                   // fail
    h->peer_send(frame(0x185, HAL_CAN_FLAG_EXT, 1, 3));    // fail: extended, other filter's id
    h->peer_send(frame(0x000123AB, HAL_CAN_FLAG_EXT, 1, 4)); // pass (ext)
    h->peer_send(frame(0x123, 0, 1, 5));                   // fail: standard
    hal_can_frame_t got;
    ASSERT_EQ(recv(h.get(), &got), HAL_OK);
    expect_same(got, frame(0x185, 0, 1, 1));
    ASSERT_EQ(recv(h.get(), &got), HAL_OK);
    expect_same(got, frame(0x000123AB, HAL_CAN_FLAG_EXT, 1, 4));
    h->let_time_pass_us(2000);
    EXPECT_EQ(hal_can_receive(h->dev(), &got, 0), HAL_E_TIMEOUT);
    // no filter: everything again
    ASSERT_EQ(hal_can_set_filters(h->dev(), nullptr, 0), HAL_OK);
    h->peer_send(frame(0x195, 0, 1, 6));
    ASSERT_EQ(recv(h.get(), &got), HAL_OK);
    expect_same(got, frame(0x195, 0, 1, 6));
}

TEST_P(CanConformance, LossReportedOnceAndCounted)
{
    const size_t depth = h->rx_queue_depth();
    if (depth == 0) GTEST_SKIP() << "the harness cannot overflow this backend's queue";
    const size_t n = depth + 5;
    for (size_t i = 0; i < n; ++i) h->peer_send(frame(0x200u + static_cast<uint32_t>(i % 256), 0, 1, 0));
    size_t frames = 0, overflows = 0;
    hal_can_frame_t got;
    for (size_t i = 0; i < n + 5; ++i) {
        const hal_status_t st = hal_can_receive(h->dev(), &got, 0);
        if (st == HAL_OK) frames++;
        else if (st == HAL_E_OVERFLOW) overflows++;
        else break;
    }
    EXPECT_EQ(overflows, 1u);
    EXPECT_EQ(frames, depth);
    hal_can_status_t status;
    ASSERT_EQ(hal_can_get_status(h->dev(), &status), HAL_OK);
    EXPECT_EQ(status.rx_overflow_count, static_cast<uint32_t>(n - depth));
}

TEST_P(CanConformance, FreshHandleIsErrorActive)
{
    hal_can_status_t status;
    ASSERT_EQ(hal_can_get_status(h->dev(), &status), HAL_OK);
    EXPECT_EQ(status.state, HAL_CAN_STATE_ERROR_ACTIVE);
    EXPECT_EQ(status.rx_overflow_count, 0u);
    EXPECT_EQ(status.bus_off_count, 0u);
    if (!status.counters_valid) {
        EXPECT_EQ(status.tx_error_count, 0u);
        EXPECT_EQ(status.rx_error_count, 0u);
    }
}
