#include "structgp/kernel/euler_lagrange_kernel.h"

#include <cassert>
#include <cmath>
#include <stdexcept>
#include <string>

namespace structgp {
namespace {

// Per angle l, with d = q_l - q'_l: f = (1 + theta cos d) / (1 + theta) and g = f^2, each with
// its log-derivatives in q_l (first) and in q_l, q'_l (mixed): rho = f_q / f,
// rho2 = f_qq' / f, r = g_q / g, r2 = g_qq' / g. The derivatives in q'_l are the negatives of
// those in q_l (the factors depend on d only).
struct AngleFactors {
  double f[kMaxEulerLagrangeJoints], rho[kMaxEulerLagrangeJoints],
      rho2[kMaxEulerLagrangeJoints], r[kMaxEulerLagrangeJoints], r2[kMaxEulerLagrangeJoints];
};

void ComputeFactors(int n, double theta, const double* x, const double* y, AngleFactors* out) {
  const double inv = 1.0 / (1.0 + theta);
  for (int l = 0; l < n; ++l) {
    const double d = x[l] - y[l];
    const double c = std::cos(d), s = std::sin(d);
    const double f = (1.0 + theta * c) * inv;
    const double fq = -theta * s * inv;
    const double fqq = theta * c * inv;  // d^2 f / d q d q'
    out->f[l] = f;
    out->rho[l] = fq / f;
    out->rho2[l] = fqq / f;
    // g = f^2: g_q = 2 f f_q, g_qq' = 2 (-f_q^2 + f f_qq').
    out->r[l] = 2.0 * fq / f;
    out->r2[l] = 2.0 * (-fq * fq + f * fqq) / (f * f);
  }
}

// Adds link `last`'s kinetic part (times wk) and potential part (times wp) to K.
void AddLink(int n, const AngleFactors& F, const double* x, const double* y, int last, double wk,
             double wp, MatrixRef K) {
  const double* a = x + n;       // qd
  const double* ap = y + n;      // qd'
  const double* b = x + 2 * n;   // qdd
  const double* bp = y + 2 * n;  // qdd'
  // Potential, k = prod_{l <= last} f_l: d_i d'_i' k = k (-rho_i rho_i' + [i = i'] (rho2_i +
  // rho_i^2)).
  if (wp != 0.0) {
    double Q = wp;
    for (int l = 0; l <= last; ++l) Q *= F.f[l];
    for (int i = 0; i <= last; ++i) {
      for (int k = 0; k <= last; ++k) {
        K(i, k) += Q * (-F.rho[i] * F.rho[k] + (i == k ? F.rho2[i] + F.rho[i] * F.rho[i] : 0.0));
      }
    }
  }
  if (wk == 0.0) return;
  // Kinetic: the entries M_jk (j <= k <= last) with covariance
  //   P_jk = wk prod_{j < l <= k} f_l prod_{k < l <= last} g_l.
  // On joint i, L_i^{jk} m = alpha m + u (qd . grad m) - gamma d_i m with
  //   alpha = [i = j] qdd_k + [i = k != j] qdd_j,  u = [i = j] qd_k + [i = k != j] qd_j,
  //   gamma = c qd_j qd_k (c = 1/2 if j = k, else 1),
  // applied to both arguments of P_jk. Per angle l, d_l is the log-derivative of P_jk's factor
  // in q_l and e_l its mixed ratio plus d_l^2 (zero for the angles P_jk does not depend on), so
  // that d_l d'_l' P_jk = P_jk (-d_l d_l' + [l = l'] e_l).
  double d[kMaxEulerLagrangeJoints], e[kMaxEulerLagrangeJoints];
  double grad[kMaxEulerLagrangeJoints], gradp[kMaxEulerLagrangeJoints],
      aH[kMaxEulerLagrangeJoints], Hap[kMaxEulerLagrangeJoints];
  for (int j = 0; j <= last; ++j) {
    for (int k = j; k <= last; ++k) {
      double Pjk = wk;
      for (int l = 0; l <= last; ++l) {
        if (l <= j) {
          d[l] = e[l] = 0.0;
        } else if (l <= k) {
          Pjk *= F.f[l];
          d[l] = F.rho[l];
          e[l] = F.rho2[l] + F.rho[l] * F.rho[l];
        } else {
          Pjk *= F.f[l] * F.f[l];
          d[l] = F.r[l];
          e[l] = F.r2[l] + F.r[l] * F.r[l];
        }
      }
      // A = qd . d, A' = qd' . d, S = sum_l qd_l qd'_l e_l.
      double A = 0.0, Ap = 0.0, S = 0.0;
      for (int l = j + 1; l <= last; ++l) {
        A += a[l] * d[l];
        Ap += ap[l] * d[l];
        S += a[l] * ap[l] * e[l];
      }
      const double D = Pjk * A;              // qd . grad P_jk
      const double Dp = -Pjk * Ap;           // qd' . grad' P_jk
      const double E = Pjk * (-A * Ap + S);  // qd^T (grad grad'^T P_jk) qd'
      for (int l = 0; l <= last; ++l) {
        grad[l] = Pjk * d[l];
        gradp[l] = -Pjk * d[l];
        aH[l] = Pjk * (-A * d[l] + a[l] * e[l]);
        Hap[l] = Pjk * (-d[l] * Ap + ap[l] * e[l]);
      }
      const double c = j == k ? 0.5 : 1.0;
      const double gamma = c * a[j] * a[k], gammap = c * ap[j] * ap[k];
      for (int i = 0; i <= last; ++i) {
        const double alpha = (i == j ? b[k] : 0.0) + (i == k && j != k ? b[j] : 0.0);
        const double u = (i == j ? a[k] : 0.0) + (i == k && j != k ? a[j] : 0.0);
        for (int ip = 0; ip <= last; ++ip) {
          const double alphap = (ip == j ? bp[k] : 0.0) + (ip == k && j != k ? bp[j] : 0.0);
          const double up = (ip == j ? ap[k] : 0.0) + (ip == k && j != k ? ap[j] : 0.0);
          const double Hii = Pjk * (-d[i] * d[ip] + (i == ip ? e[i] : 0.0));
          K(i, ip) += alpha * alphap * Pjk + alpha * (up * Dp - gammap * gradp[ip]) +
                      alphap * (u * D - gamma * grad[i]) + u * up * E - u * gammap * aH[ip] -
                      up * gamma * Hap[i] + gamma * gammap * Hii;
        }
      }
    }
  }
}

}  // namespace

EulerLagrangeKernel::EulerLagrangeKernel(int num_joints, double sigma)
    : num_joints_(num_joints), sigma_(sigma), theta_(1.0 / (1.0 + sigma)) {
  if (num_joints < 1 || num_joints > kMaxEulerLagrangeJoints) {
    throw std::invalid_argument("EulerLagrangeKernel: expected 1.." +
                                std::to_string(kMaxEulerLagrangeJoints) + " joints, got " +
                                std::to_string(num_joints));
  }
  if (!(sigma > 0.0) || !std::isfinite(sigma)) {
    throw std::invalid_argument("EulerLagrangeKernel: sigma must be finite and > 0, got " +
                                std::to_string(sigma));
  }
}

std::vector<std::string> EulerLagrangeKernel::part_names() const {
  std::vector<std::string> names;
  for (int l = 1; l <= num_joints_; ++l) names.push_back("kinetic " + std::to_string(l));
  for (int l = 1; l <= num_joints_; ++l) names.push_back("potential " + std::to_string(l));
  return names;
}

void EulerLagrangeKernel::EvaluateLink(const ConstVectorRef& a, const ConstVectorRef& b,
                                       int link, MatrixRef kinetic, MatrixRef potential) const {
  const int n = num_joints_;
  assert(a.size() == 3 * n && b.size() == 3 * n && link >= 0 && link < n);
  assert(kinetic.rows() == n && kinetic.cols() == n);
  assert(potential.rows() == n && potential.cols() == n);
  AngleFactors F;
  ComputeFactors(n, theta_, a.data(), b.data(), &F);
  kinetic.setZero();
  potential.setZero();
  AddLink(n, F, a.data(), b.data(), link, 1.0, 0.0, kinetic);
  AddLink(n, F, a.data(), b.data(), link, 0.0, 1.0, potential);
}

void EulerLagrangeKernel::Evaluate(const ConstVectorRef& a, const ConstVectorRef& b,
                                   const ConstVectorRef& part_weights, MatrixRef block) const {
  const int n = num_joints_;
  assert(a.size() == 3 * n && b.size() == 3 * n && part_weights.size() == 2 * n);
  assert(block.rows() == n && block.cols() == n);
  AngleFactors F;
  ComputeFactors(n, theta_, a.data(), b.data(), &F);
  block.setZero();
  for (int link = 0; link < n; ++link) {
    AddLink(n, F, a.data(), b.data(), link, part_weights[link], part_weights[n + link], block);
  }
}

}  // namespace structgp
