#!/usr/bin/env bash
# noisemon against the SciPy way (tests/bench/scipy_way.py), side by side on the same run directories:
#
#   tests/bench/vs_scipy.sh BUILD_DIR [WORK_DIR]
#
# Case 1: 250 cycles at 3050 rpm (sim idle_mi18), 0.1 deg encoder, 10 microphones at 51.2 kHz, linear model.
# Case 2: 50 cycles, the same with a 0.2 bar rms pressure-chain floor (sim --pressure-floor 0.2), nl_damper;
#   scipy_way.py three times: the spline straight onto 40 kHz, and --oversample 4 (anti-aliased: the floor above
#   20 kHz folds into the band otherwise), both with the model by the trapezoidal rule (--ode tustin); then
#   --oversample 4 with the model by scipy.integrate.solve_ivp (--ode solve_ivp; about 5 s per second of engine
#   time). tests/bench/vs_scipy_report.py prints each case.
# Each case times `noisemon import` + `noisemon replay --model M` against `scipy_way.py --model M` (whole processes:
# the Python start and the NumPy/SciPy imports count, as the program start does for noisemon); REPEATS=N (default
# 1) runs each N times and keeps the fastest. Prints wall and CPU seconds, x real time (engine time / wall time),
# the ratio noisemon/SciPy, and how far SciPy's levels lie from noisemon's (same cycles, matched by start time).
# Needs /usr/bin/python3 with numpy and scipy (scripts/install-deps.sh). WORK_DIR (default: a temporary directory,
# removed at the end) holds the runs, logs and CSVs.
set -euo pipefail

build=${1:?usage: tests/bench/vs_scipy.sh BUILD_DIR [WORK_DIR]}
noisemon=$(cd "$build" && pwd)/daemon/noisemon
here=$(cd "$(dirname "$0")" && pwd)
python=/usr/bin/python3
repeats=${REPEATS:-1}
[ -x "$noisemon" ] || { echo "vs_scipy.sh: $noisemon not found: build the target noisemon first" >&2; exit 1; }
"$python" -c 'import numpy, scipy' 2>/dev/null ||
  { echo "vs_scipy.sh: $python lacks numpy/scipy: apt-get install python3-numpy python3-scipy" >&2; exit 1; }
if [ $# -ge 2 ]; then work=$2; mkdir -p "$work"; else work=$(mktemp -d); trap 'rm -rf "$work"' EXIT; fi
epoch=1000000000000  # import's frame 0 at this utime: a report's start time is (utime - epoch) / 1e6 s

# best_time OUT CMD...: runs CMD `repeats` times (output to $work/last.log), writes "wall cpu" of the fastest to OUT.
best_time() {
  local out=$1 best="" t
  shift
  for _ in $(seq "$repeats"); do
    t=$( { TIMEFORMAT='%R %U %S'; time "$@" >"$work/last.log" 2>&1; } 2>&1 ) ||
      { echo "vs_scipy.sh: failed: $*" >&2; cat "$work/last.log" >&2; exit 1; }
    t=$(awk '{ printf "%.3f %.3f", $1, $2 + $3 }' <<<"$t")
    if [ -z "$best" ] || awk -v a="${t%% *}" -v b="${best%% *}" 'BEGIN { exit !(a < b) }'; then best=$t; fi
  done
  echo "$best" >"$out"
}

# run_case NAME CYCLES FLOOR_BAR MODEL VARIANT...: generates the run, times noisemon and scipy_way.py (once per
# VARIANT: K for --oversample K, or K:ODE for --oversample K --ode ODE), prints the case's rows.
logs=()
run_case() {
  local name=$1 cycles=$2 floor=$3 model=$4 v k ode
  shift 4
  local run="$work/$name/idle_mi18"
  "$noisemon" sim --condition idle_mi18 --cycles "$cycles" --encoder-deg 0.1 --pressure-floor "$floor" \
    -o "$work/$name" --force --no-progress >/dev/null 2>&1
  local engine_s
  engine_s=$(tail -n 1 "$run/pressure.csv" | cut -d, -f1)
  best_time "$work/$name.import" "$noisemon" import "$run" -o "$work/$name.lcmlog" --epoch-utime $epoch --no-progress
  best_time "$work/$name.replay" "$noisemon" replay "$work/$name.lcmlog" --model "$model" \
    --csv "$work/$name.noisemon.csv" --no-progress
  for v in "$@"; do
    k=${v%%:*} ode=${v#"$k"}
    best_time "$work/$name.scipy$v" "$python" "$here/scipy_way.py" "$run" --model "$model" --oversample "$k" \
      ${ode:+--ode "${ode#:}"} --csv "$work/$name.scipy$v.csv" --quiet
    cp "$work/last.log" "$work/$name.scipy$v.log"
    logs+=("$work/$name.scipy$v.log")
  done
  "$python" "$here/vs_scipy_report.py" "$name ($cycles cycles, $model, floor $floor bar)" "$engine_s" "$work/$name" \
    $epoch "$@"
}

echo "noisemon $(cd "$here/../.." && git describe --always --dirty 2>/dev/null || echo '?') vs SciPy $("$python" -c \
  'import numpy, scipy; print(scipy.__version__ + ", NumPy " + numpy.__version__)'); $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
printf '  %-44s %8s %8s %10s\n' "" "wall s" "CPU s" "real time"
run_case long 250 0.02 linear 1
run_case noisy 50 0.2 nl_damper 1:tustin 4:tustin 4:solve_ivp
for log in "${logs[@]}"; do
  echo "scipy_way.py's stages, $(basename "$log" .log):"
  grep '^  ' "$log"
done
