#!/usr/bin/python3
"""Scripted motion of a free rigid body under Cartesian impedance control (Python twin of
examples/scripted_motion.cpp; it prints the same table).

The "robot" is a body of 1 kg and 1 kg m^2 whose six joints are its translation and its rotation
about the base axes, so J = I and each joint torque is a component of the wrench on the body. Its
mass matrix M = I goes to the controller with the state, which makes zeta = 1 critical damping of
this body (D = 2 zeta sqrt(m K) with m = 1), so the numbers below can be checked by hand: a
spring of K N/m under F N settles at F/K.

Usage (from the build tree): PYTHONPATH=build/python /usr/bin/python3 \\
    examples/python/scripted_motion.py [--quiet]
"""

import math
import sys

import numpy as np

import cartesian_impedance as ci

DT = 0.001  # [s] 1 kHz
BODY_FRICTION = 5.0  # [N s/m], [Nm s/rad] viscous, like joint friction


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


def rotation_vector(quaternion):
    """Angle times axis of a unit quaternion x, y, z, w (as Eigen's AngleAxis computes them)."""
    vector, w = quaternion[:3], quaternion[3]
    norm = np.linalg.norm(vector)
    if norm == 0.0:
        return np.zeros(3)
    angle = 2.0 * math.atan2(norm, abs(w))
    return angle * (-vector if w < 0 else vector) / norm


class Body:
    def __init__(self):
        self.position = np.zeros(3)
        self.velocity = np.zeros(3)
        self.orientation = np.array([0.0, 0.0, 0.0, 1.0])  # x, y, z, w
        self.angular_velocity = np.zeros(3)
        self.robot = ci.make_robot_state(6)
        self.robot.jacobian = np.eye(6)
        self.robot.mass = np.eye(6)  # 1 kg, 1 kg m^2: what the damping ratio is relative to

    def state(self):
        robot = self.robot
        robot.q = np.concatenate([self.position, rotation_vector(self.orientation)])
        robot.dq = np.concatenate([self.velocity, self.angular_velocity])
        robot.pose = (self.position, self.orientation)
        return robot

    def step(self, wrench, dt):
        """Semi-implicit Euler with unit mass and inertia."""
        self.velocity += (wrench[:3] - BODY_FRICTION * self.velocity) * dt
        self.angular_velocity += (wrench[3:] - BODY_FRICTION * self.angular_velocity) * dt
        self.position += self.velocity * dt
        rotation = self.angular_velocity * dt
        angle = np.linalg.norm(rotation)
        if angle > 0.0:
            axis = rotation / angle
            turn = np.append(math.sin(angle / 2) * axis, math.cos(angle / 2))
            self.orientation = quaternion_product(turn, self.orientation)
        self.orientation = self.orientation / np.linalg.norm(self.orientation)


def main():
    quiet = len(sys.argv) > 1 and sys.argv[1] == "--quiet"

    parameters = ci.Parameters({
        "stiffness.translation": 500.0,  # N/m
        "stiffness.rotation": 50.0,  # Nm/rad
        "limits.joint_torque_rate": 200.0,  # N/s here, since J = I
    })
    controller = ci.CartesianImpedanceController(6, parameters)

    body = Body()
    controller.start(body.state())
    clock = {"time": 0.0, "max_rate": 0.0}
    external = np.zeros(6)

    def run(phase, duration):
        if not quiet:
            print("\n%s\n   t [s]    x [mm]    y [mm]    z [mm]   Fx [N]   Fy [N]   Fz [N]" % phase)
        steps = int(math.floor(duration / DT + 0.5))
        for k in range(steps):
            previous = controller.torque
            controller.update(body.state(), DT)
            tau = controller.torque
            clock["max_rate"] = max(clock["max_rate"], np.abs(tau - previous).max() / DT)
            body.step(tau + external, DT)
            clock["time"] += DT
            if not quiet and (k + 1) % 250 == 0:
                print("%8.3f %9.2f %9.2f %9.2f %8.2f %8.2f %8.2f" % (
                    clock["time"], 1e3 * body.position[0], 1e3 * body.position[1],
                    1e3 * body.position[2], tau[0], tau[1], tau[2]))

    rows = []

    # 1. Reference step of 10 cm: filtered, so the pull grows smoothly instead of jumping.
    controller.set_reference_pose(([0.1, 0.0, 0.0], body.orientation))
    run("1. reference step of 100 mm along x", 3.0)
    rows.append(("reference step to x = 100 mm", "100.00 mm", "%.2f mm" % (1e3 * body.position[0])))

    # 2. A 10 N push along y against 500 N/m settles at F / K = 20 mm.
    y0 = body.position[1]
    external[1] = 10.0
    run("2. push of 10 N along y at 500 N/m", 3.0)
    rows.append(("10 N push at 500 N/m", "20.00 mm", "%.2f mm" % (1e3 * (body.position[1] - y0))))

    # 3. Doubling the stiffness online halves the displacement under the same push.
    controller.set_stiffness([500, 1000, 500, 50, 50, 50])
    run("3. stiffness along y doubled to 1000 N/m, push continues", 3.0)
    rows.append(("same push at 1000 N/m", "10.00 mm", "%.2f mm" % (1e3 * (body.position[1] - y0))))
    external[:] = 0.0

    # 4. A commanded wrench of 5 N along z against 500 N/m moves the body by 10 mm.
    z0 = body.position[2]
    controller.set_wrench([0, 0, 5, 0, 0, 0])
    run("4. commanded force of 5 N along z", 3.0)
    rows.append(("commanded 5 N at 500 N/m", "10.00 mm",
                 "%.2f mm" % (1e3 * (body.position[2] - z0))))
    controller.set_wrench(np.zeros(6))

    # 5. Teaching: zero stiffness; a short push moves the body and it stays where it was left.
    controller.set_stiffness(np.zeros(6))
    run("5. zero stiffness (teaching mode): settle", 2.0)
    x_before = body.position[0]
    # With only viscous damping b acting (the body's friction plus the controller's minimum
    # damping, which keeps a soft arm from coasting), a push of F for T seconds moves the body by
    # F T / b in all.
    damping = BODY_FRICTION + parameters["minimum_damping.translation"]
    external[0] = 2.0
    run("   push 2 N along x for 0.3 s", 0.3)
    external[:] = 0.0
    run("   released", 3.0)
    x_moved = body.position[0] - x_before
    rows.append(("teaching: 2 N push for 0.3 s",
                 "%.1f mm, no spring back" % (1e3 * 2.0 * 0.3 / damping),
                 "%.1f mm, at rest (%.3f mm/s)" % (1e3 * x_moved, 1e3 * body.velocity[0])))

    rows.append(("largest torque rate", "<= 200.0 N/s", "%.1f N/s" % clock["max_rate"]))

    print("\n%-32s %-28s %s" % ("scenario", "theory", "measured"))
    for scenario, expected, measured in rows:
        print("%-32s %-28s %s" % (scenario, expected, measured))
    return 0


if __name__ == "__main__":
    sys.exit(main())
