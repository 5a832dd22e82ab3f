#!/usr/bin/env python3
"""ROS 2 .msg and .srv files -> the DDS IDL that ROS 2's DDS layers put on the wire, and RIHS01 hashes.

ROS 2 maps a message `pkg/msg/Name` onto the DDS type `pkg::msg::dds_::Name_` (an `@final` struct in
modules pkg, msg, dds_; nested types mapped the same way), which both of its DDS layers match by
that exact name. The type hash (REP 2011, "RIHS01") is the SHA-256 of a JSON rendering of the type
description (each type's name and fields, then every type it references, sorted by name), as
rosidl's type-description generator (Iron and later) computes it; endpoints announce it in their
USER_DATA. Parsing is rosidl's own (`rosidl_adapter`, Debian's python3-rosidl).

A service `pkg/srv/Name` is two DDS types, `pkg::srv::dds_::Name_Request_` and `Name_Response_`, on
the topics rq/<service>Request and rr/<service>Reply. rmw_cyclonedds_cpp puts its request header
(cdds_request_header_t: the client's 64-bit id, then the request's sequence number, both 8 bytes)
in front of the fields of both, in the same CDR stream; the IDL here carries the header as the
first two members (`cdds_request_header_guid`, `cdds_request_header_seq`), so that Cyclone writes
and reads exactly those bytes. The hash of each part is that of its ROS 2 message (no header); the
endpoints of a service announce the service's hash, computed from its type description (fields
request_message, response_message, event_message; the Event type with service_msgs's
ServiceEventInfo), as rosidl does. Constants carry no data on the wire and are not part of a type
description: they are left out of both.

    ros2_interfaces.py --idl OUT.idl --header OUT.hpp --json OUT.json PACKAGE_DIR...

Each PACKAGE_DIR is a folder named after its package, holding msg/*.msg and/or srv/*.srv.
"""

import argparse
import hashlib
import json
import pathlib
import sys

from rosidl_adapter.parser import Field, Type, parse_message_file, parse_service_file

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


# Names of the types the packages given define: (package, type) -> ROS name ("pkg/msg/Name",
# "pkg/srv/Name_Request"), so that a field's type resolves to a message or a service's part.
RESOLVE = {}


def resolve(pkg, name):
    return RESOLVE.get((pkg, name), f'{pkg}/msg/{name}')


# The request header rmw_cyclonedds_cpp writes before the fields of a request or reply.
REQUEST_HEADER = ['unsigned long long cdds_request_header_guid;',
                  'long long cdds_request_header_seq;']


class Message:
    """A message, or the request or response part of a service (kind 'srv')."""

    def __init__(self, package, spec, kind='msg', service=None):
        self.package = package
        self.name = spec.msg_name
        self.spec = spec
        self.kind = kind
        self.service = service  # ROS name of the service a part belongs to

    @property
    def ros_name(self):
        return f'{self.package}/{self.kind}/{self.name}'

    @property
    def dds_name(self):
        return f'{self.package}::{self.kind}::dds_::{self.name}_'

    @property
    def c_name(self):
        return f'{self.package}_{self.kind}_dds__{self.name}_'

    def nested(self):
        return [resolve(f.type.pkg_name, f.type.type)
                for f in self.spec.fields if not f.type.is_primitive_type()]


class HashOnly:
    """A type that exists only in type descriptions: a service's Event message, a service."""

    def __init__(self, ros_name, fields):
        self.ros_name = ros_name
        self.fields = fields  # [(name, type_id, capacity, nested ROS name)]

    def nested(self):
        return [nested for _, _, _, nested in self.fields if nested]

    def description(self):
        return {'type_name': self.ros_name,
                'fields': [{'name': name,
                            'type': {'type_id': type_id, 'capacity': capacity,
                                     'string_capacity': 0, 'nested_type_name': nested}}
                           for name, type_id, capacity, nested in self.fields]}


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
        nested_name = resolve(t.pkg_name, t.type)
    capacity = 0
    if t.is_array:
        if t.array_size is None:
            type_id += UNBOUNDED_SEQUENCE
        elif t.is_upper_bound:
            type_id += BOUNDED_SEQUENCE  # the bound is its capacity, as for a fixed array
            capacity = t.array_size
        else:
            type_id += FIXED_ARRAY
            capacity = t.array_size
    return {'name': field.name,
            'type': {'type_id': type_id, 'capacity': capacity,
                     'string_capacity': string_capacity, 'nested_type_name': nested_name}}


def individual_description(message):
    if isinstance(message, HashOnly):
        return message.description()
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
        package, kind, name = resolve(t.pkg_name, t.type).split('/')
        base = f'::{package}::{kind}::dds_::{name}_'
    if not t.is_array:
        return f'{base} {field.name};'
    if t.array_size is None:
        return f'sequence<{base}> {field.name};'
    if t.is_upper_bound:
        return f'sequence<{base}, {t.array_size}> {field.name};'
    return f'{base} {field.name}[{t.array_size}];'


def dependency_order(messages):
    """The types of the IDL (messages and service parts), each after the types it uses."""
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
        if isinstance(messages[name], Message):
            visit(name, [])
    return ordered


def write_idl(ordered):
    lines = ['// Generated by ros2/tools/ros2_interfaces.py from the .msg files: ROS 2\'s DDS',
             '// mapping of each message (module pkg::msg::dds_, struct Name_, @final). Do not edit.', '']
    for message in ordered:
        lines.append(f'module {message.package} {{ module {message.kind} {{ module dds_ {{')
        lines.append(f'  @final struct {message.name}_ {{')
        if message.kind == 'srv':
            lines.extend(f'    {member}' for member in REQUEST_HEADER)
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
        # What an endpoint announces: a service's endpoints announce the service's hash.
        announced = hashes[message.service] if message.service else hashes[message.ros_name]
        lines += [
            'template <>',
            f'struct MessageType<{message.c_name}> {{',
            f'  static constexpr const char* ros_name = "{message.ros_name}";',
            f'  static constexpr const char* type_hash = "{announced}";',
            f'  static const dds_topic_descriptor_t* descriptor() {{ return &{message.c_name}_desc; }}',
            '};',
            '',
        ]
    lines.append('}  // namespace cartesian_impedance_ros2')
    return '\n'.join(lines) + '\n'


def service_types(package, spec, service_name):
    """The parts of service `pkg/srv/Name`: Request and Response (on the wire), and for the
    hash the Event message and the service itself, as rosidl describes them."""
    ros_name = f'{package}/srv/{service_name}'
    request = Message(package, spec.request, 'srv', ros_name)
    response = Message(package, spec.response, 'srv', ros_name)
    event = HashOnly(f'{ros_name}_Event', [
        ('info', NESTED, 0, 'service_msgs/msg/ServiceEventInfo'),
        ('request', NESTED + BOUNDED_SEQUENCE, 1, request.ros_name),
        ('response', NESTED + BOUNDED_SEQUENCE, 1, response.ros_name)])
    service = HashOnly(ros_name, [
        ('request_message', NESTED, 0, request.ros_name),
        ('response_message', NESTED, 0, response.ros_name),
        ('event_message', NESTED, 0, event.ros_name)])
    return [request, response, event, service]


def load(package_dirs):
    """Every type of the packages: messages, service parts, and the hash-only types."""
    RESOLVE.clear()
    types = {}
    for directory in map(pathlib.Path, package_dirs):
        if not (directory / 'msg').is_dir() and not (directory / 'srv').is_dir():
            raise SystemExit(f'{directory}: not a package folder (no msg/ or srv/ in it)')
        for path in sorted((directory / 'msg').glob('*.msg')):
            spec = parse_message_file(directory.name, str(path))
            if not spec.fields:
                # An IDL struct needs a member: rosidl gives a message without fields (std_msgs/
                # Empty) this one, on the wire and in its type description alike.
                spec.fields.append(Field(Type('uint8'), 'structure_needs_at_least_one_member'))
            message = Message(directory.name, spec)
            types[message.ros_name] = message
        for path in sorted((directory / 'srv').glob('*.srv')):
            spec = parse_service_file(directory.name, str(path))
            for part in service_types(directory.name, spec, path.stem):
                types[part.ros_name] = part
                RESOLVE[(directory.name, part.ros_name.split('/')[-1])] = part.ros_name
    return types


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
        table = {}
        for m in ordered:
            table[m.ros_name] = {'dds_name': m.dds_name, 'type_hash': hashes[m.ros_name]}
            if m.service:
                table[m.ros_name].update(service=m.service, service_hash=hashes[m.service])
        pathlib.Path(args.json).write_text(json.dumps(table, indent=2) + '\n')


if __name__ == '__main__':
    main(sys.argv[1:])
