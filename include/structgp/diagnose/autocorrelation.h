#ifndef STRUCTGP_DIAGNOSE_AUTOCORRELATION_H_
#define STRUCTGP_DIAGNOSE_AUTOCORRELATION_H_

/// @file
/// Autocorrelation of residuals along a log, and what it does to a test that takes every row
/// for an independent sample.
///
/// Residuals of a 100 Hz - 1 kHz log are strongly autocorrelated: an AR(1) residual with
/// phi = 0.99 holds about m / 199 independent samples. A test of whether a candidate column e
/// explains a residual r (the evidence gain of the diagnosis, a cross-correlation at heart)
/// then overstates its statistic by Bartlett's factor
///
///     c = 1 + 2 sum_{k >= 1} rho_r(k) rho_e(k)
///
/// (the variance of the sample cross-correlation of two independent stationary series is
/// c / m instead of 1 / m; Bartlett 1935, used in Ljung-Box-type cross-correlation tests).
/// The diagnosis divides its chi-square statistic by c; m / c is the effective sample size.

#include <vector>

#include "structgp/core/types.h"

namespace structgp {

/// Sample autocorrelation rho(0..max_lag) of x (centred first; rho(0) = 1), each lag's products
/// taken within segments (segment_starts as SegmentStarts gives them: a lag never spans a
/// trajectory restart). All zeros beyond rho(0) for a constant x.
Vector Autocorrelation(const ConstVectorRef& x, const std::vector<int>& segment_starts,
                       int max_lag);

/// Bartlett's inflation factor c >= 1 of the white-noise test of candidate e against residual r
/// (same size m). The sum runs over the lags at which the residual's autocorrelation is
/// distinguishable from zero (|rho_r(k)| >= 2 / sqrt(m), up to min(m / 4, 2000)): a white
/// residual gives c = 1 whatever the candidate. Never below 1.
double BartlettInflation(const ConstVectorRef& r, const ConstVectorRef& e,
                         const std::vector<int>& segment_starts);

/// First lag at which the mean autocorrelation of the columns of R falls below level (at most
/// min(m / 4, 2000)): how many rows apart two residuals must be to count as unrelated.
int CorrelationLength(const ConstMatrixRef& R, const std::vector<int>& segment_starts,
                      double level);

}  // namespace structgp

#endif  // STRUCTGP_DIAGNOSE_AUTOCORRELATION_H_
