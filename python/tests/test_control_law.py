"""The controller against the control law written out in NumPy, on seeded random cases:

    tau = J^T (-K e - D (J dq)) + N tau_0 + J^T F,   e = [p - p_d; log(R R_d^T)],
    D = 2 zeta sqrt(K),  tau_0 = -K_ns (q - q_d) - 2 zeta_ns sqrt(K_ns) dq,
    N = I - J^T (J J^T + lambda^2 I)^-1 J,

with filters off and limits wide, so the library's result must be the formula's to 1e-10."""

import math

import numpy as np
import pytest

import cartesian_impedance as ci


def quaternion_product(a, b):
    """Hamilton product of quaternions stored x, y, z, w."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ])


def conjugate(q):
    return np.array([-q[0], -q[1], -q[2], q[3]])


def rotation_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def rotation_error(current, desired):
    """log(R R_d^T) as a rotation vector, the short way (via quaternions x, y, z, w)."""
    relative = quaternion_product(current, conjugate(desired))
    if relative[3] < 0:
        relative = -relative
    sin_half = np.linalg.norm(relative[:3])
    if sin_half < 1e-12:
        return 2 * relative[:3]
    return 2 * np.arctan2(sin_half, relative[3]) / sin_half * relative[:3]


def law(case):
    J, q, dq = case["jacobian"], case["q"], case["dq"]
    n = len(q)
    error = np.concatenate([case["p"] - case["p_d"], rotation_error(case["quat"], case["quat_d"])])
    R6 = np.kron(np.eye(2), rotation_matrix(case["quat"]))
    K = np.diag(case["stiffness"])
    D = np.diag(2 * case["zeta"] * np.sqrt(case["stiffness"]))
    # Stiffness frame: base, or the end effector (error and velocity rotated in, force out).
    S = R6 if case["stiffness_frame"] == "end_effector" else np.eye(6)
    force = S @ (-K @ S.T @ error - D @ S.T @ (J @ dq))
    tau_cartesian = J.T @ force
    k_ns = case["nullspace_stiffness"]
    tau_0 = -k_ns * (q - case["q_d"]) - 2 * case["zeta_ns"] * np.sqrt(k_ns) * dq
    lam = case["lambda"]
    if n >= 6:
        N = np.eye(n) - J.T @ np.linalg.solve(J @ J.T + lam**2 * np.eye(6), J)
    else:  # the same matrix (push-through identity), without the singular 6x6 J J^T at lambda 0
        N = np.eye(n) - np.linalg.solve(J.T @ J + lam**2 * np.eye(n), J.T @ J)
    W = R6 if case["wrench_frame"] == "end_effector" else np.eye(6)
    tau_wrench = J.T @ (W @ case["wrench"])
    return tau_cartesian, N @ tau_0, tau_wrench


def unit_quaternion(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def random_case(rng, n):
    p = rng.uniform(-1, 1, size=3)
    return {
        "jacobian": rng.uniform(-1, 1, size=(6, n)),
        "q": rng.uniform(-2, 2, size=n),
        "dq": rng.uniform(-1, 1, size=n),
        "p": p,
        "quat": unit_quaternion(rng),
        # near enough that the torque stays within the largest valid torque limit (1e4 Nm)
        "p_d": p + rng.uniform(-0.1, 0.1, size=3),
        "quat_d": unit_quaternion(rng),
        "stiffness": np.concatenate([rng.uniform(0, 2000, 3), rng.uniform(0, 200, 3)]),
        "zeta": rng.uniform(0.1, 2, size=6),
        "nullspace_stiffness": rng.uniform(0, 50, size=n),
        "zeta_ns": rng.uniform(0.1, 2),
        "q_d": rng.uniform(-2, 2, size=n),
        "lambda": rng.choice([0.0, rng.uniform(0.001, 0.5)]),
        "wrench": rng.uniform(-20, 20, size=6),
        "stiffness_frame": rng.choice(["base", "end_effector"]),
        "wrench_frame": rng.choice(["base", "end_effector"]),
    }


def wide_open_parameters(case):
    """Filters off and every limit far away, so the law alone shapes the torque."""
    # Every lower bound on the damping (if the library has any) off too.
    no_minimum_damping = {name: 0.0 for name in ci.Parameters().keys()
                          if name.startswith("minimum_damping.")}
    return ci.Parameters({
        **no_minimum_damping,
        "stiffness": {"translation": case["stiffness"][:3], "rotation": case["stiffness"][3:],
                      "frame": case["stiffness_frame"]},
        "damping_ratio": {"translation": case["zeta"][:3], "rotation": case["zeta"][3:]},
        "nullspace.stiffness": case["nullspace_stiffness"],
        "nullspace.damping_ratio": case["zeta_ns"],
        "nullspace.pseudo_inverse_damping": case["lambda"],
        "wrench": {"force": case["wrench"][:3], "torque": case["wrench"][3:],
                   "frame": case["wrench_frame"]},
        "filter": {name: {"time": 0.0} for name in ("pose", "stiffness", "nullspace", "wrench")},
        # the largest values the parameter table allows
        "limits.stiffness.translation.max": 1e5,
        "limits.stiffness.rotation.max": 1e4,
        "limits.damping_ratio.max": 10.0,
        "limits.nullspace_stiffness.max": 1e4,
        "limits.wrench.force": 1e4,
        "limits.wrench.torque": 1e3,
        "limits.pose_error.translation": 10.0,
        "limits.pose_error.rotation": math.pi,
        "limits.joint_torque": 1e4,
        "limits.joint_torque_rate": 1e6,
        # the law as written below: D = 2 zeta sqrt(K), no model
        "dynamics.inertia_shaped_damping": False,
    })


@pytest.mark.parametrize("n", [6, 7, 3])
def test_controller_matches_the_law_written_in_numpy(n):
    rng = np.random.default_rng(20240 + n)
    for _ in range(200):
        case = random_case(rng, n)
        controller = ci.CartesianImpedanceController(n, wide_open_parameters(case))
        robot = ci.RobotState(case["q"], case["dq"], (case["p"], case["quat"]), case["jacobian"])
        controller.start(robot)
        controller.set_reference_pose((case["p_d"], case["quat_d"]))
        controller.set_nullspace_target(case["q_d"])
        # 10 ms: the largest valid rate limit (1e6 Nm/s) then allows any change up to 1e4 Nm.
        assert controller.update(robot, 0.01) == ci.Status.ok
        tau_cartesian, tau_nullspace, tau_wrench = law(case)
        state = controller.state
        scale = max(1.0, np.abs(tau_cartesian).max())
        np.testing.assert_allclose(state.tau_cartesian, tau_cartesian, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(state.tau_nullspace, tau_nullspace, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(state.tau_wrench, tau_wrench, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(controller.torque, tau_cartesian + tau_nullspace + tau_wrench,
                                   rtol=0, atol=1e-10 * scale)
        assert not any(getattr(state.limits, name) for name in (
            "translation_error_clipped", "rotation_error_clipped", "joint_torque_saturated",
            "torque_rate_limited"))


def test_the_pose_error_is_reported_in_the_base_frame_with_quaternions_x_y_z_w():
    rng = np.random.default_rng(7)
    case = random_case(rng, 7)
    controller = ci.CartesianImpedanceController(7, wide_open_parameters(case))
    robot = ci.RobotState(case["q"], case["dq"], (case["p"], case["quat"]), case["jacobian"])
    controller.start(robot)
    # A 4x4 homogeneous transform is accepted wherever a pose is.
    T = np.eye(4)
    T[:3, :3] = rotation_matrix(case["quat_d"])
    T[:3, 3] = case["p_d"]
    controller.set_reference_pose(T)
    controller.update(robot, 0.001)
    expected = np.concatenate([case["p"] - case["p_d"],
                               rotation_error(case["quat"], case["quat_d"])])
    np.testing.assert_allclose(controller.state.pose_error, expected, atol=1e-12)
    target = controller.state.filtered.pose
    assert np.allclose(target.position, case["p_d"])
    # q and -q are the same rotation.
    assert np.allclose(target.orientation, case["quat_d"]) or np.allclose(
        target.orientation, -case["quat_d"])


def test_a_spring_of_stiffness_k_displaced_by_x_pushes_back_with_k_x():
    params = ci.Parameters({"filter.pose.time": 0, "nullspace.stiffness": 0,
                            "dynamics.inertia_shaped_damping": False})
    controller = ci.CartesianImpedanceController(6, params)
    robot = ci.RobotState(np.zeros(6), np.zeros(6), ([0.01, 0, 0], [0, 0, 0, 1]), np.eye(6))
    controller.start(robot)
    controller.set_reference_pose(([0, 0, 0], [0, 0, 0, 1]))
    controller.update(robot, 0.001)
    # 500 N/m x 10 mm = 5 N back toward the reference (the rate limit allows 1 N per ms).
    np.testing.assert_allclose(controller.state.tau_cartesian, [-5, 0, 0, 0, 0, 0], atol=1e-12)
