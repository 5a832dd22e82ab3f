#pragma once
/// @file
/// ROS 2's six parameter services on DDS, with rmw_cyclonedds_cpp's mapping (so that `ros2 param`
/// and rqt_reconfigure on ROS 2 with Cyclone DDS reach them), and /parameter_events:
///
/// - service `<node>/<name>` (list_parameters, get_parameters, set_parameters,
///   set_parameters_atomically, describe_parameters, get_parameter_types): a reader of
///   `rq<node>/<name>Request` and a writer of `rr<node>/<name>Reply`, of the DDS types
///   `rcl_interfaces::srv::dds_::<Name>_Request_` / `_Response_`, QoS as ROS 2's services'
///   default (reliable, volatile, keep last 10), USER_DATA `typehash=<the service's hash>;`.
/// - Each request and reply starts with rmw_cyclonedds_cpp's request header (the client's 64-bit
///   id, the request's sequence number) in front of the CDR fields; a reply copies the request's
///   header, by which the client picks its replies. Before replying to a client that names itself
///   in its USER_DATA (`clientid=...;`, as rmw_cyclonedds_cpp's clients do), the service waits up
///   to 100 ms for that client's reply reader to match, as rmw_cyclonedds_cpp does: a reply
///   written before would be lost (volatile).
/// - /parameter_events (rcl_interfaces/msg/ParameterEvent, reliable, volatile, keep last 1000 as
///   rclcpp's): every parameter as new_parameters when the services start, and each accepted set
///   as changed_parameters, node = the fully-qualified node name.
///
/// The services run on a thread of their own, never on the control thread: a slow or malformed
/// request delays only other requests. Malformed bytes are refused by Cyclone's deserializer
/// before they reach this code; a well-formed request with unknown names, wrong types or values
/// out of range is answered as rclcpp answers it.

#include <atomic>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "dds.hpp"
#include "node_parameters.hpp"

namespace cartesian_impedance_ros2 {

class ParameterServices {
 public:
  /// Creates every reader and writer. `node` is the fully-qualified node name, `events_topic`
  /// the resolved name of /parameter_events.
  /// @throws cartesian_impedance::Error naming the topic if DDS refuses an entity.
  ParameterServices(const Participant& participant, const std::string& node,
                    const std::string& events_topic, NodeParameters& parameters);
  ~ParameterServices();
  ParameterServices(const ParameterServices&) = delete;
  ParameterServices& operator=(const ParameterServices&) = delete;

  /// Publishes the first parameter event and starts answering (its own thread).
  void start();
  /// Stops the thread (also done by the destructor).
  void stop();

  /// The request readers, for the graph (ros_discovery_info).
  std::vector<dds_entity_t> readers() const;
  /// The reply writers and the /parameter_events writer.
  std::vector<dds_entity_t> writers() const;

  /// Requests answered since start (any service).
  std::uint64_t answered() const noexcept { return answered_.load(); }

  struct Endpoints;  // the DDS entities (parameter_services.cpp)

 private:
  void serve();
  void take_requests();
  void publish_event(const std::vector<NamedValue>& fresh, const std::vector<NamedValue>& changed);

  std::string node_;
  NodeParameters& parameters_;
  std::unique_ptr<Endpoints> endpoints_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> answered_{0};
  std::thread thread_;
};

}  // namespace cartesian_impedance_ros2
