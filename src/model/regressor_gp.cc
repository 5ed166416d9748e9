#include "structgp/model/regressor_gp.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Eigenvalues>

#include "structgp/core/validate.h"
#include "structgp/internal/cholesky.h"

namespace structgp {
namespace {

constexpr double kLog2Pi = 1.8378770664093453;

void RequirePositive(const std::string& what, const Vector& v) {
  for (Eigen::Index k = 0; k < v.size(); ++k) {
    if (!(std::isfinite(v[k]) && v[k] > 0.0)) {
      throw std::invalid_argument(what + ": expected finite values > 0, entry " +
                                  std::to_string(k) + " is " + std::to_string(v[k]));
    }
  }
}

}  // namespace

RegressorStatistics::RegressorStatistics(int num_parameters, int num_outputs)
    : gram(static_cast<size_t>(num_outputs), Matrix::Zero(num_parameters, num_parameters)),
      cross(Matrix::Zero(num_parameters, num_outputs)),
      y_squared(Vector::Zero(num_outputs)) {}

void RegressorStatistics::Accumulate(const RegressorMap& map, const ConstMatrixRef& X,
                                     const ConstMatrixRef& Y, Eigen::Index chunk_rows) {
  const int P = map.dim();
  const int N = map.num_outputs();
  if (num_parameters() != P || num_outputs() != N) {
    throw std::invalid_argument("RegressorStatistics::Accumulate: statistics for " +
                                std::to_string(num_parameters()) + " parameters and " +
                                std::to_string(num_outputs()) + " outputs, the map has " +
                                std::to_string(P) + " and " + std::to_string(N));
  }
  RequireSize("RegressorStatistics::Accumulate X", X.cols(), map.input_dim(), "columns");
  RequireSize("RegressorStatistics::Accumulate Y", Y.cols(), N, "columns");
  RequireSize("RegressorStatistics::Accumulate Y", Y.rows(), X.rows(), "rows (as in X)");
  RequireFinite("RegressorStatistics::Accumulate X", X);
  RequireFinite("RegressorStatistics::Accumulate Y", Y);
  if (chunk_rows < 1) throw std::invalid_argument("RegressorStatistics: chunk_rows < 1");
  // Rows of output j for a chunk of samples, so that each G_j grows by one rank-k update.
  std::vector<Matrix> rows(static_cast<size_t>(N));
  Matrix psi(N, P);
  const std::unique_ptr<RegressorMap::Scratch> scratch = map.MakeScratch();
  RegressorStatistics sum(P, N);
  for (Eigen::Index start = 0; start < X.rows(); start += chunk_rows) {
    const Eigen::Index k = std::min(chunk_rows, X.rows() - start);
    for (auto& r : rows) r.resize(k, P);
    for (Eigen::Index i = 0; i < k; ++i) {
      map.Evaluate(X.row(start + i).transpose(), psi, scratch.get());
      for (int j = 0; j < N; ++j) rows[static_cast<size_t>(j)].row(i) = psi.row(j);
    }
    for (int j = 0; j < N; ++j) {
      const Matrix& R = rows[static_cast<size_t>(j)];
      if (!R.allFinite()) {
        throw std::invalid_argument(
            "RegressorStatistics::Accumulate: the regressor is not finite on a row of samples " +
            std::to_string(start) + ".." + std::to_string(start + k - 1));
      }
      sum.gram[static_cast<size_t>(j)].selfadjointView<Eigen::Lower>().rankUpdate(R.transpose());
      sum.cross.col(j).noalias() += R.transpose() * Y.col(j).segment(start, k);
    }
  }
  for (int j = 0; j < N; ++j) {
    Matrix& G = sum.gram[static_cast<size_t>(j)];
    G.triangularView<Eigen::StrictlyUpper>() = G.transpose();
    gram[static_cast<size_t>(j)] += G;
  }
  cross += sum.cross;
  y_squared += Y.colwise().squaredNorm().transpose();
  count += static_cast<double>(X.rows());
}

RegressorGP::RegressorGP(Vector prior_mean, Vector prior_variance, Vector noise_variance)
    : prior_mean_(std::move(prior_mean)),
      prior_variance_(std::move(prior_variance)),
      noise_variance_(std::move(noise_variance)) {
  RequireSize("RegressorGP prior_variance", prior_variance_.size(), prior_mean_.size(),
              "entries (as the prior mean)");
  RequireFinite("RegressorGP prior_mean", prior_mean_);
  RequirePositive("RegressorGP prior_variance", prior_variance_);
  RequirePositive("RegressorGP noise_variance", noise_variance_);
  if (noise_variance_.size() < 1) {
    throw std::invalid_argument("RegressorGP noise_variance: expected one entry per output, got 0");
  }
}

Status RegressorGP::Fit(const RegressorStatistics& statistics, bool ladder) {
  const int P = dim();
  const int N = num_outputs();
  if (statistics.num_parameters() != P || statistics.num_outputs() != N ||
      statistics.gram.size() != static_cast<size_t>(N)) {
    throw std::invalid_argument("RegressorGP::Fit: statistics for " +
                                std::to_string(statistics.num_parameters()) + " parameters and " +
                                std::to_string(statistics.num_outputs()) +
                                " outputs, the model has " + std::to_string(P) + " and " +
                                std::to_string(N));
  }
  Matrix A = prior_variance_.cwiseInverse().asDiagonal();
  Vector b = Vector::Zero(P);
  for (int j = 0; j < N; ++j) {
    const Matrix& G = statistics.gram[static_cast<size_t>(j)];
    A += G / noise_variance_[j];
    b += (statistics.cross.col(j) - G * prior_mean_) / noise_variance_[j];
  }
  internal::Cholesky cholesky(P);
  internal::CholeskyOptions options;
  options.ladder = ladder ? internal::JitterLadder::kClimb : internal::JitterLadder::kNone;
  if (cholesky.Factorize(A, options).status != Status::kOk || !b.allFinite()) {
    return Status::kNotPositiveDefinite;
  }
  cholesky.SolveInPlace(b);
  if (!b.allFinite()) return Status::kNotPositiveDefinite;
  jitter_ = cholesky.result().jitter;
  factor_ = cholesky.ReleaseFactor();
  theta_ = prior_mean_ + b;
  if (&statistics != &statistics_) statistics_ = statistics;
  fitted_ = true;
  return Status::kOk;
}

Matrix RegressorGP::ParameterCovariance() const {
  if (!fitted_) throw std::logic_error("RegressorGP::ParameterCovariance: not fitted");
  Matrix inverse = Matrix::Identity(dim(), dim());
  factor_.triangularView<Eigen::Lower>().solveInPlace(inverse);
  return inverse.transpose() * inverse;
}

Vector RegressorGP::ParameterStd() const {
  return ParameterCovariance().diagonal().cwiseMax(0.0).cwiseSqrt();
}

int RegressorGP::IdentifiedDirections() const {
  if (!fitted_) throw std::logic_error("RegressorGP::IdentifiedDirections: not fitted");
  Matrix data = Matrix::Zero(dim(), dim());
  for (int j = 0; j < num_outputs(); ++j) {
    data += statistics_.gram[static_cast<size_t>(j)] / noise_variance_[j];
  }
  const Vector root = prior_variance_.cwiseSqrt();
  data = root.asDiagonal() * data * root.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix> eigen(data, Eigen::EigenvaluesOnly);
  return static_cast<int>((eigen.eigenvalues().array() > 1.0).count());
}

Status RegressorGP::Predict(const ConstMatrixRef& psi, VectorRef mean) const {
  if (!fitted_ || psi.rows() != num_outputs() || psi.cols() != dim() ||
      mean.size() != num_outputs() || !AllFinite(psi)) {
    return Status::kInvalidInput;
  }
  mean.noalias() = psi * theta_;
  return Status::kOk;
}

Status RegressorGP::PredictWithVariance(const ConstMatrixRef& psi, VectorRef mean,
                                        VectorRef latent_variance, VectorRef noisy_variance,
                                        Workspace& workspace) const {
  if (!fitted_ || psi.rows() != num_outputs() || psi.cols() != dim() ||
      mean.size() != num_outputs() || latent_variance.size() != num_outputs() ||
      noisy_variance.size() != num_outputs() || workspace.v.size() != dim() || !AllFinite(psi)) {
    return Status::kInvalidInput;
  }
  mean.noalias() = psi * theta_;
  for (int j = 0; j < num_outputs(); ++j) {
    workspace.v = psi.row(j).transpose();
    factor_.triangularView<Eigen::Lower>().solveInPlace(workspace.v);
    latent_variance[j] = workspace.v.squaredNorm();
    noisy_variance[j] = latent_variance[j] + noise_variance_[j];
  }
  return Status::kOk;
}

double RegressorGP::LogMarginalLikelihood(RegressorEvidenceGradient* gradient) const {
  if (!fitted_) throw std::logic_error("RegressorGP::LogMarginalLikelihood: not fitted");
  const int P = dim();
  const int N = num_outputs();
  const double m = statistics_.count;
  const Vector delta = theta_ - prior_mean_;  // A^{-1} b'
  double nle = 0.0;
  // log|A| from the factor (a jitter, if one was needed, is part of A here).
  nle += 2.0 * factor_.diagonal().array().log().sum();
  nle += prior_variance_.array().log().sum();
  Vector rss(N);
  for (int j = 0; j < N; ++j) {
    const Matrix& G = statistics_.gram[static_cast<size_t>(j)];
    const Vector G_mu = G * prior_mean_;
    const Vector c_shifted = statistics_.cross.col(j) - G_mu;  // c'_j
    // sum_i (y_ij - a_ij mu)^2
    const double ss = statistics_.y_squared[j] - 2.0 * statistics_.cross.col(j).dot(prior_mean_) +
                      prior_mean_.dot(G_mu);
    rss[j] = std::max(0.0, ss - 2.0 * delta.dot(c_shifted) + delta.dot(G * delta));
    // y'^T S^-1 y' - b'^T A^-1 b'  =  sum_j ss_j / s_j - delta^T b'
    nle += ss / noise_variance_[j] - delta.dot(c_shifted) / noise_variance_[j];
    nle += m * (kLog2Pi + std::log(noise_variance_[j]));
  }
  nle *= 0.5;
  if (gradient != nullptr) {
    const Matrix covariance = ParameterCovariance();
    gradient->d_log_prior_variance =
        -0.5 * (Vector::Ones(P) -
                (delta.array().square() + covariance.diagonal().array()).matrix().cwiseQuotient(
                    prior_variance_));
    gradient->d_log_noise_variance.resize(N);
    for (int j = 0; j < N; ++j) {
      const double trace =
          covariance.cwiseProduct(statistics_.gram[static_cast<size_t>(j)]).sum();
      gradient->d_log_noise_variance[j] = -0.5 * (m - (rss[j] + trace) / noise_variance_[j]);
    }
  }
  return -nle;
}

RegressorGPState RegressorGP::State() const {
  if (!fitted_) throw std::logic_error("RegressorGP::State: not fitted");
  return RegressorGPState{prior_mean_, prior_variance_, noise_variance_, statistics_};
}

RegressorGP RegressorGP::FromState(const RegressorGPState& state) {
  RegressorGP gp(state.prior_mean, state.prior_variance, state.noise_variance);
  const RegressorStatistics& s = state.statistics;
  if (s.num_parameters() != gp.dim() || s.num_outputs() != gp.num_outputs() ||
      s.gram.size() != static_cast<size_t>(gp.num_outputs()) || s.y_squared.size() != gp.num_outputs()) {
    throw std::invalid_argument("RegressorGPState: statistics of the wrong size");
  }
  for (const Matrix& G : s.gram) {
    if (G.rows() != gp.dim() || G.cols() != gp.dim() || !G.allFinite()) {
      throw std::invalid_argument("RegressorGPState: a Gram matrix of the wrong size or not finite");
    }
  }
  if (!s.cross.allFinite() || !s.y_squared.allFinite() || !(s.count >= 0.0)) {
    throw std::invalid_argument("RegressorGPState: statistics not finite");
  }
  if (gp.Fit(s) != Status::kOk) {
    throw std::invalid_argument("RegressorGPState: the posterior cannot be factorised");
  }
  return gp;
}

}  // namespace structgp
