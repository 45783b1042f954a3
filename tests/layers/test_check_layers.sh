#!/usr/bin/env bash
# The layer check can fail: on a copy of the source tree it passes, then fails naming the file for a model file
# that includes the daemon, a dsp file that includes a message type, a daemon file that includes the
# command-line tool, a drivers file whose library no longer links what it includes, and a folder of code that is
# no layer.
set -euo pipefail
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
check="$src/tests/layers/check_layers.py"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cp -r "$src/dsp" "$src/model" "$src/drivers" "$src/daemon" "$src/cli" "$tmp/"
python3 "$check" "$tmp" >/dev/null || { echo "FAIL: the unchanged copy does not pass"; exit 1; }

expect_violation() {  # $1: what the output must name
  if out=$(python3 "$check" "$tmp"); then echo "FAIL: passed with $1"; exit 1; fi
  grep -qF "$1" <<<"$out" || { echo "FAIL: the output does not name $1:"; echo "$out"; exit 1; }
}
echo '#include "daemon/config.hpp"' >>"$tmp/model/block_model.cpp"
expect_violation 'model/block_model.cpp: includes "daemon/config.hpp" from daemon'
cp "$src/model/block_model.cpp" "$tmp/model/block_model.cpp"
echo '#include "noisemon/cycle_report_t.hpp"' >>"$tmp/dsp/levels.hpp"
expect_violation 'dsp/levels.hpp: includes "noisemon/cycle_report_t.hpp" from msgs'
cp "$src/dsp/levels.hpp" "$tmp/dsp/levels.hpp"
echo '#include "cli/watch.hpp"' >>"$tmp/daemon/pipeline.cpp"
expect_violation 'daemon/pipeline.cpp: includes "cli/watch.hpp" from cli'
cp "$src/daemon/pipeline.cpp" "$tmp/daemon/pipeline.cpp"
# The rule is CMake's: a library that no longer links the formats may no longer include them.
sed -i 's/noisemon_can PUBLIC noisemon_formats /noisemon_can PUBLIC /' "$tmp/drivers/can/CMakeLists.txt"
expect_violation 'drivers/can/can_source.cpp: includes "drivers/formats/'
cp "$src/drivers/can/CMakeLists.txt" "$tmp/drivers/can/CMakeLists.txt"
mkdir "$tmp/model/extra" && echo '' >"$tmp/model/extra/x.cpp"
expect_violation 'model/extra: a folder of code that is not a layer'
echo "layer check: passes the tree, fails each of five violations"
