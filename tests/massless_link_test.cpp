// A URDF whose last moving link has no <inertial>: the joint moves no mass, M(q) has a zero row
// and column at every q, and the damping shaped by the task-space inertia, (J M^-1 J^T)^-1, does
// not exist. The loop used to start and then fail every cycle (numerical_error, tau = nan); now it
// is refused when made, naming the joint and the link and what makes it work, and works once one
// of those is done (check_dynamics() in model/robot_model.hpp).

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "support/errors.hpp"
#include "support/model_fixtures.hpp"

namespace ci = cartesian_impedance;
using test_errors::error_of;

namespace {

const std::string kPlanar3 =
    std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/planar3/planar3.urdf";

// The planar 3-joint arm with the <inertial> of its last moving link (link3) removed.
ci::RobotModel planar3_without_last_inertial() {
  std::string urdf = model_fixtures::read_text(kPlanar3);
  const std::size_t link = urdf.find("<link name=\"link3\">");
  const std::size_t begin = urdf.find("<inertial>", link);
  const std::size_t end = urdf.find("</inertial>", begin) + std::string("</inertial>").size();
  urdf.erase(begin, end - begin);
  return ci::RobotModel::from_urdf_string(urdf, "base_link", "tool0");
}

// Steps `loop` at q = (0.3, 0.5, 0.4), at rest, with the reference 5 cm away: every cycle must
// compute the law.
void expect_law_computed(ci::ControlLoop& loop) {
  const ci::JointVector q = model_fixtures::vector_of({0.3, 0.5, 0.4});
  const ci::JointVector dq = ci::JointVector::Zero(3);
  loop.start(q, dq);
  ci::Pose reference = loop.latest_state().controller.pose;
  reference.position.x() += 0.05;
  loop.set_reference_pose(reference);
  for (int k = 0; k < 50; ++k) loop.step(q, dq, 0.001);
  const ci::LoopState state = loop.latest_state();
  EXPECT_EQ(state.controller.status, ci::Status::ok) << ci::to_string(state.controller.fault);
  EXPECT_TRUE(state.controller.tau.allFinite());
  EXPECT_GT(state.controller.tau.norm(), 0.0);
}

}  // namespace

TEST(MasslessLink, TheModelNamesTheJointThatMovesNoMass) {
  const ci::RobotModel model = planar3_without_last_inertial();
  ASSERT_EQ(model.massless_joints(), std::vector<int>{2});
  EXPECT_EQ(model.joint_links()[2], "link3");
  // The shipped arm moves mass with every joint.
  EXPECT_TRUE(
      ci::RobotModel::from_urdf_file(kPlanar3, "base_link", "tool0").massless_joints().empty());
}

TEST(MasslessLink, TheLoopIsRefusedWhenItsOptionsNeedTheMassMatrix) {
  const ci::RobotModel model = planar3_without_last_inertial();
  const std::string message = error_of([&] { ci::ControlLoop loop(model); });
  EXPECT_EQ(message,
            "joint 'joint3' moves no mass: link 'link3' and the links after it up to the tip have "
            "no mass or rotational inertia (no <inertial> in the URDF), so M(q) is singular at "
            "every q and dynamics.inertia_shaped_damping cannot be computed; give link 'link3' "
            "its <inertial>, or joint 'joint3' its rotor inertia with dynamics.armature[2] > 0, "
            "or turn dynamics.inertia_shaped_damping off");
  ci::Parameters consistent;
  consistent.dynamics.inertia_shaped_damping = false;
  consistent.dynamics.dynamically_consistent_nullspace = true;
  EXPECT_NE(error_of([&] {
              ci::ControlLoop loop(model, consistent);
            }).find("dynamics.dynamically_consistent_nullspace cannot be computed"),
            std::string::npos);
}

TEST(MasslessLink, ItWorksWithTheRotorInertiaOrWithoutTheOptions) {
  const ci::RobotModel model = planar3_without_last_inertial();
  ci::Parameters armature;
  armature.dynamics.armature = model_fixtures::vector_of({0.0, 0.0, 0.01});
  ci::ControlLoop with_armature(model, armature);
  expect_law_computed(with_armature);

  ci::Parameters unit_mass;  // the published controller's damping: no M(q) needed
  unit_mass.dynamics.inertia_shaped_damping = false;
  ci::ControlLoop without_options(model, unit_mass);
  expect_law_computed(without_options);
}

TEST(MasslessLink, AParameterSetThatNeedsTheMassMatrixIsRefusedAndChangesNothing) {
  const ci::RobotModel model = planar3_without_last_inertial();
  ci::Parameters armature;
  armature.dynamics.armature = model_fixtures::vector_of({0.0, 0.0, 0.01});
  ci::ControlLoop loop(model, armature);
  ci::Parameters without = armature;
  without.dynamics.armature = ci::JointVector::Zero(1);
  EXPECT_NE(error_of([&] { loop.set_parameters(without); }).find("joint 'joint3' moves no mass"),
            std::string::npos);
  expect_law_computed(loop);
  EXPECT_EQ(loop.latest_parameters().dynamics.armature, armature.dynamics.armature);
}
