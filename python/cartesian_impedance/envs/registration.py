"""Environment ids, make(id, **options), and registration with Gymnasium where it is installed."""

from __future__ import annotations

import dataclasses

import cartesian_impedance as ci

from . import spaces
from .peg import PegInsertion
from .tasks import Reach, Wipe

__all__ = ["EnvSpec", "make", "ids", "register", "ENTRY_POINTS"]

# id -> the class; each id also takes any robot and engine as options.
ENTRY_POINTS = {
    "CartesianImpedance/Reach-v0": Reach,
    "CartesianImpedance/Wipe-v0": Wipe,
    "CartesianImpedance/PegInsertion-v0": PegInsertion,
}


@dataclasses.dataclass
class EnvSpec:
    """What make() made (the fields of gymnasium.envs.registration.EnvSpec that apply)."""
    id: str
    entry_point: str
    kwargs: dict
    max_episode_steps: int


def ids():
    """The environment ids, e.g. 'CartesianImpedance/Reach-v0'."""
    return sorted(ENTRY_POINTS)


def make(env_id, **options):
    """The environment `env_id` (see ids()) made with `options` (robot, engine, policy_rate,
    max_episode_steps, wrench, render_mode, ... and the task's own; see the class's docstring).
    Raises cartesian_impedance.Error for an unknown id."""
    if env_id not in ENTRY_POINTS:
        raise ci.Error("environment id = %r is not one of %s" % (env_id, ", ".join(ids())))
    cls = ENTRY_POINTS[env_id]
    env = cls(**options)
    env.spec = EnvSpec(env_id, "%s:%s" % (cls.__module__, cls.__name__), dict(options),
                       env.max_episode_steps)
    return env


def register():
    """Registers every id with gymnasium.register (so gymnasium.make(id, **options) works);
    does nothing without Gymnasium. Called when cartesian_impedance.envs is imported. Returns
    whether Gymnasium was there."""
    if not spaces.GYMNASIUM_AVAILABLE:
        return False
    import gymnasium
    for env_id, cls in ENTRY_POINTS.items():
        if env_id not in gymnasium.registry:
            # No max_episode_steps here: the environment truncates itself, after its own
            # max_episode_steps option, so gymnasium.make and make() truncate alike.
            gymnasium.register(id=env_id, entry_point="%s:%s" % (cls.__module__, cls.__name__))
    return True
