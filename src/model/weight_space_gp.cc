#include "structgp/model/weight_space_gp.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "model/factor_kernels.h"
#include "structgp/core/validate.h"

namespace structgp {
namespace {

constexpr double kLog2Pi = 1.8378770664093453;
// Relative slack of FromState's check diag(S S^T) <= Lambda_e / sigma_n^2: far above the
// rounding of any sequence of updates, far below any damage worth detecting.
constexpr double kStateVarianceSlack = 1e-6;

// (S S^T)_kk for an upper-triangular S: the squared row norms of its upper triangle, summed
// column by column (contiguous) into `out`, which must have S's size. Allocation-free.
void UpperRowSquaredNorms(const Matrix& S, VectorRef out) {
  out.setZero();
  for (Eigen::Index j = 0; j < S.cols(); ++j) {
    out.head(j + 1) += S.col(j).head(j + 1).cwiseAbs2();
  }
}

Vector ScalesOrOnes(const Vector& output_scales, int num_outputs) {
  return output_scales.size() == 0 ? Vector::Ones(num_outputs) : output_scales;
}

void ValidatePrior(const Vector& prior_variance, double noise_variance, int num_outputs,
                   const Vector& output_scales) {
  if (prior_variance.size() == 0) {
    throw std::invalid_argument("WeightSpaceGP: prior_variance is empty (need one per feature)");
  }
  if (num_outputs <= 0) {
    throw std::invalid_argument("WeightSpaceGP: num_outputs must be positive, got " +
                                std::to_string(num_outputs));
  }
  RequireFinite("WeightSpaceGP prior_variance", prior_variance);
  if ((prior_variance.array() <= 0.0).any()) {
    throw std::invalid_argument("WeightSpaceGP: prior_variance must be > 0 everywhere");
  }
  RequireInRange("WeightSpaceGP noise_variance", noise_variance, 0.0, HUGE_VAL);
  if (!PriorToNoiseRatioOk(prior_variance, noise_variance)) {
    const double max_ratio = prior_variance.maxCoeff() / noise_variance;
    const double min_ratio = prior_variance.minCoeff() / noise_variance;
    throw std::invalid_argument(
        "WeightSpaceGP: prior_variance / noise_variance must lie in [1e-200, 1e200], got " +
        std::to_string(min_ratio) + " .. " + std::to_string(max_ratio) +
        " (noise_variance " + std::to_string(noise_variance) + "); rescale the prior or the noise");
  }
  if (output_scales.size() != 0) {
    RequireSize("WeightSpaceGP output_scales", output_scales.size(), num_outputs);
    RequireFinite("WeightSpaceGP output_scales", output_scales);
    if ((output_scales.array() <= 0.0).any()) {
      throw std::invalid_argument("WeightSpaceGP: output_scales must be > 0 everywhere");
    }
  }
}

}  // namespace

bool PriorToNoiseRatioOk(const Vector& prior_variance, double noise_variance) {
  if (!(noise_variance > 0.0) || prior_variance.size() == 0) return false;
  return prior_variance.maxCoeff() / noise_variance <= kMaxPriorToNoiseRatio &&
         prior_variance.minCoeff() / noise_variance >= 1.0 / kMaxPriorToNoiseRatio;
}

WeightSpaceGP::WeightSpaceGP(const Vector& prior_variance, double noise_variance,
                             int num_outputs, const Vector& output_scales)
    : prior_variance_(prior_variance), noise_variance_(noise_variance) {
  ValidatePrior(prior_variance, noise_variance, num_outputs, output_scales);
  const Eigen::Index D = prior_variance.size();
  factor_.setZero(D, D);
  weights_.setZero(D, num_outputs);
  y_squared_.setZero(num_outputs);
  work_f_.setZero(D);
  work_h_.setZero(D);
  work_gain_.setZero(D);
  work_err_.setZero(num_outputs);
  staged_a_.setZero(D);
  staged_b_.setZero(D);
  staged_c_.setZero(D);
  staged_err_.setZero(num_outputs);
  staged_f_.setZero(D);
  Reset(prior_variance, noise_variance, output_scales);
}

void WeightSpaceGP::Reset(const Vector& prior_variance, double noise_variance,
                          const Vector& output_scales) {
  ValidatePrior(prior_variance, noise_variance, num_outputs(), output_scales);
  RequireSize("WeightSpaceGP::Reset prior_variance", prior_variance.size(), num_features());
  prior_variance_ = prior_variance;
  noise_variance_ = noise_variance;
  output_scales_ = ScalesOrOnes(output_scales, num_outputs());
  // A = sigma_n^2 Lambda^{-1}  =>  S = diag(sqrt(Lambda) / sigma_n).
  staged_ = false;
  factor_.setZero();
  factor_.diagonal() = (prior_variance_ / noise_variance_).cwiseSqrt();
  weights_.setZero();
  y_squared_.setZero();
  weight_sum_ = 0.0;
  log_weight_sum_ = 0.0;
  log_prior_broadening_ = 0.0;
  sample_count_ = 0.0;
  num_samples_ = 0;
  fit_jitter_ = 0.0;
  // S is diagonal here: (S S^T)_kk = Lambda_k / sigma_n^2 exactly.
  log_variance_headroom_ =
      std::log(kMaxPriorToNoiseRatio) - std::log(prior_variance_.maxCoeff() / noise_variance_);
}

Status WeightSpaceGP::Fit(const ConstMatrixRef& Phi, const ConstMatrixRef& Y) {
  SufficientStatistics stats(num_features(), num_outputs());
  stats.Accumulate(Phi, Y);
  return Fit(stats);
}

Status WeightSpaceGP::Fit(const SufficientStatistics& stats, FitJitter jitter_policy) {
  RequireSize("WeightSpaceGP::Fit statistics features", stats.num_features(), num_features());
  RequireSize("WeightSpaceGP::Fit statistics outputs", stats.num_outputs(), num_outputs());
  const Eigen::Index D = num_features();
  Matrix A = stats.gram.triangularView<Eigen::Lower>();
  A.diagonal() += noise_variance_ * prior_variance_.cwiseInverse();
  // The jitter ladder of the header (internal/cholesky.h): relative to diag(A), so that the
  // policy does not depend on the units of the features.
  if (!stats.cross.allFinite()) return Status::kNotPositiveDefinite;
  internal::CholeskyOptions options;
  options.scale = internal::JitterScale::kDiagonal;
  options.ladder = jitter_policy == FitJitter::kNone ? internal::JitterLadder::kNone
                                                     : internal::JitterLadder::kClimb;
  internal::Cholesky llt(D);
  const internal::CholeskyResult factorisation = llt.Factorize(A, options);
  if (factorisation.status != Status::kOk) return Status::kNotPositiveDefinite;
  // S = L^{-T}: invert the triangular factor, then transpose into the upper triangle.
  Matrix l_inv = Matrix::Identity(D, D);
  llt.matrixL().solveInPlace(l_inv);
  Matrix weights = llt.solve(stats.cross);
  if (!l_inv.allFinite() || !weights.allFinite()) return Status::kNotPositiveDefinite;
  staged_ = false;
  factor_ = l_inv.transpose();
  factor_.triangularView<Eigen::StrictlyLower>().setZero();
  weights_ = std::move(weights);
  y_squared_ = stats.y_squared;
  weight_sum_ = stats.count;
  log_weight_sum_ = 0.0;
  log_prior_broadening_ = 0.0;
  sample_count_ = stats.count;
  num_samples_ = static_cast<long>(stats.count);
  fit_jitter_ = factorisation.jitter;
  RefreshHeadroom();
  return Status::kOk;
}

void WeightSpaceGP::RefreshHeadroom() {
  Commit(nullptr, nullptr, nullptr, nullptr);
  UpperRowSquaredNorms(factor_, work_h_);
  log_variance_headroom_ = std::log(kMaxPriorToNoiseRatio) - std::log(work_h_.maxCoeff());
}

bool WeightSpaceGP::TakeHeadroom(double cost) {
  if (cost > log_variance_headroom_) {
    RefreshHeadroom();
    if (!(cost <= log_variance_headroom_)) return false;
  }
  log_variance_headroom_ -= cost;
  return true;
}

bool WeightSpaceGP::InputOk(const ConstVectorRef& phi, const ConstVectorRef& y) const {
  return phi.size() == num_features() && y.size() == num_outputs() && phi.allFinite() &&
         y.allFinite();
}

void WeightSpaceGP::RequireNotStaged(const char* what) const {
  if (staged_) {
    throw std::logic_error(std::string("WeightSpaceGP::") + what +
                           " const: an update is staged (UpdateAndPredict); call the non-const "
                           "overload or ApplyStagedUpdate() first");
  }
}

void WeightSpaceGP::Commit(const double* x1, const double* x2, double* y1, double* y2) {
  const int D = num_features();
  if (!staged_) {
    if (x1 != nullptr) internal::UpperTransposeTimes(factor_.data(), D, D, x1, x2, y1, y2);
    return;
  }
  // The fused pass takes two right-hand sides; with one, x1 is used twice.
  if (x1 != nullptr && x2 == nullptr) {
    x2 = x1;
    y2 = (y1 == work_h_.data()) ? work_f_.data() : work_h_.data();
  }
  internal::CarlsonRankOne(factor_.data(), D, D, staged_a_.data(), staged_b_.data(),
                           staged_c_.data(), work_gain_.data(), x1, x2, y1, y2);
  // W' = W + (A'^{-1} phi) e^T with A'^{-1} phi = gain / alpha.
  weights_.noalias() += (staged_inv_alpha_ * work_gain_) * staged_err_.transpose();
  staged_ = false;
}

void WeightSpaceGP::Stage(double r, double scale, double alpha) {
  internal::CarlsonCoefficients(work_f_.data(), num_features(), r, scale, staged_a_.data(),
                                staged_b_.data(), staged_c_.data());
  staged_inv_alpha_ = 1.0 / alpha;
  staged_err_ = work_err_;
  staged_f_ = work_f_;
  staged_scale_ = scale;
  staged_ = true;
}

void WeightSpaceGP::Account(const ConstVectorRef& y, double forgetting, double weight,
                            double sign) {
  if (forgetting != 1.0) {
    const double log_lambda = std::log(forgetting);
    y_squared_ *= forgetting;
    weight_sum_ *= forgetting;
    log_weight_sum_ += sample_count_ * log_lambda;
    log_prior_broadening_ -= log_lambda;
  }
  y_squared_ += (sign * weight) * y.cwiseAbs2();
  weight_sum_ += sign * weight;
  log_weight_sum_ += sign * std::log(weight);
  sample_count_ += sign;
  num_samples_ += sign > 0 ? 1 : -1;
}

Status WeightSpaceGP::Update(const ConstVectorRef& phi, const ConstVectorRef& y,
                             double forgetting, double weight) {
  if (!InputOk(phi, y) || !(forgetting > 0.0 && forgetting <= 1.0) ||
      !(weight > 0.0 && std::isfinite(weight))) {
    return Status::kInvalidInput;
  }
  // A' = lambda A + v phi phi^T >= lambda A: no variance grows by more than 1/lambda.
  if (forgetting != 1.0 && !TakeHeadroom(-std::log(forgetting))) {
    return Status::kNotPositiveDefinite;
  }
  Commit(phi.data(), nullptr, work_f_.data(), nullptr);
  const double scale = forgetting == 1.0 ? 1.0 : 1.0 / std::sqrt(forgetting);
  work_f_ *= scale;
  const double alpha = 1.0 / weight + work_f_.squaredNorm();
  if (!std::isfinite(alpha)) return Status::kNotPositiveDefinite;
  work_err_.noalias() = y - weights_.transpose() * phi;
  if (!work_err_.allFinite()) return Status::kInvalidInput;
  Stage(1.0 / weight, scale, alpha);
  Commit(nullptr, nullptr, nullptr, nullptr);
  Account(y, forgetting, weight, +1.0);
  return Status::kOk;
}

Status WeightSpaceGP::Downdate(const ConstVectorRef& phi, const ConstVectorRef& y,
                               double weight) {
  if (!InputOk(phi, y) || !(weight > 0.0 && std::isfinite(weight))) {
    return Status::kInvalidInput;
  }
  Commit(phi.data(), nullptr, work_f_.data(), nullptr);
  // Removing the sample keeps A positive definite iff 1 - weight * phi^T A^{-1} phi > 0.
  const double margin = 1.0 - weight * work_f_.squaredNorm();
  if (!(margin > kMinDowndateMargin)) return Status::kNotPositiveDefinite;
  // A'^{-1} = A^{-1} + v g g^T / margin with g = A^{-1} phi, and g_k^2 <= (A^{-1})_kk phi^T A^{-1}
  // phi: no variance grows by more than 1 / margin. (Taking headroom may refresh it, which
  // reuses work_h_ only: work_f_ is kept.)
  if (!TakeHeadroom(-std::log(margin))) return Status::kNotPositiveDefinite;
  work_err_.noalias() = y - weights_.transpose() * phi;
  if (!work_err_.allFinite()) return Status::kInvalidInput;
  Stage(-1.0 / weight, 1.0, -margin / weight);  // alpha = -1/weight + f^T f
  Commit(nullptr, nullptr, nullptr, nullptr);
  Account(y, 1.0, weight, -1.0);
  return Status::kOk;
}

void WeightSpaceGP::ReserveBatch(int max_steps) {
  if (max_steps < 0) {
    throw std::invalid_argument("WeightSpaceGP::ReserveBatch: expected max_steps >= 0, got " +
                                std::to_string(max_steps));
  }
  const Eigen::Index D = num_features();
  batch_capacity_ = max_steps;
  for (Matrix* m : {&batch_z_, &batch_f_, &batch_a_, &batch_b_, &batch_c_, &batch_gain_}) {
    m->setZero(D, max_steps);
  }
  batch_err_.setZero(num_outputs(), max_steps);
  batch_inv_alpha_.setZero(max_steps);
  batch_scale_.setZero(max_steps);
  batch_coef_.setZero(max_steps, num_outputs());
  batch_splat_.setZero(static_cast<Eigen::Index>(internal::kCarlsonSplatPerStep) * max_steps);
}

int WeightSpaceGP::UpdateBatch(const ConstMatrixRef& Phi, const ConstMatrixRef& Y,
                               const ConstVectorRef& forgetting, const ConstVectorRef& weights,
                               Status* status) {
  const Eigen::Index k = Phi.cols();
  Status local = Status::kOk;
  Status& result = status != nullptr ? *status : local;
  if (Phi.rows() != num_features() || Y.rows() != num_outputs() || Y.cols() != k ||
      forgetting.size() != k || weights.size() != k || k > batch_capacity_) {
    result = Status::kInvalidInput;
    return 0;
  }
  result = Status::kOk;
  ApplyStagedUpdate();
  int done = 0;
  while (done < k) {
    bool refresh = false;
    const int n = PlanBatch(Phi, Y, forgetting, weights, done, &result, &refresh);
    if (n > 0) ApplyBatch(n);
    done += n;
    if (result != Status::kOk) return done;
    // The headroom bound ran out mid-batch: the next round refreshes it on the updated S.
    if (refresh) RefreshHeadroom();
  }
  return done;
}

int WeightSpaceGP::PlanBatch(const ConstMatrixRef& Phi, const ConstMatrixRef& Y,
                             const ConstVectorRef& forgetting, const ConstVectorRef& weights,
                             int begin, Status* status, bool* refresh) {
  const int D = num_features();
  const int m = static_cast<int>(Phi.cols()) - begin;
  // One pass over S for every remaining step: z_i = S^T phi_i, and the errors against W.
  internal::UpperTransposeTimesMany(factor_.data(), D, D, m, Phi.col(begin).data(),
                                    static_cast<int>(Phi.outerStride()), batch_z_.data(), D);
  int n = 0;
  for (; n < m; ++n) {
    const int i = begin + n;
    const double lambda = forgetting[i];
    const double v = weights[i];
    const bool remove = v < 0.0;
    const auto phi = Phi.col(i);
    const auto y = Y.col(i);
    if (!phi.allFinite() || !y.allFinite() || !std::isfinite(v) || v == 0.0 ||
        !(lambda > 0.0 && lambda <= 1.0) || (remove && lambda != 1.0)) {
      *status = Status::kInvalidInput;
      return n;
    }
    auto z = batch_z_.col(n);
    auto err = batch_err_.col(n);
    err.noalias() = y - weights_.transpose() * phi;
    // Through the steps planned before this one: z <- S_l^T phi, and the error against
    // W_l = W_{l-1} + (gain_l / alpha_l) e_l^T, gain_l^T phi = scale_l f_l^T S_{l-1}^T phi.
    for (int l = 0; l < n; ++l) {
      const double cross = batch_scale_[l] * batch_f_.col(l).dot(z);
      err -= (cross * batch_inv_alpha_[l]) * batch_err_.col(l);
      internal::CarlsonTransposeApply(batch_a_.col(l).data(), batch_b_.col(l).data(),
                                      batch_c_.col(l).data(), D, z.data());
    }
    if (!err.allFinite()) {
      *status = Status::kInvalidInput;
      return n;
    }
    double scale = 1.0, r = 0.0, alpha = 0.0, cost = 0.0;
    if (!remove) {
      scale = lambda == 1.0 ? 1.0 : 1.0 / std::sqrt(lambda);
      cost = lambda == 1.0 ? 0.0 : -std::log(lambda);
      const double fz = z.squaredNorm() * scale * scale;
      r = 1.0 / v;
      alpha = r + fz;
      if (!std::isfinite(alpha)) {
        *status = Status::kNotPositiveDefinite;
        return n;
      }
    } else {
      const double w = -v;
      const double margin = 1.0 - w * z.squaredNorm();
      if (!(margin > kMinDowndateMargin)) {
        *status = Status::kNotPositiveDefinite;
        return n;
      }
      cost = -std::log(margin);
      r = -1.0 / w;
      alpha = -margin / w;
    }
    if (cost > log_variance_headroom_) {
      // The bound is short: with steps planned, apply them and refresh on the new S;
      // otherwise S is current and the exact headroom decides.
      if (n > 0) {
        *refresh = true;
        return n;
      }
      RefreshHeadroom();
      if (!(cost <= log_variance_headroom_)) {
        *status = Status::kNotPositiveDefinite;
        return n;
      }
    }
    log_variance_headroom_ -= cost;
    auto f = batch_f_.col(n);
    f = scale * z;
    internal::CarlsonCoefficients(f.data(), D, r, scale, batch_a_.col(n).data(),
                                  batch_b_.col(n).data(), batch_c_.col(n).data());
    batch_inv_alpha_[n] = 1.0 / alpha;
    batch_scale_[n] = scale;
    if (remove) {
      Account(y, 1.0, -v, -1.0);
    } else {
      Account(y, lambda, v, +1.0);
    }
  }
  return n;
}

void WeightSpaceGP::ApplyBatch(int n) {
  const int D = num_features();
  internal::CarlsonRankK(factor_.data(), D, D, n, batch_a_.data(), batch_b_.data(),
                         batch_c_.data(), D, batch_gain_.data(), batch_splat_.data());
  // W' = W + sum_l (gain_l / alpha_l) e_l^T, output by output.
  for (int l = 0; l < n; ++l) {
    batch_coef_.row(l) = batch_inv_alpha_[l] * batch_err_.col(l).transpose();
  }
  for (int p = 0; p < num_outputs(); ++p) {
    weights_.col(p).noalias() += batch_gain_.leftCols(n) * batch_coef_.col(p).head(n);
  }
}

Status WeightSpaceGP::Predict(const ConstVectorRef& phi, VectorRef mean, Workspace& workspace) const {
  if (phi.size() != num_features() || mean.size() != num_outputs() || !phi.allFinite() ||
      workspace.projection.size() != num_features()) {
    return Status::kInvalidInput;
  }
  mean.noalias() = weights_.transpose() * phi;
  if (staged_) {
    // The staged sample (f = scale S^T phi_u, error e): A'^{-1} phi_u = scale S f / alpha, so
    // W'^T phi = W^T phi + (h^T f / alpha) e with h = scale S^T phi (Sherman-Morrison).
    double* h = workspace.projection.data();
    internal::UpperTransposeTimes(factor_.data(), num_features(), num_features(), phi.data(),
                                  nullptr, h, nullptr);
    const double cross = staged_scale_ * workspace.projection.dot(staged_f_);
    mean += (cross * staged_inv_alpha_) * staged_err_;
    if (!std::isfinite(cross)) return Status::kInvalidInput;
  }
  return mean.allFinite() ? Status::kOk : Status::kInvalidInput;
}

Status WeightSpaceGP::PredictWithVariance(const ConstVectorRef& phi, VectorRef mean,
                                          VectorRef latent_variance, VectorRef noisy_variance,
                                          Workspace& workspace) const {
  if (phi.size() != num_features() || mean.size() != num_outputs() ||
      latent_variance.size() != num_outputs() || noisy_variance.size() != num_outputs() ||
      !phi.allFinite() || workspace.projection.size() != num_features()) {
    return Status::kInvalidInput;
  }
  Vector& h = workspace.projection;
  internal::UpperTransposeTimes(factor_.data(), num_features(), num_features(), phi.data(),
                                nullptr, h.data(), nullptr);
  mean.noalias() = weights_.transpose() * phi;
  double quad = 0.0;  // phi^T A^{-1} phi >= 0
  if (!staged_) {
    quad = h.squaredNorm();
  } else {
    // Through the staged sample, as in UpdateAndPredict: with h = scale S^T phi,
    // phi^T A'^{-1} phi = h^T h - (h^T f)^2 / alpha and W'^T phi = W^T phi + (h^T f / alpha) e.
    if (staged_scale_ != 1.0) h *= staged_scale_;
    const double cross = h.dot(staged_f_);
    mean += (cross * staged_inv_alpha_) * staged_err_;
    quad = std::max(0.0, h.squaredNorm() - cross * cross * staged_inv_alpha_);
  }
  latent_variance = (noise_variance_ * quad) * output_scales_.cwiseAbs2();
  noisy_variance = latent_variance + noise_variance_ * output_scales_.cwiseAbs2();
  return mean.allFinite() && std::isfinite(quad) ? Status::kOk : Status::kInvalidInput;
}

Status WeightSpaceGP::Predict(const ConstVectorRef& phi, VectorRef mean) {
  if (phi.size() != num_features() || mean.size() != num_outputs() || !phi.allFinite()) {
    return Status::kInvalidInput;
  }
  Commit(nullptr, nullptr, nullptr, nullptr);
  mean.noalias() = weights_.transpose() * phi;
  return mean.allFinite() ? Status::kOk : Status::kInvalidInput;
}

Status WeightSpaceGP::PredictWithVariance(const ConstVectorRef& phi, VectorRef mean,
                                          VectorRef latent_variance, VectorRef noisy_variance) {
  if (phi.size() != num_features() || mean.size() != num_outputs() ||
      latent_variance.size() != num_outputs() || noisy_variance.size() != num_outputs() ||
      !phi.allFinite()) {
    return Status::kInvalidInput;
  }
  Commit(phi.data(), nullptr, work_f_.data(), nullptr);
  mean.noalias() = weights_.transpose() * phi;
  const double quad = work_f_.squaredNorm();  // phi^T A^{-1} phi >= 0 by construction
  latent_variance = (noise_variance_ * quad) * output_scales_.cwiseAbs2();
  noisy_variance = latent_variance + noise_variance_ * output_scales_.cwiseAbs2();
  return mean.allFinite() && std::isfinite(quad) ? Status::kOk : Status::kInvalidInput;
}

Status WeightSpaceGP::UpdateAndPredict(const ConstVectorRef& phi_update, const ConstVectorRef& y,
                                       const ConstVectorRef& phi_predict, VectorRef mean,
                                       VectorRef latent_variance, VectorRef noisy_variance,
                                       double forgetting) {
  const bool want_variance = latent_variance.size() != 0 || noisy_variance.size() != 0;
  if (!InputOk(phi_update, y) || phi_predict.size() != num_features() ||
      !phi_predict.allFinite() || mean.size() != num_outputs() ||
      (want_variance && (latent_variance.size() != num_outputs() ||
                         noisy_variance.size() != num_outputs())) ||
      !(forgetting > 0.0 && forgetting <= 1.0)) {
    return Status::kInvalidInput;
  }
  if (forgetting != 1.0 && !TakeHeadroom(-std::log(forgetting))) {
    return Status::kNotPositiveDefinite;
  }
  // One pass: apply the previous step's staged change and project both new vectors.
  Commit(phi_update.data(), phi_predict.data(), work_f_.data(), work_h_.data());
  const double scale = forgetting == 1.0 ? 1.0 : 1.0 / std::sqrt(forgetting);
  if (scale != 1.0) {
    work_f_ *= scale;
    work_h_ *= scale;
  }
  const double alpha = 1.0 + work_f_.squaredNorm();
  if (!std::isfinite(alpha)) return Status::kNotPositiveDefinite;
  work_err_.noalias() = y - weights_.transpose() * phi_update;
  if (!work_err_.allFinite()) return Status::kInvalidInput;
  // With the new sample staged, A'^{-1} = P_s - P_s phi phi^T P_s / alpha (Sherman-Morrison):
  //   mean(phi_p) = W^T phi_p + (h^T f / alpha) e,  phi_p^T A'^{-1} phi_p = h^T h - (h^T f)^2 / alpha.
  const double cross = work_h_.dot(work_f_);
  mean.noalias() = weights_.transpose() * phi_predict;
  mean += (cross / alpha) * work_err_;
  if (want_variance) {
    const double quad = std::max(0.0, work_h_.squaredNorm() - cross * cross / alpha);
    latent_variance = (noise_variance_ * quad) * output_scales_.cwiseAbs2();
    noisy_variance = latent_variance + noise_variance_ * output_scales_.cwiseAbs2();
  }
  if (!mean.allFinite() || !std::isfinite(cross)) return Status::kInvalidInput;
  Stage(1.0, scale, alpha);
  Account(y, forgetting, 1.0, +1.0);
  return Status::kOk;
}

const Matrix& WeightSpaceGP::weights() const {
  RequireNotStaged("weights");
  return weights_;
}

const Matrix& WeightSpaceGP::weights() {
  ApplyStagedUpdate();
  return weights_;
}

const Matrix& WeightSpaceGP::covariance_factor() const {
  RequireNotStaged("covariance_factor");
  return factor_;
}

const Matrix& WeightSpaceGP::covariance_factor() {
  ApplyStagedUpdate();
  return factor_;
}

WeightSpaceGPState WeightSpaceGP::State() {
  ApplyStagedUpdate();
  return std::as_const(*this).State();
}

WeightSpaceGPState WeightSpaceGP::State() const {
  RequireNotStaged("State");
  WeightSpaceGPState state;
  state.prior_variance = prior_variance_;
  state.noise_variance = noise_variance_;
  state.output_scales = output_scales_;
  state.covariance_factor = factor_;
  state.weights = weights_;
  state.y_squared = y_squared_;
  state.weight_sum = weight_sum_;
  state.log_weight_sum = log_weight_sum_;
  state.log_prior_broadening = log_prior_broadening_;
  state.sample_count = sample_count_;
  state.num_samples = num_samples_;
  return state;
}

WeightSpaceGP WeightSpaceGP::FromState(const WeightSpaceGPState& state) {
  const Eigen::Index P = state.output_scales.size();
  if (P == 0) {
    throw std::invalid_argument(
        "WeightSpaceGP::FromState: output_scales is empty (need one per output)");
  }
  // Checks Lambda, sigma_n^2 and s and allocates everything.
  WeightSpaceGP model(state.prior_variance, state.noise_variance, static_cast<int>(P),
                      state.output_scales);
  const Eigen::Index D = state.prior_variance.size();
  RequireSize("WeightSpaceGP::FromState covariance_factor", state.covariance_factor.rows(), D,
              "rows");
  RequireSize("WeightSpaceGP::FromState covariance_factor", state.covariance_factor.cols(), D,
              "columns");
  RequireSize("WeightSpaceGP::FromState weights", state.weights.rows(), D, "rows");
  RequireSize("WeightSpaceGP::FromState weights", state.weights.cols(), P, "columns");
  RequireSize("WeightSpaceGP::FromState y_squared", state.y_squared.size(), P);
  RequireFinite("WeightSpaceGP::FromState covariance_factor", state.covariance_factor);
  RequireFinite("WeightSpaceGP::FromState weights", state.weights);
  RequireFinite("WeightSpaceGP::FromState y_squared", state.y_squared);
  if (!state.covariance_factor.triangularView<Eigen::StrictlyLower>().toDenseMatrix().isZero(0.0)) {
    throw std::invalid_argument(
        "WeightSpaceGP::FromState: covariance_factor must be upper-triangular (its strictly "
        "lower part is not zero)");
  }
  if (!(state.covariance_factor.diagonal().array() > 0.0).all()) {
    throw std::invalid_argument(
        "WeightSpaceGP::FromState: covariance_factor must have a positive diagonal");
  }
  // A >= sigma_n^2 Lambda_e^{-1}, so the posterior variance of every weight is at most its
  // prior variance: diag(S S^T)_k <= Lambda_k exp(log_prior_broadening) / sigma_n^2. The slack
  // covers rounding; a factor that breaks this was not made by a model (a damaged file).
  if (std::isfinite(state.log_prior_broadening)) {
    const Vector bound = state.prior_variance * (std::exp(state.log_prior_broadening) /
                                                 state.noise_variance);
    Vector row_norms(D);
    UpperRowSquaredNorms(state.covariance_factor, row_norms);
    for (Eigen::Index k = 0; k < D; ++k) {
      if (!(row_norms[k] <= bound[k] * (1.0 + kStateVarianceSlack))) {
        throw std::invalid_argument(
            "WeightSpaceGP::FromState: covariance_factor row " + std::to_string(k) +
            " gives a posterior variance above the prior variance (" +
            std::to_string(row_norms[k]) + " > " + std::to_string(bound[k]) +
            "); the factor is not one a model can reach");
      }
    }
  }
  for (double v :
       {state.weight_sum, state.log_weight_sum, state.log_prior_broadening, state.sample_count}) {
    if (!std::isfinite(v)) {
      throw std::invalid_argument("WeightSpaceGP::FromState: the evidence counters must be finite");
    }
  }
  model.factor_ = state.covariance_factor;
  model.weights_ = state.weights;
  model.y_squared_ = state.y_squared;
  model.weight_sum_ = state.weight_sum;
  model.log_weight_sum_ = state.log_weight_sum;
  model.log_prior_broadening_ = state.log_prior_broadening;
  model.sample_count_ = state.sample_count;
  model.num_samples_ = state.num_samples;
  model.RefreshHeadroom();
  return model;
}

Vector WeightSpaceGP::effective_prior_variance() const {
  return prior_variance_ * std::exp(log_prior_broadening_);
}

Matrix WeightSpaceGP::WeightCovariance(int output) {
  ApplyStagedUpdate();
  return std::as_const(*this).WeightCovariance(output);
}

Matrix WeightSpaceGP::WeightCovariance(int output) const {
  RequireNotStaged("WeightCovariance");
  if (output < 0 || output >= num_outputs()) {
    throw std::invalid_argument("WeightSpaceGP::WeightCovariance: output " +
                                std::to_string(output) + " out of range [0, " +
                                std::to_string(num_outputs()) + ")");
  }
  const auto S = factor_.triangularView<Eigen::Upper>();
  Matrix cov = S * factor_.transpose();
  return cov * (noise_variance_ * output_scales_[output] * output_scales_[output]);
}

double WeightSpaceGP::LogMarginalLikelihood() const { return LogMarginalLikelihood(nullptr); }

double WeightSpaceGP::LogMarginalLikelihood() {
  ApplyStagedUpdate();
  return std::as_const(*this).LogMarginalLikelihood(nullptr);
}

double WeightSpaceGP::LogMarginalLikelihood(EvidenceGradient* gradient) {
  ApplyStagedUpdate();
  return std::as_const(*this).LogMarginalLikelihood(gradient);
}

// With C = Phi Lambda_e Phi^T + sigma^2 V^{-1} (weights V, effective prior Lambda_e) and
// A = Phi^T V Phi + sigma^2 Lambda_e^{-1}:
//   y^T C^{-1} y = (y^T V y - w^T A w) / sigma^2,
//   log|C| = log|A| + log|Lambda_e| + (m - D) log sigma^2 - sum log v_i,
// and output j (scale s_j) adds m log s_j^2 and divides the quadratic form by s_j^2.
// Derivations of the gradient are in docs/derivations.md.
double WeightSpaceGP::LogMarginalLikelihood(EvidenceGradient* gradient) const {
  RequireNotStaged("LogMarginalLikelihood");
  const double D = num_features();
  const double m = sample_count_;
  const double s2n = noise_variance_;
  const Vector lambda_e = effective_prior_variance();
  const auto S = factor_.triangularView<Eigen::Upper>();
  const Matrix z = S.solve(weights_);  // S^{-1} W, so ||z_j||^2 = w_j^T A w_j
  const double log_det_a = -2.0 * factor_.diagonal().array().log().sum();
  const double log_det_c = log_det_a + lambda_e.array().log().sum() + (m - D) * std::log(s2n) -
                           log_weight_sum_;
  double lml = 0.0;
  Vector quad(num_outputs());
  for (int j = 0; j < num_outputs(); ++j) {
    const double s2 = output_scales_[j] * output_scales_[j];
    const double wAw = z.col(j).squaredNorm();
    quad[j] = (y_squared_[j] - wAw) / s2n;  // y^T C^{-1} y for unit scale
    lml += -0.5 * quad[j] / s2 - 0.5 * (log_det_c + m * std::log(s2)) - 0.5 * m * kLog2Pi;
  }
  if (gradient != nullptr) {
    const Vector diag_a_inv = factor_.rowwise().squaredNorm();  // lower part is zero
    const double tr_a_inv_lambda_inv = diag_a_inv.cwiseQuotient(lambda_e).sum();
    gradient->d_log_prior_variance.setZero(num_features());
    gradient->d_log_output_scale.setZero(num_outputs());
    double d_noise_var = 0.0;
    const double tr_c_inv = (m - D + s2n * tr_a_inv_lambda_inv) / s2n;
    for (int j = 0; j < num_outputs(); ++j) {
      const double s2 = output_scales_[j] * output_scales_[j];
      const auto w = weights_.col(j);
      gradient->d_log_prior_variance.array() +=
          0.5 * (w.array().square() / (s2 * lambda_e.array()) - 1.0 +
                 s2n * diag_a_inv.array() / lambda_e.array());
      const double w_lambda_w = w.cwiseAbs2().cwiseQuotient(lambda_e).sum();
      const double residual_sq = y_squared_[j] - z.col(j).squaredNorm() - s2n * w_lambda_w;
      d_noise_var += 0.5 * (residual_sq / (s2n * s2n * s2) - tr_c_inv);
      gradient->d_log_output_scale[j] = quad[j] / s2 - m;
    }
    gradient->d_log_noise_std = 2.0 * s2n * d_noise_var;
  }
  return lml;
}

}  // namespace structgp
