#include "structgp/core/status.h"

namespace structgp {

const char* ToString(Status status) {
  switch (status) {
    case Status::kOk: return "ok";
    case Status::kNotPositiveDefinite: return "not_positive_definite";
    case Status::kInvalidInput: return "invalid_input";
    case Status::kCapacityExceeded: return "capacity_exceeded";
  }
  return "unknown";
}

}  // namespace structgp
