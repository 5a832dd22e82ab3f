// The oscillation watch (CartesianImpedanceController::kOscillationSwings): a sustained swing of
// the end effector's error rate halves the stiffness the law is given, until the loop is stable
// or the stiffness is gone, when the controller fails closed.
//
// Why the error rate and not the joint velocities: a commanded motion (a trajectory, a streamed
// reference moving back and forth) swings the joints as much as a limit cycle does, but not the
// difference between the end effector's velocity and the reference's. Why halving the stiffness:
// a delay of tau turns the spring's force K x(t - tau) into negative damping of about K tau, and
// the phase lost at the loop's frequency grows with that frequency; a softer spring lowers both,
// with the damping following it (by its ratio), so the arm keeps its damping ratio, not its
// stiffness. Damping added instead would act on the same late measurement.

#include <algorithm>
#include <cmath>

#include "law.hpp"

namespace cartesian_impedance {

void CartesianImpedanceController::forget_oscillation() noexcept {
  Law& law = *law_;
  law.swing_side.fill(0);
  law.swings.fill(0);
  law.swing_peak.fill(0.0);
  law.swing_peak_before.fill(0.0);
}

// After spring_damper() (law.twist is J dq of the cycle) and the filter step (reference_before).
void CartesianImpedanceController::watch_oscillation(double dt) noexcept {
  Law& law = *law_;
  const Targets& filtered = state_.filtered;
  // The reference's own velocity: what the filter moved it by this cycle, plus a tracked
  // reference's feed-forward twist.
  // (Both orientations are unit quaternions: the conjugate is the inverse. Twice the vector part
  // of the shorter turn is its rotation vector to third order, per cycle a tiny angle.)
  const double per_second = 1.0 / dt;
  Vector6d rate = law.twist - filtered.twist;
  rate.head<3>() -= per_second * (filtered.pose.position - law.reference_before.position);
  const Eigen::Quaterniond turn =
      filtered.pose.orientation * law.reference_before.orientation.conjugate();
  rate.tail<3>() -= std::copysign(2.0 * per_second, turn.w()) * turn.vec();
  bool oscillating = false;
  for (int axis = 0; axis < 6; ++axis) {
    const auto c = static_cast<std::size_t>(axis);
    const double threshold = axis < 3 ? kOscillationSpeed : kOscillationAngularSpeed;
    int& side = law.swing_side[c];
    if (side != 0 && time_ - law.swing_began[c] > kOscillationHalfPeriod) {
      side = 0;  // a slow motion, not a swing: start counting anew
      law.swings[c] = 0;
      law.swing_peak_before[c] = 0.0;
    }
    const double magnitude = std::abs(rate[axis]);
    if (!(magnitude > threshold)) continue;
    const int now = rate[axis] > 0.0 ? 1 : -1;
    if (now == side) {
      law.swing_peak[c] = std::max(law.swing_peak[c], magnitude);
      continue;
    }
    if (side != 0) {  // the swing ended: count it if it did not decay
      const bool sustained = law.swing_peak[c] >= kOscillationSustain * law.swing_peak_before[c];
      law.swings[c] = sustained ? law.swings[c] + 1 : 1;
      law.swing_peak_before[c] = law.swing_peak[c];
      oscillating = oscillating || law.swings[c] >= kOscillationSwings;
    }
    side = now;
    law.swing_peak[c] = magnitude;
    law.swing_began[c] = time_;
  }
  if (!oscillating) return;
  // Where the passivity observer names the springs that pump the oscillation, only they are
  // halved; the others keep their stiffness.
  bool halved = false;
  if (parameters_.safety.passivity.threshold > 0.0 && law.generated.maxCoeff() > 0.0) {
    ++state_.safety.oscillations;
    halved = halve_generating_springs();
  } else {
    halved = halve_stiffness();
  }
  if (!halved) halt_oscillating();
}

void CartesianImpedanceController::halt_oscillating() noexcept {
  halted_ = true;
  halted_oscillating_ = true;
  at_rest_for_ = 0.0;
  halted_for_ = 0.0;
}

bool CartesianImpedanceController::halve_stiffness() noexcept {
  forget_oscillation();
  SafetyState& safety = state_.safety;
  ++safety.oscillations;
  // The floor bounds what any spring keeps, the passivity controller's halvings included.
  const double least = safety.oscillation_scale * safety.passivity_scale.minCoeff();
  if (!(least * 0.5 >= kOscillationFloor)) return false;
  safety.oscillation_scale *= 0.5;
  return true;
}

}  // namespace cartesian_impedance
