// Robot model: forward kinematics against published figures and hand computation (the Panda,
// the iiwa, the UR5e against its published DH table, the planar arm in closed form, sub-chains, a
// handwritten robot), the gravity vector option, and compute() on invalid input, copies and
// threads. The properties every chain has are in model_chain_test.cpp, the load-time errors in
// model_load_errors_test.cpp.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "support/model_fixtures.hpp"

namespace ci = cartesian_impedance;
using namespace model_fixtures;

// ---------------------------------------------------------------------------------------------
// Published figures.

TEST(PandaModel, DescribesTheArm) {
  const ci::RobotModel& model = panda();
  ASSERT_EQ(model.num_joints(), 7);
  EXPECT_EQ(model.robot_name(), "panda");
  EXPECT_EQ(model.base_link(), "panda_link0");
  EXPECT_EQ(model.tip_link(), "panda_link8");
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(model.joint_names()[i], "panda_joint" + std::to_string(i + 1));
    EXPECT_EQ(model.joint_types()[i], ci::JointType::revolute);
  }
  // Franka FCI documentation, as written in the URDF.
  const ci::JointLimits& limits = model.limits();
  EXPECT_EQ(limits.position_lower,
            vector_of({-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973}));
  EXPECT_EQ(limits.position_upper,
            vector_of({2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973}));
  EXPECT_EQ(limits.velocity, vector_of({2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61}));
  EXPECT_EQ(limits.effort, vector_of({87, 87, 87, 87, 12, 12, 12}));
  // Links 1..7 (the base's 2 kg is not moved by any joint): 16.062132 kg (models/README.md).
  EXPECT_NEAR(model.moving_mass(), 16.062132, 1e-9);
  EXPECT_EQ(model.gravity_base(), Eigen::Vector3d(0, 0, -9.81));
  EXPECT_TRUE(model.tool().isApprox(Eigen::Isometry3d::Identity()));
}

TEST(PandaModel, FlangeAtZeroAndAtTheReadyPose) {
  ci::ModelWorkspace workspace(panda());
  // q = 0: every joint offset is exact in the URDF, so only rounding (1e-16 m) separates the
  // flange from (0.088, 0, 0.926); the flange's z axis points down, its x axis forward.
  const Eigen::Isometry3d T_zero = forward_kinematics(workspace, ci::JointVector::Zero(7));
  EXPECT_LT((T_zero.translation() - Eigen::Vector3d(0.088, 0.0, 0.926)).norm(), 1e-12);
  EXPECT_LT((T_zero.linear() - Eigen::Vector3d(1, -1, -1).asDiagonal().toDenseMatrix()).norm(),
            1e-12);
  // Ready pose: the published (0.3069, 0, 0.5903) is rounded to 0.1 mm.
  const ci::JointVector ready = vector_of({0, -kPi / 4, 0, -3 * kPi / 4, 0, kPi / 2, kPi / 4});
  const Eigen::Isometry3d T_ready = forward_kinematics(workspace, ready);
  EXPECT_LT((T_ready.translation() - Eigen::Vector3d(0.3069, 0.0, 0.5903)).norm(), 1e-4);
  EXPECT_LT((T_ready.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12)
      << "the flange points down at the ready pose";
}

TEST(IiwaModel, FlangeAtZeroAndAtTheReadyPose) {
  const ci::RobotModel& model = iiwa();
  ASSERT_EQ(model.num_joints(), 7);
  EXPECT_EQ(model.joint_names().front(), "iiwa_joint_1");
  EXPECT_EQ(model.joint_names().back(), "iiwa_joint_7");
  EXPECT_NEAR(model.limits().position_upper[0], 170 * kPi / 180, 1e-9);
  EXPECT_NEAR(model.limits().position_upper[6], 175 * kPi / 180, 1e-9);
  EXPECT_EQ(model.limits().effort, vector_of({320, 320, 176, 176, 110, 40, 40}));
  EXPECT_NEAR(model.moving_mass(), 24.9, 1e-9);  // models/README.md
  ci::ModelWorkspace workspace(model);
  const Eigen::Isometry3d T_zero = forward_kinematics(workspace, ci::JointVector::Zero(7));
  EXPECT_LT((T_zero.translation() - Eigen::Vector3d(0.0, 0.0, 1.306)).norm(), 1e-12);
  // Ready keyframe of models/README.md, measured there in MuJoCo to 1e-6 m.
  const ci::JointVector ready = vector_of({0, kPi / 6, 0, -kPi / 2, 0, kPi / 3, 0});
  const Eigen::Isometry3d T_ready = forward_kinematics(workspace, ready);
  EXPECT_LT((T_ready.translation() - Eigen::Vector3d(0.556410, 0.0, 0.397731)).norm(), 2e-6);
  EXPECT_LT((T_ready.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
}

// ---------------------------------------------------------------------------------------------
// UR5e and the planar arm (models/ur5e, models/planar3): the URDF against the published standard
// DH table and against closed-form planar kinematics.

namespace {

std::string model_path(const std::string& relative) {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/" + relative;
}

const ci::RobotModel& ur5e() {
  static const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(model_path("ur5e/ur5e.urdf"), "base_link", "tool0");
  return model;
}

const ci::RobotModel& planar3() {
  static const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(model_path("planar3/planar3.urdf"), "base_link", "tool0");
  return model;
}

// Universal Robots, "DH parameters for calculations of kinematics and dynamics", UR5e: standard
// DH, T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i); link masses [kg] and centres of mass [m] in
// DH frame i.
constexpr double kUrD[6] = {0.1625, 0, 0, 0.1333, 0.0997, 0.0996};
constexpr double kUrA[6] = {0, -0.425, -0.3922, 0, 0, 0};
constexpr double kUrAlpha[6] = {kPi / 2, 0, 0, kPi / 2, -kPi / 2, 0};
constexpr double kUrMass[6] = {3.761, 8.058, 2.846, 1.37, 1.3, 0.365};
constexpr double kUrCom[6][3] = {{0, -0.02561, 0.00193}, {0.2125, 0, 0.11336}, {0.15, 0, 0.0265},
                                 {0, -0.0018, 0.01634},  {0, 0.0018, 0.01634}, {0, 0, -0.001159}};

// DH frames 0..6 at q: frames[0] is the base, frames[6] the flange.
std::vector<Eigen::Isometry3d> ur5e_dh_frames(const ci::JointVector& q) {
  std::vector<Eigen::Isometry3d> frames{Eigen::Isometry3d::Identity()};
  for (int i = 0; i < 6; ++i) {
    Eigen::Isometry3d link = Eigen::Isometry3d::Identity();
    link.rotate(Eigen::AngleAxisd(q[i], Eigen::Vector3d::UnitZ()));
    link.translate(Eigen::Vector3d(kUrA[i], 0, kUrD[i]));
    link.rotate(Eigen::AngleAxisd(kUrAlpha[i], Eigen::Vector3d::UnitX()));
    frames.push_back(frames.back() * link);
  }
  return frames;
}

// Uniform within the position limits (the UR5e's +-2 pi, unlike random_configuration's +-pi).
ci::JointVector uniform_in_limits(const ci::RobotModel& model, std::mt19937& rng) {
  ci::JointVector q(model.num_joints());
  for (int i = 0; i < model.num_joints(); ++i) {
    q[i] = std::uniform_real_distribution<double>(model.limits().position_lower[i],
                                                  model.limits().position_upper[i])(rng);
  }
  return q;
}

double smallest_singular_value(const Eigen::MatrixXd& matrix) {
  return Eigen::JacobiSVD<Eigen::MatrixXd>(matrix).singularValues().minCoeff();
}

// Start configurations of models/README.md.
ci::JointVector ur5e_start() {
  return vector_of({kPi, -kPi / 2, kPi / 2, -kPi / 2, -kPi / 2, 0});
}
ci::JointVector planar3_start() {
  return vector_of({0.5, 1.5, kPi - 2.0});
}

constexpr double kPlanarLength[3] = {0.4, 0.35, 0.15};
constexpr double kPlanarMass[3] = {3, 2, 0.5};
constexpr double kPedestal = 0.3;

}  // namespace

TEST(Ur5eModel, DescribesTheArm) {
  const ci::RobotModel& model = ur5e();
  ASSERT_EQ(model.num_joints(), 6);
  EXPECT_EQ(model.robot_name(), "ur5e");
  EXPECT_EQ(model.joint_names(),
            (std::vector<std::string>{"shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                      "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"}));
  for (ci::JointType type : model.joint_types()) EXPECT_EQ(type, ci::JointType::revolute);
  // UR5e data sheet: +-360 deg, 180 deg/s, 150 Nm (size 3) and 28 Nm (size 1).
  EXPECT_EQ(model.limits().position_lower, ci::JointVector::Constant(6, -2 * kPi));
  EXPECT_EQ(model.limits().position_upper, ci::JointVector::Constant(6, 2 * kPi));
  EXPECT_EQ(model.limits().velocity, ci::JointVector::Constant(6, kPi));
  EXPECT_EQ(model.limits().effort, vector_of({150, 150, 150, 28, 28, 28}));
  // The six published link masses; the base (2.9 kg, to the data sheet's 20.6 kg) is not moved.
  double published = 0.0;
  for (double mass : kUrMass) published += mass;
  EXPECT_NEAR(published, 17.7, 1e-12);
  EXPECT_NEAR(model.moving_mass(), published, 1e-12);
}

TEST(Ur5eModel, FlangeIsThePublishedStandardDhForwardKinematics) {
  ci::ModelWorkspace workspace(ur5e());
  // q = 0: the arm stretched along -x, the flange 0.1333 + 0.0996 m to the side.
  const Eigen::Isometry3d T_zero = forward_kinematics(workspace, ci::JointVector::Zero(6));
  EXPECT_LT((T_zero.translation() - Eigen::Vector3d(-0.8172, -0.2329, 0.0628)).norm(), 1e-12);
  std::mt19937 rng(12);
  double worst = 0.0;
  for (int k = 0; k < 1000; ++k) {
    const ci::JointVector q = uniform_in_limits(ur5e(), rng);
    const Eigen::Isometry3d expected = ur5e_dh_frames(q).back();
    const Eigen::Isometry3d actual = forward_kinematics(workspace, q);
    worst = std::max(worst, (actual.matrix() - expected.matrix()).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 1e-12);
}

TEST(Ur5eModel, GravityIsThatOfThePublishedMassesAndCentresOfMass) {
  // Holding torque tau_j = sum over links i >= j of (z_{j-1} x (c_i - o_{j-1})) . (m_i 9.81 e_z),
  // with the centres of mass c_i taken from the published table in DH frame i: checks how the
  // URDF wrote them in its link frames. (Inertia tensors do not enter g(q).)
  ci::ModelWorkspace workspace(ur5e());
  ci::Kinematics kinematics = workspace.make_kinematics();
  std::mt19937 rng(13);
  for (int k = 0; k < 200; ++k) {
    const ci::JointVector q = uniform_in_limits(ur5e(), rng);
    ASSERT_TRUE(workspace.compute(q, ci::JointVector::Zero(6), kinematics, true));
    const std::vector<Eigen::Isometry3d> frames = ur5e_dh_frames(q);
    ci::JointVector expected = ci::JointVector::Zero(6);
    for (int i = 0; i < 6; ++i) {
      const Eigen::Vector3d com =
          frames[i + 1] * Eigen::Vector3d(kUrCom[i][0], kUrCom[i][1], kUrCom[i][2]);
      for (int j = 0; j <= i; ++j) {
        const Eigen::Vector3d axis = frames[j].linear().col(2);
        expected[j] +=
            axis.cross(com - frames[j].translation()).dot(Eigen::Vector3d(0, 0, kUrMass[i] * 9.81));
      }
    }
    EXPECT_LT((kinematics.gravity - expected).cwiseAbs().maxCoeff(), 1e-11) << q.transpose();
  }
}

TEST(Ur5eModel, StartConfigurationIsFarFromSingularities) {
  ci::ModelWorkspace workspace(ur5e());
  ci::Kinematics kinematics = workspace.make_kinematics();
  ASSERT_TRUE(workspace.compute(ur5e_start(), ci::JointVector::Zero(6), kinematics));
  // models/README.md: flange in front of the robot at (0.4919, 0.1333, 0.4879) m, pointing down;
  // smallest singular value of the 6 x 6 Jacobian 0.2224.
  EXPECT_LT((kinematics.pose.position - Eigen::Vector3d(0.4919, 0.1333, 0.4879)).norm(), 1e-4);
  EXPECT_LT(
      (kinematics.pose.orientation * Eigen::Vector3d::UnitZ() - Eigen::Vector3d(0, 0, -1)).norm(),
      1e-12);
  EXPECT_NEAR(smallest_singular_value(kinematics.jacobian), 0.2224, 1e-4);
}

TEST(Planar3Model, DescribesTheArm) {
  const ci::RobotModel& model = planar3();
  ASSERT_EQ(model.num_joints(), 3);
  EXPECT_EQ(model.robot_name(), "planar3");
  EXPECT_EQ(model.joint_names(), (std::vector<std::string>{"joint1", "joint2", "joint3"}));
  EXPECT_EQ(model.limits().position_lower, ci::JointVector::Constant(3, -2.6));
  EXPECT_EQ(model.limits().position_upper, ci::JointVector::Constant(3, 2.6));
  EXPECT_EQ(model.limits().velocity, ci::JointVector::Constant(3, 2.0));
  EXPECT_EQ(model.limits().effort, vector_of({60, 40, 10}));
  EXPECT_NEAR(model.moving_mass(), kPlanarMass[0] + kPlanarMass[1] + kPlanarMass[2], 1e-12);
}

TEST(Planar3Model, KinematicsAndGravityInClosedForm) {
  ci::ModelWorkspace workspace(planar3());
  ci::Kinematics kinematics = workspace.make_kinematics();
  std::mt19937 rng(14);
  for (int k = 0; k < 1000; ++k) {
    const ci::JointVector q = uniform_in_limits(planar3(), rng);
    ASSERT_TRUE(workspace.compute(q, ci::JointVector::Zero(3), kinematics, true));
    // phi_i = q_1 + ... + q_i; link i points along (sin phi_i, 0, cos phi_i).
    double phi[3];
    phi[0] = q[0];
    phi[1] = phi[0] + q[1];
    phi[2] = phi[1] + q[2];
    Eigen::Vector3d tip(0, 0, kPedestal);
    for (int i = 0; i < 3; ++i) {
      tip += kPlanarLength[i] * Eigen::Vector3d(std::sin(phi[i]), 0, std::cos(phi[i]));
    }
    const Eigen::Isometry3d T = isometry(kinematics.pose);
    EXPECT_LT((T.translation() - tip).norm(), 1e-12);
    EXPECT_LT((T.linear() - Eigen::AngleAxisd(phi[2], Eigen::Vector3d::UnitY()).toRotationMatrix())
                  .norm(),
              1e-12);
    // Only x, z and the rotation about y move: rows y, rot-x, rot-z are zero.
    for (int row : {1, 3, 5}) EXPECT_EQ(kinematics.jacobian.row(row).cwiseAbs().maxCoeff(), 0.0);
    for (int j = 0; j < 3; ++j) {
      double dx = 0.0, dz = 0.0;
      for (int i = j; i < 3; ++i) {
        dx += kPlanarLength[i] * std::cos(phi[i]);
        dz -= kPlanarLength[i] * std::sin(phi[i]);
      }
      EXPECT_NEAR(kinematics.jacobian(0, j), dx, 1e-12);
      EXPECT_NEAR(kinematics.jacobian(2, j), dz, 1e-12);
      EXPECT_NEAR(kinematics.jacobian(4, j), 1.0, 1e-12);
    }
    // g_j = dV/dq_j, V = 9.81 sum m_i z_i, centre of mass i at half the link.
    ci::JointVector gravity = ci::JointVector::Zero(3);
    for (int j = 0; j < 3; ++j) {
      for (int i = j; i < 3; ++i) {
        double lever = 0.5 * kPlanarLength[i] * std::sin(phi[i]);
        for (int l = j; l < i; ++l) lever += kPlanarLength[l] * std::sin(phi[l]);
        gravity[j] -= 9.81 * kPlanarMass[i] * lever;
      }
    }
    EXPECT_LT((kinematics.gravity - gravity).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(Planar3Model, StartConfigurationIsFarFromSingularities) {
  ci::ModelWorkspace workspace(planar3());
  ci::Kinematics kinematics = workspace.make_kinematics();
  ASSERT_TRUE(workspace.compute(planar3_start(), ci::JointVector::Zero(3), kinematics));
  // models/README.md: flange at (0.5100, 0, 0.3554) m pointing down (phi_3 = pi); smallest
  // singular value of the controllable rows x, z, rot-y 0.2010 (the 3 x 3 determinant is
  // -0.4 * 0.35 * sin(q2): singular only with the elbow stretched or folded).
  EXPECT_LT((kinematics.pose.position - Eigen::Vector3d(0.5100, 0, 0.3554)).norm(), 1e-4);
  EXPECT_LT(
      (kinematics.pose.orientation * Eigen::Vector3d::UnitZ() - Eigen::Vector3d(0, 0, -1)).norm(),
      1e-12);
  Eigen::MatrixXd controllable(3, 3);
  controllable << kinematics.jacobian.row(0), kinematics.jacobian.row(2),
      kinematics.jacobian.row(4);
  EXPECT_NEAR(controllable.determinant(), -0.4 * 0.35 * std::sin(1.5), 1e-12);
  EXPECT_NEAR(smallest_singular_value(controllable), 0.2010, 1e-4);
}

// ---------------------------------------------------------------------------------------------
// Sub-chains: six joints, and a base that is not the URDF's root.

TEST(SubChain, IiwaToLinkSixByHand) {
  const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(iiwa_path(), "iiwa_link_0", "iiwa_link_6");
  ASSERT_EQ(model.num_joints(), 6);
  EXPECT_EQ(model.joint_names().back(), "iiwa_joint_6");
  ci::ModelWorkspace workspace(model);
  // Link 6 is the wrist centre: 0.36 m up to joint 2, then 0.42 + 0.40 m of arm.
  const auto wrist = [&](std::initializer_list<double> q) -> Eigen::Vector3d {
    return forward_kinematics(workspace, vector_of(q)).translation();
  };
  EXPECT_LT((wrist({0, 0, 0, 0, 0, 0}) - Eigen::Vector3d(0, 0, 1.18)).norm(), 1e-12);
  // Joint 2 at +90 deg lays the arm along +x (positive joint 2 leans forward, as in the ready
  // pose); joint 1 at +90 deg then turns it to +y; joints 5 and 6 do not move the wrist centre.
  EXPECT_LT((wrist({0, kPi / 2, 0, 0, 0.7, -1.1}) - Eigen::Vector3d(0.82, 0, 0.36)).norm(), 1e-12);
  EXPECT_LT((wrist({kPi / 2, kPi / 2, 0, 0, 0, 0}) - Eigen::Vector3d(0, 0.82, 0.36)).norm(), 1e-12);
  // Elbow (joint 4) at +90 deg with joint 2 at 0: the forearm (0.40 m) leans the same way.
  EXPECT_LT((wrist({0, 0, 0, kPi / 2, 0, 0}) - Eigen::Vector3d(-0.40, 0, 0.78)).norm(), 1e-12)
      << "forearm direction at joint 4 = +90 deg";
}

TEST(SubChain, ChainsCompose) {
  // T_0_8(q) = T_0_3(q1..q3) T_3_8(q4..q7): the base of the second model is an inner link.
  const ci::RobotModel upper =
      ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link3");
  const ci::RobotModel lower =
      ci::RobotModel::from_urdf_file(panda_path(), "panda_link3", "panda_link8");
  ASSERT_EQ(upper.num_joints(), 3);
  ASSERT_EQ(lower.num_joints(), 4);
  EXPECT_EQ(lower.joint_names().front(), "panda_joint4");
  ci::ModelWorkspace full(panda()), first(upper), second(lower);
  std::mt19937 rng(7);
  for (int k = 0; k < 20; ++k) {
    const ci::JointVector q = random_configuration(panda(), rng);
    const Eigen::Isometry3d composed =
        forward_kinematics(first, q.head(3)) * forward_kinematics(second, q.tail(4));
    EXPECT_LT((composed.matrix() - forward_kinematics(full, q).matrix()).norm(), 1e-14);
  }
}

// ---------------------------------------------------------------------------------------------
// The handwritten robot: everything by hand (see kSliderUrdf).

class SliderModel : public ::testing::Test {
 protected:
  const ci::RobotModel model = ci::RobotModel::from_urdf_string(kSliderUrdf, "base", "tip");
  // sum of m r over the bodies the spin joint swings: arm, weight, plate [kg m]
  static constexpr double kMomentArm = 2 * 0.15 + 0.5 * 0.1 + 0.25 * 0.35;
  // moment of inertia about the spin axis: m r^2 of each, plus the arm's own 0.01 [kg m^2]
  static constexpr double kSpinInertia =
      2 * 0.15 * 0.15 + 0.5 * 0.1 * 0.1 + 0.25 * 0.35 * 0.35 + 0.01;
  static constexpr double kMovingMass = 3 + 2 + 0.5 + 0.25;  // finger and base excluded
};

TEST_F(SliderModel, NamesTypesAndLimits) {
  ASSERT_EQ(model.num_joints(), 2);
  EXPECT_EQ(model.joint_names(), (std::vector<std::string>{"slide", "spin"}));
  EXPECT_EQ(model.joint_types(),
            (std::vector<ci::JointType>{ci::JointType::prismatic, ci::JointType::continuous}));
  EXPECT_STREQ(ci::to_string(ci::JointType::prismatic), "prismatic");
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(model.limits().position_lower, vector_of({-0.4, -inf}));
  EXPECT_EQ(model.limits().position_upper, vector_of({0.6, inf}));
  EXPECT_EQ(model.limits().velocity, vector_of({0.5, inf}));  // spin has no <limit>
  EXPECT_EQ(model.limits().effort, vector_of({100, inf}));
  EXPECT_NEAR(model.moving_mass(), kMovingMass, 1e-15);
}

TEST_F(SliderModel, KinematicsByHand) {
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  std::mt19937 rng(3);
  for (int k = 0; k < 50; ++k) {
    const ci::JointVector q = random_configuration(model, rng);
    ASSERT_TRUE(workspace.compute(q, ci::JointVector::Zero(2), kinematics));
    const double d = q[0], c = std::cos(q[1]), s = std::sin(q[1]);
    // tip = (d + 0.2, 0, 0.5) + Rx(90 deg) Rz(theta) (0.3, 0, 0)
    EXPECT_LT(
        (kinematics.pose.position - Eigen::Vector3d(d + 0.2 + 0.3 * c, 0, 0.5 + 0.3 * s)).norm(),
        1e-15);
    const Eigen::Matrix3d rotation = (Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitX()) *
                                      Eigen::AngleAxisd(q[1], Eigen::Vector3d::UnitZ()))
                                         .toRotationMatrix();
    // The pose carries a quaternion: matrix -> quaternion -> matrix costs a few eps.
    EXPECT_LT((kinematics.pose.orientation.toRotationMatrix() - rotation).norm(), 1e-14);
    ci::Jacobian expected(6, 2);
    expected.col(0) << 1, 0, 0, 0, 0, 0;                // slide: translation along x
    expected.col(1) << -0.3 * s, 0, 0.3 * c, 0, -1, 0;  // spin: about -y, lever 0.3 m
    EXPECT_LT((kinematics.jacobian - expected).norm(), 1e-15);
  }
}

TEST_F(SliderModel, DynamicsByHand) {
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  std::mt19937 rng(4);
  for (int k = 0; k < 50; ++k) {
    const ci::JointVector q = random_configuration(model, rng);
    const ci::JointVector dq = random_velocity(2, rng, 2.0);
    ASSERT_TRUE(workspace.compute(q, dq, kinematics, true));
    EXPECT_TRUE(kinematics.has_dynamics);
    const double c = std::cos(q[1]), s = std::sin(q[1]);
    // Centres of mass: x = d + 0.2 + r c, z = 0.5 + r s for the swinging bodies.
    ci::JointMatrix mass(2, 2);
    mass << kMovingMass, -kMomentArm * s, -kMomentArm * s, kSpinInertia;
    EXPECT_LT((kinematics.mass - mass).norm(), 1e-14);
    // Holding torque dV/dq with V = 9.81 sum m z: nothing for the horizontal slide.
    EXPECT_LT((kinematics.gravity - vector_of({0, 9.81 * kMomentArm * c})).norm(), 1e-13);
    // Lagrange: the slide feels the centrifugal pull -a cos(theta) dtheta^2; the spin joint
    // feels nothing (its inertia does not depend on theta or d).
    EXPECT_LT((kinematics.coriolis - vector_of({-kMomentArm * c * dq[1] * dq[1], 0})).norm(),
              1e-14);
  }
}

// ---------------------------------------------------------------------------------------------
// Gravity vector option.

TEST(Gravity, FollowsTheGravityVector) {
  const std::string xml = read_text(panda_path());
  const auto model_with = [&](const Eigen::Vector3d& gravity) {
    return ci::RobotModel::from_urdf_string(xml, "panda_link0", "panda_link8",
                                            Eigen::Isometry3d::Identity(), gravity);
  };
  const ci::RobotModel standard = model_with(Eigen::Vector3d(0, 0, -9.81));
  const ci::RobotModel weightless = model_with(Eigen::Vector3d::Zero());
  const ci::RobotModel sideways = model_with(Eigen::Vector3d(0, 9.81, 0));
  EXPECT_EQ(sideways.gravity_base(), Eigen::Vector3d(0, 9.81, 0));
  const ci::JointVector q = vector_of({0.3, -0.5, 0.2, -2.0, 0.1, 1.6, 0.5});
  const auto gravity_of = [&q](const ci::RobotModel& model) {
    ci::ModelWorkspace workspace(model);
    ci::Kinematics kinematics = workspace.make_kinematics();
    EXPECT_TRUE(workspace.compute(q, ci::JointVector::Zero(7), kinematics, true));
    return ci::JointVector(kinematics.gravity);
  };
  EXPECT_EQ(gravity_of(weightless), ci::JointVector::Zero(7));
  // Gravity torques are linear in the gravity vector; joint 1 (vertical axis) holds nothing
  // under vertical gravity but does under sideways gravity.
  const ci::JointVector down = gravity_of(standard);
  EXPECT_LT(std::abs(down[0]), 1e-12);
  EXPECT_GT(std::abs(gravity_of(sideways)[0]), 1.0);
  EXPECT_LT((gravity_of(model_with(Eigen::Vector3d(0, 0, 9.81))) + down).norm(), 1e-12);
}

TEST(Gravity, PandaReadyPoseMatchesMuJoCo) {
  // |tau_g| at `ready` measured in MuJoCo from the same URDF (models/README.md, 2 decimals).
  ci::ModelWorkspace workspace(panda());
  ci::Kinematics kinematics = workspace.make_kinematics();
  const ci::JointVector ready = vector_of({0, -kPi / 4, 0, -3 * kPi / 4, 0, kPi / 2, kPi / 4});
  ASSERT_TRUE(workspace.compute(ready, ci::JointVector::Zero(7), kinematics, true));
  const ci::JointVector published = vector_of({0, 1.77, 0.64, 18.57, 0.63, 1.69, 0});
  EXPECT_LT((kinematics.gravity.cwiseAbs() - published).cwiseAbs().maxCoeff(), 0.005 + 1e-12);
}

// ---------------------------------------------------------------------------------------------
// compute(): invalid input, sizing, copies, threads, RobotState.

TEST(Workspace, RejectsWrongSizesAndNonFiniteInputWithoutTouchingTheResult) {
  ci::ModelWorkspace workspace(panda());
  ci::Kinematics kinematics = workspace.make_kinematics();
  const ci::JointVector q = vector_of({0.1, -0.4, 0.2, -2.0, 0.1, 1.5, 0.3});
  const ci::JointVector dq = ci::JointVector::Constant(7, 0.2);
  ASSERT_TRUE(workspace.compute(q, dq, kinematics, true));
  const ci::Kinematics good = kinematics;
  const double nan = std::nan("");
  ci::JointVector q_nan = q, dq_inf = dq;
  q_nan[3] = nan;
  dq_inf[6] = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(workspace.compute(q.head(6), dq.head(6), kinematics, true));
  EXPECT_FALSE(workspace.compute(q, dq.head(6), kinematics, true));
  EXPECT_FALSE(workspace.compute(q_nan, dq, kinematics, true));
  EXPECT_FALSE(workspace.compute(q, dq_inf, kinematics, false));
  EXPECT_FALSE(workspace.compute_pose(q_nan, kinematics.pose));
  EXPECT_EQ(kinematics.pose.position, good.pose.position);
  EXPECT_EQ(kinematics.pose.orientation.coeffs(), good.pose.orientation.coeffs());
  EXPECT_EQ(kinematics.jacobian, good.jacobian);
  EXPECT_EQ(kinematics.mass, good.mass);
  EXPECT_EQ(kinematics.gravity, good.gravity);
  EXPECT_EQ(kinematics.coriolis, good.coriolis);
  EXPECT_TRUE(kinematics.has_dynamics);
}

TEST(Workspace, SizesAndCleansAnUnpreparedResult) {
  ci::ModelWorkspace workspace(panda());
  ci::Kinematics empty;  // 6 x 0 Jacobian, empty dynamics
  EXPECT_FALSE(workspace.compute(ci::JointVector::Zero(3), ci::JointVector::Zero(3), empty));
  EXPECT_EQ(empty.jacobian.cols(), 7);
  EXPECT_EQ(empty.mass.rows(), 7);
  EXPECT_TRUE(empty.jacobian.allFinite() && empty.mass.allFinite() && empty.gravity.allFinite());
  ci::Kinematics garbage = workspace.make_kinematics();
  garbage.pose.position.x() = std::nan("");
  garbage.mass(2, 3) = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(workspace.compute(ci::JointVector::Zero(7), ci::JointVector::Constant(7, NAN),
                                 garbage, true));
  EXPECT_TRUE(garbage.pose.position.allFinite() && garbage.mass.allFinite());
  EXPECT_FALSE(garbage.has_dynamics);
  ci::Kinematics fresh;
  ASSERT_TRUE(workspace.compute(ci::JointVector::Zero(7), ci::JointVector::Zero(7), fresh));
  EXPECT_FALSE(fresh.has_dynamics) << "kinematics only";
  EXPECT_LT((fresh.pose.position - Eigen::Vector3d(0.088, 0, 0.926)).norm(), 1e-12);
}

TEST(Workspace, DynamicsOffLeavesThePreviousDynamics) {
  ci::ModelWorkspace workspace(iiwa());
  ci::Kinematics kinematics = workspace.make_kinematics();
  const ci::JointVector dq = ci::JointVector::Constant(7, 0.5);
  ASSERT_TRUE(workspace.compute(ci::JointVector::Constant(7, 0.3), dq, kinematics, true));
  const ci::JointVector gravity = kinematics.gravity;
  ASSERT_TRUE(workspace.compute(ci::JointVector::Constant(7, -0.3), dq, kinematics, false));
  EXPECT_EQ(kinematics.gravity, gravity);
  EXPECT_FALSE(kinematics.has_dynamics);
}

TEST(Workspace, CopiesAndMovesWork) {
  ci::ModelWorkspace original(panda());
  ci::ModelWorkspace copy(original);
  ci::ModelWorkspace moved(std::move(copy));
  const ci::JointVector q = ci::JointVector::Constant(7, 0.2);
  const ci::JointVector dq = ci::JointVector::Constant(7, 0.1);
  ci::Kinematics a = original.make_kinematics(), b = a;
  ASSERT_TRUE(original.compute(q, dq, a, true));
  ASSERT_TRUE(moved.compute(q, dq, b, true));
  EXPECT_EQ(a.jacobian, b.jacobian);
  EXPECT_EQ(a.coriolis, b.coriolis);
  EXPECT_FALSE(copy.compute(q, dq, b, true));  // NOLINT(bugprone-use-after-move): documented
  copy = original;
  EXPECT_TRUE(copy.compute(q, dq, b, true));
  EXPECT_EQ(&moved.model().tip_link(), &panda().tip_link()) << "copies share the model's data";
}

TEST(Workspace, WorkspacesOfOneModelRunInParallel) {
  // KDL caches each joint's last rotation inside the chain; every workspace owns a copy of the
  // chain, so workspaces of one model in different threads must not disturb each other.
  const ci::RobotModel& model = panda();
  std::mt19937 rng(17);
  std::vector<ci::JointVector> configurations;
  for (int k = 0; k < 64; ++k) configurations.push_back(random_configuration(model, rng));
  std::vector<ci::Jacobian> expected;
  {
    ci::ModelWorkspace workspace(model);
    ci::Kinematics kinematics = workspace.make_kinematics();
    for (const ci::JointVector& q : configurations) {
      workspace.compute(q, ci::JointVector::Zero(7), kinematics);
      expected.push_back(kinematics.jacobian);
    }
  }
  std::vector<int> mismatches(2, 0);
  const auto run = [&](int thread) {
    ci::ModelWorkspace workspace(model);
    ci::Kinematics kinematics = workspace.make_kinematics();
    for (int round = 0; round < 200; ++round) {
      for (std::size_t k = thread; k < configurations.size(); k += 2) {
        workspace.compute(configurations[k], ci::JointVector::Zero(7), kinematics);
        mismatches[thread] += kinematics.jacobian != expected[k];
      }
    }
  };
  std::thread first(run, 0), second(run, 1);
  first.join();
  second.join();
  EXPECT_EQ(mismatches[0] + mismatches[1], 0);
}

TEST(Workspace, FillsARobotState) {
  ci::ModelWorkspace workspace(iiwa());
  ci::Kinematics kinematics = workspace.make_kinematics();
  const ci::JointVector q = ci::JointVector::Constant(7, 0.25);
  const ci::JointVector dq = ci::JointVector::Constant(7, -0.5);
  ASSERT_TRUE(workspace.compute(q, dq, kinematics));
  ci::RobotState state;
  ci::fill_robot_state(q, dq, kinematics, state);
  EXPECT_EQ(state.q, q);
  EXPECT_EQ(state.dq, dq);
  EXPECT_EQ(state.pose.position, kinematics.pose.position);
  EXPECT_EQ(state.pose.orientation.coeffs(), kinematics.pose.orientation.coeffs());
  EXPECT_EQ(state.jacobian, kinematics.jacobian);
}

// ---------------------------------------------------------------------------------------------
// Start configurations: how near a singularity and a joint limit.

TEST(ConfigurationCheck, NamesTheSmallestSingularValueAndTheNearestLimit) {
  const ci::RobotModel& model = panda();
  // q = 0: the Panda stands upright, joints 1 and 3 (and 5 and 7) on one vertical line, so the
  // Jacobian loses a rank; joint 4 is 0.0698 rad outside its upper limit -0.0698.
  const ci::ConfigurationCheck upright = ci::check_configuration(model, ci::JointVector::Zero(7));
  ASSERT_EQ(upright.singular_values.size(), 6);
  EXPECT_LT(upright.singular_values[5], 1e-9);
  EXPECT_EQ(upright.closest_joint, 3);
  EXPECT_NEAR(upright.limit_distance, -0.0698, 1e-12);
  ASSERT_EQ(upright.warnings.size(), 2u);
  EXPECT_NE(upright.warnings[0].find("singular: the smallest singular value"), std::string::npos)
      << upright.warnings[0];
  EXPECT_NE(upright.warnings[1].find("panda_joint4 is at 0, -0.0698 from its upper limit -0.0698 "
                                     "(outside its range)"),
            std::string::npos)
      << upright.warnings[1];

  // The ready pose: well conditioned, 0.72 rad from the nearest limit (joint 4 at -3 pi / 4, its
  // lower limit -3.0718).
  const ci::JointVector ready = vector_of({0, -kPi / 4, 0, -3 * kPi / 4, 0, kPi / 2, kPi / 4});
  const ci::ConfigurationCheck good = ci::check_configuration(model, ready);
  EXPECT_TRUE(good.warnings.empty());
  EXPECT_GT(good.singular_values[5], 0.05);
  EXPECT_EQ(good.closest_joint, 3);
  EXPECT_NEAR(good.limit_distance, 3.0718 - 3 * kPi / 4, 1e-12);
  // The singular values are the Jacobian's.
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  ASSERT_TRUE(workspace.compute(ready, ci::JointVector::Zero(7), kinematics));
  const Eigen::MatrixXd product = kinematics.jacobian * kinematics.jacobian.transpose();
  Eigen::VectorXd eigen = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(product).eigenvalues();
  EXPECT_NEAR(std::sqrt(eigen[0]), good.singular_values[5], 1e-9);

  // Near, not at: 0.05 rad from joint 6's lower limit is named with the default margin 0.1.
  ci::JointVector near = ready;
  near[5] = -0.0175 + 0.05;
  const ci::ConfigurationCheck close = ci::check_configuration(model, near);
  ASSERT_EQ(close.warnings.size(), 1u);
  EXPECT_NE(close.warnings[0].find("panda_joint6"), std::string::npos) << close.warnings[0];
  EXPECT_NE(close.warnings[0].find("lower limit"), std::string::npos) << close.warnings[0];

  EXPECT_THROW(ci::check_configuration(model, ci::JointVector::Zero(6)), ci::Error);
  ci::JointVector bad = ready;
  bad[2] = std::nan("");
  EXPECT_THROW(ci::check_configuration(model, bad), ci::Error);
}
