// The ROS 2 node's setup, threads and command handling (see node.hpp).

#include "node.hpp"

#include <chrono>
#include <cstring>
#include <optional>
#include <vector>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/node/startup_report.hpp>
#include <cartesian_impedance/node/status_reports.hpp>

#include "log.hpp"
#include "simulated_arm.hpp"

namespace cartesian_impedance_ros2 {

namespace ci = cartesian_impedance;
using ci::node::Mode;

namespace {

void log_line(const ci::node::ReportLine& line) {
  log(line.level == ci::node::ReportLine::Level::info ? LogLevel::info : LogLevel::warn, line.text);
}

// Runs `make`, which creates DDS entities: its failure is the middleware's, not the
// configuration's (exit code 1, not 2).
template <typename Make>
auto dds(Make make) -> decltype(make()) {
  try {
    return make();
  } catch (const ci::Error& error) {
    throw MiddlewareError(error.what());
  }
}

}  // namespace

Node::Node(RosArguments arguments, Ros2Configuration configuration)
    : arguments_(std::move(arguments)),
      configuration_(std::move(configuration)),
      participant_(dds([] { return Participant(); })) {
  for (const std::string& key : configuration_.common.unknown_keys) {
    log(LogLevel::warn, "ignoring parameter " + key + ": not a setting or parameter of this node");
  }
  frames_ = {settings_.base_link, settings_.tip_link, settings_.tf_prefix};
  model_.emplace(ci::RobotModel::from_urdf_string(configuration_.urdf, settings_.base_link,
                                                  settings_.tip_link));
  ci::node::check_start_q(configuration_.common, *model_);
  ci::node::apply_robot_defaults(configuration_.common, *model_);
  // The command thread waits up to 0.1 s for room in a full inbox (the cycle drains 8 commands
  // per step), so a burst is delayed rather than lost.
  ci::LoopCapacity capacity;
  capacity.send_timeout = 0.1;
  loop_ = std::make_unique<ci::ControlLoop>(*model_, configuration_.common.parameters, capacity);
  // Decided once, before anything can start the loop: only the node's own configuration may
  // let safety settings change while the robot runs, not a parameter set from the network.
  if (settings_.allow_runtime_safety_changes) loop_->allow_runtime_safety_changes(true);
  const int n = model_->num_joints();

  const auto out = [&](const std::string& name) {
    const std::string topic = arguments_.resolve(name);
    return std::make_pair("rt" + topic, configuration_.publisher(topic));
  };
  const auto in = [&](const std::string& name) {
    const std::string topic = arguments_.resolve(name);
    return std::make_pair("rt" + topic, configuration_.subscription(topic));
  };
  const auto writer = [&](auto& w, const std::string& name) {
    const auto endpoint = out(name);
    w = dds(
        [&] { return std::decay_t<decltype(w)>(participant_, endpoint.first, endpoint.second); });
  };
  const auto reader = [&](auto& r, const std::string& name) {
    const auto endpoint = in(name);
    r = dds(
        [&] { return std::decay_t<decltype(r)>(participant_, endpoint.first, endpoint.second); });
  };

  if (settings_.mode == Mode::sim) {
    simulation_.emplace(simulate_arm(configuration_, *model_));
    runner_.emplace(*simulation_, *loop_);
    writer(joint_state_writer_, "joint_states");
    log_startup_report(&simulation_->q());
  } else {
    log_startup_report(nullptr);  // the robot's start is known with its first joint states
    joint_mapper_.emplace(model_->joint_names());
    joint_samples_.emplace(n);
    torques_.emplace(n);
    writer(effort_writer_, configuration_.effort_controller + "/commands");
    reader(joint_state_reader_, "joint_states");
  }
  ci::runtime::ControlThreadOptions thread_options;
  thread_options.rate = settings_.control_rate;
  thread_options.measurement_timeout = settings_.joint_states_timeout;
  thread_options.realtime_priority = settings_.realtime_priority;
  control_thread_.emplace(thread_options);

  if (settings_.publish_tf) {
    // As robot_state_publisher and tf2_ros's broadcasters: /tf reliable, volatile, depth 100;
    // /tf_static and robot_description reliable, transient local, depth 1 (unless overridden).
    const auto latched = [&](auto& w, const std::string& name) {
      const std::string topic = arguments_.resolve(name);
      const TopicQos qos = configuration_.publisher_qos.count(topic)
                               ? configuration_.publisher(topic)
                               : TopicQos{true, true, 1};
      w = dds([&] { return std::decay_t<decltype(w)>(participant_, "rt" + topic, qos); });
    };
    links_.emplace(ci::LinkTransforms::from_urdf_string(configuration_.urdf, settings_.base_link,
                                                        model_->joint_names()));
    const std::string tf_topic = arguments_.resolve("/tf");
    const TopicQos tf_qos = configuration_.publisher_qos.count(tf_topic)
                                ? configuration_.publisher(tf_topic)
                                : TopicQos{true, false, 100};
    tf_writer_ = dds([&] { return Writer<TFMessage>(participant_, "rt" + tf_topic, tf_qos); });
    latched(tf_static_writer_, "/tf_static");
    latched(description_writer_, "robot_description");
    std::vector<Eigen::Isometry3d> transforms;
    links_->compute(ci::JointVector::Zero(n), transforms);
    TransformArray fixed(*links_, settings_.tf_prefix, false);
    tf_static_writer_.write(fixed.set(transforms, stamp_now()));
    StringMessage description{};
    description.data = configuration_.urdf.data();
    description_writer_.write(description);
  }
  writer(state_writer_, "~/controller_state");
  writer(full_state_writer_, "~/full_state");
  writer(torque_writer_, "~/commanded_torques");
  reader(reference_reader_, "~/reference_pose");
  reader(stiffness_reader_, "~/set_cartesian_stiffness");
  reader(wrench_reader_, "~/set_cartesian_wrench");
  reader(damping_reader_, "~/set_damping_factors");
  reader(config_reader_, "~/set_config");
  reader(resume_reader_, "~/resume");
  // Relative, as in the published controller: in the node's namespace.
  reader(trajectory_reader_, "joint_trajectory");
  wake_ = dds([&] {
    return Entity(check(dds_create_guardcondition(participant_.get()), "guard condition"));
  });
  // Sets are taken from the controller's first cycle (its state reads ok from then), not only
  // once the main thread's poll has seen it run: a client that waited for ok was refused.
  node_parameters_.emplace(
      *loop_, settings_, shell_settings(configuration_),
      [this] { return accepting_.load() || control_thread_->running(); },
      arguments_.fully_qualified_name());
  parameter_services_ = dds([&] {
    return std::make_unique<ParameterServices>(participant_, arguments_.fully_qualified_name(),
                                               arguments_.resolve("/parameter_events"),
                                               *node_parameters_);
  });
  graph_ = dds([&] { return GraphAnnouncer(participant_, configuration_.ros_distro); });
  announce_in_graph();

  std::string joints;
  for (const std::string& name : model_->joint_names())
    joints += (joints.empty() ? "" : " ") + name;
  log(LogLevel::info,
      arguments_.fully_qualified_name() + ": " + settings_.base_link + " -> " + settings_.tip_link +
          ", " + std::to_string(n) + " joints (" + joints + "), mode " + to_string(settings_.mode) +
          (settings_.mode == Mode::sim
               ? std::string(", engine ") + ci::sim::engine_name(settings_.engine)
               : std::string()) +
          ", " + ci::format_number(settings_.control_rate) + " Hz control, " +
          ci::format_number(settings_.publish_rate) + " Hz state" +
          (settings_.mode == Mode::sim && settings_.mjcf_path.empty() ? " (the URDF simulated)"
                                                                      : "") +
          (links_ ? ", tf of " + std::to_string(links_->joints().size()) + " joints" : "") +
          ", DDS domain " + std::to_string(participant_.domain()));
}

Node::~Node() {
  stop_threads();
}

void Node::log_startup_report(const ci::JointVector* start_q) const {
  for (const ci::node::ReportLine& line :
       ci::node::startup_report(loop_->latest_parameters(), *model_, start_q)) {
    log(line.level == ci::node::ReportLine::Level::warning ? LogLevel::warn : LogLevel::info,
        line.text);
  }
}

void Node::announce_in_graph() {
  std::vector<dds_entity_t> readers;
  std::vector<dds_entity_t> writers;
  for (const dds_entity_t reader :
       {reference_reader_.get(), stiffness_reader_.get(), wrench_reader_.get(),
        damping_reader_.get(), config_reader_.get(), trajectory_reader_.get(), resume_reader_.get(),
        joint_state_reader_.get()}) {
    if (reader > 0) readers.push_back(reader);
  }
  for (const dds_entity_t writer :
       {state_writer_.get(), full_state_writer_.get(), torque_writer_.get(),
        joint_state_writer_.get(), effort_writer_.get(), tf_writer_.get(), tf_static_writer_.get(),
        description_writer_.get()}) {
    if (writer > 0) writers.push_back(writer);
  }
  // The parameter services' request readers, reply writers and the /parameter_events writer.
  for (const dds_entity_t reader : parameter_services_->readers()) readers.push_back(reader);
  for (const dds_entity_t writer : parameter_services_->writers()) writers.push_back(writer);
  if (!graph_.announce(arguments_.node_namespace, arguments_.node_name, readers, writers)) {
    log(LogLevel::warn,
        "could not announce the node on ros_discovery_info: ros2 node list "
        "will not show it (its topics still work)");
  }
}

void Node::stop_threads() {
  if (parameter_services_) parameter_services_->stop();
  if (control_thread_) control_thread_->stop();
  stop_ = true;
  if (wake_.get() > 0) dds_set_guardcondition(wake_.get(), true);
  if (torques_) torques_->wake();
  for (std::thread* thread :
       {&command_thread_, &joint_state_thread_, &publisher_thread_, &effort_thread_}) {
    if (thread->joinable()) thread->join();
  }
}

int Node::run(const std::atomic<bool>& stop) {
  if (settings_.mode == Mode::topics) {
    joint_state_thread_ = std::thread([this] { joint_state_thread(); });
    control_thread_->start(*loop_, *joint_samples_, &*torques_);
    effort_thread_ = std::thread([this] { effort_thread(); });
    log(LogLevel::info, "waiting for " + arguments_.resolve("joint_states"));
  } else {
    control_thread_->start(*runner_);
  }
  if (const int error = control_thread_->scheduling_error()) {
    log(LogLevel::warn, "cannot give the control thread SCHED_FIFO priority " +
                            std::to_string(settings_.realtime_priority) + " (" +
                            std::strerror(error) + "); it runs at normal priority");
  }
  publisher_thread_ = std::thread([this] { publisher_thread(); });
  command_thread_ = std::thread([this] { command_thread(); });
  parameter_services_->start();

  using State = ci::runtime::ControlThread::State;
  ci::node::LogThrottle start_throttle;
  std::uint64_t rejected_starts = 0;
  while (!stop && control_thread_->state() == State::preparing) {
    report_rejected_starts(start_throttle, rejected_starts);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const bool failed = control_thread_->state() == State::failed;
  if (!failed && control_thread_->running()) {
    // Commands wait in their readers until now: start() sets the reference to the measured pose,
    // which would override one sent before.
    accepting_ = true;
    log(LogLevel::info,
        "controller running; commands on " + arguments_.fully_qualified_name() + "/...");
    log(settings_.allow_runtime_safety_changes ? LogLevel::warn : LogLevel::info,
        ci::node::safety_lock_line(settings_));
  }
  while (!stop && !failed) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  stop_threads();
  if (failed) {
    log(LogLevel::fatal, "cannot start the controller: " + control_thread_->failure());
    return 1;
  }
  return 0;
}

// ---- commands -----------------------------------------------------------------------------------

void Node::command_thread() {
  // Until the controller runs, samples wait in their readers (keep-last: the newest ones).
  while (!stop_ && !accepting_) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const dds_entity_t waitset = dds_create_waitset(participant_.get());
  if (waitset < 0) {
    log(LogLevel::error, std::string("DDS: cannot create a waitset: ") + dds_strretcode(waitset));
    return;
  }
  for (const dds_entity_t reader :
       {reference_reader_.get(), stiffness_reader_.get(), wrench_reader_.get(),
        damping_reader_.get(), config_reader_.get(), trajectory_reader_.get(),
        resume_reader_.get()}) {
    dds_set_status_mask(reader, DDS_DATA_AVAILABLE_STATUS);
    dds_waitset_attach(waitset, reader, reader);
  }
  dds_waitset_attach(waitset, wake_.get(), wake_.get());
  while (!stop_) {
    take_commands();
    dds_waitset_wait(waitset, nullptr, 0, DDS_MSECS(100));
  }
  dds_delete(waitset);
}

template <typename Convert>
void Node::send(const char* topic, Convert&& convert) {
  // One line per kind of mistake and second, with the count of those not shown, so that a flood
  // of bad samples cannot flood the log. One throttle per thread: the command thread's and the
  // joint-state thread's.
  static thread_local ci::node::LogThrottle throttle;
  std::optional<std::string> line;
  try {
    convert();
  } catch (const std::exception& error) {
    line = throttle.rejected(topic, error);
  }
  if (line) log(LogLevel::warn, *line);
}

void Node::report_rejected_starts(ci::node::LogThrottle& throttle, std::uint64_t& seen) const {
  const ci::runtime::RejectedStarts rejected = control_thread_->rejected_starts();
  if (!rejected.latest) return;
  const std::string text = "cannot start the controller from " +
                           arguments_.resolve("joint_states") + ": " + rejected.latest->what() +
                           "; waiting for joint states it can start from";
  // Every rejection counts, the ones between two polls by the newest's fault.
  for (; seen < rejected.count; ++seen) {
    if (auto line = throttle.line("joint_states start", rejected.latest->fault(), text)) {
      log(LogLevel::warn, *line);
    }
  }
}

void Node::take_commands() {
  const int n = model_->num_joints();
  reference_reader_.take([&](const PoseStamped& message) {
    send("reference_pose", [&] { loop_->send(reference_from_message(message, frames_)); });
  });
  stiffness_reader_.take([&](const WrenchStamped& message) {
    send("set_cartesian_stiffness", [&] { loop_->send(stiffness_from_message(message, frames_)); });
  });
  wrench_reader_.take([&](const WrenchStamped& message) {
    send("set_cartesian_wrench", [&] { loop_->send(wrench_from_message(message, frames_)); });
  });
  damping_reader_.take([&](const WrenchMessage& message) {
    send("set_damping_factors",
         [&] { loop_->send(ci::DampingRatio{vector_from_wrench(message)}); });
  });
  config_reader_.take([&](const ControllerConfig& message) {
    send("set_config", [&] { loop_->send_all(config_from_message(message, n)); });
  });
  resume_reader_.take([&](const EmptyMessage&) {
    send("resume", [&] {
      loop_->resume();
      log(LogLevel::info,
          "resume: a latched collision reaction (if any) ends; holding where the "
          "arm is");
    });
  });
  trajectory_reader_.take([&](const JointTrajectoryMessage& message) {
    send("joint_trajectory", [&] {
      // No trajectory services on this node: an empty trajectory stops the running one, as in
      // ros2_control.
      if (message.points._length == 0) {
        loop_->cancel_trajectory();
        log(LogLevel::info, "joint_trajectory: empty, the running trajectory is cancelled");
        return;
      }
      // The loop was made with the default capacity (the constructor's LoopCapacity).
      const std::uint64_t id = loop_->execute_trajectory(trajectory_from_message(
          message, static_cast<std::uint32_t>(ci::LoopCapacity{}.trajectory_points)));
      log(LogLevel::info, "joint_trajectory " + std::to_string(id) + ": " +
                              std::to_string(message.points._length) + " points");
    });
  });
}

// ---- joint states in, state and torques out -----------------------------------------------------

void Node::joint_state_thread() {
  const dds_entity_t waitset = dds_create_waitset(participant_.get());
  if (waitset < 0) return;
  dds_set_status_mask(joint_state_reader_.get(), DDS_DATA_AVAILABLE_STATUS);
  dds_waitset_attach(waitset, joint_state_reader_.get(), 0);
  dds_waitset_attach(waitset, wake_.get(), 1);
  ci::runtime::JointMeasurement sample;
  while (!stop_) {
    joint_state_reader_.take([&](const JointStateMessage& message) {
      send("joint_states", [&] {
        // A message about other joints only (fingers, another arm) is not the arm's.
        if (joint_mapper_->map(joint_state_view(message), sample)) joint_samples_->publish(sample);
      });
    });
    dds_waitset_wait(waitset, nullptr, 0, DDS_MSECS(100));
  }
  dds_delete(waitset);
}

void Node::publisher_thread() {
  OutgoingMessages messages(*model_, frames_);
  std::optional<TransformArray> moving;
  std::vector<Eigen::Isometry3d> transforms;
  if (links_) moving.emplace(*links_, settings_.tf_prefix, true);
  ci::node::run_publisher(
      ci::node::publisher_options(settings_), stop_, *control_thread_, *loop_,
      joint_samples_ ? &*joint_samples_ : nullptr,
      [&](const ci::node::PublisherSample& sample) {
        messages.fill(sample.state, sample.timing.statistics(), sample.measured);
        state_writer_.write(messages.published_state());
        full_state_writer_.write(messages.full_state());
        torque_writer_.write(messages.commanded_torques());
        if (joint_state_writer_.valid()) joint_state_writer_.write(messages.joint_state());
        if (moving) {
          links_->compute(sample.state.q, transforms);
          tf_writer_.write(moving->set(transforms, messages.stamp()));
        }
      },
      log_line);
}

void Node::effort_thread() {
  TorqueArray commands(model_->num_joints());
  ci::runtime::TorqueSample sample;
  while (!stop_) {
    if (!torques_->wait(0.1, sample)) continue;  // a new cycle's torque, each once
    effort_writer_.write(commands.set(sample.tau));
  }
}

}  // namespace cartesian_impedance_ros2
