#!/usr/bin/env bash
# Renders the tables written by `stagefit compare --out-dir DIR` as PNG files (gnuplot-nox is enough):
#   compare_bode_mag.png, compare_bode_phase.png   measured against model, one panel per used element
#                                                   (bodies space: compare_<body>_bode_mag.png ... per body)
#   compare_raw_bode_mag.png, ..._phase.png         the same for the raw channels (if compare_frf_raw.csv)
#   compare_error_map.png                           error by element (rows) and third-octave band (columns)
#   compare_modes.md                                the mode pairing table
#
#   scripts/plot_compare.sh DIR                -> the files in DIR
#   OUT_DIR=plots scripts/plot_compare.sh DIR  -> the files in plots/
set -euo pipefail

if [[ $# -ne 1 ]]; then
  echo "usage: $0 DIR   (DIR written by stagefit compare --out-dir DIR)" >&2
  exit 1
fi
command -v gnuplot >/dev/null || { echo "$0: gnuplot not found" >&2; exit 1; }
dir=$1
[[ -f "$dir/compare_frf.csv" ]] || { echo "$0: no file $dir/compare_frf.csv" >&2; exit 2; }
out_dir=${OUT_DIR:-$dir}
mkdir -p "$out_dir"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

terminal="pngcairo noenhanced font ',9'"
gnuplot -e "set terminal pngcairo" -e "exit" 2>/dev/null || terminal="png noenhanced"

# bode CSV PREFIX TITLE: one panel per element, magnitude and phase in two PNGs.
bode() {
  local csv=$1 prefix=$2 title=$3
  local split="$work/$prefix"
  mkdir -p "$split"
  # One whitespace-separated file per element: freq meas_abs model_abs meas_phase model_phase.
  awk -F, -v d="$split" 'NR > 1 {
      if (!($2 in index_of)) { index_of[$2] = n++; print $2 > (d "/elements.txt") }
      f = sprintf("%s/e%03d.dat", d, index_of[$2])
      print $1, $9, $10, $11, $12 > f
    }' "$csv"
  local count
  count=$(wc -l <"$split/elements.txt")
  local cols rows
  cols=$(awk -v n="$count" 'BEGIN { c = int(sqrt(n)); if (c * c < n) c++; print c }')
  rows=$(awk -v n="$count" -v c="$cols" 'BEGIN { print int((n + c - 1) / c) }')
  local width=$((cols * 360)) height=$((rows * 260 + 40))
  for kind in mag phase; do
    local script="$work/$prefix-$kind.gp"
    {
      echo "set terminal $terminal size $width,$height"
      echo "set output '$out_dir/${prefix}_bode_$kind.png'"
      echo "set multiplot layout $rows,$cols title '$title ($kind): measured (points) vs model (line)'"
      echo "set logscale x; set grid; set key off; set format x '%g'"
      if [[ $kind == mag ]]; then echo "set logscale y; set format y '%.0e'"; else echo "set yrange [-180:180]; set ytics 90"; fi
      local e=0
      while IFS= read -r name; do
        local f
        f=$(printf '%s/e%03d.dat' "$split" "$e")
        echo "set title '$name'"
        if [[ $kind == mag ]]; then
          echo "plot '$f' using 1:2 with points pt 7 ps 0.3 lc rgb '#1f77b4', '' using 1:3 with lines lw 1.5 lc rgb '#d62728'"
        else
          echo "plot '$f' using 1:4 with points pt 7 ps 0.3 lc rgb '#1f77b4', '' using 1:5 with lines lw 1.5 lc rgb '#d62728'"
        fi
        e=$((e + 1))
      done <"$split/elements.txt"
      echo "unset multiplot"
    } >"$script"
    gnuplot "$script"
  done
}

# The bodies space (elements "<body>.<DoF>/<impact>"): one pair of plots per body.
bodies=$(awk -F, 'NR > 1 { split($2, a, "/"); n = index(a[1], "."); if (n > 0) print substr(a[1], 1, n - 1) }' \
           "$dir/compare_frf.csv" | awk '!seen[$0]++')
if [[ -n "$bodies" ]]; then
  while IFS= read -r body; do
    awk -F, -v b="$body." 'NR == 1 || index($2, b) == 1' "$dir/compare_frf.csv" >"$work/frf_$body.csv"
    bode "$work/frf_$body.csv" "compare_$body" "body $body"
  done <<<"$bodies"
else
  bode "$dir/compare_frf.csv" compare "compared elements"
fi
[[ -f "$dir/compare_frf_raw.csv" ]] && bode "$dir/compare_frf_raw.csv" compare_raw "raw channels"

# Error map: element x band matrix.
map="$dir/compare_element_band.csv"
if [[ -f "$map" ]]; then
  nb=$(awk -F, 'NR > 1 && $2 + 1 > n { n = $2 + 1 } END { print n + 0 }' "$map")
  ne=$(awk -F, 'NR > 1 && $1 + 1 > n { n = $1 + 1 } END { print n + 0 }' "$map")
  awk -F, -v nb="$nb" 'NR > 1 { v = ($5 == "nan") ? "NaN" : $5; row = row (row == "" ? "" : " ") v
      if ($2 == nb - 1) { print row; row = "" } }' "$map" >"$work/map.dat"
  ytics=$(awk -F, 'NR > 1 && $2 == 0 { printf "%s\"%s\" %d", (n++ ? ", " : ""), $3, $1 }' "$map")
  xtics=$(awk -F, 'NR > 1 && $1 == 0 { printf "%s\"%.3g\" %d", (n++ ? ", " : ""), $4, $2 }' "$map")
  gnuplot <<EOF
set terminal $terminal size $((300 + nb * 34)),$((160 + ne * 22))
set output '$out_dir/compare_error_map.png'
set title 'error |ln(H_model / H_meas)| by element and third-octave band (white: no point)'
set xlabel 'band centre [Hz]'
set xtics ($xtics) rotate by 60 right
set ytics ($ytics)
set xrange [-0.5:$nb - 0.5]
set yrange [$ne - 0.5:-0.5]
set cblabel 'error'
set palette defined (0 '#ffffcc', 0.3 '#fd8d3c', 0.6 '#e31a1c', 1 '#4a0016')
set cbrange [0:*]
unset key
plot '$work/map.dat' matrix with image
EOF
fi

# Mode pairing table as markdown.
modes="$dir/compare_modes.csv"
if [[ -f "$modes" ]]; then
  awk -F, 'BEGIN {
      print "# Mode pairing (CMIF peaks, MAC)\n"
      print "| kind | f meas [Hz] | f model [Hz] | df [%] | zeta meas [%] | zeta model [%] | MAC | model mode | dominant DoF |"
      print "|---|---|---|---|---|---|---|---|---|"
    }
    function pct(x) { return x == "" || x == "nan" ? "" : sprintf("%.2f", 100 * x) }
    function num(x, f) { return x == "" || x == "nan" ? "" : sprintf(f, x) }
    NR > 1 {
      printf "| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", $1, num($4, "%.2f"), num($5, "%.2f"),
        num($6, "%+.2f"), pct($7), pct($8), num($9, "%.3f"), ($10 == "" ? "" : "#" $10 " (" num($11, "%.2f") " Hz)"), $12
    }' "$modes" >"$out_dir/compare_modes.md"
fi
ls "$out_dir"/compare_*.png "$out_dir"/compare_modes.md 2>/dev/null
