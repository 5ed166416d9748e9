#include "structgp/core/segments.h"

#include <cstdlib>
#include <stdexcept>
#include <string>

namespace structgp {

std::vector<int> SegmentStarts(const ConstVectorRef& t) {
  std::vector<int> starts{0};
  for (Eigen::Index i = 1; i < t.size(); ++i) {
    if (t[i] < t[i - 1]) starts.push_back(static_cast<int>(i));
  }
  return starts;
}

std::vector<std::pair<int, int>> ContiguousFolds(int m, int k) {
  if (k < 1 || k > m) {
    throw std::invalid_argument("ContiguousFolds: expected 1 <= k <= m, got k = " +
                                std::to_string(k) + ", m = " + std::to_string(m));
  }
  std::vector<std::pair<int, int>> folds;
  folds.reserve(static_cast<size_t>(k));
  const auto boundary = [m, k](int f) {
    return static_cast<int>(static_cast<long long>(f) * m / k);
  };
  for (int f = 0; f < k; ++f) folds.emplace_back(boundary(f), boundary(f + 1));
  return folds;
}

std::vector<std::pair<int, int>> SegmentFolds(int m, int k, const std::vector<int>& starts) {
  std::vector<std::pair<int, int>> plain = ContiguousFolds(m, k);
  if (starts.empty() || starts.front() != 0) {
    throw std::invalid_argument("SegmentFolds: segment starts must begin with row 0");
  }
  for (size_t s = 1; s < starts.size(); ++s) {
    if (starts[s] <= starts[s - 1] || starts[s] >= m) {
      throw std::invalid_argument("SegmentFolds: segment starts must increase within [0, " +
                                  std::to_string(m) + "), got " + std::to_string(starts[s]) +
                                  " after " + std::to_string(starts[s - 1]));
    }
  }
  const int num_segments = static_cast<int>(starts.size());
  if (num_segments < k) return plain;
  // Fold f begins at segment b[f]: the segment start nearest to the plain boundary, at least one
  // segment after the previous fold's and leaving one for each fold after it.
  std::vector<int> first(static_cast<size_t>(k), 0);
  for (int f = 1; f < k; ++f) {
    const int target = plain[static_cast<size_t>(f)].first;
    int best = first[static_cast<size_t>(f - 1)] + 1;
    for (int s = best; s <= num_segments - (k - f); ++s) {
      if (std::abs(starts[static_cast<size_t>(s)] - target) <
          std::abs(starts[static_cast<size_t>(best)] - target)) {
        best = s;
      }
    }
    first[static_cast<size_t>(f)] = best;
  }
  std::vector<std::pair<int, int>> folds;
  for (int f = 0; f < k; ++f) {
    const int begin = starts[static_cast<size_t>(first[static_cast<size_t>(f)])];
    const int end = f + 1 < k ? starts[static_cast<size_t>(first[static_cast<size_t>(f + 1)])] : m;
    folds.emplace_back(begin, end);
  }
  return folds;
}

}  // namespace structgp
