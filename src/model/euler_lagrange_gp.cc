#include "structgp/model/euler_lagrange_gp.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "structgp/core/row_subset.h"
#include "structgp/internal/cholesky.h"
#include "structgp/internal/workers.h"

namespace structgp {
namespace {

// The jitter always added to the covariance at inducing states (relative to its mean diagonal,
// internal/cholesky.h's JitterScale::kMeanDiagonal): inducing states close to each other make
// it singular to working precision, and the DTC posterior and the Nystrom-type joint features
// take it as part of their model.
constexpr double kInducingRelativeJitter = 1e-8;

constexpr double kLog2Pi = 1.8378770664093453;

void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("EulerLagrangeGP: " + what);
}

bool AllFinite(const ConstMatrixRef& A) { return A.allFinite(); }

// Rows state-major: y[s N + i] = Y(s, i).
Vector Stack(const ConstMatrixRef& Y) {
  const Eigen::Index n = Y.cols();
  Vector y(Y.size());
  for (Eigen::Index s = 0; s < Y.rows(); ++s) y.segment(s * n, n) = Y.row(s).transpose();
  return y;
}

double FrictionCovariance(const EulerLagrangeGPHyperparameters& h, int i, double qd, double qdp) {
  const double v = h.friction_velocity_scale[i], s = h.friction_std[i], w = h.coulomb_width;
  return s * s * (qd * qdp / (v * v) + std::tanh(qd / w) * std::tanh(qdp / w) + 1.0);
}

// Adds the effects' covariance of X against Z to C ((m N) x (p N)): joint i's diagonal entries
// gain s_i^2 phi(x)^T diag(lambda) phi(z).
void AddEffects(const FeatureMap* effects, const EulerLagrangeGPHyperparameters& h,
                const ConstMatrixRef& X, const ConstMatrixRef& Z, Matrix* C) {
  if (effects == nullptr) return;
  const int n = h.num_joints();
  Matrix Px, Pz;
  effects->EvaluateRows(X, &Px);
  effects->EvaluateRows(Z, &Pz);
  const Matrix G = Px * h.effect_prior_variance.asDiagonal() * Pz.transpose();
  for (Eigen::Index s = 0; s < X.rows(); ++s) {
    for (Eigen::Index t = 0; t < Z.rows(); ++t) {
      for (int i = 0; i < n; ++i) {
        (*C)(s * n + i, t * n + i) += h.effect_scale[i] * h.effect_scale[i] * G(s, t);
      }
    }
  }
}

// The Gram parts over X (m x 3N, or 3N + 1 with the time) against Z (p x the same), (m N) x
// (p N), row index state * N + i:
// parts[k] for the kernel part `which[k]` at unit weight, and the friction part in *F (zero
// when there is none). With symmetric (X = Z) only half the pairs are evaluated.
void PartGrams(const EulerLagrangeKernel& kernel, const EulerLagrangeGPHyperparameters& h,
               const ConstMatrixRef& X, const ConstMatrixRef& Z, bool symmetric,
               const std::vector<int>& which, std::vector<Matrix>* parts, Matrix* F) {
  const int n = kernel.num_joints();
  const Eigen::Index m = X.rows(), p = Z.rows();
  parts->assign(which.size(), Matrix::Zero(m * n, p * n));
  F->setZero(m * n, p * n);
  Matrix kin(n, n), pot(n, n);
  const Matrix Xt = X.transpose(), Zt = Z.transpose();
  for (Eigen::Index s = 0; s < m; ++s) {
    for (Eigen::Index t = symmetric ? s : 0; t < p; ++t) {
      int computed = -1;
      for (size_t k = 0; k < which.size(); ++k) {
        const int link = which[k] % n;
        if (link != computed) {
          kernel.EvaluateLink(Xt.col(s).head(3 * n), Zt.col(t).head(3 * n), link, kin, pot);
          computed = link;
        }
        const Matrix& B = which[k] < n ? kin : pot;
        (*parts)[k].block(s * n, t * n, n, n) = B;
        if (symmetric && t != s) (*parts)[k].block(t * n, s * n, n, n) = B.transpose();
      }
      if (h.friction()) {
        for (int i = 0; i < n; ++i) {
          const double f = FrictionCovariance(h, i, Xt(n + i, s), Zt(n + i, t));
          (*F)(s * n + i, t * n + i) = f;
          if (symmetric && t != s) (*F)(t * n + i, s * n + i) = f;
        }
      }
    }
  }
}

// The covariance of the torques at X against Z at the hyper-parameters (kernel + friction +
// effects).
Matrix Covariance(const EulerLagrangeKernel& kernel, const EulerLagrangeGPHyperparameters& h,
                  const FeatureMap* effects, const ConstMatrixRef& X, const ConstMatrixRef& Z,
                  bool symmetric) {
  const int n = kernel.num_joints();
  const Eigen::Index m = X.rows(), p = Z.rows();
  Matrix C = Matrix::Zero(m * n, p * n), block(n, n);
  const Matrix Xt = X.transpose(), Zt = Z.transpose();
  for (Eigen::Index s = 0; s < m; ++s) {
    for (Eigen::Index t = symmetric ? s : 0; t < p; ++t) {
      kernel.Evaluate(Xt.col(s).head(3 * n), Zt.col(t).head(3 * n), h.part_weights, block);
      if (h.friction()) {
        for (int i = 0; i < n; ++i) block(i, i) += FrictionCovariance(h, i, Xt(n + i, s), Zt(n + i, t));
      }
      C.block(s * n, t * n, n, n) = block;
      if (symmetric && t != s) C.block(t * n, s * n, n, n) = block.transpose();
    }
  }
  AddEffects(effects, h, X, Z, &C);
  return C;
}

// log p(y) for C = sum_k w_k parts[k] + F + diag(noise^2), and its gradient in (log w_k...,
// log noise_j...). -infinity when C is not positive definite. On num_threads threads: C's
// columns, the factorisation and the inverse (internal/cholesky.h: the same for every thread
// count from two on, equal to one thread's up to rounding), and the parts' gradient terms
// (each summed by one thread in a fixed order).
double EvidenceOfParts(int n, const std::vector<Matrix>& parts, const Matrix& F, const Vector& y,
                       const double* log_w, const double* log_noise, double* gradient,
                       int num_threads) {
  const size_t P = parts.size();
  const Eigen::Index size = F.rows();
  Matrix C(size, size);
  const int workers = static_cast<int>(
      std::max<Eigen::Index>(1, std::min<Eigen::Index>(num_threads, size / 64)));
  internal::RunWorkers(workers, [&](int w) {
    const Eigen::Index c0 = size * w / workers, c1 = size * (w + 1) / workers;
    auto columns = C.middleCols(c0, c1 - c0);
    columns = F.middleCols(c0, c1 - c0);
    for (size_t k = 0; k < P; ++k) columns += std::exp(log_w[k]) * parts[k].middleCols(c0, c1 - c0);
  });
  for (Eigen::Index r = 0; r < C.rows(); ++r) C(r, r) += std::exp(2.0 * log_noise[r % n]);
  // An evidence is exact or none: a factor the library's acceptance test refuses (a pivot lost
  // to rounding, as when one part's weight dwarfs the noise by 1e13 or more) is no value, so
  // that a search cannot walk into hyper-parameters whose evidence is rounding error.
  internal::Cholesky llt;
  internal::CholeskyOptions factor_options{internal::JitterLadder::kNone};
  factor_options.num_threads = num_threads;
  if (!IsOk(llt.Factorize(C, factor_options).status)) {
    return -std::numeric_limits<double>::infinity();
  }
  const Vector alpha = llt.solve(y);
  double half_logdet = 0.0;
  for (Eigen::Index r = 0; r < C.rows(); ++r) half_logdet += std::log(llt.factor()(r, r));
  const double value = -0.5 * y.dot(alpha) - half_logdet - 0.5 * kLog2Pi * static_cast<double>(y.size());
  if (!std::isfinite(value)) return -std::numeric_limits<double>::infinity();
  if (gradient != nullptr) {
    Matrix Ci = internal::InverseFromFactor(llt.factor(), num_threads);
    // d C / d log s_j = 2 s_j^2 on joint j's diagonal: its term reads C^-1's diagonal. Then,
    // with G = C^-1 - alpha alpha^T (in C^-1's place), d log p / d log w = -1/2 w (tr(C^-1 A)
    // - alpha^T A alpha) = -1/2 w sum(G .* A): one pass over each part.
    for (int j = 0; j < n; ++j) {
      double tr = 0.0, aa = 0.0;
      for (Eigen::Index r = j; r < C.rows(); r += n) {
        tr += Ci(r, r);
        aa += alpha[r] * alpha[r];
      }
      gradient[P + static_cast<size_t>(j)] = -(tr - aa) * std::exp(2.0 * log_noise[j]);
    }
    Matrix& G = Ci;
    internal::RunWorkers(workers, [&](int w) {
      const Eigen::Index c0 = size * w / workers, c1 = size * (w + 1) / workers;
      G.middleCols(c0, c1 - c0).noalias() -= alpha * alpha.segment(c0, c1 - c0).transpose();
    });
    const int part_workers = static_cast<int>(std::max<size_t>(
        1, std::min<size_t>(static_cast<size_t>(workers), P)));
    internal::RunWorkers(part_workers, [&](int w) {
      for (size_t k = static_cast<size_t>(w); k < P; k += static_cast<size_t>(part_workers)) {
        gradient[k] = -0.5 * std::exp(log_w[k]) * G.cwiseProduct(parts[k]).sum();
      }
    });
  }
  return value;
}

// The effects' map (null: none) fits the hyper-parameters' effect prior variances and takes
// the 3N states, or the 3N states and the time. Returns the GP's input dimension.
int CheckEffects(const EulerLagrangeGPHyperparameters& h, const FeatureMap* effects) {
  const int n = h.num_joints();
  Require((effects != nullptr) == h.effects() &&
              (effects == nullptr || (effects->dim() == h.effect_prior_variance.size() &&
                                      (effects->input_dim() == 3 * n ||
                                       effects->input_dim() == 3 * n + 1))),
          "the effects' map and prior variances do not fit each other, or the map takes "
          "neither the 3N states nor the 3N states and the time");
  return effects != nullptr ? effects->input_dim() : 3 * n;
}

// X: m rows of the 3N states (q, qd, qdd), and the time when input_dim is 3N + 1.
void CheckData(const ConstMatrixRef& X, const ConstMatrixRef& Y, int n, int input_dim) {
  Require(Y.cols() == n, "expected " + std::to_string(n) + " torque columns, got " +
                             std::to_string(Y.cols()));
  Require(X.cols() == input_dim,
          "expected " + std::to_string(input_dim) +
              (input_dim == 3 * n ? " state columns" : " columns (the states and the time)") +
              ", got " + std::to_string(X.cols()));
  Require(X.rows() == Y.rows(), "states have " + std::to_string(X.rows()) + " rows, torques " +
                                    std::to_string(Y.rows()));
  Require(X.rows() > 0, "no rows");
  Require(AllFinite(X) && AllFinite(Y), "non-finite state or torque");
}

}  // namespace

void EulerLagrangeGPHyperparameters::Validate() const {
  const int n = num_joints();
  Require(n >= 1 && n <= kMaxEulerLagrangeJoints,
          "expected 1.." + std::to_string(kMaxEulerLagrangeJoints) + " noise levels (one per "
          "joint), got " + std::to_string(n));
  Require(sigma > 0.0 && std::isfinite(sigma), "sigma must be finite and > 0");
  Require(part_weights.size() == 2 * n, "expected " + std::to_string(2 * n) +
                                            " part weights, got " +
                                            std::to_string(part_weights.size()));
  Require(part_weights.allFinite() && (part_weights.array() >= 0.0).all(),
          "part weights must be finite and >= 0");
  Require(noise_std.allFinite() && (noise_std.array() > 0.0).all(),
          "noise stds must be finite and > 0");
  if (friction_std.size() > 0 || friction_velocity_scale.size() > 0) {
    Require(friction_std.size() == n && friction_velocity_scale.size() == n,
            "friction needs " + std::to_string(n) + " prior stds and velocity scales");
    Require(friction_std.allFinite() && (friction_std.array() > 0.0).all() &&
                friction_velocity_scale.allFinite() &&
                (friction_velocity_scale.array() > 0.0).all(),
            "friction prior stds and velocity scales must be finite and > 0");
    Require(coulomb_width > 0.0 && std::isfinite(coulomb_width),
            "coulomb_width must be finite and > 0");
  }
  if (effect_prior_variance.size() > 0 || effect_scale.size() > 0) {
    Require(effect_prior_variance.size() > 0 && effect_scale.size() == n,
            "effects need their prior variances and " + std::to_string(n) + " scales");
    Require(effect_prior_variance.allFinite() && (effect_prior_variance.array() >= 0.0).all() &&
                effect_scale.allFinite() && (effect_scale.array() > 0.0).all(),
            "effect prior variances must be finite and >= 0, their scales finite and > 0");
  }
}

EulerLagrangeGP::EulerLagrangeGP(EulerLagrangeGPHyperparameters hyperparameters,
                                 std::shared_ptr<const FeatureMap> effects)
    : hyper_((hyperparameters.Validate(), std::move(hyperparameters))),
      kernel_(hyper_.num_joints(), hyper_.sigma),
      effects_(std::move(effects)),
      input_dim_(CheckEffects(hyper_, effects_.get())) {}

EulerLagrangeEvidence::EulerLagrangeEvidence(const EulerLagrangeGPHyperparameters& base,
                                             const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                             std::vector<int> parts, const FeatureMap* effects,
                                             int num_threads)
    : n_(base.num_joints()), parts_(std::move(parts)), num_threads_(num_threads) {
  base.Validate();
  Require(num_threads >= 1, "expected num_threads >= 1, got " + std::to_string(num_threads));
  CheckData(X, Y, n_, CheckEffects(base, effects));
  std::vector<bool> searched(static_cast<size_t>(2 * n_), false);
  for (int p : parts_) {
    Require(p >= 0 && p < 2 * n_ && !searched[static_cast<size_t>(p)],
            "part " + std::to_string(p) + " out of range [0, " + std::to_string(2 * n_) +
                ") or repeated");
    searched[static_cast<size_t>(p)] = true;
  }
  std::vector<int> rest;
  for (int p = 0; p < 2 * n_; ++p) {
    if (!searched[static_cast<size_t>(p)] && base.part_weights[p] != 0.0) rest.push_back(p);
  }
  const EulerLagrangeKernel kernel(n_, base.sigma);
  PartGrams(kernel, base, X, X, true, parts_, &grams_, &fixed_);
  if (!rest.empty()) {
    std::vector<Matrix> others;
    Matrix unused;
    EulerLagrangeGPHyperparameters no_friction = base;
    no_friction.friction_std.resize(0);
    no_friction.friction_velocity_scale.resize(0);
    PartGrams(kernel, no_friction, X, X, true, rest, &others, &unused);
    for (size_t k = 0; k < rest.size(); ++k) fixed_ += base.part_weights[rest[k]] * others[k];
  }
  AddEffects(effects, base, X, X, &fixed_);
  y_ = Stack(Y);
}

double EulerLagrangeEvidence::Evaluate(const double* log_parameters, double* gradient) const {
  return EvidenceOfParts(n_, grams_, fixed_, y_, log_parameters, log_parameters + parts_.size(),
                         gradient, num_threads_);
}

double EulerLagrangeGP::LogEvidence(const EulerLagrangeGPHyperparameters& h,
                                    const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                    Vector* gradient) {
  const int n = h.num_joints();
  std::vector<int> all;
  for (int p = 0; p < 2 * n; ++p) all.push_back(p);
  const EulerLagrangeEvidence evidence(h, X, Y, all);
  // The log of a zero weight: the part contributes nothing and its derivative is 0.
  Vector log_parameters(3 * n);
  log_parameters << h.part_weights.array().log(), h.noise_std.array().log();
  if (gradient != nullptr) gradient->resize(3 * n);
  return evidence.Evaluate(log_parameters.data(), gradient != nullptr ? gradient->data() : nullptr);
}

std::vector<int> EulerLagrangeGP::InducingRows(const ConstMatrixRef& X, int count,
                                               InducingRule rule) {
  Require(count >= 0, "inducing states: expected a count >= 0 (0: exact), got " +
                          std::to_string(count));
  if (count == 0 || X.rows() <= count) return {};
  return rule == InducingRule::kCoverStates ? FarthestStateRows(X, count)
                                            : EvenlySpacedRows(X.rows(), count);
}

Status EulerLagrangeGP::Condition(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                  int inducing_count, InducingRule rule, int num_threads) {
  const std::vector<int> rows = InducingRows(X, inducing_count, rule);
  return rows.empty() ? Condition(X, Y, Matrix(), num_threads)
                      : Condition(X, Y, SelectRows(X, rows), num_threads);
}

Status EulerLagrangeGP::Condition(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                  const ConstMatrixRef& inducing, int num_threads) {
  const int n = num_joints();
  CheckData(X, Y, n, input_dim_);
  Require(num_threads >= 1, "expected num_threads >= 1, got " + std::to_string(num_threads));
  const Vector& noise = hyper_.noise_std;
  if (inducing.size() == 0) {
    Matrix C = Covariance(kernel_, hyper_, effects_.get(), X, X, true);
    for (Eigen::Index r = 0; r < C.rows(); ++r) C(r, r) += noise[r % n] * noise[r % n];
    // The exact posterior, as the kernel form's: accepted by the library's test or refused.
    internal::Cholesky llt;
    if (!IsOk(llt.Factorize(C, {internal::JitterLadder::kNone}).status)) {
      return Status::kNotPositiveDefinite;
    }
    C = Matrix();
    const Vector y = Stack(Y);
    Vector alpha = llt.solve(y);
    double half_logdet = 0.0;
    for (Eigen::Index r = 0; r < llt.size(); ++r) half_logdet += std::log(llt.factor()(r, r));
    const double log_evidence =
        -0.5 * y.dot(alpha) - half_logdet - 0.5 * kLog2Pi * static_cast<double>(y.size());
    Adopt(llt.ReleaseFactor(), Matrix(), std::move(alpha), log_evidence, X, X, Y);
    return Status::kOk;
  }
  // K_ZZ + J = L L^T (J: a jitter of 1e-8 of the mean diagonal, higher rungs of the library's
  // ladder if the test refuses it), V = L^-1 K_ZX S^-1/2, B = I + V V^T,
  // alpha = L^-T B^-1 V S^-1/2 y.
  internal::Cholesky llt;
  if (!FactorizeInducing(inducing, &llt)) return Status::kNotPositiveDefinite;
  // V = L^-1 K_ZX S^-1/2 block by block of training states: B = I + sum_b V_b V_b^T and
  // vy = sum_b V_b S_b^-1/2 y_b. The workers take the blocks a group at a time: each forms,
  // scales and solves one block's columns, then they share B's lower triangle and vy in panels
  // of kDtcPanelRows rows, each panel adding the group's blocks in block order. Every block
  // and panel has a fixed size and is one worker's, so the sums are the same in the same order
  // for any number of workers, and no worker needs a (p N)^2 scratch of its own.
  Vector ys = Stack(Y);
  for (Eigen::Index r = 0; r < ys.size(); ++r) ys[r] /= noise[r % n];
  const Eigen::Index pn = llt.size();
  const Eigen::Index blocks = (X.rows() + kDtcBlockStates - 1) / kDtcBlockStates;
  const Eigen::Index panels = (pn + kDtcPanelRows - 1) / kDtcPanelRows;
  const int workers =
      static_cast<int>(std::max<Eigen::Index>(1, std::min<Eigen::Index>(num_threads, blocks)));
  std::vector<Matrix> V(static_cast<size_t>(workers));  // one block's columns per worker
  const auto& L = llt.matrixL();
  Matrix B = Matrix::Zero(pn, pn);
  Vector vy = Vector::Zero(pn);
  for (Eigen::Index group = 0; group < blocks; group += workers) {
    const int in_group = static_cast<int>(std::min<Eigen::Index>(workers, blocks - group));
    auto first_state = [&](int w) { return (group + w) * kDtcBlockStates; };
    auto block_states = [&](int w) {
      return std::min(kDtcBlockStates, X.rows() - first_state(w));
    };
    internal::RunWorkers(in_group, [&](int w) {
      Matrix& Vw = V[static_cast<size_t>(w)];
      Vw = Covariance(kernel_, hyper_, effects_.get(), inducing,
                      X.middleRows(first_state(w), block_states(w)), false);  // (p N) x (count N)
      for (Eigen::Index r = 0; r < Vw.cols(); ++r) Vw.col(r) /= noise[r % n];
      L.solveInPlace(Vw);
    });
    // The panels from the last (the widest rows of B's lower triangle) to the first, each to
    // the next free worker.
    std::atomic<Eigen::Index> next_panel{0};
    internal::RunWorkers(static_cast<int>(std::min<Eigen::Index>(workers, panels)), [&](int) {
      for (Eigen::Index k = next_panel++; k < panels; k = next_panel++) {
        const Eigen::Index r0 = (panels - 1 - k) * kDtcPanelRows;
        const Eigen::Index rows = std::min(kDtcPanelRows, pn - r0);
        for (int w = 0; w < in_group; ++w) {
          const Matrix& Vw = V[static_cast<size_t>(w)];
          const auto Vr = Vw.middleRows(r0, rows);
          if (r0 > 0) B.block(r0, 0, rows, r0).noalias() += Vr * Vw.topRows(r0).transpose();
          B.block(r0, r0, rows, rows).selfadjointView<Eigen::Lower>().rankUpdate(Vr);
          vy.segment(r0, rows).noalias() +=
              Vr * ys.segment(first_state(w) * n, block_states(w) * n);
        }
      }
    });
  }
  V.clear();
  B.diagonal().array() += 1.0;
  internal::Cholesky llt_b;
  if (!IsOk(llt_b.Factorize(B, {internal::JitterLadder::kNone}).status)) {
    return Status::kNotPositiveDefinite;
  }
  B = Matrix();
  Vector alpha = llt.matrixU().solve(llt_b.solve(vy));
  // log N(y; 0, Q + S), Q = K_XZ K_ZZ^-1 K_ZX: |Q + S| = |S| |B| and
  // y^T (Q + S)^-1 y = |S^-1/2 y|^2 - |L_B^-1 V S^-1/2 y|^2.
  double half_logdet = 0.0;
  for (Eigen::Index r = 0; r < llt_b.size(); ++r) half_logdet += std::log(llt_b.factor()(r, r));
  for (Eigen::Index r = 0; r < ys.size(); ++r) half_logdet += std::log(noise[r % n]);
  const double quad = ys.squaredNorm() - llt_b.matrixL().solve(vy).squaredNorm();
  const double log_evidence =
      -0.5 * quad - half_logdet - 0.5 * kLog2Pi * static_cast<double>(ys.size());
  Adopt(llt.ReleaseFactor(), llt_b.ReleaseFactor(), std::move(alpha), log_evidence, inducing, X,
        Y);
  return Status::kOk;
}

bool EulerLagrangeGP::FactorizeInducing(const ConstMatrixRef& inducing,
                                        internal::Cholesky* llt) const {
  Require(inducing.cols() == input_dim_, "inducing states need " + std::to_string(input_dim_) +
                                             " columns, got " + std::to_string(inducing.cols()));
  Require(AllFinite(inducing), "non-finite inducing state");
  const Matrix Kzz = Covariance(kernel_, hyper_, effects_.get(), inducing, inducing, true);
  return IsOk(llt->Factorize(Kzz, {internal::JitterLadder::kClimb,
                                   internal::JitterScale::kMeanDiagonal, kInducingRelativeJitter})
                  .status);
}

const Vector& EulerLagrangeGP::dtc_alpha() const {
  if (!dtc_) {
    throw std::logic_error("EulerLagrangeGP::dtc_alpha: not conditioned through inducing states");
  }
  return alpha_;
}

const Matrix& EulerLagrangeGP::dtc_factor_b() const {
  if (!dtc_) {
    throw std::logic_error(
        "EulerLagrangeGP::dtc_factor_b: not conditioned through inducing states");
  }
  return factor_b_;
}

Status EulerLagrangeGP::CheckDtcFactors(Eigen::Index pn, const DtcFactors& factors) {
  if (factors.alpha.size() != pn || factors.factor_b.rows() != pn ||
      factors.factor_b.cols() != pn || !std::isfinite(factors.log_evidence) ||
      !AllFinite(factors.alpha)) {
    return Status::kInvalidInput;
  }
  // B = I + V V^T >= I, so every diagonal entry of its Cholesky factor is at least 1 (the
  // square root of a Schur complement of B, itself >= 1); a little below 1 is rounding.
  for (Eigen::Index c = 0; c < pn; ++c) {
    const auto column = factors.factor_b.col(c).tail(pn - c);
    if (!AllFinite(column) || !(column[0] >= 1.0 - 1e-9)) return Status::kInvalidInput;
  }
  return Status::kOk;
}

Status EulerLagrangeGP::RestoreDtc(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                   const ConstMatrixRef& inducing, DtcFactors factors) {
  const int n = num_joints();
  CheckData(X, Y, n, input_dim_);
  Require(inducing.rows() > 0, "RestoreDtc needs inducing states");
  if (CheckDtcFactors(inducing.rows() * n, factors) != Status::kOk) return Status::kInvalidInput;
  internal::Cholesky llt;
  if (!FactorizeInducing(inducing, &llt)) return Status::kNotPositiveDefinite;
  Adopt(llt.ReleaseFactor(), std::move(factors.factor_b), std::move(factors.alpha),
        factors.log_evidence, inducing, X, Y);
  return Status::kOk;
}

void EulerLagrangeGP::Adopt(Matrix factor, Matrix factor_b, Vector alpha, double log_evidence,
                            const ConstMatrixRef& states, const ConstMatrixRef& X,
                            const ConstMatrixRef& Y) {
  factor_ = std::move(factor);
  factor_b_ = std::move(factor_b);
  alpha_ = std::move(alpha);
  log_evidence_ = log_evidence;
  dtc_ = factor_b_.size() > 0;
  states_ = states;
  states_t_ = states.transpose();
  SetEffectStates();
  inputs_ = X;
  targets_ = Y;
}

void EulerLagrangeGP::SetEffectStates() {
  if (!effects_) return;
  effects_->EvaluateRows(states_, &effect_z_);
  effect_z_ = effect_z_ * hyper_.effect_prior_variance.asDiagonal();
}

Status EulerLagrangeGP::Predict(const ConstMatrixRef& X, Matrix* mean,
                                Matrix* latent_variance) const {
  if (!conditioned()) throw std::logic_error("EulerLagrangeGP::Predict: not conditioned");
  const int n = num_joints();
  if (X.cols() != input_dim_ || !AllFinite(X)) return Status::kInvalidInput;
  mean->resize(X.rows(), n);
  if (latent_variance != nullptr) latent_variance->resize(X.rows(), n);
  Workspace w = MakeWorkspace();
  Vector x(input_dim_), m(n), v(latent_variance != nullptr ? n : 0);
  for (Eigen::Index s = 0; s < X.rows(); ++s) {
    x = X.row(s).transpose();
    const Status status = PredictOne(x, m, v, w);
    if (status != Status::kOk) return status;
    mean->row(s) = m.transpose();
    if (latent_variance != nullptr) latent_variance->row(s) = v.transpose();
  }
  return Status::kOk;
}

EulerLagrangeGP::Workspace EulerLagrangeGP::MakeWorkspace() const {
  if (!conditioned()) throw std::logic_error("EulerLagrangeGP::MakeWorkspace: not conditioned");
  const Eigen::Index n = num_joints(), pn = states_.rows() * n;
  return Workspace{Matrix(n, pn), Matrix(pn, n), Matrix(n, n),
                   Vector(effects_ ? effects_->dim() : 0), Vector(effects_ ? states_.rows() : 0)};
}

Status EulerLagrangeGP::PredictOne(const ConstVectorRef& x, VectorRef mean,
                                   VectorRef latent_variance, Workspace& w) const {
  if (!conditioned()) throw std::logic_error("EulerLagrangeGP::PredictOne: not conditioned");
  const int n = num_joints();
  const Eigen::Index p = states_.rows();
  if (x.size() != input_dim_ || mean.size() != n || !x.allFinite() ||
      (latent_variance.size() != 0 && latent_variance.size() != n) || w.ks.rows() != n ||
      w.ks.cols() != p * n || w.v.rows() != p * n || w.v.cols() != n || w.block.rows() != n ||
      w.block.cols() != n || w.phi.size() != (effects_ ? effects_->dim() : 0) ||
      w.g.size() != (effects_ ? p : 0)) {
    return Status::kInvalidInput;
  }
  for (Eigen::Index t = 0; t < p; ++t) {
    kernel_.Evaluate(x.head(3 * n), states_t_.col(t).head(3 * n), hyper_.part_weights, w.block);
    if (hyper_.friction()) {
      for (int i = 0; i < n; ++i) {
        w.block(i, i) += FrictionCovariance(hyper_, i, x[n + i], states_t_(n + i, t));
      }
    }
    w.ks.middleCols(t * n, n) = w.block;
  }
  if (effects_) {
    effects_->Evaluate(x, w.phi);
    w.g.noalias() = effect_z_ * w.phi;
    for (Eigen::Index t = 0; t < p; ++t) {
      for (int i = 0; i < n; ++i) {
        w.ks(i, t * n + i) += hyper_.effect_scale[i] * hyper_.effect_scale[i] * w.g[t];
      }
    }
  }
  mean.noalias() = w.ks * alpha_;
  if (latent_variance.size() == 0) return Status::kOk;
  kernel_.Evaluate(x.head(3 * n), x.head(3 * n), hyper_.part_weights, w.block);
  if (hyper_.friction()) {
    for (int i = 0; i < n; ++i) w.block(i, i) += FrictionCovariance(hyper_, i, x[n + i], x[n + i]);
  }
  if (effects_) {
    const double own = w.phi.dot(hyper_.effect_prior_variance.cwiseProduct(w.phi));
    for (int i = 0; i < n; ++i) w.block(i, i) += hyper_.effect_scale[i] * hyper_.effect_scale[i] * own;
  }
  w.v = w.ks.transpose();
  factor_.triangularView<Eigen::Lower>().solveInPlace(w.v);
  for (int i = 0; i < n; ++i) latent_variance[i] = w.block(i, i) - w.v.col(i).squaredNorm();
  if (dtc_) {
    factor_b_.triangularView<Eigen::Lower>().solveInPlace(w.v);
    for (int i = 0; i < n; ++i) latent_variance[i] += w.v.col(i).squaredNorm();
  }
  latent_variance = latent_variance.cwiseMax(0.0);
  return Status::kOk;
}

Hyperparameters ToHyperparameters(const EulerLagrangeGPHyperparameters& h) {
  h.Validate();
  const int n = h.num_joints();
  Hyperparameters out;
  const int fri = h.friction() ? 2 * n + 1 : 0;
  out.shape.resize(1 + 2 * n + fri + (h.effects() ? n : 0));
  out.shape[0] = std::log(h.sigma);
  out.shape.segment(1, 2 * n) = h.part_weights.cwiseMax(1e-300).array().log();
  if (h.friction()) {
    out.shape.segment(1 + 2 * n, n) = h.friction_std.array().log();
    out.shape.segment(1 + 3 * n, n) = h.friction_velocity_scale.array().log();
    out.shape[1 + 4 * n] = std::log(h.coulomb_width);
  }
  if (h.effects()) out.shape.tail(n) = h.effect_scale.array().log();
  out.log_block_scale.resize(0);
  out.log_noise_std = 0.0;
  out.log_output_scale = h.noise_std.array().log();
  return out;
}

std::vector<std::string> EulerLagrangeParameterNames(int num_joints, bool friction,
                                                     bool effects) {
  std::vector<std::string> names = {"log_sigma"};
  for (const char* kind : {"kinetic", "potential"}) {
    for (int j = 1; j <= num_joints; ++j) {
      names.push_back(std::string("log_weight_") + kind + "_" + std::to_string(j));
    }
  }
  if (friction) {
    for (const char* what : {"std", "velocity_scale"}) {
      for (int j = 1; j <= num_joints; ++j) {
        names.push_back(std::string("log_friction_") + what + "_" + std::to_string(j));
      }
    }
    names.push_back("log_coulomb_width");
  }
  if (effects) {
    for (int j = 1; j <= num_joints; ++j) names.push_back("log_effect_scale_" + std::to_string(j));
  }
  return names;
}

EulerLagrangeGPHyperparameters EulerLagrangeFromHyperparameters(
    const Hyperparameters& hyper, int num_joints, bool friction,
    const Vector& effect_prior_variance) {
  const int n = num_joints;
  Require(n >= 1 && n <= kMaxEulerLagrangeJoints,
          "expected 1.." + std::to_string(kMaxEulerLagrangeJoints) + " joints, got " +
              std::to_string(n));
  const bool effects = effect_prior_variance.size() > 0;
  hyper.Validate(1 + 2 * n + (friction ? 2 * n + 1 : 0) + (effects ? n : 0), 0, n,
                 "EulerLagrangeGP hyper-parameters");
  EulerLagrangeGPHyperparameters h;
  h.sigma = std::exp(hyper.shape[0]);
  h.part_weights = hyper.shape.segment(1, 2 * n).array().exp();
  h.noise_std = hyper.noise_stds();
  if (friction) {
    h.friction_std = hyper.shape.segment(1 + 2 * n, n).array().exp();
    h.friction_velocity_scale = hyper.shape.segment(1 + 3 * n, n).array().exp();
    h.coulomb_width = std::exp(hyper.shape[1 + 4 * n]);
  }
  if (effects) {
    h.effect_prior_variance = effect_prior_variance;
    h.effect_scale = hyper.shape.tail(n).array().exp();
  }
  h.Validate();
  return h;
}

double EulerLagrangeGP::LogMarginalLikelihood() const {
  if (!conditioned()) {
    throw std::logic_error("EulerLagrangeGP::LogMarginalLikelihood: not conditioned");
  }
  return log_evidence_;
}

EulerLagrangeJointFeatureMap::EulerLagrangeJointFeatureMap(const EulerLagrangeGP& gp,
                                                           const ConstMatrixRef& Z, int joint)
    : n_(gp.num_joints()),
      joint_(joint),
      hyper_(gp.hyperparameters()),
      kernel_(gp.kernel()),
      effects_(gp.effects()),
      input_dim_(gp.input_dim()) {
  Require(joint >= 0 && joint < n_, "joint " + std::to_string(joint) + " out of range [0, " +
                                        std::to_string(n_) + ")");
  Require(Z.rows() >= 1 && Z.cols() == input_dim_ && Z.allFinite(),
          "inducing states: expected p >= 1 finite rows of " + std::to_string(input_dim_) +
              " columns, got " + std::to_string(Z.rows()) + " x " + std::to_string(Z.cols()));
  Require(!effects_ || effects_->dim() <= kMaxJointMapEffectFeatures,
          "at most " + std::to_string(kMaxJointMapEffectFeatures) + " effect features, got " +
              std::to_string(effects_ ? effects_->dim() : 0));
  states_t_ = Z.transpose();
  if (effects_) {
    effects_->EvaluateRows(Z, &effect_z_);
    effect_z_ = effect_z_ * hyper_.effect_prior_variance.asDiagonal();
  }
  const Matrix K = Covariance(kernel_, hyper_, effects_.get(), Z, Z, true);
  internal::Cholesky llt;
  if (IsOk(llt.Factorize(K, {internal::JitterLadder::kClimb, internal::JitterScale::kMeanDiagonal,
                             kInducingRelativeJitter})
               .status)) {
    factor_ = llt.ReleaseFactor();
    return;
  }
  throw std::runtime_error(
      "EulerLagrangeJointFeatureMap: the covariance at the inducing states cannot be factorised");
}

void EulerLagrangeJointFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  using Block = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxEulerLagrangeJoints,
                              kMaxEulerLagrangeJoints>;
  Require(x.size() == input_dim_ && phi.size() == dim(),
          "expected an input of " + std::to_string(input_dim_) + " and " +
              std::to_string(dim()) + " features");
  const int n = n_, j = joint_;
  Block block(n, n);
  const Eigen::Index p = states_t_.cols();
  for (Eigen::Index t = 0; t < p; ++t) {
    kernel_.Evaluate(x.head(3 * n), states_t_.col(t).head(3 * n), hyper_.part_weights, block);
    for (int i = 0; i < n; ++i) phi[t * n + i] = block(j, i);
    if (hyper_.friction()) {
      phi[t * n + j] += FrictionCovariance(hyper_, j, x[n + j], states_t_(n + j, t));
    }
  }
  if (effects_) {
    Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxJointMapEffectFeatures, 1> e(effects_->dim());
    effects_->Evaluate(x, e);
    const double s2 = hyper_.effect_scale[j] * hyper_.effect_scale[j];
    for (Eigen::Index t = 0; t < p; ++t) phi[t * n + j] += s2 * effect_z_.row(t).dot(e);
  }
  factor_.triangularView<Eigen::Lower>().solveInPlace(phi);
}

std::vector<FeatureBlock> EulerLagrangeJointFeatureMap::blocks() const {
  return {FeatureBlock{"euler_lagrange_nystrom", 0, dim()}};
}

}  // namespace structgp
