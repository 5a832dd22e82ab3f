#pragma once
// The robots the model tests share: the Panda and the iiwa from models/, a handwritten robot whose
// kinematics and dynamics are worked out by hand, and seeded random configurations.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <random>
#include <string>

#include "cartesian_impedance/model/robot_model.hpp"

namespace model_fixtures {

namespace ci = cartesian_impedance;

inline constexpr double kPi = 3.14159265358979323846;

inline std::string read_text(const std::string& path) {
  std::ifstream file(path);
  return std::string(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
}

inline std::string panda_path() {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf";
}
inline std::string iiwa_path() {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/iiwa14/iiwa14.urdf";
}

// A handwritten robot with a prismatic and a continuous joint, whose kinematics and dynamics are
// worked out by hand in model_test.cpp (SliderModel tests):
//  - slide (prismatic along base x, at z = 0.5) moves `carriage` (3 kg, centre 0.05 m along x);
//  - spin (continuous, 0.2 m further along x, frame rolled by +90 deg about x so that its axis,
//    the local z, is the base's -y) turns `arm` (2 kg, centre 0.15 m along the arm's x, its
//    inertial frame pitched by +90 deg so that the URDF's ixx = 0.01 is the moment about the
//    spin axis);
//  - `weight` (0.5 kg point mass) is fixed to the arm 0.1 m along its x (a side branch);
//  - the tip is fixed to the arm 0.3 m along its x; `plate` (0.25 kg point mass) is fixed to the
//    tip 0.05 m further; `finger` (1 kg) hangs off the tip by a revolute joint, so it is not part
//    of the chain base -> tip, nor is the base's own 100 kg.
inline constexpr const char* kSliderUrdf = R"(<?xml version="1.0"?>
<robot name="slider">
  <link name="base">
    <inertial><mass value="100"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="carriage">
    <inertial>
      <origin xyz="0.05 0 0"/><mass value="3"/>
      <inertia ixx="0.01" iyy="0.02" izz="0.03" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
  <link name="arm">
    <inertial>
      <origin xyz="0.15 0 0" rpy="0 1.5707963267948966 0"/><mass value="2"/>
      <inertia ixx="0.01" iyy="0.02" izz="0.03" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
  <link name="weight">
    <inertial><mass value="0.5"/><inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="tip"/>
  <link name="plate">
    <inertial><mass value="0.25"/><inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="finger">
    <inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="slide" type="prismatic">
    <parent link="base"/><child link="carriage"/>
    <origin xyz="0 0 0.5"/><axis xyz="1 0 0"/>
    <limit lower="-0.4" upper="0.6" velocity="0.5" effort="100"/>
  </joint>
  <joint name="spin" type="continuous">
    <parent link="carriage"/><child link="arm"/>
    <origin xyz="0.2 0 0" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
  </joint>
  <joint name="weight_mount" type="fixed">
    <parent link="arm"/><child link="weight"/><origin xyz="0.1 0 0"/>
  </joint>
  <joint name="tip_mount" type="fixed">
    <parent link="arm"/><child link="tip"/><origin xyz="0.3 0 0"/>
  </joint>
  <joint name="plate_mount" type="fixed">
    <parent link="tip"/><child link="plate"/><origin xyz="0.05 0 0"/>
  </joint>
  <joint name="finger_joint" type="revolute">
    <parent link="tip"/><child link="finger"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" velocity="1" effort="10"/>
  </joint>
</robot>
)";

inline const ci::RobotModel& panda() {
  static const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8");
  return model;
}

inline const ci::RobotModel& iiwa() {
  static const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(iiwa_path(), "iiwa_link_0", "iiwa_link_ee");
  return model;
}

inline ci::JointVector vector_of(std::initializer_list<double> values) {
  ci::JointVector v(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double value : values) v[i++] = value;
  return v;
}

// Uniform within the position limits (continuous joints: one turn either way).
inline ci::JointVector random_configuration(const ci::RobotModel& model, std::mt19937& rng) {
  ci::JointVector q(model.num_joints());
  for (int i = 0; i < model.num_joints(); ++i) {
    const double lower = std::max(model.limits().position_lower[i], -kPi);
    const double upper = std::min(model.limits().position_upper[i], kPi);
    q[i] = std::uniform_real_distribution<double>(lower, upper)(rng);
  }
  return q;
}

inline ci::JointVector random_velocity(int n, std::mt19937& rng, double magnitude) {
  ci::JointVector dq(n);
  for (int i = 0; i < n; ++i) {
    dq[i] = std::uniform_real_distribution<double>(-magnitude, magnitude)(rng);
  }
  return dq;
}

inline Eigen::Isometry3d isometry(const ci::Pose& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = pose.orientation.toRotationMatrix();
  T.translation() = pose.position;
  return T;
}

inline Eigen::Isometry3d forward_kinematics(ci::ModelWorkspace& workspace,
                                            const ci::JointVector& q) {
  ci::Pose pose;
  EXPECT_TRUE(workspace.compute_pose(q, pose));
  return isometry(pose);
}

}  // namespace model_fixtures
