#!/usr/bin/python3
"""Environment steps per second of make_vector(id, n) against n separate environments stepped one
after another, for n = 1, 2, 4, 8: each environment step is one policy step at 20 Hz (50 cycles
of simulation and C++ control loop at 1 kHz) plus the Python around it. The vector environment
runs the n simulations and loops together on C++ threads (sim.BatchRunner, GIL released); the
Python parts (actions, observations, rewards) stay serial. Random actions, episodes of
max_episode_steps with their resets (autoreset for the vector). Best of --repeats runs, to damp
other processes on the machine; its load average is printed.

Not run by ctest. Usage (from the repository root, after building the module):

    PYTHONPATH=build/python /usr/bin/python3 python/benchmarks/bench_envs_vector.py
        [--env CartesianImpedance/Reach-v0] [--steps 1600] [--repeats 3] [--threads 0]
"""

import argparse
import os
import time

import cartesian_impedance.envs as envs


def separate_rate(env_id, n, steps):
    singles = [envs.make(env_id) for _ in range(n)]
    for i, env in enumerate(singles):
        env.reset(seed=i)
        env.action_space.seed(i)
    rounds = max(1, steps // n)
    begin = time.perf_counter()
    for _ in range(rounds):
        for env in singles:
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                env.reset()
    return rounds * n / (time.perf_counter() - begin)


def vector_rate(env_id, n, steps, threads):
    vector = envs.make_vector(env_id, n, threads=threads)
    vector.reset(seed=0)
    vector.action_space.seed(0)
    rounds = max(1, steps // n)
    begin = time.perf_counter()
    for _ in range(rounds):
        vector.step(vector.action_space.sample())
    elapsed = time.perf_counter() - begin
    vector.close()
    return rounds * n / elapsed


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="CartesianImpedance/Reach-v0")
    parser.add_argument("--steps", type=int, default=1600, help="environment steps per run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=0, help="0 = one per core")
    parser.add_argument("--sizes", default="1,2,4,8")
    arguments = parser.parse_args()
    print("%s, %d cores, load average before: %.2f %.2f %.2f" %
          ((arguments.env, os.cpu_count()) + os.getloadavg()))
    print("%4s %18s %18s %9s" % ("n", "separate steps/s", "vector steps/s", "speed-up"))
    for n in [int(size) for size in arguments.sizes.split(",")]:
        separate = max(separate_rate(arguments.env, n, arguments.steps)
                       for _ in range(arguments.repeats))
        vector = max(vector_rate(arguments.env, n, arguments.steps, arguments.threads)
                     for _ in range(arguments.repeats))
        print("%4d %18.0f %18.0f %8.2fx" % (n, separate, vector, vector / separate))
    print("load average after: %.2f %.2f %.2f" % os.getloadavg())


if __name__ == "__main__":
    main()
