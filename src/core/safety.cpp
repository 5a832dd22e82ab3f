// The safety layer of CartesianImpedanceController (parameters safety.*, payload.*): caps on
// what any valid command can make the arm do, on the sum of every term the controller adds (the
// energy tank that pays for parameter changes is in energy_tank.cpp). Each function is noexcept,
// allocation-free and of fixed cost; with every cap off it costs a few comparisons.

#include <algorithm>
#include <cmath>
#include <limits>

#include "law.hpp"

namespace cartesian_impedance {

namespace {

// The speed cap's governor starts taking the push along the motion away at this fraction of the
// speed it holds (kSpeedCapAim x the cap) and has taken all of it there. Across the band the drive
// scale is a damper of push / width on the end effector's speed.
constexpr double kGovernorBand = 0.8;

// ... whose gain per cycle, dt x push / width / mass along the motion, is at most 1 / this: a
// larger push starts the band lower. A damper that takes a whole cycle's worth of speed out acts
// on a speed one cycle old at best; behind a loop's delay of a few cycles (measured: readings 1 ms
// old and torques acting 1 ms late) one taking out more than about 0.4 of it per cycle
// oscillates, and did: a 300 N spring's push across the 0.05 m/s band of a 0.25 m/s cap was a
// 6000 N s/m damper, 1.2-2 of the speed per cycle on the Panda, which chattered at the cap.
constexpr double kGovernorCycles = 4.0;

// The governor's disturbance observer averages over this time [s]: a few cycles at 1 kHz, well
// inside the brake's kBrakeTime.
constexpr double kDisturbanceTime = 0.003;

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
  const MaxSpeedParameters& cap = state_.safety.max_speed_in_force;
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
    // The step as a rotation from the last reference, the shorter way; held back, it turns by
    // the largest angle about the same axis: slerp's path, for one atan2 and one sincos (slerp
    // and angularDistance cost an acos and two sines more, about 40 ns a cycle).
    Eigen::Quaterniond relative = before.orientation.conjugate() * reference.orientation;
    if (relative.w() < 0.0) relative.coeffs() = -relative.coeffs();
    const double half_sine = relative.vec().norm();
    const double angle = 2.0 * std::atan2(half_sine, relative.w());
    const double largest = cap.rotation * dt;
    if (angle > largest) {
      Law& law = *law_;
      if (largest != law.speed_step_angle) {  // the same every cycle at a fixed rate
        law.speed_step_angle = largest;
        law.speed_step_cos = std::cos(0.5 * largest);
        law.speed_step_sin = std::sin(0.5 * largest);
      }
      Eigen::Quaterniond step;
      step.w() = law.speed_step_cos;
      step.vec() = (law.speed_step_sin / half_sine) * relative.vec();
      reference.orientation = (before.orientation * step).normalized();
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
  // One triangle, mirrored: at 7 x 3 x 7 a general product spends most of its time setting up.
  for (int j = 0; j < num_joints_; ++j) {
    const Eigen::Vector3d column = mass * law.payload_map.col(j);
    for (int i = 0; i < j; ++i) {
      const double added = law.payload_map.col(i).dot(column);
      law.mass(i, j) += added;
      law.mass(j, i) += added;
    }
    law.mass(j, j) += law.payload_map.col(j).dot(column);
  }
  return law.mass;
}

// A joint the task drives into its position limit is a constraint, not a term to share: the
// mechanical stop (or the robot's reflex, which stops the arm) would hold it anyway. So the drive's
// torque toward the limit on that joint is bounded by what the loop allows it there
// (RobotState::joint_limit_ceiling, joint_limit_floor; past half the margin the loop's own wall
// pushes back), and the other joints go on resolving the pose error as far as they can. What the
// bound takes is a joint-space torque like the walls', so the caps below see it: taken after
// them it turned the speed governor's sum into one it had not bounded (a wrist at 1.5 rad/s
// against a 1.2 rad/s cap, measured).
void CartesianImpedanceController::bound_joint_drive(const RobotState& robot) noexcept {
  Law& law = *law_;
  JointVector& wall = law.joint_wall_torque;
  if (robot.joint_wall_torque.size() == num_joints_) {
    wall = robot.joint_wall_torque;
  } else {
    wall.setZero();
  }
  ActiveLimits& limits = state_.limits;
  limits.joint_limit_held = -1;
  const JointVector& ceiling = robot.joint_limit_ceiling;
  const JointVector& floor = robot.joint_limit_floor;
  constexpr double kFree = std::numeric_limits<double>::infinity();
  if (ceiling.size() == num_joints_ && floor.size() == num_joints_ &&
      ((ceiling.array() < kFree).any() || (floor.array() > -kFree).any())) {
    JointVector& drive = law.joint_drive;
    jacobian_transpose_times(robot.jacobian, law.spring_force + state_.wrench_base, drive);
    drive += state_.tau_nullspace;
    for (int i = 0; i < num_joints_; ++i) {
      const double kept =
          std::min(std::max(drive[i], std::min(floor[i], 0.0)), std::max(ceiling[i], 0.0));
      const double cut = kept - drive[i];
      if (cut == 0.0) continue;
      wall[i] += cut;
      if (limits.joint_limit_held < 0 &&
          std::abs(cut) > kLimitHoldShare * state_.joint_torque_limit[i]) {
        limits.joint_limit_held = i;
      }
    }
  }
  law.joint_walls = !wall.isZero(0.0);
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
  bound_joint_drive(robot);
  walls(robot, dt);
  const MaxForceParameters& force_cap = state_.safety.max_force_in_force;
  const MaxSpeedParameters& speed_cap = state_.safety.max_speed_in_force;
  const bool capped = force_cap.force > 0.0 || force_cap.torque > 0.0 ||
                      speed_cap.translation > 0.0 || speed_cap.rotation > 0.0;
  law.joint_wall_force.setZero();
  if (capped && law.joint_walls) {
    law.projector.task_force(robot.jacobian, parameters_.nullspace.pseudo_inverse_damping,
                             law.joint_wall_torque, law.joint_wall_force);
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
  safety.wall_energy = law.wall_energy;
}

// A stiff wall sampled at the control rate gives back more than it stored: its force, computed
// where the end effector is at the start of a cycle, is held for the whole cycle while the end
// effector moves out of it (measured: a 63,000 N/m wall returned twice what it held when the end
// effector left it by its depth within one cycle). The walls' passivity observer counts the
// energy they hold - what the tank paid into them, what the arm did pushing into them, less the
// work their force did over each cycle - and the spring gives back at most that, this cycle and
// while its force falls: Ryu and Hannaford's passivity controller, for the walls. With the energy
// tank off the walls are plain springs, as everything else is then.
void CartesianImpedanceController::keep_walls_passive(const RobotState& robot, double dt) noexcept {
  if (!parameters_.safety.energy_tank.enabled || scheduled_) return;
  Law& law = *law_;
  const double size = law.wall_spring.norm();
  if (!(size > 0.0)) return;
  const Eigen::Vector3d direction = law.wall_spring / size;
  const double along = direction.dot(law.twist.head<3>());  // [m/s] the spring giving
  if (!(along > 0.0)) return;
  // A force falls no faster than the torque-rate limit lets it (step per cycle), and gives all the
  // way down: |F| along dt this cycle and about |F|^2 / (2 step) along dt while it falls. Met at
  // speed, a stiff wall that kept its force until its account ran out gave more than it held
  // (measured: 20 mJ over the account, a 74,000 N/m wall on planar3). So the spring is held to
  // what its account pays for this cycle and the fall after it: a F^2 + b F <= E.
  const double held = std::max(law.wall_energy, 0.0);
  const double step = wall_rate_step(robot, direction, dt);
  const double b = along * dt;
  const double a = std::isfinite(step) ? b / (2.0 * step) : 0.0;
  if (a * size * size + b * size <= held) return;
  const double fitting = 2.0 * held / (b + std::sqrt(b * b + 4.0 * a * held));
  law.wall_spring *= fitting / size;
}

// The largest change of the walls' force along `direction` (unit) in one cycle that
// kWallRateShare of the joints' torque-rate limits gives: min_i rate_i dt / |(J^T u)_i|.
double CartesianImpedanceController::wall_rate_step(const RobotState& robot,
                                                    const Eigen::Vector3d& direction,
                                                    double dt) noexcept {
  Law& law = *law_;
  Vector6d wrench = Vector6d::Zero();
  wrench.head<3>() = direction;
  jacobian_transpose_times(robot.jacobian, wrench, law.governor_joint);
  double largest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < num_joints_; ++i) {
    const double lever = std::abs(law.governor_joint[i]);
    if (lever > 0.0) {
      largest = std::min(largest, kWallRateShare * joint_torque_rate_limit_[i] * dt / lever);
    }
  }
  return largest;
}

// A stiff wall met at speed asks for its force faster than the joints' torque-rate limit lets it
// come (100,000 N/m at 0.1 m/s: 10 kN/s, where the Panda's joints give about 2 kN/s at the
// flange); clipped joint by joint, the force it gets points elsewhere and spins the wrist
// (measured: 1.2 x the rotation cap). The walls' force changes by at most what the rate limit gives
// along the change, min_i rate_i / |(J^T u)_i|: a wall met at speed is entered a little deeper, and
// pushes straight. kWallRateShare of the rate goes to the walls; the rest stays for the terms that
// hold the motion back while the wall builds up (the governor's, the damping).
void CartesianImpedanceController::follow_the_rate_limit(const RobotState& robot,
                                                         double dt) noexcept {
  Law& law = *law_;
  const Eigen::Vector3d change = law.wall_spring + law.wall_damper - law.wall_force_sent;
  const double squared = change.squaredNorm();
  if (!(squared > 0.0)) return;  // no wall, nothing sent: most cycles (and no square root)
  const double size = std::sqrt(squared);
  const double largest = wall_rate_step(robot, change / size, dt);
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
  // The work the walls' force did on the arm since the last cycle, their damper's too: the walls
  // are one port, and what it took in bounds what its spring may give back. (Counting the
  // spring's own work alone, its sampling, which the damper pays for, left a pushed wall soft:
  // 50 mm deep under a 17 N push instead of 9 mm.)
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
  keep_walls_passive(robot, dt);
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
  const MaxForceParameters& cap = state_.safety.max_force_in_force;
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
  const MaxSpeedParameters& caps = state_.safety.max_speed_in_force;
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
  const MaxSpeedParameters& caps = state_.safety.max_speed_in_force;
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
    if (law.joint_walls) torque += law.joint_wall_torque;
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
    const double drive_push = (spring + wrench + forces).dot(axis.g) + axis.fixed_push;
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
    const double width = std::max((1.0 - kGovernorBand) * cap,
                                  kGovernorCycles * dt * response * std::max(drive_push, 0.0));
    if (std::max(reached, predicted) <= cap - width) continue;
    drive_scale = std::clamp((cap - speed) / width, 0.0, 1.0);
    axis.target = net - (1.0 - drive_scale) * std::max(drive_push, 0.0);
    if (response > 0.0) {
      // Below the cap the net push may bring the speed up to it within the cycle, and no faster
      // than the rate limit can take it out again; above it, it must take the excess out within
      // kBrakeTime.
      const double room = cap - speed;
      const double allowed =
          room >= 0.0 ? std::min(room / (dt * response), std::sqrt(2.0 * rate * room / response))
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
  law.still_twist += dt / (kStillFilterTime + dt) * (law.twist - law.still_twist);
  // Motion ten times the still speeds ends the stillness at once; below that, the low-passed
  // twist decides, so that noise does not.
  const bool still = law.still_twist.head<3>().norm() < kStillSpeed &&
                     law.still_twist.tail<3>().norm() < kStillAngularSpeed &&
                     law.twist.head<3>().norm() < 10.0 * kStillSpeed &&
                     law.twist.tail<3>().norm() < 10.0 * kStillAngularSpeed;
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
  safety.payload_mismatch = safety.payload_estimate_valid &&
                            std::abs(safety.payload_estimate_mass - declared) >
                                kPayloadMismatchMass + kPayloadMismatchFraction * declared;
}

}  // namespace cartesian_impedance
