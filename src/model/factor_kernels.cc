#include "model/factor_kernels.h"

#include <cmath>

#include "structgp/internal/simd.h"

#ifndef STRUCTGP_CARLSON_BLOCK
#define STRUCTGP_CARLSON_BLOCK 2
#endif

namespace structgp {
namespace internal {
namespace {

// Plain loops with reductions do not vectorise well here (the reduction lanes end up in
// memory), so the four-lane arithmetic is written out with the helpers of internal/simd.h.
using simd::Load4;
using simd::Packet4;
using simd::Splat4;
using simd::Store4;
using simd::SumPairs;

// Four columns j0..j0+3 at once over rows [0, j0) (j0 is a multiple of 4): eight independent
// accumulators keep the FMA pipes busy, and x1, x2 are loaded once for four columns.
template <bool kTwo>
STRUCTGP_ALWAYS_INLINE void Project4(const double* S, int ld, int j0, const double* x1,
                                     const double* x2, double* y1, double* y2) {
  const double* c0 = S + static_cast<long>(j0) * ld;
  const double* c1 = c0 + ld;
  const double* c2 = c1 + ld;
  const double* c3 = c2 + ld;
  Packet4 p0 = Splat4(0), p1 = Splat4(0), p2 = Splat4(0), p3 = Splat4(0);
  Packet4 q0 = Splat4(0), q1 = Splat4(0), q2 = Splat4(0), q3 = Splat4(0);
  for (int i = 0; i < j0; i += 4) {
    const Packet4 a = Load4(x1 + i);
    const Packet4 u0 = Load4(c0 + i), u1 = Load4(c1 + i), u2 = Load4(c2 + i), u3 = Load4(c3 + i);
    p0 += u0 * a;
    p1 += u1 * a;
    p2 += u2 * a;
    p3 += u3 * a;
    if (kTwo) {
      const Packet4 b = Load4(x2 + i);
      q0 += u0 * b;
      q1 += u1 * b;
      q2 += u2 * b;
      q3 += u3 * b;
    }
  }
  y1[j0] = SumPairs(p0);
  y1[j0 + 1] = SumPairs(p1);
  y1[j0 + 2] = SumPairs(p2);
  y1[j0 + 3] = SumPairs(p3);
  if (kTwo) {
    y2[j0] = SumPairs(q0);
    y2[j0 + 1] = SumPairs(q1);
    y2[j0 + 2] = SumPairs(q2);
    y2[j0 + 3] = SumPairs(q3);
  }
}

// Adds the rows [row0, j] of column j to y1[j] (and y2[j]).
template <bool kTwo>
STRUCTGP_ALWAYS_INLINE void ProjectTail(const double* S, int ld, int row0, int j, const double* x1,
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
STRUCTGP_ALWAYS_INLINE void UpperTransposeTimesImpl(const double* S, int ld, int D,
                                                    const double* x1, const double* x2, double* y1,
                                                    double* y2) {
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
STRUCTGP_ALWAYS_INLINE void CarlsonColumn(double* S, int ld, int row0, int j, double a, double b,
                                          double c, double* gain, const double* x1,
                                          const double* x2, double* y1, double* y2) {
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

// Columns j0..j0+C-1 over rows [0, rows) (rows a multiple of 4), the running gain kept in a
// register across the C columns; with kProject, the new columns' dot products with x1 and x2
// over those rows go to y1, y2.
template <int C, bool kProject>
STRUCTGP_ALWAYS_INLINE void CarlsonBlock(double* S, int ld, int j0, int rows, const double* a,
                                         const double* b, const double* c, double* gain,
                                         const double* x1, const double* x2, double* y1,
                                         double* y2) {
  double* col[C];
  Packet4 va[C], vb[C], vk[C], p[C], q[C];
  for (int t = 0; t < C; ++t) {
    col[t] = S + static_cast<long>(j0 + t) * ld;
    va[t] = Splat4(a[j0 + t]);
    vb[t] = Splat4(b[j0 + t]);
    vk[t] = Splat4(c[j0 + t]);
    p[t] = q[t] = Splat4(0);
  }
  for (int i = 0; i < rows; i += 4) {
    Packet4 g = Load4(gain + i);
    Packet4 xa = Splat4(0), xb = Splat4(0);
    if (kProject) {
      xa = Load4(x1 + i);
      xb = Load4(x2 + i);
    }
    for (int t = 0; t < C; ++t) {
      const Packet4 u = Load4(col[t] + i);
      const Packet4 nu = va[t] * u - vb[t] * g;
      g += vk[t] * u;
      Store4(col[t] + i, nu);
      if (kProject) {
        p[t] += nu * xa;
        q[t] += nu * xb;
      }
    }
    Store4(gain + i, g);
  }
  if (kProject) {
    for (int t = 0; t < C; ++t) {
      y1[j0 + t] = SumPairs(p[t]);
      y2[j0 + t] = SumPairs(q[t]);
    }
  }
}

template <bool kProject>
STRUCTGP_ALWAYS_INLINE void CarlsonRankOneImpl(double* S, int ld, int D, const double* a,
                                               const double* b, const double* c, double* gain,
                                               const double* x1, const double* x2, double* y1,
                                               double* y2) {
  // Blocks of kBlock columns; the rows above a block that are a multiple of 4 go through the
  // vector loop, the few rows left and the block's own triangle column by column.
  constexpr int kBlock = STRUCTGP_CARLSON_BLOCK;
  int j0 = 0;
  for (; j0 + kBlock <= D; j0 += kBlock) {
    const int rows = j0 & ~3;
    CarlsonBlock<kBlock, kProject>(S, ld, j0, rows, a, b, c, gain, x1, x2, y1, y2);
    for (int t = 0; t < kBlock; ++t) {
      const int j = j0 + t;
      if (kProject && rows == 0) y1[j] = y2[j] = 0.0;
      CarlsonColumn<kProject>(S, ld, rows, j, a[j], b[j], c[j], gain, x1, x2, y1, y2);
    }
  }
  for (int j = j0; j < D; ++j) {
    if (kProject) y1[j] = y2[j] = 0.0;
    CarlsonColumn<kProject>(S, ld, 0, j, a[j], b[j], c[j], gain, x1, x2, y1, y2);
  }
}

// The coefficients of columns j0..j0+C-1 of the k modifications as four-lane broadcasts, in
// the order the block loop reads them: splat[((l C + t) 3 + {0, 1, 2}) 4 ..] = a, b, c.
template <int C>
STRUCTGP_ALWAYS_INLINE void SplatCoefficients(int j0, int k, const double* a, const double* b,
                                              const double* c, int ldc, double* splat) {
  for (int l = 0; l < k; ++l) {
    const long off = static_cast<long>(l) * ldc + j0;
    for (int t = 0; t < C; ++t) {
      double* q = splat + (static_cast<long>(l) * C + t) * 12;
      Store4(q, Splat4(a[off + t]));
      Store4(q + 4, Splat4(b[off + t]));
      Store4(q + 8, Splat4(c[off + t]));
    }
  }
}

// Columns j0..j0+C-1 of S over rows [i0, i0 + 4R) through the k modifications in order: the
// R row packets of the C columns stay in registers while every modification's running gain
// passes over them; the broadcast coefficients come from `splat` (SplatCoefficients).
template <int C, int R>
STRUCTGP_ALWAYS_INLINE void CarlsonTileK(double* const* col, int i0, int k, const double* splat,
                                         int ldc, double* gains) {
  Packet4 u[R][C];
  for (int r = 0; r < R; ++r) {
    for (int t = 0; t < C; ++t) u[r][t] = Load4(col[t] + i0 + 4 * r);
  }
  for (int l = 0; l < k; ++l) {
    double* gp = gains + static_cast<long>(l) * ldc + i0;
    Packet4 g[R];
    for (int r = 0; r < R; ++r) g[r] = Load4(gp + 4 * r);
    const double* q = splat + static_cast<long>(l) * C * 12;
    for (int t = 0; t < C; ++t) {
      const Packet4 va = Load4(q + 12 * t), vb = Load4(q + 12 * t + 4),
                    vc = Load4(q + 12 * t + 8);
      for (int r = 0; r < R; ++r) {
        const Packet4 nu = va * u[r][t] - vb * g[r];
        g[r] += vc * u[r][t];
        u[r][t] = nu;
      }
    }
    for (int r = 0; r < R; ++r) Store4(gp + 4 * r, g[r]);
  }
  for (int r = 0; r < R; ++r) {
    for (int t = 0; t < C; ++t) Store4(col[t] + i0 + 4 * r, u[r][t]);
  }
}

// Columns j0..j0+C-1 of S over rows [0, rows) (a multiple of 4), eight rows at a time.
template <int C>
STRUCTGP_ALWAYS_INLINE void CarlsonBlockK(double* S, int ld, int j0, int rows, int k,
                                          const double* a, const double* b, const double* c,
                                          int ldc, double* gains, double* splat) {
  if (rows == 0) return;
  double* col[C];
  for (int t = 0; t < C; ++t) col[t] = S + static_cast<long>(j0 + t) * ld;
  SplatCoefficients<C>(j0, k, a, b, c, ldc, splat);
  int i = 0;
  for (; i + 8 <= rows; i += 8) CarlsonTileK<C, 2>(col, i, k, splat, ldc, gains);
  if (i < rows) CarlsonTileK<C, 1>(col, i, k, splat, ldc, gains);
}

// Column j over rows [row0, j) and its diagonal, through the k modifications in order.
STRUCTGP_ALWAYS_INLINE void CarlsonColumnK(double* S, int ld, int row0, int j, int k,
                                           const double* a, const double* b, const double* c,
                                           int ldc, double* gains) {
  double* col = S + static_cast<long>(j) * ld;
  for (int i = row0; i < j; ++i) {
    double u = col[i];
    for (int l = 0; l < k; ++l) {
      const long off = static_cast<long>(l) * ldc;
      double& g = gains[off + i];
      const double nu = a[off + j] * u - b[off + j] * g;
      g += c[off + j] * u;
      u = nu;
    }
    col[i] = u;
  }
  double u = col[j];
  for (int l = 0; l < k; ++l) {
    const long off = static_cast<long>(l) * ldc;
    gains[off + j] = c[off + j] * u;
    u *= a[off + j];
  }
  col[j] = u;
}

}  // namespace

STRUCTGP_TARGET_CLONES
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

STRUCTGP_TARGET_CLONES
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

namespace structgp {
namespace internal {

STRUCTGP_TARGET_CLONES
void UpperTransposeTimesMany(const double* S, int ld, int D, int k, const double* X, int ldx,
                             double* Y, int ldy) {
  // Column blocks of four outside, right-hand sides (in pairs) inside: the four columns of S
  // are read from memory once and then from cache for every pair.
  int j0 = 0;
  for (; j0 + 4 <= D; j0 += 4) {
    int r = 0;
    for (; r + 2 <= k; r += 2) {
      const double* x1 = X + static_cast<long>(r) * ldx;
      const double* x2 = x1 + ldx;
      double* y1 = Y + static_cast<long>(r) * ldy;
      double* y2 = y1 + ldy;
      Project4<true>(S, ld, j0, x1, x2, y1, y2);
      for (int t = 0; t < 4; ++t) ProjectTail<true>(S, ld, j0, j0 + t, x1, x2, y1, y2);
    }
    for (; r < k; ++r) {
      const double* x1 = X + static_cast<long>(r) * ldx;
      double* y1 = Y + static_cast<long>(r) * ldy;
      Project4<false>(S, ld, j0, x1, nullptr, y1, nullptr);
      for (int t = 0; t < 4; ++t) ProjectTail<false>(S, ld, j0, j0 + t, x1, nullptr, y1, nullptr);
    }
  }
  for (int j = j0; j < D; ++j) {
    for (int r = 0; r < k; ++r) {
      const double* x1 = X + static_cast<long>(r) * ldx;
      double* y1 = Y + static_cast<long>(r) * ldy;
      y1[j] = 0.0;
      ProjectTail<false>(S, ld, 0, j, x1, nullptr, y1, nullptr);
    }
  }
}

STRUCTGP_TARGET_CLONES
void CarlsonRankK(double* S, int ld, int D, int k, const double* a, const double* b,
                  const double* c, int ldc, double* gains, double* splat) {
  constexpr int kBlock = 4;
  int j0 = 0;
  for (; j0 + kBlock <= D; j0 += kBlock) {
    // j0 is a multiple of 4: the rows above the block go through the vector loop.
    CarlsonBlockK<kBlock>(S, ld, j0, j0, k, a, b, c, ldc, gains, splat);
    for (int t = 0; t < kBlock; ++t) CarlsonColumnK(S, ld, j0, j0 + t, k, a, b, c, ldc, gains);
  }
  for (int j = j0; j < D; ++j) {
    const int rows = j0;
    CarlsonBlockK<1>(S, ld, j, rows, k, a, b, c, ldc, gains, splat);
    CarlsonColumnK(S, ld, rows, j, k, a, b, c, ldc, gains);
  }
}

// (S_l^T x)_j = a_j z_j - b_j sum_{i<j} c_i z_i with z = S_{l-1}^T x (see CarlsonCoefficients).
void CarlsonTransposeApply(const double* a, const double* b, const double* c, int D, double* z) {
  double prefix = 0.0;
  for (int j = 0; j < D; ++j) {
    const double zj = z[j];
    z[j] = a[j] * zj - b[j] * prefix;
    prefix += c[j] * zj;
  }
}

}  // namespace internal
}  // namespace structgp
