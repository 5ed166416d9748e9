#include "structgp/prepare/butterworth.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>

namespace structgp {
namespace {

using Complex = std::complex<double>;

// Minimum padding per unit of filter order [samples] (the classic 3 x filter length).
constexpr int kPaddingPerOrder = 3;
// Padding in units of f_s / f_c: the impulse response of a Butterworth low-pass of order <= 8
// has decayed to well under 1% after two periods of the cut-off frequency.
constexpr double kPaddingCutoffPeriods = 2.0;

// Response of one section at z^-1 = e^{-i w}.
Complex SectionResponse(const BiquadSection& s, double w) {
  const Complex z1 = std::polar(1.0, -w);
  const Complex z2 = z1 * z1;
  return (s.b0 + s.b1 * z1 + s.b2 * z2) / (1.0 + s.a1 * z1 + s.a2 * z2);
}

// Runs the cascade over x[0..n) in place, forward, from the steady state of x[0].
void RunCascade(const std::vector<BiquadSection>& sections, double* x, Eigen::Index n) {
  if (n == 0) return;
  for (const BiquadSection& s : sections) {
    // Steady state of a constant input c = x[0] (each section has DC gain 1, so its output is
    // c too): s2 = (b2 - a2) c, s1 = (b1 - a1) c + s2.
    const double c = x[0];
    double s2 = (s.b2 - s.a2) * c;
    double s1 = (s.b1 - s.a1) * c + s2;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double in = x[i];
      const double out = s.b0 * in + s1;
      s1 = s.b1 * in - s.a1 * out + s2;
      s2 = s.b2 * in - s.a2 * out;
      x[i] = out;
    }
  }
}

}  // namespace

ButterworthLowPass::ButterworthLowPass(int order, double cutoff_hz, double sample_rate_hz)
    : order_(order), cutoff_hz_(cutoff_hz), sample_rate_hz_(sample_rate_hz) {
  if (order < 1 || order > kMaxButterworthOrder) {
    throw std::invalid_argument("ButterworthLowPass: order: expected 1.." +
                                std::to_string(kMaxButterworthOrder) + ", got " +
                                std::to_string(order));
  }
  if (!(sample_rate_hz > 0.0) || !std::isfinite(sample_rate_hz)) {
    throw std::invalid_argument(
        "ButterworthLowPass: sample rate: expected a positive rate in Hz, "
        "got " +
        std::to_string(sample_rate_hz));
  }
  if (!(cutoff_hz > 0.0) || !(cutoff_hz < 0.5 * sample_rate_hz)) {
    throw std::invalid_argument(
        "ButterworthLowPass: cut-off: expected 0 < cut-off < half the sample rate (" +
        std::to_string(0.5 * sample_rate_hz) + " Hz), got " + std::to_string(cutoff_hz) + " Hz");
  }
  const double fs2 = 2.0 * sample_rate_hz;
  // Pre-warped analog cut-off [rad/s].
  const double wa = fs2 * std::tan(M_PI * cutoff_hz / sample_rate_hz);
  // Poles k = 1..n of the analog prototype: wa exp(i pi (2k + n - 1) / (2n)); k and n + 1 - k
  // are conjugate, k = (n + 1) / 2 is real (-wa) when n is odd. One section per pair.
  for (int k = 1; 2 * k <= order; ++k) {
    const Complex pa = std::polar(wa, M_PI * (2.0 * k + order - 1.0) / (2.0 * order));
    const Complex pd = (1.0 + pa / fs2) / (1.0 - pa / fs2);  // bilinear transform
    BiquadSection s;
    s.a1 = -2.0 * pd.real();
    s.a2 = std::norm(pd);
    const double g = (1.0 + s.a1 + s.a2) / 4.0;  // zeros (1 + z^-1)^2, DC gain 1
    s.b0 = g;
    s.b1 = 2.0 * g;
    s.b2 = g;
    sections_.push_back(s);
  }
  if (order % 2 == 1) {
    const double pd = (1.0 - wa / fs2) / (1.0 + wa / fs2);
    BiquadSection s;
    s.a1 = -pd;
    const double g = (1.0 + s.a1) / 2.0;  // zero at z = -1, DC gain 1
    s.b0 = g;
    s.b1 = g;
    sections_.push_back(s);
  }
}

double ButterworthLowPass::Magnitude(double frequency_hz) const {
  const double w = 2.0 * M_PI * frequency_hz / sample_rate_hz_;
  double magnitude = 1.0;
  for (const auto& s : sections_) magnitude *= std::abs(SectionResponse(s, w));
  return magnitude;
}

double ButterworthLowPass::Phase(double frequency_hz) const {
  const double w = 2.0 * M_PI * frequency_hz / sample_rate_hz_;
  Complex h = 1.0;
  for (const auto& s : sections_) h *= SectionResponse(s, w);
  return std::arg(h);
}

int ButterworthLowPass::PaddingLength(Eigen::Index length) const {
  const double periods = kPaddingCutoffPeriods * sample_rate_hz_ / cutoff_hz_;
  const Eigen::Index wanted = std::max<Eigen::Index>(kPaddingPerOrder * order_,
                                                     static_cast<Eigen::Index>(std::ceil(periods)));
  return static_cast<int>(std::max<Eigen::Index>(0, std::min(wanted, length - 1)));
}

void ButterworthLowPass::Filter(const ConstVectorRef& x, Vector* y) const {
  Vector out = x;
  RunCascade(sections_, out.data(), out.size());
  *y = std::move(out);
}

void ButterworthLowPass::FiltFilt(const ConstVectorRef& x, Vector* y) const {
  const Eigen::Index n = x.size();
  if (n < 2) {
    *y = x;
    return;
  }
  const Eigen::Index pad = PaddingLength(n);
  Vector ext(n + 2 * pad);
  // Odd reflection about each end point: x[-k] = 2 x[0] - x[k], x[n-1+k] = 2 x[n-1] - x[n-1-k].
  for (Eigen::Index k = 1; k <= pad; ++k) {
    ext[pad - k] = 2.0 * x[0] - x[k];
    ext[pad + n - 1 + k] = 2.0 * x[n - 1] - x[n - 1 - k];
  }
  ext.segment(pad, n) = x;
  RunCascade(sections_, ext.data(), ext.size());
  ext.reverseInPlace();
  RunCascade(sections_, ext.data(), ext.size());
  ext.reverseInPlace();
  *y = ext.segment(pad, n);
}

}  // namespace structgp
