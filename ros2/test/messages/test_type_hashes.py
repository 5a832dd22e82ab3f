#!/usr/bin/env python3
"""RIHS01 type hashes of the generated messages (ros2/tools/ros2_interfaces.py).

- The standard messages' hashes equal the values ROS 2 publishes (each with where it was read).
- The generated header carries the same hash and DDS name as the json.
- The hash follows the type: renaming or retyping a field, or changing a referenced type, changes
  it; comments do not.
- The generated IDL marks every struct @final (XCDR1 with no DHEADER, as ROS 2 puts on the wire).

    test_type_hashes.py --json J --header H --idl I --tool ros2_interfaces.py --msg ros2/msg
"""

import argparse
import importlib.util
import json
import pathlib
import re
import shutil
import sys
import tempfile
import unittest

# ROS 2's published hashes. Those without a source named were checked on a ROS 2 Jazzy system
# (`ros2 topic info --verbose`). The others are read from
# rosidl-generated `*__description.c` files committed to public repositories: the hash of the file's
# own type, or the EXPECTED_HASH of a type it references (rosidl asserts those at run time).
PUBLISHED = {
    'geometry_msgs/msg/PoseStamped':
        '10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8',
    'geometry_msgs/msg/WrenchStamped':
        '8dc3deaf06b2ab281f9f9a742a8961c328ca7cec16e3fd6586d3a5c83fa78f77',
    'geometry_msgs/msg/Wrench':
        '018e8519d57c16adbe97c9fe1460ef21fec7e31bc541de3d653a35895677ce52',
    'std_msgs/msg/Header':
        'f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01',
    'builtin_interfaces/msg/Time':
        'b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197',
    'geometry_msgs/msg/Point':
        '6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881',
    'geometry_msgs/msg/Vector3':
        'cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d',
    # hpmicro/hpm_sdk, middleware/microros/kilted/include/geometry_msgs/geometry_msgs/msg/detail/
    # pose__description.c (micro-ROS, Kilted; the Point hash in the same file is Jazzy's above).
    'geometry_msgs/msg/Pose':
        'd501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa',
    # Same file (referenced type); also orka375/moveit2, install/moveit_msgs/include/moveit_msgs/
    # moveit_msgs/msg/detail/robot_trajectory__description.c.
    'geometry_msgs/msg/Quaternion':
        '8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684',
    # hpmicro/hpm_sdk, middleware/microros/kilted/include/sensor_msgs/sensor_msgs/msg/detail/
    # joint_state__description.c (its Header and Time hashes are Jazzy's above).
    'sensor_msgs/msg/JointState':
        'a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e',
    # hpmicro/hpm_sdk, middleware/microros/kilted/include/std_msgs/std_msgs/msg/detail/
    # float64_multi_array__description.c (the type and the two it references).
    'std_msgs/msg/Float64MultiArray':
        '1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f',
    'std_msgs/msg/MultiArrayLayout':
        '4c66e6f78e740ac103a94cf63259f968e48c617e7699e829b63c21a5cb50dac6',
    'std_msgs/msg/MultiArrayDimension':
        '5e773a60a4c7fc8a54985f307c7837aa2994252a126c301957a24e31282c9cbe',
    # orka375/moveit2, install/moveit_msgs/include/moveit_msgs/moveit_msgs/msg/detail/
    # robot_trajectory__description.c (a colcon install of moveit_msgs, Iron or later: earlier
    # distributions generate no __description.c; its Header, Time and Vector3 hashes are Jazzy's).
    'builtin_interfaces/msg/Duration':
        'e8d009f659816f758b75334ee1a9ca5b5c0b859843261f14c7f937349599d93b',
    'trajectory_msgs/msg/JointTrajectory':
        '179b33eba59d676f6d967ac71fe35e7ca2f64b2f3928f4a018cec115e213796e',
    'trajectory_msgs/msg/JointTrajectoryPoint':
        'de8907036d8bd45aac6f30cc9044a3d4a329c42cbf719aff7d95a584cfa532d7',
    # The EXPECTED_HASH of referenced types in rosidl-generated __description.c files of
    # packages that use them: object_search_msgs/msg/ObjectMaskWithTf and
    # my_mesh_interfaces/msg/MeshTf (TFMessage, TransformStamped, Transform; their Header, Time,
    # Vector3 and Quaternion hashes are the ones above), custom_message/msg/SampleMsg (String).
    'tf2_msgs/msg/TFMessage':
        'e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087',
    'geometry_msgs/msg/TransformStamped':
        '0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206',
    'geometry_msgs/msg/Transform':
        'beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc',
    'std_msgs/msg/String':
        'df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18',
    # A message without fields: rosidl's `uint8 structure_needs_at_least_one_member` (a Rust
    # crate's test of its ROS 2 hashes quotes it and the type description it is made from).
    'std_msgs/msg/Empty':
        '20b625256f32d5dbc0d04fee44f43c41e51c70d3502f84b4a08e7a9c26a96312',
    # hpmicro/hpm_sdk, middleware/microros/kilted/include/rcl_interfaces/rcl_interfaces/srv/detail/
    # set_parameters__description.c, list_parameters__description.c and
    # describe_parameters__description.c (micro-ROS, Kilted): the hashes of their services' parts
    # (below) and the EXPECTED_HASH of the messages they reference.
    'rcl_interfaces/msg/Parameter':
        'ddfe6442cffc462317adb5c92536a7b6dd55858c5c3e1e328165a6b73c2831af',
    'rcl_interfaces/msg/ParameterValue':
        '115fc089a387e23c7ecd3525c9189c379109119d6ab82e8dfbde0fdf6a7f9b68',
    'rcl_interfaces/msg/SetParametersResult':
        'cfcc0fb0371ee5159b403960ef4300f8f9d2f1fd6117c8666b7f9654d528a9b1',
    'rcl_interfaces/msg/ListParametersResult':
        '237ae3428413dcbcfb452b510c42355f3a2b021dc091afa3e18526d57022f1cd',
    'rcl_interfaces/msg/ParameterDescriptor':
        '52175dbfda6c51153101d33d2a9da05743f66f02d5ab2ca9ec4709b46b73d704',
    'rcl_interfaces/msg/FloatingPointRange':
        'e6af23a23c177fee5f3075c8b1e435162a9b63c863d78c06017460b49684262d',
    'rcl_interfaces/msg/IntegerRange':
        'f7b7fdc0f65f07702e099218e13288c3963bcb9345bde78b560e6cd19800fc5a',
    'service_msgs/msg/ServiceEventInfo':
        '41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45',
    # The graph messages (ros_discovery_info), from rosidl-generated rmw_dds_common
    # gid__description.c, node_entities_info__description.c (which also asserts Gid's) and
    # participant_entities_info__description.c of an Iron-or-later build: Gid is `char[16] data`,
    # and the readers come before the writers.
    'rmw_dds_common/msg/Gid':
        'ab6f21cfbb0a6dbb837161e1110c2051a2850ed9f9c53944d7115d9bcebedf71',
    'rmw_dds_common/msg/NodeEntitiesInfo':
        '8ffef65ee2d088c63b1e8fcd31e800ba9fc8dbe0ee15ca60d1676de5218087a7',
    'rmw_dds_common/msg/ParticipantEntitiesInfo':
        '91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e',
}

# Standard messages whose published hash was not found: computed by the same generator, whose
# other results (the types it references among them) equal ROS 2's.
UNPUBLISHED = {'rcl_interfaces/msg/ParameterEvent'}

# The services' parts, the Event messages and the services themselves (what their endpoints
# announce), from the same micro-ROS files.
PUBLISHED_SERVICES = {
    'rcl_interfaces/srv/SetParameters':
        '56eed9a67e169f9cb6c1f987bc88f868c14a8fc9f743a263bc734c154015d7e0',
    'rcl_interfaces/srv/SetParameters_Request':
        '130d46386b7e84ea9ecf60608a4d83cbe5e5cb7c6cc5b712b7a4e3a6c254e932',
    'rcl_interfaces/srv/SetParameters_Response':
        '7a0e8140a0b8d98308fa81a5403a766e610af29a239caf54b7553227906fc266',
    'rcl_interfaces/srv/SetParameters_Event':
        '5060f52369bcff7f9dbd6eca21ee521859e471e71b33a8a8df26d5236fe54a80',
    'rcl_interfaces/srv/ListParameters':
        '3e6062bfbb27bfb8730d4cef2558221f51a11646d78e7bb30a1e83afac3aad9d',
    'rcl_interfaces/srv/ListParameters_Request':
        'a1b0b5d6b967a5b8ac5bc8563c3ea678f349e312a6a4967227c5a96bc5ce38df',
    'rcl_interfaces/srv/ListParameters_Response':
        '31b937b82de3612426be79f231e386259f97e8dc843e3f2845288b4bfa296bdd',
    'rcl_interfaces/srv/ListParameters_Event':
        '89c5b5aaf68ec925ae9bbc5569ee21de82959b4d1496dbd498792ad825b9b292',
    'rcl_interfaces/srv/DescribeParameters':
        '845b484d71eb0673dae682f2e3ba3c4851a65a3dcfb97bddd82c5b57e91e4cff',
    'rcl_interfaces/srv/DescribeParameters_Request':
        '05dd1c2bc87dec2627105c8070d6f9725c781a4f2ab852975bf105462b82b644',
    'rcl_interfaces/srv/DescribeParameters_Response':
        'ad6747319613c6131589e062e095b469a46cc764f7d0f12a001a49e6cd893995',
    'rcl_interfaces/srv/DescribeParameters_Event':
        '3deba64c035093033c690184834441551a53128ea2539f71f2596fbc4ed9de43',
}

ARGS = None
TOOL = None


def tool():
    """The generator as a module, to hash without a process (and a rosidl import) per case."""
    spec = importlib.util.spec_from_file_location('ros2_interfaces', ARGS.tool)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class PublishedHashes(unittest.TestCase):
    def test_standard_messages_hash_as_ros2_publishes(self):
        table = json.loads(pathlib.Path(ARGS.json).read_text())
        for name, digest in sorted(PUBLISHED.items()):
            with self.subTest(name):
                self.assertIn(name, table)
                self.assertEqual(table[name]['type_hash'], 'RIHS01_' + digest)

    def test_every_standard_message_has_a_published_hash(self):
        standard = {p.parent.parent.name + '/msg/' + p.stem
                    for p in pathlib.Path(ARGS.msg).glob('*/msg/*.msg')}
        self.assertEqual(len(standard), 33)
        self.assertEqual(standard - set(PUBLISHED) - UNPUBLISHED, set())

    def test_services_hash_as_ros2_publishes(self):
        types = TOOL.load(sorted(p for p in pathlib.Path(ARGS.msg).iterdir() if p.is_dir()))
        for name, digest in sorted(PUBLISHED_SERVICES.items()):
            with self.subTest(name):
                self.assertEqual(TOOL.type_hash(name, types), 'RIHS01_' + digest)

    def test_service_endpoints_announce_the_services_hash(self):
        table = json.loads(pathlib.Path(ARGS.json).read_text())
        parts = {name: entry for name, entry in table.items() if '/srv/' in name}
        self.assertEqual(len(parts), 12)  # six parameter services, request and response each
        for name, entry in parts.items():
            with self.subTest(name):
                self.assertEqual(entry['service'], name.rsplit('_', 1)[0])
                digest = PUBLISHED_SERVICES.get(entry['service'])
                if digest:
                    self.assertEqual(entry['service_hash'], 'RIHS01_' + digest)


class GeneratedFiles(unittest.TestCase):
    def setUp(self):
        self.table = json.loads(pathlib.Path(ARGS.json).read_text())

    def test_header_carries_the_json_hashes(self):
        header = pathlib.Path(ARGS.header).read_text()
        entries = re.findall(r'struct MessageType<(\w+)> \{\s*'
                             r'static constexpr const char\* ros_name = "([^"]+)";\s*'
                             r'static constexpr const char\* type_hash = "([^"]+)";', header)
        self.assertEqual(len(entries), len(self.table))
        for c_name, ros_name, type_hash in entries:
            with self.subTest(ros_name):
                entry = self.table[ros_name]
                # A service's request and reply endpoints announce the service's hash.
                self.assertEqual(type_hash, entry.get('service_hash', entry['type_hash']))
                package, kind, name = ros_name.split('/')
                self.assertEqual(c_name, f'{package}_{kind}_dds__{name}_')
                self.assertEqual(entry['dds_name'], f'{package}::{kind}::dds_::{name}_')

    def test_requests_and_replies_start_with_the_request_header(self):
        idl = pathlib.Path(ARGS.idl).read_text()
        for name in (n for n in self.table if '/srv/' in n):
            with self.subTest(name):
                body = re.search(r'struct %s_ \{\s*([^}]*)\}' % name.split('/')[-1], idl).group(1)
                members = [m.strip() for m in body.split(';') if m.strip()]
                self.assertEqual(members[:2], ['unsigned long long cdds_request_header_guid',
                                               'long long cdds_request_header_seq'])

    def test_every_idl_struct_is_final(self):
        idl = re.sub(r'//[^\n]*', '', pathlib.Path(ARGS.idl).read_text())
        structs = re.findall(r'(@final\s+)?struct\s+(\w+)', idl)
        self.assertEqual(len(structs), len(self.table))
        self.assertEqual([name for final, name in structs if not final], [])


class HashFollowsTheType(unittest.TestCase):
    """The generator run on a scratch package, edited one way at a time."""

    PROBE = 'std_msgs/Header header\nfloat64 gain  # a comment\nstring[] names\n'

    def hash_of(self, probe_text, edit_header=None):
        with tempfile.TemporaryDirectory() as work:
            work = pathlib.Path(work)
            std_msgs = work / 'std_msgs'
            shutil.copytree(pathlib.Path(ARGS.msg) / 'std_msgs', std_msgs)
            shutil.copytree(pathlib.Path(ARGS.msg) / 'builtin_interfaces',
                            work / 'builtin_interfaces')
            if edit_header:
                header = std_msgs / 'msg' / 'Header.msg'
                header.write_text(edit_header(header.read_text()))
            (work / 'probe_msgs' / 'msg').mkdir(parents=True)
            (work / 'probe_msgs' / 'msg' / 'Probe.msg').write_text(probe_text)
            messages = TOOL.load([std_msgs, work / 'builtin_interfaces', work / 'probe_msgs'])
            return TOOL.type_hash('probe_msgs/msg/Probe', messages)

    def test_the_hash_is_a_function_of_the_definition(self):
        self.assertEqual(self.hash_of(self.PROBE), self.hash_of(self.PROBE))

    def test_comments_do_not_count(self):
        self.assertEqual(self.hash_of(self.PROBE),
                         self.hash_of(self.PROBE.replace('# a comment', '# another')))

    def test_renamed_field_changes_the_hash(self):
        self.assertNotEqual(self.hash_of(self.PROBE),
                            self.hash_of(self.PROBE.replace('gain', 'gains')))

    def test_retyped_field_changes_the_hash(self):
        base = self.hash_of(self.PROBE)
        for edit in (('float64 gain', 'float32 gain'), ('string[]', 'string'),
                     ('string[]', 'string[3]'), ('string[]', 'string[<=3]')):
            with self.subTest(edit):
                self.assertNotEqual(base, self.hash_of(self.PROBE.replace(*edit)))

    def test_reordered_fields_change_the_hash(self):
        lines = self.PROBE.splitlines()
        self.assertNotEqual(self.hash_of(self.PROBE),
                            self.hash_of('\n'.join([lines[0], lines[2], lines[1]]) + '\n'))

    def test_a_changed_referenced_type_changes_the_hash(self):
        self.assertNotEqual(self.hash_of(self.PROBE),
                            self.hash_of(self.PROBE,
                                         lambda text: text.replace('frame_id', 'frame')))


def main():
    global ARGS, TOOL
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for option in ('--json', '--header', '--idl', '--tool', '--msg'):
        parser.add_argument(option, required=True)
    ARGS, rest = parser.parse_known_args()
    TOOL = tool()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)


if __name__ == '__main__':
    main()
