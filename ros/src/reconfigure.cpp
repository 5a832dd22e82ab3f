// dynamic_reconfigure: three servers (stiffness, damping factors, wrench) whose ranges come from
// the limits in force and whose values are those in force. A request changes only the fields the
// user changed (command_record.hpp): the commands are built from what the node last commanded,
// from any channel, with those fields replaced.

#include <algorithm>

#include <cartesian_impedance/core/math.hpp>

#include "node.hpp"

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;

namespace {

// The stiffness and damping configurations share six fields, x, y, z of translation and rotation.
template <typename Config>
void set_axes(Config& config, const ci::Range& translation, const ci::Range& rotation,
              double ci::Range::*end) {
  config.translation_x = config.translation_y = config.translation_z = translation.*end;
  config.rotation_x = config.rotation_y = config.rotation_z = rotation.*end;
}

// Ranges of the six axes and of the nullspace field `nullspace` of a stiffness or damping
// configuration.
template <typename Config>
void set_ranges(Config& low, Config& high, const ci::Range& translation, const ci::Range& rotation,
                double Config::*nullspace, const ci::Range& nullspace_range) {
  set_axes(low, translation, rotation, &ci::Range::min);
  set_axes(high, translation, rotation, &ci::Range::max);
  low.*nullspace = nullspace_range.min;
  high.*nullspace = nullspace_range.max;
}

// Creates the server of `state` with the ranges `ranges(low, high)` sets and the values in force
// (update flags false), then sets `callback`. The server's mutex is held throughout, so that no
// request is handled before `state` knows what the server shows.
template <typename State, typename Ranges, typename Callback>
void make_server(State& state, const ros::NodeHandle& handle, const CommandRecord& record,
                 Ranges ranges, Callback callback) {
  using Config = decltype(state.applied);
  const boost::recursive_mutex::scoped_lock lock(state.mutex);
  auto server = std::make_unique<dynamic_reconfigure::Server<Config>>(state.mutex, handle);
  Config low, high, value;
  server->getConfigMin(low);
  server->getConfigMax(high);
  server->getConfigDefault(value);
  ranges(low, high);
  show_all(record, value);
  server->setConfigMin(low);
  server->setConfigMax(high);
  server->setConfigDefault(value);
  server->updateConfig(value);  // also replaces values an earlier run left on the server
  state.applied = state.shown = value;
  server->setCallback(callback);  // calls it once with `value`, whose update flag is false
  state.server = std::move(server);
}

bool sets_stiffness(const std::vector<ci::Command>& commands) {
  return std::any_of(commands.begin(), commands.end(), [](const ci::Command& command) {
    return std::holds_alternative<ci::Stiffness>(command);
  });
}

}  // namespace

void CartesianImpedanceNode::create_reconfigure_servers() {
  // Ranges from the limits in force, values from the record (the parameters at start); the
  // update flags start false, so a server's first callback changes nothing.
  const ci::LimitParameters& limits = record_->limits;
  make_server(
      stiffness_, ros::NodeHandle(private_node_, "stiffness_reconfigure"), *record_,
      [&](StiffnessConfig& low, StiffnessConfig& high) {
        set_ranges(low, high, limits.stiffness.translation, limits.stiffness.rotation,
                   &StiffnessConfig::nullspace_stiffness, limits.nullspace_stiffness);
      },
      [this](auto& config, std::uint32_t level) { on_stiffness_reconfigure(config, level); });
  make_server(
      damping_, ros::NodeHandle(private_node_, "damping_factors_reconfigure"), *record_,
      [&](DampingConfig& low, DampingConfig& high) {
        // One range for every damping ratio.
        const ci::Range& range = limits.damping_ratio;
        set_ranges(low, high, range, range, &DampingConfig::nullspace_damping, range);
      },
      [this](auto& config, std::uint32_t level) { on_damping_reconfigure(config, level); });
  make_server(
      wrench_, ros::NodeHandle(private_node_, "cartesian_wrench_reconfigure"), *record_,
      [&](WrenchConfig& low, WrenchConfig& high) {
        low.f_x = low.f_y = low.f_z = -limits.wrench.force;
        high.f_x = high.f_y = high.f_z = limits.wrench.force;
        low.tau_x = low.tau_y = low.tau_z = -limits.wrench.torque;
        high.tau_x = high.tau_y = high.tau_z = limits.wrench.torque;
      },
      [this](auto& config, std::uint32_t level) { on_wrench_reconfigure(config, level); });
}

// ---- requests (each callback runs with its server's mutex held) -----------------------------

template <typename Config>
void CartesianImpedanceNode::apply_request(Reconfigure<Config>& state, Config& config,
                                           const char* server, bool remove_wrench) {
  const std::lock_guard<std::mutex> lock(record_mutex_);
  CommandRecord& record = *record_;
  std::vector<ci::Command> commands;
  try {
    commands = remove_wrench
                   ? std::vector<ci::Command>{ci::Wrench(ci::Vector6d::Zero(), record.wrench_frame)}
                   : reconfigure_commands(record, state.applied, config);
    if (!commands.empty()) {
      loop_->send_all(commands);
      record.record(commands);
    }
  } catch (const std::exception& error) {
    if (sets_stiffness(commands) && !ci::is_diagonal(record.stiffness)) {
      ROS_WARN(
          "%s rejected: the stiffness in force is a full matrix (set_cartesian_stiffness in a "
          "frame that tf2 rotated into the base frame), and with the changed diagonal entries it "
          "is invalid: %s. Nothing changed; send a diagonal stiffness on set_cartesian_stiffness "
          "to edit it axis by axis",
          server, error.what());
    } else {
      ROS_WARN("%s rejected: %s; nothing changed", server, error.what());
    }
  }
  // The server shows the values in force: the request's where it applied (after the limits),
  // the earlier ones where it was rejected.
  show_all(record, config);
  state.applied = config;
}

void CartesianImpedanceNode::on_stiffness_reconfigure(StiffnessConfig& config,
                                                      std::uint32_t /*level*/) {
  // While update_stiffness is false, edits wait: they count when it turns true.
  if (config.update_stiffness) apply_request(stiffness_, config, "stiffness_reconfigure");
  stiffness_.shown = config;
}

void CartesianImpedanceNode::on_damping_reconfigure(DampingConfig& config,
                                                    std::uint32_t /*level*/) {
  if (config.update_damping_factors) {
    apply_request(damping_, config, "damping_factors_reconfigure");
  }
  damping_.shown = config;
}

void CartesianImpedanceNode::on_wrench_reconfigure(WrenchConfig& config, std::uint32_t /*level*/) {
  if (config.apply_wrench) {
    apply_request(wrench_, config, "cartesian_wrench_reconfigure");
  } else if (wrench_.shown.apply_wrench) {
    // Switching apply_wrench off removes the wrench in force (which the server shows, whichever
    // channel commanded it), as in the published controller; edits while it is off wait.
    apply_request(wrench_, config, "cartesian_wrench_reconfigure", true);
  }
  wrench_.shown = config;
}

// ---- commands from topics -------------------------------------------------------------------

void CartesianImpedanceNode::send_from_topic(const std::vector<ci::Command>& commands) {
  // The servers' mutexes first (see node.hpp), so that what they show follows the record.
  const boost::recursive_mutex::scoped_lock stiffness_lock(stiffness_.mutex);
  const boost::recursive_mutex::scoped_lock damping_lock(damping_.mutex);
  const boost::recursive_mutex::scoped_lock wrench_lock(wrench_.mutex);
  {
    const std::lock_guard<std::mutex> lock(record_mutex_);
    loop_->send_all(commands);
    record_->record(commands);
  }
  for (const ci::Command& command : commands) {
    if (const std::optional<SharedValue> value = shared_value(command)) show_on_servers(*value);
  }
}

void CartesianImpedanceNode::show_on_servers(SharedValue value) {
  // Called with every server's mutex held. A value a topic changed counts as applied: a request
  // that sets it back to what the server showed before is then a change.
  auto update = [&](auto& state) {
    if (!state.server) return;
    show(*record_, value, state.applied);
    show(*record_, value, state.shown);
    state.server->updateConfig(state.shown);
  };
  const std::lock_guard<std::mutex> lock(record_mutex_);
  switch (value) {
    case SharedValue::stiffness:
    case SharedValue::nullspace_stiffness:
      update(stiffness_);
      break;
    case SharedValue::damping_ratio:
    case SharedValue::nullspace_damping:
      update(damping_);
      break;
    case SharedValue::wrench:
      update(wrench_);
      break;
  }
}

}  // namespace cartesian_impedance_ros
