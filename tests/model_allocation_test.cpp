// The model's per-cycle computation allocates nothing: malloc and operator new are counted
// (support/allocation_counter) over 10,000 calls with dynamics on, for both robots, and over
// every selection of terms on both backends.

#include <gtest/gtest.h>

#include <cmath>
#include <ostream>
#include <random>
#include <string>

#include "cartesian_impedance/model/robot_model.hpp"
#include "support/allocation_counter.hpp"

namespace ci = cartesian_impedance;

namespace {

struct RobotCase {
  const char* name;
  const char* file;  // below the source tree
  const char* base;
  const char* tip;
};

std::ostream& operator<<(std::ostream& stream, const RobotCase& robot) {
  return stream << robot.name;
}

class ModelAllocationFree : public ::testing::TestWithParam<RobotCase> {};

}  // namespace

TEST_P(ModelAllocationFree, ComputeWithDynamicsAllocatesNothing) {
  const RobotCase& robot = GetParam();
  Eigen::Isometry3d T_tip_tool = Eigen::Isometry3d::Identity();
  T_tip_tool.translate(Eigen::Vector3d(0.0, 0.0, 0.1));
  const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/" + robot.file,
                                     robot.base, robot.tip, T_tip_tool);
  const int n = model.num_joints();
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  ci::RobotState state = ci::make_robot_state(n);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  ci::JointVector q(n), dq(n), step(n);
  for (int i = 0; i < n; ++i) {
    q[i] = 0.5 * (model.limits().position_lower[i] + model.limits().position_upper[i]);
    dq[i] = uniform(rng);
    step[i] = 1e-4 * uniform(rng);
  }
  int failures = 0;
  double checksum = 0.0;

  allocation_counter::Scope scope;
  for (int k = 0; k < 10000; ++k) {
    q += step;
    failures += !workspace.compute(q, dq, kinematics, /*dynamics=*/true);
    ci::fill_robot_state(q, dq, kinematics, state);
    checksum += kinematics.mass(0, 0) + kinematics.gravity[1] + kinematics.coriolis[0];
  }
  // Kinematics only, pose only, and the rejected-input path must not allocate either.
  for (int k = 0; k < 100; ++k) failures += !workspace.compute(q, dq, kinematics);
  for (int k = 0; k < 100; ++k) failures += !workspace.compute_pose(q, kinematics.pose);
  ci::JointVector bad = q;
  bad[0] = std::nan("");
  for (int k = 0; k < 100; ++k) failures -= !workspace.compute(bad, dq, kinematics, true);
  const long allocations = scope.allocations();

  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(failures, -100) << "every valid call succeeds, every invalid one fails";
  EXPECT_TRUE(std::isfinite(checksum));
}

// Every selection of terms, on each backend: the control loop asks for a different one per
// option set, and each path through the native algorithms must be as free of the heap.
TEST_P(ModelAllocationFree, EveryTermSelectionOnEachBackendAllocatesNothing) {
  const RobotCase& robot = GetParam();
  const ci::RobotModel loaded = ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/" + robot.file, robot.base, robot.tip);
  const int n = loaded.num_joints();
  ci::JointVector q(n), dq = ci::JointVector::Constant(n, 0.2);
  for (int i = 0; i < n; ++i) {
    q[i] = 0.5 * (loaded.limits().position_lower[i] + loaded.limits().position_upper[i]);
  }
  for (const ci::ModelBackend backend : {ci::ModelBackend::native, ci::ModelBackend::kdl}) {
    ci::ModelWorkspace workspace(loaded.with_backend(backend));
    ci::Kinematics kinematics = workspace.make_kinematics();
    for (unsigned bits = 0; bits <= static_cast<unsigned>(ci::ModelTerms::all); ++bits) {
      const auto terms = static_cast<ci::ModelTerms>(bits);
      int failures = 0;
      long allocations = 0;
      {
        allocation_counter::Scope scope;
        for (int k = 0; k < 1000; ++k) {
          q[0] += 1e-4;
          failures += !workspace.compute(q, dq, kinematics, terms);
        }
        allocations = scope.allocations();
      }
      EXPECT_EQ(allocations, 0) << ci::to_string(backend) << ", terms " << bits;
      EXPECT_EQ(failures, 0) << ci::to_string(backend) << ", terms " << bits;
      EXPECT_EQ(kinematics.terms, terms);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Robots, ModelAllocationFree,
                         ::testing::Values(RobotCase{"panda", "models/panda/panda.urdf",
                                                     "panda_link0", "panda_link8"},
                                           RobotCase{"iiwa14", "models/iiwa14/iiwa14.urdf",
                                                     "iiwa_link_0", "iiwa_link_ee"}),
                         [](const auto& info) { return std::string(info.param.name); });
