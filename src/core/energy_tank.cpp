// The energy tank of CartesianImpedanceController (parameters safety.energy_tank.*): every
// run-time change that stores energy in the controller's springs is paid from it, and what the
// damping dissipates fills it. noexcept and allocation-free; the search for the affordable part of
// a change whose energy is not linear in it runs only while the tank holds that change back.

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

// Iterations for the largest affordable part of a change whose stored energy is not linear in it
// (a clip, a box): enough for the Illinois method to find it to round-off on any change in range.
constexpr int kMaxIterations = 60;

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
  // The stored energy is linear in K: the change's cost is the energy of dK alone.
  const double cost = spring_energy(error, stiffness - before, clip);
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
  safety.tank_level = std::min(safety.tank_level - cost, parameters_.safety.energy_tank.capacity);
}

// The nullspace spring stores 1/2 e^T K_ns e, e = q - q_d: a raise of K_ns while the joints are
// away from their target is paid like a raise of K (from the target before this cycle's step).
void CartesianImpedanceController::pay_nullspace_stiffness_change(
    const RobotState& robot) noexcept {
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
  safety.tank_level = std::min(safety.tank_level - cost, parameters_.safety.energy_tank.capacity);
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
  safety.tank_level =
      std::clamp(safety.tank_level - paid, 0.0, parameters_.safety.energy_tank.capacity);
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
  const double s =
      cost(1.0) <= safety.tank_level ? 1.0 : largest_affordable(safety.tank_level, cost);
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
  safety.tank_level =
      std::clamp(safety.tank_level - paid, 0.0, parameters_.safety.energy_tank.capacity);
  law_->wall_energy = std::max(law_->wall_energy + paid, 0.0);
}

// The fraction of the Cartesian and of the nullspace damping the torque sent carried: a term the
// torque shaping scaled counts scaled, and a cycle whose torque was clamped or rate-limited counts
// nothing (its damping was not what the law computed).
Eigen::Vector2d CartesianImpedanceController::damping_sent(bool clamped,
                                                           bool rate_limited) const noexcept {
  const ActiveLimits& limits = state_.limits;
  if (clamped || rate_limited) return Eigen::Vector2d::Zero();
  switch (limits.torque_shaping) {
    case TorqueShaping::none:
      return Eigen::Vector2d::Ones();
    case TorqueShaping::nullspace:
      return {1.0, limits.torque_shaping_scale};
    case TorqueShaping::spring:
    case TorqueShaping::wrench:
    case TorqueShaping::payload:
      return {1.0, 0.0};
    case TorqueShaping::damping:
      return {limits.torque_shaping_scale, 0.0};
    case TorqueShaping::gravity:
      break;
  }
  return Eigen::Vector2d::Zero();
}

// What the damping dissipated this cycle fills the tank, as far as the torque sent carried it
// (counting a clamped or rate-limited cycle would let the tank pay out energy the arm never lost:
// measured 0.3 mJ per cycle against a stiff wall on a weak arm).
void CartesianImpedanceController::fill_tank() noexcept {
  Law& law = *law_;
  const EnergyTankParameters& tank = parameters_.safety.energy_tank;
  const double cartesian = std::max(law.dissipated_cartesian, 0.0);
  const double nullspace = std::max(law.dissipated_nullspace, 0.0);
  law.dissipated_cartesian = law.dissipated_nullspace = 0.0;
  if (!tank.enabled || scheduled_) return;
  const Eigen::Vector2d sent = damping_sent(law.torque_clamped, state_.limits.torque_rate_limited);
  const double energy = sent[0] * cartesian + sent[1] * nullspace;
  SafetyState& safety = state_.safety;
  safety.tank_level = std::min(safety.tank_level + energy, tank.capacity);
}

}  // namespace cartesian_impedance
