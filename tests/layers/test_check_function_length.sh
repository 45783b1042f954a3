#!/usr/bin/env bash
# The function-length check can fail: on a tree of synthetic sources it passes short functions and long bodies
# that are no function (classes, namespaces, enums, initializers, raw strings, comments, macros), and fails naming
# the function for a body over the limit, a lambda's lines counted toward its enclosing function.
set -euo pipefail
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
check="$src/tests/layers/check_function_length.py"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/dsp" "$tmp/model/engine" "$tmp/drivers" "$tmp/cli" "$tmp/tests/model"

statements() {  # $1 lines of statements
  for ((i = 0; i < $1; ++i)); do echo "  x += $i;"; done
}
function_of() {  # $1: header, $2: body lines from "{" to "}" inclusive
  echo "$1 {"
  statements $(($2 - 2))
  echo "}"
}
expect_pass() {  # $@: extra arguments
  out=$(python3 "$check" "$@" "$tmp") || { echo "FAIL: did not pass:"; echo "$out"; exit 1; }
}
expect_fail() {  # $1: what the output must name, then extra arguments
  local want="$1"
  shift
  if out=$(python3 "$check" "$@" "$tmp"); then echo "FAIL: passed, expected $want"; exit 1; fi
  grep -qF "$want" <<<"$out" || { echo "FAIL: the output does not name $want:"; echo "$out"; exit 1; }
}

# Short functions, and long bodies that are not functions; with a low limit, exactly the functions are listed, each
# with its length (a construct read wrongly would end a body early, swallow the rest of the file or add a function).
{
  echo '#include <string>'
  echo '#define OPEN {'
  echo 'namespace noisemon::model {'
  echo 'namespace {'
  echo 'constexpr int kTable[] = {'
  for ((i = 0; i < 120; ++i)); do echo "  $i'000'000,"; done
  echo '};'
  echo 'const char* kText = R"css('
  for ((i = 0; i < 120; ++i)); do echo '{ a { b } "quoted" // not a comment'; done
  echo ')css";'
  echo '/* a long comment with braces {'
  for ((i = 0; i < 120; ++i)); do echo ' { {'; done
  echo '*/'
  echo 'enum class Kind : int {'
  for ((i = 0; i < 120; ++i)); do echo "  k$i,"; done
  echo '};'
  echo '}  // namespace'
  echo 'struct Plot {'
  echo '  Plot(int a) : a_(a), b_{a} {}'
  for ((i = 0; i < 100; ++i)); do echo "  int m$i{$i};"; done
  function_of '  int member() const' 20
  echo '  int a_, b_;'
  echo '};'
  function_of 'int free_function(int x)' 80
  # return std::string("}}}") + '{' + "\" {" + R"({{)" + std::to_string(1'000 + '{');
  literals='return std::string("}}}") + '"'{'"' + "\\" {" + R"({{)" + std::to_string(1'"'000 + '{'"');'
  function_of 'std::string literals()' 30 | sed "s/x += 0;/$literals/"
  echo '// } a comment {'
  function_of 'auto trailing() -> int' 16
  function_of 'int defaults(std::vector<int> v = {1, 2}, int k = int{3})' 17
  echo '}  // namespace noisemon::model'
} >"$tmp/model/short.cpp"
expect_pass
if ! out=$(python3 "$check" --limit 15 "$tmp"); then
  expected="model/short.cpp:596: member: 20 lines (limit 15)
model/short.cpp:618: free_function: 80 lines (limit 15)
model/short.cpp:698: literals: 30 lines (limit 15)
model/short.cpp:729: trailing: 16 lines (limit 15)
model/short.cpp:745: defaults: 17 lines (limit 15)
5 function(s) over 15 lines"
  if [[ "$out" != "$expected" ]]; then
    echo "FAIL: with --limit 15, expected"; echo "$expected"; echo "got"; echo "$out"; exit 1
  fi
else
  echo "FAIL: passed with --limit 15"
  exit 1
fi

# A function over the limit fails, named with its file and line; the limit is an option.
function_of 'double long_free(double x)' 81 >"$tmp/dsp/long.cpp"
expect_fail 'dsp/long.cpp:1: long_free: 81 lines (limit 80)'
expect_pass --limit 81
expect_fail 'dsp/long.cpp:1: long_free: 81 lines (limit 70)' --limit 70
rm "$tmp/dsp/long.cpp"

# A lambda counts toward the function it is in; a brace in a string or a character literal ends nothing.
{
  echo 'void Engine::run(int n) {'
  echo '  auto step = [&](int k) {'
  echo '    if (k > 0) {'
  statements 80
  echo '    }'
  echo '  };'
  echo '  const char* s = "}"; char c = '"'"'}'"'"';'
  statements 10
  echo '}'
} >"$tmp/model/engine/lambda.cpp"
expect_fail 'model/engine/lambda.cpp:1: Engine::run: 97 lines (limit 80)'
if [[ $(wc -l <<<"$out") != 2 ]]; then echo "FAIL: expected one function over the limit:"; echo "$out"; exit 1; fi
rm "$tmp/model/engine/lambda.cpp"

# Member functions of a class, a constructor with braced member initializers, an operator.
{
  echo 'class Source {'
  echo ' public:'
  function_of '  Source(int a) : a_{a}, b_(a), f_{[a] { return a; }}' 90
  function_of '  bool operator()(int k) const noexcept' 95
  echo ' private:'
  echo '  int a_, b_;'
  echo '  std::function<int()> f_;'
  echo '};'
} >"$tmp/drivers/members.hpp"
expect_fail 'drivers/members.hpp:3: Source: 90 lines (limit 80)'
expect_fail 'drivers/members.hpp:93: operator(): 95 lines (limit 80)'
rm "$tmp/drivers/members.hpp"

# Subfolders are checked; tests are not.
function_of 'int run_cli(int argc, char** argv)' 100 >"$tmp/tests/model/test_long.cpp"
expect_pass
function_of 'int run_cli(int argc, char** argv)' 100 >"$tmp/cli/cli.cpp"
expect_fail 'cli/cli.cpp:1: run_cli: 100 lines (limit 80)'
echo "function-length check: passes short functions and long non-functions, fails each long function"
