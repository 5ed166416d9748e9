#include "structgp/diagnose/holding_torque.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "structgp/core/validate.h"
#include "structgp/core/noise_level.h"
#include "structgp/diagnose/autocorrelation.h"

namespace structgp {
namespace {

std::string Format(const char* format, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), format, value);
  return buffer;
}

}  // namespace

bool HoldingTorqueOptions::IsValid(std::string* error) const {
  std::string reason;
  if (!(rest_velocity > 0.0) || !std::isfinite(rest_velocity)) {
    reason = "rest_velocity: expected a finite value > 0, got " + std::to_string(rest_velocity);
  } else if (min_rest_rows < 2) {
    reason = "min_rest_rows: expected >= 2, got " + std::to_string(min_rest_rows);
  } else if (max_rows_per_stretch < min_rest_rows) {
    reason = "max_rows_per_stretch: expected >= min_rest_rows (" + std::to_string(min_rest_rows) +
             "), got " + std::to_string(max_rows_per_stretch);
  } else if (!(pose_tolerance >= 0.0) || !std::isfinite(pose_tolerance)) {
    reason = "pose_tolerance: expected a finite value >= 0, got " + std::to_string(pose_tolerance);
  } else if (!(min_difference_to_noise > 0.0) || !std::isfinite(min_difference_to_noise)) {
    reason = "min_difference_to_noise: expected a finite value > 0, got " +
             std::to_string(min_difference_to_noise);
  }
  if (error != nullptr) *error = reason;
  return reason.empty();
}

std::vector<RestStretch> FindRestStretches(const ConstMatrixRef& X, int num_joints,
                                          const std::vector<int>& segment_starts,
                                          const HoldingTorqueOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("HoldingTorqueOptions::" + error);
  const Eigen::Index m = X.rows();
  const int n = num_joints;
  if (n < 1) throw std::invalid_argument("FindRestStretches: expected at least one joint");
  if (X.cols() < 2 * n) {
    throw std::invalid_argument("FindRestStretches: X needs at least 2 N = " +
                                std::to_string(2 * n) + " columns (q, qd), got " +
                                std::to_string(X.cols()));
  }
  RequireFinite("FindRestStretches X", X.leftCols(2 * n));
  std::vector<bool> starts_here(static_cast<size_t>(m), false);
  for (size_t s = 0; s < segment_starts.size(); ++s) {
    const int row = segment_starts[s];
    if (row < 0 || row >= m || (s > 0 && row <= segment_starts[s - 1])) {
      throw std::invalid_argument("FindRestStretches: segment starts must be increasing rows of "
                                  "X (0 to " + std::to_string(m - 1) + "), got " +
                                  std::to_string(row) + " at position " + std::to_string(s));
    }
    starts_here[static_cast<size_t>(row)] = true;
  }
  // Runs of rows at rest, cut where a trajectory starts.
  std::vector<RestStretch> stretches;
  auto at_rest = [&](Eigen::Index i) {
    return (X.row(i).segment(n, n).array().abs() < options.rest_velocity).all();
  };
  auto close_run = [&](Eigen::Index begin, Eigen::Index end) {
    if (end - begin < options.min_rest_rows) return;
    RestStretch s;
    s.begin = static_cast<int>(begin);
    s.end = static_cast<int>(end);
    s.pose = X.middleRows(begin, end - begin).leftCols(n).colwise().mean().transpose();
    stretches.push_back(std::move(s));
  };
  Eigen::Index run = -1;
  for (Eigen::Index i = 0; i < m; ++i) {
    if (run >= 0 && starts_here[static_cast<size_t>(i)]) {
      close_run(run, i);
      run = -1;
    }
    if (at_rest(i)) {
      if (run < 0) run = i;
    } else if (run >= 0) {
      close_run(run, i);
      run = -1;
    }
  }
  if (run >= 0) close_run(run, m);
  return stretches;
}

int ReadRows(const RestStretch& stretch, const HoldingTorqueOptions& options) {
  return std::min(stretch.end - stretch.begin, options.max_rows_per_stretch);
}

HoldingTorqueFinding FindHoldingTorques(const ConstMatrixRef& X, const ConstMatrixRef& R,
                                        const std::vector<int>& segment_starts,
                                        const HoldingTorqueOptions& options) {
  const int n = static_cast<int>(R.cols());
  if (n < 1) throw std::invalid_argument("FindHoldingTorques: R has no columns (joints)");
  RequireSize("FindHoldingTorques R", R.rows(), X.rows(), "rows (as in X)");
  HoldingTorqueFinding out;
  out.stretches = FindRestStretches(X, n, segment_starts, options);
  // Each stretch's first ReadRows rows: their mean residual, and each joint's noise at rest
  // from the successive differences there.
  for (RestStretch& s : out.stretches) {
    const auto rows = R.middleRows(s.begin, ReadRows(s, options));
    RequireFinite("FindHoldingTorques R", rows);
    s.mean_residual = rows.colwise().mean().transpose();
  }
  std::vector<int> starts;  // of each stretch's rows in `rest` below
  int read = 0;
  for (const RestStretch& s : out.stretches) {
    starts.push_back(read);
    read += ReadRows(s, options);
  }
  Vector noise(n), rest(read);
  for (int j = 0; j < n; ++j) {
    for (size_t k = 0; k < out.stretches.size(); ++k) {
      const RestStretch& s = out.stretches[k];
      rest.segment(starts[k], ReadRows(s, options)) =
          R.col(j).segment(s.begin, ReadRows(s, options));
    }
    noise[j] = NoiseFromDifferences(rest, starts);
  }

  // Pairs at the same configuration; per joint the pair whose mean residuals differ most.
  std::vector<HoldingTorqueJoint> best(static_cast<size_t>(n));
  for (size_t a = 0; a < out.stretches.size(); ++a) {
    for (size_t b = a + 1; b < out.stretches.size(); ++b) {
      const RestStretch& A = out.stretches[a];
      const RestStretch& B = out.stretches[b];
      if ((A.pose - B.pose).cwiseAbs().maxCoeff() > options.pose_tolerance) continue;
      ++out.num_pairs;
      for (int j = 0; j < n; ++j) {
        const double difference = std::abs(A.mean_residual[j] - B.mean_residual[j]);
        HoldingTorqueJoint& h = best[static_cast<size_t>(j)];
        if (difference > h.difference) {
          h.joint = j + 1;
          h.difference = difference;
          h.stretch_a = static_cast<int>(a);
          h.stretch_b = static_cast<int>(b);
          h.noise = noise[j];
        }
      }
    }
  }
  for (const HoldingTorqueJoint& h : best) {
    if (h.joint > 0 && h.difference >= options.min_difference_to_noise * h.noise &&
        h.difference > 0.0) {
      out.joints.push_back(h);
    }
  }
  auto ratio = [](const HoldingTorqueJoint& h) {
    return h.noise > 0.0 ? h.difference / h.noise : INFINITY;
  };
  std::stable_sort(out.joints.begin(), out.joints.end(),
                   [&](const HoldingTorqueJoint& x, const HoldingTorqueJoint& y) {
                     return ratio(x) > ratio(y);
                   });
  out.message = HoldingTorqueMessage(out);
  return out;
}

std::string HoldingTorqueMessage(const HoldingTorqueFinding& finding, int log_begin) {
  if (finding.joints.empty()) return std::string();
  std::string list;
  for (size_t k = 0; k < finding.joints.size(); ++k) {
    const HoldingTorqueJoint& h = finding.joints[k];
    if (k > 0) list += k + 1 == finding.joints.size() ? " and " : ", ";
    list += "joint " + std::to_string(h.joint) + " by " + Format("%.3g", h.difference) + " (" +
            Format("%.3g", h.difference / std::max(h.noise, 1e-300)) + " times its noise at rest)";
  }
  auto rows = [&](const RestStretch& s) {
    const bool training = s.begin < log_begin;
    const int offset = training ? 0 : log_begin;
    return std::string(training ? "training rows " : log_begin > 0 ? "rows of the log " : "rows ") +
           std::to_string(s.begin - offset) + "-" + std::to_string(s.end - 1 - offset);
  };
  const HoldingTorqueJoint& first = finding.joints.front();
  return "At rest at the same configuration, the torque differs between stops (" +
         rows(finding.stretches.at(static_cast<size_t>(first.stretch_a))) + " and " +
         rows(finding.stretches.at(static_cast<size_t>(first.stretch_b))) + "): " + list +
         ". Static friction holds what the motion before a stop left (or the load differs "
         "between the stops); no model of the state predicts it, and no effect is suggested "
         "for it.";
}

}  // namespace structgp
