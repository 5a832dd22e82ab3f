// The node in ROS 2's graph, as `ros2 node list` and `ros2 node info` build it: a peer of the
// test's own reads the node's ros_discovery_info sample as bytes and decodes them from the wire
// description of rmw_dds_common/msg/ParticipantEntitiesInfo (CDR, little endian):
//
//   Gid gid                                   octet[W]   (W = 16 from Iron on, 24 in Humble)
//   NodeEntitiesInfo[] node_entities_info_seq uint32 count, then per node:
//     string<=256 node_namespace              uint32 length (with the NUL), the characters
//     string<=256 node_name
//     Gid[] reader_gid_seq                    uint32 count, count x octet[W]
//     Gid[] writer_gid_seq
//
// and joins the GIDs with what DDS discovery itself reports (the DCPSPublication and
// DCPSSubscription built-in topics: each endpoint's GUID, its participant's GUID, its topic), as
// ROS 2's graph cache does. None of the node's code decodes here.

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "graph_humble.h"
#include "harness.hpp"

namespace cartesian_impedance_ros2::test {
namespace {

using Guid = std::array<std::uint8_t, 16>;

struct GraphNode {
  std::string node_namespace;
  std::string node_name;
  std::vector<std::vector<std::uint8_t>> readers;
  std::vector<std::vector<std::uint8_t>> writers;
};

struct GraphSample {
  std::vector<std::uint8_t> gid;
  std::vector<GraphNode> nodes;
};

// A CDR reader over one serialized sample; every read checks the bounds.
class Cdr {
 public:
  explicit Cdr(const std::vector<std::uint8_t>& bytes) : bytes_(bytes) {}
  bool little_endian_header() {
    // Encapsulation: 0x0001 is plain CDR, little endian (what ROS 2's DDS layers write).
    if (bytes_.size() < 4 || bytes_[0] != 0 || bytes_[1] != 1) return false;
    at_ = 4;
    return true;
  }
  std::optional<std::uint32_t> uint32() {
    const std::size_t aligned = 4 + ((at_ - 4 + 3) / 4) * 4;  // aligned from the payload start
    if (aligned + 4 > bytes_.size()) return std::nullopt;
    std::uint32_t value = 0;
    for (int i = 3; i >= 0; --i) value = (value << 8) | bytes_[aligned + i];
    at_ = aligned + 4;
    return value;
  }
  std::optional<std::vector<std::uint8_t>> octets(std::size_t count) {
    if (at_ + count > bytes_.size()) return std::nullopt;
    std::vector<std::uint8_t> out(bytes_.begin() + at_, bytes_.begin() + at_ + count);
    at_ += count;
    return out;
  }
  std::optional<std::string> string() {
    const auto length = uint32();
    if (!length || *length == 0 || at_ + *length > bytes_.size() ||
        bytes_[at_ + *length - 1] != 0) {
      return std::nullopt;
    }
    std::string out(reinterpret_cast<const char*>(bytes_.data() + at_), *length - 1);
    at_ += *length;
    return out;
  }
  // What is left after the last field: CDR pads a sample to a multiple of 4 only.
  std::size_t left() const { return bytes_.size() - at_; }

 private:
  const std::vector<std::uint8_t>& bytes_;
  std::size_t at_ = 0;
};

std::optional<GraphSample> decode(const std::vector<std::uint8_t>& bytes, std::size_t gid_size) {
  Cdr cdr(bytes);
  if (!cdr.little_endian_header()) return std::nullopt;
  GraphSample sample;
  const auto gid = cdr.octets(gid_size);
  const auto nodes = cdr.uint32();
  if (!gid || !nodes || *nodes > 1024) return std::nullopt;
  sample.gid = *gid;
  const auto gids = [&](std::vector<std::vector<std::uint8_t>>& out) {
    const auto count = cdr.uint32();
    if (!count || *count > 4096) return false;
    for (std::uint32_t i = 0; i < *count; ++i) {
      const auto one = cdr.octets(gid_size);
      if (!one) return false;
      out.push_back(*one);
    }
    return true;
  };
  for (std::uint32_t i = 0; i < *nodes; ++i) {
    GraphNode node;
    const auto ns = cdr.string();
    const auto name = cdr.string();
    if (!ns || !name) return std::nullopt;
    node.node_namespace = *ns;
    node.node_name = *name;
    if (!gids(node.readers) || !gids(node.writers)) return std::nullopt;
    sample.nodes.push_back(std::move(node));
  }
  if (cdr.left() > 3) return std::nullopt;  // more than padding: not this layout
  return sample;
}

struct Endpoint {
  Guid guid{};
  Guid participant{};
  std::string topic;
  std::string type;
  std::string user_data;
  bool reliable = false;
  bool transient_local = false;
  int depth = 0;
};

Guid guid_of(const dds_guid_t& guid) {
  Guid out;
  std::memcpy(out.data(), guid.v, out.size());
  return out;
}

// A peer participant in the node's domain: the graph topic as bytes and DDS's built-in topics.
class GraphPeer {
 public:
  // The reader's descriptor only has to carry ROS 2's type name and accept the bytes (Cyclone
  // checks a sample against it before handing it over); decoding is decode()'s.
  explicit GraphPeer(bool humble) : humble_(humble), participant_(make_participant()) {
    static dds_topic_descriptor_t humble_type =
        cartesian_impedance_humble_ParticipantEntitiesInfo__desc;
    humble_type.m_typename = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";
    const dds_entity_t topic = dds_create_topic(
        participant_.get(),
        humble ? &humble_type : &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc,
        "ros_discovery_info", nullptr, nullptr);
    EXPECT_GT(topic, 0);
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
    dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
    graph_ = dds_create_reader(participant_.get(), topic, qos, nullptr);
    dds_delete_qos(qos);
    EXPECT_GT(graph_, 0);
    publications_ =
        dds_create_reader(participant_.get(), DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
    subscriptions_ =
        dds_create_reader(participant_.get(), DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, nullptr, nullptr);
  }

  // Every graph sample received so far, as bytes, newest last.
  const std::vector<std::vector<std::uint8_t>>& samples() {
    ddsi_serdata* serdata[8] = {};
    dds_sample_info_t infos[8];
    for (;;) {
      const dds_return_t n = dds_takecdr(graph_, serdata, 8, infos, DDS_ANY_STATE);
      if (n <= 0) break;
      for (dds_return_t i = 0; i < n; ++i) {
        if (infos[i].valid_data) {
          std::vector<std::uint8_t> bytes(ddsi_serdata_size(serdata[i]));
          ddsi_serdata_to_ser(serdata[i], 0, bytes.size(), bytes.data());
          samples_.push_back(std::move(bytes));
        }
        ddsi_serdata_unref(serdata[i]);
      }
    }
    return samples_;
  }

  // The newest announcement of the node `name` in namespace `ns`.
  std::optional<GraphSample> node(const std::string& ns, const std::string& name) {
    for (auto bytes = samples().rbegin(); bytes != samples_.rend(); ++bytes) {
      const auto sample = decode(*bytes, humble_ ? 24 : 16);
      if (!sample) continue;
      for (const GraphNode& node : sample->nodes) {
        if (node.node_namespace == ns && node.node_name == name) return sample;
      }
    }
    return std::nullopt;
  }

  // The endpoints DDS discovery reports, by GUID.
  std::map<Guid, Endpoint> publications() { return endpoints(publications_, pubs_); }
  std::map<Guid, Endpoint> subscriptions() { return endpoints(subscriptions_, subs_); }

 private:
  std::map<Guid, Endpoint> endpoints(dds_entity_t reader, std::map<Guid, Endpoint>& known) {
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    for (;;) {
      const dds_return_t n = dds_take(reader, samples, infos, 16, 16);
      if (n <= 0) break;
      for (dds_return_t i = 0; i < n; ++i) {
        if (!infos[i].valid_data) continue;
        const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
        Endpoint endpoint;
        endpoint.guid = guid_of(e->key);
        endpoint.participant = guid_of(e->participant_key);
        endpoint.topic = e->topic_name;
        endpoint.type = e->type_name;
        void* data = nullptr;
        size_t size = 0;
        if (dds_qget_userdata(e->qos, &data, &size) && data != nullptr) {
          endpoint.user_data.assign(static_cast<const char*>(data), size);
          dds_free(data);
        }
        dds_reliability_kind_t reliability{};
        dds_duration_t blocking = 0;
        endpoint.reliable = dds_qget_reliability(e->qos, &reliability, &blocking) &&
                            reliability == DDS_RELIABILITY_RELIABLE;
        dds_durability_kind_t durability{};
        endpoint.transient_local = dds_qget_durability(e->qos, &durability) &&
                                   durability == DDS_DURABILITY_TRANSIENT_LOCAL;
        dds_history_kind_t history{};
        int32_t depth = 0;
        if (dds_qget_history(e->qos, &history, &depth) && history == DDS_HISTORY_KEEP_LAST) {
          endpoint.depth = depth;
        }
        known[endpoint.guid] = endpoint;
      }
      dds_return_loan(reader, samples, n);
    }
    return known;
  }

  // In the node's private domain (ROS_DOMAIN_ID, set by use_private_domain()).
  static Participant make_participant() {
    use_private_domain();
    return Participant();
  }

  bool humble_;
  Participant participant_;
  dds_entity_t graph_ = 0;
  dds_entity_t publications_ = 0;
  dds_entity_t subscriptions_ = 0;
  std::vector<std::vector<std::uint8_t>> samples_;
  std::map<Guid, Endpoint> pubs_, subs_;
};

std::string sim_params() {
  return repository() + "/ros2/config/sim_panda.yaml";
}

std::set<Guid> as_guids(const std::vector<std::vector<std::uint8_t>>& gids) {
  std::set<Guid> out;
  for (const auto& gid : gids) {
    Guid guid;
    std::copy_n(gid.begin(), guid.size(), guid.begin());
    out.insert(guid);
  }
  return out;
}

// The node's endpoints as DDS discovery sees them: those of its participant, without the graph
// topic's own writer (a participant's, not a node's, as in rmw_cyclonedds).
std::map<Guid, Endpoint> of_participant(const std::map<Guid, Endpoint>& all,
                                        const Guid& participant) {
  std::map<Guid, Endpoint> out;
  for (const auto& [guid, endpoint] : all) {
    if (endpoint.participant == participant && endpoint.topic != "ros_discovery_info") {
      out.emplace(guid, endpoint);
    }
  }
  return out;
}

// GUIDs in hex, for readable failures.
std::set<std::string> hex(const std::set<Guid>& guids) {
  std::set<std::string> out;
  for (const Guid& guid : guids) {
    std::string text;
    char digits[3];
    for (const std::uint8_t byte : guid) {
      std::snprintf(digits, sizeof digits, "%02x", byte);
      text += digits;
    }
    out.insert(text);
  }
  return out;
}

std::set<std::string> topics(const std::map<Guid, Endpoint>& endpoints) {
  std::set<std::string> out;
  for (const auto& entry : endpoints) out.insert(entry.second.topic);
  return out;
}

// What the two checks share: the announced node, and its GIDs equal to the endpoints DDS reports
// for its participant, in both directions. Returns the participant's GUID.
Guid expect_node_and_endpoints(GraphPeer& peer, const std::string& ns, const std::string& name,
                               std::size_t gid_size) {
  std::optional<GraphSample> sample;
  EXPECT_TRUE(eventually(20.0, [&] { return (sample = peer.node(ns, name)).has_value(); }))
      << "no ros_discovery_info sample announces " << ns << " " << name << " with a GID of "
      << gid_size << " octets; samples received: " << peer.samples().size();
  if (!sample) return {};
  EXPECT_EQ(sample->gid.size(), gid_size);
  EXPECT_TRUE(std::all_of(sample->gid.begin() + 16, sample->gid.end(), [](auto b) {
    return b == 0;
  })) << "a GID is the GUID padded with zeros";
  EXPECT_EQ(sample->nodes.size(), 1u) << "one node per process";
  const GraphNode& node = sample->nodes.front();
  Guid participant;
  std::copy_n(sample->gid.begin(), participant.size(), participant.begin());

  const std::set<Guid> readers = as_guids(node.readers);
  const std::set<Guid> writers = as_guids(node.writers);
  std::map<Guid, Endpoint> publications, subscriptions;
  const bool complete = eventually(10.0, [&] {
    publications = of_participant(peer.publications(), participant);
    subscriptions = of_participant(peer.subscriptions(), participant);
    return publications.size() >= writers.size() && subscriptions.size() >= readers.size();
  });
  EXPECT_TRUE(complete) << "DDS discovery did not report the announced endpoints";
  std::set<Guid> discovered_writers, discovered_readers;
  for (const auto& entry : publications) discovered_writers.insert(entry.first);
  for (const auto& entry : subscriptions) discovered_readers.insert(entry.first);
  EXPECT_EQ(hex(writers), hex(discovered_writers))
      << "writer_gid_seq is not the participant's writers";
  EXPECT_EQ(hex(readers), hex(discovered_readers))
      << "reader_gid_seq is not the participant's readers";
  EXPECT_FALSE(writers.empty());
  EXPECT_FALSE(readers.empty());
  return participant;
}

TEST(Ros2Graph, NodeListAndNodeInfoSeeTheNodeWithEveryTopicItUses) {
  NodeProcess process(
      {"--ros-args", "-r", "__ns:=/left", "-r", "__node:=arm", "--params-file", sim_params()});
  GraphPeer peer(false);
  const Guid participant = expect_node_and_endpoints(peer, "/left", "arm", 16);

  // What `ros2 node info /left/arm` lists, by topic.
  const std::set<std::string> published = topics(of_participant(peer.publications(), participant));
  const std::set<std::string> subscribed =
      topics(of_participant(peer.subscriptions(), participant));
  for (const char* topic : {"rt/left/arm/full_state", "rt/left/arm/controller_state",
                            "rt/left/arm/commanded_torques", "rt/left/joint_states"}) {
    EXPECT_EQ(published.count(topic), 1u) << topic;
  }
  for (const char* topic :
       {"rt/left/arm/reference_pose", "rt/left/arm/set_cartesian_stiffness",
        "rt/left/arm/set_config", "rt/left/joint_trajectory", "rt/left/arm/resume"}) {
    EXPECT_EQ(subscribed.count(topic), 1u) << topic;
  }

  // The graph writer itself: ROS 2's type name, rmw_dds_common's QoS, Jazzy's type hash.
  bool found = false;
  for (const auto& [guid, endpoint] : peer.publications()) {
    if (endpoint.participant != participant || endpoint.topic != "ros_discovery_info") continue;
    found = true;
    EXPECT_EQ(endpoint.type, "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_");
    EXPECT_TRUE(endpoint.reliable);
    EXPECT_TRUE(endpoint.transient_local);
    EXPECT_EQ(endpoint.depth, 1);
    EXPECT_EQ(endpoint.user_data,
              "typehash=RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e;");
  }
  EXPECT_TRUE(found) << "no ros_discovery_info writer of the node's participant";
}

// The simulated robot is a node of the graph too, as a robot's driver is.
TEST(Ros2Graph, TheSimulatedRobotIsANodeWithItsTopics) {
  NodeProcess robot(CARTESIAN_IMPEDANCE_ROS2_SIM_ROBOT,
                    {"--ros-args", "-r", "__ns:=/robot", "--params-file", sim_params()});
  GraphPeer peer(false);
  const Guid participant = expect_node_and_endpoints(peer, "/robot", "sim_robot", 16);
  const std::set<std::string> published = topics(of_participant(peer.publications(), participant));
  EXPECT_EQ(published.count("rt/robot/joint_states"), 1u);
  EXPECT_EQ(published.count("rt/robot/sim_robot/contact_wrench"), 1u);
  EXPECT_EQ(topics(of_participant(peer.subscriptions(), participant)),
            std::set<std::string>{"rt/robot/effort_controller/commands"});
}

TEST(Ros2Graph, HumbleLayoutHasTwentyFourOctetGidsAndNoTypeHash) {
  NodeProcess process({"--ros-args", "--params-file", sim_params(), "-p", "ros_distro:=humble"});
  GraphPeer peer(true);
  const Guid participant =
      expect_node_and_endpoints(peer, "/", "cartesian_impedance_controller", 24);
  for (const auto& [guid, endpoint] : peer.publications()) {
    if (endpoint.participant == participant && endpoint.topic == "ros_discovery_info") {
      EXPECT_EQ(endpoint.user_data, "") << "Humble announces no type hash";
    }
  }
  // The other layout does not read it: a 16-octet decoder must not find this node.
  for (const auto& bytes : peer.samples()) {
    const auto misread = decode(bytes, 16);
    if (!misread) continue;
    for (const GraphNode& node : misread->nodes) {
      EXPECT_NE(node.node_name, "cartesian_impedance_controller");
    }
  }
}

}  // namespace
}  // namespace cartesian_impedance_ros2::test
