#include "chain_identification.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <random>
#include <stdexcept>
#include <thread>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <ceres/ceres.h>

#include "structgp/core/row_subset.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/urdf.h"

namespace structgp {
namespace {

int KinematicSize(int N) { return N >= 2 ? 4 * N - 4 : 1; }

int DesignCols(int N, bool friction) { return 11 * N + (friction ? 2 * N : 0); }

// theta minimising |W (y - Phi theta)|^2 + ridge |theta|^2 (Phi and y scaled already).
Vector SolveScaled(const Matrix& A, const Vector& b, double ridge) {
  Matrix G = A.transpose() * A;
  const double mean_diag = std::max(G.diagonal().mean(), 1e-300);
  G.diagonal().array() += ridge * mean_diag;
  return G.ldlt().solve(A.transpose() * b);
}

struct Problem {
  int N;
  Matrix X;          // search rows
  Vector y_scaled;   // stacked, each joint divided by its scale
  Vector scale;      // per joint
  bool friction;
  double width;
  double ridge;
};

// The scaled residual of the least-squares fit of the inertial (and friction) parameters for
// kinematics kappa.
bool Residual(const Problem& p, const double* kappa, double* out) {
  Vector k = Eigen::Map<const Vector>(kappa, KinematicSize(p.N));
  Matrix A;
  try {
    A = ChainDesign(ChainFromKinematics(p.N, k), p.X, p.friction, p.width);
  } catch (const std::exception&) {
    return false;
  }
  for (Eigen::Index r = 0; r < A.rows(); ++r) A.row(r) /= p.scale[r % p.N];
  const Vector theta = SolveScaled(A, p.y_scaled, p.ridge);
  Eigen::Map<Vector>(out, A.rows()) = p.y_scaled - A * theta;
  return true;
}

struct CostFunctor {
  const Problem* p;
  bool operator()(double const* const* parameters, double* residuals) const {
    return Residual(*p, parameters[0], residuals);
  }
};

Vector RandomStart(int N, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> pick(-1, 1);
  Vector k(KinematicSize(N));
  k[0] = 0.1 * u(*rng);  // beta: mostly upright, any lean reachable
  if (N >= 2) {
    k[1] = M_PI * u(*rng);                // theta_1
    k[2] = M_PI / 2 * pick(*rng) + 0.1 * u(*rng);  // alpha_2
    k[3] = 0.3 * u(*rng);                 // a_2
    for (int i = 2; i <= N - 1; ++i) {
      const int o = 4 + 4 * (i - 2);
      k[o] = M_PI * u(*rng);              // theta_i
      k[o + 1] = 0.4 * u(*rng);           // d_i
      k[o + 2] = M_PI / 2 * pick(*rng) + 0.1 * u(*rng);  // alpha_{i+1}
      k[o + 3] = 0.4 * u(*rng);           // a_{i+1}
    }
  }
  return k;
}

}  // namespace

RigidBodyChain ChainFromKinematics(int N, const Vector& kappa) {
  if (kappa.size() != KinematicSize(N)) throw std::invalid_argument("kinematics size");
  std::vector<sim::LinkParameters> links(static_cast<size_t>(N));
  for (auto& l : links) {
    l.mass = 1.0;
    l.inertia = 0.01 * Eigen::Matrix3d::Identity();
    l.armature = 0.01;
  }
  if (N >= 2) {
    links[0].theta_offset = kappa[1];
    links[1].alpha = kappa[2];
    links[1].a = kappa[3];
    for (int i = 2; i <= N - 1; ++i) {
      const int o = 4 + 4 * (i - 2);
      links[static_cast<size_t>(i - 1)].theta_offset = kappa[o];
      links[static_cast<size_t>(i - 1)].d = kappa[o + 1];
      links[static_cast<size_t>(i)].alpha = kappa[o + 2];
      links[static_cast<size_t>(i)].a = kappa[o + 3];
    }
  }
  const Eigen::Matrix3d base = Eigen::AngleAxisd(kappa[0], Eigen::Vector3d::UnitX()).toRotationMatrix();
  const sim::Robot robot("identified", links, base, sim::DhConvention::kModified);
  return sim::ToRigidBodyChain(robot);
}

Matrix ChainDesign(const RigidBodyChain& chain, const Matrix& X, bool friction, double width) {
  const int N = chain.num_joints();
  const int P = chain.num_parameters();
  Matrix A = Matrix::Zero(X.rows() * N, DesignCols(N, friction));
  RigidBodyChain::Workspace ws = chain.MakeWorkspace();
  Matrix Yr(N, P);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    const Vector x = X.row(i).transpose();
    chain.Regressor(x.head(N), x.segment(N, N), x.segment(2 * N, N),
                    RigidBodyChain::Terms::kAll, Yr, ws);
    A.block(i * N, 0, N, P) = Yr;
    if (friction) {
      for (int j = 0; j < N; ++j) {
        A(i * N + j, P + 2 * j) = x[N + j];
        A(i * N + j, P + 2 * j + 1) = std::tanh(x[N + j] / width);
      }
    }
  }
  return A;
}

ChainIdentificationResult IdentifyChain(const Matrix& X, const Matrix& Y,
                                        const ChainIdentificationOptions& options) {
  const int N = static_cast<int>(Y.cols());
  Problem p;
  p.N = N;
  p.friction = options.friction;
  p.width = options.friction_width;
  p.ridge = options.ridge;
  const std::vector<int> rows =
      EvenlySpacedRows(X.rows(), std::min<Eigen::Index>(X.rows(), options.search_rows));
  p.X = SelectRows(X, rows);
  const Matrix Ys = SelectRows(Y, rows);
  p.scale = (Y.colwise().squaredNorm() / static_cast<double>(Y.rows())).cwiseSqrt().transpose();
  for (int j = 0; j < N; ++j) p.scale[j] = std::max(p.scale[j], 1e-12);
  p.y_scaled.resize(Ys.rows() * N);
  for (Eigen::Index i = 0; i < Ys.rows(); ++i) {
    for (int j = 0; j < N; ++j) p.y_scaled[i * N + j] = Ys(i, j) / p.scale[j];
  }
  const int K = KinematicSize(N);
  std::vector<Vector> starts;
  std::mt19937_64 rng(options.seed);
  for (int s = 0; s < options.starts; ++s) starts.push_back(RandomStart(N, &rng));
  std::vector<double> costs(starts.size(), std::numeric_limits<double>::infinity());
  std::vector<Vector> found = starts;
  std::mutex mutex;
  int next = 0;
  auto worker = [&]() {
    for (;;) {
      int s;
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (next >= static_cast<int>(starts.size())) return;
        s = next++;
      }
      Vector k = starts[static_cast<size_t>(s)];
      ceres::Problem problem;
      auto* cost = new ceres::DynamicNumericDiffCostFunction<CostFunctor, ceres::FORWARD>(
          new CostFunctor{&p});
      cost->AddParameterBlock(K);
      cost->SetNumResiduals(static_cast<int>(p.y_scaled.size()));
      problem.AddResidualBlock(cost, nullptr, k.data());
      ceres::Solver::Options so;
      so.linear_solver_type = ceres::DENSE_QR;
      so.max_num_iterations = options.max_iterations;
      so.num_threads = 1;
      so.logging_type = ceres::SILENT;
      ceres::Solver::Summary summary;
      ceres::Solve(so, &problem, &summary);
      std::lock_guard<std::mutex> lock(mutex);
      costs[static_cast<size_t>(s)] = 2.0 * summary.final_cost;
      found[static_cast<size_t>(s)] = k;
      std::printf("      chain start %d: cost %.6g -> %.6g (%d iterations, %s)\n", s,
                  2.0 * summary.initial_cost, 2.0 * summary.final_cost,
                  static_cast<int>(summary.iterations.size()),
                  ceres::TerminationTypeToString(summary.termination_type));
      std::fflush(stdout);
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < std::max(1, options.threads); ++t) threads.emplace_back(worker);
  worker();
  for (auto& t : threads) t.join();

  ChainIdentificationResult r;
  r.start_costs = costs;
  r.best_start = static_cast<int>(std::min_element(costs.begin(), costs.end()) - costs.begin());
  r.kinematics = found[static_cast<size_t>(r.best_start)];
  // Inertial parameters on every row, each joint weighted by its residual noise (two passes).
  const RigidBodyChain chain = ChainFromKinematics(N, r.kinematics);
  const Matrix A = ChainDesign(chain, X, options.friction, options.friction_width);
  Vector y(Y.rows() * N);
  for (Eigen::Index i = 0; i < Y.rows(); ++i) {
    for (int j = 0; j < N; ++j) y[i * N + j] = Y(i, j);
  }
  Vector w = p.scale;
  for (int pass = 0; pass < 2; ++pass) {
    Matrix As = A;
    Vector ys = y;
    for (Eigen::Index k = 0; k < A.rows(); ++k) {
      As.row(k) /= w[k % N];
      ys[k] /= w[k % N];
    }
    r.theta = SolveScaled(As, ys, options.ridge);
    const Vector res = y - A * r.theta;
    for (int j = 0; j < N; ++j) {
      double s = 0.0;
      for (Eigen::Index i = 0; i < Y.rows(); ++i) s += res[i * N + j] * res[i * N + j];
      w[j] = std::max(std::sqrt(s / static_cast<double>(Y.rows())), 1e-12);
    }
  }
  r.noise_std = w;
  return r;
}

Matrix PredictChain(int N, const ChainIdentificationResult& r, const Matrix& X,
                    const ChainIdentificationOptions& options) {
  const Matrix A = ChainDesign(ChainFromKinematics(N, r.kinematics), X, options.friction,
                               options.friction_width);
  const Vector t = A * r.theta;
  Matrix out(X.rows(), N);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    for (int j = 0; j < N; ++j) out(i, j) = t[i * N + j];
  }
  return out;
}

}  // namespace structgp
