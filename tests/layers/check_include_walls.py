#!/usr/bin/env python3
"""The compiler keeps the layers: a library's sources see only the headers of what it links.

Each case compiles (syntax only) one line, `#include "<header>"`, with the exact flags the build gives a source of
the library (compile_commands.json, a unity build's batches expanded to their sources): a header of a library it does
not link must fail, and a header of one it does link must compile (the control: without it a broken command would
pass every forbidden case).

usage: check_include_walls.py SOURCE_DIR BUILD_DIR
"""
import os
import shlex
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "support"))
from compile_database import per_file_entries  # noqa: E402  (tests/support: a unity build's batches expanded)

# (a source of the library, a header it may not include, a header it may)
CASES = [
    ("dsp/levels.cpp", "model/block_params.hpp", "dsp/cusum.hpp"),
    ("model/engine/effects.cpp", "model/fit/band_fit.hpp", "model/block_params.hpp"),
    ("drivers/worker_thread.cpp", "daemon/config.hpp", "dsp/levels.hpp"),
    ("drivers/formats/candump.cpp", "drivers/sim/sim_faults.hpp", "drivers/combined_source.hpp"),
    ("daemon/pipeline.cpp", "model/diagnosis/gap_watch.hpp", "drivers/sim/sim_faults.hpp"),
    ("daemon/pipeline.cpp", "cli/cli_support.hpp", "model/engine/effects.hpp"),
]


def compile_command(database, source):
    for entry in database:
        if os.path.realpath(entry["file"]) == os.path.realpath(source):
            args = shlex.split(entry["command"]) if "command" in entry else list(entry["arguments"])
            return args, entry["directory"]
    raise SystemExit(f"check_include_walls: {source} is not in compile_commands.json")


def compiles(args, directory, header):
    with tempfile.NamedTemporaryFile("w", suffix=".cpp", delete=False) as probe:
        probe.write(f'#include "{header}"\n')
    try:
        flags = []
        skip = False
        for a in args[1:]:
            if skip:
                skip = False
                continue
            if a in ("-o", "-c"):
                skip = True
                continue
            flags.append(a)
        result = subprocess.run([args[0], *flags, "-fsyntax-only", probe.name], cwd=directory,
                                capture_output=True, text=True)
        return result.returncode == 0, result.stderr
    finally:
        os.unlink(probe.name)


def main():
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    source_dir, build_dir = sys.argv[1], sys.argv[2]
    database = per_file_entries(build_dir)
    failures = 0
    for source, forbidden, allowed in CASES:
        args, directory = compile_command(database, os.path.join(source_dir, source))
        ok, errors = compiles(args, directory, allowed)
        if not ok:
            print(f"FAIL {source}: the linked header {allowed} does not compile:\n{errors}")
            failures += 1
        ok, _ = compiles(args, directory, forbidden)
        if ok:
            print(f"FAIL {source}: {forbidden} compiles, though its library does not link that layer")
            failures += 1
        else:
            print(f"ok   {source}: {allowed} compiles, {forbidden} does not")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
