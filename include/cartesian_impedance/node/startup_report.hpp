#pragma once
/// @file
/// What a node says once when it starts, about the limits it runs with: on an arm nobody tuned
/// most of them are derived from the URDF (apply_robot_defaults()), and a user should see what
/// they came to, and hear when the torque-rate limit cannot follow the stiffest spring allowed.

#include <string>
#include <vector>

#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/node/status_reports.hpp"

namespace cartesian_impedance::node {

/// One info line with the limits in force (joint torques as the loop fills them in, torque
/// rates, stiffness, wrench and plausible joint speed limits), then, if `start_q` is given, one
/// warning per group the rate check (model/rate_check.hpp) finds the rate limit cannot follow at
/// that configuration, or one warning saying why the check could not be made. Not for the control
/// cycle.
/// @throws Error as with_robot_limits() for joint torques above the URDF's efforts (the loop
///         would have refused them already).
std::vector<ReportLine> startup_report(const Parameters& parameters, const RobotModel& model,
                                       const JointVector* start_q);

/// The rate check's part of startup_report(): one warning per group the torque-rate limit cannot
/// follow at `q` (the robot's limits filled in as the loop fills them), each starting with
/// `where` ("at the start configuration"), or one saying why the check could not be made. The
/// one check for the start and for a run-time change of the limits it reads.
std::vector<ReportLine> rate_check_report(const Parameters& parameters, const RobotModel& model,
                                          const JointVector& q, const std::string& where);

}  // namespace cartesian_impedance::node
