"""Parameterised skills: a few numbers that a search (rollouts.cem) tunes, run as a policy on an
environment of cartesian_impedance.envs.

InsertionSkill puts a held peg into a hole whose observed position may be off by a few mm, as
the research line on impedance-controlled insertion does it: approach above the observed hole,
descend compliantly, and search the top face with a spiral of the reference around the observed
position while pressing, until the peg drops in; then push it down.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["InsertionSkill", "insertion_rollout"]


@dataclasses.dataclass
class InsertionSkill:
    """The insertion skill's parameters (what cem() tunes, as a vector in this order; see
    `from_vector`):

    approach [m]: the height above the observed opening where the descent slows to `speed`;
    speed: the descent per policy step as a fraction of the action's largest step (0.01 m);
    press [m]: how far below the observed opening the reference is held while searching (the
    force on the top face is about stiffness_z x press);
    radius [m]: the spiral's radius after `turns` turns (0: no search, straight down);
    turns: how many turns the spiral takes to reach `radius` (it grows on at the same pitch);
    period [s]: the time one turn takes;
    stiffness_xy, stiffness_z: translational stiffness across and along the hole's axis, as
    actions in [-1, 1] (ActionLimits.stiffness_translation: 100 to 2000 N/m).

    Used as a policy: `skill(env, observation) -> action`; `skill.reset()` starts an episode.
    The goal part of the observation (the last 7 values: the opening's position, the tip's
    orientation there) is all it reads of the task; the tip position and the reference come
    from the robot's part."""

    approach: float = 0.005
    speed: float = 0.3
    press: float = 0.004
    radius: float = 0.0
    turns: float = 3.0
    period: float = 1.0
    stiffness_xy: float = 0.5
    stiffness_z: float = 0.5

    NAMES = ("approach", "speed", "press", "radius", "turns", "period", "stiffness_xy",
             "stiffness_z")

    def __post_init__(self):
        self.reset()

    @classmethod
    def from_vector(cls, values):
        """The skill from a vector in NAMES' order, clipped to where each parameter means
        something (cem samples a Gaussian). TypeError for values that are not real numbers,
        ValueError for a wrong count or a value that is not finite."""
        array = np.asarray(values)
        if array.dtype.kind not in "fiu":
            # float() would take a complex's real part with only a warning, and None as NaN.
            raise TypeError("InsertionSkill values must be real numbers, got dtype %s: %r" %
                            (array.dtype, values))
        v = [float(x) for x in array.astype(float).reshape(-1)]
        if len(v) != len(cls.NAMES):
            raise ValueError("InsertionSkill takes %d values (%s), got %d" %
                             (len(cls.NAMES), ", ".join(cls.NAMES), len(v)))
        for name, value in zip(cls.NAMES, v):
            # min(max(nan, low), high) is NaN: the clipping below would pass it on to the
            # actions, where the environment rejects it mid-episode.
            if not math.isfinite(value):
                raise ValueError("InsertionSkill %s = %r is not finite" % (name, value))
        return cls(approach=min(max(v[0], 0.0), 0.03), speed=min(max(v[1], 0.02), 1.0),
                   press=min(max(v[2], 0.0), 0.02), radius=min(max(v[3], 0.0), 0.01),
                   turns=min(max(v[4], 0.5), 10.0), period=min(max(v[5], 0.2), 5.0),
                   stiffness_xy=min(max(v[6], -1.0), 1.0),
                   stiffness_z=min(max(v[7], -1.0), 1.0))

    def vector(self):
        return np.array([getattr(self, name) for name in self.NAMES])

    def reset(self):
        self.search_steps = 0  # policy steps since the tip reached the top face
        self.inserted = False

    def __call__(self, env, obs):
        n = env.model.num_joints
        position = np.asarray(obs[2 * n:2 * n + 3], dtype=float)
        reference = np.asarray(obs[2 * n + 19:2 * n + 22], dtype=float)
        goal = np.asarray(obs[-7:-4], dtype=float)
        step = env.actions.limits.max_translation_step
        height = position[2] - goal[2]  # the tip above the observed opening [m]
        if height < -0.0005:
            # Below the top face (on it the tip sits within 0.1 mm of the opening's height): in
            # the hole, whatever the observed position says. The search stops where the tip is.
            self.inserted = True
        target = reference.copy()
        if self.inserted:
            target[:2] = position[:2]
            target[2] = reference[2] - self.speed * step
        elif height > self.approach + 0.002 and self.search_steps == 0:
            target[:2] = goal[:2]  # above the observed hole first
            if np.linalg.norm(goal[:2] - position[:2]) < 0.001:
                target[2] = max(reference[2] - step, goal[2] + self.approach)
        else:
            target[2] = max(reference[2] - self.speed * step, goal[2] - self.press)
            if height < 0.001:
                self.search_steps += 1
            t = self.search_steps / env.policy_rate
            angle = 2.0 * math.pi * t / self.period
            # An Archimedean spiral, `radius` after `turns` turns, growing on after that: the
            # tip, held back by the friction on the top face, circles inside the reference.
            r = self.radius * angle / (2.0 * math.pi * self.turns)
            target[:2] = goal[:2] + r * np.array([math.cos(angle), math.sin(angle)])
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        action[0:3] = np.clip((target - reference) / step, -1.0, 1.0)
        # Stiff on the way (the tip follows the reference closely), the skill's own stiffness
        # from `approach` above the opening on.
        action[6:9] = 1.0
        if height <= self.approach + 0.002 or self.search_steps or self.inserted:
            action[6:8] = self.stiffness_xy
            action[8] = self.stiffness_z
        return action


def insertion_rollout(params, seed, env_options=None, episodes=1):
    """`episodes` episodes of InsertionSkill.from_vector(params) on PegInsertion-v0 (options
    `env_options`, e.g. goal_noise), from reset(seed=s) for the seeds SeedSequence(seed) spawns
    (episodes=1: seed itself): a dict with 'success' (the fraction of episodes that succeeded),
    'return' (the mean summed reward), 'steps' (mean), and 'score' = return + 100 success (what
    cem ranks by: success first, the return, about -0.5 for a quick insertion and -3 for a
    jammed episode, between equals; several episodes make it less of a lottery over the
    hole's draw).
    Deterministic for (params, seed); picklable, for rollouts.Pool."""
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError("episodes = %r must be an int >= 1" % (episodes,))
    from .envs import make  # in the worker process
    env = make("CartesianImpedance/PegInsertion-v0", **(env_options or {}))
    skill = InsertionSkill.from_vector(params)
    seeds = [int(seed)] if episodes == 1 else \
        [int(s) for s in np.random.SeedSequence(int(seed)).generate_state(episodes)]
    successes, returns, steps = [], [], []
    for episode_seed in seeds:
        skill.reset()
        obs, info = env.reset(seed=episode_seed)
        total = 0.0
        terminated = truncated = False
        while not (terminated or truncated):
            obs, reward, terminated, truncated, info = env.step(skill(env, obs))
            total += reward
        successes.append(float(info["is_success"]))
        returns.append(total)
        steps.append(env.steps)
    success = float(np.mean(successes))
    total = float(np.mean(returns))
    return {"success": success, "return": total, "steps": float(np.mean(steps)),
            "score": total + 100.0 * success}
