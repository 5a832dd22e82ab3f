#pragma once
/// @file
/// The ROS 1 shell around cartesian_impedance::ControlLoop. Three kinds of threads:
///
/// - the control thread is the library's runtime::ControlThread (ROS-free, shared with every
///   other shell): the cycle at ~control_rate on absolute deadlines. Commands reach it through the
///   loop's lock-free inbox, measured joint states (topics mode) through a lock-free
///   MeasurementBuffer, and what it produces leaves through the loop's outbox and (topics mode) a
///   TorqueOutbox. In sim mode its cycle is the closed-loop runner, which steps the MuJoCo
///   simulation once per cycle.
/// - the publisher thread reads the newest state at ~publish_rate, publishes controller_state,
///   commanded_torques, (sim mode) joint_states and the arm's transforms on /tf (the fixed ones
///   go on /tf_static once, latched), and logs status changes, lost joint_states
///   and overruns; in topics mode an effort thread publishes each cycle's torque on
///   effort_command, woken by the TorqueOutbox (publishing.cpp).
/// - ROS callbacks (an AsyncSpinner) convert and validate messages, do tf2 lookups, and hand the
///   commands to the loop (callbacks.cpp, reconfigure.cpp). A rejected message is logged and
///   changes nothing.

#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/Wrench.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Empty.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <cartesian_impedance/loop/control_loop.hpp>
#include <cartesian_impedance/model/link_transforms.hpp>
#include <cartesian_impedance/model/robot_model.hpp>
#include <cartesian_impedance/node/joint_states.hpp>
#include <cartesian_impedance/node/log_throttle.hpp>
#include <cartesian_impedance/runtime/control_thread.hpp>
#include <cartesian_impedance/runtime/robot_io.hpp>
#include <cartesian_impedance/sim/closed_loop_runner.hpp>
#include <cartesian_impedance/sim/simulation.hpp>

#include <cartesian_impedance_ros/DampingConfig.h>
#include <cartesian_impedance_ros/NullspaceConfig.h>
#include <cartesian_impedance_ros/StiffnessConfig.h>
#include <cartesian_impedance_ros/WrenchConfig.h>

#include "command_record.hpp"
#include "conversions.hpp"
#include "ros_parameters.hpp"

namespace cartesian_impedance_ros {

class CartesianImpedanceNode {
 public:
  /// Reads the parameters, loads the URDF from robot_description (and in sim mode the MJCF), and
  /// creates the control loop.
  /// @throws cartesian_impedance::Error with a message for the user.
  CartesianImpedanceNode(const ros::NodeHandle& node, const ros::NodeHandle& private_node);
  ~CartesianImpedanceNode();
  CartesianImpedanceNode(const CartesianImpedanceNode&) = delete;
  CartesianImpedanceNode& operator=(const CartesianImpedanceNode&) = delete;

  /// Runs until ROS shuts down; returns the process exit code (non-zero if the control thread
  /// failed).
  int run();

 private:
  /// A dynamic_reconfigure server with what it showed when it last applied a request or a topic
  /// last changed its values (`applied`: a request's fields that differ from it are the changed
  /// ones) and what it shows now (`shown`: `applied` plus edits waiting for the update flag).
  /// `mutex` is the server's own (held during its callback) and also guards the two configs.
  template <typename Config>
  struct Reconfigure {
    boost::recursive_mutex mutex;
    std::unique_ptr<dynamic_reconfigure::Server<Config>> server;
    Config applied{};  // value-initialized: the generated type leaves its members uninitialized
    Config shown{};
  };

  // Threads: the control thread (node.cpp), publisher and effort threads (publishing.cpp).
  void start_control_thread();
  void publisher_thread();
  void effort_thread();
  void stop_threads();
  /// Logs the limits in force and, at `start_q` if given, the torque-rate check's warnings.
  void log_startup_report(const cartesian_impedance::JointVector* start_q) const;
  /// /tf_static, once (latched): the joints whose transforms do not depend on the arm's joints
  /// (fixed ones, and those outside the chain, held at position 0), stamped now.
  void publish_static_transforms();

  // Set up once the controller runs (so no command is lost to start()): node.cpp and
  // reconfigure.cpp.
  void create_command_interface();
  void create_reconfigure_servers();
  /// Sends commands from a topic to the loop as one (all or none), records those the record
  /// keeps and makes the servers show them.
  /// @throws cartesian_impedance::Error (or another std::exception) if the loop rejects them.
  void send_from_topic(const std::vector<cartesian_impedance::Command>& commands);
  /// Makes the servers that show `value` show what the record holds, as applied.
  void show_on_servers(SharedValue value);

  /// Logs a rejected message of `topic` (warning), throttled per topic and kind of fault
  /// (node::LogThrottle); any callback thread.
  void warn_rejected(const char* topic, const std::exception& error);
  /// Logs (throttled) the joint states the controller could not start from since `seen`.
  void report_rejected_starts(cartesian_impedance::node::LogThrottle& throttle,
                              std::uint64_t& seen) const;

  // Callbacks (callbacks.cpp, reconfigure.cpp).
  void on_joint_states(const sensor_msgs::JointState::ConstPtr& message);
  void on_reference_pose(const geometry_msgs::PoseStamped::ConstPtr& message);
  void on_stiffness(const geometry_msgs::WrenchStamped::ConstPtr& message);
  void on_damping_factors(const geometry_msgs::Wrench::ConstPtr& message);
  void on_wrench(const geometry_msgs::WrenchStamped::ConstPtr& message);
  void on_config(const NullspaceConfig::ConstPtr& message);
  void on_resume(const std_msgs::Empty::ConstPtr& message);
  void on_trajectory(const trajectory_msgs::JointTrajectory::ConstPtr& message);
  bool on_cancel_trajectory(std_srvs::Trigger::Request& request,
                            std_srvs::Trigger::Response& response);
  void on_stiffness_reconfigure(StiffnessConfig& config, std::uint32_t level);
  void on_damping_reconfigure(DampingConfig& config, std::uint32_t level);
  void on_wrench_reconfigure(WrenchConfig& config, std::uint32_t level);
  /// Applies the fields of a request that changed (or, with `remove_wrench`, commands a zero
  /// wrench), records them and sets `config` to the values in force. Logs a rejection.
  template <typename Config>
  void apply_request(Reconfigure<Config>& state, Config& config, const char* server,
                     bool remove_wrench = false);

  /// A stiffness diagonal or a wrench given in `frame_id`: in the named frame as it is (empty:
  /// the configured one), in any other frame rotated into the base frame once with tf2.
  /// @throws cartesian_impedance::Error if the transform is not available.
  cartesian_impedance::Command framed_command(const std::string& frame_id,
                                              const cartesian_impedance::Vector6d& values,
                                              bool stiffness);
  /// The frame a stiffness or wrench message names: nullopt for "" (the configured frame),
  /// base or end_effector for the base or tip link; else R_base_frame from tf2 in `rotation`.
  /// @throws cartesian_impedance::Error if the transform is not available.
  std::optional<cartesian_impedance::Frame> frame_of(const std::string& frame_id,
                                                     Eigen::Matrix3d& rotation) const;
  /// T_base_frame from tf2 (latest available), waiting at most ~tf_timeout.
  /// @throws cartesian_impedance::Error if it is not available.
  Eigen::Isometry3d lookup(const std::string& frame_id) const;
  bool is_base(const std::string& frame_id) const;
  bool is_tip(const std::string& frame_id) const;

  ros::NodeHandle node_;
  ros::NodeHandle private_node_;
  NodeConfiguration configuration_;
  const NodeSettings& settings_ = configuration_.settings;

  std::optional<cartesian_impedance::RobotModel> model_;
  std::optional<cartesian_impedance::LinkTransforms> links_;  // set if ~publish_tf
  std::unique_ptr<cartesian_impedance::ControlLoop> loop_;
  std::optional<cartesian_impedance::sim::Simulation> simulation_;             // sim mode
  std::optional<cartesian_impedance::sim::ClosedLoopRunner> runner_;           // sim mode
  std::unique_ptr<cartesian_impedance::node::JointStateMapper> joint_mapper_;  // topics mode
  // Hand-off to and from the control thread (topics mode; lock-free, no allocation after
  // construction): joint_states in (one writer: the joint_states callback), torques out.
  std::optional<cartesian_impedance::runtime::MeasurementBuffer> joint_samples_;
  std::optional<cartesian_impedance::runtime::TorqueOutbox> torques_;
  std::optional<cartesian_impedance::runtime::ControlThread> control_thread_;

  std::mutex log_mutex_;  // guards log_throttle_: the spinner has two threads
  cartesian_impedance::node::LogThrottle log_throttle_;
  std::atomic<bool> stop_{false};  // ends the publisher and effort threads
  std::thread publisher_thread_;
  std::thread effort_thread_;

  ros::Publisher state_publisher_;
  ros::Publisher torque_publisher_;
  ros::Publisher joint_state_publisher_;
  ros::Publisher effort_publisher_;
  ros::Publisher tf_publisher_;         // /tf: the chain's joints, at ~publish_rate
  ros::Publisher tf_static_publisher_;  // /tf_static (latched): every other joint, once
  ros::Subscriber joint_state_subscriber_;
  std::vector<ros::Subscriber> command_subscribers_;
  ros::ServiceServer cancel_service_;

  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;

  // What the node last commanded of the values that topics and the reconfigure servers share
  // (command_record.hpp); set before the first command. Lock order: the servers' mutexes
  // (stiffness, damping, wrench), then record_mutex_, which guards the record and is held from
  // building a command to recording it, so that the record follows the loop's order.
  std::mutex record_mutex_;
  std::optional<CommandRecord> record_;
  Reconfigure<StiffnessConfig> stiffness_;
  Reconfigure<DampingConfig> damping_;
  Reconfigure<WrenchConfig> wrench_;
};

}  // namespace cartesian_impedance_ros
