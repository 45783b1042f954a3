#!/usr/bin/env bash
# Builds noisemon with a sanitizer in a tree of its own and runs part of the suite there (ctest entries
# sanitize_address and sanitize_thread; see docs/benchmarks.md "Sanitizers").
#   run_sanitized.sh address BUILD_DIR   AddressSanitizer + UndefinedBehaviorSanitizer (and LeakSanitizer): the
#                                        unit suite, every test labelled dsp, model, drivers, daemon or cli but the
#                                        whole-diagnosis runs
#   run_sanitized.sh thread BUILD_DIR    ThreadSanitizer: the threaded tests (rings, worker threads, sources,
#                                        the pipeline, replay, the daemon's service, end to end over LCM)
# Any report fails the run (halt_on_error); the sanitizer's report is in the test output.
set -euo pipefail
kind="${1:?usage: $0 address|thread BUILD_DIR}"
build="${2:?usage: $0 address|thread BUILD_DIR}"
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
jobs="$(nproc)"

case "$kind" in
  address)
    sanitize="address,undefined"
    labels='^(dsp|model|drivers|daemon|cli)$'
    targets=$(cd "$src/tests" && ls dsp/test_*.cpp model/test_*.cpp drivers/test_*.cpp daemon/test_*.cpp cli/test_*.cpp |
              sed -e 's|/|_|' -e 's|\.cpp$||')
    targets="$targets noisemond noisemon"
    ;;
  thread)
    sanitize="thread"
    programs="dsp_test_spsc_ring drivers_test_worker_thread drivers_test_sim_source drivers_test_comedi_source
              drivers_test_can_source drivers_test_lcm_source daemon_test_pipeline cli_test_replay
              daemon_test_service daemon_test_sources e2e/e2e_test_lcm"
    targets="$(for p in $programs; do basename "$p"; done) noisemond noisemon"
    ;;
  *) echo "$0: unknown sanitizer '$kind' (address or thread)" >&2; exit 2 ;;
esac

start=$(date +%s)
# -O1 -g1: quicker to build than the main tree's -O2 -g, still line numbers in every report (assertions on).
cmake -S "$src" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
  -DNOISEMON_SANITIZE="$sanitize" -DNOISEMON_BUILD_BENCHMARKS=OFF >/dev/null
# shellcheck disable=SC2086
cmake --build "$build" -j "$jobs" --target $targets
built=$(date +%s)

export ASAN_OPTIONS="abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
# tsan.supp: the one false report of uninstrumented GLib, inside LCM (the file says why).
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$src/tests/sanitize/tsan.supp"
cd "$build"
status=0
if [ "$kind" = address ]; then
  # Less the whole-diagnosis runs of tests/cli/test_diagnose.cpp (minutes of fitting each under the sanitizer;
  # the fitting code is exercised by the model tests and `noisemon fit`).
  ctest --output-on-failure -j "$jobs" --timeout 1200 -L "$labels" \
    -E '^(Diagnose|[A-Za-z]+/(WithheldEffect|WithheldEffectAtTheRealFloor|NullDataset))\.' || status=$?
else
  # The threaded programs one after another (each runs its own threads; TSan slows them five- to fifteen-fold).
  for p in $programs; do
    echo "== $p" >&2
    "$build/tests/$p" --gtest_brief=1 || status=$?
  done
fi
echo "sanitize $kind: build $((built - start)) s, tests $(($(date +%s) - built)) s" >&2
exit $status
