#ifndef STRUCTGP_HYPER_HYPERPRIOR_H_
#define STRUCTGP_HYPER_HYPERPRIOR_H_

/// @file
/// A prior on the log hyper-parameters, for type-II maximum a posteriori (MAP) instead of
/// plain type-II maximum likelihood: the objective of FitHyperparameters and
/// FitKernelHyperparameters becomes
///
///     f(x) = (-log p(Y | x) - log p(x)) / n,
///
/// with independent priors on the free log values x_i, each centred on its data-derived
/// default c_i (the value the fit starts from) with a width w_i in log units:
///
/// | family    | -log p(x_i) (up to a constant)                             |
/// |-----------|------------------------------------------------------------|
/// | Gaussian  | z^2 / 2, z = (x_i - c_i) / w_i                             |
/// | Student-t | (nu + 1) / 2 * log(1 + z^2 / nu)                           |
///
/// The widths are per group (docs/hyperparameters.md explains the defaults): a log block scale
/// or kernel scale of ln(10) / 2 means that a block whose prior standard deviation is ten
/// times (or a tenth of) the one it starts with, which for a standardised output is about
/// the torque's own scale, lies two widths from the centre.

#include <string>

#include "structgp/core/types.h"

namespace structgp {

/// The shape of the prior on each log hyper-parameter.
enum class HyperpriorFamily {
  /// No prior: plain type-II maximum likelihood.
  kNone,
  /// Independent Gaussians on the log values.
  kGaussian,
  /// Independent Student-t densities on the log values (heavier tails: a value far from its
  /// centre costs log |z| instead of z^2).
  kStudentT,
};

/// "none", "gaussian", "student_t".
const char* ToString(HyperpriorFamily family);
/// The inverse of ToString; false (nothing written) for any other text.
bool FromString(const std::string& text, HyperpriorFamily* family);

/// ln(10) / 2: the default width of a log scale, so that a factor of ten lies two widths away.
inline constexpr double kDecadeOverTwoWidths = 1.151292546497023;

/// The prior of MaximumLikelihoodOptions::prior. Widths are standard deviations (Gaussian) or
/// scales (Student-t) of the log values, in log units; the centres are the starting values
/// the fit is given (FitModel: the data-derived defaults).
struct HyperpriorOptions {
  HyperpriorFamily family = HyperpriorFamily::kGaussian;
  /// Weight space: the feature map's shape parameters (e.g. log sigma of k_pol).
  double shape_width = kDecadeOverTwoWidths;
  /// Weight space: one log scale per block of the feature map.
  double block_scale_width = kDecadeOverTwoWidths;
  /// Both forms: log sigma_n.
  double noise_width = kDecadeOverTwoWidths;
  /// Both forms: the log output scales (when free).
  double output_scale_width = kDecadeOverTwoWidths;
  /// Function space: every parameter of the Kernel (block scales, signal std, length scales,
  /// shape), all log values of the kernel's own units.
  double kernel_parameter_width = kDecadeOverTwoWidths;
  /// kStudentT: degrees of freedom nu (> 0).
  double degrees_of_freedom = 4.0;

  /// True when the options are usable; otherwise false with the reason in *error (may be
  /// null).
  bool IsValid(std::string* error) const;
  /// The same prior with every width divided by `factor` (> 0): `factor`^2 times the
  /// precision of a Gaussian.
  HyperpriorOptions Tightened(double factor) const;
};

/// The prior over the flat vector x of free log hyper-parameters (the layout of
/// HyperparameterLayout or of KernelEvidenceObjective): independent entries, centre c and
/// width w each. Immutable; safe to share between threads.
class LogHyperprior {
 public:
  /// No prior (NegativeLogDensity is 0).
  LogHyperprior() = default;
  /// centre and width of equal size, finite, width > 0; dof > 0 for kStudentT. Throws
  /// std::invalid_argument otherwise. family kNone ignores centre and width.
  LogHyperprior(HyperpriorFamily family, Vector centre, Vector width,
                double degrees_of_freedom = 4.0);

  HyperpriorFamily family() const { return family_; }
  bool active() const { return family_ != HyperpriorFamily::kNone; }
  int size() const { return static_cast<int>(centre_.size()); }
  const Vector& centre() const { return centre_; }
  const Vector& width() const { return width_; }

  /// -log p(x) in nats, without the normalising constant (0 at the centre). When gradient is
  /// not null, d(-log p) / dx is *added* to gradient[0 .. size()-1]. 0 (nothing added) when
  /// not active. x must have size() entries when active (asserted).
  double NegativeLogDensity(const ConstVectorRef& x, double* gradient = nullptr) const;
  /// The same, entry by entry (size() values; zeros when not active).
  Vector Terms(const ConstVectorRef& x) const;

 private:
  HyperpriorFamily family_ = HyperpriorFamily::kNone;
  Vector centre_;
  Vector width_;
  double dof_ = 4.0;
};

}  // namespace structgp

#endif  // STRUCTGP_HYPER_HYPERPRIOR_H_
