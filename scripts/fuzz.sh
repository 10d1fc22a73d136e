#!/usr/bin/env bash
# Fuzzes every file reader with libFuzzer (clang, AddressSanitizer, UBSan): installs clang and its
# runtime when missing, configures and builds ./build-fuzz (-DSTAGEFIT_BUILD_FUZZERS=ON), then runs
# each target of tests/fuzz/ for a fixed time (or number of inputs) on a fresh copy of its seeds (tests/fuzz/corpus/) and
# stored crash inputs (tests/fuzz/regressions/). Fails when a target crashes, hangs (-timeout), uses
# more than 2 GB (-rss_limit_mb), leaks or throws anything but InputError. Crashing inputs go to
# build-fuzz/artifacts/<target>/, logs to build-fuzz/logs/.
#
# Usage: bash scripts/fuzz.sh [--seconds N | --runs N [--seed S]] [--targets a,b] [--jobs N] [--keep-corpus]
#        bash scripts/fuzz.sh --replay         every input of tests/fuzz/regressions/ and corpus/ once
#        bash scripts/fuzz.sh --make-corpus    regenerate the seeds of tests/fuzz/corpus/
#   --seconds N      time per target (default 15: about 1.5 minutes for all of them)
#   --runs N         instead of a time, N executions per target from a fixed seed (--seed, default
#                    1), as run after a change to a reader: the same amount of work on every machine
#                    however fast (the coverage feedback still varies a little); exploring for new
#                    failures is for --seconds
#   --targets a,b    only these targets (names as in tests/fuzz/, e.g. uff_measurement_fuzz)
#   --jobs N         parallel fuzzing processes per target (libFuzzer -fork=N; default 1)
#   --keep-corpus    keep and grow build-fuzz/corpus/<target>/ across runs instead of starting
#                    from the seeds each time (for long runs)
# Environment: STAGEFIT_FUZZ_BUILD_DIR (default build-fuzz); STAGEFIT_FUZZ_V73=1 also fuzzes v7.3
# (HDF5) .mat inputs, which the .mat targets skip by default (docs/reliability.md, Fuzzing).
set -euo pipefail
cd "$(dirname "$0")/.."

mode=fuzz
seconds=15
runs=0
seed=1
jobs=1
keep_corpus=0
only=""
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds="$2"; shift 2 ;;
    --runs) runs="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --targets) only="$2"; shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --keep-corpus) keep_corpus=1; shift ;;
    --replay) mode=replay; shift ;;
    --make-corpus) mode=make-corpus; shift ;;
    -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
    *) echo "fuzz: unknown argument '$1' (see --help)" >&2; exit 1 ;;
  esac
done

all_targets=(model_file_fuzz mat_measurement_fuzz raw_hammer_fuzz uff_measurement_fuzz
             csv_measurement_fuzz record_csv_fuzz)
# Largest input per target, bytes: room for the seeds and for the structures being fuzzed.
declare -A max_len=([model_file_fuzz]=16384 [mat_measurement_fuzz]=32768 [raw_hammer_fuzz]=32768
                    [uff_measurement_fuzz]=16384 [csv_measurement_fuzz]=8192 [record_csv_fuzz]=8192)
targets=("${all_targets[@]}")
if [ -n "$only" ]; then
  IFS=, read -r -a targets <<<"$only"
  for t in "${targets[@]}"; do
    [ -n "${max_len[$t]:-}" ] || { echo "fuzz: unknown target '$t' (${all_targets[*]})" >&2; exit 1; }
  done
fi

packages=(clang libclang-rt-14-dev cmake ninja-build pkg-config libeigen3-dev libfftw3-dev libmatio-dev zlib1g-dev libhdf5-dev
          libtomlplusplus-dev libceres-dev libnlopt-cxx-dev libnlopt-dev nlohmann-json3-dev libcli11-dev)
bash scripts/install-packages.sh fuzz "${packages[@]}"

build_dir="${STAGEFIT_FUZZ_BUILD_DIR:-build-fuzz}"
export LSAN_OPTIONS="suppressions=$PWD/tests/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
CC=clang CXX=clang++ cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DSTAGEFIT_BUILD_FUZZERS=ON -DSTAGEFIT_BUILD_TESTS=OFF -DSTAGEFIT_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$build_dir" -j"$(nproc)"
bin="$build_dir/fuzz"

if [ "$mode" = make-corpus ]; then
  corpus=tests/fuzz/corpus
  "$bin/stagefit_fuzz_make_corpus" "$corpus"
  # Shipped text files as seeds (the large records cut to their first lines).
  mkdir -p "$corpus/model_file_fuzz" "$corpus/record_csv_fuzz"
  cp fitting/microstation.toml "$corpus/model_file_fuzz/microstation.toml"
  sed -n '/^```toml$/,/^```$/p' docs/model-file.md | sed '1d;$d' >"$corpus/model_file_fuzz/model-file-doc.toml"
  for f in measurements/disturbance/*.csv; do
    head -n 40 "$f" >"$corpus/record_csv_fuzz/$(basename "$f")"
  done
  du -sh "$corpus"
  exit 0
fi

# Each input once, without fuzzing: the inputs that once crashed and the seeds.
if [ "$mode" = replay ]; then
  status=0
  for t in "${targets[@]}"; do
    inputs=()
    for d in tests/fuzz/regressions/$t tests/fuzz/corpus/$t; do
      [ -d "$d" ] && while IFS= read -r -d '' f; do inputs+=("$f"); done < <(find "$d" -type f -print0)
    done
    [ ${#inputs[@]} -gt 0 ] || continue
    log="$build_dir/logs/$t.replay.log"
    mkdir -p "$(dirname "$log")"
    if STAGEFIT_FUZZ_V73=1 "$bin/$t" -timeout=10 -rss_limit_mb=2048 "${inputs[@]}" >"$log" 2>&1; then
      printf '%-22s %5d inputs  ok\n' "$t" "${#inputs[@]}"
    else
      printf '%-22s %5d inputs  FAILED (log: %s)\n' "$t" "${#inputs[@]}" "$log"
      tail -n 40 "$log"
      status=1
    fi
  done
  exit $status
fi

# One target: fuzzes it and writes its row of the table to $build_dir/logs/<target>.row; its status
# is the target's.
fuzz_target() {
  local t="$1"
  local work="$build_dir/corpus/$t" artifacts="$build_dir/artifacts/$t/" log="$build_dir/logs/$t.log"
  [ "$keep_corpus" = 1 ] || rm -rf "$work"
  mkdir -p "$work" "$artifacts" "$(dirname "$log")"
  # Seeds, and the inputs that once crashed (they must keep passing under the sanitizers).
  for d in tests/fuzz/corpus/$t tests/fuzz/regressions/$t; do
    [ -d "$d" ] && cp -n "$d"/* "$work/" 2>/dev/null || true
  done
  local options=(-max_len="${max_len[$t]}" -timeout=10 -rss_limit_mb=2048
                 -print_final_stats=1 -close_fd_mask=3 -artifact_prefix="$artifacts")
  if [ "$runs" -gt 0 ]; then
    options+=(-runs="$runs" -seed="$seed")
  else
    options+=(-max_total_time="$seconds")
  fi
  [ "$jobs" -gt 1 ] && options+=(-fork="$jobs" -ignore_crashes=0)
  local result=ok started elapsed executions rate
  started=$(date +%s)
  "$bin/$t" "${options[@]}" "$work" >"$log" 2>&1 || result=FAILED
  elapsed=$(( $(date +%s) - started ))
  executions=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | tail -n 1 | grep -o '[0-9]*$' || true)
  [ -n "$executions" ] || executions=$(grep -o '#[0-9]*' "$log" | tail -n 1 | tr -d '#' || true)
  rate=$(( ${executions:-0} / (elapsed > 0 ? elapsed : 1) ))
  printf '%-22s %8s %12s %8s  %s\n' "$t" "$elapsed" "${executions:-?}" "$rate" "$result" >"$build_dir/logs/$t.row"
  [ "$result" = ok ]
}

# The targets run side by side, as many at a time as the machine has cores divided by --jobs (each
# is one process, or --jobs of them): the same work per target, in a fraction of the time.
parallel=$(( $(nproc) / jobs ))
[ "$parallel" -ge 1 ] || parallel=1
mkdir -p "$build_dir/logs"
declare -A pid_of=()
for t in "${targets[@]}"; do
  rm -f "$build_dir/logs/$t.row"
  while [ "$(jobs -rp | wc -l)" -ge "$parallel" ]; do wait -n || true; done
  fuzz_target "$t" &
  pid_of[$t]=$!
done
status=0
failed=()
for t in "${targets[@]}"; do
  wait "${pid_of[$t]}" || { status=1; failed+=("$t"); }
done
printf '%-22s %8s %12s %8s  %s\n' target seconds executions exec/s result
for t in "${targets[@]}"; do
  cat "$build_dir/logs/$t.row" 2>/dev/null || printf '%-22s %8s %12s %8s  %s\n' "$t" ? ? ? FAILED
done
for t in "${failed[@]}"; do
  echo "---- $t: $build_dir/logs/$t.log (crashing input in $build_dir/artifacts/$t/)" >&2
  grep -v '^#\|^INFO\|^MS:\|^NEW\|^REDUCE\|^pulse' "$build_dir/logs/$t.log" | tail -n 60 >&2
done
exit $status
