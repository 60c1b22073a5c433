// conformance.hpp - the HAL conformance framework: one GoogleTest
// value-parameterised suite per contract, written against the C contract
// only, run against every backend.
//
// A backend joins a suite with a *harness* (a fixture that owns one backend
// instance, plus the test-side powers the contract cannot express: drive an
// input pin, make a frame arrive, let time pass) and one INSTANTIATE line:
//
//   struct MyGpioHarness : conf::GpioHarness { ... };   // the fixture factory
//   INSTANTIATE_TEST_SUITE_P(Mine, GpioConformance,
//       ::testing::Values(conf::make_backend<conf::GpioHarness, MyGpioHarness>("mine")),
//       conf::BackendName());
//
// Backends without the hardware (null backends) join the <Contract>Null
// suites instead, which check that every operation is HAL_E_UNSUPPORTED.
// The harness is created fresh for every test (SetUp) and destroyed after
// it, so tests are independent. See docs/hal.md.
#ifndef COSLAM_HAL_CONFORMANCE_HPP
#define COSLAM_HAL_CONFORMANCE_HPP

#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "hal/hal_camera.h"
#include "hal/hal_can.h"
#include "hal/hal_clock.h"
#include "hal/hal_gpio.h"
#include "hal/hal_link.h"
#include "hal/hal_serial.h"
#include "hal/hal_storage.h"

namespace conf {

/// One backend of one contract: a name (test-name safe: [A-Za-z0-9_]) and a
/// factory making a fresh harness.
template <class Harness>
struct Backend {
    std::string name;
    std::function<std::unique_ptr<Harness>()> make;
};

/// Name generator for INSTANTIATE_TEST_SUITE_P: the backend's name.
struct BackendName {
    template <class P>
    std::string operator()(const ::testing::TestParamInfo<P> &info) const
    {
        return info.param.name;
    }
};

template <class Harness>
std::ostream &operator<<(std::ostream &os, const Backend<Harness> &b)
{
    return os << b.name;
}

// ---------------------------------------------------------------------------
// Harness interfaces, one per contract.
// ---------------------------------------------------------------------------

/// Common: a clock in the backend's stamp time base, when the harness has
/// one (stamps and timeouts are then checked against it).
struct TimeBase {
    virtual ~TimeBase() = default;
    virtual hal_clock_t *clock() { return nullptr; }
    /// Make at least us microseconds pass in the backend's time base
    /// (simulated: advance; real: sleep).
    virtual void let_time_pass_us(uint64_t us) = 0;
    /// True if timeouts consume real (wall-clock) time: tests then keep
    /// timeouts short.
    virtual bool real_time() const { return false; }
};

struct ClockHarness : TimeBase {
    virtual hal_clock_t *dev() = 0;
    hal_clock_t *clock() override { return dev(); }
};

struct GpioHarness : TimeBase {
    virtual hal_gpio_t *dev() = 0;
    /// A line whose input level the harness can drive (a loopback wire on
    /// real hardware), and one whose output level it can observe.
    virtual uint32_t input_line() const = 0;
    virtual uint32_t output_line() const = 0;
    virtual void drive_input(uint32_t line, bool high) = 0;   ///< electrical level
    virtual bool observe_output(uint32_t line) = 0;           ///< electrical level
    /// Edge queue depth if the backend reports overflow, else 0 (skip).
    virtual size_t edge_queue_depth() const { return 0; }
};

struct LinkHarness : TimeBase {
    /// At least 3 endpoints on one perfect channel (all in range, no loss).
    virtual size_t count() const = 0;
    virtual hal_link_t *dev(size_t i) = 0;
    /// Upper bound on delivery time on that channel [us].
    virtual uint64_t max_latency_us() const = 0;
};

struct StorageHarness {
    virtual ~StorageHarness() = default;
    virtual hal_storage_t *dev() = 0;
    /// Close and reopen the same medium (persistence); returns the new handle.
    virtual hal_storage_t *reopen() = 0;
};

struct CameraHarness : TimeBase {
    virtual hal_camera_t *dev() = 0;
    /// Make the camera capture one frame of the harness's choosing (pixels
    /// derived from seed); returns the exact bytes and sets *stamp_us.
    virtual std::vector<uint8_t> capture(uint32_t seed, uint64_t *stamp_us) = 0;
};

struct SerialHarness : TimeBase {
    virtual hal_serial_t *dev() = 0;
    /// Bytes the device will read.
    virtual void peer_send(const uint8_t *data, size_t len) = 0;
    /// Bytes the device wrote, up to cap (may wait up to wait_us).
    virtual size_t peer_recv(uint8_t *buf, size_t cap, uint64_t wait_us) = 0;
};

struct CanHarness : TimeBase {
    virtual hal_can_t *dev() = 0;
    /// Put a frame on the bus from another node (the device receives it).
    virtual void peer_send(const hal_can_frame_t &frame) = 0;
    /// A frame the device sent, as another node sees it; false if none
    /// within wait_us.
    virtual bool peer_recv(hal_can_frame_t *frame, uint64_t wait_us) = 0;
    /// Receive queue depth if the harness can overflow it, else 0 (skip).
    virtual size_t rx_queue_depth() const { return 0; }
};

/// Null backends: a handle for every contract the backend set covers;
/// nullptr for contracts it does not provide.
struct NullHarness {
    virtual ~NullHarness() = default;
    virtual hal_clock_t *clock() { return nullptr; }
    virtual hal_gpio_t *gpio() { return nullptr; }
    virtual hal_link_t *link() { return nullptr; }
    virtual hal_storage_t *storage() { return nullptr; }
    virtual hal_camera_t *camera() { return nullptr; }
    virtual hal_serial_t *serial() { return nullptr; }
};

using ClockBackend = Backend<ClockHarness>;
using GpioBackend = Backend<GpioHarness>;
using LinkBackend = Backend<LinkHarness>;
using StorageBackend = Backend<StorageHarness>;
using CameraBackend = Backend<CameraHarness>;
using SerialBackend = Backend<SerialHarness>;
using CanBackend = Backend<CanHarness>;
using NullBackend = Backend<NullHarness>;

/// A Backend whose factory constructs Harness(args...) (args copied).
template <class Interface, class Harness, class... Args>
Backend<Interface> make_backend(std::string name, Args... args)
{
    return Backend<Interface>{std::move(name), [=] { return std::unique_ptr<Interface>(new Harness(args...)); }};
}

/// The fixture of every suite: makes the harness in SetUp.
template <class Harness>
class Suite : public ::testing::TestWithParam<Backend<Harness>> {
protected:
    void SetUp() override
    {
        h = this->GetParam().make();
        ASSERT_NE(h, nullptr) << "harness factory failed";
    }
    void TearDown() override { h.reset(); }
    std::unique_ptr<Harness> h;
};

/// Read a clock (or fail the test).
inline uint64_t now_of(hal_clock_t *c)
{
    uint64_t t = 0;
    EXPECT_EQ(hal_clock_now_us(c, &t), HAL_OK);
    return t;
}

/// Deterministic test bytes.
inline std::vector<uint8_t> pattern(size_t n, uint32_t seed)
{
    std::vector<uint8_t> v(n);
    uint32_t x = seed * 2654435761u + 12345u;
    for (size_t i = 0; i < n; ++i) {
        x = x * 1664525u + 1013904223u;
        v[i] = static_cast<uint8_t>(x >> 24);
    }
    return v;
}

}  // namespace conf

// Suite names (fixtures) the backends instantiate.
using ClockConformance = conf::Suite<conf::ClockHarness>;
using GpioConformance = conf::Suite<conf::GpioHarness>;
using LinkConformance = conf::Suite<conf::LinkHarness>;
using StorageConformance = conf::Suite<conf::StorageHarness>;
using CameraConformance = conf::Suite<conf::CameraHarness>;
using SerialConformance = conf::Suite<conf::SerialHarness>;
using CanConformance = conf::Suite<conf::CanHarness>;
using NullConformance = conf::Suite<conf::NullHarness>;

#endif
