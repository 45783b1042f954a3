#!/usr/bin/env bash
# The project's two set-up commands (see README):
#   scripts/bootstrap.sh run    install dependencies, build, run noisemond on the simulated engine (Ctrl-C stops)
#   scripts/bootstrap.sh test   install dependencies, build, run the whole test suite
# Extra arguments after `run` go to noisemond (e.g. --config FILE).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
mode="${1:-}"
shift || true
case "$mode" in
  run|test) ;;
  *) echo "usage: $0 run [noisemond options] | test" >&2; exit 2 ;;
esac

bash "$here/scripts/install-deps.sh"
build="${NOISEMON_BUILD_DIR:-$here/build}"
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo
# Three times as many jobs as cores: one compiles while another waits on the disk, and on a machine other work loads,
# the kernel shares the cores between runnable tasks, not commands: beside two busy loops on two cores, 6 jobs get
# 1.5 cores where 4 got 1.33 and ninja's own 3 got 1.2 (docs/benchmarks.md, "The test command"). The largest
# compilations take about 1.5 GB each.
cmake --build "$build" -j "$((3 * $(nproc)))"

if [ "$mode" = run ]; then
  exec "$build/daemon/noisemond" --live "$@"
fi
cd "$build"
status=0
jobs="$(nproc)"
stage_start=0
stage_cpu=0
stage() {  # the time and CPU each stage took, for docs/benchmarks.md ("The test command")
  # CPU: user + system of every finished child so far, the second line of `times` (run in this shell: in a pipe or a
  # $(...) it would run in a subshell, which has no children).
  times >"$build/.times"
  local cpu
  cpu=$(awk 'NR == 2 { t = 0; for (i = 1; i <= 2; i++) { split($i, a, /[ms]/); t += a[1] * 60 + a[2] } printf "%d", t }' \
    "$build/.times")
  echo "noisemon test: $1 took $((SECONDS - stage_start)) s ($((cpu - stage_cpu)) s of CPU)" >&2
  stage_start=$SECONDS
  stage_cpu=$cpu
}
stage "installing and building"
# The unit suite and lint; the slow proofs (label slow) are run by hand: ctest -L slow. Twice as many tests as cores,
# as the build: many tests wait on a child process, a pipe or a clock for part of their time, and on a machine other
# work loads, the suite keeps its share of the cores.
ctest --output-on-failure -j "$((2 * jobs))" --timeout 600 -LE 'sanitize|e2e|slow' || status=$?
stage "the suite"
# The end-to-end tests mostly wait on the simulated engine's real time: twice as many at once as there are cores.
# Alone: beside a sanitizer's build on a machine already loaded, a daemon's start outgrew its allowance.
ctest --output-on-failure -j "$((2 * jobs))" --timeout 600 -L e2e || status=$?
stage "the end-to-end tests"
# AddressSanitizer + UndefinedBehaviorSanitizer (with the fuzz targets) and ThreadSanitizer, each in a tree of its own
# (docs/benchmarks.md "Sanitizers"), side by side: each tree's links and its tests' waits leave cores the other
# uses. Run even when the suite failed.
ctest --output-on-failure -j "$((2 * jobs))" --timeout 3000 -L sanitize || status=$?
stage "the sanitizers"
exit $status
