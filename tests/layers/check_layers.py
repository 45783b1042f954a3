#!/usr/bin/env python3
"""The layering rule, checked: each folder is one layer (one CMake target) and includes only from the layers it
is declared to depend on, below it; noisemond links neither Ceres nor fitting, diagnosis or report code.

  check_layers.py SOURCE_DIR [BUILD_DIR]

SOURCE_DIR: every #include "<folder>/<file>" of the project's own code (dsp, model, drivers, daemon, cli and their
subfolders; tests are not a layer) must name a folder in ALLOWED[its own folder]. Generated message headers
("noisemon/<type>.hpp") belong to msgs. BUILD_DIR (a Ninja tree): noisemond's link command must not name the
libraries in FORBIDDEN_IN_NOISEMOND. Exit 0 when clean, 1 with one line per violation.
"""
import os
import re
import subprocess
import sys

# Mirrors the target_link_libraries of each folder's CMakeLists.txt: a folder may include itself and these.
BASE = {"dsp": []}
BASE["model"] = ["dsp"]
BASE["model/engine"] = ["model", "dsp"]
BASE["model/fit"] = ["model/engine", "model", "dsp"]
BASE["model/diagnosis"] = ["model/fit", "model/engine", "model", "dsp"]
BASE["drivers"] = ["dsp"]
BASE["drivers/formats"] = ["drivers", "dsp", "msgs"]
BASE["drivers/comedi"] = ["drivers", "model", "dsp"]
BASE["drivers/can"] = ["drivers/formats", "drivers", "dsp"]
BASE["drivers/lcm"] = ["drivers/formats", "drivers", "dsp", "msgs"]
BASE["drivers/log"] = ["drivers/formats", "drivers", "dsp", "msgs"]
BASE["drivers/sim"] = ["drivers/comedi", "drivers/formats", "drivers", "model/engine", "model", "dsp"]
BASE["daemon"] = ["drivers/sim", "drivers/comedi", "drivers/can", "drivers/lcm", "drivers/log", "drivers/formats",
                  "drivers",
                  "model/engine", "model", "dsp", "msgs"]
BASE["cli/report"] = ["model/diagnosis", "model/fit", "model/engine", "model", "dsp"]
BASE["cli/formats"] = ["drivers/formats", "drivers", "dsp", "msgs"]
BASE["cli"] = ["cli/report", "cli/formats", "daemon"] + BASE["daemon"] + ["model/diagnosis", "model/fit"]
ALLOWED = {folder: set(deps) | {folder} for folder, deps in BASE.items()}

FORBIDDEN_IN_NOISEMOND = ["libceres", "libnoisemon_fit.", "libnoisemon_diagnosis.", "libnoisemon_report.",
                          "libnoisemon_cli."]

INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)


def folder_of_header(include):
    """The layer an include line names: its directory, or msgs for the generated message headers."""
    if include.startswith("noisemon/"):
        return "msgs"
    return os.path.dirname(include)


def include_violations(src):
    out = []
    for layer in sorted(ALLOWED):
        directory = os.path.join(src, layer)
        if not os.path.isdir(directory):
            out.append(f"{layer}: the layer's folder is missing")
            continue
        for name in sorted(os.listdir(directory)):
            if not name.endswith((".cpp", ".hpp", ".h")):
                continue
            path = os.path.join(directory, name)
            with open(path, encoding="utf-8") as f:
                text = f.read()
            for include in INCLUDE.findall(text):
                target = folder_of_header(include)
                if target and target not in ALLOWED[layer]:
                    out.append(f"{layer}/{name}: includes \"{include}\" from {target}, which {layer} may not use")
    # A new folder of code must be given its place before it can hold code.
    for root in ("dsp", "model", "drivers", "daemon", "cli"):
        for dirpath, _, files in os.walk(os.path.join(src, root)):
            rel = os.path.relpath(dirpath, src)
            if any(f.endswith((".cpp", ".hpp")) for f in files) and rel not in ALLOWED:
                out.append(f"{rel}: a folder of code that is not a declared layer (add it to tests/layers)")
    return out


def link_violations(build):
    if not os.path.exists(os.path.join(build, "build.ninja")):
        print(f"layers: {build} is not a Ninja tree, noisemond's link line not checked")
        return []
    command = subprocess.run(["ninja", "-C", build, "-t", "commands", "daemon/noisemond"], capture_output=True,
                             text=True, check=True).stdout.strip().splitlines()[-1]
    return [f"noisemond links {lib}" for lib in FORBIDDEN_IN_NOISEMOND if lib in command]


def main(argv):
    if len(argv) not in (2, 3) or argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0 if len(argv) == 2 else 2
    problems = include_violations(argv[1])
    if len(argv) == 3:
        problems += link_violations(argv[2])
    for p in problems:
        print(p)
    print(f"layers: {len(problems)} violation(s)" if problems else "layers: clean")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
