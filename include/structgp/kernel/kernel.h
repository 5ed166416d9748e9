#ifndef STRUCTGP_KERNEL_KERNEL_H_
#define STRUCTGP_KERNEL_KERNEL_H_

/// @file
/// A positive semi-definite kernel k(a, b) for the function-space model (KernelGP), with its
/// hyper-parameters on a log scale and its gradient with respect to them.
///
/// A kernel is an immutable value, as a FeatureMap is: its parameters are fixed at
/// construction, and WithParameters returns a new kernel with other ones. The models own the
/// parameters in use (Hyperparameters::shape, core/hyperparameters.h) and build their kernel
/// from them, so a kernel shared by const pointer is never changed under its readers.

#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"

namespace structgp {

class Kernel {
 public:
  virtual ~Kernel() = default;

  virtual int input_dim() const = 0;
  /// k(a, b). Must not allocate after construction; not required to be thread-safe.
  virtual double Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const = 0;

  virtual int num_parameters() const = 0;
  virtual std::vector<std::string> parameter_names() const = 0;
  /// The hyper-parameters of this kernel (log scale where positive).
  virtual Vector parameters() const = 0;
  /// A new kernel of the same type and structure with parameters theta (size
  /// num_parameters(), the layout of parameters()); this one is unchanged. Not real-time
  /// (allocates). Throws std::invalid_argument on a size mismatch or non-finite value.
  virtual std::unique_ptr<Kernel> WithParameters(const ConstVectorRef& theta) const = 0;
  /// d k(a, b) / d theta into dk (size num_parameters()).
  virtual void Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const = 0;

  /// An independent copy (same type, same parameters).
  virtual std::unique_ptr<Kernel> Clone() const = 0;

  /// K(i, j) = k(A.row(i), B.row(j)); K is resized to A.rows() x B.rows().
  void Gram(const ConstMatrixRef& A, const ConstMatrixRef& B, Matrix* K) const;
};

/// kernel.WithParameters(theta) as a value of the kernel's own type K (a concrete kernel
/// class, e.g. PolFormulaKernel), for code that holds kernels by value.
template <typename K>
K Reparameterized(const K& kernel, const ConstVectorRef& theta) {
  const std::unique_ptr<Kernel> moved = kernel.WithParameters(theta);
  return static_cast<const K&>(*moved);
}

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_KERNEL_H_
