#!/usr/bin/env bash
# Builds noisemon with a sanitizer in a tree of its own and runs there the tests it finds something in (ctest entries
# sanitize_address and sanitize_thread; what each covers and leaves out: docs/benchmarks.md "Sanitizers").
#   run_sanitized.sh address BUILD_DIR [NOISEMON]  AddressSanitizer + UndefinedBehaviorSanitizer (and LeakSanitizer):
#                                                  the parsers and decoders, the rings, the numerical kernels
#                                                  (sanitize_address_tests, tests/sanitize/CMakeLists.txt)
#   run_sanitized.sh thread BUILD_DIR [NOISEMON]   ThreadSanitizer: the threaded code (sanitize_thread_tests) and the
#                                                  end-to-end tests over LCM (a sanitized noisemond)
# NOISEMON: an unsanitized noisemon tool for the subscribers the tests start (default: the tree's parent build's
# daemon/noisemon), so the tree builds no more than what it checks. Any report fails the run (halt_on_error); the
# sanitizer's report is in the test output.
set -euo pipefail
kind="${1:?usage: $0 address|thread BUILD_DIR [NOISEMON]}"
build="${2:?usage: $0 address|thread BUILD_DIR [NOISEMON]}"
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
tool="${3:-$(dirname "$build")/daemon/noisemon}"
jobs="$(nproc)"
[ -x "$tool" ] || { echo "$0: no noisemon tool at $tool (build the main tree first, or name one)" >&2; exit 2; }

case "$kind" in
  address) targets="sanitize_address_tests"; label=asan ;;
  thread) targets="sanitize_thread_tests e2e_test_lcm"; label=tsan ;;
  *) echo "$0: unknown sanitizer '$kind' (address or thread)" >&2; exit 2 ;;
esac

start=$(date +%s)
bash "$src/tests/sanitize/configure_sanitized.sh" "$kind" "$build" "$tool"
if [ "$kind" = address ] && grep -q '^NOISEMON_FUZZ:BOOL=ON' "$build/CMakeCache.txt"; then targets="$targets fuzzers_quick"; fi
# shellcheck disable=SC2086
cmake --build "$build" --target $targets  # ninja's own job count, as the main build
built=$(date +%s)

export ASAN_OPTIONS="abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
# tsan.supp: the one false report of uninstrumented GLib, inside LCM (the file says why).
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$src/tests/sanitize/tsan.supp"
cd "$build"
status=0
ctest --output-on-failure -j "$jobs" --timeout 1200 -L "^$label\$" || status=$?
if [ "$kind" = thread ]; then
  # End to end over LCM with the sanitized daemon (e2e_test_lcm's tests, two at a time: each runs an unpaced daemon).
  # The lcm-logger round trip is left to the normal build: it checks a recording's numbers, not threads.
  ctest --output-on-failure -j "$jobs" --timeout 1200 -L '^e2e$' -R '^(EndToEnd|Presets/ModelMismatch)\.' \
    -E 'LcmLogger' || status=$?
fi
if [ "$kind" = address ]; then
  # The quick fuzz targets, built above in this tree: each fuzzed 5 s over its corpus (skipped, 77, without clang; a
  # failure under CI=true). The replay's, whose build is the whole daemon, is run by hand (tests/fuzz/run_fuzzers.sh).
  fuzz=0
  bash "$src/tests/fuzz/run_fuzzers.sh" --build-dir "$build" --seconds 5 --jobs "$jobs" --quick || fuzz=$?
  [ "$fuzz" -eq 0 ] || [ "$fuzz" -eq 77 ] || status=$fuzz
fi
echo "sanitize $kind: build $((built - start)) s, tests $(($(date +%s) - built)) s" >&2
exit $status
