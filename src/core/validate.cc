#include "structgp/core/validate.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace structgp {

bool AllFinite(const Eigen::Ref<const Eigen::MatrixXd>& a) {
  // (a - a) is 0 for finite entries and NaN otherwise; allFinite() does exactly this check.
  return a.allFinite();
}

void RequireSize(const std::string& what, Eigen::Index got, Eigen::Index expected,
                 const std::string& unit) {
  if (got != expected) {
    std::ostringstream os;
    os << what << ": expected " << expected << " " << unit << ", got " << got;
    throw std::invalid_argument(os.str());
  }
}

void RequireFinite(const std::string& what, const Eigen::Ref<const Eigen::MatrixXd>& a) {
  if (a.allFinite()) return;
  for (Eigen::Index j = 0; j < a.cols(); ++j) {
    for (Eigen::Index i = 0; i < a.rows(); ++i) {
      if (!std::isfinite(a(i, j))) {
        std::ostringstream os;
        os << what << ": non-finite value " << a(i, j) << " at row " << i << ", column " << j;
        throw std::invalid_argument(os.str());
      }
    }
  }
}

void RequireInRange(const std::string& what, double value, double lo, double hi, bool closed_lo,
                    bool closed_hi) {
  const bool ok_lo = closed_lo ? value >= lo : value > lo;
  const bool ok_hi = closed_hi ? value <= hi : value < hi;
  if (!(ok_lo && ok_hi) || std::isnan(value)) {
    std::ostringstream os;
    os << what << ": expected a value in " << (closed_lo ? "[" : "(") << lo << ", " << hi
       << (closed_hi ? "]" : ")") << ", got " << value;
    throw std::invalid_argument(os.str());
  }
}

}  // namespace structgp
