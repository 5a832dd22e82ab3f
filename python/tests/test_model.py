"""RobotModel.compute and the Pose conversions (quaternions x, y, z, w; 4x4 transforms)."""

import pickle

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import PANDA_URDF, PANDA_YAML


def rotation_vector(R):
    """log(R) as a rotation vector (small angles, for finite differences)."""
    return 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])


def test_panda_flange_is_where_the_published_kinematics_put_it(panda, ready):
    assert panda.num_joints == 7
    assert panda.joint_names == ["panda_joint%d" % i for i in range(1, 8)]
    assert panda.robot_name == "panda" and panda.base_link == "panda_link0"
    assert all(t == ci.JointType.revolute for t in panda.joint_types)
    np.testing.assert_allclose(panda.limits.effort, [87] * 4 + [12] * 3)
    np.testing.assert_allclose(panda.compute(np.zeros(7)).pose.position, [0.088, 0, 0.926],
                               atol=1e-12)
    np.testing.assert_allclose(panda.compute_pose(ready).position, [0.3069, 0, 0.5903], atol=1e-4)
    # Flange pointing down at the ready pose: its z axis is the base's -z.
    np.testing.assert_allclose(panda.compute(ready).pose.rotation_matrix()[:, 2], [0, 0, -1],
                               atol=1e-12)


def test_jacobian_matches_finite_differences_of_the_pose(panda, ready):
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = ready + rng.uniform(-0.3, 0.3, 7)
        kinematics = panda.compute(q, dynamics=False)
        assert kinematics.jacobian.shape == (6, 7)
        assert kinematics.mass is None and not kinematics.has_dynamics
        h = 1e-6
        for j in range(7):
            dq = np.zeros(7)
            dq[j] = h
            plus, minus = panda.compute_pose(q + dq), panda.compute_pose(q - dq)
            linear = (plus.position - minus.position) / (2 * h)
            angular = rotation_vector(plus.rotation_matrix() @ minus.rotation_matrix().T) / (2 * h)
            np.testing.assert_allclose(kinematics.jacobian[:3, j], linear, atol=1e-8)
            np.testing.assert_allclose(kinematics.jacobian[3:, j], angular, atol=1e-8)


def test_dynamics(panda, ready):
    k = panda.compute(ready, np.full(7, 0.1))
    assert k.has_dynamics
    assert k.mass.shape == (7, 7) and k.gravity.shape == (7,) and k.coriolis.shape == (7,)
    np.testing.assert_allclose(k.mass, k.mass.T, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(k.mass) > 0)
    # Published gravity torque magnitudes at the ready pose (models/README.md) [Nm].
    np.testing.assert_allclose(np.abs(k.gravity), [0, 1.77, 0.64, 18.57, 0.63, 1.69, 0], atol=0.01)
    assert np.allclose(panda.compute(ready).coriolis, 0)
    assert panda.moving_mass == pytest.approx(16.062132, abs=1e-6)
    np.testing.assert_allclose(panda.gravity, [0, 0, -9.81])


def test_tool_offset_given_as_pair_or_4x4_is_the_same(panda, ready):
    T = np.eye(4)
    T[:3, 3] = [0, 0, 0.1]
    by_pair = ci.RobotModel.from_urdf_file(PANDA_URDF, "panda_link0", "panda_link8",
                                           tool=([0, 0, 0.1], [0, 0, 0, 1]))
    by_matrix = ci.RobotModel.from_urdf_file(str(PANDA_URDF), "panda_link0", "panda_link8",
                                             tool=T, gravity=[0, 0, -9.81])
    flange = panda.compute_pose(ready)
    expected = flange.position + flange.rotation_matrix() @ [0, 0, 0.1]
    np.testing.assert_allclose(by_pair.compute_pose(ready).position, expected, atol=1e-12)
    np.testing.assert_allclose(by_matrix.compute_pose(ready).position, expected, atol=1e-12)
    np.testing.assert_allclose(by_pair.tool.matrix(), T, atol=1e-15)
    model = ci.RobotModel.from_urdf_string(PANDA_URDF.read_text(), "panda_link0", "panda_link4")
    assert model.num_joints == 4 and "4 joints" in repr(model)


def test_pose_forms_and_quaternion_order_x_y_z_w():
    # 90 deg about z: quaternion (0, 0, sin 45, cos 45) in the order x, y, z, w.
    s = np.sqrt(0.5)
    pose = ci.Pose([1, 2, 3], [0, 0, s, s])
    T = pose.matrix()
    np.testing.assert_allclose(T[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(T[:3, 3], [1, 2, 3])
    back = ci.Pose.from_matrix(T)
    np.testing.assert_allclose(back.orientation, [0, 0, s, s], atol=1e-15)
    position, quaternion = back
    np.testing.assert_allclose(position, [1, 2, 3])
    assert quaternion.shape == (4,)
    assert "orientation_xyzw=[0, 0, 0.7071067812, 0.7071067812]" in repr(pose)
    copied = pickle.loads(pickle.dumps(pose))
    np.testing.assert_array_equal(copied.matrix(), pose.matrix())
    identity = ci.Pose()
    np.testing.assert_array_equal(identity.matrix(), np.eye(4))
    identity.position = np.arange(3, dtype=np.int64)
    np.testing.assert_array_equal(identity.position, [0, 1, 2])


def test_backend_kdl_agrees_with_the_native_default(panda, ready):
    assert panda.backend == "native"
    kdl = ci.RobotModel.from_urdf_file(PANDA_URDF, "panda_link0", "panda_link8", backend="kdl")
    assert kdl.backend == "kdl"
    dq = np.full(7, 0.3)
    a, b = panda.compute(ready, dq), kdl.compute(ready, dq)
    np.testing.assert_allclose(a.pose.position, b.pose.position, atol=1e-12)
    np.testing.assert_allclose(a.jacobian, b.jacobian, atol=1e-12)
    for term in ("mass", "gravity", "coriolis"):
        np.testing.assert_allclose(getattr(a, term), getattr(b, term), atol=1e-10)
    loop = ci.ControlLoop(kdl)
    loop.start(ready, np.zeros(7))
    assert np.all(np.isfinite(loop.step(ready, np.zeros(7), 0.001)))
    with pytest.raises(ci.Error, match="expected 'native' or 'kdl'"):
        ci.RobotModel.from_urdf_file(PANDA_URDF, "panda_link0", "panda_link8", backend="rbdl")


def test_rate_check_names_a_stiffness_the_rate_limit_cannot_follow(panda, ready):
    shipped = ci.Parameters.load(PANDA_YAML)
    check = panda.check_rate_limit(ready, shipped)
    assert check["warnings"] == []
    assert np.all(check["followed"][:3] >= 0.003)
    stiff = ci.Parameters.load(PANDA_YAML)
    stiff["limits.stiffness.translation.max"] = 30000.0
    check = panda.check_rate_limit(ready, stiff)
    assert len(check["warnings"]) == 1
    assert "limits.stiffness.translation.max = 30000 N/m" in check["warnings"][0]
    # followed = R / (k lever w), w = sqrt(k / m)
    w = np.sqrt(30000.0 / check["mass"][:3])
    np.testing.assert_allclose(check["frequency"][:3], w, rtol=1e-12)
    np.testing.assert_allclose(check["followed"][:3], 1000.0 / (30000.0 * check["lever"][:3] * w),
                               rtol=1e-12)
