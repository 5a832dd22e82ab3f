// The state message's limits and safety-layer fields (ControllerState.msg, filled by
// node::fill_state_message()) through the ROS 1 types.

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include <cartesian_impedance/loop/control_loop.hpp>

#include "conversions.hpp"

namespace ci = cartesian_impedance;
namespace cir = cartesian_impedance_ros;

namespace {

ci::RobotModel panda() {
  return ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
}

// The torque shaping, the hold and every field of the safety layer reach the message, each in
// its own field: every value distinct, so a field filled from the wrong member shows.
TEST(Conversions, StateMessageCarriesTheLimitsAndTheSafetyLayer) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  ci::JointVector q(7);
  q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  loop.start(q, ci::JointVector::Zero(7));
  loop.step(q, ci::JointVector::Zero(7), 0.001);
  ci::LoopState state = loop.state();
  ci::ActiveLimits& limits = state.controller.limits;
  limits.torque_shaping = ci::TorqueShaping::wrench;
  limits.torque_shaping_scale = 0.25;
  limits.holding = true;
  ci::SafetyState& safety = state.controller.safety;
  safety.reference_speed_limited = true;
  safety.translation_drive_scale = 0.11;
  safety.rotation_drive_scale = 0.12;
  safety.braking = true;
  safety.force_scale = 0.13;
  safety.torque_scale = 0.14;
  safety.reference_clipped = true;
  safety.workspace_penetration = {0.015, -0.016, 0.017};
  safety.wall_force = {-18.0, 19.0, -20.0};
  safety.tank_level = 0.0021;
  safety.tank_draw = -0.0022;
  safety.stiffness_change_scale = 0.23;
  safety.payload_mass = 1.24;
  safety.payload_center_of_mass = {0.025, 0.026, 0.027};
  safety.payload_estimate_valid = true;
  safety.payload_estimate_mass = 1.28;
  safety.payload_estimate_center_of_mass = {0.029, 0.030, 0.031};
  safety.oscillation_scale = 0.125;
  safety.oscillations = 3;
  safety.generated_energy = 0.0625;
  safety.passivity_scale = Eigen::Vector3d(1.0, 0.25, 0.5);
  safety.passivity_halvings = 3;
  safety.max_speed_in_force.translation = 0.21;
  safety.max_force_in_force.force = 140.0;
  safety.pfl_speed_limit = 0.21;
  safety.pfl_effective_mass = 3.5;
  ci::CollisionState& collision = state.controller.collision;
  collision.detected = true;
  collision.time = 2.5;
  collision.joint = 3;
  collision.reaction = ci::CollisionReaction::reflex;
  collision.collisions = 2;
  collision.residual = ci::JointVector::LinSpaced(7, 1.0, 7.0);
  collision.threshold = ci::JointVector::Constant(7, 5.5);

  cir::ControllerState message;
  cir::fill_state_message(state, model.joint_names(), nullptr, message);
  EXPECT_EQ(message.torque_shaping, "wrench");
  EXPECT_EQ(message.torque_shaping_scale, 0.25);
  EXPECT_TRUE(message.holding);
  EXPECT_TRUE(message.reference_speed_limited);
  EXPECT_EQ(message.translation_drive_scale, 0.11);
  EXPECT_EQ(message.rotation_drive_scale, 0.12);
  EXPECT_TRUE(message.braking);
  EXPECT_EQ(message.force_scale, 0.13);
  EXPECT_EQ(message.torque_scale, 0.14);
  EXPECT_TRUE(message.reference_clipped);
  const auto xyz = [](const geometry_msgs::Vector3& v) {
    return std::vector<double>{v.x, v.y, v.z};
  };
  EXPECT_EQ(xyz(message.workspace_penetration), (std::vector<double>{0.015, -0.016, 0.017}));
  EXPECT_EQ(xyz(message.wall_force), (std::vector<double>{-18.0, 19.0, -20.0}));
  EXPECT_EQ(message.tank_level, 0.0021);
  EXPECT_EQ(message.tank_draw, -0.0022);
  EXPECT_EQ(message.stiffness_change_scale, 0.23);
  EXPECT_EQ(message.payload_mass, 1.24);
  EXPECT_EQ(xyz(message.payload_center_of_mass), (std::vector<double>{0.025, 0.026, 0.027}));
  EXPECT_TRUE(message.payload_estimate_valid);
  EXPECT_EQ(message.payload_estimate_mass, 1.28);
  EXPECT_EQ(xyz(message.payload_estimate_center_of_mass),
            (std::vector<double>{0.029, 0.030, 0.031}));
  EXPECT_EQ(message.oscillation_scale, 0.125);
  EXPECT_EQ(message.oscillations, 3u);
  EXPECT_EQ(message.generated_energy, 0.0625);
  EXPECT_EQ(message.passivity_scale_translation, 1.0);
  EXPECT_EQ(message.passivity_scale_rotation, 0.25);
  EXPECT_EQ(message.passivity_scale_nullspace, 0.5);
  EXPECT_EQ(message.passivity_halvings, 3u);
  EXPECT_EQ(message.max_speed_translation_in_force, 0.21);
  EXPECT_EQ(message.max_force_in_force, 140.0);
  EXPECT_EQ(message.pfl_speed_limit, 0.21);
  EXPECT_EQ(message.pfl_effective_mass, 3.5);
  EXPECT_TRUE(message.collision_detected);
  EXPECT_EQ(message.collision_time, 2.5);
  EXPECT_EQ(message.collision_joint, "panda_joint4");
  EXPECT_EQ(message.collision_reaction, "reflex");
  EXPECT_EQ(message.collisions, 2u);
  EXPECT_EQ(message.collision_residual, (std::vector<double>{1, 2, 3, 4, 5, 6, 7}));
  EXPECT_EQ(message.collision_threshold, std::vector<double>(7, 5.5));

  // And what a running loop reports at rest with the defaults: nothing capped, the tank full.
  cir::fill_state_message(loop.state(), model.joint_names(), nullptr, message);
  EXPECT_EQ(message.torque_shaping, "none");
  EXPECT_EQ(message.torque_shaping_scale, 1.0);
  EXPECT_FALSE(message.holding || message.braking || message.reference_clipped);
  EXPECT_EQ(message.force_scale, 1.0);
  EXPECT_EQ(message.tank_level, ci::Parameters{}.safety.energy_tank.initial);
}

}  // namespace
