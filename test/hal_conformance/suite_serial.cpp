// hal_serial contract conformance (see hal/hal_serial.h).
#include "conformance.hpp"

using conf::now_of;
using conf::pattern;

namespace {

/// Read until n bytes arrived (a stream may split them) or a read fails.
std::vector<uint8_t> read_n(hal_serial_t *s, size_t n, uint32_t timeout_us, size_t cap = 64)
{
    std::vector<uint8_t> out;
    std::vector<uint8_t> buf(cap);
    while (out.size() < n) {
        size_t got = 0;
        const hal_status_t st = hal_serial_read(s, buf.data(), buf.size(), &got, timeout_us);
        if (st != HAL_OK) break;
        EXPECT_GT(got, 0u) << "HAL_OK with no byte";
        EXPECT_LE(got, cap);
        out.insert(out.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(got));
    }
    return out;
}

}  // namespace

TEST_P(SerialConformance, WriteReachesPeerByteExact)
{
    std::vector<uint8_t> all(512);
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<uint8_t>(i);
    ASSERT_EQ(hal_serial_write(h->dev(), all.data(), all.size(), 100000), HAL_OK);
    std::vector<uint8_t> got(all.size());
    size_t n = 0;
    while (n < got.size()) {
        const size_t k = h->peer_recv(got.data() + n, got.size() - n, 200000);
        if (k == 0) break;
        n += k;
    }
    ASSERT_EQ(n, all.size());
    EXPECT_EQ(got, all);
}

TEST_P(SerialConformance, ReadReassemblesStream)
{
    const auto m = pattern(1000, 1);
    h->peer_send(m.data(), m.size());
    EXPECT_EQ(read_n(h->dev(), m.size(), 200000, 37), m);
}

TEST_P(SerialConformance, ReadTimesOutWithNothing)
{
    uint8_t buf[8];
    size_t n = 99;
    EXPECT_EQ(hal_serial_read(h->dev(), buf, sizeof buf, &n, 0), HAL_E_TIMEOUT);
    EXPECT_EQ(n, 0u);
    hal_clock_t *clk = h->clock();
    const uint64_t t0 = clk ? now_of(clk) : 0;
    EXPECT_EQ(hal_serial_read(h->dev(), buf, sizeof buf, &n, 2000), HAL_E_TIMEOUT);
    if (clk != nullptr) {
        EXPECT_GE(now_of(clk) - t0, 2000u);
    }
}

TEST_P(SerialConformance, ReadNeverExceedsCap)
{
    const auto m = pattern(100, 2);
    h->peer_send(m.data(), m.size());
    h->let_time_pass_us(1000);
    uint8_t buf[10];
    size_t n = 0;
    ASSERT_EQ(hal_serial_read(h->dev(), buf, sizeof buf, &n, 100000), HAL_OK);
    EXPECT_GE(n, 1u);
    EXPECT_LE(n, sizeof buf);
    EXPECT_TRUE(std::equal(buf, buf + n, m.begin()));
}

TEST_P(SerialConformance, FlushInputDropsPending)
{
    const auto old = pattern(50, 3);
    h->peer_send(old.data(), old.size());
    h->let_time_pass_us(1000);
    ASSERT_EQ(hal_serial_flush_input(h->dev()), HAL_OK);
    const auto fresh = pattern(20, 4);
    h->peer_send(fresh.data(), fresh.size());
    EXPECT_EQ(read_n(h->dev(), fresh.size(), 200000), fresh);
}

TEST_P(SerialConformance, CommonBaudAccepted)
{
    EXPECT_EQ(hal_serial_set_baud(h->dev(), 115200), HAL_OK);
}

TEST_P(SerialConformance, ArgumentsChecked)
{
    uint8_t b;
    size_t n;
    EXPECT_EQ(hal_serial_read(h->dev(), nullptr, 1, &n, 0), HAL_E_ARG);
    EXPECT_EQ(hal_serial_read(h->dev(), &b, 0, &n, 0), HAL_E_ARG);
    EXPECT_EQ(hal_serial_read(h->dev(), &b, 1, nullptr, 0), HAL_E_ARG);
    EXPECT_EQ(hal_serial_write(h->dev(), nullptr, 1, 0), HAL_E_ARG);
}
