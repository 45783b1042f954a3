#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz in the AddressSanitizer tree (clang; tests/sanitize/configure_sanitized.sh)
# and runs each for a bounded time over its seed corpus; fails on any crash, leak, timeout or out-of-memory. The
# sanitize_address stage runs the quick ones for 5 s a target after its unit tests; run it by hand for longer sessions,
# and for the replay's (the daemon's cycle processing) after a change there:
#
#   tests/fuzz/run_fuzzers.sh [--build-dir DIR] [--seconds N] [--jobs N] [--quick] [TARGET...]
#
#   --build-dir DIR  the AddressSanitizer tree (default: build/sanitize-address); corpora, crash artifacts and logs
#                    stay in it
#   --seconds N      fuzzing time per target (default 15)
#   --jobs N         targets fuzzed at once, also the build's -j (default 2)
#   --quick          every target but those whose build is slow (the replay's: the whole daemon), as the test command
#   TARGET           targets to run, `candump` or `fuzz_candump` (default: every target, as listed in DIR/fuzz_targets.txt)
#   Extra libFuzzer flags: NOISEMON_FUZZ_FLAGS="-max_len=65536 -only_ascii=1" tests/fuzz/run_fuzzers.sh ...
#
# Exit status: 0 clean, 1 a finding or a build failure, 77 no clang here (a skip; a failure when CI is set).
set -euo pipefail
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="$src/build/sanitize-address"
seconds=15
jobs=2
list=fuzz_targets
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build="$2"; shift 2 ;;
    --seconds) seconds="$2"; shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --quick) list=fuzzers_quick; shift ;;
    -h|--help) sed -n '2,17p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "run_fuzzers.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) targets+=("fuzz_${1#fuzz_}"); shift ;;
  esac
done
mkdir -p "$build"
build="$(cd "$build" && pwd)"

source "$(dirname "${BASH_SOURCE[0]}")/../support/under_ci.sh"

# clang with libFuzzer's runtime (Debian: clang, libclang-rt-14-dev).
missing_clang() {
  echo "fuzz: $1 (install clang and libclang-rt-14-dev: scripts/install-deps.sh)" >&2
  if under_ci; then exit 1; fi
  exit 77
}
cxx=""
for c in clang++-14 clang++; do  # configure_sanitized.sh's choice
  if command -v "$c" >/dev/null; then cxx="$c"; break; fi
done
[ -n "$cxx" ] || missing_clang "no clang++ found"
command -v "${cxx/clang++/clang}" >/dev/null || missing_clang "no ${cxx/clang++/clang} beside $cxx"
runtime="$("$cxx" -print-resource-dir)/lib/linux/libclang_rt.fuzzer-x86_64.a"
[ -f "$runtime" ] || missing_clang "$cxx has no libFuzzer runtime ($runtime)"

# Configure (cheap when nothing changed: the sanitize_address stage configured it the same way) and build the fuzz
# targets.
start=$SECONDS
bash "$src/tests/sanitize/configure_sanitized.sh" address "$build" >"$build/configure.log" 2>&1 ||
  { cat "$build/configure.log" >&2; echo "fuzz: configuring $build failed" >&2; exit 1; }
build_targets=("${targets[@]}")
[ ${#targets[@]} -gt 0 ] || build_targets=("${list/fuzz_targets/fuzzers}")
cmake --build "$build" --target "${build_targets[@]}" fuzz_make_seeds -j "$jobs" >"$build/build.log" 2>&1 ||
  { tail -n 60 "$build/build.log" >&2; echo "fuzz: building the fuzz targets failed (full log: $build/build.log)" >&2; exit 1; }
echo "fuzz: clang build ready in $((SECONDS - start)) s ($build)"

if [ ${#targets[@]} -eq 0 ]; then mapfile -t targets <"$build/$list.txt"; fi
rm -rf "$build/seeds"
"$build/tests/fuzz/fuzz_make_seeds" "$build/seeds"
mkdir -p "$build/artifacts" "$build/logs"

# One target: new inputs go to the first corpus directory (in the build tree), seeds are only read.
run_one() {
  local target="$1" name="${1#fuzz_}" exe="$build/tests/fuzz/$1"
  [ -x "$exe" ] || { echo "fuzz: no such target $target (see $build/fuzz_targets.txt)" >&2; return 1; }
  local corpora=("$build/corpus/$name") flags=()
  mkdir -p "$build/corpus/$name"
  [ -d "$src/tests/fuzz/corpus/$name" ] && corpora+=("$src/tests/fuzz/corpus/$name")
  [ -d "$build/seeds/$name" ] && corpora+=("$build/seeds/$name")
  [ "$name" = dbc ] && corpora+=("$src/tests/data/dbc")  # the real DBC files the unit tests read
  local dict="$name"
  case "$name" in replay|recordings_log|lcm_log_reader) dict=lcm_log ;; esac
  [ -f "$src/tests/fuzz/$dict.dict" ] && flags+=("-dict=$src/tests/fuzz/$dict.dict")
  # shellcheck disable=SC2086
  "$exe" "${corpora[@]}" "${flags[@]}" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=1024 \
    -artifact_prefix="$build/artifacts/$name-" -print_final_stats=1 ${NOISEMON_FUZZ_FLAGS:-} \
    >"$build/logs/$name.log" 2>&1
}

failed=()
pids=()
names=()
report() {  # waits for the i-th running target
  local i="$1" name="${names[$1]}"
  if wait "${pids[$i]}"; then
    echo "fuzz: $name ok ($(grep -o 'Done [0-9]* runs' "$build/logs/${name#fuzz_}.log" | tail -n 1 || true))"
  else
    failed+=("$name")
    echo "fuzz: $name FAILED; end of $build/logs/${name#fuzz_}.log:" >&2
    [ -f "$build/logs/${name#fuzz_}.log" ] &&
      grep -v -e '^#[0-9]' -e '^Log event has invalid' "$build/logs/${name#fuzz_}.log" | tail -n 40 >&2
    echo "fuzz: reproduce with $build/tests/fuzz/$name <artifact> (artifacts: $build/artifacts/)" >&2
  fi
}
for t in "${targets[@]}"; do
  run_one "$t" &
  pids+=($!)
  names+=("$t")
  if [ $(( ${#pids[@]} % jobs )) -eq 0 ]; then
    for i in $(seq $(( ${#pids[@]} - jobs )) $(( ${#pids[@]} - 1 ))); do report "$i"; done
  fi
done
for i in $(seq $(( ${#pids[@]} - ${#pids[@]} % jobs )) $(( ${#pids[@]} - 1 ))); do report "$i"; done

echo "fuzz: ${#targets[@]} targets, ${seconds} s each, total $((SECONDS - start)) s"
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: findings in ${failed[*]}" >&2
  exit 1
fi
