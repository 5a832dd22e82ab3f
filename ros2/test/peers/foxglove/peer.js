#!/usr/bin/env node
// A third, ROS-2-aware peer for cartesian_impedance_ros2: @foxglove/ros2, an independent pure
// TypeScript implementation of ROS 2 over RTPS (no DDS library, no ROS 2). It publishes a
// geometry_msgs/msg/PoseStamped on <fq>/reference_pose, subscribes to <fq>/controller_state
// (cartesian_impedance_controller/msg/ControllerState) and <fq>/full_state
// (cartesian_impedance_msgs/msg/ControllerState), and prints one JSON object per line:
//   {"event": "participant" | "matched" | "target", ...}   discovery, and the target chosen
//   {"topic": "controller_state", "position": [x, y, z], "distance": d, ...}
//   {"topic": "full_state", "status": ..., "cycle": ..., "cartesian_stiffness": {...},
//    "limits": {...}, "safety": {...}}
//   {"result": "reached" | "timeout", ...}                 last line; exit code 0 or 1
// State lines are thinned to one per --print-period. Message definitions come from this
// repository's .msg files (--msg-dir, repeatable), parsed by @foxglove/rosmsg; samples are
// (de)serialized (XCDR1, little endian) by @foxglove/rosmsg2-serialization.
//
// @foxglove/ros2 1.0.8 and @foxglove/rtps 1.6.0 do not talk to Cyclone DDS as they come; this
// script works around, with their own parts:
// - Discovery, loopback only. rtps binds to 0.0.0.0, joins 239.255.0.1 on the default interface
//   and announces its participant (SPDP) by multicast, once, at start; Cyclone set up for
//   loopback (AllowMulticast false, Peers 127.0.0.1, see test_foxglove_peer.py) never sends to
//   the multicast port. So the sockets are bound to 127.0.0.1, no group is joined, and the SPDP
//   announcement goes by unicast, once a second, to Cyclone's discovery ports on 127.0.0.1
//   (7400 + 250 domain + 10 + 2 i, participant index i = 0 .. --max-participant-index). Cyclone
//   answers a new participant with its own SPDP to the locator that advertises (127.0.0.1);
//   endpoint discovery and data follow by unicast. Nothing leaves the loopback interface.
// - rtps ignores endpoints announced without a reliability QoS, which DDS leaves out when it is
//   the default (the node's writers): see acceptDefaultReliability().
// - ros2's readers are transient-local, which volatile writers do not match: see subscribe().
// - ros2 cannot publish: see Publisher.
"use strict";

const fs = require("fs");
const path = require("path");
const { parse } = require("@foxglove/rosmsg");
const { MessageWriter } = require("@foxglove/rosmsg2-serialization");
const { RosNode, Subscription, rosTopicToDds, rosTypeToDds } = require("@foxglove/ros2");
const rtps = require("@foxglove/rtps");
const { UdpSocketNode } = require("@foxglove/rtps/nodejs");

const USAGE = `usage: node peer.js --fq /NODE_NAME (--offset dx,dy,dz | --target x,y,z) [options]
  --domain N                 DDS domain (default: ROS_DOMAIN_ID or 0)
  --msg-dir DIR              folder of <pkg>/msg/<Name>.msg (repeatable; default: ros2/msg and
                             ros2/interfaces of this repository)
  --offset dx,dy,dz          target = first current_pose position + offset [m]; orientation kept
  --target x,y,z             absolute target [m]; orientation: --orientation or the first one seen
  --orientation x,y,z,w      target orientation (quaternion)
  --frame-id ID              header.frame_id of the reference (default: empty = base link)
  --tolerance M              reached when |p - target| <= M [m] (default 0.005)
  --settle N                 ... for N consecutive controller_state samples (default 5)
  --full-state N             also require N decoded full_state samples (default 1; 0: do not
                             subscribe)
  --timeout S                give up after S seconds (default 60)
  --print-period S           at most one state line per topic per S seconds (default 0.2)
  --hashes FILE              ros2_type_hashes.json: advertise USER_DATA typehash=... like ROS 2
  --max-participant-index N  Cyclone discovery ports to announce to (default 30)`;

function parseArguments(argv) {
  const options = {
    domain: Number(process.env.ROS_DOMAIN_ID ?? 0),
    msgDirs: [],
    frameId: "",
    tolerance: 0.005,
    settle: 5,
    fullState: 1,
    timeout: 60,
    printPeriod: 0.2,
    maxParticipantIndex: 30,
  };
  const vector = (text, size, name) => {
    const values = text.split(",").map(Number);
    if (values.length !== size || values.some((v) => !Number.isFinite(v))) {
      throw new Error(`${name} needs ${size} comma-separated numbers, got "${text}"`);
    }
    return values;
  };
  for (let i = 0; i < argv.length; i += 2) {
    const [name, value] = [argv[i], argv[i + 1]];
    if (value === undefined) {
      throw new Error(`${name} needs a value`);
    }
    switch (name) {
      case "--fq": options.fq = value.replace(/\/+$/, ""); break;
      case "--domain": options.domain = Number(value); break;
      case "--msg-dir": options.msgDirs.push(value); break;
      case "--offset": options.offset = vector(value, 3, name); break;
      case "--target": options.target = vector(value, 3, name); break;
      case "--orientation": options.orientation = vector(value, 4, name); break;
      case "--frame-id": options.frameId = value; break;
      case "--tolerance": options.tolerance = Number(value); break;
      case "--settle": options.settle = Number(value); break;
      case "--full-state": options.fullState = Number(value); break;
      case "--timeout": options.timeout = Number(value); break;
      case "--print-period": options.printPeriod = Number(value); break;
      case "--hashes": options.hashes = JSON.parse(fs.readFileSync(value, "utf8")); break;
      case "--max-participant-index": options.maxParticipantIndex = Number(value); break;
      default: throw new Error(`unknown option ${name}`);
    }
  }
  const targets = [options.offset, options.target].filter((t) => t !== undefined).length;
  if (!options.fq?.startsWith("/") || targets !== 1) {
    throw new Error("need --fq /NAME and exactly one of --offset, --target");
  }
  if (options.msgDirs.length === 0) {
    const ros2 = path.resolve(__dirname, "../../..");
    options.msgDirs = [path.join(ros2, "msg"), path.join(ros2, "interfaces")];
  }
  return options;
}

// The full definition of a ROS 2 type ("pkg/msg/Name") as @foxglove/rosmsg parses it: the type's
// .msg text, then every type it uses, each after a "MSG: pkg/Name" separator (the ROS 1 layout
// rosmsg reads, with ROS 2 field syntax). builtin_interfaces/Time is rosmsg's primitive "time".
function loadDefinition(rosType, msgDirs) {
  const read = (pkg, name) => {
    for (const dir of msgDirs) {
      const file = path.join(dir, pkg, "msg", `${name}.msg`);
      if (fs.existsSync(file)) {
        return fs.readFileSync(file, "utf8");
      }
    }
    throw new Error(`no ${pkg}/msg/${name}.msg in ${msgDirs.join(", ")}`);
  };
  const [rootPackage, , rootName] = rosType.split("/");
  const texts = new Map(); // "pkg/Name" -> text, in discovery order
  const visit = (pkg, name) => {
    const key = `${pkg}/${name}`;
    if (texts.has(key)) {
      return;
    }
    const text = read(pkg, name);
    texts.set(key, text);
    const [definition] = parse(text, { ros2: true, skipTypeFixup: true });
    for (const field of definition.definitions) {
      if (field.isComplex) {
        const parts = field.type.split("/");
        visit(parts.length > 1 ? parts[0] : pkg, parts[parts.length - 1]);
      }
    }
  };
  visit(rootPackage, rootName);
  const separator = "\n" + "=".repeat(80) + "\n";
  const [root, ...dependencies] = [...texts.entries()];
  const full = [root[1], ...dependencies.map(([key, text]) => `MSG: ${key}\n${text}`)];
  return parse(full.join(separator), { ros2: true });
}

// A reliable, volatile, keep-last-1 writer, built as rtps's Participant builds its builtin ones:
// announced on the builtin publications writer (SEDP), matched by topic and type name to the
// remote readers the participant discovers; the participant answers ACKNACKs for it.
class Publisher {
  constructor(participant, topic, dataType, definition, typeHash) {
    this.participant = participant;
    this.topicName = rosTopicToDds(topic);
    this.typeName = rosTypeToDds(dataType);
    this.serializer = new MessageWriter(definition);
    const kind = rtps.EntityKind.AppdefWriterNoKey;
    this.entityId = rtps.makeEntityId(participant.nextEndpointId++, kind);
    const attributes = participant.attributes;
    this.guid = rtps.makeGuid(attributes.guidPrefix, this.entityId);
    this.writer = new rtps.Writer({
      guidPrefix: attributes.guidPrefix,
      entityId: this.entityId,
      topicName: this.topicName,
      typeName: this.typeName,
      durability: rtps.Durability.Volatile,
      reliability: { kind: rtps.Reliability.Reliable, maxBlockingTime: { sec: 0, nsec: 100e6 } },
      history: { kind: rtps.HistoryKind.KeepLast, depth: 1 },
      protocolVersion: attributes.protocolVersion,
      vendorId: attributes.vendorId,
    });
    // The participant answers ACKNACKs for the writers in this map.
    participant._writers.set(this.entityId, this.writer);
    this.matched = new Set();
    participant.on("discoveredSubscription", (endpoint) => this.match(endpoint));
    for (const view of participant._participants.values()) {
      for (const reader of view.remoteReaders.values()) {
        this.match(reader.attributes);
      }
    }
    this.announce(typeHash);
  }

  announce(typeHash) {
    const parameters = new rtps.Parameters();
    parameters.topicName(this.topicName);
    parameters.typeName(this.typeName);
    parameters.durability(rtps.Durability.Volatile);
    parameters.reliability(this.writer.attributes.reliability);
    parameters.history(this.writer.attributes.history);
    parameters.protocolVersion(this.participant.attributes.protocolVersion);
    parameters.vendorId(this.participant.attributes.vendorId);
    parameters.endpointGuid(this.guid);
    if (typeHash !== undefined) {
      parameters.userDataString(`typehash=${typeHash};`);
    }
    parameters.adlinkEntityFactory(1);
    parameters.finish();
    const announcerId = rtps.EntityIdBuiltin.PublicationsWriter;
    const announcer = this.participant._writers.get(announcerId);
    announcer.history.set({
      timestamp: timeNow(),
      kind: rtps.ChangeKind.Alive,
      writerGuid: rtps.makeGuid(this.participant.attributes.guidPrefix, announcerId),
      sequenceNumber: announcer.history.nextSequenceNum(),
      data: parameters.data,
      instanceHandle: this.guid,
    });
    void this.participant.sendMetatrafficChanges(announcer);
  }

  match(endpoint) {
    if (endpoint.topicName !== this.topicName || endpoint.typeName !== this.typeName) {
      return;
    }
    const view = this.participant._participants.get(endpoint.guidPrefix);
    const readerGuid = rtps.makeGuid(endpoint.guidPrefix, endpoint.entityId);
    if (view === undefined || this.matched.has(readerGuid)) {
      return;
    }
    this.matched.add(readerGuid);
    rtps.addToMultiMap(this.entityId, endpoint.entityId, view.localWriterIdToRemoteReaderIds);
    emit({ event: "matched", topic: this.topicName, reader: readerGuid });
  }

  async publish(message) {
    const history = this.writer.history;
    history.set({
      timestamp: timeNow(),
      kind: rtps.ChangeKind.Alive,
      writerGuid: this.guid,
      sequenceNumber: history.nextSequenceNum(),
      data: this.serializer.writeMessage(message),
      instanceHandle: undefined,
    });
    await this.participant.sendDefaultChanges(this.writer);
  }
}

// RosNode.subscribe with a volatile reader: @foxglove/ros2 1.0.8 hard-codes transient-local, which
// Cyclone (like any DDS) does not match with the node's volatile writers (offered durability below
// the requested one), so no sample would ever arrive. A volatile reader matches both. rtps's
// readers also hand over retransmitted older samples after newer ones (the first ACKNACK asks
// for the writer's whole history): those are dropped, so onMessage sees each writer in order.
const INFINITE = { sec: 0x7fffffff, nsec: 0xffffffff };

function subscribe(node, topic, dataType, msgDefinition, onMessage) {
  const subscribeOpts = {
    topicName: rosTopicToDds(topic),
    typeName: rosTypeToDds(dataType),
    durability: rtps.Durability.Volatile,
    reliability: { kind: rtps.Reliability.Reliable, maxBlockingTime: INFINITE },
    history: { kind: rtps.HistoryKind.KeepLast, depth: 10 },
  };
  const participant = node._participant;
  const readerEntityId = participant.subscribe(subscribeOpts);
  const newest = new Map(); // writer GUID -> highest sequence number delivered
  let inOrder = false;
  // Registered before the Subscription's own listener, so it runs first for the same sample.
  participant.on("userData", ({ subscription, publication, writerSeqNumber }) => {
    if (subscription.entityId === readerEntityId) {
      const writer = rtps.makeGuid(publication.guidPrefix, publication.entityId);
      inOrder = writerSeqNumber > (newest.get(writer) ?? 0n);
      if (inOrder) {
        newest.set(writer, writerSeqNumber);
      }
    }
  });
  const subscription = new Subscription({ subscribeOpts, readerEntityId, participant,
                                          msgDefinition });
  subscription.on("message", (_time, message) => inOrder && onMessage(message));
  node.subscriptions.set(topic, subscription);
}

// @foxglove/rtps drops every discovered endpoint whose announcement has no reliability QoS, but
// DDS omits QoS that equal the default (Cyclone does): the node's writers (reliable, 100 ms, the
// writer default) would never be seen. Parse them with the DDS defaults instead: reliable with a
// 100 ms max_blocking_time for writers, best effort for readers.
function acceptDefaultReliability(participant) {
  const reliability = rtps.ParametersView.prototype.reliability;
  const withDefault = (handle, fallback) => (...args) => {
    rtps.ParametersView.prototype.reliability = function () {
      return reliability.call(this) ?? fallback;
    };
    try {
      return handle(...args);
    } finally {
      rtps.ParametersView.prototype.reliability = reliability;
    }
  };
  participant.handlePublication = withDefault(participant.handlePublication,
    { kind: rtps.Reliability.Reliable, maxBlockingTime: { sec: 0, nsec: 100e6 } });
  participant.handleSubscription = withDefault(participant.handleSubscription,
    { kind: rtps.Reliability.BestEffort, maxBlockingTime: { sec: 0, nsec: 0 } });
}

// Binds to 127.0.0.1 and joins no multicast group: loopback only (see the top).
async function createLoopbackSocket(options) {
  const socket = await UdpSocketNode.Create(options);
  const bind = socket.bind.bind(socket);
  socket.bind = (bindOptions) => bind({ ...bindOptions, address: "127.0.0.1" });
  socket.addMembership = async () => {};
  return socket;
}

// SPDP by unicast to every Cyclone discovery port on 127.0.0.1, with rtps's own broadcast code.
function unicastAnnouncement(participant, domain, maxParticipantIndex) {
  const broadcast = rtps.Participant.prototype.broadcastParticipant;
  const locators = [];
  for (let index = 0; index <= maxParticipantIndex; index++) {
    const port = rtps.discoveryUnicastPort(domain, index);
    locators.push(rtps.locatorFromUdpAddress({ address: "127.0.0.1", family: "IPv4", port }));
  }
  return async () => {
    for (const locator of locators) {
      participant._multicastLocator = locator;
      await broadcast.call(participant, participant.attributes);
    }
  };
}

function timeNow() {
  const ms = Date.now();
  return { sec: Math.floor(ms / 1000), nsec: (ms % 1000) * 1e6 };
}

// uint64 (cycle) decodes as BigInt, float64[] as Float64Array: JSON has neither.
function emit(object) {
  const plain = (_key, value) => {
    if (typeof value === "bigint") {
      return Number(value);
    }
    return ArrayBuffer.isView(value) ? Array.from(value) : value;
  };
  process.stdout.write(JSON.stringify(object, plain) + "\n");
}

const position = (pose) => [pose.position.x, pose.position.y, pose.position.z];
const vector3 = (v) => [v.x, v.y, v.z];
const wrench = (w) => ({ force: vector3(w.force), torque: vector3(w.torque) });
// The fields appended to the full state after the timing (ControllerState.msg): the torque
// shaping, the hold and the safety layer, the last of them the message's last field.
const limitsOf = (m) => ({ torque_shaping: m.torque_shaping,
                           torque_shaping_scale: m.torque_shaping_scale, holding: m.holding });
const safetyOf = (m) => ({
  reference_speed_limited: m.reference_speed_limited,
  translation_drive_scale: m.translation_drive_scale,
  rotation_drive_scale: m.rotation_drive_scale,
  braking: m.braking,
  force_scale: m.force_scale,
  torque_scale: m.torque_scale,
  reference_clipped: m.reference_clipped,
  workspace_penetration: vector3(m.workspace_penetration),
  wall_force: vector3(m.wall_force),
  tank_level: m.tank_level,
  tank_draw: m.tank_draw,
  stiffness_change_scale: m.stiffness_change_scale,
  payload_mass: m.payload_mass,
  payload_center_of_mass: vector3(m.payload_center_of_mass),
  payload_estimate_valid: m.payload_estimate_valid,
  payload_estimate_mass: m.payload_estimate_mass,
  payload_estimate_center_of_mass: vector3(m.payload_estimate_center_of_mass),
});

async function main() {
  let options;
  try {
    options = parseArguments(process.argv.slice(2));
  } catch (error) {
    process.stderr.write(`peer.js: ${error.message}\n${USAGE}\n`);
    process.exit(2);
  }
  const types = {
    pose: "geometry_msgs/msg/PoseStamped",
    state: "cartesian_impedance_controller/msg/ControllerState",
    full: "cartesian_impedance_msgs/msg/ControllerState",
  };
  const definitions = {};
  for (const [key, type] of Object.entries(types)) {
    definitions[key] = loadDefinition(type, options.msgDirs);
  }

  const node = new RosNode({
    name: "foxglove_peer",
    domainId: options.domain,
    addresses: ["127.0.0.1"],
    udpSocketCreate: createLoopbackSocket,
  });
  const participant = node._participant;
  const announce = unicastAnnouncement(participant, options.domain, options.maxParticipantIndex);
  participant.broadcastParticipant = announce; // replaces the multicast announcement at start
  acceptDefaultReliability(participant);
  participant.on("error", (error) => process.stderr.write(`peer.js: rtps: ${error}\n`));
  node.on("discoveredParticipant", (attributes) =>
    emit({ event: "participant", guidPrefix: attributes.guidPrefix }));
  await node.start();
  const announcer = setInterval(() => void announce(), 1000);

  const typeHash = (type) => options.hashes?.[type]?.type_hash;
  const publisher = new Publisher(participant, `${options.fq}/reference_pose`, types.pose,
                                  definitions.pose, typeHash(types.pose));

  let target;
  const [qx, qy, qz, qw] = options.orientation ?? [];
  let orientation = options.orientation && { x: qx, y: qy, z: qz, w: qw };
  if (options.target !== undefined) {
    target = options.target;
  }
  let inTolerance = 0;
  let fullStates = 0;
  let lastState;
  let finished = false;
  let publishing;
  let timer;
  const lastPrinted = { controller_state: -Infinity, full_state: -Infinity };
  const due = (topic) => {
    const now = performance.now() / 1000;
    if (now - lastPrinted[topic] < options.printPeriod) {
      return false;
    }
    lastPrinted[topic] = now;
    return true;
  };

  const finish = async (result, code) => {
    if (finished) {
      return;
    }
    finished = true;
    clearInterval(announcer);
    clearInterval(publishing);
    clearTimeout(timer);
    emit({
      result,
      target,
      position: lastState && position(lastState.current_pose),
      distance: lastState && distance(lastState.current_pose),
      full_state_samples: fullStates,
    });
    await node.shutdown();
    process.exit(code);
  };
  const distance = (pose) => Math.hypot(...position(pose).map((p, i) => p - target[i]));

  subscribe(node, `${options.fq}/controller_state`, types.state, definitions.state, (message) => {
    lastState = message;
    const pose = message.current_pose;
    if (orientation === undefined) {
      orientation = pose.orientation;
    }
    if (target === undefined) {
      target = position(pose).map((p, i) => p + options.offset[i]);
      emit({ event: "target", start: position(pose), target, orientation });
    }
    const d = distance(pose);
    inTolerance = d <= options.tolerance ? inTolerance + 1 : 0;
    const reached = inTolerance >= options.settle && fullStates >= options.fullState;
    if (reached || due("controller_state")) {
      emit({ topic: "controller_state", stamp: message.header.stamp, position: position(pose),
             distance: d, cartesian_stiffness: wrench(message.cartesian_stiffness) });
    }
    if (reached) {
      void finish("reached", 0);
    }
  });
  if (options.fullState > 0) {
    const topic = `${options.fq}/full_state`;
    subscribe(node, topic, types.full, definitions.full, (message) => {
      fullStates++;
      if (fullStates === 1 || due("full_state")) {
        emit({ topic: "full_state", status: message.status, cycle: message.cycle,
               time: message.time, position: position(message.current_pose),
               joints: message.joint_state.name.length,
               cartesian_stiffness: wrench(message.cartesian_stiffness),
               realtime: message.realtime, limits: limitsOf(message),
               safety: safetyOf(message) });
      }
    });
  }

  // The reference, repeated at 10 Hz: the node keeps the latest, and a sample sent before the
  // node's reader matched is not lost for good.
  publishing = setInterval(() => {
    if (target === undefined || orientation === undefined) {
      return;
    }
    void publisher.publish({
      header: { stamp: timeNow(), frame_id: options.frameId },
      pose: { position: { x: target[0], y: target[1], z: target[2] }, orientation },
    });
  }, 100);
  timer = setTimeout(() => void finish("timeout", 1), options.timeout * 1000);
  for (const signal of ["SIGINT", "SIGTERM"]) {
    process.on(signal, () => void finish("interrupted", 1));
  }
}

main().catch((error) => {
  process.stderr.write(`peer.js: ${error.stack ?? error}\n`);
  process.exit(1);
});
