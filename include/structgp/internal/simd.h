#ifndef STRUCTGP_INTERNAL_SIMD_H_
#define STRUCTGP_INTERNAL_SIMD_H_

/// @file
/// The library's one set of SIMD helpers (not API): the macros and the four-lane vector type
/// of the hand-vectorised hot loops (model/factor_kernels.cc, model/kernel_gp.cc).
///
/// - STRUCTGP_TARGET_CLONES: GCC/Clang function multi-versioning. A function marked with it is
///   compiled twice, for x86-64-v3 (AVX2 + FMA) and for the baseline, and the clone is chosen
///   once at load time, so no -march flag is imposed on anyone. Empty outside x86-64 GCC/Clang,
///   under ASan/TSan, and when STRUCTGP_NO_TARGET_CLONES is defined.
/// - STRUCTGP_ALWAYS_INLINE: `inline` plus always_inline where the compiler has it; the
///   helpers of a cloned function must be inlined into each clone to get its instruction set.
/// - STRUCTGP_HAVE_PACKET4: defined (1) where the vector extensions below exist (GCC, Clang);
///   code without it must provide a scalar path.
/// - simd::Packet4: four doubles with the alignment of one double (loads from any address are
///   legal), one AVX register in the AVX2 clone, two SSE2 registers in the baseline.
///
/// Summation order is part of each routine's contract (bit-exact tests compare fused and
/// unfused paths), so the horizontal sums are named by their order and never reassociated:
/// SumPairs adds lanes (0 + 1) + (2 + 3), SumHalves adds (0 + 2) + (1 + 3).
///
/// A Packet4 passed by value to a function that is not inlined would change the calling
/// convention between clones; the helpers here are always inlined. A translation unit that
/// uses them is compiled with -Wno-psabi (src/CMakeLists.txt), which only silences GCC's note
/// about that convention.

#include <cstring>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__SANITIZE_ADDRESS__) && \
    !defined(__SANITIZE_THREAD__) && !defined(STRUCTGP_NO_TARGET_CLONES)
#define STRUCTGP_TARGET_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define STRUCTGP_TARGET_CLONES
#endif

#if defined(__GNUC__)
#define STRUCTGP_ALWAYS_INLINE inline __attribute__((always_inline))
#define STRUCTGP_HAVE_PACKET4 1
#else
#define STRUCTGP_ALWAYS_INLINE inline
#endif

#if defined(STRUCTGP_HAVE_PACKET4)
namespace structgp {
namespace internal {
namespace simd {

typedef double Packet4 __attribute__((vector_size(32), aligned(8)));

/// p[0..3] into a vector (p needs only double alignment).
STRUCTGP_ALWAYS_INLINE Packet4 Load4(const double* p) {
  Packet4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
/// v into p[0..3].
STRUCTGP_ALWAYS_INLINE void Store4(double* p, Packet4 v) { std::memcpy(p, &v, sizeof(v)); }
/// {x, x, x, x}.
STRUCTGP_ALWAYS_INLINE Packet4 Splat4(double x) { return Packet4{x, x, x, x}; }
/// (v[0] + v[1]) + (v[2] + v[3]).
STRUCTGP_ALWAYS_INLINE double SumPairs(Packet4 v) { return (v[0] + v[1]) + (v[2] + v[3]); }
/// (v[0] + v[2]) + (v[1] + v[3]).
STRUCTGP_ALWAYS_INLINE double SumHalves(Packet4 v) { return (v[0] + v[2]) + (v[1] + v[3]); }

}  // namespace simd
}  // namespace internal
}  // namespace structgp
#endif  // STRUCTGP_HAVE_PACKET4

#endif  // STRUCTGP_INTERNAL_SIMD_H_
