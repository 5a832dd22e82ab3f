// Fail closed: every way a measurement, a time step or a parameter can be wrong ends in a named
// status and fault and a torque that ramps toward zero within the rate limit, never in an "ok"
// built on stale data; limits are never exceeded, also while they change; a cycle costs the same
// however much is queued or sent. Each test here failed before the library was made to fail
// closed (the findings are named at each).

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/math.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "support/model_simulation.hpp"
#include "support/robots.hpp"

namespace ci = cartesian_impedance;

namespace {

constexpr double kDt = 0.001;
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

using robots::panda;
using robots::panda_ready;

// A loop holding the arm against a disturbance the robot's firmware does not know about (and
// pulling toward a reference 5 cm away), so that the joints carry torque when the bad input
// arrives.
struct Pulling {
  ci::RobotModel model = panda();
  ci::ControlLoop loop{model, parameters()};
  model_simulation::Simulation sim{model, panda_ready()};

  static ci::Parameters parameters() {
    ci::Parameters p;
    p.limits.joint_torque_rate = ci::JointVector::Constant(1, 1000.0);
    p.dynamics.armature = ci::JointVector::Constant(1, 0.1);  // as the model simulation
    return p;
  }

  Pulling() {
    // Some tests lower the torque limits or raise the plausible speeds while it runs.
    loop.allow_runtime_safety_changes();
    loop.start(sim.q, sim.dq);
    ci::Pose target = loop.state().controller.pose;
    target.position += Eigen::Vector3d(0.05, 0.0, -0.03);
    loop.set_reference_pose(target);
    sim.external = (ci::JointVector(7) << 5, 20, 5, -15, 2, 3, 1).finished();
    for (int k = 0; k < 300; ++k) sim.step(loop.step(sim.q, sim.dq, kDt), kDt);
  }
};

// After one bad cycle: the status and fault say what it was, and each joint's torque moved
// toward zero by the rate limit times `dt` (or reached zero).
void expect_failed_closed(const ci::LoopState& state, const ci::JointVector& before,
                          ci::Status status, const std::string& input, int index, double dt) {
  EXPECT_EQ(state.controller.status, status) << ci::to_string(state.controller.status);
  EXPECT_EQ(std::string(state.controller.fault.input), input);
  EXPECT_EQ(state.controller.fault.index, index);
  const ci::JointVector& tau = state.controller.tau;
  for (int i = 0; i < tau.size(); ++i) {
    const double step = 1000.0 * dt;
    const double expected =
        std::abs(before[i]) <= step ? 0.0 : before[i] - std::copysign(step, before[i]);
    EXPECT_NEAR(tau[i], expected, 1e-12) << "joint " << i;
  }
}

}  // namespace

// Finding 1: a bad joint velocity with a good position was accepted with status ok (the old dq,
// pose and Jacobian stayed); in the reproduction the controller commanded 0.004 Nm instead of
// the 76 Nm of the law, without a word.
TEST(FailClosed, BadJointVelocityWithAGoodPositionFailsClosedNamingIt) {
  struct Case {
    const char* label;
    double value;  // for dq[4]
    int size;
  };
  for (const Case& bad :
       {Case{"NaN", kNan, 7}, Case{"+inf", kInf, 7}, Case{"-inf", -kInf, 7},
        Case{"1e300", 1e300, 7}, Case{"beyond plausibility", 10.5, 7}, Case{"6 values", 0.0, 6}}) {
    SCOPED_TRACE(bad.label);
    Pulling rig;
    ci::JointVector q = rig.sim.q;
    q[1] += 0.3;  // the arm moved: a stale model would not see it
    ci::JointVector dq = rig.sim.dq;
    dq[4] = bad.value;
    dq.conservativeResize(bad.size);
    const ci::JointVector before = rig.loop.state().controller.tau;
    const ci::JointVector last_good_q = rig.loop.state().q;
    ASSERT_GT(before.cwiseAbs().maxCoeff(), 1.0) << "the arm must be carrying torque";
    rig.loop.step(q, dq, kDt);
    expect_failed_closed(rig.loop.state(), before, ci::Status::invalid_robot_state, "dq",
                         bad.size == 7 ? 4 : -1, kDt);
    EXPECT_FALSE(ci::to_string(rig.loop.state().controller.fault).empty());
    // The stale measurement is not published as if it were current.
    EXPECT_EQ(rig.loop.state().q, last_good_q);
    // The next good measurement resumes the law.
    rig.loop.step(rig.sim.q, rig.sim.dq, kDt);
    EXPECT_EQ(rig.loop.state().controller.status, ci::Status::ok);
    EXPECT_STREQ(rig.loop.state().controller.fault.input, "");
  }
}

// Finding 1, with the dynamics on: a velocity of 1e300 used to reach the model, whose Coriolis
// term overflowed, and the failed compute() was ignored.
TEST(FailClosed, VelocityThatWouldBreakTheModelFailsClosedBeforeReachingIt) {
  Pulling rig;
  ci::Parameters p = Pulling::parameters();
  p.dynamics.dynamically_consistent_nullspace = true;
  p.plausibility.joint_velocity = ci::JointVector::Constant(1, 100.0);  // the largest valid
  rig.loop.set_parameters(p);
  rig.loop.step(rig.sim.q, rig.sim.dq, kDt);
  ASSERT_EQ(rig.loop.state().controller.status, ci::Status::ok);
  ci::JointVector dq = rig.sim.dq;
  dq[2] = 1e300;
  const ci::JointVector before = rig.loop.state().controller.tau;
  rig.loop.step(rig.sim.q, dq, kDt);
  expect_failed_closed(rig.loop.state(), before, ci::Status::invalid_robot_state, "dq", 2, kDt);
  EXPECT_EQ(rig.loop.state().controller.fault.bound, 100.0);
}

TEST(FailClosed, PositionFarOutsideTheJointLimitsFailsClosed) {
  Pulling rig;
  ci::JointVector q = rig.sim.q;
  q[3] = 1.0;  // joint 4's range is [-3.07, -0.07]; 1.07 rad beyond it
  const ci::JointVector before = rig.loop.state().controller.tau;
  rig.loop.step(q, rig.sim.dq, kDt);
  expect_failed_closed(rig.loop.state(), before, ci::Status::invalid_robot_state, "q", 3, kDt);
  EXPECT_NEAR(rig.loop.state().controller.fault.bound, -0.0698 + 0.2, 1e-4);
  // At start the same position is an error naming it.
  ci::ControlLoop fresh(rig.model);
  try {
    fresh.start(q, rig.sim.dq);
    FAIL() << "start() accepted a position outside the limits";
  } catch (const ci::Error& error) {
    EXPECT_NE(std::string(error.what()).find("q[3] = 1 is outside the joint's limits"),
              std::string::npos)
        << error.what();
  }
}

// Finding 7: dt = 1e9 was ok and allowed a 30 Nm jump in one call; dt = 1e-300 froze the torque
// with status ok.
TEST(FailClosed, ImplausibleTimeStepFailsClosedAtTheRateOfTheLastValidCycle) {
  for (const double dt : {1e9, 0.05, 1e-300, 1e-7, 0.0, -0.001, kNan, kInf}) {
    SCOPED_TRACE(dt);
    Pulling rig;
    const ci::JointVector before = rig.loop.state().controller.tau;
    rig.loop.step(rig.sim.q, rig.sim.dq, dt);
    // The torque moves toward zero by what the last valid cycle (1 ms) allowed: not by
    // rate * 1e9, and not by nothing.
    expect_failed_closed(rig.loop.state(), before, ci::Status::invalid_dt, "dt", -1, kDt);
  }
}

// Finding 9: lowering limits.joint_torque left |tau| above the new limit for 671 ms, with status
// ok. The bound in force now ramps down at the rate limit: neither it nor the rate is exceeded,
// the new limit holds as soon as the rate allows, and the state says so meanwhile.
TEST(FailClosed, LoweredTorqueLimitRampsDownWithoutExceedingRateOrBound) {
  Pulling rig;
  const ci::JointVector start = rig.loop.state().controller.tau;
  const double largest = start.cwiseAbs().maxCoeff();
  ASSERT_GT(largest, 5.0);
  ci::Parameters p = Pulling::parameters();
  p.limits.joint_torque = ci::JointVector::Constant(1, 0.5);
  rig.loop.set_parameters(p);
  const int ramp_cycles = static_cast<int>(std::ceil((largest - 0.5) / (1000.0 * kDt)));
  ci::JointVector previous = start;
  ci::JointVector bound = start.cwiseAbs().cwiseMax(0.5);
  for (int k = 0; k < ramp_cycles + 50; ++k) {
    rig.sim.step(rig.loop.step(rig.sim.q, rig.sim.dq, kDt), kDt);
    const ci::ControllerState& state = rig.loop.state().controller;
    ASSERT_EQ(state.status, ci::Status::ok);
    for (int i = 0; i < 7; ++i) {
      ASSERT_LE(std::abs(state.tau[i] - previous[i]), 1.0 + 1e-12) << "rate, joint " << i;
      ASSERT_LE(std::abs(state.tau[i]), state.joint_torque_limit[i] + 1e-12) << "joint " << i;
      ASSERT_LE(state.joint_torque_limit[i], bound[i] + 1e-12) << "the bound rose, joint " << i;
      ASSERT_GE(state.joint_torque_limit[i], 0.5);
    }
    EXPECT_EQ(state.limits.joint_torque_limit_ramping,
              (state.joint_torque_limit.array() > 0.5).any());
    previous = state.tau;
    bound = state.joint_torque_limit;
    if (k >= ramp_cycles) {
      ASSERT_LE(state.tau.cwiseAbs().maxCoeff(), 0.5 + 1e-12) << "cycle " << k;
      ASSERT_FALSE(state.limits.joint_torque_limit_ramping);
    }
  }
  // Raising it again holds at once (the rate limit keeps the torque continuous).
  rig.loop.set_parameters(Pulling::parameters());
  rig.loop.step(rig.sim.q, rig.sim.dq, kDt);
  // (to the default: the Panda URDF's effort of joint 1)
  EXPECT_EQ(rig.loop.state().controller.joint_torque_limit[0], 87.0);
}

// Finding 8 (flood): every queued command used to be applied in the cycle that found it (1.1 ms
// for a full inbox). Now at most 8 per cycle, the rest in order in the next cycles.
TEST(FailClosed, AtMostEightCommandsAreAppliedPerCycleAndNoneIsLost) {
  Pulling rig;
  const std::uint64_t applied = rig.loop.state().commands_applied;
  for (int i = 0; i < 40; ++i) rig.loop.set_nullspace_damping_ratio(0.5 + 0.01 * i);
  for (int cycle = 1; cycle <= 5; ++cycle) {
    rig.loop.step(rig.sim.q, rig.sim.dq, kDt);
    EXPECT_EQ(rig.loop.state().commands_applied - applied, static_cast<std::uint64_t>(8 * cycle));
  }
  EXPECT_DOUBLE_EQ(rig.loop.latest_parameters().nullspace.damping_ratio, 0.5 + 0.01 * 39);
}

// Finding 8 (trajectory): the velocities of a 10,000-point trajectory were derived in the cycle
// that started it (163-276 us). They are derived when it is sent; starting derives only the
// first point's, which depends on where the arm is. (The cost is measured by the benchmark
// BM_StepThatStartsATrajectory; this checks the path is still the one the points describe.)
TEST(FailClosed, TrajectoryVelocitiesDerivedWhenSentGiveTheSamePath) {
  const int points = 10000;
  ci::TrajectoryBuffer buffer(1, points);
  ci::JointTrajectory trajectory;
  trajectory.joint_names = {"j"};
  for (int k = 1; k <= points; ++k) {
    trajectory.times.push_back(0.001 * k);
    trajectory.positions.push_back({std::sin(0.002 * k)});
  }
  buffer.assign(trajectory, {"j"}, ci::JointVector::Constant(1, -2),
                ci::JointVector::Constant(1, 2));
  ci::JointVector q(1), dq(1), q_other(1), dq_other(1);
  ci::TrajectoryBuffer other = buffer;
  buffer.begin(ci::JointVector::Constant(1, 0.0), ci::JointVector::Zero(1));
  other.begin(ci::JointVector::Constant(1, -0.5), ci::JointVector::Zero(1));
  // Past the second point the two starts give the same path: nothing there depends on begin().
  for (const double time : {0.0025, 1.2345, 5.0}) {
    buffer.sample(time, q, dq);
    other.sample(time, q_other, dq_other);
    EXPECT_EQ(q[0], q_other[0]) << time;
    EXPECT_EQ(dq[0], dq_other[0]) << time;
    EXPECT_NEAR(q[0], std::sin(2.0 * time), 1e-6) << time;
  }
  buffer.sample(0.0005, q, dq);
  other.sample(0.0005, q_other, dq_other);
  EXPECT_NE(q[0], q_other[0]);
}

// Finding 6: values that switched the controller off without a word are rejected, naming the
// field and the range.
TEST(FailClosed, ParametersThatWouldSilentlyDisableTheControllerAreRejected) {
  struct Case {
    const char* field;
    void (*set)(ci::Parameters&);
  };
  for (const Case& bad :
       {Case{"filter.pose.fraction", [](ci::Parameters& p) { p.filter.pose.fraction = 5e-324; }},
        Case{"filter.pose.time", [](ci::Parameters& p) { p.filter.pose.time = 1e308; }},
        Case{"limits.joint_torque[0]",
             [](ci::Parameters& p) {
               p.limits.joint_torque = ci::JointVector::Constant(1, 5e-324);
             }},
        Case{"limits.joint_torque_rate[0]",
             [](ci::Parameters& p) { p.limits.joint_torque_rate[0] = 5e-324; }},
        Case{"nullspace.pseudo_inverse_damping",
             [](ci::Parameters& p) { p.nullspace.pseudo_inverse_damping = 1e308; }},
        Case{"limits.pose_error.translation",
             [](ci::Parameters& p) { p.limits.pose_error.translation = 5e-324; }},
        Case{"limits.stiffness.translation.max",
             [](ci::Parameters& p) { p.limits.stiffness.translation.max = 1e308; }},
        Case{"trajectory.goal_tolerance",
             [](ci::Parameters& p) { p.trajectory.goal_tolerance = 5e-324; }}}) {
    SCOPED_TRACE(bad.field);
    ci::Parameters p;
    bad.set(p);
    try {
      ci::validate(p);
      FAIL() << "accepted";
    } catch (const ci::Error& error) {
      EXPECT_EQ(std::string(error.what()).rfind(bad.field, 0), 0u) << error.what();
      EXPECT_NE(std::string(error.what()).find("is outside ["), std::string::npos) << error.what();
    }
  }
}

// Finding 6: a reference or wrench beyond ~1.3e154 was "clipped" to zero (the squared norm
// overflowed) with the clipped flag set; a pose at 1e308 was accepted.
TEST(FailClosed, ClippingHugeVectorsKeepsTheirDirectionAndHugePosesAreRejected) {
  Eigen::Vector3d huge(1e200, -2e200, 2e200);
  EXPECT_TRUE(ci::clip_norm(huge, 0.1));
  EXPECT_NEAR(huge.norm(), 0.1, 1e-15);
  EXPECT_NEAR(huge.x(), 0.1 / 3.0, 1e-15);
  EXPECT_NEAR(huge.y(), -0.2 / 3.0, 1e-15);
  Eigen::Vector3d largest(1.7e308, 1.7e308, 0.0);
  EXPECT_TRUE(ci::clip_norm(largest, 1.0));
  EXPECT_NEAR(largest.x(), std::sqrt(0.5), 1e-15);

  ci::Pose far;
  far.position.x() = 1e308;
  EXPECT_THROW(ci::validate_command(ci::ReferencePose{far}, 7), ci::Error);
  far.position.x() = 1001.0;
  EXPECT_THROW(ci::validate_command(ci::ReferencePose{far}, 7), ci::Error);
  far.position.x() = 999.0;
  EXPECT_NO_THROW(ci::validate_command(ci::ReferencePose{far}, 7));
  EXPECT_THROW(ci::validate_command(ci::NullspaceTarget{ci::JointVector::Constant(7, 1e308)}, 7),
               ci::Error);
  ci::Matrix6d stiffness = ci::Matrix6d::Identity() * 1e300;
  EXPECT_THROW(ci::validate_command(ci::Stiffness{stiffness}, 7), ci::Error);
}

TEST(FailClosed, FaultTextNamesInputValueAndBound) {
  EXPECT_EQ(ci::to_string(ci::Fault{"dq", 4, kNan, "is not finite"}), "dq[4] = nan is not finite");
  EXPECT_EQ(ci::to_string(ci::Fault{"dt", -1, 1e9, "is above plausibility.dt.max", 0.02, true}),
            "dt = 1000000000 is above plausibility.dt.max = 0.02");
  EXPECT_EQ(ci::to_string(ci::Fault{}), "");
}

// One check serves both ways: the measurement that makes a cycle fail closed makes start() throw
// an Error that carries the same fault as data (field, index, value, bound), also when copied.
TEST(FailClosed, TheCycleAndStartReportTheSameFaultOfAMeasurement) {
  Pulling rig;
  ci::JointVector dq = rig.sim.dq;
  dq[5] = 50.0;  // beyond the default plausibility.joint_velocity
  rig.loop.step(rig.sim.q, dq, kDt);
  const ci::Fault cycle = rig.loop.state().controller.fault;
  ASSERT_TRUE(cycle);
  ci::ControlLoop fresh(rig.model, Pulling::parameters());
  try {
    fresh.start(rig.sim.q, dq);
    FAIL() << "start() accepted a joint velocity the cycle refuses";
  } catch (const ci::Error& thrown) {
    const ci::Error error = thrown;  // the copy keeps its own fault
    EXPECT_STREQ(error.fault().input, cycle.input);
    EXPECT_EQ(error.fault().index, 5);
    EXPECT_EQ(error.fault().value, 50.0);
    EXPECT_TRUE(error.fault().has_bound);
    EXPECT_EQ(error.fault().bound, cycle.bound);
    EXPECT_STREQ(error.fault().reason, cycle.reason);
    EXPECT_EQ(std::string(error.what()), ci::to_string(cycle));
  }
  EXPECT_FALSE(fresh.started());
  // A command's error carries its field too.
  try {
    rig.loop.set_stiffness((ci::Vector6d() << -5, 500, 500, 50, 50, 50).finished());
    FAIL() << "a negative stiffness was accepted";
  } catch (const ci::Error& error) {
    EXPECT_STREQ(error.fault().input, "stiffness.translation.x");
    EXPECT_EQ(error.fault().value, -5.0);
    EXPECT_EQ(error.fault().bound, 0.0);
  }
  // Errors that are not about one value carry no fault.
  EXPECT_FALSE(ci::Error("file 'x' cannot be read").fault());
}

// collision.measured_torque needs the robot's joint torques every cycle: a cycle without them,
// or with a wrongly sized or non-finite one, fails closed naming measured_torque (the torque
// ramps toward zero by the rate limit), and the next cycle that brings them resumes, its
// observer started over: the gap is no collision.
TEST(FailClosed, AMissingOrBadMeasuredTorqueFailsClosedNamingIt) {
  const ci::RobotModel model = panda();
  ci::Parameters p = Pulling::parameters();
  p.collision.measured_torque = true;
  ci::ControlLoop loop(model, p);
  model_simulation::Simulation sim(model, panda_ready());
  loop.start(sim.q, sim.dq);
  const auto run = [&](int steps) {
    for (int k = 0; k < steps; ++k) {
      sim.step(loop.step(sim.q, sim.dq, sim.measured_torque, kDt), kDt);
    }
  };
  run(200);
  ASSERT_EQ(loop.state().controller.status, ci::Status::ok);
  const auto fails = [&](const ci::JointVector* measured, ci::Status status, int index) {
    const ci::JointVector before = loop.state().controller.tau;
    const ci::JointVector& tau = measured == nullptr ? loop.step(sim.q, sim.dq, kDt)
                                                     : loop.step(sim.q, sim.dq, *measured, kDt);
    expect_failed_closed(loop.state(), before, status, "measured_torque", index, kDt);
    sim.step(tau, kDt);
  };
  fails(nullptr, ci::Status::missing_dynamics, -1);
  EXPECT_NE(ci::to_string(loop.state().controller.fault).find("collision.measured_torque"),
            std::string::npos)
      << ci::to_string(loop.state().controller.fault);
  ci::JointVector bad = sim.measured_torque;
  bad[3] = kNan;
  fails(&bad, ci::Status::invalid_robot_state, 3);
  EXPECT_EQ(ci::to_string(loop.state().controller.fault), "measured_torque[3] = nan is not finite");
  const ci::JointVector short_one = sim.measured_torque.head(6);
  fails(&short_one, ci::Status::invalid_robot_state, -1);
  run(300);
  EXPECT_EQ(loop.state().controller.status, ci::Status::ok);
  EXPECT_EQ(loop.state().controller.collision.collisions, 0);
  // Off, the measurement is not read: a NaN in it changes nothing.
  ci::ControlLoop unmeasured(model, Pulling::parameters());
  unmeasured.start(sim.q, sim.dq);
  unmeasured.step(sim.q, sim.dq, bad, kDt);
  EXPECT_EQ(unmeasured.state().controller.status, ci::Status::ok);
}

// Finding 10: the ROS node dropped commands when the inbox was full. A sender may now wait for
// room (LoopCapacity::send_timeout) in its own thread while the cycle drains the inbox; a loop
// that does not step makes it throw QueueFull, which a caller can tell from a bad command.
TEST(FailClosed, ASenderWaitsForRoomInAFullInboxInsteadOfDroppingTheCommand) {
  const ci::RobotModel model = panda();
  ci::ControlLoop loop(model, Pulling::parameters(), ci::LoopCapacity{8, 10, 1.0});
  model_simulation::Simulation sim(model, panda_ready());
  loop.start(sim.q, sim.dq);
  for (int i = 0; i < 8; ++i) loop.set_nullspace_damping_ratio(0.5);
  std::atomic<bool> sent{false};
  std::thread sender([&] {
    loop.set_nullspace_damping_ratio(0.9);  // the inbox is full: waits
    sent = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(sent) << "the sender should still be waiting";
  loop.step(sim.q, sim.dq, kDt);  // makes room
  sender.join();
  EXPECT_TRUE(sent);
  loop.step(sim.q, sim.dq, kDt);
  EXPECT_DOUBLE_EQ(loop.latest_parameters().nullspace.damping_ratio, 0.9);

  ci::ControlLoop stalled(model, {}, ci::LoopCapacity{2, 10, 0.02});
  stalled.set_nullspace_damping_ratio(0.5);
  stalled.set_nullspace_damping_ratio(0.5);
  const auto begin = std::chrono::steady_clock::now();
  EXPECT_THROW(stalled.set_nullspace_damping_ratio(0.5), ci::QueueFull);
  EXPECT_GE(std::chrono::steady_clock::now() - begin, std::chrono::milliseconds(20));
  EXPECT_THROW(stalled.set_nullspace_damping_ratio(-1.0), ci::Error);  // bad: at once, not full
}
