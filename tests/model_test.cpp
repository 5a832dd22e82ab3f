// Robot model: forward kinematics against published figures and hand computation, the Jacobian
// against finite differences, the dynamics against independent constructions from the URDF's
// inertial data (read here with urdfdom, one body at a time), and every load-time error.

#include <console_bridge/console.h>
#include <gtest/gtest.h>
#include <urdf_parser/urdf_parser.h>

#include <Eigen/Dense>
#include <cmath>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>
#include <thread>

#include "cartesian_impedance/error.hpp"
#include "cartesian_impedance/robot_model.hpp"

namespace ci = cartesian_impedance;

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string read_text(const std::string& path) {
  std::ifstream file(path);
  return std::string(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
}

std::string panda_path() {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf";
}
std::string iiwa_path() {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/iiwa14/iiwa14.urdf";
}

// A handwritten robot with a prismatic and a continuous joint, whose kinematics and dynamics are
// worked out by hand below (SliderModel tests):
//  - slide (prismatic along base x, at z = 0.5) moves `carriage` (3 kg, centre 0.05 m along x);
//  - spin (continuous, 0.2 m further along x, frame rolled by +90 deg about x so that its axis,
//    the local z, is the base's -y) turns `arm` (2 kg, centre 0.15 m along the arm's x, its
//    inertial frame pitched by +90 deg so that the URDF's ixx = 0.01 is the moment about the
//    spin axis);
//  - `weight` (0.5 kg point mass) is fixed to the arm 0.1 m along its x (a side branch);
//  - the tip is fixed to the arm 0.3 m along its x; `plate` (0.25 kg point mass) is fixed to the
//    tip 0.05 m further; `finger` (1 kg) hangs off the tip by a revolute joint, so it is not part
//    of the chain base -> tip, nor is the base's own 100 kg.
const char* const kSliderUrdf = R"(<?xml version="1.0"?>
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

// One chain under test: where it comes from and which links bound it.
struct ChainCase {
  const char* name;
  std::function<std::string()> xml;
  std::string base;
  std::string tip;
};

std::ostream& operator<<(std::ostream& stream, const ChainCase& chain) {
  return stream << chain.name;
}

const std::vector<ChainCase>& chain_cases() {
  static const std::vector<ChainCase> cases = {
      {"panda", [] { return read_text(panda_path()); }, "panda_link0", "panda_link8"},
      {"iiwa14", [] { return read_text(iiwa_path()); }, "iiwa_link_0", "iiwa_link_ee"},
      {"iiwa14_to_link6", [] { return read_text(iiwa_path()); }, "iiwa_link_0", "iiwa_link_6"},
      {"panda_link3_to_flange", [] { return read_text(panda_path()); }, "panda_link3",
       "panda_link8"},
      {"slider", [] { return std::string(kSliderUrdf); }, "base", "tip"},
  };
  return cases;
}

ci::RobotModel load(const ChainCase& chain,
                    const Eigen::Isometry3d& tool = Eigen::Isometry3d::Identity()) {
  return ci::RobotModel::from_urdf_string(chain.xml(), chain.base, chain.tip, tool);
}

const ci::RobotModel& panda() {
  static const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8");
  return model;
}

const ci::RobotModel& iiwa() {
  static const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(iiwa_path(), "iiwa_link_0", "iiwa_link_ee");
  return model;
}

ci::JointVector vector_of(std::initializer_list<double> values) {
  ci::JointVector v(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double value : values) v[i++] = value;
  return v;
}

// Uniform within the position limits (continuous joints: one turn either way).
ci::JointVector random_configuration(const ci::RobotModel& model, std::mt19937& rng) {
  ci::JointVector q(model.num_joints());
  for (int i = 0; i < model.num_joints(); ++i) {
    const double lower = std::max(model.limits().position_lower[i], -kPi);
    const double upper = std::min(model.limits().position_upper[i], kPi);
    q[i] = std::uniform_real_distribution<double>(lower, upper)(rng);
  }
  return q;
}

ci::JointVector random_velocity(int n, std::mt19937& rng, double magnitude) {
  ci::JointVector dq(n);
  for (int i = 0; i < n; ++i) {
    dq[i] = std::uniform_real_distribution<double>(-magnitude, magnitude)(rng);
  }
  return dq;
}

Eigen::Isometry3d isometry(const ci::Pose& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = pose.orientation.toRotationMatrix();
  T.translation() = pose.position;
  return T;
}

Eigen::Isometry3d forward_kinematics(ci::ModelWorkspace& workspace, const ci::JointVector& q) {
  ci::Pose pose;
  EXPECT_TRUE(workspace.compute_pose(q, pose));
  return isometry(pose);
}

Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& rotation) {
  const Eigen::AngleAxisd angle_axis(rotation);
  return angle_axis.angle() * angle_axis.axis();
}

// Column i: central difference of the position, and the rotation vector of
// R(q + h e_i) R(q - h e_i)^T over 2h (the angular velocity in the base frame).
ci::Jacobian finite_difference_jacobian(ci::ModelWorkspace& workspace, const ci::JointVector& q,
                                        double h) {
  const Eigen::Index n = q.size();
  ci::Jacobian jacobian(6, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    ci::JointVector plus = q, minus = q;
    plus[i] += h;
    minus[i] -= h;
    const Eigen::Isometry3d T_plus = forward_kinematics(workspace, plus);
    const Eigen::Isometry3d T_minus = forward_kinematics(workspace, minus);
    jacobian.block<3, 1>(0, i) = (T_plus.translation() - T_minus.translation()) / (2 * h);
    jacobian.block<3, 1>(3, i) =
        rotation_vector(T_plus.linear() * T_minus.linear().transpose()) / (2 * h);
  }
  return jacobian;
}

ci::JointMatrix mass_at(ci::ModelWorkspace& workspace, const ci::JointVector& q) {
  ci::Kinematics kinematics = workspace.make_kinematics();
  EXPECT_TRUE(workspace.compute(q, ci::JointVector::Zero(q.size()), kinematics, true));
  return kinematics.mass;
}

// ---------------------------------------------------------------------------------------------
// An independent description of the chain's bodies, read from the URDF with urdfdom: every link
// below the base that hangs off a chain link by fixed joints only (so it moves with the chain),
// behind at least one movable joint, each kept separately (no lumping), with a sub-model from
// the base to it whose tool frame is the body's inertial frame.

struct Body {
  std::string link;
  double mass;
  Eigen::Matrix3d inertia;  // about the centre of mass, in the inertial frame's axes
  ci::RobotModel model;     // base -> link, tool = inertial frame
  int num_joints;           // a prefix of the chain's joints
};

Eigen::Isometry3d to_isometry(const urdf::Pose& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      Eigen::Quaterniond(pose.rotation.w, pose.rotation.x, pose.rotation.y, pose.rotation.z)
          .toRotationMatrix();
  T.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  return T;
}

std::vector<Body> chain_bodies(const std::string& xml, const std::string& base,
                               const std::string& tip) {
  const urdf::ModelInterfaceSharedPtr urdf = urdf::parseURDF(xml);
  EXPECT_TRUE(urdf != nullptr);
  std::vector<std::string> chain_links;
  for (urdf::LinkConstSharedPtr link = urdf->getLink(tip); link && link->name != base;
       link = link->getParent()) {
    chain_links.push_back(link->name);
  }
  const auto on_chain = [&](const std::string& name) {
    return std::find(chain_links.begin(), chain_links.end(), name) != chain_links.end();
  };
  std::vector<Body> bodies;
  for (const auto& [name, link] : urdf->links_) {
    if (!link->inertial || link->inertial->mass == 0.0) continue;
    // Up through fixed joints to a chain link, then on to the base through movable ones.
    urdf::LinkConstSharedPtr up = link;
    while (up && !on_chain(up->name) && up->parent_joint &&
           up->parent_joint->type == urdf::Joint::FIXED) {
      up = up->getParent();
    }
    if (!up || !on_chain(up->name)) continue;
    bool behind_movable_joint = false;
    for (; up && up->name != base; up = up->getParent()) {
      behind_movable_joint |= up->parent_joint->type != urdf::Joint::FIXED;
    }
    if (!behind_movable_joint) continue;
    const urdf::Inertial& inertial = *link->inertial;
    Eigen::Matrix3d inertia;
    inertia << inertial.ixx, inertial.ixy, inertial.ixz, inertial.ixy, inertial.iyy, inertial.iyz,
        inertial.ixz, inertial.iyz, inertial.izz;
    ci::RobotModel model =
        ci::RobotModel::from_urdf_string(xml, base, name, to_isometry(inertial.origin));
    const int n = model.num_joints();
    bodies.push_back(Body{name, inertial.mass, inertia, std::move(model), n});
  }
  return bodies;
}

// Potential energy V(q) = -sum m_i g . c_i(q) [J].
double potential_energy(std::vector<Body>& bodies, const ci::JointVector& q,
                        const Eigen::Vector3d& gravity) {
  double energy = 0.0;
  for (Body& body : bodies) {
    ci::ModelWorkspace workspace(body.model);
    const Eigen::Isometry3d T = forward_kinematics(workspace, q.head(body.num_joints));
    energy -= body.mass * gravity.dot(T.translation());
  }
  return energy;
}

// M(q) = sum_i Jv_i^T m_i Jv_i + Jw_i^T R_i I_i R_i^T Jw_i, with each body's Jacobian at its
// centre of mass (padded with zero columns for the joints after it).
ci::JointMatrix composite_mass(std::vector<Body>& bodies, const ci::JointVector& q) {
  const Eigen::Index n = q.size();
  ci::JointMatrix mass = ci::JointMatrix::Zero(n, n);
  for (Body& body : bodies) {
    ci::ModelWorkspace workspace(body.model);
    ci::Kinematics kinematics = workspace.make_kinematics();
    const ci::JointVector q_body = q.head(body.num_joints);
    EXPECT_TRUE(workspace.compute(q_body, ci::JointVector::Zero(body.num_joints), kinematics));
    ci::Jacobian jacobian = ci::Jacobian::Zero(6, n);
    jacobian.leftCols(body.num_joints) = kinematics.jacobian;
    const Eigen::Matrix3d R = kinematics.pose.orientation.toRotationMatrix();
    const Eigen::Matrix3d inertia_base = R * body.inertia * R.transpose();
    mass += body.mass * jacobian.topRows<3>().transpose() * jacobian.topRows<3>() +
            jacobian.bottomRows<3>().transpose() * inertia_base * jacobian.bottomRows<3>();
  }
  return mass;
}

// The message of the ci::Error that `load` throws, or a note that it threw something else.
std::string error_of(const std::function<void()>& load) {
  try {
    load();
  } catch (const ci::Error& error) {
    return error.what();
  } catch (const std::exception& other) {
    return std::string("<not a cartesian_impedance::Error: ") + other.what() + ">";
  }
  return "<no exception>";
}

void expect_contains(const std::string& message, std::initializer_list<std::string> parts) {
  for (const std::string& part : parts) {
    EXPECT_NE(message.find(part), std::string::npos)
        << "expected \"" << part << "\" in the message: " << message;
  }
}

}  // namespace

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
// Properties that hold for every chain.

class EveryChain : public ::testing::TestWithParam<ChainCase> {};

INSTANTIATE_TEST_SUITE_P(Chains, EveryChain, ::testing::ValuesIn(chain_cases()),
                         [](const auto& info) { return std::string(info.param.name); });

// Central differences with step h have truncation error h^2/6 |p'''| and rounding error
// eps |p| / h. Positions and lever arms are below 1.4 m and every third derivative of the pose
// along one joint is bounded by the same length (unit joint axes), so with h = 1e-5 both terms
// are below 3e-11 (seen: 4e-11 at most); 1e-9 leaves a margin of 25.
constexpr double kStep = 1e-5;
constexpr double kJacobianTolerance = 1e-9;

TEST_P(EveryChain, JacobianIsTheDerivativeOfThePose) {
  const ci::RobotModel model = load(GetParam());
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  std::mt19937 rng(11);
  double worst = 0.0;
  for (int k = 0; k < 100; ++k) {
    const ci::JointVector q = random_configuration(model, rng);
    ASSERT_TRUE(workspace.compute(q, ci::JointVector::Zero(q.size()), kinematics));
    const ci::Jacobian numeric = finite_difference_jacobian(workspace, q, kStep);
    worst = std::max(worst, (kinematics.jacobian - numeric).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, kJacobianTolerance);
}

TEST_P(EveryChain, ToolOffsetMovesTheReferencePoint) {
  // A tool 12 cm out and 5 cm aside, turned 40 deg about a skew axis.
  Eigen::Isometry3d T_tip_tool = Eigen::Isometry3d::Identity();
  T_tip_tool.translate(Eigen::Vector3d(0.05, -0.02, 0.12));
  T_tip_tool.rotate(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  const ci::RobotModel plain = load(GetParam());
  const ci::RobotModel tooled = load(GetParam(), T_tip_tool);
  EXPECT_TRUE(tooled.tool().isApprox(T_tip_tool, 1e-15));
  ci::ModelWorkspace plain_workspace(plain), tool_workspace(tooled);
  ci::Kinematics at_tip = plain_workspace.make_kinematics();
  ci::Kinematics at_tool = tool_workspace.make_kinematics();
  std::mt19937 rng(12);
  double worst_numeric = 0.0, worst_shift = 0.0;
  for (int k = 0; k < 100; ++k) {
    const ci::JointVector q = random_configuration(plain, rng);
    const ci::JointVector zero = ci::JointVector::Zero(q.size());
    ASSERT_TRUE(plain_workspace.compute(q, zero, at_tip, true));
    ASSERT_TRUE(tool_workspace.compute(q, zero, at_tool, true));
    // The tool pose is the tip pose times the offset.
    EXPECT_LT(
        ((isometry(at_tip.pose) * T_tip_tool).matrix() - isometry(at_tool.pose).matrix()).norm(),
        1e-14);
    // Same angular rows; linear rows moved to the tool origin: v_tool = v_tip + w x r.
    const Eigen::Vector3d r = at_tool.pose.position - at_tip.pose.position;
    ci::Jacobian shifted = at_tip.jacobian;
    for (Eigen::Index i = 0; i < q.size(); ++i) {
      shifted.block<3, 1>(0, i) += at_tip.jacobian.block<3, 1>(3, i).cross(r);
    }
    worst_shift = std::max(worst_shift, (at_tool.jacobian - shifted).cwiseAbs().maxCoeff());
    const ci::Jacobian numeric = finite_difference_jacobian(tool_workspace, q, kStep);
    worst_numeric = std::max(worst_numeric, (at_tool.jacobian - numeric).cwiseAbs().maxCoeff());
    // A massless tool changes no dynamics.
    EXPECT_LT((at_tool.mass - at_tip.mass).norm(), 1e-15);
    EXPECT_LT((at_tool.gravity - at_tip.gravity).norm(), 1e-15);
  }
  EXPECT_LT(worst_shift, 1e-14);
  EXPECT_LT(worst_numeric, kJacobianTolerance);
}

TEST_P(EveryChain, MassMatrixIsSymmetricPositiveDefiniteAndMatchesTheBodies) {
  const ChainCase& chain = GetParam();
  const ci::RobotModel model = load(chain);
  std::vector<Body> bodies = chain_bodies(chain.xml(), chain.base, chain.tip);
  ci::ModelWorkspace workspace(model);
  std::mt19937 rng(13);
  for (int k = 0; k < 50; ++k) {
    const ci::JointVector q = random_configuration(model, rng);
    const ci::JointMatrix mass = mass_at(workspace, q);
    EXPECT_EQ(mass, mass.transpose());  // KDL fills both triangles with the same number
    const Eigen::SelfAdjointEigenSolver<ci::JointMatrix> eigen(mass, Eigen::EigenvaluesOnly);
    // The smallest eigenvalue cannot fall below the smallest inertia the last joint turns
    // (about 1e-3 kg m^2 for the iiwa's link 7; seen: 9e-4).
    EXPECT_GT(eigen.eigenvalues().minCoeff(), 1e-4) << "at q = " << q.transpose();
    // Recursive (KDL) against summed body Jacobians: the same quantity through different
    // arithmetic; entries are below 5 kg m^2 and sums of about 20 products, so rounding is a few
    // 1e-15 (seen: 4e-15). 1e-13 leaves a margin of 20.
    EXPECT_LT((mass - composite_mass(bodies, q)).cwiseAbs().maxCoeff(), 1e-13);
  }
}

TEST_P(EveryChain, GravityIsTheGradientOfPotentialEnergy) {
  const ChainCase& chain = GetParam();
  const ci::RobotModel model = load(chain);
  std::vector<Body> bodies = chain_bodies(chain.xml(), chain.base, chain.tip);
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  std::mt19937 rng(14);
  double worst = 0.0;
  for (int k = 0; k < 20; ++k) {
    const ci::JointVector q = random_configuration(model, rng);
    ASSERT_TRUE(workspace.compute(q, ci::JointVector::Zero(q.size()), kinematics, true));
    ci::JointVector gradient(q.size());
    for (Eigen::Index i = 0; i < q.size(); ++i) {
      ci::JointVector plus = q, minus = q;
      plus[i] += kStep;
      minus[i] -= kStep;
      gradient[i] = (potential_energy(bodies, plus, model.gravity_base()) -
                     potential_energy(bodies, minus, model.gravity_base())) /
                    (2 * kStep);
    }
    worst = std::max(worst, (kinematics.gravity - gradient).cwiseAbs().maxCoeff());
  }
  // V is at most 30 kg * 9.81 m/s^2 * 1.4 m = 400 J and so is each of its third derivatives
  // along a joint: truncation 400 h^2 / 6 = 7e-9, rounding 1e-16 * 400 / h = 4e-9 Nm (seen:
  // 3e-9 at most). 1e-7 Nm leaves a margin of 10 over the bound.
  EXPECT_LT(worst, 1e-7);
}

TEST_P(EveryChain, CoriolisFollowsFromTheMassMatrix) {
  // Lagrange: C(q, dq) dq = dM/dt dq - 1/2 d/dq (dq^T M dq), with dM/dt = sum_i dM/dq_i dq_i.
  const ci::RobotModel model = load(GetParam());
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  std::mt19937 rng(15);
  double worst = 0.0;
  for (int k = 0; k < 20; ++k) {
    const ci::JointVector q = random_configuration(model, rng);
    const ci::JointVector dq = random_velocity(model.num_joints(), rng, 2.0);
    ASSERT_TRUE(workspace.compute(q, dq, kinematics, true));
    const ci::JointMatrix dmass_dt =
        (mass_at(workspace, q + kStep * dq) - mass_at(workspace, q - kStep * dq)) / (2 * kStep);
    ci::JointVector expected = dmass_dt * dq;
    for (Eigen::Index i = 0; i < q.size(); ++i) {
      ci::JointVector plus = q, minus = q;
      plus[i] += kStep;
      minus[i] -= kStep;
      const ci::JointMatrix dmass_dqi =
          (mass_at(workspace, plus) - mass_at(workspace, minus)) / (2 * kStep);
      expected[i] -= 0.5 * dq.dot(dmass_dqi * dq);
    }
    worst = std::max(worst, (kinematics.coriolis - expected).cwiseAbs().maxCoeff());
  }
  // Entries of M are below 10 kg m^2 and so are their third derivatives, |dq| <= 2 rad/s on up
  // to 7 joints (|dq|_1 <= 14): truncation 10 h^2 / 6 * 14^2 = 3e-8, rounding
  // 1e-16 * 10 / h * 14^2 = 2e-8 Nm (seen: 2.5e-9 at most). 2e-7 Nm leaves a margin of 4 over
  // the bound.
  EXPECT_LT(worst, 2e-7);
}

TEST_P(EveryChain, CoriolisIsQuadraticInVelocityAndZeroAtRest) {
  const ci::RobotModel model = load(GetParam());
  ci::ModelWorkspace workspace(model);
  ci::Kinematics slow = workspace.make_kinematics(), fast = slow, still = slow;
  std::mt19937 rng(16);
  const ci::JointVector q = random_configuration(model, rng);
  const ci::JointVector dq = random_velocity(model.num_joints(), rng, 1.0);
  ASSERT_TRUE(workspace.compute(q, dq, slow, true));
  ASSERT_TRUE(workspace.compute(q, 3.0 * dq, fast, true));
  ASSERT_TRUE(workspace.compute(q, ci::JointVector::Zero(q.size()), still, true));
  EXPECT_LT((fast.coriolis - 9.0 * slow.coriolis).norm(), 1e-12);
  EXPECT_EQ(still.coriolis, ci::JointVector::Zero(q.size()));
  EXPECT_GT(slow.coriolis.norm(), 1e-3);
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
// Load-time errors.

namespace {

// A serial robot l0 - j1 - l1 - ... - jk - lk with the given joint types, each link 1 kg, each
// joint 0.1 m above the previous; `extra` is inserted before </robot>.
std::string serial_urdf(const std::vector<std::string>& types, const std::string& extra = "",
                        const std::string& link_inertial =
                            "<inertial><mass value=\"1\"/><inertia ixx=\"0.01\" iyy=\"0.01\" "
                            "izz=\"0.01\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>") {
  std::ostringstream xml;
  xml << "<robot name=\"serial\">\n<link name=\"l0\"/>\n";
  for (std::size_t i = 1; i <= types.size(); ++i) {
    xml << "<link name=\"l" << i << "\">" << link_inertial << "</link>\n";
    xml << "<joint name=\"j" << i << "\" type=\"" << types[i - 1] << "\"><parent link=\"l" << i - 1
        << "\"/><child link=\"l" << i << "\"/><origin xyz=\"0 0 0.1\"/><axis xyz=\"0 0 1\"/>";
    if (types[i - 1] == "revolute" || types[i - 1] == "prismatic") {
      xml << "<limit lower=\"-1\" upper=\"1\" velocity=\"1\" effort=\"10\"/>";
    }
    xml << "</joint>\n";
  }
  xml << extra << "</robot>\n";
  return xml.str();
}

std::string load_error(const std::string& xml, const std::string& base, const std::string& tip) {
  return error_of([&] { ci::RobotModel::from_urdf_string(xml, base, tip); });
}

}  // namespace

TEST(LoadErrors, MissingOrUnreadableFile) {
  const std::string missing = "/nonexistent/robot.urdf";
  expect_contains(error_of([&] { ci::RobotModel::from_urdf_file(missing, "a", "b"); }),
                  {"'/nonexistent/robot.urdf'", "does not exist"});
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(CARTESIAN_IMPEDANCE_SOURCE_DIR, "a", "b"); }),
      {CARTESIAN_IMPEDANCE_SOURCE_DIR, "is a directory"});
}

TEST(LoadErrors, MalformedXmlOrNotAUrdf) {
  expect_contains(load_error("<robot name='r'><link name='a'/>", "a", "b"),
                  {"the URDF text", "not a valid URDF", "urdfdom says"});
  expect_contains(load_error("", "a", "b"), {"not a valid URDF", "empty"});
  expect_contains(load_error("<html><body/></html>", "a", "b"), {"not a valid URDF", "robot"});
  // urdfdom logs an error for a mass of "nan" but still returns a model (with mass 0); the
  // logged error must count.
  expect_contains(load_error(serial_urdf({"revolute"}, "",
                                         "<inertial><mass value=\"nan\"/><inertia ixx=\"1\" "
                                         "iyy=\"1\" izz=\"1\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"
                                         "</inertial>"),
                             "l0", "l1"),
                  {"not a valid URDF", "nan", "l1"});
  // The file's path is named when the text came from a file.
  const std::string path = ::testing::TempDir() + "/model_test_broken.urdf";
  std::ofstream(path) << "<robot name='r'><link name='a'/>";
  expect_contains(error_of([&] { ci::RobotModel::from_urdf_file(path, "a", "b"); }),
                  {"URDF file '" + path + "'", "not a valid URDF"});
}

TEST(LoadErrors, UrdfdomErrorsAreCaughtEvenWhenItsLogIsSilenced) {
  // An application may silence console_bridge (urdfdom's log); its errors must still count.
  const console_bridge::LogLevel level = console_bridge::getLogLevel();
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  const std::string message = load_error(
      serial_urdf({"revolute"}, "",
                  "<inertial><mass value=\"nan\"/><inertia ixx=\"1\" iyy=\"1\" izz=\"1\" "
                  "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>"),
      "l0", "l1");
  EXPECT_EQ(console_bridge::getLogLevel(), console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  console_bridge::setLogLevel(level);
  expect_contains(message, {"not a valid URDF", "nan"});
}

TEST(LoadErrors, UnknownLinksAreNamedWithTheAvailableOnes) {
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(panda_path(), "panda_link_0", "panda_link8"); }),
      {"base link 'panda_link_0'", "not a link", "panda", "panda_link0", "panda_link7"});
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_hand"); }),
      {"tip link 'panda_hand'", "not a link", "panda_link8"});
  // Long lists are cut short with a count.
  std::vector<std::string> many(20, "fixed");
  many[0] = "revolute";
  expect_contains(load_error(serial_urdf(many), "l0", "nowhere"), {"'nowhere'", "21 in all"});
}

TEST(LoadErrors, TipMustBeBelowTheBase) {
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(panda_path(), "panda_link5", "panda_link2"); }),
      {"tip link 'panda_link2'", "above base link 'panda_link5'"});
  // Two branches of one tree: neither is below the other.
  const std::string branched = serial_urdf(
      {"revolute", "revolute"},
      "<link name=\"side\"/><joint name=\"js\" type=\"revolute\"><parent link=\"l0\"/>"
      "<child link=\"side\"/><limit lower=\"-1\" upper=\"1\" velocity=\"1\" effort=\"1\"/>"
      "</joint>\n");
  expect_contains(load_error(branched, "side", "l2"),
                  {"tip link 'l2'", "not below base link 'side'", "l2 <- l1 <- l0"});
  expect_contains(load_error(branched, "l1", "l1"), {"'l1' is the base link", "movable joint"});
}

TEST(LoadErrors, ChainWithoutMovableJoints) {
  expect_contains(
      error_of([] { ci::RobotModel::from_urdf_file(panda_path(), "panda_link7", "panda_link8"); }),
      {"'panda_link7'", "'panda_link8'", "no movable joint"});
}

TEST(LoadErrors, TooManyJoints) {
  const int too_many = ci::kMaxJoints + 1;
  const std::vector<std::string> joints(too_many, "revolute");
  const std::string tip = "l" + std::to_string(too_many);
  expect_contains(load_error(serial_urdf(joints), "l0", tip),
                  {std::to_string(too_many) + " movable joints",
                   "at most kMaxJoints = " + std::to_string(ci::kMaxJoints)});
  // kMaxJoints are fine, and so are joints beyond the tip.
  EXPECT_EQ(ci::RobotModel::from_urdf_string(serial_urdf(joints), "l0",
                                             "l" + std::to_string(ci::kMaxJoints))
                .num_joints(),
            ci::kMaxJoints);
}

TEST(LoadErrors, UnsupportedJointTypes) {
  expect_contains(load_error(serial_urdf({"revolute", "floating", "revolute"}), "l0", "l3"),
                  {"joint 'j2'", "is floating", "revolute, continuous, prismatic and fixed"});
  expect_contains(load_error(serial_urdf({"planar", "revolute"}), "l0", "l2"),
                  {"joint 'j1'", "is planar"});
  // Outside the chain they do not matter.
  EXPECT_EQ(ci::RobotModel::from_urdf_string(serial_urdf({"revolute", "floating"}), "l0", "l1")
                .num_joints(),
            1);
  const std::string mimic =
      "<robot name=\"m\"><link name=\"a\"/><link name=\"b\"/><link name=\"c\"/>"
      "<joint name=\"j1\" type=\"continuous\"><parent link=\"a\"/><child link=\"b\"/></joint>"
      "<joint name=\"j2\" type=\"continuous\"><parent link=\"b\"/><child link=\"c\"/>"
      "<mimic joint=\"j1\" multiplier=\"1\"/></joint></robot>";
  expect_contains(load_error(mimic, "a", "c"), {"joint 'j2' mimics joint 'j1'", "not supported"});
}

TEST(LoadErrors, BadMassAndInertia) {
  const auto inertial = [](const std::string& mass, const std::string& ixx) {
    return "<inertial><mass value=\"" + mass + "\"/><inertia ixx=\"" + ixx +
           "\" iyy=\"0.01\" izz=\"0.01\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial>";
  };
  expect_contains(load_error(serial_urdf({"revolute"}, "", inertial("-1.5", "0.01")), "l0", "l1"),
                  {"link 'l1'", "mass = -1.5 kg", "expected a finite value >= 0"});
  expect_contains(load_error(serial_urdf({"revolute"}, "", inertial("1", "-0.01")), "l0", "l1"),
                  {"link 'l1'", "not positive semi-definite", "-0.01"});
  // A bad mass fixed to a chain link is lumped into it, so it is checked too.
  expect_contains(
      load_error(serial_urdf({"revolute"}, "<link name=\"lump\">" + inertial("-2", "0.01") +
                                               "</link><joint name=\"jl\" type=\"fixed\"><parent "
                                               "link=\"l1\"/><child link=\"lump\"/></joint>"),
                 "l0", "l1"),
      {"link 'lump'", "mass = -2 kg"});
}

TEST(LoadErrors, BadAxisAndLimits) {
  const std::string zero_axis =
      "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/><joint name=\"j\" "
      "type=\"continuous\"><parent link=\"a\"/><child link=\"b\"/><axis xyz=\"0 0 0\"/></joint>"
      "</robot>";
  expect_contains(load_error(zero_axis, "a", "b"), {"joint 'j'", "axis = (0, 0, 0)", "non-zero"});
  const auto with_limit = [](const std::string& limit) {
    return "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/><joint name=\"j\" "
           "type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>" +
           limit + "</joint></robot>";
  };
  expect_contains(
      load_error(with_limit("<limit lower=\"1\" upper=\"-1\" velocity=\"1\" effort=\"1\"/>"), "a",
                 "b"),
      {"joint 'j'", "position limits [1, -1]", "lower <= upper"});
  expect_contains(
      load_error(with_limit("<limit lower=\"-1\" upper=\"1\" velocity=\"-2\" effort=\"1\"/>"), "a",
                 "b"),
      {"joint 'j'", "velocity limit = -2"});
  expect_contains(
      load_error(with_limit("<limit lower=\"-1\" upper=\"1\" velocity=\"2\" effort=\"-3\"/>"), "a",
                 "b"),
      {"joint 'j'", "effort limit = -3"});
}

TEST(LoadErrors, BadToolOrGravity) {
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 1.1;
  expect_contains(error_of([&] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8",
                                                   scaled);
                  }),
                  {"T_tip_tool", "not a rotation matrix", "0.21"});
  Eigen::Isometry3d mirrored = Eigen::Isometry3d::Identity();
  mirrored.linear() = Eigen::Vector3d(1, 1, -1).asDiagonal();
  expect_contains(error_of([&] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8",
                                                   mirrored);
                  }),
                  {"T_tip_tool", "det R = -1"});
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation().x() = std::numeric_limits<double>::infinity();
  expect_contains(error_of([&] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8", far);
                  }),
                  {"T_tip_tool", "non-finite"});
  expect_contains(error_of([] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8",
                                                   Eigen::Isometry3d::Identity(),
                                                   Eigen::Vector3d(0, std::nan(""), -9.81));
                  }),
                  {"gravity_base = (0, nan, -9.81)", "non-finite"});
}

// ---------------------------------------------------------------------------------------------
// Malformed trees and absurd numbers: the loader fails closed, with the culprits named.

namespace {

// A link of 1 kg and a joint of `type` from `parent` to `child` (URDF snippets for `extra`).
std::string link_xml(const std::string& name) {
  return "<link name=\"" + name +
         "\"><inertial><mass value=\"1\"/><inertia ixx=\"0.01\" iyy=\"0.01\" izz=\"0.01\" "
         "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>\n";
}
std::string joint_xml(const std::string& name, const std::string& parent, const std::string& child,
                      const std::string& type = "fixed", const std::string& inside = "") {
  return "<joint name=\"" + name + "\" type=\"" + type + "\"><parent link=\"" + parent +
         "\"/><child link=\"" + child + "\"/>" + inside + "</joint>\n";
}

}  // namespace

TEST(LoadErrors, LoopOfLinksNotConnectedToTheRootIsRejected) {
  // x -> y -> z -> x beside the chain l0 -> l1 -> l2: urdfdom finds the root l0 and accepts it.
  const std::string loop = link_xml("x") + link_xml("y") + link_xml("z") +
                           joint_xml("jxy", "x", "y") + joint_xml("jyz", "y", "z") +
                           joint_xml("jzx", "z", "x");
  const std::string xml = serial_urdf({"revolute", "revolute"}, loop);
  // Before, a chain into the loop walked its parents for ever; now any loop is rejected, even
  // one the requested chain does not touch.
  for (const auto& [base, tip] :
       std::vector<std::pair<std::string, std::string>>{{"l0", "l2"}, {"l0", "y"}, {"x", "z"}}) {
    SCOPED_TRACE(base + " -> " + tip);
    expect_contains(load_error(xml, base, tip),
                    {"the URDF text", "loop", "'x'", "'y'", "'z'", "'jxy'", "'jyz'", "'jzx'"});
  }
}

TEST(LoadErrors, LoopHiddenBehindXmlEntitiesIsRejectedAfterParsing) {
  // The pre-parse check compares names as written, so "&#120;" (an 'x' in XML) escapes it;
  // the check on urdfdom's own model must still catch the loop.
  const std::string loop =
      link_xml("x") + link_xml("y") + joint_xml("jxy", "x", "y") + joint_xml("jyx", "y", "&#120;");
  expect_contains(load_error(serial_urdf({"revolute"}, loop), "l0", "y"),
                  {"loop", "'x'", "'y'", "'jxy'", "'jyx'"});
}

TEST(LoadErrors, LongFixedSideBranchIsLumpedWithoutRecursion) {
  // 10,000 links of 1 g in a row, fixed to l1: before, lumping them recursed once per link and
  // overflowed the stack.
  constexpr int kLinks = 10000;
  std::string branch;
  branch.reserve(kLinks * 260);
  for (int i = 0; i < kLinks; ++i) {
    const std::string name = "b" + std::to_string(i);
    branch += "<link name=\"" + name +
              "\"><inertial><mass value=\"0.001\"/><inertia ixx=\"0\" iyy=\"0\" izz=\"0\" "
              "ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>" +
              joint_xml("jb" + std::to_string(i), i == 0 ? "l1" : "b" + std::to_string(i - 1), name,
                        "fixed", "<origin xyz=\"0.001 0 0\"/>");
  }
  const ci::RobotModel model =
      ci::RobotModel::from_urdf_string(serial_urdf({"revolute"}, branch), "l0", "l1");
  EXPECT_NEAR(model.moving_mass(), 1.0 + kLinks * 0.001, 1e-9);
}

TEST(LoadErrors, DeeplyNestedXmlIsRejectedBeforeUrdfdomRecursesIntoIt) {
  // TinyXML (under urdfdom) parses nested elements recursively: 100,000 levels overflowed the
  // stack. The nesting is checked on the text first.
  constexpr int kDepth = 100000;
  std::string deep;
  deep.reserve(kDepth * 7);
  for (int i = 0; i < kDepth; ++i) deep += "<a>";
  for (int i = 0; i < kDepth; ++i) deep += "</a>";
  const std::string xml = serial_urdf({"revolute"}, "<link name=\"deep\">\n" + deep + "</link>\n");
  expect_contains(load_error(xml, "l0", "l1"),
                  {"the URDF text", "nests XML elements more than 100 deep", "line"});
  // Ordinary nesting (gazebo extensions and the like) is fine.
  std::string nested;
  for (int i = 0; i < 50; ++i) nested += "<a x='>'>";
  for (int i = 0; i < 50; ++i) nested += "</a>";
  EXPECT_EQ(ci::RobotModel::from_urdf_string(
                serial_urdf({"revolute"}, "<gazebo>" + nested + "</gazebo>\n"), "l0", "l1")
                .num_joints(),
            1);
}

TEST(LoadErrors, TextThatTinyXmlCouldReadDifferentlyFromTheDepthCheckIsRejected) {
  // The depth check reads the text as TinyXML does. Where their readings could part (an XML
  // declaration other than a plain first one, invalid UTF-8 whose lead byte TinyXML takes to
  // swallow a '<', a NUL that ends TinyXML's text early), the text is rejected.
  const std::string serial = serial_urdf({"revolute"});
  expect_contains(load_error(serial + "<?xml version=\"1.0\"?>", "l0", "l1"),
                  {"XML declaration", "line 6", "only come first"});
  expect_contains(load_error("<?xml version=\"<a>\"?>" + serial, "l0", "l1"),
                  {"XML declaration", "line 1"});
  expect_contains(load_error(serial_urdf({"revolute"}, "<!-- \xF0 -->"), "l0", "l1"),
                  {"not valid UTF-8", "line 5"});
  expect_contains(load_error(serial + std::string(1, '\0') + "<robot/>", "l0", "l1"),
                  {"NUL", "line 6"});
  expect_contains(
      load_error(serial_urdf({"revolute"}, "<a b=\xEF\xBB\xBF\"</robot>\"/>"), "l0", "l1"),
      {"U+FEFF", "line 5"});
  // What would take TinyXML quadratic time: "&#" without a ';' close by, many attributes.
  expect_contains(load_error(serial_urdf({"revolute"}, "<!-- &#x1 -->"), "l0", "l1"),
                  {"character reference", "line 5"});
  std::string attributes = "<a";
  for (int i = 0; i < 65; ++i) attributes += " a" + std::to_string(i) + "='1'";
  expect_contains(load_error(serial_urdf({"revolute"}, attributes + "/>"), "l0", "l1"),
                  {"more than 64 attributes", "line 5"});
  // Unclosed constructs, which older TinyXML versions read past the end of the text.
  for (const char* tail : {"<!-- ", "<![CDATA[ ", "<link name=\"x", "<link ", "<!DOCTYPE"}) {
    expect_contains(load_error(serial + tail, "l0", "l1"), {"never closed", "line 6"});
  }
  // A plain declaration, comments, CDATA and UTF-8 names are fine.
  const std::string fine = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- <a><a><a> -->" +
                           serial_urdf({"revolute"},
                                       "<link name=\"gr\xC3\xBC\xC3\x9F\">"
                                       "<![CDATA[<a><a>]]></link>" +
                                           joint_xml("to_gruss", "l1", "gr\xC3\xBC\xC3\x9F"));
  EXPECT_EQ(ci::RobotModel::from_urdf_string(fine, "l0", "l1").num_joints(), 1);
}

TEST(LoadErrors, LinkWithTwoParentJointsIsRejected) {
  // urdfdom keeps one of the two parents (the last it reads) and says nothing.
  const std::string xml =
      serial_urdf({"revolute", "revolute"}, link_xml("c") + joint_xml("to_c_from_l1", "l1", "c") +
                                                joint_xml("to_c_from_l2", "l2", "c"));
  expect_contains(load_error(xml, "l0", "c"), {"link 'c'", "two parent joints", "'to_c_from_l1'",
                                               "'to_c_from_l2'", "'l1'", "'l2'"});
}

TEST(LoadErrors, JointFromALinkToItselfIsRejected) {
  const std::string xml = serial_urdf({"revolute"}, joint_xml("self", "l1", "l1", "continuous"));
  expect_contains(load_error(xml, "l0", "l1"),
                  {"joint 'self'", "link 'l1'", "both its parent and its child"});
}

TEST(LoadErrors, AbsurdNumbersAreRejectedAtLoadTime) {
  // Before, each of these loaded, and then every control cycle failed with numerical_error.
  const auto one_joint = [](const std::string& origin, const std::string& axis,
                            const std::string& type = "revolute",
                            const std::string& limit =
                                "<limit lower=\"-1\" upper=\"1\" velocity=\"1\" effort=\"1\"/>") {
    return "<robot name=\"r\"><link name=\"a\"/>" + link_xml("b") +
           joint_xml("j", "a", "b", type,
                     "<origin xyz=\"" + origin + "\"/><axis xyz=\"" + axis + "\"/>" + limit) +
           "</robot>";
  };
  expect_contains(load_error(one_joint("1e308 0 0", "0 0 1"), "a", "b"),
                  {"joint 'j'", "origin xyz = (1e+308, 0, 0)", "1000 m"});
  expect_contains(load_error(one_joint("0 0 -1000.5", "0 0 1"), "a", "b"),
                  {"joint 'j'", "-1000.5", "1000 m"});
  // The norm is computed without overflow, and a direction may have a norm of 5, not of 1e308.
  expect_contains(
      load_error(one_joint("0 0 0", "1e308 1e308 1e308"), "a", "b"),
      {"joint 'j'", "axis = (1e+308, 1e+308, 1e+308)", "norm 1.73205e+308", "[1e-09, 1e+09]"});
  expect_contains(load_error(one_joint("0 0 0", "1.5e308 1.5e308 0"), "a", "b"),
                  {"joint 'j'", "norm inf", "[1e-09, 1e+09]"});
  expect_contains(load_error(one_joint("0 0 0", "1e-12 0 0"), "a", "b"),
                  {"joint 'j'", "axis = (1e-12, 0, 0)", "norm 1e-12", "[1e-09, 1e+09]"});
  expect_contains(
      load_error(one_joint("0 0 0", "1 0 0", "prismatic",
                           "<limit lower=\"-1e308\" upper=\"1\" velocity=\"1\" effort=\"1\"/>"),
                 "a", "b"),
      {"joint 'j'", "position limits [-1e+308, 1]", "1000 m"});
  const auto with_inertial = [](const std::string& inertial) {
    return serial_urdf({"revolute"}, "", "<inertial>" + inertial + "</inertial>");
  };
  expect_contains(load_error(with_inertial("<mass value=\"1e7\"/><inertia ixx=\"1\" iyy=\"1\" "
                                           "izz=\"1\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"),
                             "l0", "l1"),
                  {"link 'l1'", "mass = 1e+07 kg", "1e+06 kg"});
  expect_contains(
      load_error(with_inertial("<mass value=\"1\"/><inertia ixx=\"1e308\" iyy=\"1e308\" "
                               "izz=\"1e308\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"),
                 "l0", "l1"),
      {"link 'l1'", "inertia", "1e+308", "1e+06 kg m^2"});
  expect_contains(
      load_error(with_inertial("<origin xyz=\"0 1e308 0\"/><mass value=\"1\"/><inertia ixx=\"1\" "
                               "iyy=\"1\" izz=\"1\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"),
                 "l0", "l1"),
      {"link 'l1'", "inertial origin xyz = (0, 1e+308, 0)", "1000 m"});
  // The bounds themselves are valid.
  EXPECT_NO_THROW(ci::RobotModel::from_urdf_string(one_joint("1000 -1000 0", "0 0 5"), "a", "b"));
  EXPECT_NO_THROW(ci::RobotModel::from_urdf_string(
      with_inertial("<origin xyz=\"0 -1000 0\"/><mass value=\"1e6\"/><inertia ixx=\"1e6\" "
                    "iyy=\"1e6\" izz=\"1e6\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/>"),
      "l0", "l1"));
}

TEST(LoadErrors, ModelThatCannotBeEvaluatedAtZeroIsRejected) {
  // Every number of the file within its bounds, and yet the model must compute: the loader
  // evaluates it once. A gravity of 1e308 m/s^2 is finite, its torques are not.
  expect_contains(error_of([] {
                    ci::RobotModel::from_urdf_file(panda_path(), "panda_link0", "panda_link8",
                                                   Eigen::Isometry3d::Identity(),
                                                   Eigen::Vector3d(0, 0, -1e308));
                  }),
                  {"URDF file", "gravity", "not finite at q = 0"});
}
