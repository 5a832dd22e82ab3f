#include <algorithm>
#include <cmath>

#include "scenario_support.hpp"

namespace cartesian_impedance::scenarios::detail {

void set_mutation(sim::ClosedLoopRunner& runner, Mutation mutation) {
  switch (mutation) {
    case Mutation::none:
      runner.set_torque_hook({});
      break;
    case Mutation::zero_torque:
      runner.set_torque_hook([](JointVector& tau) { tau.setZero(); });
      break;
    case Mutation::flipped_sign:
      runner.set_torque_hook([](JointVector& tau) { tau = -tau; });
      break;
  }
}

Vector6d six(double a, double b, double c, double d, double e, double f) {
  return (Vector6d() << a, b, c, d, e, f).finished();
}

Result compare(const std::string& scenario, const std::string& quantity, double expected,
               double measured, const std::string& unit, double tolerance,
               const std::string& note) {
  Result result{scenario, quantity, expected, measured, unit, tolerance, false, false, note};
  result.passed = std::abs(measured - expected) <= tolerance;
  return result;
}

Result at_most(const std::string& scenario, const std::string& quantity, double bound,
               double measured, const std::string& unit, const std::string& note) {
  Result result{scenario, quantity, bound, measured, unit, 0.0, true, false, note};
  result.passed = measured <= bound;
  return result;
}

Result at_least(const std::string& scenario, const std::string& quantity, double bound,
                double measured, const std::string& unit, const std::string& note) {
  Result result{scenario, quantity, bound, measured, unit, 0.0, false, false, note};
  result.passed = measured >= bound;
  result.note = note.empty() ? "at least" : note;
  return result;
}

Eigen::Vector3d rotation_between(const Pose& from, const Pose& to) {
  return orientation_error(to.orientation, from.orientation);
}

void notify(const MomentCallback& moment, const std::string& label, Rig& rig) {
  if (moment) moment(label, rig.sim());
}

// The largest force and torque at the flange that the joints' Coulomb friction can hold at q:
// a spring pulling with less may leave the arm standing short of its rest position. A friction
// torque tau_f (|tau_f,i| <= f_i) holds the flange wrench F = (J J^T)^-1 J tau_f; the largest
// norms are at corners of the box of friction torques.
FrictionBand friction_band(Rig& rig) {
  ModelWorkspace workspace(rig.model());
  Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(rig.sim().q(), rig.sim().dq(), kinematics);
  const Eigen::MatrixXd jacobian = kinematics.jacobian;
  const Eigen::MatrixXd map = (jacobian * jacobian.transpose()).ldlt().solve(jacobian);
  const JointVector friction = rig.sim().friction_loss();
  const int n = static_cast<int>(friction.size());
  FrictionBand band;
  for (long corner = 0; corner < (1L << n); ++corner) {
    Eigen::VectorXd tau(n);
    for (int i = 0; i < n; ++i) tau[i] = (corner >> i & 1) ? friction[i] : -friction[i];
    const Vector6d wrench = map * tau;
    band.force = std::max(band.force, wrench.head<3>().norm());
    band.torque = std::max(band.torque, wrench.tail<3>().norm());
  }
  return band;
}

}  // namespace cartesian_impedance::scenarios::detail
