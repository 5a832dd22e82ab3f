// The safety layer of CartesianImpedanceController (parameters safety.* and payload.*): caps on
// what any valid command can make the arm do. Each function is noexcept, allocation-free and of
// fixed cost; with every cap off it costs a few comparisons.

#include <algorithm>
#include <cmath>

#include "law.hpp"

namespace cartesian_impedance {

namespace {

// The energy that raising the stiffness by dK stores in the spring, per unit of e_c^T dK e_c, for
// an error of `length` clipped at `clip`: 1/2 within the clip, and 1/2 + (length - clip) / clip
// beyond it, where the spring's force no longer grows (the clipped spring's energy is then
// 1/2 e_c^T K e_c + (length - clip) / clip e_c^T K e_c).
double spring_energy_weight(double length, double clip) noexcept {
  return length > clip && clip > 0.0 ? 0.5 + (length - clip) / clip : 0.5;
}

// The speed cap's governor starts taking the push along the motion away at this fraction of the
// cap and has taken all of it at the cap. The band keeps the loop gain (push / band width, an
// extra damping near the cap) a few times the law's own damping, so the discrete loop stays far
// from its stability limit.
constexpr double kGovernorBand = 0.8;

}  // namespace

// The reference moves toward the commanded pose no faster than the speed cap: a far reference is
// approached along a ramp instead of a jump. Trajectories (track()) and schedule() set the
// reference themselves and are not held back; a trajectory's velocity, which the damper pulls
// the end effector toward, is held to the cap (measured before: a trajectory at 0.4 m/s pulled
// the end effector past 1.1 x a 0.25 m/s cap, the governor leaving that pull alone), so that
// near the cap only the spring drives, and the governor takes that away.
void CartesianImpedanceController::limit_reference_speed(double dt) noexcept {
  SafetyState& safety = state_.safety;
  safety.reference_speed_limited = false;
  const MaxSpeedParameters& cap = parameters_.safety.max_speed;
  Pose& reference = state_.filtered.pose;
  const Pose& before = law_->reference_before;
  Vector6d& twist = state_.filtered.twist;
  for (const auto& [start, largest] : {std::pair{0, cap.translation}, {3, cap.rotation}}) {
    const double speed = twist.segment<3>(start).norm();
    if (largest > 0.0 && speed > largest) {
      twist.segment<3>(start) *= largest / speed;
      safety.reference_speed_limited = true;
    }
  }
  if (cap.translation > 0.0) {
    const Eigen::Vector3d step = reference.position - before.position;
    const double length = step.norm();
    const double largest = cap.translation * dt;
    if (length > largest) {
      reference.position = before.position + (largest / length) * step;
      safety.reference_speed_limited = true;
    }
  }
  if (cap.rotation > 0.0) {
    const double angle = before.orientation.angularDistance(reference.orientation);
    const double largest = cap.rotation * dt;
    if (angle > largest) {
      reference.orientation =
          before.orientation.slerp(largest / angle, reference.orientation).normalized();
      safety.reference_speed_limited = true;
    }
  }
}

void CartesianImpedanceController::clip_reference_to_workspace() noexcept {
  const WorkspaceParameters& box = parameters_.safety.workspace;
  bool clipped = false;
  for (Targets* targets : {&state_.commanded, &state_.filtered}) {
    Eigen::Vector3d& position = targets->pose.position;
    const Eigen::Vector3d inside = position.cwiseMax(box.min).cwiseMin(box.max);
    if (inside != position) {
      position = inside;
      clipped = true;
    }
  }
  state_.safety.reference_clipped = clipped;
}

void CartesianImpedanceController::filter_payload() noexcept {
  SafetyState& safety = state_.safety;
  const double a = gains_.wrench;
  safety.payload_mass = (1.0 - a) * safety.payload_mass + a * parameters_.payload.mass;
  safety.payload_center_of_mass =
      (1.0 - a) * safety.payload_center_of_mass + a * parameters_.payload.center_of_mass;
}

// Raising the stiffness by dK while the pose error is e stores 1/2 e^T dK e in the spring: energy
// the arm did not have, which is what lets a stiffness schedule (soft while the error grows,
// stiff while it shrinks) pump an oscillation up. The tank pays for it; lowering the stiffness
// gives the energy back. What the tank cannot pay waits: the cycle's change is applied as far as
// the energy allows, and the filter carries the rest on from there.
void CartesianImpedanceController::pay_stiffness_change() noexcept {
  SafetyState& safety = state_.safety;
  safety.tank_draw = 0.0;
  safety.stiffness_change_scale = 1.0;
  const EnergyTankParameters& tank = parameters_.safety.energy_tank;
  if (!tank.enabled || scheduled_) return;
  Matrix6d& stiffness = state_.filtered.stiffness;
  const Matrix6d& before = law_->stiffness_before;
  if (stiffness == before) return;
  // The error from the reference before this cycle's step: the change of K is charged as if it
  // came first and the reference moved after it. A reference step is not the tank's to pay (the
  // speed and force caps bound it), so a stiffness command sent with a new reference, or a
  // stiffness raised at rest, costs nothing; a raise while the arm is away from its reference
  // costs what it stores.
  Vector6d error = pose_error(state_.pose, law_->reference_before);
  // Beyond limits.pose_error the spring pulls with its force at the clip, so its energy grows by
  // c u^T K u for every metre further (c the clip, u the error's direction): a raise there stores
  // (|e| / c - 1/2) e_c^T dK e_c, not 1/2 e_c^T dK e_c. (That is the clipped spring's energy for an
  // isotropic K; for another, clipping keeps the force's size, not a potential.)
  const PoseErrorLimits& clip = parameters_.limits.pose_error;
  const double translation_weight = spring_energy_weight(error.head<3>().norm(), clip.translation);
  const double rotation_weight = spring_energy_weight(error.tail<3>().norm(), clip.rotation);
  clip_norm(error.head<3>(), clip.translation);
  clip_norm(error.tail<3>(), clip.rotation);
  if (parameters_.stiffness.frame == Frame::end_effector) {
    const Eigen::Matrix3d& rotation = law_->rotation;
    error.head<3>() = rotation.transpose() * error.head<3>().eval();
    error.tail<3>() = rotation.transpose() * error.tail<3>().eval();
  }
  double cost;
  if (stiffness_diagonal_) {
    const Vector6d change = stiffness.diagonal() - before.diagonal();
    const Vector6d squared = error.cwiseAbs2();
    cost = translation_weight * change.head<3>().dot(squared.head<3>()) +
           rotation_weight * change.tail<3>().dot(squared.tail<3>());
  } else {
    const Matrix6d change = stiffness - before;
    cost = 0.5 * error.dot(change * error) +
           (translation_weight - 0.5) *
               error.head<3>().dot(change.topLeftCorner<3, 3>() * error.head<3>()) +
           (rotation_weight - 0.5) *
               error.tail<3>().dot(change.bottomRightCorner<3, 3>() * error.tail<3>());
  }
  if (cost > safety.tank_level) {
    // What the tank holds pays for the part of the change it covers, and the tank is then empty:
    // exactly, as level - cost * (level / cost) may round below zero.
    const double level = std::max(safety.tank_level, 0.0);
    const double scale = level / cost;
    if (stiffness_diagonal_) {
      stiffness.diagonal() = before.diagonal() + scale * (stiffness.diagonal() - before.diagonal());
    } else {
      stiffness = before + scale * (stiffness - before);
    }
    safety.stiffness_change_scale = scale;
    safety.tank_draw = level;
    safety.tank_level = 0.0;
    return;
  }
  safety.tank_draw = cost;
  safety.tank_level = std::min(safety.tank_level - cost, tank.capacity);
}

void CartesianImpedanceController::fill_tank(double energy) noexcept {
  const EnergyTankParameters& tank = parameters_.safety.energy_tank;
  if (!tank.enabled || scheduled_) return;
  SafetyState& safety = state_.safety;
  safety.tank_level = std::min(safety.tank_level + std::max(energy, 0.0), tank.capacity);
}

// M(q) + Jc^T m Jc, Jc = J_v - [r]x J_w the velocity map of the payload's centre of mass (a point
// mass at r = R c from the end effector's origin), for the options that use the inertia.
const JointMatrix& CartesianImpedanceController::mass_with_payload(
    const RobotState& robot) noexcept {
  const double mass = state_.safety.payload_mass;
  const DynamicsParameters& dynamics = parameters_.dynamics;
  if (!(mass > 0.0) || robot.mass.rows() != num_joints_ ||
      !(dynamics.inertia_shaped_damping || dynamics.dynamically_consistent_nullspace)) {
    return robot.mass;
  }
  Law& law = *law_;
  const Eigen::Vector3d offset = law.rotation * state_.safety.payload_center_of_mass;
  law.payload_map = robot.jacobian.topRows<3>();
  for (int i = 0; i < num_joints_; ++i) {
    law.payload_map.col(i) -= offset.cross(robot.jacobian.col(i).tail<3>());
  }
  law.mass = robot.mass;
  law.mass.noalias() += mass * law.payload_map.transpose() * law.payload_map;
  return law.mass;
}

void CartesianImpedanceController::safety_layer() noexcept {
  SafetyState& safety = state_.safety;
  safety.translation_drive_scale = 1.0;
  safety.rotation_drive_scale = 1.0;
  safety.braking = false;
  safety.force_scale = 1.0;
  safety.torque_scale = 1.0;
  safety.workspace_penetration.setZero();
  safety.wall_force.setZero();
  cap_force();
  govern_speed();
  push_back_from_walls();
}

// What presses on the environment at rest is the spring and the commanded wrench (the damping
// vanishes with the motion): their sum is scaled down to the cap, keeping its direction and the
// two terms' proportion.
void CartesianImpedanceController::cap_force() noexcept {
  const MaxForceParameters& cap = parameters_.safety.max_force;
  Vector6d& spring = law_->spring_force;
  Vector6d& wrench = state_.wrench_base;
  const auto cap_part = [&](int start, double largest, double& scale) {
    if (!(largest > 0.0)) return;
    const double norm = (spring.segment<3>(start) + wrench.segment<3>(start)).norm();
    if (norm <= largest) return;
    scale = largest / norm;
    spring.segment<3>(start) *= scale;
    wrench.segment<3>(start) *= scale;
  };
  cap_part(0, cap.force, state_.safety.force_scale);
  cap_part(3, cap.torque, state_.safety.torque_scale);
}

// Near the speed cap the spring and the commanded wrench stop pushing along the motion (from
// kGovernorBand x cap, all of it at the cap), whatever the stiffness, the reference or the wrench;
// the damping still acts. Beyond the cap (a push from outside, or the arm's own momentum) the
// excess speed is braked with the law's own damping strength, never with stiffness.
void CartesianImpedanceController::govern_speed() noexcept {
  Law& law = *law_;
  SafetyState& safety = state_.safety;
  const MaxSpeedParameters& caps = parameters_.safety.max_speed;
  Vector6d& spring = law.spring_force;
  Vector6d& wrench = state_.wrench_base;
  const auto govern = [&](int start, double cap, double& drive_scale) {
    if (!(cap > 0.0)) return;
    const Eigen::Vector3d velocity = law.twist.segment<3>(start);
    const double speed = velocity.norm();
    if (speed <= kGovernorBand * cap) return;
    const Eigen::Vector3d direction = velocity / speed;
    drive_scale = std::clamp((cap - speed) / ((1.0 - kGovernorBand) * cap), 0.0, 1.0);
    const double spring_push = spring.segment<3>(start).dot(direction);
    const double wrench_push = wrench.segment<3>(start).dot(direction);
    const double push = spring_push + wrench_push;
    if (push > 0.0) {
      // Taken from each term in proportion to how much it pushes along the motion.
      const double spring_pushes = std::max(spring_push, 0.0);
      const double wrench_pushes = std::max(wrench_push, 0.0);
      const double removed = (1.0 - drive_scale) * push;
      const double spring_share = spring_pushes / (spring_pushes + wrench_pushes);
      spring.segment<3>(start) -= (removed * spring_share) * direction;
      wrench.segment<3>(start) -= (removed * (1.0 - spring_share)) * direction;
    }
    if (speed > cap) {
      const double strength = state_.damping.diagonal().segment<3>(start).mean();
      law.damping_force.segment<3>(start) -= (strength * (speed - cap)) * direction;
      safety.braking = true;
    }
  };
  govern(0, caps.translation, safety.translation_drive_scale);
  govern(3, caps.rotation, safety.rotation_drive_scale);
}

// Outside the box a wall spring pushes the end effector's origin back, and a damper acts on its
// motion further out. Both join the damping in the torque shaping, so they are the last to give
// way, and neither is capped by safety.max_force: a wall is not a press on the environment.
void CartesianImpedanceController::push_back_from_walls() noexcept {
  const WorkspaceParameters& box = parameters_.safety.workspace;
  SafetyState& safety = state_.safety;
  const Eigen::Vector3d& position = state_.pose.position;
  safety.workspace_penetration = position - position.cwiseMax(box.min).cwiseMin(box.max);
  if (!(box.stiffness > 0.0) || safety.workspace_penetration.isZero(0.0)) return;
  Law& law = *law_;
  Eigen::Vector3d force = -box.stiffness * safety.workspace_penetration;
  for (int i = 0; i < 3; ++i) {
    if (law.twist[i] * safety.workspace_penetration[i] > 0.0)
      force[i] -= box.damping * law.twist[i];
  }
  safety.wall_force = force;
  law.damping_force.head<3>() += force;
}

// The wrench that holds the payload up at the end effector's origin: m g upward and the torque of
// that force at the centre of mass, base frame.
Vector6d CartesianImpedanceController::payload_holding_wrench() const noexcept {
  const SafetyState& safety = state_.safety;
  Vector6d holding;
  holding.head<3>() << 0.0, 0.0, safety.payload_mass * kGravity;
  const Eigen::Vector3d offset = law_->rotation * safety.payload_center_of_mass;
  holding.tail<3>() = offset.cross(holding.head<3>());
  return holding;
}

// At rest the controller's static wrench (spring plus the declared payload's compensation; the
// commanded wrench is the user's, not a load) holds up whatever hangs at the flange: its upward
// force is m g, and its torque r x (0, 0, m g) gives the centre of mass across gravity (along
// gravity it has no lever; that component is reported as zero in the base frame).
void CartesianImpedanceController::estimate_payload(double dt) noexcept {
  Law& law = *law_;
  SafetyState& safety = state_.safety;
  const bool still =
      law.twist.head<3>().norm() < kStillSpeed && law.twist.tail<3>().norm() < kStillAngularSpeed;
  if (!still) {
    law.still_for = 0.0;
    safety.payload_estimate_valid = false;
    return;
  }
  const Vector6d holding = law.spring_force + payload_holding_wrench();
  const double weight = holding[2];
  Eigen::Vector3d center_base = Eigen::Vector3d::Zero();
  if (weight > 1e-6) center_base << -holding[4] / weight, holding[3] / weight, 0.0;
  const Eigen::Vector3d center = law.rotation.transpose() * center_base;
  // Averaged over the stillness, restarted when it begins.
  const double a = law.still_for == 0.0 ? 1.0 : std::min(1.0, dt / (0.2 * kPayloadSettleTime));
  safety.payload_estimate_mass = (1.0 - a) * safety.payload_estimate_mass + a * weight / kGravity;
  safety.payload_estimate_center_of_mass =
      (1.0 - a) * safety.payload_estimate_center_of_mass + a * center;
  law.still_for += dt;
  safety.payload_estimate_valid = law.still_for >= kPayloadSettleTime;
}

}  // namespace cartesian_impedance
