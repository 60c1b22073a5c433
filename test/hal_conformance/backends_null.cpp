// The null backends (hal/null): every contract, every operation
// HAL_E_UNSUPPORTED. They are also what the Linux build uses for the camera
// and the link until V4L2 and DDS backends exist.
#include "conformance.hpp"

namespace {
struct NullSet : conf::NullHarness {
    hal_clock_t *clock() override { return hal_clock_null(); }
    hal_gpio_t *gpio() override { return hal_gpio_null(); }
    hal_link_t *link() override { return hal_link_null(); }
    hal_storage_t *storage() override { return hal_storage_null(); }
    hal_camera_t *camera() override { return hal_camera_null(); }
};
}  // namespace

INSTANTIATE_TEST_SUITE_P(Null, NullConformance, ::testing::Values(conf::make_backend<conf::NullHarness, NullSet>("null")),
                         conf::BackendName());
