// The node's setup and wiring: parameters, model, simulation or joint_states hand-off, the
// control thread, and (once the controller runs) the command interface.

#include <std_msgs/Float64MultiArray.h>
#include <tf2_msgs/TFMessage.h>

#include <cstdio>
#include <cstring>
#include <string>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/node/simulated_arm.hpp>
#include <cartesian_impedance/node/startup_report.hpp>

#include "node.hpp"

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;

// ---- construction ---------------------------------------------------------------------------

CartesianImpedanceNode::CartesianImpedanceNode(const ros::NodeHandle& node,
                                               const ros::NodeHandle& private_node)
    : node_(node), private_node_(private_node) {
  // The whole private namespace in one request; nothing set leaves every default.
  XmlRpc::XmlRpcValue values;
  ros::param::get(private_node_.getNamespace(), values);
  configuration_ = configuration_from_xmlrpc(values, private_node_.getNamespace());
  for (const std::string& key : configuration_.unknown_keys) {
    ROS_WARN("ignoring parameter %s: not a setting or parameter of this node", key.c_str());
  }

  std::string urdf;
  if (!node_.getParam("robot_description", urdf)) {
    throw ci::Error("parameter " + node_.resolveName("robot_description") +
                    " is not set: it must hold the robot's URDF, e.g. <param name=\"" +
                    "robot_description\" textfile=\"models/panda/panda.urdf\"/>");
  }
  model_.emplace(ci::RobotModel::from_urdf_string(urdf, settings_.base_link, settings_.tip_link));
  ci::node::check_start_q(configuration_, *model_);
  ci::node::apply_robot_defaults(configuration_, *model_);
  // Callbacks wait up to 0.1 s for room in a full inbox (the cycle drains 8 commands per step),
  // so a burst of commands is delayed rather than lost; only a loop that stopped stepping makes
  // a callback give up, with a warning naming the command.
  ci::LoopCapacity capacity;
  capacity.send_timeout = 0.1;
  loop_ = std::make_unique<ci::ControlLoop>(*model_, configuration_.parameters, capacity);
  // Decided once, before anything can start the loop: only the node's own configuration may
  // let safety settings change while the robot runs.
  if (settings_.allow_runtime_safety_changes) loop_->allow_runtime_safety_changes(true);
  const int n = model_->num_joints();

  if (settings_.mode == Mode::sim) {
    simulation_.emplace(ci::node::simulate_arm(configuration_, *model_, urdf, "",
                                               [](const ci::node::SimulationStart& start) {
                                                 if (start.warning) {
                                                   ROS_WARN("%s", start.message.c_str());
                                                 } else {
                                                   ROS_INFO("%s", start.message.c_str());
                                                 }
                                               }));
    runner_.emplace(*simulation_, *loop_);
    joint_state_publisher_ = node_.advertise<sensor_msgs::JointState>("joint_states", 10);
    log_startup_report(&simulation_->q());
  } else {
    log_startup_report(nullptr);  // the robot's start is known with its first joint states
    joint_mapper_ = std::make_unique<ci::node::JointStateMapper>(model_->joint_names());
    joint_samples_.emplace(n);
    torques_.emplace(n);
    effort_publisher_ = node_.advertise<std_msgs::Float64MultiArray>("effort_command", 10);
    joint_state_subscriber_ =
        node_.subscribe("joint_states", 10, &CartesianImpedanceNode::on_joint_states, this,
                        ros::TransportHints().tcpNoDelay());
  }
  ci::runtime::ControlThreadOptions thread_options;
  thread_options.rate = settings_.control_rate;
  thread_options.measurement_timeout = settings_.joint_states_timeout;
  thread_options.realtime_priority = settings_.realtime_priority;
  control_thread_.emplace(thread_options);

  if (settings_.publish_tf) {
    links_.emplace(
        ci::LinkTransforms::from_urdf_string(urdf, settings_.base_link, model_->joint_names()));
    tf_publisher_ = node_.advertise<tf2_msgs::TFMessage>("/tf", 100);
    tf_static_publisher_ = node_.advertise<tf2_msgs::TFMessage>("/tf_static", 1, true);
    publish_static_transforms();
  }
  state_publisher_ = private_node_.advertise<ControllerState>("controller_state", 10);
  torque_publisher_ = private_node_.advertise<std_msgs::Float64MultiArray>("commanded_torques", 10);

  std::string joints;
  for (const std::string& name : model_->joint_names())
    joints += (joints.empty() ? "" : " ") + name;
  ROS_INFO(
      "%s: %s -> %s, %d joints (%s), mode %s%s%s, %g Hz control, %g Hz state%s",
      private_node_.getNamespace().c_str(), settings_.base_link.c_str(), settings_.tip_link.c_str(),
      n, joints.c_str(), to_string(settings_.mode),
      settings_.mode == Mode::sim
          ? (std::string(", engine ") + ci::sim::engine_name(settings_.engine)).c_str()
          : "",
      settings_.mode == Mode::sim && settings_.mjcf_path.empty() ? " (the URDF simulated)" : "",
      settings_.control_rate, settings_.publish_rate,
      links_ ? (", tf of " + std::to_string(links_->joints().size()) + " joints").c_str() : "");
}

void CartesianImpedanceNode::log_startup_report(const ci::JointVector* start_q) const {
  for (const ci::node::ReportLine& line :
       ci::node::startup_report(loop_->latest_parameters(), *model_, start_q)) {
    if (line.level == ci::node::ReportLine::Level::warning) {
      ROS_WARN("%s", line.text.c_str());
    } else {
      ROS_INFO("%s", line.text.c_str());
    }
  }
}

CartesianImpedanceNode::~CartesianImpedanceNode() {
  stop_threads();
}

void CartesianImpedanceNode::stop_threads() {
  if (control_thread_) control_thread_->stop();
  stop_ = true;
  if (torques_) torques_->wake();
  for (std::thread* thread : {&publisher_thread_, &effort_thread_}) {
    if (thread->joinable()) thread->join();
  }
}

// The library's control thread runs the cycle: in sim mode the closed-loop runner (one
// simulation step per cycle, started from the simulated state), in topics mode the loop fed by
// joint_states (started at the first one it can start from; run() logs those it cannot) with the
// torque going to the effort thread.
void CartesianImpedanceNode::start_control_thread() {
  if (runner_) {
    control_thread_->start(*runner_);
  } else {
    control_thread_->start(*loop_, *joint_samples_, &*torques_);
  }
  if (const int error = control_thread_->scheduling_error()) {
    ROS_WARN(
        "cannot give the control thread SCHED_FIFO priority %d (%s); it runs at normal "
        "priority",
        settings_.realtime_priority, std::strerror(error));
  }
}

// ---- run ------------------------------------------------------------------------------------

int CartesianImpedanceNode::run() {
  ros::AsyncSpinner spinner(2);  // two, so a callback waiting for tf2 does not hold up others
  spinner.start();

  start_control_thread();
  publisher_thread_ = std::thread([this] { publisher_thread(); });
  if (settings_.mode == Mode::topics) effort_thread_ = std::thread([this] { effort_thread(); });

  // Commands are accepted once the controller runs: start() sets the reference to the measured
  // pose, which would override anything sent before.
  if (settings_.mode == Mode::topics) {
    ROS_INFO("waiting for %s", node_.resolveName("joint_states").c_str());
  }
  using State = ci::runtime::ControlThread::State;
  ci::node::LogThrottle start_throttle;
  std::uint64_t rejected_starts = 0;
  while (ros::ok() && control_thread_->state() == State::preparing) {
    report_rejected_starts(start_throttle, rejected_starts);
    ros::WallDuration(0.01).sleep();
  }
  const bool failed = control_thread_->state() == State::failed;
  if (failed) {
    ros::requestShutdown();
  } else if (control_thread_->running() && ros::ok()) {
    create_command_interface();
    ROS_INFO("controller running; commands on %s/...", private_node_.getNamespace().c_str());
    const std::string lock = ci::node::safety_lock_line(settings_);
    if (settings_.allow_runtime_safety_changes) {
      ROS_WARN("%s", lock.c_str());
    } else {
      ROS_INFO("%s", lock.c_str());
    }
  }

  ros::waitForShutdown();
  stop_threads();
  spinner.stop();
  if (failed) {
    ROS_FATAL("cannot start the controller: %s", control_thread_->failure().c_str());
    return 1;
  }
  return 0;
}

void CartesianImpedanceNode::report_rejected_starts(ci::node::LogThrottle& throttle,
                                                    std::uint64_t& seen) const {
  const ci::runtime::RejectedStarts rejected = control_thread_->rejected_starts();
  if (!rejected.latest) return;
  const std::string text = "cannot start the controller from " + node_.resolveName("joint_states") +
                           ": " + rejected.latest->what() +
                           "; waiting for joint states it can start from";
  // Every rejection counts, the ones between two polls by the newest's fault.
  for (; seen < rejected.count; ++seen) {
    if (auto line = throttle.line("joint_states start", rejected.latest->fault(), text)) {
      ROS_WARN("%s", line->c_str());
    }
  }
}

void CartesianImpedanceNode::create_command_interface() {
  tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);  // own thread

  // The record of the commanded values and the reconfigure servers that show it exist before
  // the first command can arrive.
  {
    const std::lock_guard<std::mutex> lock(record_mutex_);
    record_.emplace(loop_->latest_parameters());
  }
  create_reconfigure_servers();

  const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
  using Self = CartesianImpedanceNode;
  ros::NodeHandle& p = private_node_;
  // Only the newest reference matters; other commands are queued by ROS (10 deep) and then by the
  // loop, whose senders wait for room rather than drop a command.
  command_subscribers_.push_back(
      p.subscribe("reference_pose", 1, &Self::on_reference_pose, this, hints));
  command_subscribers_.push_back(
      p.subscribe("set_cartesian_stiffness", 10, &Self::on_stiffness, this, hints));
  command_subscribers_.push_back(
      p.subscribe("set_damping_factors", 10, &Self::on_damping_factors, this, hints));
  command_subscribers_.push_back(
      p.subscribe("set_cartesian_wrench", 10, &Self::on_wrench, this, hints));
  command_subscribers_.push_back(p.subscribe("set_config", 10, &Self::on_config, this, hints));
  command_subscribers_.push_back(
      p.subscribe("joint_trajectory", 10, &Self::on_trajectory, this, hints));
  command_subscribers_.push_back(p.subscribe("resume", 10, &Self::on_resume, this, hints));
  cancel_service_ = p.advertiseService("cancel_trajectory", &Self::on_cancel_trajectory, this);
}

}  // namespace cartesian_impedance_ros
