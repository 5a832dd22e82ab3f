#!/usr/bin/python3
"""Environment steps per second of cartesian_impedance.envs, per task, robot and engine: each
step is one policy step at 20 Hz, i.e. 50 cycles of the simulation and the C++ control loop at
1 kHz plus what Python does around them (the action's commands, the observation, the reward).
Random actions from the seeded action space; episodes of max_episode_steps, reset time included.
One process, one core.

Not run by ctest. Usage (from the repository root, after building the module):

    PYTHONPATH=build/python /usr/bin/python3 python/benchmarks/bench_envs.py [--steps 2000]
        [--robot panda] [--engine mujoco|dart|both]
"""

import argparse
import time

import cartesian_impedance as ci
import cartesian_impedance.envs as envs


def measure(env_id, robot, engine, steps):
    env = envs.make(env_id, robot=robot, engine=engine)
    env.action_space.seed(0)
    env.reset(seed=0)
    done_steps, resets = 0, 1
    begin = time.perf_counter()
    while done_steps < steps:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done_steps += 1
        if terminated or truncated:
            env.reset()
            resets += 1
    elapsed = time.perf_counter() - begin
    return done_steps / elapsed, resets


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--robot", default="panda")
    parser.add_argument("--engine", default="mujoco", choices=["mujoco", "dart", "both"])
    arguments = parser.parse_args()
    engines = ["mujoco", "dart"] if arguments.engine == "both" else [arguments.engine]
    print("%-30s %-8s %-7s %14s %16s %7s" % ("environment", "robot", "engine", "steps/s",
                                            "sim x real time", "resets"))
    for engine in engines:
        available, reason = ci.sim.engine_available(engine)
        if not available:
            print("%s: not available (%s)" % (engine, reason))
            continue
        for env_id in envs.ids():
            rate, resets = measure(env_id, arguments.robot, engine, arguments.steps)
            print("%-30s %-8s %-7s %14.0f %16.1f %7d" % (env_id, arguments.robot, engine, rate,
                                                        rate / 20.0, resets))


if __name__ == "__main__":
    main()
