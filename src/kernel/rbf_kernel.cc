#include "structgp/kernel/rbf_kernel.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "structgp/core/validate.h"

namespace structgp {

RbfKernel::RbfKernel(int input_dim, bool ard, double length_scale, double signal_std)
    : RbfKernel(input_dim, 0, ard, length_scale, signal_std) {}

RbfKernel::RbfKernel(int input_dim, int num_angles, bool ard, double length_scale,
                     double signal_std)
    : input_dim_(input_dim), num_angles_(num_angles), ard_(ard) {
  if (input_dim < 1) {
    throw std::invalid_argument("RbfKernel input_dim: expected at least 1, got " +
                                std::to_string(input_dim));
  }
  const double inf = std::numeric_limits<double>::infinity();
  RequireInRange("RbfKernel length_scale", length_scale, 0.0, inf);
  RequireInRange("RbfKernel signal_std", signal_std, 0.0, inf);
  log_length_scale_ = Vector::Constant(ard ? input_dim : 1, std::log(length_scale));
  log_signal_std_ = std::log(signal_std);
  inverse_squared_length_.resize(input_dim);
  UpdateCache();
}

void RbfKernel::UpdateCache() {
  for (int i = 0; i < input_dim_; ++i) {
    const double log_l = log_length_scale_[ard_ ? i : 0];
    inverse_squared_length_[i] = std::exp(-2.0 * log_l);
  }
  signal_variance_ = std::exp(2.0 * log_signal_std_);
}

double RbfKernel::Difference(int i, double a, double b) const {
  // Chordal distance between the points (cos a, sin a) and (cos b, sin b) for an angle.
  return i < num_angles_ ? 2.0 * std::sin(0.5 * (a - b)) : a - b;
}

double RbfKernel::Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const {
  assert(a.size() == input_dim_ && b.size() == input_dim_);
  // Both vectors are contiguous (ConstVectorRef has unit inner stride). Angles first, then
  // the plain inputs, without a branch per entry: this runs m times per Add or Predict.
  const double* pa = a.data();
  const double* pb = b.data();
  const double* w = inverse_squared_length_.data();
  double r2 = 0.0;
  for (int i = 0; i < num_angles_; ++i) {
    const double d = 2.0 * std::sin(0.5 * (pa[i] - pb[i]));
    r2 += d * d * w[i];
  }
  for (int i = num_angles_; i < input_dim_; ++i) {
    const double d = pa[i] - pb[i];
    r2 += d * d * w[i];
  }
  return signal_variance_ * std::exp(-0.5 * r2);
}

void RbfKernel::Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const {
  assert(dk.size() == num_parameters());
  const double k = Evaluate(a, b);
  // d k / d log l_i = k d_i^2 / l_i^2;  d k / d log sf = 2 k.
  if (!ard_) dk[0] = 0.0;
  for (int i = 0; i < input_dim_; ++i) {
    const double d = Difference(i, a[i], b[i]);
    const double term = k * d * d * inverse_squared_length_[i];
    if (ard_) {
      dk[i] = term;
    } else {
      dk[0] += term;
    }
  }
  dk[num_parameters() - 1] = 2.0 * k;
}

std::vector<std::string> RbfKernel::parameter_names() const {
  std::vector<std::string> names;
  if (ard_) {
    for (int i = 0; i < input_dim_; ++i)
      names.push_back("log_length_scale_" + std::to_string(i + 1));
  } else {
    names.push_back("log_length_scale");
  }
  names.push_back("log_signal_std");
  return names;
}

Vector RbfKernel::parameters() const {
  Vector theta(num_parameters());
  theta.head(log_length_scale_.size()) = log_length_scale_;
  theta[num_parameters() - 1] = log_signal_std_;
  return theta;
}

std::unique_ptr<Kernel> RbfKernel::WithParameters(const ConstVectorRef& theta) const {
  std::unique_ptr<Kernel> kernel = Clone();  // of the dynamic type (RbfKernel or RbfsKernel)
  static_cast<RbfKernel&>(*kernel).AssignParameters(theta);
  return kernel;
}

void RbfKernel::AssignParameters(const ConstVectorRef& theta) {
  RequireSize("RbfKernel::WithParameters theta", theta.size(), num_parameters());
  RequireFinite("RbfKernel::WithParameters theta", theta);
  log_length_scale_ = theta.head(log_length_scale_.size());
  log_signal_std_ = theta[num_parameters() - 1];
  UpdateCache();
}

std::unique_ptr<Kernel> RbfKernel::Clone() const { return std::make_unique<RbfKernel>(*this); }

Vector RbfKernel::length_scales() const { return inverse_squared_length_.array().rsqrt(); }

RbfsKernel::RbfsKernel(int num_joints, bool ard, double length_scale, double signal_std)
    : RbfKernel(3 * std::max(num_joints, 1), std::max(num_joints, 1), ard, length_scale,
                signal_std),
      num_joints_(num_joints) {
  if (num_joints < 1) {
    throw std::invalid_argument("RbfsKernel num_joints: expected at least 1, got " +
                                std::to_string(num_joints));
  }
}

std::vector<std::string> RbfsKernel::parameter_names() const {
  std::vector<std::string> names;
  if (ard()) {
    for (const char* prefix :
         {"log_length_scale_q", "log_length_scale_qd", "log_length_scale_qdd"}) {
      for (int n = 1; n <= num_joints_; ++n) names.push_back(prefix + std::to_string(n));
    }
  } else {
    names.push_back("log_length_scale");
  }
  names.push_back("log_signal_std");
  return names;
}

std::unique_ptr<Kernel> RbfsKernel::Clone() const { return std::make_unique<RbfsKernel>(*this); }

}  // namespace structgp
