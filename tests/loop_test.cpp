// The control loop: lock-free hand-off, trajectory validation and sampling, trajectory execution
// in closed loop, the model-based options, teaching, several loops side by side.

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <random>
#include <thread>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "support/model_simulation.hpp"
#include "support/robots.hpp"

namespace ci = cartesian_impedance;

namespace {

using robots::iiwa;
using robots::iiwa_ready;
using robots::panda;
using robots::panda_ready;

// Closed loop of a ControlLoop and the model simulation for `seconds`.
void run(ci::ControlLoop& loop, model_simulation::Simulation& sim, double seconds,
         double dt = 0.001) {
  const int steps = static_cast<int>(std::lround(seconds / dt));
  for (int k = 0; k < steps; ++k) sim.step(loop.step(sim.q, sim.dq, dt), dt);
}

ci::JointTrajectory trajectory_to(const ci::RobotModel& model, const ci::JointVector& from,
                                  const ci::JointVector& to, double duration, int points) {
  ci::JointTrajectory trajectory;
  trajectory.joint_names = model.joint_names();
  for (int k = 1; k <= points; ++k) {
    const double s = static_cast<double>(k) / points;
    // Smooth in time (zero velocity at both ends) so the sampled path is gentle.
    const double blend = 0.5 - 0.5 * std::cos(M_PI * s);
    const ci::JointVector q = from + blend * (to - from);
    trajectory.times.push_back(duration * s);
    trajectory.positions.emplace_back(q.data(), q.data() + q.size());
  }
  return trajectory;
}

}  // namespace

// ---- mailbox
// -------------------------------------------------------------------------------------

TEST(CommandQueue, FifoAndFullWithoutBlocking) {
  ci::CommandQueue<int> queue(3);
  EXPECT_EQ(queue.capacity(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(queue.push(i));
  EXPECT_FALSE(queue.push(99));
  int value = -1;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(queue.pop(value));
    EXPECT_EQ(value, i);
  }
  EXPECT_FALSE(queue.pop(value));
  EXPECT_TRUE(queue.push(5));  // the slots are reused
  ASSERT_TRUE(queue.pop(value));
  EXPECT_EQ(value, 5);
}

// Four writers, one reader: every value arrives exactly once and each writer's values in order.
TEST(CommandQueue, ManyWritersOneReaderLoseNothing) {
  ci::CommandQueue<std::pair<int, int>> queue(16);
  constexpr int kWriters = 4, kEach = 20000;
  std::vector<std::thread> writers;
  for (int w = 0; w < kWriters; ++w) {
    writers.emplace_back([&queue, w] {
      for (int i = 0; i < kEach;) {
        if (queue.push({w, i})) {
          ++i;
        } else {
          std::this_thread::yield();  // full: let the reader run (there may be fewer cores)
        }
      }
    });
  }
  std::vector<int> next(kWriters, 0);
  int received = 0;
  std::pair<int, int> value;
  while (received < kWriters * kEach) {
    if (!queue.pop(value)) {
      std::this_thread::yield();
      continue;
    }
    ASSERT_EQ(value.second, next[static_cast<std::size_t>(value.first)]++);
    ++received;
  }
  for (auto& writer : writers) writer.join();
  EXPECT_FALSE(queue.pop(value));
}

// A snapshot is never torn: each is an array of one repeated number.
TEST(SnapshotBuffer, ReadersNeverSeeTornSnapshots) {
  using Snapshot = std::array<long, 64>;
  Snapshot initial;
  initial.fill(0);
  ci::SnapshotBuffer<Snapshot, 4> buffer(initial);
  std::atomic<bool> done{false};
  std::vector<std::thread> readers;
  std::atomic<long> torn{0}, reads{0};
  for (int r = 0; r < 2; ++r) {
    readers.emplace_back([&] {
      Snapshot snapshot;
      long last = 0;
      while (!done.load()) {
        buffer.read(snapshot);
        for (long value : snapshot) torn += value != snapshot[0];
        torn += snapshot[0] < last;  // newer, never older
        last = snapshot[0];
        ++reads;
      }
    });
  }
  Snapshot snapshot;
  // On a loaded machine the readers may not run before 200,000 publishes are done: the writer
  // goes on until they have read while it writes.
  long i = 0;
  while (i < 200000 || reads.load() < 1000) {
    snapshot.fill(++i);
    buffer.publish(snapshot);
  }
  done = true;
  for (auto& reader : readers) reader.join();
  EXPECT_EQ(torn.load(), 0);
  EXPECT_EQ(buffer.read()[0], i);
}

// ---- trajectory buffer
// ---------------------------------------------------------------------------

TEST(TrajectoryBuffer, RejectsBadTrajectoriesNamingTheProblem) {
  const std::vector<std::string> names = {"a", "b"};
  const ci::JointVector lower = (ci::JointVector(2) << -1, -1).finished();
  const ci::JointVector upper = (ci::JointVector(2) << 1, 1).finished();
  ci::TrajectoryBuffer buffer(2, 3);
  auto rejects = [&](const ci::JointTrajectory& t, const std::string& part) {
    try {
      buffer.assign(t, names, lower, upper);
    } catch (const ci::Error& e) {
      return std::string(e.what()).find(part) != std::string::npos
                 ? ::testing::AssertionSuccess()
                 : ::testing::AssertionFailure() << "message: " << e.what();
    }
    return ::testing::AssertionFailure() << "accepted";
  };
  ci::JointTrajectory good{{"b", "a"}, {0.5, 1.0}, {{0.1, 0.2}, {0.3, 0.4}}, {}};
  EXPECT_NO_THROW(buffer.assign(good, names, lower, upper));
  ci::JointTrajectory t = good;
  t.joint_names = {"b", "c"};
  EXPECT_TRUE(rejects(t, "lacks joint 'a'"));
  t.joint_names = {"b", "a", "c"};
  EXPECT_TRUE(rejects(t, "unknown joint 'c'"));
  t.joint_names = {"a", "a"};
  EXPECT_TRUE(rejects(t, "names joint 'a' twice"));
  t = good;
  t.times = {1.0, 0.5};
  EXPECT_TRUE(rejects(t, "point 1: time 0.5 s must be finite and greater than 1"));
  t.times = {0.5, NAN};
  EXPECT_TRUE(rejects(t, "time nan"));
  t = good;
  t.positions[1] = {0.3, 1.5};
  EXPECT_TRUE(rejects(t, "joint 'a': position 1.5 is outside its limits [-1, 1]"));
  t.positions[1] = {0.3};
  EXPECT_TRUE(rejects(t, "point 1 has 1 positions; expected 2"));
  t = good;
  t.velocities = {{0, 0}};
  EXPECT_TRUE(rejects(t, "give all or none"));
  t.velocities = {{0, 0}, {INFINITY, 0}};
  EXPECT_TRUE(rejects(t, "velocity inf"));
  t = good;
  t.times = {0.5, 1, 1.5, 2};
  t.positions = {{0, 0}, {0, 0}, {0, 0}, {0, 0}};
  EXPECT_TRUE(rejects(t, "at most 3"));
  t.times = {0.0};
  t.positions = {{0, 0}};
  EXPECT_TRUE(rejects(t, "no point after time 0"));
}

// Cubic Hermite: passes through every waypoint at its time with its velocity; position and
// velocity are continuous at the knots (difference over +-1e-9 s below 1e-6 of the scale).
TEST(TrajectoryBuffer, InterpolatesThroughWaypointsWithContinuousVelocity) {
  const std::vector<std::string> names = {"a", "b"};
  const ci::JointVector lower = ci::JointVector::Constant(2, -5), upper = -lower;
  ci::TrajectoryBuffer buffer(2, 10);
  ci::JointTrajectory t{{"a", "b"},
                        {0.0, 0.4, 1.0, 1.3},
                        {{9, 9}, {0.5, -0.2}, {1.0, 0.3}, {0.2, 0.3}},
                        {{9, 9}, {1.0, 0.0}, {0.5, 0.5}, {0.0, 0.0}}};
  buffer.assign(t, names, lower, upper);
  const ci::JointVector start = (ci::JointVector(2) << 0.1, 0.1).finished();
  buffer.begin(start, ci::JointVector::Zero(2));
  EXPECT_EQ(buffer.num_points(), 4);  // the point at time 0 became the start state
  ci::JointVector q(2), dq(2), q_after(2), dq_after(2);
  buffer.sample(0.0, q, dq);
  EXPECT_EQ(q, start);
  for (std::size_t k = 1; k < t.times.size(); ++k) {
    buffer.sample(t.times[k], q, dq);
    EXPECT_NEAR(q[0], t.positions[k][0], 1e-12);
    EXPECT_NEAR(q[1], t.positions[k][1], 1e-12);
    if (k + 1 < t.times.size()) {
      EXPECT_NEAR(dq[0], t.velocities[k][0], 1e-12);
      buffer.sample(t.times[k] - 1e-9, q, dq);
      buffer.sample(t.times[k] + 1e-9, q_after, dq_after);
      EXPECT_LE((q_after - q).cwiseAbs().maxCoeff(), 1e-8);
      EXPECT_LE((dq_after - dq).cwiseAbs().maxCoeff(), 1e-6);
    }
  }
  buffer.sample(5.0, q, dq);
  EXPECT_NEAR(q[0], 0.2, 1e-12);
  EXPECT_EQ(dq, ci::JointVector::Zero(2));
}

// Without velocities the path is shape-preserving: it never overshoots a waypoint, so it stays
// within the limits the waypoints were checked against.
TEST(TrajectoryBuffer, DerivedVelocitiesDoNotOvershoot) {
  const std::vector<std::string> names = {"a"};
  const ci::JointVector lower = ci::JointVector::Constant(1, -1), upper = -lower;
  ci::TrajectoryBuffer buffer(1, 10);
  ci::JointTrajectory t{{"a"}, {0.1, 0.2, 0.3, 1.0}, {{1.0}, {1.0}, {-1.0}, {-1.0}}, {}};
  buffer.assign(t, names, lower, upper);
  buffer.begin(ci::JointVector::Constant(1, 0.0), ci::JointVector::Zero(1));
  ci::JointVector q(1), dq(1);
  for (double time = 0.0; time <= 1.0; time += 1e-4) {
    buffer.sample(time, q, dq);
    ASSERT_LE(std::abs(q[0]), 1.0 + 1e-12) << "t = " << time;
  }
}

// The path between the waypoints keeps the limits too. A velocity above the joint's limit is
// refused where it is given; positions that need more than it (2.5 rad in 0.3 s: the cubic with
// zero end velocities peaks at 1.5 x 2.5 / 0.3 = 12.5 rad/s) are refused naming the segment and
// the speed; a via velocity that makes the cubic overshoot the position limits is refused even
// without a speed limit.
TEST(TrajectoryBuffer, ThePathBetweenWaypointsKeepsPositionAndSpeedLimits) {
  const std::vector<std::string> names = {"a"};
  const ci::TrajectoryLimits limits{ci::JointVector::Constant(1, -2.9),
                                    ci::JointVector::Constant(1, 2.9),
                                    ci::JointVector::Constant(1, 2.175)};
  ci::TrajectoryBuffer buffer(1, 10);
  auto message = [&](const ci::JointTrajectory& t, const ci::TrajectoryLimits& l,
                     const ci::TrajectoryStartState* start = nullptr) -> std::string {
    try {
      buffer.assign(t, names, l, start);
    } catch (const ci::Error& e) {
      return e.what();
    }
    return "accepted";
  };
  ci::JointTrajectory t{{"a"}, {1.0, 2.0, 3.0}, {{0.0}, {0.5}, {1.0}}, {{0.0}, {1000.0}, {0.0}}};
  EXPECT_EQ(
      message(t, limits),
      "trajectory point 1, joint 'a': velocity 1000 is beyond its velocity limit 2.175 (URDF)");
  // Without a speed limit the same velocity would swing the path 160 rad past the limits.
  ci::TrajectoryLimits unlimited = limits;
  unlimited.velocity.setConstant(INFINITY);
  EXPECT_NE(message(t, unlimited)
                .find("segment from point 0 to point 1, joint 'a': the "
                      "interpolated position reaches"),
            std::string::npos)
      << message(t, unlimited);
  t.velocities.clear();
  t.times = {1.0, 1.3};
  t.positions = {{0.0}, {2.5}};
  const std::string fast = message(t, limits);
  EXPECT_NE(fast.find("segment from point 0 to point 1, joint 'a': the interpolated speed "
                      "reaches 12.5, beyond its velocity limit 2.175"),
            std::string::npos)
      << fast;
  t.times = {1.0, 3.0};  // 1.5 x 2.5 / 2 = 1.875 rad/s
  EXPECT_EQ(message(t, limits), "accepted");
  // The first segment runs from the start state, when it is known.
  const ci::TrajectoryStartState start{ci::JointVector::Constant(1, -2.0),
                                       ci::JointVector::Zero(1)};
  t.times = {1.0};
  t.positions = {{2.0}};  // 4 rad in 1 s from the start: 6 rad/s at its peak
  EXPECT_EQ(message(t, limits), "accepted");
  EXPECT_NE(message(t, limits, &start).find("segment from the start state to point 0"),
            std::string::npos)
      << message(t, limits, &start);
}

// The extremes found on each cubic are those of the path sample() produces: seeded random
// segments with random end velocities are accepted with limits 0.1 % above the sampled peak
// speed and excursion, and refused with limits 1 % below either.
TEST(TrajectoryBuffer, SegmentExtremesAreThoseOfTheSampledPath) {
  std::mt19937 rng(32);
  std::uniform_real_distribution<double> position(-1.0, 1.0), velocity(-3.0, 3.0),
      duration(0.05, 2.0);
  const std::vector<std::string> names = {"a"};
  ci::TrajectoryBuffer buffer(1, 4);
  for (int trial = 0; trial < 200; ++trial) {
    const double h = duration(rng);
    ci::JointTrajectory t{{"a"},
                          {0.5, 0.5 + h},
                          {{position(rng)}, {position(rng)}},
                          {{velocity(rng)}, {velocity(rng)}}};
    const ci::TrajectoryLimits wide{ci::JointVector::Constant(1, -1e6),
                                    ci::JointVector::Constant(1, 1e6),
                                    ci::JointVector::Constant(1, 1e6)};
    buffer.assign(t, names, wide);
    buffer.begin(ci::JointVector::Zero(1), ci::JointVector::Zero(1));
    double speed = 0.0, lowest = INFINITY, highest = -INFINITY;
    ci::JointVector q(1), dq(1);
    for (int i = 0; i <= 20000; ++i) {
      buffer.sample(0.5 + h * i / 20000.0, q, dq);
      speed = std::max(speed, std::abs(dq[0]));
      lowest = std::min(lowest, q[0]);
      highest = std::max(highest, q[0]);
    }
    const double reach = std::max(std::abs(lowest), std::abs(highest));
    auto limits = [&](double speed_limit, double position_limit) {
      return ci::TrajectoryLimits{ci::JointVector::Constant(1, -position_limit),
                                  ci::JointVector::Constant(1, position_limit),
                                  ci::JointVector::Constant(1, speed_limit)};
    };
    SCOPED_TRACE("trial " + std::to_string(trial));
    EXPECT_NO_THROW(buffer.assign(t, names, limits(1.001 * speed, 1.001 * reach)));
    EXPECT_THROW(buffer.assign(t, names, limits(0.99 * speed, 1.001 * reach)), ci::Error);
    EXPECT_THROW(buffer.assign(t, names, limits(1.001 * speed, 0.99 * reach)), ci::Error);
  }
}

// ---- the loop
// ------------------------------------------------------------------------------------

TEST(ControlLoop, HoldsStillWhereItStarts) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  model_simulation::Simulation sim(model, panda_ready());
  loop.start(sim.q, sim.dq);
  const ci::Pose start = sim.pose();
  run(loop, sim, 1.0);
  EXPECT_LE((sim.pose().position - start.position).norm(), 1e-6);
  EXPECT_EQ(loop.state().controller.status, ci::Status::ok);
  EXPECT_EQ(loop.state().cycle, 1000u);
}

TEST(ControlLoop, CommandsApplyAtTheNextStepAndBadOnesAreRejectedBySender) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  model_simulation::Simulation sim(model, panda_ready());
  loop.start(sim.q, sim.dq);
  loop.set_stiffness((ci::Vector6d() << 100, 200, 300, 10, 20, 30).finished());
  EXPECT_EQ(loop.controller().state().commanded.stiffness(0, 0), 500.0);  // not yet applied
  loop.step(sim.q, sim.dq, 0.001);
  EXPECT_EQ(loop.controller().state().commanded.stiffness(0, 0), 100.0);
  EXPECT_THROW(loop.set_stiffness(ci::Vector6d::Constant(-1)), ci::Error);
  EXPECT_THROW(loop.set_nullspace_target(Eigen::VectorXd::Zero(6)), ci::Error);
  EXPECT_THROW(loop.send(ci::NullspaceTarget{Eigen::VectorXd::Zero(6)}), ci::Error);
  const std::uint64_t applied = loop.state().commands_applied;
  loop.step(sim.q, sim.dq, 0.001);
  EXPECT_EQ(loop.state().commands_applied, applied);
  EXPECT_EQ(loop.latest_parameters().stiffness.translation.x(), 100.0);
}

TEST(ControlLoop, FullInboxThrowsInsteadOfBlocking) {
  ci::ControlLoop loop(panda(), {}, ci::LoopCapacity{4, 10});
  for (int i = 0; i < 4; ++i) loop.set_nullspace_damping_ratio(1.0);
  try {
    loop.set_nullspace_damping_ratio(1.0);
    FAIL() << "a full inbox must be reported";
  } catch (const ci::Error& e) {
    EXPECT_NE(std::string(e.what()).find("inbox is full"), std::string::npos) << e.what();
  }
}

// One thread steps as fast as it can while another sends reference poses continuously and a third
// reads the published state. Each sent pose encodes its sequence number in both position and
// orientation, so a torn or invented command would show as a mismatch; every pose the controller
// uses must be one that was sent, and they must arrive in order. Run under ThreadSanitizer in CI.
TEST(ControlLoop, ConcurrentCommandsAreAppliedWholeAndInOrder) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  model_simulation::Simulation sim(model, panda_ready());
  loop.start(sim.q, sim.dq);
  const ci::Pose home = sim.pose();
  auto pose_for = [&home](int id) {
    const double angle = 1e-4 * id;
    return ci::Pose{
        home.position + Eigen::Vector3d(1e-6 * id, 0, 0),
        Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ())) * home.orientation};
  };
  auto id_of = [&home](const ci::Pose& pose, bool& consistent) {
    const double from_position = (pose.position.x() - home.position.x()) / 1e-6;
    const double angle = 2 * std::atan2((pose.orientation * home.orientation.conjugate()).z(),
                                        (pose.orientation * home.orientation.conjugate()).w());
    consistent = std::abs(from_position - angle / 1e-4) < 1e-3 &&
                 std::abs(from_position - std::round(from_position)) < 1e-3;
    return static_cast<int>(std::lround(from_position));
  };
  constexpr int kCommands = 3000;
  std::atomic<bool> stepping{true};
  // Raised before each send: the stepping thread may apply a pose before its send returns.
  std::atomic<int> sent{0};
  std::thread sender([&] {
    for (int id = 1; id <= kCommands; ++id) {
      sent = id;
      for (;;) {
        try {
          loop.set_reference_pose(pose_for(id));
          break;
        } catch (const ci::Error&) {
          std::this_thread::yield();  // inbox full: the stepping thread will drain it
        }
      }
    }
  });
  std::atomic<int> reader_bad{0};
  std::thread reader([&] {
    while (stepping.load()) {
      const ci::LoopState state = loop.latest_state();
      bool consistent = true;
      if (state.cycle > 0) id_of(state.controller.commanded.pose, consistent);
      reader_bad += !consistent;
    }
  });
  int last_id = 0, bad = 0, cycles = 0;
  while (last_id < kCommands) {
    loop.step(sim.q, sim.dq, 0.001);
    ++cycles;
    bool consistent = true;
    const int id = id_of(loop.state().controller.commanded.pose, consistent);
    bad += !consistent || id < last_id || id > sent.load();
    last_id = id;
  }
  stepping = false;
  sender.join();
  reader.join();
  EXPECT_EQ(bad, 0);
  EXPECT_EQ(reader_bad.load(), 0);
  EXPECT_EQ(last_id, kCommands);
  EXPECT_GE(loop.state().commands_applied, static_cast<std::uint64_t>(kCommands));
  RecordProperty("cycles", cycles);
}

// ---- trajectories in closed loop ---------------------------------------------------------------

TEST(ControlLoop, TrajectoryIsTrackedAndFinishesOnlyAfterArrival) {
  const ci::RobotModel model = panda();
  ci::Parameters parameters;
  parameters.stiffness.translation.setConstant(1500.0);
  parameters.stiffness.rotation.setConstant(150.0);
  parameters.nullspace.stiffness = ci::JointVector::Constant(1, 20.0);
  ci::ControlLoop loop(model, parameters);
  model_simulation::Simulation sim(model, panda_ready());
  loop.start(sim.q, sim.dq);
  const ci::JointVector goal =
      panda_ready() + (ci::JointVector(7) << 0.3, 0.2, -0.2, 0.3, 0.2, -0.2, 0.3).finished();
  const std::uint64_t id = loop.execute_trajectory(trajectory_to(model, sim.q, goal, 2.0, 20));
  double worst_tracking = 0.0;
  bool finished_early = false;
  for (int k = 0; k < 4000; ++k) {
    sim.step(loop.step(sim.q, sim.dq, 0.001), 0.001);
    const ci::LoopState& state = loop.state();
    if (state.trajectory.state == ci::TrajectoryState::finished) {
      finished_early |= (sim.q - goal).cwiseAbs().maxCoeff() > 0.01;
    }
    if (state.trajectory.state == ci::TrajectoryState::executing && state.trajectory.time < 2.0) {
      worst_tracking = std::max(worst_tracking, state.controller.pose_error.head<3>().norm());
    }
  }
  const ci::LoopState& state = loop.state();
  EXPECT_EQ(state.trajectory.id, id);
  EXPECT_EQ(state.trajectory.state, ci::TrajectoryState::finished);
  EXPECT_FALSE(finished_early);
  EXPECT_LE((sim.q - goal).cwiseAbs().maxCoeff(), 0.01);
  // With velocity feed-forward the Cartesian error stays small while moving (centimetre level at
  // 1500 N/m against the arm's own inertia).
  EXPECT_LT(worst_tracking, 0.03);
  RecordProperty("worst_tracking_error_m", std::to_string(worst_tracking));
}

TEST(ControlLoop, BlockedArmAbortsAfterGoalTimeTolerance) {
  const ci::RobotModel model = panda();
  ci::Parameters parameters;
  parameters.trajectory.goal_time_tolerance = 0.5;
  ci::ControlLoop loop(model, parameters);
  model_simulation::Simulation sim(model, panda_ready());
  sim.blocked_joint = 0;  // an obstacle stops joint 1
  loop.start(sim.q, sim.dq);
  const ci::JointVector goal =
      panda_ready() + (ci::JointVector(7) << 0.4, 0, 0, 0, 0, 0, 0).finished();
  loop.execute_trajectory(trajectory_to(model, sim.q, goal, 1.0, 5));
  run(loop, sim, 1.4);
  EXPECT_EQ(loop.state().trajectory.state, ci::TrajectoryState::executing);
  run(loop, sim, 0.2);
  EXPECT_EQ(loop.state().trajectory.state, ci::TrajectoryState::aborted);
  EXPECT_GT(loop.state().trajectory.goal_error, 0.3);
}

// A new trajectory continues from where the running one is: the reference pose moves by no more
// than the reference speed times dt across the switch.
TEST(ControlLoop, NewTrajectoryPreemptsWithoutJumpAndCancelHolds) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  model_simulation::Simulation sim(model, panda_ready());
  loop.start(sim.q, sim.dq);
  const ci::JointVector first_goal = panda_ready() + ci::JointVector::Constant(7, 0.3);
  loop.execute_trajectory(trajectory_to(model, sim.q, first_goal, 2.0, 10));
  run(loop, sim, 1.0);
  const Eigen::Vector3d before = loop.state().controller.filtered.pose.position;
  const ci::JointVector second_goal = panda_ready() - ci::JointVector::Constant(7, 0.2);
  const std::uint64_t second =
      loop.execute_trajectory(trajectory_to(model, first_goal, second_goal, 2.0, 10));
  sim.step(loop.step(sim.q, sim.dq, 0.001), 0.001);
  const Eigen::Vector3d after = loop.state().controller.filtered.pose.position;
  EXPECT_EQ(loop.state().trajectory.id, second);
  // The first trajectory moves the flange at well under 1 m/s: under 1 mm per ms.
  EXPECT_LT((after - before).norm(), 1e-3);

  run(loop, sim, 0.5);
  loop.cancel_trajectory();
  sim.step(loop.step(sim.q, sim.dq, 0.001), 0.001);
  EXPECT_EQ(loop.state().trajectory.state, ci::TrajectoryState::cancelled);
  const ci::Pose cancelled_at = sim.pose();
  run(loop, sim, 2.5);
  const ci::Pose held = sim.pose();
  run(loop, sim, 1.0);
  // It stops near where it was cancelled (the spring catches the motion it had) and then holds.
  EXPECT_LT((held.position - cancelled_at.position).norm(), 0.02);
  EXPECT_LT((sim.pose().position - held.position).norm(), 2e-4);
}

TEST(ControlLoop, TrajectoryOutsideLimitsIsRejectedAtTheSender) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  ci::JointVector beyond = panda_ready();
  beyond[3] = 0.5;  // joint 4 must stay below -0.0698 rad
  try {
    loop.execute_trajectory(trajectory_to(model, panda_ready(), beyond, 1.0, 1));
    FAIL() << "accepted";
  } catch (const ci::Error& e) {
    EXPECT_NE(std::string(e.what()).find("panda_joint4"), std::string::npos) << e.what();
  }
}

// The Panda's URDF gives joint 2 a velocity limit of 2.175 rad/s. A via point at 1000 rad/s, or
// positions that need more (2.5 rad in 0.3 s from where the arm is), are refused at the sender
// naming the joint and the limit, and nothing starts.
TEST(ControlLoop, TrajectoryFasterThanTheUrdfAllowsIsRejectedAtTheSender) {
  const ci::RobotModel model = panda();
  ASSERT_DOUBLE_EQ(model.limits().velocity[1], 2.175);
  ci::ControlLoop loop(model);
  model_simulation::Simulation sim(model, panda_ready());
  loop.start(sim.q, sim.dq);
  run(loop, sim, 0.01);
  ci::JointTrajectory via = trajectory_to(model, sim.q, panda_ready(), 2.0, 2);
  via.velocities.assign(via.positions.size(), std::vector<double>(7, 0.0));
  via.velocities[0][1] = 1000.0;
  auto rejected = [&](const ci::JointTrajectory& trajectory) -> std::string {
    try {
      loop.execute_trajectory(trajectory);
    } catch (const ci::Error& e) {
      return e.what();
    }
    return "accepted";
  };
  const std::string via_message = rejected(via);
  EXPECT_NE(via_message.find("joint 'panda_joint2': velocity 1000 is beyond its velocity limit "
                             "2.175"),
            std::string::npos)
      << via_message;
  ci::JointVector far = panda_ready();
  far[1] += 1.25;  // joint 2's range is [-1.7628, 1.7628]; the ready pose is at -0.785
  const std::string fast_message = rejected(trajectory_to(model, sim.q, far, 0.3, 1));
  EXPECT_NE(fast_message.find("segment from the start state to point 0, joint 'panda_joint2': "
                              "the interpolated speed reaches"),
            std::string::npos)
      << fast_message;
  EXPECT_EQ(rejected(trajectory_to(model, sim.q, far, 2.0, 1)), "accepted");
  run(loop, sim, 0.01);
  EXPECT_EQ(loop.state().trajectory.state, ci::TrajectoryState::executing);
}

// ---- model-based options
// -------------------------------------------------------------------------

// A robot without firmware gravity compensation holds its pose only if the loop adds g(q); the
// start torque is g(q) so nothing drops on the first cycle.
TEST(ControlLoop, GravityCompensationHoldsARobotWithoutFirmwareCompensation) {
  const ci::RobotModel model = panda();
  ci::Parameters parameters;
  parameters.dynamics.gravity_compensation = true;
  ci::ControlLoop loop(model, parameters);
  model_simulation::Simulation sim(model, panda_ready(), /*firmware_gravity=*/false);
  loop.start(sim.q, sim.dq);
  const ci::Pose start = sim.pose();
  run(loop, sim, 2.0);
  EXPECT_LT((sim.pose().position - start.position).norm(), 1e-4);
  EXPECT_GT(loop.state().controller.tau_gravity.norm(), 10.0);

  ci::Parameters off = parameters;
  off.dynamics.gravity_compensation = false;
  ci::ControlLoop without(model, off);
  model_simulation::Simulation falling(model, panda_ready(), false);
  without.start(falling.q, falling.dq);
  run(without, falling, 2.0);
  // 500 N/m against roughly 30 N of weight moment at the flange: several centimetres of sag.
  EXPECT_GT((falling.pose().position - start.position).norm(), 0.01);
}

// Dynamic options run and converge; the dynamically consistent projector leaves the end effector
// where the Cartesian spring holds it while the elbow moves.
TEST(ControlLoop, DynamicOptionsKeepTheEndEffectorWhileTheNullspaceMoves) {
  const ci::RobotModel model = panda();
  for (bool dynamic : {false, true}) {
    ci::Parameters parameters;
    parameters.dynamics.dynamically_consistent_nullspace = dynamic;
    parameters.dynamics.inertia_shaped_damping = dynamic;
    parameters.stiffness.translation.setConstant(2000);
    parameters.stiffness.rotation.setConstant(200);
    parameters.nullspace.stiffness = ci::JointVector::Constant(1, 10.0);
    parameters.nullspace.pseudo_inverse_damping = 0.0;
    ci::ControlLoop loop(model, parameters);
    model_simulation::Simulation sim(model, panda_ready());
    loop.start(sim.q, sim.dq);
    const ci::Pose start = sim.pose();
    ci::JointVector target = panda_ready();
    target[0] += 0.4;
    target[2] -= 0.4;
    loop.set_nullspace_target(target);
    double worst = 0.0;
    for (int k = 0; k < 3000; ++k) {
      sim.step(loop.step(sim.q, sim.dq, 0.001), 0.001);
      worst = std::max(worst, (sim.pose().position - start.position).norm());
    }
    EXPECT_EQ(loop.state().controller.status, ci::Status::ok) << "dynamic " << dynamic;
    EXPECT_LT(worst, 0.002) << "dynamic " << dynamic;
    EXPECT_GT(std::abs(sim.q[0] - panda_ready()[0]), 0.05) << "the elbow should move";
  }
}

// The loop asks the model only for the terms its options use, on whichever backend the model
// names: every combination of options (with armature) commands the same torques on KDL as on the
// native backend, step after step along a moving measurement.
TEST(ControlLoop, EveryDynamicsOptionGivesTheSameTorquesOnBothBackends) {
  const ci::RobotModel native = iiwa();
  const ci::RobotModel kdl = native.with_backend(ci::ModelBackend::kdl);
  for (int options = 0; options < 8; ++options) {
    ci::Parameters parameters;
    parameters.dynamics.gravity_compensation = (options & 1) != 0;
    parameters.dynamics.inertia_shaped_damping = (options & 2) != 0;
    parameters.dynamics.dynamically_consistent_nullspace = (options & 4) != 0;
    parameters.dynamics.armature = ci::JointVector::Constant(1, 0.1);
    ci::ControlLoop a(native, parameters), b(kdl, parameters);
    EXPECT_EQ(b.model().backend(), ci::ModelBackend::kdl);
    ci::JointVector q = iiwa_ready(), dq = ci::JointVector::Constant(7, 0.05);
    a.start(q, dq);
    b.start(q, dq);
    ci::Pose target = a.state().controller.pose;
    target.position.x() += 0.03;
    a.set_reference_pose(target);
    b.set_reference_pose(target);
    double worst = 0.0;
    for (int k = 0; k < 200; ++k) {
      q += 0.001 * dq;
      const ci::JointVector tau_a = a.step(q, dq, 0.001);
      const ci::JointVector tau_b = b.step(q, dq, 0.001);
      worst = std::max(worst, (tau_a - tau_b).cwiseAbs().maxCoeff());
    }
    EXPECT_EQ(a.state().controller.status, ci::Status::ok) << "options " << options;
    EXPECT_EQ(b.state().controller.status, ci::Status::ok) << "options " << options;
    EXPECT_GT(a.state().controller.tau.norm(), 0.1) << "options " << options;
    EXPECT_LT(worst, 1e-9) << "options " << options;
  }
}

TEST(ControlLoop, JointLimitAvoidancePushesAwayFromTheLimit) {
  const ci::RobotModel model = panda();
  ci::Parameters parameters;
  parameters.joint_limit_avoidance = {0.2, 50.0};
  parameters.nullspace.stiffness = ci::JointVector::Constant(1, 0.0);
  ci::ControlLoop loop(model, parameters);
  ci::JointVector q = panda_ready();
  q[0] = model.limits().position_upper[0] - 0.05;  // 0.15 rad into the margin
  model_simulation::Simulation sim(model, q);
  loop.start(sim.q, sim.dq);
  run(loop, sim, 2.0);
  EXPECT_LT(sim.q[0], model.limits().position_upper[0] - 0.1);
}

TEST(ControlLoop, TeachingLetsThePushMoveTheArmAndItStays) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model);
  model_simulation::Simulation sim(model, panda_ready(), true, 2.0);
  loop.start(sim.q, sim.dq);
  loop.start_teaching();
  run(loop, sim, 1.0);  // the stiffness filters down to zero
  const ci::Pose before = sim.pose();
  const Eigen::Vector3d force(0, 10, 0);
  sim.external = sim.jacobian().topRows<3>().transpose() * force;
  run(loop, sim, 0.3);
  sim.external.setZero();
  const ci::Pose released = sim.pose();
  // Only the joints' own friction (2 Nms/rad here) slows the arm after the push; it must come to
  // rest without springing back toward where it started.
  run(loop, sim, 6.0);
  const ci::Pose left = sim.pose();
  run(loop, sim, 1.0);
  const double pushed = (released.position - before.position).norm();
  EXPECT_GT(pushed, 0.02) << "the push moves the arm";
  EXPECT_GE((left.position - before.position).norm(), pushed) << "no spring back";
  EXPECT_LT((sim.pose().position - left.position).norm(), 1e-3) << "and it stays";
}

// While teaching, a 30 N push that turns the base joint toward its limit (the push follows the
// flange's motion, so it keeps driving the joint) is held inside the avoidance margin by the
// joint-space wall: the largest reach into the margin is what the push's torque compresses a wall
// of the joint's bound / margin (87 Nm / 0.1 rad) by, plus what the damped wall lets the arm's
// momentum add. Without the avoidance the same push drives the joint past its limit. Every other
// joint must stay off its limits too.
TEST(ControlLoop, TeachingKeepsEveryJointOffItsLimitUnderAPush) {
  const ci::RobotModel model = panda();
  const auto push_toward_the_limit = [&](double avoidance_stiffness) {
    ci::Parameters parameters;
    parameters.joint_limit_avoidance = {0.1, avoidance_stiffness};
    ci::ControlLoop loop(model, parameters);
    ci::JointVector q = panda_ready();
    q[0] = model.limits().position_upper[0] - 0.4;
    model_simulation::Simulation sim(model, q);
    loop.start(sim.q, sim.dq);
    loop.start_teaching();
    run(loop, sim, 0.5);
    double closest = 1e9;  // smallest distance of any joint to either of its limits [rad]
    bool wall_seen = false;
    for (int k = 0; k < 3000; ++k) {
      const ci::Jacobian jacobian = sim.jacobian();
      const Eigen::Vector3d direction = jacobian.col(0).head<3>().normalized();
      sim.external = jacobian.topRows<3>().transpose() * (30.0 * direction);
      sim.step(loop.step(sim.q, sim.dq, 0.001), 0.001);
      wall_seen = wall_seen || loop.state().controller.safety.joint_limit_wall;
      const ci::JointVector to_upper = model.limits().position_upper - sim.q;
      const ci::JointVector to_lower = sim.q - model.limits().position_lower;
      closest = std::min({closest, to_upper.minCoeff(), to_lower.minCoeff()});
    }
    return std::pair{closest, wall_seen};
  };
  const auto [closest, wall_seen] = push_toward_the_limit(20.0);
  EXPECT_TRUE(wall_seen);
  // 30 N at the flange about the base axis: at most 30 N x 0.9 m = 27 Nm, 0.031 rad into the wall.
  EXPECT_GT(closest, 0.1 - 27.0 / 870.0 - 0.02) << "the wall holds the joint in the margin";
  const auto [closest_without, unused] = push_toward_the_limit(0.0);
  EXPECT_LT(closest_without, 0.0) << "without the wall the push reaches the limit";
}

// ---- several robots
// ------------------------------------------------------------------------------

// Two loops with different models run at once in two threads and give bit-identical results to
// running each alone: they share nothing.
TEST(ControlLoop, TwoRobotsSideBySideDoNotDisturbEachOther) {
  auto scenario = [](const ci::RobotModel& model, const ci::JointVector& ready) {
    ci::ControlLoop loop(model);
    model_simulation::Simulation sim(model, ready);
    loop.start(sim.q, sim.dq);
    ci::Pose target = sim.pose();
    target.position.z() -= 0.05;
    loop.set_reference_pose(target);
    run(loop, sim, 1.0);
    return ci::JointVector(sim.q);
  };
  const ci::RobotModel first = panda(), second = iiwa();
  const ci::JointVector alone_first = scenario(first, panda_ready());
  const ci::JointVector alone_second = scenario(second, iiwa_ready());
  ci::JointVector together_first, together_second;
  std::thread a([&] { together_first = scenario(first, panda_ready()); });
  std::thread b([&] { together_second = scenario(second, iiwa_ready()); });
  a.join();
  b.join();
  EXPECT_EQ(together_first, alone_first);
  EXPECT_EQ(together_second, alone_second);
  EXPECT_NE(alone_first, panda_ready());
}
