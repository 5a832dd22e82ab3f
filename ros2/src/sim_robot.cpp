// cartesian_impedance_ros2_sim_robot: a simulated arm in a process of its own that speaks what a
// robot's ros2_control speaks, so that the node's topics mode can be closed over the wire (see
// ros2/README.md, "Topics mode over the wire"):
//
// - out: `joint_states` (sensor_msgs/JointState) once per simulation step, each stamped with when
//   its reading was taken (the plant's sensing delay before it was published);
// - in: `<effort_controller>/commands` (std_msgs/Float64MultiArray, one torque per joint in the
//   model's order), as a ros2_control JointGroupEffortController takes them;
// - out: `~/contact_wrench` (geometry_msgs/WrenchStamped, world frame) at 100 Hz: what touches
//   the flange and the bodies beyond it (a table, with --table-under-flange);
// - between the two, sim::SimulatedDriver: the arm held by its brakes until the first torque, the
//   last torque held when one is late, the arm braked after --torque-timeout without one.
//
// It reads the node's own settings (a params file for sim mode: urdf_path or robot_description,
// mjcf_path, engine, start_q, control_rate as the simulation's rate, effort_controller) and the
// plant of its command line. It logs a summary every 5 s and at exit: ticks, torques, brakes and
// the effort commands' latency, from the writer's DDS source timestamp to their arrival.
// Exit codes as the node's: 0 after SIGINT or SIGTERM, 2 for what it was given, 1 if it cannot
// run.

#include <malloc.h>
#include <time.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/runtime/robot_io.hpp>
#include <cartesian_impedance/runtime/timing.hpp>
#include <cartesian_impedance/sim/simulated_driver.hpp>

#include "arguments.hpp"
#include "dds.hpp"
#include "graph.hpp"
#include "log.hpp"
#include "messages.hpp"
#include "parameters.hpp"
#include "simulated_arm.hpp"

namespace cartesian_impedance_ros2 {
namespace {

namespace ci = cartesian_impedance;

std::atomic<bool> stop_requested{false};

extern "C" void on_signal(int) {
  stop_requested = true;
}

struct RobotOptions {
  std::string plant = "nominal";
  std::uint64_t plant_seed = 1;
  double torque_timeout = 0.02;
  double table_depth = 0.0;  // [m] a table's top this far under the flange at the start; 0: none
  bool help = false;
};

std::string robot_usage() {
  return "usage: cartesian_impedance_ros2_sim_robot [--plant nominal|realistic] [--plant-seed N]\n"
         "         [--torque-timeout SECONDS] --ros-args [-r __ns:=/NAMESPACE] --params-file FILE\n"
         "         [-p NAME:=VALUE ...]\n"
         "A simulated arm for the node's topics mode: joint_states out (stamped), effort\n"
         "commands in on <ns>/<effort_controller>/commands. The params file is the node's own\n"
         "for sim mode (urdf_path, mjcf_path, engine, start_q, control_rate).\n"
         "  --plant NAME          nominal (the model, read at once) or realistic (model error,\n"
         "                        1 ms sensing and actuation delay, noise); default nominal\n"
         "  --plant-seed N        the realistic plant's draws (default 1)\n"
         "  --torque-timeout S    brake after S seconds without a command (default 0.02, as a\n"
         "                        Panda's FCI after 20 lost packets)\n"
         "  --table-under-flange D  a table (30 x 30 cm) whose top is D m under the flange at\n"
         "                        the start; the contact wrench on the flange and the bodies\n"
         "                        beyond it is published on ~/contact_wrench at 100 Hz\n";
}

// The robot's own options, before --ros-args; the rest is ROS's.
std::vector<std::string> parse_robot_options(const std::vector<std::string>& arguments,
                                             RobotOptions& options) {
  std::size_t i = 0;
  const auto value = [&](const std::string& flag) {
    if (i + 1 >= arguments.size()) throw UsageError(flag + " needs a value");
    return arguments[++i];
  };
  for (; i < arguments.size() && arguments[i] != "--ros-args"; ++i) {
    const std::string& argument = arguments[i];
    if (argument == "--help" || argument == "-h") {
      options.help = true;
    } else if (argument == "--plant") {
      options.plant = value(argument);
    } else if (argument == "--plant-seed") {
      const std::string text = value(argument);
      std::size_t used = 0;
      try {
        options.plant_seed = std::stoull(text, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != text.size() || text.empty() || text[0] == '-') {
        throw UsageError("--plant-seed '" + text + "' is not a whole number >= 0");
      }
    } else if (argument == "--torque-timeout" || argument == "--table-under-flange") {
      const std::string text = value(argument);
      char* end = nullptr;
      const double seconds_or_metres = std::strtod(text.c_str(), &end);
      if (end == text.c_str() || *end != '\0' || !(seconds_or_metres > 0.0)) {
        throw UsageError(argument + " '" + text + "' is not a number > 0");
      }
      (argument == "--table-under-flange" ? options.table_depth : options.torque_timeout) =
          seconds_or_metres;
    } else {
      throw UsageError("unknown argument '" + argument + "' (see --help)");
    }
  }
  return std::vector<std::string>(arguments.begin() + static_cast<std::ptrdiff_t>(i),
                                  arguments.end());
}

// A sensor_msgs/JointState with storage of its own: set() allocates nothing.
class JointStateArray {
 public:
  explicit JointStateArray(const std::vector<std::string>& names)
      : names_(names), position_(names.size()), velocity_(names.size()), effort_(names.size()) {
    for (std::string& name : names_) pointers_.push_back(name.data());
    const auto n = static_cast<std::uint32_t>(names.size());
    message_.name._buffer = pointers_.data();
    message_.position._buffer = position_.data();
    message_.velocity._buffer = velocity_.data();
    // The joint torque sensors (link side, gravity included), for collision.measured_torque.
    message_.effort._buffer = effort_.data();
    message_.name._length = message_.position._length = message_.velocity._length =
        message_.effort._length = n;
    message_.name._maximum = message_.position._maximum = message_.velocity._maximum =
        message_.effort._maximum = n;
    message_.header.frame_id = empty_.data();
  }

  const JointStateMessage& set(const ci::runtime::JointMeasurement& measured,
                               std::chrono::steady_clock::time_point now) {
    for (std::size_t i = 0; i < position_.size(); ++i) {
      position_[i] = measured.q[static_cast<Eigen::Index>(i)];
      velocity_[i] = measured.dq[static_cast<Eigen::Index>(i)];
      effort_[i] = measured.effort.size() == measured.q.size()
                       ? measured.effort[static_cast<Eigen::Index>(i)]
                       : 0.0;
    }
    // The stamp is ROS time (the system clock): now on it, less the reading's age.
    const auto age = std::chrono::duration_cast<std::chrono::nanoseconds>(now - measured.sampled);
    const std::int64_t ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                std::chrono::system_clock::now().time_since_epoch())
                                .count() -
                            age.count();
    message_.header.stamp.sec = static_cast<std::int32_t>(ns / 1000000000);
    message_.header.stamp.nanosec = static_cast<std::uint32_t>(ns % 1000000000);
    return message_;
  }

 private:
  std::vector<std::string> names_;
  std::vector<char*> pointers_;
  std::vector<double> position_, velocity_, effort_;
  std::string empty_;
  JointStateMessage message_{};
};

// DDS could not create an entity: the middleware's failure (exit code 1), not a fault of what the
// robot was given (2).
class MiddlewareFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

template <typename Make>
auto middleware(Make make) -> decltype(make()) {
  try {
    return make();
  } catch (const ci::Error& error) {
    throw MiddlewareFailure(error.what());
  }
}

class SimulatedRobot {
 public:
  SimulatedRobot(const RosArguments& arguments, const Ros2Configuration& configuration,
                 const RobotOptions& options)
      : model_(ci::RobotModel::from_urdf_string(configuration.urdf,
                                                configuration.common.settings.base_link,
                                                configuration.common.settings.tip_link)),
        simulation_(simulate(configuration, model_, options)),
        measurements_(model_.num_joints()),
        torques_(model_.num_joints()),
        driver_(simulation_, measurements_, torques_, driver_options(options, model_)),
        joint_states_topic_(arguments.resolve("joint_states")),
        commands_topic_(arguments.resolve(configuration.effort_controller + "/commands")),
        contact_topic_(arguments.resolve("~/contact_wrench")),
        participant_(middleware([] { return Participant(); })),
        joint_states_(middleware([&] {
          return Writer<JointStateMessage>(participant_, "rt" + joint_states_topic_,
                                           configuration.publisher(joint_states_topic_));
        })),
        commands_(middleware([&] {
          return Reader<Float64MultiArray>(participant_, "rt" + commands_topic_,
                                           configuration.subscription(commands_topic_));
        })),
        contact_(middleware([&] {
          return Writer<WrenchStamped>(participant_, "rt" + contact_topic_,
                                       configuration.publisher(contact_topic_));
        })),
        wake_(middleware([&] {
          return Entity(check(dds_create_guardcondition(participant_.get()), "guard condition"));
        })),
        graph_(middleware([&] { return GraphAnnouncer(participant_, configuration.ros_distro); })) {
    // A node of ROS 2's graph, as a robot's driver is: `ros2 node list` shows it.
    if (!graph_.announce(arguments.node_namespace, arguments.node_name, {commands_.get()},
                         {joint_states_.get(), contact_.get()})) {
      log(LogLevel::warn, "could not announce the robot on ros_discovery_info");
    }
    log(LogLevel::info, "simulating " + std::to_string(model_.num_joints()) + " joints (plant " +
                            options.plant + "): " + joint_states_topic_ + " out, " +
                            commands_topic_ + " in");
  }

  int run(const std::atomic<bool>& stop) {
    driver_.start();
    std::thread publisher([this] { publish_joint_states(); });
    std::thread commands([this] { take_commands(); });
    auto next_report = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (!stop) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      if (std::chrono::steady_clock::now() >= next_report) {
        report();
        next_report += std::chrono::seconds(5);
      }
    }
    stop_ = true;
    dds_set_guardcondition(wake_.get(), true);
    publisher.join();
    commands.join();
    driver_.stop();
    report();
    return 0;
  }

 private:
  static ci::sim::Simulation simulate(const Ros2Configuration& configuration,
                                      const ci::RobotModel& model, const RobotOptions& options) {
    const ci::sim::PlantOptions plant = ci::sim::plant_from_name(options.plant, options.plant_seed);
    if (options.table_depth == 0.0) return simulate_arm(configuration, model, plant);
    const ci::Pose flange = simulate_arm(configuration, model).body_pose(model.tip_link());
    if (options.table_depth >= flange.position.z()) {
      throw ci::Error("--table-under-flange " + ci::format_number(options.table_depth) +
                      " m: the flange is only " + ci::format_number(flange.position.z()) +
                      " m above the floor");
    }
    const ci::sim::Box table =
        ci::sim::Box::table(flange.position.head<2>(), Eigen::Vector2d::Constant(0.15),
                            flange.position.z() - options.table_depth, "table");
    return simulate_arm(configuration, model, plant, {table});
  }

  static ci::sim::SimulatedDriverOptions driver_options(const RobotOptions& options,
                                                        const ci::RobotModel& model) {
    ci::sim::SimulatedDriverOptions driver;
    driver.torque_timeout = options.torque_timeout;
    driver.contact_body = model.tip_link();
    return driver;
  }

  // Each reading once, as soon as the driver published it (polled every 100 us); the contact
  // wrench every 10 ms.
  void publish_joint_states() {
    JointStateArray message(model_.joint_names());
    ci::runtime::JointMeasurement measured;
    std::uint64_t published = 0;
    const timespec pause{0, 100000};
    WrenchStamped contact{};
    std::string world = "world";
    contact.header.frame_id = world.data();
    auto next_contact = std::chrono::steady_clock::now();
    while (!stop_) {
      measurements_.read(measured);
      const auto now = ci::runtime::monotonic_now();
      if (measured.sequence != published) {
        published = measured.sequence;
        joint_states_.write(message.set(measured, now));
      }
      if (now >= next_contact) {
        next_contact += std::chrono::milliseconds(10);
        const ci::Vector6d wrench = driver_.state().contact_wrench;
        contact.header.stamp = stamp_now();
        contact.wrench.force = {wrench[0], wrench[1], wrench[2]};
        contact.wrench.torque = {wrench[3], wrench[4], wrench[5]};
        contact_.write(contact);
      }
      clock_nanosleep(CLOCK_MONOTONIC, 0, &pause, nullptr);
    }
  }

  void take_commands() {
    const dds_entity_t waitset = dds_create_waitset(participant_.get());
    if (waitset < 0) return;
    dds_set_status_mask(commands_.get(), DDS_DATA_AVAILABLE_STATUS);
    dds_waitset_attach(waitset, commands_.get(), 0);
    dds_waitset_attach(waitset, wake_.get(), 1);
    const auto n = static_cast<std::uint32_t>(model_.num_joints());
    ci::JointVector tau(model_.num_joints());
    std::uint64_t count = 0;
    while (!stop_) {
      commands_.take([&](const Float64MultiArray& message, const dds_sample_info_t& info) {
        latency_.record(dds_time() - info.source_timestamp);
        if (message.data._length != n) {
          wrong_size_.fetch_add(1, std::memory_order_relaxed);
          return;
        }
        for (std::uint32_t i = 0; i < n; ++i) tau[i] = message.data._buffer[i];
        torques_.write(tau, ++count);
      });
      dds_waitset_wait(waitset, nullptr, 0, DDS_MSECS(100));
    }
    dds_delete(waitset);
  }

  void report() const {
    const ci::sim::SimulatedDriverState state = driver_.state();
    const ci::runtime::DurationHistogram::Snapshot latency = latency_.snapshot();
    char line[512];
    std::snprintf(line, sizeof line,
                  "%llu ticks (%llu late), %llu torques (%llu refused, %llu of the wrong size), "
                  "%llu brakes after the torque timeout; effort commands from written to taken: "
                  "%llu, p50 %.0f us, p99 %.0f us, max %.0f us",
                  static_cast<unsigned long long>(state.ticks),
                  static_cast<unsigned long long>(state.late_ticks),
                  static_cast<unsigned long long>(state.torques),
                  static_cast<unsigned long long>(state.rejected_torques),
                  static_cast<unsigned long long>(wrong_size_.load()),
                  static_cast<unsigned long long>(state.torque_timeouts),
                  static_cast<unsigned long long>(latency.count), latency.quantile_us(0.5),
                  latency.quantile_us(0.99), latency.max_us());
    log(LogLevel::info, line);
  }

  ci::RobotModel model_;
  ci::sim::Simulation simulation_;
  ci::runtime::MeasurementBuffer measurements_;
  ci::runtime::TorqueOutbox torques_;
  ci::sim::SimulatedDriver driver_;
  std::string joint_states_topic_, commands_topic_, contact_topic_;
  Participant participant_;
  Writer<JointStateMessage> joint_states_;
  Reader<Float64MultiArray> commands_;
  Writer<WrenchStamped> contact_;
  Entity wake_;
  GraphAnnouncer graph_;
  std::atomic<bool> stop_{false};
  ci::runtime::DurationHistogram latency_;  // [ns] the commands' source timestamp to their take
  std::atomic<std::uint64_t> wrong_size_{0};
};

}  // namespace
}  // namespace cartesian_impedance_ros2

int main(int argc, char** argv) {
  namespace ros2 = cartesian_impedance_ros2;
  mallopt(M_MMAP_THRESHOLD, 1 << 20);  // as the node: large samples are given back
  ros2::RobotOptions options;
  ros2::RosArguments arguments;
  ros2::Ros2Configuration configuration;
  try {
    const std::vector<std::string> ros_arguments =
        ros2::parse_robot_options(std::vector<std::string>(argv + 1, argv + argc), options);
    if (options.help) {
      std::cout << ros2::robot_usage();
      return 0;
    }
    arguments = ros2::parse_arguments(ros_arguments);
    bool named = false;
    for (const std::string& argument : ros_arguments) {
      named = named || argument.rfind("__node:=", 0) == 0;
    }
    if (!named) arguments.node_name = "sim_robot";
    ros2::set_logger_name(arguments.fully_qualified_name());
    configuration = ros2::read_configuration(arguments);
  } catch (const ros2::UsageError& error) {
    std::cerr << "cartesian_impedance_ros2_sim_robot: " << error.what() << "\n"
              << ros2::robot_usage();
    return 2;
  } catch (const std::exception& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 2;
  }
  std::signal(SIGINT, ros2::on_signal);
  std::signal(SIGTERM, ros2::on_signal);
  std::optional<ros2::SimulatedRobot> robot;
  try {
    robot.emplace(arguments, configuration, options);
  } catch (const ros2::UsageError& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());  // a topic name that is not valid
    return 2;
  } catch (const cartesian_impedance::Error& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());  // the model, the plant, the table
    return 2;
  } catch (const std::exception& error) {  // DDS
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 1;
  }
  return robot->run(ros2::stop_requested);
}
