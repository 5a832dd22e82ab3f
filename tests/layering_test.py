#!/usr/bin/env python3
"""The layers of the library, checked on the tree itself (docs/architecture.md has the table).

    layering_test.py SOURCE_DIR                  every include of the tree follows the table
    layering_test.py SOURCE_DIR --self-test      the check fails on a tree that breaks it
    layering_test.py SOURCE_DIR --compile CXX ROOTS EIGEN
                                                 with the build's include roots, a layer's headers
                                                 compile and a higher layer's do not

Each layer is a folder in src/ and in include/cartesian_impedance/. A file of a layer may include
the public headers of its own layer and of the layers below it, its own layer's private headers
(beside its sources, by relative path), the standard library, Eigen, and the third-party
libraries its row allows. The shells (apps/, python/, ros/, ros2/, bench/, examples/) may include
every public header and no private one; tests may also include the private headers of the layer
they test. Exit status 1 and one line per violation when the tree breaks a rule.
"""

import os
import re
import shutil
import subprocess
import sys
import tempfile

# Layer -> the layers it may include besides itself (already closed under "below").
BELOW = {
    "core": set(),
    "compat": {"core"},
    "config": {"core"},
    "model": {"core"},
    "loop": {"core", "model"},
    "runtime": {"core", "model", "loop"},
    "sim": {"core", "model", "loop", "runtime"},
    "node": {"core", "model", "loop", "runtime", "sim"},
}

# Third-party headers by library, as they are included.
EXTERNAL = {
    "yaml-cpp": re.compile(r"^yaml-cpp/"),
    "urdfdom/KDL": re.compile(r"^(urdf_parser|urdf_model|urdf_world|urdf_exception|kdl)/"),
    "MuJoCo": re.compile(r"^mujoco"),
    "DART": re.compile(r"^dart/"),
    "rendering": re.compile(r"^(EGL|GL|png\.h|tinyxml2\.h)"),
    "ROS": re.compile(r"^(ros/|rclcpp|rcl/|dds/|tf2|[a-z_]+_msgs/|dynamic_reconfigure|catkin)"),
    "Python": re.compile(r"^(pybind11/|Python\.h)"),
}

# Which third-party libraries each layer's sources may include; public headers include none
# (every public header compiles with Eigen alone).
ALLOWED_EXTERNAL = {
    "core": set(),
    "compat": set(),
    "config": {"yaml-cpp"},
    "model": {"urdfdom/KDL"},
    "loop": set(),
    "runtime": set(),
    "sim": {"MuJoCo", "DART", "rendering"},
    "node": set(),
}

SHELLS = ("apps", "python", "ros", "ros2", "bench", "examples")
SOURCE_SUFFIXES = (".cpp", ".hpp", ".h", ".cc")
# Files allowed directly in src/ and include/cartesian_impedance/ (the rest lives in a layer).
MAX_FLAT_FILES = 3
MAX_LINES = 800

INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]', re.M)


def includes(path):
    with open(path, encoding="utf-8", errors="replace") as f:
        text = f.read()
    for match in INCLUDE.finditer(text):
        line = text.count("\n", 0, match.start()) + 1
        yield line, match.group(1), match.group(2)


def source_files(root, folder):
    base = os.path.join(root, folder)
    for directory, _, names in os.walk(base):
        for name in sorted(names):
            if name.endswith(SOURCE_SUFFIXES):
                yield os.path.join(directory, name)


def public_layer(target):
    """'cartesian_impedance/loop/control_loop.hpp' -> 'loop'; None if not a layer's header."""
    parts = target.split("/")
    if len(parts) >= 3 and parts[0] == "cartesian_impedance":
        return parts[1]
    if len(parts) == 2 and parts[0] == "cartesian_impedance":
        return ""  # flat: an umbrella header
    return None


def check(root):
    """Every violation of the rules in the tree at `root`, as 'path:line: text'."""
    problems = []
    rel = lambda p: os.path.relpath(p, root)

    for top in ("src", os.path.join("include", "cartesian_impedance")):
        flat = [n for n in os.listdir(os.path.join(root, top))
                if os.path.isfile(os.path.join(root, top, n))]
        if len(flat) > MAX_FLAT_FILES:
            problems.append(f"{top}/: {len(flat)} files outside the layer folders "
                            f"({', '.join(sorted(flat))}); at most {MAX_FLAT_FILES}")
        for name in os.listdir(os.path.join(root, top)):
            if os.path.isdir(os.path.join(root, top, name)) and name not in BELOW:
                problems.append(f"{top}/{name}/: not a layer ({', '.join(BELOW)})")

    for layer, below in BELOW.items():
        may_include = below | {layer}
        for kind in ("public", "private"):
            folder = (os.path.join("include", "cartesian_impedance", layer) if kind == "public"
                      else os.path.join("src", layer))
            own_private = os.path.join(root, "src", layer)
            for path in source_files(root, folder):
                with open(path, encoding="utf-8", errors="replace") as f:
                    count = sum(1 for _ in f)
                if count > MAX_LINES:
                    problems.append(f"{rel(path)}: {count} lines; split it (at most {MAX_LINES})")
                for line, quote, target in includes(path):
                    where = f"{rel(path)}:{line}: #include {target}"
                    other = public_layer(target)
                    if other is not None:
                        if other == "":
                            problems.append(f"{where}: a flat header; layers include layers")
                        elif other not in BELOW:
                            problems.append(f"{where}: '{other}' is not a layer")
                        elif other not in may_include:
                            problems.append(
                                f"{where}: layer '{layer}' may not include the higher or "
                                f"sibling layer '{other}' (it may include "
                                f"{', '.join(sorted(may_include))})")
                        continue
                    library = next((name for name, pattern in EXTERNAL.items()
                                    if pattern.search(target)), None)
                    if library is not None:
                        allowed = ALLOWED_EXTERNAL[layer] if kind == "private" else set()
                        if library not in allowed:
                            problems.append(f"{where}: {library} in the {kind} part of layer "
                                            f"'{layer}'")
                        continue
                    if quote == '"':
                        resolved = os.path.normpath(os.path.join(os.path.dirname(path), target))
                        if kind == "public":
                            problems.append(f"{where}: a public header includes by relative "
                                            "path; use cartesian_impedance/<layer>/...")
                        elif not resolved.startswith(own_private + os.sep):
                            problems.append(f"{where}: outside src/{layer}/ (private headers are "
                                            "their own layer's)")
                        elif not os.path.isfile(resolved):
                            problems.append(f"{where}: no such private header")

    # The shells and the tests: public headers only (tests may reach a layer's private ones).
    for folder in SHELLS + ("tests",):
        if not os.path.isdir(os.path.join(root, folder)):
            continue
        for path in source_files(root, folder):
            for line, _, target in includes(path):
                if target.startswith("src/") and folder != "tests":
                    problems.append(f"{rel(path)}:{line}: #include {target}: a private header "
                                    "of a layer, outside its tests")
                other = public_layer(target)
                if other and other not in BELOW:
                    problems.append(f"{rel(path)}:{line}: #include {target}: no such layer")
    return problems


def self_test(root):
    """Breaks a copy of the tree in each way the check knows and expects it to say so."""
    cases = [
        ("include/cartesian_impedance/core/types.hpp",
         '#include "cartesian_impedance/loop/control_loop.hpp"\n', "may not include the higher"),
        ("src/model/robot_model.cpp", '#include "cartesian_impedance/config/yaml.hpp"\n',
         "sibling layer 'config'"),
        ("src/loop/control_loop.cpp", '#include "../model/chain_model.hpp"\n',
         "outside src/loop/"),
        ("src/core/controller.cpp", "#include <yaml-cpp/yaml.h>\n", "yaml-cpp in the private"),
        ("include/cartesian_impedance/sim/simulation.hpp", "#include <mujoco/mujoco.h>\n",
         "MuJoCo in the public"),
        ("apps/demo.cpp", '#include "src/sim/simulation_impl.hpp"\n', "a private header"),
    ]
    clean = check(root)
    if clean:
        print("self-test needs a clean tree; it has:\n  " + "\n  ".join(clean))
        return 1
    failures = 0
    for relative, line, expected in cases:
        with tempfile.TemporaryDirectory() as scratch:
            for folder in ("src", "include", "apps", "tests"):
                shutil.copytree(os.path.join(root, folder), os.path.join(scratch, folder))
            path = os.path.join(scratch, relative)
            with open(path, encoding="utf-8") as f:
                text = f.read()
            with open(path, "w", encoding="utf-8") as f:
                f.write(line + text)
            found = check(scratch)
            if not any(expected in problem and relative in problem for problem in found):
                failures += 1
                print(f"FAIL: adding {line.strip()} to {relative} was not reported as "
                      f"'{expected}'; the check said: {found}")
            else:
                print(f"ok: {relative} + {line.strip()} -> {found[0]}")
    return 1 if failures else 0


def compile_check(root, cxx, roots, eigen):
    """A layer's headers compile with its own and lower include roots; a higher layer's header is
    not found there."""
    failures = 0

    def compile_text(text, layers):
        flags = ["-std=c++17", "-fsyntax-only", "-x", "c++", "-", "-isystem", eigen]
        for layer in layers:
            flags += ["-I", os.path.join(roots, layer)]
        return subprocess.run([cxx] + flags, input=text, capture_output=True, text=True)

    for layer, below in BELOW.items():
        visible = sorted(below | {layer})
        headers = sorted(os.listdir(os.path.join(root, "include", "cartesian_impedance", layer)))
        text = "".join(f'#include "cartesian_impedance/{layer}/{h}"\n' for h in headers)
        result = compile_text(text, visible)
        if result.returncode != 0:
            failures += 1
            print(f"FAIL: the headers of '{layer}' do not compile with the roots of "
                  f"{', '.join(visible)}:\n{result.stderr[:2000]}")
        for other in sorted(set(BELOW) - below - {layer}):
            header = sorted(os.listdir(os.path.join(root, "include", "cartesian_impedance",
                                                    other)))[0]
            target = f"cartesian_impedance/{other}/{header}"
            result = compile_text(f'#include "{target}"\n', visible)
            if result.returncode == 0 or "No such file" not in result.stderr:
                failures += 1
                print(f"FAIL: '{layer}' could include {target} (it must not compile)")
        print(f"{'ok' if not failures else '..'}: {layer}: {len(headers)} headers compile; "
              f"{len(set(BELOW) - below - {layer})} higher or sibling layers unreachable")
    return 1 if failures else 0


def main(argv):
    root = os.path.abspath(argv[1])
    if len(argv) > 2 and argv[2] == "--self-test":
        return self_test(root)
    if len(argv) > 2 and argv[2] == "--compile":
        return compile_check(root, argv[3], argv[4], argv[5])
    problems = check(root)
    for problem in problems:
        print(problem)
    print(f"{len(problems)} layering problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
