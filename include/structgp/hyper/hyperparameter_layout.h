#ifndef STRUCTGP_HYPER_HYPERPARAMETER_LAYOUT_H_
#define STRUCTGP_HYPER_HYPERPARAMETER_LAYOUT_H_

/// @file
/// The free entries of a Hyperparameters struct as one flat vector, with a name for each
/// entry: what an optimiser sees and what a report prints.
///
/// Order: shape parameters, log block scales, log noise std, log output scales (only the
/// groups that are free). Names:
///
/// | group        | name                                                   |
/// |--------------|--------------------------------------------------------|
/// | shape        | the map's own, e.g. "log_sigma" (pol), "log_decay"     |
/// | block scale  | "log_scale_<block name>", e.g. "log_scale_inertial"    |
/// | noise        | "log_noise_std"                                        |
/// | output scale | "log_output_scale_<j>", j = 1..P (1-based, like joints) |

#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"

namespace structgp {

/// Which groups of Hyperparameters are free (true) or held at their given values (false).
struct FreeHyperparameters {
  bool shape = true;
  bool block_scales = true;
  bool noise = true;
  bool output_scales = false;
};

/// The group an entry of the flat vector belongs to.
enum class HyperparameterGroup {
  kShape,
  kBlockScale,
  kNoise,
  kOutputScale,
};

/// Immutable after construction.
class HyperparameterLayout {
 public:
  /// Layout for the map's shape parameters and blocks and num_outputs (>= 1) outputs.
  /// Throws std::invalid_argument when num_outputs < 1.
  HyperparameterLayout(const FeatureMap& map, int num_outputs,
                       const FreeHyperparameters& free = FreeHyperparameters());

  /// Number of free entries.
  int size() const { return static_cast<int>(entries_.size()); }
  /// Name of every free entry, in order (see the file comment).
  const std::vector<std::string>& names() const { return names_; }
  HyperparameterGroup group(int i) const { return entries_.at(static_cast<size_t>(i)).group; }
  const FreeHyperparameters& free() const { return free_; }
  int num_outputs() const { return num_outputs_; }

  /// The free entries of `hyper`, in layout order. Works on any struct in the Hyperparameters
  /// layout, e.g. the gradient from WeightSpaceEvidence::Evaluate. Throws
  /// std::invalid_argument when the sizes of hyper do not match the map and outputs.
  Vector Flatten(const Hyperparameters& hyper) const;
  /// Writes x (size()) into the free entries of *hyper; the other entries keep their values.
  /// Throws std::invalid_argument on a size mismatch.
  void Unflatten(const ConstVectorRef& x, Hyperparameters* hyper) const;

 private:
  struct Entry {
    HyperparameterGroup group;
    int index;  // within its group
  };
  void CheckSizes(const Hyperparameters& hyper, const char* what) const;

  FreeHyperparameters free_;
  int num_shape_;
  int num_blocks_;
  int num_outputs_;
  std::vector<Entry> entries_;
  std::vector<std::string> names_;
};

}  // namespace structgp

#endif  // STRUCTGP_HYPER_HYPERPARAMETER_LAYOUT_H_
