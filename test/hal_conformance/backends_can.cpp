// CAN backends in the hal_can conformance suite (suite_can.cpp):
//  - sim: the simulated bus (sim/devices/can CanBus) on a SimClock, the
//    device and a peer as two endpoints; its queue depth is known, so the
//    loss report is exercised;
//  - socketcan_pair: the SocketCAN backend over a socketpair carrying
//    struct can_frame datagrams (this machine has no PF_CAN; the same path
//    test/can/test_socketcan uses), stamped with CLOCK_MONOTONIC.
#include <cerrno>
#include <cstring>
#include <memory>
#include <poll.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <linux/can.h>

#include "conformance.hpp"
#include "hal/hal_clock_linux.h"
#include "hal_can_socketcan_internal.h"
#include "sim/can/can_bus.hpp"
#include "sim_hal/sim_clock.hpp"

namespace {

struct SimCanHarness : conf::CanHarness {
    static constexpr size_t kDepth = 16;
    SimCanHarness() : sim_clock(1000000), bus([this] { return sim_clock.now_us(); }, coslam::sim::CanBus::Config{kDepth})
    {
        dut = bus.attach("dut");
        peer = bus.attach("peer");
    }
    hal_can_t *dev() override { return dut; }
    hal_clock_t *clock() override { return sim_clock.handle(); }
    void let_time_pass_us(uint64_t us) override { sim_clock.advance_by(us); }
    void peer_send(const hal_can_frame_t &f) override { EXPECT_EQ(hal_can_send(peer, &f, 0), HAL_OK); }
    bool peer_recv(hal_can_frame_t *f, uint64_t) override { return hal_can_receive(peer, f, 0) == HAL_OK; }
    size_t rx_queue_depth() const override { return kDepth; }

    coslam::sim::SimClock sim_clock;
    coslam::sim::CanBus bus;
    hal_can_t *dut = nullptr;
    hal_can_t *peer = nullptr;
};

struct SocketCanPairHarness : conf::CanHarness {
    SocketCanPairHarness()
    {
        EXPECT_EQ(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
        EXPECT_EQ(hal_can_socketcan_open_fd(&sc, sv[0]), HAL_OK);
    }
    ~SocketCanPairHarness() override
    {
        hal_can_close(dev());
        close(sv[1]);
    }
    hal_can_t *dev() override { return &sc.can; }
    hal_clock_t *clock() override { return hal_clock_linux(); }
    void let_time_pass_us(uint64_t us) override
    {
        const timespec ts{static_cast<time_t>(us / 1000000u), static_cast<long>((us % 1000000u) * 1000u)};
        nanosleep(&ts, nullptr);
    }
    bool real_time() const override { return true; }
    void peer_send(const hal_can_frame_t &f) override
    {
        can_frame cf;
        std::memset(&cf, 0, sizeof cf);
        cf.can_id = f.id | ((f.flags & HAL_CAN_FLAG_EXT) ? CAN_EFF_FLAG : 0u) |
                    ((f.flags & HAL_CAN_FLAG_RTR) ? CAN_RTR_FLAG : 0u);
        cf.can_dlc = f.dlc;
        std::memcpy(cf.data, f.data, sizeof cf.data);
        EXPECT_EQ(write(sv[1], &cf, sizeof cf), static_cast<ssize_t>(sizeof cf));
    }
    bool peer_recv(hal_can_frame_t *f, uint64_t wait_us) override
    {
        pollfd p{sv[1], POLLIN, 0};
        if (poll(&p, 1, static_cast<int>((wait_us + 999u) / 1000u)) != 1) return false;
        can_frame cf;
        if (read(sv[1], &cf, sizeof cf) != static_cast<ssize_t>(sizeof cf)) return false;
        std::memset(f, 0, sizeof *f);
        f->flags = static_cast<uint8_t>(((cf.can_id & CAN_EFF_FLAG) ? HAL_CAN_FLAG_EXT : 0u) |
                                        ((cf.can_id & CAN_RTR_FLAG) ? HAL_CAN_FLAG_RTR : 0u));
        f->id = cf.can_id & ((cf.can_id & CAN_EFF_FLAG) ? CAN_EFF_MASK : CAN_SFF_MASK);
        f->dlc = cf.can_dlc;
        std::memcpy(f->data, cf.data, sizeof f->data);
        return true;
    }

    int sv[2] = {-1, -1};
    hal_can_socketcan_t sc{};
};

}  // namespace

INSTANTIATE_TEST_SUITE_P(Backends, CanConformance,
                         ::testing::Values(conf::make_backend<conf::CanHarness, SimCanHarness>("sim"),
                                           conf::make_backend<conf::CanHarness, SocketCanPairHarness>(
                                               "socketcan_pair")),
                         conf::BackendName());
