#ifndef STRUCTGP_REPORT_REPORT_DATA_H_
#define STRUCTGP_REPORT_REPORT_DATA_H_

/// @file
/// What goes into a report, from a model and data: each model's predictions on the rows, their
/// errors per joint, the per-joint series of the plots, and the whole ReportData of a
/// diagnosis (what `structgp diagnose --report` writes) and of a replay (`structgp replay
/// --report`).

#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/io/robot_data.h"
#include "structgp/model/robot_model.h"
#include "structgp/online/replay.h"
#include "structgp/report/report.h"

namespace structgp {
namespace report {

/// One model's predictions on the m rows of some data.
struct ModelPredictions {
  std::string label;  ///< "pol + coulomb@2"
  Matrix mean;        ///< m x N
  Matrix std;         ///< m x N, latent (without the measurement noise)
};

/// Predictions of `model` on `data` (ModelInputs, then RobotModel::PredictRows). Throws
/// std::invalid_argument when the model needs the time and the data have none, or on sizes;
/// std::runtime_error when a prediction fails numerically.
ModelPredictions Predict(const RobotModel& model, const RobotData& data);

/// Errors of predictions against measurements (both m x N), per joint and overall.
struct PredictionErrors {
  Vector rms;                 ///< per joint
  Vector nmse;                ///< per joint: MSE / variance of the measured torque (inf when 0)
  double overall_rms = 0.0;   ///< over every joint and sample
  double overall_nmse = 0.0;  ///< mean of the per-joint nMSE
};
PredictionErrors ComputeErrors(const Matrix& predicted, const Matrix& measured);

/// The errors of one model as a report shows them; with `coverage` (per joint, BandCoverage of
/// fit/fit_check.h), also its 2 sigma band's coverage.
ModelErrors ToModelErrors(const std::string& label, const PredictionErrors& errors,
                          const Vector& coverage = Vector());

/// The per-joint series of a report: t (or the row index without times), q, qd, the measured
/// torque and each model's predictions.
std::vector<JointData> JointSeries(const RobotData& data,
                                   const std::vector<ModelPredictions>& models);

/// The states (q, qd) of each joint of `data`: ReportData::diagnosed_states when a report
/// plots other data than the diagnosed ones.
std::vector<JointStates> JointStatesOf(const RobotData& data);

/// The report of a diagnosis of `model` on `data`: title, the model's predictions with their
/// error bars, its errors and the findings. Throws as Predict.
ReportData DiagnosisReportData(const RobotModel& model, const RobotData& data,
                               const Diagnosis& diagnosis);

/// The note a report shows for a model whose bands are calibrated
/// (RobotModel::latent_variance_scale not all 1), naming the joints and their factors; empty
/// otherwise. DiagnosisReportData adds it.
std::string CalibratedBandsNote(const RobotModel& model);

/// The report of a replay of `data` (the log that was replayed, in the same row order):
/// per joint the measured torque with the one-step-ahead prediction (measured - error), the
/// one-step-ahead error over time (SignalPlot "one-step-ahead error"), and the residual plots;
/// the RMS and nMSE of the error over the first and the last fifth of the steps; the replay's
/// counters and latencies as notes. model_label names the model ("rbd+fri from zero").
/// Throws std::invalid_argument when the summary's errors are not data.size() x N.
ReportData ReplayReportData(const ReplaySummary& summary, const RobotData& data,
                            const std::string& model_label);

}  // namespace report
}  // namespace structgp

#endif  // STRUCTGP_REPORT_REPORT_DATA_H_
