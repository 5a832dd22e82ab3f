#!/usr/bin/python3
"""Writes a plausible serial arm as a URDF, deterministic for a seed (standard library only).

    generate_arm.py --seed 7 --out arm.urdf [--joints 5|6|7] [--info arm.json]

prints one line of JSON: the base and tip link names (for the demo's --base-link/--tip-link),
the joint count, the family and the arm's key numbers; --info writes the same with more detail.

The arm is laid out upright at q = 0 (z up, as the Panda and the iiwa are), in one of three
families of real arms:
  alternating  z y z y z y z (5, 6 or 7 joints): iiwa, Panda, Kinova Gen3, xArm7, YuMi-like;
               optional shoulder height between joints 1 and 2, elbow offsets (Panda: 0.0825 m),
               spherical or offset wrist (Panda: 0.088 m).
  ur           z y y y z y (6) or z y y y z (5): UR-like, parallel shoulder, elbow and wrist 1,
               shoulder and elbow offsets along the parallel axes, non-spherical wrist.
  industrial   z y y z y z (6) or z y y y z (5): KUKA KR, ABB, xArm6-like; shoulder and elbow
               offsets, a spherical wrist or an offset one (xArm6: 0.076 m).
Each link is an aluminium tube from its joint to the next (density 2700 kg/m^3, fill fraction
drawn 0.15-0.35: walls, covers and cables) plus the actuator of the next joint (a solid cylinder
around that joint's axis whose mass and radius grow with its torque); its inertia is the sum of
the shapes' own inertias about the link's centre of mass (parallel axis theorem). Efforts are
drawn as a margin over the worst static gravity load of the outboard links (sampled over the
joint ranges, with the joint's axis horizontal), clamped to the ranges of real joints; the
masses depend on the efforts (actuators), so the two are iterated to a fixed point and an arm
that misses a range is drawn again. See tests/arms/README.md.
"""

import argparse
import json
import math
import random
import sys

GRAVITY = 9.81  # [m/s^2]
ALUMINIUM_DENSITY = 2700.0  # [kg/m^3]

# Ranges of real arms (UR, Franka, KUKA, Kinova, xArm, ABB): [low, high].
EFFORT_RANGE = {"shoulder": (40.0, 330.0), "elbow": (30.0, 180.0), "wrist": (5.0, 40.0)}  # [Nm]
VELOCITY_RANGE = {"shoulder": (1.2, 2.2), "elbow": (1.5, 2.8), "wrist": (2.0, 3.2)}  # [rad/s]
REACH_RANGE = (0.5, 1.3)  # [m], shoulder (joint 2) to tool0 stretched out
TOTAL_MASS_RANGE = (5.0, 35.0)  # [kg], every link including the base
SEGMENT_RANGE = (0.05, 0.6)  # [m], distance between consecutive joints that are not coincident
HOLD_MARGIN = 1.3  # effort / worst static gravity load of the outboard links
WEAK_HOLD_MARGIN = 1.1  # the same for the wrists of a "weak" arm
JOINT_RANGE_TOLERANCE = 1e-9

X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


# ---- small 3-vector and 3x3-matrix algebra (row-major tuples of tuples) ----
def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def scale(a, s):
    return tuple(x * s for x in a)


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a):
    return math.sqrt(dot(a, a))


def matmul(a, b):
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3))
                 for i in range(3))


def matvec(a, v):
    return tuple(dot(row, v) for row in a)


def transpose(a):
    return tuple(tuple(a[j][i] for j in range(3)) for i in range(3))


def outer(a, b):
    return tuple(tuple(a[i] * b[j] for j in range(3)) for i in range(3))


def madd(a, b):
    return tuple(tuple(a[i][j] + b[i][j] for j in range(3)) for i in range(3))


def mscale(a, s):
    return tuple(tuple(a[i][j] * s for j in range(3)) for i in range(3))


IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def rotation(axis, angle):
    """Rodrigues: rotation by angle [rad] about the unit vector axis."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    return ((t * x * x + c, t * x * y - s * z, t * x * z + s * y),
            (t * x * y + s * z, t * y * y + c, t * y * z - s * x),
            (t * x * z - s * y, t * y * z + s * x, t * z * z + c))


def z_onto(direction):
    """A rotation that maps the z axis onto the unit vector direction."""
    d = scale(direction, 1.0 / norm(direction))
    axis = cross(Z, d)
    s = norm(axis)
    if s < 1e-12:
        return IDENTITY if d[2] > 0 else rotation(X, math.pi)
    return rotation(scale(axis, 1.0 / s), math.atan2(s, d[2]))


def rpy_of(r):
    """URDF roll-pitch-yaw of a rotation: r = Rz(yaw) Ry(pitch) Rx(roll)."""
    if abs(r[2][0]) < 1.0 - 1e-12:
        pitch = math.asin(-r[2][0])
        return (math.atan2(r[2][1], r[2][2]), pitch, math.atan2(r[1][0], r[0][0]))
    # Gimbal lock (pitch +-pi/2): roll and yaw turn about the same axis; put it all in yaw.
    pitch = math.copysign(math.pi / 2.0, -r[2][0])
    return (0.0, pitch, math.atan2(-r[0][1], r[1][1]))


def from_rpy(rpy):
    roll, pitch, yaw = rpy
    return matmul(rotation(Z, yaw), matmul(rotation(Y, pitch), rotation(X, roll)))


def snap(value):
    """Rounds away float dust so the file shows 0.3, not 0.30000000000000004 (10 digits), and 0,
    not 2e-16 (no length, mass or inertia of an arm is below 1e-12 in SI units)."""
    rounded = float("%.10g" % value)
    return 0.0 if abs(rounded) < 1e-12 else rounded


def text(values):
    return " ".join(repr(snap(v)) for v in values)


# ---- shapes: mass, centre of mass and inertia about it, in the world frame at q = 0 ----
class Body:
    """A rigid body as mass [kg], centre of mass [m] and inertia about it [kg m^2]."""

    def __init__(self, mass=0.0, com=(0.0, 0.0, 0.0), inertia=None):
        self.mass = mass
        self.com = com
        self.inertia = inertia if inertia is not None else mscale(IDENTITY, 0.0)

    def __add__(self, other):
        mass = self.mass + other.mass
        com = scale(add(scale(self.com, self.mass), scale(other.com, other.mass)), 1.0 / mass)
        inertia = mscale(IDENTITY, 0.0)
        for body in (self, other):
            d = sub(body.com, com)  # parallel axis theorem: I + m (|d|^2 1 - d d^T)
            shift = madd(mscale(IDENTITY, dot(d, d)), mscale(outer(d, d), -1.0))
            inertia = madd(inertia, madd(body.inertia, mscale(shift, body.mass)))
        return Body(mass, com, inertia)


def tube(start, end, radius, fill, density=ALUMINIUM_DENSITY):
    """A tube of outer radius [m] from start to end whose wall fills `fill` of its section."""
    axis = sub(end, start)
    length = norm(axis)
    u = scale(axis, 1.0 / length)
    inner_sq = radius * radius * (1.0 - fill)
    mass = density * math.pi * radius * radius * length * fill
    radial_sq = radius * radius + inner_sq
    axial = mass * radial_sq / 2.0
    transverse = mass * (3.0 * radial_sq + length * length) / 12.0
    inertia = madd(mscale(IDENTITY, transverse), mscale(outer(u, u), axial - transverse))
    return Body(mass, scale(add(start, end), 0.5), inertia)


def cylinder(centre, axis, radius, length, mass):
    """A solid cylinder of the given mass (an actuator, a flange, a base)."""
    axial = mass * radius * radius / 2.0
    transverse = mass * (3.0 * radius * radius + length * length) / 12.0
    inertia = madd(mscale(IDENTITY, transverse), mscale(outer(axis, axis), axial - transverse))
    return Body(mass, centre, inertia)


def actuator_mass(effort):
    """Motor + gear + brake + electronics [kg]: about 0.5 kg at 5 Nm, 1.2 kg at 40 Nm (Kinova
    Gen3's actuators), 2.7 kg at 150 Nm (UR size 3), 4.2 kg at 330 Nm."""
    return 0.15 + 0.12 * effort ** 0.6


def actuator_radius(effort):
    """Housing radius [m]: 0.032 at 5 Nm, 0.05 at 40 Nm, 0.077 at 150 Nm (UR: 0.06-0.075)."""
    return 0.022 + 0.0045 * math.sqrt(effort)


# ---- the layout of the three families (world frame at q = 0, z up) ----
def draw_layout(rng, family, joints):
    """Returns (axes, positions, flange, flange_direction, classes, roles) of the joints."""
    u = rng.uniform
    side = rng.choice((1.0, -1.0))  # mirror the lateral offsets
    if family == "alternating":
        pattern = [Z, Y, Z, Y, Z, Y, Z][:joints]
        height = u(0.1, 0.36)
        shoulder = 0.0 if rng.random() < 0.5 else u(0.05, 0.2)
        upper, fore = u(0.25, 0.5), u(0.2, 0.45)
        elbow = 0.0 if rng.random() < 0.5 else side * u(0.03, 0.09)
        wrist = 0.0 if rng.random() < 0.5 else u(0.05, 0.1)
        roll_at = u(0.35, 0.65)
        p1 = (0.0, 0.0, height)
        p2 = add(p1, (0.0, 0.0, shoulder))
        p3 = add(p2, (0.0, 0.0, upper * roll_at))
        p4 = add(p2, (elbow, 0.0, upper))
        p5 = add(p4, (-elbow, 0.0, fore * roll_at))
        p6 = add(p4, (-elbow, 0.0, fore))
        p7 = add(p6, (wrist, 0.0, 0.0 if wrist else u(0.05, 0.12)))
        positions = [p1, p2, p3, p4, p5, p6, p7][:joints]
        if joints == 5:  # the last joint is the forearm's roll: the flange ends the forearm
            positions[4] = add(p4, (-elbow, 0.0, fore * roll_at))
            flange = add(p4, (-elbow, 0.0, fore + u(0.05, 0.12)))
        elif joints == 6:
            flange = add(p6, (0.0, 0.0, u(0.08, 0.15)))
        else:
            flange = add(p7, (0.0, 0.0, u(0.05, 0.12)))
        classes = ["shoulder", "shoulder", "elbow", "elbow", "wrist", "wrist", "wrist"][:joints]
        roles = ["base", "pitch", "roll", "elbow", "roll", "pitch", "roll"][:joints]
    elif family == "ur":
        pattern = [Z, Y, Y, Y, Z, Y][:joints]
        base = u(0.09, 0.2)
        shoulder_offset = side * u(0.1, 0.18)
        elbow_offset = -side * u(0.0, 0.13)
        upper, fore = u(0.24, 0.6), u(0.21, 0.57)
        wrist1 = side * u(0.08, 0.14)
        wrist2, wrist3 = u(0.08, 0.12), u(0.06, 0.12)
        p1 = (0.0, 0.0, base)
        p2 = add(p1, (0.0, shoulder_offset, 0.0))
        p3 = add(p2, (0.0, elbow_offset, upper))
        p4 = add(p3, (0.0, 0.0, fore))
        p5 = add(p4, (0.0, wrist1, 0.0))
        p6 = add(p5, (0.0, 0.0, wrist2))
        positions = [p1, p2, p3, p4, p5, p6][:joints]
        flange = add(p6, (0.0, side * wrist3, 0.0)) if joints == 6 else add(p5, (0.0, 0.0, wrist2))
        classes = ["shoulder", "shoulder", "elbow", "wrist", "wrist", "wrist"][:joints]
        roles = ["base", "pitch", "elbow", "pitch", "roll", "pitch"][:joints]
    else:  # industrial
        height = u(0.15, 0.4)
        shoulder_offset = 0.0 if rng.random() < 0.4 else u(0.05, 0.15)
        elbow_offset = 0.0 if rng.random() < 0.4 else u(0.05, 0.12)
        upper, fore = u(0.25, 0.6), u(0.2, 0.5)
        p1 = (0.0, 0.0, height)
        p2 = add(p1, (shoulder_offset, 0.0, 0.0 if rng.random() < 0.5 else u(0.05, 0.1)))
        p3 = add(p2, (0.0, 0.0, upper))
        if joints == 5:  # z y y y z
            pattern = [Z, Y, Y, Y, Z]
            p4 = add(p3, (elbow_offset, 0.0, fore))
            p5 = add(p4, (0.0, 0.0, u(0.05, 0.1)))
            positions = [p1, p2, p3, p4, p5]
            flange = add(p5, (0.0, 0.0, u(0.05, 0.12)))
            classes = ["shoulder", "shoulder", "elbow", "wrist", "wrist"]
            roles = ["base", "pitch", "elbow", "pitch", "roll"]
        else:  # z y y z y z
            pattern = [Z, Y, Y, Z, Y, Z]
            p4 = add(p3, (elbow_offset, 0.0, u(0.05, 0.15)))
            p5 = add(p3, (elbow_offset, 0.0, fore))
            spherical = rng.random() < 0.5
            p6 = p5 if spherical else add(p5, (u(0.05, 0.09), 0.0, u(0.05, 0.1)))
            positions = [p1, p2, p3, p4, p5, p6]
            flange = add(p6, (0.0, 0.0, u(0.06, 0.12)))
            classes = ["shoulder", "shoulder", "elbow", "wrist", "wrist", "wrist"]
            roles = ["base", "pitch", "elbow", "roll", "pitch", "roll"]
    return pattern, positions, flange, classes, roles


def draw_limits(rng, role, family):
    """Joint range [rad] like real arms': +-2 pi (UR), +-170 deg (KUKA), one-sided elbows
    (Panda: -3.07..-0.07), +-120 deg shoulders and wrist pitches."""
    two_pi = 2.0 * math.pi
    if family == "ur" and rng.random() < 0.8:
        return (-two_pi, two_pi)
    deg = math.radians
    if role == "base":
        half = rng.choice((two_pi, deg(170), deg(166), deg(185)))
    elif role == "pitch":
        half = rng.choice((deg(120), deg(101), deg(128), deg(135), two_pi))
    elif role == "roll":
        half = rng.choice((deg(170), deg(166), deg(175), two_pi))
    else:  # elbow
        if rng.random() < 0.2:
            inner = rng.uniform(0.05, 0.15)
            outer = rng.uniform(2.6, 3.07)
            return (-outer, -inner) if rng.random() < 0.5 else (inner, outer)
        half = rng.choice((deg(150), deg(170), deg(120), two_pi))
    return (-half, half)


def chain_transforms(axes, positions, q):
    """Product of exponentials: (rotation, translation) of each moving link at q, from its pose at
    q = 0 in the world frame (joint k turns everything outboard about its axis through p_k)."""
    rot, trans = IDENTITY, (0.0, 0.0, 0.0)
    result = []
    for axis, p, angle in zip(axes, positions, q):
        r = rotation(axis, angle)
        # g_k = (r, p - r p): rotation about the line through p
        step_trans = sub(p, matvec(r, p))
        trans = add(matvec(rot, step_trans), trans)
        rot = matmul(rot, r)
        result.append((rot, trans))
    return result


def sampled_poses(rng, axes, positions, limits, samples=400):
    """The moving links' poses at q = 0 (stretched) and at `samples` configurations drawn in the
    joint ranges, with each joint's axis and origin there (world frame)."""
    n = len(axes)
    configurations = [[0.0] * n] + [[rng.uniform(lo, hi) for lo, hi in limits]
                                    for _ in range(samples)]
    result = []
    for q in configurations:
        poses = chain_transforms(axes, positions, q)
        joint_axes = [matvec(r, a) for (r, _), a in zip(poses, axes)]
        origins = [add(matvec(r, p), t) for (r, t), p in zip(poses, positions)]
        result.append((poses, joint_axes, origins))
    return result


def worst_gravity_loads(poses_sampled, links):
    """Worst static gravity torque [Nm] of each joint from the links outboard of it, over the
    sampled configurations, with the joint's axis horizontal and gravity perpendicular to it in
    the worst direction: g |a x sum m_j (c_j - p_i)|. Joint 1 turns about the vertical: none."""
    n = len(links)
    loads = [0.0] * n
    for poses, joint_axes, origins in poses_sampled:
        # sum_j m_j c_j and sum_j m_j of the links outboard of each joint
        weighted = [scale(add(matvec(r, link.com), t), link.mass)
                    for (r, t), link in zip(poses, links)]
        first_moment, mass = (0.0, 0.0, 0.0), 0.0
        for i in range(n - 1, 0, -1):
            first_moment = add(first_moment, weighted[i])
            mass += links[i].mass
            moment = sub(first_moment, scale(origins[i], mass))
            loads[i] = max(loads[i], GRAVITY * norm(cross(joint_axes[i], moment)))
    return loads


class Rejected(Exception):
    pass


def draw_arm(rng, joints):
    family = rng.choice(("alternating", "alternating", "ur", "industrial")) if joints != 7 \
        else "alternating"
    axes, positions, flange, classes, roles = draw_layout(rng, family, joints)
    axes = [tuple(a) for a in axes]
    ends = positions[1:] + [flange]
    for start, end in zip(positions, ends):
        length = norm(sub(end, start))
        if length > 1e-12 and not SEGMENT_RANGE[0] - 1e-9 <= length <= SEGMENT_RANGE[1]:
            raise Rejected("segment of %.3f m" % length)
    reach = sum(norm(sub(e, s)) for s, e in zip(positions[1:], ends[1:]))
    tool_offset = rng.uniform(0.0, 0.03)
    reach += tool_offset
    if not REACH_RANGE[0] <= reach <= REACH_RANGE[1]:
        raise Rejected("reach %.3f m" % reach)
    limits = [draw_limits(rng, role, family) for role in roles]
    weak = rng.random() < 0.25
    fill = rng.uniform(0.15, 0.35)
    margins = [rng.uniform(1.3, 2.0) for _ in range(joints)]
    # Real arms are sized for a rated payload at full reach (UR3 3 kg at 0.5 m, UR10 10 kg at
    # 1.3 m, Panda 3 kg, Gen3 4 kg, iiwa14 14 kg at 0.8 m): their drives, hence their actuators'
    # masses, carry it on top of the arm's own weight.
    payload = min(14.0, max(1.0, rng.uniform(3.0, 10.0) * reach))
    payload_loads = [0.0] + [payload * GRAVITY * norm(sub(flange, p)) for p in positions[1:]]
    efforts = [rng.uniform(*EFFORT_RANGE[c]) for c in classes]  # first guess
    flange_direction = scale(sub(flange, positions[-1]), 1.0 / norm(sub(flange, positions[-1])))
    flange_radius = 0.0
    poses_sampled = sampled_poses(random.Random(1), axes, positions, limits)
    for _ in range(30):
        radii = [actuator_radius(e) for e in efforts]
        links = []
        for i in range(joints):
            start, end = positions[i], ends[i]
            radius = 0.8 * (min(radii[i], radii[i + 1]) if i + 1 < joints else radii[i])
            body = Body()
            if norm(sub(end, start)) > 1e-12:
                body = tube(start, end, radius, fill)
            if i + 1 < joints:  # the actuator of the next joint sits in this link
                a = radii[i + 1]
                body = body + cylinder(end, axes[i + 1], a, 1.6 * a, actuator_mass(efforts[i + 1]))
            else:  # the flange plate
                flange_radius = radius
                plate_mass = ALUMINIUM_DENSITY * math.pi * radius * radius * 0.01
                body = body + cylinder(sub(flange, scale(flange_direction, 0.005)),
                                       flange_direction, radius, 0.01, plate_mass)
            links.append(body)
        loads = worst_gravity_loads(poses_sampled, links)
        # Joint 1 turns about the vertical and holds no weight; real arms give it a drive like the
        # shoulder's (UR, Panda, iiwa: the same), for the accelerations it must give.
        # A weak arm's wrists are sized for their own load only, 1.1x.
        sized_for = [load + payload_load for load, payload_load in zip(loads, payload_loads)]
        sized_for[0] = 0.8 * sized_for[1]
        new_efforts = []
        for i, c in enumerate(classes):
            lo, hi = EFFORT_RANGE[c]
            if weak and c == "wrist":
                new_efforts.append(min(hi, max(lo, WEAK_HOLD_MARGIN * loads[i])))
            else:
                new_efforts.append(min(hi, max(lo, margins[i] * sized_for[i])))
        if max(abs(a - b) for a, b in zip(new_efforts, efforts)) < 1e-6:
            break
        efforts = new_efforts
    else:
        raise Rejected("efforts do not converge")
    for i, c in enumerate(classes):
        needed = (WEAK_HOLD_MARGIN if weak and c == "wrist" else HOLD_MARGIN) * loads[i]
        if efforts[i] < needed - 1e-9:
            raise Rejected("joint %d cannot hold its outboard links" % (i + 1))
    base_radius = 1.2 * actuator_radius(efforts[0])
    base = cylinder((0.0, 0.0, positions[0][2] / 2.0), Z, base_radius, positions[0][2],
                    ALUMINIUM_DENSITY * math.pi * base_radius ** 2 * positions[0][2] * 0.2)
    base = base + cylinder(positions[0], Z, actuator_radius(efforts[0]),
                           1.6 * actuator_radius(efforts[0]), actuator_mass(efforts[0]))
    total = base.mass + sum(link.mass for link in links)
    if not TOTAL_MASS_RANGE[0] <= total <= TOTAL_MASS_RANGE[1]:
        raise Rejected("total mass %.1f kg" % total)
    velocities = []
    for c in classes:
        lo, hi = VELOCITY_RANGE[c]
        velocities.append(rng.uniform(lo, hi))
    damping = [rng.uniform(0.02, 0.08) * math.sqrt(e) for e in efforts]
    # Coulomb friction as the shipped models have it (0.05-0.2 Nm): small beside a real arm's
    # (several Nm on a big joint, mostly compensated by its firmware).
    friction = [rng.uniform(0.003, 0.01) * e ** 0.7 for e in efforts]
    return dict(family=family, axes=axes, positions=positions, ends=ends, flange=flange,
                flange_direction=flange_direction, flange_radius=flange_radius, classes=classes,
                limits=limits, weak=weak, fill=fill, efforts=efforts, velocities=velocities,
                damping=damping, friction=friction, links=links, base=base, loads=loads,
                reach=reach, total_mass=total, payload=payload, tool_offset=tool_offset,
                radii=[actuator_radius(e) for e in efforts])


def draw_frames(rng, arm):
    """World orientation of each link frame at q = 0: all aligned with the base (iiwa-style
    URDFs), the joint axis as each frame's z (DH-style: UR, Panda), or a mix, each turned about
    its joint axis by a multiple of 90 deg. The arm is the same; its URDF is written differently."""
    style = rng.choice(("aligned", "z-axis", "mixed"))
    frames = []
    for axis in arm["axes"]:
        if style == "aligned" or (style == "mixed" and rng.random() < 0.5):
            frames.append(IDENTITY)
        else:
            twist = rotation(axis, rng.choice((0, 1, 2, 3)) * math.pi / 2.0)
            frames.append(matmul(twist, z_onto(axis)))
    return style, frames


def link_xml(name, body_world, rotation_world, origin_world, shapes, indent="  "):
    """<link> with its inertial and shapes expressed in a frame at origin_world turned by
    rotation_world (world frame at q = 0)."""
    rt = transpose(rotation_world)
    com = matvec(rt, sub(body_world.com, origin_world))
    inertia = matmul(rt, matmul(body_world.inertia, rotation_world))
    lines = ['%s<link name="%s">' % (indent, name),
             '%s  <inertial>' % indent,
             '%s    <origin xyz="%s" rpy="0 0 0"/>' % (indent, text(com)),
             '%s    <mass value="%s"/>' % (indent, text([body_world.mass])),
             '%s    <inertia ixx="%s" ixy="%s" ixz="%s" iyy="%s" iyz="%s" izz="%s"/>'
             % ((indent,) + tuple(text([v]) for v in (inertia[0][0], inertia[0][1], inertia[0][2],
                                                    inertia[1][1], inertia[1][2], inertia[2][2]))),
             '%s  </inertial>' % indent]
    for kind in ("visual", "collision"):
        for centre, direction, radius, length in shapes:
            local_centre = matvec(rt, sub(centre, origin_world))
            local_rpy = rpy_of(z_onto(matvec(rt, direction)))
            lines += ['%s  <%s>' % (indent, kind),
                      '%s    <origin xyz="%s" rpy="%s"/>' % (indent, text(local_centre),
                                                             text(local_rpy)),
                      '%s    <geometry><cylinder radius="%s" length="%s"/></geometry>'
                      % (indent, text([radius]), text([length])),
                      '%s  </%s>' % (indent, kind)]
    lines.append('%s</link>' % indent)
    return lines


def generate(seed, joints=None):
    """Returns (urdf_text, info) of the arm drawn from seed; joints None draws 5, 6 or 7."""
    rng = random.Random("cartesian_impedance arm %d" % seed)
    # Drawn always: --joints N of a seed that draws N is that seed's arm.
    drawn = rng.choice((5, 6, 6, 7, 7))
    if joints is None:
        joints = drawn
    if joints not in (5, 6, 7):
        raise ValueError("joints must be 5, 6 or 7, not %r" % joints)
    for attempt in range(1000):
        try:
            arm = draw_arm(rng, joints)
            break
        except Rejected:
            continue
    else:
        raise RuntimeError("seed %d: no plausible arm in 1000 draws" % seed)
    style, frames = draw_frames(rng, arm)
    name = "generated_arm_seed_%d" % seed
    n = joints
    positions, axes = arm["positions"], arm["axes"]
    out = ['<?xml version="1.0"?>',
           '<!-- A plausible %d-joint serial arm drawn by tests/arms/generate_arm.py'
           ' (seed %d, joints %d)' % (n, seed, n),
           '     family %s, link frames %s, reach %.3f m, mass %.2f kg%s.' % (
               arm["family"], style, arm["reach"], arm["total_mass"],
               ", weak wrist (holds %.1fx its own load)" % WEAK_HOLD_MARGIN if arm["weak"] else ""),
           '     Not a real robot: for testing the controller on arms nobody tuned. -->',
           '<robot name="%s">' % name]
    base_shapes = [((0.0, 0.0, positions[0][2] / 2.0), Z, 1.2 * arm["radii"][0], positions[0][2]),
                   (positions[0], axes[0], arm["radii"][0], 1.6 * arm["radii"][0])]
    out += link_xml("base_link", arm["base"], IDENTITY, (0.0, 0.0, 0.0), base_shapes)
    previous_rotation, previous_origin = IDENTITY, (0.0, 0.0, 0.0)
    for i in range(n):
        link_name = "link_%d" % (i + 1)
        parent = "base_link" if i == 0 else "link_%d" % i
        r, p = frames[i], positions[i]
        rel_rotation = matmul(transpose(previous_rotation), r)
        rel_origin = matvec(transpose(previous_rotation), sub(p, previous_origin))
        lo, hi = arm["limits"][i]
        out += ['  <joint name="joint_%d" type="revolute">' % (i + 1),
                '    <parent link="%s"/>' % parent,
                '    <child link="%s"/>' % link_name,
                '    <origin xyz="%s" rpy="%s"/>' % (text(rel_origin), text(rpy_of(rel_rotation))),
                '    <axis xyz="%s"/>' % text(matvec(transpose(r), axes[i])),
                '    <limit lower="%s" upper="%s" effort="%s" velocity="%s"/>' % (
                    text([lo]), text([hi]), text([arm["efforts"][i]]),
                    text([arm["velocities"][i]])),
                '    <dynamics damping="%s" friction="%s"/>' % (
                    text([arm["damping"][i]]), text([arm["friction"][i]])),
                '  </joint>']
        start, end = p, arm["ends"][i]
        shapes = []
        length = norm(sub(end, start))
        radius = 0.8 * (min(arm["radii"][i], arm["radii"][i + 1]) if i + 1 < n
                        else arm["radii"][i])
        if length > 1e-12:
            shapes.append((scale(add(start, end), 0.5), scale(sub(end, start), 1.0 / length),
                           radius, length))
        if i + 1 < n:
            a = arm["radii"][i + 1]
            shapes.append((end, axes[i + 1], a, 1.6 * a))
        else:
            shapes.append((sub(arm["flange"], scale(arm["flange_direction"], 0.005)),
                           arm["flange_direction"], arm["flange_radius"], 0.01))
        out += link_xml(link_name, arm["links"][i], r, p, shapes)
        previous_rotation, previous_origin = r, p
    # tool0: a small adapter on the flange, turned about the flange axis like a real tool frame.
    tool_turn = rng.choice((0.0, math.pi / 4.0, -math.pi / 4.0, math.pi / 2.0, math.pi))
    tool_rotation = matmul(rotation(arm["flange_direction"], tool_turn),
                           z_onto(arm["flange_direction"]))
    tool_origin = add(arm["flange"], scale(arm["flange_direction"], arm["tool_offset"]))
    adapter_length = max(arm["tool_offset"], 0.004)
    adapter_radius = 0.6 * arm["flange_radius"]
    adapter_mass = ALUMINIUM_DENSITY * math.pi * adapter_radius ** 2 * adapter_length * 0.5
    adapter_centre = sub(tool_origin, scale(arm["flange_direction"], adapter_length / 2.0))
    adapter = cylinder(adapter_centre, arm["flange_direction"], adapter_radius, adapter_length,
                       adapter_mass)
    rel_rotation = matmul(transpose(previous_rotation), tool_rotation)
    rel_origin = matvec(transpose(previous_rotation), sub(tool_origin, previous_origin))
    out += ['  <joint name="tool0_joint" type="fixed">',
            '    <parent link="link_%d"/>' % n,
            '    <child link="tool0"/>',
            '    <origin xyz="%s" rpy="%s"/>' % (text(rel_origin), text(rpy_of(rel_rotation))),
            '  </joint>']
    out += link_xml("tool0", adapter, tool_rotation, tool_origin,
                    [(adapter_centre, arm["flange_direction"], adapter_radius, adapter_length)])
    out.append('</robot>')
    total_mass = arm["total_mass"] + adapter_mass
    info = {
        "seed": seed, "joints": n, "family": arm["family"], "frames": style,
        "base_link": "base_link", "tip_link": "tool0", "weak_wrist": arm["weak"],
        "reach": round(arm["reach"], 4), "rated_payload": round(arm["payload"], 2),
        "total_mass": round(total_mass, 3),
        "efforts": [round(e, 3) for e in arm["efforts"]],
        "gravity_loads": [round(v, 3) for v in arm["loads"]],
        "velocities": [round(v, 3) for v in arm["velocities"]],
        "joint_classes": arm["classes"],
        "limits": [[round(lo, 4), round(hi, 4)] for lo, hi in arm["limits"]],
    }
    return "\n".join(out) + "\n", info


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, required=True, help="the arm's seed (any integer)")
    parser.add_argument("--joints", type=int, choices=(5, 6, 7),
                        help="number of revolute joints (default: drawn from the seed)")
    parser.add_argument("--out", required=True, help="URDF file to write")
    parser.add_argument("--info", help="also write the arm's numbers as JSON to this file")
    args = parser.parse_args(argv)
    urdf, info = generate(args.seed, args.joints)
    with open(args.out, "w") as f:
        f.write(urdf)
    if args.info:
        with open(args.info, "w") as f:
            json.dump(info, f, indent=1)
            f.write("\n")
    summary = {k: info[k] for k in ("base_link", "tip_link", "joints", "family", "weak_wrist",
                                    "reach", "total_mass")}
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
