"""make_vector(id, n): n environments stepped in one call, their simulations and C++ control loops
advanced together on threads (sim.BatchRunner, GIL released), with Gymnasium's vector API."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

import cartesian_impedance as ci

from . import spaces
from .base import CartesianImpedanceEnv
from .registration import make

__all__ = ["VectorEnv", "make_vector", "AUTORESET_MODE"]

_VectorEnvBase: Any
AUTORESET_MODE: Any
try:  # gymnasium.vector's wrappers need a gymnasium.vector.VectorEnv
    import gymnasium.vector as _gymnasium_vector
    _VectorEnvBase = _gymnasium_vector.VectorEnv
    # Gymnasium >= 1.1 names the mode with an enum; 1.0 had only this behaviour.
    AUTORESET_MODE = getattr(getattr(_gymnasium_vector, "AutoresetMode", None), "NEXT_STEP",
                             "NextStep")
except ImportError:
    _VectorEnvBase = object
    AUTORESET_MODE = "NextStep"


def _batch_box(box, n):
    """The Box of n stacked samples of `box` (gymnasium.vector.utils.batch_space for a Box)."""
    return spaces.Box(np.stack([box.low] * n), np.stack([box.high] * n), dtype=box.dtype)


def _is_int(value):
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _count(value, name, least, note=""):
    """`value` as an int >= least: TypeError for anything but an int (int() would make 2.9
    environments 2 and accept '2'), cartesian_impedance.Error below `least`."""
    if not _is_int(value):
        raise TypeError("%s = %r must be an int, got %s" % (name, value, type(value).__name__))
    if value < least:
        raise ci.Error("%s = %d must be >= %d%s" % (name, value, least, note))
    return int(value)


def _seeds(seed, n, name):
    """Per-environment seeds from None, an int (seed, seed + 1, ...) or a sequence of n (ints
    >= 0 or None), checked here so that a bad one fails before any environment is reset."""
    if seed is None:
        return [None] * n
    if _is_int(seed):
        seeds = [int(seed) + i for i in range(n)]
    else:
        if isinstance(seed, (str, bytes, float)) or not hasattr(seed, "__iter__"):
            raise TypeError("%s = %r must be an int, a sequence of %d ints or None" %
                            (name, seed, n))
        seeds = list(seed)
        if len(seeds) != n:
            raise ci.Error("%s has %d seeds, expected %d (one per environment) or one int" %
                           (name, len(seeds), n))
    for i, value in enumerate(seeds):
        if value is not None and not _is_int(value):
            raise TypeError("%s[%d] = %r must be an int or None" % (name, i, value))
        if value is not None and value < 0:
            # SeedSequence takes no negative entropy.
            raise ci.Error("%s[%d] = %d must be >= 0" % (name, i, value))
    return [None if value is None else int(value) for value in seeds]


class VectorEnv(_VectorEnvBase):
    """n environments of one id and options, with the API of gymnasium.vector.VectorEnv:
    num_envs; single_action_space and single_observation_space (one environment's Box);
    action_space and observation_space (Box of shape (num_envs, ...)); reset(seed=None,
    options=None) -> (observations (num_envs, size) float32, infos); step(actions (num_envs,
    action size)) -> (observations, rewards float64, terminations bool, truncations bool, infos)
    (each of num_envs rows); close(); envs (the environments).

    infos is a dict as Gymnasium's vector environments make it: for each key of an environment's
    info, an array of num_envs values, and under "_key" a bool mask of the environments that set
    it.

    Autoreset: next step (Gymnasium 1.x's default, metadata["autoreset_mode"]). When environment
    i ends (terminated or truncated), the step that reports it returns its last observation; the
    NEXT step resets it (its action is ignored) and returns the reset observation, reward 0,
    terminated and truncated False and the reset's info. The reset takes no seed: it continues
    the environment's generator, as env.reset() after an episode does.

    One step: each environment's action is checked (a bad one raises cartesian_impedance.Error
    naming the environment, e.g. 'env 2: action has shape ...', and then nothing has changed)
    and sent to its control loop (C++, PolicyInterface); the simulations and loops of all
    stepping environments run one policy period together on `threads` C++ threads with the GIL
    released (sim.BatchRunner); then each observation (C++) and reward (Python) is computed.
    Each environment ends bit for bit where a separate environment with the same seed and actions would. A task
    that overrides advance() is advanced by its own advance(), one environment after another
    (Wipe does not: the simulation itself averages its contact force over every millisecond,
    Simulation.track_contact_wrench).
    """

    metadata = {"autoreset_mode": AUTORESET_MODE, "render_modes": ["rgb_array"]}

    def __init__(self, envs, seeds=None, threads=0, spin=0.002):
        envs = list(envs)
        if not envs:
            raise ci.Error("num_envs = 0: a vector environment needs at least one environment")
        self.threads = _count(threads, "threads", 0, " (0 = one per core)")
        if isinstance(spin, bool) or not isinstance(spin, (int, float, np.integer, np.floating)):
            raise TypeError("spin = %r must be a number of seconds" % (spin,))
        self.spin = float(spin)
        if not 0.0 <= self.spin <= 1.0:
            raise ci.Error("spin = %r s is outside [0, 1] s" % (spin,))
        self.envs = envs
        self.num_envs = len(envs)
        first = envs[0]
        for i, env in enumerate(envs):
            if env.action_space.shape != first.action_space.shape or \
                    env.observation_space.shape != first.observation_space.shape:
                raise ci.Error("env %d: action/observation shapes %s/%s differ from env 0's "
                               "%s/%s" % (i, env.action_space.shape,
                                          env.observation_space.shape, first.action_space.shape,
                                          first.observation_space.shape))
        self.single_action_space = first.action_space
        self.single_observation_space = first.observation_space
        self.action_space = _batch_box(first.action_space, self.num_envs)
        self.observation_space = _batch_box(first.observation_space, self.num_envs)
        self.metadata = dict(self.metadata, render_fps=first.metadata.get("render_fps"))
        self.render_mode = first.render_mode
        self.spec = getattr(first, "spec", None)
        self.closed = False
        self._first_seeds = None if seeds is None else _seeds(seeds, self.num_envs, "seeds")
        self._autoreset = np.zeros(self.num_envs, dtype=np.bool_)
        self._started = False
        # Environments whose advance() is the base class's (one sim.run): these run batched.
        self._batched = [i for i, env in enumerate(envs)
                         if type(env).advance is CartesianImpedanceEnv.advance]
        self._runner = None
        self._runner_loops = ()
        self._runner_process = None

    @property
    def unwrapped(self):
        return self

    def reset(self, *, seed=None, options=None):
        """Resets every environment: seed None (the seeds given to make_vector on the first
        reset, else each generator goes on), an int (environment i gets seed + i, as
        Gymnasium's vector environments do) or a sequence of num_envs ints or None."""
        if seed is None and self._first_seeds is not None:
            seeds = self._first_seeds
        else:
            seeds = _seeds(seed, self.num_envs, "seed")
        self._first_seeds = None
        observations, infos = [], {}
        for i, (env, env_seed) in enumerate(zip(self.envs, seeds)):
            observation, info = env.reset(seed=env_seed, options=options)
            observations.append(observation)
            self._add_info(infos, info, i)
        self._autoreset[:] = False
        self._started = True
        return np.stack(observations), infos

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if not hasattr(actions, "__len__") or isinstance(actions, (str, bytes)):
            raise TypeError("actions = %r must be an array of num_envs = %d rows" %
                            (actions, self.num_envs))
        if len(actions) != self.num_envs:
            raise ci.Error("actions has %d rows, expected num_envs = %d (one per environment)" %
                           (len(actions), self.num_envs))
        # Every action is checked before any is sent: a bad one changes nothing.
        checked = []
        for i, env in enumerate(self.envs):
            try:
                checked.append(env.actions.check(actions[i]))
            except (ci.Error, TypeError) as error:
                raise type(error)("env %d: %s" % (i, error)) from None
        n = self.num_envs
        observations = [None] * n
        rewards = np.zeros(n, dtype=np.float64)
        terminations = np.zeros(n, dtype=np.bool_)
        truncations = np.zeros(n, dtype=np.bool_)
        infos = {}
        stepping = []
        for i, env in enumerate(self.envs):
            if self._autoreset[i]:
                observations[i], info = env.reset()
                self._add_info(infos, info, i)
            else:
                # Checking the clipped action again gives it back unchanged.
                env.apply_action(checked[i])
                stepping.append(i)
        self._advance(stepping)
        for i in stepping:
            (observations[i], rewards[i], terminations[i], truncations[i],
             info) = self.envs[i].finish_step()
            self._add_info(infos, info, i)
        self._autoreset = terminations | truncations
        return np.stack(observations), rewards, terminations, truncations, infos

    def _advance(self, stepping):
        batchable = set(self._batched)
        batched = [i for i in stepping if i in batchable]
        for i in stepping:
            if i not in batchable:
                self.envs[i].advance()
        if not batched:
            return
        sims = [self.envs[i].sim for i in batched]
        loops = [self.envs[i].loop for i in batched]
        period = self.envs[batched[0]].period
        if len(batched) < len(self._batched):
            # Some are being reset this step: a one-off batch of the others.
            ci.sim.run_many(sims, loops, period, self.threads)
            return
        # reset() makes a new loop, so the kept runner (its threads) is renewed after resets;
        # and in a process forked from the one that made it: fork copies no thread, the runner's
        # pool stayed in the parent (a step there waited for it forever).
        if self._runner is None or self._runner_process != os.getpid() or \
                any(a is not b for a, b in zip(loops, self._runner_loops)):
            self._runner = ci.sim.BatchRunner(sims, loops, self.threads, self.spin)
            self._runner_loops = tuple(loops)
            self._runner_process = os.getpid()
        self._runner.run(period)

    def _add_info(self, infos, info, i):
        """Adds environment i's info to the vector infos as Gymnasium's vector environments do
        (an array per key, a bool mask under '_key')."""
        for key, value in info.items():
            if isinstance(value, dict):
                infos[key] = self._add_info(infos.get(key, {}), value, i)
                infos.setdefault("_" + key, np.zeros(self.num_envs, dtype=np.bool_))[i] = True
                continue
            if key not in infos:
                if type(value) in (int, float, bool) or isinstance(value, np.number):
                    infos[key] = np.zeros(self.num_envs, dtype=type(value))
                elif isinstance(value, np.ndarray):
                    infos[key] = np.zeros((self.num_envs,) + value.shape, dtype=value.dtype)
                else:
                    infos[key] = np.full(self.num_envs, None, dtype=object)
                infos["_" + key] = np.zeros(self.num_envs, dtype=np.bool_)
            infos[key][i] = value
            infos["_" + key][i] = True
        return infos

    def render(self):
        """Each environment's render() (tuple of num_envs frames), as SyncVectorEnv's."""
        return tuple(env.render() for env in self.envs)

    def close(self, **kwargs):
        if self.closed:
            return
        for env in self.envs:
            env.close()
        self._runner = None
        self._runner_loops = ()
        self.closed = True

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001  (interpreter shutdown)
            pass

    def __repr__(self):
        return "VectorEnv(%s, num_envs=%d)" % (getattr(self.spec, "id", "?"), self.num_envs)


def make_vector(env_id, n, seeds=None, threads=0, spin=0.002, **options):
    """A VectorEnv of `n` environments make(env_id, **options) (see make()). seeds: what the
    first reset() without a seed uses (an int: env i gets seeds + i; or a sequence of n ints);
    threads: C++ threads that run the simulations (0 = one per core, at most one per
    environment); spin [s]: how long those threads look for the next step before they sleep
    (sim.BatchRunner; 0 uses no CPU between steps, for processes that share their cores, at the
    cost of a thread wake-up per step). Raises cartesian_impedance.Error for an unknown id, n < 1
    or a wrong number of seeds, TypeError for an n, threads or seed that is not an int."""
    n = _count(n, "n", 1, " (environments)")
    # Checked before n environments are built.
    _seeds(seeds, n, "seeds")
    _count(threads, "threads", 0, " (0 = one per core)")
    return VectorEnv([make(env_id, **options) for _ in range(n)], seeds, threads, spin)
