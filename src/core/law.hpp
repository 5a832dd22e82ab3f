#pragma once
// The control law's per-cycle workspace, private to the core: what CartesianImpedanceController's
// law functions (law.cpp) share within a cycle and carry from one cycle to the next. Sized once at
// construction; copying a controller copies it.

#include <array>

#include "cartesian_impedance/core/controller.hpp"
#include "kernels.hpp"

namespace cartesian_impedance {

// Cycles of torque the passivity observer keeps: safety.passivity.delay up to 0.1 s at 1 kHz.
inline constexpr int kPassivityRing = 128;

struct CartesianImpedanceController::Law {
  explicit Law(int num_joints);

  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // R_base_ee of the cycle
  bool damping_diagonal = true;  // this cycle's D is diagonal (the cheap route)
  // (The small terms every cycle reads come first, before the large workspaces below, so that
  // they share a few cache lines: behind them they cost a cache miss each, about 15 ns a cycle.)
  // The safety envelope's terms, base frame: the workspace walls' spring and damper, the force
  // the joint-limit walls press with at the end effector (joint_walls: they act this cycle), and
  // what the nullspace torque leaks there.
  Eigen::Vector3d wall_spring = Eigen::Vector3d::Zero();
  Eigen::Vector3d wall_damper = Eigen::Vector3d::Zero();
  // The walls' passivity observer: the force they sent last cycle, where the end effector was then,
  // and the energy they hold (paid in by the tank or by the arm pushing in, less what they gave
  // back) [J].
  Eigen::Vector3d wall_force_sent = Eigen::Vector3d::Zero();
  Eigen::Vector3d wall_spring_sent = Eigen::Vector3d::Zero();
  Eigen::Vector3d wall_damper_sent = Eigen::Vector3d::Zero();
  Eigen::Vector3d wall_position = Eigen::Vector3d::Zero();
  double wall_energy = 0.0;
  Vector6d joint_wall_force = Vector6d::Zero();
  Vector6d joint_wall_force_before = Vector6d::Zero();  // before the caps
  Vector6d nullspace_leak = Vector6d::Zero();
  bool joint_walls = false;
  // The oscillation watch, per axis of the end effector's error rate (base frame): the side of
  // the threshold it was last beyond (0: none, or the swings went stale), when that swing began
  // [s, controller time], its largest magnitude, the previous swing's, and the sustained swings
  // in a row. The stiffness scale through the stiffness filter, and its square root, which
  // scales a scheduled damping and the minimum damping.
  std::array<int, 6> swing_side{};
  std::array<double, 6> swing_began{};
  std::array<double, 6> swing_peak{};
  std::array<double, 6> swing_peak_before{};
  std::array<int, 6> swings{};
  double oscillation_scale_filtered = 1.0;
  double oscillation_damping_scale = 1.0;
  // The speed governor's disturbance observer: the end effector's twist and the acceleration the
  // torque sent should have given it (J M^-1 tau), both of the last cycle, and the low-passed
  // difference to the acceleration measured since: what the law does not model (the centripetal
  // and Coriolis terms, the rate limit's and the shaping's changes to the torque, a push).
  Vector6d twist_before = Vector6d::Zero();
  Vector6d expected_acceleration = Vector6d::Zero();
  Vector6d disturbance = Vector6d::Zero();
  bool expecting = false;
  Matrix6d damping_frame;  // D before the minimum damping, in the stiffness frame
  // The filtered K and zeta the (full, unit-mass) damping was last computed for: it is only
  // recomputed while they move.
  Matrix6d damping_computed_for_stiffness;
  Vector6d damping_computed_for_ratio;
  InertiaShapedDamping inertia_damping;  // tracks the square root's axes from cycle to cycle
  TaskInertia pfl_inertia;               // the arm's effective mass for power and force limiting
  NullspaceProjector projector;
  JointVector nullspace_damping;  // D_ns of the cycle
  JointVector tau_0;              // the nullspace torque before the projection
  JointVector max_step;           // rate limit * dt per joint
  // The spring's part of the Cartesian force, -K e in the base frame, and what the torque
  // shaping (limit_torque) splits the cycle's torque into when it does not fit.
  Vector6d spring_force = Vector6d::Zero();
  JointVector tau_spring, tau_damping, tau_kept;
  // The drive's torque J^T (spring + wrench) + the nullspace torque, where the joint-limit bounds
  // act (bound_joint_drive()), and the joint-space walls: the loop's plus what those bounds took.
  JointVector joint_drive;
  JointVector joint_wall_torque;
  JointVector tau_payload;  // the declared payload's compensation (part of tau_gravity)
  // The rest of the Cartesian force (damping, and the safety layer's walls and brake), base frame,
  // and the end effector's twist J dq of the cycle.
  Vector6d damping_force = Vector6d::Zero();
  Vector6d twist = Vector6d::Zero();
  // The filtered K before this cycle's filter step: the energy tank pays for the difference.
  Matrix6d stiffness_before = Matrix6d::Zero();
  // The filtered nullspace target and stiffness before this cycle's filter step: the tank pays
  // for a raise of the stiffness, 1/2 e^T dK_ns e.
  JointVector nullspace_q_before, nullspace_stiffness_before;
  // The nullspace damping torque, before and after the projection: what it dissipates fills the
  // tank (computed while the tank is not full).
  JointVector nullspace_damping_torque, nullspace_damping_projected;
  // Scratch space of the speed governor and the passivity observer (a joint torque).
  JointVector governor_joint;
  // What the Cartesian and the nullspace damping dissipate this cycle [J], for the tank once the
  // torque is known (fill_tank()).
  double dissipated_cartesian = 0.0;
  double dissipated_nullspace = 0.0;
  // The pose error before clipping, base frame.
  Vector6d unclipped_error = Vector6d::Zero();
  // The rotation speed cap's largest step per cycle [rad] and the cosine and sine of its half.
  double speed_step_angle = -1.0, speed_step_cos = 1.0, speed_step_sin = 0.0;
  // The filtered reference before this cycle's filter step: the speed cap limits the step.
  Pose reference_before;
  // M(q) with the payload's inertia (payload.mass > 0 and a dynamic option on), and the
  // velocity map of the payload's centre of mass, J_v - [r]x J_w.
  JointMatrix mass;
  Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, kMaxJoints> payload_map;
  // How long the end effector has been still [s], for the payload estimate, and its twist
  // low-passed (kStillFilterTime) for that test, so that sensor noise does not read as motion.
  double still_for = 0.0;
  Vector6d still_twist = Vector6d::Zero();

  // The passivity observer (passivity.cpp): the drive's torque sent in the last kPassivityRing
  // cycles (all but the gravity torque and the commanded wrench, which are the arm's own and the
  // user's), oldest overwritten first; the power the Cartesian damper takes out of the arm's motion
  // this cycle, translation and rotation [W]; the energy each spring's port generated in the window
  // (translation, rotation, nullspace) and their sum [J]; how long the observer waits after a
  // halving [s].
  std::array<JointVector, kPassivityRing> torque_sent;
  int sent_next = 0;
  int sent_count = 0;
  Eigen::Vector2d damper_power = Eigen::Vector2d::Zero();
  // Whether the clamp acted on this cycle's torque (limit_torque()).
  bool torque_clamped = false;
  Eigen::Vector3d generated = Eigen::Vector3d::Zero();
  double generated_sum = 0.0;
  double passivity_wait = 0.0;

  // The damping must be computed anew at the next cycle (K, zeta or the mode changed).
  void forget_damping() noexcept {
    damping_computed_for_stiffness.setConstant(std::numeric_limits<double>::quiet_NaN());
  }
};

}  // namespace cartesian_impedance
