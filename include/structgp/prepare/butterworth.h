#ifndef STRUCTGP_PREPARE_BUTTERWORTH_H_
#define STRUCTGP_PREPARE_BUTTERWORTH_H_

/// @file
/// A digital Butterworth low-pass filter and its zero-phase (forward-backward) application,
/// used to smooth logged joint positions before they are differentiated.
///
/// Design. The analog prototype of order n has its poles evenly spaced on the left half of the
/// circle of radius w_a = 2 f_s tan(pi f_c / f_s) (the cut-off pre-warped so that the digital
/// filter has its -3 dB point exactly at f_c); the bilinear transform s = 2 f_s (z - 1)/(z + 1)
/// maps them to the digital poles and puts all n zeros at z = -1. The filter is kept as a
/// cascade of second-order sections (one first-order section when n is odd), each scaled to a
/// DC gain of exactly 1, which stays accurate for cut-offs far below the sampling rate where a
/// single high-order polynomial would lose its poles to rounding.
///
/// Magnitude response (the design's closed form, used by the tests as the reference):
///     |H(e^{i w})|^2 = 1 / (1 + (tan(w / 2) / tan(w_c / 2))^{2n}),  w = 2 pi f / f_s.
/// The forward-backward application has the response |H|^2 and zero phase.

#include <vector>

#include "structgp/core/types.h"

namespace structgp {

/// Highest filter order accepted. Higher orders bring no benefit for smoothing robot logs and
/// only lengthen the edge transients.
inline constexpr int kMaxButterworthOrder = 8;

/// One second-order section in direct form II transposed:
///     y = b0 x + s1,  s1 <- b1 x - a1 y + s2,  s2 <- b2 x - a2 y
/// (a first-order section has b2 = a2 = 0).
struct BiquadSection {
  double b0 = 1.0, b1 = 0.0, b2 = 0.0;
  double a1 = 0.0, a2 = 0.0;
};

class ButterworthLowPass {
 public:
  /// A low-pass filter of the given order (1..kMaxButterworthOrder) with its -3 dB cut-off at
  /// cutoff_hz, for samples at sample_rate_hz. Requires 0 < cutoff_hz < sample_rate_hz / 2.
  /// Throws std::invalid_argument naming the bad value.
  ButterworthLowPass(int order, double cutoff_hz, double sample_rate_hz);

  int order() const { return order_; }
  double cutoff_hz() const { return cutoff_hz_; }
  double sample_rate_hz() const { return sample_rate_hz_; }
  /// The cascade, ceil(order / 2) sections, each of DC gain 1.
  const std::vector<BiquadSection>& sections() const { return sections_; }

  /// |H| of one (causal) pass at frequency f in Hz (0 <= f <= f_s / 2), evaluated from the
  /// sections' coefficients.
  double Magnitude(double frequency_hz) const;
  /// Phase of one causal pass at f [rad], from the sections' coefficients.
  double Phase(double frequency_hz) const;

  /// Number of samples of odd-reflection padding FiltFilt puts at each end of a signal of
  /// `length` samples: 3 x order, at least, and long enough for the filter's impulse
  /// response to decay (about 2 f_s / f_c samples), at most length - 1.
  int PaddingLength(Eigen::Index length) const;

  /// Causal filtering of x (one pass), starting from the steady state of a constant input
  /// x[0]. y may alias x.
  void Filter(const ConstVectorRef& x, Vector* y) const;

  /// Zero-phase filtering: x is extended at both ends by an odd reflection about its end
  /// points (x[-k] = 2 x[0] - x[k]), which continues value and slope and so keeps the edge
  /// transient small; filtered forward, then backward, each pass starting from the steady
  /// state of its first sample; and cut back to the original length. Needs at least 2
  /// samples (a shorter x is returned unchanged). y may alias x. O(length x order).
  void FiltFilt(const ConstVectorRef& x, Vector* y) const;

 private:
  int order_;
  double cutoff_hz_;
  double sample_rate_hz_;
  std::vector<BiquadSection> sections_;
};

}  // namespace structgp

#endif  // STRUCTGP_PREPARE_BUTTERWORTH_H_
