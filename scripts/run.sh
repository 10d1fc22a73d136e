#!/usr/bin/env bash
# The main job: set up, then run stagefit on the embedded micro-station model and the shipped example
# measurement (measurements/microstation-12x10/frf.mat): modes, comparison, fit, diagnosis, and the
# loop (fit, diagnose, add the best effect, refit, until at the noise floor). Outputs go to ./out/.
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
echo "== 5. the loop: fit, diagnose, add the best effect, refit, until at the noise floor"
$s loop --measurement $m --out out/final.toml --out-dir out/loop --report out/loop.json
echo "Outputs in out/ (plots: bash scripts/plot_compare.sh out/compare; bash scripts/plot_loop.sh out/loop)"
