#include "structgp/diagnose/diagnosis.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>
#include <set>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include <Eigen/Cholesky>
#include <boost/math/distributions/chi_squared.hpp>
#include <nlohmann/json.hpp>

#include "structgp/core/validate.h"
#include "structgp/core/noise_level.h"
#include "structgp/diagnose/autocorrelation.h"
#include "structgp/feature/effect_feature_map.h"
#include "structgp/feature/effects.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/regressor_feature_map.h"
#include "structgp/fit/fit_model.h"
#include "structgp/kernel/nystrom_feature_map.h"
#include "structgp/core/row_subset.h"
#include "structgp/core/segments.h"
#include "structgp/hyper/cross_validation.h"
#include "structgp/hyper/evidence.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/internal/cholesky.h"
#include "structgp/internal/text.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/rigid_body/dh_chain.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {
namespace {

using Index = std::vector<int>;

struct Candidate {
  std::string effect;
  int joint = 0;  // 1-based
  EffectParameters params;
  Index cols;      // columns in the design matrix F
  std::string spec;
  std::string scope = "all";  // Suggestion::scope
  bool alive = true;
};

// Folds as (begin, size): SegmentFolds' blocks (whole trajectories when the log has enough of
// them), in time order.
std::vector<std::pair<int, int>> Folds(int m, int k, const std::vector<int>& starts) {
  std::vector<std::pair<int, int>> folds = SegmentFolds(m, k, starts);
  for (auto& fold : folds) fold.second -= fold.first;
  return folds;
}

// Noise level from successive differences of a residual, robustly: a missing effect that is
// smooth along the log cancels in the differences, and the median ignores its rare jumps (a
// Coulomb step at each velocity reversal): median |r_{i+1} - r_i| / (0.6745 sqrt 2).
std::vector<Concentration> Concentrations(const Vector& r, const Matrix& vars,
                                          const std::vector<std::string>& names, int bins) {
  const int m = static_cast<int>(r.size());
  const double mean = r.mean();
  const double total = (r.array() - mean).square().sum();
  std::vector<Concentration> out;
  if (total <= 0.0 || m < 2 * bins) return out;
  for (int v = 0; v < vars.cols(); ++v) {
    std::vector<int> order(static_cast<size_t>(m));
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int a, int b) { return vars(a, v) < vars(b, v); });
    Concentration c;
    c.variable = names[static_cast<size_t>(v)];
    double between = 0.0;
    for (int b = 0; b < bins; ++b) {
      const int begin = m * b / bins, end = m * (b + 1) / bins;
      double s = 0.0, ss = 0.0;
      for (int i = begin; i < end; ++i) {
        s += r[order[i]] - mean;
        ss += r[order[i]] * r[order[i]];
      }
      const int count = end - begin;
      between += s * s / count;
      const double rms = std::sqrt(ss / count);
      if (rms > c.bin_rms) {
        c.bin_rms = rms;
        c.bin_low = vars(order[begin], v);
        c.bin_high = vars(order[end - 1], v);
      }
    }
    c.explained = between / total;
    out.push_back(c);
  }
  std::sort(out.begin(), out.end(),
            [](const Concentration& a, const Concentration& b) { return a.explained > b.explained; });
  if (out.size() > 3) out.resize(3);
  return out;
}

// The evidence gains are those of these exact precisions: the library's factorisation without
// jitter (internal/cholesky.h).
const internal::CholeskyOptions kExactFactorisation{internal::JitterLadder::kNone,
                                                    internal::JitterScale::kDiagonal, 0.0};

// One fit of the base columns B on some statistics, kept to score candidates.
struct BaseFit {
  internal::Cholesky llt;  // of A_B
  Matrix W;                // A_B^{-1} b_B (|B| x P)
  bool ok = false;
};

// G: a Matrix, or a FoldGram (below); read as G(I, J) with index lists.
template <typename Gram>
BaseFit FitBase(const Gram& G, const Matrix& cross, const Index& B, const Vector& lambda,
                double s2n) {
  BaseFit fit;
  Matrix A = G(B, B);
  for (size_t i = 0; i < B.size(); ++i) A(i, i) += s2n / lambda[B[i]];
  if (fit.llt.Factorize(A, kExactFactorisation).status != Status::kOk) return fit;
  fit.W = fit.llt.solve(Matrix(cross(B, Eigen::all)));
  fit.ok = fit.W.allFinite();
  return fit;
}

// Adds the columns E to a base fit: Z (Schur complement), u, and the new weights.
struct Augmented {
  internal::Cholesky z;
  Matrix u;    // |E| x P
  Matrix V;    // L^{-1} G(B, E)
  bool ok = false;
};

template <typename Gram>
Augmented Augment(const BaseFit& base, const Gram& G, const Matrix& cross, const Index& B,
                  const Index& E, const Vector& lambda, double s2n) {
  Augmented a;
  const Matrix GBE = G(B, E);
  a.V = base.llt.matrixL().solve(GBE);
  Matrix Z = G(E, E);
  for (size_t i = 0; i < E.size(); ++i) Z(i, i) += s2n / lambda[E[i]];
  Z.noalias() -= a.V.transpose() * a.V;
  if (a.z.Factorize(Z, kExactFactorisation).status != Status::kOk) return a;
  a.u = Matrix(cross(E, Eigen::all)) - GBE.transpose() * base.W;
  a.ok = a.u.allFinite();
  return a;
}

// Gain in log evidence of joint j's torque when the columns E are added (Schur complement Z
// of the base precision; docs/diagnosis.md):
//   0.5 u_j^T Z^{-1} u_j / (sigma^2 s_j^2) - 0.5 (log|Z| + log|Lambda_E| - k log sigma^2).
double LogEvidenceGain(const Augmented& aug, const Index& E, const Vector& lambda, double s2n,
                       double s2j, int j) {
  const Vector zu = aug.z.solve(Vector(aug.u.col(j)));
  const double log_det_z = 2.0 * Matrix(aug.z.matrixL()).diagonal().array().log().sum();
  double log_lambda_e = 0.0;
  for (int col : E) log_lambda_e += std::log(lambda[col]);
  const double k = static_cast<double>(E.size());
  return 0.5 * aug.u.col(j).dot(zu) / (s2n * s2j) -
         0.5 * (log_det_z + log_lambda_e - k * std::log(s2n));
}

// Noise level and output scales re-estimated by evidence on a log whose base statistics are
// gram = Phi^T Phi and cross = Phi^T Y (the model's prior structure kept).
Hyperparameters ProfileOnLog(const std::shared_ptr<const FeatureMap>& base_map, Matrix gram,
                             Matrix cross, const ConstMatrixRef& Y, const Hyperparameters& h) {
  SufficientStatistics base_stats(base_map->dim(), static_cast<int>(Y.cols()));
  base_stats.gram = std::move(gram);
  base_stats.cross = std::move(cross);
  base_stats.y_squared = Y.colwise().squaredNorm().transpose();
  base_stats.count = static_cast<int>(Y.rows());
  WeightSpaceEvidence evidence(base_map, std::move(base_stats));
  return ProfileNoiseAndScales(evidence, h);
}

// ResidualContext::score: the log-evidence gain of one joint's torque when an effect is added
// to the base features, against the base alone (before any suggestion), with the noise and
// scales profiled on the log as in the selection. Set up on the first call (one O(m D^2)
// pass), so that effects which do not score cost nothing.
class EvidenceScorer {
 public:
  EvidenceScorer(std::shared_ptr<const FeatureMap> base_map, const Matrix& Phi,
                 const ConstMatrixRef& Y, const Matrix& Xt, const Hyperparameters& hyper,
                 double broad_prior_std)
      : base_map_(std::move(base_map)), Phi_(Phi), Y_(Y), Xt_(Xt), hyper_(hyper),
        broad_variance_(broad_prior_std * broad_prior_std) {}

  // The effect on rows from_row.. only (its columns zero before: Suggestion::scope "log").
  double Score(const std::string& name, int joint, const EffectParameters& params,
               int from_row = 0) {
    std::shared_ptr<const Effect> effect;
    try {
      effect = MakeEffect(name, params);
    } catch (const std::invalid_argument&) {
      return -HUGE_VAL;
    }
    if (!ready_) {
      try {
        SetUp();
      } catch (const std::runtime_error&) {
        base_.ok = false;  // the evidence of the log could not be profiled: nothing to score
      }
    }
    if (!base_.ok) return -HUGE_VAL;
    const int N = static_cast<int>(Y_.cols());
    EffectFeatureMap map(N, effect, {joint}, /*with_time=*/true);
    Matrix E;
    map.EvaluateRows(Xt_, &E);
    E.topRows(from_row).setZero();
    const int D = static_cast<int>(Phi_.cols()), k = static_cast<int>(E.cols());
    Matrix G(D + k, D + k), cross(D + k, N);
    G.topLeftCorner(D, D) = gram_;
    G.topRightCorner(D, k) = Phi_.transpose() * E;
    G.bottomLeftCorner(k, D) = G.topRightCorner(D, k).transpose();
    G.bottomRightCorner(k, k) = E.transpose() * E;
    cross.topRows(D) = cross_;
    cross.bottomRows(k) = E.transpose() * Y_;
    Vector lambda(D + k);
    lambda.head(D) = lambda_;
    lambda.tail(k).setConstant(broad_variance_);
    Index B(static_cast<size_t>(D)), cols(static_cast<size_t>(k));
    std::iota(B.begin(), B.end(), 0);
    std::iota(cols.begin(), cols.end(), D);
    const Augmented aug = Augment(base_, G, cross, B, cols, lambda, s2n_);
    if (!aug.ok) return -HUGE_VAL;
    const double s = hyper_.output_scales()[joint - 1];
    const double gain = LogEvidenceGain(aug, cols, lambda, s2n_, s * s, joint - 1);
    return std::isfinite(gain) ? gain : -HUGE_VAL;
  }

 private:
  void SetUp() {
    ready_ = true;
    gram_ = Phi_.transpose() * Phi_;
    cross_ = Phi_.transpose() * Y_;
    hyper_ = ProfileOnLog(base_map_, gram_, cross_, Y_, hyper_);
    lambda_ = PriorVariance(*base_map_, hyper_);
    s2n_ = hyper_.noise_variance();
    Index B(static_cast<size_t>(Phi_.cols()));
    std::iota(B.begin(), B.end(), 0);
    base_ = FitBase(gram_, cross_, B, lambda_, s2n_);
  }

  std::shared_ptr<const FeatureMap> base_map_;
  const Matrix& Phi_;
  ConstMatrixRef Y_;
  const Matrix& Xt_;
  Hyperparameters hyper_;
  double broad_variance_;
  bool ready_ = false;
  Matrix gram_, cross_;
  Vector lambda_;
  double s2n_ = 0.0;
  BaseFit base_;
};

}  // namespace

const char* ToString(DiagnosisOptions::Autocorrelation correction) {
  switch (correction) {
    case DiagnosisOptions::Autocorrelation::kNone: return "none";
    case DiagnosisOptions::Autocorrelation::kBartlett: return "bartlett";
    case DiagnosisOptions::Autocorrelation::kPrewhitening: return "prewhitening";
  }
  return "unknown";
}

bool FromString(const std::string& text, DiagnosisOptions::Autocorrelation* correction) {
  for (const auto c : {DiagnosisOptions::Autocorrelation::kNone,
                       DiagnosisOptions::Autocorrelation::kBartlett,
                       DiagnosisOptions::Autocorrelation::kPrewhitening}) {
    if (text == ToString(c)) {
      *correction = c;
      return true;
    }
  }
  return false;
}

const char* ToString(DiagnosisStatus status) {
  switch (status) {
    case DiagnosisStatus::kOk:
      return "ok";
    case DiagnosisStatus::kNumericalFailure:
      return "numerical_failure";
  }
  return "unknown";
}

bool DiagnosisOptions::IsValid(std::string* error) const {
  auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = "DiagnosisOptions::" + message;
    return false;
  };
  std::string holding_error;
  if (!holding.IsValid(&holding_error)) return fail("holding." + holding_error);
  auto number = [](double v) {
    std::ostringstream os;
    os << v;
    return os.str();
  };
  if (folds < 2) return fail("folds: expected >= 2, got " + std::to_string(folds));
  if (!(min_log_evidence_gain >= 0.0) || !std::isfinite(min_log_evidence_gain)) {
    return fail("min_log_evidence_gain: expected a finite value >= 0 nats, got " +
                number(min_log_evidence_gain));
  }
  if (!(min_relative_rms_gain >= 0.0 && min_relative_rms_gain < 1.0)) {
    return fail("min_relative_rms_gain: expected a fraction in [0, 1), got " +
                number(min_relative_rms_gain));
  }
  if (max_suggestions < 0) {
    return fail("max_suggestions: expected >= 0, got " + std::to_string(max_suggestions));
  }
  if (max_refused < 0) {
    return fail("max_refused: expected >= 0, got " + std::to_string(max_refused));
  }
  if (bins < 1) return fail("bins: expected >= 1, got " + std::to_string(bins));
  const std::vector<std::string> known = EffectNames();
  for (const std::string& name : candidates) {
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string list;
      for (const auto& n : known) list += (list.empty() ? "" : ", ") + n;
      return fail("candidates: unknown effect '" + name + "' (known: " + list + ")");
    }
  }
  // A search range names a parameter of a registered effect and lies in its valid range.
  for (const auto& [key, range] : search_ranges) {
    const auto dot = key.find('.');
    const std::string effect = dot == std::string::npos ? key : key.substr(0, dot);
    const EffectParameter* parameter = nullptr;
    std::vector<EffectParameter> info;
    if (dot != std::string::npos && std::find(known.begin(), known.end(), effect) != known.end()) {
      info = EffectParameterInfo(effect);
      for (const EffectParameter& p : info) {
        if (p.name == key.substr(dot + 1)) parameter = &p;
      }
    }
    if (parameter == nullptr) {
      return fail("search_ranges: '" + key + "' names no parameter of a registered effect " +
                  "(expected \"effect.parameter\", e.g. \"cogging.period\")");
    }
    if (!(range.min <= range.max) || !parameter->valid.Contains(range.min) ||
        !parameter->valid.Contains(range.max)) {
      return fail("search_ranges: '" + key + "' expected min <= max, both " +
                  parameter->ExpectedText() + ", got [" + number(range.min) + ", " +
                  number(range.max) + "]");
    }
  }
  if (!(significance > 0.0 && significance < 1.0)) {
    return fail("significance: expected a level in (0, 1), got " + number(significance));
  }
  if (!(min_residual_fall >= 0.0 && min_residual_fall < 1.0)) {
    return fail("min_residual_fall: expected a fraction in [0, 1), got " +
                number(min_residual_fall));
  }
  if (!(held_out_fall_alone > 0.0 && held_out_fall_alone <= 1.0)) {
    return fail("held_out_fall_alone: expected a fraction in (0, 1], got " +
                number(held_out_fall_alone));
  }
  if (!(min_effect_to_noise >= 0.0) || !std::isfinite(min_effect_to_noise)) {
    return fail("min_effect_to_noise: expected a finite value >= 0, got " +
                number(min_effect_to_noise));
  }
  if (!(min_effect_z >= 0.0) || !std::isfinite(min_effect_z)) {
    return fail("min_effect_z: expected a finite value >= 0, got " + number(min_effect_z));
  }
  if (confirmation_gap < -1) {
    return fail("confirmation_gap: expected -1 (automatic) or >= 0 rows, got " +
                std::to_string(confirmation_gap));
  }
  if (!(coverage_ratio >= 1.0) || !std::isfinite(coverage_ratio)) {
    return fail("coverage_ratio: expected a finite value >= 1, got " + number(coverage_ratio));
  }
  if (!(noise_tolerance >= 1.0) || !std::isfinite(noise_tolerance)) {
    return fail("noise_tolerance: expected a finite value >= 1, got " + number(noise_tolerance));
  }
  if (nystrom_features < 1) {
    return fail("nystrom_features: expected >= 1, got " + std::to_string(nystrom_features));
  }
  return true;
}

namespace {

// Suggestions by score, at most max_suggestions; refused candidates (those that passed against
// the model alone first, then by their white-noise gain), at most max_refused, without an
// effect that is suggested on that joint (in either scope).
void OrderFindings(const DiagnosisOptions& options, Diagnosis* d) {
  std::stable_sort(d->suggestions.begin(), d->suggestions.end(),
                   [](const Suggestion& a, const Suggestion& b) { return a.score > b.score; });
  if (static_cast<int>(d->suggestions.size()) > options.max_suggestions) {
    d->suggestions.resize(static_cast<size_t>(options.max_suggestions));
  }
  auto suggested = [&](const Refusal& r) {
    return std::any_of(d->suggestions.begin(), d->suggestions.end(), [&](const Suggestion& s) {
      return s.effect == r.candidate.effect && s.joint == r.candidate.joint;
    });
  };
  d->refused.erase(std::remove_if(d->refused.begin(), d->refused.end(), suggested),
                   d->refused.end());
  std::stable_sort(d->refused.begin(), d->refused.end(), [](const Refusal& a, const Refusal& b) {
    if (a.after_suggestions != b.after_suggestions) return a.after_suggestions;
    return a.candidate.score_uncorrected > b.candidate.score_uncorrected;
  });
  if (static_cast<int>(d->refused.size()) > options.max_refused) {
    d->refused.resize(static_cast<size_t>(options.max_refused));
  }
}

// The Gram matrix of a held-out block's fit rows, G_total - G_block - F_gap^T F_gap, read by
// index lists as a Matrix is: the rows of the gap next to the block are kept as rows (at most
// twice the gap), not as a Gram matrix over every column, so that the fold sets of joints with
// different gaps share the blocks' Gram matrices.
struct FoldGram {
  const Matrix* total = nullptr;
  const Matrix* block = nullptr;
  Matrix gap;  // F(gap rows, all columns)
  Matrix operator()(const Index& I, const Index& J) const {
    Matrix r = (*total)(I, J) - (*block)(I, J);
    if (gap.rows() > 0) r.noalias() -= gap(Eigen::all, I).transpose() * gap(Eigen::all, J);
    return r;
  }
};

// Held-out blocks of the confirmation and the statistics of each block's fit.
struct FoldSet {
  int first = 0;                            // the rows first.. it splits
  std::vector<std::pair<int, int>> ranges;  // (first row, rows) of each held-out block
  int gap = 0;                              // rows left out on each side (same trajectory)
  bool by_trajectory = false;               // blocks are whole trajectories
  int held_out_rows = 0;                    // rows of all blocks
  std::vector<FoldGram> G;                  // Phi^T Phi of each block's fit rows
  std::vector<Matrix> cross;                // Phi^T Y of each block's fit rows
};

// Diagnose, with numerical trouble deep inside (a profile of the evidence, the Nystrom
// factorisation, a prediction) as std::runtime_error.
// only_joint (1-based, 0: every joint): the candidates of that joint alone; a model with a
// regressor (rbd) is diagnosed one joint at a time, against the features of its row, and
// test_multiplier (the number of joints) makes each call count every joint's tests.
// X, Y, t: the rows the candidates are scored on, segment starts `starts`; the diagnosed log is
// rows log_begin.. (the training data, when given, come first).
Diagnosis DiagnoseOrThrow(const RobotModel& model, const ConstMatrixRef& X,
                          const ConstMatrixRef& Y, const Vector& t,
                          const std::vector<int>& starts, int log_begin,
                          const DiagnosisOptions& options, int only_joint,
                          int test_multiplier) {
  std::string invalid;
  if (!options.IsValid(&invalid)) throw std::invalid_argument("Diagnose: " + invalid);
  const bool euler = model.fitted() && model.gp().euler_lagrange() != nullptr;
  if (!model.fitted() ||
      (!model.feature_map() && !model.kernel() && !model.regressor_map() && !euler)) {
    throw std::invalid_argument("Diagnose: needs a fitted model");
  }
  const int N = model.num_joints();
  const int m = static_cast<int>(X.rows());
  RequireSize("Diagnose X", X.cols(), model.input_dim(), "columns");
  RequireSize("Diagnose Y", Y.cols(), N, "columns (joints)");
  RequireSize("Diagnose Y", Y.rows(), m, "rows (as in X)");
  if (t.size() != 0) RequireSize("Diagnose t", t.size(), m, "entries (rows of X)");
  RequireFinite("Diagnose X", X);
  RequireFinite("Diagnose Y", Y);
  if (t.size() != 0) RequireFinite("Diagnose t", t);
  if (options.folds < 2 || m < 4 * options.folds) {
    throw std::invalid_argument("Diagnose: need at least " + std::to_string(4 * options.folds) +
                                " rows for " + std::to_string(options.folds) +
                                "-fold blocked cross-validation, got " + std::to_string(m));
  }

  // The features the candidates are scored against: the model's own map, or for a model in
  // function space (rbf, rbfs, pol beyond its explicit map) Nystrom features of its kernel
  // on inducing states chosen among these rows.
  std::shared_ptr<const FeatureMap> base_map = model.feature_map();
  Hyperparameters base_hyper = model.hyperparameters();
  // Per-joint hyper-parameters: one joint at a time against that joint's own set (and, without
  // a feature map, its own kernel), each column keeping its joint's output scale (only this
  // joint's column is read); the branches below then serve it as they serve a shared set.
  std::unique_ptr<Kernel> joint_kernel;
  std::string per_joint_text;
  if (model.per_joint()) {
    if (only_joint < 1) {
      throw std::logic_error("Diagnose: a model with per-joint hyper-parameters is diagnosed per "
                             "joint");
    }
    Hyperparameters own = base_hyper.Output(only_joint - 1);
    own.log_output_scale.resize(N);
    for (int j = 0; j < N; ++j) own.log_output_scale[j] = base_hyper.Output(j).log_output_scale[0];
    base_hyper = own;
    if (!base_map) joint_kernel = model.kernel()->WithParameters(own.shape);
    per_joint_text = ", with each joint's own hyper-parameters, one joint at a time";
  }
  const Kernel* kernel = joint_kernel ? joint_kernel.get() : model.kernel();
  Diagnosis out;
  if (base_map) {
    out.features =
        "the model's feature map (D = " + std::to_string(base_map->dim()) + ")" + per_joint_text;
  } else if (model.regressor_map()) {
    if (only_joint < 1) throw std::logic_error("Diagnose: a regressor model is diagnosed per joint");
    base_map = std::make_shared<RegressorFeatureMap>(model.regressor_map(), only_joint - 1);
    Hyperparameters h = DefaultHyperparameters(*base_map, N);
    h.log_noise_std = base_hyper.log_noise_std;
    h.log_output_scale = base_hyper.log_output_scale;
    base_hyper = h;
    out.features = "each joint's row of the model's rigid-body regressor (P = " +
                   std::to_string(base_map->dim()) + "), one joint at a time";
  } else if (euler) {
    if (only_joint < 1) throw std::logic_error("Diagnose: a lagk model is diagnosed per joint");
    // Nystrom features of this joint's torque under the model's prior, on inducing states
    // covering the rows: p states of N torques each.
    const EulerLagrangeGP& gp = *model.gp().euler_lagrange();
    const int p = std::max(1, std::min(options.nystrom_features / N, m / 2));
    // (The rows keep the time when the model's effects take it.)
    const Matrix Z = SelectRows(X, FarthestStateRows(X.leftCols(3 * N), p));
    base_map = std::make_shared<EulerLagrangeJointFeatureMap>(gp, Z, only_joint - 1);
    Hyperparameters h = DefaultHyperparameters(*base_map, N);
    // The features carry the prior's scale: unit output scales, the joint's own noise.
    h.log_noise_std = std::log(gp.hyperparameters().noise_std[only_joint - 1]);
    h.log_output_scale = Vector::Zero(N);
    base_hyper = h;
    out.features = "Nystrom features of each joint's torque under the model's Euler-Lagrange "
                   "prior on " + std::to_string(Z.rows()) +
                   " inducing states covering the rows (D = " + std::to_string(base_map->dim()) +
                   "), one joint at a time";
  } else {
    const Matrix Z =
        SelectInducingStates(*kernel, X, std::min(options.nystrom_features, m / 2));
    base_map = std::make_shared<NystromFeatureMap>(*kernel, Z);
    Hyperparameters h = DefaultHyperparameters(*base_map, N);
    h.log_noise_std = base_hyper.log_noise_std;
    h.log_output_scale = base_hyper.log_output_scale;
    base_hyper = h;
    out.features = "Nystrom features of the model's kernel on " + std::to_string(Z.rows()) +
                   " inducing states chosen among the rows (D = " +
                   std::to_string(base_map->dim()) + ")" + per_joint_text;
  }
  const int m_log = m - log_begin;
  out.num_samples = m_log;
  out.model = ToString(model.spec());
  if (!model.spec().effects.empty()) out.model += " + " + ToString(model.spec().effects);

  // ---- residuals of the model as it is -----------------------------------------------------
  // On the model's batch threads (RobotModelOptions::batch, LoadOptions::num_threads of a
  // loaded model): the same predictions bit for bit for any number.
  Matrix mean;
  model.PredictRows(X.bottomRows(m_log), &mean, nullptr, model.options().batch.num_threads);
  const Matrix R = Y.bottomRows(m_log) - mean;
  Matrix vars(m_log, 3 * N + (t.size() ? 1 : 0));
  vars.leftCols(3 * N) = X.bottomRows(m_log).leftCols(3 * N);
  std::vector<std::string> var_names;
  for (const char* prefix : {"q", "qd", "qdd"}) {
    for (int j = 1; j <= N; ++j) var_names.push_back(prefix + std::to_string(j));
  }
  if (t.size()) {
    vars.col(3 * N) = t.tail(m_log);
    var_names.push_back("t");
  }
  for (int j = 0; j < N; ++j) {
    JointFinding f;
    f.joint = j + 1;
    const Vector r = R.col(j);
    f.rms = std::sqrt(r.squaredNorm() / m_log);
    const Vector y = Y.col(j).tail(m_log);
    const double var_y = (y.array() - y.mean()).square().mean();
    f.nmse = var_y > 0 ? f.rms * f.rms / var_y : 0.0;
    f.concentrations = Concentrations(r, vars, var_names, options.bins);
    out.joints.push_back(f);
  }

  // ---- candidates -----------------------------------------------------------------------------
  const auto& spec = model.spec();
  // Blocks the model contains (Effect::spanned_by): its feature map's, and in function space
  // the friction block that "+fri" puts in its kernel.
  std::set<std::string> model_blocks;
  if (model.feature_map()) {
    for (const FeatureBlock& b : model.feature_map()->blocks()) model_blocks.insert(b.name);
  }
  if (spec.friction) model_blocks.insert(FrictionFeatureMap::kBlockName);
  auto model_has = [&](const Effect& effect, int joint) {
    for (const std::string& block : effect.spanned_by()) {
      if (model_blocks.count(block)) return true;
    }
    for (const auto& e : spec.effects) {
      if (e.name != effect.name()) continue;
      if (e.joints.empty() || effect.joint_independent()) return true;
      if (std::find(e.joints.begin(), e.joints.end(), joint) != e.joints.end()) return true;
    }
    return false;
  };
  // Inputs of the candidate maps: the state and the time.
  Matrix Xt(m, 3 * N + 1);
  Xt.leftCols(3 * N) = X.leftCols(3 * N);
  Xt.col(3 * N) = t.size() ? t : Vector::Zero(m);

  Matrix Phi;
  base_map->EvaluateRows(X, &Phi);
  const Matrix Yg = model.prior_mean() ? Matrix(Y - model.PriorMeanRows(X)) : Matrix(Y);
  Matrix refit_residual;
  {
    const Hyperparameters& h = base_hyper;
    WeightSpaceGP refit(PriorVariance(*base_map, h), h.noise_variance(), N,
                        h.output_scales());
    // The refit learns what the model's GP learns: the torques less its prior mean (rbd+<base>).
    if (refit.Fit(Phi, Yg) != Status::kOk) {
      out.status = DiagnosisStatus::kNumericalFailure;
      out.message = "the model could not be refitted on these data (posterior precision not "
                    "positive definite)";
      return out;
    }
    refit_residual = Yg - Phi * refit.weights();
  }
  for (int j = 0; j < N; ++j) {
    // The noise from the refit's residual: the model's own residual on a log it extrapolates
    // to is large and varies from row to row by more than the noise.
    const Vector r = refit_residual.col(j).tail(m_log);
    out.joints[static_cast<size_t>(j)].refit_rms = std::sqrt(r.squaredNorm() / m_log);
    out.joints[static_cast<size_t>(j)].noise_std_estimate = NoiseFromDifferences(r, {0});
  }


  std::vector<Candidate> candidates;
  std::vector<Matrix> blocks;  // candidate columns, in order
  int next_col = base_map->dim();
  // scope "log": the effect on the diagnosed log's rows only (columns zero on the training rows).
  auto add_candidate = [&](const std::string& name, int joint, EffectParameters params,
                           const std::string& scope) {
    std::shared_ptr<const Effect> effect;
    try {
      effect = MakeEffect(name, params);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("Diagnose: effect '" + name +
                                  "' proposed parameters it does not accept: " + e.what());
    }
    EffectFeatureMap map(N, effect, {joint}, /*with_time=*/true);
    Matrix E;
    map.EvaluateRows(Xt, &E);
    if (scope == "log") E.topRows(log_begin).setZero();
    Candidate c;
    c.effect = name;
    c.joint = joint;
    c.params = params;
    c.scope = scope;
    EffectSpec es{name, {joint}, params};
    c.spec = ToString(es);
    for (int k = 0; k < E.cols(); ++k) c.cols.push_back(next_col++);
    blocks.push_back(std::move(E));
    candidates.push_back(std::move(c));
  };
  EvidenceScorer scorer(base_map, Phi, Yg, Xt, base_hyper, model.options().broad_prior_std);
  const std::vector<std::string> names =
      options.candidates.empty() ? EffectNames() : options.candidates;
  for (const auto& name : names) {
    const std::unique_ptr<Effect> prototype = MakeEffectPrototype(name);
    // A time-dependent effect cannot be tried on data without time.
    if (prototype->uses_time() && t.size() == 0) continue;
    std::map<std::string, ParameterRange> search;
    for (const EffectParameter& p : EffectParameterInfo(name)) {
      const auto it = options.search_ranges.find(name + "." + p.name);
      search[p.name] = it != options.search_ranges.end() ? it->second
                       : p.search                        ? *p.search
                                                         : p.valid;
    }
    for (int j = 1; j <= N; ++j) {
      if (only_joint > 0 && j != only_joint) continue;
      // The effect proposes its parameters from what a refit of the model on these data
      // cannot explain (the model's own residual also carries its extrapolation error).
      if (!model_has(*prototype, j)) {
        ResidualContext context(j, X.col(j - 1), X.col(N + j - 1), X.col(2 * N + j - 1), t,
                                refit_residual.col(j - 1));
        context.search_ranges = search;
        context.score = [&scorer, name, j](const EffectParameters& p) {
          return scorer.Score(name, j, p);
        };
        for (EffectParameters& params : prototype->ProposeParameters(context)) {
          add_candidate(name, j, std::move(params), "all");
        }
      }
      // With the training data, on the diagnosed log alone, from the log's rows: what the
      // robot does now and did not then (an effect the model has on every row included: its
      // change in this log is another hypothesis), not diluted by the rows without it.
      if (log_begin > 0) {
        ResidualContext context(j, X.col(j - 1).tail(m_log), X.col(N + j - 1).tail(m_log),
                                X.col(2 * N + j - 1).tail(m_log),
                                t.size() ? t.tail(m_log) : t.head(0),
                                refit_residual.col(j - 1).tail(m_log));
        context.search_ranges = search;
        context.score = [&scorer, name, j, log_begin](const EffectParameters& p) {
          return scorer.Score(name, j, p, log_begin);
        };
        for (EffectParameters& params : prototype->ProposeParameters(context)) {
          add_candidate(name, j, std::move(params), "log");
        }
      }
    }
  }

  // ---- design matrix and its statistics ------------------------------------------------------
  Matrix F(m, next_col);
  F.leftCols(Phi.cols()) = Phi;
  {
    int col = static_cast<int>(Phi.cols());
    for (const auto& E : blocks) {
      F.middleCols(col, E.cols()) = E;
      col += static_cast<int>(E.cols());
    }
  }
  std::vector<int> segment_of(static_cast<size_t>(m));
  for (size_t s = 0; s < starts.size(); ++s) {
    const int end = s + 1 < starts.size() ? starts[s + 1] : m;
    for (int i = starts[s]; i < end; ++i) segment_of[static_cast<size_t>(i)] = static_cast<int>(s);
  }
  auto statistics = [&](const std::vector<int>& rows, Matrix* G, Matrix* cross) {
    SufficientStatistics s(next_col, N);
    if (!rows.empty()) s.Accumulate(F(rows, Eigen::all), Yg(rows, Eigen::all));
    *G = s.gram.selfadjointView<Eigen::Lower>();
    *cross = std::move(s.cross);
  };
  Matrix G_total, cross_total;
  {
    SufficientStatistics s(next_col, N);
    s.Accumulate(F, Yg);
    G_total = s.gram.selfadjointView<Eigen::Lower>();
    cross_total = std::move(s.cross);
  }
  // Held-out blocks of the rows first.. first + count - 1 (whole trajectories when they hold
  // enough of them), each block's fit on every other row but the gap: rows next to a held-out
  // block (same trajectory) are too correlated with it to count as unseen. The gap is joint
  // j's own (how far apart its residuals are unrelated), so that another joint's residual
  // does not change how j's candidates are confirmed; the statistics come later, once per
  // distinct set.
  auto fold_layout = [&](int first, int count, int j) {
    FoldSet set;
    set.first = first;
    std::vector<int> local_starts;
    for (int s : starts) {
      if (s >= first && s < first + count) local_starts.push_back(s - first);
    }
    set.by_trajectory = static_cast<int>(local_starts.size()) >= options.folds;
    set.ranges = Folds(count, options.folds, local_starts);
    for (auto& range : set.ranges) range.first += first;
    if (!set.by_trajectory) {
      int smallest = count;
      for (const auto& [begin, size] : set.ranges) smallest = std::min(smallest, size);
      set.gap = options.confirmation_gap >= 0
                    ? options.confirmation_gap
                    : CorrelationLength(refit_residual.col(j).segment(first, count),
                                        local_starts, 0.1);
      set.gap = std::min(set.gap, smallest / 2);
    }
    return set;
  };
  // Each block's own statistics, per first row of a split (the joints' sets of one split
  // differ in their gaps only); the fold sets point into them.
  std::map<int, std::vector<std::pair<Matrix, Matrix>>> block_statistics;
  auto fold_statistics = [&](FoldSet* set) {
    auto& own = block_statistics[set->first];
    if (own.empty()) {
      for (const auto& [begin, size] : set->ranges) {
        std::vector<int> rows(static_cast<size_t>(size));
        std::iota(rows.begin(), rows.end(), begin);
        own.emplace_back();
        statistics(rows, &own.back().first, &own.back().second);
      }
    }
    for (size_t f = 0; f < set->ranges.size(); ++f) {
      const auto [begin, size] = set->ranges[f];
      const int end = begin + size;
      std::vector<int> gap_rows;
      for (int i = std::max(0, begin - set->gap); i < begin; ++i) {
        if (segment_of[i] == segment_of[begin]) gap_rows.push_back(i);
      }
      for (int i = end; i < std::min(m, end + set->gap); ++i) {
        if (segment_of[i] == segment_of[end - 1]) gap_rows.push_back(i);
      }
      FoldGram gram;
      gram.total = &G_total;
      gram.block = &own[f].first;
      gram.gap = F(gap_rows, Eigen::all);
      set->G.push_back(std::move(gram));
      set->cross.push_back(cross_total - own[f].second);
      if (!gap_rows.empty()) {
        set->cross.back().noalias() -= set->G.back().gap.transpose() * Yg(gap_rows, Eigen::all);
      }
      set->held_out_rows += size;
    }
  };
  // Per scope, every row's blocks; and with the training data, the diagnosed log's own
  // blocks, where an effect of scope "log" acts (its columns are zero on the training rows):
  // it is confirmed on unseen parts of the log, with the training rows in every block's fit.
  // Over every row, a log that is a small part of the rows is held out in one or two blocks
  // whose fits keep little or nothing of it to fit the effect on.
  const bool log_folds = log_begin > 0 && m_log >= 4 * options.folds;
  const int num_scopes = log_folds ? 2 : 1;
  auto folds_of_scope = [&](const std::string& scope) -> int {
    return scope == "log" && log_folds ? 1 : 0;
  };
  std::vector<FoldSet> fold_sets;
  // fold_set_of[j][scope]: joint j's blocks (an index into fold_sets; joints whose gaps agree
  // share them).
  std::vector<std::array<int, 2>> fold_set_of(static_cast<size_t>(N), {-1, -1});
  for (int j = 0; j < N; ++j) {
    if (only_joint > 0 && j != only_joint - 1) continue;
    for (int scope = 0; scope < num_scopes; ++scope) {
      FoldSet set = scope == 0 ? fold_layout(0, m, j) : fold_layout(log_begin, m_log, j);
      int index = -1;
      for (size_t k = 0; k < fold_sets.size(); ++k) {
        if (fold_sets[k].first == set.first && fold_sets[k].gap == set.gap) {
          index = static_cast<int>(k);
        }
      }
      if (index < 0) {
        fold_statistics(&set);
        index = static_cast<int>(fold_sets.size());
        fold_sets.push_back(std::move(set));
      }
      fold_set_of[static_cast<size_t>(j)][static_cast<size_t>(scope)] = index;
    }
  }
  auto folds_of_joint = [&](int j, int scope) -> const FoldSet& {
    return fold_sets[static_cast<size_t>(
        fold_set_of[static_cast<size_t>(j)][static_cast<size_t>(scope)])];
  };

  // The noise level and output scales are re-estimated on these data by evidence (the model's
  // prior structure kept), so that the evidence gains below are calibrated to this log.
  const int D = base_map->dim();
  const Hyperparameters hyper = ProfileOnLog(base_map, G_total.topLeftCorner(D, D),
                                             cross_total.topRows(D), Yg, base_hyper);
  out.noise_std = hyper.noise_variance() > 0 ? std::sqrt(hyper.noise_variance()) : 0.0;
  Vector lambda(next_col);
  lambda.head(base_map->dim()) = PriorVariance(*base_map, hyper);
  const double broad = model.options().broad_prior_std;
  lambda.tail(next_col - base_map->dim()).setConstant(broad * broad);
  const double s2n = hyper.noise_variance();
  const Vector s2 = hyper.output_scales().cwiseAbs2();

  // Fits of a base set of columns on all data and on each block's fit rows of joint j's fold
  // sets: a base only joint j's candidates are tested against.
  struct BaseFits {
    Index cols;
    BaseFit all;
    std::vector<std::vector<BaseFit>> folds;  // [scope][block], on joint j's fold sets
    Matrix residual;  // Yg - F_B W on all data (m x N)
  };
  // The fit on all data (the same for every joint), then joint j's blocks.
  auto fit_all = [&](const Index& cols, BaseFits* b) {
    b->cols = cols;
    b->all = FitBase(G_total, cross_total, cols, lambda, s2n);
    if (!b->all.ok) return false;
    b->residual = Yg - F(Eigen::all, cols) * b->all.W;
    return true;
  };
  auto fit_folds = [&](BaseFits* b, int j) {
    const Index& cols = b->cols;
    b->folds.assign(static_cast<size_t>(num_scopes), {});
    for (int scope = 0; scope < num_scopes; ++scope) {
      const FoldSet& set = folds_of_joint(j, scope);
      auto& fits = b->folds[static_cast<size_t>(scope)];
      for (size_t f = 0; f < set.ranges.size(); ++f) {
        fits.push_back(FitBase(set.G[f], set.cross[f], cols, lambda, s2n));
        if (!fits.back().ok) return false;
      }
    }
    return true;
  };
  auto fit_base = [&](const Index& cols, BaseFits* b, int j) {
    return fit_all(cols, b) && fit_folds(b, j);
  };
  // What adding the columns E to a base does to joint j.
  struct Addition {
    bool ok = false;
    double statistic = 0;  // u^T Z^{-1} u / (sigma^2 s_j^2): chi-square(k) under white noise
    double occam = 0;      // 1/2 (log|Z| + log|Lambda_E| - k log sigma^2)
    double sse_before = 0, sse_after = 0;  // held-out, over the folds
    int folds_improved = 0;
    double fold_ratio = 1;  // mean over the folds of the held-out RMS after / before
    int scope = 0;          // the blocks they come from: 0 every row's, 1 the log's
    Vector change;         // the change in the fitted torque of joint j on all data
    Vector residual_after;
    Vector we;
  };
  // The held-out numbers come from joint j's blocks of scope `scope` (0: every row, 1: the
  // log's); b is a base of joint j.
  auto add_columns = [&](const BaseFits& b, const Index& E, int j, int scope) {
    Addition a;
    const Augmented aug = Augment(b.all, G_total, cross_total, b.cols, E, lambda, s2n);
    if (!aug.ok) return a;
    a.we = aug.z.solve(Vector(aug.u.col(j)));
    a.statistic = aug.u.col(j).dot(a.we) / (s2n * s2[j]);
    const double log_det_z = 2.0 * Matrix(aug.z.matrixL()).diagonal().array().log().sum();
    double log_lambda_e = 0.0;
    for (int col : E) log_lambda_e += std::log(lambda[col]);
    a.occam = 0.5 * (log_det_z + log_lambda_e - static_cast<double>(E.size()) * std::log(s2n));
    const FoldSet& set = folds_of_joint(j, scope);
    const int num_folds = static_cast<int>(set.ranges.size());
    double ratio_sum = 0.0;
    for (int f = 0; f < num_folds; ++f) {
      const auto [begin, count] = set.ranges[f];
      const BaseFit& base = b.folds[static_cast<size_t>(scope)][f];
      const Augmented af = Augment(base, set.G[f], set.cross[f], b.cols, E, lambda, s2n);
      if (!af.ok) return Addition{};
      const Vector we = af.z.solve(Vector(af.u.col(j)));
      const Vector delta = base.llt.matrixU().solve(Vector(af.V * we));
      const Vector before = F(Eigen::seqN(begin, count), b.cols) * base.W.col(j);
      const Vector after = before - F(Eigen::seqN(begin, count), b.cols) * delta +
                           F(Eigen::seqN(begin, count), E) * we;
      const double sb = (Yg.col(j).segment(begin, count) - before).squaredNorm();
      const double sa = (Yg.col(j).segment(begin, count) - after).squaredNorm();
      a.sse_before += sb;
      a.sse_after += sa;
      if (sa < sb) ++a.folds_improved;
      ratio_sum += sb > 0 ? std::sqrt(sa / sb) : 1.0;
    }
    a.scope = scope;
    a.fold_ratio = ratio_sum / std::max(1, num_folds);
    const Vector delta = b.all.llt.matrixU().solve(Vector(aug.V * a.we));
    a.change = F(Eigen::all, E) * a.we - F(Eigen::all, b.cols) * delta;
    a.residual_after = b.residual.col(j) - a.change;
    a.ok = std::isfinite(a.statistic) && std::isfinite(a.sse_after) && a.change.allFinite();
    return a;
  };

  // ---- selection ----------------------------------------------------------------------------
  Index B(static_cast<size_t>(base_map->dim()));
  std::iota(B.begin(), B.end(), 0);
  // Every candidate on every joint is a test (a model diagnosed one joint at a time passes
  // the other joints' count in test_multiplier).
  const int num_tests = std::max(1, static_cast<int>(candidates.size()) * test_multiplier);
  // Candidates that passed every bar when first scored, with their numbers then (for the
  // joint choice of friction-like effects below).
  std::map<int, Suggestion> eligible;
  auto threshold = [&](int round) {
    switch (options.multiplicity) {
      case DiagnosisOptions::Multiplicity::kHolm:
        return options.significance / std::max(1, num_tests - round);
      case DiagnosisOptions::Multiplicity::kBenjaminiHochberg:
        return options.significance * (round + 1) / num_tests;
      case DiagnosisOptions::Multiplicity::kNone:
        break;
    }
    return options.significance;
  };
  auto adjust = [&](double p, int round) {
    switch (options.multiplicity) {
      case DiagnosisOptions::Multiplicity::kHolm:
        return std::min(1.0, p * std::max(1, num_tests - round));
      case DiagnosisOptions::Multiplicity::kBenjaminiHochberg:
        return std::min(1.0, p * num_tests / (round + 1));
      case DiagnosisOptions::Multiplicity::kNone:
        break;
    }
    return p;
  };
  // The inflation of the test of columns E against the base b (a: what adding them did), on
  // the columns as the test sees them (what b does not explain), with the residual the columns
  // leave: Bartlett's, the largest over the columns; or by prewhitening, all columns at once.
  auto calibrate = [&](const BaseFits& b, const Index& E, const Addition& a) {
    using Correction = DiagnosisOptions::Autocorrelation;
    double inflation = 1.0;
    if (options.autocorrelation == Correction::kNone) return inflation;
    const Matrix P = b.all.llt.solve(Matrix(G_total(b.cols, E)));
    const Matrix E_perp = F(Eigen::all, E) - F(Eigen::all, b.cols) * P;
    if (options.autocorrelation == Correction::kPrewhitening) {
      return PrewhiteningInflation(a.residual_after + a.change, a.residual_after, E_perp, starts);
    }
    for (int k = 0; k < E_perp.cols(); ++k) {
      inflation = std::max(inflation, BartlettInflation(a.residual_after, E_perp.col(k), starts));
    }
    return inflation;
  };
  // What adding columns to the base b did to joint j (the suggestion's outcome): held-out
  // error over the folds, the residual on the diagnosed log's rows before and after (the rows
  // themselves with `rows`: a suggestion's, not a refused candidate's).
  auto record_outcome = [&](const BaseFits& b, const Addition& a, int j, Suggestion* s,
                            bool rows) {
    const FoldSet& set = folds_of_joint(j, a.scope);
    s->confirmation = set.by_trajectory ? "trajectories" : "blocks";
    s->confirmation_folds = static_cast<int>(set.ranges.size());
    s->confirmation_gap = set.gap;
    s->rms_before = std::sqrt(a.sse_before / set.held_out_rows);
    s->rms_after = std::sqrt(a.sse_after / set.held_out_rows);
    s->residual_rms_before = std::sqrt(b.residual.col(j).tail(m_log).squaredNorm() / m_log);
    s->residual_rms_after = std::sqrt(a.residual_after.tail(m_log).squaredNorm() / m_log);
    s->folds_improved = a.folds_improved;
    s->fold_rms_ratio = a.fold_ratio;
    if (!rows) return;
    s->residual_before_rows = b.residual.col(j).tail(m_log);
    s->residual_after_rows = a.residual_after.tail(m_log);
  };
  // Scores candidate ci against the base b; true when it passes every bar of this round. When
  // it does not (and the columns could be added), *refusal names the first bar it failed and
  // holds its numbers as far as they were computed.
  auto evaluate = [&](const BaseFits& b, size_t ci, int round, Suggestion* s, Refusal* refusal) {
    const Candidate& c = candidates[ci];
    const int j = c.joint - 1;
    const Addition a = add_columns(b, c.cols, j, folds_of_scope(c.scope));
    if (!a.ok) return false;
    const double gain_white = 0.5 * a.statistic - a.occam;
    // The effect's size on the diagnosed log (the training rows, when given, may not have it).
    const double res_before = std::sqrt(b.residual.col(j).tail(m_log).squaredNorm() / m_log);
    const double res_after = std::sqrt(a.residual_after.tail(m_log).squaredNorm() / m_log);
    const double noise = out.joints[static_cast<size_t>(j)].noise_std_estimate;
    const double effect_rms = std::sqrt(a.change.tail(m_log).squaredNorm() / m_log);
    s->effect = c.effect;
    s->joint = c.joint;
    s->score = gain_white;
    s->score_uncorrected = gain_white;
    s->effect_rms = effect_rms;
    s->effect_to_noise = noise > 0 ? effect_rms / noise : HUGE_VAL;
    record_outcome(b, a, j, s, false);
    s->spec = c.spec;
    s->scope = c.scope;
    s->params = MakeEffect(c.effect, c.params)->parameters();
    auto refuse = [&](const char* bar, const std::string& reason, bool calibrated) {
      refusal->bar = bar;
      refusal->reason = reason;
      refusal->calibrated = calibrated;
      return false;
    };
    // A large held-out fall stands in for the effect-size bars; in all folds but at most one,
    // and not against the evidence on the log, for the evidence bars too (the held-out route).
    // Not on the log's own blocks: there any column of the log alone can stand for how the
    // whole log differs from the training rows (a bias, a load it carries) and predict its
    // unseen blocks for that reason, so an effect of the log alone needs the evidence.
    const bool large_held_out = a.fold_ratio <= 1.0 - options.held_out_fall_alone;
    const bool held_out_route = options.held_out_may_replace_evidence && a.scope == 0 &&
                                gain_white >= 0.0 && large_held_out &&
                                a.folds_improved >= s->confirmation_folds - 1;
    // Cheap bars first (the calibration below costs O(m K) per column).
    if (!held_out_route && !(gain_white > options.min_log_evidence_gain)) {
      return refuse("evidence",
                    internal::Format("evidence %.3g nats <= %.3g", gain_white,
                                     options.min_log_evidence_gain),
                    false);
    }
    // Held out, each fold weighs the same: a fold that the model extrapolates to badly (its
    // error far above the others') does not drown what the effect does in the others.
    if (!(a.fold_ratio < 1.0 - options.min_relative_rms_gain)) {
      return refuse("held_out",
                    internal::Format("held-out mean fold RMS ratio %.3g >= %.3g", a.fold_ratio,
                                     1.0 - options.min_relative_rms_gain),
                    false);
    }
    // And over all held-out rows together: an effect that helps most blocks a little and makes
    // one far worse does not predict the unseen data better.
    if (!(a.sse_after < a.sse_before)) {
      return refuse("held_out",
                    internal::Format("pooled held-out RMS does not fall (%.4g -> %.4g)",
                                     s->rms_before, s->rms_after),
                    false);
    }
    // The effect's size on this log; or, when a refit absorbs it in sample, out of sample.
    if (!large_held_out) {
      if (!(res_after <= (1.0 - options.min_residual_fall) * res_before)) {
        return refuse("residual_fall",
                      internal::Format("residual falls %.3g%% (%.4g -> %.4g) < %.3g%%",
                                       res_before > 0 ? 100.0 * (1.0 - res_after / res_before)
                                                      : 0.0,
                                       res_before, res_after, 100.0 * options.min_residual_fall),
                      false);
      }
      if (!(effect_rms >= options.min_effect_to_noise * noise)) {
        return refuse("effect_size",
                      internal::Format("effect %.3g times the noise < %.3g", s->effect_to_noise,
                                       options.min_effect_to_noise),
                      false);
      }
    }
    const double inflation = calibrate(b, c.cols, a);
    const double statistic = a.statistic / inflation;
    const double dof = static_cast<double>(c.cols.size());
    const double p = boost::math::cdf(boost::math::complement(
        boost::math::chi_squared_distribution<double>(dof), statistic));
    s->score = 0.5 * statistic - a.occam;
    s->inflation = inflation;
    s->effective_samples = m / inflation;
    s->p_value = p;
    s->adjusted_p_value = adjust(p, round);
    s->z = std::sqrt(statistic);
    const bool evidence_passes = gain_white > options.min_log_evidence_gain &&
                                 s->score > options.min_log_evidence_gain &&
                                 s->z >= options.min_effect_z && p <= threshold(round);
    if (!evidence_passes && !held_out_route) {
      if (!(s->score > options.min_log_evidence_gain)) {
        return refuse("calibrated_evidence",
                      internal::Format("calibrated evidence %.3g nats <= %.3g (inflation %.3g)",
                                       s->score, options.min_log_evidence_gain, inflation),
                      true);
      }
      if (!(s->z >= options.min_effect_z)) {
        return refuse("z", internal::Format("z %.3g < %.3g", s->z, options.min_effect_z), true);
      }
      return refuse("significance",
                    internal::Format("p %.3g > %.3g (adjusted p %.3g)", p, threshold(round),
                                     s->adjusted_p_value),
                    true);
    }
    s->passed_by = evidence_passes ? "evidence" : "held_out";
    record_outcome(b, a, j, s, true);
    return true;
  };

  // The suggestions so far, with the candidate each one is.
  std::vector<std::pair<int, Suggestion>> picks;
  std::map<std::tuple<std::string, int, std::string>, Refusal> refused;
  // Each joint's candidates are tested against the model's columns and the suggestions on
  // that joint: an effect of another joint is not part of this joint's torque, and as a
  // column of it (the weight-space form shares its features among the joints) it would let an
  // effect found on one joint change what another joint is suggested.
  const auto base_failed = [&out]() {
    out.status = DiagnosisStatus::kNumericalFailure;
    out.message = "the model's posterior could not be factorised on these data (not "
                  "positive definite)";
    return out;
  };
  std::vector<std::shared_ptr<const BaseFits>> joint_base(static_cast<size_t>(N));
  {
    BaseFits model_fit;  // the fit on all data, copied into each joint's base
    if (!fit_all(B, &model_fit)) return base_failed();
    for (int j = 0; j < N; ++j) {
      if (only_joint > 0 && j != only_joint - 1) continue;
      auto base = std::make_shared<BaseFits>(model_fit);
      if (!fit_folds(base.get(), j)) return base_failed();
      joint_base[static_cast<size_t>(j)] = std::move(base);
    }
  }
  // The candidates that passed every bar in each round, with their scores (the alternatives of
  // each round's choice are read from two consecutive rounds).
  std::vector<std::map<int, double>> passed_in_round;
  while (static_cast<int>(picks.size()) < options.max_suggestions) {
    const int round = static_cast<int>(picks.size());
    int best = -1;
    Suggestion best_s;
    passed_in_round.emplace_back();
    for (size_t ci = 0; ci < candidates.size(); ++ci) {
      if (!candidates[ci].alive) continue;
      Suggestion s;
      Refusal refusal;
      const BaseFits& base = *joint_base[static_cast<size_t>(candidates[ci].joint - 1)];
      if (!evaluate(base, ci, round, &s, &refusal)) {
        // Against the model as given, the closest parameter set of each effect, joint and
        // scope; a candidate that passed there and fails after the suggestions chosen since
        // replaces it (the suggestions explain it).
        const bool passed_before = eligible.count(static_cast<int>(ci)) > 0;
        if ((round == 0 || passed_before) && !refusal.bar.empty()) {
          const auto key = std::make_tuple(s.effect, s.joint, s.scope);
          auto it = refused.find(key);
          if (passed_before || it == refused.end() ||
              (!it->second.after_suggestions &&
               s.score_uncorrected > it->second.candidate.score_uncorrected)) {
            refusal.candidate = std::move(s);
            refusal.after_suggestions = passed_before;
            if (passed_before) refusal.reason = "with the suggestions before it, " + refusal.reason;
            refused[key] = std::move(refusal);
          }
        }
        continue;
      }
      eligible.emplace(static_cast<int>(ci), s);
      passed_in_round.back().emplace(static_cast<int>(ci), s.score);
      if (best < 0 || s.score > best_s.score) {
        best = static_cast<int>(ci);
        best_s = s;
      }
    }
    if (best < 0) break;
    const Candidate& chosen = candidates[static_cast<size_t>(best)];
    picks.emplace_back(best, best_s);
    const int chosen_joint = chosen.joint - 1;
    Index cols = joint_base[static_cast<size_t>(chosen_joint)]->cols;
    cols.insert(cols.end(), chosen.cols.begin(), chosen.cols.end());
    auto next = std::make_shared<BaseFits>();
    if (!fit_base(cols, next.get(), chosen_joint)) return base_failed();
    joint_base[static_cast<size_t>(chosen_joint)] = std::move(next);
    for (auto& c : candidates) {
      if (c.effect == chosen.effect && c.joint == chosen.joint) c.alive = false;
    }
  }

  // Each choice's alternatives: the other effects of its joint (by effect and scope) that passed
  // in its round and in no parameter set once it was added. The last choice has none when the
  // round after it was not run (max_suggestions).
  for (size_t r = 0; r < picks.size() && r + 1 < passed_in_round.size(); ++r) {
    Suggestion& chosen = picks[r].second;
    std::map<std::pair<std::string, std::string>, AlternativeEffect> alternatives;
    std::set<std::pair<std::string, std::string>> still_passing;
    for (const auto& [ci, score] : passed_in_round[r + 1]) {
      const Candidate& c = candidates[static_cast<size_t>(ci)];
      if (c.joint == chosen.joint) still_passing.emplace(c.effect, c.scope);
    }
    for (const auto& [ci, score] : passed_in_round[r]) {
      const Candidate& c = candidates[static_cast<size_t>(ci)];
      if (c.joint != chosen.joint || c.effect == chosen.effect) continue;
      const auto key = std::make_pair(c.effect, c.scope);
      if (still_passing.count(key)) continue;
      auto it = alternatives.find(key);
      if (it == alternatives.end() || score > it->second.score) {
        alternatives[key] = AlternativeEffect{c.spec, c.scope, score};
      }
    }
    for (auto& [key, a] : alternatives) chosen.alternatives.push_back(std::move(a));
    std::stable_sort(chosen.alternatives.begin(), chosen.alternatives.end(),
                     [](const AlternativeEffect& a, const AlternativeEffect& b) {
                       return a.score > b.score;
                     });
  }

  // ---- friction-like effects of one joint, chosen jointly ------------------------------------
  // Coulomb, viscous, Stribeck, drift and offset overlap: the greedy step may take the one that
  // explains most of the log alone where a pair explains it better. Per joint, every set of
  // at most three of those that passed (one parameter set per effect) is scored by its
  // calibrated evidence against the base with the joint's other suggestions.
  static const std::set<std::string> kFrictionLike = {"viscous", "coulomb", "stribeck", "drift",
                                                      "offset"};
  for (int joint = 1; joint <= N; ++joint) {
    std::vector<int> pool;  // every friction-like candidate of the joint that passed
    for (const auto& [ci, s] : eligible) {
      const Candidate& c = candidates[static_cast<size_t>(ci)];
      if (c.joint == joint && kFrictionLike.count(c.effect)) pool.push_back(ci);
    }
    if (pool.size() < 2) continue;
    // The greedy choice on this joint, and the base without it.
    std::vector<int> greedy_set;
    Index others(static_cast<size_t>(base_map->dim()));
    std::iota(others.begin(), others.end(), 0);
    for (const auto& [ci, s] : picks) {
      if (s.joint != joint) continue;
      if (kFrictionLike.count(s.effect)) {
        greedy_set.push_back(ci);
      } else {
        const Index& cols = candidates[static_cast<size_t>(ci)].cols;
        others.insert(others.end(), cols.begin(), cols.end());
      }
    }
    if (greedy_set.empty()) continue;
    BaseFits rest;
    if (!fit_base(others, &rest, joint - 1)) continue;
    auto columns_of = [&](const std::vector<int>& set) {
      Index cols;
      for (int ci : set) {
        const Index& c = candidates[static_cast<size_t>(ci)].cols;
        cols.insert(cols.end(), c.begin(), c.end());
      }
      return cols;
    };
    // A set is confirmed on the log's blocks when all of it acts on the log alone.
    auto folds_of = [&](const std::vector<int>& set) {
      const bool log_alone = std::all_of(set.begin(), set.end(), [&](int ci) {
        return candidates[static_cast<size_t>(ci)].scope == "log";
      });
      return folds_of_scope(log_alone ? "log" : "all");
    };
    // The greedy choice's held-out numbers on each fold set: a set is compared with it on the
    // blocks the set is confirmed on.
    std::vector<Addition> greedy_adds;
    for (int scope = 0; scope < num_scopes; ++scope) {
      greedy_adds.push_back(add_columns(rest, columns_of(greedy_set), joint - 1, scope));
    }
    const Addition& greedy_add = greedy_adds[static_cast<size_t>(folds_of(greedy_set))];
    if (!greedy_add.ok) continue;
    // The two best parameter sets (either scope) of each effect by score: every effect that
    // passed stays in the pool however many parameter sets another one has (at most 10
    // candidates: 175 sets below).
    std::stable_sort(pool.begin(), pool.end(),
                     [&](int a, int b) { return eligible.at(a).score > eligible.at(b).score; });
    {
      std::map<std::string, int> kept;
      std::vector<int> best_of_each;
      for (int ci : pool) {
        if (kept[candidates[static_cast<size_t>(ci)].effect]++ < 2) best_of_each.push_back(ci);
      }
      pool = std::move(best_of_each);
    }
    const int n = static_cast<int>(pool.size());
    // A set's evidence, its statistic deflated by its own inflation factor.
    auto set_gain = [&](const std::vector<int>& set, const Addition& a) {
      return 0.5 * a.statistic / calibrate(rest, columns_of(set), a) - a.occam;
    };
    // A set replaces the greedy choice when its evidence is higher by min_log_evidence_gain
    // and its held-out error is no worse; the set of highest evidence among those.
    const double greedy_gain = set_gain(greedy_set, greedy_add);
    std::vector<int> best_set = greedy_set;
    Addition best_add = greedy_add;
    double best_gain = greedy_gain + options.min_log_evidence_gain;
    for (int mask = 1; mask < (1 << n); ++mask) {
      if (__builtin_popcount(static_cast<unsigned>(mask)) > 3) continue;
      std::vector<int> set;
      std::set<std::string> effects;  // one parameter set per effect
      for (int i = 0; i < n; ++i) {
        if (mask & (1 << i)) {
          set.push_back(pool[static_cast<size_t>(i)]);
          effects.insert(candidates[static_cast<size_t>(pool[static_cast<size_t>(i)])].effect);
        }
      }
      if (effects.size() != set.size()) continue;
      const Addition a = add_columns(rest, columns_of(set), joint - 1, folds_of(set));
      if (!a.ok || a.fold_ratio > greedy_adds[static_cast<size_t>(a.scope)].fold_ratio) continue;
      const double gain = set_gain(set, a);
      if (gain > best_gain) {
        best_set = set;
        best_add = a;
        best_gain = gain;
      }
    }
    std::sort(best_set.begin(), best_set.end());
    std::sort(greedy_set.begin(), greedy_set.end());
    if (best_set == greedy_set) continue;
    // Replace the greedy choice on this joint by the set; its members keep the calibration
    // numbers of their first scoring, and carry the set's held-out and residual numbers.
    picks.erase(std::remove_if(picks.begin(), picks.end(),
                               [&](const std::pair<int, Suggestion>& p) {
                                 return std::find(greedy_set.begin(), greedy_set.end(),
                                                  p.first) != greedy_set.end();
                               }),
                picks.end());
    for (int ci : best_set) {
      Suggestion s = eligible.at(ci);
      s.selection = "joint";
      record_outcome(rest, best_add, joint - 1, &s, true);
      picks.emplace_back(ci, s);
    }
  }
  // What each joint's final suggestions leave of its error on the log (the model's columns and
  // exactly those suggestions' columns, in the fit the candidates were scored in). The joint's
  // base is that fit unless the joint selection replaced its greedy choice.
  for (int j = 0; j < N; ++j) {
    if (only_joint > 0 && j + 1 != only_joint) continue;
    Index cols = B;
    for (const auto& [ci, s] : picks) {
      if (s.joint != j + 1) continue;
      const Index& c = candidates[static_cast<size_t>(ci)].cols;
      cols.insert(cols.end(), c.begin(), c.end());
    }
    const BaseFits* fit = joint_base[static_cast<size_t>(j)].get();
    BaseFits refit;
    if (fit->cols != cols) {
      if (!fit_all(cols, &refit)) continue;
      fit = &refit;
    }
    out.joints[static_cast<size_t>(j)].residual_rms_with_suggestions =
        std::sqrt(fit->residual.col(j).tail(m_log).squaredNorm() / m_log);
  }
  for (auto& [ci, s] : picks) out.suggestions.push_back(std::move(s));
  for (auto& [key, r] : refused) out.refused.push_back(std::move(r));
  OrderFindings(options, &out);
  return out;
}

}  // namespace

namespace {

// A model on a chain IdentifyChain found (DiagnosisOptions::reidentify_chain): the chain
// identified again on the rows X (the model's inputs: training rows and log), torques Y and
// times t, from the model's own kinematics, with the model's effects and `beside` in its least
// squares, and the model (its effects only) fitted again on it from its training data. Empty
// when the model's chain is not one identify wrote (*finding untouched), or when the search or
// the fit failed (*finding says what).
std::optional<RobotModel> ChainAgain(const RobotModel& model, const ConstMatrixRef& X,
                                     const ConstMatrixRef& Y, const Vector& t,
                                     const std::vector<EffectSpec>& beside,
                                     const DiagnosisOptions& options,
                                     std::optional<ChainFinding>* finding) {
  const std::shared_ptr<const RigidBodyChain>& chain = model.options().rigid_body;
  if (!chain) return std::nullopt;
  ModelSpec with_beside = model.spec();
  with_beside.effects.insert(with_beside.effects.end(), beside.begin(), beside.end());
  const std::optional<ChainIdentificationOptions> again = SearchAgainOptions(
      *chain, with_beside, model.options().friction_width, options.chain);
  if (!again) return std::nullopt;
  const ChainIdentificationOptions& o = *again;
  const auto start = std::chrono::steady_clock::now();
  const int N = model.num_joints();
  ChainFinding c;
  c.kinematics_before = o.initial_kinematics;
  c.effects = ToString(beside);
  std::optional<RobotModel> out;
  try {  // too few rows for the effects' bases, an effect that needs the times, no usable chain
    const ChainIdentificationSummary id = IdentifyChain(X.leftCols(3 * N), t, Y, o);
    c.kinematics = id.kinematics;
    c.cost = ChainIdentificationCost(id);
    c.urdf = id.urdf;
    FitOptions fit;
    fit.model = model.options();
    fit.model.rigid_body = std::make_shared<const RigidBodyChain>(
        RigidBodyChain::FromUrdfString(id.urdf, {}, chain->source()));
    fit.per_joint = model.per_joint();
    StartFromModel(model, &fit);
    FittedModel refit = FitModel(model.spec(), options.training_inputs.leftCols(3 * N),
                                 options.training_targets, options.training_times, fit);
    if (refit.summary.IsUsable()) {
      out.emplace(std::move(refit.model));
    } else {
      c.message = "the model could not be fitted on the chain identified again: " +
                  refit.summary.message;
    }
  } catch (const std::exception& e) {
    c.message = std::string("the chain could not be identified again: ") + e.what();
  }
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  *finding = std::move(c);
  return out;
}

// ChainFinding::message once the two diagnoses are compared.
std::string ChainMessage(const ChainFinding& c, double fall) {
  const std::string beside = c.effects.empty() ? "" : ", with " + c.effects + " beside it";
  if (!c.changed) {
    return internal::Format(
        "The chain identified again on the training data and this log (from the model's "
        "own%s, %.1f s) does not explain the log better (no joint's refitted error falls by "
        "%.0f%% with none rising as much): the findings are against the model as it is.",
        beside.c_str(), c.seconds,
        100 * fall);
  }
  std::string joints;
  for (size_t k = 0; k < c.joints.size(); ++k) {
    const int j = c.joints[k] - 1;
    joints += internal::Format("%s%d (%.3g -> %.3g)", k == 0 ? "" : ", ", j + 1,
                               c.refit_rms_before[j], c.refit_rms_after[j]);
  }
  std::string explained;
  for (size_t k = 0; k < c.explained.size(); ++k) {
    explained += (k == 0 ? "" : ", ") + c.explained[k];
  }
  return internal::Format(
      "The chain identified from the training data does not carry to this log: identified "
      "again on both (from the model's own%s, %.1f s), it lowers the refitted error on joint%s "
      "%s. The findings are against the model on that chain%s; fit the model on it (diagnose "
      "--out-urdf writes it) or identify the chain on the training data and this log together "
      "(structgp identify --data TRAIN --data LOG).",
      beside.c_str(), c.seconds,
      c.joints.size() > 1 ? "s" : "", joints.c_str(),
      explained.empty() ? ""
                        : (", which explains what was suggested on the model's own chain: " +
                           explained).c_str());
}

// Distance of every row of X to the nearest training state, per joint, in the joint's
// (q, qd, qdd) standardised by the training data; decimated in time into the finding.
void MeasureCoverage(const ConstMatrixRef& X, const Vector& t, const Matrix& train, int N,
                     Diagnosis* d) {
  const int m = static_cast<int>(X.rows());
  constexpr int kMaxTrainingStates = 2000, kMaxPoints = 400;
  const int n_all = static_cast<int>(train.rows());
  const int n = std::min(n_all, kMaxTrainingStates);
  Matrix dist(m, N);
  for (int j = 0; j < N; ++j) {
    Eigen::Matrix<double, 3, Eigen::Dynamic> T(3, n);
    for (int i = 0; i < n; ++i) {
      const int row = static_cast<int>(static_cast<long long>(i) * n_all / n);
      for (int v = 0; v < 3; ++v) T(v, i) = train(row, v * N + j);
    }
    Eigen::Vector3d mean, scale;
    for (int v = 0; v < 3; ++v) {
      const Vector col = train.col(v * N + j);
      mean[v] = col.mean();
      const double sd = std::sqrt((col.array() - mean[v]).square().mean());
      scale[v] = sd > 0 ? 1.0 / sd : 1.0;
    }
    T = scale.asDiagonal() * (T.colwise() - mean);
    for (int r = 0; r < m; ++r) {
      Eigen::Vector3d x;
      for (int v = 0; v < 3; ++v) x[v] = scale[v] * (X(r, v * N + j) - mean[v]);
      dist(r, j) = std::sqrt((T.colwise() - x).colwise().squaredNorm().minCoeff());
    }
  }
  for (int j = 0; j < N && j < static_cast<int>(d->joints.size()); ++j) {
    d->joints[static_cast<size_t>(j)].outside_fraction = (dist.col(j).array() > 1.0).cast<double>().mean();
    d->joints[static_cast<size_t>(j)].max_distance = dist.col(j).maxCoeff();
  }
  const int points = std::min(m, kMaxPoints);
  d->coverage.distance_time.resize(points);
  d->coverage.distance.resize(points, N);
  for (int p = 0; p < points; ++p) {
    const int begin = static_cast<int>(static_cast<long long>(p) * m / points);
    const int end = static_cast<int>(static_cast<long long>(p + 1) * m / points);
    d->coverage.distance_time[p] = t.size() ? t[begin] : static_cast<double>(begin);
    d->coverage.distance.row(p) = dist.middleRows(begin, end - begin).colwise().maxCoeff();
  }
}

// The verdict of the coverage finding, from the joints' errors and the suggestions.
void Conclude(const DiagnosisOptions& options, Diagnosis* d) {
  CoverageFinding& c = d->coverage;
  c.coverage_joints.clear();
  c.unexplained_joints.clear();
  bool all_explained = true, refit_short = false;
  std::string worst;
  for (const JointFinding& f : d->joints) {
    const double noise = options.noise_tolerance * f.noise_std_estimate;
    if (f.rms > noise) all_explained = false;
    if (f.refit_rms > noise) refit_short = true;
    if (f.refit_rms <= noise && f.rms > options.coverage_ratio * f.refit_rms) {
      c.coverage_joints.push_back(f.joint);
      worst += internal::Format("%sjoint %d: %.3g on the log, %.3g refitted there", worst.empty() ? "" : "; ",
                                f.joint, f.rms, f.refit_rms);
    }
  }
  // The joints whose error the refit with their suggestions leaves above the noise, those
  // with suggestions and those without apart: "joints 1 and 3 stay at 22 and 9.9 times the
  // noise with their suggestions, joint 2 stays at 17 times the noise with none".
  std::map<int, int> suggestions_of;  // joint -> how many
  for (const Suggestion& s : d->suggestions) ++suggestions_of[s.joint];
  std::vector<int> with, without;
  std::vector<std::string> with_ratio, without_ratio;
  for (const JointFinding& f : d->joints) {
    const double noise = options.noise_tolerance * f.noise_std_estimate;
    const double left =
        f.residual_rms_with_suggestions >= 0 ? f.residual_rms_with_suggestions : f.refit_rms;
    const bool coverage = std::find(c.coverage_joints.begin(), c.coverage_joints.end(),
                                    f.joint) != c.coverage_joints.end();
    if (coverage || !(f.rms > noise && left > noise)) continue;
    c.unexplained_joints.push_back(f.joint);
    const double ratio = f.noise_std_estimate > 0 ? left / f.noise_std_estimate : HUGE_VAL;
    const bool suggested = suggestions_of.count(f.joint) > 0;
    (suggested ? with : without).push_back(f.joint);
    (suggested ? with_ratio : without_ratio)
        .push_back(!std::isfinite(ratio) ? std::string("infinitely many")
                   : ratio < 100         ? internal::Format("%.2g", ratio)
                                         : internal::Format("%.0f", ratio));
  }
  // "joints 1 and 3 stay at 22 and 9.9 times the noise with <how>".
  const auto stay = [](const std::vector<int>& joints, const std::vector<std::string>& ratios,
                       const std::string& how) {
    return internal::JointsText(joints) + (joints.size() > 1 ? " stay at " : " stays at ") +
           internal::ListText(ratios) + " times the noise with " + how;
  };
  std::string unexplained;
  if (!with.empty()) {
    unexplained = stay(with, with_ratio,
                       with.size() > 1                  ? "their suggestions"
                       : suggestions_of.at(with[0]) > 1 ? "its suggestions"
                                                        : "its suggestion");
  }
  if (!without.empty()) {
    unexplained += (unexplained.empty() ? "" : ", ") + stay(without, without_ratio, "none");
  }
  if (!unexplained.empty()) {
    unexplained = "refitted on this log, " + unexplained +
                  ": something neither the model nor the candidate effects express changes "
                  "these torques (for instance a load that changes during the log, or a state "
                  "the log does not record)";
  }
  const std::string coverage_text =
      c.coverage_joints.empty()
          ? ""
          : "the model does not extrapolate to these motions on " +
                internal::JointsText(c.coverage_joints) + " (" + worst +
                "): refitted on this log it reaches the noise, so the training data, not the "
                "physics, are missing; retrain with motions like these";
  const std::string but = unexplained.empty() ? std::string() : "; but " + unexplained;
  if (!d->suggestions.empty()) {
    c.verdict = Verdict::kMissingEffect;
    c.message = "effects are missing (see the suggestions)" +
                (coverage_text.empty() ? std::string() : "; also " + coverage_text) + but;
  } else if (!c.coverage_joints.empty()) {
    c.verdict = Verdict::kCoverage;
    c.message = coverage_text + but;
  } else if (refit_short && !all_explained) {
    c.verdict = Verdict::kUnexplained;
    c.message = unexplained.empty()
                    ? "refitted on this log the model stays above the noise on some joint, and "
                      "no candidate effect explains it"
                    : "no candidate effect explains the error: " + unexplained;
  } else {
    c.verdict = Verdict::kExplained;
    c.message = "the model explains this log to the noise";
    c.unexplained_joints.clear();
  }
}

}  // namespace

const char* ToString(Verdict verdict) {
  switch (verdict) {
    case Verdict::kExplained:
      return "explained";
    case Verdict::kCoverage:
      return "coverage";
    case Verdict::kMissingEffect:
      return "missing_effect";
    case Verdict::kUnexplained:
      return "unexplained";
  }
  return "unknown";
}

namespace {

// FindHoldingTorques on the model's residual at the rows of the still stretches that it reads
// (only those are predicted: a lagk model's predictions cost about 0.05 s a row on one thread;
// the other rows are not read).
HoldingTorqueFinding HoldingTorques(const RobotModel& model, const ConstMatrixRef& X,
                                    const ConstMatrixRef& Y, const std::vector<int>& starts,
                                    const HoldingTorqueOptions& options) {
  const int N = model.num_joints();
  std::vector<int> rest;
  for (const RestStretch& s : FindRestStretches(X, N, starts, options)) {
    const int read = std::min(s.end - s.begin, options.max_rows_per_stretch);
    for (int i = s.begin; i < s.begin + read; ++i) rest.push_back(i);
  }
  Matrix R = Matrix::Zero(X.rows(), N);
  if (!rest.empty()) {
    Matrix mean;
    model.PredictRows(SelectRows(X, rest), &mean, nullptr, model.options().batch.num_threads);
    for (size_t k = 0; k < rest.size(); ++k) {
      R.row(rest[k]) = Y.row(rest[k]) - mean.row(static_cast<Eigen::Index>(k));
    }
  }
  return FindHoldingTorques(X, R, starts, options);
}

}  // namespace

Diagnosis Diagnose(const RobotModel& model, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                   const Vector& t, const DiagnosisOptions& options) {
  const int N = model.num_joints();
  const bool with_training = options.training_targets.size() != 0;
  if (options.training_inputs.size() != 0) {
    const Eigen::Index cols = with_training ? model.input_dim() : 3 * N;
    if ((with_training ? options.training_inputs.cols() != cols
                       : options.training_inputs.cols() < cols) ||
        options.training_inputs.rows() < 1) {
      throw std::invalid_argument(
          "Diagnose: DiagnosisOptions::training_inputs: expected rows x " +
          std::string(with_training ? "" : "at least ") + std::to_string(cols) +
          " columns (the model's inputs), got " + std::to_string(options.training_inputs.rows()) +
          " x " + std::to_string(options.training_inputs.cols()));
    }
    RequireFinite("Diagnose training_inputs", options.training_inputs);
  }
  // With the training data, the candidates are scored on the training rows and the log together.
  Matrix Xu, Yu;
  Vector tu;
  std::vector<int> starts = SegmentStarts(t);
  int log_begin = 0;
  if (with_training) {
    const Matrix& Xtr = options.training_inputs;
    const Matrix& Ytr = options.training_targets;
    if (Xtr.size() == 0) {
      throw std::invalid_argument(
          "Diagnose: DiagnosisOptions::training_targets given without training_inputs");
    }
    RequireSize("Diagnose training_targets", Ytr.rows(), Xtr.rows(), "rows (as training_inputs)");
    RequireSize("Diagnose training_targets", Ytr.cols(), N, "columns (joints)");
    RequireFinite("Diagnose training_targets", Ytr);
    const Vector& ttr = options.training_times;
    if (t.size() != 0 && ttr.size() != Xtr.rows()) {
      throw std::invalid_argument(
          "Diagnose: DiagnosisOptions::training_times: the log has times, so the training data "
          "need them too: expected " + std::to_string(Xtr.rows()) + " entries, got " +
          std::to_string(ttr.size()));
    }
    RequireFinite("Diagnose training_times", ttr);
    RequireSize("Diagnose X", X.cols(), model.input_dim(), "columns");
    RequireSize("Diagnose Y", Y.cols(), N, "columns (joints)");
    log_begin = static_cast<int>(Xtr.rows());
    Xu.resize(Xtr.rows() + X.rows(), X.cols());
    Xu << Xtr, X;
    Yu.resize(Ytr.rows() + Y.rows(), N);
    Yu << Ytr, Y;
    if (t.size() != 0) {
      tu.resize(ttr.size() + t.size());
      tu << ttr, t;
    }
    starts = t.size() != 0 ? SegmentStarts(ttr) : std::vector<int>{0};
    for (int s : SegmentStarts(t)) starts.push_back(log_begin + s);
  }
  const ConstMatrixRef Xs = with_training ? ConstMatrixRef(Xu) : X;
  const ConstMatrixRef Ys = with_training ? ConstMatrixRef(Yu) : Y;
  const Vector& ts = with_training ? tu : t;
  // The candidates of a model scored on the rows (one joint at a time where the model needs it:
  // against its own row of the regressor, lagk's Nystrom features of its torque, per-joint
  // hyper-parameters' own prior), the suggestions merged.
  auto scored = [&](const RobotModel& m) {
    if (!m.regressor_map() && !(m.fitted() && m.gp().euler_lagrange() != nullptr) &&
        !m.per_joint()) {
      return DiagnoseOrThrow(m, Xs, Ys, ts, starts, log_begin, options, 0, 1);
    }
    Diagnosis out = DiagnoseOrThrow(m, Xs, Ys, ts, starts, log_begin, options, 1, N);
    for (int j = 2; j <= N && out.status == DiagnosisStatus::kOk; ++j) {
      Diagnosis joint = DiagnoseOrThrow(m, Xs, Ys, ts, starts, log_begin, options, j, N);
      if (joint.status != DiagnosisStatus::kOk) return joint;
      JointFinding& to = out.joints[static_cast<size_t>(j - 1)];
      const JointFinding& from = joint.joints[static_cast<size_t>(j - 1)];
      to.refit_rms = from.refit_rms;
      to.noise_std_estimate = from.noise_std_estimate;
      to.residual_rms_with_suggestions = from.residual_rms_with_suggestions;
      out.suggestions.insert(out.suggestions.end(), joint.suggestions.begin(),
                             joint.suggestions.end());
      out.refused.insert(out.refused.end(), joint.refused.begin(), joint.refused.end());
    }
    OrderFindings(options, &out);
    return out;
  };
  try {
    Diagnosis out = scored(model);
    // A chain IdentifyChain found, identified again on the training rows and the log.
    std::optional<RobotModel> rechained;
    if (out.status == DiagnosisStatus::kOk && with_training && options.reidentify_chain) {
      // The suggestions on the model's own chain beside it (not those of the log alone): a
      // missing effect would bend the chain as it bent the first identification.
      std::vector<EffectSpec> beside;
      for (const Suggestion& s : out.suggestions) {
        if (s.scope == "log") continue;
        for (EffectSpec& e : ParseEffectList(s.spec)) beside.push_back(std::move(e));
      }
      rechained = ChainAgain(model, Xs, Ys, ts, beside, options, &out.chain);
      if (rechained) {
        Diagnosis after = scored(*rechained);
        if (after.status != DiagnosisStatus::kOk) {
          out.chain->message = "the model on the chain identified again could not be diagnosed: " +
                               after.message;
          rechained.reset();
        } else {
          ChainFinding& c = *out.chain;
          c.refit_rms_before.resize(N);
          c.refit_rms_after.resize(N);
          // Better where it falls by min_residual_fall, and nowhere worse by as much: a chain
          // the least squares cannot tell from the model's can need inertial parameters the
          // refit's prior does not expect.
          bool worse = false;
          for (int j = 0; j < N; ++j) {
            c.refit_rms_before[j] = out.joints[static_cast<size_t>(j)].refit_rms;
            c.refit_rms_after[j] = after.joints[static_cast<size_t>(j)].refit_rms;
            if (c.refit_rms_after[j] < (1.0 - options.min_residual_fall) * c.refit_rms_before[j]) {
              c.joints.push_back(j + 1);
            }
            worse |= c.refit_rms_after[j] > (1.0 + options.min_residual_fall) * c.refit_rms_before[j];
          }
          if (worse) c.joints.clear();
          c.changed = !c.joints.empty();
          if (c.changed) {
            for (const Suggestion& s : out.suggestions) {
              const bool kept = std::any_of(
                  after.suggestions.begin(), after.suggestions.end(), [&](const Suggestion& a) {
                    return a.effect == s.effect && a.joint == s.joint;
                  });
              if (!kept) c.explained.push_back(s.spec);
            }
            // The model's own error on the log stays its own; everything refitted is the
            // chain's identified again.
            for (int j = 0; j < N; ++j) {
              JointFinding& to = after.joints[static_cast<size_t>(j)];
              const JointFinding& from = out.joints[static_cast<size_t>(j)];
              to.rms = from.rms;
              to.nmse = from.nmse;
              to.concentrations = from.concentrations;
            }
            after.chain = std::move(out.chain);
            out = std::move(after);
          } else {
            rechained.reset();
          }
          out.chain->message = ChainMessage(*out.chain, options.min_residual_fall);
        }
      }
    }
    const RobotModel& final_model = rechained ? *rechained : model;
    if (out.status == DiagnosisStatus::kOk) {
      if (options.training_inputs.size() != 0) {
        MeasureCoverage(X, t, options.training_inputs, N, &out);
      }
      Conclude(options, &out);
      out.holding = HoldingTorques(final_model, Xs, Ys, starts, options.holding);
      out.holding.message = HoldingTorqueMessage(out.holding, log_begin);
    }
    return out;
  } catch (const std::invalid_argument&) {
    throw;  // a caller mistake
  } catch (const std::runtime_error& e) {
    Diagnosis out;
    out.status = DiagnosisStatus::kNumericalFailure;
    out.message = e.what();
    out.num_samples = static_cast<int>(X.rows());
    out.model = ToString(model.spec());
    return out;
  }
}

namespace {

// A suggestion's FINDINGS.json object; without the numbers of the calibration when
// `calibrated` is false (a refused candidate that a cheap bar stopped first).
nlohmann::ordered_json SuggestionJson(const Suggestion& s, bool calibrated) {
  nlohmann::ordered_json js;
  js["effect"] = s.effect;
  js["joint"] = s.joint;
  js["score"] = s.score;
  js["rms_before"] = s.rms_before;
  js["rms_after"] = s.rms_after;
  js["residual_rms_before"] = s.residual_rms_before;
  js["residual_rms_after"] = s.residual_rms_after;
  js["score_uncorrected"] = s.score_uncorrected;
  js["inflation"] = s.inflation;
  js["effective_samples"] = s.effective_samples;
  js["p_value"] = s.p_value;
  js["adjusted_p_value"] = s.adjusted_p_value;
  js["effect_rms"] = s.effect_rms;
  js["effect_to_noise"] = s.effect_to_noise;
  js["z"] = s.z;
  js["confirmation"] = {{"method", s.confirmation},
                        {"folds", s.confirmation_folds},
                        {"gap", s.confirmation_gap},
                        {"folds_improved", s.folds_improved},
                        {"fold_rms_ratio", s.fold_rms_ratio},
                        {"rms_before", s.rms_before},
                        {"rms_after", s.rms_after}};
  js["selection"] = s.selection;
  js["passed_by"] = s.passed_by;
  js["scope"] = s.scope;
  js["params"] = nlohmann::ordered_json::object();
  for (const auto& [k, v] : s.params) js["params"][k] = v;
  js["spec"] = s.spec;
  js["alternatives"] = nlohmann::ordered_json::array();
  for (const AlternativeEffect& a : s.alternatives) {
    js["alternatives"].push_back({{"spec", a.spec}, {"scope", a.scope}, {"score", a.score}});
  }
  if (!calibrated) {
    for (const char* key : {"score", "inflation", "effective_samples", "p_value",
                            "adjusted_p_value", "z"}) {
      js.erase(key);
    }
  }
  return js;
}

}  // namespace

std::string ToJson(const Diagnosis& d) {
  nlohmann::ordered_json j;
  j["status"] = ToString(d.status);
  if (!d.message.empty()) j["message"] = d.message;
  j["model"] = d.model;
  j["num_samples"] = d.num_samples;
  j["features"] = d.features;
  j["joints"] = nlohmann::ordered_json::array();
  for (const auto& f : d.joints) {
    nlohmann::ordered_json jf;
    jf["joint"] = f.joint;
    jf["rms"] = f.rms;
    jf["nmse"] = f.nmse;
    jf["noise_std_estimate"] = f.noise_std_estimate;
    jf["refit_rms"] = f.refit_rms;
    if (f.residual_rms_with_suggestions >= 0) {
      jf["residual_rms_with_suggestions"] = f.residual_rms_with_suggestions;
    }
    if (f.max_distance >= 0) {
      jf["outside_fraction"] = f.outside_fraction;
      jf["max_distance"] = f.max_distance;
    }
    jf["concentrations"] = nlohmann::ordered_json::array();
    for (const auto& c : f.concentrations) {
      jf["concentrations"].push_back({{"variable", c.variable},
                                      {"explained", c.explained},
                                      {"bin_low", c.bin_low},
                                      {"bin_high", c.bin_high},
                                      {"bin_rms", c.bin_rms}});
    }
    j["joints"].push_back(jf);
  }
  j["suggestions"] = nlohmann::ordered_json::array();
  for (const auto& s : d.suggestions) j["suggestions"].push_back(SuggestionJson(s, true));
  j["refused"] = nlohmann::ordered_json::array();
  for (const auto& r : d.refused) {
    nlohmann::ordered_json jr = SuggestionJson(r.candidate, r.calibrated);
    jr.erase("selection");
    jr.erase("alternatives");
    jr["refused_by"] = r.bar;
    jr["reason"] = r.reason;
    jr["after_suggestions"] = r.after_suggestions;
    j["refused"].push_back(jr);
  }
  nlohmann::ordered_json c;
  c["verdict"] = ToString(d.coverage.verdict);
  c["message"] = d.coverage.message;
  c["coverage_joints"] = d.coverage.coverage_joints;
  c["unexplained_joints"] = d.coverage.unexplained_joints;
  if (d.coverage.distance.size() != 0) {
    c["distance_time"] = std::vector<double>(d.coverage.distance_time.data(),
                                             d.coverage.distance_time.data() +
                                                 d.coverage.distance_time.size());
    c["distance"] = nlohmann::ordered_json::array();
    for (int r = 0; r < d.coverage.distance.rows(); ++r) {
      std::vector<double> row(static_cast<size_t>(d.coverage.distance.cols()));
      for (int k = 0; k < d.coverage.distance.cols(); ++k) row[static_cast<size_t>(k)] = d.coverage.distance(r, k);
      c["distance"].push_back(row);
    }
  }
  j["coverage"] = c;
  nlohmann::ordered_json h;
  h["message"] = d.holding.message;
  h["stretches"] = nlohmann::ordered_json::array();
  for (const RestStretch& r : d.holding.stretches) {
    nlohmann::ordered_json jr;
    jr["begin"] = r.begin;
    jr["end"] = r.end;
    jr["pose"] = std::vector<double>(r.pose.data(), r.pose.data() + r.pose.size());
    jr["mean_residual"] = std::vector<double>(r.mean_residual.data(),
                                              r.mean_residual.data() + r.mean_residual.size());
    h["stretches"].push_back(jr);
  }
  h["pairs"] = d.holding.num_pairs;
  h["joints"] = nlohmann::ordered_json::array();
  for (const HoldingTorqueJoint& hj : d.holding.joints) {
    nlohmann::ordered_json jj;
    jj["joint"] = hj.joint;
    jj["difference"] = hj.difference;
    jj["noise"] = hj.noise;
    jj["stretch_a"] = hj.stretch_a;
    jj["stretch_b"] = hj.stretch_b;
    h["joints"].push_back(jj);
  }
  j["holding_torque"] = h;
  if (d.chain) {
    const ChainFinding& chain = *d.chain;
    auto list = [](const Vector& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
    const std::vector<std::string> names =
        ChainKinematicNames(std::max(1, static_cast<int>(d.joints.size())));
    auto by_name = [&](const Vector& v) {
      nlohmann::ordered_json k = nlohmann::ordered_json::object();
      for (size_t i = 0; i < names.size() && static_cast<Eigen::Index>(i) < v.size(); ++i) {
        k[names[i]] = v[static_cast<Eigen::Index>(i)];
      }
      return k;
    };
    nlohmann::ordered_json jc;
    jc["changed"] = chain.changed;
    jc["joints"] = chain.joints;
    jc["refit_rms_before"] = list(chain.refit_rms_before);
    jc["refit_rms_after"] = list(chain.refit_rms_after);
    jc["explained"] = chain.explained;
    jc["kinematics_before"] = by_name(chain.kinematics_before);
    jc["kinematics"] = by_name(chain.kinematics);
    jc["effects"] = chain.effects;
    jc["cost"] = chain.cost;
    jc["seconds"] = chain.seconds;
    jc["message"] = chain.message;
    jc["urdf"] = chain.urdf;
    j["chain"] = jc;
  } else {
    j["chain"] = nullptr;
  }
  return j.dump(2) + "\n";
}

}  // namespace structgp
