#!/usr/bin/python3
"""Writes a robot description package as vendors ship them, from an arm of generate_arm.py.

    make_description.py --seed 3 --joints 6 --package acme_arm_description --arm acme6 --out DIR
    make_description.py --style beta --seed 5 --joints 7 --package beta_description --arm beta7 ...
    make_description.py --style gamma --seed 8 --joints 6 --package gamma_robot --arm gamma6 ...

The package (DIR/<package>/) has what real description packages (franka_description,
ur_description, iiwa_description) have: package.xml, CMakeLists.txt, urdf/<arm>.urdf whose
visual and collision geometry are meshes named by package://<package>/meshes/... URIs (visual
OBJ with a .mtl, collision STL and OBJ), a root link `world` with a fixed joint, <transmission>
and <gazebo> tags, and no <dynamics> (no friction, no damping). Each cylinder of the generated
arm becomes a 24-sided prism, so the masses and the kinematics are the generator's own.
Styles (each is what a family of published packages does):
  acme   as above.
  beta   a 7-joint arm with a hand (franka_description, kinova): visual meshes in COLLADA in
         millimetres (<unit meter="0.001">), collision STL; a hand with two prismatic fingers, one
         a <mimic> of the other; <safety_controller>, <calibration>, a <ros2_control> block,
         <material> colours at the robot level; and one link whose published principal moments
         break the triangle inequality (A + B < C), as CAD exports sometimes do.
  gamma  a SolidWorks-exporter package (sw_urdf_exporter; many arms from smaller vendors): no
         `world` link, meshes named <LINK>.STL in capitals with collision meshes in COLLADA,
         inertial frames rotated (rpy), and mesh URIs relative to the URDF (../meshes/...).
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


def write_dae(path, name, vertices, triangles, unit):
    """COLLADA 1.4.1 with one triangle mesh, its coordinates written in `unit` metres."""
    scale = 1.0 / unit
    positions = " ".join("%.6f" % (c * scale) for v in vertices for c in v)
    indices = " ".join("%d" % i for t in triangles for i in t)
    with open(path, "w") as f:
        f.write('''<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset>
    <contributor><authoring_tool>make_description.py</authoring_tool></contributor>
    <unit name="%s" meter="%g"/>
    <up_axis>Z_UP</up_axis>
  </asset>
  <library_geometries>
    <geometry id="%s-mesh" name="%s">
      <mesh>
        <source id="%s-positions">
          <float_array id="%s-positions-array" count="%d">%s</float_array>
          <technique_common>
            <accessor source="#%s-positions-array" count="%d" stride="3">
              <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
            </accessor>
          </technique_common>
        </source>
        <vertices id="%s-vertices"><input semantic="POSITION" source="#%s-positions"/></vertices>
        <triangles count="%d">
          <input semantic="VERTEX" source="#%s-vertices" offset="0"/>
          <p>%s</p>
        </triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="Scene" name="Scene">
      <node id="%s" name="%s" type="NODE">
        <instance_geometry url="#%s-mesh" name="%s"/>
      </node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>
''' % ("millimeter" if unit == 0.001 else "meter", unit, name, name, name, name,
           3 * len(vertices), positions, name, len(vertices), name, name, len(triangles), name,
           indices, name, name, name, name))


def floats(text, default):
    return tuple(float(x) for x in text.split()) if text else default


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def transpose(a):
    return [[a[j][i] for j in range(3)] for i in range(3)]


def inertia_matrix(element):
    g = {k: float(element.get(k)) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    return [[g["ixx"], g["ixy"], g["ixz"]], [g["ixy"], g["iyy"], g["iyz"]],
            [g["ixz"], g["iyz"], g["izz"]]]


def set_inertia(element, m):
    for key, (i, j) in (("ixx", (0, 0)), ("ixy", (0, 1)), ("ixz", (0, 2)), ("iyy", (1, 1)),
                        ("iyz", (1, 2)), ("izz", (2, 2))):
        element.set(key, "%.10g" % m[i][j])


def mesh_geometry(kind, style, counter):
    """(folder, extension, writer) of one mesh of `kind` in `style`."""
    if style == "acme":
        if kind == "visual":
            return "meshes/visual", "obj", "obj_material"
        return "meshes/collision", ("obj" if counter % 2 == 0 else "stl"), None
    if style == "beta":
        return ("meshes/visual", "dae", "mm") if kind == "visual" else ("meshes/collision", "stl",
                                                                        None)
    return ("meshes", "STL", None) if kind == "visual" else ("meshes/collision", "dae", "m")


def add_hand(robot, tip, arm):
    """A hand fixed to the flange with two prismatic fingers, the second a <mimic> of the first."""
    def link(name, mass, size, xyz):
        element = ElementTree.SubElement(robot, "link", name=name)
        inertial = ElementTree.SubElement(element, "inertial")
        ElementTree.SubElement(inertial, "origin", xyz=xyz, rpy="0 0 0")
        ElementTree.SubElement(inertial, "mass", value="%g" % mass)
        a, b, c = size
        ElementTree.SubElement(inertial, "inertia", ixx="%.6g" % (mass * (b * b + c * c) / 12),
                               ixy="0", ixz="0", iyy="%.6g" % (mass * (a * a + c * c) / 12),
                               iyz="0", izz="%.6g" % (mass * (a * a + b * b) / 12))
        for kind in ("visual", "collision"):
            shape = ElementTree.SubElement(element, kind)
            ElementTree.SubElement(shape, "origin", xyz=xyz, rpy="0 0 0")
            geometry = ElementTree.SubElement(shape, "geometry")
            ElementTree.SubElement(geometry, "box", size="%g %g %g" % size)
            if kind == "visual":
                ElementTree.SubElement(shape, "material", name=arm + "_white")
    def joint(name, kind, parent, child, xyz, axis=None):
        element = ElementTree.SubElement(robot, "joint", name=name, type=kind)
        ElementTree.SubElement(element, "parent", link=parent)
        ElementTree.SubElement(element, "child", link=child)
        ElementTree.SubElement(element, "origin", xyz=xyz, rpy="0 0 0")
        if axis:
            ElementTree.SubElement(element, "axis", xyz=axis)
            ElementTree.SubElement(element, "limit", lower="0", upper="0.04", effort="20",
                                   velocity="0.2")
        return element
    link("hand", 0.6, (0.06, 0.2, 0.06), "0 0 0.03")
    joint("hand_joint", "fixed", tip, "hand", "0 0 0")
    for side, sign in (("left", 1), ("right", -1)):
        link("finger_" + side, 0.015, (0.02, 0.01, 0.05), "0 %g 0.025" % (0.01 * sign))
        element = joint("finger_joint_" + side, "prismatic", "hand", "finger_" + side,
                        "0 0 0.06", "0 %d 0" % sign)
        if side == "right":
            ElementTree.SubElement(element, "mimic", joint="finger_joint_left")
    ElementTree.SubElement(robot, "link", name="hand_tcp")
    joint("hand_tcp_joint", "fixed", "hand", "hand_tcp", "0 0 0.1034")


def make(seed, joints, package, arm, out, style="acme"):
    urdf = subprocess.run([sys.executable, os.path.join(HERE, "..", "arms", "generate_arm.py"),
                           "--seed", str(seed), "--joints", str(joints), "--out", "/dev/stdout"],
                          check=True, capture_output=True, text=True).stdout
    urdf = urdf[urdf.index("<?xml"):]
    robot = ElementTree.fromstring(urdf[urdf.index("<robot"):urdf.index("</robot>") + 8])
    root = os.path.join(out, package)
    folders = {"acme": ("urdf", "meshes/visual", "meshes/collision", "launch"),
               "beta": ("urdf", "meshes/visual", "meshes/collision", "launch"),
               "gamma": ("urdf", "meshes", "meshes/collision", "launch")}[style]
    for folder in folders:
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
                if kind == "collision":
                    counter += 1
                name = "%s_%d" % (link.get("name"), index)
                folder, ext, how = mesh_geometry(kind, style, counter)
                if style == "gamma" and kind == "visual":
                    name = link.get("name") if index == 0 else name
                file = "%s/%s.%s" % (folder, name, ext)
                path = os.path.join(root, file)
                if ext.lower() == "stl":
                    write_stl(path, name, vertices, triangles)
                elif ext == "obj":
                    write_obj(path, name, vertices, triangles,
                              arm.rstrip("0123456789") + "_orange" if how else None)
                else:
                    write_dae(path, name, vertices, triangles, 0.001 if how == "mm" else 1.0)
                geometry.remove(cylinder)
                uri = ("../" + file) if style == "gamma" else "package://%s/%s" % (package, file)
                ElementTree.SubElement(geometry, "mesh", filename=uri)
                if style == "beta" and kind == "visual":
                    ElementTree.SubElement(element, "material", name=arm + "_white")
    for joint in robot.findall("joint"):
        for dynamics in joint.findall("dynamics"):
            joint.remove(dynamics)
    revolute = [j for j in robot.findall("joint") if j.get("type") != "fixed"]
    links = robot.findall("link")
    if style == "beta":
        # Published moments that break A + B >= C by 15 % (a CAD export's rounding gone wrong).
        inertia = links[3].find("inertial").find("inertia")
        m = inertia_matrix(inertia)
        m[2][2] = 1.15 * (m[0][0] + m[1][1])
        m[0][1] = m[1][0] = m[0][2] = m[2][0] = m[1][2] = m[2][1] = 0.0
        set_inertia(inertia, m)
        for joint in revolute:
            limit = joint.find("limit")
            lower, upper = float(limit.get("lower")), float(limit.get("upper"))
            ElementTree.SubElement(joint, "safety_controller", k_position="100", k_velocity="40",
                                   soft_lower_limit="%.6g" % (lower + 0.05),
                                   soft_upper_limit="%.6g" % (upper - 0.05))
            ElementTree.SubElement(joint, "calibration", rising="0.0")
        tip = links[-1].get("name")
        add_hand(robot, tip, arm)
        material = ElementTree.Element("material", name=arm + "_white")
        ElementTree.SubElement(material, "color", rgba="0.95 0.95 0.95 1")
        robot.insert(0, material)
        control = ElementTree.SubElement(robot, "ros2_control", name=arm, type="system")
        hardware = ElementTree.SubElement(control, "hardware")
        ElementTree.SubElement(hardware, "plugin").text = "beta_hardware/BetaSystemInterface"
        ElementTree.SubElement(hardware, "param", name="robot_ip").text = "192.168.1.10"
        for joint in revolute:
            j = ElementTree.SubElement(control, "joint", name=joint.get("name"))
            ElementTree.SubElement(j, "command_interface", name="effort")
            for interface in ("position", "velocity", "effort"):
                ElementTree.SubElement(j, "state_interface", name=interface)
    if style == "gamma":
        # Inertial frames turned as the exporter writes them (principal axes of the CAD part):
        # the tensor is given in the turned axes, R^T I R, so the body is the same.
        for link in links:
            inertial = link.find("inertial")
            if inertial is None:
                continue
            origin = inertial.find("origin")
            if origin is None:
                origin = ElementTree.SubElement(inertial, "origin", xyz="0 0 0")
            rpy = (0.3, -0.2, 0.5)
            if floats(origin.get("rpy"), (0, 0, 0)) != (0, 0, 0):
                continue
            origin.set("rpy", "%g %g %g" % rpy)
            r = rotation(rpy)
            inertia = inertial.find("inertia")
            set_inertia(inertia, matmul(transpose(r), matmul(inertia_matrix(inertia), r)))
    if style in ("acme", "beta"):
        base = robot.find("link").get("name")
        world = ElementTree.Element("link", name="world")
        fixed = ElementTree.Element("joint", name="world_joint", type="fixed")
        ElementTree.SubElement(fixed, "parent", link="world")
        ElementTree.SubElement(fixed, "child", link=base)
        ElementTree.SubElement(fixed, "origin", xyz="0 0 0", rpy="0 0 0")
        robot.insert(0, fixed)
        robot.insert(0, world)
    robot.set("name", arm)
    for joint in (revolute if style != "gamma" else []):
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
    if style == "acme":
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
    parser.add_argument("--style", choices=("acme", "beta", "gamma"), default="acme")
    args = parser.parse_args()
    make(args.seed, args.joints, args.package, args.arm, args.out, args.style)


if __name__ == "__main__":
    main()
