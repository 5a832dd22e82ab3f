#pragma once
// What the scenarios share: result lines, the Rig's helpers and the registry's entries. Internal
// to the scenarios library (the demo and the tests include scenarios.hpp).

#include <array>
#include <initializer_list>
#include <limits>
#include <string>
#include <vector>

#include "scenarios.hpp"

namespace cartesian_impedance::scenarios::detail {

constexpr double kDt = 0.001;
constexpr double kForever = std::numeric_limits<double>::infinity();

/// Breaks the runner's controllers on purpose (for tests of the tests): the hook replaces the
/// torque they computed with what a broken controller would apply.
void set_mutation(sim::ClosedLoopRunner& runner, Mutation mutation);

Vector6d six(double a, double b, double c, double d, double e, double f);

/// |measured - expected| <= tolerance.
Result compare(const std::string& scenario, const std::string& quantity, double expected,
               double measured, const std::string& unit, double tolerance,
               const std::string& note = "");
Result at_most(const std::string& scenario, const std::string& quantity, double bound,
               double measured, const std::string& unit, const std::string& note = "");
Result at_least(const std::string& scenario, const std::string& quantity, double bound,
                double measured, const std::string& unit, const std::string& note = "");

/// The flange Jacobian (6 x n, base frame) at the rig's current configuration.
Eigen::MatrixXd jacobian_now(Rig& rig);

/// A line for something `robot` cannot do, with the reason.
Result not_applicable(const std::string& scenario, const std::string& quantity,
                      const std::string& reason);

/// The task directions (x, y, z, rotation about x, y, z; base frame) that the chain can move its
/// flange in at the rig's current configuration: those in the range of its Jacobian.
struct TaskDirections {
  std::array<bool, 6> controlled{};
  int dimension = 0;   ///< how many of the six; the rank of the Jacobian may exceed it (coupled)
  int redundancy = 0;  ///< joints minus the Jacobian's rank
  /// "x, z, rotation about y"
  std::string describe() const;
  /// The first controlled of `preferred` (indices 0..5), or -1.
  int first_of(std::initializer_list<int> preferred) const;
};
TaskDirections task_directions(Rig& rig);

/// The scenario's parameters that differ from the robot's configuration, for Outcome::overrides.
std::vector<std::string> overrides(const RobotSetup& robot, const Parameters& used);

Eigen::Vector3d rotation_between(const Pose& from, const Pose& to);

/// A picture of `rig` now (Rig::moment()), with `details` added to its caption.
void notify(const MomentCallback& moment, const std::string& label, Rig& rig,
            const std::vector<std::string>& details = {});

/// printf into a std::string, for captions.
std::string format(const char* format, ...) __attribute__((format(printf, 1, 2)));

/// The largest force and torque at the flange that the joints' Coulomb friction can hold at q:
/// a spring pulling with less may leave the arm standing short of its rest position.
struct FrictionBand {
  double force = 0.0;                                     ///< [N]
  double torque = 0.0;                                    ///< [Nm]
  Eigen::Vector3d force_along = Eigen::Vector3d::Zero();  ///< [N] largest |force| per base axis
};
FrictionBand friction_band(Rig& rig);

// The scenarios, in scenarios.cpp and scenarios_sweeps.cpp.
Outcome hold(const RobotSetup& robot, const MomentCallback& moment);
Outcome compliance(const RobotSetup& robot, const MomentCallback& moment);
Outcome reference_step(const RobotSetup& robot, const MomentCallback& moment);
Outcome wrench_on_table(const RobotSetup& robot, const MomentCallback& moment);
Outcome nullspace(const RobotSetup& robot, const MomentCallback& moment);
Outcome teaching(const RobotSetup& robot, const MomentCallback& moment);
Outcome trajectory(const RobotSetup& robot, const MomentCallback& moment);
Outcome stability_grid(const RobotSetup& robot, const MomentCallback& moment);
Outcome convergence(const RobotSetup& robot, const MomentCallback& moment);
Outcome two_arms(const RobotSetup& robot, const MomentCallback& moment);

}  // namespace cartesian_impedance::scenarios::detail
