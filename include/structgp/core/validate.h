#ifndef STRUCTGP_CORE_VALIDATE_H_
#define STRUCTGP_CORE_VALIDATE_H_

/// @file
/// Checks of caller input at the API boundary. The Require* functions throw
/// std::invalid_argument with a message naming what is wrong ("expected 12 columns, got 9");
/// AllFinite is the allocation-free test used on the real-time path.

#include <string>

#include "structgp/core/types.h"

namespace structgp {

/// True when every entry is finite (no NaN, no Inf). Never allocates.
bool AllFinite(const Eigen::Ref<const Eigen::MatrixXd>& a);

/// Throws std::invalid_argument "<what>: expected <expected> <unit>, got <got>" on mismatch.
void RequireSize(const std::string& what, Eigen::Index got, Eigen::Index expected,
                 const std::string& unit = "entries");

/// Throws std::invalid_argument naming the first non-finite entry (row and column, 0-based
/// within `what`) when `a` contains NaN or Inf.
void RequireFinite(const std::string& what, const Eigen::Ref<const Eigen::MatrixXd>& a);

/// Throws std::invalid_argument unless lo < value < hi (or lo <= value when closed_lo).
void RequireInRange(const std::string& what, double value, double lo, double hi,
                    bool closed_lo = false, bool closed_hi = false);

}  // namespace structgp

#endif  // STRUCTGP_CORE_VALIDATE_H_
