#!/usr/bin/python3
"""Learns the peg-insertion skill's parameters with the cross-entropy method on a Dask cluster.

PegInsertion-v0 with the hole's observed position off by up to goal_noise (1 mm) in x and y: a
straight descent onto the observed position jams on the block's top face most of the time; the
skill (cartesian_impedance.skills.InsertionSkill) can search with a spiral while pressing.
rollouts.cem tunes its 8 parameters on a rollouts.Pool (LocalCluster, 2 workers), each sample
scored on --episodes episodes of its own seeds; the final mean is then evaluated on held-out
seeds. Prints the
success per iteration and writes the learning curve (matplotlib, Agg) to --plot.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/peg_insertion_cem.py
"""

import argparse
import functools
import json
import time

import numpy as np

from cartesian_impedance import rollouts
from cartesian_impedance.skills import InsertionSkill, insertion_rollout

# The starting guess: straight down onto the observed hole (no search), moderately stiff.
START = InsertionSkill(approach=0.005, speed=0.3, press=0.004, radius=0.0, turns=3.0,
                       period=1.0, stiffness_xy=0.5, stiffness_z=0.5)
# The sampling spread of each parameter (NAMES' order): about the range where it matters.
SPREAD = [0.003, 0.15, 0.003, 0.002, 1.0, 0.4, 0.8, 0.8]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--iterations", type=int, default=12)
    parser.add_argument("--episodes", type=int, default=4,
                        help="episodes (seeds) per sample of the population")
    parser.add_argument("--population", type=int, default=32)
    parser.add_argument("--evaluation-seeds", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--goal-noise", type=float, default=0.001, help="[m]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--plot", default="peg_insertion_cem.png")
    parser.add_argument("--json", default="", help="write the figures to this file")
    args = parser.parse_args(argv)

    options = {"goal_noise": args.goal_noise}
    rollout = functools.partial(insertion_rollout, env_options=options, episodes=args.episodes)
    evaluation = functools.partial(insertion_rollout, env_options=options)
    # Held-out seeds: cem's are below 2^31 and the episodes' seeds spawned from them are 32-bit
    # hashes, so these (2^31 + k) meet one of them with a chance of about 1e-7 per episode.
    evaluation_seeds = [2**31 + k for k in range(args.evaluation_seeds)]
    figures = {"iterations": []}
    start = time.monotonic()
    with rollouts.Pool(n_workers=args.workers) as pool:
        def success_of(params):
            results = pool.map(evaluation, [(params, s) for s in evaluation_seeds])
            return float(np.mean([r["success"] for r in results]))

        figures["start_success"] = success_of(START.vector())
        print("start (straight down): success %.2f on %d held-out seeds" %
              (figures["start_success"], len(evaluation_seeds)), flush=True)
        successes = []

        def score(result):
            # cem ranks each population in this process, in order: the successes of an
            # iteration are the last `population` recorded.
            successes.append(result["success"])
            if len(successes) % args.population == 0:
                row = {"iteration": len(successes) // args.population,
                       "population_success": float(np.mean(successes[-args.population:])),
                       "wall_time": time.monotonic() - start}
                figures["iterations"].append(row)
                print("iteration %d: population success %.2f, %.0f s" %
                      (row["iteration"], row["population_success"], row["wall_time"]),
                      flush=True)
            return result["score"]

        result = rollouts.cem(rollout, START.vector(), SPREAD, iterations=args.iterations,
                              population=args.population, score=score, seed=args.seed,
                              pool=pool)
        mean = result.mean
        figures["final_mean"] = dict(zip(InsertionSkill.NAMES, map(float, mean)))
        figures["final_success"] = success_of(mean)
    figures["wall_time"] = time.monotonic() - start
    print("final mean: %s" % ", ".join("%s %.4g" % kv for kv in figures["final_mean"].items()))
    print("final mean: success %.2f on %d held-out seeds; %.0f s in all" %
          (figures["final_success"], len(evaluation_seeds), figures["wall_time"]))
    if args.json:
        with open(args.json, "w") as out:
            json.dump(figures, out, indent=1)
    if args.plot:
        plot(figures, args.plot)
    return figures


def plot(figures, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = figures["iterations"]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot([r["iteration"] for r in rows], [r["population_success"] for r in rows], "o-",
            label="population (sampled parameters)")
    # Iteration 0 is the starting guess itself, on the held-out seeds, not a population.
    ax.plot([0], [figures["start_success"]], "s", color="tab:red",
            label="start (straight descent), held-out seeds")
    ax.axhline(figures["final_success"], color="g", ls="--",
               label="final mean, held-out seeds")
    ax.set_xlabel("CEM iteration")
    ax.set_ylabel("insertion success")
    ax.set_ylim(0, 1.02)
    ax.legend(loc="lower right")
    ax.set_title("PegInsertion-v0, goal noise 1 mm: CEM on InsertionSkill")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()
