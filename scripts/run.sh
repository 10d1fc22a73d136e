#!/usr/bin/env bash
# The main job: set up, then run stagefit on the embedded micro-station model and the shipped example
# measurement (measurements/microstation-12x10/frf.mat): modes, comparison, fit, diagnosis, and the
# loop's second step (fit with the best effect, diagnose again). Outputs go to ./out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh -DSTAGEFIT_BUILD_BENCHMARKS=ON
mkdir -p out
m=measurements/microstation-12x10/frf.mat
s=./build/stagefit
echo "== 1. the model";                $s model
echo "== 2. compare";                  $s compare --measurement $m --out-dir out/compare --report out/compare.json
echo "== 3. fit the joint stiffnesses"; $s fit --measurement $m --out out/tuned.toml --report out/fit.json || true
echo "== 4. diagnose the tuned model";  $s diagnose --model out/tuned.toml --measurement $m --out out/with-effect.toml --report out/diagnose.json
if [ -f out/with-effect.toml ]; then
  echo "== 5. refit with the effect";   $s fit --model out/with-effect.toml --measurement $m --out out/tuned-with-effect.toml --report out/fit-with-effect.json || true
fi
echo "Outputs in out/ (plots: bash scripts/plot_compare.sh out/compare)"
