"""PegInsertion (cartesian_impedance.envs): the Gymnasium API, determinism under a seed, the
scene (the tip is the controlled frame, the hole where the goal says), a scripted insertion that
succeeds and policies that must fail."""

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import requires_sim

pytestmark = requires_sim

if hasattr(ci, "sim"):
    import cartesian_impedance.envs as envs
    from test_envs import robot_part, run_episode

PEG = "CartesianImpedance/PegInsertion-v0"


def insertion_policy(env, obs, speed=0.3):
    """Moves the reference above the observed goal (x, y), and once the tip is within 0.5 mm of
    it laterally, down at `speed` of the largest step (0.3: 3 mm per step, 6 cm/s), at a moderate
    translational stiffness (action 0.5: 1525 N/m; at 1050 N/m the tip sags across the hole's
    edge on 3 of 10 seeds) and the middle of the rotational range (77.5 Nm/rad)."""
    part = robot_part(env, obs)
    goal = obs[-7:-4]
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    step = env.actions.limits.max_translation_step
    action[0:2] = np.clip((goal[:2] - part["reference"][:2]) / step, -1, 1)
    if np.linalg.norm(goal[:2] - part["position"][:2]) < 5e-4:
        action[2] = -speed
    action[6:9] = 0.5
    return action


def test_registered_and_the_api():
    assert PEG in envs.ids()
    env = envs.make(PEG, max_episode_steps=3)
    assert env.spec.id == PEG and isinstance(env, envs.PegInsertion)
    assert env.action_space.shape == (12,) and env.action_space.dtype == np.float32
    assert env.observation_space.shape == (2 * 7 + 32 + 7,)
    obs, info = env.reset(seed=0)
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    assert info["is_success"] is False and info["status"] == "ok"
    env.action_space.seed(0)
    for k in range(3):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        assert type(reward) is float and np.isfinite(reward)
        assert type(terminated) is bool and type(truncated) is bool
        assert truncated == (k == 2)
    assert env.sim.time == pytest.approx(0.001 + 3 * 0.05)
    env.close()


def test_the_tip_is_controlled_the_peg_declared_and_the_goal_is_the_hole():
    env = envs.make(PEG, start_noise=0.0)
    obs, info = env.reset(seed=3)
    assert env.parameters["payload.mass"] == env.peg_mass
    # The observed pose is the peg's tip (the tool offset), where the simulated peg ends.
    peg = env.sim.body_pose("peg").matrix()
    tip = peg[:3, 3] + peg[:3, 2] * env.peg_length / 2
    np.testing.assert_allclose(robot_part(env, obs)["position"], tip, atol=1e-6)
    # The goal: the hole's opening, `gap` below the tip, off by at most hole_noise in x and y.
    goal = obs[-7:].astype(float)
    np.testing.assert_allclose(goal[:3], info["hole"], atol=1e-6)
    assert goal[2] == pytest.approx(tip[2] - env.gap, abs=1e-4)
    assert np.all(np.abs(goal[:2] - tip[:2]) <= env.hole_noise + 1e-4)
    np.testing.assert_allclose(goal[3:], obs[2 * 7 + 3:2 * 7 + 7], atol=1e-6)  # tip's attitude
    assert info["depth"] == pytest.approx(-env.gap, abs=1e-4)
    with pytest.raises(ci.Error, match=r"clearance = 0\.002 must be in \(0, 0\.001\]"):
        envs.make(PEG, clearance=0.002)


def test_same_seed_same_episode_other_seed_another():
    env = envs.make(PEG, max_episode_steps=6)

    def episode(seed):
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        observations, rewards = [obs], []
        truncated = terminated = False
        while not (truncated or terminated):
            obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            observations.append(obs)
            rewards.append(reward)
        return np.array(observations), np.array(rewards)

    first = episode(1)
    other = episode(2)
    again = episode(1)
    np.testing.assert_array_equal(first[0], again[0])
    np.testing.assert_array_equal(first[1], again[1])
    assert not np.array_equal(first[0][0][-7:], other[0][0][-7:])  # the hole moved


def test_scripted_insertion_succeeds_zero_and_upward_fail():
    env = envs.make(PEG, max_episode_steps=80)
    for seed in (0, 1, 2):
        obs, reward, terminated, truncated, info = run_episode(env, insertion_policy, seed)
        assert terminated and not truncated and info["is_success"], (seed, info)
        assert info["depth"] >= env.success_depth and info["lateral"] < env.clearance
    inserted = reward
    # Off by the hole's noise, the zero action stays above the block; upward moves away.
    short = envs.make(PEG, max_episode_steps=30)
    zero = lambda env, obs: np.zeros(12, dtype=np.float32)  # noqa: E731
    up = lambda env, obs: -insertion_policy(env, obs, speed=-0.3)  # noqa: E731
    for policy in (zero, up):
        obs, reward, terminated, truncated, info = run_episode(short, policy, 0)
        assert not terminated and truncated and not info["is_success"]
        assert info["depth"] < 0
    # The reward is larger (less negative) once inserted than at the start.
    start = env.reset(seed=0)[1]
    assert -start["distance"] - start["lateral"] < inserted
