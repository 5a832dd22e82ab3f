#pragma once
// What the scenarios share: result lines, the Rig's helpers and the registry's entries. Internal
// to the scenarios library (the demo and the tests include scenarios.hpp).

#include <array>
#include <functional>
#include <initializer_list>
#include <limits>
#include <optional>
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

/// The largest value of `direction`.x over 4 s of the linear system the law makes of the arm
/// now, Lambda x'' + D x' + K x = 0 with Lambda^-1 = J (M + armature)^-1 J^T, D and K as the law
/// used them in the last cycle (base frame), started at rest from the error x0 = pose - target
/// [m; rad]. Zero for one mode alone at damping ratio 1; positive where Lambda couples the axes
/// (a step also turns the flange, and the turn then crosses its target although each mode is
/// critically damped).
double linear_overshoot(Rig& rig, const Vector6d& x0, const Vector6d& direction);

/// The wrench [N; Nm] at the flange, least-norm with J^T F = tau, of the controller's nullspace
/// torque now: zero where the nullspace is exact, what the damped pseudo-inverse of the
/// projector lets through otherwise. A static check's tolerance includes it: a frictionless arm
/// has no friction band to hide it in.
Vector6d nullspace_wrench(Rig& rig);

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

/// "the flange (tool0) has no collision geometry ..." if nothing of the flange's body can touch a
/// table (contact checks are then n/a, not FAIL); "" if it can.
std::string flange_without_geometry(Rig& rig, const RobotSetup& robot);

/// Whether a link of the chain other than the flange's body touches the environment now.
bool other_link_touches(Rig& rig);

/// Tables with their top at `top_z` [m], half sizes 15, 10, 7, 5 and 3 cm, centred under
/// `center_xy` and named "table": the candidates of first_table_only_the_flange_meets().
std::vector<sim::Box> tables_under(const Eigen::Vector2d& center_xy, double top_z);

/// The first of `candidates` that no link but the flange touches while the flange descends
/// `depth` [m] from `probe`'s state. What it must leave free is the arm's geometry along the
/// descent, not the controller's motion (a broken controller's flailing then cannot make a
/// scenario not apply): the joint motion to first order (J^+ dx), checked at five states in
/// MuJoCo (which finds contacts at a set state) whatever `robot`'s engine. Null if none fits.
const sim::Box* first_table_only_the_flange_meets(const RobotSetup& robot,
                                                  const Parameters& parameters, Rig& probe,
                                                  const std::vector<sim::Box>& candidates,
                                                  double depth);

/// The model at the simulation's true state (pose, Jacobian, M(q)), with the simulated rotors'
/// inertia added to M(q)'s diagonal.
Kinematics simulated_arm(Rig& rig);

/// What the plant's noise (RobotSetup::plant: torque_noise, velocity_noise) keeps a settled arm
/// moving at [rad/s or m/s], the largest over its joints of the standard deviation of the joint's
/// speed: 0 on the nominal plant. Each joint j is a mass m_j (M(q)_jj + the simulated armature)
/// damped by c_jj of C = J^T D J + D_ns (the law's damping in joint space, D_ns the nullspace
/// damping or its minimum), driven by white torque noise of sigma_j^2 = torque_noise^2 +
/// velocity_noise^2 sum_k C_jk^2 (the damping acts on the noisy readings) per step dt: a damped
/// mass under white force moves at sigma_j sqrt(dt / (2 m_j c_jj)).
double noise_speed(Rig& rig, const sim::PlantOptions& plant);

/// The energy the plant's noise puts into the arm per second [W], in expectation: each step a
/// joint's noise torque (sigma_j as in noise_speed()) is an impulse sigma_j dt, which adds
/// (sigma_j dt)^2 / (2 m_j) of kinetic energy whatever the joint's speed; summed over the joints,
/// per second. 0 on the nominal plant.
double noise_power(Rig& rig, const sim::PlantOptions& plant);

/// How many cycles of a second at rest the torque-rate limit acts on for the plant's noise alone:
/// the damping turns velocity noise (and the stiffness position noise) into a change of the
/// commanded torque each cycle, per joint j Gaussian with sigma_j = sqrt(2) sqrt(velocity_noise^2
/// sum_k C_jk^2 + position_noise^2 sum_k S_jk^2) (C = J^T D J + D_ns as in noise_speed(), S =
/// J^T K J), which passes the joint's rate limit r_j dt with probability erfc(r_j dt / (sqrt(2)
/// sigma_j)); summed over the joints and the cycles of a second. 0 on a plant without sensor
/// noise.
double noise_rate_limited_cycles(Rig& rig, const sim::PlantOptions& plant);

/// Steps `rig` one cycle at a time for `seconds`, calling `each` after every cycle with the
/// flange's speed over that cycle [m/s] (ground truth: the simulation's flange poses).
void run_measured(Rig& rig, double seconds, const std::function<void(double speed)>& each);

/// The largest mass [kg] a force along `direction` (base frame) at the flange can meet at the
/// rig's state, every other direction of the flange held (as a flat face stuck on a surface
/// holds it): d^T Lambda d, Lambda = (J M^-1 J^T)^+ the task-space inertia, M with the simulated
/// rotors' inertia. Holding fewer directions meets less mass.
double mass_along(Rig& rig, const Eigen::Vector3d& direction);

/// The joint positions [rad or m] that reach the flange pose `target` (base frame) from `q` by
/// a few Gauss-Newton steps (J^+ e), every joint `margin` [rad or m] inside its limits on the
/// way; none if they do not.
std::optional<JointVector> reach(const RobotModel& model, JointVector q, const Pose& target,
                                 double margin);

/// A move of the flange along one base axis that the arm makes with its orientation kept.
struct Move {
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();  ///< unit, along x, y or z
  double length = 0.0;                                  ///< [m]; 0: none found
  JointVector goal;                                     ///< the joints there [rad or m]
};
/// Sideways (y) if the arm can move its flange so, else along x or z, toward the base first;
/// `longest` [m], or half, a quarter or an eighth of it, whichever the arm reaches (reach())
/// first with every joint 0.1 rad inside its limits.
Move reachable_move(Rig& rig, double longest);

/// `moment` with the face of `box` (base frame) at coordinate `face` [m] across `axis` (0, 1, 2)
/// drawn as a red outline, and `requested` (if its position is finite) as a pale frame: a
/// reference requested outside the box. Empty if `moment` is.
MomentCallback showing_box_face(const MomentCallback& moment, const std::string& base_link,
                                const WorkspaceParameters& box, int axis, double face,
                                const Pose& requested);

// The scenarios, in scenarios.cpp, scenarios_sweeps.cpp and scenarios_safety.cpp.
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
// In scenarios_safety.cpp.
Outcome safety(const RobotSetup& robot, const MomentCallback& moment);
// In scenarios_collision.cpp.
Outcome collision(const RobotSetup& robot, const MomentCallback& moment);

}  // namespace cartesian_impedance::scenarios::detail
