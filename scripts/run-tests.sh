#!/usr/bin/env bash
# Installs the dependencies, builds everything (Release, assertions kept on in the tests),
# runs the whole test suite, then installs the package into a scratch prefix and builds the
# downstream consumer in examples/consumer against it.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

jobs=$(nproc 2>/dev/null || echo 2)
build=${STRUCTGP_BUILD_DIR:-build}

cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$jobs"
ctest --test-dir "$build" --output-on-failure -j "$jobs"

# The installed package works for a consumer: find_package(structgp) -> structgp::structgp.
prefix="$build/install-prefix"
rm -rf "$prefix" "$build/consumer"
cmake --install "$build" --prefix "$prefix" > /dev/null
cmake -S examples/consumer -B "$build/consumer" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$(pwd)/$prefix"
cmake --build "$build/consumer"
"$build/consumer/structgp_consumer"
echo "run-tests: all tests passed"
