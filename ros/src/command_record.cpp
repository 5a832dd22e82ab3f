#include "command_record.hpp"

#include <algorithm>
#include <string>
#include <type_traits>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/core/math.hpp>
#include <cartesian_impedance/node/log_throttle.hpp>

namespace cartesian_impedance_ros {

namespace ci = cartesian_impedance;

namespace {

// The stiffness and damping configurations share six fields, x, y, z of translation and rotation.
template <typename Config>
ci::Vector6d axes_of(const Config& config) {
  return (ci::Vector6d() << config.translation_x, config.translation_y, config.translation_z,
          config.rotation_x, config.rotation_y, config.rotation_z)
      .finished();
}

template <typename Config>
void set_axes(Config& config, const ci::Vector6d& axes) {
  config.translation_x = axes[0];
  config.translation_y = axes[1];
  config.translation_z = axes[2];
  config.rotation_x = axes[3];
  config.rotation_y = axes[4];
  config.rotation_z = axes[5];
}

ci::Vector6d wrench_of(const WrenchConfig& config) {
  return (ci::Vector6d() << config.f_x, config.f_y, config.f_z, config.tau_x, config.tau_y,
          config.tau_z)
      .finished();
}

// `record` with the entries where `after` differs from `before` replaced by those of `after`.
ci::Vector6d replace_changed(ci::Vector6d record, const ci::Vector6d& before,
                             const ci::Vector6d& after) {
  for (int i = 0; i < 6; ++i) {
    if (after[i] != before[i]) record[i] = after[i];
  }
  return record;
}

double clamp(double value, const ci::Range& range) {
  return std::clamp(value, range.min, range.max);
}

}  // namespace

CommandRecord::CommandRecord(const ci::Parameters& parameters)
    : stiffness(ci::Vector6d((ci::Vector6d() << parameters.stiffness.translation,
                              parameters.stiffness.rotation)
                                 .finished())
                    .asDiagonal()),
      stiffness_frame(parameters.stiffness.frame),
      damping_ratio((ci::Vector6d() << parameters.damping_ratio.translation,
                     parameters.damping_ratio.rotation)
                        .finished()),
      nullspace_stiffness(parameters.nullspace.stiffness),
      nullspace_damping_ratio(parameters.nullspace.damping_ratio),
      wrench((ci::Vector6d() << parameters.wrench.force, parameters.wrench.torque).finished()),
      wrench_frame(parameters.wrench.frame),
      configured_stiffness_frame(parameters.stiffness.frame),
      configured_wrench_frame(parameters.wrench.frame),
      limits(parameters.limits) {}

void CommandRecord::record(const std::vector<ci::Command>& commands) {
  for (const ci::Command& command : commands) {
    std::visit(
        [this](const auto& c) {
          using T = std::decay_t<decltype(c)>;
          if constexpr (std::is_same_v<T, ci::Stiffness>) {
            stiffness = c.stiffness;
            stiffness_frame = c.frame.value_or(configured_stiffness_frame);
          } else if constexpr (std::is_same_v<T, ci::DampingRatio>) {
            damping_ratio = c.ratio;
          } else if constexpr (std::is_same_v<T, ci::NullspaceStiffness>) {
            nullspace_stiffness = c.stiffness;
          } else if constexpr (std::is_same_v<T, ci::NullspaceDampingRatio>) {
            nullspace_damping_ratio = c.ratio;
          } else if constexpr (std::is_same_v<T, ci::Wrench>) {
            wrench = c.wrench;
            wrench_frame = c.frame.value_or(configured_wrench_frame);
          }
        },
        command);
  }
}

std::optional<SharedValue> shared_value(const ci::Command& command) {
  return std::visit(
      [](const auto& c) -> std::optional<SharedValue> {
        using T = std::decay_t<decltype(c)>;
        if constexpr (std::is_same_v<T, ci::Stiffness>) return SharedValue::stiffness;
        if constexpr (std::is_same_v<T, ci::DampingRatio>) return SharedValue::damping_ratio;
        if constexpr (std::is_same_v<T, ci::NullspaceStiffness>) {
          return SharedValue::nullspace_stiffness;
        }
        if constexpr (std::is_same_v<T, ci::NullspaceDampingRatio>) {
          return SharedValue::nullspace_damping;
        }
        if constexpr (std::is_same_v<T, ci::Wrench>) return SharedValue::wrench;
        return std::nullopt;
      },
      command);
}

// ---- requests -----------------------------------------------------------------------------

std::vector<ci::Command> reconfigure_commands(const CommandRecord& record,
                                              const StiffnessConfig& applied,
                                              const StiffnessConfig& requested) {
  std::vector<ci::Command> commands;
  const ci::Vector6d before = axes_of(applied);
  const ci::Vector6d after = axes_of(requested);
  if (after != before) {
    ci::Matrix6d stiffness = record.stiffness;
    stiffness.diagonal() = replace_changed(stiffness.diagonal(), before, after);
    commands.emplace_back(ci::Stiffness(stiffness, record.stiffness_frame));
  }
  if (requested.nullspace_stiffness != applied.nullspace_stiffness) {
    commands.emplace_back(
        ci::NullspaceStiffness(ci::JointVector::Constant(1, requested.nullspace_stiffness)));
  }
  return commands;
}

std::vector<ci::Command> reconfigure_commands(const CommandRecord& record,
                                              const DampingConfig& applied,
                                              const DampingConfig& requested) {
  std::vector<ci::Command> commands;
  const ci::Vector6d before = axes_of(applied);
  const ci::Vector6d after = axes_of(requested);
  if (after != before) {
    commands.emplace_back(ci::DampingRatio{replace_changed(record.damping_ratio, before, after)});
  }
  if (requested.nullspace_damping != applied.nullspace_damping) {
    commands.emplace_back(ci::NullspaceDampingRatio{requested.nullspace_damping});
  }
  return commands;
}

std::vector<ci::Command> reconfigure_commands(const CommandRecord& record,
                                              const WrenchConfig& applied,
                                              const WrenchConfig& requested) {
  const ci::Vector6d before = wrench_of(applied);
  const ci::Vector6d after = wrench_of(requested);
  const bool frame_changed = requested.frame != applied.frame;
  if (after == before && !frame_changed) return {};
  // The library's message quotes a name it refuses whole: a peer's megabyte would be a megabyte
  // log line. No valid name is long.
  if (frame_changed && requested.frame.size() > 64) {
    throw ci::Error("frame = " + ci::node::quoted(requested.frame, 32) +
                    " is not a frame (valid: base, end_effector)");
  }
  const ci::Frame frame =
      frame_changed ? ci::frame_from_name("frame", requested.frame) : record.wrench_frame;
  return {ci::Wrench(replace_changed(record.wrench, before, after), frame)};
}

// ---- what the servers show ----------------------------------------------------------------

void show(const CommandRecord& record, SharedValue value, StiffnessConfig& config) {
  const ci::LimitParameters& limits = record.limits;
  if (value == SharedValue::stiffness) {
    ci::Matrix6d stiffness = record.stiffness;
    ci::saturate_stiffness(stiffness, limits.stiffness.translation.min,
                           limits.stiffness.translation.max, limits.stiffness.rotation.min,
                           limits.stiffness.rotation.max);
    set_axes(config, stiffness.diagonal());
  } else if (value == SharedValue::nullspace_stiffness) {
    config.nullspace_stiffness = clamp(record.nullspace_stiffness[0], limits.nullspace_stiffness);
  }
}

void show(const CommandRecord& record, SharedValue value, DampingConfig& config) {
  const ci::Range& range = record.limits.damping_ratio;
  if (value == SharedValue::damping_ratio) {
    set_axes(config, record.damping_ratio.cwiseMax(range.min).cwiseMin(range.max).eval());
  } else if (value == SharedValue::nullspace_damping) {
    config.nullspace_damping = clamp(record.nullspace_damping_ratio, range);
  }
}

void show(const CommandRecord& record, SharedValue value, WrenchConfig& config) {
  if (value != SharedValue::wrench) return;
  ci::Vector6d wrench = record.wrench;
  ci::clip_norm(wrench.head<3>(), record.limits.wrench.force);
  ci::clip_norm(wrench.tail<3>(), record.limits.wrench.torque);
  config.f_x = wrench[0];
  config.f_y = wrench[1];
  config.f_z = wrench[2];
  config.tau_x = wrench[3];
  config.tau_y = wrench[4];
  config.tau_z = wrench[5];
  config.frame = std::string(ci::frame_name(record.wrench_frame));
}

}  // namespace cartesian_impedance_ros
