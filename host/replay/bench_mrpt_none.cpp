// host/replay/bench_mrpt_none.cpp - stand-in when the build has no MRPT
// (the benchmark then runs coslam's filters only and says why).
#include "bench_slam.h"

namespace coslam::replay {

bool mrpt_available()
{
    return false;
}

std::unique_ptr<SlamUnderTest> make_mrpt_slam(const MrptSlamOptions &)
{
    return nullptr;
}

} // namespace coslam::replay
