// LinkTransforms (the transforms a node publishes on tf): the tip's transform composed from the
// joints equals the model's forward kinematics, joints off the chain are present and held at
// position 0, and what is rejected.

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/link_transforms.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "support/model_fixtures.hpp"

namespace ci = cartesian_impedance;
using namespace model_fixtures;

namespace {

const ci::LinkJoint* find_joint(const ci::LinkTransforms& links, const std::string& name) {
  for (const ci::LinkJoint& joint : links.joints()) {
    if (joint.name == name) return &joint;
  }
  return nullptr;
}

TEST(LinkTransforms, TipComposedFromTheJointsIsTheForwardKinematics) {
  for (const ci::RobotModel* model : {&panda(), &iiwa()}) {
    const std::string xml = read_text(model == &panda() ? panda_path() : iiwa_path());
    const ci::LinkTransforms links =
        ci::LinkTransforms::from_urdf_string(xml, model->base_link(), model->joint_names());
    EXPECT_EQ(links.joints().size(), 8u);  // 7 revolute joints and the fixed flange
    ci::ModelWorkspace workspace(*model);
    std::mt19937 rng(7);
    for (int trial = 0; trial < 20; ++trial) {
      const ci::JointVector q = random_configuration(*model, rng);
      const Eigen::Isometry3d expected = forward_kinematics(workspace, q);
      const Eigen::Isometry3d tip = links.link_pose(model->tip_link(), q);
      EXPECT_LT((tip.matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-12)
          << model->robot_name() << " q = " << q.transpose();
    }
  }
}

TEST(LinkTransforms, JointsOffTheChainAreHeldAtZeroAndFixedOnesAtTheirOrigin) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_string(kSliderUrdf, "base", "tip");
  const ci::LinkTransforms links =
      ci::LinkTransforms::from_urdf_string(kSliderUrdf, "base", model.joint_names());
  ASSERT_EQ(links.joints().size(), 6u);
  // Parents before children, each with its chain index (-1: does not change with q).
  std::vector<std::string> seen = {"base"};
  for (const ci::LinkJoint& joint : links.joints()) {
    EXPECT_NE(std::find(seen.begin(), seen.end(), joint.parent), seen.end()) << joint.name;
    seen.push_back(joint.child);
  }
  EXPECT_EQ(find_joint(links, "slide")->chain_index, 0);
  EXPECT_EQ(find_joint(links, "spin")->chain_index, 1);
  for (const char* name : {"weight_mount", "tip_mount", "plate_mount", "finger_joint"}) {
    ASSERT_NE(find_joint(links, name), nullptr) << name;
    EXPECT_EQ(find_joint(links, name)->chain_index, -1) << name;
  }
  const ci::JointVector q = vector_of({0.25, 0.7});
  std::vector<Eigen::Isometry3d> transforms;
  links.compute(q, transforms);
  ASSERT_EQ(transforms.size(), links.joints().size());
  // The finger (revolute, off the chain) at 0: its origin, 0.1 m above the tip.
  const Eigen::Isometry3d finger = links.link_pose("finger", q);
  const Eigen::Isometry3d tip = links.link_pose("tip", q);
  EXPECT_LT((finger.translation() - tip * Eigen::Vector3d(0, 0, 0.1)).norm(), 1e-12);
  EXPECT_LT((finger.linear() - tip.linear()).norm(), 1e-12);
  // The slide moves the carriage along x by q[0].
  EXPECT_NEAR(links.link_pose("carriage", q).translation().x(), 0.25, 1e-12);
  ci::ModelWorkspace workspace(model);
  EXPECT_LT((tip.matrix() - forward_kinematics(workspace, q).matrix()).cwiseAbs().maxCoeff(),
            1e-12);
  EXPECT_TRUE(links.visual_links().empty());  // the slider has no <visual>
}

TEST(LinkTransforms, VisualLinksAreListed) {
  const ci::LinkTransforms links = ci::LinkTransforms::from_urdf_string(
      read_text(panda_path()), "panda_link0", panda().joint_names());
  // panda_link0 .. panda_link7 have visuals; the flange panda_link8 has none.
  EXPECT_EQ(links.visual_links().size(), 8u);
  EXPECT_EQ(links.visual_links().front(), "panda_link0");
}

TEST(LinkTransforms, Rejects) {
  const std::string xml = read_text(panda_path());
  EXPECT_THROW(ci::LinkTransforms::from_urdf_string(xml, "panda_hand", panda().joint_names()),
               ci::LoadError);
  EXPECT_THROW(ci::LinkTransforms::from_urdf_string(xml, "panda_link0", {"panda_joint8"}),
               ci::LoadError);  // fixed
  EXPECT_THROW(ci::LinkTransforms::from_urdf_string(xml, "panda_link3", {"panda_joint1"}),
               ci::LoadError);  // above the base
  EXPECT_THROW(ci::LinkTransforms::from_urdf_string("<robot", "a", {}), ci::LoadError);
  const ci::LinkTransforms links =
      ci::LinkTransforms::from_urdf_string(xml, "panda_link0", panda().joint_names());
  std::vector<Eigen::Isometry3d> transforms;
  EXPECT_THROW(links.compute(ci::JointVector::Zero(3), transforms), ci::Error);
  EXPECT_THROW(links.link_pose("nowhere", ci::JointVector::Zero(7)), ci::Error);
}

}  // namespace
