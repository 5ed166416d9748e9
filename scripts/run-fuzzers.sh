#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ with clang (ASan + UBSan) and runs each from its seed
# corpus in fuzz/corpus/<target>/. New inputs go to a scratch corpus in the build directory
# (the repository is not modified); a crash, a sanitizer report, a timeout or an out-of-memory
# stops the run with a nonzero status and leaves the input in <build>/artifacts/<target>/.
#
#   bash scripts/run-fuzzers.sh [SECONDS_PER_TARGET] [TARGET...]
#
# With STRUCTGP_FUZZ_RUNS=N (what CI uses) each target instead runs exactly N inputs from a
# fixed seed: the same inputs on every run of the same build, so a CI result can be
# reproduced. Time-bounded runs (the default) explore further and are for finding new bugs.
#
# Environment: STRUCTGP_FUZZ_BUILD_DIR (default build-fuzz), STRUCTGP_FUZZ_RUNS.
set -euo pipefail
cd "$(dirname "$0")/.."

seconds=${1:-45}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=(fuzz_csv fuzz_model_spec fuzz_model_file)
fi
build=${STRUCTGP_FUZZ_BUILD_DIR:-build-fuzz}
jobs=$(nproc 2>/dev/null || echo 2)

# A tree already configured with the fuzz targets (scripts/run-tests.sh's ASan tree, which
# also builds the tests) is used as it is; otherwise the fuzz targets get a tree of their own.
# -O1 (libFuzzer's documentation builds its targets with -O1 or -O2): faster to compile than -O3.
if ! grep -q '^STRUCTGP_BUILD_FUZZERS:BOOL=ON$' "$build/CMakeCache.txt" 2>/dev/null; then
  CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DSTRUCTGP_BUILD_FUZZERS=ON -DBUILD_TESTING=OFF -DSTRUCTGP_BUILD_BENCHMARKS=OFF \
    -DSTRUCTGP_BUILD_EXPERIMENTS=OFF -DSTRUCTGP_BUILD_EXAMPLES=OFF > /dev/null
fi
cmake --build "$build" -j "$jobs" --target "${targets[@]}"

export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# The same budget for every target: a fixed number of inputs from a fixed seed, or a time.
if [ -n "${STRUCTGP_FUZZ_RUNS:-}" ]; then
  budget=(-runs="$STRUCTGP_FUZZ_RUNS" -seed=1)
  budget_text="$STRUCTGP_FUZZ_RUNS inputs from seed 1"
else
  budget=(-max_total_time="$seconds")
  budget_text="for ${seconds} s"
fi
# Each target is one process on one core: up to $jobs run at once (each writes its own log and
# corpus); the results are read in the targets' order once all have run.
run_target() {
  local target=$1
  local corpus="$build/corpus/$target"
  local artifacts="$build/artifacts/$target/"
  mkdir -p "$corpus" "$artifacts"
  local status=0
  "$build/fuzz/$target" "${budget[@]}" -timeout=10 -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$artifacts" \
    "$corpus" "fuzz/corpus/$target" 2> "$build/$target.log" || status=$?
  echo "$status" > "$build/$target.status"
}

for target in "${targets[@]}"; do
  echo "run-fuzzers: $target, $budget_text"
  rm -f "$build/$target.status"
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do
    wait -n || true
  done
  run_target "$target" &
done
wait

failed=0
for target in "${targets[@]}"; do
  status=$(cat "$build/$target.status" 2>/dev/null || echo 1)
  if [ "$status" != 0 ]; then
    tail -n 60 "$build/$target.log"
    echo "run-fuzzers: $target FAILED (status $status); the input is in $build/artifacts/$target/" >&2
    failed=1
  else
    echo "run-fuzzers: $target:"
    grep -E "^stat::number_of_executed_units|^#[0-9]+.*DONE" "$build/$target.log" | tail -n 2 || true
  fi
done
if [ "$failed" != 0 ]; then
  exit 1
fi
echo "run-fuzzers: all targets ran without a finding"
