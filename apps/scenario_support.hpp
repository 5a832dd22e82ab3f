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

/// What the arm can do at the rig's current configuration, from its URDF (efforts, position
/// limits) and the parameters in force (limits.joint_torque): the scenarios size their pushes,
/// steps, table and trajectory by it, so that they fit an arm nobody tuned them for.
/// Sets the task stiffness to `translation` [N/m] and `rotation` [Nm/rad] and the nullspace
/// stiffness to `nullspace` [Nm/rad], each lowered to its limits.* maximum where that is lower.
void set_stiffness_within_limits(Parameters& parameters, double translation, double rotation,
                                 double nullspace);

struct Capacity {
  double reach = 0.0;  ///< distance from the base origin to the flange [m]
  /// Per joint: what is left of min(URDF effort, limits.joint_torque) once g(q) is held [Nm]. The
  /// simulated firmware holds gravity apart, but a real arm's limit covers both.
  JointVector torque_left;
  JointVector q;             ///< where it was computed [rad]
  Eigen::MatrixXd jacobian;  ///< 6 x n at q, base frame
  JointVector lower, upper;  ///< position limits [rad]
  /// Largest force [N] along `direction` (base frame, normalised here) the joints can hold at the
  /// flange: J^T (F d) must stay within torque_left, so F = min_i torque_left_i / |(J^T d)_i|.
  double force_along(const Eigen::Vector3d& direction) const;
  /// The same for a torque about `axis` [Nm].
  double torque_about(const Eigen::Vector3d& axis) const;
  /// The largest of 1, 1/2, ... 1/8 of the flange motion `twist` [m; rad, base frame] whose joint
  /// motion to first order, J^+ twist, keeps every joint `margin` [rad] inside its limits; 0 if
  /// none does.
  double fraction_within_limits(const Vector6d& twist, double margin) const;
};
Capacity capacity(Rig& rig);

/// Of what the joints can hold, the share a scenario's largest load may take: the rest is left
/// for the arm's own acceleration, the damping, and the law's margin to its torque limits.
constexpr double kLoadShare = 0.3;

/// The load [N or Nm] a scenario applies: `tuned` (the value the shipped robots were tuned with),
/// or less where it would exceed kLoadShare of `capacity` or carry a spring of `stiffness` farther
/// than `travel` (beyond a few cm an arm is no longer linear about its start).
double fitted_load(double tuned, double capacity, double stiffness, double travel);

/// "20 N is more than 30 % of the 45 N its joints can hold along x at the start": why a load was
/// reduced, for the result's note; "" if it was not.
std::string load_note(double tuned, double used, const char* unit);

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
// In scenarios_energy_tank.cpp.
Outcome energy_tank(const RobotSetup& robot, const MomentCallback& moment);

}  // namespace cartesian_impedance::scenarios::detail
