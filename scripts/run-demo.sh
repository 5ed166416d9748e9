#!/usr/bin/env bash
# Installs the dependencies, builds the structgp program and runs its main job on the
# embedded default. Extra arguments are passed to the demo.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

build=${STRUCTGP_BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
      -DSTRUCTGP_BUILD_BENCHMARKS=OFF
cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" --target engine_demo
"$build/examples/engine_demo" "$@"
