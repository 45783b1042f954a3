#!/usr/bin/env bash
# The tree is formatted with its .clang-format: every tracked .cpp/.hpp of the project (the vendored and generated
# code aside) is what clang-format would write. Exit 0 when it is, 1 naming the files that are not (fix:
# clang-format -i FILE...), 77 (skipped) without clang-format or git: a failure under CI for want of clang-format.
#
#   check_format.sh SOURCE_DIR
set -euo pipefail
src="$(cd "$1" && pwd)"
source "$(dirname "${BASH_SOURCE[0]}")/../support/under_ci.sh"
if ! command -v clang-format >/dev/null || ! git -C "$src" rev-parse --git-dir >/dev/null 2>&1; then
  echo "format: clang-format or git missing, not checked"
  if under_ci; then exit 1; fi
  exit 77
fi
cd "$src"
mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h' | grep -v '/vendor/')
# One clang-format per core over a share of the files; each names the files it would change.
mapfile -t bad < <(printf '%s\n' "${files[@]}" |
  xargs -P "$(nproc)" -n 64 clang-format --dry-run --Werror 2>&1 >/dev/null |
  sed -n 's/^\([^:]*\):[0-9]*:[0-9]*: error: code should be clang-formatted.*/\1/p' | sort -u)
if [ "${#bad[@]}" -gt 0 ]; then
  printf 'format: not as .clang-format writes it: %s\n' "${bad[@]}"
  exit 1
fi
echo "format: ${#files[@]} files as .clang-format writes them"
