// Unit tests of the ROS shell's message conversions that need no ROS master: joint states mapped
// to the model's order, poses, wrenches, stiffness and trajectories across frames, the state
// message from a loop step and the control thread's timing, and hostile messages fuzzed through
// them while the cycle stays safe.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <cartesian_impedance/config/yaml.hpp>
#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/loop/control_loop.hpp>

#include "conversions.hpp"

namespace ci = cartesian_impedance;
namespace cir = cartesian_impedance_ros;

namespace {

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;

ci::RobotModel panda() {
  return ci::RobotModel::from_urdf_file(kSource + "/models/panda/panda.urdf", "panda_link0",
                                        "panda_link8");
}

}  // namespace

// ---- joint states ---------------------------------------------------------------------------

TEST(JointStateMapper, ReordersAndIgnoresOtherJoints) {
  const ci::node::JointStateMapper mapper({"a", "b", "c"});
  sensor_msgs::JointState message;
  message.name = {"finger", "c", "a", "b"};
  message.position = {9, 3, 1, 2};
  message.velocity = {9, 30, 10, 20};
  message.effort = {9, 300, 100, 200};
  cir::JointSample sample;
  ASSERT_TRUE(mapper.map(cir::joint_state_view(message), sample));
  EXPECT_EQ(sample.q, (Eigen::Vector3d(1, 2, 3)));
  EXPECT_EQ(sample.dq, (Eigen::Vector3d(10, 20, 30)));
  EXPECT_EQ(sample.effort, (Eigen::Vector3d(100, 200, 300)));

  message.effort.clear();  // efforts are optional
  ASSERT_TRUE(mapper.map(cir::joint_state_view(message), sample));
  EXPECT_EQ(sample.effort.size(), 0);

  sensor_msgs::JointState gripper;
  gripper.name = {"finger"};
  gripper.position = {0.1};
  gripper.velocity = {0.0};
  EXPECT_FALSE(mapper.map(cir::joint_state_view(gripper), sample));
}

// header.stamp (system clock) becomes the measurement's time on the control thread's clock.
TEST(JointStateMapper, TakesWhenItWasMeasuredFromTheStamp) {
  const ci::node::JointStateMapper mapper({"a"});
  sensor_msgs::JointState message;
  message.name = {"a"};
  message.position = {0.1};
  message.velocity = {0.0};
  cir::JointSample sample;
  ASSERT_TRUE(mapper.map(cir::joint_state_view(message), sample));
  EXPECT_EQ(sample.sampled.time_since_epoch().count(), 0);  // no stamp

  const auto now = std::chrono::system_clock::now().time_since_epoch();
  message.header.stamp.fromNSec(static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(now - std::chrono::milliseconds(30))
          .count()));
  ASSERT_TRUE(mapper.map(cir::joint_state_view(message), sample));
  const double age =
      std::chrono::duration<double>(ci::runtime::monotonic_now() - sample.sampled).count();
  EXPECT_GE(age, 0.030);
  EXPECT_LT(age, 0.035);  // the few microseconds in between, with a loaded machine's margin
}

TEST(JointStateMapper, RejectsIncompleteMessages) {
  const ci::node::JointStateMapper mapper({"a", "b", "c"});
  cir::JointSample sample;
  sensor_msgs::JointState message;
  message.name = {"a", "b"};
  message.position = {1, 2};
  message.velocity = {1, 2};
  EXPECT_THROW(mapper.map(cir::joint_state_view(message), sample), ci::Error);  // c missing
  message.name = {"a", "b", "c"};
  message.position = {1, 2, 3};
  message.velocity = {};
  EXPECT_THROW(mapper.map(cir::joint_state_view(message), sample), ci::Error);  // no velocities
  message.velocity = {1, 2, 3};
  message.effort = {1};
  EXPECT_THROW(mapper.map(cir::joint_state_view(message), sample), ci::Error);  // effort size
  message.effort = {};
  message.position = {1, 2};
  EXPECT_THROW(mapper.map(cir::joint_state_view(message), sample), ci::Error);  // position size
  message.name = {"a", "b", "c", "a"};
  message.position = {1, 2, 3, 4};
  message.velocity = {1, 2, 3, 4};
  EXPECT_THROW(mapper.map(cir::joint_state_view(message), sample), ci::Error);  // a twice
}

TEST(JointStateMapper, PassesNonFiniteValuesOnToTheController) {
  const ci::node::JointStateMapper mapper({"a"});
  sensor_msgs::JointState message;
  message.name = {"a"};
  message.position = {std::numeric_limits<double>::quiet_NaN()};
  message.velocity = {0.0};
  cir::JointSample sample;
  ASSERT_TRUE(mapper.map(cir::joint_state_view(message), sample));
  EXPECT_TRUE(std::isnan(sample.q[0]));
}

// ---- geometry -------------------------------------------------------------------------------

TEST(Conversions, PoseRoundTripKeepsQuaternionOrderAndNorm) {
  geometry_msgs::Pose message;
  message.position.x = 1;
  message.position.y = 2;
  message.position.z = 3;
  message.orientation.x = 0.0;
  message.orientation.y = 2.0;  // not unit: the library, not the conversion, rejects it
  message.orientation.z = 0.0;
  message.orientation.w = 0.0;
  const ci::Pose pose = cir::pose_from_message(message);
  EXPECT_EQ(pose.orientation.y(), 2.0);
  EXPECT_EQ(pose.orientation.w(), 0.0);
  geometry_msgs::Pose back;
  cir::pose_to_message(pose, back);
  EXPECT_EQ(back, message);
}

TEST(Conversions, TransformsPosesWrenchesAndStiffness) {
  // Frame "world" has the base at (1, 0, 0), rotated 90 degrees about z.
  geometry_msgs::Transform transform;
  transform.translation.x = 1.0;
  transform.rotation.z = std::sqrt(0.5);
  transform.rotation.w = std::sqrt(0.5);
  const Eigen::Isometry3d T = cir::isometry_from_transform(transform);

  ci::Pose pose;
  pose.position = Eigen::Vector3d(1, 0, 0);
  const ci::Pose base = cir::transform_pose(T, pose);
  EXPECT_TRUE(base.position.isApprox(Eigen::Vector3d(1, 1, 0)));
  EXPECT_NEAR(base.orientation.angularDistance(
                  Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()))),
              0.0, 1e-12);

  ci::Vector6d wrench;
  wrench << 1, 0, 0, 0, 2, 0;
  ci::Vector6d expected;
  expected << 0, 1, 0, -2, 0, 0;
  EXPECT_TRUE(cir::rotate_wrench(T.linear(), wrench).isApprox(expected));

  ci::Vector6d diagonal;
  diagonal << 100, 200, 300, 10, 20, 30;
  const ci::Matrix6d K = cir::rotate_stiffness(T.linear(), diagonal);
  ci::Vector6d swapped;
  swapped << 200, 100, 300, 20, 10, 30;
  EXPECT_TRUE(K.diagonal().isApprox(swapped));
  EXPECT_NEAR((K - ci::Matrix6d(swapped.asDiagonal())).norm(), 0.0, 1e-9);
}

TEST(Conversions, Trajectory) {
  trajectory_msgs::JointTrajectory message;
  message.joint_names = {"b", "a"};
  message.points.resize(2);
  message.points[0].positions = {1, 2};
  message.points[0].time_from_start = ros::Duration(0.5);
  message.points[1].positions = {3, 4};
  message.points[1].time_from_start = ros::Duration(1.5);
  ci::JointTrajectory trajectory = cir::trajectory_from_message(message);
  EXPECT_EQ(trajectory.joint_names, message.joint_names);
  EXPECT_EQ(trajectory.times, (std::vector<double>{0.5, 1.5}));
  EXPECT_EQ(trajectory.positions[1], (std::vector<double>{3, 4}));
  EXPECT_TRUE(trajectory.velocities.empty());

  message.points[1].velocities = {0, 0};
  EXPECT_THROW(cir::trajectory_from_message(message), ci::Error);
  message.points[0].velocities = {0.1, 0.2};
  trajectory = cir::trajectory_from_message(message);
  EXPECT_EQ(trajectory.velocities[0], (std::vector<double>{0.1, 0.2}));
}

// ---- state message --------------------------------------------------------------------------

TEST(Conversions, StateMessageFromALoopStep) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  ci::JointVector q(7);
  q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  const ci::JointVector dq = ci::JointVector::Zero(7);
  loop.start(q, dq);
  ci::Vector6d stiffness;
  stiffness << 100, 200, 300, 10, 20, 30;
  loop.set_stiffness(stiffness, ci::Frame::end_effector);
  loop.step(q, dq, 0.001);

  cir::ControllerState message;
  cir::JointSample measured;
  measured.effort = ci::JointVector::Constant(7, 1.0);
  cir::fill_state_message(loop.state(), model.joint_names(), &measured, message);
  EXPECT_EQ(message.status, "ok");
  EXPECT_EQ(message.cycle, 1u);
  EXPECT_NEAR(message.current_pose.position.x, 0.3069, 1e-4);
  EXPECT_NEAR(message.current_pose.position.z, 0.5903, 1e-4);
  EXPECT_EQ(message.joint_state.name, model.joint_names());
  EXPECT_EQ(message.joint_state.position.size(), 7u);
  EXPECT_EQ(message.commanded_torques.size(), 7u);
  EXPECT_EQ(message.nullspace_config.size(), 7u);
  EXPECT_EQ(message.stiffness_frame, "end_effector");
  EXPECT_EQ(message.commanded_cartesian_stiffness.force.y, 200.0);
  EXPECT_EQ(message.commanded_cartesian_stiffness.torque.z, 30.0);
  // Damping in the stiffness frame: the diagonal of the D the law used.
  EXPECT_EQ(message.cartesian_damping.force.x, loop.state().controller.damping(0, 0));
  EXPECT_EQ(message.cartesian_damping.torque.z, loop.state().controller.damping(5, 5));
  ASSERT_EQ(message.external_torques.size(), 7u);
  EXPECT_NEAR(message.external_torques[0], 1.0 - message.commanded_torques[0], 1e-12);
  EXPECT_EQ(message.trajectory_state, "idle");

  cir::fill_state_message(loop.state(), model.joint_names(), nullptr, message);
  EXPECT_TRUE(message.external_torques.empty());
  EXPECT_TRUE(message.joint_state.effort.empty());
}

TEST(Conversions, TimingOfTheControlThread) {
  ci::runtime::ControlThreadStatistics statistics;
  statistics.cycles = 5000;
  statistics.overruns = 37;
  statistics.latest_lateness_us = 120.0;
  statistics.worst_lateness_us = 412.3;
  statistics.period_min_us = 880.0;
  statistics.period_p50_us = 1000.2;
  statistics.period_p99_us = 1130.0;
  statistics.period_max_us = 1520.0;
  statistics.stale_episodes = 2;
  statistics.realtime = true;
  statistics.measurement_age_p50_us = 1210.0;
  statistics.measurement_age_p99_us = 2450.5;
  statistics.measurement_age_max_us = 8100.0;
  cir::ControllerState message;
  cir::fill_timing(statistics, message);
  EXPECT_EQ(message.overruns, 37u);
  EXPECT_EQ(message.latest_lateness_us, 120.0);
  EXPECT_EQ(message.worst_lateness_us, 412.3);
  EXPECT_EQ(message.period_min_us, 880.0);
  EXPECT_EQ(message.period_p50_us, 1000.2);
  EXPECT_EQ(message.period_p99_us, 1130.0);
  EXPECT_EQ(message.period_max_us, 1520.0);
  EXPECT_EQ(message.stale_episodes, 2u);
  EXPECT_TRUE(message.realtime);
  EXPECT_EQ(message.measurement_age_p50_us, 1210.0);
  EXPECT_EQ(message.measurement_age_p99_us, 2450.5);
  EXPECT_EQ(message.measurement_age_max_us, 8100.0);

  EXPECT_EQ(ci::runtime::overrun_summary(statistics, 0.001, 5.004),
            "control cycle: 37 overruns of the 1 ms period in the last 5 s (worst 412 us late); "
            "period p50 1000 us, p99 1130 us, max 1520 us");
  statistics.overruns = 1;
  const std::string line = ci::runtime::overrun_summary(statistics, 0.002, 5.0);
  EXPECT_EQ(line.rfind("control cycle: 1 overrun of the 2 ms period in the last 5 s", 0), 0u)
      << line;
}

// ---- fuzz -----------------------------------------------------------------------------------
// Thousands of hostile messages through the conversions and into a running loop, as the node's
// callbacks pass them on: every one is either accepted or rejected with the library's Error,
// nothing else is thrown, and the cycle keeps producing finite torques within its bounds. Run
// under ASan + UBSan in CI.

namespace {

// Numbers a broken or hostile publisher could send.
double hostile_number(std::mt19937& rng) {
  static const double kSpecial[] = {0.0,
                                    -0.0,
                                    1.0,
                                    -1.0,
                                    0.5,
                                    1e-300,
                                    5e-324,
                                    1e154,
                                    1.5e154,
                                    1e300,
                                    -1e308,
                                    std::numeric_limits<double>::max(),
                                    std::numeric_limits<double>::infinity(),
                                    -std::numeric_limits<double>::infinity(),
                                    std::numeric_limits<double>::quiet_NaN()};
  std::uniform_int_distribution<int> pick(0, 8 * static_cast<int>(std::size(kSpecial)));
  const int k = pick(rng);
  if (k < static_cast<int>(std::size(kSpecial))) return kSpecial[k];
  return std::uniform_real_distribution<double>(-3.0, 3.0)(rng);
}

std::vector<double> hostile_array(std::mt19937& rng, int usual_size) {
  std::uniform_int_distribution<int> size(0, 7);
  const int choice = size(rng);
  const int n = choice == 0 ? 0 : choice == 1 ? usual_size + 1 : usual_size;
  std::vector<double> values(static_cast<std::size_t>(n));
  for (double& value : values) value = hostile_number(rng);
  return values;
}

}  // namespace

TEST(Fuzz, HostileMessagesAreAcceptedOrRejectedWithErrorAndTheCycleStaysSafe) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(kSource + "/models/panda/panda.urdf",
                                                              "panda_link0", "panda_link8");
  ci::ControlLoop loop(model, ci::load_parameters(kSource + "/config/panda.yaml"));
  const ci::JointVector ready =
      (ci::JointVector(7) << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4).finished();
  loop.start(ready, ci::JointVector::Zero(7));
  const ci::node::JointStateMapper mapper(model.joint_names());
  std::mt19937 rng(20261123);
  int accepted = 0, rejected = 0;
  const int kMessages = 4000;
  for (int k = 0; k < kMessages; ++k) {
    try {
      switch (k % 6) {
        case 0: {
          geometry_msgs::Pose pose;
          pose.position.x = hostile_number(rng);
          pose.position.y = hostile_number(rng);
          pose.position.z = hostile_number(rng);
          pose.orientation.x = hostile_number(rng);
          pose.orientation.y = hostile_number(rng);
          pose.orientation.z = hostile_number(rng);
          pose.orientation.w = hostile_number(rng);
          geometry_msgs::Transform transform;
          transform.translation.x = hostile_number(rng);
          transform.rotation.w = hostile_number(rng);
          transform.rotation.z = hostile_number(rng);
          const ci::Pose in_frame = cir::pose_from_message(pose);
          loop.set_reference_pose(
              k % 12 == 0 ? cir::transform_pose(cir::isometry_from_transform(transform), in_frame)
                          : in_frame);
          break;
        }
        case 1: {
          geometry_msgs::Wrench wrench;
          wrench.force.x = hostile_number(rng);
          wrench.force.y = hostile_number(rng);
          wrench.force.z = hostile_number(rng);
          wrench.torque.x = hostile_number(rng);
          wrench.torque.y = hostile_number(rng);
          wrench.torque.z = hostile_number(rng);
          const ci::Vector6d values = cir::vector_from_wrench(wrench);
          switch (k % 4) {
            case 0:
              loop.set_wrench(values);
              break;
            case 1:
              loop.set_stiffness(values.cwiseAbs());
              break;
            case 2: {
              const Eigen::Matrix3d rotation =
                  Eigen::AngleAxisd(hostile_number(rng), Eigen::Vector3d::UnitZ()).matrix();
              loop.set_stiffness_matrix(cir::rotate_stiffness(rotation, values.cwiseAbs()));
              break;
            }
            default:
              loop.set_damping_ratio(values.cwiseAbs());
          }
          break;
        }
        case 2: {
          sensor_msgs::JointState message;
          message.name = model.joint_names();
          if (k % 5 == 0) std::swap(message.name[1], message.name[4]);
          if (k % 7 == 0) message.name.pop_back();
          message.position = hostile_array(rng, 7);
          message.velocity = hostile_array(rng, 7);
          message.effort = hostile_array(rng, 7);
          cir::JointSample sample;
          sample.q = ready;
          sample.dq = ci::JointVector::Zero(7);
          if (mapper.map(cir::joint_state_view(message), sample)) {
            // As the node's control thread: the sample goes to the cycle as it is.
            loop.step(sample.q, sample.dq, 0.001);
          }
          break;
        }
        case 3: {
          trajectory_msgs::JointTrajectory message;
          message.joint_names = model.joint_names();
          if (k % 9 == 0) message.joint_names[2] = "elbow";
          const int points = std::uniform_int_distribution<int>(0, 4)(rng);
          double time = 0.0;
          for (int p = 0; p < points; ++p) {
            trajectory_msgs::JointTrajectoryPoint point;
            for (int j = 0; j < 7; ++j) {
              point.positions.push_back(k % 3 == 0 ? hostile_number(rng)
                                                   : ready[j] + 0.01 * hostile_number(rng));
            }
            if (k % 2 == 0) point.velocities = hostile_array(rng, 7);
            time += k % 4 == 0 ? hostile_number(rng) : 0.2;
            point.time_from_start =
                ros::Duration(std::isfinite(time) && std::abs(time) < 1e6 ? time : 0.1);
            message.points.push_back(point);
          }
          loop.execute_trajectory(cir::trajectory_from_message(message));
          break;
        }
        case 4: {
          const std::vector<double> target = hostile_array(rng, 7);
          loop.set_nullspace_target(Eigen::Map<const Eigen::VectorXd>(
              target.data(), static_cast<Eigen::Index>(target.size())));
          break;
        }
        default: {
          const std::vector<double> stiffness = hostile_array(rng, 7);
          loop.set_nullspace_stiffness(Eigen::Map<const Eigen::VectorXd>(
              stiffness.data(), static_cast<Eigen::Index>(stiffness.size())));
        }
      }
      ++accepted;
    } catch (const ci::Error&) {
      ++rejected;
    }
    // The robot holds still here; whatever was accepted, the cycle stays finite and bounded.
    const ci::JointVector& tau = loop.step(ready, ci::JointVector::Zero(7), 0.001);
    ASSERT_TRUE(tau.allFinite()) << "message " << k;
    ASSERT_TRUE(
        (tau.cwiseAbs().array() <= loop.state().controller.joint_torque_limit.array() + 1e-12)
            .all())
        << "message " << k;
  }
  std::printf("ros conversions fuzz: %d messages, %d accepted, %d rejected\n", kMessages, accepted,
              rejected);
  RecordProperty("accepted", accepted);
  RecordProperty("rejected", rejected);
  EXPECT_GT(accepted, kMessages / 10);
  EXPECT_GT(rejected, kMessages / 10);
}
