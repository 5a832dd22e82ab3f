// The robot model against DART 6.12, an independent rigid-body library with its own URDF loader
// and its own recursive algorithms: for every robot the project ships, over random configurations
// within the joint limits and random joint speeds, the flange pose, the Jacobian, M(q), g(q) and
// C(q, dq) dq agree to 1e-9 (relative to each quantity's scale). Both read the same URDF, so this
// checks our URDF-to-KDL conversion (joint origins and axes, inertias moved to the joint frames,
// fixed links merged) and the use of KDL's solvers, not the numbers in the file.

#include <gtest/gtest.h>

#include <dart/dart.hpp>
#include <dart/utils/urdf/DartLoader.hpp>

#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "cartesian_impedance/model/robot_model.hpp"

namespace {

namespace ci = cartesian_impedance;

struct Robot {
  const char* name;
  const char* urdf;  // under models/
  const char* base;
  const char* tip;
};

const Robot kRobots[] = {
    {"panda", "panda/panda.urdf", "panda_link0", "panda_link8"},
    {"iiwa14", "iiwa14/iiwa14.urdf", "iiwa_link_0", "iiwa_link_ee"},
    {"ur5e", "ur5e/ur5e.urdf", "base_link", "tool0"},
    {"planar3", "planar3/planar3.urdf", "base_link", "tool0"},
};

class DartModel : public ::testing::TestWithParam<Robot> {};

dart::dynamics::SkeletonPtr load(const std::string& path) {
  dart::utils::DartLoader loader;
  // The root link welded to the world, as the arm stands on its base.
  dart::utils::DartLoader::Options options;
  options.mDefaultRootJointType = dart::utils::DartLoader::RootJointType::FIXED;
  // A link without <inertial> is massless in URDF; DART's default would give it 1 kg (the flange
  // links tool0 and panda_link8 have none).
  options.mDefaultInertia =
      dart::dynamics::Inertia(0.0, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero());
  loader.setOptions(options);
  dart::dynamics::SkeletonPtr skeleton =
      loader.parseSkeleton(dart::common::Uri::createFromPath(path));
  if (skeleton == nullptr) throw std::runtime_error("DART cannot load " + path);
  skeleton->setGravity(Eigen::Vector3d(0.0, 0.0, -9.81));
  return skeleton;
}

double relative_difference(const Eigen::MatrixXd& ours, const Eigen::MatrixXd& theirs) {
  return (ours - theirs).norm() / std::max(1.0, theirs.norm());
}

TEST_P(DartModel, PoseJacobianAndDynamicsAgreeOverRandomStates) {
  const Robot& robot = GetParam();
  const std::string path = std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/" + robot.urdf;
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(path, robot.base, robot.tip);
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  const dart::dynamics::SkeletonPtr skeleton = load(path);
  const int n = model.num_joints();

  // The chain's joints in DART's generalised coordinates (DART orders them its own way and holds
  // every joint of the file).
  std::vector<std::size_t> index;
  for (const std::string& joint : model.joint_names()) {
    const dart::dynamics::DegreeOfFreedom* dof = skeleton->getDof(joint);
    ASSERT_NE(dof, nullptr) << joint;
    index.push_back(dof->getIndexInSkeleton());
  }
  ASSERT_EQ(skeleton->getNumDofs(), static_cast<std::size_t>(n))
      << "the shipped robots have no joints outside the chain";
  const dart::dynamics::BodyNode* base = skeleton->getBodyNode(robot.base);
  const dart::dynamics::BodyNode* tip = skeleton->getBodyNode(robot.tip);
  ASSERT_NE(base, nullptr);
  ASSERT_NE(tip, nullptr);

  std::mt19937 rng(12);
  double worst_pose = 0.0, worst_jacobian = 0.0, worst_mass = 0.0, worst_gravity = 0.0,
         worst_coriolis = 0.0;
  for (int sample = 0; sample < 200; ++sample) {
    ci::JointVector q(n), dq(n);
    for (int i = 0; i < n; ++i) {
      dq[i] = std::uniform_real_distribution<double>(-1.5, 1.5)(rng);
      skeleton->setVelocity(index[static_cast<std::size_t>(i)], dq[i]);
      const double low = std::max(model.limits().position_lower[i], -M_PI);
      const double high = std::min(model.limits().position_upper[i], M_PI);
      q[i] = std::uniform_real_distribution<double>(low, high)(rng);
      skeleton->setPosition(index[static_cast<std::size_t>(i)], q[i]);
    }
    ASSERT_TRUE(workspace.compute(q, dq, kinematics, true));

    // Flange pose in the base frame.
    const Eigen::Isometry3d T = base->getWorldTransform().inverse() * tip->getWorldTransform();
    worst_pose = std::max(worst_pose, (kinematics.pose.position - T.translation()).norm());
    worst_pose = std::max(
        worst_pose, kinematics.pose.orientation.toRotationMatrix().isApprox(T.linear(), 1e-9)
                        ? 0.0
                        : (kinematics.pose.orientation.toRotationMatrix() - T.linear()).norm());

    // DART's world Jacobian at the tip's origin is [angular; linear]; the base is the world.
    const dart::math::Jacobian full = skeleton->getWorldJacobian(tip);
    Eigen::MatrixXd jacobian(6, n), mass(n, n);
    Eigen::VectorXd gravity(n), coriolis(n);
    const Eigen::MatrixXd& M = skeleton->getMassMatrix();
    const Eigen::VectorXd& g = skeleton->getGravityForces();
    const Eigen::VectorXd& cdq = skeleton->getCoriolisForces();
    for (int c = 0; c < n; ++c) {
      const std::size_t j = index[static_cast<std::size_t>(c)];
      jacobian.col(c) << full.col(static_cast<Eigen::Index>(j)).tail<3>(),
          full.col(static_cast<Eigen::Index>(j)).head<3>();
      gravity[c] = g[static_cast<Eigen::Index>(j)];
      coriolis[c] = cdq[static_cast<Eigen::Index>(j)];
      for (int r = 0; r < n; ++r) {
        mass(r, c) = M(static_cast<Eigen::Index>(index[static_cast<std::size_t>(r)]),
                       static_cast<Eigen::Index>(j));
      }
    }
    worst_jacobian = std::max(worst_jacobian, relative_difference(kinematics.jacobian, jacobian));
    worst_mass = std::max(worst_mass, relative_difference(kinematics.mass, mass));
    // DART's gravity force is the term of M ddq + c + g = tau: the torque that holds the arm.
    worst_gravity = std::max(worst_gravity, relative_difference(kinematics.gravity, gravity));
    worst_coriolis = std::max(worst_coriolis, relative_difference(kinematics.coriolis, coriolis));
  }
  // Both compute in double precision with recursive algorithms of a few dozen operations per
  // link: their results differ by rounding, some 1e-15 relative.
  EXPECT_LT(worst_pose, 1e-9);
  EXPECT_LT(worst_jacobian, 1e-9);
  EXPECT_LT(worst_mass, 1e-9);
  EXPECT_LT(worst_gravity, 1e-9);
  EXPECT_LT(worst_coriolis, 1e-9);
  std::printf(
      "%s, largest relative differences to DART: pose %.1e, J %.1e, M %.1e, g %.1e, "
      "C dq %.1e\n",
      robot.name, worst_pose, worst_jacobian, worst_mass, worst_gravity, worst_coriolis);
}

INSTANTIATE_TEST_SUITE_P(ShippedRobots, DartModel, ::testing::ValuesIn(kRobots),
                         [](const ::testing::TestParamInfo<Robot>& info) {
                           return std::string(info.param.name);
                         });

}  // namespace
