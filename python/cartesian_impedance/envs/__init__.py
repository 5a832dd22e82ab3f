"""Gymnasium-API environments on the library's Cartesian impedance controller (pure Python on
the bindings; python/README.md, "Environments").

    import cartesian_impedance.envs as envs
    env = envs.make("CartesianImpedance/Reach-v0", robot="panda", engine="mujoco")
    observation, info = env.reset(seed=0)
    observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

Gymnasium is optional: where it is importable, the spaces are gymnasium.spaces.Box, the
environments are gymnasium.Env and the ids are registered (gymnasium.make works).
"""

from .spaces import Box, GYMNASIUM_AVAILABLE
from .actions import ActionInterface, ActionLimits, observe_robot, robot_observation_size
from .robots import RobotSpec, SHIPPED_ROBOTS, robot_spec
from .base import CartesianImpedanceEnv
from .tasks import Reach, Wipe
from .peg import PegInsertion
from .registration import EnvSpec, ids, make, register
from .robot_interface import RobotActionInterface
from .vector import VectorEnv, make_vector

register()

__all__ = ["Box", "GYMNASIUM_AVAILABLE", "ActionInterface", "ActionLimits", "observe_robot",
           "robot_observation_size", "RobotSpec", "SHIPPED_ROBOTS", "robot_spec",
           "CartesianImpedanceEnv", "Reach", "Wipe", "PegInsertion", "EnvSpec", "ids", "make", "register",
           "RobotActionInterface"]
__all__ += ["VectorEnv", "make_vector"]
