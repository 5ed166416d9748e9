#include "structgp/diagnose/autocorrelation.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Eigenvalues>

namespace structgp {
namespace {

// Largest lag looked at: a quarter of the log, at most 2,000.
int MaxLag(Eigen::Index m) {
  return std::max(1, static_cast<int>(std::min<Eigen::Index>(m / 4, 2000)));
}

// Each segment of rows 0..m-1 as [begin, end); no starts: one segment.
std::vector<std::pair<int, int>> SegmentRanges(const std::vector<int>& segment_starts, int m) {
  const std::vector<int> starts = segment_starts.empty() ? std::vector<int>{0} : segment_starts;
  std::vector<std::pair<int, int>> ranges;
  for (size_t s = 0; s < starts.size(); ++s) {
    ranges.emplace_back(starts[s], s + 1 < starts.size() ? starts[s + 1] : m);
  }
  return ranges;
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
  for (const auto& [b, e] : SegmentRanges(segment_starts, m)) {
    for (int k = 1; k <= max_lag && k < e - b; ++k) {
      rho[k] += c.segment(b, e - b - k).dot(c.segment(b + k, e - b - k)) / c0;
    }
  }
  return rho;
}

namespace {

// Lags 1..lags at which r's autocorrelation is distinguishable from zero (|rho| >= 2 / sqrt(m)),
// up to MaxLag: the first lag below that band ends them.
int CorrelatedLags(const ConstVectorRef& r, const std::vector<int>& segment_starts) {
  const Eigen::Index m = r.size();
  const int K = MaxLag(m);
  const Vector rho_r = Autocorrelation(r, segment_starts, K);
  const double band = 2.0 / std::sqrt(static_cast<double>(m));
  int lags = 0;
  while (lags < K && std::abs(rho_r[lags + 1]) >= band) ++lags;
  return lags;
}

// 1 + 2 sum_{k=1..lags} rho_r(k) rho_e(k), at least 1.
double BartlettSum(const ConstVectorRef& r, const ConstVectorRef& e,
                   const std::vector<int>& segment_starts, int lags) {
  if (lags <= 0) return 1.0;
  const Vector rho_r = Autocorrelation(r, segment_starts, lags);
  const Vector rho_e = Autocorrelation(e, segment_starts, lags);
  const double c = 1.0 + 2.0 * rho_r.segment(1, lags).dot(rho_e.segment(1, lags));
  return std::isfinite(c) ? std::max(1.0, c) : 1.0;
}

}  // namespace

double BartlettInflation(const ConstVectorRef& r, const ConstVectorRef& e,
                         const std::vector<int>& segment_starts) {
  const Eigen::Index m = r.size();
  if (m < 4 || e.size() != m) return 1.0;
  return BartlettSum(r, e, segment_starts, CorrelatedLags(r, segment_starts));
}

Autoregression FitAutoregression(const ConstVectorRef& x, const std::vector<int>& segment_starts,
                                 int max_order) {
  Autoregression ar;
  const Eigen::Index m = x.size();
  const int P = static_cast<int>(std::max<Eigen::Index>(0, std::min<Eigen::Index>(max_order, m / 10)));
  if (P == 0) return ar;
  const Vector rho = Autocorrelation(x, segment_starts, P);
  // Levinson-Durbin: the order-p coefficients from the order-(p - 1) ones; v is the
  // innovation variance over Var(x). The sample autocorrelation (every lag over the same c0)
  // is positive definite, so |kappa| < 1 while the recursion is exact.
  Vector previous, phi;
  double v = 1.0, best_aic = 0.0;
  for (int p = 1; p <= P; ++p) {
    double acc = rho[p];
    for (int k = 1; k < p; ++k) acc -= previous[k - 1] * rho[p - k];
    const double kappa = acc / v;
    if (!std::isfinite(kappa) || std::abs(kappa) >= 1.0) break;
    phi.resize(p);
    for (int k = 1; k < p; ++k) phi[k - 1] = previous[k - 1] - kappa * previous[p - k - 1];
    phi[p - 1] = kappa;
    v *= 1.0 - kappa * kappa;
    if (!(v > 0.0)) break;
    const double aic = static_cast<double>(m) * std::log(v) + 2.0 * p;
    if (aic < best_aic) {
      best_aic = aic;
      ar.phi = phi;
      ar.innovation_variance_ratio = v;
    }
    previous = phi;
  }
  return ar;
}

namespace {

// The starts of the segments of a filtered series (Prewhiten: p rows fewer per segment, the
// segments of p rows or fewer gone), and its row count last.
std::vector<int> FilteredStarts(const std::vector<int>& segment_starts, int m, int p) {
  std::vector<int> starts;
  int row = 0;
  for (const auto& [b, e] : SegmentRanges(segment_starts, m)) {
    if (e - b > p) {
      starts.push_back(row);
      row += e - b - p;
    }
  }
  starts.push_back(row);
  return starts;
}

}  // namespace

Matrix Prewhiten(const ConstMatrixRef& x, const Vector& phi,
                 const std::vector<int>& segment_starts) {
  const int m = static_cast<int>(x.rows());
  const int p = static_cast<int>(phi.size());
  Matrix out(FilteredStarts(segment_starts, m, p).back(), x.cols());
  Eigen::Index o = 0;
  for (const auto& [b, e] : SegmentRanges(segment_starts, m)) {
    for (int t = b + p; t < e; ++t, ++o) {
      out.row(o) = x.row(t);
      for (int k = 1; k <= p; ++k) out.row(o) -= phi[k - 1] * x.row(t - k);
    }
  }
  return out;
}

namespace {

// r^T E (E^T E)^+ E^T r: the part of r's square that the columns of E explain.
double ProjectedSquare(const ConstMatrixRef& E, const ConstVectorRef& r) {
  const Matrix G = E.transpose() * E;
  const Vector b = E.transpose() * r;
  const Eigen::SelfAdjointEigenSolver<Matrix> es(G);
  if (es.info() != Eigen::Success) return 0.0;
  const double top = es.eigenvalues().cwiseAbs().maxCoeff();
  double sum = 0.0;
  for (Eigen::Index i = 0; i < G.rows(); ++i) {
    const double lambda = es.eigenvalues()[i];
    if (lambda > 1e-10 * top) {
      const double c = es.eigenvectors().col(i).dot(b);
      sum += c * c / lambda;
    }
  }
  return sum;
}

}  // namespace

double PrewhiteningInflation(const ConstVectorRef& r_before, const ConstVectorRef& r_after,
                             const ConstMatrixRef& E, const std::vector<int>& segment_starts,
                             int max_order) {
  const Eigen::Index m = r_before.size();
  if (m < 4 || r_after.size() != m || E.rows() != m || E.cols() == 0) return 1.0;
  const Autoregression ar = FitAutoregression(r_after, segment_starts, max_order);
  if (ar.phi.size() == 0) return 1.0;
  const Vector centred = r_after.array() - r_after.mean();
  const double variance = centred.squaredNorm() / static_cast<double>(m);
  const double white = ProjectedSquare(E, r_before) / variance;
  if (!(white > 0.0) || !std::isfinite(white)) return 1.0;
  // The candidate's columns, the residual before and the centred residual after, filtered
  // together.
  const Eigen::Index k = E.cols();
  Matrix columns(m, k + 2);
  columns << E, r_before, centred;
  const Matrix filtered = Prewhiten(columns, ar.phi, segment_starts);
  const auto Ew = filtered.leftCols(k);
  const auto uw = filtered.col(k + 1);
  if (uw.size() < 2) return 1.0;
  const double innovation = uw.squaredNorm() / static_cast<double>(uw.size());
  const double whitened = ProjectedSquare(Ew, filtered.col(k)) / innovation;
  // What the AR model leaves correlated (a wander slower than its order reaches): Bartlett's
  // factor of the filtered residual against each filtered column, on the filtered segments.
  std::vector<int> filtered_starts = FilteredStarts(
      segment_starts, static_cast<int>(m), static_cast<int>(ar.phi.size()));
  filtered_starts.pop_back();  // the row count
  // Over the lags at which the residual itself is correlated: after a good filter each
  // filtered autocorrelation is small, but a wander the filter misses leaves small ones at
  // many lags, which together count (each alone would fall inside the white-noise band).
  const int lags = std::min(CorrelatedLags(r_after, segment_starts),
                            MaxLag(uw.size()));
  double residual_correlation = 1.0;
  for (Eigen::Index c = 0; c < k; ++c) {
    residual_correlation = std::max(
        residual_correlation, BartlettSum(uw, Ew.col(c), filtered_starts, lags));
  }
  // An effect the filter takes away entirely: no evidence left (a finite factor, for JSON).
  const double c = white / std::max(whitened, 1e-12 * white) * residual_correlation;
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
