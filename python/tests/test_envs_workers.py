"""Environments in worker processes, as Gymnasium's AsyncVectorEnv and Stable-Baselines3's
SubprocVecEnv run them: the parent makes one environment (AsyncVectorEnv does, for the spaces),
then forks workers that each make their own and reset it. Forked workers start as copies of the
parent, so a name one of them makes from its copied state (a heap address, a generator's state)
is the name every other makes too, and one removes the file another is reading. PegInsertion
rebuilds its scene from the URDF at every reset, the path that writes such a file. Real worker
processes (fork and spawn), several resets each, started together at a barrier; nothing may be
left in their temporary folder. And what a forked process inherits: a vector environment whose
BatchRunner's threads stayed in the parent, an environment whose render() files the copy could
remove."""

import multiprocessing
import os

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import requires_sim

pytestmark = requires_sim

if hasattr(ci, "sim"):
    import cartesian_impedance.envs as envs

PEG = "CartesianImpedance/PegInsertion-v0"
REACH = "CartesianImpedance/Reach-v0"
WORKERS = 4
RESETS = 6


def reset_in_a_worker(barrier, results, index, temporary):
    """A worker's life under AsyncVectorEnv: make the environment, reset it (a new scene each
    time) and step once; the outcome is sent back, never raised (a worker's traceback would not
    reach the test)."""
    try:
        os.environ["TMPDIR"] = temporary  # the C++ temporary files go where the test looks
        env = envs.make(PEG, max_episode_steps=2)
        observations = []
        for episode in range(RESETS):
            # Every worker resets at the same time, as a vector environment's do.
            barrier.wait(timeout=60)
            # The same seeds in every worker: their heaps stay alike, as the forks' of one
            # parent are, so a name made from an address is the same in each at every reset.
            observation, _ = env.reset(seed=100 + episode)
            observations.append(observation)
        observation, *_ = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        env.close()
        results.put((index, "ok", np.stack(observations)))
    except BaseException as error:  # noqa: BLE001  (reported to the test)
        barrier.abort()
        results.put((index, "error", "%s: %s" % (type(error).__name__, error)))


def run_workers(method, temporary):
    context = multiprocessing.get_context(method)
    barrier = context.Barrier(WORKERS)
    results = context.Queue()
    workers = [context.Process(target=reset_in_a_worker, args=(barrier, results, i, temporary))
               for i in range(WORKERS)]
    for worker in workers:
        worker.start()
    try:
        outcomes = dict((index, (status, value)) for index, status, value in
                        (results.get(timeout=120) for _ in workers))
    finally:
        for worker in workers:
            worker.join(timeout=30)
            if worker.is_alive():  # only after a failure above: leave no process behind
                worker.kill()
                worker.join()
    assert [worker.exitcode for worker in workers] == [0] * WORKERS
    return outcomes


# Landed: the temporary MJCF file was named by the model's heap address, alike in forked workers
# ("cannot read '<tmp>/cartesian_impedance_906488064.xml'" in about two of three runs here,
# depending on the timing); named by mkstemps, 0 of 10.
@pytest.mark.parametrize("method", ["fork", "spawn"])
def test_peg_insertion_in_worker_processes_resets_in_each(method, tmp_path):
    # The parent has made and used an environment before the fork, as AsyncVectorEnv's parent
    # has: the workers inherit its state.
    parent = envs.make(PEG, max_episode_steps=2)
    expected = [parent.reset(seed=100 + episode)[0] for episode in range(RESETS)]
    parent.close()
    outcomes = run_workers(method, str(tmp_path))
    errors = {index: value for index, (status, value) in outcomes.items() if status != "ok"}
    assert not errors, errors
    # Each worker's episodes are the ones its seeds give in this process: the scenes were its own.
    for index in range(WORKERS):
        assert np.array_equal(outcomes[index][1], np.stack(expected)), index
    # Nothing of theirs stays behind.
    assert sorted(os.listdir(tmp_path)) == []


def step_after_the_fork(vector, runner, actions, results):
    """In the forked process: the parent's BatchRunner refuses to run (its threads are the
    parent's), and the vector environment steps on threads of its own."""
    try:
        try:
            runner.run(0.01)
            results.put(("runner", "ran"))
        except ci.Error as error:
            results.put(("runner", str(error)))
        results.put(("vector", vector.step(actions)[0]))
    except BaseException as error:  # noqa: BLE001  (reported to the test)
        results.put(("error", "%s: %s" % (type(error).__name__, error)))


def test_a_vector_env_made_before_a_fork_steps_in_the_forked_process():
    """fork copies only the calling thread: a BatchRunner's pool stays in the parent, and a step
    in the child waited for it forever (so did dropping the runner, joining threads that are not
    there)."""
    vector = envs.make_vector(REACH, 2, threads=2, seeds=0, max_episode_steps=5)
    twin = envs.make_vector(REACH, 2, threads=2, seeds=0, max_episode_steps=5)
    actions = np.full((2, 12), 0.5, dtype=np.float32)
    for each in (vector, twin):
        each.reset()
        each.step(actions)  # its runner's threads are running now
    pairs = [envs.make(REACH) for _ in range(2)]
    for env in pairs:
        env.reset(seed=0)
    runner = ci.sim.BatchRunner([env.sim for env in pairs], [env.loop for env in pairs], 2)
    runner.run(0.01)
    context = multiprocessing.get_context("fork")
    results = context.Queue()
    worker = context.Process(target=step_after_the_fork,
                             args=(vector, runner, actions, results))
    worker.start()
    try:
        outcomes = dict(results.get(timeout=60) for _ in range(2))
    finally:
        worker.join(timeout=30)
        if worker.is_alive():
            worker.kill()
            worker.join()
    assert worker.exitcode == 0 and "error" not in outcomes, outcomes
    assert outcomes["runner"] == (
        "this BatchRunner was made in process %d and its threads do not exist in this forked "
        "process %d: make a new BatchRunner here" % (os.getpid(), worker.pid))
    # The child's step is the one the twin takes here.
    assert np.array_equal(outcomes["vector"], twin.step(actions)[0])
    # The parent's runner and vector go on.
    assert np.array_equal(runner.run(0.01), [10, 10])
    assert np.array_equal(vector.step(actions)[0], outcomes["vector"])


def close_after_the_fork(env, results):
    try:
        env.close()  # the copy's close, as a worker's end does
        results.put("closed")
    except BaseException as error:  # noqa: BLE001  (reported to the test)
        results.put("%s: %s" % (type(error).__name__, error))


def test_rendering_keeps_no_file_a_forked_copy_can_take_away(tmp_path, monkeypatch):
    """render() kept one folder for its frames: a forked copy of the environment that closed
    removed it under the parent, whose next render() failed; and it stayed behind a process
    that never closed."""
    available, reason = ci.sim.offscreen_rendering_available()
    if not available:
        pytest.skip("offscreen rendering unavailable: " + reason)
    pytest.importorskip("PIL", reason="render() needs Pillow (Debian: python3-pil)")
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    env = envs.make(REACH, render_mode="rgb_array", render_size=(24, 32))
    env.reset(seed=0)
    first = env.render()
    context = multiprocessing.get_context("fork")
    results = context.Queue()
    worker = context.Process(target=close_after_the_fork, args=(env, results))
    worker.start()
    try:
        assert results.get(timeout=60) == "closed"
    finally:
        worker.join(timeout=30)
        if worker.is_alive():
            worker.kill()
            worker.join()
    assert np.array_equal(env.render(), first)  # nothing moved: the same picture
    assert os.listdir(tmp_path) == []  # and no frame stays
