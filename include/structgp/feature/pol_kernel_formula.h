#ifndef STRUCTGP_FEATURE_POL_KERNEL_FORMULA_H_
#define STRUCTGP_FEATURE_POL_KERNEL_FORMULA_H_

/// @file
/// The structured kernels of the paper evaluated directly from their formulas, in O(N) per
/// pair. They are the reference for PolFeatureMap (sum_k lambda_k phi_k(a) phi_k(b) equals
/// PolKernel(a, b, N, sigma) up to rounding) and the exact kernel form when the explicit map is
/// too large (N >= 4).
///
/// Arguments a and b are robot states (q_1..q_N, qd_1..qd_N, qdd_1..qdd_N) of 3N entries;
/// sigma >= 0 (sigma = +inf is allowed: theta = 0). Each function throws std::invalid_argument
/// when a or b does not have 3 * num_joints entries or num_joints < 1; none allocates.

#include "structgp/core/types.h"

namespace structgp {

/// k_qdd(a, b) = <qdd_a, qdd_b> / N  (eq. 7).
double QddKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints);

/// k_qd(x)qd(a, b) = <qd_a, qd_b>^2 / N^2  (eq. 8).
double QdQdKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints);

/// k_psi(a, b) = prod_n (cos(q_an - q_bn) + 1)  (eq. 9).
double PsiKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints);

/// k_psi_sigma(a, b) = c_psi prod_n (1 + theta cos(q_an - q_bn)), theta = 1 / (1 + sigma),
/// c_psi = (1 + theta)^-N  (eq. 18). Equals 1 at a = b.
double PsiSigmaKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints,
                      double sigma);

/// k_pol(a, b) = (k_qdd + theta k_qdqd) k_psi_sigma^2 + k_psi_sigma - c_psi  (eq. 17).
/// When d_log_sigma is not null it receives d k_pol / d log sigma (forward mode, no division,
/// valid for every sigma >= 0).
double PolKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints, double sigma,
                 double* d_log_sigma = nullptr);

/// The gravity-free k~_pol(a, b) = (k_qdd + theta k_qdqd) k_psi_sigma^2  (eq. 55), with its
/// derivative with respect to log sigma as for PolKernel.
double PolKernelGravityFree(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints,
                            double sigma, double* d_log_sigma = nullptr);

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_POL_KERNEL_FORMULA_H_
