// What the nodes log about their controller (node/status_reports.hpp): a status other than ok
// with the fault that explains it, and each oscillation the watch finds with the stiffness left.

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cartesian_impedance/node/status_reports.hpp"

namespace ci = cartesian_impedance;
using ci::node::ReportLine;

namespace {

std::string joined(const std::vector<ReportLine>& lines) {
  std::string text;
  for (const ReportLine& line : lines) {
    text += (line.level == ReportLine::Level::warning ? "W " : "I ") + line.text + "\n";
  }
  return text;
}

}  // namespace

TEST(StatusReports, AnOscillationIsReportedOnceWithTheStiffnessLeft) {
  ci::node::StatusReporter reporter(0.001, 0.1, "joint_states");
  ci::LoopState state;
  state.controller.status = ci::Status::ok;
  const ci::runtime::ControlThreadSnapshot timing;
  EXPECT_EQ(joined(reporter.update(state, timing)), "");
  state.controller.safety.oscillations = 2;
  state.controller.safety.oscillation_scale = 0.25;
  const std::string reported = joined(reporter.update(state, timing));
  EXPECT_NE(reported.find("W the closed loop oscillated"), std::string::npos) << reported;
  EXPECT_NE(reported.find("the stiffness is now 0.25 of the commanded (2 oscillation(s)"),
            std::string::npos)
      << reported;
  EXPECT_EQ(joined(reporter.update(state, timing)), "") << "once per oscillation";
  // A restart begins the count anew; the next oscillation is reported again.
  state.controller.safety.oscillations = 0;
  EXPECT_EQ(joined(reporter.update(state, timing)), "");
  state.controller.safety.oscillations = 1;
  state.controller.safety.oscillation_scale = 0.5;
  EXPECT_NE(joined(reporter.update(state, timing)).find("0.5 of the commanded"), std::string::npos);
}

TEST(StatusReports, APassivityHalvingIsReportedOnceWithTheSpringsLeft) {
  ci::node::StatusReporter reporter(0.001, 0.1, "joint_states");
  ci::LoopState state;
  state.controller.status = ci::Status::ok;
  const ci::runtime::ControlThreadSnapshot timing;
  EXPECT_EQ(joined(reporter.update(state, timing)), "");
  state.controller.safety.passivity_halvings = 2;
  state.controller.safety.passivity_scale = Eigen::Vector3d(1.0, 0.25, 0.5);
  const std::string reported = joined(reporter.update(state, timing));
  EXPECT_NE(reported.find("W the controller generated energy on its port"), std::string::npos)
      << reported;
  EXPECT_NE(reported.find("translation 1, rotation 0.25, nullspace 0.5 of the commanded (2 "
                          "halving(s)"),
            std::string::npos)
      << reported;
  EXPECT_EQ(joined(reporter.update(state, timing)), "") << "once per halving";
}

TEST(StatusReports, ACollisionIsReportedOnceWithItsJointAndReaction) {
  ci::node::StatusReporter reporter(0.001, 0.1, "joint_states");
  ci::LoopState state;
  state.controller.status = ci::Status::ok;
  const ci::runtime::ControlThreadSnapshot timing;
  EXPECT_EQ(joined(reporter.update(state, timing)), "");
  state.controller.collision.collisions = 1;
  state.controller.collision.joint = 2;
  state.controller.collision.ratio = 1.5;
  state.controller.collision.reaction = ci::CollisionReaction::stop;
  const std::string reported = joined(reporter.update(state, timing));
  EXPECT_NE(reported.find("W collision: the external torque on joint 3 passed its threshold 1.5 "
                          "times"),
            std::string::npos)
      << reported;
  EXPECT_NE(reported.find("reaction stop, holding until resume (1 collision(s)"), std::string::npos)
      << reported;
  EXPECT_EQ(joined(reporter.update(state, timing)), "") << "once per collision";
}

TEST(StatusReports, AStatusOtherThanOkNamesItsFault) {
  ci::node::StatusReporter reporter(0.001, 0.1, "joint_states");
  ci::LoopState state;
  state.controller.status = ci::Status::motion_halted;
  state.controller.fault = ci::Fault{"oscillation",
                                     -1,
                                     0.0,
                                     "of the closed loop persisted at 1/256 of the commanded "
                                     "stiffness",
                                     0.0,
                                     false,
                                     "",
                                     ci::Fault::Form::statement};
  const std::string reported = joined(reporter.update(state, {}));
  EXPECT_NE(reported.find("W controller status: motion_halted (oscillation of the closed loop "
                          "persisted at 1/256"),
            std::string::npos)
      << reported;
  state.controller.status = ci::Status::ok;
  state.controller.fault = ci::Fault{};
  EXPECT_EQ(joined(reporter.update(state, {})), "I controller status: ok\n");
}
