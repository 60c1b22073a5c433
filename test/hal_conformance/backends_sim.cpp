// Simulator backends in the conformance suites, each under both blocking
// models of the simulated clock (docs/hal.md, "Simulated time"):
//  - hook:     single thread, the step hook jumps time to the wait's deadline
//  - lockstep: the test thread is the firmware thread; a SimLockstepDriver
//              thread advances time whenever it blocks.
#include <memory>
#include <optional>

#include "conformance.hpp"
#include "sim_hal/sim_camera.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_gpio.hpp"
#include "sim_hal/sim_link.hpp"
#include "sim_hal/sim_serial.hpp"
#include "sim_hal/sim_storage.hpp"

using namespace coslam::sim;

namespace {

enum class Model { hook, lockstep };

/// A world: the clock and its scheduler, per the model.
struct World {
    explicit World(Model m) : clock(1000000)
    {
        if (m == Model::hook) {
            clock.set_step_hook([this](uint64_t deadline_us) { clock.advance_to(deadline_us); });
        } else {
            me.emplace(clock);  // the test thread is the firmware thread
            driver = std::make_unique<SimLockstepDriver>(clock, 0);
        }
    }
    ~World() { driver.reset(); }  // stop the driver before the devices go
    SimClock clock;
    std::optional<SimClock::LockstepParticipant> me;
    std::unique_ptr<SimLockstepDriver> driver;
};

template <class Base>
struct SimTime : Base {
    explicit SimTime(Model m) : world(m) {}
    hal_clock_t *clock() override { return world.clock.handle(); }
    void let_time_pass_us(uint64_t us) override { world.clock.advance_by(us); }
    World world;
};

struct SimClockHarness : SimTime<conf::ClockHarness> {
    using SimTime::SimTime;
    hal_clock_t *dev() override { return world.clock.handle(); }
};

struct SimGpioHarness : SimTime<conf::GpioHarness> {
    explicit SimGpioHarness(Model m) : SimTime(m), gpio(world.clock, 8, 16) {}
    hal_gpio_t *dev() override { return gpio.handle(); }
    uint32_t input_line() const override { return 3; }
    uint32_t output_line() const override { return 5; }
    void drive_input(uint32_t line, bool high) override { gpio.set_input_level(line, high); }
    bool observe_output(uint32_t line) override
    {
        const auto v = gpio.output_level(line);
        EXPECT_TRUE(v.has_value()) << "output line not driven";
        return v.value_or(false);
    }
    size_t edge_queue_depth() const override { return gpio.edge_queue_depth(); }
    SimGpio gpio;
};

struct SimLinkHarness : SimTime<conf::LinkHarness> {
    static SimLinkParams perfect()
    {
        SimLinkParams p;
        p.range_m = 10.0;
        p.latency_us = 2000;
        p.jitter_us = 500;
        p.loss_prob = 0.0;
        return p;
    }
    explicit SimLinkHarness(Model m) : SimTime(m), hub(world.clock, std::vector<uint16_t>{3, 7, 11, 12}, perfect())
    {
        hub.set_position(3, 0.0, 0.0);
        hub.set_position(7, 1.0, 0.0);
        hub.set_position(11, 0.0, 2.0);
        hub.set_position(12, -3.0, -3.0);
    }
    size_t count() const override { return 4; }
    hal_link_t *dev(size_t i) override { return hub.endpoint(std::vector<uint16_t>{3, 7, 11, 12}.at(i)); }
    uint64_t max_latency_us() const override { return 2500; }
    SimLinkHub hub;
};

struct SimStorageHarness : conf::StorageHarness {
    hal_storage_t *dev() override { return storage.handle(); }
    hal_storage_t *reopen() override { return storage.handle(); }  // memory persists with the object
    SimStorage storage{4u << 20};
};

struct SimCameraHarness : SimTime<conf::CameraHarness> {
    SimCameraHarness(Model m, hal_camera_pixfmt_t fmt, uint32_t stride)
        : SimTime(m), cam(world.clock, 64, 48, fmt, stride)
    {
    }
    hal_camera_t *dev() override { return cam.handle(); }
    std::vector<uint8_t> capture(uint32_t seed, uint64_t *stamp_us) override
    {
        auto frame = conf::pattern(cam.format().frame_bytes, seed);
        *stamp_us = world.clock.now_us();
        cam.push_frame(frame.data(), frame.size(), *stamp_us);
        return frame;
    }
    SimCamera cam;
};

struct SimSerialHarness : SimTime<conf::SerialHarness> {
    explicit SimSerialHarness(Model m) : SimTime(m), port(world.clock) { port.set_max_chunk(7); }
    hal_serial_t *dev() override { return port.handle(); }
    void peer_send(const uint8_t *data, size_t len) override { ASSERT_EQ(port.peer_write(data, len), len); }
    size_t peer_recv(uint8_t *buf, size_t cap, uint64_t) override
    {
        const auto v = port.peer_read(cap);
        std::copy(v.begin(), v.end(), buf);
        return v.size();
    }
    SimSerialPort port;
};

}  // namespace

INSTANTIATE_TEST_SUITE_P(Sim, ClockConformance,
                         ::testing::Values(conf::make_backend<conf::ClockHarness, SimClockHarness>("hook", Model::hook),
                                           conf::make_backend<conf::ClockHarness, SimClockHarness>("lockstep", Model::lockstep)),
                         conf::BackendName());

INSTANTIATE_TEST_SUITE_P(Sim, GpioConformance,
                         ::testing::Values(conf::make_backend<conf::GpioHarness, SimGpioHarness>("hook", Model::hook),
                                           conf::make_backend<conf::GpioHarness, SimGpioHarness>("lockstep", Model::lockstep)),
                         conf::BackendName());

INSTANTIATE_TEST_SUITE_P(Sim, LinkConformance,
                         ::testing::Values(conf::make_backend<conf::LinkHarness, SimLinkHarness>("hook", Model::hook),
                                           conf::make_backend<conf::LinkHarness, SimLinkHarness>("lockstep", Model::lockstep)),
                         conf::BackendName());

INSTANTIATE_TEST_SUITE_P(Sim, StorageConformance,
                         ::testing::Values(conf::make_backend<conf::StorageHarness, SimStorageHarness>("memory")),
                         conf::BackendName());

INSTANTIATE_TEST_SUITE_P(
    Sim, CameraConformance,
    ::testing::Values(
        conf::make_backend<conf::CameraHarness, SimCameraHarness>("rgb24_hook", Model::hook, HAL_CAMERA_PIX_RGB24, 0u),
        conf::make_backend<conf::CameraHarness, SimCameraHarness>("yuyv_padded_hook", Model::hook, HAL_CAMERA_PIX_YUYV, 160u),
        conf::make_backend<conf::CameraHarness, SimCameraHarness>("rgb24_lockstep", Model::lockstep, HAL_CAMERA_PIX_RGB24, 0u)),
    conf::BackendName());

INSTANTIATE_TEST_SUITE_P(Sim, SerialConformance,
                         ::testing::Values(conf::make_backend<conf::SerialHarness, SimSerialHarness>("hook", Model::hook),
                                           conf::make_backend<conf::SerialHarness, SimSerialHarness>("lockstep",
                                                                                          Model::lockstep)),
                         conf::BackendName());
