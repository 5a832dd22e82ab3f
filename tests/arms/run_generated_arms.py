#!/usr/bin/python3
"""Runs the demo's scenarios on generated arms nobody tuned (the ctest `generated_arms`).

    run_generated_arms.py --demo build/apps/cartesian_impedance_demo [--count 20] [--seed 1]
                          [--first 0] [--no-regression] [--dart 4] [--jobs 2] [--report]
                          [--keep DIR]
    run_generated_arms.py --self-check [--count 20] [--seed 1]     (the ctest `arm_generator`)

Generates --count arms from seeds --seed + --first, --seed + --first + 1, ... (the environment
variable CI_ARM_SEED picks another base seed; --first lets two runs share one base seed without
overlapping), adds the regression arms of tests/arms/regression/ (unless --no-regression), runs
`cartesian_impedance_demo --urdf ... --base-link ... --tip-link ... --no-render --no-plots` on each
with MuJoCo and on DART every sixth generated arm counted from the base seed (at most --dart of
them), --jobs at a time. Exits 0 only
if every run exits 0; otherwise prints per failing run the seed, the joints, the exit code, the
demo's FAIL and could-not-run lines, and the commands that reproduce it. --report prints a table
of every run and the FAIL lines per scenario instead, and exits 0 (for measurements).

--self-check tests the generator itself: the same seed gives the same file, and each arm loads in
the library (Python module `cartesian_impedance`, PYTHONPATH=build/python) with the joint count
asked for, positive masses, efforts and velocities in the generator's ranges, and gravity torques
g(q) over sampled configurations that every joint holds with the margin the generator promises.
"""

import argparse
import collections
import concurrent.futures
import glob
import math
import os
import random
import re
import resource
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ElementTree

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import generate_arm  # noqa: E402

DEFAULT_SEED = 1
DART_EVERY = 6
REGRESSION_DIR = os.path.join(HERE, "regression")


def base_seed(option):
    if option is not None:
        return option
    return int(os.environ.get("CI_ARM_SEED", DEFAULT_SEED))


def arms_to_run(count, seed, folder, regression=True):
    """(label, seed or None, urdf path, info) of the generated arms and the regression arms."""
    arms = []
    for s in range(seed, seed + count):
        urdf, info = generate_arm.generate(s)
        path = os.path.join(folder, "arm_seed_%d.urdf" % s)
        with open(path, "w") as f:
            f.write(urdf)
        arms.append(("seed %d" % s, s, path, info))
    for path in sorted(glob.glob(os.path.join(REGRESSION_DIR, "*.urdf")) if regression else []):
        joints = sum(1 for j in ElementTree.parse(path).getroot().iter("joint")
                     if j.get("type") == "revolute")
        arms.append((os.path.relpath(path, os.path.dirname(os.path.dirname(HERE))), None, path,
                     {"joints": joints, "base_link": "base_link", "tip_link": "tool0"}))
    return arms


HEADER = re.compile(r"^\[\d+/\d+\] (.+?) \.\.\. ?(.*)$")


def run_demo(demo, arm, engine, out):
    label, seed, path, info = arm
    command = [demo, "--urdf", path, "--base-link", info["base_link"], "--tip-link",
               info["tip_link"], "--no-render", "--no-plots"]
    if engine != "mujoco":
        command += ["--engine", engine]
    command += ["--out", out]
    # The demo runs in its output folder: MuJoCo writes MUJOCO_LOG.TXT (an unstable simulation)
    # into the working folder, which is shown below and must not litter the caller's.
    os.makedirs(out, exist_ok=True)
    started = time.time()
    try:
        done = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              universal_newlines=True, timeout=600, cwd=out)
        code, output = done.returncode, done.stdout
    except subprocess.TimeoutExpired as expired:
        code, output = "timeout", (expired.output or "") if isinstance(expired.output, str) else ""
    seconds = time.time() - started
    failures = collections.Counter()  # scenario -> FAIL lines
    not_run = []
    problems = []  # the lines to show
    scenario = None
    for line in output.splitlines():
        header = HEADER.match(line)
        if header:
            scenario = header.group(1)
            if header.group(2).startswith("could not run"):
                not_run.append(scenario)
                problems.append("%s: %s" % (scenario, header.group(2)))
            continue
        stripped = line.strip()
        if stripped.startswith("FAIL"):
            failures[scenario] += 1
            problems.append("%s: %s" % (scenario, " ".join(stripped.split())))
        elif code == 2 and stripped.startswith("cartesian_impedance_demo:"):
            problems.append(stripped)
    if code not in (0, 1, 3) and not problems:
        problems = output.strip().splitlines()[-5:]
    unstable = 0
    mujoco_log = os.path.join(out, "MUJOCO_LOG.TXT")
    if os.path.exists(mujoco_log):
        with open(mujoco_log) as f:
            warnings = [line.strip() for line in f if line.startswith("WARNING")]
        unstable = len(warnings)
        problems += ["MuJoCo: " + w for w in warnings[:3]]
    return dict(label=label, seed=seed, joints=info["joints"], engine=engine, code=code,
                failures=failures, not_run=not_run, problems=problems, unstable=unstable,
                seconds=seconds,
                command=" ".join(command[:-2] + ["--out", "/tmp/arm_demo"]))


def reproduce(result, arm):
    lines = []
    if result["seed"] is not None:
        lines.append("/usr/bin/python3 tests/arms/generate_arm.py --seed %d --out %s"
                     % (result["seed"], arm[2].replace(os.path.dirname(arm[2]), "/tmp")))
        return lines + [result["command"].replace(os.path.dirname(arm[2]), "/tmp")]
    return [result["command"]]


def run_all(args):
    if not os.access(args.demo or "", os.X_OK):
        print("run_generated_arms: --demo '%s' is not an executable" % args.demo)
        return 2
    seed = base_seed(args.seed) + args.first
    with tempfile.TemporaryDirectory(prefix="generated_arms_") as scratch:
        folder = os.path.abspath(args.keep or scratch)  # the demo runs in its output folder
        args.demo = os.path.abspath(args.demo)
        os.makedirs(folder, exist_ok=True)
        arms = arms_to_run(args.count, seed, folder, not args.no_regression)
        # DART on every DART_EVERY-th generated arm counted from the base seed (at most --dart),
        # so that splitting the seeds over two runs (--first) keeps the same arms on DART.
        first = seed - args.first
        on_dart = [arm for arm in arms
                   if arm[1] is not None and (arm[1] - first) % DART_EVERY == 0]
        on_dart = on_dart[:max(0, args.dart)]
        jobs = [(arm, "mujoco") for arm in arms] + [(arm, "dart") for arm in on_dart]
        print("%d arms (seeds %d..%d and %d regression arms): %d runs on MuJoCo, %d on DART, "
              "%d at a time" % (len(arms), seed, seed + args.count - 1, len(arms) - args.count,
                                len(arms), len(on_dart), args.jobs), flush=True)
        results = []
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            futures = {}
            for index, (arm, engine) in enumerate(jobs):
                out = os.path.join(folder, "out_%d_%s" % (index, engine))
                futures[pool.submit(run_demo, args.demo, arm, engine, out)] = (arm, index)
            for future in concurrent.futures.as_completed(futures):
                result = future.result()
                arm, index = futures[future]
                result["arm"], result["index"] = arm, index
                results.append(result)
                print("  %-40s %-6s exit %s" % (result["label"], result["engine"], result["code"]),
                      flush=True)
        results.sort(key=lambda r: r["index"])
        print("demo runs: %.0f s of CPU in all, the longest %.0f s" % (
            resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
            + resource.getrusage(resource.RUSAGE_CHILDREN).ru_stime,
            max(r["seconds"] for r in results)))
        failed = [r for r in results if r["code"] != 0]
        if args.report:
            print_report(results)
            return 0
        if not failed:
            print("every run exits 0 (%d runs)" % len(results))
            return 0
        print("\n%d of %d runs did not exit 0:" % (len(failed), len(results)))
        for r in failed:
            print("\n%s (%d joints), %s: exit %s" % (r["label"], r["joints"], r["engine"],
                                                     r["code"]))
            for line in r["problems"]:
                print("    " + line)
            print("  reproduce (from the source folder):")
            for line in reproduce(r, r["arm"]):
                print("    " + line)
        return 1


def print_report(results):
    print("\n%-40s %-6s %-6s %-5s %s" % ("arm", "joints", "engine", "exit", "FAIL lines per "
                                           "scenario / could not run"))
    per_scenario = collections.Counter()
    arms_per_scenario = collections.Counter()
    not_run = collections.Counter()
    codes = collections.Counter()
    for r in results:
        detail = ", ".join("%s %d" % (s, n) for s, n in sorted(r["failures"].items()))
        if r["not_run"]:
            detail += (", " if detail else "") + "not run: " + ", ".join(r["not_run"])
        if r["unstable"]:
            detail += (", " if detail else "") + "MuJoCo unstable %d times" % r["unstable"]
        if r["code"] == 2:
            detail += " ".join(r["problems"])[:150]
        print("%-40s %-6d %-6s %-5s %s" % (r["label"], r["joints"], r["engine"], r["code"],
                                           detail))
        codes[r["code"]] += 1
        for s, n in r["failures"].items():
            per_scenario[s] += n
            arms_per_scenario[s] += 1
        for s in r["not_run"]:
            not_run[s] += 1
    passed = sum(1 for r in results if r["code"] == 0)
    print("\npassed (exit 0): %d of %d runs (%.0f %%); exit codes: %s" % (
        passed, len(results), 100.0 * passed / max(1, len(results)),
        ", ".join("%s: %d" % (c, n) for c, n in sorted(codes.items(), key=str))))
    print("%-20s %12s %14s %14s" % ("scenario", "FAIL lines", "runs with FAIL", "not run"))
    for s in sorted(set(per_scenario) | set(not_run), key=lambda s: -arms_per_scenario[s]):
        print("%-20s %12d %14d %14d" % (s, per_scenario[s], arms_per_scenario[s], not_run[s]))


# ---- the generator's self-check (ctest arm_generator) ----
def self_check(args):
    seed = base_seed(args.seed)
    problems = []

    def check(condition, message):
        if not condition:
            problems.append(message)

    try:
        import cartesian_impedance as ci
    except ImportError as error:
        print("run_generated_arms --self-check: the Python module cartesian_impedance is not "
              "importable (%s); set PYTHONPATH=build/python" % error)
        return 1
    joint_counts = collections.Counter()
    weak = 0
    with tempfile.TemporaryDirectory(prefix="arm_generator_") as folder:
        previous = None
        for s in range(seed, seed + args.count):
            urdf, info = generate_arm.generate(s)
            check(urdf != previous, "seeds %d and %d: the same file" % (s - 1, s))
            previous = urdf
            joints = info["joints"]
            joint_counts[joints] += 1
            weak += info["weak_wrist"]
            if s < seed + 3:  # a few suffice: each generate() takes about 0.5 s
                check(urdf == generate_arm.generate(s)[0],
                      "seed %d: two runs give different files" % s)
                check(urdf == generate_arm.generate(s, joints)[0],
                      "seed %d --joints %d: not the arm of seed %d" % (s, joints, s))
                for asked in set((5, 6, 7)) - {joints}:
                    check(generate_arm.generate(s, asked)[1]["joints"] == asked,
                          "seed %d --joints %d: another joint count" % (s, asked))
            path = os.path.join(folder, "arm.urdf")
            with open(path, "w") as f:
                f.write(urdf)
            problems.extend("seed %d: %s" % (s, p) for p in check_urdf(ci, path, info))
        regression = sorted(glob.glob(os.path.join(REGRESSION_DIR, "arm_seed_*.urdf")))
        for path in regression:
            s = int(re.search(r"arm_seed_(\d+)", path).group(1))
            with open(path) as f:
                committed = f.read()
            joints = int(re.search(r"joints (\d)\)", committed).group(1))
            check(committed == generate_arm.generate(s, joints)[0],
                  "%s: the generator no longer writes it (regenerate it, or keep the old arm)"
                  % path)
    print("%d arms from seed %d: joints %s, %d with weak wrists; %d regression arms" % (
        args.count, seed, dict(sorted(joint_counts.items())), weak, len(regression)))
    check(set(joint_counts) == {5, 6, 7} or args.count < 10,
          "the joint counts drawn are %s, not 5, 6 and 7" % sorted(joint_counts))
    for p in problems:
        print("FAIL " + p)
    print("ok" if not problems else "%d problems" % len(problems))
    return 1 if problems else 0


def check_urdf(ci, path, info):
    """What the library and the URDF text say about the arm, against the generator's promises."""
    problems = []
    root = ElementTree.parse(path).getroot()
    masses = {}
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            problems.append("link %s has no <inertial>" % link.get("name"))
            continue
        mass = float(inertial.find("mass").get("value"))
        i = inertial.find("inertia").attrib
        xx, yy, zz = float(i["ixx"]), float(i["iyy"]), float(i["izz"])
        xy, xz, yz = float(i["ixy"]), float(i["ixz"]), float(i["iyz"])
        masses[link.get("name")] = mass
        # Positive definite (leading minors) and the triangle inequality of principal moments.
        minors = (xx, xx * yy - xy * xy, xx * (yy * zz - yz * yz) - xy * (xy * zz - yz * xz)
                  + xz * (xy * yz - yy * xz))
        if mass <= 0 or min(minors) <= 0 or xx + yy < zz or yy + zz < xx or xx + zz < yy:
            problems.append("link %s: mass %g, inertia %s not physical" % (link.get("name"), mass,
                                                                          i))
    total = sum(masses.values())
    if not generate_arm.TOTAL_MASS_RANGE[0] <= total <= generate_arm.TOTAL_MASS_RANGE[1] + 0.5:
        problems.append("total mass %.2f kg" % total)
    model = ci.RobotModel.from_urdf_file(path, info["base_link"], info["tip_link"])
    n = model.num_joints
    if n != info["joints"]:
        problems.append("the library sees %d joints, not %d" % (n, info["joints"]))
        return problems
    moving = total - masses["base_link"]
    if abs(model.moving_mass - moving) > 1e-6 * moving:
        problems.append("the library's moving mass %.4f kg, the file's %.4f kg"
                        % (model.moving_mass, moving))
    limits = model.limits
    for j, c in enumerate(info["joint_classes"]):
        lo, hi = generate_arm.EFFORT_RANGE[c]
        if not lo - 1e-6 <= limits.effort[j] <= hi + 1e-6:
            problems.append("joint %d (%s): effort %g Nm outside %g..%g" % (j + 1, c,
                                                                          limits.effort[j], lo, hi))
        lo, hi = generate_arm.VELOCITY_RANGE[c]
        if not lo - 1e-6 <= limits.velocity[j] <= hi + 1e-6:
            problems.append("joint %d (%s): velocity %g rad/s outside %g..%g"
                            % (j + 1, c, limits.velocity[j], lo, hi))
    # The library's own gravity torques, with the base turned so every joint's axis can lie
    # horizontal: at random configurations and gravity directions no joint needs more than its
    # effort / margin. (The generator's promise is over its own sampling; the library's dynamics
    # are independent of it. 1e-3 relative covers the 10 digits the file keeps.)
    rng = random.Random(info["seed"])
    for _ in range(200):
        q = [rng.uniform(max(-math.pi, l), min(math.pi, u))
             for l, u in zip(limits.position_lower, limits.position_upper)]
        direction = [rng.gauss(0, 1) for _ in range(3)]
        length = math.sqrt(sum(d * d for d in direction))
        gravity = [9.81 * d / length for d in direction]
        turned = ci.RobotModel.from_urdf_file(path, info["base_link"], info["tip_link"],
                                              gravity=gravity)
        g = turned.compute(q).gravity
        upright = model.compute(q).gravity
        for j, c in enumerate(info["joint_classes"]):
            if j == 0:  # joint 1 turns about the vertical of the arm as mounted: it holds nothing
                if abs(upright[0]) > 1e-6 * limits.effort[0]:
                    problems.append("joint 1 carries %.3g Nm of gravity upright" % upright[0])
                continue
            margin = (generate_arm.WEAK_HOLD_MARGIN if info["weak_wrist"] and c == "wrist"
                      else generate_arm.HOLD_MARGIN)
            if abs(g[j]) * margin > limits.effort[j] * (1 + 1e-3) + 1e-9:
                problems.append("joint %d: gravity torque %.3f Nm at q = %s x %.1f exceeds its "
                                "effort %.3f Nm" % (j + 1, g[j], [round(v, 3) for v in q],
                                                     margin, limits.effort[j]))
                return problems
    return problems


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--demo", help="the cartesian_impedance_demo executable")
    parser.add_argument("--count", type=int, default=20, help="generated arms (default 20)")
    parser.add_argument("--seed", type=int, help="first seed (default: $CI_ARM_SEED or %d)"
                        % DEFAULT_SEED)
    parser.add_argument("--first", type=int, default=0,
                        help="skip this many seeds after the first (default 0)")
    parser.add_argument("--no-regression", action="store_true",
                        help="only the generated arms, not those of tests/arms/regression/")
    parser.add_argument("--dart", type=int, default=4,
                        help="also run at most N of the arms on DART: every sixth generated arm "
                        "from the base seed (default 4)")
    parser.add_argument("--jobs", type=int, default=2, help="demo runs at a time (default 2)")
    parser.add_argument("--report", action="store_true",
                        help="print every run's result and the pass rates; always exit 0")
    parser.add_argument("--keep", help="write the arms and the demo's output here")
    parser.add_argument("--self-check", action="store_true",
                        help="check the generator (determinism, loading, ranges) and exit")
    args = parser.parse_args()
    if args.self_check:
        return self_check(args)
    return run_all(args)


if __name__ == "__main__":
    sys.exit(main())
