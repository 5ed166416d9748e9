// The rigid-body regressor (RigidBodyChain::Regressor, with a workspace) against one KDL
// inverse-dynamics evaluation, on the random robots of the simulator (as URDF) of 2..7 joints.

#include <random>

#include <benchmark/benchmark.h>

#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/urdf.h"

namespace {

using structgp::Matrix;
using structgp::RigidBodyChain;
using structgp::Vector;

struct Fixture {
  explicit Fixture(int n)
      : chain(structgp::sim::ToRigidBodyChain(structgp::sim::RandomRobot(n, 1))),
        q(Vector::Random(n)),
        qd(Vector::Random(n)),
        qdd(Vector::Random(n)) {}
  RigidBodyChain chain;
  Vector q, qd, qdd;
};

void BM_Regressor(benchmark::State& state) {
  Fixture f(static_cast<int>(state.range(0)));
  RigidBodyChain::Workspace workspace = f.chain.MakeWorkspace();
  Matrix y(f.chain.num_joints(), f.chain.num_parameters());
  for (auto _ : state) {
    f.chain.Regressor(f.q, f.qd, f.qdd, RigidBodyChain::Terms::kAll, y, workspace);
    benchmark::DoNotOptimize(y.data());
  }
}
BENCHMARK(BM_Regressor)->DenseRange(2, 7);

void BM_InverseDynamics(benchmark::State& state) {
  Fixture f(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(f.chain.InverseDynamics(f.q, f.qd, f.qdd));
}
BENCHMARK(BM_InverseDynamics)->DenseRange(2, 7);

}  // namespace

BENCHMARK_MAIN();
