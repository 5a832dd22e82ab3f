#include "graph.hpp"

#include <algorithm>
#include <cstring>
#include <vector>

#include <cartesian_impedance/core/error.hpp>

#include "graph_humble.h"

namespace cartesian_impedance_ros2 {
namespace {

namespace ci = cartesian_impedance;

constexpr const char* kDistroNames[] = {"humble", "iron", "jazzy", "kilted", "lyrical", "rolling"};
constexpr const char* kTopic = "ros_discovery_info";

using HumbleInfo = cartesian_impedance_humble_ParticipantEntitiesInfo_;
using LaterInfo = rmw_dds_common_msg_dds__ParticipantEntitiesInfo_;

// Humble's descriptor under ROS 2's type name: peers match types by name (the descriptors carry
// no type information), so this is the type Humble's rmw_dds_common announces.
const dds_topic_descriptor_t* humble_descriptor() {
  static const dds_topic_descriptor_t renamed = [] {
    dds_topic_descriptor_t copy = cartesian_impedance_humble_ParticipantEntitiesInfo__desc;
    copy.m_typename = MessageType<LaterInfo>::descriptor()->m_typename;
    return copy;
  }();
  return &renamed;
}

// GIDs as rmw_cyclonedds makes them: the entity's GUID, then zeros up to the GID's width.
template <typename Gid>
bool fill_gid(dds_entity_t entity, Gid& gid) {
  static_assert(sizeof gid.data >= sizeof(dds_guid_t));
  dds_guid_t guid{};
  if (dds_get_guid(entity, &guid) < 0) return false;
  std::memset(gid.data, 0, sizeof gid.data);
  std::memcpy(gid.data, guid.v, sizeof guid.v);
  return true;
}

template <typename Info>
bool write(dds_entity_t writer, dds_entity_t participant, const std::string& node_namespace,
           const std::string& node_name, const std::vector<dds_entity_t>& readers,
           const std::vector<dds_entity_t>& writers) {
  using Node = std::remove_reference_t<decltype(*Info{}.node_entities_info_seq._buffer)>;
  using Gid = std::remove_reference_t<decltype(*Node{}.reader_gid_seq._buffer)>;
  Node node{};
  if (node_namespace.size() >= sizeof node.node_namespace ||
      node_name.size() >= sizeof node.node_name) {
    return false;  // ROS 2 bounds both to 256 characters; a valid name is far shorter
  }
  std::memcpy(node.node_namespace, node_namespace.c_str(), node_namespace.size() + 1);
  std::memcpy(node.node_name, node_name.c_str(), node_name.size() + 1);
  std::vector<Gid> reader_gids(readers.size());
  std::vector<Gid> writer_gids(writers.size());
  for (std::size_t i = 0; i < readers.size(); ++i)
    if (!fill_gid(readers[i], reader_gids[i])) return false;
  for (std::size_t i = 0; i < writers.size(); ++i)
    if (!fill_gid(writers[i], writer_gids[i])) return false;
  const auto view = [](auto& sequence, auto& items) {
    sequence._maximum = sequence._length = static_cast<uint32_t>(items.size());
    sequence._buffer = items.data();
    sequence._release = false;
  };
  view(node.reader_gid_seq, reader_gids);
  view(node.writer_gid_seq, writer_gids);

  Info info{};
  if (!fill_gid(participant, info.gid)) return false;
  info.node_entities_info_seq._maximum = info.node_entities_info_seq._length = 1;
  info.node_entities_info_seq._buffer = &node;
  info.node_entities_info_seq._release = false;
  return dds_write(writer, &info) >= 0;
}

}  // namespace

RosDistro ros_distro_from_string(std::string_view text) {
  for (std::size_t i = 0; i < std::size(kDistroNames); ++i) {
    if (text == kDistroNames[i]) return static_cast<RosDistro>(i);
  }
  std::string known;
  for (const char* name : kDistroNames) known += (known.empty() ? "" : ", ") + std::string(name);
  throw ci::Error("ros_distro = '" + std::string(text) +
                  "' is not a ROS 2 distribution this node knows (" + known + ")");
}

const char* to_string(RosDistro distro) {
  return kDistroNames[static_cast<int>(distro)];
}

int gid_size(RosDistro distro) {
  return distro == RosDistro::humble ? 24 : 16;
}

GraphAnnouncer::GraphAnnouncer(const Participant& participant, RosDistro distro) : distro_(distro) {
  const bool humble = distro == RosDistro::humble;
  const dds_entity_t topic = find_or_create_topic(
      participant, humble ? humble_descriptor() : MessageType<LaterInfo>::descriptor(), kTopic);
  // Humble announces no type hash (RIHS01 came with Iron).
  dds_qos_t* qos =
      endpoint_qos(TopicQos{true, true, 1}, humble ? nullptr : MessageType<LaterInfo>::type_hash);
  const dds_entity_t writer = dds_create_writer(participant.get(), topic, qos, nullptr);
  dds_delete_qos(qos);
  writer_ = Entity(check(writer, std::string("writer of ") + kTopic));
}

bool GraphAnnouncer::announce(const std::string& node_namespace, const std::string& node_name,
                              const std::vector<dds_entity_t>& readers,
                              const std::vector<dds_entity_t>& writers) const {
  const dds_entity_t participant = dds_get_participant(writer_.get());
  if (participant < 0) return false;
  return distro_ == RosDistro::humble
             ? write<HumbleInfo>(writer_.get(), participant, node_namespace, node_name, readers,
                                 writers)
             : write<LaterInfo>(writer_.get(), participant, node_namespace, node_name, readers,
                                writers);
}

}  // namespace cartesian_impedance_ros2
