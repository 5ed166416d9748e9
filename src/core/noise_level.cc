#include "structgp/core/noise_level.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace structgp {

double NoiseFromDifferences(const ConstVectorRef& x, const std::vector<int>& segment_starts) {
  std::vector<double> d;
  for (size_t s = 0; s < segment_starts.size(); ++s) {
    const Eigen::Index begin = segment_starts[s];
    const Eigen::Index end =
        s + 1 < segment_starts.size() ? segment_starts[s + 1] : x.size();
    for (Eigen::Index i = begin; i + 1 < end; ++i) d.push_back(std::abs(x[i + 1] - x[i]));
  }
  if (d.empty()) return 0.0;
  auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  return *mid / (0.6744897501960817 * std::sqrt(2.0));
}

}  // namespace structgp
