#pragma once
/// @file
/// The node in ROS 2's graph: `ros_discovery_info`, the topic on which every ROS 2 participant
/// says which nodes it hosts and which of its readers and writers belong to each. DDS discovery
/// alone shows endpoints, not nodes; `ros2 node list` and `ros2 node info` join the two through
/// these GIDs (an endpoint's GID is its DDS GUID, zero-padded to the distribution's width).

#include <dds/dds.h>

#include <string>
#include <string_view>
#include <vector>

#include "dds.hpp"

namespace cartesian_impedance_ros2 {

/// The ROS 2 distribution whose graph layout the node announces. Only the GID's width differs:
/// 24 octets in Humble, 16 from Iron on.
enum class RosDistro { humble, iron, jazzy, kilted, lyrical, rolling };

/// The current LTS (May 2026).
constexpr RosDistro kDefaultRosDistro = RosDistro::lyrical;

/// @throws cartesian_impedance::Error naming `text` and the distributions known.
RosDistro ros_distro_from_string(std::string_view text);
const char* to_string(RosDistro distro);
/// Octets of rmw_dds_common/msg/Gid in `distro`.
int gid_size(RosDistro distro);

/// The writer of ros_discovery_info (type rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_;
/// reliable, transient local, keep last 1, as rmw_dds_common's QoS), so that a participant that
/// joins later still reads the last announcement.
class GraphAnnouncer {
 public:
  GraphAnnouncer() = default;
  /// @throws cartesian_impedance::Error if DDS refuses the writer.
  GraphAnnouncer(const Participant& participant, RosDistro distro);

  /// Announces one node (namespace "/..." and name) owning `readers` and `writers`, replacing the
  /// last announcement. False if DDS did not take it or an entity has no GUID.
  bool announce(const std::string& node_namespace, const std::string& node_name,
                const std::vector<dds_entity_t>& readers,
                const std::vector<dds_entity_t>& writers) const;

  dds_entity_t writer() const noexcept { return writer_.get(); }

 private:
  RosDistro distro_ = kDefaultRosDistro;
  Entity writer_;
};

}  // namespace cartesian_impedance_ros2
