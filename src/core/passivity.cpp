// The passivity observer and controller of CartesianImpedanceController (safety.passivity.*;
// time-domain passivity, Hannaford and Ryu): the energy the controller generates on its port to
// the arm, and the halving of the springs that generate it.
//
// What the port takes in is tau(k - d) . dq(k): the torque sent d cycles ago (d =
// safety.passivity.delay) is the one acting while the velocity dq(k) was measured. The same
// controller without the delay would have put in tau(k) . dq(k), whose dissipative part (the
// damper's, as far as the torque sent carried it) takes energy out and whose rest (the springs',
// the walls', what the limits made of them) is what the controller may exchange with the arm.
// So the energy generated is the sum of tau(k - d) . dq(k) - (tau(k) - tau_damper(k)) . dq(k):
// without a delay it is the damper's dissipation, never positive, whatever the caps, clips and
// limits did to the springs (they act on both terms alike); behind a delay a spring pushes with
// where the arm was, K (q(k) - q(k - d)) . dq(k), about K tau |dq|^2: a negative damping, and
// the sum says whether the damper outweighs it. No stored energy enters it, so no model of what
// the limits did to the springs can be wrong. (Velocity noise does not bias it: tau(k - d) is
// older than the noise of dq(k), and the damper's response to that noise cancels between the
// terms.) The torque is split into the springs' ports by the force it presses with at the end
// effector, F = (J J^T)^-1 J tau: F_t . v and F_r . w are the translation's and the rotation's,
// the rest the nullspace's; the three add up to the whole.
//
// Why halving the stiffness and not the damping Hannaford and Ryu add: a damper acting on a late
// measurement pumps energy in as soon as the loop's frequency lags it by a quarter period
// (measured on the realistic Panda behind 20 ms: a damping passivity controller drove the
// oscillation on until the controller failed closed), while a softer spring lowers the loop's
// frequency and with it the phase the delay takes, with the damping following it by its ratio.
// Why a window: the dissipation of a past motion would otherwise hide the generation of a limit
// cycle for as long as it lasts.

#include <algorithm>
#include <cmath>

#include "law.hpp"

namespace cartesian_impedance {

void CartesianImpedanceController::forget_passivity() noexcept {
  Law& law = *law_;
  law.sent_count = 0;
  law.generated.setZero();
  law.generated_sum = 0.0;
  law.passivity_wait = 0.0;
  state_.safety.generated_energy = 0.0;
}

// After the torque limits: the energy of the port is updated with the torque sent d cycles ago,
// and this cycle's joins the ring.
void CartesianImpedanceController::observe_passivity(const RobotState& robot, double dt) noexcept {
  Law& law = *law_;
  const PassivityParameters& passivity = parameters_.safety.passivity;
  const int delay =
      std::clamp(static_cast<int>(std::lround(passivity.delay / dt)), 0, kPassivityRing - 1);
  JointVector& now = law.torque_sent[static_cast<std::size_t>(law.sent_next)];
  now = state_.tau - state_.tau_gravity - state_.tau_wrench;
  if (law.sent_count >= delay) {
    const JointVector& acted = law.torque_sent[static_cast<std::size_t>(
        (law.sent_next + kPassivityRing - delay) % kPassivityRing)];
    // tau(k - d) - tau(k), by the springs' ports, and the damper's power.
    law.governor_joint = acted - now;
    Vector6d force;
    law.projector.task_force(robot.jacobian, parameters_.nullspace.pseudo_inverse_damping,
                             law.governor_joint, force);
    const double translation = force.head<3>().dot(law.twist.head<3>());
    const double rotation = force.tail<3>().dot(law.twist.tail<3>());
    // The damper's power as far as the torque sent carried it: none on a cycle the clamp or the
    // rate limit cut, whose torque lags the law's (a limit cycle the rate limit feeds is sent
    // little of its damping, and counting it would hide the cycle).
    const Eigen::Vector2d damper =
        damping_sent(law.torque_clamped, state_.limits.torque_rate_limited)[0] * law.damper_power;
    const Eigen::Vector3d step =
        dt * Eigen::Vector3d(translation + damper[0], rotation + damper[1],
                             law.governor_joint.dot(robot.dq) - translation - rotation);
    const double keep = 1.0 - dt / kPassivityWindow;
    law.generated = keep * law.generated + step;
    law.generated_sum = keep * law.generated_sum + step.sum();
    if (law.passivity_wait > 0.0) {
      law.passivity_wait -= dt;
      law.generated.setZero();
      law.generated_sum = 0.0;
    } else if (passivity.threshold > 0.0 && law.generated_sum > passivity.threshold) {
      ++state_.safety.passivity_halvings;
      if (halve_generating_springs()) {
        law.passivity_wait = kPassivitySettle + delay * dt;
      } else {
        halt_oscillating();
      }
    }
    state_.safety.generated_energy = law.generated_sum;
  }
  law.sent_next = (law.sent_next + 1) % kPassivityRing;
  law.sent_count = std::min(law.sent_count + 1, kPassivityRing);
}

bool CartesianImpedanceController::halve_generating_springs() noexcept {
  Law& law = *law_;
  SafetyState& safety = state_.safety;
  // The springs that generated at least half of what the most generating one did; all of them
  // where none generated (an oscillation the observer did not see).
  const double most = law.generated.maxCoeff();
  Eigen::Vector3d halve = Eigen::Vector3d::Ones();
  if (most > 0.0) halve = (law.generated.array() >= 0.5 * most).cast<double>();
  const Eigen::Vector3d scale =
      safety.passivity_scale.cwiseProduct((Eigen::Vector3d::Ones() - 0.5 * halve).eval());
  law.generated.setZero();
  law.generated_sum = 0.0;
  // The oscillation watch counts the halved loop's swings anew.
  forget_oscillation();
  if (!(scale.minCoeff() * safety.oscillation_scale >= kOscillationFloor)) return false;
  // The springs let go at once (which releases energy; the rate limit smooths the torque), not
  // through the stiffness filter, so that the observer sees the halved loop when it looks again.
  const Eigen::Vector3d step = scale.cwiseQuotient(safety.passivity_scale);
  safety.passivity_scale = scale;
  Targets& filtered = state_.filtered;
  scale_stiffness_groups(filtered.stiffness, step);
  filtered.nullspace_stiffness *= step[2];
  return true;
}

// K's translation and rotation blocks by scale[0] and scale[1] (S K S, S = diag(sqrt(scale[0]) I,
// sqrt(scale[1]) I), which keeps K symmetric and positive definite).
void CartesianImpedanceController::scale_stiffness_groups(
    Matrix6d& stiffness, const Eigen::Vector3d& scale) const noexcept {
  if (scale[0] == 1.0 && scale[1] == 1.0) return;
  if (stiffness_diagonal_) {
    stiffness.diagonal().head<3>() *= scale[0];
    stiffness.diagonal().tail<3>() *= scale[1];
    return;
  }
  Vector6d root;
  root << Eigen::Vector3d::Constant(std::sqrt(scale[0])),
      Eigen::Vector3d::Constant(std::sqrt(scale[1]));
  stiffness = root.asDiagonal() * stiffness * root.asDiagonal();
}

}  // namespace cartesian_impedance
