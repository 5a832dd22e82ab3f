// The record of commanded values behind the ROS node's one-owner rule: what a dynamic_reconfigure
// request turns into, and what the servers show (ros/src/command_record.hpp). No master needed.

#include <gtest/gtest.h>

#include <string>
#include <variant>
#include <vector>

#include <cartesian_impedance/config/yaml.hpp>
#include <cartesian_impedance/core/command.hpp>
#include <cartesian_impedance/core/error.hpp>

#include "command_record.hpp"
#include "conversions.hpp"

namespace ci = cartesian_impedance;
namespace cir = cartesian_impedance_ros;

namespace {

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;

ci::Vector6d v6(double a, double b, double c, double d, double e, double f) {
  return (ci::Vector6d() << a, b, c, d, e, f).finished();
}

// The record of a Panda started with config/panda.yaml, and a stiffness server showing it.
struct RecordFixture {
  cir::CommandRecord record{ci::load_parameters(kSource + "/config/panda.yaml")};
  // Value-initialized: the generated types leave their members (the flags too) uninitialized.
  cir::StiffnessConfig stiffness_shown{};
  cir::DampingConfig damping_shown{};
  cir::WrenchConfig wrench_shown{};

  RecordFixture() {
    cir::show_all(record, stiffness_shown);
    cir::show_all(record, damping_shown);
    cir::show_all(record, wrench_shown);
  }
  // A topic command: recorded, and shown by the servers.
  void from_topic(const ci::Command& command) {
    record.record({command});
    const cir::SharedValue value = cir::shared_value(command).value();
    cir::show(record, value, stiffness_shown);
    cir::show(record, value, damping_shown);
    cir::show(record, value, wrench_shown);
  }
};

}  // namespace

TEST(CommandRecord, StartsFromTheParametersAndServersShowThem) {
  const RecordFixture f;
  EXPECT_EQ(f.record.stiffness, ci::Matrix6d(v6(500, 500, 500, 50, 50, 50).asDiagonal()));
  EXPECT_EQ(f.record.nullspace_stiffness.size(), 7);
  EXPECT_EQ(f.record.nullspace_stiffness[4], 5.0);
  EXPECT_EQ(f.stiffness_shown.translation_z, 500.0);
  EXPECT_EQ(f.stiffness_shown.nullspace_stiffness, 10.0);  // the first joint's
  EXPECT_EQ(f.damping_shown.rotation_y, 1.0);
  EXPECT_EQ(f.wrench_shown.frame, "base");
  EXPECT_EQ(f.wrench_shown.f_z, 0.0);
}

TEST(CommandRecord, ReconfigureChangesOnlyTheFieldsTheUserChanged) {
  // The README's sequence: stiffness z = 100 and a wrench by topic, then translation_x = 300 by
  // dynamic_reconfigure.
  RecordFixture f;
  f.from_topic(ci::Stiffness::diagonal(v6(500, 500, 100, 50, 50, 50)));
  f.from_topic(ci::Wrench(v6(0, 0, -5, 0, 0, 0), ci::Frame::base));
  EXPECT_EQ(f.stiffness_shown.translation_z, 100.0);
  EXPECT_EQ(f.wrench_shown.f_z, -5.0);
  const cir::StiffnessConfig applied = f.stiffness_shown;
  cir::StiffnessConfig request = applied;
  request.translation_x = 300;
  request.update_stiffness = true;
  const std::vector<ci::Command> commands = cir::reconfigure_commands(f.record, applied, request);
  ASSERT_EQ(commands.size(), 1u);  // no nullspace stiffness: the per-joint values stay
  const auto& stiffness = std::get<ci::Stiffness>(commands[0]);
  EXPECT_EQ(stiffness.stiffness, ci::Matrix6d(v6(300, 500, 100, 50, 50, 50).asDiagonal()));
  EXPECT_EQ(stiffness.frame, ci::Frame::base);

  // Nothing changed: no command. The scalar nullspace field, once changed, sets every joint.
  EXPECT_TRUE(cir::reconfigure_commands(f.record, applied, applied).empty());
  request = applied;
  request.nullspace_stiffness = 20;
  const std::vector<ci::Command> nullspace = cir::reconfigure_commands(f.record, applied, request);
  ASSERT_EQ(nullspace.size(), 1u);
  EXPECT_EQ(std::get<ci::NullspaceStiffness>(nullspace[0]).stiffness,
            ci::JointVector::Constant(1, 20.0));
}

TEST(CommandRecord, EditsWhileTheFlagIsFalseCountWhenItTurnsTrue) {
  // The comparison is with what was last applied, not with the previous request.
  RecordFixture f;
  const cir::DampingConfig applied = f.damping_shown;
  cir::DampingConfig edited = applied;
  edited.translation_y = 0.7;  // update_damping_factors false: waits
  cir::DampingConfig request = edited;
  request.update_damping_factors = true;
  const std::vector<ci::Command> commands = cir::reconfigure_commands(f.record, applied, request);
  ASSERT_EQ(commands.size(), 1u);
  EXPECT_EQ(std::get<ci::DampingRatio>(commands[0]).ratio, v6(1, 0.7, 1, 1, 1, 1));
}

TEST(CommandRecord, TopicValuesAreShownAndCountAsApplied) {
  // After a topic set z = 100, setting z back to the 500 the server showed before is a change.
  RecordFixture f;
  const cir::StiffnessConfig before = f.stiffness_shown;
  f.from_topic(ci::Stiffness::diagonal(v6(500, 500, 100, 50, 50, 50)));
  const std::vector<ci::Command> commands =
      cir::reconfigure_commands(f.record, f.stiffness_shown, before);
  ASSERT_EQ(commands.size(), 1u);
  EXPECT_EQ(std::get<ci::Stiffness>(commands[0]).stiffness(2, 2), 500.0);

  // Per-joint nullspace stiffness and damping from set_config.
  ci::JointVector per_joint(7);
  per_joint << 12, 12, 12, 12, 6, 6, 6;
  f.from_topic(ci::NullspaceStiffness(per_joint));
  f.from_topic(ci::NullspaceDampingRatio{0.8});
  EXPECT_EQ(f.stiffness_shown.nullspace_stiffness, 12.0);
  EXPECT_EQ(f.damping_shown.nullspace_damping, 0.8);
  EXPECT_EQ(f.record.nullspace_stiffness, per_joint);
}

TEST(CommandRecord, ServersShowValuesAfterTheLimits) {
  // config/panda.yaml: stiffness.translation <= 3000, damping ratio in [0.1, 2], |force| <= 60.
  RecordFixture f;
  f.from_topic(ci::Stiffness::diagonal(v6(5000, 100, 100, 10, 10, 10)));
  f.from_topic(ci::DampingRatio{v6(3, 1, 1, 1, 1, 1)});
  f.from_topic(ci::Wrench(v6(0, 80, -60, 0, 0, 0), ci::Frame::end_effector));
  EXPECT_EQ(f.stiffness_shown.translation_x, 3000.0);
  EXPECT_EQ(f.damping_shown.translation_x, 2.0);
  EXPECT_NEAR(f.wrench_shown.f_y, 48.0, 1e-12);  // (80, -60) scaled to norm 60
  EXPECT_NEAR(f.wrench_shown.f_z, -36.0, 1e-12);
  EXPECT_EQ(f.wrench_shown.frame, "end_effector");
  // The record keeps what was commanded; an unchanged field is re-sent as commanded, and the
  // loop saturates it again.
  cir::StiffnessConfig request = f.stiffness_shown;
  request.translation_y = 200;
  const std::vector<ci::Command> commands =
      cir::reconfigure_commands(f.record, f.stiffness_shown, request);
  EXPECT_EQ(std::get<ci::Stiffness>(commands.at(0)).stiffness.diagonal(),
            v6(5000, 200, 100, 10, 10, 10));
}

TEST(CommandRecord, WrenchFieldsAndFrame) {
  RecordFixture f;
  f.from_topic(ci::Wrench(v6(1, 2, -5, 0, 0, 0.5), ci::Frame::base));
  const cir::WrenchConfig applied = f.wrench_shown;
  cir::WrenchConfig request = applied;
  request.f_x = 3;
  request.apply_wrench = true;
  std::vector<ci::Command> commands = cir::reconfigure_commands(f.record, applied, request);
  ASSERT_EQ(commands.size(), 1u);
  EXPECT_EQ(std::get<ci::Wrench>(commands[0]).wrench, v6(3, 2, -5, 0, 0, 0.5));
  EXPECT_EQ(std::get<ci::Wrench>(commands[0]).frame, ci::Frame::base);
  // Only the frame: the recorded wrench, in the new frame.
  request = applied;
  request.frame = "end_effector";
  commands = cir::reconfigure_commands(f.record, applied, request);
  ASSERT_EQ(commands.size(), 1u);
  EXPECT_EQ(std::get<ci::Wrench>(commands[0]).wrench, v6(1, 2, -5, 0, 0, 0.5));
  EXPECT_EQ(std::get<ci::Wrench>(commands[0]).frame, ci::Frame::end_effector);
  request.frame = "tool";
  EXPECT_THROW(cir::reconfigure_commands(f.record, applied, request), ci::Error);
  // A megabyte frame is named by its start and length, not echoed into the log line.
  request.frame = std::string(1 << 20, 't');
  try {
    cir::reconfigure_commands(f.record, applied, request);
    ADD_FAILURE() << "a megabyte frame was accepted";
  } catch (const ci::Error& error) {
    const std::string message = error.what();
    EXPECT_LT(message.size(), 300u);
    EXPECT_NE(message.find("frame = 'tttt"), std::string::npos) << message;
    EXPECT_NE(message.find("(1048576 characters) is not a frame (valid: base, end_effector)"),
              std::string::npos)
        << message;
  }
}

TEST(CommandRecord, FullMatrixStiffnessKeepsItsCouplingOrFailsValidation) {
  // A stiffness given in a frame rotated 45 degrees about z: a full matrix in the base frame.
  RecordFixture f;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitZ()).matrix();
  f.from_topic(
      ci::Stiffness(cir::rotate_stiffness(R, v6(1000, 200, 500, 50, 50, 50)), ci::Frame::base));
  EXPECT_NEAR(f.stiffness_shown.translation_x, 600.0, 1e-9);
  EXPECT_NEAR(f.record.stiffness(0, 1), 400.0, 1e-9);
  cir::StiffnessConfig request = f.stiffness_shown;
  request.translation_z = 300;
  std::vector<ci::Command> commands =
      cir::reconfigure_commands(f.record, f.stiffness_shown, request);
  ci::Matrix6d expected = f.record.stiffness;
  expected(2, 2) = 300;
  EXPECT_EQ(std::get<ci::Stiffness>(commands.at(0)).stiffness, expected);
  EXPECT_NO_THROW(ci::validate_command(commands[0], 7));
  // x down to 100 with the coupling of 400 to y (600): the 2x2 block [[100, 400], [400, 600]]
  // has a negative eigenvalue.
  request = f.stiffness_shown;
  request.translation_x = 100;
  commands = cir::reconfigure_commands(f.record, f.stiffness_shown, request);
  try {
    ci::validate_command(commands.at(0), 7);
    FAIL() << "not rejected";
  } catch (const ci::Error& error) {
    EXPECT_NE(std::string(error.what()).find("not positive semi-definite"), std::string::npos)
        << error.what();
  }
}
