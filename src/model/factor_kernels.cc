#include "model/factor_kernels.h"

#include <cmath>

// GCC/Clang function multi-versioning: an AVX2+FMA clone and the baseline, dispatched once at
// load time. Disabled under sanitizers and on non-x86 targets.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__SANITIZE_ADDRESS__) && \
    !defined(__SANITIZE_THREAD__) && !defined(STRUCTGP_NO_TARGET_CLONES)
#define STRUCTGP_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define STRUCTGP_CLONES
#endif

namespace structgp {
namespace internal {

STRUCTGP_CLONES
void UpperTransposeTimes(const double* S, int ld, int D, const double* x, double* f) {
  for (int j = 0; j < D; ++j) {
    const double* col = S + static_cast<long>(j) * ld;
    double acc = 0.0;
#pragma omp simd reduction(+ : acc)
    for (int i = 0; i <= j; ++i) acc += col[i] * x[i];
    f[j] = acc;
  }
}

STRUCTGP_CLONES
void UpperTransposeTimes2(const double* S, int ld, int D, const double* x1, const double* x2,
                          double* f1, double* f2) {
  for (int j = 0; j < D; ++j) {
    const double* col = S + static_cast<long>(j) * ld;
    double acc1 = 0.0;
    double acc2 = 0.0;
#pragma omp simd reduction(+ : acc1, acc2)
    for (int i = 0; i <= j; ++i) {
      acc1 += col[i] * x1[i];
      acc2 += col[i] * x2[i];
    }
    f1[j] = acc1;
    f2[j] = acc2;
  }
}

// Derivation (docs/derivations.md): with alpha_0 = r, alpha_j = alpha_{j-1} + f_j^2,
//   I - f f^T / alpha_D = M M^T,  M upper triangular,
//   M_jj = sqrt(alpha_{j-1} / alpha_j),  M_ij = -f_i f_j / (alpha_j M_jj) (i < j),
// (for r > 0 the latter is -f_i f_j / sqrt(alpha_{j-1} alpha_j); writing it with alpha_j
// keeps it right for a removal, where every alpha_j is negative),
// so S' = scale * S M, column by column, with the running sum K = scale * S f.
STRUCTGP_CLONES
void CarlsonRankOne(double* S, int ld, int D, const double* f, double r, double scale,
                    double* gain) {
  double alpha_prev = r;
  for (int j = 0; j < D; ++j) {
    double* col = S + static_cast<long>(j) * ld;
    const double fj = f[j];
    const double alpha = alpha_prev + fj * fj;
    const double m_jj = std::sqrt(alpha_prev / alpha);
    const double a = m_jj * scale;
    const double b = fj / (alpha * m_jj);  // keeps the sign of r (removal: alpha < 0)
    const double c = fj * scale;
#pragma omp simd
    for (int i = 0; i < j; ++i) {
      const double u = col[i];
      col[i] = a * u - b * gain[i];
      gain[i] += c * u;
    }
    gain[j] = c * col[j];
    col[j] *= a;
    alpha_prev = alpha;
  }
}

}  // namespace internal
}  // namespace structgp
