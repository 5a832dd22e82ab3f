// What leaves the node: controller_state (with the control thread's timing), commanded_torques and
// (sim mode) joint_states at ~publish_rate from the publisher thread, which also logs status
// changes, lost joint_states and, every 5 s while there are any, a summary of the control thread's
// overruns; effort_command each control cycle (topics mode) from the effort thread. Neither ever
// blocks the control thread: they read its lock-free outboxes and atomic counters.

#include <std_msgs/Float64MultiArray.h>

#include <cartesian_impedance/runtime/status_reports.hpp>

#include "node.hpp"

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;

namespace {

void prepare_array(std_msgs::Float64MultiArray& message, int size) {
  message.layout.dim.resize(1);
  message.layout.dim[0].label = "joints";
  message.layout.dim[0].size = static_cast<std::uint32_t>(size);
  message.layout.dim[0].stride = static_cast<std::uint32_t>(size);
  message.layout.data_offset = 0;
  message.data.assign(static_cast<std::size_t>(size), 0.0);
}

}  // namespace

void CartesianImpedanceNode::publisher_thread() {
  ControllerState state_message;
  state_message.header.frame_id = settings_.base_link;
  std_msgs::Float64MultiArray torque_message;
  prepare_array(torque_message, model_->num_joints());
  sensor_msgs::JointState joint_message;
  joint_message.name = model_->joint_names();
  ci::runtime::run_publisher(
      ci::runtime::publisher_options(settings_), stop_, *control_thread_, *loop_,
      joint_samples_ ? &*joint_samples_ : nullptr,
      [&](const ci::runtime::PublisherSample& sample) {
        const ci::LoopState& state = sample.state;
        const ros::Time stamp = ros::Time::now();
        fill_state_message(state, model_->joint_names(), sample.measured, state_message);
        fill_timing(sample.timing.statistics(), state_message);
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
      },
      [](const ci::runtime::ReportLine& line) {
        if (line.level == ci::runtime::ReportLine::Level::info) {
          ROS_INFO("%s", line.text.c_str());
        } else {
          ROS_WARN("%s", line.text.c_str());
        }
      });
}

void CartesianImpedanceNode::effort_thread() {
  std_msgs::Float64MultiArray message;
  prepare_array(message, model_->num_joints());
  ci::runtime::TorqueSample sample;
  while (!stop_) {
    if (!torques_->wait(0.1, sample)) continue;  // a new cycle's torque, each once
    message.data.assign(sample.tau.data(), sample.tau.data() + sample.tau.size());
    effort_publisher_.publish(message);
  }
}

}  // namespace cartesian_impedance_ros
