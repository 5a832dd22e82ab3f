#!/usr/bin/python3
"""Writes a robot description package as vendors ship them, from an arm of generate_arm.py.

    make_description.py --seed 3 --joints 6 --package acme_arm_description --arm acme6 --out DIR

The package (DIR/<package>/) has what real description packages (franka_description,
ur_description, iiwa_description) have: package.xml, CMakeLists.txt, urdf/<arm>.urdf whose
visual and collision geometry are meshes named by package://<package>/meshes/... URIs (visual
OBJ with a .mtl, collision STL and OBJ), a root link `world` with a fixed joint, <transmission>
and <gazebo> tags, and no <dynamics> (no friction, no damping). Each cylinder of the generated
arm becomes a 24-sided prism, so the masses and the kinematics are the generator's own.
The committed copies in tests/vendor/ were written by this script (standard library only);
tests/vendor/CATKIN_IGNORE and COLCON_IGNORE keep a ROS workspace that holds this repository
from building them as packages.
"""

import argparse
import math
import os
import struct
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

HERE = os.path.dirname(os.path.abspath(__file__))
SIDES = 24


def rotation(rpy):
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y),
                              math.sin(y))
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]


def prism(radius, length, origin):
    """Vertices and triangles (outward) of a cylinder around z placed at origin (xyz, rpy)."""
    xyz, rpy = origin
    rot = rotation(rpy)
    local = []
    for z in (-0.5 * length, 0.5 * length):
        for k in range(SIDES):
            a = 2.0 * math.pi * k / SIDES
            local.append((radius * math.cos(a), radius * math.sin(a), z))
    local += [(0.0, 0.0, -0.5 * length), (0.0, 0.0, 0.5 * length)]
    vertices = [tuple(sum(rot[i][j] * v[j] for j in range(3)) + xyz[i] for i in range(3))
                for v in local]
    bottom, top = 2 * SIDES, 2 * SIDES + 1
    triangles = []
    for k in range(SIDES):
        n = (k + 1) % SIDES
        triangles += [(k, n, SIDES + n), (k, SIDES + n, SIDES + k),
                      (bottom, n, k), (top, SIDES + k, SIDES + n)]
    return vertices, triangles


def normal(a, b, c):
    u = [b[i] - a[i] for i in range(3)]
    v = [c[i] - a[i] for i in range(3)]
    n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    length = math.sqrt(sum(x * x for x in n)) or 1.0
    return [x / length for x in n]


def write_stl(path, name, vertices, triangles):
    with open(path, "wb") as f:
        f.write(("binary STL " + name).encode().ljust(80, b" "))
        f.write(struct.pack("<I", len(triangles)))
        for t in triangles:
            corners = [vertices[i] for i in t]
            f.write(struct.pack("<3f", *normal(*corners)))
            for c in corners:
                f.write(struct.pack("<3f", *c))
            f.write(b"\0\0")


def write_obj(path, name, vertices, triangles, material):
    with open(path, "w") as f:
        if material:
            f.write("mtllib %s.mtl\nusemtl %s\n" % (name, material))
        f.write("o %s\n" % name)
        for v in vertices:
            f.write("v %.6f %.6f %.6f\n" % v)
        for t in triangles:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))
    if material:
        with open(os.path.join(os.path.dirname(path), name + ".mtl"), "w") as f:
            f.write("newmtl %s\nKd 0.85 0.55 0.1\n" % material)


def floats(text, default):
    return tuple(float(x) for x in text.split()) if text else default


def make(seed, joints, package, arm, out):
    urdf = subprocess.run([sys.executable, os.path.join(HERE, "..", "arms", "generate_arm.py"),
                           "--seed", str(seed), "--joints", str(joints), "--out", "/dev/stdout"],
                          check=True, capture_output=True, text=True).stdout
    urdf = urdf[urdf.index("<?xml"):]
    robot = ElementTree.fromstring(urdf[urdf.index("<robot"):urdf.index("</robot>") + 8])
    root = os.path.join(out, package)
    for folder in ("urdf", "meshes/visual", "meshes/collision", "launch"):
        os.makedirs(os.path.join(root, folder), exist_ok=True)
    counter = 0
    for link in robot.findall("link"):
        for kind in ("visual", "collision"):
            for index, element in enumerate(link.findall(kind)):
                geometry = element.find("geometry")
                cylinder = geometry.find("cylinder")
                if cylinder is None:
                    continue
                origin = element.find("origin")
                placed = ((floats(origin.get("xyz"), (0, 0, 0)), floats(origin.get("rpy"), (0, 0, 0)))
                          if origin is not None else ((0, 0, 0), (0, 0, 0)))
                vertices, triangles = prism(float(cylinder.get("radius")),
                                            float(cylinder.get("length")), placed)
                if origin is not None:
                    element.remove(origin)  # the mesh carries the placement, as exported ones do
                name = "%s_%d" % (link.get("name"), index)
                if kind == "visual":
                    file = "meshes/visual/%s.obj" % name
                    write_obj(os.path.join(root, file), name, vertices, triangles, "acme_orange")
                else:
                    # Collision meshes alternate between STL and OBJ (franka_description ships OBJ).
                    counter += 1
                    ext = "obj" if counter % 2 == 0 else "stl"
                    file = "meshes/collision/%s.%s" % (name, ext)
                    if ext == "stl":
                        write_stl(os.path.join(root, file), name, vertices, triangles)
                    else:
                        write_obj(os.path.join(root, file), name, vertices, triangles, None)
                geometry.remove(cylinder)
                ElementTree.SubElement(geometry, "mesh",
                                       filename="package://%s/%s" % (package, file))
    for joint in robot.findall("joint"):
        for dynamics in joint.findall("dynamics"):
            joint.remove(dynamics)
    base = robot.find("link").get("name")
    world = ElementTree.Element("link", name="world")
    fixed = ElementTree.Element("joint", name="world_joint", type="fixed")
    ElementTree.SubElement(fixed, "parent", link="world")
    ElementTree.SubElement(fixed, "child", link=base)
    ElementTree.SubElement(fixed, "origin", xyz="0 0 0", rpy="0 0 0")
    robot.insert(0, fixed)
    robot.insert(0, world)
    robot.set("name", arm)
    for joint in robot.findall("joint"):
        if joint.get("type") == "fixed":
            continue
        transmission = ElementTree.SubElement(robot, "transmission",
                                              name=joint.get("name") + "_transmission")
        ElementTree.SubElement(transmission, "type").text = \
            "transmission_interface/SimpleTransmission"
        j = ElementTree.SubElement(transmission, "joint", name=joint.get("name"))
        ElementTree.SubElement(j, "hardwareInterface").text = \
            "hardware_interface/EffortJointInterface"
        actuator = ElementTree.SubElement(transmission, "actuator",
                                          name=joint.get("name") + "_motor")
        ElementTree.SubElement(actuator, "mechanicalReduction").text = "1"
    for link in robot.findall("link"):
        gazebo = ElementTree.SubElement(robot, "gazebo", reference=link.get("name"))
        ElementTree.SubElement(gazebo, "material").text = "Gazebo/Orange"
        ElementTree.SubElement(gazebo, "selfCollide").text = "false"
    gazebo = ElementTree.SubElement(robot, "gazebo")
    plugin = ElementTree.SubElement(gazebo, "plugin", name="gazebo_ros_control",
                                    filename="libgazebo_ros_control.so")
    ElementTree.SubElement(plugin, "robotNamespace").text = "/" + arm
    ElementTree.indent(robot)
    with open(os.path.join(root, "urdf", arm + ".urdf"), "w") as f:
        f.write('<?xml version="1.0"?>\n<!-- %s: written by tests/vendor/make_description.py '
                '(seed %d, %d joints) as a vendor would ship it. Not a real robot. -->\n'
                % (arm, seed, joints))
        f.write(ElementTree.tostring(robot, encoding="unicode") + "\n")
    with open(os.path.join(root, "package.xml"), "w") as f:
        f.write('<?xml version="1.0"?>\n<package format="2">\n  <name>%s</name>\n'
                '  <version>1.2.0</version>\n  <description>URDF and meshes of the %s arm'
                '</description>\n  <maintainer email="support@acme-robots.example">ACME'
                '</maintainer>\n  <license>BSD</license>\n'
                '  <buildtool_depend>catkin</buildtool_depend>\n'
                '  <exec_depend>xacro</exec_depend>\n  <exec_depend>robot_state_publisher'
                '</exec_depend>\n</package>\n' % (package, arm))
    with open(os.path.join(root, "CMakeLists.txt"), "w") as f:
        f.write("cmake_minimum_required(VERSION 3.0.2)\nproject(%s)\nfind_package(catkin REQUIRED)"
                "\ncatkin_package()\ninstall(DIRECTORY launch meshes urdf\n"
                "  DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})\n" % package)
    with open(os.path.join(root, "launch", "display.launch"), "w") as f:
        f.write('<launch>\n  <param name="robot_description" textfile="$(find %s)/urdf/%s.urdf"/>'
                '\n  <node name="robot_state_publisher" pkg="robot_state_publisher" '
                'type="robot_state_publisher"/>\n</launch>\n' % (package, arm))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--joints", type=int, required=True)
    parser.add_argument("--package", required=True)
    parser.add_argument("--arm", required=True)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    make(args.seed, args.joints, args.package, args.arm, args.out)


if __name__ == "__main__":
    main()
