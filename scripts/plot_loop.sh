#!/usr/bin/env bash
# Renders what `stagefit loop --out-dir DIR` wrote as PNG files (gnuplot-nox is enough):
#   loop_error.png       the error after every step of the loop (log scale) against the noise floor
#   loop_bode_mag.png    per compared element: measured (points), the model as given (grey) and the
#                        final model (red), magnitude
#   loop_bode_phase.png  the same, phase
#
#   scripts/plot_loop.sh DIR                -> the files in DIR
#   OUT_DIR=plots scripts/plot_loop.sh DIR  -> the files in plots/
set -euo pipefail

if [[ $# -ne 1 ]]; then
  echo "usage: $0 DIR   (DIR written by stagefit loop --out-dir DIR)" >&2
  exit 1
fi
command -v gnuplot >/dev/null || { echo "$0: gnuplot not found" >&2; exit 1; }
dir=$1
for f in loop_history.csv before/compare_frf.csv after/compare_frf.csv; do
  [[ -f "$dir/$f" ]] || { echo "$0: no file $dir/$f" >&2; exit 2; }
done
out_dir=${OUT_DIR:-$dir}
mkdir -p "$out_dir"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

terminal="pngcairo noenhanced font ',9'"
gnuplot -e "set terminal pngcairo" -e "exit" 2>/dev/null || terminal="png noenhanced"

# The column of a CSV whose header name starts with $2 (1-based), from the header row.
column() {
  awk -F, -v want="$2" 'NR == 1 { for (i = 1; i <= NF; ++i) { gsub(/"/, "", $i); if (index($i, want) == 1) { print i; exit } } }' "$1"
}

# Error history: step, error, floor (the effect text is quoted and may hold commas: parse it out).
hist="$dir/loop_history.csv"
awk 'NR > 1 {
    line = $0; gsub(/"[^"]*"/, "", line); n = split(line, f, ",")
    printf "%d %s %s \"%s\"\n", f[1], f[4], (f[5] == "" ? "NaN" : f[5]), f[2]
  }' "$hist" >"$work/history.dat"
steps=$(wc -l <"$work/history.dat")
gnuplot <<GP
set terminal $terminal size $((420 + steps * 90)),420
set output '$out_dir/loop_error.png'
set title 'the loop: error after each step, against the noise floor (dashed)'
set logscale y
set grid
set ylabel 'error'
set xtics rotate by 20 right font ',8'
set bmargin 8
set xrange [-0.5:$steps - 0.5]
set key top right
plot '$work/history.dat' using 1:2:xtic(4) with linespoints pt 7 lw 2 lc rgb '#d62728' title 'model error', \
     '' using 1:3 with lines dt 2 lw 1.5 lc rgb '#444444' title 'noise floor'
GP

# Bode overlays: the before and after tables hold the same elements and frequencies in the same order.
before="$dir/before/compare_frf.csv" after="$dir/after/compare_frf.csv"
fc=$(column "$after" freq) ec=$(column "$after" element)
ma=$(column "$after" meas_abs) mo=$(column "$after" model_abs)
pa=$(column "$after" meas_phase) po=$(column "$after" model_phase)
mkdir -p "$work/e"
paste -d, "$after" "$before" | awk -F, -v fc="$fc" -v ec="$ec" -v ma="$ma" -v mo="$mo" -v pa="$pa" -v po="$po" \
    -v n_after="$(head -1 "$after" | awk -F, '{ print NF }')" -v d="$work/e" 'NR > 1 {
      if (!($ec in index_of)) { index_of[$ec] = n++; print $ec > (d "/elements.txt") }
      f = sprintf("%s/e%03d.dat", d, index_of[$ec])
      print $fc, $ma, $mo, $(n_after + mo), $pa, $po, $(n_after + po) > f
    }'
count=$(wc -l <"$work/e/elements.txt")
cols=$(awk -v n="$count" 'BEGIN { c = int(sqrt(n)); if (c * c < n) c++; print c }')
rows=$(awk -v n="$count" -v c="$cols" 'BEGIN { print int((n + c - 1) / c) }')
for kind in mag phase; do
  {
    echo "set terminal $terminal size $((cols * 360)),$((rows * 260 + 40))"
    echo "set output '$out_dir/loop_bode_$kind.png'"
    echo "set multiplot layout $rows,$cols title 'the loop ($kind): measured (points), model as given (grey), final model (red)'"
    echo "set logscale x; set grid; set key off; set format x '%g'"
    if [[ $kind == mag ]]; then echo "set logscale y; set format y '%.0e'"; else echo "set yrange [-180:180]; set ytics 90"; fi
    e=0
    while IFS= read -r name; do
      f=$(printf '%s/e/e%03d.dat' "$work" "$e")
      echo "set title '$name'"
      if [[ $kind == mag ]]; then
        echo "plot '$f' using 1:2 with points pt 7 ps 0.3 lc rgb '#1f77b4', '' using 1:4 with lines lw 1 lc rgb '#999999', '' using 1:3 with lines lw 1.5 lc rgb '#d62728'"
      else
        echo "plot '$f' using 1:5 with points pt 7 ps 0.3 lc rgb '#1f77b4', '' using 1:7 with lines lw 1 lc rgb '#999999', '' using 1:6 with lines lw 1.5 lc rgb '#d62728'"
      fi
      e=$((e + 1))
    done <"$work/e/elements.txt"
    echo "unset multiplot"
  } >"$work/bode-$kind.gp"
  gnuplot "$work/bode-$kind.gp"
done
ls "$out_dir"/loop_*.png
