#ifndef STRUCTGP_CORE_TYPES_H_
#define STRUCTGP_CORE_TYPES_H_

/// @file
/// Dense types used across the library. Data sets are stored one sample per row.

#include <Eigen/Core>

namespace structgp {

using Vector = Eigen::VectorXd;
using Matrix = Eigen::MatrixXd;
/// Read-only view of a vector: accepts a VectorXd, a segment or a mapped buffer, no copy.
using ConstVectorRef = Eigen::Ref<const Eigen::VectorXd>;
/// Writable view of a vector of the right size.
using VectorRef = Eigen::Ref<Eigen::VectorXd>;
using ConstMatrixRef = Eigen::Ref<const Eigen::MatrixXd>;
/// Writable view of a matrix of the right size.
using MatrixRef = Eigen::Ref<Eigen::MatrixXd>;

}  // namespace structgp

#endif  // STRUCTGP_CORE_TYPES_H_
