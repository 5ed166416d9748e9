#ifndef STRUCTGP_EXPERIMENTS_LAGRANGIAN_KERNEL_GP_H_
#define STRUCTGP_EXPERIMENTS_LAGRANGIAN_KERNEL_GP_H_

// A prototype, for measurement only: a GP on the joint torques with the library's
// EulerLagrangeKernel (structgp/kernel/euler_lagrange_kernel.h: a GP prior on each link's
// kinetic and potential energy, the torque kernel by the Euler-Lagrange operator on both
// arguments), so that one GP explains every joint. No kinematic parameters. Dense, O((m N)^3).
// Without per_link only link N's parts are used: one kinetic and one potential energy for the
// whole chain.
// Hyper-parameters by type-II maximum likelihood (Ceres LBFGS, analytic gradient): log w_M,
// log w_V (or, per link, one pair for each link's energies) and one log noise std per joint, at
// the best of a few sigma. The posterior is exact on its rows, or, with inducing states, the
// deterministic training conditional (DTC) on every row: the torques at p inducing states
// Z (p N outputs) carry the posterior, O(m N (p N)^2) instead of O((m N)^3).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>
#include <vector>

#include <ceres/ceres.h>
#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "structgp/core/types.h"
#include "structgp/kernel/euler_lagrange_kernel.h"

namespace structgp {
namespace lagrangian_prototype {

// The semi-parametric friction beside it (the "+fri" of the other models): on joint i the
// bases qd_i, tanh(qd_i / width) and 1, independent, prior std scale_i (1/rms_qd_i for qd_i).
struct Friction {
  bool enabled = false;
  double width = 0.01;
  Vector scale, rms_qd;
  double Evaluate(int n, int i, const double* x, const double* y) const {
    const double a = x[n + i], b = y[n + i];
    return scale[i] * scale[i] *
           (a * b / (rms_qd[i] * rms_qd[i]) + std::tanh(a / width) * std::tanh(b / width) + 1.0);
  }
};

// Gram parts over states X (m x 3N) against Z (p x 3N), each (m N) x (p N), row index
// state * N + i: kinetic then potential, for the whole chain (2 parts) or per link (2 N parts:
// kinetic of links 1..N, then potential of links 1..N). F: the friction part (prior fixed).
// With weights: one part, the weighted sum of them all plus F (F is then left empty).
inline void Gram(int n, double sigma, const Matrix& X, const Matrix& Z, bool per_link,
                 bool symmetric, const Friction& fri, std::vector<Matrix>* parts, Matrix* F,
                 const Vector* weights = nullptr) {
  const EulerLagrangeKernel kernel(n, sigma);
  const Eigen::Index m = X.rows(), p = Z.rows();
  const int links = per_link ? n : 1;
  const bool combine = weights != nullptr;
  parts->assign(combine ? 1 : static_cast<size_t>(2 * links), Matrix::Zero(m * n, p * n));
  Matrix& Fo = combine ? (*parts)[0] : *F;
  if (combine) F->resize(0, 0);
  else F->setZero(m * n, p * n);
  Matrix kin(n, n), pot(n, n);
  const Matrix Xt = X.transpose(), Zt = Z.transpose();
  for (Eigen::Index s = 0; s < m; ++s) {
    for (Eigen::Index t = symmetric ? s : 0; t < p; ++t) {
      const double* xs = Xt.col(s).data();
      const double* zt = Zt.col(t).data();
      for (int link = 0; link < links; ++link) {
        kernel.EvaluateLink(Xt.col(s), Zt.col(t), per_link ? link : n - 1, kin, pot);
        Matrix& K = (*parts)[combine ? 0 : static_cast<size_t>(link)];
        Matrix& V = (*parts)[combine ? 0 : static_cast<size_t>(links + link)];
        const double wk = combine ? (*weights)[link] : 1.0;
        const double wv = combine ? (*weights)[links + link] : 1.0;
        for (int i = 0; i < n; ++i) {
          for (int k = 0; k < n; ++k) {
            const double kv = kin(i, k);
            const double pv = pot(i, k);
            K(s * n + i, t * n + k) += wk * kv;
            V(s * n + i, t * n + k) += wv * pv;
            if (symmetric && t != s) {
              K(t * n + k, s * n + i) += wk * kv;
              V(t * n + k, s * n + i) += wv * pv;
            }
          }
        }
      }
      if (fri.enabled) {
        for (int i = 0; i < n; ++i) {
          const double f = fri.Evaluate(n, i, xs, zt);
          Fo(s * n + i, t * n + i) += f;
          if (symmetric && t != s) Fo(t * n + i, s * n + i) += f;
        }
      }
    }
  }
}

inline Matrix Combine(const std::vector<Matrix>& parts, const Vector& w, const Matrix& F) {
  Matrix C = F;
  for (size_t k = 0; k < parts.size(); ++k) C += w[static_cast<Eigen::Index>(k)] * parts[k];
  return C;
}

struct Options {
  std::vector<double> sigmas = {1.0, 3.0, 10.0, 30.0, 100.0};  // theta = 1 / (1 + sigma)
  int inducing = 0;  // > 0: DTC posterior on this many evenly spaced training states
};

struct Fitted {
  Friction friction;
  bool per_link = false;
  double sigma = 1.0;  // of the kernel's trigonometric factors
  Vector weights;  // one per part
  Vector noise;    // per joint, std
  double log_evidence = 0.0;  // without its constant -(m N / 2) log(2 pi)
  Matrix X;        // training states (exact) or inducing states (DTC)
  Vector alpha;    // exact: C^{-1} y; DTC: L^-T B^-1 V S^-1/2 y
  Eigen::LLT<Matrix> llt;  // exact: C; DTC: K_ZZ = L L^T
  bool dtc = false;
  Eigen::LLT<Matrix> llt_b;  // DTC: B = I + V V^T, V = L^-1 K_ZX S^-1/2 (S: noise variances)
};

// -log evidence of y (stacked state-major) and its gradient in (log w_part..., log noise_j).
class Objective : public ceres::FirstOrderFunction {
 public:
  Objective(int n, const std::vector<Matrix>& parts, const Matrix& F, const Vector& y)
      : n_(n), parts_(parts), F_(F), y_(y) {}
  int NumParameters() const override { return static_cast<int>(parts_.size()) + n_; }
  bool Evaluate(const double* p, double* cost, double* gradient) const override {
    const int P = static_cast<int>(parts_.size());
    Vector w(P);
    for (int k = 0; k < P; ++k) w[k] = std::exp(p[k]);
    Matrix C = Combine(parts_, w, F_);
    for (Eigen::Index r = 0; r < C.rows(); ++r) C(r, r) += std::exp(2.0 * p[P + r % n_]);
    Eigen::LLT<Matrix> llt(C);
    if (llt.info() != Eigen::Success) return false;
    const Vector alpha = llt.solve(y_);
    double logdet = 0.0;
    for (Eigen::Index r = 0; r < C.rows(); ++r) logdet += std::log(llt.matrixL()(r, r));
    *cost = 0.5 * y_.dot(alpha) + logdet;
    if (!std::isfinite(*cost)) return false;
    if (gradient != nullptr) {
      const Matrix Ci = llt.solve(Matrix::Identity(C.rows(), C.rows()));
      // d cost / d log w = 1/2 (tr(C^-1 A) - alpha^T A alpha) w.
      for (int k = 0; k < P; ++k) {
        const Matrix& A = parts_[static_cast<size_t>(k)];
        gradient[k] = 0.5 * w[k] * ((Ci.cwiseProduct(A)).sum() - alpha.dot(A * alpha));
      }
      for (int j = 0; j < n_; ++j) {
        double tr = 0.0, aa = 0.0;
        for (Eigen::Index r = j; r < C.rows(); r += n_) {
          tr += Ci(r, r);
          aa += alpha[r] * alpha[r];
        }
        gradient[P + j] = (tr - aa) * std::exp(2.0 * p[P + j]);
      }
    }
    return true;
  }

 private:
  int n_;
  const std::vector<Matrix>& parts_;
  const Matrix& F_;
  const Vector& y_;
};

inline Vector Stack(const Matrix& Y) {
  Vector y(Y.size());
  for (Eigen::Index s = 0; s < Y.rows(); ++s) y.segment(s * Y.cols(), Y.cols()) = Y.row(s).transpose();
  return y;
}

// Hyper-parameters on (Xh, Yh), then the posterior on (X, Y).
inline Fitted Fit(const Matrix& Xh, const Matrix& Yh, const Matrix& X, const Matrix& Y,
                  bool friction, bool per_link, const Options& options = Options()) {
  const int n = static_cast<int>(Y.cols());
  const Vector yh = Stack(Yh);
  Fitted best;
  best.per_link = per_link;
  best.friction.enabled = friction;
  best.friction.scale.resize(n);
  best.friction.rms_qd.resize(n);
  for (int j = 0; j < n; ++j) {
    best.friction.scale[j] = std::sqrt(Y.col(j).squaredNorm() / Y.rows());
    best.friction.rms_qd[j] = std::max(std::sqrt(X.col(n + j).squaredNorm() / X.rows()), 1e-3);
  }
  best.log_evidence = -INFINITY;
  if (options.sigmas.empty()) throw std::invalid_argument("lagk: no sigma to try");
  for (double sigma : options.sigmas) {
    if (!(sigma > 0.0)) throw std::invalid_argument("lagk: sigma must be > 0");
    std::vector<Matrix> parts;
    Matrix F;
    Gram(n, sigma, Xh, Xh, per_link, true, best.friction, &parts, &F);
    const int P = static_cast<int>(parts.size());
    std::vector<double> p(static_cast<size_t>(P + n));
    // Start: every part at the torque's spread, noise 10% of each joint's RMS torque.
    const double spread = yh.squaredNorm() / yh.size();
    for (int k = 0; k < P; ++k) {
      p[static_cast<size_t>(k)] =
          std::log(spread / P / (parts[static_cast<size_t>(k)].diagonal().mean() + 1e-300));
    }
    for (int j = 0; j < n; ++j) {
      p[static_cast<size_t>(P + j)] =
          std::log(0.1 * std::sqrt(Yh.col(j).squaredNorm() / Yh.rows()));
    }
    ceres::GradientProblem problem(new Objective(n, parts, F, yh));
    ceres::GradientProblemSolver::Options o;
    o.max_num_iterations = 80;
    ceres::GradientProblemSolver::Summary summary;
    ceres::Solve(o, problem, p.data(), &summary);
    std::printf("    lagk%s sigma %.2g: -log evidence %.6g (%d iterations, %s)\n",
                per_link ? "/link" : "", sigma, summary.final_cost,
                static_cast<int>(summary.iterations.size()),
                summary.termination_type == ceres::CONVERGENCE ? "converged" : "stopped");
    std::fflush(stdout);
    if (!summary.IsSolutionUsable()) continue;
    if (-summary.final_cost > best.log_evidence) {
      best.log_evidence = -summary.final_cost;
      best.sigma = sigma;
      best.weights.resize(P);
      for (int k = 0; k < P; ++k) best.weights[k] = std::exp(p[static_cast<size_t>(k)]);
      best.noise.resize(n);
      for (int j = 0; j < n; ++j) best.noise[j] = std::exp(p[static_cast<size_t>(P + j)]);
    }
  }
  if (best.weights.size() == 0) {
    throw std::runtime_error("lagk: type-II maximum likelihood failed at every sigma");
  }
  std::vector<Matrix> parts;
  Matrix F;
  if (options.inducing > 0 && options.inducing < X.rows()) {
    // DTC on every row: K_ZZ = L L^T (a relative jitter of 1e-8), V = L^-1 K_ZX S^-1/2,
    // B = I + V V^T; mean weights alpha = L^-T B^-1 V S^-1/2 y.
    const int p = options.inducing;
    Matrix Z(p, X.cols());
    for (int r = 0; r < p; ++r) {
      Z.row(r) = X.row(static_cast<Eigen::Index>((static_cast<double>(r) + 0.5) * X.rows() / p));
    }
    Gram(n, best.sigma, Z, Z, per_link, true, best.friction, &parts, &F, &best.weights);
    Matrix Kzz = std::move(parts[0]);
    const double jitter = 1e-8 * Kzz.diagonal().mean();
    Kzz.diagonal().array() += jitter;
    best.llt.compute(Kzz);
    if (best.llt.info() != Eigen::Success) throw std::runtime_error("lagk: K_ZZ not positive");
    // K_ZX directly (the kernel is symmetric), not K_XZ and a transposed copy of it.
    Gram(n, best.sigma, Z, X, per_link, false, best.friction, &parts, &F, &best.weights);
    Matrix V = std::move(parts[0]);  // (p N) x (m N)
    parts.clear();
    Vector ys = Stack(Y);
    for (Eigen::Index r = 0; r < V.cols(); ++r) {
      V.col(r) /= best.noise[r % n];
      ys[r] /= best.noise[r % n];
    }
    best.llt.matrixL().solveInPlace(V);
    Matrix B = Matrix::Identity(V.rows(), V.rows());
    B.selfadjointView<Eigen::Lower>().rankUpdate(V);
    best.llt_b.compute(B);  // reads the lower triangle
    if (best.llt_b.info() != Eigen::Success) throw std::runtime_error("lagk: B not positive");
    best.alpha = best.llt.matrixU().solve(best.llt_b.solve(V * ys));
    best.X = Z;
    best.dtc = true;
    return best;
  }
  Gram(n, best.sigma, X, X, per_link, true, best.friction, &parts, &F, &best.weights);
  Matrix C = std::move(parts[0]);
  for (Eigen::Index r = 0; r < C.rows(); ++r) C(r, r) += best.noise[r % n] * best.noise[r % n];
  best.llt.compute(C);
  best.alpha = best.llt.solve(Stack(Y));
  best.X = X;
  return best;
}

// Mean (m x N) at the states Z, and the noisy predictive std at every `stride`-th row (other
// rows: NaN), stride >= 1.
inline void Predict(const Fitted& f, const Matrix& Z, int stride, Matrix* mean, Matrix* noisy_std) {
  const int n = static_cast<int>(f.noise.size());
  stride = std::max(stride, 1);
  mean->resize(Z.rows(), n);
  noisy_std->setConstant(Z.rows(), n, std::nan(""));
  std::vector<Matrix> parts;
  Matrix F;
  for (Eigen::Index s = 0; s < Z.rows(); ++s) {
    Gram(n, f.sigma, Z.row(s), f.X, f.per_link, false, f.friction, &parts, &F, &f.weights);
    const Matrix Ks = parts[0];  // N x (m N)
    mean->row(s) = (Ks * f.alpha).transpose();
    if (s % stride == 0) {
      Gram(n, f.sigma, Z.row(s), Z.row(s), f.per_link, false, f.friction, &parts, &F,
           &f.weights);
      const Matrix Kss = parts[0];
      const Matrix v = f.llt.matrixL().solve(Ks.transpose());
      Matrix cov = Kss - v.transpose() * v;
      if (f.dtc) {  // + K_*Z (K_ZZ + K_ZX S^-1 K_XZ)^-1 K_Z* = |L_B^-1 v|^2
        const Matrix w = f.llt_b.matrixL().solve(v);
        cov += w.transpose() * w;
      }
      for (int i = 0; i < n; ++i) {
        (*noisy_std)(s, i) = std::sqrt(std::max(cov(i, i), 0.0) + f.noise[i] * f.noise[i]);
      }
    }
  }
}

}  // namespace lagrangian_prototype
}  // namespace structgp

#endif  // STRUCTGP_EXPERIMENTS_LAGRANGIAN_KERNEL_GP_H_
