#ifndef STRUCTGP_REPORT_REPORT_H_
#define STRUCTGP_REPORT_REPORT_H_

/// @file
/// The diagnosis report: one self-contained HTML file (no network, no external scripts) with,
/// the diagnosis' verdict first; per joint, measured vs predicted torque over time with a
/// +-2 sigma band, the residual against qd and against q (where a friction step or a cogging
/// ripple shows), and for each suggestion on the joint the residual on the diagnosed log
/// against qd and q before and after it; the ranked suggestions with their calibration and
/// confirmation numbers; the distance of the log to the training states over time (when the
/// diagnosis has it); for a comparison, the errors of each model per joint; and signals over
/// time such as a replay's one-step-ahead error (SignalPlot).
/// Plots are interactive (zoom by dragging, double-click to reset, hover for values).

#include <string>
#include <vector>

#include "structgp/diagnose/diagnosis.h"

namespace structgp {
namespace report {

/// One model's predictions for one joint, aligned with the measurements.
struct PredictionSeries {
  std::string label;           ///< model name, e.g. "pol" or "pol + coulomb@2"
  std::vector<double> mean;    ///< predicted torque per sample
  std::vector<double> std;     ///< predictive standard deviation per sample (may be empty)
};

/// A signal of one joint over time that is not a torque prediction (e.g. a replay's
/// one-step-ahead error).
struct TimeSeries {
  std::string label;
  std::vector<double> values;  ///< one per measured sample; NaN: none (drawn as a gap)
};

/// A plot of signals over time, drawn after the joint's torque plot, with a zero line.
struct SignalPlot {
  std::string title;    ///< "one-step-ahead error" (shown as "Joint j: <title>")
  std::string y_label;  ///< "torque error"
  std::vector<TimeSeries> series;
};

struct JointData {
  int joint = 0;                    ///< 1-based
  std::vector<double> t;            ///< time (s) or sample index when the data have no time
  std::vector<double> q, qd;        ///< the joint's position and velocity
  std::vector<double> measured;     ///< measured torque
  std::vector<PredictionSeries> predictions;  ///< one per model (first = the model diagnosed)
  std::vector<SignalPlot> signal_plots;       ///< more plots over time (may be empty)
};

/// The states of one joint on the diagnosed log, one per row of the diagnosis.
struct JointStates {
  int joint = 0;                ///< 1-based
  std::vector<double> q, qd;    ///< position and velocity (either may be empty)
};

/// Errors of one model, per joint.
struct ModelErrors {
  std::string label;
  std::vector<double> rms;   ///< per joint
  std::vector<double> nmse;  ///< per joint
  /// Per joint, the fraction of the measured torques inside the noisy 2 sigma band
  /// (BandCoverage, fit/fit_check.h); empty when the band is not known (no column then).
  std::vector<double> coverage;
};

struct ReportData {
  std::string title = "structgp report";
  std::string data_source;          ///< the data file
  std::vector<JointData> joints;
  bool has_diagnosis = false;
  Diagnosis diagnosis;              ///< when has_diagnosis
  /// The diagnosed log's states per joint, when `joints` show other data (the demo diagnoses
  /// its training log and plots its test log): each suggestion's residual before and after it
  /// (Suggestion::residual_before_rows, one per row of the diagnosed log) is plotted against
  /// these. Empty: the diagnosed log is the data of `joints`.
  std::vector<JointStates> diagnosed_states;
  std::vector<ModelErrors> errors;  ///< one per model (compare: before, after)
  std::vector<std::string> notes;   ///< free text lines shown at the top
};

/// The complete HTML document. At most max_points_per_plot points are drawn per series
/// (evenly thinned, extremes kept) so that large logs stay light.
std::string RenderHtml(const ReportData& data, int max_points_per_plot = 4000);

}  // namespace report
}  // namespace structgp

#endif  // STRUCTGP_REPORT_REPORT_H_
