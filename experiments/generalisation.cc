// generalisation: slow -> fast on KDL-simulated arms, each model against the reference that
// knows the answer (docs/generalisation.md).
//
//   generalisation [--robots=two_link,three_link,puma560,panda] [--cases=none,friction,payload]
//                  [--models=reference,rbd+fri,rbd+fri/off30,lag+fri,pol+fri,rbf+fri]
//                  [--train-seconds=50] [--train-vias=50] [--noise=0.01] [--tests=2]
//                  [--size-by=train|default-slow]
//                  [--lagk-rows=800] [--lagk-hyper-rows=400] [--lagk-inducing=0]
//                  [--lagk-inducing-rule=cover|stride]
//                  [--lagk-sigmas=1,3,10,30,100] [--prior=gaussian|student_t|none]
//                  [--components] [--out=FILE.csv]
//                  [--quick] [--check]
//
// Per robot and case: a slow training log (--train-vias via points in --train-seconds, seed 1,
// 100 Hz: 5,000 rows by default) and --tests
// fast test logs (speed 2.5: velocities 2.5 and accelerations 6.25 times larger, seeds 2, 3,
// ...: other paths), torques by KDL's recursive Newton-Euler (sim::Simulate), noise per joint
// --noise times that joint's RMS noise-free training torque. Case "friction": viscous and
// Coulomb friction on every joint (Coulomb 10% of the joint's RMS torque, viscous 5% of it per
// RMS velocity, tanh width 0.01 rad/s), and the models are told (+fri). With
// --size-by=default-slow the RMS torques and velocities that size noise and friction are the
// default slow log's (50 via points in 50 s) whatever the training log.
//
// Models: "reference" is least squares (noise-weighted) on the true rigid-body regressor of the
// simulated chain (sim::ToUrdf -> RigidBodyChain, armature included) plus the true friction
// bases: what a model that knows the kinematics and the effect bases gets; every other model is
// fitted by the library's workflow with the CLI's defaults (FitModel, type-II maximum
// likelihood). Variants: "/joint" each joint its own hyper-parameters (FitOptions::per_joint:
// pol, motor, rbf, rbfs), "/chain" one GP per joint with joint J's PolChainKernel for pol,
// "/chain1" joint 1's on every joint. "lagk" is the library's EulerLagrangeGP (one GP for all joints on the
// Euler-Lagrange kernel, FitEulerLagrangeGP), "/link" with one weight per link's energies; its
// posterior is exact on --lagk-rows rows or, with --lagk-inducing=P, the DTC approximation
// through P inducing states on --lagk-rows rows, chosen to cover the states (or, with
// --lagk-inducing-rule=stride, evenly spaced in time); hyper-parameters on --lagk-hyper-rows
// evenly spaced of those rows either way.
// "lagk+fri/defaults" (or "lagk/defaults") is the same model as the product fits it:
// FitModel with the CLI's defaults (every row, through RobotModelOptions::batch.inducing_states
// inducing states; hyper-parameters on FitOptions::max_euler_lagrange_evidence_values / N rows).
// rbd and rbd+pol use the robot's URDF (armature not in it); "/off30" centres rbd's
// prior (rbd+pol: its prior mean) on inertial parameters each off by up to +-30%.
//
// Columns: test RMS / noise per joint (the mean over the test logs; 1.0 is a perfect model),
// the largest of them, the mean nMSE, the 2-sigma coverage of the noisy predictive band (worst
// joint), training rows and fit time. With --components, a second table splits each model's
// error into the gravity, inertial and velocity terms (ComponentRatios).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "experiment_program.h"
#include "structgp/core/row_subset.h"
#include "structgp/fit/fit_model.h"
#include "structgp/hyper/euler_lagrange_fit.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/internal/text.h"
#include "structgp/io/csv.h"
#include "structgp/kernel/pol_chain_kernel.h"
#include "structgp/kernel/sum_kernel.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/fit/chain_identification.h"
#include "structgp/rigid_body/physical_consistency.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"
#include "structgp/sim/urdf.h"

namespace structgp {
namespace {

using internal::Format;

int g_chain_threads = 1;
int g_chain_starts = ChainIdentificationOptions().starts;
int g_chain_rows = ChainIdentificationOptions().search_rows;
std::vector<double> g_chain_initial;

constexpr double kDt = 0.01;           // s
constexpr int kVias = 10;
constexpr double kRange = 1.0;         // rad
constexpr double kFastSpeed = 2.5;
constexpr double kTestSeconds = 10.0;
constexpr double kWidth = 0.01;        // rad/s, the friction tanh (the model's default too)

struct Flags {
  std::vector<std::string> robots{"two_link", "three_link", "puma560"};
  std::vector<std::string> cases{"none", "friction", "payload"};
  std::vector<std::string> models{"reference", "rbd+fri", "rbd+fri/off30", "lag+fri", "pol+fri",
                                  "rbf+fri"};
  double train_seconds = 50.0;
  int train_vias = 50;
  int train_rows = 0;  // 0: all
  std::string train_rows_rule = "even";  // or "random"
  int lagk_rows = 800;        // the Lagrangian kernel prototype's posterior rows
  int lagk_hyper_rows = 400;  // and its ML-II rows
  int lagk_inducing = 0;      // > 0: DTC posterior through this many inducing states
  int threads = 1;            // FitOptions::num_threads, batch and lagk's: the fits' threads
  std::string lagk_inducing_rule = "cover";  // or "stride"
  std::vector<double> lagk_sigmas = EulerLagrangeGPOptions().sigmas;
  std::string prior = "gaussian";  // of every type-II search (the CLI's --prior)
  bool calibrate_bands = true;     // FitOptions::calibrate_bands (the CLI's default)
  double band_coverage = 0.95;     // FitCheckOptions::target_coverage (the CLI's default)
  double noise = 0.01;
  // "train": noise and friction sized by the training log's RMS torques and velocities;
  // "default-slow": by the default slow log's (50 via points in 50 s), whatever the training
  // log, so that runs with other training motion keep the same noise and friction.
  std::string size_by = "train";
  int tests = 2;
  std::string out;
  bool quick = false;
  bool check = false;
  bool components = false;
  std::string write_logs;  // non-empty: each case's training and test logs go there as CSV
};

sim::Robot MakeRobot(const std::string& name) {
  try {
    return sim::RobotByName(name);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--robots: ") + e.what());
  }
}

// The chain of a simulated robot: with its armature (the truth), or as its URDF has it.
RigidBodyChain ChainOf(const sim::Robot& robot, bool with_armature) {
  if (with_armature) return sim::ToRigidBodyChain(robot);
  return RigidBodyChain::FromUrdfString(sim::ToUrdf(robot), {}, robot.name() + ".urdf");
}

struct Case {
  sim::Dataset train;
  std::vector<sim::Dataset> tests;
  std::vector<sim::TorqueComponents> test_components;  // the noise-free terms of each test log
  Vector noise;   // per joint, N m
  bool friction = false;
  std::shared_ptr<const RigidBodyChain> truth;  // the simulated chain (armature, payload)
};


constexpr double kPayload = 2.0;  // kg

Case MakeCase(const sim::Robot& dh_robot, const std::string& kind, const Flags& f) {
  const int N = dh_robot.num_joints();
  Case c;
  c.friction = kind == "friction";
  // "payload": 2 kg, 5 cm off the last link's origin along its z axis, unknown to the URDF.
  c.truth = std::make_shared<const RigidBodyChain>(
      kind == "payload" ? ChainOf(dh_robot, true).WithPayload(kPayload, {0.0, 0.0, 0.05})
                        : ChainOf(dh_robot, true));
  const sim::Robot robot = kind == "payload" ? sim::Robot::FromRigidBodyChain(*c.truth) : dh_robot;
  const bool friction = c.friction;
  const sim::Trajectory slow = sim::ViaPoints(N, f.train_seconds, kDt, f.train_vias, 1.0, kRange, 1);
  const Flags defaults;
  const sim::Trajectory sizing =
      f.size_by == "train" ? slow
                           : sim::ViaPoints(N, defaults.train_seconds, kDt, defaults.train_vias,
                                            1.0, kRange, 1);
  const sim::Dataset clean = sim::Simulate(robot, sizing);
  const Vector rms = (clean.Y.colwise().squaredNorm() / clean.Y.rows()).cwiseSqrt().transpose();
  const Vector qd_rms =
      (sizing.qd.colwise().squaredNorm() / sizing.qd.rows()).cwiseSqrt().transpose();
  sim::SimulationOptions options;
  if (friction) {
    std::vector<sim::JointFriction> joints(static_cast<size_t>(N));
    for (int j = 0; j < N; ++j) {
      joints[static_cast<size_t>(j)].coulomb = 0.1 * rms[j];
      joints[static_cast<size_t>(j)].viscous = 0.05 * rms[j] / std::max(qd_rms[j], 0.1);
      joints[static_cast<size_t>(j)].smoothing_velocity = kWidth;
    }
    options.friction = sim::FrictionModel(joints);
  }
  c.noise = f.noise * rms;
  auto simulate = [&](const sim::Trajectory& tr, std::uint64_t seed) {
    sim::SimulationOptions o = options;
    sim::Dataset d = sim::Simulate(robot, tr, o);
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    for (Eigen::Index i = 0; i < d.Y.rows(); ++i) {
      for (int j = 0; j < N; ++j) d.Y(i, j) += c.noise[j] * normal(rng);
    }
    return d;
  };
  c.train = simulate(slow, 1001);
  if (f.train_rows > 0 && f.train_rows < c.train.X.rows()) {
    // Fewer training rows: evenly spaced over the whole slow log (core/row_subset.h), or drawn
    // at random (a fixed seed, kept in time order). Evenly spaced rows can alias with the via
    // points: 50 or 100 of the 5,000 rows of a 50 s log with a via point a second fall on its
    // via points and midpoints, where every joint acceleration is zero.
    std::vector<int> rows = EvenlySpacedRows(c.train.X.rows(), f.train_rows);
    if (f.train_rows_rule == "random") {
      std::vector<int> all(static_cast<size_t>(c.train.X.rows()));
      for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
      std::mt19937_64 rng(77);
      std::shuffle(all.begin(), all.end(), rng);
      rows.assign(all.begin(), all.begin() + f.train_rows);
      std::sort(rows.begin(), rows.end());
    }
    c.train.X = SelectRows(c.train.X, rows);
    c.train.Y = SelectRows(c.train.Y, rows);
    c.train.t = SelectRows(c.train.t, rows);
  }
  for (int k = 0; k < f.tests; ++k) {
    const auto seed = static_cast<std::uint64_t>(2 + k);
    const sim::Trajectory fast = sim::ViaPoints(N, kTestSeconds, kDt, kVias, kFastSpeed, kRange, seed);
    c.tests.push_back(simulate(fast, 2001 + seed));
    c.test_components.push_back(sim::SimulateComponents(robot, fast, options));
  }
  return c;
}

// The case's logs as the CLI reads them (DIR/NAME_train.csv, DIR/NAME_test1.csv, ...), so that
// a row of the table can be reproduced with `structgp fit` and `structgp evaluate`.
void WriteLogs(const std::string& dir, const std::string& name, const Case& c) {
  WriteRobotCsv(dir + "/" + name + "_train.csv", sim::ToRobotData(c.train));
  for (std::size_t k = 0; k < c.tests.size(); ++k) {
    WriteRobotCsv(dir + "/" + name + "_test" + std::to_string(k + 1) + ".csv",
                  sim::ToRobotData(c.tests[k]));
  }
}

struct Prediction {
  Matrix mean, noisy_std;
};

struct Row {
  std::string robot, kase, model;
  Vector ratio;     // test RMS / noise per joint
  double nmse = 0;  // mean over joints and tests
  Vector coverage;  // 2-sigma coverage per joint
  int rows = 0;
  double seconds = 0;
  std::string note;
  // Models with rigid-body parameters (rbd, the reference): the identified parameters.
  bool identified = false;
  double parameter_error = 0;     // |pi_hat - pi| / |pi|
  double pd_fraction = 0;         // M(q) positive definite, of 1000 random configurations
  int consistent_links = 0;       // of N
  int directions = 0;             // identified directions (rbd)
  double last_mass_change = 0;    // identified minus URDF mass of the last link, kg
  // --components: test RMS error / noise per joint (columns) of the gravity, inertial and
  // velocity (Coriolis + friction) terms (rows), the mean over the test logs; empty otherwise.
  Matrix component_ratio;
  Matrix component_size;  // the true terms' RMS / noise, the same layout
};

constexpr const char* kComponentNames[] = {"gravity", "inertial", "velocity"};

// The model's terms read off its mean at modified states (exact for any model whose torque is
// M(q) qdd + h(q, qd) with h(q, 0) = G(q), lagk, pol and rbd among them): gravity at
// qd = qdd = 0, inertial at qd = 0 less gravity, velocity at qdd = 0 less gravity; against the
// simulation's own terms of each test log.
Matrix ComponentRatios(const Case& c, const std::function<Matrix(const Matrix&)>& mean) {
  const int N = static_cast<int>(c.noise.size());
  Matrix ratio = Matrix::Zero(3, N);
  for (size_t k = 0; k < c.tests.size(); ++k) {
    const Matrix& X = c.tests[k].X;
    Matrix X0 = X, Xa = X, Xv = X;
    X0.middleCols(N, 2 * N).setZero();
    Xa.middleCols(N, N).setZero();
    Xv.middleCols(2 * N, N).setZero();
    const Matrix g = mean(X0);
    const sim::TorqueComponents& truth = c.test_components[k];
    const Matrix err[3] = {g - truth.gravity, mean(Xa) - g - truth.inertial,
                           mean(Xv) - g - truth.coriolis - truth.friction};
    for (int r = 0; r < 3; ++r) {
      for (int j = 0; j < N; ++j) {
        ratio(r, j) += std::sqrt(err[r].col(j).squaredNorm() / static_cast<double>(X.rows())) /
                       c.noise[j] / static_cast<double>(c.tests.size());
      }
    }
  }
  return ratio;
}

// The true terms' RMS / noise per joint, the same layout: the errors of a model that predicts
// zero.
Matrix ComponentSizes(const Case& c) {
  return ComponentRatios(c, [N = c.noise.size()](const Matrix& X) {
    return Matrix(Matrix::Zero(X.rows(), N));
  });
}

// The identification columns of a row from the rigid-body parameters pi_hat.
void Identification(const Case& c, const RigidBodyChain& urdf, const Vector& pi_hat, Row* row) {
  const Vector& pi = c.truth->parameters();
  const int N = c.truth->num_joints();
  row->identified = true;
  row->parameter_error = (pi_hat - pi).norm() / pi.norm();
  const PhysicalConsistency pc = CheckPhysicalConsistency(*c.truth, pi_hat, 1000, 1);
  row->pd_fraction = pc.mass_matrix_pd_fraction;
  row->consistent_links = 0;
  for (const LinkConsistency& l : pc.links) row->consistent_links += l.ok() ? 1 : 0;
  row->last_mass_change = pi_hat[10 * (N - 1)] - urdf.parameters()[10 * (N - 1)];
}

// Stacked weighted least squares on the true regressor and friction bases.
class Reference {
 public:
  Reference(const RigidBodyChain& truth, bool friction, const Vector& noise)
      : chain_(truth), friction_(friction), noise_(noise) {}
  int dim() const { return chain_.num_parameters() + (friction_ ? 2 * chain_.num_joints() : 0); }
  Matrix Psi(const Vector& x) const {
    const int N = chain_.num_joints();
    Matrix psi = Matrix::Zero(N, dim());
    psi.leftCols(chain_.num_parameters()) =
        chain_.Regressor(x.head(N), x.segment(N, N), x.segment(2 * N, N));
    if (friction_) {
      for (int j = 0; j < N; ++j) {
        psi(j, chain_.num_parameters() + 2 * j) = x[N + j];
        psi(j, chain_.num_parameters() + 2 * j + 1) = std::tanh(x[N + j] / kWidth);
      }
    }
    return psi;
  }
  void Fit(const Matrix& X, const Matrix& Y) {
    const int N = chain_.num_joints();
    Matrix A(X.rows() * N, dim());
    Vector b(X.rows() * N);
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
      const Matrix psi = Psi(X.row(i).transpose());
      for (int j = 0; j < N; ++j) {
        A.row(i * N + j) = psi.row(j) / noise_[j];
        b[i * N + j] = Y(i, j) / noise_[j];
      }
    }
    theta_ = A.colPivHouseholderQr().solve(b);
  }
  const Vector& theta() const { return theta_; }
  Prediction Predict(const Matrix& X) const {
    const int N = chain_.num_joints();
    Prediction p{Matrix(X.rows(), N), Matrix(X.rows(), N)};
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
      p.mean.row(i) = (Psi(X.row(i).transpose()) * theta_).transpose();
      p.noisy_std.row(i) = noise_.transpose();  // the parameters' own variance is negligible
    }
    return p;
  }

 private:
  RigidBodyChain chain_;
  bool friction_;
  Vector noise_;
  Vector theta_;
};

Prediction PredictModel(const RobotModel& model, const Matrix& X) {
  const int N = model.num_joints();
  Prediction p{Matrix(X.rows(), N), Matrix(X.rows(), N)};
  RobotModel::Workspace ws = model.MakeWorkspace();
  Vector mean(N), latent(N), noisy(N);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    if (model.PredictWithVariance(X.row(i).transpose(), mean, latent, noisy, ws) != Status::kOk) {
      throw std::runtime_error("prediction failed at test row " + std::to_string(i));
    }
    p.mean.row(i) = mean.transpose();
    p.noisy_std.row(i) = noisy.cwiseSqrt().transpose();
  }
  return p;
}

void Score(const Case& c, const std::vector<Prediction>& predictions, Row* row) {
  const int N = static_cast<int>(c.noise.size());
  row->ratio = Vector::Zero(N);
  row->coverage = Vector::Zero(N);
  row->nmse = 0.0;
  Vector counted = Vector::Zero(N);
  for (size_t k = 0; k < c.tests.size(); ++k) {
    const Matrix& Y = c.tests[k].Y;
    const Prediction& p = predictions[k];
    const Matrix err = p.mean - Y;
    for (int j = 0; j < N; ++j) {
      const double mse = err.col(j).squaredNorm() / Y.rows();
      row->ratio[j] += std::sqrt(mse) / c.noise[j] / static_cast<double>(c.tests.size());
      const double mean = Y.col(j).mean();
      const double var = (Y.col(j).array() - mean).square().mean();
      row->nmse += mse / var / (N * static_cast<double>(c.tests.size()));
      // Rows without a predictive std (NaN: not computed) are not counted.
      row->coverage[j] += static_cast<double>(
          (err.col(j).array().abs() <= 2.0 * p.noisy_std.col(j).array()).count());
      counted[j] += static_cast<double>(p.noisy_std.col(j).array().isFinite().count());
    }
  }
  row->coverage = row->coverage.cwiseQuotient(counted.cwiseMax(1.0));
}

std::string Join(const Vector& v, const char* format) {
  std::string out;
  for (Eigen::Index i = 0; i < v.size(); ++i) out += (i ? " " : "") + Format(format, v[i]);
  return out;
}

// Variant "/chain" of pol: one single-output GP per joint, each with its own kernel parameters,
// noise and scale by type-II maximum likelihood (the library's evidence options and row limits),
// pol's kernel replaced by joint J's PolChainKernel; "/chain1": by joint 1's on every joint (only
// q_1 dropped from the inertial and Coriolis terms). ("/joint", each joint its own
// hyper-parameters with the kernel unchanged, is the product's FitOptions::per_joint.)
std::vector<Prediction> PerJointKernels(const ModelSpec& spec, const std::string& variant,
                                        const Case& c, Row* row) {
  const int N = c.train.num_joints();
  RobotModelOptions model_options;
  model_options.max_explicit_features = 1;  // pol as its kernel at every N
  const RobotModel model(spec, N, model_options);
  if (model.kernel() == nullptr) {
    throw std::invalid_argument("--models: /chain needs pol as its kernel");
  }
  const Kernel& full = *model.kernel();
  const FitOptions defaults;
  const Matrix& X = c.train.X;
  const Matrix& Y = c.train.Y;
  const std::vector<int> hyper_rows = EvenlySpacedRows(X.rows(), defaults.max_evidence_rows);
  const std::vector<int> gp_rows = EvenlySpacedRows(X.rows(), RobotModelOptions().batch.max_kernel_rows);
  const Matrix Xs = SelectRows(X, hyper_rows), Ys = SelectRows(Y, hyper_rows);
  const Matrix Xg = SelectRows(X, gp_rows), Yg = SelectRows(Y, gp_rows);
  const Hyperparameters start = model.DefaultHyperparameters(Y);
  std::vector<Prediction> predictions;
  for (const auto& t : c.tests) {
    predictions.push_back({Matrix(t.X.rows(), N), Matrix(t.X.rows(), N)});
  }
  std::string notes;
  for (int j = 0; j < N; ++j) {
    const PolChainKernel joint_kernel(N, variant == "chain1" ? 1 : j + 1);
    const auto* sum = dynamic_cast<const SumKernel*>(&full);
    const std::unique_ptr<Kernel> kernel =
        sum ? std::make_unique<SumKernel>(std::vector<const Kernel*>{&joint_kernel, &sum->part(1)})
            : joint_kernel.Clone();
    Hyperparameters h = start.Output(j);
    const MaximumLikelihoodSummary s =
        FitKernelHyperparameters(*kernel, Xs, Ys.col(j), defaults.evidence, &h);
    if (!s.usable()) throw std::runtime_error("joint " + std::to_string(j + 1) + ": " + s.message);
    KernelGP gp(*kernel->WithParameters(h.shape), h.noise_variance(), 1, h.output_scales());
    if (gp.Fit(Xg, Yg.col(j)) != Status::kOk) {
      throw std::runtime_error("joint " + std::to_string(j + 1) + ": the kernel GP did not factorise");
    }
    Vector mean(1), latent(1), noisy(1);
    for (size_t k = 0; k < c.tests.size(); ++k) {
      const Matrix& T = c.tests[k].X;
      for (Eigen::Index i = 0; i < T.rows(); ++i) {
        if (gp.PredictWithVariance(T.row(i).transpose(), mean, latent, noisy) != Status::kOk) {
          throw std::runtime_error("prediction failed at test row " + std::to_string(i));
        }
        predictions[k].mean(i, j) = mean[0];
        predictions[k].noisy_std(i, j) = std::sqrt(noisy[0]);
      }
    }
    notes += Format("%sJ%d sigma %.3g", j ? ", " : "", j + 1, std::exp(h.shape[0]));
  }
  row->rows = static_cast<int>(gp_rows.size());
  row->note = "one GP per joint (" + notes + ")";
  return predictions;
}

// The chain `structgp identify` finds from the case's training log (--chain-* flags), and the
// search's outcome in words.
std::shared_ptr<const RigidBodyChain> IdentifiedChain(const Case& c, bool friction,
                                                      std::string* note) {
  ChainIdentificationOptions o;
  o.friction = friction;
  o.num_threads = g_chain_threads;
  o.starts = g_chain_starts;
  o.search_rows = g_chain_rows;
  if (!g_chain_initial.empty()) {
    o.initial_kinematics = Eigen::Map<const Vector>(
        g_chain_initial.data(), static_cast<Eigen::Index>(g_chain_initial.size()));
  }
  const ChainIdentificationSummary id = IdentifyChain(c.train.X, c.train.Y, o);
  std::vector<double> sorted = id.start_costs;
  std::sort(sorted.begin(), sorted.end());
  *note = Format("; identify: best of %d starts (%d at it), costs %s; kinematics %s",
                 static_cast<int>(sorted.size()), id.starts_at_best,
                 Join(Eigen::Map<const Vector>(sorted.data(),
                                               static_cast<Eigen::Index>(sorted.size())),
                      "%.3g")
                     .c_str(),
                 Join(id.kinematics, "%.3f").c_str());
  return std::make_shared<const RigidBodyChain>(RigidBodyChain::FromUrdfString(id.urdf));
}

Row RunModel(const std::string& robot_name, const std::string& case_name, const std::string& name,
             const sim::Robot& robot, const Case& c, int lagk_rows, int lagk_hyper_rows,
             const EulerLagrangeGPOptions& lagk_options, bool components,
             bool calibrate_bands, double band_coverage) {
  Row row;
  row.robot = robot_name;
  row.kase = case_name;
  row.model = name;
  row.rows = static_cast<int>(c.train.X.rows());
  const auto start = std::chrono::steady_clock::now();
  std::vector<Prediction> predictions;
  if (name == "lagk" || name == "lagk+fri" || name == "lagk/link" || name == "lagk+fri/link") {
    // One GP on the Euler-Lagrange kernel (hyper/euler_lagrange_fit.h) on evenly spaced rows.
    const int m = std::min(static_cast<int>(c.train.X.rows()), lagk_rows);
    const std::vector<int> rows = EvenlySpacedRows(c.train.X.rows(), m);
    const bool friction = c.friction && name.rfind("lagk+fri", 0) == 0;
    const bool per_link = name.find("/link") != std::string::npos;
    row.model = std::string(friction ? "lagk+fri" : "lagk") + (per_link ? "/link" : "");
    EulerLagrangeGPOptions options = lagk_options;
    options.friction = friction;
    options.per_link = per_link;
    options.hyperparameter_rows = std::min(m, lagk_hyper_rows);
    std::optional<EulerLagrangeGP> gp;
    const EulerLagrangeGPSummary summary = FitEulerLagrangeGP(
        SelectRows(c.train.X, rows), SelectRows(c.train.Y, rows), options, &gp);
    for (size_t k = 0; k < summary.sigmas.size(); ++k) {
      std::printf("    %s sigma %.2g: log evidence %.6g\n", row.model.c_str(), summary.sigmas[k],
                  summary.log_evidence_per_sigma[k]);
    }
    std::fflush(stdout);
    if (!gp) throw std::runtime_error(row.model + ": " + summary.message);
    row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    row.rows = m;
    const EulerLagrangeGPHyperparameters& h = summary.hyperparameters;
    row.note = Format("one GP for every joint, Euler-Lagrange kernel (sigma %.3g, weights %s; "
                      "ML-II on %d rows%s)",
                      h.sigma, Join(h.part_weights, "%.2g").c_str(), summary.hyperparameter_rows,
                      summary.inducing_states > 0
                          ? Format("; DTC, %d inducing states", summary.inducing_states).c_str()
                          : "");
    for (const auto& t : c.tests) {
      // The mean on every row; the band on every 10th (its cost is a solve per row).
      Prediction p;
      if (!IsOk(gp->Predict(t.X, &p.mean))) throw std::runtime_error("lagk: bad test states");
      const std::vector<int> strided = EvenlySpacedRows(t.X.rows(), (t.X.rows() + 9) / 10);
      Matrix mean, latent;
      if (!IsOk(gp->Predict(SelectRows(t.X, strided), &mean, &latent))) {
        throw std::runtime_error("lagk: bad test states");
      }
      p.noisy_std.setConstant(t.X.rows(), h.num_joints(), std::nan(""));
      for (size_t r = 0; r < strided.size(); ++r) {
        for (int j = 0; j < h.num_joints(); ++j) {
          p.noisy_std(strided[r], j) =
              std::sqrt(latent(static_cast<Eigen::Index>(r), j) + h.noise_std[j] * h.noise_std[j]);
        }
      }
      predictions.push_back(p);
    }
    if (components) {
      row.component_ratio = ComponentRatios(c, [&gp](const Matrix& X) {
        Matrix out;
        if (!IsOk(gp->Predict(X, &out))) throw std::runtime_error("lagk: bad states");
        return out;
      });
    }
  } else if (name == "reference") {
    Reference reference(*c.truth, c.friction, c.noise);
    reference.Fit(c.train.X, c.train.Y);
    row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    for (const auto& t : c.tests) predictions.push_back(reference.Predict(t.X));
    Identification(c, *c.truth, reference.theta().head(c.truth->num_parameters()), &row);
    if (components) {
      row.component_ratio =
          ComponentRatios(c, [&](const Matrix& X) { return reference.Predict(X).mean; });
    }
  } else {
    std::string spec_text = name;
    bool off = false;
    const auto slash = name.find('/');
    std::string variant;
    if (slash != std::string::npos) {
      variant = name.substr(slash + 1);
      if (variant != "off30" && variant != "joint" && variant != "chain" &&
          variant != "chain1" && variant != "defaults") {
        throw std::invalid_argument("--models: unknown variant '" + name +
                                    "' (expected /off30, /joint, /chain, /chain1 or /defaults)");
      }
      spec_text = name.substr(0, slash);
      off = variant == "off30";
    }
    // "chain" and "chain+fri": the product's path for a robot without a URDF, `structgp
    // identify` on the training log, then rbd on the URDF it wrote.
    const bool identified = spec_text == "chain" || spec_text == "chain+fri";
    if (identified) spec_text = spec_text == "chain+fri" ? "rbd+fri" : "rbd";
    ModelSpec spec = ParseModelSpec(spec_text);
    if (!c.friction) spec.friction = false;  // the models are told which effects there are
    row.model = identified ? (spec.friction ? "chain+fri" : "chain")
                           : ToString(spec) + (variant.empty() ? "" : "/" + variant);
    if (variant == "chain" || variant == "chain1") {
      if (spec.base != BaseModel::kPol) {
        throw std::invalid_argument("--models: /chain is a variant of pol");
      }
      predictions = PerJointKernels(spec, variant, c, &row);
      row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      Score(c, predictions, &row);
      return row;
    }
    FitOptions options;
    options.per_joint = variant == "joint";
    options.calibrate_bands = calibrate_bands;       // --no-calibrate-bands
    options.check.target_coverage = band_coverage;  // --band-coverage
    options.evidence.prior.family = lagk_options.prior.family;  // --prior, for every search
    options.num_threads = lagk_options.num_threads;              // --threads
    options.model.batch.num_threads = lagk_options.num_threads;
    std::string identify_note;
    if (identified) {
      options.model.rigid_body = IdentifiedChain(c, spec.friction, &identify_note);
    } else if (spec.base == BaseModel::kRbd || spec.rigid_body_features) {
      RigidBodyChain chain = ChainOf(robot, false);
      if (off) {
        std::mt19937_64 rng(5);
        std::uniform_real_distribution<double> u(-0.3, 0.3);
        Vector pi = chain.parameters();
        for (Eigen::Index k = 0; k < pi.size(); ++k) pi[k] *= 1.0 + u(rng);
        chain = chain.WithParameters(pi);
      }
      options.model.rigid_body = std::make_shared<const RigidBodyChain>(chain);
    }
    FittedModel fitted{RobotModel(ParseModelSpec("motor"), c.train.num_joints()), {}};
    try {
      fitted = FitModel(spec, c.train.X, c.train.Y, Vector(), options);
    } catch (const std::invalid_argument& e) {
      row.note = std::string("not available: ") + e.what();
      return row;
    }
    row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!fitted.summary.IsUsable()) {
      row.note = "fit failed: " + fitted.summary.message;
      return row;
    }
    row.note = fitted.summary.method_description + identify_note;
    row.rows = fitted.summary.model_rows;
    for (const auto& t : c.tests) predictions.push_back(PredictModel(fitted.model, t.X));
    if (components) {
      row.component_ratio =
          ComponentRatios(c, [&](const Matrix& X) { return PredictModel(fitted.model, X).mean; });
    }
    const RegressorGP* gp = fitted.model.gp().regressor();
    if (gp != nullptr && spec.base == BaseModel::kRbd && !identified) {  // the truth's chain
      Identification(c, *options.model.rigid_body, gp->parameters().head(c.truth->num_parameters()),
                     &row);
      row.directions = gp->IdentifiedDirections();
    }
  }
  Score(c, predictions, &row);
  return row;
}

int Run(const Flags& flags, int argc, char** argv) {
  Flags f = flags;
  if (f.quick) {
    f.robots = {"two_link"};
    f.cases = {"friction"};
    f.models = {"reference", "rbd+fri", "rbd+fri/off30"};
    f.train_seconds = 20.0;
    f.train_vias = 20;
    f.tests = 1;
  }
  EulerLagrangeGPOptions lagk_options;
  lagk_options.inducing_states = f.lagk_inducing;
  lagk_options.inducing_rule = f.lagk_inducing_rule == "stride"
                                   ? EulerLagrangeGPOptions::InducingRule::kEvenlySpaced
                                   : EulerLagrangeGPOptions::InducingRule::kCoverStates;
  lagk_options.sigmas = f.lagk_sigmas;
  lagk_options.num_threads = f.threads;
  g_chain_threads = f.threads;
  if (!FromString(f.prior, &lagk_options.prior.family)) {
    throw std::invalid_argument("--prior: expected gaussian, student_t or none, got '" + f.prior + "'");
  }
  std::vector<Row> rows;
  std::printf("| robot | case | model | test RMS / noise per joint | max | mean nMSE | 2σ coverage "
              "per joint | rows | fit s | hyper-parameters |\n|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& robot_name : f.robots) {
    const sim::Robot robot = MakeRobot(robot_name);
    for (const std::string& case_name : f.cases) {
      if (case_name != "none" && case_name != "friction" && case_name != "payload") {
        throw std::invalid_argument("--cases: unknown case '" + case_name +
                                    "' (expected none, friction, payload)");
      }
      const Case c = MakeCase(robot, case_name, f);
      if (!f.write_logs.empty()) WriteLogs(f.write_logs, robot_name + "_" + case_name, c);
      for (const std::string& model : f.models) {
        Row row = RunModel(robot_name, case_name, model, robot, c, f.lagk_rows,
                           f.lagk_hyper_rows, lagk_options, f.components,
                           f.calibrate_bands, f.band_coverage);
        if (f.components) row.component_size = ComponentSizes(c);
        std::printf("| %s | %s | %s | %s | %s | %s | %s | %d | %.1f | %s |\n", row.robot.c_str(),
                    row.kase.c_str(), row.model.c_str(),
                    row.ratio.size() ? Join(row.ratio, "%.3g").c_str() : "-",
                    row.ratio.size() ? Format("%.3g", row.ratio.maxCoeff()).c_str() : "-",
                    row.ratio.size() ? Format("%.3g", row.nmse).c_str() : "-",
                    row.coverage.size() ? Join(100 * row.coverage, "%.0f%%").c_str() : "-",
                    row.rows, row.seconds, row.note.c_str());
        std::fflush(stdout);
        rows.push_back(row);
      }
    }
  }
  if (f.components) {
    std::printf("\nThe fast test logs' terms: the true term's RMS / noise (\"true size\"), then "
                "each model's error on it, RMS / noise per joint (velocity: Coriolis and "
                "centrifugal + friction):\n\n| robot | case | model | term | per joint | max "
                "|\n|---|---|---|---|---|---|\n");
    std::string last_case;
    for (const Row& r : rows) {
      if (r.robot + "/" + r.kase != last_case) {
        last_case = r.robot + "/" + r.kase;
        const Matrix& size = r.component_size;
        for (int t = 0; t < 3; ++t) {
          std::printf("| %s | %s | true size | %s | %s | %.3g |\n", r.robot.c_str(),
                      r.kase.c_str(), kComponentNames[t], Join(size.row(t).transpose(), "%.3g").c_str(),
                      size.row(t).maxCoeff());
        }
      }
      if (r.component_ratio.size() == 0) continue;
      for (int t = 0; t < 3; ++t) {
        std::printf("| %s | %s | %s | %s | %s | %.3g |\n", r.robot.c_str(), r.kase.c_str(),
                    r.model.c_str(), kComponentNames[t],
                    Join(r.component_ratio.row(t).transpose(), "%.3g").c_str(),
                    r.component_ratio.row(t).maxCoeff());
      }
    }
  }
  std::printf("\nIdentified rigid-body parameters (rbd: posterior mean; reference: least "
              "squares):\n\n| robot | case | model | parameter error | M(q) PD | consistent "
              "links | identified directions | last link mass change, kg |\n"
              "|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : rows) {
    if (!r.identified) continue;
    std::printf("| %s | %s | %s | %.3g | %.1f%% | %d of %d | %s | %+.3g |\n", r.robot.c_str(),
                r.kase.c_str(), r.model.c_str(), r.parameter_error, 100 * r.pd_fraction,
                r.consistent_links, static_cast<int>(r.ratio.size()),
                r.directions ? std::to_string(r.directions).c_str() : "-", r.last_mass_change);
  }
  if (!f.out.empty()) {
    std::ofstream out(f.out);
    out << "# " << CommandLine("generalisation", argc, argv) << "\n";
    out << "robot,case,model,joint,rms_over_noise,coverage,nmse_mean,rows,fit_seconds\n";
    for (const Row& r : rows) {
      for (Eigen::Index j = 0; j < r.ratio.size(); ++j) {
        out << r.robot << "," << r.kase << "," << r.model << "," << j + 1 << ","
            << Format("%.6g", r.ratio[j]) << "," << Format("%.6g", r.coverage[j]) << ","
            << Format("%.6g", r.nmse) << "," << r.rows << "," << Format("%.3f", r.seconds)
            << "\n";
      }
    }
  }
  if (f.check) {
    // rbd with the right effects must predict the fast motion within 1.1x of the noise; the
    // Euler-Lagrange prototype within 8x (three-link, 400 rows: 5.3; pol+fri there: 22).
    for (const Row& r : rows) {
      const double limit = r.model.rfind("rbd", 0) == 0 ? 1.1
                           : r.model.rfind("lagk", 0) == 0 ? 8.0
                                                            : INFINITY;
      if (std::isfinite(limit) && (r.ratio.size() == 0 || r.ratio.maxCoeff() > limit)) {
        std::fprintf(stderr, "generalisation: check failed: %s on %s/%s\n", r.model.c_str(),
                     r.robot.c_str(), r.kase.c_str());
        return 3;
      }
    }
  }
  return 0;
}

}  // namespace
}  // namespace structgp

int main(int argc, char** argv) {
  CLI::App app("Slow -> fast generalisation on KDL-simulated arms (docs/generalisation.md)",
               "generalisation");
  structgp::Flags f;
  structgp::AddListFlag(&app, "--robots", &f.robots, "two_link, three_link, puma560, panda, random4 and random7 (sim::RandomRobot(N, 1))");
  structgp::AddListFlag(&app, "--cases", &f.cases, "none, friction, payload");
  structgp::AddListFlag(&app, "--models", &f.models,
                        "reference, or a model (rbd+fri, pol+fri, rbf+fri, ...), /off30 for rbd "
                        "with inertial parameters off by up to 30%");
  structgp::AddFlag(&app, "--train-seconds", &f.train_seconds, "length of the slow log, s")
      ->check(structgp::GreaterThan(0));
  structgp::AddFlag(&app, "--train-vias", &f.train_vias, "via points of the slow log")
      ->check(structgp::AtLeast(2));
  structgp::AddFlag(&app, "--train-rows", &f.train_rows,
                    "keep this many evenly spaced rows of the slow log (0: all)")
      ->check(structgp::AtLeast(0));
  app.add_option("--train-rows-rule", f.train_rows_rule,
                 "how --train-rows picks its rows: even (evenly spaced) or random (a fixed seed)")
      ->check(CLI::IsMember({"even", "random"}));
  structgp::AddFlag(&app, "--lagk-rows", &f.lagk_rows,
                    "rows of the Lagrangian kernel prototype lagk's posterior")
      ->check(structgp::AtLeast(2));
  structgp::AddFlag(&app, "--lagk-hyper-rows", &f.lagk_hyper_rows,
                    "rows of lagk's type-II maximum likelihood")
      ->check(structgp::AtLeast(2));
  structgp::AddFlag(&app, "--lagk-inducing", &f.lagk_inducing,
                    "lagk's posterior through this many inducing states (DTC; 0: exact)")
      ->check(structgp::AtLeast(0));
  structgp::AddFlag(&app, "--threads", &f.threads,
                    "threads of every fit (as structgp fit --threads: the searches' evidence "
                    "and statistics, lagk's posterior)")
      ->check(structgp::AtLeast(1));
  structgp::AddFlag(&app, "--chain-starts", &structgp::g_chain_starts,
                    "chain: starts of the kinematic search")
      ->check(structgp::AtLeast(1));
  structgp::AddFlag(&app, "--chain-initial", &structgp::g_chain_initial,
                    "chain: a start of one's own, the kinematic parameters (comma-separated)")
      ->delimiter(',');
  structgp::AddFlag(&app, "--chain-rows", &structgp::g_chain_rows,
                    "chain: evenly spaced rows of the kinematic search")
      ->check(structgp::AtLeast(2));
  app.add_option("--lagk-inducing-rule", f.lagk_inducing_rule,
                 "how lagk's inducing states are chosen: cover (the states) or stride (in time)")
      ->check(CLI::IsMember({"cover", "stride"}));
  structgp::AddFlag(&app, "--prior", &f.prior,
                    "prior on the log hyper-parameters of every type-II search (as structgp fit "
                    "--prior): gaussian, student_t or none");
  structgp::AddFlag(&app, "--lagk-sigmas", &f.lagk_sigmas,
                    "the sigma grid of lagk's type-II maximum likelihood")
      ->delimiter(',')
      ->check(structgp::GreaterThan(0));
  app.add_flag("!--no-calibrate-bands", f.calibrate_bands,
               "keep the posterior's own bands (structgp fit --no-calibrate-bands); by default "
               "the fits calibrate them on their held-out check, as the CLI does");
  structgp::AddFlag(&app, "--band-coverage", &f.band_coverage,
                    "the held-out coverage the calibrated bands are scaled to (structgp fit "
                    "--band-coverage)")
      ->check(CLI::Range(0.5, 0.999));
  app.add_flag("--components", f.components,
               "also split each model's test error into its gravity, inertial and velocity "
               "(Coriolis + friction) terms against the simulation's (reference, lagk and "
               "FitModel's models)");
  structgp::AddFlag(&app, "--noise", &f.noise, "noise std relative to each joint's RMS torque")
      ->check(structgp::GreaterThan(0));
  app.add_option("--size-by", f.size_by,
                 "what sizes the noise and the friction: the training log's RMS torques and "
                 "velocities (train), or the default slow log's, 50 via points in 50 s "
                 "(default-slow: the same noise and friction whatever --train-seconds and "
                 "--train-vias)")
      ->check(CLI::IsMember({"train", "default-slow"}));
  structgp::AddFlag(&app, "--tests", &f.tests, "fast test logs")->check(structgp::AtLeast(1));
  app.add_option("--out", f.out, "CSV file of the per-joint results");
  app.add_option("--write-logs", f.write_logs,
                 "write each case's training log (after --train-rows) and test logs to this "
                 "existing folder as ROBOT_CASE_train.csv, ROBOT_CASE_test1.csv, ... (the CLI's "
                 "format: structgp fit / evaluate reproduce a row)");
  app.add_flag("--quick", f.quick, "a CI-size run: two_link with friction, reference and rbd");
  app.add_flag("--check", f.check,
               "exit 3 unless every rbd model is within 1.1x of the noise and every lagk model "
               "within 8x");
  return structgp::RunProgram(&app, argc, argv, [&] { return structgp::Run(f, argc, argv); });
}
