#include "node.hpp"

#include <pthread.h>
#include <sched.h>
#include <std_msgs/Float64MultiArray.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <exception>
#include <limits>
#include <string_view>

#include <cartesian_impedance/error.hpp>

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;
using Clock = std::chrono::steady_clock;

namespace {

Clock::duration period_of(double rate) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate));
}

// tf2 frame ids carry no leading slash; tolerate the tf1 habit.
std::string_view strip_slash(const std::string& frame_id) {
  std::string_view frame(frame_id);
  while (!frame.empty() && frame.front() == '/') frame.remove_prefix(1);
  return frame;
}

void prepare_array(std_msgs::Float64MultiArray& message, int size) {
  message.layout.dim.resize(1);
  message.layout.dim[0].label = "joints";
  message.layout.dim[0].size = static_cast<std::uint32_t>(size);
  message.layout.dim[0].stride = static_cast<std::uint32_t>(size);
  message.layout.data_offset = 0;
  message.data.assign(static_cast<std::size_t>(size), 0.0);
}

}  // namespace

// ---- Wakeup ---------------------------------------------------------------------------------

Wakeup::Wakeup() {
  sem_init(&semaphore_, 0, 0);
}
Wakeup::~Wakeup() {
  sem_destroy(&semaphore_);
}
void Wakeup::post() noexcept {
  sem_post(&semaphore_);
}

bool Wakeup::wait_for(double seconds) noexcept {
  timespec deadline{};
  clock_gettime(CLOCK_REALTIME, &deadline);
  const long nanoseconds = deadline.tv_nsec + static_cast<long>(seconds * 1e9);
  deadline.tv_sec += nanoseconds / 1000000000L;
  deadline.tv_nsec = nanoseconds % 1000000000L;
  int result;
  while ((result = sem_timedwait(&semaphore_, &deadline)) == -1 && errno == EINTR) {
  }
  return result == 0;
}

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
  // Callbacks wait up to 0.1 s for room in a full inbox (the cycle drains 8 commands per step),
  // so a burst of commands is delayed rather than lost; only a loop that stopped stepping makes
  // a callback give up, with a warning naming the command.
  ci::LoopCapacity capacity;
  capacity.send_timeout = 0.1;
  loop_ = std::make_unique<ci::ControlLoop>(*model_, configuration_.parameters, capacity);
  const int n = model_->num_joints();

  if (settings_.mode == Mode::sim) {
    ci::sim::SimulationOptions options;
    options.timestep = 1.0 / settings_.control_rate;  // one simulation step per control cycle
    options.joint_names = model_->joint_names();
    // The simulated firmware compensates gravity like the real robots, unless the controller is
    // configured to do it itself (then it would be compensated twice).
    options.gravity_compensation = !configuration_.parameters.dynamics.gravity_compensation;
    simulation_.emplace(ci::sim::Simulation::from_mjcf_file(settings_.mjcf_path, options));
    joint_state_publisher_ = node_.advertise<sensor_msgs::JointState>("joint_states", 10);
  } else {
    joint_mapper_ = std::make_unique<JointStateMapper>(model_->joint_names());
    JointSample empty;
    empty.q = empty.dq = ci::JointVector::Zero(n);
    joint_samples_.publish(empty);
    effort_publisher_ = node_.advertise<std_msgs::Float64MultiArray>("effort_command", 10);
    joint_state_subscriber_ =
        node_.subscribe("joint_states", 10, &CartesianImpedanceNode::on_joint_states, this,
                        ros::TransportHints().tcpNoDelay());
  }
  TorqueSample zero;
  zero.tau = ci::JointVector::Zero(n);
  torques_.publish(zero);

  state_publisher_ = private_node_.advertise<ControllerState>("controller_state", 10);
  torque_publisher_ = private_node_.advertise<std_msgs::Float64MultiArray>("commanded_torques", 10);

  std::string joints;
  for (const std::string& name : model_->joint_names())
    joints += (joints.empty() ? "" : " ") + name;
  ROS_INFO("%s: %s -> %s, %d joints (%s), mode %s, %g Hz control, %g Hz state",
           private_node_.getNamespace().c_str(), settings_.base_link.c_str(),
           settings_.tip_link.c_str(), n, joints.c_str(), to_string(settings_.mode),
           settings_.control_rate, settings_.publish_rate);
}

CartesianImpedanceNode::~CartesianImpedanceNode() {
  stop_threads();
}

void CartesianImpedanceNode::stop_threads() {
  stop_ = true;
  torque_wakeup_.post();
  for (std::thread* thread : {&control_thread_, &publisher_thread_, &effort_thread_}) {
    if (thread->joinable()) thread->join();
  }
}

// ---- run ------------------------------------------------------------------------------------

int CartesianImpedanceNode::run() {
  ros::AsyncSpinner spinner(2);  // two, so a callback waiting for tf2 does not hold up others
  spinner.start();

  control_thread_ = std::thread([this] { control_thread(); });
  if (settings_.realtime_priority > 0) {
    sched_param parameters{};
    parameters.sched_priority = settings_.realtime_priority;
    const int error =
        pthread_setschedparam(control_thread_.native_handle(), SCHED_FIFO, &parameters);
    if (error != 0) {
      ROS_WARN(
          "cannot give the control thread SCHED_FIFO priority %d (%s); it runs at normal "
          "priority",
          settings_.realtime_priority, std::strerror(error));
    }
  }
  publisher_thread_ = std::thread([this] { publisher_thread(); });
  if (settings_.mode == Mode::topics) effort_thread_ = std::thread([this] { effort_thread(); });

  // Commands are accepted once the controller runs: start() sets the reference to the measured
  // pose, which would override anything sent before.
  if (settings_.mode == Mode::topics) {
    ROS_INFO("waiting for %s", node_.resolveName("joint_states").c_str());
  }
  while (ros::ok() && !started_ && !failed_) ros::WallDuration(0.01).sleep();
  if (started_ && ros::ok()) {
    create_command_interface();
    ROS_INFO("controller running; commands on %s/...", private_node_.getNamespace().c_str());
  }

  ros::waitForShutdown();
  stop_threads();
  spinner.stop();
  if (failed_) {
    ROS_FATAL("%s", failure_.c_str());
    return 1;
  }
  return 0;
}

void CartesianImpedanceNode::create_command_interface() {
  tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);  // own thread

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
  cancel_service_ = p.advertiseService("cancel_trajectory", &Self::on_cancel_trajectory, this);
  create_reconfigure_servers();
}

void CartesianImpedanceNode::create_reconfigure_servers() {
  // Ranges from the limits in force, values from the parameters; the update flags start false,
  // so a server's first callback (and values left on the parameter server by an earlier run)
  // change nothing.
  const ci::Parameters parameters = loop_->latest_parameters();
  const ci::LimitParameters& limits = parameters.limits;

  stiffness_server_ = std::make_unique<StiffnessServer>(
      stiffness_mutex_, ros::NodeHandle(private_node_, "stiffness_reconfigure"));
  {
    StiffnessConfig low, high, value;
    stiffness_server_->getConfigMin(low);
    stiffness_server_->getConfigMax(high);
    low.translation_x = low.translation_y = low.translation_z = limits.stiffness.translation.min;
    high.translation_x = high.translation_y = high.translation_z = limits.stiffness.translation.max;
    low.rotation_x = low.rotation_y = low.rotation_z = limits.stiffness.rotation.min;
    high.rotation_x = high.rotation_y = high.rotation_z = limits.stiffness.rotation.max;
    low.nullspace_stiffness = limits.nullspace_stiffness.min;
    high.nullspace_stiffness = limits.nullspace_stiffness.max;
    stiffness_server_->getConfigDefault(value);
    value.translation_x = parameters.stiffness.translation.x();
    value.translation_y = parameters.stiffness.translation.y();
    value.translation_z = parameters.stiffness.translation.z();
    value.rotation_x = parameters.stiffness.rotation.x();
    value.rotation_y = parameters.stiffness.rotation.y();
    value.rotation_z = parameters.stiffness.rotation.z();
    value.nullspace_stiffness = parameters.nullspace.stiffness[0];
    value.update_stiffness = false;
    stiffness_server_->setConfigMin(low);
    stiffness_server_->setConfigMax(high);
    stiffness_server_->setConfigDefault(value);
    stiffness_server_->updateConfig(value);
    stiffness_server_->setCallback([this](StiffnessConfig& config, std::uint32_t level) {
      on_stiffness_reconfigure(config, level);
    });
  }

  damping_server_ = std::make_unique<DampingServer>(
      damping_mutex_, ros::NodeHandle(private_node_, "damping_factors_reconfigure"));
  {
    DampingConfig low, high, value;
    damping_server_->getConfigMin(low);
    damping_server_->getConfigMax(high);
    for (double* x : {&low.translation_x, &low.translation_y, &low.translation_z, &low.rotation_x,
                      &low.rotation_y, &low.rotation_z, &low.nullspace_damping}) {
      *x = limits.damping_ratio.min;
    }
    for (double* x :
         {&high.translation_x, &high.translation_y, &high.translation_z, &high.rotation_x,
          &high.rotation_y, &high.rotation_z, &high.nullspace_damping}) {
      *x = limits.damping_ratio.max;
    }
    damping_server_->getConfigDefault(value);
    value.translation_x = parameters.damping_ratio.translation.x();
    value.translation_y = parameters.damping_ratio.translation.y();
    value.translation_z = parameters.damping_ratio.translation.z();
    value.rotation_x = parameters.damping_ratio.rotation.x();
    value.rotation_y = parameters.damping_ratio.rotation.y();
    value.rotation_z = parameters.damping_ratio.rotation.z();
    value.nullspace_damping = parameters.nullspace.damping_ratio;
    value.update_damping_factors = false;
    damping_server_->setConfigMin(low);
    damping_server_->setConfigMax(high);
    damping_server_->setConfigDefault(value);
    damping_server_->updateConfig(value);
    damping_server_->setCallback([this](DampingConfig& config, std::uint32_t level) {
      on_damping_reconfigure(config, level);
    });
  }

  wrench_server_ = std::make_unique<WrenchServer>(
      wrench_mutex_, ros::NodeHandle(private_node_, "cartesian_wrench_reconfigure"));
  {
    WrenchConfig low, high, value;
    wrench_server_->getConfigMin(low);
    wrench_server_->getConfigMax(high);
    low.f_x = low.f_y = low.f_z = -limits.wrench.force;
    high.f_x = high.f_y = high.f_z = limits.wrench.force;
    low.tau_x = low.tau_y = low.tau_z = -limits.wrench.torque;
    high.tau_x = high.tau_y = high.tau_z = limits.wrench.torque;
    wrench_server_->getConfigDefault(value);
    value.apply_wrench = false;
    wrench_server_->setConfigMin(low);
    wrench_server_->setConfigMax(high);
    wrench_server_->setConfigDefault(value);
    wrench_server_->updateConfig(value);
    wrench_server_->setCallback([this](WrenchConfig& config, std::uint32_t level) {
      on_wrench_reconfigure(config, level);
    });
  }
}

// ---- threads --------------------------------------------------------------------------------

void CartesianImpedanceNode::control_thread() noexcept {
  const Clock::duration period = period_of(settings_.control_rate);
  const auto timeout = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(settings_.joint_states_timeout));
  JointSample sample;
  try {
    if (simulation_) {
      loop_->start(simulation_->q(), simulation_->dq());
    } else {
      // The first complete, finite joint state starts the controller at the measured pose.
      for (;;) {
        if (stop_) return;
        joint_samples_.read(sample);
        if (sample.sequence != 0 && sample.q.allFinite() && sample.dq.allFinite()) break;
        std::this_thread::sleep_for(period);
      }
      loop_->start(sample.q, sample.dq);
    }
  } catch (const std::exception& error) {
    failure_ = std::string("cannot start the controller: ") + error.what();
    failed_ = true;
    ros::requestShutdown();
    return;
  }
  started_ = true;

  // From here on: no allocation, no lock, no ROS.
  const ci::JointVector invalid =
      ci::JointVector::Constant(model_->num_joints(), std::numeric_limits<double>::quiet_NaN());
  TorqueSample out;
  out.tau = ci::JointVector::Zero(model_->num_joints());
  Clock::time_point next = Clock::now();
  Clock::time_point last = next - period;
  while (!stop_) {
    next += period;
    const ci::JointVector* tau = nullptr;
    if (simulation_) {
      tau = &loop_->step(simulation_->q(), simulation_->dq(), simulation_->timestep());
      try {
        simulation_->set_torque(*tau);  // tau is always finite and sized: this does not throw
      } catch (...) {
      }
      simulation_->step();
    } else {
      joint_samples_.read(sample);
      const Clock::time_point now = Clock::now();
      const double dt = std::chrono::duration<double>(now - last).count();
      last = now;
      // A lost robot connection is a bad measurement: the cycle reports invalid_robot_state and
      // ramps the torque toward zero within the rate limit, as for any invalid input.
      const bool fresh = now - sample.received <= timeout;
      joint_states_stale_.store(!fresh, std::memory_order_relaxed);
      tau = fresh ? &loop_->step(sample.q, sample.dq, dt) : &loop_->step(invalid, invalid, dt);
    }
    out.tau = *tau;
    out.cycle = loop_->state().cycle;
    torques_.publish(out);
    torque_wakeup_.post();

    const Clock::time_point now = Clock::now();
    if (now > next) {
      overruns_.fetch_add(1, std::memory_order_relaxed);
      if (now - next > period) next = now;  // far behind: skip, do not run a burst of cycles
    }
    std::this_thread::sleep_until(next);
  }
}

void CartesianImpedanceNode::publisher_thread() {
  const Clock::duration period = period_of(settings_.publish_rate);
  const int n = model_->num_joints();
  ControllerState state_message;
  state_message.header.frame_id = settings_.base_link;
  std_msgs::Float64MultiArray torque_message;
  prepare_array(torque_message, n);
  sensor_msgs::JointState joint_message;
  joint_message.name = model_->joint_names();
  JointSample measured;
  ci::Status last_status = ci::Status::ok;
  bool was_stale = false;
  std::uint64_t reported_overruns = 0;

  Clock::time_point next = Clock::now();
  while (!stop_) {
    next += period;
    if (started_) {
      const ci::LoopState state = loop_->latest_state();
      const ros::Time stamp = ros::Time::now();
      const JointSample* effort = nullptr;
      if (!simulation_) {
        joint_samples_.read(measured);
        effort = &measured;
      }
      fill_state_message(state, model_->joint_names(), effort, state_message);
      state_message.header.stamp = stamp;
      state_publisher_.publish(state_message);
      torque_message.data.assign(state.controller.tau.data(),
                                 state.controller.tau.data() + state.controller.tau.size());
      torque_publisher_.publish(torque_message);
      if (simulation_) {
        joint_message.header.stamp = stamp;
        joint_message.position.assign(state.q.data(), state.q.data() + state.q.size());
        joint_message.velocity.assign(state.dq.data(), state.dq.data() + state.dq.size());
        joint_message.effort = state_message.commanded_torques;
        joint_state_publisher_.publish(joint_message);
      }

      // Reports for the log, from here rather than from the control thread.
      const ci::Status status = state.controller.status;
      if (status != last_status) {
        if (status == ci::Status::ok) {
          ROS_INFO("controller status: ok");
        } else {
          ROS_WARN("controller status: %s", ci::to_string(status));
        }
        last_status = status;
      }
      const bool stale = joint_states_stale_.load(std::memory_order_relaxed);
      if (stale != was_stale) {
        if (stale) {
          ROS_WARN("no joint_states for more than %g s: torque ramps toward zero",
                   settings_.joint_states_timeout);
        } else {
          ROS_INFO("joint_states are back");
        }
        was_stale = stale;
      }
      const std::uint64_t overruns = overruns_.load(std::memory_order_relaxed);
      if (overruns != reported_overruns) {
        ROS_WARN_THROTTLE(5.0, "control cycle overran its %g ms period %llu times so far",
                          1e3 / settings_.control_rate, static_cast<unsigned long long>(overruns));
        reported_overruns = overruns;
      }
    }
    const Clock::time_point now = Clock::now();
    if (now - next > period) next = now;
    std::this_thread::sleep_until(next);
  }
}

void CartesianImpedanceNode::effort_thread() {
  std_msgs::Float64MultiArray message;
  prepare_array(message, model_->num_joints());
  TorqueSample sample;
  bool any = false;
  std::uint64_t last_cycle = 0;
  while (!stop_) {
    if (!torque_wakeup_.wait_for(0.1) || !started_) continue;
    torques_.read(sample);
    if (any && sample.cycle == last_cycle) continue;  // already sent (several posts, one read)
    any = true;
    last_cycle = sample.cycle;
    message.data.assign(sample.tau.data(), sample.tau.data() + sample.tau.size());
    effort_publisher_.publish(message);
  }
}

// ---- callbacks ------------------------------------------------------------------------------

void CartesianImpedanceNode::on_joint_states(const sensor_msgs::JointState::ConstPtr& message) {
  // One writer (roscpp never runs one subscription's callback twice at once).
  try {
    JointSample sample;
    if (!joint_mapper_->map(*message, sample)) return;  // about other joints
    if (!sample.q.allFinite() || !sample.dq.allFinite()) {
      ROS_WARN_THROTTLE(1.0,
                        "joint_states has non-finite values: passed on, the controller "
                        "ramps the torque down");
    }
    sample.sequence = ++joint_sequence_;
    sample.received = Clock::now();
    joint_samples_.publish(sample);
  } catch (const std::exception& error) {
    ROS_WARN_THROTTLE(1.0, "joint_states rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_reference_pose(
    const geometry_msgs::PoseStamped::ConstPtr& message) {
  try {
    ci::Pose pose = pose_from_message(message->pose);
    if (!message->header.frame_id.empty() && !is_base(message->header.frame_id)) {
      pose = transform_pose(lookup(message->header.frame_id), pose);
    }
    loop_->set_reference_pose(pose);
  } catch (const std::exception& error) {
    ROS_WARN_THROTTLE(1.0, "reference_pose rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_stiffness(const geometry_msgs::WrenchStamped::ConstPtr& message) {
  try {
    const ci::Vector6d diagonal = vector_from_wrench(message->wrench);
    Eigen::Matrix3d rotation;
    const std::optional<ci::Frame> frame = frame_of(message->header.frame_id, rotation);
    if (frame || message->header.frame_id.empty()) {
      loop_->set_stiffness(diagonal, frame);
    } else {
      loop_->set_stiffness_matrix(rotate_stiffness(rotation, diagonal), ci::Frame::base);
    }
  } catch (const std::exception& error) {
    ROS_WARN_THROTTLE(1.0, "set_cartesian_stiffness rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_damping_factors(const geometry_msgs::Wrench::ConstPtr& message) {
  try {
    loop_->set_damping_ratio(vector_from_wrench(*message));
  } catch (const std::exception& error) {
    ROS_WARN_THROTTLE(1.0, "set_damping_factors rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_wrench(const geometry_msgs::WrenchStamped::ConstPtr& message) {
  try {
    const ci::Vector6d wrench = vector_from_wrench(message->wrench);
    Eigen::Matrix3d rotation;
    const std::optional<ci::Frame> frame = frame_of(message->header.frame_id, rotation);
    if (frame || message->header.frame_id.empty()) {
      loop_->set_wrench(wrench, frame);
    } else {
      loop_->set_wrench(rotate_wrench(rotation, wrench), ci::Frame::base);
    }
  } catch (const std::exception& error) {
    ROS_WARN_THROTTLE(1.0, "set_cartesian_wrench rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_config(const NullspaceConfig::ConstPtr& message) {
  try {
    // Validate all parts before sending any, so a bad message changes nothing.
    const int n = model_->num_joints();
    std::vector<ci::Command> commands;
    if (!message->q_d_nullspace.empty()) {
      commands.push_back(ci::Command::nullspace_target(
          Eigen::Map<const Eigen::VectorXd>(
              message->q_d_nullspace.data(),
              static_cast<Eigen::Index>(message->q_d_nullspace.size())),
          n));
    }
    if (!message->nullspace_stiffness.empty()) {
      commands.push_back(ci::Command::nullspace_stiffness(
          Eigen::Map<const Eigen::VectorXd>(
              message->nullspace_stiffness.data(),
              static_cast<Eigen::Index>(message->nullspace_stiffness.size())),
          n));
    }
    commands.push_back(ci::Command::nullspace_damping_ratio(message->nullspace_damping_ratio));
    for (const ci::Command& command : commands) loop_->send(command);
  } catch (const std::exception& error) {
    ROS_WARN_THROTTLE(1.0, "set_config rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_trajectory(
    const trajectory_msgs::JointTrajectory::ConstPtr& message) {
  try {
    if (message->points.empty()) {
      // As for ros_control's trajectory controllers: an empty trajectory stops the current one.
      loop_->cancel_trajectory();
      ROS_INFO("empty joint_trajectory: trajectory cancelled, holding");
      return;
    }
    const std::uint64_t id = loop_->execute_trajectory(trajectory_from_message(*message));
    ROS_INFO("trajectory %llu: %zu points over %.3f s", static_cast<unsigned long long>(id),
             message->points.size(), message->points.back().time_from_start.toSec());
  } catch (const std::exception& error) {
    ROS_WARN_THROTTLE(1.0, "joint_trajectory rejected: %s", error.what());
  }
}

bool CartesianImpedanceNode::on_cancel_trajectory(std_srvs::Trigger::Request& /*request*/,
                                                  std_srvs::Trigger::Response& response) {
  try {
    loop_->cancel_trajectory();
    response.success = true;
    response.message = "cancelled; holding the current pose";
  } catch (const std::exception& error) {
    response.success = false;
    response.message = error.what();
  }
  return true;
}

void CartesianImpedanceNode::on_stiffness_reconfigure(StiffnessConfig& config,
                                                      std::uint32_t /*level*/) {
  if (!config.update_stiffness) return;
  try {
    ci::Vector6d diagonal;
    diagonal << config.translation_x, config.translation_y, config.translation_z, config.rotation_x,
        config.rotation_y, config.rotation_z;
    const ci::Command stiffness = ci::Command::stiffness(diagonal);
    const ci::Command nullspace = ci::Command::nullspace_stiffness(
        Eigen::VectorXd::Constant(1, config.nullspace_stiffness), model_->num_joints());
    loop_->send(stiffness);
    loop_->send(nullspace);
  } catch (const std::exception& error) {
    ROS_WARN("stiffness_reconfigure rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_damping_reconfigure(DampingConfig& config,
                                                    std::uint32_t /*level*/) {
  if (!config.update_damping_factors) return;
  try {
    ci::Vector6d ratio;
    ratio << config.translation_x, config.translation_y, config.translation_z, config.rotation_x,
        config.rotation_y, config.rotation_z;
    const ci::Command cartesian = ci::Command::damping_ratio(ratio);
    const ci::Command nullspace = ci::Command::nullspace_damping_ratio(config.nullspace_damping);
    loop_->send(cartesian);
    loop_->send(nullspace);
  } catch (const std::exception& error) {
    ROS_WARN("damping_factors_reconfigure rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_wrench_reconfigure(WrenchConfig& config, std::uint32_t /*level*/) {
  try {
    if (!config.apply_wrench) {
      // Switching apply_wrench off removes the wrench this server applied; otherwise (the first
      // callback at start, edits while off) the wrench from parameters or topics stays.
      if (wrench_from_reconfigure_) loop_->set_wrench(ci::Vector6d::Zero());
      wrench_from_reconfigure_ = false;
      return;
    }
    ci::Vector6d wrench;
    wrench << config.f_x, config.f_y, config.f_z, config.tau_x, config.tau_y, config.tau_z;
    loop_->set_wrench(wrench, ci::frame_from_name("frame", config.frame));
    wrench_from_reconfigure_ = true;
  } catch (const std::exception& error) {
    ROS_WARN("cartesian_wrench_reconfigure rejected: %s", error.what());
  }
}

// ---- frames ---------------------------------------------------------------------------------

bool CartesianImpedanceNode::is_base(const std::string& frame_id) const {
  return strip_slash(frame_id) == settings_.base_link;
}

bool CartesianImpedanceNode::is_tip(const std::string& frame_id) const {
  return strip_slash(frame_id) == settings_.tip_link;
}

std::optional<ci::Frame> CartesianImpedanceNode::frame_of(const std::string& frame_id,
                                                          Eigen::Matrix3d& rotation) const {
  if (frame_id.empty()) return std::nullopt;
  if (is_base(frame_id)) return ci::Frame::base;
  if (is_tip(frame_id)) return ci::Frame::end_effector;
  rotation = lookup(frame_id).linear();
  return std::nullopt;
}

Eigen::Isometry3d CartesianImpedanceNode::lookup(const std::string& frame_id) const {
  const std::string frame(strip_slash(frame_id));
  try {
    const geometry_msgs::TransformStamped transform = tf_buffer_->lookupTransform(
        settings_.base_link, frame, ros::Time(0), ros::Duration(settings_.tf_timeout));
    return isometry_from_transform(transform.transform);
  } catch (const tf2::TransformException& error) {
    throw ci::Error("no transform from frame '" + frame + "' to the base frame '" +
                    settings_.base_link + "' within " + ci::format_number(settings_.tf_timeout) +
                    " s: " + error.what());
  }
}

}  // namespace cartesian_impedance_ros
