// The native backend against KDL, the reference it replaces: pose, Jacobian, M(q), g(q) and
// C(q, dq) dq at 10,000 random configurations of every shipped robot, of a handwritten robot with
// a prismatic first joint, and of a test chain built to catch every shortcut (tilted axes of any
// length, prismatic joints, fixed joints with rotated origins between movable ones, a continuous
// joint, side branches and a massive tip folded into their bodies, a mass fixed to the base,
// a tool offset), also under a tilted gravity. A wrong sign, axis, frame or inertia would show
// as errors of order 0.1, against tolerances of 1e-12 and 1e-10.
//
// Tolerances. Pose and Jacobian are sums of a few products of numbers below 2 m with rotation
// entries, each rounded at 1e-16: both implementations land within ~1e-15 m or rad of the exact
// value, so 1e-12 absolute leaves three orders of margin. M, g and C are sums over up to n
// bodies of products m |r|^2, m |r| |g| or m |r|^2 |dq|^2; rounding scales with the largest
// such term, which is bounded by the largest entry of the result (times a few units: the native
// algorithm takes inertias about the base origin, where terms m |c|^2 partly cancel). The test
// therefore takes 1e-10 relative to max(1, largest |entry|) of KDL's result: errors seen are
// ~1e-14 of that scale, and any modelling error is ~1e-2 or more.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <functional>
#include <limits>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "cartesian_impedance/model/robot_model.hpp"
#include "support/model_fixtures.hpp"

namespace ci = cartesian_impedance;
using namespace model_fixtures;

namespace {

// Every kind of joint and frame the loader accepts, with nothing aligned to an axis.
constexpr const char* kTiltedUrdf = R"(<?xml version="1.0"?>
<robot name="tilted">
  <link name="ground"/>
  <link name="pedestal">
    <inertial><mass value="7"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="l1">
    <inertial>
      <origin xyz="0.02 0.05 0.1" rpy="0.1 0.2 0.3"/><mass value="2.5"/>
      <inertia ixx="0.02" iyy="0.03" izz="0.015" ixy="0.001" ixz="-0.002" iyz="0.003"/>
    </inertial>
  </link>
  <link name="l2">
    <inertial>
      <origin xyz="-0.03 0.01 0.04" rpy="-0.5 0.1 1.1"/><mass value="1.7"/>
      <inertia ixx="0.011" iyy="0.009" izz="0.013" ixy="-0.001" ixz="0.0005" iyz="0.0"/>
    </inertial>
  </link>
  <link name="l2_plate">
    <inertial>
      <origin xyz="0.01 0.02 0.03" rpy="0.7 -0.3 0.2"/><mass value="0.6"/>
      <inertia ixx="0.002" iyy="0.003" izz="0.004" ixy="0.0002" ixz="0" iyz="-0.0001"/>
    </inertial>
  </link>
  <link name="l3">
    <inertial>
      <origin xyz="0.1 -0.02 0.0" rpy="0 0 0"/><mass value="1.2"/>
      <inertia ixx="0.004" iyy="0.012" izz="0.011" ixy="0" ixz="0.001" iyz="0"/>
    </inertial>
  </link>
  <link name="l4">
    <inertial>
      <origin xyz="0.0 0.06 0.02" rpy="1.2 0.4 -0.8"/><mass value="0.9"/>
      <inertia ixx="0.003" iyy="0.002" izz="0.0025" ixy="0.0003" ixz="-0.0002" iyz="0.0001"/>
    </inertial>
  </link>
  <link name="side_mass">
    <inertial><origin xyz="0.05 0 0"/><mass value="0.4"/><inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="l5">
    <inertial>
      <origin xyz="0.01 0.0 -0.05"/><mass value="0.7"/>
      <inertia ixx="0.001" iyy="0.0015" izz="0.0008" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
  <link name="l6">
    <inertial>
      <origin xyz="0.0 0.0 0.03" rpy="0.3 0 0"/><mass value="0.5"/>
      <inertia ixx="0.0007" iyy="0.0007" izz="0.0004" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
  <link name="flange">
    <inertial><origin xyz="0 0.01 0.02"/><mass value="0.3"/><inertia ixx="0.0002" iyy="0.0003" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="finger">
    <inertial><mass value="0.2"/><inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="mount" type="fixed">
    <parent link="ground"/><child link="pedestal"/><origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.2 0.5"/>
  </joint>
  <joint name="j1" type="revolute">
    <parent link="pedestal"/><child link="l1"/><origin xyz="0 0 0.2" rpy="0 0 0.4"/>
    <axis xyz="0.3 -0.5 0.8"/><limit lower="-2.5" upper="2.5" velocity="2" effort="100"/>
  </joint>
  <joint name="j2" type="prismatic">
    <parent link="l1"/><child link="l2"/><origin xyz="0.1 0.05 0.25" rpy="-0.4 0.2 0.1"/>
    <axis xyz="2 0.5 -1"/><limit lower="-0.3" upper="0.4" velocity="0.5" effort="200"/>
  </joint>
  <joint name="plate_mount" type="fixed">
    <parent link="l2"/><child link="l2_plate"/><origin xyz="0.05 -0.1 0.15" rpy="1.0 0.5 -0.7"/>
  </joint>
  <joint name="j3" type="continuous">
    <parent link="l2_plate"/><child link="l3"/><origin xyz="0.02 0.0 0.12" rpy="0.2 -1.1 0.3"/>
    <axis xyz="-0.2 0.9 0.1"/>
  </joint>
  <joint name="j4" type="revolute">
    <parent link="l3"/><child link="l4"/><origin xyz="0.3 0.02 -0.01" rpy="0 0.6 0"/>
    <axis xyz="1 1 0"/><limit lower="-2" upper="1.5" velocity="2" effort="50"/>
  </joint>
  <joint name="side_mount" type="fixed">
    <parent link="l4"/><child link="side_mass"/><origin xyz="0 0.1 0" rpy="0.4 0.4 0.4"/>
  </joint>
  <joint name="j5" type="prismatic">
    <parent link="l4"/><child link="l5"/><origin xyz="0.0 0.2 0.05" rpy="-0.9 0 0.2"/>
    <axis xyz="0 0 -3"/><limit lower="0" upper="0.25" velocity="0.3" effort="80"/>
  </joint>
  <joint name="j6" type="revolute">
    <parent link="l5"/><child link="l6"/><origin xyz="0.01 0.0 0.08" rpy="0 0 0"/>
    <axis xyz="0 0 -1"/><limit lower="-3" upper="3" velocity="3" effort="20"/>
  </joint>
  <joint name="flange_mount" type="fixed">
    <parent link="l6"/><child link="flange"/><origin xyz="0.0 0.03 0.07" rpy="3.0 0.1 -1.4"/>
  </joint>
  <joint name="finger_joint" type="revolute">
    <parent link="flange"/><child link="finger"/><origin xyz="0 0 0.05"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" velocity="1" effort="10"/>
  </joint>
</robot>
)";

struct BackendCase {
  const char* name;
  std::function<std::string()> xml;
  std::string base;
  std::string tip;
};

std::ostream& operator<<(std::ostream& stream, const BackendCase& robot) {
  return stream << robot.name;
}

std::string model_file(const char* relative) {
  return read_text(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/" + relative);
}

const std::vector<BackendCase>& backend_cases() {
  static const std::vector<BackendCase> cases = {
      {"panda", [] { return model_file("panda/panda.urdf"); }, "panda_link0", "panda_link8"},
      {"iiwa14", [] { return model_file("iiwa14/iiwa14.urdf"); }, "iiwa_link_0", "iiwa_link_ee"},
      {"ur5e", [] { return model_file("ur5e/ur5e.urdf"); }, "base_link", "tool0"},
      {"planar3", [] { return model_file("planar3/planar3.urdf"); }, "base_link", "tool0"},
      {"slider", [] { return std::string(kSliderUrdf); }, "base", "tip"},
      {"tilted", [] { return std::string(kTiltedUrdf); }, "ground", "flange"},
  };
  return cases;
}

Eigen::Isometry3d test_tool() {
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.translate(Eigen::Vector3d(0.01, -0.02, 0.12));
  tool.rotate(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -0.4, 1.0).normalized()));
  return tool;
}

// Largest absolute difference, and the same divided by max(1, largest |entry| of `expected`).
struct Errors {
  double position = 0.0, rotation = 0.0, jacobian = 0.0;
  double mass = 0.0, gravity = 0.0, coriolis = 0.0;  // relative to max(1, scale)
};

template <typename A, typename B>
double relative_error(const A& actual, const B& expected) {
  const double scale = std::max(1.0, expected.cwiseAbs().maxCoeff());
  return (actual - expected).cwiseAbs().maxCoeff() / scale;
}

void update(Errors& worst, const ci::Kinematics& native, const ci::Kinematics& kdl) {
  worst.position =
      std::max(worst.position, (native.pose.position - kdl.pose.position).cwiseAbs().maxCoeff());
  worst.rotation = std::max(worst.rotation, (native.pose.orientation.toRotationMatrix() -
                                             kdl.pose.orientation.toRotationMatrix())
                                                .cwiseAbs()
                                                .maxCoeff());
  worst.jacobian = std::max(worst.jacobian, (native.jacobian - kdl.jacobian).cwiseAbs().maxCoeff());
  worst.mass = std::max(worst.mass, relative_error(native.mass, kdl.mass));
  worst.gravity = std::max(worst.gravity, relative_error(native.gravity, kdl.gravity));
  worst.coriolis = std::max(worst.coriolis, relative_error(native.coriolis, kdl.coriolis));
}

// Uniform within the limits (continuous: +-pi); velocities up to 2 rad/s and 0.5 m/s.
void random_state(const ci::RobotModel& model, std::mt19937& rng, ci::JointVector& q,
                  ci::JointVector& dq) {
  q = random_configuration(model, rng);
  dq.resize(model.num_joints());
  for (int i = 0; i < model.num_joints(); ++i) {
    const double bound =
        model.joint_types()[static_cast<std::size_t>(i)] == ci::JointType::prismatic ? 0.5 : 2.0;
    dq[i] = std::uniform_real_distribution<double>(-bound, bound)(rng);
  }
}

Errors compare_backends(const ci::RobotModel& model, int configurations, unsigned seed) {
  const ci::RobotModel kdl_model = model.with_backend(ci::ModelBackend::kdl);
  EXPECT_EQ(model.backend(), ci::ModelBackend::native);
  EXPECT_EQ(kdl_model.backend(), ci::ModelBackend::kdl);
  ci::ModelWorkspace native(model), kdl(kdl_model);
  EXPECT_EQ(kdl.model().backend(), ci::ModelBackend::kdl);
  ci::Kinematics a = native.make_kinematics(), b = kdl.make_kinematics();
  std::mt19937 rng(seed);
  ci::JointVector q, dq;
  Errors worst;
  for (int k = 0; k < configurations; ++k) {
    random_state(model, rng, q, dq);
    // C^T dq has its own test (KDL has no solver for it; the backend takes it from differences).
    EXPECT_TRUE(native.compute(q, dq, a, true));
    EXPECT_TRUE(kdl.compute(q, dq, b, true));
    update(worst, a, b);
    ci::Pose pose_a, pose_b;
    EXPECT_TRUE(native.compute_pose(q, pose_a));
    EXPECT_TRUE(kdl.compute_pose(q, pose_b));
    worst.position =
        std::max(worst.position, (pose_a.position - pose_b.position).cwiseAbs().maxCoeff());
  }
  return worst;
}

void expect_agreement(const Errors& worst, const std::string& what) {
  std::printf("%-28s max |dp| %.2e m, |dR| %.2e, |dJ| %.2e; relative dM %.2e, dg %.2e, dc %.2e\n",
              what.c_str(), worst.position, worst.rotation, worst.jacobian, worst.mass,
              worst.gravity, worst.coriolis);
  EXPECT_LE(worst.position, 1e-12) << what;
  EXPECT_LE(worst.rotation, 1e-12) << what;
  EXPECT_LE(worst.jacobian, 1e-12) << what;
  EXPECT_LE(worst.mass, 1e-10) << what;
  EXPECT_LE(worst.gravity, 1e-10) << what;
  EXPECT_LE(worst.coriolis, 1e-10) << what;
}

class NativeMatchesKdl : public ::testing::TestWithParam<BackendCase> {};

}  // namespace

TEST_P(NativeMatchesKdl, AtTenThousandConfigurations) {
  const BackendCase& robot = GetParam();
  const ci::RobotModel model = ci::RobotModel::from_urdf_string(robot.xml(), robot.base, robot.tip);
  expect_agreement(compare_backends(model, 10000, 11), robot.name);
}

TEST_P(NativeMatchesKdl, WithAToolAndTiltedGravity) {
  const BackendCase& robot = GetParam();
  const ci::RobotModel model = ci::RobotModel::from_urdf_string(
      robot.xml(), robot.base, robot.tip, test_tool(), Eigen::Vector3d(1.5, -2.5, -9.0));
  expect_agreement(compare_backends(model, 10000, 12), std::string(robot.name) + " (tool, g)");
}

INSTANTIATE_TEST_SUITE_P(Robots, NativeMatchesKdl, ::testing::ValuesIn(backend_cases()),
                         [](const auto& info) { return std::string(info.param.name); });

// C(q, dq)^T dq, the momentum observer's term, two ways no native code computes: KDL's M(q)
// differenced along each joint (C^T dq = dT/dq = 1/2 dq^T dM/dq_k dq), and the
// Christoffel identity dM/dt = C + C^T, with dM/dt dq from the native M(q) differenced along dq
// and checked against the native C dq + C^T dq. Central differences of step h = 1e-6 err by
// about eps |M| |dq|^2 / h (1e-10 of the scale |M| |dq|^2) plus h^2 times M's third derivative:
// 1e-7 of the scale leaves a thousandfold margin; a wrong sign, joint or body is of order 1.
TEST_P(NativeMatchesKdl, CoriolisTransposedIsTheKineticEnergysGradient) {
  const BackendCase& robot = GetParam();
  const ci::RobotModel model = ci::RobotModel::from_urdf_string(
      robot.xml(), robot.base, robot.tip, test_tool(), Eigen::Vector3d(1.5, -2.5, -9.0));
  ci::ModelWorkspace native(model), kdl(model.with_backend(ci::ModelBackend::kdl));
  ci::Kinematics a = native.make_kinematics(), b = kdl.make_kinematics();
  ci::Kinematics plus = a, minus = a, shifted = b;
  std::mt19937 rng(13);
  ci::JointVector q, dq;
  double worst_kdl = 0.0, worst_identity = 0.0, largest = 0.0;
  constexpr double h = 1e-6;
  for (int k = 0; k < 300; ++k) {
    random_state(model, rng, q, dq);
    ASSERT_TRUE(native.compute(q, dq, a, ci::ModelTerms::all));
    ci::JointVector from_kdl(model.num_joints());
    for (int j = 0; j < model.num_joints(); ++j) {
      double side[2];
      for (int sign = 0; sign < 2; ++sign) {
        ci::JointVector q_shifted = q;
        q_shifted[j] += sign == 0 ? h : -h;
        ASSERT_TRUE(kdl.compute(q_shifted, dq, shifted, ci::ModelTerms::mass));
        side[sign] = dq.dot(shifted.mass * dq);
      }
      from_kdl[j] = 0.5 * (side[0] - side[1]) / (2.0 * h);
    }
    ASSERT_TRUE(native.compute(q + h * dq, dq, plus, ci::ModelTerms::mass));
    ASSERT_TRUE(native.compute(q - h * dq, dq, minus, ci::ModelTerms::mass));
    const ci::JointVector mass_rate_dq = (plus.mass - minus.mass) / (2.0 * h) * dq;
    const double scale = std::max(1.0, a.mass.cwiseAbs().maxCoeff() * dq.squaredNorm());
    worst_kdl =
        std::max(worst_kdl, (a.coriolis_transposed - from_kdl).cwiseAbs().maxCoeff() / scale);
    worst_identity =
        std::max(worst_identity,
                 (a.coriolis + a.coriolis_transposed - mass_rate_dq).cwiseAbs().maxCoeff() / scale);
    largest = std::max(largest, a.coriolis_transposed.cwiseAbs().maxCoeff() / scale);
  }
  std::printf("%-20s C^T dq: relative to KDL's dM/dq %.1e, to dM/dt - C %.1e (largest %.2f)\n",
              robot.name, worst_kdl, worst_identity, largest);
  EXPECT_LE(worst_kdl, 1e-7);
  EXPECT_LE(worst_identity, 1e-7);
  EXPECT_GE(largest, 1e-3) << "the states must exercise the term";
}

TEST(ModelBackend, ChosenPerModelAndKeptByCopies) {
  const ci::RobotModel& native = panda();
  EXPECT_EQ(native.backend(), ci::ModelBackend::native);
  const ci::RobotModel kdl = native.with_backend(ci::ModelBackend::kdl);
  EXPECT_EQ(kdl.backend(), ci::ModelBackend::kdl);
  EXPECT_EQ(native.backend(), ci::ModelBackend::native) << "with_backend returns a copy";
  const ci::RobotModel copy = kdl;
  EXPECT_EQ(copy.backend(), ci::ModelBackend::kdl);
  ci::ModelWorkspace workspace(copy);
  const ci::ModelWorkspace workspace_copy(workspace);
  EXPECT_EQ(workspace_copy.model().backend(), ci::ModelBackend::kdl);
  EXPECT_EQ(kdl.with_backend(ci::ModelBackend::native).backend(), ci::ModelBackend::native);
  EXPECT_STREQ(ci::to_string(ci::ModelBackend::native), "native");
  EXPECT_STREQ(ci::to_string(ci::ModelBackend::kdl), "kdl");
}

TEST(ModelTermsSet, CombinesAndTests) {
  using ci::ModelTerms;
  EXPECT_EQ(ModelTerms::mass | ModelTerms::gravity | ModelTerms::coriolis |
                ModelTerms::coriolis_transposed,
            ModelTerms::all);
  EXPECT_EQ(ModelTerms::all & ModelTerms::gravity, ModelTerms::gravity);
  EXPECT_EQ(~ModelTerms::gravity,
            ModelTerms::mass | ModelTerms::coriolis | ModelTerms::coriolis_transposed);
  EXPECT_EQ(~ModelTerms::all, ModelTerms::none);
  EXPECT_TRUE(ci::includes(ModelTerms::all, ModelTerms::mass | ModelTerms::coriolis));
  EXPECT_FALSE(ci::includes(ModelTerms::mass, ModelTerms::mass | ModelTerms::gravity));
  EXPECT_TRUE(ci::includes(ModelTerms::mass, ModelTerms::none));
}

// Each selection computes exactly its terms: those asked for equal the full computation at the
// new q; the others keep what the previous call left; `terms` and has_dynamics say which is
// which. On both backends.
TEST(ModelTermsSet, OnlyTheRequestedTermsChange) {
  using ci::ModelTerms;
  const ModelTerms selections[] = {ModelTerms::none,
                                   ModelTerms::mass,
                                   ModelTerms::gravity,
                                   ModelTerms::coriolis,
                                   ModelTerms::mass | ModelTerms::gravity,
                                   ModelTerms::mass | ModelTerms::coriolis,
                                   ModelTerms::gravity | ModelTerms::coriolis,
                                   ModelTerms::coriolis_transposed,
                                   ModelTerms::mass | ModelTerms::coriolis_transposed,
                                   ModelTerms::all};
  const ci::JointVector q_old = vector_of({0.1, -0.4, 0.2, -2.0, 0.3, 1.5, 0.6});
  const ci::JointVector dq_old = vector_of({0.3, -0.2, 0.1, 0.4, -0.5, 0.2, 0.1});
  const ci::JointVector q_new = vector_of({-0.5, 0.3, -0.6, -1.2, -0.4, 2.2, -0.3});
  const ci::JointVector dq_new = vector_of({-0.6, 0.5, 0.7, -0.3, 0.8, -0.4, 0.9});
  for (const ci::ModelBackend backend : {ci::ModelBackend::native, ci::ModelBackend::kdl}) {
    ci::ModelWorkspace workspace(panda().with_backend(backend));
    ci::Kinematics old_full = workspace.make_kinematics(), new_full = old_full;
    ASSERT_TRUE(workspace.compute(q_old, dq_old, old_full, ModelTerms::all));
    ASSERT_TRUE(workspace.compute(q_new, dq_new, new_full, ModelTerms::all));
    EXPECT_TRUE(new_full.has_dynamics);
    EXPECT_EQ(new_full.terms, ModelTerms::all);
    for (const ModelTerms terms : selections) {
      SCOPED_TRACE(std::string(ci::to_string(backend)) + " terms " +
                   std::to_string(static_cast<unsigned>(terms)));
      ci::Kinematics k = old_full;
      ASSERT_TRUE(workspace.compute(q_new, dq_new, k, terms));
      EXPECT_EQ(k.terms, terms);
      EXPECT_EQ(k.has_dynamics,
                ci::includes(terms, ModelTerms::mass | ModelTerms::gravity | ModelTerms::coriolis));
      EXPECT_EQ(k.pose.position, new_full.pose.position);
      EXPECT_EQ(k.jacobian, new_full.jacobian);
      const auto expect_term = [&](ModelTerms term, const auto& actual, const auto& fresh,
                                   const auto& stale) {
        if (ci::includes(terms, term)) {
          EXPECT_EQ(actual, fresh);
        } else {
          EXPECT_EQ(actual, stale) << "a term not asked for is left untouched";
        }
      };
      expect_term(ModelTerms::mass, k.mass, new_full.mass, old_full.mass);
      expect_term(ModelTerms::gravity, k.gravity, new_full.gravity, old_full.gravity);
      expect_term(ModelTerms::coriolis, k.coriolis, new_full.coriolis, old_full.coriolis);
      expect_term(ModelTerms::coriolis_transposed, k.coriolis_transposed,
                  new_full.coriolis_transposed, old_full.coriolis_transposed);
    }
    // The bool overload is all or none.
    ci::Kinematics k = old_full;
    ASSERT_TRUE(workspace.compute(q_new, dq_new, k, false));
    EXPECT_EQ(k.terms, ModelTerms::none);
    EXPECT_FALSE(k.has_dynamics);
    EXPECT_EQ(k.mass, old_full.mass);
    ASSERT_TRUE(workspace.compute(q_new, dq_new, k, true));
    EXPECT_EQ(k.terms, ModelTerms::mass | ModelTerms::gravity | ModelTerms::coriolis);
    EXPECT_EQ(k.coriolis, new_full.coriolis);
  }
}

// A failed call leaves out.terms (and every value) as it was.
TEST(ModelTermsSet, AFailedCallChangesNothing) {
  ci::ModelWorkspace workspace(panda());
  ci::Kinematics k = workspace.make_kinematics();
  const ci::JointVector q = vector_of({0.1, -0.4, 0.2, -2.0, 0.3, 1.5, 0.6});
  ASSERT_TRUE(workspace.compute(q, ci::JointVector::Zero(7), k, ci::ModelTerms::gravity));
  const ci::Kinematics before = k;
  ci::JointVector bad = q;
  bad[3] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(workspace.compute(bad, ci::JointVector::Zero(7), k, ci::ModelTerms::all));
  EXPECT_EQ(k.terms, ci::ModelTerms::gravity);
  EXPECT_EQ(k.gravity, before.gravity);
  EXPECT_EQ(k.jacobian, before.jacobian);
}
