// hal_link contract conformance (see hal/hal_link.h), on a perfect channel:
// loss, range and latency models are backend tests, not contract tests.
#include <algorithm>
#include <set>

#include "conformance.hpp"

using conf::now_of;
using conf::pattern;

namespace {

uint16_t id_of(hal_link_t *l)
{
    uint16_t id = 0;
    EXPECT_EQ(hal_link_self_id(l, &id), HAL_OK);
    return id;
}

struct Rx {
    hal_status_t st;
    hal_link_rx_info_t info;
    std::vector<uint8_t> data;
};

Rx recv_one(hal_link_t *l, uint32_t timeout_us, size_t cap = HAL_LINK_MAX_PAYLOAD)
{
    Rx r{};
    r.data.resize(cap);
    r.st = hal_link_recv(l, r.data.data(), cap, &r.info, timeout_us);
    r.data.resize(r.st == HAL_OK ? r.info.len : std::min(cap, r.info.len));
    return r;
}

}  // namespace

TEST_P(LinkConformance, SelfIdsDistinct)
{
    ASSERT_GE(h->count(), 3u);
    std::set<uint16_t> ids;
    for (size_t i = 0; i < h->count(); ++i) {
        const uint16_t id = id_of(h->dev(i));
        EXPECT_NE(id, HAL_LINK_BROADCAST);
        ids.insert(id);
    }
    EXPECT_EQ(ids.size(), h->count());
}

TEST_P(LinkConformance, UnicastReachesOnlyDestination)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1), *c = h->dev(2);
    const auto msg = pattern(123, 1);
    hal_clock_t *clk = h->clock();
    const uint64_t t_send = clk ? now_of(clk) : 0;
    ASSERT_EQ(hal_link_send(a, id_of(b), msg.data(), msg.size(), 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    Rx r = recv_one(b, 0);
    ASSERT_EQ(r.st, HAL_OK);
    EXPECT_EQ(r.data, msg);
    EXPECT_EQ(r.info.len, msg.size());
    EXPECT_EQ(r.info.src_id, id_of(a));
    if (clk != nullptr) {
        EXPECT_GE(r.info.stamp_us, t_send);
        EXPECT_LE(r.info.stamp_us, now_of(clk));
    }
    EXPECT_EQ(recv_one(c, 0).st, HAL_E_TIMEOUT) << "a unicast leaked to a third robot";
    EXPECT_EQ(recv_one(a, 0).st, HAL_E_TIMEOUT) << "the sender received its own datagram";
    EXPECT_EQ(recv_one(b, 0).st, HAL_E_TIMEOUT) << "delivered twice";
}

TEST_P(LinkConformance, BroadcastReachesAllOthers)
{
    const auto msg = pattern(40, 2);
    hal_link_t *src = h->dev(1);
    ASSERT_EQ(hal_link_send(src, HAL_LINK_BROADCAST, msg.data(), msg.size(), 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    for (size_t i = 0; i < h->count(); ++i) {
        Rx r = recv_one(h->dev(i), 0);
        if (h->dev(i) == src) {
            EXPECT_EQ(r.st, HAL_E_TIMEOUT) << "broadcast looped back to its sender";
        } else {
            ASSERT_EQ(r.st, HAL_OK) << "endpoint " << i;
            EXPECT_EQ(r.data, msg);
            EXPECT_EQ(r.info.src_id, id_of(src));
        }
    }
}

TEST_P(LinkConformance, DatagramBoundariesPreserved)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1);
    std::multiset<std::vector<uint8_t>> sent;
    for (size_t n : {size_t{1}, size_t{100}, size_t{1000}, size_t{HAL_LINK_MAX_PAYLOAD}}) {
        const auto m = pattern(n, static_cast<uint32_t>(n));
        ASSERT_EQ(hal_link_send(a, id_of(b), m.data(), m.size(), 0), HAL_OK);
        sent.insert(m);
    }
    h->let_time_pass_us(h->max_latency_us());
    std::multiset<std::vector<uint8_t>> got;
    for (size_t i = 0; i < sent.size(); ++i) {
        Rx r = recv_one(b, 0);
        ASSERT_EQ(r.st, HAL_OK) << "datagram " << i;
        got.insert(r.data);
    }
    EXPECT_EQ(got, sent) << "datagrams split, merged or altered (order is not part of the contract)";
    EXPECT_EQ(recv_one(b, 0).st, HAL_E_TIMEOUT);
}

TEST_P(LinkConformance, SendArgumentsChecked)
{
    hal_link_t *a = h->dev(0);
    std::vector<uint8_t> big(HAL_LINK_MAX_PAYLOAD + 1, 0x55);
    const uint16_t b = id_of(h->dev(1));
    EXPECT_EQ(hal_link_send(a, b, big.data(), big.size(), 0), HAL_E_ARG);
    EXPECT_EQ(hal_link_send(a, b, big.data(), 0, 0), HAL_E_ARG);
    EXPECT_EQ(hal_link_send(a, b, nullptr, 5, 0), HAL_E_ARG);
    EXPECT_EQ(hal_link_send(a, id_of(a), big.data(), 5, 0), HAL_E_ARG) << "send to self";
    hal_link_rx_info_t info;
    uint8_t buf[4];
    EXPECT_EQ(hal_link_recv(a, nullptr, 4, &info, 0), HAL_E_ARG);
    EXPECT_EQ(hal_link_recv(a, buf, 0, &info, 0), HAL_E_ARG);
    EXPECT_EQ(hal_link_recv(a, buf, 4, nullptr, 0), HAL_E_ARG);
    uint16_t id;
    EXPECT_EQ(hal_link_self_id(nullptr, &id), HAL_E_ARG);
    EXPECT_EQ(hal_link_self_id(a, nullptr), HAL_E_ARG);
}

TEST_P(LinkConformance, UnknownDestinationAcceptedAndLost)
{
    std::set<uint16_t> ids;
    for (size_t i = 0; i < h->count(); ++i) ids.insert(id_of(h->dev(i)));
    uint16_t unknown = 0;
    while (ids.count(unknown) != 0) ++unknown;
    const uint8_t m[3] = {1, 2, 3};
    EXPECT_EQ(hal_link_send(h->dev(0), unknown, m, sizeof m, 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    for (size_t i = 0; i < h->count(); ++i) EXPECT_EQ(recv_one(h->dev(i), 0).st, HAL_E_TIMEOUT);
}

TEST_P(LinkConformance, RecvTimesOut)
{
    hal_clock_t *clk = h->clock();
    const uint64_t t0 = clk ? now_of(clk) : 0;
    EXPECT_EQ(recv_one(h->dev(0), 0).st, HAL_E_TIMEOUT);
    Rx r = recv_one(h->dev(0), 3000);
    EXPECT_EQ(r.st, HAL_E_TIMEOUT);
    EXPECT_EQ(r.info.len, 0u);
    if (clk != nullptr) {
        EXPECT_GE(now_of(clk) - t0, 3000u) << "returned before the timeout";
    }
}

TEST_P(LinkConformance, RecvWaitsForArrival)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1);
    const auto m = pattern(10, 3);
    ASSERT_EQ(hal_link_send(a, id_of(b), m.data(), m.size(), 0), HAL_OK);
    // a blocking receive (no explicit time passing) must see it
    Rx r = recv_one(b, static_cast<uint32_t>(h->max_latency_us() + 100000));
    ASSERT_EQ(r.st, HAL_OK);
    EXPECT_EQ(r.data, m);
}

TEST_P(LinkConformance, ShortBufferTruncatesAndDiscards)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1);
    const auto m = pattern(100, 4), next = pattern(5, 5);
    ASSERT_EQ(hal_link_send(a, id_of(b), m.data(), m.size(), 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    ASSERT_EQ(hal_link_send(a, id_of(b), next.data(), next.size(), 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    Rx r = recv_one(b, 0, 10);
    EXPECT_EQ(r.st, HAL_E_OVERFLOW);
    EXPECT_EQ(r.info.len, 100u) << "full length reported";
    EXPECT_EQ(r.info.src_id, id_of(a));
    EXPECT_EQ(r.data, std::vector<uint8_t>(m.begin(), m.begin() + 10)) << "first cap bytes copied";
    Rx r2 = recv_one(b, 0);
    ASSERT_EQ(r2.st, HAL_OK);
    EXPECT_EQ(r2.data, next) << "the truncated datagram must be discarded, not re-delivered";
}
