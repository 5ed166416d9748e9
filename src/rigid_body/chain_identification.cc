#include "structgp/rigid_body/chain_identification.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <ceres/ceres.h>
#include <kdl/frames.hpp>

#include "structgp/core/row_subset.h"
#include "structgp/internal/workers.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/internal/text.h"

namespace structgp {
namespace {

// Numbers that read back to the same double.
std::string Num(double value) { return internal::ShortestDecimal(value); }

// Modified DH of one joint: alpha, a, theta, d.
struct Dh {
  double alpha = 0.0, a = 0.0, theta = 0.0, d = 0.0;
};

// Which joint's which DH number each kinematic parameter is (the header's layout): tilt is
// joint 1's alpha, then theta_1, alpha_2, a_2, and theta_i, d_i, alpha_{i+1}, a_{i+1}.
enum class Field { kAlpha, kA, kTheta, kD };
struct Entry {
  int joint;  // 0-based
  Field field;
};

std::vector<Entry> Layout(int N) {
  std::vector<Entry> layout = {{0, Field::kAlpha}};
  if (N >= 2) layout.insert(layout.end(), {{0, Field::kTheta}, {1, Field::kAlpha}, {1, Field::kA}});
  for (int i = 1; i < N - 1; ++i) {
    layout.insert(layout.end(),
                  {{i, Field::kTheta}, {i, Field::kD}, {i + 1, Field::kAlpha}, {i + 1, Field::kA}});
  }
  return layout;
}

bool IsLength(const Entry& e) { return e.field == Field::kA || e.field == Field::kD; }

std::vector<Dh> DhOf(int N, const ConstVectorRef& k) {
  std::vector<Dh> dh(static_cast<size_t>(N));
  const std::vector<Entry> layout = Layout(N);
  for (size_t i = 0; i < layout.size(); ++i) {
    Dh& j = dh[static_cast<size_t>(layout[i].joint)];
    double* field[] = {&j.alpha, &j.a, &j.theta, &j.d};
    *field[static_cast<int>(layout[i].field)] = k[static_cast<Eigen::Index>(i)];
  }
  return dh;
}

// Least squares of the inertial parameters (and friction) on the design A (rows scaled), with a
// ridge of 1e-9 of each column's own squared norm (at least 1e-12 of the mean one): the
// regressor has directions no motion shows, where this gives the minimum-norm answer and a cost
// that is smooth in the kinematics. Relative to each column, since the columns' norms spread
// over ten orders of magnitude (a light wrist link's inertias against a heavy link's mass on a
// joint scaled by its small torque): a ridge relative to the mean column would bias the light
// ones by far more than the noise.
Vector SolveNormal(Matrix G, const Vector& g) {
  const double floor =
      1e-12 * std::max(G.diagonal().mean(), std::numeric_limits<double>::min());
  G.diagonal().array() += 1e-9 * G.diagonal().array().max(floor);
  return G.ldlt().solve(g);
}

Vector Solve(const Matrix& A, const Vector& b) {
  return SolveNormal(A.transpose() * A, A.transpose() * b);
}

// The design of X's rows for chain: row i * N + j is joint j's torque regressor at row i, then
// viscous and Coulomb columns per joint when asked; each row divided by its joint's scale.
Matrix Design(const RigidBodyChain& chain, const ConstMatrixRef& X, const Vector& scale,
              const ChainIdentificationOptions& options) {
  const int N = chain.num_joints();
  const int P = chain.num_parameters();
  Matrix A = Matrix::Zero(X.rows() * N, P + (options.friction ? 2 * N : 0));
  RigidBodyChain::Workspace ws = chain.MakeWorkspace();
  Matrix regressor(N, P);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    chain.Regressor(X.row(i).segment(0, N).transpose(), X.row(i).segment(N, N).transpose(),
                    X.row(i).segment(2 * N, N).transpose(), RigidBodyChain::Terms::kAll,
                    regressor, ws);
    A.block(i * N, 0, N, P) = regressor;
    if (options.friction) {
      for (int j = 0; j < N; ++j) {
        const double qd = X(i, N + j);
        A(i * N + j, P + 2 * j) = qd;
        A(i * N + j, P + 2 * j + 1) = std::tanh(qd / options.friction_width);
      }
    }
  }
  for (Eigen::Index r = 0; r < A.rows(); ++r) A.row(r) /= scale[r % N];
  return A;
}

struct Search {
  int N;
  Matrix X;   // the search rows
  Vector y;   // their torques stacked row by row, each divided by its joint's scale
  Vector scale;
  const ChainIdentificationOptions* options;
};

// The scaled least-squares residual for the kinematics k; false where no chain is made of them.
bool Residual(const Search& s, const double* k, double* out) {
  Matrix A;
  try {
    const Eigen::Map<const Vector> kinematics(k, NumChainKinematicParameters(s.N));
    const RigidBodyChain chain = RigidBodyChain::FromUrdfString(ChainUrdf(s.N, kinematics));
    A = Design(chain, s.X, s.scale, *s.options);
  } catch (const std::logic_error&) {  // no chain of these numbers (a URDF or KDL check)
    return false;
  }
  Eigen::Map<Vector>(out, A.rows()) = s.y - A * Solve(A, s.y);
  return true;
}

struct ResidualFunctor {
  const Search* search;
  bool operator()(double const* const* parameters, double* residuals) const {
    return Residual(*search, parameters[0], residuals);
  }
};

// Lengths pulled towards 0 (weight at each length entry, 0 at the angles).
struct LengthPull {
  Vector weights;
  bool operator()(double const* const* parameters, double* residuals) const {
    for (Eigen::Index i = 0; i < weights.size(); ++i) residuals[i] = weights[i] * parameters[0][i];
    return true;
  }
};

// Starts drawn as arms are built: twists 0 or +-pi/2, angles about the axes a multiple of pi/2
// or anywhere, and each length 0 (intersecting or coplanar axes) or within 0.5 m, each half
// the time; the first axis vertical (tilt 0) or horizontal (tilt pi/2), three times in four
// vertical.
Vector RandomStart(int N, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> quarter(-1, 1), turn(-1, 2);
  std::bernoulli_distribution half(0.5), mostly(0.75);
  const std::vector<Entry> layout = Layout(N);
  Vector k(static_cast<Eigen::Index>(layout.size()));
  k[0] = mostly(*rng) ? 0.0 : M_PI / 2;  // the tilt
  for (size_t i = 1; i < layout.size(); ++i) {
    switch (layout[i].field) {
      case Field::kAlpha: k[static_cast<Eigen::Index>(i)] = M_PI / 2 * quarter(*rng); break;
      case Field::kTheta:
        k[static_cast<Eigen::Index>(i)] = half(*rng) ? M_PI / 2 * turn(*rng) : M_PI * u(*rng);
        break;
      case Field::kA:
      case Field::kD: k[static_cast<Eigen::Index>(i)] = half(*rng) ? 0.0 : 0.5 * u(*rng); break;
    }
  }
  return k;
}

// Levenberg-Marquardt from *k; the final cost (mean squared scaled residual), infinite when
// the start's chain cannot be evaluated.
double Minimise(const Search& search, int max_iterations, Vector* k) {
  ceres::Problem problem;
  auto* cost = new ceres::DynamicNumericDiffCostFunction<ResidualFunctor, ceres::FORWARD>(
      new ResidualFunctor{&search});
  cost->AddParameterBlock(static_cast<int>(k->size()));
  cost->SetNumResiduals(static_cast<int>(search.y.size()));
  problem.AddResidualBlock(cost, nullptr, k->data());
  // Lengths that no torque determines (the offsets along two parallel axes trade off, say)
  // stay small: a pull of 1e-6 per m^2 on the mean cost, a thousandth of a 1% residual's for
  // lengths of 0.3 m, the size of the minimum where they do show.
  const std::vector<Entry> layout = Layout(search.N);
  Vector weights(k->size());
  for (Eigen::Index i = 0; i < k->size(); ++i) {
    weights[i] = IsLength(layout[static_cast<size_t>(i)])
                     ? std::sqrt(1e-6 * static_cast<double>(search.y.size()))
                     : 0.0;
  }
  auto* pull = new ceres::DynamicNumericDiffCostFunction<LengthPull, ceres::FORWARD>(
      new LengthPull{weights});
  pull->AddParameterBlock(static_cast<int>(k->size()));
  pull->SetNumResiduals(static_cast<int>(k->size()));
  problem.AddResidualBlock(pull, nullptr, k->data());
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = max_iterations;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary result;
  ceres::Solve(solver, &problem, &result);
  if (!result.IsSolutionUsable() || !std::isfinite(result.final_cost)) {
    return std::numeric_limits<double>::infinity();
  }
  // The cost of the fit alone (without the pull), the angles in [-pi, pi].
  for (Eigen::Index i = 0; i < k->size(); ++i) {
    if (weights[i] == 0.0) (*k)[i] = std::remainder((*k)[i], 2.0 * M_PI);
  }
  std::vector<double> r(search.y.size());
  if (!Residual(search, k->data(), r.data())) return std::numeric_limits<double>::infinity();
  double sum = 0.0;
  for (double v : r) sum += v * v;
  return sum / static_cast<double>(r.size());
}

// Y's rows stacked (row i's joint j at i N + j), each joint divided by its scale: the right-hand
// side of Design's rows.
Vector StackScaled(const ConstMatrixRef& Y, const Vector& scale) {
  const Eigen::Index N = Y.cols();
  Vector y(Y.rows() * N);
  for (Eigen::Index i = 0; i < Y.rows(); ++i) {
    for (Eigen::Index j = 0; j < N; ++j) y[i * N + j] = Y(i, j) / scale[j];
  }
  return y;
}

// The rows of the search, their torques stacked and scaled.
void SetRows(const ConstMatrixRef& X, const ConstMatrixRef& Y, Eigen::Index count, Search* s) {
  const std::vector<int> rows = EvenlySpacedRows(X.rows(), std::min<Eigen::Index>(X.rows(), count));
  s->X = SelectRows(X, rows);
  s->y = StackScaled(SelectRows(Y, rows), s->scale);
}

// A robot name the URDF's XML can hold as written.
void CheckRobotName(const char* where, const std::string& name) {
  for (char c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) {
      throw std::invalid_argument(std::string(where) + ": robot name '" + name +
                                  "': letters, digits, '_', '-' and '.' only (it is written "
                                  "into the URDF)");
    }
  }
}

}  // namespace

int NumChainKinematicParameters(int num_joints) {
  if (num_joints < 1) throw std::invalid_argument("chain: at least one joint");
  return num_joints >= 2 ? 4 * num_joints - 4 : 1;
}

std::vector<std::string> ChainKinematicNames(int num_joints) {
  NumChainKinematicParameters(num_joints);  // checks num_joints
  static const char* const kFields[] = {"alpha", "a", "theta", "d"};
  std::vector<std::string> names;
  for (const Entry& e : Layout(num_joints)) {
    names.push_back(names.empty() ? std::string("tilt")
                                  : kFields[static_cast<int>(e.field)] + std::to_string(e.joint + 1));
  }
  return names;
}

std::string ChainUrdf(int num_joints, const ConstVectorRef& kinematics,
                      const std::string& robot_name) {
  const int N = num_joints;
  if (kinematics.size() != NumChainKinematicParameters(N)) {
    throw std::invalid_argument("ChainUrdf: " + std::to_string(kinematics.size()) +
                                " kinematic parameters, expected " +
                                std::to_string(NumChainKinematicParameters(N)) + " for " +
                                std::to_string(N) + " joints");
  }
  if (!kinematics.allFinite()) throw std::invalid_argument("ChainUrdf: a non-finite parameter");
  CheckRobotName("ChainUrdf", robot_name);
  const std::vector<Dh> dh = DhOf(N, kinematics);
  std::ostringstream os;
  os << "<?xml version=\"1.0\"?>\n"
     << "<!-- A serial chain identified from joint torques by structgp (structgp identify): its\n"
     << "     kinematics, modified Denavit-Hartenberg, joint i: alpha a theta d\n";
  for (int i = 0; i < N; ++i) {
    const Dh& j = dh[static_cast<size_t>(i)];
    os << "       joint" << i + 1 << " " << Num(j.alpha) << " " << Num(j.a) << " " << Num(j.theta)
       << " " << Num(j.d) << "\n";
  }
  os << "     The inertial values are placeholders (1 kg, 0.01 kg m^2 at each link's origin):\n"
     << "     the rbd models identify them from the data. -->\n"
     << "<robot name=\"" << robot_name << "\">\n  <link name=\"base\"/>\n";
  for (int i = 0; i < N; ++i) {
    const Dh& j = dh[static_cast<size_t>(i)];
    const KDL::Frame f = KDL::Frame(KDL::Rotation::RotX(j.alpha)) *
                         KDL::Frame(KDL::Vector(j.a, 0.0, 0.0)) *
                         KDL::Frame(KDL::Rotation::RotZ(j.theta)) *
                         KDL::Frame(KDL::Vector(0.0, 0.0, j.d));
    double roll = 0.0, pitch = 0.0, yaw = 0.0;
    f.M.GetRPY(roll, pitch, yaw);
    const std::string parent = i == 0 ? "base" : "link" + std::to_string(i);
    const std::string child = "link" + std::to_string(i + 1);
    os << "  <joint name=\"joint" << i + 1 << "\" type=\"continuous\">\n"
       << "    <parent link=\"" << parent << "\"/>\n    <child link=\"" << child << "\"/>\n"
       << "    <origin xyz=\"" << Num(f.p.x()) << " " << Num(f.p.y()) << " " << Num(f.p.z())
       << "\" rpy=\"" << Num(roll) << " " << Num(pitch) << " " << Num(yaw) << "\"/>\n"
       << "    <axis xyz=\"0 0 1\"/>\n  </joint>\n"
       << "  <link name=\"" << child << "\">\n    <inertial>\n"
       << "      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n      <mass value=\"1\"/>\n"
       << "      <inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/>\n"
       << "    </inertial>\n  </link>\n";
  }
  os << "</robot>\n";
  return os.str();
}

ChainIdentificationSummary IdentifyChain(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                         const ChainIdentificationOptions& options) {
  const int N = static_cast<int>(Y.cols());
  if (N < 1) throw std::invalid_argument("IdentifyChain: no torque columns");
  if (X.cols() != 3 * N) {
    throw std::invalid_argument("IdentifyChain: " + std::to_string(X.cols()) +
                                " input columns, expected 3 N = " + std::to_string(3 * N) +
                                " (q, qd, qdd of " + std::to_string(N) + " joints)");
  }
  if (X.rows() != Y.rows() || X.rows() < 2) {
    throw std::invalid_argument("IdentifyChain: " + std::to_string(X.rows()) + " input rows and " +
                                std::to_string(Y.rows()) +
                                " torque rows (equal, and at least 2)");
  }
  if (!X.allFinite() || !Y.allFinite()) {
    throw std::invalid_argument("IdentifyChain: a non-finite entry in the data");
  }
  if (!(options.friction_width > 0.0) || !std::isfinite(options.friction_width) ||
      options.search_rows < 2 || options.starts < 1 || options.max_iterations < 1 ||
      options.kept_starts < 1 || options.screen_rows < 2 || options.screen_iterations < 1 ||
      options.num_threads < 1) {
    throw std::invalid_argument(
        "IdentifyChain: options out of range (friction_width > 0, search_rows >= 2, starts >= 1, "
        "kept_starts >= 1, screen_rows >= 2, screen_iterations >= 1, "
        "max_iterations >= 1, num_threads >= 1)");
  }
  if (options.initial_kinematics.size() != 0 &&
      (options.initial_kinematics.size() != NumChainKinematicParameters(N) ||
       !options.initial_kinematics.allFinite())) {
    throw std::invalid_argument("IdentifyChain: initial_kinematics has " +
                                std::to_string(options.initial_kinematics.size()) +
                                " entries (finite), expected " +
                                std::to_string(NumChainKinematicParameters(N)));
  }
  CheckRobotName("IdentifyChain", options.robot_name);  // before the search, not after it
  // Each row gives N torques; 11 N inertial parameters (and 2 N friction coefficients) are
  // fitted on every set of rows: with fewer than twice as many torques any chain fits.
  const Eigen::Index unknowns = 11 * N + (options.friction ? 2 * N : 0);
  const Eigen::Index fewest =
      std::min<Eigen::Index>({X.rows(), options.search_rows,
                              options.kept_starts < options.starts ? options.screen_rows
                                                                   : options.search_rows});
  if (fewest * N < 2 * unknowns) {
    throw std::invalid_argument(
        "IdentifyChain: " + std::to_string(fewest) + " rows (of the data, search_rows or "
        "screen_rows) give " + std::to_string(fewest * N) + " torques for " +
        std::to_string(unknowns) + " linear parameters: at least " +
        std::to_string((2 * unknowns + N - 1) / N) + " rows are needed");
  }
  ChainIdentificationSummary summary;
  summary.torque_rms = (Y.colwise().squaredNorm() / static_cast<double>(Y.rows())).cwiseSqrt().transpose();
  for (int j = 0; j < N; ++j) {
    if (!(summary.torque_rms[j] > 0.0)) {
      throw std::invalid_argument("IdentifyChain: the torque of joint " + std::to_string(j + 1) +
                                  " is zero on every row");
    }
  }

  Search search;
  search.N = N;
  search.options = &options;
  search.scale = summary.torque_rms;

  // Screening: every random start a few iterations on few rows; the kept_starts of least cost
  // go on to the end on search_rows rows.
  std::mt19937_64 rng(options.seed);
  std::vector<Vector> found;
  for (int s = 0; s < options.starts; ++s) found.push_back(RandomStart(N, &rng));
  std::vector<double> screened(found.size(), std::numeric_limits<double>::infinity());
  auto run = [&](const std::vector<size_t>& which, int iterations, std::vector<double>* costs) {
    const int workers = std::max(1, std::min<int>(options.num_threads, static_cast<int>(which.size())));
    internal::RunWorkers(workers, [&](int w) {
      for (size_t i = static_cast<size_t>(w); i < which.size(); i += static_cast<size_t>(workers)) {
        (*costs)[which[i]] = Minimise(search, iterations, &found[which[i]]);
      }
    });
  };
  std::vector<size_t> all(found.size());
  std::iota(all.begin(), all.end(), size_t{0});
  std::vector<size_t> kept = all;
  if (options.kept_starts < options.starts) {
    SetRows(X, Y, options.screen_rows, &search);
    run(all, options.screen_iterations, &screened);
    std::stable_sort(kept.begin(), kept.end(),
                     [&](size_t a, size_t b) { return screened[a] < screened[b]; });
    kept.resize(static_cast<size_t>(options.kept_starts));
  }
  if (options.initial_kinematics.size() > 0) {
    found.push_back(options.initial_kinematics);
    kept.push_back(found.size() - 1);
  }
  SetRows(X, Y, options.search_rows, &search);
  std::vector<double> costs(found.size(), std::numeric_limits<double>::infinity());
  run(kept, options.max_iterations, &costs);
  for (size_t i : kept) {
    summary.starts.push_back(static_cast<int>(i));
    summary.start_costs.push_back(costs[i]);
  }
  const size_t winner = kept[static_cast<size_t>(
      std::min_element(summary.start_costs.begin(), summary.start_costs.end()) -
      summary.start_costs.begin())];
  summary.best_start = static_cast<int>(winner);
  const double best = costs[winner];
  if (!std::isfinite(best)) {
    throw std::runtime_error("IdentifyChain: no start gave a chain whose torques could be fitted");
  }
  for (double c : summary.start_costs) {
    summary.starts_at_best += c <= 1.01 * best + 1e-12 ? 1 : 0;  // noise-free logs: best ~ 0
  }
  summary.kinematics = found[winner];
  // Moves out of a local minimum: each length of the best chain set to 0 in turn (most arms
  // have intersecting or coplanar axes, which a search from a random start can miss) and the
  // search run again from there; a move that lowers the cost by 1% is kept.
  if (options.length_moves) {
    double cost = best;
    const std::vector<Entry> layout = Layout(N);
    for (Eigen::Index i = 0; i < summary.kinematics.size(); ++i) {
      if (!IsLength(layout[static_cast<size_t>(i)]) || std::abs(summary.kinematics[i]) < 0.02) {
        continue;
      }
      Vector moved = summary.kinematics;
      moved[i] = 0.0;
      const double c = Minimise(search, options.max_iterations, &moved);
      if (c < 0.99 * cost) {
        cost = c;
        summary.kinematics = moved;
        ++summary.moves_kept;
      }
    }
    summary.moved_cost = cost;
  }
  // The best start refined on more rows: the search rows' noise moves the minimum a little.
  if (options.refine_rows > options.search_rows && X.rows() > options.search_rows) {
    SetRows(X, Y, options.refine_rows, &search);
    Vector refined = summary.kinematics;
    summary.refined_cost = Minimise(search, options.max_iterations, &refined);
    if (std::isfinite(summary.refined_cost)) summary.kinematics = refined;
  }
  summary.urdf = ChainUrdf(N, summary.kinematics, options.robot_name);

  // The residual on every row with the identified kinematics: the normal equations and then
  // the residual block by block of rows (a long log's whole design would not fit in memory).
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(summary.urdf);
  constexpr Eigen::Index kBlock = 1000;
  auto block_rows = [&](Eigen::Index begin, Matrix* A, Vector* y) {
    const Eigen::Index n = std::min(kBlock, X.rows() - begin);
    *A = Design(chain, X.middleRows(begin, n), search.scale, options);
    *y = StackScaled(Y.middleRows(begin, n), search.scale);
  };
  Matrix A;
  Vector y;
  Matrix G;
  Vector g;
  for (Eigen::Index begin = 0; begin < X.rows(); begin += kBlock) {
    block_rows(begin, &A, &y);
    if (begin == 0) {
      G = A.transpose() * A;
      g = A.transpose() * y;
    } else {
      G.noalias() += A.transpose() * A;
      g.noalias() += A.transpose() * y;
    }
  }
  const Vector theta = SolveNormal(G, g);
  Vector sum = Vector::Zero(N);
  for (Eigen::Index begin = 0; begin < X.rows(); begin += kBlock) {
    block_rows(begin, &A, &y);
    const Vector r = y - A * theta;
    for (Eigen::Index k = 0; k < r.size(); ++k) sum[k % N] += r[k] * r[k];
  }
  summary.residual_rms.resize(N);
  for (int j = 0; j < N; ++j) {
    summary.residual_rms[j] = search.scale[j] * std::sqrt(sum[j] / static_cast<double>(X.rows()));
  }
  return summary;
}

}  // namespace structgp
