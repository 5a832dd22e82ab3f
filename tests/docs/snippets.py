#!/usr/bin/python3
"""The documentation's code blocks, read from the Markdown, and the tests that run them.

Every fenced block of the documents below is one of:
  - text: no language (formulas, diagrams, a folder tree) or `text`; nothing to run;
  - python: run as a pytest case (tests/docs/test_python_snippets.py);
  - cpp with a main(): compiled against the installed package and run (test docs_cpp), with the
    block marked `docs_cpp_cmake` as its CMakeLists.txt;
  - a block marked with the test that runs it, by an HTML comment on the line before the fence:
        <!-- snippet: docs_shell -->
    optionally followed by `; CMD runs in FILE`: that line of the block is not run by the test,
    which instead checks that FILE runs CMD (the command that runs the tests runs in CI);
  - a block marked `<!-- snippet: output of TEST -->`: what the previous block printed, checked
    by TEST;
  - a block marked `<!-- snippet: fragment: REASON -->`: part of something bigger, not run, and
    the reason is said where a reader sees it in the source.
A block that is none of these fails the test docs_inventory, so nothing is skipped silently.

Usage: snippets.py SOURCE_DIR BUILD_DIR TEST   (TEST: docs_inventory, docs_shell, docs_cpp,
docs_demo, docs_ros); exit status 0 if every block of the test did what the docs say.
"""

import os
import pathlib
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

DOCUMENTS = [
    "README.md", "ros/README.md", "ros2/README.md", "python/README.md", "models/README.md",
    "docs/*.md"
]
TESTS = {"docs_shell", "docs_cpp", "docs_cpp_cmake", "docs_demo", "docs_ros"}
MARKER = re.compile(r"^<!--\s*snippet:\s*(.*?)\s*-->\s*$")


class Snippet:
    def __init__(self, document, line, language, code, marker):
        self.document = document  # path relative to the source folder
        self.line = line  # of the opening fence
        self.language = language
        self.code = code
        self.marker = marker  # the text after "snippet:", "" if none
        # A fragment's reason is free text; other markers are "TEST[; CMD runs in FILE]...".
        parts = [part.strip() for part in marker.split(";")] if marker else []
        if marker.startswith("fragment:"):
            parts = [marker]
        self.runner = parts[0] if parts else ""
        # "CMD runs in FILE": lines the test leaves to FILE.
        self.elsewhere = []
        for part in parts[1:]:
            command, _, where = part.partition(" runs in ")
            if not where:
                raise ValueError(f"{self}: '{part}' is not 'COMMAND runs in FILE'")
            self.elsewhere.append((command.strip(), where.strip()))

    def __str__(self):
        return f"{self.document}:{self.line}"

    @property
    def kind(self):
        if self.runner.startswith("fragment:"):
            return "fragment"
        if self.runner.startswith("output of "):
            return "output"
        if self.runner:
            return self.runner
        if self.language in ("", "text"):
            return "text"
        if self.language == "python":
            return "docs_python"
        if self.language == "cpp" and re.search(r"\bint main\(", self.code):
            return "docs_cpp"
        return "unaccounted"

    def commands(self):
        """The block's shell lines without the ones run elsewhere."""
        skipped = {command for command, _ in self.elsewhere}
        return "\n".join(line for line in self.code.splitlines()
                         if line.split("#")[0].strip() not in skipped)


def documents(root):
    for pattern in DOCUMENTS:
        yield from sorted(root.glob(pattern))


def snippets(root):
    """Every fenced block of the documents, in order."""
    found = []
    for path in documents(root):
        lines = path.read_text().splitlines()
        marker, i = "", 0
        while i < len(lines):
            line = lines[i]
            match = MARKER.match(line)
            if match:
                marker = match.group(1)
            elif line.startswith("```"):
                language, start, body = line[3:].strip(), i + 1, []
                i += 1
                while i < len(lines) and not lines[i].startswith("```"):
                    body.append(lines[i])
                    i += 1
                found.append(Snippet(str(path.relative_to(root)), start, language,
                                     "\n".join(body) + "\n", marker))
                marker = ""
            elif line.strip():
                marker = ""  # a marker belongs to the block right after it
            i += 1
    return found


def substitute_build(code, build):
    """The docs say build/ (the folder scripts/test and scripts/demo use); a test runs against
    the build it belongs to."""
    return re.sub(r"(?<![\w./-])build(?=/|\s|$)", str(build), code)


def run(command, what, timeout, **kwargs):
    started = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True, timeout=timeout, **kwargs)
    print(f"  {what}: exit {result.returncode} after {time.monotonic() - started:.1f} s")
    if result.returncode != 0:
        print(result.stdout[-4000:])
        print(result.stderr[-4000:])
    return result


# ---- the tests -------------------------------------------------------------------------------


def docs_inventory(root, build, blocks):
    problems = []
    counts = {}
    for block in blocks:
        kind = block.kind
        counts[kind] = counts.get(kind, 0) + 1
        if kind == "unaccounted":
            problems.append(f"{block}: a {block.language} block that no test runs; mark it with "
                            "<!-- snippet: TEST --> or <!-- snippet: fragment: REASON -->")
        elif kind not in TESTS | {"text", "fragment", "output", "docs_python"}:
            problems.append(f"{block}: unknown snippet marker '{block.marker}'")
        elif kind == "fragment" and len(block.runner) < len("fragment: ") + 10:
            problems.append(f"{block}: a fragment must say why it is not run")
        if kind == "output" and block.runner[len("output of "):] not in TESTS:
            problems.append(f"{block}: output of an unknown test '{block.runner}'")
        for command, where in block.elsewhere:
            file = root / where
            if not file.is_file() or command not in file.read_text():
                problems.append(f"{block}: says '{command}' runs in {where}; it does not")
    for kind in sorted(counts):
        print(f"  {kind}: {counts[kind]}")
    print(f"  {len(blocks)} blocks in {len(list(documents(root)))} documents")
    for problem in problems:
        print("FAIL:", problem)
    return not problems


def docs_shell(root, build, blocks):
    ok = True
    for block in blocks:
        result = run(["bash", "-eo", "pipefail", "-c", substitute_build(block.commands(), build)],
                     str(block), timeout=600, cwd=root)
        ok &= result.returncode == 0
    return ok


def docs_cpp(root, build, blocks):
    """Installs the build to a scratch prefix and builds each C++ program of the docs against it
    with the docs' own CMake lines, then runs it from the source folder (its paths are relative
    to the repository, as the docs say)."""
    cmake_blocks = [b for b in snippets(root) if b.kind == "docs_cpp_cmake"]
    if len(cmake_blocks) != 1:
        print(f"FAIL: expected one block marked docs_cpp_cmake, found {len(cmake_blocks)}")
        return False
    cmake_lines = cmake_blocks[0].code
    target = re.search(r"target_link_libraries\((\w+)", cmake_lines).group(1)
    work = pathlib.Path(tempfile.mkdtemp(prefix="docs_cpp_"))
    try:
        prefix = work / "prefix"
        if run(["cmake", "--install", str(build), "--prefix", str(prefix)], "install",
               timeout=300).returncode != 0:
            return False
        ok = True
        for index, block in enumerate(blocks):
            project = work / f"snippet{index}"
            project.mkdir()
            (project / "main.cpp").write_text(block.code)
            (project / "CMakeLists.txt").write_text(
                "cmake_minimum_required(VERSION 3.16)\nproject(docs_snippet CXX)\n"
                "set(CMAKE_CXX_STANDARD 17)\nset(CMAKE_CXX_STANDARD_REQUIRED ON)\n"
                "add_compile_options(-Wall -Wextra -Wpedantic -Werror)\n"
                f"add_executable({target} main.cpp)\n" + cmake_lines)
            steps = [
                (["cmake", "-S", str(project), "-B", str(project / "build"),
                  f"-DCMAKE_PREFIX_PATH={prefix}", "-DCMAKE_BUILD_TYPE=Release"], "configure"),
                (["cmake", "--build", str(project / "build"), "-j2"], "build"),
                ([str(project / "build" / target)], "run"),
            ]
            for command, what in steps:
                result = run(command, f"{block} {what}", timeout=600, cwd=root)
                if result.returncode != 0:
                    ok = False
                    break
                if what == "run":
                    print("   ", result.stdout.strip().replace("\n", "\n    "))
        return ok
    finally:
        shutil.rmtree(work, ignore_errors=True)


def table_rows(text):
    """The rows of the demo's result table (after its header), keyed by scenario, what and
    theory, each with its verdict: the measured value is the one column that may change."""
    rows, in_table = {}, False
    for line in text.splitlines():
        if line.startswith("scenario ") and "measured" in line:
            in_table = True
            continue
        cells = re.split(r"\s{2,}", line.strip())
        if in_table and len(cells) >= 4 and cells[-1] in ("ok", "FAIL"):
            rows[tuple(cells[:-2])] = cells[-1]
    return rows


def docs_demo(root, build, blocks):
    """Runs the README's demo command and checks that every row of the excerpt it shows is in
    the demo's table with the same theory and an ok."""
    outputs = [b for b in snippets(root) if b.runner == "output of docs_demo"]
    env = dict(os.environ, CARTESIAN_IMPEDANCE_BUILD_DIR=str(build))
    ok = True
    for block in blocks:
        result = run(["bash", "-eo", "pipefail", "-c", block.commands()], str(block),
                     timeout=900, cwd=root, env=env)
        ok &= result.returncode == 0
        measured = table_rows(result.stdout)
        for output in outputs:
            shown = table_rows(output.code)
            if not shown:
                print(f"FAIL: {output}: no table rows")
                ok = False
            for key in shown:
                verdict = measured.get(key)
                if verdict != "ok":
                    print(f"FAIL: {output}: the docs show {key}; the demo's table "
                          f"{'has it as ' + verdict if verdict else 'has no such row'}")
                    ok = False
            print(f"  {output}: {len(shown)} rows checked against the demo's "
                  f"{len(measured)}")
    return ok


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


ROS_CHECK = r"""
import math, sys, time
import rospy
from cartesian_impedance_ros.msg import ControllerState
rospy.init_node("docs_check", anonymous=True, disable_signals=True)
def state():
    return rospy.wait_for_message("/cartesian_impedance_controller/controller_state",
                                  ControllerState, timeout=10)
def axes(w):
    return [w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z]
# What the commands ask for: the reference (0.35, 0.1, 0.5), stiffness (300, 500, 100; 50, 50,
# 50) after the reconfigure set x to 300 and kept the topic's z, and 5 N pressing down: at
# 100 N/m the flange settles 50 mm below the reference. The joints' Coulomb friction in the
# Panda's model, mapped through this pose's Jacobian, can hold about 0.45 N along z against the
# spring: 4.5 mm, plus 1 mm for the arm stopping anywhere in that band as it comes to rest
# (ros/test/node_test.py, case reconfigure_keeps_topic_commands, derives the same band).
# Were the reconfigure to restore z = 500 N/m,
# the press would be 10 mm; in x and y no force acts, so friction alone: the same band.
deadline = time.monotonic() + 20
while True:
    s = state()
    p = s.current_pose.position
    k = axes(s.commanded_cartesian_stiffness)
    w = axes(s.commanded_wrench)
    settled = math.sqrt(sum(v * v for v in s.joint_state.velocity)) < 1e-3
    if settled or time.monotonic() > deadline:
        break
    time.sleep(0.2)
print("position %.4f %.4f %.4f, stiffness %s, wrench %s, status %s"
      % (p.x, p.y, p.z, k, w, s.status))
failures = []
if s.status != "ok": failures.append("status " + s.status)
if max(abs(a - b) for a, b in zip(k, [300, 500, 100, 50, 50, 50])) > 1e-9:
    failures.append("commanded stiffness %s, not (300, 500, 100, 50, 50, 50)" % k)
if abs(w[2] + 5.0) > 1e-9: failures.append("commanded force z %g, not -5 N" % w[2])
if abs(p.z - (0.5 - 5.0 / 100.0)) > 0.0055:
    failures.append("z = %.4f m, not 0.45 +- 0.0055 m (5 N at 100 N/m below 0.5 m)" % p.z)
if math.hypot(p.x - 0.35, p.y - 0.1) > 0.0055:
    failures.append("x, y = %.4f, %.4f m, not the reference 0.35, 0.1 (+- 5.5 mm)" % (p.x, p.y))
for f in failures: print("FAIL:", f)
sys.exit(1 if failures else 0)
"""


def docs_ros(root, build, blocks):
    """The ROS manual's blocks in order in one shell, as a user types them (the first starts
    the node in the background), against a master of its own on a free port; then checks that
    the arm does what the commands said."""
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_HOME=tempfile.mkdtemp(),
               PYTHONUNBUFFERED="1")
    script = "\n".join(substitute_build(b.commands(), build) for b in blocks)
    check = pathlib.Path(env["ROS_HOME"]) / "check.py"
    check.write_text(ROS_CHECK)
    script += f"\nsleep 2\n/usr/bin/python3 {check}\n"
    # Output to a file: roslaunch, left in the background as the docs say, would hold a pipe open.
    log = pathlib.Path(env["ROS_HOME"]) / "output.txt"
    with open(log, "w") as output_file:
        process = subprocess.Popen(["bash", "-eo", "pipefail", "-c", script], cwd=root, env=env,
                                   stdout=output_file, stderr=subprocess.STDOUT,
                                   start_new_session=True)
        try:
            process.wait(timeout=300)
        except subprocess.TimeoutExpired:
            print("FAIL: timed out after 300 s")
        finally:
            try:
                os.killpg(process.pid, signal.SIGINT)  # roslaunch and its master
                time.sleep(3)
                os.killpg(process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            process.wait()
    output = log.read_text()
    shutil.rmtree(env["ROS_HOME"], ignore_errors=True)
    print(output[-6000:])
    print(f"  {len(blocks)} blocks of {', '.join(sorted({b.document for b in blocks}))}: "
          f"exit {process.returncode}")
    return process.returncode == 0


def main():
    root = pathlib.Path(sys.argv[1]).resolve()
    build = pathlib.Path(sys.argv[2]).resolve()
    test = sys.argv[3]
    blocks = snippets(root)
    if test != "docs_inventory":
        blocks = [b for b in blocks if b.kind == test]
        if not blocks:
            print(f"FAIL: no block of the docs is marked for {test}")
            return 1
        print(f"{test}: {len(blocks)} blocks: {', '.join(str(b) for b in blocks)}")
    return 0 if globals()[test](root, build, blocks) else 1


if __name__ == "__main__":
    sys.exit(main())
