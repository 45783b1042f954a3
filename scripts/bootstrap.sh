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
cmake --build "$build" -j "$(nproc)"

if [ "$mode" = run ]; then
  exec "$build/daemon/noisemond" --live "$@"
fi
cd "$build"
# The suite, then the sanitizer runs (label sanitize: each builds the project again in a tree of its own, so they
# come last and one at a time; docs/benchmarks.md "Sanitizers" says how long each takes). Both run even when the first fails.
status=0
ctest --output-on-failure -j "$(nproc)" --timeout 600 -LE sanitize || status=$?
ctest --output-on-failure --timeout 3000 -L sanitize || status=$?
exit $status
