// cartesian_impedance_sim_robot: a simulated arm in a node of its own that speaks what a robot's
// ROS 1 driver speaks, so that the controller's topics mode can be closed across processes (see
// ros/README.md, "Topics mode over the wire"):
//
// - out: `joint_states` (sensor_msgs/JointState) once per simulation step, each stamped with when
//   its reading was taken (the plant's sensing delay before it was published);
// - in: `effort_command` (std_msgs/Float64MultiArray, one torque per joint in the model's order),
//   the topic the controller's topics mode writes;
// - out: `~contact_wrench` (geometry_msgs/WrenchStamped, world frame) at 100 Hz: what touches the
//   flange and the bodies beyond it (a table, with ~table_under_flange);
// - between them, sim::SimulatedDriver: the arm held by its brakes until the first torque, the
//   last torque held when one is late, the arm braked after ~torque_timeout without one.
//
// Its private parameters are the controller node's settings for sim mode (robot_description,
// ~mjcf_path, ~engine, ~start_q, ~control_rate as the simulation's rate, ~base_link, ~tip_link,
// the controller's ~dynamics/gravity_compensation for the firmware's) and its own: ~plant
// (nominal or realistic), ~plant_seed, ~torque_timeout [s], ~table_under_flange [m]. It logs a
// summary every 5 s and at exit. Exit code 1 for what it cannot start with.

#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64MultiArray.h>
#include <time.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <exception>
#include <optional>
#include <string>
#include <thread>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/node/simulated_arm.hpp>
#include <cartesian_impedance/runtime/robot_io.hpp>
#include <cartesian_impedance/sim/simulated_driver.hpp>

#include "ros_parameters.hpp"

namespace cartesian_impedance_ros {
namespace {

namespace ci = cartesian_impedance;

// The robot's own parameters, taken out of its private namespace before the node's decoder reads
// the rest (which would call them unknown).
struct RobotOptions {
  std::string plant = "nominal";
  int plant_seed = 1;
  double torque_timeout = 0.02;
  double table_depth = 0.0;  // [m] a table's top this far under the flange at the start; 0: none
};

double number(XmlRpc::XmlRpcValue& value, const std::string& name) {
  if (value.getType() == XmlRpc::XmlRpcValue::TypeDouble) return static_cast<double>(value);
  if (value.getType() == XmlRpc::XmlRpcValue::TypeInt) return static_cast<int>(value);
  throw ci::Error("ROS parameter " + name + ": expected a number");
}

RobotOptions take_robot_options(XmlRpc::XmlRpcValue& values, const std::string& namespace_name) {
  RobotOptions options;
  if (values.getType() != XmlRpc::XmlRpcValue::TypeStruct) return options;
  XmlRpc::XmlRpcValue rest;
  rest.begin();  // an empty struct
  for (auto& [key, value] : values) {
    const std::string name = namespace_name + "/" + key;
    if (key == "plant") {
      if (value.getType() != XmlRpc::XmlRpcValue::TypeString) {
        throw ci::Error("ROS parameter " + name + ": expected nominal or realistic");
      }
      options.plant = static_cast<std::string>(value);
    } else if (key == "plant_seed") {
      const double seed = number(value, name);
      if (!(seed >= 0.0 && seed <= 1e9) || seed != static_cast<int>(seed)) {
        throw ci::Error("ROS parameter " + name + " = " + ci::format_number(seed) +
                        ": expected a whole number in [0, 1e9]");
      }
      options.plant_seed = static_cast<int>(seed);
    } else if (key == "torque_timeout" || key == "table_under_flange") {
      const double amount = number(value, name);
      if (!(amount >= 0.0 && amount <= 1e6) || (key == "torque_timeout" && amount == 0.0)) {
        throw ci::Error("ROS parameter " + name + " = " + ci::format_number(amount) +
                        (key == "torque_timeout" ? " s: expected (0, 1e6]" : " m: expected >= 0"));
      }
      (key == "torque_timeout" ? options.torque_timeout : options.table_depth) = amount;
    } else {
      rest[key] = value;
    }
  }
  values = rest;
  return options;
}

class SimulatedRobot {
 public:
  SimulatedRobot(ros::NodeHandle& node, ros::NodeHandle& private_node) {
    XmlRpc::XmlRpcValue values;
    ros::param::get(private_node.getNamespace(), values);
    options_ = take_robot_options(values, private_node.getNamespace());
    configuration_ = configuration_from_xmlrpc(values, private_node.getNamespace());
    std::string urdf;
    if (!node.getParam("robot_description", urdf)) {
      throw ci::Error("parameter " + node.resolveName("robot_description") +
                      " is not set: it must hold the robot's URDF");
    }
    const ci::node::NodeSettings& settings = configuration_.settings;
    model_.emplace(ci::RobotModel::from_urdf_string(urdf, settings.base_link, settings.tip_link));
    const auto report = [](const ci::node::SimulationStart& start) {
      ROS_INFO("%s", start.message.c_str());
    };
    const ci::sim::PlantOptions plant =
        ci::sim::plant_from_name(options_.plant, static_cast<std::uint64_t>(options_.plant_seed));
    std::vector<ci::sim::Box> boxes;
    if (options_.table_depth > 0.0) {
      const ci::Pose flange = ci::node::simulate_arm(configuration_, *model_, urdf, "", report)
                                  .body_pose(model_->tip_link());
      boxes.push_back(ci::sim::Box::table(flange.position.head<2>(),
                                          Eigen::Vector2d::Constant(0.15),
                                          flange.position.z() - options_.table_depth, "table"));
    }
    simulation_.emplace(
        ci::node::simulate_arm(configuration_, *model_, urdf, "", report, plant, boxes));
    const int n = model_->num_joints();
    measurements_.emplace(n);
    torques_.emplace(n);
    ci::sim::SimulatedDriverOptions driver;
    driver.torque_timeout = options_.torque_timeout;
    driver.contact_body = model_->tip_link();
    driver_.emplace(*simulation_, *measurements_, *torques_, driver);

    joint_states_ = node.advertise<sensor_msgs::JointState>("joint_states", 10);
    contact_ = private_node.advertise<geometry_msgs::WrenchStamped>("contact_wrench", 10);
    commands_ = node.subscribe("effort_command", 10, &SimulatedRobot::on_command, this,
                               ros::TransportHints().tcpNoDelay());
    ROS_INFO("simulating %d joints (plant %s): %s out, %s in", n, options_.plant.c_str(),
             node.resolveName("joint_states").c_str(), node.resolveName("effort_command").c_str());
  }

  int run() {
    driver_->start();
    ros::AsyncSpinner spinner(1);  // one: the outbox has one writer
    spinner.start();
    std::thread publisher([this] { publish(); });
    ros::WallTime next_report = ros::WallTime::now() + ros::WallDuration(5.0);
    while (ros::ok()) {
      ros::WallDuration(0.01).sleep();
      if (ros::WallTime::now() >= next_report) {
        report();
        next_report += ros::WallDuration(5.0);
      }
    }
    stop_ = true;
    publisher.join();
    spinner.stop();
    driver_->stop();
    report();
    return 0;
  }

 private:
  void on_command(const std_msgs::Float64MultiArray::ConstPtr& message) {
    if (message->data.size() != static_cast<std::size_t>(model_->num_joints())) {
      ++wrong_size_;
      return;
    }
    ci::JointVector tau(model_->num_joints());
    for (int i = 0; i < model_->num_joints(); ++i) tau[i] = message->data[static_cast<size_t>(i)];
    torques_->write(tau, ++commands_taken_);
  }

  // Each reading once, as soon as the driver published it (polled every 100 us); the contact
  // wrench every 10 ms.
  void publish() {
    sensor_msgs::JointState message;
    message.name = model_->joint_names();
    ci::runtime::JointMeasurement measured;
    std::uint64_t published = 0;
    const timespec pause{0, 100000};
    auto next_contact = std::chrono::steady_clock::now();
    while (!stop_) {
      measurements_->read(measured);
      const auto now = ci::runtime::monotonic_now();
      if (measured.sequence != published) {
        published = measured.sequence;
        message.position.assign(measured.q.data(), measured.q.data() + measured.q.size());
        message.velocity.assign(measured.dq.data(), measured.dq.data() + measured.dq.size());
        // The joint torque sensors (link side, gravity included), for collision.measured_torque.
        message.effort.assign(measured.effort.data(),
                              measured.effort.data() + measured.effort.size());
        // ROS time (the wall clock here) now, less the reading's age.
        message.header.stamp =
            ros::Time::now() -
            ros::Duration(std::chrono::duration<double>(now - measured.sampled).count());
        joint_states_.publish(message);
      }
      if (now >= next_contact) {
        next_contact += std::chrono::milliseconds(10);
        const ci::Vector6d wrench = driver_->state().contact_wrench;
        geometry_msgs::WrenchStamped contact;
        contact.header.stamp = ros::Time::now();
        contact.header.frame_id = "world";
        contact.wrench.force.x = wrench[0];
        contact.wrench.force.y = wrench[1];
        contact.wrench.force.z = wrench[2];
        contact.wrench.torque.x = wrench[3];
        contact.wrench.torque.y = wrench[4];
        contact.wrench.torque.z = wrench[5];
        contact_.publish(contact);
      }
      clock_nanosleep(CLOCK_MONOTONIC, 0, &pause, nullptr);
    }
  }

  void report() const {
    const ci::sim::SimulatedDriverState state = driver_->state();
    ROS_INFO(
        "%llu ticks (%llu late), %llu torques (%llu refused, %llu of the wrong size), %llu "
        "brakes after the torque timeout",
        static_cast<unsigned long long>(state.ticks),
        static_cast<unsigned long long>(state.late_ticks),
        static_cast<unsigned long long>(state.torques),
        static_cast<unsigned long long>(state.rejected_torques),
        static_cast<unsigned long long>(wrong_size_.load()),
        static_cast<unsigned long long>(state.torque_timeouts));
  }

  RobotOptions options_;
  NodeConfiguration configuration_;
  std::optional<ci::RobotModel> model_;
  std::optional<ci::sim::Simulation> simulation_;
  std::optional<ci::runtime::MeasurementBuffer> measurements_;
  std::optional<ci::runtime::TorqueOutbox> torques_;
  std::optional<ci::sim::SimulatedDriver> driver_;
  ros::Publisher joint_states_, contact_;
  ros::Subscriber commands_;
  std::atomic<bool> stop_{false};
  std::uint64_t commands_taken_ = 0;  // the spinner's
  std::atomic<std::uint64_t> wrong_size_{0};
};

}  // namespace
}  // namespace cartesian_impedance_ros

int main(int argc, char** argv) {
  ros::init(argc, argv, "sim_robot");
  ros::NodeHandle node;
  ros::NodeHandle private_node("~");
  std::optional<cartesian_impedance_ros::SimulatedRobot> robot;
  try {
    robot.emplace(node, private_node);
  } catch (const std::exception& error) {
    ROS_FATAL("%s: %s", ros::this_node::getName().c_str(), error.what());
    return 1;
  }
  return robot->run();
}
