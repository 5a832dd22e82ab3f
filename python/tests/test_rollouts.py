"""cartesian_impedance.rollouts on a Dask LocalCluster of two worker processes: results in the
input order and equal to a serial run, a worker killed mid-rollout loses nothing and counts
nothing twice, a raising rollout is named, and the cross-entropy method finds a known optimum.

The rollout is the real library: a Panda in MuJoCo reaching for 0.5 s with the stiffness given by
params, toward a target drawn from the seed, in the worker processes (which import the module)."""

import functools
import os
import signal
import sys

import cloudpickle
import numpy as np
import pytest

import cartesian_impedance as ci
from cartesian_impedance import rollouts
from conftest import PANDA_URDF, PANDA_XML, requires_sim

# The workers cannot import this test file: its functions travel by value (what they use from
# cartesian_impedance, numpy, ... is imported there).
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def reach(params, seed):
    """0.5 s of a Panda reaching 5 cm in a direction drawn from the seed, with translational
    stiffness params[0] [N/m]: the final position error [m] and joint positions."""
    model = ci.RobotModel.from_urdf_file(PANDA_URDF, "panda_link0", "panda_link8")
    sim = ci.sim.Simulation.from_mjcf_file(PANDA_XML)
    loop = ci.ControlLoop(model, {"stiffness.translation": float(params[0])})
    loop.start(sim.q, sim.dq)
    direction = np.random.default_rng(seed).normal(size=3)
    pose = loop.state.controller.pose
    target = pose.position + 0.05 * direction / np.linalg.norm(direction)
    loop.set_reference_pose((target, pose.orientation))
    sim.run(loop, 0.5)
    error = float(np.linalg.norm(loop.state.controller.pose.position - target))
    return {"error": error, "q": sim.q, "seed": seed, "pid": os.getpid()}


def reach_killing_its_worker_once(marker, log, params, seed):
    """reach(), but the first rollout of seed 3 kills its worker process (SIGKILL, as the OOM
    killer would) halfway; every completed run is logged."""
    if seed == 3 and not os.path.exists(marker):
        open(marker, "w").close()
        os.kill(os.getpid(), signal.SIGKILL)
    result = reach(params, seed)
    with open(log, "a") as file:
        file.write("%d\n" % seed)
    return result


def raising_at_seed_2(params, seed):
    if seed == 2:
        raise ValueError("stiffness %g is not allowed here" % params[0])
    return {"seed": seed}


def quadratic(params, seed):
    """A toy objective with its optimum at (1, -2, 0.5): the score is -|params - optimum|^2."""
    del seed
    return {"score": -float(np.sum((np.asarray(params) - [1.0, -2.0, 0.5]) ** 2))}


PAIRS = [([stiffness], seed) for seed, stiffness in enumerate([200, 400, 800, 1200, 1600, 300])]


def without_pid(results):
    return [{key: value for key, value in result.items() if key != "pid"} for result in results]


def assert_equal_results(measured, expected):
    assert len(measured) == len(expected)
    for index, (a, b) in enumerate(zip(measured, expected)):
        assert a.keys() == b.keys(), index
        for key in a:
            assert np.array_equal(a[key], b[key]), (index, key, a[key], b[key])


@pytest.fixture(scope="module")
def pool():
    with rollouts.Pool(n_workers=2, retries=2) as started:
        yield started


@requires_sim
def test_results_come_in_input_order_and_equal_a_serial_run(pool):
    serial = without_pid([reach(params, seed) for params, seed in PAIRS])
    results = pool.map(reach, PAIRS)
    assert [result["seed"] for result in results] == [seed for _, seed in PAIRS]
    assert_equal_results(without_pid(results), serial)
    assert {result["pid"] for result in results}.isdisjoint({os.getpid()})  # ran in workers
    # Stiffer reaches get closer in 0.5 s: the params reached the controller.
    errors = {params[0]: result["error"] for (params, _), result in zip(PAIRS, results)}
    assert errors[1600] < errors[200]
    # Chunks of rollouts per task, and the serial pool, give the same.
    assert_equal_results(without_pid(pool.map(reach, PAIRS, chunk_size=4)), serial)
    assert_equal_results(without_pid(rollouts.evaluate(reach, PAIRS, serial=True)), serial)


@requires_sim
def test_a_worker_killed_mid_rollout_loses_nothing_and_counts_nothing_twice(pool, tmp_path):
    marker, log = tmp_path / "killed", tmp_path / "completed"
    rollout = functools.partial(reach_killing_its_worker_once, str(marker), str(log))
    results = pool.map(rollout, PAIRS)
    assert marker.exists()  # a worker did die
    assert len(results) == len(PAIRS)
    assert [result["seed"] for result in results] == [seed for _, seed in PAIRS]
    serial = without_pid([reach(params, seed) for params, seed in PAIRS])
    assert_equal_results(without_pid(results), serial)
    # The killed run of seed 3 never completed; its rerun did. A rollout that shared the dead
    # worker may have been rerun as well, but each pair's result is taken once.
    completed = [int(line) for line in log.read_text().split()]
    assert sorted(set(completed)) == [seed for _, seed in PAIRS]


def test_a_raising_rollout_is_named_by_its_pair(pool):
    with pytest.raises(rollouts.RolloutError) as raised:
        pool.map(raising_at_seed_2, [([100.0 * k], k) for k in range(5)])
    error = raised.value
    assert (error.index, error.params, error.seed) == (2, [200.0], 2)
    assert "rollout 2 (params=[200.0], seed=2) raised ValueError: stiffness 200 is not allowed" \
        in str(error)
    assert "raising_at_seed_2" in error.remote_traceback
    assert isinstance(error.__cause__, ValueError)
    # Serially the same.
    with pytest.raises(rollouts.RolloutError, match=r"^rollout 2 \(params=\[200.0\], seed=2\)"):
        rollouts.evaluate(raising_at_seed_2, [([100.0 * k], k) for k in range(5)], serial=True)
    with pytest.raises(TypeError, match=r"^pairs\[1\] must be a pair \(params, seed\)"):
        pool.map(raising_at_seed_2, [([1.0], 0), 7])
    with pytest.raises(rollouts.RolloutError, match=r"returned list; a rollout returns a dict"):
        rollouts.evaluate(lambda params, seed: [seed], [([1.0], 0)], serial=True)


def test_cem_finds_the_optimum_of_a_quadratic(pool):
    options = dict(iterations=20, population=24, elite_fraction=0.25, seed=7)
    found = rollouts.cem(quadratic, [0.0, 0.0, 0.0], [2.0, 2.0, 2.0], pool=pool, chunk_size=8,
                         **options)
    # The search narrows onto the optimum: the mean, an average of the 6 elite samples drawn with
    # that spread, lies within 3 final spreads of it (7 standard errors of the elite's mean).
    optimum = np.array([1.0, -2.0, 0.5])
    assert np.all(found.std < 0.02), found.std
    assert np.all(np.abs(found.mean - optimum) <= 3 * found.std), (found.mean, found.std)
    assert found.best_score == pytest.approx(-np.sum((found.best_params - optimum) ** 2))
    assert found.best_score > -1e-3
    assert found.best_result == quadratic(found.best_params, 0)
    assert found.history[-1]["elite_score"] > found.history[0]["elite_score"]
    assert len(found.history) == 20
    # Reproducible: the same seed gives the same search serially.
    serial = rollouts.cem(quadratic, [0.0, 0.0, 0.0], [2.0, 2.0, 2.0], serial=True, **options)
    assert np.array_equal(serial.mean, found.mean) and np.array_equal(serial.std, found.std)
    # Minimising the same score drives the search away from the optimum.
    away = rollouts.cem(quadratic, [0.0, 0.0, 0.0], [2.0, 2.0, 2.0], serial=True,
                        maximize=False, **dict(options, iterations=3))
    assert away.best_score < found.best_score - 1.0
    with pytest.raises(ValueError, match=r"^mean has shape \(2,\) and std \(3,\)"):
        rollouts.cem(quadratic, [0.0, 0.0], [1.0, 1.0, 1.0], serial=True)
    with pytest.raises(ValueError, match=r"^score 'reward' could not be read"):
        rollouts.cem(quadratic, [0.0], [1.0], score="reward", serial=True, iterations=1)
