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

/// An autoregressive model of a centred series, x_t = sum_{k=1..p} phi_k x_{t-k} + u_t, fitted
/// by the Yule-Walker equations (Levinson-Durbin on the autocorrelation within segments) with
/// the order p in 0..max_order of least AIC, m log(Var u / Var x) + 2 p.
struct Autoregression {
  /// phi_1..phi_p; empty for a white series (p = 0).
  Vector phi;
  /// Var(u) / Var(x) of the Yule-Walker fit (1 for p = 0).
  double innovation_variance_ratio = 1.0;
};
Autoregression FitAutoregression(const ConstVectorRef& x, const std::vector<int>& segment_starts,
                                 int max_order);

/// The filtered series u_t = x_t - sum_k phi_k x_{t-k} of every column, within segments: the
/// first p rows of each segment (whose lags would span the restart) are left out. x is not
/// centred (a constant column becomes (1 - sum phi) times itself). Rows: m minus p per segment
/// longer than p.
Matrix Prewhiten(const ConstMatrixRef& x, const Vector& phi, const std::vector<int>& segment_starts);

/// The factor c >= 1 by which a test of candidate columns E against a residual overstates its
/// statistic, measured by prewhitening instead of Bartlett's formula: the white-noise
/// statistic (the projection of r_before on E, over the variance of r_after) divided by the
/// same statistic after filtering r_before and E with an AR model fitted to r_after (the
/// residual with the candidate in the model, so the filter describes the noise and not the
/// effect), over the variance of its innovations, times Bartlett's factor of the filtered
/// residual against the filtered columns (what the AR model leaves correlated: a wander slower
/// than its order reaches; 1 when it whitens the residual). Under noise that the AR model describes the
/// prewhitened statistic is chi-square with E.cols() degrees of freedom; the test then keeps
/// the power of a candidate whose shape the noise does not share (a step against a slow
/// wander), where Bartlett's factor, which only sees the two autocorrelations, deflates it as
/// much as a slow one. A white r_after (p = 0) gives exactly 1. max_order: see
/// FitAutoregression.
double PrewhiteningInflation(const ConstVectorRef& r_before, const ConstVectorRef& r_after,
                             const ConstMatrixRef& E, const std::vector<int>& segment_starts,
                             int max_order = 20);

/// First lag at which the mean autocorrelation of the columns of R falls below level (at most
/// min(m / 4, 2000)): how many rows apart two residuals must be to count as unrelated.
int CorrelationLength(const ConstMatrixRef& R, const std::vector<int>& segment_starts,
                      double level);

}  // namespace structgp

#endif  // STRUCTGP_DIAGNOSE_AUTOCORRELATION_H_
