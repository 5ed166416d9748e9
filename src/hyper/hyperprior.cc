#include "structgp/hyper/hyperprior.h"

#include <cassert>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace structgp {
namespace {

bool WidthValid(const char* name, double value, std::string* error) {
  if (std::isfinite(value) && value > 0.0) return true;
  if (error != nullptr) {
    std::ostringstream os;
    os << "HyperpriorOptions::" << name << ": expected a finite width > 0 (log units), got "
       << value;
    *error = os.str();
  }
  return false;
}

}  // namespace

const char* ToString(HyperpriorFamily family) {
  switch (family) {
    case HyperpriorFamily::kNone:
      return "none";
    case HyperpriorFamily::kGaussian:
      return "gaussian";
    case HyperpriorFamily::kStudentT:
      return "student_t";
  }
  return "unknown";
}

bool FromString(const std::string& text, HyperpriorFamily* family) {
  for (HyperpriorFamily f :
       {HyperpriorFamily::kNone, HyperpriorFamily::kGaussian, HyperpriorFamily::kStudentT}) {
    if (text == ToString(f)) {
      *family = f;
      return true;
    }
  }
  return false;
}

bool HyperpriorOptions::IsValid(std::string* error) const {
  if (family == HyperpriorFamily::kNone) return true;
  if (family == HyperpriorFamily::kStudentT &&
      !(std::isfinite(degrees_of_freedom) && degrees_of_freedom > 0.0)) {
    if (error != nullptr) {
      *error = "HyperpriorOptions::degrees_of_freedom: expected a finite value > 0, got " +
               std::to_string(degrees_of_freedom);
    }
    return false;
  }
  return WidthValid("shape_width", shape_width, error) &&
         WidthValid("block_scale_width", block_scale_width, error) &&
         WidthValid("noise_width", noise_width, error) &&
         WidthValid("output_scale_width", output_scale_width, error) &&
         WidthValid("kernel_parameter_width", kernel_parameter_width, error);
}

HyperpriorOptions HyperpriorOptions::Tightened(double factor) const {
  if (!(std::isfinite(factor) && factor > 0.0)) {
    throw std::invalid_argument("HyperpriorOptions::Tightened: expected a finite factor > 0, got " +
                                std::to_string(factor));
  }
  HyperpriorOptions o = *this;
  o.shape_width /= factor;
  o.block_scale_width /= factor;
  o.noise_width /= factor;
  o.output_scale_width /= factor;
  o.kernel_parameter_width /= factor;
  return o;
}

LogHyperprior::LogHyperprior(HyperpriorFamily family, Vector centre, Vector width,
                             double degrees_of_freedom)
    : family_(family), dof_(degrees_of_freedom) {
  if (family_ == HyperpriorFamily::kNone) return;
  if (centre.size() != width.size()) {
    throw std::invalid_argument("LogHyperprior: centre has " + std::to_string(centre.size()) +
                                " entries, width " + std::to_string(width.size()) +
                                "; expected the same number");
  }
  if (!centre.allFinite()) throw std::invalid_argument("LogHyperprior: centre is not finite");
  for (Eigen::Index i = 0; i < width.size(); ++i) {
    if (!(std::isfinite(width[i]) && width[i] > 0.0)) {
      throw std::invalid_argument("LogHyperprior: width " + std::to_string(i) +
                                  " must be finite and > 0, got " + std::to_string(width[i]));
    }
  }
  if (family_ == HyperpriorFamily::kStudentT && !(std::isfinite(dof_) && dof_ > 0.0)) {
    throw std::invalid_argument("LogHyperprior: degrees of freedom must be finite and > 0, got " +
                                std::to_string(dof_));
  }
  centre_ = std::move(centre);
  width_ = std::move(width);
}

double LogHyperprior::NegativeLogDensity(const ConstVectorRef& x, double* gradient) const {
  if (!active()) return 0.0;
  assert(x.size() == centre_.size());
  double total = 0.0;
  for (Eigen::Index i = 0; i < centre_.size(); ++i) {
    const double z = (x[i] - centre_[i]) / width_[i];
    if (family_ == HyperpriorFamily::kGaussian) {
      total += 0.5 * z * z;
      if (gradient != nullptr) gradient[i] += z / width_[i];
    } else {
      total += 0.5 * (dof_ + 1.0) * std::log1p(z * z / dof_);
      if (gradient != nullptr) gradient[i] += (dof_ + 1.0) * z / (dof_ + z * z) / width_[i];
    }
  }
  return total;
}

Vector LogHyperprior::Terms(const ConstVectorRef& x) const {
  Vector terms = Vector::Zero(centre_.size());
  if (!active()) return terms;
  for (Eigen::Index i = 0; i < centre_.size(); ++i) {
    terms[i] = LogHyperprior(family_, centre_.segment(i, 1), width_.segment(i, 1), dof_)
                   .NegativeLogDensity(x.segment(i, 1));
  }
  return terms;
}

}  // namespace structgp
