// Properties that hold for every chain (the Panda, the iiwa, sub-chains of both and a handwritten
// robot): the Jacobian against finite differences, the tool offset, and the dynamics against
// independent constructions from the URDF's inertial data (read here with urdfdom, one body at a
// time).

#include <gtest/gtest.h>
#include <urdf_parser/urdf_parser.h>

#include <Eigen/Dense>
#include <algorithm>
#include <functional>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "cartesian_impedance/model/robot_model.hpp"
#include "support/model_fixtures.hpp"

namespace ci = cartesian_impedance;
using namespace model_fixtures;

namespace {

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

}  // namespace

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
