// dynamic_reconfigure: three servers (stiffness, damping factors, wrench) whose ranges come from
// the limits in force and whose values come from the parameters; each callback validates and
// sends commands to the control loop.

#include "node.hpp"

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;

namespace {

// The stiffness and damping configurations share six fields, x, y, z of translation and rotation.
template <typename Config>
void set_axes(Config& config, const Eigen::Vector3d& translation, const Eigen::Vector3d& rotation) {
  config.translation_x = translation.x();
  config.translation_y = translation.y();
  config.translation_z = translation.z();
  config.rotation_x = rotation.x();
  config.rotation_y = rotation.y();
  config.rotation_z = rotation.z();
}

template <typename Config>
ci::Vector6d axes_of(const Config& config) {
  return (ci::Vector6d() << config.translation_x, config.translation_y, config.translation_z,
          config.rotation_x, config.rotation_y, config.rotation_z)
      .finished();
}

// A server whose ranges and value `adjust(low, high, value)` sets on the generated ones, then
// calling `callback`.
template <typename Config, typename Adjust, typename Callback>
std::unique_ptr<dynamic_reconfigure::Server<Config>> make_server(boost::recursive_mutex& mutex,
                                                                 const ros::NodeHandle& handle,
                                                                 Adjust adjust, Callback callback) {
  auto server = std::make_unique<dynamic_reconfigure::Server<Config>>(mutex, handle);
  Config low, high, value;
  server->getConfigMin(low);
  server->getConfigMax(high);
  server->getConfigDefault(value);
  adjust(low, high, value);
  server->setConfigMin(low);
  server->setConfigMax(high);
  server->setConfigDefault(value);
  server->updateConfig(value);
  server->setCallback(callback);
  return server;
}

// Ranges of the six axes and of the nullspace field `nullspace` of a stiffness or damping
// configuration.
template <typename Config>
void set_ranges(Config& low, Config& high, const ci::Range& translation, const ci::Range& rotation,
                double Config::*nullspace, const ci::Range& nullspace_range) {
  set_axes(low, Eigen::Vector3d::Constant(translation.min),
           Eigen::Vector3d::Constant(rotation.min));
  set_axes(high, Eigen::Vector3d::Constant(translation.max),
           Eigen::Vector3d::Constant(rotation.max));
  low.*nullspace = nullspace_range.min;
  high.*nullspace = nullspace_range.max;
}

}  // namespace

void CartesianImpedanceNode::create_reconfigure_servers() {
  // Ranges from the limits in force, values from the parameters; the update flags start false,
  // so a server's first callback (and values left on the parameter server by an earlier run)
  // change nothing.
  const ci::Parameters parameters = loop_->latest_parameters();
  const ci::LimitParameters& limits = parameters.limits;

  stiffness_server_ = make_server<StiffnessConfig>(
      stiffness_mutex_, ros::NodeHandle(private_node_, "stiffness_reconfigure"),
      [&](StiffnessConfig& low, StiffnessConfig& high, StiffnessConfig& value) {
        set_ranges(low, high, limits.stiffness.translation, limits.stiffness.rotation,
                   &StiffnessConfig::nullspace_stiffness, limits.nullspace_stiffness);
        set_axes(value, parameters.stiffness.translation, parameters.stiffness.rotation);
        value.nullspace_stiffness = parameters.nullspace.stiffness[0];
        value.update_stiffness = false;
      },
      [this](auto& config, std::uint32_t level) { on_stiffness_reconfigure(config, level); });

  damping_server_ = make_server<DampingConfig>(
      damping_mutex_, ros::NodeHandle(private_node_, "damping_factors_reconfigure"),
      [&](DampingConfig& low, DampingConfig& high, DampingConfig& value) {
        // One range for every damping ratio.
        const ci::Range& range = limits.damping_ratio;
        set_ranges(low, high, range, range, &DampingConfig::nullspace_damping, range);
        set_axes(value, parameters.damping_ratio.translation, parameters.damping_ratio.rotation);
        value.nullspace_damping = parameters.nullspace.damping_ratio;
        value.update_damping_factors = false;
      },
      [this](auto& config, std::uint32_t level) { on_damping_reconfigure(config, level); });

  wrench_server_ = make_server<WrenchConfig>(
      wrench_mutex_, ros::NodeHandle(private_node_, "cartesian_wrench_reconfigure"),
      [&](WrenchConfig& low, WrenchConfig& high, WrenchConfig& value) {
        low.f_x = low.f_y = low.f_z = -limits.wrench.force;
        high.f_x = high.f_y = high.f_z = limits.wrench.force;
        low.tau_x = low.tau_y = low.tau_z = -limits.wrench.torque;
        high.tau_x = high.tau_y = high.tau_z = limits.wrench.torque;
        value.apply_wrench = false;
      },
      [this](auto& config, std::uint32_t level) { on_wrench_reconfigure(config, level); });
}

void CartesianImpedanceNode::on_stiffness_reconfigure(StiffnessConfig& config,
                                                      std::uint32_t /*level*/) {
  if (!config.update_stiffness) return;
  try {
    loop_->send_all(
        {ci::Stiffness::diagonal(axes_of(config)),
         ci::NullspaceStiffness(ci::JointVector::Constant(1, config.nullspace_stiffness))});
  } catch (const std::exception& error) {
    ROS_WARN("stiffness_reconfigure rejected: %s", error.what());
  }
}

void CartesianImpedanceNode::on_damping_reconfigure(DampingConfig& config,
                                                    std::uint32_t /*level*/) {
  if (!config.update_damping_factors) return;
  try {
    loop_->send_all(
        {ci::DampingRatio{axes_of(config)}, ci::NullspaceDampingRatio{config.nullspace_damping}});
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

}  // namespace cartesian_impedance_ros
