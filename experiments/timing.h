// Clocks of the experiment programs: CPU time of the process and wall-clock time since a start.

#ifndef STRUCTGP_EXPERIMENTS_TIMING_H_
#define STRUCTGP_EXPERIMENTS_TIMING_H_

#include <chrono>
#include <ctime>

namespace structgp {

// CPU time of this process, all threads, seconds.
inline double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

// Wall-clock seconds from `start` to now (steady clock).
inline double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace structgp

#endif  // STRUCTGP_EXPERIMENTS_TIMING_H_
