// The drop-in under the published library's usual threading: one thread calls the setters (a ROS
// callback thread: setNumberOfJoints, setNullspaceConfig, ...) while the control thread calls
// calculateCommandedTorques() and the getters. The setters hand their settings over through a
// lock-free buffer and the control thread takes them up at its next call, so neither thread
// touches what the other writes (it used to: "free(): corrupted unsorted chunks", 5 of 5 runs).
// ThreadSanitizer runs this binary in CI (scripts/test --sanitize thread).

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>
#include <utility>
#include <vector>

#include "cartesian_impedance/compat/cartesian_impedance_controller.hpp"

namespace ci = cartesian_impedance;
using Compat = cartesian_impedance_controller::CartesianImpedanceController;

namespace {

constexpr int kJoints = 7;
constexpr double kDelta = 0.5;  // [Nm] per call

struct Arm {
  Eigen::VectorXd q = Eigen::VectorXd::LinSpaced(kJoints, -0.6, 0.6);
  Eigen::VectorXd dq = Eigen::VectorXd::Constant(kJoints, 0.05);
  Eigen::Vector3d position = Eigen::Vector3d(0.4, 0.0, 0.5);
  Eigen::Quaterniond orientation = Eigen::Quaterniond(0.0, 1.0, 0.0, 0.0);
  Eigen::MatrixXd jacobian;

  Arm() {
    jacobian = Eigen::MatrixXd::Zero(6, kJoints);
    for (int c = 0; c < kJoints; ++c) {
      for (int r = 0; r < 6; ++r) jacobian(r, c) = 0.3 * std::sin(1.0 + r + 2.0 * c);
    }
    jacobian.leftCols(6) += Eigen::MatrixXd::Identity(6, 6);
  }
};

// A thread joined however the test ends (a failed ASSERT returns early).
class Joined {
 public:
  template <typename F>
  explicit Joined(F&& f) : thread_(std::forward<F>(f)) {}
  ~Joined() { join(); }
  void join() {
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::thread thread_;
};

// The nullspace configuration the setter thread sends in round `i`.
Eigen::VectorXd nullspace_config(int i) {
  return Eigen::VectorXd::LinSpaced(kJoints, -0.5, 0.5).array() + 0.001 * (i % 100);
}

}  // namespace

// The pattern, with every setter the wrapper's callbacks use. Both threads run until the
// setter thread is done; the control thread checks each call on its own terms (finite torques,
// each joint's change within the torque delta, also across a reset of the joint count), and after
// the setter thread has finished, the last settings are in force.
TEST(CompatThreads, OneSetterThreadAndTheControlThread) {
  const Arm arm;
  Compat controller;
  controller.setMaxTorqueDelta(kDelta);
  controller.initDesiredPose(arm.position, arm.orientation);
  controller.initNullspaceConfig(arm.q);
  // The threads overlap for at least kOverlap calls: the setter thread goes on until the control
  // thread has made them (each side only counts; nothing waits on a clock).
  constexpr int kRounds = 3000;
  constexpr long kOverlap = 2000;

  std::atomic<bool> setter_started{false}, setter_done{false};
  std::atomic<long> control_calls{0};
  int last_round = -1;
  Joined setter([&] {
    setter_started.store(true);
    for (int i = 0; i < kRounds || control_calls.load() < kOverlap; ++i) {
      controller.setNumberOfJoints(kJoints);
      controller.setNullspaceConfig(nullspace_config(i));
      const double k = 300.0 + (i % 7) * 100.0;
      controller.setStiffness(k, k, k, 30.0, 30.0, 30.0, 10.0);
      controller.setReferencePose(arm.position + Eigen::Vector3d(0.0, 0.0, 0.001 * (i % 50)),
                                  arm.orientation);
      controller.applyWrench((Eigen::Matrix<double, 6, 1>() << 0, 0, -(i % 5), 0, 0, 0).finished());
      last_round = i;
    }
    setter_done.store(true);
  });

  while (!setter_started.load()) std::this_thread::yield();
  Eigen::VectorXd tau = Eigen::VectorXd::Zero(kJoints), last = tau;
  Eigen::VectorXd q_d_nullspace;
  long calls = 0, not_ok = 0;
  double largest_change = 0.0;
  while (!setter_done.load() || calls < 200) {
    const ci::Status status = controller.calculateCommandedTorques(
        arm.q, arm.dq, arm.position, arm.orientation, arm.jacobian, tau);
    if (status != ci::Status::ok) ++not_ok;
    ASSERT_TRUE(tau.allFinite()) << "call " << calls;
    largest_change = std::max(largest_change, (tau - last).cwiseAbs().maxCoeff());
    last = tau;
    // The wrapper's state publisher reads the getters on the control thread.
    controller.getState(nullptr, nullptr, nullptr, nullptr, &q_d_nullspace, nullptr);
    ASSERT_EQ(q_d_nullspace.size(), kJoints);
    ASSERT_EQ(controller.getLastCommands(), tau);
    control_calls.store(++calls);
  }
  setter.join();
  EXPECT_EQ(not_ok, 0);
  // Rounding only: tau + clamp(law - tau) can land an ulp past the delta.
  EXPECT_LE(largest_change, kDelta * (1.0 + 1e-12));
  EXPECT_GT(largest_change, 0.9 * kDelta);  // the law moved, the limit bound
  RecordProperty("control_calls", static_cast<int>(calls));
  RecordProperty("setter_rounds", last_round + 1);

  // What the setter thread sent last is what the next call uses (no filters: at once).
  controller.calculateCommandedTorques(arm.q, arm.dq, arm.position, arm.orientation, arm.jacobian,
                                       tau);
  Eigen::Matrix<double, 6, 6> stiffness;
  Eigen::Vector3d position_d;
  controller.getState(&position_d, nullptr, &stiffness, nullptr, &q_d_nullspace, nullptr);
  EXPECT_EQ(q_d_nullspace, nullspace_config(last_round));
  EXPECT_EQ(stiffness(0, 0), 300.0 + (last_round % 7) * 100.0);
  EXPECT_EQ(position_d.z(), arm.position.z() + 0.001 * (last_round % 50));
  EXPECT_EQ(controller.getAppliedWrench()[2], -(last_round % 5));
}

// A new joint count from the setter thread takes effect whole at a call of the control thread:
// a call either computes for the count in force (torques and nullspace configuration of that size)
// or, if the count changed since the caller sized its vectors, refuses the wrongly sized output
// and computes nothing; the caller then resizes to getLastCommands().size(). The setter thread
// changes the count once the control thread has seen the last change (it waits on the control
// thread's count, not on a clock), so every change crosses the hand-over while both run.
TEST(CompatThreads, ANewJointCountFromTheSetterThreadSwitchesWhole) {
  Compat controller;
  controller.setMaxTorqueDelta(kDelta);
  constexpr int kChanges = 200;  // 6, 7, 6, ..., 7
  std::atomic<bool> setter_done{false};
  std::atomic<long> seen{7};
  Joined setter([&] {
    for (int i = 0; i < kChanges; ++i) {
      const int n = i % 2 == 0 ? 6 : 7;
      controller.setNumberOfJoints(static_cast<size_t>(n));
      controller.setNullspaceConfig(Eigen::VectorXd::Constant(n, 0.1 * n));
      while (seen.load() != n) std::this_thread::yield();
    }
    setter_done.store(true);
  });
  long calls = 0, resized = 0, switches = 0;
  while (!setter_done.load()) {
    const Eigen::Index n = controller.getLastCommands().size();
    ASSERT_TRUE(n == 6 || n == 7) << n;
    if (n != seen.load()) ++switches;
    seen.store(n);
    const Eigen::VectorXd q = Eigen::VectorXd::Zero(n), dq = Eigen::VectorXd::Zero(n);
    Eigen::MatrixXd jacobian = Eigen::MatrixXd::Zero(6, n);
    jacobian.leftCols(6).setIdentity();
    Eigen::VectorXd tau = Eigen::VectorXd::Constant(n, 123.0);
    const ci::Status status = controller.calculateCommandedTorques(
        q, dq, Eigen::Vector3d(0.4, 0, 0.5), Eigen::Quaterniond::Identity(), jacobian, tau);
    if (status == ci::Status::ok) {
      ASSERT_TRUE(tau.allFinite());
    } else {
      ASSERT_EQ(status, ci::Status::invalid_robot_state) << ci::to_string(controller.fault());
      ASSERT_STREQ(controller.fault().input, "tau");
      ASSERT_EQ(tau, Eigen::VectorXd::Constant(n, 123.0));  // nothing written
      ++resized;
    }
    ++calls;
  }
  setter.join();
  EXPECT_EQ(switches, kChanges);
  RecordProperty("control_calls", static_cast<int>(calls));
  RecordProperty("resized_calls", static_cast<int>(resized));
  EXPECT_EQ(controller.getLastCommands().size(), 7);
  Eigen::MatrixXd jacobian = Eigen::MatrixXd::Zero(6, 7);
  jacobian.leftCols(6).setIdentity();
  controller.calculateCommandedTorques(Eigen::VectorXd::Zero(7), Eigen::VectorXd::Zero(7),
                                       Eigen::Vector3d(0.4, 0, 0.5), Eigen::Quaterniond::Identity(),
                                       jacobian);
  EXPECT_EQ(controller.status(), ci::Status::ok);
  Eigen::VectorXd q_d_nullspace;
  controller.getState(nullptr, nullptr, nullptr, nullptr, &q_d_nullspace, nullptr);
  EXPECT_EQ(q_d_nullspace, Eigen::VectorXd::Constant(7, 0.1 * 7));
}
