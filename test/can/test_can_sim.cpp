// Simulated CAN bus and CiA 402 drive emulators, then the firmware driver
// end to end: three emulated drives on the bus, the cia402_omni driver on
// the robot endpoint, body-velocity commands, odometry against the ground
// truth, and fault injection (EMCY, heartbeat loss, reboot).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

extern "C" {
#include "cia402/cia402_omni.h"
#include "coslam/motion.h"
#include "coslam/pose2.h"
#include "coslam/rng.h"
}
#include "sim/can/can_bus.hpp"
#include "sim/can/cia402_drive_emu.hpp"
#include "sim/can/omni_can_rig.hpp"

using coslam::sim::CanBus;
using coslam::sim::Cia402DriveEmu;
using coslam::sim::Cia402DriveEmuConfig;
using coslam::sim::OmniCanRig;
using coslam::sim::OmniCanRigConfig;

namespace {

constexpr double kPi = 3.14159265358979323846;

hal_can_frame_t make(uint32_t id, std::initializer_list<uint8_t> bytes, uint8_t flags = 0)
{
    hal_can_frame_t f{};
    f.id = id;
    f.flags = flags;
    f.dlc = static_cast<uint8_t>(bytes.size());
    std::size_t i = 0;
    for (uint8_t b : bytes) f.data[i++] = b;
    return f;
}

std::vector<hal_can_frame_t> drain(hal_can_t *ep)
{
    std::vector<hal_can_frame_t> out;
    hal_can_frame_t f;
    while (hal_can_receive(ep, &f, 0) == HAL_OK) out.push_back(f);
    return out;
}

void expect_bytes(const hal_can_frame_t &f, uint32_t id, std::initializer_list<uint8_t> bytes)
{
    EXPECT_EQ(f.id, id);
    ASSERT_EQ(f.dlc, bytes.size()) << "frame 0x" << std::hex << f.id;
    std::size_t i = 0;
    for (uint8_t b : bytes) {
        EXPECT_EQ(f.data[i], b) << "byte " << i << " of frame 0x" << std::hex << f.id;
        ++i;
    }
}

} // namespace

// ---------------------------------------------------------------------------
// the bus
// ---------------------------------------------------------------------------

TEST(CanBus, DeliversInOrderToOthersWithStamps)
{
    uint64_t now = 1000;
    CanBus bus([&] { return now; });
    hal_can_t *a = bus.attach("a");
    hal_can_t *b = bus.attach("b");
    hal_can_t *c = bus.attach("c");
    EXPECT_EQ(bus.endpoint_count(), 3u);
    hal_can_frame_t f1 = make(0x123, {1, 2, 3});
    ASSERT_EQ(hal_can_send(a, &f1, 0), HAL_OK);
    now = 1500;
    hal_can_frame_t f2 = make(0x1ABCDEF, {9}, HAL_CAN_FLAG_EXT);
    ASSERT_EQ(hal_can_send(b, &f2, 0), HAL_OK);
    const auto at_a = drain(a);
    const auto at_b = drain(b);
    const auto at_c = drain(c);
    ASSERT_EQ(at_a.size(), 1u); // not its own frame
    ASSERT_EQ(at_b.size(), 1u);
    ASSERT_EQ(at_c.size(), 2u);
    EXPECT_EQ(at_c[0].id, 0x123u);
    EXPECT_EQ(at_c[0].stamp_us, 1000u);
    EXPECT_EQ(at_c[0].data[2], 3);
    EXPECT_EQ(at_c[1].id, 0x1ABCDEFu);
    EXPECT_EQ(at_c[1].flags, HAL_CAN_FLAG_EXT);
    EXPECT_EQ(at_c[1].stamp_us, 1500u);
    EXPECT_EQ(at_a[0].id, 0x1ABCDEFu);
    EXPECT_EQ(at_b[0].id, 0x123u);
    EXPECT_EQ(bus.frames_on_bus(), 2u);
    hal_can_frame_t g;
    EXPECT_EQ(hal_can_receive(c, &g, 0), HAL_E_TIMEOUT);
    EXPECT_EQ(hal_can_receive(c, &g, 5000), HAL_E_TIMEOUT); // no hook: time does not pass here
    f1.dlc = 9;
    EXPECT_EQ(hal_can_send(a, &f1, 0), HAL_E_ARG);
}

TEST(CanBus, FiltersOverflowCloseBusOff)
{
    uint64_t now = 0;
    CanBus bus([&] { return now; }, CanBus::Config{4});
    hal_can_t *tx = bus.attach("tx");
    hal_can_t *rx = bus.attach("rx");
    hal_can_t *all = bus.attach("all");
    const hal_can_filter_t flt = {0x180, 0x780, 0};
    ASSERT_EQ(hal_can_set_filters(rx, &flt, 1), HAL_OK);
    for (uint32_t id : {0x181u, 0x281u, 0x182u, 0x183u, 0x184u, 0x185u, 0x186u}) {
        hal_can_frame_t f = make(id, {});
        ASSERT_EQ(hal_can_send(tx, &f, 0), HAL_OK);
    }
    // rx accepted 6 TPDO ids, kept 4: one overflow report, then the 4 oldest
    hal_can_frame_t f;
    EXPECT_EQ(hal_can_receive(rx, &f, 0), HAL_E_OVERFLOW);
    std::vector<uint32_t> ids;
    while (hal_can_receive(rx, &f, 0) == HAL_OK) ids.push_back(f.id);
    EXPECT_EQ(ids, (std::vector<uint32_t>{0x181, 0x182, 0x183, 0x184}));
    hal_can_status_t st;
    ASSERT_EQ(hal_can_get_status(rx, &st), HAL_OK);
    EXPECT_EQ(st.rx_overflow_count, 2u);
    ASSERT_EQ(hal_can_get_status(all, &st), HAL_OK);
    EXPECT_EQ(st.rx_overflow_count, 3u);
    // too many filters
    std::vector<hal_can_filter_t> many(HAL_CAN_MAX_FILTERS + 1, flt);
    EXPECT_EQ(hal_can_set_filters(rx, many.data(), many.size()), HAL_E_ARG);
    // bus-off: sends fail, status says so; recovery
    bus.set_bus_off(tx, true);
    hal_can_frame_t g = make(0x181, {});
    EXPECT_EQ(hal_can_send(tx, &g, 0), HAL_E_IO);
    ASSERT_EQ(hal_can_get_status(tx, &st), HAL_OK);
    EXPECT_EQ(st.state, HAL_CAN_STATE_BUS_OFF);
    EXPECT_EQ(st.bus_off_count, 1u);
    bus.set_bus_off(tx, false);
    EXPECT_EQ(hal_can_send(tx, &g, 0), HAL_OK);
    // a closed endpoint neither sends nor receives
    hal_can_close(rx);
    EXPECT_EQ(hal_can_send(rx, &g, 0), HAL_E_CLOSED);
    EXPECT_EQ(hal_can_receive(rx, &f, 0), HAL_E_CLOSED);
    EXPECT_EQ(hal_can_send(tx, &g, 0), HAL_OK);
}

TEST(CanBus, WaitHookLetsTimeAndDevicesAdvance)
{
    uint64_t now = 0;
    CanBus bus([&] { return now; });
    hal_can_t *a = bus.attach("a");
    hal_can_t *b = bus.attach("b");
    uint32_t asked = 0;
    bus.set_wait_hook([&](uint32_t timeout_us) {
        asked = timeout_us;
        now += 300;
        hal_can_frame_t f = make(0x55, {0xAA});
        hal_can_send(b, &f, 0);
    });
    hal_can_frame_t f;
    ASSERT_EQ(hal_can_receive(a, &f, 1000), HAL_OK);
    EXPECT_EQ(asked, 1000u);
    EXPECT_EQ(f.id, 0x55u);
    EXPECT_EQ(f.stamp_us, 300u);
    std::vector<std::size_t> seen;
    bus.set_monitor([&](std::size_t from, const hal_can_frame_t &) { seen.push_back(from); });
    hal_can_frame_t g = make(0x1, {});
    hal_can_send(a, &g, 0);
    hal_can_send(b, &g, 0);
    EXPECT_EQ(seen, (std::vector<std::size_t>{0, 1}));
}

// ---------------------------------------------------------------------------
// one emulated drive, driven with hand-made frames
// ---------------------------------------------------------------------------

class DriveEmu : public ::testing::Test {
protected:
    uint64_t now = 0;
    CanBus bus{[this] { return now; }};
    hal_can_t *master = bus.attach("master");
    Cia402DriveEmuConfig cfg = [] {
        Cia402DriveEmuConfig c;
        c.node_id = 4;
        c.vendor_id = 0x11223344;
        return c;
    }();
    Cia402DriveEmu drive{bus.attach("drive"), cfg};

    void tick(int ms = 1)
    {
        for (int i = 0; i < ms; ++i) {
            drive.step(now);
            now += 1000;
        }
    }
    std::vector<hal_can_frame_t> exchange(const hal_can_frame_t &f, int ms = 1)
    {
        hal_can_send(master, &f, 0);
        tick(ms);
        return drain(master);
    }
    void boot()
    {
        tick(5);
        auto got = drain(master);
        ASSERT_EQ(got.size(), 1u);
        expect_bytes(got[0], 0x704, {0x00});
        EXPECT_EQ(got[0].stamp_us, 2000u); // boot_delay_us after power-on
    }
};

TEST_F(DriveEmu, BootsAndServesSdo)
{
    boot();
    EXPECT_EQ(drive.nmt(), Cia402DriveEmu::Nmt::PreOperational);
    auto r = exchange(make(0x604, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}));
    ASSERT_EQ(r.size(), 1u);
    expect_bytes(r[0], 0x584, {0x43, 0x18, 0x10, 0x01, 0x44, 0x33, 0x22, 0x11});
    r = exchange(make(0x604, {0x40, 0x18, 0x10, 0x00, 0, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x4F, 0x18, 0x10, 0x00, 0x04, 0, 0, 0});
    r = exchange(make(0x604, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00});
    // heartbeat producer: 20 ms
    r = exchange(make(0x604, {0x2B, 0x17, 0x10, 0x00, 20, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0});
    tick(100);
    const auto hbs = drain(master);
    ASSERT_EQ(hbs.size(), 5u);
    for (const auto &h : hbs) expect_bytes(h, 0x704, {0x7F});
    EXPECT_EQ(hbs[1].stamp_us - hbs[0].stamp_us, 20000u);
    // mode: 3 accepted, 2 refused
    r = exchange(make(0x604, {0x2F, 0x60, 0x60, 0x00, 0x02, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06});
    r = exchange(make(0x604, {0x2F, 0x60, 0x60, 0x00, 0x03, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0});
    r = exchange(make(0x604, {0x40, 0x61, 0x60, 0x00, 0, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x4F, 0x61, 0x60, 0x00, 0x03, 0, 0, 0});
    // the abort codes
    r = exchange(make(0x604, {0x40, 0x34, 0x12, 0x00, 0, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x80, 0x34, 0x12, 0x00, 0x00, 0x00, 0x02, 0x06}); // no object
    r = exchange(make(0x604, {0x40, 0x18, 0x10, 0x05, 0, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x80, 0x18, 0x10, 0x05, 0x11, 0x00, 0x09, 0x06}); // no sub-index
    r = exchange(make(0x604, {0x2B, 0x41, 0x60, 0x00, 0x01, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x80, 0x41, 0x60, 0x00, 0x02, 0x00, 0x01, 0x06}); // read only
    r = exchange(make(0x604, {0x2B, 0x60, 0x60, 0x00, 0x03, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x80, 0x60, 0x60, 0x00, 0x10, 0x00, 0x07, 0x06}); // length
    r = exchange(make(0x604, {0x21, 0x60, 0x60, 0x00, 0x01, 0, 0, 0}));
    expect_bytes(r[0], 0x584, {0x80, 0x60, 0x60, 0x00, 0x01, 0x00, 0x04, 0x05}); // segmented
    // another node's SDO is not answered
    r = exchange(make(0x605, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}));
    EXPECT_TRUE(r.empty());
}

TEST_F(DriveEmu, StateMachineMotorAndFaults)
{
    boot();
    exchange(make(0x604, {0x2F, 0x60, 0x60, 0x00, 0x03, 0, 0, 0}));
    // RPDOs are ignored before NMT start
    exchange(make(0x204, {0x06, 0, 0, 0, 0, 0}));
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::SwitchOnDisabled);
    auto r = exchange(make(0x000, {0x01, 0x04}));
    ASSERT_EQ(r.size(), 1u); // first TPDO right away
    expect_bytes(r[0], 0x184, {0x40, 0x12, 0, 0, 0, 0});
    r = exchange(make(0x204, {0x06, 0, 0, 0, 0, 0}));
    ASSERT_FALSE(r.empty());
    expect_bytes(r[0], 0x184, {0x31, 0x12, 0, 0, 0, 0});
    r = exchange(make(0x204, {0x07, 0, 0, 0, 0, 0}));
    expect_bytes(r[0], 0x184, {0x33, 0x12, 0, 0, 0, 0});
    // enable with target 1000.0 rpm (10000 units of 0.1 rpm)
    r = exchange(make(0x204, {0x0F, 0x00, 0x10, 0x27, 0, 0}));
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::OperationEnabled);
    ASSERT_FALSE(r.empty());
    EXPECT_EQ(r[0].data[0], 0x37);
    // first-order response: 1000 (1 - exp(-t / 50 ms)); t counted from the step that saw the RPDO
    const uint64_t t_enable = now - 1000;
    while (now - t_enable <= 50000) tick();
    const double t_s = static_cast<double>(now - 1000 - t_enable) * 1e-6;
    EXPECT_NEAR(drive.motor_rpm(), 1000.0 * (1.0 - std::exp(-t_s / 0.05)), 1e-6);
    tick(500);
    EXPECT_NEAR(drive.motor_rpm(), 1000.0, 0.1);
    EXPECT_NEAR(drive.true_wheel_speed_radps(), 1000.0 / 16.0 * 2.0 * kPi / 60.0, 1e-3);
    // the periodic TPDO reports velocity actual in 0.1 rpm and "target reached"
    auto tp = drain(master);
    ASSERT_FALSE(tp.empty());
    const hal_can_frame_t &last = tp.back();
    EXPECT_EQ(last.id, 0x184u);
    EXPECT_EQ(last.data[0] & 0x6F, 0x27);
    EXPECT_NE(last.data[1] & 0x04, 0); // bit 10
    int32_t v;
    std::memcpy(&v, &last.data[2], 4); // little-endian host
    EXPECT_NEAR(v, 10000, 1);
    // targets beyond max_motor_rpm are clamped
    exchange(make(0x204, {0x0F, 0x00, 0x40, 0x42, 0x0F, 0x00})); // 1e6 units = 100000 rpm
    tick(1000);
    EXPECT_NEAR(drive.motor_rpm(), 3000.0, 0.1);
    drain(master);
    // a fault: EMCY, reaction (braking), FAULT
    drive.raise_fault(0x2310, 0x03);
    r = drain(master);
    ASSERT_EQ(r.size(), 1u);
    expect_bytes(r[0], 0x084, {0x10, 0x23, 0x03, 0, 0, 0, 0, 0});
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::FaultReactionActive);
    tick(500);
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::Fault);
    EXPECT_LT(std::fabs(drive.motor_rpm()), 1.0);
    // enable does nothing in FAULT; the reset needs a rising edge of bit 7
    exchange(make(0x204, {0x0F, 0, 0, 0, 0, 0}));
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::Fault);
    exchange(make(0x204, {0x80, 0, 0, 0, 0, 0}));
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::SwitchOnDisabled);
    // quick stop from enabled ends in SWITCH_ON_DISABLED once stopped
    exchange(make(0x204, {0x06, 0, 0, 0, 0, 0}));
    exchange(make(0x204, {0x0F, 0x00, 0x10, 0x27, 0, 0}));
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::OperationEnabled);
    tick(300);
    exchange(make(0x204, {0x02, 0, 0, 0, 0, 0}));
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::QuickStopActive);
    tick(300);
    EXPECT_EQ(drive.state(), Cia402DriveEmu::State::SwitchOnDisabled);
    EXPECT_LT(std::fabs(drive.motor_rpm()), 1.0);
    // silent: nothing on the bus any more
    drain(master);
    drive.set_silent(true);
    tick(100);
    EXPECT_TRUE(drain(master).empty());
}

TEST(DriveEmuSlip, SeededAndZeroMean)
{
    auto run = [](uint64_t seed) {
        uint64_t now = 0;
        CanBus bus([&] { return now; });
        hal_can_t *m = bus.attach("m");
        Cia402DriveEmuConfig c;
        c.slip_sigma = 0.05;
        c.seed = seed;
        Cia402DriveEmu d(bus.attach("d"), c);
        auto send = [&](std::initializer_list<uint8_t> b, uint32_t id) {
            hal_can_frame_t f = make(id, b);
            hal_can_send(m, &f, 0);
            d.step(now);
            now += 1000;
        };
        for (int i = 0; i < 5; ++i) send({}, 0x7FF); // boot
        send({0x2F, 0x60, 0x60, 0x00, 0x03, 0, 0, 0}, 0x601);
        send({0x01, 0x01}, 0x000);
        send({0x06, 0, 0, 0, 0, 0}, 0x201);
        send({0x07, 0, 0, 0, 0, 0}, 0x201);
        send({0x0F, 0, 0x10, 0x27, 0, 0}, 0x201);
        std::vector<double> ratio;
        for (int i = 0; i < 2000; ++i) {
            d.step(now);
            now += 1000;
            if (i > 500) ratio.push_back(d.true_motor_rpm() / d.motor_rpm() - 1.0);
        }
        return ratio;
    };
    const auto a = run(7);
    const auto b = run(7);
    const auto c = run(8);
    ASSERT_EQ(a, b); // same seed, same noise
    EXPECT_NE(a, c);
    double mean = 0.0, var = 0.0;
    for (double x : a) mean += x;
    mean /= static_cast<double>(a.size());
    for (double x : a) var += (x - mean) * (x - mean);
    var /= static_cast<double>(a.size() - 1);
    EXPECT_NEAR(mean, 0.0, 0.01);
    EXPECT_NEAR(std::sqrt(var), 0.05, 0.005);
}

TEST(DriveEmuRobust, RandomFramesNeverBreakIt)
{
    // random traffic on the drive's COB-IDs: it must keep answering with
    // well-formed frames only (the _san build checks memory and UB)
    uint64_t now = 0;
    CanBus bus([&] { return now; });
    hal_can_t *m = bus.attach("m");
    Cia402DriveEmuConfig c;
    c.heartbeat_period_ms = 10;
    Cia402DriveEmu d(bus.attach("d"), c);
    rng_t rng;
    rng_seed(&rng, 301);
    const int n = COSLAM_TEST_FULL ? 1000000 : 20000;
    const uint32_t ids[5] = {0x000, 0x201, 0x601, 0x181, 0x7FF};
    bool seen[8] = {};
    for (int i = 0; i < n; ++i) {
        hal_can_frame_t f{};
        f.id = ids[rng_below(&rng, 5)];
        f.dlc = static_cast<uint8_t>(rng_below(&rng, 9));
        for (auto &b : f.data) b = static_cast<uint8_t>(rng_below(&rng, 256));
        if (rng_below(&rng, 2) == 0) { // mostly well-formed, so that every state is reached
            static const uint8_t nmt[6] = {0x01, 0x01, 0x02, 0x80, 0x81, 0x82};
            if (f.id == 0x000) {
                f.dlc = 2;
                f.data[0] = nmt[rng_below(&rng, 6)];
                f.data[1] = static_cast<uint8_t>(rng_below(&rng, 2));
            } else if (f.id == 0x201) {
                f.dlc = 6;
            } else if (f.id == 0x601) {
                f.dlc = 8;
            }
        }
        hal_can_send(m, &f, 0);
        if (rng_below(&rng, 200) == 0) d.raise_fault();
        d.step(now);
        seen[static_cast<int>(d.state())] = true;
        now += rng_below(&rng, 2000);
        hal_can_frame_t g;
        while (hal_can_receive(m, &g, 0) == HAL_OK) {
            ASSERT_TRUE(hal_can_frame_is_valid(&g));
            const uint32_t fn = g.id & 0x780u;
            ASSERT_EQ(g.id & 0x7Fu, 1u);
            if (fn == 0x580u || fn == 0x080u) {
                ASSERT_EQ(g.dlc, 8);
            } else if (fn == 0x180u) {
                ASSERT_EQ(g.dlc, 6);
            } else {
                ASSERT_EQ(fn, 0x700u);
                ASSERT_EQ(g.dlc, 1);
            }
        }
    }
    EXPECT_GT(d.counters().sdo_requests, 0u);
    EXPECT_GT(d.counters().rpdos, 0u);
    // every resting state was visited (the braking states end within the
    // step at these speeds and are covered by StateMachineMotorAndFaults)
    for (int st : {0, 1, 2, 3, 4, 7}) EXPECT_TRUE(seen[st]) << "state " << st << " never reached";
}

// ---------------------------------------------------------------------------
// end to end: firmware driver + bus + three emulated drives
// ---------------------------------------------------------------------------

class EndToEnd : public ::testing::Test {
protected:
    uint64_t now = 0;
    OmniCanRig rig{[this] { return now; }};
    cia402_omni_t omni{};
    pose2_t truth{0, 0, 0};
    std::vector<std::pair<uint64_t, pose2_t>> truth_log; // pose at each tick's time

    void SetUp() override
    {
        const cia402_omni_config_t cfg = cia402_omni_config_default();
        ASSERT_EQ(cia402_omni_init(&omni, &cfg, rig.robot_can()), COSLAM_OK);
        ASSERT_EQ(cia402_omni_start(&omni, now), COSLAM_OK);
    }

    // one millisecond: firmware poll, drives step, physics integrates truth
    void tick()
    {
        cia402_omni_poll(&omni, now);
        rig.step(now);
        double vx, vy, w;
        rig.true_body_velocity(vx, vy, w);
        truth = motion_apply(truth, motion_from_body_velocity(vx, vy, w, 0.001));
        now += 1000;
        truth_log.emplace_back(now, truth);
    }
    template <class Pred> uint64_t run_until(Pred pred, int max_ms)
    {
        const uint64_t t0 = now;
        for (int i = 0; i < max_ms; ++i) {
            tick();
            if (pred()) return now - t0;
        }
        ADD_FAILURE() << "condition not reached within " << max_ms << " ms";
        return now - t0;
    }
    void run_ms(int ms)
    {
        for (int i = 0; i < ms; ++i) tick();
    }
    pose2_t truth_at(uint64_t t) const
    {
        for (const auto &e : truth_log) {
            if (e.first == t) return e.second;
        }
        ADD_FAILURE() << "no truth at " << t;
        return pose2_t{0, 0, 0};
    }
    // another driver and rig on the fixture's clock, ms milliseconds; the
    // driver polled (a live master) or not (a dead one)
    void run_other(cia402_omni_t &o, OmniCanRig &r, int ms, bool poll = true)
    {
        for (int i = 0; i < ms; ++i) {
            if (poll) cia402_omni_poll(&o, now);
            r.step(now);
            now += 1000;
        }
    }
    // a fault reset that restarts the bring-up, then enabled again
    void reset_and_enable()
    {
        ASSERT_EQ(cia402_omni_fault_reset(&omni, now), COSLAM_OK);
        run_until([&] { return cia402_omni_is_running(&omni) != 0; }, 500);
        run_until([&] {
            cia402_omni_fault_t r;
            return cia402_omni_get_fault(&omni, &r) == COSLAM_E_EMPTY;
        }, 100);
        ASSERT_EQ(cia402_omni_enable(&omni, 1), COSLAM_OK);
        run_until([&] { return cia402_omni_is_enabled(&omni) != 0; }, 200);
    }
    void enable_all()
    {
        run_until([&] { return cia402_omni_is_running(&omni) != 0; }, 500);
        ASSERT_EQ(cia402_omni_enable(&omni, 1), COSLAM_OK);
        run_until([&] { return cia402_omni_is_enabled(&omni) != 0; }, 200);
    }
};

TEST_F(EndToEnd, BringUpConfiguresTheDrives)
{
    const uint64_t t_run = run_until([&] { return cia402_omni_is_running(&omni) != 0; }, 500);
    ASSERT_EQ(cia402_omni_enable(&omni, 1), COSLAM_OK);
    const uint64_t t_en = run_until([&] { return cia402_omni_is_enabled(&omni) != 0; }, 200);
    RecordProperty("bring_up_ms", static_cast<int>(t_run / 1000));
    RecordProperty("enable_ms", static_cast<int>(t_en / 1000));
    std::printf("bring-up (NMT reset .. NMT start) %.0f ms, enable %.0f ms\n", t_run / 1000.0, t_en / 1000.0);
    EXPECT_LT(t_run, 100000u);
    EXPECT_LT(t_en, 50000u);
    for (int k = 0; k < 3; ++k) {
        const Cia402DriveEmu &d = rig.drive(k);
        EXPECT_EQ(d.mode(), 3);
        EXPECT_EQ(d.heartbeat_period_ms(), 100);
        EXPECT_EQ(d.consumer_heartbeat(), (127u << 16) | 200u); // the drive-side watchdog
        EXPECT_EQ(d.abort_option(), 3);
        EXPECT_EQ(d.nmt(), Cia402DriveEmu::Nmt::Operational);
        EXPECT_EQ(d.state(), Cia402DriveEmu::State::OperationEnabled);
        EXPECT_EQ(omni.drive[k].vendor_id, d.config().vendor_id);
        EXPECT_EQ(omni.drive[k].product_code, d.config().product_code);
    }
    // stays healthy: heartbeats and TPDOs keep the supervision happy
    run_ms(2000);
    cia402_omni_fault_t rep;
    EXPECT_EQ(cia402_omni_get_fault(&omni, &rep), COSLAM_E_EMPTY);
    EXPECT_EQ(omni.rx_overflows, 0u);
    EXPECT_EQ(omni.rx_foreign, 0u);
    for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(omni.drive[k].rx_malformed, 0u);
        EXPECT_GE(rig.drive(k).counters().heartbeats, 19u);
        EXPECT_GE(rig.drive(k).counters().tpdos, 190u);
        EXPECT_EQ(rig.drive(k).counters().consumer_timeouts, 0u); // a live master never trips it
    }
    EXPECT_GE(omni.master_hb_sent, 40u);
}

// The master dies (the robot process crashed, hung or was killed: nothing
// polls the driver any more) while the base drives at 0.3 m/s. The drives'
// own watchdog stops every wheel: not before the consumer time after the
// last master heartbeat (50 ms period, 200 ms), and at rest soon after.
// Without the watchdog the wheels keep their last command: the case it fixes.
TEST_F(EndToEnd, DeadMasterStopsTheWheels)
{
    enable_all();
    ASSERT_EQ(cia402_omni_set_body_velocity(&omni, 0.3, 0.0, 0.0), COSLAM_OK);
    run_ms(300);
    const double rpm0 = std::fabs(rig.drive(0).motor_rpm());
    ASSERT_GT(rpm0, 900.0);
    const uint64_t t_dead = now;
    const pose2_t at_death = truth;
    // the drives and the physics go on; the firmware does not
    auto dead_tick = [&] {
        rig.step(now);
        double vx, vy, w;
        rig.true_body_velocity(vx, vy, w);
        truth = motion_apply(truth, motion_from_body_velocity(vx, vy, w, 0.001));
        now += 1000;
    };
    for (int i = 0; i < 140; ++i) dead_tick();
    for (int k : {0, 2}) EXPECT_GT(std::fabs(rig.drive(k).motor_rpm()), 0.95 * rpm0) << "tripped early, wheel " << k;
    uint64_t t_stop = 0;
    for (int i = 0; i < 1000 && t_stop == 0; ++i) {
        dead_tick();
        bool all = true;
        for (int k = 0; k < 3; ++k) all = all && std::fabs(rig.drive(k).motor_rpm()) < 1.0;
        if (all) t_stop = now;
    }
    ASSERT_NE(t_stop, 0u) << "the wheels never stopped";
    const double travelled = std::hypot(truth.x - at_death.x, truth.y - at_death.y);
    std::printf("dead master -> wheels at rest after %.1f ms, %.3f m travelled\n", (t_stop - t_dead) / 1000.0,
                travelled);
    // trip at most 200 ms after death (+1 ms step), then the quick-stop lag
    // (20 ms) from ~1000 rpm to below 1 rpm: 20 ms x ln(1000) = 138 ms
    EXPECT_LE(t_stop - t_dead, 201000u + 140000u);
    // 0.3 m/s for at most 200 ms, then braking: 0.3 x (0.2 + 0.02) = 0.066 m
    EXPECT_LT(travelled, 0.3 * 0.22 + 0.005);
    for (int k = 0; k < 3; ++k) {
        const Cia402DriveEmu &d = rig.drive(k);
        EXPECT_EQ(d.counters().consumer_timeouts, 1u) << "wheel " << k;
        EXPECT_EQ(d.nmt(), Cia402DriveEmu::Nmt::PreOperational) << "wheel " << k;
        EXPECT_EQ(d.state(), Cia402DriveEmu::State::SwitchOnDisabled) << "wheel " << k; // quick stop, then off
    }

    // the master comes back: the EMCY it missed is a fault, and the reset
    // brings the drives up again (a new bring-up: they left OPERATIONAL)
    run_until([&] {
        cia402_omni_fault_t r;
        return cia402_omni_get_fault(&omni, &r) == COSLAM_OK;
    }, 50);
    cia402_omni_fault_t rep;
    ASSERT_EQ(cia402_omni_get_fault(&omni, &rep), COSLAM_OK);
    EXPECT_EQ(rep.info.reason, CIA402_FAULT_EMCY);
    EXPECT_EQ(rep.info.emcy_code, 0x8130);
    reset_and_enable();
    ASSERT_EQ(cia402_omni_set_body_velocity(&omni, 0.3, 0.0, 0.0), COSLAM_OK);
    run_ms(1000);
    EXPECT_GT(std::fabs(rig.drive(0).motor_rpm()), 0.95 * rpm0);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(rig.drive(k).counters().consumer_timeouts, 1u) << "wheel " << k;
}

// A clean stop: disabled, then released. The drives' watchdog is switched
// off by the NMT reset communication, so the heartbeat stopping does not
// end every clean stop in their EMCY.
TEST_F(EndToEnd, ReleasedDrivesDoNotTrip)
{
    enable_all();
    ASSERT_EQ(cia402_omni_set_body_velocity(&omni, 0.2, 0.0, 0.0), COSLAM_OK);
    run_ms(300);
    ASSERT_EQ(cia402_omni_set_body_velocity(&omni, 0.0, 0.0, 0.0), COSLAM_OK);
    ASSERT_EQ(cia402_omni_enable(&omni, 0), COSLAM_OK);
    run_ms(100);
    ASSERT_EQ(cia402_omni_release(&omni), COSLAM_OK);
    run_other(omni, rig, 1000, false); // the process has exited
    for (int k = 0; k < 3; ++k) {
        const Cia402DriveEmu &d = rig.drive(k);
        EXPECT_EQ(d.counters().consumer_timeouts, 0u) << "wheel " << k;
        EXPECT_EQ(d.consumer_heartbeat(), 0u) << "wheel " << k;
        EXPECT_EQ(d.nmt(), Cia402DriveEmu::Nmt::PreOperational) << "wheel " << k;
        EXPECT_EQ(d.state(), Cia402DriveEmu::State::SwitchOnDisabled) << "wheel " << k;
        EXPECT_LT(std::fabs(d.motor_rpm()), 1.0) << "wheel " << k;
    }
}

// The other two 0x6007 actions, and the watchdog switched off.
TEST_F(EndToEnd, DeadMasterActionsAndNoWatchdog)
{
    struct Case {
        int16_t action;      // 0: no watchdog (master_node_id 0)
        Cia402DriveEmu::State end;
        bool stopped;
    };
    const Case cases[] = {{CIA402_ABORT_DISABLE_VOLTAGE, Cia402DriveEmu::State::SwitchOnDisabled, true},
                          {CIA402_ABORT_FAULT, Cia402DriveEmu::State::Fault, true},
                          {0, Cia402DriveEmu::State::OperationEnabled, false}};
    for (const Case &c : cases) {
        OmniCanRig r2{[this] { return now; }};
        cia402_omni_config_t cfg = cia402_omni_config_default();
        if (c.action == 0) {
            cfg.drive.master_node_id = 0;
        } else {
            cfg.drive.master_loss_action = c.action;
        }
        cia402_omni_t o{};
        ASSERT_EQ(cia402_omni_init(&o, &cfg, r2.robot_can()), COSLAM_OK);
        ASSERT_EQ(cia402_omni_start(&o, now), COSLAM_OK);
        run_other(o, r2, 200);
        ASSERT_TRUE(cia402_omni_is_running(&o)) << "action " << c.action;
        ASSERT_EQ(cia402_omni_enable(&o, 1), COSLAM_OK);
        ASSERT_EQ(cia402_omni_set_body_velocity(&o, 0.3, 0.0, 0.0), COSLAM_OK);
        run_other(o, r2, 300);
        ASSERT_TRUE(cia402_omni_is_enabled(&o)) << "action " << c.action;
        run_other(o, r2, 2000, false); // the master died
        for (int k = 0; k < 3; ++k) {
            const Cia402DriveEmu &d = r2.drive(k);
            EXPECT_EQ(d.state(), c.end) << "action " << c.action << " wheel " << k;
            EXPECT_EQ(d.counters().consumer_timeouts, c.stopped ? 1u : 0u) << "action " << c.action;
            if (k != 1) { // wheel 1 stands still going straight ahead
                EXPECT_EQ(std::fabs(d.motor_rpm()) < 1.0, c.stopped) << "action " << c.action << " wheel " << k;
            }
        }
    }
}

// A drive without the watchdog objects refuses the set-up: the bring-up
// halts with the object named, rather than run unguarded.
TEST_F(EndToEnd, DriveWithoutWatchdogObjectsIsRefused)
{
    OmniCanRigConfig rc;
    rc.drive.watchdog_objects = false;
    OmniCanRig r2{[this] { return now; }, rc};
    cia402_omni_config_t cfg = cia402_omni_config_default();
    cia402_omni_t o{};
    ASSERT_EQ(cia402_omni_init(&o, &cfg, r2.robot_can()), COSLAM_OK);
    ASSERT_EQ(cia402_omni_start(&o, now), COSLAM_OK);
    run_other(o, r2, 300);
    cia402_omni_fault_t rep;
    ASSERT_EQ(cia402_omni_get_fault(&o, &rep), COSLAM_OK);
    EXPECT_EQ(rep.info.reason, CIA402_FAULT_SDO_ABORT);
    EXPECT_EQ(rep.info.sdo_abort_code, 0x06020000u); // object does not exist
    EXPECT_EQ(rep.info.sdo_index, 0x1016);
    EXPECT_FALSE(cia402_omni_is_running(&o));
    // switched off knowingly, the same drives run
    cfg.drive.master_node_id = 0;
    ASSERT_EQ(cia402_omni_init(&o, &cfg, r2.robot_can()), COSLAM_OK);
    ASSERT_EQ(cia402_omni_start(&o, now), COSLAM_OK);
    run_other(o, r2, 300);
    EXPECT_TRUE(cia402_omni_is_running(&o));
    EXPECT_EQ(cia402_omni_get_fault(&o, &rep), COSLAM_E_EMPTY);
}

TEST_F(EndToEnd, BodyVelocityCommandGivesMatchingOdometry)
{
    enable_all();
    odo_increment_t u;
    uint64_t until = 0;
    ASSERT_EQ(cia402_omni_take_odometry(&omni, &u, &until), COSLAM_OK);
    const pose2_t start_truth = truth_at(until);
    const double vx = 0.3, vy = 0.1, w = 0.5;
    ASSERT_EQ(cia402_omni_set_body_velocity(&omni, vx, vy, w), COSLAM_OK);
    // the SLAM loop would take an increment every 100 ms
    pose2_t odo = {0, 0, 0};
    uint64_t end = until;
    for (int i = 0; i < 30; ++i) {
        run_ms(100);
        ASSERT_EQ(cia402_omni_take_odometry(&omni, &u, &end), COSLAM_OK);
        odo = motion_apply(odo, u);
    }
    // truth over the same interval, in the start frame
    const pose2_t rel = pose2_between(start_truth, truth_at(end));
    std::printf("3 s arc: odometry (%.4f, %.4f, %.4f), truth (%.4f, %.4f, %.4f)\n", odo.x, odo.y, odo.theta, rel.x,
                rel.y, rel.theta);
    EXPECT_NEAR(odo.x, rel.x, 0.001);
    EXPECT_NEAR(odo.y, rel.y, 0.001);
    EXPECT_NEAR(angle_wrap(odo.theta - rel.theta), 0.0, 0.001);
    // and the motion is the commanded one once settled
    double mvx, mvy, mw;
    ASSERT_EQ(cia402_omni_measured_velocity(&omni, &mvx, &mvy, &mw), COSLAM_OK);
    EXPECT_NEAR(mvx, vx, 1e-3);
    EXPECT_NEAR(mvy, vy, 1e-3);
    EXPECT_NEAR(mw, w, 1e-3);
    double tvx, tvy, tw;
    rig.true_body_velocity(tvx, tvy, tw);
    EXPECT_NEAR(tvx, vx, 1e-3);
    EXPECT_NEAR(tw, w, 1e-3);
    // the closed-form arc (the 50 ms motor lag costs about v * tau of path)
    const pose2_t arc = {std::sin(w * 3.0) * vx / w + (std::cos(w * 3.0) - 1.0) * vy / w,
                         (1.0 - std::cos(w * 3.0)) * vx / w + std::sin(w * 3.0) * vy / w, w * 3.0};
    EXPECT_NEAR(odo.x, arc.x, 0.05);
    EXPECT_NEAR(odo.y, arc.y, 0.05);
    EXPECT_NEAR(angle_wrap(odo.theta - arc.theta), 0.0, 0.05);
}

TEST_F(EndToEnd, FaultOnOneDriveStopsAllAndIsReported)
{
    enable_all();
    ASSERT_EQ(cia402_omni_set_body_velocity(&omni, 0.4, 0.0, 0.8), COSLAM_OK);
    run_ms(500);
    for (int k = 0; k < 3; ++k) ASSERT_GT(std::fabs(rig.drive(k).motor_rpm()), 100.0);
    rig.drive(1).raise_fault(0x2310, 0x03);
    const uint64_t t_report = run_until(
        [&] {
            cia402_omni_fault_t r;
            return cia402_omni_get_fault(&omni, &r) == COSLAM_OK;
        },
        50);
    EXPECT_LE(t_report, 2000u); // the EMCY is read at the next poll
    std::printf("EMCY -> fault reported after %.1f ms\n", t_report / 1000.0);
    cia402_omni_fault_t rep;
    ASSERT_EQ(cia402_omni_get_fault(&omni, &rep), COSLAM_OK);
    EXPECT_EQ(rep.wheel, 1);
    EXPECT_EQ(rep.node_id, 2);
    EXPECT_EQ(rep.info.reason, CIA402_FAULT_EMCY);
    EXPECT_EQ(rep.info.emcy_code, 0x2310);
    EXPECT_EQ(rep.info.emcy_register, 0x03);
    EXPECT_EQ(cia402_omni_set_body_velocity(&omni, 0.4, 0.0, 0.0), COSLAM_E_DRIVE_FAULT);
    run_ms(500);
    for (int k = 0; k < 3; ++k) {
        EXPECT_LT(std::fabs(rig.drive(k).motor_rpm()), 1.0) << "wheel " << k;
        EXPECT_EQ(rig.drive(k).commanded_rpm(), 0.0);
    }
    EXPECT_EQ(rig.drive(0).state(), Cia402DriveEmu::State::SwitchOnDisabled); // quick stop done
    EXPECT_EQ(rig.drive(2).state(), Cia402DriveEmu::State::SwitchOnDisabled);
    EXPECT_EQ(rig.drive(1).state(), Cia402DriveEmu::State::Fault);
    double tvx, tvy, tw;
    rig.true_body_velocity(tvx, tvy, tw);
    EXPECT_NEAR(std::hypot(tvx, tvy), 0.0, 1e-3);
    // fault reset, re-enable, drive again
    ASSERT_EQ(cia402_omni_fault_reset(&omni, now), COSLAM_OK);
    run_until([&] {
        cia402_omni_fault_t r;
        return cia402_omni_get_fault(&omni, &r) == COSLAM_E_EMPTY;
    }, 100);
    EXPECT_EQ(rig.drive(1).state(), Cia402DriveEmu::State::SwitchOnDisabled);
    ASSERT_EQ(cia402_omni_enable(&omni, 1), COSLAM_OK);
    run_until([&] { return cia402_omni_is_enabled(&omni) != 0; }, 200);
    ASSERT_EQ(cia402_omni_set_body_velocity(&omni, 0.2, 0.0, 0.0), COSLAM_OK);
    run_ms(500);
    double mvx;
    ASSERT_EQ(cia402_omni_measured_velocity(&omni, &mvx, nullptr, nullptr), COSLAM_OK);
    EXPECT_NEAR(mvx, 0.2, 1e-3);
}

TEST_F(EndToEnd, HeartbeatLossStopsAll)
{
    enable_all();
    ASSERT_EQ(cia402_omni_set_body_velocity(&omni, 0.0, 0.3, 0.0), COSLAM_OK);
    run_ms(300);
    rig.drive(2).set_silent(true);
    const uint64_t t_report = run_until(
        [&] {
            cia402_omni_fault_t r;
            return cia402_omni_get_fault(&omni, &r) == COSLAM_OK;
        },
        400);
    cia402_omni_fault_t rep;
    ASSERT_EQ(cia402_omni_get_fault(&omni, &rep), COSLAM_OK);
    EXPECT_EQ(rep.wheel, 2);
    // TPDOs stop too, and the PDO timeout (100 ms) is shorter than the heartbeat's (250 ms)
    EXPECT_EQ(rep.info.reason, CIA402_FAULT_PDO_TIMEOUT);
    std::printf("silent drive -> PDO timeout reported after %.1f ms\n", t_report / 1000.0);
    EXPECT_GE(t_report, 90000u);
    EXPECT_LE(t_report, 115000u);
    run_ms(500);
    // the silent drive still hears the quick stop, so everything stops
    for (int k = 0; k < 3; ++k) EXPECT_LT(std::fabs(rig.drive(k).motor_rpm()), 1.0) << "wheel " << k;
}

TEST_F(EndToEnd, HeartbeatConsumerAloneDetectsLoss)
{
    // with PDO supervision off, the heartbeat consumer (250 ms) catches it
    cia402_omni_config_t cfg = cia402_omni_config_default();
    cfg.drive.pdo_timeout_us = 0;
    ASSERT_EQ(cia402_omni_init(&omni, &cfg, rig.robot_can()), COSLAM_OK);
    ASSERT_EQ(cia402_omni_start(&omni, now), COSLAM_OK);
    enable_all();
    run_ms(50);
    rig.drive(0).set_silent(true);
    const uint64_t t_report = run_until(
        [&] {
            cia402_omni_fault_t r;
            return cia402_omni_get_fault(&omni, &r) == COSLAM_OK;
        },
        600);
    cia402_omni_fault_t rep;
    ASSERT_EQ(cia402_omni_get_fault(&omni, &rep), COSLAM_OK);
    EXPECT_EQ(rep.wheel, 0);
    EXPECT_EQ(rep.info.reason, CIA402_FAULT_HEARTBEAT);
    std::printf("silent drive -> heartbeat loss reported after %.1f ms\n", t_report / 1000.0);
    EXPECT_GT(t_report, 150000u); // last heartbeat up to 100 ms before going silent
    EXPECT_LE(t_report, 252000u);
}

TEST_F(EndToEnd, DriveRebootIsAnNmtFault)
{
    enable_all();
    rig.drive(0).power_cycle(now);
    run_until(
        [&] {
            cia402_omni_fault_t r;
            return cia402_omni_get_fault(&omni, &r) == COSLAM_OK;
        },
        50);
    cia402_omni_fault_t rep;
    ASSERT_EQ(cia402_omni_get_fault(&omni, &rep), COSLAM_OK);
    EXPECT_EQ(rep.wheel, 0);
    EXPECT_EQ(rep.info.reason, CIA402_FAULT_NMT);
    // the reset brings it up again from scratch
    reset_and_enable();
    EXPECT_EQ(rig.drive(0).mode(), 3);
}
