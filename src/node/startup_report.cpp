#include "cartesian_impedance/node/startup_report.hpp"

#include <string>
#include <utility>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/rate_check.hpp"
#include "cartesian_impedance/model/robot_limits.hpp"

namespace cartesian_impedance::node {
namespace {

// One number if every joint has the same, else the list.
std::string per_joint(const JointVector& values, const char* unit) {
  if (values.size() > 0 && (values.array() == values(0)).all()) {
    return format_number(values(0)) + " " + unit;
  }
  std::string text = "[";
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    text += (i > 0 ? ", " : "") + format_number(values(i));
  }
  return text + "] " + unit;
}

const char* speed_unit(const RobotModel& model) {
  for (const JointType type : model.joint_types()) {
    if (type == JointType::prismatic) return "rad/s (m/s for prismatic joints)";
  }
  return "rad/s";
}

}  // namespace

std::vector<ReportLine> startup_report(const Parameters& parameters, const RobotModel& model,
                                       const JointVector* start_q) {
  const Parameters in_force = with_robot_limits(parameters, model);
  const LimitParameters& limits = in_force.limits;
  std::vector<ReportLine> lines;
  for (const std::string& warning : model.warnings()) {
    lines.push_back({ReportLine::Level::warning, "the URDF: " + warning});
  }
  lines.push_back(
      {ReportLine::Level::info,
       "limits in force (those the configuration leaves out are derived from the URDF): joint "
       "torque " +
           per_joint(limits.joint_torque, "Nm") + ", torque rate " +
           per_joint(limits.joint_torque_rate, "Nm/s") + ", stiffness up to " +
           format_number(limits.stiffness.translation.max) + " N/m and " +
           format_number(limits.stiffness.rotation.max) + " Nm/rad, wrench up to " +
           format_number(limits.wrench.force) + " N and " + format_number(limits.wrench.torque) +
           " Nm, plausible joint speed " +
           per_joint(in_force.plausibility.joint_velocity, speed_unit(model))});
  if (start_q == nullptr) return lines;
  for (ReportLine& line :
       rate_check_report(parameters, model, *start_q, "the start configuration")) {
    lines.push_back(std::move(line));
  }
  return lines;
}

std::vector<ReportLine> rate_check_report(const Parameters& parameters, const RobotModel& model,
                                          const JointVector& q, const std::string& where) {
  std::vector<ReportLine> lines;
  try {
    const RateCheck check = check_rate_limit(model, q, with_robot_limits(parameters, model));
    for (const std::string& warning : check.warnings) {
      lines.push_back({ReportLine::Level::warning, "at " + where + ": " + warning});
    }
  } catch (const Error& error) {
    lines.push_back({ReportLine::Level::warning,
                     "the torque-rate check cannot be made at " + where + ": " + error.what()});
  }
  return lines;
}

}  // namespace cartesian_impedance::node
