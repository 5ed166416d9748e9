#ifndef STRUCTGP_TESTS_ALLOC_COUNTER_H_
#define STRUCTGP_TESTS_ALLOC_COUNTER_H_

// Counts heap allocations made through the global operator new / malloc-free C++ allocation
// path of this process. Linking alloc_counter.cc replaces the global operator new family, so
// every C++ allocation (Eigen's included: Eigen allocates through std::malloc, which is
// counted separately via the malloc hook below) increments the counter.
//
// Use:
//   structgp::testing::AllocationCounter guard;
//   model.Update(...);
//   EXPECT_EQ(guard.count(), 0);

#include <cstddef>

namespace structgp {
namespace testing {

/// Number of allocations (operator new and malloc/calloc/realloc) since program start.
std::size_t TotalAllocations();

/// Counts allocations made during its lifetime (on any thread).
class AllocationCounter {
 public:
  AllocationCounter() : start_(TotalAllocations()) {}
  std::size_t count() const { return TotalAllocations() - start_; }

 private:
  std::size_t start_;
};

}  // namespace testing
}  // namespace structgp

#endif  // STRUCTGP_TESTS_ALLOC_COUNTER_H_
