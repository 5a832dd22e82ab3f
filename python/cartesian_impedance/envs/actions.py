"""The action and observation of every environment, apart from the task: what a policy commands
(a pose increment, the Cartesian stiffness, optionally a wrench) and what it sees of the robot.

The same `ActionInterface` serves a simulated environment (CartesianImpedanceEnv) and a
ControlLoop driven by a robot's driver (RobotActionInterface): a policy gets the same numbers and
its actions mean the same commands in both.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Optional

import numpy as np

import cartesian_impedance as ci

from .spaces import Box

__all__ = ["ActionInterface", "ActionLimits", "robot_observation_size", "observe_robot",
           "quaternion_to_matrix", "matrix_to_quaternion", "rotation_vector_to_matrix",
           "matrix_to_rotation_vector"]


# ---- rotations (quaternions x, y, z, w as everywhere in the library) ----

def quaternion_to_matrix(q):
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_to_quaternion(r):
    """Unit quaternion (x, y, z, w) with w >= 0 (one of the two signs, so that an observation
    does not jump between q and -q)."""
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = np.array([(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s,
                      (r[1, 0] - r[0, 1]) / s, 0.25 * s])
    else:
        i = int(np.argmax([r[0, 0], r[1, 1], r[2, 2]]))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + r[i, i] - r[j, j] - r[k, k], 1e-300))
        q = np.zeros(4)
        q[i] = 0.25 * s
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
        q[3] = (r[k, j] - r[j, k]) / s
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def rotation_vector_to_matrix(v):
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.eye(3)
    k = np.asarray(v, dtype=float) / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def matrix_to_rotation_vector(r):
    q = matrix_to_quaternion(r)  # w >= 0: the angle is in [0, pi]
    sin_half = float(np.linalg.norm(q[:3]))
    if sin_half < 1e-12:
        return np.zeros(3)
    return 2.0 * math.atan2(sin_half, q[3]) * q[:3] / sin_half


# ---- the action ----

@dataclasses.dataclass
class ActionLimits:
    """What the normalised action [-1, 1] maps onto (every value documented in python/README.md,
    "Environments").

    max_translation_step [m] and max_rotation_step [rad]: the reference pose moves by at most
    this per policy step (action * maximum; at 20 Hz the defaults are 0.2 m/s and 1 rad/s, below
    the shipped speed caps). stiffness_translation (low, high) [N/m] and stiffness_rotation
    (low, high) [Nm/rad]: -1 is low, +1 high, linear in between; high is lowered to the
    parameters' limits.stiffness.*.max. max_force [N], max_torque [Nm]: the commanded wrench per
    axis (only with wrench=True), lowered to limits.wrench.*. reference_leash (translation [m],
    rotation [rad]): the reference stays within this of the measured pose, so that a policy
    pushing against a table does not wind the reference up (None: the parameters'
    limits.pose_error)."""
    max_translation_step: float = 0.01
    max_rotation_step: float = 0.05
    stiffness_translation: tuple = (100.0, 2000.0)
    stiffness_rotation: tuple = (5.0, 150.0)
    max_force: float = 30.0
    max_torque: float = 3.0
    reference_leash: Optional[tuple] = None

    def __post_init__(self):
        # The values themselves are checked by PolicyInterface; a value of the wrong type would
        # get only pybind11's "incompatible constructor arguments" there, naming no field.
        for name in ("max_translation_step", "max_rotation_step", "max_force", "max_torque"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                                 np.floating)):
                raise TypeError("action limits: %s = %r must be a number, got %s" % (
                    name, value, type(value).__name__))


class ActionInterface:
    """Turns normalised actions into commands of a ControlLoop and robot states into the robot
    part of an observation.

    Action (float32, each in [-1, 1]; values outside are clipped, NaN or a wrong shape raise
    cartesian_impedance.Error naming the element and change nothing):
      [0:3]   translation increment of the reference, base frame: a * max_translation_step [m]
      [3:6]   rotation increment (rotation vector, base frame): a * max_rotation_step [rad]
      [6:9]   translational stiffness x, y, z (base frame): low + (a + 1) / 2 (high - low) [N/m]
      [9:12]  rotational stiffness about x, y, z: likewise [Nm/rad]
      [12:18] with wrench=True: commanded force a * max_force [N], torque a * max_torque [Nm],
              base frame, on the environment
    """

    def __init__(self, model, parameters, wrench=False, limits: Optional[ActionLimits] = None):
        self.limits = limits or ActionLimits()
        self.wrench = bool(wrench)
        k = self.limits
        # The C++ PolicyInterface does the work (the same class a C++ program uses on a robot):
        # a few microseconds per action and observation instead of NumPy's hundred.
        self.core = ci.PolicyInterface(
            model, parameters, self.wrench, max_translation_step=k.max_translation_step,
            max_rotation_step=k.max_rotation_step, stiffness_translation=k.stiffness_translation,
            stiffness_rotation=k.stiffness_rotation, max_force=k.max_force,
            max_torque=k.max_torque, reference_leash=k.reference_leash)
        self.stiffness_low = self.core.stiffness_low
        self.stiffness_high = self.core.stiffness_high
        self.max_force = self.core.max_force
        self.max_torque = self.core.max_torque
        self.leash = self.core.leash
        self.size = self.core.action_size
        self.action_space = Box(-1.0, 1.0, shape=(self.size,), dtype=np.float32)

    def check(self, action) -> np.ndarray:
        """The action as float64, clipped to [-1, 1]; raises cartesian_impedance.Error naming
        the field for a wrong shape or a value that is not finite."""
        return self.core.check(action)

    @staticmethod
    def field(i) -> str:
        return ci.PolicyInterface.field(i)

    def layout(self) -> str:
        return self.core.layout()

    def reset(self, loop):
        """Puts the reference at the flange's pose in loop.latest_state() (the start)."""
        self.core.reset(loop)

    def stiffness(self, action) -> np.ndarray:
        """The diagonal stiffness (6,) [N/m x3, Nm/rad x3] the action asks for."""
        return self.core.stiffness(action)

    def stiffness_action(self, stiffness) -> np.ndarray:
        """The inverse: the action values [6:12] that ask for `stiffness` (6,)."""
        return self.core.stiffness_action(stiffness)

    def apply(self, action, loop):
        """Checks `action` (nothing is changed if it is bad), moves the reference (kept within
        the leash of the flange's pose in loop.latest_state()) and sends the reference, the
        stiffness and (with wrench) the wrench to `loop`; returns the checked action."""
        return self.core.apply(action, loop)

    def observe(self, loop, goal=None) -> np.ndarray:
        """The observation (float32): observe_robot's values from loop.latest_state(), then
        `goal`."""
        return self.core.observe(loop, goal)

    @property
    def reference_position(self) -> np.ndarray:
        return self.core.reference.position

    @property
    def reference_rotation(self) -> np.ndarray:
        return quaternion_to_matrix(self.core.reference.orientation)


# ---- the robot's part of the observation ----

def robot_observation_size(num_joints) -> int:
    return 2 * num_joints + 32


def observe_robot(model, state, interface: ActionInterface) -> np.ndarray:
    """The robot part of the observation (float64) from a LoopState:
    q (n) [rad], dq (n) [rad/s], flange position (3) [m] and orientation (quaternion x, y, z, w,
    w >= 0) in the base frame, flange twist J dq (6) [m/s; rad/s], the controller's estimate of
    the external wrench on the flange (6) [N; Nm], the reference position (3) [m] and orientation
    (4), the stiffness in force (diagonal of the filtered K, 6) [N/m; Nm/rad]. `model` is the
    interface's (kept for the signature).

    The external wrench is what the controller's Cartesian torque balances when the arm is at
    rest: F_ext = -(J^T)^+ (tau_cartesian + tau_wrench), base frame. It reads the contact force
    of a table pressed on; while the arm accelerates it includes the inertial force, and the
    joints' friction shows in it."""
    del model
    return interface.core.observe_state(state)
