#!/usr/bin/env bash
# Sets up, builds and runs the whole test suite (unit, integration and CLI tests) with CTest, then
# a short fuzz pass over the file readers (scripts/fuzz.sh).
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
# Then a short libFuzzer pass over every file reader (clang build in ./build-fuzz): 100000 inputs
# per target from a fixed seed: the same amount of work on every machine (exploring: --seconds N).
cd .. && bash scripts/fuzz.sh --runs 100000 --seed 1
