"""RobotActionInterface: a policy's actions on a ControlLoop that a robot's driver steps.

On a robot nothing steps the loop for the policy: the driver (or the runtime's control thread)
calls loop.step(q, dq, dt) at 1 kHz on its own thread, and the policy, at its own rate, reads the
newest state and sends commands; both are thread-safe (ControlLoop.latest_state(), set_*). This
class gives the policy the same action and observation as the simulated environments.
"""

from __future__ import annotations

import numpy as np

from .actions import ActionInterface, ActionLimits

__all__ = ["RobotActionInterface"]


class RobotActionInterface:
    """The environments' action and observation on a running ControlLoop.

    RobotActionInterface(loop, model, parameters, wrench=False, action_limits=None): loop is a
    started ControlLoop that a driver steps; model its RobotModel; parameters the loop's
    Parameters (for the stiffness range and the leash). reset() puts the reference at the
    flange's pose now; act(action) checks the action (raises cartesian_impedance.Error naming the
    field, and changes nothing) and sends reference, stiffness and wrench; observation(goal)
    gives what the environment with that goal would (float32)."""

    def __init__(self, loop, model, parameters, wrench=False, action_limits=None):
        if isinstance(action_limits, dict):
            action_limits = ActionLimits(**action_limits)
        self.loop = loop
        self.model = model
        self.actions = ActionInterface(model, parameters, wrench, action_limits)
        self.action_space = self.actions.action_space

    def reset(self):
        self.actions.reset(self.loop)

    def act(self, action):
        return self.actions.apply(action, self.loop)

    def observation(self, goal=()):
        return self.actions.observe(self.loop, np.asarray(goal, dtype=float))
