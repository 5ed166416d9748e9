#include "structgp/model/kernel_gp.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "structgp/core/validate.h"
#include "structgp/internal/cholesky.h"
#include "structgp/internal/gram.h"
#include "structgp/internal/simd.h"

// The hot loops below are forward substitutions over the packed factor, written with the
// four-lane vectors of internal/simd.h so that the compiler emits packed SSE2 code in the
// baseline build and AVX2/FMA code in the clone chosen at load time (STRUCTGP_TARGET_CLONES).

namespace structgp {
namespace {

constexpr double kLog2Pi = 1.8378770664093454836;  // log(2 pi)

// Distance, in doubles, at which the row being read is prefetched. The passes read the packed
// factor strictly sequentially and the hardware prefetcher follows, but on a Zen 3 machine an
// explicit prefetch 4 KiB ahead made AddAndPredict 10-30% faster at m = 2000 and 4000 (16 and
// 64 MB factors), and left m = 1000 (4 MB, cache resident) within noise.
constexpr int kPrefetchDoubles = 512;

// Every dot product in this file uses this one summation order: two 4-wide partial sums over
// blocks of 8 entries (the last block zero-padded), then a fixed horizontal reduction. The same
// value computed by different routines (a one- or two-right-hand-side solve, the new row of
// AddAndPredict) is therefore bit-identical, which makes AddAndPredict equal to Add followed
// by a prediction.
#if defined(STRUCTGP_HAVE_PACKET4)
using internal::simd::Load4;
using internal::simd::Packet4;
using internal::simd::SumHalves;

STRUCTGP_ALWAYS_INLINE double Dot1(const double* r, const double* a, int n) {
  Packet4 s0 = internal::simd::Splat4(0.0);
  Packet4 s1 = s0;
  int j = 0;
  for (; j + 8 <= n; j += 8) {
    __builtin_prefetch(r + j + kPrefetchDoubles, 0, 3);
    const Packet4 r0 = Load4(r + j);
    const Packet4 r1 = Load4(r + j + 4);
    const Packet4 a0 = Load4(a + j);
    const Packet4 a1 = Load4(a + j + 4);
    s0 += r0 * a0;
    s1 += r1 * a1;
  }
  // The tail (fewer than 8 entries) as one zero-padded block, with the same vector
  // arithmetic as the body, so no entry is summed by a differently rounded scalar path.
  double r_tail[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  double a_tail[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  for (int t = 0; j + t < n; ++t) {
    r_tail[t] = r[j + t];
    a_tail[t] = a[j + t];
  }
  {
    const Packet4 r0 = Load4(r_tail);
    const Packet4 r1 = Load4(r_tail + 4);
    const Packet4 a0 = Load4(a_tail);
    const Packet4 a1 = Load4(a_tail + 4);
    s0 += r0 * a0;
    s1 += r1 * a1;
  }
  const Packet4 s = s0 + s1;
  return SumHalves(s);
}

// Dot1(r, a, n) and Dot1(r, b, n) with one read of r.
STRUCTGP_ALWAYS_INLINE void Dot2(const double* r, const double* a, const double* b, int n,
                                 double* dot_a, double* dot_b) {
  Packet4 sa0 = internal::simd::Splat4(0.0);
  Packet4 sa1 = sa0;
  Packet4 sb0 = sa0;
  Packet4 sb1 = sa0;
  int j = 0;
  for (; j + 8 <= n; j += 8) {
    __builtin_prefetch(r + j + kPrefetchDoubles, 0, 3);
    const Packet4 r0 = Load4(r + j);
    const Packet4 r1 = Load4(r + j + 4);
    const Packet4 a0 = Load4(a + j);
    const Packet4 a1 = Load4(a + j + 4);
    const Packet4 b0 = Load4(b + j);
    const Packet4 b1 = Load4(b + j + 4);
    sa0 += r0 * a0;
    sa1 += r1 * a1;
    sb0 += r0 * b0;
    sb1 += r1 * b1;
  }
  double r_tail[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  double a_tail[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  double b_tail[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  for (int t = 0; j + t < n; ++t) {
    r_tail[t] = r[j + t];
    a_tail[t] = a[j + t];
    b_tail[t] = b[j + t];
  }
  {
    const Packet4 r0 = Load4(r_tail);
    const Packet4 r1 = Load4(r_tail + 4);
    const Packet4 a0 = Load4(a_tail);
    const Packet4 a1 = Load4(a_tail + 4);
    const Packet4 b0 = Load4(b_tail);
    const Packet4 b1 = Load4(b_tail + 4);
    sa0 += r0 * a0;
    sa1 += r1 * a1;
    sb0 += r0 * b0;
    sb1 += r1 * b1;
  }
  const Packet4 sa = sa0 + sa1;
  const Packet4 sb = sb0 + sb1;
  *dot_a = SumHalves(sa);
  *dot_b = SumHalves(sb);
}
#else
STRUCTGP_ALWAYS_INLINE double Dot1(const double* r, const double* a, int n) {
  double sum = 0.0;
  for (int j = 0; j < n; ++j) sum += r[j] * a[j];
  return sum;
}
STRUCTGP_ALWAYS_INLINE void Dot2(const double* r, const double* a, const double* b, int n,
                                 double* dot_a, double* dot_b) {
  *dot_a = Dot1(r, a, n);
  *dot_b = Dot1(r, b, n);
}
#endif

// x^T y over n entries, in the order of Dot1.
STRUCTGP_TARGET_CLONES
double Dot(const double* x, const double* y, int n) { return Dot1(x, y, n); }

// In place a <- L^{-1} a over the first m rows of the packed factor (dot-product form: row i
// is one contiguous read). One pass over m (m + 1) / 2 doubles.
STRUCTGP_TARGET_CLONES
void PackedForwardSolve(const double* packed, int m, double* a) {
  const double* r = packed;
  for (int i = 0; i < m; ++i) {
    a[i] = (a[i] - Dot1(r, a, i)) / r[i];
    r += i + 1;
  }
}

// In place a <- L^{-1} a and b <- L^{-1} b with one pass over the packed factor; each result
// is bit-identical to PackedForwardSolve's.
STRUCTGP_TARGET_CLONES
void PackedForwardSolve2(const double* packed, int m, double* a, double* b) {
  const double* r = packed;
  for (int i = 0; i < m; ++i) {
    double dot_a, dot_b;
    Dot2(r, a, b, i, &dot_a, &dot_b);
    const double pivot = r[i];
    a[i] = (a[i] - dot_a) / pivot;
    b[i] = (b[i] - dot_b) / pivot;
    r += i + 1;
  }
}

// True when the squared pivot d2 of a row whose diagonal entry of K + sigma_n^2 I is
// `diagonal` is accepted (false for NaN too): the acceptance test of internal/cholesky.h.
bool PivotOk(double d2, double diagonal) {
  return d2 >= kMinRelativePivot * diagonal && std::isfinite(d2);
}

}  // namespace

KernelGP::KernelGP(const Kernel& kernel, double noise_variance, int num_outputs,
                   const Vector& output_scales)
    : kernel_(kernel.Clone()),
      noise_variance_(noise_variance),
      num_outputs_(num_outputs),
      output_scales_(output_scales) {
  RequireInRange("KernelGP noise_variance", noise_variance, 0.0,
                 std::numeric_limits<double>::infinity());
  if (num_outputs < 1) {
    throw std::invalid_argument("KernelGP num_outputs: expected at least 1, got " +
                                std::to_string(num_outputs));
  }
  if (output_scales_.size() == 0) output_scales_ = Vector::Ones(num_outputs);
  RequireSize("KernelGP output_scales", output_scales_.size(), num_outputs);
  for (Eigen::Index j = 0; j < output_scales_.size(); ++j) {
    RequireInRange("KernelGP output_scales[" + std::to_string(j) + "]", output_scales_[j], 0.0,
                   std::numeric_limits<double>::infinity());
  }
  inputs_.resize(kernel_->input_dim(), 0);
  Y_.resize(0, num_outputs_);
  beta_.resize(0, num_outputs_);
}

int KernelGP::input_dim() const { return kernel_->input_dim(); }

void KernelGP::Reserve(int capacity) {
  if (capacity < 0) {
    throw std::invalid_argument("KernelGP::Reserve: expected a capacity >= 0, got " +
                                std::to_string(capacity));
  }
  if (capacity <= capacity_) return;
  // conservativeResize keeps the stored entries: the packed rows do not depend on the
  // capacity, and the leading rows/columns of the other arrays keep their indices.
  packed_.conservativeResize(RowOffset(capacity));
  inputs_.conservativeResize(Eigen::NoChange, capacity);
  Y_.conservativeResize(capacity, Eigen::NoChange);
  beta_.conservativeResize(capacity, Eigen::NoChange);
  own_.column.resize(capacity);
  capacity_ = capacity;
}

bool KernelGP::VectorOk(const ConstVectorRef& v, Eigen::Index size) {
  return v.size() == size && v.allFinite();
}

void KernelGP::KernelColumn(const ConstVectorRef& x, int m, double* column) const {
  for (int i = 0; i < m; ++i) column[i] = kernel_->Evaluate(inputs_.col(i), x);
}

Status KernelGP::Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y) {
  RequireSize("KernelGP::Fit X", X.cols(), input_dim(), "columns");
  RequireSize("KernelGP::Fit Y", Y.cols(), num_outputs_, "columns");
  RequireSize("KernelGP::Fit Y", Y.rows(), X.rows(), "rows (one per row of X)");
  RequireFinite("KernelGP::Fit X", X);
  RequireFinite("KernelGP::Fit Y", Y);
  const int m = static_cast<int>(X.rows());

  // C = K + sigma_n^2 I, with the argument order of Add (earlier point first).
  const Matrix points = X.transpose();
  Matrix C;
  internal::KernelGram(*kernel_, points, &C);
  C.diagonal().array() += noise_variance_;
  // The library's factorisation without jitter (the model is the exact posterior): its pivot
  // test is the one Add applies to a new point (PivotOk).
  internal::CholeskyOptions options;
  options.ladder = internal::JitterLadder::kNone;
  internal::Cholesky llt(m);
  if (llt.Factorize(C, options).status != Status::kOk) return Status::kNotPositiveDefinite;
  const Matrix& factor = llt.factor();  // lower triangle is L
  const Matrix beta = llt.matrixL().solve(Y);
  // Targets of absurd (finite) magnitude can overflow the solve: refuse rather than store inf.
  if (!beta.allFinite()) return Status::kNotPositiveDefinite;

  Reserve(std::max(m, capacity_));
  for (int i = 0; i < m; ++i) {
    Eigen::Map<Vector>(row(i), i + 1) = factor.row(i).head(i + 1).transpose();
  }
  inputs_.leftCols(m) = points;
  Y_.topRows(m) = Y;
  beta_.topRows(m) = beta;
  size_ = m;
  return Status::kOk;
}

Status KernelGP::Add(const ConstVectorRef& x, const ConstVectorRef& y) {
  if (!VectorOk(x, input_dim()) || !VectorOk(y, num_outputs_)) return Status::kInvalidInput;
  const int m = size_;
  if (m >= capacity_) return Status::kCapacityExceeded;

  // The new row is built in place in the (unused) storage of row m: l = L^{-1} k_X(x).
  double* l = row(m);
  KernelColumn(x, m, l);
  PackedForwardSolve(packed_.data(), m, l);
  const double diagonal = kernel_->Evaluate(x, x) + noise_variance_;
  const double d2 = diagonal - Dot(l, l, m);
  if (!PivotOk(d2, diagonal)) return Status::kNotPositiveDefinite;
  const double d = std::sqrt(d2);

  // Row m lies beyond size_ until the end: an early return leaves the model unchanged.
  l[m] = d;
  if (!NewWeightsOk(l, y, m, d)) return Status::kInvalidInput;
  inputs_.col(m) = x;
  Y_.row(m) = y.transpose();
  size_ = m + 1;
  return Status::kOk;
}

bool KernelGP::NewWeightsOk(const double* l, const ConstVectorRef& y, int m, double d) {
  for (int j = 0; j < num_outputs_; ++j) {
    double* beta_j = beta_.col(j).data();
    beta_j[m] = (y[j] - Dot(l, beta_j, m)) / d;
    if (!std::isfinite(beta_j[m])) return false;
  }
  return true;
}

void KernelGP::WritePrediction(const double* p, double kxx, VectorRef mean,
                               VectorRef latent_variance, VectorRef noisy_variance) const {
  const int m = size_;
  for (int j = 0; j < num_outputs_; ++j) mean[j] = Dot(p, beta_.col(j).data(), m);
  if (latent_variance.size() == 0) return;
  const double reduced = std::max(kxx - Dot(p, p, m), 0.0);
  for (int j = 0; j < num_outputs_; ++j) {
    const double s2 = output_scales_[j] * output_scales_[j];
    latent_variance[j] = s2 * reduced;
    noisy_variance[j] = s2 * (reduced + noise_variance_);
  }
}

KernelGP::Workspace KernelGP::MakeWorkspace() const { return Workspace{Vector(capacity_)}; }

Status KernelGP::Predict(const ConstVectorRef& x, VectorRef mean, Workspace& workspace) const {
  if (!VectorOk(x, input_dim()) || mean.size() != num_outputs_ ||
      workspace.column.size() < size_) {
    return Status::kInvalidInput;
  }
  double* p = workspace.column.data();
  KernelColumn(x, size_, p);
  PackedForwardSolve(packed_.data(), size_, p);
  for (int j = 0; j < num_outputs_; ++j) mean[j] = Dot(p, beta_.col(j).data(), size_);
  return mean.allFinite() ? Status::kOk : Status::kInvalidInput;
}

Status KernelGP::PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                                     VectorRef latent_variance, VectorRef noisy_variance,
                                     Workspace& workspace) const {
  if (!VectorOk(x, input_dim()) || mean.size() != num_outputs_ ||
      latent_variance.size() != num_outputs_ || noisy_variance.size() != num_outputs_ ||
      workspace.column.size() < size_) {
    return Status::kInvalidInput;
  }
  double* p = workspace.column.data();
  KernelColumn(x, size_, p);
  PackedForwardSolve(packed_.data(), size_, p);
  WritePrediction(p, kernel_->Evaluate(x, x), mean, latent_variance, noisy_variance);
  return mean.allFinite() && latent_variance.allFinite() ? Status::kOk : Status::kInvalidInput;
}

Status KernelGP::AddAndPredict(const ConstVectorRef& x, const ConstVectorRef& y,
                               const ConstVectorRef& x_predict, VectorRef mean,
                               VectorRef latent_variance, VectorRef noisy_variance) {
  const bool with_variance = latent_variance.size() != 0 || noisy_variance.size() != 0;
  if (!VectorOk(x, input_dim()) || !VectorOk(y, num_outputs_) ||
      !VectorOk(x_predict, input_dim()) || mean.size() != num_outputs_ ||
      (with_variance &&
       (latent_variance.size() != num_outputs_ || noisy_variance.size() != num_outputs_))) {
    return Status::kInvalidInput;
  }
  const int m = size_;
  if (m >= capacity_) return Status::kCapacityExceeded;

  // l = L^{-1} k_X(x) in the storage of row m, p = L^{-1} k_X(x_predict) in own_.column, both in
  // one pass over L.
  double* l = row(m);
  double* p = own_.column.data();
  KernelColumn(x, m, l);
  KernelColumn(x_predict, m, p);
  PackedForwardSolve2(packed_.data(), m, l, p);
  const double diagonal = kernel_->Evaluate(x, x) + noise_variance_;
  const double d2 = diagonal - Dot(l, l, m);
  if (!PivotOk(d2, diagonal)) return Status::kNotPositiveDefinite;
  const double d = std::sqrt(d2);

  // Commit the new point (as Add does), then extend p by the new row of L.
  l[m] = d;
  if (!NewWeightsOk(l, y, m, d)) return Status::kInvalidInput;
  inputs_.col(m) = x;
  Y_.row(m) = y.transpose();
  size_ = m + 1;
  p[m] = (kernel_->Evaluate(inputs_.col(m), x_predict) - Dot(l, p, m)) / d;

  WritePrediction(p, with_variance ? kernel_->Evaluate(x_predict, x_predict) : 0.0, mean,
                  latent_variance, noisy_variance);
  return Status::kOk;
}

void KernelGP::Truncate(int m) {
  if (m < 0 || m > size_) {
    throw std::invalid_argument("KernelGP::Truncate: expected 0 <= m <= " + std::to_string(size_) +
                                ", got " + std::to_string(m));
  }
  size_ = m;
}

double KernelGP::LogMarginalLikelihood() const {
  const int m = size_;
  double log_det = 0.0;  // sum_i log L_ii
  for (int i = 0; i < m; ++i) log_det += std::log(row(i)[i]);
  double value = -num_outputs_ * log_det - 0.5 * m * num_outputs_ * kLog2Pi;
  for (int j = 0; j < num_outputs_; ++j) {
    const double s = output_scales_[j];
    value -= 0.5 * beta_.col(j).head(m).squaredNorm() / (s * s) + m * std::log(s);
  }
  return value;
}

double KernelGP::LogMarginalLikelihood(Vector* d_kernel_parameters, double* d_log_noise_std,
                                       Vector* d_log_output_scale) const {
  const int m = size_;
  const int num_parameters = kernel_->num_parameters();
  if (d_log_output_scale != nullptr) {
    // log p(y_j) = -||beta_j||^2 / (2 s_j^2) - m log s_j + (terms free of s_j).
    d_log_output_scale->resize(num_outputs_);
    for (int j = 0; j < num_outputs_; ++j) {
      const double s = output_scales_[j];
      (*d_log_output_scale)[j] = beta_.col(j).head(m).squaredNorm() / (s * s) - m;
    }
  }
  if (d_kernel_parameters != nullptr || d_log_noise_std != nullptr) {
    // With C = K + sigma_n^2 I and alpha_j = (s_j^2 C)^{-1} y_j, summed over outputs:
    //   d log p / d theta = 0.5 tr(W dC/d theta),  W = sum_j s_j^2 alpha_j alpha_j^T - P C^{-1},
    // where s_j^2 alpha_j = L^{-T} beta_j and C^{-1} = L^{-T} L^{-1}.
    Matrix L = Matrix::Zero(m, m);
    for (int i = 0; i < m; ++i) L.row(i).head(i + 1) = Eigen::Map<const Vector>(row(i), i + 1);
    Matrix W = internal::InverseFromFactor(L);
    W *= -static_cast<double>(num_outputs_);
    Matrix scaled_alpha = beta_.topRows(m);  // -> s_j^2 alpha_j = L^{-T} beta_j
    L.transpose().triangularView<Eigen::Upper>().solveInPlace(scaled_alpha);
    for (int j = 0; j < num_outputs_; ++j) {
      const double s = output_scales_[j];
      W.noalias() += scaled_alpha.col(j) * scaled_alpha.col(j).transpose() / (s * s);
    }
    if (d_log_noise_std != nullptr) {
      // dC / d log sigma_n = 2 sigma_n^2 I.
      *d_log_noise_std = noise_variance_ * W.trace();
    }
    if (d_kernel_parameters != nullptr) {
      d_kernel_parameters->setZero(num_parameters);
      Vector dk(num_parameters);
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j <= i; ++j) {
          kernel_->Gradient(inputs_.col(j), inputs_.col(i), dk);
          // W and dK are symmetric: each off-diagonal pair appears twice in the trace.
          const double weight = (i == j ? 0.5 : 1.0) * W(i, j);
          *d_kernel_parameters += weight * dk;
        }
      }
    }
  }
  return LogMarginalLikelihood();
}

Matrix KernelGP::inputs() const { return inputs_.leftCols(size_).transpose(); }

Matrix KernelGP::targets() const { return Y_.topRows(size_); }

}  // namespace structgp
