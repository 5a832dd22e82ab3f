#pragma once
// The project's robots as the tests load them: the Panda and the iiwa14 models from models/, and
// their ready poses (the keyframes of their MJCF files).

#include <cmath>
#include <string>

#include "cartesian_impedance/model/robot_model.hpp"

namespace robots {

namespace ci = cartesian_impedance;

inline ci::RobotModel panda() {
  return ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
}

inline ci::RobotModel iiwa() {
  return ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/iiwa14/iiwa14.urdf", "iiwa_link_0",
      "iiwa_link_ee");
}

inline ci::JointVector panda_ready() {
  return (ci::JointVector(7) << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4).finished();
}

inline ci::JointVector iiwa_ready() {
  return (ci::JointVector(7) << 0, M_PI / 6, 0, -M_PI / 2, 0, M_PI / 3, 0).finished();
}

}  // namespace robots
