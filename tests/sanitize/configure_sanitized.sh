#!/usr/bin/env bash
# Configures a sanitizer's tree, one configuration for everything built in it (run_sanitized.sh, and
# tests/fuzz/run_fuzzers.sh for the AddressSanitizer tree's fuzz targets), so neither rebuilds the other's objects:
#   configure_sanitized.sh address|thread BUILD_DIR [NOISEMON]
# NOISEMON: the unsanitized noisemon tool the tree's tests start (kept from the last configure when not given).
# With clang (the sanitizers' own compiler: it builds these trees in 0.6 of GCC's time), the AddressSanitizer tree
# also holds the libFuzzer targets (-DNOISEMON_FUZZ=ON). GCC when there is no clang, without them.
set -euo pipefail
kind="${1:?usage: $0 address|thread BUILD_DIR [NOISEMON]}"
build="${2:?usage: $0 address|thread BUILD_DIR [NOISEMON]}"
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
case "$kind" in
  address) sanitize="address,undefined" ;;
  thread) sanitize="thread" ;;
  *) echo "$0: unknown sanitizer '$kind' (address or thread)" >&2; exit 2 ;;
esac
options=()
for c in clang++-14 clang++; do
  if command -v "$c" >/dev/null && command -v "${c/clang++/clang}" >/dev/null; then
    options=(-DCMAKE_CXX_COMPILER="$c" -DCMAKE_C_COMPILER="${c/clang++/clang}")
    [ "$kind" = address ] && options+=(-DNOISEMON_FUZZ=ON)
    break
  fi
done
[ -n "${3:-}" ] && options+=(-DNOISEMON_TOOL_PATH="$3")
# -O1 -g1: quicker to build than the main tree's -O2, still line numbers in every report (assertions on).
cmake -S "$src" -B "$build" -G Ninja "${options[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DNOISEMON_SANITIZE="$sanitize" -DNOISEMON_BUILD_BENCHMARKS=OFF >/dev/null
