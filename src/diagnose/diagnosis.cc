#include "structgp/diagnose/diagnosis.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>
#include <sstream>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <nlohmann/json.hpp>

#include "structgp/core/validate.h"
#include "structgp/feature/effect_feature_map.h"
#include "structgp/feature/effects.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/regressor_feature_map.h"
#include "structgp/kernel/nystrom_feature_map.h"
#include "structgp/core/segments.h"
#include "structgp/hyper/cross_validation.h"
#include "structgp/hyper/evidence.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/internal/cholesky.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

using Index = std::vector<int>;

struct Candidate {
  std::string effect;
  int joint = 0;  // 1-based
  EffectParameters params;
  Index cols;      // columns in the design matrix F
  std::string spec;
  bool alive = true;
};

// Folds as (begin, size): SegmentFolds' blocks (whole trajectories when the log has enough of
// them), in time order.
std::vector<std::pair<int, int>> Folds(int m, int k, const Vector& t) {
  std::vector<std::pair<int, int>> folds = SegmentFolds(m, k, SegmentStarts(t));
  for (auto& fold : folds) fold.second -= fold.first;
  return folds;
}

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

BaseFit FitBase(const Matrix& G, const Matrix& cross, const Index& B, const Vector& lambda,
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

Augmented Augment(const BaseFit& base, const Matrix& G, const Matrix& cross, const Index& B,
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

  double Score(const std::string& name, int joint, const EffectParameters& params) {
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
  if (nystrom_features < 1) {
    return fail("nystrom_features: expected >= 1, got " + std::to_string(nystrom_features));
  }
  return true;
}

namespace {

// Diagnose, with numerical trouble deep inside (a profile of the evidence, the Nystrom
// factorisation, a prediction) as std::runtime_error.
// only_joint (1-based, 0: every joint): the candidates of that joint alone; a model with a
// regressor (rbd) is diagnosed one joint at a time, against the features of its row.
Diagnosis DiagnoseOrThrow(const RobotModel& model, const ConstMatrixRef& X,
                          const ConstMatrixRef& Y, const Vector& t,
                          const DiagnosisOptions& options, int only_joint) {
  std::string invalid;
  if (!options.IsValid(&invalid)) throw std::invalid_argument("Diagnose: " + invalid);
  if (!model.fitted() || (!model.feature_map() && !model.kernel() && !model.regressor_map())) {
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
  Diagnosis out;
  if (base_map) {
    out.features = "the model's feature map (D = " + std::to_string(base_map->dim()) + ")";
  } else if (model.regressor_map()) {
    if (only_joint < 1) throw std::logic_error("Diagnose: a regressor model is diagnosed per joint");
    base_map = std::make_shared<RegressorFeatureMap>(model.regressor_map(), only_joint - 1);
    Hyperparameters h = DefaultHyperparameters(*base_map, N);
    h.log_noise_std = base_hyper.log_noise_std;
    h.log_output_scale = base_hyper.log_output_scale;
    base_hyper = h;
    out.features = "each joint's row of the model's rigid-body regressor (P = " +
                   std::to_string(base_map->dim()) + "), one joint at a time";
  } else {
    const Matrix Z = SelectInducingStates(*model.kernel(), X,
                                          std::min(options.nystrom_features, m / 2));
    base_map = std::make_shared<NystromFeatureMap>(*model.kernel(), Z);
    Hyperparameters h = DefaultHyperparameters(*base_map, N);
    h.log_noise_std = base_hyper.log_noise_std;
    h.log_output_scale = base_hyper.log_output_scale;
    base_hyper = h;
    out.features = "Nystrom features of the model's kernel on " + std::to_string(Z.rows()) +
                   " inducing states chosen among the rows (D = " +
                   std::to_string(base_map->dim()) + ")";
  }
  out.num_samples = m;
  out.model = ToString(model.spec());
  if (!model.spec().effects.empty()) out.model += " + " + ToString(model.spec().effects);

  // ---- residuals of the model as it is -----------------------------------------------------
  Matrix mean;
  model.PredictRows(X, &mean);
  const Matrix R = Y - mean;
  Matrix vars(m, 3 * N + (t.size() ? 1 : 0));
  vars.leftCols(3 * N) = X.leftCols(3 * N);
  std::vector<std::string> var_names;
  for (const char* prefix : {"q", "qd", "qdd"}) {
    for (int j = 1; j <= N; ++j) var_names.push_back(prefix + std::to_string(j));
  }
  if (t.size()) {
    vars.col(3 * N) = t;
    var_names.push_back("t");
  }
  for (int j = 0; j < N; ++j) {
    JointFinding f;
    f.joint = j + 1;
    const Vector r = R.col(j);
    f.rms = std::sqrt(r.squaredNorm() / m);
    const double var_y = (Y.col(j).array() - Y.col(j).mean()).square().mean();
    f.nmse = var_y > 0 ? f.rms * f.rms / var_y : 0.0;
    const Vector dr = r.tail(m - 1) - r.head(m - 1);
    f.noise_std_estimate = std::sqrt(dr.squaredNorm() / (2.0 * (m - 1)));
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

  std::vector<Candidate> candidates;
  std::vector<Matrix> blocks;  // candidate columns, in order
  int next_col = base_map->dim();
  auto add_candidate = [&](const std::string& name, int joint, EffectParameters params) {
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
    Candidate c;
    c.effect = name;
    c.joint = joint;
    c.params = params;
    EffectSpec es{name, {joint}, params};
    c.spec = ToString(es);
    for (int k = 0; k < E.cols(); ++k) c.cols.push_back(next_col++);
    blocks.push_back(std::move(E));
    candidates.push_back(std::move(c));
  };
  EvidenceScorer scorer(base_map, Phi, Y, Xt, base_hyper, model.options().broad_prior_std);
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
      if (model_has(*prototype, j)) continue;
      // The effect proposes its parameters from what a refit of the model on these data
      // cannot explain (the model's own residual also carries its extrapolation error).
      ResidualContext context(j, X.col(j - 1), X.col(N + j - 1), X.col(2 * N + j - 1), t,
                              refit_residual.col(j - 1));
      context.search_ranges = search;
      context.score = [&scorer, name, j](const EffectParameters& p) {
        return scorer.Score(name, j, p);
      };
      for (EffectParameters& params : prototype->ProposeParameters(context)) {
        add_candidate(name, j, std::move(params));
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
  const auto folds = Folds(m, options.folds, t);
  // Statistics of each fold; the total is their sum, a fold's training set the total minus it.
  std::vector<Matrix> fold_gram, fold_cross;
  Matrix G_total = Matrix::Zero(next_col, next_col), cross_total = Matrix::Zero(next_col, N);
  for (const auto& [begin, count] : folds) {
    SufficientStatistics s(next_col, N);
    s.Accumulate(F.middleRows(begin, count), Y.middleRows(begin, count));
    Matrix G = s.gram.selfadjointView<Eigen::Lower>();
    G_total += G;
    cross_total += s.cross;
    fold_gram.push_back(std::move(G));
    fold_cross.push_back(std::move(s.cross));
  }

  // The noise level and output scales are re-estimated on these data by evidence (the model's
  // prior structure kept), so that the evidence gains below are calibrated to this log.
  const int D = base_map->dim();
  const Hyperparameters hyper = ProfileOnLog(base_map, G_total.topLeftCorner(D, D),
                                             cross_total.topRows(D), Y, base_hyper);
  out.noise_std = hyper.noise_variance() > 0 ? std::sqrt(hyper.noise_variance()) : 0.0;
  Vector lambda(next_col);
  lambda.head(base_map->dim()) = PriorVariance(*base_map, hyper);
  const double broad = model.options().broad_prior_std;
  lambda.tail(next_col - base_map->dim()).setConstant(broad * broad);
  const double s2n = hyper.noise_variance();
  const Vector s2 = hyper.output_scales().cwiseAbs2();

  // ---- greedy forward selection -----------------------------------------------------------------
  Index B(static_cast<size_t>(base_map->dim()));
  std::iota(B.begin(), B.end(), 0);
  const int num_fits = options.folds + 1;  // fit 0: all data; fit f + 1: all but fold f
  std::vector<Matrix> Gs(static_cast<size_t>(num_fits)), crosses(static_cast<size_t>(num_fits));
  for (int fit = 0; fit < num_fits; ++fit) {
    Gs[fit] = fit == 0 ? G_total : Matrix(G_total - fold_gram[fit - 1]);
    crosses[fit] = fit == 0 ? cross_total : Matrix(cross_total - fold_cross[fit - 1]);
  }
  while (static_cast<int>(out.suggestions.size()) < options.max_suggestions) {
    std::vector<BaseFit> base(static_cast<size_t>(num_fits));
    for (int fit = 0; fit < num_fits; ++fit) {
      base[fit] = FitBase(Gs[fit], crosses[fit], B, lambda, s2n);
      if (!base[fit].ok) {
        out.status = DiagnosisStatus::kNumericalFailure;
        out.message = "the model's posterior could not be factorised on these data (not "
                      "positive definite)";
        out.suggestions.clear();
        return out;
      }
    }
    // Held-out squared error per joint of the model refitted without the candidate.
    Vector sse_base = Vector::Zero(N);
    for (int f = 0; f < options.folds; ++f) {
      const auto [begin, count] = folds[f];
      const Matrix pred = F(Eigen::seqN(begin, count), B) * base[f + 1].W;
      sse_base += (Y.middleRows(begin, count) - pred).colwise().squaredNorm().transpose();
    }
    int best = -1;
    Suggestion best_s;
    for (size_t ci = 0; ci < candidates.size(); ++ci) {
      Candidate& c = candidates[ci];
      if (!c.alive) continue;
      const int j = c.joint - 1;
      const Augmented aug = Augment(base[0], Gs[0], crosses[0], B, c.cols, lambda, s2n);
      if (!aug.ok) continue;
      const double gain = LogEvidenceGain(aug, c.cols, lambda, s2n, s2[j], j);
      // Held-out error of joint j with the candidate, from the same fold fits.
      double sse_aug = 0.0;
      bool ok = true;
      for (int f = 0; f < options.folds && ok; ++f) {
        const auto [begin, count] = folds[f];
        const Augmented a = Augment(base[f + 1], Gs[f + 1], crosses[f + 1], B, c.cols, lambda, s2n);
        if (!a.ok) {
          ok = false;
          break;
        }
        const Vector we = a.z.solve(Vector(a.u.col(j)));
        const Vector wb =
            base[f + 1].W.col(j) - base[f + 1].llt.matrixU().solve(Vector(a.V * we));
        const Vector pred = F(Eigen::seqN(begin, count), B) * wb +
                            F(Eigen::seqN(begin, count), c.cols) * we;
        sse_aug += (Y.col(j).segment(begin, count) - pred).squaredNorm();
      }
      if (!ok) continue;
      const double rms_before = std::sqrt(sse_base[j] / m);
      const double rms_after = std::sqrt(sse_aug / m);
      const bool significant = gain > options.min_log_evidence_gain &&
                               rms_after < (1.0 - options.min_relative_rms_gain) * rms_before;
      if (significant && (best < 0 || gain > best_s.score)) {
        best = static_cast<int>(ci);
        best_s.effect = c.effect;
        best_s.joint = c.joint;
        best_s.score = gain;
        best_s.rms_before = rms_before;
        best_s.rms_after = rms_after;
        best_s.params = MakeEffect(c.effect, c.params)->parameters();
        best_s.spec = c.spec;
      }
    }
    if (best < 0) break;
    Candidate& chosen = candidates[static_cast<size_t>(best)];
    {
      // Residual of the chosen joint on all the data, refitted without and with the effect.
      const int j = chosen.joint - 1;
      const Augmented aug = Augment(base[0], Gs[0], crosses[0], B, chosen.cols, lambda, s2n);
      const Vector we = aug.z.solve(Vector(aug.u.col(j)));
      const Vector wb = base[0].W.col(j) - base[0].llt.matrixU().solve(Vector(aug.V * we));
      const Vector before = Y.col(j) - F(Eigen::all, B) * base[0].W.col(j);
      const Vector after = Y.col(j) - F(Eigen::all, B) * wb - F(Eigen::all, chosen.cols) * we;
      best_s.residual_rms_before = std::sqrt(before.squaredNorm() / m);
      best_s.residual_rms_after = std::sqrt(after.squaredNorm() / m);
    }
    out.suggestions.push_back(best_s);
    B.insert(B.end(), chosen.cols.begin(), chosen.cols.end());
    for (auto& c : candidates) {
      if (c.effect == chosen.effect && c.joint == chosen.joint) c.alive = false;
    }
  }
  std::stable_sort(out.suggestions.begin(), out.suggestions.end(),
                   [](const Suggestion& a, const Suggestion& b) { return a.score > b.score; });
  return out;
}

}  // namespace

Diagnosis Diagnose(const RobotModel& model, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                   const Vector& t, const DiagnosisOptions& options) {
  try {
    if (!model.regressor_map()) return DiagnoseOrThrow(model, X, Y, t, options, 0);
    // One joint at a time against its own row of the regressor; the suggestions merged.
    Diagnosis out = DiagnoseOrThrow(model, X, Y, t, options, 1);
    for (int j = 2; j <= model.num_joints() && out.status == DiagnosisStatus::kOk; ++j) {
      Diagnosis joint = DiagnoseOrThrow(model, X, Y, t, options, j);
      if (joint.status != DiagnosisStatus::kOk) return joint;
      out.suggestions.insert(out.suggestions.end(), joint.suggestions.begin(),
                             joint.suggestions.end());
    }
    std::stable_sort(out.suggestions.begin(), out.suggestions.end(),
                     [](const Suggestion& a, const Suggestion& b) { return a.score > b.score; });
    if (static_cast<int>(out.suggestions.size()) > options.max_suggestions) {
      out.suggestions.resize(static_cast<size_t>(options.max_suggestions));
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
  for (const auto& s : d.suggestions) {
    nlohmann::ordered_json js;
    js["effect"] = s.effect;
    js["joint"] = s.joint;
    js["score"] = s.score;
    js["rms_before"] = s.rms_before;
    js["rms_after"] = s.rms_after;
    js["residual_rms_before"] = s.residual_rms_before;
    js["residual_rms_after"] = s.residual_rms_after;
    js["params"] = nlohmann::ordered_json::object();
    for (const auto& [k, v] : s.params) js["params"][k] = v;
    js["spec"] = s.spec;
    j["suggestions"].push_back(js);
  }
  return j.dump(2) + "\n";
}

}  // namespace structgp
