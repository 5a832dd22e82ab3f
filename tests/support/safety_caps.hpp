#pragma once
// Every part of the safety layer acting at once on an arm that moves with a constant joint
// velocity: the scene of the benchmark BM_LoopStepEveryCap (bench/bench_loop.cpp) and of the
// allocation tests, so the benchmark times the branches the tests count.
//
// At the start configuration q, moving with dq (the flange's twist v, w = J dq):
// - safety.max_speed far below the flange's speed: the reference is held back every cycle (it
//   has at least the box's 6 cm and 3 rad to go at 1e-4 m/s and 1e-3 rad/s: 600 s of cycles and
//   more), the governor takes all of the push along the motion away and the brake acts on the
//   excess;
// - a commanded wrench along v and w that outweighs the spring, so there is a push along the
//   motion to take away;
// - safety.max_force below spring + wrench: both scaled down;
// - a 6 cm workspace box 10 cm behind the flange (against v): the reference is clipped into
//   it, the flange is outside and moving further out, so the wall's spring and damper act;
// - a stiffness raise while the flange is away from its reference: more than the energy tank
//   holds, so the tank is emptied and the change applied only as far as it pays, every cycle;
// - a declared payload (gravity and, with the default inertia-shaped damping, inertia).
// Stand the arm still (dq = 0) for kPayloadSettleTime and the payload estimate runs too.

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "cartesian_impedance/core/command.hpp"
#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/model/robot_model.hpp"

namespace safety_caps {

namespace ci = cartesian_impedance;

struct Scene {
  ci::Parameters parameters;
  std::vector<ci::Command> commands;  ///< to send after start()
  /// Where to start the loop: ten seconds of dq back. The reference starts at that flange and
  /// moves at the speed cap, so the flange is centimetres from it from the first cycle on and the
  /// stiffness raise costs joules: the tank stays short however long the run.
  ci::JointVector start;
};

/// The scene for `model` at q moving with dq, on top of `parameters`.
inline Scene scene(const ci::RobotModel& model, const ci::JointVector& q, const ci::JointVector& dq,
                   ci::Parameters parameters = {}) {
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(q, dq, kinematics, ci::ModelTerms::none);
  const ci::Pose flange = kinematics.pose;
  const ci::Vector6d twist = kinematics.jacobian * dq;
  const Eigen::Vector3d along = twist.head<3>().normalized();
  const Eigen::Vector3d turning = twist.tail<3>().normalized();

  ci::SafetyParameters& safety = parameters.safety;
  safety.max_speed.translation = 1e-4;  // [m/s]
  safety.max_speed.rotation = 1e-3;     // [rad/s]
  safety.max_force.force = 10.0;        // [N]
  safety.max_force.torque = 2.0;        // [Nm]
  // Outside the box along the largest component of `along` (at least 1/sqrt(3) of it): by
  // 0.1 m x 0.577 - 0.03 m = 2.8 cm or more.
  const Eigen::Vector3d center = flange.position - 0.1 * along;
  safety.workspace.min = center.array() - 0.03;
  safety.workspace.max = center.array() + 0.03;
  safety.workspace.stiffness = 500.0;  // [N/m]
  safety.energy_tank.enabled = true;
  parameters.payload.mass = 1.0;                        // [kg]
  parameters.payload.center_of_mass = {0.0, 0.0, 0.1};  // [m]
  // Soft at the start, raised by a command below to the largest stiffness: the tank, filled only
  // by the damping, pays for the raise a little each cycle (at 0.01 rad/s per joint the Panda's
  // stiffness climbs about 3 N/m per 1000 cycles), so the raise is still waiting after millions of
  // cycles. Over the tests' few thousand cycles the spring (at most 0.1 m x 200 N/m = 20 N and
  // 0.5 rad x 10 Nm/rad = 5 Nm at the start) stays below the wrench.
  parameters.stiffness.translation.setConstant(200.0);
  parameters.stiffness.rotation.setConstant(10.0);

  Scene result;
  result.parameters = parameters;
  result.start = q - 10.0 * dq;
  ci::Pose reference;
  reference.position = flange.position - 1.0 * along;  // clipped into the box
  reference.orientation =
      (Eigen::Quaterniond(Eigen::AngleAxisd(3.0, turning)) * flange.orientation).normalized();
  result.commands.emplace_back(ci::ReferencePose{reference});
  result.commands.emplace_back(
      ci::Stiffness::diagonal((ci::Vector6d() << 5000, 5000, 5000, 500, 500, 500).finished()));
  ci::Vector6d wrench;
  wrench << 60.0 * along, 15.0 * turning;  // [N; Nm], base frame
  result.commands.emplace_back(ci::Wrench{wrench});
  return result;
}

/// Which parts of the safety layer acted in any of the states recorded.
struct Acted {
  bool reference_speed_limited = false;
  bool translation_governed = false;
  bool rotation_governed = false;
  bool braking = false;
  bool force_capped = false;
  bool torque_capped = false;
  bool reference_clipped = false;
  bool wall = false;
  bool tank_short = false;
  bool payload = false;
  bool payload_estimate = false;

  void record(const ci::SafetyState& s) {
    reference_speed_limited |= s.reference_speed_limited;
    translation_governed |= s.translation_drive_scale < 1.0;
    rotation_governed |= s.rotation_drive_scale < 1.0;
    braking |= s.braking;
    force_capped |= s.force_scale < 1.0;
    torque_capped |= s.torque_scale < 1.0;
    reference_clipped |= s.reference_clipped;
    wall |= s.workspace_penetration.norm() > 0.0 && s.wall_force.norm() > 0.0;
    // Short: the raise was held back (the tank may be empty this cycle: it fills only from
    // damping the torque carried, and the shaped torque here often carries none).
    tank_short |= s.stiffness_change_scale < 1.0;
    payload |= s.payload_mass > 0.0;
    // Settled, the estimate ran to its end: valid, or found a contact.
    payload_estimate |= s.payload_estimate_valid || s.static_wrench_unexplained;
  }

  /// The names of the parts that never acted ("" if all did); the payload estimate only if
  /// `estimate` (it needs the arm still).
  std::string missing(bool estimate) const {
    std::string names;
    const std::pair<const char*, bool> parts[] = {
        {"reference_speed_limited", reference_speed_limited},
        {"translation_drive_scale", translation_governed},
        {"rotation_drive_scale", rotation_governed},
        {"braking", braking},
        {"force_scale", force_capped},
        {"torque_scale", torque_capped},
        {"reference_clipped", reference_clipped},
        {"wall_force", wall},
        {"stiffness_change_scale", tank_short},
        {"payload_mass", payload},
        {"payload_estimate_valid", payload_estimate || !estimate}};
    for (const auto& [name, acted] : parts) {
      if (!acted) names += (names.empty() ? "" : ", ") + std::string(name);
    }
    return names;
  }
};

}  // namespace safety_caps
