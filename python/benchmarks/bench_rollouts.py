#!/usr/bin/python3
"""Dask's cost per rollout in cartesian_impedance.rollouts: a trivial rollout (returns its seed)
through a LocalCluster of worker processes, against the same rollouts called serially in this
process, one rollout per Dask task and in chunks. Also the time to start and close the cluster.

Not run by ctest. Usage (from the repository root, after building the module):

    PYTHONPATH=build/python /usr/bin/python3 python/benchmarks/bench_rollouts.py [--rollouts 2000]
        [--workers 2]
"""

import argparse
import time

from cartesian_impedance import rollouts


def trivial(params, seed):
    return {"seed": seed, "params": params}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rollouts", type=int, default=2000)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    pairs = [([float(k)], k) for k in range(args.rollouts)]

    begin = time.perf_counter()
    serial = rollouts.evaluate(trivial, pairs, serial=True)
    t_serial = time.perf_counter() - begin

    begin = time.perf_counter()
    pool = rollouts.Pool(n_workers=args.workers)
    t_start = time.perf_counter() - begin
    try:
        pool.map(trivial, pairs[:50])  # workers warm (the function unpickled once)
        print("%d rollouts, %d workers; LocalCluster start: %.2f s" % (
            args.rollouts, args.workers, t_start))
        print("serial:                 %8.1f us per rollout" % (1e6 * t_serial / args.rollouts))
        for chunk_size in (1, 10, 100):
            begin = time.perf_counter()
            results = pool.map(trivial, pairs, chunk_size=chunk_size)
            elapsed = time.perf_counter() - begin
            assert results == serial
            print("dask, chunk_size %4d:  %8.1f us per rollout" % (
                chunk_size, 1e6 * elapsed / args.rollouts))
    finally:
        begin = time.perf_counter()
        pool.close()
        print("LocalCluster close: %.2f s" % (time.perf_counter() - begin))


if __name__ == "__main__":
    main()
