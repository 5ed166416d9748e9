#!/usr/bin/env bash
# Installs every system dependency of structgp on Debian 12 (run as root).
# Idempotent: packages already present are left as they are.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev
  libceres-dev libsuitesparse-dev libgoogle-glog-dev libgflags-dev
  libboost-dev
  liborocos-kdl-dev
  libkdl-parser-dev liburdfdom-dev  # URDF robots (src/rigid_body)
  libgtest-dev libgmock-dev
  libbenchmark-dev
  nlohmann-json3-dev libcli11-dev
  chromium  # headless browser test of the HTML report (tests/test_report.cc)
  zlib1g-dev
  python3-sklearn  # experiments/sklearn_compare.py (side by side with scikit-learn; not in ctest)
  pybind11-dev python3-dev python3-numpy  # the Python module (python/)
  python3-pytest  # its tests (python/tests/, in ctest)
  python3-matplotlib  # examples/python/diagnose_and_plot.py (its figure in docs/python.md)
  clang libclang-rt-14-dev  # libFuzzer targets in fuzz/ (scripts/run-fuzzers.sh)
  lld  # a faster linker for the test programs (CMakeLists.txt: STRUCTGP_USE_LLD)
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}"
