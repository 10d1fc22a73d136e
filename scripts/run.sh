#!/usr/bin/env bash
# The main job: set up, then run stagefit on the embedded micro-station model and the shipped example
# measurement. Outputs go to ./out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
./build/stagefit model
