#!/usr/bin/python3
"""Per-step cost of ControlLoop.step(q, dq, dt) called from Python, against the same step run in
C++ in the same process, so the difference is what the bindings add (argument conversion, the
call, the returned NumPy array). The setup is that of BM_LoopStep in bench/bench_loop.cpp: Panda,
default parameters, dq = 0.01 rad/s, a reference 5 cm below the start.

Not run by ctest. Usage (from the repository root, after building the module):

    PYTHONPATH=build/python /usr/bin/python3 python/benchmarks/bench_step.py [--calls 200000]
        [--cpp-benchmark build/bench/benchmarks]

--cpp-benchmark also runs Google Benchmark's BM_LoopStep/native for comparison.
"""

import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import time
import timeit

import numpy as np

import cartesian_impedance as ci

SOURCE_DIR = pathlib.Path(
    os.environ.get("CARTESIAN_IMPEDANCE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
READY = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])


def make_loop():
    model = ci.RobotModel.from_urdf_file(SOURCE_DIR / "models/panda/panda.urdf", "panda_link0",
                                         "panda_link8")
    loop = ci.ControlLoop(model)
    q, dq = READY.copy(), np.full(7, 0.01)
    loop.start(q, dq)
    target = loop.state.controller.pose
    loop.set_reference_pose((target.position - [0, 0, 0.05], target.orientation))
    loop.step(q, dq, 0.001)
    return loop, q, dq


def per_call_us(function, calls, repeats):
    """Time per call of `function` [us], (best, median) over `repeats` runs of `calls` calls, as
    wall time and as CPU time (the latter is what Google Benchmark's "CPU" column shows; on a
    shared machine the wall time also holds the time other processes had the core)."""
    result = []
    for timer in (time.perf_counter, time.process_time):
        totals = timeit.repeat(function, number=calls, repeat=repeats, timer=timer)
        per_call = [1e6 * total / calls for total in totals]
        result.append((min(per_call), statistics.median(per_call)))
    return result


def cpp_us(loop, q, dq, calls, repeats):
    runs = [loop._benchmark_steps(q, dq, 0.001, calls) for _ in range(repeats)]
    return [(min(1e6 * run[i] / calls for run in runs),
             statistics.median(1e6 * run[i] / calls for run in runs)) for i in (0, 1)]


def tail_us(function, calls):
    """Per-call timing of single calls: median, 99th percentile and worst [us] (each includes the
    cost of reading the clock, subtracted as measured on an empty call)."""
    clock = time.perf_counter_ns
    empty = []
    for _ in range(calls):
        start = clock()
        empty.append(clock() - start)
    baseline = statistics.median(empty)
    samples = []
    for _ in range(calls):
        start = clock()
        function()
        samples.append(clock() - start - baseline)
    samples = np.array(samples) / 1e3
    return np.median(samples), np.percentile(samples, 99), samples.max()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=int, default=200000, help="calls per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--cpp-benchmark", help="path of build/bench/benchmarks, to run too")
    args = parser.parse_args()

    loop, q, dq = make_loop()
    q_list, dq_list = q.tolist(), dq.tolist()
    rows = [("C++ loop.step() in the module (GIL released)", cpp_us(loop, q, dq, args.calls,
                                                                      args.repeats))]
    rows.append(("Python loop.step(q, dq, dt), NumPy float64 arrays",
                 per_call_us(lambda: loop.step(q, dq, 0.001), args.calls, args.repeats)))
    rows.append(("Python loop.step(q, dq, dt), lists of floats",
                 per_call_us(lambda: loop.step(q_list, dq_list, 0.001), args.calls, args.repeats)))
    cpp = rows[0][1]

    print("per-step time over %d calls x %d repeats [us]; overhead = best minus C++ best"
          % (args.calls, args.repeats))
    print("%-52s %21s   %21s" % ("", "wall: best median overhead", "CPU: best median overhead"))
    for name, timings in rows:
        text = "%-52s" % name
        for (best, median), (cpp_best, _) in zip(timings, cpp):
            overhead = "" if name.startswith("C++") else "%.2f" % (best - cpp_best)
            text += " %8.3f %7.3f %5s  " % (best, median, overhead)
        print(text)

    median, p99, worst = tail_us(lambda: loop.step(q, dq, 0.001), min(args.calls, 100000))
    print("single Python calls (NumPy arrays): median %.2f, 99th percentile %.2f, worst %.1f us"
          % (median, p99, worst))
    status = loop.state.controller.status
    assert status == ci.Status.ok, status

    if args.cpp_benchmark:
        print("\nGoogle Benchmark, %s:" % args.cpp_benchmark)
        sys.stdout.flush()
        subprocess.run([args.cpp_benchmark, "--benchmark_filter=BM_LoopStep/native$",
                        "--benchmark_repetitions=5", "--benchmark_report_aggregates_only=true"],
                       check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
