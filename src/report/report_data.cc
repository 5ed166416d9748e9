#include "structgp/report/report_data.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "structgp/fit/fit_check.h"
#include "structgp/fit/fit_model.h"

namespace structgp {
namespace report {

ModelPredictions Predict(const RobotModel& model, const RobotData& data) {
  ModelPredictions p;
  p.label = ModelLabel(model.spec());
  model.PredictRows(ModelInputs(model, data.X, data.t), &p.mean, &p.std);
  return p;
}

PredictionErrors ComputeErrors(const Matrix& predicted, const Matrix& measured) {
  const Eigen::Index m = measured.rows();
  const Eigen::Index N = measured.cols();
  PredictionErrors e;
  e.rms.resize(N);
  e.nmse.resize(N);
  double total = 0.0;
  for (Eigen::Index j = 0; j < N; ++j) {
    const double sse = (predicted.col(j) - measured.col(j)).squaredNorm();
    const double mean = measured.col(j).mean();
    const double var = (measured.col(j).array() - mean).square().sum() / static_cast<double>(m);
    e.rms[j] = std::sqrt(sse / static_cast<double>(m));
    e.nmse[j] = var > 0.0 ? sse / static_cast<double>(m) / var : HUGE_VAL;
    total += sse;
  }
  e.overall_rms = std::sqrt(total / static_cast<double>(m * N));
  e.overall_nmse = e.nmse.mean();
  return e;
}

ModelErrors ToModelErrors(const std::string& label, const PredictionErrors& errors,
                          const Vector& coverage) {
  auto values = [](const Vector& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
  return ModelErrors{label, values(errors.rms), values(errors.nmse), values(coverage)};
}

std::vector<JointData> JointSeries(const RobotData& data,
                                   const std::vector<ModelPredictions>& models) {
  const int N = data.num_joints;
  const Eigen::Index m = data.size();
  auto column = [m](const auto& a, Eigen::Index c) {
    std::vector<double> v(static_cast<size_t>(m));
    for (Eigen::Index i = 0; i < m; ++i) v[static_cast<size_t>(i)] = a(i, c);
    return v;
  };
  std::vector<JointData> joints;
  for (int j = 0; j < N; ++j) {
    JointData jd;
    jd.joint = j + 1;
    jd.t.resize(static_cast<size_t>(m));
    for (Eigen::Index i = 0; i < m; ++i) {
      jd.t[static_cast<size_t>(i)] = data.has_time() ? data.t[i] : static_cast<double>(i);
    }
    jd.q = column(data.X, j);
    jd.qd = column(data.X, N + j);
    jd.measured = column(data.Y, j);
    for (const ModelPredictions& p : models) {
      PredictionSeries s;
      s.label = p.label;
      s.mean = column(p.mean, j);
      s.std = column(p.std, j);
      jd.predictions.push_back(std::move(s));
    }
    joints.push_back(std::move(jd));
  }
  return joints;
}

std::vector<JointStates> JointStatesOf(const RobotData& data) {
  const int N = data.num_joints;
  const Eigen::Index m = data.size();
  std::vector<JointStates> states(static_cast<size_t>(N));
  for (int j = 0; j < N; ++j) {
    JointStates& s = states[static_cast<size_t>(j)];
    s.joint = j + 1;
    s.q.resize(static_cast<size_t>(m));
    s.qd.resize(static_cast<size_t>(m));
    for (Eigen::Index i = 0; i < m; ++i) {
      s.q[static_cast<size_t>(i)] = data.X(i, j);
      s.qd[static_cast<size_t>(i)] = data.X(i, N + j);
    }
  }
  return states;
}

ReportData DiagnosisReportData(const RobotModel& model, const RobotData& data,
                               const Diagnosis& diagnosis) {
  const ModelPredictions p = Predict(model, data);
  ReportData r;
  r.title = "structgp diagnosis: " + p.label + " on " +
            (data.source.empty() ? std::string("the data") : data.source);
  r.data_source = data.source;
  r.joints = JointSeries(data, {p});
  r.has_diagnosis = true;
  r.diagnosis = diagnosis;
  r.errors.push_back(
      ToModelErrors(p.label, ComputeErrors(p.mean, data.Y),
                    BandCoverage(p.mean, p.std, model.hyperparameters().noise_stds(), data.Y)));
  const std::string bands = CalibratedBandsNote(model);
  if (!bands.empty()) r.notes.push_back(bands);
  return r;
}

std::string CalibratedBandsNote(const RobotModel& model) {
  const std::string text = CalibratedBandsText(model);
  if (text.empty()) return {};
  return "The 2 sigma bands are calibrated on the fit's held-out check: " + text + ".";
}

ReportData ReplayReportData(const ReplaySummary& summary, const RobotData& data,
                            const std::string& model_label) {
  const int N = data.num_joints;
  const Eigen::Index m = data.size();
  if (summary.errors.rows() != m || summary.errors.cols() != N) {
    throw std::invalid_argument(
        "ReplayReportData: the replay's errors are " + std::to_string(summary.errors.rows()) +
        " x " + std::to_string(summary.errors.cols()) + ", expected " + std::to_string(m) + " x " +
        std::to_string(N) + " (the rows and joints of the data replayed)");
  }
  ModelPredictions p;
  p.label = "one-step-ahead prediction";
  p.mean = data.Y - summary.errors;  // NaN where the prediction failed
  p.std = Matrix::Zero(m, N);
  ReportData r;
  r.title = "structgp replay: " + model_label;
  r.data_source = data.source;
  r.joints = JointSeries(data, {p});
  for (int j = 0; j < N; ++j) {
    r.joints[static_cast<size_t>(j)].predictions.front().std.clear();  // no band
    TimeSeries e;
    e.label = "measured - one-step-ahead prediction";
    e.values.resize(static_cast<size_t>(m));
    for (Eigen::Index i = 0; i < m; ++i) e.values[static_cast<size_t>(i)] = summary.errors(i, j);
    r.joints[static_cast<size_t>(j)].signal_plots.push_back(
        {"one-step-ahead error over time", "torque error", {std::move(e)}});
  }
  const Eigen::Index fifth = std::max<Eigen::Index>(1, m / 5);
  const auto errors_of = [&](const std::string& label, Eigen::Index begin) {
    const Matrix measured = data.Y.middleRows(begin, fifth);
    const Matrix predicted = measured - summary.errors.middleRows(begin, fifth);
    return ToModelErrors(label, ComputeErrors(predicted, measured));
  };
  r.errors.push_back(errors_of("first fifth of the steps", 0));
  r.errors.push_back(errors_of("last fifth of the steps", m - fifth));
  r.notes.push_back(std::to_string(summary.steps) + " samples replayed in time order (predict, "
                    "then learn), " + std::to_string(summary.segment_starts.size()) +
                    (summary.segment_starts.size() == 1 ? " trajectory" : " trajectories") +
                    "; " + summary.form + " form, " + std::to_string(summary.num_features) +
                    (summary.form == "regressor" ? " parameters" : " features") + "; " +
                    std::to_string(summary.bad_samples) + " bad samples");
  char latency[160];
  std::snprintf(latency, sizeof(latency),
                "update %.1f us p50, %.1f us p99; predict %.1f us p50, %.1f us p99",
                summary.update_us_p50, summary.update_us_p99, summary.predict_us_p50,
                summary.predict_us_p99);
  r.notes.push_back(latency);
  return r;
}

}  // namespace report
}  // namespace structgp
