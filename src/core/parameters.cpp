#include "cartesian_impedance/core/parameters.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <type_traits>

#include "cartesian_impedance/core/checks.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameter_tree.hpp"

namespace cartesian_impedance {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

template <typename T>
ParameterField field_of(T* pointer) {
  return ParameterField(pointer);
}

// Largest values that still mean something for an arm. Beyond them a value is a typo or an
// attack, and some (a filter time of 1e308, a torque limit of 5e-324) would switch the controller
// off without a word, so every range is closed on both sides. Stiffness and force bounds are ten
// to a hundred times what torque-controlled arms use (Panda: 3000 N/m, 300 Nm/rad), and keep
// every product in the law far from overflow.
constexpr double kMaxTranslationalStiffness = 1e5;  // [N/m]
constexpr double kMaxRotationalStiffness = 1e4;     // [Nm/rad]
constexpr double kMaxJointStiffness = 1e4;          // [Nm/rad]
constexpr double kMaxDampingRatio = 10.0;           // [-]
constexpr double kMaxForce = 1e4;                   // [N]
constexpr double kMaxTorque = 1e3;                  // [Nm]
constexpr double kMaxJointTorque = 1e4;             // [Nm]
// A filter must take effect: a time constant time / -ln(1 - fraction) of at most 30 s / ln 2.
constexpr double kMaxFilterTime = 30.0;     // [s]
constexpr double kMinFilterFraction = 0.5;  // [-]

std::vector<ParameterInfo> make_table() {
  // Valid ranges here are what is physically meaningful; user limits (limits.*) then saturate
  // commands inside these ranges.
  return {
      {"stiffness.translation", "N/m", 0, kMaxTranslationalStiffness, false,
       "Cartesian translational stiffness along x, y, z of the stiffness frame",
       [](Parameters& p) { return field_of(&p.stiffness.translation); }},
      {"stiffness.rotation", "Nm/rad", 0, kMaxRotationalStiffness, false,
       "Cartesian rotational stiffness about x, y, z of the stiffness frame",
       [](Parameters& p) { return field_of(&p.stiffness.rotation); }},
      {"stiffness.frame", "", 0, 0, false,
       "frame the stiffness is expressed in: base or end_effector",
       [](Parameters& p) { return field_of(&p.stiffness.frame); }},
      {"damping_ratio.translation", "-", 0, kMaxDampingRatio, false,
       "damping ratio zeta per translational axis; 1 is critical damping (see "
       "dynamics.inertia_shaped_damping)",
       [](Parameters& p) { return field_of(&p.damping_ratio.translation); }},
      {"damping_ratio.rotation", "-", 0, kMaxDampingRatio, false,
       "damping ratio zeta per rotational axis",
       [](Parameters& p) { return field_of(&p.damping_ratio.rotation); }},
      {"minimum_damping.translation", "N s/m", 0, 1000, false,
       "smallest translational damping, so that low or zero stiffness (teaching) stays damped: "
       "after a release the arm coasts about (task-space mass / this) x its speed",
       [](Parameters& p) { return field_of(&p.minimum_damping.translation); }},
      {"minimum_damping.rotation", "Nm s/rad", 0, 100, false, "smallest rotational damping",
       [](Parameters& p) { return field_of(&p.minimum_damping.rotation); }},
      {"minimum_damping.nullspace", "Nm s/rad", 0, 100, false,
       "smallest nullspace damping per joint",
       [](Parameters& p) { return field_of(&p.minimum_damping.nullspace); }},
      {"nullspace.stiffness", "Nm/rad", 0, kMaxJointStiffness, false,
       "joint stiffness toward the nullspace target (one value or one per joint)",
       [](Parameters& p) { return field_of(&p.nullspace.stiffness); }},
      {"nullspace.damping_ratio", "-", 0, kMaxDampingRatio, false,
       "nullspace damping ratio, D_ns = 2 zeta sqrt(K_ns)",
       [](Parameters& p) { return field_of(&p.nullspace.damping_ratio); }},
      // lambda enters as lambda^2 next to J J^T, whose entries are squared lever arms (m^2): at
      // 1 the projector no longer removes anything an arm's Jacobian can do.
      {"nullspace.pseudo_inverse_damping", "-", 0, 1, false,
       "lambda in N = I - J^T (J J^T + lambda^2 I)^-1 J; 0 gives the exact projector",
       [](Parameters& p) { return field_of(&p.nullspace.pseudo_inverse_damping); }},
      {"wrench.force", "N", -kMaxForce, kMaxForce, false,
       "commanded force on the environment, x, y, z",
       [](Parameters& p) { return field_of(&p.wrench.force); }},
      {"wrench.torque", "Nm", -kMaxTorque, kMaxTorque, false,
       "commanded torque on the environment, x, y, z",
       [](Parameters& p) { return field_of(&p.wrench.torque); }},
      {"wrench.frame", "", 0, 0, false, "frame the wrench is expressed in: base or end_effector",
       [](Parameters& p) { return field_of(&p.wrench.frame); }},
      {"filter.pose.time", "s", 0, kMaxFilterTime, false,
       "time after which filter.pose.fraction of a reference pose step is applied; 0 = no filter",
       [](Parameters& p) { return field_of(&p.filter.pose.time); }},
      {"filter.pose.fraction", "-", kMinFilterFraction, 1, false,
       "fraction of a step applied after the time",
       [](Parameters& p) { return field_of(&p.filter.pose.fraction); }},
      {"filter.stiffness.time", "s", 0, kMaxFilterTime, false,
       "filter time of stiffness and damping ratio changes; 0 = no filter",
       [](Parameters& p) { return field_of(&p.filter.stiffness.time); }},
      {"filter.stiffness.fraction", "-", kMinFilterFraction, 1, false,
       "fraction of a step applied after the time",
       [](Parameters& p) { return field_of(&p.filter.stiffness.fraction); }},
      {"filter.nullspace.time", "s", 0, kMaxFilterTime, false,
       "filter time of nullspace target, stiffness and damping changes; 0 = no filter",
       [](Parameters& p) { return field_of(&p.filter.nullspace.time); }},
      {"filter.nullspace.fraction", "-", kMinFilterFraction, 1, false,
       "fraction of a step applied after the time",
       [](Parameters& p) { return field_of(&p.filter.nullspace.fraction); }},
      {"filter.wrench.time", "s", 0, kMaxFilterTime, false,
       "filter time of commanded wrench changes; 0 = no filter",
       [](Parameters& p) { return field_of(&p.filter.wrench.time); }},
      {"filter.wrench.fraction", "-", kMinFilterFraction, 1, false,
       "fraction of a step applied after the time",
       [](Parameters& p) { return field_of(&p.filter.wrench.fraction); }},
      {"limits.stiffness.translation.min", "N/m", 0, kMaxTranslationalStiffness, false,
       "smallest translational stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.stiffness.translation.min); }},
      {"limits.stiffness.translation.max", "N/m", 0, kMaxTranslationalStiffness, false,
       "largest translational stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.stiffness.translation.max); }},
      {"limits.stiffness.rotation.min", "Nm/rad", 0, kMaxRotationalStiffness, false,
       "smallest rotational stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.stiffness.rotation.min); }},
      {"limits.stiffness.rotation.max", "Nm/rad", 0, kMaxRotationalStiffness, false,
       "largest rotational stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.stiffness.rotation.max); }},
      {"limits.damping_ratio.min", "-", 0, kMaxDampingRatio, false,
       "smallest damping ratio (Cartesian and nullspace) a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.damping_ratio.min); }},
      {"limits.damping_ratio.max", "-", 0, kMaxDampingRatio, false,
       "largest damping ratio (Cartesian and nullspace) a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.damping_ratio.max); }},
      {"limits.nullspace_stiffness.min", "Nm/rad", 0, kMaxJointStiffness, false,
       "smallest nullspace stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.nullspace_stiffness.min); }},
      {"limits.nullspace_stiffness.max", "Nm/rad", 0, kMaxJointStiffness, false,
       "largest nullspace stiffness a command is saturated to",
       [](Parameters& p) { return field_of(&p.limits.nullspace_stiffness.max); }},
      {"limits.wrench.force", "N", 0, kMaxForce, false,
       "largest norm of the commanded force; longer vectors are scaled down, keeping direction",
       [](Parameters& p) { return field_of(&p.limits.wrench.force); }},
      {"limits.wrench.torque", "Nm", 0, kMaxTorque, false,
       "largest norm of the commanded torque; longer vectors are scaled down, keeping direction",
       [](Parameters& p) { return field_of(&p.limits.wrench.torque); }},
      // Below a centimetre (a hundredth of a radian) the spring could not even hold the arm's
      // own friction: the clip would switch the spring off.
      {"limits.pose_error.translation", "m", 0.01, 10, false,
       "translation error norm is clipped to this, so a far reference cannot pull violently; a "
       "raise while the error is beyond it is paid from the energy tank",
       [](Parameters& p) { return field_of(&p.limits.pose_error.translation); }},
      {"limits.pose_error.rotation", "rad", 0.01, M_PI, false,
       "rotation error norm is clipped to this",
       [](Parameters& p) { return field_of(&p.limits.pose_error.rotation); }},
      {"limits.joint_torque", "Nm", 0.1, kMaxJointTorque, false,
       "absolute commanded torque per joint (one value or one per joint; [] = the URDF's efforts, "
       "100 where it gives none); at most the URDF's; lowered while running, the bound ramps "
       "down at the torque-rate limit",
       [](Parameters& p) { return field_of(&p.limits.joint_torque); }},
      {"limits.joint_torque_rate", "Nm/s", 1, 1e6, false,
       "rate of change of the commanded torque, per joint (one value or one per joint)",
       [](Parameters& p) { return field_of(&p.limits.joint_torque_rate); }},
      {"dynamics.gravity_compensation", "", 0, 0, false,
       "add g(q) to the command, for robots that do not compensate gravity themselves "
       "(needs the model: the control loop provides it)",
       [](Parameters& p) { return field_of(&p.dynamics.gravity_compensation); }},
      {"dynamics.inertia_shaped_damping", "", 0, 0, false,
       "damping ratios relative to the task-space inertia, d = 2 zeta sqrt(m k) per mode (needs "
       "the model); false: the published controller's unit-mass D = 2 zeta sqrt(K)",
       [](Parameters& p) { return field_of(&p.dynamics.inertia_shaped_damping); }},
      {"dynamics.dynamically_consistent_nullspace", "", 0, 0, false,
       "project the nullspace torque with N = I - J^T Lambda J M^-1 (needs the model)",
       [](Parameters& p) { return field_of(&p.dynamics.dynamically_consistent_nullspace); }},
      {"dynamics.armature", "kg m^2", 0, 100, false,
       "reflected rotor inertia per joint, added to the model's M(q) (a URDF has none); one "
       "value or one per joint",
       [](Parameters& p) { return field_of(&p.dynamics.armature); }},
      {"joint_limit_avoidance.margin", "rad", 0, 1, false,
       "distance from a joint's position limit where the nullspace push away from it starts; "
       "inside it the drive toward the limit is bounded (none at half the margin) and a wall "
       "pushes back from there (while teaching, a wall over the whole margin); 0: neither",
       [](Parameters& p) { return field_of(&p.joint_limit_avoidance.margin); }},
      {"joint_limit_avoidance.stiffness", "Nm/rad", 0, kMaxJointStiffness, false,
       "stiffness of that push (inside the margin, in the nullspace); 0 switches it off",
       [](Parameters& p) { return field_of(&p.joint_limit_avoidance.stiffness); }},
      {"trajectory.goal_tolerance", "rad", 1e-4, 1, false,
       "every joint within this of the last point reports a trajectory finished",
       [](Parameters& p) { return field_of(&p.trajectory.goal_tolerance); }},
      {"trajectory.goal_time_tolerance", "s", 0, 60, false,
       "time after the last point within which the goal must be reached, else aborted",
       [](Parameters& p) { return field_of(&p.trajectory.goal_time_tolerance); }},
      {"plausibility.dt.min", "s", 1e-6, 1, false,
       "shortest believable cycle time step; a shorter dt fails the cycle closed (invalid_dt)",
       [](Parameters& p) { return field_of(&p.plausibility.dt.min); }},
      {"plausibility.dt.max", "s", 1e-6, 1, false,
       "longest believable cycle time step; a longer dt fails the cycle closed (invalid_dt)",
       [](Parameters& p) { return field_of(&p.plausibility.dt.max); }},
      {"plausibility.joint_velocity", "rad/s", 0.1, 100, false,
       "fastest believable measured joint speed (one value or one per joint); faster fails the "
       "cycle closed (invalid_robot_state)",
       [](Parameters& p) { return field_of(&p.plausibility.joint_velocity); }},
      {"plausibility.joint_position_margin", "rad", 0, 10, false,
       "how far a measured position may lie outside the URDF's limits before the cycle fails "
       "closed (checked by the control loop, which knows the limits)",
       [](Parameters& p) { return field_of(&p.plausibility.joint_position_margin); }},
      {"safety.max_speed.translation", "m/s", 0, 10, false,
       "speed cap of the end effector: the reference (and a trajectory's velocity) moves no "
       "faster, nothing the controller adds (spring, wrench, walls, payload) pushes it past 95 % "
       "of it, the excess is braked out within 5 ms; 0 = off",
       [](Parameters& p) { return field_of(&p.safety.max_speed.translation); }},
      {"safety.max_speed.rotation", "rad/s", 0, 30, false,
       "angular speed cap of the end effector, as for translation; 0 = off",
       [](Parameters& p) { return field_of(&p.safety.max_speed.rotation); }},
      {"safety.max_force.force", "N", 0, kMaxForce, false,
       "largest norm of the force the controller presses with: spring, commanded wrench, walls, "
       "nullspace leak and a declared payload's compensation, carried or not; 0 = off",
       [](Parameters& p) { return field_of(&p.safety.max_force.force); }},
      {"safety.max_force.torque", "Nm", 0, kMaxTorque, false,
       "largest norm of the torque the controller presses with, as for the force; 0 = off",
       [](Parameters& p) { return field_of(&p.safety.max_force.torque); }},
      {"safety.workspace.min", "m", -100, 100, false,
       "lower corner of the box (base frame) references are clipped into and walls keep the end "
       "effector in",
       [](Parameters& p) { return field_of(&p.safety.workspace.min); }},
      {"safety.workspace.max", "m", -100, 100, false, "upper corner of the box (base frame)",
       [](Parameters& p) { return field_of(&p.safety.workspace.max); }},
      {"safety.workspace.stiffness", "N/m", 0, kMaxTranslationalStiffness, false,
       "stiffness of the walls outside the box, also while teaching, under the force and speed "
       "caps; a raise or a box moved past the flange is paid from the energy tank; 0 = no walls",
       [](Parameters& p) { return field_of(&p.safety.workspace.stiffness); }},
      {"safety.workspace.damping", "N s/m", 0, 1e4, false,
       "damping of the walls, on motion out of the box",
       [](Parameters& p) { return field_of(&p.safety.workspace.damping); }},
      {"safety.energy_tank.enabled", "", 0, 0, false,
       "energy tank: every change that stores energy (Cartesian and nullspace stiffness, "
       "pose-error clip, workspace box and walls) is paid from it, and the damping fills it; "
       "what it cannot pay waits, so no parameter schedule pumps up motion",
       [](Parameters& p) { return field_of(&p.safety.energy_tank.enabled); }},
      {"safety.energy_tank.capacity", "J", 0, 1e3, false,
       "most energy the tank holds: how far parameter changes may grow the motion's energy",
       [](Parameters& p) { return field_of(&p.safety.energy_tank.capacity); }},
      {"safety.energy_tank.initial", "J", 0, 1e3, false,
       "tank level at start (at most the capacity)",
       [](Parameters& p) { return field_of(&p.safety.energy_tank.initial); }},
      {"safety.passivity.threshold", "J", 0, 1e3, false,
       "energy the controller may generate on its port to the arm within 0.5 s (what a delay "
       "makes its springs put in) before the stiffness of the springs that generated it is "
       "halved; 0 = observe only (state.safety.generated_energy)",
       [](Parameters& p) { return field_of(&p.safety.passivity.threshold); }},
      {"safety.passivity.delay", "s", 0, 0.1, false,
       "time from a joint measurement to its torque acting on the arm (the measurement's age "
       "plus the drive's delay): the passivity observer pairs each torque with the velocity "
       "measured while it acted",
       [](Parameters& p) { return field_of(&p.safety.passivity.delay); }},
      {"safety.pfl.body_region", "", 0, 0, false,
       "power and force limiting after ISO/TS 15066: the body region a contact may reach (none, "
       "skull, face, neck, back, chest, abdomen, pelvis, upper_arm, forearm, hand, thigh, "
       "lower_leg); its quasi-static force limit caps the force, and the speed whose impact "
       "stays within its transient limit, by the arm's effective mass, caps the translation",
       [](Parameters& p) { return field_of(&p.safety.pfl.body_region); }},
      {"payload.mass", "kg", 0, 1e3, false,
       "mass carried at the end effector: its gravity is compensated and its inertia shapes the "
       "damping; filtered with filter.wrench; its weight must fit under safety.max_force.force",
       [](Parameters& p) { return field_of(&p.payload.mass); }},
      {"payload.center_of_mass", "m", -10, 10, false,
       "centre of mass of the payload in the end-effector frame",
       [](Parameters& p) { return field_of(&p.payload.center_of_mass); }},
      {"collision.detection", "", 0, 0, false,
       "collision monitor: a momentum observer estimates the external torque on each joint; one "
       "beyond what is expected by its threshold is a collision (state.collision), with the link "
       "it hit",
       [](Parameters& p) { return field_of(&p.collision.detection); }},
      {"collision.reaction", "", 0, 0, false,
       "what a collision does: report; stop (hold where the arm was, braked by the damping); "
       "reflex (Cartesian and nullspace stiffness to zero: the arm complies); retract (back off "
       "by collision.retract_distance); all but report latch until a resume command",
       [](Parameters& p) { return field_of(&p.collision.reaction); }},
      {"collision.observer_gain", "1/s", 0, 1000, true,
       "gain K_O of the momentum observer: its estimate follows the external torque with time "
       "constant 1/K_O (faster detection, more noise)",
       [](Parameters& p) { return field_of(&p.collision.observer_gain); }},
      {"collision.threshold", "Nm", 0, kMaxJointTorque, true,
       "external torque per joint beyond what is expected that is a collision; one value or one "
       "per joint",
       [](Parameters& p) { return field_of(&p.collision.threshold); }},
      {"collision.threshold_fraction", "-", 0, 10, false,
       "added to the threshold per unit of the torque the joint's drive applies (filtered like "
       "the estimate; with collision.measured_torque, per unit of the measured torque): the "
       "model's error grows with it",
       [](Parameters& p) { return field_of(&p.collision.threshold_fraction); }},
      {"collision.velocity_noise", "rad/s", 0, 1, false,
       "standard deviation of the measured joint velocities: the observer passes it on as "
       "K_O M_ii times it, and the threshold adds 4 times that",
       [](Parameters& p) { return field_of(&p.collision.velocity_noise); }},
      {"collision.contact_force", "N", 0, kMaxForce, false,
       "force the end effector may meet without a collision (a tool on a surface); the "
       "commanded wrench's reaction is expected besides",
       [](Parameters& p) { return field_of(&p.collision.contact_force); }},
      {"collision.contact_torque", "Nm", 0, kMaxTorque, false,
       "torque the end effector may meet without a collision",
       [](Parameters& p) { return field_of(&p.collision.contact_torque); }},
      {"collision.retract_distance", "m", 0, 1, false,
       "how far the retract reaction moves the end effector away from the contact",
       [](Parameters& p) { return field_of(&p.collision.retract_distance); }},
      {"collision.measured_torque", "", 0, 0, false,
       "the observer uses the joint torques the robot measures (link side, gravity included, as "
       "Franka's tau_J; the effort of joint_states) instead of the torque sent: the drive's "
       "delay, noise and friction leave the estimate; every cycle must bring them",
       [](Parameters& p) { return field_of(&p.collision.measured_torque); }},
  };
}

std::string element_name(std::string_view base, const char* suffix) {
  std::string name(base);
  name += suffix;
  return name;
}

std::string with_unit(double value, std::string_view unit) {
  std::string text = format_number(value);
  if (!unit.empty() && unit != "-") text += " " + std::string(unit);
  return text;
}

}  // namespace

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
    const std::string input(element), unit_text(unit);
    const bool above = value > max;
    throw Error(Fault{input.c_str(), -1, value,
                      !std::isfinite(value) ? "is not finite"
                      : above               ? "is above"
                                            : "is below",
                      above ? max : min, std::isfinite(value), unit_text.c_str()},
                message);
  }
}

const std::vector<ParameterInfo>& parameter_table() {
  static const std::vector<ParameterInfo> table = [] {
    std::vector<ParameterInfo> rows = make_table();
    if (rows.size() > kMaxParameterRows) throw Error("the parameter table outgrew ParameterNames");
    return rows;
  }();
  return table;
}

std::size_t parameter_table_depth() {
  static const std::size_t depth = [] {
    std::size_t deepest = 0;
    for (const ParameterInfo& info : parameter_table()) {
      deepest = std::max(deepest, 1 + static_cast<std::size_t>(
                                          std::count(info.name.begin(), info.name.end(), '.')));
    }
    return deepest;
  }();
  return depth;
}

const ParameterInfo* find_parameter(std::string_view name) {
  for (const ParameterInfo& info : parameter_table()) {
    if (info.name == name) return &info;
  }
  return nullptr;
}

bool is_parameter_group(std::string_view path) {
  for (const ParameterInfo& info : parameter_table()) {
    if (info.name.size() > path.size() && info.name[path.size()] == '.' &&
        info.name.substr(0, path.size()) == path) {
      return true;
    }
  }
  return false;
}

const ParameterInfo& parameter_info(std::string_view name) {
  if (const ParameterInfo* info = find_parameter(name)) return *info;
  throw unknown_parameter(name);
}

std::string_view frame_name(Frame frame) {
  return frame == Frame::base ? "base" : "end_effector";
}

Frame frame_from_name(std::string_view field, std::string_view name) {
  return decode_frame(ParameterValue::string(std::string(name)), field);
}

std::string_view reaction_name(CollisionReaction reaction) {
  switch (reaction) {
    case CollisionReaction::stop:
      return "stop";
    case CollisionReaction::reflex:
      return "reflex";
    case CollisionReaction::retract:
      return "retract";
    case CollisionReaction::report:
      break;
  }
  return "report";
}

namespace {

constexpr CollisionReaction kReactions[] = {CollisionReaction::report, CollisionReaction::stop,
                                            CollisionReaction::reflex, CollisionReaction::retract};

// ISO/TS 15066:2016, Annex A: Table A.2 (quasi-static force [N]; the transient limit is twice it,
// Table A.2 note c, but on the skull, forehead and face, where transient contact is not
// permitted) and Table A.3 (effective spring constant [N/mm] and effective mass [kg]). The neck's
// spring constant is the sides' (the front's, 10 N/mm, would allow a faster impact).
struct RegionRow {
  BodyRegion region;
  const char* name;
  double force, spring_n_per_mm, mass;
  bool head;
};
constexpr RegionRow kRegions[] = {
    {BodyRegion::none, "none", 0, 0, 0, false},
    {BodyRegion::skull, "skull", 130, 150, 4.4, true},
    {BodyRegion::face, "face", 65, 75, 4.4, true},
    {BodyRegion::neck, "neck", 150, 50, 1.2, false},
    {BodyRegion::back, "back", 210, 35, 40, false},
    {BodyRegion::chest, "chest", 140, 25, 40, false},
    {BodyRegion::abdomen, "abdomen", 110, 10, 40, false},
    {BodyRegion::pelvis, "pelvis", 180, 25, 40, false},
    {BodyRegion::upper_arm, "upper_arm", 150, 30, 3, false},
    {BodyRegion::forearm, "forearm", 160, 40, 2, false},
    {BodyRegion::hand, "hand", 140, 75, 0.6, false},
    {BodyRegion::thigh, "thigh", 220, 50, 75, false},
    {BodyRegion::lower_leg, "lower_leg", 130, 60, 75, false},
};

const RegionRow& region_row(BodyRegion region) noexcept {
  for (const RegionRow& row : kRegions) {
    if (row.region == region) return row;
  }
  return kRegions[0];
}

}  // namespace

BodyRegionLimits body_region_limits(BodyRegion region) noexcept {
  const RegionRow& row = region_row(region);
  return {row.force, row.head ? row.force : 2.0 * row.force, row.spring_n_per_mm * 1000.0,
          row.mass};
}

std::string_view body_region_name(BodyRegion region) {
  return region_row(region).name;
}

std::vector<std::string_view> choice_names(const ParameterField& field) {
  if (std::holds_alternative<Frame*>(field)) {
    return {frame_name(Frame::base), frame_name(Frame::end_effector)};
  }
  std::vector<std::string_view> names;
  if (std::holds_alternative<CollisionReaction*>(field)) {
    for (const CollisionReaction reaction : kReactions) names.push_back(reaction_name(reaction));
  }
  if (std::holds_alternative<BodyRegion*>(field)) {
    for (const RegionRow& row : kRegions) names.push_back(row.name);
  }
  return names;
}

std::string_view choice_name(const ParameterField& field) {
  if (const auto* frame = std::get_if<Frame*>(&field)) return frame_name(**frame);
  if (const auto* reaction = std::get_if<CollisionReaction*>(&field)) {
    return reaction_name(**reaction);
  }
  if (const auto* region = std::get_if<BodyRegion*>(&field)) return body_region_name(**region);
  return "";
}

void set_choice(const ParameterField& field, std::string_view element, std::string_view name) {
  const ParameterValue value = ParameterValue::string(std::string(name));
  if (const auto* frame = std::get_if<Frame*>(&field)) {
    **frame = decode_frame(value, element);
  } else if (const auto* reaction = std::get_if<CollisionReaction*>(&field)) {
    const std::string chosen =
        decode_name(value, element, "a collision reaction", choice_names(field));
    for (const CollisionReaction candidate : kReactions) {
      if (reaction_name(candidate) == chosen) **reaction = candidate;
    }
  } else if (const auto* region = std::get_if<BodyRegion*>(&field)) {
    const std::string chosen = decode_name(value, element, "a body region", choice_names(field));
    for (const RegionRow& row : kRegions) {
      if (row.name == chosen) **region = row.region;
    }
  } else {
    throw Error(std::string(element) + " takes no name");
  }
}

bool may_come_from_the_robot(std::string_view name) {
  return name == "limits.joint_torque";
}

JointVector per_joint(const JointVector& values, int num_joints, double otherwise) {
  if (values.size() == 0) return JointVector::Constant(num_joints, otherwise);
  return per_joint(values, num_joints);
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
      const bool size_ok = (values.size() == 0 && may_come_from_the_robot(info.name)) ||
                           (num_joints > 0 ? (values.size() == 1 || values.size() == num_joints)
                                           : (values.size() >= 1 && values.size() <= kMaxJoints));
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
  checks::raise(consistency_fault(parameters));
}

namespace {

// The fault of a range whose min lies above its max: its texts are the range's own, static.
struct RangeRule {
  const char* min_name;
  const char* reason;  // "is greater than <name>.max"
  const char* unit;
  const Range& (*range)(const Parameters&);
};

}  // namespace

Fault consistency_fault(const Parameters& parameters) noexcept {
  static const RangeRule kRanges[] = {
      {"limits.stiffness.translation.min", "is greater than limits.stiffness.translation.max",
       "N/m", [](const Parameters& p) -> const Range& { return p.limits.stiffness.translation; }},
      {"limits.stiffness.rotation.min", "is greater than limits.stiffness.rotation.max", "Nm/rad",
       [](const Parameters& p) -> const Range& { return p.limits.stiffness.rotation; }},
      {"limits.damping_ratio.min", "is greater than limits.damping_ratio.max", "",
       [](const Parameters& p) -> const Range& { return p.limits.damping_ratio; }},
      {"limits.nullspace_stiffness.min", "is greater than limits.nullspace_stiffness.max", "Nm/rad",
       [](const Parameters& p) -> const Range& { return p.limits.nullspace_stiffness; }},
      {"plausibility.dt.min", "is greater than plausibility.dt.max", "s",
       [](const Parameters& p) -> const Range& { return p.plausibility.dt; }},
  };
  for (const RangeRule& rule : kRanges) {
    const Range& range = rule.range(parameters);
    if (range.min > range.max) {
      return Fault{rule.min_name, -1, range.min, rule.reason, range.max, true, rule.unit};
    }
  }
  static const char* const kWorkspaceReasons[3] = {"is greater than safety.workspace.max.x",
                                                   "is greater than safety.workspace.max.y",
                                                   "is greater than safety.workspace.max.z"};
  const WorkspaceParameters& box = parameters.safety.workspace;
  for (int i = 0; i < 3; ++i) {
    if (box.min[i] > box.max[i]) {
      return Fault{
          "safety.workspace.min", i, box.min[i], kWorkspaceReasons[i], box.max[i], true, "m",
          Fault::Form::axis};
    }
  }
  const EnergyTankParameters& tank = parameters.safety.energy_tank;
  if (tank.initial > tank.capacity) {
    return Fault{"safety.energy_tank.initial",
                 -1,
                 tank.initial,
                 "is greater than safety.energy_tank.capacity",
                 tank.capacity,
                 true,
                 "J"};
  }
  // Whether the declared load is carried or not, the force the arm presses with differs by its
  // weight (the compensation holds a load that is there, and pushes up where there is none): the
  // force cap can bound both only if the weight alone fits under it.
  const PayloadParameters& payload = parameters.payload;
  const MaxForceParameters& cap = parameters.safety.max_force;
  constexpr double kStandardGravity = 9.81;  // CartesianImpedanceController::kGravity
  const double weight = payload.mass * kStandardGravity;
  if (cap.force > 0.0 && weight > cap.force) {
    return Fault{"payload.mass",
                 -1,
                 payload.mass,
                 "weighs more than the force cap holds, safety.max_force.force / g",
                 cap.force / kStandardGravity,
                 true,
                 "kg"};
  }
  const double lever = payload.center_of_mass.norm();
  if (cap.torque > 0.0 && weight * lever > cap.torque) {
    return Fault{"payload.center_of_mass",
                 -1,
                 lever,
                 "(its norm) holds the payload's weight out farther than the torque cap allows, "
                 "safety.max_force.torque / (payload.mass g)",
                 cap.torque / weight,
                 true,
                 "m"};
  }
  return Fault{};
}

ParameterUpdate ParameterUpdate::of(const Parameters& values,
                                    std::initializer_list<std::string_view> names) {
  ParameterUpdate update{values, {}};
  const std::vector<ParameterInfo>& table = parameter_table();
  for (const std::string_view name : names) {
    bool found = false;
    for (std::size_t i = 0; i < table.size(); ++i) {
      const std::string_view row = table[i].name;
      if (row == name || (row.size() > name.size() && row.substr(0, name.size()) == name &&
                          row[name.size()] == '.')) {
        update.names[i] = true;
        found = true;
      }
    }
    if (!found) throw unknown_parameter(name);
  }
  return update;
}

std::vector<std::string_view> ParameterUpdate::row_names() const {
  std::vector<std::string_view> rows;
  const std::vector<ParameterInfo>& table = parameter_table();
  for (std::size_t i = 0; i < table.size(); ++i) {
    if (names[i]) rows.push_back(table[i].name);
  }
  return rows;
}

std::size_t parameter_index(const ParameterInfo& row) {
  return static_cast<std::size_t>(&row - parameter_table().data());
}

namespace {

// Calls `each(a_field, b_field)` with the two fields of one row, of the same type.
template <typename Each>
void visit_row(const ParameterInfo& row, Parameters& a, Parameters& b, Each&& each) noexcept {
  const ParameterField field_a = row.field(a);
  const ParameterField field_b = row.field(b);
  std::visit(
      [&](auto* pointer_a) {
        using Pointer = decltype(pointer_a);
        each(*pointer_a, **std::get_if<Pointer>(&field_b));
      },
      field_a);
}

}  // namespace

void copy_parameters(const Parameters& from, Parameters& to, const ParameterNames& names) noexcept {
  const std::vector<ParameterInfo>& table = parameter_table();
  Parameters& source = const_cast<Parameters&>(from);  // read only
  for (std::size_t i = 0; i < table.size(); ++i) {
    if (!names[i]) continue;
    visit_row(table[i], to, source, [](auto& target, const auto& value) { target = value; });
  }
}

ParameterNames changed_parameters(const Parameters& a, const Parameters& b) noexcept {
  const std::vector<ParameterInfo>& table = parameter_table();
  Parameters& left = const_cast<Parameters&>(a);  // read only
  Parameters& right = const_cast<Parameters&>(b);
  ParameterNames changed;
  for (std::size_t i = 0; i < table.size(); ++i) {
    visit_row(table[i], left, right, [&](const auto& x, const auto& y) {
      using T = std::decay_t<decltype(x)>;
      if constexpr (std::is_same_v<T, JointVector>) {
        changed[i] = x.size() != y.size() || x != y;
      } else {
        changed[i] = !(x == y);
      }
    });
  }
  return changed;
}

bool is_safety_setting(std::string_view name) {
  for (const std::string_view group :
       {"safety", "limits", "plausibility", "payload", "collision"}) {
    if (name == group || (name.size() > group.size() && name.substr(0, group.size()) == group &&
                          name[group.size()] == '.')) {
      return true;
    }
  }
  return false;
}

const ParameterNames& safety_settings() {
  static const ParameterNames names = [] {
    ParameterNames set;
    const std::vector<ParameterInfo>& table = parameter_table();
    for (std::size_t i = 0; i < table.size(); ++i) set[i] = is_safety_setting(table[i].name);
    return set;
  }();
  return names;
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
  } else if (!choice_name(field).empty()) {
    text << choice_name(field);
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
    std::string choices;
    for (const std::string_view name : choice_names(field)) {
      choices += (choices.empty() ? "" : ", ") + std::string(name);
    }
    const bool is_switch = std::holds_alternative<bool*>(field);
    text << "| `" << info.name << "` | " << (info.unit.empty() ? "" : info.unit) << " | "
         << value_text(defaults, info) << " | "
         << (!choices.empty() ? choices
             : is_switch      ? std::string("true, false")
                              : info.range_text())
         << " | " << info.description << " |\n";
  }
  return text.str();
}

}  // namespace cartesian_impedance
