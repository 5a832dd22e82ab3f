"""The safety layer from Python: ControllerState.safety (every field, NumPy arrays, documented
with units), what it reports when each part acts, and the safety.* and payload.* parameters
through Parameters."""

import math

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import PANDA_YAML

# Every field of the C++ SafetyState, with the unit its docstring must name ("" for flags and
# scales, which are fractions).
SAFETY_FIELDS = {
    "reference_speed_limited": "",
    "translation_drive_scale": "[0, 1]",
    "rotation_drive_scale": "[0, 1]",
    "braking": "",
    "force_scale": "[0, 1]",
    "torque_scale": "[0, 1]",
    "reference_clipped": "",
    "workspace_penetration": "[m]",
    "wall_force": "[N]",
    "wall_energy": "[J]",
    "tank_level": "[J]",
    "tank_draw": "[J]",
    "stiffness_change_scale": "[0, 1]",
    "payload_mass": "[kg]",
    "payload_center_of_mass": "[m]",
    "payload_estimate_valid": "",
    "payload_estimate_mass": "[kg]",
    "payload_estimate_center_of_mass": "[m]",
    "nullspace_scale": "[0, 1]",
    "settings_held": "",
    "joint_limit_wall": "",
    "static_wrench_unexplained": "",
    "payload_mismatch": "",
    "oscillation_scale": "[1/256, 1]",
    "oscillations": "since start()",
    "generated_energy": "[J]",
    "passivity_scale": "[1/256, 1]",
    "passivity_halvings": "since start()",
    "max_speed_in_force": "[m/s]",
    "max_force_in_force": "[N]",
    "pfl_speed_limit": "[m/s]",
    "pfl_effective_mass": "[kg]",
    # The settings in force, as objects whose fields carry the units.
    "pose_error_in_force": "PoseErrorLimits",
    "workspace_in_force": "Workspace",
}
VECTORS = {"workspace_penetration", "wall_force", "payload_center_of_mass",
           "payload_estimate_center_of_mass", "passivity_scale"}
FLAGS = {"reference_speed_limited", "braking", "reference_clipped", "payload_estimate_valid",
         "settings_held", "joint_limit_wall", "static_wrench_unexplained", "payload_mismatch"}
# Their fields and units.
IN_FORCE_FIELDS = {ci.PoseErrorLimits: {"translation": "[m]", "rotation": "[rad]"},
                   ci.Workspace: {"min": "[m]", "max": "[m]", "stiffness": "[N/m]",
                                  "damping": "[N s/m]"}}


def rotation(axis, angle):
    """Rodrigues: the rotation matrix of `angle` [rad] about the unit vector `axis`."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def test_safety_state_has_every_field_documented_with_its_unit():
    names = {name for name in dir(ci.SafetyState) if not name.startswith("_")}
    assert names == set(SAFETY_FIELDS)
    for name, unit in SAFETY_FIELDS.items():
        doc = getattr(ci.SafetyState, name).__doc__
        assert doc and len(doc) > 20, name
        assert unit in doc, f"{name}: {doc!r} does not name {unit}"
    assert "safety" in ci.ControllerState.safety.__doc__
    assert ci.SafetyState.__doc__
    for cls, fields in IN_FORCE_FIELDS.items():
        assert {name for name in dir(cls) if not name.startswith("_")} == set(fields)
        for name, unit in fields.items():
            assert unit in getattr(cls, name).__doc__, f"{cls.__name__}.{name}"


def test_a_loop_at_rest_reports_nothing_capped_and_a_full_tank(panda, ready):
    loop = ci.ControlLoop(panda)
    loop.start(ready, np.zeros(7))
    loop.step(ready, np.zeros(7), 0.001)
    safety = loop.state.controller.safety
    for name in SAFETY_FIELDS:
        value = getattr(safety, name)
        if name in VECTORS:
            assert isinstance(value, np.ndarray) and value.shape == (3,) and value.dtype == float
            assert np.all(value == (1.0 if name == "passivity_scale" else 0.0)), name
        elif name in FLAGS:
            assert value is False, name
    assert safety.translation_drive_scale == safety.rotation_drive_scale == 1.0
    assert safety.force_scale == safety.torque_scale == safety.stiffness_change_scale == 1.0
    assert safety.nullspace_scale == 1.0
    assert safety.passivity_halvings == 0 and safety.generated_energy <= 0.0
    # No caps configured, no body region: nothing in force.
    assert safety.max_speed_in_force == (0.0, 0.0) and safety.max_force_in_force == (0.0, 0.0)
    assert safety.pfl_speed_limit == 0.0 and safety.pfl_effective_mass == 0.0
    # The settings in force are the parameters (nothing waits for the tank).
    defaults = ci.Parameters()
    assert safety.pose_error_in_force.translation == defaults["limits.pose_error.translation"]
    np.testing.assert_array_equal(safety.workspace_in_force.max, defaults["safety.workspace.max"])
    assert safety.tank_level == ci.Parameters()["safety.energy_tank.initial"]
    assert safety.tank_draw == 0.0 and safety.payload_mass == 0.0
    assert "tank_level=0.005 J" in repr(safety)
    # A returned array is a copy: changing it changes nothing in the state.
    safety.wall_force[0] = 5.0
    assert loop.state.controller.safety.wall_force[0] == 0.0


def test_every_part_of_the_safety_layer_reports_when_it_acts(panda, ready):
    """The arm moves as commanded (q integrates dq: open loop, the speed is what we say), faster
    than tiny speed caps, away from a small workspace box 10 cm behind the flange; the force caps
    are below spring + wrench, a stiffness raise is more than the energy tank holds, a payload is
    declared. Then it stands still long enough for the payload estimate."""
    dq = np.full(7, 0.01)
    start = panda.compute(ready)
    twist = start.jacobian @ dq
    along = twist[:3] / np.linalg.norm(twist[:3])
    turning = twist[3:] / np.linalg.norm(twist[3:])
    center = start.pose.position - 0.1 * along
    wall_stiffness, wall_damping = 500.0, 100.0
    parameters = {
        "safety.max_speed.translation": 1e-4, "safety.max_speed.rotation": 1e-3,
        "safety.max_force.force": 10.0, "safety.max_force.torque": 2.0,
        "safety.workspace.min": center - 0.03, "safety.workspace.max": center + 0.03,
        "safety.workspace.stiffness": wall_stiffness, "safety.workspace.damping": wall_damping,
        "payload.mass": 1.0, "payload.center_of_mass": [0.0, 0.0, 0.1],
        "stiffness.translation": 200.0, "stiffness.rotation": 10.0,
    }
    loop = ci.ControlLoop(panda, parameters)
    q = ready.copy()
    loop.start(q, dq)
    reference = np.eye(4)
    reference[:3, :3] = rotation(turning, 3.0) @ start.pose.rotation_matrix()
    reference[:3, 3] = start.pose.position - along  # a metre behind: clipped into the box
    loop.set_reference_pose(reference)
    loop.set_stiffness([1000, 1000, 1000, 50, 50, 50])
    loop.set_wrench(np.concatenate([60.0 * along, 15.0 * turning]), "base")

    lower, upper = center - 0.03, center + 0.03
    clipped_once = False
    tank_short_once = False
    for k in range(2000):
        loop.step(q, dq, 0.001)
        state = loop.state.controller
        assert state.status == ci.Status.ok, state.fault
        safety = state.safety
        clipped_once |= safety.reference_clipped
        # The raise costs more than the tank holds: it is applied only as far as it pays.
        tank_short_once |= safety.stiffness_change_scale < 1.0 and safety.tank_draw > 0.0
        # The commanded reference is inside the box, every cycle.
        position = state.commanded.pose.position
        assert np.all(position >= lower - 1e-15) and np.all(position <= upper + 1e-15)
        if k % 500 == 499:
            # What the state says against what the physics says, from this cycle's pose.
            flange = state.pose.position
            penetration = flange - np.clip(flange, lower, upper)
            np.testing.assert_allclose(safety.workspace_penetration, penetration, atol=1e-15)
            assert np.linalg.norm(penetration) > 0.02  # outside by at least 2 cm
            # The walls push from the box in force: the flange started outside the box, so the
            # box in force started around it and closes in only as the energy tank pays for
            # what that stores (the raise below keeps the tank empty), waiting meanwhile.
            box = safety.workspace_in_force
            assert box.stiffness == wall_stiffness and box.damping == wall_damping
            assert safety.settings_held
            assert np.all(box.min <= lower + 1e-12) and np.all(box.max >= upper - 1e-12)
            outside = flange - np.clip(flange, box.min, box.max)
            assert np.linalg.norm(outside) > 0.0
            velocity = (panda.compute(q).jacobian @ dq)[:3]
            outward = velocity * outside > 0
            assert outward.any()  # the damper acts too
            # Spring (K x depth) and damper (on the outward motion) push inward on every axis;
            # both are part of what the caps scale and govern (max_force, max_speed), so the
            # force is at most what they would give uncapped.
            wall = safety.wall_force
            assert np.all(wall * outside <= 1e-12), (wall, outside)
            uncapped = -wall_stiffness * outside - wall_damping * velocity * outward
            assert 0.0 < np.linalg.norm(wall) <= np.linalg.norm(uncapped) + 1e-9
            # Far above the speed caps: all of the push along the motion removed, braking.
            assert safety.translation_drive_scale == 0.0 and safety.rotation_drive_scale == 0.0
            assert safety.braking and safety.reference_speed_limited
            assert 0.0 < safety.force_scale < 1.0 and 0.0 < safety.torque_scale < 1.0
            assert 0.0 <= safety.tank_level <= ci.Parameters()["safety.energy_tank.capacity"]
            # Declared at start and applied at once (the filter then holds it).
            assert safety.payload_mass == pytest.approx(1.0, abs=1e-12)
            np.testing.assert_allclose(safety.payload_center_of_mass, [0, 0, 0.1], atol=1e-12)
            assert not safety.payload_estimate_valid  # moving
        q = q + 0.001 * dq
    assert clipped_once
    assert tank_short_once

    dq = np.zeros(7)
    valid_after = None
    for k in range(700):
        loop.step(q, dq, 0.001)
        settled = loop.state.controller.safety
        # Valid, or a static wrench no hanging load makes (the spring still pulls the flange
        # toward the reference clipped into the box): either way the estimate has settled.
        if valid_after is None and (
            settled.payload_estimate_valid or settled.static_wrench_unexplained
        ):
            valid_after = (k + 1) * 0.001
    # Still for kPayloadSettleTime (0.5 s) once the flange's low-passed speed (time constant
    # kStillFilterTime, 0.05 s) has fallen below kStillSpeed after the motion before.
    assert 0.5 <= valid_after <= 0.5 + 6 * 0.05
    safety = loop.state.controller.safety
    assert not safety.braking and safety.translation_drive_scale == 1.0
    assert math.isfinite(safety.payload_estimate_mass)
    assert safety.payload_estimate_center_of_mass.shape == (3,)


def test_parameters_read_and_write_the_safety_and_payload_rows(tmp_path, panda, ready):
    shipped = ci.Parameters.load(PANDA_YAML)
    assert shipped["safety.max_speed.translation"] == 1.0
    assert shipped["safety.max_force.force"] == 100.0
    np.testing.assert_array_equal(shipped["safety.workspace.min"], [-0.9, -0.9, 0.0])
    assert shipped["safety.energy_tank.enabled"] is True
    assert shipped["payload.mass"] == 0.0

    p = ci.Parameters()
    p["safety.max_speed.rotation"] = 1.5
    p["safety.workspace.max"] = [0.5, 0.6, 0.7]
    p.update({"safety": {"max_force": {"torque": 8.0}, "energy_tank": {"capacity": 0.02}},
              "payload.mass": 0.75, "payload": {"center_of_mass": [0.0, 0.01, 0.05]}})
    assert p["safety.max_speed.rotation"] == 1.5
    np.testing.assert_array_equal(p["safety.workspace.max"], [0.5, 0.6, 0.7])
    assert p["safety.max_force.torque"] == 8.0 and p["safety.energy_tank.capacity"] == 0.02
    assert p["payload.mass"] == 0.75
    np.testing.assert_array_equal(p["payload.center_of_mass"], [0.0, 0.01, 0.05])
    nested = p.to_dict(nested=True)
    assert nested["safety"]["max_force"]["torque"] == 8.0 and nested["payload"]["mass"] == 0.75
    path = tmp_path / "safety.yaml"
    p.save(path)
    again = ci.Parameters.load(path)
    for name in ("safety.max_speed.rotation", "safety.workspace.max", "safety.max_force.torque",
                 "safety.energy_tank.capacity", "payload.mass", "payload.center_of_mass"):
        np.testing.assert_array_equal(again[name], p[name])
    assert "payload.mass" in repr(p) and "safety.max_force.torque" in repr(p)

    # Bad values name the parameter, the value and the bound, and change nothing.
    before = p.to_dict()
    with pytest.raises(ci.Error, match=r"safety\.max_speed\.translation.*-1.*0"):
        p["safety.max_speed.translation"] = -1.0
    with pytest.raises(ci.Error, match=r"safety\.workspace\.min.*greater than safety\.workspace"):
        p.update({"safety.workspace.min": [0.8, 0.0, 0.0]})  # above max.x = 0.5
    with pytest.raises(ci.Error, match=r"safety\.energy_tank\.initial.*capacity"):
        p["safety.energy_tank.initial"] = 0.5
    with pytest.raises(TypeError):
        p["safety.energy_tank.enabled"] = "yes"
    with pytest.raises(ci.Error, match=r"payload\.mass"):
        p["payload.mass"] = -0.1
    after = p.to_dict()
    assert before.keys() == after.keys()
    assert all(np.array_equal(before[k], after[k]) for k in before)

    # A loop made from them reports them.
    loop = ci.ControlLoop(panda, p)
    loop.start(ready, np.zeros(7))
    loop.step(ready, np.zeros(7), 0.001)
    assert loop.latest_parameters()["payload.mass"] == 0.75
    safety = loop.state.controller.safety
    assert safety.payload_mass == pytest.approx(0.75, abs=1e-12)
    np.testing.assert_allclose(safety.payload_center_of_mass, [0.0, 0.01, 0.05], atol=1e-12)
    assert safety.tank_level == p["safety.energy_tank.initial"]


def test_the_collision_monitor_reports_and_resume_ends_a_reaction(panda, ready):
    """A push the model does not explain (a step of dq no torque caused) is a collision; the
    state says where and what was done; resume() ends the stop; a wrong reaction name is refused
    naming the valid ones; the body region of power and force limiting is a choice too."""
    with pytest.raises(ci.Error, match="report, stop, reflex, retract"):
        ci.ControlLoop(panda, {"collision.reaction": "brake"})
    with pytest.raises(ci.Error, match="none, skull, face"):
        ci.ControlLoop(panda, {"safety.pfl.body_region": "knee"})
    loop = ci.ControlLoop(panda, {"collision.reaction": "stop", "safety.pfl.body_region": "hand"})
    loop.start(ready, np.zeros(7))
    loop.step(ready, np.zeros(7), 0.001)
    collision = loop.state.controller.collision
    assert collision.residual.shape == (7,) and not collision.detected
    assert loop.state.controller.safety.pfl_speed_limit > 1.0  # a hand: about 1.4 m/s
    dq = np.zeros(7)
    dq[1] = 0.5  # joint 2 kicked to 0.5 rad/s within a cycle: tens of Nm nobody commanded
    loop.step(ready, dq, 0.001)
    collision = loop.state.controller.collision
    # The kick's momentum reaches the joints M couples to joint 2: the last one past its threshold
    # is named.
    assert collision.detected and collision.joint >= 1
    assert collision.reaction == ci.CollisionReaction.stop and collision.collisions == 1
    assert "detected=True" in repr(collision)
    for _ in range(50):
        loop.step(ready, np.zeros(7), 0.001)
    loop.resume()
    loop.step(ready, np.zeros(7), 0.001)
    assert not loop.state.controller.collision.detected


def test_the_collision_monitor_reads_measured_joint_torques(panda, ready):
    """With collision.measured_torque the observer reads the torques step() is given: a cycle
    without them fails closed naming them; given the torque that holds the arm at rest (g(q)), the
    residual stays at zero; 20 Nm more on joint 2 than the model explains is a collision there."""
    loop = ci.ControlLoop(panda, {"collision.measured_torque": True})
    loop.start(ready, np.zeros(7))
    loop.step(ready, np.zeros(7), 0.001)
    assert loop.state.controller.status == ci.Status.missing_dynamics
    assert "measured_torque" in str(loop.state.controller.fault)
    holding = panda.compute(ready, np.zeros(7), dynamics=True).gravity
    for _ in range(20):
        loop.step(ready, np.zeros(7), 0.001, measured_torque=holding)
    collision = loop.state.controller.collision
    assert loop.state.controller.status == ci.Status.ok
    assert np.max(np.abs(collision.residual)) < 1e-9 and not collision.detected
    pressed = holding.copy()
    pressed[1] += 20.0  # the drive holds 20 Nm the model does not: something presses on link 2
    for _ in range(50):
        loop.step(ready, np.zeros(7), 0.001, measured_torque=pressed)
    collision = loop.state.controller.collision
    assert collision.detected and collision.joint == 1
    # The observer follows the torque with its first-order filter: 50 ms at K_O = 100 is 99 %.
    assert collision.residual[1] == pytest.approx(-20.0, rel=0.02)
    with pytest.raises(ValueError, match="measured_torque must have shape"):
        loop.step(ready, np.zeros(7), 0.001, measured_torque=np.zeros(6))
