"""cartesian_impedance.rollouts on a Dask LocalCluster of two worker processes: results in the
input order and equal to a serial run, a worker killed mid-rollout loses nothing and counts
nothing twice, a raising rollout is named (also one that calls sys.exit() or returns what cannot
be pickled), and the cross-entropy method finds a known optimum (also past rollouts scored NaN).

The rollout is the real library: a Panda in MuJoCo reaching for 0.5 s with the stiffness given by
params, toward a target drawn from the seed, in the worker processes (which import the module)."""

import functools
import gc
import os
import signal
import sys
import threading

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


def exiting_at_seed_1(log, params, seed):
    if seed == 1:
        with open(log, "a") as file:
            file.write("%d\n" % os.getpid())
        sys.exit("rollout 1 gives up")
    return {"seed": seed}


def interrupted(params, seed):
    raise KeyboardInterrupt


def seed_only(params, seed):
    return {"seed": seed}


def result_holding_a_lock(params, seed):
    return {"seed": seed, "lock": threading.Lock()}


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


def test_a_rollout_calling_sys_exit_is_named_and_not_rerun(pool, tmp_path):
    """SystemExit is not an Exception: it escaped the serial run, and on a worker it ended the
    task as a dead worker does, run again retries times (9 s) and then blamed on the process."""
    log = tmp_path / "runs"
    rollout = functools.partial(exiting_at_seed_1, str(log))
    pairs = [([1.0], k) for k in range(3)]
    with pytest.raises(rollouts.RolloutError,
                       match=r"^rollout 1 \(params=\[1.0\], seed=1\) raised SystemExit: "
                             r"rollout 1 gives up") as raised:
        pool.map(rollout, pairs)
    assert isinstance(raised.value.__cause__, SystemExit)
    assert "exiting_at_seed_1" in raised.value.remote_traceback
    # Run once, in a worker process that lives on (no rerun, no restart).
    (pid,) = [int(line) for line in log.read_text().split()]
    assert pid in pool.client.run(os.getpid).values()
    with pytest.raises(rollouts.RolloutError, match=r"^rollout 1 .* raised SystemExit"):
        rollouts.evaluate(rollout, pairs, serial=True)
    # Ctrl-C stops a serial run as it stops anything else.
    with pytest.raises(KeyboardInterrupt):
        rollouts.evaluate(interrupted, pairs, serial=True)
    assert [r["seed"] for r in pool.map(seed_only, pairs)] == [0, 1, 2]


def test_a_result_that_cannot_be_pickled_is_named_by_its_pair_and_key(pool):
    """A result Dask could not send back ended its task 'finished' with nothing to fetch, and the
    cause was only in the workers' logs."""
    with pytest.raises(rollouts.RolloutError,
                       match=r"^rollout [0-2] \(params=\[1.0\], seed=[0-2]\) raised TypeError: "
                             r"the rollout's result cannot be pickled .*lock.*; the values of "
                             r"'lock' cannot be pickled") as raised:
        pool.map(result_holding_a_lock, [([1.0], k) for k in range(3)])
    assert raised.value.index == raised.value.seed
    # Serially nothing is sent: the result comes back as it is.
    (result,) = rollouts.evaluate(result_holding_a_lock, [([1.0], 0)], serial=True)
    assert result["seed"] == 0
    # The pool goes on.
    assert [r["seed"] for r in pool.map(seed_only, [([1.0], 5)])] == [5]


def test_cem_never_keeps_a_nan_best_and_raises_when_nothing_was_scored():
    """A first population scored NaN (every comparison with NaN is False: the NaN best was never
    replaced), later ones finite: the best is the best finite one, and the distribution did not
    move on the unscored population."""
    calls = []

    def nan_for_the_first_population(result):
        calls.append(None)
        return float("nan") if len(calls) <= 24 else result["score"]

    found = rollouts.cem(quadratic, [0.0, 0.0, 0.0], [2.0, 2.0, 2.0], iterations=20,
                         population=24, seed=7, score=nan_for_the_first_population, serial=True)
    assert len(calls) == 20 * 24
    assert np.isfinite(found.best_score) and found.best_score > -1e-3
    assert found.best_score == quadratic(found.best_params, 0)["score"]
    assert found.best_score == max(entry["best_score"] for entry in found.history[1:])
    assert np.array_equal(found.history[0]["mean"], [0.0, 0.0, 0.0])
    assert np.array_equal(found.history[0]["std"], [2.0, 2.0, 2.0])
    assert found.history[0]["unscored"] == 24 and np.isnan(found.history[0]["best_score"])
    assert found.history[1]["unscored"] == 0
    # NaN for the samples near the optimum, minimising: they are never elite nor best.
    half = rollouts.cem(quadratic, [0.0, 0.0, 0.0], [2.0, 2.0, 2.0], iterations=20,
                        population=24, seed=7, maximize=False, serial=True,
                        score=lambda r: float("nan") if r["score"] > -4.0 else -r["score"])
    assert np.isfinite(half.best_score) and half.best_score >= 4.0
    assert all(entry["elite_score"] >= 4.0 for entry in half.history
               if entry["unscored"] < 24)
    # Nothing scored in the whole run: an error, not a result.
    with pytest.raises(ValueError, match=r"^score 'score' was NaN for every one of the 8 "
                                         r"rollouts \(2 iterations of 4\)"):
        rollouts.cem(lambda params, seed: {"score": float("nan")}, [0.0], [1.0], iterations=2,
                     population=4, serial=True)


def test_cem_rejects_scores_and_options_that_are_not_what_they_claim():
    # float() of a NumPy complex drops its imaginary part with only a ComplexWarning.
    with pytest.raises(ValueError, match=r"^score <function .*> could not be read .*"
                                         r"\(1\+2j\) is not a real number"):
        rollouts.cem(quadratic, [0.0], [1.0], score=lambda r: np.complex128(1 + 2j),
                     serial=True, iterations=1)
    for option, value, message in [
            ("iterations", True, r"iterations = True must be an int >= 1"),
            ("iterations", 2.0, r"iterations = 2.0 must be an int >= 1"),
            ("population", 1, r"population = 1 must be an int >= 2"),
            ("elite_fraction", "0.5", r"elite_fraction = '0.5' must be a number in \(0, 1\]"),
            ("elite_fraction", float("nan"), r"elite_fraction = nan must be a number"),
            ("std_smoothing", 1.0, r"std_smoothing = 1.0 must be a number in \[0, 1\)"),
            ("min_std", float("inf"), r"min_std = inf must be a number finite and >= 0")]:
        with pytest.raises(ValueError, match="^" + message):
            rollouts.cem(quadratic, [0.0], [1.0], serial=True, **{option: value})
    for name, value in [("mean", [1.0 + 1.0j]), ("mean", [None]), ("std", ["1"])]:
        with pytest.raises(TypeError, match=r"^%s = .* must be real numbers" % name):
            rollouts.cem(quadratic, **dict({"mean": [0.0], "std": [1.0]}, **{name: value}),
                         serial=True)


def test_insertion_skill_refuses_values_it_would_pass_on_as_nan():
    from cartesian_impedance.skills import InsertionSkill, insertion_rollout

    good = InsertionSkill().vector()
    assert np.array_equal(InsertionSkill.from_vector(good).vector(), good)
    # min(max(nan, low), high) is NaN: the skill made NaN actions, refused mid-episode.
    for index, value in [(0, np.nan), (6, np.inf)]:
        bad = good.copy()
        bad[index] = value
        with pytest.raises(ValueError, match=r"^InsertionSkill %s = %s is not finite" % (
                InsertionSkill.NAMES[index], value)):
            InsertionSkill.from_vector(bad)
    with pytest.raises(TypeError, match=r"^InsertionSkill values must be real numbers, got "
                                        r"dtype complex128"):
        InsertionSkill.from_vector(good + 0j)
    for episodes in (0, 1.5, True):
        with pytest.raises(ValueError, match=r"^episodes = %r must be an int >= 1" % episodes):
            insertion_rollout(good, 0, episodes=episodes)


def test_a_pool_dropped_unclosed_ends_its_worker_processes():
    def alive(pid):
        try:
            with open("/proc/%d/stat" % pid) as stat:
                return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return False

    dropped = rollouts.Pool(n_workers=1)
    pids = list(dropped.client.run(os.getpid).values())
    assert pids and all(alive(pid) for pid in pids)
    with pytest.warns(ResourceWarning, match=r"dropped without close\(\)"):
        del dropped
        gc.collect()
    assert not any(alive(pid) for pid in pids)


def test_a_rollout_or_params_that_cannot_be_pickled_are_named(pool):
    """Dask said only "cannot pickle '_thread.lock' object", not whose."""
    lock = threading.Lock()
    with pytest.raises(TypeError, match=r"^the rollout <function .*<lambda>.*> cannot be pickled "
                                        r"to be sent to the workers \(TypeError: cannot pickle "
                                        r"'_thread.lock' object\)"):
        pool.map(lambda params, seed, lock=lock: {"seed": seed}, [([1.0], 0)])
    with pytest.raises(TypeError, match=r"^pairs\[1\] \(params=<unlocked _thread.lock object .*>, "
                                        r"seed=1\) cannot be pickled to be sent to a worker"):
        pool.map(seed_only, [([1.0], 0), (lock, 1)])
    assert [r["seed"] for r in pool.map(seed_only, [([1.0], 2)])] == [2]
    # NumPy integers are ints (a count computed with NumPy), bools are not.
    assert [r["seed"] for r in pool.map(seed_only, [([1.0], 3)], chunk_size=np.int64(2))] == [3]
    with pytest.raises(ValueError, match=r"^chunk_size = True must be an int >= 1"):
        pool.map(seed_only, [([1.0], 3)], chunk_size=True)
    with pytest.raises(ValueError, match=r"^n_workers = True must be an int >= 1"):
        rollouts.Pool(n_workers=True)
