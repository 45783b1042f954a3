#!/usr/bin/env python3
"""The build's compile commands, one per source file, for the tools that check a file at a time.

A unity build (NOISEMON_UNITY_BUILD) compiles a target's sources in batches: compile_commands.json then names the
batch files (<target>.dir/Unity/unity_N_cxx.cxx, each a list of #include lines), not the sources. Each source gets the
command of the batch that holds it, with its own path as the input. Entries of sources compiled alone pass through.

usage: compile_database.py BUILD_DIR OUT_DIR   writes OUT_DIR/compile_commands.json (for clang-tidy -p OUT_DIR)
"""
import json
import os
import re
import shlex
import sys

_INCLUDE = re.compile(r'^#include "(.+)"\s*$')


def _arguments(entry):
    return shlex.split(entry["command"]) if "command" in entry else list(entry["arguments"])


def _batch_sources(batch_file):
    with open(batch_file) as f:
        return [m.group(1) for m in map(_INCLUDE.match, f) if m]


def _with_input(arguments, old_input, new_input):
    out = []
    for a in arguments:
        if a == old_input:
            out.append(new_input)
        else:
            out.append(a)
    return out


def per_file_entries(build_dir):
    """Entries of compile_commands.json, one per source file (a unity batch expanded to its sources)."""
    with open(os.path.join(build_dir, "compile_commands.json")) as f:
        database = json.load(f)
    entries = []
    for entry in database:
        batch = entry["file"]
        if not re.search(r"/Unity/unity_\d+_c(xx)?\.cx*$", batch):
            entries.append(entry)
            continue
        arguments = _arguments(entry)
        for source in _batch_sources(batch):
            entries.append({"directory": entry["directory"], "file": source,
                            "arguments": _with_input(arguments, batch, source)})
    return entries


def main():
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    os.makedirs(sys.argv[2], exist_ok=True)
    with open(os.path.join(sys.argv[2], "compile_commands.json"), "w") as f:
        json.dump(per_file_entries(sys.argv[1]), f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
