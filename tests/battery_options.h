#ifndef STRUCTGP_TESTS_BATTERY_OPTIONS_H_
#define STRUCTGP_TESTS_BATTERY_OPTIONS_H_

// The installed feature-map battery (structgp/testing/feature_map_battery.h) with this
// project's allocation counter (alloc_counter.h) plugged in: the plain build asserts that
// Evaluate allocates nothing; a sanitizer build, where the count is incomplete, says why it
// does not.

#include "alloc_counter.h"
#include "structgp/testing/feature_map_battery.h"

namespace structgp {
namespace testing {

inline BatteryOptions CountingBatteryOptions() {
  BatteryOptions options;
  if (CountsEveryAllocation()) {
    options.allocation_count = &TotalAllocations;
  } else {
    options.allocation_note = kIncompleteCountReason;
  }
  return options;
}

}  // namespace testing
}  // namespace structgp

#endif  // STRUCTGP_TESTS_BATTERY_OPTIONS_H_
