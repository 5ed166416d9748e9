#!/usr/bin/env bash
# Installs the dependencies, builds the structgp program and runs its main job on the
# embedded default: a simulated two-link arm with hidden Coulomb friction on joint 2; fit,
# diagnose, add the suggested effect, refit, and compare (see docs/cli.md). Extra arguments
# are passed to `structgp demo` (e.g. --effect cogging --joint 1 --out /tmp/demo).
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

build=${STRUCTGP_BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
      -DSTRUCTGP_BUILD_BENCHMARKS=OFF -DSTRUCTGP_BUILD_EXPERIMENTS=OFF \
      -DSTRUCTGP_BUILD_EXAMPLES=ON
cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" --target structgp_cli
"$build/src/cli/structgp" demo "$@"
