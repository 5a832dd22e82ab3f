#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <sstream>

#include "scenario_support.hpp"

namespace cartesian_impedance::scenarios::detail {

void set_mutation(sim::ClosedLoopRunner& runner, Mutation mutation) {
  switch (mutation) {
    case Mutation::none:
    case Mutation::no_energy_tank:
    case Mutation::no_speed_cap:  // parameters, not the torque: the Rig or the scenario sets them
    case Mutation::no_force_cap:
    case Mutation::no_workspace:
    case Mutation::no_payload:
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

void notify(const MomentCallback& moment, const std::string& label, Rig& rig,
            const std::vector<std::string>& details) {
  rig.moment(moment, label, details);
}

std::string format(const char* format, ...) {
  char text[256];
  va_list arguments;
  va_start(arguments, format);
  std::vsnprintf(text, sizeof(text), format, arguments);
  va_end(arguments);
  return text;
}

// The largest force and torque at the flange that the joints' Coulomb friction can hold at q:
// a spring pulling with less may leave the arm standing short of its rest position. A friction
// torque tau_f (|tau_f,i| <= f_i) holds the flange wrench F = (J J^T)^-1 J tau_f; the largest
// norms are at corners of the box of friction torques.
double linear_overshoot(Rig& rig, const Vector6d& x0, const Vector6d& direction) {
  ModelWorkspace workspace(rig.model());
  Kinematics kinematics = workspace.make_kinematics();
  const int n = rig.model().num_joints();
  if (!workspace.compute(rig.sim().true_q(), JointVector::Zero(n), kinematics, ModelTerms::all)) {
    return 0.0;
  }
  const Parameters parameters = rig.loop().latest_parameters();
  const JointVector& armature = parameters.dynamics.armature;
  Eigen::MatrixXd mass = kinematics.mass;
  for (int i = 0; i < n; ++i) mass(i, i) += armature.size() == 1 ? armature[0] : armature[i];
  const Matrix6d inverse_inertia =
      kinematics.jacobian * mass.llt().solve(kinematics.jacobian.transpose());
  const ControllerState& state = rig.loop().latest_state().controller;
  const Matrix6d stiffness = state.stiffness_base(), damping = state.damping_base();
  // RK4 at 0.1 ms: the stiffest mode of the shipped and generated arms is below 400 rad/s.
  constexpr double dt = 1e-4;
  Vector6d x = x0, v = Vector6d::Zero();
  const auto acceleration = [&](const Vector6d& p, const Vector6d& w) -> Vector6d {
    return -inverse_inertia * (damping * w + stiffness * p);
  };
  double largest = direction.dot(x);
  for (int k = 0; k < 40000; ++k) {
    const Vector6d a1 = acceleration(x, v);
    const Vector6d a2 = acceleration(x + 0.5 * dt * v, v + 0.5 * dt * a1);
    const Vector6d a3 = acceleration(x + 0.5 * dt * (v + 0.5 * dt * a1), v + 0.5 * dt * a2);
    const Vector6d a4 = acceleration(x + dt * (v + 0.5 * dt * a2), v + dt * a3);
    x += dt * v + dt * dt / 6.0 * (a1 + a2 + a3);
    v += dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
    largest = std::max(largest, direction.dot(x));
  }
  return x.allFinite() ? largest : 0.0;
}

FrictionBand friction_band(Rig& rig) {
  const Eigen::MatrixXd jacobian = jacobian_now(rig);
  // The least-norm wrench with J^T F = tau: (J J^T)^-1 J for a full-rank J, and still defined
  // for a chain that controls fewer than six directions.
  const Eigen::MatrixXd map =
      Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(jacobian.transpose()).pseudoInverse();
  const JointVector friction = rig.sim().friction_loss();
  const int n = static_cast<int>(friction.size());
  FrictionBand band;
  for (long corner = 0; corner < (1L << n); ++corner) {
    Eigen::VectorXd tau(n);
    for (int i = 0; i < n; ++i) tau[i] = (corner >> i & 1) ? friction[i] : -friction[i];
    const Vector6d wrench = map * tau;
    band.force = std::max(band.force, wrench.head<3>().norm());
    band.force_along = band.force_along.cwiseMax(wrench.head<3>().cwiseAbs());
    band.torque = std::max(band.torque, wrench.tail<3>().norm());
  }
  return band;
}

// The nullspace torque's projector uses a damped pseudo-inverse
// (nullspace.pseudo_inverse_damping), so on an arm with no nullspace (or where the Jacobian
// is poorly conditioned) part of tau_0 = K_ns (q_ns - q) reaches the flange. It is small
// (about 0.1 % of a 1 kg payload's weight on a 6-joint arm whose sag moved q off q_ns) and hidden
// in the friction band on arms with friction; a frictionless arm measures it.
Vector6d nullspace_wrench(Rig& rig) {
  const Eigen::MatrixXd map =
      Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(jacobian_now(rig).transpose())
          .pseudoInverse();
  return map * rig.loop().state().controller.tau_nullspace;
}

std::string flange_without_geometry(Rig& rig, const RobotSetup& robot) {
  const std::string& tip = robot.tip_link;
  if (rig.sim().has_collision_geometry(tip)) return "";
  return "the flange ('" + tip +
         "') and the links welded to it have no collision geometry: nothing can press on it "
         "(give its URDF link a <collision>)";
}

Eigen::MatrixXd jacobian_now(Rig& rig) {
  ModelWorkspace workspace(rig.model());
  Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(rig.sim().true_q(), rig.sim().true_dq(), kinematics);
  return kinematics.jacobian;
}

Result not_applicable(const std::string& scenario, const std::string& quantity,
                      const std::string& reason) {
  Result result{scenario, quantity, 0.0, 0.0, "", 0.0, false, false, "not applicable: " + reason};
  result.applicable = false;
  return result;
}

Capacity capacity(Rig& rig) {
  Capacity result;
  const RobotModel& model = rig.model();
  const int n = model.num_joints();
  ModelWorkspace workspace(model);
  Kinematics kinematics = workspace.make_kinematics();
  result.q = rig.sim().true_q();
  workspace.compute(result.q, JointVector::Zero(n), kinematics, true);
  result.reach = kinematics.pose.position.norm();
  result.jacobian = kinematics.jacobian;
  // An empty limits.joint_torque means the URDF's efforts.
  const JointVector limit = model.limits().effort.cwiseMin(
      per_joint(rig.loop().controller().parameters().limits.joint_torque, n, kForever));
  result.torque_left = (limit - kinematics.gravity.cwiseAbs()).cwiseMax(0.0);
  result.lower = model.limits().position_lower;
  result.upper = model.limits().position_upper;
  return result;
}

namespace {
double largest_along(const Capacity& capacity, const Vector6d& wrench) {
  const Eigen::VectorXd torque = capacity.jacobian.transpose() * wrench;
  double largest = kForever;
  for (int i = 0; i < torque.size(); ++i) {
    if (std::abs(torque[i]) > 1e-12) {
      largest = std::min(largest, capacity.torque_left[i] / std::abs(torque[i]));
    }
  }
  return largest;
}
}  // namespace

double Capacity::force_along(const Eigen::Vector3d& direction) const {
  Vector6d wrench = Vector6d::Zero();
  wrench.head<3>() = direction.normalized();
  return largest_along(*this, wrench);
}

double Capacity::torque_about(const Eigen::Vector3d& axis) const {
  Vector6d wrench = Vector6d::Zero();
  wrench.tail<3>() = axis.normalized();
  return largest_along(*this, wrench);
}

double Capacity::fraction_within_limits(const Vector6d& twist, double margin) const {
  const Eigen::VectorXd dq =
      Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(jacobian).solve(twist);
  for (double fraction = 1.0; fraction >= 0.125; fraction *= 0.5) {
    const JointVector goal = q + fraction * dq;
    if (((goal - lower).array() >= margin).all() && ((upper - goal).array() >= margin).all()) {
      return fraction;
    }
  }
  return 0.0;
}

double fitted_load(double tuned, double capacity, double stiffness, double travel) {
  double load = std::min(tuned, kLoadShare * capacity);
  if (stiffness > 0.0) load = std::min(load, stiffness * travel);
  return load;
}

std::string load_note(double tuned, double used, const char* unit) {
  if (used >= tuned) return "";
  return format(
      "%.3g %s instead of the tuned %.3g %s: at most %.0f %% of what the joints hold, "
      "and a spring travel of a few cm",
      used, unit, tuned, unit, 100.0 * kLoadShare);
}

namespace {
const char* const kDirectionNames[6] = {
    "x", "y", "z", "rotation about x", "rotation about y", "rotation about z"};
}  // namespace

std::string TaskDirections::describe() const {
  std::string text;
  for (int i = 0; i < 6; ++i) {
    if (controlled[i]) text += (text.empty() ? "" : ", ") + std::string(kDirectionNames[i]);
  }
  return text.empty() ? "nothing" : text;
}

int TaskDirections::first_of(std::initializer_list<int> preferred) const {
  for (int i : preferred) {
    if (controlled[static_cast<std::size_t>(i)]) return i;
  }
  return -1;
}

TaskDirections task_directions(Rig& rig) {
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(jacobian_now(rig), Eigen::ComputeFullU);
  const Eigen::VectorXd& sigma = svd.singularValues();
  // Rank relative to the largest singular value: an upright arm's lost direction leaves a value
  // of about 1e-17, a well-conditioned one none below 1e-2.
  int rank = 0;
  while (rank < sigma.size() && sigma[rank] > 1e-6 * sigma[0]) ++rank;
  const Eigen::MatrixXd range = svd.matrixU().leftCols(rank);
  TaskDirections directions;
  for (int i = 0; i < 6; ++i) {
    // The part of the unit direction the flange can move in; 1 if wholly, 0 if not at all.
    directions.controlled[static_cast<std::size_t>(i)] = range.row(i).squaredNorm() > 0.999;
    directions.dimension += directions.controlled[static_cast<std::size_t>(i)] ? 1 : 0;
  }
  directions.redundancy = rig.model().num_joints() - rank;
  return directions;
}

namespace {
// "300 0 300": Eigen's default aligns columns, which pads with spaces.
const Eigen::IOFormat kOneLine(Eigen::StreamPrecision, Eigen::DontAlignCols, " ", " ");

void compare_three(const std::string& name, const Eigen::Vector3d& configured,
                   const Eigen::Vector3d& used, const char* unit, std::vector<std::string>& out) {
  if (configured == used) return;
  std::ostringstream text;
  text << name << " = " << used.transpose().format(kOneLine) << " " << unit
       << " (configured: " << configured.transpose().format(kOneLine) << ")";
  out.push_back(text.str());
}
}  // namespace

std::vector<std::string> overrides(const RobotSetup& robot, const Parameters& used) {
  const Parameters configured = base_parameters(robot);
  std::vector<std::string> out;
  compare_three("stiffness.translation", configured.stiffness.translation,
                used.stiffness.translation, "N/m", out);
  compare_three("stiffness.rotation", configured.stiffness.rotation, used.stiffness.rotation,
                "Nm/rad", out);
  compare_three("damping_ratio.translation", configured.damping_ratio.translation,
                used.damping_ratio.translation, "", out);
  compare_three("damping_ratio.rotation", configured.damping_ratio.rotation,
                used.damping_ratio.rotation, "", out);
  if (configured.nullspace.stiffness != used.nullspace.stiffness) {
    std::ostringstream text;
    text << "nullspace.stiffness = " << used.nullspace.stiffness.transpose().format(kOneLine)
         << " Nm/rad (configured: " << configured.nullspace.stiffness.transpose().format(kOneLine)
         << ")";
    out.push_back(text.str());
  }
  if (configured.filter.nullspace.time != used.filter.nullspace.time) {
    out.push_back("filter.nullspace.time = " + std::to_string(used.filter.nullspace.time) +
                  " s (configured: " + std::to_string(configured.filter.nullspace.time) + ")");
  }
  if (configured.trajectory.goal_tolerance != used.trajectory.goal_tolerance) {
    out.push_back(
        format("trajectory.goal_tolerance = %.3g rad (configured: %.3g): what the "
               "joints' friction holds against the springs, twice",
               used.trajectory.goal_tolerance, configured.trajectory.goal_tolerance));
  }
  if (configured.filter.pose.time != used.filter.pose.time) {
    out.push_back("filter.pose.time = " + std::to_string(used.filter.pose.time) +
                  " s (configured: " + std::to_string(configured.filter.pose.time) + ")");
  }
  return out;
}

void set_stiffness_within_limits(Parameters& parameters, double translation, double rotation,
                                 double nullspace) {
  const LimitParameters& limits = parameters.limits;
  parameters.stiffness.translation.setConstant(
      std::min(translation, limits.stiffness.translation.max));
  parameters.stiffness.rotation.setConstant(std::min(rotation, limits.stiffness.rotation.max));
  parameters.nullspace.stiffness =
      JointVector::Constant(1, std::min(nullspace, limits.nullspace_stiffness.max));
}

// Steps the rig one cycle at a time for `seconds`, calling `each` after every cycle with the
// flange's speed over that cycle [m/s] (ground truth, from the simulation's poses).
void run_measured(Rig& rig, double seconds, const std::function<void(double speed)>& each) {
  Eigen::Vector3d previous = rig.flange().position;
  const int steps = static_cast<int>(std::lround(seconds / kDt));
  for (int k = 0; k < steps; ++k) {
    rig.run(kDt);
    const Eigen::Vector3d now = rig.flange().position;
    each((now - previous).norm() / kDt);
    previous = now;
  }
}

Kinematics simulated_arm(Rig& rig) {
  ModelWorkspace workspace(rig.model());
  Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(rig.sim().true_q(), rig.sim().true_dq(), kinematics, true);
  kinematics.mass.diagonal() += rig.sim().armature();
  return kinematics;
}

namespace {

// The law's damping in joint space now, C = J^T D J + D_ns (the nullspace damping, or its
// minimum), what acts on the readings' velocity noise.
Eigen::MatrixXd joint_damping(Rig& rig, const Eigen::MatrixXd& jacobian) {
  const ControllerState& state = rig.loop().state().controller;
  const Parameters& parameters = rig.loop().controller().parameters();
  Eigen::MatrixXd damping = jacobian.transpose() * state.damping_base() * jacobian;
  const JointVector& k_ns = state.filtered.nullspace_stiffness;
  for (int j = 0; j < damping.rows(); ++j) {
    damping(j, j) += std::max(2.0 * state.filtered.nullspace_damping_ratio * std::sqrt(k_ns[j]),
                              parameters.minimum_damping.nullspace);
  }
  return damping;
}

// Per joint j of the rig now: the standard deviation sigma_j of the noise torque per step (torque
// noise and the damping on the velocity noise), the mass m_j and the damping c_jj; empty on a
// plant without either noise.
struct NoiseDrive {
  std::vector<double> sigma, mass, damping;
};

NoiseDrive noise_drive(Rig& rig, const sim::PlantOptions& plant) {
  NoiseDrive drive;
  if (!(plant.torque_noise > 0.0) && !(plant.velocity_noise > 0.0)) return drive;
  const Kinematics kinematics = simulated_arm(rig);
  const JointMatrix& mass = kinematics.mass;
  const Eigen::MatrixXd damping = joint_damping(rig, kinematics.jacobian);
  for (int j = 0; j < damping.rows(); ++j) {
    drive.sigma.push_back(
        std::sqrt(plant.torque_noise * plant.torque_noise +
                  plant.velocity_noise * plant.velocity_noise * damping.row(j).squaredNorm()));
    drive.mass.push_back(mass(j, j));
    drive.damping.push_back(damping(j, j));
  }
  return drive;
}

}  // namespace

double noise_speed(Rig& rig, const sim::PlantOptions& plant) {
  const NoiseDrive drive = noise_drive(rig, plant);
  double largest = 0.0;
  for (std::size_t j = 0; j < drive.sigma.size(); ++j) {
    if (!(drive.damping[j] > 0.0)) continue;
    largest = std::max(largest,
                       drive.sigma[j] * std::sqrt(kDt / (2.0 * drive.mass[j] * drive.damping[j])));
  }
  return largest;
}

double noise_power(Rig& rig, const sim::PlantOptions& plant) {
  const NoiseDrive drive = noise_drive(rig, plant);
  double power = 0.0;
  for (std::size_t j = 0; j < drive.sigma.size(); ++j) {
    power += drive.sigma[j] * drive.sigma[j] * kDt / (2.0 * drive.mass[j]);
  }
  return power;
}

double noise_rate_limited_cycles(Rig& rig, const sim::PlantOptions& plant) {
  if (!(plant.velocity_noise > 0.0) && !(plant.position_noise > 0.0)) return 0.0;
  const Kinematics kinematics = simulated_arm(rig);
  const Eigen::MatrixXd& jacobian = kinematics.jacobian;
  const Parameters& parameters = rig.loop().controller().parameters();
  const Eigen::MatrixXd damping = joint_damping(rig, jacobian);
  const Eigen::MatrixXd spring =
      jacobian.transpose() * rig.loop().state().controller.stiffness_base() * jacobian;
  const JointVector rate =
      per_joint(parameters.limits.joint_torque_rate, static_cast<int>(damping.rows()));
  double cycles = 0.0;
  for (int j = 0; j < damping.rows(); ++j) {
    const double sigma = std::sqrt(
        2.0 * (plant.velocity_noise * plant.velocity_noise * damping.row(j).squaredNorm() +
               plant.position_noise * plant.position_noise * spring.row(j).squaredNorm()));
    if (sigma > 0.0) cycles += std::erfc(rate[j] * kDt / (std::sqrt(2.0) * sigma)) / kDt;
  }
  return cycles;
}

// The largest mass a force along `direction` at the flange can meet: every other direction of
// the flange held (a flat face stuck on a surface), d^T (J M^-1 J^T)^+ d over the six task
// directions, M with the simulated rotors' inertia.
double mass_along(Rig& rig, const Eigen::Vector3d& direction) {
  const Kinematics kinematics = simulated_arm(rig);
  const JointMatrix& mass = kinematics.mass;
  const Eigen::MatrixXd& jacobian = kinematics.jacobian;
  const Eigen::MatrixXd mobility = jacobian * mass.ldlt().solve(jacobian.transpose());
  const Eigen::MatrixXd inertia =
      Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(mobility).pseudoInverse();
  return direction.dot(inertia.topLeftCorner<3, 3>() * direction);
}

// The joint positions that reach the pose `target` from q by a few Gauss-Newton steps (J^+ e)
// with every joint `margin` inside its limits on the way, if they do.
std::optional<JointVector> reach(const RobotModel& model, JointVector q, const Pose& target,
                                 double margin) {
  ModelWorkspace workspace(model);
  Kinematics kinematics = workspace.make_kinematics();
  const JointLimits& limits = model.limits();
  for (int iteration = 0; iteration < 30; ++iteration) {
    workspace.compute(q, JointVector::Zero(q.size()), kinematics);
    Vector6d error;
    error << target.position - kinematics.pose.position,
        orientation_error(target.orientation, kinematics.pose.orientation);
    if (error.head<3>().norm() < 1e-4 && error.tail<3>().norm() < 1e-3) return q;
    q += Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(kinematics.jacobian).solve(error);
    if (((q - limits.position_lower).array() < margin).any() ||
        ((limits.position_upper - q).array() < margin).any()) {
      return std::nullopt;
    }
  }
  return std::nullopt;
}

Move reachable_move(Rig& rig, double longest) {
  const TaskDirections directions = task_directions(rig);
  const Pose start = rig.flange();
  for (double length = longest; length >= longest / 8.0; length *= 0.5) {
    for (const int axis : {1, 0, 2}) {
      if (!directions.controlled[static_cast<std::size_t>(axis)]) continue;
      // Toward the base first: outward an arm runs out of reach before its joints' limits.
      const double inward = start.position[axis] > 1e-3 ? -1.0 : 1.0;
      for (const double sense : {inward, -inward}) {
        Pose target = start;
        target.position[axis] += sense * length;
        if (const auto goal = reach(rig.model(), rig.sim().true_q(), target, 0.1)) {
          return {sense * Eigen::Vector3d::Unit(axis), length, *goal};
        }
      }
    }
  }
  return {};
}

MomentCallback showing_box_face(const MomentCallback& moment, const std::string& base_link,
                                const WorkspaceParameters& box, int axis, double face,
                                const Pose& requested) {
  if (!moment) return {};
  return
      [=](const std::string& label, const sim::Simulation& sim, const sim::RenderOverlay& overlay) {
        sim::RenderOverlay drawn = overlay;
        const Pose base = sim.body_pose(base_link);
        if (requested.position.allFinite()) {
          drawn.frames.push_back({Pose{base.position + base.orientation * requested.position,
                                       base.orientation * requested.orientation},
                                  0.06, 0.4f, "requested"});
          drawn.caption += "\npale axes: the reference as requested, outside the box";
        }
        // The face's four edges, as arrows from corner to corner.
        const int a = (axis + 1) % 3, b = (axis + 2) % 3;
        Eigen::Vector3d corners[4];
        for (int k = 0; k < 4; ++k) {
          corners[k][axis] = face;
          corners[k][a] = (k == 0 || k == 3) ? box.min[a] : box.max[a];
          corners[k][b] = k < 2 ? box.min[b] : box.max[b];
          corners[k] = base.position + base.orientation * corners[k];
        }
        for (int k = 0; k < 4; ++k) {
          drawn.arrows.push_back({corners[k], corners[(k + 1) % 4] - corners[k], 1.0,
                                  Eigen::Vector4f(0.9f, 0.15f, 0.1f, 0.7f),
                                  k == 0 ? "workspace wall" : ""});
        }
        drawn.caption += "\nred outline: the face of the workspace box the wall stands on";
        moment(label, sim, drawn);
      };
}

}  // namespace cartesian_impedance::scenarios::detail
