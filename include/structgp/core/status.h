#ifndef STRUCTGP_CORE_STATUS_H_
#define STRUCTGP_CORE_STATUS_H_

/// @file
/// Outcome of a numerical operation. Numerical trouble is an ordinary result that the caller
/// sees, never an exception and never a silent NaN. Caller mistakes on non-real-time paths
/// (wrong sizes in a batch fit, say) throw std::invalid_argument instead.

namespace structgp {

enum class Status {
  kOk = 0,
  /// A factorisation failed, or a downdate would make the posterior precision indefinite.
  /// The model is left exactly as it was.
  kNotPositiveDefinite,
  /// A sample or query contained NaN/Inf or had the wrong size; it was not used.
  kInvalidInput,
  /// The model was reserved for fewer points than this operation needs (kernel form).
  kCapacityExceeded,
};

/// Stable, human-readable name ("ok", "not_positive_definite", ...), for logs and files.
const char* ToString(Status status);

inline bool IsOk(Status status) { return status == Status::kOk; }

}  // namespace structgp

#endif  // STRUCTGP_CORE_STATUS_H_
