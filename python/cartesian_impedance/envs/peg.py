"""PegInsertion: a square peg held at the flange, into a square hole drawn at reset."""

from __future__ import annotations

import dataclasses

import numpy as np

import cartesian_impedance as ci

from . import spaces
from .actions import matrix_to_quaternion, quaternion_to_matrix
from .base import CartesianImpedanceEnv, _number
from .robots import robot_spec

__all__ = ["PegInsertion"]


class PegInsertion(CartesianImpedanceEnv):
    """Insert a square peg held at the flange into a square hole in a block.

    Scene (ci.sim.make_peg_in_hole_scene): a peg 2 peg_half_width [m] square, peg_length [m]
    long and peg_mass [kg] along the flange's z axis; a hole `clearance` [m] wider than the peg
    (at most 1 mm), `depth` [m] deep, its sides along the flange's x and y at the start, its
    opening `gap` [m] below the peg's tip at the start (nominal start_q).
    The controlled frame is the peg's tip (the robot's `tool` offset is (0, 0, peg_length) in
    the flange frame): the reference, the observed pose and the stiffness refer to the tip, and
    the peg is declared to the controller (payload.mass = peg_mass, centre of mass peg_length / 2
    behind the tip).
    Randomised at reset: the start (start_noise [rad] per joint), the hole's position: the
    nominal one plus an offset drawn uniformly from +-hole_noise [m] in x and y (base frame).
    The scene is rebuilt at each reset with the hole there (0.07 s; python/README.md).
    Goal (observation's task part, 7): the pose the tip must have at the centre of the hole's
    opening to go in: position [m] and orientation (quaternion x, y, z, w; the tip's z axis into
    the hole), base frame. With goal_noise [m] > 0 the observed position is off from the true one
    by an offset drawn uniformly from +-goal_noise in x and y at reset (an imperfect perception
    of the hole, which a policy must search for); info['hole'] holds the true position.
    Reward: -(distance from the tip to the centre of the hole's floor) - (the tip's distance from
    the hole's axis) [m], every step. Success (info['is_success'], and terminated): the tip is at
    least success_depth [m] below the opening (info: 'depth', 'lateral', 'distance').
    Default episode: 100 steps (5 s at 20 Hz); start_noise 0.005 rad."""

    goal_size = 7
    default_max_episode_steps = 100
    default_start_noise = 0.005

    def __init__(self, robot="panda", peg_half_width=0.0125, peg_length=0.1, peg_mass=0.2,
                 clearance=0.001, depth=0.03, gap=0.03, hole_noise=0.004, goal_noise=0.0,
                 success_depth=0.02, **options):
        # float() would take '0.01' and a bool; each is named as the mistake it is.
        self.peg_half_width = _number("peg_half_width", peg_half_width, "m")
        self.peg_length = _number("peg_length", peg_length, "m")
        self.peg_mass = _number("peg_mass", peg_mass, "kg")
        self.clearance = _number("clearance", clearance, "m")
        self.depth = _number("depth", depth, "m")
        self.gap = _number("gap", gap, "m")
        self.hole_noise = _number("hole_noise", hole_noise, "m")
        self.goal_noise = _number("goal_noise", goal_noise, "m")
        self.success_depth = _number("success_depth", success_depth, "m")
        checks = [("peg_half_width", self.peg_half_width, self.peg_half_width > 0, "> 0"),
                  ("peg_length", self.peg_length, self.peg_length > 0, "> 0"),
                  ("peg_mass", self.peg_mass, self.peg_mass > 0, "> 0"),
                  ("clearance", self.clearance, 0 < self.clearance <= 0.001,
                   "in (0, 0.001] m"),
                  ("depth", self.depth, self.depth > 0, "> 0"),
                  ("gap", self.gap, self.gap >= 0, ">= 0"),
                  ("hole_noise", self.hole_noise, self.hole_noise >= 0, ">= 0"),
                  ("goal_noise", self.goal_noise, self.goal_noise >= 0, ">= 0"),
                  ("success_depth", self.success_depth, 0 < self.success_depth <= self.depth,
                   "in (0, depth = %g]" % self.depth)]
        for name, value, ok, bound in checks:
            if not (ok and np.isfinite(value)):
                raise ci.Error("%s = %r must be %s" % (name, value, bound))
        spec = dataclasses.replace(robot_spec(robot),
                                   tool=((0.0, 0.0, self.peg_length), (0.0, 0.0, 0.0, 1.0)))
        parameters = {"payload.mass": self.peg_mass,
                      "payload.center_of_mass": [0.0, 0.0, -self.peg_length / 2]}
        parameters.update(dict(options.pop("parameters", None) or {}))
        self.hole_offset = np.zeros(2)
        self.goal_error = np.zeros(2)
        super().__init__(robot=spec, parameters=parameters, **options)

    # ---- the scene ----

    def hole(self, offset=(0.0, 0.0)):
        """The SquareHole with its opening `gap` below the nominal start tip, moved by `offset`
        (x, y) [m] in the base frame."""
        tip = self.start_pose.matrix()
        # The opening's z axis points out of the hole, against the tip's; x and y stay along the
        # peg's sides.
        opening = tip @ np.diag([1.0, -1.0, -1.0, 1.0])
        opening[:3, 3] = tip[:3, 3] + tip[:3, 2] * self.gap + [offset[0], offset[1], 0.0]
        return ci.sim.SquareHole(opening, peg_half_width=self.peg_half_width,
                                 clearance=self.clearance, depth=self.depth)

    def _scene(self, offset):
        extra: dict = {} if self.plant is None else dict(plant=self.plant)
        return ci.sim.make_peg_in_hole_scene(
            self.robot.urdf, self.robot.tip_link, self.hole(offset), peg_length=self.peg_length,
            peg_mass=self.peg_mass, start_q=list(self.start_q), engine=self.engine, **extra)

    def build_simulation(self, plain):
        return self._scene(self.hole_offset)

    # ---- the episode ----

    def reset(self, *, seed=None, options=None):
        # The hole is drawn before the robot is reset: the scene is rebuilt around it.
        if seed is not None:
            self._np_random, self._np_random_seed = spaces.np_random(seed)
        rng = self.np_random
        self.hole_offset = rng.uniform(-self.hole_noise, self.hole_noise, 2)
        self.goal_error = rng.uniform(-self.goal_noise, self.goal_noise, 2)
        if self.plant_mode != "randomized":  # else the base draws the plant and builds the scene
            self.sim = self._scene(self.hole_offset)
        return super().reset(seed=None, options=options)

    def reset_task(self, rng):
        opening = self.hole(self.hole_offset).opening
        self.hole_position = np.asarray(opening.position, dtype=float)
        self.hole_axis = -quaternion_to_matrix(opening.orientation)[:, 2]  # into the hole
        self.hole_bottom = self.hole_position + self.depth * self.hole_axis
        tip_orientation = matrix_to_quaternion(quaternion_to_matrix(self.start_pose.orientation))
        observed = self.hole_position + np.array([*self.goal_error, 0.0])
        return np.concatenate([observed, tip_orientation])

    def evaluate(self):
        tip = np.asarray(self.flange_pose.position, dtype=float)
        along = tip - self.hole_position
        depth = float(along @ self.hole_axis)
        lateral = float(np.linalg.norm(along - depth * self.hole_axis))
        distance = float(np.linalg.norm(tip - self.hole_bottom))
        success = depth >= self.success_depth
        return -distance - lateral, success, {
            "is_success": success, "depth": depth, "lateral": lateral, "distance": distance,
            "hole": self.hole_position.copy()}
