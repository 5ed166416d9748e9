#ifndef STRUCTGP_SRC_FEATURE_PER_THREAD_SCRATCH_H_
#define STRUCTGP_SRC_FEATURE_PER_THREAD_SCRATCH_H_

// Scratch of a const, thread-safe map kept per thread: each thread holds one Scratch per type,
// made by make() on the thread's first call and again whenever the thread last served another
// owner (another map object); later calls allocate nothing.

#include <cstdint>
#include <utility>

namespace structgp {
namespace internal {

// A new owner id (never 0), one per map object.
std::uint64_t NewScratchOwner();

template <class Scratch, class Make>
Scratch& PerThreadScratch(std::uint64_t owner, Make&& make) {
  thread_local std::uint64_t current = 0;
  thread_local Scratch scratch;
  if (current != owner) {
    scratch = std::forward<Make>(make)();
    current = owner;
  }
  return scratch;
}

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_SRC_FEATURE_PER_THREAD_SCRATCH_H_
