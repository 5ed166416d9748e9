#ifndef STRUCTGP_MODEL_REGRESSOR_GP_H_
#define STRUCTGP_MODEL_REGRESSOR_GP_H_

/// @file
/// The Bayesian linear model of a RegressorMap (feature/regressor_map.h): N outputs that share
/// one parameter vector theta (P),
///     y_i = Psi(x_i) theta + e_i,   e_ij ~ N(0, sigma_j^2) independent,
///     theta ~ N(mu, diag(lambda)),
/// each output j with a noise level of its own. With a_ij = row j of Psi(x_i) the posterior is
///     A = sum_j G_j / sigma_j^2 + diag(1 / lambda),   G_j = sum_i a_ij^T a_ij,
///     theta_hat = mu + A^{-1} sum_j (c_j - G_j mu) / sigma_j^2,   c_j = sum_i a_ij^T y_ij,
/// so the data enter through the per-output statistics (G_j, c_j, sum y_ij^2, count), O(N P^2)
/// memory whatever the number of samples: the evidence and its gradient for any prior and noise
/// levels follow from them without touching the data again (type-II maximum likelihood).
///
/// Cost: statistics O(m N P^2) (BLAS-3, in chunks), fit O(N P^2 + P^3), prediction with
/// variance O(N P^2) (one triangular solve per output), evidence with gradient O(N P^2 + P^3).
/// The predictions with a workspace allocate nothing.

#include <vector>

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/regressor_map.h"

namespace structgp {

/// Per-output sums of a data set under a RegressorMap.
struct RegressorStatistics {
  /// G_j = sum_i a_ij^T a_ij, one P x P matrix per output (full, symmetric).
  std::vector<Matrix> gram;
  /// Column j is c_j = sum_i a_ij^T y_ij (P x N).
  Matrix cross;
  /// sum_i y_ij^2 per output (N).
  Vector y_squared;
  /// Number of samples.
  double count = 0.0;

  RegressorStatistics() = default;
  RegressorStatistics(int num_parameters, int num_outputs);
  int num_parameters() const { return static_cast<int>(cross.rows()); }
  int num_outputs() const { return static_cast<int>(cross.cols()); }

  /// Adds the samples X (m x map.input_dim()) -> Y (m x N), in chunks of chunk_rows. Throws
  /// std::invalid_argument on a size mismatch or a non-finite value (nothing is added then).
  void Accumulate(const RegressorMap& map, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                  Eigen::Index chunk_rows = 512);
};

/// d log p(Y) with respect to the log prior variances (P) and the log noise variances (N).
struct RegressorEvidenceGradient {
  Vector d_log_prior_variance;
  Vector d_log_noise_variance;
};

/// Everything a fitted RegressorGP's results depend on (RegressorGP::FromState restores it
/// by refitting, exactly: the fit is deterministic).
struct RegressorGPState {
  Vector prior_mean;
  Vector prior_variance;
  Vector noise_variance;
  RegressorStatistics statistics;
};

class RegressorGP {
 public:
  /// prior_mean (P), prior_variance (P, > 0), noise_variance (N, > 0). Throws
  /// std::invalid_argument naming the bad argument.
  RegressorGP(Vector prior_mean, Vector prior_variance, Vector noise_variance);

  int dim() const { return static_cast<int>(prior_mean_.size()); }
  int num_outputs() const { return static_cast<int>(noise_variance_.size()); }
  const Vector& prior_mean() const { return prior_mean_; }
  const Vector& prior_variance() const { return prior_variance_; }
  const Vector& noise_variance() const { return noise_variance_; }

  /// The posterior of the statistics (kept for the evidence). kNotPositiveDefinite when the
  /// precision cannot be factorised even with the jitter ladder (or, with ladder false, without
  /// jitter); the model is then unchanged. Throws std::invalid_argument on a size mismatch.
  Status Fit(const RegressorStatistics& statistics, bool ladder = true);
  bool fitted() const { return fitted_; }
  /// Relative jitter the fit needed (0 normally).
  double fit_jitter() const { return jitter_; }
  const RegressorStatistics& statistics() const { return statistics_; }

  /// Posterior mean theta_hat (P) and covariance A^{-1} (P x P, allocates).
  const Vector& parameters() const { return theta_; }
  Matrix ParameterCovariance() const;
  /// Posterior standard deviation of each parameter (P, allocates).
  Vector ParameterStd() const;
  /// Number of directions of theta the data determine better than the prior: eigenvalues
  /// above 1 of the data precision sum_j G_j / sigma_j^2 in prior-whitened coordinates
  /// (Lambda^{1/2} ... Lambda^{1/2}). The rest are held by the prior (allocates, O(P^3)).
  int IdentifiedDirections() const;

  struct Workspace {
    Vector v;
  };
  Workspace MakeWorkspace() const { return Workspace{Vector(dim())}; }
  /// Mean Psi theta_hat (N) at a regressor value psi (N x P); with variance: latent
  /// a_j A^{-1} a_j^T and noisy latent + sigma_j^2. Allocation-free with a workspace.
  /// kInvalidInput for a non-finite psi or wrong sizes (outputs untouched).
  Status Predict(const ConstMatrixRef& psi, VectorRef mean) const;
  Status PredictWithVariance(const ConstMatrixRef& psi, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance, Workspace& workspace) const;

  /// log p(Y) of the fitted statistics, and its gradient when not null. Throws
  /// std::logic_error when not fitted.
  double LogMarginalLikelihood(RegressorEvidenceGradient* gradient = nullptr) const;

  RegressorGPState State() const;
  /// Throws std::invalid_argument when the state is inconsistent or cannot be factorised.
  static RegressorGP FromState(const RegressorGPState& state);

 private:
  Vector prior_mean_, prior_variance_, noise_variance_;
  RegressorStatistics statistics_;
  bool fitted_ = false;
  double jitter_ = 0.0;
  Matrix factor_;  // L, L L^T = A (lower)
  Vector theta_;   // posterior mean
};

}  // namespace structgp

#endif  // STRUCTGP_MODEL_REGRESSOR_GP_H_
