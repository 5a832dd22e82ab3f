#pragma once
/// @file
/// The message types the peer handles, behind one interface: a sample of the fastddsgen type,
/// its TopicDataType, JSON output (echo) and `field=value` input (pub, fuzz base samples).

#include <fastdds/dds/topic/TopicDataType.hpp>
#include <memory>
#include <string>
#include <vector>

namespace fastdds_peer {

/// One sample of a ROS message type.
class Message {
 public:
  virtual ~Message() = default;
  /// The type's ROS name, e.g. "geometry_msgs/msg/PoseStamped".
  virtual const std::string& ros_type() const = 0;
  /// A new instance of the generated TopicDataType (the caller owns it).
  virtual eprosima::fastdds::dds::TopicDataType* new_type() const = 0;
  /// The sample, as the TopicDataType reads and writes it.
  virtual void* data() = 0;
  /// The sample as one JSON object (NaN and Infinity as Python's json reads them).
  virtual std::string json() const = 0;
  /// Sets a field from text; the names are listed in peer_messages.cpp per type.
  /// @throws std::invalid_argument for an unknown field or a malformed value.
  virtual void assign(const std::string& field, const std::string& value) = 0;
  /// Sets header.stamp, if the type has a header.
  virtual void stamp(double seconds) = 0;
};

/// A default sample of `ros_type`.
/// @throws std::invalid_argument for a type the peer does not handle.
std::unique_ptr<Message> make_message(const std::string& ros_type);

/// The sample serialized as on the wire (XCDR1, 4-byte encapsulation header first).
std::vector<unsigned char> serialize(Message& message);

/// Applies `field=value` assignments in order.
/// @throws std::invalid_argument naming the bad assignment.
void assign_all(Message& message, const std::vector<std::string>& assignments);

/// JSON helpers shared with the subcommands.
std::string json_number(double value);
std::string json_string(const std::string& text);
std::string json_numbers(const std::vector<double>& values);

}  // namespace fastdds_peer
