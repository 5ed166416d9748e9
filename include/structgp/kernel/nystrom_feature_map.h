#ifndef STRUCTGP_KERNEL_NYSTROM_FEATURE_MAP_H_
#define STRUCTGP_KERNEL_NYSTROM_FEATURE_MAP_H_

/// @file
/// Nystrom features: a reduced explicit feature map of any kernel, for online learning when
/// the exact map is too wide (k_pol has 422,603 features at N = 6; docs/feature_maps.md).
///
/// Given M inducing states Z = (z_1, ..., z_M) and the lower Cholesky factor
/// L L^T = K_ZZ + jitter I of their Gram matrix,
///
///     phi(x) = L^{-1} k_Z(x),    k_Z(x) = (k(z_1, x), ..., k(z_M, x)),    dim() = M,
///
/// with unit prior variances. Then phi(a)^T phi(b) = k_Z(a)^T (K_ZZ + jitter I)^{-1} k_Z(b),
/// the Nystrom approximation of k(a, b): the kernel of the GP conditioned on exact values at Z
/// (the "subset of regressors" / DTC model with whitened weights). It never exceeds the exact
/// kernel: k(x, x) - |phi(x)|^2 >= 0, and K - Phi Phi^T is positive semi-definite; at
/// x = z_i the approximation is exact up to the jitter. A WeightSpaceGP on phi with
/// Lambda = 1 is the same model as a KernelGP with this approximate kernel, at O(M^2) per
/// online step instead of O(m^2).
///
/// The kernel's hyper-parameters are frozen into the features (changing them changes phi), so
/// the map has no shape parameters; its output scale and noise belong to the model. One block,
/// "nystrom".
///
/// Evaluate costs M kernel evaluations and a triangular solve, M^2 / 2 multiply-adds; it needs
/// no scratch beyond phi itself (the kernel column is written into phi and solved in place) and
/// never allocates. For PolFormulaKernel (up to kMaxNystromFastPolJoints joints) the kernel
/// column is computed by a specialised loop: the cosines and sines of the inducing states'
/// angles are tabulated at construction and cos(q_n - z_n) = cos q_n cos z_n + sin q_n sin z_n,
/// so one evaluation needs 2N trigonometric calls instead of N M. At N = 6, M = 512 this makes
/// the kernel column several times cheaper than M kernel calls and the whole evaluation, then
/// dominated by the triangular solve, about twice as fast; the results agree to rounding.
///
/// Concurrency: the generic path calls the kernel's Evaluate, so concurrent calls are safe
/// exactly when that is (the k_pol path does not call the kernel and is always safe).
/// Every built-in kernel is safe (FeatureKernel keeps its scratch on the stack); for a kernel
/// of your own that is not, give each thread its own copy of the kernel (Kernel::Clone) and use
/// the Evaluate(x, phi, kernel) overload.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/kernel/kernel.h"

namespace structgp {

/// Jitter always added, relative to the mean diagonal of K_ZZ (a regularisation that is part of
/// the features; when it is not enough, the library's jitter ladder continues with its larger
/// rungs, 1e-7 and 1e-5: internal/cholesky.h, docs/reliability.md). The features stay bounded
/// whatever the jitter (|phi(x)|^2 <= k(x, x)); the jitter only has to make the factorisation
/// succeed when K_ZZ is singular to rounding (duplicate states, a finite-rank kernel with more
/// inducing states than its rank). Rounding errors along K_ZZ's null directions,
/// ~eps |K|, are amplified by at most 1 / sqrt(jitter): ~1e-12 relative at this level.
inline constexpr double kNystromRelativeJitter = 1e-8;
/// Largest number of joints of the specialised k_pol kernel column (its per-call trigonometric
/// values live on the stack); larger robots use the generic path.
inline constexpr int kMaxNystromFastPolJoints = 16;

/// How inducing states are chosen among candidate states.
enum class InducingSelection {
  /// M distinct candidates uniformly at random.
  kRandomSubset,
  /// Greedy farthest point in the kernel distance d(x, z)^2 = k(x,x) + k(z,z) - 2 k(x,z):
  /// a random first state, then repeatedly the candidate farthest from the chosen set.
  /// O(m M) kernel evaluations.
  kFarthestPoint,
  /// Greedy maximum residual variance (pivoted Cholesky of the candidates' Gram matrix): each
  /// step takes the candidate worst explained by the states chosen so far,
  /// argmax k(x,x) - k_Z(x)^T K_ZZ^{-1} k_Z(x). It greedily minimises the trace of the
  /// Nystrom error on the candidates. O(m M) kernel evaluations and O(m M^2) flops, m M
  /// doubles of memory. Deterministic (the seed is not used).
  kGreedyVariance,
};

/// Stable name ("random", "farthest_point", "greedy_variance").
const char* ToString(InducingSelection selection);

struct InducingOptions {
  InducingSelection selection = InducingSelection::kGreedyVariance;
  /// Seed of kRandomSubset and of kFarthestPoint's first state (std::mt19937_64).
  std::uint64_t seed = 1;
  /// kGreedyVariance stops early, returning fewer than M states, when the largest residual
  /// variance falls below this fraction of the largest k(x, x): every remaining candidate is
  /// then explained to rounding, and more states would only add near-duplicate directions.
  double min_relative_residual = 1e-12;
};

/// Chooses up to M inducing states among the rows of X (m x kernel.input_dim()); returns them
/// as rows (M' x input_dim, M' = min(M, m), or fewer with kGreedyVariance's early stop).
/// Throws std::invalid_argument on M < 1, an empty X, a column mismatch or NaN/Inf in X.
Matrix SelectInducingStates(const Kernel& kernel, const ConstMatrixRef& X, int M,
                            const InducingOptions& options = InducingOptions());

/// Immutable after construction.
class NystromFeatureMap : public FeatureMap {
 public:
  /// kernel: copied (Clone). Z: inducing states as rows (M x kernel.input_dim(), M >= 1,
  /// finite). Factorises K_ZZ + jitter I, jitter = delta * mean(diag K_ZZ), with delta =
  /// kNystromRelativeJitter, then the larger rungs of the library's ladder (1e-7, 1e-5) when
  /// the factor is not accepted (internal/cholesky.h). O(M^2) kernel evaluations
  /// and O(M^3 / 3) flops. Throws std::invalid_argument on bad sizes or values, and
  /// std::runtime_error when even the largest jitter fails (the kernel is then not positive
  /// semi-definite on Z, or returned NaN).
  NystromFeatureMap(const Kernel& kernel, const ConstMatrixRef& Z);

  int input_dim() const override { return static_cast<int>(inducing_.rows()); }
  int dim() const override { return static_cast<int>(inducing_.cols()); }
  /// phi(x) = L^{-1} k_Z(x). Allocation-free; throws std::invalid_argument on a size mismatch.
  /// Thread-safe when the kernel's Evaluate is (see the file comment).
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  /// The same with a caller-owned kernel, which must equal kernel() (e.g. kernel().Clone(),
  /// one per thread, for kernels whose Evaluate is not thread-safe). Only sizes are checked.
  /// Always the generic path (kernel.Evaluate at each inducing state).
  void Evaluate(const ConstVectorRef& x, VectorRef phi, const Kernel& kernel) const;
  /// One block, "nystrom". Unit prior variances, no shape parameters (FeatureMap defaults).
  std::vector<FeatureBlock> blocks() const override;

  const Kernel& kernel() const { return *kernel_; }
  /// Inducing states as rows (M x input_dim).
  Matrix inducing_states() const { return inducing_.transpose(); }
  /// Lower Cholesky factor L of K_ZZ + jitter I (M x M; strictly upper part zero).
  const Matrix& cholesky_factor() const { return factor_; }
  /// The jitter added to the diagonal of K_ZZ, absolute.
  double jitter() const { return jitter_; }
  /// Rungs of the jitter ladder climbed (0: kNystromRelativeJitter was enough).
  int jitter_steps() const { return jitter_steps_; }
  /// Whether Evaluate uses the specialised k_pol kernel column.
  bool uses_pol_fast_path() const { return pol_joints_ > 0; }

 private:
  // Constants of k_pol (PolFormulaKernel) for the specialised kernel column, and per inducing
  // state i the 4N values (cos z_q, sin z_q, z_qd, z_qdd) at pol_table_[4 N i].
  void InitPolFastPath();
  void PolKernelColumn(const ConstVectorRef& x, VectorRef column) const;
  int pol_joints_ = 0;  // 0: generic path
  double pol_theta_ = 0.0;
  double pol_c_psi_ = 0.0;
  double pol_scale_inertial_ = 0.0;
  double pol_scale_coriolis_ = 0.0;
  double pol_scale_gravity_ = 0.0;
  std::vector<double> pol_table_;

  std::unique_ptr<Kernel> kernel_;
  Matrix inducing_;  // input_dim x M: inducing state i is column i (contiguous)
  Matrix factor_;    // L, M x M lower
  double jitter_ = 0.0;
  int jitter_steps_ = 0;
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_NYSTROM_FEATURE_MAP_H_
