#include "structgp/kernel/nystrom_feature_map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "feature/trig_tensor.h"
#include "structgp/core/status.h"
#include "structgp/core/validate.h"
#include "structgp/internal/cholesky.h"
#include "structgp/internal/gram.h"
#include "structgp/kernel/pol_kernel.h"

namespace structgp {
namespace {

// Uniform integer in [0, n) from 53 random bits (the same on every platform, unlike
// std::uniform_int_distribution).
Eigen::Index UniformIndex(std::mt19937_64& engine, Eigen::Index n) {
  const double u = static_cast<double>(engine() >> 11) * 0x1.0p-53;
  return std::min(n - 1, static_cast<Eigen::Index>(u * static_cast<double>(n)));
}

Matrix RandomSubset(const ConstMatrixRef& X, int M, std::uint64_t seed) {
  const Eigen::Index m = X.rows();
  std::vector<Eigen::Index> index(static_cast<std::size_t>(m));
  std::iota(index.begin(), index.end(), Eigen::Index{0});
  std::mt19937_64 engine(seed);
  // Partial Fisher-Yates: the first M entries become a uniform random M-subset.
  for (Eigen::Index i = 0; i < M; ++i) {
    const Eigen::Index j = i + UniformIndex(engine, m - i);
    std::swap(index[static_cast<std::size_t>(i)], index[static_cast<std::size_t>(j)]);
  }
  Matrix Z(M, X.cols());
  for (int i = 0; i < M; ++i) Z.row(i) = X.row(index[static_cast<std::size_t>(i)]);
  return Z;
}

Matrix Rows(const ConstMatrixRef& X, const std::vector<Eigen::Index>& chosen) {
  Matrix Z(static_cast<Eigen::Index>(chosen.size()), X.cols());
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    Z.row(static_cast<Eigen::Index>(i)) = X.row(chosen[i]);
  }
  return Z;
}

Matrix FarthestPoint(const Kernel& kernel, const Matrix& Xt, int M, std::uint64_t seed) {
  const Eigen::Index m = Xt.cols();
  Vector diag(m);
  for (Eigen::Index i = 0; i < m; ++i) diag[i] = kernel.Evaluate(Xt.col(i), Xt.col(i));
  std::mt19937_64 engine(seed);
  std::vector<Eigen::Index> chosen;
  chosen.push_back(UniformIndex(engine, m));
  Vector min_distance = Vector::Constant(m, std::numeric_limits<double>::infinity());
  while (static_cast<int>(chosen.size()) < M) {
    const Eigen::Index p = chosen.back();
    for (Eigen::Index i = 0; i < m; ++i) {
      const double d2 = diag[i] + diag[p] - 2.0 * kernel.Evaluate(Xt.col(i), Xt.col(p));
      min_distance[i] = std::min(min_distance[i], std::max(0.0, d2));
    }
    for (const Eigen::Index c : chosen) min_distance[c] = -1.0;
    Eigen::Index next = 0;
    const double best = min_distance.maxCoeff(&next);
    if (!(best > 0.0)) break;  // every remaining candidate duplicates a chosen state
    chosen.push_back(next);
  }
  Matrix Xr = Xt.transpose();
  return Rows(Xr, chosen);
}

Matrix GreedyVariance(const Kernel& kernel, const Matrix& Xt, int M, double min_relative_residual) {
  const Eigen::Index m = Xt.cols();
  Vector residual(m);
  for (Eigen::Index i = 0; i < m; ++i) residual[i] = kernel.Evaluate(Xt.col(i), Xt.col(i));
  const double largest = residual.maxCoeff();
  const double floor = min_relative_residual * std::max(largest, 0.0);
  // Columns of the partial pivoted Cholesky factor of the candidates' Gram matrix.
  Matrix G(m, M);
  std::vector<Eigen::Index> chosen;
  Vector column(m);
  for (int t = 0; t < M; ++t) {
    Eigen::Index p = 0;
    const double best = residual.maxCoeff(&p);
    if (!(best > floor)) break;
    chosen.push_back(p);
    const double pivot = std::sqrt(best);
    for (Eigen::Index i = 0; i < m; ++i) column[i] = kernel.Evaluate(Xt.col(i), Xt.col(p));
    if (t > 0) column.noalias() -= G.leftCols(t) * G.row(p).head(t).transpose();
    G.col(t) = column / pivot;
    residual -= G.col(t).cwiseAbs2();
    residual[p] = -std::numeric_limits<double>::infinity();  // never chosen twice
  }
  Matrix Xr = Xt.transpose();
  return Rows(Xr, chosen);
}

}  // namespace

const char* ToString(InducingSelection selection) {
  switch (selection) {
    case InducingSelection::kRandomSubset:
      return "random";
    case InducingSelection::kFarthestPoint:
      return "farthest_point";
    case InducingSelection::kGreedyVariance:
      return "greedy_variance";
  }
  return "unknown";
}

Matrix SelectInducingStates(const Kernel& kernel, const ConstMatrixRef& X, int M,
                            const InducingOptions& options) {
  if (M < 1) {
    throw std::invalid_argument("SelectInducingStates M: expected at least 1, got " +
                                std::to_string(M));
  }
  if (X.rows() == 0) throw std::invalid_argument("SelectInducingStates: X has no rows");
  RequireSize("SelectInducingStates X", X.cols(), kernel.input_dim(), "columns");
  RequireFinite("SelectInducingStates X", X);
  const int count = static_cast<int>(std::min<Eigen::Index>(M, X.rows()));
  switch (options.selection) {
    case InducingSelection::kRandomSubset:
      return RandomSubset(X, count, options.seed);
    case InducingSelection::kFarthestPoint:
      return FarthestPoint(kernel, X.transpose(), count, options.seed);
    case InducingSelection::kGreedyVariance:
      return GreedyVariance(kernel, X.transpose(), count, options.min_relative_residual);
  }
  throw std::invalid_argument("SelectInducingStates: unknown selection method");
}

NystromFeatureMap::NystromFeatureMap(const Kernel& kernel, const ConstMatrixRef& Z)
    : kernel_(kernel.Clone()) {
  if (Z.rows() < 1) {
    throw std::invalid_argument("NystromFeatureMap: expected at least 1 inducing state, got 0");
  }
  RequireSize("NystromFeatureMap Z", Z.cols(), kernel.input_dim(), "columns");
  RequireFinite("NystromFeatureMap Z", Z);
  inducing_ = Z.transpose();
  Matrix K;
  internal::KernelGram(*kernel_, inducing_, &K);
  if (!K.allFinite()) {
    throw std::runtime_error(
        "NystromFeatureMap: the kernel returned NaN/Inf on the inducing states");
  }
  // The library's factorisation (internal/cholesky.h) with a jitter proportional to the
  // identity, so that the features are those of K_ZZ + jitter I: always at least
  // kNystromRelativeJitter of the mean diagonal, then the ladder's larger rungs.
  internal::CholeskyOptions options;
  options.scale = internal::JitterScale::kMeanDiagonal;
  options.min_jitter = kNystromRelativeJitter;
  internal::Cholesky llt;
  const internal::CholeskyResult result = llt.Factorize(K, options);
  if (result.status != Status::kOk) {
    throw std::runtime_error(
        "NystromFeatureMap: K_ZZ + jitter I is not positive definite even with jitter " +
        std::to_string(result.jitter * internal::MeanDiagonal(K)) +
        " (the kernel is not positive semi-definite on these states?)");
  }
  factor_ = llt.ReleaseFactor();
  jitter_ = result.jitter * internal::MeanDiagonal(K);
  jitter_steps_ = result.steps;
  InitPolFastPath();
}

void NystromFeatureMap::InitPolFastPath() {
  const auto* pol = dynamic_cast<const PolFormulaKernel*>(kernel_.get());
  if (pol == nullptr || pol->num_joints() > kMaxNystromFastPolJoints) return;
  const int n = pol->num_joints();
  const Vector p = pol->parameters();
  // The same constants, computed the same way, as PolFormulaKernel's cache.
  const internal::PolShape shape = internal::MakePolShape(p[PolFormulaKernel::kLogSigma], n);
  pol_theta_ = shape.theta;
  pol_c_psi_ = shape.c_psi;
  pol_scale_inertial_ = std::exp(2.0 * p[PolFormulaKernel::kLogScaleInertial]);
  pol_scale_coriolis_ = std::exp(2.0 * p[PolFormulaKernel::kLogScaleCoriolis]);
  pol_scale_gravity_ =
      pol->options().include_gravity ? std::exp(2.0 * p[PolFormulaKernel::kLogScaleGravity]) : 0.0;
  const Eigen::Index M = inducing_.cols();
  const Eigen::Index stride = Eigen::Index{4} * n;
  pol_table_.assign(static_cast<std::size_t>(stride * M), 0.0);
  for (Eigen::Index i = 0; i < M; ++i) {
    double* row = pol_table_.data() + stride * i;
    for (int j = 0; j < n; ++j) {
      row[j] = std::cos(inducing_(j, i));
      row[n + j] = std::sin(inducing_(j, i));
      row[2 * n + j] = inducing_(n + j, i);
      row[3 * n + j] = inducing_(2 * n + j, i);
    }
  }
  pol_joints_ = n;
}

// k_pol(z_i, x) for every inducing state, term by term as PolFormulaKernel computes it, with
// cos(z - q) from the tabulated cosines and sines.
void NystromFeatureMap::PolKernelColumn(const ConstVectorRef& x, VectorRef column) const {
  const int n = pol_joints_;
  double cos_x[kMaxNystromFastPolJoints];
  double sin_x[kMaxNystromFastPolJoints];
  for (int j = 0; j < n; ++j) {
    cos_x[j] = std::cos(x[j]);
    sin_x[j] = std::sin(x[j]);
  }
  const double* qd_x = x.data() + n;
  const double* qdd_x = x.data() + Eigen::Index{2} * n;
  const double inv_n = 1.0 / n;
  const Eigen::Index M = column.size();
  const Eigen::Index stride = Eigen::Index{4} * n;
  for (Eigen::Index i = 0; i < M; ++i) {
    const double* z = pol_table_.data() + stride * i;
    double r = 1.0;
    double e = 0.0;  // r - 1, accumulated without cancellation
    double qd = 0.0;
    double qdd = 0.0;
    for (int j = 0; j < n; ++j) {
      const double t = pol_theta_ * (z[j] * cos_x[j] + z[n + j] * sin_x[j]);
      r *= 1.0 + t;
      e += t + e * t;
      qd += z[2 * n + j] * qd_x[j];
      qdd += z[3 * n + j] * qdd_x[j];
    }
    const double psi = pol_c_psi_ * r;
    const double psi2 = psi * psi;
    const double k_qdd = qdd * inv_n;
    const double k_qdqd = qd * inv_n * qd * inv_n;
    column[i] = pol_scale_inertial_ * k_qdd * psi2 +
                pol_scale_coriolis_ * pol_theta_ * k_qdqd * psi2 +
                pol_scale_gravity_ * pol_c_psi_ * e;
  }
}

void NystromFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (pol_joints_ == 0) {
    Evaluate(x, phi, *kernel_);
    return;
  }
  if (x.size() != input_dim()) RequireSize("NystromFeatureMap::Evaluate x", x.size(), input_dim());
  if (phi.size() != dim()) RequireSize("NystromFeatureMap::Evaluate phi", phi.size(), dim());
  PolKernelColumn(x, phi);
  factor_.triangularView<Eigen::Lower>().solveInPlace(phi);
}

void NystromFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi,
                                 const Kernel& kernel) const {
  if (x.size() != input_dim()) RequireSize("NystromFeatureMap::Evaluate x", x.size(), input_dim());
  if (phi.size() != dim()) RequireSize("NystromFeatureMap::Evaluate phi", phi.size(), dim());
  if (kernel.input_dim() != input_dim()) {
    RequireSize("NystromFeatureMap::Evaluate kernel input_dim", kernel.input_dim(), input_dim());
  }
  const Eigen::Index M = dim();
  for (Eigen::Index i = 0; i < M; ++i) phi[i] = kernel.Evaluate(inducing_.col(i), x);
  factor_.triangularView<Eigen::Lower>().solveInPlace(phi);
}

std::vector<FeatureBlock> NystromFeatureMap::blocks() const {
  return {FeatureBlock{"nystrom", 0, dim()}};
}

}  // namespace structgp
