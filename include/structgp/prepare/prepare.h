#ifndef STRUCTGP_PREPARE_PREPARE_H_
#define STRUCTGP_PREPARE_PREPARE_H_

/// @file
/// From a raw log (joint positions against time, torques or motor currents) to robot data
/// (q, qd, qdd, tau) for fitting: the sampling is checked, the positions are smoothed by a
/// zero-phase Butterworth low-pass (butterworth.h) and differentiated by central differences,
/// currents are turned into torques with per-joint gains.
///
/// Why filter first, then differentiate. Forward-backward filtering and differencing are both
/// linear and time-invariant, so in exact arithmetic the order would not matter for the
/// interior; but the filter's edge handling (odd reflection) is designed for a smooth signal
/// that keeps its value and slope at the ends, which the positions are and a differenced,
/// noise-dominated velocity is not. Filtering q once also gives one smooth q from which qd and
/// qdd are taken consistently (qdd is the second difference of the same filtered q), and the
/// output q is that filtered q, so the three columns describe one trajectory. Central
/// differences have no phase lag and an O(h^2) truncation error, negligible below the
/// cut-off: at f = f_c = 10 Hz and 1 kHz the relative error of the first difference is
/// (2 pi f h)^2 / 6 = 0.07%.
///
/// Edges: within about f_s / f_c samples of either end the reflection is only an
/// approximation of the unknown continuation, and qdd there is biased (the odd reflection
/// flips the curvature). PrepareSummary::edge_samples says how many; PrepareOptions::trim_edges
/// drops them.

#include <string>
#include <vector>

#include "structgp/io/robot_data.h"
#include "structgp/prepare/raw_log.h"

namespace structgp {

/// Default largest relative deviation of a time step from the median step (10%).
inline constexpr double kDefaultMaxTimeJitter = 0.1;
/// Default cut-off [Hz] when none is given: robot arms move well below 10 Hz; logs sampled
/// slower than 50 Hz get a fifth of their sampling rate instead.
inline constexpr double kDefaultCutoffHz = 10.0;
/// Largest relative difference accepted between a sample rate given by the caller and the one
/// measured from the time column (1%).
inline constexpr double kMaxRateMismatch = 0.01;

struct PrepareOptions {
  /// Cut-off frequency of the low-pass [Hz]; 0 picks min(kDefaultCutoffHz, rate / 5). Must be
  /// below half the sampling rate.
  double cutoff_hz = 0.0;
  /// Butterworth order (1..kMaxButterworthOrder); each of the two passes has this order.
  int order = 3;
  /// Sampling rate [Hz]. Without a time column it is required and the times become
  /// t_i = i / rate. With one, 0 measures it from the median step, and a given rate must
  /// agree with the measured one within kMaxRateMismatch.
  double sample_rate_hz = 0.0;
  /// Per-joint torque constants (N values, torque per unit of current): tau_j = g_j i_j from
  /// the current columns i1..iN. Empty: the log's tau columns are used.
  std::vector<double> current_gains;
  /// Also smooth the torques with the same zero-phase filter (off: torque noise is left to
  /// the model's noise term, where it belongs).
  bool filter_torque = false;
  /// Largest accepted |dt_i - median dt| / median dt. Logs with gaps or dropped samples must
  /// be split or resampled first.
  double max_time_jitter = kDefaultMaxTimeJitter;
  /// Drop PrepareSummary::edge_samples rows at both ends of the output.
  bool trim_edges = false;
};

/// The sampling of a raw log as measured from its time column.
struct Sampling {
  /// 1 / median time step [Hz].
  double rate_hz = 0.0;
  /// Median time step [s].
  double step = 0.0;
  /// Largest |dt_i - step| / step over the log.
  double max_jitter = 0.0;
};

/// Measures the sampling of a log with a time column and checks that t strictly increases and
/// that every step is within max_time_jitter of the median. Throws DataError naming the file,
/// line and column of the first offending `t` cell (line 0 for a log made in memory), and
/// std::invalid_argument when the log has fewer than 2 samples or no time column.
Sampling MeasureSampling(const RawLog& log, double max_time_jitter = kDefaultMaxTimeJitter);

/// What PrepareRawLog did.
struct PrepareSummary {
  int num_joints = 0;
  int num_samples = 0;           ///< rows written (after trimming)
  double sample_rate_hz = 0.0;   ///< nominal rate used for the filter
  bool rate_from_time = false;   ///< measured from the t column (else given)
  double max_time_jitter = 0.0;  ///< largest relative step deviation seen (0 without t)
  double cutoff_hz = 0.0;
  int order = 0;
  int padding = 0;       ///< reflected samples added at each end
  int edge_samples = 0;  ///< samples at each end where the edge transient may bias qdd
  bool torque_from_current = false;
  bool torque_filtered = false;
};

/// Derivative of x (one column per signal, one row per sample) against the sample times t by
/// three-point differences: central in the interior (exact for quadratics, for any spacing),
/// one-sided of second order at the two ends. Needs m >= 3 strictly increasing times.
void Differentiate(const Eigen::VectorXd& t, const Eigen::MatrixXd& x, Eigen::MatrixXd* dx);
/// Second derivative by the three-point formula (central in the interior; the ends take the
/// value of their neighbour's stencil). Needs m >= 3 strictly increasing times.
void SecondDifference(const Eigen::VectorXd& t, const Eigen::MatrixXd& x, Eigen::MatrixXd* ddx);

/// Prepares robot data from a raw log: the result has t, filtered q, qd, qdd and tau, one row
/// per (kept) sample, with the log's source and file lines. Throws std::invalid_argument for
/// invalid options (naming the PrepareOptions field, e.g. a gain count that is not N, a
/// missing rate without time column, a rate that disagrees with t, a cut-off at or above
/// half the rate) and DataError for a time column that is not increasing or not uniform
/// enough. Needs at least 3 samples (after trimming).
RobotData PrepareRawLog(const RawLog& log, const PrepareOptions& options,
                        PrepareSummary* summary = nullptr);

}  // namespace structgp

#endif  // STRUCTGP_PREPARE_PREPARE_H_
