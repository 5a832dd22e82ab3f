#!/usr/bin/python3
"""Speed-up of batched closed loops (cartesian_impedance.sim.BatchRunner, run_many) over running
the same pairs one after the other with sim.run(loop, seconds), for n = 1, 2, 4, 8 Panda pairs
(MuJoCo, default parameters, a 10 cm reference step). Wall time, best of --repeats.

Not run by ctest. Usage (from the repository root, after building the module):

    PYTHONPATH=build/python /usr/bin/python3 python/benchmarks/bench_batch.py [--seconds 1.0]
        [--per-call 0.01] [--repeats 3]

--per-call: also the cost of many short calls (as a learning environment makes them): the same
simulated time in calls of this many seconds, with a BatchRunner kept and with run_many (threads
started per call).
"""

import argparse
import os
import pathlib
import time

import cartesian_impedance as ci

SOURCE_DIR = pathlib.Path(
    os.environ.get("CARTESIAN_IMPEDANCE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))


def make_pairs(model, n):
    sims, loops = [], []
    for _ in range(n):
        sim = ci.sim.Simulation.from_mjcf_file(SOURCE_DIR / "models/panda/panda.xml")
        loop = ci.ControlLoop(model)
        loop.start(sim.q, sim.dq)
        pose = loop.state.controller.pose
        loop.set_reference_pose((pose.position + [0.1, 0, 0], pose.orientation))
        sims.append(sim)
        loops.append(loop)
    return sims, loops


def best_of(repeats, make, run):
    times = []
    for _ in range(repeats):
        pairs = make()
        begin = time.perf_counter()
        run(*pairs)
        times.append(time.perf_counter() - begin)
    return min(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=1.0, help="simulated time per pair")
    parser.add_argument("--per-call", type=float, default=0.01, help="seconds per short call")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    model = ci.RobotModel.from_urdf_file(SOURCE_DIR / "models/panda/panda.urdf", "panda_link0",
                                         "panda_link8")
    calls = int(round(args.seconds / args.per_call))
    print("cores: %d; %g s simulated per pair (1 ms steps)" % (os.cpu_count(), args.seconds))
    print("%6s %10s %10s %8s %14s %8s %14s %8s" % (
        "pairs", "serial s", "batch s", "speedup", "batch/%g s" % args.per_call, "speedup",
        "run_many/%g s" % args.per_call, "speedup"))
    for n in (1, 2, 4, 8):
        def make():
            return make_pairs(model, n)

        def serial(sims, loops):
            for sim, loop in zip(sims, loops):
                sim.run(loop, args.seconds)

        def batch(sims, loops):
            ci.sim.BatchRunner(sims, loops).run(args.seconds)

        def batch_calls(sims, loops):
            runner = ci.sim.BatchRunner(sims, loops)
            for _ in range(calls):
                runner.run(args.per_call)

        def run_many_calls(sims, loops):
            for _ in range(calls):
                ci.sim.run_many(sims, loops, args.per_call)

        t_serial = best_of(args.repeats, make, serial)
        t_batch = best_of(args.repeats, make, batch)
        t_calls = best_of(args.repeats, make, batch_calls)
        t_many = best_of(args.repeats, make, run_many_calls)
        print("%6d %10.3f %10.3f %8.2f %14.3f %8.2f %14.3f %8.2f" % (
            n, t_serial, t_batch, t_serial / t_batch, t_calls, t_serial / t_calls, t_many,
            t_serial / t_many))


if __name__ == "__main__":
    main()
