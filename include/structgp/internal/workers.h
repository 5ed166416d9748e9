#ifndef STRUCTGP_INTERNAL_WORKERS_H_
#define STRUCTGP_INTERNAL_WORKERS_H_

/// @file
/// Internal: work(0), ..., work(workers - 1) on `workers` threads, work(0) on the calling one.
/// An exception of any of them is rethrown (the first by index) after every thread has been
/// joined; so is a failure to start a thread, after the ones started are joined.

#include <exception>
#include <thread>
#include <vector>

namespace structgp {
namespace internal {

template <typename Work>
void RunWorkers(int workers, Work&& work) {
  std::vector<std::exception_ptr> errors(static_cast<size_t>(workers));
  auto guarded = [&](int w) {
    try {
      work(w);
    } catch (...) {
      errors[static_cast<size_t>(w)] = std::current_exception();
    }
  };
  std::vector<std::thread> threads;
  threads.reserve(static_cast<size_t>(workers > 1 ? workers - 1 : 0));
  try {
    for (int w = 1; w < workers; ++w) threads.emplace_back(guarded, w);
  } catch (...) {
    for (auto& t : threads) t.join();
    throw;
  }
  guarded(0);
  for (auto& t : threads) t.join();
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_INTERNAL_WORKERS_H_
