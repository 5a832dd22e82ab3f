"""cartesian_impedance.envs: the Gymnasium API (spaces, the 5-tuple, seeding, reset after an
episode ends, render), each task's behaviour under a scripted policy and under policies that must
fail, the stiffness in the action reaching the law, bad actions, and the same actions on a
ControlLoop that the runtime's control thread steps from a simulated robot driver."""

import re
import time
import warnings

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import requires_sim

pytestmark = requires_sim

if hasattr(ci, "sim"):
    import cartesian_impedance.envs as envs

REACH = "CartesianImpedance/Reach-v0"
WIPE = "CartesianImpedance/Wipe-v0"


def robot_part(env, obs):
    """Named slices of the robot part of an observation (python/README.md, Environments)."""
    n = env.model.num_joints
    return {"q": obs[:n], "position": obs[2 * n:2 * n + 3], "wrench": obs[2 * n + 13:2 * n + 19],
            "reference": obs[2 * n + 19:2 * n + 22], "stiffness": obs[2 * n + 26:2 * n + 32]}


def reach_policy(env, obs, sign=1.0):
    """Toward the goal at most at the largest step, stiff; sign -1: away from it."""
    part = robot_part(env, obs)
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    step = env.actions.limits.max_translation_step
    action[0:3] = np.clip(sign * (obs[-3:] - part["position"]) / step, -1, 1)
    action[6:12] = 1.0
    return action


def wipe_policy(env, obs, sign=1.0):
    """Presses with f* (sign -1: pulls up), keeps the reference at the flange's height, and once
    the estimated normal force shows contact moves the reference toward a point 1 cm past the
    goal (friction holds the flange back from its reference)."""
    part = robot_part(env, obs)
    goal = obs[-4:]
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    step = env.actions.limits.max_translation_step
    if part["wrench"][2] > 0.5 * goal[3]:
        target = goal[:2] + 0.01 * env.direction
        action[0:2] = np.clip(0.3 * (target - part["reference"][:2]) / step, -0.5, 0.5)
    action[2] = np.clip((part["position"][2] - part["reference"][2]) / step, -1, 1)
    action[8] = -1.0  # soft along the normal: the commanded force sets the contact force
    action[9:12] = 1.0
    action[14] = -sign * goal[3] / env.actions.max_force
    return action


def run_episode(env, policy, seed, steps=None):
    obs, info = env.reset(seed=seed)
    for _ in range(steps or env.max_episode_steps):
        obs, reward, terminated, truncated, info = env.step(policy(env, obs))
        if terminated or truncated:
            break
    return obs, reward, terminated, truncated, info


# ---- spaces ----

def test_box_follows_gymnasium_box():
    box = envs.spaces._Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
    assert box.shape == (4,) and box.dtype == np.float32
    assert box.low.dtype == np.float32 and np.all(box.low == -1) and np.all(box.high == 1)
    assert box.seed(7) == [7]
    first = [box.sample() for _ in range(3)]
    box.seed(7)
    second = [box.sample() for _ in range(3)]
    assert all(np.array_equal(a, b) for a, b in zip(first, second))
    assert all(s.dtype == np.float32 and box.contains(s) for s in first)
    assert not np.array_equal(first[0], first[1])
    # The generator is the one Gymnasium's seeding makes: PCG64 from SeedSequence(seed).
    reference = np.random.Generator(np.random.PCG64(np.random.SeedSequence(7)))
    np.testing.assert_array_equal(
        first[0], reference.uniform(-1.0, 1.0, size=4).astype(np.float32))
    assert [0.5, 0, 0, 0] in box and box.contains(np.zeros(4, dtype=np.float32))
    assert not box.contains(np.zeros(3)) and not box.contains([2.0, 0, 0, 0])
    assert not box.contains([np.nan, 0, 0, 0]) and not box.contains("text")
    assert not box.contains(np.zeros(4, dtype=np.float64))  # float64 does not cast to float32
    unbounded = envs.spaces._Box(-np.inf, np.inf, shape=(2,), dtype=np.float64, seed=1)
    assert not unbounded.is_bounded() and np.all(np.isfinite(unbounded.sample()))
    with pytest.raises(ValueError, match="low > high"):
        envs.spaces._Box([1.0], [0.0])


# ---- the Gymnasium API ----

def test_ids_and_make():
    assert envs.ids() == ["CartesianImpedance/PegInsertion-v0", REACH, WIPE]
    with pytest.raises(ci.Error, match="'CartesianImpedance/Fly-v0' is not one of"):
        envs.make("CartesianImpedance/Fly-v0")
    with pytest.raises(ci.Error, match="robot = 'r2d2' is not a shipped robot"):
        envs.make(REACH, robot="r2d2")


@pytest.mark.parametrize("env_id, action_size, goal_size", [(REACH, 12, 3), (WIPE, 18, 4)])
def test_api_spaces_and_the_five_tuple(env_id, action_size, goal_size):
    env = envs.make(env_id, max_episode_steps=3)
    assert env.spec.id == env_id and env.spec.max_episode_steps == 3
    assert env.metadata["render_modes"] == ["rgb_array"] and env.metadata["render_fps"] == 20
    assert env.action_space.shape == (action_size,) and env.action_space.dtype == np.float32
    assert np.all(env.action_space.low == -1) and np.all(env.action_space.high == 1)
    assert env.observation_space.shape == (2 * 7 + 32 + goal_size,)
    assert env.observation_space.dtype == np.float32
    obs, info = env.reset(seed=0)
    assert isinstance(obs, np.ndarray) and obs.dtype == np.float32
    assert env.observation_space.contains(obs) and isinstance(info, dict)
    assert info["is_success"] is False and info["status"] == "ok"
    env.action_space.seed(0)
    for k in range(3):
        result = env.step(env.action_space.sample())
        assert isinstance(result, tuple) and len(result) == 5
        obs, reward, terminated, truncated, info = result
        assert env.observation_space.contains(obs)
        assert type(reward) is float and np.isfinite(reward)
        assert type(terminated) is bool and type(truncated) is bool and isinstance(info, dict)
        assert truncated == (k == 2)
    # The policy rate: 20 Hz, so 3 steps are 0.15 s of the simulation's 1 kHz.
    assert env.sim.time == pytest.approx(0.001 + 3 * 0.05)
    env.close()


@pytest.mark.parametrize("env_id", [REACH, WIPE])
def test_same_seed_same_episode_other_seed_another(env_id):
    env = envs.make(env_id, max_episode_steps=8)

    def episode(seed):
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        observations, rewards = [obs], []
        truncated = False
        while not truncated:
            obs, reward, _, truncated, _ = env.step(env.action_space.sample())
            observations.append(obs)
            rewards.append(reward)
        return np.array(observations), np.array(rewards)

    first = episode(1)
    other = episode(2)  # between the two: the environment has run another episode
    again = episode(1)
    np.testing.assert_array_equal(first[0], again[0])
    np.testing.assert_array_equal(first[1], again[1])
    assert not np.array_equal(first[0][0], other[0][0])  # start and goal are randomised
    assert not np.array_equal(first[1], other[1])
    env.reset(seed=5)
    assert isinstance(env.np_random, np.random.Generator) and env.np_random_seed == 5


def test_reset_after_termination_and_truncation():
    env = envs.make(REACH, max_episode_steps=60)
    obs, reward, terminated, truncated, info = run_episode(env, reach_policy, seed=3)
    assert terminated and info["is_success"] and not truncated
    obs, info = env.reset(seed=4)  # after termination
    assert env.observation_space.contains(obs) and env.steps == 0
    obs, reward, terminated, truncated, info = run_episode(env, reach_policy, seed=4, steps=60)
    assert terminated
    short = envs.make(REACH, max_episode_steps=2)
    short.reset(seed=0)
    zero = np.zeros(12, dtype=np.float32)
    assert short.step(zero)[3] is False and short.step(zero)[3] is True
    obs, _ = short.reset()  # after truncation, unseeded: continues the generator
    assert short.step(zero)[3] is False and short.observation_space.contains(obs)


def test_render_rgb_array():
    available, reason = ci.sim.offscreen_rendering_available()
    if not available:
        pytest.skip("offscreen rendering unavailable: " + reason)
    pytest.importorskip("PIL", reason="render() needs Pillow (Debian: python3-pil)")
    env = envs.make(REACH, render_mode="rgb_array", render_size=(48, 64))
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8
    assert frame.std() > 0  # a picture, not a blank
    env.close()
    with pytest.warns(UserWarning, match="render_mode"):
        assert envs.make(REACH).render() is None
    with pytest.raises(ci.Error, match="render_mode = 'human'"):
        envs.make(REACH, render_mode="human")


# ---- behaviour ----

def test_reach_scripted_policy_reaches_zero_and_reversed_do_not():
    env = envs.make(REACH, max_episode_steps=40)
    obs, reward, terminated, _, info = run_episode(env, reach_policy, seed=11)
    assert terminated and info["is_success"] and info["distance"] < env.tolerance
    assert reward == pytest.approx(-info["distance"])
    start_distance = env.reset(seed=11)[1]["distance"]
    assert start_distance > 3 * env.tolerance  # the goal is not where the flange starts
    _, _, terminated, truncated, info = run_episode(
        env, lambda e, o: np.zeros(12, dtype=np.float32), seed=11)
    assert not info["is_success"] and truncated
    assert info["distance"] == pytest.approx(start_distance, abs=0.005)
    _, _, terminated, truncated, info = run_episode(
        env, lambda e, o: reach_policy(e, o, sign=-1.0), seed=11)
    assert not info["is_success"] and info["distance"] > start_distance


def test_wipe_scripted_policy_keeps_the_force_in_band():
    env = envs.make(WIPE, max_episode_steps=80)
    obs, reward, terminated, _, info = run_episode(env, wipe_policy, seed=3)
    assert terminated and info["is_success"]
    assert info["in_band_fraction"] >= 0.75 and info["distance"] < 0.02
    assert abs(info["normal_force"] - env.target_force) <= env.band
    # The estimate of the external wrench in the observation reads the same contact force.
    assert robot_part(env, obs)["wrench"][2] == pytest.approx(info["normal_force"], abs=2.0)
    for policy in (lambda e, o: np.zeros(18, dtype=np.float32),
                   lambda e, o: wipe_policy(e, o, sign=-1.0)):
        _, _, terminated, truncated, info = run_episode(env, policy, seed=3, steps=40)
        assert not info["is_success"] and info["normal_force"] == 0.0


def test_stiffness_in_the_action_is_the_stiffness_in_force():
    env = envs.make(REACH, max_episode_steps=100, start_noise=0.0)
    displacement = {}
    for level in (-1.0, 1.0):
        obs, _ = env.reset(seed=0)
        action = np.zeros(12, dtype=np.float32)
        action[6:12] = level
        for _ in range(10):  # 0.5 s: the stiffness filter (95 % in 0.2 s) has passed it on
            obs, *_ = env.step(action)
        expected = env.actions.stiffness(action)
        k = np.diag(env.loop.state.controller.stiffness_base())
        np.testing.assert_allclose(k, expected, rtol=0.01)
        np.testing.assert_allclose(robot_part(env, obs)["stiffness"], expected, rtol=0.01)
        start = robot_part(env, obs)["position"].copy()
        env.sim.push(env.robot.tip_link, [0, 4.0, 0, 0, 0, 0])  # 4 N along y
        for _ in range(30):
            obs, *_ = env.step(action)
        displacement[level] = robot_part(env, obs)["position"][1] - start[1]
    # F / K: 4 N at 100 N/m is 40 mm, at 2000 N/m 2 mm; the joints' friction holds a little.
    assert displacement[-1.0] == pytest.approx(4.0 / 100.0, rel=0.15)
    assert displacement[1.0] == pytest.approx(4.0 / 2000.0, abs=0.001)


def test_bad_actions_raise_naming_the_field_and_change_nothing():
    env = envs.make(REACH)
    env.reset(seed=0)
    before = (env.sim.time, env.loop.state.cycle, env.actions.reference_position.copy())
    bad = np.zeros(12)
    bad[4] = np.nan
    with pytest.raises(ci.Error, match=r"action\[4\] = nan is not finite.*rotation.y"):
        env.step(bad)
    with pytest.raises(ci.Error, match=r"action has shape \(6,\), expected \(12,\)"):
        env.step(np.zeros(6))
    # Values that are not real numbers are a wrong type, named as such: forcecast made a complex
    # action its real part (only a ComplexWarning) and None NaN ('action[0] = nan is not finite').
    for wrong, dtype in [(["left"] * 12, "<U4"), (np.full(12, 0.5 + 0.5j), "complex128"),
                         (np.full(12, 0.5, dtype=np.complex64), "complex64"),
                         (np.array([None] * 12), "object"), ([None] * 12, "object"),
                         (np.ones(12, dtype=bool), "bool")]:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a ComplexWarning would be a silent conversion
            with pytest.raises(TypeError, match=r"^action must be real numbers \(an integer or "
                               r"float dtype\), got .*dtype " + re.escape(dtype) + "$"):
                env.step(wrong)
    with pytest.raises(TypeError, match=r"^action must be real numbers, got None"):
        env.step(None)
    # Any real dtype is converted, as everywhere in the module.
    assert env.actions.check(np.zeros(12, dtype=np.float16)).dtype == np.float64
    assert env.actions.check(np.zeros(12, dtype=np.int8)).dtype == np.float64
    assert (env.sim.time, env.loop.state.cycle) == before[:2]
    np.testing.assert_array_equal(env.actions.reference_position, before[2])
    # The episode goes on as one that never saw them.
    fresh = envs.make(REACH)
    fresh.reset(seed=0)
    action = np.full(12, 0.5, dtype=np.float32)
    np.testing.assert_array_equal(env.step(action)[0], fresh.step(action)[0])


def test_other_robots_and_dart():
    ur5e = envs.make(REACH, robot="ur5e", max_episode_steps=40)
    assert ur5e.observation_space.shape == (2 * 6 + 32 + 3,)
    _, _, terminated, _, info = run_episode(ur5e, reach_policy, seed=2)
    assert terminated and info["is_success"]
    own = envs.make(REACH, max_episode_steps=40, robot={
        "urdf": ci.data_dir() / "models/iiwa14/iiwa14.urdf", "base_link": "iiwa_link_0",
        "tip_link": "iiwa_link_ee"})  # no configuration: the shipped files' safety layer
    assert own.parameters["safety.max_speed.translation"] == 1.0
    _, _, terminated, _, info = run_episode(own, reach_policy, seed=2)
    assert terminated and info["is_success"]
    # A tool frame 0.1 m along the flange's z (a held peg's tip): the pose the policy sees and
    # moves is the tool's.
    tool = envs.make(REACH, start_noise=0.0, robot=dict(
        envs.robot_spec("panda").__dict__, tool=([0, 0, 0.1], [0, 0, 0, 1])))
    flange = envs.make(REACH, start_noise=0.0)
    tip = robot_part(tool, tool.reset(seed=0)[0])["position"]
    origin = robot_part(flange, flange.reset(seed=0)[0])["position"]
    along_z = envs.actions.quaternion_to_matrix(flange.flange_pose.orientation)[:, 2]
    np.testing.assert_allclose(tip, origin + 0.1 * along_z, atol=1e-6)
    available, reason = ci.sim.engine_available("dart")
    if not available:
        pytest.skip("DART: " + reason)
    dart = envs.make(REACH, engine="dart", max_episode_steps=40)
    assert dart.sim.engine == "dart"
    _, _, terminated, _, info = run_episode(dart, reach_policy, seed=2)
    assert terminated and info["is_success"]
    dart = envs.make(WIPE, engine="dart", max_episode_steps=80)
    _, _, terminated, _, info = run_episode(dart, wipe_policy, seed=3)
    assert terminated and info["is_success"]


# ---- the same actions on a loop stepped by a driver ----

def test_robot_action_interface_on_the_control_thread_with_a_simulated_driver():
    # As on a robot: the driver (a simulated Panda stepped in real time, one 1 ms timestep per
    # tick, by its own C++ thread) publishes the joint state; the runtime's control thread steps
    # the loop from it at 1 kHz on absolute deadlines and hands each torque back to the driver.
    # The policy runs at 20 Hz on this thread and sees the loop only through
    # RobotActionInterface (latest_state(), commands).
    data = ci.data_dir()
    model = ci.RobotModel.from_urdf_file(data / "models/panda/panda.urdf", "panda_link0",
                                         "panda_link8")
    parameters = ci.Parameters.load(data / "config/panda.yaml")
    robot = ci.sim.Simulation.from_mjcf_file(data / "models/panda/panda.xml",
                                             joint_names=model.joint_names)
    loop = ci.ControlLoop(model, parameters)
    measurements = ci.runtime.MeasurementBuffer(model.num_joints)
    torques = ci.runtime.TorqueOutbox(model.num_joints)
    with ci.runtime.ControlThread(rate=1000.0) as control, \
            ci.sim.SimulatedDriver(robot, measurements, torques) as driver:
        control.start(loop, measurements, torques)
        driver.start()
        began = time.monotonic()
        give_up = began + 10.0
        while loop.latest_state().cycle == 0 and time.monotonic() < give_up:
            time.sleep(0.001)  # the control thread starts the loop at the first measurement
        assert control.running
        interface = envs.RobotActionInterface(loop, model, parameters)
        interface.reset()
        start = loop.latest_state().controller.pose.position
        goal = start + np.array([0.08, -0.06, -0.05])
        env = envs.make(REACH)  # only for its policy's layout: same action, same observation
        ran = (control.statistics().cycles, driver.state().ticks, driver.state().steps)
        for _ in range(200):  # at most 10 s
            obs = interface.observation(goal)
            assert obs.shape == env.observation_space.shape and obs.dtype == np.float32
            if np.linalg.norm(robot_part(env, obs)["position"] - goal) < 0.02:
                break
            interface.act(reach_policy(env, obs))
            time.sleep(0.05)
        with pytest.raises(ci.Error, match=r"action\[0\] = inf"):
            interface.act(np.array([np.inf] + [0.0] * 11))
    statistics, state = control.statistics(), driver.state()
    assert np.linalg.norm(loop.latest_state().controller.pose.position - goal) < 0.02
    assert loop.latest_state().controller.status == ci.Status.ok
    # Both threads kept running while the policy acted (how many cycles and ticks a second they
    # got depends on the machine's load; the control thread's rate is measured by the C++ benchmark BM_ControlThreadPeriod).
    assert statistics.cycles > ran[0] and state.ticks > ran[1]
    # The arm moved by the driver's steps, under the control thread's torques: it was never
    # braked for want of them, and the loop's cycles match what the driver received.
    assert not state.held and state.torque_timeouts == 0 and state.rejected_torques == 0
    assert state.steps > ran[2]
    assert 0 < state.torque_cycle <= loop.latest_state().cycle


def test_gymnasium_make_where_installed():
    gymnasium = pytest.importorskip("gymnasium", reason="Gymnasium is not installed (Debian 12 "
                                    "has no package); the environments work without it")
    env = gymnasium.make(REACH, max_episode_steps=5)
    obs, info = env.reset(seed=0)
    assert isinstance(env.observation_space, gymnasium.spaces.Box)
    assert env.observation_space.contains(obs)


def test_robot_action_interface_observation_without_a_goal_is_the_robots_part():
    data = ci.data_dir()
    model = ci.RobotModel.from_urdf_file(data / "models/panda/panda.urdf", "panda_link0",
                                         "panda_link8")
    parameters = ci.Parameters.load(data / "config/panda.yaml")
    loop = ci.ControlLoop(model, parameters)
    loop.start([0, -0.785, 0, -2.356, 0, 1.571, 0.785], [0.0] * 7)
    interface = envs.RobotActionInterface(loop, model, parameters)
    interface.reset()
    robot = interface.observation()
    assert robot.shape == (2 * 7 + 32,) and robot.dtype == np.float32
    with_goal = interface.observation([0.4, 0.0, 0.5])
    np.testing.assert_array_equal(with_goal[:-3], robot)
    np.testing.assert_allclose(with_goal[-3:], [0.4, 0.0, 0.5], rtol=1e-7)
    with pytest.raises(ValueError, match=r"goal must have shape \(k,\), got shape \(1, 3\)"):
        interface.observation([[0.4, 0.0, 0.5]])
    with pytest.raises(TypeError, match="model must be a RobotModel, got str"):
        ci.PolicyInterface("panda", parameters)


def test_environment_options_of_a_wrong_type_or_out_of_range_are_named():
    # `max_episode_steps or default` made 0 the default, int() made 2.9 two steps.
    for options, error, message in [
            (dict(max_episode_steps=0), ci.Error, r"max_episode_steps = 0 must be >= 1"),
            (dict(max_episode_steps=2.9), TypeError, r"max_episode_steps = 2.9 must be an int"),
            (dict(policy_rate="20"), TypeError, r"policy_rate = '20' must be a number \[Hz\]"),
            (dict(policy_rate=np.inf), ci.Error, r"policy_rate = inf Hz must be finite and >= 0.1"),
            (dict(start_noise=np.nan), ci.Error, r"start_noise = nan rad must be finite and >= 0"),
            (dict(start_noise=-0.1), ci.Error, r"start_noise = -0.1 rad must be finite and >= 0"),
            (dict(wrench="no"), TypeError, r"wrench = 'no' must be True, False or None"),
            (dict(render_size=(480.5, 640)), TypeError,
             r"render_size\[0\] \(height\) = 480.5 must be an int"),
            (dict(render_size=480), TypeError, r"render_size = 480 must be \(height, width\)")]:
        with pytest.raises(error, match="^" + message):
            envs.make(REACH, **options)
    # Each task's own options: a NaN goal range made NaN goals, band = 0 divided by zero.
    wipe, peg = "CartesianImpedance/Wipe-v0", "CartesianImpedance/PegInsertion-v0"
    for env_id, options, error, message in [
            (REACH, dict(goal_range=np.nan), ci.Error, r"goal_range = nan m must be finite"),
            (REACH, dict(tolerance=0.0), ci.Error, r"tolerance = 0.0 m must be finite and > 0"),
            (wipe, dict(band=0), ci.Error, r"band = 0.0 N must be finite and > 0"),
            (wipe, dict(force_range=(15.0, 8.0)), ci.Error,
             r"force_range\[1\] = 8.0 N must be finite and >= force_range\[0\]"),
            (wipe, dict(force_range=10.0), TypeError, r"force_range = 10.0 must be \(low, high\)"),
            (peg, dict(peg_mass="0.2"), TypeError, r"peg_mass = '0.2' must be a number \[kg\]"),
            (peg, dict(depth=np.inf), ci.Error, r"depth = inf m must be finite")]:
        with pytest.raises(error, match="^" + message):
            envs.make(env_id, **options)
    # A policy faster than the simulation never advanced it (Simulation.run rounds to whole
    # steps); one slower than 0.1 Hz ran the 1 kHz loop for minutes per step.
    for options, error, message in [
            (dict(policy_rate=5000.0), ci.Error,
             r"policy_rate = 5000 Hz is faster than the simulation's 1000 Hz"),
            (dict(policy_rate=0.001), ci.Error,
             r"policy_rate = 0.001 Hz must be finite and >= 0.1"),
            (dict(engine=None), TypeError, r"engine = None must be 'mujoco' or 'dart'"),
            (dict(action_limits={"max_force": 1 + 1j}), TypeError,
             r"action limits: max_force = \(1\+1j\) must be a number, got complex")]:
        with pytest.raises(error, match="^" + message):
            envs.make(REACH, **options)
    assert envs.make(REACH, policy_rate=1000.0).reset(seed=0) is not None


def test_a_realistic_plant_and_one_drawn_anew_each_episode():
    # The scripted reach still succeeds on the realistic arm: the controller keeps the model's
    # rotor inertia, the simulation reads late and noisy.
    env = envs.make(REACH, max_episode_steps=40, plant="realistic")
    _, _, terminated, _, info = run_episode(env, reach_policy, seed=11)
    assert terminated and info["is_success"]
    assert not np.array_equal(env.sim.dq, env.sim.true_dq)
    assert np.array_equal(env.sim.model_armature, [0.1, 0.1, 0.1, 0.1, 0.04, 0.04, 0.04])
    assert not np.array_equal(env.sim.armature, env.sim.model_armature)
    configured = env.loop.latest_parameters()["dynamics.armature"]
    assert np.array_equal(configured, env.sim.model_armature)
    # 'randomized': a plant drawn from the episode's seed: the same seed the same arm, another
    # seed another.
    env = envs.make(REACH, max_episode_steps=5, plant="randomized")
    env.reset(seed=3)
    first = env.sim.armature.copy()
    env.reset(seed=4)
    assert not np.array_equal(env.sim.armature, first)
    env.reset(seed=3)
    assert np.array_equal(env.sim.armature, first)
    with pytest.raises(ci.Error, match="plant = 'noisy' is not one of nominal, realistic, "
                                       "randomized"):
        envs.make(REACH, plant="noisy")
    with pytest.raises(TypeError, match="plant = 5 must be one of"):
        envs.make(REACH, plant=5)


def test_a_vector_of_environments_each_with_its_own_randomized_plant():
    vector = envs.make_vector(REACH, 2, max_episode_steps=3, plant="randomized")
    vector.reset(seed=7)
    first = vector.envs[0].sim.armature.copy()
    assert not np.array_equal(first, vector.envs[1].sim.armature)
    actions = np.zeros((2, vector.envs[0].action_space.shape[0]), dtype=np.float32)
    for _ in range(4):  # past an episode's end: each environment is reset, its arm drawn anew
        vector.step(actions)
    assert not np.array_equal(vector.envs[0].sim.armature, first)
