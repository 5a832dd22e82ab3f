// The safety layer of CartesianImpedanceController (parameters safety.*, payload.*, and the
// energy-storing limits.pose_error): caps on what any valid command can make the arm do. Each
// function is noexcept, allocation-free and of fixed cost; with every cap off it costs a few
// comparisons.

#include <algorithm>
#include <cmath>
#include <limits>

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
// speed it holds (kSpeedCapAim x the cap) and has taken all of it there. The band keeps the loop gain (push / band width, an
// extra damping near the cap) a few times the law's own damping, so the discrete loop stays far
// from its stability limit.
constexpr double kGovernorBand = 0.8;

// The governor's disturbance observer averages over this time [s]: a few cycles at 1 kHz, well
// inside the brake's kBrakeTime.
constexpr double kDisturbanceTime = 0.003;


// Iterations for the largest affordable part of a change whose stored energy is not linear in it
// (a clip, a box): enough for the Illinois method to find it to round-off on any change in range.
constexpr int kMaxIterations = 60;

// The largest s in [0, 1] with |s d + b| <= cap, for |b| <= cap (s = 0 fits); 0 if |b| > cap.
double largest_fitting(const Eigen::Vector3d& d, const Eigen::Vector3d& b, double cap) noexcept {
  const double excess = b.squaredNorm() - cap * cap;
  if (excess > 0.0) return 0.0;
  const double dd = d.squaredNorm();
  const double db = d.dot(b);
  if (dd + 2.0 * db + excess <= 0.0) return 1.0;
  // dd s^2 + 2 db s + excess = 0: the larger root, >= 0 since excess <= 0.
  const double root = (-db + std::sqrt(std::max(db * db - dd * excess, 0.0))) / dd;
  return std::clamp(root, 0.0, 1.0);
}

// The largest s for which both |s d + offset| <= cap and |s d + offset + payload| <= cap: the
// press of the sum whether a declared payload is carried (its compensation holds its weight) or
// not (it pushes).
double largest_fitting_both(const Eigen::Vector3d& d, const Eigen::Vector3d& offset,
                            const Eigen::Vector3d& payload, double cap) noexcept {
  return std::min(largest_fitting(d, offset, cap), largest_fitting(d, offset + payload, cap));
}

// The walls' stored energy per axis, 1/2 k (p_i - box(p)_i)^2, for a box and stiffness.
Eigen::Vector3d wall_energy(const Eigen::Vector3d& position, const Eigen::Vector3d& min,
                            const Eigen::Vector3d& max, double stiffness) noexcept {
  return 0.5 * stiffness * (position - position.cwiseMax(min).cwiseMin(max)).cwiseAbs2();
}

// The largest s in [0, 1] whose cost(s) fits into `level` >= 0, given cost(0) = 0 and
// cost(1) > level: by regula falsi with the Illinois modification (it converges superlinearly,
// also where the cost is nearly linear in s over a change many orders larger than what the tank
// pays, which bisection would resolve only after some 40 steps), keeping the affordable end.
template <typename Cost>
double largest_affordable(double level, const Cost& cost) noexcept {
  double low = 0.0, high = 1.0;
  double f_low = -level, f_high = cost(1.0) - level;
  int side = 0;
  for (int i = 0; i < kMaxIterations && f_low < -1e-9 * level && high - low > 1e-15; ++i) {
    double s = (low * f_high - high * f_low) / (f_high - f_low);
    if (!(s > low && s < high)) s = 0.5 * (low + high);
    const double f = cost(s) - level;
    if (f <= 0.0) {
      low = s;
      f_low = f;
      if (side == -1) f_high *= 0.5;
      side = -1;
    } else {
      high = s;
      f_high = f;
      if (side == 1) f_low *= 0.5;
      side = 1;
    }
  }
  return low;
}

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

// The commanded reference, and with `filtered` the filtered one too (at once: without a speed
// cap nothing else brings it in).
void CartesianImpedanceController::clip_reference_to_workspace(bool filtered) noexcept {
  const WorkspaceParameters& box = parameters_.safety.workspace;
  bool& clipped = state_.safety.reference_clipped;
  if (!filtered) clipped = false;
  for (Targets* targets : {&state_.commanded, &state_.filtered}) {
    if (targets == &state_.filtered && !filtered) continue;
    Eigen::Vector3d& position = targets->pose.position;
    const Eigen::Vector3d inside = position.cwiseMax(box.min).cwiseMin(box.max);
    if (inside != position) {
      position = inside;
      clipped = true;
    }
  }
}

void CartesianImpedanceController::filter_payload() noexcept {
  SafetyState& safety = state_.safety;
  const double a = gains_.wrench;
  safety.payload_mass = (1.0 - a) * safety.payload_mass + a * parameters_.payload.mass;
  safety.payload_center_of_mass =
      (1.0 - a) * safety.payload_center_of_mass + a * parameters_.payload.center_of_mass;
}

// Every run-time change that can raise the energy stored in the controller's springs is paid
// from the tank: the Cartesian stiffness (as filtered), the nullspace stiffness, the pose-error
// clip and the workspace box and its wall stiffness. A change that releases energy is applied at
// once and returns it to the tank; one the tank cannot pay is applied as far as it can and waits
// for the rest (the stiffnesses through their filters, the clip and the box in
// SafetyState::*_in_force). So "kinetic + stored + tank energy never grows" holds for any schedule
// of these parameters, not only of the stiffness.
void CartesianImpedanceController::charge_parameter_changes(const RobotState& robot) noexcept {
  SafetyState& safety = state_.safety;
  safety.tank_draw = 0.0;
  safety.stiffness_change_scale = 1.0;
  const EnergyTankParameters& tank = parameters_.safety.energy_tank;
  if (!tank.enabled || scheduled_) {
    safety.pose_error_in_force = parameters_.limits.pose_error;
    safety.workspace_in_force = parameters_.safety.workspace;
    safety.settings_held = false;
    return;
  }
  pay_stiffness_change();
  pay_nullspace_stiffness_change(robot);
  pay_pose_error_limit_change();
  pay_workspace_change();
  const PoseErrorLimits& clip = parameters_.limits.pose_error;
  const WorkspaceParameters& box = parameters_.safety.workspace;
  const WorkspaceParameters& in_force = safety.workspace_in_force;
  safety.settings_held = safety.pose_error_in_force.translation != clip.translation ||
                         safety.pose_error_in_force.rotation != clip.rotation ||
                         in_force.min != box.min || in_force.max != box.max ||
                         in_force.stiffness != box.stiffness;
}

// The energy of the clipped spring K (stiffness frame) at the pose error `error` (base frame,
// unclipped) with the clips `clip`: w_t e_t^T K_tt e_t + w_r e_r^T K_rr e_r + e_t^T K_tr e_r for
// the clipped halves, w the weights of spring_energy_weight().
double CartesianImpedanceController::spring_energy(const Vector6d& error, const Matrix6d& stiffness,
                                                   const PoseErrorLimits& clip) const noexcept {
  Vector6d clipped = error;
  const double translation_weight =
      spring_energy_weight(clipped.head<3>().norm(), clip.translation);
  const double rotation_weight = spring_energy_weight(clipped.tail<3>().norm(), clip.rotation);
  clip_norm(clipped.head<3>(), clip.translation);
  clip_norm(clipped.tail<3>(), clip.rotation);
  if (parameters_.stiffness.frame == Frame::end_effector) {
    const Eigen::Matrix3d& rotation = law_->rotation;
    clipped.head<3>() = rotation.transpose() * clipped.head<3>().eval();
    clipped.tail<3>() = rotation.transpose() * clipped.tail<3>().eval();
  }
  if (stiffness_diagonal_) {
    const Vector6d squared = clipped.cwiseAbs2();
    return translation_weight * stiffness.diagonal().head<3>().dot(squared.head<3>()) +
           rotation_weight * stiffness.diagonal().tail<3>().dot(squared.tail<3>());
  }
  return 0.5 * clipped.dot(stiffness * clipped) +
         (translation_weight - 0.5) *
             clipped.head<3>().dot(stiffness.topLeftCorner<3, 3>() * clipped.head<3>()) +
         (rotation_weight - 0.5) *
             clipped.tail<3>().dot(stiffness.bottomRightCorner<3, 3>() * clipped.tail<3>());
}

// Raising the stiffness by dK while the pose error is e stores 1/2 e^T dK e in the spring: energy
// the arm did not have, which is what lets a stiffness schedule (soft while the error grows,
// stiff while it shrinks) pump an oscillation up. The tank pays for it; lowering the stiffness
// gives the energy back. What the tank cannot pay waits: the cycle's change is applied as far as
// the energy allows, and the filter carries the rest on from there.
void CartesianImpedanceController::pay_stiffness_change() noexcept {
  SafetyState& safety = state_.safety;
  Matrix6d& stiffness = state_.filtered.stiffness;
  const Matrix6d& before = law_->stiffness_before;
  if (stiffness == before) return;
  // The error from the reference before this cycle's step: the change of K is charged as if it
  // came first and the reference moved after it. A reference step is not the tank's to pay (the
  // speed and force caps bound it), so a stiffness command sent with a new reference, or a
  // stiffness raised at rest, costs nothing; a raise while the arm is away from its reference
  // costs what it stores. (The stored energy is linear in K, so the part of the change that the
  // tank can pay is in proportion.)
  const Vector6d error = pose_error(state_.pose, law_->reference_before);
  const PoseErrorLimits& clip = safety.pose_error_in_force;
  const double cost = spring_energy(error, stiffness, clip) - spring_energy(error, before, clip);
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
    safety.tank_draw += level;
    safety.tank_level = 0.0;
    return;
  }
  safety.tank_draw += cost;
  safety.tank_level =
      std::min(safety.tank_level - cost, parameters_.safety.energy_tank.capacity);
}

// The nullspace spring stores 1/2 e^T K_ns e, e = q - q_d: a raise of K_ns while the joints are
// away from their target is paid like a raise of K (from the target before this cycle's step).
void CartesianImpedanceController::pay_nullspace_stiffness_change(const RobotState& robot) noexcept {
  Law& law = *law_;
  JointVector& stiffness = state_.filtered.nullspace_stiffness;
  const JointVector& before = law.nullspace_stiffness_before;
  if (stiffness == before) return;
  SafetyState& safety = state_.safety;
  const double cost =
      0.5 * (stiffness - before).dot((robot.q - law.nullspace_q_before).cwiseAbs2());
  if (cost > safety.tank_level) {
    const double level = std::max(safety.tank_level, 0.0);
    stiffness = before + (level / cost) * (stiffness - before);
    safety.tank_draw += level;
    safety.tank_level = 0.0;
    return;
  }
  safety.tank_draw += cost;
  safety.tank_level =
      std::min(safety.tank_level - cost, parameters_.safety.energy_tank.capacity);
}

// Beyond limits.pose_error the spring pulls with its force at the clip, k c, whatever the error: a
// raised clip lets it pull harder at once, storing k (|e| (c' - c) - (c'^2 - c^2) / 2) that nothing
// paid for (measured before: a clip raised while the error shrinks and lowered while it grows
// pumped a 5 cm error up to 92 cm). The clips in force follow limits.pose_error as the tank pays.
void CartesianImpedanceController::pay_pose_error_limit_change() noexcept {
  SafetyState& safety = state_.safety;
  const PoseErrorLimits& target = parameters_.limits.pose_error;
  PoseErrorLimits& in_force = safety.pose_error_in_force;
  if (in_force.translation == target.translation && in_force.rotation == target.rotation) return;
  const PoseErrorLimits from = in_force;
  const Vector6d error = pose_error(state_.pose, law_->reference_before);
  const Matrix6d& stiffness = state_.filtered.stiffness;
  const double before = spring_energy(error, stiffness, from);
  const auto at = [&](double s) {
    return PoseErrorLimits{from.translation + s * (target.translation - from.translation),
                           from.rotation + s * (target.rotation - from.rotation)};
  };
  const auto cost = [&](double s) { return spring_energy(error, stiffness, at(s)) - before; };
  const double whole = cost(1.0);
  const double s = whole <= safety.tank_level ? 1.0 : largest_affordable(safety.tank_level, cost);
  const double paid = s == 1.0 ? whole : cost(s);
  in_force = s == 1.0 ? target : at(s);
  safety.tank_draw += paid;
  safety.tank_level = std::clamp(safety.tank_level - paid, 0.0,
                                 parameters_.safety.energy_tank.capacity);
}

// The wall stores 1/2 k_w |p - box(p)|^2: moving the box past the end effector, or stiffening a
// wall it is outside of, would throw it back with energy nobody paid for (measured before: a box
// moved 0.15 m past the flange threw it back at 1.35 m/s). The box in force follows the
// parameters as the tank pays; a face that would pass the end effector stops at it (that costs
// nothing) and follows it in, since the reference is clipped into the box of the parameters.
void CartesianImpedanceController::pay_workspace_change() noexcept {
  SafetyState& safety = state_.safety;
  const WorkspaceParameters& target = parameters_.safety.workspace;
  WorkspaceParameters& in_force = safety.workspace_in_force;
  in_force.damping = target.damping;
  if (in_force.min == target.min && in_force.max == target.max &&
      in_force.stiffness == target.stiffness) {
    return;
  }
  const WorkspaceParameters from = in_force;
  const Eigen::Vector3d& position = state_.pose.position;
  const Eigen::Vector3d before = wall_energy(position, from.min, from.max, from.stiffness);
  const auto change = [&](double s) -> Eigen::Vector3d {
    return wall_energy(position, from.min + s * (target.min - from.min),
                       from.max + s * (target.max - from.max),
                       from.stiffness + s * (target.stiffness - from.stiffness)) -
           before;
  };
  // What a wall's move stores is paid for on its own: energy that another wall releases (a box
  // moved sideways past the flange) goes to the tank but does not pay for it, which would throw
  // the flange across at once with the energy moved from one wall to the other.
  const auto cost = [&](double s) { return change(s).cwiseMax(0.0).sum(); };
  const double s = cost(1.0) <= safety.tank_level ? 1.0 : largest_affordable(safety.tank_level, cost);
  const double paid = change(s).sum();
  if (s == 1.0) {
    in_force.min = target.min;
    in_force.max = target.max;
    in_force.stiffness = target.stiffness;
  } else {
    in_force.min = from.min + s * (target.min - from.min);
    in_force.max = from.max + s * (target.max - from.max);
    in_force.stiffness = from.stiffness + s * (target.stiffness - from.stiffness);
  }
  safety.tank_draw += paid;
  safety.tank_level = std::clamp(safety.tank_level - paid, 0.0,
                                 parameters_.safety.energy_tank.capacity);
  law_->wall_energy = std::max(law_->wall_energy + paid, 0.0);
}

// What the damping dissipated this cycle fills the tank, as far as the torque sent carried the
// damping: a term the torque shaping scaled counts scaled, and a cycle whose torque was clamped
// or rate-limited counts nothing (its damping was not what the law computed; counting it would
// let the tank pay out energy the arm never lost: measured 0.3 mJ per cycle against a stiff wall
// on a weak arm).
void CartesianImpedanceController::fill_tank(bool clamped) noexcept {
  Law& law = *law_;
  const EnergyTankParameters& tank = parameters_.safety.energy_tank;
  const double cartesian = std::max(law.dissipated_cartesian, 0.0);
  const double nullspace = std::max(law.dissipated_nullspace, 0.0);
  law.dissipated_cartesian = law.dissipated_nullspace = 0.0;
  if (!tank.enabled || scheduled_) return;
  const ActiveLimits& limits = state_.limits;
  if (clamped || limits.torque_rate_limited) return;
  double energy = 0.0;
  switch (limits.torque_shaping) {
    case TorqueShaping::none:
      energy = cartesian + nullspace;
      break;
    case TorqueShaping::nullspace:
      energy = cartesian + limits.torque_shaping_scale * nullspace;
      break;
    case TorqueShaping::spring:
    case TorqueShaping::wrench:
    case TorqueShaping::payload:
      energy = cartesian;
      break;
    case TorqueShaping::damping:
      energy = limits.torque_shaping_scale * cartesian;
      break;
    case TorqueShaping::gravity:
      break;
  }
  SafetyState& safety = state_.safety;
  safety.tank_level = std::min(safety.tank_level + energy, tank.capacity);
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

// The envelope: the walls first, then the caps on the sum of every Cartesian term (walls
// included), then the walls join the damping (the last to give way in the torque shaping).
void CartesianImpedanceController::safety_layer(const RobotState& robot, const JointMatrix& mass,
                                                double dt) noexcept {
  SafetyState& safety = state_.safety;
  safety.translation_drive_scale = 1.0;
  safety.rotation_drive_scale = 1.0;
  safety.braking = false;
  safety.force_scale = 1.0;
  safety.torque_scale = 1.0;
  safety.nullspace_scale = 1.0;
  Law& law = *law_;
  law.joint_walls = robot.joint_wall_torque.size() == num_joints_ &&
                    !robot.joint_wall_torque.isZero(0.0);
  walls(robot, dt);
  const MaxForceParameters& force_cap = parameters_.safety.max_force;
  const MaxSpeedParameters& speed_cap = parameters_.safety.max_speed;
  const bool capped = force_cap.force > 0.0 || force_cap.torque > 0.0 ||
                      speed_cap.translation > 0.0 || speed_cap.rotation > 0.0;
  law.joint_wall_force.setZero();
  if (capped && law.joint_walls) {
    law.projector.task_force(robot.jacobian, parameters_.nullspace.pseudo_inverse_damping,
                             robot.joint_wall_torque, law.joint_wall_force);
  }
  law.joint_wall_force_before = law.joint_wall_force;
  // What the nullspace torque leaks to the end effector: it joins the sum where a cap acts on it.
  law.nullspace_leak.setZero();
  if (capped) {
    law.projector.task_force(robot.jacobian, parameters_.nullspace.pseudo_inverse_damping,
                             state_.tau_nullspace, law.nullspace_leak);
  }
  if (force_cap.force > 0.0 || force_cap.torque > 0.0) cap_force();
  if (speed_cap.translation > 0.0 || speed_cap.rotation > 0.0) govern_speed(robot, mass, dt);
  // What the caps took off the joint-limit walls' task-space force, taken off their torque.
  law.damping_force += law.joint_wall_force - law.joint_wall_force_before;
  law.damping_force.head<3>() += law.wall_spring + law.wall_damper;
  safety.wall_force = law.wall_spring + law.wall_damper;
  law.wall_force_sent = safety.wall_force;
  law.wall_spring_sent = law.wall_spring;
  law.wall_damper_sent = law.wall_damper;
}

// A stiff wall sampled at the control rate gives back more than it stored: its force, computed
// where the end effector is at the start of a cycle, is held for the whole cycle while the end
// effector moves out of it (measured: a 63,000 N/m wall returned twice what it held when the end
// effector left it by its depth within one cycle). The walls' passivity observer counts the
// energy they hold - what the tank paid into them, what the arm did pushing into them, less the
// work their force did over each cycle - and the spring gives back at most that within the next
// cycle: Ryu and Hannaford's passivity controller, for the walls.
// With the energy tank off the walls are plain springs, as everything else is then.
void CartesianImpedanceController::keep_walls_passive(double dt) noexcept {
  if (!parameters_.safety.energy_tank.enabled || scheduled_) return;
  Law& law = *law_;
  const double giving = law.wall_spring.dot(law.twist.head<3>()) * dt;  // to the arm, this cycle
  if (giving > law.wall_energy) {
    law.wall_spring *= std::max(law.wall_energy, 0.0) / giving;
  }
}

// A stiff wall met at speed asks for its force faster than the joints' torque-rate limit lets it
// come (100,000 N/m at 0.1 m/s: 10 kN/s, where the Panda's joints give about 2 kN/s at the
// flange); clipped joint by joint, the force it gets points elsewhere and spins the wrist (measured:
// 1.2 x the rotation cap). The walls' force changes by at most what the rate limit gives along
// the change, min_i rate_i / |(J^T u)_i|: a wall met at speed is entered a little deeper,
// and pushes straight. kWallRateShare of the rate goes to the walls; the rest stays for the terms
// that hold the motion back while the wall builds up (the governor's, the damping).
void CartesianImpedanceController::follow_the_rate_limit(const RobotState& robot,
                                                         double dt) noexcept {
  Law& law = *law_;
  const Eigen::Vector3d change = law.wall_spring + law.wall_damper - law.wall_force_sent;
  const double size = change.norm();
  if (!(size > 0.0)) return;
  Vector6d direction = Vector6d::Zero();
  direction.head<3>() = change / size;
  jacobian_transpose_times(robot.jacobian, direction, law.governor_joint);
  double largest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < num_joints_; ++i) {
    const double lever = std::abs(law.governor_joint[i]);
    if (lever > 0.0) {
      largest = std::min(largest, kWallRateShare * joint_torque_rate_limit_[i] * dt / lever);
    }
  }
  if (size <= largest) return;
  const double kept = largest / size;
  law.wall_spring = law.wall_spring_sent + kept * (law.wall_spring - law.wall_spring_sent);
  law.wall_damper = law.wall_damper_sent + kept * (law.wall_damper - law.wall_damper_sent);
}

// Outside the box in force a wall spring pushes the end effector's origin back, and a damper acts
// on its motion further out. Both are part of the envelope: capped with the rest, and the spring
// governed with the drive (the damper only ever takes energy out).
void CartesianImpedanceController::walls(const RobotState& robot, double dt) noexcept {
  Law& law = *law_;
  SafetyState& safety = state_.safety;
  const Eigen::Vector3d& position = state_.pose.position;
  // The work the walls' force did on the arm since the last cycle.
  law.wall_energy -= law.wall_force_sent.dot(position - law.wall_position);
  law.wall_position = position;
  const WorkspaceParameters& configured = parameters_.safety.workspace;
  safety.workspace_penetration =
      position - position.cwiseMax(configured.min).cwiseMin(configured.max);
  law.wall_spring.setZero();
  law.wall_damper.setZero();
  const WorkspaceParameters& box = safety.workspace_in_force;
  if (!(box.stiffness > 0.0)) {
    law.wall_energy = 0.0;
    follow_the_rate_limit(robot, dt);
    return;
  }
  const Eigen::Vector3d penetration = position - position.cwiseMax(box.min).cwiseMin(box.max);
  if (penetration.isZero(0.0)) {
    law.wall_energy = 0.0;  // what a wall held and did not give back was dissipated
    follow_the_rate_limit(robot, dt);
    return;
  }
  law.wall_spring = -box.stiffness * penetration;
  for (int i = 0; i < 3; ++i) {
    if (law.twist[i] * penetration[i] > 0.0) law.wall_damper[i] = -box.damping * law.twist[i];
  }
  keep_walls_passive(dt);
  follow_the_rate_limit(robot, dt);
}

// What presses on the environment at rest is the sum of every term the controller adds (the
// damping vanishes with the motion): the drive (spring, commanded wrench, the walls' spring, the
// joint-limit walls' force) and what does not scale with it, the nullspace torque's leak and the
// declared payload's compensation. The drive is scaled as a whole, keeping its direction and its
// terms' proportions, so that the sum stays under the cap whether the payload is carried (its
// compensation holds the load's weight) or not (it presses); validate() keeps the payload's own
// weight under the cap, so scaling the drive always can. Where the leak alone would break the
// cap (near a singularity), the nullspace torque is scaled first.
void CartesianImpedanceController::cap_force() noexcept {
  Law& law = *law_;
  SafetyState& safety = state_.safety;
  const MaxForceParameters& cap = parameters_.safety.max_force;
  Vector6d& spring = law.spring_force;
  Vector6d& wrench = state_.wrench_base;
  const Vector6d payload = safety.payload_mass > 0.0 ? payload_holding_wrench() : Vector6d::Zero();
  // The walls' damper joins the sum: met at speed, a stiff wall's damper alone asked for more
  // than the joints had (measured: 185 N at 0.37 m/s), and the jolt spun the wrist past its cap.
  Vector6d drive = spring + wrench + law.joint_wall_force;
  drive.head<3>() += law.wall_spring + law.wall_damper;
  double nullspace_scale = 1.0;
  const auto part_scale = [&](int start, double largest, double& scale) {
    if (!(largest > 0.0)) return;
    const Eigen::Vector3d leak = law.nullspace_leak.segment<3>(start);
    const Eigen::Vector3d load = payload.segment<3>(start);
    // The leak alone (with the payload either way) must fit first.
    const double leak_scale = largest_fitting_both(leak, Eigen::Vector3d::Zero(), load, largest);
    nullspace_scale = std::min(nullspace_scale, leak_scale);
    scale = largest_fitting_both(drive.segment<3>(start), leak_scale * leak, load, largest);
  };
  part_scale(0, cap.force, safety.force_scale);
  part_scale(3, cap.torque, safety.torque_scale);
  if (nullspace_scale < 1.0) {
    state_.tau_nullspace *= nullspace_scale;
    law.nullspace_leak *= nullspace_scale;
    safety.nullspace_scale = nullspace_scale;
  }
  for (const auto& [start, scale] : {std::pair{0, safety.force_scale}, {3, safety.torque_scale}}) {
    if (scale == 1.0) continue;
    spring.segment<3>(start) *= scale;
    wrench.segment<3>(start) *= scale;
    law.joint_wall_force.segment<3>(start) *= scale;
  }
  law.wall_spring *= safety.force_scale;
  law.wall_damper *= safety.force_scale;
}

// What the torque sent this cycle should do to the end effector, J M^-1 (tau - g), for the
// governor's disturbance observer (gravity is held by the firmware or by the law's g(q)).
void CartesianImpedanceController::expect_acceleration(const RobotState& robot) noexcept {
  Law& law = *law_;
  const MaxSpeedParameters& caps = parameters_.safety.max_speed;
  TaskInertia& inertia = law.inertia_damping.inertia();
  law.expecting = (caps.translation > 0.0 || caps.rotation > 0.0) && inertia.valid();
  if (!law.expecting) return;
  JointVector& torque = law.governor_joint;
  torque = state_.tau;
  if (parameters_.dynamics.gravity_compensation) torque -= robot.gravity;
  inertia.acceleration(torque, law.expected_acceleration);
  law.twist_before = law.twist;
}

// Near the speed cap the sum stops pushing along the motion (from kGovernorBand x cap, all of it
// at the cap), whatever term pushes: the spring, the commanded wrench, a wall, a joint-limit wall,
// the nullspace torque or an uncarried payload's compensation. A push is measured by what it does
// to the motion, through the arm's inertia: the force along the motion that would accelerate the
// end effector along it as much, e^T J M^-1 tau / e^T A e with A = J M^-1 J^T and e the direction
// of the motion as a twist. So a torque about the flange that speeds up its translation through
// the arm's inertia counts, and so does a full damping matrix that turns rotation into
// translation (measured before, with the force along the motion alone: 13 % past the cap). The
// sum with the damping may not carry the end effector past the cap within the cycle either,
// v + dt e^T A e push <= cap: a strong drive on a light arm would otherwise cross the band in one
// cycle. The push is taken from the spring and the wrench where they push (in proportion), and
// the rest is held by a counter-force along the motion with the damping. Beyond the cap (a push
// from outside, or the arm's own momentum) the excess speed is braked out within kBrakeTime,
// never with stiffness. Without M(q) (unit-mass damping and no control loop) a push is its force
// along the motion, and the brake has the law's own damping strength.
void CartesianImpedanceController::govern_speed(const RobotState& robot, const JointMatrix& mass,
                                                double dt) noexcept {
  Law& law = *law_;
  SafetyState& safety = state_.safety;
  const MaxSpeedParameters& caps = parameters_.safety.max_speed;
  Vector6d& spring = law.spring_force;
  Vector6d& wrench = state_.wrench_base;
  const Vector6d payload = safety.payload_mass > 0.0 ? payload_holding_wrench() : Vector6d::Zero();
  TaskInertia& inertia = law.inertia_damping.inertia();
  if (!inertia.valid() && mass.rows() == num_joints_) inertia.compute(robot.jacobian, mass);
  // What accelerated the end effector since the last cycle beyond what the torque sent should
  // have: low-passed over kDisturbanceTime, so that measurement noise does not drive it.
  if (law.expecting) {
    const Vector6d measured = (law.twist - law.twist_before) / dt;
    const double a = std::min(dt / kDisturbanceTime, 1.0);
    law.disturbance = (1.0 - a) * law.disturbance + a * (measured - law.expected_acceleration);
  } else {
    law.disturbance.setZero();
  }
  // What the joint torques besides J^T F do to the end effector: the nullspace torque and the
  // joint-limit walls (their task-space force's change by the caps is among the forces below).
  Vector6d joint_acceleration = Vector6d::Zero();
  if (inertia.valid()) {
    JointVector& torque = law.governor_joint;
    torque = state_.tau_nullspace;
    if (law.joint_walls) torque += robot.joint_wall_torque;
    inertia.acceleration(torque, joint_acceleration);
  }
  // The walls' damper too: it takes energy out along the wall, but a large one turns into a
  // push on the other half through the arm's inertia (measured: a 99 N wall damper spun the wrist
  // past its cap while the governor, which did not count it, believed it was braking).
  Vector6d forces = law.joint_wall_force - law.joint_wall_force_before;
  forces.head<3>() += law.wall_spring;
  Vector6d wall_damper = Vector6d::Zero();
  wall_damper.head<3>() = law.wall_damper;
  // Per half (translation, rotation): the direction of the motion, the force g with which g . F
  // is a force's push, the pushes that do not change (joint torques, payload), and the net push
  // the governor leaves.
  struct Axis {
    bool active = false;
    Eigen::Vector3d direction = Eigen::Vector3d::Zero();
    Vector6d g = Vector6d::Zero();
    double fixed_push = 0.0;
    double target = 0.0;
  };
  Axis axes[2];
  const auto net_push = [&](const Axis& axis) {
    return (spring + wrench + forces + wall_damper + law.damping_force).dot(axis.g) +
           axis.fixed_push;
  };
  for (int half = 0; half < 2; ++half) {
    const int start = 3 * half;
    const double cap = kSpeedCapAim * (half == 0 ? caps.translation : caps.rotation);
    double& drive_scale = half == 0 ? safety.translation_drive_scale : safety.rotation_drive_scale;
    if (!(cap > 0.0)) continue;
    const Eigen::Vector3d velocity = law.twist.segment<3>(start);
    const double speed = velocity.norm();
    if (!(speed > 0.0)) continue;
    Axis& axis = axes[half];
    axis.direction = velocity / speed;
    Vector6d along = Vector6d::Zero();
    along.segment<3>(start) = axis.direction;
    double response = 0.0;  // e^T A e; 0 without M
    axis.g = along;
    if (inertia.valid()) {
      axis.g.noalias() = inertia.inverse() * along;
      response = along.dot(axis.g);
      axis.g /= response;
      axis.fixed_push = along.dot(joint_acceleration) / response;
    } else {
      axis.fixed_push = (law.nullspace_leak + law.joint_wall_force_before).dot(axis.g);
    }
    // With the payload carried its compensation holds the load; without, it pushes too.
    axis.fixed_push += std::max(payload.dot(axis.g), 0.0);
    const double drive_push =
        (spring + wrench + forces).dot(axis.g) + axis.fixed_push;
    const double net = net_push(axis);
    // A disturbance along the motion counts as a push the governor has to hold too (never one
    // against it: the governor does not lean on what it cannot see).
    const double disturbed = std::max(along.dot(law.disturbance), 0.0);
    const double predicted = speed + dt * (response * net + disturbed);
    // The torque-rate limit lets a push fall only so fast, rate = min_i rate_i / |(J^T e)_i| along
    // e: until it is gone the end effector keeps speeding up, by 1/2 push^2 e^T A e / rate. So
    // the push may be at most sqrt(2 rate (cap - v) / e^T A e), from which the rate limit can
    // still take it out before the cap (measured before: a wall's 50 N push, rate-limited on its
    // way out, carried the flange 10 % past the cap).
    double rate = std::numeric_limits<double>::infinity();
    if (response > 0.0) {
      jacobian_transpose_times(robot.jacobian, along, law.governor_joint);
      for (int i = 0; i < num_joints_; ++i) {
        const double lever = std::abs(law.governor_joint[i]);
        if (lever > 0.0) rate = std::min(rate, joint_torque_rate_limit_[i] / lever);
      }
    }
    const double reached =
        response > 0.0 && net > 0.0 ? speed + 0.5 * net * net * response / rate : speed;
    if (std::max(reached, predicted) <= kGovernorBand * cap) continue;
    drive_scale = std::clamp((cap - speed) / ((1.0 - kGovernorBand) * cap), 0.0, 1.0);
    axis.target = net - (1.0 - drive_scale) * std::max(drive_push, 0.0);
    if (response > 0.0) {
      // Below the cap the net push may bring the speed up to it within the cycle, and no faster
      // than the rate limit can take it out again; above it, it must take the excess out within
      // kBrakeTime.
      const double room = cap - speed;
      const double allowed =
          room >= 0.0
              ? std::min(room / (dt * response), std::sqrt(2.0 * rate * room / response))
              : std::min(dt / kBrakeTime, 1.0) * room / (dt * response);
      axis.target = std::min(axis.target, allowed - disturbed / response);
    } else if (speed > cap) {
      // Without M(q): a brake with the law's own damping strength.
      axis.target -= state_.damping.diagonal().segment<3>(start).mean() * (speed - cap);
    }
    axis.active = true;
    safety.braking = safety.braking || speed > cap;
  }
  // A force that holds back one half pushes the other through the arm's inertia (a torque at the
  // flange speeds up its translation): a few rounds, each taking out what is left, bring both to
  // their targets.
  for (int round = 0; round < 3; ++round) {
    for (int half = 0; half < 2; ++half) {
      const Axis& axis = axes[half];
      if (!axis.active) continue;
      const double removed = net_push(axis) - axis.target;
      if (!(removed > 1e-12 * (1.0 + std::abs(axis.target)))) continue;
      const int start = 3 * half;
      // A force along the motion changes the push by itself (g . e = 1); taken from the spring
      // and the wrench where they push, in proportion, the rest held by a counter-force.
      const double spring_pushes = std::max(spring.dot(axis.g), 0.0);
      const double wrench_pushes = std::max(wrench.dot(axis.g), 0.0);
      const double pushes = spring_pushes + wrench_pushes;
      const double from_terms = std::min(removed, pushes);
      if (from_terms > 0.0) {
        spring.segment<3>(start) -= (from_terms * spring_pushes / pushes) * axis.direction;
        wrench.segment<3>(start) -= (from_terms * wrench_pushes / pushes) * axis.direction;
      }
      law.damping_force.segment<3>(start) -= (removed - from_terms) * axis.direction;
    }
  }
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

// At rest the controller's static wrench (spring, walls and the declared payload's compensation;
// the commanded wrench is the user's, not a load) holds up whatever hangs at the flange: its
// upward force is m g, and its torque r x (0, 0, m g) gives the centre of mass across gravity
// (along gravity it has no lever; that component is reported as zero in the base frame). A
// static wrench no hanging load can make (a press down, a sideways force, a twist about the
// vertical) is a contact: the estimate is then not valid.
void CartesianImpedanceController::estimate_payload(double dt) noexcept {
  Law& law = *law_;
  SafetyState& safety = state_.safety;
  const bool still =
      law.twist.head<3>().norm() < kStillSpeed && law.twist.tail<3>().norm() < kStillAngularSpeed;
  if (!still) {
    law.still_for = 0.0;
    safety.payload_estimate_valid = false;
    safety.static_wrench_unexplained = false;
    safety.payload_mismatch = false;
    return;
  }
  Vector6d holding = law.spring_force + payload_holding_wrench();
  holding.head<3>() += law.wall_spring;
  const double weight = holding[2];
  Eigen::Vector3d center_base = Eigen::Vector3d::Zero();
  if (weight > 1e-6) center_base << -holding[4] / weight, holding[3] / weight, 0.0;
  const Eigen::Vector3d center = law.rotation.transpose() * center_base;
  // Averaged over the stillness, restarted when it begins.
  const double a = law.still_for == 0.0 ? 1.0 : std::min(1.0, dt / (0.2 * kPayloadSettleTime));
  safety.payload_estimate_mass =
      (1.0 - a) * safety.payload_estimate_mass + a * std::max(weight, 0.0) / kGravity;
  safety.payload_estimate_center_of_mass =
      (1.0 - a) * safety.payload_estimate_center_of_mass + a * center;
  const double force_tolerance =
      std::max(kUnexplainedForce, kUnexplainedFraction * std::abs(weight));
  const double torque_tolerance =
      std::max(kUnexplainedTorque, kUnexplainedFraction * holding.segment<2>(3).norm());
  const bool unexplained = weight < -force_tolerance ||
                           holding.head<2>().norm() > force_tolerance ||
                           std::abs(holding[5]) > torque_tolerance;
  law.still_for += dt;
  const bool settled = law.still_for >= kPayloadSettleTime;
  safety.static_wrench_unexplained = settled && unexplained;
  safety.payload_estimate_valid = settled && !unexplained;
  const double declared = safety.payload_mass;
  safety.payload_mismatch =
      safety.payload_estimate_valid &&
      std::abs(safety.payload_estimate_mass - declared) >
          kPayloadMismatchMass + kPayloadMismatchFraction * declared;
}

}  // namespace cartesian_impedance
