// What leaves the node: controller_state (with the control thread's timing), commanded_torques,
// (sim mode) joint_states and the chain's transforms on /tf at ~publish_rate from the publisher
// thread (computed there from the measured q, with the model's KDL code), which also logs status
// changes, lost joint_states and, every 5 s while there are any, a summary of the control thread's
// overruns; effort_command each control cycle (topics mode) from the effort thread. Neither ever
// blocks the control thread: they read its lock-free outboxes and atomic counters.

#include <std_msgs/Float64MultiArray.h>
#include <tf2_msgs/TFMessage.h>

#include <cartesian_impedance/node/status_reports.hpp>

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

// One TransformStamped per joint of `links` for which `pick(joint)` holds, frames prefixed.
template <typename Pick>
tf2_msgs::TFMessage transform_message(const ci::LinkTransforms& links,
                                      const ci::node::NodeSettings& settings, Pick pick) {
  tf2_msgs::TFMessage message;
  for (const ci::LinkJoint& joint : links.joints()) {
    if (!pick(joint)) continue;
    geometry_msgs::TransformStamped transform;
    transform.header.frame_id = tf_frame(settings, joint.parent);
    transform.child_frame_id = tf_frame(settings, joint.child);
    message.transforms.push_back(transform);
  }
  return message;
}

// Fills the transforms of `message` (made by transform_message with the same pick).
template <typename Pick>
void fill_transforms(const ci::LinkTransforms& links, const std::vector<Eigen::Isometry3d>& T,
                     const ros::Time& stamp, Pick pick, tf2_msgs::TFMessage& message) {
  std::size_t k = 0;
  for (std::size_t i = 0; i < links.joints().size(); ++i) {
    if (!pick(links.joints()[i])) continue;
    geometry_msgs::TransformStamped& transform = message.transforms[k++];
    transform.header.stamp = stamp;
    transform_to_message(T[i], transform.transform);
  }
}

bool is_moving(const ci::LinkJoint& joint) {
  return joint.chain_index >= 0;
}
bool is_static(const ci::LinkJoint& joint) {
  return joint.chain_index < 0;
}

}  // namespace

void CartesianImpedanceNode::publish_static_transforms() {
  tf2_msgs::TFMessage message = transform_message(*links_, settings_, is_static);
  std::vector<Eigen::Isometry3d> transforms;
  links_->compute(ci::JointVector::Zero(model_->num_joints()), transforms);
  fill_transforms(*links_, transforms, ros::Time::now(), is_static, message);
  tf_static_publisher_.publish(message);
}

void CartesianImpedanceNode::publisher_thread() {
  ControllerState state_message;
  state_message.header.frame_id = tf_frame(settings_, settings_.base_link);
  tf2_msgs::TFMessage tf_message;
  std::vector<Eigen::Isometry3d> transforms;
  if (links_) tf_message = transform_message(*links_, settings_, is_moving);
  std_msgs::Float64MultiArray torque_message;
  prepare_array(torque_message, model_->num_joints());
  sensor_msgs::JointState joint_message;
  joint_message.name = model_->joint_names();
  ci::node::run_publisher(
      ci::node::publisher_options(settings_), stop_, *control_thread_, *loop_,
      joint_samples_ ? &*joint_samples_ : nullptr,
      [&](const ci::node::PublisherSample& sample) {
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
        if (links_) {
          links_->compute(state.q, transforms);
          fill_transforms(*links_, transforms, stamp, is_moving, tf_message);
          tf_publisher_.publish(tf_message);
        }
      },
      [](const ci::node::ReportLine& line) {
        if (line.level == ci::node::ReportLine::Level::info) {
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
