#include "structgp/hyper/hyperparameter_layout.h"

#include <stdexcept>

#include "structgp/core/validate.h"

namespace structgp {

HyperparameterLayout::HyperparameterLayout(const FeatureMap& map, int num_outputs,
                                           const FreeHyperparameters& free)
    : free_(free),
      num_shape_(map.num_shape_parameters()),
      num_blocks_(static_cast<int>(map.blocks().size())),
      num_outputs_(num_outputs) {
  if (num_outputs < 1) {
    throw std::invalid_argument("HyperparameterLayout: expected num_outputs >= 1, got " +
                                std::to_string(num_outputs));
  }
  if (free.shape) {
    const std::vector<std::string> shape_names = map.shape_parameter_names();
    for (int i = 0; i < num_shape_; ++i) {
      entries_.push_back({HyperparameterGroup::kShape, i});
      names_.push_back(i < static_cast<int>(shape_names.size())
                           ? shape_names[static_cast<size_t>(i)]
                           : "shape_" + std::to_string(i + 1));
    }
  }
  if (free.block_scales) {
    const std::vector<FeatureBlock> blocks = map.blocks();
    for (int b = 0; b < num_blocks_; ++b) {
      entries_.push_back({HyperparameterGroup::kBlockScale, b});
      names_.push_back("log_scale_" + blocks[static_cast<size_t>(b)].name);
    }
  }
  if (free.noise) {
    entries_.push_back({HyperparameterGroup::kNoise, 0});
    names_.push_back("log_noise_std");
  }
  if (free.output_scales) {
    for (int j = 0; j < num_outputs_; ++j) {
      entries_.push_back({HyperparameterGroup::kOutputScale, j});
      names_.push_back("log_output_scale_" + std::to_string(j + 1));
    }
  }
}

void HyperparameterLayout::CheckSizes(const Hyperparameters& hyper, const char* what) const {
  const std::string prefix = std::string("HyperparameterLayout::") + what;
  RequireSize(prefix + " shape", hyper.shape.size(), num_shape_);
  RequireSize(prefix + " log_block_scale", hyper.log_block_scale.size(), num_blocks_);
  RequireSize(prefix + " log_output_scale", hyper.log_output_scale.size(), num_outputs_);
}

Vector HyperparameterLayout::Flatten(const Hyperparameters& hyper) const {
  CheckSizes(hyper, "Flatten");
  Vector x(size());
  for (int i = 0; i < size(); ++i) {
    const Entry& e = entries_[static_cast<size_t>(i)];
    switch (e.group) {
      case HyperparameterGroup::kShape:
        x[i] = hyper.shape[e.index];
        break;
      case HyperparameterGroup::kBlockScale:
        x[i] = hyper.log_block_scale[e.index];
        break;
      case HyperparameterGroup::kNoise:
        x[i] = hyper.log_noise_std;
        break;
      case HyperparameterGroup::kOutputScale:
        x[i] = hyper.log_output_scale[e.index];
        break;
    }
  }
  return x;
}

void HyperparameterLayout::Unflatten(const ConstVectorRef& x, Hyperparameters* hyper) const {
  if (hyper == nullptr) throw std::invalid_argument("HyperparameterLayout::Unflatten: null hyper");
  RequireSize("HyperparameterLayout::Unflatten x", x.size(), size());
  CheckSizes(*hyper, "Unflatten");
  for (int i = 0; i < size(); ++i) {
    const Entry& e = entries_[static_cast<size_t>(i)];
    switch (e.group) {
      case HyperparameterGroup::kShape:
        hyper->shape[e.index] = x[i];
        break;
      case HyperparameterGroup::kBlockScale:
        hyper->log_block_scale[e.index] = x[i];
        break;
      case HyperparameterGroup::kNoise:
        hyper->log_noise_std = x[i];
        break;
      case HyperparameterGroup::kOutputScale:
        hyper->log_output_scale[e.index] = x[i];
        break;
    }
  }
}

}  // namespace structgp
