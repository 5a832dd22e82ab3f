"""The robots an environment can simulate: the shipped ones by name, or a user's URDF.

A robot is the controller's model (RobotModel), its parameters (the shipped config/<robot>.yaml,
which turns the safety layer on) and how to simulate it (an MJCF file for MuJoCo where one is
shipped, else the URDF; a start configuration).
"""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Any, Optional, Sequence

import numpy as np

import cartesian_impedance as ci

__all__ = ["RobotSpec", "robot_spec", "SHIPPED_ROBOTS"]

SHIPPED_ROBOTS = ("panda", "iiwa14", "ur5e", "planar3")


@dataclasses.dataclass
class RobotSpec:
    """What an environment needs to simulate and control one arm.

    urdf, base_link, tip_link: the controller's chain (the tip is the flange). mjcf: an MJCF
    scene for MuJoCo with torque motors and a keyframe "ready" ('' = simulate the URDF).
    config: a parameter file read on top of the URDF's derived defaults ('' = none: then the
    safety layer is switched on as the shipped files do, see `user_safety`). start_q: [rad]
    (None = the MJCF keyframe, or find_start_configuration()). translation_axes: the base-frame
    axes a task may move along (the planar arm moves in x-z only). tool: T_tip_tool, the
    controlled frame in the tip link's frame (a Pose or (position [m], quaternion x, y, z, w);
    None = the tip link itself), e.g. the tip of a peg held at the flange: the reference, the
    observed pose and the stiffness then refer to it."""
    name: str
    urdf: str
    base_link: str
    tip_link: str
    mjcf: str = ""
    config: str = ""
    start_q: Optional[Sequence[float]] = None
    translation_axes: Sequence[bool] = (True, True, True)
    tool: Any = None

    def load_model(self) -> "ci.RobotModel":
        if self.tool is None:
            return ci.RobotModel.from_urdf_file(self.urdf, self.base_link, self.tip_link)
        return ci.RobotModel.from_urdf_file(self.urdf, self.base_link, self.tip_link,
                                            tool=self.tool)

    def load_parameters(self, model) -> "ci.Parameters":
        """The shipped configuration on top of what the URDF says the arm can do; a URDF without
        a configuration gets the shipped files' safety layer (`user_safety`)."""
        if self.config:
            return ci.Parameters.load(self.config)
        parameters = model.default_parameters()
        parameters.update(user_safety(model, self.start_q))
        return parameters


def user_safety(model, start_q=None) -> dict:
    """The safety layer for an arm without a configuration file, as the shipped files set it:
    speed caps 1 m/s and 2.5 rad/s, force caps of at most 100 N and 20 Nm (below the arm's
    limits.wrench), the energy tank at 5 mJ, and a workspace box of +-reach around the base with
    its floor at the mounting plane (z = 0) and 2000 N/m walls; reach is the largest distance of
    the flange from the base over the start configuration and 64 seeded configurations."""
    defaults = model.default_parameters()
    limits = model.limits
    rng = np.random.default_rng(0)
    low = np.where(np.isfinite(limits.position_lower), limits.position_lower, -math.pi)
    high = np.where(np.isfinite(limits.position_upper), limits.position_upper, math.pi)
    samples = [rng.uniform(low, high) for _ in range(64)]
    if start_q is not None:
        samples.append(np.asarray(start_q, dtype=float))
    reach = max(float(np.linalg.norm(model.compute_pose(q).position)) for q in samples)
    reach = max(reach, 0.1)
    return {
        "safety.max_speed.translation": 1.0,
        "safety.max_speed.rotation": 2.5,
        "safety.max_force.force": min(100.0, float(defaults["limits.wrench.force"])),
        "safety.max_force.torque": min(20.0, float(defaults["limits.wrench.torque"])),
        "safety.workspace.min": [-reach, -reach, 0.0],
        "safety.workspace.max": [reach, reach, reach],
        "safety.workspace.stiffness": 2000.0,
        "safety.workspace.damping": 100.0,
        "safety.energy_tank.enabled": True,
        "safety.energy_tank.capacity": 0.005,
        "safety.energy_tank.initial": 0.005,
    }


def robot_spec(robot) -> RobotSpec:
    """A RobotSpec from a shipped robot's name ('panda', 'iiwa14', 'ur5e', 'planar3'), a dict of
    RobotSpec's fields for a user's URDF (urdf, base_link, tip_link required), or a RobotSpec."""
    if isinstance(robot, RobotSpec):
        return robot
    if isinstance(robot, dict):
        missing = [k for k in ("urdf", "base_link", "tip_link") if k not in robot]
        if missing:
            raise ci.Error("robot = %r lacks %s: a URDF robot needs urdf, base_link and "
                           "tip_link" % (robot, ", ".join(missing)))
        fields = dict(robot)
        fields.setdefault("name", os.path.splitext(os.path.basename(str(fields["urdf"])))[0])
        for key in ("urdf", "mjcf", "config"):
            if key in fields:
                fields[key] = os.fspath(fields[key])
        try:
            return RobotSpec(**fields)
        except TypeError as error:
            raise ci.Error("robot: %s (fields: %s)" % (
                error, ", ".join(f.name for f in dataclasses.fields(RobotSpec)))) from None
    data = ci.data_dir()
    models, config = data / "models", data / "config"
    if robot == "panda":
        return RobotSpec("panda", str(models / "panda/panda.urdf"), "panda_link0", "panda_link8",
                         mjcf=str(models / "panda/panda.xml"), config=str(config / "panda.yaml"))
    if robot == "iiwa14":
        return RobotSpec("iiwa14", str(models / "iiwa14/iiwa14.urdf"), "iiwa_link_0",
                         "iiwa_link_ee", mjcf=str(models / "iiwa14/iiwa14.xml"),
                         config=str(config / "iiwa14.yaml"))
    if robot == "ur5e":
        # In front of the base (+x) at about 0.5 m height, the tool pointing down, as the demo.
        return RobotSpec("ur5e", str(models / "ur5e/ur5e.urdf"), "base_link", "tool0",
                         config=str(config / "ur5e.yaml"),
                         start_q=(math.pi, -math.pi / 2, math.pi / 2, -math.pi / 2,
                                  -math.pi / 2, 0.0))
    if robot == "planar3":
        return RobotSpec("planar3", str(models / "planar3/planar3.urdf"), "base_link", "tool0",
                         config=str(config / "planar3.yaml"),
                         start_q=(0.5, 1.5, math.pi - 2.0),
                         translation_axes=(True, False, True))
    raise ci.Error("robot = %r is not a shipped robot (%s); give a dict with urdf, base_link "
                   "and tip_link for your own" % (robot, ", ".join(SHIPPED_ROBOTS)))


def make_simulation(spec: RobotSpec, model, engine: str, boxes=(), plant=None):
    """The simulation of `spec` with `boxes` (a list of ci.sim.Box) on `engine`: MuJoCo loads the
    MJCF scene where there is one (its motors' torque ranges, keyframe 'ready'), DART and robots
    without MJCF the URDF (start: spec.start_q, else the MJCF keyframe, else
    find_start_configuration). plant: None (nominal) or a ci.sim.Plant."""
    available, reason = ci.sim.engine_available(engine)
    if not available:
        raise ci.Error("engine = '%s' is not available: %s" % (engine, reason))
    names = list(model.joint_names)
    start_q: Any = spec.start_q
    if engine == "mujoco" and spec.mjcf:
        options: dict = dict(joint_names=names, engine=engine)
        if plant is not None:
            options["plant"] = plant
        if start_q is not None:
            options["start_q"] = list(start_q)
        return ci.sim.make_scene(spec.mjcf, list(boxes), **options)
    if start_q is None and spec.mjcf:
        start_q = ci.sim.Simulation.from_mjcf_file(spec.mjcf, joint_names=names).q
    if start_q is None:
        start_q = ci.find_start_configuration(model)["q"]
    extra: dict = {} if plant is None else dict(plant=plant)
    return ci.sim.make_scene(spec.urdf, list(boxes), joint_names=names, engine=engine,
                             start_q=list(np.asarray(start_q, dtype=float)), **extra)
