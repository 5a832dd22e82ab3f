#pragma once
/// @file
/// The ROS 2 shell around cartesian_impedance::ControlLoop, on DDS. Threads:
///
/// - the control thread is the library's runtime::ControlThread (the same one the ROS 1 node
///   runs): the cycle at control_rate on absolute deadlines; in sim mode its cycle is the
///   closed-loop runner stepping MuJoCo, in topics mode the loop fed by joint_states through a
///   lock-free MeasurementBuffer, its torques leaving through a TorqueOutbox. It never waits on
///   DDS.
/// - the command thread waits on a DDS waitset for every command topic, converts and validates
///   each sample and hands it to the loop's lock-free inbox; a rejected sample is logged with the
///   field and value and changes nothing.
/// - the joint-state thread (topics mode) maps joint_states into the MeasurementBuffer, apart
///   from commands so that a flood of commands cannot delay a measurement.
/// - the publisher thread writes the state topics and the chain's transforms (tf) at
///   publish_rate and logs status changes; the effort thread (topics mode) writes each cycle's
///   torque to the effort controller. The transforms that do not depend on the arm's q
///   (tf_static) and robot_description are written once, transient local, at construction.
/// - the parameter services' thread (ParameterServices) answers ROS 2's six parameter services
///   and publishes /parameter_events; a set goes through the library's decoder to the loop's
///   inbox like any command.

#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include <cartesian_impedance/loop/control_loop.hpp>
#include <cartesian_impedance/model/robot_model.hpp>
#include <cartesian_impedance/node/joint_states.hpp>
#include <cartesian_impedance/node/log_throttle.hpp>
#include <cartesian_impedance/runtime/control_thread.hpp>
#include <cartesian_impedance/runtime/robot_io.hpp>
#include <cartesian_impedance/sim/closed_loop_runner.hpp>
#include <cartesian_impedance/sim/simulation.hpp>

#include "arguments.hpp"
#include "dds.hpp"
#include "graph.hpp"
#include "messages.hpp"
#include "node_parameters.hpp"
#include "parameter_services.hpp"
#include "parameters.hpp"

namespace cartesian_impedance_ros2 {

/// DDS could not create what the node needs: a failure of the middleware (or its environment:
/// ROS_DOMAIN_ID, CYCLONEDDS_URI), not of the node's configuration.
class MiddlewareError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Node {
 public:
  /// Loads the model (and in sim mode the MJCF) and creates every DDS entity.
  /// @throws MiddlewareError if DDS cannot create an entity; cartesian_impedance::Error (a
  ///         LoadError, a ParameterError, ...) or UsageError for what the node was given: a URDF
  ///         or MJCF that does not load or does not match, a start_q outside the chain's limits, a
  ///         topic name that is not valid.
  Node(RosArguments arguments, Ros2Configuration configuration);
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  /// Runs until `stop` becomes true; returns the process exit code (1 if the controller could
  /// not start). In topics mode it waits for the first joint states the controller can start
  /// from, logging those it cannot (throttled), as a running cycle fails closed on them.
  int run(const std::atomic<bool>& stop);

 private:
  void command_thread();
  void joint_state_thread();
  void publisher_thread();
  void effort_thread();
  void stop_threads();
  /// Logs the limits in force and, at `start_q` if given, the torque-rate check's warnings.
  void log_startup_report(const cartesian_impedance::JointVector* start_q) const;
  /// Announces the node and every reader and writer it made on ros_discovery_info.
  void announce_in_graph();

  /// Takes every waiting sample of every command topic and sends what converts and validates.
  void take_commands();
  /// Runs `convert` (which sends a command or a measurement); a rejection is logged, throttled
  /// per topic and kind of fault (node::LogThrottle, one per thread).
  template <typename Convert>
  void send(const char* topic, Convert&& convert);
  /// Logs (throttled) the joint states the controller could not start from since `seen`.
  void report_rejected_starts(cartesian_impedance::node::LogThrottle& throttle,
                              std::uint64_t& seen) const;

  RosArguments arguments_;
  Ros2Configuration configuration_;
  const cartesian_impedance::node::NodeSettings& settings_ = configuration_.common.settings;
  Frames frames_;

  std::optional<cartesian_impedance::RobotModel> model_;
  std::optional<cartesian_impedance::LinkTransforms> links_;  // set if publish_tf
  std::unique_ptr<cartesian_impedance::ControlLoop> loop_;
  std::optional<cartesian_impedance::sim::Simulation> simulation_;           // sim mode
  std::optional<cartesian_impedance::sim::ClosedLoopRunner> runner_;         // sim mode
  std::optional<cartesian_impedance::node::JointStateMapper> joint_mapper_;  // topics mode
  std::optional<cartesian_impedance::runtime::MeasurementBuffer> joint_samples_;
  std::optional<cartesian_impedance::runtime::TorqueOutbox> torques_;
  std::optional<cartesian_impedance::runtime::ControlThread> control_thread_;

  // DDS: the participant first, so that it outlives (and deletes) everything below.
  Participant participant_;
  GraphAnnouncer graph_;  // ros_discovery_info: this node and its endpoints
  Writer<PublishedState> state_writer_;
  Writer<FullState> full_state_writer_;
  Writer<Float64MultiArray> torque_writer_;
  Writer<JointStateMessage> joint_state_writer_;  // sim mode
  Writer<Float64MultiArray> effort_writer_;       // topics mode
  Writer<TFMessage> tf_writer_;                   // publish_tf: /tf
  Writer<TFMessage> tf_static_writer_;            // publish_tf: /tf_static, transient local
  Writer<StringMessage> description_writer_;      // publish_tf: robot_description, same
  Reader<PoseStamped> reference_reader_;
  Reader<WrenchStamped> stiffness_reader_;
  Reader<WrenchStamped> wrench_reader_;
  Reader<WrenchMessage> damping_reader_;
  Reader<ControllerConfig> config_reader_;
  Reader<JointTrajectoryMessage> trajectory_reader_;
  Reader<EmptyMessage> resume_reader_;            // ends a latched collision reaction
  Reader<JointStateMessage> joint_state_reader_;  // topics mode
  Entity wake_;                                   // guard condition: ends the waits
  // ROS 2's parameter services and /parameter_events, on a thread of their own.
  std::optional<NodeParameters> node_parameters_;
  std::unique_ptr<ParameterServices> parameter_services_;

  std::atomic<bool> stop_{false};
  std::atomic<bool> accepting_{false};  // commands are applied once the controller runs
  std::thread command_thread_;
  std::thread joint_state_thread_;
  std::thread publisher_thread_;
  std::thread effort_thread_;
};

}  // namespace cartesian_impedance_ros2
