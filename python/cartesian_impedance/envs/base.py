"""CartesianImpedanceEnv: the Gymnasium-API environment every task derives from.

A task is a small subclass: the boxes of its scene (scene_boxes), its goal and randomisation
(reset_task), the goal's part of the observation (task_observation, goal_size) and its reward
and success (evaluate). Everything else (the robot, the simulation, the control loop at 1 kHz
between policy steps, the action, the robot's observation, seeding, rendering) is here.
"""

from __future__ import annotations

import os
import tempfile
import warnings
from typing import Any

import numpy as np

import cartesian_impedance as ci

from . import spaces
from .actions import ActionInterface, ActionLimits, robot_observation_size
from .robots import make_simulation, robot_spec

__all__ = ["CartesianImpedanceEnv"]

_EnvBase: Any
try:  # gymnasium.make and its wrappers need a gymnasium.Env
    import gymnasium as _gymnasium_module
    _EnvBase = _gymnasium_module.Env
except ImportError:
    _EnvBase = object


#: The slowest policy: a step of 10 s, 10,000 cycles of the 1 kHz loop.
MIN_POLICY_RATE = 0.1


def _integer(name, value, least):
    """An option that counts: an int >= least (int() would turn 2.9 into 2 and accept '2')."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError("%s = %r must be an int, got %s" % (name, value, type(value).__name__))
    if value < least:
        raise ci.Error("%s = %d must be >= %d" % (name, value, least))
    return int(value)


def _number(name, value, unit, ok=lambda v: True, bound=None):
    """An option that is one real number, finite and within `bound` (a task's options too)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError("%s = %r must be a number [%s], got %s" % (name, value, unit,
                                                                  type(value).__name__))
    value = float(value)
    if not (np.isfinite(value) and ok(value)):
        raise ci.Error("%s = %r %s must be finite%s" % (name, value, unit,
                                                         " and " + bound if bound else ""))
    return value


def _render_size(size):
    try:
        height, width = size
    except (TypeError, ValueError):
        raise TypeError("render_size = %r must be (height, width) [px]" % (size,)) from None
    return (_integer("render_size[0] (height)", height, 1),
            _integer("render_size[1] (width)", width, 1))


PLANTS = ("nominal", "realistic", "randomized")


def _plant(plant):
    """The plant option as (mode, Plant or None): a name of PLANTS or a ci.sim.Plant."""
    if plant is None:
        return "nominal", None
    if isinstance(plant, ci.sim.Plant):
        return "given", plant
    if not isinstance(plant, str):
        raise TypeError("plant = %r must be one of %s or a cartesian_impedance.sim.Plant" %
                        (plant, ", ".join(PLANTS)))
    if plant not in PLANTS:
        raise ci.Error("plant = '%s' is not one of %s" % (plant, ", ".join(PLANTS)))
    if plant == "nominal":
        return plant, None
    # 'randomized' draws anew at every reset; seed 1 until the first.
    return plant, ci.sim.Plant.realistic(seed=1)


class CartesianImpedanceEnv(_EnvBase):
    """A simulated arm under the library's Cartesian impedance controller, with the Gymnasium
    API: reset(seed=None, options=None) -> (observation, info); step(action) -> (observation,
    reward, terminated, truncated, info); action_space, observation_space (Box); render() -> RGB
    array (H, W, 3) uint8 with render_mode='rgb_array'; close(); metadata; np_random (seeded by
    reset(seed)).

    Each step applies the action (see ActionInterface: a pose increment, the stiffness, with
    wrench=True a wrench), then runs the simulation and the C++ control loop for
    1 / policy_rate seconds at the simulation's 1 kHz with the GIL released (Simulation.run).
    The parameters are the robot's shipped configuration, so the safety layer is on: speed and
    force caps, the energy tank, the workspace box.

    Options: robot ('panda', 'iiwa14', 'ur5e', 'planar3', or a dict urdf/base_link/tip_link
    [/config/mjcf/start_q] for your own URDF), engine ('mujoco' or 'dart'), policy_rate [Hz]
    (default 20; from 0.1 up to the simulation's rate), max_episode_steps (truncated after
    this many steps), wrench (the action includes a commanded wrench), start_noise [rad]
    (each joint's start is drawn from start +- this at reset), action_limits (ActionLimits or
    a dict of its fields), parameters (a dict of parameters set on top of the robot's
    configuration), plant (the simulated arm: 'nominal', the controller's model read at once and
    exactly; 'realistic', ci.sim.Plant.realistic(1): model error, delays and noise; a
    ci.sim.Plant; or 'randomized', a realistic plant drawn anew from the environment's generator
    at every reset, for domain randomisation; the controller keeps the model's rotor inertia),
    render_mode (None or 'rgb_array'), render_size (height, width) [px]. A
    value of the wrong type raises TypeError, one out of range cartesian_impedance.Error, each
    naming the option and the value.

    Observation: float32, the robot part (observe_robot: q, dq, flange pose and twist, external
    wrench estimate, reference pose, stiffness in force) then the task's goal.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}
    #: Size of the task's part of the observation (after the robot's).
    goal_size = 0
    default_max_episode_steps = 100
    default_wrench = False
    default_start_noise = 0.02

    def __init__(self, robot="panda", engine="mujoco", policy_rate=20.0, max_episode_steps=None,
                 wrench=None, start_noise=None, action_limits=None, parameters=None,
                 render_mode=None, render_size=(480, 640), plant=None):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ci.Error("render_mode = %r is not one of %s" %
                           (render_mode, self.metadata["render_modes"]))
        # Below 0.1 Hz a step would run the 1 kHz loop for over 10 s (policy_rate=0.001 for
        # 1000 was a step of 17 simulated minutes).
        self.policy_rate = _number("policy_rate", policy_rate, "Hz",
                                   lambda v: v >= MIN_POLICY_RATE, ">= %g" % MIN_POLICY_RATE)
        if not isinstance(engine, str):
            raise TypeError("engine = %r must be 'mujoco' or 'dart'" % (engine,))
        self.render_mode = render_mode
        self.render_size = _render_size(render_size)
        self.metadata = dict(self.metadata, render_fps=self.policy_rate)
        # Not `max_episode_steps or default`: 0 would quietly become the default.
        self.max_episode_steps = _integer(
            "max_episode_steps",
            self.default_max_episode_steps if max_episode_steps is None else max_episode_steps, 1)
        self.start_noise = _number(
            "start_noise", self.default_start_noise if start_noise is None else start_noise,
            "rad", lambda v: v >= 0, ">= 0")
        if wrench is not None and not isinstance(wrench, (bool, np.bool_)):
            # bool('no') is True: a flag given as anything else is a mistake to name.
            raise TypeError("wrench = %r must be True, False or None" % (wrench,))
        self.robot = robot_spec(robot)
        self.engine = engine
        self.plant_mode, self.plant = _plant(plant)
        self.model = self.robot.load_model()
        self.parameters = self.robot.load_parameters(self.model)
        if parameters:
            self.parameters.update(dict(parameters))
        # The start configuration, then the scene around it (a task's boxes depend on where the
        # flange starts).
        probe = make_simulation(self.robot, self.model, engine)
        self.start_q = np.array(probe.q)
        self.start_pose = self.model.compute_pose(self.start_q)
        self.sim = self.build_simulation(self._plain_simulation(probe))
        self.parameters["dynamics.armature"] = list(self.sim.model_armature)
        self.parameters.validate(self.model.num_joints)
        self.period = 1.0 / self.policy_rate
        if self.period < 0.5 * self.sim.timestep:
            # Simulation.run rounds to whole timesteps: such a step would not advance at all.
            raise ci.Error("policy_rate = %g Hz is faster than the simulation's %g Hz: a step "
                           "would not advance it" % (self.policy_rate, 1.0 / self.sim.timestep))
        if isinstance(action_limits, dict):
            action_limits = ActionLimits(**action_limits)
        self.actions = ActionInterface(self.model, self.parameters,
                                       self.default_wrench if wrench is None else wrench,
                                       action_limits)
        self.action_space = self.actions.action_space
        size = robot_observation_size(self.model.num_joints) + self.goal_size
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float32)
        self.loop = None
        self.goal = np.zeros(self.goal_size)
        self.steps = 0
        self._np_random = None
        self._np_random_seed = None

    # ---- what a task defines ----

    def scene_boxes(self):
        """The static boxes of the task's scene (list of ci.sim.Box); start_pose is known."""
        return []

    def build_simulation(self, plain):
        """The task's simulation on the current plant (self.plant); `plain` is the robot alone
        on it (at start_q), or None where it was not built. The default adds scene_boxes() to
        it; a task with more than boxes (a peg attached to the flange) builds its own here."""
        boxes = self.scene_boxes()
        if not boxes:
            return plain if plain is not None else self._plain_simulation()
        return make_simulation(self.robot, self.model, self.engine, boxes, plant=self.plant)

    def _plain_simulation(self, nominal=None):
        """The robot alone on the current plant (`nominal`, if given, is the nominal one)."""
        if self.plant is None and nominal is not None:
            return nominal
        return make_simulation(self.robot, self.model, self.engine, plant=self.plant)

    def draw_plant(self, rng):
        """With plant='randomized', draws this episode's plant from rng (a realistic plant of a
        new seed); True if it did, and the simulation must be built anew."""
        if self.plant_mode != "randomized":
            return False
        self.plant = ci.sim.Plant.realistic(seed=int(rng.integers(0, 2**63)))
        return True

    def reset_task(self, rng):
        """Draws the task's goal (and whatever else it randomises) from rng after the robot has
        been reset; returns the goal (goal_size,)."""
        return np.zeros(self.goal_size)

    def task_observation(self):
        """The task's part of the observation (goal_size,)."""
        return self.goal

    def evaluate(self):
        """(reward, terminated, info) after a step; info should hold 'is_success'."""
        return 0.0, False, {"is_success": False}

    def advance(self):
        """Runs the simulation and the control loop for one policy period (a task that samples
        the simulation within the period overrides it)."""
        self.sim.run(self.loop, self.period)

    # ---- Gymnasium API ----

    @property
    def np_random(self) -> np.random.Generator:
        """The environment's generator (reset(seed) seeds it; seeded from fresh entropy when
        used unseeded)."""
        if self._np_random is None:
            self._np_random, self._np_random_seed = spaces.np_random()
        return self._np_random

    @np_random.setter
    def np_random(self, value):
        self._np_random = value
        self._np_random_seed = -1

    @property
    def np_random_seed(self) -> int:
        if self._np_random_seed is None:
            self._np_random, self._np_random_seed = spaces.np_random()
        return self._np_random_seed

    @property
    def unwrapped(self):
        return self

    def reset(self, *, seed=None, options=None):
        if seed is not None:
            self._np_random, self._np_random_seed = spaces.np_random(seed)
        rng = self.np_random
        if self.draw_plant(rng):
            self.sim = self.build_simulation(None)
        self.sim.reset()
        q = self.start_q.copy()
        if self.start_noise > 0:
            limits = self.model.limits
            q = np.clip(q + rng.uniform(-self.start_noise, self.start_noise, q.shape),
                        limits.position_lower, limits.position_upper)
            self.sim.set_state(q, np.zeros_like(q))
        self.loop = ci.ControlLoop(self.model, self.parameters)
        self.loop.start(self.sim.q, self.sim.dq)
        self.sim.run(self.loop, self.sim.timestep)  # one cycle: the state holds the pose
        self.actions.reset(self.loop)
        self.steps = 0
        self.goal = np.asarray(self.reset_task(rng), dtype=float)
        _, _, info = self.evaluate()
        return self._observation(), self._info(info)

    def step(self, action):
        self.apply_action(action)
        self.advance()
        return self.finish_step()

    # step() in its three parts, so that a vector environment (vector.py) can advance many
    # environments' simulations together between the Python parts.

    def apply_action(self, action):
        """Checks `action` and sends it to the control loop (nothing changes if it is bad);
        the first part of step()."""
        if self.loop is None:
            raise RuntimeError("call reset() before step()")
        self.actions.apply(action, self.loop)

    def finish_step(self):
        """After advance(): counts the step, evaluates the task and returns step()'s
        (observation, reward, terminated, truncated, info)."""
        self.steps += 1
        reward, terminated, info = self.evaluate()
        status = self.loop.state.controller.status
        if status != ci.Status.ok:
            # The controller failed closed (a fault it names): the episode cannot go on.
            terminated = True
            info["fault"] = str(self.loop.state.controller.fault)
        truncated = self.steps >= self.max_episode_steps
        return (self._observation(), float(reward), bool(terminated), bool(truncated),
                self._info(info))

    def render(self):
        if self.render_mode is None:
            warnings.warn("render() without a render_mode: make the environment with "
                          "render_mode='rgb_array'", stacklevel=2)
            return None
        try:
            from PIL import Image
        except ImportError:
            raise ImportError("render() reads the offscreen renderer's PNG back with Pillow, "
                              "which is not installed (Debian: python3-pil)") from None
        # A file of its own for each frame, gone when it is read: a folder kept across frames
        # was shared with every process forked from this one (the first to close() removed it
        # under the others), and stayed behind a process that was killed.
        descriptor, path = tempfile.mkstemp(prefix="cartesian_impedance_frame_", suffix=".png")
        os.close(descriptor)
        try:
            height, width = self.render_size
            self.sim.render_png(path, width=width, height=height)
            with Image.open(path) as image:
                return np.array(image.convert("RGB"), dtype=np.uint8)
        finally:
            os.remove(path)

    def close(self):
        """Nothing to release (render() keeps no files); for the Gymnasium API."""

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001  (interpreter shutdown)
            pass

    # ---- helpers for tasks ----

    @property
    def flange_pose(self):
        """The measured flange pose (base frame) the controller saw last."""
        return self.loop.state.controller.pose

    def _observation(self):
        return self.actions.observe(self.loop, self.task_observation())

    def _info(self, info):
        safety = self.loop.state.controller.safety
        info.setdefault("is_success", False)
        info.update(status=str(self.loop.state.controller.status.name),
                    tank_level=float(safety.tank_level),
                    stiffness_change_scale=float(safety.stiffness_change_scale),
                    force_scale=float(safety.force_scale))
        return info
