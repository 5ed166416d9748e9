#include "structgp/hyper/euler_lagrange_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <ceres/ceres.h>

#include "structgp/core/row_subset.h"

namespace structgp {
namespace {

void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("FitEulerLagrangeGP: " + what);
}

double Rms(const ConstMatrixRef& A, Eigen::Index col) {
  return std::sqrt(A.col(col).squaredNorm() / static_cast<double>(A.rows()));
}

// -log evidence - log prior for Ceres.
class NegativeLogPosterior : public ceres::FirstOrderFunction {
 public:
  NegativeLogPosterior(const EulerLagrangeEvidence& evidence, const LogHyperprior& prior)
      : evidence_(evidence), prior_(prior) {}
  int NumParameters() const override { return evidence_.num_parameters(); }
  bool Evaluate(const double* p, double* cost, double* gradient) const override {
    const double value = evidence_.Evaluate(p, gradient);
    if (!std::isfinite(value)) return false;
    *cost = -value;
    if (gradient != nullptr) {
      for (int k = 0; k < NumParameters(); ++k) gradient[k] = -gradient[k];
    }
    *cost += prior_.NegativeLogDensity(Eigen::Map<const Vector>(p, NumParameters()), gradient);
    return std::isfinite(*cost);
  }

 private:
  const EulerLagrangeEvidence& evidence_;
  const LogHyperprior& prior_;
};

// The prior of options.prior centred on the data-derived start (log part weights, then log
// noise levels), or none.
LogHyperprior Prior(const HyperpriorOptions& options, const std::vector<double>& centre,
                    size_t num_parts) {
  if (options.family == HyperpriorFamily::kNone) return LogHyperprior();
  Vector c = Eigen::Map<const Vector>(centre.data(), static_cast<Eigen::Index>(centre.size()));
  Vector w(c.size());
  for (Eigen::Index k = 0; k < c.size(); ++k) {
    w[k] = static_cast<size_t>(k) < num_parts ? options.block_scale_width : options.noise_width;
  }
  return LogHyperprior(options.family, std::move(c), std::move(w), options.degrees_of_freedom);
}

// The base hyper-parameters at sigma: zero part weights, unit noise, and friction's prior std
// the joint's RMS torque, its velocity scale the joint's RMS velocity (data-derived scales).
EulerLagrangeGPHyperparameters Base(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                    const EulerLagrangeGPOptions& options, double sigma) {
  const int n = static_cast<int>(Y.cols());
  EulerLagrangeGPHyperparameters h;
  h.sigma = sigma;
  h.noise_std = Vector::Ones(n);
  h.part_weights = Vector::Zero(2 * n);
  if (options.friction) {
    h.coulomb_width = options.coulomb_width;
    h.friction_std.resize(n);
    h.friction_velocity_scale.resize(n);
    for (int j = 0; j < n; ++j) {
      h.friction_std[j] = std::max(Rms(Y, j), 1e-12);
      h.friction_velocity_scale[j] = std::max(Rms(X, n + j), 1e-3);
    }
  }
  if (options.effects) {
    h.effect_prior_variance = options.effect_prior_variance;
    h.effect_scale.resize(n);
    for (int j = 0; j < n; ++j) h.effect_scale[j] = std::max(Rms(Y, j), 1e-12);
  }
  return h;
}

// The parts searched: one weight per link's kinetic and potential energy, or link N's only.
std::vector<int> SearchedParts(int n, bool per_link) {
  std::vector<int> searched;
  for (int kind = 0; kind < 2; ++kind) {
    for (int link = 0; link < n; ++link) {
      if (per_link || link == n - 1) searched.push_back(kind * n + link);
    }
  }
  return searched;
}

// A searched part whose mean prior variance on the evidence rows is at most this fraction of
// the largest part's is one the rows do not excite (at rounding level: a log whose joint
// accelerations are all zero leaves the first link's kinetic energy, I_1 qdd_1, unseen). Its
// weight cannot be measured against those rows: divided by that variance it would be
// astronomical (e^71 on such a log, and predictions of 1e14 N m wherever the joint
// accelerates), so it starts at the median of the excited parts' weights instead and its
// search leaves it where the prior holds it.
constexpr double kUnexcitedPartVarianceRatio = 1e-12;

// Which searched parts the evidence rows do not excite (see kUnexcitedPartVarianceRatio).
std::vector<bool> UnexcitedParts(const EulerLagrangeEvidence& evidence) {
  const int P = static_cast<int>(evidence.parts().size());
  double largest = 0.0;
  for (int k = 0; k < P; ++k) largest = std::max(largest, evidence.MeanPartVariance(k));
  std::vector<bool> unexcited(static_cast<size_t>(P));
  for (int k = 0; k < P; ++k) {
    const double v = evidence.MeanPartVariance(k);
    unexcited[static_cast<size_t>(k)] = !(v > kUnexcitedPartVarianceRatio * largest);
  }
  return unexcited;
}

// The log of part k's mean prior variance on the evidence's rows (the scale a part's weight is
// measured against when it is carried to the next sigma); 0 for a part they do not excite
// (UnexcitedParts), whose weight carries over as it is.
double LogMeanPartVariance(const EulerLagrangeEvidence& evidence,
                           const std::vector<bool>& unexcited, size_t k) {
  if (unexcited[k]) return 0.0;
  return std::log(std::max(evidence.MeanPartVariance(static_cast<int>(k)), 1e-300));
}

// The start of the search (log part weights of the searched parts, log noise per joint): the
// torques' mean square shared by the parts, each at its own mean prior variance (a part the
// rows do not excite, as UnexcitedParts says: the median of the others' log weights), and the
// noise at 10% of each joint's RMS torque.
std::vector<double> Start(const EulerLagrangeEvidence& evidence, const std::vector<bool>& unexcited,
                          const ConstMatrixRef& Yh) {
  const int n = static_cast<int>(Yh.cols());
  const int P = static_cast<int>(evidence.parts().size());
  double spread = 0.0;
  for (int j = 0; j < n; ++j) spread += Rms(Yh, j) * Rms(Yh, j) / n;
  std::vector<double> p(static_cast<size_t>(P + n));
  std::vector<double> excited;
  for (int k = 0; k < P; ++k) {
    p[static_cast<size_t>(k)] =
        std::log(std::max(spread, 1e-300) / P / std::max(evidence.MeanPartVariance(k), 1e-300));
    if (!unexcited[static_cast<size_t>(k)]) excited.push_back(p[static_cast<size_t>(k)]);
  }
  double median = 0.0;
  if (!excited.empty()) {
    std::sort(excited.begin(), excited.end());
    const size_t h = excited.size() / 2;
    median = excited.size() % 2 == 1 ? excited[h] : 0.5 * (excited[h - 1] + excited[h]);
  }
  for (int k = 0; k < P; ++k) {
    if (unexcited[static_cast<size_t>(k)]) p[static_cast<size_t>(k)] = median;
  }
  for (int j = 0; j < n; ++j) {
    p[static_cast<size_t>(P + j)] = std::log(std::max(0.1 * Rms(Yh, j), 1e-12));
  }
  return p;
}

// h with the searched parts' weights and the noise levels of p (logs).
EulerLagrangeGPHyperparameters WithParameters(EulerLagrangeGPHyperparameters h,
                                              const std::vector<int>& searched,
                                              const std::vector<double>& p) {
  const int P = static_cast<int>(searched.size());
  for (int k = 0; k < P; ++k) {
    h.part_weights[searched[static_cast<size_t>(k)]] = std::exp(p[static_cast<size_t>(k)]);
  }
  for (int j = 0; j < h.num_joints(); ++j) h.noise_std[j] = std::exp(p[static_cast<size_t>(P + j)]);
  return h;
}

// X: the 3N states, and the time last when the options' effects take it.
void CheckFitData(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                  const EulerLagrangeGPOptions& options) {
  const int n = static_cast<int>(Y.cols());
  Require(n >= 1 && n <= kMaxEulerLagrangeJoints,
          "expected 1.." + std::to_string(kMaxEulerLagrangeJoints) + " torque columns, got " +
              std::to_string(n));
  const int width = options.effects ? options.effects->input_dim() : 3 * n;
  Require(X.cols() == width && X.rows() == Y.rows() && X.rows() > 0,
          "expected " + std::string(width == 3 * n ? "states" : "states and times") + " m x " +
              std::to_string(width) + " beside torques m x " +
              std::to_string(n) + ", got " + std::to_string(X.rows()) + " x " +
              std::to_string(X.cols()) + " and " + std::to_string(Y.rows()) + " x " +
              std::to_string(n));
  Require(X.allFinite() && Y.allFinite(), "non-finite state or torque");
}

}  // namespace

EulerLagrangeGPHyperparameters EulerLagrangeStart(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                                  const EulerLagrangeGPOptions& options,
                                                  double sigma) {
  options.Validate();
  CheckFitData(X, Y, options);
  Require(sigma > 0.0 && std::isfinite(sigma), "sigma must be finite and > 0");
  const int n = static_cast<int>(Y.cols());
  const std::vector<int> rows = EvenlySpacedRows(X.rows(), options.hyperparameter_rows);
  const Matrix Xh = SelectRows(X, rows), Yh = SelectRows(Y, rows);
  const EulerLagrangeGPHyperparameters base = Base(X, Y, options, sigma);
  const std::vector<int> searched = SearchedParts(n, options.per_link);
  const EulerLagrangeEvidence evidence(base, Xh, Yh, searched, options.effects.get());
  return WithParameters(base, searched, Start(evidence, UnexcitedParts(evidence), Yh));
}

void EulerLagrangeGPOptions::Validate() const {
  Require(!sigmas.empty(), "options: no sigma to try");
  for (double s : sigmas) {
    Require(s > 0.0 && std::isfinite(s), "options: sigmas must be finite and > 0, got " +
                                             std::to_string(s));
  }
  Require(coulomb_width > 0.0 && std::isfinite(coulomb_width),
          "options: coulomb_width must be finite and > 0");
  Require(hyperparameter_rows >= 0, "options: hyperparameter_rows must be >= 0");
  Require(inducing_states >= 0, "options: inducing_states must be >= 0");
  Require(max_iterations >= 1, "options: max_iterations must be >= 1");
  Require(num_threads >= 1, "options: num_threads must be >= 1");
  std::string prior_error;
  Require(prior.IsValid(&prior_error), "options: prior: " + prior_error);
  if (start) {
    Require(start->sigma > 0.0 && std::isfinite(start->sigma),
            "options: start's sigma must be finite and > 0");
    const int n = start->num_joints();
    Require(n >= 1 && start->part_weights.size() == 2 * n,
            "options: start needs 2N part weights and N noise levels");
    for (int k : SearchedParts(n, per_link)) {
      Require(start->part_weights[k] > 0.0 && std::isfinite(start->part_weights[k]),
              "options: start's weight of part " + std::to_string(k) + " must be finite and > 0");
    }
    Require(start->noise_std.allFinite() && (start->noise_std.array() > 0.0).all(),
            "options: start's noise levels must be finite and > 0");
  }
  Require((effects != nullptr) == (effect_prior_variance.size() > 0) &&
              (effects == nullptr || effects->dim() == effect_prior_variance.size()),
          "options: effects need a map and one prior variance per feature");
}

EulerLagrangeGPSummary FitEulerLagrangeGP(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                          const EulerLagrangeGPOptions& options,
                                          std::optional<EulerLagrangeGP>* gp) {
  const auto start = std::chrono::steady_clock::now();
  options.Validate();
  CheckFitData(X, Y, options);
  const int n = static_cast<int>(Y.cols());
  if (gp != nullptr) gp->reset();
  EulerLagrangeGPSummary summary;
  summary.rows = static_cast<int>(X.rows());
  const std::vector<int> hyper_rows = EvenlySpacedRows(X.rows(), options.hyperparameter_rows);
  summary.hyperparameter_rows = static_cast<int>(hyper_rows.size());
  const Matrix Xh = SelectRows(X, hyper_rows), Yh = SelectRows(Y, hyper_rows);
  const std::vector<int> searched = SearchedParts(n, options.per_link);

  double best = -std::numeric_limits<double>::infinity();
  EulerLagrangeGPHyperparameters best_h;
  if (options.start) {
    Require(options.start->num_joints() == n,
            "options: start has " + std::to_string(options.start->num_joints()) +
                " joints, the data " + std::to_string(n));
  }
  std::vector<double> sigmas =
      options.start ? std::vector<double>{options.start->sigma} : options.sigmas;
  std::sort(sigmas.begin(), sigmas.end());
  sigmas.erase(std::unique(sigmas.begin(), sigmas.end()), sigmas.end());
  // The previous sigma's optimum with each part's log weight plus the log of its mean prior
  // variance (the scale that carries over between sigmas); empty before the first usable one.
  std::vector<double> carried;
  const size_t P = searched.size();
  for (double sigma : sigmas) {
    summary.sigmas.push_back(sigma);
    summary.log_evidence_per_sigma.push_back(std::numeric_limits<double>::quiet_NaN());
    summary.log_prior_per_sigma.push_back(std::numeric_limits<double>::quiet_NaN());
    summary.iterations_per_sigma.push_back(0);
    summary.warm_start_per_sigma.push_back(false);
    summary.evaluations_per_sigma.push_back(0);
    const EulerLagrangeGPHyperparameters base = Base(X, Y, options, sigma);
    const EulerLagrangeEvidence evidence(base, Xh, Yh, searched, options.effects.get(),
                                         options.num_threads);
    const std::vector<bool> unexcited = UnexcitedParts(evidence);
    std::vector<double> p = Start(evidence, unexcited, Yh);
    if (summary.sigmas.size() == 1) {
      std::string names;
      int count = 0;
      for (size_t k = 0; k < P; ++k) {
        if (!unexcited[k]) continue;
        ++count;
        const int part = searched[k];
        names += (names.empty() ? "" : ", ") +
                 std::string(part < n ? "kinetic energy of link " : "potential energy of link ") +
                 std::to_string(part % n + 1);
      }
      if (!names.empty()) {
        summary.warnings.push_back(
            "the " + std::to_string(hyper_rows.size()) +
            " hyper-parameter rows do not excite the " + names +
            " (prior variance there at rounding level: e.g. no joint acceleration in the log); " +
            (count == 1 ? std::string("its weight is") : std::string("their weights are")) +
            " the median of the other parts', not measured: predictions of motions that need " +
            (count == 1 ? "it" : "them") +
            " carry that prior's uncertainty. Train on a log that excites every joint.");
      }
    }
    const LogHyperprior prior = Prior(options.prior, p, P);
    auto penalty = [&](const std::vector<double>& x) {  // -log p(x)
      return prior.NegativeLogDensity(
          Eigen::Map<const Vector>(x.data(), static_cast<Eigen::Index>(x.size())));
    };
    auto objective = [&](const std::vector<double>& x) {
      return evidence.Evaluate(x.data(), nullptr) - penalty(x);
    };
    if (options.start) {
      for (size_t k = 0; k < P; ++k) p[k] = std::log(options.start->part_weights[searched[k]]);
      for (int j = 0; j < n; ++j) p[P + static_cast<size_t>(j)] = std::log(options.start->noise_std[j]);
    }
    if (!carried.empty()) {
      std::vector<double> warm = carried;
      for (size_t k = 0; k < P; ++k) warm[k] -= LogMeanPartVariance(evidence, unexcited, k);
      if (objective(warm) > objective(p)) {
        p = std::move(warm);
        summary.warm_start_per_sigma.back() = true;
      }
    }
    const double start_penalty = penalty(p);
    ceres::GradientProblem problem(new NegativeLogPosterior(evidence, prior));
    ceres::GradientProblemSolver::Options o;
    o.max_num_iterations = options.max_iterations;
    o.logging_type = ceres::SILENT;
    ceres::GradientProblemSolver::Summary s;
    ceres::Solve(o, problem, p.data(), &s);
    summary.iterations_per_sigma.back() = static_cast<int>(s.iterations.size());
    summary.evaluations_per_sigma.back() = s.num_cost_evaluations + s.num_gradient_evaluations;
    if (summary.sigmas.size() == 1 && std::isfinite(s.initial_cost)) {
      summary.initial_log_evidence = -s.initial_cost + start_penalty;
    }
    if (!s.IsSolutionUsable() || !std::isfinite(s.final_cost)) continue;
    const double log_prior = -penalty(p);
    summary.log_evidence_per_sigma.back() = -s.final_cost - log_prior;
    summary.log_prior_per_sigma.back() = log_prior;
    carried = p;
    for (size_t k = 0; k < P; ++k) carried[k] += LogMeanPartVariance(evidence, unexcited, k);
    if (-s.final_cost > best) {
      best = -s.final_cost;
      best_h = WithParameters(base, searched, p);
      summary.log_evidence = -s.final_cost - log_prior;
      summary.log_prior = log_prior;
    }
  }
  auto finish = [&](Status status, std::string message) {
    summary.status = status;
    summary.message = std::move(message);
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
  };
  if (!std::isfinite(best)) {
    return finish(Status::kNotPositiveDefinite,
                  "type-II maximum likelihood found no usable hyper-parameters at any sigma");
  }
  summary.hyperparameters = best_h;
  if (gp == nullptr) return finish(Status::kOk, "");
  EulerLagrangeGP model(best_h, options.effects);
  const Status status =
      model.Condition(X, Y, options.inducing_states, options.inducing_rule, options.num_threads);
  if (model.dtc()) summary.inducing_states = static_cast<int>(model.states().rows());
  if (!IsOk(status)) {
    return finish(status, "the posterior's factorisation failed at the fitted hyper-parameters");
  }
  gp->emplace(std::move(model));
  return finish(Status::kOk, "");
}

}  // namespace structgp
