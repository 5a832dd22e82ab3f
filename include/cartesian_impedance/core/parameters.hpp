#pragma once
/// @file
/// Every configurable quantity of the controller, declared once. The plain structs hold the
/// values; `parameter_table()` describes each field (name, unit, valid range, description) and is
/// what validation, the YAML loader, the bindings and the README table are built from.

#include <bitset>
#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance {

/// The torque bound of a joint whose limit nobody gave: not in the parameters, not in the URDF
/// [Nm or N].
inline constexpr double kDefaultJointTorque = 100.0;

/// True for the per-joint parameters that may be left empty to mean "from the robot's URDF"
/// (limits.joint_torque).
bool may_come_from_the_robot(std::string_view name);

/// Closed interval [min, max] used for saturation limits and plausibility bounds.
struct Range {
  double min = 0.0;
  double max = 0.0;
};

/// First-order filter of a commanded quantity: after `time` seconds, `fraction` of a step has been
/// applied, whatever the control rate. `time = 0` switches the filter off (steps apply at once).
struct FilterSettings {
  double time = 0.2;       ///< [s]
  double fraction = 0.95;  ///< [-] in (0, 1]
};

struct StiffnessParameters {
  Eigen::Vector3d translation = Eigen::Vector3d::Constant(500.0);  ///< [N/m]
  Eigen::Vector3d rotation = Eigen::Vector3d::Constant(50.0);      ///< [Nm/rad]
  Frame frame = Frame::base;
};

/// Damping ratio zeta per axis: 1 is critical damping of the end effector's own mass-spring
/// system (d = 2 zeta sqrt(m k) per mode, with the task-space inertia) unless
/// dynamics.inertia_shaped_damping is off, which gives the published controller's unit-mass
/// "damping factor" D = 2 zeta sqrt(K).
struct DampingRatioParameters {
  Eigen::Vector3d translation = Eigen::Vector3d::Ones();  ///< [-]
  Eigen::Vector3d rotation = Eigen::Vector3d::Ones();     ///< [-]
};

struct NullspaceParameters {
  /// Joint stiffness [Nm/rad]: one value for every joint, or one per joint.
  JointVector stiffness = JointVector::Constant(1, 10.0);
  double damping_ratio = 1.0;  ///< [-], D_ns = 2 zeta sqrt(K_ns)
  /// lambda of the damped pseudo-inverse in N = I - J^T (J J^T + lambda^2 I)^-1 J; 0 is exact.
  double pseudo_inverse_damping = 0.01;
};

/// Damping that stays when the stiffness is low or zero (teaching), so a soft arm does not coast.
/// The Cartesian damping's diagonal and the nullspace damping never fall below these.
struct MinimumDampingParameters {
  double translation = 30.0;  ///< [N s/m]
  double rotation = 1.0;      ///< [Nm s/rad]
  double nullspace = 0.5;     ///< [Nm s/rad] per joint
};

/// Options that need a dynamics model; the control loop provides M(q) and g(q) for them.
struct DynamicsParameters {
  /// Add g(q) to the command, for robots that do not compensate gravity themselves.
  bool gravity_compensation = false;
  /// Damping ratios relative to the task-space inertia Lambda (d = 2 zeta sqrt(m k) per mode,
  /// so zeta = 1 is critical damping). Off: the published controller's D = 2 zeta sqrt(K),
  /// which takes every mass as 1 kg (1 kg m^2) and overshoots on a real arm.
  bool inertia_shaped_damping = true;
  /// Use the dynamically consistent projector N = I - J^T Lambda J M^-1.
  bool dynamically_consistent_nullspace = false;
  /// Reflected rotor inertia per joint [kg m^2 or kg], added to the diagonal of M(q): a URDF
  /// does not carry it, but on a geared arm it is a large part of what the wrist joints feel.
  /// One value for every joint, or one per joint.
  JointVector armature = JointVector::Zero(1);
};

/// Nullspace torques that push joints away from their position limits.
struct JointLimitAvoidanceParameters {
  double margin = 0.1;      ///< [rad or m] distance from a limit where the push starts
  double stiffness = 20.0;  ///< [Nm/rad] spring pushing out of the margin; 0 switches it off
};

/// What a measurement and the cycle's time step may be. Outside these the input is not
/// believed: the cycle fails closed (status and fault say which input; the torque ramps toward
/// zero, or gravity, within the rate limit) and recovers with the next plausible input.
struct PlausibilityParameters {
  Range dt{1e-5, 0.02};  ///< [s] time step of a cycle
  /// Largest believable joint speed [rad/s or m/s], one value or one per joint.
  JointVector joint_velocity = JointVector::Constant(1, 10.0);
  /// How far a measured position may lie outside the URDF's limits [rad or m].
  double joint_position_margin = 0.2;
};

/// Execution of joint trajectories.
struct TrajectoryParameters {
  double goal_tolerance = 0.01;      ///< [rad or m] per joint, to report a trajectory finished
  double goal_time_tolerance = 1.0;  ///< [s] after the end before an unreached goal aborts
};

struct WrenchParameters {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   ///< [N]
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();  ///< [Nm]
  Frame frame = Frame::base;
};

struct FilterParameters {
  FilterSettings pose;       ///< reference pose (position linearly, orientation by slerp)
  FilterSettings stiffness;  ///< Cartesian stiffness and damping ratio
  FilterSettings nullspace;  ///< nullspace target, stiffness and damping ratio
  FilterSettings wrench;     ///< commanded wrench
};

struct CartesianRanges {
  Range translation;
  Range rotation;
};

struct WrenchLimits {
  double force = 0.0;   ///< [N] largest norm of the commanded force
  double torque = 0.0;  ///< [Nm] largest norm of the commanded torque
};

struct PoseErrorLimits {
  double translation = 0.0;  ///< [m] largest norm of the translation error
  double rotation = 0.0;     ///< [rad] largest norm of the rotation error
};

struct LimitParameters {
  CartesianRanges stiffness{{0.0, 5000.0}, {0.0, 500.0}};  ///< [N/m], [Nm/rad]
  Range damping_ratio{0.0, 10.0};                          ///< [-]
  Range nullspace_stiffness{0.0, 500.0};                   ///< [Nm/rad]
  WrenchLimits wrench{100.0, 20.0};
  PoseErrorLimits pose_error{0.1, 0.5};
  /// Absolute commanded torque per joint [Nm]: one value for every joint, or one per joint, or
  /// none (empty, the default): the URDF's efforts, which the control loop fills in (see
  /// model/robot_limits.hpp; a value above them is refused); kDefaultJointTorque per joint where
  /// there is no URDF or it gives no effort.
  JointVector joint_torque = JointVector();
  /// Rate of change of the commanded torque per joint [Nm/s]: one value, or one per joint.
  JointVector joint_torque_rate = JointVector::Constant(1, 1000.0);
};

/// The speed of the end effector the commands may cause (0 switches a cap off). The reference
/// moves toward a commanded pose no faster than this, the spring and the commanded wrench stop
/// accelerating the end effector as its speed reaches the cap, and beyond it the damping is
/// doubled on the excess: a push from outside is braked, not fought with stiffness.
struct MaxSpeedParameters {
  double translation = 0.0;  ///< [m/s] speed of the end effector's origin
  double rotation = 0.0;     ///< [rad/s] angular speed of the end effector
};

/// The force and torque the controller presses with at the end effector (0 switches a cap off):
/// the norm of spring + commanded wrench is scaled down to these, keeping its direction.
struct MaxForceParameters {
  double force = 0.0;   ///< [N]
  double torque = 0.0;  ///< [Nm]
};

/// A box in the base frame the end effector is kept in: references outside it are clipped into
/// it, and outside it a wall spring with damping pushes the end effector's origin back (also
/// while teaching). A wall stiffness of 0 switches the walls off (references are still clipped).
struct WorkspaceParameters {
  Eigen::Vector3d min = Eigen::Vector3d::Constant(-10.0);  ///< [m] lower corner, base frame
  Eigen::Vector3d max = Eigen::Vector3d::Constant(10.0);   ///< [m] upper corner, base frame
  double stiffness = 0.0;                                  ///< [N/m] wall spring
  double damping = 100.0;  ///< [N s/m] wall damper, acting only on motion out of the box
};

/// The energy tank that keeps the controller passive while its stiffness changes: raising the
/// stiffness while the pose error is e stores 1/2 e^T dK e in the spring, which is drawn from
/// the tank; the tank is filled by what the Cartesian damping dissipates, up to its capacity;
/// when it cannot pay, the stiffness change waits (it is applied as far as the energy allows).
struct EnergyTankParameters {
  bool enabled = true;
  double capacity = 0.005;  ///< [J] the most the tank holds
  double initial = 0.005;   ///< [J] its level at start()
};

/// The passivity observer on the controller's port to the arm: the energy the torque sent puts
/// into the arm (each torque paired with the joint velocity measured while it acted, `delay`
/// later) beyond what the same controller without the delay would have, less what its damper
/// takes out, over a window of CartesianImpedanceController::kPassivityWindow. A passive
/// controller never generates energy; behind a delay its springs push with where the arm was and
/// do. Past `threshold` the passivity controller halves the stiffness of the springs that
/// generated it (translation, rotation, nullspace), keeping the others.
struct PassivityParameters {
  double threshold = 0.2;  ///< [J] generated energy that halves; 0: observe only
  double delay = 0.002;    ///< [s] from the measurement to its torque acting on the arm
};

/// What the controller does when the collision monitor finds a contact nobody commanded
/// (collision.reaction). Every reaction but `report` latches until a Resume command: the
/// reference pose and nullspace targets sent meanwhile are not followed, a running trajectory is
/// aborted, and the commanded wrench is dropped.
enum class CollisionReaction {
  report,  ///< reported in the state (and by the nodes); the motion goes on
  stop,    ///< the reference holds where the arm was: the law's damping brakes it, its spring holds
  reflex,  ///< the Cartesian and nullspace stiffness drop to zero: the arm complies, damped
  retract  ///< the reference moves collision.retract_distance away from the contact, and holds
};

/// The collision threshold's margin over the velocity noise the observer lets through, in its
/// standard deviations (CollisionParameters): the residual of free motion on the realistic
/// plant peaks near 3 of them (measured).
inline constexpr double kCollisionNoiseSigmas = 4.0;

/// "report", "stop", "reflex", "retract".
std::string_view reaction_name(CollisionReaction reaction);

/// The collision monitor: a generalized momentum observer (De Luca; Haddadin et al. 2017)
/// estimates the external joint torque r from what the model says the arm should do with the
/// torque it was sent, r = K_O (M dq - integral(tau - g + C^T dq + r) dt): a first-order filter
/// of the torque that something outside presses on the joints, with time constant 1/K_O. A
/// joint whose |r| leaves what is expected (the commanded wrench's reaction, a declared contact)
/// by more than its threshold is a collision; the last such joint names the link. The threshold
/// of joint i is `threshold` + `threshold_fraction` |tau_i| (the model's error grows with the
/// torque its drive applies, filtered like r; with `measured_torque`, the measured torque,
/// gravity's part included) + kCollisionNoiseSigmas K_O M_ii
/// `velocity_noise` (r carries the noise of the measured velocity through M dq, as much as
/// the observer's gain lets through).
struct CollisionParameters {
  bool detection = true;
  CollisionReaction reaction = CollisionReaction::report;
  double observer_gain = 100.0;  ///< [1/s] K_O
  /// [Nm or N] per joint: one value for every joint, or one per joint.
  JointVector threshold = JointVector::Constant(1, 5.0);
  double threshold_fraction = 0.3;  ///< [-] of the (filtered) torque each drive applies
  double velocity_noise = 0.005;    ///< [rad/s or m/s] standard deviation of a measured dq
  /// A contact the end effector is expected to make (a tool on a surface): the force and torque
  /// it may meet there without a collision [N; Nm].
  double contact_force = 0.0;
  double contact_torque = 0.0;
  double retract_distance = 0.05;  ///< [m] for CollisionReaction::retract
  /// The observer takes the joint torques the robot measures (RobotState::measured_torque: link
  /// side, gravity included, as Franka's tau_J) less the model's g(q), instead of the torque
  /// sent less tau_gravity: the drive's delay, noise, friction and rotor inertia then stay out
  /// of the estimate. Every cycle must bring the measurement (else it fails closed, naming it).
  bool measured_torque = false;
};

/// The body region a contact with a person may reach, for power and force limiting after
/// ISO/TS 15066 (safety.pfl.body_region): `none` (off), or one of the standard's regions.
enum class BodyRegion {
  none,
  skull,  ///< skull and forehead
  face,
  neck,
  back,  ///< back and shoulders
  chest,
  abdomen,
  pelvis,
  upper_arm,  ///< upper arms and elbows
  forearm,    ///< lower arms and wrists
  hand,       ///< hands and fingers
  thigh,      ///< thighs and knees
  lower_leg
};

/// ISO/TS 15066:2016's figures for one body region (Annex A, Tables A.2 and A.3): the largest
/// quasi-static contact force [N], the largest transient one (twice the quasi-static, except on
/// the head, where a transient contact is not permitted and the quasi-static limit stands), the
/// region's effective spring constant [N/m] and its effective mass [kg].
struct BodyRegionLimits {
  double quasi_static_force = 0.0;
  double transient_force = 0.0;
  double spring_constant = 0.0;
  double mass = 0.0;
};

/// The figures of `region` (all zero for BodyRegion::none).
BodyRegionLimits body_region_limits(BodyRegion region) noexcept;
/// "none", "skull", "face", ...
std::string_view body_region_name(BodyRegion region);

/// Power and force limiting (ISO/TS 15066): with a body region set, the force cap in force is at
/// most its quasi-static limit, and the translational speed cap at most the speed whose impact
/// stays within its transient limit, v = F_transient / sqrt(k mu), 1/mu = 1/m_H + 1/m_R, m_R the
/// arm's effective mass at the end effector along its motion (1 / u^T J M^-1 J^T u, recomputed
/// every cycle). The tighter of these and safety.max_speed / safety.max_force acts.
struct PflParameters {
  BodyRegion body_region = BodyRegion::none;
};

/// The safety layer: caps on what any valid command can make the arm do.
struct SafetyParameters {
  MaxSpeedParameters max_speed;
  MaxForceParameters max_force;
  WorkspaceParameters workspace;
  EnergyTankParameters energy_tank;
  PassivityParameters passivity;
  PflParameters pfl;
};

/// A load carried at the end effector whose gravity the controller compensates (J^T of the wrench
/// that holds it up; the base frame's -z is taken as down) and whose inertia enters the task-space
/// inertia of the damping and the dynamically consistent projector. Changes are filtered with
/// filter.wrench.
struct PayloadParameters {
  double mass = 0.0;                                         ///< [kg]
  Eigen::Vector3d center_of_mass = Eigen::Vector3d::Zero();  ///< [m] end-effector frame
};

/// The complete configuration. Defaults are the values of a default-constructed object.
struct Parameters {
  /// Its name as a command (command.hpp), which replaces the whole configuration.
  static constexpr const char* kName = "parameters";
  StiffnessParameters stiffness;
  DampingRatioParameters damping_ratio;
  MinimumDampingParameters minimum_damping;
  NullspaceParameters nullspace;
  WrenchParameters wrench;
  FilterParameters filter;
  LimitParameters limits;
  DynamicsParameters dynamics;
  JointLimitAvoidanceParameters joint_limit_avoidance;
  TrajectoryParameters trajectory;
  PlausibilityParameters plausibility;
  SafetyParameters safety;
  PayloadParameters payload;
  CollisionParameters collision;
};

/// Which rows of parameter_table() a ParameterUpdate names: bit i is row i (parameter_index()).
inline constexpr std::size_t kMaxParameterRows = 128;
using ParameterNames = std::bitset<kMaxParameterRows>;

/// A partial update, as a command: it sets the rows it names and keeps every other parameter as
/// it is in force when the update is applied, so that two senders that each change a few
/// parameters never undo each other's changes, and a stiffness sent on a topic survives an update
/// of filter.pose.time. The commanded stiffness, damping ratio, nullspace stiffness and damping
/// ratio and wrench are re-commanded from the parameters only where the update names one of their
/// rows. `values` is a whole valid set (what decode_parameter_update() and of() make: the
/// parameters in force with the update applied); only its named rows are read when it is applied,
/// and the set it is applied to must then still satisfy consistency_fault() (else it is refused).
struct ParameterUpdate {
  static constexpr const char* kName = "parameter_update";
  Parameters values;
  ParameterNames names;

  /// The update of the rows called `names` (dotted, as in the table) to their values in `values`.
  /// @throws Error for a name that is no row (a group names every row under it).
  static ParameterUpdate of(const Parameters& values,
                            std::initializer_list<std::string_view> names);
  /// The names of the rows it sets, in table order.
  std::vector<std::string_view> row_names() const;
};

/// Pointer to the storage of one parameter inside a Parameters object.
using ParameterField = std::variant<double*, Eigen::Vector3d*, JointVector*, Frame*, bool*,
                                    CollisionReaction*, BodyRegion*>;

/// The fields that take one of a few names (a frame, collision.reaction): the names, in order;
/// empty for every other field.
std::vector<std::string_view> choice_names(const ParameterField& field);
/// The name of a choice field's value; "" for every other field.
std::string_view choice_name(const ParameterField& field);
/// Sets a choice field to the value called `name`.
/// @throws Error naming `element`, the name and the valid names, if it is none of them.
void set_choice(const ParameterField& field, std::string_view element, std::string_view name);

/// Description of one parameter: the single definition everything else is served from.
struct ParameterInfo {
  std::string_view name;         ///< dotted path, as in YAML: "stiffness.translation"
  std::string_view unit;         ///< SI unit, "-" if dimensionless, "" for frames and switches
  double min;                    ///< smallest valid value of each element
  double max;                    ///< largest valid value of each element
  bool min_exclusive;            ///< true if `min` itself is not valid
  std::string_view description;  ///< one line for docs and help texts
  ParameterField (*field)(Parameters&);

  /// The field inside `parameters` this row describes.
  ParameterField in(Parameters& parameters) const { return field(parameters); }
  /// "[0, inf)", "(0, 1]", ...
  std::string range_text() const;
  /// Throws Error naming `element_name` if `value` is not finite or outside the range (its fault:
  /// the element, the value and the bound it broke).
  void check(std::string_view element_name, double value) const;
};

/// Every parameter, in documentation order.
const std::vector<ParameterInfo>& parameter_table();

/// The row called `name`; throws Error naming the key if there is none.
const ParameterInfo& parameter_info(std::string_view name);

/// The row called `name` (a dotted path); nullptr if there is none.
const ParameterInfo* find_parameter(std::string_view name);

/// How many levels deep the table nests its names ("limits.stiffness.translation.min": 4).
std::size_t parameter_table_depth();

/// True if `path` is a group of parameters: "limits", "limits.stiffness", not a row itself.
bool is_parameter_group(std::string_view path);

/// Throws Error (naming field, value and range) unless every value is finite and in range, every
/// per-joint field has 1 or `num_joints` entries (any count up to kMaxJoints if num_joints is 0),
/// and the rules that tie parameters together hold (consistency_fault()).
void validate(const Parameters& parameters, int num_joints = 0);

/// The first rule tying parameters together that `parameters` breaks, or no fault: every limit's
/// min <= max, the workspace box's min <= max, the tank's initial level <= its capacity, and a
/// declared payload that the force caps can hold whether or not it is carried (its weight
/// payload.mass g at most safety.max_force.force, its moment payload.mass g |center_of_mass| at
/// most safety.max_force.torque, where those caps are on). noexcept and allocation-free (the
/// fault's texts are static), so the control cycle checks an update merged into the parameters in
/// force with it; validate() raises it.
Fault consistency_fault(const Parameters& parameters) noexcept;

/// The position of `row` in parameter_table().
std::size_t parameter_index(const ParameterInfo& row);

/// Copies the rows in `names` from `from` into `to`. noexcept and allocation-free (joint-sized
/// fields have a fixed capacity), for the control cycle.
void copy_parameters(const Parameters& from, Parameters& to, const ParameterNames& names) noexcept;

/// The rows whose values differ between `a` and `b` (exactly: a per-joint field of another length
/// differs). noexcept and allocation-free.
ParameterNames changed_parameters(const Parameters& a, const Parameters& b) noexcept;

/// The safety settings: the rows under safety.*, limits.*, plausibility.*, payload.* and
/// collision.*, which a
/// running ControlLoop refuses to change unless its owner allowed it before start
/// (ControlLoop::allow_runtime_safety_changes()).
const ParameterNames& safety_settings();
/// True if `name` (a row or a group) is a safety setting or a group of them.
bool is_safety_setting(std::string_view name);

/// Text of a parameter's value: "0.2", "[500, 500, 500]", "base".
std::string value_text(const Parameters& parameters, const ParameterInfo& info);

/// "base" / "end_effector".
std::string_view frame_name(Frame frame);
/// Inverse of frame_name(); throws Error naming `field` for anything else.
Frame frame_from_name(std::string_view field, std::string_view name);

/// The parameter table as Markdown (name, unit, default, range, description), as in the README.
std::string parameter_table_markdown();

/// Expands a per-joint field (1 or n entries) to n entries; an empty one (a value left to the
/// robot, see may_come_from_the_robot()) to `otherwise`.
JointVector per_joint(const JointVector& values, int num_joints, double otherwise);
/// Expands a per-joint field (1 or n entries) to n entries.
JointVector per_joint(const JointVector& values, int num_joints);

}  // namespace cartesian_impedance
