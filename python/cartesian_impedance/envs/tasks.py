"""The tasks: Reach and Wipe, each a small subclass of CartesianImpedanceEnv."""

from __future__ import annotations

import math

import numpy as np

import cartesian_impedance as ci

from .base import CartesianImpedanceEnv, _number

__all__ = ["Reach", "Wipe"]


class Reach(CartesianImpedanceEnv):
    """Bring the flange to a random goal position.

    Goal: the start flange position plus an offset drawn uniformly from +-goal_range [m] on each
    axis the robot moves along (base frame), kept inside the safety layer's workspace box with a
    5 cm margin. Observation's task part (3): the goal position [m], base frame.
    Reward: -distance from the flange to the goal [m], every step. Success (info['is_success'],
    and terminated when terminate_on_success): the distance is below tolerance [m].
    Default episode: 100 steps (5 s at 20 Hz)."""

    goal_size = 3

    def __init__(self, goal_range=0.15, tolerance=0.02, terminate_on_success=True, **options):
        # Unchecked, a NaN range made NaN goals and observations, a tolerance <= 0 no success.
        self.goal_range = _number("goal_range", goal_range, "m", lambda v: v >= 0, ">= 0")
        self.tolerance = _number("tolerance", tolerance, "m", lambda v: v > 0, "> 0")
        self.terminate_on_success = bool(terminate_on_success)
        super().__init__(**options)

    def reset_task(self, rng):
        axes = np.asarray(self.robot.translation_axes, dtype=float)
        start = np.asarray(self.flange_pose.position)
        goal = start + axes * rng.uniform(-self.goal_range, self.goal_range, 3)
        low = np.asarray(self.parameters["safety.workspace.min"]) + 0.05
        high = np.asarray(self.parameters["safety.workspace.max"]) - 0.05
        return np.where(axes > 0, np.clip(goal, low, high), start)

    def evaluate(self):
        distance = float(np.linalg.norm(np.asarray(self.flange_pose.position) - self.goal))
        success = distance < self.tolerance
        return -distance, success and self.terminate_on_success, {
            "is_success": success, "distance": distance}


class Wipe(CartesianImpedanceEnv):
    """Press on a table with a normal force inside a band while moving the flange along it.

    Scene: a table (a plate 2 (wipe_length + 0.05) m square, 5 cm thick) whose top lies `gap`
    [m] below the flange's start position.
    Randomised at reset: the start (start_noise), the wiping direction (any in the x-y plane; +-x
    for a robot moving in x-z), the target normal force f* from force_range [N].
    Goal: the point wipe_length [m] from the start along the direction, on the table.
    Observation's task part (4): the goal point x, y [m], the table top z [m], f* [N].
    Normal force f: the force the table exerts on the flange's body along +z [N] (the
    simulation's contact force, averaged over the policy step).
    Reward: -(distance from the flange to the goal in x-y) / wipe_length
    - 0.5 min(|f - f*| / band, 2), every step. Success (and terminated): the flange is within
    0.02 m of the goal in x-y and f was within f* +- band [N] in at least 75 % of the steps since
    the first contact (info: 'is_success', 'normal_force', 'in_band_fraction').
    The action includes the wrench by default (wrench=True). Default episode: 200 steps (10 s)."""

    goal_size = 4
    default_max_episode_steps = 200
    default_wrench = True
    default_start_noise = 0.01

    def __init__(self, wipe_length=0.15, gap=0.04, force_range=(8.0, 15.0), band=5.0,
                 **options):
        # Unchecked, band = 0 divided the reward by zero and a NaN made NaN rewards.
        self.wipe_length = _number("wipe_length", wipe_length, "m", lambda v: v > 0, "> 0")
        self.gap = _number("gap", gap, "m", lambda v: v >= 0, ">= 0")
        try:
            low, high = force_range
        except (TypeError, ValueError):
            raise TypeError("force_range = %r must be (low, high) [N]" % (force_range,)) from None
        self.force_range = (_number("force_range[0]", low, "N", lambda v: v > 0, "> 0"),
                            _number("force_range[1]", high, "N", lambda v: v >= low,
                                    ">= force_range[0]"))
        self.band = _number("band", band, "N", lambda v: v > 0, "> 0")
        super().__init__(**options)

    def scene_boxes(self):
        start = np.asarray(self.start_pose.position)
        self.table_top = float(start[2] - self.gap)
        # A plate, not a table standing on the floor: a box down to the floor around the flange
        # would hold the arm's lower links inside it.
        half = self.wipe_length + 0.05
        return [ci.sim.Box([start[0], start[1], self.table_top - 0.025], [half, half, 0.025],
                           name="wipe_table")]

    def build_simulation(self, plain):
        sim = super().build_simulation(plain)
        sim.track_contact_wrench(self.robot.tip_link)  # every millisecond, also in a batch
        return sim

    def reset_task(self, rng):
        start = np.asarray(self.flange_pose.position)
        if self.robot.translation_axes[1]:
            angle = rng.uniform(-math.pi, math.pi)
        else:
            angle = 0.0 if rng.uniform() < 0.5 else math.pi
        self.direction = np.array([math.cos(angle), math.sin(angle)])
        self.target_force = float(rng.uniform(*self.force_range))
        self.contact_steps = 0
        self.in_band_steps = 0
        end = start[:2] + self.wipe_length * self.direction
        return np.array([end[0], end[1], self.table_top, self.target_force])

    def evaluate(self):
        # The mean over the step: MuJoCo's contact force on a sliding flange alternates between
        # 0 and about twice its mean from one millisecond to the next (the flange does not move
        # off the table), so the simulation averages it over every millisecond of the step. At
        # reset the one cycle run is dropped.
        mean = float(self.sim.take_mean_contact_wrench()[2])
        force = mean if self.steps > 0 else 0.0
        self.force = force
        distance = float(np.linalg.norm(np.asarray(self.flange_pose.position)[:2] -
                                        self.goal[:2]))
        in_band = abs(force - self.target_force) <= self.band
        if self.steps > 0 and (self.contact_steps > 0 or force > 0.5):
            self.contact_steps += 1
            self.in_band_steps += int(in_band)
        fraction = self.in_band_steps / self.contact_steps if self.contact_steps else 0.0
        success = distance < 0.02 and fraction >= 0.75
        reward = -distance / self.wipe_length - 0.5 * min(
            abs(force - self.target_force) / self.band, 2.0)
        return reward, success, {"is_success": success, "normal_force": force,
                                 "in_band": in_band, "in_band_fraction": fraction,
                                 "distance": distance}
