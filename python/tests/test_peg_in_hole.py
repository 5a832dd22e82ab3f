"""Geometry attached to the robot and the peg-in-hole scene from Python (ci.sim.AttachedBox,
SquareHole, hole_boxes, make_scene(attached=...), make_peg_in_hole_scene): the scene a learning
environment builds, driven by the impedance controller at a policy's rate."""

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import PANDA_READY, PANDA_URDF, PANDA_XML, requires_sim

pytestmark = requires_sim

PEG_LENGTH = 0.1
DEPTH = 0.03


def hole_below_the_peg(panda, offset=0.0):
    """A hole with 1 mm clearance for a 25 mm peg, its opening 2 cm below the peg's tip at the
    ready pose (shifted by `offset` [m] along x), its sides along the flange's x and y."""
    flange = panda.compute_pose(PANDA_READY).matrix()
    opening = flange @ np.diag([1.0, -1.0, -1.0, 1.0])  # z up, out of the hole
    opening[:3, 3] = flange[:3, 3] + flange[:3, 2] * PEG_LENGTH + [offset, 0.0, -0.02]
    return ci.sim.SquareHole(opening, peg_half_width=0.0125, clearance=0.001, depth=DEPTH)


def test_hole_boxes_leave_the_clearance_around_the_peg():
    hole = ci.sim.SquareHole((np.zeros(3), [0, 0, 0, 1]), peg_half_width=0.01, clearance=0.0006,
                             depth=0.02)
    boxes = {box.name: box for box in ci.sim.hole_boxes(hole)}
    assert sorted(boxes) == ["hole_floor", "hole_wall_x_minus", "hole_wall_x_plus",
                             "hole_wall_y_minus", "hole_wall_y_plus"]
    wall = boxes["hole_wall_x_plus"]
    assert wall.center[0] - wall.half_size[0] == pytest.approx(0.0103, abs=1e-15)
    floor = boxes["hole_floor"]
    assert floor.center[2] + floor.half_size[2] == pytest.approx(-0.02, abs=1e-15)
    hole.clearance = -0.001
    with pytest.raises(ci.Error, match=r"hole\.clearance = -0\.001"):
        ci.sim.hole_boxes(hole)


def test_an_attached_box_moves_with_the_flange_and_its_errors_name_the_field():
    box = ci.sim.AttachedBox("panda_link8", [0.0125, 0.0125, 0.05], 0.3, position=[0, 0, 0.05])
    assert "panda_link8" in repr(box) and box.mass == 0.3
    sim = ci.sim.make_scene(PANDA_XML, [], attached=[box])
    flange = sim.body_pose("panda_link8").matrix()
    peg = sim.body_pose("attached_box_0").position
    np.testing.assert_allclose(peg, flange[:3, 3] + 0.05 * flange[:3, 2], atol=1e-12)
    box.body = "panda_hand"
    with pytest.raises(ci.Error, match=r"attached\[0\]\.body = 'panda_hand'.*panda_link8"):
        ci.sim.make_scene(PANDA_XML, [], attached=[box])


def insert(panda, engine, offset):
    """The reference moved down at 3 cm/s, 1 cm past the hole's floor, updated every 10 ms (as
    a policy would) for 3 s; returns the tip's depth below the opening [m]."""
    hole = hole_below_the_peg(panda, offset)
    sim = ci.sim.make_peg_in_hole_scene(PANDA_URDF, "panda_link8", hole, peg_length=PEG_LENGTH,
                                        peg_mass=0.2, start_q=PANDA_READY, engine=engine)
    parameters = ci.Parameters({"stiffness.translation": [2000.0] * 3,
                                "stiffness.rotation": [100.0] * 3, "payload.mass": 0.2,
                                "payload.center_of_mass": [0, 0, PEG_LENGTH / 2],
                                "dynamics.armature": list(sim.armature)})
    loop = ci.ControlLoop(panda, parameters)
    loop.start(sim.q, sim.dq)
    start = panda.compute_pose(PANDA_READY)
    for k in range(300):
        target = ci.Pose(start.position - [0, 0, min(0.06, 0.03 * 0.01 * (k + 1))],
                         start.orientation)
        loop.set_reference_pose(target)
        sim.run(loop, 0.01)
    peg = sim.body_pose("peg").matrix()
    tip = peg[:3, 3] + peg[:3, 2] * PEG_LENGTH / 2
    return hole.opening.position[2] - tip[2], sim.contact_wrench("peg")


@pytest.mark.parametrize("engine", ["mujoco", "dart"])
def test_the_controller_inserts_the_peg_and_jams_it_3mm_off(panda, engine):
    available, reason = ci.sim.engine_available(engine)
    if not available:
        pytest.skip(reason)
    depth, wrench = insert(panda, engine, 0.0)
    assert depth == pytest.approx(DEPTH, abs=1e-3)
    assert wrench[2] == pytest.approx(20.0, abs=2.0)  # 2000 N/m x the last 1 cm
    depth, wrench = insert(panda, engine, 0.003)
    assert depth < 1e-3
    assert wrench[2] > 20.0
