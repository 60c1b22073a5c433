// Linux backends in the conformance suites: the monotonic clock and file
// storage in a fresh temporary directory per test.
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "conformance.hpp"
#include "hal/hal_clock_linux.h"
#include "hal/hal_storage_linux.h"

namespace {

struct LinuxClockHarness : conf::ClockHarness {
    hal_clock_t *dev() override { return hal_clock_linux(); }
    bool real_time() const override { return true; }
    void let_time_pass_us(uint64_t us) override
    {
        struct timespec ts;
        ts.tv_sec = static_cast<time_t>(us / 1000000u);
        ts.tv_nsec = static_cast<long>((us % 1000000u) * 1000u);
        while (nanosleep(&ts, &ts) != 0) {
        }
    }
};

struct LinuxStorageHarness : conf::StorageHarness {
    LinuxStorageHarness()
    {
        std::string tmpl = (std::filesystem::temp_directory_path() / "coslam_storage_XXXXXX").string();
        if (mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
        dir = tmpl;
        open();
    }
    ~LinuxStorageHarness() override
    {
        hal_storage_close(&st.dev);
        std::error_code ec;
        std::filesystem::remove_all(dir, ec);
    }
    void open()
    {
        const hal_status_t s = hal_storage_linux_open(&st, (dir + "/blobs").c_str());
        EXPECT_EQ(s, HAL_OK);
    }
    hal_storage_t *dev() override { return &st.dev; }
    hal_storage_t *reopen() override
    {
        hal_storage_close(&st.dev);
        open();
        return &st.dev;
    }
    std::string dir;
    hal_storage_linux_t st{};
};

}  // namespace

INSTANTIATE_TEST_SUITE_P(Linux, ClockConformance,
                         ::testing::Values(conf::make_backend<conf::ClockHarness, LinuxClockHarness>("monotonic")),
                         conf::BackendName());

INSTANTIATE_TEST_SUITE_P(Linux, StorageConformance,
                         ::testing::Values(conf::make_backend<conf::StorageHarness, LinuxStorageHarness>("files")),
                         conf::BackendName());
