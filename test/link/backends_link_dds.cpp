// The Cyclone DDS link in the hal_link conformance suite (suite_link.cpp):
// three robots as participants of this process on a loopback-only domain
// (172), in a partition of their own per process and per harness, so that
// tests and parallel runs never hear each other.
//
// The suite's tests that send arbitrary bytes (pattern()) cannot pass on
// this backend, which carries map messages only (hal_link_dds.h: anything
// else is HAL_E_ARG). CTest runs the suite with those six excluded
// (GTEST_FILTER, test/link/CMakeLists.txt); each has a twin below, Map_*,
// that checks the same clause of the contract with codec map messages.
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "conformance.hpp"
#include "hal/hal_clock_linux.h"
#include "hal/hal_link_dds.h"
#include "link_test_util.h"

namespace {

constexpr uint32_t kDomain = 172;
constexpr size_t kRobots = 3;

struct DdsLinkHarness : conf::LinkHarness {
    DdsLinkHarness()
    {
        static int instance = 0;
        unsetenv("CYCLONEDDS_URI");
        partition = "coslam-test-conf-" + std::to_string(getpid()) + "-" + std::to_string(instance++);
        for (size_t i = 0; i < kRobots; ++i) {
            st[i] = std::make_unique<hal_link_dds_t>();
            hal_link_dds_config_t c{};
            c.domain_id = kDomain;
            c.self_id = static_cast<uint16_t>(11 + i);
            c.config = LT_DDS_LOOPBACK_XML;
            c.partition = partition.c_str();
            EXPECT_EQ(hal_link_dds_open(st[i].get(), &c), HAL_OK);
        }
        for (size_t i = 0; i < kRobots; ++i) {
            EXPECT_EQ(hal_link_dds_wait_matched(st[i].get(), kRobots - 1, 2000000), HAL_OK);
        }
    }
    ~DdsLinkHarness() override
    {
        for (auto &s : st) hal_link_close(&s->link);
    }
    size_t count() const override { return kRobots; }
    hal_link_t *dev(size_t i) override { return &st[i]->link; }
    uint64_t max_latency_us() const override { return 50000; }
    hal_clock_t *clock() override { return hal_clock_linux(); }
    bool real_time() const override { return true; }
    void let_time_pass_us(uint64_t us) override
    {
        struct timespec ts;
        ts.tv_sec = static_cast<time_t>(us / 1000000u);
        ts.tv_nsec = static_cast<long>((us % 1000000u) * 1000u);
        while (nanosleep(&ts, &ts) != 0) {
        }
    }
    std::string partition;
    std::unique_ptr<hal_link_dds_t> st[kRobots];
};

uint16_t id_of(hal_link_t *l)
{
    uint16_t id = 0;
    EXPECT_EQ(hal_link_self_id(l, &id), HAL_OK);
    return id;
}

/// A valid map message from `from` to `to` (ids as the codec's u8) with n landmarks.
std::vector<uint8_t> map_message(uint16_t from, uint16_t to, uint16_t n, uint64_t seed)
{
    std::vector<uint8_t> b(MAP_MSG_MAX_BYTES);
    const size_t len = lt_encode(b.data(), static_cast<uint8_t>(from),
                                 to == HAL_LINK_BROADCAST ? MAP_MSG_BROADCAST : static_cast<uint8_t>(to), n, seed);
    EXPECT_GT(len, 0u);
    b.resize(len);
    return b;
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

TEST_P(LinkConformance, Map_UnicastReachesOnlyDestination)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1), *c = h->dev(2);
    const auto msg = map_message(id_of(a), id_of(b), 5, 1);
    const uint64_t t_send = conf::now_of(h->clock());
    ASSERT_EQ(hal_link_send(a, id_of(b), msg.data(), msg.size(), 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    Rx r = recv_one(b, 0);
    ASSERT_EQ(r.st, HAL_OK);
    EXPECT_EQ(r.data, msg);
    EXPECT_EQ(r.info.src_id, id_of(a));
    EXPECT_GE(r.info.stamp_us, t_send);
    EXPECT_LE(r.info.stamp_us, conf::now_of(h->clock()));
    EXPECT_EQ(recv_one(c, 0).st, HAL_E_TIMEOUT) << "a unicast leaked to a third robot";
    EXPECT_EQ(recv_one(a, 0).st, HAL_E_TIMEOUT) << "the sender received its own datagram";
    EXPECT_EQ(recv_one(b, 0).st, HAL_E_TIMEOUT) << "delivered twice";
}

TEST_P(LinkConformance, Map_BroadcastReachesAllOthers)
{
    hal_link_t *src = h->dev(1);
    const auto msg = map_message(id_of(src), HAL_LINK_BROADCAST, 3, 2);
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

TEST_P(LinkConformance, Map_DatagramBoundariesPreserved)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1);
    std::multiset<std::vector<uint8_t>> sent;
    for (uint16_t n : {uint16_t{0}, uint16_t{1}, uint16_t{13}, uint16_t{LT_MAX_LANDMARKS}}) {
        auto m = map_message(id_of(a), id_of(b), n, n);
        // with a trailer too: the backend carries up to HAL_LINK_DDS_TRAILER_MAX opaque bytes
        for (uint8_t k = 0; k < n % 7; ++k) m.push_back(static_cast<uint8_t>(0xA0 + k));
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
    EXPECT_EQ(got, sent) << "datagrams split, merged or altered";
    EXPECT_EQ(recv_one(b, 0).st, HAL_E_TIMEOUT);
}

TEST_P(LinkConformance, Map_UnknownDestinationAcceptedAndLost)
{
    std::set<uint16_t> ids;
    for (size_t i = 0; i < h->count(); ++i) ids.insert(id_of(h->dev(i)));
    uint16_t unknown = 0;
    while (ids.count(unknown) != 0) ++unknown;
    const auto m = map_message(id_of(h->dev(0)), unknown, 1, 3);
    EXPECT_EQ(hal_link_send(h->dev(0), unknown, m.data(), m.size(), 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    for (size_t i = 0; i < h->count(); ++i) EXPECT_EQ(recv_one(h->dev(i), 0).st, HAL_E_TIMEOUT);
}

TEST_P(LinkConformance, Map_RecvWaitsForArrival)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1);
    const auto m = map_message(id_of(a), id_of(b), 2, 4);
    ASSERT_EQ(hal_link_send(a, id_of(b), m.data(), m.size(), 0), HAL_OK);
    Rx r = recv_one(b, static_cast<uint32_t>(h->max_latency_us() + 100000));
    ASSERT_EQ(r.st, HAL_OK);
    EXPECT_EQ(r.data, m);
}

TEST_P(LinkConformance, Map_ShortBufferTruncatesAndDiscards)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1);
    const auto m = map_message(id_of(a), id_of(b), 4, 5), next = map_message(id_of(a), id_of(b), 0, 6);
    ASSERT_EQ(hal_link_send(a, id_of(b), m.data(), m.size(), 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    ASSERT_EQ(hal_link_send(a, id_of(b), next.data(), next.size(), 0), HAL_OK);
    h->let_time_pass_us(h->max_latency_us());
    Rx r = recv_one(b, 0, 10);
    EXPECT_EQ(r.st, HAL_E_OVERFLOW);
    EXPECT_EQ(r.info.len, m.size()) << "full length reported";
    EXPECT_EQ(r.info.src_id, id_of(a));
    EXPECT_EQ(r.data, std::vector<uint8_t>(m.begin(), m.begin() + 10)) << "first cap bytes copied";
    Rx r2 = recv_one(b, 0);
    ASSERT_EQ(r2.st, HAL_OK);
    EXPECT_EQ(r2.data, next) << "the truncated datagram must be discarded, not re-delivered";
}

// This backend's own rule: bytes that are not one codec message are refused.
TEST_P(LinkConformance, Map_NonMapDatagramsRefused)
{
    hal_link_t *a = h->dev(0), *b = h->dev(1);
    const auto junk = conf::pattern(300, 9);
    EXPECT_EQ(hal_link_send(a, id_of(b), junk.data(), junk.size(), 0), HAL_E_ARG);
    h->let_time_pass_us(h->max_latency_us());
    EXPECT_EQ(recv_one(b, 0).st, HAL_E_TIMEOUT);
}

INSTANTIATE_TEST_SUITE_P(Dds, LinkConformance,
                         ::testing::Values(conf::make_backend<conf::LinkHarness, DdsLinkHarness>("cyclonedds")),
                         conf::BackendName());
