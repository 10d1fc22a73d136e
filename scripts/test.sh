#!/usr/bin/env bash
# Sets up, builds and runs the whole test suite (unit, integration and CLI tests, and the file
# readers' stored fuzz inputs replayed: FuzzReplay.*) with CTest. Fuzzing for new inputs (clang,
# libFuzzer, sanitizers) is its own job: bash scripts/fuzz.sh (docs/reliability.md).
# Usage: bash scripts/test.sh            (release build in ./build)
#        bash scripts/test.sh --sanitize (AddressSanitizer + UBSan build in ./build-asan)
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "--sanitize" ]; then
  STAGEFIT_BUILD_DIR=build-asan bash scripts/setup.sh -DSTAGEFIT_SANITIZE=ON -DSTAGEFIT_BUILD_BENCHMARKS=OFF
  cd build-asan
else
  # The benchmark programs are not tests: leave them out here to keep the run short.
  bash scripts/setup.sh -DSTAGEFIT_BUILD_BENCHMARKS=OFF
  cd build
fi
ctest --output-on-failure -j"$(nproc)" --timeout 600
