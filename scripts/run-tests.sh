#!/usr/bin/env bash
# Installs the dependencies, builds everything (Release, assertions kept on in the tests),
# runs the whole test suite (with the Python module's pytest files), then installs the package
# into a scratch prefix, builds the downstream consumer in examples/consumer against it and
# imports the installed Python module. Then the reliability passes
# (docs/reliability.md): the suite again under AddressSanitizer + UndefinedBehaviorSanitizer
# (build-asan, clang; the tests that run all the code the suite runs, tests/release_only.txt
# and tests/sanitizer_redundant.txt name the others), the threaded tests under
# ThreadSanitizer (build-tsan), and each libFuzzer target, built in the same instrumented tree
# as the ASan suite, on 100,000 inputs from a fixed seed (scripts/run-fuzzers.sh).
# STRUCTGP_SKIP_SANITIZERS=1 skips these passes (for a quick local run; CI runs them).
set -euo pipefail
cd "$(dirname "$0")/.."

# The wall time of each step, printed at the end (also when a step fails), so that a CI log
# says where its time went (docs/reliability.md, section 5, keeps the measurements).
step_start=$SECONDS
steps=()
step_done() {
  steps+=("$(printf '%-28s %5d s' "$1" $((SECONDS - step_start)))")
  step_start=$SECONDS
}
print_steps() {
  echo "run-tests: wall time per step"
  for s in "${steps[@]}"; do echo "  $s"; done
  echo "  $(printf '%-28s %5d s' total "$SECONDS")"
}
trap print_steps EXIT

bash scripts/install-deps.sh
step_done dependencies

jobs=$(nproc 2>/dev/null || echo 2)
build=${STRUCTGP_BUILD_DIR:-build}

cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$jobs"
step_done "Release build"
ctest --test-dir "$build" --output-on-failure -j "$jobs"
step_done "Release ctest"

# The installed package works for a consumer: find_package(structgp) -> structgp::structgp,
# and a program of under 30 lines fits, diagnoses and saves a model with it.
prefix="$build/install-prefix"
rm -rf "$prefix" "$build/consumer"
cmake --install "$build" --prefix "$prefix" > /dev/null
cmake -S examples/consumer -B "$build/consumer" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$(pwd)/$prefix"
cmake --build "$build/consumer"
# The consumer fits, diagnoses and saves a model of the demo's slow log; the program then
# evaluates the saved file on the fast log.
rm -rf "$build/consumer-data"
"$build/src/cli/structgp" demo --out "$build/consumer-data" --quiet > /dev/null
"$build/consumer/structgp_consumer" "$build/consumer-data/train.csv" \
  "$build/consumer-data/consumer_model.json"
"$build/src/cli/structgp" evaluate --model "$build/consumer-data/consumer_model.json" \
  --data "$build/consumer-data/test.csv"
# The installed Python module imports (when the build has it: STRUCTGP_PYTHON).
module=$(find "$prefix" -name 'structgp.cpython-*.so' | head -n 1)
if [ -n "$module" ]; then
  PYTHONPATH="$(dirname "$module")" /usr/bin/python3 -c \
    'import structgp; print("installed Python module structgp", structgp.__version__)'
fi
step_done "installed package, consumer"

if [ "${STRUCTGP_SKIP_SANITIZERS:-0}" != 1 ]; then
  # ASan + UBSan with clang at -O1 (half the compile time of -O3 per file), in one tree with
  # the libFuzzer targets (STRUCTGP_BUILD_FUZZERS: the library and the fuzz targets carry
  # libFuzzer's coverage instrumentation; the tests, the CLI and the simulator, which feed no
  # fuzzer, do not), so that one instrumented library serves both passes: every test of the
  # suite but those of the two lists below (docs/reliability.md, section 5). Benchmark programs
  # are not tests, and the experiments' quick checks are too slow under ASan: both left out.
  asan=${STRUCTGP_ASAN_BUILD_DIR:-build-asan}
  # A tree configured with another compiler (GCC, before) is configured again from scratch.
  if [ -f "$asan/CMakeCache.txt" ] && ! grep -q '^CMAKE_CXX_COMPILER:[A-Z]*=.*clang++' "$asan/CMakeCache.txt"; then
    rm -rf "$asan"
  fi
  CC=clang CXX=clang++ cmake -S . -B "$asan" -G Ninja -DCMAKE_BUILD_TYPE=Release \
        -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DSTRUCTGP_BUILD_FUZZERS=ON \
        -DSTRUCTGP_BUILD_BENCHMARKS=OFF -DSTRUCTGP_BUILD_EXPERIMENTS=OFF
  cmake --build "$asan" -j "$jobs"
  step_done "ASan + UBSan build"
  # One anchored pattern per line of tests/release_only.txt (long tests whose code the tests
  # named next to them run here) and of tests/sanitizer_redundant.txt (tests whose every line and
  # branch outcome other tests of this pass run: scripts/coverage-per-test.py wrote it). Every
  # line names a test of the Release pass (a test renamed or removed would otherwise leave a
  # line that keeps nothing out, and its replacement would run here unmeasured).
  release_tests=$(ctest --test-dir "$build" -N | sed -n 's/^ *Test *#[0-9]*: //p')
  release_only_patterns=()
  for list in tests/release_only.txt tests/sanitizer_redundant.txt; do
    mapfile -t patterns < <(sed -e 's/#.*//' -e 's/[[:space:]]*$//' -e '/^$/d' \
                              -e 's/^/^/' -e 's/$/$/' "$list")
    for pattern in "${patterns[@]}"; do
      if ! grep -qE -- "$pattern" <<< "$release_tests"; then
        echo "run-tests: $list: '$pattern' names no test of the Release pass" >&2
        exit 1
      fi
    done
    release_only_patterns+=("${patterns[@]}")
  done
  release_only=$(IFS='|'; echo "${release_only_patterns[*]}")
  # ctest refuses a longer expression ("Expression too big") and then excludes nothing.
  if [ "${#release_only}" -gt 40000 ]; then
    echo "run-tests: the two lists make a ctest expression of ${#release_only} characters" \
         "(at most 40,000): shorten tests/sanitizer_redundant.txt (scripts/coverage-per-test.py)" >&2
    exit 1
  fi
  ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1} \
  UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1} \
    ctest --test-dir "$asan" --output-on-failure -j "$jobs" -E "$release_only"
  step_done "ASan + UBSan ctest"

  # TSan: the tests that run threads (online learner next to a control loop, multi-threaded
  # batch statistics, Nystrom features built on several threads, the lagk posterior's DTC on
  # several workers, lagk's evidence and the factorisation and inverse under it on several
  # threads, the joints' own searches at once); only their targets are built.
  tsan=${STRUCTGP_TSAN_BUILD_DIR:-build-tsan}
  cmake -S . -B "$tsan" -G Ninja -DCMAKE_BUILD_TYPE=Release -DSTRUCTGP_SANITIZER=thread \
        -DSTRUCTGP_BUILD_BENCHMARKS=OFF -DSTRUCTGP_BUILD_EXPERIMENTS=OFF -DSTRUCTGP_BUILD_EXAMPLES=OFF
  cmake --build "$tsan" -j "$jobs" --target test_online test_nystrom test_batch_fit test_concurrent_predict \
        test_euler_lagrange_gp test_cholesky test_per_joint
  step_done "TSan build"
  threaded='^test_(online|nystrom|batch_fit|concurrent_predict)\.'
  threaded+='|^test_euler_lagrange_gp\.EulerLagrangeGP\.(DtcOverBlocksAndWorkers|EvidenceOnThreads)'
  threaded+='|^test_cholesky\.(Cholesky\.ThreadsGiveTheOneThread|Workers\.)'
  threaded+='|^test_per_joint\.PerJointFit\.JointsOnThreads'
  TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1} \
    ctest --test-dir "$tsan" --output-on-failure -j "$jobs" -R "$threaded"
  step_done "TSan ctest"

  # libFuzzer, each target from its seed corpus, built in the ASan tree above: a fixed number
  # of inputs from a fixed seed, so that the result is reproducible (new bugs are hunted with
  # time-bounded runs: scripts/run-fuzzers.sh SECONDS).
  STRUCTGP_FUZZ_BUILD_DIR="$asan" \
  STRUCTGP_FUZZ_RUNS=${STRUCTGP_FUZZ_RUNS:-100000} \
    bash scripts/run-fuzzers.sh
  step_done "fuzzing"
fi
echo "run-tests: all tests passed"
