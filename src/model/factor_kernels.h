#ifndef STRUCTGP_SRC_MODEL_FACTOR_KERNELS_H_
#define STRUCTGP_SRC_MODEL_FACTOR_KERNELS_H_

// Hot loops over an upper-triangular factor S (column-major, leading dimension ld; only the
// upper triangle is read or written). Written as plain loops, four columns at a time, so that
// the compiler builds an AVX2/FMA clone next to the baseline one (chosen at load time) without
// imposing -march flags on anyone. Each function makes exactly one pass over S.

namespace structgp {
namespace internal {

// y1 = S^T x1 and, when x2 is not null, y2 = S^T x2. O(D^2 / 2), reads S once.
void UpperTransposeTimes(const double* S, int ld, int D, const double* x1, const double* x2,
                         double* y1, double* y2);

// Coefficients of Carlson's triangular rank-one modification (see factor_kernels.cc) for
// f = scale * S^T phi and observation variance r (r < 0 removes an observation); a, b, c are
// arrays of size D.
void CarlsonCoefficients(const double* f, int D, double r, double scale, double* a, double* b,
                         double* c);

// Applies the modification: on exit S' S'^T = P_s - P_s phi phi^T P_s / alpha with
// P_s = scale^2 S S^T and alpha = r + f^T f, and gain = P_s phi. When x1 is not null it also
// returns y1 = S'^T x1 and y2 = S'^T x2 (x2 may equal x1), in the same pass.
void CarlsonRankOne(double* S, int ld, int D, const double* a, const double* b, const double* c,
                    double* gain, const double* x1, const double* x2, double* y1, double* y2);

// Y = S^T X for k right-hand sides (X: D x k, leading dimension ldx; Y: D x k, ldy), one pass
// over S (the columns of a block of S are reused for every right-hand side while in cache).
// Each column of Y has exactly the summation order of UpperTransposeTimes.
void UpperTransposeTimesMany(const double* S, int ld, int D, int k, const double* X, int ldx,
                             double* Y, int ldy);

// Applies k Carlson modifications in sequence in one pass over S: S <- S M_1 M_2 ... M_k
// (scales included), where modification l has the coefficients a + l ldc, b + l ldc,
// c + l ldc (CarlsonCoefficients of f_l = scale_l S_{l-1}^T phi_l). On exit gains + l ldc
// holds gain_l = scale_l S_{l-1} f_l (P_s phi_l of modification l). Tiles of four columns
// by eight rows are carried through all k modifications while in registers: O(k D^2 / 2)
// arithmetic, S read and written once. splat: scratch of kCarlsonSplatPerStep * k doubles.
inline constexpr int kCarlsonSplatPerStep = 48;
void CarlsonRankK(double* S, int ld, int D, int k, const double* a, const double* b,
                  const double* c, int ldc, double* gains, double* splat);

// z <- scale_l M_l^T z for the modification with coefficients a, b, c (size D): the projection
// S_l^T x from S_{l-1}^T x, O(D).
void CarlsonTransposeApply(const double* a, const double* b, const double* c, int D, double* z);

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_SRC_MODEL_FACTOR_KERNELS_H_
