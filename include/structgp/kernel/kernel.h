#ifndef STRUCTGP_KERNEL_KERNEL_H_
#define STRUCTGP_KERNEL_KERNEL_H_

/// @file
/// A positive semi-definite kernel k(a, b) for the function-space model (KernelGP), with its
/// hyper-parameters on a log scale and its gradient with respect to them.

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
  /// Current hyper-parameters (log scale where positive).
  virtual Vector parameters() const = 0;
  /// Throws std::invalid_argument on a size mismatch or non-finite value.
  virtual void set_parameters(const ConstVectorRef& theta) = 0;
  /// d k(a, b) / d theta into dk (size num_parameters()).
  virtual void Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const = 0;

  /// An independent copy (same type, same parameters).
  virtual std::unique_ptr<Kernel> Clone() const = 0;

  /// K(i, j) = k(A.row(i), B.row(j)); K is resized to A.rows() x B.rows().
  void Gram(const ConstMatrixRef& A, const ConstMatrixRef& B, Matrix* K) const;
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_KERNEL_H_
