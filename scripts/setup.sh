#!/usr/bin/env bash
# Installs the Debian packages stagefit needs (when missing), configures and builds it in ./build.
# Usage: bash scripts/setup.sh [extra cmake options...]
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(build-essential cmake ninja-build pkg-config
          libeigen3-dev libfftw3-dev libceres-dev libnlopt-cxx-dev libnlopt-dev libmatio-dev zlib1g-dev libhdf5-dev
          libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev libtomlplusplus-dev nlohmann-json3-dev
          gnuplot-nox python3)
bash scripts/install-packages.sh setup "${packages[@]}"

build_dir="${STAGEFIT_BUILD_DIR:-build}"
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build "$build_dir" -j"$(nproc)"
