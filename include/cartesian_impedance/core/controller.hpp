#pragma once
/// @file
/// The Cartesian impedance control law with nullspace joint impedance and a commanded wrench:
///
///   tau = J^T (-K e - D (J dq - v_ref)) + N tau_0 + J^T F [+ g(q)],
///   tau_0 = -K_ns (q - q_d) - D_ns (dq - dq_d),   N = I - J^T (J J^T + lambda^2 I)^-1 J,
///   D = L (2 Z^1/2 sqrt(L^-1 K L^-T) Z^1/2) L^T,  Lambda = L L^T = (J M^-1 J^T + lambda^2 I)^-1,
///
/// so that each mode of the end effector's mass-spring system has the damping ratio zeta (Z =
/// diag(zeta); dynamics.inertia_shaped_damping, the default). With it off, D = 2 Z^1/2 sqrt(K)
/// Z^1/2 (the published controller's damping factor, every mass 1). D never falls below
/// minimum_damping; N may be the dynamically consistent I - J^T Lambda J M^-1. Every commanded
/// quantity is low-pass filtered and saturated to user limits, the pose error is clipped, and the
/// torque is limited in magnitude and rate. math.hpp holds each formula on its own.
///
/// Setters validate and throw `Error` (a rejected command changes nothing); `update` is noexcept,
/// allocates nothing, takes no lock and does no I/O. One controller serves one robot; it is not
/// thread-safe (see the control loop for hand-off between threads).

#include <array>
#include <memory>
#include <optional>
#include <string>

#include "cartesian_impedance/core/command.hpp"
#include "cartesian_impedance/core/command_setters.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/math.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance {

/// Outcome of one control cycle. Every status but ok and not_started is a cycle that failed
/// closed: the torque ramps toward zero (toward g(q) with dynamics.gravity_compensation) within
/// the rate limit, ControllerState::fault names the input, and the next good cycle resumes.
enum class Status {
  ok,                   ///< torque computed from the law
  not_started,          ///< start() has not been called; torque is zero
  invalid_dt,           ///< dt not finite or outside plausibility.dt
  invalid_robot_state,  ///< q, dq, pose or Jacobian wrongly sized, not finite or implausible
  numerical_error,      ///< a term of the law could not be evaluated (the fault names it)
  missing_dynamics,     ///< an option needs robot.mass or robot.gravity, which were not given
  model_error,          ///< the robot model could not be evaluated at the measured q
  /// The arm moved implausibly (beyond plausibility.joint_velocity or its joint limits) in
  /// kHoldEpisodes separate episodes within kHoldWindow seconds: an oscillation that resuming the
  /// law would feed. The springs are off and only the minimum damping acts (plus g(q) with
  /// dynamics.gravity_compensation) until every joint has been slower than kRestSpeed for
  /// kRestTime; then the controller holds where the arm stopped (ActiveLimits::holding).
  motion_halted,
};

/// "ok", "not_started", ...
const char* to_string(Status status) noexcept;

/// The quantities the law is evaluated with: either as commanded or after filtering.
struct Targets {
  Pose pose;                         ///< reference pose T_base_ref
  Matrix6d stiffness;                ///< K in the stiffness frame [N/m, Nm/rad]
  Vector6d damping_ratio;            ///< zeta per axis of the stiffness frame [-]
  JointVector nullspace_q;           ///< nullspace target q_d [rad]
  JointVector nullspace_stiffness;   ///< K_ns per joint [Nm/rad]
  double nullspace_damping_ratio{};  ///< zeta_ns [-]
  Vector6d wrench;                   ///< F in the wrench frame [N, Nm]
  /// Velocity feed-forward of a tracked reference (not filtered; zero unless track() is used):
  Vector6d twist;            ///< reference twist [m/s; rad/s], base frame
  JointVector nullspace_dq;  ///< nullspace target velocity [rad/s]
};

/// Which term of the law gave way when the torque it asked for exceeded a joint's bound
/// (ControllerState::joint_torque_limit). The command is shaped in task space, in this order of
/// giving way: the nullspace torque, then the Cartesian spring, then the commanded wrench, then a
/// declared payload's compensation, then the damping; gravity is only ever clipped. The term named
/// was scaled by ActiveLimits::torque_shaping_scale (keeping its direction); the terms before it
/// were dropped, those after it kept whole.
enum class TorqueShaping {
  none,       ///< the torque fitted: nothing shaped
  nullspace,  ///< the nullspace torque scaled
  spring,     ///< the nullspace dropped, the spring -K e scaled
  wrench,     ///< the nullspace and spring dropped, the commanded wrench scaled
  payload,    ///< the wrench dropped too, the payload's compensation (payload.*) scaled
  damping,    ///< only damping and gravity left, the damping scaled
  gravity,    ///< not even gravity fits: it is clipped per joint
};

/// "none", "nullspace", "spring", "wrench", "payload", "damping", "gravity".
const char* to_string(TorqueShaping shaping) noexcept;

/// Which limits shaped the commands and the last cycle. A command saturation flag says whether
/// the last command of that quantity was saturated (new parameters re-command them all); the
/// others describe the last cycle.
struct ActiveLimits {
  bool stiffness_saturated = false;
  bool damping_ratio_saturated = false;
  bool nullspace_stiffness_saturated = false;
  bool wrench_saturated = false;
  bool translation_error_clipped = false;
  bool rotation_error_clipped = false;
  /// The torque the law asked for exceeded a joint's bound in force: it was shaped in task space
  /// (see torque_shaping), and clipped per joint only where gravity alone does not fit.
  bool joint_torque_saturated = false;
  /// Which term gave way to the torque bound, and the fraction of it that was kept [0, 1].
  TorqueShaping torque_shaping = TorqueShaping::none;
  double torque_shaping_scale = 1.0;
  bool torque_rate_limited = false;
  /// limits.joint_torque was lowered below the torque being commanded: the bound in force
  /// (ControllerState::joint_torque_limit) is ramping down to it at the torque-rate limit.
  bool joint_torque_limit_ramping = false;
  /// After Status::motion_halted the arm came to rest and the controller holds where it stopped
  /// (reference pose and nullspace target reset to the measured ones, a trajectory aborted)
  /// instead of pulling it back into the motion. Cleared by the next reference pose command.
  bool holding = false;
  /// The first joint (-1: none) whose torque toward a position limit the joint-limit bounds
  /// (RobotState::joint_limit_ceiling, filled by the control loop) cut by more than
  /// kLimitHoldShare of its torque bound this cycle. The law resolves the pose error locally: a
  /// reference whose nearest joint configuration lies past a limit (a far reorientation the wrist
  /// would have to make the other way round) leaves the arm held off that limit, short of the
  /// reference, until a nullspace target or a joint trajectory takes it around.
  int joint_limit_held = -1;
};

/// ActiveLimits::joint_limit_held: the share of a joint's torque bound the joint-limit bounds
/// must cut before the arm counts as held off a limit, well above a settling arm's residue.
inline constexpr double kLimitHoldShare = 0.1;

/// What the safety layer (parameters safety.*, payload.*) did in the last cycle. A scale is the
/// fraction of a quantity that was kept (1: untouched).
///
/// The caps act on the sum of every Cartesian term the controller adds (the envelope): the
/// spring, the commanded wrench, the workspace walls' spring, the task-space part of the
/// joint-limit walls, what the nullspace torque leaks to the end effector, and the declared
/// payload's compensation, taken both as carried (it then holds the load's weight) and as not
/// carried (it then pushes up), since the controller cannot know which.
struct SafetyState {
  /// safety.max_speed: the reference was held back (it moves toward the commanded pose no faster
  /// than the cap), the drive was kept from accelerating the end effector near the cap (the drive
  /// scales: the fraction of the sum's push along the motion that was kept), and the end effector
  /// was faster than a cap, so its excess speed was braked.
  bool reference_speed_limited = false;
  double translation_drive_scale = 1.0;
  double rotation_drive_scale = 1.0;
  bool braking = false;
  /// safety.max_force: the fraction of the drive (spring, commanded wrench, walls) kept [0, 1] so
  /// that the sum presses with at most the cap, the payload carried or not.
  double force_scale = 1.0;
  double torque_scale = 1.0;
  /// The fraction of the nullspace torque kept [0, 1]: below 1 only where what it leaks to the
  /// end effector (near a singularity, through the damped projector) alone exceeds a force cap.
  double nullspace_scale = 1.0;
  /// safety.workspace: the reference was clipped into the box; the end effector's origin is
  /// outside the box of the parameters by `workspace_penetration` [m] (base frame, zero inside),
  /// pushed back by `wall_force` [N] (spring and damper, after the caps) from the box in force
  /// (`workspace_in_force`).
  bool reference_clipped = false;
  Eigen::Vector3d workspace_penetration = Eigen::Vector3d::Zero();
  Eigen::Vector3d wall_force = Eigen::Vector3d::Zero();
  /// What the walls hold [J] (their passivity observer): the work the end effector did pushing
  /// into them (against spring and damper) and what the energy tank paid into them, less what
  /// they gave back. With the tank on their spring gives back no more; zero inside the box in
  /// force (what was left was dissipated).
  double wall_energy = 0.0;
  /// The settings that store energy as they are in force: limits.pose_error and the workspace box
  /// and wall stiffness follow their parameters as far as the energy tank pays for what a change
  /// stores (at once where it releases energy; always at once with the tank off). A box that
  /// would put the end effector outside it starts around the end effector and closes in as the
  /// end effector moves in (the reference is clipped into the box of the parameters).
  /// `settings_held`: one of them differs from its parameter, waiting for the tank.
  PoseErrorLimits pose_error_in_force;
  WorkspaceParameters workspace_in_force;
  bool settings_held = false;
  /// While teaching (zero commanded Cartesian stiffness), a joint inside its
  /// joint_limit_avoidance.margin is held off its limit by a joint-space wall
  /// (RobotState::joint_wall_torque, added to tau_cartesian): true while one acts.
  bool joint_limit_wall = false;
  /// safety.energy_tank: its level [J], the energy a stiffness change drew from it this cycle
  /// (negative: returned to it) [J], and the fraction of the cycle's stiffness change that was
  /// applied (below 1: the tank could not pay for all of it, the change waits).
  double tank_level = 0.0;
  double tank_draw = 0.0;
  double stiffness_change_scale = 1.0;
  /// The payload being compensated (payload.*, filtered) [kg; m, end-effector frame].
  double payload_mass = 0.0;
  Eigen::Vector3d payload_center_of_mass = Eigen::Vector3d::Zero();
  /// What the controller holds up at rest, read as a payload: the mass [kg] and the centre of
  /// mass across gravity [m, end-effector frame] that explain the static force it commands
  /// (spring + payload compensation, the commanded wrench excluded), averaged while the end
  /// effector is still. Valid once it has been still for kPayloadSettleTime.
  bool payload_estimate_valid = false;
  double payload_estimate_mass = 0.0;
  Eigen::Vector3d payload_estimate_center_of_mass = Eigen::Vector3d::Zero();
  /// At rest, the static wrench is not one a hanging load can make (it presses down, pushes
  /// sideways or twists about the vertical beyond what the joints' friction explains): a
  /// contact. The estimate is then not valid (and its mass is never negative).
  bool static_wrench_unexplained = false;
  /// The estimate is valid and differs from the declared payload (payload.mass, filtered) by more
  /// than kPayloadMismatchMass + kPayloadMismatchFraction of it: a load declared but not carried,
  /// or carried but not declared. The compensation still follows the declaration (it is the
  /// user's word; the caps bound what a wrong one can do), and the nodes warn.
  bool payload_mismatch = false;
  /// The oscillation watch (CartesianImpedanceController::kOscillationSwings): the fraction of
  /// the commanded Cartesian and nullspace stiffness the law is given [1/256, 1] (the damping
  /// follows: through the ratios, or by its square root where schedule() gives it), and how many
  /// sustained oscillations it has seen since start(). Each one halves the fraction; it is
  /// restored only by start(), since the loop that oscillated (a delay, a soft mount) is still
  /// there.
  double oscillation_scale = 1.0;
  int oscillations = 0;
  /// The passivity observer (safety.passivity): the energy the controller generated on its port
  /// to the arm within the last kPassivityWindow [J]: what the torque sent put into the arm beyond
  /// what the same controller without the loop's delay would have, less what its damper took out
  /// (at or below zero while it is passive; a delay makes its springs pump). The fraction of the
  /// commanded stiffness the passivity controller left each spring: translation, rotation,
  /// nullspace [1/256, 1], on top of oscillation_scale; start() restores it. passivity_halvings
  /// counts the observer's halvings past safety.passivity.threshold (the oscillation watch's,
  /// of the springs the observer names, count in oscillations).
  double generated_energy = 0.0;
  Eigen::Vector3d passivity_scale = Eigen::Vector3d::Ones();
  int passivity_halvings = 0;
  /// The speed and force caps in force this cycle: safety.max_speed and safety.max_force, or
  /// tighter where power and force limiting (safety.pfl) asks for it. Its speed limit [m/s] from
  /// the body region and the arm's effective mass at the end effector along its motion [kg]
  /// (infinite without M(q)); both 0 while safety.pfl.body_region is none.
  MaxSpeedParameters max_speed_in_force;
  MaxForceParameters max_force_in_force;
  double pfl_speed_limit = 0.0;
  double pfl_effective_mass = 0.0;
};

/// What the collision monitor (collision.*) sees and did.
struct CollisionState {
  /// The momentum observer's estimate of the external torque on each joint [Nm or N], and the
  /// part of it nobody expected (beyond the commanded wrench's reaction and a declared contact),
  /// against the threshold in force this cycle. Zero while the monitor does not run.
  JointVector residual;
  JointVector unexpected;
  JointVector threshold;
  /// A collision was found. With a reaction other than `report` it is latched, and the reaction
  /// holds, until a Resume command; with `report` it clears once every joint's unexpected torque
  /// is below half its threshold, and the next crossing is a new collision.
  bool detected = false;
  double time = 0.0;  ///< [s] controller time of the detection
  /// The link it hit: the last joint whose unexpected torque crossed its threshold (a contact on
  /// a link acts on the joints before it only), updated for kCollisionIsolationTime after the
  /// detection; -1: none. The control loop names its link (RobotModel::joint_links()).
  int joint = -1;
  /// |unexpected| / threshold of that joint at detection: how far past it the contact was.
  double ratio = 0.0;
  /// The wrench at the end effector that explains the residual, (J J^T + lambda^2 I)^-1 J r
  /// (lambda: nullspace.pseudo_inverse_damping) [N; Nm], base frame: the contact's wrench where
  /// it is on the last link. Computed while the contact is isolated
  /// (kCollisionIsolationTime after the detection), then kept.
  Vector6d contact_wrench = Vector6d::Zero();
  CollisionReaction reaction = CollisionReaction::report;  ///< the reaction taken
  int collisions = 0;                                      ///< found since start()
  /// Reference poses and nullspace targets not followed while a reaction was latched.
  int commands_held = 0;
};

/// Snapshot written by every update().
struct ControllerState {
  Status status = Status::not_started;
  Pose pose;            ///< measured end-effector pose T_base_ee
  Vector6d pose_error;  ///< e = [p - p_d; log(R R_d^T)], base frame, after clipping [m; rad]
  Targets commanded;    ///< targets as last commanded (after validation and saturation)
  Targets filtered;     ///< targets the law used this cycle
  Matrix6d damping;     ///< D the law used, in the stiffness frame
  Frame stiffness_frame = Frame::base;  ///< frame of the stiffness and damping targets
  Frame wrench_frame = Frame::base;     ///< frame of the wrench targets
  Vector6d wrench_base;                 ///< filtered F in the base frame
  JointVector tau_cartesian;            ///< J^T (-K e - D J dq) [Nm]
  JointVector tau_nullspace;            ///< N tau_0 [Nm]
  JointVector tau_wrench;               ///< J^T F [Nm]
  /// g(q) if dynamics.gravity_compensation, else 0, plus the payload's gravity torque [Nm]
  JointVector tau_gravity;
  JointVector tau;  ///< commanded torque after torque and rate limits [Nm]
  /// Torque bound in force per joint [Nm]: limits.joint_torque, or above it while ramping down
  /// to a lowered limit (|tau| never exceeds this, and this never falls faster than the rate).
  JointVector joint_torque_limit;
  ActiveLimits limits;
  SafetyState safety;
  CollisionState collision;
  /// Why the last cycle failed closed (empty when status is ok): the input ("dq", index 4, ...),
  /// or the term of the law that could not be evaluated ("damping", "tau_nullspace", ...).
  Fault fault;

  /// Filtered K and the damping D the law used, in the base frame (rotated on request; the cycle
  /// itself works in the stiffness frame).
  Matrix6d stiffness_base() const noexcept;
  Matrix6d damping_base() const noexcept;
};

/// The impedance of one cycle as its caller schedules it: every quantity the law uses, with the
/// damping given explicitly instead of derived from damping ratios. See
/// CartesianImpedanceController::schedule().
struct ScheduledImpedance {
  Pose reference;                   ///< reference pose T_base_ref (unit quaternion)
  Matrix6d stiffness;               ///< K in the stiffness frame [N/m, Nm/rad], symmetric PSD
  Matrix6d damping;                 ///< D in the stiffness frame [N s/m, Nm s/rad], symmetric PSD
  JointVector nullspace_q;          ///< nullspace target q_d [rad or m]
  JointVector nullspace_stiffness;  ///< K_ns per joint [Nm/rad]
  JointVector nullspace_damping;    ///< D_ns per joint [Nm s/rad]
  Vector6d wrench;                  ///< F in the wrench frame [N; Nm]
};

class CartesianImpedanceController : public CommandSetters<CartesianImpedanceController> {
 public:
  /// Implausible-motion episodes within kHoldWindow [s] that halt the motion (Status::
  /// motion_halted), and what counts as at rest again: every joint slower than kRestSpeed
  /// [rad/s or m/s] for kRestTime [s].
  static constexpr int kHoldEpisodes = 3;
  static constexpr double kHoldWindow = 1.0;
  static constexpr double kRestSpeed = 0.05;
  static constexpr double kRestTime = 0.1;
  /// The oscillation watch: a limit cycle of the closed loop (a measurement or actuation delay
  /// past the stiffness's margin, a structural resonance) that stays below
  /// plausibility.joint_velocity. It watches the end effector's error rate, J dq less the
  /// reference's own velocity, per axis of the base frame: kOscillationSwings swings in a row
  /// across +-kOscillationSpeed [m/s] (kOscillationAngularSpeed [rad/s]), each at least
  /// kOscillationSustain of the one before (a decaying ring with a damping ratio above 0.07 never
  /// counts) and each shorter than kOscillationHalfPeriod [s] (a sustained motion at 1 Hz or
  /// faster), is an oscillation: found within three of its periods, 3 s at most. The thresholds
  /// are seven to ten times what a real arm's velocity noise puts on the error rate (0.005 rad/s
  /// per joint of a Panda: about 7 mm/s and 0.01 rad/s); a wrist buzzing at 0.2 rad/s behind
  /// unit-mass damping (measured on the realistic Panda) passes 0.1 rad/s. The commanded
  /// stiffnesses are then halved (SafetyState::oscillation_scale; through their filter, the
  /// damping following), which slows every mode and buys phase margin against any delay. An
  /// oscillation that persists past kOscillationFloor of the stiffness fails closed as
  /// Status::motion_halted.
  static constexpr int kOscillationSwings = 6;
  static constexpr double kOscillationSpeed = 0.05;
  static constexpr double kOscillationAngularSpeed = 0.1;
  static constexpr double kOscillationSustain = 0.8;
  static constexpr double kOscillationHalfPeriod = 0.5;
  static constexpr double kOscillationFloor = 1.0 / 256.0;
  /// The passivity observer's window [s]: what the port generated decays with this time
  /// constant, so that the dissipation of a past motion does not hide a generation now. After a
  /// halving, it looks again kPassivitySettle [s] after the torques sent before it have acted
  /// (safety.passivity.delay).
  static constexpr double kPassivityWindow = 0.5;
  static constexpr double kPassivitySettle = 0.05;
  /// After a collision is found, its link is the last joint past its threshold within this time
  /// [s]: a contact far out on the arm may first show on a joint nearer the base, whose residual
  /// has the longer lever.
  static constexpr double kCollisionIsolationTime = 0.02;
  /// The payload estimate (SafetyState) is valid after the end effector has been still (slower
  /// than kStillSpeed [m/s] and kStillAngularSpeed [rad/s]) for this long [s]. The speeds are
  /// of its twist low-passed with the time constant kStillFilterTime [s]: a real arm's joint
  /// velocities carry noise (0.005 rad/s on a Panda's seven joints is about 7 mm/s at the
  /// flange, white), which the filter takes down tenfold while motion still shows within it;
  /// a twist ten times those speeds ends the stillness at once.
  static constexpr double kPayloadSettleTime = 0.5;
  static constexpr double kStillSpeed = 0.005;
  static constexpr double kStillAngularSpeed = 0.02;
  static constexpr double kStillFilterTime = 0.05;
  /// Above a speed cap the excess speed is braked out with this time constant [s]: the brake's
  /// force along the motion is m (v - cap) / kBrakeTime, m the mass the end effector has along
  /// it (1 / e^T J M^-1 J^T e), or the law's damping where that is stronger. It also holds
  /// against what the arm's own motion does to the end effector (the centripetal and Coriolis
  /// terms the law does not model, which a fast-turning wrist puts on the flange's translation:
  /// measured 0.5 m/s^2, which a brake with the law's damping strength let carry the flange 10 %
  /// past the cap). A fifth of the excess per cycle at 1 kHz: far from the discrete loop's limit.
  static constexpr double kBrakeTime = 0.005;
  /// The governor holds the end effector at this fraction of a speed cap (and brakes from there),
  /// so that what the torque-rate limit lets through while it acts (a few percent, on arms
  /// whose joints cannot change their torque as fast as the cap asks) stays within the cap's
  /// 10 % margin. Measured on 2,000 generated compositions with the governor at the cap: 0.5 %
  /// of them passed 1.1 x the cap, by at most 1.5 %.
  static constexpr double kSpeedCapAim = 0.95;
  /// A workspace wall's force changes by at most this share of what the joints' torque-rate
  /// limits allow along the change, so that a wall met at speed pushes straight (clipped joint
  /// by joint, its force pointed elsewhere and spun the wrist) and leaves rate for the governor.
  static constexpr double kWallRateShare = 0.9;
  /// SafetyState::payload_mismatch: estimate and declaration differ by more than
  /// kPayloadMismatchMass [kg] + kPayloadMismatchFraction x the declared mass (the joints'
  /// friction holds part of a load: the shipped robots' estimates of 1 kg read 0.94-0.98 kg).
  static constexpr double kPayloadMismatchMass = 0.25;
  static constexpr double kPayloadMismatchFraction = 0.15;
  /// The static wrench is unexplained (a contact) beyond a sideways force, a downward press or a
  /// torque about the vertical of kUnexplainedForce [N] (kUnexplainedTorque [Nm]) or
  /// kUnexplainedFraction of the load's weight (moment), whichever is larger.
  static constexpr double kUnexplainedForce = 2.0;
  static constexpr double kUnexplainedTorque = 0.2;
  static constexpr double kUnexplainedFraction = 0.2;
  /// Standard gravity [m/s^2]; the payload's weight acts along the base frame's -z.
  static constexpr double kGravity = 9.81;

  /// @throws Error if num_joints is outside [1, kMaxJoints] or the parameters are invalid.
  explicit CartesianImpedanceController(int num_joints, const Parameters& parameters = {});
  ~CartesianImpedanceController();
  CartesianImpedanceController(const CartesianImpedanceController& other);
  CartesianImpedanceController& operator=(const CartesianImpedanceController& other);
  CartesianImpedanceController(CartesianImpedanceController&& other) noexcept;
  CartesianImpedanceController& operator=(CartesianImpedanceController&& other) noexcept;

  int num_joints() const noexcept { return num_joints_; }

  /// Current configuration. The diagonal setters keep it up to date, so a read-modify-write
  /// through set_parameters() preserves them.
  const Parameters& parameters() const noexcept { return parameters_; }

  /// Starts (or restarts) from the measured state: reference pose = current pose, nullspace
  /// target = current q, filtered stiffness and damping = commanded, filtered wrench = 0 (it
  /// ramps in through its filter), previous torque = `tau_previous` (zero if not given), so the
  /// first commands are continuous with what the robot already receives.
  /// @throws Error if `robot` is wrongly sized or not finite.
  void start(const RobotState& robot);
  void start(const RobotState& robot, const Eigen::Ref<const Eigen::VectorXd>& tau_previous);
  bool started() const noexcept { return started_; }

  // set_parameters(), set_reference_pose(), set_stiffness(), ... and start_teaching() come from
  // CommandSetters: each validates its command (throwing Error, changing nothing) and applies it.

  /// Validates and applies any command (see command.hpp); the setters are this.
  /// @throws Error naming the field, value and valid range; nothing changes then.
  void apply(const Command& command);
  /// Applies a validated command: noexcept and allocation-free, so a control loop can apply
  /// commands handed over from other threads inside its cycle. Returns false (and changes
  /// nothing) if the command was validated for a different joint count, or if it is a
  /// ParameterUpdate that the parameters in force no longer fit (consistency_fault() of the
  /// merged set).
  bool apply(const ValidCommand& command) noexcept;

  /// Drives the reference directly, bypassing the pose and nullspace filters, for a caller that
  /// already produces a smooth reference (trajectory execution): reference pose and twist
  /// [m/s; rad/s] in the base frame, nullspace target and its velocity. The twist and joint
  /// velocity are feed-forward: the damping acts on J dq - twist and dq - dq_desired. noexcept,
  /// no allocation; the caller guarantees finite values of the right size.
  void track(const Pose& pose_base, const Vector6d& twist_base, const JointVector& q_desired,
             const JointVector& dq_desired) noexcept;
  /// Ends tracking: the reference stays where it is, the feed-forward velocities become zero.
  void stop_tracking() noexcept;

  /// Sets the commanded and filtered impedance of the next cycles directly, bypassing the
  /// filters, the saturation of commands and the damping rule: for a caller that schedules K and
  /// D itself (a learned variable-impedance policy, or the compatibility API with the published
  /// controller's filter semantics). The law, the minimum damping, the pose-error clipping, the
  /// torque and rate limits and the fail-closed checks still apply. The explicit damping holds
  /// until the next command other than a reference pose or nullspace target. noexcept, no
  /// allocation; the caller guarantees finite values of the right sizes and a unit quaternion.
  void schedule(const ScheduledImpedance& impedance) noexcept;
  /// True while a schedule() is in force (no command has replaced it).
  bool scheduled() const noexcept { return scheduled_; }

  /// One control cycle: filters the targets with the elapsed `dt` [s], evaluates the law at the
  /// measured `robot` state and applies the limits. The result is torque() and state(). Never
  /// throws and never allocates. It fails closed (a status other than ok, state().fault naming
  /// the input, the torque ramping toward zero within the rate limit) on a dt that is not finite
  /// or outside plausibility.dt, and on a robot state that is wrongly sized, not finite, has a
  /// non-unit orientation or a joint faster than plausibility.joint_velocity.
  Status update(const RobotState& robot, double dt) noexcept;

  /// update() for a caller that has checked q and dq itself with checks::measurement() against
  /// joint_velocity_bound() (the control loop does, with the joint limits besides): the measurement
  /// is not checked twice in one cycle; the rest of the robot state is.
  Status update_measured(const RobotState& robot, double dt) noexcept;

  /// plausibility.joint_velocity per joint [rad/s or m/s].
  const JointVector& joint_velocity_bound() const noexcept { return joint_velocity_bound_; }

  /// A cycle without a usable measurement, for a caller that found the fault itself (the control
  /// loop: a position outside the joint limits, a model that could not be evaluated): ramps the
  /// torque toward zero (or g) within the rate limit over `dt` [s] (the last valid dt if `dt` is
  /// not plausible) and reports `status` and `fault`. noexcept, no allocation.
  Status fail_closed(Status status, const Fault& fault, double dt) noexcept;

  /// Commanded joint torque of the last update() [Nm].
  const JointVector& torque() const noexcept { return state_.tau; }
  /// Snapshot of the last update().
  const ControllerState& state() const noexcept { return state_; }

 private:
  friend class CommandSetters<CartesianImpedanceController>;
  void submit_command(const Command& command) { apply(command); }

  struct FilterGains {
    double dt = -1.0;
    double pose = 1.0, stiffness = 1.0, nullspace = 1.0, wrench = 1.0;
  };
  /// Which commanded quantities a command set anew (their saturation flags are set afresh).
  struct Commanded {
    static constexpr unsigned none = 0, stiffness = 1, damping_ratio = 2, nullspace_stiffness = 4,
                              wrench = 8, everything = 15;
  };
  struct Law;  // the law's per-cycle workspace: its kernels and scratch space (src/core/law.hpp)

  // Commands (controller.cpp).
  void apply_saturation(Targets& commanded, ActiveLimits& limits,
                        unsigned commanded_now) const noexcept;
  void commit(const Parameters& parameters, Targets commanded, unsigned commanded_now) noexcept;
  // The Commanded quantities whose rows `names` includes, and those re-commanded from
  // `parameters` (the diagonal stiffness, the damping ratios, ...).
  static unsigned quantities_named(const ParameterNames& names) noexcept;
  void recommand(const Parameters& parameters, unsigned quantities,
                 Targets& commanded) const noexcept;
  void refresh_damping_mode() noexcept;
  void change_frames(Frame stiffness_frame, Frame wrench_frame) noexcept;
  // The cycle (controller.cpp).
  Status cycle(const RobotState& robot, double dt, const Fault& input_fault) noexcept;
  void update_gains(double dt) noexcept;
  void filter_targets() noexcept;
  // The law, one function per term (law.cpp); a term that cannot be evaluated returns false and
  // names its cause in `fault`.
  bool evaluate_law(const RobotState& robot, double dt, Fault& fault) noexcept;
  bool evaluate_halt(const RobotState& robot, Fault& fault) noexcept;
  void measure_pose(const RobotState& robot) noexcept;
  void clip_pose_error() noexcept;
  bool compute_damping(const RobotState& robot, const JointMatrix& mass, Fault& fault) noexcept;
  void spring_damper(const RobotState& robot, double dt) noexcept;
  bool nullspace(const RobotState& robot, const JointMatrix& mass, Fault& fault) noexcept;
  void measure_nullspace_dissipation(const RobotState& robot, double dt) noexcept;
  void commanded_wrench() noexcept;
  void cartesian_torques(const RobotState& robot) noexcept;
  void gravity(const RobotState& robot) noexcept;
  // The safety layer (safety.cpp).
  void limit_reference_speed(double dt) noexcept;
  void clip_reference_to_workspace(bool filtered) noexcept;
  void filter_payload() noexcept;
  void charge_parameter_changes(const RobotState& robot) noexcept;
  void pay_stiffness_change() noexcept;
  void pay_nullspace_stiffness_change(const RobotState& robot) noexcept;
  void pay_pose_error_limit_change() noexcept;
  void pay_workspace_change() noexcept;
  double spring_energy(const Vector6d& error, const Matrix6d& stiffness,
                       const PoseErrorLimits& clip) const noexcept;
  Eigen::Vector2d damping_sent(bool clamped, bool rate_limited) const noexcept;
  void fill_tank() noexcept;
  const JointMatrix& mass_with_payload(const RobotState& robot) noexcept;
  void safety_layer(const RobotState& robot, const JointMatrix& mass, double dt) noexcept;
  void walls(const RobotState& robot, double dt) noexcept;
  void follow_the_rate_limit(const RobotState& robot, double dt) noexcept;
  void keep_walls_passive(const RobotState& robot, double dt) noexcept;
  double wall_rate_step(const RobotState& robot, const Eigen::Vector3d& direction,
                        double dt) noexcept;
  void cap_force() noexcept;
  void govern_speed(const RobotState& robot, const JointMatrix& mass, double dt) noexcept;
  void expect_acceleration(const RobotState& robot) noexcept;
  Vector6d payload_holding_wrench() const noexcept;
  void estimate_payload(double dt) noexcept;
  // The passivity observer and controller (passivity.cpp).
  void observe_passivity(const RobotState& robot, double dt) noexcept;
  void forget_passivity() noexcept;
  // Halves the springs the observer finds generating (all of them where it finds none); false
  // where a spring would go below kOscillationFloor (and nothing is halved).
  bool halve_generating_springs() noexcept;
  // The passivity controller's scales applied to a stiffness: translation and rotation blocks.
  void scale_stiffness_groups(Matrix6d& stiffness, const Eigen::Vector3d& scale) const noexcept;
  // Power and force limiting (pfl.cpp): the caps of this cycle, SafetyState::max_*_in_force.
  void update_caps_in_force(const RobotState& robot) noexcept;
  // The collision monitor (collision.cpp).
  void observe_collision(const RobotState& robot, double dt) noexcept;
  void react_to_collision(const RobotState& robot) noexcept;
  // After the law: the contact's wrench while it is isolated, and the retract's way out.
  void identify_contact(const RobotState& robot) noexcept;
  void record_applied_torque() noexcept;
  void forget_collision_observer() noexcept;
  bool collision_latched() const noexcept;
  // The oscillation watch (oscillation.cpp).
  void watch_oscillation(double dt) noexcept;
  void forget_oscillation() noexcept;
  // Halves SafetyState::oscillation_scale; false (and nothing halved) at kOscillationFloor.
  bool halve_stiffness() noexcept;
  // Past the floor: Status::motion_halted, the springs off until the arm is at rest.
  void halt_oscillating() noexcept;
  void limit_torque(double dt, const RobotState* law_robot = nullptr) noexcept;
  void shape_torque(const RobotState& robot, const JointVector& bound) noexcept;
  void bound_joint_drive(const RobotState& robot) noexcept;

  int num_joints_;
  Parameters parameters_;
  JointVector joint_torque_limit_;
  JointVector joint_torque_rate_limit_;
  JointVector joint_velocity_bound_;
  bool started_ = false;
  FilterGains gains_;
  double last_valid_dt_ = 1e-3;
  ControllerState state_;
  JointVector tau_previous_;  // the torque of the last cycle, after the limits
  // The filter blends commanded and filtered K, so K stays diagonal while both are: the law then
  // takes the diagonal route.
  bool stiffness_diagonal_ = true;
  // Episodes of implausible motion: when the last kHoldEpisodes began (controller time [s]),
  // whether the current failed-closed stretch is one, and whether to hold at the next good cycle.
  void count_implausible_motion(const Fault& fault) noexcept;
  void hold_where_the_arm_is(const RobotState& robot) noexcept;
  double time_ = 0.0;
  std::array<double, kHoldEpisodes> episode_began_{};
  int episodes_ = 0;
  bool in_episode_ = false;
  bool halted_ = false;              // Status::motion_halted: waiting for the arm to come to rest
  bool halted_oscillating_ = false;  // ... because the oscillation watch found no scale left
  double at_rest_for_ = 0;           // [s] every joint slower than kRestSpeed
  double halted_for_ = 0;  // [s] since the halt began, or since the last halving within it
  // Set by schedule(): the damping then comes from the caller, not from the damping ratios.
  bool scheduled_ = false;
  bool scheduled_damping_diagonal_ = true;
  Matrix6d scheduled_damping_;
  JointVector scheduled_nullspace_damping_;
  // Owns the law's workspace; a copy of the controller copies it.
  class LawHandle {
   public:
    explicit LawHandle(int num_joints);
    ~LawHandle();
    LawHandle(const LawHandle& other);
    LawHandle& operator=(const LawHandle& other);
    LawHandle(LawHandle&& other) noexcept;
    LawHandle& operator=(LawHandle&& other) noexcept;
    Law* operator->() const noexcept { return law_.get(); }
    Law& operator*() const noexcept { return *law_; }

   private:
    std::unique_ptr<Law> law_;
  };
  LawHandle law_;
  // The momentum observer (collision.cpp): the momentum of the last cycle, the filtered torque
  // the drives applied (for the thresholds) and the commanded wrench's reaction as the estimate
  // would show it; the end effector's filtered velocity (where it came from).
  bool observer_running_ = false;
  bool observer_measured_ = false;  // whether the running observer reads measured torques
  bool resume_pending_ = false;     // a Resume command, carried out with the next measurement
  JointVector observer_momentum_;
  JointVector observer_applied_filtered_;
  JointVector observer_wrench_filtered_;
  Eigen::Vector3d motion_direction_ = Eigen::Vector3d::Zero();  // low-passed end-effector velocity
  // The filters' factors for the dt and gain they were computed for.
  double observer_dt_ = -1.0, observer_gain_ = -1.0, observer_follow_ = 0.0, motion_follow_ = 0.0;
};

}  // namespace cartesian_impedance
