#ifndef STRUCTGP_SRC_MODEL_FACTOR_KERNELS_H_
#define STRUCTGP_SRC_MODEL_FACTOR_KERNELS_H_

// Hot loops over an upper-triangular factor S (column-major, leading dimension ld; only the
// upper triangle is read or written). Written as plain loops so that the compiler can build
// an AVX2/FMA clone next to the baseline one (chosen at load time), without imposing
// -march flags on anyone.

namespace structgp {
namespace internal {

// f = S^T x, one pass over S. O(D^2 / 2).
void UpperTransposeTimes(const double* S, int ld, int D, const double* x, double* f);

// f1 = S^T x1 and f2 = S^T x2 in one pass over S.
void UpperTransposeTimes2(const double* S, int ld, int D, const double* x1, const double* x2,
                          double* f1, double* f2);

// Carlson's triangular rank-one modification of a covariance square root, with a uniform
// scaling folded in. On entry S S^T = P and f = scale * S^T phi. On exit
//     S' S'^T = P_s - P_s phi phi^T P_s / alpha,   P_s = scale^2 P,   alpha = r + f^T f,
// and gain = P_s phi (so P' phi = gain / alpha). r > 0 adds an observation of variance r,
// r < 0 removes one of variance -r; the caller checks that alpha has the sign of r.
// One pass over S. O(D^2 / 2).
void CarlsonRankOne(double* S, int ld, int D, const double* f, double r, double scale,
                    double* gain);

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_SRC_MODEL_FACTOR_KERNELS_H_
