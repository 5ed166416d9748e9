#ifndef STRUCTGP_MODEL_KERNEL_GP_H_
#define STRUCTGP_MODEL_KERNEL_GP_H_

/// @file
/// The function-space (kernel) form of a Gaussian process: an exact GP on m stored inputs with
/// any Kernel, P outputs sharing one Cholesky factor.
///
/// Model, for output j with scale s_j:  y_j ~ N(0, s_j^2 (K + sigma_n^2 I)).
/// The model keeps the lower Cholesky factor L of K + sigma_n^2 I (packed by rows, so adding a
/// point appends one row) and beta = L^{-1} Y. Then
///     mean_j(x) = p^T beta_j,  latent variance_j(x) = s_j^2 (k(x, x) - p^T p),  p = L^{-1} k_X(x).
/// Adding a point is one forward substitution, O(m^2); a batch fit is O(m^3).
///
/// Real-time contract: after Reserve(capacity), Add, Predict, PredictWithVariance and
/// AddAndPredict allocate nothing and throw nothing (the kernel's Evaluate must not allocate
/// either); bad input gives kInvalidInput, a full model kCapacityExceeded, and a
/// point whose conditional variance is not positive (a duplicate with tiny noise)
/// kNotPositiveDefinite, each leaving the model unchanged.
///
/// Threads (model apart from workspace): the const predictions take their scratch from a
/// Workspace the caller owns (MakeWorkspace(), one per thread), so one const model may serve
/// concurrent readers whose kernel's Evaluate is thread-safe (every built-in kernel: a
/// FeatureKernel keeps its scratch on the stack, and allocates it per call only beyond 2048
/// features). The overloads without a workspace are non-const and
/// use the model's own scratch (allocation-free, not for concurrent use).
///
/// Memory: Reserve(c) holds c (c + 1) / 2 doubles for L (16 MB at c = 2000, 64 MB at
/// c = 4000) plus c (input_dim + 2 P + 1) doubles. Add, Predict and AddAndPredict stream the
/// first m rows of the packed factor once per call, so once 4 m^2 bytes exceed the last-level
/// cache they are bound by memory bandwidth.

#include <cstddef>
#include <memory>

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/internal/cholesky.h"
#include "structgp/kernel/kernel.h"

namespace structgp {

/// Smallest conditional variance d^2 = k(x,x) + sigma_n^2 - l^T l accepted when a point is
/// added, relative to k(x,x) + sigma_n^2: the pivot floor of the library's factorisation
/// (internal/cholesky.h). Below it the new pivot is lost to rounding. Fit applies the same
/// test to every pivot of its factorisation, without jitter, so a data set is accepted by Fit
/// exactly when adding its points one by one would be (up to rounding).
inline constexpr double kMinRelativePivot = internal::kMinPivotRatio;

class KernelGP {
 public:
  /// kernel: copied (Clone) so the model owns its own. noise_variance > 0. output_scales:
  /// size num_outputs, all > 0, or empty for all 1. Throws std::invalid_argument on bad values.
  KernelGP(const Kernel& kernel, double noise_variance, int num_outputs,
           const Vector& output_scales = Vector());

  int input_dim() const;
  int num_outputs() const { return num_outputs_; }
  /// Number of stored points m.
  int size() const { return size_; }
  int capacity() const { return capacity_; }
  const Kernel& kernel() const { return *kernel_; }
  double noise_variance() const { return noise_variance_; }
  const Vector& output_scales() const { return output_scales_; }

  /// Allocates room for `capacity` points (keeps the stored ones; a capacity not above the
  /// current one does nothing). Not real-time. Throws std::invalid_argument if capacity < 0.
  void Reserve(int capacity);

  /// Batch fit on X (m x input_dim) and Y (m x P); replaces all stored points. Reserves
  /// max(m, capacity()). kNotPositiveDefinite (model unchanged) if K + sigma_n^2 I is not
  /// numerically positive definite (Eigen's LLT fails or a pivot is below kMinRelativePivot)
  /// or when the solve overflows (targets of absurd magnitude). Throws std::invalid_argument on sizes or NaN/Inf (naming the row and column).
  /// O(m^3) time, O(m^2) temporary memory.
  Status Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y);

  /// Appends one point (x: input_dim, y: P), O(m^2), allocation-free within capacity.
  /// kInvalidInput on a wrong size or NaN/Inf, kCapacityExceeded when size() == capacity(),
  /// kNotPositiveDefinite when the new pivot is below kMinRelativePivot, kInvalidInput also
  /// when the new weight overflows (a target of absurd magnitude); the model is unchanged in
  /// each case.
  Status Add(const ConstVectorRef& x, const ConstVectorRef& y);

  /// Scratch of the const predictions: one kernel column (at least size() doubles).
  struct Workspace {
    Vector column;
  };
  /// A workspace for up to capacity() points (capacity() doubles; allocates). After a
  /// Reserve beyond its size, make a new one.
  Workspace MakeWorkspace() const;

  /// Predictive mean (size P) at x. O(m^2) (a forward substitution). kInvalidInput (nothing
  /// written) on a wrong size or NaN/Inf, or a workspace with fewer than size() entries;
  /// kInvalidInput also when the result overflows (the outputs are then not to be used).
  /// With no stored points the prior: mean 0. Allocation-free; safe for concurrent calls
  /// with one workspace each (see the file comment).
  Status Predict(const ConstVectorRef& x, VectorRef mean, Workspace& workspace) const;
  /// Predictive mean, latent and noisy variance (each size P) at x. O(m^2). The latent
  /// variance s_j^2 (k(x,x) - p^T p) is clamped at 0 against rounding; the noisy variance
  /// adds s_j^2 sigma_n^2. kInvalidInput (nothing written) on bad sizes or NaN/Inf.
  Status PredictWithVariance(const ConstVectorRef& x, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance, Workspace& workspace) const;
  /// The same with the model's own workspace (allocation-free; not for concurrent use).
  Status Predict(const ConstVectorRef& x, VectorRef mean) { return Predict(x, mean, own_); }
  Status PredictWithVariance(const ConstVectorRef& x, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance) {
    return PredictWithVariance(x, mean, latent_variance, noisy_variance, own_);
  }

  /// Appends (x, y) and predicts at x_predict with the updated model, reading L once (both
  /// forward substitutions share one pass over the factor). Equal to Add followed by
  /// PredictWithVariance. Pass latent_variance and noisy_variance of size 0 to skip the
  /// variances. On any failure (same statuses as Add, or bad x_predict/output sizes) nothing
  /// is changed or written.
  Status AddAndPredict(const ConstVectorRef& x, const ConstVectorRef& y,
                       const ConstVectorRef& x_predict, VectorRef mean, VectorRef latent_variance,
                       VectorRef noisy_variance);

  /// log p(Y) (sum over outputs). O(m P).
  double LogMarginalLikelihood() const;
  /// log p(Y) and its gradient: d/d kernel parameters (size kernel().num_parameters()),
  /// d/d log sigma_n, d/d log s_j (size P). Any output pointer may be null; the vectors are
  /// resized. O(m^3 + m^2 * num_parameters) time, O(m^2) temporary memory.
  double LogMarginalLikelihood(Vector* d_kernel_parameters, double* d_log_noise_std,
                               Vector* d_log_output_scale) const;

  /// Forgets the newest points: keeps the first m (0 <= m <= size()). O(1), allocation-free,
  /// exact: because the factor is built row by row, its leading m rows and the leading m rows
  /// of beta are those of a model that only ever saw the first m points. Throws
  /// std::invalid_argument when m is out of range.
  void Truncate(int m);

  /// Stored inputs (m x input_dim).
  Matrix inputs() const;
  /// Stored targets (m x P).
  Matrix targets() const;

 private:
  // Writes the weights of a new point m (row l of L, pivot d) into beta_; false when one is not
  // finite (row m is beyond size_, so nothing visible has changed).
  bool NewWeightsOk(const double* l, const ConstVectorRef& y, int m, double d);
  // Packed row-major lower triangle: row i (i + 1 entries, L(i, 0..i)) starts at i*(i+1)/2,
  // independently of the capacity, so growing the storage keeps the stored rows in place.
  static std::ptrdiff_t RowOffset(int i) { return static_cast<std::ptrdiff_t>(i) * (i + 1) / 2; }
  double* row(int i) { return packed_.data() + RowOffset(i); }
  const double* row(int i) const { return packed_.data() + RowOffset(i); }

  // True when v has `size` entries, all finite. Never allocates.
  static bool VectorOk(const ConstVectorRef& v, Eigen::Index size);
  // column[i] = k(x_i, x) for the m stored points. Allocation-free.
  void KernelColumn(const ConstVectorRef& x, int m, double* column) const;
  // Writes mean (and, when latent_variance has size P, the variances) from p = L^{-1} k_X(x)
  // of length size_ and kxx = k(x, x).
  void WritePrediction(const double* p, double kxx, VectorRef mean, VectorRef latent_variance,
                       VectorRef noisy_variance) const;

  std::unique_ptr<Kernel> kernel_;
  double noise_variance_;
  int num_outputs_;
  Vector output_scales_;

  // Invariants: 0 <= size_ <= capacity_; the first size_ rows of the packed factor hold the
  // lower Cholesky factor L of K + sigma_n^2 I of the stored points (positive diagonal);
  // beta_.topRows(size_) = L^{-1} Y. Storage beyond size_ is scratch.
  int size_ = 0;
  int capacity_ = 0;
  Vector packed_;  // L, capacity*(capacity+1)/2
  Matrix inputs_;  // input_dim x capacity (column i = point i, contiguous for the kernel)
  Matrix Y_;       // capacity x P
  Matrix beta_;    // capacity x P, L^{-1} Y (each output's column contiguous)

  Workspace own_;  // of the non-const predictions and AddAndPredict (capacity)
};

}  // namespace structgp

#endif  // STRUCTGP_MODEL_KERNEL_GP_H_
