#include "structgp/fit/chain_identification.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <random>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <ceres/ceres.h>
#include <nlohmann/json.hpp>

#include "structgp/core/noise_level.h"
#include "structgp/core/row_subset.h"
#include "structgp/core/segments.h"
#include "structgp/feature/effects.h"
#include "structgp/feature/rigid_body_regressor_map.h"
#include "structgp/feature/semi_parametric_regressor_map.h"
#include "structgp/internal/workers.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {
namespace {

using Field = ChainKinematicParameter::Field;

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

// The regressor of the chain with the friction and effects of the options: the columns of the
// rbd model (RobotModel's, with "+fri" and the effects) that will use the identified URDF.
struct Columns {
  SemiParametricOptions options;  // friction, effects, with_time
};

// The design of X's rows for chain: row i * N + j is joint j's torque regressor at row i (the
// chain's inertial parameters, then friction and effects), each row divided by its joint's
// scale.
Matrix Design(const RigidBodyChain& chain, const ConstMatrixRef& X, const Vector& scale,
              const Columns& columns) {
  const int N = chain.num_joints();
  const SemiParametricRegressorMap map(std::make_shared<RigidBodyRegressorMap>(chain),
                                       columns.options);
  Matrix A(X.rows() * N, map.dim());
  const std::unique_ptr<RegressorMap::Scratch> scratch = map.MakeScratch();
  Matrix psi(N, map.dim());
  const Eigen::Index inputs = map.input_dim();
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    map.Evaluate(X.row(i).head(inputs).transpose(), psi, scratch.get());
    A.middleRows(i * N, N) = psi;
  }
  for (Eigen::Index r = 0; r < A.rows(); ++r) A.row(r) /= scale[r % N];
  return A;
}

struct Search {
  int N;
  Matrix X;   // the search rows
  Vector y;   // their torques stacked row by row, each divided by its joint's scale
  Vector scale;
  const Columns* columns;
};

// The scaled least-squares residual for the kinematics k; false where no chain is made of them.
bool Residual(const Search& s, const double* k, double* out) {
  Matrix A;
  try {
    const Eigen::Map<const Vector> kinematics(k, NumChainKinematicParameters(s.N));
    const RigidBodyChain chain = RigidBodyChain::FromUrdfString(ChainUrdf(s.N, kinematics));
    A = Design(chain, s.X, s.scale, *s.columns);
  } catch (const std::logic_error&) {  // no chain of these numbers (a URDF or KDL check)
    return false;
  }
  Eigen::Map<Vector>(out, A.rows()) = s.y - A * Solve(A, s.y);
  return true;
}

// Ceres's forward differences step by 1e-6 of each parameter's magnitude, which near 0 (a
// length pulled there, a tilt just off vertical) is too small a step to see the cost change
// (and a parameter there could never leave it): the solver holds every kinematic parameter
// shifted by kShift, and the cost functions take it off again, so that each step is 3e-6 to
// 6e-6 (angles in [-pi, pi], lengths within a few metres).
constexpr double kShift = 4.0;

struct ResidualFunctor {
  const Search* search;
  int size;
  bool operator()(double const* const* parameters, double* residuals) const {
    const Vector k = Eigen::Map<const Vector>(parameters[0], size).array() - kShift;
    return Residual(*search, k.data(), residuals);
  }
};

// The pull on what the torques leave free: each length towards 0 (w k), the tilt (entry 0)
// towards a horizontal axis 1 (w (1 - |sin k|)); weight 0 elsewhere.
struct Pull {
  Vector weights;
  bool operator()(double const* const* parameters, double* residuals) const {
    for (Eigen::Index i = 0; i < weights.size(); ++i) {
      const double k = parameters[0][i] - kShift;
      residuals[i] = weights[i] * (i == 0 ? 1.0 - std::abs(std::sin(k)) : k);
    }
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
  const std::vector<ChainKinematicParameter> layout = ChainKinematicLayout(N);
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
      new ResidualFunctor{&search, static_cast<int>(k->size())});
  cost->AddParameterBlock(static_cast<int>(k->size()));
  cost->SetNumResiduals(static_cast<int>(search.y.size()));
  // Lengths that no torque determines (the offsets along two parallel axes trade off, say)
  // stay small: a pull of 1e-6 per m^2 on the mean cost, a thousandth of a 1% residual's for
  // lengths of 0.3 m, the size of the minimum where they do show. The same weight on
  // 1 - |sin(tilt)|: when every axis is parallel to the first, gravity's torque only scales with
  // sin(tilt), which the first moments absorb, and a search from a vertical axis 1 stops just
  // off it, where the first moments must be huge to keep the cost (a chain that explains the
  // log, and that rbd's prior cannot hold). Where the torques show the tilt (any other arm),
  // this moves it by about 1e-6 / (the cost's curvature in it): 3e-4 rad on the three-link arm,
  // whose vertical first axis carries little torque.
  const std::vector<ChainKinematicParameter> layout = ChainKinematicLayout(search.N);
  const double weight = std::sqrt(1e-6 * static_cast<double>(search.y.size()));
  Vector weights(k->size());
  for (Eigen::Index i = 0; i < k->size(); ++i) {
    weights[i] = i == 0 || layout[static_cast<size_t>(i)].is_length() ? weight : 0.0;
  }
  auto* pull = new ceres::DynamicNumericDiffCostFunction<Pull, ceres::FORWARD>(new Pull{weights});
  pull->AddParameterBlock(static_cast<int>(k->size()));
  pull->SetNumResiduals(static_cast<int>(k->size()));
  Vector shifted = k->array() + kShift;
  problem.AddResidualBlock(cost, nullptr, shifted.data());
  problem.AddResidualBlock(pull, nullptr, shifted.data());
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
  *k = shifted.array() - kShift;
  // The cost of the fit alone (without the pull), the angles in [-pi, pi].
  for (Eigen::Index i = 0; i < k->size(); ++i) {
    if (!layout[static_cast<size_t>(i)].is_length()) (*k)[i] = std::remainder((*k)[i], 2.0 * M_PI);
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

// Per joint, the sum of squares of a vector stacked as Design's rows.
Vector JointSquares(const Vector& stacked, int N) {
  Vector sum = Vector::Zero(N);
  for (Eigen::Index r = 0; r < stacked.size(); ++r) sum[r % N] += stacked[r] * stacked[r];
  return sum;
}

// The rows of the search, their torques stacked and scaled.
void SetRows(const ConstMatrixRef& X, const ConstMatrixRef& Y, Eigen::Index count, Search* s) {
  const std::vector<int> rows = EvenlySpacedRows(X.rows(), std::min<Eigen::Index>(X.rows(), count));
  s->X = SelectRows(X, rows);
  s->y = StackScaled(SelectRows(Y, rows), s->scale);
}

// What the search rows determine of each kinematic parameter (the summary's cost_change,
// faster_change and undetermined): each moved alone by 0.1, the linear parameters fitted again.
void Determination(const Search& search, ChainIdentificationSummary* summary) {
  const int N = search.N;
  constexpr double kStep = 0.1, kFaster = 2.0;
  Matrix faster = search.X;
  faster.middleCols(N, N) *= kFaster;
  faster.middleCols(2 * N, N) *= kFaster * kFaster;
  // The cost on the search rows and the predicted torques of the faster rows (scaled, stacked).
  auto fit = [&](const Vector& k, double* cost, Vector* residual, Vector* fast) {
    const RigidBodyChain chain = RigidBodyChain::FromUrdfString(ChainUrdf(N, k));
    const Matrix A = Design(chain, search.X, search.scale, *search.columns);
    const Vector theta = Solve(A, search.y);
    *residual = search.y - A * theta;
    *cost = residual->squaredNorm() / static_cast<double>(residual->size());
    *fast = Design(chain, faster, search.scale, *search.columns) * theta;
  };
  const std::vector<ChainKinematicParameter> layout = ChainKinematicLayout(N);
  const Eigen::Index K = static_cast<Eigen::Index>(layout.size());
  summary->cost_change = Vector::Constant(K, std::numeric_limits<double>::quiet_NaN());
  summary->faster_change = summary->cost_change;
  double cost = 0.0;
  Vector residual, fast;
  try {
    fit(summary->kinematics, &cost, &residual, &fast);
  } catch (const std::logic_error&) {
    return;  // no chain of these numbers: nothing to say
  }
  const double rows = static_cast<double>(search.X.rows());
  const Vector noise = (JointSquares(residual, N) / rows).cwiseSqrt();  // the residual RMS
  for (Eigen::Index i = 0; i < K; ++i) {
    Vector moved = summary->kinematics;
    moved[i] += kStep;
    double moved_cost = 0.0;
    Vector moved_residual, moved_fast;
    try {
      fit(moved, &moved_cost, &moved_residual, &moved_fast);
    } catch (const std::logic_error&) {
      continue;
    }
    const Vector change = (JointSquares(moved_fast - fast, N) / rows).cwiseSqrt();
    summary->cost_change[i] = moved_cost / std::max(cost, std::numeric_limits<double>::min()) - 1.0;
    summary->faster_change[i] =
        (change.array() / noise.array().max(std::numeric_limits<double>::min())).maxCoeff();
    if (summary->cost_change[i] < 0.01 && summary->faster_change[i] > 1.0) {
      summary->undetermined.push_back(static_cast<int>(i));
    }
  }
}

// True when the finished chain leaves more than `ratio` times its residual's white noise on
// some joint (a smooth misfit).
bool Misfit(const ChainIdentificationSummary& summary, double ratio) {
  for (Eigen::Index j = 0; j < summary.residual_rms.size(); ++j) {
    if (summary.residual_rms[j] > ratio * summary.noise[j]) return true;
  }
  return false;
}

// The best start's chain finished: length moves and refinement from `kinematics` (cost `best`
// on the search rows), what the rows determine, the URDF, and the residual on every row with
// its white noise.
void Finish(const ConstMatrixRef& X, const ConstMatrixRef& Y,
            const ChainIdentificationOptions& options, const Columns& columns, double best,
            const Vector& kinematics, Search* search, ChainIdentificationSummary* summary) {
  const int N = search->N;
  summary->kinematics = kinematics;
  summary->moves_kept = 0;
  summary->moved_cost = std::numeric_limits<double>::quiet_NaN();
  summary->refined_cost = std::numeric_limits<double>::quiet_NaN();
  summary->undetermined.clear();
  SetRows(X, Y, options.search_rows, search);
  // Moves out of a local minimum: each length of the best chain set to 0 in turn (most arms
  // have intersecting or coplanar axes, which a search from a random start can miss) and the
  // search run again from there; a move that lowers the cost by 1% is kept.
  if (options.length_moves) {
    double cost = best;
    const std::vector<ChainKinematicParameter> layout = ChainKinematicLayout(N);
    for (Eigen::Index i = 0; i < summary->kinematics.size(); ++i) {
      if (!layout[static_cast<size_t>(i)].is_length() || std::abs(summary->kinematics[i]) < 0.02) {
        continue;
      }
      Vector moved = summary->kinematics;
      moved[i] = 0.0;
      const double c = Minimise(*search, options.max_iterations, &moved);
      if (c < 0.99 * cost) {
        cost = c;
        summary->kinematics = moved;
        ++summary->moves_kept;
      }
    }
    summary->moved_cost = cost;
  }
  // The best start refined on more rows: the search rows' noise moves the minimum a little.
  if (options.refine_rows > options.search_rows && X.rows() > options.search_rows) {
    SetRows(X, Y, options.refine_rows, search);
    Vector refined = summary->kinematics;
    summary->refined_cost = Minimise(*search, options.max_iterations, &refined);
    if (std::isfinite(summary->refined_cost)) summary->kinematics = refined;
  }
  Determination(*search, summary);
  summary->urdf = ChainUrdf(N, summary->kinematics, options.robot_name);

  // The residual on every row with the identified kinematics: the normal equations and then
  // the residual block by block of rows (a long log's whole design would not fit in memory).
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(summary->urdf);
  constexpr Eigen::Index kBlock = 1000;
  auto block_rows = [&](Eigen::Index begin, Matrix* A, Vector* y) {
    const Eigen::Index n = std::min(kBlock, X.rows() - begin);
    *A = Design(chain, X.middleRows(begin, n), search->scale, columns);
    *y = StackScaled(Y.middleRows(begin, n), search->scale);
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
  Matrix residual(X.rows(), N);  // row by row, in the torques' units
  for (Eigen::Index begin = 0; begin < X.rows(); begin += kBlock) {
    block_rows(begin, &A, &y);
    const Vector r = y - A * theta;
    for (Eigen::Index k = 0; k < r.size(); ++k) {
      residual(begin + k / N, k % N) = r[k] * search->scale[k % N];
    }
  }
  summary->residual_rms =
      (residual.colwise().squaredNorm() / static_cast<double>(X.rows())).cwiseSqrt().transpose();
  // The residual's white noise, within the log's trajectories when it has the time.
  const std::vector<int> segments =
      X.cols() == 3 * N + 1 ? SegmentStarts(X.col(3 * N)) : std::vector<int>{0};
  summary->noise.resize(N);
  for (int j = 0; j < N; ++j) summary->noise[j] = NoiseFromDifferences(residual.col(j), segments);
}

}  // namespace

ChainIdentificationSummary IdentifyChain(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                         const ChainIdentificationOptions& options) {
  const int N = static_cast<int>(Y.cols());
  if (N < 1) throw std::invalid_argument("IdentifyChain: no torque columns");
  if (X.cols() != 3 * N && X.cols() != 3 * N + 1) {
    throw std::invalid_argument("IdentifyChain: " + std::to_string(X.cols()) +
                                " input columns, expected 3 N = " + std::to_string(3 * N) +
                                " (q, qd, qdd of " + std::to_string(N) +
                                " joints), or 3 N + 1 with the time last");
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
      options.search_rows < 2 || options.starts < 0 || options.max_iterations < 1 ||
      options.kept_starts < 1 || options.screen_rows < 2 || options.screen_iterations < 1 ||
      options.max_rounds < 1 || !(options.misfit_ratio > 0.0) || options.num_threads < 1) {
    throw std::invalid_argument(
        "IdentifyChain: options out of range (friction_width > 0, search_rows >= 2, starts >= 0, "
        "kept_starts >= 1, screen_rows >= 2, screen_iterations >= 1, "
        "max_iterations >= 1, max_rounds >= 1, misfit_ratio > 0, num_threads >= 1)");
  }
  if (options.initial_kinematics.size() != 0 &&
      (options.initial_kinematics.size() != NumChainKinematicParameters(N) ||
       !options.initial_kinematics.allFinite())) {
    throw std::invalid_argument("IdentifyChain: initial_kinematics has " +
                                std::to_string(options.initial_kinematics.size()) +
                                " entries (finite), expected " +
                                std::to_string(NumChainKinematicParameters(N)));
  }
  if (options.starts == 0 && options.initial_kinematics.size() == 0) {
    throw std::invalid_argument(
        "IdentifyChain: starts = 0 (a local search) needs initial_kinematics to start from");
  }
  CheckRobotName("IdentifyChain", options.robot_name);  // before the search, not after it
  // The columns beside the chain's: friction and the effects, each on its joints.
  Columns columns;
  columns.options.friction = options.friction;
  columns.options.friction_width = options.friction_width;
  int effect_columns = 0;
  for (const EffectSpec& e : options.effects) {
    std::shared_ptr<const Effect> effect;
    try {
      effect = MakeEffect(e.name, e.params);
    } catch (const std::invalid_argument& error) {
      throw std::invalid_argument("IdentifyChain: effect '" + ToString(e) + "': " + error.what());
    }
    for (int j : e.joints) {
      if (j < 1 || j > N) {
        throw std::invalid_argument("IdentifyChain: effect '" + ToString(e) + "' names joint " +
                                    std::to_string(j) + ", but the robot has " +
                                    std::to_string(N) + " joints");
      }
    }
    if (effect->uses_time()) {
      if (X.cols() != 3 * N + 1) {
        throw std::invalid_argument("IdentifyChain: effect '" + ToString(e) +
                                    "' uses the time: X needs the time t as its last column");
      }
      columns.options.with_time = true;
    }
    const int joints = effect->joint_independent() ? 1
                       : e.joints.empty()         ? N
                                                  : static_cast<int>(e.joints.size());
    effect_columns += effect->num_bases() * joints;
    columns.options.effects.push_back({ToString(e), std::move(effect), e.joints});
  }
  // Each row gives N torques; 11 N inertial parameters (with friction 3 N coefficients, and the
  // effects' bases) are fitted on every set of rows: with fewer than twice as many torques any
  // chain fits.
  const Eigen::Index unknowns = 11 * N + (options.friction ? 3 * N : 0) + effect_columns;
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
  search.columns = &columns;
  search.scale = summary.torque_rms;

  // Rounds of starts: every random start of a round a few iterations on few rows (screening),
  // its kept_starts of least cost to the end on search_rows rows. Another round while fewer
  // than two kept starts have reached the best cost, or while the best chain, finished (length
  // moves, refinement, the residual on every row), leaves more than misfit_ratio times the
  // white noise of its residual on some joint.
  std::mt19937_64 rng(options.seed);
  auto run = [&](std::vector<Vector>* starts, int iterations, std::vector<double>* costs) {
    const int workers =
        std::max(1, std::min<int>(options.num_threads, static_cast<int>(starts->size())));
    internal::RunWorkers(workers, [&](int w) {
      for (size_t i = static_cast<size_t>(w); i < starts->size(); i += static_cast<size_t>(workers)) {
        (*costs)[i] = Minimise(search, iterations, &(*starts)[i]);
      }
    });
  };
  const bool screening = options.kept_starts < options.starts;
  double best = std::numeric_limits<double>::infinity();
  Vector best_kinematics;
  int finished_start = -2;  // the start whose chain was last finished (none yet)
  // Without random starts (a local search from initial_kinematics) one round is all there is.
  const int max_rounds = options.starts == 0 ? 1 : options.max_rounds;
  for (int round = 0; round < max_rounds; ++round) {
    std::vector<Vector> drawn;
    for (int s = 0; s < options.starts; ++s) drawn.push_back(RandomStart(N, &rng));
    std::vector<int> index(drawn.size());
    std::iota(index.begin(), index.end(), round * options.starts);
    if (screening) {
      SetRows(X, Y, options.screen_rows, &search);
      std::vector<double> screened(drawn.size(), std::numeric_limits<double>::infinity());
      run(&drawn, options.screen_iterations, &screened);
      std::vector<size_t> order(drawn.size());
      std::iota(order.begin(), order.end(), size_t{0});
      std::stable_sort(order.begin(), order.end(),
                       [&](size_t a, size_t b) { return screened[a] < screened[b]; });
      order.resize(static_cast<size_t>(options.kept_starts));
      std::vector<Vector> kept;
      std::vector<int> kept_index;
      for (size_t i : order) {
        kept.push_back(drawn[i]);
        kept_index.push_back(index[i]);
      }
      drawn = std::move(kept);
      index = std::move(kept_index);
    }
    if (round == 0 && options.initial_kinematics.size() > 0) {
      drawn.push_back(options.initial_kinematics);
      index.push_back(-1);
    }
    SetRows(X, Y, options.search_rows, &search);
    std::vector<double> costs(drawn.size(), std::numeric_limits<double>::infinity());
    run(&drawn, options.max_iterations, &costs);
    for (size_t i = 0; i < drawn.size(); ++i) {
      summary.starts.push_back(index[i]);
      summary.start_costs.push_back(costs[i]);
      if (costs[i] < best) {
        best = costs[i];
        summary.best_start = index[i];
        best_kinematics = drawn[i];
      }
    }
    summary.rounds = round + 1;
    summary.starts_at_best = 0;
    for (double c : summary.start_costs) {
      summary.starts_at_best += c <= 1.01 * best + 1e-12 ? 1 : 0;  // noise-free logs: best ~ 0
    }
    const bool last = round + 1 == max_rounds;
    if (!std::isfinite(best)) {
      if (last) {
        throw std::runtime_error(
            "IdentifyChain: no start gave a chain whose torques could be fitted");
      }
      continue;
    }
    if (summary.starts_at_best < 2 && !last) continue;
    if (summary.best_start != finished_start) {
      Finish(X, Y, options, columns, best, best_kinematics, &search, &summary);
      finished_start = summary.best_start;
    }
    if (last || !Misfit(summary, options.misfit_ratio)) break;
  }
  return summary;
}

ChainIdentificationSummary IdentifyChain(const ConstMatrixRef& states, const ConstVectorRef& t,
                                         const ConstMatrixRef& Y,
                                         const ChainIdentificationOptions& options) {
  if (t.size() == 0) return IdentifyChain(states, Y, options);
  if (t.size() != states.rows()) {
    throw std::invalid_argument("IdentifyChain: t has " + std::to_string(t.size()) +
                                " entries, expected one per row of the states (" +
                                std::to_string(states.rows()) + ")");
  }
  Matrix X(states.rows(), states.cols() + 1);
  X << states, t;
  return IdentifyChain(X, Y, options);
}

std::optional<ChainIdentificationOptions> SearchAgainOptions(const RigidBodyChain& chain,
                                                             const ModelSpec& spec,
                                                             double friction_width,
                                                             ChainIdentificationOptions search) {
  std::optional<Vector> kinematics = ChainKinematicsOf(chain);
  if (!kinematics) return std::nullopt;
  search.friction = spec.friction;
  search.effects = spec.effects;
  search.friction_width = friction_width;
  search.initial_kinematics = std::move(*kinematics);
  search.robot_name = chain.robot_name();
  return search;
}

double ChainIdentificationCost(const ChainIdentificationSummary& s) {
  if (std::isfinite(s.refined_cost)) return s.refined_cost;
  if (std::isfinite(s.moved_cost)) return s.moved_cost;
  double best = std::numeric_limits<double>::infinity();
  for (double c : s.start_costs) best = std::min(best, c);
  return best;
}

std::string ToJson(const ChainIdentificationSummary& s,
                   const ChainIdentificationOptions& options) {
  using Json = nlohmann::ordered_json;
  const int N = static_cast<int>(s.torque_rms.size());
  const std::vector<std::string> names = ChainKinematicNames(std::max(N, 1));
  auto by_name = [&](const Vector& values) {
    Json j = Json::object();
    for (size_t k = 0; k < names.size() && static_cast<Eigen::Index>(k) < values.size(); ++k) {
      const double v = values[static_cast<Eigen::Index>(k)];
      if (std::isfinite(v)) j[names[k]] = v;
    }
    return j;
  };
  Json doc;
  doc["friction"] = options.friction;
  doc["effects"] = ToString(options.effects);
  doc["starts"] = options.starts;
  doc["rounds"] = s.rounds;
  doc["kinematics"] = by_name(s.kinematics);
  doc["kept_starts"] = Json::array();
  for (int k : s.starts) doc["kept_starts"].push_back(k + 1);
  doc["start_costs"] = s.start_costs;
  doc["best_start"] = s.best_start + 1;
  doc["starts_at_best"] = s.starts_at_best;
  if (std::isfinite(s.moved_cost)) doc["moved_cost"] = s.moved_cost;
  doc["moves_kept"] = s.moves_kept;
  if (std::isfinite(s.refined_cost)) doc["refined_cost"] = s.refined_cost;
  doc["undetermined"] = Json::array();
  for (int k : s.undetermined) doc["undetermined"].push_back(names[static_cast<size_t>(k)]);
  doc["cost_change"] = by_name(s.cost_change);
  doc["faster_change"] = by_name(s.faster_change);
  doc["joints"] = Json::array();
  for (int j = 0; j < N; ++j) {
    doc["joints"].push_back({{"joint", j + 1},
                             {"torque_rms", s.torque_rms[j]},
                             {"residual_rms", s.residual_rms[j]},
                             {"noise", s.noise[j]}});
  }
  return doc.dump(2) + "\n";
}

}  // namespace structgp
