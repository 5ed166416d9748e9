// Numerical soak of the online weight-space model with forgetting: a 3-joint pol model
// (PolFeatureMap(3), D = 1151) learns torques of the KDL-simulated ThreeLinkArm, one sample at a
// time through UpdateAndPredict (the control-loop path) with forgetting factor lambda, or with
// --batch=K > 1 in bursts of K samples through UpdateBatch (the online learner's path). At every
// check point the online weights are compared with a batch refit (WeightSpaceGP::Fit, one
// Cholesky factorisation) on the same exponentially weighted data, accumulated independently
// here, with the prior broadened to Lambda / lambda^n as documented in weight_space_gp.h.
//
// Fails (exit status 1) when at a check point the relative difference of the weights exceeds
// --tolerance, or at any step a prediction is not finite or a predictive variance is negative.
//
//   soak_forgetting [--updates=1000000] [--check-every=100000] [--forgetting=0.99999]
//                   [--tolerance=1e-8] [--seed=1] [--batch=1]
//
// The short form (10^4 updates) is a ctest; the long form and its results are in
// docs/reliability.md.

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "structgp/core/status.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace structgp {
namespace {

struct Options {
  long updates = 1000000;
  long check_every = 100000;
  double forgetting = 0.99999;
  double tolerance = 1e-8;
  unsigned long seed = 1;
  int batch = 1;
};

// Samples are simulated in blocks of this many (independent uniform states per block).
constexpr long kBlock = 500;
// Model noise variance sigma_n^2 (torques in N m, simulated noise std 0.01 N m).
constexpr double kNoiseVariance = 1e-4;

[[noreturn]] void Usage(const std::string& problem) {
  std::fprintf(stderr,
               "soak_forgetting: %s\nusage: soak_forgetting [--updates=N] [--check-every=K] "
               "[--forgetting=L] [--tolerance=T] [--seed=S]\n",
               problem.c_str());
  std::exit(2);
}

Options ParseArgs(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto eq = arg.find('=');
    if (arg.rfind("--", 0) != 0 || eq == std::string::npos) Usage("bad argument '" + arg + "'");
    const std::string key = arg.substr(2, eq - 2);
    const std::string value = arg.substr(eq + 1);
    char* end = nullptr;
    const double number = std::strtod(value.c_str(), &end);
    if (value.empty() || *end != '\0' || !std::isfinite(number)) {
      Usage("--" + key + ": expected a number, got '" + value + "'");
    }
    if (key == "updates") {
      o.updates = static_cast<long>(number);
    } else if (key == "check-every") {
      o.check_every = static_cast<long>(number);
    } else if (key == "forgetting") {
      o.forgetting = number;
    } else if (key == "tolerance") {
      o.tolerance = number;
    } else if (key == "batch") {
      o.batch = static_cast<int>(number);
    } else if (key == "seed") {
      o.seed = static_cast<unsigned long>(number);
    } else {
      Usage("unknown flag --" + key);
    }
  }
  if (o.updates < kBlock || o.check_every < kBlock || o.check_every % kBlock != 0) {
    Usage("--updates and --check-every must be >= " + std::to_string(kBlock) +
          ", --check-every a multiple of it");
  }
  if (!(o.forgetting > 0.0 && o.forgetting <= 1.0)) Usage("--forgetting must be in (0, 1]");
  if (o.batch < 1 || kBlock % o.batch != 0) {
    Usage("--batch must be >= 1 and divide " + std::to_string(kBlock));
  }
  return o;
}

int Run(const Options& o) {
  const sim::Robot robot = sim::ThreeLinkArm();
  const PolFeatureMap map(3);
  const int D = map.dim();
  const int P = 3;
  Vector lambda(D);
  map.PriorVariance(map.default_shape_parameters(), lambda);

  WeightSpaceGP online(lambda, kNoiseVariance, P);
  if (o.batch > 1) online.ReserveBatch(o.batch);
  const Vector batch_forgetting = Vector::Constant(o.batch, o.forgetting);
  const Vector batch_weights = Vector::Ones(o.batch);
  Matrix batch_phi(D, o.batch), batch_y(P, o.batch);
  // The reference: exponentially weighted sufficient statistics, sum_i lambda^(n-i) ...
  SufficientStatistics weighted(D, P);

  std::printf("soak_forgetting: D = %d, P = %d, updates = %ld, forgetting = %.8g, seed = %lu, "
              "batch = %d\n",
              D, P, o.updates, o.forgetting, o.seed, o.batch);
  std::printf("%10s %14s %14s %14s %12s %9s\n", "updates", "rel_dW", "rel_dvar", "min_var",
              "log_broaden", "time_s");

  Matrix phi_block(kBlock, D);
  Matrix y_block(kBlock, P);
  Vector mean(P), latent(P), noisy(P);
  Vector phi_next(D);
  double min_variance = HUGE_VAL;
  bool ok = true;
  const auto start = std::chrono::steady_clock::now();
  long n = 0;
  for (long block = 0; n < o.updates; ++block) {
    // kBlock + 1 states: the last one is only predicted at (the next block starts anew).
    sim::SimulationOptions sim_options;
    sim_options.noise_std = 0.01;
    sim_options.seed = o.seed * 1000003 + static_cast<unsigned long>(block);
    const sim::Trajectory traj =
        sim::UniformBox(3, kBlock + 1, M_PI, 2.0, 5.0, sim_options.seed + 17);
    const sim::Dataset data = sim::Simulate(robot, traj, sim_options);
    for (long i = 0; i <= kBlock; ++i) {
      Vector phi(D);
      map.Evaluate(data.X.row(i).transpose(), phi);
      if (i < kBlock) {
        phi_block.row(i) = phi.transpose();
        y_block.row(i) = data.Y.row(i);
      }
    }
    for (long i = 0; o.batch > 1 && i < kBlock; i += o.batch) {
      batch_phi = phi_block.middleRows(i, o.batch).transpose();
      batch_y = y_block.middleRows(i, o.batch).transpose();
      Status status = Status::kOk;
      const int applied =
          online.UpdateBatch(batch_phi, batch_y, batch_forgetting, batch_weights, &status);
      if (applied != o.batch) {
        std::printf("FAIL: UpdateBatch returned %s at update %ld\n", ToString(status),
                    n + i + applied);
        return 1;
      }
      phi_next = i + o.batch < kBlock ? Vector(phi_block.row(i + o.batch).transpose()) : phi_next;
      if (online.PredictWithVariance(phi_block.row(i).transpose(), mean, latent, noisy) !=
              Status::kOk ||
          !mean.allFinite() || !(latent.minCoeff() >= 0.0)) {
        std::printf("FAIL: bad prediction after update %ld\n", n + i + o.batch);
        return 1;
      }
      min_variance = std::min(min_variance, latent.minCoeff());
    }
    if (o.batch > 1) map.Evaluate(data.X.row(kBlock).transpose(), phi_next);
    for (long i = 0; o.batch == 1 && i < kBlock; ++i) {
      if (i + 1 < kBlock) {
        phi_next = phi_block.row(i + 1).transpose();
      } else {
        map.Evaluate(data.X.row(kBlock).transpose(), phi_next);
      }
      const Status status = online.UpdateAndPredict(phi_block.row(i).transpose(),
                                                    y_block.row(i).transpose(), phi_next, mean,
                                                    latent, noisy, o.forgetting);
      if (status != Status::kOk) {
        std::printf("FAIL: UpdateAndPredict returned %s at update %ld\n", ToString(status), n + i);
        return 1;
      }
      if (!mean.allFinite() || !latent.allFinite() || !noisy.allFinite()) {
        std::printf("FAIL: non-finite prediction at update %ld\n", n + i);
        return 1;
      }
      min_variance = std::min(min_variance, latent.minCoeff());
      if (latent.minCoeff() < 0.0) {
        std::printf("FAIL: negative latent variance %g at update %ld\n", latent.minCoeff(), n + i);
        return 1;
      }
    }
    // Reference statistics: old ones forgotten by lambda^kBlock, sample i of the block weighted
    // lambda^(kBlock - 1 - i) (it has been forgotten that often since it was added).
    Vector w(kBlock);
    for (long i = 0; i < kBlock; ++i) {
      w[i] = std::pow(o.forgetting, static_cast<double>(kBlock - 1 - i));
    }
    const double decay = std::pow(o.forgetting, static_cast<double>(kBlock));
    const Matrix scaled_phi = w.cwiseSqrt().asDiagonal() * phi_block;
    weighted.gram *= decay;
    weighted.gram.selfadjointView<Eigen::Lower>().rankUpdate(scaled_phi.transpose());
    weighted.cross = decay * weighted.cross + phi_block.transpose() * (w.asDiagonal() * y_block);
    weighted.y_squared =
        decay * weighted.y_squared + (w.asDiagonal() * y_block.cwiseAbs2()).colwise().sum().transpose();
    weighted.count = decay * weighted.count + w.sum();
    n += kBlock;

    if (n % o.check_every == 0 || n >= o.updates) {
      // Batch posterior with the prior broadened by forgetting: Lambda / lambda^n.
      const double log_broadening = -static_cast<double>(n) * std::log(o.forgetting);
      WeightSpaceGP batch(lambda * std::exp(log_broadening), kNoiseVariance, P);
      const Status status = batch.Fit(weighted);
      if (status != Status::kOk) {
        std::printf("FAIL: batch refit returned %s at update %ld\n", ToString(status), n);
        return 1;
      }
      const Matrix& w_online = online.weights();
      const Matrix& w_batch = batch.weights();
      const double rel_w = (w_online - w_batch).norm() / w_batch.norm();
      // Predictive variance at the next state, both ways.
      Vector m2(P), l2(P), v2(P), m1(P), l1(P), v1(P);
      online.PredictWithVariance(phi_next, m1, l1, v1);
      batch.PredictWithVariance(phi_next, m2, l2, v2);
      const double rel_var = ((l1 - l2).cwiseAbs().array() / l2.array()).maxCoeff();
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      const bool finite = w_online.allFinite() && online.covariance_factor().allFinite();
      std::printf("%10ld %14.3e %14.3e %14.3e %12.4f %9.1f\n", n, rel_w, rel_var, min_variance,
                  log_broadening, seconds);
      std::fflush(stdout);
      if (!finite || !(rel_w <= o.tolerance) || !(rel_var <= o.tolerance)) {
        std::printf("FAIL: at update %ld relative differences %g (weights), %g (variance), "
                    "tolerance %g%s\n",
                    n, rel_w, rel_var, o.tolerance, finite ? "" : ", non-finite model");
        ok = false;
      }
    }
  }
  std::printf("%s: %ld updates, smallest latent variance %.3e\n", ok ? "PASS" : "FAIL", n,
              min_variance);
  return ok ? 0 : 1;
}

}  // namespace
}  // namespace structgp

int main(int argc, char** argv) { return structgp::Run(structgp::ParseArgs(argc, argv)); }
