#!/usr/bin/env bash
# The disturbance chain end to end on the records in measurements/disturbance/ and the embedded
# micro-station model:
#   record -> PSD (geophone correction, best line or circle removed)
#          -> model sensitivity from the source to {X} relative to the granite
#          -> source PSD = motion PSD / |sensitivity|^2 (bins with too small a sensitivity flagged)
#          -> a synthesised time signal of that source PSD (for `stagefit simulate`)
#          -> PNG plots of every CSV.
# Usage: bash scripts/disturbance.sh [OUT_DIR]   (default out/disturbance; needs a built ./build/stagefit,
#        e.g. from scripts/setup.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
stagefit=${STAGEFIT:-./build/stagefit}
[[ -x "$stagefit" ]] || { echo "$0: no $stagefit; run bash scripts/setup.sh first" >&2; exit 1; }
records=measurements/disturbance
out=${1:-out/disturbance}
mkdir -p "$out"

echo "== ground motion: L-4C geophone voltage -> ground displacement PSD"
"$stagefit" disturbance psd "$records/ground_l4c_voltage.csv" --kind ground-geophone --geophone L-4C \
  --resolution "0.1 Hz" --out "$out/ground_psd.csv"
"$stagefit" disturbance sensitivity --source ground.Dz --output X_rel.Dz --at "$out/ground_psd.csv" \
  --out "$out/ground_to_x_sensitivity.csv"

echo "== translation stage: straightness scanned at 1 mm/s -> vertical force inside the Ty joint"
"$stagefit" disturbance psd "$records/ty_straightness.csv" --kind straightness --speed "1 mm/s" \
  --out "$out/ty_psd.csv"
"$stagefit" disturbance sensitivity --source ty.F.Dz --output X_rel.Dz --at "$out/ty_psd.csv" \
  --out "$out/ty_sensitivity.csv"
"$stagefit" disturbance force --psd "$out/ty_psd.csv" --column vertical_m \
  --sensitivity "$out/ty_sensitivity.csv" --out "$out/ty_force_psd.csv"

echo "== spindle: five-sensor error analyser at 60 rpm -> axial force inside the spindle joint"
"$stagefit" disturbance psd "$records/spindle_60rpm.csv" --kind spindle --out "$out/spindle_psd.csv"
"$stagefit" disturbance sensitivity --source rz.F.Dz --output X_rel.Dz --at "$out/spindle_psd.csv" \
  --out "$out/rz_sensitivity.csv"
"$stagefit" disturbance force --psd "$out/spindle_psd.csv" --column Dz \
  --sensitivity "$out/rz_sensitivity.csv" --out "$out/rz_force_psd.csv"

echo "== time signals of the source PSDs (10 s at 1 kHz)"
"$stagefit" disturbance synth --psd "$out/ty_force_psd.csv" --duration "10 s" --rate "1 kHz" --seed 1 \
  --out "$out/ty_force_signal.csv"
"$stagefit" disturbance synth --psd "$out/rz_force_psd.csv" --duration "10 s" --rate "1 kHz" --seed 2 \
  --out "$out/rz_force_signal.csv"

if command -v gnuplot >/dev/null; then
  bash scripts/plot_disturbance.sh "$out"/*_psd.csv "$out"/*_sensitivity.csv
else
  echo "gnuplot not found: no plots" >&2
fi
