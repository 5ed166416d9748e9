#include "structgp/diagnose/autocorrelation.h"

#include <algorithm>
#include <cmath>

namespace structgp {
namespace {

// Largest lag looked at: a quarter of the log, at most 2,000.
int MaxLag(Eigen::Index m) {
  return std::max(1, static_cast<int>(std::min<Eigen::Index>(m / 4, 2000)));
}

}  // namespace

Vector Autocorrelation(const ConstVectorRef& x, const std::vector<int>& segment_starts,
                       int max_lag) {
  const int m = static_cast<int>(x.size());
  Vector rho = Vector::Zero(std::max(0, max_lag) + 1);
  rho[0] = 1.0;
  if (m == 0) return rho;
  const Vector c = x.array() - x.mean();
  const double c0 = c.squaredNorm();
  if (!(c0 > 0.0)) return rho;
  const std::vector<int> starts = segment_starts.empty() ? std::vector<int>{0} : segment_starts;
  for (size_t s = 0; s < starts.size(); ++s) {
    const int b = starts[s], e = s + 1 < starts.size() ? starts[s + 1] : m;
    for (int k = 1; k <= max_lag && k < e - b; ++k) {
      rho[k] += c.segment(b, e - b - k).dot(c.segment(b + k, e - b - k)) / c0;
    }
  }
  return rho;
}

double BartlettInflation(const ConstVectorRef& r, const ConstVectorRef& e,
                         const std::vector<int>& segment_starts) {
  const Eigen::Index m = r.size();
  if (m < 4 || e.size() != m) return 1.0;
  const int K = MaxLag(m);
  const Vector rho_r = Autocorrelation(r, segment_starts, K);
  const double band = 2.0 / std::sqrt(static_cast<double>(m));
  int lags = 0;
  while (lags < K && std::abs(rho_r[lags + 1]) >= band) ++lags;
  if (lags == 0) return 1.0;
  const Vector rho_e = Autocorrelation(e, segment_starts, lags);
  const double c = 1.0 + 2.0 * rho_r.segment(1, lags).dot(rho_e.segment(1, lags));
  return std::isfinite(c) ? std::max(1.0, c) : 1.0;
}

int CorrelationLength(const ConstMatrixRef& R, const std::vector<int>& segment_starts,
                      double level) {
  const int K = MaxLag(R.rows());
  Vector mean = Vector::Zero(K + 1);
  for (Eigen::Index j = 0; j < R.cols(); ++j) mean += Autocorrelation(R.col(j), segment_starts, K);
  mean /= static_cast<double>(std::max<Eigen::Index>(1, R.cols()));
  for (int k = 1; k <= K; ++k) {
    if (mean[k] < level) return k;
  }
  return K;
}

}  // namespace structgp
