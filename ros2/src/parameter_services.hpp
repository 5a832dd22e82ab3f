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
///   rclcpp's): every parameter as new_parameters when the services start, each accepted set as
///   changed_parameters, and every other change of a parameter's value in force (a topic's
///   stiffness, damping, wrench or nullspace command), found by comparing every 50 ms
///   (NodeParameters::changes()), node = the fully-qualified node name.
///
/// The services run on a thread of their own (at nice 10), never on the control thread: a slow or
/// malformed request delays only other requests, and those little: every request is held to
/// request_limits before any work, each service is served a round of at most 16 requests before
/// the next, and a client without a reply reader is waited for once per 10 s, not per request.
/// Malformed bytes are refused by Cyclone's deserializer before they reach this code; a well-formed
/// request with unknown names, wrong types or values out of range is answered as rclcpp answers it.

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <cartesian_impedance/node/log_throttle.hpp>

#include "dds.hpp"
#include "node_parameters.hpp"

namespace cartesian_impedance_ros2 {

/// The bounds every request is held to before any work is done on it: a request beyond one is
/// refused as a whole (a set_parameters one with a single result), naming what was too long or
/// too many, how long and the bound, and the start of an oversized text, never all of it. They are
/// far above what a valid request needs (this node has under 200 parameters, the longest name 41
/// characters, string values are frames), and they bound the work and memory of a request: an
/// unknown name costs the decoder's suggestions time in proportion to its length, and a reply
/// that quoted it would be as large again.
namespace request_limits {
constexpr std::uint64_t kItems = 256;         ///< names, prefixes or parameters of one request
constexpr std::size_t kNameLength = 128;      ///< a parameter name or prefix [characters]
constexpr std::size_t kStringLength = 4096;   ///< a string value, or one of a string array
constexpr std::uint64_t kArrayLength = 1024;  ///< the elements of an array value
}  // namespace request_limits

/// "`what`: `count`, more than `limit`" if count > limit.
std::optional<std::string> count_fault(const char* what, std::uint64_t count, std::uint64_t limit);
/// "`what` of N characters (beginning '...') is longer than `limit`" if `text` is; reads at most
/// limit + 1 characters of a text within the bound.
std::optional<std::string> length_fault(const char* what, const char* text, std::size_t limit);

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
  /// Answers up to a round of requests of each service; true if more may wait.
  bool take_requests();
  void publish_event(const std::vector<NamedValue>& fresh, const std::vector<NamedValue>& changed);
  /// The reason a request beyond request_limits is refused with, logged (throttled per service).
  std::string refused(const char* service, const std::string& fault);

  std::string node_;
  NodeParameters& parameters_;
  std::unique_ptr<Endpoints> endpoints_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> answered_{0};
  cartesian_impedance::node::LogThrottle throttle_;  // the services' thread's
  std::thread thread_;
};

}  // namespace cartesian_impedance_ros2
