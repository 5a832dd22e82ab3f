// The MuJoCo simulation backend, checked against MuJoCo's own C API on an independent copy of the
// same model (mass matrix, Jacobians, bias forces) and against plain physics (a free arm held by
// gravity compensation stays put; a pressed flange feels the pressing force from the table).
//
// Tolerances, where they are not round-off:
// - One step from rest of a gravity-compensated arm under a generalized force f, with MuJoCo's
//   implicit integrator, gives dq = dt (M + dt D)^-1 (f + f_friction), D = diag(joint damping).
//   The joint friction force (frictionloss, a constraint) is bounded per joint by the frictionloss
//   value, so |dq - dt (M + dt D)^-1 f| <= dt ||(M + dt D)^-1||_2 ||frictionloss||_2, and the
//   tests choose f large enough that this bound is < 10 % of the expected dq.
// - Replays against raw MuJoCo differ only by how the gravity torque and the push wrench are
//   computed (subtree centre of mass vs. recursive Newton-Euler; xfrc_applied vs. J^T F), i.e. by
//   round-off of about 1e-14 Nm per step; after a few hundred steps that leaves < 1e-9.

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "cartesian_impedance/error.hpp"
#include "cartesian_impedance/robot_model.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "sim/simulation_impl.hpp"

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
#include "support/allocation_counter.hpp"
#endif

namespace ci = cartesian_impedance;
namespace sim = cartesian_impedance::sim;
using ci::JointMatrix;
using ci::JointVector;
using ci::Vector6d;

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string model_file(const std::string& relative) {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/" + relative;
}
const std::string kPandaXml = model_file("panda/panda.xml");
const std::string kIiwaXml = model_file("iiwa14/iiwa14.xml");
const std::string kPandaUrdf = model_file("panda/panda.urdf");
const std::string kIiwaUrdf = model_file("iiwa14/iiwa14.urdf");
const std::string kUr5eUrdf = model_file("ur5e/ur5e.urdf");
const std::string kPlanar3Urdf = model_file("planar3/planar3.urdf");

JointVector joints(std::initializer_list<double> values) {
  JointVector v(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double value : values) v[i++] = value;
  return v;
}

JointVector panda_ready() {
  return joints({0, -kPi / 4, 0, -3 * kPi / 4, 0, kPi / 2, kPi / 4});
}
JointVector iiwa_ready() {
  return joints({0, kPi / 6, 0, -kPi / 2, 0, kPi / 3, 0});
}

// Expects `call` to throw ci::Error whose message contains every one of `parts`; the macro adds
// the line of the check to a failure.
void expect_error_impl(const std::function<void()>& call, const std::vector<std::string>& parts) {
  try {
    call();
    ADD_FAILURE() << "expected cartesian_impedance::Error";
  } catch (const ci::Error& error) {
    const std::string message = error.what();
    for (const std::string& part : parts) {
      EXPECT_NE(message.find(part), std::string::npos)
          << "message \"" << message << "\" lacks \"" << part << "\"";
    }
  }
}
#define EXPECT_ERROR(...)           \
  do {                              \
    SCOPED_TRACE("EXPECT_ERROR");   \
    expect_error_impl(__VA_ARGS__); \
  } while (false)

// An independent MuJoCo model and data of the same file, driven through the raw C API with
// qfrc_applied only: the reference the Simulation is compared with.
class Reference {
 public:
  explicit Reference(const std::string& path) {
    char error[1000] = "";
    model_ = mj_loadXML(path.c_str(), nullptr, error, sizeof(error));
    if (model_ == nullptr) throw std::runtime_error(error);
    model_->opt.timestep = 0.001;
    model_->opt.enableflags |= mjENBL_MULTICCD;  // as SimulationOptions::multi_point_contacts
    data_ = mj_makeData(model_);
    scratch_ = mj_makeData(model_);
    const int key = mj_name2id(model_, mjOBJ_KEY, "ready");
    if (key >= 0) {
      mj_resetDataKeyframe(model_, data_, key);
    }
    mj_forward(model_, data_);
  }
  ~Reference() {
    mj_deleteData(scratch_);
    mj_deleteData(data_);
    mj_deleteModel(model_);
  }
  Reference(const Reference&) = delete;
  Reference& operator=(const Reference&) = delete;

  int nv() const { return model_->nv; }
  const mjModel* model() const { return model_; }
  const mjData* data() const { return data_; }

  void set_state(const JointVector& q, const JointVector& dq) {
    for (int i = 0; i < nv(); ++i) {
      data_->qpos[i] = q[i];
      data_->qvel[i] = dq[i];
    }
    mj_forward(model_, data_);
  }
  JointVector q() const { return Eigen::Map<const Eigen::VectorXd>(data_->qpos, nv()); }
  JointVector dq() const { return Eigen::Map<const Eigen::VectorXd>(data_->qvel, nv()); }

  // Joint-space inertia including armature.
  JointMatrix mass_matrix() const {
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> dense(nv(), nv());
    mj_fullM(model_, dense.data(), data_->qM);
    return dense;
  }
  JointMatrix damping() const {
    return Eigen::Map<const Eigen::VectorXd>(model_->dof_damping, nv()).asDiagonal();
  }
  JointVector frictionloss() const {
    return Eigen::Map<const Eigen::VectorXd>(model_->dof_frictionloss, nv());
  }

  // After mj_step, data's kinematics belong to the positions before the step; the scratch copy
  // is brought up to date with the current positions (and zero velocity) instead.
  const mjData* fresh() {
    mju_copy(scratch_->qpos, data_->qpos, model_->nq);
    mju_zero(scratch_->qvel, model_->nv);
    mj_forward(model_, scratch_);
    return scratch_;
  }

  // 6 x nv geometric Jacobian [linear; angular] of the origin of a body or a site, at the current
  // positions.
  Eigen::MatrixXd jacobian(const std::string& body_or_site) {
    const mjData* d = fresh();
    int site = mj_name2id(model_, mjOBJ_SITE, body_or_site.c_str());
    const int body = site >= 0 ? model_->site_bodyid[site]
                               : mj_name2id(model_, mjOBJ_BODY, body_or_site.c_str());
    const mjtNum* point = site >= 0 ? d->site_xpos + 3 * site : d->xpos + 3 * body;
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> linear(3, nv());
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> angular(3, nv());
    mj_jac(model_, d, linear.data(), angular.data(), point, body);
    Eigen::MatrixXd jacobian(6, nv());
    jacobian << linear, angular;
    return jacobian;
  }

  // g(q): qfrc_bias at the current positions with zero velocity.
  JointVector gravity() { return Eigen::Map<const Eigen::VectorXd>(fresh()->qfrc_bias, nv()); }
  Eigen::Vector3d site_position(const std::string& site) {
    return Eigen::Map<const Eigen::Vector3d>(fresh()->site_xpos +
                                             3 * mj_name2id(model_, mjOBJ_SITE, site.c_str()));
  }

  // One step with qfrc_applied = f (no actuators used).
  void step(const JointVector& generalized_force) {
    for (int i = 0; i < nv(); ++i) data_->qfrc_applied[i] = generalized_force[i];
    mj_step(model_, data_);
  }

 private:
  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
  mjData* scratch_ = nullptr;
};

// dq after one step from rest under generalized force f, and the bound on its error from joint
// friction: each friction force is at most that joint's frictionloss, so per joint i
// |dq_i - predicted_i| <= dt sum_j |(M + dt D)^-1_ij| frictionloss_j.
struct OneStepPrediction {
  JointVector dq;
  JointVector bound;
};
OneStepPrediction predict_one_step(const Reference& reference, const JointVector& force) {
  const double dt = 0.001;
  const JointMatrix a_inverse = (reference.mass_matrix() + dt * reference.damping()).inverse();
  return {dt * a_inverse * force, dt * a_inverse.cwiseAbs() * reference.frictionloss()};
}

// The measured one-step dq agrees with the prediction within the friction bound (+ round-off),
// and the bound is small against the prediction, so the check means something.
void expect_one_step(const JointVector& dq, const OneStepPrediction& prediction) {
  ASSERT_LT(prediction.bound.norm(), 0.1 * prediction.dq.norm());
  for (int i = 0; i < dq.size(); ++i) {
    EXPECT_LE(std::abs(dq[i] - prediction.dq[i]), prediction.bound[i] + 1e-12)
        << "joint " << i + 1 << ": dq " << dq[i] << ", predicted " << prediction.dq[i];
  }
}

struct RobotCase {
  const char* label;
  std::string file;
  std::string joint_prefix;  // joint i is prefix + i (1-based)
  JointVector ready;
  JointVector torque_limit;
};

std::vector<RobotCase> robot_cases() {
  return {
      {"panda", kPandaXml, "panda_joint", panda_ready(), joints({87, 87, 87, 87, 12, 12, 12})},
      {"iiwa14", kIiwaXml, "iiwa_joint_", iiwa_ready(), joints({320, 320, 176, 176, 110, 40, 40})}};
}

void PrintTo(const RobotCase& robot, std::ostream* out) {
  *out << robot.label;
}

class RobotFiles : public ::testing::TestWithParam<RobotCase> {};

}  // namespace

INSTANTIATE_TEST_SUITE_P(Models, RobotFiles, ::testing::ValuesIn(robot_cases()),
                         [](const auto& info) { return std::string(info.param.label); });

// ---------------------------------------------------------------------------------------------
// Loading

TEST_P(RobotFiles, LoadsSevenNamedJointsAtTheReadyKeyframe) {
  const RobotCase& robot = GetParam();
  const sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file);
  ASSERT_EQ(s.num_joints(), 7);
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(s.joint_names()[i], robot.joint_prefix + std::to_string(i + 1));
  }
  EXPECT_EQ(s.timestep(), 0.001);
  EXPECT_EQ(s.time(), 0.0);
  // The keyframe stores the decimal expansions of the same angles: equal to round-off.
  EXPECT_LT((s.q() - robot.ready).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(s.dq(), JointVector::Zero(7));
  EXPECT_EQ(s.torque(), JointVector::Zero(7));
  EXPECT_EQ(s.torque_upper_limits(), robot.torque_limit);
  EXPECT_EQ(s.torque_lower_limits(), -robot.torque_limit);
}

TEST(Loading, TimestepOptionReplacesTheModels) {
  sim::SimulationOptions options;
  options.timestep = 0.002;
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml, options);
  EXPECT_EQ(s.timestep(), 0.002);
}

TEST(Loading, WithoutKeyframeStartsAtTheDefaultPose) {
  sim::SimulationOptions options;
  options.keyframe = "";
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml, options);
  EXPECT_EQ(s.q(), JointVector::Zero(7));
}

TEST(Loading, JointOrderFollowsJointNames) {
  sim::SimulationOptions options;
  for (int i = 7; i >= 1; --i) options.joint_names.push_back("panda_joint" + std::to_string(i));
  sim::Simulation reversed = sim::Simulation::from_mjcf_file(kPandaXml, options);
  sim::Simulation normal = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_EQ(reversed.joint_names(), options.joint_names);
  EXPECT_EQ(reversed.q(), normal.q().reverse().eval());

  const JointVector tau = joints({5, -3, 2, 4, 1, -1, 0.5});
  normal.set_torque(tau);
  reversed.set_torque(tau.reverse());
  for (int k = 0; k < 200; ++k) {
    normal.step();
    reversed.step();
  }
  EXPECT_GT(normal.dq().norm(), 0.1);  // it did move
  EXPECT_EQ(reversed.q(), normal.q().reverse().eval());
  EXPECT_EQ(reversed.dq(), normal.dq().reverse().eval());
}

TEST(Loading, ASubsetOfJointsLeavesTheOthersUndriven) {
  sim::SimulationOptions options;
  options.joint_names = {"panda_joint2", "panda_joint4"};
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml, options);
  EXPECT_EQ(s.num_joints(), 2);
  EXPECT_EQ(s.q(), joints({-kPi / 4, -3 * kPi / 4}));
  EXPECT_EQ(s.torque_upper_limits(), joints({87, 87}));
}

// ---------------------------------------------------------------------------------------------
// Gravity compensation

TEST_P(RobotFiles, GravityCompensatedArmHoldsStillForTwoSeconds) {
  const RobotCase& robot = GetParam();
  sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file);
  double deviation = 0.0;
  for (int k = 0; k < 2000; ++k) {
    s.step();
    deviation = std::max(deviation, (s.q() - robot.ready).cwiseAbs().maxCoeff());
  }
  EXPECT_NEAR(s.time(), 2.0, 1e-9);
  // g(q) is exact to round-off (1e-14 Nm); joint friction (>= 0.05 Nm) holds such residues, so the
  // arm does not move at all. 1e-3 rad is the brief's bound; the measured value is ~1e-20.
  EXPECT_LT(deviation, 1e-3);
  EXPECT_LT(s.dq().cwiseAbs().maxCoeff(), 1e-6);
}

TEST_P(RobotFiles, ArmFallsWithoutGravityCompensation) {
  const RobotCase& robot = GetParam();
  sim::SimulationOptions options;
  options.gravity_compensation = false;
  sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file, options);
  for (int k = 0; k < 500; ++k) s.step();
  // Measured with raw MuJoCo (models/README.md): about 1 rad after 0.5 s for both robots.
  EXPECT_GT((s.q() - robot.ready).cwiseAbs().maxCoeff(), 0.3);
}

// The gravity torque is MuJoCo's own bias force at zero velocity, also while the arm moves: a
// replay with raw MuJoCo (qfrc_applied = tau + qfrc_bias(q, 0)) follows the same trajectory.
TEST_P(RobotFiles, GravityCompensationAndTorquesMatchRawMujocoWhileMoving) {
  const RobotCase& robot = GetParam();
  sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file);
  Reference reference(robot.file);
  double difference = 0.0;
  for (int k = 0; k < 500; ++k) {
    JointVector tau(7);
    for (int i = 0; i < 7; ++i) {
      tau[i] = 0.3 * robot.torque_limit[i] * std::sin(0.01 * k + i);
    }
    ASSERT_FALSE(s.set_torque(tau));
    const JointVector force = tau + reference.gravity();
    s.step();
    reference.step(force);
    difference = std::max(difference, (s.q() - reference.q()).cwiseAbs().maxCoeff());
    difference = std::max(difference, (s.dq() - reference.dq()).cwiseAbs().maxCoeff());
  }
  EXPECT_GT((s.q() - robot.ready).norm(), 0.1);  // it really moved
  EXPECT_LT(difference, 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Commanded torque

// Joint k alone, half its torque limit: one step from rest gives dt (M + dt D)^-1 tau, so the
// torque reaches the joint unscaled (gear 1), with the right sign, in joint space.
TEST_P(RobotFiles, JointTorqueAcceleratesAsTheInverseMassMatrixSays) {
  const RobotCase& robot = GetParam();
  for (int k = 0; k < 7; ++k) {
    SCOPED_TRACE("joint " + std::to_string(k + 1));
    sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file);
    Reference reference(robot.file);
    JointVector tau = JointVector::Zero(7);
    tau[k] = 0.5 * robot.torque_limit[k];
    ASSERT_FALSE(s.set_torque(tau));
    s.step();
    expect_one_step(s.dq(), predict_one_step(reference, tau));
    EXPECT_GT(s.dq()[k], 0.0);
  }
}

TEST(Torque, IsClippedToTheActuatorRangeAndReported) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_TRUE(s.set_torque(joints({100, -100, 50, 0, 13, -12.5, 5})));
  EXPECT_EQ(s.torque(), joints({87, -87, 50, 0, 12, -12, 5}));
  EXPECT_FALSE(s.set_torque(joints({87, -87, 1, 2, 12, -12, 0})));
  EXPECT_EQ(s.torque(), joints({87, -87, 1, 2, 12, -12, 0}));

  // What is applied is the clipped torque: a raw replay with the clipped values matches.
  Reference reference(kPandaXml);
  const JointVector clipped = joints({87, -87, 50, 0, 12, -12, 5});
  s.set_torque(joints({1000, -1000, 50, 0, 100, -100, 5}));
  for (int k = 0; k < 50; ++k) {
    const JointVector force = clipped + reference.gravity();
    s.step();
    reference.step(force);
  }
  EXPECT_LT((s.q() - reference.q()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Torque, RejectsWrongSizeAndNonFiniteValuesAndKeepsThePrevious) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  const JointVector tau = joints({1, 2, 3, 4, 5, 6, 7});
  s.set_torque(tau);
  EXPECT_ERROR([&] { s.set_torque(JointVector::Zero(6)); }, {"tau", "6", "expected 7"});
  JointVector bad = tau;
  bad[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_ERROR([&] { s.set_torque(bad); }, {"tau[2]", "panda_joint3", "nan", "finite"});
  bad[2] = std::numeric_limits<double>::infinity();
  EXPECT_ERROR([&] { s.set_torque(bad); }, {"tau[2]", "inf"});
  EXPECT_EQ(s.torque(), tau);
}

TEST(State, SetStateMovesTheJointsAndRejectsBadInput) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  Reference reference(kPandaXml);
  const JointVector q = joints({0.3, -0.2, 0.1, -2.0, 0.4, 1.9, -0.5});
  const JointVector dq = joints({0.1, 0, 0, 0, 0, 0, -0.2});
  s.set_state(q, dq);
  EXPECT_EQ(s.q(), q);
  EXPECT_EQ(s.dq(), dq);
  reference.set_state(q, dq);
  EXPECT_LT((s.site_pose("flange").position - reference.site_position("flange")).norm(), 1e-15);

  EXPECT_ERROR([&] { s.set_state(JointVector::Zero(3), dq); }, {"q", "3", "expected 7"});
  JointVector bad = dq;
  bad[6] = std::nan("");
  EXPECT_ERROR([&] { s.set_state(q, bad); }, {"dq[6]", "panda_joint7"});
  EXPECT_EQ(s.q(), q);  // unchanged by the rejected call

  s.set_torque(joints({1, 1, 1, 1, 1, 1, 1}));
  s.push("flange", Vector6d::Ones(), 1.0);
  for (int k = 0; k < 10; ++k) s.step();
  s.reset();
  EXPECT_EQ(s.time(), 0.0);
  EXPECT_LT((s.q() - panda_ready()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(s.torque(), JointVector::Zero(7));
  for (int k = 0; k < 100; ++k) s.step();  // no torque, no push left: holds still
  EXPECT_LT((s.q() - panda_ready()).cwiseAbs().maxCoeff(), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Poses

TEST(Poses, FlangeAtTheReadyPoseAndFollowingTheJoints) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  const ci::Pose flange = s.site_pose("flange");
  // Published: (0.3069, 0, 0.5903) to 4 digits; MuJoCo computes (0.306891, 0, 0.590282).
  EXPECT_LT((flange.position - Eigen::Vector3d(0.306891, 0, 0.590282)).norm(), 1e-6);
  // Flange z axis points down at the ready pose.
  EXPECT_LT((flange.orientation * Eigen::Vector3d::UnitZ() - Eigen::Vector3d(0, 0, -1)).norm(),
            1e-12);
  const ci::Pose link8 = s.body_pose("panda_link8");
  EXPECT_LT((link8.position - flange.position).norm(), 1e-15);
  EXPECT_LT(link8.orientation.angularDistance(flange.orientation), 1e-12);

  // After steps the pose belongs to the current q (not to the start of the last step).
  s.set_torque(joints({10, 10, 10, 10, 3, 3, 3}));
  for (int k = 0; k < 100; ++k) s.step();
  Reference reference(kPandaXml);
  reference.set_state(s.q(), s.dq());
  EXPECT_LT((s.site_pose("flange").position - reference.site_position("flange")).norm(), 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Pushes

// A force F at the flange site yields the generalized force J^T F (J from mj_jacSite): one step
// from rest gives dt (M + dt D)^-1 J^T F. A pure torque likewise gives J_angular^T tau.
TEST(Push, ForceAndTorqueOnTheFlangeActThroughTheJacobianTranspose) {
  Reference reference(kPandaXml);
  const Eigen::MatrixXd jacobian = reference.jacobian("flange");
  const std::vector<Vector6d> wrenches = {(Vector6d() << 60, -40, -100, 0, 0, 0).finished(),
                                          (Vector6d() << 0, 0, 0, 2, 8, 4).finished(),
                                          (Vector6d() << -80, 20, 40, 4, -4, 2).finished()};
  for (const Vector6d& wrench : wrenches) {
    SCOPED_TRACE(::testing::PrintToString(wrench.transpose()));
    sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
    s.push("flange", wrench, 1.0);
    s.step();
    expect_one_step(s.dq(), predict_one_step(reference, jacobian.transpose() * wrench));
  }
}

// On a body, the wrench acts at the body's origin (not its centre of mass).
TEST(Push, OnABodyActsAtItsOrigin) {
  Reference reference(kPandaXml);
  const Eigen::MatrixXd jacobian = reference.jacobian("panda_link5");
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  const Vector6d wrench = (Vector6d() << 0, 100, 0, 0, 0, 0).finished();
  s.push("panda_link5", wrench, 1.0);
  s.step();
  expect_one_step(s.dq(), predict_one_step(reference, jacobian.transpose() * wrench));
}

// A push lasts `duration` (20 steps here) at a point that moves with the flange, then stops:
// a raw replay with qfrc_applied = g + J(q)^T F for exactly 20 steps matches.
TEST(Push, LastsItsDurationAndFollowsTheSite) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  Reference reference(kPandaXml);
  const Vector6d wrench = (Vector6d() << 10, 20, -15, 0.5, 0, -0.5).finished();
  s.push("flange", wrench, 0.02);
  for (int k = 0; k < 100; ++k) {
    JointVector force = reference.gravity();
    if (k < 20) force += reference.jacobian("flange").transpose() * wrench;
    s.step();
    reference.step(force);
  }
  EXPECT_GT((s.q() - panda_ready()).norm(), 0.01);  // it moved
  EXPECT_LT((s.q() - reference.q()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((s.dq() - reference.dq()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Push, ClearPushesEndsThem) {
  sim::Simulation pushed = sim::Simulation::from_mjcf_file(kPandaXml);
  sim::Simulation untouched = sim::Simulation::from_mjcf_file(kPandaXml);
  pushed.push("flange", Vector6d::Constant(10.0), std::numeric_limits<double>::infinity());
  pushed.push("panda_link3", Vector6d::Constant(5.0), 1.0);
  pushed.clear_pushes();
  for (int k = 0; k < 100; ++k) {
    pushed.step();
    untouched.step();
  }
  EXPECT_EQ(pushed.q(), untouched.q());
}

TEST(Push, RejectsUnknownNamesAndBadValues) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_ERROR([&] { s.push("gripper", Vector6d::Zero(), 1.0); },
               {"'gripper'", "flange", "panda_link7"});
  Vector6d bad = Vector6d::Zero();
  bad[4] = std::nan("");
  EXPECT_ERROR([&] { s.push("flange", bad, 1.0); }, {"wrench_world[4]", "nan"});
  EXPECT_ERROR([&] { s.push("flange", Vector6d::Zero(), 0.0); }, {"duration", "0"});
  EXPECT_ERROR([&] { s.push("flange", Vector6d::Zero(), std::nan("")); }, {"duration"});
  EXPECT_ERROR([&] { s.push("world", Vector6d::Zero(), 1.0); }, {"world"});
}

// ---------------------------------------------------------------------------------------------
// Scenes and contact

// A table 4 cm below the flange; a 20 N downward push lowers the gravity-compensated arm onto it.
// At rest the table must push back with 20 N: static equilibrium J^T (F + F_contact) =
// tau_friction, with |tau_friction| <= 0.1 Nm against a lever of >= 0.3 m, i.e. < 0.4 N = 2 %;
// the contact solver adds a small step-to-step ripple (measured 1.5 %). Bound: 5 %.
TEST(Scene, FlangePressedOnATableFeelsThePressingForce) {
  const double top = 0.55;
  sim::Simulation s =
      sim::make_scene(kPandaXml, {sim::Box::table({0.45, 0.0}, {0.25, 0.4}, top, "table")});
  EXPECT_EQ(s.num_joints(), 7);
  EXPECT_EQ(s.contact_wrench("panda_link8"), Vector6d::Zero());  // hovering 4 cm above

  const Eigen::Vector3d force(0, 0, -20);
  s.push("flange", (Vector6d() << force, 0, 0, 0).finished(),
         std::numeric_limits<double>::infinity());
  for (int k = 0; k < 2500; ++k) s.step();
  for (int k = 0; k < 500; ++k) {
    s.step();
    const Vector6d wrench = s.contact_wrench("panda_link8");
    ASSERT_NEAR(wrench[2], 20.0, 1.0) << "step " << k << ": " << wrench.transpose();
    ASSERT_LT(wrench.head<2>().norm(), 1.0) << "step " << k << ": " << wrench.transpose();
  }
  // The flange rests on the table (soft contact: sub-millimetre penetration).
  EXPECT_NEAR(s.site_pose("flange").position.z(), top, 1e-3);
  // panda_link8 has no geoms: its contacts are those of panda_link7, to which it is welded.
  EXPECT_EQ(s.contact_wrench("panda_link7").head<3>(), s.contact_wrench("panda_link8").head<3>());
  EXPECT_EQ(s.contact_wrench("panda_link3"), Vector6d::Zero());
}

TEST(Scene, BoxesAreValidated) {
  sim::Box box = sim::Box::table({0.5, 0}, {0.2, 0.2}, 0.3);
  EXPECT_DOUBLE_EQ(box.center.z(), 0.15);
  EXPECT_DOUBLE_EQ(box.half_size.z(), 0.15);
  box.half_size.y() = 0.0;
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {box}); }, {"boxes[0].half_size[1]", "> 0"});
  box.half_size.y() = 0.2;
  box.center.x() = std::nan("");
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {box}); }, {"boxes[0].center[0]", "finite"});
  // A URDF is converted (the scene then is the URDF's robot); another XML file is neither.
  EXPECT_EQ(sim::make_scene(kPandaUrdf, {}).num_joints(), 7);
  const std::string sdf = ::testing::TempDir() + "sim_test_robot.sdf";
  std::ofstream(sdf) << "<sdf version=\"1.6\"><model name=\"arm\"/></sdf>\n";
  EXPECT_ERROR([&] { sim::make_scene(sdf, {}); }, {"not an MJCF file", "<sdf>"});
  std::remove(sdf.c_str());
  EXPECT_ERROR([&] { sim::make_scene("/nonexistent/robot.xml", {}); },
               {"/nonexistent/robot.xml", "does not exist"});
  sim::Box a = sim::Box::table({0.5, 0}, {0.2, 0.2}, 0.3, "same");
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {a, a}); }, {"same"});
}

TEST(Scene, WorksForTheIiwaAndKeepsItsKeyframe) {
  sim::Simulation s =
      sim::make_scene(kIiwaXml, {{"wall", Eigen::Vector3d(0, 0.8, 0.5),
                                  Eigen::Vector3d(1, 0.05, 0.5), Eigen::Quaterniond::Identity()}});
  EXPECT_LT((s.q() - iiwa_ready()).cwiseAbs().maxCoeff(), 1e-15);
}

// ---------------------------------------------------------------------------------------------
// URDF

TEST(Urdf, LoadsSevenJointsAndAppliesTorqueThroughQfrcApplied) {
  for (const std::string& file : {kPandaUrdf, kIiwaUrdf}) {
    SCOPED_TRACE(file);
    const sim::Simulation s = sim::Simulation::from_urdf_file(file);
    EXPECT_EQ(s.num_joints(), 7);
    EXPECT_EQ(s.timestep(), 0.001);
    EXPECT_EQ(s.q(), JointVector::Zero(7));               // URDF has no keyframe
    EXPECT_TRUE(std::isinf(s.torque_upper_limits()[0]));  // no actuator, no limit
  }
  // Without the import's rotor inertia the simulation is MuJoCo's plain URDF model, which the
  // reference loads.
  sim::SimulationOptions options;
  options.armature = JointVector::Zero(1);
  sim::Simulation s = sim::Simulation::from_urdf_file(kPandaUrdf, options);
  EXPECT_EQ(s.joint_names()[3], "panda_joint4");
  s.set_state(panda_ready(), JointVector::Zero(7));
  for (int k = 0; k < 500; ++k) s.step();  // gravity compensation through qfrc_applied
  EXPECT_LT((s.q() - panda_ready()).cwiseAbs().maxCoeff(), 1e-3);

  // The reference loads the MJCF the import made (armature 0, as the options above).
  const std::string imported = ::testing::TempDir() + "sim_test_panda_imported.xml";
  std::ofstream(imported) << sim::detail::mjcf_from_urdf(kPandaUrdf, {0.0, 0.5});
  Reference reference(imported);
  std::remove(imported.c_str());
  reference.set_state(s.q(), JointVector::Zero(7));
  s.set_state(s.q(), JointVector::Zero(7));
  const JointVector tau = joints({0, 0, 0, 500, 0, 0, 0});
  EXPECT_FALSE(s.set_torque(tau));  // not limited
  s.step();
  expect_one_step(s.dq(), predict_one_step(reference, tau));
  EXPECT_GT(s.dq()[3], 0.0);
}

TEST(Options, StartConfigurationAndArmatureReplaceTheModels) {
  sim::SimulationOptions options;
  options.start_q = panda_ready();
  sim::Simulation s = sim::Simulation::from_urdf_file(kPandaUrdf, options);
  EXPECT_EQ(s.q(), panda_ready());
  EXPECT_EQ(s.armature(), JointVector::Constant(7, 0.1));  // the URDF import's default
  s.set_state(JointVector::Zero(7), JointVector::Zero(7));
  s.reset();
  EXPECT_EQ(s.q(), panda_ready());  // reset() returns to the start configuration too

  // One torque on the wrist (joint 7, M_77 about 0.01 kg m^2) meets the rotor inertia first:
  // with 1 kg m^2 instead of 0.1 the first step's acceleration is (M_77 + 0.1) / (M_77 + 1),
  // about a ninth; the other joints' coupling moves that by a few per cent at most.
  const JointVector tau = joints({0, 0, 0, 0, 0, 0, 1});
  s.set_torque(tau);
  s.step();
  const double light = s.dq()[6];
  options.armature = JointVector::Constant(1, 1.0);
  sim::Simulation heavy = sim::Simulation::from_urdf_file(kPandaUrdf, options);
  EXPECT_EQ(heavy.armature(), JointVector::Constant(7, 1.0));
  heavy.set_torque(tau);
  heavy.step();
  EXPECT_GT(light, 0.0);
  EXPECT_NEAR(heavy.dq()[6] / light, 0.11 / 1.01, 0.02);

  // Per joint, on an MJCF: replaces the file's values.
  options.armature = joints({0.5, 0.5, 0.5, 0.5, 0.2, 0.2, 0.2});
  options.start_q = JointVector();
  EXPECT_EQ(sim::Simulation::from_mjcf_file(kPandaXml, options).armature(), options.armature);
}

TEST(Errors, BadStartConfigurationOrArmatureNameTheJoint) {
  sim::SimulationOptions options;
  options.start_q = JointVector::Zero(7);  // joint 4's range is [-3.0718, -0.0698]
  EXPECT_ERROR([&] { sim::Simulation::from_urdf_file(kPandaUrdf, options); },
               {"start_q[3] = 0", "panda_joint4", "outside its range [-3.0718, -0.0698]"});
  options.start_q = JointVector::Zero(3);
  EXPECT_ERROR([&] { sim::Simulation::from_urdf_file(kPandaUrdf, options); },
               {"start_q has 3 values", "one per joint (7)"});
  options.start_q = panda_ready();
  options.start_q[1] = std::nan("");
  EXPECT_ERROR([&] { sim::Simulation::from_urdf_file(kPandaUrdf, options); },
               {"start_q[1]", "panda_joint2", "not finite"});
  options.start_q = JointVector();
  options.armature = joints({0.1, 0.1, -0.1, 0.1, 0.1, 0.1, 0.1});
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"armature[2] = -0.1", "panda_joint3", ">= 0"});
  options.armature = JointVector::Constant(2, 0.1);
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"armature has 2 values", "1 or one per joint (7)"});
}

// The URDF-only robots (models/README.md): loaded by MuJoCo's importer, their start configuration
// held by gravity compensation, and the project's model (urdfdom + KDL) of the same file agreeing
// with MuJoCo on the flange pose, the gravity torques and the mass matrix.
namespace {

struct UrdfRobot {
  std::string file;
  std::vector<std::string> joint_names;
  JointVector start;
};

std::vector<UrdfRobot> urdf_robots() {
  return {{kUr5eUrdf,
           {"shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
            "wrist_2_joint", "wrist_3_joint"},
           joints({kPi, -kPi / 2, kPi / 2, -kPi / 2, -kPi / 2, 0})},
          {kPlanar3Urdf, {"joint1", "joint2", "joint3"}, joints({0.5, 1.5, kPi - 2.0})}};
}

}  // namespace

TEST(Urdf, Ur5eAndPlanarArmHoldTheirStartConfigurationWithZeroTorque) {
  for (const UrdfRobot& robot : urdf_robots()) {
    SCOPED_TRACE(robot.file);
    sim::Simulation s = sim::Simulation::from_urdf_file(robot.file);
    EXPECT_EQ(s.joint_names(), robot.joint_names);
    const int n = s.num_joints();
    s.set_state(robot.start, JointVector::Zero(n));
    const ci::Pose start = s.body_pose("tool0");
    // The flange body is the model's tip link at the same q.
    const ci::RobotModel model = ci::RobotModel::from_urdf_file(robot.file, "base_link", "tool0");
    ci::ModelWorkspace workspace(model);
    ci::Pose expected;
    ASSERT_TRUE(workspace.compute_pose(robot.start, expected));
    EXPECT_LT((start.position - expected.position).norm(), 1e-12);
    EXPECT_LT(start.orientation.angularDistance(expected.orientation), 1e-12);
    // Zero torque for 1 s; gravity compensation (on by default) holds the arm (measured: the
    // flange does not move at all; joint friction holds the round-off residues).
    double drift = 0.0;
    for (int k = 0; k < 1000; ++k) {
      s.step();
      drift = std::max(drift, (s.body_pose("tool0").position - start.position).norm());
    }
    EXPECT_NEAR(s.time(), 1.0, 1e-9);
    EXPECT_LT(drift, 1e-3);
    EXPECT_LT((s.q() - robot.start).cwiseAbs().maxCoeff(), 1e-3);
  }
}

TEST(Urdf, Ur5eAndPlanarArmModelGravityAndMassMatchMujoco) {
  for (const UrdfRobot& robot : urdf_robots()) {
    SCOPED_TRACE(robot.file);
    const ci::RobotModel model = ci::RobotModel::from_urdf_file(robot.file, "base_link", "tool0");
    ci::ModelWorkspace workspace(model);
    ci::Kinematics kinematics = workspace.make_kinematics();
    const int n = model.num_joints();
    // Raw MuJoCo on the same URDF (no armature): g(q) and M(q) at random configurations. Measured:
    // 4e-14 Nm and 5e-15 kg m^2. (The Panda's mass matrix agrees only to 1e-8, models/README.md:
    // MuJoCo re-derives each body inertia from an eigen-decomposition; these inertias are nearly
    // diagonal, so it is exact to round-off here.)
    Reference reference(robot.file);
    ASSERT_EQ(reference.nv(), n);
    std::mt19937 rng(21);
    double gravity_error = 0.0, mass_error = 0.0;
    for (int k = 0; k < 100; ++k) {
      JointVector q(n);
      for (int i = 0; i < n; ++i) q[i] = std::uniform_real_distribution<double>(-2.5, 2.5)(rng);
      ASSERT_TRUE(workspace.compute(q, JointVector::Zero(n), kinematics, true));
      reference.set_state(q, JointVector::Zero(n));
      gravity_error =
          std::max(gravity_error, (kinematics.gravity - reference.gravity()).cwiseAbs().maxCoeff());
      mass_error =
          std::max(mass_error, (kinematics.mass - reference.mass_matrix()).cwiseAbs().maxCoeff());
    }
    EXPECT_LT(gravity_error, 1e-12);
    EXPECT_LT(mass_error, 1e-12);

    // The model's g(q) as the commanded torque, MuJoCo's own compensation off: the arm stays for
    // 1 s (measured: it does not move at all); with zero torque it falls.
    sim::SimulationOptions options;
    options.gravity_compensation = false;
    for (const bool compensate : {true, false}) {
      sim::Simulation s = sim::Simulation::from_urdf_file(robot.file, options);
      s.set_state(robot.start, JointVector::Zero(n));
      const Eigen::Vector3d start = s.body_pose("tool0").position;
      double drift = 0.0;
      for (int k = 0; k < 1000; ++k) {
        ASSERT_TRUE(workspace.compute(s.q(), s.dq(), kinematics, true));
        s.set_torque(compensate ? JointVector(kinematics.gravity) : JointVector::Zero(n));
        s.step();
        drift = std::max(drift, (s.body_pose("tool0").position - start).norm());
      }
      if (compensate) {
        EXPECT_LT(drift, 1e-3);
      } else {
        EXPECT_GT(drift, 0.1);
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Errors at load time

TEST(Errors, MissingFile) {
  EXPECT_ERROR([] { sim::Simulation::from_mjcf_file("/nonexistent/robot.xml"); },
               {"MJCF", "/nonexistent/robot.xml", "does not exist"});
  EXPECT_ERROR([] { sim::Simulation::from_urdf_file("/nonexistent/robot.urdf"); },
               {"URDF", "/nonexistent/robot.urdf"});
}

TEST(Errors, MalformedXml) {
  const std::string path = ::testing::TempDir() + "sim_test_malformed.xml";
  {
    std::ofstream file(path);
    file << "<mujoco><worldbody><geom type=\"box\" size=\"1 1 1\"</worldbody></mujoco>";
  }
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(path); }, {"cannot load", path});
  std::remove(path.c_str());
}

TEST(Errors, UnknownOrDuplicateJointNameAndBadOptions) {
  sim::SimulationOptions options;
  options.joint_names = {"panda_joint1", "elbow"};
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"joint_names[1]", "'elbow'", "panda_joint1", "panda_joint7"});
  options.joint_names = {"panda_joint1", "panda_joint1"};
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); }, {"twice"});
  options.joint_names = {};
  options.timestep = 0.0;
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"timestep", "0", "positive"});
}

TEST(Errors, UnknownBodyOrSite) {
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_ERROR([&] { s.site_pose("tcp"); }, {"site 'tcp'", "flange"});
  EXPECT_ERROR([&] { s.body_pose("hand"); }, {"body 'hand'", "panda_link0"});
  EXPECT_ERROR([&] { s.contact_wrench("hand"); }, {"body 'hand'", "panda_link8"});
}

TEST(Errors, RenderArgumentsAreCheckedBeforeAnyOpenGl) {
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_ERROR([&] { s.render_png("/tmp/x.png", 0, 10); }, {"size", "0 x 10"});
  EXPECT_ERROR([&] { s.render_png("/tmp/x.png", 10, 10, "overhead"); },
               {"camera 'overhead'", "(none)"});
  EXPECT_ERROR([&] { s.render_png("", 10, 10); }, {"path"});
}

// ---------------------------------------------------------------------------------------------
// Rendering

namespace {

struct PngInfo {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::set<std::uint32_t> colours;
};

PngInfo read_png(const std::string& path) {
  PngInfo info;
  std::ifstream file(path, std::ios::binary);
  std::vector<unsigned char> header(24);
  file.read(reinterpret_cast<char*>(header.data()), 24);
  const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (!file || !std::equal(signature, signature + 8, header.begin()) ||
      std::string(header.begin() + 12, header.begin() + 16) != "IHDR") {
    return info;
  }
  auto big_endian = [&](int at) {
    return (std::uint32_t{header[at]} << 24) | (std::uint32_t{header[at + 1]} << 16) |
           (std::uint32_t{header[at + 2]} << 8) | std::uint32_t{header[at + 3]};
  };
  info.width = big_endian(16);
  info.height = big_endian(20);

  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_file(&image, path.c_str()) == 0) return info;
  image.format = PNG_FORMAT_RGB;
  std::vector<unsigned char> pixels(PNG_IMAGE_SIZE(image));
  if (png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr) == 0) return info;
  for (std::size_t i = 0; i + 2 < pixels.size(); i += 3) {
    info.colours.insert((std::uint32_t{pixels[i]} << 16) | (std::uint32_t{pixels[i + 1]} << 8) |
                        pixels[i + 2]);
  }
  return info;
}

}  // namespace

TEST(Rendering, WritesAPngOfTheRequestedSizeShowingTheScene) {
  std::string reason;
  if (!sim::offscreen_rendering_available(&reason)) {
    GTEST_SKIP() << "offscreen rendering unavailable here: " << reason;
  }
  sim::Simulation s =
      sim::make_scene(kPandaXml, {sim::Box::table({0.45, 0.0}, {0.25, 0.4}, 0.55, "table")});
  const std::string path = ::testing::TempDir() + "sim_test_render.png";
  s.render_png(path, 320, 200);
  PngInfo info = read_png(path);
  EXPECT_EQ(info.width, 320u);
  EXPECT_EQ(info.height, 200u);
  // Floor checker, robot, table, lighting: many colours (a blank frame has one).
  EXPECT_GT(info.colours.size(), 50u);

  // Larger than MuJoCo's default 640 x 480 offscreen buffer: the context grows.
  s.render_png(path, 1000, 700);
  info = read_png(path);
  EXPECT_EQ(info.width, 1000u);
  EXPECT_EQ(info.height, 700u);
  EXPECT_GT(info.colours.size(), 50u);
  std::remove(path.c_str());

  EXPECT_ERROR([&] { s.render_png("/nonexistent/dir/x.png", 10, 10); }, {"/nonexistent/dir/x.png"});
}

// ---------------------------------------------------------------------------------------------
// Real-time behaviour

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
TEST(RealTime, StepAllocatesNothingWithTorquePushesAndContact) {
  sim::Simulation s =
      sim::make_scene(kPandaXml, {sim::Box::table({0.45, 0.0}, {0.25, 0.4}, 0.55, "table")});
  s.push("flange", (Vector6d() << 0, 0, -20, 0, 0, 0).finished(),
         std::numeric_limits<double>::infinity());
  s.push("panda_link5", (Vector6d() << 0, 1, 0, 0, 0, 0).finished(), 0.5);
  JointVector tau = JointVector::Zero(7);
  for (int k = 0; k < 200; ++k) s.step();  // warm up: contacts appear
  allocation_counter::Scope scope;
  for (int k = 0; k < 3000; ++k) {
    tau[0] = 0.1 * std::sin(0.01 * k);
    s.set_torque(tau);
    s.step();
  }
  EXPECT_EQ(scope.allocations(), 0);
  EXPECT_GT(s.contact_wrench("panda_link8")[2], 10.0);  // the contact was there throughout
}
#endif
