"""cartesian_impedance.envs.make_vector: n environments advanced together by sim.BatchRunner end
bit for bit where n separate environments with the same seeds and actions end (next-step
autoreset included), with Gymnasium's vector API (batched spaces, infos with masks) and errors
that name the environment and change nothing."""

import re

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import requires_sim

pytestmark = requires_sim

if hasattr(ci, "sim"):
    import cartesian_impedance.envs as envs

REACH = "CartesianImpedance/Reach-v0"
WIPE = "CartesianImpedance/Wipe-v0"


def run_separately(singles, seeds, actions):
    """The reference: each environment alone, with next-step autoreset done by hand (Gymnasium
    1.x's default). Returns the stacked (observations, rewards, terminations, truncations, tank
    levels) of the reset and of every step."""
    first = [env.reset(seed=seed) for env, seed in zip(singles, seeds)]
    trace = [(np.stack([o for o, _ in first]), None, None, None,
              np.array([i["tank_level"] for _, i in first]))]
    done = [False] * len(singles)
    for batch in actions:
        rows = []
        for i, env in enumerate(singles):
            if done[i]:
                observation, info = env.reset()
                rows.append((observation, 0.0, False, False, info))
            else:
                rows.append(env.step(batch[i]))
            done[i] = rows[-1][2] or rows[-1][3]
        trace.append((np.stack([r[0] for r in rows]), np.array([r[1] for r in rows]),
                      np.array([r[2] for r in rows]), np.array([r[3] for r in rows]),
                      np.array([r[4]["tank_level"] for r in rows])))
    return trace


def run_vector(vector, seed, actions):
    observations, infos = vector.reset(seed=seed)
    trace = [(observations, None, None, None, infos["tank_level"])]
    for batch in actions:
        observations, rewards, terminations, truncations, infos = vector.step(batch)
        assert rewards.dtype == np.float64 and terminations.dtype == np.bool_
        assert infos["_tank_level"].all()
        trace.append((observations, rewards, terminations, truncations, infos["tank_level"]))
    return trace


def assert_same_traces(vector_trace, separate_trace):
    assert len(vector_trace) == len(separate_trace)
    for step, (got, expected) in enumerate(zip(vector_trace, separate_trace)):
        for name, a, b in zip(("observations", "rewards", "terminations", "truncations",
                               "tank_level"), got, expected):
            if b is None:
                continue
            assert np.array_equal(a, b), "step %d: %s differ\n%s\n%s" % (step, name, a, b)


def random_actions(space, n, steps, seed):
    rng = np.random.default_rng(seed)
    return [rng.uniform(-1, 1, (n,) + space.shape).astype(np.float32) for _ in range(steps)]


def test_make_vector_is_bit_identical_to_separate_envs_through_an_autoreset():
    n, steps = 3, 7  # episodes of 3 steps: two autoresets, all environments at once
    vector = envs.make_vector(REACH, n, max_episode_steps=3, start_noise=0.05)
    singles = [envs.make(REACH, max_episode_steps=3, start_noise=0.05) for _ in range(n)]
    actions = random_actions(vector.single_action_space, n, steps, seed=1)
    vector_trace = run_vector(vector, 10, actions)
    assert_same_traces(vector_trace, run_separately(singles, [10, 11, 12], actions))
    # The autoreset step: reward 0, both flags False, the reset observation.
    assert vector_trace[3][3].all() and not vector_trace[4][3].any()
    assert np.array_equal(vector_trace[4][1], np.zeros(n))
    # Different seeds give different environments (the comparison above can fail).
    assert not np.array_equal(vector_trace[0][0][0], vector_trace[0][0][1])
    vector.close()
    assert vector.closed


def test_staggered_episodes_wipe_and_a_task_with_its_own_advance_stay_bit_identical():
    # Episodes of 2, 3 and 4 steps: some environments reset while the others run (a one-off
    # batch of those), and the kept runner is renewed after each reset.
    lengths = [2, 3, 4]
    vector = envs.VectorEnv([envs.make(REACH, max_episode_steps=m) for m in lengths],
                            threads=2)
    singles = [envs.make(REACH, max_episode_steps=m) for m in lengths]
    actions = random_actions(vector.single_action_space, 3, 9, seed=2)
    assert_same_traces(run_vector(vector, [3, 4, 5], actions),
                       run_separately(singles, [3, 4, 5], actions))
    # Wipe's normal force is averaged over every millisecond by the simulation itself
    # (track_contact_wrench), so it runs batched too.
    vector = envs.make_vector(WIPE, 2, seeds=[7, 8], max_episode_steps=2)
    assert vector._batched == [0, 1]
    singles = [envs.make(WIPE, max_episode_steps=2) for _ in range(2)]
    actions = random_actions(vector.single_action_space, 2, 3, seed=3)
    assert_same_traces(run_vector(vector, None, actions),
                       run_separately(singles, [7, 8], actions))
    # A task with its own advance() is advanced by it, one environment after another, beside
    # the batched ones.
    mixed = [envs.make(REACH, max_episode_steps=3), HalfStepsReach(max_episode_steps=3),
             envs.make(REACH, max_episode_steps=3)]
    vector = envs.VectorEnv(mixed, threads=2, spin=0.0)  # its pool sleeps between steps
    assert vector._batched == [0, 2]
    singles = [envs.make(REACH, max_episode_steps=3), HalfStepsReach(max_episode_steps=3),
               envs.make(REACH, max_episode_steps=3)]
    actions = random_actions(vector.single_action_space, 3, 5, seed=4)
    assert_same_traces(run_vector(vector, [1, 2, 3], actions),
                       run_separately(singles, [1, 2, 3], actions))
    assert mixed[1].halves == singles[1].halves > 0


class HalfStepsReach(envs.Reach if hasattr(ci, "sim") else object):
    """A task that runs its policy period in two halves in its own advance()."""

    def __init__(self, **options):
        super().__init__(**options)
        self.halves = 0

    def advance(self):
        for _ in range(2):
            self.sim.run(self.loop, self.period / 2)
            self.halves += 1


def test_spaces_are_batched_and_the_api_is_gymnasiums():
    vector = envs.make_vector(REACH, 4)
    single = envs.make(REACH)
    assert vector.num_envs == 4 and len(vector.envs) == 4
    assert vector.single_action_space == single.action_space
    assert vector.single_observation_space == single.observation_space
    assert vector.action_space.shape == (4, 12) and vector.action_space.dtype == np.float32
    assert vector.observation_space.shape == (4, 49)
    assert vector.observation_space.dtype == np.float32
    assert np.array_equal(vector.action_space.low, np.stack([single.action_space.low] * 4))
    assert np.array_equal(vector.action_space.high, np.stack([single.action_space.high] * 4))
    assert vector.metadata["autoreset_mode"] == envs.vector.AUTORESET_MODE
    observations, infos = vector.reset(seed=0)
    assert observations.shape == (4, 49) and observations.dtype == np.float32
    assert vector.observation_space.contains(observations)
    assert infos["status"].tolist() == ["ok"] * 4 and infos["_status"].all()
    assert vector.action_space.contains(vector.action_space.sample())


def test_bad_actions_and_seeds_raise_naming_the_environment_and_change_nothing():
    vector = envs.make_vector(REACH, 3, seeds=0, max_episode_steps=5)
    twin = envs.make_vector(REACH, 3, seeds=0, max_episode_steps=5)
    with pytest.raises(RuntimeError, match="reset"):
        vector.step(np.zeros((3, 12)))
    vector.reset()
    twin.reset()
    good = np.full((3, 12), 0.5, dtype=np.float32)
    bad_row = good.copy()
    bad_row[2, 4] = np.nan
    with pytest.raises(ci.Error, match=r"env 2: action\[4\] = nan .*rotation.y"):
        vector.step(bad_row)
    with pytest.raises(ci.Error, match=r"env 0: action has shape \(11,\), expected \(12,\)"):
        vector.step(good[:, :11])
    with pytest.raises(ci.Error, match=r"actions has 2 rows, expected num_envs = 3"):
        vector.step(good[:2])
    ragged = [good[0], good[1], good[2, :5]]
    with pytest.raises(ci.Error, match=r"env 2: action has shape \(5,\)"):
        vector.step(ragged)
    with pytest.raises(ci.Error, match="seed has 2 seeds, expected 3"):
        vector.reset(seed=[1, 2])
    # Nothing of the rejected calls stayed: the next step is the twin's.
    got, expected = vector.step(good), twin.step(good)
    for a, b in zip(got[:4], expected[:4]):
        assert np.array_equal(a, b)
    with pytest.raises(ci.Error, match="seeds has 4 seeds, expected 2"):
        envs.make_vector(REACH, 2, seeds=[1, 2, 3, 4])
    with pytest.raises(ci.Error, match="n = 0"):
        envs.make_vector(REACH, 0)
    with pytest.raises(ci.Error, match=r"spin = -0.1 s is outside \[0, 1\] s"):
        envs.make_vector(REACH, 1, spin=-0.1)


def test_counts_seeds_and_actions_of_a_wrong_type_raise_before_anything_changes():
    # int() made 2.9 environments 2 and accepted '2'.
    for n in (2.9, "2", 2.0, True, None):
        with pytest.raises(TypeError, match=r"^n = %s must be an int, got %s$" % (
                re.escape(repr(n)), type(n).__name__)):
            envs.make_vector(REACH, n)
    with pytest.raises(TypeError, match=r"^threads = 1.5 must be an int"):
        envs.make_vector(REACH, 1, threads=1.5)
    with pytest.raises(ci.Error, match=r"^threads = -1 must be >= 0 \(0 = one per core\)"):
        envs.make_vector(REACH, 1, threads=-1)
    with pytest.raises(TypeError, match=r"^seeds\[1\] = 2.5 must be an int or None"):
        envs.make_vector(REACH, 2, seeds=[1, 2.5])
    with pytest.raises(TypeError, match=r"^seeds = '12' must be an int, a sequence of 2 ints"):
        envs.make_vector(REACH, 2, seeds="12")
    vector = envs.make_vector(REACH, np.int64(2), seeds=[3, None], max_episode_steps=5)
    twin = envs.make_vector(REACH, 2, seeds=[3, None], max_episode_steps=5)
    assert vector.num_envs == 2
    # A negative seed is refused before environment 0 is reset (SeedSequence would refuse it
    # only at environment 0, after nothing, or at a later one, after the first were reset).
    with pytest.raises(ci.Error, match=r"^seed\[0\] = -1 must be >= 0"):
        vector.reset(seed=-1)
    first = vector.reset(seed=[3, 4])
    assert np.array_equal(first[0], twin.reset(seed=[3, 4])[0])
    good = np.full((2, 12), 0.5, dtype=np.float32)
    with pytest.raises(TypeError, match=r"^env 1: action must be real numbers .* complex64$"):
        vector.step([good[0], good[1] + 0.5j])
    with pytest.raises(TypeError, match=r"^actions = 0.5 must be an array of num_envs = 2 rows"):
        vector.step(0.5)
    got, expected = vector.step(good), twin.step(good)
    for a, b in zip(got[:4], expected[:4]):
        assert np.array_equal(a, b)

