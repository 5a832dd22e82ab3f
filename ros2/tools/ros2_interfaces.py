#!/usr/bin/env python3
"""ROS 2 .msg files -> the DDS IDL that ROS 2's DDS layers put on the wire, and RIHS01 type hashes.

ROS 2 maps a message `pkg/msg/Name` onto the DDS type `pkg::msg::dds_::Name_` (an `@final` struct in
modules pkg, msg, dds_; nested types mapped the same way), which both of its DDS layers match by
that exact name. The type hash (REP 2011, "RIHS01") is the SHA-256 of a JSON rendering of the type
description (each type's name and fields, then every type it references, sorted by name), as
rosidl's type-description generator (Iron and later) computes it; endpoints announce it in their
USER_DATA. Parsing is rosidl's own (`rosidl_adapter`, Debian's python3-rosidl).

    ros2_interfaces.py --idl OUT.idl --header OUT.hpp --json OUT.json PACKAGE_DIR...

Each PACKAGE_DIR is a folder named after its package, holding msg/*.msg.
"""

import argparse
import hashlib
import json
import pathlib
import sys

from rosidl_adapter.parser import parse_message_file

# .msg primitive -> (DDS IDL type, FieldType id of type_description_interfaces). byte and char
# become octet and uint8 in ROS IDL, whose FieldType ids the hash uses.
PRIMITIVES = {
    'bool': ('boolean', 15), 'byte': ('octet', 16), 'char': ('octet', 3),
    'int8': ('octet', 2), 'uint8': ('octet', 3), 'int16': ('short', 4),
    'uint16': ('unsigned short', 5), 'int32': ('long', 6), 'uint32': ('unsigned long', 7),
    'int64': ('long long', 8), 'uint64': ('unsigned long long', 9), 'float32': ('float', 10),
    'float64': ('double', 11), 'string': ('string', 17), 'wstring': ('wstring', 18),
}
NESTED = 1
# FieldType id offsets of the array kinds (FieldType.msg).
FIXED_ARRAY, BOUNDED_SEQUENCE, UNBOUNDED_SEQUENCE = 48, 96, 144
BOUNDED_STRING, BOUNDED_WSTRING = 21, 22


class Message:
    def __init__(self, package, spec):
        self.package = package
        self.name = spec.msg_name
        self.spec = spec
        if spec.constants:
            raise SystemExit(f'{self.ros_name}: constants are not supported by this generator')

    @property
    def ros_name(self):
        return f'{self.package}/msg/{self.name}'

    @property
    def dds_name(self):
        return f'{self.package}::msg::dds_::{self.name}_'

    @property
    def c_name(self):
        return f'{self.package}_msg_dds__{self.name}_'

    def nested(self):
        return [f'{f.type.pkg_name}/msg/{f.type.type}'
                for f in self.spec.fields if not f.type.is_primitive_type()]


def field_description(field):
    """One field as rosidl's type description serializes it (without default_value)."""
    t = field.type
    string_capacity = 0
    if t.is_primitive_type():
        type_id = PRIMITIVES[t.type][1]
        if t.string_upper_bound is not None:
            string_capacity = t.string_upper_bound
            type_id = BOUNDED_STRING if t.type == 'string' else BOUNDED_WSTRING
        nested_name = ''
    else:
        type_id = NESTED
        nested_name = f'{t.pkg_name}/msg/{t.type}'
    capacity = 0
    if t.is_array:
        if t.array_size is None:
            type_id += UNBOUNDED_SEQUENCE
        elif t.is_upper_bound:
            type_id += BOUNDED_SEQUENCE
        else:
            type_id += FIXED_ARRAY
            capacity = t.array_size
    return {'name': field.name,
            'type': {'type_id': type_id, 'capacity': capacity,
                     'string_capacity': string_capacity, 'nested_type_name': nested_name}}


def individual_description(message):
    return {'type_name': message.ros_name,
            'fields': [field_description(f) for f in message.spec.fields]}


def type_hash(name, messages):
    """RIHS01 of `name`: the description of the type and of every type it references, sorted."""
    references, queue = set(), list(messages[name].nested())
    while queue:
        reference = queue.pop()
        if reference not in references:
            references.add(reference)
            queue.extend(messages[reference].nested())
    description = {
        'type_description': individual_description(messages[name]),
        'referenced_type_descriptions': [individual_description(messages[r])
                                         for r in sorted(references)],
    }
    text = json.dumps(description, ensure_ascii=True, allow_nan=False, separators=(', ', ': '))
    return 'RIHS01_' + hashlib.sha256(text.encode('utf-8')).hexdigest()


def idl_member(field):
    t = field.type
    if t.is_primitive_type():
        base = PRIMITIVES[t.type][0]
        if t.string_upper_bound is not None:
            base = f'{base}<{t.string_upper_bound}>'
    else:
        base = f'::{t.pkg_name}::msg::dds_::{t.type}_'
    if not t.is_array:
        return f'{base} {field.name};'
    if t.array_size is None:
        return f'sequence<{base}> {field.name};'
    if t.is_upper_bound:
        return f'sequence<{base}, {t.array_size}> {field.name};'
    return f'{base} {field.name}[{t.array_size}];'


def dependency_order(messages):
    ordered, done = [], set()

    def visit(name, path):
        if name in done:
            return
        if name in path:
            raise SystemExit(f'{name}: recursive message definition')
        if name not in messages:
            raise SystemExit(f'{path[-1]} uses {name}, which no package given defines')
        for nested in messages[name].nested():
            visit(nested, path + [name])
        done.add(name)
        ordered.append(messages[name])

    for name in sorted(messages):
        visit(name, [])
    return ordered


def write_idl(ordered):
    lines = ['// Generated by ros2/tools/ros2_interfaces.py from the .msg files: ROS 2\'s DDS',
             '// mapping of each message (module pkg::msg::dds_, struct Name_, @final). Do not edit.', '']
    for message in ordered:
        lines.append(f'module {message.package} {{ module msg {{ module dds_ {{')
        lines.append(f'  @final struct {message.name}_ {{')
        lines.extend(f'    {idl_member(f)}' for f in message.spec.fields)
        lines.append('  };')
        lines.append('}; }; };')
        lines.append('')
    return '\n'.join(lines)


def write_header(ordered, hashes, idl_header):
    lines = [
        '// Generated by ros2/tools/ros2_interfaces.py. Do not edit.',
        '#pragma once',
        '/// @file',
        '/// For each message type: its ROS 2 name, the DDS topic descriptor generated by idlc, and',
        '/// its RIHS01 type hash (what endpoints announce in USER_DATA as `typehash=...;`).',
        '',
        f'#include "{idl_header}"',
        '',
        'namespace cartesian_impedance_ros2 {',
        '',
        'template <typename Message>',
        'struct MessageType;',
        '',
    ]
    for message in ordered:
        lines += [
            'template <>',
            f'struct MessageType<{message.c_name}> {{',
            f'  static constexpr const char* ros_name = "{message.ros_name}";',
            f'  static constexpr const char* type_hash = "{hashes[message.ros_name]}";',
            f'  static const dds_topic_descriptor_t* descriptor() {{ return &{message.c_name}_desc; }}',
            '};',
            '',
        ]
    lines.append('}  // namespace cartesian_impedance_ros2')
    return '\n'.join(lines) + '\n'


def load(package_dirs):
    messages = {}
    for directory in map(pathlib.Path, package_dirs):
        if not (directory / 'msg').is_dir():
            raise SystemExit(f'{directory}: not a package folder (no msg/ in it)')
        for path in sorted((directory / 'msg').glob('*.msg')):
            message = Message(directory.name, parse_message_file(directory.name, str(path)))
            messages[message.ros_name] = message
    return messages


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--idl', required=True)
    parser.add_argument('--header')
    parser.add_argument('--json')
    parser.add_argument('packages', nargs='+')
    args = parser.parse_args(argv)

    messages = load(args.packages)
    ordered = dependency_order(messages)
    hashes = {name: type_hash(name, messages) for name in messages}
    pathlib.Path(args.idl).write_text(write_idl(ordered))
    if args.header:
        idl_header = pathlib.Path(args.idl).with_suffix('.h').name
        pathlib.Path(args.header).write_text(write_header(ordered, hashes, idl_header))
    if args.json:
        table = {m.ros_name: {'dds_name': m.dds_name, 'type_hash': hashes[m.ros_name]}
                 for m in ordered}
        pathlib.Path(args.json).write_text(json.dumps(table, indent=2) + '\n')


if __name__ == '__main__':
    main(sys.argv[1:])
