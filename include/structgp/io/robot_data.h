#ifndef STRUCTGP_IO_ROBOT_DATA_H_
#define STRUCTGP_IO_ROBOT_DATA_H_

/// @file
/// Samples of a robot's inverse dynamics as read from a file: joint positions, velocities and
/// accelerations with the joint torques they needed.

#include <string>
#include <vector>

#include <Eigen/Core>

namespace structgp {

/// m samples of an N-joint robot, one row per sample, in file order.
///
/// Invariants (kept by ReadRobotCsv and by Rows): X is m x 3N, Y is m x N, and t and line
/// each have either m entries or none (line is empty for data made in memory). Joints are 1-based in every message and file
/// (column `q1` is joint 1) and 0-based in the matrices (column 0 of Y is joint 1).
struct RobotData {
  /// N, the number of joints.
  int num_joints = 0;
  /// Inputs, m x 3N: columns q1..qN [rad or m], qd1..qdN [rad/s or m/s],
  /// qdd1..qddN [rad/s^2 or m/s^2], in that order.
  Eigen::MatrixXd X;
  /// Targets, m x N: joint torques tau1..tauN [N m or N].
  Eigen::MatrixXd Y;
  /// Time of each sample [s], m entries; empty when the file has no `t` column. Non-decreasing
  /// within each trajectory: a log of several trajectories whose time starts again at each
  /// holds one segment per trajectory (segments(), core/segments.h).
  Eigen::VectorXd t;
  /// What Y holds: joint torques (tau1..tauN, N m), or motor currents (cur1..curN, in the
  /// log's units) when the file has those instead. A model fitted to currents predicts
  /// currents: each joint's torque constant and gear ratio become part of its output scale.
  enum class Target { kTorque, kCurrent };
  Target target = Target::kTorque;
  /// "tau" or "cur": the prefix of Y's columns in files.
  const char* target_prefix() const { return target == Target::kCurrent ? "cur" : "tau"; }
  /// The path the data came from (empty for data made in memory).
  std::string source;
  /// 1-based line of each row in `source`, so that later checks can point at the file;
  /// empty when the data were not read from a file.
  Eigen::VectorXi line;

  /// Number of samples m.
  int size() const { return static_cast<int>(X.rows()); }
  /// True when the samples carry a time stamp (t is not empty).
  bool has_time() const { return t.size() > 0; }
  /// First row of each trajectory: SegmentStarts(t) ({0} without times).
  std::vector<int> segments() const;

  /// The `count` contiguous samples starting at sample `begin` (0-based), with their times
  /// and file lines. Throws std::invalid_argument unless 0 <= begin, 0 <= count and
  /// begin + count <= size().
  RobotData Rows(int begin, int count) const;
};

}  // namespace structgp

#endif  // STRUCTGP_IO_ROBOT_DATA_H_
