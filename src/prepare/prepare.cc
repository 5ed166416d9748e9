#include "structgp/prepare/prepare.h"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "structgp/io/data_error.h"
#include "structgp/prepare/butterworth.h"

namespace structgp {
namespace {

// A value for a message: 10 significant digits, no trailing zeros.
std::string Num(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.10g", value);
  return buffer;
}

// A percentage for a message, 3 significant digits.
std::string Percent(double fraction) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.3g%%", 100.0 * fraction);
  return buffer;
}

// Fraction of the sampling rate used as cut-off by default for slow logs.
constexpr double kDefaultCutoffFraction = 0.2;

[[noreturn]] void FailTime(const RawLog& log, Eigen::Index row, const std::string& message) {
  const int line = log.line.size() == log.q.rows() ? log.line[row] : 0;
  const int column = log.time_column.size() == log.q.rows() ? log.time_column[row] : 0;
  const std::string where = line > 0 ? "" : "sample " + std::to_string(row + 1) + ": ";
  throw DataError(log.source.empty() ? std::string("(raw log)") : log.source, line, column,
                  where + message);
}

void RequireTimes(const Eigen::VectorXd& t, Eigen::Index m, const char* what) {
  if (t.size() != m) {
    throw std::invalid_argument(std::string(what) + ": expected " + std::to_string(m) +
                                " times (one per row), got " + std::to_string(t.size()));
  }
  if (m < 3) {
    throw std::invalid_argument(std::string(what) + ": needs at least 3 samples, got " +
                                std::to_string(m));
  }
  for (Eigen::Index i = 1; i < m; ++i) {
    if (!(t[i] > t[i - 1])) {
      throw std::invalid_argument(std::string(what) + ": times must strictly increase (sample " +
                                  std::to_string(i) + ")");
    }
  }
}

}  // namespace

Sampling MeasureSampling(const RawLog& log, double max_time_jitter) {
  if (!log.has_time()) throw std::invalid_argument("MeasureSampling: the log has no time column");
  const Eigen::Index m = log.t.size();
  if (m < 2) {
    throw std::invalid_argument("MeasureSampling: needs at least 2 samples, got " +
                                std::to_string(m));
  }
  if (!(max_time_jitter > 0.0)) {
    throw std::invalid_argument("PrepareOptions::max_time_jitter: expected > 0, got " +
                                Num(max_time_jitter));
  }
  std::vector<double> steps(static_cast<std::size_t>(m - 1));
  for (Eigen::Index i = 1; i < m; ++i) {
    const double dt = log.t[i] - log.t[i - 1];
    if (!(dt > 0.0)) {
      FailTime(log, i,
               std::string(dt == 0.0 ? "time does not advance" : "time goes backwards") +
                   ": t = " + Num(log.t[i]) + " after t = " + Num(log.t[i - 1]) +
                   " (t must strictly increase to differentiate; remove repeated samples)");
    }
    steps[static_cast<std::size_t>(i - 1)] = dt;
  }
  std::vector<double> sorted = steps;
  const std::size_t mid = sorted.size() / 2;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(mid), sorted.end());
  Sampling s;
  s.step = sorted[mid];
  s.rate_hz = 1.0 / s.step;
  for (Eigen::Index i = 1; i < m; ++i) {
    const double jitter = std::abs(steps[static_cast<std::size_t>(i - 1)] - s.step) / s.step;
    if (jitter > max_time_jitter) {
      FailTime(log, i,
               "sampling is not uniform: step of " + Num(steps[static_cast<std::size_t>(i - 1)]) +
                   " s from the previous sample, the median step is " + Num(s.step) + " s (" +
                   Percent(jitter) + " off, at most " + Percent(max_time_jitter) +
                   " accepted); split the log at gaps or resample it first");
    }
    s.max_jitter = std::max(s.max_jitter, jitter);
  }
  return s;
}

void Differentiate(const Eigen::VectorXd& t, const Eigen::MatrixXd& x, Eigen::MatrixXd* dx) {
  const Eigen::Index m = x.rows();
  RequireTimes(t, m, "Differentiate");
  dx->resize(m, x.cols());
  // Interior: Lagrange three-point derivative at the middle node, h1 = t_i - t_{i-1},
  // h2 = t_{i+1} - t_i: -h2/(h1 (h1+h2)) x_{i-1} + (h2-h1)/(h1 h2) x_i + h1/(h2 (h1+h2)) x_{i+1}.
  for (Eigen::Index i = 1; i + 1 < m; ++i) {
    const double h1 = t[i] - t[i - 1], h2 = t[i + 1] - t[i];
    dx->row(i) = (-h2 / (h1 * (h1 + h2))) * x.row(i - 1) + ((h2 - h1) / (h1 * h2)) * x.row(i) +
                 (h1 / (h2 * (h1 + h2))) * x.row(i + 1);
  }
  // Ends: the same parabola's slope at its first / last node.
  {
    const double h1 = t[1] - t[0], h2 = t[2] - t[1];
    dx->row(0) = (-(2.0 * h1 + h2) / (h1 * (h1 + h2))) * x.row(0) +
                 ((h1 + h2) / (h1 * h2)) * x.row(1) - (h1 / (h2 * (h1 + h2))) * x.row(2);
  }
  {
    const Eigen::Index k = m - 1;
    const double h1 = t[k - 1] - t[k - 2], h2 = t[k] - t[k - 1];
    dx->row(k) = (h2 / (h1 * (h1 + h2))) * x.row(k - 2) - ((h1 + h2) / (h1 * h2)) * x.row(k - 1) +
                 ((2.0 * h2 + h1) / (h2 * (h1 + h2))) * x.row(k);
  }
}

void SecondDifference(const Eigen::VectorXd& t, const Eigen::MatrixXd& x, Eigen::MatrixXd* ddx) {
  const Eigen::Index m = x.rows();
  RequireTimes(t, m, "SecondDifference");
  ddx->resize(m, x.cols());
  // The parabola through three nodes has second derivative
  // 2 (x_{i-1}/(h1 (h1+h2)) - x_i/(h1 h2) + x_{i+1}/(h2 (h1+h2))).
  for (Eigen::Index i = 1; i + 1 < m; ++i) {
    const double h1 = t[i] - t[i - 1], h2 = t[i + 1] - t[i];
    ddx->row(i) = (2.0 / (h1 * (h1 + h2))) * x.row(i - 1) - (2.0 / (h1 * h2)) * x.row(i) +
                  (2.0 / (h2 * (h1 + h2))) * x.row(i + 1);
  }
  ddx->row(0) = ddx->row(1);
  ddx->row(m - 1) = ddx->row(m - 2);
}

RobotData PrepareRawLog(const RawLog& log, const PrepareOptions& options, PrepareSummary* summary) {
  const int n = log.num_joints;
  const Eigen::Index m = log.q.rows();
  if (n < 1 || log.q.cols() != n) {
    throw std::invalid_argument("PrepareRawLog: q must have num_joints (" + std::to_string(n) +
                                ") columns, got " + std::to_string(log.q.cols()));
  }
  if (m < 3) {
    throw std::invalid_argument("PrepareRawLog: needs at least 3 samples to differentiate, got " +
                                std::to_string(m));
  }
  if (options.order < 1 || options.order > kMaxButterworthOrder) {
    throw std::invalid_argument("PrepareOptions::order: expected 1.." +
                                std::to_string(kMaxButterworthOrder) + ", got " +
                                std::to_string(options.order));
  }
  if (!(options.cutoff_hz >= 0.0) || !std::isfinite(options.cutoff_hz)) {
    throw std::invalid_argument("PrepareOptions::cutoff_hz: expected >= 0 (0 = default), got " +
                                Num(options.cutoff_hz));
  }
  if (!(options.sample_rate_hz >= 0.0) || !std::isfinite(options.sample_rate_hz)) {
    throw std::invalid_argument(
        "PrepareOptions::sample_rate_hz: expected >= 0 (0 = from t), "
        "got " +
        Num(options.sample_rate_hz));
  }

  // Torques.
  Eigen::MatrixXd tau;
  const bool from_current = !options.current_gains.empty();
  if (from_current) {
    if (static_cast<int>(options.current_gains.size()) != n) {
      throw std::invalid_argument("PrepareOptions::current_gains: expected " + std::to_string(n) +
                                  " gains (one per joint), got " +
                                  std::to_string(options.current_gains.size()));
    }
    for (size_t j = 0; j < options.current_gains.size(); ++j) {
      if (!std::isfinite(options.current_gains[j]) || options.current_gains[j] == 0.0) {
        throw std::invalid_argument("PrepareOptions::current_gains: gain of joint " +
                                    std::to_string(j + 1) + " must be finite and non-zero, got " +
                                    Num(options.current_gains[j]));
      }
    }
    if (log.current.cols() != n || log.current.rows() != m) {
      throw std::invalid_argument(
          "PrepareOptions::current_gains: the log has no current columns "
          "i1..i" +
          std::to_string(n));
    }
    tau = log.current *
          Eigen::Map<const Eigen::VectorXd>(options.current_gains.data(), n).asDiagonal();
  } else {
    if (log.tau.cols() != n || log.tau.rows() != m) {
      throw std::invalid_argument(
          "PrepareOptions::current_gains: the log has no torque columns "
          "tau1..tau" +
          std::to_string(n) + ", so current gains are needed to convert i1..i" + std::to_string(n));
    }
    tau = log.tau;
  }

  // Sampling.
  PrepareSummary s;
  Eigen::VectorXd t;
  if (log.has_time()) {
    const Sampling sampling = MeasureSampling(log, options.max_time_jitter);
    if (options.sample_rate_hz > 0.0 &&
        std::abs(options.sample_rate_hz - sampling.rate_hz) > kMaxRateMismatch * sampling.rate_hz) {
      throw std::invalid_argument("PrepareOptions::sample_rate_hz: " + Num(options.sample_rate_hz) +
                                  " Hz disagrees with the time column (median step " +
                                  Num(sampling.step) + " s, " + Num(sampling.rate_hz) +
                                  " Hz); leave it out to use the measured rate");
    }
    s.sample_rate_hz = options.sample_rate_hz > 0.0 ? options.sample_rate_hz : sampling.rate_hz;
    s.rate_from_time = options.sample_rate_hz == 0.0;
    s.max_time_jitter = sampling.max_jitter;
    t = log.t;
  } else {
    if (options.sample_rate_hz == 0.0) {
      throw std::invalid_argument(
          "PrepareOptions::sample_rate_hz: the log has no time column "
          "'t', so the sampling rate must be given");
    }
    s.sample_rate_hz = options.sample_rate_hz;
    t = Eigen::VectorXd::LinSpaced(m, 0.0, static_cast<double>(m - 1)) / s.sample_rate_hz;
  }
  s.cutoff_hz = options.cutoff_hz > 0.0
                    ? options.cutoff_hz
                    : std::min(kDefaultCutoffHz, kDefaultCutoffFraction * s.sample_rate_hz);
  if (!(s.cutoff_hz < 0.5 * s.sample_rate_hz)) {
    throw std::invalid_argument("PrepareOptions::cutoff_hz: " + Num(s.cutoff_hz) +
                                " Hz is not below half the sampling rate (" +
                                Num(0.5 * s.sample_rate_hz) + " Hz)");
  }
  const ButterworthLowPass filter(options.order, s.cutoff_hz, s.sample_rate_hz);
  s.order = options.order;
  s.padding = filter.PaddingLength(m);
  // One cut-off period (a measured rate is a hair off the nominal one: round, don't ceil).
  s.edge_samples = static_cast<int>(std::lround(s.sample_rate_hz / s.cutoff_hz));

  // Smooth, then differentiate.
  Eigen::MatrixXd q(m, n);
  Eigen::VectorXd column;
  for (int j = 0; j < n; ++j) {
    filter.FiltFilt(log.q.col(j), &column);
    q.col(j) = column;
  }
  if (options.filter_torque) {
    for (int j = 0; j < n; ++j) {
      filter.FiltFilt(tau.col(j), &column);
      tau.col(j) = column;
    }
  }
  Eigen::MatrixXd qd, qdd;
  Differentiate(t, q, &qd);
  SecondDifference(t, q, &qdd);

  Eigen::Index begin = 0, count = m;
  if (options.trim_edges) {
    begin = s.edge_samples;
    count = m - 2 * begin;
    if (count < 3) {
      throw std::invalid_argument("PrepareOptions::trim_edges: the log has " + std::to_string(m) +
                                  " samples, too few to drop " + std::to_string(begin) +
                                  " at each end");
    }
  }
  RobotData data;
  data.num_joints = n;
  data.X.resize(count, 3 * n);
  data.X.leftCols(n) = q.middleRows(begin, count);
  data.X.middleCols(n, n) = qd.middleRows(begin, count);
  data.X.rightCols(n) = qdd.middleRows(begin, count);
  data.Y = tau.middleRows(begin, count);
  data.t = t.segment(begin, count);
  data.source = log.source;
  if (log.line.size() == m) data.line = log.line.segment(begin, count);

  s.num_joints = n;
  s.num_samples = static_cast<int>(count);
  s.torque_from_current = from_current;
  s.torque_filtered = options.filter_torque;
  if (summary) *summary = s;
  return data;
}

}  // namespace structgp
