#include "structgp/feature/lagrangian_regressor_map.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace structgp {
namespace {

constexpr int kKineticBases = 5;    // 1, cos q, sin q, cos 2q, sin 2q
constexpr int kPotentialBases = 3;  // 1, cos q, sin q
const char* const kBasisName[kKineticBases] = {"", "cos", "sin", "cos2", "sin2"};

int Power(int base, int exponent) {
  int out = 1;
  for (int i = 0; i < exponent; ++i) out *= base;
  return out;
}

void Check(int num_joints) {
  if (num_joints < 1 || num_joints > kMaxLagrangianJoints) {
    throw std::invalid_argument("LagrangianRegressorMap: expected 1.." +
                                std::to_string(kMaxLagrangianJoints) + " joints, got " +
                                std::to_string(num_joints));
  }
}

}  // namespace

int LagrangianDimension(int num_joints) {
  Check(num_joints);
  int P = Power(kPotentialBases, num_joints) - 1;
  for (int a = 0; a < num_joints; ++a) {
    for (int b = a; b < num_joints; ++b) {
      P += Power(kPotentialBases, b - a) * Power(kKineticBases, num_joints - 1 - b);
    }
  }
  return P;
}

LagrangianRegressorMap::LagrangianRegressorMap(int num_joints) : num_joints_(num_joints) {
  Check(num_joints);
  const int N = num_joints;
  for (int a = 0; a < N; ++a) {
    for (int b = a; b < N; ++b) {
      // M_ab depends on the angles a+1..N-1: those up to b with the bases 1, cos, sin (only
      // joint a's column of the link's Jacobian turns with them), those after b with all five.
      const int count = Power(kPotentialBases, b - a) * Power(kKineticBases, N - 1 - b);
      for (int code = 0; code < count; ++code) {
        Param p;
        p.a = a;
        p.b = b;
        int rest = code;
        for (int l = a + 1; l < N; ++l) {
          const int bases = l <= b ? kPotentialBases : kKineticBases;
          p.index.at(static_cast<size_t>(l)) = static_cast<std::int8_t>(rest % bases);
          rest /= bases;
        }
        params_.push_back(p);
      }
    }
  }
  num_kinetic_ = static_cast<int>(params_.size());
  const int count = Power(kPotentialBases, N);
  for (int code = 1; code < count; ++code) {  // code 0 is the constant
    Param p;
    p.a = p.b = -1;
    int rest = code;
    for (int l = 0; l < N; ++l) {
      p.index[static_cast<size_t>(l)] = static_cast<std::int8_t>(rest % kPotentialBases);
      rest /= kPotentialBases;
    }
    params_.push_back(p);
  }
  // The earliest link that can produce each term, and the parameters ordered by it (stable:
  // within a link, M_ab then its bases as enumerated), kinetic first.
  auto link_of = [N](const Param& p) {
    int link = p.a >= 0 ? p.b : 0;
    for (int l = 0; l < N; ++l) {
      if (p.index[static_cast<size_t>(l)] != 0) link = std::max(link, l);
    }
    return link;
  };
  std::stable_sort(params_.begin(), params_.begin() + num_kinetic_,
                   [&](const Param& x, const Param& y) { return link_of(x) < link_of(y); });
  std::stable_sort(params_.begin() + num_kinetic_, params_.end(),
                   [&](const Param& x, const Param& y) { return link_of(x) < link_of(y); });
  for (const Param& p : params_) link_.push_back(link_of(p));
}

std::vector<FeatureBlock> LagrangianRegressorMap::blocks() const {
  // Blocks follow the parameters' order (see the constructor): "kinetic L" and "potential L"
  // hold the terms that only links L..N can produce (a term of M_ab or V that varies with q_l
  // needs a link at or after l; M_ab at all, a link at or after max(a, b)), so that a light
  // wrist gets a small prior scale of its own.
  std::vector<FeatureBlock> out;
  for (int k = 0; k < dim(); ++k) {
    const std::string name = std::string(params_[static_cast<size_t>(k)].a >= 0 ? "kinetic "
                                                                                 : "potential ") +
                             std::to_string(link_[static_cast<size_t>(k)] + 1);
    if (!out.empty() && out.back().name == name) {
      ++out.back().size;
    } else {
      out.push_back(FeatureBlock{name, k, 1});
    }
  }
  return out;
}

std::vector<std::string> LagrangianRegressorMap::parameter_names() const {
  std::vector<std::string> names;
  for (const Param& p : params_) {
    std::string basis;
    for (int l = 0; l < num_joints_; ++l) {
      const int i = p.index[static_cast<size_t>(l)];
      if (i == 0) continue;
      basis += (basis.empty() ? "" : " ") + std::string(kBasisName[i]) + " q" + std::to_string(l + 1);
    }
    names.push_back((p.a < 0 ? std::string("V")
                             : "M" + std::to_string(p.a + 1) + "," + std::to_string(p.b + 1)) +
                    "[" + (basis.empty() ? "1" : basis) + "]");
  }
  return names;
}

std::vector<std::string> LagrangianRegressorMap::component_names() const {
  return {"inertial", "coriolis", "gravity"};
}

void LagrangianRegressorMap::Fill(const ConstVectorRef& x, MatrixRef psi, int parts) const {
  const int N = num_joints_;
  // Per angle: the bases and their derivatives.
  double B[kMaxLagrangianJoints][kKineticBases], dB[kMaxLagrangianJoints][kKineticBases];
  for (int l = 0; l < N; ++l) {
    const double c = std::cos(x[l]), s = std::sin(x[l]);
    const double c2 = c * c - s * s, s2 = 2.0 * s * c;
    B[l][0] = 1.0;
    B[l][1] = c;
    B[l][2] = s;
    B[l][3] = c2;
    B[l][4] = s2;
    dB[l][0] = 0.0;
    dB[l][1] = -s;
    dB[l][2] = c;
    dB[l][3] = -2.0 * s2;
    dB[l][4] = 2.0 * c2;
  }
  const double* qd = x.data() + N;
  const double* qdd = x.data() + 2 * N;
  psi.setZero();
  double grad[kMaxLagrangianJoints];
  for (int k = 0; k < dim(); ++k) {
    const Param& p = params_[static_cast<size_t>(k)];
    const bool kinetic = p.a >= 0;
    if (kinetic ? (parts & 3) == 0 : (parts & 4) == 0) continue;
    const int first = kinetic ? p.a + 1 : 0;
    // The basis function and its gradient over the angles it depends on.
    double value = 1.0;
    for (int l = first; l < N; ++l) value *= B[l][p.index[static_cast<size_t>(l)]];
    for (int l = first; l < N; ++l) {
      double g = dB[l][p.index[static_cast<size_t>(l)]];
      for (int m = first; m < N && g != 0.0; ++m) {
        if (m != l) g *= B[m][p.index[static_cast<size_t>(m)]];
      }
      grad[l] = g;
    }
    if (!kinetic) {
      for (int i = first; i < N; ++i) psi(i, k) = grad[i];
      continue;
    }
    const int a = p.a, b = p.b;
    if (parts & 1) {  // M qdd
      psi(a, k) += value * qdd[b];
      if (a != b) psi(b, k) += value * qdd[a];
    }
    if (parts & 2) {  // sum_jk (dM_ij/dq_k - 1/2 dM_jk/dq_i) qd_j qd_k
      double rate = 0.0;  // d(basis)/dt = grad . qd
      for (int l = first; l < N; ++l) rate += grad[l] * qd[l];
      psi(a, k) += qd[b] * rate;
      if (a != b) psi(b, k) += qd[a] * rate;
      const double w = a == b ? qd[a] * qd[a] : 2.0 * qd[a] * qd[b];
      for (int i = first; i < N; ++i) psi(i, k) -= 0.5 * grad[i] * w;
    }
  }
}

Vector LagrangianRegressorMap::KernelPriorVariance(double sigma,
                                                   const ConstVectorRef& part_weights) const {
  const int N = num_joints_;
  if (!(sigma > 0.0) || !std::isfinite(sigma)) {
    throw std::invalid_argument("LagrangianRegressorMap::KernelPriorVariance: sigma must be "
                                "finite and > 0, got " + std::to_string(sigma));
  }
  if (part_weights.size() != 2 * N) {
    throw std::invalid_argument("LagrangianRegressorMap::KernelPriorVariance: expected " +
                                std::to_string(2 * N) + " part weights, got " +
                                std::to_string(part_weights.size()));
  }
  for (Eigen::Index p = 0; p < part_weights.size(); ++p) {
    if (!(part_weights[p] >= 0.0) || !std::isfinite(part_weights[p])) {
      throw std::invalid_argument("LagrangianRegressorMap::KernelPriorVariance: part weight " +
                                  std::to_string(p) + " must be finite and >= 0, got " +
                                  std::to_string(part_weights[p]));
    }
  }
  const double theta = 1.0 / (1.0 + sigma);
  const double g0 = (1.0 + theta) * (1.0 + theta);
  const double kinetic_coef[kKineticBases] = {(1.0 + 0.5 * theta * theta) / g0,
                                              2.0 * theta / g0, 2.0 * theta / g0,
                                              0.5 * theta * theta / g0, 0.5 * theta * theta / g0};
  const double potential_coef[kPotentialBases] = {1.0 / (1.0 + theta), theta / (1.0 + theta),
                                                  theta / (1.0 + theta)};
  Vector v(dim());
  for (int k = 0; k < dim(); ++k) {
    const Param& p = params_[static_cast<size_t>(k)];
    const bool kinetic = p.a >= 0;
    const double* weight = part_weights.data() + (kinetic ? 0 : N);
    // The angle's factor: f's coefficients (potential_coef) for V's angles and M_ab's up to b,
    // g's (kinetic_coef) for M_ab's after b. Link L' covers the angles first..L'; the
    // parameter's angles past its earliest link are constant in it, each adding the constant
    // basis's coefficient (of g: they come after b).
    auto coef = [&](int l) { return kinetic && l > p.b ? kinetic_coef : potential_coef; };
    const int first = kinetic ? p.a + 1 : 0;
    const int earliest = link_[static_cast<size_t>(k)];
    double product = 1.0;
    for (int l = first; l <= earliest; ++l) product *= coef(l)[p.index[static_cast<size_t>(l)]];
    double sum = 0.0;
    for (int link = earliest; link < N; ++link) {
      if (link > earliest) product *= coef(link)[0];
      sum += weight[link] * product;
    }
    v[k] = sum;
  }
  return v;
}

void LagrangianRegressorMap::Evaluate(const ConstVectorRef& x, MatrixRef psi, Scratch*) const {
  Fill(x, psi, 7);
}

void LagrangianRegressorMap::EvaluateComponent(int component, const ConstVectorRef& x,
                                               MatrixRef psi, Scratch*) const {
  if (component < 0 || component >= 3) {
    throw std::invalid_argument("LagrangianRegressorMap::EvaluateComponent: component " +
                                std::to_string(component) + " out of range [0, 3)");
  }
  Fill(x, psi, 1 << component);
}

}  // namespace structgp
