// test/vision/alloc_counter.hpp - counts heap allocations while armed, by
// interposing malloc and friends for the whole process (shared libraries
// such as OpenCV included) and forwarding to glibc's own. Include in ONE
// translation unit of a test executable.
//
// Under AddressSanitizer (the sanitizer build, `make test SANITIZE=1`) ASan
// owns malloc: interposing it as well crashes the process before main (ASan
// allocates while it initialises). There kCounting is false, nothing is
// interposed and during() returns -1: the tests check the count only where
// it is counted (the normal build) and ASan checks the memory itself.
#ifndef COSLAM_TEST_VISION_ALLOC_COUNTER_HPP
#define COSLAM_TEST_VISION_ALLOC_COUNTER_HPP

#if defined(__SANITIZE_ADDRESS__)
#define COSLAM_ALLOC_COUNTING 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define COSLAM_ALLOC_COUNTING 0
#endif
#endif
#ifndef COSLAM_ALLOC_COUNTING
#define COSLAM_ALLOC_COUNTING 1
#endif

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
inline constexpr bool kCounting = COSLAM_ALLOC_COUNTING != 0;
inline std::atomic<bool> armed{false};
inline std::atomic<long> count{0};
inline void note()
{
    if (armed.load(std::memory_order_relaxed)) count.fetch_add(1, std::memory_order_relaxed);
}
/// Allocations made by f() (-1 where not counted: kCounting false).
template <class F> long during(F &&f)
{
    if (!kCounting) {
        f();
        return -1;
    }
    count = 0;
    armed = true;
    f();
    armed = false;
    return count.load();
}
}  // namespace alloc_counter

#if COSLAM_ALLOC_COUNTING
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

#endif
