#include "cartesian_impedance/parameters.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "cartesian_impedance/error.hpp"

namespace cartesian_impedance {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

template <typename T>
ParameterField field_of(T* pointer) {
  return ParameterField(pointer);
}

std::vector<ParameterInfo> make_table() {
  // Valid ranges here are what is physically meaningful; user limits (limits.*) then saturate
  // commands inside these ranges.
  return {
      {"stiffness.translation", "N/m", 0, kInf, false,
       "Cartesian translational stiffness along x, y, z of the stiffness frame",
       [](Parameters& p) { return field_of(&p.stiffness.translation); }},
      {"stiffness.rotation", "Nm/rad", 0, kInf, false,
       "Cartesian rotational stiffness about x, y, z of the stiffness frame",
       [](Parameters& p) { return field_of(&p.stiffness.rotation); }},
      {"stiffness.frame", "", 0, 0, false,
       "frame the stiffness is expressed in: base or end_effector",
       [](Parameters& p) { return field_of(&p.stiffness.frame); }},
      {"damping_ratio.translation", "-", 0, kInf, false,
       "damping ratio zeta per translational axis, D = 2 zeta sqrt(K)",
       [](Parameters& p) { return field_of(&p.damping_ratio.translation); }},
      {"damping_ratio.rotation", "-", 0, kInf, false, "damping ratio zeta per rotational axis",
       [](Parameters& p) { return field_of(&p.damping_ratio.rotation); }},
      {"minimum_damping.translation", "N s/m", 0, kInf, false,
       "smallest translational damping, so that low or zero stiffness (teaching) stays damped",
       [](Parameters& p) { return field_of(&p.minimum_damping.translation); }},
      {"minimum_damping.rotation", "Nm s/rad", 0, kInf, false, "smallest rotational damping",
       [](Parameters& p) { return field_of(&p.minimum_damping.rotation); }},
      {"minimum_damping.nullspace", "Nm s/rad", 0, kInf, false,
       "smallest nullspace damping per joint",
       [](Parameters& p) { return field_of(&p.minimum_damping.nullspace); }},
      {"nullspace.stiffness", "Nm/rad", 0, kInf, false,
       "joint stiffness toward the nullspace target (one value or one per joint)",
       [](Parameters& p) { return field_of(&p.nullspace.stiffness); }},
      {"nullspace.damping_ratio", "-", 0, kInf, false,
       "nullspace damping ratio, D_ns = 2 zeta sqrt(K_ns)",
       [](Parameters& p) { return field_of(&p.nullspace.damping_ratio); }},
      {"nullspace.pseudo_inverse_damping", "-", 0, kInf, false,
       "lambda in N = I - J^T (J J^T + lambda^2 I)^-1 J; 0 gives the exact projector",
       [](Parameters& p) { return field_of(&p.nullspace.pseudo_inverse_damping); }},
      {"wrench.force", "N", -kInf, kInf, false, "commanded force on the environment, x, y, z",
       [](Parameters& p) { return field_of(&p.wrench.force); }},
      {"wrench.torque", "Nm", -kInf, kInf, false, "commanded torque on the environment, x, y, z",
       [](Parameters& p) { return field_of(&p.wrench.torque); }},
      {"wrench.frame", "", 0, 0, false, "frame the wrench is expressed in: base or end_effector",
       [](Parameters& p) { return field_of(&p.wrench.frame); }},
      {"filter.pose.time", "s", 0, kInf, false,
       "time after which filter.pose.fraction of a reference pose step is applied; 0 = no filter",
       [](Parameters& p) { return field_of(&p.filter.pose.time); }},
      {"filter.pose.fraction", "-", 0, 1, true, "fraction of a step applied after the time",
       [](Parameters& p) { return field_of(&p.filter.pose.fraction); }},
      {"filter.stiffness.time", "s", 0, kInf, false,
       "filter time of stiffness and damping ratio changes; 0 = no filter",
       [](Parameters& p) { return field_of(&p.filter.stiffness.time); }},
      {"filter.stiffness.fraction", "-", 0, 1, true, "fraction of a step applied after the time",
       [](Parameters& p) { return field_of(&p.filter.stiffness.fraction); }},
      {"filter.nullspace.time", "s", 0, kInf, false,
       "filter time of nullspace target, stiffness and damping changes; 0 = no filter",
       [](Parameters& p) { return field_of(&p.filter.nullspace.time); }},
      {"filter.nullspace.fraction", "-", 0, 1, true, "fraction of a step applied after the time",
       [](Parameters& p) { return field_of(&p.filter.nullspace.fraction); }},
      {"filter.wrench.time", "s", 0, kInf, false,
       "filter time of commanded wrench changes; 0 = no filter",
       [](Parameters& p) { return field_of(&p.filter.wrench.time); }},
      {"filter.wrench.fraction", "-", 0, 1, true, "fraction of a step applied after the time",
       [](Parameters& p) { return field_of(&p.filter.wrench.fraction); }},
      {"limits.stiffness.translation.min", "N/m", 0, kInf, false,
       "smallest translational stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.stiffness.translation.min); }},
      {"limits.stiffness.translation.max", "N/m", 0, kInf, false,
       "largest translational stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.stiffness.translation.max); }},
      {"limits.stiffness.rotation.min", "Nm/rad", 0, kInf, false,
       "smallest rotational stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.stiffness.rotation.min); }},
      {"limits.stiffness.rotation.max", "Nm/rad", 0, kInf, false,
       "largest rotational stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.stiffness.rotation.max); }},
      {"limits.damping_ratio.min", "-", 0, kInf, false,
       "smallest damping ratio (Cartesian and nullspace) a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.damping_ratio.min); }},
      {"limits.damping_ratio.max", "-", 0, kInf, false,
       "largest damping ratio (Cartesian and nullspace) a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.damping_ratio.max); }},
      {"limits.nullspace_stiffness.min", "Nm/rad", 0, kInf, false,
       "smallest nullspace stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.nullspace_stiffness.min); }},
      {"limits.nullspace_stiffness.max", "Nm/rad", 0, kInf, false,
       "largest nullspace stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.nullspace_stiffness.max); }},
      {"limits.wrench.force", "N", 0, kInf, false,
       "largest norm of the commanded force; longer vectors are scaled down, keeping direction",
       [](Parameters& p) { return field_of(&p.limits.wrench.force); }},
      {"limits.wrench.torque", "Nm", 0, kInf, false,
       "largest norm of the commanded torque; longer vectors are scaled down, keeping direction",
       [](Parameters& p) { return field_of(&p.limits.wrench.torque); }},
      {"limits.pose_error.translation", "m", 0, kInf, true,
       "translation error norm is clipped to this, so a far reference cannot pull violently",
       [](Parameters& p) { return field_of(&p.limits.pose_error.translation); }},
      {"limits.pose_error.rotation", "rad", 0, kInf, true, "rotation error norm is clipped to this",
       [](Parameters& p) { return field_of(&p.limits.pose_error.rotation); }},
      {"limits.joint_torque", "Nm", 0, kInf, true,
       "absolute commanded torque per joint (one value or one per joint)",
       [](Parameters& p) { return field_of(&p.limits.joint_torque); }},
      {"limits.joint_torque_rate", "Nm/s", 0, kInf, true,
       "rate of change of the commanded torque per joint; the change keeps its direction",
       [](Parameters& p) { return field_of(&p.limits.joint_torque_rate); }},
      {"dynamics.gravity_compensation", "", 0, 0, false,
       "add g(q) to the command, for robots that do not compensate gravity themselves "
       "(needs the model: the control loop provides it)",
       [](Parameters& p) { return field_of(&p.dynamics.gravity_compensation); }},
      {"dynamics.inertia_shaped_damping", "", 0, 0, false,
       "shape the Cartesian damping with the task-space inertia, d = 2 zeta sqrt(m k) per mode, "
       "instead of D = 2 zeta sqrt(K) (needs the model)",
       [](Parameters& p) { return field_of(&p.dynamics.inertia_shaped_damping); }},
      {"dynamics.dynamically_consistent_nullspace", "", 0, 0, false,
       "project the nullspace torque with N = I - J^T Lambda J M^-1 (needs the model)",
       [](Parameters& p) { return field_of(&p.dynamics.dynamically_consistent_nullspace); }},
      {"joint_limit_avoidance.margin", "rad", 0, kInf, false,
       "distance from a joint's position limit where the nullspace push away from it starts",
       [](Parameters& p) { return field_of(&p.joint_limit_avoidance.margin); }},
      {"joint_limit_avoidance.stiffness", "Nm/rad", 0, kInf, false,
       "stiffness of that push (inside the margin, in the nullspace); 0 switches it off",
       [](Parameters& p) { return field_of(&p.joint_limit_avoidance.stiffness); }},
      {"trajectory.goal_tolerance", "rad", 0, kInf, true,
       "every joint within this of the last point reports a trajectory finished",
       [](Parameters& p) { return field_of(&p.trajectory.goal_tolerance); }},
      {"trajectory.goal_time_tolerance", "s", 0, kInf, false,
       "time after the last point within which the goal must be reached, else aborted",
       [](Parameters& p) { return field_of(&p.trajectory.goal_time_tolerance); }},
  };
}

std::string element_name(std::string_view base, const char* suffix) {
  std::string name(base);
  name += suffix;
  return name;
}

constexpr const char* kAxisSuffix[3] = {".x", ".y", ".z"};

std::string with_unit(double value, std::string_view unit) {
  std::string text = format_number(value);
  if (!unit.empty() && unit != "-") text += " " + std::string(unit);
  return text;
}

void check_ranges(const Range& range, std::string_view name, std::string_view unit) {
  if (range.min > range.max) {
    throw Error(std::string(name) + ".min = " + with_unit(range.min, unit) + " is greater than " +
                std::string(name) + ".max = " + with_unit(range.max, unit));
  }
}

}  // namespace

std::string format_number(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.10g", value);
  return buffer;
}

std::string ParameterInfo::range_text() const {
  std::string text = min_exclusive ? "(" : "[";
  text += format_number(min) + ", " + format_number(max);
  text += std::isinf(max) ? ")" : "]";
  if (std::isinf(min)) text[0] = '(';
  return text;
}

void ParameterInfo::check(std::string_view element, double value) const {
  const bool below = min_exclusive ? !(value > min) : !(value >= min);
  if (!std::isfinite(value) || below || value > max) {
    std::string message = std::string(element) + " = " + with_unit(value, unit);
    message += std::isfinite(value) ? " is outside " + range_text()
                                    : " is not finite (valid: " + range_text() + ")";
    throw Error(message);
  }
}

const std::vector<ParameterInfo>& parameter_table() {
  static const std::vector<ParameterInfo> table = make_table();
  return table;
}

const ParameterInfo& parameter_info(std::string_view name) {
  for (const ParameterInfo& info : parameter_table()) {
    if (info.name == name) return info;
  }
  throw Error("unknown parameter '" + std::string(name) + "'");
}

std::string_view frame_name(Frame frame) {
  return frame == Frame::base ? "base" : "end_effector";
}

Frame frame_from_name(std::string_view field, std::string_view name) {
  if (name == "base") return Frame::base;
  if (name == "end_effector") return Frame::end_effector;
  throw Error(std::string(field) + " = '" + std::string(name) +
              "' is not a frame (valid: base, end_effector)");
}

JointVector per_joint(const JointVector& values, int num_joints) {
  if (values.size() == num_joints) return values;
  return JointVector::Constant(num_joints, values.size() > 0 ? values[0] : 0.0);
}

void validate(const Parameters& parameters, int num_joints) {
  // The table only hands out mutable pointers; reading through them changes nothing.
  Parameters& p = const_cast<Parameters&>(parameters);
  for (const ParameterInfo& info : parameter_table()) {
    const ParameterField field = info.in(p);
    if (auto* value = std::get_if<double*>(&field)) {
      info.check(info.name, **value);
    } else if (auto* vector = std::get_if<Eigen::Vector3d*>(&field)) {
      for (int i = 0; i < 3; ++i)
        info.check(element_name(info.name, kAxisSuffix[i]), (**vector)[i]);
    } else if (auto* joints = std::get_if<JointVector*>(&field)) {
      const JointVector& values = **joints;
      const bool size_ok = num_joints > 0 ? (values.size() == 1 || values.size() == num_joints)
                                          : (values.size() >= 1 && values.size() <= kMaxJoints);
      if (!size_ok) {
        throw Error(std::string(info.name) + " has " + std::to_string(values.size()) +
                    " values; expected 1 (all joints) or " +
                    (num_joints > 0 ? std::to_string(num_joints) + " (one per joint)"
                                    : "one per joint, at most " + std::to_string(kMaxJoints)));
      }
      for (Eigen::Index i = 0; i < values.size(); ++i) {
        info.check(std::string(info.name) + "[" + std::to_string(i) + "]", values[i]);
      }
    }
  }
  const LimitParameters& limits = parameters.limits;
  check_ranges(limits.stiffness.translation, "limits.stiffness.translation", "N/m");
  check_ranges(limits.stiffness.rotation, "limits.stiffness.rotation", "Nm/rad");
  check_ranges(limits.damping_ratio, "limits.damping_ratio", "");
  check_ranges(limits.nullspace_stiffness, "limits.nullspace_stiffness", "Nm/rad");
}

std::string value_text(const Parameters& parameters, const ParameterInfo& info) {
  const ParameterField field = info.in(const_cast<Parameters&>(parameters));
  std::ostringstream text;
  if (auto* value = std::get_if<double*>(&field)) {
    text << format_number(**value);
  } else if (auto* vector = std::get_if<Eigen::Vector3d*>(&field)) {
    text << "[" << format_number((**vector)[0]) << ", " << format_number((**vector)[1]) << ", "
         << format_number((**vector)[2]) << "]";
  } else if (auto* joints = std::get_if<JointVector*>(&field)) {
    const JointVector& values = **joints;
    if (values.size() == 1) {
      text << format_number(values[0]);
    } else {
      text << "[";
      for (Eigen::Index i = 0; i < values.size(); ++i) {
        text << (i ? ", " : "") << format_number(values[i]);
      }
      text << "]";
    }
  } else if (auto* frame = std::get_if<Frame*>(&field)) {
    text << frame_name(**frame);
  } else if (auto* flag = std::get_if<bool*>(&field)) {
    text << (**flag ? "true" : "false");
  }
  return text.str();
}

std::string parameter_table_markdown() {
  const Parameters defaults;
  std::ostringstream text;
  text << "| name | unit | default | valid range | description |\n";
  text << "|---|---|---|---|---|\n";
  for (const ParameterInfo& info : parameter_table()) {
    const ParameterField field = info.in(const_cast<Parameters&>(defaults));
    const bool is_frame = std::holds_alternative<Frame*>(field);
    const bool is_switch = std::holds_alternative<bool*>(field);
    text << "| `" << info.name << "` | " << (info.unit.empty() ? "" : info.unit) << " | "
         << value_text(defaults, info) << " | "
         << (is_frame    ? "base, end_effector"
             : is_switch ? "true, false"
                         : info.range_text())
         << " | " << info.description << " |\n";
  }
  return text.str();
}

}  // namespace cartesian_impedance
