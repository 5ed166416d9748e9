#ifndef STRUCTGP_SRC_FEATURE_TRIG_TENSOR_H_
#define STRUCTGP_SRC_FEATURE_TRIG_TENSOR_H_

// Private helpers of the trigonometric tensor-product maps (pol, gravity basis): the per-joint
// factors u(q) and v(q) of docs/feature_maps.md and in-place tensor expansion of a buffer.
//
// Index convention: a multi-index (i_1, ..., i_N) with i_n in {0..K-1} is stored at
// sum_n i_n K^(N-n), i.e. joint 1 is the most significant digit. Index 0 is the all-zero
// multi-index (the constant product).

#include <cmath>

namespace structgp {
namespace internal {

/// Number of per-joint factors of u(q) = (1, cos q, sin q).
inline constexpr int kNumU = 3;
/// Number of per-joint factors of v(q) = (1, cos q, sin q, cos 2q, sin 2q).
inline constexpr int kNumV = 5;

/// K^n for small non-negative n.
inline constexpr int IntPow(int k, int n) { return n == 0 ? 1 : k * IntPow(k, n - 1); }

/// u(q) = (1, cos q, sin q).
inline void TrigU(double q, double* u) {
  u[0] = 1.0;
  u[1] = std::cos(q);
  u[2] = std::sin(q);
}

/// v(q) = (1, cos q, sin q, cos 2q, sin 2q), the double angle from the single one.
inline void TrigV(double q, double* v) {
  const double c = std::cos(q);
  const double s = std::sin(q);
  v[0] = 1.0;
  v[1] = c;
  v[2] = s;
  v[3] = (c - s) * (c + s);
  v[4] = 2.0 * s * c;
}

/// Combines two factors: Op()(old, factor).
struct Multiply {
  double operator()(double a, double b) const { return a * b; }
};
struct Add {
  double operator()(double a, double b) const { return a + b; }
};

/// In place: buf[i * K + j] = op(buf[i], f[j]) for i < size, j < K. buf must hold size * K
/// entries. Returns size * K. Walking i downwards never overwrites an entry not yet read.
template <int K, typename Op>
inline int Expand(double* buf, int size, const double* f, Op op) {
  for (int i = size - 1; i >= 0; --i) {
    const double t = buf[i];
    double* out = buf + i * K;
    for (int j = K - 1; j >= 0; --j) out[j] = op(t, f[j]);
  }
  return size * K;
}

/// As Expand but drops the entry (i, j) = (0, 0): buf[i * K + j - 1] = op(buf[i], f[j]).
/// buf must hold size * K - 1 entries (size >= 1). Returns size * K - 1.
template <int K, typename Op>
inline int ExpandDropFirst(double* buf, int size, const double* f, Op op) {
  for (int i = size - 1; i >= 1; --i) {
    const double t = buf[i];
    double* out = buf + i * K - 1;
    for (int j = K - 1; j >= 0; --j) out[j] = op(t, f[j]);
  }
  const double t = buf[0];
  for (int j = K - 1; j >= 1; --j) buf[j - 1] = op(t, f[j]);
  return size * K - 1;
}

/// Writes the tensor product over `num_joints` joints of per-joint factor rows
/// factors[n * K .. n * K + K) into buf, starting from `identity` (1 for products, 0 for
/// sums). When drop_first, the all-zero multi-index is left out and buf holds K^N - 1 entries;
/// otherwise K^N. Returns the number written.
template <int K, typename Op>
inline int TensorProduct(int num_joints, const double* factors, double identity, bool drop_first,
                         Op op, double* buf) {
  buf[0] = identity;
  int size = 1;
  for (int n = 0; n < num_joints; ++n) {
    const bool last = n + 1 == num_joints;
    if (last && drop_first) {
      size = ExpandDropFirst<K>(buf, size, factors + n * K, op);
    } else {
      size = Expand<K>(buf, size, factors + n * K, op);
    }
  }
  return size;
}

/// The sigma-dependent constants of k_psi_sigma (eq. 18) and their derivatives with respect
/// to log sigma (written d/dl below).
struct PolShape {
  double theta;            // 1 / (1 + sigma)
  double one_minus_theta;  // sigma / (1 + sigma), computed without cancellation
  double c_psi;            // (1 + theta)^-N
  double dlog_c_psi;       // d log c_psi / dl = N theta (1 - theta) / (1 + theta)
  /// d log theta / dl = -(1 - theta).
  double dlog_theta() const { return -one_minus_theta; }
};

inline PolShape MakePolShapeFromSigma(double sigma, int num_joints) {
  PolShape s;
  s.theta = 1.0 / (1.0 + sigma);
  s.one_minus_theta = 1.0 / (1.0 + 1.0 / sigma);  // exact limits at sigma = 0 and sigma = inf
  s.c_psi = std::pow(1.0 + s.theta, -num_joints);
  s.dlog_c_psi = num_joints * s.theta * s.one_minus_theta / (1.0 + s.theta);
  return s;
}

inline PolShape MakePolShape(double log_sigma, int num_joints) {
  return MakePolShapeFromSigma(std::exp(log_sigma), num_joints);
}

/// Per-joint prior weights of u: (1, theta, theta), and their d log / dl.
inline void WeightsU(const PolShape& s, double* w, double* dlog_w) {
  w[0] = 1.0;
  w[1] = w[2] = s.theta;
  dlog_w[0] = 0.0;
  dlog_w[1] = dlog_w[2] = -s.one_minus_theta;
}

/// Per-joint prior weights of v: (1 + theta^2/2, 2 theta, 2 theta, theta^2/2, theta^2/2),
/// from (1 + theta cos d)^2 = 1 + theta^2/2 + 2 theta cos d + (theta^2/2) cos 2d, and their
/// d log / dl (d theta / dl = -theta (1 - theta)).
inline void WeightsV(const PolShape& s, double* w, double* dlog_w) {
  const double half_theta2 = 0.5 * s.theta * s.theta;
  w[0] = 1.0 + half_theta2;
  w[1] = w[2] = 2.0 * s.theta;
  w[3] = w[4] = half_theta2;
  dlog_w[0] = -2.0 * half_theta2 * s.one_minus_theta / w[0];
  dlog_w[1] = dlog_w[2] = -s.one_minus_theta;
  dlog_w[3] = dlog_w[4] = -2.0 * s.one_minus_theta;
}

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_SRC_FEATURE_TRIG_TENSOR_H_
