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
  address) sanitize="address,undefined"; targets="sanitize_address_tests"; label=asan ;;
  thread) sanitize="thread"; targets="sanitize_thread_tests e2e_test_lcm"; label=tsan ;;
  *) echo "$0: unknown sanitizer '$kind' (address or thread)" >&2; exit 2 ;;
esac

# clang (the sanitizers' own compiler, as the fuzz targets'): it builds these trees in 0.6 of GCC's time. GCC when
# there is no clang.
compilers=()
for c in clang++-14 clang++; do
  if command -v "$c" >/dev/null && command -v "${c/clang++/clang}" >/dev/null; then
    compilers=(-DCMAKE_CXX_COMPILER="$c" -DCMAKE_C_COMPILER="${c/clang++/clang}")
    break
  fi
done
start=$(date +%s)
# -O1 -g1: quicker to build than the main tree's -O2, still line numbers in every report (assertions on).
cmake -S "$src" -B "$build" -G Ninja "${compilers[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DNOISEMON_SANITIZE="$sanitize" -DNOISEMON_BUILD_BENCHMARKS=OFF \
  -DNOISEMON_TOOL_PATH="$tool" >/dev/null
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
echo "sanitize $kind: build $((built - start)) s, tests $(($(date +%s) - built)) s" >&2
exit $status
