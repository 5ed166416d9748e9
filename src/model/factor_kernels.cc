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
#define STRUCTGP_INLINE inline __attribute__((always_inline))

namespace structgp {
namespace internal {
namespace {

// Four columns j0..j0+3 at once over rows [0, j0): eight independent dot products keep the
// FMA pipes busy, and x1, x2 are loaded once for four columns.
template <bool kTwo>
STRUCTGP_INLINE void Project4(const double* S, int ld, int j0, const double* x1,
                              const double* x2, double* y1, double* y2) {
  const double* c0 = S + static_cast<long>(j0) * ld;
  const double* c1 = c0 + ld;
  const double* c2 = c1 + ld;
  const double* c3 = c2 + ld;
  double p0 = 0, p1 = 0, p2 = 0, p3 = 0, q0 = 0, q1 = 0, q2 = 0, q3 = 0;
#pragma omp simd reduction(+ : p0, p1, p2, p3, q0, q1, q2, q3)
  for (int i = 0; i < j0; ++i) {
    p0 += c0[i] * x1[i];
    p1 += c1[i] * x1[i];
    p2 += c2[i] * x1[i];
    p3 += c3[i] * x1[i];
    if (kTwo) {
      q0 += c0[i] * x2[i];
      q1 += c1[i] * x2[i];
      q2 += c2[i] * x2[i];
      q3 += c3[i] * x2[i];
    }
  }
  y1[j0] = p0;
  y1[j0 + 1] = p1;
  y1[j0 + 2] = p2;
  y1[j0 + 3] = p3;
  if (kTwo) {
    y2[j0] = q0;
    y2[j0 + 1] = q1;
    y2[j0 + 2] = q2;
    y2[j0 + 3] = q3;
  }
}

// Adds the rows [row0, j] of column j to y1[j] (and y2[j]).
template <bool kTwo>
STRUCTGP_INLINE void ProjectTail(const double* S, int ld, int row0, int j, const double* x1,
                                 const double* x2, double* y1, double* y2) {
  const double* col = S + static_cast<long>(j) * ld;
  double p = 0, q = 0;
  for (int i = row0; i <= j; ++i) {
    p += col[i] * x1[i];
    if (kTwo) q += col[i] * x2[i];
  }
  y1[j] += p;
  if (kTwo) y2[j] += q;
}

template <bool kTwo>
STRUCTGP_INLINE void UpperTransposeTimesImpl(const double* S, int ld, int D, const double* x1,
                                             const double* x2, double* y1, double* y2) {
  int j0 = 0;
  for (; j0 + 4 <= D; j0 += 4) {
    Project4<kTwo>(S, ld, j0, x1, x2, y1, y2);
    for (int t = 0; t < 4; ++t) ProjectTail<kTwo>(S, ld, j0, j0 + t, x1, x2, y1, y2);
  }
  for (int j = j0; j < D; ++j) {
    y1[j] = 0.0;
    if (kTwo) y2[j] = 0.0;
    ProjectTail<kTwo>(S, ld, 0, j, x1, x2, y1, y2);
  }
}

// Carlson's update of column j over rows [row0, j), then its diagonal; optionally the dot
// products of the new column with x1, x2 over rows [row0, j] are added to y1[j], y2[j].
template <bool kProject>
STRUCTGP_INLINE void CarlsonColumn(double* S, int ld, int row0, int j, double a, double b,
                                   double c, double* gain, const double* x1, const double* x2,
                                   double* y1, double* y2) {
  double* col = S + static_cast<long>(j) * ld;
  double p = 0, q = 0;
  for (int i = row0; i < j; ++i) {
    const double u = col[i];
    const double nu = a * u - b * gain[i];
    gain[i] += c * u;
    col[i] = nu;
    if (kProject) {
      p += nu * x1[i];
      q += nu * x2[i];
    }
  }
  gain[j] = c * col[j];
  col[j] *= a;
  if (kProject) {
    y1[j] += p + col[j] * x1[j];
    y2[j] += q + col[j] * x2[j];
  }
}

template <bool kProject>
STRUCTGP_INLINE void CarlsonRankOneImpl(double* S, int ld, int D, const double* a,
                                        const double* b, const double* c, double* gain,
                                        const double* x1, const double* x2, double* y1,
                                        double* y2) {
  int j0 = 0;
  for (; j0 + 4 <= D; j0 += 4) {
    double* c0 = S + static_cast<long>(j0) * ld;
    double* c1 = c0 + ld;
    double* c2 = c1 + ld;
    double* c3 = c2 + ld;
    const double a0 = a[j0], a1 = a[j0 + 1], a2 = a[j0 + 2], a3 = a[j0 + 3];
    const double b0 = b[j0], b1 = b[j0 + 1], b2 = b[j0 + 2], b3 = b[j0 + 3];
    const double k0 = c[j0], k1 = c[j0 + 1], k2 = c[j0 + 2], k3 = c[j0 + 3];
    double p0 = 0, p1 = 0, p2 = 0, p3 = 0, q0 = 0, q1 = 0, q2 = 0, q3 = 0;
    // Rows above the block: the four columns in turn, the running gain kept in a register.
#pragma omp simd reduction(+ : p0, p1, p2, p3, q0, q1, q2, q3)
    for (int i = 0; i < j0; ++i) {
      double g = gain[i];
      double u = c0[i];
      double nu = a0 * u - b0 * g;
      g += k0 * u;
      c0[i] = nu;
      if (kProject) {
        p0 += nu * x1[i];
        q0 += nu * x2[i];
      }
      u = c1[i];
      nu = a1 * u - b1 * g;
      g += k1 * u;
      c1[i] = nu;
      if (kProject) {
        p1 += nu * x1[i];
        q1 += nu * x2[i];
      }
      u = c2[i];
      nu = a2 * u - b2 * g;
      g += k2 * u;
      c2[i] = nu;
      if (kProject) {
        p2 += nu * x1[i];
        q2 += nu * x2[i];
      }
      u = c3[i];
      nu = a3 * u - b3 * g;
      g += k3 * u;
      c3[i] = nu;
      if (kProject) {
        p3 += nu * x1[i];
        q3 += nu * x2[i];
      }
      gain[i] = g;
    }
    if (kProject) {
      y1[j0] = p0, y1[j0 + 1] = p1, y1[j0 + 2] = p2, y1[j0 + 3] = p3;
      y2[j0] = q0, y2[j0 + 1] = q1, y2[j0 + 2] = q2, y2[j0 + 3] = q3;
    }
    // The 4 x 4 corner, column by column (each column starts its row's gain).
    for (int t = 0; t < 4; ++t) {
      const int j = j0 + t;
      CarlsonColumn<kProject>(S, ld, j0, j, a[j], b[j], c[j], gain, x1, x2, y1, y2);
    }
  }
  for (int j = j0; j < D; ++j) {
    if (kProject) y1[j] = y2[j] = 0.0;
    CarlsonColumn<kProject>(S, ld, 0, j, a[j], b[j], c[j], gain, x1, x2, y1, y2);
  }
}

}  // namespace

STRUCTGP_CLONES
void UpperTransposeTimes(const double* S, int ld, int D, const double* x1, const double* x2,
                         double* y1, double* y2) {
  if (x2 == nullptr) {
    UpperTransposeTimesImpl<false>(S, ld, D, x1, nullptr, y1, nullptr);
  } else {
    UpperTransposeTimesImpl<true>(S, ld, D, x1, x2, y1, y2);
  }
}

// Derivation (docs/derivations.md): with alpha_0 = r, alpha_j = alpha_{j-1} + f_j^2,
//   I - f f^T / alpha_D = M M^T,  M upper triangular,
//   M_jj = sqrt(alpha_{j-1} / alpha_j),  M_ij = -f_i f_j / (alpha_j M_jj) (i < j)
// (for r > 0 the latter is -f_i f_j / sqrt(alpha_{j-1} alpha_j); written with alpha_j it
// stays right for a removal, where every alpha_j is negative). Then S' = scale * S M, built
// column by column with the running sum gain = scale * S f:
//   S'_ij = a_j S_ij - b_j gain_i,  gain_i += c_j S_ij,
//   a_j = scale M_jj,  b_j = f_j / (alpha_j M_jj),  c_j = scale f_j.
void CarlsonCoefficients(const double* f, int D, double r, double scale, double* a, double* b,
                         double* c) {
  double alpha_prev = r;
  for (int j = 0; j < D; ++j) {
    const double fj = f[j];
    const double alpha = alpha_prev + fj * fj;
    const double m_jj = std::sqrt(alpha_prev / alpha);
    a[j] = m_jj * scale;
    b[j] = fj / (alpha * m_jj);
    c[j] = fj * scale;
    alpha_prev = alpha;
  }
}

STRUCTGP_CLONES
void CarlsonRankOne(double* S, int ld, int D, const double* a, const double* b, const double* c,
                    double* gain, const double* x1, const double* x2, double* y1, double* y2) {
  if (x1 == nullptr) {
    CarlsonRankOneImpl<false>(S, ld, D, a, b, c, gain, nullptr, nullptr, nullptr, nullptr);
  } else {
    CarlsonRankOneImpl<true>(S, ld, D, a, b, c, gain, x1, x2, y1, y2);
  }
}

}  // namespace internal
}  // namespace structgp
