#include "structgp/online/replay.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "structgp/core/segments.h"
#include "structgp/core/validate.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/internal/text.h"

namespace structgp {
namespace {

using Clock = std::chrono::steady_clock;

double Percentile(Vector v, double q) {
  if (v.size() == 0) return 0.0;
  std::sort(v.data(), v.data() + v.size());
  return v[static_cast<Eigen::Index>(q * static_cast<double>(v.size() - 1))];
}

// RMS per joint over rows [begin, end), NaN rows left out.
Vector RmsRows(const Matrix& errors, Eigen::Index begin, Eigen::Index end) {
  Vector rms = Vector::Zero(errors.cols());
  for (Eigen::Index j = 0; j < errors.cols(); ++j) {
    double sum = 0.0;
    long n = 0;
    for (Eigen::Index i = begin; i < end; ++i) {
      if (std::isfinite(errors(i, j))) {
        sum += errors(i, j) * errors(i, j);
        ++n;
      }
    }
    rms[j] = n > 0 ? std::sqrt(sum / static_cast<double>(n))
                   : std::numeric_limits<double>::quiet_NaN();
  }
  return rms;
}

// The learner's options for the model: its posterior when fitted, else its prior at hyper.
// A fitted model's calibrated bands (RobotModel::latent_variance_scale), empty when they are
// the posterior's own.
Vector CalibratedScale(const RobotModel& model) {
  return model.bands_calibrated() ? model.latent_variance_scale() : Vector();
}

OnlineLearnerOptions LearnerOptions(const RobotModel& model, const Hyperparameters& hyper) {
  OnlineLearnerOptions o;
  o.start_thread = false;
  o.max_batch = 1;  // one sample at a time: it is predicted, then learned
  if (model.regressor_map() != nullptr) {
    o.regressor_map = model.regressor_map();
    if (model.fitted()) {
      o.initial_regressor = std::make_shared<const RegressorGP>(*model.gp().regressor());
    } else {
      o.prior_variance = RegressorPriorVariance(*model.regressor_map(), hyper.log_block_scale);
      o.noise_variance = hyper.noise_variance();
      o.output_scales = hyper.output_scales();
    }
    if (model.fitted()) o.latent_variance_scale = CalibratedScale(model);
    return o;
  }
  if (model.fitted() && model.per_joint()) {
    throw std::invalid_argument(
        "Replay: model '" + ToString(model.spec()) +
        "' has per-joint hyper-parameters (one posterior per joint); the online learner updates "
        "one posterior shared by the joints: fit the model without --per-joint");
  }
  if (model.feature_map() == nullptr ||
      (model.fitted() && model.gp().weight_space() == nullptr)) {
    throw std::invalid_argument(
        "Replay: model '" + ToString(model.spec()) +
        "' runs in function space (no finite feature map in use); replay needs a weight-space "
        "or regressor model (pol up to its explicit limit, motor, rbd, lag)");
  }
  o.feature_map = model.feature_map();
  o.num_outputs = model.num_joints();
  if (model.fitted()) {
    o.initial_model = std::make_shared<const WeightSpaceGP>(*model.gp().weight_space());
    o.latent_variance_scale = CalibratedScale(model);
  } else {
    o.prior_variance = PriorVariance(*model.feature_map(), hyper);
    o.noise_variance = hyper.noise_variance();
    o.output_scales = hyper.output_scales();
  }
  return o;
}

}  // namespace

bool ReplayOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error != nullptr) *error = "ReplayOptions: " + m;
    return false;
  };
  if (!(forgetting > 0.0 && forgetting <= 1.0)) {
    return fail("forgetting: expected a value in (0, 1], got " + std::to_string(forgetting));
  }
  if (window_length < 0) {
    return fail("window_length: expected >= 0 (0: no window), got " +
                std::to_string(window_length));
  }
  if (default_rows < 1) {
    return fail("default_rows: expected >= 1, got " + std::to_string(default_rows));
  }
  return true;
}

std::string ReplaySummary::Report() const {
  std::ostringstream os;
  os << "replayed " << steps << " samples (" << segment_starts.size() << " trajector"
     << (segment_starts.size() == 1 ? "y" : "ies") << "), " << form << " form, "
     << num_features << (form == "regressor" ? " parameters" : " features") << "; bad samples "
     << bad_samples << "\n"
     << internal::Format("update %.1f us p50, %.1f us p99; predict %.1f us p50, %.1f us p99\n",
                         update_us_p50, update_us_p99, predict_us_p50, predict_us_p99);
  std::vector<std::vector<std::string>> rows = {
      {"joint", "RMS first fifth", "RMS last fifth", "ratio"}};
  for (Eigen::Index j = 0; j < rms_first_fifth.size(); ++j) {
    rows.push_back({std::to_string(j + 1), internal::Format("%.4g", rms_first_fifth[j]),
                    internal::Format("%.4g", rms_last_fifth[j]),
                    internal::Format("%.3g", rms_last_fifth[j] / rms_first_fifth[j])});
  }
  os << internal::Table(rows);
  return os.str();
}

ReplaySummary Replay(const RobotModel& model, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                     const ConstVectorRef& t, const ReplayOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  const int N = model.num_joints();
  RequireSize("Replay X", X.cols(), model.input_dim(), "columns (the model's inputs)");
  RequireSize("Replay Y", Y.cols(), N, "columns (joints)");
  RequireSize("Replay Y", Y.rows(), X.rows(), "rows (as in X)");
  if (t.size() != 0) RequireSize("Replay t", t.size(), X.rows(), "entries (as X's rows)");
  if (X.rows() < 1) throw std::invalid_argument("Replay: the log has no samples");
  if (options.target_limit.size() != 0) {
    RequireSize("ReplayOptions target_limit", options.target_limit.size(), N);
  }
  Hyperparameters hyper = model.fitted() ? model.hyperparameters() : options.hyperparameters;
  if (!model.fitted() && hyper.log_output_scale.size() == 0) {
    const Eigen::Index k = std::min<Eigen::Index>(Y.rows(), options.default_rows);
    Matrix first = Y.topRows(k);
    if (model.prior_mean()) first -= model.PriorMeanRows(X.topRows(k));
    hyper = model.DefaultHyperparameters(first);
  }
  OnlineLearnerOptions lo = LearnerOptions(model, hyper);
  lo.forgetting = options.forgetting;
  lo.window_length = options.window_length;
  lo.target_limit = options.target_limit;
  lo.queue_capacity = 1;
  OnlineLearner learner(lo);

  const Eigen::Index m = X.rows();
  ReplaySummary s;
  s.form = learner.regressor_form() ? "regressor" : "weight_space";
  s.num_features = learner.num_features();
  s.segment_starts = SegmentStarts(t);
  s.errors.setConstant(m, N, std::numeric_limits<double>::quiet_NaN());
  s.update_us.setZero(m);
  s.predict_us.setZero(m);
  Vector x(X.cols()), y(N), mean(N), prior(N);
  prior.setZero();
  // rbd+<base>: the learner learns the torques less the URDF's (the model's prior mean).
  const RigidBodyTorqueFeatureMap* prior_mean = model.prior_mean().get();
  for (Eigen::Index i = 0; i < m; ++i) {
    x = X.row(i).transpose();
    y = Y.row(i).transpose();
    const auto t0 = Clock::now();
    if (prior_mean != nullptr) prior_mean->Torque(x.head(3 * N), prior);
    const Status predicted = learner.Predict(x, mean);
    const auto t1 = Clock::now();
    if (predicted == Status::kOk) s.errors.row(i) = (y - prior - mean).transpose();
    const long failures_before = learner.summary().update_failures;
    const auto t2 = Clock::now();
    const SubmitResult submitted = learner.Submit(x, y - prior);
    learner.ProcessPending();
    const auto t3 = Clock::now();
    if (submitted != SubmitResult::kAccepted ||
        learner.summary().update_failures != failures_before) {
      ++s.bad_samples;
    }
    s.predict_us[i] = std::chrono::duration<double, std::micro>(t1 - t0).count();
    s.update_us[i] = std::chrono::duration<double, std::micro>(t3 - t2).count();
  }
  s.steps = m;
  s.update_us_p50 = Percentile(s.update_us, 0.5);
  s.update_us_p99 = Percentile(s.update_us, 0.99);
  s.predict_us_p50 = Percentile(s.predict_us, 0.5);
  s.predict_us_p99 = Percentile(s.predict_us, 0.99);
  const Eigen::Index fifth = std::max<Eigen::Index>(1, m / 5);
  s.rms_first_fifth = RmsRows(s.errors, 0, fifth);
  s.rms_last_fifth = RmsRows(s.errors, m - fifth, m);
  s.learner = learner.summary();

  {
    RobotModelState state;
    state.spec = model.spec();
    state.num_joints = N;
    state.options = model.options();
    state.hyperparameters = hyper;
    state.latent_variance_scale = lo.latent_variance_scale;  // the start's calibration
    if (learner.regressor_form()) {
      state.form = Form::kRegressor;
      state.regressor = learner.regressor_model().State();
    } else {
      state.form = Form::kWeightSpace;
      state.weight_space = learner.model().State();
    }
    s.model = std::make_shared<const RobotModel>(RobotModel::FromState(state));
  }
  return s;
}

}  // namespace structgp
