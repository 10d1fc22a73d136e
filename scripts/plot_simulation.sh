#!/usr/bin/env bash
# Renders the CSV files written by `stagefit simulate tomography|raster` to PNG with gnuplot:
#   <experiment>.csv       -> <experiment>_errors.png (error signals versus time, nm) and, for a
#                             tomography, <experiment>_xy.png (PoI path in the x-y plane, nm)
#   <experiment>_psd.csv   -> <experiment>_psd.png (amplitude spectral densities, m/sqrt(Hz))
#   <experiment>_compare_psd.csv (when present) -> <experiment>_compare_psd.png
#
#   scripts/plot_simulation.sh DIR EXPERIMENT       e.g. scripts/plot_simulation.sh out tomography
set -euo pipefail

if [[ $# -ne 2 ]]; then
  echo "usage: $0 DIR tomography|raster" >&2
  exit 1
fi
command -v gnuplot >/dev/null || { echo "$0: gnuplot not found" >&2; exit 1; }
dir=$1
experiment=$2
series="$dir/$experiment.csv"
psd="$dir/${experiment}_psd.csv"
[[ -f "$series" ]] || { echo "$0: no file $series" >&2; exit 2; }
[[ -f "$psd" ]] || { echo "$0: no file $psd" >&2; exit 2; }

header() { awk '!/^#/ && NF { print; exit }' "$1"; }

# Error columns follow the 14 pose columns (time, setpoint, Dx..Rz, vib_Dx..vib_Rz).
IFS=',' read -r -a columns <<<"$(header "$series")"
plots=""
for ((c = 14; c < ${#columns[@]}; ++c)); do
  name=${columns[$c]}
  [[ "$experiment" == tomography && "$name" != radial && "$name" != axial && "$name" != x ]] && continue
  plots+="${plots:+, }'$series' every 10 using 1:(\$$((c + 1))*1e9) with lines lw 1 title '$name'"
done
gnuplot <<GNUPLOT
set terminal pngcairo size 1000,600 noenhanced
set output '$dir/${experiment}_errors.png'
set datafile separator ','
set datafile commentschars '#'
set key autotitle columnhead outside right
set title 'stagefit simulate $experiment: errors of the PoI relative to the granite'
set xlabel 'Time [s]'
set ylabel 'Error [nm]'
set grid
plot $plots
GNUPLOT

if [[ "$experiment" == tomography ]]; then
  gnuplot <<GNUPLOT
set terminal pngcairo size 700,700 noenhanced
set output '$dir/${experiment}_xy.png'
set datafile separator ','
set datafile commentschars '#'
set title 'PoI path in the x-y plane (offset circle + vibration)'
set xlabel 'Dx [nm]'
set ylabel 'Dy [nm]'
set size ratio -1
set grid
plot '$series' every 10 using (\$3*1e9):(\$4*1e9) with lines lw 1 title 'PoI', \
     '$series' every 10 using (\$18*1e9):(\$19*1e9) with lines lw 1 title 'circle removed (x_fit, y_fit)'
GNUPLOT
fi

plot_asd() {
  local csv=$1 png=$2 title=$3
  local -a cols
  IFS=',' read -r -a cols <<<"$(header "$csv")"
  local p=""
  for ((c = 1; c < ${#cols[@]}; ++c)); do
    p+="${p:+, }'$csv' using 1:((\$$((c + 1)) > 0 && \$1 > 0) ? sqrt(\$$((c + 1))) : 1/0) with lines lw 1.2 title '${cols[$c]}'"
  done
  gnuplot <<GNUPLOT
set terminal pngcairo size 1000,600 noenhanced
set output '$png'
set datafile separator ','
set datafile commentschars '#'
set logscale xy
set format y '%.0e'
set title '$title'
set xlabel 'Frequency [Hz]'
set ylabel 'ASD [m/sqrt(Hz)]'
set grid
set key outside right
plot $p
GNUPLOT
}
plot_asd "$psd" "$dir/${experiment}_psd.png" "stagefit simulate $experiment: error spectra"
compare="$dir/${experiment}_compare_psd.csv"
if [[ -f "$compare" ]]; then
  plot_asd "$compare" "$dir/${experiment}_compare_psd.png" "simulated and measured error spectra"
fi
echo "wrote PNGs to $dir"
