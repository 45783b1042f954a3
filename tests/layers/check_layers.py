#!/usr/bin/env python3
"""The layering rule, checked: each folder is one layer (one CMake target) and includes only from the layers it
is declared to depend on, below it; noisemond links neither Ceres nor fitting, diagnosis or report code.

  check_layers.py SOURCE_DIR [BUILD_DIR]

SOURCE_DIR: every #include "<folder>/<file>" of the project's own code (dsp, model, drivers, daemon, cli and their
subfolders; tests are not a layer) must name its own folder or one whose library its folder's library links,
directly or through another (read from the CMakeLists.txt files: the layers are what CMake builds). Generated message headers
("noisemon/<type>.hpp") belong to msgs. BUILD_DIR (a Ninja tree): noisemond's link command must not name the
libraries in FORBIDDEN_IN_NOISEMOND. Exit 0 when clean, 1 with one line per violation.
"""
import os
import re
import subprocess
import sys

ROOTS = ("dsp", "model", "drivers", "daemon", "cli")
ADD_LIBRARY = re.compile(r"add_library\(\s*(noisemon_\w+)")
LINKS = re.compile(r"target_link_libraries\(\s*(noisemon_\w+)([^)]*)\)", re.S)


def layer_links(src):
    """What each layer may use, read from the CMake files: a folder's library links (target_link_libraries)
    other noisemon libraries, each of one folder; the folder may include from those folders and from everything
    they link in turn (PUBLIC links reach through). noisemon_msgs is the generated message headers (msgs)."""
    folder_of = {"noisemon_msgs": "msgs"}
    links = {}
    for root in ROOTS:
        for dirpath, _, files in os.walk(os.path.join(src, root)):
            if "CMakeLists.txt" not in files:
                continue
            with open(os.path.join(dirpath, "CMakeLists.txt"), encoding="utf-8") as f:
                text = re.sub(r"#.*", "", f.read())
            folder = os.path.relpath(dirpath, src)
            for target in ADD_LIBRARY.findall(text):
                folder_of[target] = folder
            for target, args in LINKS.findall(text):
                links.setdefault(target, set()).update(re.findall(r"\bnoisemon_\w+", args))
    allowed = {}
    for target, folder in folder_of.items():
        if folder == "msgs":
            continue
        reach, todo = set(), [target]
        while todo:
            for dep in links.get(todo.pop(), ()):
                if dep not in reach and dep in folder_of:
                    reach.add(dep)
                    todo.append(dep)
        allowed[folder] = {folder_of[d] for d in reach} | {folder}
    return allowed


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
    ALLOWED = layer_links(src)
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
    for root in ROOTS:
        for dirpath, _, files in os.walk(os.path.join(src, root)):
            rel = os.path.relpath(dirpath, src)
            if any(f.endswith((".cpp", ".hpp")) for f in files) and rel not in ALLOWED:
                out.append(f"{rel}: a folder of code that is not a layer (no add_library in its CMakeLists.txt)")
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
