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


def phases(env_id, n, rounds, threads):
    """Per environment step [us]: the Python before (action) and after (observation, reward)
    the batch, the batch itself, and the same simulation and loops run one after another. Python
    stays serial, so on c free cores the speed-up is at most
    (python + serial) / (python + serial / c)."""
    vector = envs.make_vector(env_id, n, threads=threads, max_episode_steps=rounds + 1)
    vector.reset(seed=0)
    vector.action_space.seed(0)
    every = list(range(n))
    before = batch = after = serial = 0.0
    for _ in range(rounds):
        actions = vector.action_space.sample()
        start = time.perf_counter()
        for env, action in zip(vector.envs, actions):
            env.apply_action(action)
        applied = time.perf_counter()
        vector._advance(every)
        advanced = time.perf_counter()
        for env in vector.envs:
            env.finish_step()
        finished = time.perf_counter()
        for env in vector.envs:  # then the same again, one pair after another
            env.sim.run(env.loop, env.period)
        serial += time.perf_counter() - finished
        before, batch, after = (before + applied - start, batch + advanced - applied,
                                after + finished - advanced)
    vector.close()
    scale = 1e6 / (rounds * n)
    return before * scale, batch * scale, after * scale, serial * scale


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
    n = max(int(size) for size in arguments.sizes.split(","))
    before, batch, after, serial = phases(arguments.env, n, 200, arguments.threads)
    python = before + after
    print("n = %d, per environment step: Python %.0f us (action %.0f, observation and reward "
          "%.0f), batch %.0f us, the same pairs one after another %.0f us; with Python serial "
          "the speed-up on 2 free cores is at most %.2fx" %
          (n, python, before, after, batch, serial, (python + serial) / (python + serial / 2)))


if __name__ == "__main__":
    main()
