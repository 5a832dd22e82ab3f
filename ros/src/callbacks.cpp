// The ROS callbacks: messages converted and validated, frames resolved through tf2, commands
// handed to the control loop. A rejected message is logged (throttled per topic and kind of
// fault) and changes nothing.
// Commands of the values that the reconfigure servers share go through send_from_topic()
// (reconfigure.cpp), which records them and makes the servers show them.

#include <optional>
#include <string>
#include <string_view>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/node/log_throttle.hpp>

#include "node.hpp"

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;

namespace {

// tf2 frame ids carry no leading slash; tolerate the tf1 habit.
std::string_view strip_slash(const std::string& frame_id) {
  std::string_view frame(frame_id);
  while (!frame.empty() && frame.front() == '/') frame.remove_prefix(1);
  return frame;
}

}  // namespace

void CartesianImpedanceNode::warn_rejected(const char* topic, const std::exception& error) {
  std::optional<std::string> line;
  {
    const std::lock_guard<std::mutex> lock(log_mutex_);
    line = log_throttle_.rejected(topic, error);
  }
  if (line) ROS_WARN("%s", line->c_str());
}

void CartesianImpedanceNode::on_joint_states(const sensor_msgs::JointState::ConstPtr& message) {
  // One writer (roscpp never runs one subscription's callback twice at once).
  try {
    JointSample sample;
    if (!joint_mapper_->map(joint_state_view(*message), sample)) return;  // about other joints
    if (!sample.q.allFinite() || !sample.dq.allFinite()) {
      ROS_WARN_THROTTLE(1.0,
                        "joint_states has non-finite values: passed on, the controller "
                        "ramps the torque down");
    }
    joint_samples_->publish(sample);  // numbered and stamped with the time of arrival
  } catch (const std::exception& error) {
    warn_rejected("joint_states", error);
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
    warn_rejected("reference_pose", error);
  }
}

ci::Command CartesianImpedanceNode::framed_command(const std::string& frame_id,
                                                   const ci::Vector6d& values, bool stiffness) {
  Eigen::Matrix3d rotation;
  const std::optional<ci::Frame> frame = frame_of(frame_id, rotation);
  const bool as_given = frame || frame_id.empty();
  if (stiffness) {
    if (as_given) return ci::Stiffness::diagonal(values, frame);
    return ci::Stiffness(rotate_stiffness(rotation, values), ci::Frame::base);
  }
  if (as_given) return ci::Wrench(values, frame);
  return ci::Wrench(rotate_wrench(rotation, values), ci::Frame::base);
}

void CartesianImpedanceNode::on_stiffness(const geometry_msgs::WrenchStamped::ConstPtr& message) {
  try {
    send_from_topic(
        {framed_command(message->header.frame_id, vector_from_wrench(message->wrench), true)});
  } catch (const std::exception& error) {
    warn_rejected("set_cartesian_stiffness", error);
  }
}

void CartesianImpedanceNode::on_damping_factors(const geometry_msgs::Wrench::ConstPtr& message) {
  try {
    send_from_topic({ci::DampingRatio{vector_from_wrench(*message)}});
  } catch (const std::exception& error) {
    warn_rejected("set_damping_factors", error);
  }
}

void CartesianImpedanceNode::on_wrench(const geometry_msgs::WrenchStamped::ConstPtr& message) {
  try {
    send_from_topic(
        {framed_command(message->header.frame_id, vector_from_wrench(message->wrench), false)});
  } catch (const std::exception& error) {
    warn_rejected("set_cartesian_wrench", error);
  }
}

void CartesianImpedanceNode::on_config(const NullspaceConfig::ConstPtr& message) {
  try {
    // All parts or none: a bad message changes nothing.
    std::vector<ci::Command> commands;
    if (!message->q_d_nullspace.empty()) {
      commands.emplace_back(ci::NullspaceTarget(Eigen::Map<const Eigen::VectorXd>(
          message->q_d_nullspace.data(),
          static_cast<Eigen::Index>(message->q_d_nullspace.size()))));
    }
    if (!message->nullspace_stiffness.empty()) {
      commands.emplace_back(ci::NullspaceStiffness(Eigen::Map<const Eigen::VectorXd>(
          message->nullspace_stiffness.data(),
          static_cast<Eigen::Index>(message->nullspace_stiffness.size()))));
    }
    commands.emplace_back(ci::NullspaceDampingRatio{message->nullspace_damping_ratio});
    send_from_topic(commands);
  } catch (const std::exception& error) {
    warn_rejected("set_config", error);
  }
}

void CartesianImpedanceNode::on_resume(const std_msgs::Empty::ConstPtr& /*message*/) {
  try {
    // Ends a latched collision reaction; the arm holds where it is until the next reference.
    loop_->resume();
    ROS_INFO("resume: a latched collision reaction (if any) ends; holding where the arm is");
  } catch (const std::exception& error) {
    warn_rejected("resume", error);
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
    warn_rejected("joint_trajectory", error);
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

// ---- frames ---------------------------------------------------------------------------------

// A frame named with or without the node's tf_prefix.
bool CartesianImpedanceNode::is_base(const std::string& frame_id) const {
  const std::string_view frame = strip_slash(frame_id);
  return frame == settings_.base_link || frame == tf_frame(settings_, settings_.base_link);
}

bool CartesianImpedanceNode::is_tip(const std::string& frame_id) const {
  const std::string_view frame = strip_slash(frame_id);
  return frame == settings_.tip_link || frame == tf_frame(settings_, settings_.tip_link);
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
  const std::string base = tf_frame(settings_, settings_.base_link);
  // No frame of a tf tree is this long: refused before tf2 waits tf_timeout for it and quotes it
  // in its message (a megabyte frame_id made log lines of megabytes).
  constexpr std::size_t kMaxFrameLength = 256;
  if (frame.size() > kMaxFrameLength) {
    throw ci::Error("header.frame_id = " + ci::node::quoted(frame) + " is longer than " +
                    std::to_string(kMaxFrameLength) + " characters: no frame of the tf tree");
  }
  try {
    const geometry_msgs::TransformStamped transform = tf_buffer_->lookupTransform(
        base, frame, ros::Time(0), ros::Duration(configuration_.tf_timeout));
    return isometry_from_transform(transform.transform);
  } catch (const tf2::TransformException& error) {
    throw ci::Error("no transform from frame " + ci::node::quoted(frame) + " to the base frame '" +
                    base + "' within " + ci::format_number(configuration_.tf_timeout) +
                    " s: " + error.what());
  }
}

}  // namespace cartesian_impedance_ros
