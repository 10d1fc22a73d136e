#!/usr/bin/env bash
# Renders the CSV files of `stagefit disturbance` as log-log plots, one PNG per file:
#   - PSD tables (`disturbance psd`, the target tables in measurements/disturbance/): amplitude
#     spectral densities sqrt(PSD), one curve per column;
#   - sensitivities (`disturbance sensitivity`, columns re,im,abs): |H| in its unit;
#   - force (source) PSDs (`disturbance force`, with a `reliable` column): sqrt(PSD), the bins
#     flagged unreliable (sensitivity too small) drawn as grey points.
# Needs gnuplot (gnuplot-nox is enough).
#
#   scripts/plot_disturbance.sh PSD.csv [S.csv F.csv ...] -> PSD.png, S.png, F.png beside the inputs
#   OUT_DIR=plots scripts/plot_disturbance.sh PSD.csv     -> plots/PSD.png
set -euo pipefail

if [[ $# -lt 1 ]]; then
  echo "usage: $0 PSD.csv [PSD2.csv ...]" >&2
  exit 1
fi
command -v gnuplot >/dev/null || { echo "$0: gnuplot not found" >&2; exit 1; }

for csv in "$@"; do
  [[ -f "$csv" ]] || { echo "$0: no file $csv" >&2; exit 2; }
  header=$(awk '!/^#/ && NF { print; exit }' "$csv")
  IFS=',' read -r -a columns <<<"$header"
  if [[ ${#columns[@]} -lt 2 ]]; then
    echo "$0: $csv: expected a frequency column and at least one PSD column" >&2
    exit 2
  fi
  xlabel="Frequency [Hz]"
  [[ "${columns[0]}" == spatial_frequency_per_m ]] && xlabel="Spatial frequency [1/m]"
  # Units of the PSD columns from the "# unit NAME UNIT" lines; the ASD unit is written as
  # sqrt(UNIT) unless the unit is "X^2/Y" (then X/sqrt(Y)).
  base=$(basename "${csv%.*}")
  out_dir=${OUT_DIR:-$(dirname "$csv")}
  mkdir -p "$out_dir"
  png="$out_dir/$base.png"
  plots=""
  ylabel="Amplitude spectral density"
  meta="${csv%.csv}.meta.json"
  unit_of() {
    local u
    u=$(awk -v n="$1" '$1 == "#" && $2 == "unit" && $3 == n { $1 = $2 = $3 = ""; sub(/^ +/, ""); print; exit }' "$csv")
    # Header-first files keep their units in the .meta.json sidecar: "units": {"NAME": "UNIT", ...}.
    if [[ -z "$u" && -f "$meta" ]]; then
      u=$(awk -v n="\"$1\":" '/"units"/ { inside = 1; next } inside && /}/ { exit }
            inside && $1 == n { line = $0; sub(/^[^:]*: *"/, "", line); sub(/",? *$/, "", line); print line; exit }' "$meta")
    fi
    echo "$u"
  }
  reliable_column=0
  for ((c = 1; c < ${#columns[@]}; ++c)); do
    [[ "${columns[$c]}" == reliable ]] && reliable_column=$((c + 1))
  done
  sensitivity=0
  [[ " ${columns[*]} " == *" abs "* ]] && sensitivity=1
  if ((sensitivity)); then
    # A sensitivity: plot its magnitude.
    for ((c = 1; c < ${#columns[@]}; ++c)); do
      [[ "${columns[$c]}" == abs ]] || continue
      unit=$(unit_of abs)
      ylabel="|H| [${unit:-model units}]"
      plots="'$csv' using 1:((\$$((c + 1)) > 0) ? \$$((c + 1)) : 1/0) with lines lw 1.5 title '|H|'"
    done
  fi
  for ((c = 1; c < ${#columns[@]}; ++c)); do
    ((sensitivity)) && break
    name=${columns[$c]}
    [[ "$name" == reliable ]] && continue
    unit=$(unit_of "$name")
    if [[ "$unit" =~ ^([^/^]+)\^2/(.+)$ ]]; then
      asd_unit="${BASH_REMATCH[1]}/sqrt(${BASH_REMATCH[2]})"
    elif [[ -n "$unit" ]]; then
      asd_unit="sqrt($unit)"
    else
      asd_unit="U/sqrt(Hz)"
    fi
    v="\$$((c + 1))"
    if ((reliable_column > 0)); then
      r="\$$reliable_column"
      plots+="${plots:+, }'$csv' using 1:(($v > 0 && $r > 0) ? sqrt($v) : 1/0) with lines lw 1.5 title '$name [$asd_unit]'"
      plots+=", '$csv' using 1:(($v > 0 && $r == 0) ? sqrt($v) : 1/0) with points pt 7 ps 0.4 lc rgb 'grey60' title 'unreliable: sensitivity too small'"
    else
      plots+="${plots:+, }'$csv' using 1:(($v > 0 && \$1 > 0) ? sqrt($v) : 1/0) with lines lw 1.5 title '$name [$asd_unit]'"
    fi
  done
  gnuplot <<GNUPLOT
set terminal pngcairo size 900,600 noenhanced
set output '$png'
set datafile separator ','
set datafile commentschars '#'
set key autotitle columnhead
set logscale xy
set grid xtics ytics mxtics mytics
set format y '%.0e'
set xlabel '$xlabel'
set ylabel '$ylabel'
set title '$base'
set key bottom left
plot $plots
GNUPLOT
  echo "wrote $png"
done
