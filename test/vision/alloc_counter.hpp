// test/vision/alloc_counter.hpp - counts heap allocations while armed, by
// interposing malloc and friends for the whole process (shared libraries
// such as OpenCV included) and forwarding to glibc's own. Include in ONE
// translation unit of a test executable.
#ifndef COSLAM_TEST_VISION_ALLOC_COUNTER_HPP
#define COSLAM_TEST_VISION_ALLOC_COUNTER_HPP

#include <atomic>
#include <cerrno>
#include <cstddef>

extern "C" {
void *__libc_malloc(size_t);
void *__libc_calloc(size_t, size_t);
void *__libc_realloc(void *, size_t);
void *__libc_memalign(size_t, size_t);
}

namespace alloc_counter {
inline std::atomic<bool> armed{false};
inline std::atomic<long> count{0};
inline void note()
{
    if (armed.load(std::memory_order_relaxed)) count.fetch_add(1, std::memory_order_relaxed);
}
/// Allocations made by f().
template <class F> long during(F &&f)
{
    count = 0;
    armed = true;
    f();
    armed = false;
    return count.load();
}
}  // namespace alloc_counter

extern "C" {
void *malloc(size_t n)
{
    alloc_counter::note();
    return __libc_malloc(n);
}
void *calloc(size_t n, size_t m)
{
    alloc_counter::note();
    return __libc_calloc(n, m);
}
void *realloc(void *p, size_t n)
{
    alloc_counter::note();
    return __libc_realloc(p, n);
}
void *memalign(size_t a, size_t n)
{
    alloc_counter::note();
    return __libc_memalign(a, n);
}
void *aligned_alloc(size_t a, size_t n)
{
    alloc_counter::note();
    return __libc_memalign(a, n);
}
int posix_memalign(void **out, size_t a, size_t n)
{
    alloc_counter::note();
    void *p = __libc_memalign(a, n);
    if (p == nullptr) return ENOMEM;
    *out = p;
    return 0;
}
}

#endif
