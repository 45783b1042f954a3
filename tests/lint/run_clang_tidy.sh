#!/usr/bin/env bash
# clang-tidy with the checks of .clang-tidy over the project's sources a change touched: the .cpp files of cli,
# daemon, drivers, model and dsp changed by the commits after BASE, newest commit first, and the .cpp beside each
# changed header (a header is checked through the files that include it); at most MAX files (6-15 s each).
#
#   run_clang_tidy.sh SOURCE_DIR BUILD_DIR [BASE [MAX]]
#
# BASE: a commit (default HEAD~10), or "all" for every file (about as long as a build). MAX: default 8 (about a
# minute on two cores: the suite's share; 16 took two minutes of both cores, a sixth of the suite's CPU).
# BUILD_DIR must hold compile_commands.json (CMAKE_EXPORT_COMPILE_COMMANDS is on). Exit 0 clean, 1 with the findings, 77 (skipped) without clang-tidy or git
# history: a failure under CI for want of clang-tidy, which scripts/install-deps.sh installs.
set -euo pipefail
src="$(cd "$1" && pwd)"
build="$2"
base="${3:-HEAD~10}"
max="${4:-8}"
source "$(dirname "${BASH_SOURCE[0]}")/../support/under_ci.sh"

if ! command -v clang-tidy >/dev/null; then
  echo "clang-tidy: not installed"
  if under_ci; then exit 1; fi
  exit 77
fi
[ -f "$build/compile_commands.json" ] || { echo "clang-tidy: $build/compile_commands.json missing"; exit 1; }
# One command per source file (a unity build's batches expanded): clang-tidy checks each file on its own.
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 "$(dirname "${BASH_SOURCE[0]}")/../support/compile_database.py" "$build" "$work"

cd "$src"
layers=(cli daemon drivers model dsp)
if [ "$base" = all ]; then
  mapfile -t changed < <(git ls-files "${layers[@]}" | grep -E '\.(cpp|hpp)$' || true)
else
  if ! git rev-parse -q --verify "$base^{commit}" >/dev/null 2>&1; then
    base="$(git rev-list --max-parents=0 HEAD 2>/dev/null | tail -1 || true)"  # a short history: all of it
    [ -n "$base" ] || { echo "clang-tidy: no git history here, skipped"; exit 77; }
  fi
  mapfile -t changed < <(git log --name-only --format= "$base..HEAD" -- "${layers[@]}" | grep -E '\.(cpp|hpp)$' || true)
fi
files=()
for f in "${changed[@]}"; do
  cpp="${f%.*}.cpp"  # a changed .cpp, or the .cpp beside a changed header
  [ -f "$cpp" ] && grep -qF "\"$src/$cpp\"" "$work/compile_commands.json" && files+=("$cpp")
done
# The first MAX distinct files, in the order of the log (newest change first).
mapfile -t files < <(printf '%s\n' "${files[@]}" | sed '/^$/d' | awk '!seen[$0]++' | head -n "$max")
if [ "${#files[@]}" -eq 0 ]; then
  echo "clang-tidy: no source changed since $base"
  exit 0
fi
echo "clang-tidy: ${#files[@]} file(s) changed since $base"
out="$work/findings"
status=0
printf '%s\n' "${files[@]}" |
  xargs -P "$(nproc)" -n 4 clang-tidy -p "$work" --quiet --extra-arg=-Wno-unknown-warning-option >"$out" 2>&1 ||
  status=$?
grep -E 'warning:|error:' "$out" | sort -u || true
if [ "$status" -ne 0 ]; then
  echo "clang-tidy: findings above (checks: .clang-tidy)"
  exit 1
fi
echo "clang-tidy: clean"
