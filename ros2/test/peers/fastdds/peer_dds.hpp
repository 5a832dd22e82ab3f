#pragma once
/// @file
/// The Fast DDS side of the peer: a participant and endpoints that follow ROS 2's conventions the
/// way rmw_fastrtps does (topic "rt" + ROS name, type pkg::msg::dds_::Name_, reliable, volatile,
/// keep-last 10, XCDR1, USER_DATA typehash=...; on endpoints and enclave=/; on the participant,
/// domain ROS_DOMAIN_ID), with switches to break exactly one of those rules on purpose.

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <map>
#include <string>

#include "fastdds_type_names.hpp"

namespace fastdds_peer {

/// The data representation a writer offers. ROS 2 uses XCDR1 only; XCDR2 must not match.
enum class Representation { xcdr1, xcdr2 };

/// The DDS name and RIHS01 hash of a ROS type ("geometry_msgs/msg/PoseStamped").
/// @throws std::invalid_argument for a type the node's interface does not have.
const TypeNames& type_names(const std::string& ros_type);

/// The DDS topic of a fully-qualified ROS topic name: "rt" + name.
/// @throws std::invalid_argument if the name is not absolute.
std::string dds_topic(const std::string& ros_topic);

/// Seconds since the epoch (header stamps).
double wall_time();

/// A participant in domain ROS_DOMAIN_ID with the default participant profile of the XML file in
/// FASTRTPS_DEFAULT_PROFILES_FILE (the tests' loopback-only transport), as a ROS 2 user
/// configures rmw_fastrtps.
class Peer {
 public:
  /// @throws std::runtime_error if ROS_DOMAIN_ID is invalid or Fast DDS cannot start.
  Peer();
  ~Peer();
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;

  /// A writer of `type` (the peer takes ownership; registered under type->getName()) on
  /// `ros_topic`, announcing `type_hash`.
  eprosima::fastdds::dds::DataWriter* writer(const std::string& ros_topic,
                                             eprosima::fastdds::dds::TopicDataType* type,
                                             const std::string& type_hash,
                                             Representation representation = Representation::xcdr1);
  /// A reader of `type` (owned by the peer) on `ros_topic`, accepting XCDR1 only.
  eprosima::fastdds::dds::DataReader* reader(const std::string& ros_topic,
                                             eprosima::fastdds::dds::TopicDataType* type,
                                             const std::string& type_hash);
  std::uint32_t domain() const noexcept { return domain_; }

 private:
  eprosima::fastdds::dds::Topic* topic(const std::string& ros_topic,
                                       eprosima::fastdds::dds::TopicDataType* type);

  std::uint32_t domain_ = 0;
  eprosima::fastdds::dds::DomainParticipant* participant_ = nullptr;
  eprosima::fastdds::dds::Publisher* publisher_ = nullptr;
  eprosima::fastdds::dds::Subscriber* subscriber_ = nullptr;
  std::map<std::string, eprosima::fastdds::dds::Topic*> topics_;
};

/// Current number of matched readers of `writer` / writers of `reader`.
int matched(eprosima::fastdds::dds::DataWriter* writer);
int matched(eprosima::fastdds::dds::DataReader* reader);

/// Waits up to `timeout` seconds for at least one match; returns the final count.
int wait_matched(eprosima::fastdds::dds::DataWriter* writer, double timeout);

}  // namespace fastdds_peer
