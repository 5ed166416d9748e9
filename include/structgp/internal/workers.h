#ifndef STRUCTGP_INTERNAL_WORKERS_H_
#define STRUCTGP_INTERNAL_WORKERS_H_

/// @file
/// Internal: work(0), ..., work(workers - 1) on `workers` threads, work(0) on the calling one.
/// The work items must not wait for each other (no barrier between them): when a thread
/// cannot be started (std::thread throws, e.g. at the system's thread limit), the items it
/// would have run run on the calling thread after work(0), so the results are the same and
/// only the time differs. An exception of any item is rethrown (the first by index) after
/// every thread has been joined.

#include <exception>
#include <thread>
#include <utility>
#include <vector>

namespace structgp {
namespace internal {

/// Starts a thread running `run` (the default of RunWorkers: std::thread). Tests pass one that
/// fails, to exercise the fallback.
struct StartThread {
  template <typename Run>
  std::thread operator()(Run&& run) const {
    return std::thread(std::forward<Run>(run));
  }
};

template <typename Work, typename Start = StartThread>
void RunWorkers(int workers, Work&& work, Start&& start = Start()) {
  std::vector<std::exception_ptr> errors(static_cast<size_t>(workers > 0 ? workers : 0));
  auto guarded = [&](int w) {
    try {
      work(w);
    } catch (...) {
      errors[static_cast<size_t>(w)] = std::current_exception();
    }
  };
  std::vector<std::thread> threads;
  int started = 1;  // items 1..started-1 run on their own threads
  try {
    threads.reserve(static_cast<size_t>(workers > 1 ? workers - 1 : 0));
    for (; started < workers; ++started) threads.push_back(start([&guarded, started] {
      guarded(started);
    }));
  } catch (...) {
    // No thread for items started..workers-1: the calling thread runs them below.
  }
  guarded(0);
  for (int w = started; w < workers; ++w) guarded(w);
  for (auto& t : threads) t.join();
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_INTERNAL_WORKERS_H_
