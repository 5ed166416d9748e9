// The engine at work: a Bayesian linear GP learns a function online, one sample at a time,
// and ends exactly where a batch fit on the same data ends.
//
//   build/examples/engine_demo [num_samples]

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "structgp/structgp.h"

int main(int argc, char** argv) {
  using structgp::Matrix;
  using structgp::Vector;
  int n = 5000;
  CLI::App app("A Bayesian linear GP learns online and ends where a batch fit ends.",
               "engine_demo");
  app.add_option("num_samples", n, "samples learned, >= 10")->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "engine_demo: %s\nrun 'engine_demo --help' for the flags\n", e.what());
    return 2;
  }
  if (n < 10) {
    std::fprintf(stderr, "engine_demo: num_samples must be >= 10, got %d\n", n);
    return 2;
  }
  const int D = 128, P = 7;
  const unsigned seed = 2026;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;

  // Random cosine features of a 9-dimensional input; targets from hidden weights + noise.
  const Matrix Omega = Matrix::NullaryExpr(9, D, [&]() { return normal(rng); });
  const Vector offset = Vector::NullaryExpr(D, [&]() { return 6.283185307179586 * (normal(rng)); });
  const Matrix W_true = Matrix::NullaryExpr(D, P, [&]() { return normal(rng); }) / std::sqrt(D);
  auto features = [&](const Matrix& X) {
    Matrix Phi = X * Omega;
    Phi.rowwise() += offset.transpose();
    return Matrix(Phi.array().cos() * std::sqrt(2.0));
  };
  const Matrix X = Matrix::NullaryExpr(n, 9, [&]() { return normal(rng); });
  const Matrix X_test = Matrix::NullaryExpr(1000, 9, [&]() { return normal(rng); });
  const Matrix Phi = features(X), Phi_test = features(X_test);
  const double noise_std = 0.05;
  const Matrix Y = Phi * W_true + noise_std * Matrix::NullaryExpr(n, P, [&]() { return normal(rng); });
  const Matrix Y_test = Phi_test * W_true;

  structgp::WeightSpaceGP online(Vector::Ones(D), noise_std * noise_std, P);
  Vector mean(P), latent(P), noisy(P);
  auto test_rms = [&](const structgp::WeightSpaceGP& model) {
    double sse = 0.0;
    structgp::WeightSpaceGP::Workspace workspace = model.MakeWorkspace();
    for (int i = 0; i < Phi_test.rows(); ++i) {
      model.Predict(Phi_test.row(i).transpose(), mean, workspace);
      sse += (mean - Y_test.row(i).transpose()).squaredNorm();
    }
    return std::sqrt(sse / (Phi_test.rows() * P));
  };

  std::printf("structgp engine demo: D = %d features, %d outputs, seed %u\n", D, P, seed);
  std::printf("%10s %14s %22s\n", "samples", "test RMS", "mean latent std");
  double step_seconds = 0.0;
  for (int i = 0; i < n; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto status = online.UpdateAndPredict(Phi.row(i).transpose(), Y.row(i).transpose(),
                                                Phi.row((i + 1) % n).transpose(), mean, latent,
                                                noisy);
    step_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (status != structgp::Status::kOk) {
      std::fprintf(stderr, "update %d failed: %s\n", i, structgp::ToString(status));
      return 1;
    }
    const int count = i + 1;
    if (count == 10 || count == 100 || count == 1000 || count == n) {
      std::printf("%10d %14.5f %22.5f\n", count, test_rms(online), std::sqrt(latent.mean()));
    }
  }
  structgp::WeightSpaceGP batch(Vector::Ones(D), noise_std * noise_std, P);
  if (batch.Fit(Phi, Y) != structgp::Status::kOk) return 1;
  const double rel = (online.weights() - batch.weights()).norm() / batch.weights().norm();
  std::printf("online step (update + predict mean and variance): %.2f us on average\n",
              1e6 * step_seconds / n);
  std::printf("online vs batch fit: relative weight difference %.2e; log evidence %.6f vs %.6f\n",
              rel, online.LogMarginalLikelihood(), batch.LogMarginalLikelihood());
  return rel < 1e-8 ? 0 : 1;
}
