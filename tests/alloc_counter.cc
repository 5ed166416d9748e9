// Replaces the global allocation functions to count them. malloc itself is wrapped through
// glibc's __libc_malloc so that Eigen's aligned_malloc (which calls std::malloc) is counted.

#include "alloc_counter.h"

#include <atomic>
#include <cstdlib>
#include <new>

extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);
}

namespace {
std::atomic<std::size_t> g_allocations{0};
}  // namespace

namespace structgp {
namespace testing {
std::size_t TotalAllocations() { return g_allocations.load(std::memory_order_relaxed); }
}  // namespace testing
}  // namespace structgp

// GCC defines __SANITIZE_ADDRESS__ / __SANITIZE_THREAD__; clang answers __has_feature.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define STRUCTGP_UNDER_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define STRUCTGP_UNDER_SANITIZER 1
#endif
#endif

namespace structgp {
namespace testing {
#ifdef STRUCTGP_UNDER_SANITIZER
bool CountsEveryAllocation() { return false; }
#else
bool CountsEveryAllocation() { return true; }
#endif
}  // namespace testing
}  // namespace structgp

#ifndef STRUCTGP_UNDER_SANITIZER
// Sanitizers install their own malloc; wrapping it would bypass their checks, so under a
// sanitizer only operator new is counted.
extern "C" {
void* malloc(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return __libc_realloc(p, size);
}
void free(void* p) { __libc_free(p); }
}
#define STRUCTGP_NEW_ALLOC(size) std::malloc(size)
#define STRUCTGP_NEW_FREE(p) std::free(p)
#else
#define STRUCTGP_NEW_ALLOC(size) \
  (g_allocations.fetch_add(1, std::memory_order_relaxed), std::malloc(size))
#define STRUCTGP_NEW_FREE(p) std::free(p)
#endif

void* operator new(std::size_t size) {
  void* p = STRUCTGP_NEW_ALLOC(size == 0 ? 1 : size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  return STRUCTGP_NEW_ALLOC(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  return STRUCTGP_NEW_ALLOC(size == 0 ? 1 : size);
}
void operator delete(void* p) noexcept { STRUCTGP_NEW_FREE(p); }
void operator delete[](void* p) noexcept { STRUCTGP_NEW_FREE(p); }
void operator delete(void* p, std::size_t) noexcept { STRUCTGP_NEW_FREE(p); }
void operator delete[](void* p, std::size_t) noexcept { STRUCTGP_NEW_FREE(p); }
